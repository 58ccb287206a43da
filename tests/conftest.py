"""Shared fixtures: the repository's scenario folder and a small, fast scenario; the one rule for
a test whose tool is missing (skip off CI with how to install it, fail under CI=true)."""

from __future__ import annotations

import importlib
import os
from pathlib import Path
from types import ModuleType
from typing import NoReturn

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

#: ``--set`` overrides that take a scene built on the reference chip as built
#: (chiptwin.config.reference_chip) back to the ideal converter, for tests written on it.
IDEAL_ADC = ["chip.adc.comparator_noise_uV=0", "chip.adc.inl_max_lsb=0",
             "chip.adc.dnl_rms_lsb=0", "chip.adc.offset_sigma_lsb=0", "chip.adc.gain_sigma=0"]

#: ``--set`` overrides that take such a scene back to the paper's idealised chip: the ideal
#: converter, the NA² emitter convention and no top surface (nothing returned from above), for
#: tests whose oracle is a closed form of that idealisation.
NO_TOP = ['optics.top.medium="solution"', "optics.top.solution_depth_um=0",
          "optics.top.lid_thickness_um=0", "optics.top.lid_n=0"]
PAPER_CHIP = IDEAL_ADC + ['optics.emitter="lambertian_na2"'] + NO_TOP

SMALL = """
[scenario]
name = "small"
seed = 7

[assay]
kind = "pyrosequencing"
template = "TCAGGTTCCA"
n_flows = 14
flow_period_s = 20.0
start_s = 4.0
k_a_per_s = 0.25
photons_per_incorporation = 0.01

[sites]
at_pixels = [[1, 1], [2, 4]]

[chip]
rows = 4
cols = 6

[chip.dsp]
n_dark_frames = 4
cms_samples = 2
average_frames = 4

[run]
duration_s = 284.0
"""


@pytest.fixture
def small_toml(tmp_path: Path) -> Path:
    """A 4 × 6 chip sequencing a 10-base template in 14 short flows: runs in well under a second."""
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


#: ``--set`` keys that make a bundled scenario small: the same physics, fewer frames (and
#: pixels), so a test can run every bundled scenario in seconds.
REDUCED = {
    "pyro_1fmol": ["assay.n_flows=8", "run.duration_s=500.0"],
    "ccd_100fmol": ["assay.n_flows=8", "run.duration_s=496.0"],
    "pyro_array_256": ["assay.n_flows=8", "run.duration_s=500.0", "chip.rows=8", "chip.cols=8",
                       "sites.at_pixels=[[2, 2], [2, 6], [6, 2], [6, 6]]"],
    "pyro_paper_yield": ["assay.n_flows=8", "run.duration_s=500.0"],
    "pyro_paper_yield_fast": ["assay.n_flows=8", "assay.flow_period_s=4.0",
                              "run.duration_s=34.0"],
    # 16 flows of its 400 on 4 × 8 sites: the chemistry preset's light, the dephase caller
    "pyro_454_flx": ["assay.n_flows=16", "run.duration_s=1000.0", "chip.rows=4",
                     "chip.cols=8"],
}


#: Where measured data sets are looked for: ``$CHIPTWIN_DATA``, else a ``shared/data/real`` folder
#: beside the repository when there is one (set for the whole session, so a bundled calibrate
#: study's ``${CHIPTWIN_DATA}`` resolves in the tests and the commands they start).
if not os.environ.get("CHIPTWIN_DATA") and (ROOT.parent / "shared" / "data" / "real").is_dir():
    os.environ["CHIPTWIN_DATA"] = str(ROOT.parent / "shared" / "data" / "real")


def real_data(*parts: str) -> Path:
    """A measured data set (EMVA 1288 images, flowgrams) under ``$CHIPTWIN_DATA``, by default the
    ``shared/data/real`` folder beside the repository; the project does not carry them. Absent,
    the test skips naming the path it looked for (docs/background/testing.md)."""
    root = os.environ.get("CHIPTWIN_DATA") or ROOT.parent / "shared" / "data" / "real"
    path = Path(root).joinpath(*parts)
    if not path.exists():
        pytest.skip(f"needs the measured data set {path} (set CHIPTWIN_DATA to its root)")
    return path


