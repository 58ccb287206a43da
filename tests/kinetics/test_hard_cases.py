"""Hard numerical cases of the cascade and the photon streams, each against an exact reference.

References: the cascade's linear regime solved in 50 digits (:mod:`chiptwin.kinetics.
cascade_reference`, mpmath eigen-decomposition: no underflow, no stiffness), or the same model at a
tightened tolerance where the kinetics are non-linear. Errors are measured per window: relative on
windows holding more than 1e-6 of the total photons, and absolute divided by the total photons
on every window (the solver controls the photon counter's error relative to the counter, so a
window far down a tail is accurate to ≈ rtol × total, not to rtol × itself).
``benchmarks/bench_cascade.py`` prints the same cases as a table of error vs solver tolerance vs
wall time.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from chiptwin.kinetics import PulseTrain
from chiptwin.kinetics import cascade_reference as ref
from chiptwin.kinetics.cascade import cascade_pyrosequencing
from chiptwin.kinetics.cascade_params import CascadeParams
from chiptwin.photons import arrival_times


def linear(k_s: float, k_pol: float, k_t: float, k_a: float, **changes) -> CascadeParams:
    """Cascade constants whose single incorporation is the linear system of the reference."""
    return CascadeParams.from_closed_form(k_t, k_a, sulfurylase_per_s=k_s,
                                          dntp_clearance_per_s=0.0, polymerase_kpol_per_s=k_pol,
                                          **changes)


# name: (params, template concentration M, horizon s)
CASES = {
    # k from 1e-3 (apyrase) to 1e6 s⁻¹ (sulfurylase), 1e-18 M template beside 1e-3 M APS and
    # luciferin, integrated over 1e4 s
    "stiff_1e-3_to_1e6_per_s_1e-18_M_1e4_s": (linear(1e6, 1e5, 1.0, 1e-3), 1e-18, 1e4),
    # apyrase 1 s⁻¹ over 1e4 s: the light falls as e^{-t}, far below the smallest double
    "underflow_exp_minus_1e4": (linear(1e3, 1e2, 1.0, 1.0), 1e-12, 1e4),
    # a 2 L "site" with 1 pM template: 1e12 photons/s at the peak
    "peak_1e12_photons_per_s": (linear(1e3, 1e2, 1.0, 0.05, volume_L=2.0), 1e-12, 300.0),
}


def window_errors(got: np.ndarray, want: np.ndarray) -> tuple[float, float]:
    """(max relative error on windows holding > 1e-6 of the total, max |error| / total)."""
    big = want > 1e-6 * want.sum()
    return (float(np.max(np.abs(got[big] / want[big] - 1))),
            float(np.max(np.abs(got - want)) / want.sum()))


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    params, dna_M, horizon = CASES[request.param]
    rates = ref.linear_rates_of(params, dna_M)
    edges = np.concatenate([[0.0], np.geomspace(1e-4, horizon, 50)])
    want = ref.linear_photons(edges, dna_M, rates["k_p"], rates["k_s"], rates["k_t"],
                              rates["k_a"], ref.photons_per_M(params))
    return request.param, params, dna_M, edges, want


@pytest.mark.parametrize(("rtol", "rel_tol", "abs_tol"), [(1e-8, 1e-3, 1e-7),
                                                          (1e-10, 1e-5, 1e-8)])
def test_window_photons_against_the_50_digit_reference(case, rtol, rel_tol, abs_tol):
    """Measured (LSODA) at rtol 1e-8: worst relative error 2.1e-4, abs/total 2.8e-8; at 1e-10:
    1.0e-6 and 1.5e-9. The tolerances are ≈ 5× those."""
    name, params, dna_M, edges, want = case
    src = cascade_pyrosequencing([dna_M * params.volume_L], "T", "T", 1, edges[-1], 0.0, params,
                                 rtol=rtol)
    got = src.photons(edges)[0]
    assert np.isfinite(got).all() and (got >= 0).all()
    rel, absolute = window_errors(got, want)
    assert rel < rel_tol, name
    assert absolute < abs_tol, name
    conc = src.concentrations(np.geomspace(1e-6, edges[-1], 400))
    assert all(np.isfinite(v).all() and (v >= 0).all() for v in conc.values())
    assert max(src.mass_balance().values()) < 10 * rtol


def test_peak_of_1e12_photons_per_s_matches_the_reference_rate():
    params, dna_M, _ = CASES["peak_1e12_photons_per_s"]
    rates = ref.linear_rates_of(params, dna_M)
    t = np.array([0.05, 0.1, 1.0, 10.0, 100.0])
    want = ref.linear_rate(t, dna_M, rates["k_p"], rates["k_s"], rates["k_t"], rates["k_a"],
                           ref.photons_per_M(params))
    src = cascade_pyrosequencing([dna_M * params.volume_L], "T", "T", 1, 300.0, 0.0, params)
    assert want.max() > 1e12
    np.testing.assert_allclose(src.rate(t)[0], want, rtol=1e-5)


def test_saturated_cascade_at_1_mM_against_a_tightened_tolerance():
    """1 mM template and 5 mM nucleotide per flow: ATP ≫ K_m(ATP), apyrase saturated, luciferin
    and APS run out (non-linear, no closed form). Default tolerance vs rtol 1e-12 (Radau): windows
    within 1e-5 of the brightest; no negative concentration; conservation laws hold."""
    p = CascadeParams(volume_L=1e-9, dntp_M=5e-3)
    dna_mol = 1e-3 * p.volume_L
    edges = np.linspace(0.0, 600.0, 61)
    tight = cascade_pyrosequencing([dna_mol], "TAAC", "TACG", 4, 150.0, 0.0, p, rtol=1e-12,
                                   method="Radau").photons(edges)[0]
    src = cascade_pyrosequencing([dna_mol], "TAAC", "TACG", 4, 150.0, 0.0, p)
    got = src.photons(edges)[0]
    assert np.max(np.abs(got - tight)) < 1e-5 * tight.max()
    conc = src.concentrations(np.linspace(0.0, 600.0, 2001))
    assert conc["luciferin"].min() < 0.1 * p.luciferin_M  # it ran out
    assert all(np.isfinite(v).all() and (v >= 0).all() for v in conc.values())
    assert max(src.mass_balance().values()) < 1e-7


@pytest.mark.parametrize("change", [{"luciferase_M": 0.0}, {"alpha": 0.0},
                                    {"sulfurylase_M": 0.0}, {"aps_M": 0.0}])
def test_zero_light_is_exactly_zero(change):
    p = replace(CascadeParams(), **change)
    src = cascade_pyrosequencing([1e-15], "TCAG", "TACG", 4, 30.0, 0.0, p)
    edges = np.linspace(0.0, 200.0, 41)
    assert (src.photons(edges) == 0).all()
    assert (src.rate(edges) == 0).all()
    assert max(src.mass_balance().values()) < 1e-7


def test_events_from_a_rate_spanning_1e_minus3_to_1e6_per_s_and_underflowing():
    """A 1e6 s⁻¹ flash (e^{-1e6 t} underflows after 1 ms) beside a 1e-3 s⁻¹ glow: arrival
    times stay in the window, and the rescaled intervals are Exp(1)."""
    src = PulseTrain(site=[0, 0], onset_s=[0.0, 0.0], amplitude_per_s=[5e9, 300.0],
                     decay_per_s=[1e6, 1e-3], n_sites=1)
    events = arrival_times(src, 0.0, 20.0, np.random.default_rng(99))
    t = events.pixel(0)
    assert np.isfinite(t).all() and t.min() >= 0.0 and t.max() <= 20.0
    tau = src.photons(np.concatenate([[0.0], t]))[0]
    assert tau.size > 8000
    assert stats.kstest(tau, "expon").pvalue > 1e-3
    early = np.searchsorted(t, 1e-4)
    assert abs(early - 5000.0) < 5 * np.sqrt(5000.0)  # the flash's 5e9 / 1e6 photons
