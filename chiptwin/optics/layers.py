"""The planar layer stack between an emitting site and the photodiodes (issue 18).

Light leaves the site inside the well's solution and crosses planar layers (oxide or nitride
passivation, a glass coverslip, a fibre-optic faceplate's cladding) before it reaches the silicon.
A :class:`Stack` lists them top to bottom; the site sits in the first layer, ``thickness_um`` above
its lower interface, and the diode plane is the upper surface of the silicon below the last layer.

Units: lengths in µm; ``alpha_per_um`` is the intensity absorption coefficient (Beer–Lambert,
``I = I₀ exp(−α s)`` along a path of length ``s``); ``n`` the real refractive index.
Indices with sources: REFERENCE §2 (water 1.33, SiO₂ 1.46, Si₃N₄ ≈ 2.0, glass 1.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

N_RANGE: tuple[float, float] = (1.0, 4.5)
"""Refractive indices accepted: vacuum up to silicon's ≈ 4.1 at 500 nm, with a margin."""

THICKNESS_RANGE_UM: tuple[float, float] = (0.0, 1e5)
"""Layer thicknesses accepted: 0 (an interface alone) to 10 cm (far beyond any contact imager)."""

ALPHA_MAX_PER_UM: float = 1e3
"""Largest absorption coefficient accepted: far above silicon's ≈ 1 µm⁻¹ in the blue."""


@dataclass(frozen=True)
class Layer:
    """One planar layer: its name, refractive index, thickness and absorption."""

    name: str
    n: float
    thickness_um: float
    alpha_per_um: float = 0.0

    def __post_init__(self) -> None:
        lo, hi = N_RANGE
        if not (math.isfinite(self.n) and lo <= self.n <= hi):
            raise ValueError(f"layer {self.name!r}: n = {self.n!r}, allowed [{lo}, {hi}]")
        lo, hi = THICKNESS_RANGE_UM
        if not (math.isfinite(self.thickness_um) and lo <= self.thickness_um <= hi):
            raise ValueError(f"layer {self.name!r}: thickness_um = {self.thickness_um!r}, "
                             f"allowed [{lo}, {hi}] µm")
        if not (math.isfinite(self.alpha_per_um) and 0.0 <= self.alpha_per_um <= ALPHA_MAX_PER_UM):
            raise ValueError(f"layer {self.name!r}: alpha_per_um = {self.alpha_per_um!r}, "
                             f"allowed [0, {ALPHA_MAX_PER_UM}] µm⁻¹")


@dataclass(frozen=True)
class Stack:
    """Layers top to bottom, the emitter in the first; below the last lies the silicon.

    The first layer's ``thickness_um`` is the distance from the site down to the first interface
    (the solution below the site). ``silicon_n`` is the substrate's index (≈ 4.3 at 470–560 nm,
    REFERENCE §2): its reflectance follows from Fresnel at the last interface.
    """

    layers: tuple[Layer, ...]
    silicon_n: float = 4.3

    def __post_init__(self) -> None:
        if not self.layers:
            raise ValueError("a stack needs at least the layer the site emits in")
        lo, hi = N_RANGE
        if not (math.isfinite(self.silicon_n) and lo <= self.silicon_n <= hi):
            raise ValueError(f"silicon_n = {self.silicon_n!r}, allowed [{lo}, {hi}]")

    @property
    def height_um(self) -> float:
        """Distance from the site to the diode plane: the sum of the thicknesses."""
        return float(sum(layer.thickness_um for layer in self.layers))

    @property
    def homogeneous(self) -> bool:
        """True when every layer has one index and no absorption: today's one-medium psf."""
        n0 = self.layers[0].n
        return all(layer.n == n0 and layer.alpha_per_um == 0.0 for layer in self.layers)
