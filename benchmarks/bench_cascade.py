"""Cascade kinetics: error vs solver tolerance vs wall time, wall time per flow, the
cascade against the closed form, and the calibrated photon yield against Ronaghi 2001
(docs/background/sources.md K13).

Usage: ``python benchmarks/bench_cascade.py [--quick] [--repeat 3] [--methods LSODA Radau BDF]``.
``--quick``: LSODA at rtol 1e-6 only, one repeat, the reference cases on 12 windows (not 50) and
the saturated case over one flow (not four): every table, a row or two each.
Prints markdown tables. References: the 50-digit solution of the linear regime
(:mod:`chiptwin.kinetics.cascade_reference`) for the hard cases, paper eq. 19 for the paper's
limit, and the same model at rtol = 1e-12 (Radau) for the saturated, non-linear case.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from chiptwin.constants import N_A
from chiptwin.kinetics import cascade_reference as ref
from chiptwin.kinetics import closed_form as cf
from chiptwin.kinetics import flow_incorporations, pyrosequencing
from chiptwin.kinetics.calibrate import (
    fit_light_curve,
    fit_photon_yield,
    photon_yield,
)
from chiptwin.kinetics.cascade import cascade_pyrosequencing
from chiptwin.kinetics.cascade_params import CascadeParams

TEMPLATE, FLOWS, N_FLOWS, PERIOD, START = "TCAGGTTCCAAAGTCGAT", "TACG", 25, 60.0, 20.0
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)


def linear(k_s, k_pol, k_t, k_a, **changes) -> CascadeParams:
    return CascadeParams.from_closed_form(k_t, k_a, sulfurylase_per_s=k_s,
                                          dntp_clearance_per_s=0.0, polymerase_kpol_per_s=k_pol,
                                          **changes)


def paper_limit() -> CascadeParams:
    return CascadeParams.from_closed_form(1.0, 0.05, 0.88, sulfurylase_per_s=1e5,
                                          polymerase_kpol_per_s=1e5, volume_L=1e-6,
                                          apyrase_km_atp_M=1e-2, apyrase_km_dntp_M=1e-2)


def _reference_cases(quick: bool = False) -> dict[str, tuple]:
    """name: (params, dna_mol, template, flows, n_flows, period, edges, reference photons).
    ``quick``: 12 windows per linear case and one saturated flow (the 50-digit and rtol 1e-12
    references cost most of a quick run)."""
    cases = {}
    n_edges, sat_template, sat_flows = (12, "T", 1) if quick else (50, "TAAC", 4)
    for name, (p, dna_M, horizon) in {
        "k 1e-3…1e6 /s, 1e-18 M, 1e4 s": (linear(1e6, 1e5, 1.0, 1e-3), 1e-18, 1e4),
        "e^-t to 1e4 s (underflow)": (linear(1e3, 1e2, 1.0, 1.0), 1e-12, 1e4),
        "1e12 photons/s peak": (linear(1e3, 1e2, 1.0, 0.05, volume_L=2.0), 1e-12, 300.0),
    }.items():
        r = ref.linear_rates_of(p, dna_M)
        edges = np.concatenate([[0.0], np.geomspace(1e-4, horizon, n_edges)])
        want = ref.linear_photons(edges, dna_M, r["k_p"], r["k_s"], r["k_t"], r["k_a"],
                                  ref.photons_per_M(p))
        cases[name] = (p, dna_M * p.volume_L, "T", "T", 1, horizon, edges, want)
    edges = np.arange(0.0, 201.0)
    cases["paper's limit vs eq. 19"] = (paper_limit(), 1e-15, "A", "A", 1, 200.0, edges,
                                        np.diff(cf.pyrosequencing_photons(edges, 1e-15)))
    sat = CascadeParams(dntp_M=5e-3)
    edges = np.linspace(0.0, 150.0 * sat_flows, 15 * sat_flows + 1)
    tight = cascade_pyrosequencing([1e-12], sat_template, "TACG", sat_flows, 150.0, 0.0, sat,
                                   rtol=1e-12, method="Radau").photons(edges)[0]
    cases["1 mM, saturated (vs rtol 1e-12)"] = (sat, 1e-12, sat_template, "TACG", sat_flows,
                                                150.0, edges, tight)
    return cases


def error_table(methods, repeat: int, rtols=RTOLS, quick: bool = False) -> None:
    print("## Error vs solver tolerance vs wall time\n")
    print("rel = max relative error on windows holding > 1e-6 of the total; abs = max |error| / "
          "total photons; wall = build + photons(), median of", repeat, "(warm JIT)\n")
    print("| case | method | rtol | rel | abs | wall (ms) |")
    print("|---|---|---|---|---|---|")
    for name, (p, dna, tmpl, flows, n, period, edges, want) in _reference_cases(quick).items():
        big = want > 1e-6 * want.sum()
        for method in methods:
            for rtol in rtols:
                walls = []
                for _ in range(repeat):
                    t0 = time.perf_counter()
                    got = cascade_pyrosequencing([dna], tmpl, flows, n, period, 0.0, p,
                                                 rtol=rtol, method=method).photons(edges)[0]
                    walls.append(time.perf_counter() - t0)
                rel = np.max(np.abs(got[big] / want[big] - 1))
                err = np.max(np.abs(got - want)) / want.sum()
                print(f"| {name} | {method} | {rtol:.0e} | {rel:.1e} | {err:.1e} | "
                      f"{1e3 * float(np.median(walls)):.1f} |")
    print()


def per_flow(methods, repeat: int, rtols=(1e-6, 1e-8, 1e-10)) -> None:
    print("## Cascade wall time per flow: pyro_1fmol program (2 sites, 18 bases, 25 flows)\n")
    print("| method | rtol | wall per flow (ms) | steps per flow | build (s) |")
    print("|---|---|---|---|---|")
    for method in methods:
        for rtol in rtols:
            stats = []
            for _ in range(repeat):
                src = cascade_pyrosequencing([1e-15, 1e-15], TEMPLATE, FLOWS, N_FLOWS, PERIOD,
                                             START, rtol=rtol, method=method)
                stats.append(src.solver_stats())
            best = min(stats, key=lambda s: s["wall_per_flow_s"])
            print(f"| {method} | {rtol:.0e} | {1e3 * best['wall_per_flow_s']:.2f} | "
                  f"{best['steps'] / (N_FLOWS + 1):.0f} | {best['build_wall_s']:.3f} |")
    print()


def versus_closed_form() -> None:
    print("## Cascade vs closed form (eq. 19), 1 fmol per site, pyro_1fmol flow program\n")
    _, n_inc = flow_incorporations(TEMPLATE, FLOWS, N_FLOWS)
    edges = np.arange(0.0, START + N_FLOWS * PERIOD + 1.0)
    lit = n_inc > 0
    print("| reading | cascade params | total ratio | lit flows: ratio min / mean / max | "
          "peak rate cascade / eq. 19 |")
    print("|---|---|---|---|---|")
    ronaghi = fit_photon_yield(0.01, CascadeParams())
    for label, params, y in (("paper (17.6 / base)", CascadeParams(), None),
                             ("measured (0.01 / base)", ronaghi.params, 0.01)):
        casc = cascade_pyrosequencing([1e-15], TEMPLATE, FLOWS, N_FLOWS, PERIOD, START, params)
        closed = pyrosequencing([1e-15], n_inc, PERIOD, start_s=START,
                                photons_per_incorporation=y)
        a, b = casc.photons(edges)[0], closed.photons(edges)[0]
        fa = a[int(START):].reshape(N_FLOWS, -1).sum(axis=1)
        fb = b[int(START):].reshape(N_FLOWS, -1).sum(axis=1)
        ratio = fa[lit] / fb[lit]
        t = np.linspace(START, START + N_FLOWS * PERIOD, 30001)
        peak = casc.rate(t)[0].max() / closed.rate(t)[0].max()
        print(f"| {label} | {'defaults' if y is None else 'luciferase fitted'} | "
              f"{a.sum() / b.sum():.4f} | {ratio.min():.4f} / {ratio.mean():.4f} / "
              f"{ratio.max():.4f} | {peak:.4f} |")
    print()


def calibrated_yield() -> None:
    print("## Calibrated photon yield vs Ronaghi 2001 (≈ 0.01 photon per base)\n")
    p = CascadeParams()
    # 1. fit luciferase and apyrase to the paper's eq. 19 light curve, from 3× / ÷3 off
    t = np.linspace(0.5, 100.0, 40)
    start = replace(p, luciferase_M=3 * p.luciferase_M, apyrase_M=p.apyrase_M / 3)
    curve = fit_light_curve(t, cf.pyrosequencing_rate(t, 1e-15), start)
    y_curve = photon_yield(curve.params)
    # 2. fit luciferase to the measured yield
    meas = fit_photon_yield(0.01, p)
    print("| calibration target | fitted | residual | k_t (1/s) | k_a (1/s) | "
          "yield (photons/base) | / Ronaghi 0.01 |")
    print("|---|---|---|---|---|---|---|")
    for label, res, y in (("eq. 19 light curve, 1 fmol", curve, y_curve),
                          ("Ronaghi yield 0.01", meas, photon_yield(meas.params))):
        r = res.params.linear_rates()
        vals = ", ".join(f"{k} = {v:.3g}" for k, v in res.values.items())
        print(f"| {label} | {vals} | {res.residual:.1e} | {r['turnover_per_s']:.3g} | "
              f"{r['apyrase_atp_per_s']:.3g} | {y:.4g} | {y / 0.01:.3g} |")
    mass = meas.values["luciferase_M"] * 62e3 * 1e3  # 62 kDa firefly luciferase, in mg/L
    print(f"\nLuciferase for Ronaghi's yield: {meas.values['luciferase_M']:.3g} M ≈ {mass:.2g} "
          f"µg/mL (62 kDa); for the paper's k_t = 1 s⁻¹: {p.luciferase_M:.3g} M. 1 fmol gives "
          f"{0.01 * 1e-15 * N_A * 18:.3g} photons over the 18-base read at the measured yield.\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="LSODA, rtol 1e-6, one repeat")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--methods", nargs="+", default=["LSODA", "Radau", "BDF"])
    args = ap.parse_args(argv)
    rtols = {"rtols": (1e-6,)} if args.quick else {}
    if args.quick:
        args.repeat, args.methods = 1, ["LSODA"]
    t0 = time.perf_counter()
    cascade_pyrosequencing([1e-15], "TA", "TA", 2, 10.0)  # JIT compile / cache load
    print(f"first cascade call (numba compile or cache load): {time.perf_counter() - t0:.2f} s\n")
    per_flow(args.methods, args.repeat, **rtols)
    error_table(args.methods, args.repeat, **rtols, quick=args.quick)
    versus_closed_form()
    calibrated_yield()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
