"""Cross-field rules of ``[optics]``: the emitter law, the top over the sites, the layer stack,
the band, and what each optics level needs (run by
:func:`chiptwin.config.consistency.check_consistency`)."""

from __future__ import annotations

from dataclasses import MISSING

from chiptwin.config.budget import (
    FIBER_PER_DIODE_MAX,
    FOOTPRINT_PER_HEIGHT_MAX,
)
from chiptwin.config.consistency_base import _fail
from chiptwin.config.schema import Scenario


def _optics(s: Scenario) -> None:
    o = s.optics
    if o.coupling == "lens":
        for key in ("aperture_diameter_um", "object_distance_um"):
            if getattr(o, key) <= 0:
                _fail(s, f"optics.{key}", getattr(o, key), "must be > 0 with lens coupling")
        if s.run.fidelity.optics in ("psf", "raytrace"):
            _fail(s, "run.fidelity.optics", s.run.fidelity.optics,
                  f'{s.run.fidelity.optics} models contact coupling; use "na2"')
    if s.sites.footprint_radius_um > s.chip.pitch_um:
        _fail(s, "sites.footprint_radius_um", s.sites.footprint_radius_um,
              f"must not exceed the pixel pitch {s.chip.pitch_um:g} µm")
    if (s.run.fidelity.optics == "psf" and s.assay.kind != "flux" and o.coupling == "contact"
            and s.sites.footprint_radius_um > FOOTPRINT_PER_HEIGHT_MAX * s.sites.height_um):
        _fail(s, "sites.height_um", s.sites.height_um,
              f"must be ≥ footprint_radius_um / {FOOTPRINT_PER_HEIGHT_MAX:g} = "
              f"{s.sites.footprint_radius_um / FOOTPRINT_PER_HEIGHT_MAX:g} µm with the psf "
              "optics: the footprint's quadrature does not converge for a disc that wide so "
              "close to the diode")
    _pitch_holds_diode(s)
    _optics_law(s)
    _optics_layers(s)
    _optics_stack_levels(s)
    _optics_band(s)
    _optics_top(s)


def _pitch_holds_diode(s: Scenario) -> None:
    """The pitch holds the diode; neither moves the other (the pitch is the array's layout, the
    diode its own key), so the refusal names both keys and the value of each that works."""
    px, pitch = s.chip.pixel, s.chip.pitch_um
    wide = [(k, v) for k, v in (("diode_w_um", px.diode_w_um), ("diode_h_um", px.diode_h_um))
            if v > pitch]
    if wide:
        diode = " and ".join(f"chip.pixel.{k} = {v:g} µm" for k, v in wide)
        keys = " and ".join(f"chip.pixel.{k}" for k, _ in wide)
        _fail(s, "chip.pitch_um", pitch,
              f"must be ≥ the diode {diode}: set {keys} ≤ {pitch:g} or chip.pitch_um ≥ "
              f"{max(v for _, v in wide):g} (the node capacitance follows the diode unless "
              "chip.pixel.capacitance_fF is given)")


#: Ranges of ``[optics.top]`` once its medium needs the key (0 means "not given" in the schema).
TOP_DEPTH_UM = (0.1, 1.0e4)


LID_THICKNESS_UM = (1.0, 1.0e4)


def _optics_top(s: Scenario) -> None:
    """``[optics.top]``: each key where its medium uses it, and only there; a top that returns
    light needs contact imaging, a physical emitter law and the psf or raytrace level."""
    top = s.optics.top
    key = "optics.top."
    unused = [("solution_depth_um", top.solution_depth_um)] if not top.present else []
    if top.medium != "glass":
        unused += [("lid_thickness_um", top.lid_thickness_um), ("lid_n", top.lid_n)]
    for name, value in unused:
        if value:
            _fail(s, key + name, value,
                  f"is not used with optics.top.medium = {top.medium!r}: "
                  + ("a lid's key, with medium = \"glass\" only" if name.startswith("lid")
                     else "the solution continues above the site and nothing returns; set "
                          "medium = \"air\" or \"glass\", or remove it"))
    if not top.present:
        return
    lo, hi = TOP_DEPTH_UM
    if not lo <= top.solution_depth_um <= hi:
        _fail(s, key + "solution_depth_um", top.solution_depth_um or MISSING,
              f"is required with optics.top.medium = {top.medium!r}: µm from the site plane up "
              f"to the {'surface' if top.medium == 'air' else 'lid'}, in [{lo:g}, {hi:g}] (an "
              "open drop 100 µm – a few mm, a flow cell's channel 50–500 µm)")
    if top.medium == "glass":
        _lid(s)
    _top_levels(s)


