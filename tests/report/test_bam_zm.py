"""Ion BAMs whose flow signals are in ``ZM`` (Torrent Suite 3.4 on, usually without ``FZ``):
read as ZM / 256 from flow 0, key flows included, on the flow axis FZ / 100 is read on; the
same values to ZM's quantum and the same calls through ``chiptwin reads call`` as the same reads
written with FZ; FZ read when a record carries both; a record with neither refused naming it."""

from __future__ import annotations

import json
from array import array

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError
from chiptwin.detection.key_pass import key_counts
from chiptwin.report.flowgram_files import read_flowgrams
from chiptwin.report.flowgrams import key_flows
from tests.conftest import real_data, require_module

pysam = require_module("pysam")

ORDER = "TACG" * 25  # 100 flows
KEY = "TCAG"


def zm_of(x) -> array:
    """ZM as Torrent Suite's BaseCaller stores flow values ``x`` (1-mer = 1): 2·trunc(128·x),
    clipped to ±16,383 before doubling (Analysis/BaseCaller/BaseCaller.cpp of iontorrent/TS:
    ``scaleup_flowgram`` in releases 5.2 to 5.18; inline from 3.4, the clip from 4.6)."""
    v = np.clip(np.trunc(128.0 * np.asarray(x, dtype=np.float64)), -16383, 16383)
    return array("h", (2 * v).astype(np.int16).tolist())


def _bam(path, reads, fo=ORDER, ks=KEY):
    """An unaligned Ion-like BAM: each read (name, sequence, tags besides RG)."""
    header = {"HD": {"VN": "1.6"}, "RG": [{"ID": "r1", "FO": fo, "KS": ks}]}
    with pysam.AlignmentFile(str(path), "wb", header=header) as out:
        for name, seq, tags in reads:
            a = pysam.AlignedSegment()
            a.query_name, a.query_sequence, a.flag = name, seq, 4
            a.query_qualities = pysam.qualitystring_to_array("I" * len(seq))
            a.set_tags([("RG", "r1"), *tags])
            out.write(a)
    return path


def _reads(rng, n=12):
    """``n`` reads as an Ion run stores them: key TCAG, then a random template; FZ the flow
    values × 100 rounded and clipped at 0; the bases after the key; ZF their first flow."""
    out = []
    for j in range(n):
        calls = np.zeros(len(ORDER), dtype=np.int64)
        calls[[0, 2, 5, 7]] = 1  # TCAG
        calls[8:] = rng.choice([0, 0, 1, 1, 2, 3], len(ORDER) - 8)
        fz = np.clip(np.rint(100 * (calls + rng.normal(0, 0.08, len(ORDER)))), 0, None)
        bases = "".join(ORDER[k] * int(c) for k, c in enumerate(calls))[len(KEY):]
        zf = int(np.flatnonzero(calls[8:])[0]) + 8
        out.append((f"r{j:02d}", bases, fz.astype(np.uint16), zf))
    return out


def _twins(tmp_path, reads):
    """The same reads written with FZ and with ZM only (ZM made from the FZ values)."""
    fz = _bam(tmp_path / "fz.bam", [(name, seq, [("ZF", zf), ("FZ", array("H", v.tolist()))])
                                    for name, seq, v, zf in reads])
    zm = _bam(tmp_path / "zm.bam", [(name, seq, [("ZF", zf), ("ZM", zm_of(v / 100.0))])
                                    for name, seq, v, zf in reads])
    return fz, zm


def test_zm_gives_the_fz_values_to_its_quantum_flow_for_flow(tmp_path):
    """BaseCaller truncates 128·x toward 0 and doubles it: ZM / 256 is within 1/128 of the
    value, never above it for x ≥ 0; every flow on the same index as FZ's, from flow 0."""
    fz, zm = (read_flowgrams(p) for p in _twins(tmp_path, _reads(np.random.default_rng(7))))
    assert [r.name for r in zm.reads] == [r.name for r in fz.reads]
    assert [r.bases for r in zm.reads] == [r.bases for r in fz.reads]
    for a, b in zip(fz.reads, zm.reads, strict=True):
        assert b.values.shape == a.values.shape == (len(ORDER),)
        gap = a.values - b.values
        assert gap.min() >= 0 and gap.max() < 1 / 128
    assert zm.notes[0].startswith("12 reads' flow values from ZM")
    assert not any("FZ and ZM" in n for n in zm.notes + fz.notes)


def test_a_zm_bam_is_called_as_its_fz_twin(tmp_path):
    """Through the command: the FASTQ of the ZM file holds the FZ file's calls, read for read
    (rounding cannot tell them apart: hundredths never cross a half-base boundary when
    truncated by less than 1/128)."""
    fz, zm = _twins(tmp_path, _reads(np.random.default_rng(11)))
    seqs = []
    for path in (fz, zm):
        out = tmp_path / f"{path.stem}-out"
        assert main(["reads", "call", str(path), "--out", str(out), "--quiet"]) == 0
        seqs.append((out / "reads.fastq").read_text().splitlines()[1::4])
    assert seqs[0] == seqs[1] and len(seqs[0]) == 12


