"""Validation at the rtl level: the chain's width limit is refused by name, as at fixed.

Here, not in ``tests/config``, so the RTL tests' simulator policy applies (``conftest.py``:
skipped with how to install Verilator on a machine without it, a failure with ``CI=true``).
"""

from __future__ import annotations

import pytest

from tests.config.test_dsp_widths import ISSUE, _validate, assert_refuses_acc_bits

pytestmark = pytest.mark.rtl


def test_issue_command_is_refused_naming_acc_bits_at_rtl():
    assert_refuses_acc_bits(*_validate("pyro_1fmol", ISSUE + ['chip.dsp.mode="rtl"']))
