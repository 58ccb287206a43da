"""The runs behind the documentation's figures, executed when the pages are built.

Every bundled scenario runs here with the ``--set`` keys below (the same physics; fewer flows or
pixels where the full scene takes longer than a few seconds), and every bundled study as a tiny
version of itself (2 replicates, 8 flows, fewer points): the figure is the one the twin writes
for the full command, from a shorter run. The pages say which keys each figure was made with.

Used by docs/gallery.md, docs/index.md and the tutorials (their kernels find this folder on
``PYTHONPATH``: docs/conf.py).
"""

from __future__ import annotations

import functools
import tempfile
import tomllib
from pathlib import Path

#: ``--set`` keys per scenario for the gallery's run (none: the full bundled scenario).
SHORTER: dict[str, list[str]] = {
    "pyro_1fmol": ["assay.n_flows=8", "run.duration_s=500.0"],
    "ccd_100fmol": ["assay.n_flows=8", "run.duration_s=496.0"],
    "pyro_array_256": ["assay.n_flows=8", "run.duration_s=500.0", "chip.rows=16", "chip.cols=16",
                       "sites.at_pixels=[" + ", ".join(f"[{r}, {c}]" for r in (1, 5, 9, 13)
                                                       for c in (1, 5, 9, 13)) + "]"],
    "pyro_paper_yield": ["assay.n_flows=8", "run.duration_s=500.0"],
    "pyro_paper_yield_fast": ["assay.n_flows=8", "assay.flow_period_s=4.0",
                              "run.duration_s=34.0"],
    "pyro_long_read": ["assay.n_flows=32", "run.duration_s=1940.0"],
    "pyro_454_flx": ["assay.n_flows=32", "run.duration_s=1940.0"],
}

#: ``set`` keys of the tiny studies: the first 8 flows of pyro_1fmol (the key's four 1-mers,
#: from which a site's SNR is read).
KEY_FLOWS = {"assay.n_flows": 8, "run.duration_s": 500.0}

ROOT = Path(tempfile.mkdtemp(prefix="chiptwin-docs-"))


@functools.cache
def scenario_outputs(name: str) -> Path:
    """The output folder of the bundled scenario ``name`` run with :data:`SHORTER`'s keys."""
    import chiptwin as ct
    from chiptwin.report import write_outputs

    result = ct.run(name, SHORTER.get(name, []), seed=1)
    return write_outputs(result, ROOT / name)


def command(name: str) -> str:
    """The shell command that makes the figure (with the shortening keys, if any)."""
    return shell(f"chiptwin run {name}", *[f"--set {k}" if " " not in k else f"--set '{k}'"
                                            for k in SHORTER.get(name, [])])


def shell(*words: str, width: int = 76) -> str:
    """A command line as one would type it in a page's code block: continued with a
    backslash where it would pass ``width`` columns."""
    lines = [words[0]]
    for word in words[1:]:
        if len(lines[-1]) + 1 + len(word) > width - 2:
            lines[-1] += " \\"
            lines.append("    " + word)
        else:
            lines[-1] += " " + word
    return "\n".join(lines)


def show(name: str, figure: str, width: int = 640):
    """The figure ``figure`` (a PNG the run writes) of scenario ``name``, for a page."""
    from IPython.display import Image

    return Image(filename=str(scenario_outputs(name) / figure), width=width)


def _tiny(name: str, edit) -> object:
    from chiptwin.config.catalog import bundled_studies, resolve_scenario
    from chiptwin.study.spec import study_from_dict

    path = bundled_studies()[name]
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    edit(raw["study"])
    return study_from_dict(raw, str(path), None, path.parent, resolve_scenario)


def _adc_bits(st: dict) -> None:
    st.update(replicates=2)
    st.setdefault("set", {}).update(KEY_FLOWS)
    st["axis"] = [{"key": "chip.adc.bits", "values": [10, 11, 12, 13, 14, 15, 16]}]
    st["metric"] = [{"name": "snr_loss_db"}, {"name": "adc_power_w"}]
    st["requirement"] = {"snr_loss_db": "<= 0.5", "confidence": 0.95}


