"""The chip model's DSP running a program: the front end (:class:`~chiptwin.dsp.pipeline.Pipeline`,
or its RTL twin) followed by the kinetics and spatial stages of :mod:`chiptwin.dsp.program`.

Every output carries its expected value and its independent variance beside the value the DSP
level computed, as the front end's do. The kinetics stage is a linear combination of a window's
frames; the spatial stages are a matrix ``L`` (n_grid × n_pixels) on each output frame, so the
variance propagates as ``(L ∘ L) @ var`` and the covariance as ``L diag(var) Lᵀ``
(:meth:`ProgramPipeline.covariance`). Outputs are read back at every pixel of the array (pixel
``p`` reads the grid cell it lies in), so detection finds each site at its pixel.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from chiptwin.dsp import reference
from chiptwin.dsp.errors import Case, compare
from chiptwin.dsp.filters import (
    KineticsConfig,
    WienerEqualizer,
    fir_fixed,
    kinetics_weighted_fixed,
    wiener_equalize_fixed,
)
from chiptwin.dsp.fmt import Fmt
from chiptwin.dsp.frame_ops import bin_lines_fixed
from chiptwin.dsp.pipeline import BlockOut, ErrorStats
from chiptwin.dsp.program import (
    FIR_TAPS,
    KINETICS_COEF,
    KINETICS_NORM_BITS,
    ProgramFormats,
    program_formats,
)
from chiptwin.dsp.registers import FixedResult

#: The FIR runs along each row of the output grid; its output is read this many columns late
#: (the chip flushes the row with as many zeros), so the 8-tap linear-phase filter is centred on
#: each column to within half a pixel (its delay is 3.5 columns).
FIR_ALIGN = FIR_TAPS // 2


@dataclass(frozen=True)
class KineticsPlan:
    """The kinetics stage of a scenario.

    Attributes
    ----------
    cfg : KineticsConfig
        Weights ``exp(−k t_j)`` at the window-relative frame starts ``t_s`` and formats.
    window : array of int
        Window of each DSP job after the dark block (one frame each); −1 outside every window.
    last : array of bool
        Whether the job is its window's last frame (the output is made then).
    scale : float
        ``Σw / N``: from the amplitude ``Â`` (a frame's value at the window's start) to the
        window total over ``N = average_frames``, the unit the detection's window sums read
        (one output per window, weight N).
    """

    cfg: KineticsConfig
    window: np.ndarray
    last: np.ndarray
    scale: float

    @property
    def weights(self) -> np.ndarray:
        return reference.kinetics_weights(np.array(self.cfg.t_s), self.cfg.k_per_s)

    @property
    def coefficients(self) -> np.ndarray:
        """``Â = Σ c_j y_j``: ``c = w / Σw²`` (float)."""
        w = self.weights
        return w / np.dot(w, w)


def kinetics_plan(chip: Any, sch: Any, edges: np.ndarray, k: float) -> KineticsPlan:
    """Windows of the kinetics stage and its weights ``exp(−k t_j)`` at each frame's start
    relative to its window's (the same table for every window: one weight ROM).

    ``chip`` is a ``[chip]`` section (:class:`chiptwin.config.schema.Chip`), ``sch`` its frame
    schedule (:class:`chiptwin.chip.Schedule`), ``edges`` the assay's window edges (s), ``k``
    the light's decay rate (1/s)."""
    d = chip.dsp
    frames = np.arange(sch.dark_frames, sch.n_frames)
    t0 = np.array([sch.window_s(f)[0] for f in frames])
    t1 = np.array([sch.window_s(f)[1] for f in frames])
    win = np.searchsorted(edges, t0, side="right") - 1
    inside = (win >= 0) & (win < len(edges) - 1)
    inside &= t1 <= edges[np.clip(win + 1, 0, len(edges) - 1)] + 1e-9
    win = np.where(inside, win, -1)
    if not (win >= 0).any():
        raise ValueError("kinetics: no frame of the run lies inside an assay window")
    counts = np.bincount(win[win >= 0], minlength=len(edges) - 1)
    full = counts.max()
    win = np.where((win >= 0) & (counts[np.maximum(win, 0)] == full), win, -1)  # cut windows
    first = win == win[win >= 0][0]
    t_s = tuple(float(v) for v in t0[first] - edges[win[first][0]])
    last = np.zeros(len(win), bool)
    idx = np.flatnonzero(win >= 0)
    last[idx] = np.append(win[idx][1:] != win[idx][:-1], True)
    fmts = program_formats(chip)
    cfg = KineticsConfig(t_s=t_s, k_per_s=k, in_fmt=fmts.front.average.out_fmt,
                         coef_fmt=KINETICS_COEF, acc_fmt=fmts.kinetics_acc,
                         norm_word_bits=KINETICS_NORM_BITS, out_fmt=fmts.kinetics_out,
                         rounding=d.rounding, overflow=d.overflow, acc_overflow=d.acc_overflow)
    w = np.exp(-k * np.array(t_s))
    return KineticsPlan(cfg, win, last, float(w.sum()) / d.average_frames)


