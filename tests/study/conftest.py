"""A small study over the suite's small scenario (4 × 6 chip, 14 flows): fast to run whole."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from tests.conftest import SMALL

STUDY = """
[study]
name = "small_study"
scenario = "small.toml"
seed = 11
replicates = 3
reference = { "chip.adc.bits" = 14 }

[[study.axis]]
key = "chip.adc.bits"
values = [6, 8, 10]

[[study.metric]]
name = "calls_correct"

[[study.metric]]
name = "base_error_rate"

[[study.metric]]
name = "snr_loss_db"

[[study.metric]]
name = "memory_peak_frames"

[study.requirement]
base_error_rate = "<= 0.2"
confidence = 0.9
"""


def write_study(folder: Path, text: str = STUDY) -> Path:
    """The small scenario and a study of it, side by side in ``folder``."""
    (folder / "small.toml").write_text(SMALL)
    path = folder / "study.toml"
    path.write_text(text)
    return path


@pytest.fixture
def small_study(tmp_path: Path) -> Path:
    return write_study(tmp_path)


def comparable(table: list[dict]) -> list[tuple]:
    """A runs table without wall times, in (point, replicate) order: what must match exactly."""
    return sorted((r["point"], r["kind"], r["replicate"], r["seed"], repr(r["params"]),
                   repr(r["metrics"]), r["status"], r["message"]) for r in table)


# --- the bundled studies, shrunk ------------------------------------------------------------------

#: ``set`` keys that cut a pyro_1fmol study row to its first 8 flows (500 frames instead of
#: 1,520). The key TCAG's four 1-mers are flows 1, 3, 6 and 8 of TACG, and a site's power SNR is
#: read from those flows only (``twin.results._pyro_sites``); the chip's schedule, memory and
#: random streams of the first 500 frames are those of the whole run. So ``snr_power``,
#: ``frames_dropped``, ``memory_peak_frames`` and ``results_valid`` are the whole run's, bit for
#: bit (``test_bundled.test_eight_flows_give_the_rows_of_the_whole_run`` checks it), and a
#: metric that needs the whole read (``calls_correct``, ``base_error_rate``) is not asked of them.
KEY_FLOWS = {"assay.n_flows": 8, "run.duration_s": 500.0}


def bundled_study(name: str, edit):
    """The bundled study ``name`` with its ``[study]`` table edited in place by ``edit``."""
    from chiptwin.cli import bundled_studies, resolve_scenario
    from chiptwin.study.spec import study_from_dict

    path = bundled_studies()[name]
    raw = tomllib.loads(path.read_text())
    edit(raw["study"])
    return study_from_dict(raw, str(path), None, path.parent, resolve_scenario)


def _frame_memory(st: dict) -> None:
    """Every point of the bundled grid (5 memories × 3 N × 2 K), 2 replicates, 8 flows.

    frames_dropped and memory_peak_frames are the chip's schedule, the same in every replicate;
    the SNR loss decides the rest with a wide margin. Its standard error at n = 2 is ≤ 0.04 dB
    with 4 dark frames (loss ≈ 5.0 dB) and ≈ 0.016 dB with 16 (loss ≈ 0.0 dB); the one-sided
    95 % bound, t(0.95, 1) = 6.31 standard errors out, measured 4.76 dB at the lowest (K = 4)
    and 0.09 dB at the highest (K = 16): each side of 0.5 dB by > 25 standard errors. (At the
    bundled 4 replicates the bounds were within 0.03 dB of the same losses.)"""
    st["replicates"] = 2
    st.setdefault("set", {}).update(KEY_FLOWS)


@pytest.fixture(scope="session")
def frame_memory_result():
    """The bundled frame_memory study (its whole grid) run once in this process, shared by the
    answer test (test_bundled) and the report test (test_outputs)."""
    from chiptwin.study import run_study

    return run_study(bundled_study("frame_memory", _frame_memory), workers=1)
