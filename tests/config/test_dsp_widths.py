"""``[chip.dsp]`` integer keys together: a register wider than the DSP's 64 bits is refused by
name at validation, never an internal error (exit 1) at validation or in the run.

Each key alone is in range; together they can need more than 64 bits: ``acc_bits = 64`` with
``average_frames = 5`` multiplies the accumulator by an 18-bit reciprocal (an 82-bit product),
a 24-bit ADC with M = 256 and K = 65535 needs a 67-bit product for the dark reference's divide.
The rule (:func:`chiptwin.config.consistency_chip._dsp_formats`) runs before the schedule and the
program's costs, which derive the formats. Three tests:

* the issue's command and the tight ends of each limit (the widest value that fits validates,
  one more is refused naming its key), through ``chiptwin.cli.main``;
* a hypothesis test that sets the integer keys that meet in one register (pairs and triples,
  the ADC's bits among them, and maybe one more key) to the ends of their ranges and to the
  values beside the widths that just fit, with the assay's start, flows and duration fitted to
  the new block sizes so that validation reaches the DSP's formats, on scenarios with today's
  chain, a kinetics program and the spatial programs: ``validate`` exits 0 or 2 with one line
  (without the rule it finds the issue's crash);
* the chain's limit itself (:func:`chiptwin.dsp.chain.chain_configs`), key by key.
"""

from __future__ import annotations

import contextlib
import io
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from chiptwin.cli import main
from chiptwin.dsp.chain import FormatLimit, chain_configs, with_accumulator
from tests.config import _mutations as M

FIXED = ['chip.dsp.mode="fixed"']
ISSUE = ["chip.dsp.acc_bits=64", "chip.dsp.average_frames=5", "assay.start_s=21",
         "run.duration_s=1525"]


