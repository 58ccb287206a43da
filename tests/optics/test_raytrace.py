"""The ``raytrace`` optics level: validation against closed forms, equivalence with ``psf``.

Kinds: validation (the analytic fractions of sources.md O7–O10, within 4 standard errors),
equivalence (a homogeneous stack against :func:`coupling_psf`, pixel by pixel within 4 SE; the
optiland 0.6.3 non-sequential engine on one slab), unit (bookkeeping, seeds, the ray-count rule,
the cache, validation messages). The closed forms are computed here by quadrature, the slow
obvious reference of the kernel.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from chiptwin.optics import _raytrace_kernels as _k
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.psf import coupling_psf
from chiptwin.optics.raytrace import _stack_arrays, rays_for_error, raytrace
from tests.conftest import require_module

SIGMAS = 4.0


def _fresnel_r(n1: float, n2: float, c1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rs, Rp at ``n1 → n2`` for incidence cosines ``c1`` (1 beyond the critical angle)."""
    s2 = (n1 / n2) ** 2 * (1.0 - c1 * c1)
    c2 = np.sqrt(np.clip(1.0 - s2, 0.0, None))
    rs = ((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)) ** 2
    rp = ((n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)) ** 2
    tir = s2 >= 1.0
    return np.where(tir, 1.0, rs), np.where(tir, 1.0, rp)


def _cos_in(n1: float, n2: float, c1: float) -> float:
    """Cosine in medium 2 of a ray with cosine ``c1`` in medium 1 (Snell's invariant)."""
    return float(np.sqrt(max(0.0, 1.0 - (n1 / n2) ** 2 * (1.0 - c1 * c1))))


def _single(n1: float, n2: float) -> float:
    """½∫ T(θ) sinθ dθ over the lower hemisphere, unpolarised T = 1 − (Rs + Rp)/2."""
    def f(c):
        rs, rp = _fresnel_r(n1, n2, np.array(c))
        return 1.0 - 0.5 * (rs + rp)
    return 0.5 * integrate.quad(f, 0.0, 1.0, epsabs=1e-12, limit=200)[0]


def _slab(n1: float, n2: float, n3: float, average: bool) -> float:
    """Incoherent slab: ½∫ T12·T23 / (1 − R21·R23) sinθ dθ (sources.md Optics).

    ``average=False``: per polarisation, then the mean of s and p (they never mix in planar
    layers); ``average=True``: with the unpolarised mean R at each interface.
    """
    def f(c1):
        c2 = _cos_in(n1, n2, c1)
        r12, r23 = _fresnel_r(n1, n2, np.array(c1)), _fresnel_r(n2, n3, np.array(c2))
        if c2 == 0.0:
            return 0.0
        if average:
            a, b = 0.5 * (r12[0] + r12[1]), 0.5 * (r23[0] + r23[1])
            return float((1 - a) * (1 - b) / (1 - a * b))
        return float(np.mean([(1 - r12[j]) * (1 - r23[j]) / (1 - r12[j] * r23[j])
                              for j in (0, 1)]))
    return 0.5 * integrate.quad(f, 0.0, 1.0, epsabs=1e-12, limit=400)[0]


def _plane(stack: Stack, n_rays: int, seed: int = 1, **kw):
    """Trace a point site over one big pixel; return the result."""
    return raytrace(stack, n_rows=1, n_cols=1, pitch_um=10.0, diode_w_um=10.0, diode_h_um=10.0,
                    site_x_um=[5.0], site_y_um=[5.0], rng=np.random.default_rng(seed),
                    n_rays=n_rays, cache=False, **kw)


def _within(value: float, expected: float, n: int) -> None:
    se = np.sqrt(expected * (1.0 - expected) / n)
    assert abs(value - expected) <= SIGMAS * se, (value, expected, (value - expected) / se)


# --- validation: closed forms -------------------------------------------------------------------


@pytest.mark.parametrize("n1, n2, published", [(1.33, 1.5, 0.4403), (1.5, 1.0, 0.1148),
                                               (1.33, 1.46, 0.4466), (1.33, 1.0, 0.1577)])
