"""Dose response and limit of detection: the paper's "minimum detectable analyte concentration".

Salama et al. 2004, Sec. 4: combining the kinetics, optics, sensor and post-processing models gives
the minimum detectable analyte amount for a set of system parameters. A scenario asks for it by
giving each site its own amount (``[sites] amounts_fmol``, 0 = a blank site); this module

* checks that a scene's light per site follows its amount (:func:`honours_amounts`; the light is
  scaled where it is made, :func:`chiptwin.twin.stages.scale_source`: every closed-form assay's
  light is proportional to its analyte, eqs. 5–19, so a site holding ``x`` of the ``[assay]``
  amount ``A`` emits ``x / A`` of its light, exactly);
* turns the run's per-site estimates into the dose response and the limit of detection
  (:func:`dose_response_figures`): the blank's 3σ threshold (IUPAC: mean of the blank + 3 standard
  deviations), with σ from the noise model propagated through the DSP, checked against the
  spread the blank sites actually show, and the amount at which the chip's expected response
  crosses it (:func:`interpolate_lod`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin.constants import N_A
from chiptwin.detection import snr
from chiptwin.twin.stages import site_amounts_fmol, site_scale

if TYPE_CHECKING:
    from chiptwin.config import Scenario
    from chiptwin.twin.scene import Scene

#: What each assay kind doses (``[sites] amounts_fmol``).
ANALYTES = {"atp": "ATP", "pyrosequencing": "template DNA", "luciferase_label": "luciferase",
            "substrate": "substrate", "catalyst": "enzyme"}
#: The blank's threshold in its standard deviations (IUPAC's limit of detection, k = 3).
K_SIGMA = 3.0
AMOL_PER_FMOL = 1e3


def honours_amounts(s: Scenario, scene: Scene) -> bool:
    """Whether the scene's light per site is in the proportion of ``[sites] amounts_fmol``
    (always true when no amounts are given). Blank sites must emit nothing."""
    scale = site_scale(s)
    if scale is None:
        return True
    total = scene.site_photons.sum(axis=1)
    ref = int(np.argmax(scale))
    if scale[ref] == 0:
        return bool(np.all(total == 0))
    expected = total[ref] * scale / scale[ref]
    return bool(np.allclose(total, expected, rtol=1e-9, atol=1e-12 * max(total[ref], 1.0)))


# --- the limit of detection -----------------------------------------------------------------------


def interpolate_lod(amounts: np.ndarray, expected_e: np.ndarray, threshold_e: float) -> float:
    """The smallest amount at which a response reaches ``threshold_e``, by linear interpolation
    between the two dose points that bracket it (the response is linear in the amount, so a
    straight segment is exact between two sites of equal gain).

    Parameters
    ----------
    amounts : array (n,)
        Dose points, > 0, any order. Unit: any (the result's).
    expected_e : array (n,)
        Expected signal at each. Unit: e⁻.
    threshold_e : float
        The signal to reach. Unit: e⁻.

    Returns
    -------
    The amount; ``nan`` when no point reaches the threshold, the smallest amount when all do
    (the LoD lies below the dose range: extrapolated through the origin then).
    """
    order = np.argsort(amounts)
    x, y = np.asarray(amounts, float)[order], np.asarray(expected_e, float)[order]
    above = np.flatnonzero(y >= threshold_e)
    if not len(above):
        return math.nan
    i = int(above[0])
    if i == 0:
        return float(x[0] * threshold_e / y[0]) if y[0] > 0 else float(x[0])
    x0, x1, y0, y1 = x[i - 1], x[i], y[i - 1], y[i]
    return float(x0 + (threshold_e - y0) * (x1 - x0) / (y1 - y0))


def blank_statistics(measured_e: np.ndarray, expected_e: np.ndarray, sd_model_e: np.ndarray
                     ) -> dict[str, Any]:
    """The blank sites: the noise model's mean and σ beside the mean and spread they show.

    ``sd_model_e`` is rms-averaged over the blanks (their dark currents differ, DSNU). The
    measured standard deviation's standard error is σ/√(2(n − 1)) (normal samples); the
    threshold's, √(σ²/n + 9σ²/(2(n − 1))) (its mean's and 3 × its σ's, independent).
    """
    n = len(measured_e)
    sigma = float(np.sqrt(np.mean(np.square(sd_model_e))))
    out: dict[str, Any] = {"n_sites": n, "mean_model_e": float(np.mean(expected_e)),
                           "sigma_model_e": sigma}
    if n >= 2:
        sd = float(np.std(measured_e, ddof=1))
        sd_se = sd / math.sqrt(2 * (n - 1))
        out.update(mean_measured_e=float(np.mean(measured_e)), sd_measured_e=sd,
                   sd_measured_se_e=sd_se, sd_ratio_measured_to_model=sd / sigma,
                   sd_ratio_se=sd_se / sigma,
                   threshold_measured_e=float(np.mean(measured_e)) + K_SIGMA * sd,
                   threshold_measured_se_e=math.sqrt(sd**2 / n + (K_SIGMA * sd_se) ** 2))
    return out


def dose_response_figures(s: Scenario, sites: list[dict], expected: np.ndarray
                          ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """``summary['dose_response']`` and its arrays, from the per-site rows of a run.

    ``expected`` is each site's signal as the same estimator gives it on the DSP's expected
    outputs (:func:`chiptwin.twin.results.expected_site_signal`): the chip's calibration curve, gain
    non-uniformity and cross-talk included, with no noise.
    """
    amounts = site_amounts_fmol(s, len(sites)) * AMOL_PER_FMOL
    measured = np.array([site["signal_e"] for site in sites])
    sd = np.array([site["signal_sd_e"] for site in sites])
    blank, dosed = amounts == 0, amounts > 0
    stats = blank_statistics(measured[blank], expected[blank], sd[blank]) if blank.any() else {}
    summary: dict[str, Any] = {"analyte": ANALYTES[s.assay.kind], "unit": "amol",
                               "estimator": s.run.light_estimator, "k_sigma": K_SIGMA,
                               "blank": stats}
    if stats:
        summary["threshold_e"] = stats["mean_model_e"] + K_SIGMA * stats["sigma_model_e"]
    summary["points"] = _points(sites, amounts, measured, expected, sd, dosed,
                                summary.get("threshold_e"))
    if dosed.any():
        summary.update(_sensitivity(amounts[dosed], measured[dosed], expected[dosed], sd[dosed]))
    if stats and dosed.any():
        summary.update(_lod(amounts[dosed], expected[dosed], stats, summary["threshold_e"],
                            summary["slope_e_per_amol"]))
    summary["method"] = METHOD
    arrays = {"dose_amount_amol": amounts, "dose_signal_e": measured,
              "dose_expected_e": expected, "dose_sd_e": sd}
    return summary, arrays


METHOD = (
    "threshold = mean + 3 sigma of the blank sites (amount 0), both from the noise model "
    "propagated through the DSP (sigma: rms over the blanks); LoD = the amount at which the "
    "expected dose response (the same estimator on the DSP's expected outputs, site by site) "
    "reaches the threshold, by linear interpolation between the two bracketing dose points. "
    "Checked against the blank sites' measured spread: lod_from_blank_spread_amol uses their "
    "sample mean + 3 sample sd instead, with its standard error from n blanks."
)


def _points(sites, amounts, measured, expected, sd, dosed, threshold) -> list[dict]:
    p, a = snr(measured, sd)
    order = [i for i in np.argsort(amounts, kind="stable") if dosed[i]]
    return [{"amount_amol": float(amounts[i]), "site": int(sites[i]["id"]),
             "pixel": sites[i]["pixel"], "signal_e": float(measured[i]),
             "expected_signal_e": float(expected[i]), "noise_e": float(sd[i]),
             "snr_power": float(p[i]), "snr_amplitude": float(a[i]),
             "above_threshold": bool(threshold is not None and measured[i] >= threshold)}
            for i in order]


def _sensitivity(amounts, measured, expected, sd) -> dict[str, Any]:
    """Slope of the response: e⁻ per amol (least squares through the origin, expected and
    measured), and the log-log slope of the measured points with amplitude SNR ≥ 10 (1 for a
    linear response)."""
    g_exp = float(np.sum(expected * amounts) / np.sum(amounts**2))
    w = 1.0 / np.maximum(sd, 1e-300) ** 2
    g_meas = float(np.sum(w * measured * amounts) / np.sum(w * amounts**2))
    g_se = float(1.0 / math.sqrt(np.sum(w * amounts**2)))
    out = {"slope_e_per_amol": g_exp, "slope_measured_e_per_amol": g_meas,
           "slope_measured_se_e_per_amol": g_se}
    bright = (measured > 0) & (measured >= 10 * sd)
    if bright.sum() >= 2:
        out["loglog_slope"] = float(np.polyfit(np.log10(amounts[bright]),
                                               np.log10(measured[bright]), 1)[0])
        out["loglog_points"] = int(bright.sum())
    return out


def _lod(amounts, expected, stats, threshold, slope_e_per_amol) -> dict[str, Any]:
    lod = interpolate_lod(amounts, expected, threshold)
    out: dict[str, Any] = {"lod_amol": lod, "lod_molecules": lod * 1e-18 * N_A,
                           "dose_range_amol": [float(amounts.min()), float(amounts.max())]}
    if "threshold_measured_e" in stats:
        t, t_se = stats["threshold_measured_e"], stats["threshold_measured_se_e"]
        # the response is linear: the LoD's standard error is the threshold's over the slope
        # (none: no amount gives a signal, e.g. a 1 e⁻ full well, so no amount is detected)
        se = t_se / slope_e_per_amol if slope_e_per_amol > 0 else math.inf
        out.update(lod_from_blank_spread_amol=interpolate_lod(amounts, expected, t),
                   lod_from_blank_spread_se_amol=se)
    return out
