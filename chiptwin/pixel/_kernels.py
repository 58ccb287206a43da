"""numba kernels of the pixel stage: arrays and scalars in, arrays out, no checks.

The validating wrappers are :func:`chiptwin.pixel.chain.sensor_chain` and
:func:`chiptwin.pixel.frames.binned_codes`. Random draws come from :mod:`chiptwin.pixel._random`:
the caller's bit-generator state advanced inline (a *source*), NumPy's samplers on it.

:func:`frame_codes` (the ``binned`` level) draws, bit for bit, what ``sample_frame`` draws frame
by frame on the caller's ``Generator`` (its PCG64 or SFC64 state passed as a source, or the
``Generator`` itself for any other bit generator): NumPy's Poisson, NumPy's ziggurat (tested).
:func:`chain_chunk` (``sensor_chain``, the large-array path) draws its counts with
:func:`~chiptwin.pixel._random.poisson_fast` (Ahrens & Dieter above a mean of 10: the same law,
not NumPy's draws) from its chunk's own streams.
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT, NJIT_INLINE, NJIT_NORC
from chiptwin.pixel._random import poisson, poisson_fast, standard_normal

#: ``shot_noise`` codes of :func:`chain_chunk`.
SHOT_POISSON: int = 0
SHOT_GAUSSIAN: int = 1


@NJIT_INLINE
def gaussian_count(shot, normal, lam: float, min_mean: float, fast: bool) -> float:
    """Approximate Poisson count: ``max(0, rint(lam + √lam·z))``, z from the source ``normal``,
    when ``lam ≥ min_mean``; below it an exact count from the source ``shot``:
    :func:`~chiptwin.pixel._random.poisson_fast` if ``fast``, else NumPy's
    :func:`~chiptwin.pixel._random.poisson`."""
    if lam < min_mean:
        return float(poisson_fast(shot, lam) if fast else poisson(shot, lam))
    return max(0.0, np.rint(lam + math.sqrt(lam) * standard_normal(normal)))


@NJIT
def adc_code(volts: float, v_min: float, lsb: float, gain: float, offset: float, top: float) -> int:
    """``clip(rint((v − v_min)/lsb·gain + offset), 0, top)``, the order of ``adc_convert``."""
    x = np.rint((volts - v_min) / lsb * gain + offset)
    if x < 0.0:
        return 0
    if x > top:
        return int(top)
    return int(x)


_SQRT_HALF = math.sqrt(0.5)
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


@NJIT
def _tail_sums(a: float, n: float, sd: float, coeffs) -> tuple[float, float]:
    """``Σ_{j=1}^{n} Q(t_j)`` and ``Σ_{j=1}^{n} (2j − 1) Q(t_j)``, ``t_j = (j − ½ − a)/sd``, by the
    midpoint Euler–Maclaurin formula with the coefficients ``coeffs`` (a tuple;
    :func:`chiptwin.pixel.adc._end_moments` states the integrals and derivatives)."""
    t0, t1 = -a / sd, (n - a) / sd
    q0, q1 = 0.5 * math.erfc(t0 * _SQRT_HALF), 0.5 * math.erfc(t1 * _SQRT_HALF)
    p0, p1 = math.exp(-0.5 * t0 * t0) * _INV_SQRT_2PI, math.exp(-0.5 * t1 * t1) * _INV_SQRT_2PI
    s0 = sd * ((t1 * q1 - p1) - (t0 * q0 - p0))
    s1 = 2.0 * a * s0 + sd * sd * (((t1 * t1 - 1.0) * q1 - t1 * p1)
                                   - ((t0 * t0 - 1.0) * q0 - t0 * p0))
    inv = 1.0 / sd
    for end in range(2):
        t, q, p = (t1, q1, p1) if end == 0 else (t0, q0, p0)
        w, sign = (2.0 * n, 1.0) if end == 0 else (0.0, -1.0)  # 2x − 1 at x = n + ½, ½
        h_odd, h_even = 0.0, 1.0  # He_{2m−3}, He_{2m−2} (He_{−1} = 0)
        pow_k = inv  # sd^{−k}, k = 2m − 1
        for m in range(len(coeffs)):
            k = 2 * m + 1
            f_k = -pow_k * h_even * p  # f^{(k)}, k odd
            f_k1 = q if m == 0 else pow_k * sd * h_odd * p  # f^{(k−1)}, k − 1 even
            s0 += sign * coeffs[m] * f_k
            s1 += sign * coeffs[m] * (w * f_k + 2.0 * k * f_k1)
            h_odd = t * h_even - (k - 1) * h_odd  # He_k
            h_even = t * h_odd - k * h_even  # He_{k+1}
            pow_k *= inv * inv
    return s0, s1


@NJIT
def end_moments(mu, sd, top, coeffs, mean, var):
    """Mean and variance of ``clip(rint(X), 0, top)``, ``X ~ N(mu[i], sd[i]²)``, about
    ``c = clip(rint(mu), 0, top)`` by two tail sums on either side
    (:func:`chiptwin.pixel.adc._end_moments`)."""
    for i in range(mu.size):
        c = min(max(np.rint(mu[i]), 0.0), top)
        up0, up1 = _tail_sums(mu[i] - c, top - c, sd[i], coeffs)
        lo0, lo1 = _tail_sums(c - mu[i], c, sd[i], coeffs)
        d1 = up0 - lo0
        mean[i] = c + d1
        var[i] = max(up1 + lo1 - d1 * d1, 0.0)


#: Pixels whose samples :func:`chain_chunk` converts together as built: the voltages of a block
#: (``2M × 256 × 8 B``, 16 kB at M = 4) stay in the L1 cache; a whole chunk's went to memory and
#: back (≈ 15 ns a conversion more, measured).
CONVERT_BLOCK: int = 256

#: Cells of the search LUT per LSB: a cell holds at most one transition unless a code is
#: narrower than 1/CELLS_PER_LSB LSB (then the search walks the levels). A power of two.
CELLS_PER_LSB: float = 2.0


@NJIT_INLINE
def _lut_cell(x: float, x_lo: float, x_hi: float, base: int) -> tuple[float, int]:
    """``x`` clamped into the LUT's first and last cells (``x_lo``, ``x_hi``: their lower
    edges) and its cell's column: scaled by a power of two and floored, which is exact."""
    xc = min(max(x, x_lo), x_hi)
    return xc, int(math.floor(xc * CELLS_PER_LSB)) - base


