"""Model only what the scene needs: named shortcuts, each an equivalence with the full path.

A shortcut skips work whose result no figure of the run reads, or reads only through a law the
shortcut reproduces. Each is named here with what it skips, why it is equivalent and within what
tolerance; ``tests/test_shortcuts.py`` checks each against the full path and
``benchmarks/bench_shortcuts.py`` measures its speed-up and the error it incurs.

**Carried dark pixels** (:data:`CARRY_DARK_PIXELS_OPTION`, off by default). At the ``binned``
photon level every pixel of the array is drawn frame by frame (a Poisson count, kTC and 2M read
noises, 2M ADC conversions) and goes through the DSP, but the run keeps the DSP outputs of the
site pixels only (:func:`chiptwin.twin.runner.simulate`, ``sites``). A pixel that is not kept
and sees no site light above :data:`DARK_LIGHT_NOISE_FRACTION` of its noise is *carried*: it is
not drawn and not run through the per-frame path at all. The pixels drawn (kept ∪ lit ∪ at risk of
clipping) are simulated as a smaller scene (:func:`drawn_scene`) on the same chip schedule; the
carried ones are restored at the ``expected`` level (:func:`restore`):

* exactly the same (moments, no draw): their dark-reference variance ``dark_var_e2`` and the
  chip's event trace, memory history and flags (the schedule does not depend on the pixels);
  ``full_well_pixel_frames`` (a carried pixel's expected charge stays below the full well);
* the kept outputs (``value_e`` at the sites): the same law, other draws. The sites' codes come
  from the streams of the smaller array (:func:`chiptwin.pixel.chunk_streams` of ``len(drawn)``
  pixels), so they are not the bits of the full path for the same seed: equal in distribution,
  tested by Monte Carlo (mean within 4 standard errors, variance within 10 %);
  their ``mean_e``/``var_e2`` are the full path's to 1e-12;
* ``peak_frame_e`` at the carried pixels: the expected output plus one normal draw per pixel of
  its variance (dark reference included), from a stream of its own (:data:`CARRIED_STREAM_KEY`)
  in one vectorised step. The full path's value there sits on the lattice of one ADC code over
  M·N samples; the normal has its mean and variance (the lattice's rounding excepted);
* ``adc_clipped_samples`` counts the drawn pixels' samples: a carried pixel's samples stay
  :data:`CLIP_MARGIN_SIGMA` standard deviations inside the ADC range (below 1e-15 per sample in
  the normal approximation), so its expected count is 0;
* DSP overflow counts: the drawn pixels only. Not applied where a carried pixel could overflow
  or where the DSP mixes pixels: a narrowed accumulator (``chip.dsp.acc_bits``), fixed-vs-float
  error statistics (``report_error``, which are over every pixel), a program beyond today's
  chain (``bin_rows``, ``fir8``, ``wiener`` read neighbours), the RTL, ``save_frames``, the
  ``events`` level (its counted pixels index the whole array) and the ``expected`` level (which
  draws nothing).

The summary can say so: :attr:`~chiptwin.twin.scene.ChainOutput.carried_pixels` counts them.

Measured (``benchmarks/bench_shortcuts.py``, warm, simulate + detect, 2-core machine shared with
other jobs) on the scenes as they were before they were built as the chip is (the NA² emitter law,
an ideal converter, no top surface: the light stays near its sites): ``pyro_array_256`` draws 4,103
of 65,536 pixels, 19.9–22.8 s → 1.6–2.3 s (9.9–12.4×), its figures within the full path's
seed-to-seed spread (median |Δ signal| 0.85 σ against 0.84 σ, fraction called right 0.005 against
0.004); its median power SNR over 8 seeds 44.17 ± 0.28 against the full path's 44.20 ± 0.29;
``pyro_1fmol`` 44 of 128, 1.5×; ``pyro_paper_yield_fast`` 107 of 128, 1.1×. Under the flow cell the
bundled scene states (1 mm glass lid), the lid returns a third of each site's light spread over ≈
8,400 pixels: only 1,114 of ``pyro_array_256``'s 65,536 pixels stay dark over its 25 flows, and the
shortcut saves nothing there (which is why the scene leaves it off).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace

import numpy as np

from chiptwin.dsp.pipeline import Frame, Pipeline
from chiptwin.dsp.program import is_default
from chiptwin.twin import stages
from chiptwin.twin.scene import ChainOutput, Scene, pixel_frames

#: The switch of the carried-dark-pixels shortcut: ``[run] carry_dark_pixels`` (a bool; read by
#: :func:`chiptwin.twin.runner.simulate` when the scenario has it, else the ``carry_dark``
#: argument).
CARRY_DARK_PIXELS_OPTION: str = "carry_dark_pixels"

#: A pixel whose light charge in every frame stays at or below this fraction of its noise (the
#: standard deviation of its CMS difference in darkness) is dark. Unit: 1.
DARK_LIGHT_NOISE_FRACTION: float = 0.1

#: A carried pixel's samples stay this many standard deviations inside the ADC's range and below
#: the full well (normal approximation: < 1e-15 per sample). Unit: standard deviations.
CLIP_MARGIN_SIGMA: float = 8.0

#: Spawn key (under the pixel stream's seed) of the stream that draws the carried pixels'
#: peak-frame noise: ``crc32("carried_pixels")``, far above any chunk number.
CARRIED_STREAM_KEY: int = zlib.crc32(b"carried_pixels")


@dataclass(frozen=True)
class Split:
    """The pixels a run draws and those it carries. Indices into the whole array, sorted."""

    drawn: np.ndarray
    carried: np.ndarray
    scene: Scene  # the scene of the drawn pixels only
    carried_scene: Scene  # and of the carried ones

    def local(self, pixels: np.ndarray) -> np.ndarray:
        """Positions in ``drawn`` of the (drawn) pixels ``pixels``."""
        return np.searchsorted(self.drawn, pixels)


def applies(s, photons_level: str, keep: np.ndarray | None, keep_codes: bool,
            saving_frames: bool) -> bool:
    """Whether the carried-dark-pixels shortcut may run on this scenario (module docstring)."""
    d = s.chip.dsp
    return (photons_level == "binned" and keep is not None and not keep_codes
            and not saving_frames and is_default(d.program) and s.dsp_level != "rtl"
            and not d.acc_bits and not d.report_error)


def dark_mask(light_e_max: np.ndarray, dark_e: np.ndarray, read_noise_e: float, ktc_e: float,
              n_samples: int, true_cds: bool,
              fraction: float = DARK_LIGHT_NOISE_FRACTION) -> np.ndarray:
    """Pixels whose largest light charge in a frame is at most ``fraction`` of their noise.

    The noise is the standard deviation of the CMS difference of a dark frame:
    ``√(dark + 2σ_read²/M + 2σ_kTC²·[not true CDS])``. Unit of charges: e⁻.
    """
    var = dark_e + 2.0 * read_noise_e**2 / n_samples + (0.0 if true_cds else 2.0 * ktc_e**2)
    return light_e_max <= fraction * np.sqrt(var)


def clip_safe(lam_max_e: np.ndarray, sensor, adc, margin: float = CLIP_MARGIN_SIGMA
              ) -> np.ndarray:
    """Pixels whose samples stay ``margin`` standard deviations inside the ADC range and whose
    charge stays that far below the full well (normal approximation of charge + kTC + read).

    ``lam_max_e``: the largest expected charge in a frame. ``sensor``: a
    :class:`~chiptwin.twin.stages.SensorModel`; ``adc``: ``chip.adc``.
    """
    sd = np.sqrt(lam_max_e + sensor.ktc_e**2 + sensor.read_noise_e**2)
    to_code = sensor.conversion_gain_uV_per_e * 1e-6 / sensor.lsb_V * (1.0 + adc.gain_error)
    at_zero = (sensor.pedestal_V - adc.v_min_V) / sensor.lsb_V * (1.0 + adc.gain_error)
    lo = at_zero + adc.offset_error_lsb + (-margin * sd) * to_code
    hi = at_zero + adc.offset_error_lsb + (lam_max_e + margin * sd) * to_code
    top = 2.0**adc.bits - 1.0
    below_well = lam_max_e + margin * np.sqrt(lam_max_e) < sensor.full_well_e
    return (lo >= 0.5) & (hi <= top - 0.5) & below_well


def split_dark(s, scene: Scene, keep: np.ndarray) -> Split | None:
    """The drawn and carried pixels of ``scene`` (None: nothing to carry).

    A pixel is carried when it is not in ``keep``, is dark (:func:`dark_mask`) and clip-safe
    (:func:`clip_safe`). The light per pixel is bounded by ``coupling @ max_t(site_photons)``
    (the coupling is non-negative), which is at least its largest value over the frames.
    Kept with the scene (its memo), so the replicates of a study share the split and the
    drawn scene's own memo.
    """
    key = ("split_dark", s.chip.timing.t_int_s, s.chip.adc, np.asarray(keep).tobytes())
    if key not in scene._memo:
        scene._memo[key] = _split_dark(s, scene, keep)
    return scene._memo[key]


def _split_dark(s, scene: Scene, keep: np.ndarray) -> Split | None:
    sensor = scene.sensor
    most = scene.site_photons.max(axis=1) if scene.site_photons.size else np.zeros(
        scene.site_photons.shape[0])
    light_e = sensor.qe * sensor.gain_map * np.asarray(scene.coupling @ most).reshape(-1)
    dark_e = sensor.dark_e_per_s * s.chip.timing.t_int_s
    carried = (dark_mask(light_e, dark_e, sensor.read_noise_e, sensor.ktc_e,
                         sensor.cms_samples, sensor.true_cds)
               & clip_safe(light_e + dark_e, sensor, s.chip.adc))
    carried[keep] = False
    if not carried.any():
        return None
    drawn, rest = np.flatnonzero(~carried), np.flatnonzero(carried)
    return Split(drawn, rest, sub_scene(scene, drawn), sub_scene(scene, rest))


def sub_scene(scene: Scene, pixels: np.ndarray) -> Scene:
    """The scene restricted to ``pixels``: coupling rows, the sensor's maps and its converters
    (as built: each pixel's own gain, offset and ramp) at them."""
    conv = scene.sensor.converter
    sensor = replace(scene.sensor, gain_map=scene.sensor.gain_map[pixels],
                     dark_e_per_s=scene.sensor.dark_e_per_s[pixels],
                     converter=None if conv is None else conv.at(pixels))
    return Scene(scene.sch, scene.source, scene.site_photons, scene.coupling[pixels], sensor)


def _carried_rng(rng: np.random.Generator) -> np.random.Generator:
    return stages.child_rng(rng, "carried_pixels")  # spawn key CARRIED_STREAM_KEY


def _expected_frames(s, scene: Scene, frames: list[int]) -> list[Frame]:
    """The ``expected`` level's frames ``frames`` (ascending) of ``scene``: moments only, one
    :func:`~chiptwin.twin.scene.pixel_frames` call per run of consecutive frames."""
    out: list[Frame] = []
    breaks = np.flatnonzero(np.diff(frames) != 1) + 1
    for run in np.split(np.asarray(frames, dtype=np.int64), breaks):
        if not run.size:
            continue
        m = pixel_frames(scene, s.chip.timing.t_int_s, s.chip.adc.gain_error,
                         int(run[0]), int(run[-1]) + 1)
        out += [Frame(codes=None, mean=m.cds_mean_lsb[i], var=m.cds_var_lsb2[i])
                for i in range(len(run))]
    return out


def restore(s, scene: Scene, split: Split, out: ChainOutput, keep: np.ndarray,
            rng: np.random.Generator) -> ChainOutput:
    """The smaller run's output on the whole array: kept pixels by global index, the dark
    reference's variance at every pixel, the carried pixels in the peak frame.

    The carried pixels' dark reference and peak-block output are the ``expected`` level's
    (a float :class:`~chiptwin.dsp.pipeline.Pipeline` on moments, the full path's arithmetic),
    on the frames the DSP read for them (the first ``K`` written, the peak block's).
    """
    sch, chip = scene.sch, out.chip
    dropped = set(chip.dropped)
    dark_frames = [k for k in range(sch.n_frames) if k not in dropped][:sch.dark_frames]
    carried_scene = split.carried_scene
    moments = Pipeline("float")
    moments.dark(_expected_frames(s, carried_scene, dark_frames))
    e = scene.sensor.e_per_lsb
    dark_var = np.empty(scene.n_pixels)
    dark_var[split.drawn] = out.dark_var_e2
    dark_var[split.carried] = moments.dark_var * e**2
    out.dark_var_e2 = dark_var
    out.pixels = keep
    out.carried_pixels = len(split.carried)
    if out.peak_frame_e is not None and chip.outputs:
        frame = np.empty(scene.n_pixels)
        frame[split.drawn] = out.peak_frame_e
        block = moments.block(_expected_frames(s, carried_scene, chip.outputs[out.peak_block][0]))
        sd = np.sqrt(block.var + moments.dark_var)
        frame[split.carried] = (block.mean + sd * _carried_rng(rng).standard_normal(sd.size)) * e
        out.peak_frame_e = frame
    return out


def drawn_share(split: Split | None, n_pixels: int) -> float:
    """The fraction of the array's pixels drawn frame by frame (1 without the shortcut)."""
    return 1.0 if split is None else len(split.drawn) / max(n_pixels, 1)


__all__ = ["CARRIED_STREAM_KEY", "CARRY_DARK_PIXELS_OPTION", "CLIP_MARGIN_SIGMA",
           "DARK_LIGHT_NOISE_FRACTION", "Split", "applies", "clip_safe", "dark_mask",
           "drawn_share", "restore", "split_dark", "sub_scene"]

