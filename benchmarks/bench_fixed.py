"""Benchmark: the bit-accurate DSP in numba vs plain numpy int64 vs APyTypes, on 1e6 elements.

Run from the repository root::

    python benchmarks/bench_fixed.py [--repeat 7] [--cold] [--json out.json]

Every workload runs in the three implementations side by side; the numpy and APyTypes results are
checked bit-exact against numba before timing (a mismatch aborts). Times are medians of
``--repeat`` runs after one warm-up call; the warm-up (numba: JIT compile, or loading the on-disk
cache) is reported apart. ``--cold`` points numba at an empty cache directory, so the warm-up
column shows the real compile time. "numba" is the public, validating function a user calls;
"kernel" is the bare ``_kernels`` call where one exists. Every ratio comes from this run (no
figure measured elsewhere is written here); without APyTypes installed its column says so and
gives no ratio. ``--quick``: 1e4 elements, 2 repeats, the same code path.

The APyTypes side uses the test oracle ``tests/dsp/_dsp_apy.py`` for the routines (exact float
conversion then ``cast``, docs/background/sources.md F5) and builds its input arrays outside the
timed region for the core operations.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "dsp")]  # this working tree, and the oracle

N = 1_000_000

#: APyTypes (the test extra) runs beside ours when installed; without it, no ratio.
HAVE_APY = importlib.util.find_spec("apytypes") is not None


@dataclass
class Workload:
    name: str
    ref: str | None  # short name of the workload
    numba: Callable[[], object]
    numpy: Callable[[], object]
    apy: Callable[[], object]
    kernel: Callable[[], object] | None = None
    same: Callable[[object, object], bool] | None = None


def _time(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """(one warm-up call ms, median of ``repeat`` further calls ms)."""
    t0 = time.perf_counter()
    fn()
    first = (time.perf_counter() - t0) * 1e3
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        runs.append((time.perf_counter() - t0) * 1e3)
    return first, statistics.median(runs)


# ---------------------------------------------------------------------------------------------
# numpy int64 implementations (plain, vectorized, no overflow checks beyond the formats)
# ---------------------------------------------------------------------------------------------


def np_round_shift(v, sh: int, mode: str):
    """``v / 2^sh`` rounded: RND (ties up) or RND_CONV (ties to even)."""
    import numpy as np

    if sh <= 0:
        return v << -sh
    half = np.int64(1) << (sh - 1)
    if mode == "RND":
        return (v + half) >> sh
    q = v >> sh
    r = v & ((np.int64(1) << sh) - 1)
    return q + ((r > half) | ((r == half) & ((q & 1) == 1)))


def np_sat(v, fmt):
    import numpy as np

    return np.clip(v, fmt.min_code, fmt.max_code)


def np_wrap(v, bits: int):
    """Two's complement wrap of int64 codes to ``bits`` bits."""
    return (v << (64 - bits)) >> (64 - bits)


