"""The numbers the README and the docs quote, generated from the runs that make them.

    python scripts/answers.py             # run the cheap entries (scenes, frame_memory, lod_pyro)
                                          # at their documented seeds, write docs/answers.json,
                                          # rewrite every marked quote
    python scripts/answers.py --all       # also the expensive studies (5–40 min each)
    python scripts/answers.py --only pyro_long_read   # the entries of one scene or study
    python scripts/answers.py --rewrite   # rewrite the marked quotes from docs/answers.json only
    python scripts/answers.py --check     # exit 1 where a marked quote differs from answers.json

A quote is marked by an HTML comment right after its bold text, which GitHub and MyST render as
nothing: ``**264,192 bits**<!-- answer: frame_memory.least_bits -->``. Each answer is one
:class:`Entry` of :data:`ENTRIES`: its source (a bundled scene, run with ``chiptwin run NAME``, or
a bundled study, ``chiptwin study NAME``) at the seed the file states, the path of the figure in
its ``summary.json`` or ``study.json``, and its format; ``docs/answers.json`` keeps each value
with its source's run time and the machine. A run-time quote names the machine and the date;
``tests/docs/test_answers.py`` fails when a marked quote and answers.json disagree, or an entry
has no marker or a marker no entry, and reruns the scene entries (the same seed gives the same
bits).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
ANSWERS = ROOT / "docs" / "answers.json"
#: A marked quote: bold text, then the marker naming its entry.
MARK = re.compile(r"\*\*(?P<text>[^*\n]+?)\*\*<!-- answer: (?P<key>[\w.\-]+) -->")
#: Folders of generated pages (rewritten by each docs build), never scanned for markers.
SKIP = ("docs/_build", "docs/reference/generated")


def wall(v: float, e: dict[str, Any]) -> str:
    """A run time with its machine and date: ``1.2 s on a 2-core machine, 2026-11-29``; a
    machine busier than its cores says so (``… under load 9, …``): the time is an upper bound."""
    took = f"{v:.2g}" if v < 10 else f"{v:.0f}"
    cores, load = e["machine"]["cores"], e["machine"].get("load_average_1min")
    busy = f" under load {load:.0f}" if load is not None and load > cores else ""
    return f"{took} s on a {cores}-core machine{busy}, {e['date']}"


@dataclass(frozen=True)
class Entry:
    """One quoted number: ``key`` (``source.figure``), its source, where it sits in the
    source's output (a path of keys and list indices), and how it is written."""

    key: str
    kind: str  # "run" (a bundled scene: summary.json) or "study" (study.json)
    source: str
    path: tuple[str | int, ...]
    fmt: str | Callable[[Any, dict[str, Any]], str]  # a format of ``v``, or (value, entry) → text
    cheap: bool = True  # runs in minutes on 2 cores (the expensive ones: --all)

    def text(self, value: Any, record: dict[str, Any]) -> str:
        return self.fmt(value, record) if callable(self.fmt) else self.fmt.format(v=value)


def between(v: list, unit: str) -> str:
    """A budget the grid brackets: ``between 0.056 and 0.1 fmol`` (``at most 0.001 fmol``)."""
    def num(x: Any) -> str:
        return f"{x:,}" if isinstance(x, int) else f"{x:.2g}"

    return f"at most {num(v[1])} {unit}" if v[0] is None else \
        f"between {num(v[0])} and {num(v[1])} {unit}"


_MEM = ("answer", 0, "least", "chip.memory.capacity_bits")
_LOD = ("answer", 0, "least", "assay.dna_fmol")
_ARRAY = ("array",)
_SB = ("sensitivity", "results", 0)  # a sensitivity study's (only) section
_RL13 = ("answer", {"condition": "chip.adc.bits = 13"})  # read_length_pyro at 13 bits


