"""Exact convex hulls (csgnb.mesh.hull) against brute-force facet enumeration with Python ints.

The reference enumerates every plane through three points with Python ints, keeps those
with all points on one side, and reduces them: the facet planes of the hull, by
definition. Volumes are checked against the exact BSP boundary of the hull's linear BSP
(an independent code path: mesh cutting) and against qhull's float volume.
"""

from __future__ import annotations

import itertools
from fractions import Fraction
from math import gcd

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb import GeometryError, PrecisionError
from csgnb.exact import budget, from_wide
from csgnb.mesh.hull import BRUTE_FORCE_POINTS, _gift_wrap, _qhull_facets, convex_hull, small_hulls


def reference_planes(points) -> set[tuple[int, int, int, int]]:
    """Facet planes of conv(points): all supporting planes through 3 points, reduced, outward (Python ints)."""
    P = sorted({tuple(int(x) for x in p) for p in points})
    out = set()
    for a, b, c in itertools.combinations(P, 3):
        u = [b[i] - a[i] for i in range(3)]
        v = [c[i] - a[i] for i in range(3)]
        n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        if not any(n):
            continue
        d = -sum(n[i] * a[i] for i in range(3))
        s = [sum(n[i] * p[i] for i in range(3)) + d for p in P]
        if all(x <= 0 for x in s):
            sign = 1
        elif all(x >= 0 for x in s):
            sign = -1
        else:
            continue
        g = gcd(*n)
        out.add((sign * n[0] // g, sign * n[1] // g, sign * n[2] // g, sign * d // g))
    return out


def hull_planes(h) -> set[tuple[int, ...]]:
    return {tuple(int(x) for x in row) for row in h.planes}


coords = st.integers(-12, 12)
point = st.tuples(coords, coords, coords)


@st.composite
def point_sets(draw):
    """Random points, often with many on a few planes or lines (coplanar facets, collinear edge points)."""
    pts = draw(st.lists(point, min_size=4, max_size=24))
    if draw(st.booleans()):  # a grid of coplanar points on an axis plane and a diagonal plane
        z = draw(coords)
        pts += [(x, y, z) for x in (-4, 0, 4) for y in (-4, 0, 4)]
        pts += [(t, t, draw(coords)) for t in (-6, -3, 0, 3, 6)]
    return np.array(pts, np.int64)


def full_dimensional(P) -> bool:
    Q = np.unique(P, axis=0)
    return np.linalg.matrix_rank((Q - Q[0]).astype(float)) == 3 if len(Q) >= 4 else False


@given(point_sets())
def test_facets_equal_brute_force_enumeration(P):
    if not full_dimensional(P):
        with pytest.raises(GeometryError, match="degenerate"):
            convex_hull(P)
        return
    h = convex_hull(P)
    ref = reference_planes(P)
    assert hull_planes(h) == ref
    # Vertices: exactly the points that are on three facets with independent normals.
    vertices = set()
    for p in {tuple(x) for x in P.tolist()}:
        normals = [n[:3] for n in ref if sum(n[i] * p[i] for i in range(3)) + n[3] == 0]
        if len(normals) >= 3 and np.linalg.matrix_rank(np.array(normals, float)) == 3:
            vertices.add(p)
    assert {tuple(x) for x in h.points.tolist()} == vertices
    # Faces: one per plane, each vertex on its plane, counter-clockwise seen from outside.
    for f, plane in zip(h.faces, h.planes, strict=True):
        pts = [[int(x) for x in h.points[i]] for i in f]
        n = [int(x) for x in plane[:3]]
        assert all(sum(n[i] * p[i] for i in range(3)) + int(plane[3]) == 0 for p in pts)
        area = [0, 0, 0]
        for a, b in zip(pts, pts[1:] + pts[:1], strict=True):
            area = [area[0] + a[1] * b[2] - a[2] * b[1], area[1] + a[2] * b[0] - a[0] * b[2],
                    area[2] + a[0] * b[1] - a[1] * b[0]]
        assert sum(n[i] * area[i] for i in range(3)) > 0


@given(point_sets())
@settings(max_examples=25)
def test_volume_matches_bsp_boundary_and_qhull(P):
    if not full_dimensional(P):
        return
    from scipy.spatial import ConvexHull as Qhull

    h = convex_hull(P)
    v = h.volume()
    assert isinstance(v, Fraction)
    assert v == h.to_bsp().volume()
    assert float(v) == pytest.approx(Qhull(P.astype(float)).volume, rel=1e-9)


@given(point_sets(), st.lists(point, min_size=1, max_size=30))
def test_contains_is_exact(P, queries):
    if not full_dimensional(P):
        return
    h = convex_hull(P)
    ref = reference_planes(P)
    Q = np.array(queries, np.int64)
    expect = [all(sum(n[i] * q[i] for i in range(3)) + n[3] <= 0 for n in ref) for q in queries]
    strict = [all(sum(n[i] * q[i] for i in range(3)) + n[3] < 0 for n in ref) for q in queries]
    assert h.contains(Q).tolist() == expect
    assert h.contains(Q, strict=True).tolist() == strict
    assert h.contains(P).all()
    # The linear BSP agrees with contains() away from the boundary.
    labels = h.to_bsp().classify(Q)
    for lab, inside, strictly in zip(labels, expect, strict, strict=True):
        if strictly:
            assert lab == 1
        elif not inside:
            assert lab == 0


def test_qhull_path_and_gift_wrapping_agree_on_larger_sets():
    rng = np.random.default_rng(7)
    for n in (40, 120, 400):
        v = rng.normal(size=(n, 3))
        P = np.rint(v / np.linalg.norm(v, axis=1)[:, None] * 300).astype(np.int64)
        P = np.unique(P, axis=0)
        L = P - P[0]
        from csgnb.mesh.hull import _independent

        q = _qhull_facets(L, _independent(L))
        assert q is not None
        g = _gift_wrap(L)
        assert np.array_equal(q[0], g[0]) and np.array_equal(q[1], g[1])
        assert hull_planes(convex_hull(P)) == {tuple(int(x) for x in r) + (int(e),)
                                                for r, e in zip(g[0], g[1] - g[0] @ P[0], strict=True)}


def test_nearly_flat_sets_are_exact():
    """A dense flat grid with one point a unit off the plane: qhull's float facets are checked or replaced."""
    xs = np.arange(-300, 301, 20)
    flat = np.array([(x, y, (x + 2 * y) // 7 * 0 + 0) for x in xs for y in xs], np.int64)
    for apex in ([1, 2, 1], [299, -299, -1], [0, 0, 1]):
        P = np.vstack([flat, [apex]])
        h = convex_hull(P)
        assert h.n_planes == 5  # the square base and four triangles to the apex
        assert h.volume() == Fraction(600 * 600 * 1, 3)
        L = np.unique(P, axis=0)
        L = L - L[0]
        N, d = _gift_wrap(L)
        assert N.shape[0] == 5
    # Points a unit off a tilted plane, many coplanar ones: brute-force reference on a subset size.
    rng = np.random.default_rng(3)
    base = rng.integers(-50, 51, (BRUTE_FORCE_POINTS + 20, 2))
    P = np.column_stack([base, base[:, 0] * 3 + base[:, 1] * 5])
    P = np.vstack([P, [[0, 0, 1]]])
    assert hull_planes(convex_hull(P)) == reference_planes(P)


@pytest.mark.parametrize("points, what", [
    ([[1, 2, 3]] * 5, "same point"),
    ([[0, 0, 0], [1, 1, 1], [2, 2, 2], [5, 5, 5]], "collinear"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 4, 0], [7, 1, 0]], "coplanar"),
    ([[x, y, x + y] for x in range(4) for y in range(4)], "coplanar"),
])
def test_degenerate_sets_raise_a_clear_error(points, what):
    with pytest.raises(GeometryError, match=what):
        convex_hull(np.array(points, np.int64))


def test_budget_is_enforced_with_the_bound_named():
    V = budget(128).max_mesh_coordinate
    ok = np.array([[0, 0, 0], [V, 0, 0], [0, V, 0], [0, 0, -V]], np.int64)
    convex_hull(ok, width=128)
    with pytest.raises(PrecisionError, match="eq. 8"):
        convex_hull(ok + [1, 0, 0], width=128)
    h = convex_hull(ok + [1, 0, 0], width=256)
    with pytest.raises(PrecisionError, match="eq. 8"):
        h.planes_wide(128)
    with pytest.raises(TypeError, match="integer"):
        convex_hull(ok.astype(float))


def test_wide_coordinates_use_python_ints_exactly():
    """At the 256-bit budget, normals and offsets exceed int64: planes are Python ints, still exact."""
    V = budget(256).max_mesh_coordinate
    P = np.array([[-V, -V, -V], [V, -V, -V], [-V, V, -V], [-V, -V, V], [V, V, V], [3, -V, 7], [V, 5, -V + 1]],
                 np.int64)
    h = convex_hull(P, width=256)
    assert hull_planes(h) == reference_planes(P)
    assert h.planes.dtype == object or np.abs(h.planes).max() < 2**63
    wide = from_wide(h.planes_wide())
    assert [[int(x) for x in r] for r in wide] == [[int(x) for x in r] for r in h.planes]
    big = np.unique(np.vstack([P, np.rint(np.random.default_rng(0).uniform(-V, V, (40, 3)))]).astype(np.int64),
                    axis=0)
    assert hull_planes(convex_hull(big, width=256)) == hull_planes(convex_hull(big, width=256))
    Lb = big - big[0]
    g = _gift_wrap(Lb)
    assert {tuple(int(x) for x in r) for r in g[0]} == {tuple(int(x) for x in r[:3])
                                                        for r in convex_hull(big, width=256).planes}


@given(st.lists(st.tuples(point, point, point), min_size=1, max_size=6), point)
def test_small_hulls_equal_convex_hull(tris, move):
    """Prisms (a triangle at two poses): batch enumeration equals the single hull, flat ones are None."""
    A = np.array(tris, np.int64)  # (m, 3, 3)
    B = A + np.array(move)
    batch = small_hulls(np.concatenate([A, B], axis=1))
    for h, a, b in zip(batch, A, B, strict=True):
        P = np.vstack([a, b])
        if not full_dimensional(P):
            assert h is None
            continue
        assert hull_planes(h) == reference_planes(P)
        assert h.volume() == convex_hull(P).volume()


def test_translation_is_exact():
    rng = np.random.default_rng(5)
    P = rng.integers(-30, 31, (25, 3))
    h = convex_hull(P)
    t = np.array([7, -3, 11])
    moved = h.translated(t)
    assert hull_planes(moved) == hull_planes(convex_hull(P + t))
    assert moved.volume() == h.volume()
    assert np.array_equal(moved.points, h.points + t)
    with pytest.raises(TypeError):
        h.translated(np.array([0.5, 0, 0]))


axis_heavy = st.one_of(point, st.tuples(coords, st.just(0), st.just(0)), st.tuples(st.just(0), coords, coords),
                       st.tuples(coords, coords, st.just(0)))


@given(point_sets(), axis_heavy, point)
def test_swept_hull_is_the_hull_of_both_poses(P, t, u):
    """hull.swept(t) (facets and silhouette edges, no hull search) is exactly convex_hull of the points at both
    poses: the same planes in the same order, the same box, faces and volume -- also for moves parallel to facets
    and edges (axis moves of a box-like set), where facets with n·t = 0 are stretched, not duplicated; and with an
    offset, the sweep of the translated hull."""
    if not full_dimensional(P):
        return
    h = convex_hull(P)
    t = np.array(t, np.int64)
    swept = h.swept(t)
    ref = convex_hull(np.vstack([P, P + t]))
    assert np.array_equal(swept.planes, ref.planes)
    assert np.array_equal(swept.lo, ref.lo) and np.array_equal(swept.hi, ref.hi)
    assert np.array_equal(swept.points, ref.points)
    assert swept.volume() == ref.volume()  # (convex_hull itself is checked against brute force above)
    u = np.array(u, np.int64)
    moved = h.swept(t, offset=u)
    assert np.array_equal(moved.planes, convex_hull(np.vstack([P + u, P + u + t])).planes)
    assert np.array_equal(moved.planes, h.translated(u).swept(t).planes)


def test_swept_tools_equal_hulls_of_both_poses_and_refuse_bad_input():
    from csgnb.apps import tools
    from csgnb.exact import Grid

    g = Grid.from_resolution(1 / 64)
    rng = np.random.default_rng(3)
    for shape in (tools.flat_end_mill(6, 12, segments=12), tools.ball_end_mill(4, 8, segments=16),
                  tools.bull_nose(6, 1, 10, segments=10), tools.v_bit(6, 90, segments=8)):
        tool = shape.on(g)
        for t in ([640, 0, 0], [0, 0, -128], [300, -300, 0], list(rng.integers(-900, 900, 3))):
            a = rng.uniform(-5, 5, 3)
            b = a + np.array(t) / g.scale
            fast = tool.hull_at(a, b)
            ref = convex_hull(np.vstack([tool.at(a), tool.at(b)]), width=g.width, grid=g)
            assert np.array_equal(fast.planes, ref.planes) and fast.grid is g
            assert fast.volume() == ref.volume()
    # A move longer than the budget box's half width: the budget holds for the poses, not for the move vector.
    tool = tools.flat_end_mill(6, 12, segments=12).on(g)
    a, b = (-34.4, 0, 0), (34.4, 0, 0)
    assert int(np.abs(tool.tip(b) - tool.tip(a)).max() + np.abs(tool.offsets).max()) > g.max_coordinate
    ref = convex_hull(np.vstack([tool.at(a), tool.at(b)]), width=g.width, grid=g)
    assert np.array_equal(tool.hull_at(a, b).planes, ref.planes)
    h = convex_hull(rng.integers(-9, 9, (12, 3)))
    assert h.swept(np.zeros(3, np.int64)) is h
    with pytest.raises(TypeError):
        h.swept(np.array([0.5, 0, 0]))
    V = budget(128).max_mesh_coordinate
    with pytest.raises(PrecisionError):
        h.swept(np.array([V, 0, 0]))


def test_mesh_output_is_a_valid_closed_mesh():
    from csgnb.bsp.build import validate_mesh

    rng = np.random.default_rng(11)
    h = convex_hull(rng.integers(-40, 41, (60, 3)))
    V, T = h.to_mesh()
    W, _ = validate_mesh(V, T)
    assert len(W) == len(V)
    assert len(T) == sum(len(f) - 2 for f in h.faces)


class _BadQhull:
    """Stands in for scipy's ConvexHull with wrong combinatorics, to prove the exact checks catch it."""

    mode = "drop"

    def __init__(self, points):
        import scipy.spatial

        if self.mode == "raise":
            raise scipy.spatial.QhullError("simulated qhull failure")
        s = _REAL_QHULL(points).simplices.copy()
        if self.mode == "drop":
            s = s[1:]
        elif self.mode == "inner":
            s[0] = [0, 1, 2] if not np.array_equal(s[0], [0, 1, 2]) else [0, 1, 3]
        elif self.mode == "duplicate":
            s = np.vstack([s, s[:1]])
        self.simplices = s


from scipy.spatial import ConvexHull as _REAL_QHULL  # noqa: E402


@pytest.mark.parametrize("mode", ["drop", "inner", "duplicate", "raise"])
def test_wrong_qhull_output_is_detected_and_replaced(monkeypatch, mode):
    import scipy.spatial

    rng = np.random.default_rng(13)
    P = np.unique(rng.integers(-20, 21, (40, 3)), axis=0)
    expect = reference_planes(P)
    monkeypatch.setattr(_BadQhull, "mode", mode)
    monkeypatch.setattr(scipy.spatial, "ConvexHull", _BadQhull)
    L = P - P[0]
    from csgnb.mesh.hull import _independent

    if mode != "duplicate":  # a repeated triangle is the same plane: harmless, and accepted
        assert _qhull_facets(L, _independent(L)) is None
    from csgnb.mesh import hull as H

    monkeypatch.setattr(H, "_incremental_facets", lambda L, basis, rings=None: None)  # qhull's path, then wrapping
    assert hull_planes(convex_hull(P)) == expect


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([3, 40, 10**6, 8 * 10**7]), st.integers(11, 60))
def test_compiled_face_rings_match_the_python_reference(seed, extent, n):
    """The compiled face rings and closure check (int64) agree with the Python-integer ones, ring for ring, on
    hulls with many coplanar and collinear points (small extents) and on wide ones; and both refuse the same
    incomplete or duplicated plane sets."""
    from csgnb.mesh import hull as H

    rng = np.random.default_rng(seed)
    P = rng.integers(-extent, extent + 1, (n, 3))
    try:
        h = convex_hull(P, width=256)
    except GeometryError:
        return
    L, N = h._candidates, h._normals
    S = h._side(L)
    for j, ring in enumerate(h._faces_local):
        on = np.flatnonzero(S[:, j] == 0)
        assert np.array_equal(ring, on[H._polygon_order(L[on], N[j])])
    assert H._faces_close(L, N, h._d_local, S) and H._faces_close_py(L, N, S)
    k = N.shape[0]
    for keep in (np.delete(np.arange(k), rng.integers(k)), np.r_[np.arange(k), rng.integers(k)]):
        Nk, dk, Sk = N[keep], h._d_local[keep], S[:, keep]
        assert H._faces_close(L, Nk, dk, Sk) == H._faces_close_py(L, Nk, Sk) is False


@pytest.mark.parametrize("extent", [280_000, "budget"])
def test_face_rings_at_the_edges_of_their_paths(extent):
    """The compiled rings take int64 points below 2**62 (their cross products in i128), whatever the size of the
    signed values (Python ints at the 256-bit mesh budget, local ~175 M): they agree with the Python reference
    ring for ring at ~560,000 and at the budget, and the hull is exact."""
    from csgnb.exact import budget
    from csgnb.mesh import hull as H

    V = budget(256).max_mesh_coordinate if extent == "budget" else extent
    rng = np.random.default_rng(3)
    P = np.r_[np.array([[x, y, z] for x in (-V, V) for y in (-V, V) for z in (-V, V)]),
              rng.integers(-V, V + 1, (40, 3)), [[V, 0, 0], [0, V, 0], [V, V, 0]]]
    h = convex_hull(P, width=256)
    L, N = h._candidates, h._normals
    S = h._side(L)
    assert H._rings_fit_int64(L)  # i128 cross products: the compiled path at every width's budget
    for j, ring in enumerate(h._faces_local):
        on = np.flatnonzero(S[:, j] == 0)
        assert np.array_equal(ring, on[H._polygon_order(L[on], N[j])])
    assert H._faces_close(L, N, h._d_local, S) and H._faces_close_py(L, N, S)
    assert h.volume() == (2 * V) ** 3


def test_sorted_unique_planes_int64_path_is_the_python_order():
    """The int64 fast path (unique rows by a lexsort) gives the planes the Python-int path gives: the same set in the
    same lexicographic order, duplicates dropped (the hull's facet order depends on it)."""
    import numpy as np

    from csgnb.mesh.hull import _sorted_unique_planes

    rng = np.random.default_rng(3)
    for trial in range(100):
        n = int(rng.integers(1, 80))
        N = rng.integers(-4, 5, (n, 3))
        d = rng.integers(-3, 4, n) if trial % 2 else rng.integers(-(1 << 50), 1 << 50, n)
        fast = _sorted_unique_planes(N, d)
        slow = _sorted_unique_planes(N.astype(object), d.astype(object))
        assert np.array_equal(fast[0], slow[0].astype(np.int64)) and np.array_equal(fast[1], slow[1].astype(np.int64))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 60), st.integers(1, 5),
       st.sampled_from([2, 7, 1 << 20, (1 << 62) - 1]))
