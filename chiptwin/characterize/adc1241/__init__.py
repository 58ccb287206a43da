"""IEEE Std 1241 ADC bench, the analysis half: codes in, figures with uncertainties out.

One converter's records, one function per test, the results summarised over the chip::

    stimulus (V) ──► converter ──► codes ──► histogram_test ──► transitions, DNL, INL, missing
    Ramp / Sine      (the caller:              (code density)     codes, offset, gain (± σ)
    dc_sweep_V        twin or chip)  ──► dynamic_test ──────► SINAD, ENOB, SFDR (sine fit)
                                     ──► transition_noise ──► σ per transition, rms (± σ)
    per-converter figures ──► summarize ──► worst and median, JSON-ready (``adc1241.json``)

* :mod:`.histogram`: the stimuli, the histogram test, the sample-count helper, the summary;
* :mod:`.sine`: the sine-wave fits, the spectrum, SINAD, ENOB, SFDR;
* :mod:`.noise`: transition noise from a DC sweep;
* :mod:`.plots`: DNL/INL against code, the code histogram, the output spectrum;
* :mod:`.bench`: every converter of a scenario's chip on the bench (``chiptwin characterize
  --adc``, ``adc1241.json``).

Conventions (those of :mod:`chiptwin.pixel.adc`): codes 0 … 2^N − 1, the ideal code width
``Q = (v_max_V − v_min_V) / 2^N`` and code k centred on ``v_min_V + k·Q``, so the ideal transition
levels are ``T[k] = v_min_V + (k − ½)·Q``, k = 1 … 2^N − 1; ``T[k]`` is the input at which the
output changes from k − 1 to k. Per-code arrays are indexed by code; ``inl[k]`` belongs to
``T[k]``, the lower edge of code k; entries that do not exist (code 0's lower edge, the end codes'
widths) are NaN.

Clause numbers are those of IEEE Std 1241-2000 as the author knows them (code-transition levels
by the histogram method §4.1.6 — static (ramp) and dynamic (sine) histograms; DNL, INL, missing
codes §4.4?; gain and offset §4.2?; transition noise §4.5?); they are not checked against the text
here, so every formula is written out in its docstring.
"""

from chiptwin.characterize.adc1241.histogram import (
    BenchRecords,
    HistogramResult,
    Ramp,
    Sine,
    bench_records,
    converter_figures,
    dc_sweep_V,
    histogram_from_counts,
    histogram_samples,
    histogram_test,
    ramp_V,
    sine_V,
    summarize,
    to_jsonable,
)
from chiptwin.characterize.adc1241.noise import TransitionNoise, transition_noise
from chiptwin.characterize.adc1241.sine import (
    DynamicResult,
    SineFit,
    Spectrum,
    coherent_cycles,
    dynamic_test,
    sine_fit_3,
    sine_fit_4,
    spectrum,
)

__all__ = ["BenchRecords", "DynamicResult", "HistogramResult", "Ramp", "Sine", "SineFit",
           "Spectrum", "TransitionNoise", "bench_records", "coherent_cycles",
           "converter_figures", "dc_sweep_V", "dynamic_test", "histogram_from_counts",
           "histogram_samples",
           "histogram_test", "ramp_V", "sine_V", "sine_fit_3", "sine_fit_4", "spectrum",
           "summarize", "to_jsonable", "transition_noise"]
