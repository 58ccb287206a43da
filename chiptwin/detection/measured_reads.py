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

The key-pass filter (:mod:`chiptwin.detection.key_pass`) is applied by the caller of these.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import nnls

from chiptwin.detection.reads import (
    MAX_CALL,
    FlowNoise,
    Read,
    call_dephased,
    call_rounded,
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


def fit_noise(values: list[np.ndarray]) -> tuple[FlowNoise, list[FlowNoise]]:
    """The file's noise and each read's (module docstring)."""
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
    """One read by ``caller`` (``round`` or ``dephase``)."""
    y = np.asarray(y, dtype=np.float64)
    if caller == "dephase":
        return call_dephased(y, flows, noise)
    return call_rounded(y, flows, noise)


def after_key(read: Read, flow_order: str, key: str) -> tuple[str, NDArray[np.uint8],
                                                              NDArray[np.float64]]:
    """The read's bases after the key, their phred qualities and error probabilities."""
    bases = read.bases(flow_order)
    p = read.base_error()
    return bases[len(key):], phred(p[len(key):]).astype(np.uint8), p[len(key):]
