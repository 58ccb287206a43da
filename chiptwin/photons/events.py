"""Photon statistics levels ``binned`` and ``events``: counts per window, or exact arrival times.

A pixel's photon arrivals form an inhomogeneous Poisson process with rate
``r_p(t) = Σ_s C[p, s] r_s(t)`` (photons/s), ``r_s`` a
:class:`~chiptwin.kinetics.light_source.LightSource`'s rate and ``C`` the coupling (optics: the
share of a site's photons reaching the pixel, possibly times QE). Its integrated rate
``Λ_p(t) = ∫ r_p`` is known exactly at any window edge (``source.photons``).

* ``binned`` (:func:`binned`): Poisson counts of the exact window integrals.
* ``events`` (:func:`arrival_times`): arrival times by time rescaling. The window
  ``[t_start, t_stop]`` is cut into cells; on each cell ``Λ_p`` is represented by the cubic
  Hermite interpolant that matches the exact cell integral and the rate at both ends, cells being
  bisected until the interpolant's error at the cell midpoint is below ``rel_tol`` of the cell's
  count (and it is monotone). The count of each cell is drawn as Poisson(exact cell integral);
  the times inside a cell are sorted uniforms mapped through the interpolant's inverse (bracketed
  Newton, in numba). Counts in any union of cells — the caller's windows are always cell
  boundaries — are therefore exactly Poisson with the exact mean; times inside a cell carry the
  interpolation error (``PhotonEvents.cdf_rel_error``).

Randomness only from the ``rng`` passed in. The chip model's ``events`` level does not draw the
arrivals: it needs only each site pixel's count and the time its well filled, whose joint law
it draws from the count and an order statistic (:class:`chiptwin.twin.stages.EventPixels`,
tested against :func:`arrival_times` and :func:`saturation_time`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.kinetics.light_source import LightSource
from chiptwin.photons import _kernels

MAX_EVENTS: int = 20_000_000
"""Default cap on the expected number of photons :func:`arrival_times` will draw (memory: 16 bytes
per photon while drawing)."""

_ABS_TOL = 1e-12  # expected-count error below which a cell needs no refinement
_MAX_ROUNDS = 48
_INITIAL_CELLS = 64


@dataclass(frozen=True, eq=False)
class PhotonEvents:
    """Photon arrival times of several pixels on one window.

    Attributes
    ----------
    times_s : ndarray, shape (n_events,)
        All arrival times, pixel after pixel, each pixel's sorted. Unit: s.
    offsets : ndarray of int64, shape (n_pixels + 1,)
        Pixel ``p``'s times are ``times_s[offsets[p]:offsets[p + 1]]``.
    t_start_s, t_stop_s : float
        The window. Unit: s.
    expected : ndarray, shape (n_pixels,)
        The exact integrated rate over the window (mean count). Unit: photons.
    n_cells : int
        Cells of the piecewise-cubic cumulative.
    cdf_rel_error : float
        Largest midpoint error of the cumulative over a cell, relative to the cell's count: the
        timing accuracy inside cells.
    """

    times_s: NDArray[np.float64]
    offsets: NDArray[np.int64]
    t_start_s: float
    t_stop_s: float
    expected: NDArray[np.float64]
    n_cells: int
    cdf_rel_error: float

    @property
    def n_pixels(self) -> int:
        """Number of pixels."""
        return int(self.offsets.size - 1)

    def pixel(self, p: int) -> NDArray[np.float64]:
        """Sorted arrival times of pixel ``p`` (a view). Unit: s."""
        return self.times_s[self.offsets[p]:self.offsets[p + 1]]

    def counts(self, t_edges_s: ArrayLike) -> NDArray[np.int64]:
        """Events per pixel in each window ``[t_i, t_{i+1})``: shape (n_pixels, n_windows)."""
        return counts_from_events(self, t_edges_s)


# --- the integrated rate of each pixel ---------------------------------------------------------


def _weights(weights: ArrayLike | None, n_sites: int) -> NDArray[np.float64]:
    if weights is None:
        return np.eye(n_sites)
    w = _checks.nonnegative("weights", weights)
    if w.ndim != 2 or w.shape[1] != n_sites:
        raise ValueError(f"weights has shape {w.shape}: must be (n_pixels, {n_sites})")
    return w


def _edges(name: str, value: ArrayLike) -> NDArray[np.float64]:
    edges = _checks.as_float_array(name, value)
    if edges.ndim != 1 or edges.size < 2 or (np.diff(edges) < 0).any():
        raise ValueError(f"{name} must be 1-D, non-decreasing, with >= 2 edges")
    return edges


def expected_counts(source: LightSource, t_edges_s: ArrayLike,
                    weights: ArrayLike | None = None) -> NDArray[np.float64]:
    """Mean photons per pixel and window: ``C @ source.photons(edges)``.

    Parameters
    ----------
    source : LightSource
        Light per site (photons into 4π, or any photons the weights turn into pixel photons).
    t_edges_s : array_like, shape (n_windows + 1,)
        Window edges, non-decreasing. Unit: s.
    weights : array_like, shape (n_pixels, n_sites), optional
        Coupling ``C`` (>= 0); default identity (one pixel per site).

    Returns
    -------
    ndarray, shape (n_pixels, n_windows). Unit: photons.
    """
    w = _weights(weights, source.n_sites)
    return w @ source.photons(_edges("t_edges_s", t_edges_s))


def binned(source: LightSource, t_edges_s: ArrayLike, rng: np.random.Generator,
           weights: ArrayLike | None = None) -> NDArray[np.int64]:
    """Photon counts per pixel and window: Poisson of the exact window integrals (level ``binned``).

    Arguments as :func:`expected_counts`; ``rng`` draws the counts.

    Returns
    -------
    ndarray of int64, shape (n_pixels, n_windows). Unit: photons.
    """
    return rng.poisson(expected_counts(source, t_edges_s, weights)).astype(np.int64)


# --- the piecewise-cubic cumulative -------------------------------------------------------------


def _breakpoints(source: LightSource, t0: float, t1: float) -> NDArray[np.float64]:
    """Times where the source's rate may jump (onsets, dispensations) inside ``(t0, t1)``."""
    pts = getattr(source, "breakpoints_s", None)
    if pts is None:
        pts = getattr(source, "onset_s", np.zeros(0))
    pts = np.asarray(pts, dtype=np.float64)
    return pts[(pts > t0) & (pts < t1)]


