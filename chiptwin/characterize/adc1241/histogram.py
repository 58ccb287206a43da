"""IEEE Std 1241 ADC bench, the histogram (code-density) test: the stimuli, the transition levels,
DNL, INL, missing codes, offset and gain with their uncertainties; the sample count; the summary
over a chip's converters (:mod:`chiptwin.characterize.adc1241` draws the whole bench)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtri

from chiptwin.characterize.adc1241.noise import TransitionNoise
from chiptwin.characterize.adc1241.sine import DynamicResult, coherent_cycles
from chiptwin.pixel._checks import check_int, check_scalar

__all__ = ["BenchRecords", "HistogramResult", "Ramp", "Sine", "bench_records", "converter_figures",
           "dc_sweep_V", "histogram_from_counts", "histogram_samples", "histogram_test",
           "ramp_V", "sine_V", "summarize", "to_jsonable"]

#: Widest converter analysed (as :data:`chiptwin.pixel.adc.MAX_BITS`). Unit: bit.
MAX_BITS: int = 24


# ── stimuli ──────────────────────────────────────────────────────────────────────────────────


@dataclass(frozen=True)
class Ramp:
    """A linear ramp from ``v_start_V`` to ``v_stop_V`` (V), sampled uniformly in time.

    None for either end: the ramp's span is not known, so the histogram test scales the
    transition levels by the end codes (end-point) and cannot give offset and gain.
    """

    v_start_V: float | None
    v_stop_V: float | None

    def __post_init__(self) -> None:
        if self.v_start_V is not None and self.v_stop_V is not None and not (
                np.isfinite(self.v_start_V) and np.isfinite(self.v_stop_V)
                and self.v_start_V < self.v_stop_V):
            raise ValueError(f"ramp from {self.v_start_V!r} to {self.v_stop_V!r} V: must rise, "
                             "finite (a falling ramp's histogram is a rising one's: give its "
                             "ends in rising order)")


@dataclass(frozen=True)
class Sine:
    """A sine ``offset_V + amplitude_V·sin(2π·cycles·n/M + φ)`` (V).

    ``cycles``: whole cycles per record (coherent), or None. ``offset_V`` / ``amplitude_V`` None:
    not known; the histogram test then estimates them from the clipped end codes.
    """

    offset_V: float | None
    amplitude_V: float | None
    cycles: int | None = None

    def __post_init__(self) -> None:
        if self.amplitude_V is not None and not (np.isfinite(self.amplitude_V)
                                                 and self.amplitude_V > 0):
            raise ValueError(f"sine amplitude_V = {self.amplitude_V!r}: must be finite and > 0 "
                             "(a negative one is the same sine half a period on)")
        if self.offset_V is not None and not np.isfinite(self.offset_V):
            raise ValueError(f"sine offset_V = {self.offset_V!r}: must be finite")


def ramp_V(ramp: Ramp, samples: int) -> NDArray[np.float64]:
    """The ramp's M samples, ``v_start + (v_stop − v_start)·(i + ½)/M``. Unit: V."""
    m = check_int("samples", samples, 2)
    if ramp.v_start_V is None or ramp.v_stop_V is None:
        raise ValueError("ramp_V needs a Ramp with both ends known")
    return ramp.v_start_V + (ramp.v_stop_V - ramp.v_start_V) * (np.arange(m) + 0.5) / m


def sine_V(sine: Sine, samples: int, phase_rad: float = 0.0) -> NDArray[np.float64]:
    """The sine's M samples (``cycles`` must be set). Unit: V."""
    m = check_int("samples", samples, 8)
    if sine.offset_V is None or sine.amplitude_V is None or sine.cycles is None:
        raise ValueError("sine_V needs a Sine with offset, amplitude and cycles")
    return sine.offset_V + sine.amplitude_V * np.sin(
        2.0 * np.pi * sine.cycles * np.arange(m) / m + phase_rad)


