"""A small study over the suite's small scenario (4 × 6 chip, 14 flows): fast to run whole."""

from __future__ import annotations

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
