"""Collection efficiency of a disc aperture, both conventions (sources.md Optics)."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.optics import collection as col

LAMB, ISO = col.LAMBERTIAN_NA2, col.ISOTROPIC


def test_camera_lens_lambertian_is_1p54_percent():
    """Camera, D = 0.5 f, U = 2 f: NA² = 1.54 % (sources.md Optics; the paper quotes 1.6 %).
    Tolerance: the printed digits, ±0.005 %; exact value 1/65 to 1e-12."""
    eff = col.collection_efficiency(0.5, 2.0, convention=LAMB)
    assert eff == pytest.approx(0.0154, abs=0.00005)
    assert eff == pytest.approx(1 / 65, rel=1e-12)  # t = 1/8: t²/(1+t²) = 1/65


def test_contact_lambertian_is_91p7_percent():
    """Contact, D = 100 µm, U = 15 µm: NA² = 91.7 % (sources.md Optics; the paper quotes 91 %).
    Tolerance: ±0.05 %; exact value (50²)/(50²+15²) to 1e-12."""
    eff = col.collection_efficiency(100.0, 15.0, convention=LAMB)
    assert eff == pytest.approx(0.917, abs=0.0005)
    assert eff == pytest.approx(2500 / 2725, rel=1e-12)


def test_isotropic_versions_are_0p39_and_35p6_percent():
    """The same two geometries for an isotropic emitter, (1 − cos θ)/2: 0.39 % and 35.6 %
    (derived; sources.md O4). Tolerance: the printed digits (±0.005 %, ±0.05 %)."""
    camera = col.collection_efficiency(0.5, 2.0, convention=ISO)
    contact = col.collection_efficiency(100.0, 15.0, convention=ISO)
    assert camera == pytest.approx(0.0039, abs=0.00005)
    assert contact == pytest.approx(0.356, abs=0.0005)
    assert contact == pytest.approx((1 - 15 / np.hypot(50, 15)) / 2, rel=1e-12)


def test_limits_and_plane_fraction():
    assert col.plane_fraction(LAMB) == 1.0 and col.plane_fraction(ISO) == 0.5
    for conv in col.CONVENTIONS:
        assert col.collection_efficiency(1.0, 0.0, convention=conv) == col.plane_fraction(conv)
        assert col.collection_efficiency(0.0, 1.0, convention=conv) == 0.0
        assert col.collection_efficiency(1e12, 1.0, convention=conv) == pytest.approx(
            col.plane_fraction(conv), rel=1e-12)


def test_tiny_apertures_keep_relative_precision():
    """Small-angle limits: NA² → t², isotropic → t²/4 with t = D/2U (no 1 − cos cancellation)."""
    t = 1e-9
    assert col.collection_efficiency(2 * t, 1.0, convention=LAMB) == pytest.approx(t * t, rel=1e-12)
    assert col.collection_efficiency(2 * t, 1.0, convention=ISO) == pytest.approx(t * t / 4,
                                                                                  rel=1e-12)


def test_vectorised_and_half_angle():
    eff = col.collection_efficiency(np.array([0.5, 100.0]), np.array([2.0, 15.0]), convention=LAMB)
    np.testing.assert_allclose(eff, [1 / 65, 2500 / 2725], rtol=1e-12)
    assert col.half_angle_rad(2.0, 1.0) == pytest.approx(np.pi / 4)
    assert np.sin(col.half_angle_rad(100.0, 15.0)) ** 2 == pytest.approx(2500 / 2725)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: col.collection_efficiency(1.0, 1.0, convention="gaussian"),
         r"convention = 'gaussian' is unknown: must be one of 'lambertian_na2', 'isotropic'"),
        (lambda: col.collection_efficiency(-1.0, 1.0, convention=LAMB), r"diameter_um = -1.0"),
        (lambda: col.collection_efficiency(1.0, np.inf, convention=LAMB), r"distance_um = inf"),
        (lambda: col.collection_efficiency(0.0, 0.0, convention=ISO), r"both 0"),
        (lambda: col.plane_fraction("NA2"), r"convention = 'NA2' is unknown"),
    ],
)
def test_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()
