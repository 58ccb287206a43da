"""The on-chip DSP as a program: ``[chip.dsp] program``, an ordered list of stages.

::

    cms ─► dark ─► background ─► average ──┬─► bin_rows ─► fir8 ─► wiener
                                 kinetics ─┘   (each optional, in this order)

The front end (``cms``, ``dark``, ``background``, then ``average`` or ``kinetics``) works on the
frames in time; the optional spatial stages work on each output frame. Every stage declares what
it holds in frame memory (words × width, bits) and its DSP cycles per pixel (:func:`stage_costs`),
from the chip's numbers alone, so the chip model's schedule (:class:`chiptwin.chip.Schedule`)
counts them: memory occupancy and ``dsp_utilization`` follow the program.

Costs (choices, documented here once):

============ =================================== ================================================
stage        held in frame memory                cycles per pixel
============ =================================== ================================================
cms          —                                   2M × ``cycles_per_sample`` per frame: one pass
                                                 over the stored words, dark / background /
                                                 average fused into it (today's chain)
dark         dark reference: P × ``word_bits``   0 (in the cms pass)
background   —                                   0 (in the cms pass)
average      — (reads its N frames in memory)    0 (in the cms pass)
kinetics     accumulator: P × ``kinetics_acc_bits`` 1 per frame (a MAC; each frame is freed once
                                                 added) + 1 per output (× the normalisation)
bin_rows     line accumulator: cols × out width  1 per input pixel per output (an add)
fir8         delay line: 8 × in width            8 per pixel per output (8 MACs)
wiener       input frame: n × in width, and the  n per pixel per output (a row of the n × n
             n × n coefficient table × coef bits matrix); n = pixels of its input grid
============ =================================== ================================================

The spatial stages are linear: each output frame is ``L @ x`` with ``L`` = W·F·B (Wiener, FIR,
binning), so the noise propagates as the covariance ``L diag(var) Lᵀ`` (they correlate
neighbours), not only its diagonal (:meth:`Program.covariance`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import Any

from chiptwin.dsp.chain import MAX_REGISTER_BITS, ChainConfig, FormatLimit
from chiptwin.dsp.filters import FirConfig
from chiptwin.dsp.fmt import Fmt, mul_fmt, sum_fmt
from chiptwin.dsp.frame_ops import BinningConfig

#: A ``[chip]`` section (:class:`chiptwin.config.schema.Chip`; its ``dsp``, a
#: :class:`~chiptwin.config.schema.Dsp`). The stage
#: packages sit below the scenario files (``docs/architecture.md``): they read its fields by
#: name and import nothing from ``config``.
Chip = Dsp = Any

#: Every stage a program may name, in the only order they may come.
STAGES = ("cms", "dark", "background", "average", "kinetics", "bin_rows", "fir8", "wiener")
DEFAULT_PROGRAM = ("cms", "dark", "background", "average")
FRONT = ("cms", "dark", "background")
REDUCERS = ("average", "kinetics")
SPATIAL = ("bin_rows", "fir8", "wiener")
#: Stages with an RTL block in ``rtl_ref`` (``ct_cms``, ``ct_average``, ``ct_background``,
#: ``ct_chain``, ``ct_kinetics``, ``ct_fir``); binning and the Wiener equalizer have none.
RTL_STAGES = frozenset({"cms", "dark", "background", "average", "kinetics", "fir8"})
#: Assays whose light decays as exp(−k t), and the key of k: the kinetics stage's weights.
DECAY_KEYS = {"pyrosequencing": "k_a_per_s", "atp": "turnover_per_s"}
FIR_TAPS = 8
#: Weights of the kinetics stage: unsigned Q1.15 (w = exp(−k t) ∈ (0, 1]).
KINETICS_COEF = Fmt(False, 16, 15)
KINETICS_NORM_BITS = 18
#: Largest input grid of the wiener stage: its n × n coefficient table (1e6 words) is larger
#: than any frame memory on such a chip.
WIENER_MAX_GRID = 1024


def is_default(program: list[str] | tuple[str, ...]) -> bool:
    """Whether a program is today's chain (CMS → dark → background → average)."""
    return tuple(program) == DEFAULT_PROGRAM


