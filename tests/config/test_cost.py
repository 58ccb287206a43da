"""The time and disk estimate before a run: its terms count what the run does,
a run past ``[run] max_wall_s`` or past the free disk is refused naming the key that raises the
limit, and the estimate is within :data:`~chiptwin.config.cost.ESTIMATE_FACTOR` of the wall
time measured on two bundled scenes (a factor, never a timing bound that could flake)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError, cost, load_scenario
from chiptwin.config.catalog import resolve_scenario
from tests.conftest import IDEAL_ADC, NO_TOP, PAPER_CHIP, REDUCED


def scene(name: str, *sets: str):
    return load_scenario(resolve_scenario(name), [*REDUCED.get(name, []), *sets])


def terms(s) -> dict[str, float]:
    return {t.what.split(" × ")[0]: t.seconds for t in cost.wall_estimate(s)}


def test_the_terms_count_what_the_run_does():
    s = scene("pyro_1fmol")
    c = s.chip
    frames = cost.n_frames(s)
    assert frames == 500
    est = cost.wall_estimate(s)
    ps = next(t for t in est if "pixel-samples (binned)" in t.what)
    assert ps.seconds == pytest.approx(frames * c.n_pixels * c.samples_per_frame
                                       * cost.PIXEL_SAMPLE_S["binned"])
    assert not any("DSP" in t.what or "well fills" in t.what or "cascade" in t.what for t in est)
    fixed = cost.wall_estimate(scene("pyro_1fmol", "run.fidelity.dsp=fixed"))
    assert any("fixed DSP" in t.what for t in fixed)
    events = cost.wall_estimate(scene("pyro_1fmol", "run.fidelity.photons=events"))
    assert any("whose well fills" in t.what for t in events)
    cascade = cost.wall_estimate(scene("pyro_1fmol", "run.fidelity.kinetics=cascade"))
    assert any("8 windows of its stiff solver" in t.what for t in cascade)
    # the chip model in closed form, or in SimPy when a DSP program runs
    frame_term = next(t.what for t in est if "frames of chip events" in t.what)
    assert "in closed form" in frame_term
    program = cost.wall_estimate(scene("pyro_1fmol", 'chip.dsp.program=["cms", "dark", '
                                                     '"background", "kinetics"]'))
    assert any("frames of chip events in SimPy" in t.what for t in program)
    # twice the frames, about twice the time
    longer = scene("pyro_1fmol", "run.duration_s=1000.0")
    fixed_part = cost.RUN_S + sum(t.seconds for t in cost.wall_estimate(s)  # per run, not frame
                                  if "footprint" in t.what or "detection" in t.what
                                  or "caller" in t.what)
    assert cost.wall_seconds(longer) - fixed_part == pytest.approx(
        2 * (cost.wall_seconds(s) - fixed_part))


def test_a_run_past_max_wall_s_is_refused_naming_the_key(capsys):
    # pyro_array_256 as bundled: ≈ 61 s estimated
    with pytest.raises(ScenarioError, match=r"run.max_wall_s = 1.0.*estimated at.*raise "
                                            r"run.max_wall_s"):
        load_scenario(resolve_scenario("pyro_array_256"), ["run.max_wall_s=1.0"])
    assert main(["run", "pyro_array_256", "--set", "run.max_wall_s=1", "--quiet",
                 "--out", "/nonexistent/never"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.max_wall_s" in err[0]
    assert scene("ccd_two_wells").run.max_wall_s == 3600.0  # the stated default


def test_save_frames_past_the_free_disk_is_refused(tmp_path, monkeypatch):
    s = scene("pyro_1fmol", "run.save_frames=true")
    assert cost.disk_bytes(s) == 500 * 2 * s.chip.samples_per_frame * s.chip.n_pixels
    cost.check_disk(s, tmp_path / "out")  # fits
    import shutil

    monkeypatch.setattr(shutil, "disk_usage", lambda p: shutil._ntuple_diskusage(1, 1, 1000))
    with pytest.raises(ScenarioError, match=r"run.save_frames.*GB"):
        cost.check_disk(s, tmp_path / "out")
    assert cost.disk_bytes(replace(s, run=replace(s.run, save_frames=False))) == 0


def test_validate_prints_the_estimate(capsys):
    assert main(["validate", "pyro_1fmol"]) == 0
    out = capsys.readouterr().out
    assert "estimated wall time" in out and "run.max_wall_s" in out


def test_the_converter_as_built_costs_by_where_its_moments_come_from():
    """The converter as built's expected moments: the series costs little a pixel-frame; a
    transition table, or a dark level within 10 (white + kTC) rms of code 0, sends them to
    the quadrature. ccd_two_wells's pedestal sits at code 1,311: a 64-LSB comparator reaches 807
    codes (the series), a 128-LSB one 1,447 (the quadrature, with the ends' closed form at each
    node: before it, a window of 2,565 codes a node, and the run did not end in 100 s). A
    transition table keeps its window."""
    def term(*sets):
        return next(t for t in cost.wall_estimate(scene(*sets)) if "as built" in t.what)

    assert not any("as built" in t.what for t in cost.wall_estimate(scene("pyro_1fmol",
                                                                          *IDEAL_ADC)))
    series = term("ccd_two_wells", "chip.adc.comparator_noise_lsb=64")
    wide = term("ccd_two_wells", "chip.adc.comparator_noise_lsb=128")
    assert "by the series" in series.what and "by quadrature" in wide.what
    assert "closed form" in wide.what and "codes" not in wide.what
    assert wide.seconds > 10 * series.seconds and "comparator_noise_lsb" in wide.keys
    table = term("pyro_1fmol", *IDEAL_ADC, "chip.adc.dnl_rms_lsb=0.2")
    assert "by quadrature" in table.what and "79 nodes" in table.what and "codes" in table.what
    # the reference chip as built: a smooth bow, no DNL: the series
    assert "by the series" in term("pyro_1fmol").what


@pytest.mark.parametrize(("name", "sets"), [
    ("pyro_1fmol", ["chip.adc.comparator_noise_uV=122.07"]),  # the series (and the bow)
    # the series with little white noise (0.079 LSB: 19 harmonics, their square's double sum);
    # at 0.02 LSB (76 harmonics) a run takes 30 s, estimated 41 s, and a flat cost per
    # pixel-frame said 0.09 s: a mutated scene ran over 16 minutes on such an estimate
    ("pyro_1fmol", [*IDEAL_ADC, "chip.adc.comparator_noise_lsb=0.001",
                    "chip.pixel.read_noise_e=60"]),
    ("ccd_two_wells", ["chip.adc.comparator_noise_lsb=128"]),  # the quadrature, the ends' form
])
def test_the_as_built_estimate_is_within_its_factor(name, sets):
    """The series (pyro_1fmol reduced, a 1-LSB comparator: 0.3 s) and the quadrature with the
    ends' closed form (ccd_two_wells reduced, a 128-LSB comparator: ≈ 4 s). The window
    constants were fitted to two whole runs of ≈ 20 and 30 s (config/cost.py), too long to
    repeat here. One run each, its kernels loaded from numba's cache (or compiled) included."""
    from chiptwin.fidelity import run

    s = scene(name, *sets)
    measured = run(s).summary["wall_time_s"]
    estimate = cost.wall_seconds(s)
    assert measured / cost.ESTIMATE_FACTOR <= estimate <= measured * cost.ESTIMATE_FACTOR, (
        f"{sets}: estimate {estimate:.3g} s, measured {measured:.3g} s")


