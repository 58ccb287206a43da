"""The JSSC 2006 reference chip's optical stack, as data with its sources and named assumptions.

Source: Eltoukhy, Salama, El Gamal, "A 0.18-µm CMOS bioluminescence detection lab-on-chip",
IEEE JSSC 41(3):651, 2006 (abstract: the assays sit on a fibre-optic faceplate placed directly on
the chip). Everything else below is an ASSUMPTION, named in :data:`ASSUMPTIONS`:
the abstract gives no faceplate data and no passivation thicknesses.
"""

from __future__ import annotations

from chiptwin.optics.faceplate import Faceplate
from chiptwin.optics.layers import Layer, Stack

WATER_N: float = 1.33
"""Assay buffer at 560 nm (textbook value; docs/background/sources.md O11)."""

ASSUMPTIONS: dict[str, str] = {
    "water_um": "10 µm of assay solution from the emitting site down to the faceplate: a bead of "
                "≈ 20 µm resting on the face (choice; the paper's contact case is 15 µm)",
    "faceplate.na": "1.0 in air: the common 'NA 1.0' faceplates of the makers' datasheets "
                    "(typically 0.5–1.0); in water it accepts n·sinθ ≤ 1, θ ≤ 48.8°",
    "faceplate.fiber_pitch_um": "6 µm (typical fibre pitch of imaging faceplates; choice)",
    "faceplate.thickness_um": "1000 µm (choice; does not enter the psf level)",
    "faceplate.open_area_ratio": "0.7 (core share of the face; choice)",
    "faceplate.core_n": "1.8 (high-index glass core of NA 1.0 faceplates; choice)",
    "passivation": "0.18 µm process: ≈ 1 µm SiO₂ (n 1.46) + ≈ 0.5 µm Si₃N₄ (n 2.0) over the "
                   "diodes (assumption, not in the abstract); below the faceplate they add no "
                   "spread at the psf level and are listed for the raytrace level",
    "silicon_n": "4.3 (crystalline silicon, 470–560 nm; Layer/Stack default)",
}

PASSIVATION: tuple[Layer, ...] = (
    Layer("SiO2 passivation (assumed)", 1.46, 1.0),
    Layer("Si3N4 passivation (assumed)", 2.0, 0.5),
)
"""The assumed passivation between the faceplate and the diodes (see :data:`ASSUMPTIONS`)."""


def jssc2006_faceplate(*, na: float = 1.0, fiber_pitch_um: float = 6.0,
                       thickness_um: float = 1000.0, open_area_ratio: float = 0.7,
                       core_n: float | None = 1.8) -> Faceplate:
    """The reference chip's faceplate with the assumed parameters (:data:`ASSUMPTIONS`)."""
    return Faceplate(na=na, fiber_pitch_um=fiber_pitch_um, thickness_um=thickness_um,
                     open_area_ratio=open_area_ratio, core_n=core_n)


def jssc2006_stack(*, water_um: float = 10.0) -> Stack:
    """The stack above the faceplate: the assay solution from the site down to the face."""
    return Stack((Layer("assay solution", WATER_N, water_um),))


def jssc2006_direct_contact_stack(*, water_um: float = 10.0) -> Stack:
    """The same chip without the faceplate, for comparison: solution on the passivation."""
    return Stack((Layer("assay solution", WATER_N, water_um),) + PASSIVATION)
