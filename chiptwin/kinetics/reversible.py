"""The general reversible mass-action reaction of the paper (eqs. 2–4), solved exactly.

``S + E ⇌ P + E`` with the enzyme E a catalyst (constant) and ``[S] + [P] = [S0] + [P0]``
conserved::

    d[P]/dt = k_f [S][E] − k_r [E][P]                       (eq. 2)
    I(t)    = α V N_A d[P]/dt                               (eq. 3)
    N(T)    = α V N_A ([P](T) − [P](0))                     (eq. 4, eq. 3 integrated)

With ``k = (k_f + k_r)[E]`` and ``[P]_eq = k_f ([S0] + [P0]) / (k_f + k_r)``::

    [P](t)  = [P]_eq + ([P0] − [P]_eq) e^{−k t}
    I(t)    = α V N_A k ([P]_eq − [P0]) e^{−k t}
    N(T)    = −α V N_A ([P]_eq − [P0]) expm1(−k T)

k_r = 0 is substrate detection, eqs. 5–6. Every function broadcasts (numpy rules), is 0 before
``t = 0``, uses ``expm1`` (no cancellation for small ``kT``) and stays finite when ``e^{−kt}``
underflows. :func:`solve_reversible` integrates eq. 2 numerically (stiff solver, analytic
Jacobian) as the check of the closed form; :func:`reversible_source` gives the light per site as a
:class:`~chiptwin.kinetics.pulse_train.PulseTrain`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from chiptwin import _checks
from chiptwin.constants import N_A
from chiptwin.kinetics.closed_form import ALPHA_SELIGER_MCELROY
from chiptwin.kinetics.pulse_train import PulseTrain

FloatOrArray = np.float64 | NDArray[np.float64]


def _constants(substrate0_M, enzyme_M, k_f_per_M_per_s, k_r_per_M_per_s, product0_M):
    """``k`` (1/s), ``[P]_eq`` and ``[P0]`` (M), checked and broadcast."""
    s0 = _checks.nonnegative("substrate0_M", substrate0_M)
    p0 = _checks.nonnegative("product0_M", product0_M)
    e = _checks.nonnegative("enzyme_M", enzyme_M)
    k_f = _checks.nonnegative("k_f_per_M_per_s", k_f_per_M_per_s)
    k_r = _checks.nonnegative("k_r_per_M_per_s", k_r_per_M_per_s)
    k_sum = k_f + k_r
    share = np.divide(k_f, k_sum, out=np.zeros(np.broadcast(k_f, k_sum).shape), where=k_sum > 0)
    return k_sum * e, share * (s0 + p0), p0 + np.zeros_like(share)


def reversible_product_M(
    t_s: ArrayLike,
    substrate0_M: ArrayLike,
    enzyme_M: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    k_r_per_M_per_s: ArrayLike,
    product0_M: ArrayLike = 0.0,
) -> FloatOrArray:
    """Product concentration ``[P](t)`` of the reversible reaction (eq. 2 solved).

    Parameters
    ----------
    t_s : array_like
        Time since mixing; ``[P0]`` before 0. Unit: s.
    substrate0_M, product0_M : array_like
        ``[S0]``, ``[P0]``, >= 0. Unit: M.
    enzyme_M : array_like
        ``[E]`` (a catalyst: constant), >= 0. Unit: M.
    k_f_per_M_per_s, k_r_per_M_per_s : array_like
        Forward and reverse rate constants, >= 0. Unit: 1/(M·s).

    Returns
    -------
    ``[P]_eq + ([P0] − [P]_eq) e^{−k t}``. Unit: M.
    """
    k, p_eq, p0 = _constants(substrate0_M, enzyme_M, k_f_per_M_per_s, k_r_per_M_per_s,
                             product0_M)
    t = np.maximum(_checks.as_float_array("t_s", t_s), 0.0)
    return (p0 + (p_eq - p0) * -np.expm1(-k * t))[()]


def reversible_rate(
    t_s: ArrayLike,
    substrate0_M: ArrayLike,
    enzyme_M: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    k_r_per_M_per_s: ArrayLike,
    volume_L: ArrayLike,
    product0_M: ArrayLike = 0.0,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photon rate of the reversible reaction, eq. 3 on eq. 2.

    Other arguments as :func:`reversible_product_M`.

    Parameters
    ----------
    volume_L : array_like
        Reaction volume, >= 0. Unit: L.
    alpha : float
        Quantum yield in [0, 1].

    Returns
    -------
    ``α V N_A k ([P]_eq − [P0]) e^{−k t}`` for ``t >= 0``, 0 before. Unit: photons/s. Negative
    when the net reaction runs backwards (``[P0] > [P]_eq``), as eq. 3 reads.
    """
    k, p_eq, p0 = _constants(substrate0_M, enzyme_M, k_f_per_M_per_s, k_r_per_M_per_s,
                             product0_M)
    t = _checks.as_float_array("t_s", t_s)
    scale = _checks.quantum_yield("alpha", alpha) * _checks.nonnegative("volume_L", volume_L) * N_A
    value = scale * k * (p_eq - p0) * np.exp(-k * np.maximum(t, 0.0))
    return np.where(t >= 0.0, value, 0.0)[()]


