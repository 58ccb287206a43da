"""From the chip model's outputs to the summary: per-site figures, base calls, chip figures.

:func:`detect` turns the DSP outputs (in electrons, with their propagated variances) into the
``sites``, ``flows``, ``chip``, ``cost`` and ``throughput`` entries of ``summary.json`` and the
arrays beside it. The statistics themselves (SNR, window sums) are pure functions in
:mod:`chiptwin.detection`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin.config import Scenario, ScenarioError
from chiptwin.detection import snr, window_sums
from chiptwin.detection.reads import TAIL_FLOWS
from chiptwin.kinetics import pyro
from chiptwin.twin import chip_cost, dose_response, saturation, stages
from chiptwin.twin.optics_summary import optics_figures
from chiptwin.twin.programs import program_figures
from chiptwin.twin.reads import call_reads, caller_input, read_figures

if TYPE_CHECKING:
    from chiptwin.chip import ChipRun, Schedule
    from chiptwin.dsp.pipeline import Pipeline
    from chiptwin.twin.scene import ChainOutput, Scene

#: Chip flags under which per-site figures and calls are not to be trusted.
INVALIDATING_FLAGS = frozenset({"memory_overflow", "dsp_cannot_keep_up", "adc_clipped"})


def light_decay_per_s(s: Scenario) -> float | None:
    """k of the matched filter, or None for the plain sum (``run.light_estimator``)."""
    if s.run.light_estimator != "matched":
        return None
    return {"pyrosequencing": s.assay.k_a_per_s, "atp": s.assay.turnover_per_s}.get(
        s.assay.kind, 0.0)  # constant light: the matched filter is the sum


def detect(s: Scenario, scene: Scene, out: ChainOutput
           ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Per-site estimates, decisions, base calls, and the chip's figures."""
    sch = scene.sch
    rc = stages.site_pixels(s)
    idx = stages.site_pixel_indices(s)
    n_avg = s.chip.dsp.average_frames
    cols = out.columns(idx)
    arrays: dict[str, np.ndarray] = {
        "block_t_s": out.block_t_s, "site_pixel_index": idx,
        "site_signal_e": out.value_e[:, cols].T / 1.0,
        "site_pixel_photons": scene.coupling[idx] @ scene.site_photons,
        "site_photons": scene.site_photons,
    }
    summary: dict[str, Any] = {}
    if s.assay.kind == "pyrosequencing":
        sites = _pyro_sites(s, out, idx, summary, arrays)
    else:
        edges = np.array([s.assay.start_s, s.run.duration_s])
        sums, var = window_sums(out.block_t_s, out.value_e[:, cols], out.var_e2[:, cols],
                                out.dark_var_e2[idx], n_avg, edges, light_decay_per_s(s))
        sites = _site_rows(s, rc, sums[0], np.sqrt(var[0]), out, idx)
        for site, sd in zip(sites, np.sqrt(var[0]), strict=True):
            site["signal_sd_e"] = float(sd)  # the window total is itself the estimate
    if out.saturation_s is not None:
        for i, site in enumerate(sites):
            t = out.saturation_s[:, i]
            site["saturated_frames"] = int(np.isfinite(t).sum())
            site["first_saturation_s"] = float(t[np.isfinite(t)][0]) if site[
                "saturated_frames"] else None
    summary["sites"] = sites
    summary["array"] = array_figures(summary, sites)
    if s.sites.amounts_fmol:
        _require_site_amounts(s, scene)
        summary["dose_response"], dose_arrays = dose_response.dose_response_figures(
            s, sites, expected_site_signal(s, out, idx))
        arrays.update(dose_arrays)
    arrays["site_snr_power"] = np.array([site["snr_power"] for site in sites])
    if "called_sequences" in summary:
        arrays["site_called_right"] = np.array(
            [c == summary["true_sequence"] for c in summary["called_sequences"]])
    peak, frame = out.peak_block, out.peak_frame_e
    if frame is None:  # every pixel kept: the brightest output is one of them
        peak = int(np.argmax(out.value_e[:, cols].sum(axis=1))) if len(out.value_e) else 0
        frame = out.value_e[peak] if len(out.value_e) else np.zeros(s.chip.n_pixels)
    arrays["peak_frame_e"] = frame.reshape(s.chip.rows, s.chip.cols)
    arrays["peak_frame_t_s"] = np.array(out.block_t_s[peak] if len(out.block_t_s) else 0.0)
    arrays["memory_t_s"] = np.array([t for t, _ in out.chip.occupancy]) / 1e9
    arrays["memory_frames"] = np.array([o for _, o in out.chip.occupancy])
    summary["chip"] = chip_figures(s, sch, out.chip)
    summary["chip"]["adc_clipped_samples"] = out.adc_clipped_samples
    summary["chip"]["full_well_pixel_frames"] = out.full_well_pixel_frames
    if out.adc_clipped_samples:
        summary["chip"]["flags"].append("adc_clipped")
    if out.full_well_pixel_frames:
        summary["chip"]["flags"].append("full_well")
    summary["dsp"] = dsp_figures(out.dsp)
    optics_section = scene.once("optics", lambda: optics_figures(s, scene.coupling))
    if optics_section is not None:
        summary["optics"] = optics_section
    section = saturation.saturation_figures(s, scene, out, idx)
    if section is not None:
        section["cost"] = saturation.frame_cost(s, summary["chip"])
        summary["saturation"] = section
    program_figures(s, scene, out, summary, arrays)  # [chip.dsp] program (chiptwin.twin.programs)
    summary["cost"] = chip_cost.cost_figures(s, sch, summary)  # silicon area and power
    summary["throughput"] = chip_cost.throughput_figures(s, summary, summary["cost"])
    # A dropped frame makes the DSP average non-consecutive frames, as the chip would; the
    # figures are still reported, but not as trustworthy.
    summary["results_valid"] = not set(summary["chip"]["flags"]) & INVALIDATING_FLAGS
    summary["light_estimator"] = s.run.light_estimator
    return summary, arrays


