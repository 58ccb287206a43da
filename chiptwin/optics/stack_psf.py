"""The ``psf`` level through a planar layer stack, with an optional fibre faceplate.

Same geometry and output as :func:`chiptwin.optics.psf.coupling_psf` (pixel ``p = row·n_cols +
col``, diodes centred in their pitch cells, ``C[p, s]`` the fraction of site ``s``'s emitted
photons landing on pixel ``p``'s diode), with the one medium of height ``U`` replaced by a
:class:`~chiptwin.optics.layers.Stack` (single pass: Snell, Fresnel per polarisation at every
interface, thin films coherent over the emission band, TIR, Beer–Lambert along the oblique path;
:mod:`chiptwin.optics.profile`).

Emitters (:data:`EMITTERS`): ``"isotropic"`` and ``"lambertian"`` are physical laws traced through
the stack; ``"lambertian_na2"`` is the paper's convention kept by name for reproducing its figures:
one medium of height ``stack.height_um``, the stack's indices ignored.

Routing: a homogeneous stack (one index, no absorption), no faceplate and no silicon interface go
to today's closed-form :func:`~chiptwin.optics.psf.coupling_psf`, bit for bit. Otherwise the
general path integrates the tabulated radial profile over each diode exactly in angle:

``F(x, y) = [H(x, y) + H(y, x)] / 2π``,  ``H(x, y) = ∫₀^{asinh(y/x)} P(x cosh w) / cosh w dw``

is the share landing in ``[0, x] × [0, y]`` (``φ`` from the foot, ``tan φ = sinh w``: the
variable that keeps a rectangle edge close to the foot smooth), and a rectangle is the signed sum of
four corners, as in the closed form. A disc footprint convolves the profile first
(:func:`chiptwin.optics.profile.disc_profile`); a square footprint and the faceplate's box blur are
averaged over Gauss–Legendre nodes. Node counts double until two levels agree within
``rtol × plane fraction`` (the same contract as ``coupling_psf``).

The site's top surface (``top``, :mod:`chiptwin.optics.top`): the light it returns is one more
profile per part (air: one; a lid: its front face, and through the lid), an image source single
reflection (:func:`chiptwin.optics.profile.build_profile`), summed with the direct light's
coupling; each part converges within its share of the tolerance.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.optics import _profile_kernels, thinfilm
from chiptwin.optics.collection import ISOTROPIC, LAMBERTIAN_NA2, plane_fraction
from chiptwin.optics.faceplate import Faceplate
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.profile import (
    ISOTROPIC_LAW,
    LAMBERTIAN_LAW,
    RadialProfile,
    _arrays,
    _cosines,
    _emission,
    build_profile,
    disc_profile,
    fresnel_unpolarised,
)
from chiptwin.optics.psf import (
    _check_grid,
    _footprint,
    _footprint_nodes,
    _sites,
    coupling_psf,
    distinct_offsets,
    pixel_centers_um,
    point_below,
)
from chiptwin.optics.quadrature import gauss_legendre
from chiptwin.optics.top import Top

EMITTERS: tuple[str, ...] = (ISOTROPIC_LAW, LAMBERTIAN_LAW, LAMBERTIAN_NA2)
"""Emission laws by name: two physical ones and the paper's convention."""

METHODS: tuple[str, ...] = ("auto", "radial")
"""``auto``: closed form when the stack is homogeneous; ``radial``: always the general path."""

_N_W_FIRST, _N_W_MAX = 16, 1024
_CHUNK = 1 << 20


def check_emitter(emitter: str) -> str:
    """Return ``emitter`` if it is one of :data:`EMITTERS`, else raise a ValueError."""
    if emitter not in EMITTERS:
        raise ValueError(f"emitter = {emitter!r} is unknown: must be one of {EMITTERS}")
    return emitter


def _plane_of(emitter: str) -> float:
    return plane_fraction(ISOTROPIC if emitter == ISOTROPIC_LAW else LAMBERTIAN_NA2)


def receiving_stack(stack: Stack, *, into_silicon: bool = False,
                    faceplate: Faceplate | None = None) -> Stack:
    """The stack the profile is built for: a zero-thickness layer adds the last interface
    (into the silicon, ``stack.silicon_n``, or into the faceplate's cores, ``core_n``)."""
    if into_silicon and faceplate is not None:
        raise ValueError("into_silicon with a faceplate: the faceplate's exit is straight down at "
                         "the psf level; give one of the two")
    if into_silicon:
        return replace(stack, layers=stack.layers + (Layer("silicon", stack.silicon_n, 0.0),))
    if faceplate is not None and faceplate.core_n is not None:
        core = Layer("faceplate core", faceplate.core_n, 0.0)
        return replace(stack, layers=stack.layers + (core,))
    return stack


