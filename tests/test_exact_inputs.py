"""Bad and edge input of csgnb.exact: integral conversion, widths, quantization at the double range, doctests."""

from __future__ import annotations

import doctest
import math
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from csgnb import GeometryError, PrecisionError, exact
from csgnb.exact import Grid, budget, quantize

# ---------------------------------------------------------------------------
# integral values only


@pytest.mark.parametrize("width", exact.WIDTHS)
def test_to_wide_refuses_non_integral_values(width):
    for bad in ([[0.5, 1]], [1.5], [np.float64(2.5)], [Fraction(7, 2)], [Decimal("2.5")]):
        with pytest.raises(PrecisionError, match="not an integer.*quantize"):
            exact.to_wide(bad, width)
    for bad in (["1"], [1 + 2j], [None], [True], "12"):
        with pytest.raises(TypeError):
            exact.to_wide(bad, width)
    with pytest.raises(GeometryError, match="not finite"):
        exact.to_wide([math.inf], width)
    with pytest.raises(GeometryError, match="not finite"):
        exact.to_wide(np.array([np.nan]), width)


@pytest.mark.parametrize("width", exact.WIDTHS)
def test_to_wide_accepts_integral_values_exactly(width):
    values = [2.0, np.float64(-3), Fraction(6, 3), Decimal("4"), 1e30, 2**100, np.int8(-7), np.uint64(2**64 - 1)]
    got = exact.from_wide(exact.to_wide(values, width)).tolist()
    assert got == [2, -3, 2, 4, int(1e30), 2**100, -7, 2**64 - 1]
    assert exact.from_wide(exact.to_wide(np.array([1.0, -2.0, 2.0**62]), width)).tolist() == [1, -2, 2**62]


@given(width=st.sampled_from(exact.WIDTHS), target=st.sampled_from(exact.WIDTHS), data=st.data())
def test_to_width_keeps_values_or_refuses(width, target, data):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    t_lo, t_hi = -(1 << (target - 1)), (1 << (target - 1)) - 1
    values = data.draw(st.lists(st.one_of(st.integers(lo, hi), st.sampled_from([lo, hi, t_lo, t_hi, t_lo - 1,
                                                                                   t_hi + 1, 0, -1])
                                          .filter(lambda v: lo <= v <= hi)), min_size=1, max_size=6))
    arr = exact.to_wide(values, width)
    if all(t_lo <= v <= t_hi for v in values):
        out = exact.to_width(arr, target)
        assert exact.width_of(out) == target and exact.from_wide(out).tolist() == values
    else:
        with pytest.raises(PrecisionError, match=f"does not fit in {target} bits"):
            exact.to_width(arr, target)


def test_bad_widths():
    for bad in (100, 0, -128, 128.5):
        with pytest.raises(PrecisionError, match="width must be one of"):
            exact.wide_dtype(bad)
        with pytest.raises(PrecisionError, match="width must be one of"):
            exact.budget(bad)
    for bad in ("128", None, [128]):
        with pytest.raises(TypeError, match="width"):
            exact.wide_dtype(bad)
    assert exact.check_width(192.0) == 192


def test_predicates_take_integral_floats_and_refuse_the_rest():
    p, q, r = [0.0, 0, 0], [4, 0, 0], [0, 4.0, 0]
    plane = exact.plane_from_points(p, q, r, width=128)
    assert exact.from_wide(plane).tolist() == [0, 0, 1, 0]
    with pytest.raises(PrecisionError, match=r"p\[0, 0\] = 0.5 is not an integer.*quantize"):
        exact.plane_from_points([[0.5, 0, 0]], q, r, width=128)
    with pytest.raises(PrecisionError, match="not an integer"):
        exact.signed_distance([[4.5, 1, 1]], plane)
    with pytest.raises(TypeError, match="strings"):
        exact.homogeneous_points(np.array([["1", "2", "3"]]))


@pytest.mark.parametrize("width", exact.WIDTHS)
def test_classify_vertex_refuses_points_at_infinity(width):
    points = exact.to_wide([[1, 2, 3, 1], [1, 2, 3, 0]], width)
    plane = exact.to_wide([1, 0, 0, -1], width)
    with pytest.raises(GeometryError, match=r"points\[1\] has x4 = 0"):
        exact.classify_vertex(points, plane)


# ---------------------------------------------------------------------------
# quantization over the whole double range


