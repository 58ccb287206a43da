"""The gallery's study captions are made from the studies and the scene they run: the tiny
``adc_bits_pyro`` was captioned "ideal comparator" while it ran the scene's 61 µV comparator.
Builds the study objects only (nothing runs)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

import chiptwin as ct

EXT = Path(__file__).resolve().parents[2] / "docs" / "_ext" / "gallery_runs.py"


@pytest.fixture(scope="module")
def gallery():
    spec = importlib.util.spec_from_file_location("gallery_runs", EXT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_adc_caption_names_the_comparator_the_scene_runs(gallery):
    comparator = ct.load_scenario("pyro_1fmol").chip.adc.comparator_noise_uV
    assert comparator > 0  # the reference chip as built: a noisy comparator
    caption = gallery.study_command("adc_bits_pyro")
    flat = " ".join(caption.replace("#", " ").split())
    assert f"chip.adc.comparator_noise_uV = {comparator} (the scene's" in flat
    assert "ideal" not in flat
    assert flat.startswith("chiptwin study adc_bits_pyro 5,760 runs")  # 64 points × 90


@pytest.mark.parametrize("name", ["adc_bits_pyro", "frame_memory", "lod_pyro",
                                  "read_length_pyro"])
def test_every_caption_states_the_tiny_studys_axes_and_replicates(gallery, name):
    tiny, full = gallery.tiny_study(name), gallery.full_study(name)
    flat = " ".join(gallery.tiny_changes(name).split())
    for axis in tiny.axes:
        assert axis.key in flat
    for key in {a.key for a in full.axes} - {a.key for a in tiny.axes}:
        assert f"{key} = " in flat and "(the scene's" in flat  # the value it ran, not a word
    if tiny.replicates != full.replicates:
        assert f"{tiny.replicates} replicate" in flat
