"""Cross-field rules: values that are each in range but cannot work together.

Each rule raises :class:`ScenarioError` naming the key a user would change. The last ones
(:func:`chiptwin.config.budget.check_budget`) refuse a run too large to work: its memory, the
counts its samplers would be handed, the chip model's time span.
"""

from __future__ import annotations

import math
import re
from dataclasses import MISSING

import numpy as np

from chiptwin.config.budget import (
    FIBER_PER_DIODE_MAX,
    FOOTPRINT_PER_HEIGHT_MAX,
    amount_key,
    check_budget,
)
from chiptwin.config.cost import check_wall_time
from chiptwin.config.fields import ScenarioError
from chiptwin.config.schema import CLOCK_MAX_HZ, Scenario
from chiptwin.constants import Q_E, s_to_ticks
from chiptwin.dsp.fixed import accumulator_bits_needed

BASES = frozenset("ACGT")

#: Narrowest ADC input range: below any ADC's (integrated ones span 0.1–5 V). Unit: V.
ADC_SPAN_MIN_V = 1e-3

#: Fidelity levels that exist. Others are refused at validation time, not half-run.
BUILT_LEVELS: dict[str, tuple[str, ...]] = {
    "kinetics": ("closed_form", "cascade"),
    "photons": ("expected", "binned", "events"),
    "optics": ("na2", "psf", "raytrace"),
    "shot": ("poisson", "gaussian"),
    "dsp": ("float", "fixed", "rtl"),
    "adc": ("ideal", "as_built"),
}


def check_consistency(s: Scenario) -> None:
    """Run every cross-field rule on a built scenario."""
    # _dsp_formats, then _dsp_program, before _timing: the schedule is derived from the
    # program's stages, and their costs from the register formats
    for rule in (_name, _fidelity, _assay, _cascade, _sites, _optics, _dsp_formats, _dsp_program,
                 _timing, _adc_range, _converter, _memory, _duration, _matched_filter, check_budget,
                 _site_amounts, check_wall_time):
        rule(s)


def _fail(s: Scenario, key: str, value: object, allowed: str) -> None:
    raise ScenarioError(s.source, key, value, allowed)


def _name(s: Scenario) -> None:
    """The name becomes the default output folder ``out/<name>``: one plain path component."""
    name = s.scenario.name
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,255}", name) or name in (".", ".."):
        _fail(s, "scenario.name", name,
              "must be 1 to 255 letters, digits, '_', '-', '.' (a folder name)")


def _fidelity(s: Scenario) -> None:
    levels = {**{f: getattr(s.run.fidelity, f) for f in BUILT_LEVELS}, "dsp": s.dsp_level}
    auto = s.run.fidelity.auto_stages()
    if auto and not s.run.error_budget.items():
        _fail(s, f"run.fidelity.{auto[0]}", "auto",
              "needs [run] error_budget, the error it may spend (e.g. { snr_rel = 0.01 })")
    for stage, level in levels.items():
        if level == "auto":
            continue  # resolved before the run (chiptwin.fidelity.auto), then checked again
        if level not in BUILT_LEVELS[stage]:
            key = "chip.dsp.mode" if stage == "dsp" and not s.run.fidelity.dsp else (
                f"run.fidelity.{stage}")
            _fail(s, key, level, f"level not built yet; built: {', '.join(BUILT_LEVELS[stage])}")
    if s.run.fidelity.kinetics == "cascade" and s.assay.kind != "pyrosequencing":
        _fail(s, "run.fidelity.kinetics", "cascade",
              f"the cascade models pyrosequencing; assay kind {s.assay.kind!r} has closed_form")
    if s.dsp_level in ("fixed", "rtl") and s.run.fidelity.photons == "expected":
        _fail(s, "run.fidelity.photons", "expected",
              f"carries no ADC codes for the {s.dsp_level} DSP to compute on; use binned")
    if s.dsp_level == "rtl":
        from chiptwin.config.rtl_path import make_importable

        make_importable()
        from rtl_ref.tools import INSTALL_HINT, missing

        if "verilator" in missing():
            key = "run.fidelity.dsp" if s.run.fidelity.dsp else "chip.dsp.mode"
            _fail(s, key, "rtl", f"simulates the DSP's Verilog with Verilator: {INSTALL_HINT}")
    if s.run.fidelity.dsp not in ("", "auto") and s.run.fidelity.dsp != s.chip.dsp.mode != "float":
        _fail(s, "run.fidelity.dsp", s.run.fidelity.dsp,
              f"contradicts chip.dsp.mode = {s.chip.dsp.mode!r}; set one of them")


