"""The documentation against the code it describes (no Sphinx needed).

- every bundled scenario and study the README and the docs name exists;
- every flag the docs write after ``chiptwin <command>`` exists in that command's parser, and so
  does every flag of the generated command-line reference;
- every Markdown link to a local file resolves.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

from chiptwin.cli import build_parser
from chiptwin.config.catalog import bundled_scenarios, bundled_studies

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts
               and "generated" not in p.parts and "jupyter_execute" not in p.parts)
TEXTS = {p: p.read_text(encoding="utf-8") for p in [ROOT / "README.md", *PAGES]}


def _reference_module():
    spec = importlib.util.spec_from_file_location(
        "chiptwin_reference", DOCS / "_ext" / "chiptwin_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


REF = _reference_module()
COMMANDS = REF.subcommands(build_parser())


def _flags(command: str) -> set[str]:
    return {o for a in COMMANDS[command]._actions for o in a.option_strings}


def test_pages_found():
    assert len(PAGES) >= 20, PAGES


def _scenario_names(text: str) -> set[str]:
    names = set(re.findall(r"chiptwin (?:run|validate|ladder|dsp-report|characterize) "
                           r"([a-z0-9_]+)\b(?![./])", text))
    names |= set(re.findall(r"ct\.(?:run|load_scenario|characterize)\(\"([A-Za-z0-9_]+)\"", text))
    names |= set(re.findall(r"^\| `([a-z0-9_]+)` \|", text, flags=re.M)) & _catalogue_rows(text)
    return names


def _catalogue_rows(text: str) -> set[str]:
    """First-column names of a table whose header is ``| scenario |``."""
    rows, inside = set(), False
    for line in text.splitlines():
        if line.startswith("| scenario |"):
            inside = True
        elif inside and line.startswith("| `"):
            rows.add(line.split("`")[1])
        elif inside and not line.startswith("|"):
            inside = False
    return rows


@pytest.mark.parametrize("path", list(TEXTS), ids=lambda p: str(p.relative_to(ROOT)))
def test_named_scenarios_and_studies_exist(path):
    text = TEXTS[path]
    scenarios = set(bundled_scenarios())
    studies = set(bundled_studies())
    #: names the how-to pages invent for the reader's own files
    examples = {"my_scene", "my_study"}
    missing = {n for n in _scenario_names(text) - examples if n not in scenarios}
    # `chiptwin validate` takes a study too
    missing -= set(re.findall(r"chiptwin validate ([a-z0-9_]+)\b(?![./])", text)) & studies
    named_studies = set(re.findall(r"chiptwin study ([a-z0-9_]+)\b(?![./])", text))
    named_studies |= set(re.findall(r"run_study\(\"([A-Za-z0-9_]+)\"", text))
    named_studies |= set(re.findall(r"study `([a-z0-9_]+)`", text))
    missing |= {n for n in named_studies - examples if n not in studies}
    assert not missing, f"{path}: not bundled: {sorted(missing)}"


def test_catalogue_lists_every_bundled_scenario():
    readme = TEXTS[ROOT / "README.md"]
    assert _catalogue_rows(readme) == set(bundled_scenarios())


_COMMAND_LINE = re.compile(r"chiptwin (run|validate|list|dsp-report|characterize|ladder|study)"
                           r"((?: +[^\s`#|]+)*)")


@pytest.mark.parametrize("path", list(TEXTS), ids=lambda p: str(p.relative_to(ROOT)))
def test_flags_written_in_docs_exist(path):
    bad = []
    for line in TEXTS[path].splitlines():
        for m in _COMMAND_LINE.finditer(line):
            for flag in re.findall(r"(?<![\w-])(--[a-z][a-z-]*)", m.group(2)):
                if flag not in _flags(m.group(1)):
                    bad.append(f"chiptwin {m.group(1)} {flag}")
    assert not bad, f"{path}: flags the CLI does not have: {bad}"


def test_generated_cli_reference_matches_help():
    """Every flag in the generated reference is in ``chiptwin <command> --help``, and every
    command has its section."""
    text = REF.cli_markdown()
    for command, parser in COMMANDS.items():
        section = text.split(f"## `chiptwin {command}`", 1)[1].split("\n## ", 1)[0]
        listed = set(re.findall(r"^`(--[a-z][a-z-]*)[ `]", section, flags=re.M))
        helped = set(re.findall(r"(--[a-z][a-z-]*)", parser.format_help()))
        assert listed <= helped, (command, listed - helped)
        assert listed == _flags(command) - {"-h", "--help"}, (command, listed)


def test_generated_scenario_reference_lists_every_key():
    text = REF.scenario_markdown()
    for key in REF.scenario_keys():
        section, name = key.rsplit(".", 1)
        block = text.split(f"## `[{section}]`", 1)[1].split("\n## ", 1)[0]
        assert f"\n`{name}`\n: " in block, key


def test_generated_study_reference_lists_every_key():
    from chiptwin.study.metrics import CATALOGUE
    from chiptwin.study.spec import AXIS_KEYS, STUDY_KEYS
    from chiptwin.study.spec_sensitivity import ASSUMPTION_KEYS

    text = REF.study_markdown()
    assumption = text.split("## `[[study.assumption]]`", 1)[1].split("\n## ", 1)[0]
    for key in ASSUMPTION_KEYS:
        assert f"\n`{key}`\n: " in assumption, key
    for key in [*STUDY_KEYS, *AXIS_KEYS, *CATALOGUE]:
        assert f"\n`{key}`\n: " in text, key


_LINK = re.compile(r"\]\(([^)\s]+)\)")


@pytest.mark.parametrize("path", list(TEXTS), ids=lambda p: str(p.relative_to(ROOT)))
def test_local_links_resolve(path):
    broken = []
    for target in _LINK.findall(TEXTS[path]):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        file = target.split("#", 1)[0]
        if "generated/" in file:  # written at build time: check the page it is made from
            assert Path(file).name in REF.PAGES, target
            continue
        if not (path.parent / file).exists():
            broken.append(target)
    assert not broken, f"{path}: broken links {broken}"


def test_generated_reference_reads_as_a_person_would_type_it():
    """No raw machine bounds (2^63 − 1, 1.67772e+07), every flag as code (so a copied command
    keeps its two hyphens), ``<...>`` escaped so Markdown does not read it as a tag, and an
    example file at the top of the two file references."""
    cli, scenario, study = REF.cli_markdown(), REF.scenario_markdown(), REF.study_markdown()
    for text in (cli, scenario, study):
        assert "9223372036854775807" not in text and "e+" not in text
        assert not re.search(r"(?<!\\)<[a-z]", text.split("-->", 1)[1]), "an unescaped tag"
    assert "`--set KEY=VALUE`" in cli and "`--out OUT`" in cli
    assert "≥ 0" in scenario and "−2^24 … 2^24" in scenario
    assert scenario.index("```toml") < scenario.index("## `[scenario]`")
    assert study.index("```toml") < study.index("## `[study]`")
    assert REF._num(16777216) == "2^24" and REF._num(1e-9) == "1e-9" and REF._num(4096) == "4,096"
