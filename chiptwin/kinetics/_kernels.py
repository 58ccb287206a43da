"""numba kernels behind :class:`chiptwin.kinetics.PulseTrain`.

Arrays and scalars in, arrays out; no validation here (the public wrappers in
:mod:`chiptwin.kinetics.pulse_train` check dtype, shape and range once). A slow, obvious numpy
reference of each kernel lives in ``tests/kinetics/test_pulse_train.py``.
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT

#: Below this ``k w``, ``(1 - exp(-k w)) / k`` is evaluated by its series ``w (1 - k w / 2)``; the
#: truncation error ``w (k w)**2 / 6`` is then below 2e-17 w, under one ulp of the result.
_SERIES_BELOW = 1e-8


@NJIT
def decay_integral(k: float, width: float) -> float:  # pragma: no cover - compiled
    """``∫_0^w e^{-k t} dt = (1 - exp(-k w)) / k`` for ``k, w >= 0`` (``w`` at ``k = 0``).

    No cancellation (``expm1``), no 0/0, and ``1/k`` when ``k w`` overflows.
    """
    x = k * width
    if x < _SERIES_BELOW:
        return width * (1.0 - 0.5 * x)
    return -math.expm1(-x) / k


@NJIT
def pulse_rate(site, onset_s, amplitude_per_s, decay_per_s, t_s, n_sites):  # pragma: no cover
    """Sum of ``A exp(-k (t - t0))`` for ``t >= t0`` (0 before) per site: ``(n_sites, n_t)``."""
    out = np.zeros((n_sites, t_s.size))
    for p in range(site.size):
        amp = amplitude_per_s[p]
        if amp == 0.0:
            continue
        s = site[p]
        for j in range(t_s.size):
            dt = t_s[j] - onset_s[p]
            if dt >= 0.0:
                out[s, j] += amp * math.exp(-decay_per_s[p] * dt)
    return out


@NJIT
def _activate(state, t_ref, k, onset, amplitude):  # pragma: no cover - compiled
    """Add a pulse to a group state ``B`` at ``t_ref`` (rate ``B e^{-k (t - t_ref)}``)."""
    if state == 0.0:
        return amplitude, onset
    return state * math.exp(-k * (onset - t_ref)) + amplitude, onset


@NJIT
def _group_photons(onset_s, amplitude_per_s, k, t_edges_s, out_row):  # pragma: no cover
    """Integrate one group (same site, same decay ``k``; onsets sorted) over every window.

    The group's rate after its latest started pulse ``t_ref`` is ``B e^{-k (t - t_ref)}`` with
    ``B = Σ A_p e^{-k (t_ref - t0_p)}``, so a window piece ``[a, b]`` after ``t_ref`` holds exactly
    ``B e^{-k (a - t_ref)} (1 - e^{-k (b - a)}) / k``; windows are split at the onsets inside them.
    One exp and one expm1 per window and group, whatever the number of pulses; each term is
    evaluated directly (no running product over windows), so the relative error does not grow
    with the number of windows. When the state underflows to exactly 0 the loop jumps to the
    window of the next onset (or stops).
    """
    n_w = t_edges_s.size - 1
    m = onset_s.size
    j = 0
    state, t_ref = 0.0, 0.0
    i = max(np.searchsorted(t_edges_s, onset_s[0], side="right") - 1, 0)
    while i < n_w:
        a, hi = t_edges_s[i], t_edges_s[i + 1]
        while j < m and onset_s[j] <= a:
            state, t_ref = _activate(state, t_ref, k, onset_s[j], amplitude_per_s[j])
            j += 1
        acc = 0.0
        while j < m and onset_s[j] < hi:
            if state > 0.0:
                acc += state * math.exp(-k * (a - t_ref)) * decay_integral(k, onset_s[j] - a)
            a = onset_s[j]
            state, t_ref = _activate(state, t_ref, k, onset_s[j], amplitude_per_s[j])
            j += 1
        if state > 0.0:
            acc += state * math.exp(-k * (a - t_ref)) * decay_integral(k, hi - a)
        out_row[i] += acc
        if state * math.exp(-k * (hi - t_ref)) == 0.0:
            if j >= m:
                break
            state = 0.0
            i = max(i + 1, np.searchsorted(t_edges_s, onset_s[j], side="right") - 1)
        else:
            i += 1


@NJIT
def pulse_photons(
    group_start, site, onset_s, amplitude_per_s, decay_per_s, t_edges_s, n_sites
):  # pragma: no cover - compiled
    """Exact integral of the pulses over each window ``[t_i, t_{i+1}]``, summed per site.

    Pulses come sorted by (site, decay, onset); ``group_start`` holds the first index of every run
    of equal (site, decay) plus the total count. ``t_edges_s`` must be non-decreasing. Cost:
    O(n_pulses + n_groups × n_windows), where the light of a group has not underflowed.
    """
    out = np.zeros((n_sites, t_edges_s.size - 1))
    for g in range(group_start.size - 1):
        lo, hi = group_start[g], group_start[g + 1]
        _group_photons(onset_s[lo:hi], amplitude_per_s[lo:hi], decay_per_s[lo],
                       t_edges_s, out[site[lo]])
    return out
