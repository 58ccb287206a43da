"""The IEEE 1241 ADC bench on the twin's own converters (chiptwin.characterize.adc1241.bench,
``chiptwin characterize SCENARIO --adc``): round trips against what the twin built.

The truth is the converter a run of the scenario converts with (``chip_sensor(s).converter``),
or the table file injected, turned into transition levels in volts here by the converter's
definition (``pixel/converter.py``: level L of converter i is crossed at
``v_min + ((L − offset_i)/gain_i − offset_lsb)/(1 + gain_error)·LSB``), not by the bench's code.
Statistical checks use the bench's stated standard errors: per code |error| ≤ 4σ and at least
90 % of the codes within 2σ. Small converters (8–10 bits) keep the file under a minute.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from chiptwin.characterize.adc1241.bench import (
    BenchSettings,
    adc_bench,
    pick_converters,
    sub_converter,
)
from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.config.catalog import resolve_scenario
from chiptwin.twin.runner import chip_sensor
from tests.conftest import IDEAL_ADC


def scenario(*sets: str, seed: int | None = None):
    """pyro_1fmol on the ideal converter, plus ``sets``: each test injects its own effects."""
    return load_scenario(resolve_scenario("pyro_1fmol"), IDEAL_ADC + list(sets), seed)


def cli(tmp_path, name, *extra):
    out = tmp_path / name
    argv = ["characterize", "pyro_1fmol", "--adc", "--quiet", "--out", str(out)]
    for s in IDEAL_ADC + list(extra):
        argv += ["--set", s] if "=" in s and not s.startswith("-") else [s]
    assert main(argv) == 0
    return out


def injected_levels(bits: int, rng) -> np.ndarray:
    """Transition levels (LSB, level k between codes k and k + 1): random code widths
    1 + 0.2·z (≥ 0.3 LSB), code 77 missing (width 0), a 1.5 LSB quadratic bow."""
    n = 2**bits
    w = np.clip(1.0 + 0.2 * rng.standard_normal(n - 2), 0.3, None)
    w[77 - 1] = 0.0
    t = 0.5 + np.concatenate([[0.0], np.cumsum(w)]) * (n - 2) / w.sum()
    u = (t - 0.5) / (n - 2)
    return t + 1.5 * 4 * u * (1 - u)


def test_injected_table_and_noise_round_trip(tmp_path):
    """An 8-bit table file (0.2 LSB rms DNL, code 77 missing, 1.5 LSB bow; ``inl_shape =
    "table"``) with 0.3 LSB comparator noise, through the CLI: every transition level T[k]
    and every DNL within 4 stated σ of the table's, ≥ 90 % of DNLs within 2σ, code 77 the only
    missing code, the bow seen as end-point INL (peak 1.5 LSB within 4σ + the DNL's walk)."""
    bits = 8
    levels = injected_levels(bits, np.random.default_rng(3))
    table = tmp_path / "levels.txt"
    table.write_text("\n".join(f"{v:.12f}" for v in levels))
    out = cli(tmp_path, "o", f"chip.adc.bits={bits}", "chip.adc.inl_shape=table",
              f"chip.adc.inl_table={table}", "chip.adc.comparator_noise_lsb=0.3",
              "--adc-converters", "16")
    z = np.load(out / "adc1241.npz")
    q = 1.0 / 2**bits
    t_true = levels * q  # v_min = 0: no mismatch, no offset or gain error
    np.testing.assert_allclose(z["configured_transitions_V"][:, 1:], np.broadcast_to(
        t_true, (16, t_true.size)), atol=1e-12)
    err_t = (z["transitions_V"][:, 1:] - t_true) / z["transitions_sigma_V"][:, 1:]
    assert np.all(np.abs(err_t) <= 4.0)
    dnl_true = np.diff(t_true) / ((t_true[-1] - t_true[0]) / (2**bits - 2)) - 1.0
    zd = (z["dnl_lsb"][:, 1:-1] - dnl_true) / z["dnl_sigma_lsb"][:, 1:-1]
    assert np.all(np.abs(zd) <= 4.0)
    assert np.mean(np.abs(zd) <= 2.0) >= 0.9
    err = z["dnl_lsb"][:, 1:-1] - dnl_true
    assert np.sqrt(np.mean(err**2)) < 0.5 * dnl_true.std()  # measured 0.057 vs 0.21 LSB
    doc = json.loads((out / "adc1241.json").read_text())
    assert doc["worst"]["missing_codes"] == [77]
    assert doc["summary"]["figures"]["missing_codes"]["worst"] == 1
    assert doc["converter_keys"]["inl_shape"] == "table"
    inl_ep = z["inl_endpoint_lsb"][:, 1:]
    k = np.arange(1, 2**bits)
    inl_true = (t_true - t_true[0]) / (t_true[-1] - t_true[0]) * (2**bits - 2) - (k - 1)
    assert np.all(np.abs(inl_ep - inl_true) <= 4 * z["inl_endpoint_sigma_lsb"][:, 1:] + 1e-9)
    assert {p.name for p in out.iterdir()} >= {"adc1241.json", "adc1241.npz", "adc1241.md",
                                                "adc1241_dnl_inl.png", "adc1241_spectrum.png",
                                                "adc1241_histogram.png"}


def test_ideal_converter():
    """Validation (textbook; IEEE Std 1241): the ideal 10-bit converter of the scenario gives
    SINAD = 6.02 N + 1.76 dB within 0.1 dB and ENOB = N within 0.02 bit on every converter;
    every DNL within 4 stated σ of 0 (the histogram test's bound) and below 0.1 LSB; no
    missing code; offset and gain zero within 4σ; transition noise unresolved (no noise)."""
    b = adc_bench(scenario("chip.adc.bits=10"), max_converters=16)
    for f in b.figures:
        assert abs(f["sinad_db"] - (6.02 * 10 + 1.76)) < 0.1
        assert abs(f["enob_bits"] - 10) < 0.02
        assert f["missing_codes"] == 0 and np.isnan(f["transition_noise_lsb"])
        assert abs(f["offset_lsb"]) <= 4 * f["offset_lsb_sigma"]
        assert abs(f["gain_error"]) <= 4 * f["gain_error_sigma"]
    d, s = b.arrays["dnl_lsb"][:, 1:-1], b.arrays["dnl_sigma_lsb"][:, 1:-1]
    assert np.all(np.abs(d) <= 4 * s) and np.abs(d).max() < 0.1


def test_comparator_noise_as_transition_noise():
    """Comparator noise 0.5 LSB (10 bits, nothing else): each converter's transition noise
    within 4 of its stated σ of 0.5 LSB, and the mean over 16 converters within 4 σ/√16."""
    b = adc_bench(scenario("chip.adc.bits=10", "chip.adc.comparator_noise_lsb=0.5"),
                  max_converters=16)
    tn = np.array([f["transition_noise_lsb"] for f in b.figures])
    sig = np.array([f["transition_noise_lsb_sigma"] for f in b.figures])
    assert np.all(np.abs(tn - 0.5) <= 4 * sig)
    assert abs(tn.mean() - 0.5) <= 4 * np.sqrt(np.mean(sig**2) / tn.size)
    assert b.to_json()["bench"]["transition_noise"]["transitions_resolved_median"] >= 4


def test_mismatch_recovered():
    """Per-converter offset (2 LSB rms) and gain (1 % rms) mismatch with 0.2 LSB comparator
    noise, 9 bits, a grid of 32 of the 128 converters: each converter's offset and gain error
    (independently based) within 4 stated σ and within 0.05 LSB / 2e-4 of the twin's
    pixel_offset_lsb and pixel_gain − 1 at that pixel (the deterministic ramp is far better
    than its binomial σ); the mismatch is really there (spread > 1 LSB)."""
    s = scenario("chip.adc.bits=9", "chip.adc.offset_sigma_lsb=2", "chip.adc.gain_sigma=0.01",
                 "chip.adc.comparator_noise_lsb=0.2")
    b = adc_bench(s, max_converters=32)
    conv = chip_sensor(s).converter
    off_true = np.asarray(conv.pixel_offset_lsb)[b.pixels]
    gain_true = np.asarray(conv.pixel_gain)[b.pixels] - 1.0
    off = np.array([f["offset_lsb"] for f in b.figures])
    gain = np.array([f["gain_error"] for f in b.figures])
    assert np.all(np.abs(off - off_true) <= 4 * np.array([f["offset_lsb_sigma"]
                                                          for f in b.figures]))
    assert np.all(np.abs(gain - gain_true) <= 4 * np.array([f["gain_error_sigma"]
                                                            for f in b.figures]))
    assert np.abs(off - off_true).max() < 0.05 and np.abs(gain - gain_true).max() < 2e-4
    assert off_true.std() > 1.0 and b.pixels.size == 32


def test_same_seed_same_json(tmp_path):
    """Same scenario and seed: byte-identical adc1241.json and equal npz arrays; another
    seed (comparator noise drawn from stage_rng(seed, "characterize.adc")) differs."""
    sets = ("chip.adc.bits=8", "chip.adc.comparator_noise_lsb=0.5", "chip.adc.dnl_rms_lsb=0.1",
            "--adc-converters", "8")
    a, b = cli(tmp_path, "a", *sets), cli(tmp_path, "b", *sets)
    c = cli(tmp_path, "c", *sets, "--seed", "5")
    assert (a / "adc1241.json").read_bytes() == (b / "adc1241.json").read_bytes()
    za, zb = np.load(a / "adc1241.npz"), np.load(b / "adc1241.npz")
    assert all(np.array_equal(za[k], zb[k], equal_nan=True) for k in za.files)
    assert (a / "adc1241.json").read_bytes() != (c / "adc1241.json").read_bytes()


def test_reference_chip_seconds():
    """The reference chip's converters made ideal (pyro_1fmol: 128 converters, 13 bits): the
    whole bench (8 × 10^5 ramp samples per converter for 0.1 LSB DNL σ; about 4 s measured on a
    loaded machine), SINAD 80.0 dB = 6.02·13 + 1.76 within 0.1 dB, no missing code, all 128
    converters measured."""
    b = adc_bench(scenario())
    doc = b.to_json()
    assert doc["bench"]["converters_measured"] == 128 and doc["bench"]["subset"] == "all"
    assert abs(doc["summary"]["figures"]["sinad_db"]["worst"] - (6.02 * 13 + 1.76)) < 0.1
    assert doc["summary"]["figures"]["missing_codes"]["worst"] == 0


def test_refused_named(tmp_path, capsys):
    """What cannot fit is refused with exit 2 naming the flag or key: a DNL σ of 0.002 LSB at
    13 bits (over 10^10 conversions), 0 converters, 3 bits."""
    out = str(tmp_path / "x")
    assert main(["characterize", "pyro_1fmol", "--adc", "--adc-dnl-sigma", "0.002", "--quiet",
                 "--out", out]) == 2
    assert "--adc-dnl-sigma" in capsys.readouterr().err
    assert main(["characterize", "pyro_1fmol", "--adc", "--adc-converters", "0", "--quiet",
                 "--out", out]) == 2
    assert "--adc-converters" in capsys.readouterr().err
    assert main(["characterize", "pyro_1fmol", "--adc", "--set", "chip.adc.bits=3", "--set",
                 "chip.adc.range_below_full_well_ok=true", "--quiet", "--out", out]) == 2
    assert "chip.adc.bits" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
    with pytest.raises(ValueError, match="fit_samples"):
        BenchSettings(fit_samples=10)


def test_subset_grid_and_sub_converter():
    """A 256 × 256 array with max 256: a 16 × 16 grid, both ends of rows and columns
    included (so 16 column ramps are sampled); a sub-converter gives, for the same volts,
    the codes of the whole chip's converters at those pixels (DNL per column ramp, mismatch,
    INL; no noise)."""
    idx = pick_converters((256, 256), 256)
    rows, cols = np.unique(idx // 256), np.unique(idx % 256)
    assert idx.size == 256 and rows.size == cols.size == 16
    assert rows[[0, -1]].tolist() == cols[[0, -1]].tolist() == [0, 255]
    s = scenario("chip.adc.bits=8", "chip.adc.ramp=column", "chip.adc.dnl_rms_lsb=0.3",
                 "chip.adc.inl_max_lsb=1", "chip.adc.offset_sigma_lsb=1",
                 "chip.adc.gain_sigma=0.01")
    conv = chip_sensor(s).converter
    pix = pick_converters((8, 16), 12)
    sub, table = sub_converter(conv, pix)
    v = np.linspace(-0.01, 1.01, 3000)
    full = conv.convert(np.broadcast_to(v[:, None, None], (v.size, 8, 16))).reshape(v.size, -1)
    part = sub.convert(np.broadcast_to(v[:, None], (v.size, pix.size)))
    assert np.array_equal(part, full[:, pix])
    assert np.array_equal(table, pix % 16)  # column ramps
