"""The fast path (chiptwin.pixel.chain.sensor_chain and its numba kernels) against slow obvious
references: bit for bit where the draws can be replayed, in distribution against the plain path
(sample_frame → to_volts → adc_convert) where they cannot. Statistical tolerances: 5 standard
errors from the sample sizes (a mean: √(var/n); a variance: √((m4 − m2²)/n))."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
from numba import njit

from chiptwin.pixel import _kernels, _random, adc_convert, sample_frame, sensor_chain, to_volts
from chiptwin.pixel.chain import chunk_streams

CHIP = dict(
    qe=0.55,
    full_well_e=20_000.0,
    read_noise_e=6.0,
    conversion_gain_uV_per_e=40.0,
    pedestal_V=0.05,
    bits=12,
    v_min_V=0.0,
    v_max_V=1.0,
)


# --- the ADC kernel, bit for bit (the samplers: test_random.py) -------------------------------


@njit
def _adc_codes(volts, v_min, lsb, gain, offset, top):
    out = np.empty(volts.size, np.int64)
    for i in range(volts.size):
        out[i] = _kernels.adc_code(volts[i], v_min, lsb, gain, offset, top)
    return out


@pytest.mark.parametrize(("offset", "gain_error"), [(0.0, 0.0), (0.37, -0.013), (-2.0, 0.05)])
def test_adc_kernel_matches_adc_convert(offset, gain_error):
    """Random volts, exact ties and values past both ends: the same code, bit for bit."""
    lsb = 1.0 / 4096
    rng = np.random.default_rng(8)
    volts = np.concatenate(
        [rng.uniform(-0.1, 1.1, 100_000), (np.arange(4096) + 0.5) * lsb, [-1e9, 1e9]]
    )
    ref = adc_convert(volts, 12, 0.0, 1.0, offset, gain_error)
    assert np.array_equal(_adc_codes(volts, 0.0, lsb, 1.0 + gain_error, offset, 4095.0), ref)


# --- the whole kernel against a slow reference that replays its draws --------------------------


def slow_chain(
    seed,
    photons,
    n_frames,
    chunk,
    *,
    gain_map,
    dark_e,
    ktc_e,
    true_cds,
    n_samples,
    read_reset,
    shot_noise="poisson",
    gauss_min=1000.0,
    offset_lsb=0.0,
    gain_error=0.0,
):
    """Per pixel in Python, drawing from each chunk's two streams in the order the kernel
    documents (the counts by the same sampler, _random.poisson_fast, on the shot stream's state:
    its law is tested in test_random.py; the normals by NumPy's Generator), then the public
    to_volts and adc_convert."""
    flat = photons.ravel()
    shot, noise = chunk_streams(np.random.default_rng(seed), flat.size, chunk)
    shot = [_random.state_of(g) for g in shot]
    m_reset = n_samples if read_reset else 0
    frames = []
    for _ in range(n_frames):
        reset = np.zeros((m_reset, flat.size))
        signal = np.zeros((n_samples, flat.size))
        for i in range(flat.size):
            gen = noise[i // chunk]
            lam = CHIP["qe"] * gain_map.ravel()[i] * flat[i] + dark_e.ravel()[i]
            if shot_noise == "gaussian" and lam >= gauss_min:
                count = max(0.0, np.rint(lam + math.sqrt(lam) * gen.standard_normal()))
            else:
                count = float(_random.poisson_fast(shot[i // chunk], lam))
            collected = min(count, CHIP["full_well_e"])
            k_sig = ktc_e * gen.standard_normal() if ktc_e > 0 else 0.0
            if read_reset:
                k_res = ktc_e * gen.standard_normal() if ktc_e > 0 and not true_cds else k_sig
                for m in range(n_samples):
                    reset[m, i] = k_res + CHIP["read_noise_e"] * gen.standard_normal()
            for m in range(n_samples):
                signal[m, i] = (collected + k_sig) + CHIP["read_noise_e"] * gen.standard_normal()
        frames.append(tuple(_to_codes(x, offset_lsb, gain_error) for x in (reset, signal)))
    return frames


def _to_codes(electrons, offset_lsb=0.0, gain_error=0.0):
    volts = to_volts(electrons, CHIP["conversion_gain_uV_per_e"], CHIP["pedestal_V"])
    return adc_convert(
        volts, CHIP["bits"], CHIP["v_min_V"], CHIP["v_max_V"], offset_lsb, gain_error
    )


@pytest.mark.parametrize(
    "opts",
    [
        dict(ktc_e=0.0, true_cds=True, n_samples=1, read_reset=False),
        dict(ktc_e=40.0, true_cds=True, n_samples=2, read_reset=True),
        dict(ktc_e=40.0, true_cds=False, n_samples=3, read_reset=True),
        dict(ktc_e=40.0, true_cds=False, n_samples=1, read_reset=False),
        dict(
            ktc_e=5.0,
            true_cds=True,
            n_samples=2,
            read_reset=True,
            shot_noise="gaussian",
            gauss_min=500.0,
            offset_lsb=0.4,
            gain_error=-0.01,
        ),
    ],
    ids=["one-read", "cds-M2", "no-cds-M3", "no-cds-signal-only", "gaussian-errors"],
)
def test_kernel_matches_slow_reference_bit_for_bit(opts):
    """7 × 9 pixels in chunks of 16 (a ragged last chunk), 3 frames, photons from 0 to past the
    full well, PRNU and DSNU maps: identical codes."""
    rng = np.random.default_rng(21)
    photons = rng.uniform(0.0, 3000.0, (7, 9))
    photons[0, :3] = [0.0, 5.0, 60_000.0]
    gain_map = rng.uniform(0.9, 1.1, (7, 9))
    dark_e = rng.uniform(0.0, 20.0, (7, 9))
    ref = slow_chain(99, photons, 3, 16, gain_map=gain_map, dark_e=dark_e, **opts)
    kw = {k: v for k, v in opts.items() if k != "gauss_min"}
    got = sensor_chain(
        np.random.default_rng(99),
        photons,
        n_frames=3,
        chunk_pixels=16,
        gain_map=gain_map,
        dark_e=dark_e,
        gaussian_min_mean_e=opts.get("gauss_min", 1000.0),
        **kw,
        **CHIP,
    )
    frames = list(got)
    assert len(frames) == 3
    for (r, s), (rr, rs) in zip(frames, ref, strict=True):
        assert r.shape == (rr.shape[0], 7, 9) and s.shape == (rs.shape[0], 7, 9)
        assert np.array_equal(r.reshape(rr.shape), rr)
        assert np.array_equal(s.reshape(rs.shape), rs)


# --- reproducibility ----------------------------------------------------------------------------


def _run(seed, n_threads=2, photons=None, chunk=500, **kw):
    photons = np.full((64, 64), 800.0) if photons is None else photons
    frames = sensor_chain(
        np.random.default_rng(seed),
        photons,
        n_frames=3,
        dark_e=10.0,
        ktc_e=20.0,
        read_reset=True,
        n_threads=n_threads,
        chunk_pixels=chunk,
        **CHIP,
        **kw,
    )
    return [np.concatenate([r.ravel(), s.ravel()]) for r, s in frames]


def test_bits_do_not_depend_on_thread_count():
    """Same seed, 1, 2, 3 and 8 threads (9 chunks): identical codes in every frame."""
    ref = _run(1, n_threads=1)
    for n in (2, 3, 8):
        assert all(np.array_equal(a, b) for a, b in zip(ref, _run(1, n_threads=n), strict=True))


def test_same_seed_same_bits_different_seed_different_bits():
    assert all(np.array_equal(a, b) for a, b in zip(_run(5), _run(5), strict=True))
    assert not np.array_equal(_run(5)[0], _run(6)[0])
    frames = _run(5)
    assert not np.array_equal(frames[0], frames[1])  # temporal noise does not repeat


def test_frame_sources_are_equivalent():
    """One frame × n_frames, a list, an (n_frames, H, W) array and a generator: the same codes."""
    photons = np.random.default_rng(2).uniform(0, 2000, (16, 16))

    def codes(source, n_frames=None):
        it = sensor_chain(
            np.random.default_rng(3),
            source,
            n_frames=n_frames,
            dark_e=1.0,
            chunk_pixels=100,
            **CHIP,
        )
        return np.array([s.copy() for _, s in it])

    ref = codes(photons, n_frames=4)
    assert ref.shape == (4, 1, 16, 16)
    for source in ([photons] * 4, np.stack([photons] * 4), (photons for _ in range(4))):
        assert np.array_equal(codes(source), ref)


def test_gaussian_level_is_exact_below_its_threshold():
    """All means below gaussian_min_mean_e: the "gaussian" level draws exactly the Poisson bits."""
    photons = np.full((32, 32), 300.0)
    assert all(
        np.array_equal(a, b)
        for a, b in zip(
            _run(4, photons=photons), _run(4, photons=photons, shot_noise="gaussian"), strict=True
        )
    )


# --- statistics against the plain path ---------------------------------------------------------


def _moments_se(x):
    d = x - x.mean()
    m2, m4 = (d**2).mean(), (d**4).mean()
    return x.mean(), m2, math.sqrt(m2 / x.size), math.sqrt(max(m4 - m2 * m2, 0.0) / x.size)


@pytest.mark.parametrize(
    ("photons", "opts"),
    [
        (1500.0, dict(ktc_e=40.0, true_cds=True, n_samples=2)),
        (1500.0, dict(ktc_e=40.0, true_cds=False, n_samples=1)),
        (12.0, dict(ktc_e=0.0, true_cds=True, n_samples=1)),
        (36_000.0, dict(ktc_e=10.0, true_cds=True, n_samples=1)),  # at the full well
        (4000.0, dict(ktc_e=10.0, true_cds=True, n_samples=1, shot_noise="gaussian")),  # λ ≈ 2200
    ],
    ids=["cds-M2", "no-cds", "small-mean", "full-well", "gaussian"],
)
def test_moments_agree_with_plain_path(photons, opts):
    """Mean and variance of the CDS difference in codes, mean(signal) − mean(reset), and of the
    first signal code: fast path vs plain path, 2^18 pixels each, within 5 standard errors."""
    n_side = 512
    fast = next(
        sensor_chain(
            np.random.default_rng(31),
            np.full((n_side, n_side), photons),
            n_frames=1,
            dark_e=15.0,
            read_reset=True,
            **opts,
            **CHIP,
        )
    )
    fast = tuple(x.reshape(x.shape[0], -1) for x in fast)
    reset_e, signal_e = sample_frame(
        np.random.default_rng(32),
        np.full(n_side * n_side, photons),
        CHIP["qe"],
        1.0,
        15.0,
        CHIP["full_well_e"],
        opts["ktc_e"],
        CHIP["read_noise_e"],
        opts["n_samples"],
        opts["true_cds"],
    )
    plain = (_to_codes(reset_e), _to_codes(signal_e))
    for pick in (lambda r, s: s.mean(0) - r.mean(0), lambda r, s: s[0]):
        a = _moments_se(pick(*fast).astype(float))
        b = _moments_se(pick(*plain).astype(float))
        assert abs(a[0] - b[0]) < 5 * math.hypot(a[2], b[2])
        assert abs(a[1] - b[1]) < 5 * math.hypot(a[3], b[3])


# --- memory and buffers -------------------------------------------------------------------------


def _peak_bytes(n_frames, out):
    photons = np.full((256, 256), 500.0)
    tracemalloc.start()
    for _ in sensor_chain(
        np.random.default_rng(1),
        photons,
        n_frames=n_frames,
        dark_e=1.0,
        read_reset=True,
        out=out,
        **CHIP,
    ):
        pass
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


@pytest.mark.parametrize("reuse", [True, False])
def test_memory_does_not_grow_with_frames(reuse):
    """Peak traced memory for 30 frames exceeds that for 3 by less than one frame of codes
    (512 KiB), with and without caller-provided buffers."""

    def out():
        shape = (1, 256, 256)
        return (np.empty(shape, np.int64), np.empty(shape, np.int64)) if reuse else None

    sensor_chain(np.random.default_rng(0), np.ones((4, 4)), n_frames=1, dark_e=0.0, **CHIP)
    assert _peak_bytes(30, out()) - _peak_bytes(3, out()) < 256 * 256 * 8


def test_out_buffers_are_written_and_yielded():
    out = (np.empty((2, 8, 8), np.int64), np.empty((2, 8, 8), np.int64))
    frames = sensor_chain(
        np.random.default_rng(1),
        np.full((8, 8), 100.0),
        n_frames=2,
        dark_e=0.0,
        n_samples=2,
        read_reset=True,
        out=out,
        **CHIP,
    )
    for r, s in frames:
        assert r is out[0] and s is out[1]
    fresh = list(
        sensor_chain(
            np.random.default_rng(1),
            np.full((8, 8), 100.0),
            n_frames=2,
            dark_e=0.0,
            n_samples=2,
            read_reset=True,
            **CHIP,
        )
    )
    assert np.array_equal(fresh[1][1], out[1]) and not np.array_equal(fresh[0][1], fresh[1][1])


# --- argument checks ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"qe": 1.2}, "qe"),
        ({"full_well_e": 0.0}, "full_well_e"),
        ({"bits": 30}, "bits"),
        ({"v_max_V": -1.0}, "v_max_V"),
        ({"n_samples": 0}, "n_samples"),
        ({"n_threads": 0}, "n_threads"),
        ({"chunk_pixels": 0}, "chunk_pixels"),
        ({"shot_noise": "normal"}, "shot_noise"),
        ({"dark_e": np.ones(3)}, "dark_e"),
        ({"gain_map": -1.0}, "gain_map"),
        ({"n_frames": -1}, "n_frames"),
        ({"out": (np.empty((1, 4, 4), np.int64), np.empty((1, 4, 4), np.int64))}, r"out\[0\]"),
    ],
)
def test_bad_arguments_raise_when_called(kw, name):
    args = CHIP | {"dark_e": 0.0, "n_frames": 2} | kw
    with pytest.raises(ValueError, match=name):
        sensor_chain(np.random.default_rng(0), np.ones((4, 4)), **args)


def test_bad_later_frame_raises_when_reached():
    frames = sensor_chain(
        np.random.default_rng(0), [np.ones((4, 4)), np.ones((4, 5))], dark_e=0.0, **CHIP
    )
    next(frames)
    with pytest.raises(ValueError, match="shape"):
        next(frames)


def test_no_frames_yields_nothing():
    assert list(sensor_chain(np.random.default_rng(0), [], dark_e=0.0, **CHIP)) == []
    assert (
        list(sensor_chain(np.random.default_rng(0), np.ones(3), n_frames=0, dark_e=0.0, **CHIP))
        == []
    )
