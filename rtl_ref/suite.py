"""The co-simulation suite: which configs of each block are built and how many vectors they get.

Each block kind is one :class:`~rtl_ref.cosim.Bank` (one build per simulator) holding the
model's default config, the config the chip's chain uses, and variants chosen to reach every
rounding mode, every overflow mode of every register, signed and unsigned words, the
reciprocal divide, narrow accumulators that saturate or wrap, one-pixel and one-frame edge
cases. ``VECTORS`` input beats per block kind go through Verilator (split over the configs);
``ICARUS_VECTORS`` per config through Icarus.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

from chiptwin.dsp.chain import chain_configs
from chiptwin.dsp.filters import FirConfig, KineticsConfig
from chiptwin.dsp.fixed import OVERFLOW_MODES, ROUNDING_MODES, Fmt
from chiptwin.dsp.frame_ops import AverageConfig, BackgroundConfig, CmsConfig
from rtl_ref import vectors
from rtl_ref.block import Block
from rtl_ref.cosim import Bank, Report
from rtl_ref.filter_blocks import FirBlock, KineticsBlock
from rtl_ref.frame_blocks import AverageBlock, BackgroundBlock, CmsBlock

VECTORS = 1_000_000
"""Input beats per block kind on Verilator."""
ICARUS_VECTORS = 1_500
"""Input beats per config on Icarus (4-state, ~100× slower)."""
PIXELS = 16
"""Pixels per frame of the stateful blocks (their RAM depth) unless a config says otherwise."""
BACK_PRESSURE = ((1.0, 1.0), (0.9, 0.8), (0.6, 0.35), (1.0, 0.5), (0.5, 1.0))
"""(p_valid, p_ready) per config, cycling: full rate, light, heavy, output-limited,
input-limited."""

S16_2 = Fmt(True, 16, 2)
ADC13 = Fmt(False, 13, 0)


def background_blocks() -> list[Block]:
    """Default, chain, the 18 rounding × overflow modes, unsigned and left-shifting outputs."""
    chain = chain_configs(13, 4, 16, 4)
    cfgs = [BackgroundConfig(), chain.background]
    narrow = {"in_fmt": S16_2, "dark_fmt": Fmt(True, 14, 5), "out_fmt": Fmt(True, 12, 1)}
    for r, o in itertools.product(ROUNDING_MODES, OVERFLOW_MODES):
        cfgs.append(BackgroundConfig(rounding=r, overflow=o, **narrow))
    unsigned = {**narrow, "out_fmt": Fmt(False, 12, 1)}
    for r, o in (("TRN", "SAT"), ("RND_INF", "WRAP"), ("RND_CONV", "SAT_SYM")):
        cfgs.append(BackgroundConfig(rounding=r, overflow=o, **unsigned))
    for o in ("WRAP", "SAT"):
        cfgs.append(BackgroundConfig(in_fmt=S16_2, dark_fmt=Fmt(True, 14, 5),
                                     out_fmt=Fmt(True, 20, 7), overflow=o))
    return [BackgroundBlock(c) for c in cfgs]


def average_blocks() -> list[Block]:
    """Default, the chain's dark and block averages, reciprocal divides, narrow accumulators."""
    chain = chain_configs(13, 4, 16, 4)
    return [
        AverageBlock(AverageConfig(n=4), PIXELS),
        AverageBlock(chain.average, PIXELS),
        AverageBlock(chain.dark, PIXELS),
        AverageBlock(AverageConfig(n=5), PIXELS),
        AverageBlock(AverageConfig(n=5, out_fmt=Fmt(True, 36, 20)), PIXELS),  # reachable ties
        AverageBlock(AverageConfig(n=64, in_fmt=ADC13, acc_fmt=Fmt(False, 16, 0)), PIXELS),
        AverageBlock(AverageConfig(n=6, acc_fmt=Fmt(True, 17, 2), acc_overflow="SAT",
                                   rounding="TRN"), PIXELS),
        AverageBlock(AverageConfig(n=8, acc_fmt=Fmt(True, 18, 2), acc_overflow="SAT_SYM",
                                   out_fmt=Fmt(True, 12, 2), rounding="RND_INF",
                                   overflow="SAT_SYM"), PIXELS),
        AverageBlock(AverageConfig(n=3, rounding="RND_ZERO", overflow="WRAP",
                                   out_fmt=Fmt(True, 14, 1)), 1),
        AverageBlock(AverageConfig(n=1, out_fmt=Fmt(True, 15, 1), rounding="TRN_ZERO"), 5),
    ]