def dc_sweep_V(bits: int, v_min_V: float, v_max_V: float, first_code: int, last_code: int,
               step_lsb: float = 0.05, margin_lsb: float = 3.0) -> NDArray[np.float64]:
    """DC levels for :func:`transition_noise`: ``T[first_code] − margin`` … ``T[last_code] +
    margin`` in steps of ``step_lsb`` (ideal LSB). Unit: V. Keep the step ≤ σ/2 of the noise to
    be measured (σ ≥ 2·step is resolved)."""
    n, lo, q = _check_range(bits, v_min_V, v_max_V)
    k0 = check_int("first_code", first_code, 1, 2**n - 1)
    k1 = check_int("last_code", last_code, k0, 2**n - 1)
    step = check_scalar("step_lsb", step_lsb, 0.0, 1.0, lo_open=True)
    margin = check_scalar("margin_lsb", margin_lsb, 0.0)
    x = np.arange(k0 - 0.5 - margin, k1 - 0.5 + margin + step / 2, step)
    return lo + x * q


@dataclass(frozen=True)
class BenchRecords:
    """Stimuli of one bench run (V): a ramp and an overdriven sine for the histogram test, a
    coherent sine just inside full scale for the sine fit, each with its description."""

    ramp: Ramp
    ramp_V: NDArray[np.float64]
    histogram_sine: Sine
    histogram_sine_V: NDArray[np.float64]
    fit_sine: Sine
    fit_sine_V: NDArray[np.float64]


def bench_records(bits: int, v_min_V: float, v_max_V: float, samples: int, *,
                  overdrive_lsb: float = 8.0, fit_amplitude_frac: float = 0.999,
                  target_cycles: float | None = None) -> BenchRecords:
    """The bench's stimuli for an N-bit converter over ``[v_min_V, v_max_V]``.

    Parameters
    ----------
    samples : int
        Samples per record M (:func:`histogram_samples` gives how many the histogram needs).
    overdrive_lsb : float
        How far the ramp and the histogram sine go beyond the end transitions (IEEE 1241 wants
        both end codes hit). Unit: LSB.
    fit_amplitude_frac : float
        The fit sine's amplitude over half the full scale ``2^(N−1)·Q`` (< 1: no clipping).
    target_cycles : float, optional
        Cycles per record, made prime to M by :func:`coherent_cycles` (default about M/20).
    """
    n, lo, q = _check_range(bits, v_min_V, v_max_V)
    m = check_int("samples", samples, 8)
    over = check_scalar("overdrive_lsb", overdrive_lsb, 0.0, lo_open=True)
    frac = check_scalar("fit_amplitude_frac", fit_amplitude_frac, 0.0, 1.0, lo_open=True)
    cycles = coherent_cycles(m, m / 20.0 + 0.3 if target_cycles is None else target_cycles)
    centre, half = lo + (2 ** (n - 1) - 0.5) * q, 2 ** (n - 1) * q
    ramp = Ramp(centre - half - over * q, centre + half + over * q)
    hist = Sine(centre, half + over * q, cycles)
    fit = Sine(centre, frac * half, cycles)
    return BenchRecords(ramp, ramp_V(ramp, m), hist, sine_V(hist, m), fit, sine_V(fit, m))


def _check_range(bits: int, v_min_V: float, v_max_V: float) -> tuple[int, float, float]:
    n = check_int("bits", bits, 2, MAX_BITS)
    lo, hi = check_scalar("v_min_V", v_min_V), check_scalar("v_max_V", v_max_V)
    if not hi > lo:
        raise ValueError(f"v_max_V = {v_max_V!r}: must be greater than v_min_V = {v_min_V!r}")
    return n, lo, (hi - lo) / 2.0**n


# ── code density (histogram) test ────────────────────────────────────────────────────────────


