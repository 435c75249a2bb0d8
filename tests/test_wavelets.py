"""Wavelet analysis and synthesis: reconstruction, containment, the PyWavelets oracle."""

from __future__ import annotations

import contextlib
import os
import signal
import time
import warnings
from collections.abc import Iterator

import numpy as np
import pytest
import pywt
from hypothesis import given
from hypothesis import strategies as st

from tests.conftest import height_grids
from zwcore.errors import InvalidInputError
from zwcore.grid import sampling
from zwcore.mrr import _pyramid
from zwcore.mrr.wavelets import (
    WAVELETS,
    _reference_step,
    analyse,
    analysis_step,
    level_count,
    synthesis_step,
)


def _rounding(z: np.ndarray, depth: int) -> float:
    return 64 * np.finfo(float).eps * max(1.0, float(np.abs(z).max())) * max(depth, 1)


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("lifted", [True, False])
@given(z=height_grids())
def test_perfect_reconstruction(z: np.ndarray, wavelet: str, lifted: bool) -> None:
    mrr = analyse(z, wavelet, lifted=lifted)
    back = mrr.synthesize()
    assert back.shape == z.shape
    np.testing.assert_allclose(back, z, rtol=0, atol=_rounding(z, mrr.depth))
    # Every intermediate level is rebuilt too, not only the finest.
    for j, approx in enumerate(mrr.approximations):
        np.testing.assert_allclose(mrr.synthesize(to_level=j), approx, rtol=0,
                                   atol=_rounding(z, mrr.depth))


@pytest.mark.parametrize("wavelet", WAVELETS)
@given(z=height_grids())
def test_lifted_levels_contain_the_part(z: np.ndarray, wavelet: str) -> None:
    mrr = analyse(z, wavelet)
    for j, approx in enumerate(mrr.approximations):
        on_fine = sampling.at_fine_nodes(approx, mrr.scale(j), z.shape, mrr.interpolation)
        assert (on_fine - z).min() >= 0.0, f"level {j} cuts into the part"


@pytest.mark.parametrize("wavelet", WAVELETS)
@given(z=height_grids())
def test_lifted_levels_nest(z: np.ndarray, wavelet: str) -> None:
    # Each coarser model contains the next finer one on the finer one's nodes.
    mrr = analyse(z, wavelet)
    for j in range(mrr.depth):
        fine = mrr.approximations[j + 1]
        coarse = sampling.at_fine_nodes(mrr.approximations[j], 2, fine.shape, mrr.interpolation)
        assert (coarse - fine).min() >= 0.0


def test_unlifted_single_knot_undercuts_somewhere() -> None:
    # The lift is what makes containment hold: without it a peak is cut off.
    z = np.zeros((5, 5))
    z[1, 1] = 1.0
    mrr = analyse(z, "single_knot", lifted=False, levels=1)
    on_fine = sampling.bilinear_at_fine_nodes(mrr.approximations[0], 2, z.shape)
    assert (on_fine - z).min() < 0
    lifted = analyse(z, "single_knot", levels=1)
    assert (sampling.bilinear_at_fine_nodes(lifted.approximations[0], 2, z.shape) - z).min() >= 0


def test_lifted_haar_is_block_maximum() -> None:
    z = np.random.default_rng(3).normal(size=(16, 8))
    ll, _ = analysis_step(z, "haar")
    np.testing.assert_array_equal(ll, z.reshape(8, 2, 4, 2).max(axis=(1, 3)))


@pytest.mark.filterwarnings("ignore:Level value")
@given(z=height_grids(max_side=17))
def test_unlifted_haar_matches_pywavelets(z: np.ndarray) -> None:
    mrr = analyse(z, "haar", lifted=False)
    coeffs = pywt.wavedec2(z, "haar", mode="symmetric", level=mrr.depth)
    # pywt's orthonormal Haar carries a factor sqrt(2) per 1-D step: 2 per 2-D level,
    # so level j's approximation is 2**(J-j) times ours and every detail band 2 times
    # ours at its level (cH = lh, cV = hl, cD = hh).
    np.testing.assert_allclose(coeffs[0], mrr.approximations[0] * 2.0 ** mrr.depth, atol=1e-9)
    for j, (ch, cv, cd) in enumerate(coeffs[1:]):
        bands = mrr.details[j]
        gain = 2.0 ** (mrr.depth - j)
        np.testing.assert_allclose(ch, bands.lh * gain, atol=1e-9)
        np.testing.assert_allclose(cv, bands.hl * gain, atol=1e-9)
        np.testing.assert_allclose(cd, bands.hh * gain, atol=1e-9)