def cms_blocks() -> list[Block]:
    """Default (M = 4), reciprocal (M = 3), M = 1 on one pixel, narrow wrapping / saturating
    accumulators, the chain's CMS for M = 2."""
    return [
        CmsBlock(CmsConfig(m=4), PIXELS),
        CmsBlock(CmsConfig(m=3), PIXELS),
        CmsBlock(CmsConfig(m=3, out_fmt=Fmt(True, 34, 17)), PIXELS),  # reachable ties
        CmsBlock(CmsConfig(m=1, rounding="RND"), 1),
        CmsBlock(CmsConfig(m=8, acc_fmt=Fmt(False, 14, 0), rounding="RND_INF"), PIXELS),
        CmsBlock(CmsConfig(m=4, acc_fmt=Fmt(False, 14, 0), acc_overflow="SAT",
                           out_fmt=Fmt(True, 12, 0), rounding="TRN_ZERO",
                           overflow="SAT_SYM"), PIXELS),
        CmsBlock(chain_configs(13, 2, 4, 4).cms, 7),
    ]


def fir_blocks() -> list[Block]:
    """The 8-tap default; 40 → 30 / 28-bit accumulators that saturate / wrap; 5 taps with a
    narrow output; 2 taps on unsigned ADC codes and one pixel."""
    return [
        FirBlock(FirConfig(), PIXELS),
        FirBlock(FirConfig(acc_fmt=Fmt(True, 30, 17), acc_overflow="SAT"), PIXELS),
        FirBlock(FirConfig(acc_fmt=Fmt(True, 28, 17), acc_overflow="WRAP"), PIXELS),
        FirBlock(FirConfig(taps=5, cutoff=0.4, out_fmt=Fmt(True, 12, 0), rounding="RND_CONV",
                           overflow="SAT_SYM"), PIXELS),
        FirBlock(FirConfig(taps=2, cutoff=0.5, in_fmt=ADC13, rounding="RND_ZERO"), 1),
    ]


def kinetics_blocks() -> list[Block]:
    """The default 16-frame decay; a saturating narrow accumulator; a wrapping one on one
    pixel; a narrow output with SAT_SYM."""
    return [
        KineticsBlock(KineticsConfig(), PIXELS),
        KineticsBlock(KineticsConfig(t_s=tuple(float(i) for i in range(8)), k_per_s=0.2,
                                     acc_fmt=Fmt(True, 30, 17), acc_overflow="SAT"), PIXELS),
        KineticsBlock(KineticsConfig(t_s=(0.0, 1.0, 2.0, 3.0, 4.0), k_per_s=0.5,
                                     acc_fmt=Fmt(True, 31, 17), acc_overflow="WRAP"), 1),
        KineticsBlock(KineticsConfig(out_fmt=Fmt(True, 14, 2), rounding="RND_INF",
                                     overflow="SAT_SYM"), PIXELS),
        KineticsBlock(KineticsConfig(out_fmt=Fmt(True, 48, 32), rounding="RND_ZERO"), PIXELS),
    ]


KINDS: dict[str, Callable[[], list[Block]]] = {
    "background": background_blocks,
    "average": average_blocks,
    "cms": cms_blocks,
    "fir": fir_blocks,
    "kinetics": kinetics_blocks,
}


def bank(kind: str, defines: tuple[str, ...] = ()) -> Bank:
    """The bank of block kind ``kind``."""
    return Bank(KINDS[kind](), defines)


def run_kind(
    b: Bank, simulator: str, n_total: int, seed: int = 2024, n_each: int | None = None
) -> list[Report]:
    """Every config of a bank on its own vectors; ``n_total`` beats split evenly, or
    ``n_each`` per config. One seeded generator per config (``SeedSequence.spawn``)."""
    seqs = np.random.SeedSequence(seed).spawn(len(b.blocks))
    each = n_each if n_each is not None else -(-n_total // len(b.blocks))
    reports = []
    for i, (blk, seq) in enumerate(zip(b.blocks, seqs, strict=True)):
        rng = np.random.default_rng(seq)
        inputs = vectors.for_block(blk, each, rng)
        p_valid, p_ready = BACK_PRESSURE[i % len(BACK_PRESSURE)]
        reports.append(b.run(i, inputs, simulator, p_valid, p_ready, seed=seed + i))
    return reports
