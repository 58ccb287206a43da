"""``summary['optics']``: what the optics did to a scene's light.

Three parts, each cheap (one site, at most a :data:`WINDOW` × :data:`WINDOW` window of pixels):

* **the run's coupling** at its level: the first site's own-pixel share of its emitted photons,
  the cross-talk to its brightest edge neighbour (``10·log10(neighbour / own)``, a ratio of
  light; None below :data:`CROSSTALK_FLOOR`) and the share all pixels collect;
* **the emitter law's weight** (contact imaging): the share a point site at the array's centre
  puts on all diodes, at the ``psf`` level through the scenario's stack, under each law
  (``isotropic``, ``lambertian`` and the paper's ``lambertian_na2`` convention); flagged when
  they differ by more than the run's budget (``[run] error_budget`` ``signal_rel``, else
  ``snr_rel``, else :data:`LAW_SPREAD_DEFAULT`);
* **the faceplate against direct contact** (a scenario with ``[optics.faceplate]``): own pixel,
  cross-talk and collected share at the ``psf`` level with the faceplate, and with the same
  layers directly on the diodes;
* **the top surface** (a scenario whose ``[optics.top]`` returns light): what it is, the share
  of an isotropic emitter's light it returns downwards through the site plane (and the part of
  it beyond the critical angle into air, returned by TIR), and own pixel, cross-talk and
  collected share of a centre site at the ``psf`` level with the top and without it
  (``"solution"``), under the scenario's emitter law;
* **thin films** (a stack with inner layers of at most ``optics.thin_film_um``): which layers
  are crossed coherently, over which band, and the share of the emitted light reaching the
  diode plane (a faceplate's acceptance and open area aside) with them coherent against the
  same stack traced as rays alone (``thin_film_um = 0``), at the ``psf`` level under the
  scenario's emitter law.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from chiptwin import optics
from chiptwin.config import Scenario
from chiptwin.optics.profile import build_profile
from chiptwin.optics.stack_psf import receiving_stack
from chiptwin.twin import stages

#: Side of the window of pixels around the centre site the law and faceplate figures use (the
#: array when smaller): 33 pixels of the reference chip's 125 µm pitch span 4 mm.
WINDOW = 33

#: Neighbour/own ratio below which the cross-talk is reported as none (None): −120 dB, far
#: below any measurement and above the psf quadrature's ±1e-18 zeros.
CROSSTALK_FLOOR = 1e-12

#: Relative spread between the laws' collected shares reported when no budget names one.
LAW_SPREAD_DEFAULT = 0.01


def optics_figures(s: Scenario, coupling) -> dict[str, Any] | None:
    """The ``optics`` section of ``summary.json``, or None for light given at the sensor."""
    if s.assay.kind == "flux":
        return None
    o = s.optics
    idx = stages.site_pixel_indices(s)
    col = coupling[:, [0]]
    col = np.asarray(col.toarray() if hasattr(col, "toarray") else col)[:, 0]
    out: dict[str, Any] = {"level": s.run.fidelity.optics, "emitter": o.law,
                           "site": int(idx[0]), **_own_and_neighbour(s, col, int(idx[0]))}
    if o.coupling != "contact":
        return out
    shares = law_shares(s)  # the spread is a ratio: without the transmission, which cancels
    lo, hi = min(shares.values()), max(shares.values())
    spread = hi / lo - 1.0 if lo > 0 else (math.inf if hi > 0 else 0.0)
    budget = s.run.error_budget.signal_rel or s.run.error_budget.snr_rel or LAW_SPREAD_DEFAULT
    out["collected_fraction"] = {law: _r(v * o.transmission) for law, v in shares.items()}
    out["law_spread_rel"] = _r(spread) if math.isfinite(spread) else None  # None: a law sees none
    out["laws_differ_beyond_budget"] = bool(spread > budget)
    if o.faceplate.present:
        out["faceplate"] = faceplate_vs_direct(s)
    if o.top.present:
        out["top"] = top_figures(s)
    films = thin_films(s)
    if films:
        out["thin_films"] = films
    return out


def thin_films(s: Scenario) -> dict[str, Any] | None:
    """The stack's thin films and what their coherence does to the plane fraction (None without
    films, or under the paper's one-medium convention, which ignores the stack)."""
    if s.optics.law == optics.LAMBERTIAN_NA2:
        return None
    fp = stages.optics_faceplate(s)
    receiving = receiving_stack(stages.optics_stack(s), into_silicon=s.optics.silicon_n > 0,
                                faceplate=fp)  # the psf level's stack, as coupling() builds it
    names = [layer for i, layer in enumerate(receiving.layers) if receiving.is_film(i)]
    if not names:
        return None
    na = fp.na if fp is not None else None
    coherent = build_profile(receiving, s.optics.law, na=na).total
    rays = build_profile(replace(receiving, thin_film_um=0.0), s.optics.law, na=na).total
    return {"films": [{"name": f.name, "n": f.n, "thickness_um": f.thickness_um}
                      for f in names],
            "band_nm": {"peak": receiving.band.peak_nm, "fwhm": receiving.band.fwhm_nm},
            "plane_fraction": {"coherent": _r(coherent), "rays_only": _r(rays)},
            "change_rel": _r(coherent / rays - 1.0) if rays > 0 else None}


