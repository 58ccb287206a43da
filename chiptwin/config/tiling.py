"""A representative tile of a periodic site layout: which sites a tiled run simulates, and how
many of the array's sites each one stands for (``[run] tile``; the run itself in
:mod:`chiptwin.twin.tile`).

Geometry only, no optics: a layout is periodic when its sites fill a rectangular lattice (rows
``r0 + i·pr``, columns ``c0 + j·pc``, every node once) and every site holds the same light (no
per-site amounts or DNA draws). Along each axis of ``n`` lattice positions and a tile of ``k``,
three bands are simulated: the first ``k`` positions (the top or left edge), ``k`` in the middle
and the last ``k`` (the bottom or right edge). An edge band's position stands for itself (it
sees the neighbours an edge site sees); a middle position ``m0 + u`` stands for every middle
position ``i`` with ``(i − m0) mod k = u`` (periodic in the tile). An axis of fewer than
``3k + 1`` positions is simulated whole. The simulated sites are the product of the two axes'
positions (4 corner tiles, 4 edge tiles, 1 interior tile), each weighted by the product of its
axes' counts, so the weights sum to the array's sites. This is stratified sampling (Cochran,
*Sampling Techniques*, 3rd ed. 1977, §5.1) with one stratum per edge distance: exact in light
where the optical coupling reaches no further than a tile (``k·pitch`` pixels), and otherwise
off by what a middle site near an edge misses, which :func:`chiptwin.twin.tile.light_error`
states. The memory budget and the wall-time estimate are taken on what a run simulates
(:func:`simulated_scenario`): an array too large to run whole may run tiled.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from chiptwin.config.budget import check_budget
from chiptwin.config.fields import ScenarioError
from chiptwin.config.schema import Scenario

#: ``[run] tile = "auto"``: sites per tile side at most. 9 tiles of 8 × 8 = 576 sites put the
#: 1-σ Monte Carlo error of a fraction of sites at most √(0.25/576) = 0.021 and of a mean at
#: σ/24, and their pixels cost ≈ 0.35 s of pyro_array_256's 1,520 frames (CHOICE: a design
#: point in seconds; ask for a larger tile in pixels where the interval must be narrower).
AUTO_MAX_SITES: int = 8
#: ``"auto"``: sites per tile side at least (a smaller tile is mostly edge).
AUTO_MIN_SITES: int = 2


@dataclass(frozen=True, eq=False)
class AxisPlan:
    """One axis of the lattice: its ``n`` positions, the ``k`` of a tile, those simulated.

    Attributes
    ----------
    origin, pitch : int
        Pixel of position 0, pixels between positions.
    n, k : int
        Lattice positions, positions per tile.
    sim : ndarray of int
        The simulated positions, in order (top band, middle band, bottom band; or all).
    weight : ndarray of int
        How many positions each simulated one stands for (sums to ``n``).
    rep : ndarray of int
        For every position, the index in ``sim`` of the one standing for it.
    """

    origin: int
    pitch: int
    n: int
    k: int
    sim: np.ndarray
    weight: np.ndarray
    rep: np.ndarray

    @property
    def banded(self) -> bool:
        """False when the axis is simulated whole (too short for three bands)."""
        return len(self.sim) < self.n


def axis_plan(origin: int, pitch: int, n: int, k: int) -> AxisPlan:
    """The bands of one axis (module docstring); the whole axis when ``n ≤ 3k``."""
    if n <= 3 * k:
        all_ = np.arange(n)
        return AxisPlan(origin, pitch, n, k, all_, np.ones(n, np.int64), all_)
    m0 = (n - k) // 2  # the middle band, centred; m0 ≥ k and m0 + k ≤ n − k as n > 3k
    sim = np.concatenate([np.arange(k), m0 + np.arange(k), n - k + np.arange(k)])
    i = np.arange(n)
    rep = np.where(i < k, i, np.where(i >= n - k, 2 * k + i - (n - k), k + (i - m0) % k))
    weight = np.bincount(rep, minlength=3 * k)
    return AxisPlan(origin, pitch, n, k, sim, weight, rep)


@dataclass(frozen=True, eq=False)
class TilePlan:
    """The sites a tiled run simulates and their weights (module docstring).

    ``scenario`` is the run's own scenario with the simulated sites' pixels as its chip: a
    ``len(rows.sim) × len(cols.sim)`` array with a site on every pixel (``[run] tile`` off),
    which the chip model and the detection read; the light on those pixels, the array's
    schedule and its chip figures come from the whole array (:mod:`chiptwin.twin.tile`).
    ``site_id`` maps lattice (i, j) to the index of the site in ``sites.at_pixels``.
    """

    rows: AxisPlan
    cols: AxisPlan
    site_id: np.ndarray
    scenario: Scenario

    @property
    def n_sites(self) -> int:
        return self.rows.n * self.cols.n

    @property
    def n_simulated(self) -> int:
        return len(self.rows.sim) * len(self.cols.sim)

    @property
    def weights(self) -> np.ndarray:
        """Array sites each simulated site stands for, row-major over the simulated grid."""
        return np.outer(self.rows.weight, self.cols.weight).ravel()

    @property
    def simulated_ids(self) -> np.ndarray:
        """Index in ``sites.at_pixels`` of each simulated site, row-major."""
        return self.site_id[np.ix_(self.rows.sim, self.cols.sim)].ravel()

    def simulated(self, s: Scenario) -> Scenario:
        """``s`` (a replicate of the scenario planned: another seed) on the simulated grid:
        :attr:`scenario` with ``s``'s sections but the chip and the sites."""
        return replace(s, chip=self.scenario.chip, sites=self.scenario.sites,
                       run=replace(s.run, tile="off"))

    def simulated_pixels(self, cols: int) -> np.ndarray:
        """Row-major index in the whole array (``cols`` wide) of each simulated site's pixel."""
        r = self.rows.origin + self.rows.pitch * self.rows.sim
        c = self.cols.origin + self.cols.pitch * self.cols.sim
        return (r[:, None] * cols + c[None, :]).ravel()