def test_unique_rows_is_numpys_row_unique(seed, n, k, extent):
    """The hull's row deduplication (a lexsort and a neighbour comparison, not np.unique's structured view) gives
    np.unique(axis=0)'s rows in np.unique's order, on int64 rows with duplicates, negatives and the int64 extremes."""
    import numpy as np

    from csgnb.mesh.hull import _unique_rows

    rng = np.random.default_rng(seed)
    M = rng.integers(-extent, extent, (n, k), endpoint=True, dtype=np.int64)
    if n > 2:
        M[rng.integers(0, n, n // 2)] = M[rng.integers(0, n, n // 2)]  # duplicates
        M[0, 0] = np.iinfo(np.int64).min if seed % 2 else np.iinfo(np.int64).max
    assert np.array_equal(_unique_rows(M), np.unique(M, axis=0))
    assert _unique_rows(M).dtype == np.int64


def _local_points(seed: int, extent: int, n: int):
    """Random distinct grid points in [-extent, extent]³, in coordinates local to the first, and four affinely
    independent ones among them (``None`` when the set is flat)."""
    from csgnb.mesh import hull as H

    rng = np.random.default_rng(seed)
    P = np.unique(rng.integers(-extent, extent + 1, (n, 3)), axis=0)
    L = P - P[0]
    basis = H._independent(L)
    return None if basis is None else (L, basis)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([2 * 10**5, 10**7, 8 * 10**7]), st.integers(8, 80))
def test_wide_qhull_path_equals_the_python_int_path(seed, extent, n):
    """On wide grids the facets' offsets are Python ints: the compiled verification (signs in i128 against each
    facet's anchor point) gives the planes of the Python-integer computation, in the same order, and a hull's
    signs of points against its facets (_side_signs, offsets split in two int64 halves) are the exact ones."""
    from csgnb.mesh import hull as H

    found = _local_points(seed, extent, n)
    if found is None:
        return
    L, basis = found
    wide = H._qhull_facets(L, basis)
    slow = H._qhull_facets(L.astype(object), basis)  # object points: the Python-integer path throughout
    assert (wide is None) == (slow is None)
    if wide is None:
        return
    assert [list(map(int, r)) for r in wide[0]] == [list(map(int, r)) for r in slow[0]]
    assert [int(v) for v in wide[1]] == [int(v) for v in slow[1]]
    N, d = wide
    exact = H._object(L) @ H._object(N).T + H._object(d)[None, :]
    if H._signs_fit(int(np.abs(L).max()), np.asarray(N, np.int64), d):
        signs = H._side_signs(L.astype(np.int64), np.asarray(N, np.int64), *H._split_offsets(d))
        assert np.array_equal(signs, np.sign(exact).astype(np.int8))


@settings(max_examples=120, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([2, 3, 40, 1000, (1 << 16) - 1, (1 << 28) - 1]), st.integers(5, 90))
def test_compiled_qhull_verification_equals_the_python_int_path(seed, extent, n):
    """Below a local extent of 2**29 qhull's triangles are turned into planes and verified in one compiled kernel
    (_verified_facets, signs in i128): the same planes in the same order as the Python-integer path, or None exactly
    when it gives None; _independent's compiled path picks the same four points."""
    from csgnb.mesh import hull as H

    rng = np.random.default_rng(seed)
    P = np.unique(rng.integers(-extent, extent + 1, (n, 3)), axis=0)
    L = P - P[0]
    basis = H._independent(L)
    slow_basis = H._independent(L.astype(object))
    assert (basis is None) == (slow_basis is None)
    if basis is None:
        return
    assert [int(i) for i in basis] == [int(i) for i in slow_basis]
    assert int(np.abs(L).max()) < H._COMPILED_FACETS_SAFE
    fast = H._qhull_facets(L, basis)
    slow = H._qhull_facets(L.astype(object), basis)
    assert (fast is None) == (slow is None)
    if fast is not None:
        assert fast[0].dtype == np.int64  # offsets: int64 where they fit, Python ints beyond
        assert [list(map(int, r)) + [int(v)] for r, v in zip(*fast, strict=True)] == \
               [list(map(int, r)) + [int(v)] for r, v in zip(*slow, strict=True)]


@pytest.mark.parametrize("side", [2, 5, 9])
def test_face_rings_of_dense_faces_sort_by_both_paths(side):
    """Faces with more points than the insertion sort takes (_INSERTION_SORT_POINTS) are sorted by argsorts: a
    full cube of grid points (side + 1)² per face gives the Python reference's rings and the cube's volume."""
    from csgnb.mesh import hull as H

    g = np.arange(side + 1)
    P = np.array(np.meshgrid(g, g, g, indexing="ij")).reshape(3, -1).T
    h = convex_hull(P)
    L, N = h._candidates, h._normals
    S = h._side(L)
    assert max(int(np.sum(S[:, j] == 0)) for j in range(N.shape[0])) == (side + 1) ** 2
    for j, ring in enumerate(h._faces_local):
        on = np.flatnonzero(S[:, j] == 0)
        assert np.array_equal(ring, on[H._polygon_order(L[on], N[j])])
    assert h.volume() == side**3 and len(h.faces) == 6 and all(len(f) == 4 for f in h.faces)


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 2, 3, 40, 1000, (1 << 16) - 1, 175_000_000]), st.integers(5, 120))
def test_incremental_hull_equals_the_python_int_path(seed, extent, n):
    """The compiled exact incremental hull (small local extents) is verified and gives the planes of the
    Python-integer qhull path, in the same order -- on grids of a few units (many coplanar and collinear points,
    points inside faces and edges) and on wide ones."""
    from csgnb.mesh import hull as H

    found = _local_points(seed, extent, n)
    if found is None:
        return
    L, basis = found
    fast = H._incremental_facets(L, basis)
    assert fast is not None  # exact signs: it never needs the fallback
    slow = H._qhull_facets(L.astype(object), basis)
    if slow is None:
        slow = H._gift_wrap(L.astype(object))
    assert [list(map(int, r)) + [int(v)] for r, v in zip(*fast, strict=True)] == \
           [list(map(int, r)) + [int(v)] for r, v in zip(*slow, strict=True)]


