"""An EMVA 1288 data set as a calibration's target: a twin-made set gives back the values it was
made with, and the real set 001 is compared as calibrate_emva says (bright pairs below
saturation, dark pairs at every point, one offset for the means, the misfit's Birge ratios).

The twin-made set is the bench's own protocol on a 16 × 16 chip
(:func:`chiptwin.characterize.export.write_measured`, single frames), drawn from the scenario's
seed; the fit reads the twin through it with the study seed's common random numbers and
another chip (its fixed pattern from the study seed): the two share no draw.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from chiptwin.study import load_study, run_study
from chiptwin.study.calibrate_emva import BLOCKS, emva_measured, used_points
from tests.conftest import real_data

CAMERA = Path(__file__).resolve().parents[2] / "scenarios" / "measured_camera_set001.toml"
#: The development camera's values the twin-made set is made with.
TRUE = {"chip.pixel.capacitance_fF": 2.336096, "chip.pixel.read_noise_e": 7.667307}

FIT = """
[study]
name = "cal_emva"
kind = "calibrate"
scenario = "camera.toml"
seed = 21
optimiser = {{ popsize = 4, generations = 4 }}

[[study.parameter]]
key = "chip.pixel.capacitance_fF"
range = [0.5, 20.0]
why = "12-bit machine-vision gains, 0.03-1.3 DN/e-"

[[study.parameter]]
key = "chip.pixel.read_noise_e"
range = [1.0, 40.0]
why = "a CCD's read noise per sample"

[study.target]
kind = "emva1288"
path = "{path}"
"""


def small_camera(folder: Path, seed: int = 5) -> Path:
    """The development camera on a 16 × 16 chip (its pixels' values unchanged)."""
    text = CAMERA.read_text(encoding="utf-8").replace("rows = 128", "rows = 16").replace(
        "cols = 128", "cols = 16").replace("seed = 1", f"seed = {seed}")
    assert tomllib.loads(text)["chip"]["rows"] == 16
    path = folder / "camera.toml"
    path.write_text(text, encoding="utf-8")
    return path


def twin_data_set(folder: Path) -> Path:
    """The twin's EMVA 1288 protocol on the small camera, written as a data set."""
    from chiptwin.characterize.export import single_frame_protocol, write_measured
    from chiptwin.characterize.measure import measure
    from chiptwin.config import load_scenario

    s = load_scenario(small_camera(folder))
    m = measure(s, single_frame_protocol(), keep_images=True)
    return write_measured(m, folder / "twin_set", "small camera")


@pytest.mark.slow
def test_a_twin_made_data_set_gives_back_its_gain_and_read_noise(tmp_path):
    data = twin_data_set(tmp_path)
    study = load_study(_write(tmp_path, FIT.format(path=data.name)))
    m = study.calibration.target.measurement
    measured = emva_measured(m)
    assert measured.n == 2 * int(used_points(m.temporal).sum()) + 2 * m.temporal.t_exp_s.size
    s = run_study(study, workers=1).summary
    for p in s["parameters"]:
        lo, hi = p["interval"]
        assert lo < TRUE[p["key"]] < hi and not any(p["open"]), p
    assert [b["name"] for b in s["objective"]["blocks"]] == list(BLOCKS)
    assert "offset" in s["objective"] and s["objective"]["nuisance"] == 1


def _write(folder: Path, text: str) -> Path:
    path = folder / "study.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_real_set_is_compared_below_saturation_with_its_dark_pairs_throughout(tmp_path):
    data = real_data("emva1288", "set001_ccd_12bit_crop128")
    small_camera(tmp_path)
    study = load_study(_write(tmp_path, FIT.format(path=data.as_posix())))
    t = study.calibration.target.measurement.temporal
    used = used_points(t)
    var = t.column("bright", "var")
    assert used.sum() == 37 and not used[int(np.argmax(var)):].any()  # saturation: 38 of 50
    measured = emva_measured(study.calibration.target.measurement)
    assert measured.n == study.calibration.target.n_points == 2 * 37 + 2 * 50
    assert measured.offset.sum() == 37 + 50  # the means share the black level's offset
    assert np.all(measured.se > 0)