def test_thin_films_are_costed_within_the_factor():
    """A 0.1 µm nitride film (33 band wavelengths) under pyro_1fmol reduced, isotropic, over
    silicon: the film term is most of the estimate, which is within its factor of the measured
    run (≈ 1.3 s, 3 profiles; the cache of profiles emptied first, as in a new process);
    without the film there is no such term."""
    from chiptwin.fidelity import run
    from chiptwin.optics.profile import _build_profile

    layers = ('optics.layers=[{name="buffer", n=1.33}, {name="Si3N4", n=2.0, thickness_um=0.1},'
              ' {name="SiO2", n=1.46, thickness_um=13.9}]')
    sets = ['optics.emitter="isotropic"', "optics.silicon_n=4.3"]
    sets += NO_TOP  # the film's profiles alone: a top's parts add their own
    s = scene("pyro_1fmol", layers, *sets)
    terms = {t.what.split(":")[0]: t.seconds for t in cost.wall_estimate(s)}
    film = terms.pop("3 profiles through 1 thin film(s)")
    assert film > sum(terms.values())
    _build_profile.cache_clear()
    measured = run(s).summary["wall_time_s"]
    assert measured / cost.ESTIMATE_FACTOR <= cost.wall_seconds(s) <= (
        measured * cost.ESTIMATE_FACTOR)
    assert not [t for t in cost.wall_estimate(scene("pyro_1fmol", *sets)) if "film" in t.what]
    # the paper's convention still has the summary's two law shares built through the film
    na2 = scene("pyro_1fmol", layers, *PAPER_CHIP)  # the nitride between buffer and oxide
    assert [t.what for t in cost.wall_estimate(na2) if "film" in t.what][0].startswith(
        "2 profiles through 1 thin film(s)")
    _build_profile.cache_clear()
    measured = run(na2).summary["wall_time_s"]
    assert measured / cost.ESTIMATE_FACTOR <= cost.wall_seconds(na2) <= (
        measured * cost.ESTIMATE_FACTOR)
    # a thin last layer with nothing below it (silicon_n = 0) is no film
    last = ('optics.layers=[{name="buffer", n=1.33}, {name="SiO2", n=1.46, thickness_um=13.0},'
            ' {name="Si3N4", n=2.0, thickness_um=1.0}]')
    assert not [t for t in cost.wall_estimate(scene("pyro_1fmol", last, sets[0]))
                if "film" in t.what]


