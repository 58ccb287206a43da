"""Site-to-pixel coupling: exact rectangle integrals, footprint quadrature, na2 level."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from chiptwin.optics import collection as col
from chiptwin.optics import psf

CONVENTIONS = col.CONVENTIONS


def irradiance(r2: float, u: float, convention: str) -> float:
    """The plane irradiance per emitted photon, written out as in sources.md Optics."""
    if convention == col.ISOTROPIC:
        return u / (r2 + u * u) ** 1.5 / (4 * np.pi)
    return u * u / (r2 + u * u) ** 2 / np.pi


def quad_rectangle(x0, x1, y0, y1, u, convention) -> float:
    """scipy dblquad of the irradiance over a rectangle (foot of the source at the origin)."""
    f = lambda y, x: irradiance(x * x + y * y, u, convention)  # noqa: E731
    return integrate.dblquad(f, x0, x1, y0, y1, epsabs=1e-15, epsrel=1e-12)[0]


GRID = {"n_rows": 8, "n_cols": 16, "pitch_um": 100.0, "diode_w_um": 80.0, "diode_h_um": 60.0}


# --- the closed-form rectangle -------------------------------------------------------------------

RECTANGLES = [  # x0, x1, y0, y1, u
    (-50, 50, -50, 50, 15),
    (0, 40, 0, 30, 15),
    (20, 70, -10, 35, 15),
    (-130, -30, 60, 160, 15),
    (350, 450, 150, 250, 15),
    (-3, 1, -2, 5, 0.5),
    (-50, 50, -50, 50, 400),
]


@pytest.mark.parametrize("rect", RECTANGLES)
@pytest.mark.parametrize("convention", CONVENTIONS)
def test_rectangle_closed_form_matches_quadrature(rect, convention):
    """Corner-term superposition vs scipy dblquad (rel 1e-8, abs 1e-13)."""
    got = psf.point_rectangle_fraction(*rect[:4], rect[4], convention=convention)
    want = quad_rectangle(*rect, convention)
    assert got == pytest.approx(want, rel=1e-8, abs=1e-13)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_rectangle_limits(convention):
    """Infinite plane → plane_fraction; quadrants add up; a zero-area rectangle collects 0."""
    plane = col.plane_fraction(convention)
    big = 1e9
    assert psf.point_rectangle_fraction(-big, big, -big, big, 15.0,
                                        convention=convention) == pytest.approx(plane, rel=1e-7)
    whole = psf.point_rectangle_fraction(-20, 30, -40, 10, 7.0, convention=convention)
    parts = sum(psf.point_rectangle_fraction(a, b, c, d, 7.0, convention=convention)
                for a, b in ((-20, 0), (0, 30)) for c, d in ((-40, 0), (0, 10)))
    assert whole == pytest.approx(parts, rel=1e-13)
    assert psf.point_rectangle_fraction(5, 5, -1, 1, 3.0, convention=convention) == 0.0


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_square_lies_between_inscribed_and_circumscribed_discs(convention):
    """A 100 µm square at 15 µm collects more than its inscribed disc (the paper's 91.7 %
    Lambertian), less than the circumscribed one."""
    square = psf.point_rectangle_fraction(-50, 50, -50, 50, 15.0, convention=convention)
    inner = col.collection_efficiency(100.0, 15.0, convention=convention)
    outer = col.collection_efficiency(100.0 * np.sqrt(2), 15.0, convention=convention)
    assert inner < square < outer


def test_rectangle_errors():
    with pytest.raises(ValueError, match="x_max_um < x_min_um"):
        psf.point_rectangle_fraction(1, 0, 0, 1, 1.0, convention="isotropic")
    with pytest.raises(ValueError, match=r"height_um = 0.0 .*> 0"):
        psf.point_rectangle_fraction(0, 1, 0, 1, 0.0, convention="isotropic")
    with pytest.raises(ValueError, match="convention = 'lambertian'"):
        psf.point_rectangle_fraction(0, 1, 0, 1, 1.0, convention="lambertian")


# --- the coupling matrix ------------------------------------------------------------------------


def centred_coupling(convention, **kwargs):
    x, y = psf.pixel_centers_um(GRID["n_rows"], GRID["n_cols"], GRID["pitch_um"])
    return psf.coupling_psf(**GRID, site_x_um=x, site_y_um=y, height_um=15.0,
                            convention=convention, **kwargs)


def test_pixel_centres_are_row_major():
    x, y = psf.pixel_centers_um(2, 3, 10.0)
    np.testing.assert_array_equal(x, [5, 15, 25, 5, 15, 25])
    np.testing.assert_array_equal(y, [5, 5, 5, 15, 15, 15])


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_point_coupling_is_the_exact_rectangle_integral(convention):
    """Every entry of the point-source matrix equals the closed form for its own pixel (rel 1e-9,
    the offset de-duplication quantum is 1e-9 µm)."""
    rng = np.random.default_rng(7)
    sx, sy = rng.uniform(-50, 1700, 5), rng.uniform(-50, 900, 5)
    c = psf.coupling_psf(**GRID, site_x_um=sx, site_y_um=sy, height_um=12.0, convention=convention)
    px, py = psf.pixel_centers_um(GRID["n_rows"], GRID["n_cols"], GRID["pitch_um"])
    for s in range(sx.size):
        dx, dy = px - sx[s], py - sy[s]
        want = psf.point_rectangle_fraction(dx - 40, dx + 40, dy - 30, dy + 30, 12.0,
                                            convention=convention)
        np.testing.assert_allclose(c[:, s], want, rtol=1e-9, atol=1e-18)


@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize("footprint", [{}, {"site_radius_um": 30.0}, {"site_side_um": 50.0}])
def test_sums_symmetry_and_translation(convention, footprint):
    """Rows and columns sum to ≤ the plane total; sites at pixel centres give a symmetric matrix,
    invariant under mirroring the array and under translation between interior pixels."""
    c = centred_coupling(convention, **footprint)
    plane = col.plane_fraction(convention)
    assert c.shape == (128, 128)
    assert (c >= 0).all()
    assert c.sum(axis=0).max() <= plane and c.sum(axis=1).max() <= plane
    np.testing.assert_allclose(c, c.T, rtol=0, atol=1e-15)
    flip = np.arange(128).reshape(8, 16)[::-1, ::-1].ravel()  # 180° rotation of the array
    np.testing.assert_allclose(c[np.ix_(flip, flip)], c, rtol=0, atol=1e-15)
    a, b = 2 * 16 + 3, 5 * 16 + 9  # two interior pixels; compare their 3×3 neighbourhoods
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            assert c[a + 16 * dr + dc, a] == pytest.approx(c[b + 16 * dr + dc, b], rel=1e-12)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_column_sum_is_bracketed_by_the_plane_total(convention):
    """A site at the centre of a 21×21 array with fill factor 1 loses at most the light beyond the
    inscribed disc of radius R = 10.5 pitches: plane − tail(R) ≤ Σ_p C[p, s] ≤ plane."""
    n, pitch, u = 21, 50.0, 15.0
    c = psf.coupling_psf(n_rows=n, n_cols=n, pitch_um=pitch, diode_w_um=pitch, diode_h_um=pitch,
                         site_x_um=[n * pitch / 2], site_y_um=[n * pitch / 2], height_um=u,
                         convention=convention)
    plane = col.plane_fraction(convention)
    inside = col.collection_efficiency(n * pitch, u, convention=convention)
    assert inside <= c.sum() <= plane
    assert c.sum() == pytest.approx(plane, abs=plane - inside)


def reference_footprint_average(dx, dy, half_w, half_h, u, convention, shape, size):
    """scipy nquad of the closed-form point integral over the footprint (independent of the
    Gauss–Legendre rule under test)."""
    def point(qx, qy):
        cx, cy = dx - qx, dy - qy
        return float(psf.point_rectangle_fraction(cx - half_w, cx + half_w, cy - half_h,
                                                  cy + half_h, u, convention=convention))
    opts = {"epsabs": 1e-13, "epsrel": 1e-11, "limit": 200}
    if shape == "disc":
        f = lambda phi, r: point(r * np.cos(phi), r * np.sin(phi)) * r  # noqa: E731
        val = integrate.nquad(f, [(0, 2 * np.pi), (0, size)], opts=[opts, opts])[0]
        return val / (np.pi * size * size)
    h = size / 2
    return integrate.nquad(lambda qy, qx: point(qx, qy), [(-h, h), (-h, h)],
                           opts=[opts, opts])[0] / size**2


@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize(("shape", "size"), [("disc", 40.0), ("square", 90.0)])
def test_footprint_quadrature_meets_its_tolerance(convention, shape, size):
    """Footprint-averaged coupling vs scipy nquad for a site and its neighbours: every entry within
    rtol × plane_fraction, rtol = 1e-6 (the stated tolerance of :func:`coupling_psf`)."""
    rtol = 1e-6
    kwargs = {"site_radius_um": size} if shape == "disc" else {"site_side_um": size}
    c = psf.coupling_psf(n_rows=2, n_cols=2, pitch_um=100.0, diode_w_um=80.0, diode_h_um=60.0,
                         site_x_um=[50.0], site_y_um=[50.0], height_um=15.0,
                         convention=convention, rtol=rtol, **kwargs)
    px, py = psf.pixel_centers_um(2, 2, 100.0)
    for p in range(4):
        want = reference_footprint_average(px[p] - 50.0, py[p] - 50.0, 40.0, 30.0, 15.0,
                                           convention, shape, size)
        assert c[p, 0] == pytest.approx(want, abs=rtol * col.plane_fraction(convention))


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_footprint_converges_as_rtol_tightens(convention):
    """Results at rtol 1e-4 and 1e-6 agree with rtol 1e-10 within their own tolerances; a
    vanishing footprint tends to the point source; light stays ≤ the plane total."""
    fine = centred_coupling(convention, site_radius_um=45.0, rtol=1e-10)
    plane = col.plane_fraction(convention)
    for rtol in (1e-4, 1e-6):
        coarse = centred_coupling(convention, site_radius_um=45.0, rtol=rtol)
        assert np.abs(coarse - fine).max() <= rtol * plane
    tiny = centred_coupling(convention, site_radius_um=1e-4)
    point = centred_coupling(convention)
    np.testing.assert_allclose(tiny, point, rtol=0, atol=1e-9)
    assert (fine.diagonal() < point.diagonal()).all()  # a wide site spills more into neighbours


def test_unreachable_tolerance_is_an_error():
    with pytest.raises(ValueError, match=r"did not reach rtol = 1e-12"):
        psf.coupling_psf(n_rows=1, n_cols=1, pitch_um=100.0, diode_w_um=100.0, diode_h_um=100.0,
                         site_x_um=[50.0], site_y_um=[50.0], height_um=0.01,
                         convention="isotropic", site_side_um=100.0, rtol=1e-12)


@pytest.mark.parametrize(
    ("override", "match"),
    [
        ({"n_rows": 0}, r"n_rows = 0 is out of range: must be an int >= 1"),
        ({"n_cols": 2.0}, r"n_cols = 2.0"),
        ({"diode_w_um": 120.0}, r"diode_w_um = 120.0 .*<= pitch_um = 100.0"),
        ({"pitch_um": -1.0}, r"pitch_um = -1.0 .*> 0"),
        ({"height_um": 0.0}, r"height_um = 0.0 .*> 0"),
        ({"convention": "lambert"}, r"convention = 'lambert' is unknown"),
        ({"site_radius_um": 5.0, "site_side_um": 5.0}, r"give at most one footprint"),
        ({"site_radius_um": -5.0}, r"site_radius_um = -5.0"),
        ({"rtol": 0.5}, r"rtol = 0.5 is out of range"),
        ({"site_x_um": [1.0, 2.0]}, r"site_x_um \(2,\) and site_y_um \(1,\)"),
    ],
)
def test_coupling_errors(override, match):
    kwargs = {**GRID, "pitch_um": 100.0, "site_x_um": [50.0], "site_y_um": [50.0],
              "height_um": 15.0, "convention": "isotropic", **override}
    with pytest.raises(ValueError, match=match):
        psf.coupling_psf(**kwargs)


# --- the na2 level ------------------------------------------------------------------------------


def test_na2_apertures():
    """'inscribed_disc' is the paper's 91.7 % (sources.md Optics); 'rectangle' is the centred point
    diagonal of the psf level; 'equal_area_disc' sits between the discs."""
    kw = {"diode_w_um": 100.0, "diode_h_um": 100.0, "height_um": 15.0}
    paper = psf.diode_collection_efficiency(**kw, convention="lambertian_na2",
                                            aperture="inscribed_disc")
    assert paper == pytest.approx(0.917, abs=0.0005)
    for conv in CONVENTIONS:
        rect = psf.diode_collection_efficiency(**kw, convention=conv)
        assert rect == pytest.approx(
            float(psf.point_rectangle_fraction(-50, 50, -50, 50, 15.0, convention=conv)),
            rel=1e-15)
        area = psf.diode_collection_efficiency(**kw, convention=conv, aperture="equal_area_disc")
        assert col.collection_efficiency(100.0, 15.0, convention=conv) < area
    with pytest.raises(ValueError, match=r"aperture = 'square' is unknown"):
        psf.diode_collection_efficiency(**kw, convention="isotropic", aperture="square")


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_na2_couples_each_site_to_the_pixel_under_it(convention):
    sx = np.array([50.0, 1599.0, 0.0, 730.0])
    sy = np.array([50.0, 799.0, 0.0, 120.0])
    c = psf.coupling_na2(**GRID, site_x_um=sx, site_y_um=sy, height_um=15.0,
                         convention=convention)
    pixels = [0, 7 * 16 + 15, 0, 1 * 16 + 7]
    eff = psf.diode_collection_efficiency(diode_w_um=80.0, diode_h_um=60.0, height_um=15.0,
                                          convention=convention)
    assert (np.count_nonzero(c, axis=0) == 1).all()
    np.testing.assert_allclose(c[pixels, np.arange(4)], eff, rtol=1e-15)
    point = centred_coupling(convention)
    assert eff == pytest.approx(point[0, 0], rel=1e-12)  # na2 = psf diagonal, without spread


def test_na2_rejects_sites_off_the_array():
    with pytest.raises(ValueError, match=r"site_x_um\[1\] = 1600.0 is outside the pixel array"):
        psf.coupling_na2(**GRID, site_x_um=[5.0, 1600.0], site_y_um=[5.0, 5.0], height_um=15.0,
                         convention="isotropic")


def test_distinct_offsets_is_numpys_unique_of_the_rounded_pairs():
    """The same first occurrences and inverse as ``np.unique(axis=0)`` on the rounded offsets:
    ties (a grid's repeated offsets), offsets closer than the quantum, zeros, and one set where
    every offset is distinct."""
    rng = np.random.default_rng(4)
    grid = np.abs(rng.integers(0, 9, (2, 5000)) - rng.integers(0, 9, (2, 5000))) * 7.5
    near = grid + rng.choice([0.0, 0.2e-9, 3e-9], size=grid.shape)
    for dx, dy in (grid, near, rng.uniform(0.0, 300.0, (2, 4000)), np.zeros((2, 10))):
        keys = np.round(np.stack([dx, dy], axis=1) / psf.OFFSET_QUANTUM_UM)
        _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
        got_first, got_inverse = psf.distinct_offsets(dx, dy)
        assert np.array_equal(got_first, first)
        assert np.array_equal(got_inverse, inverse.ravel())