def test_one_interface_matches_reference(n1, n2, published):
    """sources.md Optics: isotropic emitter through one interface into an infinite plane,
    unpolarised Fresnel, TIR cone included: 1.33→1.5 0.4403, 1.5→1.0 0.1148, 1.33→1.46 0.4466,
    1.33→1.0 0.1577. Light reflected at the interface goes up through the site plane and never
    returns, so the multiple-reflection tracer must give the single-pass value: within 4 SE."""
    assert _single(n1, n2) == pytest.approx(published, abs=6e-5)
    n = 400_000
    r = _plane(Stack((Layer("a", n1, 3.0),), silicon_n=n2), n)
    _within(float(r.transmitted[0]), published, n)


@pytest.mark.parametrize("n3", [1.0, 4.3])
@pytest.mark.parametrize("polarisation", ["random", "average"])
def test_slab_multiple_reflections(n3, polarisation):
    """sources.md Optics: a slab (water 1.33 | glass 1.5 | n3) transmits ½∫ T12·T23/(1 − R21·R23)
    sinθ dθ (incoherent: the 2 µm glass traced as rays, thin_film_um = 0); n3 = 1.0 adds TIR
    at the bottom (light trapped, bouncing, leaving up).
    ``random`` against the per-polarisation sum, ``average`` against the mean-R sum: 4 SE."""
    n = 400_000
    expected = _slab(1.33, 1.5, n3, average=polarisation == "average")
    r = _plane(Stack((Layer("water", 1.33, 1.0), Layer("glass", 1.5, 2.0)), thin_film_um=0.0,
                 silicon_n=n3), n,
               polarisation=polarisation)
    _within(float(r.transmitted[0]), expected, n)
    assert r.truncated[0] == 0.0


def test_polarisation_choice_matters_beyond_one_interface():
    """Mean R per hit forgets the partial polarisation after the first interface: for water |
    nitride 2.0 | silicon 4.3 the closed forms differ by 2.5e-3 (0.7 %), resolvable with 1e6 rays
    (SE 4.8e-4); the traced ``random`` mode sits on the per-polarisation form."""
    exact, mean_r = _slab(1.33, 2.0, 4.3, False), _slab(1.33, 2.0, 4.3, True)
    assert exact - mean_r == pytest.approx(2.52e-3, abs=2e-5)


def test_beer_lambert_layer():
    """An absorbing layer over index-matched silicon: transmitted = ½∫ exp(−α t/cosθ) sinθ dθ."""
    alpha, t, n = 0.2, 2.0, 300_000
    expected = 0.5 * integrate.quad(lambda c: np.exp(-alpha * t / c), 1e-12, 1.0)[0]
    r = _plane(Stack((Layer("dye", 1.4, t, alpha_per_um=alpha),), silicon_n=1.4), n)
    _within(float(r.transmitted[0]), expected, n)
    _within(float(r.absorbed_layers[0, 0]), 0.5 - expected, n)


def test_absorbing_well_is_the_solid_angle_of_its_floor():
    """sources.md Optics: a square of half-side a = 2 at distance d = 1 subtends 0.29517 of 4π. A
    point site in a 4 µm absorbing well 1 µm above index-matched silicon: transmitted 0.29517, walls
    the rest of the lower half."""
    n = 300_000
    r = _plane(Stack((Layer("water", 1.33, 1.0),), silicon_n=1.33), n, well_side_um=4.0)
    _within(float(r.transmitted[0]), 0.29517, n)
    _within(float(r.absorbed_walls[0]), 0.5 - 0.29517, n)


def test_reflecting_well_and_lambertian_lose_nothing():
    """Mirror walls send every downward ray to index-matched silicon: exactly half of an isotropic
    emitter; a Lambertian emitter facing down puts all its light there. (A near-horizontal ray
    bounces between mirrors ~ depth/(side·|dz|) times: ``max_events`` is raised so none is
    truncated; at the default 10⁴, 5 of 50 000 were.)"""
    stack = Stack((Layer("water", 1.33, 5.0),), silicon_n=1.33)
    iso = _plane(stack, 50_000, well_side_um=3.0, walls="reflecting", site_radius_um=1.0,
                 max_events=10**7)
    lam = _plane(stack, 50_000, well_side_um=3.0, walls="reflecting", emitter="lambertian")
    assert iso.transmitted[0] + iso.escaped_top[0] == 1.0
    _within(float(iso.transmitted[0]), 0.5, 50_000)
    assert lam.transmitted[0] == 1.0


