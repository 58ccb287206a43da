"""Photodiode and pixel readout: photons on the diode → electrons in each reset and signal sample.

The readout of one frame (see the package docstring for the full picture): reset, ``M`` reset
samples right after reset, integration, ``M`` signal samples at its end. Collected charge is one
merged Poisson draw per pixel, clipped at the full well; reset (kTC) noise is shared by the reset
and signal samples of a frame with true CDS and independent without it; read noise is white and
independent per sample. Two photon-statistics levels share these parameters:

* ``binned`` — :func:`sample_frame` draws the samples of one frame.
* ``expected`` — :func:`expected_frame` gives the mean and variance of the correlated double
  sampling difference ``mean(signal) − mean(reset)`` analytically, without drawing.

Sources: El Gamal & Eltoukhy, IEEE Circuits & Devices 21(3), 2005 (noise model);
Salama et al., Biosensors & Bioelectronics 19 (2004), eqs. 20–21.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import pdtr

from chiptwin.constants import K_B, Q_E, T_ROOM_K
from chiptwin.pixel._checks import check_array, check_int, check_scalar

_ABS_ZERO_C = -273.15


def dark_current_e_per_s(
    j_nA_per_cm2: float,
    area_um2: float,
    temp_C: float,
    ref_temp_C: float = 25.0,
    doubling_C: float = 7.0,
) -> float:
    """Dark current of a photodiode at a temperature. Unit: e⁻/s.

    Parameters
    ----------
    j_nA_per_cm2 : float
        Dark current density at ``ref_temp_C``. Unit: nA/cm². Typical: 0.1–10 for plain n-well
        diodes at 25 °C, tens of pA/cm² for low-dark-current diodes (docs/background/sources.md P8).
    area_um2 : float
        Photodiode area. Unit: µm².
    temp_C : float
        Operating temperature. Unit: °C.
    ref_temp_C : float
        Temperature at which ``j_nA_per_cm2`` holds. Unit: °C.
    doubling_C : float
        Temperature step that doubles the dark current. Unit: °C. Typical 5–8, default 7.

    Returns
    -------
    float
        ``j · A / q · 2^((T − T0)/ΔT)``. Unit: e⁻/s.

    Notes
    -----
    Doubling every 5–8 °C: Theuwissen, Harvest Imaging (sources.md P7). 1 nA/cm² on 100 × 100 µm
    gives 1e-13 A ≈ 6.24e5 e⁻/s at the reference temperature.
    """
    j = check_scalar("j_nA_per_cm2", j_nA_per_cm2, 0.0)
    area = check_scalar("area_um2", area_um2, 0.0, lo_open=True)
    t = check_scalar("temp_C", temp_C, _ABS_ZERO_C)
    t0 = check_scalar("ref_temp_C", ref_temp_C, _ABS_ZERO_C)
    dt = check_scalar("doubling_C", doubling_C, 0.0, lo_open=True)
    amps = j * 1e-9 * area * 1e-8  # nA/cm² → A/cm², µm² → cm²
    return amps / Q_E * 2.0 ** ((t - t0) / dt)


def ktc_noise_e(capacitance_fF: float, temp_K: float = T_ROOM_K) -> float:
    """Reset (kTC) noise of a sense node, as charge. Unit: e⁻ rms.

    Parameters
    ----------
    capacitance_fF : float
        Sense-node capacitance. Unit: fF.
    temp_K : float
        Temperature. Unit: K.

    Returns
    -------
    float
        ``√(k·T·C) / q``: 40 e⁻ at 10 fF, 127 e⁻ at 100 fF, 402 e⁻ at 1 pF, 300 K (derived;
        sources.md P5).
    """
    c = check_scalar("capacitance_fF", capacitance_fF, 0.0, lo_open=True)
    t = check_scalar("temp_K", temp_K, 0.0)
    return float(np.sqrt(K_B * t * c * 1e-15) / Q_E)


def conversion_gain_uV_per_e(capacitance_fF: float) -> float:
    """Conversion gain of a sense node, ``q / C``. Unit: µV/e⁻.

    Parameters
    ----------
    capacitance_fF : float
        Sense-node capacitance. Unit: fF.

    Returns
    -------
    float
        16.0 µV/e⁻ at 10 fF; 0.160 µV/e⁻ at 1 pF (the 100 µm diode of sources.md P6).
    """
    c = check_scalar("capacitance_fF", capacitance_fF, 0.0, lo_open=True)
    return Q_E / (c * 1e-15) * 1e6


def _unit_mean_lognormal(rng: np.random.Generator, n: int, cv: float) -> NDArray[np.float64]:
    """``n`` lognormal draws with coefficient of variation ``cv``, rescaled to mean exactly 1."""
    sigma = np.sqrt(np.log1p(cv * cv))
    draws = rng.lognormal(-0.5 * sigma * sigma, sigma, size=n)
    return draws / draws.mean()


def fixed_pattern_maps(
    rng: np.random.Generator, n_pixels: int, prnu_frac: float, dsnu_frac: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-pixel gain (PRNU) and dark (DSNU) multipliers, each with mean exactly 1.

    Parameters
    ----------
    rng : numpy.random.Generator
        The stream to draw from (the gain map is drawn first, then the dark map).
    n_pixels : int
        Number of pixels. Reshape the maps to the array's shape if needed.
    prnu_frac : float
        Photo-response non-uniformity, the rms spread of the gain as a fraction of its mean.
    dsnu_frac : float
        Dark-signal non-uniformity, the rms spread of the dark current as a fraction of its mean.

    Returns
    -------
    gain_map, dark_map : ndarray (n_pixels,)
        Multipliers of the photo-generated charge and of the dark charge. Unit: 1.

    Notes
    -----
    Both maps are lognormal with mean 1 and coefficient of variation ``frac``, then divided by
    their sample mean, so each averages to exactly 1 (up to rounding) and the array's mean
    response is the nominal one. Pyxel 3.0.2's PRNU map does not average to 1 (measured here;
    sources.md A2). The lognormal is positive by construction (no negative gain or dark current
    however large the spread); for the gain with ``frac`` ≲ 0.05 it is indistinguishable from the
    Gaussian N(1, frac²) of EMVA 1288; for the dark map its right skew gives the hot-pixel tail that
    dark current distributions show. The normalisation changes the sample CV by O(frac/√n).
    """
    n = check_int("n_pixels", n_pixels, 1)
    prnu = check_scalar("prnu_frac", prnu_frac, 0.0)
    dsnu = check_scalar("dsnu_frac", dsnu_frac, 0.0)
    gain_map = _unit_mean_lognormal(rng, n, prnu)
    dark_map = _unit_mean_lognormal(rng, n, dsnu)
    return gain_map, dark_map


