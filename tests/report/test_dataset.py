"""A run's arrays as one labelled Dataset (``run.nc``, :mod:`chiptwin.report.dataset`): written and
read back value for value, frames included; its dimensions, coordinates, units and scenario; the
scenario's TOML text loads back to the same scenario; ``open_run`` on folders that are not a
run's."""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace

import numpy as np
import pytest

import chiptwin as ct
from chiptwin.chip import Schedule
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.config.load import scenario_from_dict
from chiptwin.fidelity import run
from chiptwin.report import open_run
from chiptwin.report.dataset import DATASET_FILE, VARIABLES, run_dataset, write_dataset
from chiptwin.report.scenario_toml import scenario_toml
from tests.conftest import SCENARIOS


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The small scene run with its frames kept, and its output folder."""
    from tests.conftest import SMALL

    folder = tmp_path_factory.mktemp("dataset")
    (folder / "small.toml").write_text(SMALL)
    result = run(folder / "small.toml", ["run.save_frames=true"])
    arrays = {**result.arrays, **result.trace.to_arrays(), "frames": np.load(result.frames_path)}
    (folder / "out").mkdir()
    write_dataset(result, folder / "out" / DATASET_FILE, result.frames_path)
    return result, arrays, folder / "out"


def test_round_trip_value_for_value(written):
    """Every array of the run, the trace and the frames: the same values, dtypes and shapes
    (strings as strings, booleans as booleans); the read offsets as CF's count per site."""
    result, arrays, out = written
    with open_run(out) as ds:
        for name, want in arrays.items():
            if name == "read_quality_offsets":
                got = np.concatenate([[0], np.cumsum(ds["read_bases"].values)])
            elif name == "trace_frame_steps":
                got = np.array(bool(ds.attrs["trace_frame_steps"]))
            elif name == "frames":
                got = ds["frames"].values.reshape(want.shape)
            else:
                got = ds[name].values
            assert got.shape == want.shape, name
            if want.dtype.kind == "U":
                assert got.tolist() == want.tolist(), name
            else:
                assert got.dtype == want.dtype and np.array_equal(got, want, equal_nan=True), name


def test_dimensions_coordinates_and_units(written):
    """Named dimensions; times, positions and nucleotides as coordinates; a unit and a meaning
    on every variable the table names."""
    result, arrays, out = written
    s = result.scenario
    with open_run(out) as ds:
        assert ds["site_signal_e"].dims == ("site", "block")
        assert ds["site_photons"].dims == ("site", "frame")
        assert ds["flow_values"].dims == ("site", "flow")
        assert ds["frames"].dims == ("frame", "sample", "row", "col")
        assert ds["sample_kind"].values.tolist() == ["reset"] * 2 + ["signal"] * 2
        assert ds["peak_frame_e"].dims == ("row", "col") and ds["trace_block"].dims == ("trace",)
        assert ds["site_x_um"].values.tolist() == [(c + 0.5) * s.chip.pitch_um for c in (1, 4)]
        assert ds["site_y_um"].values.tolist() == [(r + 0.5) * s.chip.pitch_um for r in (1, 2)]
        assert ds["flow_nucleotide"].values.tolist() == [
            f["nucleotide"] for f in result.summary["flows"]]
        sch = Schedule.from_chip(s.chip, s.run.duration_s)
        mids = [sum(sch.window_s(k)) / 2 for k in range(sch.n_frames)]
        assert np.allclose(ds["frame_t_s"].values, mids, rtol=0, atol=1e-9)
        assert ds["block_t_s"].dims == ("block",) and ds["trace_t_ns"].attrs["units"] == "ns"
        for name in VARIABLES:
            if name in ds and name not in ("trace_block", "trace_event", "trace_value"):
                assert ds[name].attrs["units"] and ds[name].attrs["long_name"], name
        assert ds["site_signal_e"].attrs["units"] == "e-"


def test_the_scenario_and_seed_in_the_attributes(written):
    """The attributes say what made the run: the TOML text loads back to the same scenario."""
    result, _, out = written
    with open_run(out) as ds:
        assert ds.attrs["seed"] == 7 and ds.attrs["scenario"] == "small"
        assert ds.attrs["chiptwin_version"] == ct.__version__
        again = scenario_from_dict(tomllib.loads(ds.attrs["scenario_toml"]),
                                   result.scenario.source)
        assert again == result.scenario
        assert json.loads(ds.attrs["fidelity"]) == result.summary["fidelity"]


@pytest.mark.parametrize("name", sorted(p.stem for p in SCENARIOS.glob("*.toml")))
def test_scenario_toml_loads_back_to_the_scenario(name, tmp_path):
    """Every bundled scenario written as TOML and loaded again: the same scenario (a drawn
    template, inline tables of layers, the assay kind's keys only)."""
    s = load_scenario(SCENARIOS / f"{name}.toml", seed=3)
    path = tmp_path / "again.toml"
    path.write_text(scenario_toml(s))
    assert replace(load_scenario(path), source=s.source) == s


def test_an_array_the_table_does_not_name_is_kept(written, tmp_path):
    """A stage's new array still goes in, on dimensions of its own, saying it is unlabelled."""
    result, _, _ = written
    extra = replace(result, arrays={**result.arrays, "new_thing": np.arange(6.0).reshape(2, 3)},
                    frames_path=None)
    ds = run_dataset(extra)
    assert ds["new_thing"].dims == ("new_thing_dim0", "new_thing_dim1")
    assert "not labelled" in ds["new_thing"].attrs["long_name"]
    write_dataset(extra, tmp_path / DATASET_FILE)


def test_open_run_says_what_a_folder_is(written, tmp_path):
    """Not a folder, an empty one, a run written before the dataset, a study's, a damaged or a
    newer dataset: one line naming the folder and what to do."""
    cases = {"missing": "no such folder", "empty": "not a run's output folder",
             "old": "before runs wrote run.nc", "study": "chiptwin.open_study",
             "damaged": "cannot be read", "newer": "upgrade chiptwin"}
    for case in cases:
        (tmp_path / case).mkdir(parents=True, exist_ok=case != "missing")
    (tmp_path / "missing").rmdir()
    (tmp_path / "old" / "summary.json").write_text(json.dumps({"chiptwin_version": "0.0.9",
                                                              "seed": 4}))
    (tmp_path / "study" / "results.sqlite").write_bytes(b"")
    (tmp_path / "damaged" / DATASET_FILE).write_bytes(b"not a netcdf file")
    result, _, _ = written
    ds = run_dataset(replace(result, frames_path=None))
    ds.attrs["chiptwin_dataset_version"] = 99
    ds.to_netcdf(tmp_path / "newer" / DATASET_FILE, engine="h5netcdf")
    for case, says in cases.items():
        with pytest.raises(ScenarioError, match=says) as err:
            open_run(tmp_path / case)
        assert "\n" not in str(err.value) and str(tmp_path / case) in str(err.value)
    with pytest.raises(ScenarioError, match="seed 4"):
        open_run(tmp_path / "old")


def test_the_public_api_reads_runs_and_studies():
    from chiptwin.report.study_dataset import open_study

    assert ct.open_run is open_run and ct.open_study is open_study
    assert {"open_run", "open_study"} <= set(ct.__all__)
