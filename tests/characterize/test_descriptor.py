"""The EMVA 1288 descriptor data set (:mod:`chiptwin.characterize.descriptor`).

* unit: every refusal of the reader, the image loader and the writer names the file, the line
  (or image, or step), the value and what is allowed, and a refused write leaves nothing;
* equivalence: the real reference set (Basler CCD, 12 bits, cropped to 128 × 128) reads as the
  ``emva1288`` reference implementation's parser reads it (sources.md A5), and a written set
  reads back bit for bit with ours and with emva1288's parser and loader.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from chiptwin.characterize import descriptor as dsc
from chiptwin.characterize import descriptor_write
from chiptwin.characterize.descriptor import (
    DATA_FILE,
    DescriptorError,
    load_image,
    read_descriptor,
    stack_images,
)
from chiptwin.characterize.descriptor_write import _write_png, write_descriptor
from tests.characterize._emva import numpy_shim
from tests.conftest import real_data


def _real() -> Path:
    return real_data("emva1288", "set001_ccd_12bit_crop128")


def _emva_parse(path: Path):
    from emva1288.process.parser import ParseEmvaDescriptorFile

    return ParseEmvaDescriptorFile(str(path), loglevel=logging.WARNING)


def _as_sets(d: dsc.Descriptor) -> set[tuple[str, float, float, tuple[Path, ...]]]:
    return {("temporal" if s.temporal else "spatial", s.exposure_ns, s.photons, s.images)
            for s in d.steps}


def _emva_sets(images: dict) -> set[tuple[str, float, float, tuple[Path, ...]]]:
    return {(kind, exposure, photons, tuple(Path(f).resolve() for f in files))
            for kind, by_exposure in images.items()
            for exposure, by_photons in by_exposure.items()
            for photons, files in by_photons.items()}


# --- the real reference set -------------------------------------------------------------------


def test_real_set_reads_as_its_descriptor_states():
    d = read_descriptor(_real())
    assert (d.release, d.bits, d.width, d.height, len(d.steps)) == ("3.0", 12, 128, 128, 102)
    points = d.temporal_points()
    assert len(points) == 50
    exposure, photons, bright, dark = points[0]
    assert (exposure, photons) == (40000.0, 120.0)
    assert (bright.kind, dark.kind, dark.exposure_ns, dark.photons) == ("b", "d", 40000.0, 0.0)
    assert [p[0] for p in points] == sorted(p[0] for p in points)
    b, k = d.spatial()
    assert (b.exposure_ns, b.photons, len(b.images), k.exposure_ns, len(k.images)) == (
        5160000.0, 15508.0, 50, 5160000.0, 50)
    assert b.images[0].name == "b_s_000_snap_000.png" and b.images[0].is_absolute()
    img = load_image(d, bright.images[0])
    assert img.shape == (128, 128) and img.dtype == np.uint16 and 0 < img.max() < 4096


def test_real_set_reads_as_emva1288_parses_it():
    folder = _real()
    ours = read_descriptor(folder / DATA_FILE)
    theirs = _emva_parse(folder / DATA_FILE)
    assert _as_sets(ours) == _emva_sets(theirs.images)
    assert theirs.format == {"bits": 12, "width": 128, "height": 128}
    assert len(_as_sets(ours)) == 102


# --- a written set, read back -----------------------------------------------------------------

W, H, BITS = 16, 12, 12
EXPOSURES = (1000.0, 2000.0, 4000.0, 8000.0, 16000.0)


def _small_steps(rng: np.random.Generator, spatial: bool = True) -> list:
    def imgs(n: int, level: float) -> list[np.ndarray]:
        return [rng.poisson(level, (H, W)).clip(0, 2**BITS - 1).astype(np.uint16)
                for _ in range(n)]

    steps = []
    for t in EXPOSURES:
        steps.append(("b", t, t / 10.0, imgs(2, 50.0 + t / 20.0)))
        steps.append(("d", t, 0.0, imgs(2, 50.0)))
    if spatial:
        steps += [("b", 3000.0, 300.0, imgs(4, 200.0)), ("d", 3000.0, 0.0, imgs(4, 50.0))]
    steps[0][3][0][0, 0] = 2**BITS - 1  # the top code survives the round trip
    return steps


def test_round_trip_through_ours_is_bit_exact(tmp_path):
    steps = _small_steps(np.random.default_rng(1))
    out = write_descriptor(tmp_path / "set", bits=BITS, width=W, height=H, steps=steps,
                           header="round trip\nsecond line")
    assert out == (tmp_path / "set").resolve()
    d = read_descriptor(out)
    assert (d.release, d.bits, d.width, d.height) == ("4.0", BITS, W, H)
    assert [(s.kind, s.exposure_ns, s.photons) for s in d.steps] == [
        (k, t, p) for k, t, p, _ in steps]
    for step, (_, _, _, arrays) in zip(d.steps, steps, strict=True):
        for got, want in zip(stack_images(d, step), arrays, strict=True):
            assert got.dtype == np.uint16 and np.array_equal(got, want)
    assert [p[:2] for p in d.temporal_points()] == [(t, t / 10.0) for t in EXPOSURES]
    assert d.spatial()[0].photons == 300.0 and len(d.spatial()[1].images) == 4
    names = sorted(p.name for p in (out / "images").iterdir())
    assert names[0] == "b_000_snap_001.png" and "d_s_000_snap_003.png" in names
    assert len(names) == 5 * 4 + 8


def test_written_lines_use_backslashes_and_the_reference_layout(tmp_path):
    out = write_descriptor(tmp_path / "set", bits=BITS, width=W, height=H,
                           steps=_small_steps(np.random.default_rng(2)), release="3.1",
                           header="made by a test")
    lines = (out / DATA_FILE).read_text().splitlines()
    assert lines[:4] == ["# made by a test", "v 3.1", f"n {BITS} {W} {H}", "b 1000.0 100.0"]
    assert lines[4] == "i images\\b_000_snap_001.png"
    assert "b 3000.0 300.0" in lines and "i images\\d_s_000_snap_000.png" in lines


def test_round_trip_through_emva1288_parser_and_loader(tmp_path):
    from emva1288.process.loader import LoadImageData

    steps = _small_steps(np.random.default_rng(3))
    out = write_descriptor(tmp_path / "set", bits=BITS, width=W, height=H, steps=steps)
    parsed = _emva_parse(out / DATA_FILE)
    assert parsed.format == {"bits": BITS, "width": W, "height": H}
    assert _emva_sets(parsed.images) == _as_sets(read_descriptor(out))
    with numpy_shim():
        data = LoadImageData(parsed.images, loglevel=logging.WARNING).data
    assert (data["height"], data["width"]) == (H, W)
    temporal = {t: {} for t in EXPOSURES}
    for _, t, photons, arrays in steps[:-2]:
        temporal[t][photons] = sum(int(a.astype(np.int64).sum()) for a in arrays)
    assert {t: {p: int(v["sum"]) for p, v in by.items()}
            for t, by in data["temporal"].items()} == temporal
    spatial = data["spatial"][3000.0]
    assert sorted(spatial) == [0.0, 300.0]
    want = sum(a.astype(np.int64) for a in steps[-2][3])
    assert np.array_equal(spatial[300.0]["sum"], want) and spatial[300.0]["L"] == 4


def test_a_set_replaces_a_previous_set_whole(tmp_path):
    rng = np.random.default_rng(4)
    folder = tmp_path / "set"
    write_descriptor(folder, bits=BITS, width=W, height=H, steps=_small_steps(rng))
    write_descriptor(folder, bits=BITS, width=W, height=H, steps=_small_steps(rng, spatial=False))
    assert read_descriptor(folder).spatial() is None
    assert not any("_s_" in p.name for p in (folder / "images").iterdir())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]


# --- reading: what is accepted ----------------------------------------------------------------

IMAGES = ("a.png", "b.png", "c.png")


def _step(kind: str, exposure: str, photons: str = "", n: int = 2, sep: str = "\\") -> list[str]:
    head = f"b {exposure} {photons}" if kind == "b" else f"d {exposure}"
    return [head] + [f"i images{sep}{IMAGES[j]}" for j in range(n)]


def _base() -> list[str]:
    """A valid descriptor: 3 temporal points, one spatial pair of 3 images, 4 × 3 images."""
    lines = ["# a test set", "", "v 4.0", "n 12 4 3"]
    for t, p in (("1000", "10"), ("2000", "20"), ("3000", "30")):
        lines += _step("b", t, p) + _step("d", t)
    return lines + _step("b", "5000", "50", n=3) + _step("d", "5000", n=3)


def _folder(tmp_path: Path, lines: list[str], encoding: str = "utf-8") -> Path:
    """A data-set folder: three 4 × 3 8-bit images and the descriptor ``lines``."""
    folder = tmp_path / "set"
    (folder / "images").mkdir(parents=True, exist_ok=True)
    for k, name in enumerate(IMAGES):
        Image.fromarray(np.full((3, 4), 10 * k, np.uint8)).save(folder / "images" / name)
    (folder / DATA_FILE).write_bytes("\n".join(lines).encode(encoding))
    return folder


def test_the_base_set_reads(tmp_path):
    d = read_descriptor(_folder(tmp_path, _base()))
    assert len(d.temporal_points()) == 3 and d.spatial()[0].exposure_ns == 5000.0
    assert d.steps[0].line == 5 and d.steps[0].images[1].name == "b.png"


def test_forward_slashes_decimal_commas_and_no_release_are_read(tmp_path):
    lines = [x for x in _base() if not x.startswith("v ")]
    lines[lines.index("b 2000 20")] = "b 2000,5 20,25"
    lines[lines.index("d 2000")] = "d 2000,5"
    lines[lines.index("b 1000 10") + 1] = "i images/a.png"
    d = read_descriptor(_folder(tmp_path, lines))
    assert d.release == ""
    assert [p[:2] for p in d.temporal_points()][1] == (2000.5, 20.25)
    assert d.steps[0].images[0] == (tmp_path / "set" / "images" / "a.png").resolve()


def test_a_latin1_comment_is_skipped(tmp_path):
    lines = ["# Copyright Müller GmbH", *_base()]
    assert read_descriptor(_folder(tmp_path, lines, encoding="latin-1")).bits == 12


def test_bright_steps_at_one_exposure_share_its_dark(tmp_path):
    lines = _base() + _step("b", "3000", "60")
    points = read_descriptor(_folder(tmp_path, lines)).temporal_points()
    assert [(t, p) for t, p, _, _ in points][-2:] == [(3000.0, 30.0), (3000.0, 60.0)]
    assert points[-1][3] is points[-2][3]


# --- reading: what is refused -----------------------------------------------------------------


def _replace(old: str, *new: str):
    def edit(lines: list[str]) -> list[str]:
        k = lines.index(old)
        return lines[:k] + list(new) + lines[k + 1:]
    return edit


def _drop_step(head: str):
    def edit(lines: list[str]) -> list[str]:
        k = lines.index(head)
        end = k + 1
        while end < len(lines) and lines[end].startswith("i "):
            end += 1
        return lines[:k] + lines[end:]
    return edit


def _append(*new: str):
    return lambda lines: lines + list(new)


#: (id, edit of the base lines, the offending line's text, a fragment of what is allowed).
BAD_LINES = [
    ("unknown kind", _replace("v 4.0", "x 4.0"), "x 4.0", "must start with v, n, b, d or i"),
    ("b field count", _replace("b 1000 10", "b 1000"), "b 1000", "b EXPOSURE_NS PHOTONS"),
    ("d field count", _replace("d 1000", "d 1000 0"), "d 1000 0", "d EXPOSURE_NS"),
    ("path with a space", _append("i images\\a b.png"), "i images\\a b.png",
     "a path cannot hold spaces"),
    ("not a number", _replace("b 1000 10", "b 1ms 10"), "b 1ms 10", "'1ms'"),
    ("infinite", _replace("b 1000 10", "b inf 10"), "b inf 10", "finite number ≥ 0"),
    ("nan", _replace("d 1000", "d nan"), "d nan", "finite number ≥ 0"),
    ("negative", _replace("b 1000 10", "b -1000 10"), "b -1000 10", "≥ 0"),
    ("negative photons", _replace("b 1000 10", "b 1000 -10"), "b 1000 -10", "> 0"),
    ("zero photons", _replace("b 1000 10", "b 1000 0"), "b 1000 0", "PHOTONS_PER_PIXEL"),
    ("bits low", _replace("n 12 4 3", "n 7 4 3"), "n 7 4 3", "BITS must be an integer in 8..16"),
    ("bits high", _replace("n 12 4 3", "n 17 4 3"), "n 17 4 3", "in 8..16"),
    ("bits not whole", _replace("n 12 4 3", "n 12.0 4 3"), "n 12.0 4 3", "'12.0'"),
    ("width zero", _replace("n 12 4 3", "n 12 0 3"), "n 12 0 3", "WIDTH must be an integer ≥ 1"),
    ("height negative", _replace("n 12 4 3", "n 12 4 -3"), "n 12 4 -3", "HEIGHT"),
    ("release", _replace("v 4.0", "v 2.0"), "v 2.0", "3.0, 3.1, 4.0"),
    ("second release", _replace("n 12 4 3", "n 12 4 3", "v 3.0"), "v 3.0", "at most once"),
    ("second n", _replace("v 4.0", "n 12 4 3"), "n 12 4 3", "a second 'n' line"),
    ("second n after steps", _append("n 12 4 3"), "n 12 4 3", "a second 'n' line"),
    ("step before n", lambda x: [v for v in x if not v.startswith("n ")] + ["n 12 4 3"],
     "b 1000 10", "a step before the 'n"),
    ("one image", _replace("i images\\b.png", ), "b 1000 10", "a step needs ≥ 2"),
    ("no image at the end", _append("d 9000"), "d 9000", "followed by 0 'i' line(s)"),
    ("i before any step", _replace("n 12 4 3", "n 12 4 3", "i images/a.png"),
     "i images/a.png", "must follow a b or d line"),
    ("i after v", lambda x: _replace("d 1000", "v 4.0", "i images/c.png", "d 1000")(x[:2] + x[3:]),
     "i images/c.png", "must follow a b or d line"),
    ("missing image", _append("b 9000 90", "i images\\a.png", "i images\\nope.png"),
     "i images\\nope.png", "nope.png, which does not exist"),
    ("absolute path", _append("b 9000 90", "i /etc/a.png", "i images\\a.png"), "i /etc/a.png",
     "must be relative"),
    ("duplicate", _append(*_step("b", "1000.0", "10.0")), "b 1000.0 10.0",
     "a second step of the same kind, exposure and photons as line 5"),
    ("duplicate dark", _append(*_step("d", "1e3")), "d 1e3", "as line 8"),
    ("b without d", _drop_step("d 2000"), "b 2000 20", "needs a d step of the same exposure"),
    ("d without b", _drop_step("b 2000 20"), "d 2000", "needs a b step"),
    ("spatial b without d", _drop_step("d 5000"), "b 5000 50", "also a spatial stack"),
    ("two spatial pairs", _append(*_step("b", "6000", "60", n=3), *_step("d", "6000", n=3)),
     "b 6000 60", "a second spatial pair"),
]


@pytest.mark.parametrize(("edit", "text", "allowed"), [c[1:] for c in BAD_LINES],
                         ids=[c[0] for c in BAD_LINES])
def test_a_bad_line_is_refused_naming_file_line_text_and_rule(tmp_path, edit, text, allowed):
    lines = edit(_base())
    folder = _folder(tmp_path, lines)
    with pytest.raises(DescriptorError) as err:
        read_descriptor(folder)
    e = err.value
    key = f"line {len(lines) - lines[::-1].index(text)}"  # its last occurrence
    assert (e.source, e.key, e.value) == (str(folder / DATA_FILE), key, text), str(e)
    assert allowed in e.allowed, e.allowed
    assert str(e).startswith(f"{folder / DATA_FILE}: {key} = {text!r}: ")


def test_a_missing_n_line_is_refused(tmp_path):
    folder = _folder(tmp_path, ["v 4.0"])
    with pytest.raises(DescriptorError, match=r"EMVA1288_Data.txt: n = \(missing\): ") as err:
        read_descriptor(folder)
    assert err.value.key == "n" and "'n BITS WIDTH HEIGHT'" in err.value.allowed


def test_too_few_temporal_points_are_refused(tmp_path):
    folder = _folder(tmp_path, _drop_step("b 3000 30")(_drop_step("d 3000")(_base())))
    with pytest.raises(DescriptorError) as err:
        read_descriptor(folder)
    e = err.value
    assert (e.source, e.key, e.value) == (str(folder / DATA_FILE), "temporal points", 2)
    assert "needs ≥ 3 b/d pairs" in e.allowed


def test_bytes_that_are_not_utf8_outside_a_comment_are_refused(tmp_path):
    lines = _base()
    lines[lines.index("v 4.0")] = "v 4.0 é"
    folder = _folder(tmp_path, lines, encoding="latin-1")
    with pytest.raises(DescriptorError, match="line 3 = b'v 4.0 \\\\xe9': must be UTF-8"):
        read_descriptor(folder)


def test_a_folder_without_a_descriptor_is_refused(tmp_path):
    with pytest.raises(DescriptorError, match=f"holding {DATA_FILE}") as err:
        read_descriptor(tmp_path)
    assert err.value.source == str(tmp_path / DATA_FILE) and err.value.key == "descriptor"


# --- images -----------------------------------------------------------------------------------


@pytest.fixture
def desc(tmp_path) -> dsc.Descriptor:
    """The base set's descriptor: 12 bits, 4 × 3 images."""
    return read_descriptor(_folder(tmp_path, _base()))