def build() -> list[Workload]:
    import _dsp_apy as apy_oracle
    import numpy as np

    from chiptwin.dsp import _kernels as K
    from chiptwin.dsp import filters as fl
    from chiptwin.dsp import fixed as fx
    from chiptwin.dsp import frame_ops as fo
    from chiptwin.dsp.registers import reciprocal_code
    from chiptwin.dsp.stress import default_configs, stress_inputs

    rng = np.random.default_rng(2024)
    work: list[Workload] = []

    # float → Q4.12, RND_CONV, SAT
    q412 = fx.Fmt(True, 16, 12)
    x = rng.uniform(-8.5, 8.5, N)
    work.append(
        Workload(
            "quantize float→Q4.12 RNE SAT",
            "quantize",
            lambda: fx.quantize(x, q412, "RND_CONV", "SAT"),
            lambda: np_sat(np.rint(x * 4096.0).astype(np.int64), q412),
            lambda: apy_oracle.quantize(x, q412, "RND_CONV", "SAT", apy_oracle.exact(x, q412)),
            kernel=lambda: K.quantize_kernel(x, 12, q412.spec, 5, 1),
        )
    )

    # Q1.15 × Q1.15 → Q2.30, full precision
    q115 = fx.Fmt(True, 16, 15)
    a = rng.integers(-32768, 32768, N)
    b = rng.integers(-32768, 32768, N)
    a_apy, b_apy = apy_oracle.from_codes(a, q115), apy_oracle.from_codes(b, q115)
    a2, b2 = a.reshape(1, -1), b
    work.append(
        Workload(
            "Q1.15 multiply (full precision)",
            "mul",
            lambda: fx.mul(a, q115, b, q115)[0],
            lambda: a * b,
            lambda: a_apy * b_apy,
            kernel=lambda: K.mul_kernel(a2, b2),
            same=lambda ours, theirs: np.array_equal(
                ours, apy_oracle.to_codes(theirs, fx.Fmt(True, 32, 30))
            ),
        )
    )

    # Q2.30 → Q1.15, RND, SAT
    p = a * b
    q230 = fx.Fmt(True, 32, 30)
    p_apy = apy_oracle.from_codes(p, q230)
    work.append(
        Workload(
            "requantize Q2.30→Q1.15 RND SAT",
            None,
            lambda: fx.requantize(p, q230, q115, "RND", "SAT"),
            lambda: np_sat(np_round_shift(p, 15, "RND"), q115),
            lambda: apy_oracle.to_codes(apy_oracle.cast(p_apy, q115, "RND", "SAT"), q115),
            kernel=lambda: K.requantize_kernel(p, -15, q115.spec, 2, 1),
        )
    )

    # 64-frame accumulate of 128 × 128 ADC frames (full-precision 19-bit accumulator)
    adc, acc19 = fx.Fmt(False, 13, 0), fx.Fmt(False, 19, 0)
    frames = rng.integers(0, 8192, (64, 128 * 128))
    f_apy = apy_oracle.from_codes(frames, adc)
    work.append(
        Workload(
            "64-frame accumulate 128×128",
            "accumulate",
            lambda: fx.accumulate_into(frames, adc, acc19, "WRAP"),
            lambda: frames.sum(axis=0),
            lambda: f_apy.sum(axis=0),
            kernel=lambda: K.accumulate_kernel(frames.reshape(1, 64, -1), acc19.spec, 0, False),
            same=lambda ours, theirs: np.array_equal(
                ours, apy_oracle.to_codes(theirs, fx.Fmt(True, theirs.bits, 0))
            ),
        )
    )

    # the routines, default formats, stress data of ≥ 1e6 input values
    fns = {
        "background": (fo.subtract_background_fixed, apy_oracle.background),
        "cms": (fo.cms_fixed, apy_oracle.cms),
        "average": (fo.average_frames_fixed, apy_oracle.average),
        "binning": (fo.bin_lines_fixed, apy_oracle.binning),
        "kinetics": (fl.kinetics_weighted_fixed, apy_oracle.kinetics),
        "fir": (fl.fir_fixed, apy_oracle.fir),
        "wiener": (fl.wiener_equalize_fixed, lambda f, eq: apy_oracle.wiener(f, eq, False)),
    }
    numpy_impl = _numpy_routines(np, fx, reciprocal_code)
    for label, (routine, cfg) in default_configs().items():
        if routine not in fns:
            continue
        per = 128 * (cfg.m if routine == "cms" else 1)
        inputs = list(stress_inputs(routine, cfg, rng, -(-N // per), 128).values())
        ours, theirs = fns[routine]
        work.append(
            Workload(
                f"{label} ({'×'.join(map(str, inputs[0].shape))})",
                "fir" if routine == "fir" else None,
                lambda ours=ours, inputs=inputs, cfg=cfg: ours(*inputs, cfg).codes,
                lambda f=numpy_impl[routine], inputs=inputs, cfg=cfg: f(*inputs, cfg),
                lambda theirs=theirs, inputs=inputs, cfg=cfg: theirs(*inputs, cfg),
            )
        )
    return work


def _numpy_routines(np, fx, reciprocal_code):
    """Plain numpy int64 versions of the routines (default formats: no internal overflow)."""

    def divide(v, fmt, n, rw, out, rnd):
        if n & (n - 1) == 0:
            k = n.bit_length() - 1
            return np_round_shift(v, fmt.frac_bits + k - out.frac_bits, rnd)
        rf = rw + n.bit_length() - 1
        prod = v * np.int64(reciprocal_code(n, rw))
        return np_round_shift(prod, fmt.frac_bits + rf - out.frac_bits, rnd)

    def background(frames, dark, cfg):
        diff = (frames << (cfg.dark_fmt.frac_bits - cfg.in_fmt.frac_bits)) - dark
        return np_sat(
            np_round_shift(diff, cfg.dark_fmt.frac_bits - cfg.out_fmt.frac_bits, "RND_CONV"),
            cfg.out_fmt,
        )

    def cms(reset, signal, cfg):
        d = signal.sum(axis=-2) - reset.sum(axis=-2)
        return np_sat(
            divide(d, cfg.in_fmt, cfg.m, cfg.recip_word_bits, cfg.out_fmt, "RND_CONV"), cfg.out_fmt
        )

    def average(frames, cfg):
        s = frames.reshape(-1, cfg.n, frames.shape[-1]).sum(axis=1)
        return np_sat(
            divide(s, cfg.in_fmt, cfg.n, cfg.recip_word_bits, cfg.out_fmt, "RND_CONV"), cfg.out_fmt
        )

    def binning(frames, cfg):
        lead = frames.shape[:-1]
        s = frames.reshape(*lead, cfg.rows // cfg.factor, cfg.factor, cfg.cols).sum(axis=-2)
        return s.reshape(*lead, -1)

    def kinetics(frames, cfg):
        w = np.array(cfg.weight_codes, dtype=np.int64)
        acc = np.einsum("j,bjp->bp", w, frames)
        f = cfg.in_fmt.frac_bits + cfg.coef_fmt.frac_bits + cfg.norm_fmt.frac_bits
        out = np_round_shift(acc * np.int64(cfg.norm_code), f - cfg.out_fmt.frac_bits, "RND_CONV")
        return np_sat(out, cfg.out_fmt)

    def fir(frames, cfg):
        acc = np.zeros_like(frames)
        for k, h in enumerate(cfg.coef_codes):
            acc[k:] += h * frames[: frames.shape[0] - k]
        acc = np_wrap(acc, cfg.acc_fmt.word_bits)
        out = np_round_shift(acc, cfg.acc_fmt.frac_bits - cfg.out_fmt.frac_bits, "RND")
        return np_sat(out, cfg.out_fmt)

    def wiener(frames, eq):
        acc = frames @ eq.coef_codes.T
        out = np_round_shift(acc, eq.acc_fmt.frac_bits - eq.out_fmt.frac_bits, "RND_CONV")
        return np_sat(out, eq.out_fmt)

    return {
        "background": background,
        "cms": cms,
        "average": average,
        "binning": binning,
        "kinetics": kinetics,
        "fir": fir,
        "wiener": wiener,
    }


def _codes(result):
    import numpy as np

    if isinstance(result, tuple):
        result = result[0]
    return np.asarray(result)


def run(repeat: int) -> tuple[list[dict], float]:
    """The rows of the table, and the setup time (imports, data, coefficient design) in ms."""
    import numpy as np

    t0 = time.perf_counter()
    work = build()
    setup_ms = (time.perf_counter() - t0) * 1e3
    rows = []
    for w in work:
        t0 = time.perf_counter()
        ours = _codes(w.numba())  # the first call: JIT compile or cache load
        warm_up = (time.perf_counter() - t0) * 1e3
        assert np.array_equal(ours, _codes(w.numpy())), f"numpy differs: {w.name}"
        if HAVE_APY:
            theirs = w.apy()
            ok = w.same(ours, theirs) if w.same else np.array_equal(ours, _codes(theirs))
            assert ok, f"APyTypes differs: {w.name}"
        row = {"workload": w.name, "ref": w.ref, "numba_first": warm_up}
        for impl in ("numba", "kernel", "numpy", "apy"):
            fn = getattr(w, impl) if impl != "apy" or HAVE_APY else None
            row[impl] = None if fn is None else _time(fn, repeat)[1]
        rows.append(row)
    return rows, setup_ms


def table(rows: list[dict]) -> str:
    head = (
        f"{'workload':<34} {'numba':>8} {'kernel':>8} {'numpy':>8} {'APyTypes':>9} "
        f"{'np/nb':>6} {'apy/nb':>7} {'warm-up':>8}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        apy = r["apy"]
        lines.append(
            f"{r['workload']:<34} {r['numba']:>8.3f} "
            f"{'—' if r['kernel'] is None else format(r['kernel'], '.3f'):>8} "
            f"{r['numpy']:>8.3f} {'absent' if apy is None else format(apy, '.2f'):>9} "
            f"{r['numpy'] / r['numba']:>6.2f} "
            f"{'—' if apy is None else format(apy / r['numba'], '.1f'):>7} "
            f"{r['numba_first']:>8.1f}"
        )
    lines.append(
        f"{N:.0e} elements; times in ms, medians, all from this run; 'numba' = public validating"
        " call, 'kernel' = bare kernel; warm-up = first numba call (JIT compile with --cold, else"
        " cache load)" + ("" if HAVE_APY else "; APyTypes not installed: no ratio against it")
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per cell (median)")
    parser.add_argument("--cold", action="store_true", help="empty numba cache: time the compile")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON")
    parser.add_argument("--quick", action="store_true", help="1e4 elements, 2 repeats")
    args = parser.parse_args(argv)
    if args.quick:
        global N
        N, args.repeat = 10_000, 2
    if args.cold:
        os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="chiptwin-numba-")
    rows, setup_ms = run(args.repeat)
    print(table(rows))
    print(f"setup (imports, data, coefficient design, quantize JIT): {setup_ms:.0f} ms")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
