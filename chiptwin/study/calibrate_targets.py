"""What a calibration fits to: a table of measured values, or an EMVA 1288 data set.

**Table** (``[study.target] kind = "table"``): a CSV file, ``#`` lines and blank lines ignored,
the first other line the header, every column named ``name [unit]`` (``[1]`` for a pure
number), e.g.::

    # SNR of the 4 × 4 test chip at three light levels, each the mean of 5 runs
    assay.photons_per_s_per_um2 [photons/s/um2], snr_power [1], snr_power_se [1]
    0.2, 41.3, 2.1
    0.5, 196.0, 8.4

The study names the two columns it fits (``x``, ``y``); the file holds exactly those two and,
optionally, ``<y>_se``, in any order, nothing else:

- ``x`` is a **scenario key** (every row is the scenario run with that key set; its unit is the
  one the key's name carries, :func:`key_unit`: ``_um`` → µm, ``_fF`` → fF, …, a key without
  one takes ``[1]``) and ``y`` a **metric** of :data:`chiptwin.study.metrics.CATALOGUE` of kind
  "mean" (a number per run), in the metric's unit; or
- ``x`` is ``time [s]`` (a **time series** from one run) and ``y`` a quantity of
  :data:`SERIES`: ``light [photons/s]``, what a plate reader reads of one well.
- ``<y>_se`` (optional, ``y``'s unit, > 0): the standard error of each ``y``. With it the
  objective is χ² (a likelihood); without it, least squares with equal weights, the scale of
  the errors estimated from the residuals.
- Rows with the same ``x`` are **replicates** of one measurement: they are merged into their
  mean before the fit (inverse-variance weighted with standard errors, its standard error
  ``1/√Σw``; plain without), so a data point is a distinct ``x``.

Units are compared after spelling is normalised (``um`` = ``µm``, ``e-`` = ``e⁻``, ``^2`` =
``²``, spaces dropped); a wrong unit is refused naming the column, its unit and the unit allowed.
Errors in the file name the file, the line and the column.

**EMVA 1288** (``kind = "emva1288"``): a data set's folder (``EMVA1288_Data.txt`` and its
images), read by :func:`chiptwin.characterize.measured.read_measured`. Its identity is the hash
of every file in the folder.

**IEEE 1241 ADC bench** (``kind = "adc1241"``): the folder ``chiptwin characterize SCENARIO
--adc`` writes; each converter's transition noise in its ``adc1241.json`` is what the fit
compares (:mod:`chiptwin.study.calibrate_adc`, which reads and checks it).
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.config import ScenarioError
from chiptwin.study.metrics import CATALOGUE

#: Time-series quantities a table target may fit (``x = "time"``): name → (unit, meaning).
SERIES: dict[str, tuple[str, str]] = {
    "light": ("photons/s", "the light a site emits into 4π at that time, mean over the "
              "scenario's sites (the kinetics stage's rate: chiptwin.twin.stages.light_source)"),
}

#: A scenario key's unit from the end of its name, longest match first; no match: ``1``.
KEY_UNITS: tuple[tuple[str, str], ...] = (
    ("_photons_per_s_per_um2", "photons/s/µm²"), ("_nA_per_cm2", "nA/cm²"),
    ("_per_M_per_s", "1/(M·s)"), ("_photons_per_incorporation", "photons"),
    ("_per_s", "1/s"), ("_um", "µm"), ("_nm", "nm"), ("_fF", "fF"), ("_uV", "µV"),
    ("_V", "V"), ("_hz", "Hz"), ("_fmol", "fmol"), ("_amol", "amol"), ("_M", "M"),
    ("_C", "°C"), ("_lsb", "LSB"), ("_db", "dB"), ("_e", "e⁻"), ("_s", "s"),
)
_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_.]*)\s*\[([^\]]*)\]\s*$")
_SPELLINGS = (("µ", "u"), ("μ", "u"), ("⁻", "-"), ("²", "2"), ("^2", "2"), ("**2", "2"),
              ("°", ""), ("deg", ""), ("·", "*"), (" ", ""))


def key_unit(key: str) -> str:
    """The unit a scenario key's name carries (``chip.pixel.capacitance_fF`` → ``fF``)."""
    leaf = "_" + key.rsplit(".", 1)[-1]
    return next((unit for end, unit in KEY_UNITS if leaf.endswith(end)), "1")


def same_unit(a: str, b: str) -> bool:
    """Two spellings of one unit (``um2`` and ``µm²``, ``e-`` and ``e⁻``)."""
    def norm(u: str) -> str:
        for x, y in _SPELLINGS:
            u = u.replace(x, y)
        return u

    return norm(a) == norm(b)


