"""The radial profile's compiled ``P(ρ)`` and corner integral
(:mod:`chiptwin.optics._profile_kernels`) against NumPy oracles written from the formulas:
``searchsorted`` for the table node, the cubic Hermite interpolant in whole-array passes, and
the corner integral ``H`` as two Gauss–Legendre panels summed in NumPy."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.optics import stack_psf as sp
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.profile import RadialProfile, build_profile
from chiptwin.optics.quadrature import gauss_legendre

STACKS = {
    "water over oxide": Stack((Layer("water", 1.33, 10.0), Layer("oxide", 1.46, 14.0)), 3.5),
    "one medium": Stack((Layer("water", 1.33, 25.0),), 3.5),
}


def _profiles() -> list[RadialProfile]:
    out = [build_profile(s, law) for s in STACKS.values() for law in ("isotropic", "lambertian")]
    out.append(build_profile(STACKS["water over oxide"], "lambertian", na=0.5))  # bounded
    return out


@np.errstate(all="ignore")  # 1e300 and ±inf radii: their lanes are replaced below
def _p_numpy(p: RadialProfile, r: np.ndarray) -> np.ndarray:
    rho, last = p.rho_um, p.rho_um.size - 2
    k = np.clip(np.searchsorted(rho, r, side="right") - 1, 0, last)
    h = rho[k + 1] - rho[k]
    s = (r - rho[k]) / h
    s2, s3 = s * s, s * s * s
    out = ((2 * s3 - 3 * s2 + 1) * p.cum[k] + (s3 - 2 * s2 + s) * h * p.dens[k]
           + (3 * s2 - 2 * s3) * p.cum[k + 1] + (s3 - s2) * h * p.dens[k + 1])
    q = rho[-1] / np.where(r > 0, r, 1.0)
    tail = p.total if p.bounded else p.total - (p.total - p.cum[-1]) * (q * q)
    out = np.where(r >= rho[-1], tail, out)
    return np.where(r <= 0, 0.0, out)


@pytest.mark.parametrize("profile", _profiles(), ids=lambda p: f"bounded={p.bounded}")
def test_p_is_the_hermite_table_to_the_bit(profile):
    """Random radii, every node exactly (ties: ``P`` at a node is its table value), the midpoints,
    0, negatives, the last node and far beyond: the same bits as the NumPy oracle."""
    rho = profile.rho_um
    r = np.concatenate([
        np.random.default_rng(1).uniform(0.0, 1.2 * rho[-1] if profile.bounded else 500.0, 20_000),
        rho, 0.5 * (rho[1:] + rho[:-1]), np.nextafter(rho[1:], 0.0),
        [0.0, -1.0, -np.inf, rho[-1], 2 * rho[-1], 1e300, np.inf]])
    got = profile.cumulative(r)
    assert np.array_equal(got, _p_numpy(profile, r))
    assert np.array_equal(profile.cumulative(rho), np.concatenate([profile.cum[:-1], [
        profile.total if profile.bounded else profile.cum[-1]]]))
    assert profile.cumulative(np.float64(rho[3])).shape == ()


@np.errstate(all="ignore")
def _dp_numpy(p: RadialProfile, r: np.ndarray) -> np.ndarray:
    rho, last = p.rho_um, p.rho_um.size - 2
    k = np.clip(np.searchsorted(rho, r, side="right") - 1, 0, last)
    h = rho[k + 1] - rho[k]
    s = (r - rho[k]) / h
    s2 = s * s
    out = ((6 * s2 - 6 * s) / h * p.cum[k] + (3 * s2 - 4 * s + 1) * p.dens[k]
           + (6 * s - 6 * s2) / h * p.cum[k + 1] + (3 * s2 - 2 * s) * p.dens[k + 1])
    return np.where((r <= 0) | (r >= rho[-1]), 0.0, out)


@pytest.mark.parametrize("profile", _profiles(), ids=lambda p: f"bounded={p.bounded}")
def test_density_is_the_hermite_derivative_to_the_bit(profile):
    """dP/dr on the same radii as P's test, alone and together with P."""
    rho = profile.rho_um
    r = np.concatenate([np.random.default_rng(3).uniform(0.0, 1.2 * rho[-1], 20_000), rho,
                        0.5 * (rho[1:] + rho[:-1]), [0.0, -1.0, rho[-1], 1e300, np.inf]])
    want = _dp_numpy(profile, r)
    assert np.array_equal(profile.density(r), want)
    p, d = profile.evaluate(r)
    assert np.array_equal(d, want) and np.array_equal(p, _p_numpy(profile, r))
    assert profile.evaluate(r, density=False)[1] is None


def _h_numpy(p: RadialProfile, x: np.ndarray, y: np.ndarray, n: int) -> np.ndarray:
    w_max = np.arcsinh(y / x)
    w_edge = (np.minimum(np.arccosh(np.clip(p.rho_um[-1] / x, 1.0, None)), w_max)
              if p.bounded else w_max)
    gx, gw = gauss_legendre(n)
    out = np.zeros(x.size)
    for lo, hi in ((np.zeros_like(w_max), w_edge), (w_edge, w_max)):
        half = 0.5 * (hi - lo)[:, None]
        cosh = np.cosh(0.5 * (hi + lo)[:, None] + half * gx[None, :])
        out += np.sum(_p_numpy(p, x[:, None] * cosh) / cosh * half * gw[None, :], axis=1)
    return out


@pytest.mark.parametrize("profile", _profiles(), ids=lambda p: f"bounded={p.bounded}")
@pytest.mark.parametrize("n", [16, 64])
def test_corner_integral_is_numpys_to_rounding(profile, n):
    rng = np.random.default_rng(2)
    x, y = rng.uniform(0.05, 80.0, 3_000), rng.uniform(0.05, 80.0, 3_000)
    want = _h_numpy(profile, x, y, n)
    np.testing.assert_allclose(sp._h(profile, x, y, n), want, rtol=1e-13, atol=1e-17)
