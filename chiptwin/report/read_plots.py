"""Plots, report lines and SFF records of a pyrosequencing run's reads (``summary['reads']``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin.config import Scenario
from chiptwin.report.sff import SffRead, quality_clip
from chiptwin.twin.figures import quality_calibration
from chiptwin.twin.figures import save_figure as _save

if TYPE_CHECKING:
    from chiptwin.twin.runner import Result

#: Flows the flowgram plot shows (the first ones: where the key and the best calls are).
FLOWGRAM_FLOWS = 160


def read_plots(result: Result, folder: Path) -> list[tuple[str, str]]:
    """Flowgram of site 0 with its calls, accuracy against read position, error rate by
    homopolymer length, read lengths over the sites, quality calibration."""
    import matplotlib.pyplot as plt

    a, r = result.arrays, result.summary["reads"]
    order = result.scenario.assay.flow_order
    plots = []
    n = min(FLOWGRAM_FLOWS, a["read_calls"].shape[1])
    fig, ax = plt.subplots(figsize=(10, 3.5))
    k = np.arange(n)
    ax.bar(k, a["read_flowgram_x100"][0, :n] / 100.0, color="tab:green", label="flow value")
    ax.plot(k, a["read_calls"][0, :n], "k_", ms=7, mew=1.5, label="called length")
    wrong = a["read_calls"][0, :n] != a["read_true_n"][:n]
    ax.plot(k[wrong], a["read_true_n"][:n][wrong], "rx", label="true length (miscalled)")
    ax.set_xticks(k[::4], [order[i % len(order)] for i in k[::4]], fontsize=6)
    ax.set(xlabel="flow", ylabel="normalised flow value",
           title=f"Flowgram of site 0, first {n} flows ({r['caller']} caller)")
    ax.legend(fontsize=7)
    plots.append(_save(fig, folder, "flowgram.png", f"Flowgram of site 0: flow values and the "
                       f"called homopolymer lengths (first {n} flows)"))

    pos = r["accuracy_by_position"]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    acc = np.array([np.nan if v is None else v for v in pos["accuracy"]])
    ax.plot(np.array(pos["bin_start"]) + 0.5 * (pos["bin_start"][1] if len(acc) > 1 else 1),
            100 * acc, "o-")
    ax.axhline(99.0, color="k", ls=":", lw=1, label="99 % (Q20)")
    ax.set(xlabel="read position (bases)", ylabel="accuracy (%)",
           title="Accuracy against read position, all sites")
    ax.legend(fontsize=7)
    plots.append(_save(fig, folder, "accuracy_position.png", "Accuracy against read position"))

    hp = r["homopolymer_errors"]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    lengths = np.array([h["length"] for h in hp])
    ax.bar(lengths - 0.2, [h["over_rate"] for h in hp], 0.4, label="over-call")
    ax.bar(lengths + 0.2, [h["under_rate"] for h in hp], 0.4, label="under-call")
    ax.set(xlabel="true homopolymer length", ylabel="rate per flow",
           title="Error rate by homopolymer length")
    ax.legend(fontsize=7)
    plots.append(_save(fig, folder, "homopolymer_errors.png",
                       "Over- and under-call rate by true homopolymer length"))

    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.hist([[s["q20_read_length"] for s in r["sites"]],
             [s["read_length_99"] for s in r["sites"]]], bins=30,
            label=["Q20 (stated qualities)", "99 % accuracy (against the template)"])
    ax.set(xlabel="read length (bases)", ylabel="sites", title="Read length over the sites")
    ax.legend(fontsize=7)
    plots.append(_save(fig, folder, "read_length.png", "Read length at Q20 and at 99 % "
                       "accuracy over the sites"))

    fig, ax = plt.subplots(figsize=(5, 4))
    quality_calibration(ax, r["calibration"])
    plots.append(_save(fig, folder, "quality_calibration.png",
                       "Stated against observed error rate, bases binned by quality (a bin "
                       "without an error: its 95 % upper bound 3/n, arrow down)"))
    return plots


def read_lines(summary: dict[str, Any]) -> list[str]:
    """The reads section of report.md."""
    r = summary["reads"]
    q20, l99 = r["q20_read_length"], r["read_length_99"]
    lines = ["## Reads", "",
             f"{r['n_reads']} reads, {r['caller']} caller; the flows reach "
             f"{r['template_bases']} template bases.", "",
             "| figure | median | p10 | p90 | min | max |", "|---|---|---|---|---|---|",
             *(f"| {name} | {x['median']:.0f} | {x['p10']:.0f} | {x['p90']:.0f} | "
               f"{x['min']:.0f} | {x['max']:.0f} |"
               for name, x in (("read length at Q20 (bases)", q20),
                               ("read length at 99 % accuracy (bases)", l99))),
             "", f"Read accuracy {100 * r['read_accuracy']:.3f} %; {r['chip_q20_bases']} bases "
             f"at Q20 over the chip; {r['sites_q20_at_least_200']} sites read ≥ 200 bases at "
             f"Q20; {r.get('key_fail_reads', 0)} reads fail the key (left out of reads.sff).",
             "", "| homopolymer | flows | over-call | under-call |", "|---|---|---|---|",
             *(f"| {h['length']} | {h['flows']} | {h['over_rate']:.2e} | {h['under_rate']:.2e} |"
               for h in r["homopolymer_errors"]),
             "", "| quality | bases | stated error | observed (95 % CI) |", "|---|---|---|---|",
             *(f"| {c['q_lo']}–{c['q_hi'] - 1} | {c['bases']} | {c['stated_error']:.2e} | "
               f"{c['observed_error']:.2e} ({c['ci_low']:.1e} … {c['ci_high']:.1e}) |"
               for c in r["calibration"]), ""]
    return lines


def sff_reads(s: Scenario, summary: dict[str, Any], arrays: dict[str, np.ndarray]) -> list:
    """The run's reads as :class:`chiptwin.report.sff.SffRead`, one per site whose first flows
    spell the key (the key-pass filter; the others are counted in ``summary['reads']
    ['key_fail_reads']``): the caller's flow values (hundredths), bases, phred qualities, flow
    of each base; quality clip from after the key to the end of the read's Q20 length (1-based,
    as SFF defines clip points; :func:`chiptwin.report.sff.quality_clip`: a read with no base
    at Q20 after the key is clipped to nothing)."""
    a = s.assay
    order = a.flow_order
    key = a.key
    calls, q = arrays["read_calls"], arrays["read_quality"]
    off = arrays["read_quality_offsets"]
    out = []
    for j, row in enumerate(calls):
        site = summary["reads"]["sites"][j]
        if not site.get("key_pass", True):
            continue
        bases = "".join(order[k % len(order)] * int(c) for k, c in enumerate(row))
        left, right = quality_clip(len(key), max(int(site["q20_read_length"]) - len(key), 0))
        out.append(SffRead(
            name=f"site{j:04d}_px{int(arrays['site_pixel_index'][j]):06d}",
            flowgram_x100=arrays["read_flowgram_x100"][j], bases=bases,
            qualities=q[off[j]:off[j + 1]], flow_index=np.repeat(np.arange(row.size), row),
            clip_qual_left=left, clip_qual_right=right))
    return out


def flow_chars(s: Scenario) -> str:
    """The flow characters of the run: the flow order over every flow."""
    order = s.assay.flow_order
    return "".join(order[k % len(order)] for k in range(s.assay.n_flows))
