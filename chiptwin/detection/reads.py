"""Base calling from flowgrams: the phase-correcting caller and per-base quality values.

Two callers, both in flow space on normalised flow values (a 1-mer reads ≈ 1):

``round``
    Each flow's value rounded to a homopolymer length
    (:func:`chiptwin.kinetics.pyro.call_sequence`), kept as the twin's first caller; its calls
    are not dephased, but its qualities come from the dephasing caller's posterior
    (:func:`call_rounded`).
``dephase``
    Model-based dephasing after Eltoukhy & El Gamal ("Modeling and base-calling for DNA
    sequencing-by-synthesis", ICASSP 2006): the flowgram of a strand population under incomplete
    extension ε, carry-forward λ and droop δ (:func:`chiptwin.kinetics.phasing.phased_signal`) is
    predicted from the current calls; each flow's value is then ``a_k·h + b_k``, the in-phase
    strands' share ``a_k`` times the unknown homopolymer length ``h`` plus the out-of-phase leak
    ``b_k``, and ``h`` is re-called from its posterior (:func:`dephase`, a left-to-right sweep;
    then :func:`polish`, a hill climb of the whole read's likelihood). ε, λ and δ are estimated
    from the read itself (:func:`estimate_phasing`: coordinate descent over grids, each point
    scored by the likelihood of the read's first 96, then 192 flows, each parameter set above 0
    charged the Bayesian information criterion, and kept only when the whole read says so:
    :func:`keep_phasing`), with the light an empty flow reads besides the leak, β
    (:data:`EMPTY_LIGHT_GRID`: the mean of ``h = 0`` is ``b_k + β``), and the read's 1-mer
    level from its called flows after each of the two fits (:func:`rescale`). 454: ε 0.1–0.3 %,
    λ 1–2 % (Margulies et al., Nature 437:376, 2005). The last :data:`TAIL_FLOWS` flows are
    left uncalled.

Quality values (phred, Ewing & Green, Genome Res. 8:186, 1998: ``Q = −10·log10 P(error)``)
come from the posterior of each flow's call under the noise the twin predicts for that flow
(:class:`FlowNoise`): a flow value for ``h`` is Normal with mean ``a_k·h + b_k`` and variance
``floor + shot·m + ref·m²`` (``m`` the mean): the empty-flow floor (dark, read and quantisation
noise), the shot noise per incorporated base, and the error of the read's 1-mer scale. The prior
(:class:`Prior`) follows the flow order (the next homopolymer's base is neither the last one's
nor any dispensed since) with the read's own composition and length histogram. The posterior is
averaged over the phasing estimate's grid neighbours and widened where the residuals exceed the
prediction (:func:`final_posterior`). As 454 does, the ``i``-th base of a called ``h``-mer is
wrong when the true length is below ``i``; an under-call is charged to the run's last base, a
run missed entirely (a flow called 0) to the base before the gap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chiptwin.detection._posterior_kernels import (
    mixed_posterior,
    posterior_kernel,
    window_inflation,
)
from chiptwin.detection._read_kernels import (
    P_POS_MIN,
    _score,
    context_prior,
    dephase_kernel,
    polish_kernel,
    template_of,
)
from chiptwin.kinetics._phasing_kernels import phase_flows

CALLERS = ("round", "dephase")
"""The base callers a scene may name (``[assay] caller``)."""

MAX_CALL = 12
"""The longest homopolymer the callers resolve (bases): the posterior runs over 0 … MAX_CALL.
454 flowgrams stop separating lengths near 8–10 (Balzer et al., Bioinformatics 26:i420, 2010:
the flow-value spread reaches half a base there); a template with a longer run is refused."""

Q_MAX = 40
"""Highest quality stated (phred): 454's own ceiling; a posterior error below 1e-4 says 40."""