def expected_site_signal(s: Scenario, out: ChainOutput, idx: np.ndarray) -> np.ndarray:
    """Each site's ``signal_e`` as the DSP's expected outputs (``out.mean_e``, no noise) give it
    through the same estimator: the light window's total, or (pyrosequencing) the mean of the
    key's single-base flow totals. Gain non-uniformity and cross-talk included. Unit: e⁻."""
    a, cols = s.assay, out.columns(idx)
    zero = np.zeros(len(idx))
    if a.kind == "pyrosequencing":
        edges = a.start_s + a.flow_period_s * np.arange(a.n_flows + 1)
    else:
        edges = np.array([a.start_s, s.run.duration_s])
    sums, _ = window_sums(out.block_t_s, out.mean_e[:, cols], np.zeros_like(out.mean_e[:, cols]),
                          zero, s.chip.dsp.average_frames, edges, light_decay_per_s(s))
    if a.kind != "pyrosequencing":
        return sums[0]
    ones = np.flatnonzero(pyro.key_flow_counts(a.key, a.flow_order) == 1)
    return sums[ones].mean(axis=0)


def _require_site_amounts(s: Scenario, scene: Scene) -> None:
    """Refuse figures from a scene whose light ignores ``[sites] amounts_fmol``: a run path that
    prepares the scene without :func:`chiptwin.twin.stages.scale_source` would report a dose
    response of equal amounts."""
    if not dose_response.honours_amounts(s, scene):
        raise ScenarioError(s.source, "sites.amounts_fmol", str(s.sites.amounts_fmol)[:40],
                            "per-site amounts are not applied by this run path (its scene was "
                            "prepared without chiptwin.twin.stages.scale_source)")


def _site_rows(s: Scenario, rc: np.ndarray, signal: np.ndarray, noise: np.ndarray,
               out: ChainOutput, idx: np.ndarray, peak_window: np.ndarray | None = None,
               ) -> list[dict]:
    """One summary row per site.

    ``peak_frame_*`` is the brightest single DSP output among those in ``peak_window`` (all by
    default; for pyrosequencing the key's single-base flows, so it is a 1-mer peak). Its signal
    is the expected value, so its SNR is a property of the chip, not of one noisy frame.
    """
    p, a = snr(signal, noise)
    cols = out.columns(idx)
    values = out.mean_e[:, cols] if len(out.mean_e) else np.zeros((1, len(idx)))
    frame_snr = (values**2 / (out.var_e2[:, cols] + out.dark_var_e2[idx]) if len(out.value_e)
                 else np.zeros_like(values))
    masked = np.where(peak_window[:, None], values, -np.inf) if peak_window is not None else values
    peak = np.argmax(masked, axis=0)
    return [
        {"id": i, "pixel": [int(r), int(c)], "signal_e": float(signal[i]),
         "noise_e": float(noise[i]), "snr_power": float(p[i]), "snr_amplitude": float(a[i]),
         # one-sided: light adds to the signal; a strongly negative estimate (|a|² above the
         # threshold) is no detection (counted as one, the no-light false-detection rate doubled)
         "detected": bool(a[i] >= math.sqrt(s.run.detection_snr_power)),
         "peak_frame_signal_e": float(values[peak[i], i]),
         "peak_frame_snr_power": float(frame_snr[peak[i], i])}
        for i, (r, c) in enumerate(rc)
    ]