# --- a point over a rectangle, through the profile -----------------------------------------------


def _panel(lo: NDArray, hi: NDArray, n: int) -> tuple[NDArray, NDArray]:
    x, w = gauss_legendre(n)
    half = 0.5 * (hi - lo)[:, None]
    return 0.5 * (hi + lo)[:, None] + half * x[None, :], half * w[None, :]


def _quarter_circle() -> tuple[NDArray, NDArray]:
    """Angles over ``[0, π/2]`` and their weights, flat: 512 panels of 8 Gauss–Legendre nodes
    (the plane fractions' quadrature in angle)."""
    edges = np.linspace(0.0, np.pi / 2, 513)
    theta, w = _panel(edges[:-1], edges[1:], 8)
    return theta.ravel(), w.ravel()


def _h(profile: RadialProfile, x: NDArray, y: NDArray, n: int) -> NDArray:
    """``H(x, y) = ∫₀^{asinh(y/x)} P(x cosh w)/cosh w dw`` for ``x, y > 0``; split at the
    profile's outer edge when it is bounded (a kink of ``P``); ``n`` Gauss–Legendre nodes a panel
    (:func:`chiptwin.optics._profile_kernels.corner_h`)."""
    gl_x, gl_w = gauss_legendre(n)
    out = np.empty(x.size)
    _profile_kernels.corner_h(*profile.table, np.ascontiguousarray(x, dtype=np.float64),
                              np.ascontiguousarray(y, dtype=np.float64), gl_x, gl_w, out)
    return out


def _corner(profile: RadialProfile, x: NDArray, y: NDArray, n: int) -> NDArray:
    """Signed share of ``[0, x] × [0, y]`` (any signs), as the closed form's corner terms."""
    ax, ay = np.abs(x), np.abs(y)
    ok = (ax > 0) & (ay > 0)
    out = np.zeros(x.size)
    if ok.any():
        a, b = ax[ok], ay[ok]
        out[ok] = (_h(profile, a, b, n) + _h(profile, b, a, n)) / (2.0 * np.pi)
    return np.sign(x) * np.sign(y) * out


def _rectangle(profile, x0, x1, y0, y1, n: int) -> NDArray:
    return (_corner(profile, x1, y1, n) - _corner(profile, x0, y1, n)
            - _corner(profile, x1, y0, n) + _corner(profile, x0, y0, n))


def point_rectangle_fraction_stack(
    x_min_um: ArrayLike, x_max_um: ArrayLike, y_min_um: ArrayLike, y_max_um: ArrayLike,
    *, stack: Stack, emitter: str, n_w: int = 128,
) -> NDArray[np.float64]:
    """Fraction of a point source's photons landing on a rectangle (relative to the foot), through
    ``stack`` (general path, ``n_w`` Gauss–Legendre nodes per panel). For tests and diagnostics;
    the coupling matrix uses the converged :func:`coupling_stack`."""
    law = check_emitter(emitter)
    if law == LAMBERTIAN_NA2:
        raise ValueError("lambertian_na2 is the one-medium convention: "
                         "use psf.point_rectangle_fraction")
    arrays = [np.atleast_1d(_checks.as_float_array(name, v)).ravel() for name, v in (
        ("x_min_um", x_min_um), ("x_max_um", x_max_um), ("y_min_um", y_min_um),
        ("y_max_um", y_max_um))]
    arrays = np.broadcast_arrays(*arrays)
    return _rectangle(build_profile(stack, law), *arrays, n_w)


# --- the coupling matrix ------------------------------------------------------------------------


def _blur_nodes(square_um: float, faceplate: Faceplate | None, n: int):
    """Nodes over the square footprint ⊛ the faceplate's kernel (either, both or none): both are
    separable, uniform over the square's side and a triangle on ± the fibre pitch (see
    :func:`_axis_nodes`), so the nodes are one axis's squared (n² of them, not n⁴: a square
    footprint under a faceplate once ran for more than 10 minutes on a 5 × 5 grid)."""
    pitch = faceplate.fiber_pitch_um if faceplate is not None else 0.0
    if pitch <= 0:
        return (_footprint_nodes("square", square_um, n) if square_um > 0
                else (np.zeros(1), np.zeros(1), np.ones(1)))
    q, qw = _axis_nodes(max(square_um, 0.0), pitch, n)
    qx, qy = np.meshgrid(q, q)
    return qx.ravel(), qy.ravel(), np.outer(qw, qw).ravel()


