"""The study report: the status map shows a third budget axis as facets and
names the states on its colour bar; the points table leads with the requirement a point fails.

One real study: the bundled ``frame_memory`` (three budget axes: 5 memories × 3 N × 2 K, with
passing, failing and invalid points) at 2 replicates and 8 flows, run once in this process and
shared with ``test_bundled`` (``conftest.frame_memory_result``); the saved figure is caught at
``outputs._save`` and its axes counted through matplotlib (no pixels compared)."""

from __future__ import annotations

import pytest

from chiptwin.study import outputs

DARK = "chip.dsp.n_dark_frames"


@pytest.fixture(scope="module")
def written(tmp_path_factory, frame_memory_result):
    """The study's outputs written, and every figure's non-colour-bar axes as it was saved."""
    result = frame_memory_result
    saved = {}
    real = outputs._save
    mp = pytest.MonkeyPatch()

    def spy(fig, folder, name, caption, **kw):
        saved[name] = {"facets": [ax for ax in fig.axes if ax.get_label() != "<colorbar>"],
                       "bars": [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]}
        if name == "status_map.png":
            return real(fig, folder, name, caption, **kw)
        # the 21 metric-vs-axis figures are made but not rendered to PNG (≈ 0.5 s each in
        # matplotlib): nothing here reads them; test_engine's CLI run writes them for real
        import matplotlib.pyplot as plt  # make_plots has chosen the Agg backend

        plt.close(fig)
        return name, caption

    mp.setattr(outputs, "_save", spy)
    out = tmp_path_factory.mktemp("frame_memory")
    try:
        outputs.write_study_outputs(result, out)
    finally:
        mp.undo()
    return result.summary, saved, out


def test_status_map_has_one_facet_per_value_of_the_third_axis(written):
    summary, saved, out = written
    status = saved["status_map.png"]
    assert (out / "status_map.png").is_file()
    assert [ax.get_title() for ax in status["facets"]] == [f"{DARK} = 4", f"{DARK} = 16"]
    (bar,) = status["bars"]
    assert [t.get_text() for t in bar.get_yticklabels()] == ["invalid", "fail", "undecided",
                                                             "pass"]


def test_points_table_leads_with_the_failing_requirement(written):
    summary, _, out = written
    text = (out / "report.md").read_text()
    table = [line for line in text.splitlines() if line.startswith("| ")]
    header = [c.strip() for c in table[0].strip("|").split("|")]
    assert header[:3] == ["fails", "point", "status"]
    assert header[4:6] == ["frames_dropped", "snr_loss_db"]  # the required metrics first
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in table[1:]]
    assert len(rows) == len(summary["points"])
    by_status = {}
    for row in rows:
        by_status.setdefault(row[2], []).append(row[0])
    assert by_status["fail"] and all(q in summary["requirement"]
                                     for c in by_status["fail"] for q in c.split("; "))
    assert set(by_status.get("pass", [])) | set(by_status.get("invalid", [])) <= {"–"}
