"""What the ``chiptwin`` command prints besides the numbers: its help texts and examples, the
table layout of a terminal, close names for a mistyped one, and the grouped
summary of a study's inconsistent points. Plain functions of strings, no I/O, so each is tested
on its own (tests/test_cli.py).
"""

from __future__ import annotations

import difflib
import re
import textwrap
from collections.abc import Iterable, Mapping

#: Columns every line the CLI prints fits in (a laptop's terminal; a pasted log stays readable);
#: a narrower terminal (or ``COLUMNS``) narrows the tables (:func:`columns`).
WIDTH = 100


def columns() -> int:
    """The width tables wrap to: the terminal's (``COLUMNS`` when set), at most :data:`WIDTH`,
    at least 60."""
    import shutil

    return max(60, min(WIDTH, shutil.get_terminal_size((WIDTH, 24)).columns))
#: The label column of the terminal table: two spaces, 28 characters, one space.
LABEL = 28

SEE_ALSO = ("`chiptwin list` names every bundled scenario and study; `chiptwin COMMAND --help` "
            "shows each command's examples. The documentation (Getting started, a gallery, "
            "how-tos, the command reference) is in docs/ of the source; bash scripts/docs.sh "
            "builds it.")

#: Two or three example command lines per command: (command line, what it does).
EXAMPLES: dict[str, list[tuple[str, str]]] = {
    "chiptwin": [
        ("chiptwin list", "the bundled scenarios and studies"),
        ("chiptwin run pyro_1fmol", "1 fmol pyrosequencing on the reference chip"),
        ("chiptwin run pyro_1fmol --set chip.adc.bits=10", "the same with a 10-bit ADC"),
        ("chiptwin study adc_bits_pyro", "the fewest ADC bits for the assay, with statistics"),
    ],
    "run": [
        ("chiptwin run pyro_1fmol", "run a bundled scenario; outputs in out/pyro_1fmol/"),
        ("chiptwin run pyro_1fmol --set chip.adc.bits=10 --out out/bits10",
         "change one key, write elsewhere"),
        ("chiptwin run my_chip.toml --seed 7", "your own file, another seed"),
    ],
    "validate": [
        ("chiptwin validate pyro_1fmol", "check a scenario and estimate its wall time"),
        ("chiptwin validate my_chip.toml --set chip.adc.bits=15",
         "check an override before a long run"),
        ("chiptwin validate frame_memory", "a study: its points, the inconsistent ones, its time"),
    ],
    "list": [("chiptwin list", "every bundled scenario and study with one sentence each")],
    "dsp-report": [
        ("chiptwin dsp-report pyro_1fmol", "fixed-point DSP against float: error in LSB, SQNR"),
        ("chiptwin dsp-report pyro_1fmol --json dsp.json", "the same, also as JSON"),
    ],
    "characterize": [
        ("chiptwin characterize pyro_1fmol", "the chip's EMVA 1288 datasheet (photon transfer)"),
        ("chiptwin characterize --from my_sensor.json", "a twin configured from a datasheet"),
        ("chiptwin characterize pyro_1fmol --adc", "the ADC's IEEE 1241 bench: DNL, INL, ENOB"),
        ("chiptwin characterize --measured my_camera/", "a camera's EMVA 1288 data set, evaluated"),
        ("chiptwin characterize --measured my_camera/ --pixel-pitch-um 7.4 --write-scenario "
         "cam.toml", "and its twin, read through the same protocol"),
    ],
    "reads": [
        ("chiptwin reads call run.sff", "call a 454 run's reads; agreement with the instrument's"),
        ("chiptwin reads call ion.bam --caller dephase",
         "an aligned Ion BAM: errors against the reference, twin and instrument"),
        ("chiptwin reads call run.sff --truth templates.fasta", "against known templates"),
    ],
    "ladder": [
        ("chiptwin ladder pyro_1fmol", "every fidelity level's time and error"),
        ("chiptwin ladder pyro_1fmol --replicates 3 --reference dsp=fixed",
         "fewer seeds, a fixed-point reference"),
    ],
    "study": [
        ("chiptwin study adc_bits_pyro", "fewest ADC bits for the assay; resumes if interrupted"),
        ("chiptwin study adc_bits_pyro --set chip.adc.comparator_noise_uV=45 --given "
         "chip.pixel.qe=0.3,0.6", "re-asked for your comparator, one answer per DNA amount "
         "and QE"),
        ("chiptwin study adc_bits_pyro --quick", "a first look: 10 replicates, 4 bit depths"),
        ("chiptwin study frame_memory --workers 2", "two local processes"),
        ("chiptwin study lod_pyro --scheduler tcp://head:8786", "on a Dask cluster"),
        ("chiptwin study lod_pyro --scheduler-file ~/sched.json",
         "on an HPC cluster's Dask scheduler"),
    ],
}


def epilog(command: str) -> str:
    """The examples and pointers printed under a command's ``--help``, within :data:`WIDTH`."""
    rows = EXAMPLES[command]
    width = max([len(cmd) for cmd, _ in rows if len(cmd) <= 44] + [20]) + 2
    lines = ["examples:"]
    for cmd, what in rows:
        first = f"  {cmd:<{width}}"
        if len(cmd) >= width:  # a long command line: its explanation on the next line
            lines.append(f"  {cmd}")
            first = " " * (2 + width)
        lines.append(textwrap.fill(what, WIDTH, initial_indent=first,
                                   subsequent_indent=" " * (2 + width)))
    return "\n".join(lines) + "\n\n" + textwrap.fill(SEE_ALSO, WIDTH)


def paragraph(text: str) -> str:
    """A description wrapped to :data:`WIDTH` (argparse's raw formatter keeps it as given)."""
    return textwrap.fill(text, WIDTH)