def _assert_optimal(pts, width, grid, q):
    """In budget, distinct points stay distinct where the budget allows, and one step finer breaks the budget."""
    assert np.abs(grid).max() <= q.max_coordinate <= budget(width).max_mesh_coordinate
    finer = np.rint(np.ldexp(pts - q.origin, q.exponent + 1))
    assert np.abs(finer).max() > q.max_coordinate


@pytest.mark.parametrize(("pts", "width"), [
    ([[0, 0, 0], [1e305, 0, 0]], 128),  # needs a scale of 2**-1001 (the old exponent clip was -1000)
    ([[1e308, 0, 0], [1.5e308, 0, 0]], 256),  # (lo + hi) / 2 overflows
    ([[-1.7e308, 0, 0], [1.7e308, 1, 1]], 128),  # the extent itself overflows
    ([[1, 1, 1], [np.nextafter(1, 2), 1, 1]], 128),  # the rounded origin is not the centre
    ([[0, 0, 0], [1e-300, 0, 0]], 128),  # 2**1009, beyond the old 2**1000
    ([[0, 0, 0], [5e-324, 0, 0], [1e-323, 0, 0]], 256),  # subnormal extents: a scale beyond the double range
])
def test_quantize_fits_any_finite_extent(pts, width):
    pts = np.array(pts, dtype=np.float64)
    grid, q = quantize(pts, width)
    _assert_optimal(pts, width, grid, q)
    assert len({tuple(g) for g in grid.tolist()}) == len({tuple(p) for p in pts.tolist()})  # distinct stay distinct
    assert np.array_equal(q.to_grid(q.to_model(grid)), grid)


any_float = st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=True)


@given(width=st.sampled_from(exact.WIDTHS),
       pts=arrays(np.float64, st.tuples(st.integers(1, 6), st.just(3)), elements=any_float))
def test_quantize_never_refuses_finite_points(width, pts):
    grid, q = quantize(pts, width)
    if np.any(pts.max(axis=0) != pts.min(axis=0)):  # not all one point (np.ptp overflows near the float limit)
        _assert_optimal(pts, width, grid, q)
    assert np.array_equal(grid, q.to_grid(pts))


def test_quantize_refuses_non_numbers():
    with pytest.raises(TypeError, match="strings"):
        quantize(np.array([["1", "2", "3"]]))
    with pytest.raises(TypeError, match="complex"):
        quantize(np.array([[1 + 2j, 0, 0]]))
    with pytest.raises(TypeError, match="real numbers"):
        quantize([[None, 0, 0]])
    with pytest.raises(GeometryError, match="empty"):
        quantize(np.zeros((0, 3)))
    with pytest.raises(PrecisionError, match="max_coordinate"):
        quantize(np.zeros((1, 3)), max_coordinate=4.5)


def test_grid_construction():
    g = Grid(scale=0.25, origin=(1, 2, 3), width=192)
    assert g.exponent == -2 and g.resolution == 4.0 and g.scale == 0.25
    assert Grid(exponent=1100).scale == math.inf and Grid(exponent=1100).resolution == 0.0
    assert Grid.from_resolution(0.3).scale == 4.0 and Grid.from_resolution(1e-310).exponent == 1030
    with pytest.raises(PrecisionError, match="power of two"):
        Grid(scale=3.0)
    with pytest.raises(TypeError, match="either scale"):
        Grid()
    with pytest.raises(GeometryError, match="finite"):
        Grid(scale=1.0, origin=(0, np.nan, 0))
    with pytest.raises(AttributeError, match="immutable"):
        g.exponent = 3
    assert g == Grid(exponent=-2, origin=(1.0, 2.0, 3.0), width=192)
    assert hash(g) == hash(Grid(exponent=-2, origin=(1, 2, 3), width=192))
    import copy
    import pickle

    tiny = Grid(exponent=1100, width=256)
    for grid in (g, tiny):
        assert pickle.loads(pickle.dumps(grid)) == grid == copy.deepcopy(grid)


# ---------------------------------------------------------------------------
# docstrings are tests: the budget figures cannot drift


@pytest.mark.parametrize("module", ["budgets", "integral", "wide", "quantization", "predicates", "planes"])
def test_docstring_examples(module):
    import importlib

    mod = importlib.import_module(f"csgnb.exact.{module}") if module != "planes" else pytest.importorskip(
        "csgnb.exact.planes")
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_package_docstring_example():
    assert doctest.testmod(exact).failed == 0
