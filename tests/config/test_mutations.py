"""Mutated bundled scenarios exit 0 or 2 with one line and nothing written, never a traceback.

Every key of every bundled scenario is set, one at a time, to NaN, ±inf, −1, 0,
1e±300, 2^63, wrong types, the ends of its declared range (and just past them), or removed
(:mod:`tests.config._mutations`). Three tests:

* a sweep of every key × those values through the loader that ``validate``, ``run`` and studies
  share (:func:`chiptwin.config.scenario_from_dict`): a :class:`ScenarioError` or a scenario,
  never another exception;
* a hypothesis test that mutates one to three keys with those values or drawn ones (any float,
  huge integers, text) and goes through ``chiptwin.cli.main`` in-process: ``validate`` exits 0
  or 2, with exactly one stderr line on 2;
* a hypothesis test that runs the valid ones, shortened to a few flows of at most
  ``RUN_FRAMES`` frames in all (``_mutations.shorten``: fewer N-frame blocks per flow where 8
  flows are still longer, as pyro_paper_yield_fast's 128 frames/s), with ``run --out``: exit 0
  writes the outputs, exit 2 one line and nothing.

Plus the exact crashes the issue lists, each value named there, so that they stay fixed.
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from chiptwin.cli import main
from chiptwin.config import ScenarioError, cost, load_scenario, scenario_from_dict
from tests.config import _mutations as M
from tests.conftest import REDUCED

SCENARIOS = {p.stem: p for p in M.SCENARIO_FILES}
RAW = {name: M.read(path) for name, path in SCENARIOS.items()}
KEYS = {name: M.keys_of(raw) for name, raw in RAW.items()}

#: The sweep lists at most this many sites of a scenario (pyro_array_256 lists 4,096: checking
#: each of them 1,400 times is a minute, and the site list is mutated as a whole anyway).
SWEEP_SITES = 64

#: A valid mutation is run when its shortened run is at most this big (the test's time budget):
#: every scenario but pyro_array_256 fits, pyro_paper_yield_fast with one 1 s block per flow
#: (1,280 frames) and ccd_two_wells's 512 pixels with 336 frames. A run's cost is mostly fixed
#: (plots, the optics summary); what grows with its pixel-frames is the converter as built
#: (its expected moments: ≈ 1.4 µs a pixel-frame by the series, tens of µs by Gauss–Hermite
#: with a wide white noise near code 0), which the wall-time estimate holds under RUN_WALL_MAX_S.
RUN_FRAMES, RUN_PIXEL_FRAMES = 1300, 180_000
#: A valid mutation estimated past this (chiptwin.config.cost) is validated, not run (ccd_two_wells
#: with a comparator of 256 LSB, its range's top, is estimated at 6.5 s and runs in ≈ 10 s; before
#: the ends' closed form it was ≈ 50 min). Unit: s.
RUN_WALL_MAX_S = 30.0
#: Faceplates the run test runs: the imaging range (3 … 25 µm fibres, the schema's doc). Beyond
#: half the diode a fibre is refused (config.budget.FIBER_PER_DIODE_MAX: the quadrature of its
#: blur does not converge in minutes); between 25 µm and that, each psf coupling of the run and
#: its optics summary costs up to ≈ 4 s: such mutations are validated, not run.
RUN_FIBER_PITCH_MAX_UM = 25.0


def _sweep_raw(name: str) -> dict:
    raw = copy.deepcopy(RAW[name])
    at = raw.get("sites", {}).get("at_pixels")
    if isinstance(at, list) and len(at) > SWEEP_SITES:
        raw["sites"]["at_pixels"] = at[:SWEEP_SITES]
    return raw


def test_sweep_every_key_every_value_is_a_scenario_or_refused():
    """Every key × the issue's values and its range's ends: never an exception but a refusal."""
    failures, counts = [], {"ok": 0, "refused": 0}
    for name in SCENARIOS:
        raw = _sweep_raw(name)
        pristine = copy.deepcopy(raw)
        for key, field in KEYS[name]:
            present = M._get(raw, key) is not M.MISSING
            for value in list(M.GENERIC) + M.extremes(field):
                if value is M.MISSING and not present:
                    continue
                try:  # the loader only reads its table: the mutation shares the rest with raw
                    scenario_from_dict(M.mutate_shallow(raw, key, value), name)
                    counts["ok"] += 1
                except ScenarioError:
                    counts["refused"] += 1
                except Exception as exc:  # noqa: BLE001 (what the test looks for)
                    failures.append(f"{name}: {M.label(key, value)}: {type(exc).__name__}: {exc}")
        assert raw == pristine, f"{name}: the loader wrote into the table it was given"
    assert not failures, "\n".join(failures[:20])
    assert counts["ok"] > 500 and counts["refused"] > 3000, counts


# --- through the command line ---------------------------------------------------------------------


def _values(field) -> st.SearchStrategy:
    listed = list(M.GENERIC) + M.extremes(field)
    return st.one_of(
        st.sampled_from(listed),
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(min_value=-(2**70), max_value=2**70),
        st.text(max_size=8),
        st.booleans(),
    )


@st.composite
def mutated(draw, in_range: bool = False) -> tuple[str, str, dict]:
    """A bundled scenario with one to three keys mutated: (name, the keys, the table)."""
    name = draw(st.sampled_from(sorted(SCENARIOS)))
    raw, keys = RAW[name], []
    for key, field in draw(st.lists(st.sampled_from(KEYS[name]), min_size=1, max_size=3)):
        if in_range:  # a value the field allows, so that the run is reached
            choices = [v for v in M.extremes(field) if _allowed(field, v)] or [M.MISSING]
            value = draw(st.sampled_from(choices))
        else:
            value = draw(_values(field))
        raw = M.mutate(raw, key, value)  # a key drawn twice: the last value stands
        keys.append(key)
    return name, ",".join(dict.fromkeys(keys)), raw


def _allowed(field, value) -> bool:
    from chiptwin.config.fields import check_value

    try:
        check_value(field, value, "", "")
        return True
    except ScenarioError:
        return False


def _write(tmp: Path, raw: dict) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / "mutated.toml"
    path.write_text(M.dumps(raw), encoding="utf-8")
    return path


def _cli(argv: list[str]) -> tuple[int, str]:
    """``main(argv)`` in-process: the exit code and what it printed on stderr."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    return code, err.getvalue()


