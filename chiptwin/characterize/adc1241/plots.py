"""The IEEE 1241 bench's plots of one converter: DNL and INL against code, the code histogram,
the output spectrum.

Each function draws one figure into ``folder`` and returns ``(file name, caption)``, as
:mod:`chiptwin.characterize.plots` does for the EMVA 1288 datasheet.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from chiptwin.characterize.adc1241.histogram import HistogramResult
from chiptwin.characterize.adc1241.sine import DynamicResult
from chiptwin.twin.figures import save_figure as _save


def make_plots(hist: HistogramResult | None, dyn: DynamicResult | None, folder: str | Path,
               prefix: str = "adc") -> list[tuple[str, str]]:
    """Every plot the results allow, as PNG files ``<prefix>_*.png`` in ``folder`` (created)."""
    import matplotlib

    matplotlib.use("Agg")
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    made = []
    if hist is not None:
        made += [dnl_inl(hist, out, prefix), code_histogram(hist, out, prefix)]
    if dyn is not None:
        made.append(output_spectrum(dyn, out, prefix))
    return made


def dnl_inl(h: HistogramResult, folder: Path, prefix: str = "adc") -> tuple[str, str]:
    """DNL (top) and INL, end-point and best-fit (bottom), against code, with ±2σ bands."""
    import matplotlib.pyplot as plt

    k = np.arange(h.counts.size)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax1.plot(k, h.dnl_lsb, lw=0.7, color="tab:blue", label="DNL")
    ax1.fill_between(k, -2 * h.dnl_sigma_lsb, 2 * h.dnl_sigma_lsb, color="grey", alpha=0.3,
                     label="±2σ (sample count)")
    if h.missing_codes.size:
        ax1.plot(h.missing_codes, np.full(h.missing_codes.size, -1.0), "rv", ms=4,
                 label=f"missing codes ({h.missing_codes.size})")
    ax1.set(ylabel="DNL (LSB)", title=f"{h.bits}-bit converter, {h.stimulus} histogram, "
            f"S = {h.samples}")
    ax1.legend(fontsize=8)
    ax2.plot(k, h.inl_endpoint_lsb, lw=0.8, color="tab:orange", label="INL end-point")
    ax2.plot(k, h.inl_bestfit_lsb, lw=0.8, color="tab:green", label="INL best-fit")
    ax2.fill_between(k, -2 * h.inl_bestfit_sigma_lsb, 2 * h.inl_bestfit_sigma_lsb,
                     color="grey", alpha=0.3, label="±2σ best-fit")
    ax2.set(xlabel="code", ylabel="INL (LSB)")
    ax2.legend(fontsize=8)
    return _save(fig, folder, f"{prefix}_dnl_inl.png",
                 "DNL and INL (end-point and best-fit) against code, IEEE 1241 histogram test")


def code_histogram(h: HistogramResult, folder: Path, prefix: str = "adc") -> tuple[str, str]:
    """Hits per code, with the expected ideal density (flat for a ramp, arcsine for a sine)."""
    import matplotlib.pyplot as plt

    k = np.arange(h.counts.size)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.step(k, h.counts, where="mid", lw=0.7, label="hits")
    t = h.transitions_V
    if h.stimulus == "sine" and np.isfinite(h.stimulus_amplitude_V):
        c, a = h.stimulus_offset_V, h.stimulus_amplitude_V
        lo = np.clip((t[1:-1] - c) / a, -1, 1)  # lower edges of codes 1 … 2^N − 2
        edges = np.append(lo, np.clip((t[-1] - c) / a, -1, 1))
        ideal = h.samples * np.diff(np.arcsin(np.linspace(edges[0], edges[-1], edges.size))) / np.pi
        ax.plot(k[1:-1], ideal, "--", color="k", lw=0.8, label="ideal arcsine density")
    else:
        ax.axhline(np.mean(h.counts[1:-1]), ls="--", color="k", lw=0.8, label="mean")
    ax.set(xlabel="code", ylabel="hits", yscale="log",
           title=f"Code histogram ({h.stimulus}), end codes {h.counts[0]} and {h.counts[-1]}")
    ax.legend(fontsize=8)
    return _save(fig, folder, f"{prefix}_histogram.png",
                 "Code histogram of the histogram test's record")


def output_spectrum(d: DynamicResult, folder: Path, prefix: str = "adc") -> tuple[str, str]:
    """The output spectrum in dBFS with SINAD, ENOB and SFDR, the largest spur marked."""
    import matplotlib.pyplot as plt

    s = d.spectrum
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(s.cycles_per_sample, s.power_dbfs, lw=0.6, color="tab:blue")
    ax.plot(s.cycles_per_sample[s.spur_bin], s.power_dbfs[s.spur_bin], "rv", ms=5,
            label=f"largest spur: SFDR = {d.sfdr_db:.1f} dBc")
    ax.set(xlabel="frequency (cycles/sample)", ylabel="power (dBFS)",
           title=f"SINAD {d.sinad_db:.2f} dB, ENOB {d.enob_bits:.2f} bit ({s.window} window)")
    ax.legend(fontsize=8)
    return _save(fig, folder, f"{prefix}_spectrum.png",
                 "Output spectrum of the sine-fit record (0 dBFS: full-scale sine)")
