"""Shared fixtures: the repository's scenario folder and a small, fast scenario."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

SMALL = """
[scenario]
name = "small"
seed = 7

[assay]
kind = "pyrosequencing"
template = "TCAGGTTCCA"
n_flows = 14
flow_period_s = 20.0
start_s = 4.0
k_a_per_s = 0.25
photons_per_incorporation = 0.01

[sites]
at_pixels = [[1, 1], [2, 4]]

[chip]
rows = 4
cols = 6

[chip.dsp]
n_dark_frames = 4
cms_samples = 2
average_frames = 4

[run]
duration_s = 284.0
"""


@pytest.fixture
def small_toml(tmp_path: Path) -> Path:
    """A 4 × 6 chip sequencing a 10-base template in 14 short flows: runs in well under a second."""
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


#: ``--set`` keys that make a bundled scenario small: the same physics, fewer frames (and
#: pixels), so a test can run every bundled scenario in seconds.
REDUCED = {
    "pyro_1fmol": ["assay.n_flows=8", "run.duration_s=500.0"],
    "ccd_100fmol": ["assay.n_flows=8", "run.duration_s=496.0"],
    "pyro_array_256": ["assay.n_flows=8", "run.duration_s=500.0", "chip.rows=8", "chip.cols=8",
                       "sites.at_pixels=[[2, 2], [2, 6], [6, 2], [6, 6]]"],
    "pyro_paper_yield": ["assay.n_flows=8", "run.duration_s=500.0"],
    "pyro_paper_yield_fast": ["assay.n_flows=8", "assay.flow_period_s=4.0",
                              "run.duration_s=34.0"],
}
