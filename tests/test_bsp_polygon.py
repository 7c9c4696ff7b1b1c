"""Plane-based polygons: vertices, exact splits and the triangle import, against Fractions."""

from fractions import Fraction
from math import gcd

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from csgnb import GeometryError, PrecisionError, exact
from csgnb.bsp.polygon import (
    PolygonSet,
    classify_polygon,
    negative_piece_into,
    polygon_set_vertices,
    polygon_vertices,
    polygons_from_triangles,
    split_polygon,
    split_polygon_planes,
    split_polygons,
)
from tests.exact_reference import cross, side, solve_3_planes

WIDTH = 128
V128 = exact.budget(128).max_mesh_coordinate


def ints(arr):
    return [[int(v) for v in row] for row in exact.from_wide(arr)]


def cartesian(arr):
    """Homogeneous wide points as Fraction triples."""
    return [tuple(Fraction(r[i], r[3]) for i in range(3)) for r in ints(arr)]


def signed_plane(palette, s):
    row = ints(palette[s if s >= 0 else ~s : (s if s >= 0 else ~s) + 1])[0]
    return row if s >= 0 else [-c for c in row]


def reference_vertices(palette, polygons, i):
    """Vertices from Cramer's rule on the palette rows (independent of the kernels)."""
    pal = ints(palette)
    s = int(polygons.support[i])
    sup = pal[s if s >= 0 else ~s]
    e = [pal[int(x)] for x in polygons.polygon_edges(i)]
    return [tuple(solve_3_planes(sup, e[j], e[(j + 1) % len(e)])) for j in range(len(e))]


