"""BAM in: Ion Torrent's flowgrams through pysam (the ``bam`` extra), aligned or not.

Per read, as Torrent Suite writes it: ``FZ`` the flow signals × 100 from flow 0 (key flows
included; already phase-corrected), ``ZF`` the flow of the read's first base after the key, the
read group's ``FO`` flow order (one letter per flow, e.g. 1,000 flows, not a repeating cycle) and
``KS`` key. The stored sequence and qualities (without the key) are the instrument's calls; a
reverse-strand read is turned back to flow order (reverse-complemented, qualities reversed).

The truth of an aligned read is the reference under it, rebuilt from its CIGAR and ``MD`` tag
(:func:`reference_from_md`; the reference itself is not needed), reverse-complemented for a
reverse-strand read; a soft-clipped start (in flow order) is carried as the instrument's calls,
not scored. Unmapped reads, and mapped ones without ``MD``, have no truth; secondary and
supplementary alignments are skipped (the primary carries the read).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from chiptwin.config import ScenarioError
from chiptwin.report.flowgrams import (
    FlowgramFile,
    MeasuredRead,
    check_flow_order,
    key_flows,
    require,
)

_COMPLEMENT = str.maketrans("ACGTNacgtn", "TGCANtgcan")

#: CIGAR operations (SAM v1 §1.4): M I D N S H P = X.
_M, _I, _D, _N, _S, _H, _P, _EQ, _X = range(9)


def reverse_complement(seq: str) -> str:
    return seq.translate(_COMPLEMENT)[::-1]


def reference_from_md(query: str, cigar: list[tuple[int, int]], md: str) -> str:
    """The reference under an aligned read, from its query sequence, CIGAR and ``MD`` tag
    (SAM optional fields: ``[0-9]+(([A-Z]|\\^[A-Z]+)[0-9]+)*``), in the read's stored
    orientation. Raises ValueError when they disagree or the CIGAR skips reference (``N``)."""
    ref: list[str] = []
    q = 0
    for op, n in cigar:
        if op in (_M, _EQ, _X):
            ref += query[q:q + n]
            q += n
        elif op == _D:
            ref += ["^"] * n
        elif op in (_I, _S):
            q += n
        elif op == _N:
            raise ValueError("CIGAR skips reference (N): not a DNA read's alignment")
    if not re.fullmatch(r"[0-9]+(([A-Za-z]|\^[A-Za-z]+)[0-9]+)*", md):
        raise ValueError(f"MD {md!r} is not [0-9]+(([A-Z]|^[A-Z]+)[0-9]+)*")
    p = 0
    for number, deleted, mismatch in re.findall(r"([0-9]+)|\^([A-Za-z]+)|([A-Za-z])", md):
        if number:
            p += int(number)
            if p > len(ref) or "^" in ref[p - int(number):p]:
                raise ValueError(f"MD {md!r} matches past the CIGAR's aligned bases")
        elif deleted:
            if ref[p:p + len(deleted)] != ["^"] * len(deleted):
                raise ValueError(f"MD {md!r} deletes where the CIGAR has no deletion")
            ref[p:p + len(deleted)] = deleted.upper()
            p += len(deleted)
        else:
            if p >= len(ref) or ref[p] == "^":
                raise ValueError(f"MD {md!r} has a mismatch where the CIGAR has none")
            ref[p] = mismatch.upper()
            p += 1
    if p != len(ref):
        raise ValueError(f"MD {md!r} covers {p} reference bases, the CIGAR {len(ref)}")
    return "".join(ref).upper()


def _soft_clip_5p(cigar: list[tuple[int, int]], reverse: bool) -> int:
    """Soft-clipped bases at the read's start in flow order."""
    end = cigar[-1] if reverse else cigar[0]
    return end[1] if end[0] == _S else 0


def _flow_signals(path: Path, rec, number: int) -> np.ndarray:
    if not rec.has_tag("FZ"):
        raise ScenarioError(str(path), f"record {number} ({rec.query_name})", "no FZ tag",
                            "every read needs its flow signals: the FZ tag (values × 100 from "
                            "flow 0), as Torrent Suite writes it")
    return np.asarray(rec.get_tag("FZ"), dtype=np.float64) / 100.0


def _read_group(path: Path, header: dict, rg: str | None, number: int) -> tuple[str, str]:
    groups = {g.get("ID"): g for g in header.get("RG", [])}
    group = groups.get(rg) if rg is not None else (next(iter(groups.values()))
                                                   if len(groups) == 1 else None)
    if group is None or "FO" not in group or "KS" not in group:
        raise ScenarioError(str(path), f"record {number} read group", rg,
                            "must name a header @RG with the flow order (FO) and key (KS), "
                            f"as Torrent Suite writes them (header read groups: "
                            f"{', '.join(map(str, groups)) or 'none'})")
    return str(group["FO"]).upper(), str(group["KS"]).upper()


