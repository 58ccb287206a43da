"""``[chip.dsp] program``: validation (malformed programs exit 2 with one line), today's chain
unchanged, the stages' memory and cycles in the chip model, each new stage's fixed point against
its float reference within the analytic bound in the chip, and the propagated noise (covariance
of the spatial stages, variance of the kinetics stage) against Monte Carlo."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from chiptwin.chip import Schedule
from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.constants import s_to_ticks
from chiptwin.dsp.chain import chain_configs
from chiptwin.dsp.filters import KineticsConfig
from chiptwin.dsp.pipeline import Frame, Pipeline, chain_for
from chiptwin.dsp.program import (
    KINETICS_COEF,
    program_formats,
    program_load,
    stage_costs,
)
from chiptwin.dsp.program_pipeline import FIR_ALIGN, KineticsPlan, ProgramPipeline, _fir_rows
from chiptwin.fidelity import run
from chiptwin.twin.programs import program_pipeline, spatial_plan
from tests.conftest import SCENARIOS

SPATIAL = '["cms","dark","background","average","bin_rows","fir8","wiener"]'
KINETICS = '["cms","dark","background","kinetics"]'
#: A PSF wide enough to couple neighbours on the small chip (150 µm above 125 µm pixels).
WIDE = ["sites.height_um=150", "chip.dsp.bin_factor=2"]


def _prog(p: str) -> str:
    return f"chip.dsp.program={p}"


MALFORMED = [
    ([_prog('["cms","dark","background","average","blur"]')], "'blur': unknown DSP stage"),
    ([_prog('["dark","cms","background","average"]')], "stage 'cms' must come first"),
    ([_prog('["cms","background","average"]')], "stage 'dark' must come after cms"),
    ([_prog('["cms","dark","background"]')], "after background comes average or kinetics"),
    ([_prog('["cms","dark","background","average","kinetics"]')], "use one of them"),
    ([_prog('["cms","dark","background","average","wiener","fir8"]')], "order bin_rows, fir8"),
    ([_prog('["cms","dark","background","average","fir8","fir8"]')], "appears twice"),
    ([_prog('["cms","dark","background","average",3]')], "= 3: unknown DSP stage"),
    ([_prog(SPATIAL), "chip.dsp.mode=rtl"], "'bin_rows' has no RTL block"),
    ([_prog('["cms","dark","background","average","wiener"]'), "chip.dsp.mode=rtl"],
     "'wiener' has no RTL block"),
    ([_prog('["cms","dark","background","average","wiener"]'), "run.fidelity.optics=na2"],
     "stage 'wiener' equalizes the optics' coupling matrix"),
    ([_prog(KINETICS), "luciferase_label.toml"], "stage 'kinetics' weights frames"),
    ([_prog('["cms","dark","background","average","bin_rows"]'), "chip.dsp.bin_factor=3"],
     "chip.dsp.bin_factor = 3"),
    ([_prog(KINETICS), "chip.dsp.kinetics_acc_bits=20"],
     "chip.dsp.kinetics_acc_bits = 20: cannot hold one 34-bit product"),
    ([_prog(SPATIAL), "chip.memory.capacity_bits=1400"],
     "chip.memory.capacity_bits = 1400: must be ≥"),
]


@pytest.mark.parametrize("sets, needle", MALFORMED)
def test_malformed_programs_exit_2_with_one_line_and_write_nothing(small_toml, tmp_path,
                                                                    capsys, sets, needle):
    out = tmp_path / "out"
    files = [SCENARIOS / s for s in sets if s.endswith(".toml")]  # a bundled scenario instead
    argv = ["run", str(files[0] if files else small_toml), "--out", str(out)]
    for s in sets:
        if not s.endswith(".toml"):
            argv += ["--set", s]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert needle in err and "chip." in err
    assert not out.exists()


def test_default_program_schedule_is_todays_formula(small_toml):
    """The chain's schedule, by today's formula, for several chips: memory after the dark
    reference, the DSP time per frame from the stored words, no output cost, blocks of N."""
    for sets in ([], ["chip.dsp.cms_samples=4", "chip.dsp.average_frames=2"],
                 ["chip.dsp.cycles_per_sample=3.3", "chip.dsp.clock_hz=1e5"]):
        chip = load_scenario(small_toml, sets).chip
        sch = Schedule.from_chip(chip, 284.0)
        words = chip.n_pixels * chip.samples_per_frame
        assert sch.memory_frames == (chip.memory.capacity_bits
                                     - chip.memory.word_bits * chip.n_pixels) // chip.frame_bits
        assert sch.dsp_ns_per_frame == max(1, s_to_ticks(
            words * chip.dsp.cycles_per_sample / chip.dsp.clock_hz))
        assert (sch.dsp_ns_per_output, sch.block_frames) == (0, chip.dsp.average_frames)


def _frames(rng, mean, n, m=1, pedestal=200):
    """Frames whose CMS difference is exactly Poisson(mean): M reset samples at the pedestal."""
    p = len(mean)
    reset = np.full((n, m, p), pedestal, np.int64)
    signal = pedestal + rng.poisson(mean, (n, m, p))
    codes = np.concatenate([reset, signal], axis=1)
    return [Frame(codes=c, mean=mean.astype(float), var=mean.astype(float) / m) for c in codes]


def test_program_without_stages_is_the_chain_bit_for_bit(rng):
    """The program wrapper with nothing after the chain hands on the chain's outputs unchanged."""
    chain = chain_configs(13, 1, 4, 4)
    dark, light = np.full(12, 30.0), np.linspace(0, 5000, 12)
    a, b = Pipeline("fixed", chain), ProgramPipeline(Pipeline("fixed", chain), "fixed", None, None)
    dark_frames, blocks = _frames(rng, dark, 4), [_frames(rng, dark + light, 4) for _ in range(3)]
    a.dark(dark_frames)
    b.dark(dark_frames)
    for fr in blocks:
        x, y = a.block(fr), b.block(fr)
        for f in ("value", "mean", "var"):
            np.testing.assert_array_equal(getattr(x, f), getattr(y, f))
    np.testing.assert_array_equal(a.dark_var, b.dark_var)
    assert a.overflow == b.overflow


