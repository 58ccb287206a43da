"""A read against its truth in base space: the kernel against a plain dynamic programme, the
errors, homopolymers and wrong bases of hand-made cases."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.detection import align as al


def _free_end_distance(read: str, truth: str) -> int:
    """The obvious reference: the full edit-distance table, the least cost where either
    sequence has run out."""
    n, m = len(read), len(truth)
    d = [[0] * (m + 1) for _ in range(n + 1)]
    for i in range(n + 1):
        for j in range(m + 1):
            if i == 0 or j == 0:
                d[i][j] = i + j
            else:
                d[i][j] = min(d[i - 1][j - 1] + (read[i - 1] != truth[j - 1]),
                              d[i - 1][j] + 1, d[i][j - 1] + 1)
    return min(min(d[n]), min(row[m] for row in d))


def _mutate(rng, seq: str) -> str:
    out = []
    for b in seq:
        r = rng.random()
        if r < 0.05:
            continue  # deletion
        out.append(rng.choice(list("ACGT")) if r < 0.08 else b)
        if r > 0.95:
            out.append(b)  # homopolymer over-call
    return "".join(out)


def test_alignment_is_the_least_cost_and_spells_both_sequences():
    rng = np.random.default_rng(5)
    for _ in range(60):
        truth = "".join(rng.choice(list("ACGT"), int(rng.integers(0, 40))))
        read = _mutate(rng, truth)[: int(rng.integers(0, 45))]
        a = al.align(read, truth)
        assert al.error_counts(a)["errors"] == _free_end_distance(read, truth)
        assert "".join(read[i] for i in a.read_index if i >= 0) == read[:a.read_index.max() + 1
                                                                       if a.read_index.size
                                                                       and a.read_index.max() >= 0
                                                                       else 0]
        t = a.truth_index[a.truth_index >= 0]
        assert t.tolist() == list(range(t.size))  # the truth from its first base, in order
        kinds = a.kind[(a.read_index >= 0) & (a.truth_index >= 0)]
        pairs = [(read[i], truth[j]) for i, j in zip(a.read_index, a.truth_index, strict=True)
                 if i >= 0 and j >= 0]
        assert [(x == y) for x, y in pairs] == (kinds == al.MATCH).tolist()


@pytest.mark.parametrize(("read", "truth", "counts", "wrong", "runs"), [
    # exact
    ("ACGT", "ACGT", (0, 0, 0), [0, 0, 0, 0], [(1, 1)] * 3),
    # an over-called run: its last base is wrong (454's convention)
    ("AAAGT", "AAGT", (0, 1, 0), [0, 0, 1, 0, 0], [(2, 3), (1, 1)]),
    # an under-called run: its last called base carries the missing one
    ("AGT", "AAGT", (0, 0, 1), [1, 0, 0], [(2, 1), (1, 1)]),
    # a run missed entirely: the base before the gap carries it
    ("AGT", "ACGT", (0, 0, 1), [1, 0, 0], [(1, 1), (1, 0), (1, 1)]),
    # ... at the read's start: the first base
    ("CGT", "ACGT", (0, 0, 1), [1, 0, 0], [(1, 0), (1, 1), (1, 1)]),
    # a new run inserted: an over-called 0-mer, wrong itself
    ("ACTG", "ACG", (0, 1, 0), [0, 0, 1, 0], [(1, 1), (1, 1), (0, 1)]),
    # a substitution: the base itself, and the missed truth run's neighbour
    ("ATG", "ACG", (1, 0, 0), [1, 1, 0], [(1, 1), (1, 0), (0, 1)]),
    # the read past its truth is not scored
    ("ACGTTTTACG", "ACGT", (0, 0, 0), [0] * 10, [(1, 1), (1, 1), (1, 1)]),
    # the truth's last run may be cut by its end: not judged
    ("ACGG", "ACGGG", (0, 0, 0), [0] * 4, [(1, 1), (1, 1)]),
])
def test_errors_wrong_bases_and_homopolymers(read, truth, counts, wrong, runs):
    a = al.align(read, truth)
    c = al.error_counts(a)
    assert (c["mismatches"], c["insertions"], c["deletions"]) == counts
    assert al.wrong_bases(a).astype(int).tolist() == wrong
    assert sorted(al.homopolymers(a)) == sorted(runs)


def test_a_truth_head_given_as_calls_is_not_scored():
    """A soft-clipped start stands in the truth as the instrument's calls: not scored."""
    a = al.align("TTACGT", "GGACGT", scored_from=2)
    c = al.error_counts(a)
    assert c["errors"] == 0 and c["truth_bases"] == 4
    assert not al.wrong_bases(a).any()
    assert al.align("TTACGT", "GGACGT").kind.tolist().count(al.MISMATCH) == 2


def test_the_truth_past_a_short_read_is_not_scored():
    a = al.align("ACG", "ACGTTGCA")
    assert al.error_counts(a) == {"truth_bases": 3, "mismatches": 0, "insertions": 0,
                                  "deletions": 0, "errors": 0}
