"""One site's cascade, solved flow by flow with a stiff solver and an analytic Jacobian.

:class:`SiteRun` integrates the ODE of :mod:`chiptwin.kinetics._cascade_kernels` from one
dispensation to the next (``scipy.integrate.solve_ivp``: LSODA, Radau or BDF), applying at each
dispensation the jumps a flow brings: the merged held-back strands, the incomplete-extension split,
the nucleotide added, the carry-forward step (:mod:`chiptwin.kinetics.phasing`) and the reset of
the segment's photon counter. Each segment keeps its dense output, so any time can be evaluated
afterwards; times past the last segment are integrated on demand.

Error control: ``rtol`` relative, and per component an absolute floor ``atol_frac`` × the
component's natural scale (the template concentration for every DNA-derived species, the
dispensed dNTP for nucleotides), so a site with 1e-18 M of template is solved as accurately as
one with 1e-6 M.

Non-negativity: the right-hand side is quasi-positive (every consumption rate vanishes with its
substrate), so the exact solution stays >= 0. The solver's values are checked after every segment:
a value below ``-NEGATIVE_TOL_FACTOR × (atol + rtol × scale)`` is an error; smaller negatives
are truncation error at the tolerance: they stay in the state (the kinetics drive them back to
0, which keeps the conservation laws exact) and are set to 0 in every output.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import OdeSolution, solve_ivp

from chiptwin.constants import N_A
from chiptwin.kinetics import _cascade_kernels as _k
from chiptwin.kinetics import phasing
from chiptwin.kinetics.cascade_params import CascadeParams

NEGATIVE_TOL_FACTOR = 1000.0
"""Largest negative excursion accepted as truncation error, in units of the component's error
tolerance ``atol + rtol × scale`` (the local error the solver allows near a value of the size of
the component's scale). Truncation error carried along the strand chain over a 25-flow run
reaches ≈ 30 of these units at rtol = 1e-4 (BDF) and < 1 at rtol <= 1e-8; a sign error in the
kinetics would exceed it by orders of magnitude."""

_TINY_M = 1e-30  # scale floor for a site without template (M)
_STATE_NAMES = ("PPi", "ATP", "SO4", "OXY", "LAMP", "ATPD")  # then 4 NDEG, then Q


@dataclass(frozen=True)
class Layout:
    """Indices into one site's state vector (template length ``n_pos``; see the kernels)."""

    n_pos: int

    @property
    def n(self) -> int:
        """State size."""
        return self.n_pos + 1 + _k.N_SPECIES_AFTER_STRANDS

    @property
    def strands(self) -> slice:
        """The strand entries D_0 … D_L."""
        return slice(0, self.n_pos + 1)

    def nucleotide(self, n: int) -> int:
        """Free dNTP of base ``n`` (0–3 for A, C, G, T)."""
        return self.n_pos + 1 + n

    def degraded(self, n: int) -> int:
        """dNTP of base ``n`` hydrolysed by apyrase."""
        return self.n_pos + 11 + n

    def species(self, name: str) -> int:
        """One of PPi, ATP, SO4, OXY, LAMP, ATPD, Q."""
        return self.n_pos + 5 + _STATE_NAMES.index(name)

    @property
    def ppi(self) -> int:
        return self.species("PPi")

    @property
    def atp(self) -> int:
        return self.species("ATP")

    @property
    def so4(self) -> int:
        return self.species("SO4")

    @property
    def oxy(self) -> int:
        return self.species("OXY")

    @property
    def lamp(self) -> int:
        return self.species("LAMP")

    @property
    def atpd(self) -> int:
        return self.species("ATPD")

    @property
    def q(self) -> int:
        """Light-path turnovers since the segment started (the photon counter)."""
        return self.n_pos + 15


def polymerase_bound_fraction(polymerase_M: float, dna_M: float, kd_M: float) -> float:
    """Share θ of primed strands bound by polymerase at binding equilibrium (exact quadratic).

    ``bound = 2 P D / (P + D + K + sqrt((P + D + K)² − 4 P D))`` (no cancellation);
    ``θ = bound / D``, and ``P / (P + K)`` as ``D → 0``.
    """
    s = polymerase_M + dna_M + kd_M
    root = np.sqrt(max(s * s - 4.0 * polymerase_M * dna_M, 0.0))
    return float(2.0 * polymerase_M / (s + root))


def kernel_constants(p: CascadeParams, dna_M: float) -> NDArray[np.float64]:
    """The constants vector ``c`` of :mod:`chiptwin.kinetics._cascade_kernels` for one site."""
    theta = polymerase_bound_fraction(p.polymerase_M, dna_M, p.polymerase_kd_dna_M)
    inhibit = 1.0 if p.product_inhibition else 0.0
    return np.array([
        p.polymerase_kpol_per_s * theta, p.polymerase_kd_dntp_M,
        p.apyrase_kcat_atp_per_s * p.apyrase_M, p.apyrase_km_atp_M,
        p.apyrase_kcat_dntp_per_s * p.apyrase_M, p.apyrase_km_dntp_M,
        p.sulfurylase_kcat_per_s * p.sulfurylase_M, p.sulfurylase_km_ppi_M,
        p.sulfurylase_km_aps_M, p.aps_M,
        p.luciferase_kcat_per_s * p.luciferase_M, p.luciferase_km_atp_M,
        p.luciferase_km_luciferin_M, p.luciferin_M, p.lamp_fraction,
        inhibit / p.ki_oxyluciferin_M, inhibit / p.ki_lamp_M,
    ])


def light_rate_M_per_s(y: NDArray[np.float64], c: NDArray[np.float64],
                       lay: Layout) -> NDArray[np.float64]:
    """Light-path luciferase velocity ``(1 − f) v_L`` from states ``y`` of shape (n, n_t). M/s.

    The kernels' formula on states already checked and clipped to >= 0.
    """
    atp = np.maximum(y[lay.atp], 0.0)
    oxy, lamp = np.maximum(y[lay.oxy], 0.0), np.maximum(y[lay.lamp], 0.0)
    lh = np.maximum(c[13] - oxy - lamp, 0.0)
    inh = 1.0 + oxy * c[15] + lamp * c[16]
    return (1.0 - c[14]) * c[10] * atp / (c[11] + atp) * lh / (c[12] * inh + lh)


def prefix_counts(tmpl: NDArray[np.int64]) -> NDArray[np.float64]:
    """``cnt[j, n]``: occurrences of base n in the first j template bases; shape (L + 1, 4)."""
    cnt = np.zeros((tmpl.size + 1, 4))
    cnt[1:][np.arange(tmpl.size), tmpl] = 1.0
    return np.cumsum(cnt, axis=0)


def conserved_totals(y: NDArray[np.float64], held: NDArray[np.float64], tmpl: NDArray[np.int64],
                     aps0_M: float, luciferin0_M: float) -> dict[str, NDArray[np.float64]]:
    """The cascade's conserved quantities at one state, each in M.

    Parameters
    ----------
    y : ndarray, shape (n,)
        A state (layout in :mod:`chiptwin.kinetics._cascade_kernels`).
    held : ndarray, shape (L + 1,)
        Strands held back in the current flow (not part of the ODE state).
    tmpl : ndarray of int
        Template as base indices.
    aps0_M, luciferin0_M : float
        Initial APS and luciferin.

    Returns
    -------
    dict
        ``strands`` (= template amount), ``bases`` (incorporated bases), ``pyrophosphate``
        (PPi + ATP + ATP hydrolysed − bases: = 0), ``nucleotide`` (shape (4,): free + hydrolysed +
        incorporated, = dispensed), ``sulfate`` (SO4 − ATP made: = 0), ``aps`` (APS + SO4 = APS0),
        ``luciferin`` (luciferin + oxyluciferin + L-AMP = LH0).
    """
    lay = Layout(tmpl.size)
    strands = y[lay.strands] + held
    bases = float(np.dot(np.arange(tmpl.size + 1), strands))
    made_atp = y[lay.atp] + y[lay.oxy] + y[lay.lamp] + y[lay.atpd]
    nuc = np.array([y[lay.nucleotide(n)] + y[lay.degraded(n)] for n in range(4)])
    lh = max(luciferin0_M - y[lay.oxy] - y[lay.lamp], 0.0)
    return {
        "strands": np.float64(strands.sum()),
        "bases": np.float64(bases),
        "pyrophosphate": np.float64(y[lay.ppi] + y[lay.atp] + y[lay.atpd] - bases),
        "nucleotide": nuc + strands @ prefix_counts(tmpl),
        "sulfate": np.float64(y[lay.so4] - made_atp),
        "aps": np.float64(max(aps0_M - y[lay.so4], 0.0) + y[lay.so4]),
        "luciferin": np.float64(lh + y[lay.oxy] + y[lay.lamp]),
    }


@dataclass
class Segment:
    """One integration interval ``[t0, t1]`` (s) between dispensations (or a tail piece)."""

    t0: float
    t1: float
    sol: OdeSolution
    held: NDArray[np.float64]
    y_start: NDArray[np.float64]
    y_end: NDArray[np.float64]
    flow: int  # -1 for tail pieces after the last flow
    wall_s: float
    n_steps: int
    nfev: int
    njev: int

    @property
    def q_end(self) -> float:
        """Light-path turnovers in the segment (M)."""
        return float(self.y_end[-1])


@dataclass
class SiteRun:
    """The cascade of one site (one unique (params, template amount, start) combination).

    Parameters
    ----------
    params : CascadeParams
    dna_M : float
        Primed template concentration. Unit: M.
    tmpl : ndarray of int
        Template as base indices (:func:`chiptwin.kinetics.phasing.template_indices`).
    flow_bases : ndarray of int
        Nucleotide index of every flow.
    t_disp_s : ndarray
        Dispensation time of every flow, increasing. Unit: s.
    t_stop_s : float
        End of the first solve (later times are integrated on demand). Unit: s.
    rtol, atol_frac : float
        Solver tolerances (see the module docstring).
    method : str
        ``"Radau"``, ``"BDF"`` or ``"LSODA"``.
    """

    params: CascadeParams
    dna_M: float
    tmpl: NDArray[np.int64]
    flow_bases: NDArray[np.int64]
    t_disp_s: NDArray[np.float64]
    t_stop_s: float
    rtol: float
    atol_frac: float
    method: str
    segments: list[Segment] = field(default_factory=list)
    dispensed_M: NDArray[np.float64] = field(default_factory=lambda: np.zeros(4))

    def __post_init__(self) -> None:
        self.lay = Layout(self.tmpl.size)
        self.c = kernel_constants(self.params, self.dna_M)
        self.run = phasing.run_lengths(self.tmpl)
        self.atol = self._atol()
        self.tol = self.atol * (1.0 + self.rtol / self.atol_frac)
        self.worst_negative = 0.0
        self.photons_per_M = self.params.alpha * N_A * self.params.volume_L
        y = np.zeros(self.lay.n)
        y[0] = self.dna_M
        held = np.zeros(self.tmpl.size + 1)
        if self.t_disp_s.size == 0:
            return
        ends = np.append(self.t_disp_s[1:], max(self.t_stop_s, self.t_disp_s[-1]))
        for k, (t0, t1) in enumerate(zip(self.t_disp_s, ends, strict=True)):
            y, held = self._dispense(y, held, k)
            self._solve(t0, t1, y, held, k)
            y, held = self.segments[-1].y_end.copy(), held

    # --- setup ------------------------------------------------------------------------------

    def _atol(self) -> NDArray[np.float64]:
        lay, p = self.lay, self.params
        dna = max(self.dna_M, _TINY_M)
        nuc = p.dntp_M if p.dntp_M > 0 else dna
        scale = np.full(lay.n, dna)
        for n in range(4):
            scale[lay.nucleotide(n)] = scale[lay.degraded(n)] = nuc
        return self.atol_frac * scale

    def _dispense(self, y: NDArray[np.float64], held: NDArray[np.float64], k: int
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The jumps of dispensation ``k``: merge, split ε, add dNTP, carry-forward λ, reset Q."""
        lay, p = self.lay, self.params
        y = y.copy()
        active, held = phasing.split_held(y[lay.strands] + held, p.incomplete_extension)
        x = int(self.flow_bases[k])
        y[lay.nucleotide(x)] += p.dntp_M
        self.dispensed_M[x] += p.dntp_M
        prev = int(self.flow_bases[k - 1]) if k > 0 else -1
        if p.carry_forward > 0 and prev >= 0:
            carry = p.carry_forward * active
            jumped, b_x, b_y = phasing.carry_jump(carry, self.run, x, prev)
            if b_x > y[lay.nucleotide(x)]:  # never with dntp_M above the template amount
                scale = y[lay.nucleotide(x)] / b_x
                carry, jumped, b_x, b_y = carry * scale, jumped * scale, b_x * scale, b_y * scale
            active = active - carry
            held = held + jumped
            y[lay.nucleotide(x)] -= b_x
            y[lay.ppi] += b_x + b_y
            self.dispensed_M[prev] += b_y  # the carried-over nucleotide, counted as dispensed
        y[lay.strands] = active
        y[lay.q] = 0.0
        return y, held

    # --- integration ------------------------------------------------------------------------

    def _solve(self, t0: float, t1: float, y0: NDArray[np.float64], held: NDArray[np.float64],
               flow: int) -> None:
        tmpl, c = self.tmpl, self.c
        start = time.perf_counter()
        if t1 > t0:
            res = solve_ivp(lambda t, y: _k.rhs(y, tmpl, c), (t0, t1), y0, method=self.method,
                            jac=lambda t, y: _k.jacobian(y, tmpl, c), rtol=self.rtol,
                            atol=self.atol, dense_output=True)
            if not res.success:
                raise RuntimeError(f"cascade solver failed on [{t0}, {t1}] s: {res.message}")
            sol, ys, stats = res.sol, res.y, (res.t.size - 1, res.nfev, res.njev)
        else:
            sol, ys, stats = _constant_solution(t0, y0), y0[:, None], (0, 0, 0)
        self._check_nonnegative(ys, t0, t1)
        self.segments.append(Segment(t0, t1, sol, held, y0, ys[:, -1].copy(), flow,
                                     time.perf_counter() - start, *stats))

    def _check_nonnegative(self, ys: NDArray[np.float64], t0: float, t1: float) -> None:
        """Negative values must be truncation error: above ``-NEGATIVE_TOL_FACTOR × tol``."""
        worst = ys.min(axis=1) / self.tol
        self.worst_negative = min(self.worst_negative, float(worst.min()))
        if worst.min() < -NEGATIVE_TOL_FACTOR:
            i = int(np.argmin(worst))
            bound = NEGATIVE_TOL_FACTOR * self.tol[i]
            raise RuntimeError(f"cascade state component {i} reached {ys[i].min():.3e} M on "
                               f"[{t0}, {t1}] s, below -{NEGATIVE_TOL_FACTOR:g} × "
                               f"(atol + rtol × scale) = {-bound:.3e} M")

    def extend_to(self, t_s: float) -> None:
        """Integrate past the last segment until ``t_s`` (tail pieces, doubling in length)."""
        while self.segments and self.segments[-1].t1 < t_s:
            last = self.segments[-1]
            span = max(last.t1 - last.t0, last.t1 - self.t_disp_s[0], 1.0)
            y0 = last.y_end.copy()
            y0[self.lay.q] = 0.0
            self._solve(last.t1, last.t1 + span, y0, last.held, -1)

    # --- evaluation -------------------------------------------------------------------------

    @property
    def t_starts(self) -> NDArray[np.float64]:
        """Start of every segment (s)."""
        return np.array([s.t0 for s in self.segments])

    def segment_index(self, t: NDArray[np.float64]) -> NDArray[np.int64]:
        """Segment holding each time (−1 before the first dispensation); solves further first
        if a time lies past the last segment."""
        if t.size:
            self.extend_to(float(t.max()))
        return np.searchsorted(self.t_starts, t, side="right") - 1

    def states(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """State at the times ``t`` (before the first dispensation: the initial state); (n, n_t)."""
        seg = self.segment_index(t)
        out = np.zeros((self.lay.n, t.size))
        out[0] = self.dna_M
        for s in np.unique(seg[seg >= 0]):
            m = seg == s
            out[:, m] = self.segments[s].sol(t[m])
        return np.maximum(out, 0.0)

    def rate(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Photon emission rate at ``t``. Unit: photons/s."""
        out = light_rate_M_per_s(self.states(t), self.c, self.lay) * self.photons_per_M
        out[self.segment_index(t) < 0] = 0.0
        return out

    def photons(self, edges: NDArray[np.float64]) -> NDArray[np.float64]:
        """Photons in each window ``[edges[i], edges[i+1]]`` from the segments' counters."""
        if not self.segments:  # no dispensation: no light
            return np.zeros(edges.size - 1)
        seg = self.segment_index(edges)
        local = np.zeros(edges.size)
        for s in np.unique(seg[seg >= 0]):
            m = seg == s
            local[m] = self.segments[s].sol(edges[m])[self.lay.q]
        totals = np.array([s.q_end for s in self.segments])
        prefix = np.concatenate([[0.0], np.cumsum(totals)])
        sa, sb = seg[:-1], seg[1:]
        la, lb = np.where(sa >= 0, local[:-1], 0.0), np.where(sb >= 0, local[1:], 0.0)
        rest_a = np.where(sa >= 0, totals[np.maximum(sa, 0)] - la, 0.0)
        between = prefix[np.maximum(sb, 0)] - prefix[np.maximum(sa + 1, 0)]
        q = np.where(sa == sb, lb - la, rest_a + np.where(sb > sa, between, 0.0) + lb)
        q[sb < 0] = 0.0
        floor = NEGATIVE_TOL_FACTOR * (self.tol[self.lay.q] + self.rtol * np.abs(totals).max())
        if q.min(initial=0.0) < -floor:
            raise RuntimeError(f"negative window integral {q.min():.3e} M beyond tolerance")
        return np.maximum(q, 0.0) * self.photons_per_M


def _constant_solution(t0: float, y0: NDArray[np.float64]) -> OdeSolution:
    """A zero-length segment's 'solution': the state itself at any time."""

    class _Const:
        def __call__(self, t):
            t = np.asarray(t, dtype=np.float64)
            return np.repeat(y0[:, None], t.size, axis=1) if t.ndim else y0.copy()

    return _Const()  # type: ignore[return-value]
