"""IEEE Std 1241 transition noise of one converter, from repeated conversions of DC levels
swept across its transitions (the DC-sweep form of the standard's transition-noise test, §4.5?
in IEEE Std 1241-2000 as the author knows it; the formulas are written out below).

DC levels (V) × R conversions ──► fraction at or above code k per level ──► probit fit per
transition ──► σ_k ± its standard error ──► rms over the transitions ± its standard error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from chiptwin.pixel._checks import check_int, check_scalar
from chiptwin.pixel.adc import lsb_V

__all__ = ["TransitionNoise", "transition_noise"]

#: Widest converter analysed (as :data:`chiptwin.pixel.adc.MAX_BITS`). Unit: bit.
MAX_BITS: int = 24


@dataclass(frozen=True)
class TransitionNoise:
    """Transition noise of one converter: per fitted transition k (``transitions``), its 50 %
    level ``level_V`` and Gaussian sigma ``sigma_lsb`` ± ``sigma_sigma_lsb``; the rms over them
    ``transition_noise_lsb`` ± ``transition_noise_sigma_lsb``; ``unresolved``: transitions in the
    sweep whose sigma the level grid could not resolve (excluded). LSB: the ideal Q."""

    transitions: NDArray[np.int64]
    level_V: NDArray[np.float64]
    sigma_lsb: NDArray[np.float64]
    sigma_sigma_lsb: NDArray[np.float64]
    transition_noise_lsb: float
    transition_noise_sigma_lsb: float
    unresolved: NDArray[np.int64]


def _upper_fraction(codes: NDArray[np.int64], ks: NDArray[np.int64]) -> NDArray[np.float64]:
    """Fraction of each level's conversions (rows) with code ≥ k, shape (len(ks), levels)."""
    lo = int(codes.min())
    tab = np.zeros((codes.shape[0], int(codes.max()) - lo + 2))
    np.add.at(tab, (np.arange(codes.shape[0])[:, None], codes - lo), 1.0)
    ge = np.cumsum(tab[:, ::-1], axis=1)[:, ::-1]  # ge[:, c - lo] = #(code ≥ c)
    return (ge[:, ks - lo] / codes.shape[1]).T


def _probit_terms(a, b, xc, r: int):
    """Per row at ``Φ(a + b·xc)``: η, the CDF and density, the Fisher information's weight
    ``r·φ²/(Φ(1 − Φ))`` and its moments in xc, ``(s0, s1, s2, det)`` (the fit's and its
    covariance's, :func:`_rms_sigma`)."""
    eta = np.clip(a[:, None] + b[:, None] * xc, -8.0, 8.0)
    cdf = np.clip(ndtr(eta), 1e-15, 1 - 1e-15)
    pdf = np.exp(-0.5 * eta**2) / np.sqrt(2.0 * np.pi)
    w = r * pdf**2 / (cdf * (1.0 - cdf))
    s0, s1, s2 = w.sum(1), (w * xc).sum(1), (w * xc * xc).sum(1)
    return eta, cdf, pdf, w, (s0, s1, s2, s0 * s2 - s1**2)


def _probit_fit(x: NDArray[np.float64], y: NDArray[np.float64], r: int, iters: int = 60):
    """Binomial maximum likelihood of y ≈ Φ(a + b·x) per row (Fisher scoring), with the inverse
    Fisher information's var(b). Start from the moments of the step in y.

    Each row is fitted in x centred on its starting 50 % level μ₀ (then a = a_c − b·μ₀): at
    13 bits x is ≈ 4096, and centring keeps det = s0·s2 − s1² from cancelling; det and var(b)
    are unchanged by the shift. Stops when every row's step is below 1e-12 (a noiseless step
    never converges: all iterations)."""
    dy = np.diff(y, axis=1)
    xm = 0.5 * (x[1:] + x[:-1])
    w0 = np.clip(dy, 0.0, None) / np.maximum(np.clip(dy, 0.0, None).sum(1, keepdims=True), 1e-300)
    mu = (w0 * xm).sum(1)
    sd = np.sqrt(np.maximum((w0 * (xm - mu[:, None]) ** 2).sum(1), np.diff(x).min() ** 2))
    xc = x[None, :] - mu[:, None]
    a, b = np.zeros(mu.size), 1.0 / sd
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(iters):
            eta, cdf, pdf, w, (s0, s1, s2, det) = _probit_terms(a, b, xc, r)
            z = eta + (y - cdf) / np.maximum(pdf, 1e-300)
            t0, t1 = (w * z).sum(1), (w * xc * z).sum(1)
            a_new, b_new = (s2 * t0 - s1 * t1) / det, (s0 * t1 - s1 * t0) / det
            step = np.maximum(np.abs(a_new - a), np.abs(b_new - b) / np.abs(b_new))
            a, b = a_new, b_new
            if np.all(step <= 1e-12):
                break
        return a - b * mu, b, s0 / det


