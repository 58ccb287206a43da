"""Optics: the share of each site's light that reaches each pixel's photodiode.

Unit in: photons emitted per site (into 4π); unit out: photons per pixel, via the coupling matrix
``C (n_pixels, n_sites)`` — pixel photons = ``C @ source.photons(edges)``.

Levels: ``na2`` (:func:`coupling_na2`, geometric collection efficiency, no
spread) and ``psf`` (:func:`coupling_psf`, the irradiance integrated exactly over every diode and
averaged over the site footprint, cross-talk included). Both take an emission ``convention`` by
name (:data:`CONVENTIONS`): ``"lambertian_na2"`` (the paper's NA²) or ``"isotropic"``.
Through a planar :class:`Stack` (:func:`coupling_stack`), with an optional fibre
:class:`Faceplate` and the site's :class:`Top` surface (an open well or a lid returning the light
the site sends up; :mod:`chiptwin.optics.top`).
"""

from __future__ import annotations

from chiptwin.optics.collection import (
    CONVENTIONS,
    ISOTROPIC,
    LAMBERTIAN_NA2,
    check_convention,
    collection_efficiency,
    half_angle_rad,
    plane_fraction,
)
from chiptwin.optics.faceplate import Faceplate
from chiptwin.optics.layers import Band, Layer, Stack
from chiptwin.optics.psf import (
    APERTURES,
    coupling_na2,
    coupling_psf,
    diode_collection_efficiency,
    pixel_centers_um,
    point_rectangle_fraction,
)
from chiptwin.optics.stack_psf import (
    EMITTERS,
    collected_fractions,
    coupling_stack,
    plane_fraction_stack,
)
from chiptwin.optics.top import Top, returned_fraction

__all__ = [
    "APERTURES",
    "Band",
    "CONVENTIONS",
    "EMITTERS",
    "Faceplate",
    "Layer",
    "Stack",
    "Top",
    "collected_fractions",
    "coupling_stack",
    "plane_fraction_stack",
    "ISOTROPIC",
    "LAMBERTIAN_NA2",
    "check_convention",
    "collection_efficiency",
    "coupling_na2",
    "coupling_psf",
    "diode_collection_efficiency",
    "half_angle_rad",
    "pixel_centers_um",
    "plane_fraction",
    "point_rectangle_fraction",
    "returned_fraction",
]
