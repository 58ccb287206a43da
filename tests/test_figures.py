"""``chiptwin.twin.figures.save_figure``: one draw instead of two, the same bytes."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from chiptwin.twin.figures import DPI, save_figure  # noqa: E402


def _figure():
    fig, ax = plt.subplots(figsize=(7, 3.5))
    x = np.linspace(0.0, 100.0, 500)
    for i in range(3):
        ax.plot(x, np.sin(x + i), lw=0.8, label=f"site {i}")
    im = ax.imshow(np.arange(32.0).reshape(4, 8), extent=(0, 30, -1, 1))
    fig.colorbar(im, ax=ax, label="e⁻ per frame")
    ax.set(xlabel="time (s)", ylabel="signal per frame (e⁻)", title="a run's figure")
    ax.legend(fontsize=7)
    return fig


def _draws(fig) -> list[int]:
    """Count the figure's draws (rendered or not) from here on."""
    calls, draw = [], fig.draw
    fig.draw = lambda renderer: (calls.append(1), draw(renderer))[1]
    return calls


def test_same_bytes_as_tight_layout_and_savefig_with_one_draw_fewer(tmp_path):
    fig = _figure()
    classic = _draws(fig)
    fig.tight_layout()
    fig.savefig(tmp_path / "classic.png", dpi=DPI)
    plt.close(fig)

    fig = _figure()
    ours = _draws(fig)
    assert save_figure(fig, tmp_path, "ours.png", "caption") == ("ours.png", "caption")
    assert (tmp_path / "ours.png").read_bytes() == (tmp_path / "classic.png").read_bytes()
    assert (len(classic), len(ours)) == (2, 1)
    assert not plt.fignum_exists(fig.number)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["classic.png", "ours.png"]


def test_constrained_layout_keeps_its_engine(tmp_path):
    """``tight=False`` leaves a constrained figure's engine alone: its layout is done in the
    draw, so the file is the one ``savefig`` writes."""
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.set(xlabel="x label", ylabel="y label", title="constrained")
    fig.savefig(tmp_path / "classic.png", dpi=DPI)
    save_figure(fig, tmp_path, "ours.png", tight=False)
    assert (tmp_path / "ours.png").read_bytes() == (tmp_path / "classic.png").read_bytes()
