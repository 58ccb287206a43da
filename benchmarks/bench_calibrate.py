"""A calibration's cost: the bundled ``calibrate_emva_set001`` (five keys fitted to a real camera's
EMVA 1288 data set), from scratch, with its evaluations per stage and its wall time.

    python benchmarks/bench_calibrate.py [--workers 2] [--max-pixels 4096] [--generations 40]
                                         [--replay] [--quick]

``--replay``: first the seconds of one candidate (the twin read through the data set's protocol)
at several ``max_pixels``. ``--quick``: a light curve of the bundled ``atp_glow`` scene (its
kinetics at known values, 2 % noise from a seeded generator) fitted for two keys in one process
(the same fit, profile and store code path, no data set needed). Without the data set
(``$CHIPTWIN_DATA/emva1288/set001_ccd_12bit_crop128``) only ``--quick`` runs.

Measured: see the bundled study's opening comment (evaluations and wall time on 2 workers).

Numbers only; nothing is asserted (speed never lives in the tests).
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from chiptwin.cli import bundled_studies, resolve_scenario
from chiptwin.study import run_study
from chiptwin.study.spec import study_from_dict

LIGHT = """
[study]
name = "bench_light"
kind = "calibrate"
scenario = "{scenario}"
seed = 1
optimiser = {{ popsize = 6, generations = 8 }}

[[study.parameter]]
key = "assay.turnover_per_s"
range = [0.01, 1.0]
why = "glow to flash"

[[study.parameter]]
key = "assay.atp_fmol"
range = [1.0e-4, 1.0e-2]
why = "0.1 to 10 amol"

[study.target]
kind = "table"
path = "light.csv"
x = "time"
y = "light"
"""


def quick(folder: Path) -> None:
    """The light curve of atp_glow fitted for its turnover and its ATP amount."""
    from chiptwin.study.calibrate_eval import model_of, simulate

    scenario = resolve_scenario("atp_glow")
    times = np.linspace(21.0, 60.0, 14)
    (folder / "light.csv").write_text("time [s], light [photons/s]\n" + "".join(
        f"{float(t)!r}, 1.0\n" for t in times))
    text = LIGHT.format(scenario=scenario)
    study = study_from_dict(tomllib.loads(text), str(folder / "s.toml"), text, folder)
    truth = {"assay.turnover_per_s": 0.1, "assay.atp_fmol": 0.001}
    model = dataclasses.replace(model_of(study), x_values=tuple(times))
    light, _ = simulate(model, truth)
    se = 0.02 * light
    measured = light + se * np.random.default_rng(1).standard_normal(light.size)
    (folder / "light.csv").write_text("time [s], light [photons/s], light_se [photons/s]\n"
                                      + "".join(f"{float(t)!r}, {float(v)!r}, {float(s)!r}\n"
                                                for t, v, s in zip(times, measured, se,
                                                                   strict=True)))
    study = study_from_dict(tomllib.loads(text), str(folder / "s.toml"), text, folder)
    report(run_study(study, workers=1).summary)


def replay_cost(study, sizes: list[int]) -> None:
    """Seconds of one candidate at each ``max_pixels``."""
    from chiptwin.study.calibrate_eval import model_of, simulate

    model = model_of(study)
    params = {p.key: p.reference for p in study.calibration.parameters}
    for n in sizes:
        m = dataclasses.replace(model, max_pixels=n)
        simulate(m, params)  # warm (numba, caches)
        t0 = time.perf_counter()
        for _ in range(3):
            simulate(m, params)
        print(f"replay, max_pixels {n:>6}: {(time.perf_counter() - t0) / 3:.3f} s a candidate")


def report(s: dict) -> None:
    ev = s["evaluations"]
    print(f"evaluations {ev['total']} ({ev['computed']} computed): "
          + ", ".join(f"{k} {v}" for k, v in ev["by_stage"].items()))
    print(f"wall {s['wall_time_s']:.1f} s on {s['executor']['kind']} × "
          f"{s['executor']['workers']}; {ev['wall_s_mean']:.3f} s a candidate")
    for p in s["parameters"]:
        lo, hi = p["interval"]
        print(f"  {p['key']} = {p['value']:.5g} [{lo:.5g}, {hi:.5g}]"
              + (" open " + str(p["open"]) if any(p["open"]) else ""))
    o = s["objective"]
    print(f"  χ² {o['chi2_unscaled']:.5g} for {o['dof']} dof; scales "
          + ", ".join(f"{b['name']} {b['scale']:.3g}" for b in o["blocks"]))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--max-pixels", type=int)
    ap.add_argument("--generations", type=int)
    ap.add_argument("--replay", action="store_true")
    ap.add_argument("--quick", action="store_true", help="a light curve, one process")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.quick:
            quick(Path(tmp))
            return
        path = bundled_studies()["calibrate_emva_set001"]
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
        if args.max_pixels:
            raw["study"]["target"]["max_pixels"] = args.max_pixels
        if args.generations:
            raw["study"]["optimiser"]["generations"] = args.generations
        study = study_from_dict(raw, str(path), None, path.parent, resolve_scenario)
        if args.replay:
            replay_cost(study, [1024, 4096, 16384])
        t0 = time.perf_counter()
        result = run_study(study, workers=args.workers, db=Path(tmp) / "results.sqlite")
        print(f"calibrate_emva_set001: {time.perf_counter() - t0:.1f} s")
        report(result.summary)


if __name__ == "__main__":
    main()