VALUES = np.array([[0, 1, 255, 7], [100, 200, 3, 4], [9, 8, 6, 5]])


@pytest.mark.parametrize(("dtype", "suffix", "mode"), [
    (np.uint8, "png", "L"), (np.uint16, "png", "I;16"), (np.uint16, "tif", "I;16"),
    (">u2", "tif", "I;16B"), (np.int32, "tif", "I")])
def test_8_and_16_bit_png_and_tiff_load_with_their_values(desc, tmp_path, dtype, suffix, mode):
    values = VALUES if dtype == np.uint8 else VALUES * 16 + 15  # 12-bit: up to 4095
    path = tmp_path / f"x.{suffix}"
    img = Image.fromarray(values.astype(dtype)) if mode != "I;16B" else (
        Image.frombytes("I;16B", (4, 3), values.astype(">u2").tobytes()))
    img.save(path)
    assert Image.open(path).mode == mode
    got = load_image(desc, path)
    assert got.dtype == np.uint16 and got.shape == (3, 4) and np.array_equal(got, values)


def _image(tmp_path: Path, name: str, img: Image.Image, **save) -> Path:
    path = tmp_path / name
    img.save(path, **save)
    return path


def _bad_images(tmp_path: Path) -> dict[str, tuple[Path, str, str, str]]:
    """id → (image, key, a fragment of the value, a fragment of what is allowed)."""
    big = Image.fromarray(np.full((3, 4), 4096, np.uint16))
    frames = [Image.fromarray(np.zeros((3, 4), np.uint8))] * 2
    text = tmp_path / "text.png"
    text.write_text("not an image")
    return {
        "size": (_image(tmp_path, "s.png", Image.fromarray(np.zeros((4, 3), np.uint16))),
                 "image size", "3 x 4", "must be 4 x 3 (width x height) as "),
        "values": (_image(tmp_path, "v.png", big), "image values", "4096..4096",
                   "0..4095 (12 bits"),
        "rgb": (_image(tmp_path, "c.png", Image.new("RGB", (4, 3))), "image mode", "PNG RGB",
                "single channel"),
        "alpha": (_image(tmp_path, "la.png", Image.new("LA", (4, 3))), "image mode", "PNG LA",
                  "single channel"),
        "float": (_image(tmp_path, "f.tif", Image.fromarray(np.zeros((3, 4), np.float32))),
                  "image mode", "TIFF F", "8 to 16 bits"),
        "jpeg": (_image(tmp_path, "j.jpg", Image.new("L", (4, 3))), "image mode", "JPEG L",
                 "PNG or TIFF"),
        "two frames": (_image(tmp_path, "m.tif", frames[0], save_all=True,
                              append_images=frames[1:]), "image mode", "2 frame(s)", "one PNG"),
        "not an image": (text, "image", "UnidentifiedImageError", "readable PNG or TIFF"),
        "missing": (tmp_path / "gone.png", "image", "FileNotFoundError", "readable"),
    }


