"""The ``chiptwin`` command: a thin layer over :func:`chiptwin.twin.runner.run`.

Here the parser and what each command does; what it prints besides the numbers (help texts,
tables, close names) in :mod:`chiptwin.cli.text`, its progress line in
:mod:`chiptwin.cli.progress`.

Exit codes: 0 success, 2 bad input (one clear line, no traceback), 1 internal error, 130 on
Ctrl-C and 143 on SIGTERM (what ``kill``, systemd, Slurm and Kubernetes send): both stop the
command the same way, one line, everything a study stored kept, its workers gone.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import sys
import textwrap
import threading
import traceback
from collections.abc import Sequence
from pathlib import Path

from chiptwin import __version__
from chiptwin.cli.characterize import CHARACTERIZE_HELP, add_characterize, characterize_command
from chiptwin.cli.common import (
    _check_json_path,
    _scenario_path,
    _shown,
    _study_path,
    _working,
)
from chiptwin.cli.progress import Progress as _Progress
from chiptwin.cli.reads import READS_HELP, add_reads, reads_command
from chiptwin.cli.text import (
    WIDTH,
    epilog,
    first_sentences,
    fit,
    listing,
    opening_comment,
    paragraph,
    table,
)
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.config.catalog import (
    bundled_scenarios,
    bundled_scenarios_folder,
    bundled_studies,
    resolve_scenario,
    resolve_study,
)
from chiptwin.config.cost import (
    IN_FLIGHT_PER_WORKER,
    MAX_IN_FLIGHT,
    MAX_ROWS_PER_TASK,
    MAX_WORKER_TIMEOUT_S,
    TASK_TARGET_S,
    WORKER_TIMEOUT_S,
)


class UsageError(Exception):
    """A command line argparse cannot read: the parser whose usage to show, and why."""

    def __init__(self, parser: argparse.ArgumentParser, message: str) -> None:
        super().__init__(message)
        self.parser = parser


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # argparse's default exits; we want an exit code
        raise UsageError(self, message)


def _command(sub, name: str, help: str, **kw) -> argparse.ArgumentParser:
    """A sub-command whose ``--help`` ends with its examples and where to read more."""
    return sub.add_parser(name, help=help, description=paragraph(help[0].upper() + help[1:] + "."),
                          epilog=epilog(name), formatter_class=_Formatter, **kw)


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the epilog's example columns; wraps the rest to :data:`chiptwin.cli.text.WIDTH`."""

    def __init__(self, prog: str) -> None:
        super().__init__(prog, width=WIDTH, max_help_position=32)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="chiptwin", description=paragraph(
                "Digital twin of a CMOS bioluminescence detection chip: assay light, optics, "
                "pixels, ADCs, frame memory and on-chip DSP, with the SNR, calls and limit of "
                "detection they give."), epilog=epilog("chiptwin"),
                formatter_class=_Formatter)
    p.add_argument("--version", action="version", version=f"chiptwin {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    r = _command(sub, "run", "run a scenario and write its outputs")
    _scenario_args(r)
    r.add_argument("--out", help="output folder (default: out/SCENARIO_NAME)")
    r.add_argument("--quiet", action="store_true", help="no progress, no table")
    r.add_argument("--vcd", action="store_true",
                   help="also write the chip's timing as a waveform, chip.vcd (IEEE 1364 value "
                        "change dump, for GTKWave or Surfer)")
    v = _command(sub, "validate", "check a scenario or study file without running it, and "
                 "estimate its wall time")
    _scenario_args(v)
    v.add_argument("--verbose", action="store_true",
                   help="a study: every inconsistent point with its full reason")
    _command(sub, "list", "list the bundled scenarios and studies")
    d = _command(sub, "dsp-report", "fixed-point DSP vs float on a scenario's data")
    _scenario_args(d)
    d.add_argument("--json", help="also write the report as JSON to this file")
    add_characterize(_command(sub, "characterize", CHARACTERIZE_HELP))
    add_reads(_command(sub, "reads", READS_HELP))
    la = _command(sub, "ladder", "speed against error: every fidelity level of a scene "
                  "against the most faithful combination")
    _scenario_args(la)
    la.add_argument("--out", help="output folder (default: out/SCENARIO_NAME_ladder)")
    la.add_argument("--replicates", type=int, default=5,
                    help="seeds per level (default 5; common random numbers across levels)")
    la.add_argument("--json", help="also write ladder.json to this file")
    la.add_argument("--reference", action="append", default=[], metavar="STAGE=LEVEL",
                    help="pin a level of the reference, e.g. --reference dsp=fixed (repeatable;"
                         " default: the most faithful level the scene accepts)")
    st = _command(sub, "study", "run a budget study: axes × replicates → the answer")
    st.add_argument("study", help="a study TOML file, or the name of a bundled study")
    st.add_argument("--out", help="output folder (default: out/STUDY_NAME); an existing one "
                    "resumes the study")
    st.add_argument("--workers", type=int, help="local processes (default: every core)")
    dask = st.add_mutually_exclusive_group()
    dask.add_argument("--scheduler", help='a Dask scheduler address, or "local" for a Dask '
                      "LocalCluster (needs the [dask] extra)")
    dask.add_argument("--scheduler-file", metavar="PATH",
                      help="the JSON file a Dask scheduler writes on an HPC cluster (`dask "
                           "scheduler --scheduler-file PATH`): run on that scheduler's workers")
    st.add_argument("--worker-timeout", type=float, default=WORKER_TIMEOUT_S, metavar="S",
                    help=f"seconds a Dask cluster may take to show its first worker before "
                         f"the study gives up (default {WORKER_TIMEOUT_S:g}; in (0, "
                         f"{MAX_WORKER_TIMEOUT_S:g}]: a batch queue may need hours)")
    st.add_argument("--rows-per-task", type=int, metavar="N",
                    help=f"rows an executor task runs (default: about {TASK_TARGET_S:g} s of "
                         f"rows by the measured or estimated row time; in [1, "
                         f"{MAX_ROWS_PER_TASK}]: a task's rows travel back in one message); "
                         "the table does not depend on it")
    st.add_argument("--in-flight", type=int, metavar="N",
                    help=f"executor tasks out at once (default {IN_FLIGHT_PER_WORKER} per "
                         f"worker; in [1, {MAX_IN_FLIGHT}]: each is a future the client holds)")
    st.add_argument("--fresh", action="store_true", help="discard stored rows and start over")
    st.add_argument("--quiet", action="store_true", help="no progress")
    _whatif_args(st)
    return p


def _whatif_args(st: argparse.ArgumentParser) -> None:
    """The study re-asked (chiptwin.study.whatif): each value checked against its key's range
    before anything runs; the study as run is written to OUT/study.toml."""
    from chiptwin.study.whatif import QUICK_AXIS_VALUES, QUICK_REPLICATES

    w = st.add_argument_group("what-ifs (the study as run: OUT/study.toml; default OUT: "
                              "out/NAME-DIGEST)")
    w.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a key of the study's base scene, e.g. --set chip.adc.comparator_noise_uV"
                        "=45 (repeatable; a condition of that key is pinned at the value)")
    w.add_argument("--axis", action="append", default=[], metavar="KEY=V1,V2|KEY=LO:HI:STEP",
                   help="the values of the axis of KEY, e.g. --axis chip.adc.bits=12:16:1 (a "
                        "condition stays one); a new KEY is a budget axis after the others")
    w.add_argument("--given", action="append", default=[], metavar="KEY=V1,V2",
                   help="a condition: one answer per value, e.g. --given chip.pixel.diode_w_um="
                        "50,100 (replaces the axis of KEY, or adds one; KEY1+KEY2=… gives both "
                        "keys the values together, e.g. a square diode's two sides)")
    w.add_argument("--replicates", type=int, metavar="N", help="runs per point (a bisection's "
                   "cap)")
    w.add_argument("--quick", action="store_true",
                   help=f"a first look: at most {QUICK_REPLICATES} replicates, each budget axis "
                        f"thinned to {QUICK_AXIS_VALUES} values (its ends kept), the conditions "
                        "whole; every output is labelled QUICK LOOK")


