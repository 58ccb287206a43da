"""The site's top surface (:mod:`chiptwin.optics.top`) at the psf and raytrace levels.

Kinds: validation (the returned share against an independent quadrature of Fresnel's
equations, Born & Wolf §1.5.2: water 1.33 under air, TIR beyond 48.75°; a glass lid's
incoherent slab), equivalence (psf's image source against the tracer pixel by pixel, where the
tracer's extra passes vanish: an index-matched plane, the jssc2006_faceplate geometry), unit
(the faceplate's acceptance of returned light, "solution" bit for bit, refusals).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from chiptwin.optics.faceplate import Faceplate
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.profile import build_profile
from chiptwin.optics.raytrace import raytrace
from chiptwin.optics.stack_psf import coupling_stack, plane_fraction_stack
from chiptwin.optics.top import Top, returned_fraction

SIGMAS = 4.0
WATER = 1.33
AIR_TOP = Top("air", solution_depth_um=5.0)
LID_TOP = Top("glass", solution_depth_um=5.0, lid_n=1.5, lid_thickness_um=8.0)


def _r(n1: float, n2: float, c1: float) -> tuple[float, float]:
    """Rs, Rp at ``n1 → n2`` for the incidence cosine ``c1``; (1, 1) beyond the critical angle."""
    s2 = (n1 / n2) ** 2 * (1.0 - c1 * c1)
    if s2 >= 1.0:
        return 1.0, 1.0
    c2 = math.sqrt(1.0 - s2)
    rs = ((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)) ** 2
    rp = ((n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)) ** 2
    return rs, rp


def _r_air(c0: float) -> float:
    """Unpolarised reflectance of water's free surface under air at ``cos θ₀ = c0``."""
    return 0.5 * sum(_r(WATER, 1.0, c0))


def _r_lid(c0: float, n_lid: float = 1.5) -> float:
    """Incoherent slab water → glass → air, per polarisation then averaged:
    ``R₁₂ + T₁₂² R₂₃ / (1 − R₁₂ R₂₃)``."""
    s2 = (WATER / n_lid) ** 2 * (1.0 - c0 * c0)
    cg = math.sqrt(1.0 - s2)
    out = 0.0
    for r12, r23 in zip(_r(WATER, n_lid, c0), _r(n_lid, 1.0, cg), strict=True):
        out += 0.5 * (r12 + (1 - r12) ** 2 * r23 / (1 - r12 * r23))
    return out


def _half_integral(r, lo: float = 0.0, hi: float = 1.0) -> float:
    """½∫ R(θ) sinθ dθ over ``cos θ`` in ``[lo, hi]``, split at water → air's critical cosine."""
    cc = math.sqrt(1.0 - 1.0 / WATER**2)
    cuts = sorted({lo, hi, *([cc] if lo < cc < hi else [])})
    return 0.5 * sum(integrate.quad(r, a, b, epsabs=1e-13, limit=200)[0]
                     for a, b in zip(cuts[:-1], cuts[1:], strict=True))


def _plane(stack: Stack, top: Top | None, n: int, seed: int = 1, **kw):
    return raytrace(stack, n_rows=1, n_cols=1, pitch_um=10.0, diode_w_um=10.0, diode_h_um=10.0,
                    site_x_um=[5.0], site_y_um=[5.0], rng=np.random.default_rng(seed),
                    n_rays=n, cache=False, top=top, **kw)


def _within(value: float, expected: float, n: int) -> None:
    se = math.sqrt(expected * (1.0 - expected) / n)
    assert abs(value - expected) <= SIGMAS * se, (value, expected, (value - expected) / se)


# --- validation: the returned share --------------------------------------------------------------


def test_tir_third_and_returned_share_of_water_under_air():
    """Born & Wolf §1.5 (Fresnel, TIR): of an isotropic emitter's light in water (1.33), the
    part beyond the critical angle upwards, ½cos θc = 0.3297 (θc = 48.75°), returns by TIR; with
    the Fresnel share inside the cone, ½∫R sinθ dθ = 0.34233 returns, and 0.5 − 0.34233 =
    0.15767 leaves (the published one-interface 1.33 → 1.0 transmission, 0.1577). The psf
    level's closed quadrature and its profile within 1e-8 of this test's own integral."""
    cc = math.sqrt(1.0 - 1.0 / WATER**2)
    assert math.degrees(math.acos(cc)) == pytest.approx(48.75, abs=0.01)
    assert 0.5 * cc == pytest.approx(0.3297, abs=1e-4)
    assert _half_integral(_r_air, 0.0, cc) == pytest.approx(0.5 * cc, abs=1e-12)  # TIR: R = 1
    expected = _half_integral(_r_air)
    assert expected == pytest.approx(0.5 - 0.1577, abs=5e-5)
    assert returned_fraction(AIR_TOP, WATER) == pytest.approx(expected, abs=1e-9)
    stack = Stack((Layer("water", WATER, 4.0),), silicon_n=WATER)
    assert build_profile(stack, "isotropic", top=AIR_TOP).total == pytest.approx(expected,
                                                                                  abs=1e-8)


