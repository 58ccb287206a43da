"""The chip model in closed form for a steady run: SimPy's ChipRun and trace, without the events.

A run is *steady* when the frame memory holds the dark block and every job's frames (no write
overflows) and every DSP job ends before the next write after the one that started it, at a tick
where the sensor does nothing, and starts at one (its write) too. Then no two events meet at
one tick where their order could matter, and :func:`~chiptwin.chip.des.simulate_chip`'s run
follows from the schedule alone (frame ``k`` is written at ``t_k = k·frame_period + busy``)::

    dark job   frames 0 … K−1, from t_{K−1}, for job_ns(K); dark() at its end
    job j      frames K + jN … K + (j+1)N − 1, from the write of its last frame, for job_ns(N)
    the frames after the last whole job stay in the memory (unprocessed)

The sensor acts after a write at the next frame's reset, reset conversions, integration start and
signal conversions when the trace records frame steps, at its signal conversions only when it
does not (``frame_period − M·t_conv`` after the write; :data:`chiptwin.chip.trace.FRAME_STEPS`),
and writes again one frame period after. A job that ends strictly before that next write frees
its frames before it (the memory's history is the schedule's); one that ends at none of the
sensor's ticks meets no event whose same-tick order SimPy would decide, so the trace is the
events sorted by time (a job longer than the idle time ends among the next frame's steps:
pyro_paper_yield_fast's 128-frame jobs, 1.3 ms against 0.5 ms of idle). :func:`steady_run`
declines every other schedule (a tie, an overflow, a DSP slower than a frame), and SimPy, the
reference engine, runs it. The two are compared on random schedules, ties, overflows and slow
DSPs included, in ``tests/chip/test_steady.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from chiptwin.chip.des import ChipRun, Schedule
from chiptwin.chip.trace import FRAME_STEPS, Recorder

#: A frame's records in the trace, in the order :func:`simulate_chip` makes them: its steps
#: (with ``frame_steps``), its write, then the DSP job that write starts (if one does).
SLOTS: tuple[tuple[str, str], ...] = FRAME_STEPS + (
    ("adc", "frame_ready"), ("memory", "write"), ("dsp", "job_start"), ("dsp", "job_end"),
    ("memory", "free"))
_SLOT_NAMES = np.array(SLOTS, dtype=object)
_STEPS, _WRITE, _JOB = slice(0, 4), slice(4, 6), slice(6, 9)
_MEMORY = [5, 8]  # the slots that change the memory's occupancy: write, free


@dataclass(frozen=True)
class SteadyRun:
    """A steady run of ``sch`` (:func:`steady_run` made it): its jobs in closed form.

    Attributes
    ----------
    sch : Schedule
    frame_steps : bool
        Whether the trace records each frame's steps (:attr:`Recorder.frame_steps`).
    """

    sch: Schedule
    frame_steps: bool

    @property
    def dark_done(self) -> bool:
        """Whether the run has the K frames of the dark block."""
        return self.sch.n_frames >= self.sch.dark_frames

    @property
    def n_jobs(self) -> int:
        """Jobs after the dark one: ``block_frames`` frames and one DSP output each."""
        sch = self.sch
        return max(0, (sch.n_frames - sch.dark_frames) // sch.block_frames)

    def frames_of(self, job: int) -> range:
        """The frames of job ``job`` after the dark one."""
        first = self.sch.dark_frames + job * self.sch.block_frames
        return range(first, first + self.sch.block_frames)

    def chip_run(self, outputs: Sequence[Any], rec: Recorder) -> ChipRun:
        """The run's :class:`ChipRun`, ``outputs[j]`` the DSP output of job ``j``; its trace
        appended to ``rec`` as :func:`simulate_chip` records it."""
        sch = self.sch
        if len(outputs) != self.n_jobs:
            raise ValueError(f"{len(outputs)} DSP outputs for {self.n_jobs} jobs")
        frames = sch.dark_frames + np.arange(self.n_jobs * sch.block_frames)
        run = ChipRun(outputs=list(zip(frames.reshape(-1, sch.block_frames).tolist(), outputs,
                                       strict=True)))
        size, ns = self._jobs()
        written = np.arange(sch.n_frames) * sch.frame_period_ns + sch.busy_ns
        run.dsp_busy_ns = int(ns.sum())
        run.end_ns = max([sch.n_frames * sch.frame_period_ns]  # the sensor's last idle time
                         + (written + ns)[size > 0].tolist())  # or the last job's end
        run.last_write_ns = int(written[-1]) if sch.n_frames else 0
        run.unprocessed_frames = sch.n_frames - int(size.sum())
        run.occupancy, events = self._events(written, size, ns)
        rec.events.extend(events)
        return run

    def _jobs(self) -> tuple[np.ndarray, np.ndarray]:
        """Per frame: the frames of the DSP job its write starts (0: none), and its time (ns)."""
        sch = self.sch
        size = np.zeros(sch.n_frames, np.int64)
        ns = np.zeros(sch.n_frames, np.int64)
        if self.dark_done:
            size[sch.dark_frames - 1] = sch.dark_frames
            ns[sch.dark_frames - 1] = sch.job_ns(sch.dark_frames, False)
            last = sch.dark_frames - 1 + sch.block_frames * np.arange(1, self.n_jobs + 1)
            size[last] = sch.block_frames
            ns[last] = sch.job_ns(sch.block_frames, True)
        return size, ns

    def _events(self, written: np.ndarray, size: np.ndarray, ns: np.ndarray
                ) -> tuple[list[tuple[int, int]], list[tuple[int, str, str, float]]]:
        """The memory's occupancy history and the trace: a row of :data:`SLOTS` per frame,
        the slots that happen kept, row by row."""
        sch, n = self.sch, self.sch.n_frames
        k = np.arange(n)
        freed = np.zeros(n, np.int64)  # a job's frames are freed before the next write
        starts = np.flatnonzero(size[:-1])
        freed[starts + 1] = size[starts]
        held = k + 1 - np.cumsum(freed)  # frames in the memory after frame k's write
        t = np.empty((n, len(SLOTS)), np.int64)
        value = np.empty((n, len(SLOTS)))
        conv = sch.cms_samples * sch.t_conv_ns
        t[:, _STEPS] = (k * sch.frame_period_ns)[:, None] + np.cumsum(
            [0, sch.t_reset_ns, conv, sch.t_int_ns])
        t[:, 4:7] = written[:, None]
        t[:, 7:] = (written + ns)[:, None]
        value[:, _STEPS] = np.stack([k, np.full(n, sch.cms_samples)] * 2, axis=1)
        value[:, 4:] = np.stack([k, held, size, size, held - size], axis=1)
        shown = np.zeros((n, len(SLOTS)), bool)
        shown[:, _STEPS] = self.frame_steps
        shown[:, _WRITE] = True
        shown[:, _JOB] = (size > 0)[:, None]
        names = _SLOT_NAMES[np.nonzero(shown)[1]]
        order = np.argsort(t[shown], kind="stable")  # a job may end among the next frame's steps
        events = list(zip(t[shown][order].tolist(), names[order, 0].tolist(),
                          names[order, 1].tolist(), value[shown][order].tolist(), strict=True))
        memory = np.zeros_like(shown)
        memory[:, _MEMORY] = shown[:, _MEMORY]
        occupancy = list(zip(t[memory].tolist(), value[memory].astype(np.int64).tolist(),
                             strict=True))  # a write, then its job's free: in time order already
        return occupancy, events


def steady_run(sch: Schedule, frame_steps: bool) -> SteadyRun | None:
    """``sch``'s run in closed form when it is steady, else None (SimPy decides).

    Steady: a dark block of at least one frame; a memory that holds it and a job's frames; an
    idle time ≥ 0; every DSP job of a length ≥ 0, shorter than a frame period (it ends before
    the next write), starting (at its write) and ending at none of the sensor's ticks after that
    write (:func:`_sensor_ticks`; with no idle time the write is the next frame's reset).
    """
    if sch.dark_frames < 1 or sch.block_frames < 1 or sch.frame_period_ns < sch.busy_ns:
        return None
    if sch.memory_frames < max(sch.dark_frames, sch.block_frames):
        return None
    jobs = (sch.job_ns(sch.dark_frames, False), sch.job_ns(sch.block_frames, True))
    if min(jobs) < 0 or max(jobs) >= sch.frame_period_ns:
        return None
    if {0, *jobs} & _sensor_ticks(sch, frame_steps):  # a job starts or ends on a sensor tick
        return None
    return SteadyRun(sch, frame_steps)


def _sensor_ticks(sch: Schedule, frame_steps: bool) -> set[int]:
    """The times after a write at which the sensor's process resumes before the next write: the
    next frame's four steps, or (without frame steps) its signal conversions. Unit: ns."""
    idle, conv = sch.frame_period_ns - sch.busy_ns, sch.cms_samples * sch.t_conv_ns
    steps = (0, sch.t_reset_ns, sch.t_reset_ns + conv, sch.t_reset_ns + conv + sch.t_int_ns)
    return {idle + d for d in (steps if frame_steps else steps[-1:])}
