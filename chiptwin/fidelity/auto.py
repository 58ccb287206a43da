"""``auto`` fidelity's calibrations: the runs of a scene that measure a level's error.

The levels, the choice and the estimates cache are :mod:`chiptwin.twin.levels` (below the twin's
runner, which needs them to run a resolved scenario); this module runs scenes, so it sits above
the twin: :class:`Calibrations` measures what the cache lacks (the expected-level runs of the
kinetics, optics and ADC calibrations, the analytic bounds of the photons, shot and DSP levels
on the scene's own figures), :func:`resolve` resolves a scenario's ``auto`` keys with it and
:func:`run` is :func:`chiptwin.twin.runner.run` with ``auto`` resolved so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.chip import Recorder
from chiptwin.config import Scenario
from chiptwin.config.budget import window_edges
from chiptwin.detection import window_sums
from chiptwin.twin import runner, stages
from chiptwin.twin.levels import (
    EXPECTED_SDS,
    FIGURES,
    SEEN_SNR_POWER,
    AutoChoice,
    CachedEstimates,
    Estimate,
    figure_errors,
    figures,
    gaussian_moment_bounds,
    with_levels,
)
from chiptwin.twin.levels import resolve as _resolve
from chiptwin.twin.results import detect, light_decay_per_s


def resolve(s: Scenario, cache: Path | None = None) -> tuple[Scenario, AutoChoice | None]:
    """``s`` with every ``auto`` stage set to a level, and the choice; ``(s, None)`` when no
    stage is ``auto``. Levels whose error on this scene is not in ``cache`` (default in the
    user cache, :func:`chiptwin.twin.levels.cache_path`) are calibrated and cached."""
    return _resolve(s, cache, Calibrations)


def run(scenario: Scenario | str | Path, overrides: Iterable[str] = (), seed: int | None = None,
        progress: Callable[[int, int], None] | None = None) -> runner.Result:
    """:func:`chiptwin.twin.runner.run` with ``auto`` keys resolved by :func:`resolve`: the
    ``run`` of the CLI and of ``chiptwin.run``."""
    return runner.run(scenario, overrides, seed, progress, resolve=resolve)


class Calibrations(CachedEstimates):
    """Each level's :class:`Estimate` on one scene, calibrated when the cache does not hold it
    (the expected-level run the calibrations share is made once)."""

    def __init__(self, s: Scenario, ref: dict[str, str], cache: Path | None) -> None:
        super().__init__(s, ref, cache)
        self._runs: dict[tuple, _ExpectedRun] = {}

    def calibrate(self, stage: str, level: str) -> Estimate:
        """The level's error on this scene, measured (kinetics, optics) or bounded."""
        return getattr(self, "_" + stage)(level)

    # -- calibrated stages -------------------------------------------------------------------

    def _kinetics(self, level: str) -> Estimate:
        return self._calibrated("kinetics", level, "calibration: the expected-level run at "
                                f"{level} against {self.ref['kinetics']}")

    def _optics(self, level: str) -> Estimate:
        est = self._calibrated("optics", level, f"calibration: the expected-level run at {level} "
                               f"against {self.ref['optics']}")
        how = est.how + (f"; psf cross-talk at the site pixels {_cross_talk_share(self.s):.3g} "
                         "of their light")
        if self.ref["optics"] == "raytrace":
            how += "; " + _raytrace_note(with_levels(self.s, self.ref))
        return Estimate(est.errors, how)

    def _adc(self, level: str) -> Estimate:
        keys = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}"
                         for k, v in self.s.chip.adc.as_built_keys.items())
        return self._calibrated("adc", level, f"calibration: the expected-level run with the "
                                f"ideal converter against the converter as built ({keys})")

    def _calibrated(self, stage: str, level: str, how: str) -> Estimate:
        base = self._expected_levels()  # its stage is at the reference: that side is the base
        cheap, ref = (self._expected({**base, stage: lv}) for lv in (level, self.ref[stage]))
        measured = figure_errors(cheap.figures, ref.figures)
        return Estimate({f: float(measured.get(f, 0.0)) for f in FIGURES}, how)  # no flows: 0

    # -- analytic stages ---------------------------------------------------------------------

    def _photons(self, level: str) -> Estimate:
        if level == "binned":  # against events
            return Estimate.exact("binned counts have the events level's law (Poisson counts "
                                  "of the same means, the same full-well clip)")
        base = self._expected(self._expected_levels())
        summary, out, e_per_lsb = base.summary, base.out, base.e_per_lsb
        sites = summary["sites"]
        k = EXPECTED_SDS
        signal_rel = max((st["signal_sd_e"] / abs(st["signal_e"]) for st in sites
                          if st["signal_e"]), default=math.inf)
        errors = {"signal_rel": k * signal_rel, "noise_rel": 0.0,
                  "dsp_lsb": k * float(np.sqrt(np.max(out.var_e2, initial=0.0))) / e_per_lsb}
        flows = summary.get("flows")
        if flows:  # a flow value v = F / K: its spread from the flow's and the key's
            key_e, key_sd = sites[0]["signal_e"], sites[0]["signal_sd_e"]
            errors["flow_value_abs"] = k * max(
                math.hypot(f["noise_e"], f["value"] * key_sd) / key_e for f in flows)
        else:
            errors["flow_value_abs"] = 0.0
        return Estimate(_with_snr(errors), f"expected reports each figure's mean, the "
                        f"reference's figure strays {k:g} σ from it (σ_signal/signal "
                        f"{signal_rel:.3g})")

    def _shot(self, level: str) -> Estimate:
        lam = self._min_site_mean_e()
        dm, dv = gaussian_moment_bounds(lam)
        base = self._expected(self._expected_levels())
        summary, e_per_lsb = base.summary, base.e_per_lsb
        n_avg, n_dark = self.s.chip.dsp.average_frames, self.s.chip.dsp.n_dark_frames
        frames = window_gain(base)  # a window total's weight on its pixel-frame counts
        shift, var = 2 * frames * dm, 2 * frames**2 * dv  # light frames and the dark reference
        signal = _seen_signal(summary)
        flows = summary.get("flows") or []
        top = max((abs(f["value"]) for f in flows), default=0.0)
        spread = EXPECTED_SDS * math.sqrt(var) / signal
        errors = {"signal_rel": shift / signal, "noise_rel": 0.0,
                  "flow_value_abs": (1 + top) * (shift / signal + spread) if flows else 0.0,
                  "dsp_lsb": (2 * dm + EXPECTED_SDS * math.sqrt(dv * (1 / n_avg + 1 / n_dark)))
                  / e_per_lsb}
        errors = _with_snr(errors)
        snr_rel = (2 * signal * shift + shift**2 + var) / signal**2
        errors["snr_rel"] = snr_rel
        errors["snr_db"] = 10 * math.log10(1 + snr_rel)
        return Estimate(errors, f"the rounded normal's mean within {dm:.2g} e⁻ and variance "
                        f"within {dv:.2g} e⁻² of Poisson's at every mean ≥ {lam:.4g} e⁻ (the "
                        f"smallest of a site pixel in a frame), through a window of {frames:g} "
                        "pixel-frames and the dark reference; the noise figure is the Poisson "
                        "moments' at both levels")

    def _dsp(self, level: str) -> Estimate:
        if level == "fixed":  # against rtl
            return Estimate.exact("fixed equals the RTL bit for bit (co-simulated)")
        from chiptwin.dsp.fixed import accumulator_bits_needed
        from chiptwin.dsp.pipeline import chain_for
        from chiptwin.dsp.program import DEFAULT_PROGRAM, is_default

        d = self.s.chip.dsp
        chain = chain_for(self.s.chip)
        if d.acc_bits and d.acc_bits < accumulator_bits_needed(chain.average.in_fmt,
                                                               d.average_frames):
            return Estimate(dict.fromkeys(FIGURES, math.inf),
                            f"the {d.acc_bits}-bit N-frame accumulator can wrap: fixed differs "
                            "from float without bound")
        lsb = _rounding_bound_lsb(chain)
        how = ("M, K, N powers of two: the fixed chain is exact" if lsb == 0 else
               f"the chain's rounding, at most {lsb:.3g} LSB per output")
        if not is_default(d.program):
            front_gain, later, broken = self._program_bound_lsb()
            if broken:
                return Estimate(dict.fromkeys(FIGURES, math.inf),
                                f"{broken} on this scene: fixed differs from float without "
                                "the analytic bound")
            lsb = lsb * front_gain + later
            further = [st for st in d.program if st not in DEFAULT_PROGRAM]
            how += (f", × {front_gain:.3g} through the program; its further stages "
                    f"({', '.join(further)}) at most {later:.3g} LSB at its output (their "
                    "analytic bounds on this scene's data, through the stages after each)")
        base = self._expected(self._expected_levels())
        gain = window_gain(base)
        how += (f"; × {gain:.4g} to a window total (the detection's sum of N-frame averages, "
                "its ℓ∞ gain on per-output errors)")
        total_e = lsb * base.e_per_lsb * gain
        signal = _seen_signal(base.summary)
        top = max((abs(f["value"]) for f in base.summary.get("flows") or []), default=1.0)
        errors = {"dsp_lsb": lsb, "signal_rel": total_e / signal, "noise_rel": 0.0,
                  "flow_value_abs": (1 + top) * total_e / signal}
        return Estimate(_with_snr(errors), how)

    def _program_bound_lsb(self) -> tuple[float, float, str | None]:
        """The chain's error gain to the program's output, the sum of the analytic bounds of the
        program's stages after the chain (kinetics, bin_rows, fir8, wiener: coefficient
        quantisation and rounding, which depend on the data) carried to its output, in the
        units the detection reads (ADC LSB of a window total: :meth:`chiptwin.dsp.
        program_pipeline.ProgramPipeline.error_gain`), from one fixed-point run of the scene
        with ``report_error``; and what breaks the bounds there, or None. Each stage's bound is
        in its own output LSB and passes through the stages after it: a sum in LSB of
        different formats (as once here) understates a Wiener equalizer's amplified error and
        overstates a kinetics stage's fine LSB. A register that saturated or wrapped anywhere
        in the run, a stage whose outputs clipped, or one that broke its bound leaves the error
        unbounded (a wrapped kinetics accumulator once passed as 0.5 LSB against 29,000)."""
        sv = with_levels(self.s, {**self.ref, "photons": "binned", "dsp": "fixed"})
        sv = replace(sv, chip=replace(sv.chip, dsp=replace(sv.chip.dsp, report_error=True)))
        summary = runner.run(sv).summary
        fig = summary["dsp_program"]
        bounds = fig.get("stage_error_bounds", {})
        broken = [f"{reg} overflowed ({c['sat']} saturated, {c['wrap']} wrapped)"
                  for reg, c in summary["dsp"]["overflow"].items() if c["sat"] or c["wrap"]]
        broken += [f"stage {st} clipped {b['n_clipped']} outputs" for st, b in bounds.items()
                   if b["n_clipped"]]
        broken += [f"stage {st} {'broke its bound' if b['bound_ok'] is False else 'overflowed'}"
                   for st, b in bounds.items() if b["bound_ok"] is not True]
        return (float(fig.get("front_error_gain", 1.0)),
                float(sum(b["bound_at_output"] for b in bounds.values())),
                "; ".join(broken) or None)

    # -- the scene at the expected level -----------------------------------------------------

    def _expected_levels(self) -> dict[str, str]:
        return {**self.ref, "photons": "expected", "dsp": "float", "shot": "poisson"}

    def _expected(self, levels: dict[str, str]) -> _ExpectedRun:
        """The scene at ``levels`` and the expected photon level, made once per levels."""
        key = tuple(sorted(levels.items()))
        if key not in self._runs:
            self._runs[key] = _ExpectedRun.of(self.s, levels)
        return self._runs[key]

    def _min_site_mean_e(self) -> float:
        base = self._expected(self._expected_levels())
        scene, s = base.scene, base.scenario
        idx = stages.site_pixel_indices(s)
        t_int, gain = s.chip.timing.t_int_s, s.chip.adc.gain_error
        lam, b = math.inf, scene.block_frames
        for start in range(0, scene.sch.n_frames, b):
            block = scene.pixel_block(t_int, gain, start, min(start + b, scene.sch.n_frames))
            lam = min(lam, float(np.min(block.mean_e[:, idx])))
        return lam


