"""The metric catalogue: what a study can measure of each run, and how it is summarised.

Each metric is computed per run (one row of the ``runs`` table) from the run's summary and
arrays. Two kinds:

- ``rate``: a count of successes ``k`` out of ``n`` trials in the run (``calls_correct``: reads
  equal to the template out of the sites' reads; ``base_error_rate``: base errors out of the
  template's bases over every site). Pooled over replicates they carry Clopper–Pearson
  intervals at Korn & Graubard's effective number of trials, the runs as clusters
  (:func:`chiptwin.detection.stats.rate_estimate`): a read's base errors clump, and with
  ``vary_chip = true`` a run's sites share a chip. With ``vary_chip = false`` every interval is
  conditional on that one chip.
- ``mean``: a number per run (``snr_power``, ``memory_peak_frames``, …), summarised by its mean
  with a Student-t interval over replicates.

``snr_loss_db`` is derived per point: ``10·log10(mean SNR_ref / mean SNR)`` from the power SNR of
the point's rows and of its reference point's rows (``study.reference``), with a delta-method
interval (:func:`chiptwin.detection.stats.loss_db_interval`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from chiptwin.config import Scenario
    from chiptwin.twin.runner import Result


@dataclass(frozen=True)
class Metric:
    """One entry of the catalogue."""

    name: str
    kind: str  # "rate", "mean" or "loss" (derived from snr_power and the reference)
    unit: str
    doc: str
    extract: Callable[[Result], Any] | None = None
    pyro_only: bool = False
    needs_fixed: bool = False


def edit_distance(a: str, b: str) -> int:
    """Levenshtein distance: substitutions, insertions and deletions turning ``a`` into ``b``.

    Per-base error counting for sequencing reads (insertions and deletions are the dominant
    pyrosequencing errors, at homopolymers).
    """
    prev = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        cur = [i]
        for j, cb in enumerate(b, 1):
            cur.append(min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (ca != cb)))
        prev = cur
    return prev[-1]


def _calls(r: Result) -> tuple[int, int]:
    true = r.summary["true_sequence"]
    reads = r.summary["called_sequences"]
    return sum(c == true for c in reads), len(reads)


def _base_errors(r: Result) -> tuple[int, int]:
    """Errors per read clamp at the template length, so ``k ≤ n`` (a read of pure noise is
    every base wrong, not more)."""
    true = r.summary["true_sequence"]
    reads = r.summary["called_sequences"]
    errors = sum(min(edit_distance(c, true), len(true)) for c in reads)
    return errors, len(true) * len(reads)


def _flow_value_error(r: Result) -> float:
    true_n = np.array([f["true_n"] for f in r.summary["flows"]], dtype=float)
    return float(np.max(np.abs(r.arrays["flow_values"] - true_n[None, :])))


def _detected(r: Result) -> tuple[int, int]:
    sites = r.summary["sites"]
    return sum(s["detected"] for s in sites), len(sites)


def _dsp_max_err(r: Result) -> float:
    return float(r.summary["dsp"]["error_vs_float"]["max_abs_err_lsb"])


def _chip(key: str) -> Callable[[Result], float]:
    return lambda r: float(r.summary["chip"][key])


def _min_site(key: str) -> Callable[[Result], float]:
    return lambda r: float(min(s[key] for s in r.summary["sites"]))


def _section(section: str, key: str) -> Callable[[Result], float]:
    return lambda r: float(r.summary[section][key])


def _energy_per_base(r: Result) -> float:
    """nJ per Q20 base; infinite when the run reads none (the summary's None)."""
    value = r.summary["cost"]["energy_per_base_nj"]
    return float("inf") if value is None else float(value)


def _reads(key: str, stat: str) -> Callable[[Result], float]:
    return lambda r: float(r.summary["reads"][key][stat])


def _read_accuracy(r: Result) -> tuple[int, int]:
    """Correct bases of the sites' reads within the flows they call: template bases read
    minus errors, of the bases called (at least the template's, clamped)."""
    reads = r.summary["reads"]
    n = sum(min(s["bases"], s["template_bases"]) for s in reads["sites"])
    return max(n - reads["errors"], 0), max(n, 1)


def _homopolymer_errors(r: Result) -> tuple[int, int]:
    """Miscalled flows among the flows that read a homopolymer of 2 bases or more."""
    rows = [h for h in r.summary["reads"]["homopolymer_errors"] if h["length"] >= 2]
    return (sum(h["over_calls"] + h["under_calls"] for h in rows),
            max(sum(h["flows"] for h in rows), 1))


_METRICS = [
    Metric("q20_read_length", "mean", "bases", "median over the sites of the read length at "
           "Q20 (the most bases whose stated error probabilities sum to ≤ 1 % of them)",
           _reads("q20_read_length", "median"), pyro_only=True),
    Metric("q20_read_length_p10", "mean", "bases", "10th percentile over the sites of the read "
           "length at Q20 (nine sites in ten read at least this)",
           _reads("q20_read_length", "p10"), pyro_only=True),
    Metric("read_length_99", "mean", "bases", "median over the sites of the read length at "
           "99 % accuracy (errors against the template ≤ 1 % of the bases)",
           _reads("read_length_99", "median"), pyro_only=True),
    Metric("read_accuracy", "rate", "bases", "bases called right, of the bases the sites' reads "
           "call within the template (flow-space errors)", _read_accuracy, pyro_only=True),
    Metric("homopolymer_error_rate", "rate", "flows", "miscalled flows (over- or under-calls) "
           "among the flows reading a homopolymer of ≥ 2 bases", _homopolymer_errors,
           pyro_only=True),
    Metric("calls_correct", "rate", "reads", "reads equal to the whole template, of all sites' "
           "reads (1 fmol headline: the chip calls the template)", _calls, pyro_only=True),
    Metric("base_error_rate", "rate", "bases", "per-base errors (edit distance of each called "
           "read to the template, clamped at its length) of the template's bases over all "
           "sites", _base_errors, pyro_only=True),
    Metric("sites_detected", "rate", "sites", "sites whose signed amplitude SNR reaches "
           "√run.detection_snr_power (light adds: a negative estimate is no detection)",
           _detected),
    Metric("results_valid", "rate", "runs", "runs whose figures are trustworthy (no memory "
           "overflow, DSP keeping up, no ADC clipping)",
           lambda r: (int(r.summary["results_valid"]), 1)),
    Metric("snr_power", "mean", "1", "power SNR Q²/σ² (paper eq. 22), minimum over sites",
           _min_site("snr_power")),
    Metric("snr_amplitude", "mean", "1", "amplitude SNR Q/σ, minimum over sites",
           _min_site("snr_amplitude")),
    Metric("snr_loss_db", "loss", "dB", "10·log10(SNR_ref/SNR) of the mean power SNR against "
           "the reference point (study.reference)"),
    Metric("flow_value_error", "mean", "incorporations", "max |normalised flow value − true "
           "incorporations| over flows and sites", _flow_value_error, pyro_only=True),
    Metric("memory_peak_frames", "mean", "frames", "most raw frames held in frame memory at once",
           _chip("memory_peak_frames")),
    Metric("memory_capacity_frames", "mean", "frames", "raw frames the frame memory holds",
           _chip("memory_capacity_frames")),
    Metric("frames_dropped", "mean", "frames", "frames lost to a full frame memory",
           _chip("overflows")),
    Metric("dsp_utilization", "mean", "1", "DSP busy time / active time", _chip("dsp_utilization")),
    Metric("overflows", "mean", "events", "DSP register saturations + wraps",
           lambda r: float(sum(r.summary["dsp"]["overflow_total"].values()))),
    Metric("adc_clipped", "mean", "samples", "ADC samples at code 0 or full scale",
           _chip("adc_clipped_samples")),
    Metric("adc_power_w", "mean", "W", "the ADCs' average power: every pixel's 2M conversions a "
           "frame at the Schreier FOM's energy per conversion ([chip.adc] fom_schreier_db, at the "
           "bits' ideal SNDR 6.02 N + 1.76 dB) over the frame period", _chip("adc_power_w")),
    Metric("adc_energy_per_frame_j", "mean", "J", "the ADCs' energy per frame (every pixel's 2M "
           "conversions)", _chip("adc_energy_per_frame_j")),
    # what the chip costs in silicon (chiptwin.chip.silicon, [chip.cost]) and what it yields
    Metric("area_mm2", "mean", "mm²", "die area: pixel array, converters, frame memory, DSP, "
           "readout periphery and pads ([chip.cost])", _section("cost", "area_mm2")),
    Metric("power_mw", "mean", "mW", "average power over the run: pixel bias, converters "
           "(Schreier FOM), memory traffic, DSP operations, periphery and I/O ([chip.cost])",
           _section("cost", "power_mw")),
    Metric("energy_per_base_nj", "mean", "nJ", "the run's energy (power × duration) per Q20 "
           "base; infinite when it reads none", _energy_per_base, pyro_only=True),
    Metric("q20_bases_per_run", "mean", "bases", "Q20 bases the chip's sites read in the run "
           "(each site's read length at Q20, summed)", _section("throughput",
                                                                "q20_bases_per_run"),
           pyro_only=True),
    Metric("q20_bases_per_hour", "mean", "bases/h", "Q20 bases per hour of run time "
           "(run.duration_s)", _section("throughput", "q20_bases_per_hour"), pyro_only=True),
    Metric("q20_bases_per_hour_mm2", "mean", "bases/h/mm²", "Q20 bases per hour per mm² of die",
           _section("throughput", "q20_bases_per_hour_mm2"), pyro_only=True),
    Metric("sites_called_frac", "mean", "1", "share of sites called: pyrosequencing, the whole "
           "template read right (the share calls_correct counts); an assay, detected (the "
           "share sites_detected counts)", _section("throughput", "sites_called_frac")),
    Metric("sites_per_mm2", "mean", "1/mm²", "sites called (as sites_called_frac) per mm² of die",
           _section("throughput", "sites_per_mm2")),
    Metric("dsp_max_err_lsb", "mean", "LSB", "max |fixed − float| DSP output error (the run "
           "computes the float reference beside the fixed chain)", _dsp_max_err,
           needs_fixed=True),
]

#: The catalogue, by name.
CATALOGUE: dict[str, Metric] = {m.name: m for m in _METRICS}


def row_metrics(names: tuple[str, ...]) -> tuple[str, ...]:
    """The per-run metrics a study stores: those asked for, ``snr_power`` for a loss, and the
    capacity beside the peak occupancy (for the memory plot)."""
    out = [n for n in names if CATALOGUE[n].kind != "loss"]
    if "snr_loss_db" in names and "snr_power" not in out:
        out.append("snr_power")
    if "memory_peak_frames" in names and "memory_capacity_frames" not in out:
        out.append("memory_capacity_frames")
    return tuple(out)


def measure(result: Result, names: tuple[str, ...]) -> dict[str, Any]:
    """Every per-run metric of ``names`` for one run: ``[k, n]`` for rates, a float otherwise."""
    out: dict[str, Any] = {}
    for name in names:
        value = CATALOGUE[name].extract(result)
        out[name] = list(value) if isinstance(value, tuple) else value
    return out


def check_metric_applies(name: str, s: Scenario, study: Any) -> str | None:
    """Why ``name`` cannot be computed on this study's scenario, or None."""
    m = CATALOGUE[name]
    if m.pyro_only and s.assay.kind != "pyrosequencing":
        return f"needs base calls; the scenario's assay kind is {s.assay.kind!r}"
    if m.needs_fixed:
        levels = {v for a in study.axes for v in a.values
                  if a.key in ("chip.dsp.mode", "run.fidelity.dsp")} or {s.dsp_level}
        if "float" in levels or s.run.fidelity.photons == "expected":
            return ("compares the fixed DSP with float: needs chip.dsp.mode = 'fixed' (or "
                    "'rtl') at every point and binned or events photons")
    return None