#: Longest template, key or flow order: far beyond a pyrosequencing read (≈ 400–1,000 bases).
MAX_BASES = 100_000


def _assay(s: Scenario) -> None:
    a = s.assay
    if a.kind != "pyrosequencing":
        return
    for key, text in (("template", a.template), ("flow_order", a.flow_order)):
        if not text or set(text) - BASES or len(text) > MAX_BASES:
            _fail(s, f"assay.{key}", _short(text),
                  f"must be a string of 1 to {MAX_BASES} of A, C, G, T")
    if set(a.key) - BASES or not a.template.startswith(a.key) or not a.key:
        _fail(s, "assay.key", _short(a.key),
              f"must be a non-empty prefix of the template {_short(a.template)!r}")
    _key_flows(s)
    _long_reads(s)


#: The longest homopolymer the phase-correcting caller resolves (bases): its posterior runs
#: over 0 … this (chiptwin.detection.reads.MAX_CALL, kept equal by a test).
CALLER_MAX_HOMOPOLYMER = 12


def _long_reads(s: Scenario) -> None:
    """A drawn template as long as asked; homopolymers the caller resolves; the cascade's
    limits (it models phasing, not droop nor a per-site spread of the DNA)."""
    a = s.assay
    if a.template_length and len(a.template) != len(a.key) + a.template_length:
        _fail(s, "assay.template_length", a.template_length,
              f"is drawn by the scenario loader into template (key + {a.template_length} "
              f"bases); this template has {len(a.template)} bases: set template = \"\" in "
              "the file, or leave template_length at 0")
    if a.caller == "dephase":
        longest, run, prev = 0, 0, ""
        for b in a.template:
            run = run + 1 if b == prev else 1
            longest, prev = max(longest, run), b
        if longest > CALLER_MAX_HOMOPOLYMER:
            _fail(s, "assay.template", _short(a.template),
                  f"has a homopolymer of {longest} bases; the dephase caller resolves up to "
                  f"{CALLER_MAX_HOMOPOLYMER}")
    if s.run.fidelity.kinetics == "cascade":
        for key in ("droop_per_flow", "dna_cv"):
            if getattr(a, key):
                _fail(s, f"assay.{key}", getattr(a, key),
                      "must be 0 with run.fidelity.kinetics = \"cascade\" (the cascade models "
                      "incomplete extension and carry-forward, not droop nor a per-site DNA "
                      "spread); use closed_form")


#: Rates the cascade level takes: its enzyme amounts are sized from k_t and k_a
#: (CascadeParams.from_closed_form) and its solver was run at every corner of this box. Unit: 1/s.
CASCADE_RATES = (1e-3, 1e3)
#: Measured yields the cascade is fitted to, and how far from eq. 19's α·k_t/k_a: its luciferase
#: is searched within a factor 1e4 (kinetics.fit_photon_yield), which fails near 1e-4 and 1e4.
CASCADE_YIELD_MAX = 100.0
CASCADE_FIT = (1e-3, 5e3)


def _cascade(s: Scenario) -> None:
    a = s.assay
    if s.run.fidelity.kinetics != "cascade" or a.kind != "pyrosequencing":
        return
    lo, hi = CASCADE_RATES
    for key in ("k_t_per_s", "k_a_per_s"):
        if not lo <= getattr(a, key) <= hi:
            _fail(s, f"assay.{key}", getattr(a, key),
                  f"must be in [{lo:g}, {hi:g}] 1/s with run.fidelity.kinetics = \"cascade\" "
                  "(its enzymes are sized from k_t and k_a and its solver is checked over that "
                  "range; closed_form takes the whole range)")
    y = a.photons_per_incorporation
    if not y:
        return
    eq19 = a.quantum_yield * a.k_t_per_s / a.k_a_per_s
    y_lo, y_hi = eq19 / CASCADE_FIT[1], min(eq19 / CASCADE_FIT[0], CASCADE_YIELD_MAX)
    if not y_lo <= y <= y_hi:
        _fail(s, "assay.photons_per_incorporation", y,
              f"must be in [{y_lo:.3g}, {y_hi:.3g}] with run.fidelity.kinetics = \"cascade\": "
              f"its luciferase is fitted to this yield from eq. 19's α·k_t/k_a = {eq19:.3g}, "
              f"and the fit reaches {1 / CASCADE_FIT[1]:g} … {1 / CASCADE_FIT[0]:g} times that "
              f"(at most {CASCADE_YIELD_MAX:g})")