@pytest.mark.parametrize(("top", "r"), [(AIR_TOP, _r_air), (LID_TOP, _r_lid)],
                         ids=["air", "glass"])
def test_returned_share_by_angle(top, r):
    """The returned light as a function of angle: over an index-matched (absorbing) plane 4 µm
    below the site, a ray returned at θ₀ lands ``(2D + 4 µm)·tanθ₀`` from the site (the lid
    adds ``2t·tanθ_g``), so the psf profile's cumulative at that radius is ½∫₀^θ₀ R sinθ dθ
    (this test's quadrature; 1e-7: the profile's Hermite interpolation, checked at 8 angles,
    across the critical angle). The tracer's returned share (transmitted − ½) within 4 SE of the
    whole integral (400,000 rays)."""
    stack = Stack((Layer("water", WATER, 4.0),), silicon_n=WATER)
    profile = build_profile(stack, "isotropic", top=top, part=top.parts - 1)
    front = (build_profile(stack, "isotropic", top=top, part=0) if top.parts > 1 else None)
    for deg in (10, 30, 45, 48.7, 48.8, 60, 75, 85):
        t0 = math.radians(deg)
        rho = (2 * top.solution_depth_um + 4.0) * math.tan(t0)
        got = float(profile.cumulative(rho))
        if front is not None:  # the lid's front face lands at the image point; the rest beyond
            beta = WATER * math.sin(t0)
            rho_g = rho + 2 * top.lid_thickness_um * beta / math.sqrt(top.lid_n**2 - beta**2)
            got = float(front.cumulative(rho) + profile.cumulative(rho_g))
        assert got == pytest.approx(_half_integral(r, math.cos(t0), 1.0), abs=1e-7), deg
    n = 400_000
    traced = _plane(stack, top, n)
    expected = _half_integral(r)
    _within(float(traced.transmitted[0]) - 0.5, expected, n)
    _within(float(traced.escaped_top[0]), 0.5 - expected, n)
    assert traced.truncated[0] == 0.0


# --- equivalence: psf's image source against the tracer ------------------------------------------


@pytest.mark.parametrize("top", [AIR_TOP, LID_TOP], ids=["air", "glass"])
def test_psf_equals_raytrace_over_an_index_matched_plane(top):
    """Over an index-matched plane nothing comes back up from below, so the tracer returns each
    ray at most once, as the psf level's single reflection does: the matrices agree pixel by
    pixel within 4 SE (5 × 5 pixels of 20 µm, diodes 15 × 12 µm, two sites, disc footprint; the
    lid's rays that round the lid twice or more, placed one round trip short by psf, are below
    the error here)."""
    grid = dict(n_rows=5, n_cols=5, pitch_um=20.0, diode_w_um=15.0, diode_h_um=12.0,
                site_x_um=[50.0, 37.0], site_y_um=[50.0, 61.0], site_radius_um=3.0)
    stack = Stack((Layer("water", WATER, 6.0),), silicon_n=WATER)
    n = 200_000
    r = raytrace(stack, rng=np.random.default_rng(7), n_rays=n, cache=False, top=top, **grid)
    psf = coupling_stack(stack=stack, emitter="isotropic", top=top, **grid)
    direct = coupling_stack(stack=stack, emitter="isotropic", method="radial", **grid)
    assert np.all(psf[:, 0] - direct[:, 0] > 5e-4)  # every pixel sees returned light
    se = np.sqrt(psf * (1 - psf) / n)
    assert np.all(np.abs(r.coupling - psf) <= SIGMAS * se), np.max(np.abs(r.coupling - psf) / se)


