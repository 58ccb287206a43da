"""The cascade level: kernels against slow references, the paper's limit, conservation, sources."""

from __future__ import annotations

from dataclasses import replace

import mpmath
import numpy as np
import pytest
from scipy import integrate

from chiptwin.constants import N_A
from chiptwin.kinetics import LightSource, flow_incorporations
from chiptwin.kinetics import _cascade_kernels as kern
from chiptwin.kinetics import closed_form as cf
from chiptwin.kinetics.cascade import CascadeSource, cascade_pyrosequencing
from chiptwin.kinetics.cascade_params import CascadeParams
from chiptwin.kinetics.cascade_solver import Layout, kernel_constants
from chiptwin.kinetics.phasing import template_indices

TEMPLATE = "TCAGGTTCCAAAGTCGAT"  # the headline scenario's: homopolymers up to 3
FLOWS = "TACG"


# --- slow, obvious reference of the right-hand side (the equations of the module docstring) --


def reference_rhs(y, tmpl, p: CascadeParams, dna_M: float) -> np.ndarray:
    """Michaelis–Menten cascade written out species by species, for y >= 0."""
    lay = Layout(tmpl.size)
    c = kernel_constants(p, dna_M)
    d, nuc = y[lay.strands], y[lay.nucleotide(0):lay.nucleotide(0) + 4]
    ppi, atp, so4, oxy, lamp = (y[i] for i in (lay.ppi, lay.atp, lay.so4, lay.oxy, lay.lamp))
    pol = np.array([c[0] * d[j] * nuc[b] / (p.polymerase_kd_dntp_M + nuc[b])
                    for j, b in enumerate(tmpl)])
    den = 1 + atp / p.apyrase_km_atp_M + nuc.sum() / p.apyrase_km_dntp_M
    v_atp = p.apyrase_kcat_atp_per_s * p.apyrase_M * atp / p.apyrase_km_atp_M / den
    v_nuc = p.apyrase_kcat_dntp_per_s * p.apyrase_M * nuc / p.apyrase_km_dntp_M / den
    aps = p.aps_M - so4
    v_s = (p.sulfurylase_kcat_per_s * p.sulfurylase_M * ppi / (p.sulfurylase_km_ppi_M + ppi)
           * aps / (p.sulfurylase_km_aps_M + aps))
    lh = p.luciferin_M - oxy - lamp
    k_lh = p.luciferase_km_luciferin_M
    if p.product_inhibition:
        k_lh *= 1 + oxy / p.ki_oxyluciferin_M + lamp / p.ki_lamp_M
    v_l = (p.luciferase_kcat_per_s * p.luciferase_M * atp / (p.luciferase_km_atp_M + atp)
           * lh / (k_lh + lh))
    f = p.lamp_fraction
    dy = np.zeros(y.shape, dtype=y.dtype)
    dy[lay.strands] = np.append(0.0, pol) - np.append(pol, 0.0)
    for n in range(4):
        dy[lay.nucleotide(n)] = -pol[tmpl == n].sum() - v_nuc[n]
        dy[lay.degraded(n)] = v_nuc[n]
    dy[lay.ppi] = pol.sum() - v_s + v_l
    dy[lay.atp] = v_s - v_l - v_atp
    dy[lay.so4] = v_s
    dy[lay.oxy] = dy[lay.q] = (1 - f) * v_l
    dy[lay.lamp] = f * v_l
    dy[lay.atpd] = v_atp
    return dy


def random_state(rng, tmpl, dna_M=1e-6) -> np.ndarray:
    """Positive state with every species at a different magnitude."""
    lay = Layout(tmpl.size)
    y = rng.uniform(0.1, 1.0, lay.n) * dna_M
    y[lay.nucleotide(0):lay.nucleotide(0) + 4] = rng.uniform(1e-7, 2e-5, 4)
    y[lay.oxy], y[lay.lamp] = 3e-7, 2e-9
    return y


FULL = replace(CascadeParams(), product_inhibition=True, lamp_fraction=0.2,
               luciferin_M=20e-6, aps_M=40e-6)


