"""The measured flow-value profiles and the chemistry presets against them
(chiptwin.report.flow_profile, ``chiptwin reads profile``)."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.config import ScenarioError
from chiptwin.kinetics.chemistry import N_BINS
from chiptwin.kinetics.chemistry_fit import histograms, model_distributions, total_variation
from chiptwin.kinetics.chemistry_presets import PRESETS
from chiptwin.report.flow_profile import (
    LENGTHS,
    PROFILE_LENGTHS,
    between_454,
    measured_values,
    read_profile,
)
from tests.conftest import real_data, require_module


def _write_profile(path, nlp: np.ndarray) -> None:
    """A profile file: per length a header line, then −ln P per bin."""
    lines = []
    for h in range(PROFILE_LENGTHS):
        lines.append(f"{h}.0")
        lines += [repr(float(v)) for v in nlp[h]]
    path.write_text("\n".join(lines) + "\n")


def test_profile_reader_normalises_each_length(tmp_path):
    """A hand-made file: row h puts 3/4 of its mass on bin 100·h and 1/4 on the next, stored
    unnormalised (×2, as −ln P − ln 2) with the other bins at −ln P = 50: read back as those
    probabilities, each row summing to 1."""
    nlp = np.full((PROFILE_LENGTHS, N_BINS), 50.0)
    for h in range(PROFILE_LENGTHS):
        nlp[h, 100 * h] = -np.log(2 * 0.75)
        nlp[h, 100 * h + 1] = -np.log(2 * 0.25)
    _write_profile(tmp_path / "p.dat", nlp)
    p = read_profile(tmp_path / "p.dat")
    assert p.shape == (PROFILE_LENGTHS, N_BINS)
    assert np.allclose(p.sum(axis=1), 1.0)
    for h in range(PROFILE_LENGTHS):
        assert p[h, 100 * h] == pytest.approx(0.75, rel=1e-9)
        assert p[h, 100 * h + 1] == pytest.approx(0.25, rel=1e-9)


def test_profile_reader_refuses_a_short_file_and_names_a_bad_line(tmp_path):
    bad = tmp_path / "short.dat"
    bad.write_text("0\n1\n2\n")
    with pytest.raises(ScenarioError, match="must be 10010"):
        read_profile(bad)
    nlp = np.ones((PROFILE_LENGTHS, N_BINS))
    _write_profile(tmp_path / "x.dat", nlp)
    text = (tmp_path / "x.dat").read_text().split("\n")
    text[5] = "oops"
    (tmp_path / "x.dat").write_text("\n".join(text))
    with pytest.raises(ScenarioError, match="line 6"):
        read_profile(tmp_path / "x.dat")


#: The FLX preset's distance to the FLX profile per length 0–5 when it was fitted (TV, 0.01
#: bins: 0.072, 0.068, 0.077, 0.094, 0.078, 0.111); a change of the model or of the preset
#: that moves one by more than this fails.
FLX_TV = (0.072, 0.068, 0.077, 0.094, 0.078, 0.111)
TIT_TV = (0.056, 0.071, 0.044, 0.063, 0.050, 0.099)
TV_TOLERANCE = 0.005


def test_flx_preset_is_closer_to_flx_than_titanium_is():
    """Validation against the 454 GS FLX flow-value profile (PyroNoise, Quince et al., Nature
    Methods 6:639, 2009; qiime denoiser, Reeder & Knight, Nature Methods 7:668, 2010): the
    ``454_flx`` preset's law at the detection level is within :data:`TV_TOLERANCE` of its
    fitted distances, and closer to FLX than the Titanium profile is, at every length 0–5
    (FLX vs Titanium: 0.257, 0.100, 0.097, 0.145, 0.176, 0.165)."""
    flx = read_profile(real_data("flow_profiles", "FLX_error_profile.dat"))
    tit = read_profile(real_data("flow_profiles", "Titanium_error_profile.dat"))
    between = between_454(flx, tit)
    for chem, profile, stated in (("454_flx", flx, FLX_TV), ("454_titanium", tit, TIT_TV)):
        law = model_distributions(PRESETS[chem], list(range(6)))
        for h in range(6):
            tv = total_variation(profile[h], law[h])
            assert tv == pytest.approx(stated[h], abs=TV_TOLERANCE), (chem, h)
            if chem == "454_flx":
                assert tv < between[h][1], h


@pytest.mark.slow
def test_ion_preset_against_the_ion_reads():
    """Validation against 449 Ion PGM reads (BioD's b7_295_chunk.bam; Rothberg et al., Nature
    475:348, 2011), their flow values by the true length from the alignment: TV per length
    0–3 within 0.01 of the fitted 0.012, 0.082, 0.077, 0.125 (1,000s of flows each; lengths 4
    and 5 hold 1,169 and 738 flows, whose TV a perfect model leaves near 0.15–0.21)."""
    require_module("pysam")
    y, h = measured_values(real_data("ion", "b7_295_chunk.bam"))
    assert y.size == 254_710
    counts = histograms(y, h, 3)
    law = model_distributions(PRESETS["ion_pgm"], [0, 1, 2, 3])
    for n, stated in enumerate((0.012, 0.082, 0.077, 0.125)):
        assert total_variation(counts[n], law[n]) == pytest.approx(stated, abs=0.01), n


def test_profile_command_refuses_a_folder_without_the_data(tmp_path, capsys):
    """``chiptwin reads profile DATA`` names the missing file and exits 2."""
    from chiptwin.cli import main

    assert main(["reads", "profile", str(tmp_path), "--out", str(tmp_path / "out"),
                 "--quiet"]) == 2
    assert "FLX_error_profile.dat" in capsys.readouterr().err
    assert main(["reads", "profile", str(tmp_path / "nowhere"), "--quiet"]) == 2


def test_flx_sff_run_is_closer_to_the_flx_preset():
    """Cross-check on a 454 GS FLX run without truth (Fasting_Example.sff, 1,339 reads of 16S
    amplicons, qiime's test data; Reeder & Knight, Nature Methods 7:668, 2010): its pooled
    flow values are closer to the FLX preset's mixture than to Titanium's (TV 0.139 against
    0.188 when fitted; each within 0.01)."""
    require_module("Bio", "sff")
    from chiptwin.report.flow_profile import sff_check

    c = sff_check(real_data("sff", "Fasting_Example.sff"), "GS FLX")
    assert c.reads == 1339
    assert c.tv["454_flx"] == pytest.approx(0.139, abs=0.01)
    assert c.tv["454_titanium"] == pytest.approx(0.188, abs=0.01)
    assert c.tv["454_flx"] < c.tv["454_titanium"]


def test_twin_check_reads_the_runs_corrected_values_and_states_the_floor():
    """The check histograms the run's ``read_corrected`` (no read called again), and each
    length's sampling floor is what as many draws of the scene's own model show: positive, and
    larger for the 40 flows of a length than for the hundreds of another."""
    from chiptwin.report.flow_profile_out import TWIN_FLOWS, markdown, summary, twin_check

    flx = model_distributions(PRESETS["454_flx"], list(LENGTHS))
    sets = ("sites.at_pixels=[[4, 8], [2, 3]]", "assay.n_flows=60", "run.duration_s=3620")
    check = twin_check(flx, overrides=sets)
    assert check.reads == 2 and TWIN_FLOWS >= 60
    flows = {row["length"]: row["flows"] for row in check.rows}
    floors = {row["length"]: row["tv_floor"] for row in check.rows}
    assert sum(flows.values()) == 2 * 60  # every flow: the template's runs are ≤ 5
    assert all(check.values[n].sum() == flows[n] for n in flows)
    few, many = min(flows, key=flows.get), max(flows, key=flows.get)
    assert 0 < floors[many] < floors[few] <= 1
    text = markdown(summary([], [], [check]))
    assert "TV floor" in text and f"{floors[many]:.4g}" in text
