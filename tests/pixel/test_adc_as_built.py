"""The converter as built (chiptwin.pixel.converter): equivalence with today's ideal converter,
exactness of the transition-table lookup against a numpy oracle, and Monte Carlo checks of the
DNL statistics, the ``expected`` level's moments and the dither law.

Equivalence tests are bit for bit; the Monte Carlo tests have fixed seeds and tolerances of four
standard errors (a wrong model fails them by tens).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ndtr

from chiptwin.pixel import (
    AsBuilt,
    Converter,
    adc_convert,
    adc_expected,
    binned_codes,
    build_converter,
    check_transition_table,
    chunk_streams,
    load_transition_table,
    quantization_var_of_mean,
    sensor_chain,
)
from chiptwin.pixel.ramp import MAX_TABLE_BYTES

BITS = 10
TOP = 2**BITS - 1
LSB = 1.0 / 2**BITS  # v_min 0, v_max 1: LSB a power of two, so ties are exact in volts


def _volts_with_ties(rng: np.random.Generator, n: int, shape: tuple[int, ...] = ()) -> np.ndarray:
    """Random volts plus exact ties (k + 0.5 LSB), both range ends and beyond (±inf)."""
    v = rng.uniform(-0.05, 1.05, (n, *shape))
    ties = (rng.integers(-3, TOP + 3, (n, *shape)) + 0.5) * LSB
    v = np.where(rng.random((n, *shape)) < 0.3, ties, v)
    v.flat[:4] = [-np.inf, np.inf, -0.5 * LSB, (TOP + 0.5) * LSB]
    return v


def _oracle(levels: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The lookup by numpy: ``#{levels ≤ x}``; on a level, half to even of the codes either side."""
    lo = np.searchsorted(levels, x, side="left")
    hi = np.searchsorted(levels, x, side="right")
    return np.where(lo % 2 == 0, lo, hi)


# --- defaults: today's converter, bit for bit -------------------------------------------------


@pytest.mark.parametrize("offset, gain", [(0.0, 0.0), (0.25, 0.0), (-1.5, 0.01), (0.5, -0.02)])
def test_defaults_give_todays_codes(offset, gain):
    rng = np.random.default_rng(1)
    volts = _volts_with_ties(rng, 4000, (2, 3))
    conv = build_converter(
        rng, (2, 3), bits=BITS, v_min_V=0.0, v_max_V=1.0, offset_lsb=offset, gain_error=gain
    )
    assert conv.ideal
    assert np.array_equal(conv.convert(volts), adc_convert(volts, BITS, 0.0, 1.0, offset, gain))


def test_defaults_draw_nothing_from_the_map_stream():
    rng = np.random.default_rng(2)
    state = rng.bit_generator.state
    build_converter(
        rng,
        (8, 16),
        bits=13,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(inl_max_lsb=2.0, comparator_noise_lsb=0.5),
    )
    assert rng.bit_generator.state == state  # INL and comparator noise are not map draws


def test_ideal_table_is_rint_with_ties_to_even():
    """The table ``k + 0.5``, through the table kernel, gives ``clip(rint(x))`` bit for bit."""
    rng = np.random.default_rng(3)
    volts = _volts_with_ties(rng, 20000)
    table = np.arange(TOP, dtype=float) + 0.5
    conv = Converter(BITS, 0.0, 1.0, levels=table, shape=(1,))
    assert not conv.ideal
    got = conv.convert(volts[:, None])[:, 0]
    assert np.array_equal(got, adc_convert(volts, BITS, 0.0, 1.0))
    ties = (np.arange(-2, TOP + 3) + 0.5) * LSB
    assert np.array_equal(conv.convert(ties[:, None])[:, 0], adc_convert(ties, BITS, 0.0, 1.0))


def _chain_kw():
    return dict(
        qe=0.5,
        dark_e=20.0,
        full_well_e=2e4,
        read_noise_e=30.0,
        ktc_e=40.0,
        conversion_gain_uV_per_e=30.0,
        pedestal_V=0.05,
        n_samples=2,
        read_reset=True,
    )


