"""What a chip costs in silicon: each block's area and average power, numbers in, numbers out.

Five blocks, in the order the signal travels (mm², mW):

- **pixel**: the array's cells (diode, the pixel's own transistors, the spacing to the pitch),
  the converters' share left out; power, each pixel's source-follower bias while it is read out.
- **converter**: one single-slope converter per pixel (the reference chip's), ``bits`` ×
  area per bit; energy per conversion from the Schreier figure of merit.
- **memory**: the frame memory, 6T SRAM cells over the macro's efficiency; energy per bit
  written or read.
- **dsp**: a stated area; energy per operation × operations per second.
- **readout_io**: the periphery (decoders, ramp generator, bias, timing) and the bonding pads;
  energy per bit sent off chip.

Power is dynamic energy per second, plus the periphery's stated draw; leakage, which is small at
0.18 µm (Horowitz, ISSCC 2014), is not modelled. Units: µm² and pJ in, mm² and mW out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The blocks, in signal order.
BLOCKS = ("pixel", "converter", "memory", "dsp", "readout_io")

UM2_PER_MM2 = 1.0e6
PJ_PER_S_PER_MW = 1.0e9  # 1 mW = 1e9 pJ/s


@dataclass(frozen=True)
class Block:
    """One block's silicon area and average power."""

    area_mm2: float
    power_mw: float


def schreier_energy_per_conversion_j(fom_schreier_db: float, bits: int) -> float:
    """Energy of one conversion at the ideal SNDR of ``bits`` (6.02 N + 1.76 dB):
    FOM_S = SNDR + 10 log10(f_s / 2 / P) gives P / f_s = ½ · 10^(−(FOM_S − SNDR)/10). Unit: J
    (Murmann, "ADC Performance Survey 1997–2025")."""
    sndr_db = 6.02 * bits + 1.76
    return 0.5 * 10.0 ** (-(fom_schreier_db - sndr_db) / 10.0)


def pixel_cell_um2(pitch_um: float, content_um2: float) -> float:
    """A pixel's cell: the pitch squared, or what it holds when that does not fit (the array
    then spreads beyond its pitch). Unit: µm²."""
    return max(pitch_um * pitch_um, content_um2)


def pixel_block(n_pixels: int, cell_um2: float, converter_um2: float, bias_uA: float,
                supply_V: float, read_duty: float) -> Block:
    """The array less its converters; each pixel draws ``bias_uA`` from ``supply_V`` for the
    ``read_duty`` share of the frame it is read out."""
    area = n_pixels * (cell_um2 - converter_um2) / UM2_PER_MM2
    power_mw = n_pixels * bias_uA * 1e-3 * supply_V * read_duty
    return Block(area, power_mw)


def converter_block(n_converters: int, bits: int, area_per_bit_um2: float,
                    conversions_per_s: float, energy_per_conversion_j: float) -> Block:
    """Per-pixel converters: ``bits`` × the area per bit each; every conversion at its energy."""
    area = n_converters * bits * area_per_bit_um2 / UM2_PER_MM2
    return Block(area, conversions_per_s * energy_per_conversion_j * 1e3)


def memory_block(capacity_bits: int, cell_um2: float, efficiency: float,
                 bits_per_s: float, energy_per_bit_pJ: float) -> Block:
    """SRAM of ``capacity_bits`` cells, the cells ``efficiency`` of the macro; ``bits_per_s``
    written plus read."""
    area = capacity_bits * cell_um2 / efficiency / UM2_PER_MM2
    return Block(area, bits_per_s * energy_per_bit_pJ / PJ_PER_S_PER_MW)


def dsp_block(area_mm2: float, ops_per_s: float, energy_per_op_pJ: float) -> Block:
    """The DSP: its stated area; operations per second at their energy."""
    return Block(area_mm2, ops_per_s * energy_per_op_pJ / PJ_PER_S_PER_MW)


def readout_io_block(periphery_area_mm2: float, periphery_power_mw: float, pads: int,
                     pad_area_um2: float, bits_out_per_s: float,
                     energy_per_bit_pJ: float) -> Block:
    """The periphery's stated area and draw, the pads' area and the bits they send."""
    area = periphery_area_mm2 + pads * pad_area_um2 / UM2_PER_MM2
    return Block(area, periphery_power_mw + bits_out_per_s * energy_per_bit_pJ / PJ_PER_S_PER_MW)


def total(blocks: dict[str, Block]) -> Block:
    """The die: the blocks' areas and powers summed."""
    return Block(math.fsum(b.area_mm2 for b in blocks.values()),
                 math.fsum(b.power_mw for b in blocks.values()))


def energy_per_item_nj(power_mw: float, seconds: float, items: float) -> float:
    """The energy a run of ``seconds`` at ``power_mw`` spends per item it yields (a base);
    infinite when it yields none. Unit: nJ."""
    if items <= 0:
        return math.inf
    return power_mw * 1e-3 * seconds / items * 1e9
