"""``chiptwin reads call``: the twin's callers on real flowgrams against the instrument's calls
and the truth, the key-pass filter, the outputs (FASTQ, SFF that Biopython trims to what the
twin calls good, under the user's umask) and the command line's refusals."""

from __future__ import annotations

import os
import re
import stat

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.kinetics.pyro import flow_incorporations
from chiptwin.report.reads_call import call_file, write_reads_outputs
from chiptwin.report.sff import SffRead, write_sff
from tests.conftest import real_data, require_module

require_module("pysam")
SeqIO = require_module("Bio.SeqIO")


@pytest.fixture(scope="module")
def ion_round():
    return call_file(real_data("ion", "b7_295_chunk.bam"), caller="round")


def test_round_on_ion_flow_signals_makes_the_instruments_calls(ion_round):
    """Validation. The 449 Ion PGM reads (E. coli K-12) against the reference under each (CIGAR
    + MD): the instrument's calls make 1,193 errors in 147,535 reference bases (edit distance,
    counted by hand by a colleague), and so does rounding FZ/100, since these flow values are
    already phase-corrected. Exact."""
    s = ion_round.summary
    for side in ("twin_vs_truth", "instrument_vs_truth"):
        r = s[side]
        assert (r["reads"], r["errors"], r["truth_bases"]) == (449, 1193, 147535)
        assert (r["mismatches"], r["insertions"], r["deletions"]) == (114, 491, 588)
    hp = {r["length"]: r for r in s["twin_vs_truth"]["homopolymers"]}
    assert hp[1]["runs"] > 80000 and hp[1]["accuracy"] > 0.99 and hp[5]["accuracy"] < 0.9
    assert s["key_fail_reads"] == 0 and s["flows"] == 1000
    assert [r["q_lo"] for r in s["instrument_vs_truth"]["calibration"]][:2] == [0, 10]


def test_dephase_leaves_phase_corrected_flowgrams_as_they_are():
    """The phase-correcting caller on flow values already corrected: no phasing estimated on
    most reads, and no more errors than the instrument's than a few (60 reads: 168 against
    164; all 449: 1,177 against 1,193)."""
    s = call_file(real_data("ion", "b7_295_chunk.bam"), caller="dephase", first=60).summary
    assert s["phasing_estimated_zero"] >= 50
    assert s["twin_vs_truth"]["errors"] <= 1.1 * s["instrument_vs_truth"]["errors"]


@pytest.mark.parametrize(("caller", "first", "least", "n"), [("round", 200, 0.9995, 13),
                                                             ("dephase", 100, 0.995, 4)])
def test_454_calls_agree_with_the_instruments(caller, first, least, n):
    """Fasting_Example.sff (454 GS FLX): the calls agree with the instrument's on ≥ 99.5 % of
    its bases (measured: round 99.97 % on the first 200 reads, 99.98 % on all 1,339; dephase
    99.95 % on the first 100, 99.94 % on all); the instrument's N are counted apart."""
    s = call_file(real_data("sff", "Fasting_Example.sff"), caller=caller, first=first).summary
    assert s["twin_vs_instrument"]["agreement"] >= least
    assert s["instrument_n_bases"] == n and s["reads"] == first  # the instrument's N


def _synthetic_sff(path, rng):
    """Twelve 100-flow reads: ten clean (key TCAG, then a random template read through the
    flow order, so that each flowgram is one a template can make), one whose first flow is
    empty (fails the key), one of noise after the key (no base at Q20)."""
    order = "TACG" * 25
    reads = []
    for j in range(12):
        template = "TCAG" + "".join(rng.choice(list("ACGT"), 120))
        calls = flow_incorporations(template, order, 100)[1]
        y = calls + rng.normal(0, 0.05, 100)
        if j == 10:
            y[0] = 0.02  # no T: the key fails
        if j == 11:
            y[8:] = 0.5 + rng.normal(0, 0.02, 92)  # half a base in every flow
        bases = "".join(order[k] * int(c) for k, c in enumerate(calls))
        reads.append(SffRead(f"r{j:02d}", np.clip(np.rint(y * 100), 0, None).astype(np.uint16),
                             bases, np.full(len(bases), 30, np.uint8),
                             np.repeat(np.arange(100), calls), 5, len(bases)))
    return write_sff(path, order, "TCAG", reads)