def _pyro_sites(s, out: ChainOutput, idx, summary, arrays) -> list[dict]:
    """Flow values per site, normalised by the key's 1-mers, and the called sequences.

    A site's ``signal_e`` is its 1-mer level, the mean of the key's K single-base flow totals;
    ``noise_e`` is the noise of ONE 1-mer flow (rms over those flows), so ``snr_*`` is the SNR
    a single-base call faces. ``signal_sd_e`` is the standard deviation of the 1-mer level
    itself: the mean of K flows whose shared dark reference correlates them (≈ 72 % of a flow's
    variance on pyro_1fmol), so it is √(Σ independent/K² + (Σ a_i/K)²·σ²_dark), between
    noise_e/√K and noise_e (pyro_1fmol: 0.90 · noise_e; checked by Monte Carlo).
    """
    a = s.assay
    nucs, n_inc = stages.flow_program(s)
    edges = a.start_s + a.flow_period_s * np.arange(a.n_flows + 1)
    n_avg, decay = s.chip.dsp.average_frames, light_decay_per_s(s)
    cols = out.columns(idx)
    sums, var = window_sums(out.block_t_s, out.value_e[:, cols], out.var_e2[:, cols],
                            out.dark_var_e2[idx], n_avg, edges, decay)
    # a_i²: each window's weight on the (common) dark reference, for unit dark variance
    zero = np.zeros((len(out.block_t_s), 1))
    _, a2 = window_sums(out.block_t_s, zero, zero, np.ones(1), n_avg, edges, decay)
    key_n = pyro.key_flow_counts(a.key, a.flow_order)
    ones = np.flatnonzero(key_n == 1)
    coherent = np.sqrt(a2[ones, 0]).sum() / len(ones)
    flow_values, calls, signal, noise, level_sd = [], [], [], [], []
    for j, pix in enumerate(idx):
        independent = var[ones, j] - a2[ones, 0] * out.dark_var_e2[pix]
        level_sd.append(float(np.sqrt(independent.sum() / len(ones) ** 2
                                      + coherent**2 * out.dark_var_e2[pix])))
        ref = float(np.mean(sums[ones, j]))
        norm = pyro.normalise_flows(sums[:, j], key_n) if ref > 0 else np.zeros(a.n_flows)
        flow_values.append(norm)
        calls.append(pyro.call_sequence(nucs, norm))
        signal.append(ref)
        noise.append(float(np.sqrt(np.mean(var[ones, j]))))
    true_seq = "".join(nuc * int(n) for nuc, n in zip(nucs, n_inc, strict=True))
    summary["true_sequence"] = true_seq
    summary["template_length"] = len(a.template)  # the flows may reach only its first bases
    summary["called_sequence"] = calls[0][0]
    summary["called_sequences"] = [c for c, _ in calls]
    summary["flows"] = [
        {"nucleotide": nucs[f], "value": float(flow_values[0][f]),
         "called_n": int(calls[0][1][f]), "true_n": int(n_inc[f]),
         "signal_e": float(sums[f, 0]), "noise_e": float(np.sqrt(var[f, 0]))}
        for f in range(a.n_flows)
    ]
    arrays["flow_values"] = np.array(flow_values)
    arrays["flow_sums_e"] = sums.T
    values = caller_input(s, arrays["flow_values"])
    reads = call_reads(s, values, var, np.array(signal), np.array(level_sd))
    summary["reads"], read_arrays = read_figures(s, values, reads, n_inc)
    arrays.update(read_arrays)
    if a.caller == "dephase":  # the scene's caller spells the reads the headline compares
        _dephased_sequences(summary, nucs, read_arrays)
    flow_of_block = np.searchsorted(edges, out.block_t_s, side="right") - 1
    sites = _site_rows(s, stages.site_pixels(s), np.array(signal), np.array(noise), out, idx,
                       peak_window=np.isin(flow_of_block, ones))
    for site, sd in zip(sites, level_sd, strict=True):
        site["signal_sd_e"] = sd
    return sites


