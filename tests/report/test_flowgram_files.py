"""Measured flowgrams in: the real SFF and Ion BAM files read as their formats define, the
reference under a read rebuilt from CIGAR and MD against pysam's (the oracle), and every bad
input refused naming the file, the record or byte, and what is allowed."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from chiptwin.config import ScenarioError
from chiptwin.report.flowgram_files import read_flowgrams, read_truth_fasta
from chiptwin.report.flowgrams import key_flows
from tests.conftest import real_data, require_module

pysam = require_module("pysam")
require_module("Bio")

from chiptwin.report.bam_in import reference_from_md, reverse_complement  # noqa: E402


@pytest.mark.parametrize(("name", "reads", "flows", "n_bases", "stored"), [
    # the README's counts of stored bases whose letter is not their flow's (all N), key included
    ("E3MFGYR02_random_10_reads.sff", 10, 400, 15, 2674),
    ("greek.sff", 24, 800, 115, 8378),
    ("Fasting_Example.sff", 1339, 400, 39, 362861),
])
def test_real_sff_files(name, reads, flows, n_bases, stored):
    data = read_flowgrams(real_data("sff", name))
    assert (len(data.reads), data.n_flows, data.key) == (reads, flows, "TCAG")
    assert data.off_flow_bases == n_bases
    assert data.stored_bases + 4 * reads == stored  # the key's 4 bases per read
    r = data.reads[0]
    assert r.values.shape == (flows,) and 0.8 < r.values[0] < 1.2  # the key's first 1-mer


def test_a_corrupted_sff_is_refused_naming_the_byte():
    path = real_data("sff", "invalid_greek_E3MFGYR02.sff")
    with pytest.raises(ScenarioError, match=r"invalid_greek_E3MFGYR02\.sff: end, after record "
                                            r"24 \(byte 65296\)"):
        read_flowgrams(path)


@pytest.mark.parametrize(("cut", "where"), [
    (20, r"header \(byte 20\)"),
    (5000, r"record 2 \(byte 5000\).*truncated"),
    (65100, r"index \(byte 65100\).*truncated"),
])
def test_a_truncated_sff_is_refused_naming_the_record_and_byte(tmp_path, cut, where):
    path = tmp_path / "cut.sff"
    path.write_bytes(real_data("sff", "greek.sff").read_bytes()[:cut])
    with pytest.raises(ScenarioError, match=where):
        read_flowgrams(path)


def test_ion_bam_reads_in_flow_order_with_the_reference_under_each():
    path = real_data("ion", "b7_295_chunk.bam")
    data = read_flowgrams(path)
    assert (len(data.reads), data.n_flows, data.key) == (449, 1000, "TCAG")
    assert data.flow_order.startswith("TACGTACGTCTGAGCATCGATCGATGTACAGC")
    assert data.truth_source == "alignment"
    by_name = {r.name: r for r in data.reads}
    with pysam.AlignmentFile(str(path), "rb") as bam:
        for rec in bam:
            oracle = rec.get_reference_sequence().upper()
            assert reference_from_md(rec.query_sequence, rec.cigartuples,
                                     rec.get_tag("MD")) == oracle
            r = by_name[rec.query_name]
            assert r.truth == (reverse_complement(oracle) if rec.is_reverse else oracle)
            seq = reverse_complement(rec.query_sequence) if rec.is_reverse else rec.query_sequence
            assert r.bases == seq and r.values.size == 1000
            # the first read flow (ZF) holds the read's first base, after the key's flows
            assert data.flow_order[rec.get_tag("ZF")] == r.bases[0]


def test_md_that_disagrees_with_the_cigar_is_refused():
    with pytest.raises(ValueError, match="covers"):
        reference_from_md("ACGT", [(0, 4)], "3")
    with pytest.raises(ValueError, match="deletes"):
        reference_from_md("ACGT", [(0, 4)], "2^A2")
    assert reference_from_md("ACGTT", [(4, 1), (0, 2), (2, 1), (0, 2)], "1A0^C2") == "CACTT"


def _bam(path, reads, fo="TACG" * 10, ks="TCAG", rg=True):
    """An unaligned Ion-like BAM: (name, sequence, FZ or None, ZF)."""
    header = {"HD": {"VN": "1.6"}, "RG": [{"ID": "r1", "FO": fo, "KS": ks}] if rg else []}
    with pysam.AlignmentFile(str(path), "wb", header=header) as out:
        for name, seq, fz, zf in reads:
            a = pysam.AlignedSegment()
            a.query_name, a.query_sequence, a.flag = name, seq, 4
            a.query_qualities = pysam.qualitystring_to_array("I" * len(seq))
            tags = [("RG", "r1"), ("ZF", zf)] + ([("FZ", fz)] if fz is not None else [])
            a.set_tags(tags)
            out.write(a)
    return path


# "TCAG" + "GA" through TACG: T, A0, C, G0, T0, A, C0, G (key's G and the read's G), T0, A
FZ = [100, 2, 98, 0, 1, 103, 0, 197, 3, 101] + [0] * 30


def test_an_unaligned_bam_has_no_truth(tmp_path):
    data = read_flowgrams(_bam(tmp_path / "u.bam", [("r", "GA", FZ, 7)]))
    assert data.truth_source is None and data.reads[0].truth is None
    np.testing.assert_allclose(data.reads[0].values[:4], [1.0, 0.02, 0.98, 0.0])


@pytest.mark.parametrize(("kw", "match"), [
    ({"reads": [("r", "GA", None, 7)]}, r"record 1 \(r\).*FZ"),
    ({"fo": "TACN" * 10}, r"FO/KS flow order.*A, C, G, T \(found N\)"),
    ({"ks": "TCAX"}, r"key = 'TCAX'.*one or more of A, C, G, T"),
    ({"fo": "TACG", "ks": "TCAGTCAG"}, r"key = 'TCAGTCAG'.*within its 4 flows"),
    ({"reads": [("r", "GA", FZ, 5)]}, r"ZF = 5.*key TCAG"),
    ({"rg": False}, r"read group.*FO.*KS"),
])
def test_bad_bam_input_is_refused_naming_the_record_and_what_is_allowed(tmp_path, kw, match):
    reads = kw.pop("reads", [("r", "GA", FZ, 7)])
    path = _bam(tmp_path / "bad.bam", reads, **kw)
    with pytest.raises(ScenarioError, match=match) as exc:
        read_flowgrams(path)
    assert str(path) in str(exc.value)


def test_a_truncated_bam_is_refused_naming_the_record(tmp_path):
    path = _bam(tmp_path / "ok.bam", [(f"r{i}", "GA", FZ, 7) for i in range(3000)])
    cut = tmp_path / "cut.bam"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(ScenarioError, match=r"cut\.bam: record \d+ \(byte \d+\) = 'truncated"):
        read_flowgrams(cut)


def test_a_missing_extra_is_named(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pysam", None)
    with pytest.raises(ScenarioError, match=r'pip install "chiptwin\[bam\]"'):
        read_flowgrams(_bam_bytes(tmp_path))
    monkeypatch.setitem(sys.modules, "Bio", None)
    with pytest.raises(ScenarioError, match=r'pip install "chiptwin\[sff\]"'):
        read_flowgrams(real_data("sff", "greek.sff"))


def _bam_bytes(tmp_path):
    path = tmp_path / "x.bam"
    path.write_bytes(b"\x1f\x8b\x08\x04" + bytes(60))
    return path


def test_not_sff_nor_bam_is_refused(tmp_path):
    path = tmp_path / "reads.fastq"
    path.write_text("@r\nACGT\n+\nIIII\n")
    with pytest.raises(ScenarioError, match="must be SFF.*or BAM"):
        read_flowgrams(path)


def test_truth_fasta_must_name_every_read_and_hold_acgt(tmp_path):
    sff = real_data("sff", "E3MFGYR02_random_10_reads.sff")
    names = [r.name for r in read_flowgrams(sff).reads]
    fasta = tmp_path / "t.fasta"
    fasta.write_text("".join(f">{n} a template\nACGT\nTTGA\n" for n in names[:-1]))
    with pytest.raises(ScenarioError, match=rf"t\.fasta: record = '{names[-1]}'.*1 of 10"):
        read_flowgrams(sff, fasta)
    fasta.write_text(">a\nACGU\n")
    with pytest.raises(ScenarioError, match=r"record a = 'U': must hold only A, C, G, T"):
        read_truth_fasta(fasta)
    fasta.write_text("".join(f">{n}\nACGT\nTTGA\n" for n in names))
    data = read_flowgrams(sff, fasta)
    assert data.truth_source == str(fasta) and data.reads[3].truth == "ACGTTTGA"


def test_key_flows_through_an_order():
    assert key_flows("TCAG", "TACGTACG").tolist() == [0, 2, 5, 7]
    assert key_flows("TTC", "TACG").tolist() == [0, 0, 2]
    assert key_flows("TCAG", "TACG") is None