@NJIT
def table_code(x: float, levels: np.ndarray, lut: np.ndarray, base: int, r: int) -> int:
    """Code of the continuous input ``x`` (not NaN) on ramp ``r`` of the levels ``levels``.

    ``levels[r]`` holds the ``n`` non-decreasing levels of ramp ``r`` and a last column of +inf.
    Code ``k`` covers ``levels[r, k−1] ≤ x < levels[r, k]``: the code is
    ``#{levels ≤ x}``. On a level exactly (``lo = #{< x}`` < ``hi = #{≤ x}``) it is ``lo`` if
    ``lo`` is even, else ``hi``: half to even, so the ideal table ``k + 0.5`` gives
    ``numpy.rint`` bit for bit.

    The LUT ``lut[r, c] = (level, below)`` (each ramp's cells together: a converter's samples,
    spread by noise over some codes, read one stretch of memory; level-major storage, which
    interleaves the ramps, ran 5–10× slower with a table per column, measured): cell ``c`` is
    ``[(base + c)/CELLS_PER_LSB, (base + c + 1)/CELLS_PER_LSB)``, ``below`` counts the levels
    under it and ``level`` is its one level (+inf if none, NaN if several: then the levels are
    walked). The first and last cells lie beyond every level; ``x`` is clamped into them
    (:func:`_lut_cell`). The kernels' loop (:func:`_table_rows`) writes the rest out.
    """
    xc, c = _lut_cell(x, base / CELLS_PER_LSB, (base + lut.shape[1] - 1) / CELLS_PER_LSB, base)
    t = lut[r, c, 0]
    k = np.int64(lut[r, c, 1])
    if t == t:  # at most one level in the cell: one comparison, no search
        return k + int(xc > t) + int(xc == t) * (k & 1)
    return _walk(xc, levels, k, r)


@NJIT
def _walk(x: float, levels: np.ndarray, k: int, r: int) -> int:
    """:func:`table_code` in a cell of several levels: walk from the ``k`` below it. Not
    inlined: the loops, rarely run, would slow the one-comparison path threefold (measured)."""
    hi = k
    while levels[r, hi] <= x:
        hi += 1
    if levels[r, hi - 1] == x:  # on a level: half to even
        lo = hi - 1
        while lo > 0 and levels[r, lo - 1] == x:
            lo -= 1
        if lo % 2 == 0:
            return lo
    return hi