EPS_GRID = np.array([0.0, 0.001, 0.002, 0.004, 0.008, 0.015])
LAMBDA_GRID = np.array([0.0, 0.0025, 0.005, 0.0075, 0.01, 0.015, 0.02, 0.03, 0.04])
"""The grids the phasing search walks (fractions per flow), wide of the 454 values."""



@dataclass(frozen=True)
class FlowNoise:
    """The predicted noise of a normalised flow value with mean ``m``:
    ``var = floor + shot·m + ref·m²``. Unit: incorporations²."""

    floor: float
    shot: float
    ref: float = 0.0

    def var(self, mean: np.ndarray) -> np.ndarray:
        m = np.maximum(mean, 0.0)
        return self.floor + self.shot * m + self.ref * m * m


@dataclass(frozen=True)
class Read:
    """One called read: calls per flow, the posterior, and the phasing estimated."""

    calls: NDArray[np.int64]
    posterior: NDArray[np.float64]  # (n_flows, MAX_CALL + 1)
    eps: float
    lam: float
    droop: float
    n_called: int | None = None  # flows called (None: all); the rest are left uncalled
    gain: float = 1.0  # the read's 1-mer level re-estimated, relative to the key's
    corrected: NDArray[np.float64] | None = None  # phase-corrected flow values (a·h + b → h)
    noise: FlowNoise | None = None  # the noise the posterior was computed under
    empty_light: float = 0.0  # the light of an empty flow estimated (1-mers; EMPTY_LIGHT_GRID)

    def bases(self, flow_order: str) -> str:
        letters = np.frombuffer(flow_order.encode("ascii"), dtype=np.uint8)
        flow = self.flow_index()
        return letters[flow % letters.size].tobytes().decode("ascii")

    def flow_index(self) -> NDArray[np.int64]:
        """0-based flow of every called base."""
        return np.repeat(np.arange(self.calls.size), self.calls)

    def base_error(self) -> NDArray[np.float64]:
        """P(error) of every called base (module docstring), in read order."""
        return base_error(self.calls, self.posterior)


def gap_base(calls: np.ndarray) -> NDArray[np.int64]:
    """Per flow, the called base a run missed there is charged to: the last one called before
    the flow (the read's first base when none is)."""
    return np.maximum(np.cumsum(calls) - np.asarray(calls) - 1, 0).astype(np.int64)


def base_error(calls: np.ndarray, post: np.ndarray) -> np.ndarray:
    """Per-base error probability, as 454 states it: base ``i`` (1-based) of a called ``h``-mer
    is wrong with probability ``P(H < i)``, the last one also ``P(H > h)``; a flow called 0
    charges its ``P(H > 0)``, a run missed entirely, to the base before the gap
    (:func:`gap_base`). Capped at 1."""
    below = np.cumsum(post, axis=1)  # below[k, i] = P(H <= i)
    calls = np.asarray(calls, dtype=np.int64)
    k = np.flatnonzero(calls)
    h = calls[k]
    if not k.size:
        return np.zeros(0)
    flow = np.repeat(k, h)
    i = np.arange(flow.size) - np.repeat(np.cumsum(h) - h, h)  # i − 1 for base i of its run
    # P(H < i) for i = 1 … h; a call beyond MAX_CALL: its extra bases get no chance
    p = np.where(i < MAX_CALL, below[flow, np.minimum(i, MAX_CALL)], 1.0)
    last = np.cumsum(h) - 1
    p[last] += np.where(h <= MAX_CALL, 1.0 - below[k, np.minimum(h, MAX_CALL)], 0.0)
    empty = np.flatnonzero(calls == 0)
    np.add.at(p, gap_base(calls)[empty], 1.0 - post[empty, 0])
    return np.clip(p, 0.0, 1.0)


def phred(p_error: np.ndarray) -> np.ndarray:
    """Phred quality ``round(−10·log10 p)`` in 0 … :data:`Q_MAX` (Ewing & Green 1998)."""
    q = -10.0 * np.log10(np.maximum(p_error, 10.0 ** (-Q_MAX / 10.0)))
    return np.clip(np.rint(q), 0, Q_MAX).astype(np.int64)