def test_stage_costs_reach_the_schedule(small_toml):
    """The Wiener table and buffers leave fewer frames of memory; the output cycles are the
    stages' cycles per pixel times their input pixels; kinetics frees each frame (jobs of 1)."""
    s = load_scenario(small_toml, [_prog(SPATIAL), *WIDE])
    chip = s.chip
    costs = stage_costs(chip)
    grid = (chip.rows // 2) * chip.cols
    fmts = program_formats(chip)
    assert costs["wiener"].memory_bits == grid * fmts.wiener_in.word_bits + grid**2 * 18
    assert costs["fir8"].memory_bits == 8 * fmts.fir.in_fmt.word_bits
    assert costs["bin_rows"].memory_bits == chip.cols * fmts.binning.out_fmt.word_bits
    load = program_load(chip)
    assert load.cycles_per_output == chip.n_pixels * 1 + grid * 8 + grid * grid
    sch = Schedule.from_chip(chip, s.run.duration_s)
    assert sch.memory_frames == (chip.memory.capacity_bits - load.resident_bits) \
        // chip.frame_bits
    assert sch.dsp_ns_per_output == s_to_ticks(load.cycles_per_output / chip.dsp.clock_hz)
    k = load_scenario(small_toml, [_prog(KINETICS)]).chip
    assert program_load(k).frames_per_job == 1
    assert stage_costs(k)["kinetics"].memory_bits == k.n_pixels * 44


def test_dsp_utilization_follows_the_program(small_toml):
    """The DSP's busy time is K dark frames, then per output N frames of front end plus the
    output stages; with a slow clock the program is flagged where the chain is not."""
    base = run(small_toml)
    prog = run(small_toml, [_prog(SPATIAL), *WIDE])
    sch = Schedule.from_chip(prog.scenario.chip, prog.scenario.run.duration_s)
    n_out = len(prog.arrays["block_t_s"])
    front = sch.dsp_ns_per_frame - -(-sch.dsp_ns_per_output // sch.block_frames)
    busy = (sch.dark_frames + n_out * sch.block_frames) * front + n_out * sch.dsp_ns_per_output
    active = sch.n_frames * sch.frame_period_ns
    assert prog.summary["chip"]["dsp_utilization"] == pytest.approx(busy / active, rel=1e-12)
    assert prog.summary["chip"]["dsp_utilization"] > base.summary["chip"]["dsp_utilization"]
    slow = ["chip.dsp.clock_hz=220"]  # chain: 192 cycles per 1 s frame; program: 258
    assert "dsp_cannot_keep_up" not in run(small_toml, slow).summary["chip"]["flags"]
    flagged = run(small_toml, [_prog(SPATIAL), *WIDE, *slow]).summary["chip"]["flags"]
    assert "dsp_cannot_keep_up" in flagged


def test_new_stages_fixed_within_their_bound_in_the_chip(small_toml):
    """Each stage's fixed-point output, on the input the chip gave it, against its float
    reference: within the analytic bound of :mod:`chiptwin.dsp.errors`, and not exact (the test
    could fail); the whole program's error is reported in summary['dsp']."""
    sets = ["chip.dsp.mode=fixed", "chip.dsp.report_error=true"]
    r = run(small_toml, [_prog(SPATIAL), *WIDE, *sets])
    k = run(small_toml, [_prog(KINETICS), *sets])
    bounds = {**r.summary["dsp_program"]["stage_error_bounds"],
              **k.summary["dsp_program"]["stage_error_bounds"]}
    assert set(bounds) == {"bin_rows", "fir8", "wiener", "kinetics"}
    for stage, b in bounds.items():
        assert b["bound_ok"] and b["max_abs_err_lsb"] <= b["bound_lsb"], stage
        assert b["outputs"] > 0
    assert bounds["fir8"]["max_abs_err_lsb"] > 0 and bounds["wiener"]["max_abs_err_lsb"] > 0
    assert bounds["bin_rows"]["max_abs_err_lsb"] == 0  # binning is exact
    for res in (r, k):
        assert res.summary["dsp"]["error_vs_float"]["outputs"] > 0
    regs = r.summary["dsp"]["registers"]
    assert {"bin_rows", "fir8", "wiener"} <= set(regs) and "kinetics" in k.summary["dsp"][
        "registers"]
    assert any(key.startswith("wiener.") for key in r.summary["dsp"]["overflow"])


@pytest.mark.parametrize("program, extra", [(SPATIAL, WIDE), (KINETICS, [])])
def test_stage_bounds_carried_to_the_output_bound_the_programs_error(small_toml, program, extra):
    """fixed − float of the whole program telescopes into each stage's own error passed through
    the float stages after it (linear: at most their ℓ∞ gain), so the chain's bound × its gain
    plus every stage's ``bound_at_output`` bounds the error measured at the program's output
    (the detection's units). The gains are not 1: the equalizer amplifies the errors before it
    (a sum of the stages' bounds in their own LSB, as fidelity.auto once took, is another
    number). Oracles for the gains: the designed equalizer's largest absolute row sum (what an
    error before it can grow by), the kinetics weights' Σ|c_j| times the window scale."""
    from chiptwin.fidelity.auto import Calibrations, _rounding_bound_lsb
    from chiptwin.twin.levels import reference_levels

    sets = [_prog(program), *extra, "chip.dsp.mode=fixed", "chip.dsp.report_error=true"]
    r = run(small_toml, sets)
    pipe = program_pipeline(r.scenario)
    fig = r.summary["dsp_program"]
    scale = fig.get("kinetics", {}).get("output_scale", 1.0)
    measured = (r.summary["dsp"]["error_vs_float"]["max_abs_err_lsb"] * pipe.out_fmt.lsb
                * scale)
    chain = _rounding_bound_lsb(chain_for(r.scenario.chip)) * fig["front_error_gain"]
    stages = fig["stage_error_bounds"]
    total = chain + sum(b["bound_at_output"] for b in stages.values())
    assert 0 < measured <= total
    # fidelity.auto's float-DSP level states this bound from its own run at the reference's
    # levels: within 4× of the error measured here (taking each stage's LSB as an ADC LSB, it
    # once said 19× for the spatial program, 7.6× for the kinetics one)
    calib = Calibrations(r.scenario, reference_levels(r.scenario), None)
    assert measured <= calib.calibrate("dsp", "float").errors["dsp_lsb"] <= 4 * measured
    if program == SPATIAL:
        g = pipe.spatial.wiener.g
        assert stages["wiener"]["gain_to_output"] == pytest.approx(1.0)
        assert stages["fir8"]["gain_to_output"] == pytest.approx(
            np.abs(g).sum(axis=1).max(), rel=1e-12) and stages["fir8"]["gain_to_output"] > 1.2
    else:
        c = pipe.kin.coefficients
        assert fig["front_error_gain"] == pytest.approx(np.abs(c).sum() * scale, rel=1e-12)
        assert stages["kinetics"]["gain_to_output"] == pytest.approx(scale, rel=1e-12)


def test_a_wrapped_stage_leaves_the_dsp_error_unbounded(small_toml):
    """A kinetics accumulator of 34 bits (allowed) under 100 photons an incorporation wraps: the
    stage's check reports its bound as not applicable (None, not True), and fidelity.auto's
    float-DSP level states no bound, naming the register (it once said 0.51 LSB against a
    measured 29,000)."""
    from chiptwin.fidelity.auto import Calibrations
    from chiptwin.twin.levels import reference_levels

    sets = [_prog(KINETICS), "chip.dsp.kinetics_acc_bits=34",
            "assay.photons_per_incorporation=100"]
    r = run(small_toml, [*sets, "chip.dsp.mode=fixed", "chip.dsp.report_error=true"])
    assert r.summary["dsp"]["overflow"]["kinetics.acc"]["wrap"] > 0
    assert r.summary["dsp_program"]["stage_error_bounds"]["kinetics"]["bound_ok"] is None
    s = load_scenario(small_toml, sets)
    est = Calibrations(s, reference_levels(s), None).calibrate("dsp", "float")
    assert est.errors["dsp_lsb"] == float("inf") and "kinetics.acc overflowed" in est.how


def test_fir_row_alignment_against_an_exact_oracle(small_toml, rng):
    """The FIR along each row, read FIR_ALIGN columns late: codes equal the exact sum
    ``Σ h_q[k] x[c + 4 − k]`` rounded RND (ties up) and saturated, on random rows, ties and
    full-scale rows."""
    s = load_scenario(small_toml, [_prog(SPATIAL), *WIDE, "chip.dsp.mode=fixed",
                                   "chip.dsp.rounding=RND"])
    pipe = program_pipeline(s)
    fir = pipe.spatial.formats.fir
    hq = np.array(fir.coef_codes, dtype=np.int64)
    cols, fmt = s.chip.cols, fir.in_fmt
    top = int(fmt.max_value * 2**fmt.frac_bits)
    x = rng.integers(-top - 1, top + 1, (50, cols))
    x[0], x[1] = top, -top - 1  # saturation corners
    x[2] = 0
    x[2, 2] = 1 << 14  # a product with exactly the half-LSB bit set in one tap: a tie
    out = _fir_rows(x, cols, lambda a: pipe._run("fir8", a, fir).codes)
    for row, y in zip(x, out, strict=True):
        for c in range(cols):
            acc = sum(int(hq[k]) * int(row[c + FIR_ALIGN - k]) for k in range(8)
                      if 0 <= c + FIR_ALIGN - k < cols)
            code = (acc + (1 << 14)) >> 15  # RND: ties toward +inf
            code = min(max(code, -top - 1), top)
            assert y[c] == code


def _kinetics_pipe(chain, t_s, k):
    cfg = KineticsConfig(t_s=t_s, k_per_s=k, in_fmt=chain.average.out_fmt,
                         coef_fmt=KINETICS_COEF)
    n = len(t_s)
    plan = KineticsPlan(cfg, np.zeros(n, np.int64), np.arange(n) == n - 1, 1.0)
    return ProgramPipeline(Pipeline("fixed", chain), "fixed", plan, None)


def test_kinetics_variance_equals_monte_carlo(rng):
    """The kinetics stage's propagated variance ``Σ c_j² var_j`` plus its dark share
    ``(Σ c_j)² σ²_dark`` against the spread of 400 seeds (fixed point), per pixel: within
    4.5 standard errors of a variance (√(2/(n−1)))."""
    chain = chain_configs(13, 1, 4, 1)
    t_s, k = tuple(float(i) for i in range(8)), 0.25
    dark = np.full(6, 40.0)
    amp = np.array([0, 50, 200, 1000, 3000, 6000.0])
    values, pred = [], None
    for _ in range(400):
        p = _kinetics_pipe(chain, t_s, k)
        p.dark(_frames(rng, dark, 4))
        out = None
        for t in t_s:
            out = p.block(_frames(rng, dark + amp * np.exp(-k * t), 1)) or out
        values.append(out.value)
        pred = out.var + p.dark_var
        mean = out.mean
    values = np.array(values)
    se = np.sqrt(2 / (len(values) - 1))
    assert np.all(np.abs(values.var(axis=0, ddof=1) / pred - 1) < 4.5 * se)
    assert np.all(np.abs(values.mean(axis=0) - mean) < 4.5 * np.sqrt(pred / len(values)))


def test_spatial_covariance_equals_monte_carlo(small_toml, rng):
    """bin_rows → fir8 → wiener correlate neighbouring cells: the propagated covariance
    ``L diag(var) Lᵀ`` (block noise plus the dark reference's) against the sample covariance
    of 400 seeds at the fixed level, every element within 5 standard errors
    (``√((σ_i² σ_j² + c_ij²)/n)``), and neighbours really correlated (|ρ| > 0.3 somewhere)."""
    s = load_scenario(small_toml, [_prog(SPATIAL), *WIDE, "chip.dsp.mode=fixed",
                                   "chip.dsp.cms_samples=1"])
    plan = spatial_plan(s)
    chain = chain_for(s.chip)
    p_pix = s.chip.n_pixels
    dark = np.full(p_pix, 40.0)
    light = 2000 * np.exp(-((np.arange(p_pix) % 6 - 2.5) ** 2) / 4)
    grids, cov = [], None
    for _ in range(400):
        pipe = ProgramPipeline(Pipeline("fixed", chain), "fixed", None, plan)
        pipe.dark(_frames(rng, dark, s.chip.dsp.n_dark_frames))
        out = pipe.block(_frames(rng, dark + light, s.chip.dsp.average_frames))
        grids.append(pipe.profiles[-1][1])
        if cov is None:
            cov = pipe.covariance(pipe.front_var + pipe.front.dark_var)
            mean = pipe.profiles[-1][3]
            assert np.array_equal(out.var, ((pipe._matrix**2) @ pipe.front_var)[
                plan.cell_of_pixel])  # each pixel reads its cell's variance
    g = np.array(grids)
    n = len(g)
    sample = np.cov(g, rowvar=False)
    sd = np.sqrt(np.diag(cov))
    se = np.sqrt((np.outer(sd, sd) ** 2 + cov**2) / n)
    assert np.all(np.abs(sample - cov) < 5 * se)
    rho = cov / np.outer(sd, sd)
    assert np.max(np.abs(rho - np.eye(len(rho)))) > 0.3
    assert np.all(np.abs(g.mean(axis=0) - mean) < 5 * sd / np.sqrt(n))


def test_pyro_1fmol_kinetics_on_chip_matches_the_float_matched_filter():
    """pyro_1fmol with the kinetics stage on chip (fixed point) calls the template, with each
    site's power SNR within 5 % of the float matched filter's (run.light_estimator =
    "matched" on today's chain)."""
    path = SCENARIOS / "pyro_1fmol.toml"
    matched = run(path, ["run.light_estimator=matched"])
    chip = run(path, [_prog(KINETICS), "chip.dsp.mode=fixed"])
    assert chip.summary["called_sequences"] == [matched.summary["true_sequence"]] * 2
    for a, b in zip(chip.summary["sites"], matched.summary["sites"], strict=True):
        assert a["snr_power"] == pytest.approx(b["snr_power"], rel=0.05)
    assert chip.summary["chip"]["memory_capacity_frames"] < matched.summary["chip"][
        "memory_capacity_frames"] or chip.summary["dsp_program"]["memory_bits"]["kinetics"] > 0


def test_kinetics_fixed_level_equals_float_level_within_bound(small_toml):
    """The same scenario at the float and fixed levels with the kinetics program: per-site
    figures agree to a fraction of the noise (the fixed point adds < 1 LSB per output)."""
    a = run(small_toml, [_prog(KINETICS)])
    b = run(small_toml, [_prog(KINETICS), "chip.dsp.mode=fixed"])
    for x, y in zip(a.summary["sites"], b.summary["sites"], strict=True):
        assert abs(x["signal_e"] - y["signal_e"]) < 0.05 * x["noise_e"]
        assert x["noise_e"] == pytest.approx(y["noise_e"], rel=1e-12)


def test_kinetics_program_replaces(small_toml):
    """Sanity of the replace() path used by program_formats: kinetics forces N = 1 in the
    front end, whatever average_frames is."""
    chip = load_scenario(small_toml, [_prog(KINETICS)]).chip
    assert program_formats(chip).front.average.n == 1
    assert program_formats(replace(chip, dsp=replace(chip.dsp, program=[
        "cms", "dark", "background", "average"]))).front.average.n == chip.dsp.average_frames


# --- the Wiener stage where zero forcing has no inverse (found by the mutation sweep) ----------


def _with_lambda(name: str, lam: float, **sites):
    s = load_scenario(SCENARIOS / f"{name}.toml")
    return replace(s, chip=replace(s.chip, dsp=replace(s.chip.dsp, wiener_noise_to_signal=lam)),
                   sites=replace(s.sites, **sites))


def test_minimum_pitch_skips_pitches_without_a_zero_forcing_equalizer():
    """ccd_two_wells at λ = 0: at 0.1 × its 24 µm pitch, 150 µm below the wells, every pixel of
    the 5 × 5 probe reads the same light, the Gram matrix is singular (LinAlgError before). That
    pitch is unresolved with the equalizer; the scan goes on to one where it exists."""
    from chiptwin.twin.programs import PITCH_SCAN, minimum_pitch

    s = _with_lambda("ccd_two_wells", 0.0)
    without, with_eq = minimum_pitch(s)
    assert with_eq is not None and with_eq > PITCH_SCAN[0] * s.chip.pitch_um
    assert without is None or with_eq <= without


def test_wiener_that_cannot_invert_the_grid_is_refused_naming_lambda(monkeypatch):
    """Zero forcing of a grid whose Gram matrix is exactly singular has no equalizer (numpy
    raises LinAlgError; seen in the minimum-pitch probe, not found on a bundled grid, so the
    design is made to fail here): the run is refused by λ's key, one line, not an internal
    error."""
    import chiptwin.twin.programs as programs
    from chiptwin.config import ScenarioError

    def singular(*_args, **_kw):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(programs, "design_wiener", singular)
    with pytest.raises(ScenarioError, match="chip.dsp.wiener_noise_to_signal = 0.0: stage "
                                            "'wiener' cannot invert this 128-cell grid"):
        spatial_plan(_with_lambda("crosstalk_microarray", 0.0))


def test_column_profile_plot_without_light_at_the_sites(tmp_path):
    """Found by the mutation test (ccd_two_wells, ``chip.pixel.capacitance_fF = 1e7``: no charge
    reaches a code): the profile's valley/peak is None and the plot's title said ``None:.2f``
    (TypeError, exit 1 after the run). It says there is no light instead."""
    from types import SimpleNamespace

    from chiptwin.twin.programs import program_plots

    s = load_scenario(SCENARIOS / "ccd_two_wells.toml")
    zero = np.zeros((1, s.chip.cols))
    result = SimpleNamespace(
        scenario=s, arrays={f"column_profile_{k}_e": zero for k in (
            "before", "after", "before_expected", "after_expected")},
        summary={"column_profile": {"valley_to_peak_before": None, "valley_to_peak_after": None}})
    assert [name for name, _ in program_plots(result, tmp_path)] == ["column_profile.png"]
    assert (tmp_path / "column_profile.png").stat().st_size > 0


def test_headline_when_no_scanned_pitch_resolves_neighbours(small_toml):
    """Found by an optics sweep of crosstalk_microarray (``sites.height_um = 1e4``): no pitch of
    the scan resolves a neighbour, minimum_pitch gives None, and the headline's ``None:.0f``
    failed the report after the run (TypeError, exit 1). It says so instead."""
    from chiptwin.report.outputs import headline

    cross = {"before_db_median": 2.0, "after_db_median": -1.0, "after_predicted_db_median": -1.0,
             "snr_cost_db_median": 3.0, "min_pitch_um_with": None, "min_pitch_um_without": None}
    summary = {**run(small_toml).summary, "crosstalk": cross}
    rows = dict(headline(summary))
    assert rows["neighbours resolved"] == "at no scanned pitch with the equalizer, at none without"
    cross.update(min_pitch_um_with=98.2, min_pitch_um_without=303.2)
    assert dict(headline(summary))["neighbours resolved"] == (
        "from 98 µm pitch with the equalizer, 303 µm without")