def _short(text: str) -> str:
    return text if len(text) <= 40 else f"{text[:37]}…"


def _key_flows(s: Scenario) -> None:
    """The key's flows normalise every flow: they must give a 1-mer and all be dispensed."""
    from chiptwin.kinetics import pyro

    a = s.assay
    missing = sorted(set(a.key) - set(a.flow_order))
    if missing:
        _fail(s, "assay.flow_order", a.flow_order,
              f"never dispenses {''.join(missing)}, which the key {a.key!r} needs")
    n_key = pyro.flows_to_sequence(a.key, a.flow_order)
    if not (pyro.flow_incorporations(a.key, a.flow_order, n_key - 1)[1] == 1).any():
        _fail(s, "assay.key", a.key,
              f"must have a single-base flow before its last flow with flow_order "
              f"{a.flow_order!r}: its 1-mers are the reference every flow is normalised by")
    if a.n_flows < n_key:
        _fail(s, "assay.n_flows", a.n_flows,
              f"must be ≥ {n_key}, the flows that read the key {a.key!r} with flow_order "
              f"{a.flow_order!r} (its 1-mers normalise every flow)")


def _sites(s: Scenario) -> None:
    at = s.sites.at_pixels
    if isinstance(at, str):
        if at not in ("all", "centre"):
            _fail(s, "sites.at_pixels", at, 'must be "all", "centre" or a list of [row, col]')
        return
    rows, cols = s.chip.rows, s.chip.cols
    seen = set()
    for rc in at:
        ok = isinstance(rc, list) and len(rc) == 2 and all(type(v) is int for v in rc)
        if not ok or not (0 <= rc[0] < rows and 0 <= rc[1] < cols) or tuple(rc) in seen:
            _fail(s, "sites.at_pixels", rc,
                  f"each entry must be a distinct [row, col], 0 ≤ row < {rows}, 0 ≤ col < {cols}")
        seen.add(tuple(rc))
    if not seen:
        _fail(s, "sites.at_pixels", at, "must name at least one pixel")


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
    px = s.chip.pixel
    if max(px.diode_w_um, px.diode_h_um) > s.chip.pitch_um:
        _fail(s, "chip.pitch_um", s.chip.pitch_um,
              f"must be ≥ the diode size {max(px.diode_w_um, px.diode_h_um):g} µm")
    _optics_law(s)
    _optics_layers(s)
    _optics_stack_levels(s)
    _optics_band(s)
    _optics_top(s)


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


def _timing(s: Scenario) -> None:
    """Checked in the chip model's own nanosecond ticks, as it will run."""
    from chiptwin.chip.des import Schedule

    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    if sch.busy_ns > sch.frame_period_ns:
        _fail(s, "chip.timing.frame_period_s", s.chip.timing.frame_period_s,
              f"must be ≥ reset + integration + {s.chip.samples_per_frame} conversions "
              f"= {sch.busy_ns} ns (t_int_s {s.chip.timing.t_int_s:g} s, one conversion "
              f"{sch.t_conv_ns} ns); {_schedule_fix(s, sch)}")