def test_sensor_chain_with_the_ideal_converter_is_unchanged():
    photons = np.random.default_rng(4).uniform(0, 2e4, (20, 30))
    kw = _chain_kw()
    conv = build_converter(
        np.random.default_rng(0), (20, 30), bits=12, v_min_V=0.0, v_max_V=1.0, offset_lsb=0.3
    )
    ref = [
        tuple(map(np.copy, f))
        for f in sensor_chain(
            np.random.default_rng(9),
            photons,
            n_frames=3,
            bits=12,
            v_min_V=0.0,
            v_max_V=1.0,
            offset_lsb=0.3,
            chunk_pixels=256,
            **kw,
        )
    ]
    got = [
        tuple(map(np.copy, f))
        for f in sensor_chain(
            np.random.default_rng(9), photons, n_frames=3, converter=conv, chunk_pixels=256, **kw
        )
    ]
    for (r0, s0), (r1, s1) in zip(ref, got, strict=True):
        assert np.array_equal(r0, r1) and np.array_equal(s0, s1)


def _frames_kw():
    return dict(
        full_well_e=3e4,
        ktc_e=40.0,
        read_noise_e=30.0,
        n_samples=2,
        true_cds=True,
        conversion_gain_uV_per_e=30.0,
        pedestal_V=0.05,
    )


def test_binned_codes_with_the_ideal_converter_is_unchanged():
    lam = np.random.default_rng(5).uniform(0, 2e4, (4, 300))
    conv = Converter.ideal_adc(12, 0.0, 1.0, -0.4, 0.01)
    r0, r1 = np.random.default_rng(6), np.random.default_rng(6)
    ref = binned_codes(
        r0, lam, bits=12, v_min_V=0.0, v_max_V=1.0, offset_lsb=-0.4, gain_error=0.01, **_frames_kw()
    )
    got = binned_codes(r1, lam, converter=conv, **_frames_kw())
    assert np.array_equal(ref, got) and r0.bit_generator.state == r1.bit_generator.state


# --- the table lookup, exactly --------------------------------------------------------------


def _random_table(rng: np.random.Generator, bits: int) -> np.ndarray:
    """Non-decreasing levels with repeats (missing codes) and values on the half-LSB grid."""
    steps = rng.choice([0.0, 0.25, 0.5, 1.0, 1.5, 2.0], 2**bits - 2)
    return np.concatenate([[0.5], 0.5 + np.cumsum(steps)]) * (2**bits - 2) / max(steps.sum(), 1)


def test_injected_table_is_applied_exactly():
    """Per-column tables, per-converter gain and offset: the kernel against a numpy oracle, on
    random inputs and on inputs exactly on the levels (ties)."""
    rng = np.random.default_rng(7)
    shape = (3, 4)
    levels = np.array([_random_table(rng, BITS) for _ in range(4)])
    gain, offset = 1.0 + 0.01 * rng.standard_normal(12), 0.3 * rng.standard_normal(12)
    rows = np.tile(np.arange(4), 3)
    conv = Converter(
        BITS,
        0.0,
        1.0,
        0.2,
        0.01,
        levels=levels,
        table_of_pixel=rows,
        pixel_gain=gain,
        pixel_offset_lsb=offset,
        shape=shape,
    )
    volts = rng.uniform(-0.05, 1.05, (3000, *shape))
    x = ((volts - 0.0) / LSB * 1.01 + 0.2) * gain.reshape(shape) + offset.reshape(shape)
    want = np.empty(x.shape, np.int64)
    for i in range(12):
        r, c = divmod(i, 4)
        want[:, r, c] = _oracle(levels[rows[i]], x[:, r, c])
    assert np.array_equal(conv.convert(volts), want)
    on_level = Converter(BITS, 0.0, 1.0, levels=levels[:1], shape=(1,))
    xs = np.concatenate([levels[0], levels[0] + 1e-9, levels[0] - 1e-9])
    got = on_level.convert(xs[:, None] * LSB)[:, 0]
    assert np.array_equal(got, _oracle(levels[0], xs * LSB / LSB))


