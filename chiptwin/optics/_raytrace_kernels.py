"""numba kernel of :mod:`chiptwin.optics.raytrace`: analog Monte Carlo rays through a planar stack.

Arrays and scalars in, one outcome code per ray out; no objects, no globals but the code constants
below. The wrapper validates everything once, so the kernels do not. Geometry: ``z`` is the height
above the diode plane (µm); layer ``i`` spans ``[z_bottom[i], z_top[i]]`` with ``z_top[0]`` the site
plane; below the last layer lies the silicon.

Outcome codes (one per ray, so transmitted + reflected out + absorbed = emitted, ray by ray):
``0 … n_pixels−1`` the pixel whose diode absorbed the ray, then ``n_pixels +`` :data:`SILICON`
(absorbed in silicon outside every diode), :data:`TOP` (left upwards: through the site plane,
or out through the top surface when one is traced),
:data:`WALL` (absorbed by a well wall), :data:`TRUNCATED` (still bouncing after ``max_events``
interactions) and :data:`LAYER` ``+ i`` (absorbed in layer ``i``); with a fibre faceplate below
the last layer, ``LAYER + n_layers`` (absorbed in the faceplate: outside its acceptance, or on the
cladding and extramural absorber, the share ``1 − open_area``).
"""

from __future__ import annotations

import math

import numpy as np

from chiptwin._numba import NJIT

SILICON, TOP, WALL, TRUNCATED, LAYER = 0, 1, 2, 3, 4
"""Offsets after the pixel codes; ``LAYER + i`` is absorption in layer ``i``."""

POL_S, POL_P, POL_AVERAGE = 0, 1, 2
"""Fresnel reflectance used: s, p (one per ray, drawn at emission) or their mean at each hit."""

EMIT_ISOTROPIC, EMIT_LAMBERTIAN = 0, 1
TOP_NONE, TOP_AIR, TOP_GLASS = 0, 1, 2
"""The site's top (:mod:`chiptwin.optics.top`): the solution continues (nothing returns), an
open well's free surface under air, a glass lid with air above it."""
BACK, OUT, SOLUTION, SPENT, ON_WALL = 0, 1, 2, 3, 4
"""Fates of a trip above the site plane (:func:`_above`): back down through the site plane, out
through the top, absorbed in the solution above the site, out of events, on a wall's top face."""
FOOT_POINT, FOOT_DISC, FOOT_SQUARE = 0, 1, 2
WALLS_NONE, WALLS_ABSORBING, WALLS_REFLECTING = 0, 1, 2


@NJIT
def fresnel(n1: float, n2: float, cos_i: float, pol: int) -> tuple[float, float]:
    """Reflectance and transmitted cosine at a planar interface ``n1 → n2``.

    Returns ``(R, cos_t)``; total internal reflection gives ``(1, 0)``. ``pol`` is
    :data:`POL_S`, :data:`POL_P` or :data:`POL_AVERAGE` (unpolarised mean of the two).
    """
    if n1 == n2:
        return 0.0, cos_i
    sin_t2 = (n1 / n2) ** 2 * (1.0 - cos_i * cos_i)
    if sin_t2 >= 1.0:
        return 1.0, 0.0
    cos_t = math.sqrt(1.0 - sin_t2)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    if pol == POL_S:
        return rs * rs, cos_t
    if pol == POL_P:
        return rp * rp, cos_t
    return 0.5 * (rs * rs + rp * rp), cos_t


@NJIT
def _pixel_code(x, y, n_rows, n_cols, pitch, half_w, half_h) -> int:
    """Index of the pixel whose diode rectangle holds ``(x, y)``, or −1 (fill factor: silicon)."""
    col = math.floor(x / pitch)
    row = math.floor(y / pitch)
    if col < 0 or col >= n_cols or row < 0 or row >= n_rows:
        return -1
    if abs(x - (col + 0.5) * pitch) > half_w or abs(y - (row + 0.5) * pitch) > half_h:
        return -1
    return int(row) * n_cols + int(col)