def _frame_memory(st: dict) -> None:
    st.update(replicates=2)
    st.setdefault("set", {}).update(KEY_FLOWS)


def _lod(st: dict) -> None:
    st.update(replicates=4, search="grid")
    st.pop("batch", None)
    st["axis"][0]["n"] = 5


def _read_length(st: dict) -> None:
    st.update(replicates=1, vary_chip=False)
    st.setdefault("set", {}).update({"assay.n_flows": 24, "run.duration_s": 1460.0})
    st["axis"] = [{"key": "assay.dna_fmol", "values": [0.003, 0.03, 0.3]}]
    st["metric"] = [{"name": "q20_read_length"}, {"name": "read_accuracy"}]
    st["requirement"] = {"q20_read_length": ">= 10", "confidence": 0.95}


#: How each study is shrunk, and why where the reason is not in the keys themselves. What the
#: tiny study runs is said by :func:`tiny_changes`, from the study objects: a caption cannot
#: name a value the run does not use.
TINY = {
    "adc_bits_pyro": (_adc_bits, ""),
    "frame_memory": (_frame_memory, ""),
    "lod_pyro": (_lod, ""),
    "read_length_pyro": (_read_length, "24 flows read at most about half as many bases, so the "
                         "requirement is lowered with them"),
}


def full_study(name: str):
    """The bundled study ``name`` as its file gives it."""
    from chiptwin.config.catalog import bundled_studies, resolve_scenario
    from chiptwin.study import load_study

    return load_study(bundled_studies()[name], resolve_scenario)


def tiny_study(name: str):
    """The tiny version of the bundled study ``name`` (:data:`TINY`)."""
    return _tiny(name, TINY[name][0])


def tiny_changes(name: str) -> str:
    """What the tiny version of study ``name`` runs, against the full study, read from both
    study objects and the tiny study's scene: its axes, the value of each key the full study
    varies and the tiny one does not (the scene's own), and every other difference."""
    from chiptwin.study.spec import point_scenario

    full, tiny = full_study(name), tiny_study(name)
    scene = point_scenario(tiny, {}, tiny.seed, None)
    kept = {a.key for a in tiny.axes}
    parts = [f"{a.key} {_values(a.values)}" + (" (a condition)" if a.given else "")
             for a in tiny.axes]
    parts += [f"{k} = {_value_of(scene, k)} (the scene's; the full study varies it)"
              for k in dict.fromkeys(a.key for a in full.axes) if k not in kept]
    if tiny.replicates != full.replicates:
        parts.append(f"{tiny.replicates} replicate{'s' * (tiny.replicates > 1)} a point instead "
                     f"of {full.replicates}")
    if tiny.vary_chip != full.vary_chip:
        parts.append("one chip for every replicate" if not tiny.vary_chip else
                     "another chip every replicate")
    parts += [f"{k} = {v}" for k, v in tiny.overrides.items() if full.overrides.get(k) != v]
    if tiny.search != full.search:
        parts.append(f"search {tiny.search} instead of {full.search}")
    if tiny.metrics != full.metrics:
        parts.append("metrics " + ", ".join(tiny.metrics))
    if tiny.requirements != full.requirements:
        parts.append("requirement " + " and ".join(map(str, tiny.requirements)))
    return "; ".join(parts) or "the full study"


def full_runs(name: str) -> int:
    """The runs of the full study ``name``: every point and reference point × replicates (a
    bisection's cap)."""
    from chiptwin.study.engine import Plan

    plan = Plan(full_study(name))
    return (len(plan.points) + len(plan.references)) * plan.study.replicates


def _values(values: tuple) -> str:
    ints = all(type(v) is int for v in values)
    if ints and len(values) > 2 and list(values) == list(range(values[0], values[-1] + 1)):
        return f"{values[0]} … {values[-1]}"
    return ", ".join(map(str, values))


def _value_of(scene, key: str):
    value = scene
    for part in key.split("."):
        value = getattr(value, part)
    return value