def _assert_clean(code: int, err: str, what: str) -> None:
    assert code in (0, 2), f"{what}: exit {code}\n{err}"
    assert "Traceback" not in err, f"{what}\n{err}"
    if code == 2:
        assert err.count("\n") == 1 and err.startswith("chiptwin: error: "), f"{what}\n{err}"


#: Drawn mutations validated per run (the draws differ from run to run). Every single key at
#: every listed value and range end is covered exhaustively by the sweep above (≈ 27,000
#: mutations through the loader validate uses); what is left to chance here is the
#: combinations of keys and the drawn values, and the command line's one-line exit 2.
VALIDATE_EXAMPLES = 100


@settings(max_examples=VALIDATE_EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(case=mutated())
def test_mutated_scenario_validates_or_exits_2_with_one_line(tmp_path_factory, case):
    name, keys, raw = case
    tmp = tmp_path_factory.mktemp("v")
    path = _write(tmp, raw)
    code, err = _cli(["validate", str(path)])
    _assert_clean(code, err if code == 2 else "", f"{name}: {keys}")
    assert [p.name for p in tmp.iterdir()] == ["mutated.toml"]
    event(f"validate exit {code}")


def _affordable(path: Path) -> bool:
    """Small enough to run here: not the RTL (its own tests build it), few frames and pixels,
    estimated within RUN_WALL_MAX_S, no faceplate beyond the imaging range."""
    s = load_scenario(path)
    frames = int(s.run.duration_s / s.chip.timing.frame_period_s)
    plate = s.optics.faceplate
    return (s.dsp_level != "rtl" and frames <= RUN_FRAMES
            and frames * s.chip.n_pixels <= RUN_PIXEL_FRAMES
            and cost.wall_seconds(s) <= RUN_WALL_MAX_S
            and not (plate.na > 0 and plate.fiber_pitch_um > RUN_FIBER_PITCH_MAX_UM))


#: Drawn valid mutations per run (the draws differ from run to run; about half validate and
#: run, 1.5–3 s each, most of it the outputs' plots and the optics summary). The known run-time
#: crashes are pinned below one by one (AT_RUN, FOUND, COMBINED).
RUN_EXAMPLES = 10


@settings(max_examples=RUN_EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(case=mutated(in_range=True))
def test_valid_mutation_runs_shortened_or_exits_2_writing_nothing(tmp_path_factory, case):
    name, keys, raw = case
    tmp = tmp_path_factory.mktemp("r")
    short = M.shorten(raw, keys, max_frames=RUN_FRAMES)
    if isinstance(short.get("run"), dict) and "run.max_wall_s" not in keys.split(","):
        # validate itself calibrates fidelity "auto": a scene estimated past the run limit is
        # refused (exit 2) instead of calibrated for minutes (a 256 x 256 converter as built)
        short["run"].setdefault("max_wall_s", RUN_WALL_MAX_S)
    path = _write(tmp, short)
    code, err = _cli(["validate", str(path)])
    _assert_clean(code, err if code == 2 else "", f"{name}: {keys} (validate)")
    if code != 0 or not _affordable(path):
        event("refused" if code else "valid, too big to run here")
        return
    out = tmp / "out"
    code, err = _cli(["run", str(path), "--out", str(out), "--quiet"])
    _assert_clean(code, err if code == 2 else "", f"{name}: {keys} (run)")
    event(f"run exit {code}")
    if code == 2:
        assert not out.exists()
    else:
        assert (out / "summary.json").is_file()


# --- the issue's crashes, one by one ----------------------------------------------------------

#: At validation, times far beyond any experiment or below one tick
#: (OverflowError / ZeroDivisionError in s_to_ticks).
AT_VALIDATION = [
    (scenario, key, value)
    for key in ("run.duration_s", "assay.start_s", "assay.flow_period_s",
                "chip.timing.frame_period_s", "chip.timing.t_int_s")
    for value in ("1e300", "1e-300")
    for scenario in ("pyro_1fmol",)
] + [("pyro_1fmol", "chip.adc.clock_hz", "1e-300")]

#: At run time, after validation said OK (OverflowError, "lam value too large", MemoryError).
AT_RUN = [
    ("atp_glow", "assay.atp_fmol", "1e300"),
    ("pyro_1fmol", "assay.dna_fmol", "1e300"),
    ("luciferase_label", "assay.luciferase_amol", "1e300"),
    ("pyro_1fmol", "assay.photons_per_incorporation", "1e300"),
    ("atp_glow", "assay.turnover_per_s", "1e300"),
    ("pyro_1fmol", "chip.pixel.temperature_C", "1e300"),
    ("pyro_1fmol", "chip.pixel.dark_current_nA_per_cm2", "1e300"),
    ("pyro_1fmol", "chip.pixel.read_noise_e", "1e300"),
    ("pyro_1fmol", "chip.pixel.capacitance_fF", "1e300"),
    ("pyro_1fmol", "chip.adc.v_max_V", "1e300"),
    ("pyro_1fmol", "run.duration_s", str(2**63)),
]

#: Found by the mutation sweep beside the issue's list (internal errors before the fix).
FOUND = [
    ("pyro_1fmol", "chip.dsp.cycles_per_sample", "1e19"),  # int64 overflow of the DSP's ticks
    ("pyro_1fmol", "chip.dsp.clock_hz", "1e-300"),  # OverflowError in s_to_ticks
    ("pyro_1fmol", "chip.timing.t_reset_s", "1e300"),
    ("pyro_1fmol", "chip.pixel.capacitance_fF", "5e-324"),  # ZeroDivisionError
    ("pyro_1fmol", "sites.height_um", "5e-324"),  # the psf footprint quadrature fails
    ("ccd_100fmol", "assay.n_flows", "1"),  # fewer flows than the key: IndexError
    ("pyro_1fmol", "assay.k_a_per_s", "1e300"),
    ("pyro_1fmol", "chip.pixel.diode_h_um", "1e-300"),
    # the matched filter's weights underflow: 0 ± 0, SNR inf, the report's histogram fails
    ("pyro_array_256", "assay.k_a_per_s", "1e9"),
    # the faceplate's blur quadrature ran > 10 min at 1 mm fibres (estimated 0.19 s)
    ("jssc2006_faceplate", "optics.faceplate.fiber_pitch_um", "1000"),
]


@pytest.mark.parametrize(("scenario", "key", "value"), AT_VALIDATION + AT_RUN + FOUND,
                         ids=[f"{s}:{k}={v}" for s, k, v in AT_VALIDATION + AT_RUN + FOUND])
def test_issue_crash_is_refused_naming_the_key(tmp_path, capsys, scenario, key, value):
    out = tmp_path / "out"
    argv = [scenario, "--set", f"{key}={value}"]
    assert main(["validate", *argv]) == 2
    err = capsys.readouterr().err
    assert main(["run", *argv, "--out", str(out), "--quiet"]) == 2
    assert capsys.readouterr().err == err
    assert err.count("\n") == 1 and "Traceback" not in err and key in err, err
    assert not out.exists()


#: Two keys together, found beside the one-key sweep (internal errors before the fix).
COMBINED = [
    # the cascade's solver and its yield fit fail outside the range they were sized for
    ("pyro_1fmol", ['run.fidelity.kinetics="cascade"', "assay.k_a_per_s=1e9"], "assay.k_a_per_s"),
    ("pyro_1fmol", ['run.fidelity.kinetics="cascade"', "assay.k_t_per_s=100"],
     "assay.photons_per_incorporation"),
    ("pyro_1fmol", ['run.fidelity.kinetics="cascade"', "assay.photons_per_incorporation=1e3"],
     "assay.photons_per_incorporation"),
    # the matched filter's weights underflow (0 ± 0 and SNR inf, "detected")
    ("pyro_1fmol", ['run.light_estimator="matched"', "assay.k_a_per_s=1e9"], "assay.k_a_per_s"),
    ("atp_glow", ['run.light_estimator="matched"', "assay.turnover_per_s=1e9"],
     "assay.turnover_per_s"),
]


#: Valid runs that were internal errors (found by the run test above and by the studies' tests):
#: each runs now, shortened as :data:`tests.conftest.REDUCED` shortens its scenario.
RUNS = [
    # the optics summary's law spread divided two shares that rounded to 0 (ZeroDivisionError)
    ("atp_dose_response", ["optics.transmission=5e-324", "run.duration_s=40.0"]),
    # the carried dark pixels' sub-scene kept the whole array's converters (a reshape error)
    ("pyro_1fmol", ["run.carry_dark_pixels=true", "chip.adc.comparator_noise_uV=100"]),
]


@pytest.mark.parametrize(("scenario", "sets"), RUNS, ids=[f"{s}:{'+'.join(v)}" for s, v in RUNS])
def test_found_valid_run_runs(tmp_path, scenario, sets):
    out = tmp_path / "out"
    argv = ["run", scenario, "--out", str(out), "--quiet"]
    for text in REDUCED.get(scenario, []) + sets:
        argv += ["--set", text]
    assert main(argv) == 0
    assert (out / "summary.json").is_file()


@pytest.mark.parametrize(("scenario", "sets", "key"), COMBINED,
                         ids=[f"{s}:{'+'.join(v)}" for s, v, _ in COMBINED])
def test_combined_crash_is_refused_naming_the_key(tmp_path, capsys, scenario, sets, key):
    out = tmp_path / "out"
    argv = ["run", scenario, "--out", str(out), "--quiet"]
    for text in sets:
        argv += ["--set", text]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and key in err, err
    assert not out.exists()


@pytest.mark.parametrize(("key", "value"), [
    ("assay.key", '"T"'),  # no 1-mer before the key's last flow
    ("assay.flow_order", '"TCG"'),  # never dispenses the key's A
])
def test_key_that_cannot_normalise_is_refused(capsys, key, value):
    assert main(["validate", "pyro_1fmol", "--set", f"{key}={value}",
                 "--set", 'assay.template="TCAGGTTCCAAAGTCGAT"']) == 2
    err = capsys.readouterr().err
    assert key in err and err.count("\n") == 1


def test_times_in_range_never_under_or_overflow_the_tick():
    from chiptwin.constants import MAX_TIME_S, TICK_S, s_to_ticks

    assert s_to_ticks(TICK_S) == 1
    assert s_to_ticks(MAX_TIME_S) == 10**16 < 2**63
    assert math.isclose(s_to_ticks(math.nextafter(MAX_TIME_S, 0)), 1e16, rel_tol=1e-15)


def test_subnormal_footprint_is_a_point_source():
    """Found by the optics sweep on crosstalk_microarray and ccd_two_wells
    (``sites.footprint_radius_um = 5e-324``): the disc's radial weights ∝ r underflowed to 0/0,
    the quadrature never converged (ValueError, exit 1 in the run). The weights no longer hold
    r: a subnormal disc is the point."""
    from chiptwin.optics.psf import coupling_psf

    grid = dict(n_rows=3, n_cols=3, pitch_um=125.0, diode_w_um=100.0, diode_h_um=100.0,
                site_x_um=[0.0], site_y_um=[0.0], height_um=150.0, convention="lambertian_na2")
    point = coupling_psf(**grid)
    for r in (5e-324, 1e-310):
        assert np.allclose(coupling_psf(**grid, site_radius_um=r), point, rtol=1e-9, atol=0)


def test_dose_response_without_a_slope_has_no_lod_error():
    """Found by a pixel sweep of atp_dose_response (``chip.pixel.full_well_e = 1``: every pixel
    clips, no amount gives a signal): the LoD's standard error divided by the slope 0
    (ZeroDivisionError after the run, exit 1). With no slope it is infinite."""
    from chiptwin.twin.dose_response import _lod

    amounts, expected = np.array([1.0, 2.0]), np.zeros(2)
    stats = {"threshold_measured_e": 3.0, "threshold_measured_se_e": 0.5}
    out = _lod(amounts, expected, stats, 3.0, 0.0)
    assert out["lod_from_blank_spread_se_amol"] == math.inf
    assert _lod(amounts, np.array([2.0, 4.0]), stats, 3.0, 2.0)[
        "lod_from_blank_spread_se_amol"] == 0.25
