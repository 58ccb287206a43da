"""The fast caller against the caller as first written: the checkpointed phasing model is the
flowgram predicted from flow 0, bit for bit; the incremental sweep and hill climb give the same
calls and the same likelihoods as the kernels that predicted the whole flowgram for every step
and candidate (``tests/detection/naive_caller.py``); and the bundled scenes still call what they
called before the change (regression: digests recorded on the unchanged code, at the scenes' own
seeds; ``python -m tests.detection.test_caller_equivalence`` prints them again)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from chiptwin.detection import _read_kernels as rk
from chiptwin.detection import reads
from chiptwin.kinetics import _phasing_kernels as pk
from chiptwin.kinetics import phasing, templates
from tests.detection import naive_caller as naive

#: sha256 (first 16 hex digits) of every site's calls (int64, sites × flows), recorded before
#: the incremental kernels replaced the naive ones (the chip model as of that commit) and held
#: through every speed-up since. pyro_long_read's re-recorded for a change of the caller's model
#: (the empty-flow light, a second walk of the phasing, a second estimate of the read's 1-mer
#: level), not of speed: read accuracy 0.935 → 0.931, Q20 length median 204 either way (on
#: pyro_454_flx 0.832 → 0.866 and 171.5 → 188); pyro_1fmol's calls did not move.
BUNDLED_CALLS = {
    ("pyro_1fmol", ()): "eaa2ac55b4b6f8d9",
    ("pyro_1fmol", ('assay.caller="dephase"',)): "fe0e6b05ed872a96",
    ("pyro_long_read", ()): "0a184ccb244ff408",
}


def calls_digest(calls: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(calls, dtype=np.int64).tobytes()).hexdigest()[:16]


def _phased_read(rng, n_flows, eps, lam, droop, sigma):
    t = "TCAG" + templates.draw_template(n_flows, 0.5, 0.3, 6, rng)
    s, _, ideal = phasing.phased_signal(t, "TACG", n_flows, eps, lam, droop)
    noise = reads.FlowNoise(sigma**2, (sigma / 2) ** 2)
    return s + rng.normal(0, 1, n_flows) * np.sqrt(noise.var(s)), noise


@pytest.mark.parametrize("seed", range(6))
def test_checkpointed_model_is_the_flowgram_from_flow_0(seed):
    """Run whole, then again from every checkpoint: each equals phase_flows bit for bit, and no
    flow reads a template position beyond its recorded reach (the reach of flow k bounds what a
    change of the template can leave unchanged)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 300))
    tmpl = rng.integers(0, 4, int(rng.integers(5, 250))).astype(np.int64)
    flows = np.array([3, 0, 1, 2])[np.arange(n) % 4]
    par = (0.002, 0.01, 0.001) if seed % 2 else tuple(rng.uniform(0, [0.02, 0.05, 0.01]))
    ref = pk.phase_flows(tmpl, flows, *par)
    bufs = pk.model_buffers(n, tmpl.size + 2)
    run = pk.run_table(tmpl)
    for k0 in (0, *range(pk.CHECK_EVERY, n, 3 * pk.CHECK_EVERY)):
        k = pk.model_restore(k0, *bufs[:6])
        bufs[6][k:] = np.nan
        pk.model_advance(run, flows, *par, k, n, *bufs)
        for got, want in zip(bufs[6:9], ref, strict=True):
            assert np.array_equal(got, want)
    # cut the template just past each flow's reach: the flows up to it are unchanged
    reach = bufs[9]
    for k in range(0, n, 17):
        if reach[k] + 1 < tmpl.size:
            cut = pk.phase_flows(tmpl[: reach[k] + 1], flows, *par)
            assert np.array_equal(cut[0][: k + 1], ref[0][: k + 1])


CASES = [  # (ε, λ, droop, 0-mer sd, flows)
    (0.002, 0.01, 0.001, 0.03, 300),
    (0.002, 0.01, 0.001, 0.12, 200),
    (0.0, 0.0, 0.0, 0.06, 400),
    (0.004, 0.02, 0.002, 0.05, 160),
    (0.002, 0.01, 0.001, 0.5, 120),  # SNR 2: candidates merge runs past MAX_CALL
]


