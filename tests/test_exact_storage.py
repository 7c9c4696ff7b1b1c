"""Plane layouts, budget scans and the fast conversion path, against Python ints and Fractions.

* narrow plane records: exact round trips, refusal at the field edges, every predicate
  agrees on both layouts, the mesh budget always fits the narrow fields;
* the vector scans behind the fast budget checks: their bounds are upper bounds of the
  exact maxima (and close to them), their zero flags are exact, at every width and layout;
* the budget edges are decided exactly however the fast bounds fall;
* ``to_double_position``'s certified fast path: bit-identical to ``float(Fraction)`` on ties,
  near-ties and random quotients, and the exact fallback is taken where it must be.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from csgnb import GeometryError, PrecisionError, exact
from csgnb.exact import budget, integer_root
from csgnb.exact import budgets as B
from csgnb.exact.planes import narrow_field_bits, narrow_fields_hold_the_mesh_budget
from tests.exact_reference import side, solve_3_planes

WIDTHS = exact.WIDTHS
widths = st.sampled_from(WIDTHS)


def ints(arr):
    return [int(v) for v in exact.from_wide(arr).reshape(-1)]


@st.composite
def narrow_rows(draw, width, count):
    """Planes whose coefficients fit the narrow fields, the extremes over-represented."""
    n_bits, d_bits = narrow_field_bits(width)
    n_max, d_max = (1 << (n_bits - 1)) - 1, (1 << (d_bits - 1)) - 1
    normal = st.one_of(st.sampled_from([n_max, -n_max, 0, 1, -1]), st.integers(-n_max, n_max))
    offset = st.one_of(st.sampled_from([d_max, -d_max, 0, 1, -1, 2**63, -(2**63)]).filter(lambda v: abs(v) <= d_max),
                       st.integers(-d_max, d_max))
    rows = []
    for _ in range(count):
        n = draw(st.lists(normal, min_size=3, max_size=3).filter(any))
        rows.append(n + [draw(offset)])
    return rows


# ---------------------------------------------------------------------------
# narrow plane records


@pytest.mark.parametrize("width", WIDTHS)
def test_narrow_fields_hold_every_mesh_plane(width):
    assert narrow_fields_hold_the_mesh_budget(width)
    size = exact.plane_dtype(width).itemsize
    assert size == (20 if width == 128 else 40)  # paper §4.4
    # The extreme mesh planes themselves.
    V = budget(width).max_mesh_coordinate
    plane = exact.plane_from_points([-V, -V, -V], [V, -V, V], [-V, V, V], width=width, canonical=False, narrow=True)
    full = exact.plane_from_points([-V, -V, -V], [V, -V, V], [-V, V, V], width=width, canonical=False)
    assert ints(exact.to_full_planes(plane)) == ints(full)


@given(width=widths, data=st.data())
def test_narrow_round_trip(width, data):
    rows = data.draw(narrow_rows(width, data.draw(st.integers(1, 5))))
    full = exact.to_wide(rows, width)
    narrow = exact.to_narrow_planes(full)
    assert exact.is_narrow_planes(narrow) and exact.plane_width_of(narrow) == width
    assert ints(exact.to_full_planes(narrow)) == ints(full)
    assert narrow["normal"].tolist() == [r[:3] for r in rows]


@pytest.mark.parametrize("width", WIDTHS)
def test_narrow_refuses_what_does_not_fit(width):
    n_bits, d_bits = narrow_field_bits(width)
    for bad in ([1 << (n_bits - 1), 0, 0, 0], [-(1 << (n_bits - 1)), 1, 0, 0], [0, 1, 0, 1 << (d_bits - 1)],
                [0, 0, 1, -(1 << (d_bits - 1))]):
        if max(abs(v) for v in bad) >= 1 << (width - 1):
            continue
        with pytest.raises(PrecisionError, match="does not fit the narrow"):
            exact.to_narrow_planes(exact.to_wide([[1, 0, 0, 0], bad], width))


@given(width=widths, data=st.data())
def test_predicates_agree_on_both_layouts(width, data):
    """Within the plane budget and the narrow fields: every predicate, both layouts, against Fractions."""
    limit = budget(width).limit
    n_bits, d_bits = narrow_field_bits(width)
    N = data.draw(st.sampled_from([1, 7, min(integer_root((limit - 1) // 16, 3), (1 << (n_bits - 1)) - 1)]))
    D = min((limit - 1) // (16 * N**3), (1 << (d_bits - 1)) - 1)
    coef = lambda bound: st.one_of(st.sampled_from([bound, -bound, 0, 1]), st.integers(-bound, bound))  # noqa: E731
    rows = [data.draw(st.lists(coef(N), min_size=3, max_size=3).filter(any)) + [data.draw(coef(D))]
            for _ in range(4)]
    full = exact.to_wide(rows, width)
    narrow = exact.to_narrow_planes(full)
    p, q, r, s = rows
    point = solve_3_planes(p, q, r)
    if point is None:
        for layout in (full, narrow):
            with pytest.raises(GeometryError, match="linearly dependent"):
                exact.intersect_3_planes(layout[0], layout[1], layout[2])
    else:
        x_full = exact.intersect_3_planes(full[0], full[1], full[2])
        x_narrow = exact.intersect_3_planes(narrow[0], narrow[1], narrow[2])
        assert ints(x_full) == ints(x_narrow)
        x = ints(x_full)
        assert [Fraction(x[i], x[3]) for i in range(3)] == point
        assert exact.classify_vertex(x_full, full[3]) == exact.classify_vertex(x_full, narrow[3]) == side(point, s)
    for a, b in ((0, 1), (2, 3)):
        expected = not any([rows[a][1] * rows[b][2] - rows[a][2] * rows[b][1],
                            rows[a][2] * rows[b][0] - rows[a][0] * rows[b][2],
                            rows[a][0] * rows[b][1] - rows[a][1] * rows[b][0]])
        assert bool(exact.are_planes_parallel(full[a], full[b])) == expected
        assert bool(exact.are_planes_parallel(narrow[a], narrow[b])) == expected
        assert bool(exact.are_planes_parallel(narrow[a], full[b])) == expected
    v_max = min((limit - 1 - D) // (3 * N), 2**62)
    v = data.draw(st.lists(st.integers(-v_max, v_max), min_size=3, max_size=3))
    expected = sum(a * b for a, b in zip(v, p[:3], strict=True)) + p[3]
    assert ints(exact.signed_distance([v], full[:1])) == ints(exact.signed_distance([v], narrow[:1])) == [expected]


@pytest.mark.parametrize("width", WIDTHS)
def test_plane_from_points_narrow(width):
    rng = np.random.default_rng(width)
    V = budget(width).max_mesh_coordinate
    pts = rng.integers(-V, V + 1, size=(3, 300, 3))
    full = exact.plane_from_points(*pts, width=width)
    narrow = exact.plane_from_points(*pts, width=width, narrow=True)
    assert ints(exact.to_full_planes(narrow)) == ints(full)


def test_parallel_at_the_full_row_budget():
    """Full rows compute n_p x n_q at a reduced width (192 bits for 256-bit planes): exact at the budget edge."""
    for width in WIDTHS:
        limit = budget(width).limit
        N = integer_root((limit**2 - 1) // 27, 6)  # the largest normal the 3x3 bound admits (d = 0)
        rows = [[N, N - 1, 1, 0], [N - 1, N, 1, 0], [N, N - 1, 1, 0], [-N, -(N - 1), -1, 0]]
        planes = exact.to_wide(rows, width)
        assert exact.are_planes_parallel(planes[:2], planes[2:]).tolist() == [True, False]
        assert exact.are_planes_parallel(planes[0], planes[1]) == (not any(np.cross(rows[0][:3], rows[1][:3])))


# ---------------------------------------------------------------------------
# the scans behind the fast checks


def _wide_values(width):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    special = [0, -1, 1, lo, hi, 2**64, -(2**64), 2**64 - 1, -(2**64) + 1, 2**128 - 1, -(2**128)]
    return st.one_of(st.sampled_from([v for v in special if lo <= v <= hi]), st.integers(lo, hi),
                     st.integers(-(2**70), 2**70), st.integers(-5, 5))


@given(width=widths, data=st.data())
def test_scan_bounds_are_upper_bounds_and_zero_flags_exact(width, data):
    n = data.draw(st.integers(1, 12))
    rows = [data.draw(st.lists(_wide_values(width), min_size=4, max_size=4)) for _ in range(n)]
    arr = exact.to_wide(rows, width)
    acc = B.scan(arr, width)
    bounds = B.scan_bounds(acc, width)
    for c in range(4):
        m = max(abs(r[c]) for r in rows)
        assert m <= bounds[c]
        top = max(m, 1).bit_length()
        assert bounds[c] <= 2 * m + 2 or bounds[c] <= m + 2 ** max(0, top - 60)  # tight unless the lead limb is tiny
    assert B.scan_has_zero_normal(acc) == any(not any(r[:3]) for r in rows)
    assert B.scan_has_zero_w(acc) == any(r[3] == 0 for r in rows)
    # The scan is a fold: two halves give the same accumulator.
    part = B.new_scan(width)
    for chunk in (arr[: n // 2], arr[n // 2:]):
        if chunk.shape[0]:
            B._scan_all(np.ascontiguousarray(chunk), part)
    assert part.tolist() == acc.tolist()


@given(width=widths, data=st.data())
def test_narrow_scans_bound_the_fields(width, data):
    rows = data.draw(narrow_rows(width, data.draw(st.integers(1, 9))))
    narrow = exact.to_narrow_planes(exact.to_wide(rows, width))
    acc = B.scan(narrow, width)
    bounds = B.scan_bounds(acc, width)
    for c in range(4):
        m = max(abs(r[c]) for r in rows)
        assert m <= bounds[c] <= 2 * m + 2**33 + 2
    assert not B.scan_has_zero_normal(acc)
    zero = narrow.copy()
    zero["normal"][data.draw(st.integers(0, len(rows) - 1))] = 0  # the vector path and the last (scalar) record
    assert B.scan_has_zero_normal(B.scan(zero, width))


@pytest.mark.parametrize("width", WIDTHS)
def test_budget_edges_are_exact_whatever_the_fast_bound(width):
    """At the edge the fast bound fails and the exact maxima decide; one more is refused."""
    limit = budget(width).limit
    for N in (1, 5, 2**20 + 1):
        D = (limit - 1) // (16 * N**3)
        ok = exact.to_wide([[N, 0, 0, D], [0, 1, 0, 0], [0, 0, 1, 0]], width)
        exact.intersect_3_planes(ok[0], ok[1], ok[2])
        exact.are_planes_parallel(ok, ok)
        bad = exact.to_wide([[N, 0, 0, D + 1], [0, 1, 0, 0], [0, 0, 1, 0]], width)
        with pytest.raises(PrecisionError, match=f"16·N³·D = {16 * N**3 * (D + 1)}"):
            exact.intersect_3_planes(bad[0], bad[1], bad[2])
        with pytest.raises(PrecisionError, match=r"planes\[0\]"):
            exact.classify_vertex(exact.to_wide([1, 1, 1, 1], width), bad)
        exact.are_planes_parallel(bad, ok)  # only the normals matter to the parallel test


@pytest.mark.parametrize("width", WIDTHS)
def test_parallel_refuses_normals_beyond_its_cross_product(width):
    from csgnb.exact.budgets import CROSS_PRODUCT_BITS

    M = CROSS_PRODUCT_BITS[width]
    N = integer_root(((1 << (M - 1)) - 1) // 2, 2)  # the largest N with 2 N^2 < 2**(M-1)
    assert 2 * N**2 < 1 << (M - 1) <= 2 * (N + 1) ** 2
    rows = [[N, N - 1, 1, 0], [N - 1, N, 1, 0], [N, N - 1, 1, 5]]
    planes = exact.to_wide(rows, width)
    assert exact.are_planes_parallel(planes[0], planes[1:]).tolist() == [False, True]
    with pytest.raises(PrecisionError, match=f"formed at {M} bits"):
        exact.are_planes_parallel(exact.to_wide([[N + 1, 0, 1, 0]], width), planes[0])


@pytest.mark.parametrize("width", WIDTHS)
def test_zero_normals_and_points_at_infinity_in_bulk(width):
    planes = exact.to_wide([[1, 0, 0, 1]] * 700 + [[0, 0, 0, 3]] + [[0, 1, 0, 1]] * 5, width)
    for layout in (planes, exact.to_narrow_planes(planes)):
        with pytest.raises(GeometryError, match=r"p\[700\] has a zero normal"):
            exact.are_planes_parallel(layout, layout[:1])
    points = exact.to_wide([[1, 2, 3, 1]] * 300 + [[1, 2, 3, 0]], width)
    with pytest.raises(GeometryError, match=r"points\[300\] has x4 = 0"):
        exact.classify_vertex(points, planes[:1])
    with pytest.raises(GeometryError, match=r"y\[300\] has x4 = 0"):
        exact.points_equal(points[:1], points)


def test_broadcasting_and_empty_inputs():
    planes = exact.to_wide([[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, -3]], 192)
    for layout in (planes, exact.to_narrow_planes(planes)):
        x = exact.intersect_3_planes(layout[0], layout[1], layout[2])
        assert ints(x) == [-1, -2, -3, -1]
        assert exact.classify_vertex(np.stack([x] * 5), layout[1]).tolist() == [0] * 5
        assert exact.are_planes_parallel(layout[:1], layout).tolist() == [True, False, False]
    empty = planes[:0]
    assert exact.classify_vertex(exact.to_wide(np.zeros((0, 4), np.int64), 192), empty).shape == (0,)
    assert exact.to_double_position(exact.to_wide(np.zeros((0, 4), np.int64), 192)).shape == (0, 3)


# ---------------------------------------------------------------------------
# to_double_position: the certified fast path and its fallback


def _positions(width, rows):
    stats = {}
    got = exact.to_double_position(exact.to_wide(rows, width), stats=stats)
    want = [[float(Fraction(v, r[3])) for v in r[:3]] for r in rows]
    assert got.tolist() == want
    return stats["exact"]


@pytest.mark.parametrize("width", WIDTHS)
def test_ties_take_the_exact_path(width):
    rows = []
    for k in (0, 3, 40, width - 60):
        for mantissa in (2**53 + 1, 2**53 + 3, 2**54 - 1):  # odd 54-bit numbers: exact ties
            for denominator in (1, 3, -7):
                rows.append([mantissa * denominator * 2**k, -mantissa * denominator, 0, denominator])
    assert _positions(width, rows) >= 2 * len(rows)  # every tie is decided exactly


@pytest.mark.parametrize("width", WIDTHS)
def test_near_ties_are_rounded_correctly(width):
    # x / w = (m + 1/2) -+ 1 / w: a midpoint between the doubles m and m + 1 (2**52 <= m < 2**53), missed
    # by far less than the fast path can resolve.
    rows = []
    rng = np.random.default_rng(width)
    for _ in range(200):
        m = int(rng.integers(2**52, 2**53))
        w = int(rng.integers(1, 2**20)) | 1
        k = int(rng.integers(0, width - 54 - 24))
        den = w << (k + 1)
        for delta in (-1, 1):
            x = (2 * m + 1) * (w << k) + delta
            rows.append([x, -x, (2 * m + 1) * (w << k), den])
    assert _positions(width, rows) >= 3 * len(rows) // 2  # near-ties and ties go the exact way


@given(width=widths, data=st.data())
def test_random_quotients_are_correctly_rounded(width, data):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    n = data.draw(st.integers(1, 6))
    rows = []
    for _ in range(n):
        x = data.draw(st.lists(st.one_of(st.integers(lo, hi), st.integers(-(2**60), 2**60), st.just(0)),
                               min_size=3, max_size=3))
        w = data.draw(st.one_of(st.integers(lo, hi), st.integers(-5, 5), st.sampled_from([lo, hi])).filter(bool))
        rows.append(x + [w])
    _positions(width, rows)


def test_the_fast_path_settles_random_points():
    rng = np.random.default_rng(7)
    V = budget(256).max_mesh_coordinate
    pts = rng.integers(-V, V + 1, size=(3, 2000, 3))
    planes = exact.plane_from_points(*pts, width=256)
    x = exact.intersect_3_planes(planes, np.roll(planes, 1, axis=0), np.roll(planes, 2, axis=0))
    stats = {}
    got = exact.to_double_position(x, stats=stats)
    assert stats["exact"] == 0
    rows = exact.from_wide(x).tolist()
    assert got.tolist() == [[float(Fraction(v, r[3])) for v in r[:3]] for r in rows]


@given(width=widths, data=st.data())
def test_python_ints_become_limbs_as_their_bytes_say(width, data):
    """``to_wide`` of an object array of Python ints (a 256-bit tool's planes) takes numpy's object loops; every limb
    is checked against the value's own two's-complement bytes, the signed range's ends included."""
    from csgnb.exact.wide import _python_ints_to_wide, to_wide

    top = (1 << (width - 1)) - 1
    # columns that fit in int64 take numpy's int64 loops, the others bytes: mix both, and their edges
    value = st.one_of(st.integers(-top - 1, top), st.integers(-(1 << 63), (1 << 63) - 1),
                      st.sampled_from([-(1 << 63), (1 << 63) - 1, 1 << 63, -(1 << 63) - 1, 0, -1]))
    values = data.draw(st.lists(value, min_size=1, max_size=12))
    values += [-top - 1, top, 0, -1]
    shape = data.draw(st.sampled_from(["flat", "rows", "3-d"])) if len(values) % 4 == 0 else "flat"
    arr = np.array(values, dtype=object)
    arr = arr.reshape({"flat": (-1,), "rows": (-1, 4), "3-d": (-1, 2, 2)}[shape])
    got = to_wide(arr, width)
    assert got.shape == arr.shape
    expected = np.frombuffer(b"".join(int(v).to_bytes(width // 8, "little", signed=True) for v in arr.reshape(-1)),
                             dtype=got.dtype).reshape(arr.shape)
    assert got.tobytes() == expected.tobytes()
    assert _python_ints_to_wide(arr, width).tobytes() == expected.tobytes()
    scalar = np.array(values[0], dtype=object)  # a 0-d object array (it once failed on an int without astype)
    assert to_wide(scalar, width).tobytes() == expected.reshape(-1)[:1].tobytes()
    for bad in (top + 1, -top - 2):
        with pytest.raises(PrecisionError, match=f"does not fit in {width} bits"):
            to_wide(np.array([1, bad], dtype=object), width)


def test_object_arrays_of_other_things_take_the_checked_path():
    """Only plain Python ints take the fast object path: numpy scalars are converted exactly, bools and floats that
    are not integers refused, as before."""
    from csgnb.exact.wide import from_wide, to_wide

    mixed = np.array([np.int64(-5), 7, 1 << 100], dtype=object)
    assert [int(v) for v in from_wide(to_wide(mixed, 256))] == [-5, 7, 1 << 100]
    with pytest.raises(TypeError):
        to_wide(np.array([True, 1 << 70], dtype=object), 128)
    with pytest.raises(PrecisionError):
        to_wide(np.array([0.5, 1 << 70], dtype=object), 128)
