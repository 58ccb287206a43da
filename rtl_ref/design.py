"""A simulation top: one or more block instances behind one generic stream interface.

Every design the harness builds has the same top-level ports, so one testbench (C++ for
Verilator, Verilog for Icarus) drives any of them::

    ct_top(clk, rst, sel[7:0],
           in_valid, in_ready, in_d0[63:0], in_d1[63:0],
           out_valid, out_ready, out_d0[63:0], out_d1[63:0], out_flags[7:0],
           cnt_idx[5:0], cnt[63:0])

``sel`` (static during a run) picks the instance; the beat words ``in_d0``/``in_d1`` feed the
instance's data inputs (low bits, two's complement); its one or two data outputs come back sign-
or zero-extended to 64 bits in ``out_d0``/``out_d1`` (so the words read as int64 are the codes);
``out_flags`` carries its 1-bit outputs; ``cnt`` shows counter ``cnt_idx``. Several instances
in one top share one Verilator build (builds, not simulations, dominate the cost).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

CNT_W = 48
"""Width of every overflow counter in the RTL."""

MAX_INSTANCES = 256
MAX_COUNTERS = 64


@dataclass(frozen=True)
class Port:
    """A data port of a block: name, width, and whether its code is two's complement."""

    name: str
    width: int
    signed: bool


@dataclass(frozen=True)
class Instance:
    """One block instance: its module, parameters and how its ports map to the generic top.

    Attributes
    ----------
    module : str
        Verilog module (``ct_background`` …).
    params : tuple of (name, Verilog literal)
    inputs : tuple of Port
        Fed from ``in_d0`` then ``in_d1``.
    outputs : tuple of Port
        Sent to ``out_d0`` then ``out_d1``.
    flags : tuple of str
        1-bit outputs, bit 0 upwards of ``out_flags``.
    counters : tuple of str
        Counter ports (``CNT_W`` bits), ``cnt_idx`` 0 upwards.
    """

    module: str
    params: tuple[tuple[str, str], ...]
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    flags: tuple[str, ...]
    counters: tuple[str, ...]

    def __post_init__(self) -> None:
        if not 1 <= len(self.inputs) <= 2 or not 1 <= len(self.outputs) <= 2:
            raise ValueError(f"{self.module}: one or two data inputs and outputs")
        for port in self.inputs + self.outputs:
            if not 1 <= port.width <= 64:
                raise ValueError(
                    f"{self.module}.{port.name}: {port.width} bits; the generic top carries "
                    "words of at most 64 bits"
                )
        if len(self.flags) > 8 or len(self.counters) > MAX_COUNTERS:
            raise ValueError(f"{self.module}: at most 8 flags and {MAX_COUNTERS} counters")


def literal(value: int, width: int | None = None) -> str:
    """A Verilog literal: plain decimal, or ``W'h…`` two's complement when ``width`` is given."""
    if width is None:
        return str(int(value))
    return f"{width}'h{int(value) % (1 << width):x}"


def packed(codes: Sequence[int], width: int) -> str:
    """A ROM as one packed literal: element ``k`` at bits ``[k*width +: width]``."""
    word = 0
    for k, code in enumerate(codes):
        word |= (int(code) % (1 << width)) << (k * width)
    return literal(word, width * len(codes))


def _extend(sig: str, port: Port) -> str:
    if port.width == 64:
        return sig
    fill = f"{sig}[{port.width - 1}]" if port.signed else "1'b0"
    return f"{{{{{64 - port.width}{{{fill}}}}}, {sig}}}"


