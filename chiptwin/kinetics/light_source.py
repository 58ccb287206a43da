"""The light-source contract every kinetics level fulfils (docs/architecture.md)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray


@runtime_checkable
class LightSource(Protocol):
    """Light emitted per site, into 4π.

    :class:`~chiptwin.kinetics.pulse_train.PulseTrain` (closed form) is one; the cascade level
    (issue 5) provides another with the same methods.
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
