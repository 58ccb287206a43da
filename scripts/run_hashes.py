"""SHA-256 of every bundled scenario's outputs: run it on two versions of the code and compare.

    PYTHONPATH=<checkout> python scripts/run_hashes.py > hashes.json
    python scripts/run_hashes.py --compare before.json after.json

Each bundled scenario, reduced as ``tests/conftest.py`` ``REDUCED`` says (the others as they
are), for seeds 7 and 8, at the float and the fixed DSP level (``chip.dsp.mode``; fixed also with
``chip.dsp.report_error``), run twice: by ``run()`` (the full trace) and as a study row
(:func:`chiptwin.twin.runner.run_prepared` with ``frame_steps=False``). Per run: the summary
without its timing keys, every array and the trace, each hashed; a run that raises hashes its
error. ``pyro_1fmol`` also at the ``expected`` and ``events`` photon levels and through
``simulate(keep_codes=True)`` (the kept ADC samples). Nothing but the public API of the
checkout on ``PYTHONPATH`` is used, so the same file runs on the code before and after a change.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TIMING = {"stage_time_s", "wall_time_s"}
SEEDS = (7, 8)
LEVELS = {
    "float": ["chip.dsp.mode=float"],
    "fixed": ["chip.dsp.mode=fixed"],
    "fixed+error": ["chip.dsp.mode=fixed", "chip.dsp.report_error=true"],
}
EXTRA = {  # pyro_1fmol only
    "expected": ["run.fidelity.photons=expected"],
    "events": ["run.fidelity.photons=events"],
}


def _reduced() -> dict[str, list[str]]:
    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import REDUCED

    return REDUCED


def _digest_arrays(arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for key in sorted(arrays):
        a = np.ascontiguousarray(arrays[key])
        h.update(f"{key}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes() if a.dtype != object else repr(a.tolist()).encode())
    return h.hexdigest()


def _digest_summary(summary: dict) -> str:
    kept = {k: v for k, v in summary.items() if k not in TIMING}
    text = json.dumps(kept, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _digest_result(result) -> dict[str, str]:
    return {"summary": _digest_summary(result.summary), "arrays": _digest_arrays(result.arrays),
            "trace": _digest_arrays(result.trace.to_arrays()),
            "events": str(len(result.trace))}


def _guarded(fn, *args) -> dict[str, str]:
    try:
        return fn(*args)
    except Exception as exc:  # the error is the outcome: it must be the same too
        return {"error": f"{type(exc).__name__}: {exc}"}


def _run(path: Path, overrides: list[str], seed: int) -> dict[str, str]:
    from chiptwin.config import load_scenario
    from chiptwin.fidelity import run

    return _digest_result(run(load_scenario(path, overrides), seed=seed))


def _row(path: Path, overrides: list[str], seed: int) -> dict[str, str]:
    from chiptwin.config import load_scenario
    from chiptwin.fidelity import resolve
    from chiptwin.twin.runner import prepare, run_prepared

    s, choice = resolve(load_scenario(path, overrides))
    s = replace(s, scenario=replace(s.scenario, seed=seed))
    return _digest_result(run_prepared(s, prepare(s), choice=choice, frame_steps=False))


def _kept(path: Path, overrides: list[str], seed: int) -> dict[str, str]:
    from chiptwin.config import load_scenario
    from chiptwin.fidelity import resolve
    from chiptwin.twin.runner import Recorder, prepare, simulate, stage_rng

    s, _ = resolve(load_scenario(path, overrides, seed))
    out = simulate(s, prepare(s), "binned", stage_rng(seed, "pixel"), Recorder(),
                   keep_codes=True)
    return {"kept": _digest_arrays({"kept": np.stack(out.dsp.kept)}),
            "value": _digest_arrays({"v": out.value_e, "m": out.mean_e, "var": out.var_e2})}


def compute() -> dict[str, dict[str, str]]:
    reduced = _reduced()
    out: dict[str, dict[str, str]] = {}
    for path in sorted((ROOT / "scenarios").glob("*.toml")):
        base = reduced.get(path.stem, [])
        variants = dict(LEVELS)
        if path.stem == "pyro_1fmol":
            variants.update(EXTRA)
        for label, over in variants.items():
            for seed in SEEDS:
                key = f"{path.stem}|{label}|{seed}"
                out[f"run|{key}"] = _guarded(_run, path, base + over, seed)
                out[f"row|{key}"] = _guarded(_row, path, base + over, seed)
                print(key, file=sys.stderr, flush=True)
        if path.stem == "pyro_1fmol":
            for seed in SEEDS:
                out[f"kept|{path.stem}|{seed}"] = _guarded(_kept, path, base, seed)
    return out


def compare(before: Path, after: Path) -> int:
    a, b = json.loads(before.read_text()), json.loads(after.read_text())
    differ = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
    errors = sorted(k for k, v in b.items() if "error" in v)
    for k in differ:
        print(f"DIFFER {k}\n  before {a.get(k)}\n  after  {b.get(k)}")
    print(f"{len(a)} runs before, {len(b)} after: {len(differ)} differ; "
          f"{len(errors)} raise (the same on both sides unless listed above)")
    return 1 if differ else 0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--compare", nargs=2, type=Path)
    args = ap.parse_args()
    if args.compare:
        return compare(*args.compare)
    json.dump(compute(), sys.stdout, indent=1, sort_keys=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
