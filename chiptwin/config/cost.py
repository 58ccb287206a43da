"""How long a run would take and how much it would write, estimated before it starts.

The estimate adds the stage costs the twin already knows from a scenario, each a count times a
cost per unit (:func:`wall_estimate`, term by term):

* **pixel-frames**: every frame, every pixel, every CMS sample is made (moments, and codes at
  the ``binned``/``events`` levels) and read by the DSP at its level (``float``, ``fixed``,
  ``rtl``);
* **chip events**: a fixed cost per frame (the SimPy processes, the trace);
* **filling times** (``events`` level): ``binned``'s draws, and for each site pixel's window
  whose well fills (:func:`window_electrons`: the closed forms' typical light, not the bound)
  the time it filled: one Beta draw and Newton's few evaluations of the light's integral, each
  dearer over the cascade's dense output than over the closed forms;
* **solver** (``cascade`` kinetics): the stiff ODE per flow or per assay window;
* **the converter as built** (any ``[chip.adc]`` effect): its expected moments per pixel-frame,
  by the sawtooth's series, or by a quadrature over exact table sums where the series does not
  apply (:mod:`chiptwin.pixel.expected_adc`), whose cost grows with the white noise's window;
* **footprint profiles**: the light integrated over the sites' footprints, by the ``psf``
  coupling through a stated stack and by the summary's with/without-top figures (``raytrace``
  reads its traced matrix);
* **detection**: per site, and per site and flow of a pyrosequencing run.

A run estimated past ``[run] max_wall_s`` is refused (exit 2) naming the estimate, its largest
term and the key that raises the limit; ``save_frames`` past the free disk of the output folder
likewise (:func:`check_disk`). The estimate is a planning figure: ``tests/config/test_cost.py``
holds it within :data:`ESTIMATE_FACTOR` of measured wall time on bundled scenes.

Calibration: ``benchmarks/bench_estimates.py`` (``python benchmarks/bench_estimates.py``) runs the
scenes below and prints measured against estimated wall time; the constants were measured with it
on the 2-core development machine (Linux, Python 3.11, numba cache warm; recalibrated on
2026-11-25 after the sampler and steady-schedule speed-ups made the first constants 2–77× high),
per scene: pyro_1fmol (1,520 frames × 128 pixels × 8 samples, binned, float DSP: 0.088 s),
pyro_array_256 reduced (500 frames × 65,536 pixels × 8 samples: 9.1 s), ccd_two_wells (336
frames × 512 pixels × 2 samples, fixed DSP and its 7-stage program: 0.85 s),
crosstalk_microarray (56 frames × 128 × 8, fixed: 0.24 s), the events level on pyro_1fmol
(reduced: 0.42 s) and cascade kinetics on pyro_1fmol (8 flows: 0.67 s, a new process 1.1–1.4 s).
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from chiptwin.config.budget import (
    _lognormal_max,
    as_built_quadrature,
    as_built_white_lsb,
    film_bound,
    max_coupling,
    max_dark_e,
    max_site_photons,
    moments_kept,
    n_sites,
)
from chiptwin.config.fields import ScenarioError
from chiptwin.config.schema import Scenario
from chiptwin.config.tiling import simulated_scenario
from chiptwin.constants import N_A, s_to_ticks

#: Per run: scene preparation, coupling, outputs gathered (not the interpreter's start). Unit: s
#: (warm, medians of 3–5, 2026-11-28: snr10_requirement whole at auto 0.005 s; what the other
#: terms leave of atp_glow's 0.018 s 0.012 s, of atp_dose_response's 0.026 s 0.005 s. It was
#: 0.01, twice snr10_requirement's whole run; the 0.05–0.1 s once seen beyond the terms were the
#: optics summary's footprint profiles, now :data:`FOOTPRINT_PROFILE_S`).
RUN_S: float = 0.005
#: Per frame of a chip model run in SimPy (a DSP program, the RTL, a memory or DSP that does not
#: keep up): the events (reset, integrate, convert, write, DSP job) and the trace. Unit: s
#: (pyro_1fmol at the expected level with a kinetics program: 0.18 s over 1,520 frames).
FRAME_S: float = 1.0e-4
#: Per frame of a run known ahead (:func:`chiptwin.chip.steady.steady_run`: the default DSP
#: chain, the memory and the DSP keeping up): the closed-form schedule and the trace. Unit: s
#: (pyro_paper_yield_fast at auto: 2.2–5.4 s over 192,256 frames, the machine shared).
STEADY_FRAME_S: float = 1.5e-5
#: Per pixel-sample of a frame made and read by the float DSP (moments, Poisson draws, codes).
#: Unit: s (pyro_array_256 reduced: 9.1 s / (500 × 65,536 × 8); whole at auto, binned, 51–70 s
#: over 7.97e8 on the shared 2-core machine; the expected level: at most pyro_paper_yield's
#: whole 0.013–0.033 s over 1.56e6).
PIXEL_SAMPLE_S: dict[str, float] = {"expected": 8.0e-9, "binned": 5.0e-8, "events": 5.0e-8}
#: Per pixel-sample at each DSP level, beyond the float level's. Unit: s. ``fixed``, a program in
#: SimPy and its figures in the summary (warm, 2026-11-28, the program's dsp, memory and
#: detection stages): ccd_two_wells at auto 0.12 s over 336 × 1,024 pixel-samples (its
#: 7-stage program; the whole run 0.21–0.49 s as the shared machine's load varied, estimated
#: 1.27 s at 3e-6) and crosstalk_microarray 0.053 s over 56 × 1,024 (whole 0.065–0.40 s).
#: ``rtl``: NOT measured here (no simulator on the calibration path); a stated guess of 100×
#: the fixed level's first calibration (2.2e-5 s), so that an RTL co-simulation of a long run is
#: refused rather than let run.
DSP_PIXEL_SAMPLE_S: dict[str, float] = {"float": 0.0, "fixed": 1.0e-6, "rtl": 2.2e-3}
#: The same for the default chain (cms, dark, background, average) at ``fixed``: its numba
#: kernel, no program in SimPy. Unit: s (at most 0.047 s of atp_glow's whole reference run over
#: 82,000 pixel-samples, and of pyro_1fmol's 2.6 s over 1.56e6; 3e-6 said 0.25 s and 4.7 s).
DSP_DEFAULT_FIXED_S: float = 1.0e-7
#: The events level, per window: the filling times' bookkeeping over the drawn counts. Unit: s
#: (ccd_100fmol at its reference levels, no well filling: 0.011 s over 1,516 windows beside
#: binned).
EVENTS_WINDOW_S: float = 1.0e-5
#: Per site pixel and window whose well fills at the events level: a Beta draw, Λ(T) and
#: Newton's ≈ 3 evaluations of Λ (one light-source integral a pixel each). Unit: s, by kinetics
#: level (closed form: pyro_1fmol at 300 fmol, 8 flows, 180 windows filled, 0.23 ms each beside
#: binned; the cascade's dense output costs ≈ 4× the closed forms' per integral, as the site
#: pixels' integrals did when every window was integrated: 0.12 ms against 0.5 ms).
EVENTS_FILL_S: dict[str, float] = {"closed_form": 2.5e-4, "cascade": 1.0e-3}
#: The cascade's yield fit, once a process (``twin.stages._fitted_yield``), and its stiff solver
#: per assay window (a flow). Unit: s (warm, the fit's cache emptied, median of 5, 2026-11-28:
#: the fit 0.148 s on pyro_1fmol, 0.042 s on ccd_100fmol; the solver 0.0036–0.0044 s a flow on
#: both, 8 and 25 flows of 18 bases. They were 0.8 and 0.03: ccd_100fmol at auto estimated
#: 1.60 s, measured 0.19 s. A new process's first run adds ≈ 1 s of loading).
CASCADE_FIT_S: float = 0.15
CASCADE_WINDOW_S: float = 0.004
#: The template CASCADE_WINDOW_S was measured on (pyro_1fmol's 18 bases); the solver's state
#: holds a strand share per template position, and a window costs in proportion: 0.052 s a
#: flow over 16 flows of a 400-base template (0.004 × 401/19 = 0.084; 0.58 s a flow before).
CASCADE_BASES = 18
#: Per pixel-frame of the converter-as-built's expected moments by the sawtooth's series (the
#: signal side's E_y[v] and the true-CDS covariance). Unit: s (pyro_1fmol with a 1-LSB
#: comparator at the expected level: 0.27 s over 194,560 pixel-frames).
AS_BUILT_SERIES_S: float = 1.4e-6
#: Per pixel-frame, pass and square of the series' harmonics (``series_harmonics``: its square's
#: double sum): 51–73 ns measured from 2 to 96 harmonics (0.29 µs an element at 1 LSB of white
#: noise, 472 µs at 1/64 LSB, where a mutated scene once ran for over 16 minutes on an estimate
#: of seconds). Unit: s.
AS_BUILT_HARMONIC_S: float = 5.5e-8
#: Per pixel-frame, pass and node of the same moments by the quadrature (a transition table, a
#: dark level within reach of code 0, white noise below 1/64 LSB), and per code summed there.
#: Unit: s. Fitted to pyro_1fmol with DNL 0.2 LSB rms (194,560 pixel-frames, 2 passes; the
#: pixel stage's time, one run each): 16.8 s (192 nodes, 7 codes) and, with a 2-LSB comparator,
#: 24.6 s (48 nodes, 45 codes). Before the window came from the search LUT and the reset side
#: was summed once per pixel: 1.7e-7 and 3.5e-8 (31 s for the first). With the trapezoid
#: quadrature's nodes (79 for the first: chiptwin.pixel.expected_adc) it estimates 6.9 s of the
#: pixel stage's measured 7.8 s.
AS_BUILT_NODE_S: float = 2.2e-8
AS_BUILT_CODE_S: float = 2.9e-8
#: Per pixel-frame, pass and node near the range's ends from 3 LSB of white rms on the ideal
#: transitions: the moments' closed form (chiptwin.pixel.adc._end_moments) instead of a window
#: of codes, with :data:`AS_BUILT_NODE_S`. Unit: s (ccd_two_wells, a 256-LSB comparator: the
#: pixel stage's 6.1 s over 2 passes × 48 nodes × 172,032 pixel-frames, one run).
AS_BUILT_END_S: float = 3.5e-7
#: Per angle, wavelength, polarisation and film group of a profile through thin films
#: (``thinfilm.band_product``), and the distinct profiles a run builds through them
#: (``build_profile`` keeps them): the summary's emitter-law shares, isotropic and lambertian,
#: at every level and under every law of contact imaging; under a physical law the coupling
#: shares one of them and the thin-film figure adds the stack as rays alone (3 in pyro_1fmol
#: with 0.1 µm of nitride, a 1.25 s run); under ``lambertian_na2`` 2. Unit: s (0.52 s over
#: 36,864 angles × 33 wavelengths × 2, 14 s with 874 wavelengths).
FILM_ELEMENT_S: float = 2.1e-7
FILM_PROFILES: int = 3
#: Profiles a top that returns light adds through thin films: one per part of the returned light
#: (air 1; a lid 2: its front face, and through it), built for the coupling and shared by the
#: summary's figures (``chiptwin.optics.top.Top.parts``).
TOP_PARTS: dict[str, int] = {"solution": 0, "air": 1, "glass": 2}
FILM_PROFILE_ANGLES: int = 36_864
#: Per profile of the light integrated over the sites' footprint and the diodes
#: (``chiptwin.optics.coupling_stack`` with a footprint: the disc's profile, a part of a top's
#: returned light split at the top's critical angle): one profile, and one per part of a top's
#: returned light (``TOP_PARTS``). The ``psf`` level's coupling through a stated stack under a
#: physical law makes 1 + parts of them; the summary's with/without-top figures 2 + parts at
#: every level (``raytrace`` reads its traced matrix instead: ≈ 1 ms). Unit: s (warm, median of 3,
#: the coupling and the top figures timed alone, per profile: luciferase_label's 10 µm
#: footprints 0.038–0.050 s (no top, air, glass), pyro_1fmol's 20 µm 0.065–0.089 s,
#: jssc2006_faceplate's and pyro_long_read's 0.053–0.078 s; luciferase_label whole at auto's
#: other levels: 0.257 s at psf, 0.153 s at raytrace, 2026-11-28). Not counted: the sparse
#: coupling's kernel (above :data:`chiptwin.limits.DENSE_COUPLING_ENTRIES`) grown to the array
#: under a lid, pyro_array_256's 6.2 s at psf (0.33 s at raytrace).
FOOTPRINT_PROFILE_S: float = 0.06
#: The factor within which the estimate is held of measured wall time (tests/config/test_cost.py).
ESTIMATE_FACTOR: float = 10.0
#: Per worker of a study's process pool: spawn, import numpy/numba/chiptwin, load the kernels.
#: Unit: s (the small study of tests/study: 40 rows on 2 workers, ≈ 4 s before the first row).
WORKER_START_S: float = 4.0
# A study's rows go to its workers in tasks (chiptwin.study.execute):
#: Seconds of rows one task aims at. A task costs the Dask scheduler about a millisecond and the
#: client one future and one message (the pool: one pickled message each way); at a few seconds
#: a task that is under 0.1 % of its rows' time, while an interrupted study loses at most
#: ``in_flight`` tasks of work and the study's last tasks end within seconds of each other.
TASK_TARGET_S: float = 2.0
#: Rows a task holds at most (``--rows-per-task``): its rows travel back in one message, and an
#: interrupted task loses them all.
MAX_ROWS_PER_TASK: int = 10_000
#: Tasks out at once per worker: one running, one queued behind it, so a worker never waits
#: for the client between two tasks.
IN_FLIGHT_PER_WORKER: int = 2
#: Tasks in flight at most (``--in-flight``): each is a future the client holds.
MAX_IN_FLIGHT: int = 10_000
#: Seconds a Dask cluster may take to show its first worker (``--worker-timeout``) by default:
#: a local or running cluster has workers within seconds; a batch queue's may wait longer
#: (raise it there).
WORKER_TIMEOUT_S: float = 60.0
#: ``--worker-timeout`` at most: a day, longer than any batch queue's wait worth sitting through.
MAX_WORKER_TIMEOUT_S: float = 86_400.0
#: Free disk kept beyond ``save_frames``' file (outputs, plots, the temporary folder). Unit: B.
DISK_MARGIN_BYTES: int = 64 << 20


@dataclass(frozen=True)
class CostTerm:
    """One term of the estimate: what it counts, its seconds, and the keys that set its size.
    ``per_scene``: paid when the scene is prepared (kinetics, optics, the summary's optical
    figures), which a study's replicates of one point share (:func:`row_seconds`)."""

    what: str
    seconds: float
    keys: str
    per_scene: bool = False


