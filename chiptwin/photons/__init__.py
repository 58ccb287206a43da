"""Photon statistics: from a light source's rate to photons per pixel.

Levels (the fidelity ladder): ``expected`` (means and variances, in :mod:`chiptwin.pixel`),
``binned`` (:func:`binned`: Poisson counts of the exact window integrals) and ``events``
(:func:`arrival_times`: exact arrival times of the inhomogeneous Poisson process, by time
rescaling through the integrated rate). :func:`saturation_time` turns arrival times into the time a
pixel's well fills (QE as thinning, dark current as a second Poisson stream);
:func:`saturation_time_from_rate` draws the same time straight from the rate (one Gamma variate
per pixel), at any light level. The chip model's ``events`` level draws the same joint law of a
window's count and filling time without drawing arrivals
(:class:`chiptwin.twin.stages.EventPixels`); these are its references.
"""

from __future__ import annotations

from chiptwin.photons.events import (
    MAX_EVENTS,
    PhotonEvents,
    arrival_times,
    binned,
    counts_from_events,
    detected_electrons,
    expected_counts,
    saturation_time,
    saturation_time_from_rate,
)

__all__ = [
    "MAX_EVENTS",
    "PhotonEvents",
    "arrival_times",
    "binned",
    "counts_from_events",
    "detected_electrons",
    "expected_counts",
    "saturation_time",
    "saturation_time_from_rate",
]
