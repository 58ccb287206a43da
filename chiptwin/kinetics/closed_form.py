"""Closed-form light generation: the equations 2–19 of Salama et al. 2004, as pure array functions.

Source: K. Salama, H. Eltoukhy, A. Hassibi, A. El Gamal, "Modeling and simulation of luminescence
detection platforms", Biosensors & Bioelectronics 19 (2004) — "the paper" below; the numbers are
tabulated in docs/background/sources.md, Kinetics.

Units: time in s, rate constants in 1/s or 1/(M·s), concentrations in M (= mol/L), amounts of
reactant in mol (``V·[X]``: volume in L times concentration in M), light in photons/s or photons,
always emitted into 4π. The paper's ``αVA`` is quantum yield × volume × Avogadro's number; here
``V·[X]`` is the amount ``*_mol`` and ``A`` is :data:`chiptwin.constants.N_A`.

Every rate function is 0 before ``t = 0`` (the moment the reagents meet) and every function
broadcasts its array arguments (numpy rules); scalar inputs give numpy scalars.

:mod:`chiptwin.kinetics.sources` turns the same equations into per-site light sources
(:class:`~chiptwin.kinetics.pulse_train.PulseTrain`), which the rest of the twin consumes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.constants import N_A

FloatOrArray = np.float64 | NDArray[np.float64]

ALPHA_SELIGER_MCELROY: float = 0.88
"""Firefly luciferase quantum yield used by the paper (Seliger & McElroy 1960; ± 0.25)."""

ALPHA_ANDO: float = 0.41
"""Firefly luciferase quantum yield measured by Ando et al., Nature Photonics 2 (2008) (± 0.074)."""

ATP_TURNOVER_GLOW_PER_S: float = 0.1
"""Luciferase turnover of a glow-type ATP reagent, the paper's eqs. 12–13. Unit: 1/s."""

ATP_TURNOVER_FLASH_PER_S: float = 1.0
"""Luciferase turnover of a flash-type ATP reagent (paper). Unit: 1/s."""

PYRO_TURNOVER_PER_S: float = 1.0
"""Pyrosequencing light-generation turnover k_t, paper eq. 19. Unit: 1/s."""

PYRO_APYRASE_PER_S: float = 0.05
"""Pyrosequencing decay k_a (apyrase degrading ATP and dNTP), paper eq. 19. Unit: 1/s."""

RONAGHI_PHOTONS_PER_INCORPORATION: float = 0.01
"""Measured yield, "1 pmol DNA → 6e11 ATP → > 6e9 photons" (Ronaghi, Genome Res. 11, 2001; the
quote is not checked against the primary text here): about 0.01 photon per incorporated base."""


def _out(x: NDArray[np.float64]) -> FloatOrArray:
    """Numpy scalar for 0-d results, the array otherwise."""
    return x[()]


def _decaying_rate(t_s: ArrayLike, total: NDArray, k: NDArray) -> FloatOrArray:
    """``total · k e^{−k t}`` for ``t ≥ 0``, 0 before: a pulse that emits ``total`` photons."""
    t = _checks.as_float_array("t_s", t_s)
    with np.errstate(over="ignore"):  # k t = inf gives e^{-inf} = 0, as it should
        decay = np.exp(-k * np.maximum(t, 0.0))
    value = total * (k * decay)
    return _out(np.where(t >= 0.0, value, 0.0))


def _decaying_photons(t_int_s: ArrayLike, total: NDArray, k: NDArray) -> FloatOrArray:
    """``∫_0^T total · k e^{−k t} dt = total · (1 − e^{−kT})`` via ``expm1``: finite for any kT."""
    t_int = _checks.nonnegative("t_int_s", t_int_s)
    with np.errstate(over="ignore"):  # k T = inf gives expm1(-inf) = -1, as it should
        fraction = -np.expm1(-k * t_int)
    return _out(total * fraction)


# --- eqs. 2–3: mass action and photon rate ---------------------------------------------------