@pytest.mark.parametrize("case", ["size", "values", "rgb", "alpha", "float", "jpeg",
                                  "two frames", "not an image", "missing"])
def test_a_bad_image_is_refused_naming_it_and_the_descriptor(desc, tmp_path, case):
    path, key, value, allowed = _bad_images(tmp_path)[case]
    with pytest.raises(DescriptorError) as err:
        load_image(desc, path)
    e = err.value
    assert (e.source, e.key) == (str(path), key) and value in e.value, str(e)
    assert allowed in e.allowed, e.allowed
    if key in ("image size", "image values"):
        assert str(desc.path) in e.allowed and "n 12 4 3" in e.allowed


def test_stack_images_loads_a_step_in_order(desc):
    stack = list(stack_images(desc, desc.spatial()[0]))
    assert [int(a[0, 0]) for a in stack] == [0, 10, 20]


# --- writing: what is refused (and nothing is written) ----------------------------------------


def _bad_steps(rng: np.random.Generator) -> dict[str, tuple[dict, str, str]]:
    """id → (keyword changes to a valid call, the key, a fragment of what is allowed)."""
    def steps(k: int, item: tuple) -> list:
        s = _small_steps(rng)
        s[k] = item
        return s

    ok = _small_steps(rng)
    img = ok[0][3][0]
    negative = img.astype(np.int64)
    negative[1, 1] = -1
    return {
        "over bits": ({"steps": steps(1, ("d", 1000.0, 0.0, [img, img | 4096]))},
                      "steps[1].images[1]", "0..4095 (12 bits, as the bits argument says)"),
        "negative": ({"steps": steps(0, ("b", 1000.0, 100.0, [img, negative]))},
                     "steps[0].images[1]", "0..4095"),
        "shape": ({"steps": steps(2, ("b", 2000.0, 200.0, [img, img.T]))},
                  "steps[2].images[1]", "shape (12, 16)"),
        "float": ({"steps": steps(2, ("b", 2000.0, 200.0, [img, img.astype(float)]))},
                  "steps[2].images[1]", "integer array"),
        "kind": ({"steps": steps(0, ("x", 1000.0, 100.0, [img, img]))}, "steps[0]", "'b'"),
        "item": ({"steps": steps(0, ("b", 1000.0, [img, img]))}, "steps[0]", "(kind, "),
        "b photons 0": ({"steps": steps(0, ("b", 1000.0, 0.0, [img, img]))}, "steps[0]", "> 0"),
        "d photons": ({"steps": steps(1, ("d", 1000.0, 5.0, [img, img]))}, "steps[1]",
                      "0 for a 'd'"),
        "exposure": ({"steps": steps(1, ("d", -1.0, 0.0, [img, img]))}, "steps[1]", "≥ 0"),
        "one image": ({"steps": steps(1, ("d", 1000.0, 0.0, [img]))}, "steps[1]", "≥ 2 images"),
        "b without d": ({"steps": steps(1, ("d", 1500.0, 0.0, [img, img]))}, "steps[0]",
                        "needs a d step"),
        "duplicate": ({"steps": steps(2, ("b", 1000.0, 100.0, [img, img]))}, "steps[2]",
                      "same kind, exposure and photons as steps[0]"),
        "few points": ({"steps": ok[:4] + ok[-2:]}, "temporal points", "≥ 3 b/d pairs"),
        "two stacks": ({"steps": ok + [("b", 6e3, 6.0, [img] * 3), ("d", 6e3, 0.0, [img] * 3)]},
                       "steps[12]", "a second spatial pair"),
        "bits": ({"bits": 17}, "bits", "≤ 16"),
        "bool width": ({"width": True}, "width", "integer ≥ 1"),
        "release": ({"release": "5.0"}, "release", "3.0, 3.1, 4.0"),
    }


