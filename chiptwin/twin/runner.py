"""``run(scenario, overrides, seed)``: the one entry point the CLI and the Python API share.

The run goes through :data:`chiptwin.STAGES` in order: the light of every site over every
integration window (kinetics), onto the pixels (optics), through the chip model (pixel, ADC, frame
memory and DSP as SimPy events), to per-site estimates (detection). Each stage draws from its own
named random stream (:func:`stage_rng`), so adding a stage never shifts another's numbers.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin import __version__
from chiptwin.chip import ChipRun, Recorder, Schedule, SteadyRun, simulate_chip, steady_run
from chiptwin.config import Scenario, load_scenario, reference_chip
from chiptwin.config.consistency import check_consistency, scenario_warnings
from chiptwin.config.cost import moments_at_kept_pixels
from chiptwin.constants import TICKS_PER_S
from chiptwin.detection import SNR_DEFINITION, required_signal_e, window_sums
from chiptwin.dsp.pipeline import BlockOut, FrameStack, Pipeline, chain_for
from chiptwin.dsp.program import is_default
from chiptwin.twin import levels, physical_law, shortcuts, stages, tile
from chiptwin.twin.frame_reader import FrameReader, frames_file
from chiptwin.twin.results import detect, light_decay_per_s
from chiptwin.twin.scene import ChainOutput, Scene, StageTimer, stage_rng


@dataclass
class Result:
    """A finished run: the summary (as in ``summary.json``), the arrays, and the event trace."""

    summary: dict[str, Any]
    arrays: dict[str, np.ndarray]
    trace: Recorder
    scenario: Scenario
    #: ``[run] save_frames``: every frame as read, a ``.npy`` file in the temporary folder
    #: (:func:`chiptwin.report.write_outputs` copies it into the run's dataset, ``run.nc``, and
    #: removes it).
    frames_path: Path | None = None


def run(
    scenario: Scenario | str | Path,
    overrides: Iterable[str] = (),
    seed: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    resolve: Callable[[Scenario], tuple[Scenario, levels.AutoChoice | None]] | None = None,
) -> Result:
    """Run a scenario end to end.

    Parameters
    ----------
    scenario : Scenario, or a path to a TOML file
    overrides : ``"section.key=value"`` strings (only with a path)
    seed : replaces ``scenario.seed``
    progress : ``progress(frames_done, n_frames)``, called once per frame
    resolve : resolves the ``auto`` fidelity keys (default :func:`chiptwin.twin.levels.resolve`,
        from cached estimates only; :func:`chiptwin.fidelity.run` passes the resolver that
        runs the calibrations the cache lacks)
    """
    t_start = time.perf_counter()
    if isinstance(scenario, Scenario):
        if overrides:
            raise TypeError("overrides apply to scenario files; use dataclasses.replace here")
        s = scenario if seed is None else replace(
            scenario, scenario=replace(scenario.scenario, seed=seed))
    else:
        s = load_scenario(scenario, overrides, seed)
    check_consistency(s)  # a Scenario built or replaced in Python meets the file's rules too
    s, choice = (resolve or levels.resolve)(s)
    timer = StageTimer()
    result = run_prepared(s, prepare(s, timer), timer, progress, t_start, choice)
    if physical_law.applies(s):  # the paper's convention: the physical law's answer beside it
        with timer("physical_law"):
            result.summary["physical_law"] = physical_law.beside(
                s, lambda sc: run_prepared(sc, prepare(sc)).summary)
        result.summary["stage_time_s"]["physical_law"] = round(timer.seconds["physical_law"], 6)
        result.summary["wall_time_s"] = round(time.perf_counter() - t_start, 6)
    return result


def run_prepared(s: Scenario, scene: Scene, timer: StageTimer | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 t_start: float | None = None, choice: levels.AutoChoice | None = None,
                 frame_steps: bool = True) -> Result:
    """The chip model and the detection for a scene :func:`prepare` made of ``s``.

    A study prepares a point once and calls this per replicate with ``s`` carrying the
    replicate's seed: the result is bit for bit the one :func:`run` gives for that seed (the
    random draws all happen here, from ``s.scenario.seed``'s named streams). ``s`` has no
    ``auto`` level left (:func:`chiptwin.fidelity.auto.resolve`); ``choice``, what resolved them,
    goes in the summary. ``frame_steps=False`` records the trace without each frame's reset and
    conversion steps (:class:`~chiptwin.chip.Recorder`; the same outputs, fewer events).
    """
    _check_resolved(s)
    t_start = time.perf_counter() if t_start is None else t_start
    timer = timer or StageTimer()
    rec = Recorder(frame_steps=frame_steps)
    frames_path = frames_file() if s.run.save_frames else None
    tiled = scene.tile  # a tiled run reads its simulated sites as a scenario of their own
    s_run = s if tiled is None else tiled.simulated(s)
    out = simulate(s_run, scene, s.run.fidelity.photons, stage_rng(s.scenario.seed, "pixel"),
                   rec, timer, progress, sites=stages.site_pixel_indices(s_run),
                   frames_path=frames_path)
    with timer("detection"):
        summary, arrays = detect(s_run, scene, out)
        if tiled is not None:
            tile.scale(s, tiled, scene.tile_section, scene.sch, out, summary, arrays)
        elif scene.tile_section is not None:  # "auto" on a scene it cannot tile
            summary["tiled"] = scene.tile_section
        if s.assay.kind == "flux":
            idx = stages.site_pixel_indices(s)
            summary["required_flux_photons_per_s_per_um2"] = _required_flux(s, idx)
            summary["required_flux_snr_power"] = s.run.detection_snr_power
    summary.update(
        scenario=s.scenario.name, description=s.scenario.description, seed=s.scenario.seed,
        chiptwin_version=__version__,
        fidelity=fidelity_used(s),
        stage_time_s={k: round(v, 6) for k, v in timer.seconds.items()},
        wall_time_s=round(time.perf_counter() - t_start, 6),
        snr_definition=SNR_DEFINITION,
        warnings=scenario_warnings(s),
        **(choice.summary() if choice else {}),
    )
    summary["assumptions"] = reference_chip.stated(s)
    if s.assay.kind != "flux":
        summary["optics_convention"] = ("paper (NA², Salama et al. 2004 §3.1)"
                                        if s.optics.law == "lambertian_na2" else "physical")
    if s.run.carry_dark_pixels:
        applies = shortcuts.applies(s, s.run.fidelity.photons, out.pixels, False,
                                    frames_path is not None)
        summary["shortcuts"] = {"carry_dark_pixels": {
            "applies": applies, "carried_pixels": int(out.carried_pixels),
            "of_pixels": scene.n_pixels,
            "note": "carried pixels are at the expected level; the sites' outputs have the full "
                    "path's law, not its bits" if applies else
                    "not applied: binned photons, the default DSP program (no rtl, acc_bits, "
                    "report_error) and no save_frames are needed (chiptwin.twin.shortcuts)"}}
    return Result(summary=summary, arrays=arrays, trace=rec, scenario=s, frames_path=frames_path)


def _check_resolved(s: Scenario) -> None:
    auto = s.run.fidelity.auto_stages()
    if auto:
        raise ValueError(f"run.fidelity.{auto[0]} is still \"auto\": resolve it first "
                         "(chiptwin.fidelity.resolve)")


def fidelity_used(s: Scenario) -> dict[str, str]:
    """The level each stage ran at; ``none`` where the scene bypassed it (light given at the
    sensor plane skips kinetics and optics)."""
    flux = s.assay.kind == "flux"
    return {"kinetics": "none" if flux else s.run.fidelity.kinetics,
            "photons": s.run.fidelity.photons,
            "optics": "none" if flux else s.run.fidelity.optics,
            "shot": "none" if s.run.fidelity.photons == "expected" else s.run.fidelity.shot,
            "dsp": s.dsp_level,
            "adc": adc_level(s)}


def adc_level(s: Scenario) -> str:
    """The converter that made the codes: ``as_built`` when ``[chip.adc]`` sets an as-built
    effect and the fidelity keeps it, else ``ideal``."""
    return "as_built" if s.run.fidelity.adc == "as_built" and s.chip.adc.as_built_keys else "ideal"


def prepare(s: Scenario, timer: StageTimer | None = None) -> Scene:
    """Kinetics and optics: photons per site in every integration window, and the site-to-pixel
    coupling. The light per pixel (``coupling @ site_photons``) is made later, a block of frames
    at a time, as the chip model reaches them (:meth:`Scene.pixel_block`)."""
    _check_resolved(s)
    timer = timer or StageTimer()
    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    with timer("optics"):
        tiled = tile.tile(s)  # [run] tile: the simulated sites, their light (None: off)
    plan = tiled.plan if tiled is not None else None
    s_run = s if plan is None else plan.scenario  # whose sites and pixels are simulated
    with timer("kinetics"):
        source = stages.light_source(s_run)
        edges = np.array([sch.window_s(k) for k in range(sch.n_frames)]).reshape(-1)
        # integration windows only (not the gaps between them), as a copy: a strided view would
        # keep the whole (n_sites, 2·n_frames) array alive for the run
        site_photons = np.ascontiguousarray(source.photons(edges)[:, ::2])
    with timer("optics"):
        coupling = stages.coupling(s) if plan is None else tiled.coupling
    scene = Scene(sch, source, site_photons, coupling, chip_sensor(s_run), tile=plan,
                  tile_section=None if tiled is None else tiled.section)
    if plan is not None:  # the whole array's optics figures, not the simulated grid's
        scene.once("optics", lambda: tiled.optics)
    return scene


def chip_sensor(s: Scenario) -> stages.SensorModel:
    """The sensor of this chip: its PRNU/DSNU maps drawn from ``chip.fixed_pattern_seed``, or
    from ``scenario.seed`` when that is -1 (one chip per seed)."""
    chip_seed = s.chip.fixed_pattern_seed if s.chip.fixed_pattern_seed >= 0 else s.scenario.seed
    return stages.sensor_model(s, stage_rng(chip_seed, "fixed_pattern"),
                               stage_rng(chip_seed, "adc_map"))


def simulate(s: Scenario, scene: Scene, photons_level: str, rng: np.random.Generator,
             rec: Recorder, timer: StageTimer | None = None, progress=None,
             keep_codes: bool = False, sites: np.ndarray | None = None,
             frames_path: Path | None = None, carry_dark: bool | None = None) -> ChainOutput:
    """Pixel → ADC → memory → DSP through the chip model, for the scene's light.

    The light per pixel and what no random draw enters (expected charge, CMS moments) are made a
    block of frames at a time as the chip model reaches them (:meth:`Scene.pixel_block`; kept for
    the replicates of a small scene). At the ``binned`` and ``events`` levels the codes of a
    block are drawn ahead in frame order (:class:`FrameReader`), one stream per chunk of
    :data:`chiptwin.pixel.CHUNK_PIXELS` pixels, the chunks on every core. Light, moments and
    draws are booked to the ``pixel`` stage; ``adc`` counts the clipped samples.

    ``sites`` (pixel indices) keeps the DSP outputs at those pixels only, and the whole output
    frame where they sum highest; None keeps every pixel's. ``frames_path`` streams every frame
    as read (codes, or the expected CMS difference at the ``expected`` level) to a ``.npy`` file.

    ``carry_dark`` (default: the scenario's ``[run] carry_dark_pixels``)
    takes the shortcut :mod:`chiptwin.twin.shortcuts` names: pixels not kept that see no site light
    above a tenth of their noise are not drawn but carried at the ``expected`` level; the sites'
    outputs are then equal in distribution to the full path's, not bit for bit.
    """
    timer = timer or StageTimer()
    keep = None if sites is None else np.unique(np.asarray(sites, dtype=np.int64))
    if carry_dark is None:
        carry_dark = s.run.carry_dark_pixels
    split = None
    saving = frames_path is not None
    if carry_dark and shortcuts.applies(s, photons_level, keep, keep_codes, saving):
        with timer("pixel"):
            split = shortcuts.split_dark(s, scene, keep)
    full = scene
    if split is not None:  # the drawn pixels only, as a scene of their own
        scene, sites, keep = split.scene, split.local(np.asarray(sites)), split.local(keep)
    reader = FrameReader(s, scene, photons_level, rng, timer, frames_path,
                          moments_at=moments_read_at(s, photons_level, keep, keep_codes))
    pipeline = _TimedPipeline(_dsp_level(s, keep_codes), timer, keep, sites,
                              scene.sensor.e_per_lsb)
    # a run known ahead (steady, and a DSP whose timing no output changes) skips the events
    steady = (steady_run(scene.sch, rec.frame_steps)
              if isinstance(pipeline.inner, Pipeline) and isinstance(rec, Recorder) else None)
    inner = ("pixel", "adc", "dsp")
    inner_before = sum(timer.seconds[k] for k in inner)
    t0 = time.perf_counter()
    try:
        chip = (simulate_chip(scene.sch, reader, pipeline, rec, progress) if steady is None
                else _steady_chip(steady, reader, pipeline, rec, progress))
    finally:
        reader.close()
    inner_s = sum(timer.seconds[k] for k in inner) - inner_before
    timer.seconds["memory"] += time.perf_counter() - t0 - inner_s  # the event engine itself
    out = _chain_output(chip, scene.sch, pipeline.inner, scene.sensor.e_per_lsb, keep,
                        scene.n_pixels, pipeline.stacked())
    out.peak_frame_e, out.peak_block = pipeline.peak_frame_e, pipeline.peak_block
    out.adc_clipped_samples = reader.clipped
    out.full_well_pixel_frames = reader.full_well
    if reader.events is not None:
        events = reader.events
        out.saturation_s = np.array(events.saturation_s).reshape(-1, len(events.pixels))
    if split is not None:
        with timer("pixel"):
            out = shortcuts.restore(s, full, split, out, split.drawn[keep], rng)
    return out


def moments_read_at(s: Scenario, photons_level: str, keep: np.ndarray | None,
                    keep_codes: bool) -> np.ndarray | None:
    """The pixels whose CMS moments a run reads (:func:`~chiptwin.twin.scene.pixel_frames`'s
    ``moments_at``), or None for every pixel: the kept outputs' pixels where
    :func:`chiptwin.config.cost.moments_at_kept_pixels` says (the DSP carries each pixel's
    moments beside its codes, and a run that keeps outputs at ``keep`` drops the others as they
    leave it), and every pixel when codes are kept for the RTL (``keep_codes``)."""
    if keep is None or keep_codes or not moments_at_kept_pixels(s, photons_level):
        return None
    return keep


def _dsp_level(s: Scenario, keep_codes: bool) -> Pipeline:
    """The DSP at the scenario's level: float, bit-accurate fixed point, or the RTL; a program
    beyond today's chain (``[chip.dsp] program``) runs its further stages after it."""
    if not is_default(s.chip.dsp.program):
        from chiptwin.twin.programs import program_pipeline

        return program_pipeline(s, keep_codes)
    chain = chain_for(s.chip) if s.dsp_level in ("fixed", "rtl") else None
    if s.dsp_level == "rtl":
        from chiptwin.twin.rtl import RtlPipeline

        return RtlPipeline(chain, report_error=s.chip.dsp.report_error, keep_codes=keep_codes)
    return Pipeline(s.dsp_level, chain, report_error=s.chip.dsp.report_error,
                    keep_codes=keep_codes)


class _TimedPipeline:
    """Wraps the DSP: its wall time is booked to the ``dsp`` stage, and each output is cut to the
    kept pixels (``keep``; None = all) as it leaves the DSP, so the run holds outputs at those
    pixels only, plus the one whole output frame where ``sites`` sum highest."""

    def __init__(self, inner: Pipeline, timer: StageTimer, keep: np.ndarray | None = None,
                 sites: np.ndarray | None = None, e_per_lsb: float = 1.0) -> None:
        self.inner, self.timer, self.keep, self.e_per_lsb = inner, timer, keep, e_per_lsb
        self.sites = None if sites is None else np.asarray(sites, dtype=np.int64)
        self.peak_frame_e: np.ndarray | None = None
        self.peak_block, self._peak_sum, self._n = 0, -np.inf, 0
        self._stacks: list[tuple[np.ndarray, ...]] = []  # the outputs of blocks(), per call

    def dark(self, frames):
        with self.timer("dsp"):
            return self.inner.dark(frames)

    def dark_stack(self, frames: FrameStack) -> None:
        with self.timer("dsp"):
            self.inner.dark_stack(frames)

    def blocks(self, frames: FrameStack, n: int) -> list[BlockOut]:
        """:meth:`block` of each run of ``n`` frames (:meth:`Pipeline.blocks`), in order."""
        with self.timer("dsp"):
            out = self.inner.blocks(frames, n)
            if self.sites is not None:  # block()'s figures, the whole frame for the peak only
                # rows in C order, as block()'s 1-D gathers: NumPy then sums each the same way
                at_sites = np.ascontiguousarray(out.value[:, self.sites])
                totals = (at_sites * self.e_per_lsb).sum(axis=1)
                for j, total in enumerate(totals):
                    if total > self._peak_sum or self.peak_frame_e is None:
                        self.peak_frame_e = out.value[j] * self.e_per_lsb
                        self.peak_block, self._peak_sum = self._n + j, total
            self._n += len(out.value)
            rows = (out.value, out.mean, out.var)
            if self.keep is not None:
                rows = tuple(np.ascontiguousarray(x[:, self.keep]) for x in rows)
            self._stacks.append(rows)
            return [BlockOut(value=v, mean=m, var=w) for v, m, w in zip(*rows, strict=True)]

    def stacked(self) -> dict[str, np.ndarray] | None:
        """Every output of :meth:`blocks` as ``(n_outputs, n_kept)`` arrays by name (what
        stacking the outputs one by one gives); None when :meth:`block` made them."""
        if not self._stacks:
            return None
        return {name: np.concatenate([rows[i] for rows in self._stacks])
                for i, name in enumerate(("value", "mean", "var"))}

    def block(self, frames):
        with self.timer("dsp"):
            out = self.inner.block(frames)
            if out is None:  # a program's kinetics stage between the ends of its windows
                return None
            if self.sites is not None:
                value_e = out.value * self.e_per_lsb
                total = value_e[self.sites].sum()
                if total > self._peak_sum or self.peak_frame_e is None:
                    self.peak_frame_e, self.peak_block, self._peak_sum = value_e, self._n, total
            self._n += 1
            if self.keep is None:
                return out
            return BlockOut(value=out.value[self.keep], mean=out.mean[self.keep],
                            var=out.var[self.keep])


def _steady_chip(plan: SteadyRun, reader: FrameReader, dsp: _TimedPipeline, rec: Recorder,
                 progress: Callable[[int, int], None] | None) -> ChipRun:
    """The chip model's run in closed form (:mod:`chiptwin.chip.steady`): each block of frames
    the reader makes goes to the DSP as it is made, its whole jobs in one batch
    (:meth:`Pipeline.blocks`); the frames of a job not yet whole wait, as in the frame memory."""
    sch, waiting, outputs = plan.sch, _Waiting(), []
    dark = plan.dark_done
    for k in range(0, sch.n_frames, reader.scene.block_frames):
        waiting.put(reader.stack(k))
        if dark and len(waiting) >= sch.dark_frames:
            dsp.dark_stack(waiting.take(sch.dark_frames))
            dark = False
        if not dark and plan.dark_done:
            jobs = min(len(waiting) // sch.block_frames, plan.n_jobs - len(outputs))
            for frames in waiting.take_jobs(jobs, sch.block_frames):
                outputs += dsp.blocks(frames, sch.block_frames)
        waiting.compact()
        if progress is not None:
            for j in range(k, min(k + reader.scene.block_frames, sch.n_frames)):
                progress(j + 1, sch.n_frames)
    return plan.chip_run(outputs, rec)


class _Waiting:
    """Frames read and in no DSP job yet, oldest first: views of the reader's blocks, the last
    few of a block copied out of it (:meth:`compact`) so the block itself can go."""

    def __init__(self) -> None:
        self.parts: list[FrameStack] = []
        self._block = 0  # frames of the block put last

    def __len__(self) -> int:
        return sum(len(p) for p in self.parts)

    def put(self, frames: FrameStack) -> None:
        self.parts.append(frames)
        self._block = len(frames)

    def take(self, n: int) -> FrameStack:
        """The oldest ``n`` frames: a view of one block, or (across blocks) a copy."""
        taken, left = [], n
        while left:
            head = self.parts[0]
            taken.append(head[:left])
            if len(head) <= left:
                self.parts.pop(0)
            else:
                self.parts[0] = head[left:]
            left -= len(taken[-1])
        return taken[0] if len(taken) == 1 else FrameStack.join(taken)

    def take_jobs(self, jobs: int, n: int):
        """The oldest ``jobs · n`` frames in few stacks of whole jobs: a job across two blocks
        alone (its frames copied), the jobs within a block together (a view)."""
        while jobs:
            head = len(self.parts[0])
            whole = min(jobs, head // n) or 1
            yield self.take(whole * n)
            jobs -= whole

    def compact(self) -> None:
        """Copy what is left of the last block once the DSP took the rest (only it can be
        a part of a block: older frames went first)."""
        if self.parts and len(self.parts[-1]) < self._block:
            self.parts[-1] = FrameStack.join(self.parts[-1:])


def _chain_output(chip: ChipRun, sch: Schedule, dsp: Pipeline, e_per_lsb: float,
                  keep: np.ndarray | None, n_pixels: int,
                  stacked: dict[str, np.ndarray] | None = None) -> ChainOutput:
    """The run's outputs as arrays; ``stacked``: the same, already stacked by the DSP."""
    n_pix = n_pixels if keep is None else len(keep)
    mids = _output_times(chip, sch)

    def stack(name: str) -> np.ndarray:
        if stacked is not None:
            return stacked[name]
        return np.array([getattr(o, name) for _, o in chip.outputs]).reshape(-1, n_pix)

    return ChainOutput(
        chip=chip, block_t_s=mids, value_e=stack("value") * e_per_lsb,
        mean_e=stack("mean") * e_per_lsb, var_e2=stack("var") * e_per_lsb**2,
        dark_var_e2=(dsp.dark_var if dsp.dark_var is not None else np.zeros(0)) * e_per_lsb**2,
        dsp=dsp, pixels=keep,
    )


def _output_times(chip: ChipRun, sch: Schedule) -> np.ndarray:
    """Each output's time: the mean of its frames' integration midpoints. Unit: s.

    ``np.mean`` over each output's ``sum(sch.window_s(k)) / 2``, one row per output: the ticks
    are exact in float64 below 2**53 ns (104 days), so dividing them is
    :func:`~chiptwin.constants.ticks_to_s`'s correctly rounded ``int / int``; beyond, one by one.
    """
    if not chip.outputs:
        return np.array([])
    frames = np.array([ks for ks, _ in chip.outputs], dtype=np.int64)  # every job has N frames
    start = frames * sch.frame_period_ns + (sch.t_reset_ns + sch.cms_samples * sch.t_conv_ns)
    stop = start + sch.t_int_ns
    if stop.max() >= 2**53:
        return np.array([np.mean([sum(sch.window_s(k)) / 2 for k in ks])
                         for ks, _ in chip.outputs])
    return ((start / TICKS_PER_S + stop / TICKS_PER_S) / 2).mean(axis=1)


def _required_flux(s: Scenario, idx: np.ndarray) -> float:
    """Flux at the diode that gives power SNR = ``run.detection_snr_power`` (site 0).

    The chain is linear in the flux below the full well: signal S = a·flux and variance
    var0 + k·S. Both come from the ``expected`` level run at a reference flux of 1 photon/s/µm²
    and in darkness, so the answer does not depend on the scenario's own flux.
    """
    unit = replace(s, assay=replace(s.assay, photons_per_s_per_um2=1.0))
    edges = np.array([s.assay.start_s, s.run.duration_s])
    n = s.chip.dsp.average_frames
    lit = prepare(unit)
    figures = []
    for flux in (1.0, 0.0):
        scene = replace(lit, site_photons=lit.site_photons * flux)
        out = simulate(unit, scene, "expected", stage_rng(s.scenario.seed, "required_flux"),
                       Recorder(), sites=idx[:1])  # the expected level draws nothing
        sig, var = window_sums(out.block_t_s, out.mean_e, out.var_e2, out.dark_var_e2[idx[:1]],
                               n, edges, light_decay_per_s(s))
        figures.append((sig[0, 0], var[0, 0]))
    (a, v1), (_, v0) = figures
    needed = required_signal_e(s.run.detection_snr_power, v0, (v1 - v0) / a)
    return float(needed / a)