def read_bam(path: Path) -> FlowgramFile:
    """Every primary read of the BAM file at ``path`` (module docstring)."""
    pysam = require("bam", path)
    verbosity = pysam.set_verbosity(0)  # htslib's own lines on stderr: the refusal says it
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "no BGZF EOF marker": a truncated read says more
            reads, flow_order, key = _records(pysam, path)
    finally:
        pysam.set_verbosity(verbosity)
    if not reads:
        raise ScenarioError(str(path), "reads", 0, "must hold one primary read or more")
    no_md = sum(not has_md for _, has_md in reads)
    aligned = any(r.truth is not None for r, _ in reads)
    return FlowgramFile(path, "bam", "Ion Torrent (BAM)", flow_order, key,
                        [r for r, _ in reads], truth_source="alignment" if aligned else None,
                        notes=[f"{no_md} aligned reads have no MD tag: no truth for them"]
                        if no_md else [])


def _records(pysam, path: Path) -> tuple[list[tuple[MeasuredRead, bool]], str, str]:
    """The primary records, each with whether an aligned one had MD, and the flow order and
    key; a corrupted or truncated file refused naming the record and the byte (the BGZF
    block's offset)."""
    try:
        bam = pysam.AlignmentFile(str(path), "rb", check_sq=False, ignore_truncation=True)
    except (ValueError, OSError) as exc:
        raise ScenarioError(str(path), "header", str(exc),
                            "must be a whole, uncorrupted BAM file") from None
    out: list[tuple[MeasuredRead, bool]] = []
    header = bam.header.to_dict()
    flow_order = key = ""
    number = 0
    it = bam.fetch(until_eof=True)
    try:
        while True:
            offset = bam.tell() >> 16  # BGZF virtual offset: the block's byte in the file
            try:
                rec = next(it)
            except StopIteration:
                break
            except (ValueError, OSError) as exc:
                raise ScenarioError(str(path), f"record {number + 1} (byte {offset})",
                                    str(exc), "must be a whole, uncorrupted BAM file") from None
            number += 1
            if rec.is_secondary or rec.is_supplementary:
                continue
            fo, ks = _read_group(path, header,
                                 rec.get_tag("RG") if rec.has_tag("RG") else None, number)
            if not flow_order:
                check_flow_order(path, "read group FO/KS", fo, ks)
                flow_order, key = fo, ks
            elif (fo, ks) != (flow_order, key):
                raise ScenarioError(str(path), f"record {number} read group", rec.get_tag("RG"),
                                    "every read must share one flow order and key")
            read, has_md = _read(path, rec, number, flow_order, key)
            out.append((read, has_md))
    finally:
        try:
            bam.close()
        except OSError:
            pass  # closing a truncated file: already refused
    return out, flow_order, key


def _read(path: Path, rec, number: int, flow_order: str, key: str
          ) -> tuple[MeasuredRead, bool]:
    """One primary record in flow order, with its truth when it is aligned with ``MD``."""
    values = _flow_signals(path, rec, number)
    where = f"record {number} ({rec.query_name})"
    if values.size > len(flow_order):
        raise ScenarioError(str(path), where, f"{values.size} flow signals",
                            f"must be at most the read group's {len(flow_order)} flows")
    if rec.has_tag("ZF") and rec.get_tag("ZF") < key_flows(key, flow_order)[-1]:
        raise ScenarioError(str(path), f"{where} ZF", rec.get_tag("ZF"),
                            f"the first flow after key {key} must be at least its last flow, "
                            f"{int(key_flows(key, flow_order)[-1])}: key and flow order do not "
                            "match the read")
    seq = (rec.query_sequence or "").upper()
    qual = np.asarray(rec.query_qualities if rec.query_qualities is not None
                      else np.zeros(len(seq)), dtype=np.uint8)
    reverse = rec.is_reverse
    flow_seq = reverse_complement(seq) if reverse else seq
    flow_qual = qual[::-1].copy() if reverse else qual
    truth, truth_from, has_md = None, 0, True
    if not rec.is_unmapped and rec.cigartuples:
        has_md = rec.has_tag("MD")
        hard = any(op == _H for op, _ in rec.cigartuples)
        if has_md and not hard:
            try:
                ref = reference_from_md(seq, rec.cigartuples, rec.get_tag("MD"))
            except ValueError as exc:
                raise ScenarioError(str(path), f"{where} MD", rec.get_tag("MD"),
                                    f"must match the read's CIGAR {rec.cigarstring} ({exc})"
                                    ) from None
            truth_from = _soft_clip_5p(rec.cigartuples, reverse)
            truth = flow_seq[:truth_from] + (reverse_complement(ref) if reverse else ref)
    return MeasuredRead(rec.query_name, values, flow_seq, flow_qual, truth, truth_from), has_md
