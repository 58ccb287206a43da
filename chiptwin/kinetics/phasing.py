"""Phasing: incomplete extension and carry-forward in a pyrosequencing flow program.

A population of strands is tracked as a distribution over template positions: ``dist[j]`` is the
amount (any unit: mol, M, or a fraction) of strands extended by ``j`` bases, ``j = 0 … L``. In
each flow, with dispensed nucleotide X and previous flow's nucleotide Y (none in flow 0):

* a share ε (``incomplete_extension``) of the strands does not extend at all;
* of the others, a share λ (``carry_forward``) extends through the X homopolymer at its
  position and then through the Y homopolymer after it (the previous nucleotide not yet removed);
* the rest extends through the X homopolymer only.

This is the per-flow phasing model of Eltoukhy & El Gamal ("Modeling and base-calling for DNA
sequencing-by-synthesis", ICASSP 2006), with the sequential X-then-Y carry-forward step; the 454
values are ε ≈ 0.1–0.3 %, λ ≈ 1–2 % (Margulies et al., Nature 437, 2005). With ε = λ = 0 it is
:func:`chiptwin.kinetics.pyro.flow_incorporations`.

The cascade (:mod:`chiptwin.kinetics.cascade`) applies the ε and λ steps at each dispensation with
:func:`split_held` and :func:`carry_jump` and lets the polymerase kinetics do the X extension, so
in the limit of fast, complete extension its incorporations per flow equal :func:`phased_flows`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.kinetics.pyro import NUCLEOTIDES, _bases, flow_incorporations


def template_indices(template: str) -> NDArray[np.int64]:
    """Template bases as indices into ``"ACGT"``: shape (L,), int64."""
    seq = _bases("template", template, allow_empty=True)
    return np.array([NUCLEOTIDES.index(b) for b in seq], dtype=np.int64)


def run_lengths(tmpl: NDArray[np.int64]) -> NDArray[np.int64]:
    """``run[j, n]``: length of the homopolymer of base n starting at position j (0 if none).

    Shape (L + 1, 4); row L (the fully extended strand) is all zeros.
    """
    n_pos = tmpl.size
    run = np.zeros((n_pos + 1, 4), dtype=np.int64)
    for j in range(n_pos - 1, -1, -1):
        run[j, tmpl[j]] = run[j + 1, tmpl[j]] + 1
    return run


def _fraction(name: str, value: float) -> float:
    x = _checks.scalar(name, value, minimum=0.0, strict=False)
    if x > 1.0:
        raise ValueError(f"{name} = {x!r} is out of range: must be in [0, 1]")
    return x


def extend_through(dist: NDArray[np.float64], run: NDArray[np.int64],
                   base: int) -> tuple[NDArray[np.float64], float]:
    """Extend every strand through the homopolymer of ``base`` at its position.

    Returns
    -------
    new_dist : ndarray, shape (L + 1,)
    bases : float
        Bases added, summed over the strands (unit of ``dist`` × bases).
    """
    if base < 0:
        return dist.copy(), 0.0
    steps = run[:, base]
    out = np.zeros_like(dist)
    np.add.at(out, np.arange(dist.size) + steps, dist)
    return out, float(np.dot(dist, steps))


def split_held(dist: NDArray[np.float64], incomplete_extension: float
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Split strands into (extending, held back this flow): shares 1 − ε and ε."""
    held = incomplete_extension * dist
    return dist - held, held


def carry_jump(dist: NDArray[np.float64], run: NDArray[np.int64], base: int, previous: int
               ) -> tuple[NDArray[np.float64], float, float]:
    """Extend strands through the X (``base``) run, then the Y (``previous``) run after it.

    Returns
    -------
    new_dist : ndarray
    bases_x, bases_y : float
        Bases of X and of Y added (unit of ``dist`` × bases).
    """
    after_x, bases_x = extend_through(dist, run, base)
    after_y, bases_y = extend_through(after_x, run, previous)
    return after_y, bases_x, bases_y