def canonical(plane):
    g = gcd(*plane[:3])
    plane = [c // g for c in plane]
    first = next(c for c in plane[:3] if c)
    return plane if first > 0 else [-c for c in plane]


def plane_through(p, q, r):
    n = cross([b - a for a, b in zip(p, q, strict=True)], [b - a for a, b in zip(p, r, strict=True)])
    return n + [-sum(a * b for a, b in zip(n, p, strict=True))]


def shoelace(points, axis):
    """Signed area of a polygon projected along ``axis`` (Fractions)."""
    u, v = [c for c in range(3) if c != axis]
    return sum(points[j][u] * points[(j + 1) % len(points)][v] - points[(j + 1) % len(points)][u] * points[j][v]
               for j in range(len(points))) / 2


def point(bound):
    return st.lists(st.integers(-bound, bound), min_size=3, max_size=3)


@st.composite
def triangle(draw, bound=V128):
    b = draw(st.sampled_from([3, 40, bound]))
    p, q, r = draw(point(b)), draw(point(b)), draw(point(b))
    assume(any(cross([q[i] - p[i] for i in range(3)], [r[i] - p[i] for i in range(3)])))
    return p, q, r


# ---------------------------------------------------------------------------
# triangles -> polygons


@given(st.lists(triangle(), min_size=1, max_size=4))
def test_triangle_vertices_are_its_corners_in_order(tris):
    V = np.array([c for t in tris for c in t], np.int64)
    T = np.arange(V.shape[0]).reshape(-1, 3)
    palette, polys = polygons_from_triangles(V, T, WIDTH)
    assert list(polys.payload) == list(range(len(tris)))
    for i, (p, q, r) in enumerate(tris):
        got = cartesian(polygon_vertices(palette, polys, i))
        assert got == [tuple(map(Fraction, c)) for c in (p, q, r)]
        assert got == reference_vertices(palette, polys, i)
        # The polygon faces the side of (q - p) x (r - p): the signed support is a positive multiple.
        n = cross([q[k] - p[k] for k in range(3)], [r[k] - p[k] for k in range(3)])
        s = signed_plane(palette, int(polys.support[i]))
        ratio = {Fraction(a, b) for a, b in zip(n, s[:3], strict=True) if b} | {
            Fraction(0) for a, b in zip(n, s[:3], strict=True) if not b and a
        }
        assert len(ratio) == 1 and ratio.pop() > 0
    all_verts = cartesian(polygon_set_vertices(palette, polys))
    assert all_verts == [tuple(map(Fraction, c)) for t in tris for c in t]


@given(triangle(bound=50))
def test_equal_planes_share_a_palette_row(tri):
    p, q, r = tri
    # The same triangle again, reversed, and a coplanar one sharing the edge (p, q).
    far = [2 * p[k] - r[k] for k in range(3)]
    V = np.array([p, q, r, p, r, q, q, p, far], np.int64)
    palette, polys = polygons_from_triangles(V, np.arange(9).reshape(3, 3), WIDTH)
    rows = ints(palette)
    assert len({tuple(r) for r in rows}) == len(rows)  # distinct
    assert all(r == canonical(r) for r in rows)  # canonical
    s = [int(x) for x in polys.support]
    assert s[0] == ~s[1] and s[2] == s[0]  # one plane; triangle 1 faces the other way
    e0, e1 = polys.polygon_edges(0), polys.polygon_edges(1)
    assert set(e0.tolist()) == set(e1.tolist())  # same edges, orientation ignored
    assert int(polys.polygon_edges(2)[1]) == int(e0[1])  # edge (q, p) is edge (p, q)


def test_triangle_errors():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    with pytest.raises(GeometryError, match="degenerate"):
        polygons_from_triangles(V, [[0, 1, 3]], WIDTH)
    with pytest.raises(GeometryError, match="indices"):
        polygons_from_triangles(V, [[0, 1, 4]], WIDTH)
    with pytest.raises(GeometryError, match=r"\(n, 3\) integer"):
        polygons_from_triangles(V.astype(float), [[0, 1, 2]], WIDTH)
    with pytest.raises(GeometryError, match=r"\(m, 3\)"):
        polygons_from_triangles(V, [[0, 1, 2, 3]], WIDTH)
    with pytest.raises(PrecisionError, match="mesh budget"):
        polygons_from_triangles(V * (V128 + 1), [[0, 1, 2]], WIDTH)
    palette, polys = polygons_from_triangles(V, np.zeros((0, 3), np.int64), WIDTH)
    assert len(polys) == 0 and palette.shape == (0, 4)


def test_polygon_set_errors():
    palette = exact.to_wide([[0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [1, 1, 0, -1], [1, 0, 0, -1]], WIDTH)
    with pytest.raises(GeometryError, match=">= 3"):
        PolygonSet.from_lists([0], [[1, 2]])
    with pytest.raises(GeometryError, match="offsets"):
        PolygonSet([0], [0, 4], [1, 2, 3])
    with pytest.raises(GeometryError, match="payload"):
        PolygonSet.from_lists([0], [[1, 2, 3]], payload=[1, 2])
    with pytest.raises(GeometryError, match="outside the palette"):
        polygon_vertices(palette, PolygonSet.from_lists([5], [[1, 2, 3]]), 0)
    with pytest.raises(GeometryError, match="edge plane index"):
        polygon_vertices(palette, PolygonSet.from_lists([0], [[1, 2, 7]]), 0)
    # Edges x = 0 and x = 1 are parallel: vertex 0 is no point.
    with pytest.raises(GeometryError, match="vertex 0 of polygon 0"):
        polygon_vertices(palette, PolygonSet.from_lists([0], [[1, 4, 2]]), 0)
    with pytest.raises(IndexError):
        polygon_vertices(palette, PolygonSet.from_lists([0], [[1, 2, 3]]), 1)
    with pytest.raises(GeometryError, match="plane must be a palette row"):
        split_polygons(palette, PolygonSet.from_lists([0], [[1, 2, 3]]), 5)


# ---------------------------------------------------------------------------
# splitting


def check_split(palette, polys, plane_row):
    """Split by palette row ``plane_row`` and check every piece against Fractions."""
    pal = ints(palette)
    plane = pal[plane_row]
    neg, pos, sides = split_polygons(palette, polys, plane_row)
    ni = pi = 0
    for i in range(len(polys)):
        verts = reference_vertices(palette, polys, i)
        sup = signed_plane(palette, int(polys.support[i]))
        axis = max(range(3), key=lambda c: abs(sup[c]))
        vs = [side(v, plane) for v in verts]
        expect = 2 if (min(vs) < 0 < max(vs)) else (-1 if min(vs) < 0 else (1 if max(vs) > 0 else 0))
        assert sides[i] == expect
        area = shoelace(verts, axis)
        pieces = []
        if expect in (-1, 2):
            pieces.append((neg, ni, -1))
            ni += 1
        if expect in (1, 2):
            pieces.append((pos, pi, 1))
            pi += 1
        total = Fraction(0)
        for subset, j, sign in pieces:
            assert int(subset.support[j]) == int(polys.support[i])
            assert int(subset.payload[j]) == int(polys.payload[i])
            pv = reference_vertices(palette, subset, j)
            assert cartesian(polygon_vertices(palette, subset, j)) == pv
            assert len(pv) >= 3 and len(set(pv)) == len(pv)
            for v in pv:
                assert side(v, sup) == 0  # on the support
                assert side(v, plane) in (0, sign)  # on the split plane or strictly on its side
            piece_area = shoelace(pv, axis)
            assert piece_area * area > 0  # same facing
            # Strictly convex: every consecutive triple turns the same way as the whole.
            for k in range(len(pv)):
                tri = [pv[k - 1], pv[k], pv[(k + 1) % len(pv)]]
                assert shoelace(tri, axis) * area > 0
            if expect == 2:
                assert plane_row in subset.polygon_edges(j).tolist()
            else:
                assert subset.polygon_edges(j).tolist() == polys.polygon_edges(i).tolist()
            total += piece_area
        if expect != 0:
            assert total == area  # the pieces tile the polygon exactly
    assert ni == len(neg) and pi == len(pos)
    return neg, pos, sides


def with_planes(palette, planes):
    """Append canonical integer planes to the palette; return it and their rows."""
    rows = [canonical(p) for p in planes]
    first = palette.shape[0]
    return np.concatenate([palette, exact.to_wide(rows, WIDTH)]), list(range(first, first + len(rows)))


@st.composite
def cut_plane(draw, tri, bound):
    """A plane through random points, a vertex, an edge, two vertices, or the support itself."""
    p, q, r = tri
    kind = draw(st.sampled_from(["random", "vertex", "edge", "two-vertices", "coplanar", "flipped"]))
    a, b = draw(point(bound)), draw(point(bound))
    if kind == "random":
        pts = [a, b, draw(point(bound))]
    elif kind == "vertex":
        pts = [draw(st.sampled_from([p, q, r])), a, b]
    elif kind == "edge":
        u, w = draw(st.sampled_from([(p, q), (q, r), (r, p)]))
        pts = [u, w, a]
    elif kind == "two-vertices":
        pts = [p, r, [(q[k] + a[k]) // 2 for k in range(3)]]
    elif kind == "coplanar":
        pts = [p, q, r]
    else:
        pts = [p, r, q]
    plane = plane_through(*pts)
    assume(any(plane[:3]))
    return plane


@given(st.data())
def test_split_triangles_exactly(data):
    bound = data.draw(st.sampled_from([4, 30, V128]))
    tri = data.draw(triangle(bound=bound))
    plane = data.draw(cut_plane(tri, bound))
    palette, polys = polygons_from_triangles(np.array(tri, np.int64), [[0, 1, 2]], WIDTH)
    palette, (row,) = with_planes(palette, [plane])
    check_split(palette, polys, row)


@given(st.data())
def test_split_general_convex_polygons(data):
    """Polygons cut twice already (fractional vertices, up to 5 edges), then cut again."""
    bound = data.draw(st.sampled_from([6, 30, V128]))
    tri = data.draw(triangle(bound=bound))
    planes = [data.draw(cut_plane(tri, bound)) for _ in range(3)]
    palette, polys = polygons_from_triangles(np.array(tri, np.int64), [[0, 1, 2]], WIDTH)
    palette, rows = with_planes(palette, planes)
    for row in rows[:2]:
        neg, pos, _ = split_polygons(palette, polys, row)
        parts = [x for x in (neg, pos) if len(x)]
        assume(parts)
        polys = data.draw(st.sampled_from(parts))
    check_split(palette, polys, rows[2])


def test_split_through_vertices_and_along_edges():
    """Hand-made degenerate cases of a square (edge planes x = 0, y = 0, x = 4, y = 4 on z = 0)."""
    palette = exact.to_wide(
        [[0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, -4], [0, 1, 0, -4],
         [1, -1, 0, 0],  # the diagonal through two corners
         [1, 0, 0, -2],  # through two edge midpoints
         [1, 1, 0, -4],  # the other diagonal
         [0, 1, 0, 0],  # along the edge y = 0 (a duplicate row on purpose)
         [1, 1, 0, 0],  # touching one corner
         [0, 0, 1, -1]],  # parallel to the support
        WIDTH,
    )
    square = PolygonSet.from_lists([0], [[1, 2, 3, 4]], payload=[7])
    assert cartesian(polygon_vertices(palette, square, 0)) == [(0, 0, 0), (4, 0, 0), (4, 4, 0), (0, 4, 0)]
    expected = {5: (2, 3, 3), 6: (2, 4, 4), 7: (2, 3, 3), 8: (1, 0, 0), 9: (1, 0, 0), 10: (-1, 0, 0), 0: (0, 0, 0)}
    for row, (side_, kn, kp) in expected.items():
        neg, pos, sides = check_split(palette, square, row)
        assert sides[0] == side_
        if side_ == 2:
            assert (neg.sizes[0], pos.sizes[0]) == (kn, kp)


def test_split_kernels_callable_from_numba_code():
    palette = exact.to_wide([[0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, -4], [0, 1, 0, -4],
                             [1, -1, 0, -2]], WIDTH)
    edges_in = np.array([1, 2, 3, 4], np.int32)
    out_neg, out_pos = np.full(5, -9, np.int32), np.full(5, -9, np.int32)
    work = np.empty((4, 4), palette.dtype)
    sides = np.empty(4, np.int8)
    side_, kn, kp = split_polygon_planes(palette, 0, 5, edges_in, 4, out_neg, out_pos, work, sides)
    ref_neg, ref_pos, _ = split_polygons(palette, PolygonSet.from_lists([0], [edges_in]), 5)
    assert side_ == 2
    assert out_neg[:kn].tolist() == ref_neg.edges.tolist() and out_pos[:kp].tolist() == ref_pos.edges.tolist()
    assert cartesian(work) == [(0, 0, 0), (4, 0, 0), (4, 4, 0), (0, 4, 0)]
    assert sides.tolist() == [-1, 1, -1, -1]
    # The store variant: vertices cached, pieces written with their vertices.
    edges = np.zeros(16, np.int32)
    verts = np.zeros((16, 4), palette.dtype)
    edges[:4] = edges_in
    verts[:4] = work
    side_, kn, kp = split_polygon(palette, 0, 5, edges, verts, 0, 4, sides, 4, 10)
    assert (side_, kn, kp) == (2, 5, 3)
    assert edges[4:9].tolist() == ref_neg.edges.tolist() and edges[10:13].tolist() == ref_pos.edges.tolist()
    assert cartesian(verts[4:9]) == cartesian(polygon_vertices(palette, ref_neg, 0))
    assert cartesian(verts[10:13]) == cartesian(polygon_vertices(palette, ref_pos, 0))
    assert split_polygon(palette, 0, 0, edges, verts, 0, 4, sides, 4, 10) == (0, 0, 0)


@pytest.mark.parametrize("plane", [[1, -1, 0, -2], [-1, 1, 0, 2], [1, 1, 0, -3], [0, 1, 0, -1], [2, 3, 0, -7]])
def test_the_inner_piece_alone_is_split_polygons_negative_piece(plane):
    """negative_piece_into (clipping a tool polygon to a cell wall keeps only the inner piece) writes the piece
    split_polygon writes on the negative side, edges and vertices bit for bit, and nothing else."""
    palette = exact.to_wide([[0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, -4], [0, 1, 0, -4], plane], WIDTH)
    work = np.empty((4, 4), palette.dtype)
    sides = np.empty(4, np.int8)
    split_polygon_planes(palette, 0, 5, np.array([1, 2, 3, 4], np.int32), 4, np.empty(5, np.int32),
                         np.empty(5, np.int32), work, sides)
    edges = np.zeros(16, np.int32)
    verts = np.zeros((16, 4), palette.dtype)
    edges[:4] = [1, 2, 3, 4]
    verts[:4] = work
    alone_edges, alone_verts = edges.copy(), verts.copy()
    assert classify_polygon(palette, verts, 0, 4, 5, sides) == 2
    k = negative_piece_into(palette, 0, 5, alone_edges, alone_verts, 0, 4, sides, 4)
    side_, kn, _ = split_polygon(palette, 0, 5, edges, verts, 0, 4, sides, 4, 10)
    assert side_ == 2 and k == kn
    assert alone_edges[4:4 + k].tolist() == edges[4:4 + kn].tolist()
    assert alone_verts[4:4 + k].tobytes() == verts[4:4 + kn].tobytes()
    assert not alone_edges[4 + k:].any() and not alone_verts[4 + k:]["limbs"].any()  # no outer piece written
