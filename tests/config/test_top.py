"""``[optics.top]``: the site's top surface, its keys and cross-field rules.

Unit tests: a good top loads with its defaults resolved; every bad one is refused by
``chiptwin validate`` with exit 2 and one line naming the file, the key, the value and what is
allowed (the pattern of ``test_validation.py``).
"""

from __future__ import annotations

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.twin.stages import optics_top
from tests.conftest import NO_TOP, SMALL

ISOTROPIC = '[optics]\nemitter = "isotropic"\n'


def _scenario(optics: str) -> str:
    """The small scenario with an ``[optics]`` block (and its sub-tables) before ``[chip]``."""
    assert "[chip]" in SMALL
    return SMALL.replace("[chip]", optics + "\n[chip]", 1)


def test_defaults_are_the_solution(tmp_path):
    """No ``[optics.top]``: medium "solution", nothing returns, no top handed to the optics."""
    path = tmp_path / "s.toml"
    path.write_text(_scenario(ISOTROPIC))
    s = load_scenario(path)
    assert s.optics.top.medium == "solution" and not s.optics.top.present
    assert optics_top(s) is None


def test_glass_lid_resolves_its_index(tmp_path):
    """A lid without ``lid_n`` is glass of index 1.5; the top handed to the optics carries it."""
    path = tmp_path / "s.toml"
    path.write_text(_scenario(ISOTROPIC + "[optics.top]\nmedium = \"glass\"\n"
                              "solution_depth_um = 80.0\nlid_thickness_um = 170.0\n"))
    top = optics_top(load_scenario(path))
    assert (top.medium, top.solution_depth_um, top.lid_n, top.lid_thickness_um) == (
        "glass", 80.0, 1.5, 170.0)


# (what is wrong, the [optics] block, the key the message must name, a word of the rule)
BAD = [
    ("unknown medium", ISOTROPIC + '[optics.top]\nmedium = "water"\n', "optics.top.medium",
     "'solution', 'air', 'glass'"),
    ("depth missing", ISOTROPIC + '[optics.top]\nmedium = "air"\n',
     "optics.top.solution_depth_um", "required"),
    ("depth too small", ISOTROPIC + '[optics.top]\nmedium = "air"\nsolution_depth_um = 0.01\n',
     "optics.top.solution_depth_um", "[0.1, 10000]"),
    ("depth too large", ISOTROPIC + '[optics.top]\nmedium = "air"\nsolution_depth_um = 2e4\n',
     "optics.top.solution_depth_um", "[0, 10000]"),
    ("lid without thickness", ISOTROPIC + '[optics.top]\nmedium = "glass"\n'
     "solution_depth_um = 50.0\n", "optics.top.lid_thickness_um", "needs its thickness"),
    ("lid index on an open well", ISOTROPIC + '[optics.top]\nmedium = "air"\n'
     "solution_depth_um = 50.0\nlid_n = 1.5\n", "optics.top.lid_n", "glass"),
    ("lid thickness on an open well", ISOTROPIC + '[optics.top]\nmedium = "air"\n'
     "solution_depth_um = 50.0\nlid_thickness_um = 100.0\n", "optics.top.lid_thickness_um",
     "glass"),
    ("depth with nothing above", ISOTROPIC + "[optics.top]\nsolution_depth_um = 50.0\n",
     "optics.top.solution_depth_um", "nothing returns"),
    ("lid below the solution's index", ISOTROPIC + '[optics.top]\nmedium = "glass"\n'
     "solution_depth_um = 50.0\nlid_thickness_um = 100.0\nlid_n = 1.2\n", "optics.top.lid_n",
     "lower index"),
    ("lambertian_na2", '[optics]\nemitter = "lambertian_na2"\n[optics.top]\nmedium = "air"\n'
     "solution_depth_um = 50.0\n", "optics.top.medium", "one medium"),
    ("lens coupling", '[optics]\ncoupling = "lens"\nemitter = "isotropic"\n'
     "aperture_diameter_um = 1000.0\nobject_distance_um = 2000.0\n[optics.top]\n"
     'medium = "air"\nsolution_depth_um = 50.0\n', "optics.top.medium", "contact imaging"),
]
#: Options of a case beyond the file (a lens is refused at psf before its top is looked at).
ARGS = {"lens coupling": ["--set", 'run.fidelity.optics="na2"']}


@pytest.mark.parametrize(("what", "optics", "key", "rule"), BAD, ids=[b[0] for b in BAD])
def test_bad_top_exits_2_naming_the_key(tmp_path, capsys, what, optics, key, rule):
    path = tmp_path / "bad.toml"
    path.write_text(_scenario(optics))
    assert main(["validate", str(path), *ARGS.get(what, [])]) == 2
    err = capsys.readouterr().err
    assert f"{key} = " in err and str(path) in err and rule in err, err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_na2_level_refuses_a_top(tmp_path, capsys):
    """The na2 level (the own diode's solid angle) has no model of the top: the level is named."""
    path = tmp_path / "bad.toml"
    path.write_text(_scenario(ISOTROPIC + '[optics.top]\nmedium = "air"\n'
                              "solution_depth_um = 50.0\n"))
    assert main(["validate", str(path), "--set", 'run.fidelity.optics="na2"']) == 2
    err = capsys.readouterr().err
    assert "run.fidelity.optics = 'na2'" in err and "top surface" in err


def test_a_top_costs_the_raytrace_level_more_rays_time():
    """A traced ray under an open top takes ≈ 2.5× as long (measured 4.4 → 2.2 M rays/s on the
    pyro_1fmol stack): 8.8e8 rays pass the raytrace level's 1.2e9-ray cap without a top and are
    refused under one, naming the key that lowers them."""
    sets = [*NO_TOP, 'optics.emitter="isotropic"', 'run.fidelity.optics="raytrace"',
            'sites.at_pixels="all"', "chip.rows=16", "chip.cols=32",
            "optics.raytrace_rel_error=0.001", "chip.memory.capacity_bits=4194304"]
    assert load_scenario("pyro_1fmol", sets).optics.top.medium == "solution"
    with pytest.raises(ScenarioError, match="under the air top, 2.5× a ray's time") as e:
        load_scenario("pyro_1fmol", [*sets, 'optics.top.medium="air"',
                                     "optics.top.solution_depth_um=50.0"])
    assert e.value.key == "optics.raytrace_rel_error"


def test_light_given_at_the_sensor_refuses_a_top():
    """A flux scene gives its light at the sensor plane: a top would be silently ignored."""
    with pytest.raises(ScenarioError, match="crosses no optics") as e:
        load_scenario("snr10_requirement", ['optics.top.medium="air"',
                                            "optics.top.solution_depth_um=50.0"])
    assert e.value.key == "optics.top.medium" and e.value.value == "air"