BAD_WRITES = ["over bits", "negative", "shape", "float", "kind", "item", "b photons 0",
              "d photons", "exposure", "one image", "b without d", "duplicate", "few points",
              "two stacks", "bits", "bool width", "release"]


@pytest.mark.parametrize("case", BAD_WRITES)
def test_a_bad_write_is_refused_and_writes_nothing(tmp_path, case):
    changes, key, allowed = _bad_steps(np.random.default_rng(5))[case]
    call = {"bits": BITS, "width": W, "height": H, "steps": _small_steps(np.random.default_rng(6))}
    folder = tmp_path / "new" / "set"
    with pytest.raises(DescriptorError) as err:
        write_descriptor(folder, **{**call, **changes})
    e = err.value
    assert (e.source, e.key) == (str(folder), key) and allowed in e.allowed, str(e)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_is_not_a_data_set_is_left_alone(tmp_path):
    folder = tmp_path / "set"
    folder.mkdir()
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(DescriptorError) as err:
        write_descriptor(folder, bits=BITS, width=W, height=H,
                         steps=_small_steps(np.random.default_rng(7)))
    assert (err.value.source, err.value.key) == (str(folder), "folder")
    assert f"no {DATA_FILE}" in err.value.allowed
    assert [p.name for p in folder.iterdir()] == ["notes.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["set"]


def test_a_write_that_fails_midway_leaves_nothing(tmp_path, monkeypatch):
    real, calls = _write_png, []

    def failing(path: Path, arr: np.ndarray) -> None:
        calls.append(path)
        if len(calls) == 3:
            raise OSError("disk full")
        real(path, arr)

    monkeypatch.setattr(descriptor_write, "_write_png", failing)
    with pytest.raises(OSError, match="disk full"):
        write_descriptor(tmp_path / "set", bits=BITS, width=W, height=H,
                         steps=_small_steps(np.random.default_rng(8)))
    assert len(calls) == 3 and list(tmp_path.iterdir()) == []