def _dephased_sequences(summary: dict, nucs: list[str], read_arrays: dict) -> None:
    """``called_sequence(s)``, ``true_sequence`` and the flows' ``called_n`` from the dephase
    caller's reads, over the flows it calls (its last flows are left uncalled)."""
    calls, true_n = read_arrays["read_calls"], read_arrays["read_true_n"].copy()
    true_n[max(len(nucs) - TAIL_FLOWS, 0):] = 0

    def spell(row: np.ndarray) -> str:
        return "".join(n * int(c) for n, c in zip(nucs, row, strict=True))

    summary["true_sequence"] = spell(true_n)
    summary["called_sequences"] = [spell(row) for row in calls]
    summary["called_sequence"] = summary["called_sequences"][0]
    for f, flow in enumerate(summary["flows"]):
        flow["called_n"] = int(calls[0, f])


#: Percentiles of the per-site SNR given in ``summary['array']``.
SNR_PERCENTILES = (0, 5, 25, 50, 75, 95, 100)


def array_figures(summary: dict[str, Any], sites: list[dict]) -> dict[str, Any]:
    """The array as a whole: how many sites, the fraction detected and (pyrosequencing) called
    right (the whole called sequence equals the template's), and the per-site power SNR's
    distribution (percentiles, mean, in dB too)."""
    snr_p = np.array([site["snr_power"] for site in sites], dtype=np.float64)
    pct = np.percentile(snr_p, SNR_PERCENTILES) if len(snr_p) else np.full(7, np.nan)
    out: dict[str, Any] = {
        "n_sites": len(sites),
        "fraction_detected": float(np.mean([site["detected"] for site in sites])) if sites
        else 0.0,
        "snr_power_percentiles": {f"p{q}": float(v) for q, v in zip(SNR_PERCENTILES, pct,
                                                                      strict=True)},
        "snr_power_mean": float(snr_p.mean()) if len(snr_p) else float("nan"),
        "snr_power_median_db": float(10 * np.log10(pct[3])) if len(snr_p) and pct[3] > 0
        else None,
    }
    if "called_sequences" in summary:
        right = [c == summary["true_sequence"] for c in summary["called_sequences"]]
        out["sites_called_right"] = int(sum(right))
        out["fraction_called_right"] = float(np.mean(right)) if right else 0.0
    return out


def chip_figures(s: Scenario, sch: Schedule, chip: ChipRun) -> dict[str, Any]:
    """Frames, memory, DSP load and the flags, for ``summary['chip']``."""
    active_ns = max(sch.n_frames * sch.frame_period_ns, 1)
    slow = sch.dsp_ns_per_frame > sch.frame_period_ns
    lag_ns = max(0, chip.end_ns - chip.last_write_ns)
    flags = []
    if chip.dropped:
        flags.append("memory_overflow")
    if slow or chip.unprocessed_frames >= sch.block_frames:
        flags.append("dsp_cannot_keep_up")
    adc = s.chip.adc
    conversions = s.chip.n_pixels * 2 * sch.cms_samples  # reset and signal samples, every pixel
    energy_j = conversions * adc.energy_per_conversion_J
    return {
        "frames": sch.n_frames,
        "adc_bits": adc.bits,
        # the cost of a bit (Murmann's ADC survey): Schreier FOM at the bits' ideal SNDR
        "adc_fom_schreier_db": adc.fom_schreier_db,
        "adc_energy_per_conversion_j": adc.energy_per_conversion_J,
        "adc_energy_per_frame_j": energy_j,
        "adc_power_w": energy_j / (sch.frame_period_ns / 1e9),
        "memory_bits": s.chip.memory.capacity_bits,
        "memory_capacity_frames": sch.memory_frames,
        "memory_peak_frames": chip.memory_peak_frames,
        "dsp_utilization": chip.dsp_busy_ns / active_ns,
        "dsp_lag_s": lag_ns / 1e9,
        "overflows": len(chip.dropped),
        "unprocessed_frames": chip.unprocessed_frames,
        "frame_period_s": sch.frame_period_ns / 1e9,
        "conversion_time_s": sch.t_conv_ns / 1e9,
        "dsp_time_per_frame_s": sch.dsp_ns_per_frame / 1e9,
        "flags": flags,
    }


def dsp_figures(dsp: Pipeline) -> dict[str, Any]:
    """The DSP level, its registers, overflow counts and (when asked) fixed-vs-float error."""
    out: dict[str, Any] = {"level": dsp.level}
    if dsp.chain is not None:
        out["registers"] = {step: {reg: fmt.q for reg, fmt in regs.items()}
                            for step, regs in dsp.chain.registers().items()}
    out["overflow"] = dsp.overflow
    out["overflow_total"] = {k: sum(c[k] for c in dsp.overflow.values()) for k in ("sat", "wrap")}
    if dsp.error is not None:
        out["error_vs_float"] = dsp.error.summary()
    return out
