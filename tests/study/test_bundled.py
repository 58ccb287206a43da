"""The bundled studies' answers hold at reduced replicates (README "Studies" explains them).

Every study here runs in this process (``workers=1``: a row's numbers do not depend on the
executor, ``test_engine`` checks it). The pyro_1fmol rows whose metrics read only the key's
flows run 8 flows instead of 25 (:data:`tests.study.conftest.KEY_FLOWS`): the same rows, bit for
bit, at a third of the frames (checked below).
"""

from __future__ import annotations

import math

import pytest

from chiptwin.study import run_study
from chiptwin.study.engine import Plan
from chiptwin.study.rows import run_row
from tests.study.conftest import KEY_FLOWS, bundled_study

_bundled = bundled_study  # the name tests elsewhere import

FRAME_MEMORY_ANSWER = {"chip.memory.capacity_bits": 524288, "chip.dsp.average_frames": 1,
                       "chip.dsp.n_dark_frames": 16}
SMALL_MEMORY = {"chip.memory.capacity_bits": 131072, "chip.dsp.average_frames": 1,
                "chip.dsp.n_dark_frames": 4}


def test_eight_flows_give_the_rows_of_the_whole_run(frame_memory_result):
    """The premise of :data:`KEY_FLOWS`: a row of the 8-flow study has every metric of the same
    row run over all 25 flows (same seed, same chip), bit for bit: the SNR, the frames dropped,
    the memory peak, validity and the DSP's utilization."""
    def one_point(st):
        st["replicates"] = 1
        for axis in st["axis"]:
            axis["values"] = [SMALL_MEMORY[axis["key"]]]

    plan = Plan(bundled_study("frame_memory", one_point))  # the bundled 25 flows
    (point,) = plan.points
    whole = run_row(plan.tasks(point.id, range(1))[0])
    reduced = next(r for r in frame_memory_result.table
                   if r["point"] == point.id and r["replicate"] == 0)
    assert plan.scenarios[point.id].assay.n_flows == 25
    assert whole["status"] == reduced["status"] == "ok"
    assert whole["seed"] == reduced["seed"]
    assert whole["metrics"] == reduced["metrics"]


def test_frame_memory_answer_is_31_frames_with_16_dark_frames(frame_memory_result):
    """README: 524,288 bits (31 frames), N = 1, 16 dark frames; 7 frames cost ≈ 5 dB.

    The bundled grid, every point, at 2 replicates and 8 flows (``conftest._frame_memory`` gives
    the margins: ≥ 20 standard errors on both sides of 0.5 dB)."""
    result = frame_memory_result
    assert result.answer[0]["point"] == FRAME_MEMORY_ANSWER
    small = next(p for p in result.summary["points"] if p["params"] == SMALL_MEMORY)
    assert 4.0 < small["metrics"]["snr_loss_db"]["value"] < 6.0


# --- ADC bits -----------------------------------------------------------------------------------

#: Three replicates decide the comparisons at 1 fmol: there the per-replicate power SNR varies
#: little, the standard error of the loss is ≈ 4.34·cv·√(2/3) dB and the one-sided 95 % bound
#: sits t(0.95, 2) = 2.92 of them above the loss: 15 bits (loss ≈ 0.11 dB, bound ≈ 0.2 dB)
#: passes, 14 bits (0.54–0.56 dB) never does, and at 1 LSB of comparator noise 13 bits (0.26 dB,
#: bound 0.32 dB) passes while 12 bits (1.1 dB) fails by > 20 standard errors. At 0.1 fmol on the
#: chip as built the power SNR varies by 10–14 % a replicate (8 seeds of the 2 sites): three
#: bound the loss only to ≈ ±1 dB, so 15 bits passes or stays undecided by the draws (then 16
#: answers); the study's 90 replicates decide it.
ADC_REPLICATES = 3


def _adc(st, bits, amounts, comparator):
    st["replicates"] = ADC_REPLICATES
    st["search"] = "grid"
    st["set"].update(KEY_FLOWS)  # snr_loss_db reads the key's flows only
    st["axis"][0] = {"key": "chip.adc.bits", "values": bits}
    st["axis"][1]["values"] = amounts
    st["axis"][2]["values"] = comparator
    st["metric"] = [{"name": "snr_loss_db"}]
    st["requirement"] = {"snr_loss_db": "<= 0.5", "confidence": 0.95}


@pytest.fixture(scope="module")
def noiseless_adc():
    """adc_bits_pyro without comparator noise: bits 12 … 16 at both amounts, the rows both ADC
    tests read (a row's seed is its point's and replicate's, so they are the same rows in
    either test's study)."""
    study = bundled_study("adc_bits_pyro",
                          lambda st: _adc(st, [12, 13, 14, 15, 16], [1.0, 0.1], [0.0]))
    return run_study(study, workers=1)


