"""What a chip costs in silicon (:mod:`chiptwin.chip.silicon`) and what a run yields
(:mod:`chiptwin.twin.chip_cost`).

Unit tests of the pure formulas against hand-worked tables; an equivalence test (the converter's
energy is the one ``[chip.adc]`` and ``summary['chip']`` already state); the reference chip's
figures worked by hand from the published numbers the defaults cite; and the throughput figures
from a summary of known counts.
"""

from __future__ import annotations

import math

import pytest

from chiptwin.chip import Schedule, silicon
from chiptwin.config import load_scenario
from chiptwin.config.schema_chip import Adc
from chiptwin.twin import chip_cost
from tests.conftest import SCENARIOS


@pytest.mark.parametrize(("fom_db", "bits", "want_j"), [
    # P/f_s = ½·10^(−(FOM − 6.02 N − 1.76)/10), worked by hand
    (165.7, 13, 0.5 * 10 ** (-(165.7 - 80.02) / 10)),
    (160.2, 10, 0.5 * 10 ** (-(160.2 - 61.96) / 10)),
    (189.2, 8, 0.5 * 10 ** (-(189.2 - 49.92) / 10)),
])
def test_schreier_energy_per_conversion(fom_db, bits, want_j):
    """The Schreier FOM's energy, and the same number ``[chip.adc]`` gives."""
    got = silicon.schreier_energy_per_conversion_j(fom_db, bits)
    assert got == pytest.approx(want_j, rel=1e-12)
    assert got == pytest.approx(Adc(bits=bits, fom_schreier_db=fom_db).energy_per_conversion_J,
                                rel=1e-12)


def test_a_bit_costs_four_times_the_energy():
    """At a fixed FOM each bit adds 6.02 dB of SNDR: 10^0.602 = 4.0× the energy."""
    e = [silicon.schreier_energy_per_conversion_j(165.7, b) for b in (12, 13)]
    assert e[1] / e[0] == pytest.approx(10 ** 0.602, rel=1e-12)


# (block function, its arguments, area mm², power mW), each worked by hand
TABLE = [
    (silicon.memory_block, (1_048_576, 5.59, 0.7, 2.0e6, 2.5),
     1_048_576 * 5.59 / 0.7 / 1e6, 2.0e6 * 2.5e-12 * 1e3),
    (silicon.converter_block, (128, 13, 10.0, 1024.0, 1.0e-9), 128 * 13 * 10.0 / 1e6,
     1024.0 * 1e-9 * 1e3),
    (silicon.pixel_block, (128, 15625.0, 130.0, 1.0, 1.8, 0.01), 128 * (15625.0 - 130.0) / 1e6,
     128 * 1e-6 * 1.8 * 0.01 * 1e3),
    (silicon.dsp_block, (0.5, 1.0e6, 15.0), 0.5, 1.0e6 * 15e-12 * 1e3),
    (silicon.readout_io_block, (0.25, 1.0, 40, 1.0e4, 1.0e3, 50.0), 0.25 + 40 * 1e4 / 1e6,
     1.0 + 1.0e3 * 50e-12 * 1e3),
]


@pytest.mark.parametrize(("block", "args", "area", "power"), TABLE,
                         ids=[row[0].__name__ for row in TABLE])
def test_block_formulas(block, args, area, power):
    got = block(*args)
    assert got.area_mm2 == pytest.approx(area, rel=1e-12)
    assert got.power_mw == pytest.approx(power, rel=1e-12)


def test_pixel_cell_is_the_pitch_or_what_it_holds():
    """The pitch squared, unless the diode and circuits do not fit: then the array spreads."""
    assert silicon.pixel_cell_um2(125.0, 10_000.0 + 230.0) == 15625.0
    assert silicon.pixel_cell_um2(10.0, 150.0) == 150.0


def test_total_and_energy_per_item():
    blocks = {"a": silicon.Block(1.0, 2.0), "b": silicon.Block(0.5, 0.25)}
    assert silicon.total(blocks) == silicon.Block(1.5, 2.25)
    # 1 mW for 1000 s = 1 J over 1e6 bases = 1 µJ = 1000 nJ a base
    assert silicon.energy_per_item_nj(1.0, 1000.0, 1e6) == pytest.approx(1000.0, rel=1e-12)
    assert silicon.energy_per_item_nj(1.0, 1000.0, 0) == math.inf


def test_reference_chip_worked_by_hand():
    """pyro_1fmol's chip (8 × 16 pixels at 125 µm, 100 µm diodes, 13 bits, 1 Mbit of SRAM,
    1 s frames, CMS 4 + 4) at the 0.18 µm defaults, block by block:

    - memory: 2^20 × 5.59 µm² (Intel 180 nm cell, Yang et al., IEDM 1998) / 0.7 = 8.374 mm²;
    - converters: 128 × 13 × 10 µm² = 0.01664 mm²; their power, 128 × 8 conversions a second
      at the FOM's energy, is ``summary['chip']['adc_power_w']``;
    - pixel: the array, 128 × 125² µm² = 2.0 mm², less the converters;
    - the die is the sum; the cell fits its pitch; fill factor 100²/125² = 0.64.
    """
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml")
    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    cost = chip_cost.cost_figures(s, sch, {})
    b = cost["blocks"]
    assert b["memory"]["area_mm2"] == pytest.approx(2**20 * 5.59 / 0.7 / 1e6, rel=1e-12)
    assert b["converter"]["area_mm2"] == pytest.approx(0.01664, rel=1e-12)
    adc_w = 128 * 8 * s.chip.adc.energy_per_conversion_J / 1.0
    assert b["converter"]["power_mw"] == pytest.approx(adc_w * 1e3, rel=1e-9)
    assert b["pixel"]["area_mm2"] + b["converter"]["area_mm2"] == pytest.approx(2.0, rel=1e-12)
    assert cost["area_mm2"] == pytest.approx(sum(v["area_mm2"] for v in b.values()), rel=1e-12)
    assert cost["power_mw"] == pytest.approx(sum(v["power_mw"] for v in b.values()), rel=1e-12)
    assert cost["pixel_fits_pitch"] and cost["fill_factor"] == pytest.approx(0.64)
    assert "energy_per_base_nj" not in cost  # no reads in the summary given


