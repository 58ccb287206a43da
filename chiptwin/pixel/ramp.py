"""The ramp of the single-slope converters as built: its transition levels.

The levels every converter on a ramp compares its input with, in the LSB of the ideal converter
(IEEE Std 1241; docs/background/sources.md D1–D4): the DNL's spread of code widths, the INL's
bow (quadratic or cubic) or a measured table of levels, which converters share a ramp, and the
search LUT the kernels walk. :mod:`chiptwin.pixel.converter` builds the chip's converters on
them (mismatch, comparator noise) and computes their codes and moments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.pixel import _kernels
from chiptwin.pixel._checks import check_scalar

RAMPS: tuple[str, ...] = ("chip", "column", "pixel")


INL_SHAPES: tuple[str, ...] = ("quadratic", "cubic", "table")


#: Largest memory the transition tables may take: 40 B per level (the level, 8 B, and the search
#: LUT, 16 B a cell, two cells per LSB). 256 × 256 converters on their own ramps with 13 bits
#: would need 21 GB. Unit: byte.
MAX_TABLE_BYTES: int = 256 * 2**20


#: Peak of ``u(1−u)(1−2u)`` on [0, 1] (at ``u = 1/2 − 1/(2√3)``): ``1/(6√3)``.
_CUBIC_PEAK: float = 1.0 / (6.0 * math.sqrt(3.0))


#: Steepest slope ``|b'(u)|`` of each unit bow on [0, 1] (both at the end points).
_BOW_SLOPE: dict[str, float] = {"quadratic": 4.0, "cubic": 1.0 / _CUBIC_PEAK}


@dataclass(frozen=True)
class AsBuilt:
    """The converter's effects, each 0 by default (then the converter is ideal).

    Parameters
    ----------
    comparator_noise_lsb : float
        Input-referred comparator and ramp noise, rms, a fresh draw per conversion (it dithers).
        Unit: LSB. Typical: a few tenths to one LSB. ≥ 0.
    inl_max_lsb : float
        Peak of the ramp's bow (end-point INL), signed. Unit: LSB.
    inl_shape : {"quadratic", "cubic", "table"}
        The bow's shape, or ``"table"``: the levels of ``inl_table`` (then ``inl_max_lsb`` = 0).
    inl_table : str, Path, array_like or None
        Transition levels of the ramp (``2^bits − 1`` of them, LSB of the ideal converter), or a
        file of them (:func:`load_transition_table`). Only with ``inl_shape = "table"``.
    dnl_rms_lsb : float
        Spread of the code widths, fixed per chip; widths clipped at 0 (missing codes). Unit: LSB.
    offset_sigma_lsb, gain_sigma : float
        Per-converter offset (LSB) and fractional gain mismatch, rms, fixed per chip. ≥ 0;
        ``gain_sigma`` ≤ 0.1 (so that ``1 + gain_sigma·z`` stays positive).
    ramp : {"chip", "column", "pixel"}
        Which converters share a ramp (its INL and DNL): all, each column's, none.
    """

    comparator_noise_lsb: float = 0.0
    inl_max_lsb: float = 0.0
    inl_shape: str = "quadratic"
    inl_table: str | Path | ArrayLike | None = field(default=None, compare=False)
    dnl_rms_lsb: float = 0.0
    offset_sigma_lsb: float = 0.0
    gain_sigma: float = 0.0
    ramp: str = "chip"

    def __post_init__(self) -> None:
        check_scalar("comparator_noise_lsb", self.comparator_noise_lsb, 0.0)
        check_scalar("inl_max_lsb", self.inl_max_lsb)
        check_scalar("dnl_rms_lsb", self.dnl_rms_lsb, 0.0)
        check_scalar("offset_sigma_lsb", self.offset_sigma_lsb, 0.0)
        check_scalar("gain_sigma", self.gain_sigma, 0.0, 0.1)
        for name, value, allowed in (
            ("inl_shape", self.inl_shape, INL_SHAPES),
            ("ramp", self.ramp, RAMPS),
        ):
            if value not in allowed:
                raise ValueError(f"{name} = {value!r}: must be one of {', '.join(allowed)}")
        has_table = self.inl_table is not None and not (
            isinstance(self.inl_table, str) and self.inl_table == ""
        )
        if (self.inl_shape == "table") != has_table:
            raise ValueError(
                f"inl_table = {self.inl_table!r}: a table is required with "
                "inl_shape = 'table' and allowed only with it"
            )
        if self.inl_shape == "table" and self.inl_max_lsb != 0.0:
            raise ValueError(
                f"inl_max_lsb = {self.inl_max_lsb!r}: must be 0 with inl_shape = "
                "'table' (the table carries the INL)"
            )

    @property
    def ideal(self) -> bool:
        """No effect: the converter these effects build is today's rounding ADC."""
        return self.inl_shape != "table" and not any(
            (self.comparator_noise_lsb, self.inl_max_lsb, self.dnl_rms_lsb,
             self.offset_sigma_lsb, self.gain_sigma))

    @property
    def shaped(self) -> bool:
        """The ramp's levels are not the ideal transitions (INL, DNL or a measured table): the
        converters carry a transition table."""
        return self.inl_max_lsb != 0.0 or self.dnl_rms_lsb > 0.0 or self.inl_shape == "table"

    @classmethod
    def from_keys(cls, section: object, base_dir: str | Path | None = None) -> AsBuilt:
        """The effects read by name from any object holding the ``[chip.adc]`` keys (the
        scenario's ``Adc``; this layer does not import the config). A relative ``inl_table`` is
        taken from ``base_dir`` (the scenario's folder); ``""`` means none."""
        names = (
            "comparator_noise_lsb",
            "inl_max_lsb",
            "inl_shape",
            "inl_table",
            "dnl_rms_lsb",
            "offset_sigma_lsb",
            "gain_sigma",
            "ramp",
        )
        kw = {n: getattr(section, n) for n in names if hasattr(section, n)}
        table = kw.get("inl_table")
        if isinstance(table, (str, Path)) and str(table) and base_dir is not None:
            kw["inl_table"] = str(Path(base_dir) / table)
        return cls(**kw)