def test_jssc2006_faceplate_geometry_with_an_open_top():
    """The jssc2006_faceplate scene's geometry (10 µm of water on an NA-1.0 faceplate, 6 µm
    fibres, 70 % open, no entry loss; 125 µm pitch, 100 µm diodes) under a 50 µm open top. The
    faceplate absorbs every ray it does not accept, so the tracer too returns each ray at most
    once: psf and raytrace agree pixel by pixel within 4 SE (3 × 3 pixels, 200,000 rays)."""
    grid = dict(n_rows=3, n_cols=3, pitch_um=125.0, diode_w_um=100.0, diode_h_um=100.0,
                site_x_um=[187.5], site_y_um=[187.5])
    stack = Stack((Layer("assay solution", WATER, 10.0),))
    fp = Faceplate(na=1.0, fiber_pitch_um=6.0, thickness_um=1000.0, open_area_ratio=0.7)
    top = Top("air", solution_depth_um=50.0)
    n = 200_000
    r = raytrace(stack, rng=np.random.default_rng(11), n_rays=n, cache=False, top=top,
                 faceplate=fp, **grid)
    psf = coupling_stack(stack=stack, emitter="isotropic", top=top, faceplate=fp, **grid)
    se = np.sqrt(psf * (1 - psf) / n)
    assert np.all(np.abs(r.coupling - psf) <= SIGMAS * se), np.max(np.abs(r.coupling - psf) / se)


def test_pyro_1fmol_stack_under_an_open_top():
    """The pyro_1fmol stack (1 µm water over 14 µm SiO₂ on an absorbing diode plane; 125 µm
    pitch, 100 µm diodes, 20 µm disc footprint) under an open top 50 µm up. Here the tracer is
    multi-pass: light the water/oxide interface reflects up is returned by the top too, which
    psf's single pass leaves out (measured with 2 M rays: the edge neighbour +1.8 % traced, the
    own pixel −0.09 %, 0.2 % of the light more in the window). At 400,000 rays (SE 1.7 % on a
    neighbour) that is within 4 SE: own pixel and edge neighbours agree within 4 SE, and the
    top's cross-talk, −17.2 dB against −34.1 dB without it, within 0.5 dB."""
    grid = dict(n_rows=3, n_cols=3, pitch_um=125.0, diode_w_um=100.0, diode_h_um=100.0,
                site_x_um=[187.5], site_y_um=[187.5], site_radius_um=20.0)
    stack = Stack((Layer("assay buffer", WATER, 1.0), Layer("SiO2", 1.46, 14.0)),
                  silicon_n=1.46)
    top = Top("air", solution_depth_um=50.0)
    n = 400_000
    r = raytrace(stack, rng=np.random.default_rng(13), n_rays=n, cache=False, top=top, **grid)
    psf = coupling_stack(stack=stack, emitter="isotropic", top=top, **grid)[:, 0]
    bare = coupling_stack(stack=stack, emitter="isotropic", **grid)[:, 0]
    traced = r.coupling[:, 0]
    for p in (4, 1, 3, 5, 7):  # own, then the edge neighbours
        se = math.sqrt(psf[p] * (1 - psf[p]) / n)
        assert abs(traced[p] - psf[p]) <= SIGMAS * se, (p, traced[p], psf[p])
    db = 10 * np.log10(np.array([psf[5] / psf[4], traced[5] / traced[4], bare[5] / bare[4]]))
    assert db[0] == pytest.approx(-17.17, abs=0.05) and abs(db[1] - db[0]) < 0.5
    assert db[2] == pytest.approx(-34.12, abs=0.05)


def test_faceplate_never_accepts_tir_returned_light():
    """Light returned by TIR travels at n·sinθ > 1 in water: an NA-1.0 faceplate's acceptance
    (n·sinθ ≤ NA) refuses all of it. What the faceplate passes of the returned light is the
    Fresnel share inside the cone only, 70 % × ½∫₀^θc R sinθ dθ (this test's quadrature), at
    the psf level (1e-8) and traced (the plane's share within 4 SE of
    70 % × (½(1 − cos θc) + that share))."""
    cc = math.sqrt(1.0 - 1.0 / WATER**2)
    inside = _half_integral(_r_air, cc, 1.0)
    assert 0.005 < inside < 0.02  # 2 % at normal incidence rising to 1 at the critical angle
    stack = Stack((Layer("water", WATER, 10.0),))
    fp = Faceplate(na=1.0, fiber_pitch_um=6.0, thickness_um=500.0, open_area_ratio=0.7)
    returned = build_profile(stack, "isotropic", na=fp.na, top=Top("air", 50.0)).total
    assert returned == pytest.approx(inside, abs=1e-8)
    n = 400_000
    r = _plane(stack, Top("air", 50.0), n, faceplate=fp)
    _within(float(r.transmitted[0]), 0.7 * (0.5 * (1.0 - cc) + inside), n)


# --- unit -------------------------------------------------------------------------------------


