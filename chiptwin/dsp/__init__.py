"""The on-chip DSP: float reference (:mod:`.reference`), the chip-model pipeline (:mod:`.pipeline`)."""
