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
from chiptwin.pixel.ramp import (
    AsBuilt,
    _bow,
    _check_memory,
    _padded,
    _ramp_index,
    _search_lut,
    _with_dnl,
    check_transition_table,
    load_transition_table,
)

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


def build_converter(
    rng: np.random.Generator,
    shape: tuple[int, ...],
    *,
    bits: int,
    v_min_V: float,
    v_max_V: float,
    offset_lsb: float = 0.0,
    gain_error: float = 0.0,
    as_built: AsBuilt = AsBuilt(),  # noqa: B008 (a frozen dataclass: immutable)
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
