"""Flowgrams in the field's format: SFF, 454 Life Sciences' Standard Flowgram Format.

Layout (big-endian, every section padded with zeros to a multiple of 8 bytes), as 454's
"Standard Flowgram Format" specification gives it and Biopython's ``Bio.SeqIO`` "sff" reader
checks it:

* common header: magic ``.sff``, version 0.0.0.1, index offset (u64) and length (u32) (0: no
  index), number of reads (u32), header length (u16), key length (u16), flows per read (u16),
  flowgram format code (u8, 1: uint16 hundredths), the flow characters, the key;
* per read, a header: its length (u16), name length (u16), number of bases (u32), clip points
  (u16 each: quality left and right, adapter left and right; 1-based, 0 = not set), the name;
* per read, the data: flowgram values (u16, value × 100, one per flow), the flow index of each
  base (u8, relative to the previous base's flow; the first is 1-based), the bases, the phred
  qualities (u8).

:func:`quality_clip` gives the clip points of a read whose good part follows its key: a read
with no good base is clipped to nothing (``clip_qual_right`` one below ``clip_qual_left``, as
the format allows), never left at 0, which means "not set" and keeps the whole read.

:func:`write_sff` writes a whole file or nothing: to a temporary file in the target's folder,
then ``os.replace``; the file gets the mode the user's umask gives a new file.
"""

from __future__ import annotations

import os
import struct
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from chiptwin.config.outputs import new_file_mode

MAGIC = 0x2E736666  # ".sff"
VERSION = b"\x00\x00\x00\x01"
FLOWGRAM_FORMAT = 1  # uint16, value × 100
_HEADER = ">I4sQIIHHHB"
_READ_HEADER = ">HHIHHHH"


@dataclass(frozen=True)
class SffRead:
    """One read as SFF stores it.

    ``flow_index`` is the 0-based flow of each base (it is written relative, as the format
    asks); clip points are 1-based, 0 = not set.
    """

    name: str
    flowgram_x100: np.ndarray  # uint16 (n_flows,)
    bases: str
    qualities: np.ndarray  # uint8 (n_bases,)
    flow_index: np.ndarray  # int (n_bases,), 0-based absolute
    clip_qual_left: int = 0
    clip_qual_right: int = 0


def quality_clip(key_length: int, good: int) -> tuple[int, int]:
    """``(clip_qual_left, clip_qual_right)``, 1-based, of a read whose first ``good`` bases
    after a key of ``key_length`` bases are kept. No good base: ``right = left − 1``, an empty
    clip (SFF's 0 would mean "not set": ``sff-trim`` and Biopython's ``trim=True`` would keep the
    whole read)."""
    if key_length < 0 or good < 0:
        raise ValueError(f"key_length {key_length} and good {good} must be ≥ 0")
    left = max(key_length, 1) + 1 if good == 0 else key_length + 1
    return min(left, 65535), min(key_length + good if good else left - 1, 65535)


def _pad(n: int) -> bytes:
    return b"\x00" * (-n % 8)


def _check(read: SffRead, n_flows: int) -> None:
    n = len(read.bases)
    if read.flowgram_x100.shape != (n_flows,):
        raise ValueError(f"SFF read {read.name!r}: {read.flowgram_x100.shape} flowgram values, "
                         f"must be ({n_flows},), one per flow")
    if len(read.qualities) != n or len(read.flow_index) != n:
        raise ValueError(f"SFF read {read.name!r}: {n} bases, {len(read.qualities)} qualities, "
                         f"{len(read.flow_index)} flow indices: must be equal")
    if set(read.bases) - set("ACGTN"):
        raise ValueError(f"SFF read {read.name!r}: bases must be A, C, G, T or N")
    steps = np.diff(np.concatenate([[-1], np.asarray(read.flow_index, dtype=np.int64)]))
    if n and (steps.min() < 0 or steps.max() > 255 or read.flow_index[-1] >= n_flows):
        raise ValueError(f"SFF read {read.name!r}: flow indices must rise by 0 … 255 and stay "
                         f"below {n_flows} flows (the format stores each step in one byte)")
    if not 0 <= read.clip_qual_left <= 65535 or not 0 <= read.clip_qual_right <= 65535:
        raise ValueError(f"SFF read {read.name!r}: clip points must be in 0 … 65535")


def sff_bytes(flow_chars: str, key: str, reads: Sequence[SffRead]) -> bytes:
    """The SFF file of ``reads``, as bytes (see the module docstring)."""
    n_flows = len(flow_chars)
    if not 0 < n_flows <= 65535 or not key:
        raise ValueError(f"SFF: {n_flows} flows and key {key!r}: need 1 … 65535 flows, a key")
    head_len = struct.calcsize(_HEADER) + n_flows + len(key)
    out = [struct.pack(_HEADER, MAGIC, VERSION, 0, 0, len(reads), head_len + (-head_len % 8),
                       len(key), n_flows, FLOWGRAM_FORMAT),
           flow_chars.encode("ascii"), key.encode("ascii"), _pad(head_len)]
    for read in reads:
        _check(read, n_flows)
        name = read.name.encode("ascii")
        rh_len = struct.calcsize(_READ_HEADER) + len(name)
        n = len(read.bases)
        out += [struct.pack(_READ_HEADER, rh_len + (-rh_len % 8), len(name), n,
                            read.clip_qual_left, read.clip_qual_right, 0, 0), name, _pad(rh_len)]
        index = np.diff(np.concatenate([[-1], np.asarray(read.flow_index, dtype=np.int64)]))
        out += [np.asarray(read.flowgram_x100, dtype=">u2").tobytes(),
                index.astype(np.uint8).tobytes(), read.bases.encode("ascii"),
                np.asarray(read.qualities, dtype=np.uint8).tobytes(),
                _pad(2 * n_flows + 3 * n)]
    return b"".join(out)


def write_sff(path: str | Path, flow_chars: str, key: str, reads: Sequence[SffRead]) -> Path:
    """Write ``reads`` to ``path`` whole or not at all (temporary file, then ``os.replace``)."""
    path = Path(path)
    data = sff_bytes(flow_chars, key, reads)  # every check before a byte reaches the disk
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, new_file_mode())  # mkstemp's 0600, not the user's choice
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