@dataclass(frozen=True)
class TableTarget:
    """A table of measured values (see the module's grammar), replicates merged.

    Attributes
    ----------
    x, y : the fitted columns: a scenario key or ``"time"``; a metric or a :data:`SERIES` name
    x_values, y_values : (n,) one entry per distinct x, sorted by x
    se : (n,) standard errors, or None (least squares with equal weights)
    replicates : (n,) rows merged into each point
    units : the units of x and y as the file writes them
    """

    path: str
    hash: str
    x: str
    y: str
    x_values: tuple
    y_values: tuple[float, ...]
    se: tuple[float, ...] | None
    replicates: tuple[int, ...]
    units: tuple[str, str]
    kind: str = "table"

    @property
    def series(self) -> bool:
        """A time series of one run (``x = "time"``), not one run per row."""
        return self.x == "time"

    @property
    def n_points(self) -> int:
        return len(self.y_values)

    def describe(self) -> str:
        se = f"{self.y}_se given: χ² with the measured standard errors" if self.se else \
            f"no {self.y}_se: least squares with equal weights"
        return (f"table {Path(self.path).name}: {self.y} [{self.units[1]}] at "
                f"{self.n_points} values of {self.x} [{self.units[0]}] "
                f"({sum(self.replicates)} rows, replicates merged); {se}")


@dataclass(frozen=True)
class EmvaTarget:
    """An EMVA 1288 data set: its photon-transfer series is what the fit compares.

    ``measurement`` is the data set read (a
    :class:`~chiptwin.characterize.measure.Measurement`); ``max_pixels`` bounds the pixels of
    the twin read per image (None: the scenario's chip, as the bench tiles it)."""

    path: str
    hash: str
    pixel_pitch_um: float | None
    max_pixels: int | None
    measurement: Any = field(compare=False, repr=False)
    kind: str = "emva1288"

    @property
    def n_points(self) -> int:
        """Values the fit compares: the bright mean and variance below saturation, the dark
        mean and variance at every point (:mod:`chiptwin.study.calibrate_emva`)."""
        from chiptwin.study.calibrate_emva import emva_measured

        return emva_measured(self.measurement).n

    def describe(self) -> str:
        from chiptwin.study.calibrate_emva import used_points

        t = self.measurement.temporal
        n, below = int(t.t_exp_s.size), int(used_points(t).sum())
        return (f"EMVA 1288 data set {Path(self.path).name}: the standard's K and R = Kη over "
                f"its range ({below} of {n} photon-transfer points), the variance at "
                f"saturation, dark mean and variance at all {n}; {t.n_values} values an image")


#: The EMVA target's compared statistics, by version (2: the standard's K and R over its range,
#: the variance at saturation, the dark means and variances; 1 compared the bright pairs point
#: by point).
EMVA_STATISTICS: int = 2


