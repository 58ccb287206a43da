"""Outputs of a run: ``summary.json``, ``run.nc`` (its arrays as one labelled dataset), PNG plots,
``report.md`` and, on request, ``chip.vcd`` (the chip's timing as a waveform), atomically.

Everything is written into a fresh temporary folder beside the target and renamed into place at the
end, so a crashed or refused run never leaves a half-written folder that looks complete.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin import __version__
from chiptwin.chip import Schedule
from chiptwin.chip.vcd import write_vcd
from chiptwin.config import ScenarioError
from chiptwin.config.outputs import check_out_dir, replacing
from chiptwin.report.dataset import DATASET_FILE, write_dataset
from chiptwin.report.read_plots import flow_chars, read_lines, read_plots, sff_reads
from chiptwin.report.sff import write_sff
from chiptwin.twin.figures import light_curves, memory_occupancy
from chiptwin.twin.figures import save_figure as _save
from chiptwin.twin.programs import program_plots

if TYPE_CHECKING:
    from chiptwin.twin.runner import Result


def write_outputs(result: Result, out_dir: str | Path, vcd: bool = False) -> Path:
    """Write every output of ``result`` into ``out_dir``, replacing a previous output whole.

    ``vcd``: also write the chip's event trace as ``chip.vcd`` (:mod:`chiptwin.chip.vcd`); a
    trace without every frame's steps is refused (:func:`check_vcd`), and nothing is written.
    """
    if vcd:
        check_vcd(result)
    out = check_out_dir(out_dir)
    with replacing(out) as tmp:
        (tmp / "summary.json").write_text(json.dumps(result.summary, indent=2) + "\n")
        frames, result.frames_path = result.frames_path, None  # [run] save_frames
        try:
            write_dataset(result, tmp / DATASET_FILE, frames)
        finally:
            if frames is not None:
                frames.unlink(missing_ok=True)
        if vcd:
            write_chip_vcd(result, tmp / VCD_FILE)
        if "read_calls" in result.arrays:  # pyrosequencing: every site's read, in SFF
            write_sff(tmp / "reads.sff", flow_chars(result.scenario), result.scenario.assay.key,
                      sff_reads(result.scenario, result.summary, result.arrays))
        plots = make_plots(result, tmp)
        (tmp / "report.md").write_text(report_markdown(result.summary, plots))
    return out


#: The chip's timing as a waveform, in a run's output folder (``chiptwin run --vcd``).
VCD_FILE = "chip.vcd"


def check_vcd(result: Result) -> None:
    """Refuse a VCD of a trace that lacks the frames' steps (reset, conversions, integration):
    ``Recorder(frame_steps=False)``, a study's replicates (``run_prepared(frame_steps=False)``).

    Raises
    ------
    ScenarioError
        Naming ``frame_steps``, the key that records them.
    """
    trace = result.trace
    if trace.events and trace.frame_steps:
        return
    what = "no chip trace" if not trace.events else "a chip trace without the frames' steps"
    raise ScenarioError(result.scenario.source, "--vcd",
                        "no events" if not trace.events else "frame_steps=False",
                        f"this result has {what} (reset, conversions, integration): run it "
                        "with frame_steps=True (chiptwin.run records them; a study's "
                        "replicates do not: run_prepared(..., frame_steps=True))")


def write_chip_vcd(result: Result, path: Path) -> None:
    """The chip's trace as a value change dump, ending when the run's frames end."""
    s = result.scenario
    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    end_ns = max(sch.n_frames * sch.frame_period_ns, result.trace.events[-1][0])
    write_vcd(result.trace.events, path, frame_steps=result.trace.frame_steps, end_ns=end_ns,
              comment=f"chiptwin run of {s.scenario.name}, seed {s.scenario.seed}",
              version=f"chiptwin {__version__}")


def make_plots(result: Result, folder: Path) -> list[tuple[str, str]]:
    """Light curve per site, a DSP frame image, memory occupancy and (pyrosequencing) the pyrogram.

    Returns
    -------
    list of (file name, caption).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, plots = result.arrays, []
    fig, ax = plt.subplots(figsize=(7, 3.5))
    n_sites = a["site_signal_e"].shape[0]
    drawn = min(n_sites, MAX_CURVES)
    light_curves(ax, a["block_t_s"], a["site_signal_e"][:drawn], [f"site {i}" for i in
                                                                   range(drawn)])
    ax.set(xlabel="time (s)", ylabel="signal per frame (e⁻)", title="Light curve at site pixels")
    if n_sites <= 8:
        ax.legend(fontsize=7)
    shown = "each site's pixel" if n_sites <= MAX_CURVES else f"the first {MAX_CURVES} sites"
    plots.append(_save(fig, folder, "light_curve.png", f"DSP output at {shown}"))
    if n_sites >= MIN_SITES_FOR_MAP:
        plots += _array_plots(result, folder)

    fig, ax = plt.subplots(figsize=(7, 3.5))
    # Symmetric log scale: the optical cross-talk into neighbours is orders below the site.
    norm = matplotlib.colors.SymLogNorm(linthresh=100.0, vmin=min(0.0, a["peak_frame_e"].min()),
                                        vmax=max(a["peak_frame_e"].max(), 1000.0))
    im = ax.imshow(a["peak_frame_e"], cmap="magma", interpolation="nearest", norm=norm)
    fig.colorbar(im, ax=ax, label="e⁻ per frame (symmetric log)")
    ax.set(title=f"DSP output frame at t = {float(a['peak_frame_t_s']):.1f} s", xlabel="column",
           ylabel="row")
    plots.append(_save(fig, folder, "frame.png", "The brightest DSP output frame"))

    if "flow_values" in a:
        fig, ax = plt.subplots(figsize=(7, 3.5))
        flows = result.summary["flows"]
        ax.bar(range(len(flows)), a["flow_values"][0], color="tab:green")
        ax.set_xticks(range(len(flows)), [f["nucleotide"] for f in flows], fontsize=7)
        ax.set(ylabel="normalised flow value", title="Pyrogram (site 0)")
        for n in range(1, int(np.max(a["flow_values"][0]) + 1.5)):
            ax.axhline(n, color="grey", lw=0.5, ls=":")
        plots.append(_save(fig, folder, "pyrogram.png", "Pyrogram of site 0"))

    if "reads" in result.summary:
        plots += read_plots(result, folder)
    if "dose_response" in result.summary:
        plots.append(_dose_response_plot(result.summary["dose_response"], a, folder))
    if any(site.get("fills") for site in result.summary.get("saturation", {}).get("sites", [])):
        plots.append(_saturation_plot(result.summary["saturation"], folder))

    fig, ax = plt.subplots(figsize=(7, 2.5))
    memory_occupancy(ax, a["memory_t_s"], a["memory_frames"],
                     result.summary["chip"]["memory_capacity_frames"])
    ax.set(xlabel="time (s)", ylabel="frames", title="Frame memory occupancy")
    plots.append(_save(fig, folder, "memory.png", "Frame memory occupancy against its capacity"))
    plots += program_plots(result, folder)  # [chip.dsp] program figures (chiptwin.twin.programs)
    return plots


