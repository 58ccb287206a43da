"""How far the bit-accurate DSP is from its float reference, against the bound it must meet.

For each routine on given inputs: max ``|fixed - float|`` in output LSB, mean error (bias), SQNR in
dB (these three over the outputs whose float value the output can reach: a clipped output's
error is its clipping, counted in ``n_clipped``, not rounding), overflow counts per register, and
the analytic bound, checked.

The bound (output LSB) is the sum of

* ``output_rounding``: the one requantization on each path (every other register is full
  precision or an accumulator wide enough not to overflow): 0 when it drops no bit, 0.5 for the
  round-to-nearest modes, 1 for TRN / TRN_ZERO;
* ``coefficients``: ``Σ_j |c_q,j - c_j| · max|x_j|`` over the coefficients ``c`` that multiply
  the inputs ``x`` (reciprocal ``1/n``, kinetics weights times their normalisation, FIR taps, one
  Wiener row), with ``max|x_j|`` taken from the data;
* a slack of 1e-6 LSB for the float reference's own rounding.

It holds for every output whose float value lies inside the output format's range (outputs
outside are counted as ``n_clipped``) as long as no register before the output overflowed; if one
did, ``bound_ok`` is None and the note names the register.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np

from chiptwin.dsp import reference
from chiptwin.dsp.filters import (
    FirConfig,
    KineticsConfig,
    WienerEqualizer,
    fir_fixed,
    kinetics_weighted_fixed,
    wiener_equalize_fixed,
)
from chiptwin.dsp.fixed import Fmt
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
from chiptwin.dsp.registers import FixedResult, reciprocal_error, rounding_error_lsb

SLACK_LSB = 1e-6
"""Allowance for the float reference's own rounding, in output LSB."""

ROUTINES: tuple[str, ...] = (
    "background",
    "cms",
    "accumulate",
    "average",
    "binning",
    "kinetics",
    "fir",
    "wiener",
)
"""Routine names understood by :func:`error_report`."""


class Case(NamedTuple):
    """One routine on one data set.

    ``inputs`` keys: background ``frames``, ``dark`` · cms ``reset``, ``signal`` · the others
    ``frames``. Arrays are integer codes of the config's input formats.
    """

    routine: str
    cfg: Any
    inputs: Mapping[str, np.ndarray]


@dataclass(frozen=True)
class _Run:
    fixed: FixedResult
    ref: np.ndarray
    terms: dict[str, float]


def _rounding_term(registers: dict[str, Fmt], rounding: str) -> float:
    names = list(registers)
    src = registers[names[names.index("output") - 1]]
    return rounding_error_lsb(rounding, src, registers["output"])


def _recip_term(n: int, recip_word_bits: int, max_abs: float, out: Fmt) -> float:
    return reciprocal_error(n, recip_word_bits) * max_abs / out.lsb


def divide_bound(cfg: CmsConfig | AverageConfig) -> float:
    """Worst ``|fixed − float|`` of one divide step (CMS by M, an average by N) over every input
    its format holds, in the inputs' units (ADC LSB for the chain): the output's rounding (half
    an output LSB to nearest, one for TRN and TRN_ZERO, none when no bit is dropped) plus the
    rounded reciprocal's error on the largest sum, ``n·max|input|``."""
    n = cfg.m if isinstance(cfg, CmsConfig) else cfg.n
    largest = float(max(abs(cfg.in_fmt.min_value), abs(cfg.in_fmt.max_value)))
    return (_rounding_term(cfg.registers(), cfg.rounding) * cfg.out_fmt.lsb
            + reciprocal_error(n, cfg.recip_word_bits) * n * largest)


def subtract_bound(cfg: BackgroundConfig) -> float:
    """Worst ``|fixed − float|`` the background subtraction adds, in the inputs' units: its
    output's rounding when the difference has more fractional bits than the output."""
    return _rounding_term(cfg.registers(), cfg.rounding) * cfg.out_fmt.lsb


def _max_abs(x: np.ndarray) -> float:
    return float(np.max(np.abs(x))) if x.size else 0.0