@pytest.mark.parametrize("name", ["pyro_1fmol", "crosstalk_microarray"])
def test_the_estimate_is_within_its_factor_of_measured_wall_time(name):
    from chiptwin.fidelity import run

    s = scene(name)
    run(s)  # warm: compiled kernels loaded, as the calibration measured
    measured = run(s).summary["wall_time_s"]
    estimate = cost.wall_seconds(s)
    assert measured / cost.ESTIMATE_FACTOR <= estimate <= measured * cost.ESTIMATE_FACTOR, (
        f"{name}: estimate {estimate:.3g} s, measured {measured:.3g} s")


def test_the_physical_law_beside_the_convention_is_charged_its_two_runs():
    """A paper-convention scene's run adds two expected-level runs (``summary['physical_law']``):
    the scene's own estimate at those levels and the same under the isotropic law, which at the
    psf level integrates the light over the 20 µm footprints (the convention does not: one
    medium, a closed form), and nothing when it is turned off."""
    def beside(*sets):
        s = load_scenario(resolve_scenario("pyro_paper_yield"), list(sets))
        return [t.seconds for t in cost.wall_estimate(s) if "physical law" in t.what]

    def own(*sets):
        s = load_scenario(resolve_scenario("pyro_paper_yield"),
                          ['run.fidelity.photons="expected"', 'chip.dsp.mode="float"', *sets])
        return sum(t.seconds for t in cost.wall_estimate(s, beside=False))

    psf, na2 = 'run.fidelity.optics="psf"', 'run.fidelity.optics="na2"'
    assert beside(na2) == [pytest.approx(2 * own(na2))]
    physical = own(psf, 'optics.emitter="isotropic"')
    assert physical == pytest.approx(own(psf) + cost.FOOTPRINT_PROFILE_S)
    assert beside(psf) == [pytest.approx(own(psf) + physical)]
    assert not beside("run.beside_physical_law=false")


