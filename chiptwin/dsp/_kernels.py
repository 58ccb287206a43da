"""numba kernels of the bit-accurate DSP: arrays and scalars in, arrays out, no objects, no globals.

Every value is an ``int64`` code; no ``uint64`` ever enters a kernel (numba turns ``uint64`` mixed
with ``int64`` into ``float64``). numba emits ``add nsw`` / ``mul nsw`` for ``int64``: a signed
overflow is undefined behaviour for LLVM, not a reliable wrap. The kernels therefore never let an
``int64`` add or multiply overflow:

* products: the wrappers admit only operands with ``W_a + W_b ≤ 64`` bits, so ``|a·b| < 2^63``;
* register updates go through :func:`_add_fit`, which splits both operands in two halves so that
  the sum is exact even when it leaves the ``int64`` range (64-bit accumulators);
* left shifts use ``shl`` (no ``nsw``: it wraps modulo 2^64 by definition) and are range-checked
  before the shift; right shifts of 63 bits and more are reduced with a sticky bit first.

A register is described by ``spec = (lo, hi, wrap_shift, signed)`` (``int64[4]``): the smallest
and largest code, ``64 - word_bits`` and 1 for signed / 0 for unsigned (see ``Fmt.spec``).

Rounding modes (``rmode``): 0 TRN, 1 TRN_ZERO, 2 RND, 3 RND_ZERO, 4 RND_INF, 5 RND_CONV; inside
the kernels they travel as the bit mask ``mb = mode_bits(rmode)``.
Overflow modes (``omode``): 0 WRAP, 1 SAT, 2 SAT_SYM.
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT

TRN, TRN_ZERO, RND, RND_ZERO, RND_INF, RND_CONV = 0, 1, 2, 3, 4, 5
WRAP, SAT, SAT_SYM = 0, 1, 2

_I64_MAX = 9223372036854775807
_TWO62 = 4611686018427387904
_TWO62_F = 4.611686018427388e18
_TWO53_F = 9007199254740992.0
_TINY_F = 9.332636185032189e-302  # 2^-1000: above it a product by 2^F is a normal float, exact


# ---------------------------------------------------------------------------------------------
# scalar primitives
# ---------------------------------------------------------------------------------------------


@NJIT
def _wrap(v, hi, ws, sg):
    """``v`` modulo ``2^W`` into the register's range (two's complement for signed)."""
    if sg == 1:
        return (v << ws) >> ws
    return v & hi


@NJIT
def _fit(q, lo, hi, ws, sg, omode):
    """Put the exact integer ``q`` into the register. Returns ``(code, n_sat, n_wrap)``.

    Branch-free on the data (min/max, compare-and-count), so that a hot loop stays if-converted.
    """
    if omode == WRAP:
        c = _wrap(q, hi, ws, sg)
        return c, 0, 1 if c != q else 0
    lo_sat = -hi if (omode == SAT_SYM and sg == 1) else lo
    c = min(max(q, lo_sat), hi)
    return c, 1 if c != q else 0, 0


@NJIT
def _shl_fit(v, s, lo, hi, ws, sg, omode):
    """Put the exact ``v · 2^s`` (``s ≥ 0``, any size) into the register."""
    if v == 0 or s == 0:
        return _fit(v, lo, hi, ws, sg, omode)
    if s >= 64:
        over = True
        wrapped = 0  # v·2^s ≡ 0 modulo 2^W for every W ≤ 64
    else:
        hi_lim = hi >> s
        lo_lim = lo >> s
        if (lo_lim << s) != lo:
            lo_lim += 1  # ceil(lo / 2^s)
        over = v > hi_lim or v < lo_lim
        wrapped = _wrap(v << s, hi, ws, sg) if over else 0
    if not over:
        return _fit(v << s, lo, hi, ws, sg, omode)
    if omode == WRAP:
        return wrapped, 0, 1
    if v > 0:
        return hi, 1, 0
    if omode == SAT_SYM and sg == 1:
        return -hi, 1, 0
    return lo, 1, 0


# Rounding rule as bits, so that the per-value decision has no branch on the mode:
# up = (ABOVE & above) | (tie & (TIE | TIE_NEG & neg | TIE_POS & !neg | TIE_ODD & odd))
#      | (INEXACT_NEG & inexact & neg)
_ABOVE, _TIE, _TIE_NEG, _TIE_POS, _TIE_ODD, _INEXACT_NEG = 1, 2, 4, 8, 16, 32


@NJIT
def mode_bits(rmode):
    """The rounding rule of mode code ``rmode`` as a bit mask (computed once per kernel call)."""
    if rmode == TRN:
        return 0
    if rmode == TRN_ZERO:
        return _INEXACT_NEG
    if rmode == RND:
        return _ABOVE | _TIE
    if rmode == RND_ZERO:
        return _ABOVE | _TIE_NEG
    if rmode == RND_INF:
        return _ABOVE | _TIE_POS
    return _ABOVE | _TIE_ODD


@NJIT
def _inc(above, tie, inexact, neg, odd, mb):
    """Rounding increment (0 or 1) from the facts about the discarded part; branch-free.

    ``above``: it exceeds half an LSB; ``tie``: it is exactly half; ``inexact``: it is not zero;
    ``neg``: the value is negative; ``odd``: the truncated (floor) result is odd; ``mb``: the
    rule, from :func:`mode_bits`.
    """
    a = 1 if above else 0
    t = 1 if tie else 0
    x = 1 if inexact else 0
    n = 1 if neg else 0
    o = 1 if odd else 0
    tie_up = (mb >> 1) | ((mb >> 2) & n) | ((mb >> 3) & (1 - n)) | ((mb >> 4) & o)
    return ((mb & a) | (t & tie_up) | ((mb >> 5) & x & n)) & 1


@NJIT
def _round_inc(q, r, half, mb):
    """Increment rounding ``q + r / (2 half)``, floor ``q``, remainder ``0 ≤ r < 2 half``."""
    return _inc(r > half, r == half, r != 0, q < 0, (q & 1) == 1, mb)


@NJIT
def _shr_round(v, sh, mb):
    """``v / 2^sh`` rounded to an integer (``sh ≥ 0``, any size). Never overflows ``int64``."""
    if sh <= 0:
        return v
    if sh > 62:
        # keep floor(v / 2^k) and a sticky bit for what falls off; 62 bits of shift remain
        k = sh - 61
        if k >= 64:
            top = -1 if v < 0 else 0
            sticky = 1 if v != 0 else 0
        elif k == 63:
            top = v >> 63
            sticky = 1 if (v & _I64_MAX) != 0 else 0
        else:
            top = v >> k
            sticky = 1 if (v & ((1 << k) - 1)) != 0 else 0
        v = 2 * top + sticky
        sh = 62
    q = v >> sh
    r = v & ((1 << sh) - 1)
    return q + _round_inc(q, r, 1 << (sh - 1), mb)


@NJIT
def _add_fit(a, b, lo, hi, ws, sg, omode):
    """Put the exact ``a + b`` into the register, also when the sum leaves ``int64``."""
    ha = a >> 1
    hb = b >> 1
    la = a & 1
    lb = b & 1
    u = ha + hb + (la & lb)  # a + b = 2u + (la ^ lb); |u| < 2^63, no overflow
    if -_TWO62 <= u < _TWO62:
        return _fit(2 * u + (la ^ lb), lo, hi, ws, sg, omode)
    # the exact sum is outside int64, hence outside every register of at most 64 bits
    if omode == WRAP:
        return _wrap((u << 1) | (la ^ lb), hi, ws, sg), 0, 1
    if u > 0:
        return hi, 1, 0
    if omode == SAT_SYM and sg == 1:
        return -hi, 1, 0
    return lo, 1, 0


@NJIT
def _round_float(y, mb):
    """Round the float ``y`` (``|y| < 2^62``) to an integer; exact, no double rounding."""
    fl = math.floor(y)
    r = y - fl  # exact: y and floor(y) share the binade or floor(y) has fewer bits
    q = np.int64(fl)
    return q + _inc(r > 0.5, r == 0.5, r != 0.0, y < 0.0, (q & 1) == 1, mb)


@NJIT
def _exact_in_float(x, y):
    """True when ``y = x · 2^F`` is exact and small enough for :func:`_round_float`."""
    a = abs(y)
    return a < _TWO62_F and (a >= _TINY_F or x == 0.0)


@NJIT
def _quantize_slow(x, frac_bits, lo, hi, ws, sg, mb, omode):
    """One float64 by integer arithmetic: ``x = m · 2^(ex - 53)`` exactly, ``|m| < 2^53``."""
    if x == 0.0:
        return _fit(0, lo, hi, ws, sg, omode)
    mant, ex = math.frexp(x)
    m = np.int64(mant * _TWO53_F)
    s = ex - 53 + frac_bits
    if s >= 0:
        return _shl_fit(m, s, lo, hi, ws, sg, omode)
    return _fit(_shr_round(m, -s, mb), lo, hi, ws, sg, omode)


# ---------------------------------------------------------------------------------------------
# array kernels of the arithmetic core
# ---------------------------------------------------------------------------------------------


@NJIT
def quantize_kernel(x, frac_bits, spec, rmode, omode):
    """float64[n] → codes int64[n], n_sat, n_wrap.

    Pass 1 rounds every value whose scaled float ``x · 2^F`` is exact (the common case) in a
    tight loop; pass 2 takes the rest (huge, tiny, subnormal, or ``|F| > 960``) the slow exact way.
    """
    n = x.size
    out = np.zeros(n, dtype=np.int64)
    mb = mode_bits(rmode)
    lo, hi, ws, sg = spec[0], spec[1], spec[2], spec[3]
    fast = -960 <= frac_bits <= 960
    scale = math.ldexp(1.0, frac_bits) if fast else 1.0
    n_sat = 0
    n_wrap = 0
    n_slow = n
    if fast:
        n_slow = 0
        for i in range(n):
            y = x[i] * scale
            if _exact_in_float(x[i], y):
                c, s, w = _fit(_round_float(y, mb), lo, hi, ws, sg, omode)
                out[i] = c
                n_sat += s
                n_wrap += w
            else:
                n_slow += 1
    if n_slow:
        for i in range(n):
            if not fast or not _exact_in_float(x[i], x[i] * scale):
                c, s, w = _quantize_slow(x[i], frac_bits, lo, hi, ws, sg, mb, omode)
                out[i] = c
                n_sat += s
                n_wrap += w
    return out, n_sat, n_wrap


@NJIT
def requantize_kernel(v, shift, spec, rmode, omode):
    """codes int64[n] with ``F_src`` → codes with ``F_dst = F_src + shift``, n_sat, n_wrap."""
    n = v.size
    out = np.empty(n, dtype=np.int64)
    mb = mode_bits(rmode)
    lo, hi, ws, sg = spec[0], spec[1], spec[2], spec[3]
    n_sat = 0
    n_wrap = 0
    if 0 <= shift < 64:  # widening: exact unless the shifted value leaves the range
        hi_lim = hi >> shift
        lo_lim = -((-lo) >> shift) if lo > -_I64_MAX else lo >> shift  # ceil(lo / 2^shift)
        for i in range(n):
            if lo_lim <= v[i] <= hi_lim:
                c, s, w = _fit(v[i] << shift, lo, hi, ws, sg, omode)
            else:
                c, s, w = _shl_fit(v[i], shift, lo, hi, ws, sg, omode)
            out[i] = c
            n_sat += s
            n_wrap += w
    elif shift >= 64:
        for i in range(n):
            c, s, w = _shl_fit(v[i], shift, lo, hi, ws, sg, omode)
            out[i] = c
            n_sat += s
            n_wrap += w
    elif shift >= -62:  # the common case, kept in a tight loop
        sh = -shift
        mask = (1 << sh) - 1
        half = 1 << (sh - 1)
        for i in range(n):
            q = v[i] >> sh
            c, s, w = _fit(q + _round_inc(q, v[i] & mask, half, mb), lo, hi, ws, sg, omode)
            out[i] = c
            n_sat += s
            n_wrap += w
    else:
        for i in range(n):
            c, s, w = _fit(_shr_round(v[i], -shift, mb), lo, hi, ws, sg, omode)
            out[i] = c
            n_sat += s
            n_wrap += w
    return out, n_sat, n_wrap


@NJIT
def range_kernel(v):
    """``(min, max)`` of int64[n] in one pass (n ≥ 1): the wrappers' range check."""
    lo = v[0]
    hi = v[0]
    for i in range(1, v.size):
        lo = min(lo, v[i])
        hi = max(hi, v[i])
    return lo, hi


