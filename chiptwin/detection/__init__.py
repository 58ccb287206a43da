"""Detection: per-site statistics of the DSP's results.

* :mod:`.statistics`: SNR as a power ratio (paper eq. 22) and as an amplitude ratio, window
  sums with the coherent noise of a shared dark reference, the signal a target SNR needs.
* :mod:`.stats`: binomial (Clopper–Pearson at Korn–Graubard's effective n, runs as clusters),
  t and delta-method intervals for rates and means over replicates, and decisions against a
  requirement (studies, the ladder).
* :mod:`.reads`, :mod:`.read_stats`: the base callers (``round``, ``dephase``), per-base
  qualities and the figures of reads in flow space; :mod:`.key_pass`, the key-pass filter.
* :mod:`.measured_reads`: measured flowgrams through the same callers (their noise measured
  from the values); :mod:`.align`, a called read against its truth in base space.
"""

from chiptwin.detection.statistics import SNR_DEFINITION, required_signal_e, snr, window_sums

__all__ = ["SNR_DEFINITION", "required_signal_e", "snr", "window_sums"]
