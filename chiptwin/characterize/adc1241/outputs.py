"""The ADC bench's outputs: ``adc1241.json``, ``adc1241.npz``, ``adc1241.md`` and the plots,
written whole or not at all (:func:`chiptwin.config.outputs.replacing`), as the EMVA 1288
datasheet's (:mod:`chiptwin.characterize.outputs`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.characterize.adc1241.histogram import FIGURES, summarize, to_jsonable

#: The bench's result (:class:`~chiptwin.characterize.adc1241.bench.AdcBench`), by name only:
#: the bench imports this module to write itself, so this one must not import the bench.
AdcBench = Any

JSON_NAME = "adc1241.json"
STANDARD = ("IEEE Std 1241-2000: histogram (code density) test with a slow ramp, sine-wave fit, "
            "transition noise from a DC sweep")

#: Ramp tables whose per-code DNL/INL go into the JSON (all are in the npz).
MAX_JSON_TABLES: int = 16

#: Unit and meaning of each figure, for the JSON and the report.
UNITS: dict[str, str] = {
    "dnl_max_lsb": "LSB (max |DNL| over codes 1 … 2^N − 2; the mean code width is 1)",
    "inl_max_lsb": "LSB (max |best-fit INL|, in units of the fitted line's slope)",
    "inl_endpoint_max_lsb": "LSB (max |end-point INL|)",
    "missing_codes": "count of interior codes never hit",
    "sinad_db": "dB (fitted amplitude / √2 over the fit residual's rms)",
    "enob_bits": "bit (N − log2(residual rms / (1/√12)), IEEE 1241)",
    "sfdr_db": "dBc",
    "transition_noise_lsb": "LSB of the ideal converter, input-referred, rms over transitions",
    "offset_lsb": "LSB (independently based, from the best-fit line)",
    "gain_error": "fractional (G − 1, independently based)",
}

CODE_ARRAYS = ("dnl_lsb", "dnl_sigma_lsb", "inl_endpoint_lsb", "inl_endpoint_sigma_lsb",
               "inl_bestfit_lsb", "inl_bestfit_sigma_lsb")


def _where(b: AdcBench, i: int) -> dict[str, int]:
    p = int(b.pixels[i])
    return {"converter": i, "pixel": p, "row": p // b.shape[1], "col": p % b.shape[1],
            "ramp_table": int(b.ramp_table[i])}


def _worst(b: AdcBench) -> dict[str, Any]:
    i = b.worst
    out: dict[str, Any] = {"by": "dnl_max_lsb", **_where(b, i)}
    out.update({k: b.arrays[k][i] for k in CODE_ARRAYS})
    out["missing_codes"] = b.worst_hist.missing_codes
    return out


def _tables(b: AdcBench) -> list[dict[str, Any]]:
    """Per distinct ramp table: the mean of its measured converters' DNL and INL (they share
    the table; offset and gain mismatch leave DNL and end-point INL unchanged), σ of the mean."""
    out = []
    for t in np.unique(b.ramp_table)[:MAX_JSON_TABLES]:
        on = np.flatnonzero(b.ramp_table == t)
        entry: dict[str, Any] = {"ramp_table": int(t), "converters": on}
        for k in ("dnl_lsb", "inl_endpoint_lsb", "inl_bestfit_lsb"):
            sig = k.replace("_lsb", "_sigma_lsb")
            entry[k] = b.arrays[k][on].mean(axis=0)
            entry[sig] = np.sqrt((b.arrays[sig][on] ** 2).sum(axis=0)) / on.size
        out.append(entry)
    return out


def to_json(b: AdcBench) -> dict[str, Any]:
    """The ``adc1241.json`` document (no wall time in it: same seed, same bytes)."""
    from chiptwin import __version__

    summary = summarize(b.figures)
    for fig in summary["figures"].values():
        if fig["worst_converter"] is not None:
            fig["worst_pixel"] = int(b.pixels[fig["worst_converter"]])
    n_tab = int(np.unique(b.ramp_table).size)
    n_chip = b.shape[0] * b.shape[1]
    subset = ("all" if b.pixels.size == n_chip else
              f"a grid of {b.pixels.size} of {n_chip} converters evenly spaced over the array "
              f"(max_converters = {b.settings.max_converters}); converters on one ramp share its "
              "INL and DNL, offset/gain mismatch and noise differ per converter")
    doc = {
        "standard": STANDARD, "scenario": b.scenario, "source": b.source, "seed": b.seed,
        "chiptwin_version": __version__,
        "rng_stream": "stage_rng(scenario.seed, 'characterize.adc')",
        "converter_keys": b.adc_keys,
        "bits": b.bits, "v_min_V": b.v_min_V, "v_max_V": b.v_max_V,
        "lsb_V": (b.v_max_V - b.v_min_V) / 2**b.bits,
        "bench": {"settings": b.settings, "dnl_sigma_lsb_asked": b.settings.dnl_sigma_lsb,
                  "dnl_sigma_lsb_median": float(np.nanmedian(b.arrays["dnl_sigma_lsb"])),
                  "converters_on_chip": n_chip, "converters_measured": int(b.pixels.size),
                  "subset": subset, "ramp_tables_measured": n_tab, **b.stimulus},
        "units": UNITS,
        "summary": summary,
        "converters": [{**_where(b, i), **f} for i, f in enumerate(b.figures)],
        "worst": _worst(b),
        "ramp_tables": _tables(b),
        "notes": NOTES,
    }
    return to_jsonable(doc)


NOTES = [
    "Per-code arrays are indexed by code k (0 … 2^N − 1): DNL[k] is code k's width, INL[k] "
    "belongs to T[k], the lower edge of code k; missing entries are null.",
    "Uncertainties are from the sample counts (binomial code hits, IEEE 1241's model of random "
    "sampling); the deterministic ramp and sine give at most these.",
    "The DC sweep is sized from the configured comparator noise (step σ/5, margin 3 LSB + 5σ).",
    "The ramp histogram recovers the transition levels with comparator noise too (with "
    "Gaussian noise the fraction of samples below T[k] of a uniform ramp is unchanged).",
]


def markdown(b: AdcBench, doc: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    """``adc1241.md``: the bench, the chip's figures (worst and median), the plots."""
    h, st = doc["bench"]["histogram"], doc["bench"]
    lines = [f"# IEEE 1241 ADC bench: {b.scenario}", "",
             f"{STANDARD}; chiptwin {doc['chiptwin_version']}, seed {b.seed}, "
             f"{b.wall_time_s:.2f} s.", "",
             f"- converter: {b.bits} bits over {b.v_min_V:g} … {b.v_max_V:g} V; "
             + ", ".join(f"{k} = {b.adc_keys[k]!r}" for k in _SHOWN if k in b.adc_keys),
             f"- measured: {st['converters_measured']} of {st['converters_on_chip']} converters "
             f"({st['subset']}), {st['ramp_tables_measured']} distinct ramp table(s)",
             f"- ramp {h['v_start_V']:.6g} … {h['v_stop_V']:.6g} V, {h['samples']} samples "
             f"({h['hits_per_lsb']:.1f} per LSB; DNL σ asked {b.settings.dnl_sigma_lsb:g} LSB, "
             f"median stated {st['dnl_sigma_lsb_median']:.3g} LSB)",
             f"- sine: {st['sine']['samples']} samples, {st['sine']['cycles']} cycles, "
             f"{st['sine']['amplitude_frac']:g} of each converter's half range",
             f"- transition noise: DC levels every {st['transition_noise']['step_lsb']:g} LSB "
             f"across transitions {st['transition_noise']['first_transition']} … "
             f"{st['transition_noise']['last_transition']}, {st['transition_noise']['repeats']} "
             "conversions each", "",
             "## The chip's figures", "",
             "| figure | worst ± 1σ | worst converter (pixel) | median | unit |",
             "|---|---|---|---|---|"]
    for name in FIGURES:
        f = doc["summary"]["figures"][name]
        worst = _num(f["worst"]) + ("" if f["worst_sigma"] is None else
                                    f" ± {_num(f['worst_sigma'])}")
        lines.append(f"| {name} | {worst} | {f['worst_converter']} ({f.get('worst_pixel')}) | "
                     f"{_num(f['median'])} | {UNITS[name].replace('|', '∣')} |")
    lines += ["", "## Plots (worst converter by max |DNL|: converter "
              f"{b.worst}, pixel {int(b.pixels[b.worst])})", ""]
    lines += [f"![{cap}]({name})\n\n*{cap}*\n" for name, cap in plots]
    lines += ["## Notes", ""] + [f"- {n}" for n in NOTES] + [""]
    return "\n".join(lines)


