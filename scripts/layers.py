"""The layers of chiptwin, read from its own imports: checked, and drawn (docs/architecture.md).

    python scripts/layers.py            # print each package's layer and its arrows; exit 1 on
                                        # an arrow that runs up or sideways, or an import circle
    python scripts/layers.py --draw docs/layers.png

Every import counts: at the top of a module, inside a function, under ``TYPE_CHECKING``. A
package (or a flat module) may import from its own package and from the layers below its own;
``tests/test_layers.py`` runs :func:`violations` and :func:`circles`, so the map cannot drift.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The layers, bottom to top, and the rooms (packages or flat modules) on each.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("foundations", ("constants", "_numba", "_checks", "limits")),
    ("stage kernels", ("kinetics", "optics", "pixel", "dsp", "detection")),
    ("stages over stages", ("photons", "chip", "rtl_ref")),
    ("files", ("config",)),
    ("twin", ("twin",)),
    ("tools", ("fidelity", "report", "characterize", "study")),
    ("command line", ("cli", "__main__")),
)
#: Rooms of one layer that may import another of the same layer (the arrow named).
SIDEWAYS: frozenset[tuple[str, str]] = frozenset({
    ("photons", "kinetics"),  # arrival times of a light source's rate
    ("detection", "kinetics"),  # the phase-correcting caller predicts flowgrams by phasing
    ("chip", "dsp"),  # the chip model runs the DSP program's stages
    ("study", "fidelity"),  # a study point's auto keys are resolved with calibrations
    ("study", "characterize"),  # a calibrate study's measured data set, replayed on the bench
    ("__main__", "cli"),
})


def room_of(module: str) -> str | None:
    """``chiptwin.twin.runner`` → ``twin``; ``chiptwin`` itself (the package's door) → None;
    ``rtl_ref.…`` → ``rtl_ref`` (the reference RTL's harness imports the DSP it verifies: a
    room of its own above the stage kernels)."""
    parts = module.split(".")
    if parts[0] == "rtl_ref":
        return "rtl_ref"
    return parts[1] if parts[0] == "chiptwin" and len(parts) > 1 else None


def layer_of(room: str) -> int:
    for i, (_, rooms) in enumerate(LAYERS):
        if room in rooms:
            return i
    raise KeyError(f"{room!r} is on no layer: add it to scripts/layers.py LAYERS")


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Every module of the package, and of ``rtl_ref``, by dotted name."""
    out = {}
    paths = [*(root / "chiptwin").rglob("*.py"), *(root / "rtl_ref").glob("*.py")]
    for path in sorted(paths):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The chiptwin modules ``name`` imports (``from pkg import mod`` counts as ``pkg.mod``)."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.add(sub if sub in known else base)
    return {m for m in found if m.split(".")[0] in ("chiptwin", "rtl_ref") and m != name}


def graph(root: Path = ROOT) -> dict[str, set[str]]:
    mods = modules(root)
    return {name: imports(name, path, set(mods)) for name, path in mods.items()}


def violations(g: dict[str, set[str]] | None = None) -> list[str]:
    """Arrows that run up a layer, or sideways without being named in :data:`SIDEWAYS`."""
    bad = []
    for src, targets in sorted((g or graph()).items()):
        a = room_of(src)
        for dst in sorted(targets):
            b = room_of(dst)
            if a is None or b is None or a == b:
                continue  # the package's door (lazy API), or inside one room
            la, lb = layer_of(a), layer_of(b)
            if lb > la or (lb == la and (a, b) not in SIDEWAYS):
                bad.append(f"{src} -> {dst}: {LAYERS[la][0]} may not import {LAYERS[lb][0]}")
    return bad


def circles(g: dict[str, set[str]] | None = None) -> list[list[str]]:
    """Import circles between modules (Tarjan's strongly connected components of size > 1)."""
    g = g or graph()
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def room_arrows(g: dict[str, set[str]]) -> dict[str, set[str]]:
    arrows: dict[str, set[str]] = defaultdict(set)
    for src, targets in g.items():
        for dst in targets:
            a, b = room_of(src), room_of(dst)
            if a and b and a != b:
                arrows[a].add(b)
    return arrows


def draw(path: Path, g: dict[str, set[str]]) -> None:
    """The layers as bands, the rooms as boxes sized by their lines, the arrows between rooms."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mods = modules()
    lines: dict[str, int] = defaultdict(int)
    for name, p in mods.items():
        if room_of(name):
            lines[room_of(name)] += len(p.read_text(encoding="utf-8").splitlines())
    fig, ax = plt.subplots(figsize=(11, 7.5))
    pos = {}
    for i, (label, rooms) in enumerate(LAYERS):
        ax.axhspan(i - 0.45, i + 0.45, color="0.94" if i % 2 else "0.88", zorder=0)
        ax.text(-0.35, i, label, ha="right", va="center", fontsize=9, color="0.25")
        for j, room in enumerate(rooms):
            x = (j + 0.5) * 5.0 / len(rooms)
            pos[room] = (x, i)
            ax.text(x, i, f"{room}\n{lines.get(room, 0):,} lines", ha="center", va="center",
                    fontsize=9, zorder=3,
                    bbox={"boxstyle": "round", "fc": "white", "ec": "0.3"})
    for a, targets in room_arrows(g).items():
        for b in targets:
            (x0, y0), (x1, y1) = pos[a], pos[b]
            ax.annotate("", xy=(x1, y1 + 0.22), xytext=(x0, y0 - 0.22), zorder=2,
                        arrowprops={"arrowstyle": "->", "color": "tab:blue", "alpha": 0.35,
                                    "shrinkA": 4, "shrinkB": 4})
    ax.set_xlim(-2.2, 5.2)
    ax.set_ylim(-0.6, len(LAYERS) - 0.4)
    ax.axis("off")
    ax.set_title("chiptwin's layers, drawn from its imports: every arrow points down "
                 "(scripts/layers.py)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draw", metavar="PNG", help="draw the layers into this file")
    args = p.parse_args(argv)
    g = graph()
    for i, (label, rooms) in reversed(list(enumerate(LAYERS))):
        arrows = room_arrows(g)
        print(f"{i + 1}  {label:20s} " + "; ".join(
            f"{r} -> {', '.join(sorted(arrows.get(r, ()))) or '-'}" for r in rooms))
    bad, loops = violations(g), circles(g)
    for line in bad:
        print("arrow up or sideways:", line)
    for loop in loops:
        print("circle:", " -> ".join(loop))
    if args.draw:
        draw(Path(args.draw), g)
        print(f"drew {args.draw}")
    return 1 if bad or loops else 0


if __name__ == "__main__":
    sys.exit(main())