def _level(s: Scenario, stage: str, default: str, order: tuple[str, ...]) -> str:
    """The level in force (``auto``: the cheapest it may pick, so nothing is refused on a guess)."""
    level = getattr(s.run.fidelity, stage) or default
    return order[0] if level == "auto" else level


#: The detection per site (window sums, the site's figures) and, in a pyrosequencing run, per
#: site and flow (flow values, the base calls). Unit: s (warm, results.detect less the optics
#: summary, median of 5: atp_dose_response 3.3 ms at 64 sites, 1.1 ms at 4; pyro_1fmol with a
#: site on each of 128 pixels 0.116 s over 8 flows, 0.190 s over 25, 7.7 ms with 2 sites).
DETECT_SITE_S: float = 4.0e-5
DETECT_SITE_FLOW_S: float = 6.0e-5
#: The callers' cost per read and flow (chiptwin.detection.reads.read_model: phasing search,
#: sweeps, hill climb, averaged posterior; ``dephase`` calls from it, ``round`` states its
#: qualities from the same posterior, so both pay it): pyro_long_read, 128 reads × 400
#: flows, 1.13–1.18 s on one core of a quiet 2-core machine (2.2e-5 s a read-flow;
#: benchmarks/bench_long_reads.py), rounded up for a loaded one. Unit: s.
DEPHASE_FLOW_S = 3.0e-5