def in_ci() -> bool:
    """``CI=true`` (GitHub Actions, GitLab, most CI services set it)."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def unavailable(what: str) -> NoReturn:
    """A test's tool is missing (``what`` says which and how to install it): skip on a
    developer's machine, fail under ``CI=true``, where scripts/test.sh installs every tool — the
    suite's only skips (test_kill's ``/proc`` too; README, "Quick start")."""
    if not in_ci():
        pytest.skip(what)
    pytest.fail(f"CI=true and a test cannot run: {what}", pytrace=False)


def require_module(name: str, extra: str = "test") -> ModuleType:
    """``import name``, or :func:`unavailable` naming the extra that installs it."""
    try:
        return importlib.import_module(name)
    except ImportError:
        unavailable(f"{name} is not installed (pip install -e '.[{extra}]')")


#: Modules whose costly module- or session-scoped fixtures serve several tests: under
#: ``pytest -n auto --dist loadgroup`` (scripts/test.sh) each group runs on one worker, so each
#: fixture is computed once instead of once per worker that gets one of its tests. The same
#: holds for numba's compilation on a fresh checkout (no cache yet): two workers that meet one
#: kernel at once both compile it.
XDIST_GROUPS = {
    "tests/validation/test_paper_yield.py": "paper_yield",  # two whole runs (7 s and 2 s)
    "tests/validation/test_noise_monte_carlo.py": "noise_monte_carlo",  # 1.5 s of seeds
    # the session's `characterized` chips (tests/characterize/conftest.py)
    "tests/characterize/test_cli.py": "characterized",
    "tests/characterize/test_emva1288.py": "characterized",
    "tests/characterize/test_roundtrip.py": "characterized",
    "tests/characterize/test_twin.py": "characterized",
    # the session's `frame_memory_result` study (tests/study/conftest.py)
    "tests/study/test_bundled.py": "frame_memory_study",
    "tests/study/test_outputs.py": "frame_memory_study",
    # _random.fill on three sources (PCG64, SFC64, a Generator): 17-27 s of compilation cold,
    # the PCG64 version compiled by both workers when the module was split (0.7 s of tests warm)
    "tests/pixel/test_random.py": "random_fill",
}


#: The slow tier, marked ``slow`` here rather than at each test so that the whole tier reads in
#: one place: a plain ``bash scripts/test.sh`` is the quick loop (``-m "not slow"``, under 2 min
#: on 2 cores), ``bash scripts/test.sh --all`` runs every test, as CI does (.ci/run). Slow are
#: the tests of ≥ 1 s on 2 cores
#: (junit durations, warm numba cache): whole runs that write their figures, processes
#: (kill/resume, pools, Dask, the benchmark scripts), co-simulation, traced memory, sweeps of
#: thousands of mutated files, million-vector cross-checks; and the modules whose shared fixture
#: is such a run (listed as a module: all its tests). ``module::function`` marks every
#: parametrisation of the function. An entry that names no test stops the session (a renamed
#: test must not fall out of the tier unnoticed); a test of ≥ SLOW_S outside it is listed at the
#: end of the run.
SLOW = {
    # modules: processes, co-simulation, or a shared fixture that is a whole run
    "tests/test_benchmarks.py",  # the 15 benchmark scripts, --quick
    "tests/study/test_kill.py",  # SIGTERM/SIGKILL a study and its pool, then resume
    "tests/rtl/test_rtl_icarus.py",  # Icarus, cycle for cycle against Verilator
    "tests/rtl/test_rtl_cosim.py",
    "tests/rtl/test_rtl_program.py",
    "tests/validation/test_paper_yield.py",  # the paper's two scenes, whole
    "tests/validation/test_noise_monte_carlo.py",
    "tests/characterize/test_cli.py",  # the `characterized` chips: EMVA 1288 sweeps
    "tests/characterize/test_emva1288.py",
    "tests/characterize/test_roundtrip.py",
    "tests/characterize/test_twin.py",
    "tests/study/test_bundled.py",  # the `frame_memory_result` study
    "tests/study/test_outputs.py",
    "tests/study/test_optimize.py",  # whole design searches (a grid, resumption, the CLI)
    "tests/study/test_least.py::test_pyro_1fmol_needs_264192_bits_not_the_grids_524288",
    "tests/study/test_least.py::test_the_schedules_memory_runs_and_one_frame_less_is_refused",
    "tests/study/test_least.py::test_a_memory_study_states_the_schedules_need_checked_by_a_run",
    "tests/docs/test_answers.py::test_the_cheap_entries_rerun_to_the_same_numbers",
    "tests/docs/test_site.py",  # every built page in Chromium (skips when the site is not built)
    # whole runs, traced memory, sweeps
    "tests/config/test_budget.py::test_memory_estimate_is_above_what_a_run_holds",
    "tests/config/test_budget.py::test_footprint_limit_converges",
    "tests/config/test_budget.py::test_charge_bound_is_above_every_pixel_frame",
    "tests/config/test_cost.py::test_the_as_built_estimate_is_within_its_factor",
    "tests/config/test_cost.py::test_thin_films_are_costed_within_the_factor",
    "tests/config/test_study_mutations.py::"
    "test_every_mutation_loads_or_is_refused_with_file_key_and_allowed",
    "tests/config/test_mutations.py::test_valid_mutation_runs_shortened_or_exits_2_writing_nothing",
    "tests/config/test_mutations.py::test_sweep_every_key_every_value_is_a_scenario_or_refused",
    "tests/config/test_mutations.py::test_found_valid_run_runs",
    "tests/config/test_mutations.py::test_mutated_scenario_validates_or_exits_2_with_one_line",
    "tests/config/test_dsp_widths.py::test_dsp_integer_keys_together_validate_or_exit_2",
    "tests/test_run.py::test_every_bundled_scenario_writes_its_outputs",
    "tests/test_run.py::test_output_folder_is_never_a_stranger",
    "tests/test_run.py::test_closed_form_run_is_the_simpy_run",
    "tests/test_figures_read.py::test_a_runs_figures_use_them",
    "tests/test_fidelity.py::test_auto_is_cheaper_than_the_reference_and_within_its_budget",
    "tests/test_fidelity.py::test_a_study_resolves_auto_once_per_point_and_runs_the_level_it_picks",
    "tests/test_fidelity.py::test_calibration_is_cached_per_scene",
    "tests/test_adc_levels.py::test_ladder_has_an_ideal_adc_row_with_its_error",
    "tests/test_adc_levels.py::"
    "test_auto_keeps_as_built_within_a_tight_budget_and_takes_ideal_within_a_loose_one",
    "tests/test_shortcuts.py::test_converters_as_built_are_carried_with_their_pixels",
    "tests/test_tile.py::test_tiled_pyro_array_256_agrees_with_the_whole_array_within_monte_carlo",
    "tests/test_tile.py::"
    "test_at_the_expected_level_every_simulated_site_reads_the_whole_arrays_figures",
    "tests/test_tile.py::test_a_study_replicate_on_a_tiled_scene_is_the_run_at_its_seed",
    "tests/test_tile.py::test_the_mirrored_kernel_is_the_whole_grids",
    "tests/test_tile.py::"
    "test_a_tile_on_a_layout_that_is_not_periodic_is_refused_and_auto_runs_whole",
    "tests/test_ladder.py::test_cli_ladder_writes_its_outputs",
    "tests/fidelity/test_dsp_bound.py",  # fixed and float whole runs, same seeds
    "tests/fidelity/test_coverage.py",  # auto and the reference, 4 seeds each
    "tests/fidelity/test_shot_bound.py::test_window_total_moves_within_the_charge_and_far_below_tv",
    "tests/fidelity/test_events_estimate.py::test_estimated_filled_windows_are_the_runs",
    "tests/study/test_engine.py::test_serial_pool_and_dask_give_identical_tables",
    "tests/study/test_engine.py::test_killed_study_resumes_to_the_same_tables",
    "tests/study/test_engine.py::test_changed_study_is_refused_for_resumption",
    "tests/study/test_engine.py::test_answer_statistics_and_outputs",
    "tests/chip/test_chip_scale.py::test_saved_frames_are_what_the_dsp_saw",
    "tests/chip/test_chip_scale.py::test_peak_memory_does_not_grow_with_frames_beyond_the_trace",
    "tests/chip/test_steady.py::test_closed_form_is_simpy_where_it_applies",
    "tests/characterize/test_adc_bench.py::test_same_seed_same_json",
    "tests/characterize/test_adc_bench.py::test_injected_table_and_noise_round_trip",
    "tests/characterize/test_adc_bench.py::test_reference_chip_seconds",
    "tests/characterize/test_adc1241.py::test_bench_end_to_end",
    "tests/characterize/test_evaluate.py::test_sensitivity_threshold_sigma_matches_its_spread",
    "tests/characterize/test_adc1241.py::test_transition_noise_rms_sigma_counts_shared_conversions",
    "tests/optics/test_raytrace.py::test_optiland_cross_check",
    "tests/optics/test_psf.py::test_footprint_quadrature_meets_its_tolerance",
    "tests/optics/test_stack.py::test_cross_talk_falls_as_the_water_gap_shrinks",
    "tests/optics/test_thinfilm.py::test_a_thick_layer_averaged_over_the_band_is_the_incoherent_slab",
    "tests/optics/test_wiring.py::test_a_passivation_film_is_coherent_and_reported",
    "tests/optics/test_top_wiring.py::test_jssc2006_faceplate_under_an_open_top_reports_it",
    "tests/optics/test_thinfilm.py::test_raytrace_crosses_films_both_ways_as_incoherent_tmm_says",
    "tests/optics/test_thinfilm.py::"
    "test_a_ray_at_a_films_critical_angle_and_a_first_layer_denser_than_the_last",
    "tests/dsp/test_dsp_batch.py::test_batch_and_single_jobs_are_the_per_job_pipeline",
    "tests/dsp/test_dsp_routines.py::test_routine_matches_exact_reference",
    "tests/dsp/test_dsp_program.py::test_kinetics_variance_equals_monte_carlo",
    # measured at ≥ 4.5 s each under load (about 1 s on a quiet machine): pools and Dask,
    # whole runs through the CLI, the 256 × 256 coupling, the calibrated bench
    "tests/config/test_budget.py::test_sparse_kernel_radius_is_at_least_the_stage_s",
    "tests/config/test_budget.py::test_film_table_term_is_above_what_the_tables_hold",
    "tests/config/test_cost.py::test_the_estimate_is_within_its_factor_of_measured_wall_time",
    "tests/study/test_execute.py::test_the_table_does_not_depend_on_batching_or_executor",
    "tests/study/test_execute.py::"
    "test_an_interrupted_study_keeps_whole_tasks_and_runs_no_stored_row_again",
    "tests/study/test_execute.py::test_a_cluster_without_workers_exits_2_naming_the_timeout",
    "tests/study/test_execute.py::test_a_scheduler_file_runs_the_study_on_its_workers",
    "tests/study/test_sensitivity.py::test_one_and_two_workers_give_identical_tables",
    "tests/study/test_sensitivity.py::test_the_assumption_that_moves_the_answer_ranks_first",
    "tests/study/test_calibrate_adc.py::test_a_twin_made_bench_gives_back_its_comparator_noise",
    "tests/characterize/test_measured.py::test_written_twin_loads_and_reproduces_the_datasheet",
    "tests/characterize/test_measured.py::test_round_trip_through_the_format",
    "tests/test_fidelity.py::test_auto_refuses_the_cheap_level_of_each_hard_case",
    "tests/test_fidelity.py::test_a_run_with_auto_says_why_in_summary_and_report",
    "tests/test_fidelity.py::test_the_hard_cases_measure_what_they_claim",
    "tests/chip/test_chip_scale.py::test_an_array_of_sites_gets_its_figures_map_and_histogram",
    "tests/optics/test_wiring.py::test_jssc2006_faceplate_runs_and_reports",
    "tests/optics/test_thinfilm.py::test_raytrace_film_tables_interpolate_within_2e_4",
    "tests/optics/test_thinfilm.py::test_light_tunnels_through_a_thin_low_index_gap",
    "tests/dsp/test_dsp_program.py::"
    "test_pyro_1fmol_kinetics_on_chip_matches_the_float_matched_filter",
    "tests/dsp/test_fixed_properties.py::test_accumulate_into_is_exact",
    "tests/dsp/test_fixed_properties.py::test_requantize_is_exact",
    "tests/dsp/test_fixed_properties.py::test_accumulate_full_precision_is_exact",
    "tests/report/test_vcd.py::test_cli_run_vcd_writes_the_same_bytes",
    "tests/report/test_vcd.py::test_run_vcd_is_the_trace_event_for_event",
    "tests/report/test_reads_call.py::test_round_on_ion_flow_signals_makes_the_instruments_calls",
    "tests/test_run.py::test_cli_run_writes_every_output",
    "tests/test_run.py::test_expected_level_is_the_mean_of_binned_runs",
    "tests/pixel/test_norc.py::"  # two fresh compilations of a sampler loop
    "test_reference_counting_puts_an_atomic_pair_around_each_draw_and_norc_removes_it",
    # statistics and exact references that draw or evaluate millions
    "tests/pixel/test_expected_adc.py::test_sawtooth_series_equals_the_exact_sums",
    "tests/pixel/test_expected_adc.py::"
    "test_quadrature_in_slices_is_the_whole_and_holds_little_memory",
    "tests/pixel/test_expected_adc.py::"
    "test_expected_moments_match_a_monte_carlo_of_the_binned_path",
    "tests/pixel/test_expected_adc.py::test_quadrature_is_within_its_stated_bound",
    "tests/pixel/test_pixel_noise_model.py::test_dark_series_recovers_dark_current",
    "tests/pixel/test_pixel_noise_model.py::test_photon_transfer_recovers_conversion_gain",
    "tests/photons/test_events.py::test_window_counts_have_poisson_mean_and_variance",
    "tests/photons/test_events.py::test_events_in_windows_are_distributed_as_binned_counts",
    "tests/photons/test_events.py::"
    "test_saturation_time_from_rate_has_the_event_based_distribution",
    "tests/kinetics/test_hard_cases.py::"
    "test_saturated_cascade_at_1_mM_against_a_tightened_tolerance",
    "tests/kinetics/test_hard_cases.py::test_window_photons_against_the_50_digit_reference",
    "tests/kinetics/test_cascade.py::test_source_is_a_light_source_and_photons_integrate_its_rate",
    "tests/kinetics/test_pulse_train.py::test_pyrosequencing_like_train_over_many_windows",
    "tests/kinetics/test_phasing.py::test_cascade_incorporations_equal_the_phasing_model",
    "tests/kinetics/test_flow_model_caller.py::test_run_keeps_each_reads_corrected_values",
    "tests/kinetics/test_flow_model_caller.py::test_each_study_replicate_draws_its_own_chemistry",
    "tests/report/test_flow_profile.py::"
    "test_twin_check_reads_the_runs_corrected_values_and_states_the_floor",
    "tests/test_detection.py::test_detection_is_one_sided",
    "tests/validation/test_dose_response.py::"
    "test_blank_three_sigma_threshold_gives_the_normal_false_positive_rate",
    "tests/validation/test_chunk_equivalence.py::"
    "test_chunks_draw_the_same_distribution_whose_mean_is_expected",
    "tests/dsp/test_fixed_apytypes.py::test_requantize_matches_apytypes",
    "tests/dsp/test_fixed_apytypes.py::test_quantize_matches_apytypes",
    "tests/dsp/test_fixed_apytypes.py::test_routine_matches_apytypes_on_a_million_vectors",
    "tests/dsp/test_fixed_properties.py::test_full_precision_ops_are_exact",
    "tests/dsp/test_fixed_properties.py::test_quantize_is_exact",
    "tests/detection/test_reads.py::test_qualities_are_calibrated_monte_carlo",  # 150 reads
    "tests/detection/test_qualities.py",  # 400 drawn reads; the Ion set called twice
    "tests/detection/test_caller_equivalence.py::test_bundled_scenes_call_what_they_called",
    "tests/detection/test_caller_equivalence.py::"
    "test_sweep_and_hill_climb_match_the_naive_kernels",  # the naive kernels: 1-2 s a case
    "tests/report/test_sff.py::test_run_writes_reads_sff_biopython_reads_back",  # a whole run
    # the corners of the study keys: ~180 whole runs of a small scene, 1-12 s each
    "tests/config/test_corners.py::test_each_key_at_both_ends_runs_or_is_refused",
    "tests/config/test_corners.py::test_pairs_of_keys_at_their_ends_run_or_are_refused",
    "tests/config/test_corners.py::test_the_point_like_radius_runs",  # two whole runs
    "tests/chip/test_silicon.py::test_a_run_reports_its_cost_and_throughput",  # a whole run
}

#: A test outside the slow tier taking at least this long (setup, call and teardown) is named at
#: the end of the run, to be made cheaper or added to :data:`SLOW`. Unit: s.
SLOW_S = 1.5


def _check_slow_entries() -> None:
    """Every :data:`SLOW` entry names a test module, and a function defined in it."""
    texts: dict[str, str] = {}  # each module read once
    for entry in SLOW:
        module, _, function = entry.partition("::")
        path = ROOT / module
        if path.is_file() and module not in texts:
            texts[module] = path.read_text()
        if module not in texts or (function and f"def {function}(" not in texts[module]):
            raise pytest.UsageError(f"tests/conftest.py SLOW: {entry!r} names no test (renamed "
                                    "or removed? keep the slow tier true)")


def pytest_sessionstart(session) -> None:
    """Check the slow tier before collecting, on the controller too: raised inside an xdist
    worker's collection hook, the usage error surfaced only as every group lost."""
    _check_slow_entries()


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads the marks into node ids
def pytest_collection_modifyitems(config, items) -> None:
    for item in items:
        module = item.path.relative_to(ROOT).as_posix()
        group = XDIST_GROUPS.get(module)
        if group:
            item.add_marker(pytest.mark.xdist_group(group))
        if module in SLOW or f"{module}::{getattr(item, 'originalname', item.name)}" in SLOW:
            item.add_marker(pytest.mark.slow)