@functools.cache
def study_outputs(name: str) -> Path:
    """The output folder of the tiny version of the bundled study ``name``."""
    from chiptwin.study import run_study
    from chiptwin.study.outputs import write_study_outputs

    out = ROOT / f"study-{name}"
    out.mkdir(parents=True, exist_ok=True)
    result = run_study(tiny_study(name), workers=1, db=out / "results.sqlite")
    write_study_outputs(result, out)
    return out


def study_command(name: str) -> str:
    """The command of the full study (its runs), and a comment saying what the figure's tiny
    run ran (:func:`tiny_changes`) and why, where :data:`TINY` gives a reason."""
    import textwrap

    why = TINY[name][1]
    most = "at most " if full_study(name).search != "grid" else ""
    return f"chiptwin study {name}    # {most}{full_runs(name):,} runs\n" + textwrap.fill(
        f"the figure: a tiny version: {tiny_changes(name)}" + (f" ({why})" if why else ""),
        76, initial_indent="# ", subsequent_indent="# ")


def show_study(name: str, figure: str, width: int = 640):
    """A figure of the tiny version of study ``name``."""
    from IPython.display import Image

    return Image(filename=str(study_outputs(name) / figure), width=width)


def study_figures(name: str) -> list[str]:
    """The PNG files the tiny study wrote."""
    return sorted(p.name for p in study_outputs(name).glob("*.png"))


#: The signal chain as the package docstring draws it: stage, what leaves it.
CHAIN = [("assay\nkinetics", "photons/s\nper site"), ("optics", "photons/s\nper pixel"),
         ("pixel", "e⁻"), ("ADC", "codes"), ("frame\nmemory", "frames"), ("DSP", "results"),
         ("detection", "SNR,\ncalls")]


def signal_chain(name: str = "pyro_1fmol", width: int = 760):
    """The landing page's picture: the chip's signal chain, and the pyrogram it gives for
    ``name`` (the gallery's run of it)."""
    import io

    import matplotlib
    from IPython.display import Image

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from chiptwin import open_run

    with open_run(scenario_outputs(name)) as ds:
        flows = ds["flow_values"].values[0]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 4.6), height_ratios=[1, 1.5])
    top.set(xlim=(0, len(CHAIN)), ylim=(0, 1)), top.axis("off")
    for i, (stage, leaves) in enumerate(CHAIN):
        top.text(i + 0.4, 0.62, stage, ha="center", va="center", fontsize=10,
                 bbox={"boxstyle": "round", "fc": "#e8f0fb", "ec": "#3060a0"})
        top.text(i + 0.4, 0.12, leaves, ha="center", va="center", fontsize=8, color="#444")
        if i < len(CHAIN) - 1:
            top.annotate("", (i + 1.05, 0.62), (i + 0.78, 0.62),
                         arrowprops={"arrowstyle": "->", "color": "#3060a0"})
    top.set_title("The chip the twin models, stage by stage (what each stage hands on below)",
                  fontsize=10)
    nucleotides = "TACG" * (len(flows) // 4 + 1)
    bottom.bar(range(len(flows)), flows, color="tab:green")
    bottom.set_xticks(range(len(flows)), list(nucleotides[:len(flows)]))
    for n in range(1, int(flows.max() + 1.5)):
        bottom.axhline(n, color="grey", lw=0.5, ls=":")
    bottom.set(ylabel="bases incorporated", title=f"What comes out: the pyrogram of {name} "
               "(site 0, first 8 flows)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return Image(data=buf.getvalue(), width=width)


def cli_output(*argv: str) -> str:
    """What ``chiptwin ARGV`` prints, run in a fresh folder (so its output path is short)."""
    import contextlib
    import io
    import os

    from chiptwin.cli import main

    here, buf = os.getcwd(), io.StringIO()
    os.chdir(tempfile.mkdtemp())
    os.environ["COLUMNS"] = "76"  # the width of a page's code block
    try:
        with contextlib.redirect_stdout(buf):
            code = main(list(argv))
    finally:
        os.chdir(here)
    assert code == 0, code
    return buf.getvalue()
