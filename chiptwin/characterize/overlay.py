"""Measured against simulated: a camera's curves and its twin's, read through the same protocol,
laid over each other with their residuals in units of the standard error.

The curves of EMVA 1288 Release 4.0 Linear: photon transfer (σ²_y against μ_y), SNR against
μ_p, the linearity deviation δ, and the dark mean and dark variance against the exposure time.
At each point the residual is ``z = (twin − measured)/√(se_measured² + se_twin²)``, the standard
errors those of the pair statistics (:mod:`chiptwin.characterize.estimators`). Each curve's
largest |z| is stated below saturation (where the twin's linear camera model applies) and over
the whole series, with where it falls; a curve whose |z| exceeds :data:`Z_FOLLOWS` is named as
one the twin does not follow, with the reason the data show.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from chiptwin.characterize import evaluate as ev
from chiptwin.characterize.measure import Measurement

#: |z| up to which a curve is said to follow the measurement (a 3σ band: 0.27 % of a normal's
#: values fall outside it, so a few of 50 points may, by chance).
Z_FOLLOWS: float = 3.0


@dataclass(frozen=True)
class Curve:
    """One curve of both: x, the measured and the twin's y with standard errors, z."""

    name: str
    xlabel: str
    ylabel: str
    x: NDArray[np.float64]
    measured: NDArray[np.float64]
    measured_se: NDArray[np.float64]
    twin: NDArray[np.float64]
    twin_se: NDArray[np.float64]
    below_saturation: NDArray[np.bool_]

    @property
    def z(self) -> NDArray[np.float64]:
        se = np.hypot(self.measured_se, self.twin_se)
        return np.where(se > 0, (self.twin - self.measured) / np.where(se > 0, se, 1.0), 0.0)

    def largest(self, below_only: bool = True) -> tuple[float, float]:
        """The largest |z| (below saturation, or anywhere) and the x where it falls."""
        z = np.abs(self.z)
        mask = self.below_saturation if below_only else np.isfinite(z)
        if not mask.any():
            return float("nan"), float("nan")
        i = int(np.flatnonzero(mask)[np.argmax(z[mask])])
        return float(z[i]), float(self.x[i])


def _col(m: Measurement, which: str, attr: str) -> NDArray[np.float64]:
    return m.temporal.column(which, attr)


def _signal(m: Measurement) -> tuple[NDArray, NDArray]:
    """``μ_y − μ_y.dark`` and its standard error (:func:`chiptwin.characterize.evaluate.signal`).
    Unit: DN."""
    y, var = ev.signal(m.temporal)
    return y, np.sqrt(var)


def _snr(m: Measurement) -> tuple[NDArray, NDArray]:
    """SNR = (μ_y − μ_y.dark)/σ_y and its standard error (delta method)."""
    y, y_se = _signal(m)
    var, var_se = _col(m, "bright", "var"), _col(m, "bright", "var_se")
    sd = np.sqrt(np.maximum(var, 1e-300))
    snr = y / sd
    rel = np.hypot(y_se / np.maximum(np.abs(y), 1e-300), var_se / (2 * np.maximum(var, 1e-300)))
    return snr, np.abs(snr) * rel


def _deviation(m: Measurement, fit: ev.Linearity) -> tuple[NDArray, NDArray]:
    """δ = 100 (y − fit)/fit against the *measured* fit line, so both sides share it. Unit: %."""
    y, y_se = _signal(m)
    line = fit.offset + fit.slope * m.temporal.mu_p
    return 100.0 * (y - line) / line, 100.0 * y_se / np.abs(line)