def test_a_faulty_incremental_hull_falls_back(monkeypatch):
    """Triangles missing from the incremental hull fail the exact verification: convex_hull takes qhull's and
    the hull is still exact."""
    from csgnb.mesh import hull as H

    rng = np.random.default_rng(5)
    P = np.unique(rng.integers(-30, 31, (50, 3)), axis=0)
    expect = reference_planes(P)
    real = H._incremental_triangles
    monkeypatch.setattr(H, "_incremental_triangles", lambda L, basis: real(L, basis)[1:])
    L = P - P[0]
    assert H._incremental_facets(L, H._independent(L)) is None
    assert hull_planes(convex_hull(P)) == expect


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(1, BRUTE_FORCE_POINTS), st.sampled_from([1, 3, 1000]))
def test_unique_rows_per_set_is_unique_rows_of_each(seed, m, k, extent):
    """small_hulls deduplicates all its sets in one compiled pass: each set's rows are _unique_rows' (np.unique's)
    rows in their order, repeated points included, and each box is the set's min and max."""
    from csgnb.mesh import hull as H

    rng = np.random.default_rng(seed)
    L = rng.integers(-extent, extent + 1, (m, k, 3))
    L[:, -1] = L[:, 0]  # a repeated point in every set
    points, first, lo, hi = H._unique_rows_per_set(L)
    assert first[0] == 0 and first[-1] == points.shape[0]
    for h in range(m):
        assert points[first[h]:first[h + 1]].tolist() == np.unique(L[h], axis=0).tolist()
        assert lo[h].tolist() == L[h].min(axis=0).tolist() and hi[h].tolist() == L[h].max(axis=0).tolist()


