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

so the mean and ``v_tot`` are one exact Gaussian sum each and only ``E_y[v(y)]`` needs more.
(``v`` rather than ``Var_y(f)``: ``f`` carries the input's trend, which multiplies a
quadrature's error by the spread; ``v`` stays ≈ white² + 1/12.) With true CDS the two sides
share ``k``: ``Cov(S̄, R̄) = Cov_k(g(k), f_r(k))`` with ``g(k) = E_c[f_s]`` (exact: one Gaussian).
``Var D = Var S̄ + Var R̄ − 2 Cov(S̄, R̄)``.

Two ways to the two expectations over a Gaussian ``y``:

* **The sawtooth's series** (the ideal transitions ``k + ½``, with mismatch and comparator
  noise, inside the range): there the code is ``round(x)``, ``x − round(x)`` is the sawtooth
  ``Σ (−1)^{k+1} sin(2πkx)/(πk)``, and white noise of rms ``u`` damps its ``k``-th harmonic by
  ``e^{−2π²u²k²}``; ``v``, ``f`` and their products are then short trigonometric series whose
  Gaussian expectations are closed forms (:func:`_series_mean_of_var`, :func:`_series_ktc_cov`).
  ``⌈1.5/u⌉`` harmonics (2 at ``u`` ≥ 1 LSB, 12 at the reference chip's 0.13 LSB of read
  noise) leave out terms below 1e-19.
