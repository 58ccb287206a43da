"""Cross-field rules of ``[chip]``: the converter and its range, the frame memory, the matched
filter, the DSP's register formats and its program (run by
:func:`chiptwin.config.consistency.check_consistency`)."""

from __future__ import annotations

import math

import numpy as np

from chiptwin.config.consistency_base import _fail
from chiptwin.config.schema import Scenario
from chiptwin.constants import Q_E

#: Narrowest ADC input range: below any ADC's (integrated ones span 0.1–5 V). Unit: V.
ADC_SPAN_MIN_V = 1e-3


#: The ``[chip.adc]`` keys of the converter as built, and the one a pixel-level ValueError names.
AS_BUILT_KEYS = ("comparator_noise_lsb", "inl_max_lsb", "inl_shape", "inl_table", "dnl_rms_lsb",
                 "offset_sigma_lsb", "gain_sigma", "ramp")


def _converter(s: Scenario) -> None:
    """The converter as built (``chiptwin.pixel.converter``) can be built: a table file that
    exists with 2^bits − 1 non-decreasing levels, a bow that keeps the transitions in order,
    tables that fit in memory; one comparator-noise key."""
    from pathlib import Path

    from chiptwin import pixel

    adc = s.chip.adc
    if adc.comparator_noise_lsb > 0 and adc.comparator_noise_uV > 0:
        _fail(s, "chip.adc.comparator_noise_uV", adc.comparator_noise_uV,
              f"give the comparator noise once: comparator_noise_lsb is "
              f"{adc.comparator_noise_lsb:g} already (set one of the two to 0)")
    if (adc.inl_shape == "table") != bool(adc.inl_table):
        key, value = (("chip.adc.inl_table", adc.inl_table) if adc.inl_table else
                      ("chip.adc.inl_shape", adc.inl_shape))
        _fail(s, key, value, 'a transition table needs inl_shape = "table" and an inl_table file')
    folder = Path(s.source).parent if Path(s.source).is_file() else Path.cwd()
    try:
        spec = pixel.AsBuilt.from_keys(adc, folder)
        if spec.ideal:
            return
        if spec.inl_shape != "table" and spec.dnl_rms_lsb == 0.0:
            # a smooth bow alone: its one check (no reversal) on the end points' span, not on
            # a table of 2^bits levels (1.4 s at 20 bits, every time a study is loaded)
            pixel.ramp.check_bow(spec.inl_max_lsb, spec.inl_shape, adc.bits)
            return
        # the shapes' checks (bow, memory) on one converter per ramp: no map is drawn here
        pixel.build_converter(np.random.default_rng(0), (s.chip.rows, s.chip.cols),
                              bits=adc.bits, v_min_V=adc.v_min_V, v_max_V=adc.v_max_V,
                              offset_lsb=adc.offset_error_lsb, gain_error=adc.gain_error,
                              as_built=spec)
    except (ValueError, OSError) as err:
        text = str(err)
        key = next((k for k in AS_BUILT_KEYS if text.startswith(k) or f" {k}" in text
                    or f"{k} " in text), "inl_table" if isinstance(err, OSError) else "ramp")
        _fail(s, f"chip.adc.{key}", getattr(adc, key), f"the converter cannot be built: {text}")


#: The range ``capacitance_fF`` has (schema_chip.Pixel), which a derived one keeps too. Unit: fF.
CAPACITANCE_RANGE_FF = (0.1, 1.0e7)


def _capacitance(s: Scenario) -> None:
    """A capacitance derived from the diode (``capacitance_fF`` not given) stays in the range a
    given one has; the refusal names the keys it was derived from."""
    px = s.chip.pixel
    lo, hi = CAPACITANCE_RANGE_FF
    if px.capacitance_fF == px.derived_capacitance_fF and not lo <= px.capacitance_fF <= hi:
        _fail(s, "chip.pixel.capacitance_fF", px.capacitance_fF,
              f"derived from the diode as junction_fF_per_um2 {px.junction_fF_per_um2:g} × "
              f"{px.diode_w_um:g} × {px.diode_h_um:g} µm + sidewall_fF_per_um "
              f"{px.sidewall_fF_per_um:g} × {2 * (px.diode_w_um + px.diode_h_um):g} µm + "
              f"readout_fF {px.readout_fF:g}, it must lie in [{lo:g}, {hi:g}] fF: change those "
              "keys or give chip.pixel.capacitance_fF")


