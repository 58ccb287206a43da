"""Equivalence: the DSP on many jobs at once (:meth:`Pipeline.blocks`) is the DSP one job at a time.

The reference is the per-job pipeline as it stood before the batch (``_PerJob`` below, its code
kept verbatim): dark reference, outputs (value, mean, variance), overflow counts (and their order),
the fixed-vs-float error statistics and the kept codes must be bit for bit the same, at the float
and the fixed level, on random frames: one pixel or many, M, K and N from 1 to 9, codes at zero and
full scale, a narrow accumulator that saturates or wraps, and the ``expected`` level (no codes).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from chiptwin.dsp import reference
from chiptwin.dsp.chain import chain_configs, with_accumulator
from chiptwin.dsp.frame_ops import average_frames_fixed, cms_fixed, subtract_background_fixed
from chiptwin.dsp.pipeline import BlockOut, Frame, FrameStack, Pipeline


class _PerJob(Pipeline):
    """The pipeline one job at a time, as it was before :meth:`Pipeline.blocks` (verbatim)."""

    def dark(self, frames: list[Frame]) -> None:
        self._keep_list(frames)
        k = len(frames)
        self.dark_mean = np.mean([f.mean for f in frames], axis=0)
        self.dark_var = np.sum([f.var for f in frames], axis=0) / k**2
        if frames[0].codes is None:
            self._dark_float = self.dark_mean
            return
        if self.level == "float" or self.error is not None:
            self._dark_float = reference.average_frames(self._cms_list(frames), k)[0]
        if self.level == "fixed":
            cms = self._fixed("cms", cms_fixed(*self._split_list(frames), self.chain.cms))
            self._dark_codes = self._fixed("dark", average_frames_fixed(cms, self.chain.dark))[0]

    def block(self, frames: list[Frame]) -> BlockOut:
        self._keep_list(frames)
        n = len(frames)
        mean = np.mean([f.mean for f in frames], axis=0) - self.dark_mean
        var = np.sum([f.var for f in frames], axis=0) / n**2
        if frames[0].codes is None:
            return BlockOut(value=mean, mean=mean, var=var)
        ref = None
        if self.level == "float" or self.error is not None:
            diff = reference.subtract_background(self._cms_list(frames), self._dark_float)
            ref = reference.average_frames(diff, n)[0]
        if self.level == "float":
            return BlockOut(value=ref, mean=mean, var=var)
        c = self.chain
        cms = self._fixed("cms", cms_fixed(*self._split_list(frames), c.cms))
        diff = self._fixed("background", subtract_background_fixed(cms, self._dark_codes,
                                                                    c.background))
        value = c.average.out_fmt.to_float(
            self._fixed("average", average_frames_fixed(diff, c.average))[0])
        if self.error is not None:
            self.error.add(value, ref)
        return BlockOut(value=value, mean=mean, var=var)

    @staticmethod
    def _split_list(frames):
        codes = np.stack([f.codes for f in frames])
        m = codes.shape[1] // 2
        return codes[:, :m], codes[:, m:]

    @classmethod
    def _cms_list(cls, frames):
        return reference.correlated_multiple_sampling(*cls._split_list(frames))

    def _keep_list(self, frames):
        if self.kept is not None and frames[0].codes is not None:
            self.kept.extend(f.codes for f in frames)


def _same(a: np.ndarray, b: np.ndarray) -> None:
    """Bit for bit: dtype, shape and every byte (−0.0 is not 0.0)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    assert np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()


def _same_state(new: Pipeline, old: Pipeline) -> None:
    assert list(new.overflow.items()) == list(old.overflow.items())
    for name in ("dark_mean", "dark_var", "_dark_float", "_dark_codes"):
        x, y = getattr(new, name), getattr(old, name)
        assert (x is None) == (y is None)
        if x is not None:
            _same(x, y)
    assert (new.error is None) == (old.error is None)
    if new.error is not None:
        assert new.error == old.error  # every running sum, exactly
    assert (new.kept is None) == (old.kept is None)
    if new.kept is not None:
        assert len(new.kept) == len(old.kept)
        for x, y in zip(new.kept, old.kept, strict=True):
            _same(x, y)