def transition_noise(levels_V: ArrayLike, codes: ArrayLike, bits: int, v_min_V: float,
                     v_max_V: float) -> TransitionNoise:
    """Transition noise from repeated conversions of DC levels swept across transitions.

    IEEE 1241 §4.5? (transition noise): at an input near T[k] the output is k or above with a
    probability that rises from 0 to 1; with Gaussian input-referred noise it is Φ((v − T[k])/σ_k).

    Parameters
    ----------
    levels_V : array_like, shape (L,)
        The DC inputs, ascending (:func:`dc_sweep_V`). Unit: V.
    codes : array_like of int, shape (L, R)
        R conversions at each level.
    bits, v_min_V, v_max_V
        The ideal converter, for the LSB Q.

    Returns
    -------
    TransitionNoise

    Notes
    -----
    For each transition k crossed by the sweep: the fraction y_j of the R conversions at level
    v_j with code ≥ k is fitted by binomial maximum likelihood (probit regression, Fisher
    scoring) with Φ(a + b·x), x = (v − v_min)/Q, so σ_k = 1/b (LSB), T[k] = v_min − a/b·Q, and
    σ(σ_k) = √var(b) / b² from the inverse Fisher information. A transition is kept if the level
    grid covers T[k] ± 4σ_k with no gap wider than σ_k (else listed as unresolved: its sigma is
    below the grid's resolution or the sweep ends too near it). The rms over the K kept
    transitions is √(mean σ_k²); its σ counts that neighbouring transitions are fitted from the
    same conversions (a conversion with code ≥ l ≥ k counts for both): to first order the fits'
    scores are linear in the fractions, whose covariance at a level is (min(p_k, p_l) − p_k·p_l)/R,
    so Cov(b_k, b_l) = R Σ_j h_jk h_jl (min(p_jk, p_jl) − p_jk p_jl) with h_jk the fit's
    influence (:func:`_rms_sigma`); its diagonal is each σ(σ_k) above. Treating the σ_k as
    independent understated the rms's σ by 8 % at 0.5 LSB of noise and 32 % at 1.5 LSB (Monte
    Carlo, 10 bits, 200 conversions a level).
    """
    n = check_int("bits", bits, 2, MAX_BITS)
    lo, q = check_scalar("v_min_V", v_min_V), lsb_V(bits, v_min_V, v_max_V)
    v = np.asarray(levels_V, dtype=np.float64)
    c = np.asarray(codes)
    if v.ndim != 1 or c.ndim != 2 or c.shape[0] != v.size or v.size < 4:
        raise ValueError(f"levels_V (L,) and codes (L, R) must match, got {v.shape}, {c.shape}")
    if not np.issubdtype(c.dtype, np.integer) or np.any(np.diff(v) <= 0):
        raise ValueError("codes: must be integers; levels_V: strictly ascending")
    x = (v - lo) / q
    ks = np.arange(max(int(c.min()) + 1, 1), min(int(c.max()), 2**n - 1) + 1)
    y = _upper_fraction(c.astype(np.int64), ks)
    a, b, var_b = _probit_fit(x, y, c.shape[1])
    sig, mu = 1.0 / b, -a / b
    ok = _covered(x, mu, sig) & np.isfinite(sig) & (sig > 0)
    s_k, e_k = sig[ok], np.sqrt(var_b[ok]) / b[ok] ** 2
    rms = float(np.sqrt(np.mean(s_k**2))) if s_k.size else np.nan
    err = _rms_sigma(x, a[ok], b[ok], c.shape[1], rms) if s_k.size else np.nan
    return TransitionNoise(ks[ok], lo + mu[ok] * q, s_k, e_k, rms, err, ks[~ok])


def _rms_sigma(x: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64], r: int,
               rms: float) -> float:
    """σ of ``rms = √(mean σ_k²)``, σ_k = 1/b_k, the fits' covariance included (see
    :func:`transition_noise`). Each fit in x centred on its own transition (a + b·μ = 0)."""
    mu = -a / b
    xc = x[None, :] - mu[:, None]
    _, p, pdf, _, (s0, s1, _, det) = _probit_terms(np.zeros(b.size), b, xc, r)
    c = pdf / (p * (1.0 - p))  # the score's weight on (y − p)
    h = c * ((-s1 / det)[:, None] + (s0 / det)[:, None] * xc)  # e₂ᵀ I⁻¹ (1, x) · weight
    cov_b = np.empty((b.size, b.size))
    for k in range(b.size):
        both = np.minimum(p[k], p) - p[k] * p
        cov_b[k] = r * np.sum(h[k] * h * both, axis=1)
    u = (1.0 / b) / (b.size * rms) * (-1.0 / b**2)  # d rms / d b_k = σ_k/(K rms) · dσ_k/db_k
    return float(np.sqrt(max(u @ cov_b @ u, 0.0)))


def _covered(x: NDArray[np.float64], mu: NDArray[np.float64], sig: NDArray[np.float64]
             ) -> NDArray[np.bool_]:
    ok = np.zeros(mu.size, dtype=bool)
    for i, (m, s) in enumerate(zip(mu, sig, strict=True)):
        if not (np.isfinite(m) and np.isfinite(s) and s > 0):
            continue
        d = x - m  # offsets: m ± 4s can round to m itself at 13 bits (x ≈ 4096, s ≈ 1e-13)
        inside = d[(d > -4 * s) & (d < 4 * s)]
        pts = np.concatenate([[-4 * s], inside, [4 * s]])
        ok[i] = d[0] <= -4 * s and d[-1] >= 4 * s and np.diff(pts).max() <= s
    return ok
