"""The EMVA 1288 descriptor data set: a folder of images and the text file that describes them.

The exchange format of the EMVA 1288 reference data sets (github.com/EMVA1288/datasets) and of
the ``emva1288`` reference implementation (sources.md A5; its ``process.parser`` and
``process.loader``). A folder holds ``EMVA1288_Data.txt`` and the images it names; the file's
lines are::

    # a comment (blank lines too are ignored)
    v 4.0                        release of the standard: 3.0, 3.1 or 4.0 (optional, once)
    n 12 640 480                 BITS WIDTH HEIGHT (once, before any step): 8..16 bits, ≥ 1 px
    b 40000.0 120.0              a bright step: EXPOSURE_NS PHOTONS_PER_PIXEL (photons > 0)
    i images\\b_000_snap_001.png  ≥ 2 image lines, relative to the folder; backslashes allowed
    i images\\b_000_snap_002.png
    d 40000.0                    a dark step: EXPOSURE_NS (emva1288 keys it as 0.0 photons)
    i images\\d_000_snap_001.png
    i images\\d_000_snap_002.png

A step of exactly two images is *temporal* (a photon-transfer pair); more than two make a
*spatial* stack (the DSNU/PRNU series), as emva1288's parser decides. Numbers may use a decimal
comma, as emva1288 accepts. Images are PNG or TIFF, single-channel, 8 to 16 bits.

Refused (:class:`DescriptorError`, naming the file, the line, its text and what is allowed):
an unknown line kind; a wrong field count (paths cannot hold spaces: emva1288 splits on
whitespace); a number that is not finite or is negative, a ``b`` with photons ≤ 0; bits outside
8..16, a width or height < 1; a release other than 3.0, 3.1, 4.0; a second ``v`` or ``n``; no
``n``, or ``n`` after a step; a step with fewer than two images; an ``i`` not after a step or an
image; an absolute image path; a missing image file; two steps of the same kind (b/d, temporal/
spatial) at the same exposure and photons; a ``b`` without the ``d`` of its exposure (same
temporal/spatial kind), or a ``d`` without a ``b`` (emva1288's loader refuses both); fewer than
:data:`MIN_TEMPORAL_POINTS` temporal b/d pairs; more than one spatial b/d pair (emva1288's
``Data1288`` reads exactly one). Reading the descriptor opens no image: :func:`load_image` checks
each image (format, mode, size, values) when it is read.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import MISSING, dataclass
from pathlib import Path, PurePosixPath
from typing import NoReturn

import numpy as np
from numpy.typing import NDArray

from chiptwin.config.fields import ScenarioError

DATA_FILE = "EMVA1288_Data.txt"
"""The descriptor's file name inside a data-set folder."""

RELEASES = ("3.0", "3.1", "4.0")
"""Releases of EMVA 1288 whose data sets are read (the format is the same in all three)."""

MIN_TEMPORAL_POINTS = 3
"""Temporal b/d pairs a data set needs: the fewest a photon-transfer line can be fitted to with a
residual (EMVA 1288 Release 4.0 asks for ≥ 50; a real set has them)."""

BITS_RANGE = (8, 16)
"""Allowed digital resolutions (``n`` line). Unit: bits."""

#: Line kind → (its form, its number of fields).
_FORMS = {"v": ("v RELEASE", 2), "n": ("n BITS WIDTH HEIGHT", 4),
          "b": ("b EXPOSURE_NS PHOTONS_PER_PIXEL", 3), "d": ("d EXPOSURE_NS", 2),
          "i": ("i PATH", 2)}
#: Pillow image modes of a single-channel image of up to 16 bits (``I``: 32-bit integer, as
#: older Pillow opened 16-bit PNGs; its values are checked to fit).
_MODES = ("L", "I;16", "I;16L", "I;16B", "I;16N", "I")
_FORMATS = ("PNG", "TIFF")


