"""Every converter of a scenario's chip on the IEEE Std 1241 bench (``chiptwin characterize
SCENARIO --adc``).

The converters are exactly those a run of the scenario converts with
(:func:`chiptwin.twin.runner.chip_sensor`'s ``converter``: the ``[chip.adc]`` keys, the fixed
errors drawn from ``chip.fixed_pattern_seed``), driven at the ADC input in volts, the photodiode
bypassed::

    chip_sensor(s).converter ──► ≤ max_converters of them (a grid over the array)
      ──► slow ramp, in blocks: hits per code ──► histogram_from_counts ──► T[k], DNL, INL,
          missing codes, offset, gain (± σ)
      ──► a coherent sine just inside each converter's measured range ──► SINAD, ENOB, SFDR
      ──► DC levels across mid-scale transitions × repeats ──► transition noise
      ──► figures per converter ──► summarize (worst, median) ──► adc1241.json, .npz, .md, plots

Every random draw (the comparator noise of each conversion) comes from one stream,
``stage_rng(scenario.seed, "characterize.adc")``, in the order above and, within a test, in C
order of the (sample, converter) records: the same seed gives the same bits, whatever the block
size. The stimuli are deterministic.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.characterize.adc1241 import _kernels
from chiptwin.characterize.adc1241.histogram import (
    HistogramResult,
    Ramp,
    converter_figures,
    histogram_from_counts,
    histogram_samples,
)
from chiptwin.characterize.adc1241.noise import transition_noise
from chiptwin.characterize.adc1241.sine import DynamicResult, coherent_cycles, dynamic_test
from chiptwin.config import Scenario, ScenarioError
from chiptwin.pixel import Converter

__all__ = ["AdcBench", "BenchSettings", "adc_bench", "configured_transitions_V",
           "pick_converters", "sub_converter"]

Progress = Callable[[int, int], None]

#: Conversions per block of the ramp (volts and codes held at once: 16 MiB).
BLOCK_CONVERSIONS: int = 1 << 20

#: Most conversions one bench may make: about 200 s at the ~50 ns a conversion plus its count
#: take on one core (measured: 13-bit table converter 25 ns, count 2–25 ns).
MAX_CONVERSIONS: int = 4_000_000_000

#: Most memory the per-code arrays may take (88 B per code and converter: the hits, 10 arrays
#: of figures). Unit: byte.
MAX_BENCH_BYTES: int = 1 << 30

#: Two-sided confidence of ±1σ, so that :func:`histogram_samples`'s β is one standard error.
ONE_SIGMA: float = math.erf(1.0 / math.sqrt(2.0))


@dataclass(frozen=True)
class BenchSettings:
    """What the bench measures with (each checked, the message naming the field).

    Parameters
    ----------
    dnl_sigma_lsb : float
        The DNL's standard error asked at the least-hit code (ramp: 1/σ² hits per code). LSB.
    fit_samples : int
        Samples M of each converter's sine record (≥ 256).
    max_converters : int
        Most converters measured; a larger chip gives an evenly spaced grid of them
        (:func:`pick_converters`).
    noise_transitions : int
        Mid-scale transitions the DC sweep straddles (the fit takes every one it resolves).
    noise_repeats : int
        Conversions R at each DC level.
    fit_amplitude_frac : float
        The sine's amplitude over the converter's measured half range (< 1: no clipping).
    overdrive_lsb : float
        How far the ramp runs beyond the widest converter's end transitions (plus 6 σ of the
        comparator noise). LSB.
    """

    dnl_sigma_lsb: float = 0.1
    fit_samples: int = 1 << 14
    max_converters: int = 256
    noise_transitions: int = 4
    noise_repeats: int = 200
    fit_amplitude_frac: float = 0.999
    overdrive_lsb: float = 8.0

    def __post_init__(self) -> None:
        for name, lo, hi in (("dnl_sigma_lsb", 0.001, 1.0), ("fit_amplitude_frac", 0.5, 1.0),
                             ("overdrive_lsb", 1.0, 1e4)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and lo <= v <= hi):
                raise ValueError(f"{name} = {v!r}: must be in [{lo}, {hi}]")
        for name, lo, hi in (("fit_samples", 256, 1 << 24), ("max_converters", 1, 1 << 16),
                             ("noise_transitions", 1, 64), ("noise_repeats", 20, 100_000)):
            v = getattr(self, name)
            if not (isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi):
                raise ValueError(f"{name} = {v!r}: must be an integer in [{lo}, {hi}]")


# ── which converters, and their configured transitions ─────────────────────────────────────


def pick_converters(shape: tuple[int, int], max_converters: int) -> NDArray[np.int64]:
    """Flat (C-order) indices of the converters measured: all of them if there are at most
    ``max_converters``; else a grid of ``n_r`` rows × ``n_c`` columns evenly spaced over the
    array, both ends included: the most converters ``n_r·n_c ≤ max``, and among those the
    grid whose aspect ``n_c/n_r`` is nearest the array's (more columns on a tie, so that column
    ramps are sampled)."""
    rows, cols = int(shape[0]), int(shape[-1])
    n = rows * cols
    if n <= max_converters:
        return np.arange(n, dtype=np.int64)
    grids = [(min(rows, max_converters // c), c) for c in range(1, min(cols, max_converters) + 1)]
    n_r, n_c = max(grids, key=lambda g: (g[0] * g[1], -abs(math.log(g[1] * rows / (g[0] * cols))),
                                         g[1]))
    r = np.unique(np.round(np.linspace(0, rows - 1, n_r)).astype(np.int64))
    c = np.unique(np.round(np.linspace(0, cols - 1, n_c)).astype(np.int64))
    return (r[:, None] * cols + c[None, :]).ravel()


def sub_converter(conv: Converter, pixels: NDArray[np.int64]
                  ) -> tuple[Converter, NDArray[np.int64]]:
    """The converters ``pixels`` of ``conv`` as a converter of shape ``(len(pixels),)`` (same
    levels, mismatch and noise: the same codes for the same volts), and each one's ramp table
    (the row of ``conv.levels``; 0 without tables)."""
    table = (np.zeros(pixels.size, np.int64) if conv.table_of_pixel is None
             else np.asarray(conv.table_of_pixel)[pixels])
    if conv.ideal:
        return conv, table
    levels, local = None, None
    if conv.levels is not None:
        used, inverse = np.unique(table, return_inverse=True)
        levels = np.asarray(conv.levels)[used]
        local = inverse.astype(np.int64) if used.size > 1 else None
    pick = (lambda a: None if a is None else np.asarray(a).reshape(-1)[pixels])  # noqa: E731
    sub = Converter(conv.bits, conv.v_min_V, conv.v_max_V, conv.offset_lsb, conv.gain_error,
                    conv.comparator_noise_lsb, levels, local, pick(conv.pixel_gain),
                    pick(conv.pixel_offset_lsb), (int(pixels.size),))
    return sub, table


def configured_transitions_V(conv: Converter, n: int) -> NDArray[np.float64]:
    """T[k], k = 1 … 2^N − 1, of each of the ``n`` converters of ``conv`` as built, in volts,
    shape ``(n, 2^N − 1)``: the input at which the noiseless code goes from k − 1 to k, by
    inverting the conversion (:mod:`chiptwin.pixel.converter`): level L ↦
    ``v_min + ((L − offset_i)/gain_i − offset_lsb)/(1 + gain_error)·LSB``."""
    k = 2**conv.bits - 1
    if conv.levels is None:
        lv = np.broadcast_to(np.arange(k) + 0.5, (n, k))
    else:
        rows = np.zeros(n, np.int64) if conv.table_of_pixel is None else conv.table_of_pixel
        lv = np.asarray(conv.levels)[rows]
    g = np.ones(n) if conv.pixel_gain is None else np.asarray(conv.pixel_gain).reshape(-1)
    o = np.zeros(n) if conv.pixel_offset_lsb is None else np.asarray(conv.pixel_offset_lsb
                                                                     ).reshape(-1)
    x = (lv - o[:, None]) / g[:, None]
    return conv.v_min_V + (x - conv.offset_lsb) / (1.0 + conv.gain_error) * conv.lsb_V


# ── the result ───────────────────────────────────────────────────────────────────────────────

#: Per-code arrays kept for every converter (``adc1241.npz``), from :class:`HistogramResult`.
ARRAYS: tuple[str, ...] = ("transitions_V", "transitions_sigma_V", "dnl_lsb", "dnl_sigma_lsb",
                           "inl_endpoint_lsb", "inl_endpoint_sigma_lsb", "inl_bestfit_lsb",
                           "inl_bestfit_sigma_lsb")


@dataclass
class AdcBench:
    """A finished bench: per-converter figures, per-code arrays, the worst converter's tests.

    ``pixels`` the measured converters' flat indices on the ``shape`` array, ``ramp_table``
    each one's ramp table; ``arrays`` per-code arrays ``(n, 2^N)`` (:data:`ARRAYS`, the hits
    ``counts`` and ``configured_transitions_V``, the twin's own T[k]); ``figures`` one dict per
    converter (:func:`converter_figures`); ``worst`` the index (into ``pixels``) of the largest
    max |DNL|, whose ``worst_hist`` and ``worst_dyn`` are kept for the plots; ``stimulus`` what
    drove the converters; ``wall_time_s`` not part of the JSON (same seed, same file).
    """

    scenario: str
    source: str
    seed: int
    settings: BenchSettings
    bits: int
    v_min_V: float
    v_max_V: float
    adc_keys: dict[str, Any]
    shape: tuple[int, int]
    pixels: NDArray[np.int64]
    ramp_table: NDArray[np.int64]
    stimulus: dict[str, Any]
    arrays: dict[str, NDArray[Any]]
    figures: list[dict[str, float]]
    worst: int
    worst_hist: HistogramResult
    worst_dyn: DynamicResult
    wall_time_s: float = field(default=0.0, compare=False)
    _doc: dict[str, Any] | None = field(default=None, init=False, repr=False, compare=False)

    def to_json(self) -> dict[str, Any]:
        """The ``adc1241.json`` document (:mod:`~chiptwin.characterize.adc1241.outputs`)."""
        from chiptwin.characterize.adc1241.outputs import to_json

        if self._doc is None:  # made once: the CLI prints from it and writes it
            self._doc = to_json(self)
        return self._doc

    def write(self, out_dir: str | Path) -> Path:
        """Write ``adc1241.json``, ``adc1241.npz``, ``adc1241.md`` and the plots, atomically."""
        from chiptwin.characterize.adc1241.outputs import write_outputs

        return write_outputs(self, out_dir)


# ── the bench ────────────────────────────────────────────────────────────────────────────────


def adc_bench(s: Scenario, *, dnl_sigma_lsb: float = 0.1, fit_samples: int = 1 << 14,
              max_converters: int = 256, rng: np.random.Generator | None = None,
              progress: Progress | None = None, settings: BenchSettings | None = None
              ) -> AdcBench:
    """Measure every converter of ``s``'s chip (at most ``max_converters``) by IEEE Std 1241.

    Parameters
    ----------
    s : Scenario
        Its ``[chip.adc]`` as built and its chip seed (as a run); its ``scenario.seed`` seeds
        the bench's stream.
    dnl_sigma_lsb, fit_samples, max_converters
        As :class:`BenchSettings` (``settings`` given: those win).
    rng : numpy.random.Generator, optional
        Default ``stage_rng(s.scenario.seed, "characterize.adc")``.
    progress : callable, optional
        ``progress(conversions_done, conversions_total)``.

    Raises
    ------
    ScenarioError
        A bench that would exceed :data:`MAX_CONVERSIONS` or :data:`MAX_BENCH_BYTES`, or fewer
        than 4 bits, naming the flag or key to change.
    """
    from chiptwin.twin.runner import chip_sensor
    from chiptwin.twin.scene import stage_rng

    t0 = time.perf_counter()
    cfg = settings or BenchSettings(dnl_sigma_lsb=dnl_sigma_lsb, fit_samples=fit_samples,
                                    max_converters=max_converters)
    rng = stage_rng(s.scenario.seed, "characterize.adc") if rng is None else rng
    adc = s.chip.adc
    if adc.bits < 4:
        raise ScenarioError(s.source, "chip.adc.bits", adc.bits,
                            "the ADC bench needs at least 4 bits (2^N − 2 interior codes)")
    shape = (int(s.chip.rows), int(s.chip.cols))
    pixels = pick_converters(shape, cfg.max_converters)
    conv, table = sub_converter(chip_sensor(s).converter, pixels)
    n = int(pixels.size)
    t_cfg = configured_transitions_V(conv, n)
    plan = _plan(s, cfg, conv, t_cfg)
    tick = _Ticker(progress, n * (plan["samples"] + cfg.fit_samples + plan["noise_rows"]))
    counts = _ramp_counts(conv, plan["ramp"], plan["samples"], n, rng, tick)
    arrays, figures = _histograms(counts, conv, plan["ramp"])
    arrays["configured_transitions_V"] = _pad_codes(t_cfg)
    worst = int(np.nanargmax([f["dnl_max_lsb"] for f in figures])) if any(
        np.isfinite(f["dnl_max_lsb"]) for f in figures) else 0
    worst_hist = histogram_from_counts(counts[worst], conv.bits, conv.v_min_V, conv.v_max_V,
                                       plan["ramp"])
    sine, worst_dyn = _dynamic(conv, arrays["transitions_V"], cfg, figures, worst, rng, tick)
    noise = _noise(conv, arrays["transitions_V"], cfg, figures, rng, tick)
    stimulus = {"histogram": {"stimulus": "ramp", "v_start_V": plan["ramp"].v_start_V,
                              "v_stop_V": plan["ramp"].v_stop_V, "samples": plan["samples"],
                              "hits_per_lsb": plan["hits_per_lsb"]},
                "sine": sine, "transition_noise": noise}
    keys = asdict(adc)
    return AdcBench(s.scenario.name, s.source, s.scenario.seed, cfg, conv.bits, conv.v_min_V,
                    conv.v_max_V, keys, shape, pixels, table, stimulus, arrays, figures, worst,
                    worst_hist, worst_dyn, round(time.perf_counter() - t0, 3))


class _Ticker:
    def __init__(self, progress: Progress | None, total: int) -> None:
        self.progress, self.total, self.done = progress, total, 0

    def __call__(self, conversions: int) -> None:
        self.done += conversions
        if self.progress is not None:
            self.progress(min(self.done, self.total), self.total)


def _plan(s: Scenario, cfg: BenchSettings, conv: Converter, t_cfg: NDArray[np.float64]
          ) -> dict[str, Any]:
    """The ramp (beyond every converter's ends), its samples, the sweep's size; refuses a
    bench beyond the time or memory bound."""
    q, noise = conv.lsb_V, conv.comparator_noise_lsb
    pad = (cfg.overdrive_lsb + 6.0 * noise) * q
    ramp = Ramp(float(t_cfg[:, 0].min() - pad), float(t_cfg[:, -1].max() + pad))
    g = 1.0 if conv.pixel_gain is None else float(np.max(conv.pixel_gain))
    span_lsb = (ramp.v_stop_V - ramp.v_start_V) / q * g * (1.0 + conv.gain_error)
    over = max(0.0, (span_lsb - 2**conv.bits) / 2.0)
    samples = histogram_samples(conv.bits, cfg.dnl_sigma_lsb, ONE_SIGMA, "ramp", over)
    n, k = t_cfg.shape[0], 2**conv.bits
    sweep = _sweep_grid(noise, cfg)
    rows = sweep[0].size * cfg.noise_repeats
    total = n * (samples + cfg.fit_samples + rows)
    if total > MAX_CONVERSIONS:
        raise ScenarioError(
            s.source, "--adc-dnl-sigma", cfg.dnl_sigma_lsb,
            f"the bench would make {total:.3g} conversions ({n} converters × {samples} ramp "
            f"samples for {k} codes, + sine and DC sweep), above the {MAX_CONVERSIONS:.3g} "
            "bound (MAX_CONVERSIONS, minutes of CPU): ask a larger DNL sigma, fewer converters "
            "(--adc-converters) or fewer bits (chip.adc.bits)")
    need = n * (k * 88 + cfg.fit_samples * 12)
    if need > MAX_BENCH_BYTES:
        raise ScenarioError(
            s.source, "--adc-converters", cfg.max_converters,
            f"{n} converters × {k} codes need {need / 2**20:.0f} MiB of per-code arrays, above "
            f"the {MAX_BENCH_BYTES / 2**20:.0f} MiB bound (MAX_BENCH_BYTES): measure fewer "
            "converters or fewer bits (chip.adc.bits)")
    return {"ramp": ramp, "samples": samples, "noise_rows": rows,
            "hits_per_lsb": samples / ((ramp.v_stop_V - ramp.v_start_V) / q)}


def _convert_blocks(conv: Converter, n_rows: int, n: int, volts_of: Callable, sink: Callable,
                    rng: np.random.Generator, tick: _Ticker) -> None:
    """``sink(r0, codes)`` for blocks of rows of ``volts_of(r0, r1)`` ``(r1 − r0, n)``."""
    step = max(1, BLOCK_CONVERSIONS // n)
    for r0 in range(0, n_rows, step):
        r1 = min(n_rows, r0 + step)
        sink(r0, conv.convert(volts_of(r0, r1), rng))
        tick((r1 - r0) * n)


def _ramp_counts(conv: Converter, ramp: Ramp, samples: int, n: int, rng: np.random.Generator,
                 tick: _Ticker) -> NDArray[np.int64]:
    """Hits per code of each converter for the ramp's ``samples`` points ``(i + ½)/S`` along
    it, every converter seeing the same volts; shape ``(n, 2^N)``."""
    n_run = 1 if conv.ideal else n  # ideal: one function, nothing drawn: every converter alike
    counts = np.zeros((n_run, 2**conv.bits), np.int64)
    a, b = ramp.v_start_V, ramp.v_stop_V

    def volts(r0: int, r1: int) -> NDArray[np.float64]:
        v = a + (b - a) * (np.arange(r0, r1) + 0.5) / samples
        return np.broadcast_to(v[:, None], (r1 - r0, n_run))

    def count(_: int, codes: NDArray[np.int64]) -> None:
        _kernels.add_counts(codes, counts)
        tick(codes.size * (n // n_run - 1))

    _convert_blocks(conv, samples, n_run, volts, count, rng, tick)
    return np.repeat(counts, n, axis=0) if n_run < n else counts


def _pad_codes(t: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.full((t.shape[0], t.shape[1] + 1), np.nan)
    out[:, 1:] = t
    return out


def _histograms(counts: NDArray[np.int64], conv: Converter, ramp: Ramp
                ) -> tuple[dict[str, NDArray[Any]], list[dict[str, float]]]:
    """The histogram test of each converter: its per-code arrays stacked, its figures."""
    n, k = counts.shape
    arrays: dict[str, NDArray[Any]] = {name: np.empty((n, k)) for name in ARRAYS}
    figures = []
    for i in range(n):
        h = histogram_from_counts(counts[i], conv.bits, conv.v_min_V, conv.v_max_V, ramp)
        for name in ARRAYS:
            arrays[name][i] = getattr(h, name)
        figures.append(converter_figures(h))
    arrays["counts"] = counts
    return arrays, figures


def _dynamic(conv: Converter, t_meas: NDArray[np.float64], cfg: BenchSettings,
             figures: list[dict[str, float]], worst: int, rng: np.random.Generator,
             tick: _Ticker) -> tuple[dict[str, Any], DynamicResult]:
    """A coherent sine per converter, centred on its measured range and ``fit_amplitude_frac``
    of its half range ``(T[last] − T[1])/2 · 2^(N−1)/(2^(N−1) − 1)`` (0 dBFS: 2^(N−1) LSB of
    its own); the three-parameter fit and the spectrum of each record."""
    m, n, half_codes = cfg.fit_samples, t_meas.shape[0], 2 ** (conv.bits - 1)
    cycles = coherent_cycles(m, m / 20.0 + 0.3)
    centre = 0.5 * (t_meas[:, 1] + t_meas[:, -1])
    amp = cfg.fit_amplitude_frac * 0.5 * (t_meas[:, -1] - t_meas[:, 1]) * half_codes / (
        half_codes - 1)
    wave = np.sin(2.0 * np.pi * cycles * np.arange(m) / m)
    codes = np.empty((m, n), np.int32)

    def put(r0: int, c: NDArray[np.int64]) -> None:
        codes[r0:r0 + c.shape[0]] = c

    _convert_blocks(conv, m, n, lambda r0, r1: centre + wave[r0:r1, None] * amp, put, rng,
                    tick)
    worst_dyn = None
    for i in range(n):
        d = dynamic_test(codes[:, i], conv.bits, cycles=cycles)
        f = converter_figures(dyn=d)
        figures[i].update({k: f[k] for k in ("sinad_db", "sinad_db_sigma", "enob_bits",
                                             "enob_bits_sigma", "sfdr_db")})
        worst_dyn = d if i == worst else worst_dyn
    desc = {"samples": m, "cycles": cycles, "amplitude_frac": cfg.fit_amplitude_frac,
            "fit": "three-parameter (coherent), rectangular-window spectrum",
            "placed": "centre and half range from each converter's measured T[1], T[2^N−1]"}
    return desc, worst_dyn


def _sweep_grid(noise_lsb: float, cfg: BenchSettings) -> tuple[NDArray[np.float64], float]:
    """The DC sweep's offsets from the first swept transition (LSB) and its step: 0.05 LSB,
    or σ/5 for a comparator noise σ above 0.25 LSB; margin 3 LSB + 5σ each side."""
    step = 0.05 if noise_lsb <= 0.25 else noise_lsb / 5.0
    margin = 3.0 + 5.0 * noise_lsb
    return np.arange(-margin, cfg.noise_transitions - 1 + margin + step / 2, step), step


def _noise(conv: Converter, t_meas: NDArray[np.float64], cfg: BenchSettings,
           figures: list[dict[str, float]], rng: np.random.Generator,
           tick: _Ticker) -> dict[str, Any]:
    """Transition noise of each converter: DC levels from ``margin`` below its measured
    T[k0] to ``margin`` above T[k0 + noise_transitions − 1] (k0 = 2^(N−1) − transitions/2,
    mid-scale), R conversions at each, fitted by :func:`transition_noise`."""
    x, step = _sweep_grid(conv.comparator_noise_lsb, cfg)
    n, r, q = t_meas.shape[0], cfg.noise_repeats, conv.lsb_V
    k0 = 2 ** (conv.bits - 1) - cfg.noise_transitions // 2
    k1 = k0 + cfg.noise_transitions - 1
    slope = (t_meas[:, k1] - t_meas[:, k0]) / max(k1 - k0, 1)
    slope = np.where(k1 > k0, slope, q)
    levels = t_meas[:, k0][None, :] + x[:, None] * slope[None, :]  # (L, n)
    codes = np.empty((x.size * r, n), np.int32)

    def put(r0: int, c: NDArray[np.int64]) -> None:
        codes[r0:r0 + c.shape[0]] = c

    _convert_blocks(conv, x.size * r, n, lambda r0, r1: levels[np.arange(r0, r1) // r], put,
                    rng, tick)
    codes3 = codes.reshape(x.size, r, n)
    resolved = []
    for i in range(n):
        if np.all(codes3[:, :, i] == codes3[:, :1, i]):  # one code per level: nothing to fit
            figures[i]["transition_noise_lsb"] = np.nan
            resolved.append(0)
            continue
        tn = transition_noise(levels[:, i], codes3[:, :, i].astype(np.int64), conv.bits,
                              conv.v_min_V, conv.v_max_V)
        figures[i]["transition_noise_lsb"] = tn.transition_noise_lsb
        figures[i]["transition_noise_lsb_sigma"] = tn.transition_noise_sigma_lsb
        resolved.append(int(tn.transitions.size))
    return {"first_transition": k0, "last_transition": k1, "step_lsb": step,
            "margin_lsb": float(-x[0]), "levels": int(x.size), "repeats": r,
            "transitions_resolved_median": float(np.median(resolved)),
            "unit": "LSB of the ideal converter, input-referred; NaN when the level grid "
                    f"cannot resolve it (σ below about 2 × {step:g} LSB)"}