def order_problem(program: list) -> tuple[object, str] | None:
    """The first thing wrong with a program's stage list, as ``(stage, what is allowed)``.

    Only the list itself is checked here; the scenario's rules (assay, optics, level, memory)
    are in :mod:`chiptwin.config.consistency`.
    """
    for stage in program:
        if not isinstance(stage, str) or stage not in STAGES:
            return stage, f"unknown DSP stage; stages: {', '.join(STAGES)}"
    seen = set()
    for stage in program:
        if stage in seen:
            return stage, f"stage {stage!r} appears twice; each stage runs at most once"
        seen.add(stage)
    if tuple(program[:3]) != FRONT:
        for i, stage in enumerate(FRONT):
            if len(program) <= i or program[i] != stage:
                need = {"cms": "first: every later stage works on CMS differences",
                        "dark": "after cms: background needs the dark reference it subtracts",
                        "background": "after dark: average and kinetics work on "
                                      "dark-subtracted frames"}[stage]
                got = program[i] if len(program) > i else "(end of program)"
                return got, f"stage {stage!r} must come {need}; the program must begin " \
                            "cms, dark, background"
    rest = list(program[3:])
    if not rest or rest[0] not in REDUCERS:
        got = rest[0] if rest else "(end of program)"
        return got, ("after background comes average or kinetics (one of them): they reduce "
                     "the frames to the outputs every later stage works on")
    if any(r in rest[1:] for r in REDUCERS):
        stage = next(r for r in rest[1:] if r in REDUCERS)
        return stage, "average and kinetics both reduce frames to an output: use one of them"
    spatial = rest[1:]
    if spatial != sorted(spatial, key=SPATIAL.index):
        bad = next(a for a, b in zip(spatial, sorted(spatial, key=SPATIAL.index), strict=True)
                   if a != b)
        return bad, ("spatial stages come in the order bin_rows, fir8, wiener: the equalizer "
                     "inverts the response of everything before it")
    return None


# ---------------------------------------------------------------------------------------------
# formats and costs, from the chip alone
# ---------------------------------------------------------------------------------------------


def bin_factor(chip: Chip) -> int:
    """Rows summed by ``bin_rows`` (``[chip.dsp] bin_factor``; 0 = every row)."""
    return chip.dsp.bin_factor or chip.rows


@dataclass(frozen=True)
class ProgramFormats:
    """Register formats of a program's stages, each fed the one before (fixed-point word growth,
    sources.md F4).

    ``front`` is the chain of cms / dark / background / average (``average.n = 1`` with
    kinetics, so its output is the background-subtracted frame). ``kinetics_out`` is declared,
    not derived from the weights: ``Â = g Σ w y`` with ``g Σ w = Σw / Σw² ≤ 2`` for a decay, so
    one integer bit above the input holds it.
    """

    front: ChainConfig
    kinetics_acc: Fmt | None
    kinetics_out: Fmt | None
    binning: BinningConfig | None
    fir: FirConfig | None
    wiener_in: Fmt | None

    @property
    def front_out(self) -> Fmt:
        """What the average or kinetics stage hands on."""
        return self.kinetics_out or self.front.average.out_fmt


def program_formats(chip: Chip) -> ProgramFormats:
    """Formats of ``chip.dsp.program``'s stages.

    Raises :class:`~chiptwin.dsp.chain.FormatLimit` (a ValueError) naming the ``[chip.dsp]``
    key whose registers would be wider than 64 bits. Derived once per chip: validation, the
    schedule, the stage costs and the run each ask for them (the FIR's taps are a firwin design).
    """
    return _program_formats(replace(chip, dsp=replace(chip.dsp, program=tuple(chip.dsp.program))))


@functools.lru_cache(maxsize=32)
def _program_formats(chip: Chip) -> ProgramFormats:
    from chiptwin.dsp.pipeline import chain_for

    d, program = chip.dsp, chip.dsp.program
    kinetics = "kinetics" in program
    front = chain_for(replace(chip, dsp=replace(d, average_frames=1, acc_bits=0))) if kinetics \
        else chain_for(chip)
    k_acc = k_out = None
    if kinetics:
        k_acc, k_out = _kinetics_formats(front.average.out_fmt, d.kinetics_acc_bits)
    fmt = k_out or front.average.out_fmt
    binning = fir = None
    if "bin_rows" in program:
        binning = _binning(chip, fmt)
        fmt = binning.out_fmt
    if "fir8" in program:
        fir = _fir(d, fmt)
        fmt = fir.out_fmt
    if "wiener" in program:
        _check_wiener(chip, fmt)
    return ProgramFormats(front, k_acc, k_out, binning, fir,
                          fmt if "wiener" in program else None)


