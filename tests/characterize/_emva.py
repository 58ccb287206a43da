"""The ``emva1288`` reference implementation (PyPI 1.0.2, the test extra) run on the bench's images.

NumPy 2 shim: emva1288 1.0.2 calls ``np.asfarray``, which NumPy 2.0 removed (sources.md A5). While
it runs, :func:`numpy_shim` puts back ``np.asfarray(a, dtype=float64) = np.asarray(a, dtype)``
(NumPy 1's definition) and takes it away again afterwards, so nothing else sees it.

The images go in as emva1288's loader would hand them over (``routines.get_int_imgs`` of each
pair or stack; temporal sums reduced to scalars, exposure times in ns), scaled to integers: the
CMS frame is in steps of 1/M LSB, so ``M × frame`` is an integer image, in units of DN/M.
"""

from __future__ import annotations

import contextlib

import numpy as np

from chiptwin.characterize.estimators import StackAccumulator, pair_stats
from chiptwin.characterize.measure import Measurement, SpatialSeries, TemporalSeries


@contextlib.contextmanager
def numpy_shim():
    """``np.asfarray`` restored for the duration (a no-op on NumPy 1)."""
    name = "asfarray"  # by name: the attribute is what NumPy 2 lacks
    added = not hasattr(np, name)
    if added:
        setattr(np, name, lambda a, dtype=np.float64: np.asarray(a, dtype=dtype))
    try:
        yield
    finally:
        if added:
            delattr(np, name)


def integer(img: np.ndarray, scale: int) -> np.ndarray:
    """``scale × img`` as int64, checked to be whole numbers."""
    x = np.asarray(img, np.float64) * scale
    out = np.rint(x)
    assert np.max(np.abs(x - out), initial=0.0) < 1e-6, "image is not on the 1/M grid"
    return out.astype(np.int64)


def emva_results(m: Measurement, scale: int, index_sat: int | None):
    """``emva1288.process.Results1288`` on the measurement's images (×``scale``)."""
    from emva1288.process import routines
    from emva1288.process.data import Data1288
    from emva1288.process.results import Results1288

    t, sp, cam = m.temporal, m.spatial, m.camera
    temporal = {}
    for texp, mu_p, imgs in zip(t.t_exp_s, t.mu_p, m.images["ptc"], strict=True):
        a, b, c, d = (integer(x, scale) for x in imgs)
        temporal[float(texp * 1e9)] = {0.0: _reduced(routines.get_int_imgs([c, d])),
                                       float(mu_p): _reduced(routines.get_int_imgs([a, b]))}
    spatial = {float(sp.t_exp_s * 1e9): {
        0.0: routines.get_int_imgs([integer(x, scale) for x in m.images["spatial_dark"]]),
        float(sp.mu_p): routines.get_int_imgs([integer(x, scale)
                                              for x in m.images["spatial_bright"]])}}
    data = {"temporal": temporal, "spatial": spatial, "height": cam.rows, "width": cam.cols}
    with numpy_shim():
        dat = Data1288(data, pixels=t.n_values)
        return Results1288(dat.data, pixel_area=cam.pixel_area_um2, index_u_ysat=index_sat)


def _reduced(d: dict) -> dict:
    """What emva1288's loader keeps of a temporal pair: scalar sums."""
    return {"sum": np.sum(d["sum"]), "pvar": np.sum(d["pvar"]), "dmean": d["dmean"]}


def rescaled(m: Measurement, scale: int) -> Measurement:
    """The same measurement with every image × ``scale`` (as integers), statistics recomputed:
    what chiptwin's evaluation sees of the data emva1288 gets."""
    t, sp = m.temporal, m.spatial
    bright, dark = [], []
    for a, b, c, d in m.images["ptc"]:
        bright.append(pair_stats(integer(a, scale), integer(b, scale)))
        dark.append(pair_stats(integer(c, scale), integer(d, scale)))
    temporal = TemporalSeries(t.t_exp_s, t.mu_p, tuple(bright), tuple(dark), t.n_values,
                              t.irradiance_photons_per_s_per_um2, t.reset_level_dn * scale,
                              t.reset_level_se_dn * scale)
    stacks = {}
    for which in ("spatial_bright", "spatial_dark"):
        acc = StackAccumulator()
        for img in m.images[which]:
            acc.add(integer(img, scale))
        stacks[which] = acc.result()
    (bm, bv), (dm, dv) = stacks["spatial_bright"], stacks["spatial_dark"]
    spatial = SpatialSeries(sp.t_exp_s, sp.mu_p, sp.n_images, bm, bv, dm, dv)
    return Measurement(m.camera, m.protocol, m.tiles, temporal, spatial, m.temperature,
                       m.clipped_samples, m.images)


#: chiptwin key → how to read the same figure off emva1288's Results1288.
EMVA_NAMES = {
    "quantum_efficiency": "QE",
    "system_gain": "K",
    "inverse_system_gain": "inverse_K()",
    "responsivity": "R",
    "temporal_dark_noise_dn": "sigma_y_dark",
    "temporal_dark_noise": "sigma_d",
    "saturation_irradiation": "u_p_sat",
    "saturation_capacity": "u_e_sat",
    "snr_max": "SNR_max",
    "snr_max_db": "SNR_max_dB()",
    "snr_max_bits": "SNR_max_bit()",
    "absolute_sensitivity_threshold": "u_p_min",
    "absolute_sensitivity_threshold_area": "u_p_min_area",
    "absolute_sensitivity_threshold_e": "u_e_min",
    "dynamic_range": "DR",
    "dynamic_range_db": "DR_dB()",
    "dark_current": "u_I_mean",
    "dark_current_from_variance": "u_I_var",
    "dsnu": "DSNU1288",
    "dsnu_dn": "DSNU1288_DN()",
    "dsnu_col": "DSNU1288_col",
    "dsnu_row": "DSNU1288_row",
    "dsnu_pixel": "DSNU1288_pixel",
    "prnu": "PRNU1288",
    "prnu_col": "PRNU1288_col",
    "prnu_row": "PRNU1288_row",
    "prnu_pixel": "PRNU1288_pixel",
    "linearity_error_min": "LE_min",
    "linearity_error_max": "LE_max",
}


def emva_value(results, name: str) -> float | None:
    """One figure off Results1288 (None for NaN or a negative variance's square root)."""
    with numpy_shim(), np.errstate(invalid="ignore"):
        value = getattr(results, name[:-2])() if name.endswith("()") else getattr(results, name)
    value = float(value)
    return value if np.isfinite(value) else None
