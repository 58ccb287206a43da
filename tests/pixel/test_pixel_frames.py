"""chiptwin.pixel.binned_codes (many frames in one kernel call) against its slow obvious reference,
sample_frame → to_volts → adc_convert called frame after frame on the same Generator: the same
codes bit for bit and the Generator left in the same state (equivalence tests)."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.pixel import adc_convert, binned_codes, read_out, sample_frame, to_volts

READOUT = dict(conversion_gain_uV_per_e=0.16, pedestal_V=0.1, bits=13, v_min_V=0.0, v_max_V=1.0)


def slow_codes(rng, mean_e, *, full_well_e, ktc_e, read_noise_e, n_samples, true_cds,
               conversion_gain_uV_per_e, pedestal_V, bits, v_min_V, v_max_V, offset_lsb=0.0,
               gain_error=0.0, report_pixels=(), report_e=None):
    """Frame by frame through the public functions, as the chip model read frames before; the
    counts of ``report_pixels`` before the full-well clip written to ``report_e``."""
    frames = []
    for k, lam in enumerate(mean_e):
        if len(report_pixels):
            counts = rng.poisson(lam)
            report_e[k] = counts[list(report_pixels)]
            samples = read_out(rng, np.minimum(counts, full_well_e), ktc_e, read_noise_e,
                               n_samples, true_cds)
        else:
            samples = sample_frame(rng, lam, 1.0, 1.0, 0.0, full_well_e, ktc_e, read_noise_e,
                                   n_samples, true_cds)
        volts = to_volts(np.concatenate(samples), conversion_gain_uV_per_e, pedestal_V)
        frames.append(adc_convert(volts, bits, v_min_V, v_max_V, offset_lsb, gain_error))
    return np.array(frames, dtype=np.int64).reshape(len(mean_e), 2 * n_samples, -1)


def _mean_e(n_frames=40, n_pixels=23):
    """Means across the sampler's branches (0, < 10, ≥ 10, huge) and past the full well."""
    rng = np.random.default_rng(3)
    lam = rng.uniform(0.0, 3e4, (n_frames, n_pixels))
    lam[0, :7] = [0.0, 1e-3, 5.0, 9.999999, 10.0, 2.5e5, 1e7]
    return lam


CASES = [
    dict(full_well_e=6e6, ktc_e=400.0, read_noise_e=100.0, n_samples=4, true_cds=True),
    dict(full_well_e=2e4, ktc_e=40.0, read_noise_e=6.0, n_samples=3, true_cds=False),
    dict(full_well_e=2e4, ktc_e=0.0, read_noise_e=6.0, n_samples=1, true_cds=False),
    dict(full_well_e=1e5, ktc_e=40.0, read_noise_e=0.0, n_samples=2, true_cds=True,
         offset_lsb=0.37, gain_error=-0.013),
    dict(full_well_e=2e4, ktc_e=40.0, read_noise_e=6.0, n_samples=2, true_cds=True,
         report_pixels=[2, 5, 6]),
]


#: An 8-bit ADC whose range the charge overruns and whose zero sits on the reset level: codes
#: clip at both ends.
CLIPPING = dict(conversion_gain_uV_per_e=60.0, pedestal_V=0.0, bits=8, v_min_V=0.0, v_max_V=1.0)


@pytest.mark.parametrize("case", CASES, ids=["pyro", "no-cds", "no-ktc", "errors", "report"])
@pytest.mark.parametrize("readout", [READOUT, CLIPPING], ids=["13-bit", "8-bit-clipping"])
def test_codes_are_those_of_the_frame_by_frame_path(case, readout):
    """Identical codes (in uint16, the narrowest type that holds them) and the same Generator
    state after; reported pixels get their counts before the clip (pixel 6 is past the full
    well in frame 0) and their codes are those of a call that reports nothing."""
    kw = {**case, **readout}
    reported = "report_pixels" in kw
    if reported:
        kw["report_e"] = np.full((40, 3), -1.0)
        expected = np.full((40, 3), -2.0)
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    ref = slow_codes(a, _mean_e(), **{**kw, **({"report_e": expected} if reported else {})})
    got = binned_codes(b, _mean_e(), **kw)
    assert got.dtype == np.uint16 and got.shape == ref.shape
    assert np.array_equal(got, ref)
    assert a.bit_generator.state == b.bit_generator.state
    if reported:
        assert np.array_equal(kw["report_e"], expected)
        assert kw["report_e"][0, 2] > case["full_well_e"]
        plain = {k: v for k, v in kw.items() if not k.startswith("report")}
        assert np.array_equal(binned_codes(np.random.default_rng(9), _mean_e(), **plain), got)
    if readout is CLIPPING:
        assert (got == 255).any() and (got == 0).any()


