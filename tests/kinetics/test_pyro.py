"""The pyrosequencing dispensation program, key normalisation and base calling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chiptwin.kinetics import pyro, sources

# (template, flow order, n_flows, expected counts)
FLOW_TABLE = [
    ("TCAG", "TACG", 8, [1, 0, 1, 0, 0, 1, 0, 1]),
    ("TTTCAAAAG", "TACG", 8, [3, 0, 1, 0, 0, 4, 0, 1]),
    ("GGG", "TACG", 4, [0, 0, 0, 3]),
    ("ACGT", "ACGT", 6, [1, 1, 1, 1, 0, 0]),
    ("AAAA", "A", 3, [4, 0, 0]),
    ("", "TACG", 3, [0, 0, 0]),
    ("tcag", "tacg", 2, [1, 0]),
    ("TCAG", "TACG", 0, []),
]


@pytest.mark.parametrize(("template", "order", "n_flows", "counts"), FLOW_TABLE)
def test_flow_incorporations_table(template, order, n_flows, counts):
    """Homopolymers incorporate fully in one flow; unmatched flows add nothing."""
    nucleotides, n = pyro.flow_incorporations(template, order, n_flows)
    assert n.dtype == np.int64
    assert n.tolist() == counts
    assert nucleotides == [order.upper()[k % len(order)] for k in range(n_flows)]


def test_flows_to_sequence_and_key_counts():
    assert pyro.flows_to_sequence("TCAG", "TACG") == 8
    assert pyro.flows_to_sequence("", "TACG") == 0
    assert pyro.key_flow_counts("TCAG", "TACG").tolist() == [1, 0, 1, 0, 0, 1, 0]
    with pytest.raises(ValueError, match="never dispenses G"):
        pyro.flows_to_sequence("GA", "TAC")
    with pytest.raises(ValueError, match="no 1-mer flow"):
        pyro.key_flow_counts("AAT", "AT")


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (("TCNG", "TACG", 4), r"template has 'N' at position 2: only A, C, G, T"),
        (("TCAG", "TAUG", 4), r"flow_order has 'U' at position 2"),
        (("TCAG", "", 4), r"flow_order = '' is empty"),
        (("TCAG", "TACG", -1), r"n_flows = -1 .*int >= 0"),
        (("TCAG", "TACG", 2.0), r"n_flows = 2.0"),
        ((b"TCAG", "TACG", 2), r"template = b'TCAG' must be a string"),
    ],
)
def test_flow_incorporations_errors(args, match):
    with pytest.raises(ValueError, match=match):
        pyro.flow_incorporations(*args)


def test_normalise_flows_with_the_454_key():
    key = pyro.key_flow_counts(pyro.KEY_454, pyro.FLOW_ORDER_454)
    _, n = pyro.flow_incorporations("TCAGGTTAC", pyro.FLOW_ORDER_454, 16)
    raw = np.vstack([n * 7.0e5 + 100.0, n * 3.0e5 + 100.0])  # two sites, a 100-photon baseline
    out = pyro.normalise_flows(raw, key, subtract_zero_mer=True)
    np.testing.assert_allclose(out, np.vstack([n, n]), atol=1e-12)
    plain = pyro.normalise_flows(n * 2.0, key)
    np.testing.assert_allclose(plain, n, atol=1e-15)


@pytest.mark.parametrize(
    ("values", "key", "kwargs", "match"),
    [
        ([0.0] * 8, [1, 0, 1], {}, r"1-mer reference is 0.0 at site 0"),
        ([1.0] * 8, [0, 0], {}, r"key_n_expected = \[0, 0\] .*contain at least one 1"),
        ([1.0] * 2, [1, 0, 1], {}, r"no longer than the 2 flows"),
        ([1.0] * 8, [1, 1], {"subtract_zero_mer": True}, r"needs a key flow with expected count 0"),
        ([[[1.0]]], [1], {}, r"flow_values has shape \(1, 1, 1\)"),
    ],
)
def test_normalise_flows_errors(values, key, kwargs, match):
    with pytest.raises(ValueError, match=match):
        pyro.normalise_flows(values, key, **kwargs)


def test_call_sequence_rounds_half_up_and_clips_negatives():
    called, n = pyro.call_sequence(list("TACGT"), [0.49, 0.5, 2.49, -0.7, 1.51])
    assert n.tolist() == [0, 1, 2, 0, 2]
    assert called == "ACCTT"
    with pytest.raises(ValueError, match=r"flow_values has shape \(2,\): must be \(3,\)"):
        pyro.call_sequence(list("TAC"), [1.0, 2.0])
    with pytest.raises(ValueError, match=r"flow_nucleotides\[1\] = 'AC'"):
        pyro.call_sequence(["T", "AC"], [1.0, 2.0])
    with pytest.raises(ValueError, match=r"flow_values = nan"):
        pyro.call_sequence(["T"], [np.nan])


def test_call_sequence_caps_a_flow_at_the_sff_range():
    """A 1-mer reference barely above zero divides a flow into 2e16 (lod_pyro at 0.001 fmol
    once raised MemoryError spelling it): the call stops at 655, the SFF flowgram's top."""
    called, n = pyro.call_sequence(list("TAC"), [2e16, 655.4, 654.6])
    assert n.tolist() == [655, 655, 655] == [pyro.CALL_MAX_N] * 3
    assert called == "T" * 655 + "A" * 655 + "C" * 655


@settings(max_examples=200, deadline=None)
@given(
    insert=st.text(alphabet="ACGT", min_size=0, max_size=40),
    order=st.sampled_from(["TACG", "ACGT", "GATC", "TCAGA"]),
    noise=st.floats(-0.45, 0.45),
)
def test_round_trip_template_to_light_to_call(insert, order, noise):
    """Key + insert → flow counts → eq. 19 light per flow → key normalisation → calls = template.

    The light of each flow is integrated over its own flow period (60 decay times, so the
    carry-over into the next flow is e^-60 and invisible), plus a bounded per-flow error < 0.5.
    """
    template = pyro.KEY_454 + insert
    n_flows = pyro.flows_to_sequence(template, order) + 3
    nucleotides, n = pyro.flow_incorporations(template, order, n_flows)
    period = 60.0 / 0.05
    train = sources.pyrosequencing([1e-15], n, period)
    edges = np.arange(n_flows + 1) * period
    photons = train.photons(edges)[0]
    key = pyro.key_flow_counts(pyro.KEY_454, order)
    values = pyro.normalise_flows(photons, key)
    wobble = noise * np.cos(np.arange(n_flows))
    called, called_n = pyro.call_sequence(nucleotides, values + wobble)
    assert called == template
    assert called_n.tolist() == n.tolist()
