"""Pyrosequencing as a dispensation program: flows, incorporations, key normalisation, base calls.

One *flow* dispenses one nucleotide; the polymerase extends every primed strand across the whole
homopolymer of that base at the current position (``AAA`` gives 3 incorporations in one flow), or
not at all. The flow order repeats cyclically. :func:`flow_incorporations` runs that program on a
template; :func:`chiptwin.kinetics.sources.pyrosequencing` turns the counts into light, one
exponential pulse per flow (paper eq. 19, scaled by the homopolymer length).

Reading the light back:

1. :func:`key_flow_counts` gives the expected counts of the flows that read a known *key* (454 uses
   ``TCAG`` at the start of every read) — the last key flow is left out because it can merge with
   the first homopolymer of the unknown insert (``…G`` + ``GG…`` reads as one 3-mer).
2. :func:`normalise_flows` divides the flow signals by the mean signal of the key's 1-mer flows, so
   a 1-mer reads ≈ 1.0, a 2-mer ≈ 2.0 and an empty flow ≈ 0 (Margulies et al., Nature 437, 2005;
   the 454 flowgram convention whose peak spread Balzer et al., Bioinformatics 26, 2010 measured).
3. :func:`call_sequence` rounds the normalised values to homopolymer lengths and spells the read.

Use a template that starts with the key (``template = key + insert``); the called read then starts
with the key too.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks

NUCLEOTIDES: str = "ACGT"
"""The letters a template or a flow order may contain (case-insensitive)."""

KEY_454: str = "TCAG"
"""The 454 library key, read first on every bead (Margulies et al. 2005)."""

FLOW_ORDER_454: str = "TACG"
"""The 454 GS FLX dispensation order."""


def _bases(name: str, seq: str, *, allow_empty: bool) -> str:
    """Upper-case ``seq`` and check that it holds only A, C, G, T."""
    if not isinstance(seq, str):
        raise ValueError(f"{name} = {seq!r} must be a string of the letters A, C, G, T")
    up = seq.upper()
    if not up and not allow_empty:
        raise ValueError(f"{name} = {seq!r} is empty: must hold at least one of A, C, G, T")
    for i, letter in enumerate(up):
        if letter not in NUCLEOTIDES:
            raise ValueError(f"{name} has {seq[i]!r} at position {i}: only A, C, G, T are allowed")
    return up


def flow_incorporations(
    template: str, flow_order: str, n_flows: int
) -> tuple[list[str], NDArray[np.int64]]:
    """Run a dispensation program on a template: bases incorporated per flow.

    Parameters
    ----------
    template : str
        The bases to be synthesised, in synthesis order (A, C, G, T; case-insensitive; may be
        empty).
    flow_order : str
        The dispensation cycle, repeated (e.g. ``"TACG"``), at least one base.
    n_flows : int
        Number of flows, >= 0.

    Returns
    -------
    flow_nucleotides : list of str, length n_flows
        The nucleotide dispensed in each flow.
    n_incorporated : ndarray of int64, shape (n_flows,)
        Bases added per strand in each flow: the full homopolymer length when the flow matches
        the next template base, else 0. ``n_incorporated.sum()`` is how much of the template the
        flows cover (all of it when enough flows are given).
    """
    seq = _bases("template", template, allow_empty=True)
    order = _bases("flow_order", flow_order, allow_empty=False)
    if isinstance(n_flows, bool) or not isinstance(n_flows, int | np.integer) or n_flows < 0:
        raise ValueError(f"n_flows = {n_flows!r} is out of range: must be an int >= 0")
    nucleotides = [order[k % len(order)] for k in range(n_flows)]
    counts = np.zeros(n_flows, dtype=np.int64)
    pos = 0
    for k, base in enumerate(nucleotides):
        run = pos
        while run < len(seq) and seq[run] == base:
            run += 1
        counts[k] = run - pos
        pos = run
    return nucleotides, counts


def flows_to_sequence(template: str, flow_order: str) -> int:
    """Number of flows needed to synthesise the whole template with this flow order.

    Parameters
    ----------
    template : str
        Bases A, C, G, T.
    flow_order : str
        Dispensation cycle; must contain every base the template uses.

    Returns
    -------
    int
        The index of the flow that adds the last base, plus one (0 for an empty template).
    """
    seq = _bases("template", template, allow_empty=True)
    order = _bases("flow_order", flow_order, allow_empty=False)
    missing = sorted(set(seq) - set(order))
    if missing:
        raise ValueError(f"flow_order = {flow_order!r} never dispenses {''.join(missing)}, "
                         "which the template needs")
    flows, pos = 0, 0
    while pos < len(seq):
        base = order[flows % len(order)]
        while pos < len(seq) and seq[pos] == base:
            pos += 1
        flows += 1
    return flows


def key_flow_counts(key: str, flow_order: str) -> NDArray[np.int64]:
    """Expected incorporations of the flows that read a known key, for :func:`normalise_flows`.

    Parameters
    ----------
    key : str
        The known prefix of every template (e.g. :data:`KEY_454`, ``"TCAG"``).
    flow_order : str
        The dispensation cycle.

    Returns
    -------
    ndarray of int64, shape (n_key_flows,)
        Counts of the first ``flows_to_sequence(key, flow_order) - 1`` flows. The flow that adds
        the key's last base is left out: it also adds the insert's first bases when they repeat
        that base, so its count is not known in advance. With ``TCAG`` and ``TACG``:
        ``[1, 0, 1, 0, 0, 1, 0]`` (three 1-mer references, four empty flows).
    """
    n = flows_to_sequence(key, flow_order) - 1
    counts = flow_incorporations(key, flow_order, n)[1]
    if not (counts == 1).any():
        raise ValueError(f"key = {key!r} with flow_order = {flow_order!r} has no 1-mer flow "
                         "before its last flow: it cannot give a 1-mer reference")
    return counts


def normalise_flows(
    flow_values: ArrayLike,
    key_n_expected: ArrayLike,
    *,
    subtract_zero_mer: bool = False,
) -> NDArray[np.float64]:
    """Scale flow signals so that a 1-mer reads 1, using the key flows at the start of the read.

    Parameters
    ----------
    flow_values : array_like, shape (n_flows,) or (n_sites, n_flows)
        Signal per flow in any linear unit (photons, e⁻, codes), background already removed;
        the first ``len(key_n_expected)`` flows read the key.
    key_n_expected : array_like of int, shape (n_key_flows,)
        Expected counts of the key flows (from :func:`key_flow_counts`); at least one must be 1.
    subtract_zero_mer : bool
        If True, first subtract the mean of the key's empty (count 0) flows, a per-site baseline
        (needs at least one); the 1-mer reference is then ``mean(1-mers) − mean(0-mers)``.

    Returns
    -------
    ndarray, same shape as ``flow_values``
        Normalised flow values (1-mer ≈ 1). Unit: incorporations.

    Notes
    -----
    The 454 flowgram normalisation (Margulies et al. 2005): the key's single-base flows give each
    site's 1-mer signal. A site whose 1-mer reference is not positive cannot be normalised and
    is an error, not a silent NaN.
    """
    values = _checks.as_float_array("flow_values", flow_values)
    key = np.asarray(key_n_expected)
    if values.ndim not in (1, 2):
        raise ValueError(f"flow_values has shape {values.shape}: must be (n_flows,) or "
                         "(n_sites, n_flows)")
    if key.ndim != 1 or key.size > values.shape[-1] or not (key == 1).any():
        raise ValueError(f"key_n_expected = {key.tolist()!r} must be 1-D, no longer than the "
                         f"{values.shape[-1]} flows, and contain at least one 1")
    key_values = values[..., : key.size]
    baseline = np.zeros(values.shape[:-1])
    if subtract_zero_mer:
        if not (key == 0).any():
            raise ValueError("subtract_zero_mer needs a key flow with expected count 0; "
                             f"key_n_expected = {key.tolist()!r} has none")
        baseline = key_values[..., key == 0].mean(axis=-1)
    reference = key_values[..., key == 1].mean(axis=-1) - baseline
    if (reference <= 0).any():
        site = int(np.argmax(np.atleast_1d(reference <= 0)))
        raise ValueError(f"flow_values: the key's 1-mer reference is "
                         f"{float(np.atleast_1d(reference)[site])!r} at site {site}: must be > 0")
    return (values - baseline[..., None]) / reference[..., None]


CALL_MAX_N = 655
"""The longest homopolymer one flow calls: the SFF flowgram's largest value (flow signals kept as
uint16 hundredths of a 1-mer, 655.35; 454 Life Sciences' Standard Flowgram Format). A site whose
1-mer reference is barely above zero divides its flows into values of 10¹⁶ and more, which would
otherwise spell a read of that many bases (a MemoryError, not a wrong call)."""


def call_sequence(
    flow_nucleotides: Sequence[str], flow_values: ArrayLike
) -> tuple[str, NDArray[np.int64]]:
    """Call bases from normalised flow values by rounding to homopolymer lengths.

    Parameters
    ----------
    flow_nucleotides : sequence of str, length n_flows
        Nucleotide of each flow (A, C, G, T).
    flow_values : array_like, shape (n_flows,)
        Normalised flow values (1-mer ≈ 1), finite.

    Returns
    -------
    called : str
        The read: each flow's nucleotide repeated ``called_n`` times, in flow order.
    called_n : ndarray of int64, shape (n_flows,)
        ``floor(max(v, 0) + 0.5)``: round half up, negative values call 0, values above
        :data:`CALL_MAX_N` call that many.
    """
    values = _checks.as_float_array("flow_values", flow_values)
    if values.ndim != 1 or values.size != len(flow_nucleotides):
        raise ValueError(f"flow_values has shape {values.shape}: must be "
                         f"({len(flow_nucleotides)},), one value per flow nucleotide")
    letters = [_bases(f"flow_nucleotides[{i}]", b, allow_empty=False)
               for i, b in enumerate(flow_nucleotides)]
    bad = [i for i, b in enumerate(letters) if len(b) != 1]
    if bad:
        raise ValueError(f"flow_nucleotides[{bad[0]}] = {flow_nucleotides[bad[0]]!r}: each "
                         "flow dispenses exactly one base")
    called_n = np.floor(np.clip(values, 0.0, CALL_MAX_N) + 0.5).astype(np.int64)
    return "".join(b * int(n) for b, n in zip(letters, called_n, strict=True)), called_n
