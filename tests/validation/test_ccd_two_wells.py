"""ccd_two_wells (paper Fig. 12, Section 4): line binning, the 8-tap low-pass FIR and the PSF
equalization separate two adjacent 0.1 pmol wells whose images overlap on the CCD.

Fig. 12 shows it qualitatively: before processing the two wells' column profile is one merged
hump with a shallow dip; after it, two distinct peaks. Stated thresholds: before, the dip between
the wells stays above half the peaks (valley/peak > 0.5: merged); after, it falls by more than
0.5 and below 0.1 of the peaks (resolved), both in the measured profile (one seeded run) and in
the expected one, and the measured profile follows the expected within 1 % of its peak.
"""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.fidelity import run
from tests.conftest import SCENARIOS


@pytest.fixture(scope="module")
def result():
    return run(SCENARIOS / "ccd_two_wells.toml")


@pytest.mark.parametrize("kind", ["", "_expected"])
def test_processing_separates_the_two_wells(result, kind):
    p = result.summary["column_profile"]
    before, after = p[f"valley_to_peak_before{kind}"], p[f"valley_to_peak_after{kind}"]
    assert before > 0.5
    assert after < 0.1 and before - after > 0.5


def test_profiles_are_column_profiles_of_the_wells(result):
    a = result.arrays
    assert a["column_profile_before_e"].shape == (1, 64)  # every row binned: one profile
    for name in ("before", "after"):
        v, e = a[f"column_profile_{name}_e"][0], a[f"column_profile_{name}_expected_e"][0]
        assert np.max(np.abs(v - e)) < 0.01 * np.max(e)
        assert set(np.argsort(e)[-2:]) <= {26, 27, 28, 36, 37, 38}  # the peaks at the wells
    assert result.summary["results_valid"]
    assert result.summary["dsp"]["overflow_total"] == {"sat": 0, "wrap": 0}