def test_missing_codes_never_appear():
    rng = np.random.default_rng(8)
    conv = build_converter(
        rng,
        (2, 2),
        bits=8,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(dnl_rms_lsb=0.8, ramp="column"),
    )
    volts = np.linspace(-0.01, 1.01, 200_001)[:, None, None] * np.ones((1, 2, 2))
    codes = conv.convert(volts)
    for row in range(2):
        t = conv.levels[row]
        missing = np.flatnonzero(t[1:] == t[:-1]) + 1  # code k has levels[k−1] == levels[k]
        present = np.unique(codes[:, :, row])
        assert missing.size > 5
        assert not np.isin(missing, present).any()
        assert present.size == 256 - missing.size  # every other code is reached by the ramp


def test_dnl_statistics_match_dnl_rms():
    """Small σ (no clipping): the widths' rms is σ within its standard error; the end points stay.
    Large σ: the fraction of missing codes is P(1 + σz ≤ 0) = Φ(−1/σ) within binomial error."""
    conv = build_converter(
        np.random.default_rng(10),
        (4,),
        bits=13,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(dnl_rms_lsb=0.1, ramp="pixel"),
    )
    widths = np.diff(conv.levels, axis=1)
    assert conv.levels.shape == (4, 8191)
    assert np.all(conv.levels[:, 0] == 0.5) and np.all(conv.levels[:, -1] == 8190.5)
    n = widths.size
    assert abs(widths.std() - 0.1) < 4 * 0.1 / np.sqrt(2 * n)
    assert abs(np.corrcoef(widths[0], widths[1])[0, 1]) < 4 / np.sqrt(widths.shape[1])
    wide = build_converter(
        np.random.default_rng(11),
        (1,),
        bits=13,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(dnl_rms_lsb=0.8),
    )
    frac, p = np.mean(np.diff(wide.levels[0]) == 0.0), ndtr(-1.0 / 0.8)
    assert abs(frac - p) < 4 * np.sqrt(p * (1 - p) / 8190)


def test_inl_bow_has_its_peak_and_keeps_the_end_points():
    for shape, u_peak in (("quadratic", 0.5), ("cubic", 0.5 - 0.5 / np.sqrt(3))):
        conv = build_converter(
            np.random.default_rng(0),
            (1,),
            bits=12,
            v_min_V=0.0,
            v_max_V=1.0,
            as_built=AsBuilt(inl_max_lsb=3.0, inl_shape=shape),
        )
        inl = conv.levels[0] - (np.arange(4095) + 0.5)
        assert inl[0] == 0.0 and inl[-1] == 0.0
        assert abs(inl.max() - 3.0) < 1e-5 and abs(np.argmax(inl) / 4094 - u_peak) < 1e-3


# --- the expected level ---------------------------------------------------------------------


def test_expected_with_the_ideal_table_is_todays_sum():
    mu = np.linspace(-3.0, 70.0, 301) * (1 / 64)
    sd = np.tile([0.0, 0.05, 0.3, 1.0, 1.9], 61)[:301] * (1 / 64)
    conv = Converter(6, 0.0, 1.0, levels=np.arange(63) + 0.5, shape=(1,))
    m_t, v_t = conv.expected(mu[:, None], (sd**2)[:, None])
    m_r, v_r = adc_expected(mu, sd**2, 6, 0.0, 1.0)
    np.testing.assert_allclose(m_t[:, 0], m_r, rtol=0, atol=1e-12)
    np.testing.assert_allclose(v_t[:, 0], v_r, rtol=0, atol=1e-12)


