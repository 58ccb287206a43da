"""The study's database: ``OUT/results.sqlite`` (stdlib sqlite3, WAL, one transaction per task).

Tables:

- ``study``: one row: the study file's text, its hash (with the resolved base scenario and its
  datasheet), the resolved base scenario as JSON, the text of the EMVA 1288 datasheet it is
  configured from (or ""), the chiptwin version, and the time it was created.
- ``runs``: one row per finished run: ``point`` (the point's hash), ``kind`` (``point`` or
  ``reference``), ``replicate``, ``seed``, ``params`` JSON, ``metrics`` JSON, ``status``
  (``ok``/``invalid``/``error``), ``message``, ``wall_s``. ``(point, replicate)`` is the key.
- ``evaluations`` (a calibration): one row per candidate simulated: ``target`` (the measured
  data's hash), ``candidate`` (the fitted keys' exact values, JSON), ``status``, ``objective``
  (χ² of the unscaled residuals, NULL when not ok), ``residuals``, ``sim``, ``sim_se`` (JSON
  lists), ``message``, ``wall_s``. ``(target, candidate)`` is the key: the optimiser is
  deterministic (its own seed, common random numbers), so a rerun asks for the same candidates
  and takes each stored one instead of simulating it.
- ``target`` (a calibration): one row: the measured data's path and hash.

The rows of one executor task (a few seconds of rows) are committed together as soon as the task
arrives, in one transaction: a killed study (Ctrl-C, ``kill -9``) keeps every finished task's rows
whole and none of a task in flight; re-running the same command skips every stored row. A study
whose parsed ``[study]`` table, overrides or base scenario changed is refused for resumption,
naming what changed (comments and layout of the file are not part of its identity).
"""

from __future__ import annotations

import json
import sqlite3
import time
from pathlib import Path
from typing import Any

from chiptwin import __version__
from chiptwin.config import ScenarioError
from chiptwin.study.readers import identity_table

DB_NAME = "results.sqlite"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS study (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    name TEXT NOT NULL, text TEXT NOT NULL, hash TEXT NOT NULL,
    base_scenario TEXT NOT NULL, datasheet TEXT NOT NULL, chiptwin_version TEXT NOT NULL,
    created REAL NOT NULL);
CREATE TABLE IF NOT EXISTS runs (
    point TEXT NOT NULL, kind TEXT NOT NULL, replicate INTEGER NOT NULL, seed INTEGER NOT NULL,
    params TEXT NOT NULL, metrics TEXT, status TEXT NOT NULL
        CHECK (status IN ('ok', 'invalid', 'error')),
    message TEXT NOT NULL, wall_s REAL NOT NULL,
    PRIMARY KEY (point, replicate));
CREATE TABLE IF NOT EXISTS evaluations (
    target TEXT NOT NULL, candidate TEXT NOT NULL, status TEXT NOT NULL
        CHECK (status IN ('ok', 'invalid', 'error')),
    objective REAL, residuals TEXT, sim TEXT, sim_se TEXT, message TEXT NOT NULL,
    wall_s REAL NOT NULL,
    PRIMARY KEY (target, candidate));
CREATE TABLE IF NOT EXISTS target (
    id INTEGER PRIMARY KEY CHECK (id = 1), path TEXT NOT NULL, hash TEXT NOT NULL);