def curves(measured: Measurement, twin: Measurement) -> list[Curve]:
    """The five curves of a measurement and its twin read through the same protocol."""
    i_sat = ev.saturation_index(measured.temporal)
    n = len(measured.temporal.t_exp_s)
    below = np.arange(n) < i_sat
    fit = ev.linearity(measured.temporal, i_sat)
    in_fit = np.zeros(n, bool)
    in_fit[fit.fit_range] = True
    out = []
    mu_y, _ = _signal(measured)
    t_exp, mu_p = measured.temporal.t_exp_s, measured.temporal.mu_p
    for name, x, xl, yl, get, mask in (
        ("photon transfer", mu_y, "μ_y − μ_y.dark (DN)", "σ²_y (DN²)",
         lambda m: (_col(m, "bright", "var"), _col(m, "bright", "var_se")), below),
        ("SNR", mu_p, "μ_p (photons/pixel)", "SNR", _snr, below),
        ("linearity deviation", mu_p, "μ_p (photons/pixel)", "δ (%)",
         lambda m: _deviation(m, fit), in_fit),
        ("dark mean", t_exp, "exposure time (s)", "μ_y.dark (DN)",
         lambda m: (_col(m, "dark", "mean"), _col(m, "dark", "mean_se")), np.ones(n, bool)),
        ("dark variance", t_exp, "exposure time (s)", "σ²_y.dark (DN²)",
         lambda m: (_col(m, "dark", "var"), _col(m, "dark", "var_se")), np.ones(n, bool)),
    ):
        (my, ms), (ty, ts) = get(measured), get(twin)
        if name == "SNR":  # a clipped output has no temporal noise: no SNR there
            keep = (_col(measured, "bright", "var") > 0) & (_col(twin, "bright", "var") > 0)
            x, my, ms, ty, ts, mask = (a[keep] for a in (x, my, ms, ty, ts, mask))
        out.append(Curve(name, xl, yl, x, my, ms, ty, ts, mask))
    return out


def findings(cs: list[Curve]) -> list[str]:
    """One line per curve: its largest deviation in σ below saturation and over the series and,
    where it exceeds :data:`Z_FOLLOWS` below saturation, what the twin does not follow."""
    lines = []
    for c in cs:
        z_in, x_in = c.largest(True)
        z_all, _ = c.largest(False)
        text = (f"{c.name}: {z_in:.3g} σ at {x_in:.4g} {c.xlabel.split('(')[-1].rstrip(')')} "
                f"below saturation, {z_all:.3g} σ over the series")
        if z_in > Z_FOLLOWS:
            text += " — " + WHY[c.name]
        lines.append(text)
    return lines


#: What the data say the twin does not follow, by curve, when it is outside the 3σ band below
#: saturation (the twin's pixel and converter are linear, its dark signal a linear dark current
#: over a constant black level, its pixels' noise independent).
WHY = {
    "photon transfer": "the camera's temporal variance is not K·μ_y plus its dark variance "
                       "there (a noise the twin's pixel lacks, or a gain that bends)",
    "SNR": "the camera's response bends (see the linearity deviation): the twin's is linear",
    "linearity deviation": "the camera's response bends by up to its linearity error; the "
                           "twin's pixel and converter are linear",
    "dark mean": "the camera's black level moves from image to image by more than its pixels' "
                 "temporal noise allows (a common-mode offset the twin's pixels do not have)",
    "dark variance": "the camera's dark noise changes with the exposure time other than the "
                     "twin's dark shot noise does",
}


def overlay_figure(cs: list[Curve], folder: Path) -> tuple[str, str]:
    """Every curve measured and simulated (top) with its residuals in σ (bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from chiptwin.twin.figures import save_figure

    fig, axes = plt.subplots(2, len(cs), figsize=(4.0 * len(cs), 6.0), sharex="col",
                             gridspec_kw={"height_ratios": [2, 1]})
    for c, top, bottom in zip(cs, axes[0], axes[1], strict=True):
        log = c.name == "SNR"
        top.errorbar(c.x, c.measured, yerr=2 * c.measured_se, fmt="o", ms=3, label="measured")
        top.plot(c.x, c.twin, "-", color="tab:red", label="twin")
        top.set(title=c.name, ylabel=c.ylabel)
        if log:
            top.set(xscale="log", yscale="log")
        top.legend(fontsize=7)
        bottom.axhspan(-Z_FOLLOWS, Z_FOLLOWS, color="0.9")
        bottom.plot(c.x[c.below_saturation], c.z[c.below_saturation], "o", ms=3,
                    color="tab:blue", label="below saturation")
        bottom.plot(c.x[~c.below_saturation], c.z[~c.below_saturation], "x", ms=4,
                    color="0.5", label="saturation and beyond")
        bottom.axhline(0.0, color="k", lw=0.5)
        bottom.set(xlabel=c.xlabel, ylabel="z (σ)")
        bottom.legend(fontsize=6)
    fig.tight_layout()
    return save_figure(fig, folder, "overlay.png", "Measured and twin through the same "
                       f"protocol; residuals in standard errors (grey band ±{Z_FOLLOWS:g} σ)")


__all__ = ["Curve", "Z_FOLLOWS", "curves", "findings", "overlay_figure"]
