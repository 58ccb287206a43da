"""Random draws inside the pixel kernels: NumPy's bit generators and samplers, inline in numba.

Why inline. Through numba's ``Generator`` interface every 64 random bits are a call through a
function pointer (≈ 6 ns against ≈ 1–2 ns inline); the pixel kernels draw one Poisson count and
2M + 1 normals per pixel-frame, so that call was most of a study row's sampling time. Here the
state of the caller's bit generator is copied into a ``uint64`` array, advanced in numba, and
written back (:func:`state_of`, :func:`put_state`): the draws are the bits NumPy's own
``Generator`` would give from the same state, and it is left where NumPy would leave it (tested
draw for draw against ``Generator.random``, ``standard_normal`` and ``poisson``). The loops that
draw are compiled without reference counting (:data:`chiptwin._numba.NJIT_NORC`): with it, every
inlined draw whose rare path is a call paid an atomic increment and decrement of the source
array's count, 9 ns of a normal's 11.

A *source* is one of

* an SFC64 state, ``uint64[4]`` (NumPy's ``sfc64_next64``),
* a PCG64 state, ``uint64[2, 2]`` = ``[[state_hi, state_lo], [inc_hi, inc_lo]]`` (NumPy's
  ``pcg64_next64``: the 128-bit LCG step ``state·M + inc``, then the XSL-RR output), or
* a ``numpy.random.Generator`` (numba's interface: any bit generator, the slow path).

Samplers, each NumPy's algorithm on the source (``numpy/random/src/distributions``):
:func:`next_double` (``(x >> 11)·2⁻⁵³``), :func:`standard_normal` (the 256-level ziggurat; the
tables are numba's copy of NumPy's ``ziggurat_constants.h``), :func:`poisson` (multiplication
below a mean of 10, Hörmann's PTRS above). :func:`poisson_ad` is not NumPy's: Ahrens & Dieter's
(1982) normal-based sampler for means ≥ 10, exact in law and ≈ 3× faster than PTRS
(``benchmarks/bench_sensor_chain.py`` prints both, piece by piece).
"""

from __future__ import annotations

import math

import numpy as np
from numba import types
from numba.extending import overload
from numba.np.random import _constants as _zig  # NumPy's ziggurat tables, as numba ships them

from chiptwin._numba import NJIT, NJIT_INLINE, NJIT_NORC

_KI = _zig.ki_double
_WI = _zig.wi_double
_FI = _zig.fi_double
_ZIG_R = _zig.ziggurat_nor_r
_ZIG_INV_R = _zig.ziggurat_nor_inv_r

_U11 = np.uint64(11)
_U24 = np.uint64(24)
_U3 = np.uint64(3)
_U40 = np.uint64(40)
_U32 = np.uint64(32)
_U58 = np.uint64(58)
_U64M = np.uint64(63)
_U1 = np.uint64(1)
_LO32 = np.uint64(0xFFFFFFFF)
#: PCG64's 128-bit multiplier (NumPy's ``PCG_DEFAULT_MULTIPLIER_HIGH``/``LOW``).
_PCG_MUL_HI = np.uint64(2549297995355413924)
_PCG_MUL_LO = np.uint64(4865540595714422341)
_TWO_M53 = 1.0 / 9007199254740992.0


# ----------------------------------------------------------------------------------------------
# Bit generators
# ----------------------------------------------------------------------------------------------


@NJIT_INLINE
def sfc64_next(state: np.ndarray) -> np.uint64:
    """Next 64 bits of the SFC64 generator whose ``uint64[4]`` state is advanced in place."""
    tmp = state[0] + state[1] + state[3]
    state[3] += _U1
    state[0] = state[1] ^ (state[1] >> _U11)
    state[1] = state[2] + (state[2] << _U3)
    state[2] = ((state[2] << _U24) | (state[2] >> _U40)) + tmp
    return tmp


