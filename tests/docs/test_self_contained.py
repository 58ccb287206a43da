"""The repository stands on its own: nothing a user gets cites a file, tracker or machine they
do not have.

Users get the repository only. A citation of a private reference file ("REFERENCE §2",
"REFERENCE.md"), of a private tracker ("issue 18"), of the project's own planning files
("../shared", "SPEC.md", "STYLE.md", "SPEC", "STYLE 7") or of an absolute machine path
("/work/...", "/home/...") points at nothing for them. Numbers cite the original paper, standard
or datasheet, or a row of ``docs/background/sources.md``; engineering decisions state their
reason. This module scans every tracked text file of the package, docs, scenarios, benchmarks,
README, RTL, scripts, tests and CI and lists each offending ``file:line``; it also checks that
every citation of a sources.md row, section or anchor names one that exists.

Runs in the normal suite (it reads files only; well under a second).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ROOT / "docs" / "background" / "sources.md"
#: What users get, as paths relative to the repository's root.
SCANNED = ("chiptwin", "docs", "scenarios", "benchmarks", "README.md", "rtl_ref", "scripts",
           "tests", ".ci")
#: Build output and generated pages: not written by hand (generated pages are fixed at their
#: source, which is scanned).
SKIPPED_DIRS = {"build", "_build", "__pycache__", "generated", ".ipynb_checkpoints"}
THIS_FILE = Path(__file__).resolve().relative_to(ROOT).as_posix()

#: One pattern per kind of citation users cannot follow.
FORBIDDEN = {
    "private reference file": re.compile(r"REFERENCE\s*§|REFERENCE\.md|\[REF\b"),
    "tracker issue number": re.compile(r"\b[Ii]ssues?\s+#?\d+"),
    "planning files": re.compile(r"\.\./shared|\bSPEC\.md|\bSTYLE\.md|\bSPEC\b|\bSTYLE\s+\d"),
    "absolute machine path": re.compile(r"(?<![\w.~-])/(?:work|home)/"),
}


def offences(text: str) -> list[tuple[int, str, str]]:
    """``(line number, kind, matched text)`` of every forbidden citation in ``text``."""
    found = []
    for n, line in enumerate(text.splitlines(), start=1):
        for kind, pattern in FORBIDDEN.items():
            found += [(n, kind, m.group(0)) for m in pattern.finditer(line)]
    return found


def _tracked_files() -> list[str]:
    """The scanned files, as git tracks them; a plain walk when git or the repository is absent
    (an unpacked source archive)."""
    if shutil.which("git") and (ROOT / ".git").exists():
        out = subprocess.run(["git", "ls-files", "-z", "--", *SCANNED], cwd=ROOT,
                             capture_output=True, check=True).stdout.decode()
        files = [f for f in out.split("\0") if f]
    else:
        files = []
        for top in SCANNED:
            path = ROOT / top
            candidates = [path] if path.is_file() else path.rglob("*")
            files += [p.relative_to(ROOT).as_posix() for p in candidates if p.is_file()]
    return [f for f in files
            if f != THIS_FILE and not SKIPPED_DIRS.intersection(Path(f).parts[:-1])]


def _text(rel: str) -> str | None:
    """The file's text, or None for a binary file (figures, data)."""
    try:
        return (ROOT / rel).read_text(encoding="utf-8")
    except (UnicodeDecodeError, FileNotFoundError):
        return None


# --- the matcher itself -------------------------------------------------------------------------

@pytest.mark.parametrize("planted", [
    "indices (REFERENCE §2): water 1.33",
    "see REFERENCE.md for the rows",
    "a Km [REF §1] from the table",
    "workers never outlive the study (issue 22)",
    "Issue 11, part 2: every key",
    "as issues #4 and 5 said",
    "read ../shared/SPEC.md first",
    "levels (SPEC \"optics\")",
    "equivalence tests (STYLE 7)",
    "python -m venv /work/venvs/pyxel",
    "cache in /home/someone/.cache",
])
def test_matcher_finds_each_kind(planted):
    """Every kind of citation users cannot follow is caught, on a planted line."""
    assert offences("first line\n" + planted) and offences("x\n" + planted)[0][0] == 2