@dataclass
class _ExpectedRun:
    """A scene run at the expected photon level (no draws): its scene, chain output, summary
    and the ladder's figures."""

    scenario: Scenario
    scene: Any
    out: Any
    summary: dict[str, Any]
    figures: dict[str, np.ndarray]

    @property
    def e_per_lsb(self) -> float:
        return self.scene.sensor.e_per_lsb

    @classmethod
    def of(cls, s: Scenario, levels: dict[str, str]) -> _ExpectedRun:
        sv = with_levels(s, levels)
        scene = runner.prepare(sv)
        out = runner.simulate(sv, scene, "expected", runner.stage_rng(sv.scenario.seed, "pixel"),
                              Recorder(),
                       sites=stages.site_pixel_indices(sv))
        summary, arrays = detect(sv, scene, out)
        return cls(sv, scene, out, summary, figures(summary, arrays, scene.sensor.e_per_lsb))


def _seen_signal(summary: dict[str, Any]) -> float:
    """The smallest |signal| of the sites the relative figures are taken over (power SNR ≥
    :data:`~chiptwin.twin.levels.SEEN_SNR_POWER`, as the ladder compares them), in e⁻; every
    site's when none is seen."""
    sites = summary["sites"]
    seen = [st for st in sites if st["snr_power"] >= SEEN_SNR_POWER] or sites
    return min(abs(st["signal_e"]) for st in seen) or math.inf


