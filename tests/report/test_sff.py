"""reads.sff: the writer against Biopython's SFF reader (the oracle), whole or nothing, and a
run's reads read back value for value."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

Bio = pytest.importorskip("Bio.SeqIO")

from chiptwin.config import load_scenario  # noqa: E402
from chiptwin.report import write_outputs  # noqa: E402
from chiptwin.report.sff import SffRead, sff_bytes, write_sff  # noqa: E402
from chiptwin.twin import run  # noqa: E402


def _parse(path) -> list:
    with open(path, "rb") as f:
        return list(Bio.parse(f, "sff"))


def _reads() -> list[SffRead]:
    order = "TACG" * 5
    calls = [np.array([1, 0, 1, 0, 0, 1, 0, 1, 2, 0, 0, 3, 0, 0, 1, 0, 0, 0, 0, 1]),
             np.array([1, 0, 1, 0, 0, 1, 0, 1, 0, 2, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0])]
    out = []
    for j, c in enumerate(calls):
        bases = "".join(order[k] * int(n) for k, n in enumerate(c))
        out.append(SffRead(f"read{j}_x", (c * 100 + j * 7).astype(np.uint16), bases,
                           np.arange(len(bases), dtype=np.uint8) + 20,
                           np.repeat(np.arange(c.size), c), 5, len(bases) - j))
    return out


def test_biopython_reads_back_every_field(tmp_path):
    reads = _reads()
    path = write_sff(tmp_path / "reads.sff", "TACG" * 5, "TCAG", reads)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no padding or clip warning from the reader
        records = _parse(path)
    assert len(records) == 2
    for rec, r in zip(records, reads, strict=True):
        assert rec.id == r.name and str(rec.seq).upper() == r.bases
        assert rec.letter_annotations["phred_quality"] == r.qualities.tolist()
        assert list(rec.annotations["flow_values"]) == r.flowgram_x100.tolist()
        index = np.cumsum(rec.annotations["flow_index"]) - 1  # relative, 1-based
        assert index.tolist() == r.flow_index.tolist()
        assert rec.annotations["clip_qual_left"] == r.clip_qual_left - 1  # 0-based there
        assert rec.annotations["clip_qual_right"] == r.clip_qual_right
        assert rec.annotations["flow_chars"] == "TACG" * 5 and rec.annotations["flow_key"] == "TCAG"
    assert len(path.read_bytes()) % 8 == 0


def test_a_bad_read_writes_nothing_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "reads.sff"
    path.write_bytes(b"previous")
    good = _reads()[0]
    bad = SffRead("bad", good.flowgram_x100[:-1], good.bases, good.qualities, good.flow_index)
    with pytest.raises(ValueError, match="flowgram values"):
        write_sff(path, "TACG" * 5, "TCAG", [good, bad])
    assert path.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reads.sff"]  # no temporary left


def test_flow_index_steps_beyond_one_byte_are_refused():
    r = SffRead("far", np.zeros(300, np.uint16), "TT", np.array([30, 30], np.uint8),
                np.array([0, 290]))
    with pytest.raises(ValueError, match="one byte"):
        sff_bytes("TACG" * 75, "TCAG", [r])


def test_run_writes_reads_sff_biopython_reads_back(tmp_path):
    """The long-read scene cut to 2 sites and 80 flows: what Biopython reads back equals what
    the twin called, value for value."""
    s = load_scenario("scenarios/pyro_long_read.toml",
                      ["sites.at_pixels=[[4, 8], [2, 3]]", "assay.n_flows=80",
                       "run.duration_s=4820"])
    result = run(s)
    out = write_outputs(result, tmp_path / "out")
    records = _parse(out / "reads.sff")
    a = result.arrays
    assert len(records) == 2
    for j, rec in enumerate(records):
        calls = a["read_calls"][j]
        bases = "".join("TACG"[k % 4] * int(c) for k, c in enumerate(calls))
        assert str(rec.seq).upper() == bases and len(bases) > 40
        assert list(rec.annotations["flow_values"]) == a["read_flowgram_x100"][j].tolist()
        q = a["read_quality"][a["read_quality_offsets"][j]:a["read_quality_offsets"][j + 1]]
        assert rec.letter_annotations["phred_quality"] == q.tolist()
        assert rec.annotations["clip_qual_right"] == \
            result.summary["reads"]["sites"][j]["q20_read_length"]
    report = (out / "report.md").read_text()
    assert "## Reads" in report and "read length at Q20" in report
    for plot in ("flowgram.png", "accuracy_position.png", "homopolymer_errors.png",
                 "read_length.png", "quality_calibration.png"):
        assert (out / plot).stat().st_size > 1000 and f"({plot})" in report