def sample_noise(read_noise_e, cg_V, gain, noise_lsb, lsb, pixel_gain):
    """Per-pixel rms of one sample's read noise with the comparator noise folded in. Unit: e⁻.

    The comparator adds ``noise_lsb·z'`` to the continuous code, the read noise
    ``read_noise_e·z·cg_V/lsb·gain·pixel_gain``; both are white, Gaussian and independent per
    conversion, so their sum is one Gaussian: ``read_noise_e`` becomes
    ``√(read_noise_e² + (noise_lsb·lsb/(cg_V·gain·pixel_gain))²)``. The pixel kernels draw that,
    one normal per sample as today (no extra draw: no stream moves, and the comparator costs
    nothing); :func:`convert_rows` draws ``z'`` itself for ``Converter.convert``.
    """
    return np.sqrt(read_noise_e**2 + (noise_lsb * lsb / (cg_V * gain * pixel_gain)) ** 2)


@NJIT
def convert_rows(volts, out, v_min, lsb, gain, offset, top, conv, source):
    """Convert ``volts`` ``(R, n)`` into ``out`` ``(R, n)`` by the converters as built, converter
    ``i`` for column ``i``; comparator draws from the source ``source`` in C order (row-major).

    ``conv = (built, pixel_gain, pixel_offset, table_of_pixel, noise_lsb, levels, lut, base,
    read_e)`` (``levels, lut, base`` as in :func:`table_code`; ``read_e`` unused here; ``built``
    is True here: the ideal converter is
    :func:`adc_code`, inline in the kernels). Per conversion: the continuous code
    ``x = (v − v_min)/lsb·gain + offset`` (today's arithmetic), then the converter's own
    ``x·pixel_gain[i] + pixel_offset[i]``, then (if ``noise_lsb > 0``) ``+ noise_lsb·z``; then
    :func:`table_code` on ramp ``table_of_pixel[i]``, or round and clip as :func:`adc_code` when
    there is no table (``levels`` with 0 rows).

    A kernel of its own, called once per block of conversions: the lookup inlined at every
    sample of the pixel loops, with the tables passed down, cost 30–50 ns a conversion (numba
    reference-counts the arrays at each inlined call; measured), against a few ns here. The
    comparator draws are made first, into an array, for the same reason.
    """
    dither = np.empty(volts.shape if conv[4] > 0.0 else (0, 0))
    convert_rows_into(volts, out, v_min, lsb, gain, offset, top, conv, source, dither)


@NJIT_NORC
def convert_rows_into(volts, out, v_min, lsb, gain, offset, top, conv, source, dither):
    """:func:`convert_rows` with the comparator draws' buffer given (``volts.shape`` when
    ``noise_lsb > 0``, else ``(0, 0)``): it allocates nothing, so it draws without reference
    counting (``NJIT_NORC``) and the pixel loops, compiled so too, can call it."""
    _, c_gain, c_offset, rows, noise, levels, lut, base, _ = conv
    for m in range(dither.shape[0]):
        for i in range(dither.shape[1]):
            dither[m, i] = noise * standard_normal(source)
    args = (volts, out, v_min, lsb, gain, offset, c_gain, c_offset, dither)
    if levels.shape[0] > 0:
        _table_rows(*args, rows, levels, lut, base)
    else:
        _round_rows(*args, top)


@NJIT
def _round_rows(volts, out, v_min, lsb, gain, offset, c_gain, c_offset, dither, top):
    """:func:`convert_rows` without a table: mismatch and dither, then round and clip."""
    noisy = dither.shape[0] > 0
    for m in range(volts.shape[0]):
        for i in range(volts.shape[1]):
            x = (volts[m, i] - v_min) / lsb * gain + offset
            x = x * c_gain[i] + c_offset[i]
            if noisy:
                x = x + dither[m, i]
            out[m, i] = adc_code(x, 0.0, 1.0, 1.0, 0.0, top)


@NJIT
def _table_rows(volts, out, v_min, lsb, gain, offset, c_gain, c_offset, dither, rows, levels,
                lut, base):  # fmt: skip
    """:func:`convert_rows` with a table: :func:`table_code` written out (its arrays passed to an
    inlined call at every conversion, or a generator call anywhere in this loop, cost 10–25 ns
    a conversion more; measured)."""
    noisy = dither.shape[0] > 0
    x_lo, x_hi = base / CELLS_PER_LSB, (base + lut.shape[1] - 1) / CELLS_PER_LSB
    for m in range(volts.shape[0]):
        for i in range(volts.shape[1]):
            x = (volts[m, i] - v_min) / lsb * gain + offset
            x = x * c_gain[i] + c_offset[i]
            if noisy:
                x = x + dither[m, i]
            r = rows[i]
            xc, c = _lut_cell(x, x_lo, x_hi, base)
            t = lut[r, c, 0]
            k = np.int64(lut[r, c, 1])
            if t == t:
                out[m, i] = k + int(xc > t) + int(xc == t) * (k & 1)
            else:
                out[m, i] = _walk(xc, levels, k, r)