def window_gain(run: _ExpectedRun) -> float:
    """The largest factor a window total (:func:`chiptwin.detection.window_sums`: ``N · c ·
    Σ_j w_j y_j`` over the window's DSP outputs) applies to an error of at most 1 in each
    output: ``max_window N · c · Σ_j |w_j|`` (the ℓ∞ norm of the estimator's row): 40 for
    crosstalk_microarray's plain sum (10 outputs of N = 4 frames); N for a kinetics program's
    one output a window. In frames, it is also the window total's weight on its pixel-frame
    counts (each output averages N of them)."""
    s, t = run.scenario, run.out.block_t_s
    ones = np.ones((len(t), 1))
    sums, _ = window_sums(t, ones, np.zeros_like(ones), np.zeros(1), s.chip.dsp.average_frames,
                          window_edges(s), light_decay_per_s(s))
    return float(np.max(np.abs(sums), initial=0.0))


def _with_snr(spent: dict[str, float]) -> dict[str, float]:
    """Add ``snr_rel`` (power SNR S²/N²) and ``snr_db`` from the signal and noise errors."""
    s, n = spent["signal_rel"], spent["noise_rel"]
    snr_rel = (1 + s) ** 2 / (1 - n) ** 2 - 1 if n < 1 else math.inf
    return {**spent, "snr_rel": snr_rel, "snr_db": 10 * math.log10(1 + snr_rel)}