def mean_electrons(
    photons: ArrayLike, qe: float, gain_map: ArrayLike, dark_e: ArrayLike
) -> NDArray[np.float64]:
    """Expected collected charge in one integration window, before the full-well clip. Unit: e⁻.

    Parameters
    ----------
    photons : array_like
        Expected photons on each photodiode in the window (the exact integral of the photon rate;
        the draw happens in :func:`sample_frame`). Unit: photons.
    qe : float
        Quantum efficiency at the emission wavelength, in [0, 1] (typically 0.3–0.6 at 560 nm;
        sources.md P9).
    gain_map : array_like
        PRNU multiplier per pixel (mean 1), broadcast against ``photons``. Unit: 1.
    dark_e : array_like
        Expected dark charge per pixel in the window (dark current × time × DSNU map). Unit: e⁻.

    Returns
    -------
    ndarray
        ``qe · gain_map · photons + dark_e`` (Salama et al. 2004, eq. 20 integrated). Unit: e⁻.
    """
    ph = check_array("photons", photons, 0.0)
    q = check_scalar("qe", qe, 0.0, 1.0)
    gain = check_array("gain_map", gain_map, 0.0)
    dark = check_array("dark_e", dark_e, 0.0)
    return q * gain * ph + dark


def _check_readout(
    full_well_e: float, ktc_e: float, read_noise_e: float, n_samples: int
) -> tuple[float, float, float, int]:
    return (
        check_scalar("full_well_e", full_well_e, 0.0, lo_open=True),
        check_scalar("ktc_e", ktc_e, 0.0),
        check_scalar("read_noise_e", read_noise_e, 0.0),
        check_int("n_samples", n_samples, 1),
    )


