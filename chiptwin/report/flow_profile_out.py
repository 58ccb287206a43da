"""``chiptwin reads profile``'s outputs: the twin's check run, the figure, report.md and
flow_profile.json (:mod:`chiptwin.report.flow_profile` makes the numbers)."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.kinetics.chemistry import BIN, N_BINS
from chiptwin.kinetics.chemistry_fit import (
    histograms,
    ks_distance,
    model_distributions,
    total_variation,
)
from chiptwin.report.flow_profile import LENGTHS, ChemistryReport, SffCheck, sampling_floor

JSON_NAME = "flow_profile.json"
FIGURE_NAME = "flow_profiles.png"

#: The bundled scene the twin check runs: pyro_long_read's chip, template and phasing with the
#: 454 FLX preset.
TWIN_SCENE = "pyro_454_flx"

#: The check's runs: the scene as bundled (ε 0.2 %, λ 1 %, droop 0.1 % that the caller estimates
#: and corrects) and with no phasing (the caller's estimate then has nothing to find: what is
#: left is the chemistry through the chip, the key's normalisation and the caller's rescale).
TWIN_VARIANTS: dict[str, tuple[str, ...]] = {
    "as bundled": (),
    "no phasing": ("assay.incomplete_extension=0", "assay.carry_forward=0",
                   "assay.droop_per_flow=0"),
}

#: Flows of each read the check pools (50 cycles of TACG: the dephase caller's corrected values
#: there, before the read's far end, where the vendor's reads are trimmed too).
TWIN_FLOWS = 200


@dataclass(frozen=True)
class TwinCheck:
    """The twin's phase-corrected values per true length against the measured FLX profile,
    and against the fast path's law (the gap)."""

    scene: str
    variant: str
    reads: int
    rows: list[dict[str, Any]]
    values: dict[int, NDArray[np.float64]]


def twin_checks(flx: dict[int, NDArray[np.float64]], scene: str = TWIN_SCENE
                ) -> list[TwinCheck]:
    """:func:`twin_check` of every :data:`TWIN_VARIANTS`."""
    return [twin_check(flx, scene, name, sets) for name, sets in TWIN_VARIANTS.items()]


def twin_check(flx: dict[int, NDArray[np.float64]], scene: str = TWIN_SCENE,
               variant: str = "as bundled", overrides: tuple[str, ...] = ()) -> TwinCheck:
    """Run ``scene`` and compare the corrected values its caller kept (``read_corrected``: the
    dephase caller's, each site's own predicted noise, :func:`chiptwin.twin.reads.call_reads`)
    over the first :data:`TWIN_FLOWS` flows with the FLX profile and with the fast path's law of
    the scene's flow-value model."""
    from chiptwin.twin.runner import run
    from chiptwin.twin.stages import flow_model

    result = run(scene, overrides)
    s = result.scenario
    true_n = result.arrays["read_true_n"][:TWIN_FLOWS]
    corrected = list(np.asarray(result.arrays["read_corrected"])[:, :TWIN_FLOWS])
    y = np.concatenate(corrected)
    h = np.tile(true_n, len(corrected))
    counts = histograms(y, h, max(LENGTHS))
    model = flow_model(s)
    fast = model_distributions(model, list(LENGTHS)) if model is not None else {}
    rng = np.random.default_rng(0)  # the sampling floors' draws
    rows = []
    for n in LENGTHS:
        if counts[n].sum() == 0:
            continue
        row = {"length": n, "flows": int(counts[n].sum()),
               "tv_to_measured": total_variation(counts[n], flx[n]),
               "ks_to_measured": ks_distance(counts[n], flx[n])}
        if n in fast:
            row["tv_to_fast_path"] = total_variation(counts[n], fast[n])
            # what as many flows drawn from the model itself show: a 4-mer's 128 flows
            # alone leave ≈ 0.3 to a perfect law
            row["tv_floor"] = sampling_floor(model, n, row["flows"], rng)
        rows.append(row)
    return TwinCheck(scene, variant, len(corrected), rows,
                     {n: counts[n] for n in LENGTHS})


def figure(reports: list[ChemistryReport], folder: Path, twins: list[TwinCheck] = ()
           ) -> tuple[str, str]:
    """Measured distributions of lengths 0–5 (one row per chemistry) beside the preset's law,
    and the twin run's histogram on the FLX row."""
    import matplotlib.pyplot as plt

    from chiptwin.twin.figures import save_figure

    x = np.arange(N_BINS) * BIN
    fig, axes = plt.subplots(len(reports), len(LENGTHS), figsize=(15, 2.6 * len(reports)),
                             squeeze=False)
    for i, rep in enumerate(reports):
        law = model_distributions(rep.preset, list(LENGTHS))
        for h, ax in zip(LENGTHS, axes[i], strict=True):
            lo, hi = (0.0, 0.6) if h == 0 else (h - 1.0, h + 1.0)
            keep = (x >= lo) & (x <= hi)
            p = rep.measured[h] / rep.measured[h].sum()
            ax.step(x[keep], p[keep] / BIN, where="mid", color="0.3", lw=1.2, label="measured")
            ax.plot(x[keep], law[h][keep] / BIN, color="tab:red", lw=1.2,
                    label=f"twin ({rep.name})")
            for twin, colour in zip(twins, ("tab:blue", "tab:green"), strict=False):
                if rep.name == "454_flx" and twin.values[h].sum() > 0:
                    c = _coarse(twin.values[h])
                    ax.plot(x[keep], c[keep] / BIN, ".", color=colour, ms=2.5,
                            label=f"twin run, {twin.variant}")
            row = rep.rows[h]
            ax.set_title(f"{rep.name}, {h}-mer: TV {row.tv_preset:.3f}", fontsize=8)
            ax.tick_params(labelsize=7)
            if h == 0:
                ax.set_ylabel("density per 1-mer", fontsize=8)
            if i == len(reports) - 1:
                ax.set_xlabel("flow value (1-mer units)", fontsize=8)
    axes[0][0].legend(fontsize=6)
    return save_figure(fig, folder, FIGURE_NAME,
                       "Flow-value distributions per true homopolymer length: measured (grey), "
                       "the twin's preset at the detection level (red), twin runs' "
                       "phase-corrected values (dots, FLX row, --twin: as bundled blue, "
                       "no phasing green)")