def test_codes_past_16_bits_are_uint32():
    """A 20-bit converter's codes above 2¹⁶ are kept exactly, in uint32."""
    kw = {**CASES[0], **READOUT, "bits": 20, "pedestal_V": 0.5}
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    got = binned_codes(b, _mean_e(), **kw)
    assert got.dtype == np.uint32 and got.max() > 2**16
    assert np.array_equal(got, slow_codes(a, _mean_e(), **kw))


def test_batches_draw_what_one_call_draws():
    """Frames drawn in batches, one after another on one Generator: the same codes as one call."""
    kw = {**CASES[0], **READOUT}
    whole = binned_codes(np.random.default_rng(4), _mean_e(), **kw)
    rng = np.random.default_rng(4)
    parts = [binned_codes(rng, part, **kw) for part in np.split(_mean_e(), [1, 7, 30])]
    assert np.array_equal(np.concatenate(parts), whole)


@pytest.mark.parametrize(("kw", "name"), [
    (dict(mean_e=[[-1.0]]), "mean_e"),
    (dict(mean_e=[1.0, 2.0]), "mean_e"),
    (dict(full_well_e=0.0), "full_well_e"),
    (dict(ktc_e=-1.0), "ktc_e"),
    (dict(n_samples=0), "n_samples"),
    (dict(bits=30), "bits"),
    (dict(v_max_V=0.0), "v_max_V"),
    (dict(gain_error=-1.0), "gain_error"),
    (dict(report_pixels=[3]), "report_pixels"),
    (dict(report_pixels=[0]), "report_e"),
    (dict(report_pixels=[0], report_e=np.zeros((1, 2))), "report_e"),
])
def test_bad_arguments_raise_naming_them(kw, name):
    args = {"mean_e": [[1.0, 2.0]], **CASES[0], **READOUT, **kw}
    with pytest.raises(ValueError, match=name):
        binned_codes(np.random.default_rng(0), **args)


def _window_totals(codes, m):
    """Per pixel, the sum over frames of the CDS differences (signal codes − reset codes)."""
    c = codes.astype(np.int64)
    return (c[:, m:, :].sum(axis=1) - c[:, :m, :].sum(axis=1)).sum(axis=0)


def test_normals_on_their_own_stream_are_common_to_shot_levels():
    """With ``normal_rng`` the kTC and read-noise normals are the same draws whatever the counts
    drew: a dim, read-noise-limited array (2 e⁻ a frame, 8 e⁻ read noise) at the poisson and the
    gaussian shot level, on the same streams, differs by the counts alone, its paired
    difference's spread ≥ 5× narrower than on independent streams; and the normals' stream
    is left where the kernel's draws leave it whatever the counts' law."""
    from chiptwin.fidelity.compare import mean_difference

    kw = dict(full_well_e=2e4, ktc_e=40.0, read_noise_e=8.0, n_samples=1, true_cds=True,
              **READOUT)
    lam = np.full((20, 400), 2.0)

    def totals(shot, count_seed, normal_seed):
        normal = np.random.default_rng(normal_seed)
        codes = binned_codes(np.random.default_rng(count_seed), lam, shot_noise=shot,
                             normal_rng=normal, **kw)
        return _window_totals(codes, 1), normal.bit_generator.state

    ref, ref_state = totals("poisson", 1, 2)
    common, common_state = totals("gaussian", 1, 2)
    independent, _ = totals("gaussian", 3, 4)
    assert common_state == ref_state  # the normals drew the same, whatever the counts did
    paired = mean_difference(common - ref)
    unpaired = mean_difference(independent - ref)
    assert paired.half * 5 <= unpaired.half
    assert abs(paired.value) <= paired.half  # the two laws' means agree (true difference ≈ 0)


def test_one_stream_passed_as_both_is_the_single_stream_path():
    """``normal_rng=None`` is ``sample_frame``'s draw order (the test above it); two streams
    give other codes, the same seed the same bits."""
    kw = dict(CASES[0], **READOUT)
    lam = _mean_e(5, 7)
    one = binned_codes(np.random.default_rng(9), lam, **kw)
    two = binned_codes(np.random.default_rng(9), lam, normal_rng=np.random.default_rng(10), **kw)
    again = binned_codes(np.random.default_rng(9), lam, normal_rng=np.random.default_rng(10), **kw)
    assert not np.array_equal(one, two)
    assert np.array_equal(two, again)
