"""Templates drawn for sequencing scenes: length, base composition, homopolymer lengths, seed.

A drawn template is a chain of homopolymers. Each run's base differs from the previous run's
and is drawn so that the bases have the composition asked (G+C share ``gc``, split evenly between
G and C, A and T sharing the rest; :func:`run_base_probs`); its length is geometric,
``P(n) ∝ p^(n−1)`` for ``n = 1 … max_run``. With ``p = 0.25`` and ``gc = 0.5`` the runs are
those of a uniformly random sequence (a base repeats with probability 1/4); a larger ``p`` gives
the homopolymer-rich templates that end pyrosequencing reads.
"""

from __future__ import annotations

import zlib

import numpy as np

from chiptwin.kinetics.pyro import NUCLEOTIDES, _bases

#: Longest homopolymer a drawn template may hold; the phase-correcting caller resolves up to
#: :data:`chiptwin.detection.reads.MAX_CALL` (bases).
MAX_DRAWN_RUN = 12


def composition(gc: float) -> np.ndarray:
    """Probabilities of A, C, G, T for a G+C share ``gc`` in [0, 1]."""
    if not 0.0 <= gc <= 1.0:
        raise ValueError(f"gc = {gc!r} is out of range: must be in [0, 1]")
    return np.array([(1 - gc) / 2, gc / 2, gc / 2, (1 - gc) / 2])


def run_base_probs(gc: float) -> np.ndarray:
    """Probabilities ``c`` of A, C, G, T for a run's base, before the previous run's base is
    excluded, that give the bases the composition of :func:`composition`: a run's base follows
    the previous one with ``P(j | i) = c_j / (1 − c_i)``, whose stationary law is
    ``π_i ∝ c_i (1 − c_i)`` (runs of every base have one length law, so π is the composition).
    Solved for ``c_i (1 − c_i) = κ g_i`` with ``Σ c_i = 1`` by bisection on κ."""
    g = composition(gc)
    lo, hi = 0.0, 0.25 / g.max()

    def c_of(kappa: float) -> np.ndarray:
        return 0.5 * (1.0 - np.sqrt(np.maximum(1.0 - 4.0 * kappa * g, 0.0)))

    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if c_of(mid).sum() < 1.0 else (lo, mid)
    c = c_of(0.5 * (lo + hi))
    return c / c.sum()


def draw_template(length: int, gc: float, homopolymer_p: float, max_run: int,
                  rng: np.random.Generator) -> str:
    """Draw a template of ``length`` bases (see the module docstring).

    Parameters
    ----------
    length : int
        Bases, >= 1.
    gc : float
        G+C share in [0, 1] (0 or 1 alternate two bases only).
    homopolymer_p : float
        Geometric continuation probability of a run, in [0, 1).
    max_run : int
        Longest run, 1 … :data:`MAX_DRAWN_RUN`.
    rng : np.random.Generator

    Returns
    -------
    str of A, C, G, T
    """
    if length < 1:
        raise ValueError(f"length = {length!r} is out of range: must be >= 1")
    if not 0.0 <= homopolymer_p < 1.0:
        raise ValueError(f"homopolymer_p = {homopolymer_p!r} is out of range: must be in [0, 1)")
    if not 1 <= max_run <= MAX_DRAWN_RUN:
        raise ValueError(f"max_run = {max_run!r} is out of range: must be in 1 … {MAX_DRAWN_RUN}")
    probs = run_base_probs(gc)
    run_p = homopolymer_p ** np.arange(max_run)
    run_p /= run_p.sum()
    out: list[str] = []
    prev, total = -1, 0
    while total < length:
        p = probs.copy()
        if prev >= 0:
            p[prev] = 0.0
        if p.sum() <= 0.0:  # gc 0 or 1 after a base of the only pair: take the partner
            p = (probs > 0).astype(float)
            p[prev] = 0.0
        base = int(rng.choice(4, p=p / p.sum()))
        n = min(int(rng.choice(max_run, p=run_p)) + 1, length - total)
        out.append(NUCLEOTIDES[base] * n)
        prev, total = base, total + n
    return "".join(out)


def longest_run(seq: str) -> int:
    """Length of the longest homopolymer in ``seq`` (0 for an empty string)."""
    up = _bases("template", seq, allow_empty=True)
    best, cur = 0, 0
    for i, b in enumerate(up):
        cur = cur + 1 if i and up[i - 1] == b else 1
        best = max(best, cur)
    return best


def template_rng(seed: int) -> np.random.Generator:
    """The drawn template's own random stream: ``SeedSequence(seed)``'s child keyed by the
    stage name ``"template"``, as every stage stream (:func:`chiptwin.twin.stages.stage_rng`)."""
    key = zlib.crc32(b"template")
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(key,)))


def drawn_template(key: str, length: int, gc: float, homopolymer_p: float, max_run: int,
                   seed: int) -> str:
    """``key`` + a drawn insert of ``length`` bases (:func:`draw_template`), from ``seed``'s
    template stream. The insert's first run never repeats the key's last base (it would merge
    with the key's last flow and make the insert one base shorter than asked)."""
    rng = template_rng(seed)
    while True:
        insert = draw_template(length, gc, homopolymer_p, max_run, rng)
        if not key or insert[0] != key[-1].upper() or gc in (0.0, 1.0):
            return key.upper() + insert
