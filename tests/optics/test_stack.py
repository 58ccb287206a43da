"""The psf level through a planar stack, and the faceplate.

Validation against the analytic plane fractions of sources.md O7–O10; equivalence with today's
closed form (bit-exact when routed, within 1e-6 of the plane fraction on the general path);
quadrature references for slabs and absorption; energy; faceplate limits; the cross-talk trend.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from chiptwin.optics import psf
from chiptwin.optics import stack_psf as sp
from chiptwin.optics.faceplate import Faceplate
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.profile import build_profile, fresnel_unpolarised
from chiptwin.optics.reference_chip import ASSUMPTIONS, jssc2006_faceplate, jssc2006_stack

GRID = {"n_rows": 8, "n_cols": 16, "pitch_um": 100.0, "diode_w_um": 80.0, "diode_h_um": 60.0}
CHIP = {"n_rows": 8, "n_cols": 16, "pitch_um": 125.0, "diode_w_um": 100.0, "diode_h_um": 100.0}
OWN = 4 * 16 + 8


def interface(n1: float, n2: float, t1: float = 10.0) -> Stack:
    return Stack((Layer("above", n1, t1), Layer("below", n2, 0.0)))


def water_over_oxide(water_um: float, total_um: float = 15.0) -> Stack:
    return Stack((Layer("water", 1.33, water_um), Layer("oxide", 1.46, total_um - water_um)))


def t_pol(n1, n2, theta1):
    """Fresnel (Tₛ, Tₚ) written out independently from the amplitude reflectances (0 beyond the
    critical angle)."""
    s2 = n1 * np.sin(theta1) / n2
    if s2 >= 1:
        return 0.0, 0.0
    c1, c2 = np.cos(theta1), np.sqrt(1 - s2 * s2)
    rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)
    rp = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)
    return 1 - rs * rs, 1 - rp * rp


def t_unpol(n1, n2, theta1):
    """Unpolarised Fresnel T of one interface, (Tₛ + Tₚ)/2."""
    return 0.5 * sum(t_pol(n1, n2, theta1))


# --- validation: sources.md Optics ----------------------------------------------------------------

@pytest.mark.parametrize(("n1", "n2", "want"), [
    (1.33, 1.5, 0.4403), (1.5, 1.0, 0.1148), (1.33, 1.46, 0.4466), (1.5, 1.33, 0.2574),
    (1.33, 1.0, 0.1577), (1.0, 1.5, 0.3994), (1.46, 2.0, 0.4099), (1.33, 3.9, 0.3301)])
def test_one_interface_plane_fraction_matches_reference(n1, n2, want):
    """sources.md Optics: ½∫T(θ) sinθ dθ through one interface, unpolarised Fresnel, TIR included;
    4 decimals as printed, and the huge-diode coupling equals it (1e-9)."""
    got = sp.plane_fraction_stack(interface(n1, n2), "isotropic")
    assert got == pytest.approx(want, abs=5e-5)
    quad = integrate.quad(lambda th: 0.5 * t_unpol(n1, n2, th) * np.sin(th), 0, np.pi / 2,
                          limit=200, points=[np.arcsin(min(1, n2 / n1))])[0]
    assert got == pytest.approx(quad, abs=1e-10)


def test_fresnel_normal_incidence():
    """Normal incidence 1.33 → 1.5: T = 4 n1 n2/(n1 + n2)² = 0.996391 (textbook)."""
    t = fresnel_unpolarised(1.33, 1.5, np.array([0.0]))[0]
    assert t == pytest.approx(4 * 1.33 * 1.5 / 2.83**2, rel=1e-14)


def test_slab_single_pass_and_incoherent_sum_against_quadrature():
    """Water | 20 µm glass | air: single pass ½∫ ½(Tₛ12·Tₛ23 + Tₚ12·Tₚ23) sinθ dθ (s and p stay
    apart in a planar stack: the product of unpolarised averages is lower), and the incoherent
    slab sum ½∫ Σ_pol ½ T12 T23 / (1 − R21 R23) sinθ dθ per polarisation (sources.md Optics), to
    1e-10."""
    stack = Stack((Layer("water", 1.33, 5.0), Layer("glass", 1.5, 20.0), Layer("air", 1.0, 0.0)))

    def single(th):
        th2 = np.arcsin(1.33 * np.sin(th) / 1.5)
        (s12, p12), (s23, p23) = t_pol(1.33, 1.5, th), t_pol(1.5, 1.0, th2)
        return 0.5 * 0.5 * (s12 * s23 + p12 * p23) * np.sin(th)

    def product_of_averages(th):
        th2 = np.arcsin(1.33 * np.sin(th) / 1.5)
        return 0.5 * t_unpol(1.33, 1.5, th) * t_unpol(1.5, 1.0, th2) * np.sin(th)

    def slab(th):
        s2, s3 = 1.33 * np.sin(th) / 1.5, 1.33 * np.sin(th)
        if s3 >= 1:
            return 0.0
        c1, c2, c3 = np.cos(th), np.sqrt(1 - s2 * s2), np.sqrt(1 - s3 * s3)
        out = 0.0
        for a, b in (((1.33 * c1, 1.5 * c2), (1.5 * c2, 1.0 * c3)),
                     ((1.5 * c1, 1.33 * c2), (1.0 * c2, 1.5 * c3))):
            r12 = ((a[0] - a[1]) / (a[0] + a[1])) ** 2
            r23 = ((b[0] - b[1]) / (b[0] + b[1])) ** 2
            out += 0.5 * (1 - r12) * (1 - r23) / (1 - r12 * r23)
        return 0.5 * out * np.sin(th)

    edge = [np.arcsin(1 / 1.33)]
    want_single = integrate.quad(single, 0, np.pi / 2, points=edge, limit=200)[0]
    want_slab = integrate.quad(slab, 0, np.pi / 2, points=edge, limit=200)[0]
    assert sp.plane_fraction_stack(stack, "isotropic") == pytest.approx(want_single, abs=1e-10)
    averaged = integrate.quad(product_of_averages, 0, np.pi / 2, points=edge, limit=200)[0]
    assert want_single - averaged > 2e-5  # what the product of averages lost (0.03 % here)
    got = sp.plane_fraction_stack(stack, "isotropic", reflections="incoherent")
    assert got == pytest.approx(want_slab, abs=1e-10)
    assert 0 < got - want_single < 0.01  # the multiple reflections the single pass leaves out


def test_beer_lambert_along_oblique_paths():
    """An absorbing 5 µm layer (α = 0.05 /µm) under water: ½∫T exp(−α t / cos θ₂) sinθ dθ."""
    alpha, t = 0.05, 5.0
    stack = Stack((Layer("water", 1.33, 3.0), Layer("dye", 1.5, t, alpha)))

    def f(th):
        c2 = np.sqrt(1 - (1.33 * np.sin(th) / 1.5) ** 2)
        return 0.5 * t_unpol(1.33, 1.5, th) * np.exp(-alpha * t / c2) * np.sin(th)

    want = integrate.quad(f, 0, np.pi / 2, limit=200)[0]
    assert sp.plane_fraction_stack(stack, "isotropic") == pytest.approx(want, abs=1e-10)
    # absorption in the emitting layer too: exp(−α U / cos θ) for one medium
    one = Stack((Layer("absorbing water", 1.33, 10.0, 0.02),))
    want = integrate.quad(lambda th: 0.5 * np.exp(-0.2 / np.cos(th)) * np.sin(th), 0,
                          np.pi / 2)[0]
    assert sp.plane_fraction_stack(one, "isotropic") == pytest.approx(want, abs=1e-10)


# --- equivalence with today's closed form ------------------------------------------------------

HOMOGENEOUS = Stack((Layer("water", 1.33, 4.0), Layer("water", 1.33, 8.0)))
FOOTPRINTS = [{}, {"site_radius_um": 30.0}, {"site_side_um": 50.0}]


@pytest.mark.parametrize("footprint", FOOTPRINTS)
@pytest.mark.parametrize(("emitter", "convention"), [("isotropic", "isotropic"),
                                                     ("lambertian", "lambertian_na2")])
def test_homogeneous_stack_is_todays_psf_exactly(footprint, emitter, convention):
    """The auto route gives today's coupling_psf bit for bit (np.array_equal)."""
    x, y = psf.pixel_centers_um(GRID["n_rows"], GRID["n_cols"], GRID["pitch_um"])
    got = sp.coupling_stack(**GRID, site_x_um=x, site_y_um=y, stack=HOMOGENEOUS,
                            emitter=emitter, **footprint)
    want = psf.coupling_psf(**GRID, site_x_um=x, site_y_um=y, height_um=12.0,
                            convention=convention, **footprint)
    assert np.array_equal(got, want)