def test_the_footprint_profiles_are_charged_where_the_run_makes_them():
    """luciferase_label's sites have 10 µm footprints under an open drop (air: one part of
    returned light): the psf coupling through its stack makes 2 profiles over them, the summary's
    with/without-top figures 3 at every level; a glass lid returns two parts; point sites and
    the paper's one-medium convention make none at psf."""
    def profiles(*sets):
        s = load_scenario(resolve_scenario("luciferase_label"), list(sets))
        terms = [t for t in cost.wall_estimate(s) if "footprint" in t.what]
        return {t.what.split(":")[0]: round(t.seconds / cost.FOOTPRINT_PROFILE_S) for t in terms}

    psf, raytrace = 'run.fidelity.optics="psf"', 'run.fidelity.optics="raytrace"'
    coupling, summary = "the psf coupling through the stack", "the summary's top figures"
    assert profiles(psf) == {coupling: 2, summary: 3}
    assert profiles(raytrace) == {summary: 3}
    glass = ['optics.top.medium="glass"', "optics.top.solution_depth_um=100",
             "optics.top.lid_thickness_um=1000", "optics.top.lid_n=1.5"]
    assert profiles(psf, *glass) == {coupling: 3, summary: 4}
    assert profiles(psf, "sites.footprint_radius_um=0") == {}
    assert profiles(psf, *NO_TOP) == {coupling: 1}
    assert profiles(psf, *PAPER_CHIP) == {}


def test_the_detection_is_charged_per_site_and_per_site_and_flow():
    def detection(name, *sets):
        s = load_scenario(resolve_scenario(name), list(sets))
        return next(t for t in cost.wall_estimate(s) if t.what.startswith("the detection"))

    atp = detection("atp_dose_response")
    assert atp.seconds == pytest.approx(64 * cost.DETECT_SITE_S) and "flows" not in atp.what
    pyro = [detection("pyro_1fmol", *REDUCED["pyro_1fmol"], f"sites.at_pixels={at}").seconds
            for at in ("[[4, 8], [2, 3]]", '"all"')]
    per_site = cost.DETECT_SITE_S + 8 * cost.DETECT_SITE_FLOW_S
    assert pyro == [pytest.approx(2 * per_site), pytest.approx(128 * per_site)]


def test_a_study_row_shares_the_scene_preparation_with_its_replicates():
    """A study point's replicates share its prepared scene (kinetics, optics, the summary's
    optical figures, the moments a small scene keeps): a row pays 1/replicates of those terms.
    adc_bits_pyro's 14-bit point as built: the run estimated ≈ 0.5 s, of which the footprint
    profiles ≈ 0.4 s; its rows measured 0.064-0.08 s each (3,310 rows in 266.6 s)."""
    s = load_scenario(resolve_scenario("pyro_1fmol"), ["chip.adc.clock_hz=160e6",
                                                          "chip.adc.bits=14",
                                                          "chip.adc.comparator_noise_uV=61.04"])
    terms = cost.wall_estimate(s)
    shared = sum(t.seconds for t in terms if t.per_scene)
    assert any("footprint" in t.what and t.per_scene for t in terms)
    assert any("converter as built" in t.what and t.per_scene for t in terms)  # kept moments
    assert not any("pixel-samples" in t.what and t.per_scene for t in terms)  # the draws
    assert cost.row_seconds(s, 1) == pytest.approx(cost.wall_seconds(s))
    assert cost.row_seconds(s, 90) == pytest.approx(cost.wall_seconds(s) - shared * 89 / 90)
    assert 0.04 < cost.row_seconds(s, 90) < 0.25
