"""A footprint far smaller than the site's height is a point: the optics take the point-source
law below ``√rtol × height`` (:func:`chiptwin.optics.psf.point_below`).

Unit tests: a 1e-300 µm disc (a valid ``sites.footprint_radius_um``, whose quadrature only
resolves rounding and never converged through a stack) gives the point source's coupling bit for
bit, at the closed-form and the stack psf levels; and the threshold is inside the tolerance: a
footprint just above it, integrated by quadrature, is within ``rtol × plane fraction`` of the
point (the mean-value expansion's a²∇²f/8 bound the docstring states).
"""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.optics import psf
from chiptwin.optics import stack_psf as sp
from chiptwin.optics.layers import Layer, Stack

CHIP = {"n_rows": 4, "n_cols": 6, "pitch_um": 125.0, "diode_w_um": 100.0, "diode_h_um": 100.0}
SITES = {"site_x_um": [187.5, 562.5], "site_y_um": [187.5, 312.5]}
STACK = Stack((Layer("water", 1.33, 1.0), Layer("oxide", 1.46, 14.0)))
RTOL = 1e-6


def closed(**footprint) -> np.ndarray:
    return psf.coupling_psf(**CHIP, **SITES, height_um=15.0, convention="isotropic", rtol=RTOL,
                            **footprint)


def stacked(**footprint) -> np.ndarray:
    return sp.coupling_stack(**CHIP, **SITES, stack=STACK, emitter="isotropic", rtol=RTOL,
                             **footprint)


@pytest.mark.parametrize("coupling", [closed, stacked], ids=["closed_form", "stack"])
@pytest.mark.parametrize("footprint", ["site_radius_um", "site_side_um"])
def test_a_vanishing_footprint_is_the_point_source(coupling, footprint):
    """1e-300 µm: the point's coupling exactly (the stack path raised an internal error)."""
    assert np.array_equal(coupling(**{footprint: 1e-300}), coupling())


def test_point_below_the_threshold_only():
    """The rule: point at and below √rtol × height, the footprint as given above it."""
    edge = np.sqrt(RTOL) * 15.0
    assert psf.point_below("disc", edge, 15.0, RTOL) == ("point", 0.0)
    assert psf.point_below("square", 0.5 * edge, 15.0, RTOL) == ("point", 0.0)
    assert psf.point_below("disc", 1.01 * edge, 15.0, RTOL) == ("disc", 1.01 * edge)
    assert psf.point_below("point", 0.0, 15.0, RTOL) == ("point", 0.0)


@pytest.mark.parametrize("coupling", [closed, stacked], ids=["closed_form", "stack"])
@pytest.mark.parametrize("footprint", ["site_radius_um", "site_side_um"])
def test_just_above_the_threshold_the_quadrature_agrees_with_the_point(coupling, footprint):
    """A footprint 1 % above √rtol × height, integrated by quadrature, is within rtol × the
    isotropic plane fraction (0.5) of the point everywhere: the switch to the point costs less
    than the tolerance the quadrature is held to."""
    size = 1.01 * np.sqrt(RTOL) * 15.0
    diff = np.abs(coupling(**{footprint: size}) - coupling())
    assert diff.max() <= RTOL * 0.5