@NJIT
def _wall_distance(x, y, dx, dy, x_lo, x_hi, y_lo, y_hi) -> tuple[float, int]:
    """Path length to the nearest vertical wall of the well and its axis (0 = x, 1 = y)."""
    tx = math.inf
    if dx > 0.0:
        tx = (x_hi - x) / dx
    elif dx < 0.0:
        tx = (x_lo - x) / dx
    ty = math.inf
    if dy > 0.0:
        ty = (y_hi - y) / dy
    elif dy < 0.0:
        ty = (y_lo - y) / dy
    if tx <= ty:
        return max(tx, 0.0), 0
    return max(ty, 0.0), 1


@NJIT
def _film_rt(tab, cos_c, f, direction, pol, lam, cos_i) -> tuple[float, float]:
    """Band node ``lam``'s reflectance and transmittance of film group ``f`` met in
    ``direction`` (0 down, 1 up) at the incidence cosine ``cos_i``, linear between the table's
    nodes: uniform in cos θ up to the exit's critical cosine ``c = cos_c[f, direction]`` (0
    when the exit is denser), then uniform in ``s = √(cos² θ − c²)``, the exit's own cosine up
    to a factor, in which R and T are smooth where they turn as √(cos θ − c);
    :data:`POL_AVERAGE` the mean of s and p (the node layout: :func:`film_nodes`)."""
    nb = tab.shape[5]
    c = cos_c[f, direction]
    split = film_split(nb, c)
    cos_i = min(cos_i, 1.0)
    if cos_i <= c:
        x = cos_i / c * split
    else:
        x = split + math.sqrt(cos_i * cos_i - c * c) / math.sqrt(1.0 - c * c) * (nb - 1 - split)
    j = min(int(x), nb - 2)
    w = x - j
    r = t = 0.0
    for p in range(2):
        if pol == POL_AVERAGE or pol == p:
            share = 0.5 if pol == POL_AVERAGE else 1.0
            r += share * ((1.0 - w) * tab[f, direction, p, 0, lam, j]
                          + w * tab[f, direction, p, 0, lam, j + 1])
            t += share * ((1.0 - w) * tab[f, direction, p, 1, lam, j]
                          + w * tab[f, direction, p, 1, lam, j + 1])
    return r, t


@NJIT
def film_split(nodes: int, cos_c: float) -> int:
    """Index of a film table's node at the exit's critical cosine ``cos_c`` (0 when none): the
    nodes below it are uniform in cos θ over ``[0, cos_c]``, those above uniform in
    ``√(cos² θ − cos_c²)``; each side gets nodes in proportion to its variable's range (``cos_c``
    and ``√(1 − cos_c²)``), at least 2."""
    if cos_c <= 0.0:
        return 0
    share = cos_c / (cos_c + math.sqrt(1.0 - cos_c * cos_c))
    return min(max(int(round(share * (nodes - 1))), 2), nodes - 3)


def film_nodes(nodes: int, cos_c: float) -> np.ndarray:
    """The incidence cosines of a film table's nodes (:func:`film_split`'s layout; at least 5)."""
    if nodes < 5:
        raise ValueError(f"film table of {nodes} nodes: at least 5 (2 on either side of the "
                         "critical cosine and the node on it)")
    split = film_split(nodes, cos_c)
    below = np.linspace(0.0, cos_c, split + 1)[:-1] if split else np.zeros(0)
    s = np.linspace(0.0, math.sqrt(1.0 - cos_c * cos_c), nodes - split)
    return np.concatenate([below, np.sqrt(s * s + cos_c * cos_c)])


@NJIT
def _solution_leg(gen, depth, cos, alpha) -> bool:
    """Whether a ray survives ``depth`` µm of solution at direction cosine ``cos``
    (Beer–Lambert, a draw only when it absorbs)."""
    if alpha <= 0.0:
        return True
    return -math.log(1.0 - gen.random()) / alpha >= depth / cos