def _lid(s: Scenario) -> None:
    top, key = s.optics.top, "optics.top."
    lo, hi = LID_THICKNESS_UM
    if not lo <= top.lid_thickness_um <= hi:
        _fail(s, key + "lid_thickness_um", top.lid_thickness_um or MISSING,
              f"a glass lid needs its thickness, in [{lo:g}, {hi:g}] µm (coverslips "
              "80–250 µm, slides 1 mm)")
    n0 = float(s.optics.layers[0]["n"]) if s.optics.layers else 1.33
    if top.lid_n and not max(1.0, n0) <= top.lid_n:
        _fail(s, key + "lid_n", top.lid_n,
              f"must be 0 (glass, 1.5) or in [{n0:g}, 2.5]: at least the solution's index "
              f"(optics.layers[0].n = {n0:g}); a lid of lower index is not modelled")
    elif top.lid_index < n0:
        _fail(s, key + "lid_n", top.lid_n,
              f"0 means glass of index 1.5, below the solution's n = {n0:g}: give a lid_n ≥ "
              f"{n0:g}")


def _top_levels(s: Scenario) -> None:
    """Where a top that returns light is modelled: contact imaging, a physical emitter law,
    the psf and raytrace levels."""
    o, medium = s.optics, s.optics.top.medium
    if s.assay.kind == "flux":
        _fail(s, "optics.top.medium", medium,
              "light given at the sensor plane (assay kind \"flux\") crosses no optics: the top "
              "would be ignored; remove [optics.top]")
    if o.coupling == "lens":
        _fail(s, "optics.top.medium", medium,
              "a top that returns light models contact imaging; with lens coupling the top is "
              "the sample's, use optics.transmission (or medium = \"solution\")")
    if o.law == "lambertian_na2":
        _fail(s, "optics.top.medium", medium,
              "the paper's lambertian_na2 convention is one medium, all light going down: "
              "with a top that returns light set optics.emitter = \"isotropic\" (or medium = "
              "\"solution\")")
    if s.run.fidelity.optics == "na2":
        _fail(s, "run.fidelity.optics", "na2",
              "na2 (the own diode's solid angle) has no model of the top surface; use psf or "
              "raytrace (or optics.top.medium = \"solution\")")


def _optics_band(s: Scenario) -> None:
    """The emission band thin films are averaged over (:class:`chiptwin.optics.layers.Band`:
    its ±4σ nodes stay above 100 nm)."""
    from chiptwin.optics.layers import Band

    o = s.optics
    try:
        Band(o.wavelength_nm, o.band_fwhm_nm)
    except ValueError as e:
        _fail(s, "optics.band_fwhm_nm", o.band_fwhm_nm,
              f"with optics.wavelength_nm = {o.wavelength_nm:g}: {e}")


def _optics_law(s: Scenario) -> None:
    """``emitter`` and its older name ``convention``: either, or both when they agree."""
    o = s.optics
    if o.emitter and o.convention != "lambertian_na2" and o.emitter != o.convention:
        _fail(s, "optics.emitter", o.emitter,
              f"contradicts optics.convention = {o.convention!r} (its older name); set one")


#: Keys of one ``[[optics.layers]]`` table.
LAYER_KEYS = ("name", "n", "thickness_um", "alpha_per_um", "k")