def _adc_range(s: Scenario) -> None:
    adc, px = s.chip.adc, s.chip.pixel
    if adc.v_max_V < adc.v_min_V + ADC_SPAN_MIN_V:
        _fail(s, "chip.adc.v_max_V", adc.v_max_V,
              f"must be ≥ v_min_V + 1 mV = {adc.v_min_V + ADC_SPAN_MIN_V:g} V (no ADC has an "
              "input range below a millivolt)")
    if not adc.v_min_V <= px.pedestal_V < adc.v_max_V:
        _fail(s, "chip.pixel.pedestal_V", px.pedestal_V,
              f"must lie in the ADC range [{adc.v_min_V:g}, {adc.v_max_V:g}) V")
    # Codes the ADC gives at zero charge and at the full well, with its gain and offset errors.
    lsb = (adc.v_max_V - adc.v_min_V) / 2**adc.bits
    zero_code = (px.pedestal_V - adc.v_min_V) / lsb * (1 + adc.gain_error) + adc.offset_error_lsb
    full_well_V = px.full_well_e * Q_E / (px.capacitance_fF * 1e-15)
    full_code = zero_code + full_well_V / lsb * (1 + adc.gain_error)
    if zero_code < 0:
        _fail(s, "chip.adc.offset_error_lsb", adc.offset_error_lsb,
              f"puts the pedestal at code {zero_code:.1f}, below code 0: dark pixels would clip")
    if full_code > 2**adc.bits - 1 and not adc.range_below_full_well_ok:
        fits_e = math.floor((2**adc.bits - 1 - zero_code) / (1 + adc.gain_error) * lsb
                            * px.capacitance_fF * 1e-15 / Q_E)
        given = ("given" if px.capacitance_fF != px.derived_capacitance_fF else
                 "derived from the diode")
        _fail(s, "chip.adc.v_max_V", adc.v_max_V,
              f"is below the full well: pedestal + full_well_e·q/C = "
              f"{px.pedestal_V + full_well_V:.4g} V reaches code {full_code:.0f} > "
              f"{2**adc.bits - 1} (gain and offset errors included; C = "
              f"{px.capacitance_fF:.4g} fF, {given}); raise it, set chip.pixel.full_well_e ≤ "
              f"{fits_e}, or set chip.adc.range_below_full_well_ok = true if clipping is "
              "intended")
    if s.chip.memory.word_bits < adc.bits:
        _fail(s, "chip.memory.word_bits", s.chip.memory.word_bits,
              f"must hold an ADC code: ≥ chip.adc.bits = {adc.bits}")


def memory_needed_bits(s: Scenario) -> int:
    """The least ``chip.memory.capacity_bits`` the scenario's schedule runs on, in bits: the
    largest block of frames the DSP waits for plus what it holds (the dark reference; a
    program's stages). Validation refuses any smaller memory; a frame-memory study states this as
    its least memory, checked by a run at that size."""
    from chiptwin.dsp import program as prog

    need = _block_need(s)
    return need if prog.is_default(s.chip.dsp.program) else max(need, _program_need(s))


def _block_need(s: Scenario) -> int:
    c = s.chip
    block = max(c.dsp.n_dark_frames, c.dsp.average_frames)
    return block * c.frame_bits + c.memory.word_bits * c.n_pixels


def _program_need(s: Scenario) -> int:
    from chiptwin.dsp import program as prog

    load = prog.program_load(s.chip)
    return max(s.chip.dsp.n_dark_frames, load.frames_per_job) * s.chip.frame_bits + \
        load.resident_bits


def _memory(s: Scenario) -> None:
    """The DSP reads blocks of frames from memory: the dark block, then blocks of N."""
    c = s.chip
    block = max(c.dsp.n_dark_frames, c.dsp.average_frames)
    dark_ref_bits = c.memory.word_bits * c.n_pixels
    needed = _block_need(s)
    if c.memory.capacity_bits < needed:
        _fail(s, "chip.memory.capacity_bits", c.memory.capacity_bits,
              f"must be ≥ {needed} bits: a block of {block} frames × {c.frame_bits} bits "
              f"(word × pixels × {c.samples_per_frame} samples) + the dark reference "
              f"{dark_ref_bits} bits")


#: Fastest decay the matched filter is given, per output block (e-folds in N frame periods).
MATCHED_EFOLDS_PER_BLOCK_MAX = 50.0


def _matched_filter(s: Scenario) -> None:
    """The matched filter weights each output block by exp(−k·t) at its middle: light that decays
    by more than e^50 within one block leaves it nothing to weight (the weights underflow and the
    window total comes out 0 ± 0)."""
    keys = {"pyrosequencing": "k_a_per_s", "atp": "turnover_per_s"}
    if s.run.light_estimator != "matched" or s.assay.kind not in keys:
        return
    key = keys[s.assay.kind]
    k = getattr(s.assay, key)
    block_s = s.chip.dsp.average_frames * s.chip.timing.frame_period_s
    if k * block_s > MATCHED_EFOLDS_PER_BLOCK_MAX:
        _fail(s, f"assay.{key}", k,
              f"decays by e^{k * block_s:.3g} within one output block ({block_s:g} s) with "
              f"run.light_estimator = \"matched\": the filter needs light that lasts; it must "
              f"be ≤ {MATCHED_EFOLDS_PER_BLOCK_MAX / block_s:.3g} 1/s, or the estimator \"sum\"")


