"""The expected level through the converter as built: the CMS output's mean and
variance from the transition tables, checked against a slow reference and a Monte Carlo of the
binned path."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from chiptwin import pixel
from chiptwin.config import load_scenario
from chiptwin.pixel import expected_adc
from chiptwin.twin import runner, scene
from tests.conftest import SMALL

LSB = 1.0 / 8192
AS_BUILT = pixel.AsBuilt(comparator_noise_lsb=0.5, inl_max_lsb=2.0, dnl_rms_lsb=0.2,
                         offset_sigma_lsb=0.3, gain_sigma=0.01, ramp="column")
ON = ["chip.adc.comparator_noise_lsb=0.5", "chip.adc.inl_max_lsb=2.0", "chip.adc.dnl_rms_lsb=0.2",
      "chip.adc.offset_sigma_lsb=0.3", "chip.adc.gain_sigma=0.01"]


@pytest.mark.parametrize("white_lsb", [0.01, 0.026, 0.13, 1.0])
@pytest.mark.parametrize("ratio", [0.5, 2.0, 6.5, 20.0, 60.0, 300.0])
def test_quadrature_is_within_its_stated_bound(white_lsb, ratio):
    """E_y[v(y)] by the quadrature (INL and DNL: no series) against a 16001-point trapezoid over
    ±8σ (a step of at most 0.3 white rms): within QUAD_TOL_LSB2 up to QUAD_MAX_RATIO, within
    2e-3 LSB² beyond, where the nodes thin out. The helper's case that found Gauss–Hermite out:
    white 0.026 LSB (20 e⁻ of read noise at 1 pF), kTC 20× it; the reference chip's 6.5×."""
    spec = dataclasses.replace(AS_BUILT, comparator_noise_lsb=0.0)
    conv = pixel.build_converter(np.random.default_rng(1), (1, 4), bits=13, v_min_V=0.0,
                                 v_max_V=1.0, as_built=spec)
    mu = np.array([[0.3, 0.31, 0.5123, 0.7]])
    sd = np.full((1, 4), ratio * white_lsb * LSB)
    white = (white_lsb * LSB) ** 2
    reference = _trapezoid(conv, mu, sd, white)
    err = np.max(np.abs(expected_adc.mean_of_var(conv, mu, sd, white) - reference))
    assert err <= (expected_adc.QUAD_TOL_LSB2 if ratio <= expected_adc.QUAD_MAX_RATIO
                   else 2e-3), err


def _trapezoid(conv, mu, sd, white, shot=0.0, ped=None, k_sd=0.0):
    """The slow reference: E_y[v(y)] and the shared kTC covariance by a 16001-point trapezoid
    over ±8σ of the converter's exact table sums."""
    t = np.linspace(-8.0, 8.0, 16001)
    wt = np.exp(-t * t / 2)
    wt /= wt.sum()
    t = t.reshape((-1,) + (1,) * np.ndim(mu))
    _, v = conv.expected(mu + sd * t, white)
    if ped is None:
        return np.tensordot(wt, v, axes=1)
    g, _ = conv.expected(mu + k_sd * t, shot + white)
    f, _ = conv.expected(ped + k_sd * t, white)
    g, f = g - np.tensordot(wt, g, axes=1), f - np.tensordot(wt, f, axes=1)
    return np.tensordot(wt, v, axes=1), np.tensordot(wt, g * f, axes=1)


