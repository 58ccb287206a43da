"""atp_dose_response: the limit of detection (blank + 3σ) is what the noise model predicts, and the
blank's 3σ threshold gives the false-positive rate a normal blank should.

Salama et al. 2004, §4: the kinetics, optics, sensor and post-processing models together give
"the minimum detectable analyte concentration" for a set of system parameters; the paper gives no
number for it on the CMOS chip, so the LoD is checked against its closed form from the same
models (eq. 12 light, the Lambertian view factor of the diode, eq. 21 noise with CMS, the ADC's
rounding and the dark reference), not against a published figure. The closed form is the
paper's idealised chip (the ideal converter, the NA² convention, nothing returned from above):
the checks of it run the scene on that chip (``PAPER_CHIP``); the bundled scene is the chip as
built.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from chiptwin.config import ScenarioError, load_scenario
from chiptwin.constants import N_A, Q_E
from chiptwin.twin.dose_response import interpolate_lod
from chiptwin.twin.runner import prepare, run_prepared
from tests.conftest import PAPER_CHIP, SCENARIOS

PATH = SCENARIOS / "atp_dose_response.toml"


def _run(s, seed: int | None = None, scene=None):
    """The scenario run with each site's amount (the scene made once per chip, then reused)."""
    scene = scene or prepare(s)
    if seed is not None:
        s = dataclasses.replace(s, scenario=dataclasses.replace(s.scenario, seed=seed))
    return run_prepared(s, scene)


@pytest.fixture(scope="module")
def result():
    return _run(load_scenario(PATH, PAPER_CHIP))


def _view_factor(half_w_um: float, height_um: float) -> float:
    """Share of a Lambertian point emitter's light on a square diode centred below it: four
    corner rectangles of the differential-area-to-parallel-rectangle view factor."""
    a = b = half_w_um / height_um
    f = (a / math.hypot(1, a) * math.atan(b / math.hypot(1, a))
         + b / math.hypot(1, b) * math.atan(a / math.hypot(1, b))) / (2 * math.pi)
    return 4 * f


def _rounding_var_of_mean(m: int, noise_lsb: float) -> float:
    """Rounding error of the mean of M codes of one level with white noise: 1/(12M) + (1 − 1/M)·c,
    c the covariance of two errors, from the sawtooth's Fourier series. Unit: LSB²."""
    k = np.arange(1, 200)
    c = np.sum(np.exp(-4 * np.pi**2 * k**2 * noise_lsb**2) / (2 * np.pi**2 * k**2))
    return 1 / (12 * m) + (1 - 1 / m) * c


def _analytic(s, block_t_s: np.ndarray) -> tuple[float, float]:
    """(e⁻ per amol, σ of a blank) of the matched-filter estimate, in closed form.

    Light (eq. 12): 1 amol gives α·N_A·1e-18·(e^{−k(a−t0)} − e^{−k(b−t0)}) photons in a window
    [a, b]. Noise per frame (eq. 21 with CMS): dark shot + 2σ_read²/M + twice the rounding of an
    M-sample mean. The estimate N·c·Σ w_j ȳ_j (w_j = e^{−k(t_j − t0)}, c = Σw/Σw²) minus the
    dark reference (the mean of n_d dark frames, common to every output) has variance
    N·c²·Σw²·v + (N·c·Σw)²·v/n_d.
    """
    a, px, chip, dsp = s.assay, s.chip.pixel, s.chip, s.chip.dsp
    t_off = chip.timing.t_reset_s + dsp.cms_samples * chip.adc.conversion_time_s
    k_t, n = a.turnover_per_s, dsp.average_frames
    first = round(a.start_s / chip.timing.frame_period_s)
    frames = np.arange(first, round(s.run.duration_s / chip.timing.frame_period_s))
    w0 = frames * chip.timing.frame_period_s + t_off - a.start_s
    photons = a.quantum_yield * N_A * 1e-18 * (np.exp(-k_t * w0)
                                               - np.exp(-k_t * (w0 + chip.timing.t_int_s)))
    electrons = px.qe * _view_factor(px.diode_w_um / 2, s.sites.height_um) * photons
    t = block_t_s[block_t_s > a.start_s]
    w = np.exp(-k_t * (t - a.start_s))
    c = w.sum() / (w**2).sum()
    g = c * np.sum(w * electrons.reshape(-1, n).sum(axis=1))
    dark = px.dark_current_nA_per_cm2 * 1e-9 * px.diode_w_um * px.diode_h_um * 1e-8 / Q_E
    e_per_lsb = (chip.adc.v_max_V - chip.adc.v_min_V) / 2**chip.adc.bits / (
        Q_E / (px.capacitance_fF * 1e-15))
    m = dsp.cms_samples
    v = (dark * chip.timing.t_int_s + 2 * px.read_noise_e**2 / m
         + 2 * e_per_lsb**2 * _rounding_var_of_mean(m, px.read_noise_e / e_per_lsb))
    var = n * c**2 * (w**2).sum() * v + (n * c * w.sum()) ** 2 * v / dsp.n_dark_frames
    return float(g), math.sqrt(var)