@NJIT
def count_ends_kernel(v, lo, hi):
    """How many of int64[n] equal ``lo`` or ``hi``, in one pass (codes at either end of a range:
    the ADC's clipped samples)."""
    n = 0
    for i in range(v.size):
        n += (v[i] == lo) | (v[i] == hi)
    return n


@NJIT
def lincomb_kernel(big, s_big, k_big, small, s_small, k_small):
    """Full precision ``k_big·(big << s_big) + k_small·(small << s_small)``, ``k = ±1``.

    ``big`` is ``(n, m)``; ``small`` is ``(m,)`` (broadcast over rows) or ``(1,)`` (a scalar).
    The caller proved that every term and the result fit the result format (≤ 64 bits), and
    that the negated term is never ``-2^63``.
    """
    n, m = big.shape
    out = np.empty((n, m), dtype=np.int64)
    if small.size == 1:
        c = k_small * (small[0] << s_small)
        for i in range(n):
            for j in range(m):
                out[i, j] = k_big * (big[i, j] << s_big) + c
    else:
        for i in range(n):
            for j in range(m):
                out[i, j] = k_big * (big[i, j] << s_big) + k_small * (small[j] << s_small)
    return out


@NJIT
def mul_kernel(big, small):
    """Full precision ``big · small`` broadcast as in :func:`lincomb_kernel`; ``W_a + W_b ≤ 64``."""
    n, m = big.shape
    out = np.empty((n, m), dtype=np.int64)
    if small.size == 1:
        c = small[0]
        for i in range(n):
            for j in range(m):
                out[i, j] = big[i, j] * c
    else:
        for i in range(n):
            for j in range(m):
                out[i, j] = big[i, j] * small[j]
    return out


