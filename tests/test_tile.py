"""The representative tile (``[run] tile``; :mod:`chiptwin.config.tiling`,
:mod:`chiptwin.twin.tile`).

Unit: the bands of an axis (a table), the lattice a layout must fill, the tile's coupling
against the obvious one (the whole array's coupling matrix, its columns summed by stand-in), the
weighted figures against repeating each site by its weight, the light error 0 where the tile is
as wide as the coupling's reach; bad input exits 2 naming ``run.tile``; the memory budget taken
on what a tiled run simulates.

Equivalence: at the ``expected`` level with no fixed pattern and an ideal converter nothing is
drawn, so every simulated site's signal and noise must be the whole array's at that site (the
light on a site's pixel is the array's exactly) to 1e-9.

Validation (slow): ``pyro_array_256`` whole and tiled (``auto``) at the scenario's seed; the
tiled chip figures (fraction of sites called right, fraction detected, mean power SNR) must
agree with the whole array's within 3 standard errors of their difference (each run's own Monte
Carlo standard error over its sites, combined: a 0.3 % chance per figure of failing a right
tile), plus the light error the tile states (≤ 0.13 % of a site's light here, a bias of at most
twice that on a power SNR).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from chiptwin import limits
from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.config.tiling import TilePlan, axis_plan, lattice, simulated_scenario
from chiptwin.twin import run, stages, tile
from chiptwin.twin.runner import prepare

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
ARRAY = SCENARIOS / "pyro_array_256.toml"
#: pyro_array_256 cut to 64 × 64 pixels (16 × 16 sites at its 4-pixel pitch), 8 flows of 20 s.
SITES = [f"[{r}, {c}]" for r in range(2, 64, 4) for c in range(2, 64, 4)]
SMALL = ["chip.rows=64", "chip.cols=64", f"sites.at_pixels=[{', '.join(SITES)}]",
         "assay.n_flows=8", "assay.flow_period_s=20.0", "run.duration_s=180.0",
         "chip.memory.capacity_bits=16000000"]
#: Nothing drawn: the expected level, no fixed pattern, the ideal converter.
EXACT = ["run.fidelity.photons=\"expected\"", "chip.pixel.prnu_frac=0.0",
         "chip.pixel.dsnu_frac=0.0", "run.fidelity.adc=\"ideal\""]


@pytest.mark.parametrize("n, k, sim, weight", [
    (10, 3, [0, 1, 2, 3, 4, 5, 7, 8, 9], [1, 1, 1, 2, 1, 1, 1, 1, 1]),
    (64, 8, [*range(8), *range(28, 36), *range(56, 64)], [1] * 8 + [6] * 8 + [1] * 8),
    (9, 3, list(range(9)), [1] * 9),  # 3 tiles hold the axis: simulated whole
    (1, 2, [0], [1]),
])
def test_an_axis_has_two_edge_bands_and_a_middle_one_weighted_by_its_stand_ins(n, k, sim, weight):
    a = axis_plan(origin=2, pitch=4, n=n, k=k)
    assert list(a.sim) == sim and list(a.weight) == weight
    assert a.weight.sum() == n
    # every position stands with one at the same offset in the tile, edges with themselves
    assert all(a.sim[a.rep[i]] % k == i % k or not a.banded for i in range(n))
    assert all(a.sim[a.rep[i]] == i for i in list(range(min(k, n))) + list(range(max(n - k, 0), n)))


def test_a_layout_is_periodic_only_when_it_fills_a_lattice_once():
    grid = np.array([[r, c] for r in range(1, 20, 3) for c in range(2, 30, 4)])
    (r0, pr, nr), (c0, pc, nc), ids = lattice(grid)
    assert (r0, pr, nr, c0, pc, nc) == (1, 3, 7, 2, 4, 7)
    assert sorted(ids.ravel()) == list(range(len(grid)))
    assert lattice(grid[:-1]) is None  # a node empty
    assert lattice(np.vstack([grid[:-1], grid[:1]])) is None  # a node twice, another empty
    assert lattice(np.array([[0, 0], [0, 1], [0, 3]])) is None  # uneven steps


def _plan(nr: int, nc: int, k: int) -> TilePlan:
    ids = np.arange(nr * nc).reshape(nr, nc)
    return TilePlan(axis_plan(0, 2, nr, k), axis_plan(0, 2, nc, k), ids, None)


def test_tile_coupling_is_the_arrays_columns_summed_by_stand_in(monkeypatch):
    """The obvious reference: the whole array's (pixels of the sites) × sites matrix from the
    lattice kernel, its rows at the simulated sites, its columns summed by stand-in."""
    plan, reach = _plan(11, 13, 3), 5
    d = np.arange(-reach, reach + 1)
    lat = np.exp(-np.hypot(*np.meshgrid(d, d, indexing="ij")))  # any kernel, 11 × 11
    full = np.zeros((11 * 13, 11 * 13))
    for a in range(11 * 13):
        for b in range(11 * 13):
            (ia, ja), (ib, jb) = divmod(a, 13), divmod(b, 13)
            if abs(ia - ib) <= reach and abs(ja - jb) <= reach:
                full[a, b] = lat[ia - ib + reach, ja - jb + reach]
    sim = (plan.rows.sim[:, None] * 13 + plan.cols.sim[None, :]).ravel()
    stand_in = (plan.rows.rep[:, None] * len(plan.cols.sim) + plan.cols.rep[None, :]).ravel()
    want = np.zeros((plan.n_simulated, plan.n_simulated))
    np.add.at(want.T, stand_in, full[sim].T)
    got = tile.tile_coupling(plan, lat)
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=0)
    np.testing.assert_allclose(got.sum(axis=1), full[sim].sum(axis=1), rtol=1e-13)
    monkeypatch.setattr(limits, "coupling_is_dense", lambda *_: False)  # a large tile: sparse
    np.testing.assert_allclose(tile.tile_coupling(plan, lat).toarray(), want, rtol=1e-13, atol=0)


def test_the_mirrored_kernel_is_the_whole_grids():
    """One quadrant mirrored (the tile's kernel) against the whole (2R + 1)² grid, on the
    flow cell of pyro_array_256 cut to 8 × 8 pixels (the kernel grows to the array)."""
    s = load_scenario(ARRAY, ["chip.rows=8", "chip.cols=8", "sites.at_pixels=[[2, 2]]",
                              *SMALL[3:6]])
    (whole, r_whole), (mirrored, r_mirrored) = (stages.coupling_kernel(s, m) for m in (0, 1))
    assert r_whole == r_mirrored == 8
    np.testing.assert_allclose(mirrored, whole, rtol=1e-12, atol=1e-18)


def test_light_error_is_zero_where_the_tile_is_as_wide_as_the_reach_and_stated_beyond():
    d = np.arange(-3, 4)
    lat = np.exp(-np.hypot(*np.meshgrid(d, d, indexing="ij")))
    assert tile.light_error(_plan(20, 20, 3), lat)["max"] < 1e-12  # reach 3 sites, tiles of 3
    wide = tile.light_error(_plan(20, 20, 2), lat)  # reach 3 sites, tiles of 2: a middle site
    assert 1e-3 < wide["max"] < 0.2  # near an edge misses a row of neighbours its stand-in has


def test_weighted_figures_are_those_of_each_site_repeated_by_its_weight():
    rng = np.random.default_rng(7)
    x, w = rng.gamma(2.0, 3.0, 40), rng.integers(1, 9, 40).astype(float)
    rep = np.repeat(x, w.astype(int))
    mean, se = tile.weighted_mean(x, w)
    assert mean == pytest.approx(rep.mean(), rel=1e-12)
    q = (0, 5, 25, 50, 75, 95, 100)
    np.testing.assert_array_equal(tile.weighted_percentiles(x, w, q),
                                  np.percentile(rep, q, method="inverted_cdf"))
    # equal weights: the standard error of a plain mean
    assert tile.weighted_mean(x, np.ones(40))[1] == pytest.approx(x.std(ddof=1) / np.sqrt(40))
    assert se > x.std(ddof=1) / np.sqrt(40)  # unequal weights: fewer effective sites


@pytest.mark.parametrize("value, says", [
    ("30", "multiple of the site pitch"), ("\"half\"", "\"off\", \"auto\""),
    ("4096", "nothing to save"), ("0", "[1, 4096]"),
])
def test_a_bad_tile_exits_2_naming_the_key(value, says, capsys):
    assert main(["validate", str(ARRAY), "--set", f"run.tile={value}"]) == 2
    err = capsys.readouterr().err
    # the file is named where the key came from: here the --set that gave the value
    assert f"--set run.tile={value}: run.tile = " in err and says in err


def test_a_tile_on_a_layout_that_is_not_periodic_is_refused_and_auto_runs_whole():
    one = ["chip.rows=16", "chip.cols=16", "sites.at_pixels=[[2, 2], [2, 6], [10, 14]]",
           *SMALL[3:6]]
    with pytest.raises(ScenarioError, match=r"run\.tile.*not periodic"):
        load_scenario(ARRAY, [*one, "run.tile=8"])
    s = load_scenario(ARRAY, [*one, *EXACT, "run.tile=\"auto\""])
    assert tile.tile(s).plan is None
    r = run(s)
    assert r.summary["tiled"]["applies"] is False
    assert "not periodic" in r.summary["tiled"]["reason"]
    assert r.summary["array"]["n_sites"] == 3


def test_the_estimate_counts_the_simulated_sites_only():
    s = load_scenario(ARRAY, ["run.tile=32"])
    t = simulated_scenario(s)
    assert (t.chip.rows, t.chip.cols) == (24, 24) and t.sites.at_pixels == "all"
    assert simulated_scenario(replace(s, run=replace(s.run, tile="off"))) is not t


def test_an_array_too_large_to_run_whole_may_run_tiled(monkeypatch):
    """The memory budget is taken on what a run simulates: at a 1 GiB budget pyro_array_256 is
    refused whole (≈ 6.3 GiB) and accepted tiled."""
    monkeypatch.setenv("CHIPTWIN_MEMORY_BUDGET_GIB", "1")
    with pytest.raises(ScenarioError, match="above the 1 GiB budget"):
        load_scenario(ARRAY)
    assert load_scenario(ARRAY, ["run.tile=\"auto\""]).run.tile == "auto"


def test_at_the_expected_level_every_simulated_site_reads_the_whole_arrays_figures(monkeypatch):
    """Nothing is drawn, so the tile's sites must read what the same sites of the whole array
    read: the light on their pixels is the array's (every neighbour within reach). The small
    array's coupling is dense, every share kept; the tile's kernel drops the shares below
    ``COUPLING_DROP_RTOL`` of the own pixel's (as a large array's sparse coupling does: ≤ 256
    sites × 1e-6 of a site's light), so the drop is set to 0 here and the figures agree to
    rounding."""
    monkeypatch.setattr(limits, "COUPLING_DROP_RTOL", 0.0)
    whole = run(load_scenario(ARRAY, [*SMALL, *EXACT]))
    tiled = run(load_scenario(ARRAY, [*SMALL, *EXACT, "run.tile=16"]))
    section = tiled.summary["tiled"]
    assert section["applies"] and section["note"] == "tiled: 144 of 256 sites simulated"
    by_id = {x["id"]: x for x in whole.summary["sites"]}
    for site in tiled.summary["sites"]:
        ref = by_id[site["id"]]
        assert site["pixel"] == ref["pixel"]
        for key in ("signal_e", "noise_e", "snr_power"):
            assert site[key] == pytest.approx(ref[key], rel=1e-12), key
    assert sum(x["weight"] for x in tiled.summary["sites"]) == 256
    assert tiled.summary["chip"]["adc_power_w"] == whole.summary["chip"]["adc_power_w"]
    if "cost" in whole.summary:  # the whole array's silicon
        assert tiled.summary["cost"]["area_mm2"] == whole.summary["cost"]["area_mm2"]
    assert tiled.summary["optics"]["own_pixel"] == whole.summary["optics"]["own_pixel"]
    # the reach (the whole 64-pixel array without the drop) is wider than the 16-pixel tile:
    # the stand-ins' light is off, by what the section states
    assert 0 < section["light_error_rel"]["max"] < 0.01


def test_tiled_pyro_array_256_agrees_with_the_whole_array_within_monte_carlo():
    """Validation against the twin's own whole-array run of ``pyro_array_256`` (same seed):
    each figure within 3 standard errors of the difference (module docstring)."""
    whole = run(ARRAY)
    tiled = run(load_scenario(ARRAY, ["run.tile=\"auto\""]))
    assert tiled.summary["tiled"]["note"] == "tiled: 576 of 4096 sites simulated"
    w = np.ones(len(whole.summary["sites"]))
    right = np.array([c == whole.summary["true_sequence"]
                      for c in whole.summary["called_sequences"]], dtype=float)
    columns = {"fraction_called_right": right,
               "fraction_detected": np.array([x["detected"] for x in whole.summary["sites"]],
                                             dtype=float),
               "snr_power_mean": np.array([x["snr_power"] for x in whole.summary["sites"]])}
    bias = 2 * tiled.summary["tiled"]["light_error_rel"]["max"]
    for name, x in columns.items():
        full, full_se = tile.weighted_mean(x, w)
        assert full == pytest.approx(whole.summary["array"][name], rel=1e-12)
        got = tiled.summary["array"][name]
        se = np.hypot(tiled.summary["array"]["standard_error"][name], full_se)
        assert abs(got - full) <= 3 * se + bias * abs(full), (name, got, full, se)


def test_a_study_replicate_on_a_tiled_scene_is_the_run_at_its_seed():
    from chiptwin.twin.runner import run_prepared

    s = load_scenario(ARRAY, [*SMALL, "run.tile=16", "chip.fixed_pattern_seed=7"])  # one chip
    scene = prepare(s)
    other = replace(s, scenario=replace(s.scenario, seed=s.scenario.seed + 1))
    a = run_prepared(other, scene).summary
    b = run(other).summary
    assert a["array"] == b["array"]
    assert [x["signal_e"] for x in a["sites"]] == [x["signal_e"] for x in b["sites"]]
    assert len(stages.site_pixels(scene.tile.scenario)) == 144
