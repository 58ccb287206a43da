"""Command line of the co-simulation: ``python -m rtl_ref COMMAND``.

    lint                      verilator --lint-only -Wall on every module and generated top
    cosim KIND [options]      co-simulate a block kind of the suite, print one line per config
    top KIND                  print the generated top (ct_top) of a kind's bank
    build KIND [--sim S]      build (or find) a bank and print the executable / .vvp path
    vectors KIND INDEX --out DIR [--beats N] [--seed S]
                              write config INDEX's input beats (beats.bin, beats.hex), the
                              model's expected output words (expected.txt) and the commands
                              that run them by hand (commands.txt)
    clean                     delete rtl_ref/build

KIND is one of background, average, cms, fir, kinetics. Exit 0 when everything agrees, 1 on a
mismatch or a lint warning, 2 when a simulator is missing (the message says how to install it).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

import numpy as np

from rtl_ref import build, sim, suite, vectors
from rtl_ref.tools import SimulatorMissing


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m rtl_ref", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("lint")
    c = sub.add_parser("cosim")
    c.add_argument("kind", choices=list(suite.KINDS))
    c.add_argument("--sim", default="verilator", choices=("verilator", "icarus"))
    c.add_argument("--vectors", type=int, default=None,
                   help=f"beats per kind (default {suite.VECTORS} on Verilator, "
                        f"{suite.ICARUS_VECTORS} per config on Icarus)")
    c.add_argument("--seed", type=int, default=2024)
    c.add_argument("--mutant", action="append", default=[],
                   help="a CT_MUTANT_* define (harness self-test)")
    c.add_argument("--vcd", type=Path, help="write one VCD per config into this directory")
    t = sub.add_parser("top")
    t.add_argument("kind", choices=list(suite.KINDS))
    b = sub.add_parser("build")
    b.add_argument("kind", choices=list(suite.KINDS))
    b.add_argument("--sim", default="verilator", choices=("verilator", "icarus"))
    b.add_argument("--trace", action="store_true")
    v = sub.add_parser("vectors")
    v.add_argument("kind", choices=list(suite.KINDS))
    v.add_argument("index", type=int)
    v.add_argument("--out", type=Path, required=True)
    v.add_argument("--beats", type=int, default=10_000)
    v.add_argument("--seed", type=int, default=2024)
    sub.add_parser("clean")
    return p


def _vectors(args: argparse.Namespace) -> int:
    bank = suite.bank(args.kind)
    blk = bank.blocks[args.index]
    inputs = vectors.for_block(blk, args.beats, np.random.default_rng(args.seed))
    beats = blk.beats(inputs)
    exp = blk.expected(inputs)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    beats.astype("<i8").tofile(out / "beats.bin")
    np.savetxt(out / "beats.hex", beats.view(np.uint64), fmt="%016x")
    words = np.stack([np.where(exp.cmp0, exp.d0, 0), np.where(exp.cmp1, exp.d1, 0)], axis=1)
    np.savetxt(out / "expected.txt", words.view(np.uint64), fmt="%016x")
    n, e, c = len(beats), len(exp.d0), len(blk.counter_names())
    cmds = [
        f"# {blk.label()} (config {args.index} of the {args.kind} bank): {n} beats in, {e} out",
        f"# counters, cnt_idx order: {', '.join(blk.counter_names())}",
        f"# model overflow counts: {exp.overflow}",
        "python -m rtl_ref top " + args.kind + " > ct_top.v",
        "verilator --cc --exe --build -j 2 --prefix Vct_top --top-module ct_top --Mdir obj "
        f"ct_top.v {build.RTL_DIR}/*.v {build.TB_DIR}/tb_verilator.cpp -o tb",
        f"./obj/tb --in beats.hex --n {n} --out out.txt --expect {e} --sel {args.index} "
        f"--ncnt {c} --p-valid 0.9 --p-ready 0.8",
        f"iverilog -g2005 -o sim.vvp -s tb_icarus {build.TB_DIR}/tb_icarus.v ct_top.v "
        f"{build.RTL_DIR}/*.v",
        f"vvp -n sim.vvp +in=beats.hex +n={n} +out=out.txt +expect={e} +sel={args.index} "
        f"+ncnt={c} +pvalid=58982 +pready=52429",
        "diff <(cut -d' ' -f1,2 out.txt) expected.txt && echo bit-exact",
    ]
    (out / "commands.txt").write_text("\n".join(cmds) + "\n")
    print("\n".join(cmds))
    return 0


def _cosim(args: argparse.Namespace) -> int:
    if args.vcd:
        os.environ[sim.VCD_ENV] = str(args.vcd)
    bank = suite.bank(args.kind, tuple(args.mutant))
    if args.sim == "verilator":
        reports = suite.run_kind(bank, "verilator", args.vectors or suite.VECTORS, args.seed)
    else:
        reports = suite.run_kind(bank, "icarus", 0, args.seed,
                                 n_each=args.vectors or suite.ICARUS_VECTORS)
    for i, r in enumerate(reports):
        print(f"[{i}] {r.text()}\n    corners {r.coverage}")
    bad = sum(not r.ok for r in reports)
    print(f"{args.kind}: {len(reports)} configs, {sum(r.n_beats for r in reports)} beats, "
          f"{bad} with mismatches")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.cmd == "lint":
            for module in [p.stem for p in build.rtl_sources()]:
                build.lint(top_module=module)
            for make in suite.KINDS.values():
                build.lint([b.instance() for b in make()])
            print("lint clean: every module and every suite top")
            return 0
        if args.cmd == "cosim":
            return _cosim(args)
        if args.cmd == "top":
            print(build.top_verilog(suite.bank(args.kind).instances), end="")
            return 0
        if args.cmd == "vectors":
            return _vectors(args)
        if args.cmd == "build":
            b = suite.bank(args.kind).build(args.sim, trace=args.trace)
            print(b.path)
            return 0
        shutil.rmtree(build.build_root(), ignore_errors=True)
        return 0
    except SimulatorMissing as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except build.BuildError as err:
        print(err, file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
