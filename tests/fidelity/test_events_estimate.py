"""The events level draws ``binned``'s counts and times only the windows whose well fills: the
codes are binned's bit for bit, and the wall-time estimate charges the filled windows the run
meets (the closed forms' typical light against the run's own)."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.config import cost, load_scenario
from chiptwin.fidelity import run
from chiptwin.fidelity.ladder import reference_levels, with_levels
from tests.conftest import SCENARIOS

BRIGHT = ["assay.n_flows=8", "run.duration_s=500"]


@pytest.mark.parametrize(("dna_fmol", "lo", "hi"), [(30.0, 0, 0), (300.0, 90, 360)])
def test_estimated_filled_windows_are_the_runs(dna_fmol, lo, hi):
    """pyro_1fmol at 30 fmol: no well fills, in the run or the estimate; at 300 fmol the run
    fills 180 site-pixel windows (seed 1) and the estimate counts within a factor 2 of that."""
    s = with_levels(load_scenario(SCENARIOS / "pyro_1fmol.toml",
                                  [f"assay.dna_fmol={dna_fmol}", *BRIGHT]), {"photons": "events"})
    filled = sum(site["saturated_frames"] for site in run(s).summary["sites"])
    e = cost.window_electrons(s, cost.n_frames(s)) / cost.n_sites(s)
    estimated = int(np.sum(e >= s.chip.pixel.full_well_e)) * cost.n_sites(s)
    assert lo <= filled <= hi
    assert (estimated == 0) == (filled == 0)
    assert filled == 0 or 0.5 <= estimated / filled <= 2.0, (estimated, filled)


def test_ccd_two_wells_reference_reads_binned_codes_at_binned_cost():
    """ccd_two_wells at its reference levels (cascade, events, psf, poisson, as built; DSP
    fixed): the same codes and figures as binned on the same seed (the events level reports
    binned's counts and only times the wells), and an estimate within 10 % of binned's. Drawing
    every arrival over the cascade once took minutes and 5 GB a run here."""
    s = load_scenario(SCENARIOS / "ccd_two_wells.toml")
    ref = {**reference_levels(s), "dsp": "fixed"}
    results = {}
    for level in ("binned", "events"):
        sv = with_levels(s, {**ref, "photons": level})
        results[level] = run(sv, seed=3)
    b, e = (results[k] for k in ("binned", "events"))
    assert [x["signal_e"] for x in b.summary["sites"]] == [x["signal_e"]
                                                          for x in e.summary["sites"]]
    for name, arr in b.arrays.items():
        assert np.array_equal(arr, e.arrays[name], equal_nan=True), name
    wb, we = (cost.wall_seconds(with_levels(s, {**ref, "photons": lv}))
              for lv in ("binned", "events"))
    assert wb <= we <= 1.1 * wb
