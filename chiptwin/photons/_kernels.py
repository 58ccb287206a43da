"""numba kernels of the ``events`` photon level: inverting a piecewise-cubic cumulative rate.

Arrays and scalars in, arrays out; no validation (:mod:`chiptwin.photons.events` checks once).
A slow plain-Python reference of :func:`invert_cell` lives in ``tests/photons/test_events.py``.

On a cell ``[a, a + h]`` the expected photon count since ``a`` is the cubic Hermite

    F(s) = A (3s² − 2s³) + h r_a (s − 2s² + s³) + h r_b (s³ − s²),     s = (t − a) / h ∈ [0, 1],

which matches the exact cell integral ``A = F(1)`` and the rates ``r_a``, ``r_b`` at both ends
(slopes limited beforehand so that F is non-decreasing).
"""

from __future__ import annotations

import numpy as np

from chiptwin._numba import NJIT

#: Newton iterations are stopped when the step in s falls below this (≈ 4 ulp of s ∈ [0, 1]).
_S_TOL = 1e-15


@NJIT
def cubic_cumulative(s, area, hra, hrb):  # pragma: no cover - compiled
    """``F(s)`` and ``F'(s)`` of one cell (``hra = h r_a``, ``hrb = h r_b``)."""
    s2 = s * s
    f = area * (3.0 * s2 - 2.0 * s2 * s) + hra * (s - 2.0 * s2 + s2 * s) + hrb * (s2 * s - s2)
    df = 6.0 * area * (s - s2) + hra * (1.0 - 4.0 * s + 3.0 * s2) + hrb * (3.0 * s2 - 2.0 * s)
    return f, df


@NJIT
def invert_cell(target, lo, area, hra, hrb):  # pragma: no cover - compiled
    """The ``s`` in ``[lo, 1]`` with ``F(s) = target`` (F non-decreasing, ``F(lo) <= target``).

    Newton's method kept inside a shrinking bracket ``[lo, hi]``; a step leaving the bracket (or
    a zero slope) bisects instead. Converges to ≈ 1e-15 in s.
    """
    hi = 1.0
    s = lo + (hi - lo) * 0.5
    for _ in range(200):
        f, df = cubic_cumulative(s, area, hra, hrb)
        if f < target:
            lo = s
        else:
            hi = s
        if df > 0.0:
            step = (f - target) / df
            nxt = s - step
        else:
            step, nxt = 1.0, lo - 1.0
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
            step = hi - lo
        s = nxt
        if abs(step) < _S_TOL or hi - lo < _S_TOL:
            break
    return s


@NJIT
def sample_cells(edges, area, h_ra, h_rb, counts, uniforms, offsets, out):  # pragma: no cover
    """Arrival times of every pixel, cell by cell, into ``out``.

    Shapes: ``edges`` (n_cells + 1,) increasing; ``area``, ``h_ra``, ``h_rb``, ``counts``
    (n_pixels, n_cells); ``uniforms`` (total,) in [0, 1); ``offsets`` (n_pixels + 1,), the start
    of each pixel's events in ``out``. Within a cell the uniforms are sorted, scaled by the cell's
    area and mapped through ``F⁻¹``, so each pixel's times come out sorted; every time lies in
    its cell ``[edges[c], edges[c + 1])``.
    """
    n_pix, n_cells = counts.shape
    k = 0
    for p in range(n_pix):
        pos = offsets[p]
        for c in range(n_cells):
            n = counts[p, c]
            if n == 0:
                continue
            u = np.sort(uniforms[k:k + n])
            k += n
            a, b = edges[c], edges[c + 1]
            last = np.nextafter(b, a)
            lo = 0.0
            for i in range(n):
                s = invert_cell(u[i] * area[p, c], lo, area[p, c], h_ra[p, c], h_rb[p, c])
                lo = s
                out[pos] = min(max(a + s * (b - a), a), last)
                pos += 1
