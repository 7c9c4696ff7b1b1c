"""Quantization onto the integer grid: within budget, reversible to half a grid step."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csgnb import exact
from csgnb.exact import budget, quantize

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


point_arrays = arrays(np.float64, st.tuples(st.integers(1, 20), st.just(3)), elements=finite)


@given(width=st.sampled_from(exact.WIDTHS), pts=point_arrays)
def test_quantize_stays_in_budget_and_maps_back(width, pts):
    grid, q = quantize(pts, width)
    assert grid.dtype == np.int64
    assert np.abs(grid).max() <= budget(width).max_mesh_coordinate
    assert np.all(np.abs(q.to_model(grid) - pts) <= 0.5 * q.resolution * (1 + 1e-9) + 1e-9 * np.abs(pts))
    assert np.log2(q.scale) == np.round(np.log2(q.scale))  # a power of two


def test_quantized_mesh_feeds_the_predicates():
    rng = np.random.default_rng(1)
    verts = rng.normal(size=(30, 3))
    grid, q = quantize(verts, 128)
    planes = exact.plane_from_points(grid[:10], grid[10:20], grid[20:30], width=128)
    assert planes.shape == (10, 4)


def test_quantize_refuses_bad_input():
    with pytest.raises(ValueError, match="NaN"):
        quantize(np.array([[0.0, np.nan, 1.0]]))
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        quantize(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="max_coordinate"):
        quantize(np.zeros((1, 3)), 128, max_coordinate=10**9)


@given(num=st.integers(-(2**300), 2**300), den=st.integers(1, 2**300), exponent=st.integers(-1100, 1100))
def test_grid_volumes_in_model_units_are_the_exact_quotient(num, den, exponent):
    """``Grid.model_volume`` (a shift: the scale is 2**exponent) equals volume / scale**3 in exact arithmetic, also
    where the scale as a double would be inf (exponent > 1023) or underflow."""
    from fractions import Fraction

    from csgnb.exact import Grid

    grid = Grid(exponent=exponent, width=256) if abs(exponent) > 60 else Grid(2.0**exponent, width=256)
    volume = Fraction(num, den)
    assert grid.model_volume(volume) == volume / Fraction(2) ** (3 * exponent)
    assert grid.model_volume(num) == Fraction(num) / Fraction(2) ** (3 * exponent)


def test_grid_model_volume_refuses_inexact_volumes():
    from csgnb.exact import Grid

    for bad in (1.5, float("nan"), "abc", None):
        with pytest.raises(TypeError, match="exact volume"):
            Grid(1.0).model_volume(bad)