def pytest_terminal_summary(terminalreporter) -> None:
    """Name the tests outside the slow tier that took ``SLOW_S`` or longer (see :data:`SLOW`)."""
    took: dict[str, float] = {}
    for reports in terminalreporter.stats.values():
        for r in reports:
            if getattr(r, "duration", None) is not None and "slow" not in getattr(
                    r, "keywords", {}):  # test reports (a collection's has no duration)
                took[r.nodeid] = took.get(r.nodeid, 0.0) + r.duration
    over = sorted(((t, n) for n, t in took.items() if t >= SLOW_S), reverse=True)
    if over:
        terminalreporter.section(f"outside the slow tier, {SLOW_S:g} s or longer")
        for t, n in over:
            terminalreporter.write_line(f"{t:6.2f} s  {n}")


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook, on the controller
def pytest_xdist_node_collection_finished(node, ids) -> None:
    """Under ``--dist loadgroup`` xdist sends each group to one worker by the ``@group`` suffix
    its workers put on the node ids; with pytest 9.2 and pytest-xdist 3.8 the suffix is silently
    lost and every test goes anywhere (pytest-dev/pytest-xdist#1386). Stop rather than compute
    the groups' shared fixtures, and compile their kernels, on every worker unnoticed."""
    if node.config.getoption("dist", default="no") != "loadgroup":
        return
    lost = [i for i in ids if i.split("::")[0] in XDIST_GROUPS and "@" not in i]
    if lost:
        pytest.exit(f"--dist loadgroup groups nothing: {lost[0]} lost its group (pytest "
                    f"{pytest.__version__}, pytest-dev/pytest-xdist#1386): install the test "
                    "extra's pytest (<9.2) or run without --dist loadgroup",
                    returncode=pytest.ExitCode.USAGE_ERROR)
