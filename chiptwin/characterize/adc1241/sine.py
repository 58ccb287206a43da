"""IEEE Std 1241 dynamic test of one converter: sine-wave fit, SINAD, ENOB, SFDR.

codes of a sine record ──► sine fit (3 or 4 parameters) ──► residual rms ──► SINAD, ENOB
                      └──► spectrum (coherent: rectangular; else Blackman–Harris) ──► SFDR

Clause numbers are those of IEEE Std 1241-2000 as the author knows them (sine fitting §4.1.4:
three-parameter §4.1.4.2, four-parameter §4.1.4.3; SINAD and ENOB §4.5?; SFDR §4.4?), not checked
against the text here; the formulas are written out in each docstring so they can be checked.

Units: the codes are in LSB (code units); frequencies in cycles per sample (the record's own
sample rate, so nothing here needs a clock); phases in radians; powers in dBFS, where 0 dBFS is a
sine of amplitude ``2^(N−1)`` LSB.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import gcd

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.pixel._checks import check_int, check_scalar

__all__ = ["DynamicResult", "SineFit", "Spectrum", "coherent_cycles", "dynamic_test",
           "sine_fit_3", "sine_fit_4", "spectrum"]

#: dB per bit of an ideal quantiser and the full-scale sine's 10·log10(3/2) (IEEE 1241: the
#: ideal SINAD of an N-bit converter with a full-scale sine is 6.02 N + 1.76 dB).
DB_PER_BIT: float = 20.0 * np.log10(2.0)
SINE_Q_DB: float = 10.0 * np.log10(1.5)

#: Half-width of a tone's main lobe in the Blackman–Harris 4-term window. Unit: bins.
_BH_LOBE: int = 4


@dataclass(frozen=True)
class SineFit:
    """A least-squares sine ``y ≈ A·cos(2π f n) + B·sin(2π f n) + C``, n = 0 … M−1.

    Attributes: ``amplitude`` = √(A² + B²) and ``offset`` = C (units of ``y``: LSB for codes),
    ``phase_rad`` = atan2(−B, A) so that y ≈ amplitude·cos(2π f n + phase) + C,
    ``cycles_per_sample`` f, ``residual_rms`` (units of ``y``), ``iterations`` (0 for the
    three-parameter fit), ``converged``.
    """

    amplitude: float
    phase_rad: float
    offset: float
    cycles_per_sample: float
    residual_rms: float
    iterations: int
    converged: bool

    def evaluate(self, n: int) -> NDArray[np.float64]:
        """The fitted sine at samples 0 … n−1 (units of the fitted data)."""
        w = 2.0 * np.pi * self.cycles_per_sample * np.arange(n)
        return self.amplitude * np.cos(w + self.phase_rad) + self.offset


def _as_record(name: str, y: ArrayLike) -> NDArray[np.float64]:
    arr = np.asarray(y, dtype=np.float64)
    if arr.ndim != 1 or arr.size < 8 or not np.isfinite(arr).all():
        raise ValueError(f"{name}: must be a finite 1-D record of >= 8 samples, got shape "
                         f"{arr.shape}")
    return arr


def _lstsq_sine(y: NDArray[np.float64], f: float, extra: NDArray[np.float64] | None = None
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    w = 2.0 * np.pi * f * np.arange(y.size)
    cols = [np.cos(w), np.sin(w), np.ones(y.size)] + ([] if extra is None else [extra])
    x = np.column_stack(cols)
    coef = np.linalg.lstsq(x, y, rcond=None)[0]
    return coef, y - x @ coef


def _fit(coef: NDArray[np.float64], f: float, resid: NDArray[np.float64], it: int,
         ok: bool) -> SineFit:
    a, b, c = coef[:3]
    return SineFit(float(np.hypot(a, b)), float(np.arctan2(-b, a)), float(c), float(f),
                   float(np.sqrt(np.mean(resid**2))), it, ok)


def sine_fit_3(y: ArrayLike, cycles_per_sample: float) -> SineFit:
    """Three-parameter (known frequency) least-squares sine fit, IEEE 1241 §4.1.4.2.

    Parameters
    ----------
    y : array_like
        The record (codes, LSB), uniformly sampled.
    cycles_per_sample : float
        The stimulus frequency over the sample rate, in (0, 0.5). Unit: cycles/sample.

    Returns
    -------
    SineFit
        Linear least squares on the columns cos(2πfn), sin(2πfn), 1 (the standard's matrix D0).
    """
    rec = _as_record("y", y)
    f = check_scalar("cycles_per_sample", cycles_per_sample, 0.0, 0.5, lo_open=True, hi_open=True)
    coef, resid = _lstsq_sine(rec, f)
    return _fit(coef, f, resid, 0, True)


def _fft_peak(y: NDArray[np.float64]) -> float:
    """Frequency of the largest non-DC FFT bin, refined by the neighbouring bins' ratio."""
    mag = np.abs(np.fft.rfft(y - y.mean()))
    k = int(np.argmax(mag[1:])) + 1
    if 1 <= k < mag.size - 1:
        r = 1 if mag[k + 1] > mag[k - 1] else -1
        k = k + r * mag[k + r] / (mag[k] + mag[k + r])
    return float(k) / y.size


def sine_fit_4(y: ArrayLike, cycles_per_sample: float | None = None, *, max_iter: int = 50,
               tol: float = 1e-12) -> SineFit:
    """Four-parameter (frequency unknown) iterative least-squares sine fit, IEEE 1241 §4.1.4.3.

    Starts from a three-parameter fit at ``cycles_per_sample`` (or, if None, at the FFT peak
    refined by interpolation), then repeats the standard's linearised step: least squares on the
    columns cos, sin, 1 and ``n·(−A·sin + B·cos)·2π``, whose fourth coefficient is the frequency
    correction Δf (cycles/sample), until ``|Δf| < tol`` or ``max_iter`` steps.

    Returns
    -------
    SineFit
        With ``iterations`` the number of Δf steps and ``converged`` whether ``|Δf| < tol``.
    """
    rec = _as_record("y", y)
    f = _fft_peak(rec) if cycles_per_sample is None else check_scalar(
        "cycles_per_sample", cycles_per_sample, 0.0, 0.5, lo_open=True, hi_open=True)
    n_iter = check_int("max_iter", max_iter, 1)
    coef, resid = _lstsq_sine(rec, f)
    n = np.arange(rec.size)
    for it in range(1, n_iter + 1):
        w = 2.0 * np.pi * f * n
        dcol = 2.0 * np.pi * n * (-coef[0] * np.sin(w) + coef[1] * np.cos(w))
        coef, resid = _lstsq_sine(rec, f, dcol)
        f = f + coef[3]
        if abs(coef[3]) < tol:
            coef, resid = _lstsq_sine(rec, f)
            return _fit(coef, f, resid, it, True)
    coef, resid = _lstsq_sine(rec, f)
    return _fit(coef, f, resid, n_iter, False)


def coherent_cycles(samples: int, target_cycles: float) -> int:
    """Whole cycles per record, nearest ``target_cycles`` and prime to ``samples``.

    IEEE 1241 §4.1.4.1 (coherent sampling): J cycles in M samples with gcd(J, M) = 1 puts every
    sample at a distinct phase, J/M apart modulo one cycle, so the record exercises M phases and
    the spectrum has no leakage. For M a power of two this is the nearest odd J. Ties go to the
    smaller J. The stimulus frequency is then ``J / M · f_s``.

    Raises
    ------
    ValueError
        If no such J exists in [1, M/2).
    """
    m = check_int("samples", samples, 8)
    target = check_scalar("target_cycles", target_cycles, 1.0, m / 2.0, hi_open=True)
    for d in range(m):
        for j in (int(np.floor(target)) - d, int(np.ceil(target)) + d):
            if 1 <= j < m / 2 and gcd(j, m) == 1:
                return j
    raise ValueError(f"samples = {samples}: no cycle count prime to it below samples/2")


@dataclass(frozen=True)
class Spectrum:
    """One-sided power spectrum of a record, normalised to full scale.

    ``cycles_per_sample`` (bins 0 … M/2) and ``power_dbfs`` (0 dBFS: a sine of amplitude
    2^(N−1) LSB; a tone's power is the sum over its lobe), the ``window`` used, the fundamental's
    bin range ``signal_bins`` = (first, last) inclusive, the largest spur's bin ``spur_bin``,
    ``sfdr_db`` (dBc: fundamental over the largest other component, DC excluded) and
    ``sinad_fft_db`` (dBc: fundamental over everything else but DC).
    """

    cycles_per_sample: NDArray[np.float64]
    power_dbfs: NDArray[np.float64]
    window: str
    signal_bins: tuple[int, int]
    spur_bin: int
    sfdr_db: float
    sinad_fft_db: float


def _window(m: int, coherent: bool) -> tuple[NDArray[np.float64], int, str]:
    if coherent:
        return np.ones(m), 0, "rectangular"
    a = (0.35875, 0.48829, 0.14128, 0.01168)
    x = 2.0 * np.pi * np.arange(m) / m
    w = a[0] - a[1] * np.cos(x) + a[2] * np.cos(2 * x) - a[3] * np.cos(3 * x)
    return w, _BH_LOBE, "blackman-harris-4"


def spectrum(codes: ArrayLike, bits: int, cycles: int | None = None) -> Spectrum:
    """The output spectrum, SFDR and an FFT SINAD (IEEE 1241 §4.1.5 spectral analysis).

    Parameters
    ----------
    codes : array_like
        One record of codes (LSB).
    bits : int
        Resolution N: sets 0 dBFS.
    cycles : int, optional
        Whole stimulus cycles in the record when sampled coherently: the fundamental is that bin
        and the window rectangular. Otherwise a Blackman–Harris 4-term window (sidelobes
        < −92 dB) and the fundamental is the largest bin, its lobe ±4 bins: the record must
        hold more than 8 cycles, or the fundamental's lobe runs into DC's (ValueError).

    Returns
    -------
    Spectrum
        Powers of the windowed FFT scaled so that a bin-centred sine's lobe sums to its power
        A²/2, over the full-scale sine power 2^(2N−2)/2. The DC lobe (bins ≤ lobe) is excluded
        from spurs and noise. A spur's power is its lobe's, as the fundamental's: the bins within
        ± lobe of the largest bin outside the fundamental's and DC's lobes (one bin when
        coherent; a windowed tone's peak bin holds only ≈ 1/ENBW of its power, −3 dB, so a
        one-bin spur read SFDR 3–3.8 dB too high).
    """
    n = check_int("bits", bits, 1, 24)
    y = _as_record("codes", codes)
    m = y.size
    w, lobe, name = _window(m, cycles is not None)
    p = 2.0 * np.abs(np.fft.rfft((y - y.mean()) * w)) ** 2 / (m * np.sum(w**2))  # Parseval
    p[0] /= 2.0
    if m % 2 == 0:
        p[-1] /= 2.0
    if cycles is not None:
        k0 = check_int("cycles", cycles, 1, (m - 1) // 2)
    else:
        k0 = int(np.argmax(p[1:]) + 1)
        if k0 <= 2 * lobe:
            raise ValueError(f"codes: the record holds ≈ {k0} stimulus cycles; a windowed "
                             f"spectrum needs more than {2 * lobe} to part the fundamental's "
                             "lobe from DC's (record longer, or sample coherently: cycles)")
    lo, hi = max(k0 - lobe, lobe + 1), min(k0 + lobe, p.size - 1)
    sig = float(p[lo:hi + 1].sum())
    rest = p.copy()
    rest[: lobe + 1] = 0.0
    rest[lo:hi + 1] = 0.0
    spur = int(np.argmax(rest))
    spur_power = float(rest[max(spur - lobe, 0):spur + lobe + 1].sum())
    full = 2.0 ** (2 * n - 2) / 2.0
    with np.errstate(divide="ignore"):
        dbfs = 10.0 * np.log10(p / full)
        sfdr = 10.0 * np.log10(sig / spur_power) if spur_power > 0 else np.inf
        sinad = 10.0 * np.log10(sig / rest.sum()) if rest.sum() > 0 else np.inf
    return Spectrum(np.arange(p.size) / m, dbfs, name, (lo, hi), spur, float(sfdr), float(sinad))


@dataclass(frozen=True)
class DynamicResult:
    """The sine test of one converter (IEEE 1241 §4.5?, §4.4?).

    * ``sinad_db`` = 20·log10((A/√2) / NAD_rms), A the fitted amplitude and NAD_rms the fit
      residual's rms (noise and distortion); ``sinad_sigma_db`` its standard error from the
      record length (below).
    * ``enob_bits`` = N − log2(NAD_rms / (Q/√12)), Q = 1 LSB: **the standard's ENOB, reported**;
      it refers the noise to the ideal quantiser's and does not depend on the test amplitude.
    * ``enob_sinad_bits`` = (SINAD − 1.76) / 6.02: the datasheet form; it equals ``enob_bits`` for
      a full-scale sine and is lower by log2(FS/2 / A) for a smaller one.
    * ``sfdr_db`` from :func:`spectrum` (dBc), ``fit`` and ``spectrum`` themselves.
    """

    sinad_db: float
    sinad_sigma_db: float
    enob_bits: float
    enob_sigma_bits: float
    enob_sinad_bits: float
    sfdr_db: float
    fit: SineFit
    spectrum: Spectrum


def dynamic_test(codes: ArrayLike, bits: int, cycles: int | None = None,
                 cycles_per_sample: float | None = None) -> DynamicResult:
    """SINAD, ENOB and SFDR of one converter from one sine record.

    Parameters
    ----------
    codes : array_like
        The converter's codes for a sine stimulus that does not clip (LSB).
    bits : int
        Resolution N.
    cycles : int, optional
        Whole cycles in the record (coherent sampling, :func:`coherent_cycles`): the
        three-parameter fit at f = cycles/M and a rectangular-window spectrum.
    cycles_per_sample : float, optional
        Without ``cycles``: a starting frequency for the four-parameter fit (else the FFT peak).

    Returns
    -------
    DynamicResult

    Notes
    -----
    Standard error of SINAD from an M-sample record, treating the residuals r as independent:
    the mean square's relative error is s(r²) / (mean(r²)·√(M − 4)) (s the sample standard
    deviation, 4 fitted parameters), so σ_SINAD = (10 / ln 10) times it and σ_ENOB = σ_SINAD /
    6.02. For uniform quantisation error this is √(4/5/M) relative (0.06 dB at M = 4096).
    The fit's frequency error is not included (zero for a coherent three-parameter fit).
    """
    n = check_int("bits", bits, 1, 24)
    y = _as_record("codes", codes)
    if cycles is not None:
        fit = sine_fit_3(y, check_int("cycles", cycles, 1, (y.size - 1) // 2) / y.size)
    else:
        fit = sine_fit_4(y, cycles_per_sample)
    r2 = (y - fit.evaluate(y.size)) ** 2
    rms = float(np.sqrt(r2.mean()))
    rel = float(r2.std(ddof=1) / (r2.mean() * np.sqrt(y.size - 4))) if rms > 0 else 0.0
    sinad = 20.0 * np.log10(fit.amplitude / np.sqrt(2.0) / rms) if rms > 0 else np.inf
    s_db = 10.0 / np.log(10.0) * rel
    enob = n - np.log2(rms * np.sqrt(12.0)) if rms > 0 else np.inf
    spec = spectrum(y, n, cycles)
    return DynamicResult(float(sinad), s_db, float(enob), s_db / DB_PER_BIT,
                         float((sinad - SINE_Q_DB) / DB_PER_BIT), spec.sfdr_db, fit, spec)