@NJIT_INLINE
def _mulhi(a: np.uint64, b: np.uint64) -> np.uint64:
    """The high 64 bits of the 128-bit product ``a·b`` (32-bit halves; numba has no uint128)."""
    a0, a1 = a & _LO32, a >> _U32
    b0, b1 = b & _LO32, b >> _U32
    p00, p01, p10, p11 = a0 * b0, a0 * b1, a1 * b0, a1 * b1
    mid = (p00 >> _U32) + (p01 & _LO32) + (p10 & _LO32)
    return p11 + (p01 >> _U32) + (p10 >> _U32) + (mid >> _U32)


@NJIT_INLINE
def pcg64_next(state: np.ndarray) -> np.uint64:
    """Next 64 bits of PCG64 (XSL-RR 128/64), state ``uint64[2, 2]`` advanced in place:
    ``s ← s·M + inc`` (mod 2¹²⁸), then ``rotr(hi ^ lo, hi >> 58)`` of the new state."""
    hi, lo = state[0, 0], state[0, 1]
    new_lo = lo * _PCG_MUL_LO
    new_hi = _mulhi(lo, _PCG_MUL_LO) + hi * _PCG_MUL_LO + lo * _PCG_MUL_HI
    lo2 = new_lo + state[1, 1]
    hi2 = new_hi + state[1, 0] + (_U1 if lo2 < new_lo else np.uint64(0))
    state[0, 0], state[0, 1] = hi2, lo2
    x = hi2 ^ lo2
    rot = hi2 >> _U58
    return (x >> rot) | (x << ((_U64M + _U1 - rot) & _U64M))


def next_uint64(source) -> int:
    """Next 64 bits of ``source`` (see the module docstring). Compiled code uses the overload."""
    return int(pcg64_next(source) if source.ndim == 2 else sfc64_next(source))


@overload(next_uint64, jit_options={"cache": True}, inline="always")
def _next_uint64_jit(source):
    if isinstance(source, types.Array) and source.ndim == 2:
        return lambda source: pcg64_next(source)
    if isinstance(source, types.Array):
        return lambda source: sfc64_next(source)
    return None  # a Generator: its samplers are called instead (next_double, standard_normal)


def next_double(source) -> float:
    """Next double in [0, 1) of ``source``: NumPy's ``next_double``, ``(x >> 11)·2⁻⁵³``."""
    if isinstance(source, np.random.Generator):
        return source.random()
    return float(next_uint64(source) >> 11) * _TWO_M53


@overload(next_double, jit_options={"cache": True}, inline="always")
def _next_double_jit(source):
    if isinstance(source, types.Array):
        return lambda source: float(next_uint64(source) >> _U11) * _TWO_M53
    return lambda source: source.random()


# ----------------------------------------------------------------------------------------------
# Normal (ziggurat)
# ----------------------------------------------------------------------------------------------


@NJIT_INLINE
def _ziggurat(source) -> float:
    """NumPy's ``random_standard_normal``: 256 layers; 99.3 % of draws take one 64-bit word
    (8 bits the layer, 1 the sign, 52 the abscissa) and one comparison, inlined into the caller;
    the rest go to :func:`_ziggurat_edge`, a call (the tail's and wedges' logarithms and
    exponential stay out of the callers' loops)."""
    r = next_uint64(source)
    idx = r & np.uint64(0xFF)
    r = r >> np.uint64(8)
    rabs = (r >> _U1) & np.uint64(0x000FFFFFFFFFFFFF)
    x = float(np.int64(rabs)) * _WI[idx]  # rabs < 2⁵²: exact, and one instruction as int64
    if r & _U1:
        x = -x
    if rabs < _KI[idx]:
        return x
    return _ziggurat_edge(source, idx, rabs, x)