def _own_and_neighbour(s: Scenario, col: np.ndarray, p: int) -> dict[str, Any]:
    """Own-pixel share, cross-talk to the brightest edge neighbour (dB), total collected."""
    rows, cols = s.chip.rows, s.chip.cols
    r, c = divmod(p, cols)
    nbs = [(r + dr) * cols + c + dc for dr, dc in ((0, 1), (0, -1), (1, 0), (-1, 0))
           if 0 <= r + dr < rows and 0 <= c + dc < cols]
    own = float(col[p])
    nb = max((float(col[q]) for q in nbs), default=0.0)
    db = 10 * math.log10(nb / own) if own > 0 and nb > CROSSTALK_FLOOR * own else None
    return {"own_pixel": _r(own), "crosstalk_db": None if db is None else round(db, 2),
            "collected": _r(float(col.sum()))}


def _r(v: float) -> float:
    return float(f"{v:.6g}")


def _centre(s: Scenario) -> tuple[dict, int]:
    """The grid of a window around a site at the array's centre, and its pixel in the window."""
    chip, px = s.chip, s.chip.pixel
    nr, nc = min(chip.rows, WINDOW), min(chip.cols, WINDOW)
    r, c = nr // 2, nc // 2
    grid = dict(n_rows=nr, n_cols=nc, pitch_um=chip.pitch_um, diode_w_um=px.diode_w_um,
                diode_h_um=px.diode_h_um, site_x_um=[(c + 0.5) * chip.pitch_um],
                site_y_um=[(r + 0.5) * chip.pitch_um],
                site_radius_um=s.sites.footprint_radius_um)
    return grid, r * nc + c


def law_shares(s: Scenario) -> dict[str, float]:
    """Share of a point site's light at the array's centre on all diodes of the window (the
    footprint moves a share collected over many diodes by far less than the laws differ),
    ``psf`` through the stack, per emitter law (``lambertian_na2`` only without a faceplate: it
    is a one-medium convention, without the silicon's reflection and the top);
    ``optics.transmission`` not applied. The physical laws see the scenario's top."""
    grid, _ = _centre(s)
    grid["site_radius_um"] = 0.0  # a point site: the footprint's convolution is 85 % of the cost
    stack, fp, top = stages.optics_stack(s), stages.optics_faceplate(s), stages.optics_top(s)
    out = {}
    for law in optics.EMITTERS:
        if fp is not None and law == optics.LAMBERTIAN_NA2:
            continue
        physical = law != optics.LAMBERTIAN_NA2  # the convention is one medium: no top
        c = optics.coupling_stack(**grid, stack=stack, emitter=law, faceplate=fp,
                                  into_silicon=s.optics.silicon_n > 0 and physical,
                                  top=top if physical else None)
        out[law] = float(c.sum())
    return out


def faceplate_vs_direct(s: Scenario) -> dict[str, Any]:
    """Own pixel, cross-talk and collected share of a centre site at the ``psf`` level, with the
    faceplate and with the same layers directly on the diodes (the faceplate removed, the site
    lower by its thickness), under the scenario's emitter law and top."""
    grid, p = _centre(s)
    stack, fp = stages.optics_stack(s), stages.optics_faceplate(s)
    small = replace(s, chip=replace(s.chip, rows=grid["n_rows"], cols=grid["n_cols"]))
    out: dict[str, Any] = {"level": "psf", "emitter": s.optics.law,
                           "direct": "the same layers directly on the diodes"}
    for name, face in (("with", fp), ("without", None)):
        c = optics.coupling_stack(**grid, stack=stack, emitter=s.optics.law, faceplate=face,
                                  top=stages.optics_top(s))
        out[name] = _own_and_neighbour(small, c[:, 0] * s.optics.transmission, p)
    w, wo = out["with"], out["without"]
    if w["own_pixel"] and wo["own_pixel"]:
        out["own_pixel_ratio"] = _r(w["own_pixel"] / wo["own_pixel"])
    return out


def top_figures(s: Scenario) -> dict[str, Any]:
    """The top surface: its geometry, the share of the site's light it returns downwards
    through the site plane (``returned_share``; ``tir_share`` the part beyond the critical angle
    into air, returned by TIR) under the scenario's emitter law (an isotropic emitter's; 0 for a
    Lambertian emitter facing the diodes, which sends nothing up), and a centre site's own
    pixel, cross-talk and collected share at the ``psf`` level with the top and without it."""
    top, stack = stages.optics_top(s), stages.optics_stack(s)
    n0 = stack.layers[0].n
    out: dict[str, Any] = {"medium": top.medium, "solution_depth_um": top.solution_depth_um,
                           "solution_n": n0}
    if top.medium == "glass":
        out.update(lid_n=top.lid_n, lid_thickness_um=top.lid_thickness_um)
    up = s.optics.law == optics.ISOTROPIC  # the only law that sends light up
    out["returned_share"] = _r(optics.returned_fraction(top, n0)) if up else 0.0
    out["tir_share"] = _r(0.5 * math.sqrt(max(0.0, 1.0 - (1.0 / n0) ** 2))) if up else 0.0
    grid, p = _centre(s)
    small = replace(s, chip=replace(s.chip, rows=grid["n_rows"], cols=grid["n_cols"]))
    out.update(level="psf", emitter=s.optics.law)
    for name, t in (("with", top), ("without", None)):
        c = optics.coupling_stack(**grid, stack=stack, emitter=s.optics.law,
                                  faceplate=stages.optics_faceplate(s),
                                  into_silicon=s.optics.silicon_n > 0, top=t)
        out[name] = _own_and_neighbour(small, c[:, 0] * s.optics.transmission, p)
    w, wo = out["with"]["own_pixel"], out["without"]["own_pixel"]
    out["own_pixel_change_rel"] = _r(w / wo - 1.0) if wo else None
    return out


__all__ = ["faceplate_vs_direct", "law_shares", "optics_figures", "thin_films", "top_figures"]