@pytest.mark.parametrize("params", [CascadeParams(), FULL], ids=["default", "inhibition"])
def test_rhs_matches_the_written_out_equations(params):
    tmpl = template_indices(TEMPLATE)
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = random_state(rng, tmpl)
        got = kern.rhs(y, tmpl, kernel_constants(params, 1e-6))
        want = reference_rhs(y, tmpl, params, 1e-6)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-25)


def finite_difference_jacobian(y, tmpl, params, dna_M) -> np.ndarray:
    """Central differences of :func:`reference_rhs` evaluated in 40-digit arithmetic (mpmath),
    step 1e-15 of each component: truncation and round-off both far below 1e-12."""
    with mpmath.workdps(40):
        base = np.array([mpmath.mpf(float(v)) for v in y], dtype=object)
        fd = np.zeros((y.size, y.size))
        for i in range(y.size):
            h = mpmath.mpf(1e-15) * max(abs(y[i]), 1e-6)
            up, dn = base.copy(), base.copy()
            up[i] += h
            dn[i] -= h
            diff = (reference_rhs(up, tmpl, params, dna_M)
                    - reference_rhs(dn, tmpl, params, dna_M)) / (2 * h)
            fd[:, i] = [float(v) for v in diff]
    return fd


@pytest.mark.parametrize("params", [CascadeParams(), FULL], ids=["default", "inhibition"])
def test_analytic_jacobian_matches_finite_differences(params):
    """Every entry within 1e-10 of its column's largest entry (a 40-digit reference)."""
    tmpl = template_indices(TEMPLATE)
    y = random_state(np.random.default_rng(5), tmpl)
    jac = kern.jacobian(y, tmpl, kernel_constants(params, 1e-6))
    fd = finite_difference_jacobian(y, tmpl, params, 1e-6)
    scale = np.abs(fd).max(axis=0) + 1e-300
    assert np.max(np.abs(jac - fd) / scale) < 1e-10


def test_params_validation_names_field_value_and_range():
    with pytest.raises(ValueError, match=r"luciferase_km_atp_M = 0.0 is out of range: must be > 0"):
        CascadeParams(luciferase_km_atp_M=0.0)
    with pytest.raises(ValueError, match=r"alpha = 1.5 is out of range: must be in \[0, 1\]"):
        CascadeParams(alpha=1.5)
    with pytest.raises(ValueError, match=r"apyrase_M = nan is out of range: must be finite"):
        CascadeParams(apyrase_M=float("nan"))
    with pytest.raises(ValueError, match=r"dntp_M = -1e-06 is out of range: must be >= 0"):
        CascadeParams(dntp_M=-1e-6)
    with pytest.raises(ValueError, match="product_inhibition"):
        CascadeParams(product_inhibition=1)
    with pytest.raises(ValueError, match=r"luciferase_kcat_per_s = 0.0 cannot give a first-order "
                                         r"rate of 1.0 1/s"):
        CascadeParams.from_closed_form(1.0, 0.05, luciferase_kcat_per_s=0.0)


def test_defaults_reproduce_the_papers_rate_constants():
    """sources.md Kinetics: k_t = 1 s⁻¹, k_a = 0.05 s⁻¹, α = 0.88 → 17.6 photons per base."""
    rates = CascadeParams().linear_rates()
    assert rates["turnover_per_s"] == pytest.approx(1.0, rel=1e-12)
    assert rates["apyrase_atp_per_s"] == pytest.approx(0.05, rel=1e-12)
    assert CascadeParams().linear_photons_per_incorporation() == pytest.approx(17.6, rel=1e-12)
    p = CascadeParams.from_closed_form(0.1, 0.2, 0.41)
    assert p.linear_rates()["turnover_per_s"] == pytest.approx(0.1, rel=1e-12)
    assert p.linear_photons_per_incorporation() == pytest.approx(0.41 * 0.1 / 0.2, rel=1e-12)


# --- the paper's limit -----------------------------------------------------------------------


def paper_limit(**changes) -> CascadeParams:
    """Fast polymerase and sulfurylase, every substrate far below its K_m (linear regime)."""
    return CascadeParams.from_closed_form(
        1.0, 0.05, 0.88, sulfurylase_per_s=1e5, polymerase_kpol_per_s=1e5, volume_L=1e-6,
        apyrase_km_atp_M=1e-2, apyrase_km_dntp_M=1e-2, **changes)


