"""Unit tests of chiptwin.pixel.adc: transfer tables, no bias, clipping, code widths, the
``expected`` level against draws and against a brute-force sum, and argument checks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import ndtr

from chiptwin.pixel import adc_convert, adc_expected, lsb_V, to_volts

BITS, V0, V1 = 8, 0.0, 1.0
LSB = 1.0 / 256  # exact in binary: the tables below hit transitions exactly
TOP = 255


def _codes(x_lsb, **kw):
    """Convert inputs given in LSB above v_min with the 8-bit, 0–1 V ADC."""
    return adc_convert(V0 + np.asarray(x_lsb, float) * LSB, BITS, V0, V1, **kw)


def test_lsb():
    assert lsb_V(12, 0.0, 1.0) == 1.0 / 4096
    assert lsb_V(13, -0.5, 0.5) == pytest.approx(122.0703125e-6, rel=1e-15)


@pytest.mark.parametrize(
    ("x_lsb", "code"),
    [
        (0.0, 0),
        (0.49, 0),
        (0.5, 0),
        (0.51, 1),
        (1.0, 1),
        (1.5, 2),
        (2.5, 2),
        (3.5, 4),
        (100.25, 100),
        (100.75, 101),
        (254.49, 254),
        (254.5, 254),
        (254.51, 255),
        (255.0, 255),
        (256.0, 255),
        (1e9, 255),
        (-0.3, 0),
        (-1e9, 0),
    ],
)
def test_transfer_table_round_to_nearest_ties_to_even(x_lsb, code):
    """Code k is centred on v_min + k·LSB; exact ties (x.5) round half to even; ends clip."""
    assert _codes([x_lsb])[0] == code


def test_infinities_clip_and_nan_is_rejected():
    assert list(adc_convert([-np.inf, np.inf], 12, 0.0, 1.0)) == [0, 4095]
    with pytest.raises(ValueError, match="NaN"):
        adc_convert([0.1, np.nan], 12, 0.0, 1.0)


def test_output_is_int64_and_keeps_shape():
    codes = adc_convert(np.zeros((2, 3, 4)), 12, 0.0, 1.0)
    assert codes.dtype == np.int64 and codes.shape == (2, 3, 4)


@pytest.mark.parametrize(
    ("offset", "gain", "x_lsb", "code"),
    [
        (0.3, 0.0, 10.0, 10),
        (0.6, 0.0, 10.0, 11),
        (-2.0, 0.0, 10.0, 8),
        (-2.0, 0.0, 1.0, 0),
        (3.0, 0.0, 254.0, 255),
        (0.0, 0.1, 10.0, 11),
        (0.0, -0.1, 10.0, 9),
        (0.0, 0.02, 200.0, 204),
        (1.0, 0.02, 200.0, 205),
    ],
)
def test_offset_and_gain_error_table(offset, gain, x_lsb, code):
    """Continuous code x·(1 + gain_error) + offset_lsb, then rounded and clipped."""
    assert _codes([x_lsb], offset_lsb=offset, gain_error=gain)[0] == code


def test_no_bias_over_a_fine_ramp():
    """Mean quantisation error over a ramp of 1000 evenly spaced points per LSB across every
    interior code is 0 to 1e-9 LSB (each code's errors are symmetric); |error| ≤ 0.5 LSB. A
    truncating ADC (Pyxel 3.0.2; sources.md A2) would show −0.5 LSB."""
    k = 1000
    x = 0.5 + (np.arange(254 * k) + 0.5) / k  # codes 1 … 254, never clipped
    err = _codes(x) - x
    assert abs(err.mean()) < 1e-9
    assert np.abs(err).max() <= 0.5
    assert abs((np.floor(x) - x).mean() + 0.5) < 1e-9  # what truncation would give


def test_no_bias_on_random_inputs():
    """Uniform random inputs over the interior: mean error 0 within 5σ = 5/√(12n) LSB."""
    rng = np.random.default_rng(11)
    n = 1_000_000
    volts = rng.uniform(V0 + 0.5 * LSB, V0 + 254.5 * LSB, n)
    err = adc_convert(volts, BITS, V0, V1) - (volts - V0) / LSB
    assert abs(err.mean()) < 5 / np.sqrt(12 * n)
    assert abs(err.var() - 1 / 12) < 5 * np.sqrt(1 / 180 / n)  # uniform: Var(e²) = 1/180


@pytest.mark.parametrize("gain", [0.0, 0.02, -0.05])
def test_code_widths_equal_one_lsb(gain):
    """Histogram test (IEEE 1241) on a ramp of 1000 points per LSB: every interior code is
    1/(1 + gain_error) LSB wide to within one ramp step (DNL = 0 for the ideal ADC); the two end
    codes hold everything beyond the range."""
    k = 1000
    x = -3.0 + (np.arange(278 * k) + 0.5) / k  # −3 … 275 LSB: past both ends at ±5 %
    counts = np.bincount(_codes(x, gain_error=gain), minlength=256)
    widths = counts[1:-1] / k  # in LSB
    dnl = widths * (1.0 + gain) - 1.0
    assert np.abs(dnl).max() <= (1.0 + abs(gain)) / k + 1e-12
    assert counts[0] > 3 * k and counts[-1] > 3 * k


@settings(max_examples=60, deadline=None)
@given(
    bits=st.integers(1, 24),
    offset=st.floats(-5, 5),
    gain=st.floats(-0.5, 0.5),
    volts=st.lists(st.floats(-2, 3), min_size=2, max_size=50),
)
def test_codes_in_range_and_monotone(bits, offset, gain, volts):
    codes = adc_convert(np.sort(volts), bits, 0.0, 1.0, offset, gain)
    assert codes.min() >= 0 and codes.max() <= 2**bits - 1
    assert np.all(np.diff(codes) >= 0)


@pytest.mark.parametrize(
    ("kw", "name", "allowed"),
    [
        ({"bits": 0}, "bits", r"\[1, 24\]"),
        ({"bits": 25}, "bits", r"\[1, 24\]"),
        ({"bits": 12.0}, "bits", "integer"),
        ({"v_max_V": 0.0}, "v_max_V", "greater than v_min_V"),
        ({"v_min_V": float("nan")}, "v_min_V", "finite"),
        ({"gain_error": -1.0}, "gain_error", r"\(-1, inf\)"),
        ({"offset_lsb": float("inf")}, "offset_lsb", "finite"),
    ],
)
def test_bad_parameters_name_argument_value_and_range(kw, name, allowed):
    args = {"bits": 12, "v_min_V": 0.0, "v_max_V": 1.0} | kw
    for call in (
        lambda: adc_convert([0.1], **args),
        lambda: adc_expected([0.1], [0.0], **args),
    ):
        with pytest.raises(ValueError, match=name) as info:
            call()
        assert str(kw[name]) in str(info.value) or repr(kw[name]) in str(info.value)
        assert info.match(allowed)


def test_to_volts_table_and_checks():
    """Polarity: the voltage rises with charge; pedestal at zero charge."""
    assert np.allclose(to_volts([0.0, 1e4, -100.0], 16.0, 0.1), [0.1, 0.26, 0.0984], atol=1e-15)
    with pytest.raises(ValueError, match="conversion_gain_uV_per_e"):
        to_volts([1.0], 0.0, 0.1)
    with pytest.raises(ValueError, match="pedestal_V"):
        to_volts([1.0], 1.0, float("nan"))


# --- the expected level ---------------------------------------------------------------------------


def _code_probabilities(mu_lsb, sd_lsb, top):
    """P(code = k) for x ~ N(mu, sd²), each from the nearer tail (a difference of Φ values near
    1 rounds away the codes far above the input)."""
    k = np.arange(top + 1, dtype=float)
    z_up = (np.where(k == top, np.inf, k + 0.5) - mu_lsb) / sd_lsb
    z_lo = (np.where(k == 0, -np.inf, k - 0.5) - mu_lsb) / sd_lsb
    return k, np.where(z_lo > 0, ndtr(-z_lo) - ndtr(-z_up), ndtr(z_up) - ndtr(z_lo))


def _brute_force(mu_lsb, sd_lsb, bits):
    """Moments of clip(rint(x)) for x ~ N(mu, sd²), summing the Gaussian over every code."""
    k, p = _code_probabilities(mu_lsb, sd_lsb, 2**bits - 1)
    mean = (p * k).sum()
    return mean, (p * (k - mean) ** 2).sum()


@pytest.mark.parametrize(
    ("mu", "sd"),
    [
        (30.2, 0.05),
        (30.5, 0.13),
        (30.3, 0.6),
        (30.0, 1.99),
        (0.2, 0.4),
        (62.9, 0.3),
        (-3.0, 2.5),
        (60.0, 5.0),
        (31.0, 12.0),
        (10.0, 40.0),
        (80.0, 3.0),
    ],
)
def test_adc_expected_against_brute_force_sum(mu, sd):
    """Exact (or Sheppard, well inside the range at ≥ 2 LSB) against the full sum, to 1e-9."""
    mean, var = adc_expected(mu * LSB, (sd * LSB) ** 2, 6, 0.0, 64 * LSB)
    ref_mean, ref_var = _brute_force(mu, sd, 6)
    assert mean == pytest.approx(ref_mean, abs=1e-9)
    assert var == pytest.approx(ref_var, abs=1e-9)


@pytest.mark.parametrize("sd", [2.0, 2.7, 3.0, 5.0, 40.0, 300.0, 3000.0])
def test_moments_at_the_ends_in_closed_form_are_the_full_sums(sd):
    """Within 10σ of either end of a 13-bit range, and past the ends: the moments (exact sums
    below 3 LSB rms, the Euler–Maclaurin closed form from 3 LSB) against the full sum over every
    code (NumPy, no window, :func:`_code_probabilities`), to 1e-12 LSB² or 1e-12 relative."""
    bits, top = 13, 2.0**13 - 1
    reach = np.linspace(-3.0 * sd, 10.0 * sd, 40)
    mus = np.concatenate([reach, top - reach, [0.0, 0.5, top - 0.5, top, -40.0 * sd]])
    for mu in mus:
        k, p = _code_probabilities(mu, sd, top)
        c = np.clip(np.rint(mu), 0.0, top)
        m1, m2 = (p * (k - c)).sum(), (p * (k - c) ** 2).sum()
        mean, var = adc_expected(mu * LSB, (sd * LSB) ** 2, bits, 0.0, 2.0**bits * LSB)
        assert mean == pytest.approx(c + m1, rel=1e-14, abs=1e-12), mu
        assert var == pytest.approx(m2 - m1 * m1, rel=1e-12, abs=1e-12), mu


def test_moments_with_both_ends_in_reach():
    """A 6-bit range under 40 LSB rms: both ends clip one Gaussian (the full sum, 1e-12)."""
    for mu in (-20.0, 0.0, 31.5, 50.0, 90.0):
        mean, var = adc_expected(mu * LSB, (40.0 * LSB) ** 2, 6, 0.0, 64 * LSB)
        ref_mean, ref_var = _brute_force(mu, 40.0, 6)
        assert mean == pytest.approx(ref_mean, abs=1e-12)
        assert var == pytest.approx(ref_var, abs=1e-12)


def test_adc_expected_sheppard_inside_the_range():
    """Well inside the range with σ ≥ 2 LSB: mean x̄ and variance σ² + 1/12 LSB² (Widrow &
    Kollár 2008; sources.md D2–D3)."""
    mean, var = adc_expected(0.5, (3.0 * LSB) ** 2, BITS, V0, V1, offset_lsb=0.25)
    assert mean == pytest.approx(128.25, abs=1e-12)
    assert var == pytest.approx(9.0 + 1.0 / 12.0, abs=1e-12)


def test_adc_expected_noiseless_input_is_the_code():
    mean, var = adc_expected([0.1, 0.5 * LSB, 2.0], [0.0, 0.0, 0.0], BITS, V0, V1)
    assert list(mean) == [26.0, 0.0, 255.0] and list(var) == [0.0, 0.0, 0.0]


@pytest.mark.parametrize(("mu", "sd"), [(100.3, 0.2), (100.0, 1.0), (1.0, 2.0), (254.0, 4.0)])
def test_adc_expected_agrees_with_draws(mu, sd):
    """Mean and variance of 400 000 converted Gaussian draws within 5 standard errors."""
    n = 400_000
    v = np.random.default_rng(12).normal(mu * LSB, sd * LSB, n)
    codes = _codes(v / LSB, gain_error=0.01, offset_lsb=-0.2).astype(float)
    mean, var = adc_expected(mu * LSB, (sd * LSB) ** 2, BITS, V0, V1, -0.2, 0.01)
    d = codes - codes.mean()
    se_var = np.sqrt(((d**4).mean() - (d**2).mean() ** 2) / n)
    assert abs(codes.mean() - mean) < 5 * np.sqrt(var / n)
    assert abs(codes.var() - var) < 5 * se_var


def test_adc_expected_broadcasts_and_checks():
    mean, var = adc_expected(np.full((2, 3), 0.5), 0.0, BITS, V0, V1)
    assert mean.shape == var.shape == (2, 3)
    with pytest.raises(ValueError, match="var_V"):
        adc_expected([0.5], [-1e-9], BITS, V0, V1)