@dataclass(frozen=True)
class HistogramResult:
    """The histogram test of one converter (arrays indexed by code, length 2^N; see module).

    ``counts`` hits per code; ``transitions_V`` T[k] and ``transitions_sigma_V``; ``dnl_lsb`` and
    ``dnl_sigma_lsb`` (codes 1 … 2^N − 2); ``inl_endpoint_lsb``, ``inl_bestfit_lsb`` and their
    sigmas (T[1] … T[2^N − 1]); ``missing_codes`` (interior codes with no hit, DNL = −1);
    ``lsb_V`` the average interior code width (the DNL's reference); ``offset_lsb``,
    ``gain_error`` and sigmas (NaN if the stimulus is not known in volts); ``stimulus`` "ramp"
    or "sine"; ``stimulus_offset_V``, ``stimulus_amplitude_V`` the sine's values used (given or
    estimated; NaN for a ramp); ``samples`` S.
    """

    bits: int
    stimulus: str
    samples: int
    counts: NDArray[np.int64]
    transitions_V: NDArray[np.float64]
    transitions_sigma_V: NDArray[np.float64]
    dnl_lsb: NDArray[np.float64]
    dnl_sigma_lsb: NDArray[np.float64]
    inl_endpoint_lsb: NDArray[np.float64]
    inl_endpoint_sigma_lsb: NDArray[np.float64]
    inl_bestfit_lsb: NDArray[np.float64]
    inl_bestfit_sigma_lsb: NDArray[np.float64]
    missing_codes: NDArray[np.int64]
    lsb_V: float
    offset_lsb: float
    offset_sigma_lsb: float
    gain_error: float
    gain_sigma: float
    stimulus_offset_V: float
    stimulus_amplitude_V: float

    def as_dict(self) -> dict[str, Any]:
        """Every field, JSON-ready (arrays as lists, NaN as None)."""
        return to_jsonable({f.name: getattr(self, f.name) for f in fields(self)})


def _bridge_matvec(p: NDArray[np.float64], g: NDArray[np.float64], v: NDArray[np.float64],
                   s: int) -> NDArray[np.float64]:
    """``Σ v`` for Σ_ij = g_i g_j (min(p_i, p_j) − p_i p_j) / S, p non-decreasing, in O(n)."""
    u = g * v
    below = np.cumsum(p * u)
    above = np.cumsum(((1.0 - p) * u)[::-1])[::-1]
    above = np.append(above[1:], 0.0)
    return g * ((1.0 - p) * below + p * above) / s


def _transitions(counts: NDArray[np.int64], stimulus: Ramp | Sine, t_ideal: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                            tuple[float, float], bool]:
    """T[1 …], dT/dp, p = CH[k−1]/S, the sine's (offset, amplitude), whether absolute."""
    s = int(counts.sum())
    p = np.cumsum(counts)[:-1] / s
    if isinstance(stimulus, Ramp):
        known = stimulus.v_start_V is not None and stimulus.v_stop_V is not None
        a, b = (stimulus.v_start_V, stimulus.v_stop_V) if known else (0.0, 1.0)
        t, g, sine = a + (b - a) * p, np.full(p.size, b - a), (np.nan, np.nan)
    else:
        known = stimulus.offset_V is not None and stimulus.amplitude_V is not None
        c, amp = (stimulus.offset_V, stimulus.amplitude_V) if known else (0.0, 1.0)
        t, g = c - amp * np.cos(np.pi * p), amp * np.pi * np.sin(np.pi * p)
        sine = (c, amp)
    if not known:  # end-point scaling: T[1] and T[2^N−1] at their ideal levels
        scale = (t_ideal[-1] - t_ideal[0]) / (t[-1] - t[0])
        shift = t_ideal[0] - scale * t[0]
        t, g = shift + scale * t, scale * g
        sine = (shift + scale * sine[0], scale * sine[1])
    return t, g, p, sine, known