@NJIT
def _top_return(gen, x, y, dx, dy, c0, pol, n0, alpha0, top_kind, depth, lid_n, lid_t, events):
    """A ray going up through the site plane (direction ``(dx, dy, c0)``, ``c0 > 0``, in the
    solution of index ``n0``): up ``depth`` µm to the top, where Fresnel (TIR included) sends it
    out or back; in a lid of index ``lid_n`` and thickness ``lid_t`` it bounces between the
    lid's faces until it leaves through one. Each interface is one of ``events``.

    Returns ``(fate, x, y, events)``: :data:`BACK` (down through the site plane again at
    ``(x, y)``, direction ``(dx, dy, −c0)``), :data:`OUT`, :data:`SOLUTION` or :data:`SPENT`.
    """
    if not _solution_leg(gen, depth, c0, alpha0):
        return SOLUTION, x, y, events
    x += dx * depth / c0
    y += dy * depth / c0
    if events <= 0:
        return SPENT, x, y, events
    events -= 1
    if top_kind == TOP_AIR:
        refl, _ = fresnel(n0, 1.0, c0, pol)
        if gen.random() >= refl:
            return OUT, x, y, events
    else:
        refl, cg = fresnel(n0, lid_n, c0, pol)
        if gen.random() >= refl:  # into the lid: up and down until it leaves
            step = lid_t / cg * n0 / lid_n  # lateral path per crossing, per unit of dx, dy
            while True:
                x += dx * step
                y += dy * step
                if events <= 0:
                    return SPENT, x, y, events
                events -= 1
                if gen.random() >= fresnel(lid_n, 1.0, cg, pol)[0]:
                    return OUT, x, y, events
                x += dx * step
                y += dy * step
                if events <= 0:
                    return SPENT, x, y, events
                events -= 1
                if gen.random() >= fresnel(lid_n, n0, cg, pol)[0]:
                    break  # back into the solution, at c0 again (Snell's invariant)
    if not _solution_leg(gen, depth, c0, alpha0):
        return SOLUTION, x, y, events
    return BACK, x + dx * depth / c0, y + dy * depth / c0, events


@NJIT
def _above(gen, x, y, dx, dy, c0, pol, n0, alpha0, top_kind, depth, lid_n, lid_t, walls,
           x_lo, x_hi, y_lo, y_hi, events):
    """A ray leaving the site plane upwards, until it comes back down into the well or ends
    (:func:`_top_return`). The walls' tops are the site plane and above it the solution (and a
    lid) extend sideways without bound: a ray that comes down outside the well lands on the wall
    material's top face and is absorbed there (:data:`ON_WALL`), for mirror walls too (a mirror
    top under a top that reflects by TIR would be a lossless guide: the light would travel
    sideways until ``max_events``)."""
    fate, x, y, events = _top_return(gen, x, y, dx, dy, c0, pol, n0, alpha0, top_kind, depth,
                                     lid_n, lid_t, events)
    inside = x_lo <= x <= x_hi and y_lo <= y <= y_hi
    if fate == BACK and walls != WALLS_NONE and not inside:
        return ON_WALL, x, y, events
    return fate, x, y, events