@dataclass(frozen=True)
class Prior:
    """The prior of a flow's homopolymer length, from the read's own calls: the base
    composition ``comp`` (A, C, G, T), which with the flow order since the last called base
    gives P(h > 0) (:func:`chiptwin.detection._read_kernels.context_prior`), and the log length
    distribution ``log_len[h] = log P(h | h > 0)`` (``log_len[0]`` unused)."""

    comp: NDArray[np.float64]
    log_len: NDArray[np.float64]

    @classmethod
    def of(cls, calls: np.ndarray, flows: np.ndarray) -> Prior:
        """Counts of the called bases and homopolymer lengths, plus one half each."""
        comp = np.bincount(flows, weights=calls, minlength=4)[:4] + 0.5
        lengths = np.bincount(np.clip(calls[calls > 0], 1, MAX_CALL), minlength=MAX_CALL + 1)
        lengths = lengths[: MAX_CALL + 1].astype(float) + 0.5
        lengths[0] = 0.0
        log_len = np.full(MAX_CALL + 1, -np.inf)
        log_len[1:] = np.log(lengths[1:] / lengths[1:].sum())
        return cls(comp / comp.sum(), log_len)

    def p_pos(self, calls: np.ndarray, flows: np.ndarray) -> np.ndarray:
        """P(h_k > 0) of every flow given the calls before it."""
        return context_prior(calls.astype(np.int64), flows, self.comp, 4)


def posterior(y: np.ndarray, a: np.ndarray, b: np.ndarray, noise: FlowNoise,
              p_pos: np.ndarray, log_len: np.ndarray, inflate: np.ndarray | None = None,
              beta: float = 0.0) -> np.ndarray:
    """P(h | y_k) for h = 0 … MAX_CALL, per flow: shape (n_flows, MAX_CALL + 1); the
    variance of flow ``k`` is multiplied by ``inflate[k]`` (default 1), and ``h = 0``'s mean
    carries the empty-flow light ``beta``."""
    y = np.asarray(y, dtype=np.float64)
    inflate = np.ones(y.size) if inflate is None else np.asarray(inflate, dtype=np.float64)
    return posterior_kernel(y, np.asarray(a, dtype=np.float64),
                            np.asarray(b, dtype=np.float64), noise.floor, noise.shot, noise.ref,
                            np.asarray(p_pos, dtype=np.float64), log_len, inflate, float(beta))


#: Half-width of the window over which :func:`local_inflation` averages the residuals (flows).
RESIDUAL_HALF_WINDOW = 8


def local_inflation(y: np.ndarray, signal: np.ndarray, noise: FlowNoise,
                    half: int = RESIDUAL_HALF_WINDOW) -> np.ndarray:
    """Each flow's variance factor ``max(1, mean of (y − s)²/var over its window)``: where the
    model of the read misses (neighbouring calls wrong, phasing misestimated), the residuals
    say so, and the posterior widens by as much. The window is clipped to the read."""
    y = np.ascontiguousarray(y, dtype=np.float64)
    out = np.empty(y.size)
    window_inflation(y, np.ascontiguousarray(signal, dtype=np.float64), noise.floor,
                     noise.shot, noise.ref, half, out)
    return out


