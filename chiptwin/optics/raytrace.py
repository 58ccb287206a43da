"""The ``raytrace`` optics level: Monte Carlo rays from each site through the planar stack.

The reference the ``psf`` levels are measured against. Rays leave a site
(uniform over its footprint; isotropic, or Lambertian facing down) inside the first layer of a
:class:`~chiptwin.optics.layers.Stack` and are followed through every planar interface until each
ends in exactly one place:

* **a pixel**: transmitted into the silicon inside that pixel's diode rectangle (the geometry of
  :mod:`chiptwin.optics.psf`: diode ``diode_w_um × diode_h_um`` centred in its pitch cell);
* **silicon outside the diodes**: transmitted into the silicon between the diodes or beyond the
  array (the fill factor: that light is absorbed and counts for no pixel);
* **the top**: out through the site's top surface (``top``, :mod:`chiptwin.optics.top`): with
  none (``"solution"``, the default: the solution continues far above the site) every ray going
  up through the site plane; under an open surface (``"air"``) or a glass lid (``"glass"``) the
  ray crosses ``solution_depth_um`` of solution (absorbing as layer 0), meets the surface with
  Fresnel per polarisation and TIR, and with a lid bounces between the lid's two faces; what is
  reflected comes back down through the site plane and goes on through the stack as any ray
  (the multiple reflections between top and bottom follow, within ``max_events``). Well walls
  span the first layer up to the site plane; above it the solution and the lid extend sideways
  without bound, and a ray coming down outside the well lands on the wall material's top face
  and is absorbed there (counted as **a wall**; for mirror walls too: a mirror top under a
  surface that reflects by TIR would guide the light sideways without loss);
* **a layer**: absorbed on its path through a layer (Beer–Lambert, ``alpha_per_um``);
* **a wall**: absorbed by an absorbing well wall (a square well of side ``well_side_um`` centred
  on the site, its walls spanning the first layer from its lower interface up to the site plane);
* **truncated**: still bouncing after ``max_events`` interactions (0 in every stack whose silicon
  has the highest index, since light can then always leave into it; reported, never hidden);
* **the faceplate** (when one is given): absorbed in a fibre-optic faceplate below the last layer,
  outside its acceptance ``n·sinθ ≤ na`` or on its cladding (``1 − open_area_ratio``). Accepted
  rays go straight down to the diode plane, jittered uniformly over one fibre pitch (the model of
  :mod:`chiptwin.optics.faceplate`, traced; the Fresnel loss into the cores, ``core_n``, with
  the multiple reflections it starts, comes on top of the ``psf`` level's single pass).

Physics per interaction (analog Monte Carlo, every ray weight 1, every choice a draw):
Snell's law (the tangential component scales by ``n1/n2``), Fresnel reflectance with total
internal reflection, reflection against transmission by Russian roulette on R (so multiple
reflections, also back up and down again, follow by themselves), the Beer–Lambert free path in
each absorbing layer, at the diode plane the Fresnel reflectance into ``stack.silicon_n`` (the
transmitted part is absorbed in the silicon), reflecting walls as perfect vertical mirrors. Thin
films (:meth:`~chiptwin.optics.layers.Stack.ray_path`) are crossed in place: each ray draws one
wavelength of the stack's emission band at its start and keeps it, and a film group reflects,
transmits or absorbs it with that wavelength's coherent R and T for its polarisation (transfer
matrices, :mod:`chiptwin.optics.thinfilm`, tabulated over Snell's invariant).

Polarisation: ``"random"`` (default) draws s or p per ray with probability ½ and keeps it: in a
planar stack the plane of incidence never changes, so s and p never mix and the unpolarised result
is exactly the mean of the two; a mirror wall maps s to s. ``"average"`` uses the mean
reflectance ``(Rs + Rp)/2`` at every interface (what optiland's tracer does): exact for one
interface, but for several it forgets that a ray passing one interface is partly polarised.

The matrix entry ``C[p, s]`` is the fraction of site ``s``'s rays that end in pixel ``p``; its
standard error is the binomial ``√(C(1 − C)/N)``. ``N`` per site follows the requested relative
error on the own pixel (the pixel whose pitch cell holds the site): ``N = (1 − p)/(p·rel²)``, with
``p`` from a pilot run on a separate stream. Rays go in chunks of fixed size, each with its own
child of a ``SeedSequence`` seeded from ``rng``: memory stays flat, the same seed gives the same
bits, and the numbers do not depend on ``workers``. Matrices are cached per geometry hash (an
``.npz`` per key in ``$XDG_CACHE_HOME/chiptwin/raytrace``, beside the auto-fidelity cache), so a
study pays once.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import __version__, _checks
from chiptwin.optics import _raytrace_kernels as _k
from chiptwin.optics import thinfilm
from chiptwin.optics.faceplate import Faceplate
from chiptwin.optics.layers import Layer, Stack
from chiptwin.optics.psf import _check_grid, _footprint, _sites
from chiptwin.optics.top import Top

EMITTERS: dict[str, int] = {"isotropic": _k.EMIT_ISOTROPIC, "lambertian": _k.EMIT_LAMBERTIAN}
"""Emitter angular laws: isotropic (molecules in solution) or Lambertian facing the diodes."""

WALLS: dict[str, int] = {"absorbing": _k.WALLS_ABSORBING, "reflecting": _k.WALLS_REFLECTING}
"""Well walls, when ``well_side_um`` is given: black, or perfect mirrors."""

POLARISATIONS: dict[str, int] = {"random": _k.POL_S, "average": _k.POL_AVERAGE}
"""``"random"``: s or p per ray (exact for planar stacks); ``"average"``: mean R per hit."""

CHUNK_RAYS: int = 1 << 16
"""Rays per chunk: one random stream each, the unit of work of a thread (fixes the bits)."""

PILOT_RAYS: int = 20_000
"""Rays per site of the pilot run that estimates the own pixel's coupling."""