@pytest.mark.parametrize("footprint", FOOTPRINTS[:2])
@pytest.mark.parametrize(("emitter", "convention"), [("isotropic", "isotropic"),
                                                     ("lambertian", "lambertian_na2")])
def test_general_path_reproduces_closed_form(footprint, emitter, convention):
    """The radial-profile path on a homogeneous stack: every entry within 1e-6 × plane fraction
    of the closed form (measured: ≤ 3e-14 on the 125 µm chip, ≤ 6e-12 at 15 µm), own pixel
    within 1e-6 relative."""
    rng = np.random.default_rng(3)
    sx, sy = rng.uniform(0, 1600, 4), rng.uniform(0, 800, 4)
    args = dict(**GRID, site_x_um=sx, site_y_um=sy, **footprint)
    got = sp.coupling_stack(**args, stack=HOMOGENEOUS, emitter=emitter, method="radial")
    want = psf.coupling_psf(**args, height_um=12.0, convention=convention)
    plane = 0.5 if emitter == "isotropic" else 1.0
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * plane)
    big = want > 1e-3
    np.testing.assert_allclose(got[big], want[big], rtol=1e-6)


def test_profile_matches_homogeneous_cumulative():
    """P(ρ) of one medium: ½(1 − U/√(ρ² + U²)), to 1e-10 on a dense grid."""
    p = build_profile(HOMOGENEOUS, "isotropic")
    r = np.linspace(0, 400, 40001)
    np.testing.assert_allclose(p.cumulative(r), 0.5 * (1 - 12 / np.hypot(r, 12)), atol=1e-10)