def _left_limit(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """The float just below each time: evaluates the rate's left limit at a jump."""
    return np.nextafter(t, -np.inf)


@dataclass
class _Cells:
    """Cells ``[edges[c], edges[c+1]]`` with per-pixel area and end rates."""

    edges: NDArray[np.float64]
    area: NDArray[np.float64]
    r_left: NDArray[np.float64]
    r_right: NDArray[np.float64]


def _initial_cells(source, w, t0, t1, extra) -> _Cells:
    grid = np.unique(np.concatenate([np.linspace(t0, t1, _INITIAL_CELLS + 1),
                                     _breakpoints(source, t0, t1), extra]))
    area = np.maximum(w @ source.photons(grid), 0.0)
    return _Cells(grid, area, w @ source.rate(grid[:-1]), w @ source.rate(_left_limit(grid[1:])))


def _refine(source, w, cells: _Cells, rel_tol: float) -> tuple[_Cells, float]:
    """Bisect cells until the Hermite cumulative is monotone and its midpoint error is within
    ``rel_tol`` of the cell's count (or the cell cannot be split further in floating point).

    Returns the cells and the worst relative midpoint error among cells holding more than
    ``_ABS_TOL / rel_tol`` expected photons.
    """
    todo = np.ones(cells.area.shape[1], dtype=bool)
    worst = 0.0
    for _ in range(_MAX_ROUNDS):
        idx = np.flatnonzero(todo)
        if idx.size == 0:
            break
        a, b = cells.edges[idx], cells.edges[idx + 1]
        mid = 0.5 * (a + b)
        halves = np.maximum(w @ source.photons(np.stack([a, mid, b], axis=1).reshape(-1)), 0.0)
        left, right = halves[:, 0::3], halves[:, 1::3]
        area, r_a, r_b = cells.area[:, idx], cells.r_left[:, idx], cells.r_right[:, idx]
        err = np.abs(0.5 * area + (b - a) * (r_a - r_b) / 8.0 - left)
        bad = (err > rel_tol * area + _ABS_TOL) | ~_monotone(area, b - a, r_a, r_b)
        bad &= (mid > a) & (mid < b)  # no split below floating-point resolution
        fails = bad.any(axis=0)
        counted = (area > _ABS_TOL / rel_tol) & ~fails
        worst = max(worst, float(np.max(err / np.where(counted, area, np.inf), initial=0.0)))
        if not fails.any():
            break
        r_mid = w @ source.rate(mid[fails])
        cells, todo = _split(cells, idx[fails], left[:, fails], right[:, fails], r_mid)
    return cells, worst


def _split(cells: _Cells, split: NDArray[np.int64], left, right, r_mid
           ) -> tuple[_Cells, NDArray[np.bool_]]:
    """Replace cells ``split`` by their two halves; returns the new cells and the halves' mask."""
    mids = 0.5 * (cells.edges[split] + cells.edges[split + 1])
    edges = np.insert(cells.edges, split + 1, mids)
    pos = split + np.arange(split.size)  # index of each left half in the new arrays
    area = np.insert(cells.area, split + 1, right, axis=1)
    area[:, pos] = left
    r_left = np.insert(cells.r_left, split + 1, r_mid, axis=1)
    r_right = np.insert(cells.r_right, split, r_mid, axis=1)
    todo = np.zeros(edges.size - 1, dtype=bool)
    todo[pos] = todo[pos + 1] = True
    return _Cells(edges, area, r_left, r_right), todo


def _monotone(area, h, r_left, r_right) -> NDArray[np.bool_]:
    """Fritsch–Carlson: the Hermite cumulative is non-decreasing if both end slopes are within
    [0, 3] times the cell's mean rate."""
    mean = area / h
    return (r_left <= 3.0 * mean) & (r_right <= 3.0 * mean)


def _limited_slopes(cells: _Cells) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``h r_a`` and ``h r_b`` clipped to ``[0, 3 A]`` (Fritsch–Carlson): F stays monotone and
    keeps its exact area; only cells that refinement could not resolve are changed."""
    h = np.diff(cells.edges)
    cap = 3.0 * cells.area
    return (np.clip(h * cells.r_left, 0.0, cap), np.clip(h * cells.r_right, 0.0, cap))


# --- the events level ----------------------------------------------------------------------------


def arrival_times(
    source: LightSource,
    t_start_s: float,
    t_stop_s: float,
    rng: np.random.Generator,
    weights: ArrayLike | None = None,
    *,
    t_edges_s: ArrayLike | None = None,
    rel_tol: float = 1e-9,
    max_events: int = MAX_EVENTS,
) -> PhotonEvents:
    """Exact photon arrival times on ``[t_start_s, t_stop_s]`` (photon level ``events``).

    Parameters
    ----------
    source : LightSource
        Light per site.
    t_start_s, t_stop_s : float
        The window, ``t_start_s <= t_stop_s``. Unit: s.
    rng : numpy.random.Generator
        Draws the counts and the uniforms (in that order).
    weights : array_like, shape (n_pixels, n_sites), optional
        Coupling ``C`` (>= 0): pixel rate ``Σ_s C[p, s] r_s(t)``. Default identity.
    t_edges_s : array_like, optional
        Window edges the events will be counted in: made cell boundaries, so those counts are
        exactly Poisson(exact integral). Edges outside the window are ignored.
    rel_tol : float
        Tolerance of the cumulative's midpoint error per cell, relative to the cell's count,
        in (0, 1e-2].
    max_events : int
        Refuse windows whose expected total exceeds this (use :func:`binned` there).

    Returns
    -------
    PhotonEvents
    """
    t0 = _checks.scalar("t_start_s", t_start_s, minimum=-np.inf, strict=False)
    t1 = _checks.scalar("t_stop_s", t_stop_s, minimum=t0, strict=False)
    tol = _checks.scalar("rel_tol", rel_tol, minimum=0.0, strict=True)
    if tol > 1e-2:
        raise ValueError(f"rel_tol = {tol!r} is out of range: must be in (0, 0.01]")
    w = _weights(weights, source.n_sites)
    if t1 == t0:
        return PhotonEvents(np.zeros(0), np.zeros(w.shape[0] + 1, dtype=np.int64), t0, t1,
                            np.zeros(w.shape[0]), 0, 0.0)
    extra = np.zeros(0) if t_edges_s is None else _checks.as_float_array("t_edges_s", t_edges_s)
    extra = extra[(extra > t0) & (extra < t1)]
    rows, inverse = np.unique(w, axis=0, return_inverse=True)  # equal pixels share their cells
    cells, worst = _refine(source, rows, _initial_cells(source, rows, t0, t1, extra), tol)
    inverse = inverse.reshape(-1)
    cells = _Cells(cells.edges, cells.area[inverse], cells.r_left[inverse],
                   cells.r_right[inverse])
    expected = cells.area.sum(axis=1)
    if expected.sum() > max_events:
        raise ValueError(f"the window holds {expected.sum():.3g} expected photons, more than "
                         f"max_events = {max_events}: use the binned level (or fewer pixels, a "
                         "shorter window, or a larger max_events)")
    counts = rng.poisson(cells.area).astype(np.int64)
    uniforms = rng.random(int(counts.sum()))
    offsets = np.concatenate([[0], np.cumsum(counts.sum(axis=1))]).astype(np.int64)
    h_ra, h_rb = _limited_slopes(cells)
    times = np.empty(int(offsets[-1]))
    _kernels.sample_cells(cells.edges, cells.area, h_ra, h_rb, counts, uniforms, offsets, times)
    return PhotonEvents(times, offsets, t0, t1, expected, int(cells.area.shape[1]), worst)


def counts_from_events(events: PhotonEvents | ArrayLike,
                       t_edges_s: ArrayLike) -> NDArray[np.int64]:
    """Events per window ``[t_i, t_{i+1})``.

    Parameters
    ----------
    events : PhotonEvents, or array_like of sorted times (one pixel). Unit: s.
    t_edges_s : array_like, shape (n_windows + 1,)
        Non-decreasing edges. Unit: s.

    Returns
    -------
    ndarray of int64: (n_pixels, n_windows) for PhotonEvents, (n_windows,) for one pixel.
    """
    edges = _edges("t_edges_s", t_edges_s)
    if isinstance(events, PhotonEvents):
        return np.stack([np.diff(np.searchsorted(events.pixel(p), edges, side="left"))
                         for p in range(events.n_pixels)]).reshape(events.n_pixels, -1)
    times = _checks.as_float_array("events", events)
    if times.ndim != 1 or (np.diff(times) < 0).any():
        raise ValueError("events must be PhotonEvents or a 1-D array of sorted times")
    return np.diff(np.searchsorted(times, edges, side="left")).astype(np.int64)


# --- from photons to electrons: QE thinning, dark current, full well ------------------------------


def _per_pixel(name: str, value: ArrayLike, n: int, *, hi: float | None = None) -> NDArray:
    arr = _checks.scalar_or_matching(name, value, n)
    if (arr < 0).any() or (hi is not None and (arr > hi).any()):
        bound = f"in [0, {hi:g}]" if hi is not None else ">= 0"
        raise ValueError(f"{name} = {value!r} is out of range: must be {bound}")
    return arr


def detected_electrons(events: PhotonEvents, rng: np.random.Generator, *,
                       qe: ArrayLike = 1.0, dark_e_per_s: ArrayLike = 0.0) -> PhotonEvents:
    """Photo-electron arrival times: photons thinned by QE, merged with dark-current electrons.

    Parameters
    ----------
    events : PhotonEvents
        Photon arrivals per pixel.
    rng : numpy.random.Generator
        Draws, in order: one uniform per photon (kept if ``u < qe``), the dark counts per pixel,
        one uniform per dark electron.
    qe : float or array_like (n_pixels,)
        Quantum efficiency in [0, 1]: independent thinning keeps a Poisson process Poisson.
    dark_e_per_s : float or array_like (n_pixels,)
        Dark current, >= 0: a homogeneous Poisson stream on the window. Unit: e⁻/s.

    Returns
    -------
    PhotonEvents
        Electron arrival times (sorted per pixel); ``expected`` is ``qe · photons + dark · T``.
    """
    n = events.n_pixels
    q = _per_pixel("qe", qe, n, hi=1.0)
    dark = _per_pixel("dark_e_per_s", dark_e_per_s, n)
    span = events.t_stop_s - events.t_start_s
    keep = rng.random(events.times_s.size) < np.repeat(q, np.diff(events.offsets))
    n_dark = rng.poisson(dark * span)
    dark_t = events.t_start_s + span * rng.random(int(n_dark.sum()))
    dark_off = np.concatenate([[0], np.cumsum(n_dark)])
    parts = []
    for p in range(n):
        lo, hi = events.offsets[p], events.offsets[p + 1]
        parts.append(np.sort(np.concatenate([events.times_s[lo:hi][keep[lo:hi]],
                                             dark_t[dark_off[p]:dark_off[p + 1]]])))
    sizes = np.array([x.size for x in parts], dtype=np.int64)
    return PhotonEvents(np.concatenate(parts) if parts else np.zeros(0),
                        np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                        events.t_start_s, events.t_stop_s, q * events.expected + dark * span,
                        events.n_cells, events.cdf_rel_error)


def saturation_time(events: PhotonEvents, full_well_e: float, rng: np.random.Generator, *,
                    qe: ArrayLike = 1.0, dark_e_per_s: ArrayLike = 0.0,
                    initial_e: ArrayLike = 0.0) -> NDArray[np.float64]:
    """Time each pixel's well fills: the arrival of its ``⌈full_well − initial⌉``-th electron.

    Parameters
    ----------
    events : PhotonEvents
        Photon arrivals per pixel (from :func:`arrival_times`).
    full_well_e : float
        Full-well capacity, > 0. Unit: e⁻.
    rng : numpy.random.Generator
        As :func:`detected_electrons`.
    qe, dark_e_per_s
        As :func:`detected_electrons`.
    initial_e : float or array_like (n_pixels,)
        Charge already in the well at ``t_start_s`` (>= 0). Unit: e⁻.

    Returns
    -------
    ndarray, shape (n_pixels,)
        Saturation time (s); ``t_start_s`` if already full, ``inf`` if the well does not fill
        within the window.
    """
    well = _checks.scalar("full_well_e", full_well_e, minimum=0.0, strict=True)
    start = _per_pixel("initial_e", initial_e, events.n_pixels)
    electrons = detected_electrons(events, rng, qe=qe, dark_e_per_s=dark_e_per_s)
    need = np.ceil(well - start).astype(np.int64)
    out = np.full(events.n_pixels, np.inf)
    for p in range(events.n_pixels):
        times = electrons.pixel(p)
        if need[p] <= 0:
            out[p] = events.t_start_s
        elif times.size >= need[p]:
            out[p] = times[need[p] - 1]
    return out


def saturation_time_from_rate(
    source: LightSource,
    t_start_s: float,
    t_stop_s: float,
    full_well_e: float,
    rng: np.random.Generator,
    weights: ArrayLike | None = None,
    *,
    qe: ArrayLike = 1.0,
    dark_e_per_s: ArrayLike = 0.0,
    initial_e: ArrayLike = 0.0,
    rel_tol: float = 1e-9,
) -> NDArray[np.float64]:
    """Saturation time drawn directly from the rate, without drawing every photon.

    The same distribution as :func:`saturation_time` on :func:`arrival_times`, at any light level:
    by time rescaling, the N-th arrival of a Poisson process with integrated rate Λ is
    ``Λ⁻¹(G)``, ``G ~ Gamma(N, 1)``. Here Λ is the electron count ``qe · Λ_photons + dark · t``
    (QE thinning keeps the process Poisson), represented by the same piecewise cubic as
    :func:`arrival_times`.

    Parameters
    ----------
    source, t_start_s, t_stop_s, weights, rel_tol
        As :func:`arrival_times`.
    full_well_e, qe, dark_e_per_s, initial_e
        As :func:`saturation_time`.
    rng : numpy.random.Generator
        Draws one Gamma variate per pixel that is not already full.

    Returns
    -------
    ndarray, shape (n_pixels,)
        Saturation time (s); ``t_start_s`` if already full, ``inf`` if not within the window.
    """
    t0 = _checks.scalar("t_start_s", t_start_s, minimum=-np.inf, strict=False)
    t1 = _checks.scalar("t_stop_s", t_stop_s, minimum=t0, strict=False)
    well = _checks.scalar("full_well_e", full_well_e, minimum=0.0, strict=True)
    w = _weights(weights, source.n_sites)
    n = w.shape[0]
    q = _per_pixel("qe", qe, n, hi=1.0)
    dark = _per_pixel("dark_e_per_s", dark_e_per_s, n)
    need = np.ceil(well - _per_pixel("initial_e", initial_e, n))
    out = np.where(need <= 0, t0, np.inf)
    todo = np.flatnonzero(need > 0)
    if todo.size == 0 or t1 == t0:
        return out
    g = rng.gamma(need[todo])
    cells, _ = _refine(source, w[todo] * q[todo, None], _initial_cells(
        source, w[todo] * q[todo, None], t0, t1, np.zeros(0)), rel_tol)
    h = np.diff(cells.edges)
    area = cells.area + dark[todo, None] * h
    h_ra, h_rb = _limited_slopes(_Cells(cells.edges, area, cells.r_left + dark[todo, None],
                                        cells.r_right + dark[todo, None]))
    cum = np.cumsum(area, axis=1)
    for i, p in enumerate(todo):
        c = int(np.searchsorted(cum[i], g[i]))
        if c >= h.size:
            continue
        before = cum[i, c - 1] if c > 0 else 0.0
        s = _kernels.invert_cell(g[i] - before, 0.0, area[i, c], h_ra[i, c], h_rb[i, c])
        out[p] = min(cells.edges[c] + s * h[c], cells.edges[c + 1])
    return out
