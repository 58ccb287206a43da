"""The ``expected`` level through the converter as built: moments of one CMS output in codes.

One frame of one pixel reads M reset and M signal samples (:mod:`chiptwin.pixel`); the DSP forms
``D = S̄ − R̄``, the mean of the M signal codes minus the mean of the M reset codes. Each sample's
ADC input is a component the M samples of its side share, plus white noise of its own::

    reset  r_m = P + k_r·cg + w_m                     (k_r: kTC)
    signal s_m = P + (c + k_s)·cg + w'_m              (c: collected charge, k_s: kTC)

``w`` is the read noise (``read_noise_e·cg``), Gaussian, independent per sample; the comparator
noise adds to it inside the converter (:meth:`~chiptwin.pixel.converter.Converter.expected`).
The shared components are Gaussian at this level: ``k ~ N(0, ktc²)`` and ``c`` with the clipped
Poisson count's mean and variance (its shape at the e⁻ scale is invisible under ≥ 0.1 LSB of read
noise). With true CDS ``k_r = k_s``; otherwise they are independent.

Per side, with ``f(y)`` and ``v(y)`` the mean and variance of one code given the shared part
``y`` (the converter's transition table summed against the white noise's Gaussian), the law of
total variance gives::

    E[mean of M codes]   = E_y[f(y)]                  (exact: one Gaussian of the summed variance)
    Var[mean of M codes] = Var_y(f(y)) + E_y[v(y)]/M
                         = v_tot/M + (1 − 1/M)·Var_y(f(y)),   v_tot = Var_y(f) + E_y[v]

so the mean and ``v_tot`` are one exact Gaussian sum each and only ``E_y[v(y)]`` needs a
quadrature: Gauss–Hermite over ``y``, :data:`GH_NODES` nodes by the ratio of the shared rms to the
white rms. (``v`` rather than ``Var_y(f)``: ``f`` carries the input's trend, which multiplies
the quadrature's error by the spread; ``v`` stays ≈ white² + 1/12.) With true CDS the two sides
share ``k``: ``Cov(S̄, R̄) = Cov_k(g(k), f_r(k))`` with ``g(k) = E_c[f_s]`` (exact: one Gaussian),
on the same kind of nodes. ``Var D = Var S̄ + Var R̄ − 2 Cov(S̄, R̄)``.

Accuracy (``tests/pixel/test_expected_adc.py``): ``E_y[v]`` against a 16001-point trapezoid over
±8σ, comparator noise 0 … 0.5 LSB with INL, DNL and mismatch, shared rms σ_y 0.1 … 20 LSB, is
within ``GH_REL_TOL·σ_y² + GH_ABS_TOL_LSB2`` (measured worst 0.03 LSB² at σ_y = 5 LSB with no
comparator noise; below 1e-3 LSB² wherever σ_y ≤ 4× the white rms, to 1e-8 at ≤ 2×). The CMS
moments agree with a Monte Carlo of the binned kernel within its standard errors (same test).
Cost: ≈ 35 µs a pixel-frame (≈ 150 table sums of ≈ 20 codes), ~70× the linear ideal model.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.pixel.converter import Converter

#: Gauss–Hermite nodes of the quadrature over a side's shared component, by the ratio of its rms
#: to the white noise's (read + comparator): the staircase the quadrature integrates is smooth on
#: the scale of the white noise, so a wider shared spread needs denser nodes.
GH_NODES: tuple[tuple[float, int], ...] = ((2.0, 48), (4.0, 96), (math.inf, 192))

#: Bound on the quadrature's error in ``E_y[v(y)]`` (hence in a side's variance), relative to the
#: shared variance σ_y², plus :data:`GH_ABS_TOL_LSB2` (see the module's Accuracy).
GH_REL_TOL: float = 5e-3
GH_ABS_TOL_LSB2: float = 1e-3


def _gh(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Probabilists' Gauss–Hermite nodes and weights normalised to sum to 1 (E over N(0, 1))."""
    z, w = np.polynomial.hermite_e.hermegauss(n)
    return z, w / w.sum()


def node_count(shared_sd: ArrayLike, white_sd: ArrayLike) -> int:
    """Nodes for a call: :data:`GH_NODES` at the largest ratio of shared to white rms."""
    ratio = float(np.max(np.asarray(shared_sd) / np.maximum(white_sd, 1e-300), initial=0.0))
    return next(n for top, n in GH_NODES if ratio <= top)


def _white_sd_lsb(conv: Converter, white_var_V: float) -> float:
    """Smallest white rms of a sample at any converter (read noise at the smallest gain, plus
    comparator noise). Unit: LSB."""
    gains = conv.pixel_gain if conv.pixel_gain is not None else np.ones(1)
    read = math.sqrt(white_var_V) / conv.lsb_V * (1.0 + conv.gain_error) * float(gains.min())
    return math.hypot(read, conv.comparator_noise_lsb)


