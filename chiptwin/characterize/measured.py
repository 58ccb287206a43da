"""Measured data in: an EMVA 1288 data set of a real camera through the same estimators and the
same evaluation as the twin's own bench, into the same datasheet.

::

    EMVA1288_Data.txt ──► descriptor ──► pair and stack ──► Measurement ──► evaluation ──► datasheet
    + images (PNG/TIFF)   (checked)      statistics          (as the bench's)  (the standard's)

A data set gives, per step, the exposure time, the photons per pixel and the images
(:mod:`~chiptwin.characterize.descriptor`): two bright and two dark images per photon-transfer
point, and stacks of L bright and L dark images for the spatial figures. What it does not give,
the datasheet leaves unresolved and says why: the pixel's size (unless the user states it), the
dark current's temperature dependence (no temperature series), a raw reset level.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from chiptwin.characterize.bench import Progress
from chiptwin.characterize.datasheet import (
    Datasheet,
    curves,
    evaluate_measurement,
    fit_ranges,
    regime_notes,
)
from chiptwin.characterize.descriptor import (
    Descriptor,
    DescriptorError,
    load_image,
    read_descriptor,
)
from chiptwin.characterize.estimators import StackAccumulator, pair_stats
from chiptwin.characterize.measure import Measurement
from chiptwin.characterize.series import SpatialSeries, TemporalSeries

#: Pixel pitches a user may state for a measured camera (µm): the smallest pixels made
#: (≈ 0.5 µm) to the largest single diodes of a detection chip (≈ 1 cm).
PITCH_RANGE_UM: tuple[float, float] = (0.1, 1.0e4)


@dataclass(frozen=True)
class MeasuredCamera:
    """What an EMVA 1288 data set says about the camera that made it.

    Attributes
    ----------
    rows, cols : int  image size (the descriptor's ``height``, ``width``).
    adc_bits : int  the descriptor's bit depth.
    pixel_pitch_um : float or None  stated by the user; a data set does not carry it. Unit: µm.
    release : str  the EMVA 1288 release the data set was measured for.
    descriptor : str  the descriptor's file name and folder (not the machine's path).
    """

    rows: int
    cols: int
    adc_bits: int
    pixel_pitch_um: float | None
    release: str
    descriptor: str

    @property
    def n_pixels(self) -> int:
        return self.rows * self.cols

    @property
    def pixel_area_um2(self) -> float | None:
        """pitch², on which EMVA's photons per pixel fall; None when the pitch is not stated."""
        return None if self.pixel_pitch_um is None else self.pixel_pitch_um**2


def read_measured(folder: str | Path, pixel_pitch_um: float | None = None,
                  progress: Progress | None = None, keep_images: bool = False) -> Measurement:
    """An EMVA 1288 data set as a :class:`~chiptwin.characterize.measure.Measurement`.

    Parameters
    ----------
    folder : path
        The data set's folder (or its ``EMVA1288_Data.txt``).
    pixel_pitch_um : float, optional
        The camera's pixel pitch, for the per-area figures. Unit: µm.
    progress : callable, optional
        ``progress(images_done, images_total)``.
    keep_images : bool
        Keep the images in ``Measurement.images`` as the bench does (``ptc``: per point the
        bright pair and the dark pair; ``spatial_bright``, ``spatial_dark``).

    Raises
    ------
    DescriptorError
        (a :class:`~chiptwin.config.ScenarioError`) naming the file, the line or image, the value
        and what is allowed.
    """
    d = read_descriptor(folder)
    if pixel_pitch_um is not None and not PITCH_RANGE_UM[0] <= pixel_pitch_um <= PITCH_RANGE_UM[1]:
        raise DescriptorError("--pixel-pitch-um", "pixel_pitch_um", pixel_pitch_um,
                              f"must be in [{PITCH_RANGE_UM[0]:g}, {PITCH_RANGE_UM[1]:g}] µm")
    camera = MeasuredCamera(rows=d.height, cols=d.width, adc_bits=d.bits,
                            pixel_pitch_um=pixel_pitch_um, release=d.release,
                            descriptor=f"{d.path.parent.name}/{d.path.name}")
    reader = _Reader(d, progress, keep_images)
    temporal = _temporal(d, camera, reader)
    spatial = _spatial(d, reader)
    return Measurement(camera=camera, protocol=None, tiles=1, temporal=temporal, spatial=spatial,
                       temperature=None, clipped_samples=reader.clipped,
                       images=reader.images if keep_images else {})


class _Reader:
    """Loads images, counts them for progress and counts clipped values (0 or full scale)."""

    def __init__(self, d: Descriptor, progress: Progress | None, keep: bool) -> None:
        self.d, self.progress, self.keep = d, progress, keep
        spatial = d.spatial()
        self.total = 4 * len(d.temporal_points()) + (
            0 if spatial is None else sum(len(s.images) for s in spatial))
        self.done, self.clipped, self.images = 0, 0, {}

    def __call__(self, path: Path) -> np.ndarray:
        img = load_image(self.d, path)
        self.clipped += int(np.count_nonzero((img == 0) | (img == 2**self.d.bits - 1)))
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total)
        return img


