"""BAM in: Ion Torrent's flowgrams through pysam (the ``bam`` extra), aligned or not.

Per read, as Torrent Suite's BaseCaller writes it (``Analysis/BaseCaller/BaseCaller.cpp`` of the
iontorrent/TS repository, releases 2.2 to 5.18): the flow signals in ``FZ`` or ``ZM``, ``ZF`` the
flow of the read's first base after the key (and barcode), the read group's ``FO`` flow order
(one letter per flow, e.g. 1,000 flows, not a repeating cycle) and ``KS`` key. The stored
sequence and qualities (without the key) are the instrument's calls; a reverse-strand read is
turned back to flow order (reverse-complemented, qualities reversed).

- ``FZ`` (``B:S``): flow values × 100, rounded, from flow 0 (key flows included). Up to release
  3.2 BaseCaller's flowgram was its "corrected ionogram": already phase-corrected. From 3.4 on
  ``FZ`` is written only on request (``--flow-signals-type``, default ``none``).
- ``ZM`` (``B:s``, from 3.4 on, every read): the normalised flow signals before phase
  correction (carry-forward, incomplete extension and droop still in them: ``--caller dephase``
  fits those), also from flow 0 with the key flows, stored as ``2·trunc(128·x)`` (clipped to
  ±32,766 from release 4.6 on; ``scaleup_flowgram`` from 5.2). Read as ZM / 256, as Torrent
  Suite's own readers do (``VariantCaller/Reads/ExtendedReadInfo.cpp``,
  ``Converter/bam2sff.cpp``): within 1/128 of the value, toward 0. It stops 16 flows after the
  flow of the read's last base (from 5.4 unless ``--trim-zm`` is off, always before); a short
  array is kept as a short ``FZ`` is (the read has that many flows), one longer than the flow
  order refused.
- ``ZP`` (``B:f``): the read's carry-forward, incomplete extension and droop fitted by
  BaseCaller; summarised in the file's notes, not used (the dephasing caller fits its own).

A read carrying both reads ``FZ`` (the values this reader is validated against on real data;
Torrent Suite's bam2sff takes ``ZM``), and the notes say how many did; a read with neither is
refused naming both tags.

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
from typing import NamedTuple

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


#: Flow-signal tags in the order they are read, each with its counts per 1-mer (module docstring).
SIGNAL_TAGS = {"FZ": 100.0, "ZM": 256.0}


def _flow_signals(path: Path, rec, where: str) -> tuple[np.ndarray, str]:
    """The read's flow values from flow 0 (1-mer ≈ 1) and the tag they came from: ``FZ`` when
    present, else ``ZM``; an integer array either way."""
    tag = next((t for t in SIGNAL_TAGS if rec.has_tag(t)), None)
    if tag is None:
        raise ScenarioError(str(path), where, "no FZ or ZM tag",
                            "every read needs its flow signals: the FZ tag (values × 100 from "
                            "flow 0) or the ZM tag (values × 256 from flow 0), as Torrent Suite "
                            "writes them")
    raw = np.asarray(rec.get_tag(tag))
    if raw.ndim != 1 or raw.dtype.kind not in "iu":
        shown = f"{raw.dtype.name} array of {raw.size}" if raw.ndim == 1 else rec.get_tag(tag)
        raise ScenarioError(str(path), f"{where} {tag}", shown,
                            "must be an array of integers (B:S for FZ, B:s for ZM), as Torrent "
                            "Suite writes it")
    return raw.astype(np.float64) / SIGNAL_TAGS[tag], tag


def _phasing(rec) -> tuple[float, float, float] | None:
    """The read's ``ZP`` carry-forward, incomplete extension and droop, when it holds three
    fractions in [0, 1] (the range Torrent Suite's variant caller accepts)."""
    if not rec.has_tag("ZP"):
        return None
    zp = np.asarray(rec.get_tag("ZP"))
    if zp.shape != (3,) or zp.dtype.kind not in "fiu" or not np.all((zp >= 0) & (zp <= 1)):
        return None
    return float(zp[0]), float(zp[1]), float(zp[2])


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


class _Record(NamedTuple):
    """One primary record read: whether an aligned one had ``MD``, the tag its flow values came
    from, whether it carried both, and its ``ZP`` phasing."""

    read: MeasuredRead
    has_md: bool
    tag: str
    both: bool
    phasing: tuple[float, float, float] | None


def read_bam(path: Path) -> FlowgramFile:
    """Every primary read of the BAM file at ``path`` (module docstring)."""
    pysam = require("bam", path)
    verbosity = pysam.set_verbosity(0)  # htslib's own lines on stderr: the refusal says it
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "no BGZF EOF marker": a truncated read says more
            records, flow_order, key = _records(pysam, path)
    finally:
        pysam.set_verbosity(verbosity)
    if not records:
        raise ScenarioError(str(path), "reads", 0, "must hold one primary read or more")
    aligned = any(r.read.truth is not None for r in records)
    return FlowgramFile(path, "bam", "Ion Torrent (BAM)", flow_order, key,
                        [r.read for r in records],
                        truth_source="alignment" if aligned else None, notes=_notes(records))


def _notes(records: list[_Record]) -> list[str]:
    """What the file's reader did that the figures do not show."""
    notes = []
    no_md = sum(not r.has_md for r in records)
    if no_md:
        notes.append(f"{no_md} aligned reads have no MD tag: no truth for them")
    zm = sum(r.tag == "ZM" for r in records)
    if zm:
        notes.append(f"{zm} reads' flow values from ZM (÷ 256; normalised, not phase-corrected: "
                     "--caller dephase fits their phasing)")
    both = sum(r.both for r in records)
    if both:
        notes.append(f"{both} reads carry both FZ and ZM: FZ read")
    zp = np.array([r.phasing for r in records if r.phasing is not None])
    if zp.size:
        cf, ie, dr = np.median(zp, axis=0)
        notes.append(f"{len(zp)} reads carry the instrument's phasing (ZP), not used: median "
                     f"carry-forward {cf:.4f}, incomplete extension {ie:.4f}, droop {dr:.4f}")
    return notes


def _records(pysam, path: Path) -> tuple[list[_Record], str, str]:
    """The primary records, and the flow order and key; a corrupted or truncated file refused
    naming the record and the byte (the BGZF block's offset)."""
    try:
        bam = pysam.AlignmentFile(str(path), "rb", check_sq=False, ignore_truncation=True)
    except (ValueError, OSError) as exc:
        raise ScenarioError(str(path), "header", str(exc),
                            "must be a whole, uncorrupted BAM file") from None
    out: list[_Record] = []
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
            out.append(_read(path, rec, number, flow_order, key))
    finally:
        try:
            bam.close()
        except OSError:
            pass  # closing a truncated file: already refused
    return out, flow_order, key


def _read(path: Path, rec, number: int, flow_order: str, key: str) -> _Record:
    """One primary record in flow order, with its truth when it is aligned with ``MD``."""
    where = f"record {number} ({rec.query_name})"
    values, tag = _flow_signals(path, rec, where)
    if values.size > len(flow_order):
        raise ScenarioError(str(path), f"{where} {tag}", f"{values.size} flow signals",
                            f"must be at most the read group's {len(flow_order)} flows")
    seq = (rec.query_sequence or "").upper()
    # a read with no base after the key has no first flow: Torrent Suite writes ZF 0 for it
    if seq and rec.has_tag("ZF") and rec.get_tag("ZF") < key_flows(key, flow_order)[-1]:
        raise ScenarioError(str(path), f"{where} ZF", rec.get_tag("ZF"),
                            f"the first flow after key {key} must be at least its last flow, "
                            f"{int(key_flows(key, flow_order)[-1])}: key and flow order do not "
                            "match the read")
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
    read = MeasuredRead(rec.query_name, values, flow_seq, flow_qual, truth, truth_from)
    return _Record(read, has_md, tag, all(rec.has_tag(t) for t in SIGNAL_TAGS), _phasing(rec))