@NJIT
def bin_rows_kernel(x, factor):
    """``x[b, r, c]`` → ``Σ_i x[b, r·factor + i, c]``, full precision (proven to fit)."""
    nb, nr, nc = x.shape
    out = np.zeros((nb, nr // factor, nc), dtype=np.int64)
    for b in range(nb):
        for r in range(nr):
            ro = r // factor
            for c in range(nc):
                out[b, ro, c] += x[b, r, c]
    return out


@NJIT
def accumulate_kernel(x, spec, omode, checked):
    """Sum ``x[b, j, p]`` over ``j`` in order into a register: → acc[b, p], n_sat, n_wrap.

    Every partial sum is put into the register (``_add_fit``): that is what a hardware
    accumulator does, so a saturating accumulator depends on the order, and a wrapping one
    counts every addition whose exact result left the range. ``checked = False`` is the fast
    path for an accumulator proven wide enough (no partial sum can overflow).
    """
    nb, nj, npx = x.shape
    acc = np.zeros((nb, npx), dtype=np.int64)
    lo, hi, ws, sg = spec[0], spec[1], spec[2], spec[3]
    n_sat = 0
    n_wrap = 0
    for b in range(nb):
        for j in range(nj):
            if checked:
                for p in range(npx):
                    c, s, w = _add_fit(acc[b, p], x[b, j, p], lo, hi, ws, sg, omode)
                    acc[b, p] = c
                    n_sat += s
                    n_wrap += w
            else:
                for p in range(npx):
                    acc[b, p] += x[b, j, p]
    return acc, n_sat, n_wrap


@NJIT
def mac_frames_kernel(x, coef, spec, omode, checked):
    """``acc[b, p] = Σ_j coef[j] · x[b, j, p]`` in order ``j = 0, 1, …`` into a register."""
    nb, nj, npx = x.shape
    acc = np.zeros((nb, npx), dtype=np.int64)
    lo, hi, ws, sg = spec[0], spec[1], spec[2], spec[3]
    n_sat = 0
    n_wrap = 0
    for b in range(nb):
        for j in range(nj):
            cj = coef[j]
            if checked:
                for p in range(npx):
                    c, s, w = _add_fit(acc[b, p], cj * x[b, j, p], lo, hi, ws, sg, omode)
                    acc[b, p] = c
                    n_sat += s
                    n_wrap += w
            else:
                for p in range(npx):
                    acc[b, p] += cj * x[b, j, p]
    return acc, n_sat, n_wrap


@NJIT
def fir_kernel(x, h, spec, omode, checked):
    """Causal FIR along axis 0 with zero initial state into an accumulator register.

    ``acc[t, p] = Σ_k h[k] · x[t - k, p]``, taps added in order ``k = 0, 1, …`` (newest sample
    first); samples before ``t = 0`` are zero and add nothing.
    """
    nt, npx = x.shape
    acc = np.zeros((nt, npx), dtype=np.int64)
    lo, hi, ws, sg = spec[0], spec[1], spec[2], spec[3]
    n_sat = 0
    n_wrap = 0
    for k in range(h.size):
        hk = h[k]
        for t in range(k, nt):
            if checked:
                for p in range(npx):
                    c, s, w = _add_fit(acc[t, p], hk * x[t - k, p], lo, hi, ws, sg, omode)
                    acc[t, p] = c
                    n_sat += s
                    n_wrap += w
            else:
                for p in range(npx):
                    acc[t, p] += hk * x[t - k, p]
    return acc, n_sat, n_wrap


@NJIT
def matvec_kernel(x, g, spec, omode, checked):
    """``acc[f, s] = Σ_p g[s, p] · x[f, p]`` in order ``p = 0, 1, …`` into a register."""
    nf, npx = x.shape
    ns = g.shape[0]
    acc = np.zeros((nf, ns), dtype=np.int64)
    lo, hi, ws, sg = spec[0], spec[1], spec[2], spec[3]
    n_sat = 0
    n_wrap = 0
    for f in range(nf):
        for s_ in range(ns):
            a = np.int64(0)
            if checked:
                for p in range(npx):
                    c, s, w = _add_fit(a, g[s_, p] * x[f, p], lo, hi, ws, sg, omode)
                    a = c
                    n_sat += s
                    n_wrap += w
            else:
                for p in range(npx):
                    a += g[s_, p] * x[f, p]
            acc[f, s_] = a
    return acc, n_sat, n_wrap


# ---------------------------------------------------------------------------------------------
# the float level's CMS on integer codes (chiptwin.dsp.pipeline)
# ---------------------------------------------------------------------------------------------


@NJIT
def cms_float_kernel(codes, m, dark):
    """``(Σ signal / m − Σ reset / m) − dark`` of ``[F, 2m, P]`` codes (int64, or the ADC's
    uint16/uint32) and a ``float64[P]`` dark reference, ``float64[F, P]``, the sums in
    ``int64``; and the smallest and largest code.

    The float reference's CMS means are these quotients when every sum is exact in ``float64``
    (``m · max|code| < 2^53``: then any order of float adds gives the integer sum): the caller
    checks that with the range returned, before the sums could overflow ``int64`` too. The
    subtraction is the reference's ``cms − dark`` (``dark = 0`` leaves the CMS bit for bit).
    """
    n_frames, _, n_pix = codes.shape
    out = np.empty((n_frames, n_pix))
    reset = np.empty(n_pix, np.int64)
    signal = np.empty(n_pix, np.int64)
    lo = codes[0, 0, 0] if codes.size else 0
    hi = lo
    for f in range(n_frames):
        reset[:] = 0
        signal[:] = 0
        for i in range(m):
            for p in range(n_pix):
                a = codes[f, i, p]
                b = codes[f, m + i, p]
                reset[p] += a
                signal[p] += b
                lo = min(lo, a, b)
                hi = max(hi, a, b)
        for p in range(n_pix):
            out[f, p] = (signal[p] / m - reset[p] / m) - dark[p]
    return out, lo, hi
