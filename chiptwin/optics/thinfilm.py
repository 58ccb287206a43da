"""Coherent transmission through the planar stack: transfer matrices over the emission band.

Passivation layers of ≈ 1 µm oxide/nitride are coherent at visible wavelengths: a ray tracer treats
them incoherently, and a transfer-matrix (thin-film) calculation is the check (Macleod,
*Thin-Film Optical Filters*; docs/background/sources.md O12). This module is that check.
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

and ``M = I₀₁ · Π_j P_j I_{j,j+1}``, ``I = [[1, r], [r, 1]] / t``,
``P_j = diag(e^{−iδ_j}, e^{iδ_j})``, ``δ_j = 2π q_j d_j / λ``; the stack's ``t = 1/M₀₀``,
``r = M₁₀/M₀₀``, and the transmitted power
``T_s = Re(q_f)/Re(q₀) |t|²``, ``T_p = Re(N_f q_f*/N_f*) / Re(N₀ q₀*/N₀*) |t|²``. A layer's
``alpha_per_um`` (intensity) is its extinction ``κ = αλ/4π``: ``N = n + iκ``.

Frustrated total internal reflection comes with it: a ray beyond the critical angle of a thin
low-index layer between two higher ones tunnels through it (``q`` imaginary, ``|e^{iδ}|`` < 1),
which no ray picture transmits.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from chiptwin.optics.layers import FWHM_NM, MAX_NODES, PEAK_NM, Band, Layer

#: An evanescent or absorbed field that falls by ``e^{-35}`` across one layer transmits nothing
#: that counts (power ≤ e^{-70}); its phase factor is clipped there so the matrices stay finite.
_OPAQUE = 35.0

#: Angles × wavelengths a pass of :func:`band_average` holds: its ≈ 30 complex temporaries then
#: take ≈ 30 MB.
CHUNK = 1 << 16

#: ``q`` of an inner layer at exactly its critical angle (``β = n``), where the interface
#: formulas are 0/0: a decaying field this slow (1e-12 of ``k₀``) is the limit to ≈ 1e-12.
_AT_CRITICAL = 1e-12j


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
    for j in range(1, len(q) - 1):  # β exactly at an inner layer's index: q = 0 makes its
        q[j] = np.where(q[j] == 0, _AT_CRITICAL, q[j])  # interfaces 0/0; the limit is finite

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
    with np.errstate(divide="ignore", invalid="ignore"):  # grazing (q₀ = 0) carries no power
        if pol == "s":
            ratio = qf.real / q0.real
        else:
            ratio = ((nf * np.conj(qf) / np.conj(nf)).real
                     / (n0 * np.conj(q0) / np.conj(n0)).real)
        out = ratio * np.abs(t) ** 2
    return np.where(q0.real > 0, out, 0.0)


def complex_indices(layers: Sequence[Layer], wavelength_um: NDArray) -> list[NDArray]:
    """Each inner layer's ``n + iκ``, ``κ = αλ/4π``, as a ``(1, W)`` row over the wavelengths;
    the first's and last's real (their absorption is the caller's Beer–Lambert along the path:
    the incident and exit media of the transfer matrix are lossless)."""
    lam = np.asarray(wavelength_um, dtype=float)[None, :]
    inner = [layer.n + 1j * layer.alpha_per_um * lam / (4.0 * np.pi) for layer in layers[1:-1]]
    return [np.full_like(lam, layers[0].n, dtype=complex), *inner,
            np.full_like(lam, layers[-1].n, dtype=complex)]


def band_average(layers: Sequence[Layer], beta: NDArray, band: Band,
                 count: int | None = None) -> tuple[NDArray, NDArray]:
    """``(T_s, T_p)`` into the last layer at Snell's invariants ``beta = n₀ sin θ₀``, each
    polarisation coherent and averaged over ``band`` (``count`` wavelengths; default
    :meth:`Band.node_count`). The first and last layers' own absorption is not in it (the
    caller's path through them)."""
    return band_product([layers], beta, band, count)


def band_product(groups: Sequence[Sequence[Layer]], beta: NDArray, band: Band,
                 count: int | None = None) -> tuple[NDArray, NDArray]:
    """``(⟨Π_g T_s,g⟩, ⟨Π_g T_p,g⟩)``: the product of several stacks' transmittances (each
    ``groups[g]`` from its incident to its exit medium, all at the same ``beta``) at each
    wavelength, averaged over ``band``. A ray of one wavelength meets every group with it, so
    the fringes of two film groups are averaged together, not each alone (the product of the
    averages was 1 % off for nitride | 5 µm oxide | nitride). ``count``: default the most any
    group's :meth:`Band.node_count` asks."""
    lam, w = band.nodes(count or max(band.node_count(g) for g in groups))
    beta = np.asarray(beta, dtype=float).ravel()
    stacks = [(complex_indices(g, lam), np.array([layer.thickness_um for layer in g]))
              for g in groups]
    out = np.zeros((2, beta.size))
    step = max(1, CHUNK // lam.size)  # angles a pass: temporaries of ≈ CHUNK values
    for lo in range(0, beta.size, step):
        part = slice(lo, lo + step)
        for k, pol in enumerate(("s", "p")):
            prod = 1.0
            for idx, d in stacks:
                prod = prod * transmittance(idx, d, lam[None, :], beta[part, None], pol)
            out[k, part] = prod @ w
    return out[0], out[1]


def band_transmittance(layers: Sequence[Layer], theta0: NDArray, band: Band,
                       count: int | None = None) -> NDArray:
    """Unpolarised transmittance into the last layer at emission angles ``theta0`` (rad, in
    the first layer), averaged over ``band``: :func:`band_average` of s and p, powers averaged."""
    ts, tp = band_average(layers, layers[0].n * np.sin(np.asarray(theta0, dtype=float)), band,
                          count)
    return 0.5 * (ts + tp)


__all__ = ["Band", "FWHM_NM", "MAX_NODES", "PEAK_NM", "amplitudes", "band_average",
           "band_product", "band_transmittance", "complex_indices", "transmittance"]
