"""The standard's plots of a datasheet (EMVA 1288 Release 4.0 Linear): photon
transfer, SNR with the ideal and the shot-noise limit, linearity and its deviation, dark signal
against exposure time, DSNU and PRNU histograms, dark current against temperature.

Each function draws one figure into ``folder`` and returns ``(file name, caption)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from chiptwin.characterize import evaluate as ev
from chiptwin.characterize.datasheet import Datasheet
from chiptwin.twin.figures import save_figure as _save


def make_plots(d: Datasheet, folder: Path) -> list[tuple[str, str]]:
    """Every plot of the datasheet, as PNG files in ``folder``."""
    import matplotlib

    matplotlib.use("Agg")
    draws = [photon_transfer, snr, linearity, dark_signal]
    if d.measurement.spatial is not None:
        draws.append(histograms)
    if d.measurement.temperature is not None:
        draws.append(dark_temperature)
    out = [draw(d, folder) for draw in draws]
    if d.overlay:
        from chiptwin.characterize.overlay import overlay_figure

        out.append(overlay_figure(d.overlay, folder))
    return out


def _value(d: Datasheet, key: str) -> float:
    return d.figures[key].value


def photon_transfer(d: Datasheet, folder: Path) -> tuple[str, str]:
    """σ²_y − σ²_y.dark against μ_y − μ_y.dark, the fit range and the slope K."""
    import matplotlib.pyplot as plt

    c, fr = d.curves, d.fit_ranges
    x = c["mu_y"] - c["mu_y_dark"]
    y = c["var_y"] - c["var_y_dark"]
    last, i_sat = fr["sensitivity"]["last"], fr["saturation_index"]
    gain = _value(d, "system_gain")
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(x, y, "o", ms=3, color="tab:blue", label="data")
    ax.plot(x[: last + 1], gain * x[: last + 1], "-", color="tab:red",
            label=f"fit 0–70 % of saturation: K = {gain:.4g} DN/e⁻")
    ax.plot(x[i_sat], y[i_sat], "s", mfc="none", ms=9, color="k", label="saturation")
    ax.set(xlabel="μ_y − μ_y.dark (DN)", ylabel="σ²_y − σ²_y.dark (DN²)",
           title="Photon transfer")
    ax.legend(fontsize=8)
    return _save(fig, folder, "photon_transfer.png", "Photon transfer: the slope is the system "
                 "gain K")


def snr(d: Datasheet, folder: Path) -> tuple[str, str]:
    """SNR against μ_p (log-log): data, the linear model, the ideal and the shot-noise limit."""
    import matplotlib.pyplot as plt

    c = d.curves
    i_sat = d.fit_ranges["saturation_index"]
    mu_p = c["mu_p"]
    p_min, p_sat = _value(d, "absolute_sensitivity_threshold"), _value(d, "saturation_irradiation")
    grid = np.logspace(np.log10(0.5 * p_min), np.log10(p_sat), 200)
    qe = _value(d, "quantum_efficiency") / 100.0
    gain = _value(d, "system_gain")
    s2d = _value(d, "temporal_dark_noise") ** 2 + ev.SIGMA2_Q / gain**2
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.loglog(mu_p[: i_sat + 1], c["snr_measured"][: i_sat + 1], "o", ms=3, label="data")
    bound = " (σ_d at its upper limit)" if d.figures["temporal_dark_noise"].upper_limit else ""
    ax.loglog(grid, qe * grid / np.sqrt(s2d + qe * grid), "-", label="linear model" + bound)
    ax.loglog(grid, np.sqrt(grid), "--", color="grey", label="ideal: √μ_p")
    ax.loglog(grid, np.sqrt(qe * grid), ":", color="k", label="shot-noise limit: √(η μ_p)")
    ax.axvline(p_min, color="tab:red", lw=0.8, label=f"μ_p.min = {p_min:.4g}")
    ax.axvline(p_sat, color="tab:purple", lw=0.8, label=f"μ_p.sat = {p_sat:.4g}")
    ax.set(xlabel="μ_p (photons/pixel)", ylabel="SNR (amplitude ratio)", title="Signal to noise")
    ax.legend(fontsize=7)
    return _save(fig, folder, "snr.png", "SNR against photons per pixel, with the ideal sensor "
                 "and the shot-noise limit")


def linearity(d: Datasheet, folder: Path) -> tuple[str, str]:
    """The response with its weighted fit, and the relative deviation from it."""
    import matplotlib.pyplot as plt

    c, fr = d.curves, d.fit_ranges["linearity"]
    mu_p, y = c["mu_p"], c["mu_y"] - c["mu_y_dark"]
    sl = slice(fr["first"], fr["last"] + 1)
    i_sat = d.fit_ranges["saturation_index"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(mu_p, y, "o", ms=3, label="data")
    top.plot(mu_p[: i_sat + 1], c["linearity_fit"][: i_sat + 1], "-", color="tab:red",
             label="fit 5–95 % of saturation, weights 1/y")
    top.set(ylabel="μ_y − μ_y.dark (DN)", title="Linearity")
    top.legend(fontsize=8)
    bottom.plot(mu_p[sl], c["linearity_deviation_pct"][sl], "o-", ms=3)
    bottom.axhline(0.0, color="grey", lw=0.5)
    bottom.set(xlabel="μ_p (photons/pixel)", ylabel="deviation δ (%)",
               title=f"LE = {_value(d, 'linearity_error'):.3g} %")
    return _save(fig, folder, "linearity.png", "Response and its deviation from linearity")


def dark_signal(d: Datasheet, folder: Path) -> tuple[str, str]:
    """Dark mean and dark temporal variance against exposure time, with their regressions."""
    import matplotlib.pyplot as plt

    c = d.curves
    t = c["t_exp_s"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5))
    left.plot(t, c["mu_y_dark"], "o", ms=3)
    coef, _ = ev.ols(t, c["mu_y_dark"], np.ones_like(t))
    left.plot(t, coef[0] + coef[1] * t, "-", color="tab:red",
              label=f"μ_I = {_value(d, 'dark_current'):.4g} e⁻/s")
    left.set(xlabel="exposure time (s)", ylabel="μ_y.dark (DN)", title="Dark signal")
    left.legend(fontsize=8)
    right.plot(t, c["var_y_dark"], "o", ms=3)
    coef, _ = ev.ols(t, c["var_y_dark"], np.ones_like(t))
    right.plot(t, coef[0] + coef[1] * t, "-", color="tab:red",
               label=f"σ²_y.dark(0) = {coef[0]:.3g} DN²")
    right.set(xlabel="exposure time (s)", ylabel="σ²_y.dark (DN²)", title="Dark temporal noise")
    right.legend(fontsize=8)
    return _save(fig, folder, "dark_signal.png", "Dark signal and dark noise against exposure "
                 "time")


def _hist(ax, values: np.ndarray, xlabel: str, title: str) -> None:
    """A histogram drawn as one filled outline (``stepfilled``), not one rectangle a bin: the
    same picture, 2.4× faster to draw (256 bins on a log scale)."""
    bins = max(8, min(256, int(np.sqrt(values.size)) * 2))
    counts, edges, _ = ax.hist(values, bins=bins, color="tab:blue", alpha=0.8, label="pixels",
                               histtype="stepfilled")
    sd = values.std()
    if sd > 0:
        x = np.linspace(edges[0], edges[-1], 200)
        width = edges[1] - edges[0]
        ax.plot(x, values.size * width * np.exp(-0.5 * ((x - values.mean()) / sd) ** 2)
                / (np.sqrt(2 * np.pi) * sd), "-", color="tab:red", label="normal, same σ")
    ax.set_yscale("log")
    ax.set_ylim(bottom=0.5)
    ax.set(xlabel=xlabel, ylabel="pixels", title=title)
    ax.legend(fontsize=7)


def histograms(d: Datasheet, folder: Path) -> tuple[str, str]:
    """DSNU and PRNU histograms of the averaged spatial images (no high-pass filtering: the
    standard's 5 × 5 high-pass removes shading on large sensors; the twin has none)."""
    import matplotlib.pyplot as plt

    sp = d.measurement.spatial
    dark = sp.dark_mean.ravel()
    signal = sp.bright_mean.ravel() - dark
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5))
    _hist(left, dark - dark.mean(), "deviation from the mean (DN)",
          f"DSNU: {_fmt(d.figures['dsnu'].value)} e⁻")
    _hist(right, 100.0 * (signal / signal.mean() - 1.0), "deviation from the mean (%)",
          f"PRNU: {_fmt(d.figures['prnu'].value)} %")
    return _save(fig, folder, "histograms.png", "DSNU and PRNU histograms of the averaged "
                 "spatial images")


