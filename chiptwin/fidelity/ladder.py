"""The fidelity ladder of a scene: what each level costs and how wrong it is
(docs/background/speed-and-error.md).

The reference is the most faithful combination the scene allows (kinetics ``cascade`` for
pyrosequencing, photons ``events``, optics ``psf`` for contact imaging, DSP ``rtl`` when
Verilator is present, else ``fixed``). Each other level is run with the other stages at the
reference, one stage at a time, and so is the cheapest combination (closed_form, expected, na2,
float). For every row:

- wall time: the median of the replicates' warm ``run()`` times in this process (one warm-up
  run first, not counted), and the speed-up against the reference;
- the error of each headline figure against the reference, over replicates with the SAME
  seeds (common random numbers: the levels share the seed's named streams, so where two levels
  draw the same way their noise cancels in the difference). Relative figures are the ratio of
  the means over the seeds, per site, with a delta-method Student-t interval
  (:mod:`chiptwin.fidelity.compare`), never a mean of per-seed ratios (biased upward by the
  reference's squared coefficient of variation); the site shown is the one whose interval
  reaches furthest. Where the levels draw differently (``expected`` draws nothing; a Poisson
  count and the rounded normal; Poisson counts of moved means) the interval holds both
  levels' noise: the ``crn`` field of each row says which (:func:`common_draws`).

Figures (the relative ones over the sites whose mean power SNR in the reference is ≥ 10):
``signal_rel``, ``noise_rel`` and ``snr_rel`` (power SNR S²/N²) as ratios of means, and
``snr_db`` from the same ratio; ``flow_value_abs`` (normalised flow values), ``calls_diff``
(share of reads that differ from the reference's), ``dsp_lsb`` (DSP outputs at the site
pixels, in ADC LSB): per-seed largest differences, their mean with a Student-t interval. Each
carries ``resolved``: the relative figures' 95 % half-width is at most
:data:`chiptwin.fidelity.compare.RESOLUTION` (0.1 %), the others' at most a quarter of the
value; an unresolved figure carries ``seeds_to_resolve`` and the table prints that instead of
a number.

The ``shortcut`` row runs the reference's levels at ``binned`` photons with the carried-dark-pixels
shortcut (:mod:`chiptwin.twin.shortcuts`). When the scene leaves stages to ``auto`` (with ``[run]
error_budget``), the levels it picks are one more row, ``auto``, with its own error estimate
beside the measured one, and ``bound``: per budgeted figure whether the measurement shows
the estimate bounds it (``holds``), shows it does not (``exceeds``) or cannot tell at this seed
count (``unresolved``, with the seeds that would decide).
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from chiptwin.config import Scenario, ScenarioError
from chiptwin.config.consistency import check_consistency
from chiptwin.fidelity.auto import resolve, run
from chiptwin.fidelity.compare import RESOLUTION, mean_difference, ratio_of_means, worst
from chiptwin.twin import shortcuts
from chiptwin.twin.figures import save_figure
from chiptwin.twin.levels import (
    LEVELS,
    SEEN_SNR_POWER,
    figure_errors,
    figures,
    reference_levels,
    with_levels,
)
from chiptwin.twin.runner import chip_sensor


def common_draws(a: dict[str, str], b: dict[str, str]) -> bool:
    """Whether runs of one seed at levels ``a`` and ``b`` share every draw (common random
    numbers), so that their noise cancels in the difference.

    The kTC, read-noise and comparator normals have a stream of their own
    (:func:`chiptwin.pixel.binned_codes`' ``normal_rng``), the same whatever the counts drew;
    the DSP and converter levels read the same codes. The ``binned`` and ``events`` levels draw
    the same counts (the events level only times the wells' filling from them). The counts are
    common when both levels draw them the same way: the same shot level and the same light, or
    the same light's means changed under the ``gaussian`` shot level (one normal a pixel-frame,
    ``rint(λ + √λ·z)``: the same ``z`` whatever ``λ``). Not under ``poisson`` (NumPy's Poisson
    draws of other means from one stream are not coupled: on atp_glow na2 against psf over 4
    seeds left a 1.8 % half-width on the signal), nor across shot levels (a Poisson count and
    the rounded normal). The ``expected`` level draws nothing. A coarse ADC re-rounds a moved
    mean: its quantization is common only where the light is.
    """
    sampled = ("binned", "events")
    if a["photons"] == b["photons"] == "expected":
        return True
    if a["photons"] not in sampled or b["photons"] not in sampled:
        return False
    same_light = a["kinetics"] == b["kinetics"] and a["optics"] == b["optics"]
    return a["shot"] == b["shot"] and (same_light or a["shot"] == "gaussian")


@dataclass(frozen=True)
class HardCase:
    """A scene where one stage's cheap level is wrong: ``chiptwin ladder SCENARIO --set ...``
    shows its error, and ``auto`` with ``budget`` must refuse it (``tests/test_fidelity.py``)."""

    scenario: str
    overrides: tuple[str, ...]
    stage: str
    cheap: str
    budget: dict[str, float]
    why: str


#: The hard cases for ``auto``, each a bundled scenario with a few keys changed.
HARD_CASES: dict[str, HardCase] = {
    "dim_shot": HardCase(
        "ccd_100fmol", ("assay.n_flows=8", "run.duration_s=496.0",
                        'run.fidelity.kinetics="cascade"'), "shot", "gaussian",
        {"signal_rel": 0.001},
        "a cooled chip: the dimmest site pixel-frame holds ≈ 3 e⁻, where the rounded normal's "
        "clip at 0 lifts a count's mean by up to 0.023 e⁻: over a 60-frame window and its dark "
        "reference up to 0.25 % of the 1-mer signal"),
    "homopolymer_5mer": HardCase(
        "pyro_1fmol", ('assay.template="TCAGTTTTT"', "assay.n_flows=9", "run.duration_s=560.0"),
        "kinetics", "closed_form", {"flow_value_abs": 0.01},
        "a 5-mer saturates luciferase: the cascade's light comes later and lower, flow value "
        "5.024 against the closed form's 5.046"),
    "dense_na2": HardCase(
        "crosstalk_microarray", ('chip.dsp.program=["cms", "dark", "background", "average"]',),
        "optics", "na2", {"signal_rel": 0.01},
        "a site above every pixel, 150 µm up: the psf spreads each site's light over its "
        "neighbours, which na2 (own diode only) misses"),
    "narrow_accumulator": HardCase(
        "pyro_1fmol", ('chip.dsp.mode="fixed"', "chip.dsp.acc_bits=12", "assay.n_flows=8",
                       "run.duration_s=500.0"),
        "dsp", "float", {"snr_rel": 0.01},
        "a 12-bit N-frame accumulator wraps: fixed differs from float without bound"),
}


@dataclass
class Rung:
    """One row of the ladder."""

    stage: str  # "reference", a stage name, "cheapest" or "auto"
    level: str  # "kinetics=…, photons=…, …" for the combinations
    fidelity: dict[str, str]
    wall_s: float = math.nan
    speedup: float = math.nan
    errors: dict[str, dict[str, Any]] = field(default_factory=dict)
    crn: bool = True
    skipped: str = ""
    estimate: dict[str, float | None] | None = None  # auto's estimated errors
    bound: dict[str, dict[str, Any]] | None = None  # does the estimate bound the measurement
    carry_dark: bool = False  # the carried-dark-pixels shortcut (chiptwin.twin.shortcuts)


def _label(levels: dict[str, str]) -> str:
    return ", ".join(f"{k}={v}" for k, v in levels.items())


def plan(s: Scenario, reference: dict[str, str] | None = None) -> list[Rung]:
    """The reference, each stage's other levels one at a time, and the cheapest combination;
    levels the scene refuses are kept as skipped rows with the reason. ``reference`` pins the
    reference's levels (default: the most faithful the scene accepts)."""
    ref = {**reference_levels(s), **(reference or {})}
    rungs = [Rung("reference", _label(ref), ref)]
    for stage, levels in LEVELS.items():
        for level in levels:
            if level == ref[stage] or (stage == "adc" and not s.chip.adc.as_built_keys):
                continue  # an ideal converter: its two levels are one converter
            swapped = {**ref, stage: level}
            rungs.append(Rung(stage, level, swapped, crn=common_draws(swapped, ref)))
    cheapest = {stage: levels[0] for stage, levels in LEVELS.items()}
    rungs.append(Rung("cheapest", _label(cheapest), cheapest,
                      crn=common_draws(cheapest, ref)))
    binned = {**ref, "photons": "binned"}  # the shortcut that skips the dark pixels' draws
    rungs.append(Rung("shortcut", "carry_dark_pixels (photons=binned)", binned, crn=False,
                      carry_dark=True))
    if not shortcuts.applies(with_levels(s, binned), "binned", np.zeros(1), False, False):
        rungs[-1].skipped = ("the shortcut needs the default DSP program and no rtl, acc_bits "
                             "or report_error (chiptwin.twin.shortcuts)")
    if s.run.fidelity.auto_stages():  # the levels auto picks for the scene's budget
        choice = resolve(s)[1]
        rungs.append(Rung("auto", _label(choice.levels), choice.levels,
                          crn=common_draws(choice.levels, ref),
                          estimate=choice.summary()["fidelity_error_estimate"]))
    for r in rungs:
        try:
            check_consistency(with_levels(s, r.fidelity))
        except ScenarioError as exc:
            r.skipped = exc.allowed
        if r.stage == "shot" and r.fidelity["photons"] == "expected":
            r.skipped = "the expected photon level draws no counts: the shot level cannot matter"
    return rungs


def run_ladder(s: Scenario, replicates: int = 5, reference: dict[str, str] | None = None,
               progress=None) -> dict[str, Any]:
    """Run every rung of the ladder on ``replicates`` seeds; returns the ``ladder.json`` dict."""
    if not 2 <= replicates <= 1000:
        raise ScenarioError(s.source, "--replicates", replicates, "must be in [2, 1000]")
    seeds = [(s.scenario.seed + k) % 2**63 for k in range(replicates)]
    rungs = plan(s, reference)
    if rungs[0].skipped:
        raise ScenarioError(s.source, "reference", rungs[0].level, rungs[0].skipped)
    e_per_lsb = chip_sensor(s).e_per_lsb
    ref_figures: list[dict[str, np.ndarray]] = []
    for i, rung in enumerate(rungs):
        if rung.skipped:
            continue
        sv = with_levels(s, rung.fidelity)
        if rung.carry_dark:
            sv = replace(sv, run=replace(sv.run, carry_dark_pixels=True))
        run(sv)  # warm-up: compile and cache what this level needs
        walls, figs = [], []
        for seed in seeds:
            result = run(sv, seed=seed)
            walls.append(result.summary["wall_time_s"])
            figs.append(figures(result.summary, result.arrays, e_per_lsb))
        if rung.stage == "reference":
            ref_figures = figs
        rung.wall_s = statistics.median(walls)
        rung.errors = measured_errors(figs, ref_figures)
        if rung.estimate:
            rung.bound = _bounds(rung.errors, rung.estimate, rung.crn)
        if progress:
            progress(i + 1, len(rungs))
    ref_wall = rungs[0].wall_s
    for rung in rungs:
        rung.speedup = ref_wall / rung.wall_s if rung.wall_s > 0 else math.nan
    return {"scenario": s.scenario.name, "replicates": replicates, "seeds": seeds,
            "reference": rungs[0].fidelity,
            "method": "each level on the reference's seeds; relative figures: ratio of the "
                      "means over seeds per site (the site whose interval reaches furthest), "
                      "ci = delta-method Student-t half-width, 95 % over the sites together "
                      "(Bonferroni); other figures: mean of the "
                      "per-seed largest difference, 95 % Student-t; 'unresolved (n ≥ N)': the "
                      f"half-width exceeds {RESOLUTION:.1%} (relative) or a quarter of the "
                      "value, N seeds would resolve it; wall = median warm run()",
            "rows": [_row(r) for r in rungs]}


#: The figures compared as ratios of means (site by site), and the key of each in
#: :func:`chiptwin.twin.levels.figures`.
RATIO_FIGURES = {"signal_rel": "signal", "noise_rel": "noise", "snr_rel": "snr"}


def measured_errors(level: list[dict[str, np.ndarray]], ref: list[dict[str, np.ndarray]]
                    ) -> dict[str, dict[str, Any]]:
    """Each figure's error of a level's runs against the reference's on the same seeds (the
    ``errors`` of a ladder row; the module docstring says how each is estimated)."""
    seen = np.mean([f["snr"] for f in ref], axis=0) >= SEEN_SNR_POWER
    out: dict[str, dict[str, Any]] = {}
    for name, key in RATIO_FIGURES.items():
        x = np.array([f[key][seen] for f in level])
        y = np.array([f[key][seen] for f in ref])
        d = worst(ratio_of_means(x, y, family=True)) if x.size else None
        out[name] = (d.as_dict(RESOLUTION) if d is not None else
                     {"value": None, "ci": None, "note": "no site detected, or not finite"})
    snr = out["snr_rel"]
    if snr["value"] is not None and snr["signed"] > -1:
        scale = 10 / math.log(10)
        ci = None if snr["ci"] is None else scale * snr["ci"] / (1 + snr["signed"])
        out["snr_db"] = {**snr, "value": abs(scale * math.log1p(snr["signed"])), "ci": ci,
                         "signed": scale * math.log1p(snr["signed"])}
        out["snr_db"]["resolved"] = ci is not None and ci <= scale * RESOLUTION
    else:
        out["snr_db"] = {"value": None, "ci": None, "note": "no site detected, or not finite"}
    per_seed = [figure_errors(a, b) for a, b in zip(level, ref, strict=True)]
    for name in (n for n in per_seed[0] if n not in out):
        vals = np.array([e[name] for e in per_seed])
        if not np.all(np.isfinite(vals)):
            out[name] = {"value": None, "ci": None, "note": "not finite in some replicates"}
            continue
        d = mean_difference(vals)
        out[name] = d.as_dict(max(0.25 * abs(d.value), 0.0))
    return out


def _bounds(errors: dict[str, dict[str, Any]], estimate: dict[str, float | None], crn: bool
            ) -> dict[str, dict[str, Any]]:
    """Per budgeted figure, whether the measured error shows auto's estimate bounds it. The
    per-seed largest differences (DSP outputs, flow values) of levels that draw unlike the
    reference are both levels' noise, not the distance between their laws the estimate bounds:
    no verdict there."""
    from chiptwin.fidelity.compare import Difference

    out = {}
    for name, est in estimate.items():
        e = errors.get(name)
        if est is None or not e or e.get("value") is None:
            continue
        if not crn and name not in (*RATIO_FIGURES, "snr_db"):
            out[name] = {"estimate": est, "verdict": "not compared (draws differ)",
                         "seeds_to_decide": None}
            continue
        d = Difference(e["signed"], math.inf if e["ci"] is None else e["ci"], e["n"],
                       e["method"], e.get("confidence", 0.95))
        out[name] = {"estimate": est, "verdict": d.bounded_by(est),
                     "seeds_to_decide": d.seeds_to_decide(est)}
    return out


def _row(r: Rung) -> dict[str, Any]:
    row = {"stage": r.stage, "level": r.level, "fidelity": r.fidelity, "crn": r.crn}
    if r.estimate is not None:
        row["estimate"] = r.estimate
    if r.bound is not None:
        row["bound"] = r.bound
    if r.skipped:
        return {**row, "skipped": r.skipped}
    return {**row, "wall_s": r.wall_s, "speedup": r.speedup, "errors": r.errors}


def pareto(rows: list[dict], figure: str) -> list[int]:
    """Indices of the rows no other row beats in both wall time and ``figure``'s error."""
    pts = [(i, r["wall_s"], r["errors"][figure]["value"]) for i, r in enumerate(rows)
           if "errors" in r and r["errors"].get(figure, {}).get("value") is not None]
    front, best = [], math.inf
    for i, _, err in sorted(pts, key=lambda p: (p[1], p[2])):
        if err < best:
            front.append(i)
            best = err
    return front


def table(ladder: dict[str, Any]) -> str:
    """The ladder as a plain-text table (the terminal and ladder.md)."""
    names = list(dict.fromkeys(k for r in ladder["rows"] for k in r.get("errors", {})))
    head = f"{'stage':10s} {'level':34s} {'wall s':>8s} {'speed-up':>8s}  " + "  ".join(
        f"{n:>17s}" for n in names)
    lines = [head, "-" * len(head)]
    for r in ladder["rows"]:
        level = r["level"] if len(r["level"]) <= 34 else r["level"][:31] + "..."
        if "skipped" in r:
            lines.append(f"{r['stage']:10s} {level:34s} skipped: {r['skipped']}")
            continue
        cells = []
        for n in names:
            e = r["errors"].get(n)
            if not e or e["value"] is None:
                cells.append(f"{'–':>17s}")
            elif not e.get("resolved", True):
                need = e.get("seeds_to_resolve")
                cells.append(f"{'unres. n≥' + (str(need) if need else '?'):>17s}")
            else:
                ci = f"±{e['ci']:.2g}" if e["ci"] is not None else ""
                cells.append(f"{e['value']:>9.3g}{ci:>8s}")
        mark = "" if r["crn"] else " *"
        lines.append(f"{r['stage']:10s} {level:34s} {r['wall_s']:8.3f} {r['speedup']:8.2f}  "
                     + "  ".join(cells) + mark)
    lines.append("* draws differ from the reference's: the interval holds both levels' noise")
    lines.append("unres. n≥N: unresolved at this seed count; about N seeds would resolve it")
    for r in ladder["rows"]:
        if "estimate" in r:
            lines.append(f"auto's own estimate of its error: {r['estimate']}")
        for name, b in r.get("bound", {}).items():
            more = (f" (≈ {b['seeds_to_decide']} seeds would decide at this mean)"
                    if b["verdict"] == "unresolved" else "")
            lines.append(f"  {name}: estimate {b['estimate']:.3g} against the measured: "
                         f"{b['verdict']}{more}")
    return "\n".join(lines)


def write_ladder(ladder: dict[str, Any], out_dir) -> None:
    """``ladder.json``, ``ladder.png`` (error against wall time, log axes, Pareto front) and
    ``ladder.md`` into ``out_dir``, replacing a previous ladder whole."""
    import json

    from chiptwin.config.outputs import check_out_dir, replacing

    out = check_out_dir(out_dir, marker="ladder.json")
    with replacing(out) as tmp:
        (tmp / "ladder.json").write_text(json.dumps(ladder, indent=1) + "\n")
        figure = "snr_rel"
        _plot(ladder, figure, tmp / "ladder.png")
        (tmp / "ladder.md").write_text(
            f"# Fidelity ladder: {ladder['scenario']}\n\n{ladder['method']}; "
            f"{ladder['replicates']} replicates.\n\n```\n{table(ladder)}\n```\n\n"
            f"![{figure} against wall time](ladder.png)\n")


def _plot(ladder: dict[str, Any], figure: str, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = ladder["rows"]
    fig, ax = plt.subplots(figsize=(7, 4))
    floor = 1e-6  # the reference's own error is 0: drawn at the floor of the log axis
    for r in rows:
        e = r.get("errors", {}).get(figure)
        if not e or e["value"] is None:
            continue
        y = max(e["value"], floor)
        ax.errorbar(r["wall_s"], y, yerr=e["ci"] or 0.0, fmt="o", capsize=3)
        ax.annotate(f"{r['stage']}: {r['level']}"[:40], (r["wall_s"], y), fontsize=6,
                    xytext=(4, 4), textcoords="offset points")
    front = [rows[i] for i in pareto(rows, figure)]
    ax.plot([r["wall_s"] for r in front],
            [max(r["errors"][figure]["value"], floor) for r in front], "k--", lw=0.8,
            label="Pareto front")
    ax.set(xscale="log", yscale="log", xlabel="wall time per run (s, warm median)",
           ylabel=f"{figure} against the reference", title=f"Speed against error: "
           f"{ladder['scenario']}")
    ax.legend(fontsize=7)
    save_figure(fig, path.parent, path.name)