def mass_action_rate(
    k_f_per_M_per_s: ArrayLike,
    substrate_M: ArrayLike,
    enzyme_M: ArrayLike,
    k_r_per_M_per_s: ArrayLike = 0.0,
    product_M: ArrayLike = 0.0,
) -> FloatOrArray:
    """Rate of product formation by mass action.

    Parameters
    ----------
    k_f_per_M_per_s, k_r_per_M_per_s : array_like
        Forward and reverse rate constants, >= 0. Unit: 1/(M·s).
    substrate_M, enzyme_M, product_M : array_like
        Concentrations [S], [E], [P], >= 0. Unit: M.

    Returns
    -------
    d[P]/dt. Unit: M/s (negative when the reverse reaction dominates).

    Notes
    -----
    Paper eq. 2: ``d[P]/dt = k_f [S][E] − k_r [E][P]``.
    """
    k_f = _checks.nonnegative("k_f_per_M_per_s", k_f_per_M_per_s)
    k_r = _checks.nonnegative("k_r_per_M_per_s", k_r_per_M_per_s)
    s = _checks.nonnegative("substrate_M", substrate_M)
    e = _checks.nonnegative("enzyme_M", enzyme_M)
    p = _checks.nonnegative("product_M", product_M)
    return _out(k_f * s * e - k_r * e * p)


def photon_rate(
    product_rate_M_per_s: ArrayLike, volume_L: ArrayLike, alpha: float = ALPHA_SELIGER_MCELROY
) -> FloatOrArray:
    """Photon emission rate of a light-producing reaction.

    Parameters
    ----------
    product_rate_M_per_s : array_like
        d[P]/dt of the light-emitting step, >= 0. Unit: M/s.
    volume_L : array_like
        Reaction volume, >= 0. Unit: L.
    alpha : float
        Quantum yield, photons per reaction, in [0, 1].

    Returns
    -------
    I. Unit: photons/s (into 4π).

    Notes
    -----
    Paper eq. 3: ``I = α V A d[P]/dt`` with ``A`` = :data:`~chiptwin.constants.N_A`.
    """
    rate = _checks.nonnegative("product_rate_M_per_s", product_rate_M_per_s)
    volume = _checks.nonnegative("volume_L", volume_L)
    return _out(_checks.quantum_yield("alpha", alpha) * volume * N_A * rate)


def emission_prefactor(
    alpha: float = ALPHA_SELIGER_MCELROY, turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S
) -> FloatOrArray:
    """Photon rate per mole of light-limiting reactant, ``N_A · α · k_t``.

    Parameters
    ----------
    alpha : float
        Quantum yield in [0, 1].
    turnover_per_s : array_like
        Turnover k_t, >= 0. Unit: 1/s.

    Returns
    -------
    Unit: photons/(s·mol).

    Notes
    -----
    The paper's rounded prefactors: 5.3e22 in eqs. 12–13 (α = 0.88, k_t = 0.1 s⁻¹) and 5.3e23 in
    eq. 19 (α = 0.88, k_t = 1 s⁻¹) (5.3e22 = N_A·0.88·0.1, 5.3e23 = N_A·0.88·1.0;
    docs/background/sources.md K7).
    """
    k_t = _checks.nonnegative("turnover_per_s", turnover_per_s)
    return _out(N_A * _checks.quantum_yield("alpha", alpha) * k_t)


# --- eqs. 5–6: substrate detection (enzyme in excess) -----------------------------------------


def _substrate_total(substrate_mol, k_f_per_M_per_s, enzyme_M, alpha):
    """Photons as T → ∞, ``α A V[S0]``, and the decay rate ``k_f [E]``."""
    s = _checks.nonnegative("substrate_mol", substrate_mol)
    k = _checks.nonnegative("k_f_per_M_per_s", k_f_per_M_per_s) * _checks.nonnegative(
        "enzyme_M", enzyme_M)
    return N_A * _checks.quantum_yield("alpha", alpha) * s, k


