"""Scenario files: TOML → frozen dataclasses, with strict validation."""

from chiptwin.config.fields import ScenarioError
from chiptwin.config.load import apply_override, load_scenario, scenario_from_dict
from chiptwin.config.schema import (
    Adc,
    Assay,
    Chip,
    Dsp,
    Fidelity,
    Memory,
    Optics,
    Pixel,
    Run,
    Scenario,
    ScenarioMeta,
    Sites,
    Timing,
)

__all__ = [
    "Adc", "Assay", "Chip", "Dsp", "Fidelity", "Memory", "Optics", "Pixel", "Run", "Scenario",
    "ScenarioError", "ScenarioMeta", "Sites", "Timing", "apply_override", "load_scenario",
    "scenario_from_dict",
]