@NJIT
def _ziggurat_edge(source, idx, rabs, x) -> float:
    """The draws the ziggurat's rectangles do not decide: the base layer's tail by Marsaglia's
    exponential method, a wedge by rejection under ``exp(−x²/2)``, else a new word."""
    while True:
        if idx == 0:
            while True:
                xx = -_ZIG_INV_R * math.log1p(-next_double(source))
                yy = -math.log1p(-next_double(source))
                if yy + yy > xx * xx:
                    if (rabs >> np.uint64(8)) & _U1:
                        return -(_ZIG_R + xx)
                    return _ZIG_R + xx
        elif (_FI[idx - _U1] - _FI[idx]) * next_double(source) + _FI[idx] < math.exp(-0.5 * x * x):
            return x
        r = next_uint64(source)
        idx = r & np.uint64(0xFF)
        r = r >> np.uint64(8)
        rabs = (r >> _U1) & np.uint64(0x000FFFFFFFFFFFFF)
        x = float(np.int64(rabs)) * _WI[idx]
        if r & _U1:
            x = -x
        if rabs < _KI[idx]:
            return x


def standard_normal(source) -> float:
    """One standard normal from ``source``, bit-identical to ``Generator.standard_normal()``."""
    if isinstance(source, np.random.Generator):
        return float(source.standard_normal())
    return _ziggurat(source)


@overload(standard_normal, jit_options={"cache": True}, inline="always")
def _standard_normal_jit(source):
    if isinstance(source, types.Array):
        return lambda source: _ziggurat(source)
    return lambda source: source.standard_normal()


# ----------------------------------------------------------------------------------------------
# Poisson
# ----------------------------------------------------------------------------------------------

#: Stirling-series coefficients of log Γ (NumPy's ``random_loggam``).
_LOGGAM_COEF = (
    8.333333333333333e-02,
    -2.777777777777778e-03,
    7.936507936507937e-04,
    -5.952380952380952e-04,
    8.417508417508418e-04,
    -1.917526917526918e-03,
    6.410256410256410e-03,
    -2.955065359477124e-02,
    1.796443723688307e-01,
    -1.39243221690590e00,
)


@NJIT
def loggam(x: float) -> float:
    """log Γ(x) for x > 0, NumPy's ``random_loggam`` (Stirling series after shifting x ≥ 7)."""
    if x == 1.0 or x == 2.0:
        return 0.0
    n = 0
    x0 = x
    if x < 7.0:
        n = int(7 - x)
        x0 = x + n
    x2 = 1.0 / (x0 * x0)
    gl0 = _LOGGAM_COEF[9]
    for k in range(8, -1, -1):
        gl0 = gl0 * x2 + _LOGGAM_COEF[k]
    gl = gl0 / x0 + 0.5 * math.log(2.0 * math.pi) + (x0 - 0.5) * math.log(x0) - x0
    if x < 7.0:
        for _ in range(n):
            x0 = x0 - 1.0
            gl = gl - math.log(x0)
    return gl


@NJIT_INLINE
def _poisson_mult(source, lam: float) -> int:
    enlam = math.exp(-lam)
    count = 0
    prod = 1.0
    while True:
        prod *= next_double(source)
        if prod > enlam:
            count += 1
        else:
            return count


@NJIT
def _poisson_ptrs(source, lam: float) -> int:
    slam = math.sqrt(lam)
    loglam = math.log(lam)
    b = 0.931 + 2.53 * slam
    a = -0.059 + 0.02483 * b
    invalpha = 1.1239 + 1.1328 / (b - 3.4)
    vr = 0.9277 - 3.6224 / (b - 2)
    while True:
        u = next_double(source) - 0.5
        v = next_double(source)
        us = 0.5 - abs(u)
        k = math.floor((2 * a / us + b) * u + lam + 0.43)
        if us >= 0.07 and v <= vr:
            return k
        if k < 0 or (us < 0.013 and v > us):
            continue
        lhs = math.log(v) + math.log(invalpha) - math.log(a / (us * us) + b)
        if lhs <= -lam + k * loglam - loggam(k + 1):
            return k


@NJIT_INLINE
def poisson(source, lam: float) -> int:
    """One Poisson count of mean ``lam`` ≥ 0, bit-identical to ``Generator.poisson(lam)`` on the
    same stream (NumPy's ``random_poisson``). numba 0.68's own ``Generator.poisson`` truncates
    with ``int()`` where NumPy floors, which accepts a few zero counts NumPy rejects."""
    if lam >= 10.0:
        return _poisson_ptrs(source, lam)
    if lam == 0.0:
        return 0
    return _poisson_mult(source, lam)


