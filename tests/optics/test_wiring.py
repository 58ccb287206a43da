"""The planar stack wired into the scenario, the twin and the tools: the ``[optics]`` keys, the
levels
``na2 · psf · raytrace`` through :func:`chiptwin.twin.stages.coupling`, ``auto`` and the summary.

Kinds: equivalence (a homogeneous one-layer stack gives today's summary bit for bit;
``raytrace`` equals ``psf`` within 4 standard errors pixel by pixel through the scenario path),
unit (bad keys exit 2 naming the key; ``auto`` picks with reasons), regression of the bundled
scenes (stating their stacks under ``lambertian_na2`` changes no coupling) and the
``jssc2006_faceplate`` scene's report.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.fidelity.auto import resolve
from chiptwin.twin import stages
from chiptwin.twin.levels import LEVELS, reference_levels, with_levels
from tests.conftest import NO_TOP, PAPER_CHIP, SCENARIOS, SMALL

SIGMAS = 4.0

ISOTROPIC = ['optics.emitter="isotropic"']
ONE_LAYER = ['optics.layers=[{ name = "water", n = 1.33, thickness_um = 15.0 }]']


def _small(tmp_path, extra: str = "") -> object:
    path = tmp_path / "small.toml"
    path.write_text(SMALL + extra)
    return path


def _strip(summary: dict) -> dict:
    """The summary without what differs between two runs of one scene (the clocks)."""
    out = json.loads(json.dumps(summary))
    for key in ("wall_time_s", "stage_time_s", "calibration_s"):
        out.pop(key, None)
    return out


def test_levels_and_reference():
    """raytrace is the optics stage's most faithful level; the reference where the scene has a
    physical emitter law, psf under the paper's convention."""
    assert LEVELS["optics"] == ("na2", "psf", "raytrace")
    paper = load_scenario(SCENARIOS / "pyro_1fmol.toml", PAPER_CHIP)
    assert reference_levels(paper)["optics"] == "psf"
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml")  # isotropic, under a flow cell's lid
    assert reference_levels(s)["optics"] == "raytrace"
    lens = load_scenario(SCENARIOS / "ccd_100fmol.toml", ISOTROPIC)
    assert reference_levels(lens)["optics"] == "na2"


def test_homogeneous_one_layer_stack_is_todays_run_bit_for_bit(tmp_path):
    """A scenario without layers and the same with one homogeneous layer of the site height:
    the coupling matrices are identical and so is every figure of the summary."""
    from chiptwin.fidelity.auto import run

    path = _small(tmp_path)
    for law in ("isotropic", "lambertian", "lambertian_na2"):
        sets = [f'optics.emitter="{law}"']
        plain = load_scenario(path, sets)
        stacked = load_scenario(path, sets + ONE_LAYER)
        assert stacked.optics.stated_stack and not plain.optics.stated_stack
        assert np.array_equal(stages.coupling(plain), stages.coupling(stacked))
    a, b = run(plain), run(stacked)
    assert _strip(a.summary) == _strip(b.summary)
    assert np.array_equal(a.arrays["site_signal_e"], b.arrays["site_signal_e"])


def test_bundled_scenes_state_their_law_and_keep_their_coupling():
    """Every bundled scene states its emitter law; under lambertian_na2 the stated stack does
    not enter the coupling (one medium of the stack's height): equal to the no-stack path."""
    for path in sorted(SCENARIOS.glob("*.toml")):
        text = path.read_text()
        assert "Emitter law:" in text, path.name
        s = load_scenario(path)
        if s.optics.law != "lambertian_na2" or not s.optics.layers or s.chip.n_pixels > 4096:
            continue
        plain = load_scenario(path, ["optics.layers=[]"])
        assert np.array_equal(stages.coupling(s), stages.coupling(plain)), path.name


