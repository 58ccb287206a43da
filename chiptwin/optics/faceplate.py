"""Fibre-optic faceplate at the ``psf`` level: an angular acceptance and a pitch-sized blur.

A faceplate is a fused bundle of fibres (cores in a cladding, with an extramural absorber between
them) laid between the assay and the chip (faceplate makers' datasheets; Eltoukhy et al., JSSC 2006:
the chip carries its assays on one). The ``psf`` level models it as three deterministic operations
on the light that reaches its top face:

1. **acceptance**: a ray is carried down its fibre when Snell's invariant of the medium above,
   ``n·sinθ``, is at most the numerical aperture ``na`` (the invariant is the same in every planar
   layer above, so the test holds in any of them); the rest is absorbed by the extramural
   absorber (stated choice: no leak to the neighbours at this level; the ``raytrace`` level traces
   it);
2. **transport**: an accepted ray leaves the faceplate from the fibre it entered, uniformly over
   that fibre (its position inside the fibre is lost); where the fibre lattice sits against the
   site is unknown, so the entry is uniform within its fibre too, and exit − entry is on each
   axis the difference of two uniforms over a pitch: a triangle on ±``fiber_pitch_um``
   (variance p²/6). Until a review found it this was a box of side p centred on the entry
   (variance p²/12), which keeps the position within the fibre; a 4 M-ray Monte Carlo on an
   explicit fibre lattice at random phase measured 28.2 µm² for 13 µm fibres (p²/6 = 28.2);
3. **open area**: the light is scaled by ``open_area_ratio`` (the cores' share of the face).

``thickness_um`` does not enter the ``psf`` level (transport is straight down); it is part of the
geometry the ``raytrace`` level and the site height need. Layers below the faceplate (glue,
passivation, a few µm) add no spread at this level: stated, not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

NA_RANGE: tuple[float, float] = (0.0, 2.0)
"""Numerical apertures accepted: > 0 up to 2 (faceplate datasheets quote 0.35 … 1.0 in air)."""


@dataclass(frozen=True)
class Faceplate:
    """A fibre-optic faceplate: acceptance ``na``, ``fiber_pitch_um``, ``thickness_um``,
    ``open_area_ratio``; ``core_n`` (optional) adds the Fresnel loss at the entry into the cores."""

    na: float
    fiber_pitch_um: float
    thickness_um: float
    open_area_ratio: float
    core_n: float | None = None

    def __post_init__(self) -> None:
        lo, hi = NA_RANGE
        if not (math.isfinite(self.na) and lo < self.na <= hi):
            raise ValueError(f"na = {self.na!r} is out of range: must be in ({lo}, {hi}]")
        for name in ("fiber_pitch_um", "thickness_um"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= 1e5):
                raise ValueError(f"{name} = {value!r} is out of range: must be in (0, 1e5] µm")
        if not (math.isfinite(self.open_area_ratio) and 0.0 < self.open_area_ratio <= 1.0):
            raise ValueError(f"open_area_ratio = {self.open_area_ratio!r} is out of range: "
                             "must be in (0, 1]")
        if self.core_n is not None and not (math.isfinite(self.core_n)
                                            and 1.0 <= self.core_n <= 4.5):
            raise ValueError(f"core_n = {self.core_n!r} is out of range: must be in [1, 4.5]")
