"""A run's outputs: ``summary.json``, ``arrays.npz``, the PNG plots and ``report.md``
(:mod:`.outputs`); the fixed-point DSP's report on a scenario's data (:mod:`.dsp_report`,
``chiptwin dsp-report``). The output folder's rules are :mod:`chiptwin.config.outputs`."""

from chiptwin.report.dsp_report import dsp_report
from chiptwin.report.outputs import headline, make_plots, report_markdown, write_outputs

__all__ = ["dsp_report", "headline", "make_plots", "report_markdown", "write_outputs"]