#: Light curves drawn at most; sites from which the report maps the array.
MAX_CURVES, MIN_SITES_FOR_MAP = 16, 16


def _array_plots(result: Result, folder: Path) -> list[tuple[str, str]]:
    """The per-site SNR as a map over the array (sites called wrong ringed) and its histogram."""
    import matplotlib.pyplot as plt

    a, s = result.arrays, result.scenario
    summary = result.summary["array"]
    # −30 … 300 dB: a noiseless site's infinite SNR drawn at the top, off any sensor's scale
    snr_db = np.clip(10 * np.log10(np.maximum(a["site_snr_power"], 1e-3)), -30.0, 300.0)
    rows, cols = np.divmod(a["site_pixel_index"], s.chip.cols)
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    sc = ax.scatter(cols, rows, c=snr_db, s=max(2.0, 4e4 / len(rows)), marker="s", cmap="viridis")
    if "site_called_right" in a and not a["site_called_right"].all():
        wrong = ~a["site_called_right"]
        ax.scatter(cols[wrong], rows[wrong], s=max(6.0, 1.2e5 / len(rows)), facecolors="none",
                   edgecolors="red", linewidths=0.6, label="called wrong")
        ax.legend(fontsize=7, loc="upper right")
    ax.set(xlim=(-0.5, s.chip.cols - 0.5), ylim=(s.chip.rows - 0.5, -0.5), xlabel="column",
           ylabel="row", aspect="equal", title="Per-site SNR (power, dB) over the array")
    fig.colorbar(sc, ax=ax, label="SNR (power, dB)")
    right = summary.get("fraction_called_right")
    caption = f"Per-site SNR over the array, {summary['n_sites']} sites" + (
        f"; {right:.1%} called right (wrong ones ringed)" if right is not None else "")
    plots = [_save(fig, folder, "site_map.png", caption)]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    if "site_called_right" in a:
        right = a["site_called_right"]
        ax.hist([snr_db[right], snr_db[~right]], bins=60, stacked=True, histtype="stepfilled",
                color=["tab:blue", "tab:red"], label=["called right", "called wrong"])
    else:
        ax.hist(snr_db, bins=60, color="tab:blue", histtype="stepfilled")
    ax.axvline(10 * np.log10(s.run.detection_snr_power), color="k", ls=":", lw=1,
               label="detection threshold")
    ax.set(xlabel="SNR (power, dB)", ylabel="sites", title="Distribution of per-site SNR")
    ax.legend(fontsize=7)
    plots.append(_save(fig, folder, "snr_histogram.png",
                       "Histogram of the per-site SNR (stacked: sites called right and wrong)"))
    return plots


