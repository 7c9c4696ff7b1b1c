"""Plane-based convex polygons and their exact splitting (paper §3.6, §4.4).

A polygon is a *supporting plane* plus a cyclic list of *edge planes*; its vertices
are implied by plane triples and never stored or rounded:

* vertex ``j`` of a polygon with edge planes ``e_0 .. e_{k-1}`` is the intersection
  of the support, ``e_j`` and ``e_{(j+1) % k}`` (homogeneous, :func:`intersect_into`);
  edge ``j`` therefore runs from vertex ``j - 1`` to vertex ``j``;
* the edges are in counter-clockwise order seen from the side the polygon *faces*;
  the orientation of an edge plane is irrelevant (only its line in the support is).

Planes are rows of a shared palette (``(p, 4)`` wide array, :mod:`csgnb.exact.wide`).
A set of polygons is stored flat in a :class:`PolygonSet`:

* ``support (n,) int32``: signed palette index: ``s >= 0`` is palette row ``s`` as
  stored, ``s < 0`` is row ``~s = -s - 1`` flipped; the polygon faces the positive
  side of the (possibly flipped) plane;
* ``offsets (n + 1,) int32`` and ``edges (m,) int32``: the edge planes (palette rows)
  of polygon ``i`` are ``edges[offsets[i]:offsets[i + 1]]``;
* ``payload (n,) int32``: a per-polygon value (a face index, a label) carried
  unchanged through splits.

Splitting never creates planes: a polygon cut by plane ``s`` yields two polygons
whose new edge plane is ``s`` itself (a palette row), and the new vertices are the
triples (support, old edge, ``s``). So a split is exact and its pieces stay within
the bit budget of the palette.

Kernels for other numba code (all exact, all on flat arrays; a *polygon store* is a
pair ``edges (cap,) int32``, ``verts (cap, 4) wide`` in which a polygon occupies rows
``start .. start + k - 1``, row ``j`` holding edge ``j`` and vertex ``j``):

* :func:`polygon_vertices_into`, :func:`classify_polygon`, :func:`split_polygon`
  (vertices cached in the store), :func:`split_polygon_planes` (edge planes only), :func:`negative_piece_into`
  (the inner piece only, for clipping to a box).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb._jit import jit
from csgnb.bsp.tree import check_index_array
from csgnb.errors import GeometryError
from csgnb.exact.budgets import check_mesh_points, check_planes
from csgnb.exact.intrinsics import classify_at, intersect_into, wide_sign_at
from csgnb.exact.predicates import plane_from_points
from csgnb.exact.wide import DEFAULT_WIDTH, is_wide, to_wide, wide_dtype

__all__ = [
    "PolygonSet",
    "polygon_vertices",
    "polygon_set_vertices",
    "split_polygons",
    "polygons_from_triangles",
    "dedup_planes",
    "polygon_vertices_into",
    "classify_polygon",
    "split_polygon",
    "split_polygon_planes",
    "negative_piece_into",
]

#: classify_polygon / split results: entirely negative, coplanar, entirely positive, properly split.
NEGATIVE, COPLANAR, POSITIVE, SPLIT = -1, 0, 1, 2


# ---------------------------------------------------------------------------
# kernels


@jit(inline="always")
def copy_point(src, i, dst, j):
    """Copy the wide homogeneous point ``src[i]`` into ``dst[j]``."""
    for c in range(4):
        dst[j, c] = src[i, c]


@jit
def polygon_vertices_into(palette, support_row, edges, e0, k, verts, v0):
    """Store the ``k`` vertices of a polygon into ``verts[v0 : v0 + k]``.

    ``support_row`` is the palette row of the support (``s`` or ``~s``: the flip does
    not change the vertices), ``edges[e0 : e0 + k]`` its edge planes. Vertex ``j`` is
    intersect(support, edges[e0 + j], edges[e0 + (j + 1) % k]) (eq. 5, cofactor
    orientation: ``x4`` may be negative; it is zero only for an ill-formed polygon).
    """
    for j in range(k):
        nxt = j + 1 if j + 1 < k else 0
        intersect_into(palette, support_row, palette, edges[e0 + j], palette, edges[e0 + nxt], verts, v0 + j)


@jit
def classify_polygon(palette, verts, v0, k, plane, sides):
    """Return where the polygon with vertices ``verts[v0 : v0 + k]`` lies against palette row ``plane``.

    Fills ``sides[:k]`` (int8) with each vertex's side (-1, 0, +1, eq. 6) and returns
    -1 (no vertex positive, at least one negative), +1 (mirror), 0 (every vertex on
    the plane: coplanar) or 2 (vertices strictly on both sides: properly split).
    """
    has_neg = False
    has_pos = False
    for j in range(k):
        s = classify_at(verts, v0 + j, palette, plane)
        sides[j] = s
        if s < 0:
            has_neg = True
        elif s > 0:
            has_pos = True
    if has_neg and has_pos:
        return 2
    if has_neg:
        return -1
    if has_pos:
        return 1
    return 0


@jit
def _write_piece(palette, support_row, plane, src_edges, s0, src_verts, sv0, k, sides, sigma,
                 dst_edges, d0, dst_verts, dv0, with_verts):
    """Write the piece of a properly split polygon on the side where ``sigma * side < 0``; return its size.

    The piece keeps every edge with an endpoint strictly inside its half-space. A
    convex polygon that is properly split enters that side once (the *entry* edge:
    first endpoint on or beyond the plane, second inside) and leaves it once (the
    *exit* edge), so the kept edges are one cyclic run from entry to exit, closed by
    the split plane. The piece is written starting at the entry edge.

    Vertices: between two kept edges, the original (inside) vertex is copied. The two
    vertices on the plane are original vertices where one lies there (copied, so no
    duplicate or zero-length edge arises) and otherwise support ∩ crossing edge ∩
    plane, a proper point: the crossing edge has endpoints strictly on both sides, so
    its line is not parallel to the plane. Every kept vertex is strictly inside and the
    two on the plane are distinct, hence >= 3 distinct vertices. (One ``intersect_into``
    call site only: each one inlines a large block of wide arithmetic.)
    """
    entry = 0
    for j in range(k):
        if sigma * sides[j - 1 if j > 0 else k - 1] >= 0 and sigma * sides[j] < 0:
            entry = j
    n = 0
    j = entry
    at_plane = False
    while True:
        p1 = plane
        p2 = plane
        if at_plane:  # closing edge: the split plane, then the entry edge
            e = plane
            copy_row = entry - 1 if entry > 0 else k - 1
            if sides[copy_row] != 0:
                copy_row = -1
                p2 = src_edges[s0 + entry]
        else:
            e = src_edges[s0 + j]
            t = sigma * sides[j]
            copy_row = j if t <= 0 else -1  # inside, or on the plane where the piece is left
            p1 = e
        dst_edges[d0 + n] = e
        if with_verts:
            if copy_row >= 0:
                copy_point(src_verts, sv0 + copy_row, dst_verts, dv0 + n)
            else:
                intersect_into(palette, support_row, palette, p1, palette, p2, dst_verts, dv0 + n)
        n += 1
        if at_plane:
            return n
        if sigma * sides[j] >= 0:  # the exit edge
            at_plane = True
        else:
            j = j + 1 if j + 1 < k else 0


@jit
def split_polygon(palette, support_row, plane, edges, verts, start, k, sides, o_neg, o_pos):
    """Split the polygon at rows ``start .. start + k - 1`` of a polygon store by palette row ``plane``.

    Contract (exact; callable from numba):

    * ``palette`` (p, 4) wide; ``support_row`` the support's palette row (``s`` if
      ``s >= 0`` else ``~s``: the facing does not matter here); ``plane`` a palette
      row; ``edges`` (cap,) int32 and ``verts`` (cap, 4) wide (palette width) form
      the store, with the polygon's vertices already in ``verts[start : start + k]``
      (see :func:`polygon_vertices_into`); ``sides`` (>= k,) int8 scratch, filled
      with the vertices' sides.
    * Returns ``(side, k_neg, k_pos)`` with ``side`` as in :func:`classify_polygon`.
      Only for ``side == 2`` is anything written: the negative piece at rows
      ``o_neg .. o_neg + k_neg - 1`` and the positive one at ``o_pos ..`` (edges and
      vertices; ``k_neg, k_pos <= k + 1``, both >= 3). Otherwise ``(side, 0, 0)``:
      the polygon is unchanged (-1/+1) or coplanar with the plane (0).
    * The caller keeps the regions ``[start, start + k)``, ``[o_neg, o_neg + k + 1)``
      and ``[o_pos, o_pos + k + 1)`` disjoint and within capacity.
    * Pieces keep the counter-clockwise order and the support; ``plane`` becomes one
      edge of each (the last one: a piece starts at the edge where it enters its
      side). No piece has repeated vertices or fewer than three. Input vertices
      are copied bit for bit; new ones are intersect(support, edge, plane).
    * Cost: numba reference-counts array arguments of a call that is not inlined,
      which outweighs a classification. Walks that mostly pass polygons down one
      side should classify inline (``classify_at`` per vertex) and call this only
      for proper splits (as :mod:`csgnb.bsp.build` does).
    """
    # every integer as int64: one compiled specialisation of the helpers whatever the callers' integer types
    support_row, plane, start, k = np.int64(support_row), np.int64(plane), np.int64(start), np.int64(k)
    o_neg, o_pos = np.int64(o_neg), np.int64(o_pos)
    side = classify_polygon(palette, verts, start, k, plane, sides)
    if side != 2:
        return side, 0, 0
    k_neg = _write_piece(palette, support_row, plane, edges, start, verts, start, k, sides, np.int64(1),
                         edges, o_neg, verts, o_neg, np.bool_(True))
    k_pos = _write_piece(palette, support_row, plane, edges, start, verts, start, k, sides, np.int64(-1),
                         edges, o_pos, verts, o_pos, np.bool_(True))
    return side, k_neg, k_pos


@jit
def negative_piece_into(palette, support_row, plane, edges, verts, start, k, sides, o_neg):
    """Write only the negative piece of a properly split polygon; return its size.

    The polygon and ``sides[:k]`` (its vertices' sides, e.g. from :func:`classify_polygon`, with vertices strictly
    on both sides) are as :func:`split_polygon` takes them; the piece is the one ``split_polygon`` writes at
    ``o_neg``, bit for bit. For clipping to a box, where the outer piece is discarded: it is not built (its two new
    vertices are two three-plane intersections).
    """
    support_row, plane, start, k, o_neg = np.int64(support_row), np.int64(plane), np.int64(start), np.int64(k), \
        np.int64(o_neg)
    return _write_piece(palette, support_row, plane, edges, start, verts, start, k, sides, np.int64(1),
                        edges, o_neg, verts, o_neg, np.bool_(True))


@jit
def split_polygon_planes(palette, support_row, plane, edges_in, k, out_neg, out_pos, work, sides):
    """Split a polygon given by its edge planes only; return ``(side, k_neg, k_pos)``.

    ``edges_in[:k]`` (int32) are the edge planes, ``work`` a (>= k, 4) wide scratch
    (palette width) that receives the polygon's vertices, ``sides`` (>= k,) int8
    scratch. For ``side == 2`` the pieces' edge planes are written to ``out_neg[:k_neg]``
    and ``out_pos[:k_pos]`` (each (>= k + 1,) int32); otherwise nothing is written and
    ``(side, 0, 0)`` is returned. See :func:`split_polygon` for the guarantees.
    """
    support_row, plane, k, zero = np.int64(support_row), np.int64(plane), np.int64(k), np.int64(0)
    polygon_vertices_into(palette, support_row, edges_in, zero, k, work, zero)
    side = classify_polygon(palette, work, zero, k, plane, sides)
    if side != 2:
        return side, 0, 0
    k_neg = _write_piece(palette, support_row, plane, edges_in, zero, work, zero, k, sides, np.int64(1),
                         out_neg, zero, work, zero, np.bool_(False))
    k_pos = _write_piece(palette, support_row, plane, edges_in, zero, work, zero, k, sides, np.int64(-1),
                         out_pos, zero, work, zero, np.bool_(False))
    return side, k_neg, k_pos


@jit
def set_vertices_kernel(palette, support, offsets, edges, verts):
    """Vertices of every polygon, row-aligned with ``edges``; return the first row with x4 = 0, or -1."""
    bad = -1
    for i in range(support.shape[0]):
        s = support[i]
        row = s if s >= 0 else -s - 1
        e0 = offsets[i]
        k = offsets[i + 1] - e0
        polygon_vertices_into(palette, row, edges, e0, k, verts, e0)
        if bad < 0:
            for j in range(e0, e0 + k):
                if wide_sign_at(verts, j, 3) == 0:
                    bad = j
                    break
    return bad


@jit
def _split_set_kernel(palette, support, offsets, edges, verts, plane, sides, side_out,
                      neg_src, neg_off, neg_edges, pos_src, pos_off, pos_edges):
    """Split every polygon of a set; return (number of negative, number of positive polygons)."""
    plane = np.int64(plane)  # the helpers' one specialisation takes int64 (see split_polygon)
    nn = 0
    npos = 0
    neg_off[0] = 0
    pos_off[0] = 0
    for i in range(support.shape[0]):
        s = support[i]
        row = np.int64(s if s >= 0 else -s - 1)
        e0 = np.int64(offsets[i])
        k = np.int64(offsets[i + 1] - e0)
        side = classify_polygon(palette, verts, e0, k, plane, sides)
        side_out[i] = side
        if side == -1 or side == 2:
            o = neg_off[nn]
            if side == -1:
                for j in range(k):
                    neg_edges[o + j] = edges[e0 + j]
                kn = k
            else:
                kn = _write_piece(palette, row, plane, edges, e0, verts, e0, k, sides, np.int64(1),
                                  neg_edges, np.int64(o), verts, np.int64(0), np.bool_(False))
            neg_src[nn] = i
            neg_off[nn + 1] = o + kn
            nn += 1
        if side == 1 or side == 2:
            o = pos_off[npos]
            if side == 1:
                for j in range(k):
                    pos_edges[o + j] = edges[e0 + j]
                kp = k
            else:
                kp = _write_piece(palette, row, plane, edges, e0, verts, e0, k, sides, np.int64(-1),
                                  pos_edges, np.int64(o), verts, np.int64(0), np.bool_(False))
            pos_src[npos] = i
            pos_off[npos + 1] = o + kp
            npos += 1
    return nn, npos


# ---------------------------------------------------------------------------
# the polygon set


@dataclass(frozen=True)
class PolygonSet:
    """Plane-based convex polygons over a palette, stored flat (see the module docstring).

    Attributes
    ----------
    support : (n,) int32
        Signed palette index of each supporting plane (``~row`` = flipped).
    offsets : (n + 1,) int32
        ``offsets[0] = 0``, non-decreasing by at least 3, ``offsets[n] = m``.
    edges : (m,) int32
        Palette rows of the edge planes, counter-clockwise seen from the facing side.
    payload : (n,) int32
        Per-polygon value carried through splits (zeros when not given).
    """

    support: np.ndarray
    offsets: np.ndarray
    edges: np.ndarray
    payload: np.ndarray | None = None

    def __post_init__(self) -> None:
        support = check_index_array(self.support, "support")
        offsets = check_index_array(self.offsets, "offsets")
        edges = check_index_array(self.edges, "edges")
        n = support.shape[0]
        if offsets.shape != (n + 1,):
            raise GeometryError(
                f"a PolygonSet needs support (n,), offsets (n + 1,) and edges (m,); got {support.shape}, "
                f"{offsets.shape} and {edges.shape}"
            )
        if offsets[0] != 0 or offsets[-1] != edges.shape[0]:
            raise GeometryError(f"offsets must start at 0 and end at len(edges) = {edges.shape[0]}")
        sizes = np.diff(offsets)
        if n and sizes.min() < 3:
            raise GeometryError(f"polygon {int(np.argmin(sizes))} has {int(sizes.min())} edges; a polygon needs >= 3")
        payload = np.zeros(n, np.int32) if self.payload is None else check_index_array(self.payload, "payload")
        if payload.shape != (n,):
            raise GeometryError(f"payload must have shape ({n},), got {payload.shape}")
        for name, value in (("support", support), ("offsets", offsets), ("edges", edges), ("payload", payload)):
            object.__setattr__(self, name, value)

    @classmethod
    def from_lists(cls, supports, edge_lists, payload=None) -> PolygonSet:
        """Return the set of polygons ``supports[i]`` with edge planes ``edge_lists[i]`` (sequences of rows)."""
        sizes = [len(e) for e in edge_lists]
        offsets = np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]).astype(np.int32)
        edges = np.concatenate([np.asarray(e, np.int32) for e in edge_lists]) if sizes else np.zeros(0, np.int32)
        return cls(np.asarray(supports, np.int32), offsets, edges, payload)

    def __len__(self) -> int:
        return int(self.support.shape[0])

    @property
    def sizes(self) -> np.ndarray:
        """(n,) int32: the number of edges (= vertices) of each polygon."""
        return np.diff(self.offsets)

    def polygon_edges(self, i: int) -> np.ndarray:
        """Return the edge-plane rows of polygon ``i`` ((k,) int32)."""
        return self.edges[self.offsets[i] : self.offsets[i + 1]]

    def check(self, palette: np.ndarray) -> None:
        """Raise :class:`GeometryError` unless every plane index is a row of ``palette``."""
        if not (is_wide(palette) and palette.ndim == 2 and palette.shape[1] == 4):
            raise GeometryError(f"palette must be a (p, 4) wide array of planes, got {getattr(palette, 'shape', None)}")
        p = palette.shape[0]
        if len(self) and (self.support.max() >= p or self.support.min() < -p):
            raise GeometryError(f"a support index lies outside the palette of {p} planes (valid: -{p} .. {p - 1})")
        if self.edges.size and (self.edges.max() >= p or self.edges.min() < 0):
            raise GeometryError(f"an edge plane index lies outside the palette rows 0 .. {p - 1}")

    def __repr__(self) -> str:
        return f"PolygonSet({len(self)} polygons, {self.edges.shape[0]} edges)"


def _checked_vertices(palette: np.ndarray, polygons: PolygonSet) -> np.ndarray:
    """Validate palette and polygons; return all vertices, row-aligned with ``polygons.edges``."""
    polygons.check(palette)
    palette = np.ascontiguousarray(palette)
    if palette.shape[0]:
        check_planes(palette, "palette")
    verts = np.empty((polygons.edges.shape[0], 4), palette.dtype)
    bad = int(set_vertices_kernel(palette, polygons.support, polygons.offsets, polygons.edges, verts))
    if bad >= 0:
        i = int(np.searchsorted(polygons.offsets, bad, side="right") - 1)
        raise GeometryError(
            f"vertex {bad - int(polygons.offsets[i])} of polygon {i} is not a point: its support and two edge "
            "planes have linearly dependent normals. Edge planes must cross the support in distinct, "
            "non-parallel lines."
        )
    return verts


# ---------------------------------------------------------------------------
# public functions


def polygon_vertices(palette: np.ndarray, polygons: PolygonSet, i: int) -> np.ndarray:
    """Return the vertices of polygon ``i`` as homogeneous points.

    Parameters
    ----------
    palette : (p, 4) wide
    polygons : PolygonSet
    i : int

    Returns
    -------
    (k, 4) wide of the palette's width: vertex ``j`` = support ∩ edge ``j`` ∩ edge ``j + 1``,
    counter-clockwise seen from the side the polygon faces.
    """
    n = len(polygons)
    if not -n <= i < n:
        raise IndexError(f"polygon index {i} out of range for {n} polygons")
    i %= n
    one = PolygonSet(polygons.support[i : i + 1], np.array([0, polygons.sizes[i]], np.int32),
                     polygons.polygon_edges(i))
    return _checked_vertices(palette, one)


def polygon_set_vertices(palette: np.ndarray, polygons: PolygonSet) -> np.ndarray:
    """Return the vertices of every polygon, ``(m, 4)`` wide, row ``offsets[i] + j`` = vertex ``j`` of polygon ``i``."""
    return _checked_vertices(palette, polygons)


def split_polygons(
    palette: np.ndarray, polygons: PolygonSet, plane: int
) -> tuple[PolygonSet, PolygonSet, np.ndarray]:
    """Return the parts of ``polygons`` on the negative and positive side of palette row ``plane``.

    Exact: each properly split polygon becomes two polygons that share the split
    plane as an edge plane (see :func:`split_polygon`); polygons entirely on one side
    (vertices on the plane allowed) go to that side unchanged; coplanar polygons go
    to neither. Supports and payloads are carried over.

    Parameters
    ----------
    palette : (p, 4) wide
    polygons : PolygonSet
    plane : int
        Palette row of the splitting plane (its orientation defines the sides).

    Returns
    -------
    neg, pos : PolygonSet
        The pieces, in input order.
    side : (n,) int8
        Per input polygon: -1, +1 (one side), 0 (coplanar: in neither output), 2 (split).
    """
    verts = _checked_vertices(palette, polygons)
    palette = np.ascontiguousarray(palette)
    plane = int(plane)
    if not 0 <= plane < palette.shape[0]:
        raise GeometryError(f"plane must be a palette row 0 .. {palette.shape[0] - 1}, got {plane}")
    n, m = len(polygons), polygons.edges.shape[0]
    sides = np.empty(max(int(polygons.sizes.max()) if n else 0, 1), np.int8)
    side = np.empty(n, np.int8)
    out = []
    for _ in range(2):
        out.append((np.empty(n, np.int32), np.empty(n + 1, np.int32), np.empty(m + n, np.int32)))
    (neg_src, neg_off, neg_edges), (pos_src, pos_off, pos_edges) = out
    nn, npos = _split_set_kernel(palette, polygons.support, polygons.offsets, polygons.edges, verts, plane,
                                 sides, side, neg_src, neg_off, neg_edges, pos_src, pos_off, pos_edges)

    def assemble(src, off, edges, count):
        src = src[:count]
        return PolygonSet(polygons.support[src], off[: count + 1], edges[: off[count]], polygons.payload[src])

    return assemble(neg_src, neg_off, neg_edges, nn), assemble(pos_src, pos_off, pos_edges, npos), side


# ---------------------------------------------------------------------------
# from triangles


def _canonical_int64(planes: np.ndarray) -> np.ndarray:
    """``(n, 4) int64`` planes divided by gcd(a, b, c) with the first non-zero normal coefficient positive."""
    g = np.gcd.reduce(np.abs(planes[:, :3]), axis=1)
    planes = planes // g[:, None]
    first = np.where(planes[:, 0] != 0, planes[:, 0], np.where(planes[:, 1] != 0, planes[:, 1], planes[:, 2]))
    return np.where(first[:, None] < 0, -planes, planes)


def dedup_planes(planes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the distinct rows of canonical wide ``planes`` in first-appearance order, and each row's index.

    Rows compare bit for bit, which is exact equality of the planes when every row
    is in canonical form (coefficients divided by gcd(a, b, c), first non-zero of
    a, b, c positive). Returns ``(palette (p, 4) wide, index (n,) int32)``.
    """
    n = planes.shape[0]
    if n == 0:
        return planes.copy(), np.zeros(0, np.int32)
    rows = np.ascontiguousarray(planes).view(np.dtype((np.void, planes.dtype.itemsize * 4))).reshape(n)
    _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.shape[0])
    return np.ascontiguousarray(planes[first[order]]), rank[inverse.reshape(-1)].astype(np.int32)