def lattice(at: np.ndarray) -> tuple[tuple[int, int, int], tuple[int, int, int],
                                      np.ndarray] | None:
    """``((r0, pr, nr), (c0, pc, nc), site_id)`` when the sites ``at`` ((n, 2) [row, col])
    fill a rectangular lattice once each, else None."""
    at = np.asarray(at, dtype=np.int64).reshape(-1, 2)
    if len(at) == 0:
        return None
    axes = []
    for col in (0, 1):
        u = np.unique(at[:, col])
        steps = np.diff(u)
        if len(u) > 1 and not (steps == steps[0]).all():
            return None
        axes.append((int(u[0]), int(steps[0]) if len(u) > 1 else 1, len(u)))
    (r0, pr, nr), (c0, pc, nc) = axes
    if len(at) != nr * nc:
        return None
    site_id = np.full((nr, nc), -1, dtype=np.int64)
    site_id[(at[:, 0] - r0) // pr, (at[:, 1] - c0) // pc] = np.arange(len(at))
    if (site_id < 0).any():  # a node twice, another empty
        return None
    return (r0, pr, nr), (c0, pc, nc), site_id


def site_rc(s: Scenario) -> np.ndarray:
    """(n_sites, 2) [row, col] of every site (as :func:`chiptwin.twin.stages.site_pixels`)."""
    at = s.sites.at_pixels
    if at == "all":
        return np.stack(np.divmod(np.arange(s.chip.n_pixels), s.chip.cols), axis=1)
    if at == "centre":
        return np.array([[s.chip.rows // 2, s.chip.cols // 2]])
    return np.asarray(at, dtype=np.int64).reshape(-1, 2)


def not_tileable(s: Scenario) -> str | None:
    """Why ``s`` cannot be tiled, or None: the reason names what makes it so."""
    if s.sites.amounts_fmol:
        return "sites.amounts_fmol gives each site its own light: the layout is not periodic"
    if s.assay.kind == "pyrosequencing" and s.assay.dna_cv:
        return "assay.dna_cv draws each site's DNA: the sites' light is not periodic"
    if s.assay.kind == "flux":
        return "assay.kind = \"flux\" gives light at the sensor: there is no neighbours' light"
    from chiptwin.dsp.program import is_default

    if not is_default(s.chip.dsp.program):
        return "chip.dsp.program mixes pixels across the array: a tile cannot stand for it"
    if s.run.save_frames:
        return "run.save_frames keeps every pixel's frames: a tile simulates the sites' only"
    if lattice(site_rc(s)) is None:
        return ("sites.at_pixels does not fill a rectangular lattice (rows r0 + i·pr, columns "
                "c0 + j·pc, every node once): the layout is not periodic")
    return None


def tile_sites(s: Scenario, pitch_r: int, pitch_c: int) -> tuple[int, int] | None:
    """Sites per tile side ``(k_rows, k_cols)`` of an explicit ``[run] tile`` (pixels); None for
    ``"auto"`` (decided from the coupling's reach) and ``"off"``. Refuses a size that is no
    multiple of the site pitch, or an unknown word (exit 2, naming ``run.tile``)."""
    t = s.run.tile
    if isinstance(t, str):
        if t not in ("off", "auto"):
            raise ScenarioError(s.source, "run.tile", t, TILE_ALLOWED)
        return None
    if t % pitch_r or t % pitch_c:
        raise ScenarioError(s.source, "run.tile", t,
                            f"must be a multiple of the site pitch ({pitch_r} pixels between "
                            f"rows, {pitch_c} between columns): a tile holds whole sites")
    return t // pitch_r, t // pitch_c


#: What ``[run] tile`` accepts, in words (an error message's "allowed").
TILE_ALLOWED = ('"off", "auto", or a tile side in pixels (an integer, a multiple of the site '
                'pitch)')


def plan(s: Scenario, k_rows: int, k_cols: int) -> TilePlan | None:
    """The tile plan of ``s`` with tiles of ``k_rows × k_cols`` sites, or None when neither axis
    has room for three bands (a tile would simulate every site). ``s`` is tileable
    (:func:`not_tileable` is None)."""
    (r0, pr, nr), (c0, pc, nc), site_id = lattice(site_rc(s))
    rows, cols = axis_plan(r0, pr, nr, k_rows), axis_plan(c0, pc, nc, k_cols)
    if not (rows.banded or cols.banded):
        return None
    chip = replace(s.chip, rows=len(rows.sim), cols=len(cols.sim))
    tile_s = replace(s, chip=chip, sites=replace(s.sites, at_pixels="all"),
                     run=replace(s.run, tile="off"))
    return TilePlan(rows, cols, site_id, tile_s)


def check_tile(s: Scenario) -> None:
    """The rule of ``[run] tile`` (a cross-field rule of :mod:`chiptwin.config.consistency`):
    a known word; a size only on a periodic layout, a multiple of its pitch, with room for three
    tiles along an axis (``"auto"`` runs the whole array instead, and says so)."""
    if s.run.tile == "off":
        return
    if isinstance(s.run.tile, str):
        tile_sites(s, 1, 1)
        return
    why = not_tileable(s)
    if why is not None:
        raise ScenarioError(s.source, "run.tile", s.run.tile, f"cannot tile this scene: {why}")
    (_, pr, nr), (_, pc, nc), _ = lattice(site_rc(s))
    k = tile_sites(s, pr, pc)
    if plan(s, *k) is None:
        raise ScenarioError(s.source, "run.tile", s.run.tile,
                            f"3 tiles of {k[0]} × {k[1]} sites hold the whole {nr} × {nc} site "
                            "lattice: nothing to save; use a smaller tile or \"off\"")


def check_budget_simulated(s: Scenario) -> None:
    """:func:`chiptwin.config.budget.check_budget` of what a run of ``s`` simulates
    (:func:`simulated_scenario`): a tiled run holds its simulated sites' light, coupling and
    frames, not the whole array's, so an array too large to run whole may run tiled."""
    check_budget(simulated_scenario(s))


def simulated_scenario(s: Scenario) -> Scenario:
    """The scenario whose pixels and sites a run of ``s`` simulates, for the wall-time estimate:
    ``s`` itself, or a tiled run's simulated grid (``"auto"`` at its largest tile,
    :data:`AUTO_MAX_SITES`; the chip's schedule stays the array's)."""
    if s.run.tile == "off" or not_tileable(s):
        return s
    (_, pr, _), (_, pc, _), _ = lattice(site_rc(s))
    try:
        k = tile_sites(s, pr, pc) or (AUTO_MAX_SITES, AUTO_MAX_SITES)
    except ScenarioError:
        return s
    p = plan(s, *k)
    return s if p is None else p.scenario


__all__ = ["AUTO_MAX_SITES", "AUTO_MIN_SITES", "TILE_ALLOWED", "AxisPlan", "TilePlan",
           "axis_plan", "check_budget_simulated", "check_tile", "lattice", "not_tileable", "plan",
           "simulated_scenario", "site_rc", "tile_sites"]
