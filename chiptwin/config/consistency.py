"""Cross-field rules: values that are each in range but cannot work together.

Each rule raises :class:`ScenarioError` naming the key a user would change. The last ones
(:func:`chiptwin.config.budget.check_budget`) refuse a run too large to work: its memory, the
counts its samplers would be handed, the chip model's time span.

The rules live by the section they check: :mod:`~chiptwin.config.consistency_assay`,
:mod:`~chiptwin.config.consistency_optics`, :mod:`~chiptwin.config.consistency_chip`; here
the order they run in, the run's own rules (name, fidelity, timing, duration) and the warnings.
"""

from __future__ import annotations

import math
import re

from chiptwin.config.consistency_assay import (
    CALLER_MAX_HOMOPOLYMER,
    _assay,
    _cascade,
    _site_amounts,
    _sites,
)
from chiptwin.config.consistency_base import _fail
from chiptwin.config.consistency_chip import (
    _adc_range,
    _capacitance,
    _converter,
    _dsp_formats,
    _dsp_program,
    _matched_filter,
    _memory,
)
from chiptwin.config.consistency_optics import _optics
from chiptwin.config.cost import check_wall_time
from chiptwin.config.schema import CLOCK_MAX_HZ, Scenario
from chiptwin.config.tiling import check_budget_simulated, check_tile
from chiptwin.constants import s_to_ticks
from chiptwin.dsp.fixed import accumulator_bits_needed

#: Fidelity levels that exist. Others are refused at validation time, not half-run.
BUILT_LEVELS: dict[str, tuple[str, ...]] = {
    "kinetics": ("closed_form", "cascade"),
    "photons": ("expected", "binned", "events"),
    "optics": ("na2", "psf", "raytrace"),
    "shot": ("poisson", "gaussian"),
    "dsp": ("float", "fixed", "rtl"),
    "adc": ("ideal", "as_built"),
}


def check_consistency(s: Scenario) -> None:
    """Run every cross-field rule on a built scenario."""
    # _dsp_formats, then _dsp_program, before _timing: the schedule is derived from the
    # program's stages, and their costs from the register formats
    for rule in (_name, _fidelity, _assay, _cascade, _sites, _optics, _dsp_formats, _dsp_program,
                 _timing, _capacitance, _adc_range, _converter, _memory, _duration,
                 _matched_filter, check_budget_simulated,
                 _site_amounts, check_tile, check_wall_time):
        rule(s)


def _name(s: Scenario) -> None:
    """The name becomes the default output folder ``out/<name>``: one plain path component."""
    name = s.scenario.name
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,255}", name) or name in (".", ".."):
        _fail(s, "scenario.name", name,
              "must be 1 to 255 letters, digits, '_', '-', '.' (a folder name)")


def _fidelity(s: Scenario) -> None:
    levels = {**{f: getattr(s.run.fidelity, f) for f in BUILT_LEVELS}, "dsp": s.dsp_level}
    auto = s.run.fidelity.auto_stages()
    if auto and not s.run.error_budget.items():
        _fail(s, f"run.fidelity.{auto[0]}", "auto",
              "needs [run] error_budget, the error it may spend (e.g. { snr_rel = 0.01 })")
    for stage, level in levels.items():
        if level == "auto":
            continue  # resolved before the run (chiptwin.fidelity.auto), then checked again
        if level not in BUILT_LEVELS[stage]:
            key = "chip.dsp.mode" if stage == "dsp" and not s.run.fidelity.dsp else (
                f"run.fidelity.{stage}")
            _fail(s, key, level, f"level not built yet; built: {', '.join(BUILT_LEVELS[stage])}")
    if s.run.fidelity.kinetics == "cascade" and s.assay.kind != "pyrosequencing":
        _fail(s, "run.fidelity.kinetics", "cascade",
              f"the cascade models pyrosequencing; assay kind {s.assay.kind!r} has closed_form")
    if s.dsp_level in ("fixed", "rtl") and s.run.fidelity.photons == "expected":
        _fail(s, "run.fidelity.photons", "expected",
              f"carries no ADC codes for the {s.dsp_level} DSP to compute on; use binned")
    if s.dsp_level == "rtl":
        from chiptwin.config.rtl_path import make_importable

        make_importable()
        from rtl_ref.tools import INSTALL_HINT, missing

        if "verilator" in missing():
            key = "run.fidelity.dsp" if s.run.fidelity.dsp else "chip.dsp.mode"
            _fail(s, key, "rtl", f"simulates the DSP's Verilog with Verilator: {INSTALL_HINT}")
    if s.run.fidelity.dsp not in ("", "auto") and s.run.fidelity.dsp != s.chip.dsp.mode != "float":
        _fail(s, "run.fidelity.dsp", s.run.fidelity.dsp,
              f"contradicts chip.dsp.mode = {s.chip.dsp.mode!r}; set one of them")