MAX_EVENTS: int = 10_000
"""Interactions per ray before it is counted as truncated."""

MAX_RAYS_PER_SITE: int = 10**9
"""Largest ray count the error rule may ask for (≈ 10 min per site at 2 M rays/s)."""

KERNEL_VERSION: int = 3
"""Part of the cache key: raise it whenever the kernel's physics or stream use change."""


@dataclass(frozen=True)
class RaytraceResult:
    """A traced coupling matrix with its Monte Carlo error and every ray's fate.

    Attributes
    ----------
    coupling : ndarray (n_pixels, n_sites)
        Fraction of each site's emitted photons absorbed in each pixel's diode.
    stderr : ndarray (n_pixels, n_sites)
        Binomial standard error of each entry, ``√(C(1 − C)/N)`` (0 where no ray landed).
    n_rays : ndarray (n_sites,)
        Rays traced per site (the pilot not included).
    counts : ndarray (n_sites, n_pixels + 4 + n_layers), int64
        Rays per outcome (see :mod:`chiptwin.optics._raytrace_kernels`); each row sums to
        ``n_rays``, exactly.
    seconds : float
        Wall time of the main run (0 for a cache hit). Unit: s.
    rays_per_s : float
        Main-run throughput (that of the original run for a cache hit). Unit: rays/s.
    cached : bool
        True when read from the cache.
    faceplate : bool
        True when traced with a faceplate (its absorption is the last outcome column).
    """

    coupling: NDArray[np.float64]
    stderr: NDArray[np.float64]
    n_rays: NDArray[np.int64]
    counts: NDArray[np.int64]
    seconds: float
    rays_per_s: float
    cached: bool = False
    faceplate: bool = False

    def _share(self, offset: int) -> NDArray[np.float64]:
        n_pix = self.coupling.shape[0]
        return self.counts[:, n_pix + offset] / self.n_rays

    @property
    def silicon_outside(self) -> NDArray[np.float64]:
        """Per site: fraction absorbed in silicon outside every diode (fill factor, off-array)."""
        return self._share(_k.SILICON)

    @property
    def escaped_top(self) -> NDArray[np.float64]:
        """Per site: fraction leaving upwards through the site plane."""
        return self._share(_k.TOP)

    @property
    def absorbed_walls(self) -> NDArray[np.float64]:
        """Per site: fraction absorbed by the well walls."""
        return self._share(_k.WALL)

    @property
    def truncated(self) -> NDArray[np.float64]:
        """Per site: fraction still bouncing after ``max_events`` interactions."""
        return self._share(_k.TRUNCATED)

    @property
    def absorbed_layers(self) -> NDArray[np.float64]:
        """Per site and layer ``(n_sites, n_layers)``: fraction absorbed in each layer."""
        n_pix = self.coupling.shape[0]
        stop = self.counts.shape[1] - (1 if self.faceplate else 0)
        return self.counts[:, n_pix + _k.LAYER:stop] / self.n_rays[:, None]

    @property
    def absorbed_faceplate(self) -> NDArray[np.float64]:
        """Per site: fraction absorbed in the faceplate (0 without one)."""
        if not self.faceplate:
            return np.zeros(self.n_rays.size)
        return self.counts[:, -1] / self.n_rays

    @property
    def transmitted(self) -> NDArray[np.float64]:
        """Per site: fraction absorbed in the silicon, inside a diode or not."""
        return self.coupling.sum(axis=0) + self.silicon_outside


