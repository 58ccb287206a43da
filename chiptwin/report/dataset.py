"""A run's arrays as one labelled xarray Dataset, in ``run.nc`` (NetCDF4, written by h5netcdf).

Every array a run makes (:attr:`chiptwin.twin.runner.Result.arrays`), the chip's event trace and,
with ``[run] save_frames``, every frame as the ADCs delivered it, on named dimensions::

    site      the assay sites (coordinates: their pixel's row and column, centre in µm)
    frame     integration windows (start, end and middle in s)
    block     DSP outputs (their time in s, ``block_t_s``)
    flow      pyrosequencing dispensations (their nucleotide)
    read_base the called bases of every read, one read after another (``read_bases`` per site)
    row, col  the pixel array (pixel centres in µm); ``binned_row`` the DSP's binned rows
    sample    a frame's ADC samples, M reset then M signal (``frames`` only)
    memory_change, trace  the frame memory's history and the chip's trace (times in s, ns)

with each variable's unit (``units``) and meaning (``long_name``) in its attributes (the table
:data:`VARIABLES`), and in the dataset's attributes the scenario as the run used it (TOML text,
:func:`chiptwin.report.scenario_toml.scenario_toml`), its seed, its name and file, and the chiptwin
version. :func:`open_run` reads it back, value for value.

Why NetCDF4 and not Zarr: a run is written once, at its end, by one process, and read whole or by
variable on one machine; one file is what such a result should be (moved, mailed, attached to a
report), and NetCDF4 is read without Python by ncdump, Panoply, MATLAB, R and Julia through the
netCDF-C library, which h5netcdf's files are valid for. Zarr's strengths, chunks as separate
objects for parallel and cloud writes, a run does not need; its folder holds a file per chunk.
h5netcdf writes NetCDF4 through h5py alone (no netCDF-C build), and ships as wheels.

An array this table does not name (a stage added later) is still written, on dimensions named
``<array>_dim0``, ``<array>_dim1`` …, and its ``long_name`` says it is not labelled; the tests
require every bundled scenario's arrays to be named here.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from chiptwin import __version__
from chiptwin.chip import Schedule
from chiptwin.config import Scenario, ScenarioError
from chiptwin.report.scenario_toml import scenario_toml
from chiptwin.twin.stages import flow_program

if TYPE_CHECKING:
    import xarray as xr

    from chiptwin.twin.runner import Result

#: The dataset's file in a run's output folder.
DATASET_FILE = "run.nc"
#: The layout's version (attribute ``chiptwin_dataset_version``): a reader refuses a newer one.
DATASET_VERSION = 1
#: Arrays of this many bytes or more are compressed (gzip level 1, chunked); smaller ones are
#: stored whole, where a chunk index would cost more than compression saves.
COMPRESS_BYTES = 1 << 10
#: Bytes of frames per chunk of ``frames`` (HDF5 chunks of about 1 MiB, gzip level 1).
FRAMES_CHUNK_BYTES = 1 << 20

E = "e-"  # electrons
#: Each array of a run: its dimensions, unit and meaning.
VARIABLES: dict[str, tuple[tuple[str, ...], str, str]] = {
    "site_pixel_index": (("site",), "1", "row-major index of the pixel under each site"),
    "site_signal_e": (("site", "block"), E, "DSP output at each site's pixel"),
    "site_photons": (("site", "frame"), "photons",
                     "photons each site emits in each integration window"),
    "site_pixel_photons": (("site", "frame"), "photons",
                           "photons reaching each site's pixel in each integration window"),
    "site_snr_power": (("site",), "1", "per-site SNR, power ratio (eq. 22)"),
    "site_called_right": (("site",), "1", "the site's whole read equals the template"),
    "site_weight": (("site",), "1", "array sites each simulated site stands for (run.tile)"),
    "flow_values": (("site", "flow"), "bases", "flow value normalised by the key's 1-mers"),
    "flow_sums_e": (("site", "flow"), E, "the light of each flow's window"),
    "read_calls": (("site", "flow"), "bases", "bases called in each flow"),
    "read_flowgram_x100": (("site", "flow"), "0.01 bases", "the SFF flowgram (reads.sff)"),
    "read_corrected": (("site", "flow"), "bases",
                       "flow value corrected for phasing by the caller's model"),
    "read_true_n": (("flow",), "bases", "bases the template incorporates in each flow"),
    "read_quality": (("read_base",), "Phred",
                     "quality of each called base, the reads one after another"),
    "peak_frame_e": (("row", "col"), E, "the brightest DSP output frame"),
    "peak_frame_t_s": ((), "s", "time of the brightest DSP output frame"),
    "memory_frames": (("memory_change",), "frames", "frames held in the frame memory"),
    "dose_amount_amol": (("site",), "amol", "analyte at each site (0: a blank)"),
    "dose_signal_e": (("site",), E, "each site's measured signal"),
    "dose_expected_e": (("site",), E, "each site's expected signal (no noise)"),
    "dose_sd_e": (("site",), E, "standard deviation of each site's signal"),
    "trace_block": (("trace",), "", "the chip block that reported the event"),
    "trace_event": (("trace",), "", "what the block did"),
    "trace_value": (("trace",), "", "the event's value (frame number, occupancy, "
                                          "frames of a DSP job, CMS samples)"),
    **{f"column_profile_{name}_e": (("binned_row", "col"), E, f"column profile, {what}")
       for name, what in (("before", "before the FIR and the equalizer"),
                          ("after", "after the whole DSP program"),
                          ("before_expected", "before the FIR and the equalizer, expected"),
                          ("after_expected", "after the whole DSP program, expected"))},
}
#: Arrays that are coordinates of a dimension: name → (dimension, unit, meaning).
COORDINATES: dict[str, tuple[str, str, str]] = {
    "block_t_s": ("block", "s", "time of each DSP output: mean of its frames' integration "
                                "midpoints"),
    "memory_t_s": ("memory_change", "s", "time of each change of the frame memory"),
    "trace_t_ns": ("trace", "ns", "tick of each event of the chip's trace"),
}
#: Arrays a run makes that the dataset holds another way (``read_quality_offsets`` as the
#: count per site ``read_bases``, CF's contiguous ragged array; ``trace_frame_steps`` an
#: attribute).
RESHAPED = frozenset({"read_quality_offsets", "trace_frame_steps"})


def run_dataset(result: Result) -> xr.Dataset:
    """The run's arrays and trace as one labelled Dataset (``frames`` not included: they are
    streamed into the file by :func:`write_dataset`)."""
    import xarray as xr

    s = result.scenario
    arrays = {**result.arrays, **result.trace.to_arrays()}
    ds = xr.Dataset(attrs=_attrs(result))
    for name, value in arrays.items():
        if name in RESHAPED or name in COORDINATES:
            continue
        dims, unit, meaning = VARIABLES.get(name, (
            tuple(f"{name}_dim{i}" for i in range(np.ndim(value))), "",
            "not labelled: add it to chiptwin.report.dataset.VARIABLES"))
        ds[name] = xr.Variable(dims, np.asarray(value), _describe(unit, meaning))
    ds = ds.assign_coords(_coordinates(result, arrays, ds.sizes))
    if "read_quality_offsets" in arrays:
        ds["read_bases"] = xr.Variable(("site",), np.diff(arrays["read_quality_offsets"]), {
            **_describe("1", "called bases of each site's read in read_quality"),
            "sample_dimension": "read_base"})
    ds.attrs["trace_frame_steps"] = int(result.trace.frame_steps)
    ds.attrs["title"] = f"chiptwin run of {s.scenario.name}, seed {s.scenario.seed}"
    return ds


def _describe(unit: str, meaning: str) -> dict[str, str]:
    return {"units": unit, "long_name": meaning} if unit else {"long_name": meaning}


def _attrs(result: Result) -> dict[str, Any]:
    s = result.scenario
    return {"chiptwin_version": __version__, "chiptwin_dataset_version": DATASET_VERSION,
            "scenario": s.scenario.name, "scenario_source": s.source, "seed": s.scenario.seed,
            "scenario_toml": scenario_toml(s),
            "fidelity": json.dumps(result.summary.get("fidelity", {}), sort_keys=True)}


def _coordinates(result: Result, arrays: dict[str, np.ndarray], sizes: Any) -> dict[str, Any]:
    """The times, positions and nucleotides along the dimensions used (none of them indexes
    a dimension: select by position, ``isel``, or by these, ``where``)."""
    s = result.scenario
    pitch = s.chip.pitch_um
    coords: dict[str, Any] = {}
    for name, (dim, unit, meaning) in COORDINATES.items():
        if name in arrays:
            coords[name] = (dim, arrays[name], _describe(unit, meaning))
    if "site" in sizes:
        rows, cols = np.divmod(np.asarray(arrays["site_pixel_index"]), s.chip.cols)
        coords |= {"site_row": ("site", rows, _describe("1", "pixel row under the site")),
                   "site_col": ("site", cols, _describe("1", "pixel column under the site")),
                   "site_x_um": ("site", (cols + 0.5) * pitch, _describe("um", "site centre, x")),
                   "site_y_um": ("site", (rows + 0.5) * pitch, _describe("um", "site centre, y"))}
    if "row" in sizes:
        coords["row_y_um"] = ("row", (np.arange(sizes["row"]) + 0.5) * pitch,
                              _describe("um", "pixel centre, y"))
    if "col" in sizes:
        coords["col_x_um"] = ("col", (np.arange(sizes["col"]) + 0.5) * pitch,
                              _describe("um", "pixel centre, x"))
    if "frame" in sizes:
        coords |= _frame_times(s, sizes["frame"])
    if "flow" in sizes and s.assay.kind == "pyrosequencing":
        nucs = flow_program(s)[0]
        coords["flow_nucleotide"] = ("flow", np.array(nucs[:sizes["flow"]], dtype=str),
                                     _describe("", "nucleotide dispensed"))
    return coords


def _frame_times(s: Scenario, n: int) -> dict[str, Any]:
    """Each frame's integration window (:meth:`chiptwin.chip.Schedule.window_s`). Unit: s."""
    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    start = (np.arange(n, dtype=np.int64) * sch.frame_period_ns + sch.t_reset_ns
             + sch.cms_samples * sch.t_conv_ns)
    return {"frame_t_s": ("frame", (2 * start + sch.t_int_ns) / 2e9, {
        **_describe("s", "middle of the frame's integration window"),
        "integration_s": sch.t_int_ns / 1e9, "frame_period_s": sch.frame_period_ns / 1e9}),
        "frame_start_s": ("frame", start / 1e9, _describe("s", "integration starts"))}