def _rounding_bound_lsb(chain) -> float:
    """Largest |fixed − float| of an N-frame average, in ADC LSB, over every input the chain's
    formats hold: each divide step's rounding and its rounded reciprocal's error
    (:func:`chiptwin.dsp.errors.divide_bound`: M, K and N that are not powers of two; TRN rounds
    by up to a whole LSB), carried through the subtraction (CMS frame minus dark reference, its
    own rounding) and the averages (means of bounded errors). 0 when M, K and N are powers of
    two (the chain's extra fractional bits keep every step exact)."""
    from chiptwin.dsp.errors import divide_bound, subtract_bound

    cms = divide_bound(chain.cms)
    dark = cms + divide_bound(chain.dark)
    return cms + dark + subtract_bound(chain.background) + divide_bound(chain.average)


def _raytrace_note(s: Scenario) -> str:
    """The reference trace's own error, which a measured error against it includes."""
    r = stages.raytrace_result(s)
    idx = stages.site_pixel_indices(s)
    own = r.coupling[idx, np.arange(len(idx))]
    rel = np.max(r.stderr[idx, np.arange(len(idx))] / np.where(own > 0, own, np.inf))
    return (f"raytrace reference {int(r.n_rays.min())}–{int(r.n_rays.max())} rays per site, "
            f"own-pixel standard error ≤ {rel:.2%} (part of the measured error)")


def _cross_talk_share(s: Scenario) -> float:
    """The largest share of a site pixel's light that comes from other sites (psf coupling)."""
    c = stages.coupling(with_levels(s, {"optics": "psf"}))
    idx = stages.site_pixel_indices(s)
    rows = c[idx]
    rows = rows.toarray() if hasattr(rows, "toarray") else np.asarray(rows)
    total = rows.sum(axis=1)
    own = rows[np.arange(len(idx)), np.arange(len(idx))]
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0, 1 - own / total, 0.0)
    return float(np.max(share, initial=0.0))


__all__ = ["Calibrations", "resolve", "run"]