def _nodes_for(conv: Converter, shared_sd_V: ArrayLike, white_var_V: float) -> tuple:
    sd_lsb = np.asarray(shared_sd_V) / conv.lsb_V * (1.0 + conv.gain_error)
    if conv.pixel_gain is not None:
        sd_lsb = sd_lsb * float(conv.pixel_gain.max())
    return _gh(node_count(sd_lsb, _white_sd_lsb(conv, white_var_V)))


def mean_of_var(conv: Converter, mean_V: NDArray[np.float64], shared_sd_V: NDArray[np.float64],
                white_var_V: float) -> NDArray[np.float64]:
    """``E_y[v(y)]`` for ``y ~ N(mean_V, shared_sd_V²)``: the mean variance of one code given the
    shared part, ``v(y)`` the code's variance at input ``y`` plus white noise of variance
    ``white_var_V``. Arrays broadcast to ``(..., *conv.shape)``. Unit: LSB²."""
    z, w = _nodes_for(conv, shared_sd_V, white_var_V)
    zz = z.reshape((-1,) + (1,) * np.ndim(mean_V))
    _, v = conv.expected(mean_V + shared_sd_V * zz, white_var_V)
    return np.tensordot(w, v, axes=1)


def cms_moments(conv: Converter, mean_e: ArrayLike, shot_var_e2: ArrayLike, *, ktc_e: float,
                read_noise_e: float, cg_V: float, pedestal_V: float, n_samples: int,
                true_cds: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and variance of ``S̄ − R̄`` in codes for each pixel and frame. Unit: LSB, LSB².

    Parameters
    ----------
    conv : Converter
        The chip's converters, built with the pixel shape (not ideal).
    mean_e, shot_var_e2 : array_like (..., n_pixels)
        Mean and variance of the collected charge (clipped Poisson). Unit: e⁻, e⁻².
    ktc_e, read_noise_e : float
        Reset noise and per-sample read noise, rms. Unit: e⁻.
    cg_V : float
        Conversion gain. Unit: V/e⁻.
    pedestal_V : float
        ADC input of zero charge. Unit: V.
    n_samples : int
        M samples per side.
    true_cds : bool
        The reset and signal samples share the kTC draw.
    """
    if conv.ideal or conv.shape is None:
        raise ValueError("cms_moments needs a converter as built, with its pixel shape")
    shape = conv.shape
    mean_a = np.asarray(mean_e, float)
    lead = mean_a.shape[:-1]
    mean_a = mean_a.reshape(lead + shape)
    shot_a = np.asarray(shot_var_e2, float).reshape(lead + shape)
    keep = 1.0 - 1.0 / int(n_samples)
    white = (read_noise_e * cg_V) ** 2
    k_sd = ktc_e * cg_V
    ped = np.full(shape, float(pedestal_V))
    # each side: Var(mean of M) = v_tot − (1 − 1/M)·E_y[v(y)]; the reset side is every frame's
    r_mean, r_tot = conv.expected(ped, k_sd * k_sd + white)
    var_r = r_tot - keep * mean_of_var(conv, ped, np.full(shape, k_sd), white)
    s_mu = pedestal_V + mean_a * cg_V
    s_shared = shot_a * cg_V * cg_V + k_sd * k_sd
    s_mean, s_tot = conv.expected(s_mu, s_shared + white)
    var = s_tot - keep * mean_of_var(conv, s_mu, np.sqrt(s_shared), white) + var_r
    if true_cds and k_sd > 0.0:
        var = var - 2.0 * _shared_ktc_cov(conv, s_mu, shot_a * cg_V * cg_V, ped, k_sd, white)
    n_pix = int(math.prod(shape))
    return ((s_mean - r_mean).reshape(lead + (n_pix,)),
            np.maximum(var, 0.0).reshape(lead + (n_pix,)))


def _shared_ktc_cov(conv: Converter, s_mu: NDArray[np.float64], shot_V2: NDArray[np.float64],
                    ped: NDArray[np.float64], k_sd: float, white: float) -> NDArray[np.float64]:
    """``Cov(S̄, R̄) = Cov_k(g(k), f_r(k))`` over the kTC draw both sides share: ``g(k)`` the
    signal code's mean given ``k`` (charge and white noise summed exactly), ``f_r(k)`` the reset
    code's. Unit: LSB²."""
    z, w = _nodes_for(conv, np.full(ped.shape, k_sd), white)
    zz = z.reshape((-1,) + (1,) * s_mu.ndim)
    g, _ = conv.expected(s_mu + k_sd * zz, shot_V2 + white)
    f_r, _ = conv.expected(ped + k_sd * z.reshape((-1,) + (1,) * ped.ndim), white)
    g = g - np.tensordot(w, g, axes=1)
    f_r = f_r - np.tensordot(w, f_r, axes=1)
    f_r = f_r.reshape((z.size,) + (1,) * (s_mu.ndim - ped.ndim) + ped.shape)
    return np.tensordot(w, g * f_r, axes=1)


__all__ = ["GH_ABS_TOL_LSB2", "GH_NODES", "GH_REL_TOL", "cms_moments", "mean_of_var", "node_count"]
