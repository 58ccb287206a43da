"""Long templates: the compiled phased flowgram against the reference model, drawn templates,
the per-site DNA spread and the light the twin makes of them."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.config import load_scenario
from chiptwin.kinetics import phasing, pyro, templates
from chiptwin.twin import stages

SCENES = "scenarios"


@pytest.mark.parametrize(("eps", "lam", "droop"), [(0.0, 0.0, 0.0), (0.002, 0.0, 0.0),
                                                   (0.0, 0.015, 0.0), (0.003, 0.02, 0.002)])
def test_phased_signal_equals_the_reference_model(eps, lam, droop):
    """The kernel (tails below 1e-9 of the strands dropped) against phased_flows, the per-flow
    model written out in numpy, times (1 − droop)^k."""
    rng = np.random.default_rng(1)
    t = "TCAG" + templates.draw_template(150, 0.5, 0.35, 6, rng)
    _, ref, _ = phasing.phased_flows(t, "TACG", 240, eps, lam)
    signal, in_phase, ideal = phasing.phased_signal(t, "TACG", 240, eps, lam, droop)
    drooped = ref * (1.0 - droop) ** np.arange(240)
    assert np.max(np.abs(signal - drooped)) < 1e-6
    assert np.array_equal(ideal, pyro.flow_incorporations(t, "TACG", 240)[1])
    assert np.all(in_phase <= (1 - droop) ** np.arange(240) + 1e-12)


def test_in_phase_share_without_phasing_is_the_droop():
    t = "TCAGGTTCCAAAGTCGAT"
    _, in_phase, _ = phasing.phased_signal(t, "TACG", 30, 0.0, 0.0, 0.01)
    assert np.allclose(in_phase, 0.99 ** np.arange(30))


def test_phased_signal_refuses_droop_of_one():
    with pytest.raises(ValueError, match="droop"):
        phasing.phased_signal("TCAG", "TACG", 8, 0.0, 0.0, 1.0)


def test_drawn_template_statistics():
    """Monte Carlo: G+C share, runs never longer than asked, never two runs of one base, and
    the mean run length of the truncated geometric law."""
    rng = np.random.default_rng(7)
    seq = templates.draw_template(40_000, 0.6, 0.4, 5, rng)
    assert len(seq) == 40_000 and templates.longest_run(seq) <= 5
    gc = (seq.count("G") + seq.count("C")) / len(seq)
    assert abs(gc - 0.6) < 0.015
    runs = [len(r) for r in __import__("re").findall(r"A+|C+|G+|T+", seq)]
    n = np.arange(1, 6)
    p = 0.4 ** (n - 1) / (0.4 ** (n - 1)).sum()
    assert abs(np.mean(runs) - (n * p).sum()) < 0.03  # ≈ 12,000 runs: sd of the mean ≈ 0.007


def test_drawn_template_is_seeded_and_starts_with_the_key():
    a = templates.drawn_template("TCAG", 200, 0.5, 0.3, 8, 11)
    assert a == templates.drawn_template("TCAG", 200, 0.5, 0.3, 8, 11)
    assert a != templates.drawn_template("TCAG", 200, 0.5, 0.3, 8, 12)
    assert a.startswith("TCAG") and len(a) == 204 and a[4] != "G"


def test_long_read_scene_template():
    """The bundled scene: 400 bases drawn, an 8-mer in the part 400 flows read."""
    s = load_scenario(f"{SCENES}/pyro_long_read.toml")
    assert len(s.assay.template) == 400 and s.assay.template.startswith("TCAG")
    reach = int(pyro.flow_incorporations(s.assay.template, "TACG", s.assay.n_flows)[1].sum())
    assert templates.longest_run(s.assay.template[:reach]) == 8 and reach >= 200


def test_light_without_phasing_is_unchanged():
    """pyro_1fmol (no phasing keys): the flow program's integer counts, as before."""
    s = load_scenario(f"{SCENES}/pyro_1fmol.toml")
    assert np.array_equal(stages.expected_incorporations(s), stages.flow_program(s)[1])
    assert np.array_equal(stages.site_copies(s, 2), np.ones(2))


def test_site_copies_spread_is_the_cv_and_changes_with_the_chip():
    s = load_scenario(f"{SCENES}/pyro_long_read.toml", ["assay.dna_cv=0.3"])
    draws = np.concatenate([stages.site_copies(load_scenario(
        f"{SCENES}/pyro_long_read.toml", ["assay.dna_cv=0.3"], seed=k), 128) for k in range(40)])
    assert abs(draws.mean() - 1.0) < 0.02 and abs(draws.std() / draws.mean() - 0.3) < 0.02
    assert not np.array_equal(stages.site_copies(s, 128), draws[:128])
    assert np.array_equal(stages.site_copies(s, 128), stages.site_copies(s, 128))


def assert_each_replicate_prepares_its_own_light(s) -> None:
    """A study point's scene ``s`` prepared for replicates at seeds 1, 2 and 1 again: the
    replicates' light differs, the same seed's is the same bits."""
    from dataclasses import replace
    from types import SimpleNamespace

    from chiptwin.study import rows

    task = SimpleNamespace(scenario=s)
    one, two, again = (rows._scene(task, replace(s, scenario=replace(s.scenario, seed=k)))[0]
                       for k in (1, 2, 1))
    assert not np.allclose(one.site_photons, two.site_photons)
    assert np.array_equal(one.site_photons, again.site_photons)


def test_a_study_replicate_on_another_chip_redraws_the_sites_dna():
    """vary_chip: each replicate another chip, its sites' DNA copies too (the point's scene is
    prepared once; with dna_cv its light is prepared again per replicate)."""
    assert_each_replicate_prepares_its_own_light(load_scenario(
        f"{SCENES}/pyro_long_read.toml", ["sites.at_pixels=[[4, 8], [2, 3]]", "assay.n_flows=20",
                                          "run.duration_s=1220", "chip.fixed_pattern_seed=-1"]))