@pytest.mark.parametrize("noise_lsb", [0.0, 0.25, 1.0])
@pytest.mark.parametrize("read_lsb", [0.13, 0.5, 1.0])
def test_sawtooth_series_equals_the_exact_sums(noise_lsb, read_lsb):
    """On the ideal transitions (offset and gain mismatch on, no table) inside the range, the
    sawtooth's series for E_y[v(y)] and for the kTC covariance of true CDS against the slow
    trapezoid: within 1e-12 LSB² for shared rms 0.05 … 20 LSB (measured ≤ 2e-13; Gauss–Hermite,
    the quadrature before this round, was off by up to 0.03 LSB² on the same cases)."""
    spec = dataclasses.replace(AS_BUILT, comparator_noise_lsb=noise_lsb, inl_max_lsb=0.0,
                               dnl_rms_lsb=0.0)
    conv = pixel.build_converter(np.random.default_rng(1), (1, 4), bits=13, v_min_V=0.0,
                                 v_max_V=1.0, as_built=spec)
    assert conv.levels is None
    mu, ped = np.array([[0.3, 0.31, 0.5123, 0.7]]), np.full((1, 4), 0.05)
    white = (read_lsb * LSB) ** 2
    for shared_lsb in (0.05, 0.5, 1.0, 2.0, 5.0, 20.0):
        sd, shot = np.full((1, 4), shared_lsb * LSB), np.full((1, 4), (shared_lsb * LSB) ** 2)
        ref_v, ref_cov = _trapezoid(conv, mu, sd, white, shot, ped, 0.5 * LSB)
        got_v = expected_adc.mean_of_var(conv, mu, sd, white)
        got_cov = expected_adc._shared_ktc_cov(conv, mu, shot, ped, 0.5 * LSB, white)
        assert np.max(np.abs(got_v - ref_v)) < 1e-12, shared_lsb
        assert np.max(np.abs(got_cov - ref_cov)) < 1e-12, shared_lsb


def test_elements_off_the_series_take_the_quadrature_with_their_own_converters():
    """An input near the range's top (clipping) and a converter with a transition table are
    not on the series: those elements take the quadrature on their own converters, each with the
    node set of its own spread (a wide element beside narrow ones), the others the series'; all
    within QUAD_TOL_LSB2 of the slow trapezoid."""
    spec = dataclasses.replace(AS_BUILT, inl_max_lsb=0.0, dnl_rms_lsb=0.0)
    conv = pixel.build_converter(np.random.default_rng(1), (1, 4), bits=13, v_min_V=0.0,
                                 v_max_V=1.0, as_built=spec)
    mu = np.array([[[0.3, 0.5, 0.9995, 0.7]], [[0.2, 0.9999, 0.4, 0.6]]])
    sd = np.full(mu.shape, 0.7 * LSB)
    sd[1, 0, 1] = 30.0 * LSB  # one wide element: its own nodes, not everyone's
    white = (0.13 * LSB) ** 2
    got = expected_adc.mean_of_var(conv, mu, sd, white)
    assert (mu > 0.999).sum() == 2
    assert np.max(np.abs(got - _trapezoid(conv, mu, sd, white))) < expected_adc.QUAD_TOL_LSB2
    table = pixel.build_converter(np.random.default_rng(1), (1, 4), bits=13, v_min_V=0.0,
                                  v_max_V=1.0, as_built=AS_BUILT)
    got = expected_adc.mean_of_var(table, mu, sd, white)
    assert np.max(np.abs(got - _trapezoid(table, mu, sd, white))) < expected_adc.QUAD_TOL_LSB2
    ratios = expected_adc._ratios(table.at(np.arange(4)), sd[1, 0], white)
    assert len(set(expected_adc._node_counts(ratios).tolist())) == 2


def _scene(tmp_path, extra=()):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, ["run.fidelity.photons=expected", *extra])
    return s, runner.prepare(s)


@pytest.mark.parametrize("true_cds", [True, False])
def test_expected_moments_match_a_monte_carlo_of_the_binned_path(tmp_path, true_cds):
    """A small scene with INL, DNL, comparator noise and mismatch on: per pixel, the expected
    level's CMS mean and variance against 20000 binned draws of the brightest frame (the binned
    kernel, the scene's converter) agree within 4.5 standard errors (the largest z of 2 × 24
    pixels, two tests)."""
    extra = [*ON, f"chip.pixel.true_cds={str(true_cds).lower()}"]
    s, sc = _scene(tmp_path, extra)
    t_int = s.chip.timing.t_int_s
    frames = sc.pixel_frames(t_int, s.chip.adc.gain_error)
    f = int(np.argmax(frames.mean_e.sum(axis=1)))
    sensor = sc.sensor
    assert not sensor.converter.ideal
    n = 20000
    mean_e = np.repeat(frames.mean_e[f : f + 1], n, axis=0)
    codes = pixel.binned_codes(
        np.random.default_rng(3), mean_e, full_well_e=sensor.full_well_e, ktc_e=sensor.ktc_e,
        read_noise_e=sensor.read_noise_e, n_samples=sensor.cms_samples,
        true_cds=sensor.true_cds, conversion_gain_uV_per_e=sensor.conversion_gain_uV_per_e,
        pedestal_V=sensor.pedestal_V, converter=sensor.converter)
    m = sensor.cms_samples
    cms = codes[:, m:].mean(axis=1) - codes[:, :m].mean(axis=1)
    mc_mean, mc_var = cms.mean(axis=0), cms.var(axis=0, ddof=1)
    z_mean = (frames.cds_mean_lsb[f] - mc_mean) / np.sqrt(mc_var / n)
    z_var = (frames.cds_var_lsb2[f] - mc_var) / (mc_var * np.sqrt(2.0 / (n - 1)))
    assert np.max(np.abs(z_mean)) < 4.5 and np.max(np.abs(z_var)) < 4.5
    assert frames.cds_mean_lsb[f].max() > 10  # a lit pixel among them


