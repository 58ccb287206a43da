"""Measured flow-value distributions per true homopolymer length, the chemistry presets fitted to
them, and the distances (``chiptwin reads profile``).

Three measured sets (their layout in the real-data folder: :data:`PROFILE_FILES`,
:data:`ION_FILE`):

* 454 GS FLX and GS FLX Titanium flow-value profiles (PyroNoise, Quince et al., Nature Methods
  6:639, 2009; shipped with the qiime denoiser, Reeder & Knight, Nature Methods 7:668, 2010):
  for true lengths 0–9, −ln P(value in bin) over the bins 0.00 … 9.99, read by
  :func:`read_profile` (lengths 0–4 counted from real runs, 5–9 fitted normals);
* Ion Torrent PGM reads (Rothberg et al., Nature 475:348, 2011) with their flow values and the
  reference under each read (:func:`measured_values`);
* 454 SFF runs (:data:`SFF_FILES`), without truth: their pooled flow values against the
  presets' mixture of lengths weighted as the instrument called them (:func:`sff_check`).

For each, :func:`chemistry_report` fits the flow-value model
(:func:`chiptwin.kinetics.chemistry_fit.fit_flow_model`) and states the total variation and KS
distance per length 0–5 of the fit and of the bundled preset; the 454 sets are also compared
with each other, the yardstick a preset is held to.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from chiptwin.config import ScenarioError
from chiptwin.kinetics.chemistry import N_BINS, FlowModel, draw_flow_values
from chiptwin.kinetics.chemistry_fit import (
    Fit,
    fit_flow_model,
    histograms,
    ks_distance,
    model_distributions,
    total_variation,
)
from chiptwin.kinetics.chemistry_presets import PRESETS
from chiptwin.kinetics.pyro import flow_incorporations, flows_to_sequence

#: The 454 profiles, by chemistry, under the real-data folder.
PROFILE_FILES = {"454_flx": "flow_profiles/FLX_error_profile.dat",
                 "454_titanium": "flow_profiles/Titanium_error_profile.dat"}

#: The Ion Torrent reads with their alignment, under the real-data folder.
ION_FILE = "ion/b7_295_chunk.bam"

#: The lengths fitted and compared (0–4 counted in the 454 profiles, 5 a fitted normal there).
LENGTHS = tuple(range(6))

#: Lengths a profile holds, and lines per length (one header line, then one per bin).
PROFILE_LENGTHS, PROFILE_LINES = 10, N_BINS + 1


def read_profile(path: str | Path) -> NDArray[np.float64]:
    """A PyroNoise flow-value profile as probabilities: shape (10, 1000), each row (true length
    0 … 9) summing to 1 (the file's −ln P, exponentiated and normalised: its rows sum to
    0.98–1.007 as stored). Refuses a file of another shape or with a non-number, naming the
    line."""
    path = Path(path)
    try:
        lines = path.read_text().split()
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(str(path), "(file)", str(path),
                            f"must be a readable flow-value profile ({exc})") from None
    need = PROFILE_LENGTHS * PROFILE_LINES
    if len(lines) != need:
        raise ScenarioError(str(path), "(lines)", len(lines),
                            f"must be {need}: {PROFILE_LENGTHS} blocks of a header and "
                            f"{N_BINS} values of -ln P")
    try:
        values = np.array([float(x) for x in lines]).reshape(PROFILE_LENGTHS, PROFILE_LINES)
    except ValueError:
        bad = next(i for i, x in enumerate(lines) if not _is_number(x))
        raise ScenarioError(str(path), f"line {bad + 1}", lines[bad],
                            "must be a number (-ln P)") from None
    nlp = values[:, 1:]
    if not np.all(np.isfinite(nlp)):
        raise ScenarioError(str(path), "(values)", "non-finite", "must all be finite -ln P")
    p = np.exp(-(nlp - nlp.min(axis=1, keepdims=True)))
    return p / p.sum(axis=1, keepdims=True)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def measured_values(path: str | Path, truth: str | Path | None = None
                    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Every flow value of the file's reads that have a truth, with its true length: the
    truth (key + the template under the read) run through the file's flow order
    (:func:`chiptwin.kinetics.pyro.flow_incorporations`) up to the flow before the one that
    adds its last base (that flow may read on past the aligned part)."""
    from chiptwin.report.flowgram_files import read_flowgrams

    data = read_flowgrams(path, truth)
    ys, hs = [], []
    for read in data.reads:
        if read.truth is None:
            continue
        template = data.key + "".join(b for b in read.truth if b in "ACGT")
        n = min(flows_to_sequence(template, data.flow_order) - 1, read.values.size)
        if n <= 0:
            continue
        ys.append(read.values[:n])
        hs.append(flow_incorporations(template, data.flow_order, n)[1])
    if not ys:
        raise ScenarioError(str(path), "reads", 0, "must hold reads with a truth (aligned "
                            "reads with MD, or --truth FASTA)")
    return np.concatenate(ys), np.concatenate(hs)