def check_transition_table(
    levels: ArrayLike, bits: int, name: str = "inl_table"
) -> NDArray[np.float64]:
    """``levels`` as a float64 vector after checking: ``2^bits − 1`` finite, non-decreasing values.

    Raises
    ------
    ValueError
        Naming ``name``: the wrong count, a non-finite value, or the first decreasing step.
    """
    arr = np.asarray(levels, dtype=np.float64).reshape(-1)
    want = 2**bits - 1
    if arr.size != want:
        raise ValueError(
            f"{name} has {arr.size} transition levels: a {bits}-bit converter "
            f"has 2^{bits} − 1 = {want}"
        )
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or infinite levels: must be finite (LSB)")
    down = np.flatnonzero(np.diff(arr) < 0)
    if down.size:
        k = int(down[0])
        raise ValueError(
            f"{name} decreases at level {k + 1}: {arr[k + 1]!r} < {arr[k]!r}; "
            "transition levels must be non-decreasing"
        )
    lo, hi = -(2.0**bits), 2.0 ** (bits + 1)
    if arr.size and (arr[0] < lo or arr[-1] > hi):
        raise ValueError(
            f"{name} spans {float(arr[0])!r} … {float(arr[-1])!r} LSB: levels must lie within "
            f"one range of the converter's, [{lo:g}, {hi:g}] (a stray level is likely a unit "
            "mix-up; the search LUT holds 2 cells an LSB over the levels' span)"
        )
    return arr