def dark_temperature(d: Datasheet, folder: Path) -> tuple[str, str]:
    """Dark current against temperature (log₂ scale) and the doubling-temperature fit."""
    import matplotlib.pyplot as plt

    c = d.curves
    temp, mu = c["temperature_C"], c["dark_current_e_per_s"]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.errorbar(temp, mu, yerr=2 * c["dark_current_se_e_per_s"], fmt="o", ms=4,
                label="μ_I(T) ± 2σ")
    td = d.figures["doubling_temperature"].value
    if td is not None and np.all(mu > 0):
        t0 = d.camera.temperature_C
        ref = float(np.exp(np.mean(np.log(mu) - (temp - t0) / td * np.log(2.0))))
        ax.plot(temp, ref * 2.0 ** ((temp - t0) / td), "-", color="tab:red",
                label=f"T_d = {td:.3g} °C")
        ax.set_yscale("log", base=2)
    ax.set(xlabel="temperature (°C)", ylabel="μ_I (e⁻/s)", title="Dark current against "
           "temperature")
    ax.legend(fontsize=8)
    return _save(fig, folder, "dark_current_temperature.png", "Dark current against "
                 "temperature and its doubling temperature")


def _fmt(value: float | None) -> str:
    return "not resolved" if value is None else f"{value:.4g}"