@NJIT
def trace_chunk(
    gen, out, site_x, site_y, foot_shape, foot_size, emitter, pol_mode,
    n_layer, z_bottom, z_top, alpha, n_si, walls, well_half,
    n_rows, n_cols, pitch, half_w, half_h, max_events,
    layer_code, film_of, film_tab, film_cos_c, film_code, band_cdf, fp_layer,
    fp_na=0.0, fp_pitch=0.0, fp_open=1.0,
    top_kind=TOP_NONE, top_depth=0.0, lid_n=1.0, lid_t=0.0,
):
    """Trace ``out.size`` rays from one site; write each ray's outcome code into ``out``.

    Every decision is an analog draw from ``gen`` (a ``numpy.random.Generator``): the footprint
    point, the direction, the polarisation (``pol_mode`` :data:`POL_S`/:data:`POL_P` drawn
    half and half when ``pol_mode`` is 0, else :data:`POL_AVERAGE`), reflection against
    transmission at each interface (Russian roulette on the Fresnel R), the Beer–Lambert free path
    in each absorbing layer and, at the diode plane, reflection against absorption in silicon.

    Faceplate (``fp_na > 0``): the plane below the last layer is the faceplate's top face, and
    ``n_si`` the index of its cores (the last layer's own index for no Fresnel loss). A ray
    transmitted into it with Snell's invariant ``n·sinθ ≤ fp_na`` is carried straight down to the
    diode plane with probability ``fp_open`` (the cores' share of the face), its lateral position
    kept plus a uniform jitter over one fibre pitch ``fp_pitch`` (its place inside the fibre is
    lost); every other ray is absorbed in the faceplate. No draw is made without a faceplate, so
    the streams of a stack without one are unchanged.

    Thin films (:meth:`chiptwin.optics.layers.Stack.ray_path`): ``n_layer`` … ``alpha`` are the
    ray layers; ``film_of[k]`` the film group between ray layer ``k`` and the next (or the plane
    below the last), −1 for a bare interface. A ray draws one wavelength of the band at its
    start (``band_cdf``, only when there are films: the streams of a stack without are
    unchanged) and keeps it, so every pass through a group sees that wavelength's coherent
    reflectance and transmittance (``film_tab[f, direction, pol, R|T, wavelength, node]``, the
    nodes of :func:`film_nodes` with the exit's critical cosine ``film_cos_c[f, direction]``);
    the rest, ``1 − R − T``, is absorbed in the group (code ``LAYER + film_code[f]``, the
    group's first film: a group's absorption is not split between its films). Absorption in
    ray layer ``i`` is ``LAYER + layer_code[i]``, in the faceplate ``LAYER + fp_layer`` (the
    stack's layer count).

    The top (``top_kind``, :data:`TOP_NONE` by default: a ray going up through the site plane
    leaves, code :data:`TOP`, with no draw, so the streams without a top are unchanged): a ray
    going up through the site plane crosses ``top_depth`` µm of the solution (index and
    absorption of ray layer 0) to an open surface under air or a lid (``lid_n``, ``lid_t`` µm,
    air above), leaves through it (:data:`TOP`) or comes back down and goes on through the
    stack (:func:`_above`); absorption in the solution above the site is layer 0's.
    """
    n_layers = n_layer.size
    if layer_code.size != n_layers or film_of.size != n_layers:  # numba checks no bounds
        raise ValueError("trace_chunk: layer_code and film_of need one entry a ray layer")
    n_pix = n_rows * n_cols
    has_films = film_tab.shape[0] > 0
    for k in range(out.size):
        # the footprint point (uniform) and the direction (the emitter's law)
        x, y = site_x, site_y
        if foot_shape == FOOT_DISC:
            r = foot_size * math.sqrt(gen.random())
            a = 2.0 * math.pi * gen.random()
            x += r * math.cos(a)
            y += r * math.sin(a)
        elif foot_shape == FOOT_SQUARE:
            x += foot_size * (gen.random() - 0.5)
            y += foot_size * (gen.random() - 0.5)
        if emitter == EMIT_ISOTROPIC:
            dz = 1.0 - 2.0 * gen.random()
        else:
            dz = -math.sqrt(1.0 - gen.random())
        phi = 2.0 * math.pi * gen.random()
        st = math.sqrt(max(0.0, 1.0 - dz * dz))
        dx, dy = st * math.cos(phi), st * math.sin(phi)
        pol = POL_AVERAGE
        if pol_mode != POL_AVERAGE:
            pol = POL_S if gen.random() < 0.5 else POL_P
        lam = 0
        if has_films:
            lam = min(np.searchsorted(band_cdf, gen.random(), side="right"), band_cdf.size - 1)
        if dz >= 0.0 and (top_kind == TOP_NONE or dz == 0.0):
            out[k] = n_pix + TOP  # (dz = 0, horizontal: it never reaches a top; p = 2⁻⁵³)
            continue
        x_lo, x_hi = site_x - well_half, site_x + well_half
        y_lo, y_hi = site_y - well_half, site_y + well_half
        i, z = 0, z_top[0]
        code = n_pix + TRUNCATED
        events = max_events
        if dz > 0.0:
            fate, x, y, events = _above(gen, x, y, dx, dy, dz, pol, n_layer[0], alpha[0],
                                        top_kind, top_depth, lid_n, lid_t, walls, x_lo, x_hi,
                                        y_lo, y_hi, events)
            if fate != BACK:
                out[k] = _fate_code(fate, n_pix, layer_code[0])
                continue
            dz = -dz
        while events > 0:
            events -= 1
            if dz < 0.0:
                z_end = z_bottom[i]
            else:
                z_end = z_top[i]
            t = (z_end - z) / dz
            t_wall, axis = math.inf, 0
            if walls != WALLS_NONE and i == 0:
                t_wall, axis = _wall_distance(x, y, dx, dy, x_lo, x_hi, y_lo, y_hi)
            step = min(t, t_wall)
            if alpha[i] > 0.0:
                s_free = -math.log(1.0 - gen.random()) / alpha[i]
                if s_free < step:
                    code = n_pix + LAYER + layer_code[i]
                    break
            x += dx * step
            y += dy * step
            if t_wall < t:
                z += dz * step
                if walls == WALLS_ABSORBING:
                    code = n_pix + WALL
                    break
                if axis == 0:
                    dx = -dx
                else:
                    dy = -dy
                continue
            z = z_end
            if dz > 0.0 and i == 0:
                if top_kind == TOP_NONE:
                    code = n_pix + TOP
                    break
                fate, x, y, events = _above(gen, x, y, dx, dy, dz, pol, n_layer[0], alpha[0],
                                            top_kind, top_depth, lid_n, lid_t, walls, x_lo,
                                            x_hi, y_lo, y_hi, events)
                if fate != BACK:
                    code = _fate_code(fate, n_pix, layer_code[0])
                    break
                dz = -dz
                continue
            down = dz < 0.0
            if down:
                n2 = n_si if i == n_layers - 1 else n_layer[i + 1]
            else:
                n2 = n_layer[i - 1]
            f = film_of[i] if down else film_of[i - 1]
            if f < 0:
                refl, cos_t = fresnel(n_layer[i], n2, abs(dz), pol)
                if gen.random() < refl:
                    dz = -dz
                    continue
            else:
                refl, trans = _film_rt(film_tab, film_cos_c, f, 0 if down else 1, pol, lam,
                                       abs(dz))
                u = gen.random()
                sin_t2 = (n_layer[i] / n2) ** 2 * (1.0 - dz * dz)
                if u < refl or (sin_t2 >= 1.0 and u < refl + trans):
                    dz = -dz  # beyond the exit's critical angle nothing is transmitted: the
                    continue  # table's interpolated T there is reflection
                if u >= refl + trans:
                    code = n_pix + LAYER + film_code[f]
                    break
                cos_t = math.sqrt(1.0 - sin_t2)
            if down and i == n_layers - 1:
                if fp_na > 0.0:
                    invariant = n_layer[i] * math.sqrt(max(0.0, 1.0 - dz * dz))
                    if invariant > fp_na or gen.random() >= fp_open:
                        code = n_pix + LAYER + fp_layer
                        break
                    # exit − entry: a uniform place in the fibre entered, another where it
                    # leaves, each axis a triangle on ±pitch (chiptwin.optics.faceplate)
                    x += fp_pitch * (gen.random() - gen.random())
                    y += fp_pitch * (gen.random() - gen.random())
                p = _pixel_code(x, y, n_rows, n_cols, pitch, half_w, half_h)
                code = n_pix + SILICON if p < 0 else p
                break
            ratio = n_layer[i] / n2
            dx *= ratio
            dy *= ratio
            if down:
                dz = -cos_t
                i += 1
            else:
                dz = cos_t
                i -= 1
        out[k] = code


@NJIT
def _fate_code(fate, n_pix, solution_code) -> int:
    """The outcome code of a trip above the site plane that did not come back."""
    if fate == OUT:
        return n_pix + TOP
    if fate == SOLUTION:
        return n_pix + LAYER + solution_code
    if fate == ON_WALL:
        return n_pix + WALL
    return n_pix + TRUNCATED


@NJIT
def tally(codes, counts) -> None:
    """Add each ray's outcome to ``counts`` (one bin per code)."""
    for k in range(codes.size):
        counts[codes[k]] += 1


def empty_codes(n: int) -> np.ndarray:
    """An outcome buffer for ``n`` rays (int32)."""
    return np.empty(n, dtype=np.int32)