def _dose_response_plot(dose: dict[str, Any], a: dict[str, np.ndarray], folder: Path
                        ) -> tuple[str, str]:
    """Signal and power SNR against the amount (log–log): measured points with their noise, the
    expected response, the blank's 3σ threshold and the limit of detection."""
    import matplotlib.pyplot as plt

    amounts, dosed = a["dose_amount_amol"], a["dose_amount_amol"] > 0
    x, y, sd = amounts[dosed], a["dose_signal_e"][dosed], a["dose_sd_e"][dosed]
    order = np.argsort(x)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    pos = y > 0
    ax.errorbar(x[pos], y[pos], yerr=sd[pos], fmt="o", ms=4, label="measured ± noise (1σ)")
    ax.plot(x[order], a["dose_expected_e"][dosed][order], "-", lw=1, label="expected")
    lod = dose.get("lod_amol")
    if "threshold_e" in dose:
        ax.axhline(dose["threshold_e"], color="r", ls="--", lw=1, label="blank + 3σ (model)")
    if lod is not None and np.isfinite(lod):
        ax.axvline(lod, color="k", ls=":", lw=1, label=f"LoD {lod:.3g} amol")
    ax.set(xscale="log", yscale="log", xlabel=f"{dose['analyte']} per site (amol)",
           ylabel="signal (e⁻)", title="Dose response")
    ax.legend(fontsize=7)
    snr_p = (y / sd) ** 2
    ax2.loglog(x, np.maximum(snr_p, 1e-3), "o", ms=4)
    ax2.axhline(dose["k_sigma"] ** 2, color="r", ls="--", lw=1,
                label=f"power SNR {dose['k_sigma'] ** 2:g} (amplitude {dose['k_sigma']:g})")
    if lod is not None and np.isfinite(lod):
        ax2.axvline(lod, color="k", ls=":", lw=1)
    ax2.set(xlabel="amount per site (amol)", ylabel="SNR (power)", title="SNR per dose")
    ax2.legend(fontsize=7)
    caption = "Dose response and SNR per dose" + (
        f"; limit of detection {lod:.3g} amol (blank + 3σ)" if lod is not None
        and np.isfinite(lod) else "")
    return _save(fig, folder, "dose_response.png", caption)


def _saturation_plot(sat: dict[str, Any], folder: Path) -> tuple[str, str]:
    """When each well filled, per flow: the time into the flow (event stream, and the closed
    form's for the same frame) and the share of the flow's frames that filled."""
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for i, site in enumerate(sat["sites"][:MAX_CURVES]):
        fills = site.get("fills", [])
        flows = [f["flow"] for f in fills]
        ax.plot(flows, [1e3 * f["fill_s"] for f in fills], "o", ms=4,
                label=f"site {i} {site['pixel']} (event stream)")
        closed = [(f["flow"], 1e3 * f["fill_expected_s"]) for f in fills
                  if f["fill_expected_s"] is not None]
        ax.plot([c[0] for c in closed], [c[1] for c in closed], "k+", ms=6,
                label="closed form" if i == 0 else None)
        ax2.plot(flows, [f["frames_saturated"] / f["frames"] for f in fills], "o-", ms=3, lw=0.8)
    ax.set(yscale="log", ylabel="well full after (ms into the flow)",
           title=f"When the wells fill ({sat['full_well_e']:.3g} e⁻)")
    ax.legend(fontsize=7)
    ax2.set(xlabel="flow", ylabel="frames at full well (share)", ylim=(0, 1.05))
    return _save(fig, folder, "saturation.png",
                 "When each site's well filled in each flow, and the share of frames that filled")