def test_single_knot_definition_in_one_dimension() -> None:
    # A row grid checks the filters literally: a_i = z_2i, w_i = z_2i+1 - (z_2i + z_2i+2)/2.
    row = np.array([1.0, 4.0, 2.0, 2.0, 6.0])
    z = np.vstack([row, row, row])
    ll, bands = analysis_step(z, "single_knot", lifted=False)
    np.testing.assert_allclose(ll[0], [1.0, 2.0, 6.0])
    np.testing.assert_allclose(bands.hl[0], [4.0 - 1.5, 2.0 - 4.0])
    lifted, _ = analysis_step(z, "single_knot")
    # a'_i = a_i + max(0, w_i-1, w_i): 1 + 2.5, 2 + 2.5, 6 + 0
    np.testing.assert_allclose(lifted[0], [3.5, 4.5, 6.0], atol=1e-12)


@pytest.mark.parametrize(("shape", "wavelet", "expected"), [
    ((2, 2), "haar", 1), ((1024, 1024), "haar", 10), ((3, 5), "haar", 3),
    ((2, 2), "single_knot", 0), ((3, 3), "single_knot", 1), ((1025, 1025), "single_knot", 10),
    ((1024, 4), "single_knot", 10),
])
def test_level_count(shape: tuple[int, int], wavelet: str, expected: int) -> None:
    assert level_count(shape, wavelet) == expected  # type: ignore[arg-type]


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_padding_is_reported_and_removed(wavelet: str) -> None:
    z = np.arange(30.0).reshape(5, 6)
    ll, bands = analysis_step(z, wavelet)  # type: ignore[arg-type]
    expected = (1, 0) if wavelet == "haar" else (0, 1)
    assert bands.padding == expected
    back = synthesis_step(ll, bands, wavelet)  # type: ignore[arg-type]
    np.testing.assert_allclose(back, z, atol=1e-12)


@pytest.mark.parametrize(("levels", "message"), [(-1, "between 0"), (99, "between 0"),
                                                 (1.5, "integer")])
def test_bad_levels_are_rejected(levels: object, message: str) -> None:
    with pytest.raises(InvalidInputError, match=message) as err:
        analyse(np.zeros((4, 4)), "haar", levels=levels)  # type: ignore[arg-type]
    assert err.value.field == "levels"


def test_unknown_wavelet_lists_the_valid_ones() -> None:
    with pytest.raises(InvalidInputError, match="haar, single_knot"):
        analyse(np.zeros((4, 4)), "db4")


@given(levels=st.integers(0, 3))
def test_partial_depth(levels: int) -> None:
    z = np.random.default_rng(levels).normal(size=(9, 9))
    mrr = analyse(z, "single_knot", levels=levels)
    assert mrr.depth == levels and len(mrr.approximations) == levels + 1
    np.testing.assert_allclose(mrr.synthesize(), z, atol=1e-12)


# --------------------------------------------------------------------------
# The fast path (zwcore.mrr._pyramid: strips, Haar level pipeline, two threads)
# must reproduce the literal definition (wavelets._reference_step) bit for bit.
# --------------------------------------------------------------------------


def _reference_mrr(z: np.ndarray, wavelet: str, lifted: bool, levels: int) -> list:
    out = []
    cur = z
    for _ in range(levels):
        cur, bands = _reference_step(cur, wavelet, lifted=lifted)  # type: ignore[arg-type]
        out.append((cur, bands))
    return out


