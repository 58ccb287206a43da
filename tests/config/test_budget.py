"""The run budgets (chiptwin.config.budget): refusals name the keys and the limit; the estimates are
upper bounds of what runs hold and draw."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from chiptwin import limits
from chiptwin.cli import main
from chiptwin.config import budget as B
from chiptwin.config import load_scenario
from chiptwin.pixel.frames import POISSON_LAM_MAX
from chiptwin.twin import stages
from tests.conftest import IDEAL_ADC, REDUCED, SCENARIOS

# (what, scenario, overrides, key the one-line refusal names, words it says)
REFUSED = [
    ("frames beyond memory", "pyro_1fmol", ["run.duration_s=5e6"], "run.duration_s", "GiB"),
    ("pixels beyond memory", "pyro_1fmol",
     ["chip.rows=4096", "chip.cols=4096", "chip.memory.capacity_bits=1099511627776"],
     "chip.rows", "GiB"),
    ("sites × frames beyond memory", "pyro_1fmol",
     ['sites.at_pixels="all"', "chip.rows=512", "chip.cols=512",
      "chip.memory.capacity_bits=1099511627776"], "sites.at_pixels", "GiB"),
    ("light beyond the Poisson sampler", "pyro_1fmol",
     ["assay.dna_fmol=1e6", "assay.photons_per_incorporation=1e6"], "assay.dna_fmol", "Poisson"),
    ("flux beyond the Poisson sampler", "snr10_requirement",
     ["assay.photons_per_s_per_um2=1e12", "chip.pixel.diode_w_um=1e4",
      "chip.pixel.diode_h_um=1e4", "chip.pitch_um=1e4"], "assay.photons_per_s_per_um2", "Poisson"),
    ("hot dark current beyond the Poisson sampler", "pyro_1fmol",
     ["chip.pixel.dark_current_nA_per_cm2=1e4", "chip.pixel.temperature_C=200",
      "chip.pixel.dark_doubling_C=1"], "chip.pixel.dark_current_nA_per_cm2", "Poisson"),
    ("DSP work beyond the chip model's time", "pyro_1fmol",
     ["chip.dsp.cycles_per_sample=1e6", "chip.dsp.clock_hz=1e3"],
     "chip.dsp.cycles_per_sample", "1e+07 s"),
]


@pytest.mark.parametrize(("what", "scenario", "sets", "key", "words"), REFUSED,
                         ids=[r[0] for r in REFUSED])
def test_run_too_large_is_refused_before_it_starts(tmp_path, capsys, what, scenario, sets, key,
                                                    words):
    out = tmp_path / "out"
    argv = ["run", scenario, "--out", str(out), "--quiet"]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and key in err and words in err, err
    assert not out.exists()


def test_every_bundled_scenario_is_well_inside_the_budgets():
    """Every bundled scene fits the default memory budget with room: a quarter of it, but
    pyro_array_256, whose sparse coupling under its flow cell's lid is bounded by a 129² kernel
    a site (5.4 GB with the margin; a run's peak measured 2.4 GB), within it."""
    for path in sorted(SCENARIOS.glob("*.toml")):
        s = load_scenario(path)
        room = 1 if path.stem == "pyro_array_256" else 4
        assert B.MARGIN * sum(t.bytes for t in B.memory_estimate(s)) < (
            B.memory_budget_bytes() / room), path.stem
        assert sum(B.max_pixel_charge_e(s)) < B.POISSON_LAM_MAX / 1e6


def test_the_budget_follows_the_environment(monkeypatch, capsys):
    monkeypatch.setenv(B.MEMORY_BUDGET_ENV, "0.1")
    assert main(["validate", "pyro_1fmol"]) == 2
    assert "0.1 GiB budget" in capsys.readouterr().err
    monkeypatch.setenv(B.MEMORY_BUDGET_ENV, "lots")
    assert main(["validate", "pyro_1fmol"]) == 2
    assert B.MEMORY_BUDGET_ENV in capsys.readouterr().err
    monkeypatch.setenv(B.MEMORY_BUDGET_ENV, "64")
    assert main(["validate", "pyro_1fmol", "--set", "run.duration_s=5e6"]) == 0


def test_poisson_limit_is_the_pixel_stage_s():
    assert B.POISSON_LAM_MAX == POISSON_LAM_MAX
    rng = np.random.default_rng(0)
    rng.poisson(B.POISSON_LAM_MAX)
    with pytest.raises(ValueError):
        rng.poisson(np.nextafter(B.POISSON_LAM_MAX, np.inf) * 1.001)


@pytest.mark.parametrize(("name", "kinetics"), [
    ("pyro_1fmol", "closed_form"), ("atp_glow", "closed_form"),
    ("luciferase_label", "closed_form"), ("snr10_requirement", "closed_form"),
    ("ccd_100fmol", "closed_form"), ("pyro_1fmol", "cascade"), ("ccd_100fmol", "cascade")])
def test_charge_bound_is_above_every_pixel_frame(name, kinetics):
    """The bound the Poisson check uses is above the largest expected charge of a real run, and
    for the closed forms within a factor 100 of it (the cascade's bound is a whole flow's light:
    its rate has no closed form)."""
    from chiptwin.twin.runner import prepare

    s = load_scenario(SCENARIOS / f"{name}.toml", [f'run.fidelity.kinetics="{kinetics}"',
                                                   "chip.pixel.dark_current_nA_per_cm2=0"])
    scene = prepare(s)
    charge = scene.pixel_frames(s.chip.timing.t_int_s, 0.0).mean_e.max()
    light, dark = B.max_pixel_charge_e(s)
    assert dark == 0.0 and light >= charge > 0
    assert light < 100 * charge or kinetics == "cascade"


# (what, scenario, overrides): shapes that each stress one term of the estimate
SHAPES = [
    ("frames", "pyro_1fmol", ["chip.rows=1", "chip.cols=1", 'sites.at_pixels="centre"',
                              "assay.n_flows=100", "run.duration_s=6020"]),
    ("pixels", "pyro_1fmol", ["chip.rows=96", "chip.cols=96",
                              "chip.memory.capacity_bits=33554432", "assay.n_flows=8",
                              "run.duration_s=500"]),
    ("sites, dense psf", "pyro_1fmol", ["chip.rows=16", "chip.cols=16", 'sites.at_pixels="all"',
                                        "assay.n_flows=8", "run.duration_s=500"]),
    ("flux", "snr10_requirement", ["chip.rows=48", "chip.cols=48",
                                   "chip.memory.capacity_bits=33554432"]),
    ("dark block, M = 32", "pyro_1fmol", [
        "chip.rows=32", "chip.cols=32", "chip.dsp.cms_samples=32", "chip.dsp.n_dark_frames=64",
        "chip.adc.clock_hz=160e6", "chip.memory.capacity_bits=134217728", "assay.start_s=64",
        "assay.n_flows=8", "run.duration_s=544"]),
    # the converter as built through a DNL table: the quadrature in slices of QUAD_SLICE_VALUES
    # node values (a 1,024-frame block at 192 nodes was 25 M values whole: it once held 1.75 GB
    # where the estimate said 443 MiB). 40 e⁻ of read noise: kTC ≈ 10× the white rms, 185
    # nodes. Measured: 68 MiB traced against an estimate of 182 MiB; 265 MiB with the
    # quadrature unsliced (the test then fails)
    ("converter table", "pyro_1fmol", ["chip.adc.dnl_rms_lsb=0.2", "chip.pixel.read_noise_e=40",
                                       "assay.n_flows=8", "assay.flow_period_s=20",
                                       "run.duration_s=180"]),
]


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """Imports and JIT outside the measured runs: one small run of each scenario the shapes
    use (pyro_1fmol on 8 flows, snr10_requirement as bundled), and the converter-as-built
    shape's own run (its table and quadrature kernels). Each shape's peak after it is
    the peak after a warm-up run of that very shape, to 0.1 MiB, in either order of the
    shapes (measured: 16.4, 37.0, 19.9, 14.3 and 93.9 MiB); one warm-up instead of five
    saves ≈ 2.5 s a shape (a run's plots and optics summary)."""
    out = tmp_path_factory.mktemp("warm")
    runs = [(name, REDUCED.get(name, [])) for name in dict.fromkeys(n for _, n, _ in SHAPES)]
    # a converter as built runs kernels of its own (tables, quadrature): warmed by its shape
    runs += [(name, sets) for _, name, sets in SHAPES if any(s.startswith("chip.adc.")
                                                             for s in sets)]
    for i, (name, sets) in enumerate(runs):
        argv = [x for s in sets for x in ("--set", s)]
        assert main(["run", name, "--quiet", *argv, "--out", str(out / str(i))]) == 0


@pytest.mark.parametrize(("what", "scenario", "sets"), SHAPES, ids=[s[0] for s in SHAPES])
def test_memory_estimate_is_above_what_a_run_holds(tmp_path, warm, what, scenario, sets):
    """``tracemalloc``'s peak over ``chiptwin run`` (the interpreter and libraries excluded, as
    ``tracemalloc`` does) stays below the estimate without its base term."""
    argv = ["run", scenario, "--quiet"]
    for s in sets:
        argv += ["--set", s]
    s = load_scenario(SCENARIOS / f"{scenario}.toml", sets)
    estimate = B.MARGIN * sum(t.bytes for t in B.memory_estimate(s)[1:])
    tracemalloc.start()
    try:
        assert main([*argv, "--out", str(tmp_path / "out")]) == 0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    print(f"{what}: tracemalloc peak {peak / 2**20:.1f} MiB, estimate {estimate / 2**20:.1f} MiB")
    assert peak < estimate < 20 * peak + (64 << 20), (peak, estimate)


def test_sparse_kernel_radius_is_at_least_the_stage_s():
    """The estimate's kernel is no smaller than the one ``stages._sparse_coupling`` keeps."""
    s = load_scenario(SCENARIOS / "pyro_array_256.toml")
    c = stages.coupling(s)
    assert c.shape[0] * c.shape[1] > limits.DENSE_COUPLING_ENTRIES
    per_site = np.diff(c.tocsc().indptr).max()
    side = 2 * B._kernel_radius(s) + 1
    assert per_site <= side * side


def test_footprint_limit_converges():
    """At the largest footprint the rule allows (25 heights), the psf quadrature converges for
    the hardest diode found (10 µm under a 125 µm footprint, Lambertian)."""
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", [
        "sites.footprint_radius_um=125", f"sites.height_um={125 / B.FOOTPRINT_PER_HEIGHT_MAX}",
        "chip.pixel.diode_w_um=10", "chip.pixel.diode_h_um=10", 'sites.at_pixels="centre"',
        "optics.layers=[]"])  # one medium: its 14 µm oxide would not fit under 5 µm
    assert np.isfinite(stages.coupling(s)).all()
    with pytest.raises(Exception, match="height_um"):
        load_scenario(SCENARIOS / "pyro_1fmol.toml", [
            "sites.footprint_radius_um=125", "sites.height_um=4.9"])


