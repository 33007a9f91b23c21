"""Unmeasured points and large maps (solvers.measured, issue #30).

The FRT-style case is a map made here: a textured rectangle inside an unmeasured border, with
stray measured pixels in the border (a column of zeros, 0.3 mm spikes), as an FRT MicroProf
writes them. Filling by nearest value copied them over a quarter of the map.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from skisnow.solvers.errors import InputError
from skisnow.solvers.measured import (
    MAX_HOLE_POINTS,
    iso25178_measured,
    largest_usable_rectangle,
    prepare_measured_map,
    reduce_map,
)
from skisnow.solvers.texture import iso25178_parameters, level_heights, self_affine_surface

DX = 2e-6


def texture(shape, seed=0, rms=1e-6) -> np.ndarray:
    return self_affine_surface(
        shape, DX, hurst=0.8, rms_height_m=rms, rng=np.random.default_rng(seed)
    )


def plane_removed(h: np.ndarray) -> np.ndarray:
    """Least-squares plane of the finite points removed (an independent lstsq)."""
    i, j = np.indices(h.shape)
    ok = np.isfinite(h)
    a = np.column_stack([np.ones(ok.sum()), i[ok], j[ok]])
    coef, *_ = np.linalg.lstsq(a, h[ok], rcond=None)
    return h - (coef[0] + coef[1] * i + coef[2] * j)


def frt_style_map():
    """(raw map [m], textured rectangle (r0, r1, c0, c1), stray measured points)."""
    n0, n1 = 160, 120
    r0, r1, c0, c1 = 30, 140, 25, 105
    raw = np.full((n0, n1), np.nan)
    i, j = np.indices((r1 - r0, c1 - c0))
    raw[r0:r1, c0:c1] = 50e-6 + 2e-8 * i - 1e-8 * j + texture((r1 - r0, c1 - c0))
    raw[:, 8] = 0.0  # a column of zeros in the unmeasured border
    for r, c in ((5, 40), (150, 60), (80, 115)):
        raw[r, c] = 0.3e-3  # 0.3 mm spikes
    return raw, (r0, r1, c0, c1), n0 + 3


def test_frt_style_border_is_cut_not_spread():
    raw, (r0, r1, c0, c1), n_stray = frt_style_map()
    prep = prepare_measured_map(raw, DX)
    assert prep.crop == (r0, r1, c0, c1)
    assert prep.filled_points == 0
    assert prep.cut_measured_points == n_stray
    assert prep.measured_points == np.isfinite(raw).sum()
    # the solver's map is the textured rectangle, levelled: nothing of the stray pixels
    expected = plane_removed(raw[r0:r1, c0:c1])
    np.testing.assert_allclose(prep.heights_m, expected - expected.mean(), atol=1e-12)
    assert np.abs(prep.heights_m).max() < 10e-6
    # ISO 25178 on the measured points (stray pixels included, as the standard says)
    measured = plane_removed(raw)[np.isfinite(raw)]
    assert prep.iso_measured["Sq_m"] == pytest.approx(measured.std(), rel=1e-9)
    assert prep.iso_measured["Sa_m"] == pytest.approx(
        np.abs(measured - measured.mean()).mean(), rel=1e-9
    )
    # the record says how far Sq moved
    assert prep.sq_map_m == pytest.approx(expected.std(), rel=1e-9)
    assert prep.record()["sq_change_percent"] == pytest.approx(
        100 * (expected.std() / measured.std() - 1), rel=1e-9
    )
    # the old rule (nearest-value fill over the whole map) spread the strays: Sq many times
    old, _ = level_heights(raw, DX, max_missing_fraction=0.9)
    assert old.std() > 5 * prep.sq_map_m


def test_small_holes_take_the_median_of_their_neighbours():
    h = texture((64, 48), seed=1)
    raw = h.copy()
    raw[20, 20] = np.nan  # one point
    raw[30:32, 10:13] = np.nan  # six points
    raw[40, 30] = np.nan
    raw[40, 31] = 5e-6  # a spike beside a hole: one of its eight neighbours
    prep = prepare_measured_map(raw, DX, detrend="none")
    assert prep.crop == (0, 64, 0, 48) and prep.filled_points == 8
    levelled = raw  # detrend none: heights as given
    ring = [levelled[r, c] for r, c in itertools.product((19, 20, 21), repeat=2)]
    ring = [v for v in ring if np.isfinite(v)]
    assert prep.heights_m[20, 20] == pytest.approx(np.median(ring), abs=1e-15)
    assert prep.heights_m[40, 30] < 2e-6  # the spike does not set it
    assert np.isfinite(prep.heights_m).all()


def test_large_holes_and_edge_holes_are_cut_and_too_much_is_refused():
    h = texture((100, 80), seed=2)
    raw = h.copy()
    raw[60:75, 40:55] = np.nan  # 225 points > MAX_HOLE_POINTS: not filled
    assert 15 * 15 > MAX_HOLE_POINTS
    raw[0, 5] = np.nan  # touches the edge: cut
    prep = prepare_measured_map(raw, DX)
    r0, r1, c0, c1 = prep.crop
    assert np.isfinite(raw[r0:r1, c0:c1]).all() and prep.filled_points == 0
    assert (r1 - r0) * (c1 - c0) >= 0.5 * raw.size
    checker = h.copy()
    checker[::2, ::2] = np.nan  # 25 % unmeasured in single points: too many to fill
    with pytest.raises(InputError, match="too many holes"):
        prepare_measured_map(checker, DX)
    sparse = np.full((50, 50), np.nan)
    sparse[::3, :] = h[:50:3, :50]  # measured lines only: no rectangle of measured points
    with pytest.raises(InputError, match="too much of the map is unmeasured"):
        prepare_measured_map(sparse, DX)
    with pytest.raises(InputError, match="infinite"):
        prepare_measured_map(np.where(np.isnan(raw), np.inf, raw), DX)


def test_iso_of_a_complete_map_matches_the_full_map_parameters():
    h = texture((40, 30), seed=3)
    ours = iso25178_measured(h, DX)
    full = iso25178_parameters(h, DX, periodic=False)
    assert ours == pytest.approx(full, rel=1e-9)


@pytest.mark.parametrize("seed", range(30))
def test_largest_rectangle_is_exact_on_small_masks(seed):
    rng = np.random.default_rng(seed)
    mask = rng.random((7, 9)) > 0.25
    r0, r1, c0, c1 = largest_usable_rectangle(mask)
    assert mask[r0:r1, c0:c1].all()
    best = max(
        (b - a) * (d - c)
        for a, b in itertools.combinations(range(8), 2)
        for c, d in itertools.combinations(range(10), 2)
        if mask[a:b, c:d].all()
    )
    assert (r1 - r0) * (c1 - c0) == best


def test_largest_rectangle_on_a_large_mask_is_grown_to_the_exact_edges():
    mask = np.zeros((1197, 940), dtype=bool)
    mask[13:1190, 7:931] = True
    assert largest_usable_rectangle(mask) == (13, 1190, 7, 931)


def test_reduce_map_block_crop_none():
    h = texture((100, 70), seed=4)
    limit = 4 * 40 * 30  # mirror doubles each side
    block = reduce_map(h, DX, "block", max_solve_points=limit)
    assert block.factor == 3 and block.heights_m.shape == (33, 23)
    assert block.pixel_size_m == pytest.approx(3 * DX)
    a0, a1, b0, b1 = block.window
    assert (a1 - a0, b1 - b0) == (99, 69)
    part = h[a0:a1, b0:b1]
    np.testing.assert_allclose(
        block.heights_m[0, 0] + part.mean(), part[0:3, 0:3].mean(), rtol=1e-9
    )
    crop = reduce_map(h, DX, "crop", max_solve_points=limit)
    assert 4 * crop.heights_m.size <= limit and crop.pixel_size_m == DX
    a0, a1, b0, b1 = crop.window
    assert abs(a0 - (100 - a1)) <= 1 and abs(b0 - (70 - b1)) <= 1  # centred
    with pytest.raises(InputError, match="reduce=crop"):
        reduce_map(h, DX, "none", max_solve_points=limit)
    same = reduce_map(h, DX, "crop", max_solve_points=4 * h.size)
    assert same.method == "none" and same.heights_m is h
    with pytest.raises(InputError, match="reduce must be"):
        reduce_map(h, DX, "shrink", max_solve_points=limit)


def test_holes_sharing_neighbours_each_take_their_own_median():
    h = texture((32, 32), seed=5)
    raw = h.copy()
    for r, c in ((10, 10), (10, 12), (12, 11), (20, 20), (20, 21)):
        raw[r, c] = np.nan  # (10,10), (10,12), (12,11) are separate holes sharing neighbours
    prep = prepare_measured_map(raw, DX, detrend="none")
    assert prep.filled_points == 5

    def ring_median(points):
        cells = {(r + a, c + b) for r, c in points for a in (-1, 0, 1) for b in (-1, 0, 1)}
        return np.median([raw[p] for p in cells if np.isfinite(raw[p])])

    for hole in ([(10, 10)], [(10, 12)], [(12, 11)], [(20, 20), (20, 21)]):
        for p in hole:
            assert prep.heights_m[p] == pytest.approx(ring_median(hole), abs=1e-15)