def test_solution_is_bit_for_bit_no_top():
    """``"solution"`` changes nothing: the psf matrix and every traced ray's fate are those of
    no top, to the bit (with a faceplate, walls and a silicon interface)."""
    grid = dict(n_rows=3, n_cols=3, pitch_um=20.0, diode_w_um=15.0, diode_h_um=12.0,
                site_x_um=[30.0], site_y_um=[30.0], site_radius_um=3.0)
    stack = Stack((Layer("water", WATER, 2.0), Layer("oxide", 1.46, 8.0)), silicon_n=4.3)
    sol = Top("solution", 50.0)
    for kw in ({"into_silicon": True}, {"faceplate": Faceplate(1.0, 6.0, 500.0, 0.7)}):
        a = coupling_stack(stack=stack, emitter="isotropic", **kw, **grid)
        assert np.array_equal(a, coupling_stack(stack=stack, emitter="isotropic", top=sol,
                                                **kw, **grid))
    for kw in ({"well_side_um": 10.0, "walls": "reflecting"}, {}):
        runs = [raytrace(stack, rng=np.random.default_rng(2), n_rays=20_000, cache=False,
                         top=t, **kw, **grid).counts for t in (None, sol)]
        assert np.array_equal(*runs)


def test_lambertian_and_na2_with_a_top():
    """A Lambertian emitter facing the diodes sends nothing up: the top changes nothing; the
    paper's one-medium lambertian_na2 convention refuses a top that returns light."""
    grid = dict(n_rows=3, n_cols=3, pitch_um=20.0, diode_w_um=15.0, diode_h_um=12.0,
                site_x_um=[30.0], site_y_um=[30.0])
    stack = Stack((Layer("water", WATER, 2.0), Layer("oxide", 1.46, 8.0)))
    a = coupling_stack(stack=stack, emitter="lambertian", **grid)
    assert np.array_equal(a, coupling_stack(stack=stack, emitter="lambertian", top=AIR_TOP,
                                            **grid))
    with pytest.raises(ValueError, match="one-medium"):
        coupling_stack(stack=stack, emitter="lambertian_na2", top=AIR_TOP, **grid)


def test_plane_fraction_with_a_top():
    """The single-pass plane fraction with a top is the direct one plus the returned share."""
    stack = Stack((Layer("water", WATER, 3.0),), silicon_n=WATER)
    direct = plane_fraction_stack(stack, "isotropic")
    assert plane_fraction_stack(stack, "isotropic", top=LID_TOP) == pytest.approx(
        direct + returned_fraction(LID_TOP, WATER), abs=1e-8)


@pytest.mark.parametrize(("kw", "match"), [
    ({"medium": "lid"}, "medium"),
    ({"medium": "air", "solution_depth_um": 0.0}, "solution_depth_um"),
    ({"medium": "glass", "solution_depth_um": 50.0}, "lid_thickness_um"),
    ({"medium": "glass", "solution_depth_um": 50.0, "lid_thickness_um": 10.0, "lid_n": 3.0},
     "lid_n"),
])
def test_top_checks_name_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        Top(**kw)


def test_lower_index_lid_is_refused():
    """A lid below the solution's index (TIR at its front face, a lateral path that diverges)
    is not modelled: both levels say so."""
    stack = Stack((Layer("oil", 1.52, 3.0),), silicon_n=1.52)
    lid = Top("glass", 50.0, lid_n=1.5, lid_thickness_um=100.0)
    with pytest.raises(ValueError, match="lid_n"):
        build_profile(stack, "isotropic", top=lid, part=1)
    with pytest.raises(ValueError, match="lid_n"):
        _plane(stack, lid, 100)


def test_returned_light_outside_the_well_lands_on_the_wall_tops():
    """Walls span the first layer up to the site plane; above it the solution extends sideways.
    A point site in a 4 µm absorbing well under an open top 50 µm up: a returned ray comes back
    inside the well only within 2·50·tanθ₀ ≤ 2 µm (θ₀ < 1.2°, 2e-6 of the light), so the walls'
    share grows by the returned share, 0.34233, within 4 SE. The wall material's top absorbs for
    mirror walls too (a mirror top under TIR would guide the light sideways without loss)."""
    stack = Stack((Layer("water", WATER, 1.0),), silicon_n=WATER)
    n = 200_000
    bare = _plane(stack, None, n, well_side_um=4.0)
    top = _plane(stack, Top("air", 50.0), n, well_side_um=4.0)
    gained = float(top.absorbed_walls[0] - bare.absorbed_walls[0])
    expected = returned_fraction(Top("air", 50.0), WATER)
    se = math.sqrt(expected * (1 - expected) / n + 2 * 0.2 * 0.8 / n)  # two runs' errors
    assert abs(gained - expected) <= SIGMAS * se, (gained, expected, se)
    mirror = _plane(stack, Top("air", 50.0), n, well_side_um=4.0, walls="reflecting")
    assert mirror.truncated[0] < 1e-4  # grazing rays between the well's mirrors, as without a top
    _within(float(mirror.absorbed_walls[0]), expected, n)
