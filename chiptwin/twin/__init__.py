"""The twin: the stages wired into one run of a scenario.

A scenario goes through the stages in signal order (:data:`chiptwin.STAGES`)::

    prepare (kinetics ──► optics)  ──►  simulate (pixel ──► ADC ──► memory ──► DSP)  ──►  detect
    light per site per window           the chip model, SimPy, integer ns ticks         per site

* :mod:`.stages`: thin adapters from a :class:`~chiptwin.config.Scenario` to each stage
  package's pure functions (the light sources, the coupling matrix, the sensor model).
* :mod:`.scene`: the types the stages share (:class:`Scene`, ``ChainOutput``, ``stage_rng``).
* :mod:`.programs`: the on-chip DSP program (plans, pipeline, cross-talk figures).
* :mod:`.shortcuts`, :mod:`.saturation`: the carried dark pixels; when pixels fill.
* :mod:`.results`, :mod:`.dose_response`: chain outputs → the summary's figures.
* :mod:`.levels`: the fidelity levels, and ``auto``'s choice from estimated errors.
* :mod:`.runner`: :func:`run` = :func:`prepare` → :func:`run_prepared` (:func:`simulate`, detect).

``auto`` keys are resolved here from cached estimates only; :func:`chiptwin.run` (that is
:func:`chiptwin.fidelity.run`) runs the calibrations the cache lacks.
"""

from chiptwin.twin.runner import Result, prepare, run, run_prepared, simulate
from chiptwin.twin.scene import Scene, StageTimer, stage_rng

__all__ = ["Result", "Scene", "StageTimer", "prepare", "run", "run_prepared", "simulate",
           "stage_rng"]
