"""Measured flowgrams in: SFF (Roche 454) and BAM (Ion Torrent), with the instrument's own calls
and, where the file or the user gives one, the truth under each read.

:func:`read_flowgrams` picks the reader by the file's first bytes (:mod:`.sff_in` through
Biopython, :mod:`.bam_in` through pysam, each an optional extra) and returns one
:class:`chiptwin.report.flowgrams.FlowgramFile`: the file's own flow order (one letter per
flow: Ion's 1,000-flow order is not a repeating cycle), its key, and every read's flow values
(normalised: a 1-mer reads ≈ 1), the instrument's bases and qualities after the key (in flow
order), and its truth. A truth FASTA (:func:`read_truth_fasta`) names each read's template
after the key.

Every refusal is a :class:`chiptwin.config.ScenarioError` naming the file, the record (or the
byte) and what is allowed: a file that is not SFF or BAM, a corrupted or truncated one, a read
without flow values, a flow order with a letter outside ACGT, a key the flow order cannot spell
within the flows, a truth that misses a read or holds other letters.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from chiptwin.config import ScenarioError
from chiptwin.report.bam_in import read_bam
from chiptwin.report.flowgrams import NUCLEOTIDES, FlowgramFile
from chiptwin.report.sff_in import read_sff

__all__ = ["read_flowgrams", "read_truth_fasta", "sniff", "with_truth"]


def sniff(path: Path) -> str:
    """``"sff"`` or ``"bam"`` from the first bytes (BAM is BGZF: gzip with an extra field)."""
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as exc:
        raise ScenarioError(str(path), "file", str(path),
                            f"must be a readable SFF or BAM file ({exc.strerror})") from None
    if head == b".sff":
        return "sff"
    if head[:3] == b"\x1f\x8b\x08":
        return "bam"
    raise ScenarioError(str(path), "format", head.decode("latin-1"),
                        "must be SFF (starts '.sff') or BAM (BGZF-compressed)")


def read_flowgrams(path: str | Path, truth: str | Path | None = None) -> FlowgramFile:
    """The file's reads (module docstring), with the truth FASTA's templates if given (a BAM's
    alignments are its truth otherwise)."""
    path = Path(path)
    kind = sniff(path)
    data = read_sff(path) if kind == "sff" else read_bam(path)
    if truth is not None:
        data = with_truth(data, Path(truth))
    return data


def with_truth(data: FlowgramFile, fasta: Path) -> FlowgramFile:
    """``data`` with each read's truth from a FASTA (record named as the read; its template
    after the key, in flow order)."""
    records = read_truth_fasta(fasta)
    missing = [r.name for r in data.reads if r.name not in records]
    if missing:
        raise ScenarioError(str(fasta), "record", missing[0],
                            f"every read of {data.path.name} needs a truth record of its name "
                            f"({len(missing)} of {len(data.reads)} have none)")
    reads = [replace(r, truth=records[r.name], truth_from=0) for r in data.reads]
    return replace(data, reads=reads, truth_source=str(fasta))


def read_truth_fasta(path: Path) -> dict[str, str]:
    """FASTA records by name (the first word of the header), upper-cased; letters A, C, G, T."""
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(str(path), "--truth", str(path),
                            f"must be a readable ASCII FASTA file ({exc})") from None
    out: dict[str, str] = {}
    name, parts = None, []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if line.startswith(">"):
            if name is not None:
                out[name] = "".join(parts)
            name, parts = (line[1:].split() or [""])[0], []
            if not name or name in out:
                raise ScenarioError(str(path), f"line {number}", line[:40],
                                    "must start a record with a new, non-empty name")
        elif line:
            if name is None:
                raise ScenarioError(str(path), f"line {number}", line[:40],
                                    "must follow a '>name' header line")
            seq = line.upper()
            bad = sorted(set(seq) - set(NUCLEOTIDES))
            if bad:
                raise ScenarioError(str(path), f"record {name}", "".join(bad),
                                    "must hold only A, C, G, T")
            parts.append(seq)
    if name is not None:
        out[name] = "".join(parts)
    if not out:
        raise ScenarioError(str(path), "--truth", str(path), "must hold one FASTA record or more")
    return out
