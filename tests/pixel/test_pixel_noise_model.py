"""The noise model measured, not trusted: simulated flat fields and dark series go through the
whole binned chain (sample_frame → to_volts → adc_convert → signal − reset, as the DSP forms it),
and the sensor's parameters are recovered the way a test bench measures a real sensor (photon
transfer curve, dark series, frame averaging: EMVA 1288 style), then compared with the values
put in.

Every tolerance is 5 standard errors of the estimator, computed from the number of pixels and
frames (the standard error of a sample variance is √((m4 − m2²)/n) from the data's own fourth
moment; errors of independent estimates add in quadrature; a parameter derived from several
estimates gets its error by the delta method).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from chiptwin.characterize.estimators import pair_stats, spatial_stats, var_se
from chiptwin.pixel import (
    adc_convert,
    conversion_gain_uV_per_e,
    dark_current_e_per_s,
    fixed_pattern_maps,
    ktc_noise_e,
    lsb_V,
    sample_frame,
    to_volts,
)

N_SIDE = 512
N_PIX = N_SIDE * N_SIDE
QE = 0.5


@dataclass(frozen=True)
class Bench:
    """A simulated sensor on the test bench: what is put in, to be measured back."""

    capacitance_fF: float
    read_noise_e: float
    bits: int
    v_max_V: float
    pedestal_V: float
    exposures_e: tuple[float, ...]  # mean collected charge of the PTC flat fields
    prnu: float = 0.01
    dsnu: float = 0.1
    full_well_e: float = 1e7

    @property
    def cg(self) -> float:
        return conversion_gain_uV_per_e(self.capacitance_fF)

    @property
    def ktc(self) -> float:
        return ktc_noise_e(self.capacitance_fF)

    @property
    def gain_codes_per_e(self) -> float:
        return self.cg * 1e-6 / lsb_V(self.bits, 0.0, self.v_max_V)


SMALL_NODE = Bench(10.0, 30.0, 12, 1.0, 0.1, (0.0, 2000.0, 5000.0, 10_000.0, 20_000.0, 30_000.0))
LARGE_NODE = Bench(1000.0, 100.0, 16, 0.25, 0.05, (0.0, 1e5, 2.5e5, 5e5, 7.5e5))


def cds_codes(rng, bench, photons, dark_e, gain_map, true_cds=True, n_frames=2):
    """``n_frames`` CDS images in codes: mean(signal codes) − mean(reset codes), shape (F, n)."""
    out = []
    for _ in range(n_frames):
        reset, signal = sample_frame(
            rng,
            photons,
            QE,
            gain_map,
            dark_e,
            bench.full_well_e,
            bench.ktc,
            bench.read_noise_e,
            1,
            true_cds,
        )
        codes = [
            adc_convert(to_volts(x, bench.cg, bench.pedestal_V), bench.bits, 0.0, bench.v_max_V)
            for x in (reset, signal)
        ]
        out.append(codes[1].mean(axis=0) - codes[0].mean(axis=0))
    return np.array(out)


def pair(frames: np.ndarray) -> tuple[float, float, float, float]:
    """Mean, temporal variance var(A − B)/2 and their standard errors, from a frame pair (the
    bench's estimator, :func:`chiptwin.characterize.estimators.pair_stats`)."""
    p = pair_stats(frames[0], frames[1])
    return p.mean, p.var, p.mean_se, p.var_se


def photon_transfer(rng, bench, gain_map):
    """Weighted straight-line fit of temporal variance against mean: slope = gain (codes/e⁻)."""
    means, variances, ses = [], [], []
    for e in bench.exposures_e:
        frames = cds_codes(rng, bench, np.full(N_PIX, e / QE), 0.0, gain_map)
        m, v, _, se = pair(frames)
        means.append(m)
        variances.append(v)
        ses.append(se)
    x = np.column_stack([np.ones(len(means)), means])
    w = 1.0 / np.square(ses)
    cov = np.linalg.inv(x.T @ (x * w[:, None]))
    beta = cov @ x.T @ (w * np.array(variances))
    return float(beta[1]), float(np.sqrt(cov[1, 1]))


@pytest.fixture(scope="module", params=[SMALL_NODE, LARGE_NODE], ids=["10fF", "1pF"])
def measured(request):
    """Everything measured on one bench sensor, once per module."""
    bench = request.param
    rng = np.random.default_rng(20240601)
    gain_map, dark_map = fixed_pattern_maps(rng, N_PIX, bench.prnu, bench.dsnu)
    g, g_se = photon_transfer(rng, bench, gain_map)
    return {
        "bench": bench,
        "rng": rng,
        "gain_map": gain_map,
        "dark_map": dark_map,
        "g": g,
        "g_se": g_se,
    }


def test_photon_transfer_recovers_conversion_gain(measured):
    """The variance-vs-mean slope of flat-field pairs is the gain in codes/e⁻; times the LSB it
    is the conversion gain q/C (16.0 µV/e⁻ at 10 fF, 0.160 µV/e⁻ at 1 pF, sources.md
    P6). Tolerance: 5 standard errors of the weighted fit's slope (≈ 0.3 % here)."""
    bench, g, g_se = measured["bench"], measured["g"], measured["g_se"]
    assert abs(g - bench.gain_codes_per_e) < 5 * g_se
    assert g_se / g < 0.01
    cg_measured = g * lsb_V(bench.bits, 0.0, bench.v_max_V) * 1e6
    assert abs(cg_measured - bench.cg) < 5 * g_se / g * bench.cg


def _read_noise(measured) -> tuple[float, float, float, float]:
    """Read noise from a zero-exposure dark pair: var(D) = 2(σ_r²g² + 1/12) codes² (true CDS)."""
    bench, g = measured["bench"], measured["g"]
    frames = cds_codes(measured["rng"], bench, np.zeros(N_PIX), 0.0, 1.0)
    _, v, _, se_v = pair(frames)
    u = v / 2 - 1.0 / 12.0  # σ_r² g², in codes²
    return float(np.sqrt(u) / g), u, se_v / 2, v


def test_dark_series_recovers_read_noise(measured):
    """Read noise (e⁻ rms per sample) from dark frames at zero exposure, converted with the
    measured gain. Tolerance: 5 se, the variance's and the gain's relative errors in quadrature."""
    bench, g, g_se = measured["bench"], measured["g"], measured["g_se"]
    sigma, u, se_u, _ = _read_noise(measured)
    rel = np.hypot(se_u / (2 * u), g_se / g)
    assert abs(sigma - bench.read_noise_e) < 5 * rel * bench.read_noise_e


def test_dark_series_recovers_dark_current(measured):
    """Dark current (e⁻/s) from the slope of the mean dark signal over 0–2 s, converted with the
    measured gain: 1 nA/cm² on 10 × 10 µm at 25 °C = 6241.5 e⁻/s (its DSNU map averages to 1, so
    it does not bias the mean). Tolerance: 5 se of the slope and of the gain, in quadrature."""
    bench, rng, g, g_se = measured["bench"], measured["rng"], measured["g"], measured["g_se"]
    i_dark = dark_current_e_per_s(1.0, 100.0, 25.0)
    times = np.array([0.0, 0.5, 1.0, 2.0])
    means, ses = [], []
    for t in times:
        frames = cds_codes(rng, bench, np.zeros(N_PIX), i_dark * t * measured["dark_map"], 1.0)
        m, _, se_m, _ = pair(frames)  # temporal noise only: the DSNU map averages to 1
        means.append(m)
        ses.append(se_m)
    w = 1.0 / np.square(ses)
    x = np.column_stack([np.ones_like(times), times])
    cov = np.linalg.inv(x.T @ (x * w[:, None]))
    slope = (cov @ x.T @ (w * np.array(means)))[1]
    measured_e_per_s = slope / g
    rel = np.hypot(np.sqrt(cov[1, 1]) / slope, g_se / g)
    assert abs(measured_e_per_s - i_dark) < 5 * rel * i_dark


def _fixed_pattern(measured, photons, dark_e, n_frames=8) -> tuple[float, float]:
    """Spatial rms of the frame-averaged image, less temporal noise, over its mean; and its se."""
    frames = cds_codes(
        measured["rng"], measured["bench"], photons, dark_e, measured["gain_map"], n_frames=n_frames
    )
    avg = frames.mean(axis=0)
    stats = spatial_stats(avg, frames.var(axis=0, ddof=1), n_frames)  # the bench's estimator
    frac2 = stats.s2 / stats.mean**2
    # the image's own variance error, and the drawn map's spread about the parameter (≈ equal)
    se_frac2 = np.sqrt(2.0) * var_se(avg) / stats.mean**2
    return float(frac2), float(se_frac2)


def test_flat_fields_recover_prnu(measured):
    """PRNU from 8 averaged flat fields at half the PTC's top exposure, dark-free: spatial
    variance less temporal variance / 8, over the mean². Tolerance: 5 se on PRNU²."""
    bench = measured["bench"]
    photons = np.full(N_PIX, bench.exposures_e[-1] / 2 / QE)
    frac2, se = _fixed_pattern(measured, photons, 0.0)
    assert abs(frac2 - bench.prnu**2) < 5 * se


def test_dark_frames_recover_dsnu(measured):
    """DSNU from 8 averaged dark frames (no light; the gain map does not touch dark charge).
    Tolerance: 5 se on DSNU²."""
    bench = measured["bench"]
    dark_e = bench.exposures_e[-1] / 2 * measured["dark_map"]
    frac2, se = _fixed_pattern(measured, np.zeros(N_PIX), dark_e)
    assert abs(frac2 - bench.dsnu**2) < 5 * se


def test_no_cds_dark_frames_recover_ktc(measured):
    """Validation: kTC noise measured from dark frames read without true CDS (the reset samples
    carry an independent kTC draw): var(D) = 2g²(σ_kTC² + σ_r²) + 2/12, with g and σ_r measured
    above. sources.md P5: 40 e⁻ at 10 fF, 402 e⁻ at 1 pF (300 K). Tolerance: 5 se by
    the delta method plus the reference's rounding to whole electrons (0.5 e⁻). With true CDS the
    same dark frames lack the 2g²σ_kTC² excess."""
    bench, g, g_se = measured["bench"], measured["g"], measured["g_se"]
    _, u, se_u, v_cds = _read_noise(measured)  # true CDS: read noise and quantisation only
    frames = cds_codes(measured["rng"], bench, np.zeros(N_PIX), 0.0, 1.0, true_cds=False)
    _, v, _, se_v = pair(frames)
    numerator = (v - 1.0 / 6.0) / 2 - u  # σ_kTC² g²
    ktc2 = numerator / g**2
    se_ktc2 = np.hypot(np.hypot(se_v / 2, se_u) / g**2, 2 * ktc2 * g_se / g)
    ktc = np.sqrt(ktc2)
    published = {10.0: 40.0, 1000.0: 402.0}[bench.capacitance_fF]
    assert abs(ktc - published) < 5 * se_ktc2 / (2 * ktc) + 0.5
    assert v - v_cds > (g * published) ** 2  # true CDS removes the 2g²σ_kTC² excess