def _temporal(d: Descriptor, camera: MeasuredCamera, load: _Reader) -> TemporalSeries:
    """The photon-transfer series: each point's bright pair and the dark pair of its exposure."""
    t_exp, mu_p, bright, dark = [], [], [], []
    for exposure_ns, photons, b, k in d.temporal_points():
        imgs = [load(p) for p in (*b.images, *k.images)]
        bright.append(pair_stats(imgs[0], imgs[1]))
        dark.append(pair_stats(imgs[2], imgs[3]))
        t_exp.append(exposure_ns * 1e-9)
        mu_p.append(photons)
        if load.keep:
            load.images.setdefault("ptc", []).append(tuple(imgs))
    t, p = np.array(t_exp), np.array(mu_p)
    area = camera.pixel_area_um2
    irradiance = float(np.median(p / t) / area) if area is not None else float("nan")
    return TemporalSeries(t, p, tuple(bright), tuple(dark), bright[0].n, irradiance,
                          float("nan"), float("nan"))


def _spatial(d: Descriptor, load: _Reader) -> SpatialSeries | None:
    """The spatial stacks, averaged, with each pixel's temporal variance over the stack."""
    steps = d.spatial()
    if steps is None:
        return None
    bright, dark = steps
    if len(bright.images) != len(dark.images):
        raise DescriptorError(str(d.path), f"line {dark.line}", len(dark.images),
                              f"the dark stack must have as many images as the bright stack of "
                              f"line {bright.line} ({len(bright.images)}): the standard's "
                              "spatial figures average L images of each")
    stacks = {}
    for name, step in (("spatial_bright", bright), ("spatial_dark", dark)):
        acc = StackAccumulator()
        for path in step.images:
            img = load(path)
            acc.add(img)
            if load.keep:
                load.images.setdefault(name, []).append(img)
        stacks[name] = acc.result()
    (bm, bv), (dm, dv) = stacks["spatial_bright"], stacks["spatial_dark"]
    return SpatialSeries(bright.exposure_ns * 1e-9, bright.photons, len(bright.images), bm, bv,
                         dm, dv)


# --- the datasheet of a measured camera ---------------------------------------------------------

def measured_datasheet(m: Measurement) -> Datasheet:
    """The datasheet of a camera's measurement: the same figures as the twin's, no scenario
    beside them."""
    e = evaluate_measurement(m)
    return Datasheet(camera=m.camera, figures=e.figures, scenario_values={}, flags=e.flags,
                     notes=_notes(m, e), conditions=conditions(m),
                     fit_ranges=fit_ranges(m.temporal, e.i_sat, e.linearity),
                     curves=curves(m, e), measurement=m)


def conditions(m: Measurement) -> dict:
    """The measurement's conditions as the data set states them."""
    t, sp, cam = m.temporal, m.spatial, m.camera
    irr = t.irradiance_photons_per_s_per_um2
    return {
        "release": cam.release,
        "irradiance_photons_per_s_per_um2": None if not np.isfinite(irr) else irr,
        "ptc_points": len(t.t_exp_s),
        "ptc_exposure_s": [float(t.t_exp_s.min()), float(t.t_exp_s.max())],
        "ptc_mu_p_photons": [float(t.mu_p.min()), float(t.mu_p.max())],
        "ptc_values_per_image": t.n_values,
        "spatial_exposure_s": None if sp is None else sp.t_exp_s,
        "spatial_mu_p_photons": None if sp is None else sp.mu_p,
        "spatial_images": None if sp is None else sp.n_images,
        "clipped_values": m.clipped_samples,
    }


def _notes(m: Measurement, e) -> list[str]:
    cam, notes = m.camera, regime_notes(e.flags, e.sigma_y)
    notes.append(f"Measured by the camera: the data set {cam.descriptor} (EMVA 1288 release "
                 f"{cam.release}, {cam.adc_bits}-bit images of {cam.cols} × {cam.rows}); DN is "
                 "the camera's digital number; σ_d subtracts the standard's σ²_q = 1/12 DN².")
    if cam.pixel_pitch_um is None:
        notes.append("The pixel pitch was not stated (--pixel-pitch-um): the per-area figures "
                     "are not given.")
    return notes


def characterize_measured(folder: str | Path, pixel_pitch_um: float | None = None,
                          progress: Progress | None = None, keep_images: bool = False):
    """Read an EMVA 1288 data set and evaluate its datasheet: a
    :class:`~chiptwin.characterize.Characterization` whose ``meta`` names the data set."""
    from chiptwin import __version__
    from chiptwin.characterize import Characterization

    t0 = time.perf_counter()
    m = read_measured(folder, pixel_pitch_um, progress, keep_images)
    d = measured_datasheet(m)
    meta = {"scenario": Path(m.camera.descriptor).parent.name, "source": m.camera.descriptor,
            "measured": True, "seed": None, "chiptwin_version": __version__,
            "wall_time_s": round(time.perf_counter() - t0, 6)}
    return Characterization(d, meta)


__all__ = ["MeasuredCamera", "characterize_measured", "measured_datasheet", "read_measured"]