def test_papers_limit_matches_eqs_18_19_within_1_percent():
    """Validation, paper eqs. 18–19: I(t) = α N_A V k_t [DNA] e^{−k_a t} for 1 fmol; 5.3e8
    photons/s peak, 17.6 photons per base. Tolerance 1 % on every 1-s window of 0–100 s, on the
    rate at 50 times and on the total."""
    src = cascade_pyrosequencing([1e-15], "A", "A", 1, 400.0, 0.0, paper_limit())
    edges = np.arange(0.0, 101.0)
    want = np.diff(cf.pyrosequencing_photons(edges, 1e-15))
    np.testing.assert_allclose(src.photons(edges)[0], want, rtol=0.01)
    t = np.linspace(0.5, 100.0, 50)
    np.testing.assert_allclose(src.rate(t)[0], cf.pyrosequencing_rate(t, 1e-15), rtol=0.01)
    total = src.photons([0.0, 400.0])[0, 0]
    assert total == pytest.approx(17.6 * 1e-15 * N_A * (1 - np.exp(-20)), rel=0.01)
    assert src.rate([0.05])[0, 0] == pytest.approx(5.3e8, rel=0.01)


def test_homopolymer_light_scales_with_length_in_the_linear_regime():
    src = cascade_pyrosequencing([1e-15], "TAAAC", "TAC", 3, 400.0, 0.0, paper_limit())
    flows = src.flow_photons()[0]
    np.testing.assert_allclose(flows / flows[0], [1.0, 3.0, 1.0], rtol=1e-3)
    np.testing.assert_allclose(src.incorporations()[0], [1, 3, 1], rtol=1e-9)


# --- a 20-flow run: conservation, positivity, sources ------------------------------------------


@pytest.fixture(scope="module")
def run20() -> CascadeSource:
    """Two sites with different template and enzyme amounts, 20 flows, phasing and inhibition."""
    p = replace(CascadeParams(), incomplete_extension=0.01, carry_forward=0.02,
                product_inhibition=True, lamp_fraction=0.1)
    p2 = replace(p, luciferase_M=p.luciferase_M / 3, apyrase_M=p.apyrase_M * 2)
    return cascade_pyrosequencing([1e-15, 3e-16], TEMPLATE, FLOWS, 20, 30.0, 5.0, [p, p2])


def test_mass_balance_over_a_20_flow_run(run20):
    """Strands, pyrophosphate (PPi + ATP + hydrolysed ATP = bases), nucleotides (free +
    hydrolysed + incorporated = dispensed), sulfate (= ATP made) and light (Σ photon counters =
    oxyluciferin) are conserved to 1e-7 of their scale at rtol = 1e-8."""
    worst = run20.mass_balance()
    assert set(worst) == {"strands", "pyrophosphate", "nucleotide", "sulfate", "light"}
    assert max(worst.values()) < 1e-7, worst


def test_concentrations_never_negative_and_finite(run20):
    t = np.linspace(0.0, 700.0, 3001)
    conc = run20.concentrations(t)
    for name, values in conc.items():
        assert np.isfinite(values).all(), name
        assert (values >= 0).all(), name
    rate = run20.rate(t)
    assert np.isfinite(rate).all() and (rate >= 0).all()
    assert (rate[:, t < 5.0] == 0).all()  # dark before the first dispensation


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
def test_source_is_a_light_source_and_photons_integrate_its_rate(run20):
    assert isinstance(run20, LightSource)
    assert run20.n_sites == 2
    edges = np.array([0.0, 4.0, 5.0, 5.3, 12.0, 35.0, 36.0, 64.9, 200.0])
    got = run20.photons(edges)
    for s in range(2):
        for i in range(edges.size - 1):
            pts = run20.breakpoints_s[(run20.breakpoints_s > edges[i])
                                      & (run20.breakpoints_s < edges[i + 1])]
            want, _ = integrate.quad(lambda t, s=s: run20.rate([t])[s, 0], edges[i],
                                     edges[i + 1], points=pts, limit=200, epsrel=1e-10)
            assert got[s, i] == pytest.approx(want, rel=1e-5, abs=1e-6 * got[s].max())
    assert got[:, 0].sum() == 0.0