@dataclass(frozen=True)
class SpatialPlan:
    """The spatial stages: formats, the designed equalizer, the geometry."""

    stages: tuple[str, ...]
    rows: int
    cols: int
    formats: ProgramFormats
    wiener: WienerEqualizer | None
    grid_rows: int
    cell_of_pixel: np.ndarray = field(repr=False)

    @property
    def n_grid(self) -> int:
        return self.grid_rows * self.cols


def _fir_rows(x: np.ndarray, cols: int, apply) -> np.ndarray:
    """The FIR along each row of ``x`` (…, n_grid), read FIR_ALIGN columns late."""
    lead = x.shape[:-1]
    grid = x.reshape(-1, cols)  # (rows of all frames, cols)
    padded = np.concatenate([grid, np.zeros((grid.shape[0], FIR_ALIGN), grid.dtype)], axis=1)
    out = apply(np.ascontiguousarray(padded.T))[FIR_ALIGN:FIR_ALIGN + cols].T
    return np.ascontiguousarray(out).reshape(*lead, -1)


def spatial_float(plan: SpatialPlan, x: np.ndarray, upto: str | None = None,
                  after: str | None = None) -> np.ndarray:
    """The float reference of the spatial stages on frames ``x`` (…, n_pixels); ``upto`` stops
    before that stage, ``after`` starts after that one (``x`` is then that stage's output)."""
    f = plan.formats
    stages = plan.stages[plan.stages.index(after) + 1:] if after else plan.stages
    for stage in stages:
        if stage == upto:
            break
        if stage == "bin_rows":
            x = reference.bin_lines(x, plan.rows, plan.cols, f.binning.factor)
        elif stage == "fir8":
            h = f.fir.coefficients()
            x = _fir_rows(x, plan.cols, lambda a, h=h: reference.fir_filter(a, h))
        elif stage == "wiener":
            x = reference.wiener_equalize(x, plan.wiener.g)
    return x


def spatial_matrix(plan: SpatialPlan, upto: str | None = None,
                   after: str | None = None) -> np.ndarray:
    """``L`` (n_out × n_in) of the float spatial stages (before ``upto``, after ``after``)."""
    n = plan.n_grid if after else plan.rows * plan.cols
    return spatial_float(plan, np.eye(n), upto, after).T