def histogram_test(codes: ArrayLike, bits: int, v_min_V: float, v_max_V: float,
                   stimulus: Ramp | Sine) -> HistogramResult:
    """Code-density (histogram) test of one converter, IEEE 1241 §4.1.6 (static and sine).

    Parameters
    ----------
    codes : array_like of int
        The converter's codes for the stimulus (any shape; records may be concatenated). Both
        end codes must be hit (the stimulus overdrives the range).
    bits : int
        Resolution N, 2 … 24.
    v_min_V, v_max_V : float
        The ideal range (code 0 centred on ``v_min_V``). Unit: V.
    stimulus : Ramp or Sine
        What drove the converter; its volts, if known, make the transition levels absolute.

    Returns
    -------
    HistogramResult

    Notes
    -----
    With S samples, CH[k−1] = Σ_{j<k} h[j] and p_k = CH[k−1]/S the fraction of samples below
    T[k]:

    * ramp from V0 to V1: T[k] = V0 + (V1 − V0)·p_k;
    * sine of offset C and amplitude A (the arcsine density): T[k] = C − A·cos(π·p_k). If A and
      C are not given they are estimated from the clipped end codes, by placing T[1] and
      T[2^N − 1] at their ideal levels: −cos(π h[0]/S) and cos(π h[2^N−1]/S) are (T − C)/A at
      the two ends, so A = (T_ideal[2^N−1] − T_ideal[1]) / (cos(π h[0]/S) + cos(π h[top]/S)).
      The same end-point scaling applies to a ramp of unknown ends. Offset and gain are then
      not observable (NaN).

    Figures: W[k] = T[k+1] − T[k]; Q̄ = (T[2^N−1] − T[1]) / (2^N − 2) the average interior width;
    DNL[k] = W[k]/Q̄ − 1 (missing code: h[k] = 0, DNL = −1); end-point INL[k] = (T[k] − T[1])/Q̄
    − (k − 1); best-fit INL[k] = c0 + c1·T[k] − k, with G·T[k] + V_os + ε[k] = Q·(k − 1) + T₁
    fitted as the standard fits it (the ideal levels on the measured ones, Σ ε² least: in codes,
    k ≈ c0 + c1·T[k]; :func:`_inl_bestfit`); independently based gain and offset from that line,
    in the chip's terms (:func:`chiptwin.pixel.adc.adc_convert`): ``gain_error`` = G − 1 = Q·c1 − 1
    and ``offset_lsb`` = c0 + c1·v_min − ½.

    Uncertainties (random sampling, the standard's model: each sample's input independent and
    distributed as the stimulus; a deterministic stimulus with independent noise per
    conversion gives at most these): the counts are multinomial, so p_k is a binomial fraction
    with Cov(p_i, p_j) = (min(p_i, p_j) − p_i·p_j)/S and, to first order, Cov(T_i, T_j) =
    T'_i T'_j Cov(p_i, p_j) with T' = dT/dp (ramp: V1 − V0; sine: π·A·sin(π·p)). Every sigma is
    this covariance propagated through the linear step that makes the figure (Q̄ and the fitted
    line's slope taken as exact for DNL and INL). For a ramp σ_DNL[k] = √(h[k](1 − h[k]/S)) /
    h̄ exactly (h̄ the mean interior count), ≈ 1/√h̄ — the standard's binomial formula. A code
    with no hit is given the width of one hit, T'/(S·Q̄), as its sigma.
    """
    n, _, _ = _check_range(bits, v_min_V, v_max_V)
    c = np.asarray(codes).ravel()
    if c.size == 0 or not np.issubdtype(c.dtype, np.integer):
        raise ValueError("codes: must be a non-empty array of integer codes")
    if c.min() < 0 or c.max() > 2**n - 1:
        raise ValueError(f"codes: must lie in [0, {2**n - 1}], found [{c.min()}, {c.max()}]")
    return histogram_from_counts(np.bincount(c, minlength=2**n), bits, v_min_V, v_max_V,
                                 stimulus)


def histogram_from_counts(counts: ArrayLike, bits: int, v_min_V: float, v_max_V: float,
                          stimulus: Ramp | Sine) -> HistogramResult:
    """:func:`histogram_test` from the hits per code (``counts``, length 2^N), for a bench that
    accumulates its histograms record by record instead of keeping the codes."""
    n, lo, q = _check_range(bits, v_min_V, v_max_V)
    if not isinstance(stimulus, (Ramp, Sine)):
        raise ValueError(f"stimulus = {stimulus!r}: must be a Ramp or a Sine")
    counts = np.asarray(counts)
    if counts.shape != (2**n,) or not np.issubdtype(counts.dtype, np.integer) or \
            counts.min() < 0:
        raise ValueError(f"counts: must be {2**n} non-negative integer hits, one per code")
    counts = counts.astype(np.int64)
    if counts[0] == 0 or counts[-1] == 0:
        raise ValueError("codes: both end codes must be hit: the stimulus must overdrive the "
                         f"range (hits: code 0: {counts[0]}, code {2**n - 1}: {counts[-1]})")
    if counts[1:-1].sum() == 0:
        raise ValueError("codes: only the end codes were hit: the stimulus must sweep the "
                         "interior codes (no code width to measure)")
    t_ideal = lo + (np.arange(1, 2**n) - 0.5) * q
    t, g, p, sine, known = _transitions(counts, stimulus, t_ideal)
    return _figures(counts, t, g, p, sine, known, n, lo, q, stimulus)