def test_raytrace_equals_psf_through_the_scenario_path(tmp_path):
    """One homogeneous medium, the diode plane a perfect absorber (silicon_n = 0): the raytrace
    level's matrix through ``stages.coupling`` equals the psf level's pixel by pixel within
    4 SE (4 × 6 pixels, two sites with 20 µm disc footprints, 15 µm up, isotropic)."""
    path = _small(tmp_path)
    sets = ISOTROPIC + ['sites.footprint_radius_um=20.0', "optics.raytrace_rel_error=0.005",
                        "optics.raytrace_seed=3"]
    s = load_scenario(path, sets + ['run.fidelity.optics="raytrace"'])
    psf = stages.coupling(with_levels(s, {"optics": "psf"}))
    traced = stages.coupling(s)
    r = stages.raytrace_result(s)
    assert np.array_equal(traced, r.coupling)
    se = np.sqrt(psf * (1 - psf) / r.n_rays[None, :])
    assert np.all(np.abs(traced - psf) <= SIGMAS * se + 1e-15), np.max(np.abs(traced - psf) / se)
    idx = stages.site_pixel_indices(s)
    own = traced[idx, [0, 1]]
    assert np.all(r.stderr[idx, [0, 1]] / own < 0.0051)  # the requested error on the own pixel
    # seeded by optics.raytrace_seed, not scenario.seed: a study's replicates share it
    assert np.array_equal(stages.coupling(load_scenario(path, sets + [
        'run.fidelity.optics="raytrace"'], seed=99)), traced)


def _validate(tmp_path, extra: str, sets=()) -> tuple[int, str]:
    path = tmp_path / "bad.toml"
    path.write_text(SMALL + extra)
    err = io.StringIO()
    argv = ["validate", str(path)] + [a for kv in sets for a in ("--set", kv)]
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    return code, err.getvalue()


LAYERS_15 = '''
[optics]
emitter = "isotropic"
layers = [{ name = "water", n = 1.33, thickness_um = 1.0 },
          { name = "oxide", n = 1.46, thickness_um = 14.0 }]
'''


@pytest.mark.parametrize("extra, sets, key", [
    ('\n[optics]\nemitter = "lambertian_nA2"\n', (), "optics.emitter"),
    ('\n[optics]\nemitter = "lambertian"\nconvention = "isotropic"\n', (), "optics.emitter"),
    (LAYERS_15, ["sites.height_um=20.0"], "optics.layers"),
    (LAYERS_15.replace("n = 1.46", "n = 14.6"), (), "optics.layers[1].n"),
    (LAYERS_15.replace("n = 1.46,", "n = 1.46, k = 1e-3, alpha_per_um = 0.1,"), (),
     "optics.layers[1].k"),
    (LAYERS_15.replace("n = 1.46,", "nn = 1.46,"), (), "optics.layers[1].nn"),
    (LAYERS_15.replace("{ name = \"water\", n = 1.33, thickness_um = 1.0 }", "1.0"), (),
     "optics.layers[0]"),
    (LAYERS_15, ["optics.silicon_n=0.5"], "optics.silicon_n"),
    (LAYERS_15, ["optics.faceplate.na=3.0"], "optics.faceplate.na"),
    (LAYERS_15, ["optics.faceplate.na=1.0"], "optics.layers"),  # height must include it
    ('\n[optics]\nlayers = [{ name = "w", n = 1.33, thickness_um = 5.0 }]\n',
     ["optics.faceplate.na=1.0", "optics.faceplate.thickness_um=10.0"], "optics.faceplate.na"),
    (LAYERS_15, ['run.fidelity.optics="raytrace"', 'optics.emitter="lambertian_na2"'],
     "run.fidelity.optics"),
    (LAYERS_15, ["optics.raytrace_rel_error=0.0"], "optics.raytrace_rel_error"),
    (LAYERS_15, ['optics.walls="absorbing"', "optics.well_side_um=50.0"], "optics.walls"),
    (LAYERS_15, ['optics.walls="mirror"'], "optics.walls"),
])
def test_bad_optics_keys_exit_2_naming_the_key(tmp_path, extra, sets, key):
    code, err = _validate(tmp_path, extra, sets)
    assert code == 2, err
    assert f"{key} = " in err and len(err.strip().splitlines()) == 1, err


def test_good_optics_keys_validate(tmp_path):
    sets = ['run.fidelity.optics="raytrace"', 'optics.walls="reflecting"',
            "optics.well_side_um=60.0", "optics.silicon_n=4.3"]
    code, err = _validate(tmp_path, LAYERS_15, sets)
    assert code == 0, err


def test_the_solution_fills_the_site_height():
    """A first layer without thickness_um fills sites.height_um above the others: a bundled
    scene's height can still be set on the command line (the site moves in its solution)."""
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", ["sites.height_um=150"])
    stack = stages.optics_stack(s)
    assert [layer.thickness_um for layer in stack.layers] == [136.0, 14.0]
    with pytest.raises(Exception, match="sites.height_um"):
        load_scenario(SCENARIOS / "pyro_1fmol.toml", ["sites.height_um=10"])


