"""Equivalence, RTL vs fixed-point model, bit for bit, on Verilator: for every block kind at
least 1e6 input beats (``rtl_ref.suite.VECTORS``, split over the kind's configs), random and
corner vectors, random bubbles and back-pressure, zero differing words and identical overflow
counts per register. The vectors must reach the corners they are made for."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.fixed import OVERFLOW_MODES, ROUNDING_MODES
from rtl_ref import suite, vectors

pytestmark = pytest.mark.rtl

# corners each kind's vector set must reach (summed over its configs)
CORNERS = ("ties_pos", "ties_neg", "sat", "wrap", "min_code", "max_code")


def _failures(reports) -> str:
    return "\n".join(r.text() for r in reports if not r.ok)


@pytest.mark.parametrize("kind", list(suite.KINDS))
def test_block_matches_the_model_bit_for_bit(kind: str, banks) -> None:
    reports = suite.run_kind(banks[kind], "verilator", suite.VECTORS)
    assert all(r.ok for r in reports), _failures(reports)
    assert sum(r.n_beats for r in reports) >= 1_000_000
    total = {c: sum(r.coverage.get(c, 0) for r in reports) for c in CORNERS}
    missing = [c for c in CORNERS if total[c] == 0]
    assert not missing, f"{kind}: the vectors never reach {missing} ({total})"
    print(f"\n{kind}: {sum(r.n_beats for r in reports)} beats, {len(reports)} configs, "
          f"{sum(r.sim_seconds for r in reports):.2f} s simulated, corners {total}")


@pytest.mark.parametrize("kind", list(suite.KINDS))
def test_full_rate_is_one_beat_per_cycle(kind: str, banks) -> None:
    """Without bubbles or back-pressure every block takes a beat each cycle; its last output
    handshakes one cycle after the last input."""
    for i, blk in enumerate(banks[kind].blocks[:3]):
        inputs = vectors.for_block(blk, 2000, np.random.default_rng(i))
        r = banks[kind].run(i, inputs, "verilator")
        assert r.ok, r.text()
        assert r.cycles == r.n_beats + 1


def test_every_mode_is_built() -> None:
    """The background bank alone holds every rounding × overflow pair."""
    pairs = {(b.cfg.rounding, b.cfg.overflow) for b in suite.background_blocks()}
    assert pairs >= {(r, o) for r in ROUNDING_MODES for o in OVERFLOW_MODES}