def _figures(counts, t, g, p, sine, known, n, lo, q, stimulus) -> HistogramResult:
    s, kk = int(counts.sum()), np.arange(1, 2**n, dtype=np.float64)
    var_t = g * g * p * (1.0 - p) / s
    qbar = (t[-1] - t[0]) / (2**n - 2)
    cov_next = g[:-1] * g[1:] * p[:-1] * (1.0 - p[1:]) / s
    var_w = np.maximum(var_t[1:] + var_t[:-1] - 2.0 * cov_next, (0.5 * (g[1:] + g[:-1]) / s)**2)
    dnl = _pad(np.diff(t) / qbar - 1.0, 1, 2**n)
    dnl_s = _pad(np.sqrt(var_w) / qbar, 1, 2**n)
    inl_ep, inl_ep_s = _inl_endpoint(t, g, p, s, kk, qbar)
    inl_bf, inl_bf_s, (c0, c1), cov_c = _inl_bestfit(t, g, p, s, kk)
    off, gain, off_s, gain_s = np.nan, np.nan, np.nan, np.nan
    if known:  # G = Q·c1, and the line's code at v_min is c0 + c1·v_min = offset + ½
        off, gain = c0 + c1 * lo - 0.5, q * c1 - 1.0
        jo, jg = np.array([1.0, lo]), np.array([0.0, q])
        off_s, gain_s = np.sqrt(jo @ cov_c @ jo), np.sqrt(jg @ cov_c @ jg)
    missing = np.flatnonzero(counts[1:-1] == 0) + 1
    is_ramp = isinstance(stimulus, Ramp)
    return HistogramResult(
        n, "ramp" if is_ramp else "sine", s, counts, _pad(t, 1, 2**n),
        _pad(np.sqrt(var_t), 1, 2**n), dnl, dnl_s, _pad(inl_ep, 1, 2**n),
        _pad(inl_ep_s, 1, 2**n), _pad(inl_bf, 1, 2**n), _pad(inl_bf_s, 1, 2**n),
        missing.astype(np.int64), float(qbar), float(off), float(off_s), float(gain),
        float(gain_s), float(np.nan if is_ramp else sine[0]),
        float(np.nan if is_ramp else sine[1]))


def _pad(x: NDArray[np.float64], first: int, size: int) -> NDArray[np.float64]:
    out = np.full(size, np.nan)
    out[first:first + x.size] = x
    return out


def _inl_endpoint(t, g, p, s, kk, qbar):
    """End-point INL and its sigma: δINL[k] = (δT[k] − the line through δT[1], δT[last]) / Q̄."""
    lam = (kk - 1.0) / (kk[-1] - 1.0)
    var = g * g * p * (1.0 - p)
    c1 = g * g[0] * (np.minimum(p, p[0]) - p * p[0])
    cn = g * g[-1] * (np.minimum(p, p[-1]) - p * p[-1])
    v = (var + (1 - lam) ** 2 * var[0] + lam**2 * var[-1] - 2 * (1 - lam) * c1 - 2 * lam * cn
         + 2 * lam * (1 - lam) * c1[-1])
    inl = (t - t[0]) / qbar - (kk - 1.0)
    return inl, np.sqrt(np.maximum(v, 0.0) / s) / qbar