@dataclass(frozen=True)
class LengthRow:
    """One true length's distances: of the refit and of the preset to the measured law."""

    length: int
    flows: int | None  # measured flows (None: a profile's probabilities)
    tv_fit: float
    ks_fit: float
    tv_preset: float
    ks_preset: float
    tv_floor: float | None = None  # expected TV of a perfect model from this many flows


@dataclass(frozen=True)
class ChemistryReport:
    """A measured set, its fit and the preset's distances per length."""

    name: str
    source: str
    fit: Fit
    preset: FlowModel
    rows: list[LengthRow]
    measured: dict[int, NDArray[np.float64]] = field(repr=False)


#: Monte Carlo draws of :func:`sampling_floor`.
FLOOR_REPEATS = 20


def sampling_floor(model: FlowModel, h: int, n: int, rng: np.random.Generator) -> float:
    """The total variation a perfect model shows against ``n`` measured flows of length ``h``:
    the mean over :data:`FLOOR_REPEATS` sets of ``n`` draws from the model of their histogram's
    distance to the model's law (on 1,000 bins, a few hundred flows leave a TV near 0.2)."""
    q = model_distributions(model, [h])[h]
    tv = [total_variation(histograms(draw_flow_values(np.full(n, h), model, rng),
                                     np.full(n, h), h)[h], q) for _ in range(FLOOR_REPEATS)]
    return float(np.mean(tv))


def chemistry_report(name: str, source: str, measured: dict[int, NDArray[np.float64]],
                     law: str = "lognormal", rng: np.random.Generator | None = None
                     ) -> ChemistryReport:
    """Fit ``measured`` (length → counts or probabilities per bin), compare fit and preset
    ``name``; with counts (``rng`` given), each length's sampling floor too."""
    fit = fit_flow_model({h: measured[h] for h in LENGTHS}, law)
    preset = PRESETS[name]
    fitted = model_distributions(fit.model, list(LENGTHS))
    bundled = model_distributions(preset, list(LENGTHS))
    rows = []
    for h in LENGTHS:
        p = measured[h]
        counts = rng is not None
        rows.append(LengthRow(
            h, int(p.sum()) if counts else None,
            total_variation(p, fitted[h]), ks_distance(p, fitted[h]),
            total_variation(p, bundled[h]), ks_distance(p, bundled[h]),
            sampling_floor(preset, h, int(p.sum()), rng) if counts else None))
    return ChemistryReport(name, source, fit, preset, rows, measured)


def between_454(flx: NDArray[np.float64], titanium: NDArray[np.float64]
                ) -> list[tuple[int, float, float]]:
    """(length, TV, KS) of the FLX profile against the Titanium one, lengths 0–5."""
    return [(h, total_variation(flx[h], titanium[h]), ks_distance(flx[h], titanium[h]))
            for h in LENGTHS]


