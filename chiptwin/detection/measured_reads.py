"""Measured flowgrams through the twin's callers: the noise read from the flowgrams themselves,
the key-pass filter, the bases after the key.

A measured flow value comes with no predicted noise (the twin's callers weigh each flow with the
DSP's propagated variance, :mod:`chiptwin.twin.reads`). Here it is measured from the file: the
flows of each read rounded to a length ``h``, the mean square of ``y − h`` per length (the flows
within half a base of it), pooled over the file and shrunk toward the pool per read
(:data:`SHRINK_FLOWS` pseudo-flows), then fitted as ``floor + ref·h²``
(:class:`chiptwin.detection.reads.FlowNoise` without its shot term; non-negative least squares
over h = 1 … :data:`FIT_MAX_LENGTH`, weighted by the flows behind each). Lengths are rounded,
so a flow called wrong counts where it was called: the fit is of the calls' scatter, which is
what the posterior weighs.

Measured 0-mers are not Gaussian: Ion's are clipped at 0 (most read exactly 0, with a tail),
454's sit near +0.1. Their own scatter would make a 0-mer far narrower than a 1-mer, so a value
of 0.35 would be called a 1-mer (Ion, zero phasing: 0.35 is 8 of the 0-mers' σ from 0 and 5 of
the 1-mers' from 1), where the instrument's calls, and the truth, say 0. A 0-mer gets the
floor, the 1-mers' variance less their ``ref`` share: the 0/1 boundary stays near 0.5.

Measured flow values have heavier tails than a Gaussian: on the Ion PGM set 1.4 % of the flows
rounded to 1 lie beyond ±0.4 of it, where the 1-mers' own scatter (σ 0.14) puts 0.5 %; and a
flow is miscalled in its tail. The qualities come from a posterior whose likelihood per length
is a Student-t of ν degrees of freedom and scale ``s`` times the fitted Gaussian's sd
(:class:`MeasuredNoise`); ν and ``s`` are fitted to the file's rounded flows by maximum
likelihood of the t truncated to ±0.5 (:func:`fit_tail`; Ion PGM set: ν 3.9, s 0.82). The
calls stay those of the Gaussian (the caller's search weighs flows with it): only the stated
qualities change.

The key-pass filter (:mod:`chiptwin.detection.key_pass`) is applied by the caller of these.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize, nnls
from scipy.special import gammaln, stdtr

from chiptwin.detection.reads import (
    MAX_CALL,
    TAIL_FLOWS,
    FlowNoise,
    Prior,
    Read,
    call_dephased,
    call_rounded,
    phase_model,
    phred,
)

#: The longest homopolymer whose scatter the noise fit uses (bases): longer runs are too few.
FIT_MAX_LENGTH = 5

#: Flows a length needs in the pool to enter the fit.
FIT_MIN_FLOWS = 30

#: Weight of the file's pool in each read's own scatter, in flows (a read's rare long runs lean
#: on the pool, its many 0- and 1-mers on itself).
SHRINK_FLOWS = 20.0

#: Floor of the fitted variance (1-mers²): a flowgram stored in hundredths rounds to ±0.005.
MIN_VARIANCE = 1e-4


def rounded(y: np.ndarray) -> NDArray[np.int64]:
    """Round half up, clipped to 0 … MAX_CALL (the ``round`` caller's calls)."""
    return np.floor(np.clip(y, 0.0, MAX_CALL) + 0.5).astype(np.int64)


def scatter(y: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(sum of (y − h)², flows) per rounded length h = 0 … :data:`FIT_MAX_LENGTH`."""
    h = rounded(y)
    keep = h <= FIT_MAX_LENGTH
    sq = np.bincount(h[keep], weights=(y[keep] - h[keep]) ** 2, minlength=FIT_MAX_LENGTH + 1)
    n = np.bincount(h[keep], minlength=FIT_MAX_LENGTH + 1).astype(np.float64)
    return sq, n


def fit_variance(mean_square: np.ndarray, flows: np.ndarray) -> FlowNoise:
    """``floor + ref·h²`` through the mean squares of lengths 1 … :data:`FIT_MAX_LENGTH`,
    weighted by flows; a 0-mer gets the floor (module docstring)."""
    h = np.arange(mean_square.size, dtype=np.float64)
    ok = (flows > 0) & (h >= 1)
    if not ok.any():
        return FlowNoise(MIN_VARIANCE, 0.0, 0.0)
    w = np.sqrt(flows[ok])
    design = np.stack([np.ones(ok.sum()), h[ok] ** 2], axis=1) * w[:, None]
    coef, _ = nnls(design, mean_square[ok] * w)
    return FlowNoise(max(float(coef[0]), MIN_VARIANCE), 0.0, float(coef[1]))


@dataclass(frozen=True)
class MeasuredNoise(FlowNoise):
    """A measured read's noise: the Gaussian the caller weighs flows with, and the Student-t
    its qualities come from (module docstring): ``dof`` degrees of freedom, scale ``scale``
    times the Gaussian's standard deviation."""

    dof: float = np.inf
    scale: float = 1.0


#: Bounds of the Student-t fit: degrees of freedom and scale relative to the Gaussian's sd.
DOF_RANGE, SCALE_RANGE = (1.0, 200.0), (0.3, 3.0)


#: A read whose own 1-mer variance exceeds this many times the file's median is left out of the
#: tail fit: noise rather than a flowgram (Fasting_Example.sff: 1 % of its reads), whose
#: values would pass for a heavy tail of every read.
JUNK_FACTOR = 4.0


def fit_tail(values: list[np.ndarray], noises: list[FlowNoise]) -> tuple[float, float]:
    """(ν, s) by maximum likelihood over the flows rounded to 1 … :data:`FIT_MAX_LENGTH` of
    the reads that are not noise (:data:`JUNK_FACTOR`): each residual ``r = y − h`` is a
    Student-t draw of ν degrees of freedom and scale ``s·√v`` (``v`` those reads' pooled
    variance of ``h``), truncated to ±0.5 (a value further out is rounded to another length).
    Returns (inf, 1) when too few flows."""
    v1 = np.array([n.var(np.ones(1))[0] for n in noises])
    kept = [y for y, v in zip(values, v1, strict=True) if v <= JUNK_FACTOR * np.median(v1)]
    if not kept:
        return np.inf, 1.0
    pool, _ = _fit_gaussian(kept)
    y = np.concatenate([np.asarray(v, dtype=np.float64) for v in kept])
    h = rounded(y)
    keep = (h >= 1) & (h <= FIT_MAX_LENGTH)
    if keep.sum() < FIT_MIN_FLOWS:
        return np.inf, 1.0
    # stored flowgrams are hundredths: the same (residual, length) pairs recur, counted once
    (r, hh), n = np.unique(np.stack([y[keep] - h[keep], h[keep]]), axis=1, return_counts=True)
    sd = np.sqrt(pool.var(hh))

    def nll(u: np.ndarray) -> float:
        dof, scale = _bounded(u)
        z = scale * sd
        inside = 2.0 * stdtr(dof, 0.5 / z) - 1.0
        return float(-np.dot(n, t_logpdf(r / z, dof) - np.log(z) - np.log(inside)))

    best = minimize(nll, np.zeros(2), method="Nelder-Mead",
                    options={"xatol": 1e-4, "fatol": 1e-3, "maxiter": 400})
    return _bounded(best.x)


def t_logpdf(x: np.ndarray, dof: float) -> np.ndarray:
    """log density of Student's t with ``dof`` degrees of freedom (scipy.stats.t.logpdf's
    formula, without its per-call overhead)."""
    c = gammaln(0.5 * (dof + 1)) - gammaln(0.5 * dof) - 0.5 * np.log(dof * np.pi)
    return c - 0.5 * (dof + 1) * np.log1p(x * x / dof)


def _bounded(u: np.ndarray) -> tuple[float, float]:
    """Unbounded (u0, u1) to (ν, s) inside their ranges (a logistic in log space)."""
    t = 1.0 / (1.0 + np.exp(-np.asarray(u, dtype=np.float64)))
    out = [float(np.exp(np.log(lo) + ti * np.log(hi / lo)))
           for ti, (lo, hi) in zip(t, (DOF_RANGE, SCALE_RANGE), strict=True)]
    return out[0], out[1]


def with_tail(noise: FlowNoise, dof: float, scale: float) -> MeasuredNoise:
    """``noise`` with the t's degrees of freedom and scale."""
    return MeasuredNoise(noise.floor, noise.shot, noise.ref, dof, scale)


def fit_noise(values: list[np.ndarray]) -> tuple[MeasuredNoise, list[MeasuredNoise]]:
    """The file's noise and each read's, with the file's tail (module docstring)."""
    pool, per_read = _fit_gaussian(values)
    dof, scale = fit_tail(values, per_read)
    return with_tail(pool, dof, scale), [with_tail(n, dof, scale) for n in per_read]


def _fit_gaussian(values: list[np.ndarray]) -> tuple[FlowNoise, list[FlowNoise]]:
    """The file's Gaussian noise and each read's (module docstring)."""
    parts = [scatter(np.asarray(y, dtype=np.float64)) for y in values]
    sq = np.sum([p[0] for p in parts], axis=0)
    n = np.sum([p[1] for p in parts], axis=0)
    n_pool = np.where(n >= FIT_MIN_FLOWS, n, 0.0)
    pool = np.where(n_pool > 0, sq / np.maximum(n_pool, 1.0), 0.0)
    used = n_pool > 0
    per_read = []
    for s, k in parts:
        k = np.where(used, k, 0.0)
        ms = np.where(used, (s + SHRINK_FLOWS * pool) / (k + SHRINK_FLOWS), 0.0)
        per_read.append(fit_variance(ms, k + SHRINK_FLOWS * used))
    return fit_variance(pool, n_pool), per_read


#: Flows a read needs rounded to 0 and to 1 for :func:`caller_input` to move its levels.
LEVEL_MIN_FLOWS = 10


def caller_input(y: np.ndarray, caller: str) -> NDArray[np.float64]:
    """The values a caller reads: as stored for ``round``; for ``dephase`` with the read's 0-mer
    and 1-mer levels (the medians of its flows rounded to 0 and to 1) moved to 0 and 1, values
    above the 1-mer level shifted with it. 454 leaves its 0-mers near +0.1 (Balzer et al.,
    Bioinformatics 26:i420, 2010: 0.12), which the phasing model would explain as light leaked
    from strands out of phase, a carry-forward of 0.25 % on every read of Fasting_Example.sff."""
    y = np.asarray(y, dtype=np.float64)
    if caller != "dephase":
        return y
    h = rounded(y)
    if (h == 0).sum() < LEVEL_MIN_FLOWS or (h == 1).sum() < LEVEL_MIN_FLOWS:
        return y
    m0, m1 = float(np.median(y[h == 0])), float(np.median(y[h == 1]))
    if not m1 - m0 > 0.5:
        return y
    return np.where(y < m1, (y - m0) / (m1 - m0), y - (m1 - 1.0))


def call(y: np.ndarray, flows: np.ndarray, noise: FlowNoise, caller: str) -> Read:
    """One read by ``caller`` (``round`` or ``dephase``); with a :class:`MeasuredNoise`, its
    qualities from the posterior with the t likelihood (:func:`tail_posterior`)."""
    y = np.asarray(y, dtype=np.float64)
    # already phase-corrected values: their 0-mer level is the vendor's, which
    # :func:`caller_input` moves to 0 for ``dephase``; the empty-flow light term finds nothing
    # there (Ion PGM set, dephase: 1,177 errors with it and without) and is left out
    call = call_dephased if caller == "dephase" else call_rounded
    read = call(y, flows, noise, empty_light=False)
    if not isinstance(noise, MeasuredNoise) or not np.isfinite(noise.dof):
        return read
    return replace(read, posterior=tail_posterior(read, y, flows, noise))


def tail_posterior(read: Read, y: np.ndarray, flows: np.ndarray, noise: MeasuredNoise
                   ) -> NDArray[np.float64]:
    """P(h | y_k) with the t likelihood, the read's phasing model (its calls, ε, λ, δ,
    empty-flow light and 1-mer level) and its prior; the last
    :data:`~chiptwin.detection.reads.TAIL_FLOWS` flows keep the caller's posterior."""
    core = read.noise if read.noise is not None else noise
    # the last flows keep theirs (uncalled by ``dephase``; doubted by ``round``: TAIL_DOUBT)
    n = read.n_called if read.n_called is not None else max(y.size - TAIL_FLOWS, 0)
    calls = read.calls[:n]
    v = y[:n] / read.gain
    if read.eps or read.lam or read.droop:
        signal, a, _ = phase_model(read.calls, flows, read.eps, read.lam, read.droop)
        a, b = a[:n], (signal - a * read.calls)[:n]
    else:
        a, b = np.ones(n), np.zeros(n)
    prior = Prior.of(calls, flows[:n])
    p_pos = prior.p_pos(calls, flows[:n])
    h = np.arange(MAX_CALL + 1)
    mean = a[:, None] * h + b[:, None] + np.where(h == 0, read.empty_light, 0.0)
    z = noise.scale * np.sqrt(core.var(mean))
    ll = t_logpdf((v[:, None] - mean) / z, noise.dof) - np.log(z)
    ll += np.where(h == 0, np.log1p(-p_pos)[:, None], np.log(p_pos)[:, None] + prior.log_len)
    post = read.posterior.copy()
    post[:n] = np.exp(ll - ll.max(axis=1, keepdims=True))
    post[:n] /= post[:n].sum(axis=1, keepdims=True)
    return post


def after_key(read: Read, flow_order: str, key: str) -> tuple[str, NDArray[np.uint8],
                                                              NDArray[np.float64]]:
    """The read's bases after the key, their phred qualities and error probabilities."""
    bases = read.bases(flow_order)
    p = read.base_error()
    return bases[len(key):], phred(p[len(key):]).astype(np.uint8), p[len(key):]
