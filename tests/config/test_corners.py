"""Every valid scene runs at the edges of its ranges: the corners of the keys a design study
varies.

Each key a study moves (the site's radius and height, the diode, the pitch (the sites sit on
the pixel centres: their pitch is the chip's), the converter's bits, the averaging, the frame
period, the top surface, its medium and its lid, the equalizer, every ``[chip.cost]`` key) is
set to both ends of its declared range, alone and in a representative set of pairs, on a small,
fast scene (a 4 × 6 chip, 8 flows of 10 s, the stack and glass lid of ``pyro_1fmol``). Each
corner either runs to a summary whose figures are finite, or is refused by validation with a
:class:`ScenarioError` naming a key set (the CLI's exit 2); an internal error (any other
exception, the CLI's exit 1) is the bug this test exists to catch. The ends are read from the
schema itself, so a range that moves moves its corners.

The corner that started it: ``sites.footprint_radius_um = 1e-300`` validated, then the stack
psf quadrature never converged (a disc that small only resolves rounding); the optics now take
the point-source law below ``√rtol × height`` (:func:`chiptwin.optics.psf.point_below`).
"""

from __future__ import annotations

import functools
import math
import tomllib
from dataclasses import fields, replace
from itertools import product
from pathlib import Path

import pytest

from chiptwin.chip import Schedule
from chiptwin.cli import main
from chiptwin.config import Scenario, ScenarioError, load_scenario, scenario_from_dict
from chiptwin.config.schema_cost import Cost
from chiptwin.twin import chip_cost
from chiptwin.twin.runner import run

SCENE = """
[scenario]
name = "corners"
seed = 7

[assay]
kind = "pyrosequencing"
template = "TCAGGTTCCA"
n_flows = 8
flow_period_s = 10.0
start_s = 4.0
k_a_per_s = 0.5
photons_per_incorporation = 0.01

[sites]
at_pixels = [[1, 1], [2, 4]]
footprint_radius_um = 20.0
height_um = 15.0

[optics]
emitter = "isotropic"
layers = [
    { name = "assay buffer", n = 1.33 },
    { name = "SiO2", n = 1.46, thickness_um = 14.0 },
]

[optics.top]
medium = "glass"
solution_depth_um = 100.0
lid_thickness_um = 1000.0
lid_n = 1.5

[chip]
rows = 4
cols = 6

[chip.dsp]
n_dark_frames = 4
cms_samples = 2
average_frames = 2

[run]
duration_s = 84.0
"""

#: The program with the equalizer, for the wiener keys' corners.
WIENER = 'chip.dsp.program=["cms", "dark", "background", "average", "wiener"]'


@functools.cache
def base() -> Scenario:
    """The corner scene as written."""
    return scenario_from_dict(tomllib.loads(SCENE), "corners.toml")


def _field(key: str):
    """The schema field of a dotted scenario key."""
    *path, leaf = key.split(".")
    obj = base()
    for part in path:
        obj = getattr(obj, part)
    return next(f for f in fields(obj) if f.name == leaf)


def ends(key: str) -> tuple[float, float]:
    """Both ends of ``key``'s range: the least value it accepts (just above an open end) and
    the greatest."""
    m = _field(key).metadata
    lo = math.nextafter(m["lo"], math.inf) if m["lo_open"] else m["lo"]
    if m["kind"] is int:
        lo = math.ceil(lo)
    return lo, m["hi"]


def text(value: float) -> str:
    """A value as ``--set`` reads it (TOML: ints stay ints, floats keep their exponent)."""
    return str(value) if isinstance(value, int) else repr(float(value))


#: The keys a design study varies, each with the extra overrides its corners need.
STUDY_KEYS: dict[str, list[str]] = {
    "sites.footprint_radius_um": [],
    "sites.height_um": [],
    "chip.pixel.diode_w_um": [],
    "chip.pixel.diode_h_um": [],
    "chip.pitch_um": [],
    "chip.adc.bits": [],
    "chip.dsp.average_frames": [],
    "chip.timing.frame_period_s": [],
    "optics.top.solution_depth_um": [],
    "optics.top.lid_thickness_um": [],
    "optics.top.lid_n": [],
    "chip.dsp.wiener_noise_to_signal": [WIENER],
    "chip.dsp.wiener_coef_bits": [WIENER],
    **{f"chip.cost.{f.name}": [] for f in fields(Cost)},
}

#: Values beyond the two ends worth a corner of their own: the radius that found the bug.
EXTRA = {"sites.footprint_radius_um": [1e-300, 1e-9]}

#: A representative set of pairs: geometry against geometry, the converter against the
#: schedule, the top's two lengths, the equalizer against the pitch, cost against physics.
PAIRS = [
    ("sites.footprint_radius_um", "sites.height_um"),
    ("sites.footprint_radius_um", "chip.pitch_um"),
    ("chip.pitch_um", "chip.pixel.diode_w_um"),
    ("chip.pixel.diode_w_um", "chip.pixel.diode_h_um"),
    ("sites.height_um", "chip.pitch_um"),
    ("chip.adc.bits", "chip.timing.frame_period_s"),
    ("chip.dsp.average_frames", "chip.timing.frame_period_s"),
    ("chip.adc.bits", "chip.dsp.average_frames"),
    ("optics.top.solution_depth_um", "optics.top.lid_thickness_um"),
    ("optics.top.lid_n", "sites.height_um"),
    ("chip.dsp.wiener_noise_to_signal", "chip.pitch_um"),
    ("chip.cost.adc_area_per_bit_um2", "chip.adc.bits"),
    ("chip.cost.pixel_circuit_area_um2", "chip.pitch_um"),
    ("chip.cost.sram_cell_um2", "chip.cost.sram_array_efficiency"),
    ("chip.cost.dsp_energy_per_op_pJ", "chip.timing.frame_period_s"),
]


