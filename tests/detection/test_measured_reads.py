"""Measured flowgrams through the callers: the noise measured from the values, the levels the
phase-correcting caller reads, the key-pass filter, and a flowgram already phase-corrected left
as it is."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.detection import measured_reads as mr
from chiptwin.detection import reads
from chiptwin.detection.key_pass import key_counts, passes_key
from chiptwin.kinetics import phasing, templates


def _flowgram(rng, n_flows, sd0, ref, offset=0.0):
    t = "TCAG" + templates.draw_template(n_flows, 0.5, 0.3, 6, rng)
    _, _, ideal = phasing.phased_signal(t, "TACG", n_flows, 0.0, 0.0, 0.0)
    sd = np.sqrt(sd0**2 + ref * ideal**2)
    return ideal + rng.normal(0, 1, n_flows) * sd + offset * (ideal == 0), ideal


def test_noise_fit_recovers_the_scatter_of_1_to_5_mers():
    rng = np.random.default_rng(1)
    values = [_flowgram(rng, 400, 0.08, 0.002)[0] for _ in range(40)]
    pool, per_read = mr.fit_noise(values)
    assert pool.shot == 0.0 and len(per_read) == 40
    # flows within half a base of their length: a truncated normal's mean square, 0.0064
    assert pool.floor == pytest.approx(0.0064, rel=0.2)
    assert pool.ref == pytest.approx(0.002, rel=0.5)


def test_the_dephasing_caller_reads_454_levels_at_0_and_1():
    """454's 0-mers sit near +0.1 (Balzer et al. 2010): moved to 0, 1-mers kept at 1, longer
    runs shifted with the 1-mer."""
    rng = np.random.default_rng(2)
    y, ideal = _flowgram(rng, 400, 0.04, 0.0, offset=0.1)
    moved = mr.caller_input(y, "dephase")
    assert np.median(moved[ideal == 0]) == pytest.approx(0.0, abs=0.01)
    assert np.median(moved[ideal == 1]) == pytest.approx(1.0, abs=0.01)
    assert np.median(moved[ideal == 2]) == pytest.approx(2.0, abs=0.03)
    assert mr.caller_input(y, "round") is not moved and np.array_equal(mr.caller_input(y, "round"),
                                                                      y)


def test_a_phase_corrected_flowgram_gets_no_phasing_and_the_rounded_calls():
    """A read with no phasing left in it (what 454's SFF and Ion's FZ hold): the estimate is 0
    (the whole read scored without it wins) and the calls are the rounded ones, 600 flows."""
    rng = np.random.default_rng(7)
    flows = phasing.flow_indices("TACG", 600)
    for _ in range(3):
        y, ideal = _flowgram(rng, 600, 0.06, 0.001)
        _, noise = mr.fit_noise([y])
        read = mr.call(y, flows, noise[0], "dephase")
        assert (read.eps, read.lam, read.droop) == (0.0, 0.0, 0.0)
        n = read.n_called
        assert np.abs(read.calls[:n] - ideal[:n]).sum() <= np.abs(mr.rounded(y) - ideal)[:n].sum()


@pytest.mark.parametrize(("key", "order", "counts"), [
    ("TCAG", "TACGTACG", [1, 0, 1, 0, 0, 1, 0, 1]),
    ("TTC", "TACG", [2, 0, 1]),
    ("TCAG", "TACG", None),
])
def test_key_counts(key, order, counts):
    got = key_counts(key, order)
    assert (got is None and counts is None) or got.tolist() == counts


def test_key_pass_lets_the_reads_first_base_share_the_keys_last_flow():
    k = key_counts("TCAG", "TACGTACG")
    assert passes_key(np.array([1, 0, 1, 0, 0, 1, 0, 2, 1]), k)  # TCAG + G…
    assert not passes_key(np.array([0, 0, 1, 0, 0, 1, 0, 1, 1]), k)  # no T
    assert not passes_key(np.array([1, 0, 1, 0, 0, 1]), k)  # too short


def test_base_error_is_the_per_run_loop():
    """The vectorised per-base error against the obvious loop: base i of a called h-mer is
    wrong with P(H < i), the last also P(H > h); calls past MAX_CALL get no chance; a flow called
    0 adds its P(H > 0) to the base before it (the first base when none is)."""
    rng = np.random.default_rng(4)
    calls = rng.integers(0, 4, 60)
    calls[5] = reads.MAX_CALL + 2
    post = rng.dirichlet(np.ones(reads.MAX_CALL + 1), 60)
    below = np.cumsum(post, axis=1)
    ref = []
    for k in np.flatnonzero(calls):
        h = int(calls[k])
        p = np.ones(h)
        m = min(h, reads.MAX_CALL)
        p[:m] = below[k, :m]
        p[-1] = min(p[-1] + (1.0 - below[k, h] if h <= reads.MAX_CALL else 0.0), 1.0)
        ref.append(p)
    ref = np.concatenate(ref)
    before = -1
    for k, c in enumerate(calls):
        if c == 0:
            ref[max(before, 0)] += 1.0 - post[k, 0]
        before += c
    np.testing.assert_allclose(reads.base_error(calls, post), np.clip(ref, 0, 1), atol=1e-12)


def test_a_run_missed_entirely_is_charged_to_the_base_before_the_gap():
    from chiptwin.detection import read_stats

    true_n = np.array([1, 1, 2, 0, 1])
    calls = np.array([1, 0, 2, 0, 1])  # the second flow's base missed: the first base carries it
    assert read_stats.base_truth(calls, true_n).tolist() == [True, False, False, False]
    assert read_stats.base_truth(np.array([0, 1, 2, 0, 1]), true_n).tolist() == [
        True, False, False, False]  # missed at the start: the read's first base