def _kinetics_formats(x: Fmt, acc_bits: int) -> tuple[Fmt, Fmt]:
    """The kinetics accumulator (``kinetics_acc_bits``) and output for frames of ``x``."""
    product_bits = x.word_bits + KINETICS_COEF.word_bits
    if product_bits > MAX_REGISTER_BITS:
        raise FormatLimit(
            "program", "kinetics",
            f"stage 'kinetics' multiplies frames of {x.q} ({x.word_bits} bits: chip.adc.bits, "
            f"cms_samples and n_dark_frames set it) by {KINETICS_COEF.word_bits}-bit weights, a "
            f"{product_bits}-bit product: the DSP's multiplier is at most {MAX_REGISTER_BITS} bits")
    product = mul_fmt(x, KINETICS_COEF)
    if acc_bits < product.word_bits:
        raise FormatLimit(
            "kinetics_acc_bits", acc_bits,
            f"cannot hold one {product.word_bits}-bit product of a frame ({x.q}) and a weight: "
            f"must be ≥ {product.word_bits}")
    return Fmt(True, acc_bits, product.frac_bits), Fmt(True, x.word_bits + 1, x.frac_bits)


def _binning(chip: Chip, fmt: Fmt) -> BinningConfig:
    d, factor = chip.dsp, bin_factor(chip)
    if chip.rows % factor:
        raise FormatLimit("bin_factor", d.bin_factor,
                          f"stage 'bin_rows' sums bin_factor rows: must divide chip.rows = "
                          f"{chip.rows}")
    grow = (factor - 1).bit_length()
    if fmt.word_bits + grow > MAX_REGISTER_BITS:
        raise FormatLimit(
            "bin_factor", d.bin_factor,
            f"stage 'bin_rows' sums {factor} rows of {fmt.q} ({fmt.word_bits} bits), "
            f"{fmt.word_bits + grow} bits, more than the DSP's {MAX_REGISTER_BITS}: at most "
            f"{2 ** (MAX_REGISTER_BITS - fmt.word_bits)} rows fit")
    return BinningConfig(rows=chip.rows, cols=chip.cols, factor=factor, in_fmt=fmt,
                         rounding=d.rounding, overflow=d.overflow)


def _fir(d: Dsp, fmt: Fmt) -> FirConfig:
    coef = Fmt(True, 16, 15)
    need = fmt.word_bits + coef.word_bits + (FIR_TAPS - 1).bit_length()
    if need > MAX_REGISTER_BITS:
        raise FormatLimit(
            "program", "fir8",
            f"stage 'fir8' sums {FIR_TAPS} products of its {fmt.word_bits}-bit input ({fmt.q}) "
            f"and {coef.word_bits}-bit taps: a {need}-bit accumulator, more than the DSP's "
            f"{MAX_REGISTER_BITS} bits")
    product = mul_fmt(fmt, coef)
    return FirConfig(taps=FIR_TAPS, cutoff=d.fir_cutoff, in_fmt=fmt,
                     acc_fmt=sum_fmt(product, FIR_TAPS), out_fmt=fmt, rounding=d.rounding,
                     overflow=d.overflow)


def _check_wiener(chip: Chip, fmt: Fmt) -> None:
    """The equalizer's accumulator (input × coefficient, summed over its n inputs) fits."""
    n = math.prod(grid_shape(chip))
    grow = (n - 1).bit_length()
    coef_bits = chip.dsp.wiener_coef_bits
    if fmt.word_bits + coef_bits + grow <= MAX_REGISTER_BITS:
        return
    top = MAX_REGISTER_BITS - fmt.word_bits - grow
    fix = f"must be ≤ {top}" if top >= 4 else (
        "no coefficient width fits (bin the rows first, or fewer bits upstream)")
    raise FormatLimit(
        "wiener_coef_bits", coef_bits,
        f"stage 'wiener' sums {n} products of its {fmt.word_bits}-bit input ({fmt.q}) and the "
        f"coefficients: {fmt.word_bits} + {coef_bits} + {grow} bits is more than the DSP's "
        f"{MAX_REGISTER_BITS}; {fix}")


def grid_shape(chip: Chip) -> tuple[int, int]:
    """Rows and columns of the spatial stages' frames (after ``bin_rows``, if any)."""
    rows = chip.rows // bin_factor(chip) if "bin_rows" in chip.dsp.program else chip.rows
    return rows, chip.cols


