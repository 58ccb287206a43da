"""reads.sff: the writer against Biopython's SFF reader (the oracle), whole or nothing, and a
run's reads read back value for value."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tests.conftest import require_module

Bio = require_module("Bio.SeqIO", "sff")  # skips off CI, fails under CI=true

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


@pytest.mark.parametrize(("key", "good", "clip"), [
    (4, 10, (5, 14)),
    (4, 0, (5, 4)),  # nothing good: an empty clip, never 0 ("not set": the whole read kept)
    (0, 0, (2, 1)),
    (0, 3, (1, 3)),
])
def test_quality_clip_of_a_read_after_its_key(key, good, clip):
    from chiptwin.report.sff import quality_clip

    assert quality_clip(key, good) == clip


def test_twin_sff_drops_reads_failing_the_key_and_clips_unreadable_ones_to_nothing(tmp_path):
    """Biopython's trimming reader keeps exactly the bases after the key up to the Q20 length
    the summary states; a site whose first flows do not spell the key is left out."""
    from chiptwin.report.read_plots import sff_reads

    s = load_scenario("scenarios/pyro_long_read.toml")
    order, n = s.assay.flow_order, 40
    calls = np.zeros((3, n), dtype=np.int64)
    for row in calls:
        row[[0, 2, 5, 7]] = 1  # TCAG through TACG
        row[8:] = np.arange(n - 8) % 3
    calls[1, 0] = 0  # no T: the key fails
    q = np.full(int(calls.sum()), 35, np.uint8)
    off = np.concatenate([[0], np.cumsum(calls.sum(axis=1))])
    arrays = {"read_calls": calls, "read_quality": q, "read_quality_offsets": off,
              "read_flowgram_x100": (calls * 100).astype(np.uint16),
              "site_pixel_index": np.arange(3)}
    sites = [{"q20_read_length": 30, "key_pass": True}, {"q20_read_length": 30, "key_pass": False},
             {"q20_read_length": 3, "key_pass": True}]
    records = sff_reads(s, {"reads": {"sites": sites}}, arrays)
    assert [r.name[:8] for r in records] == ["site0000", "site0002"]
    path = write_sff(tmp_path / "reads.sff", "".join(order[k % 4] for k in range(n)), "TCAG",
                     records)
    with open(path, "rb") as f, pytest.warns(Warning, match="trimmed to nothing"):
        trimmed = [str(r.seq) for r in Bio.parse(f, "sff-trim")]
    assert trimmed[0] == records[0].bases[4:30] and trimmed[1] == ""


def test_written_files_and_folders_follow_the_umask(tmp_path):
    """tempfile makes private files (0600) and folders (0700): an output renamed from them
    gets the mode the user's umask gives a new one."""
    import os
    import stat

    from chiptwin.config.outputs import replacing

    old = os.umask(0o002)
    try:
        with replacing(tmp_path / "out") as tmp:
            write_sff(tmp / "reads.sff", "TACG" * 5, "TCAG", _reads())
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "out").stat().st_mode) == 0o775
    assert stat.S_IMODE((tmp_path / "out" / "reads.sff").stat().st_mode) == 0o664