class DescriptorError(ScenarioError):
    """A data set that cannot be read or written: names the file (descriptor or image), the key
    (``line 23``, ``n``, ``image size``, ``steps[4]``), the value and what is allowed."""


@dataclass(frozen=True)
class Step:
    """One ``b`` or ``d`` line of a descriptor and its images.

    Attributes
    ----------
    kind : str
        ``"b"`` (bright) or ``"d"`` (dark).
    exposure_ns : float
        Exposure time. Unit: ns.
    photons : float
        Mean photons reaching a pixel in the exposure (0.0 for a dark step). Unit: photons/pixel.
    images : tuple of Path
        The images, absolute and resolved, in the descriptor's order.
    line : int
        The step's line in the descriptor (1-based).
    """

    kind: str
    exposure_ns: float
    photons: float
    images: tuple[Path, ...]
    line: int

    @property
    def temporal(self) -> bool:
        """A photon-transfer pair (exactly two images), not a spatial stack."""
        return len(self.images) == 2


@dataclass(frozen=True)
class Descriptor:
    """A data set as its descriptor states it (:func:`read_descriptor` builds a checked one).

    Attributes
    ----------
    path : Path
        The descriptor file, resolved.
    release : str
        The ``v`` line's release, ``""`` when the file has none.
    bits : int
        Digital resolution of the images. Unit: bits.
    width, height : int
        Image size. Unit: pixels.
    steps : tuple of Step
        Every step, in the file's order.
    """

    path: Path
    release: str
    bits: int
    width: int
    height: int
    steps: tuple[Step, ...]

    def temporal_points(self) -> list[tuple[float, float, Step, Step]]:
        """``(exposure_ns, photons, bright, dark)`` of every temporal bright step with the
        temporal dark step of its exposure, sorted by exposure then photons (several bright
        steps at one exposure, light varied instead of time, share its dark step).

        Raises
        ------
        DescriptorError
            A temporal step without its partner, naming its line.
        """
        pairs = _pairs(self.steps, True, str(self.path), _by_line)
        return [(b.exposure_ns, b.photons, b, d) for b, d in pairs]

    def spatial(self) -> tuple[Step, Step] | None:
        """The spatial stacks ``(bright, dark)`` of one exposure, or None when the set has none.

        Raises
        ------
        DescriptorError
            A stack without its partner, or more than one spatial pair (emva1288's ``Data1288``
            evaluates exactly one), naming the line of the second bright stack.
        """
        return _one_spatial(self.steps, str(self.path), _by_line)


# --- reading ---------------------------------------------------------------------------------


def read_descriptor(folder_or_file: str | Path) -> Descriptor:
    """Read and check an EMVA 1288 descriptor (the module docstring lists what is refused).

    Parameters
    ----------
    folder_or_file : str or Path
        The data set's folder (holding ``EMVA1288_Data.txt``) or the descriptor file itself.

    Returns
    -------
    Descriptor
        Image paths absolute; each image file exists (none is opened).

    Raises
    ------
    DescriptorError
        Naming the file, the line (``line N``) or key, the text and what is allowed.
    """
    path = _descriptor_path(folder_or_file)
    reader = _Reader(path)
    for no, text in _content_lines(path):
        reader.line(no, text)
    return reader.finish()


def _descriptor_path(folder_or_file: str | Path) -> Path:
    path = Path(folder_or_file).resolve()
    if path.is_dir():
        path = path / DATA_FILE
    if not path.is_file():
        raise DescriptorError(str(path), "descriptor", str(folder_or_file),
                              f"must be a data-set folder holding {DATA_FILE}, or that file")
    return path


