"""The planar layer stack between an emitting site and the photodiodes.

Light leaves the site inside the well's solution and crosses planar layers (oxide or nitride
passivation, a glass coverslip, a fibre-optic faceplate's cladding) before it reaches the silicon.
A :class:`Stack` lists them top to bottom; the site sits in the first layer, ``thickness_um`` above
its lower interface, and the diode plane is the upper surface of the silicon below the last layer.

Units: lengths in µm; ``alpha_per_um`` is the intensity absorption coefficient (Beer–Lambert,
``I = I₀ exp(−α s)`` along a path of length ``s``); ``n`` the real refractive index.
Indices (textbook values near 560 nm; docs/background/sources.md O11): water 1.33, SiO₂ 1.46, Si₃N₄
≈ 2.0, glass 1.5.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

N_RANGE: tuple[float, float] = (1.0, 4.5)
"""Refractive indices accepted: vacuum up to silicon's ≈ 4.1 at 500 nm, with a margin."""

THICKNESS_RANGE_UM: tuple[float, float] = (0.0, 1e5)
"""Layer thicknesses accepted: 0 (an interface alone) to 10 cm (far beyond any contact imager)."""

ALPHA_MAX_PER_UM: float = 1e3
"""Largest absorption coefficient accepted: far above silicon's ≈ 1 µm⁻¹ in the blue."""

#: The luciferase's emission: peak 562 nm (Salama et al. 2004; firefly luciferase's yellow-green
#: band; docs/background/sources.md K11). The band's width is not published with it: 70 nm FWHM
#: is an assumption (the in-vitro firefly spectrum's main band); the tests and the optics notes give
#: the sensitivity.
PEAK_NM: float = 562.0
FWHM_NM: float = 70.0

#: Widths accepted: a 1 nm line (a laser-like source, coherent through 100 µm of glass) to 300 nm
#: (wider than any luciferase's band); peaks over silicon's band, 200–1200 nm. A band reaching
#: below 100 nm (its ±4σ nodes) is refused.
FWHM_RANGE_NM: tuple[float, float] = (1.0, 300.0)
PEAK_RANGE_NM: tuple[float, float] = (200.0, 1200.0)

#: Wavelength nodes per fringe of the thickest layer, and most nodes over the band.
_PER_FRINGE = 8
#: The band is sampled over ±this many standard deviations of its Gaussian.
_SIGMAS = 4.0
MAX_NODES = (1 << 14) + 1


@dataclass(frozen=True)
class Band:
    """A Gaussian emission band: peak and full width at half maximum (nm), sampled over ±4σ."""

    peak_nm: float = PEAK_NM
    fwhm_nm: float = FWHM_NM

    def __post_init__(self) -> None:
        for key, value, (lo, hi) in (("peak_nm", self.peak_nm, PEAK_RANGE_NM),
                                     ("fwhm_nm", self.fwhm_nm, FWHM_RANGE_NM)):
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"emission band {key} = {value!r}, allowed [{lo}, {hi}] nm")
        if self.peak_nm - _SIGMAS * self.sigma_nm < 100.0:
            raise ValueError(f"emission band {self.peak_nm!r} ± {self.fwhm_nm!r} nm FWHM reaches "
                             "below 100 nm: a narrower band or a longer peak")

    @property
    def sigma_nm(self) -> float:
        return self.fwhm_nm / (2.0 * math.sqrt(2.0 * math.log(2.0)))

    @property
    def coherence_length_um(self) -> float:
        """``λ²/Δλ`` (vacuum, µm): optical path differences well beyond it wash out."""
        return (self.peak_nm**2 / self.fwhm_nm) * 1e-3

    def nodes(self, count: int) -> tuple[NDArray, NDArray]:
        """``count`` wavelengths (µm) evenly over ±4σ and their weights (trapezoid on the
        normalised Gaussian, summing to 1)."""
        half = _SIGMAS * self.sigma_nm
        lam_nm = np.linspace(self.peak_nm - half, self.peak_nm + half, count)
        w = np.exp(-0.5 * ((lam_nm - self.peak_nm) / self.sigma_nm) ** 2)
        w[[0, -1]] *= 0.5
        return lam_nm * 1e-3, w / w.sum()

    def node_count(self, layers: Sequence[Layer]) -> int:
        """Enough wavelengths to resolve the finest fringes of the inner layers: the whole inner
        stack's round trip ``2 Σ n d`` gives the shortest period in λ, ``λ²/(2 Σ n d)`` (at
        normal incidence; longer when oblique), :data:`_PER_FRINGE` nodes each, at least 33
        over the band, at most :data:`MAX_NODES`."""
        lam_lo_um = (self.peak_nm - _SIGMAS * self.sigma_nm) * 1e-3
        path = sum(2.0 * layer.n * layer.thickness_um for layer in layers[1:-1])
        if path == 0.0:
            return 33
        period_nm = lam_lo_um**2 / path * 1e3
        span_nm = 2.0 * _SIGMAS * self.sigma_nm
        return int(min(max(33, math.ceil(span_nm / period_nm * _PER_FRINGE) + 1),
                       MAX_NODES))