def test_expected_matches_a_monte_carlo_of_the_binned_path():
    """INL, DNL, mismatch and comparator noise on: the moments of the codes of Gaussian inputs."""
    rng = np.random.default_rng(12)
    spec = AsBuilt(
        comparator_noise_lsb=0.3,
        inl_max_lsb=2.5,
        inl_shape="cubic",
        dnl_rms_lsb=0.5,
        offset_sigma_lsb=0.7,
        gain_sigma=0.02,
        ramp="column",
    )
    conv = build_converter(
        rng, (2, 3), bits=8, v_min_V=0.0, v_max_V=1.0, offset_lsb=0.1, as_built=spec
    )
    mean_V = np.array([[0.0, 17.3, 100.5], [200.2, 254.9, 64.0]]) / 256
    sd_V = np.array([[0.4, 0.0, 0.2], [1.5, 0.8, 3.0]]) / 256
    m, v = conv.expected(mean_V, sd_V**2)
    n = 200_000
    volts = mean_V + sd_V * rng.standard_normal((n, 2, 3))
    codes = conv.convert(volts, np.random.default_rng(13)).astype(float)
    mc_mean, mc_var = codes.mean(axis=0), codes.var(axis=0)
    m4 = ((codes - mc_mean) ** 4).mean(axis=0)
    assert np.all(np.abs(mc_mean - m) <= 4 * np.sqrt(v / n) + 1e-12)
    assert np.all(np.abs(mc_var - v) <= 4 * np.sqrt(np.maximum(m4 - v * v, 0) / n) + 1e-12)


# --- the dither law -------------------------------------------------------------------------------


def _mean_of_m(conv: Converter, level_lsb: np.ndarray, m: int, seed: int) -> np.ndarray:
    """Mean of ``m`` conversions of each level, comparator noise the only noise."""
    volts = np.repeat(level_lsb[:, None], m, axis=1) * LSB
    return conv.convert(volts[..., None], np.random.default_rng(seed))[..., 0].mean(axis=1)


@pytest.mark.parametrize("sigma", [0.5, 1.0])
def test_dither_makes_the_mean_unbiased(sigma):
    """Fixed levels: the mean of M = 4 conversions is unbiased to within 4 standard errors (plus
    the residual bias bound exp(−2π²σ²)/π, 2e-3 LSB at σ = 0.5)."""
    conv = Converter(BITS, 0.0, 1.0, comparator_noise_lsb=sigma, shape=(1,))
    reps, m = 20_000, 4
    for frac in (0.0, 0.25, 0.3, 0.5, 0.8):
        err = _mean_of_m(conv, np.full(reps, 300.0 + frac), m, seed=int(frac * 10)) - (300 + frac)
        se = err.std() / np.sqrt(reps)
        assert abs(err.mean()) < 4 * se + np.exp(-2 * np.pi**2 * sigma**2) / np.pi


@pytest.mark.parametrize("sigma, m", [(0.5, 4), (1.0, 8), (0.7, 1)])
def test_dither_variance_is_sigma2_over_m_plus_the_residual(sigma, m):
    """Levels uniform modulo one LSB: var(mean of M − level) = σ²/M + the rounding residual of
    :func:`quantization_var_of_mean` (≈ 1/(12M) once σ ≥ 0.5)."""
    conv = Converter(BITS, 0.0, 1.0, comparator_noise_lsb=sigma, shape=(1,))
    reps = 40_000
    levels = 200.0 + np.random.default_rng(14).random(reps) * 100
    err = _mean_of_m(conv, levels, m, seed=15) - levels
    want = sigma**2 / m + quantization_var_of_mean(m, sigma)
    assert abs(err.mean()) < 4 * err.std() / np.sqrt(reps)
    assert abs(err.var() - want) < 4 * want * np.sqrt(2 / reps)


def test_without_noise_the_error_is_the_deterministic_rounding():
    """σ → 0: every one of the M conversions rounds alike, the error does not average down
    (variance 1/12, ``quantization_var_of_mean(M, 0)``), and it is ``rint(level) − level``."""
    conv = Converter(BITS, 0.0, 1.0, comparator_noise_lsb=1e-9, shape=(1,))
    levels = 200.0 + np.random.default_rng(16).random(20_000) * 100
    err = _mean_of_m(conv, levels, 8, seed=17) - levels
    np.testing.assert_array_equal(err, np.rint(levels) - levels)
    assert abs(err.var() - quantization_var_of_mean(8, 0.0)) < 4 * (1 / 12) * np.sqrt(2 / 20_000)