def phased_flows(
    template: str,
    flow_order: str,
    n_flows: int,
    incomplete_extension: float = 0.0,
    carry_forward: float = 0.0,
    initial: ArrayLike | None = None,
) -> tuple[list[str], NDArray[np.float64], NDArray[np.float64]]:
    """Run the phased dispensation program on one strand population.

    Parameters
    ----------
    template, flow_order, n_flows
        As :func:`chiptwin.kinetics.pyro.flow_incorporations`.
    incomplete_extension, carry_forward : float
        ε and λ, in [0, 1].
    initial : array_like, shape (L + 1,), optional
        Starting distribution; default: all strands at position 0 (amount 1).

    Returns
    -------
    flow_nucleotides : list of str
    incorporations : ndarray, shape (n_flows,)
        Mean bases added per strand in each flow (the ideal flowgram with phasing).
    dist : ndarray, shape (n_flows + 1, L + 1)
        Strand distribution before flow 0 and after every flow.
    """
    nucleotides, _ = flow_incorporations(template, flow_order, n_flows)
    eps = _fraction("incomplete_extension", incomplete_extension)
    lam = _fraction("carry_forward", carry_forward)
    tmpl = template_indices(template)
    run = run_lengths(tmpl)
    d = np.zeros(tmpl.size + 1)
    d[0] = 1.0
    if initial is not None:
        d = _checks.nonnegative("initial", initial).astype(np.float64)
        if d.shape != (tmpl.size + 1,):
            raise ValueError(f"initial has shape {d.shape}: must be ({tmpl.size + 1},)")
    total = d.sum()
    hist = [d]
    inc = np.zeros(n_flows)
    prev = -1
    for k, letter in enumerate(nucleotides):
        x = NUCLEOTIDES.index(letter)
        d, bases = phase_step(d, run, x, prev, eps, lam)
        inc[k] = bases / total if total > 0 else 0.0
        hist.append(d)
        prev = x
    return nucleotides, inc, np.array(hist)


def phase_step(dist: NDArray[np.float64], run: NDArray[np.int64], base: int, previous: int,
               incomplete_extension: float, carry_forward: float
               ) -> tuple[NDArray[np.float64], float]:
    """One flow of the phasing model: returns the new distribution and the bases added."""
    active, held = split_held(dist, incomplete_extension)
    carry = carry_forward * active if previous >= 0 else np.zeros_like(active)
    normal, b_normal = extend_through(active - carry, run, base)
    jumped, b_x, b_y = carry_jump(carry, run, base, previous)
    return held + normal + jumped, b_normal + b_x + b_y


def flow_indices(flow_order: str, n_flows: int) -> NDArray[np.int64]:
    """Base index (into ``"ACGT"``) dispensed in each of ``n_flows`` flows of the cycle."""
    order = _bases("flow_order", flow_order, allow_empty=False)
    cycle = np.array([NUCLEOTIDES.index(b) for b in order], dtype=np.int64)
    return cycle[np.arange(n_flows) % cycle.size]


def phased_signal(
    template: str,
    flow_order: str,
    n_flows: int,
    incomplete_extension: float = 0.0,
    carry_forward: float = 0.0,
    droop: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The phased flowgram with signal droop, in O(L) per flow (compiled).

    Parameters
    ----------
    template, flow_order, n_flows
        As :func:`chiptwin.kinetics.pyro.flow_incorporations`.
    incomplete_extension, carry_forward : float
        ε and λ in [0, 1], as :func:`phased_flows` (Eltoukhy & El Gamal, ICASSP 2006).
    droop : float
        Share of the active template (or polymerase) lost per flow, in [0, 1): flow ``k``'s
        light is scaled by ``(1 − droop)**k`` (the signal decay that, with phasing, ends a
        pyrosequencing read; Margulies et al., Nature 437:376, 2005).

    Returns
    -------
    signal : ndarray (n_flows,)
        Mean bases added per starting strand in each flow, drooped. Unit: incorporations.
    in_phase : ndarray (n_flows,)
        The weight of the in-phase homopolymer in ``signal`` (see
        :func:`chiptwin.kinetics._phasing_kernels.phase_flows`).
    ideal : ndarray of int64 (n_flows,)
        :func:`chiptwin.kinetics.pyro.flow_incorporations`' counts.
    """
    from chiptwin.kinetics._phasing_kernels import phase_flows

    eps = _fraction("incomplete_extension", incomplete_extension)
    lam = _fraction("carry_forward", carry_forward)
    d = _fraction("droop", droop)
    if d >= 1.0:
        raise ValueError(f"droop = {d!r} is out of range: must be in [0, 1)")
    if isinstance(n_flows, bool) or not isinstance(n_flows, int | np.integer) or n_flows < 0:
        raise ValueError(f"n_flows = {n_flows!r} is out of range: must be an int >= 0")
    return phase_flows(template_indices(template), flow_indices(flow_order, int(n_flows)),
                       eps, lam, d)
