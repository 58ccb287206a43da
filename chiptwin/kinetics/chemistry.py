"""The flow-value model: what a flow reads for a true homopolymer length, beyond phasing.

A phase-corrected, key-normalised flow value (1-mer ≈ 1) of a true ``h``-mer is, per well and
per flow (:class:`FlowModel`, each term a scenario key of ``[assay]``)::

    h ≥ 1:  y = h·(1 − κ)^(h−1) · m  +  a
    h = 0:  y = max(0, b + a)
    m ~ Normal(1, v·flow_yield_cv²)             per-flow multiplicative yield spread
    a ~ Normal(flow_background, v·flow_noise_sd²) additive light of every flow (1-mer units)
    b ~ empty_flow_law(mean, sd)                the light of a flow that extends nothing
    v ~ Gamma(mean 1, CV well_noise_cv)         each well's noise level, drawn per well

* The spread growing with ``h`` (454 FLX flow-value sd 0.107, 0.143, 0.187, 0.259 for 1–4-mers)
  is a multiplicative factor of each flow's light, not shot noise (Balzer et al., Bioinformatics
  26:i420, 2010, fitted Titanium as Normal(h, 0.04 + 0.05 h)): the reagent each flow delivers
  to a well, its polymerase's and its enzymes' turnover vary flow by flow.
* ``v``: wells differ in how noisy they are (bead loading, position on the plate, neighbours):
  the measured values are peaked with long tails, a scale mixture of normals, not one normal
  (454 FLX 1-mers: 1 % below 0.79, 1 % above 1.27 around a median of 1.01).
* ``flow_background``: 454's 1- to 4-mers sit 0.01 above ``h`` (FLX 1.013, 2.010, 2.995,
  4.006), light every flow carries.
* ``κ`` (``homopolymer_yield_loss``) is the light lost per base beyond the first of a long
  homopolymer (extension not completed within the flow; Ion's long runs read low, Rothberg et
  al., Nature 475:348, 2011).
* ``b``: the 454 vendor's values leave empty flows near +0.1 (FLX 0.088) while 1- to 4-mers sit
  within 0.013 of ``h``, so the empty-flow light is a law of its own, not an offset of every
  flow: lognormal (Balzer et al. 2010 fitted LogNormal(−2.5, 0.2) to Titanium's 0-mers; the
  fits chose it for all three presets), or a normal. Ion stores 0 for 60 % of its 0-mers: the
  additive term's negative side, clipped.

Light cannot be negative: a flow's value is clipped at 0 (the 0-mers only, in practice), as the
flowgram files store it (SFF and Ion's ``FZ``: non-negative hundredths).

:func:`draw_flow_values` draws values for given lengths (Monte Carlo);
:func:`flow_value_distribution` gives their law on the flowgram's 0.01 bins exactly;
:func:`flow_light` makes each site's and flow's light for the twin. Presets fitted to real runs:
:data:`PRESETS` (:mod:`chiptwin.kinetics.chemistry_presets`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special
from scipy.signal import fftconvolve

EMPTY_FLOW_LAWS = ("lognormal", "normal")
"""Laws of the empty-flow light ``b`` (the light, with ``a``, clipped at 0)."""

#: Bin width of a flowgram value: SFF and Ion's FZ store hundredths of a 1-mer.
BIN = 0.01

#: Bins of a flow-value distribution: 0.00 … 9.99, as the PyroNoise / qiime denoiser profiles
#: (Quince et al., Nature Methods 6:639, 2009; Reeder & Knight, Nature Methods 7:668, 2010).
N_BINS = 1000


@dataclass(frozen=True)
class FlowModel:
    """The flow-value model's parameters (module docstring). Units: 1-mer (a fraction for the
    CV and κ)."""

    flow_yield_cv: float = 0.0
    flow_noise_sd: float = 0.0
    flow_background: float = 0.0
    well_noise_cv: float = 0.0
    homopolymer_yield_loss: float = 0.0
    empty_flow_law: str = "lognormal"
    empty_flow_mean: float = 0.0
    empty_flow_sd: float = 0.0

    def __post_init__(self) -> None:
        for name, hi in (("flow_yield_cv", 0.5), ("flow_noise_sd", 0.5), ("well_noise_cv", 3.0),
                         ("homopolymer_yield_loss", 0.2), ("empty_flow_sd", 0.5)):
            v = getattr(self, name)
            if not 0.0 <= v <= hi:
                raise ValueError(f"{name} = {v!r} is out of range: must be in [0, {hi}]")
        if not -0.2 <= self.flow_background <= 0.2:
            raise ValueError(f"flow_background = {self.flow_background!r} is out of range: "
                             "must be in [-0.2, 0.2]")
        if not -0.5 <= self.empty_flow_mean <= 0.5:
            raise ValueError(f"empty_flow_mean = {self.empty_flow_mean!r} is out of range: "
                             "must be in [-0.5, 0.5]")
        if self.empty_flow_law not in EMPTY_FLOW_LAWS:
            raise ValueError(f"empty_flow_law = {self.empty_flow_law!r}: must be one of "
                             f"{', '.join(EMPTY_FLOW_LAWS)}")
        if self.empty_flow_law == "lognormal" and self.empty_flow_mean < 0:
            raise ValueError(f"empty_flow_mean = {self.empty_flow_mean!r}: a lognormal "
                             "empty-flow light must have a mean >= 0")

    @property
    def active(self) -> bool:
        """True when any term changes a flow's light."""
        return bool(self.flow_yield_cv or self.flow_noise_sd or self.flow_background
                    or self.homopolymer_yield_loss or self.empty_flow_mean or self.empty_flow_sd)

    def mean_light(self, h: ArrayLike) -> NDArray[np.float64]:
        """``h·(1 − κ)^(h−1)``: the mean light of an ``h``-mer (0 for ``h = 0``)."""
        h = np.asarray(h, dtype=np.float64)
        return h * (1.0 - self.homopolymer_yield_loss) ** np.maximum(h - 1.0, 0.0)