@pytest.mark.parametrize("name", ["airplane.ply", "ant.ply", "nut.ply", "sphere.ply", "globe.vtk", "hexbeam.vtk"])
@pytest.mark.parametrize("width", [128, 256])
def test_hulls_of_public_meshes(name, width):
    """Meshes written by others (pyvista's shipped examples), quantized on a fitted grid: the compiled incremental
    hull gives the Python-integer qhull path's planes in its order, convex_hull holds every point, and its exact
    volume is qhull's float volume of the same grid points."""
    import os

    import pyvista as pv
    import scipy.spatial

    from csgnb.exact import Grid
    from csgnb.mesh import hull as H

    P = np.asarray(pv.read(os.path.join(os.path.dirname(pv.examples.__file__), name)).points, float)
    Q = np.unique(Grid.fit(P.min(axis=0), P.max(axis=0), width=width).to_grid(P), axis=0)
    L = Q - Q[0]
    basis = H._independent(L)
    fast = H._incremental_facets(L, basis)
    slow = H._qhull_facets(L.astype(object), basis)
    assert fast is not None and slow is not None
    assert [list(map(int, r)) + [int(v)] for r, v in zip(*fast, strict=True)] == \
           [list(map(int, r)) + [int(v)] for r, v in zip(*slow, strict=True)]
    h = convex_hull(Q, width=width)
    assert h.contains(Q).all()
    assert float(h.volume()) == pytest.approx(scipy.spatial.ConvexHull(Q.astype(float)).volume, rel=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_small_hulls_at_256_bit_extents_equal_the_exact_hull(seed):
    """Prisms too large for int64 distances (a 256-bit drill's: local extents of 2**20-2**29) take small_hulls'
    double-filtered path: translated triangles (quads exactly planar: exact zeros the doubles cannot see), triangles
    moved within their plane (flat: None), one vertex a unit off a quad's plane, a point one unit beside a plane
    with a ~2**44 normal far from the set's first point, and random ones -- each with the
    general exact hull's planes (and the Python-integer brute force's) and volume."""
    from csgnb.mesh import hull as H

    rng = np.random.default_rng(seed)
    big = int(rng.integers(2**20, 2**22))  # the 256-bit mesh budget: |coordinate| <= 87,298,202 (~2**26.4)
    sets = []
    for _ in range(12):
        tri = rng.integers(-big, big + 1, (3, 3))
        kind = rng.integers(0, 4)
        if kind == 0:  # a translation: the prism's three quads planar
            moved = tri + rng.integers(-big, big + 1, 3)
        elif kind == 1:  # moved within the triangle's own plane: flat
            moved = tri + (tri[1] - tri[0]) * int(rng.integers(-3, 4)) + (tri[2] - tri[0]) * int(rng.integers(-3, 4))
        elif kind == 2:  # a translation with one vertex one unit off the quad's plane
            moved = tri + rng.integers(-big, big + 1, 3)
            moved[int(rng.integers(0, 3)), int(rng.integers(0, 3))] += 1
        else:
            moved = rng.integers(-big, big + 1, (3, 3))
        sets.append(np.vstack([tri, moved]))
    for _ in range(6):  # a point one unit beside a plane whose normal is ~2**44 long, seen from a far set origin:
        # the distance is 1, its double terms ~2**67 (a bound of 2**-70 instead of 2**-48 fails here)
        X, Y = (int(v) for v in rng.integers(big // 2, big, 2))
        a = rng.integers(-big // 4, big // 4 + 1, 3)
        q = a - rng.integers(big // 2, big, 3)
        n = np.array([1, -X, X * Y], object)  # (X, 1, 0) x (0, Y, 1)
        side = 1 if int(n @ (q - a).astype(object)) < 0 else -1  # the unit step away from q's side
        r = a - rng.integers(big // 2, big, 3)
        sets.append(np.vstack([q, a, a + [X, 1, 0], a + [0, Y, 1], a + [side, Y, 1], r]))
    P = np.array(sets, np.int64)
    E = int(np.abs(P - P[:, :1]).max())
    assert H._arith(E) is object and E <= H.SMALL_HULLS_FILTERED_EXTENT  # the filtered path, not int64's
    for h, S in zip(small_hulls(P, width=256), P, strict=True):
        try:
            ref = convex_hull(S, width=256)
        except GeometryError:
            assert h is None
            continue
        assert h is not None and hull_planes(h) == hull_planes(ref) == reference_planes(S)
        assert h.volume() == ref.volume()
        assert h.contains(S).all()


def test_small_hulls_local_offsets_around_2_63():
    """small_hulls decides in bulk, from doubles, which sets' local offsets fit in int64 (and forms those by an int64
    sum that wraps on the way): tetrahedra with a facet whose offset is 2**63 + delta, for delta from -2**13 to
    2**13 (both signs), have the exact hull's planes, and their offsets are int64 exactly when every one of the
    set's fits -- what _maybe_int64 gives."""
    from csgnb.mesh import hull as H

    X = Y = (1 << 21) + 7
    u, v = np.array([X, 1, 0]), np.array([0, Y, 1])  # n = u x v = (1, -X, X Y): gcd 1
    sets, targets = [], []
    for delta in (-(1 << 13), -(1 << 12) - 1, -(1 << 12), -(1 << 11), -1, 0, 1, 1 << 11, 1 << 12, (1 << 12) + 1,
                  1 << 13):
        for sign in (1, -1):
            target = sign * ((1 << 63) + delta)  # n . a
            q, r = divmod(target, X * Y)
            a = np.array([r % X, -(r // X), q], np.int64)
            assert 1 * int(a[0]) - X * int(a[1]) + X * Y * int(a[2]) == target
            sets.append(np.vstack([np.zeros(3, np.int64), a, a + u, a + v]))
            targets.append(target)
    P = np.array(sets, np.int64)
    assert H._arith(int(np.abs(P).max())) is object  # the double-filtered path
    for h, S, target in zip(small_hulls(P, width=256), P, targets, strict=True):
        ref = convex_hull(S, width=256)
        assert h is not None and hull_planes(h) == hull_planes(ref) == reference_planes(S)
        d = [int(x) for x in h._d_local]
        assert abs(target) in {abs(x) for x in d}
        fits = all(abs(x) < (1 << 63) for x in d)  # (_maybe_int64: |d| < 2**63, -2**63 too stays a Python int)
        assert (h._d_local.dtype == np.int64) == fits, (target, d)


@pytest.mark.parametrize("seed", range(4))
def test_independent_points_compiled_at_wide_extents_match_python_ints(seed):
    """``_independent`` takes its compiled path up to local extents of 2**29 (a 256-bit grid's capsule: 2**22), the
    last test's sign in i128: the same four indices as the Python-int path, and None for flat sets (a line, a plane
    through the origin) whose products reach far beyond int64."""
    from csgnb.mesh.hull import _independent

    rng = np.random.default_rng(seed)
    E = 1 << int(rng.integers(20, 29))
    generic = rng.integers(-E, E, size=(30, 3))
    generic[0] = 0
    u, v = rng.integers(-E // 64, E // 64, size=(2, 3))
    t = rng.integers(-8, 8, size=(30, 2))
    plane = t[:, :1] * u + t[:, 1:] * v  # every row a combination of u and v: flat
    line = t[:, :1] * u
    plane[0] = line[0] = 0
    for L in (generic, plane, line):
        compiled = _independent(L.astype(np.int64))
        reference = _independent(L.astype(object))
        assert (compiled is None) == (reference is None)
        if reference is not None:
            assert compiled.tolist() == reference.tolist()
    assert _independent(plane.astype(np.int64)) is None and _independent(line.astype(np.int64)) is None


@pytest.mark.parametrize("seed", range(3))
def test_exact_row_dots_match_python_ints_at_their_edges(seed):
    """``_exact_row_dots`` (a 256-bit hull's offsets, split at 2**31 into two int64 dots): equal to Python ints for
    normals anywhere in int64 (-2**63 and 2**63 - 1 included) and points up to 2**29 - 1, int64 exactly when every
    value fits and Python ints otherwise."""
    from csgnb.mesh.hull import _exact_row_dots

    rng = np.random.default_rng(seed)
    for bits in (8, 31, 32, 47, 62, 64):
        N = rng.integers(-(1 << (bits - 1)), (1 << (bits - 1)) - 1, size=(40, 3), dtype=np.int64, endpoint=True)
        P = rng.integers(-(1 << 29) + 1, (1 << 29) - 1, size=(40, 3), dtype=np.int64, endpoint=True)
        N[0], P[0] = [-(1 << 63), (1 << 63) - 1, -(1 << 63)], [(1 << 29) - 1, -(1 << 29) + 1, (1 << 29) - 1]
        N[1], P[1] = [-(1 << 63), -(1 << 63), -(1 << 63)], [-(1 << 29) + 1] * 3  # the largest positive sum
        got = _exact_row_dots(N, P)
        expected = [sum(int(a) * int(b) for a, b in zip(n, p, strict=True)) for n, p in zip(N, P, strict=True)]
        assert [int(v) for v in got] == expected
        assert (got.dtype == np.int64) == all(-(1 << 63) <= v < (1 << 63) for v in expected)


@pytest.mark.parametrize("d_bits", [0, 40, 61, 62, 63, 70])
def test_split_planes_equal_python_ints_when_offsets_and_shifts_near_int64(d_bits):
    """``ConvexHull._split_planes`` (the planes of 256-bit hull tools, single and batched): d = d_local - N·origin
    equal to Python ints when d_local and the shift N·origin approach or pass 2**62 and 2**63 (a shift of ~5.8e18
    once came back int64 and was subtracted in int64: a plane offset off by 2**64, no error)."""
    from csgnb.mesh.hull import ConvexHull

    rng = np.random.default_rng(d_bits)
    for _ in range(20):
        # normals just below 2**33 and an origin just below 2**28: shifts N·origin between 2**62 and 2**63 (int64),
        # and offsets of the other sign, so that d_local - shift passes 2**63 in magnitude
        N = rng.integers((1 << 33) - (1 << 30), 1 << 33, size=(5, 3), dtype=np.int64) * rng.choice([-1, 1], (5, 1))
        origin = rng.integers((1 << 28) - (1 << 25), 1 << 28, size=3, dtype=np.int64)
        if d_bits < 63:
            magnitude = rng.integers(1 << (d_bits - 1), 1 << d_bits, size=5, dtype=np.int64) if d_bits else 0
            d_local = -np.sign(N[:, 0]) * magnitude
        else:
            d_local = np.array([int(v) * (1 << (d_bits - 40)) for v in rng.integers(-(1 << 40), 1 << 40, 5)], object)
        hull = ConvexHull(np.zeros((4, 3), np.int64), origin, N, d_local, width=256)
        got = hull._split_planes()
        assert got is not None
        expected = [int(d) - sum(int(a) * int(b) for a, b in zip(n, origin, strict=True))
                    for n, d in zip(N, d_local, strict=True)]
        assert got[0].tolist() == N.tolist() and [int(v) for v in got[1]] == expected
        assert hull.planes[:, 3].tolist() == expected


@settings(max_examples=200)
@given(st.sampled_from([128, 192, 256]), st.data())
def test_axis_aligned_boxes_take_their_six_planes_directly(width, data):
    """Eight corners of an axis-aligned box (anywhere in the budget, at its bounds too) skip the triple enumeration:
    the same sorted planes, dtype and faces as the enumeration and the Python-int reference; a box with a corner
    moved by one unit, or a flat one, is not taken for a box."""
    from csgnb.mesh.hull import _box_facets, _enumerate_facets

    V = budget(width).max_mesh_coordinate
    edge = st.integers(-V, V)
    lo = [data.draw(edge) for _ in range(3)]
    hi = [data.draw(st.integers(c, V)) for c in lo]
    P = np.array([[(hi if k & (1 << a) else lo)[a] for a in range(3)] for k in range(8)], np.int64)
    moved = data.draw(st.booleans())
    if moved:
        P[data.draw(st.integers(0, 7)), data.draw(st.integers(0, 2))] += data.draw(st.sampled_from([-1, 1]))
        P = np.clip(P, -V, V)
    if not full_dimensional(P):
        with pytest.raises(GeometryError, match="degenerate"):
            convex_hull(P, width=width)
        return
    Q = np.unique(P, axis=0)
    L = Q - Q[0]
    fast = _box_facets(L)
    is_box = all(len(set(Q[:, a].tolist())) == 2 for a in range(3)) and len(Q) == 8
    assert (fast is not None) == is_box
    h = convex_hull(P, width=width)
    assert hull_planes(h) == reference_planes(P)
    if fast is not None:
        N, d = _enumerate_facets(L)
        assert N.dtype == fast[0].dtype and d.dtype == fast[1].dtype
        assert N.tolist() == fast[0].tolist() and d.tolist() == fast[1].tolist()
        assert len(h.faces) == 6 and all(len(f) == 4 for f in h.faces)