def _schedule_fix(s: Scenario, sch) -> str:
    """The one key that makes a frame schedule fit, with the value that does: the smallest ADC
    clock (3 significant digits, rounded up) when the conversions are what overruns, else the
    longest integration."""
    adc, n = s.chip.adc, s.chip.samples_per_frame
    spare_ns = sch.frame_period_ns - sch.t_reset_ns - sch.t_int_ns  # left for the conversions
    cycles = adc.cycles_per_conversion or 2**adc.bits
    if spare_ns >= n:
        clock = _round_up(cycles * 1e9 / (spare_ns // n))
        while s_to_ticks(cycles / clock) * n > spare_ns:  # the tick rounding may need a bit more
            clock = _round_up(clock * 1.001)
        if clock <= CLOCK_MAX_HZ:
            return (f"set chip.adc.clock_hz ≥ {_hz(clock)} (now {_hz(adc.clock_hz, short=True)}, "
                    f"{cycles} cycles a conversion), or lengthen the frame period")
    t_int_ns = sch.frame_period_ns - sch.t_reset_ns - n * sch.t_conv_ns
    if t_int_ns > 0:
        digits = 10 ** (int(math.floor(math.log10(t_int_ns))) - 3)  # 4 digits, rounded down
        return (f"set chip.timing.t_int_s ≤ {t_int_ns // digits * digits * 1e-9:.4g} (now "
                f"{s.chip.timing.t_int_s:g}), or lengthen the frame period")
    return "lengthen the frame period"


def _hz(f: float, short: bool = False) -> str:
    """A clock as a TOML value and in words: 26300000.0 → "26.3e6 (26.3 MHz)"; ``short``:
    "26.3 MHz"."""
    for exp, unit in ((9, "GHz"), (6, "MHz"), (3, "kHz")):
        if f >= 10.0**exp:
            v = f"{round(f / 10.0**exp, 6):g}"
            return f"{v} {unit}" if short else f"{v}e{exp} ({v} {unit})"
    return f"{f:g} Hz"


def _round_up(x: float) -> float:
    """Up to 3 significant digits: 41,020 → 41,100."""
    scale = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.ceil(x / scale - 1e-9) * scale


#: The ``[chip.adc]`` keys of the converter as built, and the one a pixel-level ValueError names.
AS_BUILT_KEYS = ("comparator_noise_lsb", "inl_max_lsb", "inl_shape", "inl_table", "dnl_rms_lsb",
                 "offset_sigma_lsb", "gain_sigma", "ramp")


def _converter(s: Scenario) -> None:
    """The converter as built (``chiptwin.pixel.converter``) can be built: a table file that
    exists with 2^bits − 1 non-decreasing levels, a bow that keeps the transitions in order,
    tables that fit in memory; one comparator-noise key."""
    from pathlib import Path

    from chiptwin import pixel

    adc = s.chip.adc
    if adc.comparator_noise_lsb > 0 and adc.comparator_noise_uV > 0:
        _fail(s, "chip.adc.comparator_noise_uV", adc.comparator_noise_uV,
              f"give the comparator noise once: comparator_noise_lsb is "
              f"{adc.comparator_noise_lsb:g} already (set one of the two to 0)")
    if (adc.inl_shape == "table") != bool(adc.inl_table):
        key, value = (("chip.adc.inl_table", adc.inl_table) if adc.inl_table else
                      ("chip.adc.inl_shape", adc.inl_shape))
        _fail(s, key, value, 'a transition table needs inl_shape = "table" and an inl_table file')
    folder = Path(s.source).parent if Path(s.source).is_file() else Path.cwd()
    try:
        spec = pixel.AsBuilt.from_keys(adc, folder)
        if spec.ideal:
            return
        if spec.inl_shape != "table" and spec.dnl_rms_lsb == 0.0:
            # a smooth bow alone: its one check (no reversal) on the end points' span, not on
            # a table of 2^bits levels (1.4 s at 20 bits, every time a study is loaded)
            pixel.ramp.check_bow(spec.inl_max_lsb, spec.inl_shape, adc.bits)
            return
        # the shapes' checks (bow, memory) on one converter per ramp: no map is drawn here
        pixel.build_converter(np.random.default_rng(0), (s.chip.rows, s.chip.cols),
                              bits=adc.bits, v_min_V=adc.v_min_V, v_max_V=adc.v_max_V,
                              offset_lsb=adc.offset_error_lsb, gain_error=adc.gain_error,
                              as_built=spec)
    except (ValueError, OSError) as err:
        text = str(err)
        key = next((k for k in AS_BUILT_KEYS if text.startswith(k) or f" {k}" in text
                    or f"{k} " in text), "inl_table" if isinstance(err, OSError) else "ramp")
        _fail(s, f"chip.adc.{key}", getattr(adc, key), f"the converter cannot be built: {text}")


def _adc_range(s: Scenario) -> None:
    adc, px = s.chip.adc, s.chip.pixel
    if adc.v_max_V < adc.v_min_V + ADC_SPAN_MIN_V:
        _fail(s, "chip.adc.v_max_V", adc.v_max_V,
              f"must be ≥ v_min_V + 1 mV = {adc.v_min_V + ADC_SPAN_MIN_V:g} V (no ADC has an "
              "input range below a millivolt)")
    if not adc.v_min_V <= px.pedestal_V < adc.v_max_V:
        _fail(s, "chip.pixel.pedestal_V", px.pedestal_V,
              f"must lie in the ADC range [{adc.v_min_V:g}, {adc.v_max_V:g}) V")
    # Codes the ADC gives at zero charge and at the full well, with its gain and offset errors.
    lsb = (adc.v_max_V - adc.v_min_V) / 2**adc.bits
    zero_code = (px.pedestal_V - adc.v_min_V) / lsb * (1 + adc.gain_error) + adc.offset_error_lsb
    full_well_V = px.full_well_e * Q_E / (px.capacitance_fF * 1e-15)
    full_code = zero_code + full_well_V / lsb * (1 + adc.gain_error)
    if zero_code < 0:
        _fail(s, "chip.adc.offset_error_lsb", adc.offset_error_lsb,
              f"puts the pedestal at code {zero_code:.1f}, below code 0: dark pixels would clip")
    if full_code > 2**adc.bits - 1 and not adc.range_below_full_well_ok:
        _fail(s, "chip.adc.v_max_V", adc.v_max_V,
              f"is below the full well: pedestal + full_well_e·q/C = "
              f"{px.pedestal_V + full_well_V:.4g} V reaches code {full_code:.0f} > "
              f"{2**adc.bits - 1} (gain and offset errors included); raise it, or set "
              "chip.adc.range_below_full_well_ok = true if clipping is intended")
    if s.chip.memory.word_bits < adc.bits:
        _fail(s, "chip.memory.word_bits", s.chip.memory.word_bits,
              f"must hold an ADC code: ≥ chip.adc.bits = {adc.bits}")


def _memory(s: Scenario) -> None:
    """The DSP reads blocks of frames from memory: the dark block, then blocks of N."""
    c = s.chip
    block = max(c.dsp.n_dark_frames, c.dsp.average_frames)
    dark_ref_bits = c.memory.word_bits * c.n_pixels
    needed = block * c.frame_bits + dark_ref_bits
    if c.memory.capacity_bits < needed:
        _fail(s, "chip.memory.capacity_bits", c.memory.capacity_bits,
              f"must be ≥ {needed} bits: a block of {block} frames × {c.frame_bits} bits "
              f"(word × pixels × {c.samples_per_frame} samples) + the dark reference "
              f"{dark_ref_bits} bits")


def _duration(s: Scenario) -> None:
    """Dark frames first; then blocks of N frames that start with the light and, for
    pyrosequencing, never straddle two flows (checked in integer ticks, as the chip runs)."""
    c, a = s.chip, s.assay
    period = s_to_ticks(c.timing.frame_period_s)
    dark_ticks = c.dsp.n_dark_frames * period
    block = c.dsp.average_frames * period
    if s_to_ticks(a.start_s) < dark_ticks:
        _fail(s, "assay.start_s", a.start_s,
              f"must be ≥ {dark_ticks / 1e9:g} s: the {c.dsp.n_dark_frames} dark frames come "
              "before light")
    if (s_to_ticks(a.start_s) - dark_ticks) % block:
        _fail(s, "assay.start_s", a.start_s,
              f"must be the end of the dark frames ({dark_ticks / 1e9:g} s) plus a whole number "
              f"of {c.dsp.average_frames}-frame blocks ({block / 1e9:g} s each), so that no "
              "averaged block mixes dark and light")
    need = a.start_s + c.dsp.average_frames * c.timing.frame_period_s
    if a.kind == "pyrosequencing":
        need = a.start_s + a.n_flows * a.flow_period_s
        if s_to_ticks(a.flow_period_s) % block:
            _fail(s, "assay.flow_period_s", a.flow_period_s,
                  f"must be a whole number of {c.dsp.average_frames}-frame blocks "
                  f"({block / 1e9:g} s each), so that averaged frames do not straddle flows")
    if s.run.duration_s < need:
        _fail(s, "run.duration_s", s.run.duration_s, f"must be ≥ {need:g} s for this assay")


#: Fastest decay the matched filter is given, per output block (e-folds in N frame periods).
MATCHED_EFOLDS_PER_BLOCK_MAX = 50.0


def _matched_filter(s: Scenario) -> None:
    """The matched filter weights each output block by exp(−k·t) at its middle: light that decays
    by more than e^50 within one block leaves it nothing to weight (the weights underflow and the
    window total comes out 0 ± 0)."""
    keys = {"pyrosequencing": "k_a_per_s", "atp": "turnover_per_s"}
    if s.run.light_estimator != "matched" or s.assay.kind not in keys:
        return
    key = keys[s.assay.kind]
    k = getattr(s.assay, key)
    block_s = s.chip.dsp.average_frames * s.chip.timing.frame_period_s
    if k * block_s > MATCHED_EFOLDS_PER_BLOCK_MAX:
        _fail(s, f"assay.{key}", k,
              f"decays by e^{k * block_s:.3g} within one output block ({block_s:g} s) with "
              f"run.light_estimator = \"matched\": the filter needs light that lasts; it must "
              f"be ≤ {MATCHED_EFOLDS_PER_BLOCK_MAX / block_s:.3g} 1/s, or the estimator \"sum\"")


def _site_amounts(s: Scenario) -> None:
    """``[sites] amounts_fmol``: one amount per site, each in [0, the ``[assay]`` amount].

    The light of every closed-form assay is proportional to its analyte (eqs. 5–19), so a site's
    light is the ``[assay]`` amount's scaled by the site's share (chiptwin.twin.dose_response); the
    cascade's is not, and light given at the diode (``flux``) has no analyte.
    """
    amounts = s.sites.amounts_fmol
    if not amounts:
        return
    if s.assay.kind == "flux":
        _fail(s, "sites.amounts_fmol", _short(str(amounts)),
              'assay kind "flux" gives light at the diode, with no analyte to dose')
    if s.run.fidelity.kinetics == "cascade":
        _fail(s, "sites.amounts_fmol", _short(str(amounts)),
              'needs run.fidelity.kinetics = "closed_form": per-site amounts scale the light, '
              "which is proportional to the amount in the closed forms only")
    at = s.sites.at_pixels
    n = {"all": s.chip.n_pixels, "centre": 1}.get(at, 0) if isinstance(at, str) else len(at)
    if len(amounts) != n:
        _fail(s, "sites.amounts_fmol", _short(str(amounts)),
              f"must list one amount per site: {n} sites (sites.at_pixels), {len(amounts)} given")
    key = amount_key(s)
    top = getattr(s.assay, key) * (1e-3 if key.endswith("_amol") else 1.0)
    for v in amounts:
        number = isinstance(v, (int, float)) and not isinstance(v, bool)
        if not number or not 0.0 <= v <= top:  # NaN fails both comparisons
            _fail(s, "sites.amounts_fmol", v,
                  f"each must be a number in [0, {top:g}] fmol: 0 is a blank site, and the "
                  f"largest is assay.{key} = {getattr(s.assay, key):g}, which bounds the run's "
                  "budget")


def scenario_warnings(s: Scenario) -> list[str]:
    """Choices that run but that a chip architect should see: printed by ``validate``, kept in
    ``summary['warnings']``."""
    from chiptwin.dsp.pipeline import chain_for

    warnings = []
    d = s.chip.dsp
    if d.acc_bits and s.dsp_level != "float":
        in_fmt = chain_for(s.chip).average.in_fmt
        needed = accumulator_bits_needed(in_fmt, d.average_frames)
        if d.acc_bits < needed:
            warnings.append(
                f"{s.source}: chip.dsp.acc_bits = {d.acc_bits} is too narrow for "
                f"average_frames = {d.average_frames} frames of {in_fmt.q}: {needed} bits never "
                f"overflow; expect {d.acc_overflow} events (counted in summary['dsp'])")
    return warnings


def _dsp_formats(s: Scenario) -> None:
    """Every register the run derives from ``[chip.dsp]`` fits the DSP's 64 bits.

    The chain's formats (ADC bits, M, K, N, ``acc_bits``) are derived at the fixed and RTL levels
    (and wherever the level may become one, ``auto``); a program beyond today's chain derives
    its stages' formats at every level (the schedule counts their memory). A count whose
    registers would be wider is refused here by its own key, before anything derives them.
    """
    from chiptwin.dsp import program as prog
    from chiptwin.dsp.chain import FormatLimit
    from chiptwin.dsp.pipeline import chain_for

    program = s.chip.dsp.program
    if prog.order_problem(program) is not None:
        return  # _dsp_program refuses the list itself
    if s.dsp_level == "float" and prog.is_default(program):
        return
    try:
        chain_for(s.chip)
        if not prog.is_default(program):
            prog.program_formats(s.chip)
    except FormatLimit as err:
        key = "chip.adc.bits" if err.key == "adc_bits" else f"chip.dsp.{err.key}"
        _fail(s, key, err.value, err.allowed)


def _dsp_program(s: Scenario) -> None:
    """``[chip.dsp] program``: known stages in their order, each stage's needs (assay, optics,
    level, geometry, register widths), and the frame memory the program holds."""
    from chiptwin.dsp import program as prog

    c, key = s.chip, "chip.dsp.program"
    program = c.dsp.program
    bad = prog.order_problem(program)
    if bad is not None:
        _fail(s, key, bad[0], bad[1])
    if prog.is_default(program):
        return
    if "kinetics" in program and s.assay.kind not in prog.DECAY_KEYS:
        _fail(s, key, "kinetics",
              f"stage 'kinetics' weights frames by the assay's decay exp(-k t); assay kind "
              f"{s.assay.kind!r} has no decay law (kinds with one: "
              f"{', '.join(prog.DECAY_KEYS)})")
    if "wiener" in program:
        _program_wiener(s)
    if s.dsp_level == "rtl":
        for stage in program:
            if stage not in prog.RTL_STAGES:
                _fail(s, key, stage,
                      f"stage {stage!r} has no RTL block (rtl_ref has "
                      f"{', '.join(x for x in prog.STAGES if x in prog.RTL_STAGES)}); run it "
                      "at chip.dsp.mode = \"fixed\"")
    _program_formats(s)
    _program_memory(s)


def _program_wiener(s: Scenario) -> None:
    from chiptwin.dsp import program as prog

    o = s.optics
    if s.assay.kind == "flux" or o.coupling != "contact" or s.run.fidelity.optics not in (
            "psf", "raytrace", "auto"):
        _fail(s, "chip.dsp.program", "wiener",
              "stage 'wiener' equalizes the optics' coupling matrix (the PSF of contact "
              "imaging): it needs optics.coupling = \"contact\", run.fidelity.optics = \"psf\" "
              f"and an assay (not light given at the sensor); here coupling {o.coupling!r}, "
              f"optics {s.run.fidelity.optics!r}, assay {s.assay.kind!r}")
    n = prog.grid_shape(s.chip)
    if n[0] * n[1] > prog.WIENER_MAX_GRID:
        _fail(s, "chip.dsp.program", "wiener",
              f"stage 'wiener' holds an n × n coefficient table for its {n[0]} × {n[1]} input "
              f"grid: n must be ≤ {prog.WIENER_MAX_GRID} (bin the rows first, or a smaller "
              "array)")


def _program_formats(s: Scenario) -> None:
    """Register widths each stage derives must exist (≤ 64 bits, products that fit)."""
    from chiptwin.chip.des import Schedule
    from chiptwin.dsp import program as prog

    try:
        prog.program_formats(s.chip)
        if "kinetics" in s.chip.dsp.program:
            from chiptwin.config.budget import window_edges
            from chiptwin.dsp.program_pipeline import kinetics_plan

            kinetics_plan(s.chip, Schedule.from_chip(s.chip, s.run.duration_s), window_edges(s),
                          getattr(s.assay, prog.DECAY_KEYS[s.assay.kind]))
    except (ValueError, IndexError) as err:
        stage = "kinetics" if "kinetics" in str(err).lower() else "the program"
        _fail(s, "chip.dsp.program", s.chip.dsp.program,
              f"{stage}: its registers cannot be built: {err}")


def _program_memory(s: Scenario) -> None:
    """What the program holds, plus the largest block of frames the DSP waits for."""
    from chiptwin.dsp import program as prog

    c = s.chip
    costs = prog.stage_costs(c)
    load = prog.program_load(c)
    block = max(c.dsp.n_dark_frames, load.frames_per_job)
    needed = block * c.frame_bits + load.resident_bits
    if c.memory.capacity_bits < needed:
        held = ", ".join(f"{k} {v.memory_bits}" for k, v in costs.items() if v.memory_bits)
        _fail(s, "chip.memory.capacity_bits", c.memory.capacity_bits,
              f"must be ≥ {needed} bits for the DSP program {c.dsp.program}: a block of {block} "
              f"frames × {c.frame_bits} bits + what its stages hold ({held} bits)")
