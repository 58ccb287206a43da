"""Calibrating the cascade: fit its free constants to a light curve or to a measured photon yield.

The literature fixes the enzymes' Michaelis constants and turnover numbers
(docs/background/sources.md K17–K22); what an assay leaves free is mostly *how much* of each
enzyme is in the well. Two targets:

* a light curve (photons/s at given times after one dispensation): :func:`fit_light_curve`,
  non-linear least squares (``scipy.optimize.least_squares``) on the logarithms of the chosen
  :class:`~chiptwin.kinetics.cascade_params.CascadeParams` fields;
* a photon yield (photons per incorporated base, e.g. Ronaghi 2001's ≈ 0.01):
  :func:`fit_photon_yield`, a bracketed root (``scipy.optimize.brentq``) on one field.

Both return a :class:`CalibrationResult` with the fitted values and the fit residual.
:func:`photon_yield` computes the yield of any parameter set from one single-base incorporation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize

from chiptwin import _checks
from chiptwin.constants import N_A
from chiptwin.kinetics.cascade import cascade_pyrosequencing
from chiptwin.kinetics.cascade_params import CascadeParams

DEFAULT_DNA_MOL: float = 1e-15
"""Template amount of the calibration runs: 1 fmol, the headline scenario's (pyro_1fmol)."""