def _assert_bitwise_equal(z: np.ndarray, wavelet: str, lifted: bool) -> None:
    mrr = analyse(z, wavelet, lifted=lifted)
    ref = _reference_mrr(z, wavelet, lifted, mrr.depth)
    assert len(ref) == mrr.depth
    for k, (ll, bands) in enumerate(ref):  # k = 0 is the finest step
        j = mrr.depth - 1 - k
        got = mrr.details[j]
        assert mrr.approximations[j].tobytes() == ll.tobytes()
        assert mrr.approximations[j].shape == ll.shape
        for name in ("lh", "hl", "hh"):
            assert getattr(got, name).shape == getattr(bands, name).shape, name
            assert getattr(got, name).tobytes() == getattr(bands, name).tobytes(), name
        assert (got.fine_shape, got.padding, got.guard) == \
            (bands.fine_shape, bands.padding, bands.guard)


@contextlib.contextmanager
def _tiny_strips_and_threads() -> Iterator[None]:
    """Force the fast path's every branch onto small grids: 2-row strips (so the
    Haar pipeline runs strip by strip across levels), two threads from 0 nodes
    sharing 3 bands, Haar bands down to 2 rows, whole-level steps only for
    levels of at most 20 nodes."""
    names = ("STRIP_ELEMENTS", "THREAD_MIN_ELEMENTS", "MIN_BAND_ROWS", "BANDS", "BAND_ELEMENTS",
             "SMALL_ELEMENTS", "worker_count")
    saved = {name: getattr(_pyramid, name) for name in names}
    forced = {"STRIP_ELEMENTS": 1, "THREAD_MIN_ELEMENTS": 0, "MIN_BAND_ROWS": 1, "BANDS": 3,
              "BAND_ELEMENTS": 1, "SMALL_ELEMENTS": 20, "worker_count": lambda: 2}
    for name, value in forced.items():
        setattr(_pyramid, name, value)
    try:
        yield
    finally:
        for name, value in saved.items():
            setattr(_pyramid, name, value)


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("lifted", [True, False])
@given(z=height_grids(max_side=40))
def test_fast_path_equals_definition_bit_for_bit(z: np.ndarray, wavelet: str,
                                                 lifted: bool) -> None:
    _assert_bitwise_equal(z, wavelet, lifted)
    with _tiny_strips_and_threads():
        _assert_bitwise_equal(z, wavelet, lifted)


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("lifted", [True, False])
@pytest.mark.parametrize("shape", [(515, 513), (514, 1030), (1025, 256), (300, 1001)])
def test_threaded_path_equals_definition_bit_for_bit(shape: tuple[int, int], wavelet: str,
                                                     lifted: bool) -> None:
    # Large enough for the default thresholds: real strips, bands and threads.
    assert shape[0] * shape[1] >= _pyramid.THREAD_MIN_ELEMENTS
    z = np.random.default_rng(shape[0]).normal(size=shape).cumsum(axis=0) * 10
    _assert_bitwise_equal(z, wavelet, lifted)


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_analysis_step_takes_any_layout(wavelet: str) -> None:
    z = np.random.default_rng(5).normal(size=(9, 14)).T  # not C-contiguous
    ll, bands = analysis_step(z, wavelet)  # type: ignore[arg-type]
    ref_ll, ref = _reference_step(np.ascontiguousarray(z), wavelet)  # type: ignore[arg-type]
    np.testing.assert_array_equal(ll, ref_ll)
    np.testing.assert_array_equal(bands.hh, ref.hh)


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 2e6, -2e6])
@pytest.mark.parametrize("shape", [(5, 7), (600, 520)])
def test_bad_heights_are_rejected_without_warnings(wavelet: str, bad: float,
                                                   shape: tuple[int, int]) -> None:
    # A plain float64 Haar grid is validated while it is transformed; the error
    # is the one as_heights gives, before any error about levels.
    for pos in [(0, 0), (3, 4), (-1, -1)]:
        z = np.zeros(shape)
        z[pos] = bad
        for levels in (None, 0, 1, 99):
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                with pytest.raises(InvalidInputError) as err:
                    analyse(z, wavelet, levels=levels)
            assert err.value.field == "z"


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_threaded_path_works_in_a_forked_child() -> None:
    # A pre-fork server may fork after the parent used the helper thread; the
    # child must not wait forever on a thread it never inherited.
    z = np.random.default_rng(8).normal(size=(600, 600))
    analyse(z)  # starts the helper thread here
    pid = os.fork()
    if pid == 0:  # pragma: no cover - runs in the child
        code = 1
        try:
            code = 0 if analyse(z).depth == level_count(z.shape, "haar") else 1
        finally:
            os._exit(code)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            assert os.waitstatus_to_exitcode(status) == 0
            return
        time.sleep(0.05)
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
    pytest.fail("analyse hung in a forked child")


