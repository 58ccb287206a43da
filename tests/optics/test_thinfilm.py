"""Thin films by transfer matrices (chiptwin.optics.thinfilm): against S. J. Byrnes' ``tmm``
package (an independent implementation) on random stacks, absorbing and evanescent layers among
them; against closed forms (a quarter-wave anti-reflection layer, a half-wave layer that is not
there, energy conservation); and the band average of a thick layer against the incoherent slab
of sources.md O8."""

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
    """The incoherent slab (sources.md O8), ½∫ T₁₂T₂₃/(1 − R₂₁R₂₃) sinθ dθ per polarisation, for
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


def test_a_ray_at_a_films_critical_angle_and_a_first_layer_denser_than_the_last():
    """β exactly at a film's index (q = 0 there: 0/0 in its interfaces) gives the finite limit
    (2.0 | 0.1 µm of 1.5 | 2.0 at β = 1.5: T_s 0.64648, T_p 0.85252, as at β − 1e-7); a first
    layer denser than the last (glass | 0.1 µm water | water) has a finite coherent fraction,
    the psf level's, where a 0/0 beyond the last layer's critical angle once made it NaN; and
    the coherent fraction is averaged over the stack's own band."""
    idx = [np.full((1, 1), v, complex) for v in (2.0, 1.5, 2.0)]
    d, lam = np.array([0.0, 0.1, 0.0]), np.array([[0.562]])
    for pol in "sp":
        at = thinfilm.transmittance(idx, d, lam, np.array([[1.5]]), pol).item()
        near = thinfilm.transmittance(idx, d, lam, np.array([[1.5 - 1e-7]]), pol).item()
        assert np.isfinite(at) and at == pytest.approx(near, abs=1e-4)
    dense = Stack((Layer("glass", 1.5, 1.0), Layer("water", 1.33, 0.1),
                   Layer("water", 1.33, 3.0)), silicon_n=1.33)
    coherent = plane_fraction_stack(dense, "isotropic", reflections="coherent")
    assert coherent == pytest.approx(plane_fraction_stack(dense, "isotropic"), rel=1e-4)
    blue = Stack(NITRIDE_FILM.layers, 1.46, band=thinfilm.Band(450.0, 5.0))
    assert plane_fraction_stack(blue, "isotropic", reflections="coherent") == pytest.approx(
        plane_fraction_stack(blue, "isotropic"), rel=1e-6)
    assert abs(plane_fraction_stack(blue, "isotropic") / plane_fraction_stack(
        NITRIDE_FILM, "isotropic") - 1) > 0.05


def test_two_film_groups_average_their_product_over_the_band():
    """A ray of one wavelength meets both films: ⟨T₁T₂⟩ over the band, against an explicit loop
    over the wavelengths (oracle), which differs from ⟨T₁⟩⟨T₂⟩ by up to 0.36 % for 1 µm of
    nitride on either side of 5 µm of oxide (the fringes of the two films are correlated; a
    review measured ≈ 1 % of the psf plane fraction)."""
    water, oxide, si = Layer("w", 1.33, 0.0), Layer("o", 1.46, 5.0), Layer("si", 4.3, 0.0)
    g1, g2 = (water, Layer("n", 2.0, 1.0), oxide), (oxide, Layer("n", 2.0, 1.0), si)
    band = thinfilm.Band()
    beta = np.linspace(0.0, 1.3, 7)
    count = max(band.node_count(g1), band.node_count(g2))
    lam, w = band.nodes(count)
    for k, pol in enumerate("sp"):
        got = thinfilm.band_product([g1, g2], beta, band)[k]
        loop = np.zeros(beta.size)
        for lam_i, w_i in zip(lam, w, strict=True):
            t = [thinfilm.transmittance(thinfilm.complex_indices(g, np.array([lam_i])),
                                        np.array([x.thickness_um for x in g]),
                                        np.array([[lam_i]]), beta[:, None], pol)[:, 0]
                 for g in (g1, g2)]
            loop += w_i * t[0] * t[1]
        np.testing.assert_allclose(got, loop, rtol=1e-12)
        apart = thinfilm.band_product([g1], beta, band, count)[k] * thinfilm.band_product(
            [g2], beta, band, count)[k]
        assert np.max(np.abs(apart / got - 1)) > 0.002


