"""Physical constants (CODATA 2018 exact values) and the chip's time unit.

Simulation time in the chip model is an integer count of nanosecond ticks (:data:`TICKS_PER_S`);
convert only at the edges with :func:`s_to_ticks` and :func:`ticks_to_s`.
"""

from __future__ import annotations

Q_E: float = 1.602176634e-19
"""Elementary charge. Unit: C (exact, SI 2019)."""

K_B: float = 1.380649e-23
"""Boltzmann constant. Unit: J/K (exact, SI 2019)."""

N_A: float = 6.02214076e23
"""Avogadro constant. Unit: 1/mol (exact, SI 2019)."""

H_PLANCK: float = 6.62607015e-34
"""Planck constant. Unit: J·s (exact, SI 2019)."""

C_LIGHT: float = 299_792_458.0
"""Speed of light in vacuum. Unit: m/s (exact)."""

T_ROOM_K: float = 300.0
"""Room temperature used by REFERENCE §4 for kTC noise. Unit: K."""

TICKS_PER_S: int = 1_000_000_000
"""The chip model's clock: one tick is one nanosecond."""


def s_to_ticks(t_s: float) -> int:
    """Seconds to integer nanosecond ticks, rounded to the nearest tick."""
    return int(round(t_s * TICKS_PER_S))


def ticks_to_s(ticks: int) -> float:
    """Integer nanosecond ticks to seconds."""
    return ticks / TICKS_PER_S