def lognormal_shape(mean: float, sd: float) -> tuple[float, float]:
    """(μ, σ) of the log of a lognormal with this mean (> 0) and sd."""
    s2 = np.log1p((sd / mean) ** 2)
    return float(np.log(mean) - s2 / 2), float(np.sqrt(s2))


def draw_empty(model: FlowModel, rng: np.random.Generator, size) -> NDArray[np.float64]:
    """The empty-flow light ``b`` (module docstring)."""
    mean, sd = model.empty_flow_mean, model.empty_flow_sd
    if model.empty_flow_law == "normal":
        return mean + sd * rng.standard_normal(size)
    if mean <= 0:
        return np.zeros(size)
    if sd <= 0:
        return np.full(size, mean)
    mu, sigma = lognormal_shape(mean, sd)
    return rng.lognormal(mu, sigma, size)


def draw_well_noise(model: FlowModel, rng: np.random.Generator, size) -> NDArray[np.float64]:
    """Each well's noise level ``v`` (mean 1, CV ``well_noise_cv``; gamma law: positive, its
    spread one number), 1 when the CV is 0."""
    if not model.well_noise_cv:
        return np.ones(size)
    k = 1.0 / model.well_noise_cv**2
    return rng.gamma(k, 1.0 / k, size)


def _light(s: NDArray[np.float64], h: NDArray[np.float64], v: NDArray[np.float64],
           model: FlowModel, rng: np.random.Generator, shape: tuple[int, ...]
           ) -> NDArray[np.float64]:
    """The light of flows of mean ``s`` and in-phase length ``h`` in wells of noise level ``v``
    (broadcast to ``shape``); draws m, a, b in that order."""
    root_v = np.sqrt(v)
    m = 1.0 + model.flow_yield_cv * root_v * rng.standard_normal(shape)
    a = model.flow_background + model.flow_noise_sd * root_v * rng.standard_normal(shape)
    b = draw_empty(model, rng, shape)
    loss = (1.0 - model.homopolymer_yield_loss) ** np.maximum(h - 1.0, 0.0)
    return np.maximum(s * loss * m + a + np.where(h == 0, b, 0.0), 0.0)