@pytest.mark.parametrize("case", CASES)
def test_sweep_and_hill_climb_match_the_naive_kernels(case):
    """Equivalence: from the rounded calls, the sweep (whole and as the phasing search scores
    it) and then the hill climb give the naive kernels' calls and negative log-likelihood,
    exactly, on reads drawn from the twin's phasing model."""
    eps, lam, droop, sigma, n = case
    rng = np.random.default_rng(int(sigma * 1000) + n)
    flows = phasing.flow_indices("TACG", n)
    for _ in range(3):
        y, noise = _phased_read(rng, n, eps, lam, droop, sigma)
        start = np.clip(np.rint(y), 0, reads.MAX_CALL).astype(np.int64)
        prior = reads.Prior.of(start, flows)
        # the empty-flow light: none, and 454 FLX's (the values carry none: the caller's
        # model is then wrong, and both kernels must still agree)
        for par, beta in (((eps, lam, droop), 0.0), ((0.0, 0.0, 0.0), 0.0),
                          ((eps, lam, droop), 0.088)):
            for n_iter, n_score in ((4, min(96, n)), (3 * (n // reads.WINDOW + 1), n)):
                args = (y, flows, *par, start, prior.comp, prior.log_len, noise.floor,
                        noise.shot, noise.ref, n_score, n_iter, reads.WINDOW, beta)
                fast, slow = rk.dephase_kernel(*args), naive.dephase_kernel(*args)
                assert np.array_equal(fast[0], slow[0]) and fast[1] == slow[1]
            pol = (y, flows, *par, fast[0], prior.comp, prior.log_len, noise.floor, noise.shot,
                   noise.ref, reads.POLISH_TRY, reads.POLISH_Z, reads.POLISH_ROUNDS, beta)
            assert np.array_equal(rk.polish_kernel(*pol), naive.polish_kernel(*pol))


@pytest.mark.parametrize("seed", range(8))
def test_flow_step_is_the_first_written_step_bit_for_bit(seed):
    """The phasing model's flow step, its waiting shares summed in a register, against the step
    as first written (kept in the naive caller): the same flowgram, in-phase share and ideal
    calls to the bit, at zero and at large phasing, on templates with long runs."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(8, 400))
    tmpl = np.repeat(rng.integers(0, 4, 200), rng.integers(1, 9 if seed % 2 else 3, 200))
    flows = phasing.flow_indices("TACG", n)
    for par in ((0.0, 0.0, 0.0), (0.002, 0.01, 0.001), (0.0, 0.03, 0.0), (0.02, 0.0, 0.0),
                tuple(rng.uniform(0, [0.05, 0.08, 0.02]))):
        for got, want in zip(pk.phase_flows(tmpl, flows, *par),
                             naive.phase_flows(tmpl, flows, *par), strict=True):
            assert np.array_equal(got, want)


@pytest.mark.parametrize(("par", "sigma"), [((0.002, 0.01, 0.001), 0.05),
                                            ((0.0, 0.0, 0.0), 0.05),
                                            ((0.0, 0.0, 0.0), 0.12)])
def test_whole_caller_matches_the_first_written_caller(par, sigma):
    """Equivalence of the whole read model (phasing search, sweeps, hill climbs, the flat
    re-call kept or skipped by ``flat_floor``, the posterior): the same calls and phasing as the
    caller with every kernel as first written, and the posterior to 1e-9, on phased reads and
    on reads that need no correction (where the flat re-call wins)."""
    rng = np.random.default_rng(int(sigma * 100) + int(par[0] * 1e4))
    n = 160
    flows = phasing.flow_indices("TACG", n)
    flat_won = 0
    for _ in range(4):
        y, noise = _phased_read(rng, n, *par, sigma)
        fast = reads.read_model(y, flows, noise)
        old = naive.use_naive(reads)
        try:
            slow = reads.read_model(y, flows, noise)
        finally:
            naive.restore(reads, old)
        assert np.array_equal(fast.calls, slow.calls)
        assert (fast.eps, fast.lam, fast.droop, fast.empty_light) == (
            slow.eps, slow.lam, slow.droop, slow.empty_light)
        np.testing.assert_allclose(fast.posterior, slow.posterior, rtol=0, atol=1e-9)
        flat_won += not any((fast.eps, fast.lam, fast.droop))
    assert flat_won >= (2 if par == (0.0, 0.0, 0.0) else 0)


@pytest.mark.parametrize(("seed", "par", "beta"), [
    (0, (0.004, 0.02, 0.001), 0.0), (1, (0.002, 0.01, 0.0), 0.0), (2, (0.0, 0.0, 0.0), 0.0),
    (3, (0.0, 0.0, 0.0), 0.0), (4, (0.0, 0.0, 0.0), 0.09), (5, (0.002, 0.01, 0.001), 0.09)])
def test_flat_floor_bounds_every_unphased_call_set(seed, par, beta):
    """``flat_floor`` is below the score of any call set without phasing: the flat sweep's and
    hill climb's, the rounded and floored values', one drawn at random, with and without an
    empty-flow light ``beta`` (in the read and in the model); on a read without phasing it is
    within a nat a flow of the best of them (the prior's share is bounded, not known), so it
    is not vacuous; a negative ``beta`` or a value far beyond the caller's lengths gets no
    floor (−∞)."""
    rng = np.random.default_rng(seed)
    n = 200
    flows = phasing.flow_indices("TACG", n)
    y, noise = _phased_read(rng, n, *par, 0.03)
    y[np.abs(y) < 0.2] *= -1.0  # empty flows read below 0 too: the floor takes them as 0
    y[np.abs(y) < 0.2] += beta
    floor = reads.flat_floor(y, noise, beta)
    prior = reads.Prior.of(np.clip(np.rint(y), 0, reads.MAX_CALL).astype(np.int64), flows)
    sets = [np.clip(np.rint(y), 0, reads.MAX_CALL).astype(np.int64),
            np.clip(np.floor(np.maximum(y, 0)), 0, reads.MAX_CALL).astype(np.int64),
            rng.integers(0, 4, n)]
    flat = reads.dephase(y, flows, noise, 0.0, 0.0, 0.0, sets[0], prior, beta=beta)[0]
    sets.append(reads.polish(y, flows, noise, (0.0, 0.0, 0.0), flat, prior, beta))
    scores = [reads.read_nll(y, flows, noise, c, (0.0, 0.0, 0.0), prior, beta) for c in sets]
    assert min(scores) >= floor
    if not any(par):
        assert min(scores) < floor + n
    assert reads.flat_floor(y, noise, -0.01) == -np.inf
    assert reads.flat_floor(np.r_[y, 1e7], noise, beta) == -np.inf


def test_the_least_term_bounds_every_flows_term():
    """The hill climb drops a candidate on a lower bound of the flows it has not scored: every
    flow's share of the negative log-posterior, over lengths, priors and signals, is above it."""
    rng = np.random.default_rng(5)
    floor = 1e-4
    lb = rk.least_term(floor)
    log_len = np.log(np.r_[1.0, rng.dirichlet(np.ones(reads.MAX_CALL))])
    n = 5000
    y, signal = rng.uniform(-1, 8, n), rng.uniform(0, 8, n)
    signal[::3] = y[::3]  # residual 0: the tightest case
    calls = rng.integers(0, reads.MAX_CALL + 1, n)
    p_pos = rng.uniform(rk.P_POS_MIN, 1 - rk.P_POS_MIN, n)
    cum = np.zeros(n + 1)
    rk.terms_from(y, signal, calls, floor, 0.0, 0.0, p_pos, log_len, 0, n, 0.0, cum, 0.0)
    assert np.all(np.diff(cum) >= lb)
    assert np.diff(cum).min() < lb + 0.2  # and it is not loose where a flow fits


@pytest.mark.parametrize(("scene", "overrides"), list(BUNDLED_CALLS))
def test_bundled_scenes_call_what_they_called(scene, overrides):
    """Regression: every site's calls of the bundled scenes at their seeds, against digests
    recorded before the incremental kernels (the chip model unchanged since: a change upstream
    of the caller that moves a flow value would need the digests recorded again)."""
    import chiptwin

    r = chiptwin.run(scene, list(overrides))
    assert calls_digest(r.arrays["read_calls"]) == BUNDLED_CALLS[(scene, overrides)]


if __name__ == "__main__":  # print the digests of the code as it stands
    import chiptwin

    for scene, overrides in BUNDLED_CALLS:
        calls = chiptwin.run(scene, list(overrides)).arrays["read_calls"]
        print(scene, overrides, calls_digest(calls))
