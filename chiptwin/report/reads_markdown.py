"""``report.md`` of ``chiptwin reads call``, and the lines the command prints: the twin's calls
beside the instrument's, from the summary alone (:mod:`chiptwin.report.reads_call`)."""

from __future__ import annotations

from typing import Any


def _pct(x: float) -> str:
    return f"{100 * x:.3f} %"


def _median(stats: dict[str, float]) -> str:
    return f"{stats['median']:.0f}" if stats else "—"


def headline(summary: dict[str, Any]) -> list[tuple[str, str]]:
    """The compact table the command prints."""
    s = summary
    rows = [("file", f"{s['file']}: {s['reads']} reads, {s['flows']} flows, key {s['key']} "
                     f"({s['instrument']})"),
            ("caller", f"{s['caller']}; {s['key_fail_reads']} reads fail the key, "
                       f"{s['reads_without_q20_bases']} have no base at Q20")]
    if "twin_vs_truth" in s:
        for label, r in (("twin", s["twin_vs_truth"]), ("instrument", s["instrument_vs_truth"])):
            rows.append((f"{label} vs truth",
                         f"{r['errors']:,} errors in {r['truth_bases']:,} bases "
                         f"({_pct(r['error_rate'])}: {r['mismatches']} mismatches, "
                         f"{r['insertions']} insertions, {r['deletions']} deletions); "
                         f"Q20 length median {_median(r['q20_read_length'])}"))
    else:
        r = s["twin_vs_instrument"]
        rows.append(("agreement", f"{_pct(r['agreement'])} of the instrument's "
                                  f"{r['instrument_bases']:,} bases ({r['differing_errors']:,} "
                                  f"differ; the instrument stored {s['instrument_n_bases']} N)"))
        rows.append(("Q20 length", f"median {_median(r['q20_read_length'])} (twin), "
                                   f"{_median(s['instrument_q20']['q20_read_length'])} "
                                   "(instrument)"))
    if "phasing_estimated" in s:
        ph = s["phasing_estimated"]
        rows.append(("phasing estimated", f"ε median {ph['eps']['median']:.4f}, λ "
                     f"{ph['lam']['median']:.4f}, droop {ph['droop']['median']:.4f}; "
                     f"{s['phasing_estimated_zero']} of {s['reads']} reads all 0"))
    rows.append(("wall time", f"{s['wall_time_s']['total']:.2f} s (calling "
                              f"{s['wall_time_s']['call']:.2f} s)"))
    return rows


def _figures_table(twin: dict[str, Any], inst: dict[str, Any]) -> list[str]:
    rows = [("reads judged", "reads", "{:,}"), ("truth bases covered", "truth_bases", "{:,}"),
            ("errors", "errors", "{:,}"), ("error rate", "error_rate", "{:.3%}"),
            ("mismatch rate", "mismatches_rate", "{:.3%}"),
            ("insertion rate", "insertions_rate", "{:.3%}"),
            ("deletion rate", "deletions_rate", "{:.3%}"), ("bases at Q20", "q20_bases", "{:,}")]
    out = [f"| figure | twin ({twin['caller']}) | instrument |", "|---|---|---|"]
    out += [f"| {label} | {fmt.format(twin[k])} | {fmt.format(inst[k])} |"
            for label, k, fmt in rows]
    for label, k in (("read length at Q20 (median)", "q20_read_length"),
                     ("read length at 99 % accuracy (median)", "read_length_99")):
        out.append(f"| {label} | {_median(twin[k])} | {_median(inst[k])} |")
    return out


def _homopolymer_table(twin: dict[str, Any], inst: dict[str, Any]) -> list[str]:
    out = ["| true length | runs | twin: right / under / over | instrument: right / under / "
           "over |", "|---|---|---|---|"]
    by_len = {str(r["length"]): r for r in inst["homopolymers"]}
    for r in twin["homopolymers"]:
        i = by_len.get(str(r["length"]))
        if r["length"] == 0:
            out.append(f"| 0 (inserted runs) | — | over {r['over_calls']} | over "
                       f"{i['over_calls'] if i else '—'} |")
            continue
        cell = (f"{i['right']} / {i['under_calls']} / {i['over_calls']} ({i['accuracy']:.2%})"
                if i else "—")
        out.append(f"| {r['length']} | {r['runs']} | {r['right']} / {r['under_calls']} / "
                   f"{r['over_calls']} ({r['accuracy']:.2%}) | {cell} |")
    return out


def _calibration_table(fig: dict[str, Any]) -> list[str]:
    out = ["| quality | bases | stated error | observed (95 % CI) | inside |",
           "|---|---|---|---|---|"]
    out += [f"| {c['q_lo']}–{c['q_hi'] - 1} | {c['bases']:,} | {c['stated_error']:.2e} | "
            f"{c['observed_error']:.2e} ({c['ci_low']:.1e} … {c['ci_high']:.1e}) | "
            f"{'yes' if c['calibrated'] else 'no'} |" for c in fig.get("calibration", [])]
    return out


def report_markdown(summary: dict[str, Any]) -> str:
    """The report: what was read and called, then the figures beside the instrument's."""
    s = summary
    lines = [f"# Reads of {s['file']}", "", "| | |", "|---|---|",
             *(f"| {k} | {v} |" for k, v in headline(s)), ""]
    lines += [f"Flow order: {s['flows']} flows, starting `{s['flow_order'][:32]}`; key "
              f"`{s['key']}`. The noise the caller weighs each flow with is measured from the "
              f"file: var = {s['noise']['floor']:.4f} + {s['noise']['ref']:.5f}·h² (1-mers²). "
              f"The instrument stored {s['instrument_bases']:,} bases after the key, "
              f"{s['instrument_n_bases']} of them N (no base for its flow's nucleotide).", ""]
    lines += [f"Note: {n}" for n in s.get("notes", [])]
    if "twin_vs_truth" in s:
        twin, inst = s["twin_vs_truth"], s["instrument_vs_truth"]
        lines += [f"## Against the truth ({s['truth']})", "",
                  "Each read aligned to the sequence under it by edit distance (errors per "
                  "truth base covered; a read's tail past its truth is not scored).", "",
                  *_figures_table(twin, inst), "", "### Homopolymers", "",
                  *_homopolymer_table(twin, inst), "", "### Quality calibration: twin", "",
                  *_calibration_table(twin), "", "### Quality calibration: instrument", "",
                  *_calibration_table(inst), ""]
    else:
        r = s["twin_vs_instrument"]
        lines += ["## Against the instrument's calls (no truth given)", "",
                  f"The twin's calls agree with {_pct(r['agreement'])} of the instrument's "
                  f"{r['instrument_bases']:,} bases: {r['differing_mismatches']} mismatches, "
                  f"{r['differing_insertions']} insertions, {r['differing_deletions']} "
                  "deletions (an N the instrument stored differs from any call).", ""]
    return "\n".join(lines) + "\n"