THIN_FILM_UM: float = 2.0
"""Inner layers this thin or thinner are thin films (:attr:`Stack.thin_film_um`): a CMOS
passivation's 0.1–1 µm of nitride or oxide. Their multiple reflections move light at most a few
µm sideways (2·d·tan θ a round trip), far below a pixel; thicker layers' are not in place."""

THIN_FILM_RANGE_UM: tuple[float, float] = (0.0, 10.0)
"""0 (every layer a ray layer) to 10 µm: beyond it a round trip moves light ≥ 20 µm, which the
``raytrace`` level places and the ``psf`` level's single pass leaves out."""


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
    textbook; sources.md O11): its reflectance follows from Fresnel at the last interface. Inner
    layers no thicker than ``thin_film_um`` are thin films, coherent over the emission ``band``
    (:meth:`ray_path`).
    """

    layers: tuple[Layer, ...]
    silicon_n: float = 4.3
    thin_film_um: float = THIN_FILM_UM
    band: Band = field(default_factory=Band)

    def __post_init__(self) -> None:
        if not self.layers:
            raise ValueError("a stack needs at least the layer the site emits in")
        lo, hi = N_RANGE
        if not (math.isfinite(self.silicon_n) and lo <= self.silicon_n <= hi):
            raise ValueError(f"silicon_n = {self.silicon_n!r}, allowed [{lo}, {hi}]")
        lo, hi = THIN_FILM_RANGE_UM
        if not (math.isfinite(self.thin_film_um) and lo <= self.thin_film_um <= hi):
            raise ValueError(f"thin_film_um = {self.thin_film_um!r}, allowed [{lo}, {hi}] µm")

    def ray_path(self) -> tuple[tuple[Layer, ...], tuple[tuple[Layer, ...], ...]]:
        """The layers a ray crosses with its geometry, and between each two of them the thin
        films (maybe none) it crosses in place.

        A film is an inner layer (neither the first, where the site emits, nor the last, above
        the diode plane) no thicker than :attr:`thin_film_um` (0: none). Its multiple
        reflections add as amplitudes over the emission :attr:`band`
        (:func:`chiptwin.optics.thinfilm.band_average`, the transfer-matrix check, sources.md O12)
        and it moves no light sideways: ≤ d·tan θ, a few µm, against pixels of tens."""
        rays, films, between = [self.layers[0]], [], []
        for i, layer in enumerate(self.layers[1:], 1):
            if self.is_film(i):
                between.append(layer)
            else:
                rays.append(layer)
                films.append(tuple(between))
                between = []
        return tuple(rays), tuple(films)

    def is_film(self, index: int) -> bool:
        """Whether layer ``index`` is a thin film (:meth:`ray_path`)."""
        return (0 < index < len(self.layers) - 1 and self.thin_film_um > 0
                and self.layers[index].thickness_um <= self.thin_film_um)

    @property
    def height_um(self) -> float:
        """Distance from the site to the diode plane: the sum of the thicknesses."""
        return float(sum(layer.thickness_um for layer in self.layers))

    @property
    def homogeneous(self) -> bool:
        """True when every layer has one index and no absorption: today's one-medium psf."""
        n0 = self.layers[0].n
        return all(layer.n == n0 and layer.alpha_per_um == 0.0 for layer in self.layers)