@st.composite
def cases(draw):
    """A DSP level and dark block + ``jobs`` jobs of N frames of random ADC codes."""
    bits, m = draw(st.sampled_from([4, 8, 13])), draw(st.integers(1, 5))
    k, n, jobs = draw(st.integers(1, 9)), draw(st.integers(1, 9)), draw(st.integers(1, 6))
    pixels = draw(st.sampled_from([1, 2, 3, 7, 8, 9, 17, 130]))
    level = draw(st.sampled_from(["float", "fixed", "fixed", "expected"]))
    chain = chain_configs(bits, m, k, n, rounding=draw(st.sampled_from(["RND_CONV", "TRN"])),
                          overflow=draw(st.sampled_from(["SAT", "WRAP"])))
    if draw(st.booleans()):  # a narrow accumulator: overflows to count
        width = chain.average.acc_fmt.word_bits
        chain = with_accumulator(chain, draw(st.integers(max(2, width - 6), width)),
                                 draw(st.sampled_from(["SAT", "WRAP"])))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    top = 2**bits - 1
    total = k + n * jobs
    codes = rng.integers(0, top + 1, (total, 2 * m, pixels))
    codes[rng.random(codes.shape) < 0.1] = 0  # ties with the ends of the range
    codes[rng.random(codes.shape) < 0.1] = top
    codes = codes.astype(draw(st.sampled_from([np.int64, np.uint16])))  # the ADC's narrow type
    mean = rng.normal(0, 10.0 ** draw(st.integers(-3, 6)), (total, pixels))
    var = rng.random((total, pixels)) * 10.0 ** draw(st.integers(-3, 6))
    frames = [Frame(None if level == "expected" else codes[i], mean[i], var[i])
              for i in range(total)]
    args = dict(level="float" if level == "expected" else level,
                chain=None if level in ("float", "expected") else chain,
                report_error=draw(st.booleans()), keep_codes=draw(st.booleans()))
    return args, frames, k, n


@settings(max_examples=300, deadline=None)
@given(case=cases())
def test_batch_and_single_jobs_are_the_per_job_pipeline(case):
    """``blocks`` over every job at once, and ``block`` job by job, against the per-job
    pipeline: the same outputs, dark reference, overflow counts, error sums, kept codes."""
    args, frames, k, n = case
    old, one, batch = _PerJob(**args), Pipeline(**args), Pipeline(**args)
    old.dark(frames[:k])
    one.dark(frames[:k])
    batch.dark_stack(FrameStack.of(frames[:k]))
    jobs = [frames[i:i + n] for i in range(k, len(frames), n)]
    outs = batch.blocks(FrameStack.of(frames[k:]), n)
    assert outs.value.shape[0] == len(jobs)
    for j, job in enumerate(jobs):
        want, got = old.block(job), one.block(job)
        for name in ("value", "mean", "var"):
            _same(getattr(got, name), getattr(want, name))
            _same(getattr(outs, name)[j], getattr(want, name))
    _same_state(one, old)
    _same_state(batch, old)


@settings(max_examples=60, deadline=None)
@given(case=cases(), cut=st.integers(1, 5))
def test_batches_of_any_size_add_up(case, cut):
    """The jobs split into batches at any job boundary: the same as one batch."""
    args, frames, k, n = case
    whole, parts = Pipeline(**args), Pipeline(**args)
    for p in (whole, parts):
        p.dark_stack(FrameStack.of(frames[:k]))
    stack = FrameStack.of(frames[k:])
    want = whole.blocks(stack, n)
    at = min(cut, len(stack) // n) * n
    got = [parts.blocks(stack[:at], n)] + ([parts.blocks(stack[at:], n)] if at < len(stack)
                                            else [])
    for name in ("value", "mean", "var"):
        _same(np.concatenate([getattr(g, name) for g in got]), getattr(want, name))
    _same_state(parts, whole)


def test_frame_stack_slices_and_joins():
    rng = np.random.default_rng(3)
    frames = [Frame(rng.integers(0, 9, (4, 3)), rng.random(3), rng.random(3)) for _ in range(5)]
    stack = FrameStack.of(frames)
    assert len(stack) == 5 and len(stack[1:3]) == 2
    joined = FrameStack.join([stack[:2], stack[2:]])
    for name in ("codes", "mean", "var"):
        _same(getattr(joined, name), getattr(stack, name))
        _same(getattr(stack, name)[4], getattr(frames[4], name))


def test_float_cms_of_codes_beyond_exact_float_sums_is_the_reference():
    """The float level sums integer codes exactly; where float64 sums would round (M·|code| ≥
    2^53) it takes the reference's own float sums, whose rounding the integer sum would miss."""
    big = 2**53 - 1
    reset = np.array([[[big, big], [2, 2], [-2, -2]]], np.int64)  # M = 3, 2 pixels
    codes = np.concatenate([reset, np.zeros_like(reset)], axis=1)
    stack = FrameStack(codes, np.zeros((1, 2)), np.zeros((1, 2)))
    want = reference.correlated_multiple_sampling(codes[:, :3], codes[:, 3:])
    exact = -(float(big) / 3)  # the integer sum: big + 2 − 2
    assert want[0, 0] != exact  # the float sum rounded: the case is a real one
    _same(Pipeline._cms_float(stack), want)
    small = FrameStack(codes // 2**40, stack.mean, stack.var)  # exact sums: the kernel's path
    _same(Pipeline._cms_float(small), reference.correlated_multiple_sampling(
        small.codes[:, :3], small.codes[:, 3:]))