@pytest.mark.parametrize(("name", "sets", "nodes"), [
    ("pyro_1fmol", IDEAL_ADC, None),  # the ideal converter
    ("pyro_1fmol", [], None),  # as built: a smooth bow, no DNL: the series answers
    ("pyro_1fmol", ["chip.adc.comparator_noise_uV=122.07"], None),  # the series answers
    ("pyro_1fmol", [*IDEAL_ADC, "chip.adc.dnl_rms_lsb=0.2"], 79),  # a table: the quadrature
    ("pyro_1fmol", ["chip.adc.dnl_rms_lsb=0.2"], 27),  # with the 0.5-LSB comparator: fewer
    ("ccd_two_wells", ["chip.adc.comparator_noise_lsb=128"], 27),  # the dark level near code 0
])
def test_the_quadrature_has_its_memory_term_and_its_cost(name, sets, nodes):
    """Where the converter as built goes through the quadrature the memory estimate counts its
    slices (QUADRATURE_ARRAYS × QUAD_SLICE_VALUES float64; tests/pixel/test_expected_adc.py holds
    a traced quadrature below it) and the wall estimate its nodes; nowhere else."""
    s = load_scenario(SCENARIOS / f"{name}.toml", sets)
    q = B.as_built_quadrature(s)
    assert (q.nodes if q else None) == nodes
    terms = [t.what for t in B.memory_estimate(s)]
    assert any("converter-as-built quadrature" in w for w in terms) == (q is not None), terms
    from chiptwin.config import cost

    as_built = [t.what for t in cost.wall_estimate(s) if "as built" in t.what]
    assert (f"{nodes} nodes" in as_built[0]) if q else (not as_built or "series" in as_built[0])