def polygons_from_triangles(vertices, triangles, width: int = DEFAULT_WIDTH,
                            payload=None) -> tuple[np.ndarray, PolygonSet]:
    """Return ``(palette, polygons)``: one plane-based polygon per triangle.

    The support of triangle (p, q, r) is the plane through p, q, r with normal
    ``(q - p) x (r - p)`` (the polygon faces its positive side); its edge planes come
    in the order (r, p), (p, q), (q, r), so vertices 0, 1, 2 are exactly p, q, r.
    The edge plane of edge (p, q) is the plane through p, q and p + e_k, where e_k is
    the axis of the support normal's largest |n_k|:

    * its normal ``(q - p) x e_k`` has coefficients <= 2 V and offset <= 6 V^2 for
      coordinates <= V, far inside the mesh budget (8 V^2, 24 V^3), so the palette
      stays within the width's budget;
    * it contains the edge, and it is never parallel to the support: it is parallel
      to e_k, so a parallel support would have n_k = 0, yet |n_k| is the largest
      coefficient of a non-zero normal. For the same reason ``q - p`` is not parallel
      to e_k (else n = (q - p) x (r - p) would be orthogonal to e_k), so the edge
      plane's normal is non-zero, and the three edge planes of a triangle cross the
      support in the three distinct edge lines, making every vertex a proper point.

    Equal planes share one palette row (canonical gcd form, sign normalised so that
    a plane and its negation are one row; a flipped support is stored as ``~row``).

    Parameters
    ----------
    vertices : (v, 3) int64
        Within the mesh budget of ``width`` (``budget(width).max_mesh_coordinate``).
    triangles : (n, 3) int
        Vertex indices.
    width : {128, 192, 256}
    payload : (n,) int32, optional
        Defaults to the triangle index.

    Raises
    ------
    PrecisionError
        A coordinate exceeds the mesh budget.
    GeometryError
        Bad shapes or indices, or a degenerate (collinear) triangle.
    """
    V = np.asarray(vertices)
    T = np.asarray(triangles)
    if V.ndim != 2 or V.shape[1] != 3 or V.dtype.kind not in "iu":
        raise GeometryError(f"vertices must be an (n, 3) integer array, got shape {V.shape} dtype {V.dtype}")
    if T.ndim != 2 or T.shape[1] != 3 or T.dtype.kind not in "iu":
        raise GeometryError(f"triangles must be an (m, 3) integer array, got shape {T.shape} dtype {T.dtype}")
    V = V.astype(np.int64)
    T = T.astype(np.int64)
    n = T.shape[0]
    if n and (T.min() < 0 or T.max() >= V.shape[0]):
        raise GeometryError(f"triangle indices must lie in 0 .. {V.shape[0] - 1}")
    check_mesh_points(V, width, "vertices")
    if n == 0:
        return np.zeros((0, 4), wide_dtype(width)), PolygonSet(np.zeros(0, np.int32), [0], np.zeros(0, np.int32))
    P, Q, R = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    normal = np.cross(Q - P, R - P)  # |n_i| <= 8 V^2 < 2^63 within any mesh budget
    zero = np.flatnonzero(~normal.any(axis=1))
    if zero.size:
        t = int(zero[0])
        raise GeometryError(f"triangle {t} {T[t].tolist()} is degenerate (its corners are collinear); remove it")
    first = np.where(normal[:, 0] != 0, normal[:, 0], np.where(normal[:, 1] != 0, normal[:, 1], normal[:, 2]))
    flip = first < 0
    # The canonical row of the support is the one with the first non-zero normal
    # coefficient positive; a negative one is the same plane through (p, r, q).
    Q2 = np.where(flip[:, None], R, Q)
    R2 = np.where(flip[:, None], Q, R)
    supports = plane_from_points(P, Q2, R2, width=width, canonical=True).reshape(n, 4)
    axis = np.argmax(np.abs(normal), axis=1)
    e = np.zeros((n, 3), np.int64)
    e[np.arange(n), axis] = 1
    edge_planes = []
    for a, b in ((R, P), (P, Q), (Q, R)):  # edges 0, 1, 2: vertices p, q, r come out as 0, 1, 2
        m = np.cross(b - a, e)
        d = -np.einsum("ij,ij->i", m, a)
        edge_planes.append(_canonical_int64(np.concatenate([m, d[:, None]], axis=1)))
    edge_wide = to_wide(np.stack(edge_planes, axis=1).reshape(3 * n, 4), width)
    palette, index = dedup_planes(np.concatenate([supports, edge_wide]))
    support = np.where(flip, ~index[:n], index[:n]).astype(np.int32)
    edges = index[n:]  # triangle-major: triangle t owns rows 3t .. 3t + 2
    offsets = np.arange(0, 3 * n + 1, 3, dtype=np.int32)
    if payload is None:
        payload = np.arange(n, dtype=np.int32)
    return palette, PolygonSet(support, offsets, edges, payload)