def _axis_nodes(side_um: float, pitch_um: float, n: int) -> tuple[NDArray, NDArray]:
    """One axis of the blur: ``U + T``, U uniform over ``side_um`` (the square footprint) and T
    the faceplate's displacement, exit − entry: the ray enters its fibre at a uniform place (the
    lattice's phase against the site is unknown) and leaves uniformly over it, the difference of
    two uniforms over a pitch, a triangle on ±``pitch_um`` (variance p²/6;
    :mod:`chiptwin.optics.faceplate`). The density is piecewise polynomial (a box, a triangle, or
    their convolution: quadratic between the knots ±side/2, ±side/2 ± pitch): Gauss–Legendre on
    each piece weighted by the density, exact for the density times a polynomial; ``n/2`` nodes
    a piece (2 to 5 pieces)."""
    ends = (-0.5 * side_um, 0.5 * side_um) if side_um > 0 else (0.0,)
    knots = np.array(sorted({e + d for e in ends for d in (-pitch_um, 0.0, pitch_um)}))
    m = max(n // 2, 2)  # per piece: doubling n refines every piece (the convergence test)
    x, w = gauss_legendre(m)
    lo, hi = knots[:-1, None], knots[1:, None]
    q = (0.5 * (hi - lo) * (1.0 + x) + lo).ravel()
    qw = (0.5 * (hi - lo) * w * _axis_density(q.reshape(lo.size, m), side_um, pitch_um)).ravel()
    return q, qw / qw.sum()


def _axis_density(x: NDArray, side_um: float, pitch_um: float) -> NDArray:
    """Density of ``U + T`` (see :func:`_axis_nodes`) at ``x``."""
    if side_um <= 0:
        return np.clip(1.0 - np.abs(x) / pitch_um, 0.0, None) / pitch_um
    return (_triangle_cdf(x + 0.5 * side_um, pitch_um)
            - _triangle_cdf(x - 0.5 * side_um, pitch_um)) / side_um


def _triangle_cdf(t: NDArray, p: float) -> NDArray:
    """CDF of the triangle on ±p."""
    t = np.clip(t, -p, p)
    return np.where(t <= 0.0, (t + p) ** 2 / (2 * p * p), 1.0 - (p - t) ** 2 / (2 * p * p))


def _average(profile, dx, dy, half_w, half_h, nodes, n_w) -> NDArray:
    qx, qy, weight = nodes
    out = np.zeros(dx.size)
    step = max(1, _CHUNK // max(dx.size * 16 * n_w, 1))
    for start in range(0, qx.size, step):
        sl = slice(start, start + step)
        cx = (dx[:, None] - qx[None, sl]).ravel()
        cy = (dy[:, None] - qy[None, sl]).ravel()
        frac = _rectangle(profile, cx - half_w, cx + half_w, cy - half_h, cy + half_h, n_w)
        out += frac.reshape(dx.size, -1) @ weight[sl]
    return out


def _converged(profile, dx, dy, half_w, half_h, square_um, faceplate, atol) -> NDArray:
    blurred = square_um > 0 or faceplate is not None
    n_w, n_sq = _N_W_FIRST, 4
    coarse = _average(profile, dx, dy, half_w, half_h, _blur_nodes(square_um, faceplate, n_sq),
                      n_w)
    while n_w < _N_W_MAX:
        n_w *= 2
        n_sq = min(2 * n_sq, 64) if blurred else n_sq
        fine = _average(profile, dx, dy, half_w, half_h,
                        _blur_nodes(square_um, faceplate, n_sq), n_w)
        if np.max(np.abs(fine - coarse)) <= atol:
            return fine
        coarse = fine
    raise ValueError(f"the stack psf quadrature did not reach atol = {atol:g} with {_N_W_MAX} "
                     "nodes: raise rtol")


def coupling_stack(
    *,
    n_rows: int,
    n_cols: int,
    pitch_um: float,
    diode_w_um: float,
    diode_h_um: float,
    site_x_um: ArrayLike,
    site_y_um: ArrayLike,
    stack: Stack,
    emitter: str,
    faceplate: Faceplate | None = None,
    into_silicon: bool = False,
    site_radius_um: float = 0.0,
    site_side_um: float = 0.0,
    rtol: float = 1e-6,
    method: str = "auto",
    top: Top | None = None,
) -> NDArray[np.float64]:
    """Site-to-pixel coupling through a planar stack (the ``psf`` level, single pass).

    Parameters
    ----------
    n_rows, n_cols, pitch_um, diode_w_um, diode_h_um
        The array, as in :func:`chiptwin.optics.psf.coupling_psf` (µm).
    site_x_um, site_y_um, site_radius_um, site_side_um, rtol
        The sites and the tolerance, as there (µm; ``rtol`` relative to the plane fraction of
        the emitter's law: 0.5 isotropic, 1 Lambertian).
    stack : Stack
        Layers from the site (in the first) down to the diode plane, or to the faceplate's top.
    emitter : str
        ``"isotropic"``, ``"lambertian"`` (physical, through the stack) or ``"lambertian_na2"``
        (the paper's convention: one medium of height ``stack.height_um``).
    faceplate : Faceplate, optional
        A fibre faceplate below the stack, directly on the diodes
        (:mod:`chiptwin.optics.faceplate`).
    into_silicon : bool
        False (default): the light incident on the diode plane (the pixel's QE, an external QE,
        carries the surface reflection). True: times the unpolarised Fresnel transmittance into
        silicon of index ``stack.silicon_n`` at each ray's angle (then use an internal QE).
    method : str
        ``"auto"`` (closed form for a homogeneous stack) or ``"radial"`` (always the general path;
        for tests of its accuracy).
    top : Top, optional
        The site's top surface (:mod:`chiptwin.optics.top`); None or ``"solution"``: nothing
        returns (the coupling is today's, bit for bit). Otherwise, under the isotropic law, the
        light the top returns is added by an image source, single reflection: each upward ray
        weighted by the top's Fresnel reflectance per polarisation (TIR included; a lid's
        incoherent slab reflectance) and moved ``2·D·tanθ₀`` (plus a lid's ``2·t·tanθ_g``)
        before it goes down the same stack and faceplate as the direct light
        (:func:`chiptwin.optics.profile.build_profile`). A Lambertian emitter facing the diodes
        sends nothing up; ``lambertian_na2`` (one medium) refuses a top that returns light.

    Returns
    -------
    ndarray, shape (n_rows * n_cols, n_sites)
    """
    law = check_emitter(emitter)
    if method not in METHODS:
        raise ValueError(f"method = {method!r} is unknown: must be one of {METHODS}")
    if not isinstance(stack, Stack):
        raise ValueError(f"stack = {stack!r}: must be a chiptwin.optics.layers.Stack")
    grid = dict(n_rows=n_rows, n_cols=n_cols, pitch_um=pitch_um, diode_w_um=diode_w_um,
                diode_h_um=diode_h_um, site_x_um=site_x_um, site_y_um=site_y_um,
                site_radius_um=site_radius_um, site_side_um=site_side_um, rtol=rtol)
    if top is not None and not isinstance(top, Top):
        raise ValueError(f"top = {top!r}: must be a chiptwin.optics.top.Top")
    returns = top is not None and top.returns and law == ISOTROPIC_LAW
    if law == LAMBERTIAN_NA2:
        if faceplate is not None or into_silicon or (top is not None and top.returns):
            raise ValueError("emitter 'lambertian_na2' is the paper's one-medium convention: "
                             "no faceplate, no silicon interface, no top that returns light")
        return coupling_psf(**grid, height_um=stack.height_um, convention=LAMBERTIAN_NA2)
    closed = ISOTROPIC if law == ISOTROPIC_LAW else LAMBERTIAN_NA2
    if (method == "auto" and stack.homogeneous and faceplate is None and not into_silicon
            and not returns):
        return coupling_psf(**grid, height_um=stack.height_um, convention=closed)
    rows, cols, _ = _check_grid(n_rows, n_cols, pitch_um, diode_w_um, diode_h_um)
    sx, sy = _sites(site_x_um, site_y_um)
    tol = _checks.scalar("rtol", rtol, minimum=0.0, strict=True)
    if not 1e-12 <= tol <= 1e-2:
        raise ValueError(f"rtol = {tol!r} is out of range: must be in [1e-12, 1e-2]")
    shape, size = point_below(*_footprint(site_radius_um, site_side_um), stack.height_um, tol)
    receiving = receiving_stack(stack, into_silicon=into_silicon, faceplate=faceplate)
    na = faceplate.na if faceplate else None
    profiles = [build_profile(receiving, law, na=na)]
    if returns:
        profiles += [build_profile(receiving, law, na=na, top=top, part=k)
                     for k in range(top.parts)]
    atol = tol * _plane_of(law) / len(profiles)  # each part within its share of the tolerance
    px, py = pixel_centers_um(rows, cols, pitch_um)
    dx = np.abs(px[:, None] - sx[None, :]).ravel()
    dy = np.abs(py[:, None] - sy[None, :]).ravel()
    first, inverse = distinct_offsets(dx, dy)
    values = 0.0
    for profile in profiles:
        if shape == "disc":
            profile = disc_profile(profile, size, atol=0.25 * atol)
        values = values + _converged(profile, dx[first], dy[first], 0.5 * diode_w_um,
                                     0.5 * diode_h_um, size if shape == "square" else 0.0,
                                     faceplate, atol)
    if faceplate is not None:
        values = values * faceplate.open_area_ratio
    # rounding leaves −1e-17 where no light lands: a share is never negative
    return np.maximum(values, 0.0)[inverse].reshape(rows * cols, sx.size)


# --- plane fractions and the collected fraction under each law ------------------------------------


def _incoherent_weight(layers: tuple[Layer, ...], theta_m: NDArray) -> NDArray:
    """Transmittance to the last plane with the incoherent multiple-reflection sum in every
    internal layer, s and p separately (then averaged); the first layer single pass (open above)."""
    n, t, alpha = _arrays(layers)
    beta, cos = _cosines(n, theta_m)
    att = [np.exp(-a_i * t_i / np.where(c_i > 0, c_i, np.inf)) if a_i > 0 else np.ones_like(c_i)
           for a_i, t_i, c_i in zip(alpha, t, cos, strict=True)]
    total = np.zeros_like(theta_m)
    for pol in ("s", "p"):
        trans, refl = np.ones_like(theta_m), np.zeros_like(theta_m)
        for j in range(len(n) - 2, -1, -1):
            t_j = _polarised(n[j], n[j + 1], cos[j], cos[j + 1], pol)
            a2r = att[j + 1] ** 2 * refl
            denom = 1.0 - (1.0 - t_j) * a2r
            trans = t_j * att[j + 1] * trans / denom
            refl = (1.0 - t_j) + t_j * t_j * a2r / denom
        total += 0.5 * trans
    return total * att[0]


def _polarised(n1, n2, c1, c2, pol: str) -> NDArray:
    prod = 4.0 * n1 * n2 * c1 * c2
    with np.errstate(invalid="ignore", divide="ignore"):
        out = prod / ((n1 * c1 + n2 * c2) ** 2 if pol == "s" else (n2 * c1 + n1 * c2) ** 2)
    return np.nan_to_num(out)


def plane_fraction_stack(stack: Stack, emitter: str, *, into_silicon: bool = False,
                         reflections: str = "single", band: thinfilm.Band | None = None,
                         rtol: float = 1e-4, top: Top | None = None) -> float:
    """Fraction of the emitted photons reaching an infinite diode plane through ``stack``.

    ``reflections="single"``: the psf level's single pass (equal to the coupling summed over a
    huge diode). ``"incoherent"``: with the incoherent multiple-reflection sum inside every layer
    below the first (slab factor ``T₁₂T₂₃/(1 − R₂₁R₂₃)`` per polarisation, Born & Wolf Sec. 1.5;
    sources.md O8; nested):
    the energy the single pass leaves out, which the ``raytrace`` level places. ``"coherent"``:
    the multiple reflections as amplitudes (transfer matrices, :mod:`chiptwin.optics.thinfilm`)
    averaged over the emission ``band`` (default: the stack's own), over
    every angle the emitter sends down, so light that tunnels through a thin low-index layer
    beyond its critical angle counts; wavelength nodes double until two counts agree within
    ``rtol`` of the fraction. ``top`` (``"single"`` only): adds the light the site's top
    returns once (:func:`coupling_stack`'s image source, isotropic law).
    """
    law = check_emitter(emitter)
    if law == LAMBERTIAN_NA2:
        return 1.0
    receiving = receiving_stack(stack, into_silicon=into_silicon)
    layers = receiving.layers
    returns = top is not None and top.returns and law == ISOTROPIC_LAW
    if returns and reflections != "single":
        raise ValueError("plane_fraction_stack with a top: reflections='single' only")
    if reflections == "single":
        parts = range(top.parts) if returns else ()
        return build_profile(receiving, law).total + sum(
            build_profile(receiving, law, top=top, part=k).total for k in parts)
    if reflections == "coherent":
        return _coherent_fraction(layers, law, band or stack.band, rtol)
    if reflections != "incoherent":
        raise ValueError(f"reflections = {reflections!r}: must be 'single', 'incoherent' or "
                         "'coherent'")
    n, _, _ = _arrays(layers)
    theta, w = _quarter_circle()
    _, cos = _cosines(n, theta)
    dp = _emission(n, theta, cos[0], law) * _incoherent_weight(layers, theta)
    return float(dp @ w)


def _coherent_fraction(layers: tuple[Layer, ...], law: str, band: thinfilm.Band,
                       rtol: float) -> float:
    """The ``coherent`` plane fraction: the emission law over the first layer's angles θ₀ (all of
    them: a ray the ray picture loses at a thin layer's critical angle may tunnel), times the
    band-averaged transfer-matrix transmittance, times Beer–Lambert along the first and the
    last layer."""
    theta, w = _quarter_circle()
    n0, n_last = layers[0].n, layers[-1].n
    cos0 = np.cos(theta)
    law_density = 0.5 * np.sin(theta) if law == ISOTROPIC_LAW else 2.0 * np.sin(theta) * cos0
    s_last = n0 * np.sin(theta) / n_last
    cos_last = np.sqrt(np.maximum(1.0 - s_last * s_last, 0.0))
    path = np.exp(-layers[0].alpha_per_um * layers[0].thickness_um / cos0)
    depth = layers[-1].alpha_per_um * layers[-1].thickness_um
    # beyond the last layer's critical angle nothing enters it (T = 0): the factor is 0 there
    path = path * np.exp(-depth / np.where(cos_last > 0, cos_last, 1.0)) * (cos_last > 0)
    weight = law_density * path * w
    count = band.node_count(layers)
    value = float(weight @ thinfilm.band_transmittance(layers, theta, band, count))
    while 2 * count - 1 <= thinfilm.MAX_NODES:
        count = 2 * count - 1  # the same nodes and one between each pair
        finer = float(weight @ thinfilm.band_transmittance(layers, theta, band, count))
        if abs(finer - value) <= rtol * abs(finer):
            return finer
        value = finer
    raise ValueError(f"coherent plane fraction: the band's average did not settle within "
                     f"{thinfilm.MAX_NODES} wavelengths (rtol {rtol:g}); the stack's thickest "
                     "inner layer is too thick for a coherent sum over this band: use "
                     "reflections='incoherent'")


def collected_fractions(
    *, n_rows: int, n_cols: int, pitch_um: float, diode_w_um: float, diode_h_um: float,
    site_x_um: ArrayLike, site_y_um: ArrayLike, stack: Stack, faceplate: Faceplate | None = None,
    site_radius_um: float = 0.0, site_side_um: float = 0.0, rtol: float = 1e-6,
) -> dict[str, float]:
    """The share of each site's light collected by all diodes, mean over sites, per emitter law.

    Returns ``{"isotropic": …, "lambertian": …, "lambertian_na2": …}`` (the last only without a
    faceplate), for ``chiptwin run`` to report the law's weight beside the chosen one.
    """
    out = {}
    for law in EMITTERS:
        if law == LAMBERTIAN_NA2 and faceplate is not None:
            continue
        c = coupling_stack(n_rows=n_rows, n_cols=n_cols, pitch_um=pitch_um,
                           diode_w_um=diode_w_um, diode_h_um=diode_h_um, site_x_um=site_x_um,
                           site_y_um=site_y_um, stack=stack, emitter=law, faceplate=faceplate,
                           site_radius_um=site_radius_um, site_side_um=site_side_um, rtol=rtol)
        out[law] = float(np.mean(c.sum(axis=0)))
    return out


__all__ = ["EMITTERS", "METHODS", "check_emitter", "collected_fractions", "coupling_stack",
           "fresnel_unpolarised", "plane_fraction_stack", "point_rectangle_fraction_stack",
           "receiving_stack"]