def flow_light(signal: ArrayLike, ideal: ArrayLike, model: FlowModel, rng: np.random.Generator,
               n_sites: int) -> NDArray[np.float64]:
    """Each site's light per flow, in incorporations per strand (1-mer units).

    Parameters
    ----------
    signal : (n_flows,) the phased, drooping flowgram (mean bases per strand;
        :func:`chiptwin.kinetics.phasing.phased_signal`, or the ideal counts).
    ideal : (n_flows,) int, the in-phase homopolymer length of each flow
        (:func:`chiptwin.kinetics.pyro.flow_incorporations`).
    model : the flow-value model.
    rng : the stream the draws come from (each site's ``v``, then m, a and b, each
        (n_sites, n_flows)): the same seed gives the same bits.
    n_sites : sites.

    Returns
    -------
    (n_sites, n_flows), >= 0: ``signal·(1 − κ)^(h−1)·m + a``, plus ``b`` where ``h = 0``.
    """
    s = np.asarray(signal, dtype=np.float64)
    h = np.asarray(ideal, dtype=np.float64)
    v = draw_well_noise(model, rng, (n_sites, 1))
    return _light(s, h, v, model, rng, (n_sites, s.size))


def draw_flow_values(h: ArrayLike, model: FlowModel, rng: np.random.Generator,
                     chain_floor: float = 0.0, chain_shot: float = 0.0) -> NDArray[np.float64]:
    """Flow values of flows with true lengths ``h``, each from a well of its own: the model's
    light plus the chain's noise (variance ``chain_floor + chain_shot·h``, 1-mer², the twin's
    predicted noise, :class:`chiptwin.detection.reads.FlowNoise` without the key's scale
    error), clipped at 0 as a flowgram file stores them. No phasing: the values of a
    phase-corrected flowgram."""
    h = np.asarray(h, dtype=np.float64)
    v = draw_well_noise(model, rng, h.shape)
    light = _light(h, h, v, model, rng, h.shape)
    chain = np.sqrt(chain_floor + chain_shot * h) * rng.standard_normal(h.shape)
    return np.maximum(light + chain, 0.0)


#: Points of the well noise level's law the distributions average over (its quantiles at
#: (i + ½)/Q): 16 put the total variation within 1e-3 of the continuous mixture.
WELL_QUANTILES = 16


def well_levels(model: FlowModel) -> NDArray[np.float64]:
    """The noise levels ``v`` the distributions average over, equally likely."""
    if not model.well_noise_cv:
        return np.ones(1)
    k = 1.0 / model.well_noise_cv**2
    u = (np.arange(WELL_QUANTILES) + 0.5) / WELL_QUANTILES
    return special.gammaincinv(k, u) / k


def _normal_cdf(x: NDArray[np.float64], mean: float, sd: float) -> NDArray[np.float64]:
    if sd <= 0:
        return (x >= mean).astype(np.float64)
    return special.ndtr((x - mean) / sd)


def bin_edges(n_bins: int = N_BINS) -> NDArray[np.float64]:
    """Inner edges of the value bins: bin ``i`` holds values that round to ``i·BIN``; bin 0
    also every value below (the clipped ones), the last every value above."""
    return (np.arange(1, n_bins) - 0.5) * BIN


def _binned(cdf_at_edges: NDArray[np.float64]) -> NDArray[np.float64]:
    c = np.concatenate([[0.0], cdf_at_edges, [1.0]])
    return np.diff(c)


#: Step of the grid the empty-flow law is convolved on (1-mer): a tenth of a bin.
FINE = 0.001


def _gauss_kernel(sd: float, shift: float = 0.0) -> NDArray[np.float64]:
    """Mass of Normal(shift, sd²) on the :data:`FINE` grid, centred on its middle point; a
    narrower normal (sd ≤ FINE/4) split between the two points around ``shift``."""
    half = int(np.ceil((abs(shift) + 6 * sd) / FINE)) + 1
    k = np.arange(-half, half + 1) * FINE
    if sd <= FINE / 4:
        return np.interp(k, [shift - FINE, shift, shift + FINE], [0.0, 1.0, 0.0])
    edges = np.concatenate([k - FINE / 2, [k[-1] + FINE / 2]])
    return np.diff(_normal_cdf(edges, shift, sd))


