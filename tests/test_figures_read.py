"""What a run's figures draw (``chiptwin.twin.figures``), read off the figure objects: site curves
that stay apart where they overlap, the frame memory against its capacity line and legible over
thousands of frames, a quality bin without an observed error drawn as its 95 % upper bound."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from chiptwin.twin import figures  # noqa: E402


@pytest.fixture
def ax():
    fig, ax = plt.subplots()
    yield ax
    plt.close(fig)


# ------------------------------------------------------------------------------ light curves


def test_overlapping_site_curves_differ_in_colour_dash_and_marker(ax):
    """Two sites with the same signal: each line keeps its own colour, dash pattern and marker,
    and their markers sit at different points, so the one drawn second does not hide the first."""
    t = np.linspace(0.0, 100.0, 200)
    same = np.exp(-t / 30.0)
    figures.light_curves(ax, t, [same, same], ["site 0", "site 1"])
    a, b = ax.get_lines()
    assert a.get_color() != b.get_color()
    assert a.get_linestyle() != b.get_linestyle()
    assert a.get_marker() != b.get_marker()
    assert a.get_markevery() != b.get_markevery()
    assert [a.get_label(), b.get_label()] == ["site 0", "site 1"]


def test_sixteen_site_styles_are_all_different():
    styles = figures.site_styles(16)
    assert len({tuple(sorted(s.items())) for s in styles}) == 16
    for one, two in zip(styles, styles[1:], strict=False):  # neighbours differ in all three
        assert all(one[k] != two[k] for k in ("color", "ls", "marker"))


# ------------------------------------------------------------------------------------ memory


def _capacity_lines(ax, capacity):
    return [ln for ln in ax.get_lines()
            if np.allclose(ln.get_ydata(), capacity) and "capacity" in ln.get_label()]


def test_memory_plot_has_its_capacity_line(ax):
    figures.memory_occupancy(ax, [0.0, 1.0, 2.0, 3.0], [0, 4, 8, 0], capacity_frames=63)
    assert len(_capacity_lines(ax, 63)) == 1
    assert ax.get_ylim()[1] > 63  # the line is inside the plot
    steps = [ln for ln in ax.get_lines() if ln.get_label() == "frames held"]
    assert len(steps) == 1


def test_memory_plot_of_thousands_of_frames_is_binned_not_a_band_of_strokes(ax):
    """1,520 frames, each written then freed: 3,040 changes become a band of the lowest and
    highest occupancy per bin with at most MEMORY_BINS steps, and the capacity line."""
    t = np.repeat(np.arange(1520.0), 2) + np.tile([0.0, 0.5], 1520)
    frames = np.tile([4, 0], 1520)
    figures.memory_occupancy(ax, t, frames, capacity_frames=63)
    assert len(_capacity_lines(ax, 63)) == 1
    bands = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(bands) == 1
    highest = [ln for ln in ax.get_lines() if ln.get_label() == "highest"]
    assert len(highest) == 1 and len(highest[0].get_xdata()) <= figures.MEMORY_BINS
    assert np.all(highest[0].get_ydata() == 4)


def _extremes_naive(t, v, edges):
    """Each bin's lowest and highest value, one bin at a time: the value carried in at the
    bin's start and every change inside it."""
    lo, hi = [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        last = b == edges[-1]
        inside = [x for ti, x in zip(t, v, strict=True) if a <= ti and (ti < b or last)]
        before = [x for ti, x in zip(t, v, strict=True) if ti <= a]
        vals = inside + ([before[-1]] if before else [v[0]])
        lo.append(min(vals))
        hi.append(max(vals))
    return np.array(lo), np.array(hi)


@pytest.mark.parametrize("seed", range(5))
def test_binned_extremes_match_the_obvious_reference(seed):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 50.0, 400))
    v = rng.integers(0, 20, 400)
    edges, lo, hi = figures.binned_extremes(t, v, 37)
    ref_lo, ref_hi = _extremes_naive(t, v, edges)
    np.testing.assert_array_equal(lo, ref_lo)
    np.testing.assert_array_equal(hi, ref_hi)


# ------------------------------------------------------------------------ quality calibration

CAL = [
    {"q_lo": 10, "q_hi": 20, "bases": 400, "errors": 12, "stated_error": 0.03,
     "observed_error": 0.03, "ci_low": 0.016, "ci_high": 0.052},
    {"q_lo": 20, "q_hi": 30, "bases": 1500, "errors": 0, "stated_error": 0.004,
     "observed_error": 0.0, "ci_low": 0.0, "ci_high": 0.00246},
    {"q_lo": 35, "q_hi": 41, "bases": 36, "errors": 0, "stated_error": 0.0,
     "observed_error": 0.0, "ci_low": 0.0, "ci_high": 0.0974},
]