def _optics_layers(s: Scenario) -> None:
    """Each layer a table ``{name, n, thickness_um, alpha_per_um | k}`` in range; the stack
    (plus a faceplate) as high as ``sites.height_um``. The first layer (the solution from the
    site down) may leave out ``thickness_um``: it then fills ``sites.height_um`` above the
    others, so ``--set sites.height_um=…`` moves the site within its solution."""
    from chiptwin.optics.layers import ALPHA_MAX_PER_UM, N_RANGE, THICKNESS_RANGE_UM

    o = s.optics
    for i, layer in enumerate(o.layers):
        key = f"optics.layers[{i}]"
        if not isinstance(layer, dict):
            _fail(s, key, layer, "must be a table {name, n, thickness_um, alpha_per_um or k}")
        extra = sorted(set(layer) - set(LAYER_KEYS))
        if extra:
            _fail(s, f"{key}.{extra[0]}", layer[extra[0]],
                  f"unknown key; a layer's keys: {', '.join(LAYER_KEYS)}")
        if not isinstance(layer.get("name", ""), str):
            _fail(s, f"{key}.name", layer["name"], "must be a string")
        rules = (("n", N_RANGE, "the refractive index: " + "vacuum 1 … 4.5 (silicon ≈ 4.3)"),
                 ("thickness_um", THICKNESS_RANGE_UM, "µm; 0 (an interface alone) … 10 cm"),
                 ("alpha_per_um", (0.0, ALPHA_MAX_PER_UM),
                  "1/µm, Beer–Lambert; 0 … 1e3, far above silicon's ≈ 1 µm⁻¹ in the blue"),
                 ("k", (0.0, 10.0), "extinction coefficient; 0 … 10, above any metal's"))
        for name, (lo, hi), why in rules:
            if name not in layer:
                if name == "n" or (name == "thickness_um" and i > 0):
                    _fail(s, f"{key}.{name}", _MISSING, f"is required ({why})")
                continue
            v = layer[name]
            if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
                _fail(s, f"{key}.{name}", v, f"must be a number in [{lo:g}, {hi:g}] ({why})")
        if "alpha_per_um" in layer and "k" in layer:
            _fail(s, f"{key}.k", layer["k"], "give alpha_per_um or k, not both")
        if "k" in layer and 4e3 * 3.141592653589793 * layer["k"] / o.wavelength_nm > (
                ALPHA_MAX_PER_UM):
            _fail(s, f"{key}.k", layer["k"],
                  f"gives alpha_per_um = 4πk/λ above {ALPHA_MAX_PER_UM:g} at "
                  f"optics.wavelength_nm = {o.wavelength_nm:g}")
    if not o.layers:
        return
    fp = o.faceplate.thickness_um if o.faceplate.present else 0.0
    below = sum(float(layer["thickness_um"]) for layer in o.layers[1:]) + fp
    if "thickness_um" not in o.layers[0]:  # the solution fills the site height
        if below >= s.sites.height_um:
            _fail(s, "sites.height_um", s.sites.height_um,
                  f"must be above the layers below the site's solution ({below:g} µm: "
                  "optics.layers[1:] and the faceplate): the solution fills the rest")
        return
    total = sum(float(layer["thickness_um"]) for layer in o.layers)
    if not abs(total + fp - s.sites.height_um) <= 1e-9 * max(s.sites.height_um, 1.0):
        plus = f" plus the faceplate's {fp:g} µm" if fp else ""
        _fail(s, "optics.layers", f"{total:g} µm in all",
              f"the thicknesses{plus} must sum to sites.height_um = {s.sites.height_um:g} µm "
              "(the site height every level reads): change one of them")
    if float(o.layers[0]["thickness_um"]) <= 0.0:
        _fail(s, "optics.layers[0].thickness_um", o.layers[0]["thickness_um"],
              "must be > 0: the site emits inside the first layer, above its lower interface")


_MISSING = "(missing)"