def _ADC(comparator_uV: float) -> tuple:  # noqa: N802 (a path, read as a constant)
    """adc_bits_pyro's answer at 1 fmol and one comparator noise (µV)."""
    return ("answer", {"given": {"assay.dna_fmol": 1.0,
                                 "chip.adc.comparator_noise_uV": comparator_uV}}, "point")
#: Every quoted number. The expensive studies are registered and run with ``--all``.
ENTRIES: tuple[Entry, ...] = (
    Entry("pyro_1fmol.wall_time", "run", "pyro_1fmol", ("wall_time_s",), wall),
    Entry("pyro_long_read.q20_median", "run", "pyro_long_read",
          ("reads", "q20_read_length", "median"), "{v:.0f} bases"),
    Entry("pyro_long_read.rl99_median", "run", "pyro_long_read",
          ("reads", "read_length_99", "median"), "{v:.0f} bases"),
    Entry("pyro_long_read.rl99_min", "run", "pyro_long_read", ("reads", "read_length_99", "min"),
          "{v:.0f}"),
    Entry("pyro_long_read.accuracy", "run", "pyro_long_read", ("reads", "read_accuracy"),
          lambda v, e: f"{100 * v:.1f} %"),
    Entry("pyro_long_read.wall_time", "run", "pyro_long_read", ("wall_time_s",), wall),
    Entry("pyro_array_256.called", "run", "pyro_array_256", (*_ARRAY, "fraction_called_right"),
          lambda v, e: f"{100 * v:.1f} %"),
    Entry("pyro_array_256.snr_median", "run", "pyro_array_256",
          (*_ARRAY, "snr_power_percentiles", "p50"), "{v:.2g}"),
    Entry("pyro_array_256.wall_time", "run", "pyro_array_256", ("wall_time_s",), wall),
    Entry("frame_memory.least_bits", "study", "frame_memory", (*_MEM, "least"), "{v:,} bits"),
    Entry("frame_memory.grid", "study", "frame_memory", (*_MEM, "grid", "between"),
          lambda v, e: between(v, "bits")),
    Entry("lod_pyro.fmol", "study", "lod_pyro", (*_LOD, "between"),
          lambda v, e: between(v, "fmol")),
    Entry("lod_pyro.reads", "study", "lod_pyro", ("answer", 0, "bounds",
                                                  "calls_correct >= 0.99"),
          lambda v, e: f"{v['k']:,} of {v['trials']:,}"),
    # the expensive studies (4–40 min each on 2 cores): registered, run with --all
    Entry("sensitivity_bits.bits", "study", "sensitivity_bits", (*_SB, "reference", "value"),
          "{v} bits", cheap=False),
    Entry("sensitivity_bits.errors", "study", "sensitivity_bits",
          (*_SB, "reference", "bounds", "base_error_rate <= 0.001"),
          lambda v, e: f"{v['k']} errors in {v['trials']:,} bases", cheap=False),
    Entry("sensitivity_bits.loss", "study", "sensitivity_bits",
          (*_SB, "reference", "bounds", "snr_loss_db <= 0.5", "estimate"), "{v:.2f} dB",
          cheap=False),
    Entry("sensitivity_bits.decided_by", "study", "sensitivity_bits", (*_SB, "verdict"),
          lambda v, e: v.removeprefix("decided by "), cheap=False),
    Entry("sensitivity_bits.dnl", "study", "sensitivity_bits",
          (*_SB, "ranking", {"key": "chip.adc.dnl_rms_lsb"}),
          lambda v, e: f"a {v['range'][1]:g}-LSB DNL asks {v['high']['text']}", cheap=False),
    Entry("adc_bits_pyro.noiseless", "study", "adc_bits_pyro", (*_ADC(0.0), "chip.adc.bits"),
          "{v} bits", cheap=False),
    Entry("adc_bits_pyro.one_lsb", "study", "adc_bits_pyro", (*_ADC(122.07), "chip.adc.bits"),
          "{v}", cheap=False),
    Entry("sensitivity_lod.fmol", "study", "sensitivity_lod",
          ("answer", 0, "least", "assay.dna_fmol", "between"),
          lambda v, e: between(v, "fmol"), cheap=False),
    Entry("sensitivity_lod.decided_by", "study", "sensitivity_lod", (*_SB, "verdict"),
          lambda v, e: v.removeprefix("decided by "), cheap=False),
    Entry("read_length_pyro.least_13", "study", "read_length_pyro",
          (*_RL13, "least", "assay.dna_fmol", "between"), lambda v, e: between(v, "fmol"),
          cheap=False),
    Entry("read_length_pyro.q20_13", "study", "read_length_pyro",
          (*_RL13, "bounds", "q20_read_length >= 200"),
          lambda v, e: f"{v['estimate']:.1f} bases (one-sided 95 % lower bound {v['bound']:.0f})",
          cheap=False),
    Entry("read_length_pyro.q20_13_at_0.03", "study", "read_length_pyro",
          ("points", {"params": {"assay.dna_fmol": 0.03, "chip.adc.bits": 13}}, "metrics",
           "q20_read_length", "value"), "{v:.0f} bases", cheap=False),
    Entry("read_length_pyro.bits_10", "study", "read_length_pyro",
          ("answer", {"condition": "chip.adc.bits = 10"}, "statement"),
          lambda v, e: v.replace("at 95% confidence", "at 95 % confidence"), cheap=False),
    Entry("read_length_pyro.wall_time", "study", "read_length_pyro", ("wall_time_s",), wall,
          cheap=False),
)


