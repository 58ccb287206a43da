"""Detection: per-site statistics of the DSP's results.

* :mod:`.statistics`: SNR as a power ratio (paper eq. 22) and as an amplitude ratio, window
  sums with the coherent noise of a shared dark reference, the signal a target SNR needs.
* :mod:`.stats`: binomial (Clopper–Pearson at Korn–Graubard's effective n, runs as clusters),
  t and delta-method intervals for rates and means over replicates, and decisions against a
  requirement (studies, the ladder).
"""

from chiptwin.detection.statistics import SNR_DEFINITION, required_signal_e, snr, window_sums

__all__ = ["SNR_DEFINITION", "required_signal_e", "snr", "window_sums"]