def _run_background(cfg: BackgroundConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    frames, dark = inputs["frames"], inputs["dark"]
    fixed = subtract_background_fixed(frames, dark, cfg)
    ref = reference.subtract_background(cfg.in_fmt.to_float(frames), cfg.dark_fmt.to_float(dark))
    terms = {"output_rounding": _rounding_term(cfg.registers(), cfg.rounding)}
    return _Run(fixed, ref, terms)


def _run_cms(cfg: CmsConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    reset, signal = cfg.in_fmt.to_float(inputs["reset"]), cfg.in_fmt.to_float(inputs["signal"])
    fixed = cms_fixed(inputs["reset"], inputs["signal"], cfg)
    ref = reference.correlated_multiple_sampling(reset, signal)
    diff_max = _max_abs(signal.sum(axis=-2) - reset.sum(axis=-2))
    terms = {
        "output_rounding": _rounding_term(cfg.registers(), cfg.rounding),
        "coefficients": _recip_term(cfg.m, cfg.recip_word_bits, diff_max, cfg.out_fmt),
    }
    return _Run(fixed, ref, terms)


def _run_accumulate(cfg: AverageConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    fixed = accumulate_frames_fixed(inputs["frames"], cfg)
    ref = reference.accumulate_frames(cfg.in_fmt.to_float(inputs["frames"]), cfg.n)
    return _Run(fixed, ref, {"output_rounding": 0.0})


def _run_average(cfg: AverageConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    x = cfg.in_fmt.to_float(inputs["frames"])
    fixed = average_frames_fixed(inputs["frames"], cfg)
    ref = reference.average_frames(x, cfg.n)
    sum_max = _max_abs(reference.accumulate_frames(x, cfg.n))
    terms = {
        "output_rounding": _rounding_term(cfg.registers(), cfg.rounding),
        "coefficients": _recip_term(cfg.n, cfg.recip_word_bits, sum_max, cfg.out_fmt),
    }
    return _Run(fixed, ref, terms)


def _run_binning(cfg: BinningConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    fixed = bin_lines_fixed(inputs["frames"], cfg)
    x = cfg.in_fmt.to_float(inputs["frames"])
    ref = reference.bin_lines(x, cfg.rows, cfg.cols, cfg.factor)
    return _Run(fixed, ref, {"output_rounding": _rounding_term(cfg.registers(), cfg.rounding)})


def _coef_term(delta: np.ndarray, x_max: np.ndarray, out: Fmt) -> float:
    """``max over outputs of Σ_j |Δc_j| · max|x_j|`` in output LSB; ``delta`` rows = outputs."""
    return float(np.max(np.abs(delta) @ x_max)) / out.lsb


def _run_kinetics(cfg: KineticsConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    x = cfg.in_fmt.to_float(inputs["frames"])
    fixed = kinetics_weighted_fixed(inputs["frames"], cfg)
    ref = reference.kinetics_weighted_amplitude(x, cfg.t_s, cfg.k_per_s)
    w = reference.kinetics_weights(np.array(cfg.t_s), cfg.k_per_s)
    c = w / np.dot(w, w)
    g_q = cfg.norm_value
    c_q = np.array(
        [
            float(Fraction(wq) * Fraction(2) ** -cfg.coef_fmt.frac_bits * g_q)
            for wq in cfg.weight_codes
        ]
    )
    x_max = np.abs(x).reshape(-1, len(cfg.t_s), x.shape[-1]).max(axis=(0, 2))
    terms = {
        "output_rounding": _rounding_term(cfg.registers(), cfg.rounding),
        "coefficients": _coef_term((c_q - c)[None, :], x_max, cfg.out_fmt),
    }
    return _Run(fixed, ref, terms)


def _run_fir(cfg: FirConfig, inputs: Mapping[str, np.ndarray]) -> _Run:
    x = cfg.in_fmt.to_float(inputs["frames"])
    fixed = fir_fixed(inputs["frames"], cfg)
    h = cfg.coefficients()
    ref = reference.fir_filter(x, h)
    h_q = cfg.coef_fmt.to_float(np.array(cfg.coef_codes))
    x_max = np.full(cfg.taps, _max_abs(x))
    terms = {
        "output_rounding": _rounding_term(cfg.registers(), cfg.rounding),
        "coefficients": _coef_term((h_q - h)[None, :], x_max, cfg.out_fmt),
    }
    return _Run(fixed, ref, terms)


def _run_wiener(eq: WienerEqualizer, inputs: Mapping[str, np.ndarray]) -> _Run:
    x = eq.cfg.in_fmt.to_float(inputs["frames"])
    fixed = wiener_equalize_fixed(inputs["frames"], eq)
    ref = reference.wiener_equalize(x, eq.g)
    x_max = np.abs(x).reshape(-1, eq.n_pixels).max(axis=0)
    delta = eq.coef_fmt.to_float(eq.coef_codes) - eq.g
    terms = {
        "output_rounding": _rounding_term(eq.registers(), eq.cfg.rounding),
        "coefficients": _coef_term(delta, x_max, eq.out_fmt),
    }
    return _Run(fixed, ref, terms)


_RUNNERS: dict[str, Callable[[Any, Mapping[str, np.ndarray]], _Run]] = {
    "background": _run_background,
    "cms": _run_cms,
    "accumulate": _run_accumulate,
    "average": _run_average,
    "binning": _run_binning,
    "kinetics": _run_kinetics,
    "fir": _run_fir,
    "wiener": _run_wiener,
}


def _registers(cfg: Any) -> dict[str, str]:
    return {name: fmt.describe() for name, fmt in cfg.registers().items()}


def _internal_overflow(fixed: FixedResult) -> list[str]:
    return [
        name
        for name, counts in fixed.overflow.items()
        if name != "output" and (counts["sat"] or counts["wrap"])
    ]


def _sqnr_db(ref: np.ndarray, err: np.ndarray) -> float | None:
    noise = float(np.sum(err * err))
    signal = float(np.sum(ref * ref))
    if noise == 0.0 or signal == 0.0:
        return None
    return 10.0 * math.log10(signal / noise)


def compare(case: Case) -> dict[str, Any]:
    """Error statistics of one routine on one data set (a JSON-able dict; see the module doc).

    Returns
    -------
    dict
        ``routine``, ``n_outputs``, ``out_fmt``, ``registers`` (name → format), ``max_abs_err_lsb``,
        ``max_abs_err_in_range_lsb``, ``mean_err_lsb`` (bias), ``sqnr_db`` (None when the fixed
        result is exact), ``exact``, ``n_clipped``, ``bound_lsb``, ``bound_terms``, ``bound_ok``
        (None when not applicable), ``bound_note``, ``overflow``, ``overflow_total``.
    """
    if case.routine not in _RUNNERS:
        raise ValueError(f"routine {case.routine!r}: known {', '.join(ROUTINES)}")
    run = _RUNNERS[case.routine](case.cfg, case.inputs)
    fixed, ref = run.fixed, np.asarray(run.ref, dtype=np.float64)
    lsb = fixed.fmt.lsb
    err = (fixed.values() - ref) / lsb
    # the range the output can reach: SAT_SYM never gives the most negative code
    lowest = fixed.fmt.min_value
    if getattr(case.cfg, "overflow", "") == "SAT_SYM" and fixed.fmt.signed:
        lowest = -fixed.fmt.max_value
    in_range = (ref >= float(lowest)) & (ref <= float(fixed.fmt.max_value))
    bound = float(sum(run.terms.values())) + SLACK_LSB
    max_in = float(np.max(np.abs(err[in_range]))) if in_range.any() else 0.0
    err_in = err[in_range]  # bias and SQNR over the same outputs as max_in (clipped ones apart)
    internal = _internal_overflow(fixed)
    return {
        "routine": case.routine,
        "n_outputs": int(err.size),
        "out_fmt": fixed.fmt.describe(),
        "registers": _registers(case.cfg),
        "max_abs_err_lsb": float(np.max(np.abs(err))) if err.size else 0.0,
        "max_abs_err_in_range_lsb": max_in,
        "mean_err_lsb": float(np.mean(err_in)) if err_in.size else 0.0,
        "sqnr_db": _sqnr_db(ref[in_range], err_in * lsb),
        "exact": bool(np.all(err == 0)),
        "n_clipped": int(err.size - np.count_nonzero(in_range)),
        "bound_lsb": bound,
        "bound_terms": {k: float(v) for k, v in run.terms.items()},
        "bound_ok": None if internal else bool(max_in <= bound),
        "bound_note": f"overflow before the output at {', '.join(internal)}" if internal else "",
        "overflow": fixed.overflow,
        "overflow_total": fixed.total(),
    }


def error_report(cases: Mapping[str, Case]) -> dict[str, Any]:
    """Error statistics of several cases: ``{"cases": {label: compare(case)}, "all_bounds_ok"}``.

    ``all_bounds_ok`` is False if any checked bound fails; cases whose bound is not applicable
    (internal overflow) do not count against it but are listed in ``not_checked``.
    """
    rows = {label: compare(case) for label, case in cases.items()}
    return {
        "cases": rows,
        "all_bounds_ok": all(r["bound_ok"] is not False for r in rows.values()),
        "not_checked": [label for label, r in rows.items() if r["bound_ok"] is None],
    }


def _fmt_num(v: float | None, digits: int = 3) -> str:
    return "exact" if v is None else f"{v:.{digits}f}"


def format_error_table(report: Mapping[str, Any]) -> str:
    """The report as a plain-text table, one line per case."""
    head = (
        f"{'case':<24} {'routine':<10} {'output':<10} {'max|err|':>9} {'bias':>8} "
        f"{'SQNR dB':>8} {'bound':>7} {'ok':>4} {'sat':>7} {'wrap':>7} {'clipped':>7}"
    )
    lines = [head, "-" * len(head)]
    for label, r in report["cases"].items():
        ok = {True: "yes", False: "NO", None: "n/a"}[r["bound_ok"]]
        sqnr = "inf" if r["sqnr_db"] is None else f"{r['sqnr_db']:.1f}"
        lines.append(
            f"{label:<24} {r['routine']:<10} {r['out_fmt'].split()[0]:<10} "
            f"{_fmt_num(r['max_abs_err_in_range_lsb']):>9} {r['mean_err_lsb']:>8.4f} {sqnr:>8} "
            f"{r['bound_lsb']:>7.3f} {ok:>4} {r['overflow_total']['sat']:>7} "
            f"{r['overflow_total']['wrap']:>7} {r['n_clipped']:>7}"
        )
    lines.append("errors in output LSB over outputs inside the output range; bound checked there")
    return "\n".join(lines)