@pytest.mark.parametrize("lifted", [True, False])
@pytest.mark.parametrize("strip", [2, 6, 64, 1000])
@pytest.mark.parametrize("shape", [(37, 40), (40, 37), (33, 33), (64, 18), (2, 2), (3, 2)])
def test_haar_strips_of_any_size_equal_definition(shape: tuple[int, int], strip: int,
                                                  lifted: bool) -> None:
    # Strips with an even and an odd number of rows (p == q and the last row paired
    # with itself), even and odd widths, threads and bands at every size.
    z = np.random.default_rng(shape[0] * 100 + shape[1]).normal(size=shape)
    saved = (_pyramid.STRIP_ELEMENTS, _pyramid.THREAD_MIN_ELEMENTS, _pyramid.MIN_BAND_ROWS,
             _pyramid.BAND_ELEMENTS, _pyramid.worker_count)
    try:
        _pyramid.STRIP_ELEMENTS = strip
        _pyramid.THREAD_MIN_ELEMENTS, _pyramid.MIN_BAND_ROWS, _pyramid.BAND_ELEMENTS = 0, 1, 64
        _pyramid.worker_count = lambda: 2
        _assert_bitwise_equal(z, "haar", lifted)
    finally:
        (_pyramid.STRIP_ELEMENTS, _pyramid.THREAD_MIN_ELEMENTS, _pyramid.MIN_BAND_ROWS,
         _pyramid.BAND_ELEMENTS, _pyramid.worker_count) = saved


def test_haar_results_are_separate_contiguous_arrays() -> None:
    # The bands of every level are carved from one block: each must still be its own
    # C-contiguous array, overlapping no other.
    z = np.random.default_rng(11).normal(size=(37, 70))
    mrr = analyse(z, "haar")
    arrays = mrr.approximations[:-1] + [getattr(b, name) for b in mrr.details
                                        for name in ("lh", "hl", "hh")]
    for a in arrays:
        assert a.flags.c_contiguous and a.flags.writeable and a.dtype == np.float64
    for i, a in enumerate(arrays):
        for b in arrays[i + 1:]:
            assert not np.shares_memory(a, b)


def test_haar_scratch_reuse_across_calls_and_threads() -> None:
    # Scratch is kept per thread between calls: calls of other sizes (one larger than
    # what is kept), in a row and from several threads at once, must not disturb it.
    from concurrent.futures import ThreadPoolExecutor

    grids = [np.random.default_rng(n).normal(size=(n, n + 3)) for n in (700, 40, 1100, 9, 600)]
    expected = [analyse(g, "haar") for g in grids]
    saved = _pyramid.SCRATCH_KEEP
    try:
        _pyramid.SCRATCH_KEEP = 1 << 17  # the 1100-row grid's scratch is not kept
        with ThreadPoolExecutor(3) as pool:
            results = list(pool.map(lambda g: analyse(g, "haar"), grids * 3))
    finally:
        _pyramid.SCRATCH_KEEP = saved
    for got, want in zip(results, expected * 3, strict=True):
        for a, b in zip(got.approximations, want.approximations, strict=True):
            assert a.tobytes() == b.tobytes()
        for a, b in zip(got.details, want.details, strict=True):
            assert (a.lh.tobytes(), a.hl.tobytes(), a.hh.tobytes()) == \
                (b.lh.tobytes(), b.hl.tobytes(), b.hh.tobytes())
    ref = _reference_mrr(grids[0], "haar", True, 2)
    assert expected[0].approximations[-3].tobytes() == ref[1][0].tobytes()