def n_frames(s: Scenario) -> int:
    return s_to_ticks(s.run.duration_s) // s_to_ticks(s.chip.timing.frame_period_s)


def _windows(s: Scenario) -> int:
    a = s.assay
    return a.n_flows if a.kind == "pyrosequencing" else 1


#: The physical law's comparison beside a paper-convention scene (``chiptwin.twin.physical_law``)
#: is left out above this many seconds for its two runs. Unit: s.
PHYSICAL_LAW_MAX_S: float = 5.0
#: The emitter law of molecules in solution that the comparison puts in place of the paper's NA²
#: convention (the dipole pattern's orientation average).
PHYSICAL_LAW: str = "isotropic"


def physical_law_applies(s: Scenario) -> bool:
    """A contact scene with light from sites under the paper's NA² convention: its run reports
    beside it what the physical law would read (``summary['physical_law']``)."""
    return (s.optics.law == "lambertian_na2" and s.optics.coupling == "contact"
            and s.assay.kind != "flux")


def law_comparison(s: Scenario) -> tuple[Scenario, Scenario]:
    """The comparison's two runs: the scene at the ``expected`` photon level with the float DSP
    (means and variances, no draws), under the convention and under :data:`PHYSICAL_LAW`."""
    at = replace(s.run.fidelity, photons="expected", shot="poisson", dsp="")
    base = replace(s, run=replace(s.run, fidelity=at),
                   chip=replace(s.chip, dsp=replace(s.chip.dsp, mode="float")))
    physical = replace(base, optics=replace(base.optics, emitter=PHYSICAL_LAW,
                                            convention="lambertian_na2"))
    return base, physical