def _cli(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    return code, err.getvalue()


def _validate(scenario: str, sets: list[str]) -> tuple[int, str]:
    argv = ["validate", scenario]
    for text in sets:
        argv += ["--set", text]
    return _cli(argv)


def test_issue_command_is_refused_naming_acc_bits():
    """The reported command (exit 1 before): exit 2, one line, the key, its value and the fix.
    (The same at the rtl level: ``tests/rtl/test_rtl_validation.py``, under the RTL tests'
    simulator policy.)"""
    assert_refuses_acc_bits(*_validate("pyro_1fmol", ISSUE + ['chip.dsp.mode="fixed"']))


def assert_refuses_acc_bits(code: int, err: str) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "chip.dsp.acc_bits = 64" in err and "82-bit" in err and "acc_bits ≤ 46" in err


def test_issue_command_at_the_float_level_derives_no_formats():
    """The float DSP has no accumulator to narrow: the same chip validates (as before)."""
    assert _validate("pyro_1fmol", ISSUE)[0] == 0


@pytest.mark.parametrize(("sets", "ok", "key"), [
    (["chip.dsp.acc_bits=46"], True, None),  # 46 + 18 = 64: the widest that fits
    (["chip.dsp.acc_bits=47"], False, "chip.dsp.acc_bits"),
    # a kinetics program's weights: one 37-bit product (13-bit chip) is the narrowest accumulator
    (['chip.dsp.program=["cms","dark","background","kinetics"]', "chip.dsp.kinetics_acc_bits=37"],
     True, None),
    (['chip.dsp.program=["cms","dark","background","kinetics"]', "chip.dsp.kinetics_acc_bits=36"],
     False, "chip.dsp.kinetics_acc_bits"),
])
def test_tight_ends_of_the_limits(sets, ok, key):
    code, err = _validate("pyro_1fmol", FIXED + ISSUE[1:] + sets)
    if ok:
        assert code == 0, err
    else:
        assert code == 2 and err.count("\n") == 1 and f"{key} = " in err, err


@pytest.mark.parametrize(("scenario", "sets", "key"), [
    # a 24-bit ADC with 256 samples: K = 65535 needs a 67-bit reciprocal product
    ("pyro_1fmol", [*FIXED, "chip.adc.bits=24", "chip.dsp.cms_samples=256",
                    "chip.dsp.n_dark_frames=65535"], "chip.dsp.n_dark_frames"),
    # the equalizer's 8 x 16 inputs of 32-bit coefficients: 21 + 32 + 7 bits fit, 24-bit ADC not
    ("crosstalk_microarray", ["chip.adc.bits=24", "chip.dsp.wiener_coef_bits=32"],
     "chip.dsp.wiener_coef_bits"),
    # bin_rows sums rows; a float-level program derives its formats too (the schedule counts them)
    ("ccd_two_wells", ["chip.dsp.bin_factor=3"], "chip.dsp.bin_factor"),
])
def test_wide_combination_is_refused_naming_its_key(scenario, sets, key):
    code, err = _validate(scenario, sets)
    assert code == 2 and err.count("\n") == 1 and f"{key} = " in err, err


# --- the integer keys together, through the command line --------------------------------------

#: The DSP programs the sweep runs on (today's chain, kinetics, and the spatial stages).
PROGRAMS = (
    None,
    ["cms", "dark", "background", "kinetics"],
    ["cms", "dark", "background", "average", "fir8"],
    ["cms", "dark", "background", "average", "bin_rows", "fir8", "wiener"],
)
#: Scenarios whose optics and assay take every program above (or their own, with None).
BASES = ("pyro_1fmol", "crosstalk_microarray", "ccd_two_wells")
#: Values of each integer key: the ends of its range, the values beside the widths that just
#: fit (acc_bits 46 + an 18-bit reciprocal = 64), small counts that are not powers of two.
VALUES = {
    "chip.dsp.acc_bits": (0, 1, 46, 47, 63, 64),
    "chip.dsp.average_frames": (1, 2, 3, 5, 65535, 65536),
    "chip.dsp.n_dark_frames": (1, 2, 3, 5, 65535, 65536),
    "chip.dsp.cms_samples": (1, 2, 3, 255, 256),
    "chip.dsp.bin_factor": (0, 1, 2, 3, 4096),
    "chip.dsp.wiener_coef_bits": (4, 5, 31, 32),
    "chip.dsp.kinetics_acc_bits": (8, 9, 36, 37, 45, 46),
    "chip.adc.bits": (1, 2, 13, 23, 24),
    "chip.memory.word_bits": (1, 2, 63, 64),
}
#: Keys that meet in one register (widths add along the data path), drawn together.
GROUPS = (
    ("chip.dsp.acc_bits", "chip.dsp.average_frames"),
    ("chip.adc.bits", "chip.dsp.cms_samples", "chip.dsp.n_dark_frames"),
    ("chip.adc.bits", "chip.dsp.n_dark_frames", "chip.dsp.average_frames"),
    ("chip.adc.bits", "chip.dsp.acc_bits", "chip.dsp.average_frames"),
    ("chip.adc.bits", "chip.dsp.kinetics_acc_bits", "chip.dsp.cms_samples"),
    ("chip.adc.bits", "chip.dsp.bin_factor", "chip.dsp.wiener_coef_bits"),
    ("chip.adc.bits", "chip.memory.word_bits"),
)


def fit_timing(raw: dict) -> dict:
    """Start after the K dark frames, flows of whole N-frame blocks, a duration that covers them
    and memory for a block: what validation checks before the DSP's widths matter."""
    chip, a = raw["chip"], raw["assay"]
    d = chip.get("dsp", {})
    period = chip.get("timing", {}).get("frame_period_s", 1.0)
    k, n = d.get("n_dark_frames", 16), d.get("average_frames", 4)
    a["start_s"] = k * period
    if a["kind"] == "pyrosequencing":
        a["n_flows"] = M.SHORT_FLOWS
        a["flow_period_s"] = max(1, math.ceil(a.get("flow_period_s", 60.0) / (n * period))) \
            * n * period
        raw["run"]["duration_s"] = a["start_s"] + a["n_flows"] * a["flow_period_s"]
    else:
        raw["run"]["duration_s"] = a["start_s"] + 2 * n * period
    chip.setdefault("memory", {})["capacity_bits"] = 2**40
    return raw


@st.composite
def dsp_combination(draw) -> tuple[str, dict, str]:
    """A scenario with a group of keys that meet in one register (and maybe one more key) set
    to the values above, mostly at the fixed level and with the timing fitted."""
    name = draw(st.sampled_from(BASES))
    raw = M.mutate(M.read(M.ROOT / "scenarios" / f"{name}.toml"), "chip.dsp.mode",
                   draw(st.sampled_from(["fixed", "fixed", "fixed", "float"])))
    program = draw(st.sampled_from(PROGRAMS))
    if program is not None and not (name == "pyro_1fmol" and "wiener" in program):
        raw = M.mutate(raw, "chip.dsp.program", program)
    keys = list(draw(st.sampled_from(GROUPS)))
    keys += [k for k in draw(st.lists(st.sampled_from(sorted(VALUES)), max_size=1))
             if k not in keys]
    for key in keys:
        raw = M.mutate(raw, key, draw(st.sampled_from(VALUES[key])))
    if draw(st.integers(0, 3)):
        raw = fit_timing(raw)
    return name, raw, ",".join(keys)


#: Drawn combinations per run (they differ from run to run): the limits' tight ends and the
#: wide combinations are pinned above, key by key; this looks for interactions beyond them.
DSP_EXAMPLES = 100


@settings(max_examples=DSP_EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(case=dsp_combination())
def test_dsp_integer_keys_together_validate_or_exit_2(tmp_path_factory, case):
    name, raw, keys = case
    path = Path(tmp_path_factory.mktemp("w")) / "mutated.toml"
    path.write_text(M.dumps(raw), encoding="utf-8")
    code, err = _cli(["validate", str(path)])
    assert code in (0, 2), f"{name}: {keys}: exit {code}\n{err}"
    assert "Traceback" not in err
    if code == 2:
        assert err.count("\n") == 1 and err.startswith("chiptwin: error: "), err
    event(f"validate exit {code}")


# --- the chain's limits, key by key -----------------------------------------------------------


@pytest.mark.parametrize(("counts", "key", "text"), [
    ((24, 256, 65535, 4), "n_dark_frames", "or ≤ 8191"),
    ((24, 256, 65536, 65535), "average_frames", "a power of two ≤ 16384"),
])
def test_chain_names_the_count_that_does_not_fit(counts, key, text):
    with pytest.raises(FormatLimit, match=key) as info:
        chain_configs(*counts)
    assert info.value.key == key and info.value.value == counts[["n_dark_frames",
                                                                  "average_frames"].index(key) + 2]
    assert text in info.value.allowed


@pytest.mark.parametrize("n", [3, 5, 100, 65535])
def test_narrowed_accumulator_fits_up_to_the_multiplier(n):
    """With N not a power of two the product is acc_bits + 18: 46 bits fit, 47 do not; a power of
    two never multiplies."""
    chain = chain_configs(13, 4, 16, n)
    assert with_accumulator(chain, 46, "WRAP").average.registers()["product"].word_bits == 64
    with pytest.raises(FormatLimit, match="acc_bits ≤ 46"):
        with_accumulator(chain, 47, "WRAP")
    assert with_accumulator(chain_configs(13, 4, 16, 4), 64, "SAT").average.acc_fmt.word_bits == 64
