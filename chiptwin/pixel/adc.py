"""The pixel output voltage and its per-pixel ADC: e⁻ → V → codes.

The ideal transfer function, with ``LSB = (v_max_V − v_min_V) / 2^bits`` (IEEE 1241 convention,
full scale over 2^N) and round to nearest::

    x    = (v − v_min_V) / LSB · (1 + gain_error) + offset_lsb      (continuous code)
    code = clip(rint(x), 0, 2^bits − 1)

Code ``k`` is centred on ``v_min_V + k·LSB``: its transition levels sit half an LSB either side,
so every interior code is exactly one LSB wide (``1/(1 + gain_error)`` LSB with a gain error) and
the quantisation error is zero-mean. Ties round half to even (``numpy.rint``), which is unbiased
too. Pyxel 3.0.2 truncates instead, a −0.5 LSB bias (measured here; docs/background/sources.md A2).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import bernoulli, ndtr

from chiptwin.pixel import _kernels
from chiptwin.pixel._checks import check_int, check_scalar

#: Widest ADC modelled. Unit: bit.
MAX_BITS: int = 24

#: Below this rms (in LSB) :func:`adc_expected` sums the Gaussian over each code exactly; above
#: it, away from the range ends, Sheppard's LSB²/12 rule is exact to exp(−2π²σ²) < 1e-30.
_EXACT_BELOW_LSB: float = 2.0

#: Half-width of the exact summation window. Unit: standard deviations.
_WINDOW_SIGMA: float = 10.0

#: Window cells per block of the exact summation (bounds its memory to ≈ 100 MB).
_CELLS: int = 1 << 21


def to_volts(
    electrons: ArrayLike, conversion_gain_uV_per_e: float, pedestal_V: float
) -> NDArray[np.float64]:
    """Pixel output voltage at the ADC input. Unit: V.

    Parameters
    ----------
    electrons : array_like
        Charge-equivalent level of a sample relative to the reset level. Unit: e⁻.
    conversion_gain_uV_per_e : float
        Conversion gain from charge to the ADC input (sense node ``q/C`` times the source
        follower and column gain). Unit: µV/e⁻.
    pedestal_V : float
        Output at zero charge: keeps the reset level's noise inside the ADC range. Unit: V.

    Returns
    -------
    ndarray
        ``pedestal_V + electrons · conversion_gain``. Unit: V.

    Notes
    -----
    Polarity (a choice): the voltage *rises* with collected charge. On the sense node it falls;
    the differential readout inverts it, so codes rise with light.
    """
    cg = check_scalar("conversion_gain_uV_per_e", conversion_gain_uV_per_e, 0.0, lo_open=True)
    ped = check_scalar("pedestal_V", pedestal_V)
    return ped + np.asarray(electrons, dtype=np.float64) * (cg * 1e-6)


def _check_adc(bits: int, v_min_V: float, v_max_V: float) -> tuple[int, float, float]:
    n = check_int("bits", bits, 1, MAX_BITS)
    lo = check_scalar("v_min_V", v_min_V)
    hi = check_scalar("v_max_V", v_max_V)
    if not hi > lo:
        raise ValueError(f"v_max_V = {v_max_V!r}: must be greater than v_min_V = {v_min_V!r}")
    return n, lo, hi


def lsb_V(bits: int, v_min_V: float, v_max_V: float) -> float:
    """Width of one code of the ideal ADC, ``(v_max_V − v_min_V) / 2^bits``. Unit: V."""
    n, lo, hi = _check_adc(bits, v_min_V, v_max_V)
    return (hi - lo) / 2.0**n


def _continuous_code(
    volts: NDArray[np.float64], v_min_V: float, lsb: float, offset_lsb: float, gain_error: float
) -> NDArray[np.float64]:
    # The same operations, in the same order, as chiptwin.pixel._kernels.adc_code.
    return (volts - v_min_V) / lsb * (1.0 + gain_error) + offset_lsb


def _check_errors(offset_lsb: float, gain_error: float) -> tuple[float, float]:
    off = check_scalar("offset_lsb", offset_lsb)
    gain = check_scalar("gain_error", gain_error, -1.0, lo_open=True)
    return off, gain


def adc_convert(
    volts: ArrayLike,
    bits: int,
    v_min_V: float,
    v_max_V: float,
    offset_lsb: float = 0.0,
    gain_error: float = 0.0,
) -> NDArray[np.int64]:
    """Convert voltages to ADC codes: round to nearest, clip at both ends. Unit: codes (LSB).

    Parameters
    ----------
    volts : array_like
        ADC input. Unit: V. ±inf clip to the end codes; NaN is an error.
    bits : int
        Resolution, 1 … 24 (JSSC 2006: 13).
    v_min_V, v_max_V : float
        Input range: code 0 is centred on ``v_min_V``; ``v_max_V`` is ``v_min_V + 2^bits·LSB``.
        Unit: V.
    offset_lsb : float
        Offset error added to the continuous code. Unit: LSB.
    gain_error : float
        Fractional gain error, > −1: the continuous code is scaled by ``1 + gain_error``.

    Returns
    -------
    ndarray of int64
        Codes in ``[0, 2^bits − 1]``, the shape of ``volts``.

    Raises
    ------
    ValueError
        On a bad parameter (naming it, its value and the allowed range) or NaN input.
    """
    n, lo, hi = _check_adc(bits, v_min_V, v_max_V)
    off, gain = _check_errors(offset_lsb, gain_error)
    v = np.asarray(volts, dtype=np.float64)
    if np.isnan(v).any():
        raise ValueError("volts contains NaN: must be real voltages (±inf clip)")
    x = np.rint(_continuous_code(v, lo, (hi - lo) / 2.0**n, off, gain))
    return np.clip(x, 0.0, 2.0**n - 1.0).astype(np.int64)


#: Near the range's ends, from this rms on (in LSB) the moments are :func:`_end_moments`' closed
#: form, below it exact sums (windows of at most 63 codes). The closed form's remainder: 1.0e-12
#: LSB² at 2 LSB, at rounding (< 1e-13) from 2.7 LSB (measured against the full sums;
#: tests/pixel/test_pixel_adc.py).
END_CLOSED_FROM_LSB: float = 3.0

#: Terms of the midpoint Euler–Maclaurin formula of :func:`_end_moments`.
_EM_TERMS: int = 8

#: ``c_m`` of ``Σ_{j=1}^{n} f(j) = ∫_{½}^{n+½} f + Σ_m c_m (f^{(2m−1)}(n+½) − f^{(2m−1)}(½))``:
#: ``c_m = −B_{2m}(½)/(2m)! = −(1 − 2^{1−2m}) B_{2m}/(2m)!`` (−1/24, 7/5760, …).
_EM_C: tuple[float, ...] = tuple(
    -(1.0 - 2.0 ** (1 - 2 * m)) * float(bernoulli(2 * m)[-1]) / math.factorial(2 * m)
    for m in range(1, _EM_TERMS + 1))


def _end_moments(
    mu: NDArray[np.float64], sd: NDArray[np.float64], top: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and variance of ``clip(rint(X), 0, top)``, ``X ~ N(mu, sd²)``, near the range's ends,
    in closed form (``sd`` ≥ :data:`END_CLOSED_FROM_LSB`; the window sums cost ∝ ``sd`` a value,
    a minute and more of a run with a wide comparator noise at the quadrature's nodes).

    About ``c = clip(rint(mu), 0, top)``: ``E[C − c] = Σ_{k>c} P(C ≥ k) − Σ_{k≤c} P(C < k)`` and
    ``E[(C − c)²] = Σ_{k>c} (2(k − c) − 1) P(C ≥ k) + Σ_{k≤c} (2(c − k) + 1) P(C < k)``, where
    ``P(C ≥ k) = Q((k − ½ − mu)/sd)`` for ``1 ≤ k ≤ top``, ``Q = 1 − Φ``: on each side of ``c``
    the sums ``Σ_{j=1}^{n} Q(t_j)`` and ``Σ_{j=1}^{n} (2j − 1) Q(t_j)``, ``t_j = (j − ½ − a)/sd``,
    small and well conditioned. Each by the midpoint Euler–Maclaurin formula
    (:data:`_EM_C`, :func:`chiptwin.pixel._kernels.end_moments`): with ``x = ½ + a + sd·t``,
    ``∫Q dt = tQ − φ`` and ``∫tQ dt = ((t² − 1)Q − tφ)/2`` give the integrals; ``f(x) = Q(t)``
    has ``f^{(k)} = −(−1)^{k−1} sd^{−k} He_{k−1}(t) φ(t)`` (probabilists' Hermite polynomials)
    and ``g = (2x − 1) f`` has ``g^{(k)} = (2x − 1) f^{(k)} + 2k f^{(k−1)}``."""
    mean, var = np.empty_like(mu), np.empty_like(mu)
    _kernels.end_moments(np.ascontiguousarray(mu), np.ascontiguousarray(sd), float(top), _EM_C,
                         mean, var)
    return mean, var


