"""SFF in: Roche 454's flowgrams through Biopython's reader (``Bio.SeqIO.parse(handle, "sff")``,
the ``sff`` extra).

Each read's flow values (hundredths, from flow 0) become values in 1-mers; the stored bases
after the key, upper-cased, and their phred qualities are the instrument's calls. The key is
the header's; a read whose stored bases do not start with it keeps its values (the caller
decides whether it passes the key) and gives no instrument's calls. SFF values are 454's
processed flowgram (key-normalised, phase-corrected).

A corrupted or truncated file (Biopython's errors, a short read, padding holding data, a flow
index past the last flow) is refused naming the file, the record and the byte where reading
stopped.
"""

from __future__ import annotations

import re
import struct
import warnings
from pathlib import Path

import numpy as np

from chiptwin.config import ScenarioError
from chiptwin.report.flowgrams import (
    FlowgramFile,
    MeasuredRead,
    check_flow_order,
    require,
)


def _corrupt(path: Path, where: str, offset: int, why: str) -> ScenarioError:
    """A refusal naming where it was reading (the header, a record, the end) and the byte: the
    one the reader's message names, else where reading stopped."""
    named = re.search(r"offset (\d+)", why)
    return ScenarioError(str(path), f"{where} (byte {named.group(1) if named else offset})",
                         why, "must be a whole, uncorrupted SFF file (Roche's Standard "
                         "Flowgram Format, as 454's sfffile writes it)")


#: The SFF common header's fixed part: magic, version, index offset and length, reads, header
#: length, key length, flows, flowgram format (big-endian).
_HEADER = ">4s4sQIIHHHB"
HEADER_BYTES = struct.calcsize(_HEADER)


def _check_index(path: Path) -> None:
    """A file cut inside the index its header announces is truncated (Biopython stops after the
    announced reads and never looks)."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(HEADER_BYTES)
    if len(head) < HEADER_BYTES:
        raise _corrupt(path, "header", len(head), f"the file ends at byte {len(head)}, inside the "
                       f"{HEADER_BYTES}-byte common header")
    _, _, index_offset, index_length, *_ = struct.unpack(_HEADER, head)
    if index_offset and size < index_offset + index_length:
        raise ScenarioError(str(path), f"index (byte {size})", f"{size} bytes",
                            f"the header announces an index at bytes {index_offset} … "
                            f"{index_offset + index_length}: the file is truncated")


def read_sff(path: Path) -> FlowgramFile:
    """Every read of the SFF file at ``path`` (module docstring)."""
    require("sff", path)
    from Bio import BiopythonParserWarning, SeqIO

    reads: list[MeasuredRead] = []
    flow_order = key = ""
    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("error", BiopythonParserWarning)  # padding holding data
        # ... but a read clipped to nothing is allowed (quality_clip writes them)
        warnings.filterwarnings("ignore", "Overlapping clip values", BiopythonParserWarning)
        records = None
        while True:
            try:
                records = records or SeqIO.parse(handle, "sff")  # reads the header
                rec = next(records)
            except StopIteration:
                break
            except (ValueError, struct.error, UnicodeDecodeError,
                    BiopythonParserWarning) as exc:
                where = ("header" if records is None else
                         f"end, after record {len(reads)}"
                         if len(reads) == getattr(records, "number_of_reads", -1)
                         else f"record {len(reads) + 1}")
                why = str(exc)
                if isinstance(exc, struct.error) and handle.tell() >= path.stat().st_size:
                    why = f"the file ends at byte {handle.tell()}, inside it: truncated ({exc})"
                raise _corrupt(path, where, handle.tell(), why) from None
            if not reads:
                flow_order, key = rec.annotations["flow_chars"], rec.annotations["flow_key"]
                check_flow_order(path, "header", flow_order, key)
            reads.append(_read(path, rec, flow_order, key, len(reads) + 1, handle.tell()))
    _check_index(path)
    if not reads:
        raise ScenarioError(str(path), "reads", 0, "must hold one read or more")
    return FlowgramFile(path, "sff", "Roche 454 (SFF)", flow_order, key, reads)


def _read(path: Path, rec, flow_order: str, key: str, number: int, offset: int) -> MeasuredRead:
    """One record: values in 1-mers, the stored calls after the key, the off-flow bases."""
    ann = rec.annotations
    values = np.asarray(ann["flow_values"], dtype=np.float64) / 100.0
    if values.size != len(flow_order):
        raise _corrupt(path, f"record {number}", offset, f"{values.size} flow values for "
                       f"{len(flow_order)} flows")
    seq = str(rec.seq).upper()
    flow = np.cumsum(np.asarray(ann["flow_index"], dtype=np.int64)) - 1
    if flow.size != len(seq) or (flow.size and (flow[-1] >= len(flow_order) or flow[0] < 0)):
        raise _corrupt(path, f"record {number}", offset, f"read {rec.id}: flow index reaches flow "
                       f"{int(flow[-1]) + 1 if flow.size else 0} of {len(flow_order)}")
    order = np.frombuffer(flow_order.encode("ascii"), dtype=np.uint8)
    off = int(np.sum(order[flow] != np.frombuffer(seq.encode("ascii"), dtype=np.uint8)))
    quality = np.asarray(rec.letter_annotations["phred_quality"], dtype=np.uint8)
    if seq.startswith(key):
        bases, quality = seq[len(key):], quality[len(key):]
    else:
        bases, quality = "", quality[:0]
    return MeasuredRead(rec.id, values, bases, quality, off_flow=off)
