"""numba kernel behind :func:`chiptwin.kinetics.phasing.phased_signal`.

Arrays and scalars in, arrays out; no validation (the public wrapper checks once). The slow,
obvious reference is :func:`chiptwin.kinetics.phasing.phased_flows` (tests compare the two).

The per-flow functions (:func:`flow_step`, :func:`trim`, :func:`model_restore`,
:func:`model_advance`) allocate nothing and compile without numba's reference counting
(:data:`chiptwin._numba.NJIT_NORC`): the caller's hill climb runs them millions of times a run,
and with it an atomic increment and decrement of the arrays' counts wrapped every call.
"""

from __future__ import annotations

import numpy as np

from chiptwin._numba import NJIT, NJIT_NORC

#: Strand shares below this are dropped from the lagging and leading tails: each flow drops at
#: most a few 1e-9 of the strands, so a flow value moves by < 1e-5 of a base over 1,000 flows,
#: far below any flow's noise (the tails, else, spread over the whole template under λ).
TINY = 1e-9


@NJIT
def run_table(tmpl: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``run[j, b]``: length of the homopolymer of base ``b`` starting at position ``j``."""
    return run_table_into(tmpl, tmpl.size, np.empty((tmpl.size + 1, 4), dtype=np.int64))


@NJIT
def run_table_into(tmpl: np.ndarray, n_pos: int, run: np.ndarray) -> np.ndarray:  # pragma: no cover
    """:func:`run_table` of ``tmpl[:n_pos]`` written into the first ``n_pos + 1`` rows of
    ``run`` (the rows after them are not part of it)."""
    run[n_pos, :] = 0
    for j in range(n_pos - 1, -1, -1):
        run[j, :] = 0
        run[j, tmpl[j]] = run[j + 1, tmpl[j]] + 1
    return run


@NJIT
def run_rows_from(tmpl: np.ndarray, n_pos: int, run: np.ndarray,
                  lo: int) -> int:  # pragma: no cover - compiled
    """Rows ``lo … n_pos`` of :func:`run_table_into` written again, and the rows below ``lo``
    of the homopolymer ``tmpl[lo − 1]`` continues into (a row reads the one above it only
    within a run): when only ``tmpl[lo:n_pos]`` changed, ``run`` is then the new template's
    table, the rows below untouched (a template that now ends at ``lo`` has its last run's rows
    written again: they counted the bases that followed). Returns the lowest row written."""
    run[n_pos, :] = 0
    lo = min(lo, n_pos - 1)
    j = n_pos - 1
    while j >= 0 and (j >= lo or tmpl[j] == tmpl[j + 1]):
        run[j, :] = 0
        run[j, tmpl[j]] = run[j + 1, tmpl[j]] + 1
        j -= 1
    return j + 1


@NJIT_NORC
def flow_step(run: np.ndarray, x: int, prev: int, eps: float, lam: float, dist: np.ndarray,
              new: np.ndarray, lo: int, hi: int) -> tuple:  # pragma: no cover - compiled
    """One flow of :func:`phase_flows`: the strands of ``dist[lo..hi]`` held, extended or
    carried forward into ``new`` (zero on entry). Returns (bases added, highest position
    written); every template position the flow reads lies at or below that position.

    The shares that stay at ``j`` (held, waiting, carried nowhere) are summed into ``new[j]``
    in a register, in the order three additions to memory would make them: the same bits,
    without a store and reload between them (16 % of a flow's cost on 400-flow reads)."""
    bases = 0.0
    new_hi = hi
    for j in range(lo, hi + 1):
        d = dist[j]
        if d == 0.0:
            continue
        held = eps * d
        active = d - held
        carry = lam * active if prev >= 0 else 0.0
        normal = active - carry
        r = run[j, x]
        t = new[j] + held
        if r == 0:
            t += normal
        else:
            new[j + r] += normal
            bases += normal * r
        if carry > 0.0:
            r2 = run[j + r, prev]
            if r + r2 == 0:
                t += carry
            else:
                new[j + r + r2] += carry
                bases += carry * (r + r2)
                new_hi = max(new_hi, j + r + r2)
        new[j] = t
        new_hi = max(new_hi, j + r)
    return bases, new_hi


@NJIT_NORC
def trim(dist: np.ndarray, old: np.ndarray, lo: int, hi: int,
         new_hi: int) -> tuple:  # pragma: no cover - compiled
    """After a flow (``dist`` the new distribution, ``old`` the one it came from): clear
    ``old`` for the next flow and drop the tails' shares below :data:`TINY`. Returns (lo, hi)."""
    for p in range(lo, hi + 1):
        old[p] = 0.0
    hi = new_hi
    while lo < hi and dist[lo] < TINY:
        dist[lo] = 0.0  # a share below TINY of the strands: dropped, not carried
        lo += 1
    while hi > lo and dist[hi] < TINY:
        dist[hi] = 0.0
        hi -= 1
    return lo, hi


@NJIT
def phase_flows(tmpl: np.ndarray, flows: np.ndarray, eps: float, lam: float,
                droop: float) -> tuple:  # pragma: no cover - compiled
    """The phased, drooping flowgram of one strand population starting at position 0.

    Parameters
    ----------
    tmpl : int64 (L,)
        Template bases as indices into ``ACGT``.
    flows : int64 (n,)
        Base index dispensed in each flow.
    eps, lam : float
        Incomplete extension and carry-forward per flow (Eltoukhy & El Gamal, ICASSP 2006).
    droop : float
        Share of the active template lost in each flow.

    Returns
    -------
    signal : float64 (n,)
        Bases added per starting strand in each flow, times ``(1 - droop)**k``.
    in_phase : float64 (n,)
        The weight of the in-phase homopolymer in ``signal``: ``(1 - eps)`` times the share of
        strands at the ideal position before flow ``k``, times ``(1 - droop)**k``; so
        ``signal - in_phase * ideal`` is the out-of-phase leak.
    ideal : int64 (n,)
        Bases the ideal (unphased) program adds in each flow.
    """
    bases, in_phase, ideal = phase_bases(tmpl, flows, eps, lam)
    scale = droop_scale(flows.size, droop)
    return bases * scale, in_phase * scale, ideal


@NJIT
def droop_scale(n: int, droop: float) -> np.ndarray:  # pragma: no cover - compiled
    """``(1 − droop)**k`` for flows ``k = 0 … n − 1``, as a running product."""
    scale = np.empty(n)
    sc = 1.0
    for k in range(n):
        scale[k] = sc
        sc *= 1.0 - droop
    return scale


@NJIT
def phase_bases(tmpl: np.ndarray, flows: np.ndarray, eps: float,
                lam: float) -> tuple:  # pragma: no cover - compiled
    """:func:`phase_flows` without droop, which only scales each flow's light: (bases added per
    starting strand, in-phase weight, ideal counts) per flow. Several droop values share it."""
    n_pos = tmpl.size
    run = run_table(tmpl)
    dist = np.zeros(n_pos + 1)
    new = np.zeros(n_pos + 1)
    dist[0] = 1.0
    n = flows.size
    bases = np.zeros(n)
    in_phase = np.zeros(n)
    ideal = np.zeros(n, dtype=np.int64)
    lo, hi, pos, prev = 0, 0, 0, -1
    for k in range(n):
        x = flows[k]
        ideal[k] = run[pos, x]
        in_phase[k] = (1.0 - eps) * dist[pos]
        bases[k], new_hi = flow_step(run, x, prev, eps, lam, dist, new, lo, hi)
        dist, new = new, dist
        lo, hi = trim(dist, new, lo, hi, new_hi)
        pos += ideal[k]
        prev = x
    return bases, in_phase, ideal


# -- the same model from a checkpoint: a change of the template at position D leaves every flow
#    that reads only positions below D as it was (the polish and the sweep re-run the rest) --

#: The model's state is saved before every ``CHECK_EVERY``-th flow.
CHECK_EVERY = 8


@NJIT
def model_buffers(n_flows: int, width: int) -> tuple:  # pragma: no cover - compiled
    """Arrays of a checkpointed model of ``n_flows`` flows over templates of up to
    ``width − 1`` bases: (state, scale, buf, ck_dist, ck_int, ck_scale, signal, in_phase,
    ideal, reach). ``state`` is (lo, hi, pos, prev, row of ``buf`` holding the distribution)."""
    n_ck = n_flows // CHECK_EVERY + 1
    return (np.zeros(5, dtype=np.int64), np.ones(1), np.zeros((2, width)),
            np.zeros((n_ck, width)), np.zeros((n_ck, 4), dtype=np.int64), np.ones(n_ck),
            np.zeros(n_flows), np.zeros(n_flows), np.zeros(n_flows, dtype=np.int64),
            np.zeros(n_flows, dtype=np.int64))


@NJIT_NORC
def model_restore(k0: int, state: np.ndarray, scale: np.ndarray, buf: np.ndarray,
                  ck_dist: np.ndarray, ck_int: np.ndarray,
                  ck_scale: np.ndarray) -> int:  # pragma: no cover - compiled
    """The state before the last checkpointed flow at or before ``k0`` (before flow 0: every
    strand at position 0); returns that flow."""
    c = k0 // CHECK_EVERY
    # the buffers hold the last distribution in row state[4], positions state[0] … state[1],
    # and zeros elsewhere (each flow clears the row it came from)
    for p in range(state[0], state[1] + 1):
        buf[state[4], p] = 0.0
    if c == 0:
        state[0], state[1], state[2], state[3], state[4] = 0, 0, 0, -1, 0
        scale[0] = 1.0
        buf[0, 0] = 1.0
        return 0
    lo, hi = ck_int[c, 0], ck_int[c, 1]
    for i in range(4):
        state[i] = ck_int[c, i]
    state[4] = 0
    scale[0] = ck_scale[c]
    for p in range(lo, hi + 1):
        buf[0, p] = ck_dist[c, p]
    return c * CHECK_EVERY


@NJIT_NORC
def model_advance(run: np.ndarray, flows: np.ndarray, eps: float, lam: float, droop: float,
                  k_start: int, k_end: int, state: np.ndarray, scale: np.ndarray,
                  buf: np.ndarray, ck_dist: np.ndarray, ck_int: np.ndarray,
                  ck_scale: np.ndarray, signal: np.ndarray, in_phase: np.ndarray,
                  ideal: np.ndarray, reach: np.ndarray) -> None:  # pragma: no cover
    """Flows ``k_start … k_end − 1`` of :func:`phase_flows` from ``state`` (the same arithmetic,
    so the same bits), saving the checkpoints on the way; ``reach[k]`` is the highest template
    position flows 0 … k read."""
    lo, hi, pos, prev, cur = state[0], state[1], state[2], state[3], state[4]
    sc = scale[0]
    r = reach[k_start - 1] if k_start > 0 else 0
    for k in range(k_start, k_end):
        dist, new = buf[cur], buf[1 - cur]
        if k % CHECK_EVERY == 0:
            c = k // CHECK_EVERY
            ck_int[c, 0], ck_int[c, 1], ck_int[c, 2], ck_int[c, 3] = lo, hi, pos, prev
            ck_scale[c] = sc
            for p in range(lo, hi + 1):
                ck_dist[c, p] = dist[p]
        x = flows[k]
        ideal[k] = run[pos, x]
        in_phase[k] = (1.0 - eps) * dist[pos] * sc
        bases, new_hi = flow_step(run, x, prev, eps, lam, dist, new, lo, hi)
        signal[k] = bases * sc
        r = max(r, new_hi, pos + ideal[k])
        reach[k] = r
        lo, hi = trim(new, dist, lo, hi, new_hi)
        cur = 1 - cur
        pos += ideal[k]
        prev = x
        sc *= 1.0 - droop
    state[0], state[1], state[2], state[3], state[4] = lo, hi, pos, prev, cur
    scale[0] = sc


@NJIT
def first_reaching(reach: np.ndarray, position: int) -> int:  # pragma: no cover - compiled
    """The first flow that reads template position ``position`` or beyond (``reach`` is
    non-decreasing); ``len(reach)`` when none does."""
    return np.searchsorted(reach, position, side="left")
