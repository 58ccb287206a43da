"""Benchmark: the sensor chain on 1024 × 1024 pixels × 10 frames, side by side in one run.

Shot noise (one merged Poisson draw per pixel of QE·PRNU·photons + DSNU·dark), full-well clip,
read noise, conversion gain, 12-bit ADC; one read per frame (Pyxel's CMOS chain). Contenders,
timed in interleaved rounds (this machine is shared and noisy; medians are reported):

(a) floor: one bare ``Generator.poisson`` call drawing all 1.05e7 counts at the same means
    (and the same on NumPy's SFC64 bit generator, which the fast path's streams use), and two
    cores' worth of it: two threads, each drawing half (NumPy releases the GIL while it draws);
(b) plain numpy, frame by frame: the same physics with whole-array numpy calls;
(c) ``chiptwin.pixel.sensor_chain``, exact Poisson (Ahrens & Dieter above a mean of 10), all
    cores (and on one thread, for scaling);
(d) ``sensor_chain(shot_noise="gaussian")``: a named approximation, with its error measured.

(e) Pyxel 3.0.2 (``pyxel-sim``), exposure mode, warm, the same physics on the same scene (shot
    noise, QE, dark, full well, read noise, 12-bit ADC), when it can be run: in its own
    interpreter, given by ``--pyxel-python`` or ``$CHIPTWIN_PYXEL_PYTHON`` (a venv:
    ``python -m venv ~/venvs/pyxel && ~/venvs/pyxel/bin/pip install pyxel-sim==3.0.2``;
    its dependencies need not agree with ours), else this interpreter if it imports ``pyxel``.
    The worker stays up and runs once per round, between the other contenders' turns, so every
    ratio comes from runs side by side. Without Pyxel the table says so and prints no ratio.

Where the time goes: one frame of the scene on one thread, the chain's work built up a piece at a
time in small numba loops (:func:`components`): reading the means, NumPy's PTRS Poisson sampler
(our inline copy), Ahrens & Dieter's, + the read-noise normal, + conversion to volts and the ADC's
rounding and clipping; the whole again with numba's reference counting on (an atomic pair around
every draw: the chain ran 1.5× its floor so); beside NumPy's own ``Generator.poisson``.

Peak memory is measured separately with tracemalloc (NumPy's allocations are traced), Pyxel's
the same way inside its worker. No timing of another tool is written in this file.

Usage: ``python benchmarks/bench_sensor_chain.py [--side 1024] [--frames 10] [--rounds 5]
[--pyxel-python PATH] [--quick]``. ``--quick``: 128² × 2 frames, 2 rounds, no Pyxel unless
asked: the same code path in a few seconds.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from scipy.special import ndtr
from scipy.stats import poisson

from chiptwin._numba import NJIT_NORC
from chiptwin.pixel import (
    _kernels,
    _random,
    adc_convert,
    fixed_pattern_maps,
    sensor_chain,
    to_volts,
)
from chiptwin.pixel.chain import available_cores

CHIP = dict(
    qe=0.6,
    full_well_e=20_000.0,
    read_noise_e=5.0,
    conversion_gain_uV_per_e=40.0,
    pedestal_V=0.05,
    bits=12,
    v_min_V=0.0,
    v_max_V=1.0,
)


def make_scene(side: int, seed: int = 2024) -> dict[str, np.ndarray]:
    """A fixed non-flat scene: photons 500–5000 per pixel per frame, 1 % PRNU, 10 % DSNU."""
    rng = np.random.default_rng(seed)
    photons = rng.uniform(500.0, 5000.0, (side, side))
    gain, dark = fixed_pattern_maps(rng, side * side, 0.01, 0.1)
    gain, dark_e = gain.reshape(side, side), 50.0 * dark.reshape(side, side)
    lam = CHIP["qe"] * gain * photons + dark_e
    return {"photons": photons, "gain": gain, "dark_e": dark_e, "lam": lam}


def floor(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(a) One bare Poisson draw over all n_frames × pixels values (default PCG64 generator)."""
    rng.poisson(scene["lam"], size=(n_frames, *scene["lam"].shape))


