"""Budget studies: a scenario swept over axes, with replicates, metrics, statistics and an answer.

``chiptwin study FILE`` and :func:`run_study` answer "the cheapest budget (ADC bits, frame
memory, DNA amount) that meets the requirement, at what confidence":

- :mod:`.spec`: the study file, validated like a scenario;
- :mod:`.metrics`: the catalogue of per-run metrics;
- :mod:`.stats`: exact binomial, t and delta-method intervals, decisions against a requirement;
- :mod:`.search`: grid or bisection, the monotonicity check, the answer rule;
- :mod:`.rows`: one row (point × replicate), seeded from the study seed and the point's hash;
- :mod:`.execute`: serial, local process pool, Dask;
- :mod:`.store`: the SQLite database that makes a study resumable;
- :mod:`.engine`: ties them together; :mod:`.outputs`: results.csv, study.json, report.md;
- :mod:`.sensitivity`: ``kind = "sensitivity"``, which assumption moves the answer (the
  one-at-a-time design, the swing, the verdict); :mod:`.tornado`: its chart and report table.
"""

from chiptwin.study.engine import StudyResult, run_study
from chiptwin.study.spec import Study, load_study

__all__ = ["Study", "StudyResult", "load_study", "run_study"]
