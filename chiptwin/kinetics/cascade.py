"""Kinetics level ``cascade``: the pyrosequencing enzyme cascade as a stiff ODE, as a light source.

Per site, the four enzymes of the multi-enzyme model (Agah et al., Nucleic Acids Res. 32:e166,
2004), Michaelis–Menten for each, with the constants of :class:`~chiptwin.kinetics.cascade_params.
CascadeParams`::

    d[D_j]/dt   = v_pol,j−1 − v_pol,j            v_pol,j = k_pol θ [D_j] [N_j] / (K_d + [N_j])
    d[N_n]/dt   = − Σ_{j: base j = n} v_pol,j − v_apy,n
    d[PPi]/dt   = Σ_j v_pol,j − v_S + v_L         (luciferase gives the PPi back: it is recycled)
    d[ATP]/dt   = v_S − v_L − v_apy,ATP
    I(t)        = α (1 − f_LAMP) N_A V v_L         photons/s (paper eq. 3)

with ``v_S = V_S h([PPi], K_PPi) h([APS], K_APS)``, ``v_L = V_L h([ATP], K_ATP)
[LH] / (K_LH (1 + [oxy]/K_i + [L-AMP]/K_i') + [LH])`` and competitive apyrase on ATP and the four
dNTPs (``h(c, K) = c / (K + c)``). dATPαS stands for A: the polymerase uses it, luciferase does not.
Strands are tracked per template position, so homopolymers, incomplete extension and
carry-forward (:mod:`chiptwin.kinetics.phasing`) come out of the same equations.

In the paper's limit — polymerase and sulfurylase fast, every substrate ≪ K_m — the light of one
incorporation is ``α N_A V k_t [DNA] e^{−k_a t}``, eqs. 18–19 (tested to 1 %).

:func:`cascade_pyrosequencing` builds a :class:`CascadeSource`, which fulfils the
:class:`~chiptwin.kinetics.light_source.LightSource` contract: ``rate`` from the dense output of the
state, ``photons`` from a photon counter integrated as an extra ODE state (reset at every
dispensation), so window integrals are exact to the solver tolerance.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.kinetics import phasing, pyro
from chiptwin.kinetics.cascade_params import CascadeParams
from chiptwin.kinetics.cascade_solver import SiteRun, conserved_totals

METHODS: tuple[str, ...] = ("Radau", "BDF", "LSODA")
"""Stiff solvers of ``scipy.integrate.solve_ivp`` the cascade accepts (all get the Jacobian)."""

DEFAULT_RTOL: float = 1e-8
"""Default relative tolerance; see ``benchmarks/bench_cascade.py`` for error vs time."""

NUCLEOTIDE_SPECIES: tuple[str, ...] = ("dATPaS", "dCTP", "dGTP", "dTTP")
"""Names of the four free-nucleotide states, in ``"ACGT"`` order."""


def _edges(name: str, t: ArrayLike, *, min_size: int) -> NDArray[np.float64]:
    arr = _checks.as_float_array(name, t)
    if arr.ndim != 1 or arr.size < min_size:
        raise ValueError(f"{name} has shape {arr.shape}: must be 1-D with >= {min_size} values")
    return arr


@dataclass(frozen=True, eq=False)
class CascadeSource:
    """Light per site from the solved cascade; a :class:`~chiptwin.kinetics.LightSource`.

    Build it with :func:`cascade_pyrosequencing`. Sites with equal (params, template amount,
    start) share one solution.

    Attributes
    ----------
    n_sites : int
    flow_nucleotides : list of str
        Nucleotide of every flow.
    breakpoints_s : ndarray
        Dispensation times (the rate's derivative jumps there). Unit: s.
    """

    n_sites: int
    flow_nucleotides: list[str]
    breakpoints_s: NDArray[np.float64]
    _runs: tuple[SiteRun, ...]
    _site_run: NDArray[np.int64]
    build_wall_s: float

    @property
    def accuracy_rel(self) -> float:
        """The relative tolerance the solutions were solved to (the largest of the sites'):
        :meth:`photons` is accurate to about this share of a flow's photons, so a consumer that
        refines it further (the events level's cells) bisects the solver's steps, not the
        light."""
        return max((run.rtol for run in self._runs), default=0.0)

    # --- the LightSource contract -------------------------------------------------------------

    def rate(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Emission rate per site at the times ``t_s``.

        Parameters
        ----------
        t_s : array_like, shape (n_t,)
            Times, any order. Unit: s.

        Returns
        -------
        ndarray, shape (n_sites, n_t)
            ``α (1 − f_LAMP) N_A V v_L``, 0 before a site's first dispensation. Unit: photons/s
            (into 4π).
        """
        t = _edges("t_s", t_s, min_size=0)
        return self._per_site(lambda run: run.rate(t), t.size)

    def photons(self, t_edges_s: ArrayLike) -> NDArray[np.float64]:
        """Photons per site in each window ``[t_i, t_{i+1}]``: the integral of :meth:`rate`.

        Parameters
        ----------
        t_edges_s : array_like, shape (n_windows + 1,)
            Window edges, non-decreasing, at least two. Unit: s.

        Returns
        -------
        ndarray, shape (n_sites, n_windows)
            Unit: photons (into 4π). Differences of the ODE's photon counter (dense output),
            accurate to the solver tolerance: absolute error ≈ ``rtol`` × the photons of the
            flow a window falls in. Never negative (round-off negatives are checked against
            the tolerance, then set to 0).
        """
        edges = _edges("t_edges_s", t_edges_s, min_size=2)
        steps = np.diff(edges)
        if (steps < 0).any():
            i = int(np.argmax(steps < 0))
            raise ValueError(f"t_edges_s must be non-decreasing: t_edges_s[{i + 1}] = "
                             f"{float(edges[i + 1])!r} < t_edges_s[{i}] = {float(edges[i])!r}")
        return self._per_site(lambda run: run.photons(edges), edges.size - 1)

    # --- inspection ---------------------------------------------------------------------------

    def concentrations(self, t_s: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Species per site at the times ``t_s``. Unit: M; ``extended_bases``: bases/strand.

        Returns
        -------
        dict of ndarray, shape (n_sites, n_t)
            ``PPi``, ``ATP``, ``APS``, ``luciferin``, ``oxyluciferin``, ``LAMP``, the four
            nucleotides (:data:`NUCLEOTIDE_SPECIES`) and ``extended_bases`` (mean bases added per
            strand, the held-back strands included).
        """
        t = _edges("t_s", t_s, min_size=0)
        names = ("PPi", "ATP", "APS", "luciferin", "oxyluciferin", "LAMP", *NUCLEOTIDE_SPECIES,
                 "extended_bases")
        per_run = [_species(run, t) for run in self._runs]
        return {n: np.stack([per_run[r][i] for r in self._site_run]) if self.n_sites else
                np.zeros((0, t.size)) for i, n in enumerate(names)}

    def incorporations(self) -> NDArray[np.float64]:
        """Mean bases added per strand in each flow (to the next dispensation): (n_sites, n_flows).

        The cascade's flowgram before any light is read: compare with
        :func:`chiptwin.kinetics.phasing.phased_flows`.
        """
        return self._per_site(_run_incorporations, len(self.flow_nucleotides))

    def flow_photons(self) -> NDArray[np.float64]:
        """Photons per site emitted from each dispensation to the next: (n_sites, n_flows)."""
        return self._per_site(
            lambda run: np.array([s.q_end * run.photons_per_M for s in run.segments
                                  if s.flow >= 0]), len(self.flow_nucleotides))

    def mass_balance(self) -> dict[str, float]:
        """Largest violation of each conservation law over every site and segment end.

        Returns
        -------
        dict of float
            Relative residuals (divided by the law's natural scale): ``strands`` (strands =
            template), ``pyrophosphate`` (PPi + ATP + ATP hydrolysed = bases incorporated),
            ``nucleotide`` (free + hydrolysed + incorporated = dispensed, per base),
            ``sulfate`` (SO4 = ATP made), ``light`` (Σ photon counters = oxyluciferin made).
            Each should be ≲ the solver tolerance.
        """
        worst: dict[str, float] = {}
        for run in self._runs:
            for law, value in _run_balance(run).items():
                worst[law] = max(worst.get(law, 0.0), value)
        return worst

    def solver_stats(self) -> dict[str, float]:
        """Wall time and work of the solve: totals and per-flow means over unique sites."""
        segs = [s for run in self._runs for s in run.segments]
        flows = [s for s in segs if s.flow >= 0]
        return {
            "build_wall_s": self.build_wall_s,
            "n_unique_sites": float(len(self._runs)),
            "wall_s": float(sum(s.wall_s for s in segs)),
            "wall_per_flow_s": float(np.mean([s.wall_s for s in flows])) if flows else 0.0,
            "steps": float(sum(s.n_steps for s in segs)),
            "rhs_evaluations": float(sum(s.nfev for s in segs)),
            "jacobian_evaluations": float(sum(s.njev for s in segs)),
        }

    def _per_site(self, fn, n_cols: int) -> NDArray[np.float64]:
        out = np.zeros((self.n_sites, n_cols))
        for r, run in enumerate(self._runs):
            out[self._site_run == r] = fn(run)
        return out


def _species(run: SiteRun, t: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    y, lay, p = run.states(t), run.lay, run.params
    strands = y[lay.strands]
    held = np.zeros_like(strands)
    seg = run.segment_index(t)
    for s in np.unique(seg[seg >= 0]):
        held[:, seg == s] = run.segments[s].held[:, None]
    total = strands + held
    n_strands = total.sum(axis=0)
    ext = np.divide(np.arange(lay.n_pos + 1) @ total, n_strands, out=np.zeros(t.size),
                    where=n_strands > 0)
    return [y[lay.ppi], y[lay.atp], np.maximum(p.aps_M - y[lay.so4], 0.0),
            np.maximum(p.luciferin_M - y[lay.oxy] - y[lay.lamp], 0.0), y[lay.oxy], y[lay.lamp],
            *(y[lay.nucleotide(n)] for n in range(4)), ext]


def _bases_at(run: SiteRun, y: NDArray[np.float64], held: NDArray[np.float64]) -> float:
    return float(np.dot(np.arange(run.lay.n_pos + 1), y[run.lay.strands] + held))


def _run_incorporations(run: SiteRun) -> NDArray[np.float64]:
    flows = [s for s in run.segments if s.flow >= 0]
    out = np.zeros(len(flows))
    if run.dna_M <= 0:
        return out
    before = 0.0
    for k, s in enumerate(flows):
        after = _bases_at(run, s.y_end, s.held)
        out[k] = (after - before) / run.dna_M
        before = after
    return out


def _run_balance(run: SiteRun) -> dict[str, float]:
    """Relative conservation residuals of one site, worst over its segment ends."""
    p, lay = run.params, run.lay
    dna = max(run.dna_M, 1e-300)
    light = 0.0
    out = {"strands": 0.0, "pyrophosphate": 0.0, "nucleotide": 0.0, "sulfate": 0.0, "light": 0.0}
    for s in run.segments:
        tot = conserved_totals(s.y_end, s.held, run.tmpl, p.aps_M, p.luciferin_M)
        light += s.q_end
        out["strands"] = max(out["strands"], abs(tot["strands"] - run.dna_M) / dna)
        out["pyrophosphate"] = max(out["pyrophosphate"], abs(tot["pyrophosphate"]) / dna)
        out["sulfate"] = max(out["sulfate"], abs(tot["sulfate"]) / dna)
        out["light"] = max(out["light"], abs(light - s.y_end[lay.oxy]) / dna)
    if run.segments:  # dispensed amounts (carried-over nucleotide included) known at the end
        final = conserved_totals(run.segments[-1].y_end, run.segments[-1].held, run.tmpl,
                                 p.aps_M, p.luciferin_M)
        scale = max(float(run.dispensed_M.max()), 1e-300)
        out["nucleotide"] = float(np.abs(final["nucleotide"] - run.dispensed_M).max() / scale)
    return out


def _site_params(params: CascadeParams | Sequence[CascadeParams] | None,
                 n_sites: int) -> list[CascadeParams]:
    if params is None:
        return [CascadeParams()] * n_sites
    if isinstance(params, CascadeParams):
        return [params] * n_sites
    plist = list(params)
    if len(plist) != n_sites or not all(isinstance(p, CascadeParams) for p in plist):
        raise ValueError(f"params must be a CascadeParams or a sequence of {n_sites} of them "
                         f"(one per site); got {len(plist)} items")
    return plist


def cascade_pyrosequencing(
    dna_mol: ArrayLike,
    template: str,
    flow_order: str,
    n_flows: int,
    flow_period_s: float,
    start_s: ArrayLike = 0.0,
    params: CascadeParams | Sequence[CascadeParams] | None = None,
    *,
    rtol: float = DEFAULT_RTOL,
    atol_frac: float | None = None,
    method: str = "LSODA",
    t_stop_s: float | None = None,
) -> CascadeSource:
    """Pyrosequencing light per site from the enzyme cascade (kinetics level ``cascade``).

    Mirrors :func:`chiptwin.kinetics.pyrosequencing` (closed form), but takes the template and
    flow order instead of incorporation counts: the cascade finds the incorporations itself.

    Parameters
    ----------
    dna_mol : array_like, shape (n_sites,)
        Primed template per site ``V·[DNA]``, >= 0. Unit: mol.
    template : str
        Bases to synthesise (A, C, G, T), e.g. key + insert.
    flow_order : str
        Dispensation cycle, repeated (e.g. ``"TACG"``).
    n_flows : int
        Number of dispensations, >= 0.
    flow_period_s : float
        Time between dispensations, > 0. Unit: s.
    start_s : array_like
        First dispensation, scalar or per site. Unit: s.
    params : CascadeParams, sequence of them (one per site), or None
        Cascade constants (default :class:`CascadeParams` ``()``: the paper's k_t, k_a, α).
        Per-site enzyme amounts: pass one per site.
    rtol : float
        Relative tolerance of the solver, in [1e-13, 1e-2].
    atol_frac : float or None
        Absolute tolerance as a fraction of each component's scale (template or dispensed dNTP
        concentration); default ``rtol``.
    method : str
        One of :data:`METHODS`; default LSODA (the fastest here with the same accuracy, see
        ``benchmarks/bench_cascade.py``).
    t_stop_s : float or None
        End of the initial solve; default one period after the last dispensation. Later times
        are integrated on demand when asked for.

    Returns
    -------
    CascadeSource
    """
    dna = _checks.nonnegative("dna_mol", dna_mol)
    if dna.ndim != 1:
        raise ValueError(f"dna_mol has shape {dna.shape}: must be (n_sites,)")
    nucleotides, _ = pyro.flow_incorporations(template, flow_order, n_flows)
    period = _checks.scalar("flow_period_s", flow_period_s, minimum=0.0, strict=True)
    start = _checks.scalar_or_matching("start_s", start_s, dna.size)
    tol = _checks.scalar("rtol", rtol, minimum=0.0, strict=True)
    if not 1e-13 <= tol <= 1e-2:
        raise ValueError(f"rtol = {tol!r} is out of range: must be in [1e-13, 1e-2]")
    a_frac = tol if atol_frac is None else _checks.scalar("atol_frac", atol_frac, minimum=0.0,
                                                          strict=True)
    if method not in METHODS:
        raise ValueError(f"method = {method!r} is not one of {METHODS}")
    plist = _site_params(params, dna.size)
    tmpl = phasing.template_indices(template)
    bases = np.array([pyro.NUCLEOTIDES.index(b) for b in nucleotides], dtype=np.int64)
    disp = np.arange(len(nucleotides)) * period
    stop_after = disp[-1] + period if disp.size else 0.0
    if t_stop_s is not None:
        stop_after = _checks.scalar("t_stop_s", t_stop_s, minimum=-np.inf, strict=False)
    t0 = time.perf_counter()
    runs: list[SiteRun] = []
    keys: dict[tuple, int] = {}
    site_run = np.zeros(dna.size, dtype=np.int64)
    for i in range(dna.size):
        key = (plist[i], float(dna[i]), float(start[i]))
        if key not in keys:
            p = plist[i]
            keys[key] = len(runs)
            stop = stop_after if t_stop_s is not None else start[i] + stop_after
            runs.append(SiteRun(p, float(dna[i]) / p.volume_L, tmpl, bases, start[i] + disp,
                                float(stop), tol, a_frac, method))
        site_run[i] = keys[key]
    return CascadeSource(
        n_sites=int(dna.size), flow_nucleotides=nucleotides,
        breakpoints_s=np.unique(np.concatenate([start[i] + disp for i in range(dna.size)]))
        if dna.size else np.zeros(0),
        _runs=tuple(runs), _site_run=site_run, build_wall_s=time.perf_counter() - t0,
    )