@pytest.mark.parametrize("read_e", [0.0, 6.0])
def test_binned_codes_fold_the_comparator_noise_into_the_read_noise(read_e):
    """No charge: the codes are the pedestal dithered by read and comparator noise, whose
    variances add (one draw per sample of the summed variance, so the pixel stream ends where
    the ideal converter leaves it); the mean of the codes is unbiased (the dither law) and
    their variance is σ_read² + σ_comp² + 1/12 (σ ≥ 0.5 LSB), per converter gain included."""
    level, sigma, n = 100.3, 0.6, 50
    kw = dict(_frames_kw(), ktc_e=0.0, read_noise_e=read_e, n_samples=8, pedestal_V=level * LSB)
    gains = 1.0 + 0.02 * np.random.default_rng(17).standard_normal(n)
    conv = Converter(BITS, 0.0, 1.0, comparator_noise_lsb=sigma, pixel_gain=gains, shape=(n,))
    r0, r1 = np.random.default_rng(18), np.random.default_rng(18)
    codes = binned_codes(r0, np.zeros((400, n)), converter=conv, **kw)[:, 8:].reshape(-1, n)
    codes = codes.astype(float)
    binned_codes(r1, np.zeros((400, n)), bits=BITS, v_min_V=0.0, v_max_V=1.0, **kw)
    assert r0.bit_generator.state == r1.bit_generator.state
    read_lsb = read_e * kw["conversion_gain_uV_per_e"] * 1e-6 / LSB * gains
    want_var = read_lsb**2 + sigma**2 + 1 / 12
    err = codes.mean(axis=0) - level * gains
    assert np.all(np.abs(err) < 4 * np.sqrt(want_var / 3200))
    ratio = codes.var(axis=0) / want_var
    assert abs(ratio.mean() - 1) < 4 * np.sqrt(2 / 3200 / n)


# --- threads and streams ----------------------------------------------------------------------


def _built(shape: tuple[int, ...], bits: int = 12) -> Converter:
    spec = AsBuilt(
        comparator_noise_lsb=0.4,
        inl_max_lsb=2.0,
        dnl_rms_lsb=0.2,
        ramp="column",
        offset_sigma_lsb=0.5,
        gain_sigma=0.01,
    )
    return build_converter(
        np.random.default_rng(20), shape, bits=bits, v_min_V=0.0, v_max_V=1.0, as_built=spec
    )


def test_sensor_chain_as_built_does_not_depend_on_the_thread_count():
    photons = np.random.default_rng(21).uniform(0, 2e4, (24, 40))
    conv = _built((24, 40))
    runs = []
    for threads in (1, 2, 3):
        frames = sensor_chain(
            np.random.default_rng(22),
            photons,
            n_frames=2,
            converter=conv,
            n_threads=threads,
            chunk_pixels=200,
            **_chain_kw(),
        )
        runs.append([np.concatenate([np.copy(r), np.copy(s)]) for r, s in frames])
    for run in runs[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(run, runs[0], strict=True))


