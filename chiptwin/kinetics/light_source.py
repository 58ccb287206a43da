"""The light-source contract every kinetics level fulfils (docs/architecture.md)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray


@runtime_checkable
class LightSource(Protocol):
    """Light emitted per site, into 4π.

    :class:`~chiptwin.kinetics.pulse_train.PulseTrain` (closed form) is one; the cascade level
    provides another with the same methods.
    """

    @property
    def n_sites(self) -> int:
        """Number of sites (rows of every result)."""
        ...

    def rate(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Emission rate at the times ``t_s`` (s): shape ``(n_sites, n_t)``, photons/s."""
        ...

    def photons(self, t_edges_s: ArrayLike) -> NDArray[np.float64]:
        """Exact integral of the rate over each window: shape ``(n_sites, n_windows)``, photons."""
        ...


@dataclass(frozen=True, eq=False)
class Replicated:
    """``n_sites`` sites with one light: a one-site source evaluated once and shared.

    An array of identical sites (``pyro_array_256``: 4,096 sites, one template amount) needs the
    kinetics of one: each row of :meth:`photons` and :meth:`rate` is the one-site source's row,
    bit for bit what a source of ``n_sites`` identical sites gives (the closed forms evaluate
    each site on its own).
    """

    source: LightSource
    n_sites: int

    def __post_init__(self) -> None:
        if self.source.n_sites != 1:
            raise ValueError(f"source has {self.source.n_sites} sites: Replicated shares one")
        if self.n_sites < 0:
            raise ValueError(f"n_sites = {self.n_sites}: must be >= 0")

    def rate(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """The one site's rate on every row: ``(n_sites, n_t)``, photons/s."""
        return np.repeat(self.source.rate(t_s), self.n_sites, axis=0)

    def photons(self, t_edges_s: ArrayLike) -> NDArray[np.float64]:
        """The one site's photons per window on every row: ``(n_sites, n_windows)``."""
        return np.repeat(self.source.photons(t_edges_s), self.n_sites, axis=0)