#: 0!…9!: procedure F's Poisson probabilities below 10 (above, :func:`_ad_f` uses log1p and a
#: longer Stirling series instead of Ahrens & Dieter's 7-digit coefficients).
_FACT = (1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0, 5040.0, 40320.0, 362880.0)
_INV_SQRT_2PI = 0.3989422804014327


@NJIT
def _ad_f(k: float, mu: float, s: float, omega: float, c0: float, c1: float, c2: float,
          c3: float) -> tuple[float, float, float, float]:  # fmt: skip
    """Ahrens & Dieter's procedure F: ``py·exp(px)`` is the Poisson probability of ``k``,
    ``fy·exp(fx)`` the comparison density there.

    Theirs approximates ``log k!`` by ``1/(12k) − 1/(360k³)`` and ``k·log(1 + v)`` by a series
    with 7-digit coefficients; here ``px = k·log1p(v) − (μ − k) − δ(k)`` with ``v = (μ − k)/k``
    and Stirling's remainder ``δ(k) = 1/(12k) − 1/(360k³) + 1/(1260k⁵) − 1/(1680k⁷)`` (error
    < 1/(1188 k⁹) ≤ 8.5e-13 for k ≥ 10), so ``py·exp(px)`` is the Poisson probability to
    ≈ 1e-12 relative, not 1e-8.
    """
    difmuk = mu - k
    if k < 10.0:
        px = -mu
        py = mu ** k / _FACT[int(k)]
    else:
        r = 1.0 / k
        r2 = r * r
        delta = r * (1.0 / 12.0 - r2 * (1.0 / 360.0 - r2 * (1.0 / 1260.0 - r2 / 1680.0)))
        px = k * math.log1p(difmuk / k) - difmuk - delta
        py = _INV_SQRT_2PI / math.sqrt(k)
    x = (0.5 - difmuk) / s
    xx = x * x
    fx = -0.5 * xx
    fy = omega * (((c3 * xx + c2) * xx + c1) * xx + c0)
    return px, py, fx, fy


@NJIT_INLINE
def poisson_ad(source, mu: float) -> int:
    """One Poisson count of mean ``mu`` ≥ 10 by Ahrens & Dieter's algorithm PD (ACM TOMS 8(2),
    163–179, 1982, case A): exact in law, not NumPy's draws.

    Step N: ``G = μ + √μ·T`` (T a standard normal); for ``G ≥ 0`` the count ``K = ⌊G⌋`` is taken
    at once when ``K ≥ ⌊μ − 1.1484⌋`` (about half the draws) or, with one uniform ``U``, when
    ``6μ²·U ≥ (μ − K)³`` (the squeeze; nearly all the rest at large μ). Otherwise step Q accepts
    ``K`` against the Poisson probability (procedure F), and step E draws from a double
    exponential envelope until step H accepts. Typical cost: one ziggurat normal, half a uniform,
    a square root and a floor; NumPy's PTRS spends two uniforms, a square root, a logarithm and
    two divisions on every draw and logarithms and log Γ on a fifth of them.

    Steps N, I and S are inlined into the caller; the rest (:func:`_ad_rest`) is a call: each
    call passes the source array, which numba reference-counts (≈ 10 ns a call, measured: as
    much as the draw itself).

    The law is checked by chi-square and moment tests against ``scipy.stats.poisson`` from
    μ = 10 to 10⁶ (tests/pixel/test_random.py).
    """
    s = math.sqrt(mu)
    g = mu + s * standard_normal(source)
    if g < 0.0:
        return _ad_rest(source, mu, s, g, -1.0, 0.0)
    k = float(math.floor(g))
    if k >= math.floor(mu - 1.1484):
        return int(k)
    u = next_double(source)
    diff = mu - k
    if 6.0 * mu * mu * u >= diff * diff * diff:  # not ** 3: numba calls pow(), ≈ 20 ns
        return int(k)
    return _ad_rest(source, mu, s, g, k, u)