# --- energy ------------------------------------------------------------------------------------

@pytest.mark.parametrize("stack", [water_over_oxide(1.0), interface(1.5, 1.0),
                                   Stack((Layer("w", 1.33, 2.0), Layer("g", 1.5, 30.0),
                                          Layer("n", 2.0, 0.5)))])
def test_huge_diode_collects_the_plane_fraction(stack):
    """One diode of 1e7 µm under a centred point source: the plane fraction, to 1e-9."""
    c = sp.coupling_stack(n_rows=1, n_cols=1, pitch_um=1e7, diode_w_um=1e7, diode_h_um=1e7,
                          site_x_um=[5e6], site_y_um=[5e6], stack=stack, emitter="isotropic")
    assert c[0, 0] == pytest.approx(sp.plane_fraction_stack(stack, "isotropic"), abs=1e-9)


# --- faceplate -----------------------------------------------------------------------------------

def pyro_sites():
    x, y = psf.pixel_centers_um(8, 16, 125.0)
    return x[[OWN, 2 * 16 + 3]], y[[OWN, 2 * 16 + 3]]


def test_faceplate_small_na_own_pixel_only():
    """NA 0.1 under 10 µm of water: everything lands on the own diode, with the accepted
    fraction (1 − cos θ_NA)/2 × open area, sin θ_NA = 0.1/1.33 (isotropic), to 1e-12."""
    sx, sy = pyro_sites()
    fp = Faceplate(na=0.1, fiber_pitch_um=6.0, thickness_um=1000.0, open_area_ratio=0.7)
    c = sp.coupling_stack(**CHIP, site_x_um=sx, site_y_um=sy, stack=jssc2006_stack(),
                          emitter="isotropic", faceplate=fp, site_radius_um=20.0)
    want = 0.7 * (1 - np.cos(np.arcsin(0.1 / 1.33))) / 2
    assert c[OWN, 0] == pytest.approx(want, rel=1e-12)
    assert np.delete(c[:, 0], OWN).max() < 1e-15


def test_faceplate_full_acceptance_is_open_area_times_the_stack():
    """NA ≥ the stack's smallest index accepts all the light: a huge diode collects
    open_area × plane fraction (1e-9); a pitch-sized blur changes nothing on it."""
    stack = water_over_oxide(1.0)
    fp = Faceplate(na=1.46, fiber_pitch_um=6.0, thickness_um=500.0, open_area_ratio=0.6)
    c = sp.coupling_stack(n_rows=1, n_cols=1, pitch_um=1e7, diode_w_um=1e7, diode_h_um=1e7,
                          site_x_um=[5e6], site_y_um=[5e6], stack=stack, emitter="isotropic",
                          faceplate=fp)
    assert c[0, 0] == pytest.approx(0.6 * sp.plane_fraction_stack(stack, "isotropic"), abs=1e-9)