def law_comparison_seconds(pair: tuple[Scenario, Scenario]) -> float:
    """The estimated seconds of :func:`law_comparison`'s two runs (pyro_paper_yield at psf:
    0.022 s and, its isotropic footprint profile, 0.117 s)."""
    return sum(t.seconds for sc in pair for t in wall_estimate(sc, beside=False))


def wall_estimate(s: Scenario, beside: bool = True) -> list[CostTerm]:
    """The run's wall time, term by term. Unit: s. ``beside``: with the physical law's two
    expected-level runs a paper-convention scene adds (``summary['physical_law']``). A tiled
    run (``[run] tile``) is estimated on the pixels and sites it simulates."""
    terms = _own_terms(simulated_scenario(s))
    if beside and s.run.beside_physical_law and physical_law_applies(s):
        two = law_comparison_seconds(law_comparison(s))
        if two <= PHYSICAL_LAW_MAX_S:  # as chiptwin.twin.physical_law.beside decides
            terms.append(CostTerm("the physical law beside the paper's convention: two runs at "
                                  "the expected level, the convention's and the isotropic "
                                  "law's", two, "run.beside_physical_law"))
    return terms


def _own_terms(s: Scenario) -> list[CostTerm]:
    """The terms of the run itself."""
    c = s.chip
    frames = n_frames(s)
    photons = _level(s, "photons", "binned", ("expected", "binned", "events"))
    dsp = s.dsp_level if s.dsp_level != "auto" else "float"
    kinetics = _level(s, "kinetics", "closed_form", ("closed_form", "cascade"))
    ps = frames * c.n_pixels * c.samples_per_frame
    length = "run.duration_s / chip.timing.frame_period_s"
    frame_s, how = (STEADY_FRAME_S, "in closed form") if _steady(s) else (FRAME_S, "in SimPy")
    terms = [
        CostTerm("scene and outputs", RUN_S, ""),
        CostTerm(f"{frames} frames of chip events {how} × {frame_s:g} s", frames * frame_s,
                 length),
        CostTerm(f"{ps:.3g} pixel-samples ({photons}) × {PIXEL_SAMPLE_S[photons]:g} s",
                 ps * PIXEL_SAMPLE_S[photons],
                 f"{length}, chip.rows × chip.cols, chip.dsp.cms_samples"),
    ]
    dsp_s = DSP_PIXEL_SAMPLE_S[dsp]
    if dsp == "fixed" and _default_chain(s):
        dsp_s = DSP_DEFAULT_FIXED_S
    if dsp_s:
        terms.append(CostTerm(f"{ps:.3g} pixel-samples through the {dsp} DSP × {dsp_s:g} s",
                              ps * dsp_s, "run.fidelity.dsp (or chip.dsp.mode), " + length))
    if photons == "events":
        terms.append(_events_term(s, kinetics, frames, length))
    if c.adc.as_built_keys:  # moments a scene keeps are made once for its replicates
        term = _as_built_term(s, frames * _moment_pixels(s, photons))
        terms.append(replace(term, per_scene=moments_kept(c.n_pixels, frames)))
    if s.run.fidelity.auto_stages():  # calibrations not yet cached: the scene at the expected
        expected = ps * PIXEL_SAMPLE_S["expected"]  # level once, its converter as built too
        as_built = _as_built_term(s, frames * c.n_pixels).seconds if c.adc.as_built_keys else 0
        terms.append(CostTerm("fidelity auto's calibration, uncached: the scene at the expected "
                              "level (its pixel-samples and converter as built)",
                              expected + as_built,
                              "run.fidelity (auto), " + length + ", chip.rows × chip.cols",
                              per_scene=True))
    groups, nodes = film_bound(s)
    if groups and s.optics.coupling == "contact" and s.assay.kind != "flux":
        profiles = FILM_PROFILES if s.optics.law != "lambertian_na2" else FILM_PROFILES - 1
        profiles += TOP_PARTS[s.optics.top.medium]
        elements = profiles * FILM_PROFILE_ANGLES * nodes * 2 * groups
        terms.append(CostTerm(f"{profiles} profiles through {groups} thin film(s): "
                              f"{FILM_PROFILE_ANGLES} angles × {nodes} wavelengths × 2 × "
                              f"{FILM_ELEMENT_S:g} s", elements * FILM_ELEMENT_S,
                              "optics.layers, optics.thin_film_um, optics.band_fwhm_nm, "
                              "optics.top.medium", per_scene=True))
    terms += _footprint_terms(s)
    terms.append(_detection_term(s))
    if s.assay.kind == "pyrosequencing":
        sites = n_sites(s)
        flows = s.assay.n_flows
        terms.append(CostTerm(f"the {s.assay.caller} caller: {sites} reads × {flows} flows × "
                              f"{DEPHASE_FLOW_S:g} s", sites * flows * DEPHASE_FLOW_S,
                              "assay.caller, assay.n_flows, sites.at_pixels"))
    if kinetics == "cascade":
        w = _windows(s)
        per = CASCADE_WINDOW_S * max(1.0, (len(s.assay.template) + 1) / (CASCADE_BASES + 1))
        fit = CASCADE_FIT_S if s.assay.photons_per_incorporation else 0.0  # no yield: no fit
        terms.append(CostTerm(f"the cascade's yield fit, {fit:g} s, and {w} windows of "
                              f"its stiff solver × {per:.3g} s",
                              fit + w * per,
                              "run.fidelity.kinetics, assay.n_flows", per_scene=True))
    return terms