@NJIT
def _ad_rest(source, mu: float, s: float, g: float, k: float, u: float) -> int:
    """Steps P, Q, E and H of :func:`poisson_ad` for the normal deviate ``g`` not taken at once
    (``k = ⌊g⌋`` and the squeeze's uniform ``u`` when ``g ≥ 0``)."""
    omega = _INV_SQRT_2PI / s
    b1 = 1.0 / (24.0 * mu)
    b2 = 0.3 * b1 * b1
    c3 = b1 * b2 / 7.0
    c2 = b2 - 15.0 * c3
    c1 = b1 - 6.0 * b2 + 45.0 * c3
    c0 = 1.0 - b1 + 3.0 * b2 - 15.0 * c3
    c = 0.1069 / mu
    if g >= 0.0:
        px, py, fx, fy = _ad_f(k, mu, s, omega, c0, c1, c2, c3)
        if fy - u * fy <= py * math.exp(px - fx):
            return int(k)
    while True:
        e = -math.log1p(-next_double(source))  # a standard exponential
        u = 2.0 * next_double(source) - 1.0
        t = 1.8 + (e if u >= 0.0 else -e)
        if t > -0.6744:
            k = float(math.floor(mu + s * t))
            px, py, fx, fy = _ad_f(k, mu, s, omega, c0, c1, c2, c3)
            if c * abs(u) <= py * math.exp(px + e) - fy * math.exp(fx + e):
                return int(k)


@NJIT_INLINE
def poisson_fast(source, lam: float) -> int:
    """One exact Poisson count of mean ``lam`` ≥ 0: :func:`poisson_ad` from 10 on, NumPy's
    multiplication method below (the same draws as :func:`poisson` there)."""
    if lam >= 10.0:
        return poisson_ad(source, lam)
    if lam == 0.0:
        return 0
    return _poisson_mult(source, lam)


@NJIT_NORC  # as the pixel kernels' loops draw (chiptwin._numba)
def fill(source, kind: int, lam: np.ndarray, out: np.ndarray) -> None:
    """``out[i]`` = a draw of mean/parameter ``lam[i]`` in order, for tests and benchmarks:
    ``kind`` 0 :func:`poisson`, 1 :func:`poisson_fast`, 2 :func:`standard_normal` (``lam``
    unused), 3 :func:`next_double`."""
    for i in range(lam.size):
        if kind == 0:
            out[i] = poisson(source, lam[i])
        elif kind == 1:
            out[i] = poisson_fast(source, lam[i])
        elif kind == 2:
            out[i] = standard_normal(source)
        else:
            out[i] = next_double(source)


# ----------------------------------------------------------------------------------------------
# States in and out of NumPy generators
# ----------------------------------------------------------------------------------------------

_M64 = (1 << 64) - 1


def state_of(gen: np.random.Generator) -> np.ndarray | None:
    """``gen``'s bit-generator state as a kernel source (a copy), or None when the kernels cannot
    advance it inline (a bit generator other than PCG64 and SFC64: pass ``gen`` itself)."""
    st = gen.bit_generator.state
    if st["bit_generator"] == "PCG64":
        s, inc = st["state"]["state"], st["state"]["inc"]
        return np.array([[s >> 64, s & _M64], [inc >> 64, inc & _M64]], dtype=np.uint64)
    if st["bit_generator"] == "SFC64":
        return np.array(st["state"]["state"], dtype=np.uint64)
    return None


def put_state(gen: np.random.Generator, source: np.ndarray) -> None:
    """Write a kernel source back into ``gen`` (its buffered 32-bit half, untouched by every draw
    here, is kept)."""
    st = gen.bit_generator.state
    if st["bit_generator"] == "PCG64":
        hi, lo = int(source[0, 0]), int(source[0, 1])
        st["state"]["state"] = (hi << 64) | lo
    else:
        st["state"]["state"] = np.array(source, dtype=np.uint64)
    gen.bit_generator.state = st