def test_outputs_fastq_sff_trimmed_as_the_twin_says_and_the_umask(tmp_path):
    path = _synthetic_sff(tmp_path / "in.sff", np.random.default_rng(3))
    result = call_file(path)
    s = result.summary
    assert s["key_fail_reads"] == 1 and s["reads_without_q20_bases"] == 1
    old = os.umask(0o027)
    try:
        out = write_reads_outputs(result, tmp_path / "out")
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o750
    for name in ("reads.fastq", "reads.sff", "report.md", "reads.json"):
        assert stat.S_IMODE((out / name).stat().st_mode) == 0o640, name
    fastq = (out / "reads.fastq").read_text().splitlines()
    names = fastq[0::4]
    assert names == [f"@r{j:02d}" for j in range(12) if j != 10]  # the key-fail read dropped
    good = {r["name"]: r["q20_read_length"] for r in s["read_rows"]}
    with open(out / "reads.sff", "rb") as f, pytest.warns(Warning, match="trimmed to nothing"):
        trimmed = {rec.id: str(rec.seq) for rec in SeqIO.parse(f, "sff-trim")}
    assert set(trimmed) == {n[1:] for n in names}
    for name, seq in zip(names, fastq[1::4], strict=True):
        assert trimmed[name[1:]] == seq[:good[name[1:]]]  # exactly the bases at Q20
    assert trimmed["r11"] == "" and len(trimmed["r00"]) > 50


def test_command_writes_its_outputs_and_prints_the_figures(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["reads", "call", str(real_data("sff", "greek.sff")), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "agreement" in text and "99.391 %" in text and "115 N" in text
    assert {p.name for p in out.iterdir()} == {"reads.fastq", "reads.sff", "report.md",
                                               "reads.json"}
    assert "## Against the instrument's calls" in (out / "report.md").read_text()


@pytest.mark.parametrize(("argv", "match"), [
    (["{invalid}"], r"invalid_greek_E3MFGYR02\.sff: end, after record 24 \(byte 65296\)"),
    (["{greek}", "--first", "0"], r"--first = 0: must be 1 or more"),
    (["{greek}", "--truth", "{missing}"], r"--truth = .*must be a FASTA file"),
    (["{missing}"], r"FILE = .*must be an SFF or BAM file"),
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, argv, match):
    paths = {"invalid": real_data("sff", "invalid_greek_E3MFGYR02.sff"),
             "greek": real_data("sff", "greek.sff"), "missing": tmp_path / "none.fa"}
    out = tmp_path / "o"
    args = [a.format(**paths) for a in argv]
    assert main(["reads", "call", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and re.search(match, err[0]), err
    assert not out.exists()


def test_help_has_examples(capsys):
    assert main(["reads", "--help"]) == 0
    out = capsys.readouterr().out
    assert "chiptwin reads call" in out.split("examples:", 1)[1]


def test_an_sff_without_flow_values_is_refused(tmp_path):
    import struct

    head = struct.pack(">I4sQIIHHHB", 0x2E736666, b"\x00\x00\x00\x01", 0, 0, 1, 40, 4, 0, 1)
    head += b"TCAG" + bytes(5)
    read = struct.pack(">HHIHHHH", 24, 1, 0, 0, 0, 0, 0) + b"r" + bytes(7)
    (tmp_path / "none.sff").write_bytes(head + read)
    with pytest.raises(Exception, match=r"none\.sff: header flow order = '': must hold flow"):
        call_file(tmp_path / "none.sff")


def test_the_twins_own_sff_reads_back_in_with_its_empty_clips(tmp_path):
    """reads.sff written by ``reads call`` (a read clipped to nothing included) is read back in
    and called to the same bases."""
    first = call_file(_synthetic_sff(tmp_path / "in.sff", np.random.default_rng(3)))
    out = write_reads_outputs(first, tmp_path / "out")
    again = call_file(out / "reads.sff")
    assert again.summary["reads"] == 11 and again.summary["key_fail_reads"] == 0
    kept = [b for b in first.twin.bases if b is not None]
    assert again.twin.bases == kept
