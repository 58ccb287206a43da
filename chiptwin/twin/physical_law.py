"""``summary['physical_law']``: what a scene run under the paper's NA² convention would read with
the physical emitter law.

The paper (Salama et al., Biosensors & Bioelectronics 19, 2004, Sec. 3.1) writes the contact
collection efficiency as NA², a Lambertian emitter's share of a cone; molecules in solution emit
isotropically, which through the same stack puts about half that light on the diodes. The
scenes that reproduce a paper figure keep the convention (their figures are the paper's); each
such run also says how far the physical law would move its answer: the same scene, isotropic,
at the ``expected`` photon level with the float DSP (means and variances, no draws, so the
ratio holds no Monte Carlo noise) against the same scene at those levels under the convention.
Ratios of the sites' signal and power SNR, the median over the sites and the first site.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from chiptwin.config import Scenario, ScenarioError, cost
from chiptwin.config.consistency import check_consistency

PHYSICAL_LAW = cost.PHYSICAL_LAW
applies = cost.physical_law_applies


def beside(s: Scenario, run_once) -> dict[str, Any] | None:
    """The figures, or None where the convention is not in force. ``run_once(scenario)`` runs a
    resolved scenario and returns its summary (the runner's own path, passed in). Left out
    (with the reason) when the two runs are estimated above ``cost.PHYSICAL_LAW_MAX_S``: the
    scene's own run is what the user asked for, the comparison a remark beside it."""
    if not applies(s):
        return None
    if not s.run.beside_physical_law:
        return {"emitter": PHYSICAL_LAW, "computed": False,
                "why_not": "run.beside_physical_law = false"}
    base, physical = cost.law_comparison(s)
    try:
        check_consistency(physical)
        check_consistency(base)
    except ScenarioError as exc:
        return {"emitter": PHYSICAL_LAW, "computed": False,
                "why_not": f"{exc.key} = {exc.value!r}: {exc.allowed}"}
    seconds = cost.law_comparison_seconds((base, physical))
    if seconds > cost.PHYSICAL_LAW_MAX_S:
        return {"emitter": PHYSICAL_LAW, "computed": False,
                "why_not": f"two expected-level runs, ≈ {seconds:.3g} s estimated, above "
                           f"{cost.PHYSICAL_LAW_MAX_S:g} s: run the scene with optics.emitter = "
                           f"\"{PHYSICAL_LAW}\" to compare"}
    conv, phys = run_once(base)["sites"], run_once(physical)["sites"]
    signal = np.array([p["signal_e"] / c["signal_e"] if c["signal_e"] else np.nan
                       for p, c in zip(phys, conv, strict=True)])
    snr = np.array([p["snr_power"] / c["snr_power"] if c["snr_power"] else np.nan
                    for p, c in zip(phys, conv, strict=True)])
    return {"emitter": PHYSICAL_LAW, "computed": True, "level": "expected",
            "signal_ratio": _round(signal[0]), "snr_power_ratio": _round(snr[0]),
            "signal_ratio_median": _round(_median(signal)),
            "snr_power_ratio_median": _round(_median(snr)),
            "note": "the paper's NA² convention (lambertian_na2) against isotropic emitters "
                    "through the same stack, both at the expected photon level"}


def _median(x: np.ndarray) -> float:
    """The median of the defined ratios; NaN where no site reads a signal (a full well of one
    electron), without NumPy's all-NaN warning."""
    x = x[np.isfinite(x)]
    return float(np.median(x)) if x.size else np.nan


def _round(x: float) -> float | None:
    return None if not np.isfinite(x) else round(float(x), 4)


__all__ = ["PHYSICAL_LAW", "applies", "beside"]
