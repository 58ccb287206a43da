"""Measured flowgrams as the twin holds them: one :class:`FlowgramFile` of
:class:`MeasuredRead` s, whatever format they came in (:mod:`chiptwin.report.flowgram_files`
reads them), and the checks every reader makes: the flow order's letters, a key the flow order
spells, the optional extra each format needs."""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from chiptwin.config import ScenarioError

NUCLEOTIDES = "ACGT"

#: The optional extra that installs each reader's library: (module, package).
EXTRAS = {"sff": ("Bio", "biopython"), "bam": ("pysam", "pysam")}


@dataclass(frozen=True)
class MeasuredRead:
    """One read of a flowgram file.

    ``values`` are the flow values from flow 0 (key flows included), 1-mer ≈ 1. ``bases`` and
    ``quality`` are the instrument's calls after the key, in flow order. ``truth`` is the
    sequence under the read in flow order, starting at its first base after the key; its first
    ``truth_from`` bases are the instrument's own calls standing in for an unknown head (a
    soft-clipped start), not scored. ``off_flow`` counts stored bases whose letter is not their
    flow's nucleotide (SFF's flow index says which flow called each base)."""

    name: str
    values: NDArray[np.float64]
    bases: str
    quality: NDArray[np.uint8]
    truth: str | None = None
    truth_from: int = 0
    off_flow: int = 0


@dataclass(frozen=True)
class FlowgramFile:
    """A flowgram file read whole (module docstring)."""

    path: Path
    kind: str  # "sff" or "bam"
    instrument: str
    flow_order: str  # one letter per flow
    key: str
    reads: list[MeasuredRead]
    truth_source: str | None = None  # "alignment", a FASTA path, or None
    notes: list[str] = field(default_factory=list)

    @property
    def n_flows(self) -> int:
        return len(self.flow_order)

    @property
    def off_flow_bases(self) -> int:
        return sum(r.off_flow for r in self.reads)

    @property
    def stored_bases(self) -> int:
        return sum(len(r.bases) for r in self.reads)


def require(kind: str, path: Path):
    """The library of ``kind``'s reader, or a refusal naming the extra that installs it."""
    module, package = EXTRAS[kind]
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ScenarioError(str(path), "format", kind.upper(),
                            f"reading it needs {package}: pip install \"chiptwin[{kind}]\""
                            ) from None


def check_flow_order(path: Path, where: str, flow_order: str, key: str) -> None:
    """Letters in ACGT, and a key the flow order spells within its flows."""
    if not flow_order:
        raise ScenarioError(str(path), f"{where} flow order", "",
                            "must hold flow values: one flow or more (found none)")
    bad = sorted(set(flow_order) - set(NUCLEOTIDES))
    if bad:
        raise ScenarioError(str(path), f"{where} flow order", flow_order[:40] +
                            ("…" if len(flow_order) > 40 else ""),
                            f"must be letters A, C, G, T (found {''.join(bad)})")
    if not key or set(key) - set(NUCLEOTIDES):
        raise ScenarioError(str(path), f"{where} key", key, "must be one or more of A, C, G, T")
    if key_flows(key, flow_order) is None:
        raise ScenarioError(str(path), f"{where} key", key,
                            f"must be spelled by the flow order within its {len(flow_order)} "
                            f"flows (order starts {flow_order[:12]}…)")


def key_flows(key: str, flow_order: str) -> NDArray[np.int64] | None:
    """The flow of each key base when the flow order dispenses it, or None when the key does
    not fit in the flows."""
    out, f = [], 0
    for i, base in enumerate(key):
        if i and base == key[i - 1]:
            out.append(out[-1])
            continue
        f = f if not out else out[-1] + 1
        while f < len(flow_order) and flow_order[f] != base:
            f += 1
        if f >= len(flow_order):
            return None
        out.append(f)
    return np.array(out, dtype=np.int64)