def _optics_stack_levels(s: Scenario) -> None:
    """Which levels model a stated stack, a faceplate, the silicon and the well walls."""
    o, level = s.optics, s.run.fidelity.optics
    fp = o.faceplate
    if o.coupling == "lens" and (o.layers or fp.present or o.silicon_n or o.walls != "none"):
        _fail(s, "optics.coupling", "lens",
              "layers, a faceplate, silicon_n and walls model contact imaging; with a lens use "
              "transmission")
    if o.silicon_n and o.silicon_n < 1.0:
        _fail(s, "optics.silicon_n", o.silicon_n,
              "must be 0 (the diode plane absorbs) or an index in [1, 4.5]")
    if o.silicon_n and o.law == "lambertian_na2":
        _fail(s, "optics.silicon_n", o.silicon_n,
              "must be 0 with the paper's lambertian_na2 convention (one medium, no interface); "
              "the silicon's reflection needs optics.emitter = \"isotropic\" or \"lambertian\"")
    if fp.present:
        if not o.layers:
            _fail(s, "optics.layers", [], "must state the layers from the site down to the "
                  "faceplate's top face when [optics.faceplate] na > 0")
        if o.law == "lambertian_na2":
            _fail(s, "optics.faceplate.na", fp.na,
                  "a faceplate accepts by angle: it needs a physical emitter law (optics.emitter "
                  "= \"isotropic\" or \"lambertian\"), not the paper's lambertian_na2 convention")
        if o.silicon_n:
            _fail(s, "optics.silicon_n", o.silicon_n,
                  "must be 0 with a faceplate: its exit onto the diodes is straight down, "
                  "without a modelled reflection")
        if level == "na2":
            _fail(s, "run.fidelity.optics", "na2",
                  "na2 has no model of the faceplate (its acceptance and blur); use psf or "
                  "raytrace")
        if fp.core_n and fp.core_n < 1.0:
            _fail(s, "optics.faceplate.core_n", fp.core_n,
                  "must be 0 (no entry loss) or an index in [1, 4.5]")
        diode = min(s.chip.pixel.diode_w_um, s.chip.pixel.diode_h_um)
        if fp.fiber_pitch_um > FIBER_PER_DIODE_MAX * diode:
            _fail(s, "optics.faceplate.fiber_pitch_um", fp.fiber_pitch_um,
                  f"must be ≤ {FIBER_PER_DIODE_MAX:g} × the diode's smaller side = "
                  f"{FIBER_PER_DIODE_MAX * diode:g} µm: the psf level (every faceplate run's "
                  "optics summary) averages the fibre's blur by quadrature, which does not "
                  "converge in minutes for a fibre as wide as the diode; imaging faceplates' "
                  "3–25 µm fibres sit well below a luminescence pixel's diode")
    if o.walls != "none" and o.well_side_um <= 2.0 * s.sites.footprint_radius_um:
        _fail(s, "optics.well_side_um", o.well_side_um,
              f"must be > 2 × sites.footprint_radius_um = {2 * s.sites.footprint_radius_um:g} µm "
              f"with optics.walls = {o.walls!r} (the footprint sits inside the well)")
    if o.walls != "none" and level not in ("raytrace", "auto"):
        _fail(s, "optics.walls", o.walls,
              "well walls are traced at the raytrace level only; set run.fidelity.optics = "
              "\"raytrace\" (or walls = \"none\")")
    if level == "raytrace":
        _raytrace_needs(s)


#: Most rays the raytrace level may be asked for in one run: ≈ 10 min at 2 M rays/s.
RAYTRACE_MAX_RAYS = 1.2e9


def _raytrace_needs(s: Scenario) -> None:
    o = s.optics
    if o.law == "lambertian_na2":
        _fail(s, "run.fidelity.optics", "raytrace",
              "traces physical emitter laws: set optics.emitter = \"isotropic\" or "
              "\"lambertian\" (lambertian_na2 is the paper's convention, which the psf level "
              "computes exactly)")
    if s.assay.kind == "flux":  # light given at the sensor: nothing is traced
        return
    from chiptwin.config.budget import TOP_RAY_COST, raytrace_rays_estimate

    rays = raytrace_rays_estimate(s)
    cost = TOP_RAY_COST[o.top.medium]  # a ray under a top that returns light takes longer
    if rays * cost > RAYTRACE_MAX_RAYS:
        under = f" under the {o.top.medium} top, {cost:g}× a ray's time" if cost > 1 else ""
        _fail(s, "optics.raytrace_rel_error", o.raytrace_rel_error,
              f"asks ≈ {rays:.3g} rays of the raytrace level (sites × rays for this error on "
              f"the own pixel){under}, above {RAYTRACE_MAX_RAYS:g} rays' time (≈ 10 min): "
              "raise it, or use psf")