#: The top's other media, each with the keys only a lid takes cleared.
MEDIA = [('optics.top.medium="air"', "optics.top.lid_thickness_um=0", "optics.top.lid_n=0"),
         ('optics.top.medium="solution"', "optics.top.solution_depth_um=0",
          "optics.top.lid_thickness_um=0", "optics.top.lid_n=0")]


def _singles() -> list[tuple[str, ...]]:
    out = list(MEDIA)
    for key, extra in STUDY_KEYS.items():
        values = [*ends(key), *EXTRA.get(key, [])]
        out += [(f"{key}={text(v)}", *extra) for v in values]
    return out


def _pairs() -> list[tuple[str, ...]]:
    out = []
    for a, b in PAIRS:
        extra = sorted(set(STUDY_KEYS[a]) | set(STUDY_KEYS[b]))
        out += [(f"{a}={text(va)}", f"{b}={text(vb)}", *extra)
                for va, vb in product(ends(a), ends(b))]
    return out


def _finite(value) -> bool:
    """Every number in a summary is finite (None: a figure not defined, e.g. no Q20 base)."""
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, list):
        return all(_finite(v) for v in value)
    return not isinstance(value, float) or math.isfinite(value)


def _is_key(key: str) -> bool:
    """``key`` is a scenario key (``optics.layers[1:]``-style suffixes allowed)."""
    obj = base()
    for part in key.split("[", 1)[0].split("."):
        if not hasattr(obj, part):
            return False
        obj = getattr(obj, part)
    return True


def check_corner(path: Path, overrides: tuple[str, ...]) -> str:
    """Run one corner: "ran" (a finite summary) or "refused" (a ScenarioError, the CLI's exit
    2, refusing a scenario key, naming where the value came from, the file or its ``--set``,
    and a key set: as the key refused, in its source, or in what it allows); any other
    exception propagates (the internal error the test catches)."""
    keys = [o.split("=", 1)[0] for o in overrides]
    try:
        result = run(path, list(overrides))
    except ScenarioError as exc:
        assert _is_key(exc.key), f"{overrides}: refused on {exc.key!r}, not a scenario key"
        assert path.name in exc.source or "--set " in exc.source, f"{overrides}: {exc}"
        named = [k for k in keys if k == exc.key or f"--set {k}=" in exc.source
                 or k in exc.allowed]
        assert named, f"{overrides}: refused without naming a key set: {exc}"
        return "refused"
    summary = result.summary
    figures = {k: summary[k] for k in ("sites", "array", "cost", "throughput")}
    assert _finite(figures), f"{overrides}: a figure is not finite: {figures}"
    assert summary["cost"]["area_mm2"] > 0 and summary["cost"]["power_mw"] > 0
    return "ran"


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("corners") / "corners.toml"
    path.write_text(SCENE)
    return path


@pytest.mark.parametrize("overrides", _singles(), ids=lambda o: ",".join(o))
def test_each_key_at_both_ends_runs_or_is_refused(scene, overrides):
    """One key at an end of its range, the rest as the scene: a finite summary or exit 2."""
    check_corner(scene, overrides)


@pytest.mark.parametrize("overrides", _pairs(), ids=lambda o: ",".join(o))
def test_pairs_of_keys_at_their_ends_run_or_are_refused(scene, overrides):
    """Two keys at ends of their ranges together: a finite summary or exit 2."""
    check_corner(scene, overrides)


def test_the_point_like_radius_runs(scene):
    """The corner that was an internal error (the stack psf quadrature did not converge for a
    1e-300 µm disc) runs, and to the point source's answer: a disc that small is a point."""
    point = run(scene, ["sites.footprint_radius_um=0"]).summary["sites"]
    tiny = run(scene, ["sites.footprint_radius_um=1e-300"]).summary["sites"]
    assert [s["signal_e"] for s in tiny] == [s["signal_e"] for s in point]


@pytest.mark.parametrize("key", [f.name for f in fields(Cost)])
def test_cost_keys_at_both_ends_give_finite_positive_figures(key):
    """Every ``[chip.cost]`` key at each end of its range: the cost figures stay finite, the die's
    area and power positive (the formulas alone; the full runs are the slow corners above)."""
    for value in ends(f"chip.cost.{key}"):
        s = replace(base(), chip=replace(base().chip, cost=replace(base().chip.cost,
                                                                   **{key: value})))
        sch = Schedule.from_chip(s.chip, s.run.duration_s)
        cost = chip_cost.cost_figures(s, sch, {"reads": {"chip_q20_bases": 10}})
        assert _finite(cost) and cost["area_mm2"] > 0 and cost["power_mw"] > 0, (key, value)


def test_a_cost_value_out_of_range_names_file_key_value_and_range(tmp_path, capsys):
    """Bad input: a ``[chip.cost]`` value outside its range exits 2, naming the file, the key,
    the value and the range."""
    path = tmp_path / "bad_cost.toml"
    path.write_text(SCENE + "\n[chip.cost]\nsram_cell_um2 = 0.001\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    message = str(err.value)
    assert "bad_cost.toml" in message and "chip.cost.sram_cell_um2" in message
    assert "0.001" in message and "0.01" in message and "1000" in message
    assert main(["validate", str(path)]) == 2
    assert "chip.cost.sram_cell_um2" in capsys.readouterr().err
