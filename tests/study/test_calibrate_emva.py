"""An EMVA 1288 data set as a calibration's target: a twin-made set gives back the values it was
made with, and the real set 001 is compared as calibrate_emva says (the standard's K and R over
the standard's range, the dark pairs at every point with one offset for their means, the
variance at saturation), the twin through the very same statistics.

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
from chiptwin.study.calibrate_emva import (
    BLOCKS,
    comparison,
    emva_measured,
    statistics,
    used_points,
)
from tests.conftest import real_data

CAMERA = Path(__file__).resolve().parents[2] / "scenarios" / "measured_camera_set001.toml"
#: The development camera's values the twin-made set is made with.
TRUE = {"chip.pixel.capacitance_fF": 2.336096, "chip.pixel.read_noise_e": 7.667307}

FIT = """
[study]
name = "cal_emva"
kind = "calibrate"
scenario = "{scenario}"
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


def _write(folder: Path, text: str) -> Path:
    path = folder / "study.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _n_compared(t) -> int:
    """K and R, the dark mean and variance at every point, the variance at saturation."""
    return 2 + 2 * t.t_exp_s.size + 1


@pytest.mark.slow
def test_a_twin_made_data_set_gives_back_its_gain_and_read_noise(tmp_path):
    data = twin_data_set(tmp_path)
    study = load_study(_write(tmp_path, FIT.format(scenario="camera.toml", path=data.name)))
    m = study.calibration.target.measurement
    assert emva_measured(m).n == _n_compared(m.temporal)
    s = run_study(study, workers=1).summary
    for p in s["parameters"]:
        lo, hi = p["interval"]
        assert lo < TRUE[p["key"]] < hi and not any(p["open"]), p
    assert [b["name"] for b in s["objective"]["blocks"]] == list(BLOCKS)
    assert "offset" in s["objective"] and s["objective"]["nuisance"] == 1


def _real_study(tmp_path: Path, keys: str = "", max_pixels: int | None = None):
    """The real set 001 as the target of a fit of the full camera (128 × 128)."""
    data = real_data("emva1288", "set001_ccd_12bit_crop128")
    text = FIT.format(scenario=CAMERA.as_posix(), path=data.as_posix())
    if max_pixels is not None:
        text += f"max_pixels = {max_pixels}\n"
    return load_study(_write(tmp_path, text + keys))


def test_the_real_set_is_compared_through_the_standards_own_statistics(tmp_path):
    from chiptwin.characterize import evaluate

    m = _real_study(tmp_path).calibration.target.measurement
    t = m.temporal
    c = comparison(t)
    assert (c.top, c.saturation, c.n) == (26, 37, 50)  # 70 % of saturation; the 38th point
    assert used_points(t).sum() == 26
    measured = emva_measured(m)
    assert measured.n == _n_compared(t) == 103
    by = {name: measured.values[measured.block == b] for b, name in enumerate(BLOCKS)}
    # K and R are the closed form's, to the last digit (the datasheet's 0.28092 DN/e⁻, η 45.0 %)
    i = evaluate.saturation_index(t)
    assert by["gain K"][0] == pytest.approx(evaluate.system_gain(t, i)[0], rel=1e-12)
    assert by["responsivity R"][0] == pytest.approx(evaluate.responsivity(t, i)[0], rel=1e-12)
    assert by["responsivity R"][0] / by["gain K"][0] == pytest.approx(0.44998, abs=1e-5)
    assert by["var at saturation"][0] == t.column("bright", "var")[37]
    # only the dark means take the offset (the camera's black level against the twin's)
    assert np.array_equal(measured.offset, measured.block == BLOCKS.index("dark mean"))
    assert np.all(measured.se > 0)


def test_a_chi2_over_the_cameras_points_is_not_the_standards_gain(tmp_path):
    """Why K and R are compared, not the bright pairs point by point: the camera's photon
    transfer is no straight line through the origin (σ²/μ from ≈ +3 % at its dimmest points to
    −1 % at 70 % of saturation), so a χ²-weighted slope over the same points differs from the
    standard's least-squares one by several of its standard errors."""
    t = _real_study(tmp_path).calibration.target.measurement.temporal
    c = comparison(t)
    sl = slice(0, c.top)
    x = (t.column("bright", "mean") - t.column("dark", "mean"))[sl]
    y = (t.column("bright", "var") - t.column("dark", "var"))[sl]
    var = (t.column("bright", "var_se") ** 2 + t.column("dark", "var_se") ** 2)[sl]
    (gain, *_), (gain_se, *_) = statistics(t, c)
    weighted = np.sum(x * y / var) / np.sum(x * x / var)
    assert weighted / gain - 1 > 0.008 and (weighted - gain) / gain_se > 3


def test_the_full_well_is_seen_only_below_the_converters_top_code(tmp_path):
    """At the closed form's gain the mean pixel reaches the ADC's top code (4095) at ≈ 14,520
    e⁻: a full well above that changes no statistic (the fit's interval is open at the top); one
    below it clips the variance at saturation and nothing the standard's range reads."""
    from chiptwin.study.calibrate_eval import model_of, simulate

    keys = """
[[study.parameter]]
key = "chip.pixel.full_well_e"
range = [2000.0, 200000.0]
why = "a full well"
"""
    study = _real_study(tmp_path, keys, max_pixels=1024)
    model = model_of(study)

    def sim(full_well: float) -> np.ndarray:
        return simulate(model, {"chip.pixel.capacitance_fF": 2.336096,
                                "chip.pixel.read_noise_e": 7.667307,
                                "chip.pixel.full_well_e": full_well})[0]

    closed_form, far, low = sim(14709.93), sim(60000.0), sim(14300.0)
    assert np.array_equal(closed_form, far)
    sat = BLOCKS.index("var at saturation")
    measured = emva_measured(study.calibration.target.measurement)
    block = measured.block
    assert low[block == sat][0] < 0.5 * closed_form[block == sat][0]
    assert np.array_equal(low[block != sat], closed_form[block != sat])
