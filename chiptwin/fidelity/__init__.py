"""Speed against error: ``auto``'s calibrations and the fidelity ladder
(docs/background/speed-and-error.md), the tools over the twin that run it at several levels.

* :mod:`.auto`: :func:`resolve` (a scenario's ``auto`` keys, calibrating what the estimates
  cache lacks) and :func:`run` (the twin's run with ``auto`` so resolved: ``chiptwin.run``).
* :mod:`.ladder`: :func:`run_ladder`, each level's wall time and error against the most
  faithful combination, on the same seeds.
* :mod:`.compare`: how a level's error is measured over seeds (the ratio of the means with a
  delta-method Student-t interval, resolved or the seeds that would resolve it).

The levels themselves, the figures compared and the choice are :mod:`chiptwin.twin.levels`.
"""

from chiptwin.fidelity.auto import Calibrations, resolve, run
from chiptwin.fidelity.ladder import run_ladder, table, write_ladder
from chiptwin.twin.levels import (
    LEVELS,
    AutoChoice,
    Estimate,
    describe,
    gaussian_tv,
    reference_levels,
    with_levels,
)

__all__ = ["LEVELS", "AutoChoice", "Calibrations", "Estimate", "describe", "gaussian_tv",
           "reference_levels", "resolve", "run", "run_ladder", "table", "with_levels",
           "write_ladder"]
