"""The light source every closed-form assay produces: per-site sums of exponential pulses.

A pulse ``p`` belongs to site ``site[p]``, starts at ``onset_s[p]`` and emits

    r_p(t) = amplitude_per_s[p] · exp(−decay_per_s[p] · (t − onset_s[p]))   for t ≥ onset_s[p],
    r_p(t) = 0                                                                for t < onset_s[p],

in photons/s into 4π (``decay_per_s = 0`` is a constant glow). Every closed-form equation of
Salama et al. 2004 (eqs. 5–19) is one such pulse per site, and a pyrosequencing run is one pulse per
site and flow. :meth:`PulseTrain.photons` integrates the rate over integration windows exactly, in
closed form, which is what the ``binned`` and ``expected`` photon statistics need (the contract in
``docs/architecture.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chiptwin import _checks
from chiptwin.kinetics import _kernels


def _site_indices(site: ArrayLike, n_sites: int) -> NDArray[np.int64]:
    arr = np.asarray(site)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"site has dtype {arr.dtype}: must be integers in [0, {n_sites})")
    arr = arr.astype(np.int64).reshape(-1)
    bad = (arr < 0) | (arr >= n_sites)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"site = {int(arr[i])} (at index {i}) is out of range: must be in "
                         f"[0, {n_sites}) for n_sites = {n_sites}")
    return arr


def _frozen(arr: NDArray) -> NDArray:
    out = np.ascontiguousarray(arr).copy()
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class PulseTrain:
    """Per-site sums of exponential light pulses (photons/s emitted into 4π).

    Parameters
    ----------
    site : array_like of int, shape (n_pulses,)
        Site each pulse belongs to, in ``[0, n_sites)``.
    onset_s : array_like of float, shape (n_pulses,)
        Start of each pulse. Unit: s.
    amplitude_per_s : array_like of float, shape (n_pulses,)
        Emission rate at onset, >= 0. Unit: photons/s (into 4π).
    decay_per_s : array_like of float, shape (n_pulses,)
        Exponential decay rate, >= 0 (0 = constant glow). Unit: 1/s.
    n_sites : int
        Number of sites, >= 0; sites without pulses emit nothing.

    Notes
    -----
    The arrays are stored as read-only float64/int64 copies. Equality is identity (``eq=False``):
    compare the arrays to compare trains.
    """

    site: NDArray[np.int64]
    onset_s: NDArray[np.float64]
    amplitude_per_s: NDArray[np.float64]
    decay_per_s: NDArray[np.float64]
    n_sites: int

    def __post_init__(self) -> None:
        if isinstance(self.n_sites, bool) or not isinstance(self.n_sites, int | np.integer):
            raise ValueError(f"n_sites = {self.n_sites!r} must be an int >= 0")
        if self.n_sites < 0:
            raise ValueError(f"n_sites = {self.n_sites} is out of range: must be >= 0")
        fields = {
            "onset_s": _checks.as_float_array("onset_s", self.onset_s),
            "amplitude_per_s": _checks.nonnegative("amplitude_per_s", self.amplitude_per_s),
            "decay_per_s": _checks.nonnegative("decay_per_s", self.decay_per_s),
        }
        site = _site_indices(self.site, int(self.n_sites))
        for name, arr in fields.items():
            if arr.shape != site.shape:
                raise ValueError(f"{name} has shape {arr.shape}: must match site, {site.shape}")
            object.__setattr__(self, name, _frozen(arr))
        object.__setattr__(self, "site", _frozen(site))
        object.__setattr__(self, "n_sites", int(self.n_sites))

    @property
    def n_pulses(self) -> int:
        """Number of pulses."""
        return int(self.site.size)

    def rate(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Emission rate per site at the times ``t_s``.

        Parameters
        ----------
        t_s : array_like of float, shape (n_t,)
            Times, any order. Unit: s.

        Returns
        -------
        ndarray, shape (n_sites, n_t)
            Unit: photons/s (into 4π). A pulse counts from its onset on (right-continuous).
        """
        t = _checks.as_float_array("t_s", t_s)
        if t.ndim != 1:
            raise ValueError(f"t_s has shape {t.shape}: must be 1-D")
        return _kernels.pulse_rate(self.site, self.onset_s, self.amplitude_per_s,
                                   self.decay_per_s, t, self.n_sites)

    def photons(self, t_edges_s: ArrayLike) -> NDArray[np.float64]:
        """Photons per site in each window ``[t_i, t_{i+1}]``: the exact integral of the rate.

        Parameters
        ----------
        t_edges_s : array_like of float, shape (n_windows + 1,)
            Window edges, non-decreasing, at least two. Unit: s.

        Returns
        -------
        ndarray, shape (n_sites, n_windows)
            Unit: photons (into 4π).

        Notes
        -----
        Closed form per pulse, ``A e^{−k(a−t0)} (1 − e^{−kw}) / k`` over the part ``[a, a + w]``
        of the window after onset, evaluated with ``expm1``; pulses of one site sharing a decay
        rate are summed into one exponential state first (``_kernels.pulse_photons``). Relative
        error of a few ulp per pulse for any ``k ≥ 0``, window length or start time (plus the
        inherent ``k·t·ε`` of ``e^{−kt}``); never NaN or inf.
        """
        edges = _checks.as_float_array("t_edges_s", t_edges_s)
        if edges.ndim != 1 or edges.size < 2:
            raise ValueError(f"t_edges_s has shape {edges.shape}: must be 1-D with >= 2 edges")
        steps = np.diff(edges)
        if (steps < 0).any():
            i = int(np.argmax(steps < 0))
            raise ValueError(f"t_edges_s must be non-decreasing: t_edges_s[{i + 1}] = "
                             f"{float(edges[i + 1])!r} < t_edges_s[{i}] = {float(edges[i])!r}")
        start, site, onset, amplitude, decay = self._groups
        return _kernels.pulse_photons(start, site, onset, amplitude, decay, edges, self.n_sites)

    @cached_property
    def _groups(self) -> tuple[NDArray[np.int64], ...]:
        """Lit pulses sorted by (site, decay, onset) and the start index of each (site, decay) run.

        Pulses of one site with one decay rate add up to a single exponential state, which lets the
        window integral cost one exp per group and window instead of one per pulse and window.
        """
        order = np.lexsort((self.onset_s, self.decay_per_s, self.site))
        order = order[self.amplitude_per_s[order] > 0]
        site, decay = self.site[order], self.decay_per_s[order]
        breaks = np.flatnonzero((np.diff(site) != 0) | (np.diff(decay) != 0)) + 1
        start = np.concatenate([[0], breaks, [order.size]]) if order.size else np.zeros(1)
        return (start.astype(np.int64), site, self.onset_s[order], self.amplitude_per_s[order],
                decay)

    def total_photons(self) -> NDArray[np.float64]:
        """Photons per site integrated from onset to infinity (``inf`` for a lasting glow).

        Returns
        -------
        ndarray, shape (n_sites,)
            Unit: photons (into 4π).
        """
        k = self.decay_per_s
        per_pulse = np.zeros(self.n_pulses)
        lit = self.amplitude_per_s > 0
        per_pulse[lit & (k == 0)] = np.inf
        decaying = lit & (k > 0)
        per_pulse[decaying] = self.amplitude_per_s[decaying] / k[decaying]
        return np.bincount(self.site, weights=per_pulse, minlength=self.n_sites).astype(np.float64)


def superpose(*trains: PulseTrain) -> PulseTrain:
    """Sum several pulse trains over the same sites (light adds).

    Parameters
    ----------
    *trains : PulseTrain
        At least one; all with the same ``n_sites``.

    Returns
    -------
    PulseTrain
        All pulses of all trains, in order.
    """
    if not trains:
        raise ValueError("superpose needs at least one PulseTrain")
    n_sites = {t.n_sites for t in trains}
    if len(n_sites) != 1:
        raise ValueError(f"n_sites differ between trains: {sorted(n_sites)}; must all be equal")
    return PulseTrain(
        site=np.concatenate([t.site for t in trains]),
        onset_s=np.concatenate([t.onset_s for t in trains]),
        amplitude_per_s=np.concatenate([t.amplitude_per_s for t in trains]),
        decay_per_s=np.concatenate([t.decay_per_s for t in trains]),
        n_sites=n_sites.pop(),
    )
