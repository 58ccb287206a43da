"""High-precision reference for the cascade's linear regime (validation oracle, not a model level).

When every substrate is far below its K_m, the nucleotide is not consumed (no apyrase on dNTP,
``dntp_M`` ≫ template) and luciferin and APS are in excess, one single-base incorporation is the
linear system (states: unextended strands D, PPi, ATP, light-path turnovers Q)::

    D'   = −k_p D
    PPi' =  k_p D − k_s PPi + k_t ATP
    ATP' =  k_s PPi − (k_t + k_a) ATP
    Q'   =  (1 − f) k_t ATP

solved here exactly, ``y(t) = V e^{Λt} V⁻¹ y(0)``, with ``mpmath`` at 50 significant digits (no
underflow: ``e^{−10⁴}`` is an ordinary number there). :func:`linear_rates_of` reads k_p, k_s, k_t,
k_a off a :class:`~chiptwin.kinetics.cascade_params.CascadeParams` directly from the Michaelis–
Menten formulas (independently of the kernels), including the apyrase competition of the
dispensed nucleotide. Used by ``tests/kinetics/test_hard_cases.py`` and
``benchmarks/bench_cascade.py``; needs ``mpmath`` (a test dependency), imported on call.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.constants import N_A
from chiptwin.kinetics.cascade_params import CascadeParams


def linear_rates_of(params: CascadeParams, dna_M: float) -> dict[str, float]:
    """First-order constants of one incorporation in the linear regime (1/s).

    ``k_p = k_pol θ c / (K_d + c)`` with ``c = dntp_M`` and θ the exact polymerase-bound share;
    ``k_a`` includes the dispensed nucleotide occupying apyrase, ``1 / (1 + c / K_A(dNTP))``.
    """
    p = params
    s = p.polymerase_M + dna_M + p.polymerase_kd_dna_M
    theta = 2.0 * p.polymerase_M / (s + np.sqrt(max(s * s - 4 * p.polymerase_M * dna_M, 0.0)))
    c = p.dntp_M
    occupied = 1.0 + c / p.apyrase_km_dntp_M
    return {
        "k_p": p.polymerase_kpol_per_s * theta * c / (p.polymerase_kd_dntp_M + c),
        "k_s": p.sulfurylase_kcat_per_s * p.sulfurylase_M / p.sulfurylase_km_ppi_M
        * p.aps_M / (p.sulfurylase_km_aps_M + p.aps_M),
        "k_t": p.luciferase_kcat_per_s * p.luciferase_M / p.luciferase_km_atp_M
        * p.luciferin_M / (p.luciferase_km_luciferin_M + p.luciferin_M),
        "k_a": p.apyrase_kcat_atp_per_s * p.apyrase_M / p.apyrase_km_atp_M / occupied,
    }


def linear_photons(
    t_edges_s: ArrayLike,
    dna_M: float,
    k_p: float,
    k_s: float,
    k_t: float,
    k_a: float,
    photons_per_M: float,
    light_share: float = 1.0,
    dps: int = 50,
) -> NDArray[np.float64]:
    """Photons in each window after one incorporation at t = 0, exact (mpmath).

    Parameters
    ----------
    t_edges_s : array_like, shape (n + 1,)
        Window edges, >= 0, non-decreasing. Unit: s.
    dna_M : float
        Template concentration. Unit: M.
    k_p, k_s, k_t, k_a : float
        Polymerase, sulfurylase, luciferase and apyrase first-order rates, distinct enough for
        the eigen-decomposition (k_p ≠ the PPi–ATP eigenvalues). Unit: 1/s.
    photons_per_M : float
        ``α N_A V``: photons per M of light-path turnovers.
    light_share : float
        ``1 − f_LAMP``.
    dps : int
        Decimal digits of the computation.

    Returns
    -------
    ndarray, shape (n,). Unit: photons.
    """
    import mpmath  # a test dependency, needed only here

    with mpmath.workdps(dps):
        q = [_turnovers(mpmath, float(t), dna_M, k_p, k_s, k_t, k_a) for t in
             np.asarray(t_edges_s, dtype=np.float64)]
        scale = mpmath.mpf(photons_per_M) * mpmath.mpf(light_share)
        return np.array([float(scale * (b - a)) for a, b in zip(q[:-1], q[1:], strict=True)])


def linear_rate(t_s: ArrayLike, dna_M: float, k_p: float, k_s: float, k_t: float, k_a: float,
                photons_per_M: float, light_share: float = 1.0,
                dps: int = 50) -> NDArray[np.float64]:
    """Photon rate ``photons_per_M · (1 − f) k_t ATP(t)`` of the linear system. Unit: photons/s."""
    import mpmath

    with mpmath.workdps(dps):
        out = []
        for t in np.asarray(t_s, dtype=np.float64):
            y = _solve(mpmath, float(t), dna_M, k_p, k_s, k_t, k_a)
            out.append(float(mpmath.mpf(photons_per_M) * light_share * k_t * y[2]))
        return np.array(out)


def _solve(mp, t: float, dna_M: float, k_p: float, k_s: float, k_t: float, k_a: float):
    """State (D, PPi, ATP, Q) at ``t`` as mpmath numbers: ``V e^{Λt} V⁻¹ y0``."""
    kp, ks, kt, ka = (mp.mpf(k) for k in (k_p, k_s, k_t, k_a))
    a = mp.matrix([[-kp, 0, 0, 0], [kp, -ks, kt, 0], [0, ks, -(kt + ka), 0], [0, 0, kt, 0]])
    lam, vec = mp.eig(a)
    coef = mp.lu_solve(vec, mp.matrix([mp.mpf(dna_M), 0, 0, 0]))
    tt = mp.mpf(t)
    return [mp.re(sum(vec[i, j] * coef[j] * mp.exp(lam[j] * tt) for j in range(4)))
            for i in range(4)]


def _turnovers(mp, t, dna_M, k_p, k_s, k_t, k_a):
    return _solve(mp, t, dna_M, k_p, k_s, k_t, k_a)[3]


def photons_per_M(params: CascadeParams) -> float:
    """``α N_A V``: photons per M of light-path luciferase turnovers."""
    return params.alpha * N_A * params.volume_L
