"""The ``binned`` level on many cores: one stream per chunk of ``CHUNK_PIXELS`` pixels.

Equivalence tests: the codes depend on the seed only, never on the thread count; chunk 0
is the single-stream path (so arrays of at most one chunk draw what they drew before chunking);
the other chunks draw from their own streams with the same distribution as the frame-by-frame
reference ``sample_frame`` (two-sample tests at fixed seeds). And the clipped-Poisson moments'
shortcut far below the full well is bit for bit the ``pdtr`` it skips.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.special import pdtr

from chiptwin.pixel import CHUNK_PIXELS, binned_codes, chunk_streams
from chiptwin.pixel.sensor import clipped_poisson_moments

from .test_pixel_frames import CASES, READOUT, slow_codes

N_PIXELS = 2 * CHUNK_PIXELS + 300  # three chunks, the last one short


def _lam(n_frames: int = 3) -> np.ndarray:
    rng = np.random.default_rng(11)
    return rng.uniform(0.0, 3e4, (n_frames, N_PIXELS))


@pytest.mark.parametrize("case", CASES, ids=["pyro", "no-cds", "no-ktc", "errors", "report"])
def test_codes_do_not_depend_on_the_thread_count(case):
    """1, 2 and 3 threads: the same codes, bit for bit, and the streams left in the same state;
    reported counts too (one reported pixel in each chunk, in an order unlike the chunks')."""
    case = dict(case)
    if "report_pixels" in case:
        case["report_pixels"] = [CHUNK_PIXELS + 7, 5, 2 * CHUNK_PIXELS + 1]
    runs = []
    for threads in (1, 2, 3):
        streams = chunk_streams(np.random.default_rng(5), N_PIXELS)
        report = np.full((3, 3), -1.0) if "report_pixels" in case else None
        extra = {} if report is None else {"report_e": report}
        codes = binned_codes(streams, _lam(), threads=threads, **case, **extra, **READOUT)
        runs.append((codes, [g.bit_generator.state for g in streams], report))
    for codes, state, report in runs[1:]:
        assert np.array_equal(codes, runs[0][0]) and state == runs[0][1]
        assert report is None or np.array_equal(report, runs[0][2])
    if "report_pixels" in case:  # the counts the chunks drew: their mean within 5 σ of Poisson
        lam = _lam()[:, case["report_pixels"]]
        got = runs[0][2]
        assert (got >= 0).all() and np.all(got == np.rint(got))
        assert abs((got - lam).sum()) < 5 * np.sqrt(lam.sum())


def test_a_forked_child_draws_with_threads_of_its_own():
    """Regression: after the parent drew on 2 threads, a child forked from it (multiprocessing's
    default on Linux) inherited the thread pool without its threads and waited forever on its
    first draw. Now it draws, and draws the parent's codes (same seed). Fails by timeout."""
    import multiprocessing

    kw = {**CASES[0], **READOUT, "threads": 2}
    want = binned_codes(chunk_streams(np.random.default_rng(5), N_PIXELS), _lam(), **kw)

    def child(queue) -> None:
        got = binned_codes(chunk_streams(np.random.default_rng(5), N_PIXELS), _lam(), **kw)
        queue.put(bool(np.array_equal(got, want)))

    ctx = multiprocessing.get_context("fork")
    queue = ctx.SimpleQueue()
    p = ctx.Process(target=child, args=(queue,))
    p.start()
    p.join(60)
    alive = p.is_alive()
    if alive:
        p.kill()
    assert not alive and p.exitcode == 0 and queue.get() is True


def test_chunk_zero_is_the_single_stream_path():
    """Chunk 0 draws from the caller's Generator exactly what one stream over its pixels draws,
    which is the frame-by-frame path's (tests/pixel/test_pixel_frames.py)."""
    kw = {**CASES[0], **READOUT}
    got = binned_codes(chunk_streams(np.random.default_rng(8), N_PIXELS), _lam(), **kw)
    ref = slow_codes(np.random.default_rng(8), _lam()[:, :CHUNK_PIXELS], **kw)
    assert np.array_equal(got[:, :, :CHUNK_PIXELS], ref)
    small = binned_codes(chunk_streams(np.random.default_rng(8), 50), _lam()[:, :50], **kw)
    assert np.array_equal(small, binned_codes(np.random.default_rng(8), _lam()[:, :50], **kw))


def test_reported_counts_are_those_of_their_own_pixels():
    """Noiseless readout: the charge each reported pixel's codes carry is the count reported for
    it, in chunk 0 and in chunk 1 (below the full well, rounding only)."""
    kw = {**CASES[0], **READOUT, "ktc_e": 0.0, "read_noise_e": 0.0}
    where = [CHUNK_PIXELS + 2, 3]
    report = np.empty((3, 2))
    codes = binned_codes(chunk_streams(np.random.default_rng(1), N_PIXELS), _lam(), **kw,
                         report_pixels=where, report_e=report)
    e_per_code = 1.0 / 2**13 / 0.16e-6  # 1 V over 13 bits at 0.16 µV/e⁻
    signal_e = (codes[:, 4:, where] - codes[:, :4, where]).mean(axis=1) * e_per_code
    assert np.all(np.abs(signal_e - report) <= 2 * e_per_code)
    assert np.all(np.abs(report - _lam()[:, where]) < 5 * np.sqrt(_lam()[:, where]))


def test_the_other_chunks_draw_sample_frames_distribution():
    """CMS differences in chunks 1 and 2 (their own streams) against the frame-by-frame
    reference at the same means: two-sample KS and the means within 4 standard errors, at a
    fixed seed (Poisson with kTC, read noise and 13-bit rounding; 2,348 pixels × 8 frames)."""
    kw = {**CASES[1], **READOUT}  # no true CDS: kTC, read noise and shot noise all enter
    lam = np.full((8, N_PIXELS), 2500.0)
    got = binned_codes(chunk_streams(np.random.default_rng(21), N_PIXELS), lam, **kw)
    ref = slow_codes(np.random.default_rng(22), lam[:, CHUNK_PIXELS:], **kw)
    m = kw["n_samples"]

    def cms(c: np.ndarray) -> np.ndarray:
        return (c[:, m:].mean(axis=1) - c[:, :m].mean(axis=1)).ravel()

    a, b = cms(got[:, :, CHUNK_PIXELS:]), cms(ref)
    assert stats.ks_2samp(a, b).pvalue > 1e-3
    se = np.sqrt(a.var() / a.size + b.var() / b.size)
    assert abs(a.mean() - b.mean()) < 4 * se
    assert a.var() == pytest.approx(b.var(), rel=0.06)


def test_wrong_number_of_streams_is_refused():
    with pytest.raises(ValueError, match="one per chunk"):
        binned_codes([np.random.default_rng(0)], _lam(), **CASES[0], **READOUT)


@pytest.mark.parametrize("cap", [6e6, 2e4, 1e3, 120.0, 20.0, 1.0])
def test_clipped_moments_far_below_the_cap_are_pdtr_bit_for_bit(cap):
    """The shortcut (CDF = 1 far below the cap) against pdtr evaluated everywhere."""
    lam = np.concatenate([np.linspace(0.0, 2 * cap, 20001), [cap - 1, cap, cap + 1, 0.5]])
    m = np.ceil(cap) - 1.0

    def cdf(k):
        return pdtr(k, lam) if k >= 0 else np.zeros_like(lam)

    tail = 1.0 - cdf(m)
    mean = lam * cdf(m - 1) + cap * tail
    second = lam * lam * cdf(m - 2) + lam * cdf(m - 1) + cap * cap * tail
    got_mean, got_var = clipped_poisson_moments(lam, cap)
    assert np.array_equal(got_mean, mean)
    assert np.array_equal(got_var, np.maximum(second - mean * mean, 0.0))
