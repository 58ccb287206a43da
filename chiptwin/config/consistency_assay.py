"""Cross-field rules of ``[assay]`` and ``[sites]``: the template and its flows, the cascade's
rates, the sites on the chip and their amounts (run by
:func:`chiptwin.config.consistency.check_consistency`)."""

from __future__ import annotations

from chiptwin.config.budget import (
    amount_key,
)
from chiptwin.config.consistency_base import _fail, _short
from chiptwin.config.schema import Scenario

BASES = frozenset("ACGT")


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
    _chemistry(s)


#: The flow-value model's keys that change a flow's light (chiptwin.kinetics.chemistry).
FLOW_MODEL_KEYS = ("flow_yield_cv", "flow_noise_sd", "flow_background", "well_noise_cv",
                   "homopolymer_yield_loss", "empty_flow_mean", "empty_flow_sd")


def _chemistry(s: Scenario) -> None:
    """A lognormal empty-flow light has a mean >= 0; the cascade makes its own light per flow
    (the flow-value model scales the closed form's)."""
    a = s.assay
    if a.empty_flow_law == "lognormal" and a.empty_flow_mean < 0:
        _fail(s, "assay.empty_flow_mean", a.empty_flow_mean,
              "must be >= 0 with empty_flow_law = \"lognormal\" (light is not negative); "
              "use \"normal\" for a law whose mean may be below 0")
    if s.run.fidelity.kinetics == "cascade":
        for key in FLOW_MODEL_KEYS:
            if getattr(a, key):
                _fail(s, f"assay.{key}", getattr(a, key),
                      "must be 0 with run.fidelity.kinetics = \"cascade\" (the flow-value "
                      "model scales the closed form's light per flow); use closed_form, or "
                      "no [assay] chemistry")


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
