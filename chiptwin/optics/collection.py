"""Geometric collection efficiency of a circular aperture, under two named emission conventions.

A point source sits on the axis of a disc of diameter ``D`` at distance ``U``; the disc subtends the
half-angle ``θ = atan(D / 2U)``.

``"lambertian_na2"``
    The fraction is ``NA² = sin²θ``: the source radiates as a Lambertian surface facing the disc
    (radiance ∝ cos, half the sphere, total 1 over the plane). This is the paper's convention
    (Salama et al. 2004, Sec. 3: collection efficiency ∝ NA², NA = sin(θmax)), which gives 1.54 %
    for a camera lens with ``D = 0.5 f`` at ``U = 2 f`` and 91.7 % for contact imaging with
    ``D = 100 µm``, ``U = 15 µm`` (derived from the paper's formula; the paper rounds to 1.6 % and
    91 %).
``"isotropic"``
    The fraction is the solid angle over 4π, ``(1 − cos θ) / 2``: a luminescent molecule in
    solution emits the same in every direction, so at most half the light reaches the plane.
    0.39 % and 35.6 % for the two cases above (derived; docs/background/sources.md O2–O4).

Both are exact for their emitter; they are the on-axis disc cases of the plane irradiance used by
:mod:`chiptwin.optics.psf` (``U²/(r²+U²)²/π`` and ``U/(r²+U²)^{3/2}/(4π)``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks

FloatOrArray = np.float64 | NDArray[np.float64]

LAMBERTIAN_NA2: str = "lambertian_na2"
"""Lambertian emitter facing the detector: efficiency NA² (the paper's convention)."""

ISOTROPIC: str = "isotropic"
"""Isotropic point emitter: efficiency = solid angle / 4π."""

CONVENTIONS: tuple[str, ...] = (LAMBERTIAN_NA2, ISOTROPIC)
"""The emission conventions every optics function accepts, by name."""


def check_convention(convention: str) -> str:
    """Return ``convention`` if it is one of :data:`CONVENTIONS`, else raise a ValueError."""
    if convention not in CONVENTIONS:
        allowed = ", ".join(repr(c) for c in CONVENTIONS)
        raise ValueError(f"convention = {convention!r} is unknown: must be one of {allowed}")
    return convention


def plane_fraction(convention: str) -> float:
    """Fraction of the emitted light that reaches an infinite plane below the source.

    Parameters
    ----------
    convention : str
        ``"lambertian_na2"`` or ``"isotropic"``.

    Returns
    -------
    float
        1.0 (Lambertian, all light goes down) or 0.5 (isotropic, the lower hemisphere). The upper
        bound of every coupling and efficiency; a sanity check for :mod:`chiptwin.optics.psf`.
    """
    return 1.0 if check_convention(convention) == LAMBERTIAN_NA2 else 0.5


def half_angle_rad(diameter_um: ArrayLike, distance_um: ArrayLike) -> FloatOrArray:
    """Half-angle subtended by a disc of diameter ``D`` seen on axis from distance ``U``.

    Parameters
    ----------
    diameter_um : array_like
        Aperture diameter D, >= 0. Unit: µm (any length unit, the same for both).
    distance_um : array_like
        Distance U from the source to the aperture plane, >= 0. Unit: µm.

    Returns
    -------
    ``θmax = atan(D / 2U)``. Unit: rad.
    """
    radius, distance = _radius_distance(diameter_um, distance_um)
    return np.arctan2(radius, distance)[()]


def _radius_distance(diameter_um: ArrayLike, distance_um: ArrayLike):
    radius = 0.5 * _checks.nonnegative("diameter_um", diameter_um)
    distance = _checks.nonnegative("distance_um", distance_um)
    if ((radius == 0) & (distance == 0)).any():
        raise ValueError("diameter_um and distance_um are both 0: the half-angle is undefined; "
                         "at least one must be > 0")
    return np.broadcast_arrays(radius, distance)


def collection_efficiency(
    diameter_um: ArrayLike, distance_um: ArrayLike, *, convention: str
) -> FloatOrArray:
    """Fraction of a point source's light collected by an on-axis disc.

    Parameters
    ----------
    diameter_um : array_like
        Aperture (lens or photodiode) diameter D, >= 0. Unit: µm (any unit, the same for both).
    distance_um : array_like
        Source-to-aperture distance U, >= 0. Unit: µm.
    convention : str
        ``"lambertian_na2"`` (the paper's) or ``"isotropic"``; see the module docstring.

    Returns
    -------
    Collected fraction of the emitted photons, in [0, 1] (Lambertian) or [0, 0.5] (isotropic).

    Notes
    -----
    Salama et al. 2004, Sec. 3: efficiency ∝ NA², NA = sin(atan(D/2U)). Evaluated without
    cancellation as ``R²/h²`` (Lambertian) and ``R² / (2h(h + U))`` (isotropic), ``R = D/2``,
    ``h = √(R² + U²)``, so tiny apertures keep full relative precision.
    """
    check_convention(convention)
    radius, distance = _radius_distance(diameter_um, distance_um)
    h = np.hypot(radius, distance)
    if convention == LAMBERTIAN_NA2:
        return ((radius / h) ** 2)[()]
    return (radius * radius / (2.0 * h * (h + distance)))[()]
