"""The RTL is lint-clean under ``verilator --lint-only -Wall``: every module with its default
parameters, and every generated top with the parameters the model's configs give it."""

from __future__ import annotations

import pytest

from chiptwin.dsp.chain import chain_configs
from rtl_ref import build, suite
from rtl_ref.chain_block import ChainBlock

pytestmark = pytest.mark.rtl

MODULES = [p.stem for p in build.rtl_sources()]


def test_the_rtl_has_every_block() -> None:
    for module in ("ct_background", "ct_average", "ct_cms", "ct_fir", "ct_kinetics", "ct_chain"):
        assert module in MODULES


@pytest.mark.parametrize("module", MODULES)
def test_module_is_lint_clean(module: str) -> None:
    build.lint(top_module=module)  # raises BuildError with Verilator's output on any warning


@pytest.mark.parametrize("kind", list(suite.KINDS))
def test_suite_top_is_lint_clean(kind: str) -> None:
    build.lint([b.instance() for b in suite.KINDS[kind]()])


@pytest.mark.parametrize("counts", [(13, 4, 16, 4), (13, 3, 10, 5), (10, 1, 1, 1)])
def test_chain_top_is_lint_clean(counts: tuple[int, int, int, int]) -> None:
    build.lint([ChainBlock(chain_configs(*counts), 24).instance()])
