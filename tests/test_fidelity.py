"""``auto`` fidelity: the level it picks keeps the run within the error budget of the
reference, its bounds are the physics they claim, and a scene where a cheap level is wrong gets
the faithful one."""

from __future__ import annotations

import functools
import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from chiptwin import pixel
from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.fidelity import gaussian_tv, resolve
from chiptwin.fidelity.compare import mean_difference, ratio_of_means
from chiptwin.fidelity.ladder import HARD_CASES, LEVELS, reference_levels, with_levels
from chiptwin.twin.runner import fidelity_used, prepare, run_prepared
from tests.conftest import PAPER_CHIP, REDUCED, SCENARIOS

ALL_AUTO = [f'run.fidelity.{stage}="auto"' for stage in LEVELS]


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    """Each test calibrates into its own database: no test sees another's cached errors."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


# -- the gaussian shot level's bound ---------------------------------------------------------

@pytest.mark.parametrize("lam", [3.0, 30.0])
def test_gaussian_shot_level_is_the_rounded_normal_at_the_tv_distance_computed(lam):
    """The run's kernel at ``shot_noise="gaussian"`` draws max(0, rint(λ + √λ z)): its empirical
    law, 400,000 counts read through an ideal ADC (1 e⁻ per code, no read or kTC noise), is the
    rounded normal (χ² test) and lies at :func:`gaussian_tv` from Poisson(λ) within the Monte
    Carlo error of an empirical TV distance (≈ √(bins / n), bound 4×)."""
    n = 400_000
    rng = np.random.default_rng(11)
    codes = pixel.binned_codes(
        rng, np.full((1, n), lam), full_well_e=1e9, ktc_e=0.0, read_noise_e=0.0, n_samples=1,
        true_cds=True, conversion_gain_uV_per_e=1.0, pedestal_V=0.0, bits=24, v_min_V=0.0,
        v_max_V=2**24 * 1e-6, shot_noise="gaussian")
    counts = codes[0, 1] - codes[0, 0]
    k = np.arange(counts.max() + 1)
    seen = np.bincount(counts, minlength=k.size) / n
    sd = math.sqrt(lam)
    rounded = stats.norm.cdf((k + 0.5 - lam) / sd) - np.where(
        k == 0, 0.0, stats.norm.cdf((k - 0.5 - lam) / sd))
    keep = rounded * n > 20
    chi2 = float(np.sum((seen[keep] - rounded[keep]) ** 2 * n / rounded[keep]))
    assert stats.chi2.sf(chi2, keep.sum() - 1) > 1e-4
    empirical_tv = 0.5 * np.sum(np.abs(seen - stats.poisson.pmf(k, lam)))
    assert abs(empirical_tv - gaussian_tv(lam)) < 4 * math.sqrt(keep.sum() / n) / 2


def test_gaussian_tv_falls_as_one_over_root_mean():
    """The normal misses the Poisson skewness 1/√λ: TV·√λ tends to a constant (≈ 0.126), and
    the published 0.0040 at λ = 1000 (``benchmarks/bench_sensor_chain.py``)."""
    scaled = [gaussian_tv(lam) * math.sqrt(lam) for lam in (1e3, 1e4, 1e5, 1e6, 1e8)]
    assert max(scaled) / min(scaled) < 1.02
    assert gaussian_tv(1000.0) == pytest.approx(0.0040, abs=5e-5)
    assert gaussian_tv(0.0) == 0.0 and gaussian_tv(1.0) > gaussian_tv(10.0) > gaussian_tv(100.0)


# -- the budget: malformed ones are refused ----------------------------------------------------

@pytest.mark.parametrize("sets, says", [
    (['run.fidelity.photons="auto"'], "needs [run] error_budget"),
    (['run.fidelity.photons="auto"', "run.error_budget.snr_relative=0.01"], "did you mean"),
    (['run.fidelity.photons="auto"', "run.error_budget.snr_rel=-0.01"], "must be a number in"),
    (['run.fidelity.photons="auto"', "run.error_budget.snr_rel=nan"], "finite"),
    (['run.fidelity.photons="auto"', "run.error_budget=0.01"], "must be a table"),
    (['run.fidelity.photons="auto"', 'run.error_budget.snr_rel="1%"'], "must be a number"),
    (['run.fidelity.photons="fast"', "run.error_budget.snr_rel=0.01"], "must be one of"),
])
def test_malformed_budget_exits_2_with_one_line(sets, says, tmp_path, capsys):
    args = ["run", str(SCENARIOS / "pyro_1fmol.toml"), "--out", str(tmp_path / "out")]
    for text in sets:
        args += ["--set", text]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and says in err
    assert not (tmp_path / "out").exists()


# -- every bundled scenario: auto is cheaper and within its budget ---------------------------

BUDGET = {"snr_rel": 0.05, "signal_rel": 0.03, "flow_value_abs": 0.05}

#: Each bundled scene made small for the budget check (:data:`tests.conftest.REDUCED`, and here
#: the scenes it leaves whole): the same stages, levels and decisions on fewer frames and pixels.
#: The calibrations, the reference and the auto runs each cost a fixed part per run (the optics
#: summary's stack quadrature, the cascade's yield fit), so what is cut is the part that grows.
SMALLER = {
    **REDUCED,
    # 8 key flows of 8 s (80 frames, not 336) on 2 rows × 40 columns (not 8 × 64), the wells
    # still 10 columns apart, binned into one profile, FIR and Wiener over it
    "ccd_two_wells": ["assay.flow_period_s=8.0", "run.duration_s=80.0", "chip.rows=2",
                      "chip.cols=40", "sites.at_pixels=[[1, 12], [1, 22]]"],
    # a site over each of 4 × 8 pixels (not 8 × 16), the Wiener equalizer over them
    "crosstalk_microarray": ["chip.rows=4", "chip.cols=8"],
    # pyro_1fmol's reduction (8 flows, 500 s) on the faceplate chip
    "jssc2006_faceplate": ["assay.n_flows=8", "run.duration_s=500.0"],
    # 10× the light: the levels draw independent streams, and 3 seeds resolve a systematic
    # difference only where a site sits far above its noise; as built (isotropic light, the
    # comparator's noise) these scenes' sites have power SNR 50–110 and 1–20
    "luciferase_label": ["assay.luciferase_amol=1.0"],
    # 16 flows of its 400 (1,000 s of frames, not 24,020) on 4 × 8 sites (not 8 × 16): the
    # phase-correcting caller, its long-read optics and noise; 97 s → the others' seconds
    "pyro_long_read": ["assay.n_flows=16", "run.duration_s=1000.0", "chip.rows=4",
                       "chip.cols=8"],
    "pyro_array_256": [*REDUCED["pyro_array_256"], "assay.dna_fmol=0.1"],
}


def _bundled():
    return sorted(p.stem for p in SCENARIOS.glob("*.toml"))


def _seeded(s, seed: int):
    return replace(s, scenario=replace(s.scenario, seed=seed))


@pytest.mark.parametrize("name", _bundled())
def test_auto_is_cheaper_than_the_reference_and_within_its_budget(name):
    """Every stage ``auto``: no level above the reference, at least one below it, and over 3
    seeds the figures' difference from the reference is not significantly over the budget: per
    site the ratio of the means minus 1 (signal, power SNR; :func:`chiptwin.fidelity.compare.
    ratio_of_means`, at the sites the reference sees with power SNR ≥ 100) and per flow the
    mean difference, each with its 95 % Student-t interval (the levels may draw differently,
    so the interval holds both levels' noise); the interval's low end is within the budget.

    One chip (``chip.fixed_pattern_seed`` pinned) and one prepared scene per side, shared by the
    seeds as a study's replicates share theirs: ``run_prepared`` on it is ``run()`` for the seed
    bit for bit (tests/test_run.py), and what a scene computes once (the optics summary's stack
    quadrature, ~1 s on the 150 µm stacks) is computed twice, not six times."""
    sets = ALL_AUTO + [f"run.error_budget.{f}={v}" for f, v in BUDGET.items()]
    s = load_scenario(SCENARIOS / f"{name}.toml",
                      sets + SMALLER.get(name, []) + ["chip.fixed_pattern_seed=7"])
    resolved, choice = resolve(s)
    # rtl is fixed bit for bit (tests/rtl); events reads binned's counts (test below)
    ref = {**reference_levels(s), "dsp": "fixed", "photons": "binned"}
    order = {st: LEVELS[st].index for st in LEVELS}
    most = reference_levels(s)
    assert all(order[st](choice.levels[st]) <= order[st](most[st]) for st in LEVELS)
    assert any(order[st](choice.levels[st]) < order[st](most[st]) for st in LEVELS)
    assert all(choice.estimate[f] <= b for f, b in BUDGET.items())
    reference = with_levels(s, ref)
    scenes = prepare(resolved), prepare(reference)
    vals = {"signal": ([], []), "snr": ([], []), "flow": ([], [])}
    seen = None
    for seed in range(3):
        a = run_prepared(_seeded(resolved, seed), scenes[0], choice=choice).summary
        r = run_prepared(_seeded(reference, seed), scenes[1]).summary
        # relative errors of sites the reference sees (power SNR ≥ 100); a blank's is noise
        seen = seen or [i for i, y in enumerate(r["sites"]) if y["snr_power"] >= 100]
        for key, out in (("signal_e", "signal"), ("snr_power", "snr")):
            vals[out][0].append([a["sites"][i][key] for i in seen])
            vals[out][1].append([r["sites"][i][key] for i in seen])
        if "flows" in r:
            vals["flow"][0].append([x["value"] - y["value"]
                                    for x, y in zip(a["flows"], r["flows"], strict=True)])
    for figure, budget in (("signal", BUDGET["signal_rel"]), ("snr", BUDGET["snr_rel"]),
                           ("flow", BUDGET["flow_value_abs"])):
        x, y = (np.array(v) for v in vals[figure])
        if x.size == 0:
            continue
        diffs = (ratio_of_means(x, y) if figure != "flow" else
                 [mean_difference(x[:, j]) for j in range(x.shape[1])])
        assert all(abs(d.value) - d.half <= budget for d in np.ravel(diffs)), (figure, diffs)
    assert a["fidelity"] == fidelity_used(resolved)
    assert set(a["fidelity_reason"]) == set(LEVELS)
    assert all(a["fidelity_error_estimate"][f] <= b for f, b in BUDGET.items())


def test_binned_counts_are_the_events_levels():
    """auto charges binned nothing against events: the events level draws binned's counts (and
    times the wells' filling from them), so on one chip of luciferase_label every seed's site
    signals are the same at both levels; over 16 seeds their spread is the noise model's
    ``signal_sd_e`` (χ², 15 degrees of freedom, inside its 0.1 %–99.9 % range). The run is cut
    to 16 s of light (36 frames, not 52). Each level's scene is prepared once and shared by its
    seeds (one chip: ``run_prepared`` is ``run()`` bit for bit, tests/test_run.py)."""
    s = load_scenario(SCENARIOS / "luciferase_label.toml", ["chip.fixed_pattern_seed=5",
                                                             "run.duration_s=36.0"])
    n = 16
    signals, sd = {}, None
    for level, seeds in (("binned", range(n)), ("events", range(3))):
        sv = with_levels(s, {"photons": level})
        scene = prepare(sv)
        runs = [run_prepared(_seeded(sv, seed), scene).summary["sites"] for seed in seeds]
        signals[level] = np.array([[site["signal_e"] for site in sites] for sites in runs])
        sd = np.array([site["signal_sd_e"] for site in runs[0]])
    b, e = signals["binned"], signals["events"]
    assert np.array_equal(b[:3], e)
    lo, hi = stats.chi2.ppf([0.001, 0.999], n - 1)
    chi2 = (n - 1) * b.var(axis=0, ddof=1) / sd**2
    assert np.all((chi2 > lo) & (chi2 < hi)), chi2


# -- hard cases: the cheap level is wrong, and auto refuses it -------------------------------

def _choice(name: str, sets: list[str] | tuple[str, ...]):
    return _resolved_choice(name, tuple(sets))


@functools.cache
def _resolved_choice(name: str, sets: tuple[str, ...]):
    """The choice for a scene, resolved once in this module: a hard case's calibration runs the
    same in each test that reads it (each calibrates into an empty database; the expected-level
    runs draw nothing), so its refusal and its reasons are computed once, not twice."""
    s = load_scenario(SCENARIOS / f"{name}.toml", list(sets))
    return resolve(s)[1]


@pytest.mark.parametrize("case", sorted(HARD_CASES))
def test_auto_refuses_the_cheap_level_of_each_hard_case(case):
    """Each hard case (:data:`chiptwin.fidelity.ladder.HARD_CASES`): with its budget, auto keeps a
    level above the cheap one, and says why it refused the cheap one."""
    hc = HARD_CASES[case]
    budget = [f"run.error_budget.{f}={v}" for f, v in hc.budget.items()]
    choice = _choice(hc.scenario, [*hc.overrides, f'run.fidelity.{hc.stage}="auto"', *budget])
    assert choice.levels[hc.stage] != hc.cheap, choice.reasons[hc.stage]
    assert f"not {hc.cheap}" in choice.reasons[hc.stage]


def test_the_hard_cases_measure_what_they_claim():
    """The refusals are the physics each case names, and the same scenes without the hard
    part take the cheap level."""
    def reason(case: str) -> str:
        hc = HARD_CASES[case]
        budget = [f"run.error_budget.{f}={v}" for f, v in hc.budget.items()]
        return _choice(hc.scenario, [*hc.overrides, f'run.fidelity.{hc.stage}="auto"',
                                     *budget]).reasons[hc.stage]

    assert "mean within 0.023 e⁻" in reason("dim_shot")
    flow_error = float(reason("homopolymer_5mer").split("flow_value_abs ")[-1].split()[0])
    assert 0.015 < flow_error < 0.03
    assert "wrap" in reason("narrow_accumulator")
    assert "psf cross-talk at the site pixels" in reason("dense_na2")
    # pyro_1fmol's optics at its reference level: its psf level is charged the traced
    # reference's own 1 % standard error (2 % of power SNR), more than these budgets
    traced = 'run.fidelity.optics="raytrace"'
    easy = {  # the cheap level fits once the hard part is gone
        "shot": ("pyro_1fmol", ["assay.n_flows=8", "run.duration_s=500.0", traced]),
        "kinetics": ("pyro_1fmol", ['assay.template="TCAGTCAG"', "assay.n_flows=9",
                                    "run.duration_s=560.0", traced]),
        "dsp": ("pyro_1fmol", ['chip.dsp.mode="fixed"', "assay.n_flows=8",
                               "run.duration_s=500.0", traced]),
        # sites ≥ 2 pitches apart, 15 µm up, under the paper's convention with no top
        "optics": ("atp_glow", PAPER_CHIP),
    }
    for stage, (name, sets) in easy.items():
        hc = next(h for h in HARD_CASES.values() if h.stage == stage)
        budget = [f"run.error_budget.{f}={v}" for f, v in hc.budget.items()]
        assert _choice(name, [*sets, f'run.fidelity.{stage}="auto"', *budget]
                       ).levels[stage] == hc.cheap


def test_calibration_is_cached_per_scene(tmp_path):
    """The second resolve of the same scene reads every estimate (the kinetics calibration
    among them) from the database; another seed is the same scene, another amount is not."""
    sets = ['run.fidelity.kinetics="auto"', "run.error_budget.snr_rel=0.01", "assay.n_flows=8",
            "run.duration_s=500.0", 'run.fidelity.optics="raytrace"']  # psf would spend 0.02
    db = tmp_path / "fid.sqlite"
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", sets)
    first = resolve(s, db)[1]
    assert first.calibration_s > 0 and not first.cached
    again = resolve(load_scenario(SCENARIOS / "pyro_1fmol.toml", sets, seed=99), db)[1]
    assert "kinetics" in again.cached and again.estimate == first.estimate
    assert again.reasons["kinetics"] == first.reasons["kinetics"].replace(" →", " (cached) →", 1)
    other = resolve(load_scenario(SCENARIOS / "pyro_1fmol.toml", sets + ["assay.dna_fmol=0.5"]),
                    db)[1]
    assert "kinetics" not in other.cached


def test_validate_prints_the_pick_without_writing(tmp_path, capsys):
    args = ["validate", str(SCENARIOS / "atp_glow.toml"), "--set", 'run.fidelity.optics="auto"',
            "--set", "run.error_budget.snr_rel=0.01"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert 'fidelity "auto"' in out and "optics" in out and "snr_rel" in out


def test_a_study_resolves_auto_once_per_point_and_runs_the_level_it_picks(tmp_path):
    """A study over the small scenario with photons left to auto: each point runs at the level
    auto picks for that point (the 10-bit point and the 14-bit reference may differ), row for
    row the rows of the same study with that level written in."""
    from chiptwin.study import run_study
    from tests.study.conftest import STUDY, write_study

    one_point = STUDY.replace("values = [6, 8, 10]", "values = [10]")

    def table(folder: str, sets: str) -> list[dict]:
        text = one_point.replace('reference = { "chip.adc.bits" = 14 }',
                                 'reference = { "chip.adc.bits" = 14 }\nset = { ' + sets + " }")
        (tmp_path / folder).mkdir()
        rows = run_study(write_study(tmp_path / folder, text), workers=1).table
        assert {r["status"] for r in rows} == {"ok"}
        return sorted(rows, key=lambda r: (r["point"], r["kind"], r["replicate"]))

    auto = table("auto", '"run.fidelity.photons" = "auto", "run.error_budget.snr_rel" = 0.05')
    for kind, bits in (("point", 10), ("reference", 14)):
        s = load_scenario(tmp_path / "auto" / "small.toml",
                          ['run.fidelity.photons="auto"', "run.error_budget.snr_rel=0.05",
                           f"chip.adc.bits={bits}"])
        picked = resolve(s)[1].levels["photons"]
        assert picked != "events"  # the reference level; binned has its law at no cost
        same = table(f"{kind}_{picked}", f'"run.fidelity.photons" = "{picked}"')
        assert [r["metrics"] for r in auto if r["kind"] == kind] == [
            r["metrics"] for r in same if r["kind"] == kind]


def test_a_run_with_auto_says_why_in_summary_and_report(tmp_path):
    out = tmp_path / "out"
    args = ["run", str(SCENARIOS / "pyro_1fmol.toml"), "--out", str(out), "--quiet"]
    for text in [*REDUCED["pyro_1fmol"], 'run.fidelity.photons="auto"',
                 "run.error_budget.snr_rel=0.01", 'run.fidelity.optics="raytrace"']:
        args += ["--set", text]
    assert main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fidelity"]["photons"] == "binned"
    # the converter as built: its moments at every pixel at the expected level, at the site
    # pixels where codes are drawn, so binned is tried first (warm: 0.68 s against 0.86 s)
    assert "tried by estimated time: binned" in summary["fidelity_reason"]["photons"]
    assert summary["fidelity_error_estimate"]["snr_rel"] <= 0.01
    assert "`auto` fidelity" in (out / "report.md").read_text()