@dataclass(frozen=True)
class StageCost:
    """What one stage costs the chip.

    Attributes
    ----------
    memory_bits : int
        Held in frame memory for the whole run: words × width. Unit: bit.
    words, width_bits : int
        The same as a count of words of one width (a table's words may be wider than the
        memory's; the bits are what the capacity counts).
    cycles_per_pixel_frame, cycles_per_pixel_output : float
        DSP cycles per input pixel, per frame read and per output made.
    """

    memory_bits: int
    words: int
    width_bits: int
    cycles_per_pixel_frame: float
    cycles_per_pixel_output: float
    #: the memory as words × width, e.g. ``"64 × 24 bit + 4096 × 18 bit"``
    layout: str = ""


def stage_costs(chip: Chip) -> dict[str, StageCost]:
    """Every stage of ``chip.dsp.program`` with its memory and cycles (module docstring table)."""
    d, p = chip.dsp, chip.n_pixels
    # register widths only where a stage holds them: today's chain needs none (and a float-level
    # chip whose fixed-point chain would exceed 64 bits must still get its schedule)
    fmts = program_formats(chip) if set(d.program) & set(SPATIAL) else None
    n_grid = math.prod(grid_shape(chip))
    costs = {}
    for stage in d.program:
        words, width, per_frame, per_out = 0, 0, 0.0, 0.0
        if stage == "cms":
            per_frame = chip.samples_per_frame * d.cycles_per_sample
        elif stage == "dark":
            words, width = p, chip.memory.word_bits
        elif stage == "kinetics":
            words, width, per_frame, per_out = p, d.kinetics_acc_bits, 1.0, 1.0
        elif stage == "bin_rows":
            words, width, per_out = chip.cols, fmts.binning.out_fmt.word_bits, 1.0
        elif stage == "fir8":
            words, width, per_out = FIR_TAPS, fmts.fir.in_fmt.word_bits, float(FIR_TAPS)
        elif stage == "wiener":
            words = n_grid + n_grid * n_grid
            width = max(fmts.wiener_in.word_bits, d.wiener_coef_bits)
            per_out = float(n_grid)
            costs[stage] = StageCost(
                n_grid * fmts.wiener_in.word_bits + n_grid * n_grid * d.wiener_coef_bits, words,
                width, per_frame, per_out,
                f"{n_grid} × {fmts.wiener_in.word_bits} bit + {n_grid * n_grid} × "
                f"{d.wiener_coef_bits} bit")
            continue
        costs[stage] = StageCost(words * width, words, width, per_frame, per_out,
                                 f"{words} × {width} bit" if words else "")
    return costs


def input_pixels(chip: Chip) -> dict[str, int]:
    """Pixels each stage reads per frame or output (the spatial stages after binning read the
    binned grid)."""
    n_grid = math.prod(grid_shape(chip))
    return {s: (n_grid if s in ("fir8", "wiener") else chip.n_pixels) for s in STAGES}


@dataclass(frozen=True)
class ProgramLoad:
    """The program's totals, for the chip model's schedule.

    ``resident_bits`` stays in frame memory all run (the dark reference included, as before);
    ``cycles_per_frame`` the DSP spends on each frame it reads; ``cycles_per_output`` on each
    output (the stages after average / kinetics); ``frames_per_job`` frames the DSP takes at
    once after the dark block (N with average; 1 with kinetics, which frees each frame as soon
    as it is added).
    """

    resident_bits: int
    cycles_per_frame: float
    cycles_per_output: float
    frames_per_job: int


def program_load(chip: Chip) -> ProgramLoad:
    """Totals of :func:`stage_costs` over the program."""
    costs, pixels = stage_costs(chip), input_pixels(chip)
    # cms first: its term is today's words × cycles_per_sample, bit for bit
    per_frame = chip.n_pixels * chip.samples_per_frame * chip.dsp.cycles_per_sample
    per_frame += sum(c.cycles_per_pixel_frame * pixels[s] for s, c in costs.items()
                     if s != "cms")
    per_out = sum(c.cycles_per_pixel_output * pixels[s] for s, c in costs.items())
    return ProgramLoad(
        resident_bits=sum(c.memory_bits for c in costs.values()),
        cycles_per_frame=per_frame,
        cycles_per_output=per_out,
        frames_per_job=1 if "kinetics" in chip.dsp.program else chip.dsp.average_frames,
    )
