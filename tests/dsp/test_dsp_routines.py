"""The DSP routines: fixed vs the slow exact reference (every mode, SAT_SYM and unsigned registers
included), fixed vs float within each routine's analytic bound, shapes and validation.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from chiptwin.dsp import reference
from chiptwin.dsp.errors import Case, compare
from chiptwin.dsp.filters import (
    FirConfig,
    KineticsConfig,
    WienerConfig,
    design_wiener,
    fir_fixed,
    kinetics_weighted_fixed,
    wiener_equalize_fixed,
)
from chiptwin.dsp.fixed import OVERFLOW_MODES, ROUNDING_MODES, Fmt
from chiptwin.dsp.frame_ops import (
    AverageConfig,
    BackgroundConfig,
    BinningConfig,
    CmsConfig,
    accumulate_frames_fixed,
    average_frames_fixed,
    bin_lines_fixed,
    cms_fixed,
    subtract_background_fixed,
)
from chiptwin.dsp.stress import default_configs, random_codes, stress_coupling, stress_inputs
from tests.dsp import _dsp_exact as ex

ROUTINES = ("background", "cms", "accumulate", "average", "binning", "kinetics", "fir", "wiener")


def _variant(routine: str, rnd: str, ovf: str):
    """Small configs whose registers overflow, some of them unsigned."""
    if routine == "background":
        return BackgroundConfig(out_fmt=Fmt(False, 14, 1), rounding=rnd, overflow=ovf)
    if routine == "cms":
        return CmsConfig(
            m=3,
            acc_fmt=Fmt(False, 14, 0),
            out_fmt=Fmt(True, 13, 1),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    if routine in ("accumulate", "average"):
        return AverageConfig(
            n=3 if routine == "average" else 4,
            acc_fmt=Fmt(True, 17, 2),
            out_fmt=Fmt(True, 15, 3),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    if routine == "binning":
        return BinningConfig(rows=4, cols=3, out_fmt=Fmt(False, 16, 1), rounding=rnd, overflow=ovf)
    if routine == "kinetics":
        return KineticsConfig(
            t_s=tuple(float(i) for i in range(6)),
            k_per_s=0.2,
            acc_fmt=Fmt(True, 32, 17),
            out_fmt=Fmt(True, 14, 1),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    if routine == "fir":
        return FirConfig(
            acc_fmt=Fmt(True, 30, 17),
            out_fmt=Fmt(True, 14, 1),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    cfg = WienerConfig(
        acc_word_bits=33, out_fmt=Fmt(True, 15, 1), rounding=rnd, overflow=ovf, acc_overflow=ovf
    )
    return design_wiener(stress_coupling(2, 3), cfg)


def _fixed_and_naive(routine: str, cfg, inputs):
    tally = ex.Tally()
    if routine == "background":
        ours = subtract_background_fixed(inputs["frames"], inputs["dark"], cfg)
        naive = ex.naive_background(inputs["frames"], inputs["dark"], cfg, tally)
    elif routine == "cms":
        ours = cms_fixed(inputs["reset"], inputs["signal"], cfg)
        naive = ex.naive_cms(inputs["reset"], inputs["signal"], cfg, tally)
    elif routine == "accumulate":
        ours = accumulate_frames_fixed(inputs["frames"], cfg)
        naive = ex.naive_average(inputs["frames"], cfg, tally, divide=False)
    else:
        fixed_fn, naive_fn = {
            "average": (average_frames_fixed, ex.naive_average),
            "binning": (bin_lines_fixed, ex.naive_binning),
            "kinetics": (kinetics_weighted_fixed, ex.naive_kinetics),
            "fir": (fir_fixed, ex.naive_fir),
            "wiener": (wiener_equalize_fixed, ex.naive_wiener),
        }[routine]
        ours = fixed_fn(inputs["frames"], cfg)
        naive = naive_fn(inputs["frames"], cfg, tally)
    return ours, naive, tally


@pytest.mark.parametrize("ovf", OVERFLOW_MODES)
@pytest.mark.parametrize("rnd", ROUNDING_MODES)
@pytest.mark.parametrize("routine", ROUTINES)
def test_routine_matches_exact_reference(routine: str, rnd: str, ovf: str, rng) -> None:
    """Codes and per-register overflow counts equal the value-by-value Fraction reference."""
    cfg = _variant(routine, rnd, ovf)
    n_px = 6 if routine == "wiener" else 12
    inputs = stress_inputs(routine, cfg, rng, n_frames=24, n_pixels=n_px)
    ours, naive, tally = _fixed_and_naive(routine, cfg, inputs)
    np.testing.assert_array_equal(ours.codes, naive)
    for register in set(ours.overflow) | set(tally.counts):
        if register in ("weights", "coef"):  # the coefficient ROM: checked in the configs
            continue
        assert ours.overflow[register] == tally.get(register), register
    assert sum(ours.total().values()) > 0, "stress data must overflow these registers"


# --- float vs fixed ---------------------------------------------------------------------------


def _configs_in_every_rounding_mode():
    for label, (routine, cfg) in default_configs(4, 8).items():
        for rnd in ROUNDING_MODES:
            if routine == "wiener":
                wcfg = WienerConfig(rounding=rnd)
                yield f"{label}-{rnd}", routine, design_wiener(stress_coupling(4, 8), wcfg)
            elif hasattr(cfg, "rounding"):
                from dataclasses import replace

                yield f"{label}-{rnd}", routine, replace(cfg, rounding=rnd)


@pytest.mark.parametrize(
    "label, routine, cfg", list(_configs_in_every_rounding_mode()), ids=lambda v: str(v)[:24]
)
def test_fixed_within_analytic_bound_of_float(label: str, routine: str, cfg, rng) -> None:
    inputs = stress_inputs(routine, cfg, rng, n_frames=160, n_pixels=32)
    row = compare(Case(routine, cfg, inputs))
    assert row["bound_ok"] is True, (label, row["max_abs_err_in_range_lsb"], row["bound_lsb"])
    assert row["max_abs_err_in_range_lsb"] <= row["bound_lsb"]
    json.dumps(row, allow_nan=False)


def test_bound_is_tight_enough_to_mean_something(rng) -> None:
    """Nearest rounding meets 0.5 LSB exactly at ties; TRN errs by almost 1 LSB and is biased."""
    cfg = BackgroundConfig()
    inputs = stress_inputs("background", cfg, rng, 200, 128)
    nearest = compare(Case("background", cfg, inputs))
    assert nearest["max_abs_err_lsb"] == 0.5 and abs(nearest["mean_err_lsb"]) < 0.05
    from dataclasses import replace

    trn = compare(Case("background", replace(cfg, rounding="TRN"), inputs))
    assert 0.7 <= trn["max_abs_err_lsb"] < 1.0
    assert trn["mean_err_lsb"] < -0.3  # floor: about −3/8 LSB for 2 dropped bits


def test_exact_paths_are_exact(rng) -> None:
    """Power-of-two division into enough fractional bits, binning and accumulation lose nothing."""
    cases = {
        "cms": CmsConfig(m=4),
        "accumulate": AverageConfig(n=16),
        "average": AverageConfig(n=4, out_fmt=Fmt(True, 18, 4)),
        "binning": BinningConfig(rows=4, cols=8),
    }
    for routine, cfg in cases.items():
        row = compare(Case(routine, cfg, stress_inputs(routine, cfg, rng, 64, 32)))
        assert row["exact"] and row["sqnr_db"] is None and row["bound_lsb"] < 1e-5, routine


# --- the estimators the routines implement ----------------------------------------------------


def test_kinetics_estimator_recovers_a_clean_decay() -> None:
    t = np.arange(20.0)
    frames = 1234.5 * np.exp(-0.05 * t)[:, None] * np.ones((1, 3))
    np.testing.assert_allclose(reference.kinetics_weighted_amplitude(frames, t, 0.05), 1234.5)


def test_kinetics_estimator_variance_is_sigma2_over_energy(rng) -> None:
    """Var(Â) = σ² / Σ w² (the documented matched-filter gain), to 3 % with 40 000 draws."""
    t, k, sigma = np.arange(16.0), 0.05, 3.0
    w = reference.kinetics_weights(t, k)
    noise = rng.normal(0.0, sigma, (16, 40_000))
    est = reference.kinetics_weighted_amplitude(100.0 * w[:, None] + noise, t, k)
    assert abs(est.mean() - 100.0) < 0.05
    assert est.var() == pytest.approx(sigma**2 / np.dot(w, w), rel=0.03)


def test_fixed_kinetics_tracks_a_decay_within_its_bound(rng) -> None:
    cfg = KineticsConfig()
    w = reference.kinetics_weights(np.array(cfg.t_s), cfg.k_per_s)
    amplitude = rng.uniform(-8000, 8000, 256)
    codes = np.round(4 * amplitude[None, :] * w[:, None]).astype(np.int64)
    row = compare(Case("kinetics", cfg, {"frames": codes}))
    assert row["bound_ok"] is True
    fixed = kinetics_weighted_fixed(codes, cfg).values()
    np.testing.assert_allclose(fixed, amplitude, atol=0.5 + row["bound_lsb"] * 0.25)


def test_wiener_with_zero_lambda_inverts_the_coupling(rng) -> None:
    c = stress_coupling(3, 4)
    sites = rng.uniform(0, 5000, (10, 12))
    g = reference.wiener_matrix(c, 0.0)
    np.testing.assert_allclose(reference.wiener_equalize(sites @ c.T, g), sites, atol=1e-8)
    eq = design_wiener(c, WienerConfig(noise_to_signal=0.0))
    pixels = np.round(4 * sites @ c.T).astype(np.int64)
    row = compare(Case("wiener", eq, {"frames": pixels}))
    assert row["bound_ok"] is True and row["max_abs_err_lsb"] <= row["bound_lsb"]


def test_fir_coefficients_are_a_quantized_linear_phase_low_pass() -> None:
    cfg = FirConfig()
    h = cfg.coefficients()
    assert h.size == 8 and abs(h.sum() - 1.0) < 1e-12
    codes = np.array(cfg.coef_codes)
    np.testing.assert_array_equal(codes, codes[::-1])
    np.testing.assert_array_equal(codes, np.round(h * 2**15))
    assert cfg.registers()["acc"] == Fmt(True, 40, 17)
    assert (cfg.rounding, cfg.overflow) == ("RND", "SAT")


# --- shapes, registers, validation ------------------------------------------------------------


def test_shapes(rng) -> None:
    adc = Fmt(False, 13, 0)
    frames = random_codes(adc, (5, 3, 12), rng)
    assert subtract_background_fixed(frames, np.zeros(12, int), BackgroundConfig()).codes.shape == (
        5,
        3,
        12,
    )
    reset = random_codes(adc, (2, 5, 4, 12), rng)
    assert cms_fixed(reset, reset, CmsConfig(m=4)).codes.shape == (2, 5, 12)
    word = Fmt(True, 16, 2)
    assert average_frames_fixed(
        random_codes(word, (12, 7), rng), AverageConfig(n=3)
    ).codes.shape == (
        4,
        7,
    )
    binned = bin_lines_fixed(random_codes(word, (3, 2, 128), rng), BinningConfig(factor=4))
    assert binned.codes.shape == (3, 2, 32)
    kin = kinetics_weighted_fixed(random_codes(word, (3, 16, 5), rng), KineticsConfig())
    assert kin.codes.shape == (3, 5)
    assert fir_fixed(random_codes(word, (20, 2, 3), rng), FirConfig()).codes.shape == (20, 2, 3)
    eq = design_wiener(stress_coupling(2, 4), WienerConfig())
    assert wiener_equalize_fixed(random_codes(word, (4, 8), rng), eq).codes.shape == (4, 8)


def test_registers_are_declared_in_data_path_order() -> None:
    assert list(CmsConfig(m=3).registers()) == [
        "input",
        "sum_reset",
        "sum_signal",
        "diff",
        "recip",
        "product",
        "output",
    ]
    assert list(AverageConfig(n=8).registers()) == ["input", "acc", "scaled", "output"]
    assert AverageConfig(n=8).registers()["scaled"] == Fmt(True, 19, 5)
    assert list(KineticsConfig().registers()) == [
        "input",
        "weights",
        "product",
        "acc",
        "norm",
        "scaled",
        "output",
    ]
    for _, (_, cfg) in default_configs().items():
        for fmt in cfg.registers().values():
            assert isinstance(fmt, Fmt)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: AverageConfig(n=0), r"AverageConfig.n = 0"),
        (lambda: AverageConfig(rounding="ROUND"), r"AverageConfig.rounding.*TRN"),
        (lambda: CmsConfig(acc_overflow="CLIP"), r"CmsConfig.acc_overflow.*WRAP"),
        (lambda: AverageConfig(acc_fmt=Fmt(True, 20, 0)), r"must keep the input's 2"),
        (lambda: BinningConfig(rows=8, factor=3), r"factor = 3: must divide rows = 8"),
        (lambda: FirConfig(cutoff=1.5), r"cutoff = 1.5"),
        (
            lambda: FirConfig(acc_fmt=Fmt(True, 40, 15)),
            r"FirConfig: acc_fmt = Q25.15: must keep the product's 17",
        ),
        (lambda: KineticsConfig(k_per_s=-1.0), r"k_per_s = -1.0"),
        (lambda: KineticsConfig(t_s=()), r"t_s = \(\)"),
        (
            lambda: KineticsConfig(coef_fmt=Fmt(False, 4, 2), k_per_s=10.0, t_s=(5.0,)),
            r"rounds to 0",
        ),
        (lambda: WienerConfig(noise_to_signal=-0.1), r"noise_to_signal = -0.1"),
        (
            lambda: BackgroundConfig(dark_fmt=Fmt(True, 64, 0)),
            r"BackgroundConfig: sub: the full-precision result needs 65 bits",
        ),
        (
            lambda: AverageConfig(n=7, in_fmt=Fmt(True, 48, 0)),
            r"AverageConfig: mul: .* needs 69 bits",
        ),
    ],
)
def test_bad_configs_are_refused_with_the_field_named(make, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make()


def test_bad_inputs_are_refused(rng) -> None:
    cfg = BackgroundConfig()
    with pytest.raises(ValueError, match=r"code 8192 outside UQ13.0"):
        subtract_background_fixed(np.array([[8192]]), np.array([0]), cfg)
    with pytest.raises(TypeError, match="uint64"):
        subtract_background_fixed(np.array([[1]], dtype=np.uint64), np.array([0]), cfg)
    with pytest.raises(TypeError, match="integers"):
        subtract_background_fixed(np.array([[1.0]]), np.array([0]), cfg)
    with pytest.raises(ValueError, match=r"dark shape \(2,\)"):
        subtract_background_fixed(np.zeros((2, 3), int), np.zeros(2, int), cfg)
    with pytest.raises(ValueError, match="multiple of 4"):
        average_frames_fixed(np.zeros((6, 3), int), AverageConfig(n=4))
    with pytest.raises(ValueError, match=r"M=4"):
        cms_fixed(np.zeros((3, 5), int), np.zeros((3, 5), int), CmsConfig(m=4))
    with pytest.raises(ValueError, match="N=16"):
        kinetics_weighted_fixed(np.zeros((15, 5), int), KineticsConfig())
    eq = design_wiener(stress_coupling(2, 2), WienerConfig())
    with pytest.raises(ValueError, match="n_pixels = 4"):
        wiener_equalize_fixed(np.zeros((2, 5), int), eq)


def test_configs_are_frozen_and_derive_with_replace() -> None:
    from dataclasses import FrozenInstanceError, replace

    cfg = KineticsConfig()
    with pytest.raises(FrozenInstanceError):
        cfg.k_per_s = 1.0  # type: ignore[misc]
    faster = replace(cfg, k_per_s=0.1)
    assert faster.weight_codes[1] < cfg.weight_codes[1]
    assert replace(FirConfig(), cutoff=0.1).coef_codes != FirConfig().coef_codes


def test_dark_reference_of_16_frames_is_exact(rng) -> None:
    """BackgroundConfig's default dark format keeps the 4 fractional bits of a 16-frame mean."""
    cfg = BackgroundConfig()
    dark_cfg = cfg.dark_config(16)
    frames = random_codes(cfg.in_fmt, (16, 40), rng)
    dark = average_frames_fixed(frames, dark_cfg)
    assert dark.fmt == cfg.dark_fmt and sum(dark.total().values()) == 0
    np.testing.assert_array_equal(dark.values()[0], frames.mean(axis=0))
    out = subtract_background_fixed(frames, dark.codes[0], cfg)
    assert out.fmt == cfg.out_fmt