def test_adc_bits_answer_is_15_bits_for_the_snr_loss(noiseless_adc):
    """The 0.5 dB SNR-loss requirement first holds at 15 bits (read noise 0.52 LSB) at 1 fmol
    (at 0.1 fmol three replicates leave 15 undecided or passing: :data:`ADC_REPLICATES`); 13 bits
    loses ≈ 3 dB at both amounts. Three replicates on bits 12 … 16 (the base-error part needs
    the full 90 replicates to bound 1e-3, so it is left out here)."""
    result = noiseless_adc
    answer = {a["given"]["assay.dna_fmol"]: a["point"]["chip.adc.bits"] for a in result.answer}
    assert answer[1.0] == 15 and answer[0.1] in (15, 16)
    loss13 = [p["metrics"]["snr_loss_db"]["value"] for p in result.summary["points"]
              if p["params"]["chip.adc.bits"] == 13]
    assert len(loss13) == 2 and all(2.5 < v < 3.7 for v in loss13)


def test_lod_bisection_answer_at_reduced_replicates():
    """README: 0.056 fmol at ≥ 99 % of reads; with an 80-read cap (looks of 40 reads) and a
    ≥ 90 % requirement the bisection lands on the same point or the one below it, visiting few
    points.

    The bundled chip with 20 sites instead of 2 (its two among them, the rest two pixels apart):
    each run reads 20 templates, so 2 runs a look and a cap of 4 runs give the reads of the
    README's 2 sites × 20 runs and 2 × 40 runs; the rates pool reads (Clopper-Pearson on k of n
    reads, plain at k = n: no design effect to measure), so every look has the same n, the same
    per-look confidence (1 − 0.05/2) and the same pass rule (40/40 reads: lower bound 0.912 ≥
    0.9) as there, for a quarter of the runs."""
    sites = [[4, 8], [2, 3]] + [[r, c] for r in (0, 2, 4, 6) for c in (1, 3, 8, 10, 13)
                                if [r, c] not in ([4, 8], [2, 3])]

    def edit(st):
        st["replicates"] = 4
        st["batch"] = 2
        st["set"] = {"sites.at_pixels": sites}
        st["requirement"] = {"calls_correct": ">= 0.9", "confidence": 0.95}

    result = run_study(bundled_study("lod_pyro", edit), workers=1)
    assert len(sites) == 20
    # the chip as built (isotropic light, the comparator's noise): the README's 0.1 fmol at
    # 99 %; the paper's idealised chip landed on 0.0316 or 0.0562
    assert result.answer[0]["point"]["assay.dna_fmol"] in (0.0562341, 0.1)
    visited = [p for p in result.summary["points"] if p["status"] != "not_visited"]
    assert len(visited) <= 7 and result.summary["monotonicity"]["violations"] == []


def test_comparator_noise_dithers_the_adc_bits_answer_down(noiseless_adc):
    """The comparator's noise is the dither the ideal converter lacked. At 1 fmol, a
    comparator of 1 LSB of 13 bits (122 µV rms) dithers the quantizer, so 13 bits meet the 0.5 dB
    loss against the 20-bit reference with the same comparator (loss ≈ 0.3 dB, 12 bits ≈ 1.1
    dB); without it 15 bits are needed and 13 bits lose ≈ 2.9 dB. The noise itself costs SNR:
    the 13-bit point's power SNR falls by more than 4 dB (≈ 163,000 → 43,000).

    The grid of bits 12 … 15 at 1 fmol: the noiseless half is the shared study's (each given
    combination is answered from its own points and reference alone), the 122.07 µV half runs
    here. Its 12- and 13-bit points are the converter-as-built's exact moments (white noise
    below 2 LSB), by the sawtooth's series (chiptwin.pixel.expected_adc): 1.6 s for the whole
    test, 14 s by Gauss–Hermite."""
    noisy = run_study(bundled_study("adc_bits_pyro",
                                    lambda st: _adc(st, [12, 13, 14, 15], [1.0], [122.07])),
                      workers=1)
    at_1fmol = [a for result in (noiseless_adc, noisy) for a in result.answer
                if a["given"]["assay.dna_fmol"] == 1.0]
    answer = {a["given"]["chip.adc.comparator_noise_uV"]: a["point"]["chip.adc.bits"]
              for a in at_1fmol}
    assert answer == {0.0: 15, 122.07: 13}
    snr = {(p["params"]["chip.adc.bits"], p["params"]["chip.adc.comparator_noise_uV"]):
           p["metrics"]["snr_power"]["value"]
           for result in (noiseless_adc, noisy) for p in result.summary["points"]
           if p["params"]["assay.dna_fmol"] == 1.0}
    assert 10 * math.log10(snr[13, 0.0] / snr[13, 122.07]) > 4.0
