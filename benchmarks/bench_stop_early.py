"""A bundled grid study as a whole grid and with ``stop_early = true``, run in turn.

    python benchmarks/bench_stop_early.py [--study frame_memory] [--batch 2] [--repeat 2]
                                          [--bits LO HI] [--workers 2] [--quick]

Each repeat runs the whole grid, then the same study with ``stop_early = true`` (and ``batch``),
from scratch (no stored rows), side by side; prints the rows each stored, the rows saved, the
wall times and their ratio, and whether every answer and every point's status are the same.
``--bits LO HI`` narrows the first axis (``adc_bits_pyro``: ``--bits 13 16``, the answers'
range). ``--quick``: ``frame_memory`` with 2 replicates in looks of 1, one process, once (the
same code path, a smoke run).

Measured (2026-11-28, 2 workers, a 2-core machine shared with other jobs): ``frame_memory
--batch 2``: 72 rows of 120, the same answer and statuses, 14–17 s against 15–20 s (two pairs),
and 33–45 s against 42–54 s at a heavier load (time ratio 0.78–0.83); ``adc_bits_pyro --bits 13
16 --batch 10 --repeat 1`` (its references' 720 rows reused from an earlier run on both sides):
3,070 rows of 3,600, the same 8 answers and 40 statuses, 169 s against 262 s.

Numbers only; nothing is asserted (speed never lives in the tests).
"""

from __future__ import annotations

import argparse
import time
import tomllib

from chiptwin.cli import bundled_studies, resolve_scenario
from chiptwin.study import run_study
from chiptwin.study.spec import Study, study_from_dict


def bundled(name: str, edit: dict, bits: list[int] | None) -> Study:
    path = bundled_studies()[name]
    raw = tomllib.loads(path.read_text())
    raw["study"].update(edit)
    if bits:
        raw["study"]["axis"][0].update(range=bits, scale="int")
    return study_from_dict(raw, str(path), None, path.parent, resolve_scenario)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--study", default="frame_memory")
    ap.add_argument("--batch", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--bits", type=int, nargs=2, metavar=("LO", "HI"))
    ap.add_argument("--quick", action="store_true",
                    help="frame_memory, 2 replicates in looks of 1, one process, once")
    args = ap.parse_args()
    edit = {}
    if args.quick:
        args.study, args.batch, args.repeat, args.workers = "frame_memory", 1, 1, 1
        edit = {"replicates": 2}
    whole = bundled(args.study, edit, args.bits)
    early = bundled(args.study, {**edit, "stop_early": True, "batch": args.batch}, args.bits)
    for i in range(args.repeat):
        t0 = time.perf_counter()
        a = run_study(whole, workers=args.workers)
        t1 = time.perf_counter()
        b = run_study(early, workers=args.workers)
        t2 = time.perf_counter()
        same = [x.get("point") for x in a.answer] == [x.get("point") for x in b.answer]
        statuses = [p["status"] for p in a.summary["points"]] == [
            p["status"] for p in b.summary["points"]]
        print(f"{args.study} #{i + 1}: whole grid {len(a.table)} rows {t1 - t0:.1f} s; "
              f"stop_early (batch {args.batch}) {len(b.table)} rows {t2 - t1:.1f} s "
              f"({b.summary['stop_early']['runs_saved']} saved, time ratio "
              f"{(t2 - t1) / (t1 - t0):.2f}); same answers {same}, same statuses {statuses}")


if __name__ == "__main__":
    main()
