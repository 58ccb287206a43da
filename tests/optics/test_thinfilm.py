"""Thin films by transfer matrices (chiptwin.optics.thinfilm): against S. J. Byrnes' ``tmm``
package (an independent implementation) on random stacks, absorbing and evanescent layers among
them; against closed forms (a quarter-wave anti-reflection layer, a half-wave layer that is not
there, energy conservation); and the band average of a thick layer against the incoherent slab
of REFERENCE §2."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chiptwin.optics import thinfilm
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.profile import fresnel_polarised
from chiptwin.optics.stack_psf import plane_fraction_stack
from tests.conftest import require_module


def _ours(n, d, lam_um, theta0, pol):
    idx = [np.array([[v]], dtype=complex) for v in n]
    beta = np.array([[n[0].real * math.sin(theta0)]])
    lam = np.array([[lam_um]])
    thick = np.array([0.0 if math.isinf(v) else v for v in d])
    r, t = thinfilm.amplitudes(idx, thick, lam, beta, pol)
    big_t = thinfilm.transmittance(idx, thick, lam, beta, pol)
    return r.item(), t.item(), big_t.item()


def test_amplitudes_match_byrnes_tmm_on_random_stacks():
    """300 random stacks of 2–5 layers (indices 1–4, absorbing inner layers with κ up to 0.5,
    thicknesses 0–5 µm, every angle up to grazing: evanescent layers and frustrated total
    reflection among them), both polarisations: r, t and T equal tmm.coh_tmm's within 1e-12."""
    tmm = require_module("tmm")
    rng = np.random.default_rng(1603)
    worst = 0.0
    for _ in range(300):
        size = int(rng.integers(2, 6))
        n = rng.uniform(1.0, 4.0, size).astype(complex)
        n[1:-1] += 1j * rng.choice([0.0, 0.0, 0.05, 0.5], size - 2)
        d = [math.inf, *rng.choice([0.0, 0.05, 0.3, 1.0, 5.0], size - 2), math.inf]
        lam, theta0 = rng.uniform(0.4, 0.8), rng.uniform(0.0, 0.999 * math.pi / 2)
        for pol in "sp":
            ref = tmm.coh_tmm(pol, list(n), d, theta0, lam)
            r, t, big_t = _ours(n, d, lam, theta0, pol)
            worst = max(worst, abs(r - ref["r"]), abs(t - ref["t"]), abs(big_t - ref["T"]))
    assert worst < 1e-12


def test_a_quarter_wave_layer_of_index_sqrt_n0_n2_reflects_nothing_at_its_wavelength():
    """Macleod, Thin-Film Optical Filters §3: n₁ = √(n₀n₂), n₁d = λ/4: R = 0 at normal incidence;
    a half-wave layer leaves the bare interface's R = ((n₀ − n₂)/(n₀ + n₂))²."""
    n0, n2, lam = 1.33, 3.9, 0.562
    n1 = math.sqrt(n0 * n2)
    for d, expected in ((lam / (4 * n1), 0.0), (lam / (2 * n1), ((n0 - n2) / (n0 + n2)) ** 2)):
        for pol in "sp":
            r, _, big_t = _ours(np.array([n0, n1, n2]), [math.inf, d, math.inf], lam, 0.0, pol)
            assert abs(r) ** 2 == pytest.approx(expected, abs=1e-15)
            assert big_t == pytest.approx(1.0 - expected, abs=1e-14)


def test_lossless_stacks_conserve_energy_and_a_zero_thickness_layer_is_not_there():
    """R + T = 1 without absorption, at every angle (total reflection: T = 0); a layer of zero
    thickness gives the bare interface's Fresnel transmittance, at every angle."""
    rng = np.random.default_rng(5)
    theta = np.linspace(0.0, 1.55, 200)[:, None]
    for _ in range(20):
        n = rng.uniform(1.0, 4.0, 4)
        idx = [np.full((1, 1), v, complex) for v in n]
        d = np.array([0.0, *rng.uniform(0.0, 2.0, 2), 0.0])
        beta = n[0] * np.sin(theta)
        for pol in "sp":
            r, _ = thinfilm.amplitudes(idx, d, np.array([[0.55]]), beta, pol)
            big_t = thinfilm.transmittance(idx, d, np.array([[0.55]]), beta, pol)
            assert np.allclose(np.abs(r) ** 2 + big_t, 1.0, atol=1e-12)
    n0, n1, n2 = 1.33, 2.0, 1.46
    beta = n0 * np.sin(np.linspace(0.0, 1.5, 50))
    ts, tp = fresnel_polarised(n0, n2, beta)
    idx = [np.full((1, 1), v, complex) for v in (n0, n1, n2)]
    for pol, bare in (("s", ts), ("p", tp)):
        big_t = thinfilm.transmittance(idx, np.zeros(3), np.array([[0.55]]), beta[:, None], pol)
        assert np.allclose(big_t[:, 0], bare, atol=1e-14)


