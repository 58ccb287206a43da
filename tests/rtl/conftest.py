"""Fixtures of the RTL co-simulation tests: simulators present (or a skip / a CI failure that
says how to install them), and every Verilator and Icarus build made once, concurrently."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import rtl_ref
from chiptwin.dsp.chain import chain_configs
from rtl_ref import suite
from rtl_ref.chain_block import ChainBlock
from rtl_ref.cosim import Bank
from rtl_ref.frame_blocks import AverageBlock, BackgroundBlock
from tests.conftest import unavailable

MUTANTS = ("CT_MUTANT_ROUND", "CT_MUTANT_ACC")


@pytest.fixture(scope="session", autouse=True)
def simulators() -> None:
    """Skip the RTL tests without Verilator and Icarus; in CI, fail instead."""
    miss = rtl_ref.missing()
    if not miss:
        return
    unavailable(f"{' and '.join(miss)} not usable: {rtl_ref.INSTALL_HINT}")


def mutant_bank() -> Bank:
    """A rounding constant off by one (background, RND_CONV ties) and a one-bit-narrower
    accumulator (the chain's exact average: no rounding, so only the accumulator can fail)."""
    chain = chain_configs(13, 4, 16, 4)
    blocks = [BackgroundBlock(suite.background_blocks()[0].cfg),
              AverageBlock(chain.average, suite.PIXELS)]
    return Bank(blocks, MUTANTS)


@pytest.fixture(scope="session")
def banks(simulators) -> dict[str, Bank]:
    """The suite's banks (built for Verilator and Icarus) and the mutant bank (Verilator)."""
    out = {kind: suite.bank(kind) for kind in suite.KINDS}
    out["mutants"] = mutant_bank()
    small_chain = Bank([ChainBlock(chain_configs(13, 2, 4, 4), 24)])  # tests/conftest.SMALL
    jobs = [(b, sim) for b in out.values() for sim in ("verilator", "icarus")]
    jobs.append((small_chain, "verilator"))
    with ThreadPoolExecutor(len(jobs)) as pool:  # compiles are capped at the core count
        list(pool.map(lambda job: job[0].build(job[1]), jobs))
    return out


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh, seeded generator per test."""
    return np.random.default_rng(20240613)