def report_markdown(summary: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    """A short human report: headline figures, the fidelity used, the plots."""
    lines = [f"# {summary['scenario']}", "", summary.get("description", ""), ""]
    lines += ["| quantity | value |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in headline(summary)]
    lines += ["", "Fidelity: " + ", ".join(f"{k} = {v}" for k, v in summary["fidelity"].items())]
    if "fidelity_reason" in summary:  # auto: why each level, and the error it estimates
        lines += ["", f"`auto` fidelity, error budget {summary['error_budget']}, estimated "
                  f"error against the reference {summary['fidelity_error_estimate']}:", ""]
        lines += [f"- {stage}: {why}" for stage, why in summary["fidelity_reason"].items()]
    lines += ["", f"SNR: {summary['snr_definition']}", ""]
    if "reads" in summary:
        lines += read_lines(summary)
    lines += [f"![{cap}]({name})\n\n*{cap}*\n" for name, cap in plots]
    return "\n".join(lines) + "\n"


def _reach_rows(summary: dict[str, Any]) -> list[tuple[str, str]]:
    """A template longer than its flows reach: the read is judged on the bases they reach (the
    true sequence below), not on the whole template."""
    n, m = len(summary["true_sequence"]), summary.get("template_length", 0)
    return [("reads", f"the first {n} bases (the flows reach base {n} of {m})")] if n < m else []


def headline(summary: dict[str, Any]) -> list[tuple[str, str]]:
    """The compact table printed by the CLI and put at the top of report.md."""
    rows = [("wall time", f"{summary['wall_time_s']:.2f} s"), ("seed", str(summary["seed"]))]
    if "fidelity_reason" in summary:
        rows.append(("fidelity (auto)", ", ".join(f"{k}={v}" for k, v in
                                                  summary["fidelity"].items())))
    if not summary["results_valid"]:
        rows.append(("RESULTS NOT VALID", "the chip flagged " + ", ".join(
            summary["chip"]["flags"]) + ": figures below are what the chip would report"))
    for site in summary["sites"][:8]:
        rows.append((
            f"site {site['id']} {site['pixel']}",
            f"signal {site['signal_e']:.4g} e⁻, noise {site['noise_e']:.3g} e⁻, "
            f"SNR {site['snr_power']:.4g} (power) / {site['snr_amplitude']:.4g} (amplitude), "
            f"{'detected' if site['detected'] else 'NOT detected'}",
        ))
    if len(summary["sites"]) > 8:
        rows.append(("sites", f"{len(summary['sites'])} in all (see summary.json)"))
        arr = summary.get("array", {})
        if arr:
            pct = arr["snr_power_percentiles"]
            text = (f"median {pct['p50']:.4g}, 5–95 % {pct['p5']:.4g} … {pct['p95']:.4g}, "
                    f"{arr['fraction_detected']:.1%} detected")
            rows.append(("per-site SNR (power)", text))
            if "fraction_called_right" in arr:
                reach = len(summary.get("true_sequence", ""))
                on = (f", each read judged on the first {reach} bases" if reach < summary.get(
                    "template_length", 0) else "")
                rows.append(("sites called right", f"{arr['sites_called_right']} of "
                             f"{arr['n_sites']} ({arr['fraction_called_right']:.2%}){on}"))
    if "called_sequence" in summary:
        ok = summary["called_sequence"] == summary["true_sequence"]
        rows += _reach_rows(summary)
        rows.append(("true sequence", summary["true_sequence"]))
        rows.append(("called sequence", summary["called_sequence"] + ("  ✓" if ok else "  ✗")))
    reads = summary.get("reads", {})
    if reads.get("caller") == "dephase":
        q20 = reads["q20_read_length"]
        rows.append(("read length at Q20", f"median {q20['median']:.0f} bases (p10 "
                     f"{q20['p10']:.0f}, min {q20['min']:.0f}) of {reads['n_reads']} reads; "
                     f"accuracy {100 * reads['read_accuracy']:.2f} %; reads.sff"))
    if "lod_amol" in summary.get("dose_response", {}):
        d = summary["dose_response"]
        text = f"{d['lod_amol']:.3g} amol ({d['lod_molecules']:.3g} molecules), blank + 3σ"
        if "lod_from_blank_spread_amol" in d:
            text += (f"; from the {d['blank']['n_sites']} blanks' spread "
                     f"{d['lod_from_blank_spread_amol']:.3g} ± "
                     f"{d['lod_from_blank_spread_se_amol']:.2g} amol")
        rows.append(("limit of detection", text))
    rows += _optics_rows(summary.get("optics"))
    rows += _assumption_rows(summary.get("assumptions"))
    rows += _physical_law_rows(summary.get("physical_law"))
    c = summary.get("crosstalk", {})
    if c.get("before_db_median") is not None and c.get("after_db_median") is not None:
        rows.append(("cross-talk (median)", f"{c['before_db_median']:+.1f} dB before, "
                     f"{c['after_db_median']:+.1f} dB after the equalizer (predicted "
                     f"{c['after_predicted_db_median']:+.1f}); SNR cost "
                     f"{c['snr_cost_db_median']:.1f} dB"))
        w, wo = c["min_pitch_um_with"], c["min_pitch_um_without"]  # None: at no scanned pitch
        rows.append(("neighbours resolved",
                     (f"from {w:.0f} µm pitch" if w is not None else "at no scanned pitch")
                     + " with the equalizer, "
                     + (f"{wo:.0f} µm without" if wo is not None else "at none without")))
    c = summary.get("column_profile", {})
    if c.get("valley_to_peak_before") is not None and c.get("valley_to_peak_after") is not None:
        rows.append(("valley / peak", f"{c['valley_to_peak_before']:.3g} before, "
                     f"{c['valley_to_peak_after']:.3g} after binning, FIR and equalization"))
    for site in summary.get("saturation", {}).get("sites", [])[:8]:
        fills = site.get("fills", [])
        text = f"peak charge {site['peak_fraction_of_full_well']:.3g} × the full well"
        if fills:
            ms = [1e3 * f["fill_s"] for f in fills if f["frame_in_flow"] == 0]
            text += (f"; filled in {len(fills)} flows, {site['frames_saturated']} frames "
                     + (f"(first frame {min(ms):.3g}–{max(ms):.3g} ms into the flow)" if ms
                        else ""))
        rows.append((f"saturation {site['pixel']}", text))
    if "required_flux_photons_per_s_per_um2" in summary:
        rows.append((f"flux for SNR {summary['required_flux_snr_power']:g} (power)",
                     f"{summary['required_flux_photons_per_s_per_um2']:.4g} photons/s/µm²"))
    chip = summary["chip"]
    rows.append(("chip", f"{chip['frames']} frames, {chip['adc_bits']}-bit ADC, memory peak "
                 f"{chip['memory_peak_frames']} frames of {chip['memory_capacity_frames']}, "
                 f"DSP utilisation {chip['dsp_utilization']:.3g}, "
                 f"{chip['overflows'] or 'no'} frame(s) dropped"))
    rows += _cost_rows(summary.get("cost"), summary.get("throughput"))
    rows += [(f"flag: {f}", "yes") for f in chip["flags"]]
    dsp = summary["dsp"]
    if dsp["level"] != "float":
        rows.append((f"DSP ({dsp['level']})", "overflow events: " + ", ".join(
            f"{n} {word}" for n, word in ((dsp["overflow_total"]["sat"], "saturated"),
                                          (dsp["overflow_total"]["wrap"], "wrapped")))))
    if "error_vs_float" in dsp:
        e = dsp["error_vs_float"]
        sqnr = "exact" if e["sqnr_db"] is None else f"{e['sqnr_db']:.1f} dB"
        rows.append(("DSP error vs float", f"max {e['max_abs_err_lsb']:.3g} output LSB, bias "
                     f"{e['bias_lsb']:.3g} LSB, SQNR {sqnr}"))
    rows += [("warning", w) for w in summary.get("warnings", [])]
    return rows


def _cost_rows(cost: dict[str, Any] | None, tp: dict[str, Any] | None
               ) -> list[tuple[str, str]]:
    """The chip's silicon (area and power by block, chiptwin.chip.silicon) and its yield."""
    if not cost:
        return []
    blocks = ", ".join(f"{name} {b['area_mm2']:.3g} mm² / {b['power_mw']:.3g} mW"
                       for name, b in cost["blocks"].items())
    rows = [("silicon", f"{cost['area_mm2']:.3g} mm², {cost['power_mw']:.3g} mW ({blocks})"
             + ("" if cost["pixel_fits_pitch"] else "; the pixel's content exceeds its pitch"))]
    if tp:
        text = (f"{tp['sites_called']} sites called ({tp['sites_called_frac']:.1%}; "
                f"{tp['sites_called_means']}), {tp['sites_per_mm2']:.3g} per mm²")
        if "q20_bases_per_run" in tp:
            nj = cost.get("energy_per_base_nj")
            text += (f"; {tp['q20_bases_per_run']} Q20 bases, {tp['q20_bases_per_hour']:.4g} an "
                     f"hour, {tp['q20_bases_per_hour_mm2']:.4g} an hour per mm²; "
                     + (f"{nj:.4g} nJ per Q20 base" if nj is not None else "no Q20 base"))
        rows.append(("throughput", text))
    return rows


def _physical_law_rows(p: dict[str, Any] | None) -> list[tuple[str, str]]:
    """Under the paper's convention: what the physical emitter law would read instead."""
    if not p:
        return []
    if not p["computed"]:
        return [("paper convention (NA²)", f"the {p['emitter']} law's figures not computed: "
                 f"{p['why_not']}")]
    def ratio(x: float | None) -> str:  # None: the convention's site 0 reads no signal
        return "undefined (no signal under the convention)" if x is None else f"{x:.3g}"

    return [("paper convention (NA²)", f"with {p['emitter']} emitters instead: signal × "
             f"{ratio(p['signal_ratio'])}, power SNR × {ratio(p['snr_power_ratio'])} (site 0, "
             f"{p['level']} level)")]


def _assumption_rows(a: dict[str, Any] | None) -> list[tuple[str, str]]:
    """Which unpublished chip parameters the run rests on: the reference set, or what differs."""
    if not a:
        return []
    if a["as_reference"]:
        return [("assumed chip parameters", f"the reference chip as built ({a['set']})")]
    d = a["differ"]
    if len(d) > 2:
        return [("assumed chip parameters", f"{len(d)} of {a['n']} differ from {a['set']} "
                 "(summary.json: assumptions)")]
    return [("assumed chip parameters", f"{a['set']} but " + "; ".join(
        f"{k.rsplit('.', 1)[-1]} {v['value']:.4g} (not {v['reference']:.4g})"
        for k, v in d.items()))]


def _top_rows(t: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The top surface in two lines: what it is; what it returns and does to a centre site."""
    if not t:
        return []
    depth = f"{t['solution_depth_um']:g} µm of solution"
    what = (f"open well, {depth} under air" if t["medium"] == "air" else
            f"{t['lid_thickness_um']:g} µm glass lid (n {t['lid_n']:g}) on {depth}")
    w, wo = t["with"], t["without"]

    def db(f: dict[str, Any]) -> str:
        return "none" if f["crosstalk_db"] is None else f"{f['crosstalk_db']:+.1f} dB"

    change = t["own_pixel_change_rel"]
    return [("top surface", what),
            (f"top's light ({t['level']})", f"{t['returned_share']:.1%} returns; own pixel "
             + (f"{change:+.2%}" if change is not None else "n/a")
             + f", cross-talk {db(wo)} → {db(w)}")]


def _optics_rows(o: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The optics lines of the headline: the run's own pixel and cross-talk, the emitter laws
    when they differ beyond the budget, the faceplate against direct contact, thin films."""
    if not o:
        return []

    def light(f: dict[str, Any]) -> str:
        db = (f"{f['crosstalk_db']:+.1f} dB" if f["crosstalk_db"] is not None
              else "none (< −120 dB)")
        return f"own pixel {f['own_pixel']:.4g} of the site's light, cross-talk {db}"

    rows = [("optics", f"{o['level']} level, {o['emitter']} emitter: {light(o)}")]
    if o.get("laws_differ_beyond_budget"):
        rows.append(("collected, per emitter law", ", ".join(
            f"{law} {v:.4g}" for law, v in o["collected_fraction"].items())))
    fp = o.get("faceplate")
    if fp:
        ratio = fp.get("own_pixel_ratio")
        rows.append(("faceplate vs direct contact (psf)",
                     f"with: {light(fp['with'])}; without: {light(fp['without'])}"
                     + (f"; own pixel × {ratio:.3g}" if ratio else "")))
    rows += _top_rows(o.get("top"))
    tf = o.get("thin_films")
    if tf:
        films = ", ".join(f"{f['name']} ({f['thickness_um']:g} µm, n {f['n']:g})"
                          for f in tf["films"])
        change = tf["change_rel"]
        rows.append((f"thin films, coherent over {tf['band_nm']['peak']:g} ± "
                     f"{tf['band_nm']['fwhm'] / 2:g} nm",
                     f"{films}: plane fraction {tf['plane_fraction']['coherent']:.4g} "
                     f"(rays alone {tf['plane_fraction']['rays_only']:.4g}"
                     + (f", {change:+.1%}" if change is not None else "") + ")"))
    return rows