def test_zero_error_bins_are_drawn_as_upper_bounds_at_three_over_n(ax):
    figures.quality_calibration(ax, CAL)
    bounds = [ln for ln in ax.get_lines() if ln.get_marker() == "v"]
    assert len(bounds) == 1
    np.testing.assert_allclose(bounds[0].get_ydata(), [3 / 1500, 3 / 36])
    # the stated 0 of the Q35–40 bin at Q40's 1e-4, the other at its stated error
    np.testing.assert_allclose(bounds[0].get_xdata(), [0.004, 1e-4])
    arrows = [c for c in ax.texts if getattr(c, "arrow_patch", None) is not None]
    assert len(arrows) == 2
    for arrow in arrows:  # each points down, from the bound
        assert arrow.xy[1] < arrow.xyann[1]
        assert arrow.xy[0] == arrow.xyann[0]
    for line in ax.get_lines():  # no point parked at a floor (the old 1e-5)
        assert np.min(line.get_ydata()) > 1e-5 or line.get_label() == "stated = observed"


def test_a_tiny_stated_error_sits_at_its_bins_quality_and_bounds_stop_at_one(ax):
    """A caller sure of its bases states 1e-16, which its Q40 cap cannot say: drawn at 1e-4; a
    bin of 2 bases bounds the rate at 1, not 3/2."""
    cal = [{**CAL[2], "stated_error": 1.4e-16},
           {**CAL[1], "bases": 2, "q_lo": 10, "q_hi": 15, "stated_error": 0.05}]
    figures.quality_calibration(ax, cal)
    (bounds,) = [ln for ln in ax.get_lines() if ln.get_marker() == "v"]
    np.testing.assert_allclose(bounds.get_xdata(), [1e-4, 0.05])
    np.testing.assert_allclose(bounds.get_ydata(), [3 / 36, 1.0])


def test_observed_errors_keep_their_points_and_interval(ax):
    figures.quality_calibration(ax, CAL[:1])
    points = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
    assert len(points) == 1 and points[0].get_ydata()[0] == 0.03
    assert not [ln for ln in ax.get_lines() if ln.get_marker() == "v"]


def test_rule_of_three_is_a_95_percent_bound_by_monte_carlo():
    """At an error rate equal to the bound 3/n, a bin of n bases shows no error in ≤ 5 % of
    draws ((1 − 3/n)^n < e^−3 = 4.98 %): so "none seen" puts the rate below 3/n at 95 %.
    400,000 binomial draws per n; tolerance 4 binomial standard errors."""
    rng = np.random.default_rng(20261129)
    draws = 400_000
    for n in (36, 300, 5000):
        p = figures.zero_error_bound(n)
        zero = np.mean(rng.binomial(n, p, size=draws) == 0)
        exact = (1 - p) ** n
        se = np.sqrt(exact * (1 - exact) / draws)
        assert abs(zero - exact) < 4 * se
        assert zero < 0.05 + 4 * se and exact < 0.05


# -------------------------------------------------------------------------- a run's figures


def test_a_runs_figures_use_them(small_toml, tmp_path, monkeypatch):
    """make_plots of a small pyrosequencing run: the light curve's sites differ in style, the
    memory plot has the capacity line of the run's summary, the calibration plot no 1e-5 floor."""
    import chiptwin as ct
    from chiptwin.report import outputs, read_plots

    kept = {}

    def keep(fig, folder, name, caption="", **kw):
        kept[name] = fig
        return name, caption

    monkeypatch.setattr(outputs, "_save", keep)
    monkeypatch.setattr(read_plots, "_save", keep)
    result = ct.run(small_toml, seed=1)
    outputs.make_plots(result, tmp_path)
    lines = kept["light_curve.png"].axes[0].get_lines()
    assert len(lines) == 2 and lines[0].get_linestyle() != lines[1].get_linestyle()
    capacity = result.summary["chip"]["memory_capacity_frames"]
    assert len(_capacity_lines(kept["memory.png"].axes[0], capacity)) == 1
    cal_ax = kept["quality_calibration.png"].axes[0]
    for line in cal_ax.get_lines():
        assert np.min(line.get_ydata()) > 1e-5 or line.get_label() == "stated = observed"
    for fig in kept.values():
        plt.close(fig)