@NJIT
def _count_below(x: float, levels: np.ndarray, lut: np.ndarray, base: int, r: int,
                 inclusive: bool) -> int:
    """``#{levels of ramp r < x}`` (``≤ x`` if ``inclusive``): ``np.searchsorted`` of the
    levels, side ``left`` (``right``), without its binary search: the LUT cell of ``x`` counts
    the levels below the cell, then a walk over the cell's level(s). The last column's +inf
    stops the walk."""
    _, c = _lut_cell(x, base / CELLS_PER_LSB, (base + lut.shape[1] - 1) / CELLS_PER_LSB, base)
    k = np.int64(lut[r, c, 1])
    if inclusive:
        while levels[r, k] <= x:
            k += 1
    else:
        while levels[r, k] < x:
            k += 1
    return k


@NJIT
def table_moments(mu, sd, rows, lut, window, out_mean, out_var):
    """Mean and variance of the code for ``X ~ N(mu[i], sd[i]²)`` on the levels of ramp
    ``rows[i]``; ``lut = (levels, lut, base)`` as in :func:`table_code`.

    ``P(code = k) = S(levels[k−1]) − S(levels[k])`` with ``S(t) = P(X ≥ t)``, summed over the
    codes whose levels lie within ``± window·sd`` (beyond: ``S = 1`` below, ``0`` above), centred
    on the code of ``mu`` for precision. ``sd = 0``: the code of ``mu`` (:func:`table_code`).
    """
    levels = lut[0]
    for i in range(mu.size):
        r, m, s = rows[i], mu[i], sd[i]
        centre = table_code(m, levels, lut[1], lut[2], r)
        if s == 0.0:
            out_mean[i], out_var[i] = float(centre), 0.0
            continue
        j0 = _count_below(m - window * s, levels, lut[1], lut[2], r, False)
        j1 = _count_below(m + window * s, levels, lut[1], lut[2], r, True)
        s_prev, m1, m2 = 1.0, 0.0, 0.0
        scale = 1.0 / (s * math.sqrt(2.0))
        for k in range(j0, j1 + 1):
            s_next = 0.5 * math.erfc((levels[r, k] - m) * scale) if k < j1 else 0.0
            p = s_prev - s_next
            d = float(k - centre)
            m1 += p * d
            m2 += p * d * d
            s_prev = s_next
        out_mean[i] = centre + m1
        out_var[i] = max(m2 - m1 * m1, 0.0)


@NJIT
def chain_chunk(
    shot_state, normal_state, photons, gain_map, dark_e, qe, full_well, ktc, read_noise, true_cds,
    read_reset, shot_noise, gauss_min_mean, pedestal, cg_V, v_min, lsb, adc_gain, offset, top,
    conv, reset_out, signal_out, col0,
):  # fmt: skip
    """One frame of one chunk of pixels: charge, kTC, read noise, ADC. Codes into the outputs.

    Per pixel: the count, one merged Poisson draw of ``qe·gain·photons + dark`` from
    ``shot_state`` (SFC64, ``uint64[4]``, advanced and written back), or its Gaussian
    approximation, clipped at ``full_well``; then, in this order from ``normal_state``
    (SFC64, advanced in place too): the Gaussian
    level's normal (if used), the signal kTC draw (if ``ktc > 0``), the reset kTC draw (if
    ``ktc > 0``, ``read_reset`` and not ``true_cds``), the M reset samples' read noise (if
    ``read_reset``), the M signal samples' read noise. ``reset_out`` and ``signal_out`` are the
    frame's whole ``(M, N)`` codes (``reset_out`` unused unless ``read_reset``); the chunk's
    pixels are their columns ``col0 … col0 + n − 1``. (Passing the frame's arrays, not the
    chunk's column slices, keeps one compiled version: a slice is C-contiguous when the frame is
    one chunk and strided when it is several, two signatures of ≈ 15 s of compilation each.)
    Electrons and volts are formed as in ``sample_frame`` and ``to_volts``. The ideal converter
    (``conv[0]`` False) converts each sample as it is formed (:func:`adc_code`, today's
    arithmetic). As built, the sample voltages of each block of :data:`CONVERT_BLOCK` pixels are
    kept and converted after the block by :func:`convert_rows` (the per-pixel arrays sliced to
    the block): its reset samples ``(M, block)``, then its signal samples. Comparator noise
    comes folded into the read noise (``conv[8]``, see :func:`sample_noise`): nothing more is
    drawn.
    """
    state = shot_state.copy()  # private copies: threads never write neighbouring cache lines
    normal = normal_state.copy()
    n_samples = signal_out.shape[0]
    block = CONVERT_BLOCK if conv[0] else 0
    v_reset = np.empty((n_samples if read_reset else 0, block))
    v_signal = np.empty((n_samples, block))
    dither = np.empty((n_samples, block) if conv[4] > 0.0 else (0, 0))
    _chain_pixels(
        state, normal, photons, gain_map, dark_e, qe, full_well, ktc, read_noise, true_cds,
        read_reset, shot_noise, gauss_min_mean, pedestal, cg_V, v_min, lsb, adc_gain, offset, top,
        conv, reset_out, signal_out, col0, v_reset, v_signal, dither,
    )  # fmt: skip
    shot_state[:] = state
    normal_state[:] = normal


