"""A run's cost in silicon and what it yields: ``summary['cost']`` and ``summary['throughput']``.

The thin adapter between the scenario (``[chip.cost]``, ``[chip.adc] fom_schreier_db``, the
array, the schedule) and the pure formulas of :mod:`chiptwin.chip.silicon`; then the yield of
the run per chip, per hour and per mm² (Q20 bases for pyrosequencing, sites for an assay).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from chiptwin.chip import silicon
from chiptwin.dsp.program import program_load

if TYPE_CHECKING:
    from chiptwin.chip import Schedule
    from chiptwin.config import Scenario


def blocks(s: Scenario, sch: Schedule) -> dict[str, silicon.Block]:
    """Each block's area and average power over the run's frames (one frame every
    ``frame_period``; the dark frames cost as any other)."""
    chip, c = s.chip, s.chip.cost
    n, period_s = chip.n_pixels, sch.frame_period_ns / 1e9
    conversions_per_s = n * 2 * sch.cms_samples / period_s  # reset and signal, every pixel
    converter_um2 = chip.adc.bits * c.adc_area_per_bit_um2
    content = (chip.pixel.diode_w_um * chip.pixel.diode_h_um + c.pixel_circuit_area_um2
               + converter_um2)
    cell = silicon.pixel_cell_um2(chip.pitch_um, content)
    read_duty = min(chip.readout_time_s / period_s, 1.0)
    load = program_load(chip)
    ops_per_frame = load.cycles_per_frame + load.cycles_per_output / load.frames_per_job
    outputs_per_s = 1.0 / (period_s * chip.dsp.average_frames)
    return {
        "pixel": silicon.pixel_block(n, cell, converter_um2, c.pixel_bias_uA, c.supply_V,
                                     read_duty),
        "converter": silicon.converter_block(n, chip.adc.bits, c.adc_area_per_bit_um2,
                                             conversions_per_s,
                                             chip.adc.energy_per_conversion_J),
        # every raw frame written once and read once by the DSP
        "memory": silicon.memory_block(chip.memory.capacity_bits, c.sram_cell_um2,
                                       c.sram_array_efficiency, 2 * chip.frame_bits / period_s,
                                       c.sram_energy_per_bit_pJ),
        "dsp": silicon.dsp_block(c.dsp_area_mm2, ops_per_frame / period_s,
                                 c.dsp_energy_per_op_pJ),
        # one output word per pixel per averaged output
        "readout_io": silicon.readout_io_block(
            c.periphery_area_mm2, c.periphery_power_mw, c.io_pads, c.io_pad_area_um2,
            n * chip.memory.word_bits * outputs_per_s, c.io_energy_per_bit_pJ),
    }


def cost_figures(s: Scenario, sch: Schedule, summary: dict[str, Any]) -> dict[str, Any]:
    """``summary['cost']``: area (mm²) and power (mW) by block and in all, the run's energy,
    the pixel's cell, and (pyrosequencing) the energy per Q20 base (nJ; None when the run
    reads none)."""
    by_block = blocks(s, sch)
    die = silicon.total(by_block)
    pitch_um2 = s.chip.pitch_um**2
    cell = by_block["pixel"].area_mm2 + by_block["converter"].area_mm2
    cell_um2 = cell * silicon.UM2_PER_MM2 / s.chip.n_pixels
    out: dict[str, Any] = {
        "blocks": {name: {"area_mm2": b.area_mm2, "power_mw": b.power_mw}
                   for name, b in by_block.items()},
        "area_mm2": die.area_mm2,
        "power_mw": die.power_mw,
        "energy_j": die.power_mw * 1e-3 * s.run.duration_s,
        "pixel_cell_um2": cell_um2,
        "pixel_fits_pitch": cell_um2 <= pitch_um2 * (1 + 1e-12),
        "fill_factor": s.chip.pixel.diode_w_um * s.chip.pixel.diode_h_um / cell_um2,
    }
    if "reads" in summary:
        nj = silicon.energy_per_item_nj(die.power_mw, s.run.duration_s,
                                        summary["reads"]["chip_q20_bases"])
        out["energy_per_base_nj"] = nj if math.isfinite(nj) else None  # None: no Q20 base
    return out


def throughput_figures(s: Scenario, summary: dict[str, Any], cost: dict[str, Any]
                       ) -> dict[str, Any]:
    """``summary['throughput']``: sites called (pyrosequencing: the whole template read right;
    an assay: detected at ``run.detection_snr_power``), per chip and per mm²; for
    pyrosequencing the Q20 bases per run, per hour and per hour and mm²."""
    arr, area, hours = summary["array"], cost["area_mm2"], s.run.duration_s / 3600.0
    if "sites_called_right" in arr:
        called, frac = arr["sites_called_right"], arr["fraction_called_right"]
        meaning = "sites whose read equals the template as far as the flows reach"
    else:
        called = sum(site["detected"] for site in summary["sites"])
        frac, meaning = arr["fraction_detected"], (
            f"sites detected at power SNR ≥ {s.run.detection_snr_power:g}")
    out: dict[str, Any] = {
        "sites_called": int(called), "sites_called_frac": float(frac),
        "sites_called_means": meaning, "sites_per_mm2": called / area,
        "run_hours": hours,
    }
    if "reads" in summary:
        q20 = summary["reads"]["chip_q20_bases"]
        out.update(q20_bases_per_run=int(q20), q20_bases_per_hour=q20 / hours,
                   q20_bases_per_hour_mm2=q20 / hours / area)
    return out