def write_dataset(result: Result, path: Path, frames: Path | None = None) -> None:
    """Write :func:`run_dataset` to ``path`` (NetCDF4), and the frames streamed to ``frames``
    (the ``.npy`` file of ``[run] save_frames``) as the variable ``frames``, block by block."""
    ds = run_dataset(result)
    if frames is not None and np.load(frames, mmap_mode="r").ndim == 3:  # codes: 2M samples
        m = result.scenario.chip.dsp.cms_samples
        ds = ds.assign_coords(sample_kind=("sample", np.array(["reset"] * m + ["signal"] * m), {
            "long_name": "the frame's ADC samples: M reset samples, then M signal samples"}))
    encoding: dict[str, dict[str, Any]] = {}
    for name, v in ds.variables.items():
        if v.nbytes >= COMPRESS_BYTES:  # small ones whole: a chunk index costs more
            encoding[name] = {"zlib": True, "complevel": 1}
        if v.ndim and v.dtype.kind == "U":  # strings as characters, not HDF5's variable-length
            encoding.setdefault(name, {})["dtype"] = "S1"  # ones (16 B each, uncompressed)
    ds.to_netcdf(path, engine="h5netcdf", encoding=encoding)
    if frames is not None:
        _append_frames(result, path, frames)


def _append_frames(result: Result, path: Path, frames: Path) -> None:
    """Copy the frames file into ``path`` a chunk at a time (it may be larger than memory)."""
    import h5netcdf

    s = result.scenario
    data = np.load(frames, mmap_mode="r")
    sampled = data.ndim == 3
    shape = (data.shape[0], *((data.shape[1],) if sampled else ()), s.chip.rows, s.chip.cols)
    dims = ("frame", *(("sample",) if sampled else ()), "row", "col")
    per_frame = int(np.prod(shape[1:])) * data.dtype.itemsize
    step = max(1, min(shape[0], FRAMES_CHUNK_BYTES // max(per_frame, 1)))
    with h5netcdf.File(path, "a") as f:
        for dim, n in zip(dims, shape, strict=True):
            if dim not in f.dimensions:
                f.dimensions[dim] = n
            elif f.dimensions[dim].size != n:
                raise ValueError(f"frames: {n} along {dim}, the run's dataset has "
                                 f"{f.dimensions[dim].size}")
        var = f.create_variable("frames", dims, dtype=data.dtype, chunks=(step, *shape[1:]),
                                compression="gzip", compression_opts=1)
        var.attrs["units"] = "LSB"
        var.attrs["long_name"] = ("ADC codes of every frame as read (dropped ones too)"
                                  if sampled else
                                  "expected CMS difference of every frame (expected level)")
        if sampled:
            var.attrs["coordinates"] = "sample_kind"
        for k in range(0, shape[0], step):
            var[k:k + step] = np.asarray(data[k:k + step]).reshape(-1, *shape[1:])
    del data


def open_run(folder: str | Path) -> xr.Dataset:
    """A run's output folder as one labelled Dataset (``run.nc``; see
    :mod:`chiptwin.report.dataset`).

    Variables are read when used (``frames`` may be larger than memory); close the dataset, or
    use it in a ``with`` block, to release the file.

    Raises
    ------
    ScenarioError
        When ``folder`` is not a run's output folder, or one written before runs wrote their
        dataset (it names the folder and what to do).
    """
    path = _dataset_path(Path(folder))
    import xarray as xr

    try:
        ds = xr.open_dataset(path, engine="h5netcdf")
    except (OSError, ValueError) as exc:
        _refuse(folder, f"its {DATASET_FILE} cannot be read ({exc}): run the scenario again")
    version = ds.attrs.get("chiptwin_dataset_version")
    if not isinstance(version, int | np.integer) or version > DATASET_VERSION:
        ds.close()
        _refuse(folder, f"its {DATASET_FILE} has dataset layout {version!r}, this chiptwin "
                        f"({__version__}) reads up to {DATASET_VERSION}: upgrade chiptwin")
    return ds


def _dataset_path(folder: Path) -> Path:
    """``folder/run.nc``, or a refusal saying what the folder is and what to do."""
    if not folder.is_dir():
        _refuse(folder, "no such folder: give the --out folder of a `chiptwin run`")
    path = folder / DATASET_FILE
    if path.is_file():
        return path
    summary = folder / "summary.json"
    if summary.is_file():
        try:
            meta = json.loads(summary.read_text())
            made = f"by chiptwin {meta.get('chiptwin_version', '?')} (seed {meta.get('seed')})"
        except (OSError, ValueError):
            made = "by an older chiptwin"
        _refuse(folder, f"a run written {made} before runs wrote {DATASET_FILE}: run it again "
                        "with this chiptwin (chiptwin run SCENARIO --seed N --out FOLDER), or "
                        "read its arrays.npz with numpy.load")
    if (folder / "results.sqlite").is_file():
        _refuse(folder, "a study's folder, not a run's: read it with chiptwin.open_study")
    _refuse(folder, f"not a run's output folder (no summary.json, no {DATASET_FILE}): "
                    "`chiptwin run SCENARIO --out FOLDER` writes one")


def _refuse(folder: str | Path, allowed: str) -> None:
    raise ScenarioError("chiptwin.open_run", "folder", str(folder), allowed)