def table(rows: Iterable[tuple[str, str]], width: int | None = None) -> str:
    """The terminal table: a label column and values wrapped under themselves, every line within
    ``width`` columns; a label longer than its column gets a line of its own."""
    width = width or columns()
    indent = " " * (2 + LABEL + 1)
    out = []
    for label, value in rows:
        first = f"  {label:<{LABEL}} "
        if len(label) > LABEL:
            out += textwrap.wrap(label, width, initial_indent="  ", subsequent_indent="    ")
            first = indent
        out += textwrap.wrap(str(value), width, initial_indent=first, subsequent_indent=indent,
                             break_on_hyphens=False) or [first.rstrip()]
    return "\n".join(out)


def fit(lines: Iterable[str], width: int | None = None) -> str:
    """Lines printed as they are when they fit, else wrapped under their own indent + 2."""
    width = width or columns()
    out = []
    for line in lines:
        if len(line) <= width:
            out.append(line)
            continue
        indent = " " * (len(line) - len(line.lstrip()))
        out += textwrap.wrap(line.strip(), width, initial_indent=indent,
                             subsequent_indent=indent + "  ",
                             break_on_hyphens=False)
    return "\n".join(out)


def closest(name: str, known: Iterable[str], n: int = 3) -> list[str]:
    """Known names close to a mistyped one (difflib's ratio ≥ 0.5), closest first; a known name
    that contains it, or is contained in it, counts as close."""
    known = list(known)
    stem = name.rsplit("/", 1)[-1].removesuffix(".toml")
    near = difflib.get_close_matches(stem, known, n=n, cutoff=0.5)
    near += [k for k in known if k not in near and len(stem) >= 3 and (stem in k or k in stem)]
    return near[:n]


def unknown_name(name: str, kind: str, known: Iterable[str]) -> str:
    """The refusal of a name that is neither a file nor a bundled ``kind`` (scenario, study)."""
    near = closest(name, known)
    hint = f"; did you mean {' or '.join(near)}?" if near else ""
    return (f"{name!r} is no file and no bundled {kind}{hint} (`chiptwin list` names them "
            "all)")


def first_sentences(comment: str, limit: int = 240) -> str:
    """The first sentence of a file's opening comment, and the next ones while within ``limit``
    characters: whole sentences, never cut inside one (nor inside a quotation or parentheses)."""
    text = " ".join(comment.split())
    sentences: list[str] = []
    for part in re.split(r"(?<=[.!?])\s+(?=[A-Z\"(])", text):
        if sentences and _open(sentences[-1]):  # the split fell inside "…" or (…): undo it
            sentences[-1] += " " + part
        else:
            sentences.append(part)
    out = sentences[0]
    for sentence in sentences[1:]:
        if len(out) + 1 + len(sentence) > limit:
            break
        out += " " + sentence
    return out


def _open(text: str) -> bool:
    return text.count("(") > text.count(")") or text.count('"') % 2 == 1


def opening_comment(source: str) -> str:
    """The first paragraph of a TOML file's opening ``#`` comment."""
    lines = []
    for line in source.splitlines():
        if not line.startswith("#"):
            break
        text = line.lstrip("#").strip()
        if not text:
            if lines:
                break
            continue
        lines.append(text)
    return " ".join(lines)


def listing(entries: Mapping[str, str], width: int | None = None) -> str:
    """``chiptwin list``'s lines: the name, then its description wrapped under itself."""
    width = width or columns()
    col = max([len(n) for n in entries] + [22]) + 2
    out = []
    for name, text in entries.items():
        out += textwrap.wrap(text, width, initial_indent=f"{name:<{col}}",
                             subsequent_indent=" " * col) or [name]
    return "\n".join(out)


_ERROR = re.compile(r": ([A-Za-z_][\w.]*) = (.*?): (.*)$", re.S)


def invalid_summary(messages: Iterable[str], width: int = WIDTH) -> list[str]:
    """A study's inconsistent points grouped by the key each refusal names: one line per key
    with how many points, the key and the first clause of its reason (the smallest and largest
    bound when the points differ in it), without the files' paths."""
    groups: dict[str, list[str]] = {}
    for message in messages:
        m = _ERROR.search(message)
        key, reason = (m.group(1), m.group(3)) if m else ("(other)", message)
        groups.setdefault(key, []).append(reason)
    lines = []
    for key, reasons in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        clause = _first_clause(reasons[0])
        others = {_first_clause(r) for r in reasons}
        if len(others) > 1:
            clause = _bounds(sorted(others, key=_number)) or clause + " (and others)"
        head = f"  {len(reasons):>4} × {key}: "
        lines.append(head + textwrap.shorten(clause, width - len(head), placeholder=" …"))
    return lines


def _first_clause(reason: str) -> str:
    return reason.split(": ", 1)[0].split("; ", 1)[0].rstrip(".,")


def _number(clause: str) -> float:
    m = re.search(r"[-+]?\d[\d.]*(?:e[-+]?\d+)?", clause)
    return float(m.group(0)) if m else 0.0


def _bounds(clauses: list[str]) -> str | None:
    """"must be ≥ 67584 bits" and "must be ≥ 264192 bits" → "must be ≥ 67584 … 264192 bits"."""
    pattern = [re.sub(r"[-+]?\d[\d.]*(?:e[-+]?\d+)?", "#", c) for c in clauses]
    if len(set(pattern)) != 1 or pattern[0].count("#") != 1:
        return None
    lo, hi = (re.search(r"[-+]?\d[\d.]*(?:e[-+]?\d+)?", c).group(0) for c in (clauses[0],
                                                                              clauses[-1]))
    return pattern[0].replace("#", f"{lo} … {hi}", 1) + " (by point)"
