"""The chip's timing as a waveform (``chip.vcd``, :mod:`chiptwin.chip.vcd`): read back by an
independent reader (pyvcd's tokenizer, the test extra) and checked against the trace event for
event; a dropped frame, back-to-back DSP jobs, events the table does not name, a trace without
frame steps; ``chiptwin run --vcd`` and its refusal."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from chiptwin.chip.vcd import vcd_lines, write_vcd
from chiptwin.cli import main
from chiptwin.fidelity import run
from tests.conftest import require_module

#: A slow DSP and a 6-frame memory on the small scene: frames are dropped (SimPy's path).
DROPS = ["chip.dsp.clock_hz=200", "chip.memory.capacity_bits=9600"]

#: What each trace event must do to the waveform, written out once more as the test's oracle:
#: ``(signal, value)`` in order, ``v`` the event's value and ``s`` the signals' values so far.
EXPECTED = {
    ("pixel", "reset"): lambda v, s: [("pixel.reset", 1), ("pixel.frame", v)],
    ("adc", "convert_reset"): lambda v, s: [("pixel.reset", 0), ("adc.convert_reset", 1),
                                            ("adc.samples", v)],
    ("pixel", "integrate_start"): lambda v, s: [("adc.convert_reset", 0),
                                                ("pixel.integrate", 1), ("pixel.frame", v)],
    ("adc", "convert_signal"): lambda v, s: [("pixel.integrate", 0), ("adc.convert_signal", 1),
                                             ("adc.samples", v)],
    ("adc", "frame_ready"): lambda v, s: [("adc.convert_signal", 0), ("adc.frame", v)],
    ("memory", "write"): lambda v, s: [("memory.occupancy", v)],
    ("memory", "free"): lambda v, s: [("memory.occupancy", v)],
    ("memory", "overflow"): lambda v, s: [("memory.overflows", s["memory.overflows"] + 1),
                                          ("memory.dropped", v)],
    ("dsp", "job_start"): lambda v, s: [("dsp.busy", 1), ("dsp.job", 0 if s["dsp.job"] is None
                                                          else s["dsp.job"] + 1),
                                        ("dsp.job_frames", v)],
    ("dsp", "job_end"): lambda v, s: [("dsp.busy", 0), ("dsp.job_frames", 0)],
}


def read_vcd(text: str) -> tuple[dict, list[tuple[int, str, object]], dict]:
    """pyvcd's tokens: the header (timescale, comments, the last time stamp), the ``$dumpvars``
    values by signal path, and every later change as ``(time, signal path, value)`` in file
    order."""
    reader = require_module("vcd.reader")
    kind = reader.TokenKind
    scopes, names, header = [], {}, {"comments": []}
    initial, changes, t, dumping = {}, [], None, False
    for tok in reader.tokenize(io.BytesIO(text.encode())):
        k = tok.kind
        if k is kind.TIMESCALE:
            m = tok.data.magnitude  # an int, or an enum in older pyvcd
            header["timescale"] = (getattr(m, "value", m), tok.data.unit.value)
        elif k is kind.COMMENT:
            header["comments"].append(tok.data)
        elif k is kind.SCOPE:
            scopes.append(tok.data.ident)
        elif k is kind.UPSCOPE:
            scopes.pop()
        elif k is kind.VAR:
            names[tok.data.id_code] = ".".join([*scopes[1:], tok.data.reference])
            header.setdefault("vars", {})[names[tok.data.id_code]] = (tok.data.type_.value,
                                                                      tok.data.size)
        elif k is kind.DUMPVARS:
            dumping = True
        elif k is kind.END:
            dumping = False
        elif k is kind.CHANGE_TIME:
            t = header["end"] = tok.data
        elif k in (kind.CHANGE_SCALAR, kind.CHANGE_VECTOR, kind.CHANGE_REAL):
            value = _value(tok.data.value)
            if dumping:
                initial[names[tok.data.id_code]] = value
            else:
                changes.append((t, names[tok.data.id_code], value))
    return header, changes, initial


def _value(v):
    if isinstance(v, str):
        return None if v in ("x", "X") else int(v)
    return v  # int (a vector) or float (a real)


def replay(events, initial: dict) -> list[tuple[int, str, object]]:
    """The changes :data:`EXPECTED` says the events make, only those that change a value."""
    state, out = dict(initial), []
    for t, block, event, value in events:
        rule = EXPECTED.get((block, event))
        pairs = rule(int(value), state) if rule else [(f"{block}.{event}", float(value))]
        for name, new in pairs:
            if state[name] != new:
                state[name] = new
                out.append((t, name, new))
    return out


@pytest.fixture(scope="module")
def traced(tmp_path_factory):
    """The small scene's run and its output folder, chip.vcd included."""
    from chiptwin.report import write_outputs
    from tests.conftest import SMALL

    folder = tmp_path_factory.mktemp("vcd")
    (folder / "small.toml").write_text(SMALL)
    result = run(folder / "small.toml")
    return result, write_outputs(result, folder / "out", vcd=True)