def _coarse(counts: NDArray[np.float64], width: int = 5) -> NDArray[np.float64]:
    """A histogram of few flows smoothed over ``width`` bins (probabilities)."""
    p = counts / counts.sum()
    return np.convolve(p, np.ones(width) / width, mode="same")


def summary(reports: list[ChemistryReport], between: list[tuple[int, float, float]],
            twins: list[TwinCheck], sffs: list[SffCheck] = ()) -> dict[str, Any]:
    """The JSON of every number the report states."""
    return {
        "chemistries": [{
            "name": r.name, "source": r.source,
            "preset": asdict(r.preset), "refit": asdict(r.fit.model),
            "refit_cost_nats": r.fit.cost, "refit_evaluations": r.fit.evaluations,
            "lengths": [asdict(row) for row in r.rows]} for r in reports],
        "flx_vs_titanium": [{"length": h, "tv": tv, "ks": ks} for h, tv, ks in between],
        "sff_checks": [asdict(c) for c in sffs],
        "twin_checks": [{"scene": t.scene, "variant": t.variant, "reads": t.reads,
                         "flows_per_read": TWIN_FLOWS, "lengths": t.rows} for t in twins],
    }


def markdown(data: dict[str, Any]) -> str:
    """report.md: the distance tables and the fitted parameters."""
    between = {row["length"]: row for row in data["flx_vs_titanium"]}
    out = ["# Flow-value model against measured runs", "",
           "Distances per true homopolymer length between the measured flow-value "
           "distribution and the twin's law (total variation TV, Kolmogorov–Smirnov KS; "
           "0.01 bins). `preset`: the bundled `[assay] chemistry`; `refit`: fitted now. "
           "The yardstick: FLX against Titanium, two real 454 chemistries.", ""]
    for chem in data["chemistries"]:
        out += [f"## {chem['name']} ({chem['source']})", "",
                "| length | flows | TV preset | KS preset | TV refit | TV floor | "
                "TV FLX–Titanium |", "|---|---|---|---|---|---|---|"]
        for row in chem["lengths"]:
            h = row["length"]
            out.append(f"| {h} | {row['flows'] or 'profile'} | {row['tv_preset']:.3f} | "
                       f"{row['ks_preset']:.3f} | {row['tv_fit']:.3f} | "
                       f"{_num(row['tv_floor'])} | {between[h]['tv']:.3f} |")
        out += ["", "| parameter | preset | refit |", "|---|---|---|"]
        for key, value in chem["preset"].items():
            out.append(f"| {key} | {_num(value)} | {_num(chem['refit'][key])} |")
        out.append("")
    if data["sff_checks"]:
        out += ["## 454 SFF runs (no truth): pooled values against each preset's mixture", "",
                "| run | chemistry | reads | flows | TV 454_flx | TV 454_titanium | "
                "KS 454_flx | KS 454_titanium |", "|---|---|---|---|---|---|---|---|"]
        for c in data["sff_checks"]:
            out.append(f"| {Path(c['path']).name} | {c['chemistry']} | {c['reads']} | "
                       f"{c['flows']} | {c['tv']['454_flx']:.3f} | "
                       f"{c['tv']['454_titanium']:.3f} | {c['ks']['454_flx']:.3f} | "
                       f"{c['ks']['454_titanium']:.3f} |")
        out.append("")
    for twin in data["twin_checks"]:
        out += [f"## Twin run `{twin['scene']}`, {twin['variant']}, against 454 FLX", "",
                f"{twin['reads']} reads, the dephase caller's corrected values of the first "
                f"{twin['flows_per_read']} flows.", "",
                "| length | flows | TV to FLX | KS to FLX | TV to the fast path | TV floor |",
                "|---|---|---|---|---|---|"]
        for row in twin["lengths"]:
            out.append(f"| {row['length']} | {row['flows']} | {row['tv_to_measured']:.3f} | "
                       f"{row['ks_to_measured']:.3f} | {_num(row.get('tv_to_fast_path'))} | "
                       f"{_num(row.get('tv_floor'))} |")
        out.append("")
    out += [f"![flow-value distributions]({FIGURE_NAME})", ""]
    return "\n".join(out)


def _num(v: Any) -> str:
    if v is None:
        return "—"
    if isinstance(v, str):
        return v
    return f"{v:.4g}"


def write_outputs(out: Path, reports: list[ChemistryReport],
                  between: list[tuple[int, float, float]], twins: list[TwinCheck],
                  sffs: list[SffCheck] = ()) -> Path:
    """report.md, flow_profile.json and the figure in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    data = summary(reports, between, twins, sffs)
    figure(reports, out, twins)
    (out / JSON_NAME).write_text(json.dumps(data, indent=1))
    (out / "report.md").write_text(markdown(data))
    return out
