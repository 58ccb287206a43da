"""Mutated bundled studies end in a study or a clean error, never a traceback.

The sweep of :mod:`tests.config._study_mutations`: every key of every bundled study (each
``[study]`` key, each ``[[study.axis]]`` and ``[[study.metric]]`` entry and their keys, each key
of ``reference``, ``set`` and ``requirement``, and the sections) × NaN, ±inf, huge, negative,
zero, wrong types, arrays, tables, or removed. Validation only, nothing is run:

* every mutation through :func:`chiptwin.study.load_study`: a :class:`Study` or a
  :class:`ScenarioError` naming a file, the key and what is allowed, never another exception;
* the studies that load, planned as ``chiptwin validate`` plans them (every point's scenario):
  an inconsistent point is recorded as invalid, never raised;
* a fixed sample (every 20th mutation, and every metric-name one, the crash the issue names)
  through ``chiptwin validate`` in-process: exit 0, or exit 2 with one stderr line naming the
  file and the key.
"""

from __future__ import annotations

import dataclasses
import functools

import pytest

from chiptwin.config import ScenarioError
from chiptwin.config.catalog import resolve_scenario
from chiptwin.study import load_study
from chiptwin.study.engine import Plan
from tests.config._study_mutations import all_mutations, label, validate, write

MUTATIONS = all_mutations()


def test_the_sweep_covers_every_bundled_study_and_key():
    files = {src.name for src, _, _ in MUTATIONS}
    assert files == {"adc_bits_pyro.toml", "frame_memory.toml", "lod_pyro.toml",
                     "read_length_pyro.toml"}
    keys = {p for _, p, _ in MUTATIONS}
    assert ("study", "metric", 0, "name") in keys and ("study", "axis", 0, "key") in keys
    assert ("study", "requirement", "confidence") in keys
    assert len(MUTATIONS) > 2000


def test_every_mutation_loads_or_is_refused_with_file_key_and_allowed(tmp_path):
    loaded, refused = [], 0
    resolve = functools.cache(resolve_scenario)  # a bundled name's file, looked up once
    for src, path, value in MUTATIONS:
        target = write(tmp_path, src, path, value)
        try:
            loaded.append(load_study(target, resolve))
        except ScenarioError as exc:
            refused += 1
            where = f"{src.name} {label(path, value)}"
            assert exc.source and (exc.source == str(target) or ".toml" in exc.source), where
            assert exc.key and exc.allowed, where
        except Exception as exc:  # noqa: BLE001 (the point of the test)
            pytest.fail(f"{src.name} {label(path, value)}: {type(exc).__name__}: {exc}")
    # inconsistent points become invalid ones; nothing raises. A plan reads the study's axes,
    # reference, overrides, seed, chip and base scenario, never its name, description or text:
    # studies that differ only there (a mutated name or description) are planned once
    plans = {repr(dataclasses.replace(s, name="", description="", text="")): s for s in loaded}
    for study in plans.values():
        Plan(study)
    assert refused > 0.9 * len(MUTATIONS) and len(plans) > 40


#: Every 40th mutation, and a metric's name as an array or a table (the issue's traceback).
SAMPLE = [m for i, m in enumerate(MUTATIONS) if i % 40 == 0 or (
    m[1][1:2] == ("metric",) and m[1][-1] == "name" and isinstance(m[2], list | dict))][:80]


@pytest.mark.parametrize("src,path,value", SAMPLE,
                         ids=[f"{s.stem}:{label(p, v)}" for s, p, v in SAMPLE])
def test_validate_exits_0_or_2_with_one_line(tmp_path, src, path, value):
    target = write(tmp_path, src, path, value)
    code, err = validate(target)
    assert code in (0, 2), err
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and ".toml" in lines[0], err
