"""Writing an EMVA 1288 descriptor data set (:mod:`chiptwin.characterize.descriptor` reads
one): ``EMVA1288_Data.txt`` and 16-bit PNG images, checked by the reader's rules first and written
whole or not at all."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chiptwin.characterize.descriptor import (
    BITS_RANGE,
    DATA_FILE,
    RELEASES,
    DescriptorError,
    Step,
    _check_steps,
    _fit,
    _show,
)
from chiptwin.config.fields import ScenarioError


def write_descriptor(folder: str | Path, *, bits: int, width: int, height: int,
                     steps: Sequence[tuple[str, float, float, Sequence[Any]]],
                     release: str = "4.0", header: str = "") -> Path:
    """Write a data set: ``EMVA1288_Data.txt`` and ``images/*.png``, whole or not at all.

    Everything is checked before anything is written, by the rules :func:`read_descriptor`
    applies; the set is written into a temporary sibling folder that then replaces ``folder``
    (:func:`chiptwin.config.outputs.replacing`), which must be new, empty, or a previous data set
    (it holds ``EMVA1288_Data.txt``).

    Image lines use backslashes (``i images\\b_000_snap_001.png``), as the reference data sets
    write them: emva1288's parser splits paths on backslashes on every system (on Linux its
    ``normpath`` leaves them alone), and so does :func:`read_descriptor`. Images are 16-bit
    grayscale PNG named as the reference sets name them: ``b_000_snap_001.png`` and ``…_002``
    for a pair, ``b_s_000_snap_000.png`` onward for a stack (``d`` likewise), numbered per kind
    in the order given.

    Parameters
    ----------
    folder : str or Path
        The data set's folder.
    bits : int
        Digital resolution, 8..16. Unit: bits.
    width, height : int
        Image size. Unit: pixels.
    steps : sequence of (kind, exposure_ns, photons, images)
        ``kind`` ``"b"`` or ``"d"``; exposure ≥ 0; photons per pixel > 0 for ``b``, 0 for ``d``;
        ≥ 2 integer arrays of shape (height, width) with values in 0..2**bits − 1.
        Unit: ns, photons/pixel, DN.
    release : str
        The ``v`` line: 3.0, 3.1 or 4.0.
    header : str
        A comment written at the top (each line prefixed ``#``).

    Returns
    -------
    Path
        The folder, resolved.

    Raises
    ------
    DescriptorError
        ``source`` the folder; ``key`` ``steps[i]``, ``steps[i].images[j]``, ``bits``, ``width``,
        ``height``, ``release`` or ``folder``. Nothing is written.
    """
    from chiptwin.config.outputs import check_out_dir, replacing

    out = Path(folder).resolve()
    src = str(out)
    _check_format(src, bits, width, height, release)
    head = [f"# {h}".rstrip() for h in header.splitlines()]
    head += [f"v {release}", f"n {bits} {width} {height}"]
    planned = _plan(out, steps, src, first_line=len(head) + 1)
    images = [_checked_images(src, i, s[3], bits, width, height) for i, s in enumerate(steps)]
    by_line = {s.line: f"steps[{i}]" for i, s in enumerate(planned)}
    _check_steps(planned, src, lambda s: (by_line[s.line], _show(s)))
    try:
        out = check_out_dir(out, marker=DATA_FILE)
    except ScenarioError as exc:
        raise DescriptorError(src, "folder", exc.value, exc.allowed) from exc
    with replacing(out) as tmp:
        (tmp / "images").mkdir()
        for step, arrays in zip(planned, images, strict=True):
            for path, arr in zip(step.images, arrays, strict=True):
                _write_png(tmp / path.relative_to(out), arr)
        text = "\n".join(head + _step_lines(planned, out)) + "\n"
        (tmp / DATA_FILE).write_text(text, encoding="utf-8")
    return out


def _check_format(src: str, bits: int, width: int, height: int, release: str) -> None:
    lo, hi = BITS_RANGE
    for key, value, low, high in (("bits", bits, lo, hi), ("width", width, 1, None),
                                  ("height", height, 1, None)):
        if (not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low
                or (high is not None and value > high)):
            raise DescriptorError(src, key, value, f"must be an integer ≥ {low}"
                                  + (f" and ≤ {high}" if high is not None else ""))
    if release not in RELEASES:
        raise DescriptorError(src, "release", release, f"must be one of {', '.join(RELEASES)}")


def _plan(out: Path, steps: Sequence[tuple[str, float, float, Sequence[Any]]], src: str,
          first_line: int) -> list[Step]:
    """The steps as they will be written: numbers checked, image paths named, ``line`` the line
    each will have in the descriptor (the first at ``first_line``)."""
    planned, counters, line = [], {}, first_line
    for i, item in enumerate(steps):
        if len(item) != 4:
            raise DescriptorError(src, f"steps[{i}]", item, "must be (kind, exposure_ns, "
                                  "photons, images)")
        kind, exposure, photons, arrays = item
        exposure, photons = _checked_numbers(src, i, kind, exposure, photons)
        if len(arrays) < 2:
            raise DescriptorError(src, f"steps[{i}]", f"{len(arrays)} image(s)",
                                  "a step needs ≥ 2 images (2: temporal pair, > 2: spatial stack)")
        group = f"{kind}_s" if len(arrays) > 2 else kind
        k = counters[group] = counters.get(group, -1) + 1
        first = 0 if len(arrays) > 2 else 1
        names = tuple(out / "images" / f"{group}_{k:03d}_snap_{j + first:03d}.png"
                      for j in range(len(arrays)))
        planned.append(Step(kind, exposure, photons, names, line))
        line += 1 + len(names)
    return planned


def _checked_numbers(src: str, i: int, kind: Any, exposure: Any, photons: Any
                     ) -> tuple[float, float]:
    if kind not in ("b", "d"):
        raise DescriptorError(src, f"steps[{i}]", kind, "kind must be 'b' (bright) or 'd' (dark)")
    try:
        e, p = float(exposure), float(photons)
    except (TypeError, ValueError):
        e = p = math.nan
    if not (math.isfinite(e) and e >= 0.0):
        raise DescriptorError(src, f"steps[{i}]", exposure, "exposure_ns must be a finite "
                              "number ≥ 0 (ns)")
    if not math.isfinite(p) or (kind == "b" and p <= 0.0) or (kind == "d" and p != 0.0):
        raise DescriptorError(src, f"steps[{i}]", photons, "photons must be a finite number "
                              "> 0 for a 'b' step and 0 for a 'd' step (photons/pixel)")
    return e, p


def _checked_images(src: str, i: int, arrays: Sequence[Any], bits: int, width: int, height: int
                    ) -> list[NDArray[np.uint16]]:
    out = []
    for j, a in enumerate(arrays):
        arr, key = np.asarray(a), f"steps[{i}].images[{j}]"
        if arr.dtype.kind not in "ui" or arr.shape != (height, width):
            raise DescriptorError(src, key, f"{arr.dtype} array of shape {arr.shape}",
                                  f"must be an integer array of shape ({height}, {width})")
        out.append(_fit(arr, bits, src, key, "the bits argument"))
    return out


def _step_lines(planned: list[Step], out: Path) -> list[str]:
    lines = []
    for s in planned:
        lines.append(f"b {s.exposure_ns!r} {s.photons!r}" if s.kind == "b"
                     else f"d {s.exposure_ns!r}")
        lines += ["i " + "\\".join(p.relative_to(out).parts) for p in s.images]
    return lines


def _write_png(path: Path, arr: NDArray[np.uint16]) -> None:
    """A 16-bit grayscale PNG (Pillow mode ``I;16``)."""
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(arr, dtype=np.uint16)).save(path, format="PNG")


__all__ = ["write_descriptor"]