def _inl_bestfit(t, g, p, s, kk):
    """Best-fit (independently based) INL, IEEE 1241's ``G·T[k] + V_os + ε[k] = Q·(k − 1) + T₁``
    with G and V_os minimising Σ ε[k]²: the ideal levels regressed on the measured ones. In LSB,
    the codes regressed on the levels, ``k ≈ c0 + c1·T[k]``, and ``INL[k] = c0 + c1·T[k] − k``
    (= −ε[k]/Q: a level above the line is positive).

    Its sigma to first order in δT, the levels being the regressor: with X = [1, T], H its hat
    matrix, r = k − X·c the residuals and u = X (XᵀX)⁻¹ e₂, ``δINL = c1·(I − H)·δT + u·(rᵀδT)``
    and ``δc = (XᵀX)⁻¹ (e₂ rᵀ − c1 Xᵀ) δT``, each variance through Σ = Cov(T) in O(n)
    (:func:`_bridge_matvec`). Returns INL, its sigma, (c0, c1) and their covariance."""
    x = np.column_stack([np.ones(t.size), t])
    qm, rm = np.linalg.qr(x)
    c0, c1 = (float(v) for v in np.linalg.solve(rm, qm.T @ kk))
    inl = c0 + c1 * t - kk
    r = -inl
    rinv = np.linalg.inv(rm)
    xtx_inv = rinv @ rinv.T
    u = x @ xtx_inv[:, 1]
    sq = np.column_stack([_bridge_matvec(p, g, qm[:, j], s) for j in range(2)])  # Σ·Q
    qsq = qm.T @ sq
    diag = g * g * p * (1.0 - p) / s
    v_line = diag - 2.0 * np.sum(qm * sq, axis=1) + np.einsum("ka,ab,kb->k", qm, qsq, qm)
    sr = _bridge_matvec(p, g, r, s)  # Σ·r
    rsr = float(r @ sr)
    var = c1 * c1 * v_line + 2.0 * c1 * u * (sr - qm @ (qm.T @ sr)) + u * u * rsr
    e2, xsr = np.array([0.0, 1.0]), x.T @ sr
    inner = (rsr * np.outer(e2, e2) - c1 * (np.outer(e2, xsr) + np.outer(xsr, e2))
             + c1 * c1 * (rm.T @ qsq @ rm))
    return inl, np.sqrt(np.maximum(var, 0.0)), (c0, c1), xtx_inv @ inner @ xtx_inv


def histogram_samples(bits: int, dnl_uncertainty_lsb: float, confidence: float = 0.95,
                      stimulus: str = "sine", overdrive_lsb: float = 0.0) -> int:
    """Samples a histogram test needs for a DNL uncertainty, IEEE 1241 §4.1.6.

    Parameters
    ----------
    bits : int
        Resolution N.
    dnl_uncertainty_lsb : float
        β: the half-width of the DNL's confidence interval at the least-hit code. Unit: LSB.
    confidence : float
        Two-sided confidence of that interval, giving Z = Φ⁻¹((1 + confidence)/2).
    stimulus : "sine" or "ramp"
    overdrive_lsb : float
        How far the stimulus goes beyond each end transition. Unit: LSB.

    Returns
    -------
    int
        S, rounded up:

        * sine of amplitude A = 2^(N−1) + overdrive (LSB): the least-hit codes are at mid-scale
          with S/(π·A) hits each, so S = π·A·Z²/β² — the standard's S = π·2^(N−1)·Z²/β² without
          overdrive;
        * ramp spanning 2^N + 2·overdrive LSB: S = (2^N + 2·overdrive)·Z²/β².

        Both from σ_DNL = 1/√h (binomial counts, see :func:`histogram_test`). This bounds one
        code's interval; for all 2^N − 2 codes at once at the same confidence, pass
        ``confidence = 1 − (1 − c)/(2^N − 2)`` (Bonferroni).
    """
    n = check_int("bits", bits, 2, MAX_BITS)
    beta = check_scalar("dnl_uncertainty_lsb", dnl_uncertainty_lsb, 0.0, lo_open=True)
    conf = check_scalar("confidence", confidence, 0.0, 1.0, lo_open=True, hi_open=True)
    over = check_scalar("overdrive_lsb", overdrive_lsb, 0.0)
    z2 = float(ndtri(0.5 + conf / 2.0)) ** 2
    if stimulus == "sine":
        return int(np.ceil(np.pi * (2.0 ** (n - 1) + over) * z2 / beta**2))
    if stimulus == "ramp":
        return int(np.ceil((2.0**n + 2.0 * over) * z2 / beta**2))
    raise ValueError(f"stimulus = {stimulus!r}: must be 'sine' or 'ramp'")


# ── summary over converters ──────────────────────────────────────────────────────────────────

#: Each figure and which way is worse: "max" (larger is worse), "min", "abs" (larger |x|).
FIGURES: dict[str, str] = {
    "dnl_max_lsb": "max", "inl_max_lsb": "max", "inl_endpoint_max_lsb": "max",
    "missing_codes": "max", "sinad_db": "min", "enob_bits": "min", "sfdr_db": "min",
    "transition_noise_lsb": "max", "offset_lsb": "abs", "gain_error": "abs",
}