def test_raytrace_film_tables_interpolate_within_2e_4():
    """The raytrace level's tables (FILM_COS_NODES over the incidence cosine: uniform up to the
    exit's critical cosine, then in the exit's own cosine), read by the kernel's lookup, against
    the transfer matrix at 4,000 random cosines and band wavelengths per group, direction and
    polarisation: within 2e-4 everywhere (uniform in cos θ alone they were 0.016 off in the cell
    holding an exit's critical angle and above 2e-4 for the next 3-10 cells)."""
    from chiptwin.optics import _raytrace_kernels as _k
    from chiptwin.optics.raytrace import _stack_arrays

    stack = Stack((Layer("water", 1.33, 1.0), Layer("nitride", 2.0, 0.1),
                   Layer("oxide", 1.46, 3.0), Layer("nitride", 2.0, 2.0)), silicon_n=4.3)
    tab, cos_c = _stack_arrays(stack, 4.3)[6:8]
    lam, _ = stack.band.nodes(tab.shape[4])
    rays, films = Stack(stack.layers + (Layer("below", 4.3, 0.0),), 4.3).ray_path()
    groups = [(rays[k], *f, rays[k + 1]) for k, f in enumerate(films) if f]
    rng = np.random.default_rng(1025)
    for f, group in enumerate(groups):
        for way, layers in enumerate((group, group[::-1])):
            if way == 1 and f == len(groups) - 1:
                continue  # up out of the silicon: nothing goes there, the table is not built
            c, li = rng.uniform(0.0, 1.0, 4000), rng.integers(0, lam.size, 4000)
            idx = thinfilm.complex_indices(layers, lam)
            d = np.array([layer.thickness_um for layer in layers])
            beta = (layers[0].n * np.sqrt(1 - c * c))[:, None]
            for p, pol in enumerate("sp"):
                r, _ = thinfilm.amplitudes(idx, d, lam[None, :], beta, pol)
                big_t = thinfilm.transmittance(idx, d, lam[None, :], beta, pol)
                pick = (np.arange(c.size), li)
                got = np.array([_k._film_rt(tab, cos_c, f, way, p, li[m], c[m])
                                for m in range(c.size)])
                assert np.abs(got[:, 0] - np.abs(r[pick]) ** 2).max() < 2e-4, (f, way, pol)
                assert np.abs(got[:, 1] - big_t[pick]).max() < 2e-4, (f, way, pol)


def _inc_tmm_plane_fraction(tmm, layers, films_mask, band, count, alpha=None):
    """The oracle of the raytrace level's plane fraction: Byrnes' inc_tmm (ray layers
    incoherent, films coherent), isotropic emitter, ½∫ ½(T_s + T_p) sin θ dθ by 24-point
    Gauss–Legendre on each of 4 angle panels (the same to 1e-15 as 96 points), averaged over the
    band's own nodes (the ones a ray draws from); and the share absorbed in each layer."""
    lam, w = band.nodes(count)
    x, gw = np.polynomial.legendre.leggauss(24)
    edges = np.linspace(0.0, math.pi / 2, 5)
    trans, absorbed = 0.0, np.zeros(len(layers))
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        for xi, wi in zip(x, gw, strict=True):
            th = 0.5 * (lo + hi) + 0.5 * (hi - lo) * xi
            dens = 0.5 * math.sin(th) * 0.5 * (hi - lo) * wi
            for lam_i, w_i in zip(lam, w, strict=True):
                n = [layer.n + 1j * layer.alpha_per_um * lam_i / (4 * math.pi) if m else layer.n
                     for layer, m in zip(layers, films_mask, strict=True)]
                d = [math.inf, *[layer.thickness_um for layer in layers[1:-1]], math.inf]
                c = ["c" if m else "i" for m in films_mask]
                for pol in "sp":
                    res = tmm.inc_tmm(pol, n, d, c, th, lam_i)
                    trans += dens * w_i * 0.5 * res["T"]
                    absorbed += dens * w_i * 0.5 * np.array(tmm.inc_absorp_in_each_layer(res))
    return trans, absorbed


def test_raytrace_crosses_films_both_ways_as_incoherent_tmm_says():
    """water | 0.1 µm nitride | 3 µm oxide | 0.6 µm absorbing nitride | silicon 4.3: light
    reflected at the lower group crosses the upper one going up (the reversed tables), the
    lower group sits above the silicon (the plane below appended), absorbs (booked to its film)
    and both groups are met at one wavelength a ray. Oracle: Byrnes' tmm.inc_tmm (oxide
    incoherent, films coherent) over the same band nodes: transmitted into the silicon and
    absorbed in the lower film, each within 4 SE of 400,000 rays."""
    tmm = require_module("tmm")
    from chiptwin.optics.raytrace import _stack_arrays, raytrace

    water, oxide = Layer("water", 1.33, 1.0), Layer("oxide", 1.46, 3.0)
    lossy = Layer("nitride", 2.0, 0.6, alpha_per_um=0.5)
    stack = Stack((water, Layer("nitride", 2.0, 0.1), oxide, lossy), silicon_n=4.3)
    n = 400_000
    r = raytrace(stack, n_rows=1, n_cols=1, pitch_um=1e4, diode_w_um=1e4, diode_h_um=1e4,
                 site_x_um=[5e3], site_y_um=[5e3], rng=np.random.default_rng(20), n_rays=n,
                 cache=False)
    count = _stack_arrays(stack, 4.3)[6].shape[4]
    layers = (water, Layer("nitride", 2.0, 0.1), oxide, lossy, Layer("si", 4.3, 0.0))
    trans, absorbed = _inc_tmm_plane_fraction(tmm, layers, (False, True, False, True, False),
                                              stack.band, count)
    ours = float(r.transmitted[0])
    assert abs(ours - trans) <= 4 * math.sqrt(trans * (1 - trans) / n), (ours, trans)
    film = float(r.absorbed_layers[0, 3])
    assert film > 0.01 and abs(film - absorbed[3]) <= 4 * math.sqrt(film * (1 - film) / n)