_SHOWN = ("comparator_noise_lsb", "comparator_noise_uV", "inl_max_lsb", "inl_shape",
          "inl_table", "dnl_rms_lsb", "offset_sigma_lsb", "gain_sigma", "ramp")


def _num(x: float | None) -> str:
    return "—" if x is None else f"{x:.4g}"


def write_outputs(b: AdcBench, out_dir: str | Path) -> Path:
    """Write the JSON, the npz (every measured converter's per-code arrays), the plots of the
    worst converter and the report into ``out_dir``, replacing a previous ADC bench there."""
    from chiptwin.characterize.adc1241.plots import make_plots
    from chiptwin.config.outputs import check_out_dir, replacing

    out = check_out_dir(out_dir, marker=JSON_NAME)
    doc = b.to_json()
    with replacing(out) as tmp:
        plots = make_plots(b.worst_hist, b.worst_dyn, tmp, prefix="adc1241")
        np.savez(tmp / "adc1241.npz", pixels=b.pixels, ramp_table=b.ramp_table,
                 **{k: _stored(k, v) for k, v in b.arrays.items()})
        (tmp / "adc1241.md").write_text(markdown(b, doc, plots), encoding="utf-8")
        (tmp / JSON_NAME).write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n",
                                     encoding="utf-8")
    return out


def _stored(name: str, a: np.ndarray) -> np.ndarray:
    """The npz's copy: volts in float64, LSB figures and sigmas in float32 (1e-7 relative), the
    hits in int32 (half the file: 128 converters × 13 bits, 84 → 46 MB)."""
    if name.endswith("_V") and not name.endswith("sigma_V"):
        return a
    return a.astype(np.int32) if name == "counts" else a.astype(np.float32)


def headline(doc: dict[str, Any]) -> list[str]:
    """Terminal lines: each figure's worst and median over the converters."""
    lines = [f"  {doc['bench']['converters_measured']} converters, {doc['bits']} bits"]
    for name in FIGURES:
        f = doc["summary"]["figures"][name]
        sig = "" if f["worst_sigma"] is None else f" ± {_num(f['worst_sigma'])}"
        lines.append(f"  {name:22s} worst {_num(f['worst'])}{sig}   median {_num(f['median'])}")
    return lines