def _instance_text(k: int, inst: Instance) -> list[str]:
    p = f"i{k}"
    lines = [f"    // ---- instance {k}: {inst.module}"]
    lines.append(f"    wire {p}_in_ready, {p}_out_valid;")
    lines.append(f"    wire {p}_sel = (sel == 8'd{k});")
    # idle instances see constant inputs: an event-driven simulator then leaves them alone
    lines.append(f"    wire [63:0] {p}_in_d0 = {p}_sel ? in_d0 : 64'd0;")
    lines.append(f"    wire [63:0] {p}_in_d1 = {p}_sel ? in_d1 : 64'd0;")
    for port in inst.outputs:
        lines.append(f"    wire [{port.width - 1}:0] {p}_{port.name};")
    for flag in inst.flags:
        lines.append(f"    wire {p}_{flag};")
    for c in inst.counters:
        lines.append(f"    wire [{CNT_W - 1}:0] {p}_{c};")
    params = ",\n".join(f"        .{name}({value})" for name, value in inst.params)
    conns = [
        ".clk(clk)",
        ".rst(rst)",
        f".in_valid(in_valid & {p}_sel)",
        f".in_ready({p}_in_ready)",
        f".out_valid({p}_out_valid)",
        f".out_ready(out_ready & {p}_sel)",
    ]
    for word, port in zip(("in_d0", "in_d1"), inst.inputs, strict=False):
        conns.append(f".{port.name}({p}_{word}[{port.width - 1}:0])")
    for name in [o.name for o in inst.outputs] + list(inst.flags) + list(inst.counters):
        conns.append(f".{name}({p}_{name})")
    body = ",\n".join(f"        {c}" for c in conns)
    lines.append(f"    {inst.module} #(\n{params}\n    ) u_{p} (\n{body}\n    );")
    outs = [_extend(f"{p}_{o.name}", o) for o in inst.outputs] + ["64'd0"]
    lines.append(f"    wire [63:0] {p}_d0 = {outs[0]};")
    lines.append(f"    wire [63:0] {p}_d1 = {outs[1]};")
    flags = ", ".join(f"{p}_{f}" for f in reversed(inst.flags))
    pad = 8 - len(inst.flags)
    flag_bits = f"{{{pad}'d0, {flags}}}" if inst.flags and pad else (
        f"{{{flags}}}" if inst.flags else "8'd0"
    )
    lines.append(f"    wire [7:0] {p}_flags = {flag_bits};")
    cnt = "64'd0"
    for i in reversed(range(len(inst.counters))):
        cnt = f"(cnt_idx == 6'd{i}) ? {{{64 - CNT_W}'d0, {p}_{inst.counters[i]}}} : {cnt}"
    lines.append(f"    wire [63:0] {p}_cnt = {cnt};")
    return lines


def _mux(name: str, n: int, default: str) -> str:
    expr = default
    for k in reversed(range(n)):
        expr = f"(sel == 8'd{k}) ? i{k}_{name} : {expr}"
    return expr


def top_verilog(instances: Sequence[Instance]) -> str:
    """The text of ``ct_top`` for ``instances`` (``sel`` = index in the sequence)."""
    if not 1 <= len(instances) <= MAX_INSTANCES:
        raise ValueError(f"a top holds 1…{MAX_INSTANCES} instances, got {len(instances)}")
    n = len(instances)
    lines = [
        "// Generated by rtl_ref.design: a simulation top, not part of the DSP RTL.",
        "`default_nettype none",
        "/* verilator lint_off UNUSEDSIGNAL */  // the beat words are wider than most ports",
        "module ct_top (",
        "    input  wire        clk,",
        "    input  wire        rst,",
        "    input  wire [7:0]  sel,",
        "    input  wire        in_valid,",
        "    output wire        in_ready,",
        "    input  wire [63:0] in_d0,",
        "    input  wire [63:0] in_d1,",
        "    output wire        out_valid,",
        "    input  wire        out_ready,",
        "    output wire [63:0] out_d0,",
        "    output wire [63:0] out_d1,",
        "    output wire [7:0]  out_flags,",
        "    input  wire [5:0]  cnt_idx,",
        "    output wire [63:0] cnt",
        ");",
    ]
    for k, inst in enumerate(instances):
        lines += _instance_text(k, inst)
    zero = {"in_ready": "1'b0", "out_valid": "1'b0", "d0": "64'd0", "d1": "64'd0",
            "flags": "8'd0", "cnt": "64'd0"}
    ports = {"in_ready": "in_ready", "out_valid": "out_valid", "d0": "out_d0", "d1": "out_d1",
             "flags": "out_flags", "cnt": "cnt"}
    lines += [f"    assign {ports[k]} = {_mux(k, n, zero[k])};" for k in ports]
    lines += [
        "endmodule",
        "/* verilator lint_on UNUSEDSIGNAL */",
        "`default_nettype wire",
        "",
    ]
    return "\n".join(lines)