# --- equivalence: the psf level and optiland ----------------------------------------------------


@pytest.mark.parametrize("emitter, convention", [("isotropic", "isotropic"),
                                                 ("lambertian", "lambertian_na2")])
def test_homogeneous_stack_equals_psf(emitter, convention):
    """One medium, silicon index-matched (no reflection): the traced matrix equals
    ``coupling_psf`` pixel by pixel within 4 SE (5 × 5 pixels, three sites: centred, off-centre
    and off the array, disc footprint)."""
    grid = dict(n_rows=5, n_cols=5, pitch_um=20.0, diode_w_um=15.0, diode_h_um=12.0,
                site_x_um=[50.0, 37.0, -6.0], site_y_um=[50.0, 61.0, 30.0], site_radius_um=3.0)
    stack = Stack((Layer("water", 1.33, 4.0), Layer("more water", 1.33, 6.0)), silicon_n=1.33)
    r = raytrace(stack, rng=np.random.default_rng(5), n_rays=200_000, emitter=emitter,
                 cache=False, **grid)
    psf = coupling_psf(height_um=10.0, convention=convention, **grid)
    se = np.sqrt(psf * (1 - psf) / 200_000)
    assert np.all(np.abs(r.coupling - psf) <= SIGMAS * se), np.max(np.abs(r.coupling - psf) / se)


@pytest.mark.parametrize("emitter", ["isotropic", "lambertian"])
def test_faceplate_equals_psf(emitter):
    """A fibre faceplate (NA 1.2 in water: θ ≤ 64°; 6 µm fibres, 70 % open) under 12 µm of
    water, no Fresnel loss into the cores: the traced matrix (acceptance by Snell's invariant,
    open area drawn, position jittered over a fibre pitch) equals the psf level's angular
    acceptance and box blur pixel by pixel within 4 SE (5 × 5 pixels of 20 µm, diodes 15 × 12 µm,
    two sites, a disc footprint)."""
    from chiptwin.optics.faceplate import Faceplate
    from chiptwin.optics.stack_psf import coupling_stack

    grid = dict(n_rows=5, n_cols=5, pitch_um=20.0, diode_w_um=15.0, diode_h_um=12.0,
                site_x_um=[50.0, 37.0], site_y_um=[50.0, 61.0], site_radius_um=3.0)
    stack = Stack((Layer("water", 1.33, 12.0),), silicon_n=4.3)
    fp = Faceplate(na=1.2, fiber_pitch_um=6.0, thickness_um=500.0, open_area_ratio=0.7)
    n = 200_000
    r = raytrace(stack, rng=np.random.default_rng(8), n_rays=n, emitter=emitter, faceplate=fp,
                 cache=False, **grid)
    psf = coupling_stack(stack=stack, emitter=emitter, faceplate=fp, **grid)
    se = np.sqrt(np.clip(psf, 0.0, None) * (1 - psf) / n)  # quadrature zeros are ±1e-18
    assert psf[:, 0].sum() > 0.03 and np.sort(psf[:, 0])[-2] > 1e-3  # a neighbour sees light
    assert np.all(np.abs(r.coupling - psf) <= SIGMAS * se + 1e-12), \
        np.max(np.abs(r.coupling - psf) / np.maximum(se, 1e-300))
    # every ray ends once; the rejected ones are the faceplate's
    total = r.coupling.sum(axis=0) + r.silicon_outside + r.escaped_top + r.absorbed_faceplate
    assert np.allclose(total, 1.0, atol=1e-12) and r.absorbed_layers.shape == (2, 1)