def test_a_thick_layer_averaged_over_the_band_is_the_incoherent_slab():
    """REFERENCE §2's incoherent slab, ½∫ T₁₂T₂₃/(1 − R₂₁R₂₃) sinθ dθ per polarisation, for
    1 µm of water over 14 µm of oxide on silicon (n 4.3): the coherent sum over the luciferase's
    band (coherence length 4.5 µm, against the oxide's 41 µm round trip) is within 1e-4 of it;
    a narrow 2 nm line through a 1 µm oxide keeps its fringes and is not."""
    water, oxide = Layer("water", 1.33, 1.0), Layer("oxide", 1.46, 14.0)
    stack = Stack((water, oxide), silicon_n=4.3)
    incoherent = plane_fraction_stack(stack, "isotropic", into_silicon=True,
                                      reflections="incoherent")
    coherent = plane_fraction_stack(stack, "isotropic", into_silicon=True,
                                    reflections="coherent")
    assert coherent == pytest.approx(incoherent, rel=1e-4)
    thin = Stack((water, Layer("oxide", 1.46, 0.5)), silicon_n=4.3)
    line = thinfilm.Band(fwhm_nm=2.0)
    fringes = plane_fraction_stack(thin, "isotropic", into_silicon=True, reflections="coherent",
                                   band=line)
    flat = plane_fraction_stack(thin, "isotropic", into_silicon=True, reflections="incoherent")
    assert abs(fringes / flat - 1) > 0.01


def test_light_tunnels_through_a_thin_low_index_gap():
    """Frustrated total reflection: glass | water gap | glass. The ray picture loses every ray
    beyond water's critical angle whatever the gap; coherently, a gap → 0 passes them all (the
    plane fraction tends to the gapless glass's 0.5 of an isotropic emitter) and a wide gap
    none (the incoherent fraction)."""
    def stack(gap_um):
        return Stack((Layer("glass", 1.5, 1.0), Layer("water", 1.33, gap_um),
                      Layer("glass", 1.5, 10.0)))

    incoherent = plane_fraction_stack(stack(0.2), "isotropic", reflections="incoherent")
    gaps = [0.0, 0.02, 0.1, 0.5, 3.0]
    coherent = [plane_fraction_stack(stack(g), "isotropic", reflections="coherent") for g in gaps]
    assert coherent[0] == pytest.approx(0.5, rel=1e-6)
    assert all(a > b for a, b in zip(coherent, coherent[1:], strict=False))
    assert coherent[-1] == pytest.approx(incoherent, rel=0.01) and coherent[2] > 1.2 * incoherent


def test_band_and_inputs_are_checked():
    with pytest.raises(ValueError, match="fwhm_nm = 0.5, allowed"):
        thinfilm.Band(fwhm_nm=0.5)
    with pytest.raises(ValueError, match="pol = 'x'"):
        thinfilm.amplitudes([np.ones((1, 1))] * 2, np.zeros(2), np.ones((1, 1)),
                            np.zeros((1, 1)), "x")
    with pytest.raises(ValueError, match="'single', 'incoherent' or 'coherent'"):
        plane_fraction_stack(Stack((Layer("w", 1.33, 1.0),)), "isotropic", reflections="phase")


NITRIDE_FILM = Stack((Layer("water", 1.33, 1.0), Layer("nitride", 2.0, 0.1),
                      Layer("oxide", 1.46, 3.0)), silicon_n=1.46)
WATER_GAP = Stack((Layer("glass", 1.5, 1.0), Layer("water gap", 1.33, 0.1),
                   Layer("glass", 1.5, 3.0)), silicon_n=1.5)


@pytest.mark.parametrize("stack", [NITRIDE_FILM, WATER_GAP], ids=["nitride film", "water gap"])
def test_psf_and_raytrace_levels_cross_films_coherently_and_agree(stack):
    """The psf level (films in place in the radial profile) and the raytrace level (each ray a
    wavelength of the band, films as coherent tables) on a 5 × 5 grid of 4 µm pixels: every
    pixel within 4 SE of 400,000 traced rays, and the plane fraction the full transfer matrix's
    (no other interface reflects here). Rays alone (thin_film_um = 0) are far off: the nitride
    film reflects 8 % more than its two bare interfaces, and 50 % more light tunnels through the
    water gap than the ray picture passes (0.375 against 0.249)."""
    from chiptwin.optics.raytrace import raytrace
    from chiptwin.optics.stack_psf import coupling_stack

    grid = dict(n_rows=5, n_cols=5, pitch_um=4.0, diode_w_um=3.0, diode_h_um=3.0,
                site_x_um=[10.0], site_y_um=[10.0])
    n = 400_000
    traced = raytrace(stack, rng=np.random.default_rng(18), n_rays=n, cache=False, **grid)
    psf = coupling_stack(stack=stack, emitter="isotropic", **grid)
    se = np.sqrt(psf * (1 - psf) / n)
    assert np.all(np.abs(traced.coupling - psf) <= 4 * se + 1e-12)
    plane = plane_fraction_stack(stack, "isotropic")
    assert plane == pytest.approx(plane_fraction_stack(stack, "isotropic",
                                                       reflections="coherent"), rel=1e-5)
    rays_only = plane_fraction_stack(Stack(stack.layers, stack.silicon_n, thin_film_um=0.0),
                                     "isotropic")
    transmitted = float(traced.transmitted[0])
    assert abs(transmitted - plane) <= 4 * math.sqrt(plane * (1 - plane) / n)
    assert abs(rays_only - plane) > 0.08 * plane