@NJIT_NORC
def _chain_pixels(
    state, normal, photons, gain_map, dark_e, qe, full_well, ktc, read_noise, true_cds, read_reset,
    shot_noise, gauss_min_mean, pedestal, cg_V, v_min, lsb, adc_gain, offset, top, conv,
    reset_out, signal_out, col0, v_reset, v_signal, dither,
):  # fmt: skip
    """:func:`chain_chunk`'s pixel loop, without reference counting (``NJIT_NORC``: an atomic
    pair around every draw otherwise, half the chain's time); ``v_reset``, ``v_signal`` and
    ``dither`` are the block buffers its caller allocated (0 columns for the ideal converter;
    ``dither`` as :func:`convert_rows_into` wants it)."""
    n_samples = signal_out.shape[0]
    built, read_e = conv[0], conv[8]
    folded = read_e.shape[0] > 0
    block = v_signal.shape[1]
    for i in range(photons.size):
        lam = qe * gain_map[i] * photons[i] + dark_e[i]
        if shot_noise == SHOT_GAUSSIAN:
            count = gaussian_count(state, normal, lam, gauss_min_mean, True)
        else:
            count = float(poisson_fast(state, lam))
        collected = min(count, full_well)
        k_signal = ktc * standard_normal(normal) if ktc > 0.0 else 0.0
        rn = read_e[i] if folded else read_noise
        if read_reset:
            k_reset = k_signal
            if ktc > 0.0 and not true_cds:
                k_reset = ktc * standard_normal(normal)
            for m in range(n_samples):
                e = k_reset + rn * standard_normal(normal)
                if built:
                    v_reset[m, i % block] = pedestal + e * cg_V
                else:
                    reset_out[m, col0 + i] = adc_code(
                        pedestal + e * cg_V, v_min, lsb, adc_gain, offset, top
                    )
        for m in range(n_samples):
            e = (collected + k_signal) + rn * standard_normal(normal)
            if built:
                v_signal[m, i % block] = pedestal + e * cg_V
            else:
                signal_out[m, col0 + i] = adc_code(
                    pedestal + e * cg_V, v_min, lsb, adc_gain, offset, top
                )
        if built and (i % block == block - 1 or i == photons.size - 1):
            lo, hi = i - i % block, i + 1  # a block's samples: reset ones, then signal ones
            part = (True, conv[1][lo:hi], conv[2][lo:hi], conv[3][lo:hi], *conv[4:])
            consts = (v_min, lsb, adc_gain, offset, top)
            cols = slice(col0 + lo, col0 + hi)
            n_reset = v_reset.shape[0]
            convert_rows_into(v_reset[:, : hi - lo], reset_out[:, cols], *consts, part, normal,
                              dither[:n_reset, : hi - lo])
            convert_rows_into(v_signal[:, : hi - lo], signal_out[:, cols], *consts, part, normal,
                              dither[:, : hi - lo])