def test_a_pixel_too_full_spreads_the_array():
    """Circuits that do not fit the pitch: the cell grows to hold them and the summary says so."""
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", ["chip.cost.pixel_circuit_area_um2=1e4"])
    cost = chip_cost.cost_figures(s, Schedule.from_chip(s.chip, s.run.duration_s), {})
    assert not cost["pixel_fits_pitch"]
    assert cost["pixel_cell_um2"] == pytest.approx(1e4 + 1e4 + 13 * 10.0, rel=1e-12)


def test_throughput_from_known_counts():
    """36 Q20 bases in a 1520 s run on an 11.5 mm² die: 85.26 an hour, 7.41 an hour per mm²;
    2 of 2 sites called right; 1 mW over the run per base."""
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml")
    summary = {"array": {"sites_called_right": 2, "fraction_called_right": 1.0},
               "sites": [{"detected": True}] * 2, "reads": {"chip_q20_bases": 36}}
    cost = {"area_mm2": 11.5, "power_mw": 1.0}
    tp = chip_cost.throughput_figures(s, summary, cost)
    assert tp["q20_bases_per_run"] == 36
    assert tp["q20_bases_per_hour"] == pytest.approx(36 / (1520 / 3600), rel=1e-12)
    assert tp["q20_bases_per_hour_mm2"] == pytest.approx(36 / (1520 / 3600) / 11.5, rel=1e-12)
    assert (tp["sites_called"], tp["sites_called_frac"]) == (2, 1.0)
    assert tp["sites_per_mm2"] == pytest.approx(2 / 11.5, rel=1e-12)


def test_an_assay_counts_detected_sites():
    """No reads: a site is called when detected; no Q20 figures."""
    s = load_scenario(SCENARIOS / "atp_glow.toml")
    summary = {"array": {"fraction_detected": 0.5},
               "sites": [{"detected": True}, {"detected": False}]}
    tp = chip_cost.throughput_figures(s, summary, {"area_mm2": 4.0})
    assert (tp["sites_called"], tp["sites_called_frac"], tp["sites_per_mm2"]) == (1, 0.5, 0.25)
    assert "q20_bases_per_run" not in tp


def test_study_metrics_read_the_cost_and_throughput():
    """The catalogue's cost and throughput metrics, under the names a design search asks for,
    read the run's summary; no Q20 base is an infinite energy per base."""
    from types import SimpleNamespace

    from chiptwin.study.metrics import CATALOGUE, measure

    summary = {"cost": {"area_mm2": 11.5, "power_mw": 1.0, "energy_per_base_nj": 4.2e7},
               "throughput": {"q20_bases_per_run": 36, "q20_bases_per_hour": 85.26,
                              "q20_bases_per_hour_mm2": 7.4, "sites_called_frac": 1.0,
                              "sites_per_mm2": 0.17}}
    names = ("area_mm2", "power_mw", "energy_per_base_nj", "q20_bases_per_run",
             "q20_bases_per_hour", "q20_bases_per_hour_mm2", "sites_called_frac",
             "sites_per_mm2")
    assert all(CATALOGUE[n].kind == "mean" for n in names)
    got = measure(SimpleNamespace(summary=summary), names)
    assert got == {"area_mm2": 11.5, "power_mw": 1.0, "energy_per_base_nj": 4.2e7,
                   "q20_bases_per_run": 36.0, "q20_bases_per_hour": 85.26,
                   "q20_bases_per_hour_mm2": 7.4, "sites_called_frac": 1.0,
                   "sites_per_mm2": 0.17}
    summary["cost"]["energy_per_base_nj"] = None
    assert measure(SimpleNamespace(summary=summary), ("energy_per_base_nj",)) == {
        "energy_per_base_nj": math.inf}


def test_a_run_reports_its_cost_and_throughput(small_toml):
    """A run's summary carries ``cost`` and ``throughput`` (the blocks summing to the die) and
    its report shows them."""
    from chiptwin.report.outputs import headline
    from chiptwin.twin import run

    summary = run(small_toml).summary
    cost, tp = summary["cost"], summary["throughput"]
    assert set(cost["blocks"]) == set(silicon.BLOCKS)
    assert cost["area_mm2"] == pytest.approx(
        sum(b["area_mm2"] for b in cost["blocks"].values()), rel=1e-12)
    assert tp["q20_bases_per_run"] == summary["reads"]["chip_q20_bases"]
    assert tp["sites_called"] == summary["array"]["sites_called_right"]
    rows = dict(headline(summary))
    assert f"{cost['area_mm2']:.3g} mm²" in rows["silicon"] and "Q20 bases" in rows["throughput"]
