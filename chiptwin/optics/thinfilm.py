"""Coherent transmission through the planar stack: the transfer-matrix method over the emission band.

REFERENCE §2: "≈ 1 µm oxide/nitride are coherent at visible wavelengths: a ray tracer treats them
incoherently; a transfer-matrix (thin-film) calculation is the check". This module is that check.
The psf level (:mod:`chiptwin.optics.profile`) multiplies single-pass Fresnel transmittances; the
``incoherent`` plane fraction (:func:`chiptwin.optics.stack_psf.plane_fraction_stack`) adds the
multiple reflections inside each layer as powers; here they add as amplitudes, with their phases,
one wavelength at a time, and the powers are then averaged over the luciferase's emission band.
A layer much thicker than the band's coherence length ``λ²/Δλ`` (≈ 4.5 µm at 562 ± 35 nm) shows
fringes finer than the band and averages to the incoherent slab; a layer of ≈ λ/n shows them.

Geometry as :mod:`chiptwin.optics.layers`: the site emits in the first layer, which is open above
(nothing comes back down: the incident medium); the light crosses the layers between and is
counted as it enters the last, whose far side is the diode plane (the exit medium, crossed once
with Beer–Lambert, nothing reflected back from the plane). With ``into_silicon`` the silicon is the
last layer.

Amplitudes: the interface form of the characteristic-matrix method (Born & Wolf, *Principles of
Optics*, §1.6; in the notation of S. J. Byrnes, "Multilayer optical calculations",
arXiv:1603.02720). With Snell's invariant ``β = n₀ sin θ₀`` and ``q_j = √(N_j² − β²)`` (``N_j`` the
complex index, ``Im q_j ≥ 0``: fields decay in the direction of travel, evanescent ones too), the
interface ``j → j+1`` has

- s: ``r = (q_j − q_{j+1}) / (q_j + q_{j+1})``, ``t = 2 q_j / (q_j + q_{j+1})``
- p: ``r = (N_{j+1}² q_j − N_j² q_{j+1}) / (N_{j+1}² q_j + N_j² q_{j+1})``,
  ``t = 2 N_j N_{j+1} q_j / (N_{j+1}² q_j + N_j² q_{j+1})``

and ``M = I₀₁ · Π_j P_j I_{j,j+1}``, ``I = [[1, r], [r, 1]] / t``, ``P_j = diag(e^{−iδ_j}, e^{iδ_j})``,
``δ_j = 2π q_j d_j / λ``; the stack's ``t = 1/M₀₀``, ``r = M₁₀/M₀₀``, and the transmitted power
``T_s = Re(q_f)/Re(q₀) |t|²``, ``T_p = Re(N_f q_f*/N_f*) / Re(N₀ q₀*/N₀*) |t|²``. A layer's
``alpha_per_um`` (intensity) is its extinction ``κ = αλ/4π``: ``N = n + iκ``.

Frustrated total internal reflection comes with it: a ray beyond the critical angle of a thin
low-index layer between two higher ones tunnels through it (``q`` imaginary, ``|e^{iδ}|`` < 1), which
no ray picture transmits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chiptwin.optics.layers import Layer

#: The luciferase's emission: peak 562 nm (the paper; REFERENCE §1, firefly luciferase's
#: yellow-green band). The band's width is not in REFERENCE: 70 nm FWHM is an assumption (the
#: in-vitro firefly spectrum's main band); the tests and the optics notes give the sensitivity.
PEAK_NM: float = 562.0
FWHM_NM: float = 70.0

#: Widths accepted: a 1 nm line (a laser-like source, coherent through 100 µm of glass) to 300 nm
#: (wider than the whole visible band's main emitters); peaks over the visible and near IR.
FWHM_RANGE_NM: tuple[float, float] = (1.0, 300.0)
PEAK_RANGE_NM: tuple[float, float] = (350.0, 1100.0)

#: An evanescent or absorbed field that falls by ``e^{-35}`` across one layer transmits nothing
#: that counts (power ≤ e^{-70}); its phase factor is clipped there so the matrices stay finite.
_OPAQUE = 35.0

#: Wavelength nodes per fringe of the thickest layer, and most nodes over the band.
_PER_FRINGE = 8
MAX_NODES = (1 << 14) + 1
_CHUNK = 1 << 18


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
        half = 4.0 * self.sigma_nm
        lam_nm = np.linspace(self.peak_nm - half, self.peak_nm + half, count)
        w = np.exp(-0.5 * ((lam_nm - self.peak_nm) / self.sigma_nm) ** 2)
        w[[0, -1]] *= 0.5
        return lam_nm * 1e-3, w / w.sum()

    def node_count(self, layers: tuple[Layer, ...]) -> int:
        """Enough wavelengths to resolve the fringes of the thickest inner layer: its period in
        λ is ``λ²/(2 n d)`` (at normal incidence; longer when oblique), :data:`_PER_FRINGE` nodes
        each, at least 33 over the band, at most :data:`MAX_NODES`."""
        lam_lo_um = (self.peak_nm - 4.0 * self.sigma_nm) * 1e-3
        path = max((2.0 * layer.n * layer.thickness_um for layer in layers[1:-1]), default=0.0)
        if path == 0.0:
            return 33
        period_nm = lam_lo_um**2 / path * 1e3
        return int(min(max(33, math.ceil(8 * self.sigma_nm / period_nm * _PER_FRINGE) + 1),
                       MAX_NODES))


def _q(index: NDArray, beta: NDArray) -> NDArray:
    """``√(N² − β²)`` on the branch with ``Im ≥ 0`` (decaying forward)."""
    q = np.sqrt(index * index - beta * beta + 0j)
    return np.where(q.imag < 0, -q, q)


def amplitudes(indices: list[NDArray], thickness_um: NDArray, wavelength_um: NDArray,
               beta: NDArray, pol: str) -> tuple[NDArray, NDArray]:
    """The stack's amplitude ``r`` and ``t`` (incident from the first layer, into the last).

    ``indices[j]``: layer ``j``'s complex index, broadcastable with ``beta`` and
    ``wavelength_um`` (e.g. ``(1, W)`` when it depends on the wavelength); ``thickness_um[j]``
    its thickness (the first's and last's are not used: semi-infinite); ``beta = n₀ sin θ₀``.
    """
    if pol not in ("s", "p"):
        raise ValueError(f"pol = {pol!r}: must be 's' or 'p'")
    q = [_q(n_j, beta) for n_j in indices]

    def interface(j: int) -> tuple[NDArray, NDArray]:
        a, b = indices[j], indices[j + 1]
        if pol == "s":
            den = q[j] + q[j + 1]
            return (q[j] - q[j + 1]) / den, 2.0 * q[j] / den
        den = b * b * q[j] + a * a * q[j + 1]
        return (b * b * q[j] - a * a * q[j + 1]) / den, 2.0 * a * b * q[j] / den

    r, t = interface(0)
    m00, m01, m10, m11 = 1.0 / t, r / t, r / t, 1.0 / t
    for j in range(1, len(indices) - 1):
        delta = 2.0 * np.pi * q[j] * thickness_um[j] / wavelength_um
        delta = delta.real + 1j * np.minimum(delta.imag, _OPAQUE)
        back, fwd = np.exp(-1j * delta), np.exp(1j * delta)
        r, t = interface(j)
        # M ← M · diag(back, fwd) · [[1, r], [r, 1]] / t
        a00, a01, a10, a11 = m00 * back, m01 * fwd, m10 * back, m11 * fwd
        m00, m01 = (a00 + a01 * r) / t, (a00 * r + a01) / t
        m10, m11 = (a10 + a11 * r) / t, (a10 * r + a11) / t
    return m10 / m00, 1.0 / m00


def transmittance(indices: list[NDArray], thickness_um: NDArray, wavelength_um: NDArray,
                  beta: NDArray, pol: str) -> NDArray:
    """Power transmitted into the last layer, for a plane wave of unit power in the first."""
    _, t = amplitudes(indices, thickness_um, wavelength_um, beta, pol)
    n0, nf = indices[0], indices[-1]
    q0, qf = _q(n0, beta), _q(nf, beta)
    if pol == "s":
        ratio = qf.real / q0.real
    else:
        ratio = (nf * np.conj(qf) / np.conj(nf)).real / (n0 * np.conj(q0) / np.conj(n0)).real
    return ratio * np.abs(t) ** 2


def complex_indices(layers: tuple[Layer, ...], wavelength_um: NDArray) -> list[NDArray]:
    """Each inner layer's ``n + iκ``, ``κ = αλ/4π``, as a ``(1, W)`` row over the wavelengths;
    the first's and last's real (their absorption is the caller's Beer–Lambert along the path:
    the incident and exit media of the transfer matrix are lossless)."""
    lam = np.asarray(wavelength_um, dtype=float)[None, :]
    inner = [layer.n + 1j * layer.alpha_per_um * lam / (4.0 * np.pi) for layer in layers[1:-1]]
    return [np.full_like(lam, layers[0].n, dtype=complex), *inner,
            np.full_like(lam, layers[-1].n, dtype=complex)]


def band_transmittance(layers: tuple[Layer, ...], theta0: NDArray, band: Band,
                       count: int | None = None) -> NDArray:
    """Unpolarised transmittance into the last layer at emission angles ``theta0`` (rad, in
    the first layer), averaged over ``band`` (``count`` wavelengths; default
    :meth:`Band.node_count`): s and p each coherent, their powers averaged. The first layer's
    own absorption is not in it (the caller's path through it)."""
    lam, w = band.nodes(count or band.node_count(layers))
    theta0 = np.asarray(theta0, dtype=float).ravel()
    beta = (layers[0].n * np.sin(theta0))[:, None]
    idx = complex_indices(layers, lam)
    d = np.array([layer.thickness_um for layer in layers])
    total = np.zeros(theta0.shape)
    step = max(1, _CHUNK // lam.size)  # angles a pass: temporaries of ≈ _CHUNK values
    for lo in range(0, theta0.size, step):
        part = slice(lo, lo + step)
        for pol in ("s", "p"):
            total[part] += 0.5 * (transmittance(idx, d, lam[None, :], beta[part], pol) @ w)
    return total


__all__ = ["Band", "FWHM_NM", "PEAK_NM", "amplitudes", "band_transmittance",
           "complex_indices", "transmittance"]