* **A quadrature** over ``y`` elsewhere (a transition table: INL, DNL or a measured one; the
  range's ends; white noise below :data:`SERIES_MIN_WHITE_LSB`): the trapezoid rule on a uniform
  grid whose step follows the white noise (:data:`QUAD_PER_WHITE` nodes per white rms, so the
  nodes grow with the ratio of the shared rms to the white rms), on the converter's exact table
  sums.

Accuracy (``tests/pixel/test_expected_adc.py``), against a trapezoid of 16001 points over ±8σ
of the exact table sums: the series within 1e-12 LSB² (measured ≤ 2e-13, comparator noise
0 … 1 LSB, read noise 0.13 … 1 LSB, shared rms 0.05 … 20 LSB, mismatch on), the quadrature within
:data:`QUAD_TOL_LSB2` (measured ≤ 4e-9 LSB², white rms 0.01 … 1 LSB, shared rms 0.5 … 100× it)
up to :data:`QUAD_MAX_RATIO`; beyond, the nodes thin out (within 2e-3 LSB² at 300×, against a
shared variance of 9·10⁴ u²). Until this round the quadrature was Gauss–Hermite with
at most 192 nodes: E_y[v] was 50–100 % off at 20× (a true-CDS dark pixel's variance 0.0142
against 0.0313 LSB² by Monte Carlo), where its stated bound had grown with σ_y². The CMS moments
agree with a Monte Carlo of the binned kernel within its standard errors (same test).
Cost: ≈ 2 × 2·⌈6.5 × 1.25 × σ/u⌉ table sums a pixel-frame, each element with the nodes of its
own spread (:func:`_by_series`; the reset side's kTC nodes once per pixel,
:func:`_centred_reset`), each sum ≈ 0.2 µs at 0.13 LSB of white noise: ``chiptwin run
pyro_1fmol`` with 0.2 LSB of DNL (79–131 nodes against Gauss–Hermite's 192) ran 8.2 s against
20.6 s with Gauss–Hermite in the same sitting, its results within 5e-7 (4 s ideal; 32 s and
1.75 GB before the quadrature ran in slices of :data:`QUAD_SLICE_VALUES` and the window's bounds
came from the search LUT). The series ≈ 1.5 µs a pixel-frame (pyro_1fmol with a 1-LSB
comparator, expected level: 0.46 s against 19.4 s, one run each).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.pixel.converter import Converter
from chiptwin.pixel.ramp import bow_curvature, bow_inverse

#: The quadrature over a side's shared component ``y ~ N(μ, σ²)``: the trapezoid rule on a
#: uniform grid of ``z = (y − μ)/σ`` over ±:data:`QUAD_Z`. The integrands (a code's variance or
#: mean given ``y``) are the converter's staircase smoothed by the white noise ``u``, whose
#: harmonics fall as ``exp(−π²u²ν²)`` (ν in cycles per LSB): a step of ``u/QUAD_PER_WHITE`` aliases
#: them at ``exp(−π²·QUAD_PER_WHITE²) ≈ 2e-10`` of their size, and a step of at most
#: :data:`QUAD_MAX_STEP` σ integrates the Gaussian weight itself to ``exp(−2π²/QUAD_MAX_STEP²)``.
#: Nodes grow linearly with ``σ/u``; Gauss–Hermite's spacing shrinks only as ``1/√n`` (192 nodes
#: left E_y[v] 50–100 % off at σ/u ≈ 20, where a true-CDS dark pixel's variance is that term).
QUAD_Z: float = 6.5
QUAD_PER_WHITE: float = 1.25
QUAD_MAX_STEP: float = 0.5
#: At most this many nodes: up to :data:`QUAD_MAX_RATIO` at the full density; wider spreads are
#: sampled more coarsely (their error ≈ 1e-3 LSB², against a shared variance of ≥ 10⁴ u²).
QUAD_MAX_NODES: int = 2049
#: The widest shared rms, in white rms, the quadrature integrates at its full density.
QUAD_MAX_RATIO: float = (QUAD_MAX_NODES - 1) / (2.0 * QUAD_Z * QUAD_PER_WHITE)
#: Bound on the quadrature's error in ``E_y[v(y)]`` (and the kTC covariance) up to
#: :data:`QUAD_MAX_RATIO`. Unit: LSB².
QUAD_TOL_LSB2: float = 1e-8

#: Values (nodes × elements) of one slice of a quadrature: its temporaries, a dozen arrays of
#: that many, stay ≈ 100 MB whatever the block of frames. Unsliced, a block of 1,024 frames of
#: the reference chip's 128 pixels at 192 nodes made 25 M values an array: a 1.75 GB peak for
#: a run its memory estimate put at 443 MiB (pyro_1fmol with 0.2 LSB of DNL).
QUAD_SLICE_VALUES: int = 1 << 20


def _quadrature_nodes(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``n`` (odd) uniform nodes over ±:data:`QUAD_Z` and their trapezoid weights, each the
    standard normal density times the step, normalised to sum to 1 (E over N(0, 1))."""
    z = np.linspace(-QUAD_Z, QUAD_Z, n)
    w = np.exp(-0.5 * z * z)
    return z, w / w.sum()


def node_count(shared_sd: ArrayLike, white_sd: ArrayLike) -> int:
    """Nodes for the largest ratio of shared to white rms: :data:`QUAD_PER_WHITE` per white rms
    (a step of at most :data:`QUAD_MAX_STEP` σ), at most :data:`QUAD_MAX_NODES`."""
    ratio = np.max(np.asarray(shared_sd) / np.maximum(white_sd, 1e-300), initial=0.0)
    return int(_node_counts(np.asarray(ratio)))


def _node_counts(ratio: NDArray[np.float64]) -> NDArray[np.int64]:
    """:func:`node_count` of each ratio, the ratio first rounded up to a power of 2^¼ (a call's
    elements share a few node sets: at most 1.19× the nodes each needs)."""
    top = 2.0 ** (np.ceil(4.0 * np.log2(np.maximum(ratio, 1e-300))) / 4.0)
    step = np.minimum(1.0 / (QUAD_PER_WHITE * top), QUAD_MAX_STEP)
    return np.minimum(2 * np.ceil(QUAD_Z / step).astype(np.int64) + 1, QUAD_MAX_NODES)


def _ratios(conv: Converter, shared_sd_V: ArrayLike, white_var_V: ArrayLike
            ) -> NDArray[np.float64]:
    """Each element's shared rms over its white rms (read noise and the comparator's), both in
    its converter's LSB (``conv`` the elements' converters, a row)."""
    slope = conv.input_codes(conv.v_min_V)[1]  # LSB per volt, per converter
    return np.asarray(shared_sd_V) * slope / _white_lsb(conv, white_var_V, slope)


def mean_of_var(conv: Converter, mean_V: NDArray[np.float64], shared_sd_V: NDArray[np.float64],
                white_var_V: float) -> NDArray[np.float64]:
    """``E_y[v(y)]`` for ``y ~ N(mean_V, shared_sd_V²)``: the mean variance of one code given the
    shared part, ``v(y)`` the code's variance at input ``y`` plus white noise of variance
    ``white_var_V``. Arrays broadcast to ``(..., *conv.shape)``. Unit: LSB².

    On the ideal transitions inside the range, the sawtooth's series (:func:`_series_mean_of_var`);
    elsewhere (a transition table, the range's ends, white noise below :data:`SERIES_MIN_WHITE_LSB`)
    the quadrature."""
    x, slope = conv.input_codes(mean_V)
    mean_V, shared_sd_V = (np.broadcast_to(np.asarray(a, float), x.shape)
                           for a in (mean_V, shared_sd_V))
    sigma, u = shared_sd_V * slope, _white_lsb(conv, white_var_V, slope)
    series = _on_series(conv, x, u, 10.0 * (sigma + u))
    mean_f, sd_f = (np.ascontiguousarray(a).reshape(-1) for a in (mean_V, shared_sd_V))

    def by_series():
        xs, d = _unbowed(conv, x[series])
        return _series_mean_of_var(xs, d * sigma[series], d * u[series])

    return _by_series(conv, series, by_series,
                      lambda sub, rest: _ratios(sub, sd_f[rest], white_var_V),
                      lambda sub, idx, nodes: _quad_mean_of_var(sub, mean_f[idx], sd_f[idx],
                                                                white_var_V, nodes))


def _quad_mean_of_var(conv: Converter, mean_V: NDArray[np.float64],
                      shared_sd_V: NDArray[np.float64], white_var_V: float,
                      nodes: tuple) -> NDArray[np.float64]:
    """:func:`mean_of_var` by the quadrature over ``y`` at ``nodes`` (z, w)."""
    z, w = nodes
    zz = z.reshape((-1,) + (1,) * np.ndim(mean_V))
    _, v = conv.expected(mean_V + shared_sd_V * zz, white_var_V)
    return _node_sum(w, v)


def _node_sum(w: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Σ_n w[n]·v[n]`` over the first axis, node after node: an element's sum has the same bits
    whatever else the array holds (BLAS's dot, ``np.tensordot``, orders its sums by the array's
    length, so a sliced quadrature would differ from a whole one in the last bits)."""
    out = w[0] * v[0]
    for n in range(1, w.size):
        out += w[n] * v[n]
    return out


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
    code's. Unit: LSB². The sawtooth's series where :func:`mean_of_var` takes it (both sides
    inside the range), the quadrature elsewhere. ``ped`` (the reset level) has the converters'
    shape: the same in every frame."""
    a, slope = conv.input_codes(s_mu)
    b = np.broadcast_to(conv.input_codes(ped)[0], a.shape)
    kappa = k_sd * slope
    u_s, u_r = _white_lsb(conv, shot_V2 + white, slope), _white_lsb(conv, white, slope)
    series = (_on_series(conv, a, u_r, 10.0 * (kappa + u_s))
              & _on_series(conv, b, u_r, 10.0 * (kappa + u_r)))
    s_f, shot_f = (np.ascontiguousarray(np.broadcast_to(v, a.shape)).reshape(-1)
                   for v in (s_mu, shot_V2))
    reset: dict[int, NDArray[np.float64]] = {}  # f_r − E f_r per pixel, per node set, made once

    def quadrature(sub: Converter, idx: NDArray[np.int64], nodes: tuple) -> NDArray[np.float64]:
        n = nodes[0].size
        if n not in reset:
            reset[n] = _centred_reset(conv, ped, k_sd, white, nodes)
        return _quad_ktc_cov(sub, s_f[idx], shot_f[idx], reset[n][:, idx % conv.n_pixels], k_sd,
                             white, nodes)

    def by_series():
        (a_s, alpha), (b_s, beta) = _unbowed(conv, a[series]), _unbowed(conv, b[series])
        return _series_ktc_cov(a_s, b_s, kappa[series], alpha * u_s[series],
                               beta * u_r[series], alpha, beta)

    return _by_series(conv, series, by_series,
                      lambda sub, rest: _ratios(sub, np.full(rest.size, k_sd), white),
                      quadrature)


def _centred_reset(conv: Converter, ped: NDArray[np.float64], k_sd: float, white: float,
                   nodes: tuple) -> NDArray[np.float64]:
    """``f_r(k) − E_k f_r`` at the nodes, per pixel (``(nodes, n_pixels)``): the reset side's
    code mean given the kTC draw is the same in every frame, so it is summed once per pixel,
    not once per pixel-frame (half the table sums of :func:`_quad_ktc_cov`)."""
    z, w = nodes
    f_r, _ = conv.expected(ped + k_sd * z.reshape((-1,) + (1,) * ped.ndim), white)
    f_r = f_r.reshape(z.size, conv.n_pixels)
    return f_r - _node_sum(w, f_r)


def _quad_ktc_cov(conv: Converter, s_mu: NDArray[np.float64], shot_V2: NDArray[np.float64],
                  f_r: NDArray[np.float64], k_sd: float, white: float, nodes: tuple
                  ) -> NDArray[np.float64]:
    """:func:`_shared_ktc_cov` by the quadrature over ``k`` on a row of elements (``conv`` their
    converters): ``f_r`` the reset side's centred code mean at the nodes
    (:func:`_centred_reset`, one column per element)."""
    z, w = nodes
    g, _ = conv.expected(s_mu + k_sd * z[:, None], shot_V2 + white)
    return _node_sum(w, (g - _node_sum(w, g)) * f_r)


# --- the sawtooth's series ---------------------------------------------------------------------

#: The series is used where every converter's white noise (read + comparator, per sample) is at
#: least this rms: its harmonics then number ``⌈1.5 / u⌉`` ≤ 96. Unit: LSB.
SERIES_MIN_WHITE_LSB: float = 1.0 / 64


def _white_lsb(conv: Converter, var_V: ArrayLike, slope: NDArray[np.float64]
               ) -> NDArray[np.float64]:
    """Per element: the rms of a Gaussian input of variance ``var_V`` at the converter's code,
    with the comparator noise added. Unit: LSB."""
    return np.sqrt(np.asarray(var_V) * slope * slope + conv.comparator_noise_lsb ** 2)


#: With a smooth INL bow (:attr:`~chiptwin.pixel.converter.Converter.bow`) the series runs on the
#: bow's inverse ``φ`` made affine at each element (:func:`_unbowed`); the curvature it leaves
#: out moves an element's figures by about ``½|φ''|·s²`` (``s`` its rms, shared plus white).
#: Elements with ``|φ''|·s²`` above this take the quadrature. Measured against the exact table
#: sums (``tests/pixel/test_expected_adc.py``; 1–2 LSB quadratic and cubic bows at 13 bits,
#: shared rms 0.05 … 8 LSB, forced onto the series): at most 5e-8 LSB², 1/12 … 1/2000 of
#: ``|φ''|·s²``. The reference chip's 1 LSB quadratic bow at 13 bits (``|φ''|`` ≈ 1.2e-7 per LSB)
#: keeps every element of up to 2.9 LSB rms on the series. Unit: LSB².
SMOOTH_INL_TOL: float = 1e-6


def _on_series(conv: Converter, x: NDArray[np.float64], u: NDArray[np.float64],
               reach: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Elements the series answers: the ideal transitions (no table) or a smooth bow on them
    whose curvature over the element's spread (``reach/10``) stays within
    :data:`SMOOTH_INL_TOL`, white noise of at least :data:`SERIES_MIN_WHITE_LSB` at every
    converter, and ``x ± reach`` inside the range's interior transitions (beyond 10 rms a
    Gaussian's mass is 1.5e-23: clipping is invisible; with a bow ``x`` is its input code,
    within the bow's peak of the ideal code it rounds to)."""
    top = 2.0 ** conv.bits - 1.0
    smooth = conv.bow is not None
    if (conv.levels is not None and not smooth) or u.size == 0 \
            or u.min() < SERIES_MIN_WHITE_LSB:
        return np.zeros(x.shape, bool)
    margin = abs(conv.bow[0]) if smooth else 0.0
    inside = (x - reach - margin >= 0.5) & (x + reach + margin <= top - 0.5)
    if smooth:
        spread = reach / 10.0
        inside &= bow_curvature(*conv.bow, conv.bits) * spread**2 <= SMOOTH_INL_TOL
    return inside


def _unbowed(conv: Converter, x: NDArray[np.float64]
             ) -> tuple[NDArray[np.float64], NDArray[np.float64] | float]:
    """``(φ(x), φ'(x))`` of a converter's smooth bow (:func:`bow_inverse`), ``(x, 1)`` without
    one: a bowed code of ``x + e`` is ``round(φ(x) + φ'(x)·e)`` up to the curvature
    :data:`SMOOTH_INL_TOL` bounds."""
    if conv.bow is None:
        return x, 1.0
    return bow_inverse(x, *conv.bow, conv.bits)


def _by_series(conv: Converter, series: NDArray[np.bool_], by_series, ratios_of, by_quadrature
               ) -> NDArray[np.float64]:
    """An array of ``series.shape``: ``by_series()`` on the ``series`` elements; on the others
    (``rest``, their flat indices, C order) each element's ratio of shared to white rms
    ``ratios_of(sub, rest)`` (``sub`` their converters in a row) picks its node set
    (:func:`_node_counts`), and ``by_quadrature(sub, idx, nodes)`` runs on the elements of each
    node set slice by slice (:data:`QUAD_SLICE_VALUES` values of nodes × elements a slice): one
    wide element (a bright pixel's shot noise) does not set every element's nodes."""
    out = np.empty(series.shape)
    if series.any():
        out[series] = by_series()
    rest = np.flatnonzero(~series)
    if rest.size:
        pixel = rest % conv.n_pixels  # the trailing axes of series.shape are the converters'
        counts = _node_counts(ratios_of(conv.at(pixel), rest))
        flat = out.reshape(-1)
        for n in np.unique(counts):
            mine = rest[counts == n]
            nodes = _quadrature_nodes(int(n))
            step = max(1, QUAD_SLICE_VALUES // int(n))
            for lo in range(0, mine.size, step):
                part = mine[lo:lo + step]
                flat[part] = by_quadrature(conv.at(part % conv.n_pixels), part, nodes)
    return out


def series_harmonics(u_min: float) -> int:
    """``K``, the last harmonic with ``2π²u²k² < 44``: every term dropped carries
    ``γ_k(u) = e^{−2π²u²k²} < 1e-19`` (``u`` the smallest white rms, LSB). The series' cost per
    element grows as ``K²`` (its square's double sum): 2 at 1 LSB, 96 at the floor 1/64 LSB
    (≈ 0.5 ms an element there, 0.3 µs at 1 LSB)."""
    return int(math.ceil(math.sqrt(44.0 / (2.0 * math.pi**2)) / u_min))


def _harmonics(u_min: float) -> NDArray[np.float64]:
    """``k = 1 … K`` (:func:`series_harmonics`) as a column."""
    return np.arange(1.0, series_harmonics(u_min) + 1.0)[:, None]


def _damping(rms: NDArray[np.float64], k: ArrayLike) -> NDArray[np.float64]:
    """``E[e^{2πik·Z·rms}] = e^{−2π²rms²k²}``, ``Z ~ N(0, 1)``."""
    return np.exp(-2.0 * math.pi**2 * rms * rms * np.square(k))


def _series_mean_of_var(x: NDArray[np.float64], sigma: NDArray[np.float64],
                        u: NDArray[np.float64]) -> NDArray[np.float64]:
    """``E_y[v(y)]``, ``y ~ N(x, σ²)`` in LSB, on the ideal transitions (``Q = round``), white
    noise of rms ``u``; 1-D arrays of elements.

    With ``e(x) = x − round(x) = Σ b_k sin 2πkx``, ``b_k = (−1)^{k+1}/(πk)`` (the sawtooth) and
    ``e² = 1/12 + Σ (−1)^k cos 2πkx / (π²k²)``, the code's variance at input ``y`` is
    ``v(y) = Var(uZ − e(y + uZ)) = u² + 1/12 + Σ A_k γ_k cos 2πky − (Σ b_k γ_k sin 2πky)²``,
    ``A_k = (−1)^k (1/(π²k²) + 4u²)`` (Stein's lemma for ``E[Z e]``), ``γ_k = e^{−2π²u²k²}``; then
    ``E_y[cos 2πmy] = cos(2πmx)·e^{−2π²σ²m²}``. Exact but for the dropped harmonics
    (:func:`_harmonics`: < 1e-19 each) and rounding: about 1e-15 LSB² (u ≥ 1 LSB: 2 harmonics).
    """
    k = _harmonics(float(u.min()))
    sign = np.where(k % 2 == 0, 1.0, -1.0)  # (−1)^k
    gamma = _damping(u, k)
    b_gamma = -sign / (math.pi * k) * gamma  # b_k γ_k
    linear = sign * (1.0 / (math.pi * k) ** 2 + 4.0 * u * u) * gamma
    out = u * u + 1.0 / 12.0 + np.sum(linear * np.cos(2 * math.pi * k * x) * _damping(sigma, k),
                                      axis=0)
    # E_y[(Σ_j c_j sin 2πjy)²] = ½ Σ_j Σ_k c_j c_k (E cos 2π(j−k)y − E cos 2π(j+k)y)
    for j in range(k.shape[0]):
        d, s_ = (j + 1) - k, (j + 1) + k
        out -= 0.5 * np.sum(b_gamma[j] * b_gamma * (
            np.cos(2 * math.pi * d * x) * _damping(sigma, d)
            - np.cos(2 * math.pi * s_ * x) * _damping(sigma, s_)), axis=0)
    return out


def _series_ktc_cov(a: NDArray[np.float64], b: NDArray[np.float64], kappa: NDArray[np.float64],
                    u_s: NDArray[np.float64], u_r: NDArray[np.float64],
                    alpha: ArrayLike = 1.0, beta: ArrayLike = 1.0) -> NDArray[np.float64]:
    """``Cov_y(g(y), f(y))``, ``y ~ N(0, κ²)`` shared, ``g(y) = E[round(a + αy + u_s Z)]``,
    ``f(y) = E[round(b + βy + u_r Z')]`` (LSB; 1-D arrays of elements; the slopes ``α``, ``β``
    are a smooth bow's ``φ'`` on each side, 1 without one).

    ``g(y) = a + αy − Σ β_j sin 2πj(a + αy)``, ``β_j = b_j γ_j(u_s)`` (and ``f`` with ``b``,
    ``β``, ``u_r``); by Stein's lemma ``E[y sin 2πk(c + βy)] = 2πkβκ² e^{−2π²β²κ²k²} cos 2πkc``,
    and ``E[sin(p + 2πjαy) sin(q + 2πkβy)] = ½(cos(p − q)·D(jα − kβ) − cos(p + q)·D(jα + kβ))``,
    ``D(m) = e^{−2π²κ²m²}``. Exact to the same order as :func:`_series_mean_of_var`.
    """
    k = _harmonics(float(min(u_r.min(), u_s.min())))
    ka, kb = kappa * alpha, kappa * beta
    sign = np.where(k % 2 == 0, 1.0, -1.0)
    beta_s = -sign / (math.pi * k) * _damping(u_s, k)
    beta_r = -sign / (math.pi * k) * _damping(u_r, k)
    # E[y sin 2πk(c + βy)] / cos 2πkc, times the other side's slope
    slope_r = 2 * math.pi * k * ka * kb * _damping(kb, k)
    slope_s = 2 * math.pi * k * ka * kb * _damping(ka, k)
    out = ka * kb - np.sum(beta_r * np.cos(2 * math.pi * k * b) * slope_r
                           + beta_s * np.cos(2 * math.pi * k * a) * slope_s, axis=0)
    sin_a = np.sin(2 * math.pi * k * a) * _damping(ka, k)
    sin_b = np.sin(2 * math.pi * k * b) * _damping(kb, k)
    for j in range(k.shape[0]):
        jj = j + 1.0
        d, s_ = jj * alpha - k * beta, jj * alpha + k * beta
        joint = 0.5 * (np.cos(2 * math.pi * (jj * a - k * b)) * _damping(kappa, d)
                       - np.cos(2 * math.pi * (jj * a + k * b)) * _damping(kappa, s_))
        out += np.sum(beta_s[j] * beta_r * (joint - sin_a[j] * sin_b), axis=0)
    return out


__all__ = ["QUAD_MAX_RATIO", "QUAD_TOL_LSB2", "cms_moments", "mean_of_var", "node_count"]
