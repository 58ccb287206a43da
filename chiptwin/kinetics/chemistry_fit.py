"""The flow-value model fitted to measured flow-value distributions, and distances between them.

The fast path: the model's law of each true length's value (:func:`flow_value_distribution`,
exact on the flowgram's 0.01 bins, with the chain's noise the twin predicts) against the measured
law, by maximum likelihood (the cross-entropy of the measured bins under the model's, summed
over the lengths fitted, each length weighted alike), searched by Powell's method within the
parameters' ranges (``scipy.optimize.minimize``; deterministic: no random draws). No chip is
simulated per candidate; twin runs with the fitted values check the result
(:mod:`chiptwin.report.flow_profile_out`).

Distances per length: total variation ``½ Σ |p − q|`` over the bins and Kolmogorov–Smirnov
``max |P − Q|`` of the cumulative sums.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize

from chiptwin.kinetics.chemistry import (
    BIN,
    N_BINS,
    FlowModel,
    flow_value_distribution,
)

#: Probability floor of a model bin in the cross-entropy: a measured tail bin the model gives
#: no mass would make the cost infinite (the profiles' tails reach 1e-9).
P_FLOOR = 1e-12


def value_bins(values: ArrayLike, n_bins: int = N_BINS) -> NDArray[np.int64]:
    """The bin of each flow value (rounded to hundredths; below 0 → bin 0, above → the last)."""
    v = np.asarray(values, dtype=np.float64)
    return np.clip(np.floor(v / BIN + 0.5), 0, n_bins - 1).astype(np.int64)


def histograms(values: ArrayLike, lengths: ArrayLike, max_length: int,
               n_bins: int = N_BINS) -> NDArray[np.float64]:
    """Counts of values per true length 0 … ``max_length`` and bin: (max_length + 1, n_bins)."""
    h = np.asarray(lengths, dtype=np.int64)
    keep = h <= max_length
    idx = h[keep] * n_bins + value_bins(np.asarray(values)[keep], n_bins)
    return np.bincount(idx, minlength=(max_length + 1) * n_bins).reshape(max_length + 1, n_bins
                                                                         ).astype(np.float64)


def total_variation(p: ArrayLike, q: ArrayLike) -> float:
    """½ Σ |p − q| of two distributions on the same bins (each normalised here)."""
    p, q = _norm(p), _norm(q)
    return 0.5 * float(np.abs(p - q).sum())


def ks_distance(p: ArrayLike, q: ArrayLike) -> float:
    """max |P − Q| of the cumulative sums of two distributions on the same bins."""
    p, q = _norm(p), _norm(q)
    return float(np.abs(np.cumsum(p) - np.cumsum(q)).max())


def _norm(p: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(p, dtype=np.float64)
    s = a.sum()
    if not s > 0:
        raise ValueError("a distribution must have a positive total")
    return a / s


@dataclass(frozen=True)
class ChainNoise:
    """The chain's noise of a normalised flow value, ``floor + shot·h`` (1-mer²): the twin's
    predicted noise (dark, read and quantisation noise; shot noise per base)."""

    floor: float = 0.0
    shot: float = 0.0


def model_distributions(model: FlowModel, lengths: list[int], chain: ChainNoise = ChainNoise(),
                        n_bins: int = N_BINS) -> dict[int, NDArray[np.float64]]:
    """The model's law of each length's value on the bins."""
    return {h: flow_value_distribution(h, model, chain.floor, chain.shot, n_bins)
            for h in lengths}


#: The searched parameters, in the order of the search vector.
SEARCHED = ("flow_yield_cv", "flow_noise_sd", "flow_background", "well_noise_cv",
            "homopolymer_yield_loss", "empty_flow_mean", "empty_flow_sd")

#: Each searched parameter's range (the model's own); the search vector is clipped into it.
BOUNDS = {"flow_yield_cv": (0.0, 0.5), "flow_noise_sd": (0.0, 0.5),
          "flow_background": (-0.2, 0.2), "well_noise_cv": (0.0, 3.0),
          "homopolymer_yield_loss": (0.0, 0.2), "empty_flow_mean": (-0.5, 0.5),
          "empty_flow_sd": (0.0, 0.5)}


def _bounds(law: str, free: list[str]) -> list[tuple[float, float]]:
    """The search box: :data:`BOUNDS`, a lognormal empty flow's mean >= 0."""
    return [(0.0, 0.5) if n == "empty_flow_mean" and law == "lognormal" else BOUNDS[n]
            for n in free]