def substrate_detection_rate(
    t_s: ArrayLike,
    substrate_mol: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    enzyme_M: ArrayLike,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photon rate when the substrate is the analyte and the enzyme is in excess.

    Parameters
    ----------
    t_s : array_like
        Time since mixing. Unit: s.
    substrate_mol : array_like
        Amount of substrate ``V·[S0]``, >= 0. Unit: mol.
    k_f_per_M_per_s : array_like
        Forward rate constant, >= 0. Unit: 1/(M·s).
    enzyme_M : array_like
        Enzyme concentration [E] (constant, in excess), >= 0. Unit: M.
    alpha : float
        Quantum yield in [0, 1].

    Returns
    -------
    Unit: photons/s.

    Notes
    -----
    Paper eq. 5: ``I(t) = α V A k_f [E][S0] e^{−k_f [E] t}``.
    """
    total, k = _substrate_total(substrate_mol, k_f_per_M_per_s, enzyme_M, alpha)
    return _decaying_rate(t_s, total, k)


def substrate_detection_photons(
    t_int_s: ArrayLike,
    substrate_mol: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    enzyme_M: ArrayLike,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photons emitted in ``[0, T]`` by substrate detection.

    Other arguments as :func:`substrate_detection_rate`.

    Parameters
    ----------
    t_int_s : array_like
        Integration time T, >= 0. Unit: s.

    Returns
    -------
    Unit: photons.

    Notes
    -----
    Paper eq. 6: ``N(T) = α V A [S0] (1 − e^{−k_f [E] T})``, evaluated with ``expm1``.
    """
    total, k = _substrate_total(substrate_mol, k_f_per_M_per_s, enzyme_M, alpha)
    return _decaying_photons(t_int_s, total, k)


# --- eqs. 7–8: catalyst detection (substrate in excess) ---------------------------------------


def catalyst_detection_rate(
    enzyme_mol: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    substrate_max_M: ArrayLike,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Constant photon rate when the enzyme is the analyte and the substrate is in excess.

    Parameters
    ----------
    enzyme_mol : array_like
        Amount of enzyme ``V·[E]``, >= 0. Unit: mol.
    k_f_per_M_per_s : array_like
        Forward rate constant, >= 0. Unit: 1/(M·s).
    substrate_max_M : array_like
        Substrate concentration [S_max] (not depleted), >= 0. Unit: M.
    alpha : float
        Quantum yield in [0, 1].

    Returns
    -------
    Unit: photons/s.

    Notes
    -----
    Paper eq. 7: ``I = α V A k_f [S_max][E]``.
    """
    e = _checks.nonnegative("enzyme_mol", enzyme_mol)
    k = _checks.nonnegative("k_f_per_M_per_s", k_f_per_M_per_s) * _checks.nonnegative(
        "substrate_max_M", substrate_max_M)
    return _out(N_A * _checks.quantum_yield("alpha", alpha) * k * e)


def catalyst_detection_photons(
    t_int_s: ArrayLike,
    enzyme_mol: ArrayLike,
    k_f_per_M_per_s: ArrayLike,
    substrate_max_M: ArrayLike,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photons emitted in ``[0, T]`` by catalyst detection.

    Other arguments as :func:`catalyst_detection_rate`.

    Returns
    -------
    Unit: photons.

    Notes
    -----
    Paper eq. 8: ``N(T) = I · T``.
    """
    t_int = _checks.nonnegative("t_int_s", t_int_s)
    return _out(catalyst_detection_rate(enzyme_mol, k_f_per_M_per_s, substrate_max_M, alpha)
                * t_int)


# --- eq. 12: ATP assay; eq. 13: luciferase label -----------------------------------------------


def atp_assay_rate(
    t_s: ArrayLike,
    atp_mol: ArrayLike,
    turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photon rate of an ATP assay (ATP is the analyte, luciferase/luciferin in excess).

    Parameters
    ----------
    t_s : array_like
        Time since mixing. Unit: s.
    atp_mol : array_like
        Amount of ATP ``V·[ATP0]``, >= 0. Unit: mol.
    turnover_per_s : array_like
        Luciferase turnover k_t, 0.1 (glow) … 1 (flash), >= 0. Unit: 1/s.
    alpha : float
        Quantum yield in [0, 1].

    Returns
    -------
    Unit: photons/s.

    Notes
    -----
    Paper eq. 12: ``I(t) = α A k_t V[ATP0] e^{−k_t t} ≈ 5.3e22 · V[ATP0] · e^{−0.1 t}`` (glow).
    Each ATP gives α photons in total.
    """
    a = _checks.nonnegative("atp_mol", atp_mol)
    k = _checks.nonnegative("turnover_per_s", turnover_per_s)
    return _decaying_rate(t_s, N_A * _checks.quantum_yield("alpha", alpha) * a, k)


def atp_assay_photons(
    t_int_s: ArrayLike,
    atp_mol: ArrayLike,
    turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photons emitted in ``[0, T]`` by an ATP assay (arguments as :func:`atp_assay_rate`).

    Returns
    -------
    ``α A V[ATP0] (1 − e^{−k_t T})``. Unit: photons.

    Notes
    -----
    Integral of paper eq. 12 (the eq. 6 form).
    """
    a = _checks.nonnegative("atp_mol", atp_mol)
    k = _checks.nonnegative("turnover_per_s", turnover_per_s)
    return _decaying_photons(t_int_s, N_A * _checks.quantum_yield("alpha", alpha) * a, k)


def luciferase_label_rate(
    luciferase_mol: ArrayLike,
    turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Constant photon rate of a luciferase label (ATP and luciferin in excess).

    Parameters
    ----------
    luciferase_mol : array_like
        Amount of luciferase label ``V·[E0]``, >= 0. Unit: mol.
    turnover_per_s : array_like
        Luciferase turnover k_t, >= 0. Unit: 1/s.
    alpha : float
        Quantum yield in [0, 1].

    Returns
    -------
    Unit: photons/s.

    Notes
    -----
    Paper eq. 13: ``I = α A k_t V[E0] ≈ 5.3e22 · V[E0]``.
    """
    e = _checks.nonnegative("luciferase_mol", luciferase_mol)
    return _out(np.asarray(emission_prefactor(alpha, turnover_per_s)) * e)


def luciferase_label_photons(
    t_int_s: ArrayLike,
    luciferase_mol: ArrayLike,
    turnover_per_s: ArrayLike = ATP_TURNOVER_GLOW_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
) -> FloatOrArray:
    """Photons emitted in ``[0, T]`` by a luciferase label: ``I · T`` (eq. 13 with eq. 8).

    Returns
    -------
    Unit: photons.
    """
    t_int = _checks.nonnegative("t_int_s", t_int_s)
    return _out(np.asarray(luciferase_label_rate(luciferase_mol, turnover_per_s, alpha)) * t_int)


# --- eqs. 18–19: pyrosequencing, one incorporation event --------------------------------------


def incorporation_yield(
    alpha: float = ALPHA_SELIGER_MCELROY,
    turnover_per_s: ArrayLike = PYRO_TURNOVER_PER_S,
    apyrase_per_s: ArrayLike = PYRO_APYRASE_PER_S,
) -> FloatOrArray:
    """Photons per incorporated base implied by eq. 19, ``α k_t / k_a``.

    Parameters
    ----------
    alpha : float
        Quantum yield in [0, 1].
    turnover_per_s : array_like
        k_t, >= 0. Unit: 1/s.
    apyrase_per_s : array_like
        k_a, > 0. Unit: 1/s.

    Returns
    -------
    Unit: photons per incorporation. 17.6 with the paper's values.

    Notes
    -----
    Integral of eq. 19 over all time per DNA strand. It exceeds α because PPi is recycled
    (ATP sulfurylase turns it back into ATP) until apyrase removes the ATP (sources.md K8).
    """
    k_t = _checks.nonnegative("turnover_per_s", turnover_per_s)
    k_a = _checks.positive("apyrase_per_s", apyrase_per_s)
    return _out(_checks.quantum_yield("alpha", alpha) * k_t / k_a)


def pyrosequencing_amplitude(
    dna_mol: ArrayLike,
    n_incorporated: ArrayLike = 1,
    turnover_per_s: ArrayLike = PYRO_TURNOVER_PER_S,
    apyrase_per_s: ArrayLike = PYRO_APYRASE_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
    photons_per_incorporation: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Peak photon rate and decay rate of one dispensation.

    Arguments as :func:`pyrosequencing_rate`.

    Returns
    -------
    amplitude_per_s : ndarray
        ``n N_A V[DNA] α k_t`` (eq. 19), or ``n N_A V[DNA] Y k_a`` with a measured yield Y, so that
        the light integrates to ``n N_A V[DNA] Y``. Unit: photons/s.
    decay_per_s : ndarray
        ``k_a``. Unit: 1/s.
    """
    strands = N_A * _checks.nonnegative("dna_mol", dna_mol)
    n = _checks.nonnegative("n_incorporated", n_incorporated)
    k_a = _checks.positive("apyrase_per_s", apyrase_per_s)
    if photons_per_incorporation is None:
        k_t = _checks.nonnegative("turnover_per_s", turnover_per_s)
        return n * strands * _checks.quantum_yield("alpha", alpha) * k_t, k_a
    y = _checks.nonnegative("photons_per_incorporation", photons_per_incorporation)
    return n * strands * y * k_a, k_a


def _pyro_total(dna_mol, n_incorporated, turnover_per_s, apyrase_per_s, alpha,
                photons_per_incorporation):
    """Photons as T → ∞, ``n N_A V[DNA] Y``, and ``k_a``."""
    k_a = _checks.positive("apyrase_per_s", apyrase_per_s)
    if photons_per_incorporation is None:
        y = incorporation_yield(alpha, turnover_per_s, k_a)
    else:
        y = _checks.nonnegative("photons_per_incorporation", photons_per_incorporation)
    strands = N_A * _checks.nonnegative("dna_mol", dna_mol)
    return _checks.nonnegative("n_incorporated", n_incorporated) * strands * y, k_a


def pyrosequencing_rate(
    t_s: ArrayLike,
    dna_mol: ArrayLike,
    n_incorporated: ArrayLike = 1,
    turnover_per_s: ArrayLike = PYRO_TURNOVER_PER_S,
    apyrase_per_s: ArrayLike = PYRO_APYRASE_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
    photons_per_incorporation: ArrayLike | None = None,
) -> FloatOrArray:
    """Photon rate after one nucleotide dispensation that extends every strand by ``n`` bases.

    Parameters
    ----------
    t_s : array_like
        Time since the dispensation. Unit: s.
    dna_mol : array_like
        Amount of primed template ``V·[DNA]``, >= 0. Unit: mol.
    n_incorporated : array_like
        Bases incorporated per strand (homopolymer length), >= 0.
    turnover_per_s : array_like
        k_t, >= 0. Unit: 1/s. Ignored when ``photons_per_incorporation`` is given.
    apyrase_per_s : array_like
        k_a, > 0. Unit: 1/s.
    alpha : float
        Quantum yield in [0, 1]. Ignored when ``photons_per_incorporation`` is given.
    photons_per_incorporation : array_like or None
        Measured photon yield Y per incorporated base (e.g.
        :data:`RONAGHI_PHOTONS_PER_INCORPORATION`); None uses eq. 19's ``α k_t / k_a`` (17.6).

    Returns
    -------
    ``n N_A V[DNA] · Y · k_a · e^{−k_a t}``. Unit: photons/s.

    Notes
    -----
    Paper eqs. 18–19: ``I(t) = α V A k_t [DNA] e^{−k_a t} ≈ 5.3e23 · V[DNA] · e^{−0.05 t}`` for
    one base; the homopolymer factor ``n`` is the generalisation the twin uses (all ``n`` PPi are
    released within one dispensation).
    """
    total, k_a = _pyro_total(dna_mol, n_incorporated, turnover_per_s, apyrase_per_s, alpha,
                             photons_per_incorporation)
    return _decaying_rate(t_s, total, k_a)


def pyrosequencing_photons(
    t_int_s: ArrayLike,
    dna_mol: ArrayLike,
    n_incorporated: ArrayLike = 1,
    turnover_per_s: ArrayLike = PYRO_TURNOVER_PER_S,
    apyrase_per_s: ArrayLike = PYRO_APYRASE_PER_S,
    alpha: float = ALPHA_SELIGER_MCELROY,
    photons_per_incorporation: ArrayLike | None = None,
) -> FloatOrArray:
    """Photons emitted in ``[0, T]`` after one dispensation.

    Other arguments as :func:`pyrosequencing_rate`.

    Returns
    -------
    ``n N_A V[DNA] · Y · (1 − e^{−k_a T})``. Unit: photons.

    Notes
    -----
    Integral of paper eq. 19. For 1 fmol and the paper's values: 1.06e10 photons as T → ∞,
    39 % of them in the first 10 s.
    """
    total, k_a = _pyro_total(dna_mol, n_incorporated, turnover_per_s, apyrase_per_s, alpha,
                             photons_per_incorporation)
    return _decaying_photons(t_int_s, total, k_a)