def test_the_real_ion_reads_written_as_zm_make_the_same_calls_and_errors(tmp_path):
    """Validation on the measured Ion PGM set (E. coli K-12, aligned): every record rewritten
    with ZM in place of FZ (as BaseCaller would have stored the same values); the first 60
    reads called by rounding make the same calls and the same errors against the reference."""
    src = real_data("ion", "b7_295_chunk.bam")
    zm = tmp_path / "b7_295_zm.bam"
    with pysam.AlignmentFile(str(src), "rb") as bam, \
            pysam.AlignmentFile(str(zm), "wb", template=bam) as out:
        for rec in bam:
            fz = np.asarray(rec.get_tag("FZ"), dtype=np.float64) / 100.0
            rec.set_tag("FZ", None)
            rec.set_tag("ZM", zm_of(fz))
            out.write(rec)
    summaries = []
    for path in (src, zm):
        out = tmp_path / f"{path.stem}-out"
        assert main(["reads", "call", str(path), "--first", "60", "--out", str(out),
                     "--quiet"]) == 0
        summaries.append(((out / "reads.fastq").read_text().splitlines()[1::4],
                          json.loads((out / "reads.json").read_text())))
    (fz_seqs, fz_s), (zm_seqs, zm_s) = summaries
    assert zm_seqs == fz_seqs and len(zm_seqs) == 60
    assert zm_s["twin_vs_truth"]["errors"] == fz_s["twin_vs_truth"]["errors"]


#: The first 32 ZM values of read 4XJVR:04902:13325 (Ion Proton, Torrent Suite 5, ZF 28,
#: forward strand, sequence CCCTAACCC…), flow order TACGTACGTCTGAGCATCGATCGATGTACAGC, KS
#: TCAGCGGAAGAACCTCGAT (key, barcode IonXpress_076 and its adapter): uca-mdlab/sanefalcon,
#: tests/data/bamtest/Auto_user_PROTON-135-DPNI_050717_chip1_198_327_IonXpress_076_rawlib_dedup_
#: test.bam, its first record.
PROTON_ZM = (246, -20, 262, 14, -4, 228, 14, 270, -14, 198, -12, 434, 500, 248, 10, 506, -2, 464,
             54, -10, 234, 278, 282, 244, 224, 0, -20, 14, 838, 6, 0, 32)
PROTON_FO = "TACGTACGTCTGAGCATCGATCGATGTACAGC"
PROTON_KS = "TCAGCGGAAGAACCTCGAT"


def test_zm_starts_at_flow_0_with_the_key_flows_in_a_real_record(tmp_path):
    """Validation of the start flow on a real Torrent Suite record: its ZM / 256 rounded spells
    the key and barcode flow for flow from flow 0 (25 flows), the empty flows after them read
    0, and flow ZF = 28 holds the read's first bases (CCC: 838 / 256 = 3.27). Shifted by one
    flow either way, the key would not be spelled."""
    path = _bam(tmp_path / "proton.bam", [("4XJVR:04902:13325", "CCCTAACCC",
                                           [("ZF", 28), ("ZM", array("h", PROTON_ZM))])],
                fo=PROTON_FO, ks=PROTON_KS)
    y = read_flowgrams(path).reads[0].values
    counts = key_counts(PROTON_KS, PROTON_FO)
    assert np.array_equal(np.rint(y[:counts.size]), counts)
    assert np.all(np.rint(y[25:28]) == 0) and np.rint(y[28]) == 3 and PROTON_FO[28] == "C"
    for shift in (-1, 1):
        assert not np.array_equal(np.rint(np.roll(y, shift)[:counts.size]), counts)


def test_a_key_flow_zm_read_lines_up_with_its_fz_twin_and_keeps_its_negative_zeros(tmp_path):
    """The one read "GA" after key TCAG, stored both ways: TS's ZM keeps a 0-mer's negative
    signal (-16 → -0.0625) where FZ clips it at 0; every other flow is the same to 1/128, the
    key's 1-mers at flows 0, 2, 5 and 7, the read's first base (G) at ZF = 7."""
    x = np.zeros(len(ORDER))
    x[[0, 2, 5, 7, 9]] = [1.0, 0.98, 1.03, 1.97, 1.01]
    x[1] = -0.0625
    fz = _bam(tmp_path / "fz.bam", [("r", "GA", [("ZF", 7), ("FZ", array(
        "H", np.clip(np.rint(100 * x), 0, None).astype(int).tolist()))])])
    zm = _bam(tmp_path / "zm.bam", [("r", "GA", [("ZF", 7), ("ZM", zm_of(x))])])
    a, b = read_flowgrams(fz).reads[0].values, read_flowgrams(zm).reads[0].values
    assert b[1] == -0.0625 and a[1] == 0.0
    others = np.arange(len(ORDER)) != 1
    assert np.abs(a - b)[others].max() < 1 / 128
    assert np.all(b[key_flows(KEY, ORDER)] > 0.9) and ORDER[7] == "G"