_DECAYED = 1e-12  # light left (share of the template amount in PPi + ATP) when the yield is read


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of a calibration.

    Attributes
    ----------
    params : CascadeParams
        The input parameters with the fitted fields replaced.
    values : dict of str to float
        Fitted value of each free field (its unit is in its name).
    residual : float
        Light curve: RMS of (model − target) / max(target). Yield: |model / target − 1|.
    n_evaluations : int
        Cascade solves used.
    success : bool
    message : str
    """

    params: CascadeParams
    values: dict[str, float]
    residual: float
    n_evaluations: int
    success: bool
    message: str


def _one_flow(params: CascadeParams, dna_mol: float, t_stop_s: float, rtol: float):
    """One single-base incorporation ("T" on "T") dispensed at t = 0."""
    return cascade_pyrosequencing([dna_mol], "T", "T", 1, t_stop_s, 0.0, params, rtol=rtol)


def single_flow_rate(params: CascadeParams, t_s: ArrayLike, *, dna_mol: float = DEFAULT_DNA_MOL,
                     rtol: float = 1e-9) -> NDArray[np.float64]:
    """Photon rate after one single-base incorporation dispensed at ``t = 0``.

    Parameters
    ----------
    params : CascadeParams
    t_s : array_like, shape (n_t,)
        Times after the dispensation, >= 0. Unit: s.
    dna_mol : float
        Template amount. Unit: mol.
    rtol : float
        Solver tolerance.

    Returns
    -------
    ndarray, shape (n_t,). Unit: photons/s.
    """
    t = _checks.nonnegative("t_s", t_s)
    src = _one_flow(params, dna_mol, max(float(t.max(initial=0.0)), 1e-9), rtol)
    return src.rate(t)[0]


def photon_yield(params: CascadeParams, *, dna_mol: float = DEFAULT_DNA_MOL,
                 rtol: float = 1e-9) -> float:
    """Photons per incorporated base, from one single-base incorporation run until dark.

    Parameters
    ----------
    params : CascadeParams
        Must remove ATP (apyrase) — otherwise PPi recycles forever and the yield is infinite.
    dna_mol : float
        Template amount, > 0. Unit: mol.
    rtol : float
        Solver tolerance.

    Returns
    -------
    float
        Photons into 4π per incorporation; in the linear regime
        :meth:`CascadeParams.linear_photons_per_incorporation` (eq. 19 integrated: 17.6 with the
        paper's constants).
    """
    dna = _checks.scalar("dna_mol", dna_mol, minimum=0.0, strict=True)
    rates = params.linear_rates()
    k_a, k_s, k_t = (rates[k] for k in ("apyrase_atp_per_s", "sulfurylase_per_s",
                                          "turnover_per_s"))
    if k_a <= 0:
        raise ValueError("photon_yield needs apyrase acting on ATP (apyrase_M, "
                         "apyrase_kcat_atp_per_s > 0): without it every PPi recycles forever")
    # the slow eigenvalue of PPi ⇄ ATP: PPi spends k_t / (k_s + k_t) of its time unconverted
    horizon = 40.0 / (k_a * k_s / (k_s + k_t)) if k_s > 0 else 40.0 / k_a
    for _ in range(8):
        src = _one_flow(params, dna, horizon, rtol)
        left = src.concentrations([horizon])
        if left["PPi"][0, 0] + left["ATP"][0, 0] <= _DECAYED * dna / params.volume_L:
            incorporated = src.incorporations()[0, 0]
            return float(src.flow_photons()[0, 0] / (incorporated * dna * N_A))
        horizon *= 4.0
    raise RuntimeError("photon_yield: light did not decay within the horizon")


def _with(params: CascadeParams, free: Sequence[str], log_values: NDArray) -> CascadeParams:
    return replace(params, **{f: float(10.0 ** v) for f, v in zip(free, log_values, strict=True)})


def _check_free(params: CascadeParams, free: Sequence[str]) -> list[str]:
    names = list(free)
    for f in names:
        if not hasattr(params, f) or isinstance(getattr(params, f), bool):
            raise ValueError(f"free = {f!r} is not a numeric CascadeParams field")
        if getattr(params, f) <= 0:
            raise ValueError(f"{f} = {getattr(params, f)!r} must be > 0 to be fitted (log scale)")
    if not names:
        raise ValueError("free must name at least one CascadeParams field")
    return names


def fit_light_curve(
    t_s: ArrayLike,
    rate_per_s: ArrayLike,
    params: CascadeParams,
    free: Sequence[str] = ("luciferase_M", "apyrase_M"),
    *,
    dna_mol: float = DEFAULT_DNA_MOL,
    span: float = 1e3,
    rtol: float = 1e-9,
) -> CalibrationResult:
    """Fit cascade fields to a light curve after one single-base incorporation.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Times after the dispensation, >= 0. Unit: s.
    rate_per_s : array_like, shape (n,)
        Target photon rate (into 4π), >= 0, not all 0. Unit: photons/s.
    params : CascadeParams
        Starting point; the other fields stay fixed.
    free : sequence of str
        Fields to fit (each > 0), searched on a log scale within ``[x0 / span, x0 · span]``.
    dna_mol : float
        Template amount of the target. Unit: mol.
    span : float
        Search range factor, > 1.
    rtol : float
        Solver tolerance of each evaluation.

    Returns
    -------
    CalibrationResult
        ``residual`` = RMS of (model − target) / max(target).
    """
    t = _checks.nonnegative("t_s", t_s)
    target = _checks.nonnegative("rate_per_s", rate_per_s)
    if t.ndim != 1 or target.shape != t.shape or not target.max(initial=0.0) > 0:
        raise ValueError("t_s and rate_per_s must be 1-D of equal length, with some light")
    names = _check_free(params, free)
    width = math.log10(_checks.scalar("span", span, minimum=1.0, strict=True))
    x0 = np.log10([getattr(params, f) for f in names])
    scale = float(target.max())
    count = [0]

    def residuals(x: NDArray) -> NDArray:
        count[0] += 1
        return (single_flow_rate(_with(params, names, x), t, dna_mol=dna_mol, rtol=rtol)
                - target) / scale

    res = optimize.least_squares(residuals, x0, bounds=(x0 - width, x0 + width), x_scale=1.0,
                                 xtol=1e-12, ftol=1e-12, gtol=1e-12)
    fitted = _with(params, names, res.x)
    return CalibrationResult(fitted, {f: getattr(fitted, f) for f in names},
                             float(np.sqrt(np.mean(res.fun ** 2))), count[0], bool(res.success),
                             str(res.message))


def _linear_guess(params: CascadeParams, name: str, target: float, x0: float) -> float:
    """log10 of the field value at which the linear-regime yield (a power law in it) hits target."""
    y0 = params.linear_photons_per_incorporation()
    y1 = _with(params, [name], [x0 + 1.0]).linear_photons_per_incorporation()
    if not (0 < y0 < math.inf and 0 < y1 < math.inf) or y0 == y1:
        return x0
    return x0 + math.log10(target / y0) / math.log10(y1 / y0)


def _bracket(params: CascadeParams, name: str, target: float, x0: float, width: float,
             log_ratio) -> tuple[float, float]:
    """A sign-changing bracket of ``log_ratio`` around the linear-regime guess (log10 units)."""
    guess = min(max(_linear_guess(params, name, target, x0), x0 - width), x0 + width)
    for step in (0.25, 1.0, 3.0, width):
        lo, hi = max(guess - step, x0 - width), min(guess + step, x0 + width)
        if log_ratio(lo) * log_ratio(hi) <= 0:
            return lo, hi
    raise ValueError(f"no {name} in [{10 ** (x0 - width):.3g}, {10 ** (x0 + width):.3g}] gives "
                     f"{target!r} photons per incorporation; widen span")


def fit_photon_yield(
    target_photons_per_incorporation: float,
    params: CascadeParams,
    free: str = "luciferase_M",
    *,
    dna_mol: float = DEFAULT_DNA_MOL,
    span: float = 1e4,
    rtol: float = 1e-9,
) -> CalibrationResult:
    """Solve for one field so that the cascade gives a measured photon yield.

    Parameters
    ----------
    target_photons_per_incorporation : float
        Measured yield, > 0 (e.g.
        :data:`~chiptwin.kinetics.closed_form.RONAGHI_PHOTONS_PER_INCORPORATION`, 0.01).
    params : CascadeParams
        Starting point.
    free : str
        The field to solve for (> 0); the yield must be monotonic in it (``luciferase_M`` raises
        it, ``apyrase_M`` lowers it).
    dna_mol : float
        Template amount the yield refers to. Unit: mol.
    span : float
        The root is searched in ``[x0 / span, x0 · span]``.
    rtol : float
        Solver tolerance of each evaluation.

    Returns
    -------
    CalibrationResult
        ``residual`` = |yield / target − 1|.
    """
    target = _checks.scalar("target_photons_per_incorporation", target_photons_per_incorporation,
                            minimum=0.0, strict=True)
    (name,) = _check_free(params, [free])
    width = math.log10(_checks.scalar("span", span, minimum=1.0, strict=True))
    x0 = math.log10(getattr(params, name))
    count = [0]

    def log_ratio(x: float) -> float:
        count[0] += 1
        return math.log(photon_yield(_with(params, [name], [x]), dna_mol=dna_mol, rtol=rtol)
                        / target)

    lo, hi = _bracket(params, name, target, x0, width, log_ratio)
    x, info = optimize.brentq(log_ratio, lo, hi, xtol=1e-13, rtol=1e-13, full_output=True)
    fitted = _with(params, [name], [x])
    achieved = photon_yield(fitted, dna_mol=dna_mol, rtol=rtol)
    return CalibrationResult(fitted, {name: getattr(fitted, name)}, abs(achieved / target - 1.0),
                             count[0] + 1, bool(info.converged), str(info.flag))