def _content_lines(path: Path) -> Iterator[tuple[int, str]]:
    """``(line number, stripped text)`` of every line that is not blank or a comment. Comments
    may hold any bytes (a copyright notice in Latin-1); the other lines must be UTF-8."""
    raw = path.read_bytes().decode("utf-8", errors="surrogateescape")
    for no, line in enumerate(raw.splitlines(), start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        if re.search("[\udc80-\udcff]", text):
            raise DescriptorError(str(path), f"line {no}", text.encode(errors="surrogateescape"),
                                  "must be UTF-8 text (only # comments may hold other bytes)")
        yield no, text


class _Reader:
    """The parse of one descriptor, line by line: one method per line kind."""

    def __init__(self, path: Path) -> None:
        self.path, self.src, self.folder = path, str(path), path.parent
        self.release: str | None = None
        self.format: tuple[int, int, int] | None = None
        self.steps: list[tuple[str, float, float, int, str, list[Path]]] = []
        self.open = False  # an ``i`` line may follow (a step or an image line came last)

    def line(self, no: int, text: str) -> None:
        fields = text.split()
        kind = fields[0]
        if kind not in _FORMS:
            self._refuse(no, text, "must start with v, n, b, d or i (or # for a comment)")
        form, count = _FORMS[kind]
        if len(fields) != count:
            self._refuse(no, text, f"must be '{form}': {count - 1} field(s) after {kind!r}"
                                   + (" (a path cannot hold spaces)" if kind == "i" else ""))
        if kind != "i":
            self._close_step()
        getattr(self, "_" + kind)(no, text, fields[1:])
        self.open = kind != "v" and kind != "n"

    def _v(self, no: int, text: str, fields: list[str]) -> None:
        if self.release is not None:
            self._refuse(no, text, "a second 'v' line: the release is stated at most once")
        if fields[0] not in RELEASES:
            self._refuse(no, text, f"release must be one of {', '.join(RELEASES)}")
        self.release = fields[0]

    def _n(self, no: int, text: str, fields: list[str]) -> None:
        if self.format is not None:
            self._refuse(no, text, "a second 'n' line: 'n BITS WIDTH HEIGHT' is stated once")
        lo, hi = BITS_RANGE
        bits = self._integer(no, text, fields[0], "BITS", lo, hi)
        width = self._integer(no, text, fields[1], "WIDTH", 1, None)
        height = self._integer(no, text, fields[2], "HEIGHT", 1, None)
        self.format = (bits, width, height)

    def _b(self, no: int, text: str, fields: list[str]) -> None:
        exposure = self._number(no, text, fields[0], "EXPOSURE_NS", positive=False)
        photons = self._number(no, text, fields[1], "PHOTONS_PER_PIXEL", positive=True)
        self._step("b", exposure, photons, no, text)

    def _d(self, no: int, text: str, fields: list[str]) -> None:
        exposure = self._number(no, text, fields[0], "EXPOSURE_NS", positive=False)
        self._step("d", exposure, 0.0, no, text)

    def _step(self, kind: str, exposure: float, photons: float, no: int, text: str) -> None:
        if self.format is None:
            self._refuse(no, text, "a step before the 'n BITS WIDTH HEIGHT' line")
        self.steps.append((kind, exposure, photons, no, text, []))

    def _i(self, no: int, text: str, fields: list[str]) -> None:
        if not self.open or not self.steps:
            self._refuse(no, text, "an 'i' line must follow a b or d line or another 'i' line")
        name = fields[0].replace("\\", "/")
        if PurePosixPath(name).is_absolute() or re.match(r"[A-Za-z]:/", name):
            self._refuse(no, text, f"image paths must be relative to {self.folder}")
        image = (self.folder / name).resolve()
        if not image.is_file():
            self._refuse(no, text, f"names {image}, which does not exist (image paths are "
                                   f"relative to {self.folder})")
        self.steps[-1][5].append(image)

    def _close_step(self) -> None:
        if self.steps and len(self.steps[-1][5]) < 2:
            _, _, _, no, text, images = self.steps[-1]
            self._refuse(no, text, f"is followed by {len(images)} 'i' line(s); a step needs ≥ 2 "
                                   "(2: a temporal pair, > 2: a spatial stack)")

    def finish(self) -> Descriptor:
        self._close_step()
        if self.format is None:
            raise DescriptorError(self.src, "n", MISSING, "the descriptor needs one "
                                  "'n BITS WIDTH HEIGHT' line before its steps")
        steps = tuple(Step(k, e, p, tuple(imgs), no) for k, e, p, no, _, imgs in self.steps)
        texts = {no: text for _, _, _, no, text, _ in self.steps}
        _check_steps(steps, self.src, lambda s: (f"line {s.line}", texts[s.line]))
        return Descriptor(self.path, self.release or "", *self.format, steps)

    def _number(self, no: int, text: str, token: str, name: str, *, positive: bool) -> float:
        try:
            value = float(token.replace(",", "."))
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < 0.0 or (positive and value == 0.0):
            self._refuse(no, text, f"{name} must be a finite number {'>' if positive else '≥'} "
                                   f"0 (got {token!r})")
        return value

    def _integer(self, no: int, text: str, token: str, name: str, lo: int, hi: int | None
                 ) -> int:
        bound = f"in {lo}..{hi}" if hi is not None else f"≥ {lo}"
        if not re.fullmatch(r"\d+", token) or int(token) < lo or (hi is not None
                                                                  and int(token) > hi):
            self._refuse(no, text, f"{name} must be an integer {bound} (got {token!r})")
        return int(token)

    def _refuse(self, no: int, text: str, allowed: str) -> NoReturn:
        raise DescriptorError(self.src, f"line {no}", text, allowed)


# --- the steps' pairing (shared by reading and writing) ---------------------------------------


#: A step's key and value in an error: ``("line 23", "b 40000.0 120.0")`` or ``("steps[4]", …)``.
Label = Callable[["Step"], tuple[str, str]]


def _show(step: Step) -> str:
    what = f"{step.kind} {step.exposure_ns!r}" + (f" {step.photons!r}" if step.kind == "b" else "")
    return f"{what} ({len(step.images)} images)"


def _by_line(step: Step) -> tuple[str, str]:
    return f"line {step.line}", _show(step)


def _pairs(steps: Sequence[Step], temporal: bool, source: str, label: Label
           ) -> list[tuple[Step, Step]]:
    """Each bright step of one kind (temporal or spatial) with the dark step of its exposure,
    sorted by exposure then photons; a step without its partner refused."""
    mine = [s for s in steps if s.temporal == temporal]
    darks = {s.exposure_ns: s for s in mine if s.kind == "d"}
    lit = {s.exposure_ns for s in mine if s.kind == "b"}
    kind = "temporal pair" if temporal else "spatial stack"
    for s in mine:
        if s.exposure_ns not in (lit if s.kind == "d" else darks):
            need = "b" if s.kind == "d" else "d"
            raise DescriptorError(source, *label(s), f"needs a {need} step of the same "
                                  f"exposure ({s.exposure_ns!r} ns), also a {kind}: emva1288 "
                                  "pairs each bright step with the dark of its exposure")
    brights = sorted((s for s in mine if s.kind == "b"), key=lambda s: (s.exposure_ns, s.photons))
    return [(b, darks[b.exposure_ns]) for b in brights]


def _one_spatial(steps: Sequence[Step], source: str, label: Label) -> tuple[Step, Step] | None:
    pairs = _pairs(steps, False, source, label)
    if len(pairs) > 1:
        raise DescriptorError(source, *label(pairs[1][0]),
                              f"a second spatial pair (the first: {_show(pairs[0][0])}); a data "
                              "set has at most one b and one d stack, of one exposure")
    return pairs[0] if pairs else None


def _check_steps(steps: Sequence[Step], source: str, label: Label) -> None:
    """The rules a set of steps obeys whatever its images: no duplicate, each bright step with its
    dark and each dark with a bright, ≥ :data:`MIN_TEMPORAL_POINTS` temporal pairs, at most one
    spatial pair.

    Parameters
    ----------
    steps : sequence of Step
        The steps.
    source : str
        The file (or folder) named by an error.
    label : callable
        A step's key and value in an error (``line 23`` and the line's text, ``steps[4]``).

    Raises
    ------
    DescriptorError
        The first rule broken, naming the step.
    """
    seen: dict[tuple[str, bool, float, float], Step] = {}
    for s in steps:
        key = (s.kind, s.temporal, s.exposure_ns, s.photons)
        if key in seen:
            raise DescriptorError(source, *label(s), "a second step of the same kind, "
                                  f"exposure and photons as {label(seen[key])[0]}")
        seen[key] = s
    n = len(_pairs(steps, True, source, label))
    if n < MIN_TEMPORAL_POINTS:
        raise DescriptorError(source, "temporal points", n, f"needs ≥ {MIN_TEMPORAL_POINTS} "
                              "b/d pairs of 2 images each to fit the photon transfer "
                              "(EMVA 1288 Release 4.0 asks for ≥ 50)")
    _one_spatial(steps, source, label)


# --- images ----------------------------------------------------------------------------------


def load_image(d: Descriptor, path: str | Path) -> NDArray[np.uint16]:
    """One image of the data set, checked against the descriptor.

    Parameters
    ----------
    d : Descriptor
        The data set (its bits and image size).
    path : str or Path
        The image: PNG or TIFF, one frame, a single channel of 8 to 16 bits (Pillow modes ``L``,
        ``I;16``, ``I;16B``…, or ``I``, as older Pillow opened 16-bit PNGs, when its values fit).

    Returns
    -------
    ndarray of uint16, shape (height, width)
        The values (an 8-bit image promoted). Unit: DN.

    Raises
    ------
    DescriptorError
        Naming the image file, what it has and what the descriptor says.
    """
    from PIL import Image, UnidentifiedImageError

    src = str(path)
    try:
        with Image.open(path) as img:
            frames = getattr(img, "n_frames", 1)
            if img.format not in _FORMATS or img.mode not in _MODES or frames != 1:
                raise DescriptorError(src, "image mode", f"{img.format} {img.mode}, {frames} "
                                      "frame(s)", "must be one PNG or TIFF frame, a single "
                                      f"channel of 8 to 16 bits (Pillow mode {', '.join(_MODES)})")
            size, values = img.size, np.asarray(img)
    except (UnidentifiedImageError, OSError) as exc:
        raise DescriptorError(src, "image", type(exc).__name__, "must be a readable PNG or TIFF "
                              f"image ({exc})") from exc
    says = f"{d.path} line 'n {d.bits} {d.width} {d.height}'"
    if size != (d.width, d.height):
        raise DescriptorError(src, "image size", f"{size[0]} x {size[1]}",
                              f"must be {d.width} x {d.height} (width x height) as {says} says")
    return _fit(values, d.bits, src, "image values", says)


def _fit(values: np.ndarray, bits: int, src: str, key: str, says: str) -> NDArray[np.uint16]:
    """``values`` as uint16, checked to lie in 0..2**bits − 1 (``says``: where ``bits`` comes
    from, for the message)."""
    lo, hi = int(values.min()), int(values.max())
    if lo < 0 or hi >= 1 << bits:
        raise DescriptorError(src, key, f"{lo}..{hi}",
                              f"must be in 0..{(1 << bits) - 1} ({bits} bits, as {says} says)")
    return values.astype(np.uint16)


def stack_images(d: Descriptor, step: Step) -> Iterator[NDArray[np.uint16]]:
    """The step's images one at a time (:func:`load_image`), so a stack of L images never needs
    L images of memory."""
    for path in step.images:
        yield load_image(d, path)


# --- writing ---------------------------------------------------------------------------------


__all__ = ["BITS_RANGE", "DATA_FILE", "MIN_TEMPORAL_POINTS", "RELEASES", "Descriptor",
           "DescriptorError", "Step", "load_image", "read_descriptor", "stack_images"]
