"""Closed-form assays as light sources: one :class:`PulseTrain`, one pulse per site (and flow).

Each builder takes per-site amounts of reactant (mol, ``V·[X]``) and start times and returns the
light of the matching equation of Salama et al. 2004 (:mod:`chiptwin.kinetics.closed_form`) as a
:class:`~chiptwin.kinetics.pulse_train.PulseTrain`. Scalar parameters apply to every site; arrays
give one value per site.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.constants import N_A
from chiptwin.kinetics.closed_form import (
    ALPHA_SELIGER_MCELROY,
    ATP_TURNOVER_GLOW_PER_S,
    PYRO_APYRASE_PER_S,
    PYRO_TURNOVER_PER_S,
    pyrosequencing_amplitude,
)
from chiptwin.kinetics.pulse_train import PulseTrain


def _train(amplitude, decay, start_s, n_sites: int) -> PulseTrain:
    """One pulse per site with the given (broadcast) amplitude, decay and start."""
    return PulseTrain(
        site=np.arange(n_sites),
        onset_s=_checks.scalar_or_matching("start_s", start_s, n_sites),
        amplitude_per_s=np.broadcast_to(amplitude, (n_sites,)),
        decay_per_s=np.broadcast_to(decay, (n_sites,)),
        n_sites=n_sites,
    )


def _amounts(name: str, value: ArrayLike) -> NDArray[np.float64]:
    arr = _checks.nonnegative(name, value)
    if arr.ndim != 1:
        raise ValueError(f"{name} has shape {arr.shape}: must be 1-D, one amount per site")
    return arr


def _per_site(name: str, value: ArrayLike, n: int, *, strict: bool = False) -> NDArray[np.float64]:
    """Scalar or ``(n,)`` per-site parameter, ``>= 0`` (``> 0`` when ``strict``)."""
    (_checks.positive if strict else _checks.nonnegative)(name, value)
    return _checks.scalar_or_matching(name, value, n)


def atp_assay(
    atp_mol: ArrayLike,
    start_s: ArrayLike = 0.0,
    *,
    turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> PulseTrain:
    """ATP assay light per site (paper eq. 12) as a :class:`PulseTrain`.

    Parameters
    ----------
    atp_mol : array_like, shape (n_sites,)
        Amount of ATP per site ``V·[ATP0]``, >= 0. Unit: mol.
    start_s : array_like
        Mixing time, scalar or per site. Unit: s.
    turnover_per_s : array_like
        k_t, scalar or per site, > 0: 0.1 glow … 1 flash. Unit: 1/s.
    alpha : float
        Quantum yield in [0, 1].
    """
    a = _amounts("atp_mol", atp_mol)
    k = _per_site("turnover_per_s", turnover_per_s, a.size, strict=True)
    return _train(N_A * _checks.quantum_yield("alpha", alpha) * k * a, k, start_s, a.size)


def luciferase_label(
    luciferase_mol: ArrayLike,
    start_s: ArrayLike = 0.0,
    *,
    turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> PulseTrain:
    """Luciferase-label light per site (paper eq. 13, a constant glow) as a :class:`PulseTrain`.

    Parameters
    ----------
    luciferase_mol : array_like, shape (n_sites,)
        Amount of label per site ``V·[E0]``, >= 0. Unit: mol.
    start_s : array_like
        Time the substrate is added, scalar or per site. Unit: s.
    turnover_per_s : array_like
        k_t, scalar or per site, >= 0. Unit: 1/s.
    alpha : float
        Quantum yield in [0, 1].
    """
    e = _amounts("luciferase_mol", luciferase_mol)
    k = _per_site("turnover_per_s", turnover_per_s, e.size)
    return _train(N_A * _checks.quantum_yield("alpha", alpha) * k * e, 0.0, start_s, e.size)


def substrate_detection(
    substrate_mol: ArrayLike,
    start_s: ArrayLike = 0.0,
    *,
    k_f_per_M_per_s: ArrayLike,
    enzyme_M: ArrayLike,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> PulseTrain:
    """Substrate-detection light per site (paper eq. 5) as a :class:`PulseTrain`.

    Parameters
    ----------
    substrate_mol : array_like, shape (n_sites,)
        Amount of substrate per site ``V·[S0]``, >= 0. Unit: mol.
    start_s : array_like
        Mixing time, scalar or per site. Unit: s.
    k_f_per_M_per_s : array_like
        Forward rate constant, scalar or per site, >= 0. Unit: 1/(M·s).
    enzyme_M : array_like
        Enzyme concentration, scalar or per site, >= 0. Unit: M.
    alpha : float
        Quantum yield in [0, 1].
    """
    s = _amounts("substrate_mol", substrate_mol)
    k = _per_site("k_f_per_M_per_s", k_f_per_M_per_s, s.size) * _per_site(
        "enzyme_M", enzyme_M, s.size)
    return _train(N_A * _checks.quantum_yield("alpha", alpha) * k * s, k, start_s, s.size)


def catalyst_detection(
    enzyme_mol: ArrayLike,
    start_s: ArrayLike = 0.0,
    *,
    k_f_per_M_per_s: ArrayLike,
    substrate_max_M: ArrayLike,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> PulseTrain:
    """Catalyst-detection light per site (paper eq. 7, a constant glow) as a :class:`PulseTrain`.

    Parameters
    ----------
    enzyme_mol : array_like, shape (n_sites,)
        Amount of enzyme per site ``V·[E]``, >= 0. Unit: mol.
    start_s : array_like
        Time the substrate is added, scalar or per site. Unit: s.
    k_f_per_M_per_s : array_like
        Forward rate constant, scalar or per site, >= 0. Unit: 1/(M·s).
    substrate_max_M : array_like
        Substrate concentration, scalar or per site, >= 0. Unit: M.
    alpha : float
        Quantum yield in [0, 1].
    """
    e = _amounts("enzyme_mol", enzyme_mol)
    k = _per_site("k_f_per_M_per_s", k_f_per_M_per_s, e.size) * _per_site(
        "substrate_max_M", substrate_max_M, e.size)
    return _train(N_A * _checks.quantum_yield("alpha", alpha) * k * e, 0.0, start_s, e.size)


def pyrosequencing(
    dna_mol: ArrayLike,
    n_incorporated: ArrayLike,
    flow_period_s: float,
    *,
    start_s: ArrayLike = 0.0,
    turnover_per_s: float = PYRO_TURNOVER_PER_S,
    apyrase_per_s: float = PYRO_APYRASE_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
    photons_per_incorporation: float | None = None,
) -> PulseTrain:
    """Pyrosequencing light per site and flow (paper eq. 19, generalised) as a :class:`PulseTrain`.

    Parameters
    ----------
    dna_mol : array_like, shape (n_sites,)
        Amount of primed template per site ``V·[DNA]``, >= 0. Unit: mol.
    n_incorporated : array_like, shape (n_flows,) or (n_sites, n_flows)
        Bases incorporated per strand in each flow, >= 0 (see
        :func:`chiptwin.kinetics.pyro.flow_incorporations`); 1-D applies to every site.
    flow_period_s : float
        Time between dispensations, > 0: flow ``k`` starts at ``start_s + k · flow_period_s``.
        Unit: s.
    start_s : array_like
        First dispensation, scalar or per site. Unit: s.
    turnover_per_s, apyrase_per_s, alpha, photons_per_incorporation
        As in :func:`pyrosequencing_rate`.

    Returns
    -------
    PulseTrain
        One pulse per (site, flow) with ``n > 0`` and DNA present: amplitude ``n N_DNA α k_t``
        (or ``n N_DNA Y k_a`` with a measured yield Y), decay ``k_a``. Flows that extend nothing
        emit nothing (no pulse).

    Notes
    -----
    Paper eqs. 18–19. Light of a flow that has not decayed by the next dispensation overlaps it,
    as it would on the chip: choose ``flow_period_s`` several ``1/k_a`` long.
    """
    dna = _amounts("dna_mol", dna_mol)
    n = _checks.nonnegative("n_incorporated", n_incorporated)
    if n.ndim == 1:
        n = np.broadcast_to(n, (dna.size, n.size))
    if n.ndim != 2 or n.shape[0] != dna.size:
        raise ValueError(f"n_incorporated has shape {n.shape}: must be (n_flows,) or "
                         f"(n_sites, n_flows) with n_sites = {dna.size}")
    period = _checks.scalar("flow_period_s", flow_period_s, minimum=0.0, strict=True)
    start = _checks.scalar_or_matching("start_s", start_s, dna.size)
    _checks.scalar("turnover_per_s", turnover_per_s, minimum=0.0, strict=False)
    _checks.scalar("apyrase_per_s", apyrase_per_s, minimum=0.0, strict=True)
    if photons_per_incorporation is not None:
        _checks.scalar("photons_per_incorporation", photons_per_incorporation, minimum=0.0,
                       strict=False)
    amplitude, k_a = pyrosequencing_amplitude(dna[:, None], n, turnover_per_s, apyrase_per_s,
                                              alpha, photons_per_incorporation)
    site, flow = np.nonzero(amplitude > 0)
    return PulseTrain(
        site=site,
        onset_s=start[site] + flow * period,
        amplitude_per_s=amplitude[site, flow],
        decay_per_s=np.full(site.size, float(k_a)),
        n_sites=dna.size,
    )