def load_transition_table(path: str | Path, bits: int) -> NDArray[np.float64]:
    """Read a table of transition levels (LSB of the ideal converter) and check it.

    ``.npy``: one array. Otherwise text: numbers separated by white space, commas or new lines,
    ``#`` comments. Level ``k`` (0-based) is the input at which the code goes from ``k`` to
    ``k + 1``; the ideal converter's is ``k + 0.5``. Checked by :func:`check_transition_table`.
    """
    p = Path(path)
    try:
        if p.suffix == ".npy":
            raw = np.load(p, allow_pickle=False)
        else:
            lines = p.read_text(encoding="utf-8").splitlines()
            words = " ".join(line.split("#", 1)[0] for line in lines).replace(",", " ").split()
            raw = np.array([float(w) for w in words])
    except (OSError, ValueError) as exc:
        raise ValueError(f"inl_table = {str(path)!r}: cannot be read as numbers ({exc})") from None
    return check_transition_table(raw, bits)


def _search_lut(levels: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
    """The LUT of :func:`~chiptwin.pixel._kernels.table_code`, ``(n_tables, n_cells, 2)``: for
    each cell of ``1/CELLS_PER_LSB`` LSB, from one below the lowest level's to one above the
    highest's, its one level (+inf if none, NaN if several) and the count of levels below it."""
    per = _kernels.CELLS_PER_LSB
    base = int(math.floor(levels[:, 0].min() * per)) - 1
    edges = np.arange(base, int(math.floor(levels[:, -1].max() * per)) + 3) / per
    lut = np.empty((levels.shape[0], edges.size - 1, 2))
    for r in range(levels.shape[0]):
        k = np.searchsorted(levels[r], edges, side="left")
        count = np.diff(k)
        first = levels[r][np.minimum(k[:-1], levels.shape[1] - 1)]
        lut[r, :, 0] = np.where(count == 0, np.inf, np.where(count == 1, first, np.nan))
        lut[r, :, 1] = k[:-1]
    return lut, base


def _padded(levels: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(n_tables, n + 1)``: the levels with a last column of +inf (the kernels' walk then
    needs no bound check)."""
    out = np.empty((levels.shape[0], levels.shape[1] + 1))
    out[:, :-1] = levels
    out[:, -1] = np.inf
    return out


def _ramp_index(ramp: str, shape: tuple[int, ...]) -> tuple[NDArray[np.int64], int]:
    """Each converter's ramp (C order of ``shape``) and the number of ramps."""
    n = int(np.prod(shape))
    if ramp == "chip":
        return np.zeros(n, np.int64), 1
    if ramp == "column":
        cols = shape[-1]
        return np.ascontiguousarray(np.broadcast_to(np.arange(cols), shape)).ravel(), cols
    return np.arange(n, dtype=np.int64), n


def _check_memory(n_tables: int, bits: int, spec: AsBuilt) -> None:
    need = n_tables * (2**bits - 1) * 40
    if need > MAX_TABLE_BYTES:
        raise ValueError(
            f"ramp = {spec.ramp!r} with dnl_rms_lsb = {spec.dnl_rms_lsb!r}: {n_tables} transition "
            f"tables of {2**bits - 1} levels need {need / 1e9:.3g} GB, above the "
            f"{MAX_TABLE_BYTES / 2**20:.0f} MiB bound (MAX_TABLE_BYTES). Share each ramp among "
            "more converters (ramp = 'chip', or 'column' on fewer columns: a single-slope array "
            "shares its ramp and counter, the DNL's source), use fewer bits, or set "
            "dnl_rms_lsb = 0"
        )


def _with_dnl(
    base: NDArray[np.float64], dnl: float, n_tables: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``n_tables`` rows of levels: the interior widths of ``base`` plus ``dnl·z``, clipped at 0,
    scaled back to their sum (end points kept). Draws ``(n_tables, 2^N − 2)`` normals, row-major."""
    widths = np.diff(base)
    out = np.empty((n_tables, base.size))
    for r in range(n_tables):  # row by row: no (n_tables, 2^N) temporaries beyond the output
        w = np.maximum(widths + dnl * rng.standard_normal(widths.size), 0.0)
        total = w.sum()
        w = w * (widths.sum() / total) if total > 0 else widths
        out[r, 0] = base[0]
        out[r, 1:] = np.minimum(base[0] + np.cumsum(w), base[-1])
        out[r, -1] = base[-1]
    return out


def _bow(levels: NDArray[np.float64], inl: float, shape: str) -> NDArray[np.float64]:
    """``t + inl·b(u)``, ``u = (t − t_first)/(t_last − t_first)``; refuses a reversing bow."""
    lo, hi = levels[..., :1], levels[..., -1:]
    span = float((hi - lo).min()) if levels.shape[-1] > 1 else 0.0
    if span <= 0.0 or inl == 0.0:
        return levels
    steepest = abs(inl) * _BOW_SLOPE[shape] / span
    if steepest >= 1.0:
        limit = span / _BOW_SLOPE[shape]
        raise ValueError(
            f"inl_max_lsb = {inl!r}: a {shape} bow over {span:g} LSB must stay "
            f"below {limit:.4g} LSB in magnitude, or it reverses transitions"
        )
    u = (levels - lo) / (hi - lo)
    unit = 4.0 * u * (1.0 - u) if shape == "quadratic" else u * (1 - u) * (1 - 2 * u) / _CUBIC_PEAK
    return levels + inl * unit


def check_bow(inl: float, shape: str, bits: int) -> None:
    """Refuse a bow that reverses transitions (:func:`_bow`'s check, on the end points only)."""
    if 2**bits > 2:
        _bow(np.array([[0.5, 2.0**bits - 1.5]]), inl, shape)


def _bow_terms(s: NDArray[np.float64], inl: float, shape: str, bits: int
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The bow's offset ``inl·b(u)`` and slope ``d/ds`` at ideal-code places ``s`` (LSB),
    ``u = (s − ½)/(2^bits − 2)`` as :func:`_bow` places the ideal transitions ``k + ½``."""
    span = 2.0**bits - 2.0
    u = (s - 0.5) / span
    if shape == "quadratic":
        return inl * 4.0 * u * (1.0 - u), inl * 4.0 * (1.0 - 2.0 * u) / span
    return (inl * u * (1 - u) * (1 - 2 * u) / _CUBIC_PEAK,
            inl * (1.0 - 6.0 * u + 6.0 * u * u) / (_CUBIC_PEAK * span))


def bow_curvature(inl: float, shape: str, bits: int) -> float:
    """``max |T''|`` of the bow's map ``T(s) = s + inl·b(u)``, a bound on ``|φ''|·(1 + ε)`` of its
    inverse (the slope stays within ``1 ± 4|inl|/span``). Unit: 1/LSB."""
    span = 2.0**bits - 2.0
    peak = 8.0 if shape == "quadratic" else 6.0 / _CUBIC_PEAK  # max |b''(u)|
    return abs(inl) * peak / (span * span) / (1.0 - abs(inl) * _BOW_SLOPE[shape] / span) ** 3


def bow_inverse(x: ArrayLike, inl: float, shape: str, bits: int
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``φ(x)`` and ``φ'(x)``: the inverse of the bow's map ``T(s) = s + inl·b(u)``, which takes
    the ideal transitions ``k + ½`` to the bowed ones, so that a bowed converter's code of ``x``
    is the ideal rounding of ``φ(x)`` (inside the range). Newton's method from ``s = x``: the
    slope is within ``4|inl|/span`` of 1, so each step squares an error that starts at ≤ |inl|;
    four steps reach rounding (2 LSB of bow at 13 bits: 2 → 1e-3 → 5e-10 → 1e-22). Unit: LSB."""
    x = np.asarray(x, float)
    s = x.copy()
    for _ in range(4):
        b, db = _bow_terms(s, inl, shape, bits)
        s = s - (s + b - x) / (1.0 + db)
    return s, 1.0 / (1.0 + _bow_terms(s, inl, shape, bits)[1])