def _detection_term(s: Scenario) -> CostTerm:
    """The detection of every site (:data:`DETECT_SITE_S`), and of its flows in a
    pyrosequencing run (:data:`DETECT_SITE_FLOW_S`)."""
    sites = n_sites(s)
    flows = s.assay.n_flows if s.assay.kind == "pyrosequencing" else 0
    what = f"the detection: {sites} sites × ({DETECT_SITE_S:g} s"
    what += f" + {flows} flows × {DETECT_SITE_FLOW_S:g} s)" if flows else ")"
    return CostTerm(what, sites * (DETECT_SITE_S + flows * DETECT_SITE_FLOW_S),
                    "sites.at_pixels" + (", assay.n_flows" if flows else ""))


def _footprint_terms(s: Scenario) -> list[CostTerm]:
    """The light's profiles integrated over the sites' footprints (:data:`FOOTPRINT_PROFILE_S`):
    the ``psf`` coupling's through a stated stack under a physical law, and the summary's
    with/without-top figures."""
    parts = TOP_PARTS[s.optics.top.medium]
    if s.sites.footprint_radius_um <= 0 or s.optics.coupling != "contact" or s.assay.kind == "flux":
        return []
    keys = "optics.top.medium, sites.footprint_radius_um"
    terms = []
    optics = _level(s, "optics", "psf", ("na2", "psf", "raytrace"))
    if optics == "psf" and s.optics.stated_stack and s.optics.law != "lambertian_na2":
        terms.append(CostTerm(f"the psf coupling through the stack: {1 + parts} profile(s) over "
                              f"the sites' footprints × {FOOTPRINT_PROFILE_S:g} s",
                              (1 + parts) * FOOTPRINT_PROFILE_S, "run.fidelity.optics, " + keys,
                              per_scene=True))
    if parts:
        terms.append(CostTerm(f"the summary's top figures: {2 + parts} profiles over a site's "
                              f"footprint × {FOOTPRINT_PROFILE_S:g} s",
                              (2 + parts) * FOOTPRINT_PROFILE_S, keys, per_scene=True))
    return terms