def test_ideal_converter_keeps_the_linear_model_bit_for_bit(tmp_path):
    """With no as-built effect the expected level is today's arithmetic, array for array."""
    s, sc = _scene(tmp_path)
    assert sc.sensor.converter.ideal
    got = scene.pixel_frames(sc, s.chip.timing.t_int_s, s.chip.adc.gain_error)
    sensor = sc.sensor
    cds_e, var_e = pixel.clipped_poisson_moments(got.mean_e, sensor.full_well_e)
    var_e = var_e + 2 * sensor.read_noise_e**2 / sensor.cms_samples
    to_lsb = 1.0 / sensor.e_per_lsb
    quant = 2 * pixel.quantization_var_of_mean(sensor.cms_samples,
                                               sensor.read_noise_e / sensor.e_per_lsb)
    assert np.array_equal(got.cds_mean_lsb, cds_e * to_lsb)
    assert np.array_equal(got.cds_var_lsb2, var_e * to_lsb**2 + quant)


def test_expected_level_with_the_converter_as_built_is_accepted_and_runs(tmp_path):
    """The consistency rule no longer refuses it; the run reports the ADC level."""
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    result = runner.run(path, ["run.fidelity.photons=expected", *ON])
    assert result.summary["fidelity"]["adc"] == "as_built"
    ideal = runner.run(path, ["run.fidelity.photons=expected", *ON, 'run.fidelity.adc="ideal"'])
    assert ideal.summary["fidelity"]["adc"] == "ideal"
    assert result.summary["sites"][0]["signal_e"] != ideal.summary["sites"][0]["signal_e"]


def test_quadrature_in_slices_is_the_whole_and_holds_little_memory(monkeypatch):
    """The quadrature (a DNL table: no series) runs in slices of QUAD_SLICE_VALUES node values:
    any slicing gives the same bits, and the peak (tracemalloc) of the CMS moments of a block
    of 64 frames × 32 pixels (node sets of 79 … 131 nodes: kTC 4.5× the white noise, with shot
    noise up to 7×) stays below the memory estimate's term for slices of 65,536 values,
    12 arrays: 6.3 MB (the reference chip's 1,024-frame blocks held 1.75 GB unsliced)."""
    import tracemalloc

    spec = dataclasses.replace(AS_BUILT, comparator_noise_lsb=0.0)
    conv = pixel.build_converter(np.random.default_rng(1), (4, 8), bits=13, v_min_V=0.0,
                                 v_max_V=1.0, as_built=spec)
    rng = np.random.default_rng(2)
    mean_e = rng.uniform(0.0, 3e5, (64, 32))
    kw = dict(ktc_e=450.0, read_noise_e=100.0, cg_V=0.16e-6, pedestal_V=0.1, n_samples=4,
              true_cds=True)
    assert expected_adc.node_count(kw["ktc_e"], kw["read_noise_e"]) == 79
    expected_adc.cms_moments(conv, mean_e[:1], mean_e[:1], **kw)  # kernels loaded before
    monkeypatch.setattr(expected_adc, "QUAD_SLICE_VALUES", 1 << 16)
    tracemalloc.start()
    try:
        small = expected_adc.cms_moments(conv, mean_e, mean_e, **kw)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    monkeypatch.setattr(expected_adc, "QUAD_SLICE_VALUES", 7919)  # a prime: ragged slices
    ragged = expected_adc.cms_moments(conv, mean_e, mean_e, **kw)
    monkeypatch.setattr(expected_adc, "QUAD_SLICE_VALUES", 1 << 40)  # one slice: the whole
    whole = expected_adc.cms_moments(conv, mean_e, mean_e, **kw)
    for got in (small, ragged):
        assert all(np.array_equal(a, b) for a, b in zip(got, whole, strict=True))
    # the memory estimate's term for these slices (config.budget.QUADRATURE_ARRAYS arrays)
    from chiptwin.config.budget import QUADRATURE_ARRAYS

    assert peak < QUADRATURE_ARRAYS * (1 << 16) * 8 < 8e6, peak