def _scenario_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="a TOML file, or the name of a bundled scenario")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value, e.g. --set chip.adc.bits=12 (repeatable)")
    p.add_argument("--seed", type=int, help="replace scenario.seed")


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the main thread is, so it unwinds as Ctrl-C does."""


def _raise_terminated(signum, frame) -> None:
    raise Terminated


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI in-process; returns the exit code."""
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        return _main(argv)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _main(argv: Sequence[str] | None) -> int:
    try:
        parser = build_parser()
        argv = list(sys.argv[1:] if argv is None else argv)
        if not argv:  # a bare `chiptwin`: what it does and how to start, on stderr
            print(parser.format_help(), file=sys.stderr, end="")
            return 2
        return _dispatch(parser.parse_args(argv))
    except UsageError as exc:
        bad = exc.parser
        if bad is parser and argv and argv[0] in _commands(parser):  # e.g. an unknown flag
            bad = _commands(parser)[argv[0]]
        print(bad.format_usage(), end="", file=sys.stderr)
        print(f"{bad.prog}: error: {exc}\n(`{bad.prog} --help` shows the options and "
              "examples)", file=sys.stderr)
        return 2
    except ScenarioError as exc:
        print(f"chiptwin: error: {exc}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # --help and --version
        return int(exc.code or 0)
    except BrokenPipeError:  # e.g. `chiptwin list | head`: the reader left, nothing is wrong
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 (Python's documented remedy)
        return 0
    except Terminated:
        print("chiptwin: terminated (SIGTERM)", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("chiptwin: interrupted", file=sys.stderr)
        return 130
    except Exception:  # an internal error: show it, it is a bug
        traceback.print_exc()
        print("chiptwin: internal error (the traceback above is a bug report)", file=sys.stderr)
        return 1


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The sub-commands' parsers, by name."""
    return next(a.choices for a in parser._actions
                if isinstance(a, argparse._SubParsersAction))


def _dispatch(args: argparse.Namespace) -> int:
    if args.command == "list":
        return _list()
    if args.command == "study":
        return _study(args)
    if args.command == "characterize":
        return characterize_command(args)
    if args.command == "reads":
        return reads_command(args)
    if args.command == "validate" and _is_study(args.scenario):
        return _validate_study(args.scenario, args.verbose)
    path = _scenario_path(args.scenario, studies_too=args.command == "validate")
    scenario = load_scenario(path, args.set, args.seed)
    if args.command == "validate":
        from chiptwin.config.consistency import scenario_warnings

        for warning in scenario_warnings(scenario):
            print(f"chiptwin: warning: {warning}", file=sys.stderr)
        print(f"{args.scenario}: ok ({scenario.scenario.name}{_bundled_note(args.scenario)})")
        from chiptwin.config.cost import describe as describe_cost

        print("\n".join(describe_cost(scenario)))
        if scenario.run.fidelity.auto_stages():
            from chiptwin.fidelity import describe, resolve

            print('fidelity "auto" would run at (nothing is run but calibrations, cached):')
            print("\n".join(describe(resolve(scenario)[1])))
        return 0
    if args.command == "dsp-report":
        return _dsp_report(scenario, args.json)
    if args.command == "ladder":
        return _ladder(scenario, args)
    from chiptwin.config.outputs import check_out_dir, output_lock
    from chiptwin.fidelity import run
    from chiptwin.report import headline, write_outputs

    out = check_out_dir(args.out or Path("out") / scenario.scenario.name)  # before the run
    from chiptwin.config.cost import check_disk

    check_disk(scenario, out)
    progress = None if args.quiet else _Progress()
    with output_lock(out), _working(progress):
        result = run(scenario, progress=progress)
        out = write_outputs(result, out, vcd=args.vcd)
    if not args.quiet:
        print(table(headline(result.summary)))
        print(table([("outputs in", f"{_shown(out)}/ (summary.json, run.nc, report.md, plots"
                                    + (", chip.vcd)" if args.vcd else ")"))]))
    return 0


def _dsp_report(scenario, json_path: str | None) -> int:
    import json

    from chiptwin.dsp.errors import format_error_table
    from chiptwin.report.dsp_report import dsp_report
    from chiptwin.twin.runner import stage_rng

    if json_path:
        _check_json_path(json_path)
    report = dsp_report(scenario, stage_rng(scenario.scenario.seed, "dsp_stress"))
    print(f"{scenario.scenario.name}: codes from the {report['converter']} converter")
    print(format_error_table(report))
    print(f"all bounds met: {report['all_bounds_ok']}")
    if json_path:
        Path(json_path).write_text(json.dumps(report, indent=2) + "\n")
    return 0


def _is_study(name: str) -> bool:
    path = resolve_study(name)
    if name in bundled_studies():
        return True
    try:
        import tomllib

        return path.is_file() and "study" in tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return False  # the scenario loader reports it


def _validate_study(name: str, verbose: bool = False) -> int:
    """Every point checked, as ``chiptwin study`` does before its first run: the inconsistent
    points grouped by the key that refuses them, and the estimated wall time."""
    from chiptwin.cli.text import invalid_summary
    from chiptwin.config.cost import ESTIMATE_FACTOR, format_seconds
    from chiptwin.study import load_study
    from chiptwin.study.engine import Plan, estimate_s

    study = load_study(_study_path(name), resolve_scenario)
    if study.kind == "optimize":  # a search, not a grid: its space, budget and wall time
        from chiptwin.study.optimize import describe

        print(fit([describe(study, os.cpu_count() or 1) + _bundled_note(name, study=True)]))
        return 0
    plan = Plan(study)
    n, bad = len(plan.points), len(plan.invalid)
    print(f"{study.name}: ok ({n} points × {study.replicates} replicates, "
          f"{len(plan.references)} reference point(s), search {study.search}"
          f"{_bundled_note(name, study=True)})")
    if study.quick:
        print(fit([f"  QUICK LOOK: {study.quick}"]))
    if bad:
        print(f"  {bad} of {n} points are inconsistent and will be recorded as invalid, not run:")
        print("\n".join(invalid_summary(plan.invalid.values())))
        if verbose:
            for pid, message in plan.invalid.items():
                params = ", ".join(f"{k}={v}" for k, v in plan.by_id[pid].params.items())
                reason = message.split("]: ", 1)[-1]
                print(table([(f"point {params}", reason)]))
        else:
            print("  (every point with its full reason: --verbose)")
    per_row, rows = estimate_s(plan)
    rows -= bad * study.replicates  # an invalid point's rows are recorded, not run
    workers = os.cpu_count() or 1
    print(textwrap.fill(
        f"estimated ≈ {format_seconds(per_row * rows / workers)} on {workers} local "
        f"process(es): {'at most ' if study.search != 'grid' else ''}{rows} rows of "
        f"≈ {format_seconds(per_row)} each (chiptwin.config.cost; within "
        f"{ESTIMATE_FACTOR:g}× either way)",
        WIDTH, initial_indent="  ", subsequent_indent="    "))
    return 0


def _bundled_note(name: str, study: bool = False) -> str:
    """", bundled" when a name (not a path) was read from the package's own copy."""
    bundled = bundled_studies() if study else bundled_scenarios()
    return ", bundled" if Path(name).stem in bundled and not Path(name).is_file() else ""


def _list() -> int:
    folder = bundled_scenarios_folder()
    scenarios = {name: first_sentences(opening_comment(p.read_text(encoding="utf-8")))
                 for name, p in sorted(bundled_scenarios().items())}
    studies = {name: first_sentences(opening_comment(p.read_text(encoding="utf-8")))
               for name, p in sorted(bundled_studies().items())}
    print("scenarios (chiptwin run NAME; chiptwin validate NAME):")
    print(listing(scenarios))
    print("\nstudies (chiptwin study NAME):")
    print(listing(studies))
    print("\n" + "\n".join(textwrap.wrap(
        f"A bundled name reads the file in {folder}; a path (my_chip.toml, ./pyro_1fmol.toml) "
        "reads that file. Copy one to start your own.", WIDTH)))
    return 0


def _study(args: argparse.Namespace) -> int:
    from chiptwin.config.outputs import check_out_dir, output_lock
    from chiptwin.study import run_study
    from chiptwin.study.files import write_atomic
    from chiptwin.study.store import DB_NAME
    from chiptwin.study.whatif import study_toml, study_with

    if args.workers is not None and not 1 <= args.workers <= 1024:
        raise ScenarioError("chiptwin", "--workers", args.workers, "must be in [1, 1024]")
    if args.rows_per_task is not None and not 1 <= args.rows_per_task <= MAX_ROWS_PER_TASK:
        raise ScenarioError("chiptwin", "--rows-per-task", args.rows_per_task,
                            f"must be in [1, {MAX_ROWS_PER_TASK}] (a task's rows travel back "
                            "in one message and are lost together if it is interrupted)")
    if args.in_flight is not None and not 1 <= args.in_flight <= MAX_IN_FLIGHT:
        raise ScenarioError("chiptwin", "--in-flight", args.in_flight,
                            f"must be in [1, {MAX_IN_FLIGHT}] (each task in flight is a future "
                            "the client holds)")
    if not 0 < args.worker_timeout <= MAX_WORKER_TIMEOUT_S:  # NaN too
        raise ScenarioError("chiptwin", "--worker-timeout", args.worker_timeout,
                            f"must be in (0, {MAX_WORKER_TIMEOUT_S:g}] seconds")
    study = study_with(_study_path(args.study), _overrides(args), resolve_scenario, args.study)
    from chiptwin.study.outputs import answer_lines, write_study_outputs  # after a refusal's line
    out = check_out_dir(args.out or Path("out") / study.name, marker=DB_NAME)
    with output_lock(out):
        new = not out.exists()
        out.mkdir(exist_ok=True)
        (out / "study.json").unlink(missing_ok=True)  # written last: its presence = complete
        write_atomic(out / "study.toml", study_toml(study))  # runs as it is, resumes this
        bounded = getattr(study, "search", "") == "bisect" or getattr(study, "stop_early", False)
        progress = None if args.quiet else _Progress("rows", after_s=0.0, at_most=bounded)
        try:
            with _working(progress):
                result = run_study(study, workers=args.workers, scheduler=args.scheduler,
                                   db=out / DB_NAME, fresh=args.fresh, progress=progress,
                                   announce=None if args.quiet else _announcer(progress),
                                   task_rows=args.rows_per_task, in_flight=args.in_flight,
                                   scheduler_file=args.scheduler_file,
                                   worker_timeout_s=args.worker_timeout)
            if progress is not None:
                progress.finish()  # the closing line of a study that stopped early
        except ScenarioError:  # refused before any row ran (scheduler, resumption): no trace
            if new:
                shutil.rmtree(out, ignore_errors=True)
            raise
        write_study_outputs(result, out)
    print(fit(answer_lines(result.summary)))
    runs = result.summary["runs"]
    print(fit([f"  {runs['total']} runs ({runs['computed']} computed now, {runs['resumed']} "
               f"resumed) in {result.summary['wall_time_s']:.1f} s; outputs in {_shown(out)}/ "
               "(study.json, results.csv, results.sqlite, report.md, study.toml: the study as "
               "run)"]))
    return 0


def _overrides(args: argparse.Namespace):
    """The what-ifs of ``chiptwin study`` (:class:`chiptwin.study.whatif.Overrides`)."""
    from chiptwin.study.whatif import Overrides

    return Overrides(tuple(args.set), tuple(args.axis), tuple(args.given), args.replicates,
                     args.quick)


def _announcer(progress: _Progress | None):
    """Print a study's estimated total before its first row; its progress's ETA uses it."""
    from chiptwin.config.cost import format_seconds

    def announce(seconds: float, rows: int) -> None:
        print(f"  {rows} rows to run, estimated ≈ {format_seconds(seconds)} (chiptwin.config.cost"
              "; a bisect may stop sooner)", file=sys.stderr, flush=True)
        if progress is not None and rows:
            progress.per_unit_s = seconds / rows

    return announce


def _ladder_weights(scenario, args: argparse.Namespace) -> list[float]:
    """Estimated seconds of each rung of the ladder (its warm-up and replicates)."""
    from chiptwin.config.cost import wall_seconds
    from chiptwin.fidelity.ladder import plan, with_levels

    out = []
    for rung in plan(scenario, _reference_levels(args.reference)):
        out.append(0.0 if rung.skipped else
                   (args.replicates + 1) * wall_seconds(with_levels(scenario, rung.fidelity)))
    return out


def _ladder(scenario, args: argparse.Namespace) -> int:
    import json

    from chiptwin.config.outputs import check_out_dir, output_lock
    from chiptwin.fidelity.ladder import run_ladder, table, write_ladder

    out = check_out_dir(args.out or Path("out") / f"{scenario.scenario.name}_ladder",
                        marker="ladder.json")
    if args.json:
        _check_json_path(args.json)
    from chiptwin.config.cost import format_seconds

    with output_lock(out):
        weights = _ladder_weights(scenario, args)
        print(f"  {sum(w > 0 for w in weights)} levels × {args.replicates} replicates (+1 "
              f"warm-up), estimated ≈ {format_seconds(sum(weights))}", file=sys.stderr,
              flush=True)
        progress = _Progress("levels", after_s=0.0, weights=weights)
        with _working(progress):
            ladder = run_ladder(scenario, args.replicates, _reference_levels(args.reference),
                                progress=progress)
        print(table(ladder))
        write_ladder(ladder, out)
    if args.json:
        Path(args.json).write_text(json.dumps(ladder, indent=1) + "\n")
    print(f"  outputs in {_shown(out)}/ (ladder.json, ladder.png, ladder.md)")
    return 0


def _reference_levels(pins: list[str]) -> dict[str, str]:
    from chiptwin.fidelity.ladder import LEVELS

    out = {}
    for pin in pins:
        stage, _, level = pin.partition("=")
        if level not in LEVELS.get(stage, ()):
            raise ScenarioError("chiptwin", "--reference", pin, "must be STAGE=LEVEL, one of "
                                + ", ".join(f"{k}={v}" for k, lv in LEVELS.items() for v in lv))
        out[stage] = level
    return out


def entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
