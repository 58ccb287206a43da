"""Site-to-pixel coupling: the share of each site's light that lands on each pixel's photodiode.

Geometry (all lengths in µm): the pixel array lies in the plane ``z = 0``; pixel ``(row, col)`` has
index ``p = row · n_cols + col`` (row-major) and a rectangular photodiode ``diode_w_um`` (along x,
the columns) by ``diode_h_um`` (along y, the rows) centred in its pitch cell, at
``((col + ½)·pitch, (row + ½)·pitch)``. Sites are given by their centres ``(x, y)`` in the same
frame and emit from a height ``U = height_um`` above the diode plane.

Irradiance of a unit point source at lateral distance ``r`` (per µm², fraction of all photons):

* ``"isotropic"``:      ``U / (r² + U²)^{3/2} / (4π)``, integrating to 1/2 over the plane;
* ``"lambertian_na2"``: ``U² / (r² + U²)² / π``, integrating to 1 (Lambertian, facing down).

Two fidelity levels of the optics stage:

``psf``
    :func:`coupling_psf`: the irradiance integrated exactly over every diode rectangle (closed-form
    corner terms, :func:`point_rectangle_fraction`), averaged over the site's footprint (disc or
    square of uniform emission) by Gauss–Legendre quadrature refined until it meets a stated
    tolerance. Off-diagonal entries are the optical cross-talk.
``na2``
    :func:`coupling_na2`: each site couples only to the pixel under it, with the collection
    efficiency of :func:`diode_collection_efficiency` (no spread, no footprint).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.optics.collection import (
    LAMBERTIAN_NA2,
    check_convention,
    collection_efficiency,
    plane_fraction,
)
from chiptwin.optics.quadrature import gauss_legendre

APERTURES: tuple[str, ...] = ("rectangle", "inscribed_disc", "equal_area_disc")
"""How :func:`diode_collection_efficiency` models the diode seen by a centred point source."""

OFFSET_QUANTUM_UM: float = 1e-9
"""Site-to-pixel offsets equal within this many µm share one evaluation in :func:`coupling_psf`."""

_N_FIRST, _N_MAX = 4, 256
_CHUNK_ELEMENTS = 1 << 21


# --- exact point source over a rectangle ---------------------------------------------------------


def _corner_isotropic(x: NDArray, y: NDArray, u: NDArray) -> NDArray:
    """Signed solid angle / 4π of ``[0, x] × [0, y]`` seen from height ``u`` above the origin."""
    return np.arctan(x * y / (u * np.sqrt(x * x + y * y + u * u))) / (4.0 * np.pi)


def _corner_lambertian(x: NDArray, y: NDArray, u: NDArray) -> NDArray:
    """Signed point-to-rectangle form factor of ``[0, x] × [0, y]`` from height ``u``."""
    big_x, big_y = x / u, y / u
    sx, sy = np.sqrt(1.0 + big_x * big_x), np.sqrt(1.0 + big_y * big_y)
    return (big_x / sx * np.arctan(big_y / sx) + big_y / sy * np.arctan(big_x / sy)) / (2.0 * np.pi)


def _rectangle(x0, x1, y0, y1, u, convention: str) -> NDArray:
    """Superposition of the four signed corner terms (no checks)."""
    corner = _corner_lambertian if convention == LAMBERTIAN_NA2 else _corner_isotropic
    return corner(x1, y1, u) - corner(x0, y1, u) - corner(x1, y0, u) + corner(x0, y0, u)


def point_rectangle_fraction(
    x_min_um: ArrayLike,
    x_max_um: ArrayLike,
    y_min_um: ArrayLike,
    y_max_um: ArrayLike,
    height_um: ArrayLike,
    *,
    convention: str,
) -> np.float64 | NDArray[np.float64]:
    """Fraction of a point source's photons that land on a rectangle in the plane below it.

    Parameters
    ----------
    x_min_um, x_max_um, y_min_um, y_max_um : array_like
        The rectangle, relative to the foot of the source (the point right below it);
        ``x_max >= x_min``, ``y_max >= y_min``. Unit: µm.
    height_um : array_like
        Height of the source above the plane, > 0. Unit: µm.
    convention : str
        ``"isotropic"`` or ``"lambertian_na2"`` (see the module docstring).

    Returns
    -------
    Fraction of all emitted photons, in [0, plane_fraction(convention)].

    Notes
    -----
    Exact, by superposition of signed corner terms ``F(x1,y1) − F(x0,y1) − F(x1,y0) + F(x0,y0)``
    where ``F(x, y)`` covers ``[0, x] × [0, y]``: isotropic ``F = atan(xy / (U√(x²+y²+U²))) / 4π``
    (solid angle of a rectangle); Lambertian ``F = [X/√(1+X²)·atan(Y/√(1+X²)) +
    Y/√(1+Y²)·atan(X/√(1+Y²))] / 2π`` with ``X = x/U, Y = y/U`` (differential area to a parallel
    rectangle, Howell's catalogue of configuration factors). Absolute error ≲ 1e-16: far-away
    rectangles lose relative, not absolute, precision.
    """
    check_convention(convention)
    x0, x1 = _checks.as_float_array("x_min_um", x_min_um), _checks.as_float_array("x_max_um",
                                                                                  x_max_um)
    y0, y1 = _checks.as_float_array("y_min_um", y_min_um), _checks.as_float_array("y_max_um",
                                                                                  y_max_um)
    u = _checks.positive("height_um", height_um)
    for lo, hi, name in ((x0, x1, "x"), (y0, y1, "y")):
        if (hi < lo).any():
            raise ValueError(f"{name}_max_um < {name}_min_um: the rectangle must have "
                             f"{name}_max_um >= {name}_min_um")
    return _rectangle(x0, x1, y0, y1, u, convention)[()]


# --- the pixel grid -------------------------------------------------------------------------


def _count(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} = {value!r} is out of range: must be an int >= 1")
    return int(value)


def _check_grid(n_rows, n_cols, pitch_um, diode_w_um, diode_h_um) -> tuple[int, int, float]:
    rows, cols = _count("n_rows", n_rows), _count("n_cols", n_cols)
    pitch = _checks.scalar("pitch_um", pitch_um, minimum=0.0, strict=True)
    for name, value in (("diode_w_um", diode_w_um), ("diode_h_um", diode_h_um)):
        d = _checks.scalar(name, value, minimum=0.0, strict=True)
        if d > pitch:
            raise ValueError(f"{name} = {d!r} is out of range: must be <= pitch_um = {pitch!r} "
                             "(the diode sits inside its pitch cell)")
    return rows, cols, pitch


def pixel_centers_um(
    n_rows: int, n_cols: int, pitch_um: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centres of the pixels' photodiodes, in pixel-index order (row-major).

    Parameters
    ----------
    n_rows, n_cols : int
        Array size, >= 1.
    pitch_um : float
        Pixel pitch, > 0. Unit: µm.

    Returns
    -------
    x_um, y_um : ndarray, shape (n_rows * n_cols,)
        ``((col + ½)·pitch, (row + ½)·pitch)``; also the natural site positions (one site per
        pixel, centred). Unit: µm.
    """
    rows, cols = _count("n_rows", n_rows), _count("n_cols", n_cols)
    pitch = _checks.scalar("pitch_um", pitch_um, minimum=0.0, strict=True)
    row, col = np.divmod(np.arange(rows * cols), cols)
    return (col + 0.5) * pitch, (row + 0.5) * pitch


def _sites(site_x_um: ArrayLike, site_y_um: ArrayLike) -> tuple[NDArray, NDArray]:
    x = _checks.as_float_array("site_x_um", site_x_um)
    y = _checks.as_float_array("site_y_um", site_y_um)
    if x.ndim != 1 or x.shape != y.shape:
        raise ValueError(f"site_x_um {x.shape} and site_y_um {y.shape} must be 1-D, same shape")
    return x, y


# --- footprint quadrature -----------------------------------------------------------------------


def _footprint_nodes(shape: str, size_um: float, n: int) -> tuple[NDArray, NDArray, NDArray]:
    """Nodes ``(qx, qy)`` relative to the site centre and weights summing to 1.

    ``disc``: Gauss–Legendre in r (weight r) × 2n-point trapezoid in angle (spectral for a
    periodic integrand). ``square``: tensor Gauss–Legendre. ``point``: one node.
    """
    if shape == "point":
        return np.zeros(1), np.zeros(1), np.ones(1)
    x, w = gauss_legendre(n)
    if shape == "square":
        q = 0.5 * size_um * x
        qx, qy = np.meshgrid(q, q)
        return qx.ravel(), qy.ravel(), np.outer(w, w).ravel() / 4.0
    r = 0.5 * size_um * (1.0 + x)
    w_r = w * (1.0 + x) / np.sum(w * (1.0 + x))  # ∝ r, without r: a subnormal radius underflows
    phi = (np.arange(2 * n) + 0.5) * (np.pi / n)
    qx, qy = np.outer(r, np.cos(phi)), np.outer(r, np.sin(phi))
    return qx.ravel(), qy.ravel(), np.repeat(w_r / (2 * n), 2 * n)


def _footprint_average(dx, dy, half_w, half_h, u, convention, nodes) -> NDArray:
    """Mean over the footprint nodes of the exact rectangle fraction, for offsets ``(dx, dy)``."""
    qx, qy, weight = nodes
    out = np.zeros(dx.size)
    step = max(1, _CHUNK_ELEMENTS // max(dx.size, 1))
    for start in range(0, qx.size, step):
        sl = slice(start, start + step)
        cx = dx[:, None] - qx[None, sl]
        cy = dy[:, None] - qy[None, sl]
        frac = _rectangle(cx - half_w, cx + half_w, cy - half_h, cy + half_h, u, convention)
        out += frac @ weight[sl]
    return out


def _converged_average(dx, dy, half_w, half_h, u, convention, shape, size_um, rtol) -> NDArray:
    """Refine the footprint quadrature (n doubles) until two levels agree within tolerance."""
    atol = rtol * plane_fraction(convention)
    args = (dx, dy, half_w, half_h, u, convention)
    if shape == "point":
        return _footprint_average(*args, _footprint_nodes("point", 0.0, 1))
    n = _N_FIRST
    coarse = _footprint_average(*args, _footprint_nodes(shape, size_um, n))
    while n < _N_MAX:
        n *= 2
        fine = _footprint_average(*args, _footprint_nodes(shape, size_um, n))
        if np.max(np.abs(fine - coarse)) <= atol:
            return fine
        coarse = fine
    raise ValueError(f"the footprint quadrature did not reach rtol = {rtol:g} with {_N_MAX} "
                     f"nodes per dimension for a {shape} of {size_um:g} µm at height_um = {u:g}: "
                     "raise rtol (the footprint is much wider than the height)")


def distinct_offsets(dx: NDArray, dy: NDArray) -> tuple[NDArray, NDArray]:
    """The distinct (``dx``, ``dy``) offsets within :data:`OFFSET_QUANTUM_UM`, in increasing
    order of (``dx``, ``dy``): the index of each one's first occurrence, and each offset's index
    among them. This is ``np.unique(keys, axis=0, return_index=True, return_inverse=True)`` on
    the rounded pairs, the same arrays, by one stable ``lexsort`` of the two columns: ``axis=0``
    sorts the rows as structured records, 5× slower (1.9 s against 0.38 s for 1 M offsets; a
    DSP program's minimum-pitch search couples every pixel with every site several times)."""
    kx, ky = np.round(dx / OFFSET_QUANTUM_UM), np.round(dy / OFFSET_QUANTUM_UM)
    order = np.lexsort((ky, kx))
    sx, sy = kx[order], ky[order]
    new = np.ones(order.size, bool)
    new[1:] = (sx[1:] != sx[:-1]) | (sy[1:] != sy[:-1])
    inverse = np.empty(order.size, np.int64)
    inverse[order] = np.cumsum(new) - 1
    return order[new], inverse


def _footprint(site_radius_um: float, site_side_um: float) -> tuple[str, float]:
    radius = _checks.scalar("site_radius_um", site_radius_um, minimum=0.0, strict=False)
    side = _checks.scalar("site_side_um", site_side_um, minimum=0.0, strict=False)
    if radius > 0 and side > 0:
        raise ValueError(f"site_radius_um = {radius!r} and site_side_um = {side!r}: give at most "
                         "one footprint (a disc or a square)")
    if radius > 0:
        return "disc", radius
    return ("square", side) if side > 0 else ("point", 0.0)


def point_below(shape: str, size_um: float, height_um: float, rtol: float) -> tuple[str, float]:
    """The footprint the quadrature integrates: a point when its size (radius or side) is at
    most ``√rtol × height_um``.

    The mean of a smooth field over a disc of radius ``a`` is its centre value plus
    ``a²∇²f/8`` (over a square of side ``s``: ``s²∇²f/24``; the mean-value expansion), and the
    coupling's field varies over the site's height ``U`` (the irradiance's width), so
    ``|∇²f| ≲ f/U²``: a footprint of ``size ≤ √rtol · U`` moves every entry by ≲ rtol/8 of it,
    inside the tolerance. Below that size the quadrature resolves little but rounding (a
    1e-300 µm disc never converged through a stack), so the point-source law, within the
    tolerance, is the answer.
    """
    if shape != "point" and size_um <= np.sqrt(rtol) * height_um:
        return "point", 0.0
    return shape, size_um


def coupling_psf(
    *,
    n_rows: int,
    n_cols: int,
    pitch_um: float,
    diode_w_um: float,
    diode_h_um: float,
    site_x_um: ArrayLike,
    site_y_um: ArrayLike,
    height_um: float,
    convention: str,
    site_radius_um: float = 0.0,
    site_side_um: float = 0.0,
    rtol: float = 1e-6,
) -> NDArray[np.float64]:
    """Site-to-pixel coupling matrix with optical spread (the ``psf`` optics level).

    Parameters
    ----------
    n_rows, n_cols : int
        Pixel array size, >= 1.
    pitch_um : float
        Pixel pitch, > 0. Unit: µm.
    diode_w_um, diode_h_um : float
        Photodiode width (x) and height (y), in ``(0, pitch_um]``, centred in the cell. Unit: µm.
    site_x_um, site_y_um : array_like, shape (n_sites,)
        Site centres in the array frame (anywhere, also beyond the array). Unit: µm.
    height_um : float
        Height U of the emitting layer above the diode plane, > 0. Unit: µm.
    convention : str
        ``"isotropic"`` (molecules in solution) or ``"lambertian_na2"`` (the paper's).
    site_radius_um : float
        Radius of a disc footprint of uniform emission, >= 0. Unit: µm.
    site_side_um : float
        Side of a square footprint, >= 0 (at most one of the two > 0; both 0 = point). Unit: µm.
    rtol : float
        Quadrature tolerance, in [1e-12, 1e-2], relative to :func:`plane_fraction`: every entry is
        within ``rtol × plane_fraction(convention)`` of the exact footprint average.

    Returns
    -------
    ndarray, shape (n_rows * n_cols, n_sites)
        ``C[p, s]``: fraction of site ``s``'s emitted photons landing on pixel ``p``'s diode.
        Pixel photons per window are ``C @ source.photons(edges)``.

    Notes
    -----
    The tolerance is checked, not assumed: the node count per dimension doubles from 4 until two
    successive levels agree within it (the finer one is returned; Gauss–Legendre converges
    geometrically for this analytic integrand). A point source needs no quadrature, nor does a
    footprint below ``√rtol × height_um`` (:func:`point_below`).
    Offsets within :data:`OFFSET_QUANTUM_UM` and their mirror images share one evaluation.
    """
    rows, cols, _ = _check_grid(n_rows, n_cols, pitch_um, diode_w_um, diode_h_um)
    sx, sy = _sites(site_x_um, site_y_um)
    u = _checks.scalar("height_um", height_um, minimum=0.0, strict=True)
    check_convention(convention)
    tol = _checks.scalar("rtol", rtol, minimum=0.0, strict=True)
    if not 1e-12 <= tol <= 1e-2:
        raise ValueError(f"rtol = {tol!r} is out of range: must be in [1e-12, 1e-2]")
    shape, size = point_below(*_footprint(site_radius_um, site_side_um), u, tol)
    px, py = pixel_centers_um(rows, cols, pitch_um)
    dx = np.abs(px[:, None] - sx[None, :]).ravel()
    dy = np.abs(py[:, None] - sy[None, :]).ravel()
    first, inverse = distinct_offsets(dx, dy)
    values = _converged_average(dx[first], dy[first], 0.5 * diode_w_um, 0.5 * diode_h_um, u,
                                convention, shape, size, tol)
    return values[inverse].reshape(rows * cols, sx.size)


# --- the na2 level ------------------------------------------------------------------------------


def diode_collection_efficiency(
    *, diode_w_um: float, diode_h_um: float, height_um: float, convention: str,
    aperture: str = "rectangle",
) -> float:
    """Collection efficiency of one photodiode for a point source centred above it.

    Parameters
    ----------
    diode_w_um, diode_h_um : float
        Photodiode size, > 0. Unit: µm.
    height_um : float
        Source height above the diode, > 0. Unit: µm.
    convention : str
        ``"lambertian_na2"`` or ``"isotropic"``.
    aperture : str
        ``"rectangle"`` (default): the exact diode rectangle, equal to the centred point-source
        diagonal of :func:`coupling_psf`, so ``na2`` and ``psf`` differ only by spread and
        footprint. ``"inscribed_disc"``: a disc of diameter ``min(w, h)``, the paper's
        convention (91.7 % for a 100 µm diode at 15 µm, Lambertian). ``"equal_area_disc"``: a disc
        of the diode's area.

    Returns
    -------
    float
        Fraction of the emitted photons collected.
    """
    w = _checks.scalar("diode_w_um", diode_w_um, minimum=0.0, strict=True)
    h = _checks.scalar("diode_h_um", diode_h_um, minimum=0.0, strict=True)
    u = _checks.scalar("height_um", height_um, minimum=0.0, strict=True)
    check_convention(convention)
    if aperture == "rectangle":
        return float(_rectangle(-w / 2, w / 2, -h / 2, h / 2, u, convention))
    if aperture == "inscribed_disc":
        return float(collection_efficiency(min(w, h), u, convention=convention))
    if aperture == "equal_area_disc":
        return float(collection_efficiency(2.0 * np.sqrt(w * h / np.pi), u, convention=convention))
    allowed = ", ".join(repr(a) for a in APERTURES)
    raise ValueError(f"aperture = {aperture!r} is unknown: must be one of {allowed}")


def coupling_na2(
    *,
    n_rows: int,
    n_cols: int,
    pitch_um: float,
    diode_w_um: float,
    diode_h_um: float,
    site_x_um: ArrayLike,
    site_y_um: ArrayLike,
    height_um: float,
    convention: str,
    aperture: str = "rectangle",
) -> NDArray[np.float64]:
    """Site-to-pixel coupling without spread (the ``na2`` optics level).

    Parameters
    ----------
    n_rows, n_cols, pitch_um, diode_w_um, diode_h_um, site_x_um, site_y_um, height_um, convention
        As in :func:`coupling_psf`; every site must lie over the array,
        ``0 <= x < n_cols·pitch`` and ``0 <= y < n_rows·pitch``.
    aperture : str
        As in :func:`diode_collection_efficiency`.

    Returns
    -------
    ndarray, shape (n_rows * n_cols, n_sites)
        One non-zero per column: the pixel whose pitch cell holds the site gets the efficiency of
        a point source centred over its diode (Salama et al. 2004, Sec. 3: efficiency ∝ NA²). The
        site's position inside the cell and its footprint are ignored, as is cross-talk.
    """
    rows, cols, pitch = _check_grid(n_rows, n_cols, pitch_um, diode_w_um, diode_h_um)
    sx, sy = _sites(site_x_um, site_y_um)
    for name, v, extent in (("site_x_um", sx, cols * pitch), ("site_y_um", sy, rows * pitch)):
        outside = (v < 0) | (v >= extent)
        if outside.any():
            i = int(np.argmax(outside))
            raise ValueError(f"{name}[{i}] = {float(v[i])!r} is outside the pixel array: must be "
                             f"in [0, {extent!r}) for the na2 level (no pixel under the site)")
    eff = diode_collection_efficiency(diode_w_um=diode_w_um, diode_h_um=diode_h_um,
                                      height_um=height_um, convention=convention,
                                      aperture=aperture)
    pixel = (sy // pitch).astype(np.int64) * cols + (sx // pitch).astype(np.int64)
    out = np.zeros((rows * cols, sx.size))
    out[pixel, np.arange(sx.size)] = eff
    return out