def rays_for_error(p: float, rel_error: float) -> int:
    """Rays that give a binomial estimate of ``p`` the relative standard error ``rel_error``.

    ``N = ⌈(1 − p) / (p · rel²)⌉`` (from ``SE² = p(1 − p)/N``), at least 1.
    """
    if not 0.0 < p <= 1.0:
        raise ValueError(f"p = {p!r} is out of range: must be in (0, 1]")
    if not rel_error > 0.0:
        raise ValueError(f"rel_error = {rel_error!r} is out of range: must be > 0")
    return max(1, math.ceil((1.0 - p) / (p * rel_error * rel_error)))


# --- streams, chunks and one site ---------------------------------------------------------------


def _streams(seq: np.random.SeedSequence, n_rays: int, chunk: int) -> list[np.random.Generator]:
    """One SFC64 generator per chunk of ``chunk`` rays, from the children of ``seq``."""
    n_chunks = -(-n_rays // chunk)
    return [np.random.Generator(np.random.SFC64(c)) for c in seq.spawn(n_chunks)]


def _trace_site(kernel_args: tuple, n_codes: int, n_rays: int, seq: np.random.SeedSequence,
                chunk: int, workers: int) -> NDArray[np.int64]:
    """Outcome counts of ``n_rays`` rays from one site, chunk by chunk (flat memory)."""
    gens = _streams(seq, n_rays, chunk)
    sizes = [min(chunk, n_rays - c * chunk) for c in range(len(gens))]

    def work(c: int) -> NDArray[np.int64]:
        codes = _k.empty_codes(sizes[c])
        _k.trace_chunk(gens[c], codes, *kernel_args)
        counts = np.zeros(n_codes, dtype=np.int64)
        _k.tally(codes, counts)
        return counts

    if workers == 1 or len(gens) == 1:
        return sum((work(c) for c in range(len(gens))), np.zeros(n_codes, dtype=np.int64))
    with ThreadPoolExecutor(workers) as pool:
        return sum(pool.map(work, range(len(gens))), np.zeros(n_codes, dtype=np.int64))


def _own_pixel(sx: float, sy: float, rows: int, cols: int, pitch: float,
               pilot: NDArray[np.int64]) -> int:
    """The pixel whose pitch cell holds the site; off the array, the pilot's brightest pixel."""
    col, row = math.floor(sx / pitch), math.floor(sy / pitch)
    if 0 <= col < cols and 0 <= row < rows:
        return row * cols + col
    return int(np.argmax(pilot[: rows * cols]))


# --- the cache ----------------------------------------------------------------------------------


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/chiptwin/raytrace`` (default ``~/.cache/chiptwin/raytrace``)."""
    from chiptwin._numba import user_cache_dir

    return user_cache_dir().parent / "raytrace"


def _cache_key(spec: dict) -> str:
    text = json.dumps([__version__, KERNEL_VERSION, spec], sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _cache_get(folder: Path, key: str) -> RaytraceResult | None:
    path = folder / f"{key}.npz"
    if not path.is_file():
        return None
    with np.load(path) as f:
        return RaytraceResult(f["coupling"], f["stderr"], f["n_rays"], f["counts"], 0.0,
                              float(f["rays_per_s"]), cached=True,
                              faceplate=bool(f["faceplate"]) if "faceplate" in f else False)


def _cache_put(folder: Path, key: str, r: RaytraceResult) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f"{key}.{os.getpid()}.tmp.npz"
    np.savez(tmp, coupling=r.coupling, stderr=r.stderr, n_rays=r.n_rays, counts=r.counts,
             rays_per_s=r.rays_per_s, faceplate=r.faceplate)
    tmp.replace(folder / f"{key}.npz")


# --- validation ---------------------------------------------------------------------------------


def _choice(name: str, value: str, table: dict[str, int]) -> int:
    if value not in table:
        allowed = ", ".join(repr(v) for v in table)
        raise ValueError(f"{name} = {value!r} is unknown: must be one of {allowed}")
    return table[value]


def _int_in(name: str, value: int, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not lo <= value <= hi:
        raise ValueError(f"{name} = {value!r} is out of range: must be an int in [{lo}, {hi}]")
    return int(value)


def _well(well_side_um: float | None, shape: str, size: float) -> float:
    """Half the well's side (inf = no well); the footprint must fit inside."""
    if well_side_um is None:
        return math.inf
    side = _checks.scalar("well_side_um", well_side_um, minimum=0.0, strict=True)
    reach = size if shape == "disc" else size / 2.0  # a disc's radius, a square's half side
    if reach >= side / 2.0:
        raise ValueError(f"well_side_um = {side!r}: the site footprint ({shape} of {size!r} µm) "
                         "must fit inside the well")
    return side / 2.0


#: Nodes of a film group's tables over the incidence cosine (``_raytrace_kernels.film_nodes``:
#: uniform in cos θ up to the exit's critical cosine, then in the exit's own cosine, where R and
#: T are smooth; they turn as a square root in β at grazing and at the critical angle). Linear
#: interpolation between them is within 2e-4 of the transfer matrix (tests/optics/
#: test_thinfilm.py).
FILM_COS_NODES: int = 1025


def _stack_arrays(stack: Stack, n_below: float) -> tuple:
    """The kernel's stack: the ray layers' indices, bottoms and tops (height above the diode
    plane, µm) and absorption, each one's outcome code, and the thin films' tables
    (:meth:`Stack.ray_path`; a film group may sit above the plane below, of index ``n_below``,
    when the last layer is a film between two indices). Films move no light sideways: the ray
    layers keep their own thicknesses, the films' are left out of the heights."""
    if not isinstance(stack, Stack):
        raise TypeError(f"stack = {stack!r}: must be a chiptwin.optics.layers.Stack")
    below = () if n_below == stack.layers[-1].n else (Layer("below", n_below, 0.0),)
    full = dataclasses.replace(stack, layers=stack.layers + below)
    ends, films = full.ray_path()  # ends: the ray layers and the plane below when it is one
    rays = ends[:-1] if below else ends
    if not below:
        films = (*films, ())  # nothing between the last layer and the plane below
    code = np.array([i for i in range(len(stack.layers)) if not full.is_film(i)], np.int64)
    thick = np.array([layer.thickness_um for layer in rays])
    bottom = np.cumsum(thick[::-1])[::-1] - thick
    top = bottom + thick
    if top[0] <= 0.0:
        raise ValueError("the stack's height_um is 0: the site must lie above the diode plane")
    n = np.array([layer.n for layer in rays])
    alpha = np.array([layer.alpha_per_um for layer in rays])
    return (n, bottom, top, alpha, code, *_film_tables(stack.band, ends, films, code))


def _film_tables(band, ends, films, code: NDArray) -> tuple:
    """From the ray layers ``ends`` (and the plane below, when it is one) and the ``films``
    below each ray layer: ``film_of`` (per interface below each ray layer: its group or −1),
    the groups' tables
    ``(F, 2 directions, 2 polarisations, R|T, wavelengths, nodes)`` with each direction's
    critical cosine (the node layout) and outcome code, and the band's cumulative weights (all
    empty without films)."""
    groups = [k for k, f in enumerate(films) if f]
    film_of = np.full(len(films), -1, np.int64)  # one entry a ray layer
    if not groups:
        return (film_of, np.zeros((0, 2, 2, 2, 1, 2)), np.zeros((0, 2)), np.zeros(0, np.int64),
                np.ones(1))
    full = [(ends[k], *films[k], ends[k + 1]) for k in groups]
    lam, weights = band.nodes(max(band.node_count(g) for g in full))
    tab = np.zeros((len(groups), 2, 2, 2, lam.size, FILM_COS_NODES))
    cos_c = np.zeros((len(groups), 2))
    film_code = np.zeros(len(groups), np.int64)
    step = max(1, thinfilm.CHUNK // lam.size)  # cosines a pass: temporaries of ≈ CHUNK values
    for f, (k, group) in enumerate(zip(groups, full, strict=True)):
        film_of[k] = f
        film_code[f] = code[k] + 1  # the group's first film, right below ray layer k
        for way, layers in enumerate((group, group[::-1])):
            if way == 1 and k + 1 == len(films):
                continue  # nothing comes back up out of the plane below: the table is not read
            n_in, n_out = layers[0].n, layers[-1].n
            cos_c[f, way] = math.sqrt(1.0 - (n_out / n_in) ** 2) if n_out < n_in else 0.0
            cos = _k.film_nodes(FILM_COS_NODES, cos_c[f, way])
            idx = thinfilm.complex_indices(layers, lam)
            d = np.array([layer.thickness_um for layer in layers])
            for lo in range(0, cos.size, step):
                c = cos[lo:lo + step, None]
                beta = layers[0].n * np.sqrt(1.0 - c * c)
                for pol_i, pol in enumerate(("s", "p")):
                    with np.errstate(divide="ignore", invalid="ignore"):  # grazing: cos = 0
                        r, _ = thinfilm.amplitudes(idx, d, lam[None, :], beta, pol)
                        big_t = thinfilm.transmittance(idx, d, lam[None, :], beta, pol)
                    tab[f, way, pol_i, 0, :, lo:lo + step] = np.nan_to_num(
                        np.abs(r) ** 2, nan=1.0).T
                    tab[f, way, pol_i, 1, :, lo:lo + step] = np.nan_to_num(big_t, nan=0.0).T
    return film_of, tab, cos_c, film_code, np.cumsum(weights)


# --- the public function ------------------------------------------------------------------------


def raytrace(
    stack: Stack,
    *,
    n_rows: int,
    n_cols: int,
    pitch_um: float,
    diode_w_um: float,
    diode_h_um: float,
    site_x_um: ArrayLike,
    site_y_um: ArrayLike,
    rng: np.random.Generator,
    site_radius_um: float = 0.0,
    site_side_um: float = 0.0,
    rel_error: float = 0.01,
    n_rays: int | None = None,
    emitter: str = "isotropic",
    walls: str = "absorbing",
    well_side_um: float | None = None,
    polarisation: str = "random",
    max_events: int = MAX_EVENTS,
    pilot_rays: int = PILOT_RAYS,
    chunk_rays: int = CHUNK_RAYS,
    workers: int = 1,
    cache: bool | Path = True,
    faceplate: Faceplate | None = None,
    cache_tag: str | int | None = None,
    top: Top | None = None,
) -> RaytraceResult:
    """Site-to-pixel coupling by Monte Carlo ray tracing through a planar stack.

    Parameters
    ----------
    stack : Stack
        Layers from the site down to the diode plane, and the silicon's index.
    n_rows, n_cols, pitch_um, diode_w_um, diode_h_um, site_x_um, site_y_um
        The pixel array and the site centres, as in :func:`chiptwin.optics.psf.coupling_psf`.
        Unit: µm.
    rng : numpy.random.Generator
        Seeds every stream (pilot and main run, per site and chunk).
    site_radius_um, site_side_um : float
        Footprint of uniform emission: disc radius or square side (at most one > 0). Unit: µm.
    rel_error : float
        Relative standard error asked of each site's own-pixel entry, in [1e-4, 0.5]; sets the
        ray count per site through a pilot run (:func:`rays_for_error`).
    n_rays : int, optional
        Rays per site, given instead (no pilot run).
    emitter : str
        ``"isotropic"`` or ``"lambertian"`` (facing the diodes).
    walls : str
        ``"absorbing"`` or ``"reflecting"``; used when ``well_side_um`` is given.
    well_side_um : float, optional
        Side of a square well centred on each site whose walls span the first layer (from its
        lower interface up to the site plane); None: no walls. Unit: µm.
    polarisation : str
        ``"random"`` (s or p per ray, exact) or ``"average"`` (mean R at every hit).
    max_events, pilot_rays, chunk_rays : int
        Interactions per ray before truncation; pilot rays per site; rays per random stream.
    workers : int
        Threads tracing chunks (the numbers do not depend on it).
    cache : bool or Path
        False: always trace. True: the cache folder :func:`cache_dir`. A Path: that folder.
        The key is everything above but ``rng`` and ``workers``: a hit returns the stored
        estimate whatever the seed.
    faceplate : Faceplate, optional
        A fibre-optic faceplate below the last layer, directly on the diodes (its top face is
        the stack's lower plane; ``stack.silicon_n`` is then unused: the rays enter the cores,
        of index ``core_n``, or of the last layer's index when ``core_n`` is None).
    cache_tag : str or int, optional
        Added to the cache key: the seed of a caller that wants one matrix per seed (the twin
        passes ``optics.raytrace_seed``).
    top : Top, optional
        The site's top surface (:mod:`chiptwin.optics.top`); None or ``"solution"``: what goes
        up through the site plane leaves (the bits and the cache key of a run without a top).

    Returns
    -------
    RaytraceResult
        ``coupling`` (n_pixels, n_sites) with its ``stderr``, the ray counts and every ray's fate.
    """
    rows, cols, pitch = _check_grid(n_rows, n_cols, pitch_um, diode_w_um, diode_h_um)
    sx, sy = _sites(site_x_um, site_y_um)
    shape, size = _footprint(site_radius_um, site_side_um)
    if faceplate is None:
        n_below = float(stack.silicon_n)
    else:
        n_below = float(faceplate.core_n if faceplate.core_n is not None
                        else stack.layers[-1].n)
    n, bottom, z_top, alpha, *films = _stack_arrays(stack, n_below)
    emit = _choice("emitter", emitter, EMITTERS)
    wall = _choice("walls", walls, WALLS)
    pol = _choice("polarisation", polarisation, POLARISATIONS)
    half_well = _well(well_side_um, shape, size)
    rel = _checks.scalar("rel_error", rel_error, minimum=0.0, strict=True)
    if not 1e-4 <= rel <= 0.5:
        raise ValueError(f"rel_error = {rel!r} is out of range: must be in [1e-4, 0.5]")
    rays = None if n_rays is None else _int_in("n_rays", n_rays, 1, MAX_RAYS_PER_SITE)
    max_events = _int_in("max_events", max_events, 1, 10**7)
    pilot_rays = _int_in("pilot_rays", pilot_rays, 100, 10**8)
    chunk_rays = _int_in("chunk_rays", chunk_rays, 1, 1 << 24)
    workers = _int_in("workers", workers, 1, 256)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng = {rng!r}: must be a numpy.random.Generator")
    if faceplate is not None and not isinstance(faceplate, Faceplate):
        raise TypeError(f"faceplate = {faceplate!r}: must be a chiptwin.optics.Faceplate")
    top_args = _top_args(top, stack)

    spec = {"stack": dataclasses.asdict(stack), "grid": [rows, cols, pitch, diode_w_um,
            diode_h_um], "sites": [sx.tolist(), sy.tolist()], "footprint": [shape, size],
            "emitter": emitter, "walls": [walls if well_side_um is not None else None,
            well_side_um], "polarisation": polarisation, "rays": rays if rays else rel,
            "max_events": max_events, "pilot": pilot_rays, "chunk": chunk_rays}
    if faceplate is not None:
        spec["faceplate"] = dataclasses.asdict(faceplate)
    if top_args[0] != _k.TOP_NONE:
        spec["top"] = dataclasses.asdict(top)
    if cache_tag is not None:
        spec["tag"] = cache_tag
    folder = None if cache is False else cache_dir() if cache is True else Path(cache)
    key = _cache_key(spec)
    if folder is not None and (hit := _cache_get(folder, key)) is not None:
        return hit

    foot = {"point": _k.FOOT_POINT, "disc": _k.FOOT_DISC, "square": _k.FOOT_SQUARE}[shape]
    n_layers = len(stack.layers)
    n_codes = rows * cols + _k.LAYER + n_layers + (1 if faceplate is not None else 0)
    if faceplate is None:
        fp = (0.0, 0.0, 1.0)
    else:
        fp = (float(faceplate.na), float(faceplate.fiber_pitch_um),
              float(faceplate.open_area_ratio))
    pilot_root, main_root = np.random.SeedSequence(rng.integers(0, 2**63, size=4)).spawn(2)
    pilot_seqs, main_seqs = pilot_root.spawn(sx.size), main_root.spawn(sx.size)
    counts = np.zeros((sx.size, n_codes), dtype=np.int64)
    per_site = np.zeros(sx.size, dtype=np.int64)
    seconds = 0.0
    for s in range(sx.size):
        args = (float(sx[s]), float(sy[s]), foot, float(size), emit, pol, n, bottom, z_top, alpha,
                n_below, wall if math.isfinite(half_well) else _k.WALLS_NONE,
                half_well if math.isfinite(half_well) else 0.0, rows, cols, pitch,
                0.5 * float(diode_w_um), 0.5 * float(diode_h_um), max_events, *films,
                n_layers, *fp, *top_args)
        per_site[s] = rays if rays else _pilot_rays(args, n_codes, pilot_rays, pilot_seqs[s],
                                                    chunk_rays, workers, rel, (sx[s], sy[s]),
                                                    (rows, cols, pitch))
        t0 = time.perf_counter()
        counts[s] = _trace_site(args, n_codes, int(per_site[s]), main_seqs[s], chunk_rays,
                                workers)
        seconds += time.perf_counter() - t0
    coupling = (counts[:, : rows * cols] / per_site[:, None]).T
    stderr = np.sqrt(coupling * (1.0 - coupling) / per_site[None, :])
    result = RaytraceResult(coupling, stderr, per_site, counts, seconds,
                            float(per_site.sum()) / max(seconds, 1e-12),
                            faceplate=faceplate is not None)
    if folder is not None:
        _cache_put(folder, key, result)
    return result


def _top_args(top: Top | None, stack: Stack) -> tuple[int, float, float, float]:
    """The kernel's top: kind, the solution's depth, the lid's index and thickness."""
    if top is None:
        return _k.TOP_NONE, 0.0, 1.0, 0.0
    if not isinstance(top, Top):
        raise TypeError(f"top = {top!r}: must be a chiptwin.optics.top.Top")
    if top.medium == "glass" and top.lid_n < stack.layers[0].n:
        raise ValueError(f"lid_n = {top.lid_n!r} below the solution's n = "
                         f"{stack.layers[0].n!r}: a lid of lower index is not modelled")
    kind = {"solution": _k.TOP_NONE, "air": _k.TOP_AIR, "glass": _k.TOP_GLASS}[top.medium]
    return kind, float(top.solution_depth_um), float(top.lid_n), float(top.lid_thickness_um)


def _pilot_rays(args, n_codes, pilot_rays, seq, chunk, workers, rel, site, grid) -> int:
    """Rays for one site from a pilot run: the error rule on its own pixel's coupling."""
    pilot = _trace_site(args, n_codes, pilot_rays, seq, chunk, workers)
    own = _own_pixel(float(site[0]), float(site[1]), *grid, pilot)
    p = pilot[own] / pilot_rays
    if p == 0.0:
        raise ValueError(f"the pilot run ({pilot_rays} rays) put no ray on the own pixel {own} of "
                         f"the site at {tuple(map(float, site))} µm: give n_rays explicitly")
    need = rays_for_error(p, rel)
    if need > MAX_RAYS_PER_SITE:
        raise ValueError(f"rel_error = {rel:g} on an own-pixel coupling of {p:.3g} needs {need} "
                         f"rays per site, above {MAX_RAYS_PER_SITE}: ask a larger rel_error")
    return need
