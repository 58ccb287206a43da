"""Mutations of the bundled studies, one key at a time.

The study-file twin of :mod:`tests.config._mutations`: every key of every bundled study
(``[study]``'s keys, each ``[[study.axis]]`` and ``[[study.metric]]`` entry, each key of the
``reference``, ``set`` and ``requirement`` tables, and the sections themselves) set to NaN, ±inf,
huge, negative, zero, wrong types, arrays and tables, or removed. A mutation is
``(study file, path, value)``; a path is a tuple of table keys and list indices.

``python -m tests.config._study_mutations`` validates every mutation as ``chiptwin validate``
does (the study file, then every point's scenario) and prints the counts by outcome.
"""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path
from typing import Any

from tests.config._mutations import GENERIC, MISSING, dumps

ROOT = Path(__file__).resolve().parents[2]
#: The bundled studies but the sensitivity ones: loading one of those checks every assumption's
#: two ends against the scene (consistency and the wall-time estimate: ≈ 35 ms a mutation, 2 min
#: for their ≈ 3,000), which tests/study/test_sensitivity.py covers case by case; nor the
#: calibrate ones: loading one reads its measured data set (absent where the data are not), and
#: tests/study/test_calibrate_spec.py refuses each of their keys' bad values case by case; nor the
#: optimize ones: their keys are not a budget study's (parameter, objective, constraint), and
#: tests/study/test_optimize_spec.py refuses each of their bad values case by case.
STUDY_FILES = sorted(p for p in (ROOT / "scenarios" / "studies").glob("*.toml")
                     if not p.stem.startswith(("sensitivity_", "calibrate_", "optimize_")))

#: The scenario-level values plus what a study key may wrongly hold: an empty array or table, a
#: list of tables, a nested table, the empty string, text that looks like a requirement.
VALUES: tuple[Any, ...] = (*GENERIC, [], [{}], {"a": {"b": 1}}, "", "<= nan", "<= 1e999",
                           [1, 1], [math.nan, 1.0], -0.0)

Path_ = tuple[str | int, ...]


def read(path: Path) -> dict[str, Any]:
    return tomllib.loads(path.read_text(encoding="utf-8"))


def paths_of(raw: dict[str, Any]) -> list[Path_]:
    """Every key of a study file: sections, entries of the arrays of tables, leaves."""
    out: list[Path_] = [("study",)]

    def walk(node: Any, prefix: Path_) -> None:
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for k, v in items:
            out.append((*prefix, k))
            if isinstance(v, dict) or (isinstance(v, list) and v and isinstance(v[0], dict)):
                walk(v, (*prefix, k))

    walk(raw["study"], ("study",))
    for optional in ("description", "reference", "set", "search", "stop_early", "batch", "verify",
                     "vary_chip"):  # keys a study may hold but these do not
        if optional not in raw["study"]:
            out.append(("study", optional))
    return out


def label(path: Path_, value: Any) -> str:
    key = ".".join(f"[{p}]" if isinstance(p, int) else str(p) for p in path).replace(".[", "[")
    return f"{key}=(missing)" if value is MISSING else f"{key}={value!r}"


def mutate(raw: dict[str, Any], path: Path_, value: Any) -> dict[str, Any]:
    """A deep copy of ``raw`` with ``path`` set to ``value`` (deleted for :data:`MISSING`)."""
    out = copy.deepcopy(raw)
    node: Any = out
    for p in path[:-1]:
        node = node[p]
    leaf = path[-1]
    if value is MISSING:
        del node[leaf]
    else:
        node[leaf] = copy.deepcopy(value)
    return out


def mutations(path: Path) -> list[tuple[Path, Path_, Any]]:
    raw = read(path)
    out = []
    for p in paths_of(raw):
        node: Any = raw
        for part in p[:-1]:
            node = node[part]
        present = (p[-1] in node) if isinstance(node, dict) else True
        for v in VALUES:
            if v is MISSING and not present:
                continue
            out.append((path, p, v))
    return out


def all_mutations() -> list[tuple[Path, Path_, Any]]:
    return [m for f in STUDY_FILES for m in mutations(f)]


_PARSED: dict[Path, dict[str, Any]] = {}


def write(tmp: Path, src: Path, path: Path_, value: Any) -> Path:
    """The mutated study beside a copy of nothing else: its scenario is named by bundled name
    or resolved from the bundled studies' folder, so the file is written into ``tmp``."""
    if src not in _PARSED:  # each bundled study parsed once (mutate copies before it edits)
        _PARSED[src] = read(src)
    raw = mutate(_PARSED[src], path, value)
    st = raw.get("study")
    if isinstance(st, dict) and isinstance(st.get("scenario"), str):
        candidate = src.parent / st["scenario"]
        if candidate.is_file():
            st["scenario"] = str(candidate)
    target = tmp / src.name
    # a new file, not the last one truncated: ext4 flushes a file truncated and rewritten
    # (auto_da_alloc), ≈ 3.5 ms a time on the test machine, ≈ 10 s over the sweep
    target.unlink(missing_ok=True)
    target.write_text(dumps(raw) + "\n", encoding="utf-8")
    return target


def validate(target: Path) -> tuple[int, str]:
    """``chiptwin validate`` in this process: (exit code, stderr)."""
    import contextlib
    import io

    from chiptwin.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(["validate", str(target)])
    return code, err.getvalue()


if __name__ == "__main__":  # the count for the closing note
    import collections
    import sys
    import tempfile

    counts: collections.Counter = collections.Counter()
    bad = []
    with tempfile.TemporaryDirectory() as d:
        for src, p, v in all_mutations():
            code, err = validate(write(Path(d), src, p, v))
            counts[code] += 1
            if code not in (0, 2):
                bad.append((src.name, label(p, v), err.strip().splitlines()[-3:]))
    print(dict(counts), f"{sum(counts.values())} mutations of {len(STUDY_FILES)} studies")
    for b in bad:
        print(*b)
    sys.exit(1 if bad else 0)