def _exact_moments(
    mu: NDArray[np.float64], sd: NDArray[np.float64], top: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Code moments by summing the Gaussian over every code within ±10σ, centred for precision."""
    centre = np.clip(np.rint(mu), 0.0, top)
    half = np.ceil(_WINDOW_SIGMA * sd) + 1.0
    lo, hi = np.clip(centre - half, 0.0, top), np.clip(centre + half, 0.0, top)
    k = lo[:, None] + np.arange(int((hi - lo).max()) + 1)[None, :]
    upper = np.where(k >= top, np.inf, k + 0.5)
    lower = np.where(k <= 0, -np.inf, k - 0.5)
    safe = np.where(sd > 0, sd, 1.0)[:, None]
    p = ndtr((upper - mu[:, None]) / safe) - ndtr((lower - mu[:, None]) / safe)
    p = np.where(k <= hi[:, None], p, 0.0)
    d = k - centre[:, None]
    m1, m2 = (p * d).sum(axis=1), (p * d * d).sum(axis=1)
    point = sd == 0
    mean = np.where(point, centre, centre + m1)
    return mean, np.where(point, 0.0, np.maximum(m2 - m1 * m1, 0.0))


def _moments(
    mu: NDArray[np.float64], sd: NDArray[np.float64], top: float, exact_sums=None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pick per element: Sheppard inside the range from 2 LSB rms, exact sums below it and near
    the ends below 3 LSB rms, near the ends from 3 LSB rms the Euler–Maclaurin closed form
    (:func:`_end_moments`).

    ``exact_sums(mu, sd) -> (mean, var)``, if given, makes the exact sums instead of
    :func:`_exact_moments` (the as-built converter's one numba pass over the ideal transitions).
    """
    mean, var = mu.copy(), sd * sd + 1.0 / 12.0  # Sheppard: exact to exp(-2π²σ²) inside
    reach = _WINDOW_SIGMA * sd
    near_end = (mu - reach < 0.5) | (mu + reach > top - 0.5)
    exact = (sd < _EXACT_BELOW_LSB) | (near_end & (sd < END_CLOSED_FROM_LSB))
    ends = near_end & ~exact
    mean[ends], var[ends] = _end_moments(mu[ends], sd[ends], top)
    idx = np.flatnonzero(exact)
    if exact_sums is not None:
        mean[idx], var[idx] = exact_sums(mu[idx], sd[idx])
        return mean, var
    width = np.zeros_like(mu)  # codes in each exact window (≤ 63: below 3 LSB rms)
    width[idx] = np.minimum(2.0 * np.ceil(reach[idx]) + 3.0, top + 1.0)
    idx = idx[np.argsort(width[idx], kind="stable")]
    start = 0
    while start < idx.size:  # blocks of similar width, ≤ _CELLS window cells each
        rows = max(1, _CELLS // int(width[idx[start]]))
        block = idx[start : start + rows]
        block = block[width[block] <= 2 * width[idx[start]]]
        mean[block], var[block] = _exact_moments(mu[block], sd[block], top)
        start += block.size
    return mean, var


def adc_expected(
    mean_V: ArrayLike,
    var_V: ArrayLike,
    bits: int,
    v_min_V: float,
    v_max_V: float,
    offset_lsb: float = 0.0,
    gain_error: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and variance of the code for a Gaussian input (the ``expected`` level). Unit: LSB, LSB².

    Parameters
    ----------
    mean_V, var_V : array_like
        Mean (V) and variance (V²) of the ADC input, broadcast together.
    bits, v_min_V, v_max_V, offset_lsb, gain_error
        As in :func:`adc_convert`.

    Returns
    -------
    mean_code, var_code : ndarray
        Moments of the code: well inside the range and for an input rms σ ≥ 2 LSB these are
        ``x̄`` and ``σ² + 1/12`` (Sheppard's correction: the LSB²/12 quantisation noise of
        Widrow & Kollár 2008; error ∝ exp(−2π²σ²) < 1e-30); otherwise exact for a Gaussian input.

    Notes
    -----
    Below 2 LSB rms the 1/12 rule fails (a noiseless input quantises deterministically; the
    reference chip's 100 e⁻ read noise is ≈ 0.13 LSB of its 13-bit, 1 V ADC), and near the range
    ends clipping matters: there the Gaussian is summed over every code within ±10σ below 3 LSB
    rms, and from 3 LSB the sums are in closed form (:func:`_end_moments`, Euler–Maclaurin; equal
    to the full sums within 1e-12 LSB² or 1e-12 relative, tested), whatever σ.

    For the CDS difference of M reset and M signal codes the quantisation noise of each conversion
    adds separately (2/(12M) LSB² when each sample's rms is ≥ 2 LSB); with true CDS the reset and
    signal samples share the kTC draw, so their codes are correlated, not independent.
    """
    n, lo, hi = _check_adc(bits, v_min_V, v_max_V)
    off, gain = _check_errors(offset_lsb, gain_error)
    mean_a, var_a = np.broadcast_arrays(np.asarray(mean_V, float), np.asarray(var_V, float))
    if not (np.isfinite(mean_a).all() and np.isfinite(var_a).all() and (var_a >= 0).all()):
        raise ValueError("mean_V and var_V must be finite and var_V ≥ 0")
    scale = (1.0 + gain) / ((hi - lo) / 2.0**n)
    mu = _continuous_code(mean_a.ravel(), lo, (hi - lo) / 2.0**n, off, gain)
    sd = np.sqrt(var_a.ravel()) * scale
    mean, var = _moments(mu, sd, 2.0**n - 1.0)
    return mean.reshape(mean_a.shape), var.reshape(mean_a.shape)


def quantization_var_of_mean(n_samples: int, noise_lsb: float) -> float:
    """Variance of the rounding error of the mean of ``n_samples`` codes of one level. Unit: LSB².

    The samples share the level and differ by white noise of ``noise_lsb`` rms, so their rounding
    errors are correlated: averaging M samples divides LSB²/12 by M only when the noise is
    ≳ 0.5 LSB. With the level uniform modulo one LSB, the sawtooth's Fourier series gives the
    covariance of two errors, ``c = Σ_k exp(−4π²k²σ²) / (2π²k²)`` (``c = 1/12`` at σ = 0), and

        var = 1/(12 M) + (1 − 1/M) · c.

    Parameters
    ----------
    n_samples : int
        M ≥ 1 samples averaged.
    noise_lsb : float
        Per-sample white noise (read noise), ≥ 0. Unit: LSB rms.
    """
    m = check_int("n_samples", n_samples, 1)
    sigma = check_scalar("noise_lsb", noise_lsb, lo=0.0)
    k = np.arange(1, 4001, dtype=np.float64)  # the tail beyond 4000 terms is < 1e-5 of 1/12
    cov = float(np.sum(np.exp(-4.0 * np.pi**2 * k**2 * sigma**2) / (2.0 * np.pi**2 * k**2)))
    return 1.0 / (12.0 * m) + (1.0 - 1.0 / m) * cov
