"""numba kernels of the radial profile (:mod:`chiptwin.optics.profile`) and of the stack psf's
corner integral (:mod:`chiptwin.optics.stack_psf`).

The profile is its table: ``rho`` (increasing from 0), ``cum`` (``P`` at the nodes), ``dens``
(``dP/dρ``), ``total`` (``P(∞)``) and ``bounded``; between nodes ``P`` is the cubic Hermite
interpolant, beyond the last node ``total`` (bounded) or ``total − (total − cum_last)(ρ_last/ρ)²``.

NumPy did the same arithmetic in whole-array passes: ≈ 20 temporaries over millions of
evaluations for one faceplate coupling. Here each value is one pass through registers; the
Hermite formula is written in NumPy's order, so ``P`` itself is the same to the bit (the sums of
the corner integral run in another order: ≤ a few ulp).
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT

#: Steps of the guide per table node.
GUIDE_PER_NODE = 4


def guide(rho: np.ndarray) -> tuple[np.ndarray, float]:
    """An index into the table: ``k`` of the node at or below ``ρ`` is found from
    ``g = ρ/(ρ + scale)`` in one step and a short scan. The table's nodes are uniform in the
    angle, and ``g`` spreads them about evenly over ``[0, 1)`` (near the foot ``ρ ∝ θ``, towards
    grazing ``1 − g ∝ π/2 − θ``), so ``4 × nodes`` equal steps of ``g`` hold about one node each.
    Bisecting the 4,096 nodes took ≈ 80 ns a value here (12 dependent loads); with the guide a
    whole value of ``P`` takes ≈ 21 ns."""
    scale = float(rho[rho.size // 2])
    g = np.arange(GUIDE_PER_NODE * rho.size) / (GUIDE_PER_NODE * rho.size)
    k = np.searchsorted(rho, scale * g / (1.0 - g), side="right") - 1
    return np.clip(k, 0, rho.size - 2), scale



@NJIT
def evaluate(rho, cum, dens, total, bounded, index, scale, r, out_p, out_d):
    """``out_p[i] = P(r[i])`` and, when ``out_d`` is not empty, ``out_d[i] = dP/dr`` of the
    interpolant (0 at ``r ≤ 0`` and from the last node on) (flat arrays; ``index, scale``:
    :func:`guide` of ``rho``).

    One loop, no helper taking the arrays: numba counts references to every array passed to a
    function at each call, inlined or not, which cost 3× the arithmetic here (74 ns against 21 ns
    a value of ``P``, measured)."""
    last = rho.size - 1
    with_d = out_d.size > 0
    for i in range(r.size):
        x = r[i]
        if x <= 0.0:
            out_p[i] = 0.0
            if with_d:
                out_d[i] = 0.0
        elif x >= rho[last]:
            q = rho[last] / x
            out_p[i] = total if bounded else total - (total - cum[last]) * (q * q)
            if with_d:
                out_d[i] = 0.0
        else:
            k = index[int(x / (x + scale) * index.size)]  # then rho[k] ≤ x < rho[k + 1]:
            while k > 0 and rho[k] > x:
                k -= 1
            while rho[k + 1] <= x:  # stops at last − 1 at the latest, as x < rho[last]
                k += 1
            h = rho[k + 1] - rho[k]
            s = (x - rho[k]) / h
            s2, s3 = s * s, s * s * s
            out_p[i] = ((2 * s3 - 3 * s2 + 1) * cum[k] + (s3 - 2 * s2 + s) * h * dens[k]
                        + (3 * s2 - 2 * s3) * cum[k + 1] + (s3 - s2) * h * dens[k + 1])
            if with_d:
                out_d[i] = ((6 * s2 - 6 * s) / h * cum[k] + (3 * s2 - 4 * s + 1) * dens[k]
                            + (6 * s - 6 * s2) / h * cum[k + 1] + (3 * s2 - 2 * s) * dens[k + 1])


@NJIT
def corner_h(rho, cum, dens, total, bounded, index, scale, x, y, gl_x, gl_w, out):
    """``out[i] = H(x[i], y[i]) = ∫₀^{asinh(y/x)} P(x cosh w)/cosh w dw`` for ``x, y > 0``: the
    Gauss–Legendre rule ``(gl_x, gl_w)`` on each of two panels split at the profile's outer edge
    when it is bounded (a kink of ``P``), as :func:`chiptwin.optics.stack_psf._h` states it. A
    point's ``2n`` radii go through :func:`evaluate` in one call."""
    n = gl_x.size
    edge = rho[rho.size - 1]
    r, cosh, weight, p = np.empty(2 * n), np.empty(2 * n), np.empty(2 * n), np.empty(2 * n)
    no_d = np.empty(0)
    for i in range(x.size):
        w_max = math.asinh(y[i] / x[i])
        w_edge = min(math.acosh(max(edge / x[i], 1.0)), w_max) if bounded else w_max
        for panel in range(2):
            lo, hi = (0.0, w_edge) if panel == 0 else (w_edge, w_max)
            mid, half = 0.5 * (hi + lo), 0.5 * (hi - lo)
            for j in range(n):
                m = panel * n + j
                cosh[m] = math.cosh(mid + half * gl_x[j])
                r[m] = x[i] * cosh[m]
                weight[m] = half * gl_w[j]
        evaluate(rho, cum, dens, total, bounded, index, scale, r, p, no_d)
        acc = 0.0
        for m in range(2 * n):
            acc += p[m] / cosh[m] * weight[m]
        out[i] = acc
