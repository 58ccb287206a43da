"""Answers labelled by condition: a study with a given axis states one answer per condition,
named (``key = value``) on the terminal, in report.md, in study.json and in every plot (one
line and one star per condition, a legend naming each, whole-number ticks on a whole-number
axis); a ``--quick`` study says so in each of them; its ``study.toml`` runs again as it is.

One real what-if of the suite's small study (4 × 6 chip, 14 flows) run once through the CLI:
the bit axis 6 … 12 thinned by ``--quick`` to 6, 8, 10, 12, the read noise a condition of two
values; each figure is caught at ``outputs._save`` and read through matplotlib (no pixels)."""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from chiptwin.cli import main
from chiptwin.study import outputs
from chiptwin.study.outputs import answer_lines, condition_label, plot_lines
from tests.study.conftest import write_study

NOISE = "chip.pixel.read_noise_e"
BITS = "chip.adc.bits"
CONDITIONS = [f"{NOISE} = 50.0", f"{NOISE} = 200.0"]
ARGV = ["--axis", f"{BITS}=6:12:1", "--given", f"{NOISE}=50,200", "--quick", "--workers", "1",
        "--quiet"]


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """The what-if run once: its folder, what it printed, and each figure as it was saved."""
    folder = tmp_path_factory.mktemp("conditions")
    path = write_study(folder)
    out = folder / "out"
    saved = {}
    mp = pytest.MonkeyPatch()

    def spy(fig, where, name, caption, **kw):
        ax = fig.axes[0]
        saved[name] = {
            "title": fig._suptitle.get_text() if fig._suptitle else ax.get_title(),
            "lines": [ln for ln in ax.get_lines() if ln.get_marker() == "o"],
            "stars": [ln for ln in ax.get_lines() if ln.get_marker() == "*"
                      and len(ln.get_xdata())],
            "legend": [t.get_text() for t in ax.get_legend().get_texts()]
            if ax.get_legend() else [],
            "xticks": list(ax.get_xticks()), "caption": caption}
        import matplotlib.pyplot as plt

        plt.close(fig)
        return name, caption

    mp.setattr(outputs, "_save", spy)
    stdout = io.StringIO()
    try:
        with contextlib.redirect_stdout(stdout):
            assert main(["study", str(path), "--out", str(out), *ARGV]) == 0
    finally:
        mp.undo()
    return out, stdout.getvalue(), saved


@pytest.mark.slow
def test_study_json_labels_each_answer_with_its_condition_and_says_quick(ran):
    out, _, _ = ran
    summary = json.loads((out / "study.json").read_text())
    assert [a["condition"] for a in summary["answer"]] == CONDITIONS
    assert [a["given"] for a in summary["answer"]] == [{NOISE: 50.0}, {NOISE: 200.0}]
    assert summary["quick"] == f"{BITS} 7 values → 6, 8, 10, 12"
    assert summary["asked"].endswith(f"--axis {BITS}=6:12:1 --given {NOISE}=50,200 --quick")
    assert sorted({p["params"][BITS] for p in summary["points"]}) == [6, 8, 10, 12]


@pytest.mark.slow
def test_terminal_and_report_name_each_condition_and_say_quick(ran):
    out, printed, _ = ran
    assert printed.startswith("QUICK LOOK (chip.adc.bits 7 values → 6, 8, 10, 12)")
    for c in CONDITIONS:
        assert f"[{c}] cheapest: " in printed or f"[{c}] no point meets" in printed
    report = (out / "report.md").read_text()
    assert report.startswith("# Study small_study-quick-")
    assert report.splitlines()[0].endswith("(quick look)")
    assert "## Answer, one per condition" in report and "Asked as: `chiptwin study" in report
    bullets = [line for line in report.splitlines() if line.startswith("- [")]
    assert [b.split("]")[0][3:] for b in bullets] == CONDITIONS


@pytest.mark.slow
def test_each_plot_has_one_line_and_one_star_per_condition_named_in_its_legend(ran):
    out, _, saved = ran
    summary = json.loads((out / "study.json").read_text())
    answered = sum(a["point"] is not None for a in summary["answer"])
    metric_plots = {k: v for k, v in saved.items() if "_vs_" in k}
    assert len(metric_plots) >= 4
    for name, fig in metric_plots.items():
        assert len(fig["lines"]) == len(CONDITIONS), name
        assert set(CONDITIONS) <= set(fig["legend"]), (name, fig["legend"])
        assert fig["title"].startswith("QUICK LOOK: ") and fig["caption"].startswith("QUICK")
        assert all(float(t).is_integer() for t in fig["xticks"]), (name, fig["xticks"])
        if name.startswith("base_error_rate"):  # the requirement's metric: the answers starred
            assert len(fig["stars"]) == answered


@pytest.mark.slow
def test_plot_lines_give_each_condition_its_own_line_and_answer(ran):
    out, _, _ = ran
    summary = json.loads((out / "study.json").read_text())
    lines = plot_lines(summary, BITS, "base_error_rate")
    assert [ln.label for ln in lines] == CONDITIONS
    for ln, a in zip(lines, summary["answer"], strict=True):
        assert list(ln.x) == [6, 8, 10, 12]  # cheapest first, not joined across conditions
        if a["point"] is None:
            assert ln.star is None
        else:
            assert ln.x[ln.star] == a["point"][BITS]


@pytest.mark.slow
def test_the_written_study_toml_runs_as_it_is_and_resumes_every_row(ran):
    out, _, _ = ran
    before = json.loads((out / "study.json").read_text())
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(["study", str(out / "study.toml"), "--out", str(out), "--workers", "1",
                     "--quiet"]) == 0
    after = json.loads((out / "study.json").read_text())
    assert after["runs"]["computed"] == 0 and after["runs"]["resumed"] == before["runs"]["total"]
    assert [a["statement"] for a in after["answer"]] == [a["statement"] for a in
                                                          before["answer"]]
    assert after["quick"] == before["quick"]


def test_answer_lines_name_the_condition_of_a_budget_study():
    """A budget study's answers once printed no condition (the sensitivity study's shortening
    hid every given axis): two answers read 'cheapest: … = 14' and '= 15', for what?"""
    summary = {"answer": [{"given": {"assay.dna_fmol": 1.0}, "statement": "cheapest: 14"},
                          {"given": {"assay.dna_fmol": 0.1}, "statement": "cheapest: 15"}],
               "monotonicity": {"violations": []}}
    assert answer_lines(summary) == ["[assay.dna_fmol = 1.0] cheapest: 14",
                                     "[assay.dna_fmol = 0.1] cheapest: 15"]
    summary["quick"] = "replicates 90 → 10"
    assert answer_lines(summary)[0].startswith("QUICK LOOK (replicates 90 → 10)")


@pytest.mark.parametrize(("given", "reference", "label"), [
    ({"a": 1}, {}, "a = 1"),
    ({"a": 1, "b": 2}, {}, "a = 1, b = 2"),
    ({}, {}, ""),
    ({"a": 1, "qe": 0.4}, {"qe": 0.4}, "a = 1, reference"),  # an assumption at its reference
    ({"a": 1, "qe": 0.6}, {"qe": 0.4}, "a = 1, qe = 0.6"),  # moved: named
])
def test_condition_label(given, reference, label):
    assert condition_label(given, reference) == label
