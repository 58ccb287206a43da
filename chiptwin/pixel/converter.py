"""The per-pixel single-slope ADC as built: transition levels, mismatch and comparator noise.

A :class:`Converter` is the chip's converters, ready for the kernels. Unit of every level and
offset: the LSB of the ideal converter (:func:`chiptwin.pixel.adc.lsb_V`). One conversion::

    x    = (v − v_min_V)/LSB · (1 + gain_error) + offset_lsb      (today's continuous code)
    x_i  = x · pixel_gain[i] + pixel_offset_lsb[i]                  (converter i's mismatch)
         + comparator_noise_lsb · z                                 (a fresh z per conversion)
    code = #{levels[ramp(i)] ≤ x_i}                                 (half to even on a level)

Code ``k`` covers ``levels[k−1] ≤ x < levels[k]``; the ideal table is ``levels[k] = k + 0.5``,
with which the lookup is ``clip(rint(x), 0, 2^N − 1)`` bit for bit (ties included). Without INL
or DNL there is no table and ``x_i`` is rounded as today. With every effect 0 the converter is
*ideal*: the kernels run today's arithmetic and draw nothing (bit-identical codes and streams).

Conventions (IEEE Std 1241; docs/background/sources.md D1–D4):

* **DNL** (``dnl_rms_lsb``): the widths of the interior codes ``1 … 2^N − 2`` of each ramp are
  ``w_k = 1 + dnl_rms·z_k`` (ideal base) clipped at 0 (a zero width is a missing code), then all
  scaled by one factor so they sum to ``2^N − 2`` again: the end-point transitions (0.5 and
  ``2^N − 1.5``) stay, so the DNL is end-point DNL. ``dnl_rms_lsb`` is the rms before the clip.
* **INL** (``inl_max_lsb``, ``inl_shape``): a bow ``b(u)``, ``u`` = the level's place between the
  end points, added to each level: quadratic ``4u(1−u)``, cubic ``u(1−u)(1−2u)`` scaled to a peak of
  1, times ``inl_max_lsb`` (signed: > 0 delays the transitions, lowering the codes mid-range).
  Zero at both end points (end-point INL). Applied after the DNL as the increasing map
  ``t ↦ t + b(t)``, so missing codes stay missing; a bow steep enough to reverse transitions
  is refused. ``"table"``: the ramp's levels as measured (:func:`load_transition_table`).
* **Ramps** (``ramp``): converters on one ramp share its levels; per-converter offset and gain
  mismatch are drawn for every converter whatever the ramp. Only distinct tables are stored:
  without DNL every converter shares one table.
* **Fixed per chip**: DNL, offsets and gains are drawn once by :func:`build_converter` from a
  passed Generator (as the PRNU/DSNU maps), each effect from its own child stream.
* **Comparator noise** is white, Gaussian and independent per conversion, like the read noise
  of each sample: in the pixel kernels (``sensor_chain``, ``binned_codes``) the two are one
  draw of the summed variance (:func:`~chiptwin.pixel._kernels.sample_noise`), so comparator
  noise draws nothing more, moves no stream and costs nothing; :meth:`Converter.convert` (no
  read noise there) draws it from the ``rng`` it is given.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin.pixel import _kernels
from chiptwin.pixel._checks import check_scalar
from chiptwin.pixel.adc import (
    _WINDOW_SIGMA,
    _check_adc,
    _check_errors,
    _moments,
    adc_convert,
)

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


_EMPTY_F = np.zeros(0)
_EMPTY_I = np.zeros(0, np.int64)
_NO_LEVELS = np.zeros((0, 1))
_NO_LUT = np.zeros((1, 1, 2))

#: Passed as the comparator stream when nothing is drawn from it (no comparator noise).
_NO_DRAWS = np.random.Generator(np.random.SFC64(0))


@dataclass(frozen=True, eq=False)
class Converter:
    """The chip's converters as the kernels apply them: nominal ADC + levels + mismatch + noise.

    The search LUT of the levels (:func:`chiptwin.pixel._kernels.table_code`) is made here.

    Parameters
    ----------
    bits, v_min_V, v_max_V, offset_lsb, gain_error
        The nominal converter, as in :func:`chiptwin.pixel.adc.adc_convert`.
    comparator_noise_lsb : float
        Comparator noise, rms, per conversion. Unit: LSB.
    levels : ndarray (n_tables, 2^bits − 1), optional
        Transition levels of each distinct ramp, non-decreasing rows. Unit: LSB of the ideal
        converter. None: round (no INL, no DNL).
    table_of_pixel : ndarray of int (n_pixels,), optional
        Row of ``levels`` each converter uses (default 0).
    pixel_gain, pixel_offset_lsb : ndarray (n_pixels,), optional
        Each converter's gain factor (> 0, default 1) and offset (LSB, default 0).
    shape : tuple of int, optional
        Pixel array the per-converter arrays follow (C order); required unless ideal.
    """

    bits: int
    v_min_V: float
    v_max_V: float
    offset_lsb: float = 0.0
    gain_error: float = 0.0
    comparator_noise_lsb: float = 0.0
    levels: NDArray[np.float64] | None = None
    table_of_pixel: NDArray[np.int64] | None = None
    pixel_gain: NDArray[np.float64] | None = None
    pixel_offset_lsb: NDArray[np.float64] | None = None
    shape: tuple[int, ...] | None = None
    #: ``(inl_max_lsb, inl_shape)`` when ``levels`` are one ramp's ideal transitions ``k + ½``
    #: with exactly this smooth bow and nothing else (no DNL, no measured table; set by
    #: :func:`build_converter`): the ``expected`` level's sawtooth series then runs on the bow's
    #: inverse (:func:`bow_inverse`) instead of a quadrature over the table.
    bow: tuple[float, str] | None = None
    #: ``(padded levels, LUT, base)`` made from ``levels`` on construction; :meth:`at` hands a
    #: subset of the pixels its parent's, which are not checked or made again.
    _tables: tuple | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        _check_adc(self.bits, self.v_min_V, self.v_max_V)
        _check_errors(self.offset_lsb, self.gain_error)
        check_scalar("comparator_noise_lsb", self.comparator_noise_lsb, 0.0)
        if self.ideal:
            object.__setattr__(
                self, "_conv", (False, _EMPTY_F, _EMPTY_F, _EMPTY_I, 0.0, _NO_LEVELS, _NO_LUT, 0)
            )
            return
        if self.shape is None:
            raise ValueError("shape = None: a converter that is not ideal needs the pixel shape")
        n = int(np.prod(self.shape))
        gain = self._per_pixel("pixel_gain", self.pixel_gain, n, 1.0)
        if not (gain > 0).all():
            raise ValueError("pixel_gain has a value ≤ 0: each converter's gain must be > 0")
        offset = self._per_pixel("pixel_offset_lsb", self.pixel_offset_lsb, n, 0.0)
        levels, lut, base = _NO_LEVELS, _NO_LUT, 0
        rows = np.zeros(n, np.int64)
        if self.levels is not None:
            tables = self._tables
            if tables is not None and (self.levels is not tables[3]
                                       or tables[0].shape[1] != 2**self.bits):
                tables = None  # not the levels (and bits) they were made for: a replace()
            if tables is None:
                levels = np.ascontiguousarray(np.atleast_2d(np.asarray(self.levels, np.float64)))
                for r in range(levels.shape[0]):
                    check_transition_table(levels[r], self.bits, f"levels[{r}]")
                lut, base = _search_lut(levels)
                padded = _padded(levels)
                tables = (padded, lut, base, padded[:, :-1])  # the view is the levels' identity
            levels, lut, base, view = tables
            object.__setattr__(self, "_tables", tables)
            if self.table_of_pixel is not None:
                rows = np.ascontiguousarray(self.table_of_pixel, np.int64).reshape(-1)
                if rows.size != n or (n and (rows.min() < 0 or rows.max() >= levels.shape[0])):
                    raise ValueError(
                        f"table_of_pixel must hold {n} rows of levels in [0, {levels.shape[0] - 1}]"
                    )
            object.__setattr__(self, "levels", view)  # stored once, in the padded table
        noise = float(self.comparator_noise_lsb)
        object.__setattr__(self, "_conv", (True, gain, offset, rows, noise, levels, lut, base))

    @staticmethod
    def _per_pixel(name: str, values: ArrayLike | None, n: int, fill: float) -> NDArray[np.float64]:
        if values is None:
            return np.full(n, fill)
        arr = np.ascontiguousarray(values, np.float64).reshape(-1)
        if arr.size != n or not np.isfinite(arr).all():
            raise ValueError(f"{name} must hold {n} finite values, one per converter")
        return arr

    @classmethod
    def ideal_adc(
        cls,
        bits: int,
        v_min_V: float,
        v_max_V: float,
        offset_lsb: float = 0.0,
        gain_error: float = 0.0,
    ) -> Converter:
        """Today's converter: the same codes as :func:`~chiptwin.pixel.adc.adc_convert`."""
        return cls(bits, v_min_V, v_max_V, offset_lsb, gain_error)

    @property
    def ideal(self) -> bool:
        """No effect: today's arithmetic, nothing drawn."""
        return (
            self.comparator_noise_lsb == 0.0
            and self.levels is None
            and self.pixel_gain is None
            and self.pixel_offset_lsb is None
        )

    @property
    def n_pixels(self) -> int | None:
        """Converters described (None: any number, the converter is ideal)."""
        return None if self.shape is None else int(np.prod(self.shape))

    @property
    def lsb_V(self) -> float:
        """Width of one code of the ideal converter. Unit: V."""
        return (self.v_max_V - self.v_min_V) / 2.0**self.bits

    def consts(self) -> tuple[float, float, float, float, float]:
        """The kernels' nominal constants ``(v_min, lsb, 1 + gain_error, offset, top)``."""
        return (
            float(self.v_min_V),
            self.lsb_V,
            1.0 + self.gain_error,
            float(self.offset_lsb),
            2.0**self.bits - 1.0,
        )

    def kernel_conv(
        self, lo: int = 0, hi: int | None = None, fold: tuple[float, float] | None = None
    ) -> tuple:
        """The kernels' ``conv`` tuple for converters ``lo … hi − 1`` (a chunk of pixels).

        ``(built, pixel_gain, pixel_offset, table_of_pixel, noise_lsb, levels, lut, base,
        read_e)``. With ``fold = (read_noise_e, cg_V)`` (the pixel kernels) comparator noise is
        folded into a per-pixel read noise ``read_e``
        (:func:`~chiptwin.pixel._kernels.sample_noise`) and ``noise_lsb`` is 0; otherwise
        ``read_e`` is empty and the noise is drawn per conversion.
        """
        c = self._conv  # type: ignore[attr-defined]
        if not c[0]:
            return (*c, _EMPTY_F)
        noise, read_e = c[4], _EMPTY_F
        if fold is not None and noise > 0.0:
            pixel_gain = c[1][lo:hi]
            read_e = _kernels.sample_noise(
                fold[0], fold[1], 1.0 + self.gain_error, noise, self.lsb_V, pixel_gain
            )
            noise = 0.0
        return (True, c[1][lo:hi], c[2][lo:hi], c[3][lo:hi], noise, *c[5:], read_e)

    def input_codes(self, volts: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each converter's continuous code ``x_i`` of ``volts`` (the module's conversion without
        its noise) and its slope ``dx_i/dV``, broadcast to ``(..., *shape)``. Unit: LSB, LSB/V.
        Not for an ideal converter (it has no shape)."""
        if self.ideal:
            raise ValueError("input_codes needs a converter as built, with its pixel shape")
        v_min, lsb, gain, offset, _ = self.consts()
        _, g, o, *_ = self._conv  # type: ignore[attr-defined]
        g, o = g.reshape(self.shape), o.reshape(self.shape)
        x = ((np.asarray(volts, float) - v_min) / lsb * gain + offset) * g + o
        return x, np.broadcast_to(gain / lsb * g, x.shape)

    def at(self, pixels: ArrayLike) -> Converter:
        """The converters of ``pixels`` (flat C-order indices into :attr:`shape`), as a row of
        ``len(pixels)``: each keeps its gain, offset and ramp. Ideal: itself (any shape)."""
        if self.ideal:
            return self
        idx = np.asarray(pixels, np.int64).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= self.n_pixels):
            raise ValueError(f"pixels must be in [0, {self.n_pixels - 1}]")
        _, gain, offset, rows, *_ = self._conv  # type: ignore[attr-defined]
        levels = self.levels is not None
        return Converter(
            self.bits, self.v_min_V, self.v_max_V, self.offset_lsb, self.gain_error,
            self.comparator_noise_lsb, levels=self.levels,
            table_of_pixel=rows[idx] if levels else None,
            pixel_gain=None if self.pixel_gain is None else gain[idx],
            pixel_offset_lsb=None if self.pixel_offset_lsb is None else offset[idx],
            shape=(idx.size,), bow=self.bow, _tables=self._tables)

    def check_pixels(self, n_pixels: int, name: str = "converter") -> None:
        """Refuse a converter that is not ideal and describes another number of pixels."""
        if not self.ideal and self.n_pixels != n_pixels:
            raise ValueError(
                f"{name} describes {self.n_pixels} converters: the array has {n_pixels} pixels"
            )

    def comparator_stream(
        self, rng: np.random.Generator | None, name: str = "rng"
    ) -> np.random.Generator:
        """The stream :meth:`convert` draws comparator noise from: ``rng``, required when there
        is noise."""
        if self.comparator_noise_lsb > 0.0:
            if not isinstance(rng, np.random.Generator):
                raise ValueError(
                    f"{name} = {rng!r}: comparator_noise_lsb = "
                    f"{self.comparator_noise_lsb!r} needs a numpy Generator"
                )
            return rng
        return _NO_DRAWS

    def convert(
        self, volts: ArrayLike, rng: np.random.Generator | None = None
    ) -> NDArray[np.int64]:
        """Codes of ``volts`` (shape ``(..., *shape)``; any shape when ideal). Unit: codes.

        Comparator noise is drawn from ``rng`` in C order of ``volts`` (required with noise).
        Ideal: exactly :func:`~chiptwin.pixel.adc.adc_convert`.
        """
        v = np.ascontiguousarray(volts, dtype=np.float64)
        if np.isnan(v).any():
            raise ValueError("volts contains NaN: must be real voltages (±inf clip)")
        if self.ideal:
            return adc_convert(
                v, self.bits, self.v_min_V, self.v_max_V, self.offset_lsb, self.gain_error
            )
        n_pix = int(self.n_pixels)  # type: ignore[arg-type]
        if v.shape[v.ndim - len(self.shape) :] != self.shape:  # type: ignore[arg-type]
            raise ValueError(f"volts has shape {v.shape}: must end with {self.shape}")
        out = np.empty((v.size // n_pix, n_pix), np.int64)
        _kernels.convert_rows(
            v.reshape(-1, n_pix),
            out,
            *self.consts(),
            self.kernel_conv(),
            self.comparator_stream(rng, "rng"),
        )
        return out.reshape(v.shape)

    def expected(
        self, mean_V: ArrayLike, var_V: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean and variance of the code for a Gaussian input (``expected`` level). Unit: LSB, LSB².

        Per converter: ``μ_i = μ·pixel_gain + pixel_offset``, ``σ_i² = (σ·pixel_gain)² +
        comparator_noise²`` (the comparator noise adds to the input's), then the Gaussian summed
        over the codes of the converter's levels (:func:`~chiptwin.pixel._kernels.table_moments`,
        ±10σ), or :func:`~chiptwin.pixel.adc.adc_expected`'s choice (Sheppard's moments inside
        the range from 2 LSB rms, near the ends from 3 LSB a closed form, exact sums elsewhere),
        whose exact sums, for a converter with mismatch or comparator noise but no levels, are
        one numba pass over the ideal transitions ``k + ½`` (≈ 3× faster than NumPy's; a 1-LSB
        comparator made them a minute of every pyro_1fmol scene). Inputs broadcast to
        ``(..., *shape)``.
        """
        mean_a, var_a = np.broadcast_arrays(np.asarray(mean_V, float), np.asarray(var_V, float))
        if not (np.isfinite(mean_a).all() and np.isfinite(var_a).all() and (var_a >= 0).all()):
            raise ValueError("mean_V and var_V must be finite and var_V ≥ 0")
        _, g, o, rows, noise, *lut = self._conv  # type: ignore[attr-defined]
        v_min, lsb, gain, offset, top = self.consts()
        with np.errstate(over="ignore", invalid="ignore"):  # checked below
            mu = (mean_a - v_min) / lsb * gain + offset
            sd = np.sqrt(var_a) * (gain / lsb)
            if not self.ideal:
                mu, sd, rows = np.broadcast_arrays(mu, sd, rows.reshape(self.shape))
                gains, offs = g.reshape(self.shape), o.reshape(self.shape)
                mu, sd = mu * gains + offs, np.sqrt((sd * gains) ** 2 + noise * noise)
            reach = np.abs(mu) + _WINDOW_SIGMA * sd
        if not np.isfinite(reach).all():  # +inf would walk a table sum past the table's end
            raise ValueError("mean_V and var_V overflow the converter's codes (|mean| or its "
                             f"{_WINDOW_SIGMA:g} rms above ~1e300 LSB): must be real voltages")
        mu, sd = np.ascontiguousarray(mu).ravel(), np.ascontiguousarray(sd).ravel()
        if self.ideal or (self.levels is None and self.bits > IDEAL_TABLE_MAX_BITS):
            mean, var = _moments(mu, sd, top)
        elif self.levels is None:  # mismatch or comparator noise on the ideal transitions
            mean, var = _moments(mu, sd, top, exact_sums=_ideal_table_sums(self.bits))
        else:
            mean, var = np.empty_like(mu), np.empty_like(mu)
            rows = np.ascontiguousarray(rows, np.int64).ravel()
            _kernels.table_moments(mu, sd, rows, tuple(lut), _WINDOW_SIGMA, mean, var)
        shape = np.broadcast_shapes(mean_a.shape, () if self.ideal else self.shape)
        return mean.reshape(shape), var.reshape(shape)


