"""The bench's one hot loop: hits per code accumulated over a block of conversions."""

from __future__ import annotations

from chiptwin._numba import NJIT

#: Conversions of one converter counted in a row before moving to the next converter: its
#: row of counts stays in cache, the codes are read a tile at a time (measured: 4 ns a
#: conversion, against 16–25 ns row by row and 29 ns column by column, 13 bits × 128).
TILE: int = 256


@NJIT
def add_counts(codes, counts):
    """``counts[i, codes[m, i]] += 1`` for every conversion ``m`` of converter ``i``.

    ``codes`` ``(R, n)`` integer codes in ``[0, counts.shape[1])`` (the converter clips: not
    checked here), ``counts`` ``(n, 2^N)`` int64, updated in place.
    """
    for m0 in range(0, codes.shape[0], TILE):
        m1 = min(m0 + TILE, codes.shape[0])
        for i in range(codes.shape[1]):
            for m in range(m0, m1):
                counts[i, codes[m, i]] += 1