class ProgramPipeline:
    """The DSP stage of the chip model for a program beyond today's chain.

    Parameters
    ----------
    front : Pipeline or RtlPipeline
        CMS → dark → background → average (N = 1 with kinetics), at the program's level.
    level : str
        ``"float"``, ``"fixed"`` or ``"rtl"`` (kinetics and fir8 then run their RTL blocks;
        validation refuses bin_rows and wiener there).
    kinetics, spatial : plans of those stages, or None.
    rtl_routines : module, optional
        At the ``rtl`` level: the RTL blocks (``kinetics_weighted_rtl``, ``fir_rtl``), i.e.
        :data:`chiptwin.twin.rtl.routines`; passed in, because ``rtl_ref`` imports this package.
    report_error : bool
        With fixed / rtl: a float front end and the float program run beside; :attr:`error` is
        the final output's error in its LSB, :attr:`stage_bounds` each stage's error on its own
        fixed input against the routine's analytic bound (:func:`chiptwin.dsp.errors.compare`).
    """

    def __init__(self, front: Any, level: str, kinetics: KineticsPlan | None,
                 spatial: SpatialPlan | None, report_error: bool = False,
                 float_front: Any = None, rtl_routines: Any = None) -> None:
        if level == "rtl" and rtl_routines is None:
            raise ValueError("the rtl level needs the RTL blocks: rtl_routines="
                             "chiptwin.twin.rtl.routines")
        self.front, self.level, self.rtl = front, level, rtl_routines
        self.kin, self.spatial = kinetics, spatial
        self.formats = spatial.formats if spatial else None
        self._post_overflow: dict[str, dict[str, int]] = {}
        self._matrix = spatial_matrix(spatial) if spatial else None
        self._float_front = float_front if report_error and level != "float" else None
        self.error = ErrorStats(self.out_fmt.lsb) if self._float_front is not None else None
        self.stage_bounds: dict[str, dict[str, Any]] = {}
        self._buf: list[tuple[BlockOut, BlockOut | None]] = []
        self._job = 0
        #: per output, on the grid: the front end's output binned (no filter) and the program's,
        #: values then expected values (LSB)
        self.profiles: list[tuple[np.ndarray, ...]] = []
        #: the front end's variance of the last output (LSB², per pixel)
        self.front_var: np.ndarray | None = None

    # ------------------------------------------------------------------ the Pipeline interface

    @property
    def chain(self) -> _ProgramChain | None:
        """Every stage's registers (None at the float level, which has none)."""
        return None if self.front.chain is None else _ProgramChain(self)

    @property
    def kept(self):
        return self.front.kept

    @property
    def dark_mean(self):
        return self.front.dark_mean

    @property
    def out_fmt(self) -> Fmt:
        """The last stage's output register."""
        if self.spatial and self.spatial.wiener is not None:
            return self.spatial.wiener.out_fmt
        f = self.spatial.formats if self.spatial else None
        if f is not None and f.fir is not None:
            return f.fir.out_fmt
        if f is not None and f.binning is not None:
            return f.binning.out_fmt
        if self.kin is not None:
            return self.kin.cfg.out_fmt
        return self.front.chain.average.out_fmt

    @property
    def overflow(self) -> dict[str, dict[str, int]]:
        front = {k: v for k, v in self.front.overflow.items()
                 if not (self.kin is not None and k.startswith("average."))}
        return {**front, **self._post_overflow}

    @property
    def dark_var(self) -> np.ndarray | None:
        """Variance of the dark reference's share of each output pixel (coherent over outputs)."""
        dv = self.front.dark_var
        if dv is None:
            return None
        scale = 1.0
        if self.kin is not None:
            scale = float(self.kin.coefficients.sum()) * self.kin.scale
        if self._matrix is not None:
            dv = (self._matrix**2) @ dv
        return self._expand(dv) * scale**2

    def dark(self, frames) -> None:
        self.front.dark(frames)
        if self._float_front is not None:
            self._float_front.dark(frames)

    def block(self, frames) -> BlockOut | None:
        out = self.front.block(frames)
        ref = self._float_front.block(frames) if self._float_front is not None else None
        if self.kin is not None:
            j, self._job = self._job, self._job + 1
            if j >= len(self.kin.window) or self.kin.window[j] < 0:
                return None
            self._buf.append((out, ref))
            if not self.kin.last[j]:
                return None
            buf, self._buf = self._buf, []
            out, ref = self._kinetics(buf, frames[0].codes is None)
        return self._finish(out, ref, frames[0].codes is None)

    def covariance(self, var: np.ndarray) -> np.ndarray:
        """Covariance of the spatial stages' output grid for independent pixel variances
        ``var`` (n_pixels,): ``L diag(var) Lᵀ`` (the identity without spatial stages)."""
        if self._matrix is None:
            return np.diag(var)
        return (self._matrix * var[None, :]) @ self._matrix.T

    # ------------------------------------------------------------------ the stages

    def _kinetics(self, buf, expected: bool) -> tuple[BlockOut, BlockOut | None]:
        c = self.kin.coefficients
        if len(buf) != len(c):
            raise RuntimeError(f"kinetics: a window of {len(buf)} frames, the weights have "
                               f"{len(c)} (a frame was dropped)")
        mean = c @ np.array([o.mean for o, _ in buf])
        var = (c**2) @ np.array([o.var for o, _ in buf])
        if expected:
            return BlockOut(mean, mean, var), None
        x = np.array([o.value for o, _ in buf])
        ref = None
        if buf[0][1] is not None:
            xr = np.array([r.value for _, r in buf])
            ref = BlockOut(reference.kinetics_weighted_amplitude(xr, self.kin.cfg.t_s,
                                                                 self.kin.cfg.k_per_s), mean, var)
        if self.level == "float":
            value = reference.kinetics_weighted_amplitude(x, self.kin.cfg.t_s, self.kin.cfg.k_per_s)
            return BlockOut(value, mean, var), None
        cfg = self.kin.cfg
        codes = _codes(x, cfg.in_fmt)
        res = self._run("kinetics", codes, cfg)
        self._bound("kinetics", Case("kinetics", cfg, {"frames": codes}))
        return BlockOut(res.values(), mean, var), ref

    def _finish(self, out: BlockOut, ref: BlockOut | None, expected: bool) -> BlockOut:
        value, mean, var = out.value, out.mean, out.var
        self.front_var = var
        before, before_mean = value, mean
        if self.spatial is not None:
            mean, var = self._matrix @ mean, (self._matrix**2) @ var
            value = mean if expected else self._spatial(value)
        if ref is not None and self.error is not None:
            rv = ref.value if self.spatial is None else spatial_float(self.spatial, ref.value)
            self.error.add(value, rv)
        if self.spatial is not None:
            self.profiles.append((self._front_grid(before), value,
                                  self._front_grid(before_mean), mean))
        s = self.kin.scale if self.kin is not None else 1.0
        return BlockOut(self._expand(value) * s, self._expand(mean) * s,
                        self._expand(var) * s * s)

    def _front_grid(self, x: np.ndarray) -> np.ndarray:
        """The front end's output on the spatial grid (binned, no filter): the "before"."""
        if "bin_rows" not in self.spatial.stages:
            return x
        return spatial_float(self.spatial, x, upto="fir8")

    def _spatial(self, x: np.ndarray) -> np.ndarray:
        if self.level == "float":
            return spatial_float(self.spatial, x)
        f, plan = self.spatial.formats, self.spatial
        fmt = f.front_out
        codes = _codes(x, fmt)
        for stage in plan.stages:
            if stage == "bin_rows":
                self._bound("bin_rows", Case("binning", f.binning, {"frames": codes}))
                codes, fmt = self._run("bin_rows", codes, f.binning).codes, f.binning.out_fmt
            elif stage == "fir8":
                pre = codes
                codes = _fir_rows(codes, plan.cols, lambda a: self._run("fir8", a, f.fir).codes)
                padded = np.concatenate([pre.reshape(-1, plan.cols),
                                         np.zeros((pre.size // plan.cols, FIR_ALIGN), np.int64)],
                                        axis=1)
                self._bound("fir8", Case("fir", f.fir, {"frames": np.ascontiguousarray(
                    padded.T)}))
                fmt = f.fir.out_fmt
            elif stage == "wiener":
                eq = plan.wiener
                self._bound("wiener", Case("wiener", eq, {"frames": codes}))
                codes, fmt = self._run("wiener", codes, eq).codes, eq.out_fmt
        return fmt.to_float(codes)

    def _run(self, stage: str, codes: np.ndarray, cfg) -> FixedResult:
        """One stage's routine at the level (RTL block where it exists), overflow booked."""
        if stage == "kinetics":
            fn = self.rtl.kinetics_weighted_rtl if self.level == "rtl" else kinetics_weighted_fixed
        elif stage == "fir8":
            fn = self.rtl.fir_rtl if self.level == "rtl" else fir_fixed
        elif stage == "bin_rows":
            fn = bin_lines_fixed
        else:
            fn = wiener_equalize_fixed
        res = fn(codes, cfg)
        for reg, counts in res.overflow.items():
            book = self._post_overflow.setdefault(f"{stage}.{reg}", {"sat": 0, "wrap": 0})
            for kind in ("sat", "wrap"):
                book[kind] += counts[kind]
        return res

    def _bound(self, stage: str, case: Case) -> None:
        """With report_error: the stage's error against its analytic bound on this input, and
        that bound carried to the program's output (``bound_at_output``, the detection's units:
        :meth:`error_gain`). ``bound_ok`` is True when every output was within the bound, False
        when one was not, None when a register before the output overflowed (the bound does not
        apply there); ``n_clipped`` counts outputs saturated at the output format, whose error
        the bound leaves out."""
        if self.error is None:
            return
        r = compare(case)
        b = self.stage_bounds.get(stage)
        if b is None:  # the gain once per stage: it builds the float map of the stages after
            b = self.stage_bounds[stage] = {
                "max_abs_err_lsb": 0.0, "bound_lsb": 0.0, "bound_ok": True, "outputs": 0,
                "n_clipped": 0, "gain_to_output": self.error_gain(stage), "bound_at_output": 0.0}
        b["max_abs_err_lsb"] = max(b["max_abs_err_lsb"], r["max_abs_err_in_range_lsb"])
        b["bound_lsb"] = max(b["bound_lsb"], r["bound_lsb"])
        b["bound_at_output"] = b["bound_lsb"] * case.cfg.out_fmt.lsb * b["gain_to_output"]
        if b["bound_ok"] is not False and r["bound_ok"] is not True:
            b["bound_ok"] = r["bound_ok"]  # False (exceeded) outranks None (not applicable)
        b["n_clipped"] += r["n_clipped"]
        b["outputs"] += r["n_outputs"]

    def error_gain(self, stage: str) -> float:
        """How far an error of at most 1 in each output of ``stage`` (its values' units;
        ``"front"``: the chain's average, in ADC LSB) can move an output of the program, in the
        units the detection reads: the float stages after it are linear, so their largest
        absolute row sum (ℓ∞ gain: the kinetics' ``Σ|c_j|``, the spatial stages' ``L``), times
        the window scale. The stages' local errors add at the output through these gains
        (fixed − float telescopes stage by stage), which is the bound ``fidelity.auto`` uses."""
        gain = self.kin.scale if self.kin is not None else 1.0
        if stage == "front" and self.kin is not None:
            gain *= float(np.abs(self.kin.coefficients).sum())
        if self.spatial is not None:
            if stage in ("front", "kinetics"):
                matrix = self._matrix
            else:
                matrix = spatial_matrix(self.spatial, after=stage)
            if matrix.size:
                gain *= float(np.abs(matrix).sum(axis=1).max())
        return gain

    def _expand(self, x: np.ndarray) -> np.ndarray:
        """A grid value at every pixel: pixel ``p`` reads the cell it lies in."""
        return x if self.spatial is None else x[self.spatial.cell_of_pixel]


def _codes(values: np.ndarray, fmt: Fmt) -> np.ndarray:
    """Codes of values that a register of ``fmt`` produced (exact: they are on its grid)."""
    codes = np.ldexp(np.asarray(values, dtype=np.float64), fmt.frac_bits)
    out = np.rint(codes).astype(np.int64)
    if not np.array_equal(out, codes):
        raise ValueError(f"values are not on the grid of {fmt}")
    return out


class _ProgramChain:
    """``registers()`` of every stage of the program (what ``summary['dsp']`` lists)."""

    def __init__(self, p: ProgramPipeline) -> None:
        self.p = p

    def registers(self) -> dict[str, dict[str, Fmt]]:
        p = self.p
        regs = dict(p.front.chain.registers())
        if p.kin is not None:
            regs.pop("average", None)
            regs["kinetics"] = p.kin.cfg.registers()
        f = p.spatial.formats if p.spatial else None
        if f is not None and f.binning is not None:
            regs["bin_rows"] = f.binning.registers()
        if f is not None and f.fir is not None:
            regs["fir8"] = f.fir.registers()
        if p.spatial is not None and p.spatial.wiener is not None:
            regs["wiener"] = p.spatial.wiener.registers()
        return regs