@NJIT
def frame_codes(
    source, normal, mean_e, report_pixels, report_e, full_well, ktc, read_noise, true_cds,
    pedestal, cg_V, v_min, lsb, adc_gain, offset, top, gauss_min_mean, conv, codes_out,
):  # fmt: skip
    """Frames of the ``binned`` level, one after another: the counts from ``source``, the kTC,
    read-noise and comparator normals from ``normal`` (each the caller's ``Generator``, or its
    PCG64/SFC64 state: :mod:`~chiptwin.pixel._random`). One stream passed as both draws in
    ``sample_frame``'s order; two keep the normals the same whatever the counts drew (common
    random numbers across photon, shot, kinetics and optics levels).

    ``mean_e`` is ``(n_frames, n)``: the expected charge of each pixel in each frame. Per frame,
    in the order of ``sample_frame`` (so the draws are its draws): the Poisson count of every
    pixel (:func:`gaussian_count` for means ≥ ``gauss_min_mean``; ``inf`` = exact Poisson
    everywhere), written to ``report_e[f]`` for ``report_pixels`` (the ``events`` level times
    their wells' filling from these counts), then clipped at ``full_well``; if ``ktc > 0`` the
    signal kTC draw of every pixel, then (without ``true_cds``) the reset kTC draw of every
    pixel; the ``(M, n)`` reset samples' read noise, the
    ``(M, n)`` signal samples' read noise. Each sample is formed and converted as in
    ``read_out``, ``to_volts`` and ``adc_convert`` (the ideal ``conv``), or as built by
    :func:`convert_rows`, one sample row of ``n`` pixels at a time, the comparator noise folded
    into the read noise (``conv[8]``, see :func:`sample_noise`): nothing more is drawn.
    ``codes_out`` is ``(n_frames, 2M, n)``, the M reset codes first.
    """
    n, built = mean_e.shape[1], conv[0]
    row = np.empty((1, n if built else 0))
    dither = np.empty((1, n) if built and conv[4] > 0.0 else (0, 0))
    scratch = np.zeros((3, n))  # the counts (then the collected charge), signal and reset kTC
    _frame_loop(
        source, normal, mean_e, report_pixels, report_e, full_well, ktc, read_noise, true_cds,
        pedestal, cg_V, v_min, lsb, adc_gain, offset, top, gauss_min_mean, conv, codes_out, row,
        dither, scratch,
    )  # fmt: skip


@NJIT_NORC
def _frame_loop(
    source, normal, mean_e, report_pixels, report_e, full_well, ktc, read_noise, true_cds,
    pedestal, cg_V, v_min, lsb, adc_gain, offset, top, gauss_min_mean, conv, codes_out, row,
    dither, scratch,
):  # fmt: skip
    """:func:`frame_codes`' loops, without reference counting (``NJIT_NORC``: an atomic pair
    around every draw otherwise); ``row``, ``dither`` and ``scratch`` its caller allocated."""
    n_frames, n = mean_e.shape
    m = codes_out.shape[1] // 2
    built, read_e = conv[0], conv[8]
    folded = read_e.shape[0] > 0
    collected, k_signal, k_reset = scratch[0], scratch[1], scratch[2]
    # the normals of a frame in draw order: kTC (signal, then reset unless true CDS), the M
    # reset sample rows, the M signal sample rows; one call site of the inlined sampler (each
    # site is a copy of the ziggurat for numba to type and compile: five sites cost 25 s of a
    # cold first run, one 22 s)
    n_ktc = (1 if true_cds else 2) if ktc > 0.0 else 0
    for f in range(n_frames):
        for i in range(n):
            collected[i] = gaussian_count(source, source, mean_e[f, i], gauss_min_mean, False)
        for j in range(report_pixels.size):
            report_e[f, j] = collected[report_pixels[j]]
        for i in range(n):
            collected[i] = min(collected[i], full_well)
        for phase in range(n_ktc + 2 * m):
            j = phase - n_ktc  # the sample row: reset rows 0 … M − 1, then the signal rows
            for i in range(n):
                z = standard_normal(normal)
                if phase == 0 and n_ktc > 0:
                    k_signal[i] = ktc * z
                    if true_cds:
                        k_reset[i] = k_signal[i]
                    continue
                if j < 0:
                    k_reset[i] = ktc * z
                    continue
                rn = read_e[i] if folded else read_noise
                e = (k_reset[i] if j < m else collected[i] + k_signal[i]) + rn * z
                volts = pedestal + e * cg_V
                if built:
                    row[0, i] = volts
                else:
                    codes_out[f, j, i] = adc_code(volts, v_min, lsb, adc_gain, offset, top)
            if built and j >= 0:
                convert_rows_into(
                    row, codes_out[f, j : j + 1], v_min, lsb, adc_gain, offset, top, conv, normal,
                    dither,
                )  # fmt: skip
