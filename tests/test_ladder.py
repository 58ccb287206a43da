"""The fidelity ladder measures each level's error against the reference; where the error is
known analytically the ladder finds it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from chiptwin.config import ScenarioError, load_scenario
from chiptwin.fidelity.ladder import (
    pareto,
    plan,
    reference_levels,
    run_ladder,
    with_levels,
    write_ladder,
)
from chiptwin.twin import stages
from tests.conftest import SCENARIOS

CHEAP_REFERENCE = {"kinetics": "closed_form", "photons": "expected", "optics": "psf",
                   "dsp": "float"}
#: The small scenario's 8 key flows of 4 s (36 frames, not 284): a ladder runs every rung three
#: times (warm-up and two replicates), the cascade rungs at ~10 ms a frame; what these
#: tests check is per frame (errors, common random numbers) or of the optics alone.
SHORT_FLOWS = ["assay.n_flows=8", "assay.flow_period_s=4.0", "run.duration_s=36.0"]


@pytest.fixture(scope="module")
def ladder(tmp_path_factory):
    from tests.conftest import SMALL

    path = tmp_path_factory.mktemp("ladder") / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, SHORT_FLOWS)
    return s, run_ladder(s, replicates=2, reference=CHEAP_REFERENCE)


def test_na2_error_is_the_missing_cross_talk_share(ladder):
    """na2 puts a site's light on its own diode only; psf spreads it. Against the expected-level
    reference the ladder's signal error is exactly max_i |Σ_j C_na2[p_i, j] / Σ_j C_psf[p_i, j]
    − 1| over the site pixels p_i (the coupling matrices' row sums; pure light, dark removed)."""
    s, lad = ladder
    idx = stages.site_pixel_indices(s)
    psf = stages.coupling(with_levels(s, {"optics": "psf"}))[idx].sum(axis=1)
    na2 = stages.coupling(with_levels(s, {"optics": "na2"}))[idx].sum(axis=1)
    analytic = float(np.max(np.abs(na2 / psf - 1)))
    row = next(r for r in lad["rows"] if r["stage"] == "optics" and r["level"] == "na2")
    assert analytic > 1e-6
    assert row["errors"]["signal_rel"]["value"] == pytest.approx(analytic, rel=1e-6)


def test_reference_row_has_zero_error_and_unit_speedup(ladder):
    _, lad = ladder
    ref = lad["rows"][0]
    assert ref["stage"] == "reference" and ref["speedup"] == pytest.approx(1.0)
    assert all(e["value"] == 0 for e in ref["errors"].values())
    timed = [r for r in lad["rows"] if "wall_s" in r]
    assert all(r["wall_s"] > 0 for r in timed)


def test_levels_the_scene_refuses_are_skipped_with_the_reason(ladder):
    _, lad = ladder
    fixed = next(r for r in lad["rows"] if r["stage"] == "dsp" and r["level"] == "fixed")
    assert "no ADC codes" in fixed["skipped"]


def test_reference_is_the_most_faithful_level_the_scene_accepts():
    s = load_scenario(SCENARIOS / "atp_glow.toml")
    ref = reference_levels(s)
    assert ref["kinetics"] == "closed_form"  # the cascade models pyrosequencing only
    assert ref["photons"] == "events" and ref["optics"] == "raytrace"  # isotropic, traced
    assert [r.stage for r in plan(s)][0] == "reference"


def test_outputs_and_pareto_front(ladder, tmp_path):
    _, lad = ladder
    write_ladder(lad, tmp_path / "out")
    saved = json.loads((tmp_path / "out" / "ladder.json").read_text())
    assert saved["rows"][0]["stage"] == "reference"
    assert (tmp_path / "out" / "ladder.png").stat().st_size > 0
    front = pareto(lad["rows"], "snr_rel")
    timed = [i for i, r in enumerate(lad["rows"]) if "wall_s" in r]
    fastest = min(timed, key=lambda i: lad["rows"][i]["wall_s"])
    assert fastest in front and 0 in front  # the fastest, and the zero-error reference


def test_one_replicate_is_refused(ladder):
    s, _ = ladder
    with pytest.raises(ScenarioError, match="--replicates"):
        run_ladder(s, replicates=1)


def test_cli_ladder_writes_its_outputs(tmp_path, capsys):
    from chiptwin.cli import main
    from tests.conftest import SMALL

    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    out = tmp_path / "lad"
    args = ["ladder", str(path), "--out", str(out), "--replicates", "2",
            "--reference", "dsp=fixed", "--reference", "photons=binned",
            "--reference", "kinetics=closed_form"]
    for text in SHORT_FLOWS:
        args += ["--set", text]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "reference" in text and "cheapest" in text
    assert {p.name for p in out.iterdir()} == {"ladder.json", "ladder.png", "ladder.md"}
    for bad in (["--replicates", "1"], ["--reference", "dsp=vhdl"]):
        assert main(["ladder", str(path), "--out", str(tmp_path / "x"), *bad]) == 2
        assert not (tmp_path / "x").exists()


def test_a_scene_with_auto_stages_gets_an_auto_row(tmp_path, monkeypatch):
    """The levels auto picks for the scene's budget are one more rung, with auto's estimate."""
    from chiptwin.fidelity import resolve
    from tests.conftest import SMALL

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, ['run.fidelity.photons="auto"', 'run.fidelity.shot="auto"',
                             "run.error_budget.snr_rel=0.02"])
    last = plan(s)[-1]
    assert last.stage == "auto" and last.fidelity == resolve(s)[1].levels
    assert last.estimate["snr_rel"] <= 0.02


def test_errors_are_ratios_of_means_resolved_or_not(ladder):
    """The reference's own error is 0 and resolved; na2 draws like the reference (common random
    numbers; the expected level draws no photons, the seed changes only the chip's fixed
    pattern), so its SNR error is the ratio of the means with a narrow interval, resolved;
    binned photons draw where the expected reference does not: at 2 seeds (t quantile 12.7) the
    difference is unresolved, the row says how many seeds would resolve it, and the table
    prints that instead of a number."""
    from chiptwin.fidelity.ladder import table

    _, lad = ladder
    rows = {(r["stage"], r["level"]): r for r in lad["rows"] if "errors" in r}
    ref = rows[("reference", lad["rows"][0]["level"])]["errors"]["snr_rel"]
    assert ref["value"] == 0 and ref["resolved"]
    na2 = rows[("optics", "na2")]["errors"]["snr_rel"]
    assert na2["resolved"] and na2["ci"] < 1e-4
    assert na2["method"].startswith("ratio of means")
    binned = rows[("photons", "binned")]["errors"]["snr_rel"]
    assert not binned["resolved"] and binned["seeds_to_resolve"] > 2
    assert f"unres. n≥{binned['seeds_to_resolve']}" in table(lad)
