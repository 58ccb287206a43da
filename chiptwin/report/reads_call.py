"""``chiptwin reads call``: a measured flowgram file's reads called by the twin's callers, and
their figures beside the instrument's own.

:func:`call_file` reads the file (:func:`chiptwin.report.flowgram_files.read_flowgrams`),
measures its noise (:func:`chiptwin.detection.measured_reads.fit_noise`), calls every read with
the file's own flow order and key by ``round`` or ``dephase``
(:mod:`chiptwin.detection.reads`), drops the reads whose calls do not spell the key (counted),
and judges the calls and the instrument's against the truth, or against each other without one
(:mod:`chiptwin.report.reads_eval`). :func:`write_reads_outputs` writes ``reads.fastq`` (each
read after the key, under its name in the file), ``reads.sff`` (the whole read, quality-clipped
after the key to its Q20 length), ``reads.json`` and ``report.md``, whole or not at all.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.detection import measured_reads as mr
from chiptwin.detection import read_stats
from chiptwin.detection.key_pass import key_counts, passes_key
from chiptwin.detection.reads import CALLERS, Read, phred
from chiptwin.kinetics.phasing import flow_indices
from chiptwin.pixel.chain import available_cores
from chiptwin.report import reads_eval
from chiptwin.report.flowgram_files import read_flowgrams
from chiptwin.report.flowgrams import FlowgramFile
from chiptwin.report.sff import SffRead, quality_clip, write_sff

JSON_NAME = "reads.json"
"""The summary, written last: an output folder holding it is a previous ``reads call``."""

#: Largest flowgram value SFF stores: uint16 hundredths.
SFF_MAX_X100 = 65535


@dataclass
class ReadsResult:
    """A called file: its data, the twin's reads (one per read of the file), which pass the key,
    the twin's and the instrument's calls after the key, and the summary."""

    data: FlowgramFile
    caller: str
    reads: list[Read]
    key_pass: list[bool]
    twin: reads_eval.Calls
    instrument: reads_eval.Calls
    summary: dict[str, Any]


def _call_all(data: FlowgramFile, values: list[np.ndarray], caller: str, noises: list,
              progress: Callable[[int, int], None] | None) -> list[Read]:
    flows = flow_indices(data.flow_order, data.n_flows)

    def one(j: int) -> Read:
        return mr.call(values[j], flows[:values[j].size], noises[j], caller)

    n = len(data.reads)
    # both callers cost alike (``round``'s qualities come from the dephasing caller's posterior,
    # :func:`chiptwin.detection.reads.call_rounded`): threads for both, as the twin's reads use
    workers = min(available_cores(), n)
    out: list[Read] = []
    # the caller's kernels release the GIL; each read's calls do not depend on the threads
    with ThreadPoolExecutor(max(workers, 1)) as pool:
        for read in pool.map(one, range(n)):
            out.append(read)
            if progress is not None:
                progress(len(out), n)
    return out


def call_file(path: str | Path, truth: str | Path | None = None, caller: str = "round",
              progress: Callable[[int, int], None] | None = None, first: int | None = None
              ) -> ReadsResult:
    """Read, call and judge a flowgram file (module docstring); only its ``first`` reads if
    given (the file is still read whole: a corrupted end is refused)."""
    if caller not in CALLERS:
        raise ValueError(f"caller = {caller!r}: must be one of {', '.join(CALLERS)}")
    t0 = time.perf_counter()
    data = read_flowgrams(path, truth)
    if first is not None:
        data = replace(data, reads=data.reads[:first])
    t_read = time.perf_counter() - t0
    values = [mr.caller_input(r.values, caller) for r in data.reads]
    pool, noises = mr.fit_noise(values)
    reads = _call_all(data, values, caller, noises, progress)
    t_call = time.perf_counter() - t0 - t_read
    key_n = key_counts(data.key, data.flow_order)
    passed = [passes_key(r.calls, key_n) for r in reads]
    bases, quals, perr = [], [], []
    for read, ok in zip(reads, passed, strict=True):
        b, q, p = mr.after_key(read, data.flow_order, data.key) if ok else (None, None, None)
        bases.append(b)
        quals.append(q)
        perr.append(p)
    twin = reads_eval.Calls(caller, bases, quals, perr)
    instrument = reads_eval.Calls.of_instrument([r.bases for r in data.reads],
                                                [r.quality for r in data.reads])
    summary = _summary(data, caller, reads, passed, twin, instrument, pool)
    summary["wall_time_s"] = {"read": t_read, "call": t_call,
                              "judge": time.perf_counter() - t0 - t_read - t_call,
                              "total": time.perf_counter() - t0}
    return ReadsResult(data, caller, reads, passed, twin, instrument, summary)


def _summary(data: FlowgramFile, caller: str, reads: list[Read], passed: list[bool],
             twin: reads_eval.Calls, instrument: reads_eval.Calls, pool) -> dict[str, Any]:
    from chiptwin import __version__

    q20 = [read_stats.length_at_quality(p) if p is not None else 0 for p in twin.p_error]
    out: dict[str, Any] = {
        "file": data.path.name, "format": data.kind, "instrument": data.instrument,
        "flows": data.n_flows, "flow_order": data.flow_order, "key": data.key,
        "caller": caller, "reads": len(reads),
        "key_fail_reads": int(sum(not p for p in passed)),
        "reads_without_q20_bases": int(sum(ok and n == 0 for ok, n in zip(passed, q20,
                                                                            strict=True))),
        "noise": {"floor": pool.floor, "ref": pool.ref,
                  "model": "var = floor + ref·h² (1-mers²), measured from the file"},
        "instrument_bases": data.stored_bases,
        "instrument_n_bases": data.off_flow_bases,
        "truth": data.truth_source, "notes": data.notes,
    }
    if caller == "dephase":
        out["phasing_estimated"] = {
            k: reads_eval.stats([getattr(r, k) for r in reads]) for k in ("eps", "lam", "droop")}
        out["phasing_estimated_zero"] = int(sum(r.eps == r.lam == r.droop == 0 for r in reads))
    if data.truth_source is not None:
        truths = [r.truth for r in data.reads]
        start = [r.truth_from for r in data.reads]
        out["twin_vs_truth"] = reads_eval.against_truth(twin, truths, start)
        out["instrument_vs_truth"] = reads_eval.against_truth(instrument, truths, start)
    else:
        out["twin_vs_instrument"] = reads_eval.against_instrument(twin, instrument)
        out["instrument_q20"] = reads_eval.instrument_q20(instrument)
    out["read_rows"] = [
        {"name": r.name, "key_pass": ok, "bases": len(b) if b is not None else 0,
         "q20_read_length": int(n), **({"eps": read.eps, "lam": read.lam, "droop": read.droop}
                                       if caller == "dephase" else {})}
        for r, read, ok, b, n in zip(data.reads, reads, passed, twin.bases, q20, strict=True)]
    out["chiptwin_version"] = __version__
    return out


def sff_records(result: ReadsResult) -> list[SffRead]:
    """The reads that pass the key, whole (key included), quality-clipped after the key to
    their Q20 length (:func:`chiptwin.report.sff.quality_clip`)."""
    data, out = result.data, []
    key = data.key
    for j, (read, ok) in enumerate(zip(result.reads, result.key_pass, strict=True)):
        if not ok:
            continue
        values = np.zeros(data.n_flows)
        y = data.reads[j].values
        values[:y.size] = y
        p = read.base_error()
        good = result.summary["read_rows"][j]["q20_read_length"]
        left, right = quality_clip(len(key), good)
        out.append(SffRead(
            name=data.reads[j].name,
            flowgram_x100=np.clip(np.rint(np.maximum(values, 0.0) * 100), 0,
                                  SFF_MAX_X100).astype(np.uint16),
            bases=read.bases(data.flow_order), qualities=phred(p).astype(np.uint8),
            flow_index=read.flow_index(), clip_qual_left=left, clip_qual_right=right))
    return out


def fastq_text(result: ReadsResult) -> str:
    """The reads that pass the key, after the key, phred + 33."""
    lines = []
    for r, b, q in zip(result.data.reads, result.twin.bases, result.twin.quality, strict=True):
        if b is None:
            continue
        lines += [f"@{r.name}", b, "+", (np.asarray(q, dtype=np.uint8) + 33).tobytes().decode()]
    return "\n".join(lines) + ("\n" if lines else "")


def write_reads_outputs(result: ReadsResult, out_dir: str | Path) -> Path:
    """``reads.fastq``, ``reads.sff``, ``report.md`` and ``reads.json`` (last) into ``out_dir``,
    replacing a previous output whole."""
    from chiptwin.config.outputs import check_out_dir, replacing
    from chiptwin.report.reads_markdown import report_markdown

    out = check_out_dir(out_dir, marker=JSON_NAME)
    with replacing(out) as tmp:
        (tmp / "reads.fastq").write_text(fastq_text(result), encoding="ascii")
        write_sff(tmp / "reads.sff", result.data.flow_order, result.data.key,
                  sff_records(result))
        (tmp / "report.md").write_text(report_markdown(result.summary), encoding="utf-8")
        (tmp / JSON_NAME).write_text(json.dumps(result.summary, indent=1) + "\n",
                                     encoding="utf-8")
    return out