def test_a_record_with_neither_tag_exits_2_naming_it(tmp_path, capsys):
    path = _bam(tmp_path / "none.bam", [("ok", "GA", [("ZF", 7), ("ZM", zm_of([1] * 8))]),
                                        ("bare", "GA", [("ZF", 7)])])
    out = tmp_path / "out"
    assert main(["reads", "call", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "record 2 (bare)" in err
    assert "FZ" in err and "ZM" in err and not out.exists()


def test_fz_wins_over_zm_and_the_notes_say_so(tmp_path):
    fz = array("H", [100, 2, 98, 0, 1, 103, 0, 197, 3, 101])
    path = _bam(tmp_path / "both.bam", [("r", "GA", [("ZF", 7), ("FZ", fz),
                                                     ("ZM", zm_of([3.0] * 10))])])
    data = read_flowgrams(path)
    np.testing.assert_array_equal(data.reads[0].values, np.asarray(fz) / 100.0)
    assert "1 reads carry both FZ and ZM: FZ read" in data.notes


@pytest.mark.parametrize("tag", ["FZ", "ZM"])
def test_a_short_array_is_kept_short_and_a_long_one_refused_as_fz_is(tmp_path, tag):
    """BaseCaller stops ZM 16 flows after the flow of the read's last base (from 5.4 unless
    ``--trim-zm`` is off, always before): such a read has that many flows, as a short FZ has
    (neither padded nor refused); one longer than the flow order is refused naming the record
    and the tag."""
    def encode(x):
        return zm_of(x) if tag == "ZM" else array("H", np.rint(np.asarray(x) * 100).astype(int))
    short = [1.0, 0, 1.0, 0, 0, 1.0, 0, 2.0, 0, 1.0, 0, 0]
    data = read_flowgrams(_bam(tmp_path / "s.bam", [("r", "GA", [("ZF", 7),
                                                                 (tag, encode(short))])]))
    np.testing.assert_allclose(data.reads[0].values, short, atol=1 / 128)
    long_path = _bam(tmp_path / "l.bam", [("r", "GA", [("ZF", 7), (tag, encode([0.0] * 101))])])
    with pytest.raises(ScenarioError, match=rf"record 1 \(r\) {tag} = '101 flow signals'.*100"):
        read_flowgrams(long_path)


@pytest.mark.parametrize(("value", "shown"), [(array("f", [1.0, 0.0, 1.0]), "'float32 array of 3'"),
                                              ("100,0,98", "'100,0,98'")])
def test_a_zm_that_is_not_an_integer_array_is_refused(tmp_path, value, shown):
    path = _bam(tmp_path / "f.bam", [("r", "GA", [("ZF", 7), ("ZM", value)])])
    with pytest.raises(ScenarioError, match=rf"f\.bam: record 1 \(r\) ZM = {shown}: .*integers"):
        read_flowgrams(path)


def test_zp_phasing_is_summarised_in_the_notes_and_a_bad_one_left_out(tmp_path):
    """ZP is BaseCaller's carry-forward, incomplete extension and droop of the read (three
    fractions); the notes give their medians over the reads that carry a valid one."""
    zm = zm_of([1, 0, 1, 0, 0, 1, 0, 2, 0, 1])
    reads = [(f"r{j}", "GA", [("ZF", 7), ("ZM", zm), ("ZP", array("f", zp))])
             for j, zp in enumerate([(0.01, 0.004, 0.001), (0.012, 0.006, 0.0),
                                     (0.008, 0.005, 0.002), (1.5, 0.0, 0.0), (0.01, 0.0)])]
    notes = read_flowgrams(_bam(tmp_path / "zp.bam", reads)).notes
    assert ("3 reads carry the instrument's phasing (ZP), not used: median carry-forward "
            "0.0100, incomplete extension 0.0050, droop 0.0010") in notes


def test_a_read_with_no_base_after_the_key_and_zf_0_is_read(tmp_path):
    """Torrent Suite writes ZF 0 for a read with no base after the key (an unfiltered BAM holds
    such reads): it is read, not refused as a key that does not match; a read with bases and
    ZF 0 still is."""
    (name, seq, fz, zf), = _reads(np.random.default_rng(7), 1)
    signals = ("FZ", array("H", fz.tolist()))
    empty = _bam(tmp_path / "empty.bam", [(name, seq, [("ZF", zf), signals]),
                                          ("none", "", [("ZF", 0), ("FZ", array("H", [100] * 8))])])
    got = read_flowgrams(empty)
    assert [r.name for r in got.reads] == [name, "none"] and got.reads[1].values.size == 8
    bad = _bam(tmp_path / "bad.bam", [(name, seq, [("ZF", 0), signals])])
    with pytest.raises(ScenarioError, match="ZF"):
        read_flowgrams(bad)
