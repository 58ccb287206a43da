"""Equivalence: bit-exact agreement with APyTypes 0.5.1, an independent fixed-point library.

The oracle (``_dsp_apy.py``) rebuilds every operation from APyTypes arithmetic and ``cast``.
The ``apytypes_1e6`` tests run ≥ 1e6 random vectors (with the corners of the stress generators
mixed in) per core operation and per routine; the others sweep every rounding mode × WRAP / SAT on
smaller data with registers narrowed until they overflow, so that both overflow modes are really
exercised at the accumulator and at the output.
"""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.filters import (
    FirConfig,
    KineticsConfig,
    WienerConfig,
    design_wiener,
    fir_fixed,
    kinetics_weighted_fixed,
    wiener_equalize_fixed,
)
from chiptwin.dsp.fixed import ROUNDING_MODES, Fmt, add, mul, quantize, requantize, sub
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
from chiptwin.dsp.stress import random_codes, stress_coupling, stress_inputs
from tests.dsp import _dsp_apy as apy_oracle

MILLION = 1_000_000
APY_OVERFLOWS = ("WRAP", "SAT")  # APyTypes has no SAT_SYM (checked against Fraction instead)


# --- core operations --------------------------------------------------------------------------


def _float_vectors(fmt: Fmt, n: int, rng: np.random.Generator) -> np.ndarray:
    """Uniform over 1.25 × the range, a third exact ties, and the corners."""
    span = float(fmt.max_value) * 1.25
    x = rng.uniform(-span, span, n)
    ties = rng.integers(fmt.min_code - 4, fmt.max_code + 4, n // 3) + 0.5
    x[: n // 3] = np.ldexp(ties, -fmt.frac_bits)
    corners = [0.0, -0.0, float(fmt.max_value), float(fmt.min_value), 2.0**-40, -(2.0**-40)]
    x[-len(corners) :] = corners
    return x


FLOAT_CORNERS = np.array(
    [5e-324, -5e-324, 2.2250738585072014e-308, -1e-300, 1e300, -1e300, 2.0**62, -(2.0**63), 0.0]
)


@pytest.mark.apytypes_1e6
@pytest.mark.parametrize("fmt", [Fmt(True, 16, 12), Fmt(True, 16, 15), Fmt(True, 40, 30)])
def test_quantize_matches_apytypes(fmt: Fmt, rng: np.random.Generator) -> None:
    x = _float_vectors(fmt, MILLION, rng)
    exact_x = apy_oracle.exact(x, fmt)
    for rnd in ROUNDING_MODES:
        for ovf in APY_OVERFLOWS:
            got = quantize(x, fmt, rnd, ovf)
            want = apy_oracle.quantize(x, fmt, rnd, ovf, exact_x)
            np.testing.assert_array_equal(got, want, err_msg=rnd + ovf)


@pytest.mark.parametrize("fmt", [Fmt(True, 16, 12), Fmt(True, 64, 0), Fmt(True, 8, 1000)])
def test_quantize_float_corners_match_apytypes(fmt: Fmt) -> None:
    """Subnormals, huge values and ±2^63 need > 1000-bit exact words on the APyTypes side."""
    for rnd in ROUNDING_MODES:
        for ovf in APY_OVERFLOWS:
            got = quantize(FLOAT_CORNERS, fmt, rnd, ovf)
            want = apy_oracle.quantize(FLOAT_CORNERS, fmt, rnd, ovf)
            np.testing.assert_array_equal(got, want, err_msg=rnd + ovf)


@pytest.mark.apytypes_1e6
@pytest.mark.parametrize(
    "src, dst",
    [
        (Fmt(True, 40, 20), Fmt(True, 16, 8)),  # drop 12 bits and 16 integer bits
        (Fmt(True, 64, 40), Fmt(True, 24, 0)),  # 64-bit source, shift 40
        (Fmt(True, 16, 4), Fmt(True, 20, 12)),  # widening: exact
        (Fmt(True, 64, 0), Fmt(True, 64, 1)),  # left shift at the 64-bit limit
    ],
)
def test_requantize_matches_apytypes(src: Fmt, dst: Fmt, rng: np.random.Generator) -> None:
    codes = random_codes(src, (MILLION,), rng)
    for rnd in ROUNDING_MODES:
        for ovf in APY_OVERFLOWS:
            got = requantize(codes, src, dst, rnd, ovf)
            want = apy_oracle.requantize(codes, src, dst, rnd, ovf)
            np.testing.assert_array_equal(got, want, err_msg=rnd + ovf)


@pytest.mark.apytypes_1e6
@pytest.mark.parametrize(
    "fa, fb",
    [
        (Fmt(True, 16, 15), Fmt(True, 16, 15)),  # Q1.15 × Q1.15, −1 × −1 among the corners
        (Fmt(True, 24, 3), Fmt(True, 30, 20)),
        (Fmt(True, 32, 0), Fmt(True, 32, 31)),  # 64-bit product
        (Fmt(False, 13, 0), Fmt(True, 18, 4)),  # ADC code with a signed value
    ],
)
def test_full_precision_ops_match_apytypes(fa: Fmt, fb: Fmt, rng: np.random.Generator) -> None:
    a = random_codes(fa, (MILLION,), rng)
    b = random_codes(fb, (MILLION,), rng)
    ax, bx = apy_oracle.from_codes(a, fa), apy_oracle.from_codes(b, fb)
    for fn, expect in ((add, ax + bx), (sub, ax - bx), (mul, ax * bx)):
        if fn is not mul and fa.word_bits + fb.word_bits > 62:
            continue
        got, fmt = fn(a, fa, b, fb)
        if fa.signed and fb.signed:  # unsigned operands are one bit wider on the APyTypes side
            assert (expect.frac_bits, expect.int_bits) == (fmt.frac_bits, fmt.int_bits)
        else:
            assert fmt.frac_bits == expect.frac_bits and fmt.int_bits <= expect.int_bits
        # saturating into our (possibly narrower) format keeps equality only if it holds the value
        want = apy_oracle.to_codes(apy_oracle.cast(expect, fmt, "TRN", "SAT"), fmt)
        np.testing.assert_array_equal(got, want, err_msg=fn.__name__)


# --- routines ---------------------------------------------------------------------------------

WIENER = design_wiener(stress_coupling(8, 16), WienerConfig())


def _run(routine: str, cfg, inputs) -> tuple[np.ndarray, np.ndarray, dict]:
    """(our codes, APyTypes codes, our overflow counts)."""
    if routine == "background":
        ours = subtract_background_fixed(inputs["frames"], inputs["dark"], cfg)
        theirs = apy_oracle.background(inputs["frames"], inputs["dark"], cfg)
    elif routine == "cms":
        ours = cms_fixed(inputs["reset"], inputs["signal"], cfg)
        theirs = apy_oracle.cms(inputs["reset"], inputs["signal"], cfg)
    else:
        fixed_fn, apy_fn = {
            "accumulate": (accumulate_frames_fixed, apy_oracle.accumulate_frames),
            "average": (average_frames_fixed, apy_oracle.average),
            "binning": (bin_lines_fixed, apy_oracle.binning),
            "kinetics": (kinetics_weighted_fixed, apy_oracle.kinetics),
            "fir": (fir_fixed, apy_oracle.fir),
            "wiener": (
                wiener_equalize_fixed,
                lambda f, eq: apy_oracle.wiener(f, eq, eq.cfg.acc_overflow != "WRAP"),
            ),
        }[routine]
        ours = fixed_fn(inputs["frames"], cfg)
        theirs = apy_fn(inputs["frames"], cfg)
    return ours.codes, theirs, ours.overflow


DEFAULTS = {
    "background": BackgroundConfig(),
    "cms": CmsConfig(m=4),
    "cms3": CmsConfig(m=3),
    "accumulate": AverageConfig(n=64),
    "average": AverageConfig(n=4),
    "average5": AverageConfig(n=5),
    "binning": BinningConfig(),
    "kinetics": KineticsConfig(),
    "fir": FirConfig(),
    "wiener": WIENER,
}


@pytest.mark.apytypes_1e6
@pytest.mark.parametrize("name", list(DEFAULTS))
def test_routine_matches_apytypes_on_a_million_vectors(name: str, rng) -> None:
    cfg = DEFAULTS[name]
    routine = name.rstrip("0123456789")
    per_frame = 128 * (cfg.m if routine == "cms" else 1)
    n_frames = -(-MILLION // per_frame) + 64  # ≥ 1e6 values once rounded to whole runs
    inputs = stress_inputs(routine, cfg, rng, n_frames=n_frames, n_pixels=128)
    assert min(v.size for v in inputs.values() if v.ndim > 1) >= MILLION
    ours, theirs, _ = _run(routine, cfg, inputs)
    np.testing.assert_array_equal(ours, theirs)


def _narrowed(routine: str, rnd: str, ovf: str):
    """A config whose accumulator and output registers overflow on stress data."""
    if routine == "background":
        return BackgroundConfig(out_fmt=Fmt(True, 14, 1), rounding=rnd, overflow=ovf)
    if routine == "cms":
        return CmsConfig(
            m=3,
            acc_fmt=Fmt(True, 14, 0),
            out_fmt=Fmt(True, 13, 1),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    if routine in ("accumulate", "average"):
        return AverageConfig(
            n=6 if routine == "average" else 8,
            acc_fmt=Fmt(True, 17, 2),
            out_fmt=Fmt(True, 15, 3),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    if routine == "binning":
        return BinningConfig(factor=4, out_fmt=Fmt(True, 15, 1), rounding=rnd, overflow=ovf)
    if routine == "kinetics":
        return KineticsConfig(
            t_s=tuple(0.5 * i for i in range(12)),
            k_per_s=0.1,
            acc_fmt=Fmt(True, 33, 17),
            out_fmt=Fmt(True, 15, 1),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    if routine == "fir":
        return FirConfig(
            acc_fmt=Fmt(True, 31, 17),
            out_fmt=Fmt(True, 14, 1),
            rounding=rnd,
            overflow=ovf,
            acc_overflow=ovf,
        )
    cfg = WienerConfig(
        acc_word_bits=34, out_fmt=Fmt(True, 15, 1), rounding=rnd, overflow=ovf, acc_overflow=ovf
    )
    return design_wiener(stress_coupling(4, 8), cfg)


ROUTINES = ("background", "cms", "accumulate", "average", "binning", "kinetics", "fir", "wiener")


@pytest.mark.parametrize("ovf", APY_OVERFLOWS)
@pytest.mark.parametrize("rnd", ROUNDING_MODES)
@pytest.mark.parametrize("routine", ROUTINES)
def test_routine_matches_apytypes_in_every_mode(routine: str, rnd: str, ovf: str, rng) -> None:
    cfg = _narrowed(routine, rnd, ovf)
    n_px = 32 if routine == "wiener" else 128
    inputs = stress_inputs(routine, cfg, rng, n_frames=96, n_pixels=n_px)
    ours, theirs, overflow = _run(routine, cfg, inputs)
    np.testing.assert_array_equal(ours, theirs)
    events = {reg: c["sat"] + c["wrap"] for reg, c in overflow.items()}
    assert sum(events.values()) > 0, "the narrowed registers must overflow on stress data"
    kind = "wrap" if ovf == "WRAP" else "sat"
    assert all(c["sat" if kind == "wrap" else "wrap"] == 0 for c in overflow.values())


def test_apytypes_oracle_refuses_what_it_cannot_model() -> None:
    """The oracle's own guard rails: no unsigned casts, no SAT_SYM."""
    with pytest.raises(AssertionError):
        apy_oracle.cast(
            apy_oracle.from_codes(np.array([1]), Fmt(True, 4, 0)), Fmt(False, 4, 0), "RND", "SAT"
        )
    with pytest.raises(KeyError):
        apy_oracle.requantize(np.array([1]), Fmt(True, 4, 0), Fmt(True, 4, 0), "RND", "SAT_SYM")