def test_lod_is_the_noise_models_three_sigma_over_the_slope(result):
    """LoD = 3σ_blank / (e⁻ per amol), within 5 %.

    Tolerance: the twin's LoD interpolates between two sites whose gains differ by the PRNU (1 %
    rms each), its dose sites read ≈ 1.2 % of their neighbours' light (contact PSF), its blank σ
    is the rms over 48 pixels whose dark currents spread by the DSNU (10 % rms: ≈ 0.5 % on σ),
    and its blank mean carries the doses' far cross-talk (< 1 % of the threshold): ≈ 2 % combined.
    """
    s, d = result.scenario, result.summary["dose_response"]
    g, sigma = _analytic(s, result.arrays["block_t_s"])
    assert d["blank"]["sigma_model_e"] == pytest.approx(sigma, rel=0.02)
    assert d["slope_e_per_amol"] == pytest.approx(g, rel=0.03)
    assert d["lod_amol"] == pytest.approx(3 * sigma / g, rel=0.05)
    lo, hi = d["dose_range_amol"]
    assert lo < d["lod_amol"] < hi and (lo, hi) == (0.001, 100.0)  # five decades around it
    assert d["loglog_slope"] == pytest.approx(1.0, abs=0.01)  # a linear response


def test_lod_from_the_blank_sites_spread_agrees(result):
    """The 48 blanks' sample mean + 3 sd gives the same LoD within 3 of its standard errors, and
    their spread is the model's σ within 3 standard errors of a normal sample's sd."""
    d = result.summary["dose_response"]
    b = d["blank"]
    assert abs(b["sd_ratio_measured_to_model"] - 1) < 3 * b["sd_ratio_se"]
    assert abs(d["lod_from_blank_spread_amol"] - d["lod_amol"]) < 3 * d[
        "lod_from_blank_spread_se_amol"]
    above = [p["above_threshold"] for p in d["points"]]
    first = above.index(True)
    assert d["points"][first]["amount_amol"] > d["lod_amol"] / 3  # no dose far below it is seen
    assert all(above[first + 2:])  # every dose from 5× the LoD up is


def test_each_site_emits_eq12_for_its_own_amount(result):
    """Site photons per window are eq. 12's for the site's amount (blanks: none), rtol 1e-9."""
    s = result.scenario
    amounts = np.array(s.sites.amounts_fmol) * 1e-15
    photons = result.arrays["site_photons"]
    top = int(np.argmax(amounts))
    np.testing.assert_allclose(photons, photons[top] * (amounts / amounts[top])[:, None],
                               rtol=1e-9, atol=0)
    assert photons[amounts == 0].max() == 0
    assert photons[top].sum() == pytest.approx(
        0.88 * N_A * amounts[top] * (1 - math.exp(-0.1 * 60)), rel=0.02)  # 99 % in windows


def test_a_scene_that_ignores_the_amounts_is_refused():
    """Figures from a scene prepared with one amount everywhere would be a flat 'dose response'."""
    s = load_scenario(PATH)
    same = dataclasses.replace(s, sites=dataclasses.replace(s.sites, amounts_fmol=[]))
    with pytest.raises(ScenarioError, match="sites.amounts_fmol"):
        run_prepared(s, prepare(same))


