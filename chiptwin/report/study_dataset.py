"""A study's table as one labelled xarray Dataset: :func:`open_study`.

A study keeps its rows in ``OUT/results.sqlite`` (``runs``: one row per point and replicate, its
parameters and metrics as JSON; written by :mod:`chiptwin.study.store`). Read here with the
standard library's ``sqlite3``, read-only, so a study still running (or one interrupted) can be
opened: the dataset holds the rows stored so far, the rest ``NaN``::

    dimensions   one per axis (named by its key, ``chip.adc.bits``; zipped axes, whose values move
                 together, share the first one's dimension, the others are coordinates along it),
                 and ``replicate``
    variables    each metric (a rate as ``<metric>_k`` successes of ``<metric>_n`` trials), the
                 row's ``status``, ``message``, ``seed`` (-1: no row), ``wall_s``; per point its
                 ``point`` id and ``kind`` (``point``, or ``reference`` for a reference point
                 off the grid)
    attributes   the study's name, its TOML text, hash, base scenario (JSON), chiptwin version

The axes are read from the rows' parameters (so a study made by another version still opens),
in the order the study file lists them. A calibration (``kind = "calibrate"``) has no grid: its
table is the ``evaluations`` one, read over ``evaluation`` × ``parameter``.
"""

from __future__ import annotations

import json
import math
import sqlite3
import tomllib
from contextlib import closing
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin.config import ScenarioError

if TYPE_CHECKING:
    import xarray as xr

#: The study's database in its output folder (:data:`chiptwin.study.store.DB_NAME`).
DB_FILE = "results.sqlite"
#: ``seed`` where a point has no row for a replicate.
NO_SEED = -1


def open_study(folder: str | Path) -> xr.Dataset:
    """A study's output folder (its ``results.sqlite``) as a Dataset over its axes and replicates.

    Raises
    ------
    ScenarioError
        When ``folder`` holds no study database, or one without a finished row.
    """
    path = _db_path(Path(folder))
    try:
        with closing(sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)) as con:
            meta = _one(con, "SELECT * FROM study")
            rows = _all(con, "SELECT * FROM runs") if _has(con, "runs") else []
            evals = (_all(con, "SELECT * FROM evaluations")
                     if not rows and _has(con, "evaluations") else [])
    except sqlite3.DatabaseError as exc:
        _refuse(folder, f"its {DB_FILE} cannot be read ({exc})")
    if meta is None or not (rows or evals):
        _refuse(folder, f"its {DB_FILE} holds no finished run yet: run the study (an "
                        "interrupted one resumes where it stopped)")
    attrs = _attrs(meta, path)
    study = _study_table(meta.get("text", ""))
    if rows:
        return grid_dataset(rows, attrs, [a.get("key") for a in study.get("axis", [])])
    return evaluations_dataset(evals, attrs, [p.get("key") for p in study.get("parameter", [])])


def _db_path(folder: Path) -> Path:
    if not folder.is_dir():
        _refuse(folder, "no such folder: give the --out folder of a `chiptwin study`")
    path = folder / DB_FILE
    if path.is_file():
        return path
    if (folder / "summary.json").is_file():
        _refuse(folder, "a run's folder, not a study's: read it with chiptwin.open_run")
    _refuse(folder, f"not a study's output folder (no {DB_FILE}): `chiptwin study STUDY --out "
                    "FOLDER` writes one")
    raise AssertionError  # unreachable


def _refuse(folder: str | Path, allowed: str) -> None:
    raise ScenarioError("chiptwin.open_study", "folder", str(folder), allowed)


def _has(con: sqlite3.Connection, table: str) -> bool:
    return con.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?",
                       (table,)).fetchone() is not None


def _all(con: sqlite3.Connection, sql: str) -> list[dict[str, Any]]:
    cur = con.execute(sql)
    names = [d[0] for d in cur.description]
    return [dict(zip(names, values, strict=True)) for values in cur]


def _one(con: sqlite3.Connection, sql: str) -> dict[str, Any] | None:
    rows = _all(con, sql)
    return rows[0] if rows else None


def _study_table(text: str) -> dict[str, Any]:
    """The study file's ``[study]`` table (for the axes' and parameters' order), or ``{}``."""
    try:
        return tomllib.loads(text).get("study", {})
    except tomllib.TOMLDecodeError:
        return {}


def _attrs(meta: dict[str, Any], path: Path) -> dict[str, Any]:
    names = {"name": "study", "text": "study_toml", "hash": "study_hash",
             "base_scenario": "base_scenario", "datasheet": "datasheet",
             "chiptwin_version": "chiptwin_version", "created": "created_unix_s"}
    attrs = {new: meta[old] for old, new in names.items() if meta.get(old) not in (None, "")}
    attrs["database"] = str(path)
    return attrs


