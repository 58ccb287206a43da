"""``chiptwin dsp-report``: every DSP routine, bit-accurate vs float, on a scenario's own data.

The scenario runs once at the ``binned`` level, through its converter (ideal, or as built: the
header names its keys); the ADC samples it produced feed each routine in
the order the chip uses them (CMS → dark reference → background subtraction → averaging) and the
routines the chain does not use (kinetics-weighted accumulation, line binning, the 8-tap FIR,
the Wiener equalizer) on the background-subtracted frames. Stress data (every register driven to
its corners) is reported beside it. Each row carries its analytic bound, checked
(:mod:`chiptwin.dsp.errors`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin.dsp.errors import Case, error_report
from chiptwin.dsp.filters import FirConfig, KineticsConfig, WienerConfig, design_wiener
from chiptwin.dsp.frame_ops import BinningConfig, average_frames_fixed, cms_fixed
from chiptwin.dsp.frame_ops import subtract_background_fixed as background_fixed
from chiptwin.dsp.pipeline import chain_for
from chiptwin.dsp.stress import default_cases

if TYPE_CHECKING:
    from chiptwin.config import Scenario


def dsp_report(s: Scenario, rng: np.random.Generator) -> dict[str, Any]:
    """Fixed-vs-float error of every routine on the scenario's data and on stress data.

    Parameters
    ----------
    s : Scenario
        Any scenario; it is run once at the ``binned`` photon level to get real ADC samples.
    rng : numpy.random.Generator
        Stream for the stress data.

    Returns
    -------
    dict
        :func:`chiptwin.dsp.errors.error_report` of all cases, plus ``scenario``.
    """
    cases = scenario_cases(s)
    cases.update({f"stress: {label}": case for label, case in default_cases(rng).items()})
    report = error_report(cases)
    report["scenario"] = s.scenario.name
    report["converter"] = converter_label(s)
    return report


def converter_label(s: Scenario) -> str:
    """Which converter produced the scenario's codes: ``ideal`` or ``as built`` with its keys
    (``[run.fidelity] adc = "ideal"`` zeroes them)."""
    from chiptwin.twin.runner import adc_level

    if adc_level(s) == "ideal":
        zeroed = (" (as-built effects zeroed by run.fidelity.adc)"
                  if s.chip.adc.as_built_keys else "")
        return "ideal" + zeroed
    keys = ", ".join(f"{k} = {v!r}" for k, v in s.chip.adc.as_built_keys.items())
    return f"as built ({keys}, ramp = {s.chip.adc.ramp!r})"


def scenario_cases(s: Scenario) -> dict[str, Case]:
    """The chip's own samples through each routine, with the chain's register formats."""
    from chiptwin.twin.runner import Recorder, prepare, simulate, stage_rng

    scene = prepare(s)
    out = simulate(s, scene, "binned", stage_rng(s.scenario.seed, "pixel"), Recorder(),
                   keep_codes=True)
    codes = np.stack(out.dsp.kept)
    m, k, n = s.chip.dsp.cms_samples, s.chip.dsp.n_dark_frames, s.chip.dsp.average_frames
    chain = chain_for(s.chip)
    reset, signal = codes[:, :m], codes[:, m:]
    cms = cms_fixed(reset, signal, chain.cms).codes
    dark = average_frames_fixed(cms[:k], chain.dark).codes[0]
    light = cms[k:][: (len(cms) - k) // n * n]
    diff = background_fixed(light, dark, chain.background).codes
    bg_fmt = chain.background.out_fmt
    cases = {
        "cms": Case("cms", chain.cms, {"reset": reset, "signal": signal}),
        "dark reference": Case("average", chain.dark, {"frames": cms[: k * (len(cms) // k)]}),
        "background": Case("background", chain.background, {"frames": light, "dark": dark}),
        "average": Case("average", chain.average, {"frames": diff}),
        "fir 8-tap": Case("fir", FirConfig(in_fmt=bg_fmt), {"frames": diff}),
        "wiener": _wiener_case(s, scene.coupling, diff, out, bg_fmt),
    }
    if s.chip.rows % 2 == 0:
        cfg = BinningConfig(rows=s.chip.rows, cols=s.chip.cols, factor=2, in_fmt=bg_fmt)
        cases["binning x2"] = Case("binning", cfg, {"frames": diff})
    if s.assay.kind == "pyrosequencing":
        cases["kinetics"] = _kinetics_case(s, diff, bg_fmt)
    return cases


def _kinetics_case(s: Scenario, diff: np.ndarray, fmt) -> Case:
    """The matched filter over each flow: frames of one flow weighted by exp(−k_a t).

    ``diff`` starts with the frame after the K dark frames; the first flow starts at
    ``assay.start_s``, a whole number of frames later (validated).
    """
    a, c = s.assay, s.chip
    period = c.timing.frame_period_s
    per_flow = int(round(a.flow_period_s / period))
    first = int(round(a.start_s / period)) - c.dsp.n_dark_frames
    n_flows = min(a.n_flows, (len(diff) - first) // per_flow)
    t_s = tuple(float(j * period) for j in range(per_flow))
    cfg = KineticsConfig(t_s=t_s, k_per_s=a.k_a_per_s, in_fmt=fmt)
    frames = diff[first: first + n_flows * per_flow].reshape(n_flows, per_flow, -1)
    return Case("kinetics", cfg, {"frames": frames})


def _wiener_case(s: Scenario, coupling: np.ndarray, diff: np.ndarray, out, fmt) -> Case:
    """Cross-talk equalizer from the optics' coupling matrix; λ from the run's own noise."""
    per_frame_var = float(np.mean(out.var_e2)) * s.chip.dsp.average_frames
    site_peak = float(np.max(out.mean_e)) if out.mean_e.size else 1.0
    lam = per_frame_var / max(site_peak, 1.0) ** 2
    eq = design_wiener(coupling, WienerConfig(noise_to_signal=lam, in_fmt=fmt))
    return Case("wiener", eq, {"frames": diff})
