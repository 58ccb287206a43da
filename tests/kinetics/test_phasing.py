"""Phasing model: hand-computed flows, conservation, and the cascade's incorporations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from chiptwin.kinetics import flow_incorporations
from chiptwin.kinetics.cascade import cascade_pyrosequencing
from chiptwin.kinetics.cascade_params import CascadeParams
from chiptwin.kinetics.phasing import phased_flows, run_lengths, template_indices

TEMPLATE = "TCAGGTTCCAAAGTCGAT"


def test_without_phasing_it_is_the_dispensation_program():
    _, inc, _ = phased_flows(TEMPLATE, "TACG", 25)
    np.testing.assert_array_equal(inc, flow_incorporations(TEMPLATE, "TACG", 25)[1])


def test_hand_computed_three_flows():
    """Template TAT, flows T, A, T, ε = 0.1, λ = 0.2, by the module docstring's rules.

    flow 0 (T): held ε at 0; the rest add T → {0: ε, 1: 1−ε}, bases 1−ε.
    flow 1 (A, prev T): from 0 only carried strands move (no A, then T): +1; from 1 normal
    strands add A (+1), carried add A then T (+2).
    flow 2 (T, prev A): from 0 normal +1, carried T then A +2; from 1 carried add A +1; from 2
    every active strand adds T (+1; nothing after it is A).
    """
    eps, lam = 0.1, 0.2
    act = 1 - eps
    _, inc, dist = phased_flows("TAT", "TA", 3, eps, lam)
    flow1 = act * (lam * eps + (1 - lam) * act + 2 * lam * act)
    after1 = [eps * (eps + act * (1 - lam)), eps * act + act * lam * eps,
              act * (1 - lam) * act, act * lam * act]
    flow2 = act * (after1[0] * (1 - lam + 2 * lam) + after1[1] * lam + after1[2])
    np.testing.assert_allclose(inc, [act, flow1, flow2], rtol=1e-14)
    np.testing.assert_allclose(dist[2], after1, rtol=1e-14)
    np.testing.assert_allclose(inc, [0.9, 0.99, 0.6912], rtol=1e-14)


def test_strands_are_conserved_and_bases_add_up():
    _, inc, dist = phased_flows(TEMPLATE, "TACG", 40, 0.003, 0.015)
    np.testing.assert_allclose(dist.sum(axis=1), 1.0, rtol=1e-14)
    positions = dist @ np.arange(len(TEMPLATE) + 1)
    np.testing.assert_allclose(np.cumsum(inc), positions[1:], rtol=1e-13)


def test_run_lengths():
    run = run_lengths(template_indices("AAGT"))
    np.testing.assert_array_equal(run[:, 0], [2, 1, 0, 0, 0])
    np.testing.assert_array_equal(run[:, 2], [0, 0, 1, 0, 0])


@pytest.mark.parametrize(("eps", "lam"), [(0.0, 0.0), (0.01, 0.0), (0.0, 0.02), (0.005, 0.015)])
def test_cascade_incorporations_equal_the_phasing_model(eps, lam):
    """Equivalence: with fast, complete extension (default Klenow, 60 s flows, dNTP cleared by
    apyrase to e⁻³⁰) the cascade's bases per strand and flow equal the discrete model's within
    1e-6."""
    p = replace(CascadeParams(), incomplete_extension=eps, carry_forward=lam)
    src = cascade_pyrosequencing([1e-15], TEMPLATE, "TACG", 25, 60.0, 0.0, p)
    _, want, _ = phased_flows(TEMPLATE, "TACG", 25, eps, lam)
    np.testing.assert_allclose(src.incorporations()[0], want, atol=1e-6)
    assert src.mass_balance()["nucleotide"] < 1e-8


def test_bad_rates_are_rejected():
    with pytest.raises(ValueError, match=r"carry_forward = 1.5 is out of range: must be in"):
        phased_flows("TA", "TA", 2, 0.0, 1.5)
    with pytest.raises(ValueError, match=r"initial has shape \(2,\)"):
        phased_flows("TA", "TA", 2, initial=[1.0, 0.0])