def test_optiland_cross_check():
    """optiland 0.6.3's non-sequential engine (the tracer behind sources.md O17–O19) on a
    slab water 1.33 | 2 µm glass 1.5 | silicon 4.3, isotropic point source, mean-R Fresnel (its
    only mode): transmitted fractions agree within 4 combined SE."""
    require_module("optiland.nonsequential", "raytrace")
    from optiland.coordinate_system import CoordinateSystem
    from optiland.materials import IdealMaterial
    from optiland.nonsequential import (
        IrradianceDetectorConfig,
        NSQMaterial,
        NSQScene,
        PlaneGeometry,
        PointSourceConfig,
        RefractiveComponent,
        Spectrum,
    )

    def mat(n):
        return NSQMaterial(IdealMaterial(n=n))

    ns, n = (1.33, 1.5, 4.3), 100_000
    scene = NSQScene()
    scene.add_source("S", CoordinateSystem(), PointSourceConfig(
        spectrum=Spectrum.monochromatic(0.55), total_flux=1.0, half_angle_deg=180.0,
        medium=mat(ns[0])))
    for i, z in enumerate((1.0, 3.0)):  # optiland lengths in mm; the ratio is what counts
        scene.add_component(f"I{i}", RefractiveComponent(CoordinateSystem(z=z), PlaneGeometry(),
                                                         mat(ns[i]), mat(ns[i + 1])))
    scene.add_detector("Si", CoordinateSystem(z=4.0), IrradianceDetectorConfig(
        width=1e6, height=1e6, num_pixels_x=1, num_pixels_y=1, splat="hard"))
    res = scene.trace(num_rays=n, seed=3, max_depth=64)
    theirs = res.total_flux_detected / res.total_flux_in
    r = _plane(Stack((Layer("water", 1.33, 1.0), Layer("glass", 1.5, 2.0)), thin_film_um=0.0,
                 silicon_n=4.3), n,
               polarisation="average")
    ours = float(r.transmitted[0])
    se = np.sqrt(2 * ours * (1 - ours) / n)
    assert res.num_rays_depth_killed == 0
    assert abs(ours - theirs) <= SIGMAS * se, (ours, theirs)


# --- unit: bookkeeping, seeds, ray counts, cache, checks ----------------------------------------


def test_every_ray_ends_once():
    """Energy bookkeeping, ray by ray: every outcome code is one valid place, and the counts of
    pixels + silicon + top + walls + layers + truncated equal the rays emitted, exactly."""
    stack = Stack((Layer("water", 1.33, 2.0, alpha_per_um=0.01), Layer("oxide", 1.46, 3.0),
                   Layer("nitride", 2.0, 0.0), Layer("glass", 1.5, 4.0, alpha_per_um=0.02)),
                  thin_film_um=0.0)
    r = raytrace(stack, n_rows=3, n_cols=4, pitch_um=10.0, diode_w_um=6.0, diode_h_um=8.0,
                 site_x_um=[15.0, 3.0], site_y_um=[15.0, 28.0], site_radius_um=1.0,
                 well_side_um=6.0, rng=np.random.default_rng(2), n_rays=30_000, cache=False)
    assert np.all(r.counts.sum(axis=1) == 30_000)
    total = (r.coupling.sum(axis=0) + r.silicon_outside + r.escaped_top + r.absorbed_walls
             + r.absorbed_layers.sum(axis=1) + r.truncated)
    np.testing.assert_allclose(total, 1.0, rtol=0, atol=1e-12)
    assert np.all(r.absorbed_walls > 0) and np.all(r.absorbed_layers[:, [0, 3]] > 0)
    codes = _k.empty_codes(5000)
    n, bottom, top, alpha = (np.array([1.33, 1.5]), np.array([2.0, 0.0]), np.array([3.0, 2.0]),
                             np.array([0.1, 0.0]))
    # the same two layers as ray layers (a 2 µm glass over silicon would be a thin film, one
    # ray layer fewer than n above: numba does not check the bounds the kernel then overruns)
    films = _stack_arrays(Stack((Layer("w", 1.33, 1.0), Layer("g", 1.5, 2.0)),
                                thin_film_um=0.0), 4.3)[4:]
    assert films[0].size == n.size
    _k.trace_chunk(np.random.default_rng(0), codes, 5.0, 5.0, _k.FOOT_POINT, 0.0,
                   _k.EMIT_ISOTROPIC, _k.POL_S, n, bottom, top, alpha, 4.3, _k.WALLS_NONE, 0.0,
                   1, 1, 10.0, 4.0, 4.0, 100, *films, 2)
    assert codes.min() >= 0 and codes.max() < 1 + _k.LAYER + 2
    one_ray_layer = _stack_arrays(Stack((Layer("w", 1.33, 1.0), Layer("g", 1.5, 2.0))), 4.3)[4:]
    with pytest.raises(ValueError, match="one entry a ray layer"):  # not an overrun
        _k.trace_chunk(np.random.default_rng(0), codes, 5.0, 5.0, _k.FOOT_POINT, 0.0,
                       _k.EMIT_ISOTROPIC, _k.POL_S, n, bottom, top, alpha, 4.3, _k.WALLS_NONE,
                       0.0, 1, 1, 10.0, 4.0, 4.0, 100, *one_ray_layer, 2)


