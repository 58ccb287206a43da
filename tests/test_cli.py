"""The command line guides a new user: usage and examples, whole sentences, close names, the key
that fixes a refusal, lines within 100 columns, counters in words, progress in a log file.

In-process (``chiptwin.cli.main``) with pytest's capsys; no test runs a long scene.
"""

from __future__ import annotations

import re

import pytest

from chiptwin.cli import _Progress, build_parser, main
from chiptwin.cli import text as cli_text
from chiptwin.config import load_scenario
from chiptwin.config.catalog import bundled_scenarios, bundled_studies
from chiptwin.report.outputs import headline
from chiptwin.twin.runner import run

COMMANDS = ["run", "validate", "list", "dsp-report", "characterize", "ladder", "study"]


def _lines_fit(text: str, width: int = cli_text.WIDTH) -> None:
    long = [line for line in text.splitlines() if len(line) > width]
    assert not long, long


def test_bare_chiptwin_prints_usage_and_examples_and_exits_2(capsys):
    assert main([]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: chiptwin")
    assert "chiptwin run pyro_1fmol" in err and "chiptwin list" in err
    assert "(arguments)" not in err and "required: command" not in err
    _lines_fit(err)


@pytest.mark.parametrize("command", COMMANDS)
def test_every_help_has_examples_and_the_pointers(command, capsys):
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    examples = out.split("examples:\n", 1)[1]
    assert len(re.findall(rf"^  chiptwin {command}\b", examples, flags=re.M)) >= 1
    assert "`chiptwin list`" in out and "documentation" in out
    _lines_fit(out)


def test_a_missing_argument_shows_the_commands_usage(capsys):
    assert main(["run"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: chiptwin run")
    assert "required: scenario" in err and "chiptwin run --help" in err


def test_an_unknown_flag_shows_the_subcommands_usage(capsys):
    assert main(["run", "pyro_1fmol", "--bogus"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: chiptwin run") and "--bogus" in err


def test_list_wraps_whole_sentences_within_100_columns(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    _lines_fit(out)
    blocks = re.split(r"\n(?=\S)", out)  # a name and its wrapped description
    names = {*bundled_scenarios(), *bundled_studies()}
    described = {b.split()[0]: " ".join(b.split()[1:]) for b in blocks if b.split()[0] in names}
    assert set(described) == names
    for name, text in described.items():
        assert text.endswith((".", ")", '"', "?")), (name, text)  # never cut mid-sentence


@pytest.mark.parametrize(("text", "first"), [
    ("One sentence. Another one here.", "One sentence. Another one here."),
    ('Quoted "a. B c" stays. Next.', 'Quoted "a. B c" stays. Next.'),
    ("Fig. 12 (see et al. 2004. And more) ends. Then " + "x" * 300 + ".",
     "Fig. 12 (see et al. 2004. And more) ends."),
])
def test_first_sentences_never_split_inside_quotes_or_parentheses(text, first):
    assert cli_text.first_sentences(text) == first


@pytest.mark.parametrize(("typed", "command", "suggested"), [
    (["run", "pyro1fmol"], "run", "pyro_1fmol"),
    (["run", "pyro_1fmol.tom"], "run", "pyro_1fmol"),
    (["validate", "frame_memry"], "validate", "frame_memory"),
    (["study", "adc_bits"], "study", "adc_bits_pyro"),
])
def test_an_unknown_name_suggests_the_closest_and_list(typed, command, suggested, capsys):
    assert main(typed) == 2
    err = capsys.readouterr().err
    assert f"did you mean {suggested}" in err and "`chiptwin list`" in err
    assert "Errno" not in err and len(err.splitlines()) == 1


def test_a_name_close_to_nothing_still_points_to_list(capsys):
    assert main(["run", "qqqqqq"]) == 2
    err = capsys.readouterr().err
    assert "did you mean" not in err and "`chiptwin list`" in err


def test_validate_a_study_groups_the_inconsistent_points_and_estimates_time(capsys):
    assert main(["validate", "frame_memory"]) == 0
    out = capsys.readouterr().out
    _lines_fit(out)
    assert "18 of 30 points are inconsistent" in out
    grouped = re.findall(r"^ +(\d+) × ([\w.]+): ", out, flags=re.M)
    assert sum(int(n) for n, _ in grouped) == 18
    assert len(grouped) == len({key for _, key in grouped}) == 3  # one line per reason
    assert ("14", "chip.memory.capacity_bits") in grouped
    assert "estimated ≈" in out and "rows" in out
    assert "/" not in out.split("\n", 1)[0] and "scenarios/" not in out  # no installed paths
    assert main(["validate", "frame_memory", "--verbose"]) == 0
    verbose = capsys.readouterr().out
    assert verbose.count("point chip.memory.capacity_bits=") == 18
    _lines_fit(verbose)


def test_invalid_summary_takes_the_range_of_a_bound_that_varies():
    messages = [f"/a/b.toml [x=1]: chip.memory.capacity_bits = {v}: must be ≥ {need} bits: a "
                "block of frames" for v, need in ((1, 500), (2, 70), (3, 900))]
    messages.append("/a/b.toml [x=2]: assay.start_s = 20.0: must be the end of the dark frames")
    lines = cli_text.invalid_summary(messages)
    assert lines == ["     3 × chip.memory.capacity_bits: must be ≥ 70 … 900 bits (by point)",
                     "     1 × assay.start_s: must be the end of the dark frames"]


def test_the_frame_schedule_refusal_names_the_clock_that_fits(capsys):
    assert main(["validate", "pyro_1fmol", "--set", "chip.adc.bits=15"]) == 2
    err = capsys.readouterr().err
    m = re.search(r"set chip\.adc\.clock_hz ≥ ([\d.]+e\d+)", err)
    assert m, err
    clock = float(m.group(1))
    assert main(["validate", "pyro_1fmol", "--set", "chip.adc.bits=15",
                 "--set", f"chip.adc.clock_hz={clock}"]) == 0
    capsys.readouterr()
    below = clock * 0.995  # the smallest such clock, to its 3 digits
    assert main(["validate", "pyro_1fmol", "--set", "chip.adc.bits=15",
                 "--set", f"chip.adc.clock_hz={below}"]) == 2


def test_an_overlong_integration_names_the_longest_that_fits(capsys):
    assert main(["validate", "pyro_1fmol", "--set", "chip.timing.t_int_s=1.0"]) == 2
    m = re.search(r"set chip\.timing\.t_int_s ≤ ([\d.]+)", capsys.readouterr().err)
    assert m
    assert main(["validate", "pyro_1fmol", "--set", f"chip.timing.t_int_s={m.group(1)}"]) == 0


def test_the_terminal_table_fits_100_columns_and_counts_in_words(small_toml):
    scenario = load_scenario(small_toml, ["run.fidelity.dsp=fixed"])
    rows = headline(run(scenario).summary)
    text = cli_text.table(rows)
    _lines_fit(text)
    assert "{" not in text and "'sat'" not in text
    assert re.search(r"overflow events: \d+ saturated, \d+ wrapped", text)
    assert re.search(r"^  optics {22}", text, flags=re.M)  # the label fits its column


def test_a_label_longer_than_its_column_gets_its_own_line():
    text = cli_text.table([("a" * 40, "value " * 30), ("short", "v")])
    _lines_fit(text)
    lines = text.splitlines()
    assert lines[0] == "  " + "a" * 40 and lines[1].startswith(" " * 31 + "value")
    assert lines[-1] == "  short" + " " * 24 + "v"


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_progress_to_a_file_prints_rate_and_eta_every_few_seconds(monkeypatch, capsys):
    clock = _Clock()
    monkeypatch.setattr("chiptwin.cli.progress.time.perf_counter", clock)
    p = _Progress("frames")
    assert not p.tty  # capsys: not a terminal
    for k in range(1, 1001):
        clock.t += 0.02  # 50 frames/s, 20 s in all
        p(k, 1000)
    lines = capsys.readouterr().err.splitlines()
    assert 3 <= len(lines) <= 5, lines  # every 5 s, and the closing line
    assert all(re.search(r"frames \d+/1000 \(\d+ %, 50 frames/s, ETA \d+ s\)", line)
               for line in lines[:-1]), lines
    assert lines[-1].strip() == "frames 1000/1000 (100 %) in 20.0 s"


def test_progress_stays_silent_on_a_quick_run(monkeypatch, capsys):
    clock = _Clock()
    monkeypatch.setattr("chiptwin.cli.progress.time.perf_counter", clock)
    p = _Progress("frames")
    for k in range(1, 101):
        clock.t += 0.001
        p(k, 100)
    assert capsys.readouterr().err == ""


def test_the_parser_names_every_command():
    parser = build_parser()
    assert set(COMMANDS) <= set(parser.format_help().split())


def test_a_folder_named_like_a_bundled_scenario_does_not_hide_it(tmp_path, monkeypatch, capsys):
    """One rule: a name that is a file is that file, any other name a bundled scenario's
    (``chiptwin run pyro_1fmol --out pyro_1fmol`` leaves such a folder behind)."""
    (tmp_path / "pyro_1fmol").mkdir()
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "pyro_1fmol"]) == 0
    assert capsys.readouterr().out.startswith("pyro_1fmol: ok (pyro_1fmol, bundled)")


def test_fit_wraps_long_lines_under_their_indent():
    text = cli_text.fit(["short", "    " + "word " * 40])
    lines = text.splitlines()
    _lines_fit(text)
    assert lines[0] == "short" and lines[1].startswith("    word")
    assert lines[2].startswith("      word")


def test_study_help_names_each_what_if_with_an_example_that_validates(capsys):
    """``chiptwin study --help`` lists --set, --axis, --given, --replicates and --quick, and
    its what-if example is a study the parser and the loader accept (nothing run)."""
    from chiptwin.config.catalog import resolve_scenario, resolve_study
    from chiptwin.study.whatif import Overrides, study_with

    assert main(["study", "--help"]) == 0
    out = capsys.readouterr().out
    for flag in ("--set", "--axis", "--given", "--replicates", "--quick"):
        assert re.search(rf"^  {flag} ", out, flags=re.M), flag
    example = next(cmd for cmd, _ in cli_text.EXAMPLES["study"] if "--given" in cmd).split()
    args = build_parser().parse_args(example[1:])
    study = study_with(resolve_study(args.study), Overrides(
        tuple(args.set), tuple(args.axis), tuple(args.given), args.replicates, args.quick),
        resolve_scenario)
    assert {a.key for a in study.given_axes} >= {"chip.pixel.qe", "assay.dna_fmol"}