def _dsp_formats(s: Scenario) -> None:
    """Every register the run derives from ``[chip.dsp]`` fits the DSP's 64 bits.

    The chain's formats (ADC bits, M, K, N, ``acc_bits``) are derived at the fixed and RTL levels
    (and wherever the level may become one, ``auto``); a program beyond today's chain derives
    its stages' formats at every level (the schedule counts their memory). A count whose
    registers would be wider is refused here by its own key, before anything derives them.
    """
    from chiptwin.dsp import program as prog
    from chiptwin.dsp.chain import FormatLimit
    from chiptwin.dsp.pipeline import chain_for

    program = s.chip.dsp.program
    if prog.order_problem(program) is not None:
        return  # _dsp_program refuses the list itself
    if s.dsp_level == "float" and prog.is_default(program):
        return
    try:
        chain_for(s.chip)
        if not prog.is_default(program):
            prog.program_formats(s.chip)
    except FormatLimit as err:
        key = "chip.adc.bits" if err.key == "adc_bits" else f"chip.dsp.{err.key}"
        _fail(s, key, err.value, err.allowed)


def _dsp_program(s: Scenario) -> None:
    """``[chip.dsp] program``: known stages in their order, each stage's needs (assay, optics,
    level, geometry, register widths), and the frame memory the program holds."""
    from chiptwin.dsp import program as prog

    c, key = s.chip, "chip.dsp.program"
    program = c.dsp.program
    bad = prog.order_problem(program)
    if bad is not None:
        _fail(s, key, bad[0], bad[1])
    if prog.is_default(program):
        return
    if "kinetics" in program and s.assay.kind not in prog.DECAY_KEYS:
        _fail(s, key, "kinetics",
              f"stage 'kinetics' weights frames by the assay's decay exp(-k t); assay kind "
              f"{s.assay.kind!r} has no decay law (kinds with one: "
              f"{', '.join(prog.DECAY_KEYS)})")
    if "wiener" in program:
        _program_wiener(s)
    if s.dsp_level == "rtl":
        for stage in program:
            if stage not in prog.RTL_STAGES:
                _fail(s, key, stage,
                      f"stage {stage!r} has no RTL block (rtl_ref has "
                      f"{', '.join(x for x in prog.STAGES if x in prog.RTL_STAGES)}); run it "
                      "at chip.dsp.mode = \"fixed\"")
    _program_formats(s)
    _program_memory(s)


def _program_wiener(s: Scenario) -> None:
    from chiptwin.dsp import program as prog

    o = s.optics
    if s.assay.kind == "flux" or o.coupling != "contact" or s.run.fidelity.optics not in (
            "psf", "raytrace", "auto"):
        _fail(s, "chip.dsp.program", "wiener",
              "stage 'wiener' equalizes the optics' coupling matrix (the PSF of contact "
              "imaging): it needs optics.coupling = \"contact\", run.fidelity.optics = \"psf\" "
              f"and an assay (not light given at the sensor); here coupling {o.coupling!r}, "
              f"optics {s.run.fidelity.optics!r}, assay {s.assay.kind!r}")
    n = prog.grid_shape(s.chip)
    if n[0] * n[1] > prog.WIENER_MAX_GRID:
        _fail(s, "chip.dsp.program", "wiener",
              f"stage 'wiener' holds an n × n coefficient table for its {n[0]} × {n[1]} input "
              f"grid: n must be ≤ {prog.WIENER_MAX_GRID} (bin the rows first, or a smaller "
              "array)")


def _program_formats(s: Scenario) -> None:
    """Register widths each stage derives must exist (≤ 64 bits, products that fit)."""
    from chiptwin.chip.des import Schedule
    from chiptwin.dsp import program as prog

    try:
        prog.program_formats(s.chip)
        if "kinetics" in s.chip.dsp.program:
            from chiptwin.config.budget import window_edges
            from chiptwin.dsp.program_pipeline import kinetics_plan

            kinetics_plan(s.chip, Schedule.from_chip(s.chip, s.run.duration_s), window_edges(s),
                          getattr(s.assay, prog.DECAY_KEYS[s.assay.kind]))
    except (ValueError, IndexError) as err:
        stage = "kinetics" if "kinetics" in str(err).lower() else "the program"
        _fail(s, "chip.dsp.program", s.chip.dsp.program,
              f"{stage}: its registers cannot be built: {err}")


def _program_memory(s: Scenario) -> None:
    """What the program holds, plus the largest block of frames the DSP waits for."""
    from chiptwin.dsp import program as prog

    c = s.chip
    costs = prog.stage_costs(c)
    load = prog.program_load(c)
    block = max(c.dsp.n_dark_frames, load.frames_per_job)
    needed = _program_need(s)
    if c.memory.capacity_bits < needed:
        held = ", ".join(f"{k} {v.memory_bits}" for k, v in costs.items() if v.memory_bits)
        _fail(s, "chip.memory.capacity_bits", c.memory.capacity_bits,
              f"must be ≥ {needed} bits for the DSP program {c.dsp.program}: a block of {block} "
              f"frames × {c.frame_bits} bits + what its stages hold ({held} bits)")