def _at_max(value: NDArray[np.float64], sigma: NDArray[np.float64]) -> tuple[float, float]:
    if not np.isfinite(value).any():
        return np.nan, np.nan
    i = int(np.nanargmax(np.abs(value)))
    return float(abs(value[i])), float(sigma[i])


def converter_figures(hist: HistogramResult | None = None, dyn: DynamicResult | None = None,
                      noise: TransitionNoise | None = None) -> dict[str, float]:
    """One converter's scalar figures (:data:`FIGURES`) and their sigmas (``<name>_sigma``).

    DNL and INL maxima are max |.| over codes (INL best-fit; end-point separately), each with
    the sigma of the code where it occurs. A test not given leaves its figures NaN.
    """
    out: dict[str, float] = {k: np.nan for k in FIGURES}
    out.update({f"{k}_sigma": np.nan for k in FIGURES})
    if hist is not None:
        out["dnl_max_lsb"], out["dnl_max_lsb_sigma"] = _at_max(hist.dnl_lsb, hist.dnl_sigma_lsb)
        out["inl_max_lsb"], out["inl_max_lsb_sigma"] = _at_max(hist.inl_bestfit_lsb,
                                                               hist.inl_bestfit_sigma_lsb)
        out["inl_endpoint_max_lsb"], out["inl_endpoint_max_lsb_sigma"] = _at_max(
            hist.inl_endpoint_lsb, hist.inl_endpoint_sigma_lsb)
        out["missing_codes"], out["missing_codes_sigma"] = float(hist.missing_codes.size), 0.0
        out["offset_lsb"], out["offset_lsb_sigma"] = hist.offset_lsb, hist.offset_sigma_lsb
        out["gain_error"], out["gain_error_sigma"] = hist.gain_error, hist.gain_sigma
    if dyn is not None:
        out["sinad_db"], out["sinad_db_sigma"] = dyn.sinad_db, dyn.sinad_sigma_db
        out["enob_bits"], out["enob_bits_sigma"] = dyn.enob_bits, dyn.enob_sigma_bits
        out["sfdr_db"] = dyn.sfdr_db
    if noise is not None:
        out["transition_noise_lsb"] = noise.transition_noise_lsb
        out["transition_noise_lsb_sigma"] = noise.transition_noise_sigma_lsb
    return out


def summarize(per_converter: Sequence[Mapping[str, float]]) -> dict[str, Any]:
    """Worst and median of each figure over the converters, JSON-ready.

    Returns ``{"converters": n, "figures": {name: {"worst", "worst_sigma", "worst_converter",
    "median", "n"}}}``; "worst" follows :data:`FIGURES` (the signed value for "abs" figures), the
    median is over the converters where the figure is finite (None if none is).
    """
    if len(per_converter) == 0:
        raise ValueError("per_converter: need at least one converter's figures")
    figs: dict[str, Any] = {}
    for name, way in FIGURES.items():
        vals = np.array([float(f.get(name, np.nan)) for f in per_converter])
        sig = np.array([float(f.get(f"{name}_sigma", np.nan)) for f in per_converter])
        fin = np.isfinite(vals)
        if not fin.any():
            figs[name] = {"worst": None, "worst_sigma": None, "worst_converter": None,
                          "median": None, "n": 0}
            continue
        key = {"max": vals, "min": -vals, "abs": np.abs(vals)}[way]
        i = int(np.nanargmax(np.where(fin, key, np.nan)))
        figs[name] = to_jsonable({"worst": vals[i], "worst_sigma": sig[i], "worst_converter": i,
                                  "median": float(np.median(vals[fin])), "n": int(fin.sum())})
    return {"converters": len(per_converter), "figures": figs}


def to_jsonable(obj: Any) -> Any:
    """Arrays to lists, numpy scalars to Python, NaN and ±inf to None, dataclasses to dicts."""
    if hasattr(obj, "__dataclass_fields__"):
        return to_jsonable(asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f":  # fast path for per-code arrays
        out = obj.astype(object)
        out[~np.isfinite(obj)] = None
        return out.tolist()
    if isinstance(obj, np.ndarray) and obj.dtype.kind in "iub":
        return obj.tolist()
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [to_jsonable(v) for v in (obj.tolist() if isinstance(obj, np.ndarray) else obj)]
    if isinstance(obj, (np.integer, bool, np.bool_)):
        return obj.item() if isinstance(obj, np.generic) else obj
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    return obj