def test_jssc2006_faceplate_runs_and_reports(tmp_path):
    """The reference chip on its faceplate: the run reports own pixel and cross-talk with the
    faceplate against the same solution directly on the diodes (summary and report.md). The
    faceplate alone puts no light on a neighbour (below −120 dB, without the flow cell's lid);
    the lid returns light, but what its top face returns by total internal reflection travels
    beyond 48.75° in water, outside the NA-1.0 faceplate's acceptance: only the solution/glass
    face's Fresnel share gets through, −35.1 dB on the edge neighbour."""
    out = tmp_path / "out"
    argv = ["run", "jssc2006_faceplate", "--out", str(out), "--set", "assay.n_flows=8",
            "--set", "run.duration_s=500.0"]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    sm = json.loads((out / "summary.json").read_text())
    o = sm["optics"]
    assert o["emitter"] == "isotropic" and o["laws_differ_beyond_budget"]
    fp = o["faceplate"]
    assert fp["with"]["crosstalk_db"] == pytest.approx(-35.07, abs=0.05)
    assert o["top"]["medium"] == "glass"
    assert fp["without"]["crosstalk_db"] == pytest.approx(-18.85, abs=0.05)
    assert fp["own_pixel_ratio"] == pytest.approx(0.2854, abs=1e-3)
    assert o["own_pixel"] == pytest.approx(fp["with"]["own_pixel"], rel=1e-9)
    assert sm["called_sequence"] == sm["true_sequence"][: len(sm["called_sequence"])]
    report = (out / "report.md").read_text()
    assert "faceplate vs direct contact" in report and "own pixel" in report


def test_a_passivation_film_is_coherent_and_reported(tmp_path):
    """pyro_1fmol with 0.1 µm of nitride on its oxide, over silicon, isotropic: the film is
    crossed coherently at the psf level (the run's own pixel is the coherent profile's) and the
    summary and report say so, with the plane fraction against rays alone (−6.8 %, the film
    reflecting more than its two bare interfaces)."""
    out = tmp_path / "out"
    layers = ('optics.layers=[{name="buffer", n=1.33}, {name="Si3N4", n=2.0, thickness_um=0.1},'
              ' {name="SiO2", n=1.46, thickness_um=13.9}]')
    argv = ["run", "pyro_1fmol", "--out", str(out), "--set", "assay.n_flows=8", "--set",
            "run.duration_s=500.0", "--set", 'optics.emitter="isotropic"', "--set", layers,
            "--set", "optics.silicon_n=4.3"]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    optics_fig = json.loads((out / "summary.json").read_text())["optics"]
    tf = optics_fig["thin_films"]
    assert [f["name"] for f in tf["films"]] == ["Si3N4"]
    assert tf["band_nm"] == {"peak": 562.0, "fwhm": 70.0}
    assert tf["change_rel"] == pytest.approx(-0.068, abs=0.002)
    assert "thin films, coherent over 562 ± 35 nm" in (out / "report.md").read_text()
    rays = load_scenario(SCENARIOS / "pyro_1fmol.toml", [layers, "optics.silicon_n=4.3",
                                                         'optics.emitter="isotropic"',
                                                         "optics.thin_film_um=0"])
    own = stages.site_pixel_indices(rays)[0]  # the run's own pixel (its coupling) against rays
    ratio = optics_fig["own_pixel"] / stages.coupling(rays)[own, 0] - 1
    assert ratio == pytest.approx(tf["change_rel"], abs=0.01)


def test_auto_picks_among_the_three_levels_with_reasons(tmp_path):
    """atp_glow with an isotropic emitter: raytrace is the optics reference, auto calibrates
    na2 and psf against it and says why it picked what it picked."""
    budget = ["run.error_budget.signal_rel=0.05", 'run.fidelity.optics="auto"',
              "run.duration_s=60.0"]
    s = load_scenario(SCENARIOS / "atp_glow.toml", ISOTROPIC + NO_TOP + budget)  # na2: no top
    assert reference_levels(s)["optics"] == "raytrace"
    resolved, choice = resolve(s, cache=tmp_path / "est.sqlite")
    level = choice.levels["optics"]
    assert level in LEVELS["optics"] and resolved.run.fidelity.optics == level
    why = choice.reasons["optics"]
    assert "against raytrace" in why and "raytrace reference" in why
    if level != "na2":
        assert "not na2" in why
    tight = load_scenario(SCENARIOS / "atp_glow.toml", ISOTROPIC + NO_TOP + budget + [
        "run.error_budget.signal_rel=1e-6"])
    assert resolve(tight, cache=tmp_path / "est.sqlite")[1].levels["optics"] == "raytrace"
