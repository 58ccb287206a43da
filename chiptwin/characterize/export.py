"""The twin's own protocol written as an EMVA 1288 data set (``--write-measured``): the images of
the bench, as a camera's, for any tool that reads the format (the ``emva1288`` package among
them).

A data set has one image size, so the bench measures single-frame images for it (no mosaic:
:func:`single_frame_protocol`). The chip's CMS frame is in steps of 1/M LSB and can be negative
in the dark; a camera's images are non-negative integers. Each image is written as
``M × (CMS frame + black level)``, the black level the mean reset code of the dark images rounded
to a whole 1/M LSB: integers in units of DN/M (K and σ_y scale by M, η and the electron figures
do not), on the format's 8–16 bits.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from chiptwin.characterize.measure import Measurement
from chiptwin.characterize.protocol import Protocol
from chiptwin.config import ScenarioError


def single_frame_protocol(protocol: Protocol | None = None) -> Protocol:
    """The protocol with one chip frame per temporal image (``min_values = 2``)."""
    import dataclasses

    return dataclasses.replace(protocol or Protocol(), min_values=2)


def _integer_images(m: Measurement, black: int) -> dict[str, list[np.ndarray]]:
    """Every image of a kept measurement as ``M × frame + black``, integers (checked on the
    1/M grid)."""
    scale, cam = m.camera.cms_samples, m.camera
    out: dict[str, list[np.ndarray]] = {}

    def whole(img: np.ndarray) -> np.ndarray:
        x = np.asarray(img, np.float64).reshape(cam.rows, -1) * scale
        r = np.rint(x)
        if np.max(np.abs(x - r), initial=0.0) > 1e-6:
            raise ValueError("a CMS frame off the 1/M grid")  # a bug, not bad input
        return (r + black).astype(np.int64)

    out["ptc"] = [[whole(x) for x in imgs] for imgs in m.images["ptc"]]
    out["spatial_bright"] = [whole(x) for x in m.images["spatial_bright"]]
    out["spatial_dark"] = [whole(x) for x in m.images["spatial_dark"]]
    return out


def write_measured(m: Measurement, folder: str | Path, name: str) -> Path:
    """Write a measurement kept with its images (``keep_images``, single frames) as a data set.

    Refused (:class:`ScenarioError`, nothing written) when the images need more than the
    format's 16 bits.
    """
    from chiptwin.characterize.descriptor_write import write_descriptor

    if m.tiles != 1:
        raise ValueError("write_measured needs single-frame images (single_frame_protocol)")
    scale = m.camera.cms_samples
    black = int(round(scale * m.temporal.reset_level_dn))
    images = _integer_images(m, black)
    every = [x for imgs in images["ptc"] for x in imgs] + images["spatial_bright"] + \
        images["spatial_dark"]
    lo, hi = min(int(x.min()) for x in every), max(int(x.max()) for x in every)
    bits = max(8, math.ceil(math.log2(hi + 1)))
    if lo < 0 or bits > 16:
        raise ScenarioError("chiptwin", "--write-measured", str(folder),
                            f"the chip's images span {lo} … {hi} DN/{scale} (M = {scale} CMS "
                            "samples): the format holds 0 … 65535 (16 bits)")
    t, sp = m.temporal, m.spatial
    steps = []
    for texp, mu_p, (a, b, c, d) in zip(t.t_exp_s, t.mu_p, images["ptc"], strict=True):
        steps += [("b", float(texp * 1e9), float(mu_p), [a, b]),
                  ("d", float(texp * 1e9), 0.0, [c, d])]
    steps += [("b", float(sp.t_exp_s * 1e9), float(sp.mu_p), images["spatial_bright"]),
              ("d", float(sp.t_exp_s * 1e9), 0.0, images["spatial_dark"])]
    header = (f"The twin's EMVA 1288 protocol on {name}, written by chiptwin: images are "
              f"{scale} x (CMS frame + black level {black / scale:g} DN), in DN/{scale}.")
    return write_descriptor(folder, bits=bits, width=m.camera.cols, height=m.camera.rows,
                            steps=steps, release="4.0", header=header)


__all__ = ["single_frame_protocol", "write_measured"]
