"""The site's top surface: what the solution above the site sends back down.

A site sits in the first layer of a :class:`~chiptwin.optics.layers.Stack` (the solution, index
``n₀``). Light it sends upwards crosses the site plane and meets, ``solution_depth_um`` above it,
one of three tops (:data:`MEDIA`):

* ``"solution"``: the solution continues far above (a deep flow cell, or an index-matched
  absorber): nothing returns;
* ``"air"``: an open well, the solution's free surface with air (n = 1) above: Fresnel
  reflection, and total internal reflection beyond the critical angle ``asin(1/n₀)`` (48.75° for
  water, 1.33 → 1.0);
* ``"glass"``: a lid of index ``lid_n`` and thickness ``lid_thickness_um`` on the solution, air
  above it: the incoherent slab solution → glass → air with its multiple reflections inside the
  lid (a lid of ≥ 100 µm is many coherence lengths of a luciferase band thick).

Reflectances per polarisation (s, p: they never mix in planar layers) from Fresnel's equations
(Born & Wolf, *Principles of Optics*, §1.5; Hecht, *Optics*, §4.6); the slab's reflectance
``R = R₁₂ + T₁₂² R₂₃ / (1 − R₂₁ R₂₃)`` (``R₂₁ = R₁₂``, Stokes' relations; the incoherent
sum of the multiple reflections). Everything here is a pure array function of Snell's invariant
``β = n·sinθ`` (the same in every planar layer).

Geometry of the returned light: a ray leaving the site at ``θ₀`` from the upward normal comes
back down through the site plane ``2·D·tanθ₀`` away from the site (``D`` the solution's depth),
as if from an image point ``2·D`` above it; a ray that went through the lid moves a further
``2·t·tanθ_g`` per round trip in the lid (``t`` its thickness, ``θ_g`` the angle in the glass).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

MEDIA: tuple[str, ...] = ("solution", "air", "glass")
"""What lies above the site's solution: more of it, air (an open well), a glass lid."""

AIR_N: float = 1.0
"""Index above an open well or a lid."""

DEPTH_RANGE_UM: tuple[float, float] = (0.1, 1e4)
"""Solution depths accepted: 0.1 µm (a film of solution) … 1 cm (deeper than any drop or
channel: an open drop is 100 µm – a few mm, a flow cell's channel 50–500 µm)."""

LID_N_RANGE: tuple[float, float] = (1.0, 2.5)
"""Lid indices accepted: 1 … 2.5 (soda-lime and borosilicate glass 1.47–1.52, fused silica 1.46,
sapphire 1.77, PDMS 1.41, cyclic olefin 1.53; above 2.5 no transparent lid material)."""

LID_THICKNESS_RANGE_UM: tuple[float, float] = (1.0, 1e4)
"""Lid thicknesses accepted: 1 µm (a membrane) … 1 cm; coverslips are 80–250 µm, slides 1 mm."""


@dataclass(frozen=True)
class Top:
    """The top surface above the site: ``medium`` (:data:`MEDIA`), the solution's depth above
    the site plane (µm), and for a lid its index and thickness (µm)."""

    medium: str = "solution"
    solution_depth_um: float = 100.0
    lid_n: float = 1.5
    lid_thickness_um: float = 0.0

    def __post_init__(self) -> None:
        if self.medium not in MEDIA:
            raise ValueError(f"medium = {self.medium!r} is unknown: must be one of {MEDIA}")
        lo, hi = DEPTH_RANGE_UM
        if not (math.isfinite(self.solution_depth_um) and lo <= self.solution_depth_um <= hi):
            raise ValueError(f"solution_depth_um = {self.solution_depth_um!r} is out of range: "
                             f"must be in [{lo:g}, {hi:g}] µm")
        if self.medium != "glass":
            return
        lo, hi = LID_N_RANGE
        if not (math.isfinite(self.lid_n) and lo <= self.lid_n <= hi):
            raise ValueError(f"lid_n = {self.lid_n!r} is out of range: must be in [{lo}, {hi}]")
        lo, hi = LID_THICKNESS_RANGE_UM
        if not (math.isfinite(self.lid_thickness_um) and lo <= self.lid_thickness_um <= hi):
            raise ValueError(f"lid_thickness_um = {self.lid_thickness_um!r} is out of range: a "
                             f"glass lid needs a thickness in [{lo:g}, {hi:g}] µm")

    @property
    def returns(self) -> bool:
        """True when the top sends light back down (anything but ``"solution"``)."""
        return self.medium != "solution"

    @property
    def parts(self) -> int:
        """Components of the returned light with their own lateral offset (:func:`components`):
        0 for ``"solution"``, 1 for air, 2 for a lid (its front face, and through the lid)."""
        return {"solution": 0, "air": 1, "glass": 2}[self.medium]


def _cos(n: float, beta: NDArray) -> NDArray:
    """``cos θ`` in a layer of index ``n`` at Snell's invariant ``beta`` (0 where it cannot go)."""
    return np.sqrt(np.clip(1.0 - (beta / n) ** 2, 0.0, None))