def test_jssc2006_faceplate_kills_cross_talk():
    """Reference chip, assumed faceplate (NA 1.0, 6 µm, 70 %, core 1.8): neighbours < 1e-12,
    own pixel below the direct-contact stack's (the acceptance cone costs light)."""
    sx, sy = pyro_sites()
    c = sp.coupling_stack(**CHIP, site_x_um=sx, site_y_um=sy, stack=jssc2006_stack(),
                          emitter="isotropic", faceplate=jssc2006_faceplate(), site_radius_um=20.0)
    assert np.delete(c[:, 0], OWN).max() < 1e-12
    assert 0.05 < c[OWN, 0] < 0.3
    assert "passivation" in ASSUMPTIONS


# --- physical sanity: the cross-talk trend -------------------------------------------------------

def test_cross_talk_falls_as_the_water_gap_shrinks():
    """pyro_1fmol geometry, water over oxide to 15 µm: neighbour/own falls monotonically as the
    gap shrinks; at 1 µm −34.1 dB (a ray trace: −34 dB, sources.md O18; one-medium psf −16.7 dB)."""
    sx, sy = pyro_sites()
    xt = []
    for gap in (10.0, 3.0, 1.0, 0.3, 0.1):
        c = sp.coupling_stack(**CHIP, site_x_um=sx, site_y_um=sy, stack=water_over_oxide(gap),
                              emitter="isotropic", site_radius_um=20.0)
        xt.append(10 * np.log10(c[OWN + 1, 0] / c[OWN, 0]))
    assert np.all(np.diff(xt) < 0)
    assert xt[2] == pytest.approx(-34.1, abs=0.5)


def test_emitter_laws_and_convention():
    """lambertian on a homogeneous stack is the NA² closed form; collected_fractions reports
    all three; the Lambertian law collects more than the isotropic one."""
    sx, sy = pyro_sites()
    got = sp.collected_fractions(**CHIP, site_x_um=sx, site_y_um=sy, stack=water_over_oxide(1.0),
                                 site_radius_um=20.0)
    assert set(got) == {"isotropic", "lambertian", "lambertian_na2"}
    assert got["isotropic"] < got["lambertian"] <= 1.0
    with pytest.raises(ValueError, match="emitter"):
        sp.check_emitter("lambertian_cos")


def test_errors():
    with pytest.raises(ValueError, match="na = 0"):
        Faceplate(na=0.0, fiber_pitch_um=6.0, thickness_um=1.0, open_area_ratio=0.5)
    with pytest.raises(ValueError, match="open_area_ratio"):
        Faceplate(na=0.5, fiber_pitch_um=6.0, thickness_um=1.0, open_area_ratio=1.5)
    with pytest.raises(ValueError, match="method"):
        sp.coupling_stack(**CHIP, site_x_um=[1.0], site_y_um=[1.0], stack=HOMOGENEOUS,
                          emitter="isotropic", method="exact")


@pytest.mark.parametrize(("side", "pitch"), [(0.0, 6.0), (10.0, 6.0), (4.0, 13.0), (12.0, 3.0)])
def test_blur_nodes_have_the_moments_of_the_footprint_and_fibre_kernels(side, pitch):
    """A square footprint (uniform over its side) ⊛ the faceplate's exit − entry (a triangle on
    ± the pitch, variance p²/6) is separable: one axis's nodes integrate its moments exactly,
    Var = s²/12 + p²/6 and E[X⁴] = s⁴/80 + 6·(s²/12)·(p²/6) + p⁴/15 (closed forms), with n² nodes
    in two dimensions, not n⁴ (a square footprint under a faceplate never finished on a 5 × 5
    grid)."""
    from chiptwin.optics.faceplate import Faceplate

    q, w = sp._axis_nodes(side, pitch, 16)
    assert w.min() > 0 and w.sum() == pytest.approx(1.0, abs=1e-15)
    assert w @ q == pytest.approx(0.0, abs=1e-12)
    assert w @ q**2 == pytest.approx(side**2 / 12 + pitch**2 / 6, rel=1e-12)
    want4 = side**4 / 80 + 6 * (side**2 / 12) * (pitch**2 / 6) + pitch**4 / 15
    assert w @ q**4 == pytest.approx(want4, rel=1e-12)
    qx, _, wx = sp._blur_nodes(side, Faceplate(1.0, pitch, 100.0, 0.8, 1.6), 16)
    assert qx.size == q.size**2 and wx.sum() == pytest.approx(1.0, abs=1e-14)
