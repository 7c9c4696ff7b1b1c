"""The exact predicates against Python ints and Fractions, at every width and at the budget edges."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from csgnb import GeometryError, PrecisionError, exact
from csgnb._jit import jit
from csgnb.exact import budget, integer_root, intrinsics
from csgnb.exact.intrinsics import (
    box_plane_sides,
    classify_at,
    classify_wall_at,
    compare_cached_values_at,
    compare_filtered_values_at,
    cross_sign,
    plane_side_sign,
    plane_value_filtered_into,
    wide_filter_double_at,
)
from tests.exact_reference import cross, det3, side, solve_3_planes

WIDTHS = exact.WIDTHS
widths = st.sampled_from(WIDTHS)


def coefficient(bound: int):
    """Integers in [-bound, bound] with the extremes and small values over-represented."""
    small = st.integers(-3, 3).filter(lambda v: abs(v) <= bound)
    return st.one_of(st.just(bound), st.just(-bound), small, st.integers(-bound, bound))


@st.composite
def budget_bounds(draw, width):
    """(N, D): a normal bound and the largest offset bound the width allows with it, or less."""
    limit = budget(width).limit
    n_max = integer_root((limit - 1) // 16, 3)
    N = draw(st.one_of(st.just(1), st.just(n_max), st.integers(1, 64), st.integers(1, n_max)))
    d_max = (limit - 1) // (16 * N**3)
    D = draw(st.one_of(st.just(d_max), st.integers(0, d_max)))
    return N, D


@st.composite
def planes(draw, width, count, bounds=None):
    N, D = bounds if bounds is not None else draw(budget_bounds(width))
    rows = []
    for _ in range(count):
        normal = draw(st.lists(coefficient(N), min_size=3, max_size=3).filter(any))
        rows.append(normal + [draw(coefficient(D))])
    return rows


def as_ints(arr):
    return [int(v) for v in exact.from_wide(arr).reshape(-1)]


# ---------------------------------------------------------------------------
# wide storage


@given(width=widths, data=st.data())
def test_wide_roundtrip_at_the_extremes(width, data):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    values = data.draw(st.lists(st.one_of(st.just(lo), st.just(hi), st.integers(lo, hi)), min_size=1, max_size=8))
    arr = exact.to_wide(values, width)
    assert arr["limbs"].shape == (len(values), width // 64)
    assert as_ints(arr) == values


@given(width=widths, data=st.data())
def test_wide_max_abs_is_the_largest_magnitude(width, data):
    """``wide_max_abs`` (a translated tool's largest offset for the budget check, from its limbs) against Python ints,
    the extremes of the width included: |-2**(w-1)| = 2**(w-1), and -1, whose two's complement is all ones."""
    from csgnb.exact.wide import wide_max_abs

    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    special = st.sampled_from([lo, hi, -1, 0, 1, 1 << 64, -(1 << 64), (1 << 64) - 1, -(1 << 63), lo + 1])
    values = data.draw(st.lists(st.one_of(special, st.integers(lo, hi), st.integers(-(1 << 70), 1 << 70)),
                                min_size=0, max_size=8))
    assert wide_max_abs(exact.to_wide(np.array(values, dtype=object), width)) == max(map(abs, values), default=0)


@pytest.mark.parametrize("width", WIDTHS)
def test_to_wide_refuses_values_outside_the_width(width):
    with pytest.raises(PrecisionError, match=rf"2\*\*{width - 1}"):
        exact.to_wide([1 << (width - 1)], width)
    with pytest.raises(PrecisionError):
        exact.to_wide([-(1 << (width - 1)) - 1], width)


def test_int64_fast_path_matches_python_ints():
    values = np.array([0, 1, -1, np.iinfo(np.int64).max, np.iinfo(np.int64).min, -12345])
    for width in WIDTHS:
        assert as_ints(exact.to_wide(values, width)) == [int(v) for v in values]


# ---------------------------------------------------------------------------
# intersect_3_planes and to_double_position


@given(width=widths, data=st.data())
def test_intersect_3_planes_is_the_cramer_solution(width, data):
    p, q, r = data.draw(planes(width, 3))
    expected = solve_3_planes(p, q, r)
    wide = exact.to_wide([p, q, r], width)
    if expected is None:
        with pytest.raises(GeometryError, match="linearly dependent"):
            exact.intersect_3_planes(wide[0], wide[1], wide[2])
        return
    x = as_ints(exact.intersect_3_planes(wide[0], wide[1], wide[2]))
    assert x[3] == -det3([p[:3], q[:3], r[:3]])
    assert [Fraction(x[i], x[3]) for i in range(3)] == expected
    for plane in (p, q, r):  # the point lies on all three planes
        assert sum(a * b for a, b in zip(x, plane, strict=True)) == 0
    doubles = exact.to_double_position(exact.to_wide(x, width))
    assert doubles.tolist() == [float(c) for c in expected]


@given(width=widths, data=st.data())
def test_to_double_position_is_correctly_rounded(width, data):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    x = data.draw(st.lists(st.integers(lo, hi), min_size=3, max_size=3))
    w = data.draw(st.one_of(st.integers(lo, hi), st.integers(-5, 5)).filter(bool))
    out = exact.to_double_position(exact.to_wide(x + [w], width))
    assert out.tolist() == [float(Fraction(v, w)) for v in x]


@pytest.mark.parametrize("width", WIDTHS)
def test_to_double_position_rounds_ties_to_even(width):
    rows, expected = [], []
    for k in (0, 3, 40, width - 60):
        for mantissa in (2**53 + 1, 2**53 + 3, 2**54 - 1):  # odd 54-bit numbers: exact ties
            for denominator in (1, 3, -7):
                rows.append([mantissa * denominator * 2**k, -mantissa * denominator, 0, denominator])
                expected.append([float(Fraction(v, denominator)) for v in rows[-1][:3]])
    out = exact.to_double_position(exact.to_wide(rows, width))
    assert out.tolist() == expected


@pytest.mark.parametrize("width", WIDTHS)
def test_points_at_infinity_have_no_position(width):
    with pytest.raises(GeometryError, match="x4 = 0"):
        exact.to_double_position(exact.to_wide([[1, 2, 3, 0]], width))


# ---------------------------------------------------------------------------
# classify_vertex


@given(width=widths, data=st.data())
def test_classify_vertex_matches_fraction_arithmetic(width, data):
    p, q, r, s = data.draw(planes(width, 4, bounds=data.draw(budget_bounds(width))))
    point = solve_3_planes(p, q, r)
    assume(point is not None)
    wide = exact.to_wide([p, q, r, s], width)
    x = exact.intersect_3_planes(wide[0], wide[1], wide[2])
    assert exact.classify_vertex(x, wide[3]) == side(point, s)
    # Negative w: the same point scaled by -1 classifies the same.
    negated = exact.to_wide([-v for v in as_ints(x)], width)
    assert exact.classify_vertex(negated, wide[3]) == side(point, s)
    # Exactly on the planes it was built from.
    assert exact.classify_vertex(x, wide[:3]).tolist() == [0, 0, 0]


@pytest.mark.parametrize("width", WIDTHS)
def test_classify_vertex_in_bulk_and_on_combinations_of_planes(width):
    rng = np.random.default_rng(width)
    N = 1000
    rows_p, rows_q, rows_r, rows_s, expected = [], [], [], [], []
    while len(expected) < 500:
        p, q, r = (list(map(int, rng.integers(-N, N + 1, 4))) for _ in range(3))
        point = solve_3_planes(p, q, r)
        if point is None:
            continue
        if len(expected) % 3 == 0:  # a plane through the point: a combination of p, q, r
            a, b = (int(v) for v in rng.integers(-5, 6, 2))
            s = [a * u + b * v for u, v in zip(p, q, strict=True)]
            if not any(s[:3]):
                continue
        else:
            s = list(map(int, rng.integers(-N, N + 1, 4)))
        rows_p.append(p), rows_q.append(q), rows_r.append(r), rows_s.append(s)
        expected.append(side(point, s))
    P, Q, R, S = (exact.to_wide(rows, width) for rows in (rows_p, rows_q, rows_r, rows_s))
    x = exact.intersect_3_planes(P, Q, R)
    got = exact.classify_vertex(x, S)
    assert got.tolist() == expected
    assert 0 in expected and 1 in expected and -1 in expected


@pytest.mark.parametrize("width", WIDTHS)
def test_classification_at_the_hadamard_extreme(width):
    """The largest determinant the budget admits, 16·N³·D, is classified exactly."""
    limit = budget(width).limit
    H = [[1, 1, 1, 1], [1, -1, 1, -1], [1, 1, -1, -1], [1, -1, -1, 1]]  # |det| = 16
    for N in (1, 7, integer_root((limit - 1) // 16, 3)):
        D = (limit - 1) // (16 * N**3)
        rows = [[h[0] * N, h[1] * N, h[2] * N, h[3] * D] for h in H]
        s, p, q, r = rows
        wide = exact.to_wide(rows, width)
        x = exact.intersect_3_planes(wide[1], wide[2], wide[3])
        dot = sum(a * b for a, b in zip(as_ints(x), s, strict=True))
        assert abs(dot) == 16 * N**3 * D  # the extreme value itself
        assert exact.classify_vertex(x, wide[0]) == side(solve_3_planes(p, q, r), s)


# ---------------------------------------------------------------------------
# plane_from_points, signed_distance, are_planes_parallel, points_equal


@st.composite
def mesh_points(draw, width, count):
    V = budget(width).max_mesh_coordinate
    coord = st.one_of(st.just(V), st.just(-V), st.integers(-V, V), st.integers(-2, 2))
    return [[draw(coord) for _ in range(3)] for _ in range(count)]


@given(width=widths, data=st.data())
def test_plane_from_points_matches_the_cross_product(width, data):
    p, q, r = data.draw(mesh_points(width, 3))
    n = cross([b - a for a, b in zip(p, q, strict=True)], [c - a for a, c in zip(p, r, strict=True)])
    if not any(n):
        with pytest.raises(GeometryError, match="collinear"):
            exact.plane_from_points(p, q, r, width=width)
        return
    raw = as_ints(exact.plane_from_points(p, q, r, width=width, canonical=False))
    assert raw == n + [-sum(a * b for a, b in zip(n, p, strict=True))]
    g = np.gcd.reduce([abs(v) for v in n])
    canon = as_ints(exact.plane_from_points(p, q, r, width=width))
    assert canon == [v // int(g) for v in raw]
    # The plane passes through its points, and the budget makes it a valid plane for every predicate.
    planes_ = exact.to_wide([canon], width)
    assert [int(v) for v in exact.from_wide(exact.signed_distance([p, q, r], planes_))] == [0, 0, 0]


@pytest.mark.parametrize("width", WIDTHS)
def test_mesh_budget_edge(width):
    V = budget(width).max_mesh_coordinate
    p, q, r = [-V, -V, -V], [V, -V, V], [-V, V, V]
    plane = exact.plane_from_points(p, q, r, width=width, canonical=False)
    assert as_ints(plane)[3] == -sum(a * b for a, b in zip(as_ints(plane)[:3], p, strict=True))
    with pytest.raises(PrecisionError, match=f"V <= {V}"):
        exact.plane_from_points([V + 1, 0, 0], q, r, width=width)


@given(width=widths, data=st.data())
def test_signed_distance_is_the_plane_equation(width, data):
    (plane,) = data.draw(planes(width, 1))
    N, D = max(abs(v) for v in plane[:3]), abs(plane[3])
    v_max = min((budget(width).limit - 1 - D) // (3 * N), 2**62)
    v = data.draw(st.lists(st.integers(-v_max, v_max), min_size=3, max_size=3))
    got = exact.signed_distance(np.array([v], dtype=np.int64), exact.to_wide([plane], width))
    assert int(exact.from_wide(got)[0]) == sum(a * b for a, b in zip(v, plane[:3], strict=True)) + plane[3]


@given(width=widths, data=st.data())
def test_are_planes_parallel_is_a_zero_cross_product(width, data):
    p, q = data.draw(planes(width, 2, bounds=(1000, 1000)))
    k = data.draw(st.sampled_from([1, -1, 3, -7]))
    scaled = [k * v for v in p[:3]] + [q[3]]
    wide = exact.to_wide([p, q, scaled], width)
    assert bool(exact.are_planes_parallel(wide[0], wide[1])) == (not any(cross(p[:3], q[:3])))
    assert exact.are_planes_parallel(wide[0], wide[2])


@given(width=widths, data=st.data())
def test_points_equal_is_projective_equality(width, data):
    lo, hi = -(1 << (width - 3)), (1 << (width - 3)) - 1
    x = data.draw(st.lists(st.integers(lo, hi), min_size=4, max_size=4).filter(lambda v: v[3] != 0))
    k = data.draw(st.sampled_from([1, -1, 2, -3]))
    delta = data.draw(st.lists(st.integers(-1, 1), min_size=4, max_size=4))
    y = [k * v + d for v, d in zip(x, delta, strict=True)]
    assume(y[3] != 0)
    same = all(Fraction(x[i], x[3]) == Fraction(y[i], y[3]) for i in range(3))
    assert bool(exact.points_equal(exact.to_wide(x, width), exact.to_wide(y, width))) == same
    assert exact.points_equal(exact.to_wide(x, width), exact.to_wide([-2 * v for v in x], width))


# ---------------------------------------------------------------------------
# budgets


@pytest.mark.parametrize("width", WIDTHS)
def test_plane_budget_edge_is_exact(width):
    limit = budget(width).limit
    for N in (1, 5):
        D = (limit - 1) // (16 * N**3)
        ok = exact.to_wide([[N, 0, 0, D], [0, 1, 0, 0], [0, 0, 1, 0]], width)
        exact.intersect_3_planes(ok[0], ok[1], ok[2])  # accepted at the edge
        bad = exact.to_wide([[N, 0, 0, D + 1], [0, 1, 0, 0], [0, 0, 1, 0]], width)
        with pytest.raises(PrecisionError, match=rf"16·N³·D = {16 * N**3 * (D + 1)}, which must be < 2\*\*{width - 1}"):
            exact.intersect_3_planes(bad[0], bad[1], bad[2])


@pytest.mark.parametrize("width", WIDTHS)
def test_zero_offsets_are_bounded_by_the_3x3_determinant(width):
    limit = budget(width).limit
    # With d = 0 everywhere only |x4| <= 3^(3/2) N^3 binds: 27 N^6 < limit^2.
    N = integer_root((limit**2 - 1) // 27, 6)
    exact.intersect_3_planes(*exact.to_wide([[N, 0, 0, 0], [0, N, 0, 0], [0, 0, N, 0]], width))
    with pytest.raises(PrecisionError, match="3x3 determinant x4"):
        exact.intersect_3_planes(*exact.to_wide([[N + 1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], width))


@pytest.mark.parametrize("width", WIDTHS)
def test_classify_refuses_points_that_could_overflow(width):
    limit = budget(width).limit
    x = exact.to_wide([[limit // 2, limit // 2, 0, 1]], width)
    with pytest.raises(PrecisionError, match=r"\(\|x1\|\+\|x2\|\+\|x3\|\)·N \+ \|x4\|·D"):
        exact.classify_vertex(x, exact.to_wide([1, 1, 0, 0], width))


def test_zero_normal_is_not_a_plane():
    with pytest.raises(GeometryError, match="zero normal"):
        exact.classify_vertex(exact.to_wide([1, 2, 3, 1], 128), exact.to_wide([0, 0, 0, 5], 128))


def test_mixed_widths_are_refused():
    with pytest.raises(ValueError, match="different widths"):
        exact.classify_vertex(exact.to_wide([1, 2, 3, 1], 128), exact.to_wide([1, 0, 0, 5], 256))


@pytest.mark.parametrize("width", WIDTHS)
def test_budget_numbers_follow_eq_7_to_9(width):
    b = budget(width)
    V = b.max_mesh_coordinate
    assert 48 * 8**4 * V**9 < 2 ** (width - 1) <= 48 * 8**4 * (V + 1) ** 9  # eq. 8, tight
    assert abs(V / (0.239 * 2 ** (width / 9)) - 1) < 0.01  # eq. 9
    n = 1000
    v = b.max_vertex_coordinate(n)
    assert 48 * n**4 * v < 2 ** (width - 1) <= 48 * n**4 * (v + 1)  # eq. 7
    assert b.max_mesh_normal == 8 * V**2 and b.max_mesh_offset == 24 * V**3
    if width == 256:
        assert 8.72e7 < V < 8.74e7  # "positions smaller than 8.73·10^7" (paper §3.2)


@given(value=st.integers(0, 2**300), k=st.integers(1, 12))
def test_integer_root_is_exact(value, k):
    r = integer_root(value, k)
    assert r**k <= value < (r + 1) ** k


def test_broadcasting_and_shapes():
    planes_ = exact.to_wide([[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, -3], [1, 1, 1, -6]], 192)
    x = exact.intersect_3_planes(planes_[0], planes_[1], planes_[2])
    assert x.shape == (4,)
    assert exact.classify_vertex(x[None], planes_).tolist() == [0, 0, 0, 0]
    with pytest.raises(ValueError, match="cannot broadcast"):
        exact.classify_vertex(np.stack([x, x, x]), planes_[:2])


@jit
def _cross_sign_of(a, b, c, d):
    return cross_sign(a, b, c, d)


@jit
def _plane_side_sign_of(n0, n1, n2, x0, x1, x2, dh, dl):
    return plane_side_sign(n0, n1, n2, x0, x1, x2, dh, dl)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(-(2**63), 2**63 - 1), min_size=4, max_size=4), st.booleans())
def test_cross_sign_is_exact_over_all_int64(values, tie):
    """sign(a·b - c·d) in i128 against Python integers, extremes and exact ties included."""
    a, b, c, d = values
    if tie:
        c, d = b, a  # a·b - b·a = 0
    exact = a * b - c * d
    assert _cross_sign_of(a, b, c, d) == (exact > 0) - (exact < 0)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(-(2**60), 2**60), min_size=6, max_size=6), st.integers(-(2**122), 2**122),
       st.booleans())
def test_plane_side_sign_is_exact_within_its_bounds(nx, offset, on_plane):
    """sign(n·x + d) in i128, the offset split as the hull splits it (high·2**62 + low, 0 <= low < 2**62), against
    Python integers; points exactly on the plane give 0."""
    n, x = nx[:3], nx[3:]
    if on_plane:
        offset = -sum(a * b for a, b in zip(n, x, strict=True))
    value = sum(a * b for a, b in zip(n, x, strict=True)) + offset
    assert _plane_side_sign_of(*n, *x, offset >> 62, offset & ((1 << 62) - 1)) == (value > 0) - (value < 0)


# ---------------------------------------------------------------------------
# the cut's distance comparison (doubles first, the products at twice the width for close calls)


@jit
def _compare_all(D, X, iu, iv, out):
    for k in range(iu.shape[0]):
        out[k] = compare_cached_values_at(D, iu[k], iv[k], X)


def _reference_compare(du, wu, dv, wv) -> int:
    """sign(du/wu - dv/wv) as the exact products define it (0 where a denominator is 0)."""
    def sign(v):
        return (v > 0) - (v < 0)

    return sign(du * wv - dv * wu) * sign(wu) * sign(wv)


@st.composite
def quotient_pairs(draw, width):
    """(du, wu, dv, wv) over the whole signed width: random, equal quotients in other terms, and off by one unit."""
    top = (1 << (width - 1)) - 1
    value = st.one_of(st.integers(-top - 1, top), st.integers(-3, 3), st.just(top), st.just(-top - 1),
                      st.integers(-(1 << 64), 1 << 64))
    kind = draw(st.sampled_from(["random", "equal", "near", "at the filter's bound"]))
    if kind == "random":
        return tuple(draw(value) for _ in range(4))
    if kind == "at the filter's bound":
        # dv/wv = du/wu (other terms) moved by 2**-40 .. 2**-60 of itself: the doubles decide some, the products the
        # rest; a filter bound below the conversions' error (2**-58 for 2**-48) gives wrong signs here
        wu = draw(st.integers(1 << 60, top)) * draw(st.sampled_from([-1, 1]))
        du = draw(st.integers(-top - 1, top))
        k_bound = max(1, top // max(abs(du), abs(wu)))
        k = draw(st.integers(1, k_bound))
        dv, wv = du * k, wu * k
        dv += (abs(dv) >> draw(st.integers(40, 60))) * draw(st.sampled_from([-1, 1])) + draw(st.integers(-2, 2))
        assume(-top - 1 <= dv <= top)
        return du, wu, dv, wv
    p, q = draw(value), draw(value.filter(bool))
    bound = top // max(abs(p), abs(q), 1)
    k1 = draw(st.integers(-bound, bound).filter(bool)) if bound else 1
    k2 = draw(st.integers(-bound, bound).filter(bool)) if bound else 1
    du, wu, dv, wv = p * k1, q * k1, p * k2, q * k2
    if kind == "near":
        dv += draw(st.sampled_from([-1, 1]))
        assume(-top - 1 <= dv <= top)
    return du, wu, dv, wv


@settings(max_examples=300)
@given(width=widths, data=st.data())
def test_distance_comparison_is_the_sign_of_the_exact_difference(width, data):
    """``compare_cached_values_at`` (doubles decide where certain) against Python ints, over the whole width, with
    equal quotients written with other terms, quotients one unit apart, zero and negative denominators."""
    cases = data.draw(st.lists(quotient_pairs(width), min_size=1, max_size=16))
    n = len(cases)
    D = exact.to_wide([c[0] for c in cases] + [c[2] for c in cases], width)
    rows = [[0, 0, 0, c[1]] for c in cases] + [[0, 0, 0, c[3]] for c in cases]
    X = exact.to_wide(rows, width)
    out = np.zeros(n, np.int8)
    _compare_all(D, X, np.arange(n), np.arange(n) + n, out)
    assert out.tolist() == [_reference_compare(*c) for c in cases]


@jit
def _classify_and_compare_filtered(X, S, F, iu, iv, sides, out):
    for k in range(X.shape[0]):
        sides[k] = plane_value_filtered_into(X, k, S, 0, F)
    for k in range(iu.shape[0]):
        out[k] = compare_filtered_values_at(F, iu[k], iv[k], X, S, 0)


@settings(max_examples=300)
@given(width=widths, data=st.data())
def test_distance_comparison_from_kept_filter_doubles_is_exact(width, data):
    """The cut's classification keeps the filter doubles of x·s and x4 (``plane_value_filtered_into``);
    ``compare_filtered_values_at`` decides from them and forms the products again for close calls: the same signs as
    the exact products (Python ints) over the whole width, from the same doubles ``compare_cached_values_at``
    converts from stored dot products (so the same close calls go exact)."""
    cases = data.draw(st.lists(quotient_pairs(width), min_size=1, max_size=16))
    n = len(cases)
    # vertices (d, 0, 0, w) against the plane x1 = 0: x·s = d exactly
    values = [(c[0], c[1]) for c in cases] + [(c[2], c[3]) for c in cases]
    X = exact.to_wide([[d, 0, 0, w] for d, w in values], width)
    S = exact.to_wide([[1, 0, 0, 0]], width)
    F = np.full((2 * n, 2), np.nan)
    sides, out = np.zeros(2 * n, np.int8), np.zeros(n, np.int8)
    _classify_and_compare_filtered(X, S, F, np.arange(n), np.arange(n) + n, sides, out)
    assert sides.tolist() == [((d > 0) - (d < 0)) * ((w > 0) - (w < 0)) for d, w in values]
    D = exact.to_wide([d for d, _ in values], width)
    if width >= intrinsics.FILTER_COMPARISONS_FROM_BITS:
        converted = np.zeros(2 * n), np.zeros(2 * n)
        _filter_doubles(D.reshape(-1, 1), converted[0])
        _filter_doubles(np.ascontiguousarray(X[:, 3:4]), converted[1])
        assert F[:, 0].tobytes() == converted[0].tobytes() and F[:, 1].tobytes() == converted[1].tobytes()
    assert out.tolist() == [_reference_compare(*c) for c in cases]
    reference = np.zeros(n, np.int8)
    _compare_all(D, X, np.arange(n), np.arange(n) + n, reference)
    assert out.tolist() == reference.tolist()


@jit
def _box_sides_all(corners, sizes, planes, out):
    for k in range(corners.shape[0]):
        out[k] = box_plane_sides(corners, k, sizes[k], planes, k)


@settings(max_examples=300)
@given(width=widths, data=st.data())
def test_box_plane_sides_are_the_corners_signs(width, data):
    """``box_plane_sides`` (a cell box against a convex tool's face plane, from its two extreme corners) against the
    eight corners' n·v + d in Python ints: boxes up to the int64 range, normals and offsets over the whole width
    (every corner value fitting it, as the budget guarantees), values on the plane, planes through a corner."""
    top = (1 << (width - 1)) - 1
    cases = []
    for _ in range(data.draw(st.integers(1, 12))):
        e = data.draw(st.integers(0, 61))
        size = 1 << e
        lo = [data.draw(st.integers(-(1 << 62), (1 << 62) - size)) for _ in range(3)]
        n_bits = data.draw(st.sampled_from([1, 8, 46, 63, 64, width - 66]))
        n = [data.draw(st.one_of(st.integers(-(1 << n_bits), 1 << n_bits), st.just(0))) for _ in range(3)]
        corners = [[lo[c] + (size if k >> c & 1 else 0) for c in range(3)] for k in range(8)]
        through = data.draw(st.integers(-1, 7))  # -1: an offset of any size; k: the plane through corner k
        if through >= 0:
            d = -sum(a * b for a, b in zip(n, corners[through], strict=True)) + data.draw(st.integers(-1, 1))
        else:
            d = data.draw(st.integers(-top // 2, top // 2))
        values = [sum(a * b for a, b in zip(n, v, strict=True)) + d for v in corners]
        assume(all(-top - 1 <= x <= top for x in values) and all(-top - 1 <= x <= top for x in n + [d]))
        cases.append((lo, size, n + [d], values))
    lows = np.array([c[0] for c in cases], np.int64)
    out = np.zeros(len(cases), np.int8)
    _box_sides_all(lows, np.array([c[1] for c in cases], np.int64), exact.to_wide([c[2] for c in cases], width), out)
    assert out.tolist() == [int(min(v) < 0) | 2 * int(max(v) > 0) for *_, v in cases]


@jit
def _wall_sides(points, planes, axes, out, reference):
    for k in range(points.shape[0]):
        out[k] = classify_wall_at(points, k, planes, k, axes[k])
        reference[k] = classify_at(points, k, planes, k)


@settings(max_examples=300)
@given(width=widths, data=st.data())
def test_wall_classification_is_the_exact_side(width, data):
    """``classify_wall_at`` (a cell box's wall: two wide-by-word products) against Python ints and ``classify_at``,
    over the whole width: axis planes with offsets in and beyond 64 bits, normals +-1 and beyond 64 bits, points on
    the wall, and rows that are not axis planes (or name another axis): the general path, the same sign."""
    top = (1 << (width - 1)) - 1
    word = st.integers(-(1 << 63), (1 << 63) - 1)
    rows, points, axes = [], [], []
    for _ in range(data.draw(st.integers(1, 12))):
        axis = data.draw(st.integers(0, 2))
        kind = data.draw(st.sampled_from(["wall", "wide offset", "wide normal", "not a wall", "other axis"]))
        n = [0, 0, 0]
        n[axis] = data.draw(st.sampled_from([1, -1])) if kind != "wide normal" else data.draw(
            st.integers(1 << 64, 1 << 70))
        d = data.draw(st.integers(1 << 64, 1 << 90)) if kind == "wide offset" else data.draw(word)
        if kind == "not a wall":
            n[(axis + 1) % 3] = data.draw(st.integers(1, 1 << 20))
        x = [data.draw(st.integers(-(1 << (width // 2 - 40)), 1 << (width // 2 - 40))) for _ in range(3)]
        w = data.draw(st.integers(-(1 << (width // 2 - 40)), 1 << (width // 2 - 40)).filter(bool))
        if data.draw(st.booleans()) and n[axis] in (1, -1) and kind in ("wall", "other axis"):
            x[axis] = -n[axis] * d * w  # on the wall: n_a x_a + d w = 0
        rows.append(n + [d])
        points.append(x + [w])
        axes.append((axis + 1) % 3 if kind == "other axis" else axis)
    values = [sum(a * b for a, b in zip(r[:3], p[:3], strict=True)) + r[3] * p[3]
              for r, p in zip(rows, points, strict=True)]
    assume(all(-top - 1 <= v <= top for v in values)
           and all(-top - 1 <= c <= top for row in rows + points for c in row))
    out, reference = np.zeros(len(rows), np.int8), np.zeros(len(rows), np.int8)
    _wall_sides(exact.to_wide(points, width), exact.to_wide(rows, width), np.array(axes, np.int64), out, reference)
    expected = [((v > 0) - (v < 0)) * ((p[3] > 0) - (p[3] < 0)) for v, p in zip(values, points, strict=True)]
    assert out.tolist() == expected
    assert reference.tolist() == expected


@jit
def _filter_doubles(V, out):
    for k in range(V.shape[0]):
        out[k] = wide_filter_double_at(V, k, 0)


@settings(max_examples=200)
@given(width=widths, data=st.data())
def test_filter_doubles_are_within_their_bound(width, data):
    """``lowering.filter_double`` (limb by limb, for the float filters): within (1 + 2**-53)**4 - 1 of the exact value,
    checked with Fractions over the whole signed width, at the extremes, at powers of two and just beside them."""
    top = (1 << (width - 1)) - 1
    edges = [0, 1, -1, top, -top - 1] + [s * ((1 << e) + d) for e in (52, 53, 63, 64, 126, width - 2)
                                          for d in (-1, 0, 1) for s in (1, -1) if e < width - 1]
    values = data.draw(st.lists(st.one_of(st.integers(-top - 1, top), st.sampled_from(edges),
                                          st.integers(-(1 << 70), 1 << 70)), min_size=1, max_size=32))
    out = np.zeros(len(values))
    _filter_doubles(exact.to_wide([[v] for v in values], width), out)
    for v, f in zip(values, out, strict=True):
        assert abs(Fraction(f) - v) <= (Fraction((1 << 53) + 1, 1 << 53) ** 4 - 1) * abs(v), (v, f)


@pytest.mark.parametrize("regime", ["normals at the edge", "wide offsets", "offsets at the 128-bit edge"])
@pytest.mark.parametrize("seed", range(3))
def test_normals_at_the_64_bit_edge_take_either_product_and_stay_exact(regime, seed):
    """Full-width 256-bit plane rows whose normals fit in 64 bits are multiplied as wide x word, the others wide x
    wide (``lowering.plane_dot``, ``intrinsics._intersect_full_or_word``, decided row by row at run time), whatever
    the offset's size. Normals at -2^63, 2^63 - 1 (word) and
    2^63, -2^63 - 1 (wide) mixed in one triple, 2^46 normals with offsets far beyond 64 bits (the 256-bit dome
    grid's), and small normals with offsets at -2^127 - 1, -2^127, 2^127 - 1, 2^127 and beyond, must give the exact
    point and sides."""
    width = 256
    rng = np.random.default_rng(seed)
    limit = budget(width).limit
    if regime == "normals at the edge":
        choices, n_bits = [-(1 << 63), (1 << 63) - 1, 1 << 63, -(1 << 63) - 1, 1, -1, 0], 64
    elif regime == "wide offsets":
        choices, n_bits = [(1 << 46) - 1, -(1 << 46), 1, -1, 0], 46
    else:
        choices, n_bits = [(1 << 12) - 1, -(1 << 12), 3, -1, 0], 12
    D = (limit - 1) // (16 * (1 << n_bits) ** 3)  # the offsets the width allows with such normals
    edge = [-(1 << 127) - 1, -(1 << 127), (1 << 127) - 1, 1 << 127, (1 << 127) + 5, -(1 << 140)]
    checked = 0
    for _ in range(40):
        rows = []
        for _ in range(4):
            small = (1 << 11) if n_bits == 12 else (1 << 45)
            normal = [int(rng.choice(choices)) if rng.random() < 0.6 else int(rng.integers(-small, small))
                      for _ in range(3)]
            if not any(normal):
                normal[0] = 1
            if n_bits == 12 and rng.random() < 0.7:
                offset = int(rng.choice(edge)) + int(rng.integers(-2, 3))
            else:
                offset = int(rng.integers(-(1 << 62), 1 << 62)) * (D >> 62) or int(rng.integers(-D, D + 1))
            rows.append(normal + [offset])
        p, q, r, s = rows
        point = solve_3_planes(p, q, r)
        if point is None:
            continue
        wide = exact.to_wide(rows, width)
        x = as_ints(exact.intersect_3_planes(wide[0], wide[1], wide[2]))
        assert x[3] == -det3([p[:3], q[:3], r[:3]])
        assert [Fraction(x[i], x[3]) for i in range(3)] == point
        assert exact.classify_vertex(exact.to_wide(x, width), wide[3]) == side(point, s)
        assert exact.classify_vertex(exact.to_wide(x, width), wide[:3]).tolist() == [0, 0, 0]
        checked += 1
    assert checked >= 20