def grid_dataset(rows: list[dict[str, Any]], attrs: dict[str, Any],
                 axis_order: list[str | None]) -> xr.Dataset:
    """The ``runs`` rows (as stored: ``params`` and ``metrics`` JSON) on the axes' grid."""
    import xarray as xr

    for row in rows:
        row["params"] = json.loads(row["params"])
        row["metrics"] = json.loads(row["metrics"]) if row["metrics"] else {}
    points = {row["point"]: row for row in rows}  # one row of each point: its parameters
    keys = [k for k in axis_order if k] + sorted({k for r in rows for k in r["params"]})
    keys = [k for k in dict.fromkeys(keys) if any(k in r["params"] for r in rows)]
    groups = _groups(keys, [p["params"] for p in points.values()])
    labels = [_labels(g[0], points.values()) for g in groups]
    shape = (*(len(lab) for lab in labels), max(r["replicate"] for r in rows) + 1)
    index = {pid: tuple(lab.index(_label(p["params"].get(g[0])))
                        for g, lab in zip(groups, labels, strict=True))
             for pid, p in points.items()}
    dims = (*(g[0] for g in groups), "replicate")
    data = _row_variables(rows, shape, index)
    ds = xr.Dataset({name: (dims if value.ndim == len(dims) else dims[:-1], value)
                     for name, value in data.items()}, attrs=attrs)
    coords: dict[str, Any] = {"replicate": np.arange(shape[-1])}
    for g, lab in zip(groups, labels, strict=True):
        coords[g[0]] = (g[0], _values(lab))
        for key in g[1:]:  # zipped with g[0]: its value at each of g[0]'s
            along = {_label(p["params"].get(g[0])): p["params"].get(key) for p in points.values()}
            coords[key] = (g[0], _values([_label(along[x]) for x in lab]))
    return ds.assign_coords(coords)


def _row_variables(rows: list[dict[str, Any]], shape: tuple[int, ...],
                   index: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    """Each metric and the rows' status, message, seed and wall time on the grid × replicate;
    each point's id and kind on the grid."""
    rates = {m for r in rows for m, v in r["metrics"].items() if isinstance(v, list)}
    names = dict.fromkeys(m for r in rows for m in r["metrics"])
    out: dict[str, np.ndarray] = {}
    for m in names:
        for name in ([f"{m}_k", f"{m}_n"] if m in rates else [m]):
            out[name] = np.full(shape, np.nan)
    out |= {"status": np.full(shape, "", dtype=object), "message": np.full(shape, "", object),
            "seed": np.full(shape, NO_SEED, np.int64), "wall_s": np.full(shape, np.nan),
            "point": np.full(shape[:-1], "", object), "kind": np.full(shape[:-1], "", object)}
    for r in rows:
        at = (*index[r["point"]], r["replicate"])
        for m, v in r["metrics"].items():
            if m in rates:
                k, n = v if isinstance(v, list) else (math.nan, math.nan)
                out[f"{m}_k"][at], out[f"{m}_n"][at] = _number(k), _number(n)
            else:
                out[m][at] = _number(v)
        out["status"][at], out["message"][at] = r["status"], r["message"]
        out["seed"][at], out["wall_s"][at] = r["seed"], r["wall_s"]
        out["point"][at[:-1]], out["kind"][at[:-1]] = r["point"], r["kind"]
    return out


def _number(v: Any) -> float:
    """A metric's value as a float: ``None`` (not measured) is ``NaN``."""
    if v is None:
        return math.nan
    return float(v)


def _label(v: Any) -> str:
    """A parameter value's identity (values may be lists, or absent: ``null``)."""
    return json.dumps(v, sort_keys=True)


def _groups(keys: list[str], params: list[dict[str, Any]]) -> list[list[str]]:
    """The axes' dimensions: keys whose values determine each other over the points (zipped
    axes) share one, the first key's."""
    groups: list[list[str]] = []
    for key in keys:
        home = next((g for g in groups if _one_to_one(g[0], key, params)), None)
        if home is None:
            groups.append([key])
        else:
            home.append(key)
    return groups


def _one_to_one(a: str, b: str, params: list[dict[str, Any]]) -> bool:
    pairs = {(_label(p.get(a)), _label(p.get(b))) for p in params}
    return len(pairs) == len({x for x, _ in pairs}) == len({y for _, y in pairs})


def _labels(key: str, points: Any) -> list[str]:
    """The values ``key`` takes, as labels: numbers in increasing order, others as met."""
    values = list(dict.fromkeys(_label(p["params"].get(key)) for p in points))
    parsed = [json.loads(v) for v in values]
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in parsed):
        return [v for _, v in sorted(zip(parsed, values, strict=True))]
    return values


def _values(labels: list[str]) -> np.ndarray:
    """Coordinate values from labels: numbers, booleans and strings as themselves, lists and
    absent values (``null``) as their JSON text."""
    parsed = [json.loads(v) for v in labels]
    if all(isinstance(v, bool | int | float | str) for v in parsed):
        return np.array(parsed)
    return np.array([v if isinstance(v, str) else json.dumps(v) for v in parsed], dtype=object)


def evaluations_dataset(evals: list[dict[str, Any]], attrs: dict[str, Any],
                        parameters: list[str | None]) -> xr.Dataset:
    """A calibration's ``evaluations`` rows over ``evaluation`` (in the order stored) and
    ``parameter`` (the fitted keys, as the study file lists them)."""
    import xarray as xr

    candidates = [json.loads(e["candidate"]) for e in evals]
    width = max(len(c) for c in candidates)
    values = np.full((len(evals), width), np.nan)
    for i, c in enumerate(candidates):
        values[i, :len(c)] = c
    names = [p for p in parameters if p]
    ds = xr.Dataset({
        "candidate": (("evaluation", "parameter"), values),
        "objective": ("evaluation", np.array([_number(e.get("objective")) for e in evals])),
        "status": ("evaluation", np.array([e["status"] for e in evals], dtype=object)),
        "message": ("evaluation", np.array([e["message"] for e in evals], dtype=object)),
        "wall_s": ("evaluation", np.array([e["wall_s"] for e in evals], dtype=float)),
    }, attrs=attrs)
    if len(names) == width:
        ds = ds.assign_coords(parameter=names)
    return ds