def test_interpolate_lod_table():
    x, y = np.array([1.0, 10.0, 100.0]), np.array([2.0, 20.0, 200.0])
    assert interpolate_lod(x, y, 11.0) == pytest.approx(5.5)  # inside a segment
    assert interpolate_lod(x[::-1], y[::-1], 11.0) == pytest.approx(5.5)  # any order
    assert interpolate_lod(x, y, 20.0) == pytest.approx(10.0)  # on a point
    assert interpolate_lod(x, y, 1.0) == pytest.approx(0.5)  # below the range: through 0
    assert math.isnan(interpolate_lod(x, y, 1e3))  # never reached


def test_blank_three_sigma_threshold_gives_the_normal_false_positive_rate():
    """Monte Carlo: 75 seeds × 512 blank sites (38,400 blanks) on the reference chip's pixels,
    ADC and DSP in a 32 × 16 array (4 times its 8 × 16, so a quarter of the runs: a run's cost is
    mostly per frame; every blank is its own pixel, drawn independently), 20 s of the glow's
    window. The fraction above the summary's threshold (blank mean + 3σ, σ from the noise
    model) is the normal tail each site's σ predicts (≈ 1 − Φ(3) = 0.135 %) within the 99.9 %
    Clopper–Pearson interval of the count; and the blanks' z-scores have sd 1 within 3 % (8
    standard errors of it). A σ 10 % too small would give ≈ 0.32 %, far outside."""
    rows, seeds = 32, 75
    zeros = "[" + ", ".join(["0"] * (rows * 16)) + "]"
    s = load_scenario(PATH, ['sites.at_pixels="all"', f"sites.amounts_fmol={zeros}",
                             "run.duration_s=40", f"chip.rows={rows}",
                             "chip.memory.capacity_bits=4194304"])  # 4 × the 1 Mbit for 4 × pixels
    scene = prepare(s)
    above, expected, z = 0, 0.0, []
    for seed in range(seeds):
        r = _run(s, seed, scene)
        d, a = r.summary["dose_response"], r.arrays
        mean, sd = a["dose_expected_e"], a["dose_sd_e"]
        above += int(np.sum(a["dose_signal_e"] > d["threshold_e"]))
        expected += float(np.sum(stats.norm.sf((d["threshold_e"] - mean) / sd)))
        z.append((a["dose_signal_e"] - mean) / sd)
    n = seeds * rows * 16
    ci = stats.binomtest(above, n).proportion_ci(confidence_level=0.999)
    assert ci.low <= expected / n <= ci.high, (above, expected)
    assert expected / n == pytest.approx(1 - stats.norm.cdf(3), rel=0.05)
    assert np.std(np.concatenate(z)) == pytest.approx(1.0, abs=0.03)


def test_a_pyrosequencing_dose_response_compares_one_mer_levels():
    """Per-site DNA on pyro_1fmol's chip (idealised: under the flow cell's lid the blanks would
    read the light it returns): each site's expected signal is its key 1-mer level
    (eq. 19 light ∝ DNA, within 3 %: PRNU 1 % rms and neighbours' cross-talk), the measured
    1-mer level is within 5 of its standard deviations of it, and the blanks read no light."""
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", PAPER_CHIP + [
        "sites.at_pixels=[[4, 8], [2, 3], [6, 12], [1, 14], [6, 3]]",
        "sites.amounts_fmol=[1.0, 0.1, 0.01, 0, 0]"])
    d = _run(s).summary["dose_response"]
    points = {p["amount_amol"]: p for p in d["points"]}
    one_fmol = points[1000.0]["expected_signal_e"]
    for amol, p in points.items():
        assert p["expected_signal_e"] == pytest.approx(one_fmol * amol / 1000.0, rel=0.03)
        assert abs(p["signal_e"] - p["expected_signal_e"]) < 5 * p["noise_e"]
    assert abs(d["blank"]["mean_model_e"]) < 0.01 * d["blank"]["sigma_model_e"]
    assert 0 < d["lod_amol"] < 100.0