def test_photons_are_additive_over_windows(run20):
    edges = np.linspace(0.0, 650.0, 1301)
    fine = run20.photons(edges)
    coarse = run20.photons(edges[::10])
    np.testing.assert_allclose(fine.reshape(2, -1, 10).sum(axis=2), coarse, rtol=1e-9)


def test_per_site_enzyme_amounts_are_used():
    """Site 1 has a third of the luciferase, twice the apyrase and 0.3× the template: in the
    linear regime 0.3 / 6 of site 0's photons (yield α k_t / k_a)."""
    p = paper_limit()
    p1 = replace(p, luciferase_M=p.luciferase_M / 3, apyrase_M=p.apyrase_M * 2)
    src = cascade_pyrosequencing([1e-15, 3e-16], "T", "T", 1, 1000.0, 0.0, [p, p1])
    total = src.flow_photons()[:, 0]
    assert total[1] / total[0] == pytest.approx(0.3 / 6, rel=2e-3)


def test_product_inhibition_dims_the_light(run20):
    """L-AMP (K_i 3.8 nM, sources.md Kinetics) formed in 10 % of turnovers inhibits luciferase: the
    later flows of the inhibited run give less light per incorporated base than the first."""
    per_base = run20.flow_photons()[0] / np.maximum(run20.incorporations()[0], 1e-9)
    lit = run20.incorporations()[0] > 0.5
    assert per_base[lit][-1] < 0.5 * per_base[lit][0]


def test_identical_sites_share_one_solution_and_times_past_the_run_extend_it():
    src = cascade_pyrosequencing([1e-15] * 4, "TA", "TA", 2, 20.0, 0.0)
    assert src.solver_stats()["n_unique_sites"] == 1
    late = src.photons([0.0, 40.0, 200.0, 2000.0])
    assert (late[0] == late[3]).all() and late[0, 2] < late[0, 1]
    assert src.rate([1900.0])[0, 0] > 0  # apyrase still removing the last ATP


def test_incorporations_match_the_dispensation_program():
    src = cascade_pyrosequencing([1e-15], TEMPLATE, FLOWS, 25, 60.0)
    _, n_inc = flow_incorporations(TEMPLATE, FLOWS, 25)
    np.testing.assert_allclose(src.incorporations()[0], n_inc, atol=1e-6)


def test_zero_template_gives_exactly_no_light():
    src = cascade_pyrosequencing([0.0, 1e-15], TEMPLATE, FLOWS, 4, 10.0)
    assert (src.photons([0.0, 5.0, 40.0])[0] == 0).all()
    assert (src.rate([1.0, 20.0])[0] == 0).all()
    assert src.photons([0.0, 40.0])[1, 0] > 0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dna_mol": [[1e-15]]}, r"dna_mol has shape \(1, 1\)"),
        ({"template": "TCAX"}, r"template has 'X' at position 3"),
        ({"flow_period_s": 0.0}, r"flow_period_s = 0.0 is out of range"),
        ({"rtol": 1e-1}, r"rtol = 0.1 is out of range"),
        ({"method": "RK45"}, r"method = 'RK45' is not one of"),
        ({"params": [CascadeParams()] * 3}, r"one per site\); got 3 items"),
        ({"start_s": [0.0, 1.0, 2.0]}, r"start_s has shape \(3,\)"),
    ],
)
def test_builder_rejects_bad_input(kwargs, match):
    args = {"dna_mol": [1e-15, 2e-15], "template": "TCAG", "flow_order": "TACG", "n_flows": 4,
            "flow_period_s": 10.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        cascade_pyrosequencing(**args)


def test_window_edges_must_be_non_decreasing():
    src = cascade_pyrosequencing([1e-15], "T", "T", 1, 10.0)
    with pytest.raises(ValueError, match=r"t_edges_s\[2\] = 1.0 < t_edges_s\[1\] = 2.0"):
        src.photons([0.0, 2.0, 1.0])
