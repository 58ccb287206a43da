"""Sizes and limits of the model that the stages obey and the run budget checks beforehand.

One home for numbers that both a stage (:mod:`chiptwin.twin.stages`, :mod:`chiptwin.twin.scene`,
:mod:`chiptwin.pixel.frames`) and :mod:`chiptwin.config.budget` need, so the budget never
mirrors a copy; no heavy imports (validation imports it before numba is loaded).
"""

from __future__ import annotations

import numpy as np

#: Largest mean NumPy's Poisson sampler accepts (``numpy.random`` ``POISSON_LAM_MAX``). Unit: e⁻.
POISSON_LAM_MAX: float = float(np.iinfo(np.int64).max - np.sqrt(np.iinfo(np.int64).max) * 10)

#: ADC samples per block of frames (reset and signal, all pixels): the frames whose light,
#: moments and codes are made together, and so the unit of what is held at once (8 MiB of codes).
BLOCK_SAMPLES: int = 1 << 20

#: Largest coupling held as a dense (n_pixels, n_sites) array, in entries (128 MiB of float64).
#: A larger one (thousands of sites on a large array) is a ``scipy.sparse`` CSR matrix.
DENSE_COUPLING_ENTRIES: int = 1 << 24

#: Largest array whose coupling is integrated over every pixel for every site (the dense path).
#: Above 64 × 64 pixels it is the shifted kernel (``chiptwin.twin.stages._sparse_coupling``):
#: integrating the psf over all 128 × 128 pixels took 236 MB of temporaries and 0.4 s for two
#: sites, more than the whole chip model then holds.
DENSE_COUPLING_PIXELS: int = 64 * 64

#: The sparse coupling's one approximation: a pixel whose share of a site's light is below this
#: fraction of the site's own pixel's share is left out (contact optics, 125 µm pixels, 15 µm:
#: from the 8th pixel out, ≈ 1e-6 of the light; the dense matrix keeps every pixel).
COUPLING_DROP_RTOL: float = 1e-6


def frames_per_block(n_pixels: int, cms_samples: int) -> int:
    """Frames in one block of :data:`BLOCK_SAMPLES` samples (at least 1)."""
    return max(1, BLOCK_SAMPLES // max(2 * cms_samples * n_pixels, 1))


def coupling_is_dense(n_pixels: int, n_sites: int) -> bool:
    """Whether the coupling of ``n_sites`` sites on ``n_pixels`` pixels is the dense matrix."""
    return n_pixels * n_sites <= DENSE_COUPLING_ENTRIES and n_pixels <= DENSE_COUPLING_PIXELS