def _timing(s: Scenario) -> None:
    """Checked in the chip model's own nanosecond ticks, as it will run; said in seconds, the
    unit of the keys (the smallest period rounded up, so that it fits)."""
    from chiptwin.chip.des import Schedule

    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    if sch.busy_ns > sch.frame_period_ns:
        smallest = _round_up(sch.busy_ns * 1e-9, digits=5)
        _fail(s, "chip.timing.frame_period_s", s.chip.timing.frame_period_s,
              f"is below the smallest allowed, {smallest:.5g} s: reset "
              f"{sch.t_reset_ns * 1e-9:.4g} s + integration (t_int_s) {sch.t_int_ns * 1e-9:.4g} s "
              f"+ {s.chip.samples_per_frame} conversions of {sch.t_conv_ns * 1e-9:.4g} s; "
              f"{_schedule_fix(s, sch)}")


def _schedule_fix(s: Scenario, sch) -> str:
    """The one key that makes a frame schedule fit, with the value that does: the smallest ADC
    clock (3 significant digits, rounded up) when the conversions are what overruns, else the
    longest integration."""
    adc, n = s.chip.adc, s.chip.samples_per_frame
    spare_ns = sch.frame_period_ns - sch.t_reset_ns - sch.t_int_ns  # left for the conversions
    cycles = adc.cycles_per_conversion or 2**adc.bits
    if spare_ns >= n:
        clock = _round_up(cycles * 1e9 / (spare_ns // n))
        while s_to_ticks(cycles / clock) * n > spare_ns:  # the tick rounding may need a bit more
            clock = _round_up(clock * 1.001)
        if clock <= CLOCK_MAX_HZ:
            return (f"set chip.adc.clock_hz ≥ {_hz(clock)} (now {_hz(adc.clock_hz, short=True)}, "
                    f"{cycles} cycles a conversion), or chip.timing.frame_period_s ≥ "
                    f"{_round_up(sch.busy_ns * 1e-9, digits=5):.5g}")
    t_int_ns = sch.frame_period_ns - sch.t_reset_ns - n * sch.t_conv_ns
    if t_int_ns > 0:
        digits = 10 ** (int(math.floor(math.log10(t_int_ns))) - 3)  # 4 digits, rounded down
        return (f"set chip.timing.t_int_s ≤ {t_int_ns // digits * digits * 1e-9:.4g} s (now "
                f"{s.chip.timing.t_int_s:g} s), or chip.timing.frame_period_s ≥ "
                f"{_round_up(sch.busy_ns * 1e-9, digits=5):.5g}")
    return (f"set chip.timing.frame_period_s ≥ {_round_up(sch.busy_ns * 1e-9, digits=5):.5g}, "
            "or shorten chip.timing.t_int_s")


def _hz(f: float, short: bool = False) -> str:
    """A clock as a TOML value and in words: 26300000.0 → "26.3e6 (26.3 MHz)"; ``short``:
    "26.3 MHz"."""
    for exp, unit in ((9, "GHz"), (6, "MHz"), (3, "kHz")):
        if f >= 10.0**exp:
            v = f"{round(f / 10.0**exp, 6):g}"
            return f"{v} {unit}" if short else f"{v}e{exp} ({v} {unit})"
    return f"{f:g} Hz"


def _round_up(x: float, digits: int = 3) -> float:
    """Up to ``digits`` significant digits: 41,020 → 41,100 (3); 1.5032868 → 1.5033 (5)."""
    scale = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return float(f"{math.ceil(x / scale - 1e-9) * scale:.{digits}g}")


def _duration(s: Scenario) -> None:
    """Dark frames first; then blocks of N frames that start with the light and, for
    pyrosequencing, never straddle two flows (checked in integer ticks, as the chip runs)."""
    c, a = s.chip, s.assay
    period = s_to_ticks(c.timing.frame_period_s)
    dark_ticks = c.dsp.n_dark_frames * period
    block = c.dsp.average_frames * period
    if s_to_ticks(a.start_s) < dark_ticks:
        _fail(s, "assay.start_s", a.start_s,
              f"must be ≥ {dark_ticks / 1e9:g} s: the {c.dsp.n_dark_frames} dark frames come "
              "before light")
    if (s_to_ticks(a.start_s) - dark_ticks) % block:
        _fail(s, "assay.start_s", a.start_s,
              f"must be the end of the dark frames ({dark_ticks / 1e9:g} s) plus a whole number "
              f"of {c.dsp.average_frames}-frame blocks ({block / 1e9:g} s each), so that no "
              "averaged block mixes dark and light: "
              + _nearest(s_to_ticks(a.start_s), block, dark_ticks))
    need = a.start_s + c.dsp.average_frames * c.timing.frame_period_s
    if a.kind == "pyrosequencing":
        need = a.start_s + a.n_flows * a.flow_period_s
        if s_to_ticks(a.flow_period_s) % block:
            _fail(s, "assay.flow_period_s", a.flow_period_s,
                  f"must be a whole number of {c.dsp.average_frames}-frame blocks "
                  f"({block / 1e9:g} s each), so that averaged frames do not straddle flows: "
                  f"{_nearest(s_to_ticks(a.flow_period_s), block, block)}")
    if s.run.duration_s < need:
        _fail(s, "run.duration_s", s.run.duration_s, f"must be ≥ {need:g} s for this assay")


def _nearest(ticks: int, step: int, first: int) -> str:
    """The allowed values either side of ``ticks`` on the grid ``first + k · step`` (k ≥ 0), in
    seconds: "the nearest allowed are 20 s and 24 s"."""
    below = first + (ticks - first) // step * step
    values = [first] if ticks < first else [below, below + step]
    return "the nearest allowed " + ("are " if len(values) > 1 else "is ") + " and ".join(
        f"{v / 1e9:g} s" for v in values)


def scenario_warnings(s: Scenario) -> list[str]:
    """Choices that run but that a chip architect should see: printed by ``validate``, kept in
    ``summary['warnings']``."""
    from chiptwin.dsp.pipeline import chain_for

    warnings = []
    d = s.chip.dsp
    if d.acc_bits and s.dsp_level != "float":
        in_fmt = chain_for(s.chip).average.in_fmt
        needed = accumulator_bits_needed(in_fmt, d.average_frames)
        if d.acc_bits < needed:
            warnings.append(
                f"{s.source}: chip.dsp.acc_bits = {d.acc_bits} is too narrow for "
                f"average_frames = {d.average_frames} frames of {in_fmt.q}: {needed} bits never "
                f"overflow; expect {d.acc_overflow} events (counted in summary['dsp'])")
    return warnings


__all__ = ["BUILT_LEVELS", "CALLER_MAX_HOMOPOLYMER", "check_consistency", "scenario_warnings"]