def _events_term(s: Scenario, kinetics: str, frames: int, length: str) -> CostTerm:
    """The events level beside ``binned``: every window's bookkeeping, and the filling time of
    each site pixel's window whose well fills (:func:`window_electrons` per site pixel)."""
    sites = n_sites(s)
    filled = int(np.sum(window_electrons(s, frames) / sites >= s.chip.pixel.full_well_e)) * sites
    seconds = frames * EVENTS_WINDOW_S + filled * EVENTS_FILL_S[kinetics]
    return CostTerm(f"{frames} windows × {EVENTS_WINDOW_S:g} s and {filled} site-pixel windows "
                    f"whose well fills × {EVENTS_FILL_S[kinetics]:g} s", seconds,
                    f"run.fidelity.photons, run.fidelity.kinetics, sites.at_pixels, {length}")


def window_electrons(s: Scenario, frames: int) -> np.ndarray:
    """The expected electrons of all site pixels in each frame's window, as the events level
    meets them (typical, not a bound): a site's light by the closed forms (Salama et al. 2004:
    a pyrosequencing flow's 1-mer decays as ``e^{−k_a t}`` from the flow's start, an ATP glow as
    ``e^{−k t}``, the rest constant at :func:`~chiptwin.config.budget.max_site_photons`), times
    the site's own pixel's share (:func:`site_pixel_share`), QE and the sites, plus the site
    pixels' mean dark charge. Unit: e⁻."""
    a, c, px = s.assay, s.chip, s.chip.pixel
    t = np.arange(frames) * c.timing.frame_period_s - a.start_s  # window starts, light-relative
    gain = site_pixel_share(s) * px.qe * n_sites(s)
    dark = max_dark_e(s) / _lognormal_max(px.dsnu_frac, c.n_pixels) * n_sites(s)  # mean pixel
    return dark + _light_electrons(s, frames, t, gain)


def _light_electrons(s: Scenario, frames: int, t: np.ndarray, gain: float) -> np.ndarray:
    a, period, t_int = s.assay, s.chip.timing.frame_period_s, s.chip.timing.t_int_s
    if a.kind == "pyrosequencing":
        y = a.photons_per_incorporation or a.quantum_yield * a.k_t_per_s / a.k_a_per_s
        k, total = a.k_a_per_s, a.dna_fmol * 1e-15 * N_A * y
        t = np.mod(t, a.flow_period_s)
    elif a.kind == "atp":
        k, total = a.turnover_per_s, a.atp_fmol * 1e-15 * N_A * a.quantum_yield
    else:
        e = np.full(frames, max_site_photons(s) * gain)
        e[t < 0] = 0.0
        return e
    e = total * np.exp(-k * np.maximum(t, 0.0)) * -np.expm1(-k * t_int) * gain
    e[np.arange(frames) * period < a.start_s] = 0.0
    return e