def machine() -> dict[str, Any]:
    """What the run times were measured on: cores, the processor, the load when it started."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {"cores": os.cpu_count(), "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(), "load_average_1min": load}


def run_source(kind: str, name: str, folder: Path) -> tuple[dict[str, Any], float]:
    """Run a bundled scene or study at the seed its file states; its summary and wall time."""
    from chiptwin.cli import main

    out = folder / name
    t0 = time.perf_counter()
    args = ["run", name, "--out", str(out), "--quiet"] if kind == "run" else \
        ["study", name, "--out", str(out), "--quiet", "--fresh"]
    if main(args) != 0:
        raise SystemExit(f"answers.py: `chiptwin {' '.join(args[:2])}` failed")
    took = time.perf_counter() - t0
    return json.loads((out / ("summary.json" if kind == "run" else "study.json")).read_text()), \
        took


def dig(data: Any, path: tuple) -> Any:
    """Follow ``path``: a key, a list index, or ``{field: value}``: the list's first element
    whose fields equal those given."""
    for part in path:
        if isinstance(part, dict):
            data = next(x for x in data if all(x.get(k) == v for k, v in part.items()))
        else:
            data = data[part]
    return data


def generate(entries: list[Entry], old: dict[str, Any], keep: Path | None = None
             ) -> dict[str, Any]:
    """Run each source of ``entries`` once (its outputs in ``keep``/NAME, else thrown away);
    their records merged into ``old``'s."""
    records = dict(old.get("entries", {}))
    date = datetime.datetime.now(datetime.UTC).date().isoformat()
    sources = list(dict.fromkeys((e.kind, e.source) for e in entries))
    with tempfile.TemporaryDirectory(prefix="chiptwin-answers-") as tmp:
        tmp = keep or tmp
        for kind, name in sources:
            box = machine()
            print(f"answers.py: chiptwin {kind} {name} …", file=sys.stderr, flush=True)
            summary, took = run_source(kind, name, Path(tmp))
            for e in (e for e in entries if (e.kind, e.source) == (kind, name)):
                value = dig(summary, e.path)
                record = {"value": value, "source": f"chiptwin {kind} {name}",
                          "file": "summary.json" if kind == "run" else "study.json",
                          "path": list(e.path), "seed": summary.get("seed"),
                          "run_s": round(took, 2), "machine": box, "date": date,
                          "chiptwin_version": summary.get("chiptwin_version")}
                record["text"] = e.text(value, record)
                records[e.key] = record
    return {"about": "Quoted numbers of README.md and docs/, generated by scripts/answers.py; a "
                     "quote is marked **text**<!-- answer: KEY -->",
            "entries": {k: records[k] for k in sorted(records)}}