def test_run_vcd_is_the_trace_event_for_event(traced):
    """Read back by pyvcd: 1 ns ticks, the four blocks' signals, initial values, and every
    change the trace's events make, at their ticks, in their order, and nothing else."""
    result, out = traced
    header, changes, initial = read_vcd((out / "chip.vcd").read_text())
    assert header["timescale"] == (1, "ns")
    assert header["vars"]["pixel.reset"] == ("wire", 1)
    assert header["vars"]["memory.occupancy"] == ("integer", 32)
    assert {p.split(".")[0] for p in header["vars"]} == {"pixel", "adc", "memory", "dsp"}
    assert initial["pixel.reset"] == 0 and initial["adc.frame"] is None
    assert any("seed 7" in c for c in header["comments"])
    events = result.trace.events
    assert changes == replay(events, initial)
    chip = result.summary["chip"]  # the dump ends with the run: the last frame's idle time
    assert header["end"] == chip["frames"] * round(chip["frame_period_s"] * 1e9) > events[-1][0]


def test_the_waveform_shows_each_frame_and_job(traced):
    """Counted on the waveform: a reset rise per frame, a readout per frame, the frame numbers
    in order, the DSP busy once per job, the memory's peak."""
    result, out = traced
    _, changes, _ = read_vcd((out / "chip.vcd").read_text())
    frames = result.summary["chip"]["frames"]
    rises = [t for t, name, v in changes if name == "pixel.reset" and v == 1]
    assert len(rises) == frames
    assert [v for _, name, v in changes if name == "adc.frame"] == list(range(frames))
    assert sum(1 for _, n, v in changes if n == "dsp.busy" and v == 1) == result.trace.count(
        "dsp", "job_start")
    peak = max(v for _, n, v in changes if n == "memory.occupancy")
    assert peak == result.summary["chip"]["memory_peak_frames"]


def test_a_dropped_frame_on_the_waveform(small_toml, tmp_path):
    """A full memory: each dropped frame steps memory.overflows and names itself in
    memory.dropped, and its write leaves memory.occupancy at the capacity."""
    result = run(small_toml, DROPS)
    path = tmp_path / "chip.vcd"
    result.trace.write_vcd(path)
    _, changes, initial = read_vcd(path.read_text())
    assert changes == replay(result.trace.events, initial)
    dropped = [v for _, n, v in changes if n == "memory.dropped"]
    assert dropped == sorted(dropped) and len(dropped) == result.summary["chip"]["overflows"] > 0
    assert [v for _, n, v in changes if n == "memory.overflows"] == list(
        range(1, len(dropped) + 1))
    capacity = result.summary["chip"]["memory_capacity_frames"]
    assert max(v for _, n, v in changes if n == "memory.occupancy") == capacity


def test_back_to_back_jobs_and_unnamed_events():
    """Two events at one tick that set one signal are both written (a zero-width glitch); an
    event the table does not name gets a real signal; time must not run backwards."""
    events = [(0, "dsp", "job_start", 4.0), (50, "dsp", "job_end", 4.0),
              (50, "dsp", "job_start", 4.0), (60, "dsp", "gain", 0.5), (90, "dsp", "job_end", 4)]
    header, changes, initial = read_vcd("\n".join(vcd_lines(events, frame_steps=False)) + "\n")
    assert header["vars"]["dsp.gain"] == ("real", 64)
    assert "pixel.reset" not in header["vars"]
    assert any("not recorded" in c for c in header["comments"])
    assert [c for c in changes if c[1] == "dsp.busy"] == [(0, "dsp.busy", 1), (50, "dsp.busy", 0),
                                                          (50, "dsp.busy", 1), (90, "dsp.busy", 0)]
    assert (60, "dsp.gain", 0.5) in changes and changes == replay(events, initial)
    with pytest.raises(ValueError, match="not in time order"):
        write_vcd([(5, "dsp", "job_start", 1), (4, "dsp", "job_end", 1)], Path("unused.vcd"))


def test_cli_run_vcd_writes_the_same_bytes(traced, small_toml, tmp_path):
    """``chiptwin run --vcd``: chip.vcd, byte for byte the API's for the same seed."""
    _, out = traced
    assert main(["run", str(small_toml), "--out", str(tmp_path / "cli"), "--vcd", "--quiet"]) == 0
    assert (tmp_path / "cli" / "chip.vcd").read_bytes() == (out / "chip.vcd").read_bytes()


def test_vcd_of_a_trace_without_frame_steps_exits_2(small_toml, tmp_path, monkeypatch, capsys):
    """A result whose trace lacks the frames' steps (a study's replicate) cannot show the
    pixel's states: --vcd exits 2 naming frame_steps, and writes nothing."""
    import chiptwin.fidelity
    from chiptwin.twin.runner import prepare, run_prepared

    def without_steps(s, progress=None):
        return run_prepared(s, prepare(s), frame_steps=False)

    monkeypatch.setattr(chiptwin.fidelity, "run", without_steps)
    out = tmp_path / "out"
    assert main(["run", str(small_toml), "--out", str(out), "--vcd", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--vcd" in err and "frame_steps=True" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
