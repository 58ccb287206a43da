"""Every closed-form assay kind is runnable from a scenario and emits what its equation says.

Salama et al. 2004: substrate detection N(T) = α·N_A·V[S0]·(1 − exp(−k_f[E]T)) (eq. 6); catalyst
detection I = α·N_A·V[E]·k_f·[S_max] (eq. 7), per integration window. Tolerance 1e-9 (the
window integrals are exact).
"""

from __future__ import annotations

import numpy as np

from chiptwin.chip import Schedule
from chiptwin.constants import N_A
from chiptwin.fidelity import run
from tests.conftest import SMALL


def _run(tmp_path, kind: str, assay: str):
    """The small scenario with its ``[assay]`` section replaced, one site, 40 s of light."""
    head, tail = SMALL.split("[assay]")
    tail = tail[tail.index("[sites]"):]
    path = tmp_path / f"{kind}.toml"
    path.write_text(f'{head}[assay]\nkind = "{kind}"\nstart_s = 4.0\n{assay}\n\n{tail}')
    return run(path, ["sites.at_pixels=[[1, 1]]", "run.duration_s=44",
                      "run.fidelity.photons=expected"])


def _windows(result):
    sch = Schedule.from_chip(result.scenario.chip, result.scenario.run.duration_s)
    return np.array([sch.window_s(k) for k in range(sch.n_frames)])


def test_substrate_detection_follows_eq6(tmp_path):
    result = _run(tmp_path, "substrate",
                  "substrate_amol = 2.0\nk_f_per_M_per_s = 1e5\nenzyme_M = 1e-6")
    s, k, start = 2e-18, 1e5 * 1e-6, 4.0
    w = np.clip(_windows(result) - start, 0.0, None)
    # eq. 6 between the window edges: N(t1) − N(t0)
    expected = 0.88 * N_A * s * (np.exp(-k * w[:, 0]) - np.exp(-k * w[:, 1]))
    np.testing.assert_allclose(result.arrays["site_photons"][0], expected, rtol=1e-9, atol=1e-9)


def test_catalyst_detection_follows_eq7(tmp_path):
    result = _run(tmp_path, "catalyst",
                  "enzyme_amol = 0.5\nk_f_per_M_per_s = 1e5\nsubstrate_max_M = 1e-6")
    rate = 0.88 * N_A * 0.5e-18 * 1e5 * 1e-6
    w = np.clip(_windows(result) - 4.0, 0.0, None)
    np.testing.assert_allclose(result.arrays["site_photons"][0], rate * (w[:, 1] - w[:, 0]),
                               rtol=1e-9)
    assert result.summary["sites"][0]["signal_e"] > 0