def sample_frame(
    rng: np.random.Generator,
    photons: ArrayLike,
    qe: float,
    gain_map: ArrayLike,
    dark_e: ArrayLike,
    full_well_e: float,
    ktc_e: float,
    read_noise_e: float,
    n_samples: int,
    true_cds: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Draw the reset and signal samples of one frame (the ``binned`` level). Unit: e⁻.

    Parameters
    ----------
    rng : numpy.random.Generator
        The pixel stage's stream.
    photons, qe, gain_map, dark_e
        As in :func:`mean_electrons`; ``photons`` has the frame's shape ``S`` (e.g. ``(n_pix,)``).
    full_well_e : float
        Full-well capacity: collected charge is clipped here. Unit: e⁻.
    ktc_e : float
        Reset (kTC) noise, :func:`ktc_noise_e`. Unit: e⁻ rms.
    read_noise_e : float
        White read noise, independent per sample. Unit: e⁻ rms.
    n_samples : int
        ``M``: reset samples and signal samples per frame (correlated multiple sampling).
    true_cds : bool
        True: the reset samples carry the same kTC realisation as the signal samples (sampled right
        after this frame's reset), so it cancels in ``signal − reset``. False: they carry an
        independent kTC draw.

    Returns
    -------
    reset_e, signal_e : ndarray (M, *S)
        Charge-equivalent level of each sample relative to the reset level's mean. Unit: e⁻.

    Notes
    -----
    One merged Poisson draw per pixel of ``qe·gain·photons + dark_e``: each photon is detected
    independently with probability ``qe·gain`` and Poisson thinning of a Poisson count is
    Poisson, and the sum of independent Poisson counts (signal and dark) is Poisson with the
    summed mean. Then ``min(N, full_well_e)``; kTC and read noise are Gaussian. Draw order:
    Poisson counts, signal kTC (if ``ktc_e > 0``), reset kTC (if ``ktc_e > 0`` and not
    ``true_cds``), reset read noise, signal read noise.
    """
    fw, _, _, _ = _check_readout(full_well_e, ktc_e, read_noise_e, n_samples)
    lam = mean_electrons(photons, qe, gain_map, dark_e)
    collected = np.minimum(rng.poisson(lam), fw).astype(np.float64)
    return read_out(rng, collected, ktc_e, read_noise_e, n_samples, true_cds)


def read_out(
    rng: np.random.Generator,
    collected_e: ArrayLike,
    ktc_e: float,
    read_noise_e: float,
    n_samples: int,
    true_cds: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reset and signal samples of a frame whose collected charge is already known. Unit: e⁻.

    The second half of :func:`sample_frame`, for charge counted another way (the ``events``
    photon level counts arrivals). Arguments and draw order as there, without the Poisson draw.
    """
    _, ktc, read, m = _check_readout(1.0, ktc_e, read_noise_e, n_samples)
    collected = np.asarray(collected_e, dtype=np.float64)
    shape = collected.shape
    k_signal = ktc * rng.standard_normal(shape) if ktc > 0 else np.zeros(shape)
    k_reset = k_signal if true_cds or ktc == 0 else ktc * rng.standard_normal(shape)
    reset_e = k_reset + read * rng.standard_normal((m, *shape))
    signal_e = (collected + k_signal) + read * rng.standard_normal((m, *shape))
    return reset_e, signal_e


def clipped_poisson_moments(
    lam: ArrayLike, cap: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and variance of ``min(N, cap)`` for ``N ~ Poisson(lam)``, exactly. Unit: e⁻, e⁻².

    Notes
    -----
    With ``F`` the Poisson CDF and ``m = ⌈cap⌉ − 1`` the largest count below the cap, the identity
    ``k·p(k) = λ·p(k − 1)`` gives ``E[min] = λF(m−1) + cap·(1 − F(m))`` and
    ``E[min²] = λ²F(m−2) + λF(m−1) + cap²·(1 − F(m))``.
    """
    lam_a = np.asarray(lam, dtype=np.float64)
    m = np.ceil(cap) - 1.0
    # Far below the cap (m − 2 − λ ≥ 12√m + 50: Chernoff puts the tail below e⁻⁷⁰) the CDF is
    # 1.0 to the last bit, as pdtr itself returns it (tested): pdtr runs near the cap only.
    near = lam_a > (m - 2.0) - (12.0 * np.sqrt(max(m, 1.0)) + 50.0)

    def cdf(k: float) -> NDArray[np.float64]:
        if k < 0:
            return np.zeros_like(lam_a)
        if near.all():
            return pdtr(k, lam_a)
        out = np.ones_like(lam_a)
        out[near] = pdtr(k, lam_a[near])
        return out

    tail = 1.0 - cdf(m)
    mean = lam_a * cdf(m - 1) + cap * tail
    second = lam_a * lam_a * cdf(m - 2) + lam_a * cdf(m - 1) + cap * cap * tail
    return mean, np.maximum(second - mean * mean, 0.0)


def expected_frame(
    photons: ArrayLike,
    qe: float,
    gain_map: ArrayLike,
    dark_e: ArrayLike,
    full_well_e: float,
    ktc_e: float,
    read_noise_e: float,
    n_samples: int,
    true_cds: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and variance of ``mean(signal) − mean(reset)`` (the ``expected`` level, no sampling).

    Parameters
    ----------
    photons, qe, gain_map, dark_e, full_well_e, ktc_e, read_noise_e, n_samples, true_cds
        As in :func:`sample_frame`.

    Returns
    -------
    mean_diff_e : ndarray (S)
        Expected CDS difference: the mean of the clipped Poisson charge. Unit: e⁻.
    var_diff_e : ndarray (S)
        Its variance: ``Var[min(N, FW)] + 2σ_read²/M`` plus ``2σ_kTC²`` without true CDS (the two
        kTC draws are independent; with true CDS the shared draw cancels). Unit: e⁻².

    Notes
    -----
    Below the full well the variance is the paper's ``S + D + σ_read²`` (Salama et al. 2004,
    eq. 21) with the read term of a CDS difference of M-sample means; near and above it the
    clipped-Poisson moments are exact (:func:`clipped_poisson_moments`). Agrees with the moments
    of many :func:`sample_frame` draws (tested).
    """
    fw, ktc, read, m = _check_readout(full_well_e, ktc_e, read_noise_e, n_samples)
    lam = mean_electrons(photons, qe, gain_map, dark_e)
    mean, var = clipped_poisson_moments(lam, fw)
    var = var + 2.0 * read * read / m
    if not true_cds:
        var = var + 2.0 * ktc * ktc
    return mean, var