def _convolve(mass: NDArray[np.float64], sd: float, shift: float = 0.0) -> NDArray[np.float64]:
    """``mass`` convolved with Normal(shift, sd²)."""
    return fftconvolve(mass, _gauss_kernel(sd, shift), mode="same")


def _clip_at_zero(mass: NDArray[np.float64], zero: int) -> NDArray[np.float64]:
    """All mass below grid point ``zero`` (value 0) moved onto it."""
    out = np.maximum(mass, 0.0)
    out[zero] += out[:zero].sum()
    out[:zero] = 0.0
    return out


def _empty_mass(model: FlowModel, grid: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mass of ``b`` on ``grid`` (step :data:`FINE`): the lognormal's, or a normal's."""
    upper = np.concatenate([grid[1:] - FINE / 2, [np.inf]])
    if model.empty_flow_law == "normal":
        cdf = _normal_cdf(upper, model.empty_flow_mean, model.empty_flow_sd)
    elif model.empty_flow_mean <= 0:
        cdf = (upper > 0).astype(np.float64)
    else:
        mu, sigma = lognormal_shape(model.empty_flow_mean, max(model.empty_flow_sd, 1e-6))
        cdf = special.ndtr((np.log(np.maximum(upper, 1e-300)) - mu) / sigma) * (upper > 0)
    return np.diff(np.concatenate([[0.0], cdf]))


#: The grid the 0-mer's law is built on (1-mer): wide of any 0-mer value.
EMPTY_GRID = (-1.5, 3.0)


def _empty_distribution(model: FlowModel, chain_floor: float, edges: NDArray[np.float64]
                        ) -> NDArray[np.float64]:
    """The 0-mer's law on the bins: ``b + a`` per well level, the light clipped at 0, the
    chain's noise added, the value clipped at 0."""
    lo, hi = EMPTY_GRID
    grid = lo + FINE * np.arange(int(round((hi - lo) / FINE)))
    zero = int(round(-lo / FINE))
    b = _empty_mass(model, grid)
    value = np.zeros_like(grid)
    levels = well_levels(model)
    for v in levels:
        light = _convolve(b, model.flow_noise_sd * np.sqrt(v), model.flow_background)
        value += _clip_at_zero(_convolve(_clip_at_zero(light, zero),
                                         float(np.sqrt(chain_floor))), zero)
    cdf = np.cumsum(value) / levels.size
    cdf_edges = np.interp(edges, grid + FINE / 2, cdf, right=1.0)  # clipped mass: bin 0
    return _binned(np.clip(cdf_edges / max(cdf[-1], 1e-300), 0.0, 1.0))


def flow_value_distribution(h: int, model: FlowModel, chain_floor: float = 0.0,
                            chain_shot: float = 0.0, n_bins: int = N_BINS
                            ) -> NDArray[np.float64]:
    """P(value in bin ``i``) for a true ``h``-mer, bins ``i·BIN`` (:func:`bin_edges`), the law
    :func:`draw_flow_values` draws from, averaged over the wells' noise levels
    (:func:`well_levels`). Exact per level for ``h ≥ 1`` (a normal: a product with a normal
    factor plus normals); for ``h = 0`` the sums and the two clippings (the light at 0, then
    the stored value) on a grid of :data:`FINE`."""
    edges = bin_edges(n_bins)
    if h == 0:
        return _empty_distribution(model, chain_floor, edges)
    mu = float(model.mean_light(h))
    out = np.zeros(n_bins)
    levels = well_levels(model)
    for v in levels:
        var = v * ((mu * model.flow_yield_cv) ** 2 + model.flow_noise_sd**2)
        sd = float(np.sqrt(var + chain_floor + chain_shot * h))
        out += _binned(_normal_cdf(edges, mu + model.flow_background, sd))
    return out / levels.size