@pytest.mark.parametrize("film_um, n", [(0.1, 2.0), (10.0, 4.5)])
def test_film_table_term_is_above_what_the_tables_hold(film_um, n):
    """The raytrace level through a stack with a film: the estimate's film-table term is above
    the traced peak of building the tables (12.7 and 75 MiB measured for 0.1 µm of nitride and
    10 µm of index 4.5), and there is no such term at the psf level."""
    from chiptwin.optics.raytrace import _stack_arrays

    layers = (f'optics.layers=[{{name="buffer", n=1.33}}, {{name="film", n={n}, '
              f'thickness_um={film_um}}}, {{name="SiO2", n=1.46, thickness_um=12.0}}]')
    sets = [layers, "optics.silicon_n=4.3", 'optics.emitter="isotropic"',
            f"optics.thin_film_um={max(film_um, 2.0)}", "sites.height_um=30"]
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", [*sets, 'run.fidelity.optics="raytrace"'])
    term = [t.bytes for t in B.memory_estimate(s) if "thin-film tables" in t.what]
    stack = stages.optics_stack(s)
    tracemalloc.start()
    _stack_arrays(stack, stack.silicon_n)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert len(term) == 1 and peak < term[0]
    psf = load_scenario(SCENARIOS / "pyro_1fmol.toml", sets)
    assert not [t for t in B.memory_estimate(psf) if "thin-film tables" in t.what]
