"""``[chip.cost]``: what the chip costs in silicon area and power, block by block.

The converter's energy is ``[chip.adc] fom_schreier_db`` (Murmann's ADC survey); every other
figure is here, at the 0.18 µm node of the reference chip by default (Eltoukhy, Salama & El
Gamal, "A 0.18-µm CMOS bioluminescence detection lab-on-chip", IEEE JSSC 41(3):651, 2006). The
formulas are :mod:`chiptwin.chip.silicon`; the twin applies them to a run
(:mod:`chiptwin.twin.chip_cost`). Not to be confused with :mod:`chiptwin.config.cost`, the wall
time of a run.

Sources of the defaults (numbers, not code):

- Horowitz, "Computing's energy problem (and what we can do about it)", ISSCC 2014, its energy
  table: at 45 nm, 0.9 V, a 64-bit read of an 8 kB SRAM 10 pJ (0.16 pJ/bit), a 32-bit add
  0.1 pJ, an 8-bit multiply 0.2 pJ, a 32-bit multiply 3.1 pJ. Scaled to 0.18 µm, 1.8 V by C·V²
  (capacitance ∝ feature size, ×4; V², ×4): ×16.
- Yang et al., "A high performance 180 nm generation logic technology", IEDM 1998: the 6T SRAM
  cell of Intel's 180 nm process, 5.59 µm².
- Kleinfelder, Lim, Liu & El Gamal, "A 10 000 frames/s CMOS digital pixel sensor", IEEE JSSC
  36(12):2049, 2001: 0.18 µm, a 9.4 µm pixel (88 µm²) holding the photodiode (15 % fill) and an
  8-bit single-slope converter with its 8-bit memory: ≈ 9.4 µm² a bit.
"""

from __future__ import annotations

from dataclasses import dataclass

from chiptwin.config.fields import param

#: Area of a whole die, the upper end of every area key: 100 mm² (a 1 cm × 1 cm die).
DIE_MAX_MM2 = 100.0


@dataclass(frozen=True)
class Cost:
    """``[chip.cost]``: block areas and energies at the node (0.18 µm by default)."""

    supply_V: float = param(
        1.8, lo=0.3, hi=5.0,
        doc="V, the core supply the pixel bias draws from; 0.18 µm CMOS cores run at 1.8 V; "
            "0.3 V (near-threshold logic) … 5 V (the thick-oxide I/O of older nodes)")
    pixel_circuit_area_um2: float = param(
        100.0, lo=0.0, hi=1.0e6,
        doc="µm² a pixel's own transistors take beside its diode and converter (reset, "
            "source follower, select, sample capacitors); choice 100 µm² (a 3-4 transistor "
            "readout at 0.18 µm takes tens of µm²); 0 (a passive pixel) … 1 mm²")
    pixel_bias_uA: float = param(
        1.0, lo=0.0, hi=1000.0,
        doc="µA, a pixel's source-follower bias while it is read out (choice; 0.1–10 µA "
            "typical); 0 … 1 mA, beyond any pixel's column current")
    adc_area_per_bit_um2: float = param(
        10.0, lo=0.1, hi=1.0e5,
        doc="µm² of a per-pixel converter for each bit (comparator and latch shared out); "
            "≈ 9.4 µm² a bit at 0.18 µm (Kleinfelder et al., JSSC 2001: 8 bits and the "
            "comparator in 75 µm²); 0.1 µm² (a few minimum transistors at 5 nm) … 0.1 mm²")
    sram_cell_um2: float = param(
        5.59, lo=0.01, hi=1000.0,
        doc="µm² of a 6T SRAM bit cell; Intel 180 nm 5.59 µm² (Yang et al., IEDM 1998); "
            "0.01 µm² (below 5 nm-class cells, 0.021 µm²) … 1000 µm² (a 6T cell of ≈ 140 F² "
            "is ≈ 560 µm² at 2 µm)")
    sram_array_efficiency: float = param(
        0.7, lo=0.05, hi=1.0,
        doc="the bit cells' share of a memory macro, decoders and sense amplifiers the rest "
            "(choice 0.7; CACTI's macros 0.5–0.8); 0.05 (a tiny macro, its periphery twenty "
            "times its cells) … 1")
    sram_energy_per_bit_pJ: float = param(
        2.5, lo=1.0e-4, hi=1.0e3,
        doc="pJ per bit written or read; 2.5 pJ at 0.18 µm, 1.8 V (Horowitz, ISSCC 2014: 10 pJ "
            "per 64-bit read of an 8 kB SRAM at 45 nm, 0.9 V, scaled by C·V², ×16: derived); "
            "1e-4 pJ (beyond any node) … 1 nJ (an off-chip DRAM bit is ≈ 20–100 pJ)")
    dsp_area_mm2: float = param(
        0.5, lo=0.0, hi=DIE_MAX_MM2,
        doc="mm² of the DSP datapath, control and registers (choice: 20–50 k gates of "
            "≈ 10 µm² at 0.18 µm); 0 (no on-chip DSP) … 100 mm² (a whole die)")
    dsp_energy_per_op_pJ: float = param(
        15.0, lo=1.0e-3, hi=1.0e4,
        doc="pJ per DSP cycle (one 16-bit multiply-accumulate and its register traffic); "
            "15 pJ at 0.18 µm, 1.8 V (Horowitz, ISSCC 2014, 45 nm: 16-bit multiply ≈ 0.8 pJ "
            "between the 8- and 32-bit figures, add 0.05 pJ, ×16 by C·V²: derived); "
            "1e-3 pJ … 10 nJ (a processor's instruction overhead included, ≈ 70 pJ at 45 nm)")
    io_pads: int = param(
        40, kind=int, lo=4, hi=10000,
        doc="bonding pads (choice 40: supplies, clock, control, a 16-bit data bus); 4 (power, "
            "ground, clock, one data line) … 10,000 (a large flip-chip array)")
    io_pad_area_um2: float = param(
        10000.0, lo=100.0, hi=1.0e6,
        doc="µm² of one pad with its driver and ESD (choice: ≈ 60 µm pitch × 170 µm deep, a "
            "0.18 µm I/O cell); 100 µm² (a 10 µm micro-bump) … 1 mm²")
    io_energy_per_bit_pJ: float = param(
        50.0, lo=0.01, hi=1.0e5,
        doc="pJ per bit sent off chip: ½·C·V² per toggle, half the bits toggling, C = 10 pF "
            "(pad, package, board trace) at 3.3 V: ≈ 50 pJ (derived; the load is a choice); "
            "0.01 pJ (an on-package link) … 100 nJ")
    periphery_area_mm2: float = param(
        0.25, lo=0.0, hi=DIE_MAX_MM2,
        doc="mm² of the readout periphery: row and column decoders, the ramp generator, bias "
            "and timing (choice 0.25 mm²); 0 … 100 mm² (a whole die)")
    periphery_power_mw: float = param(
        1.0, lo=0.0, hi=1.0e4,
        doc="mW the periphery draws (ramp DAC, bias currents, clock tree; choice 1 mW); "
            "0 … 10 W, beyond what a die without a heat sink dissipates")