def reflectance(n1: float, n2: float, beta: NDArray) -> tuple[NDArray, NDArray]:
    """Power reflectances ``(Rₛ, Rₚ)`` of the interface ``n1 → n2`` at ``beta``; 1 beyond the
    critical angle (TIR). ``rₛ = (a − b)/(a + b)``, ``a = n₁cosθ₁, b = n₂cosθ₂``; ``rₚ`` with
    ``a = n₂cosθ₁, b = n₁cosθ₂`` (Born & Wolf §1.5.2)."""
    beta = np.asarray(beta, dtype=np.float64)
    c1, c2 = _cos(n1, beta), _cos(n2, beta)
    tir = beta >= n2
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = ((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)) ** 2
        rp = ((n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)) ** 2
    return np.where(tir, 1.0, np.nan_to_num(rs, nan=1.0)), np.where(tir, 1.0,
                                                                    np.nan_to_num(rp, nan=1.0))


def components(top: Top, n0: float, beta: NDArray) -> list[tuple[NDArray, NDArray, NDArray]]:
    """The returned light by lateral offset: a list of ``(Rₛ, Rₚ, offset_um)`` at ``beta``, one
    per :attr:`Top.parts`. The offset is the extra lateral path beyond the image point's
    ``2·D·tanθ₀`` (:func:`image_offset_um`).

    * air: ``R(n₀ → 1)``, offset 0;
    * glass: the lid's front face ``R₁₂`` (offset 0), then everything that entered the lid and
      came back, ``R_slab − R₁₂ = T₁₂² R₂₃ / (1 − R₁₂ R₂₃)``, at one round trip's offset
      ``2·t·tanθ_g``. The light that goes round the lid k ≥ 2 times (``T₁₂² R₂₃ (R₁₂R₂₃)^(k−1)``,
      a share ``R₁₂R₂₃`` of the second term: below 1 % of it up to θ₀ ≈ 70° in water under
      glass 1.5) is placed there too, ``2(k − 1)·t·tanθ_g`` short of where it lands.
    """
    if top.medium == "solution":
        return []
    if top.medium == "air":
        rs, rp = reflectance(n0, AIR_N, beta)
        return [(rs, rp, np.zeros_like(rs))]
    front = reflectance(n0, top.lid_n, beta)
    back = reflectance(top.lid_n, AIR_N, beta)
    through = []
    for r12, r23 in zip(front, back, strict=True):
        t12 = 1.0 - r12
        with np.errstate(invalid="ignore", divide="ignore"):
            through.append(np.nan_to_num(t12 * t12 * r23 / (1.0 - r12 * r23)))
    cg = _cos(top.lid_n, beta)
    with np.errstate(invalid="ignore", divide="ignore"):
        shift = np.where(cg > 0, 2.0 * top.lid_thickness_um * beta / (top.lid_n * cg), 0.0)
    return [(*front, np.zeros_like(shift)), (*through, shift)]


def slab_reflectance(top: Top, n0: float, beta: NDArray) -> NDArray:
    """Unpolarised reflectance of the top at ``beta`` (the mean of s and p, the components
    summed): what returns of a ray that meets it."""
    out = np.zeros_like(np.asarray(beta, dtype=np.float64))
    for rs, rp, _ in components(top, n0, beta):
        out = out + 0.5 * (rs + rp)
    return out


def image_offset_um(top: Top, n0: float, beta: NDArray) -> NDArray:
    """``2·D·tanθ₀``: how far from the site a returned ray crosses the site plane again (beyond
    a lid's own offset). Unit: µm."""
    c0 = _cos(n0, beta)
    with np.errstate(invalid="ignore", divide="ignore"):
        return 2.0 * top.solution_depth_um * beta / (n0 * c0)


def returned_fraction(top: Top, n0: float, nodes: int = 256) -> float:
    """Share of an isotropic emitter's light (into 4π) the top sends back down through the site
    plane: ``½∫₀^{π/2} R(θ₀) sinθ₀ dθ₀``. Beyond the critical angle into air (``n₀ sinθ₀ > 1``)
    everything returns (TIR at the surface, or at the lid's upper face: the slab then returns
    all), ``½cos θc``; inside it Gauss–Legendre (``nodes``) in the cosine in air, ``c_a``, in
    which ``R`` is smooth (it turns as a square root in θ₀ at θc):
    ``cos θ₀ = √(1 − (1 − c_a²)/n₀²)``, ``d cos θ₀ = c_a dc_a / (n₀² cos θ₀)``."""
    from chiptwin.optics.quadrature import gauss_legendre

    if not top.returns:
        return 0.0
    x, w = gauss_legendre(nodes)
    c_air = 0.5 * (x + 1.0)
    beta = np.sqrt(1.0 - c_air * c_air)
    cos0 = np.sqrt(1.0 - (beta / n0) ** 2)
    beyond = 0.5 * math.sqrt(max(0.0, 1.0 - (AIR_N / n0) ** 2))
    inside = 0.5 * np.sum(slab_reflectance(top, n0, beta) * c_air / (n0 * n0 * cos0) * 0.5 * w)
    return beyond + float(inside)


__all__ = ["AIR_N", "MEDIA", "Top", "components", "image_offset_um", "reflectance",
           "returned_fraction", "slab_reflectance"]