def file_hash(paths: list[Path], root: Path) -> str:
    """SHA-256 of the files' names (relative to ``root``) and bytes, 16 hex digits."""
    h = hashlib.sha256()
    for p in sorted(paths):
        h.update(str(p.relative_to(root)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


# ---------------------------------------------------------------- the table's grammar


def read_table(path: Path, x: str, y: str, x_rule: Any) -> TableTarget:
    """Read and check a table target (the module's grammar).

    Parameters
    ----------
    path : the CSV file
    x, y : the columns the study fits (checked by the caller: a scenario key or ``"time"``; a
        metric or a :data:`SERIES` name)
    x_rule : the x key's schema field (its rule checks every x value), None for time
    """
    src = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(src, "(file)", src, f"must be a readable UTF-8 CSV file ({exc})"
                            ) from None
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise ScenarioError(src, "(header)", "", f"the file is empty; the first line names the "
                            f"columns: {_header_example(x, y)}")
    columns = _header(src, lines[0], x, y)
    rows = [_row(src, n, line, columns) for n, line in lines[1:]]
    xs = [_x_value(src, n, v[x], x, x_rule) for n, v in rows]
    ys = [_number(src, n, y, v[y], positive=False) for n, v in rows]
    ses = [_number(src, n, f"{y}_se", v[f"{y}_se"], positive=True) for n, v in rows] \
        if f"{y}_se" in columns else None
    if y in SERIES:
        for (n, _), value in zip(rows, ys, strict=True):
            if value < 0:
                raise ScenarioError(src, f"line {n}, column {y}", value, "light is ≥ 0")
    merged = merge_replicates(xs, ys, ses)
    return TableTarget(src, file_hash([path], path.parent), x, y, *merged,
                       units=(columns[x], columns[y]))


def _header_example(x: str, y: str) -> str:
    unit = "s" if x == "time" else key_unit(x)
    yu = SERIES[y][0] if y in SERIES else CATALOGUE[y].unit if y in CATALOGUE else "?"
    return f"{x} [{unit}], {y} [{yu}], {y}_se [{yu}] (the last optional)"


def _header(src: str, first: tuple[int, str], x: str, y: str) -> dict[str, str]:
    """Column name → unit, checked against what the study fits."""
    n, line = first
    wanted = {x: "s" if x == "time" else key_unit(x),
              y: SERIES[y][0] if y in SERIES else CATALOGUE[y].unit}
    wanted[f"{y}_se"] = wanted[y]
    columns: dict[str, str] = {}
    for cell in next(csv.reader(io.StringIO(line))):
        m = _HEADER.match(cell)
        if not m:
            raise ScenarioError(src, f"line {n} (header)", cell.strip(),
                                "every column is `name [unit]` ([1] for a pure number): "
                                + _header_example(x, y))
        name, unit = m.group(1), m.group(2).strip()
        if name not in wanted:
            raise ScenarioError(src, f"line {n} (header)", name,
                                f"not a column of this fit; it holds {x}, {y} and optionally "
                                f"{y}_se (the study's target x and y): {_header_example(x, y)}")
        if name in columns:
            raise ScenarioError(src, f"line {n} (header)", name, "is named twice")
        if not same_unit(unit, wanted[name]):
            raise ScenarioError(src, f"line {n}, column {name}", f"[{unit}]",
                                f"the unit of {name} is [{wanted[name]}]")
        columns[name] = unit
    for need in (x, y):
        if need not in columns:
            raise ScenarioError(src, f"line {n} (header)", line.strip(),
                                f"has no column {need}: {_header_example(x, y)}")
    return columns


def _row(src: str, n: int, line: str, columns: dict[str, str]) -> tuple[int, dict[str, str]]:
    cells = [c.strip() for c in next(csv.reader(io.StringIO(line)))]
    if len(cells) != len(columns):
        raise ScenarioError(src, f"line {n}", line.strip(),
                            f"must hold {len(columns)} values ({', '.join(columns)})")
    return n, dict(zip(columns, cells, strict=True))


def _number(src: str, n: int, column: str, cell: str, positive: bool) -> float:
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or (positive and value <= 0):
        raise ScenarioError(src, f"line {n}, column {column}", cell,
                            "must be a finite number" + (" > 0 (a standard error; leave the "
                                                         "column out for equal weights)"
                                                         if positive else ""))
    return value


def _x_value(src: str, n: int, cell: str, x: str, rule: Any):
    """A time (≥ 0 s) or a value of the x key, checked by the key's own rule."""
    value = _number(src, n, x, cell, positive=False)
    if rule is None:
        if value < 0:
            raise ScenarioError(src, f"line {n}, column time", cell, "a time is ≥ 0 s")
        return value
    from chiptwin.config.fields import check_value

    if rule.metadata.get("kind") is int:
        if value != round(value):
            raise ScenarioError(src, f"line {n}, column {x}", cell, f"{x} is an integer")
        value = int(round(value))
    return check_value(rule, value, src, f"line {n}, column {x}")


def merge_replicates(xs: list, ys: list[float], ses: list[float] | None
                     ) -> tuple[tuple, tuple[float, ...], tuple[float, ...] | None,
                                tuple[int, ...]]:
    """Rows of one x merged: the inverse-variance weighted mean and ``1/√Σw`` with standard
    errors, else the plain mean. Returns ``(x, y, se, rows merged)``, sorted by x."""
    groups: dict[Any, list[int]] = {}
    for i, xv in enumerate(xs):
        groups.setdefault(xv, []).append(i)
    out_x, out_y, out_se, counts = [], [], [], []
    for xv in sorted(groups):
        idx = groups[xv]
        y = np.array([ys[i] for i in idx])
        if ses is None:
            out_y.append(float(y.mean()))
        else:
            w = 1.0 / np.array([ses[i] for i in idx]) ** 2
            out_y.append(float((w * y).sum() / w.sum()))
            out_se.append(float(1.0 / math.sqrt(w.sum())))
        out_x.append(xv)
        counts.append(len(idx))
    return tuple(out_x), tuple(out_y), tuple(out_se) if ses is not None else None, tuple(counts)


# ---------------------------------------------------------------- EMVA 1288 data sets


def read_emva(src: str, where: str, given: str, path: Path, pixel_pitch_um: float | None,
              max_pixels: int | None) -> EmvaTarget:
    """An EMVA 1288 data set's folder (or its ``EMVA1288_Data.txt``) read and hashed; an
    absent one is refused naming the path looked for."""
    folder = path.parent if path.is_file() else path
    descriptor = folder / "EMVA1288_Data.txt"
    if not descriptor.is_file():
        raise ScenarioError(src, where, given,
                            f"no EMVA 1288 data set there: looked for {descriptor.resolve()} "
                            "(a data set's folder holds EMVA1288_Data.txt and its images; the "
                            "project does not carry measured data: put the set there, or name "
                            "its folder, relative to this study file or absolute)")
    from chiptwin.characterize.measured import read_measured

    m = read_measured(folder, pixel_pitch_um)
    files = [p for p in folder.rglob("*") if p.is_file()]
    # the statistics compared are part of the target's identity: a store written when they were
    # others is refused on resume, not misread (EMVA_STATISTICS: which ones)
    ident = hashlib.sha256(f"{file_hash(files, folder)}/{EMVA_STATISTICS}".encode()).hexdigest()
    return EmvaTarget(str(folder), ident[:16], pixel_pitch_um, max_pixels, m)
