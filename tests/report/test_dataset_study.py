"""A study's table as a Dataset over its axes and replicates (:func:`chiptwin.open_study`): rows
stored by the study's own store (:class:`chiptwin.study.store.Store`) read back onto the grid,
zipped axes on one dimension, missing rows as NaN, rates as k of n, a reference point off the
grid, a calibration's evaluations; folders that are not a study's."""

from __future__ import annotations

import json
import sqlite3
from types import SimpleNamespace

import numpy as np
import pytest

from chiptwin.config import ScenarioError
from chiptwin.report import open_study
from chiptwin.study.store import DB_NAME, Store

STUDY_TOML = """
[study]
name = "grid"
scenario = "pyro_1fmol"
replicates = 2

[[study.axis]]
key = "chip.adc.bits"
values = [13, 10, 12]

[[study.axis]]
key = "chip.memory.capacity_bits"
values = [65536, 131072]
zip = true

[[study.axis]]
key = "chip.memory.word_bits"
values = [8, 16]
zip = true
"""


def _study(text: str = STUDY_TOML, name: str = "grid") -> SimpleNamespace:
    """What the store reads of a study: its name, text, hash, base scenario, datasheet."""
    return SimpleNamespace(name=name, text=text, hash="h-" + name, base_raw={"run": {}},
                           datasheet_text="", source="grid.toml")


def _row(bits: int, memory: int, word: int, replicate: int, **kw) -> dict:
    params = {"chip.adc.bits": bits, "chip.memory.capacity_bits": memory,
              "chip.memory.word_bits": word}
    metrics = kw.pop("metrics", {"snr_power": 10.0 * bits + replicate,
                                 "calls_correct": [bits - 9, 4]})
    return {"point": f"p{bits}-{word}", "kind": kw.pop("kind", "point"),
            "replicate": replicate, "seed": 100 * bits + replicate, "params": params,
            "metrics": metrics, "status": kw.pop("status", "ok"), "message": "", "wall_s": 0.5}


@pytest.fixture
def grid(tmp_path):
    """Bits 10, 12, 13 × two zipped memory settings × 2 replicates, one row missing, one
    invalid, and a reference point at 16 bits."""
    rows = [_row(b, m, w, r) for b in (10, 12, 13) for m, w in ((65536, 8), (131072, 16))
            for r in (0, 1) if (b, w, r) != (12, 16, 1)]
    rows[0] = _row(10, 65536, 8, 0, status="invalid", metrics=None)
    rows.append(_row(16, 131072, 16, 0, kind="reference"))
    store = Store(tmp_path / DB_NAME, _study())
    store.add(rows)
    store.close()
    return tmp_path


def test_rows_on_the_axes_and_replicates(grid):
    ds = open_study(grid)
    assert ds["snr_power"].dims == ("chip.adc.bits", "chip.memory.capacity_bits", "replicate")
    assert ds["chip.adc.bits"].values.tolist() == [10, 12, 13, 16]  # numbers in order
    # zipped: the word size is a coordinate along the capacity's dimension
    assert ds["chip.memory.word_bits"].dims == ("chip.memory.capacity_bits",)
    assert ds["chip.memory.word_bits"].values.tolist() == [8, 16]
    at = ds.sel({"chip.adc.bits": 13, "chip.memory.capacity_bits": 131072})
    assert at["snr_power"].values.tolist() == [130.0, 131.0]
    assert at["calls_correct_k"].values.tolist() == [4, 4]
    assert at["calls_correct_n"].values.tolist() == [4, 4]
    assert at["seed"].values.tolist() == [1300, 1301] and at["point"].item() == "p13-16"
    assert ds.attrs["study"] == "grid" and "[[study.axis]]" in ds.attrs["study_toml"]


def test_missing_invalid_and_reference_rows(grid):
    ds = open_study(grid)
    missing = ds.sel({"chip.adc.bits": 12, "chip.memory.capacity_bits": 131072, "replicate": 1})
    assert np.isnan(missing["snr_power"].item()) and missing["status"].item() == ""
    assert missing["seed"].item() == -1
    invalid = ds.sel({"chip.adc.bits": 10, "chip.memory.capacity_bits": 65536, "replicate": 0})
    assert invalid["status"].item() == "invalid" and np.isnan(invalid["snr_power"].item())
    ref = ds.sel({"chip.adc.bits": 16, "chip.memory.capacity_bits": 131072})
    assert ref["kind"].item() == "reference" and ref["snr_power"].values[0] == 160.0
    assert ds.sel({"chip.adc.bits": 16, "chip.memory.capacity_bits": 65536})["kind"].item() == ""


def test_a_calibration_reads_its_evaluations(tmp_path):
    text = ('[study]\nname = "fit"\nkind = "calibrate"\n[[study.parameter]]\nkey = "a.b"\n'
            '[[study.parameter]]\nkey = "c.d"\n')
    store = Store(tmp_path / DB_NAME, _study(text, "fit"))
    store.add_evaluations("t", [
        {"values": [1.0, 2.0], "status": "ok", "objective": 3.5, "residuals": [0.1],
         "sim": [1.0], "sim_se": [0.1], "message": "", "wall_s": 0.2},
        {"values": [1.5, 2.5], "status": "error", "objective": None, "residuals": None,
         "sim": None, "sim_se": None, "message": "failed", "wall_s": 0.1}])
    store.close()
    ds = open_study(tmp_path)
    assert ds["candidate"].dims == ("evaluation", "parameter")
    assert ds["parameter"].values.tolist() == ["a.b", "c.d"]
    assert ds["candidate"].values.tolist() == [[1.0, 2.0], [1.5, 2.5]]
    assert ds["objective"].values[0] == 3.5 and np.isnan(ds["objective"].values[1])
    assert ds["status"].values.tolist() == ["ok", "error"]


def test_open_study_says_what_a_folder_is(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "summary.json").write_text("{}")
    (tmp_path / "empty").mkdir()
    (tmp_path / "fresh").mkdir()
    Store(tmp_path / "fresh" / DB_NAME, _study()).close()
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / DB_NAME).write_bytes(b"not a database at all, not even close" * 40)
    cases = {"nowhere": "no such folder", "run": "chiptwin.open_run",
             "empty": "not a study's output folder", "fresh": "no finished run yet",
             "junk": "cannot be read"}
    for case, says in cases.items():
        with pytest.raises(ScenarioError, match=says) as err:
            open_study(tmp_path / case)
        assert "\n" not in str(err.value)


def test_reading_changes_nothing(grid):
    """Read-only: the database's bytes and its rows are the same after reading."""
    before = (grid / DB_NAME).read_bytes()
    open_study(grid)
    assert (grid / DB_NAME).read_bytes() == before
    with sqlite3.connect(grid / DB_NAME) as con:
        params = [json.loads(p) for (p,) in con.execute("SELECT params FROM runs")]
    assert len(params) == 12