@pytest.mark.parametrize("clean", [
    "Born & Wolf, Sec. 1.5; Casella & Berger, §5.5.4",      # a book's own section sign
    "MAX_REFERENCE_S = 300.0; CHEAP_REFERENCE = {}",         # identifiers
    "SPECS = {'ideal': None}",
    "the issue's crashes, one by one",
    "python -m venv ~/venvs/pyxel; ls ./work/x; /tmp/vcd",
    "Salama et al. 2004, eq. 19; docs/background/sources.md K8",
])
def test_matcher_passes_original_sources(clean):
    """Original sources, identifiers and relative or temporary paths are not flagged."""
    assert offences(clean) == []


# --- the repository ------------------------------------------------------------------------------

def test_no_citation_users_cannot_follow():
    """No tracked text file cites the private reference file, a tracker issue, the planning
    files or an absolute machine path: each hit is listed as ``file:line: kind: text``."""
    files = _tracked_files()
    assert any(f.startswith("chiptwin/") for f in files) and "README.md" in files
    hits = [f"{rel}:{n}: {kind}: {match!r}"
            for rel in files if (text := _text(rel)) is not None
            for n, kind, match in offences(text)]
    assert not hits, "citations users cannot follow:\n" + "\n".join(hits)


# --- sources.md: every cited row, section and anchor exists -----------------------------------

def _slug(heading: str) -> str:
    """MyST's heading anchor (``myst_heading_anchors``): lower case, punctuation dropped,
    spaces to hyphens."""
    return re.sub(r"\s+", "-", re.sub(r"[^\w\s-]", "", heading.strip().lower()))


def _sources_index() -> tuple[set[str], dict[str, str]]:
    """Row ids (``K8``) and section headings by anchor (``the-reference-chip``) of sources.md."""
    text = SOURCES.read_text(encoding="utf-8")
    rows = set(re.findall(r"^\| ([A-Z]\d+) \|", text, flags=re.M))
    headings = {_slug(h): h for h in re.findall(r"^#{1,3} (.+)$", text, flags=re.M)}
    return rows, headings


ROW_CITE = re.compile(r"sources\.md[,)]?\s+(?:\(?([A-Z][A-Za-z ]+?)\)?,?\s+)?"
                      r"([A-Z]\d+)(?:[–-]([A-Z]\d+))?\b")
SECTION_CITE = re.compile(r"sources\.md,?\s+\(?((?:[A-Z][a-z]+|ADC|EMVA)(?: [A-Za-z0-9]+)*)")
ANCHOR_CITE = re.compile(r"sources\.md#([\w-]+)")


def test_sources_page_has_rows_and_sections():
    """sources.md exists, is in the background toctree, and has the topics the brief names."""
    rows, headings = _sources_index()
    assert {"K8", "O3", "C2", "P5", "F4", "A2", "E7", "D1", "R1"} <= rows
    assert {"kinetics", "optics", "the-reference-chip", "pixel-and-noise", "fixed-point",
            "validation-anchors", "emva-1288", "adc-test-and-cost", "sequencing-reads",
            "references"} <= set(headings)
    toctree = (ROOT / "docs" / "background" / "index.md").read_text(encoding="utf-8")
    assert re.search(r"^sources$", toctree, flags=re.M)


def test_every_sources_citation_exists():
    """Each ``sources.md K8`` / ``sources.md O2–O4`` row, ``sources.md, Kinetics`` section and
    ``sources.md#optics`` anchor cited anywhere in the repository names one that sources.md has."""
    rows, headings = _sources_index()
    titles = {h.lower() for h in headings.values()}
    missing, cited = [], 0
    for rel in _tracked_files():
        text = _text(rel)
        if text is None or "sources.md" not in text:
            continue
        for n, line in enumerate(text.splitlines(), start=1):
            for m in ROW_CITE.finditer(line):
                cited += 1
                missing += [f"{rel}:{n}: row {r}" for r in m.group(2, 3) if r and r not in rows]
            for m in SECTION_CITE.finditer(line):
                words = m.group(1).split()
                # the longest leading run of words that is a section title, if any starts one
                if any(w.istitle() or w.isupper() for w in words[:1]):
                    prefixes = [" ".join(words[:k]).lower() for k in range(len(words), 0, -1)]
                    if not any(p in titles for p in prefixes) and not re.fullmatch(
                            r"[A-Z]\d+", words[0]):
                        missing.append(f"{rel}:{n}: section {m.group(1)!r}")
            for m in ANCHOR_CITE.finditer(line):
                cited += 1
                if m.group(1) not in headings:
                    missing.append(f"{rel}:{n}: anchor #{m.group(1)}")
    assert cited > 20, "the code and docs cite sources.md rows: the matcher found too few"
    assert not missing, "sources.md has no such row/section/anchor:\n" + "\n".join(missing)