@pytest.mark.parametrize("inl", [1.0, -2.0])
@pytest.mark.parametrize("shape", ["quadratic", "cubic"])
def test_series_on_a_smooth_bow_is_within_its_stated_bound(inl, shape):
    """A ramp with a smooth INL bow and no DNL (the reference chip as built) stays on the
    sawtooth's series through the bow's inverse: E_y[v(y)] and the true-CDS kTC covariance within
    SMOOTH_INL_TOL of the slow trapezoid over the exact transition table, for inputs across the
    range (where the bow's slope differs most between the reset and signal sides) and shared rms
    0.05 … 8 LSB (forced onto the series, the largest error measured was 5e-8 LSB²); the widest
    element leaves the series for the quadrature, also within the bound."""
    spec = dataclasses.replace(AS_BUILT, comparator_noise_lsb=0.5, inl_max_lsb=inl,
                               dnl_rms_lsb=0.0, inl_shape=shape)
    conv = pixel.build_converter(np.random.default_rng(1), (1, 4), bits=13, v_min_V=0.0,
                                 v_max_V=1.0, as_built=spec)
    assert conv.bow == (inl, shape) and conv.at([1, 2]).bow == conv.bow
    mu, ped = np.array([[0.07, 0.31, 0.5123, 0.93]]), np.full((1, 4), 0.02)
    white = (0.13 * LSB) ** 2
    x, _ = conv.input_codes(mu)
    on = []
    for shared_lsb in (0.05, 0.5, 1.0, 1.5, 8.0):
        sd, shot = np.full((1, 4), shared_lsb * LSB), np.full((1, 4), (shared_lsb * LSB) ** 2)
        ref_v, ref_cov = _trapezoid(conv, mu, sd, white, shot, ped, 0.5 * LSB)
        u = expected_adc._white_lsb(conv, white, conv.input_codes(mu)[1])
        on.append(expected_adc._on_series(conv, x, u, 10.0 * (shared_lsb + u)).all())
        got_v = expected_adc.mean_of_var(conv, mu, sd, white)
        got_cov = expected_adc._shared_ktc_cov(conv, mu, shot, ped, 0.5 * LSB, white)
        assert np.max(np.abs(got_v - ref_v)) < expected_adc.SMOOTH_INL_TOL, shared_lsb
        assert np.max(np.abs(got_cov - ref_cov)) < expected_adc.SMOOTH_INL_TOL, shared_lsb
    assert on[0] and not on[-1]  # 8 LSB: |φ''|·s² above the bound sends it to the quadrature


def test_bow_inverse_maps_the_bowed_transitions_onto_the_ideal_ones():
    """φ = T⁻¹ takes each bowed transition level back to k + ½ (to rounding), for both shapes and
    2 LSB of bow at 10 and 16 bits; φ' is the inverse slope (a centred difference, to its
    rounding)."""
    for bits in (10, 16):
        for shape in ("quadratic", "cubic"):
            conv = pixel.build_converter(
                np.random.default_rng(0), (1, 1), bits=bits, v_min_V=0.0, v_max_V=1.0,
                as_built=pixel.AsBuilt(inl_max_lsb=2.0, inl_shape=shape))
            levels = conv.levels[0]
            phi, d = pixel.ramp.bow_inverse(levels, 2.0, shape, bits)
            assert np.max(np.abs(phi - (np.arange(levels.size) + 0.5))) < 1e-9
            h = 1e-3
            num = (pixel.ramp.bow_inverse(levels + h, 2.0, shape, bits)[0]
                   - pixel.ramp.bow_inverse(levels - h, 2.0, shape, bits)[0]) / (2 * h)
            assert np.max(np.abs(d - num)) < 1e-7  # the difference's rounding: 2e-16·x/h