def refresh(answers: dict[str, Any]) -> dict[str, Any]:
    """Each recorded entry's text made again from its value by its registered format (a format
    changed needs no rerun)."""
    registered = {e.key: e for e in ENTRIES}
    for key, record in answers.get("entries", {}).items():
        if key in registered:
            record["text"] = registered[key].text(record["value"], record)
    return answers


def marked_files(root: Path = ROOT) -> list[Path]:
    """README.md and every docs page (generated pages aside)."""
    pages = [p for p in (root / "docs").rglob("*.md")
             if not any(p.relative_to(root).as_posix().startswith(s) for s in SKIP)]
    return [root / "README.md", *sorted(pages)]


def markers(root: Path = ROOT) -> list[tuple[Path, str, str]]:
    """Every marked quote: (file, key, the quoted text)."""
    return [(p, m["key"], m["text"]) for p in marked_files(root)
            for m in MARK.finditer(p.read_text(encoding="utf-8"))]


def rewrite(answers: dict[str, Any], root: Path = ROOT) -> list[str]:
    """Put each entry's text into its marked quotes; the files changed."""
    entries, changed = answers["entries"], []
    for p in marked_files(root):
        text = p.read_text(encoding="utf-8")
        new = MARK.sub(lambda m: f"**{entries[m['key']]['text']}**<!-- answer: {m['key']} -->"
                       if m["key"] in entries else m[0], text)
        if new != text:
            p.write_text(new, encoding="utf-8")
            changed.append(p.relative_to(root).as_posix())
    return changed


def problems(answers: dict[str, Any], root: Path = ROOT) -> list[str]:
    """Marked quotes that differ from answers.json, markers without an entry, entries without a
    marker."""
    entries, out = answers["entries"], []
    found = markers(root)
    for p, key, text in found:
        where = p.relative_to(root).as_posix()
        if key not in entries:
            out.append(f"{where}: marker {key!r} has no entry in docs/answers.json")
        elif text != entries[key]["text"]:
            out.append(f"{where}: {key} quotes {text!r}, answers.json has "
                       f"{entries[key]['text']!r} (python scripts/answers.py --rewrite)")
    out += [f"docs/answers.json: entry {k!r} is quoted nowhere (no marker)"
            for k in sorted(set(entries) - {k for _, k, _ in found})]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--all", action="store_true", help="also the expensive studies")
    ap.add_argument("--only", action="append", default=[], help="a source's entries only")
    ap.add_argument("--rewrite", action="store_true", help="rewrite from answers.json only")
    ap.add_argument("--check", action="store_true", help="compare only; exit 1 on a problem")
    ap.add_argument("--keep", type=Path, help="keep each run's outputs in KEEP/NAME")
    args = ap.parse_args(argv)
    old = json.loads(ANSWERS.read_text()) if ANSWERS.exists() else {"entries": {}}
    if args.check:
        bad = problems(old)
        print("\n".join(bad) or "answers.py: every marked quote matches docs/answers.json")
        return 1 if bad else 0
    answers = refresh(old)
    if not args.rewrite:
        chosen = [e for e in ENTRIES if (e.cheap or args.all)
                  and (not args.only or e.source in args.only)]
        answers = generate(chosen, old, args.keep)
    ANSWERS.write_text(json.dumps(answers, indent=1, ensure_ascii=False) + "\n")
    for name in rewrite(answers):
        print(f"answers.py: rewrote {name}")
    bad = problems(answers)
    print("\n".join(bad), file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
