"""The chip as a discrete-event model (SimPy), one event per chip action, never per pixel or photon.

Frame ``k`` starts at ``k · frame_period`` (integer nanosecond ticks, :mod:`chiptwin.constants`)::

    reset ─ M reset conversions ─ integrate t_int ─ M signal conversions ─ memory write ─ (idle)

All per-pixel ADCs convert at once, so one conversion event carries the whole frame. Frames wait in
a frame memory of finite capacity until the DSP has a block: first the dark block of K frames (the
dark reference), then blocks of N frames it averages. A frame occupies memory from its write until
the DSP job that reads it ends. A write into a full memory is an overflow: the frame is dropped and
counted, never silently. A DSP slower than the frames arrive is flagged.

The DSP program (``[chip.dsp] program``, :mod:`chiptwin.dsp.program`) sets what the memory holds
besides frames (dark reference, kinetics accumulator, filter buffers, Wiener table), the frames
per job (N, or 1 with the kinetics stage, which frees each frame once added) and the time of a
job: its frames' cycles, plus the output stages' cycles when the job makes an output.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from operator import itemgetter
from typing import Any, Protocol

import simpy
from simpy.core import BoundClass

from chiptwin.chip.trace import Recorder
from chiptwin.constants import s_to_ticks, ticks_to_s

#: A ``[chip]`` section (:class:`chiptwin.config.schema.Chip`). The stage
#: packages sit below the scenario files (``docs/architecture.md``): they read its fields by
#: name and import nothing from ``config``.
Chip = Any


class DspEngine(Protocol):
    """What the chip model needs of a DSP level: a dark block, then blocks of frames."""

    def dark(self, frames: list[Any]) -> None: ...

    def block(self, frames: list[Any]) -> Any: ...


@dataclass(frozen=True)
class Schedule:
    """The chip's timing in integer nanosecond ticks, derived once from the scenario."""

    n_frames: int
    frame_period_ns: int
    t_reset_ns: int
    t_conv_ns: int
    t_int_ns: int
    cms_samples: int
    memory_frames: int
    dark_frames: int
    block_frames: int
    dsp_ns_per_frame: int
    #: DSP time of the program's stages after average / kinetics, per output (0 for the chain).
    dsp_ns_per_output: int = 0

    @classmethod
    def from_chip(cls, chip: Chip, duration_s: float) -> Schedule:
        """Derive the schedule: conversions from bits and ADC clock, DSP time from its clock.

        The DSP program (:func:`chiptwin.dsp.program.program_load`) sets what stays in memory
        (the dark reference, a kinetics accumulator, filter buffers, the Wiener table), the
        frames per DSP job and the cycles per frame and per output. ``dsp_ns_per_frame``
        includes the output cycles spread over the frames of a job (the check that the DSP keeps
        up); with kinetics a job is one frame, so that spread is an upper bound.
        """
        from chiptwin.dsp.program import program_load

        load = program_load(chip)
        period = s_to_ticks(chip.timing.frame_period_s)
        dsp_s = load.cycles_per_frame / chip.dsp.clock_hz
        per_out = s_to_ticks(load.cycles_per_output / chip.dsp.clock_hz)
        return cls(
            n_frames=int(s_to_ticks(duration_s) // period),
            frame_period_ns=period,
            t_reset_ns=s_to_ticks(chip.timing.t_reset_s),
            t_conv_ns=s_to_ticks(chip.adc.conversion_time_s),
            t_int_ns=s_to_ticks(chip.timing.t_int_s),
            cms_samples=chip.dsp.cms_samples,
            memory_frames=(chip.memory.capacity_bits - load.resident_bits) // chip.frame_bits,
            dark_frames=chip.dsp.n_dark_frames,
            block_frames=load.frames_per_job,
            dsp_ns_per_frame=max(1, s_to_ticks(dsp_s)) + -(-per_out // load.frames_per_job),
            dsp_ns_per_output=per_out,
        )

    def window_s(self, k: int) -> tuple[float, float]:
        """The integration window of frame ``k``. Unit: s."""
        start = k * self.frame_period_ns + self.t_reset_ns + self.cms_samples * self.t_conv_ns
        return ticks_to_s(start), ticks_to_s(start + self.t_int_ns)

    def job_ns(self, frames: int, output: bool) -> int:
        """How long a DSP job of ``frames`` frames takes. Unit: ns.

        ``dsp_ns_per_frame`` spreads the output stages' cycles over a job's frames; a job is
        charged what it did: its frames, plus the output cycles when it makes an ``output``.
        """
        spread = -(-self.dsp_ns_per_output // self.block_frames)
        return frames * (self.dsp_ns_per_frame - spread) + (self.dsp_ns_per_output if output
                                                            else 0)

    @property
    def busy_ns(self) -> int:
        """Reset, conversions and integration of one frame. Unit: ns."""
        return self.t_reset_ns + 2 * self.cms_samples * self.t_conv_ns + self.t_int_ns


@dataclass
class ChipRun:
    """What the chip model produced: DSP outputs, memory history and the flags."""

    outputs: list[tuple[list[int], Any]] = field(default_factory=list)
    occupancy: list[tuple[int, int]] = field(default_factory=list)
    dropped: list[int] = field(default_factory=list)
    dsp_busy_ns: int = 0
    end_ns: int = 0
    last_write_ns: int = 0
    unprocessed_frames: int = 0

    @property
    def memory_peak_frames(self) -> int:
        return max(map(itemgetter(1), self.occupancy), default=0)


class _BlockGet(simpy.resources.base.Get):
    """A request for the next ``n`` frames of a :class:`_FrameStore`, granted all at once."""

    def __init__(self, store: _FrameStore, n: int):
        self.n = n
        super().__init__(store)


class _FrameStore(simpy.Store):
    """SimPy's FIFO Store, plus ``get_block(n)``: the first ``n`` items as a list, granted when
    the ``n``-th of ``n`` single gets would have been (one event and one wake-up of the DSP per
    job instead of one per frame; the same items at the same tick)."""

    get_block = BoundClass(_BlockGet)

    def _do_get(self, event):
        if not isinstance(event, _BlockGet):
            return super()._do_get(event)
        if len(self.items) >= event.n:
            event.succeed(self.items[:event.n])
            del self.items[:event.n]
        return None


class FrameMemory:
    """Frame memory of ``capacity`` frames: a SimPy Store plus occupancy accounting."""

    def __init__(self, env: simpy.Environment, capacity: int, rec: Recorder, run: ChipRun):
        self.env, self.capacity, self.rec, self.run = env, capacity, rec, run
        self.store = _FrameStore(env)
        self.occupied = 0

    def write(self, k: int, payload: Any) -> bool:
        """Store frame ``k``; a full memory drops it and records an overflow."""
        if self.occupied >= self.capacity:
            self.run.dropped.append(k)
            self.rec.record(self.env.now, "memory", "overflow", k)
            return False
        self.occupied += 1
        self.store.put((k, payload))
        self._note("write")
        return True

    def free(self, n: int) -> None:
        """Release ``n`` frames once the DSP job that read them has ended."""
        self.occupied -= n
        self._note("free")

    def _note(self, event: str) -> None:
        self.rec.record(self.env.now, "memory", event, self.occupied)
        self.run.occupancy.append((self.env.now, self.occupied))


def simulate_chip(
    sch: Schedule,
    read_frame: Callable[[int], Any],
    dsp: DspEngine,
    rec: Recorder,
    progress: Callable[[int, int], None] | None = None,
) -> ChipRun:
    """Run the chip for ``sch.n_frames`` frames.

    Parameters
    ----------
    sch : Schedule
        Timing in ticks.
    read_frame : callable
        ``read_frame(k)`` returns frame ``k`` as the ADC delivers it (pixel + ADC stages); called
        at the end of the frame's signal conversions.
    dsp : DspEngine
        The DSP level (float, fixed, or the expected-value propagation).
    rec : Recorder
        Receives every event.
    progress : callable, optional
        ``progress(frames_done, n_frames)``, called once per frame.

    Notes
    -----
    The reference engine. A steady run (no ties, no overflow, a DSP that keeps up) has the same
    :class:`ChipRun` and trace in closed form, :func:`chiptwin.chip.steady.steady_run`, which
    :func:`chiptwin.twin.runner.simulate` takes when its DSP's timing does not depend on its
    outputs.
    """
    env = simpy.Environment()
    run = ChipRun()
    memory = FrameMemory(env, sch.memory_frames, rec, run)
    env.process(_sensor(env, sch, read_frame, memory, rec, run, progress))
    env.process(_dsp(env, sch, dsp, memory, rec, run))
    env.run()
    run.end_ns = int(env.now)
    run.unprocessed_frames = len(memory.store.items)
    return run


def _sensor(env, sch: Schedule, read_frame, memory: FrameMemory, rec, run, progress):
    """Pixel array and ADCs: reset, reset samples, integrate, signal samples, write.

    A recorder without ``frame_steps`` (:data:`chiptwin.chip.trace.FRAME_STEPS`) gets the same
    waits merged: one from a frame's write to the next frame's signal conversions.
    """
    conv = sch.cms_samples * sch.t_conv_ns
    steps = getattr(rec, "frame_steps", True)
    idle = 0  # the previous frame's idle time, merged into this frame's first wait
    for k in range(sch.n_frames):
        if steps:
            yield from _frame_steps(env, sch, rec, k, conv)
        else:
            yield env.timeout(idle + sch.t_reset_ns + conv + sch.t_int_ns)
        yield env.timeout(conv)
        rec.record(env.now, "adc", "frame_ready", k)
        if memory.write(k, read_frame(k)):
            run.last_write_ns = int(env.now)
        if progress is not None:
            progress(k + 1, sch.n_frames)
        if steps:
            yield env.timeout(sch.frame_period_ns - sch.busy_ns)
        else:
            idle = sch.frame_period_ns - sch.busy_ns
    if not steps and sch.n_frames:
        yield env.timeout(idle)  # the last frame's idle time: the run ends when it did


def _frame_steps(env, sch: Schedule, rec, k: int, conv: int):
    """Frame ``k`` from its reset to its signal conversions, each step recorded."""
    rec.record(env.now, "pixel", "reset", k)
    yield env.timeout(sch.t_reset_ns)
    rec.record(env.now, "adc", "convert_reset", sch.cms_samples)
    yield env.timeout(conv)
    rec.record(env.now, "pixel", "integrate_start", k)
    yield env.timeout(sch.t_int_ns)
    rec.record(env.now, "adc", "convert_signal", sch.cms_samples)


def _dsp(env, sch: Schedule, dsp: DspEngine, memory: FrameMemory, rec, run):
    """The DSP: the dark block once, then blocks of N frames, each job taking its stated time."""
    size, first = sch.dark_frames, True
    while True:
        items = (yield memory.store.get_block(size)) if size else []
        rec.record(env.now, "dsp", "job_start", len(items))
        frames = [payload for _, payload in items]
        out = None if first else dsp.block(frames)  # None: no output yet (kinetics window)
        duration = sch.job_ns(size, out is not None)
        yield env.timeout(duration)
        run.dsp_busy_ns += duration
        if first:
            dsp.dark(frames)
        elif out is not None:
            run.outputs.append(([k for k, _ in items], out))
        rec.record(env.now, "dsp", "job_end", len(items))
        memory.free(size)
        size, first = sch.block_frames, False
