"""crosstalk_microarray (paper Fig. 9, Section 3.3): the on-chip Wiener equalizer reduces each
site's cross-talk by what the coupling matrix predicts.

Oracle, computed here from the optics stage alone: the coupling ``C`` of a site above every pixel
(:func:`chiptwin.twin.stages.coupling`), columns normalised to each site's own pixel, the float
Wiener
matrix ``G = (CᵀC + λI)⁻¹Cᵀ`` (Salama et al. 2004, Sec. 3.3); a site's cross-talk is
``Σ_n |A[n, j]| / A[j, j]`` over its 4 neighbours with ``A = C`` before and ``A = G C`` after.
The summary's "after" is measured by pushing each site's light through the chip's fixed-point
equalizer (18-bit coefficients): it must agree with the float prediction within 0.05 dB, and the
reduction must exceed 10 dB (at 150 µm the neighbours' light outweighs the site's own).
"""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.reference import wiener_matrix
from chiptwin.fidelity import run
from chiptwin.twin import stages
from tests.conftest import SCENARIOS


@pytest.fixture(scope="module")
def result():
    return run(SCENARIOS / "crosstalk_microarray.toml")


def _leak_db(a: np.ndarray, rows: int, cols: int, r: int, c: int) -> float:
    j = r * cols + c
    nb = [(r + dr) * cols + c + dc for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1))
          if 0 <= r + dr < rows and 0 <= c + dc < cols]
    return 10 * np.log10(np.abs(a[nb, j]).sum() / a[j, j])


def test_wiener_reduces_crosstalk_as_the_coupling_matrix_predicts(result):
    s = result.scenario
    c = stages.coupling(s)  # sites above every pixel: the PSF sampled on the array
    c = c / np.diag(c)[None, :]
    after = wiener_matrix(c, s.chip.dsp.wiener_noise_to_signal) @ c
    rows, cols = s.chip.rows, s.chip.cols
    x = result.summary["crosstalk"]
    per_before, per_after = x["per_site_before_db"], x["per_site_after_db"]
    reduction = []
    for r in range(rows):
        for col in range(cols):
            j = r * cols + col
            before = _leak_db(c, rows, cols, r, col)
            predicted = _leak_db(after, rows, cols, r, col)
            assert per_before[j] == pytest.approx(before, abs=1e-9)
            assert per_after[j] == pytest.approx(predicted, abs=0.05)
            reduction.append(before - predicted)
    assert x["reduction_db_median"] == pytest.approx(np.median(reduction), abs=0.05)
    assert x["reduction_db_median"] > 10.0
    assert x["before_db_median"] > 0  # excessive cross-talk: the neighbours outweigh the site


def test_equalizing_costs_snr_and_buys_pitch(result):
    """The equalizer amplifies the pixel noise (a positive SNR cost) and resolves neighbours at
    a pitch where the raw image cannot: min pitch with < the chip's 125 µm ≤ without."""
    x = result.summary["crosstalk"]
    assert x["snr_cost_db_median"] > 0
    assert x["min_pitch_um_with"] is not None and x["min_pitch_um_with"] < 125.0
    assert x["min_pitch_um_without"] is None or x["min_pitch_um_without"] > 125.0
    assert result.summary["results_valid"]
    # the equalizer's input frame (128 words of the 23-bit average) and its 128 × 128 table
    assert result.summary["dsp_program"]["memory_bits"]["wiener"] == 128 * 23 + 128**2 * 18