def test_binned_codes_as_built_does_not_depend_on_the_thread_count():
    n = 2 * 2048 + 100
    lam = np.random.default_rng(23).uniform(0, 2e4, (2, n))
    conv = _built((2, n // 2), bits=10)
    runs = []
    for threads in (1, 2, 3):
        codes = binned_codes(
            chunk_streams(np.random.default_rng(24), n),
            lam,
            converter=conv,
            threads=threads,
            **_frames_kw(),
        )
        runs.append(codes)
    assert all(np.array_equal(r, runs[0]) for r in runs[1:])


def test_comparator_noise_shifts_no_other_draw():
    """A vanishing comparator noise leaves every code of the noiseless converter (no ties in a
    continuous scene): folded into the read-noise draws, it draws nothing more."""
    photons = np.random.default_rng(26).uniform(0, 2e4, (10, 30))
    quiet = build_converter(
        np.random.default_rng(0),
        (10, 30),
        bits=12,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(inl_max_lsb=1.5),
    )
    noisy = Converter(12, 0.0, 1.0, comparator_noise_lsb=1e-12, levels=quiet.levels, shape=(10, 30))
    a = [
        np.copy(s)
        for _, s in sensor_chain(
            np.random.default_rng(27),
            photons,
            n_frames=2,
            converter=quiet,
            chunk_pixels=128,
            **_chain_kw(),
        )
    ]
    b = [
        np.copy(s)
        for _, s in sensor_chain(
            np.random.default_rng(27),
            photons,
            n_frames=2,
            converter=noisy,
            chunk_pixels=128,
            **_chain_kw(),
        )
    ]
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


# --- bad parameters ----------------------------------------------------------------------


@pytest.mark.parametrize("kw, name", [
    ({"comparator_noise_lsb": -0.1}, "comparator_noise_lsb"),
    ({"dnl_rms_lsb": -1.0}, "dnl_rms_lsb"),
    ({"offset_sigma_lsb": float("nan")}, "offset_sigma_lsb"),
    ({"gain_sigma": 0.5}, "gain_sigma"),
    ({"inl_shape": "sine"}, "inl_shape"),
    ({"ramp": "row"}, "ramp"),
    ({"inl_shape": "table"}, "inl_table"),
    ({"inl_table": [0.5, 1.5]}, "inl_table"),
    ({"inl_shape": "table", "inl_table": [0.5, 1.5, 2.5], "inl_max_lsb": 1.0}, "inl_max_lsb"),
])  # fmt: skip
def test_bad_parameters_name_themselves(kw, name):
    with pytest.raises(ValueError, match=name):
        AsBuilt(**kw)


def test_bad_tables_name_the_key(tmp_path):
    with pytest.raises(ValueError, match="inl_table decreases at level 2"):
        check_transition_table([0.5, 1.5, 1.4], 2)
    with pytest.raises(ValueError, match="inl_table has 4 transition levels.*2\\^2 − 1 = 3"):
        check_transition_table([0.5, 1.5, 2.5, 3.5], 2)
    with pytest.raises(ValueError, match="inl_table contains NaN"):
        check_transition_table([0.5, np.nan, 2.5], 2)
    path = tmp_path / "levels.txt"
    path.write_text("# ramp of chip 3\n0.5, 1.6\n2.5\n")
    np.testing.assert_array_equal(load_transition_table(path, 2), [0.5, 1.6, 2.5])
    np.save(tmp_path / "levels.npy", np.array([0.5, 1.6, 2.4]))
    assert load_transition_table(tmp_path / "levels.npy", 2)[2] == 2.4
    path.write_text("0.5 x 2\n")
    with pytest.raises(ValueError, match="inl_table"):
        load_transition_table(path, 2)
    spec = AsBuilt(inl_shape="table", inl_table=str(tmp_path / "levels.npy"))
    conv = build_converter(
        np.random.default_rng(0), (1,), bits=2, v_min_V=0.0, v_max_V=1.0, as_built=spec
    )
    assert list(conv.convert(np.array([[0.05], [0.25], [0.5], [0.75]]))[:, 0]) == [0, 1, 2, 3]


def test_reversing_bow_and_oversized_tables_are_refused():
    with pytest.raises(ValueError, match="inl_max_lsb"):
        build_converter(
            np.random.default_rng(0),
            (1,),
            bits=4,
            v_min_V=0.0,
            v_max_V=1.0,
            as_built=AsBuilt(inl_max_lsb=4.0),
        )
    with pytest.raises(ValueError, match="ramp = 'pixel' with dnl_rms_lsb = 0.1.*GB"):
        build_converter(
            np.random.default_rng(0),
            (256, 256),
            bits=13,
            v_min_V=0.0,
            v_max_V=1.0,
            as_built=AsBuilt(dnl_rms_lsb=0.1, ramp="pixel"),
        )
    # per-pixel ramps without DNL share one table: 256 × 256 at 13 bits is small
    conv = build_converter(
        np.random.default_rng(0),
        (256, 256),
        bits=13,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(inl_max_lsb=3.0, ramp="pixel", offset_sigma_lsb=0.5),
    )
    assert conv.levels.shape == (1, 8191) and conv.levels.nbytes * 1.5 < MAX_TABLE_BYTES


def test_converter_and_keywords_are_exclusive():
    conv = Converter.ideal_adc(12, 0.0, 1.0)
    with pytest.raises(ValueError, match="bits given with converter"):
        binned_codes(
            np.random.default_rng(0), np.zeros((1, 3)), bits=12, converter=conv, **_frames_kw()
        )
    with pytest.raises(ValueError, match="converter describes 4 converters"):
        binned_codes(
            np.random.default_rng(0),
            np.zeros((1, 3)),
            converter=Converter(12, 0.0, 1.0, comparator_noise_lsb=0.1, shape=(4,)),
            **_frames_kw(),
        )


def test_switching_one_effect_on_keeps_the_others_draws():
    base = AsBuilt(dnl_rms_lsb=0.3, gain_sigma=0.01)
    a = build_converter(
        np.random.default_rng(30), (4, 4), bits=8, v_min_V=0.0, v_max_V=1.0, as_built=base
    )
    b = build_converter(
        np.random.default_rng(30),
        (4, 4),
        bits=8,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt(dnl_rms_lsb=0.3, gain_sigma=0.01, offset_sigma_lsb=1.0),
    )
    assert np.array_equal(a.levels, b.levels) and np.array_equal(a.pixel_gain, b.pixel_gain)


def test_as_built_from_the_scenario_keys(tmp_path):
    """The wiring's adapter: ``[chip.adc]`` read by name, the table path taken from the
    scenario's folder; the schema's defaults give the ideal converter."""
    from chiptwin.config.schema import Adc

    assert AsBuilt.from_keys(Adc()) == AsBuilt()
    conv = build_converter(
        np.random.default_rng(0),
        (8, 16),
        bits=13,
        v_min_V=0.0,
        v_max_V=1.0,
        as_built=AsBuilt.from_keys(Adc()),
    )
    assert conv.ideal
    np.savetxt(tmp_path / "ramp.txt", np.arange(3) + 0.5)
    adc = Adc(bits=2, inl_shape="table", inl_table="ramp.txt", comparator_noise_lsb=0.25)
    spec = AsBuilt.from_keys(adc, tmp_path)
    assert spec.inl_table == str(tmp_path / "ramp.txt") and spec.comparator_noise_lsb == 0.25


def test_expected_on_the_ideal_table_is_the_numpy_sums():
    """A converter with comparator noise or mismatch but no levels takes its expected moments
    from one numba pass over the ideal transitions (table_moments); they agree with NumPy's sums
    of adc_expected (pixel.adc._moments) to 1e-12 LSB / relative, clipped ends and σ from
    0.05 to 40 LSB included."""
    from chiptwin.pixel.adc import _moments
    from chiptwin.pixel.converter import Converter

    rng = np.random.default_rng(5)
    n = 4000
    conv = Converter(bits=10, v_min_V=0.0, v_max_V=1.0, comparator_noise_lsb=0.7, shape=(n,),
                     pixel_gain=rng.uniform(0.98, 1.02, n), pixel_offset_lsb=rng.normal(0, 1, n))
    lsb = 1.0 / 1024
    mean_v = rng.uniform(-5 * lsb, 1 + 5 * lsb, n)
    var_v = (rng.uniform(0.05, 40.0, n) * lsb) ** 2
    got_mean, got_var = conv.expected(mean_v, var_v)
    mu = mean_v / lsb * conv.pixel_gain + conv.pixel_offset_lsb
    sd = np.sqrt((np.sqrt(var_v) / lsb * conv.pixel_gain) ** 2 + 0.7**2)
    want_mean, want_var = _moments(mu, sd, 1023.0)
    assert np.allclose(got_mean, want_mean, rtol=1e-12, atol=1e-12)
    assert np.allclose(got_var, want_var, rtol=1e-12, atol=1e-12)


def test_table_window_bounds_are_searchsorted():
    """``table_moments`` bounds its window of levels through the search LUT
    (``_kernels._count_below``) instead of two binary searches: the counts are
    ``np.searchsorted``'s, side left and right, on random tables, a table with repeated levels
    and codes narrower than a LUT cell (several levels in one cell), at inputs on the levels,
    between them and far past both ends."""
    from chiptwin.pixel import _kernels
    from chiptwin.pixel.ramp import _padded, _search_lut

    rng = np.random.default_rng(11)
    tables = [_random_table(rng, BITS) for _ in range(3)]
    crowded = np.sort(np.concatenate([np.arange(2**BITS - 1 - 40) + 0.5,
                                      np.full(10, 100.25), 200.0 + np.linspace(0, 0.3, 30)]))
    tables.append(crowded)
    levels = np.array(tables)
    lut, base = _search_lut(levels)
    padded = _padded(levels)
    for r, t in enumerate(tables):
        xs = np.concatenate([t, np.nextafter(t, np.inf), np.nextafter(t, -np.inf),
                             rng.uniform(-50.0, 2.0**BITS + 50.0, 2000), [-1e300, 1e300]])
        for inclusive, side in ((False, "left"), (True, "right")):
            got = [_kernels._count_below(x, padded, lut, base, r, inclusive) for x in xs]
            assert np.array_equal(got, np.searchsorted(t, xs, side=side)), (r, side)


def test_converters_of_a_subset_share_the_tables_and_a_replaced_table_is_made_again():
    """``Converter.at`` hands its parent's checked levels and LUT on (made once, not per call);
    ``dataclasses.replace`` with other levels makes theirs (a stale LUT would convert with the
    old table)."""
    import dataclasses

    rng = np.random.default_rng(3)
    one, two = (_random_table(rng, BITS)[None, :] for _ in range(2))
    conv = Converter(BITS, 0.0, 1.0, levels=one, shape=(2,), pixel_gain=np.array([1.0, 1.01]))
    sub = conv.at([1])
    assert sub._conv[5] is conv._conv[5] and sub._conv[6] is conv._conv[6]
    volts = rng.uniform(0.0, 1.0, (500, 1))
    assert np.array_equal(sub.convert(volts), conv.convert(np.hstack([volts, volts]))[:, 1:])
    other = dataclasses.replace(conv, levels=two)
    fresh = Converter(BITS, 0.0, 1.0, levels=two, shape=(2,), pixel_gain=np.array([1.0, 1.01]))
    assert other._conv[6] is not conv._conv[6]
    volts2 = rng.uniform(0.0, 1.0, (500, 2))
    assert np.array_equal(other.convert(volts2), fresh.convert(volts2))
    # a replace that keeps the levels' buffer but not the levels (rows reversed: a view of the
    # same table) or changes the bits: made again, or refused, never the parent's tables
    ramps = Converter(BITS, 0.0, 1.0, levels=np.vstack([one, two]), shape=(2,),
                      table_of_pixel=np.array([0, 1]))
    flipped = dataclasses.replace(ramps, levels=ramps.levels[::-1])
    assert np.array_equal(flipped.convert(volts2), Converter(
        BITS, 0.0, 1.0, levels=np.vstack([two, one]), shape=(2,),
        table_of_pixel=np.array([0, 1])).convert(volts2))
    with pytest.raises(ValueError, match="transition levels"):
        dataclasses.replace(conv, bits=BITS - 1)
    assert conv.at([]).n_pixels == 0  # an empty subset of a converter with tables


def test_levels_far_outside_the_range_and_overflowing_inputs_are_refused():
    """A stray level at 1,000 LSB of a 2-bit converter (a unit mix-up) asked for a search LUT
    over its whole span (1e9 LSB: ≈ 30 GiB); an input of 1e306 V overflowed to +inf LSB and the
    table sums walked past the table's end. Both refused, naming what is wrong."""
    with pytest.raises(ValueError, match="levels must lie within one range"):
        check_transition_table([0.5, 1.5, 1000.0], 2)
    check_transition_table([-3.5, 1.5, 7.5], 2)  # within one range on either side: accepted
    rng = np.random.default_rng(4)
    conv = Converter(BITS, 0.0, 1.0, levels=_random_table(rng, BITS)[None, :], shape=(1,))
    assert np.isfinite(conv.expected(np.array([1e300]), 0.0)[0]).all()
    with pytest.raises(ValueError, match="overflow"):
        conv.expected(np.array([1e306]), 0.0)
    mean, _ = conv.expected(np.array([0.5]), 1e300)  # 1e150 V rms: wide, finite, still sums
    assert np.isfinite(mean).all()