#: Up to these bits :meth:`Converter.expected` sums a converter with mismatch or comparator noise
#: but no levels on a table of the ideal transitions (2^20 levels: a 48 MB table and LUT); above,
#: NumPy's sums of :func:`~chiptwin.pixel.adc.adc_expected`.
IDEAL_TABLE_MAX_BITS: int = 20


@functools.lru_cache(maxsize=4)
def _ideal_table(bits: int) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """``(levels, lut, base)`` of :func:`~chiptwin.pixel._kernels.table_moments` for the ideal
    transitions ``k + ½``, ``k = 0 … 2^bits − 2`` (one ramp)."""
    levels = (np.arange(2**bits - 1, dtype=np.float64) + 0.5)[None, :]
    lut, base = _search_lut(levels)
    return _padded(levels), lut, base


def _ideal_table_sums(bits: int):
    """``exact_sums(mu, sd)`` of :func:`~chiptwin.pixel.adc._moments` on the ideal table."""
    table = _ideal_table(bits)

    def sums(mu: NDArray[np.float64], sd: NDArray[np.float64]):
        mean, var = np.empty_like(mu), np.empty_like(mu)
        rows = np.zeros(mu.size, np.int64)
        mu, sd = np.ascontiguousarray(mu), np.ascontiguousarray(sd)
        _kernels.table_moments(mu, sd, rows, table, _WINDOW_SIGMA, mean, var)
        return mean, var

    return sums


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