def floor_sfc64(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(a') The same with NumPy's SFC64 bit generator, the one the fast path's streams use."""
    floor(np.random.Generator(np.random.SFC64(rng.integers(2**63))), scene, n_frames)


def floor_two_cores(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(a2) Two cores' worth of (a): two threads, each one bare draw over half the frames."""
    seeds = rng.integers(2**63, size=2)
    halves = (n_frames // 2, n_frames - n_frames // 2)
    with ThreadPoolExecutor(2) as pool:
        pairs = zip(seeds, halves, strict=True)
        jobs = [pool.submit(floor, np.random.default_rng(s), scene, h) for s, h in pairs]
        for job in jobs:
            job.result()


def plain_numpy(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
    """(b) The same physics with whole-array numpy calls, frame by frame."""
    for _ in range(n_frames):
        lam = CHIP["qe"] * scene["gain"] * scene["photons"] + scene["dark_e"]
        electrons = np.minimum(rng.poisson(lam), CHIP["full_well_e"])
        electrons = electrons + CHIP["read_noise_e"] * rng.standard_normal(lam.shape)
        volts = to_volts(electrons, CHIP["conversion_gain_uV_per_e"], CHIP["pedestal_V"])
        adc_convert(volts, CHIP["bits"], CHIP["v_min_V"], CHIP["v_max_V"])


def fast(n_threads: int | None, shot_noise: str = "poisson") -> Callable:
    """(c)/(d) sensor_chain into reused buffers."""

    def run(rng: np.random.Generator, scene: dict, n_frames: int) -> None:
        shape = (1, *scene["photons"].shape)
        out = (np.empty((0, *shape[1:]), np.int64), np.empty(shape, np.int64))
        frames = sensor_chain(
            rng,
            scene["photons"],
            n_frames=n_frames,
            gain_map=scene["gain"],
            dark_e=scene["dark_e"],
            n_threads=n_threads,
            shot_noise=shot_noise,
            out=out,
            **CHIP,
        )
        for _ in frames:
            pass

    return run


@NJIT_NORC  # as the chain's loop: no reference counting around each draw (chiptwin._numba)
def _piece(state, lam, upto, out, full_well, read, pedestal, cg, v_min, lsb, top):
    """The chain's per-pixel work up to piece ``upto`` (see :func:`components`), one value each."""
    for i in range(lam.size):
        if upto == 0:
            out[i] = lam[i]
            continue
        if upto == 1:
            out[i] = _random.poisson(state, lam[i])
            continue
        count = min(float(_random.poisson_fast(state, lam[i])), full_well)
        if upto == 2:
            out[i] = count
            continue
        e = count + read * _random.standard_normal(state)
        if upto == 3:
            out[i] = e
            continue
        out[i] = _kernels.adc_code(pedestal + e * cg, v_min, lsb, 1.0, 0.0, top)


#: :func:`_piece` with numba's reference counting on (``@njit`` as the chain's loop was): the
#: atomic pair it leaves around every draw, shown beside the pieces (chiptwin._numba.NJIT_NORC).
#: Not cached: numba's cache keys a function by its name and types, not its options, so this
#: would share :func:`_piece`'s entry.
_piece_counted = numba.njit(_piece.py_func)

PIECES = ("read the means (memory traffic)", "Poisson, NumPy's PTRS (inline copy)",
          "Poisson, Ahrens & Dieter (the chain's)", "+ read-noise normal (ziggurat)",
          "+ volts, ADC rounding and clipping")


def components(scene: dict, rounds: int) -> dict[str, float]:
    """ns per pixel of one frame, one thread, best of ``rounds``: each piece of the chain's work
    cumulated (:data:`PIECES`), NumPy's ``Generator.poisson`` and the whole chain on one thread."""
    lam = np.ascontiguousarray(scene["lam"].ravel())
    out = np.empty(lam.size)
    state = _random.state_of(np.random.Generator(np.random.SFC64(3)))
    gen = np.random.Generator(np.random.SFC64(4))
    c = CHIP
    consts = (c["full_well_e"], c["read_noise_e"], c["pedestal_V"],
              c["conversion_gain_uV_per_e"] * 1e-6, c["v_min_V"],
              (c["v_max_V"] - c["v_min_V"]) / 2.0 ** c["bits"], 2.0 ** c["bits"] - 1)
    runs = {name: (lambda k=k: _piece(state, lam, k, out, *consts))
            for k, name in enumerate(PIECES)}
    runs["all of it, reference counting on"] = lambda: _piece_counted(state, lam, 4, out, *consts)
    runs["NumPy Generator.poisson (the floor)"] = lambda: gen.poisson(lam)
    runs["sensor_chain, one thread (all of it)"] = lambda: fast(1)(gen, scene, 1)
    best = {}
    for name, run in runs.items():
        run()
        best[name] = min(_timed(run) for _ in range(rounds)) / lam.size * 1e9
    return best


def _timed(run: Callable) -> float:
    t0 = time.perf_counter()
    run()
    return time.perf_counter() - t0


def time_rounds(
    methods: dict[str, Callable], scene: dict, n_frames: int, rounds: int, pyxel: Pyxel | None
) -> dict[str, list[float]]:
    """Wall times of every method, in interleaved rounds (Pyxel's turn last in each round)."""
    times: dict[str, list[float]] = {name: [] for name in methods}
    rng = np.random.default_rng(7)
    for _ in range(rounds):
        for name, run in methods.items():
            t0 = time.perf_counter()
            run(rng, scene, n_frames)
            times[name].append(time.perf_counter() - t0)
        if pyxel is not None:
            pyxel.run()
    return times


#: The Pyxel side, run in Pyxel's own interpreter: builds the YAML of the same chain, warms up,
#: then runs ``run_mode`` once per "run" line on stdin and prints its wall time; "mem" prints the
#: traced peak of one run (MB). Pyxel's models: load_image (photons per readout of 1 s), Poisson
#: shot noise, QE (no binomial sampling: the mean), dark (e⁻/s), collection, full well, charge to
#: volt, output-node read noise (V), amplifier, 12-bit ADC.
PYXEL_WORKER = r"""
import json, os, resource, sys, time, tracemalloc
a = json.loads(sys.argv[1])
import pyxel
f = lambda x: f"{float(x):.9e}"  # YAML 1.1 reads 4e-05 as a string
m = lambda n, fn, args="": (f"    - {{name: {n}, func: pyxel.models.{fn}, enabled: true"
                            + (f", arguments: {{{args}}}" if args else "") + "}")
times = ", ".join(f(t + 1) for t in range(a["frames"]))
yaml = "\n".join([
    "exposure:", f"  readout: {{times: [{times}], non_destructive: false}}",
    f"  pipeline_seed: {a['seed']}",
    "cmos_detector:",
    f"  geometry: {{row: {a['side']}, col: {a['side']}, total_thickness: 40.0,"
    " pixel_vert_size: 10.0, pixel_horz_size: 10.0}",
    "  environment: {temperature: 300.0}",
    f"  characteristics: {{quantum_efficiency: {f(a['qe'])}, charge_to_volt: {{value:"
    f" {f(a['cg_V'])}}}, pre_amplification: 1.0, adc_bit_resolution: {a['bits']},"
    f" adc_voltage_range: [{f(a['v_min'])}, {f(a['v_max'])}], full_well_capacity:"
    f" {a['full_well']}}}",
    "pipeline:",
    "  photon_collection:",
    m("load_image", "photon_collection.load_image", f"image_file: '{a['image']}'"),
    m("shot_noise", "photon_collection.shot_noise"),
    "  charge_generation:",
    m("photoelectrons", "charge_generation.simple_conversion", "binomial_sampling: false"),
    m("dark", "charge_generation.simple_dark_current", f"dark_rate: {f(a['dark_e'])}"),
    "  charge_collection:",
    m("collection", "charge_collection.simple_collection"),
    m("full_well", "charge_collection.simple_full_well"),
    "  charge_measurement:",
    m("measurement", "charge_measurement.simple_measurement"),
    m("read_noise", "charge_measurement.output_node_noise", f"std_deviation: {f(a['read_V'])}"),
    "  readout_electronics:",
    m("amplifier", "readout_electronics.simple_amplifier"),
    m("adc", "readout_electronics.simple_adc"),
])
path = os.path.join(os.path.dirname(a["image"]), "pyxel.yaml")
with open(path, "w") as fh:
    fh.write(yaml + "\n")
def once():
    cfg = pyxel.load(path)
    t0 = time.perf_counter()
    pyxel.run_mode(cfg)
    return time.perf_counter() - t0
once()  # warm: imports, caches
print(json.dumps({"version": pyxel.__version__}), flush=True)
for line in sys.stdin:
    if line.strip() == "run":
        print(json.dumps({"s": once()}), flush=True)
    elif line.strip() == "mem":
        tracemalloc.start()
        once()
        peak = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
        print(json.dumps({"peak_MB": peak, "max_rss_MB": rss}), flush=True)
"""


def pyxel_python(flag: str | None) -> str | None:
    """The interpreter that runs Pyxel: ``--pyxel-python``, ``$CHIPTWIN_PYXEL_PYTHON``, or this
    one if it imports ``pyxel``; None when there is none."""
    path = flag or os.environ.get("CHIPTWIN_PYXEL_PYTHON")
    if path:
        return path
    return sys.executable if importlib.util.find_spec("pyxel") else None


class Pyxel:
    """Pyxel's worker process over the benchmark's scene; :meth:`run` times one warm run."""

    def __init__(self, python: str, scene: dict, n_frames: int, folder: str) -> None:
        image = os.path.join(folder, "photons.npy")
        np.save(image, scene["photons"])
        dark = float(np.mean(scene["dark_e"]))  # Pyxel's simple dark current is uniform
        args = {"frames": n_frames, "seed": 1, "side": scene["photons"].shape[0], "image": image,
                "qe": CHIP["qe"], "cg_V": CHIP["conversion_gain_uV_per_e"] * 1e-6,
                "bits": CHIP["bits"], "v_min": CHIP["v_min_V"], "v_max": CHIP["v_max_V"],
                "full_well": int(CHIP["full_well_e"]), "dark_e": dark,
                "read_V": CHIP["read_noise_e"] * CHIP["conversion_gain_uV_per_e"] * 1e-6,
                }  # fmt: skip
        self.proc = subprocess.Popen(
            [python, "-c", PYXEL_WORKER, json.dumps(args)], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        )  # fmt: skip
        self.version = self._reply()["version"]
        self.times_s: list[float] = []

    def _reply(self) -> dict:
        line = self.proc.stdout.readline()  # type: ignore[union-attr]
        if not line:
            raise RuntimeError("the Pyxel worker stopped (run it by hand to see why)")
        return json.loads(line)

    def _ask(self, what: str) -> dict:
        self.proc.stdin.write(what + "\n")  # type: ignore[union-attr]
        self.proc.stdin.flush()  # type: ignore[union-attr]
        return self._reply()

    def run(self) -> None:
        self.times_s.append(self._ask("run")["s"])

    def close(self) -> dict:
        """Its memory (one more run, traced) and every time; the worker stops."""
        mem = self._ask("mem")
        self.proc.stdin.close()  # type: ignore[union-attr]
        self.proc.wait()
        return {"version": self.version, "times_s": self.times_s, **mem}


def peak_memory_mb(run: Callable, scene: dict, n_frames: int) -> float:
    """Peak traced allocation of one run, beyond what existed before it. Unit: MB."""
    tracemalloc.start()
    run(np.random.default_rng(8), scene, n_frames)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 1e6


def gaussian_error(lam: float) -> dict[str, float]:
    """Total-variation distance between Poisson(λ) and max(0, rint(λ + √λ·z)), exactly, and the
    skewness the approximation drops (Poisson: 1/√λ)."""
    sd = np.sqrt(lam)
    k = np.arange(max(0, int(lam - 40 * sd)), int(lam + 40 * sd) + 1)
    q = ndtr((k + 0.5 - lam) / sd) - ndtr((k - 0.5 - lam) / sd)
    q[k == 0] = ndtr((0.5 - lam) / sd)
    tv = 0.5 * np.abs(poisson.pmf(k, lam) - q).sum()
    return {"lam": lam, "tv_distance": float(tv), "poisson_skewness": float(1 / sd)}


def sampled_moments(shot_noise: str, lam: float, n: int = 2_000_000) -> list[float]:
    """Mean, variance and skewness of n drawn counts (via codes at 1 e⁻ per LSB, no read noise)."""
    chip = CHIP | {
        "read_noise_e": 0.0,
        "conversion_gain_uV_per_e": 1.0,
        "pedestal_V": 0.0,
        "bits": 24,
        "v_max_V": 2.0**24 * 1e-6,
        "full_well_e": 1e9,
    }
    _, codes = next(
        sensor_chain(
            np.random.default_rng(9),
            np.full(n, lam / chip["qe"]),
            n_frames=1,
            dark_e=0.0,
            shot_noise=shot_noise,
            gaussian_min_mean_e=100.0,
            **chip,
        )
    )
    x = codes.ravel().astype(float)
    d = x - x.mean()
    return [float(x.mean()), float(x.var()), float((d**3).mean() / x.var() ** 1.5)]


def report(times: dict, memory: dict, n_values: int, cold_s: float, pyxel: dict | None) -> dict:
    """Print the comparison table (ratios from this run only); return it as a dict."""
    med = {name: statistics.median(ts) for name, ts in times.items()}
    a, a2, b = med["a_floor"], med["a3_floor_two_cores"], med["b_plain_numpy"]
    print(f"{'contender':28s} {'median s':>9s} {'min s':>7s} {'max s':>7s} {'vs (a)':>7s}"
          f" {'vs (a2)':>7s} {'peak MB':>8s}")  # fmt: skip
    for name, ts in times.items():
        t = med[name]
        print(f"{name:28s} {t:9.3f} {min(ts):7.3f} {max(ts):7.3f} {t / a:7.2f} {t / a2:7.2f}"
              f" {memory[name]:8.1f}")  # fmt: skip
    c, c1 = times["c_sensor_chain"], times["c1_sensor_chain_1_thread"]
    result = {
        "median_s": med,
        "all_s": times,
        "peak_MB": memory,
        "ratio_c_vs_a": statistics.median(c) / a,
        "ratio_c_vs_two_cores_floor": statistics.median(c) / a2,
        "ratio_c1_vs_a": statistics.median(c1) / a,
        "ratio_c_vs_b": statistics.median(c) / b,
        "cold_call_s": cold_s,
    }
    cm = statistics.median(c)
    print(
        f"(c) vs two cores' floor (a2): {cm / a2:.2f}× (aim ≤ 1.1); one thread (c1) vs (a):"
        f" {statistics.median(c1) / a:.2f}×; {n_values / cm / 1e6:.1f} M pixel-frames/s"
    )
    if pyxel is None:
        print("(e) Pyxel: not installed here (see --pyxel-python): no ratio against it.")
    else:
        e = statistics.median(pyxel["times_s"])
        print(
            f"(e) Pyxel {pyxel['version']} run_mode, warm, this run: median {e:.3f} s"
            f" (min {min(pyxel['times_s']):.3f}, max {max(pyxel['times_s']):.3f}),"
            f" traced peak {pyxel['peak_MB']:.0f} MB, process RSS {pyxel['max_rss_MB']:.0f} MB"
        )
        print(
            f"(c) vs Pyxel, this run: {e / cm:.1f}× faster (per-round ratios"
            f" {min(pyxel['times_s']) / max(c):.1f}–{max(pyxel['times_s']) / min(c):.1f}×),"
            f" {pyxel['peak_MB'] / memory['c_sensor_chain']:.0f}× less traced memory"
        )
        result |= {"pyxel": pyxel, "ratio_pyxel_vs_c": e / cm}
    print(f"first call of sensor_chain (JIT load or compile): {cold_s:.2f} s")
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=1024)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument(
        "--pyxel-python",
        help="interpreter with pyxel-sim 3.0.2 installed"
        " (default $CHIPTWIN_PYXEL_PYTHON, or this one if it imports pyxel)",
    )
    parser.add_argument("--quick", action="store_true", help="128² × 2 frames, 2 rounds")
    parser.add_argument("--json", help="also write the results here")
    args = parser.parse_args(argv)
    if args.quick:
        args.side, args.frames, args.rounds = 128, 2, 2
    print(
        f"cores available: {available_cores()}; numpy {np.__version__}; numba {numba.__version__}"
    )
    scene = make_scene(args.side)
    t0 = time.perf_counter()
    fast(None)(np.random.default_rng(0), make_scene(8), 1)
    cold_s = time.perf_counter() - t0
    methods = {
        "a_floor": floor,
        "a2_floor_sfc64": floor_sfc64,
        "a3_floor_two_cores": floor_two_cores,
        "b_plain_numpy": plain_numpy,
        "c_sensor_chain": fast(None),
        "c1_sensor_chain_1_thread": fast(1),
        "d_sensor_chain_gaussian": fast(None, "gaussian"),
    }
    python = pyxel_python(args.pyxel_python) if not args.quick or args.pyxel_python else None
    print(
        f"{args.side}×{args.side} pixels × {args.frames} frames, {args.rounds} rounds;"
        f" Pyxel: {python or 'not available'}"
    )
    with tempfile.TemporaryDirectory() as folder:
        pyxel = None if python is None else Pyxel(python, scene, args.frames, folder)
        times = time_rounds(methods, scene, args.frames, args.rounds, pyxel)
        pyxel_result = None if pyxel is None else pyxel.close()
    memory = {name: peak_memory_mb(run, scene, args.frames) for name, run in methods.items()}
    result = report(times, memory, args.side**2 * args.frames, cold_s, pyxel_result)
    pieces = components(scene, args.rounds)
    print("where the time goes (one frame, one thread, ns per pixel, best of the rounds):")
    for name, ns in pieces.items():
        print(f"  {name:40s} {ns:6.1f}")
    result["components_ns_per_pixel"] = pieces
    errors = [gaussian_error(lam) for lam in (1000.0, 1e4)]
    n_draws = 20_000 if args.quick else 2_000_000
    moments = {lv: sampled_moments(lv, 1000.0, n_draws) for lv in ("poisson", "gaussian")}
    for e in errors:
        print(
            f"gaussian level at λ = {e['lam']:g}: total-variation distance {e['tv_distance']:.4f}"
            f" (drops skewness {e['poisson_skewness']:.4f})"
        )
    for lv, (m, v, sk) in moments.items():
        print(f"  {n_draws:.0e} draws at λ = 1000, {lv:8s}: mean {m:.2f}, variance {v:.1f},"
              f" skewness {sk:.4f}")  # fmt: skip
    result |= {
        "gaussian_error": errors,
        "gaussian_sampled_moments": moments,
        "max_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3,
    }
    print(f"process peak RSS: {result['max_rss_MB']:.0f} MB")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
