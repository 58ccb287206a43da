"""A run's outputs: ``summary.json``, ``run.nc`` (its arrays as one labelled xarray Dataset,
:mod:`.dataset`; :func:`open_run` reads it), the PNG plots, ``report.md`` and ``chip.vcd``
(:mod:`.outputs`); a study's table as a Dataset (:func:`open_study`, :mod:`.study_dataset`); the
fixed-point DSP's report on a scenario's data (:mod:`.dsp_report`, ``chiptwin dsp-report``). The
output folder's rules are :mod:`chiptwin.config.outputs`."""

from chiptwin.report.dataset import open_run, run_dataset
from chiptwin.report.dsp_report import dsp_report
from chiptwin.report.outputs import headline, make_plots, report_markdown, write_outputs
from chiptwin.report.study_dataset import open_study

__all__ = ["dsp_report", "headline", "make_plots", "open_run", "open_study", "report_markdown",
           "run_dataset", "write_outputs"]
