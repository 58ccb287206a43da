"""The chip's event trace as an IEEE 1364 value change dump (VCD) for a waveform viewer.

Each block of the chip model is a scope of the dump, each state of a block a signal, in the trace's
integer nanosecond ticks (``$timescale 1ns``)::

    chip.pixel   reset, integrate          1 while the array resets / integrates
                 frame                     the frame the array is exposing (set at its reset)
    chip.adc     convert_reset             1 while the ADCs convert the M reset samples
                 convert_signal            1 while they convert the M signal samples (the readout)
                 samples                   M, conversions per sample phase (CMS)
                 frame                     the last frame the ADCs delivered (adc.frame_ready)
    chip.memory  occupancy                 frames held in the frame memory
                 overflows, dropped        frames dropped so far, and the last one dropped
    chip.dsp     busy                      1 while a DSP job runs
                 job, job_frames           the job's number (0: the dark block) and its frames

:data:`CHANGES` says which signals each trace event sets, in the order they are written; an event
the table does not name (a block added later) gets a ``real`` signal ``block.event`` carrying its
value, so nothing in the trace is left out. Integers start unknown (``x``) where nothing has
happened yet (no frame, no job); the states start at 0.

Only changes are written (a value equal to the signal's current one is not), in the trace's order:
two events at one tick that set one signal (a DSP job ending and the next starting at the same
tick, ``busy`` 1 → 0 → 1) are both written, at that tick, as a zero-width glitch: the viewer shows
the last value and marks the glitch. A trace without frame steps (``Recorder(frame_steps=False)``)
has no pixel or conversion events: their signals are left out and a ``$comment`` says so.

The format is small (IEEE Std 1364-2005, clause 18) and the writer below is the whole of it, with
no dependency; the tests read its files back with an independent reader (pyvcd's tokenizer) and
check them against the trace event for event.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

#: Unknown: no value yet (no frame delivered, no job started).
X = None


@dataclass(frozen=True)
class Signal:
    """One signal of the dump: its scope (a chip block), name, VCD type and width, first value."""

    scope: str
    name: str
    kind: str  # "wire" (1 bit), "integer" (32 bits) or "real"
    initial: int | float | None
    doc: str

    @property
    def width(self) -> int:
        return {"wire": 1, "integer": 32, "real": 64}[self.kind]

    @property
    def path(self) -> str:
        return f"{self.scope}.{self.name}"


#: Every signal, in the order the dump declares them. ``steps``: only with frame steps.
SIGNALS: tuple[Signal, ...] = (
    Signal("pixel", "reset", "wire", 0, "1 while the pixel array resets"),
    Signal("pixel", "integrate", "wire", 0, "1 while the pixel array integrates"),
    Signal("pixel", "frame", "integer", X, "the frame the array is exposing"),
    Signal("adc", "convert_reset", "wire", 0, "1 while the ADCs convert the reset samples"),
    Signal("adc", "convert_signal", "wire", 0,
           "1 while the ADCs convert the signal samples (the readout)"),
    Signal("adc", "samples", "integer", X, "conversions per sample phase (CMS samples M)"),
    Signal("adc", "frame", "integer", X, "the last frame the ADCs delivered"),
    Signal("memory", "occupancy", "integer", 0, "frames held in the frame memory"),
    Signal("memory", "overflows", "integer", 0, "frames dropped so far (memory full)"),
    Signal("memory", "dropped", "integer", X, "the last frame dropped"),
    Signal("dsp", "busy", "wire", 0, "1 while a DSP job runs"),
    Signal("dsp", "job", "integer", X, "the running or last job (0: the dark block)"),
    Signal("dsp", "job_frames", "integer", 0, "frames of the running job (0: idle)"),
)

#: The signals that only the frame steps (:data:`chiptwin.chip.trace.FRAME_STEPS`) set.
STEP_SIGNALS = frozenset({"pixel.reset", "pixel.integrate", "pixel.frame", "adc.convert_reset",
                          "adc.convert_signal", "adc.samples"})

State = dict[str, "int | float | None"]
#: ``(block, event)`` → the changes it makes: ``(signal path, value of (event value, state))``.
CHANGES: dict[tuple[str, str], tuple[tuple[str, Callable[[float, State], int | float]], ...]] = {
    ("pixel", "reset"): (("pixel.reset", lambda v, s: 1), ("pixel.frame", lambda v, s: int(v))),
    ("adc", "convert_reset"): (("pixel.reset", lambda v, s: 0),
                               ("adc.convert_reset", lambda v, s: 1),
                               ("adc.samples", lambda v, s: int(v))),
    ("pixel", "integrate_start"): (("adc.convert_reset", lambda v, s: 0),
                                   ("pixel.integrate", lambda v, s: 1),
                                   ("pixel.frame", lambda v, s: int(v))),
    ("adc", "convert_signal"): (("pixel.integrate", lambda v, s: 0),
                                ("adc.convert_signal", lambda v, s: 1),
                                ("adc.samples", lambda v, s: int(v))),
    ("adc", "frame_ready"): (("adc.convert_signal", lambda v, s: 0),
                             ("adc.frame", lambda v, s: int(v))),
    ("memory", "write"): (("memory.occupancy", lambda v, s: int(v)),),
    ("memory", "free"): (("memory.occupancy", lambda v, s: int(v)),),
    ("memory", "overflow"): (("memory.overflows", lambda v, s: s["memory.overflows"] + 1),
                             ("memory.dropped", lambda v, s: int(v))),
    ("dsp", "job_start"): (("dsp.busy", lambda v, s: 1),
                           ("dsp.job", lambda v, s: 0 if s["dsp.job"] is X else s["dsp.job"] + 1),
                           ("dsp.job_frames", lambda v, s: int(v))),
    ("dsp", "job_end"): (("dsp.busy", lambda v, s: 0), ("dsp.job_frames", lambda v, s: 0)),
}

Event = tuple[int, str, str, float]


def signals_of(events: Sequence[Event], frame_steps: bool) -> list[Signal]:
    """The signals a dump of ``events`` declares: :data:`SIGNALS` (without the steps' when the
    trace has none), then a ``real`` one per event :data:`CHANGES` does not name."""
    known = [sig for sig in SIGNALS if frame_steps or sig.path not in STEP_SIGNALS]
    extra = sorted({(b, e) for _, b, e, _ in events} - set(CHANGES))
    return known + [Signal(b, e, "real", X, f"the value of the trace's {b}.{e} events")
                    for b, e in extra]


def write_vcd(events: Sequence[Event], path: str | Path, *, frame_steps: bool = True,
              end_ns: int | None = None, comment: str = "", version: str = "chiptwin") -> None:
    """Write ``events`` (``(t_ns, block, event, value)`` in time order) as a VCD file.

    Parameters
    ----------
    events : sequence of (int, str, str, float)
        The chip's trace (:attr:`chiptwin.chip.Recorder.events`). Unit of ``t_ns``: ns.
    path : str or Path
    frame_steps : bool
        Whether the trace records each frame's steps (:attr:`Recorder.frame_steps`).
    end_ns : int, optional
        When the run ended (a last time stamp after the last event, so a viewer shows the last
        frame's idle time). Unit: ns.
    comment, version : str
        The dump's ``$comment`` (what run it is) and ``$version`` (what wrote it).

    Raises
    ------
    ValueError
        When the events are not in time order.
    """
    Path(path).write_text("\n".join(vcd_lines(events, frame_steps=frame_steps, end_ns=end_ns,
                                              comment=comment, version=version)) + "\n")


def vcd_lines(events: Sequence[Event], *, frame_steps: bool = True, end_ns: int | None = None,
              comment: str = "", version: str = "chiptwin") -> list[str]:
    """The lines of :func:`write_vcd`'s file."""
    signals = signals_of(events, frame_steps)
    ids = {sig.path: vcd_id(i) for i, sig in enumerate(signals)}
    state: State = {sig.path: sig.initial for sig in signals}
    lines = _header(signals, ids, frame_steps, comment, version)
    lines += ["#0", "$dumpvars", *(_value(sig, sig.initial, ids[sig.path]) for sig in signals),
              "$end"]
    by_path = {sig.path: sig for sig in signals}
    last_t = 0
    for t, block, event, value in events:
        if t < last_t:
            raise ValueError(f"trace event at {t} ns after one at {last_t} ns: not in time order")
        for name, new in _changes(block, event, value, state):
            if new == state[name]:
                continue
            if t != last_t:
                lines.append(f"#{t}")
                last_t = t
            state[name] = new
            lines.append(_value(by_path[name], new, ids[name]))
    if end_ns is not None and end_ns > last_t:
        lines.append(f"#{end_ns}")
    return lines


def _changes(block: str, event: str, value: float, state: State
             ) -> Iterable[tuple[str, int | float]]:
    """The ``(signal, value)`` changes one event makes, in order (each sees the ones before)."""
    rules = CHANGES.get((block, event))
    if rules is None:
        yield f"{block}.{event}", float(value)
        return
    for name, rule in rules:
        yield name, rule(value, state)


def _header(signals: list[Signal], ids: dict[str, str], frame_steps: bool, comment: str,
            version: str) -> list[str]:
    lines = [f"$version {version} $end"]
    if comment:
        lines.append(f"$comment {comment} $end")
    if not frame_steps:
        lines.append("$comment frame steps (reset, conversions, integration) not recorded: "
                     "no pixel or conversion signals $end")
    lines += ["$timescale 1ns $end", "$scope module chip $end"]
    for scope in dict.fromkeys(sig.scope for sig in signals):
        lines.append(f"$scope module {scope} $end")
        lines += [f"$var {sig.kind} {sig.width} {ids[sig.path]} {sig.name} $end"
                  for sig in signals if sig.scope == scope]
        lines.append("$upscope $end")
    return [*lines, "$upscope $end", "$enddefinitions $end"]


def _value(sig: Signal, value: int | float | None, ident: str) -> str:
    """One value change: ``0!`` (a wire), ``b101 "`` (an integer), ``r0.5 #`` (a real)."""
    if sig.kind == "wire":
        return f"{'x' if value is X else int(value)}{ident}"
    if sig.kind == "real":
        return f"r{'nan' if value is X else repr(float(value))} {ident}"
    return f"b{'x' if value is X else format(int(value) & 0xFFFFFFFF, 'b')} {ident}"


def vcd_id(i: int) -> str:
    """Short printable VCD identifiers: ``!``, ``"``, ``#``, … then two characters."""
    chars = [chr(c) for c in range(33, 127)]
    out = ""
    while True:
        out = chars[i % len(chars)] + out
        i = i // len(chars) - 1
        if i < 0:
            return out