def phase_model(calls: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """(signal, in-phase share, ideal counts) of the template the calls spell, per flow
    (:func:`chiptwin.kinetics.phasing.phased_signal`)."""
    return phase_flows(template_of(calls.astype(np.int64), flows), flows, eps, lam, droop)


#: Flows re-called at a time in :func:`dephase`'s left-to-right sweep (six cycles of a 4-base
#: order): a call changed early shifts the model of every later flow, so later changes wait
#: until the prefix before them has settled.
WINDOW = 24


def dephase(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, eps: float, lam: float,
            droop: float, start: np.ndarray, prior: Prior, n_iter: int | None = None,
            n_score: int | None = None, beta: float = 0.0) -> tuple[np.ndarray, float]:
    """Re-call flows from the model of the current calls, sweeping left to right.

    Each step predicts the flowgram of the current calls, re-calls every flow from its
    posterior, and accepts the changes only in the :data:`WINDOW` flows from the first flow that
    changed; it stops when no call changes (or after ``n_iter`` steps, default enough for every
    window three times). The likeliest iterate is kept: far into a read, where the in-phase
    share is low, the sweep can cycle between nearby call sets.

    Returns the calls and their negative log-likelihood over the first ``n_score`` flows (all
    by default); ``beta`` is the light of an empty flow (:data:`EMPTY_LIGHT_GRID`).
    """
    n_score = y.size if n_score is None else n_score
    n_iter = 3 * (y.size // WINDOW + 1) if n_iter is None else n_iter
    calls, nll = dephase_kernel(
        np.ascontiguousarray(y, dtype=np.float64), flows, float(eps), float(lam), float(droop),
        start.astype(np.int64), prior.comp, prior.log_len, noise.floor, noise.shot, noise.ref,
        int(n_score), int(n_iter), WINDOW, float(beta))
    return calls, float(nll)


#: The prefixes the phasing search scores, in flows (24 and 48 cycles of a 4-base order): the
#: first where the rounded calls are still nearly all right, then a longer one on the dephased
#: calls, so that a read's noisy tail never steers the estimate.
FIT_FLOWS = (96, 192)

#: Sweep steps per scored point of the search (it starts from calls already near the fixed point).
SCORE_STEPS = 4

DROOP_GRID = np.array([0.0, 0.0005, 0.001, 0.002, 0.004, 0.008, 0.016])
"""The droop values the search walks (per flow)."""

EMPTY_LIGHT_GRID = np.array([0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 0.12, 0.15, 0.2, 0.3])
"""The empty-flow light β the search walks (1-mers): what a flow that extends nothing reads
besides the phasing leak. 454's phase-corrected values leave empty flows near +0.09 (GS FLX
0.088 in the PyroNoise profiles, Quince et al., Nature Methods 6:639, 2009) while 1- to 4-mers
sit within 0.013 of their length; a caller without it reads that light as carry-forward (λ 1.5 %
for the twin's 1 % under the 454 FLX chemistry)."""


def _descend(grid: np.ndarray, start: float, score) -> float:
    """The grid value where ``score`` stops falling, walking from the point nearest ``start``
    to the better neighbour (a local search: the score is smooth in each parameter)."""
    i = int(np.argmin(np.abs(grid - start)))
    cache = {i: score(float(grid[i]))}
    while True:
        for j in (i - 1, i + 1):
            if 0 <= j < grid.size and j not in cache:
                cache[j] = score(float(grid[j]))
        best = min((j for j in (i - 1, i, i + 1) if j in cache), key=cache.__getitem__)
        if best == i:
            return float(grid[i])
        i = best


#: Penalty of each phasing parameter the estimate sets above 0, in nats per ln(flows scored):
#: 0.5 is the Bayesian information criterion (Schwarz, Ann. Stat. 6:461, 1978). A flowgram
#: already phase-corrected (454's SFF values, Ion's FZ) has nothing to estimate, and a λ or
#: droop fitted to its first flows' noise, carried over a 1,000-flow read, miscalls its far end
#: (Ion, 449 reads: 2,756 errors unpenalised against the instrument's 1,193); a read that is
#: phased gains hundreds of nats from each.
PHASING_PENALTY = 0.5


def estimate_phasing(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, calls: np.ndarray,
                     prior: Prior, n_fit: int, start: tuple[float, float, float, float],
                     empty_light: bool = True) -> tuple[float, float, float, float]:
    """(ε, λ, δ, β) by coordinate descent over :data:`LAMBDA_GRID`, :data:`EPS_GRID`,
    :data:`DROOP_GRID` and :data:`EMPTY_LIGHT_GRID`, then each once more, each a local walk from
    the current value; each point is scored by the likelihood of the first ``n_fit`` flows after
    re-calling them (:data:`SCORE_STEPS` dephasing steps from ``calls``), plus
    :data:`PHASING_PENALTY` per parameter above 0. β comes after the phasing and the phasing is
    walked again after it: the empty flows' own light, before β takes it, reads as carry-forward
    and incomplete extension, and droop trades with ε (once: droop 0.05 % for the FLX scene's
    0.1 %). Without ``empty_light`` β stays at its start."""
    yy, ff, cc = y[:n_fit], flows[:n_fit], calls[:n_fit]
    par = list(start)
    cost = PHASING_PENALTY * np.log(max(n_fit, 1))

    def score(i: int, value: float) -> float:
        trial = list(par)
        trial[i] = value
        return (dephase(yy, ff, noise, *trial[:3], cc, prior, n_iter=SCORE_STEPS,
                        beta=trial[3])[1] + cost * sum(p > 0 for p in trial))

    for i, grid in ((1, LAMBDA_GRID), (0, EPS_GRID), (2, DROOP_GRID), (3, EMPTY_LIGHT_GRID),
                    (1, LAMBDA_GRID), (0, EPS_GRID), (2, DROOP_GRID), (3, EMPTY_LIGHT_GRID)):
        if i != 3 or empty_light:
            par[i] = _descend(grid, par[i], lambda v, i=i: score(i, v))
    return par[0], par[1], par[2], par[3]


def call_dephased(y: np.ndarray, flows: np.ndarray, noise: FlowNoise,
                  empty_light: bool = True) -> Read:
    """Call a read with ε, λ and δ estimated from it (module docstring), its last
    :data:`TAIL_FLOWS` flows left uncalled.

    Parameters
    ----------
    y : float64 (n_flows,)
        Normalised flow values.
    flows : int64 (n_flows,)
        Base index (ACGT) of each flow.
    noise : FlowNoise
        The twin's predicted noise of this read's flow values.
    empty_light : bool
        Estimate the light of an empty flow (:data:`EMPTY_LIGHT_GRID`); off for flowgrams a
        vendor already phase-corrected, whose 0-mer level is the vendor's.
    """
    return end_read(read_model(y, flows, noise, empty_light))


def read_model(y: np.ndarray, flows: np.ndarray, noise: FlowNoise,
               empty_light: bool = True) -> Read:
    """The whole read's calls, phasing and posterior, every flow called: what
    :func:`call_dephased` reads and the posterior both callers' qualities come from."""
    calls = np.clip(np.rint(y), 0, MAX_CALL).astype(np.int64)
    prior = Prior.of(calls, flows)
    est = (0.0, 0.0, 0.0, 0.0)  # ε, λ, δ and the empty-flow light β
    gain = 1.0
    for i, n_fit in enumerate(FIT_FLOWS):
        est = estimate_phasing(y, flows, noise, calls, prior, min(n_fit, y.size), est,
                               empty_light)
        m = min(FIT_FLOWS[i + 1], y.size) if i + 1 < len(FIT_FLOWS) else y.size
        calls[:m] = dephase(y[:m], flows[:m], noise, *est[:3], calls[:m], prior,
                            beta=est[3])[0]
        prior = Prior.of(calls, flows)
        # the read's 1-mer level from the flows just fitted, again once the longer prefix has
        # settled the phasing (a spurious ε on the first 96 flows scales the read 2 % high)
        y, noise, g = rescale(y, flows, noise, calls, est[:3], min(n_fit, y.size), est[3])
        est = (*est[:3], est[3] / g)  # the empty flows' light, in the new 1-mer units
        gain *= g
    par, beta = est[:3], est[3]
    calls = polish(y, flows, noise, par, calls, prior, beta)
    calls, par = keep_phasing(y, flows, noise, calls, par, prior, beta)
    signal, a, _ = phase_model(calls, flows, *par)
    corrected = (y - (signal - a * calls)) / np.maximum(a, 1e-3)
    return Read(calls, final_posterior(y, flows, noise, calls, par, beta), *par, gain=gain,
                corrected=corrected, noise=noise, empty_light=beta)


def read_nll(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, calls: np.ndarray,
             par: tuple[float, float, float], prior: Prior, beta: float = 0.0) -> float:
    """Negative log-posterior of a whole read's calls under phasing ``par`` and empty-flow
    light ``beta``."""
    return float(_score(np.ascontiguousarray(y, dtype=np.float64), flows,
                        calls.astype(np.int64), *par, prior.comp, prior.log_len, noise.floor,
                        noise.shot, noise.ref, float(beta))[0])


def keep_phasing(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, calls: np.ndarray,
                 par: tuple[float, float, float], prior: Prior, beta: float = 0.0
                 ) -> tuple[np.ndarray, tuple[float, float, float]]:
    """The phasing estimated on the read's first flows, kept only when the whole read says so:
    the read called again without phasing (the sweep and the hill climb from the rounded
    values) and the two call sets scored over every flow, each non-zero parameter charged
    :data:`PHASING_PENALTY`. A flowgram already phase-corrected shows its first flows' noise as
    a little ε or λ (454's Titanium values: ε 0.1–0.2 % on 21 of 24 reads), which, carried over
    800 flows, miscalls the read's far end; a phased read's far end needs it. Both keep the
    empty-flow light ``beta``. The flat re-call is skipped when no call set without phasing
    could win (:func:`flat_floor`): on ``pyro_long_read`` every read, a ninth of the caller's
    time."""
    if not any(par):
        return calls, par
    cost = PHASING_PENALTY * np.log(max(y.size, 1)) * sum(p > 0 for p in par)
    phased = read_nll(y, flows, noise, calls, par, prior, beta) + cost
    if flat_floor(y, noise, beta) > phased + 1e-9 * (abs(phased) + 1.0):
        return calls, par  # no call set without phasing could score better
    flat = dephase(y, flows, noise, 0.0, 0.0, 0.0,
                   np.clip(np.rint(y), 0, MAX_CALL).astype(np.int64), prior, beta=beta)[0]
    flat = polish(y, flows, noise, (0.0, 0.0, 0.0), flat, prior, beta)
    if read_nll(y, flows, noise, flat, (0.0, 0.0, 0.0), prior, beta) <= phased:
        return flat, (0.0, 0.0, 0.0)
    return calls, par


#: The largest flow value :func:`flat_floor` scans whole-number light up to (1-mers): four
#: times the longest run the caller resolves; a read with a larger one gets no floor (−∞).
FLAT_FLOOR_MAX = 4 * MAX_CALL


def flat_floor(y: np.ndarray, noise: FlowNoise, beta: float = 0.0) -> float:
    """The least negative log-posterior any call set scores without phasing (ε = λ = δ = 0):
    each flow's light is then a whole number ``s`` of bases (``beta``, the empty-flow light,
    for ``s = 0``), and its term ``(y − s)²/2v(s) + log v(s)/2`` rises with ``s`` past ``y``
    (``s·v′(s) < 2v(s)`` for ``v = floor + shot·s + ref·s²``), so each flow's least is among
    ``s = 0 … ⌈y⌉`` (``y`` taken as 0 where it is negative, which only lowers the term); the
    prior adds at least ``−log(1 − P_POS_MIN)`` a flow. On a phased read the leak makes most
    flows' light fall between whole numbers and this alone exceeds the phased calls' score, so
    the flat re-call of :func:`keep_phasing` (its sweep and hill climb) need not run."""
    yy = np.maximum(np.asarray(y, dtype=np.float64), 0.0)
    if beta < 0 or not yy.max(initial=0.0) <= FLAT_FLOOR_MAX:
        return -np.inf  # the argument needs β ≥ 0; far beyond the caller's lengths, no floor
    s = np.arange(int(np.ceil(yy.max(initial=0.0))) + 1, dtype=np.float64)
    s[0] = beta
    v = noise.floor + noise.shot * s + noise.ref * s * s
    term = 0.5 * (yy[:, None] - s[None, :]) ** 2 / v + 0.5 * np.log(v)
    # s above ⌈y⌉ is never the least (the term rises there)
    term = np.where(np.arange(s.size)[None, :] <= np.ceil(yy)[:, None], term, np.inf)
    return float(term.min(axis=1).sum() - yy.size * np.log(1.0 - P_POS_MIN))


def rescale(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, calls: np.ndarray,
            par: tuple[float, float, float], n_fit: int, beta: float = 0.0
            ) -> tuple[np.ndarray, FlowNoise, float]:
    """The read's 1-mer level re-estimated from its first ``n_fit`` called flows (least squares
    of the values on the model, the empty flows' light ``beta`` in it), the values divided by
    it, and the noise moved with them: the key's three 1-mers set one scale for the whole read,
    whose error grows with the homopolymer (σ ∝ h, :class:`FlowNoise` ``ref``); the read's many
    called flows pin it down, leaving the least-squares estimate's own variance."""
    signal, _, _ = phase_model(calls, flows, *par)
    s, v = (signal + np.where(calls == 0, beta, 0.0))[:n_fit], y[:n_fit]
    den = float(np.dot(s, s))
    if den <= 0:
        return y, noise, 1.0
    g = float(np.dot(v, s) / den)
    if not g > 0:
        return y, noise, 1.0
    per_flow = FlowNoise(noise.floor, noise.shot)  # the old scale's error is what g estimates
    var_g = float(np.dot(s * s, per_flow.var(s))) / den**2
    return y / g, FlowNoise(noise.floor / g**2, noise.shot / g, var_g / g**2), g


#: Flows at the end of a flowgram left uncalled (two cycles of a 4-base order): their calls lean
#: on the light of strands carried ahead, which no later flow shows, so a wrong length there
#: explains the data as well as the right one and its posterior is overconfident.
TAIL_FLOWS = 8


def end_read(read: Read) -> Read:
    """The read without its last :data:`TAIL_FLOWS` flows' bases (called 0, posterior 1 at 0)."""
    n = read.calls.size
    keep = max(n - TAIL_FLOWS, 0)
    calls = read.calls.copy()
    post = read.posterior.copy()
    calls[keep:] = 0
    post[keep:] = 0.0
    post[keep:, 0] = 1.0
    return Read(calls, post, read.eps, read.lam, read.droop, keep, read.gain, read.corrected,
                read.noise, read.empty_light)


#: :func:`polish`: flows tried per round, the standardised residual below which a flow is left
#: alone, and the most changes made.
POLISH_TRY, POLISH_Z, POLISH_ROUNDS = 24, 3.0, 200


def polish(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, par: tuple[float, float, float],
           calls: np.ndarray, prior: Prior, beta: float = 0.0) -> np.ndarray:
    """Hill-climb the whole read's likelihood from the sweep's calls, one base at a time where
    the residuals are largest: far into a read, where fewer than half the strands are in phase,
    the sweep can settle on a call set that explains a base by the leading strands' light; the
    whole-read likelihood tells them apart. ``beta``: the empty-flow light."""
    return polish_kernel(np.ascontiguousarray(y, dtype=np.float64), flows, *par,
                         calls.astype(np.int64), prior.comp, prior.log_len, noise.floor,
                         noise.shot, noise.ref, POLISH_TRY, POLISH_Z, POLISH_ROUNDS,
                         float(beta))


#: Factor on every flow's predicted variance in the posterior the qualities come from: the
#: posterior treats the other flows' calls as known, but a miscall shifts its neighbours' leak.
#: 1.25 from Monte Carlo at 454-like noise (0-mer sd 0.08, ε 0.2 %, λ 1 %, droop 0.1 %, 400 reads
#: of 200 flows, three seeds): 1.0 left Q15–25 bases 2–4× more often wrong than stated, 1.5 made
#: Q10–15 half as often wrong, 1.25 kept Q15–Q35 inside their 95 % intervals (Q10–15 in or out
#: by seed: a read's errors cluster).
MODEL_INFLATION = 1.25


def _neighbours(grid: np.ndarray, value: float) -> list[float]:
    i = int(np.argmin(np.abs(grid - value)))
    return sorted({float(grid[j]) for j in (i - 1, i, i + 1) if 0 <= j < grid.size} | {value})


def final_posterior(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, calls: np.ndarray,
                    par: tuple[float, float, float], beta: float = 0.0) -> np.ndarray:
    """The posterior the qualities come from: the model of the final calls and their prior,
    averaged over the phasing estimate's neighbours on the search grids (ε, λ, δ one step either
    way, weighted by the read's likelihood under each: the estimate's own uncertainty), with the
    variance widened where the read's residuals exceed the predicted noise
    (:func:`local_inflation`) and by :data:`MODEL_INFLATION`; neighbours weighing less than
    :data:`MIN_WEIGHT` are left out. Empty flows carry the empty-flow light ``beta``."""
    prior = Prior.of(calls, flows)
    calls = calls.astype(np.int64)
    grid = [np.array(_neighbours(g, v)) for g, v in zip((EPS_GRID, LAMBDA_GRID, DROOP_GRID), par,
                                                        strict=True)]
    return mixed_posterior(np.ascontiguousarray(y, dtype=np.float64), template_of(calls, flows),
                           flows, calls, *grid, noise.floor, noise.shot, noise.ref,
                           prior.p_pos(calls, flows), prior.log_len, RESIDUAL_HALF_WINDOW,
                           MODEL_INFLATION, MIN_WEIGHT, float(beta))


#: The least weight a phasing neighbour's posterior is mixed in with (:func:`final_posterior`;
#: the others' renormalised): the 26 others together move no probability by more than 3e-11,
#: seven decades under the 1e-4 at which the qualities stop (:data:`Q_MAX`).
MIN_WEIGHT = 1e-12


def call_rounded(y: np.ndarray, flows: np.ndarray, noise: FlowNoise,
                 empty_light: bool = True) -> Read:
    """Today's caller (:func:`chiptwin.kinetics.pyro.call_sequence`: round half up, clipped to
    0 … :data:`MAX_CALL`), its calls not dephased, with the qualities of those calls under the
    same posterior as the dephasing caller's (:func:`read_model`): the phasing the rounding
    ignores is in the posterior, so a 4-mer read as 3.4 far into a phased read is not stated
    Q30 (it was, from a posterior without phasing: on reads of ε 0.2 %, λ 1 %, droop 0.1 %,
    bases stated Q35+ were wrong 9 % of the time)."""
    calls = np.floor(np.clip(y, 0.0, MAX_CALL) + 0.5).astype(np.int64)
    model = read_model(y, flows, noise, empty_light)
    post = model.posterior.copy()
    tail = slice(max(y.size - TAIL_FLOWS, 0), None)
    post[tail] = (1.0 - TAIL_DOUBT) * post[tail] + TAIL_DOUBT / post.shape[1]
    return Read(calls, post, model.eps, model.lam, model.droop, gain=model.gain,
                noise=model.noise, empty_light=model.empty_light)


#: Share of a flat distribution mixed into the posterior of the last :data:`TAIL_FLOWS` flows
#: the ``round`` caller calls (the dephasing caller leaves them uncalled): their posterior is
#: overconfident (:data:`TAIL_FLOWS`), and this keeps each such call's stated error ≥ 1.8 %.
#: Measured (Monte Carlo, 150 reads of 200 flows, ε 0.2 %, λ 1 %, droop 0.1 %, 0-mer sd 0.03
#: and 0.08): 9 of 799 tail bases stated better than 1 % were wrong (1.1 %).
TAIL_DOUBT = 0.02