"""


class Store:
    """The runs of one study, in SQLite (``":memory:"`` for a study without an output folder)."""

    def __init__(self, path: str | Path, study: Any, fresh: bool = False) -> None:
        self.path = str(path)
        if fresh and self.path != ":memory:":
            for suffix in ("", "-wal", "-shm"):
                Path(self.path + suffix).unlink(missing_ok=True)
        self.db = sqlite3.connect(self.path, isolation_level=None)  # explicit transactions
        if self.path != ":memory:":
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA synchronous=NORMAL")  # WAL: durable at checkpoints, atomic
        self.db.executescript(_SCHEMA)
        self._claim(study)

    def _claim(self, study: Any) -> None:
        row = self.db.execute("SELECT text, hash, base_scenario, datasheet, chiptwin_version "
                              "FROM study").fetchone()
        base = json.dumps(study.base_raw, sort_keys=True)
        target = getattr(getattr(study, "calibration", None), "target", None)
        if row is None:
            self.db.execute("INSERT INTO study VALUES (1, ?, ?, ?, ?, ?, ?, ?)",
                            (study.name, study.text, study.hash, base, study.datasheet_text,
                             __version__, time.time()))
            if target is not None:
                self.db.execute("INSERT INTO target VALUES (1, ?, ?)", (target.path, target.hash))
            return
        if row[1] != study.hash:
            change = describe_change(row[0], row[2], study.text, base)
            if row[3] != study.datasheet_text:
                change = "the scenario's EMVA 1288 datasheet (chip.pixel.from_datasheet)"
            stored = self.db.execute("SELECT path, hash FROM target").fetchone()
            if target is not None and stored is not None and stored[1] != target.hash:
                change = (f"the measured data of study.target ({target.path}: its files "
                          f"changed, hash {stored[1]} → {target.hash})")
            raise ScenarioError(study.source, "(resume)", self.path,
                                "this folder holds another version of the study: " + change
                                + "; use --fresh to start over, or another --out")
        if row[4] != __version__:  # another model's rows would be mixed into one table
            raise ScenarioError(study.source, "(resume)", self.path,
                                f"its rows were made by chiptwin {row[4]}, this is "
                                f"{__version__}: resuming would mix two models' rows in one "
                                "table; use --fresh to start over, or another --out")

    def done(self) -> set[tuple[str, int]]:
        """``(point, replicate)`` of every stored row."""
        return set(self.db.execute("SELECT point, replicate FROM runs"))

    def add(self, rows: list[dict[str, Any]]) -> None:
        """Store finished rows (one task's) in one transaction: all of them or, if any is
        refused, none."""
        values = [(row["point"], row["kind"], row["replicate"], row["seed"],
                   json.dumps(row["params"], sort_keys=True),
                   None if row["metrics"] is None else json.dumps(row["metrics"], sort_keys=True),
                   row["status"], row["message"], row["wall_s"]) for row in rows]
        self.db.execute("BEGIN")
        try:
            self.db.executemany("INSERT OR IGNORE INTO runs VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                values)
        except BaseException:
            self.db.execute("ROLLBACK")
            raise
        self.db.execute("COMMIT")

    def rows(self) -> list[dict[str, Any]]:
        """Every stored row, ordered by point and replicate."""
        cur = self.db.execute("SELECT point, kind, replicate, seed, params, metrics, status, "
                              "message, wall_s FROM runs ORDER BY point, replicate")
        names = [d[0] for d in cur.description]
        out = []
        for values in cur:
            row = dict(zip(names, values, strict=True))
            row["params"] = json.loads(row["params"])
            row["metrics"] = None if row["metrics"] is None else json.loads(row["metrics"])
            out.append(row)
        return out

    def add_evaluations(self, target: str, records: list[dict[str, Any]]) -> None:
        """Store evaluated candidates (one task's) in one transaction."""
        def js(v: Any) -> str | None:
            return None if v is None else json.dumps(v)

        values = [(target, candidate_key(r["values"]), r["status"], r.get("objective"),
                   js(r.get("residuals")), js(r["sim"]), js(r["sim_se"]), r["message"],
                   r["wall_s"]) for r in records]
        self.db.execute("BEGIN")
        try:
            self.db.executemany("INSERT OR IGNORE INTO evaluations VALUES "
                                "(?, ?, ?, ?, ?, ?, ?, ?, ?)", values)
        except BaseException:
            self.db.execute("ROLLBACK")
            raise
        self.db.execute("COMMIT")

    def evaluations(self, target: str) -> dict[str, dict[str, Any]]:
        """Every stored evaluation of ``target``, by :func:`candidate_key`."""
        cur = self.db.execute("SELECT candidate, status, objective, residuals, sim, sim_se, "
                              "message, wall_s FROM evaluations WHERE target = ?", (target,))
        out = {}
        for key, status, objective, res, sim, sim_se, message, wall_s in cur:
            out[key] = {"values": json.loads(key), "status": status, "objective": objective,
                        "residuals": None if res is None else json.loads(res),
                        "sim": None if sim is None else json.loads(sim),
                        "sim_se": None if sim_se is None else json.loads(sim_se),
                        "message": message, "wall_s": wall_s}
        return out

    def close(self) -> None:
        self.db.close()


def candidate_key(values: list | tuple) -> str:
    """A candidate's identity: its values, exactly (JSON keeps a float's 17 digits)."""
    return json.dumps([v if isinstance(v, int) and not isinstance(v, bool) else float(v)
                       for v in values])


def describe_change(old_text: str, old_base: str, new_text: str, new_base: str) -> str:
    """What differs between the stored study and this one, in a few words."""
    import tomllib

    def flat(d: Any, prefix: str = "") -> dict[str, Any]:
        if isinstance(d, dict):
            out: dict[str, Any] = {}
            for k, v in d.items():
                out.update(flat(v, f"{prefix}{k}."))
            return out
        return {prefix.rstrip("."): d}

    def table(text: str) -> dict[str, Any]:  # what the identity reads of the text
        raw = tomllib.loads(text)
        return identity_table(raw.get("study", {})) if isinstance(raw, dict) else {}

    changes = []
    try:
        a, b = flat(table(old_text)), flat(table(new_text))
        changes += [f"study {k}: {a.get(k)!r} → {b.get(k)!r}" for k in sorted(a.keys() | b.keys())
                    if a.get(k) != b.get(k)]
    except tomllib.TOMLDecodeError:
        changes.append("the study's parsed [study] table")
    a, b = flat(json.loads(old_base)), flat(json.loads(new_base))
    changes += [f"scenario {k}: {a.get(k)!r} → {b.get(k)!r}" for k in sorted(a.keys() | b.keys())
                if a.get(k) != b.get(k)]
    shown = "; ".join(changes[:4]) + (f"; and {len(changes) - 4} more" if len(changes) > 4 else "")
    return shown or IDENTITY_CHANGED


#: What changed when the stored study and this one differ in identity but not in any key of their
#: text or base scenario: the identity is the parsed ``[study]`` table (without where its files
#: are) with its overrides, not the text, so comments or layout never change it; a folder made by
#: a chiptwin that identified a study otherwise (by its text) is the usual cause.
IDENTITY_CHANGED = ("the study's identity: its parsed [study] table or its overrides (or the "
                    "folder was made by a chiptwin that identified a study by another rule)")