def test_same_seed_same_bits_any_workers():
    """Same seed → identical matrix; 1 or 2 threads → identical (fixed chunks own the streams);
    another seed → a different draw."""
    kw = dict(n_rows=3, n_cols=3, pitch_um=10.0, diode_w_um=8.0, diode_h_um=8.0,
              site_x_um=[15.0], site_y_um=[15.0], n_rays=50_000, chunk_rays=8192, cache=False)
    stack = Stack((Layer("water", 1.33, 1.0), Layer("oxide", 1.46, 5.0)))
    a = raytrace(stack, rng=np.random.default_rng(11), **kw)
    b = raytrace(stack, rng=np.random.default_rng(11), workers=2, **kw)
    c = raytrace(stack, rng=np.random.default_rng(12), **kw)
    assert np.array_equal(a.coupling, b.coupling) and np.array_equal(a.counts, b.counts)
    assert not np.array_equal(a.counts, c.counts)


def test_ray_count_rule():
    """N = (1 − p)/(p·rel²): 0.25 at 1 % → 30 000; the pilot-chosen count meets the asked
    relative error on the own pixel (within 10 %: the pilot's p is itself an estimate)."""
    assert rays_for_error(0.25, 0.01) == 30_000
    assert rays_for_error(1.0, 0.01) == 1
    stack = Stack((Layer("water", 1.33, 1.0), Layer("oxide", 1.46, 5.0)))
    r = raytrace(stack, n_rows=3, n_cols=3, pitch_um=10.0, diode_w_um=8.0, diode_h_um=8.0,
                 site_x_um=[15.0], site_y_um=[15.0], rng=np.random.default_rng(4),
                 rel_error=0.02, cache=False)
    own = r.coupling[4, 0]
    assert r.n_rays[0] == pytest.approx(rays_for_error(own, 0.02), rel=0.1)
    assert r.stderr[4, 0] / own == pytest.approx(0.02, rel=0.1)


def test_cache_pays_once(tmp_path):
    """A second call with the same geometry reads the stored matrix (whatever the seed); a
    changed geometry traces again."""
    kw = dict(n_rows=2, n_cols=2, pitch_um=10.0, diode_w_um=8.0, diode_h_um=8.0,
              site_x_um=[5.0], site_y_um=[5.0], n_rays=20_000, cache=tmp_path)
    stack = Stack((Layer("water", 1.33, 3.0),))
    a = raytrace(stack, rng=np.random.default_rng(1), **kw)
    b = raytrace(stack, rng=np.random.default_rng(2), **kw)
    c = raytrace(Stack((Layer("water", 1.33, 4.0),)), rng=np.random.default_rng(1), **kw)
    assert not a.cached and b.cached and not c.cached
    assert np.array_equal(a.coupling, b.coupling) and np.array_equal(a.stderr, b.stderr)
    assert len(list(tmp_path.glob("*.npz"))) == 2


@pytest.mark.parametrize("kw, match", [
    ({"emitter": "lambertian_na2"}, "emitter"),
    ({"walls": "grey"}, "walls"),
    ({"polarisation": "s"}, "polarisation"),
    ({"well_side_um": 2.0, "site_radius_um": 1.0}, "fit inside the well"),
    ({"rel_error": 0.0}, "rel_error"),
    ({"n_rays": 0}, "n_rays"),
])
def test_checks_name_the_field(kw, match):
    grid = dict(n_rows=1, n_cols=1, pitch_um=10.0, diode_w_um=8.0, diode_h_um=8.0,
                site_x_um=[5.0], site_y_um=[5.0], cache=False)
    args = {"n_rays": 10, **grid, **kw}
    with pytest.raises(ValueError, match=match):
        raytrace(Stack((Layer("water", 1.33, 3.0),)), rng=np.random.default_rng(0), **args)