def measured_sets(data_dir: str | Path) -> list[tuple[str, str, dict, str]]:
    """(chemistry, source, length → measured bins, empty-flow law) of every set found under
    ``data_dir``; a missing file is refused naming it."""
    root = Path(data_dir)
    out = []
    for name, rel in PROFILE_FILES.items():
        p = read_profile(_need(root / rel))
        out.append((name, rel, {h: p[h] for h in range(PROFILE_LENGTHS)}, "lognormal"))
    y, h = measured_values(_need(root / ION_FILE))
    counts = histograms(y, h, max(LENGTHS))
    out.append(("ion_pgm", ION_FILE, {k: counts[k] for k in LENGTHS}, "lognormal"))
    return out


def _need(path: Path) -> Path:
    if not path.is_file():
        raise ScenarioError(str(path), "(file)", str(path),
                            "must exist: the real-data folder holds flow_profiles/ and ion/ "
                            "(the 454 profiles from the qiime denoiser's support files, the Ion "
                            "BAM from BioD's test data)")
    return path


#: The 454 SFF runs checked, under the real-data folder, and their chemistry (Biopython's and
#: qiime's test data; Margulies et al., Nature 437:376, 2005).
SFF_FILES = {"sff/Fasting_Example.sff": "GS FLX", "sff/E3MFGYR02_random_10_reads.sff": "GS FLX",
             "sff/greek.sff": "GS FLX Titanium"}

#: The 454 presets an SFF run is held against.
SFF_PRESETS = ("454_flx", "454_titanium")


@dataclass(frozen=True)
class SffCheck:
    """One SFF run's pooled flow values against each 454 preset's mixture."""

    path: str
    chemistry: str
    reads: int
    flows: int
    tv: dict[str, float]
    ks: dict[str, float]


def sff_check(path: str | Path, chemistry: str) -> SffCheck:
    """An SFF run has no truth: its flow values of every read's called region (key flows to
    the flow of its last stored base), pooled, against each preset's laws mixed with the
    weights of the lengths the values round to (the instrument's calls, near enough: a
    rounding miscall moves mass between neighbours, the same in the measured values and in the
    mixture's weights)."""
    from chiptwin.report.flowgram_files import read_flowgrams

    data = read_flowgrams(path)
    ys = []
    for read in data.reads:
        called = np.cumsum(np.floor(np.clip(read.values, 0.0, 12.0) + 0.5))
        last = int(np.searchsorted(called, len(read.bases) + len(data.key)))
        ys.append(read.values[: min(last + 1, read.values.size)])
    y = np.concatenate(ys)
    h = np.minimum(np.floor(np.clip(y, 0.0, 12.0) + 0.5), PROFILE_LENGTHS - 1).astype(np.int64)
    weights = np.bincount(h, minlength=PROFILE_LENGTHS) / h.size
    measured = histograms(y, np.zeros(y.size, dtype=np.int64), 0)[0]
    tv, ks = {}, {}
    for name in SFF_PRESETS:
        law = model_distributions(PRESETS[name], list(range(PROFILE_LENGTHS)))
        mix = sum(weights[k] * law[k] for k in range(PROFILE_LENGTHS))
        tv[name], ks[name] = total_variation(measured, mix), ks_distance(measured, mix)
    return SffCheck(str(path), chemistry, len(data.reads), int(y.size), tv, ks)


def sff_checks(data_dir: str | Path) -> list[SffCheck]:
    """:func:`sff_check` of every :data:`SFF_FILES` found under ``data_dir`` (a missing one, or
    all without Biopython, left out: the check is a cross-check, not the fit)."""
    import importlib.util

    if importlib.util.find_spec("Bio") is None:  # the [sff] extra's reader
        return []
    root = Path(data_dir)
    return [sff_check(root / rel, chem) for rel, chem in SFF_FILES.items()
            if (root / rel).is_file()]