def site_pixel_share(s: Scenario) -> float:
    """The share of a site's photons its own pixel gets, for the estimate: under contact
    imaging twice the diode's solid angle from the site over 4π (a Lambertian emitter's
    on-axis intensity is twice an isotropic one's; a rectangle's solid angle seen from a point
    on its axis, ``4·asin(ab / √((a² + 4h²)(b² + 4h²)))``), at most
    :func:`~chiptwin.config.budget.max_coupling`; 0.0079 at ccd_two_wells' 150 µm, where the
    bound says 0.5."""
    bound = max_coupling(s)
    if s.optics.coupling != "contact" or s.assay.kind == "flux":
        return bound
    w, h, z = s.chip.pixel.diode_w_um, s.chip.pixel.diode_h_um, s.sites.height_um
    omega = 4 * math.asin(w * h / math.sqrt((w * w + 4 * z * z) * (h * h + 4 * z * z)))
    return min(bound, 2 * omega / (4 * math.pi) * s.optics.transmission)


def _as_built_term(s: Scenario, pixel_frames: int) -> CostTerm:
    """The converter-as-built's expected moments: by the series, or by the quadrature where
    :func:`~chiptwin.config.budget.as_built_quadrature` says (its nodes, by the kTC's ratio
    to ``u``; an element with a wider shot noise takes more) over a window of ±10 ``u``, or
    from 3 LSB of ``u`` on the ideal transitions the ends' closed form instead of the window."""
    from chiptwin.pixel.adc import END_CLOSED_FROM_LSB

    a = s.chip.adc
    keys = "chip.adc (" + ", ".join(a.as_built_keys) + "), chip.pixel.read_noise_e"
    q = as_built_quadrature(s)
    if q is not None:
        if q.table or q.u < END_CLOSED_FROM_LSB:
            codes = 2 * math.ceil(10.0 * q.u) + 3
            each = AS_BUILT_NODE_S + codes * AS_BUILT_CODE_S
            what = f"{codes} codes × {AS_BUILT_CODE_S:g} s"
        else:  # near code 0 the moments' closed form, not a window of codes
            each = AS_BUILT_NODE_S + AS_BUILT_END_S
            what = f"the ends' closed form {AS_BUILT_END_S:g} s"
        return CostTerm(f"{pixel_frames:.3g} pixel-frames of the converter as built by "
                        f"quadrature: 2 passes × {q.nodes} nodes × ({AS_BUILT_NODE_S:g} s + "
                        f"{what})", pixel_frames * 2 * q.nodes * each, keys)
    from chiptwin.pixel.expected_adc import series_harmonics

    k = series_harmonics(as_built_white_lsb(s))
    each = AS_BUILT_SERIES_S + 2 * k * k * AS_BUILT_HARMONIC_S
    return CostTerm(f"{pixel_frames:.3g} pixel-frames of the converter as built by the series × "
                    f"({AS_BUILT_SERIES_S:g} s + 2 × {k}² harmonics × {AS_BUILT_HARMONIC_S:g} s)",
                    pixel_frames * each, keys)


def moments_at_kept_pixels(s: Scenario, photons: str) -> bool:
    """Whether a run that keeps its outputs at some pixels (a study's sites) computes the CMS
    moments there only: codes are drawn (``binned``, ``events``) and today's chain runs without
    ``report_error``. Elsewhere the moments are read at every pixel: they are the values at the
    ``expected`` level, a DSP program mixes pixels, the fixed-vs-float error statistics span
    every pixel. The one rule of :func:`chiptwin.twin.runner.moments_read_at` (which also reads
    every pixel's where the codes are kept for a co-simulation) and of this estimate's converter
    term; the DSP's level does not enter (float, fixed and the RTL read the same codes)."""
    return (photons in ("binned", "events") and _default_chain(s)
            and not s.chip.dsp.report_error)


def _moment_pixels(s: Scenario, photons: str) -> int:
    """Pixels whose converter-as-built moments a run computes: the sites' pixels where
    :func:`moments_at_kept_pixels`, else every pixel."""
    at = s.sites.at_pixels
    if not moments_at_kept_pixels(s, photons) or at == "all":
        return s.chip.n_pixels
    return 1 if at == "centre" else len({tuple(rc) for rc in at})


