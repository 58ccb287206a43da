"""The drop-in RTL routines return the model's :class:`FixedResult`: codes, format and
per-register overflow counts, equal (three levels of one DSP share one test)."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp.filters import FirConfig, KineticsConfig, fir_fixed, kinetics_weighted_fixed
from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.frame_ops import (
    AverageConfig,
    BackgroundConfig,
    CmsConfig,
    average_frames_fixed,
    cms_fixed,
    subtract_background_fixed,
)
from chiptwin.dsp.stress import random_codes
from rtl_ref import routines

pytestmark = pytest.mark.rtl


def _same(a, b) -> None:
    np.testing.assert_array_equal(a.codes, b.codes)
    assert a.codes.shape == b.codes.shape and a.fmt == b.fmt and a.overflow == b.overflow


def test_routines_return_the_model_result(rng) -> None:
    bg = BackgroundConfig(out_fmt=Fmt(True, 13, 2))  # narrow: saturates
    frames, dark = random_codes(bg.in_fmt, (2, 3, 9), rng), random_codes(bg.dark_fmt, (9,), rng)
    _same(routines.subtract_background_rtl(frames, dark, bg),
          subtract_background_fixed(frames, dark, bg))
    avg = AverageConfig(n=3)
    x = random_codes(avg.in_fmt, (12, 2, 5), rng)
    _same(routines.average_frames_rtl(x, avg, p_ready=0.5), average_frames_fixed(x, avg))
    cms = CmsConfig(m=2)
    r, s = (random_codes(cms.in_fmt, (2, 4, 2, 6), rng) for _ in range(2))
    _same(routines.cms_rtl(r, s, cms, simulator="icarus"), cms_fixed(r, s, cms))
    fir = FirConfig()
    x = random_codes(fir.in_fmt, (20, 3), rng)
    _same(routines.fir_rtl(x, fir), fir_fixed(x, fir))
    kin = KineticsConfig()
    x = random_codes(kin.in_fmt, (3, 2, 16, 4), rng)
    _same(routines.kinetics_weighted_rtl(x, kin), kinetics_weighted_fixed(x, kin))