def _model_of(x: NDArray[np.float64], law: str, fixed: Mapping[str, float]) -> FlowModel:
    """Search vector (the :data:`SEARCHED` parameters not in ``fixed``) → FlowModel."""
    free = [n for n in SEARCHED if n not in fixed]
    values = {n: float(np.clip(v, lo, hi))
              for n, v, (lo, hi) in zip(free, x, _bounds(law, free), strict=True)}
    return FlowModel(empty_flow_law=law, **values, **fixed)


def cross_entropy(model: FlowModel, targets: Mapping[int, NDArray[np.float64]],
                  chain: ChainNoise = ChainNoise()) -> float:
    """Σ over lengths of −Σ p_target·ln p_model (nats per flow, each length weighted alike)."""
    total = 0.0
    for h, p in targets.items():
        q = flow_value_distribution(h, model, chain.floor, chain.shot, p.size)
        total -= float(np.dot(_norm(p), np.log(np.maximum(q, P_FLOOR))))
    return total


@dataclass(frozen=True)
class Fit:
    """A fitted model, its cost (cross-entropy, nats) and the search's evaluations."""

    model: FlowModel
    cost: float
    evaluations: int


def start_point(targets: Mapping[int, NDArray[np.float64]], law: str,
                fixed: Mapping[str, float]) -> NDArray[np.float64]:
    """A start from the moments: the empty-flow mean and sd from the 0-mers, the yield CV and
    the additive sd from the 1- and highest-mers' variances (``var = sd² + (h·cv)²``)."""
    x = np.arange(N_BINS) * BIN

    def moments(p):
        p = _norm(p)[: x.size]
        m = float(np.dot(p, x[: p.size]))
        return m, float(np.sqrt(max(np.dot(p, (x[: p.size] - m) ** 2), 0.0)))

    m0, s0 = moments(targets[0]) if 0 in targets else (0.05, 0.05)
    ones = sorted(h for h in targets if h >= 1)
    v1 = moments(targets[ones[0]])[1] ** 2 if ones else 0.01
    hk = ones[-1] if ones else 1
    vk = moments(targets[hk])[1] ** 2 if ones else 0.01
    cv2 = max((vk - v1) / max(hk**2 - 1, 1), 1e-4)
    start = {"flow_yield_cv": np.sqrt(cv2), "flow_noise_sd": np.sqrt(max(v1 - cv2, 1e-4)),
             "flow_background": 0.005, "well_noise_cv": 0.5, "homopolymer_yield_loss": 0.002,
             "empty_flow_mean": max(m0, 0.01) if law == "lognormal" else m0,
             "empty_flow_sd": max(s0, 0.01)}
    return np.array([start[n] for n in SEARCHED if n not in fixed])


def fit_flow_model(targets: Mapping[int, ArrayLike], law: str,
                   chain: ChainNoise = ChainNoise(), fixed: Mapping[str, float] | None = None,
                   max_evaluations: int = 3000) -> Fit:
    """The :class:`FlowModel` whose law of each length's value is likeliest for the measured
    distributions ``targets`` (length → probabilities or counts per bin).

    ``law`` is the empty-flow law (``"lognormal"`` or ``"normal"``); ``fixed`` holds parameters
    kept at given values (e.g. ``{"homopolymer_yield_loss": 0.0}``)."""
    t = {int(h): _norm(p) for h, p in targets.items()}
    fixed = dict(fixed or {})

    def cost(x):
        return cross_entropy(_model_of(x, law, fixed), t, chain)

    free = [n for n in SEARCHED if n not in fixed]
    x, best, used = start_point(t, law, fixed), np.inf, 0
    for _ in range(RESTARTS):  # Powell restarted from its own end until it gains nothing
        res = optimize.minimize(cost, x, method="Powell", bounds=_bounds(law, free),
                                options={"maxfev": max_evaluations, "xtol": 1e-5,
                                         "ftol": 1e-9})
        used += int(res.nfev)
        gain, x, best = best - float(res.fun), res.x, min(best, float(res.fun))
        if gain < RESTART_GAIN:
            break
    return Fit(_model_of(x, law, fixed), best, used)


#: Most Powell runs of :func:`fit_flow_model`, and the fall in cost (nats) below which a restart
#: has found nothing more. (Nelder–Mead stopped on a collapsed simplex in these 7 dimensions,
#: 0.007 nats above the true parameters' cost on 200,000 draws per length; L-BFGS-B 0.026
#: above; Powell below it.)
RESTARTS, RESTART_GAIN = 4, 1e-4