def _default_chain(s: Scenario) -> bool:
    from chiptwin.dsp.program import is_default

    return is_default(s.chip.dsp.program)


def _steady(s: Scenario) -> bool:
    """The chip model runs in closed form (as :func:`chiptwin.twin.runner.simulate` decides): the
    default DSP chain below the RTL and a schedule :func:`~chiptwin.chip.steady.steady_run`
    takes."""
    from chiptwin.chip.des import Schedule
    from chiptwin.chip.steady import steady_run
    from chiptwin.dsp.program import is_default

    if not is_default(s.chip.dsp.program) or s.dsp_level == "rtl":
        return False
    return steady_run(Schedule.from_chip(s.chip, s.run.duration_s), frame_steps=True) is not None


def row_seconds(s: Scenario, rows_per_scene: int) -> float:
    """A study row's seconds: the run's own terms, and the scene's preparation shared by
    ``rows_per_scene`` rows (a point's replicates, which each process keeps prepared:
    ``chiptwin.study.rows``). Unit: s (adc_bits_pyro as built, 14 bits, 0.5 LSB₁₃ comparator:
    0.53 s a run, 0.42 s of it the scene's footprint profiles; its rows measured 0.081 s each,
    3,310 in 266.6 s)."""
    terms = wall_estimate(s)
    share = 1.0 / max(1, int(rows_per_scene))
    return sum(t.seconds * (share if t.per_scene else 1.0) for t in terms)


def wall_seconds(s: Scenario) -> float:
    """The estimate's total. Unit: s."""
    return sum(t.seconds for t in wall_estimate(s))


def disk_bytes(s: Scenario) -> int:
    """What ``save_frames`` writes (the frames, uncompressed: streamed to a temporary file during
    the run, then into ``run.nc``): 0 when it is off. Unit: bytes."""
    if not s.run.save_frames:
        return 0
    c = s.chip
    photons = _level(s, "photons", "binned", ("expected", "binned", "events"))
    if photons == "expected":
        per = 8 * c.n_pixels  # float64 means
    else:
        per = (2 if c.adc.bits <= 16 else 4) * c.samples_per_frame * c.n_pixels
    return n_frames(s) * per


def describe(s: Scenario) -> list[str]:
    """The estimate as lines for ``chiptwin validate``."""
    total = wall_seconds(s)
    lines = [f"estimated wall time ≈ {format_seconds(total)} (limit run.max_wall_s = "
             f"{format_seconds(s.run.max_wall_s)}; within {ESTIMATE_FACTOR:g}× either way):"]
    lines += [f"  {t.seconds:9.3g} s  {t.what}" for t in wall_estimate(s) if t.seconds > 0]
    if s.run.save_frames:
        lines.append(f"save_frames writes ≈ {disk_bytes(s) / 1e9:.3g} GB (the frames in run.nc)")
    return lines


def format_seconds(t: float) -> str:
    if not math.isfinite(t):
        return str(t)
    if t < 120:
        return f"{t:.3g} s"
    if t < 7200:
        return f"{t / 60:.3g} min"
    return f"{t / 3600:.3g} h"


def check_wall_time(s: Scenario) -> None:
    """Refuse a run estimated past ``[run] max_wall_s`` (exit 2 from the CLI, an invalid point in
    a study), naming the estimate, its largest term and the key that raises the limit."""
    terms = wall_estimate(s)
    total = sum(t.seconds for t in terms)
    if total <= s.run.max_wall_s:
        return
    big = max(terms, key=lambda t: t.seconds)
    raise ScenarioError(
        s.source, "run.max_wall_s", s.run.max_wall_s,
        f"the run is estimated at ≈ {format_seconds(total)} (most of it {big.what} = "
        f"{format_seconds(big.seconds)}; set by {big.keys}); raise run.max_wall_s (e.g. "
        f"--set run.max_wall_s={math.ceil(2 * total)}) or make those smaller")


def check_disk(s: Scenario, out: Path) -> None:
    """Refuse ``save_frames`` when the frames would not fit on the output folder's disk."""
    need = disk_bytes(s)
    if not need:
        return
    folder = next((p for p in [out, *out.parents] if p.exists()), Path("."))
    free = shutil.disk_usage(folder).free
    if need + DISK_MARGIN_BYTES > free:
        raise ScenarioError(s.source, "run.save_frames", True,
                            f"the frames would take ≈ {need / 1e9:.3g} GB, the disk of {folder} "
                            f"has {free / 1e9:.3g} GB free; free some, choose another --out, "
                            "or set run.save_frames = false")


__all__ = ["CostTerm", "check_disk", "check_wall_time", "describe", "disk_bytes",
           "wall_estimate", "wall_seconds"]