def build_converter(
    rng: np.random.Generator,
    shape: tuple[int, ...],
    *,
    bits: int,
    v_min_V: float,
    v_max_V: float,
    offset_lsb: float = 0.0,
    gain_error: float = 0.0,
    as_built: AsBuilt = AsBuilt(),
) -> Converter:
    """The chip's converters as built, one per pixel of ``shape``, fixed per chip.

    Parameters
    ----------
    rng : numpy.random.Generator
        The converters' map stream. Nothing is drawn unless DNL, offset or gain mismatch is on;
        then 4 integers seed a SeedSequence whose three children draw, each only if its effect
        is on: the DNL (``(n_tables, 2^bits − 2)`` normals, ramp by ramp), the offsets
        (``n_pixels`` normals, C order), the gains (likewise). So switching one effect on never
        changes another's numbers.
    shape : tuple of int
        The pixel array (``(rows, cols)``); a column is the last axis.
    bits, v_min_V, v_max_V, offset_lsb, gain_error
        The nominal converter, as in :func:`~chiptwin.pixel.adc.adc_convert`.
    as_built : AsBuilt
        The effects (default none: the ideal converter, today's codes).

    Raises
    ------
    ValueError
        Naming the parameter: a bad value, a bad table, a reversing bow, or tables beyond
        :data:`MAX_TABLE_BYTES` (``ramp = "pixel"`` with DNL on a large array).
    """
    n_bits, lo, hi = _check_adc(bits, v_min_V, v_max_V)
    shp = tuple(int(s) for s in np.atleast_1d(shape))
    if not shp or min(shp) < 1:
        raise ValueError(f"shape = {shape!r}: must be positive sizes")
    spec, n = as_built, int(np.prod(shp))
    table, shaped = spec.inl_shape == "table", spec.shaped
    rows, n_ramps = _ramp_index(spec.ramp, shp)
    n_tables = n_ramps if spec.dnl_rms_lsb > 0.0 and 2**n_bits > 2 else 1
    if shaped:
        _check_memory(n_tables, n_bits, spec)
    draws = spec.dnl_rms_lsb > 0 or spec.offset_sigma_lsb > 0 or spec.gain_sigma > 0
    streams = [None, None, None]
    if draws:
        seq = np.random.SeedSequence(rng.integers(0, 2**63, size=4).tolist())
        streams = [np.random.Generator(np.random.SFC64(s)) for s in seq.spawn(3)]
    levels = None
    if shaped:
        if table:
            src = spec.inl_table
            base = (
                load_transition_table(src, n_bits)
                if isinstance(src, (str, Path))
                else check_transition_table(src, n_bits)
            )
        else:
            base = np.arange(2**n_bits - 1, dtype=np.float64) + 0.5
        levels = base[None, :]
        if n_tables > 1 or (spec.dnl_rms_lsb > 0 and 2**n_bits > 2):
            levels = _with_dnl(base, spec.dnl_rms_lsb, n_tables, streams[0])
        if not table:
            levels = _bow(levels, spec.inl_max_lsb, spec.inl_shape)
    offsets = gains = None
    if spec.offset_sigma_lsb > 0:
        offsets = spec.offset_sigma_lsb * streams[1].standard_normal(n)
    if spec.gain_sigma > 0:
        gains = 1.0 + spec.gain_sigma * streams[2].standard_normal(n)
    smooth = shaped and not table and spec.inl_max_lsb != 0.0 and levels.shape[0] == 1 \
        and spec.dnl_rms_lsb == 0.0 and 2**n_bits > 2
    return Converter(
        n_bits,
        lo,
        hi,
        offset_lsb,
        gain_error,
        spec.comparator_noise_lsb,
        levels,
        rows if n_tables > 1 else None,
        gains,
        offsets,
        shp,
        bow=(float(spec.inl_max_lsb), spec.inl_shape) if smooth else None,
    )


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


def resolve_converter(
    converter: Converter | None, bits: int | None, v_min_V: float | None, v_max_V: float | None,
    offset_lsb: float | None, gain_error: float | None, defaults: tuple = (None, None, None, 0.0,
                                                                          0.0),
) -> Converter:  # fmt: skip
    """The converter of a call given either ``converter`` or the nominal ADC's keywords.

    ``defaults`` fill keywords left None (a None default is required). Both given: an error.
    """
    given = (bits, v_min_V, v_max_V, offset_lsb, gain_error)
    names = ("bits", "v_min_V", "v_max_V", "offset_lsb", "gain_error")
    if converter is not None:
        both = [n for n, v in zip(names, given, strict=True) if v is not None]
        if both:
            raise ValueError(
                f"{', '.join(both)} given with converter: the converter carries "
                "the nominal ADC; give one or the other"
            )
        if not isinstance(converter, Converter):
            raise ValueError(f"converter = {converter!r}: must be a chiptwin.pixel.Converter")
        return converter
    args = [d if v is None else v for v, d in zip(given, defaults, strict=True)]
    for name, value in zip(names, args, strict=True):
        if value is None:
            raise ValueError(f"{name} is required (or a converter)")
    return Converter.ideal_adc(*args)