def reversible_photons(
    t_int_s: ArrayLike,
    substrate0_M: ArrayLike,
    enzyme_M: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    k_r_per_M_per_s: ArrayLike,
    volume_L: ArrayLike,
    product0_M: ArrayLike = 0.0,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photons emitted in ``[0, T]``, eq. 4 (arguments as :func:`reversible_rate`).

    Returns
    -------
    ``−α V N_A ([P]_eq − [P0]) expm1(−k T)``. Unit: photons.
    """
    k, p_eq, p0 = _constants(substrate0_M, enzyme_M, k_f_per_M_per_s, k_r_per_M_per_s,
                             product0_M)
    t = _checks.nonnegative("t_int_s", t_int_s)
    scale = _checks.quantum_yield("alpha", alpha) * _checks.nonnegative("volume_L", volume_L) * N_A
    return (scale * (p_eq - p0) * -np.expm1(-k * t))[()]


def solve_reversible(
    t_s: ArrayLike,
    substrate0_M: float,
    enzyme_M: float,
    k_f_per_M_per_s: float,
    k_r_per_M_per_s: float,
    product0_M: float = 0.0,
    *,
    rtol: float = 1e-10,
) -> NDArray[np.float64]:
    """``[S](t)`` and ``[P](t)`` by integrating eq. 2 numerically (Radau, analytic Jacobian).

    Parameters
    ----------
    t_s : array_like, shape (n_t,)
        Output times, >= 0, increasing. Unit: s.
    substrate0_M, enzyme_M, k_f_per_M_per_s, k_r_per_M_per_s, product0_M : float
        As :func:`reversible_product_M`, scalars.
    rtol : float
        Relative tolerance (absolute: ``rtol × ([S0] + [P0])``).

    Returns
    -------
    ndarray, shape (2, n_t)
        ``[S]`` and ``[P]``. Unit: M. The independent check of :func:`reversible_product_M`.
    """
    t = _checks.nonnegative("t_s", t_s)
    if t.ndim != 1 or (np.diff(t) <= 0).any():
        raise ValueError("t_s must be 1-D, >= 0 and strictly increasing")
    s0, p0, e = (float(_checks.nonnegative(n, v)) for n, v in
                 (("substrate0_M", substrate0_M), ("product0_M", product0_M),
                  ("enzyme_M", enzyme_M)))
    k_f, k_r = (float(_checks.nonnegative(n, v)) for n, v in
                (("k_f_per_M_per_s", k_f_per_M_per_s), ("k_r_per_M_per_s", k_r_per_M_per_s)))
    jac = np.array([[-k_f * e, k_r * e], [k_f * e, -k_r * e]])
    res = solve_ivp(lambda _t, y: jac @ y, (0.0, max(float(t[-1]), 0.0)), [s0, p0],
                    method="Radau", jac=lambda _t, _y: jac, t_eval=t, rtol=rtol,
                    atol=rtol * max(s0 + p0, 1e-300))
    if not res.success:
        raise RuntimeError(f"solve_reversible failed: {res.message}")
    return res.y


def reversible_source(
    substrate0_M: ArrayLike,
    enzyme_M: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    k_r_per_M_per_s: ArrayLike,
    volume_L: ArrayLike,
    product0_M: ArrayLike = 0.0,
    start_s: ArrayLike = 0.0,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> PulseTrain:
    """Light per site of the reversible reaction as a :class:`PulseTrain` (one pulse per site).

    Parameters
    ----------
    substrate0_M : array_like, shape (n_sites,)
        ``[S0]`` per site. Unit: M.
    enzyme_M, k_f_per_M_per_s, k_r_per_M_per_s, volume_L, product0_M, start_s : array_like
        Scalars or per site (units as :func:`reversible_rate`; ``start_s`` in s).
    alpha : float
        Quantum yield in [0, 1].

    Returns
    -------
    PulseTrain
        Amplitude ``α V N_A k ([P]_eq − [P0])``, decay ``k``. A net backward reaction
        (``[P0] > [P]_eq``) emits no light by eq. 3 and is refused.
    """
    s0 = _checks.nonnegative("substrate0_M", substrate0_M)
    if s0.ndim != 1:
        raise ValueError(f"substrate0_M has shape {s0.shape}: must be (n_sites,)")
    n = s0.size
    per_site = {name: _checks.scalar_or_matching(name, v, n) for name, v in (
        ("enzyme_M", enzyme_M), ("k_f_per_M_per_s", k_f_per_M_per_s),
        ("k_r_per_M_per_s", k_r_per_M_per_s), ("volume_L", volume_L),
        ("product0_M", product0_M), ("start_s", start_s))}
    k, p_eq, p0 = _constants(s0, per_site["enzyme_M"], per_site["k_f_per_M_per_s"],
                             per_site["k_r_per_M_per_s"], per_site["product0_M"])
    if (p0 > p_eq).any():
        i = int(np.argmax(p0 > p_eq))
        raise ValueError(f"product0_M = {float(p0[i])!r} (at site {i}) is above the equilibrium "
                         f"{float(p_eq[i])!r} M: the net reaction runs backwards, emits no light")
    scale = _checks.quantum_yield("alpha", alpha) * per_site["volume_L"] * N_A
    return PulseTrain(site=np.arange(n), onset_s=per_site["start_s"],
                      amplitude_per_s=scale * k * (p_eq - p0), decay_per_s=k, n_sites=n)
