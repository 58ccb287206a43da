"""The one way chiptwin saves a figure (tight layout, one draw, PNG at 100 dpi, atomically) and
what a run's figures draw that a reader must not misread: curves of several sites in styles that
stay apart where they overlap, the frame memory against its capacity, a quality bin without an
observed error as an upper bound.

``Figure.tight_layout()`` leaves a placeholder layout engine on the figure, and ``savefig`` on a
figure with any layout engine draws it once more without rendering before the real draw (to lay
it out; matplotlib 3.11, ``FigureCanvasBase.print_figure``). The layout is already done, so the
engine is removed: the file is byte for byte the same, one draw cheaper (a run's light curve
with a colorbar: 180–197 ms → 135–150 ms, three saves each). Figures made with
``layout="constrained"`` keep their engine (``tight=False``): their layout happens in that draw.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

#: Resolution of every PNG chiptwin writes.
DPI = 100


def save_figure(fig, folder: Path, name: str, caption: str = "", *,
                tight: bool = True) -> tuple[str, str]:
    """Save ``fig`` as ``folder / name`` (through a temporary file and a rename, so a reader
    never sees half a PNG), close it and return ``(name, caption)`` for the report."""
    import matplotlib.pyplot as plt

    if tight:
        fig.tight_layout()
        fig.set_layout_engine(None)
    tmp = folder / f".{name}.tmp.png"
    try:
        fig.savefig(tmp, dpi=DPI)
        os.replace(tmp, folder / name)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return name, caption


# ------------------------------------------------------------------ what a run's figures draw

#: Line styles and markers that tell overlapping curves apart in grey print too; colours from
#: matplotlib's tab10, so 10 × 4 × 8 curves differ in at least one of the three.
LINESTYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "v", "D", "x", "+", "*")


def site_styles(n: int) -> list[dict]:
    """The style of each of ``n`` curves: colour, line style and marker all change from one
    curve to the next, so a curve drawn over another stays visible (its dashes and markers)."""
    return [{"color": f"C{i % 10}", "ls": LINESTYLES[i % len(LINESTYLES)],
             "marker": MARKERS[i % len(MARKERS)]} for i in range(n)]


def light_curves(ax, t_s, signals, labels) -> None:
    """One curve per site, each in its own style (:func:`site_styles`); markers at about 25
    points a curve, staggered so that identical curves show each one's markers."""
    n, every = len(labels), max(1, len(t_s) // 25)
    for i, (signal, label, style) in enumerate(zip(signals, labels, site_styles(n),
                                                   strict=True)):
        ax.plot(t_s, signal, lw=0.9, ms=3.5, markevery=(i * every // n, every), label=label,
                mfc="none", **style)


#: Time bins the memory plot shows at most: beyond, a step line turns into a solid band.
MEMORY_BINS = 300


def memory_occupancy(ax, t_s, frames, capacity_frames: int) -> None:
    """The frame memory's occupancy against its capacity (a dashed line at the capacity).

    Few changes: the occupancy as a step line. Many (a run of thousands of frames): per time bin
    the lowest and highest occupancy as a shaded band with the highest as a step line, so the
    plot shows how full the memory gets and how far it drains, not a band of vertical strokes.
    """
    t_s, frames = np.asarray(t_s, float), np.asarray(frames, float)
    if len(t_s) <= 2 * MEMORY_BINS:
        ax.step(t_s, frames, where="post", lw=1.0, color="C0", label="frames held")
    else:
        edges, lo, hi = binned_extremes(t_s, frames, MEMORY_BINS)
        ax.fill_between(edges[:-1], lo, hi, step="post", color="C0", alpha=0.3, lw=0,
                        label=f"lowest … highest per {edges[1] - edges[0]:.3g} s")
        ax.step(edges[:-1], hi, where="post", lw=1.0, color="C0", label="highest")
    ax.axhline(capacity_frames, color="C3", ls="--", lw=1.2,
               label=f"capacity, {capacity_frames} frames")
    ax.set_ylim(0, 1.15 * max(capacity_frames, float(frames.max(initial=0.0)), 1.0))
    ax.legend(fontsize=7, loc="upper right")


def binned_extremes(t_s: np.ndarray, values: np.ndarray, n_bins: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lowest and highest value of a step function (``values[i]`` from ``t_s[i]`` on, times
    sorted) in each of ``n_bins`` equal bins over ``t_s[0] … t_s[-1]``: the value carried into
    a bin counts as well as the changes inside it. Returns ``(edges, lowest, highest)``."""
    edges = np.linspace(t_s[0], t_s[-1], n_bins + 1)
    carried = values[np.clip(np.searchsorted(t_s, edges[:-1], side="right") - 1, 0, None)]
    which = np.clip(np.searchsorted(edges, t_s, side="right") - 1, 0, n_bins - 1)
    lo, hi = carried.copy(), carried.copy()
    np.minimum.at(lo, which, values)
    np.maximum.at(hi, which, values)
    return edges, lo, hi


def zero_error_bound(bases: int) -> float:
    """The one-sided 95 % upper bound on an error rate of which ``bases`` trials showed none:
    the rule of three, 3/n (−ln 0.05 = 3.0/n; Hanley & Lippman-Hand, JAMA 249:1743, 1983)."""
    return 3.0 / bases


def quality_calibration(ax, cal: list[dict]) -> None:
    """Stated against observed error per quality bin with its 95 % interval; a bin with no
    error observed has no point to plot on a log scale and is drawn as what it tells, an upper
    bound: a downward arrow from 3/n (:func:`zero_error_bound`, at most 1). A stated error
    below what the bin's qualities can say (0, or 1e-16 from a caller sure of its bases, whose
    Phred values stop at the bin's highest Q) is drawn at that Q's 10^(−Q/10)."""
    stated = np.array([max(c["stated_error"], 10.0 ** (-(c["q_hi"] - 1) / 10.0)) for c in cal])
    obs = np.array([c["observed_error"] for c in cal], float)
    seen = obs > 0
    if seen.any():
        lo = np.array([c["ci_low"] for c in cal], float)[seen]
        hi = np.array([c["ci_high"] for c in cal], float)[seen]
        ax.errorbar(stated[seen], obs[seen], yerr=[obs[seen] - lo, hi - obs[seen]], fmt="o",
                    color="C0", label="observed (95 % CI)")
    bound = np.array([min(zero_error_bound(c["bases"]), 1.0)
                      for c, s in zip(cal, seen, strict=True) if not s])
    if len(bound):
        x = stated[~seen]
        ax.plot(x, bound, ls="none", marker="v", color="C1",
                label="no error seen: < 3/n (95 %)")
        for xi, yi in zip(x, bound, strict=True):
            ax.annotate("", xy=(xi, yi / 4), xytext=(xi, yi),
                        arrowprops={"arrowstyle": "->", "color": "C1", "lw": 1.0})
    ys = np.concatenate([obs[seen], bound / 4, stated])
    span = (min(ys[ys > 0].min(initial=1.0), 1.0) / 2, 1.0)
    ax.plot(span, span, "k:", lw=1, label="stated = observed")
    ax.set(xscale="log", yscale="log", xlabel="stated error (quality bin)",
           ylabel="observed error", title="Quality calibration")
    ax.legend(fontsize=7)
