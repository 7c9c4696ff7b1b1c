"""Polygon soup → BSP import (paper §3.6), and the mesh validation in front of it.

:func:`bsp_from_polygons` inserts plane-based faces (:mod:`csgnb.bsp.polygon`) one by
one, in a seeded random order, into a BSP that starts as one **out** leaf:

* a face that reaches a leaf turns it into an inner node split by the face's
  supporting plane; the child behind the face (the inside) is **in**, the child in
  front **out**;
* at an inner node the face is split exactly by the node's plane and each piece
  descends its own side; a face on one side (touching the plane allowed) descends
  that side; a face coplanar with the node's plane is discarded (the node already
  separates the two sides there).

No plane is created: every node plane is a face's support and every vertex a triple
of palette planes, so the import is exact and within the palette's bit budget.

:func:`bsp_from_mesh` first checks that an integer triangle mesh bounds a solid —
within the budget, closed, edge-manifold, consistently and outwardly oriented, not
self-intersecting, its shells properly nested (cavities face inward) — and raises an
error naming the first defect it finds. Faces without area that rounding a fine mesh
onto a grid makes are removed first, the surface unchanged: collapsed ones (two
corners welded) dropped, flat ones (a corner rounded onto the opposite edge) dropped
after splitting their neighbour at that corner (:func:`validate_mesh`). Meshes that
overlap, cross or fold are refused there; ``bsp_from_mesh(..., fill="winding")`` takes
them as the points they wind around (:mod:`csgnb.bsp.winding`).
"""

from __future__ import annotations

from functools import cmp_to_key

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from csgnb._jit import borrowing_jit, jit
from csgnb._unlinked import unlinked
from csgnb.bsp.polygon import PolygonSet, _checked_vertices, copy_point, polygons_from_triangles, split_polygon
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import GeometryError, InternalError, PrecisionError
from csgnb.exact.budgets import budget, check_mesh_points
from csgnb.exact.integral import exact_int, integer_array
from csgnb.exact.intrinsics import classify_at, plane_from_points_into, signed_distance_into, wide_sign_at
from csgnb.exact.wide import DEFAULT_WIDTH, is_wide, wide_dtype

__all__ = ["bsp_from_polygons", "bsp_from_mesh", "validate_mesh", "check_seed", "check_label", "check_count"]


# ---------------------------------------------------------------------------
# the insertion loop


@unlinked
@borrowing_jit
def build_kernel(palette, support, offsets, edges, verts, order, label,
                  plane, neg, pos, lab, a_edges, a_verts, sides, st_node, st_start, st_k):
    """Insert polygons ``order[0], order[1], ...`` into a BSP; return the node count or a negative code.

    Node arrays ``plane, neg, pos, lab`` have a capacity; polygon pieces live in a
    stack-ordered arena (``a_edges``, ``a_verts``, vertices cached so that a split
    computes only its two new points); ``st_*`` is the work stack of pieces still to
    insert, ``(node, start, k)``. Returns -1 / -2 / -3 when the node arrays / the arena
    / the stack are full (the caller grows that one and starts again).

    Arena discipline: a piece at rows [start, start + k) that is split writes its
    positive piece at start + k and its negative piece at start + 2k + 1; the positive
    one is pushed, the negative one processed at once. Stack entries thus lie at
    increasing rows, and everything above a popped entry is dead.
    """
    cap_nodes = plane.shape[0]
    cap_arena = a_edges.shape[0]
    cap_stack = st_node.shape[0]
    plane[0] = -1
    neg[0] = -1
    pos[0] = -1
    lab[0] = 0
    n_nodes = 1
    for f in order:
        s = support[f]
        row = s if s >= 0 else -s - 1
        e0 = offsets[f]
        k = offsets[f + 1] - e0
        if 3 * k + 2 > cap_arena:
            return -2
        for j in range(k):
            a_edges[j] = edges[e0 + j]
            copy_point(verts, e0 + j, a_verts, j)
        st_node[0] = 0
        st_start[0] = 0
        st_k[0] = k
        top = 1
        while top > 0:
            top -= 1
            node = st_node[top]
            start = st_start[top]
            k = st_k[top]
            while True:
                if plane[node] < 0:  # a leaf: the piece's support splits it
                    if n_nodes + 2 > cap_nodes:
                        return -1
                    inside = n_nodes if s >= 0 else n_nodes + 1
                    outside = n_nodes + 1 if s >= 0 else n_nodes
                    plane[node] = row
                    lab[node] = -1
                    # The polygon faces outward: behind its (possibly flipped) support is inside.
                    neg[node] = inside if s >= 0 else outside
                    pos[node] = outside if s >= 0 else inside
                    for c in (inside, outside):
                        plane[c] = -1
                        neg[c] = -1
                        pos[c] = -1
                    lab[inside] = label
                    lab[outside] = 0
                    n_nodes += 2
                    break
                # Most visits pass a piece down one side: classify inline (an intrinsic, no
                # call) and call the splitter, whose array arguments cost reference
                # counting, only for proper splits. (Passing it the sides found here instead of
                # classifying again measured 3 % slower on the drill's steps.)
                q = plane[node]
                side = 9  # not decided yet
                if q == row:
                    side = 0  # the piece's own support
                else:
                    # A piece with an edge on q (a neighbour's support, met often: the surface is closed) lies on
                    # one closed side of it (convex); vertex j is support ∩ edge j ∩ edge j + 1, so edge j holds
                    # vertices j - 1 and j, and vertex j + 1 decides, unless it is on q too (collinear corners).
                    for j in range(start, start + k):
                        if a_edges[j] == q:
                            after = j + 1 if j + 1 < start + k else start
                            side = classify_at(a_verts, after, palette, q)
                            if side == 0:
                                side = 9
                            break
                if side == 9:
                    has_neg = False
                    has_pos = False
                    for j in range(start, start + k):
                        c = classify_at(a_verts, j, palette, q)
                        if c < 0:
                            has_neg = True
                        elif c > 0:
                            has_pos = True
                    side = 2 if has_neg and has_pos else (-1 if has_neg else (1 if has_pos else 0))
                if side == 2:
                    o_pos = start + k
                    o_neg = start + 2 * k + 1
                    if o_neg + k + 1 > cap_arena:
                        return -2
                    side, k_neg, k_pos = split_polygon(palette, row, q, a_edges, a_verts, start, k, sides, o_neg, o_pos)
                if side == 0:
                    break  # coplanar with the node's plane: discarded
                if side < 0:
                    node = neg[node]
                elif side == 1:
                    node = pos[node]
                else:
                    if top >= cap_stack:
                        return -3
                    st_node[top] = pos[node]
                    st_start[top] = o_pos
                    st_k[top] = k_pos
                    top += 1
                    node = neg[node]
                    start = o_neg
                    k = k_neg
    return n_nodes


_MAX_LABEL = np.iinfo(np.int32).max


def check_label(label, name: str = "label") -> int:
    """Return the material label ``label`` as an int in ``[1, 2**31 - 1]``; a clear error otherwise."""
    try:
        v = exact_int(label, name)
    except PrecisionError:
        raise GeometryError(f"{name} must be an integer >= 1 (0 is out), got {label!r}") from None
    if not 1 <= v <= _MAX_LABEL:
        raise GeometryError(f"{name} must be an integer in [1, {_MAX_LABEL}] (0 is out; labels are int32), got {v}")
    return v


def check_count(value, name: str, minimum: int = 0, maximum: int | None = None) -> int:
    """Return the integer parameter ``value`` (a count or size) checked against ``[minimum, maximum]``.

    Non-integers raise as in :func:`~csgnb.exact.integral.exact_int` (``TypeError`` for
    strings or ``None``, :class:`PrecisionError` for 2.7); a value out of range raises
    :class:`GeometryError` naming the range.
    """
    v = exact_int(value, name)
    if v < minimum or (maximum is not None and v > maximum):
        bound = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise GeometryError(f"{name} must be an integer {bound}, got {v}")
    return v


def check_seed(seed) -> int:
    """Return the random seed ``seed`` as a non-negative int; a clear error otherwise."""
    try:
        v = exact_int(seed, "seed")
    except TypeError:
        raise TypeError(f"seed must be a non-negative integer, got {type(seed).__name__} {seed!r}") from None
    except ValueError:
        raise GeometryError(f"seed must be a non-negative integer, got {seed!r}") from None
    if v < 0:
        raise GeometryError(f"seed must be a non-negative integer (numpy.random.default_rng), got {v}")
    return v


def _initial_capacities(n_polygons: int, max_size: int) -> tuple[int, int, int]:
    """Starting sizes of the node arrays, the piece arena and the work stack (grown when too small).

    A build that runs out of room starts again from the beginning, after doing nearly all the work it would
    have done: the node arrays start at 12 nodes a polygon (a convex or exact-union tool needs ~2, a rounded float
    mesh's ~11: 43,975 nodes from the 4,113 faces of one of the drill's sweeps), 16 bytes a node."""
    return 12 * n_polygons + 64, 64 * max_size + 4096, 256


def bsp_from_polygons(palette: np.ndarray, polygons: PolygonSet, *, seed: int = 0, label: int = 1) -> BSPTree:
    """Return the BSP of the solid bounded by outward-facing plane-based polygons (paper §3.6).

    Faces are inserted in the order of a permutation drawn from
    ``numpy.random.default_rng(seed)``; the tree depends on the seed, the solid it
    represents does not.

    Parameters
    ----------
    palette : (p, 4) wide
        Planes within the width's budget.
    polygons : PolygonSet
        Convex faces, each facing out of the solid (the solid lies behind its
        support, on the negative side of the support as flipped by the sign).
        Together they must bound the solid: closed and non-self-intersecting
        (:func:`bsp_from_mesh` checks this for triangle meshes; here it is assumed).
    seed : int
    label : int
        Label of the inside leaves (>= 1; the outside is 0).

    Returns
    -------
    BSPTree
        Node planes are supports; a node whose face's support is stored flipped
        (``~row``) has its **in** child on the positive side of that palette row.
        The palette is reduced to the rows the nodes use (in first-use order).
    """
    if not (is_wide(palette) and palette.ndim == 2 and palette.shape[1] == 4):
        raise TypeError(f"palette must be an (p, 4) wide array of planes (csgnb.exact.to_wide), got "
                        f"{type(palette).__name__} {getattr(palette, 'shape', '')}")
    if not isinstance(polygons, PolygonSet):
        raise TypeError(f"polygons must be a csgnb.bsp.PolygonSet, got {type(polygons).__name__}")
    label = check_label(label)
    seed = check_seed(seed)
    verts = _checked_vertices(palette, polygons)
    palette = np.ascontiguousarray(palette)
    n = len(polygons)
    if n == 0:
        return BSPTree.leaf(palette[:0], OUT)
    order = np.random.default_rng(seed).permutation(n).astype(np.int32)
    cap_nodes, cap_arena, cap_stack = _initial_capacities(n, int(polygons.sizes.max()))
    while True:
        plane, neg, pos, lab = (np.empty(cap_nodes, np.int32) for _ in range(4))
        a_edges = np.empty(cap_arena, np.int32)
        a_verts = np.empty((cap_arena, 4), palette.dtype)
        sides = np.empty(cap_arena, np.int8)
        st = [np.empty(cap_stack, np.int32) for _ in range(3)]
        count = int(build_kernel(palette, polygons.support, polygons.offsets, polygons.edges, verts, order,
                                  int(label), plane, neg, pos, lab, a_edges, a_verts, sides, *st))
        if count >= 0:
            break
        if count == -1:
            cap_nodes *= 4
        elif count == -2:
            cap_arena *= 2
        else:
            cap_stack *= 2
    plane, neg, pos, lab = plane[:count], neg[:count], pos[:count], lab[:count]
    inner = plane >= 0
    used, first = np.unique(plane[inner], return_index=True)
    used = used[np.argsort(first, kind="stable")]
    remap = np.full(palette.shape[0], -1, np.int32)
    remap[used] = np.arange(used.shape[0], dtype=np.int32)
    plane = np.where(inner, remap[np.maximum(plane, 0)], -1).astype(np.int32)
    # built here, valid by construction (its palette was checked with the polygons): not re-validated
    return BSPTree(np.ascontiguousarray(palette[used]), plane, neg, pos, lab, validate=False)


# ---------------------------------------------------------------------------
# exact triangle-triangle tests (integer vertices within the mesh budget)


@jit
def _orient3d(V, a, b, c, d, pl, sd):
    """Sign of det[b - a, c - a, d - a] for rows of ``V`` ((n, 3) int64).

    Computed as n·d + w of the plane (n, w) through a, b, c. Within any width's mesh
    budget (|coordinate| <= 87 298 202) |n| <= 8 V^2, |w| <= 24 V^3 and the value
    <= 48 V^3 < 2^127, so the 128-bit scratch ``pl``, ``sd`` is always exact.
    """
    plane_from_points_into(V, a, V, b, V, c, pl, 0)
    signed_distance_into(V, d, pl, 0, sd, 0)
    return wide_sign_at(sd, 0, 0)


@jit
def _orient2d(V, a, b, c, ax):
    """Sign of the orientation of rows a, b, c of ``V`` projected along axis ``ax`` (int64: |value| <= 8 V^2)."""
    u = 1 if ax == 0 else 0
    v = 1 if ax == 2 else 2
    det = (V[b, u] - V[a, u]) * (V[c, v] - V[a, v]) - (V[b, v] - V[a, v]) * (V[c, u] - V[a, u])
    if det > 0:
        return 1
    return -1 if det < 0 else 0


@jit
def _dominant_axis(V, p, q, r):
    """Axis of the largest |coefficient| of (q - p) x (r - p): the projection that keeps the triangle's area."""
    x1, y1, z1 = V[q, 0] - V[p, 0], V[q, 1] - V[p, 1], V[q, 2] - V[p, 2]
    x2, y2, z2 = V[r, 0] - V[p, 0], V[r, 1] - V[p, 1], V[r, 2] - V[p, 2]
    n0 = abs(y1 * z2 - z1 * y2)
    n1 = abs(z1 * x2 - x1 * z2)
    n2 = abs(x1 * y2 - y1 * x2)
    if n0 >= n1 and n0 >= n2:
        return 0
    return 1 if n1 >= n2 else 2


@jit
def _on_segment_2d(V, a, b, c, ax):
    """For c collinear with a, b (projected): whether c lies on the closed segment [a, b]."""
    for t in range(3):
        if t != ax and not (min(V[a, t], V[b, t]) <= V[c, t] <= max(V[a, t], V[b, t])):
            return False
    return True


@jit
def _segments_meet_2d(V, a, b, c, d, ax):
    d1 = _orient2d(V, a, b, c, ax)
    d2 = _orient2d(V, a, b, d, ax)
    d3 = _orient2d(V, c, d, a, ax)
    d4 = _orient2d(V, c, d, b, ax)
    if d1 * d2 < 0 and d3 * d4 < 0:
        return True
    return ((d1 == 0 and _on_segment_2d(V, a, b, c, ax)) or (d2 == 0 and _on_segment_2d(V, a, b, d, ax))
            or (d3 == 0 and _on_segment_2d(V, c, d, a, ax)) or (d4 == 0 and _on_segment_2d(V, c, d, b, ax)))


@jit
def _in_triangle_2d(V, x, p, q, r, ax):
    s1 = _orient2d(V, p, q, x, ax)
    s2 = _orient2d(V, q, r, x, ax)
    s3 = _orient2d(V, r, p, x, ax)
    return not ((s1 < 0 or s2 < 0 or s3 < 0) and (s1 > 0 or s2 > 0 or s3 > 0))


@jit
def _segment_meets_triangle(V, a, b, p, q, r, pl, sd):
    """Whether the closed segment [a, b] and the closed triangle (p, q, r) share a point (exact)."""
    oa = _orient3d(V, p, q, r, a, pl, sd)
    ob = _orient3d(V, p, q, r, b, pl, sd)
    if oa == ob and oa != 0:
        return False
    if oa == 0 and ob == 0:  # in the triangle's plane: decide in a projection that keeps incidences
        ax = _dominant_axis(V, p, q, r)
        if _in_triangle_2d(V, a, p, q, r, ax) or _in_triangle_2d(V, b, p, q, r, ax):
            return True
        return (_segments_meet_2d(V, a, b, p, q, ax) or _segments_meet_2d(V, a, b, q, r, ax)
                or _segments_meet_2d(V, a, b, r, p, ax))
    # The segment meets the plane in one point; the line ab passes through the closed
    # triangle iff its sides against the three edge lines (Plücker) never disagree.
    s1 = _orient3d(V, a, b, p, q, pl, sd)
    s2 = _orient3d(V, a, b, q, r, pl, sd)
    s3 = _orient3d(V, a, b, r, p, pl, sd)
    return not ((s1 > 0 or s2 > 0 or s3 > 0) and (s1 < 0 or s2 < 0 or s3 < 0))


@jit
def _triangles_overlap(V, T, i, j, pl, sd):
    """Whether faces i and j of a manifold mesh meet beyond the vertices and edge they share.

    * no shared vertex: any common point. The intersection of two triangles, if
      not empty, contains a point on an edge of one of them (an endpoint of the
      intersection segment, or a vertex in the coplanar case), so six
      segment-triangle tests decide it;
    * one shared vertex v: they meet elsewhere iff the edge opposite v of one meets
      the other (near v both are cones from v; a common direction reaches the
      opposite edge of the shorter triangle inside the longer one);
    * a shared edge: only coplanar triangles folded onto the same side of it overlap.
    """
    shared = 0
    for s in range(3):
        for t in range(3):
            if T[i, s] == T[j, t]:
                shared += 1
    if shared == 0:
        for s in range(3):
            a, b = T[i, s], T[i, (s + 1) % 3]
            if _segment_meets_triangle(V, a, b, T[j, 0], T[j, 1], T[j, 2], pl, sd):
                return True
            a, b = T[j, s], T[j, (s + 1) % 3]
            if _segment_meets_triangle(V, a, b, T[i, 0], T[i, 1], T[i, 2], pl, sd):
                return True
        return False
    if shared == 1:
        si = 0
        tj = 0
        for s in range(3):
            for t in range(3):
                if T[i, s] == T[j, t]:
                    si, tj = s, t
        if _segment_meets_triangle(V, T[i, (si + 1) % 3], T[i, (si + 2) % 3], T[j, 0], T[j, 1], T[j, 2], pl, sd):
            return True
        return _segment_meets_triangle(V, T[j, (tj + 1) % 3], T[j, (tj + 2) % 3], T[i, 0], T[i, 1], T[i, 2], pl, sd)
    if shared == 2:
        ci = -1
        cj = -1
        for s in range(3):
            if T[i, s] != T[j, 0] and T[i, s] != T[j, 1] and T[i, s] != T[j, 2]:
                ci = s
            if T[j, s] != T[i, 0] and T[j, s] != T[i, 1] and T[j, s] != T[i, 2]:
                cj = s
        u, w = T[i, (ci + 1) % 3], T[i, (ci + 2) % 3]
        if _orient3d(V, u, w, T[i, ci], T[j, cj], pl, sd) != 0:
            return False
        ax = _dominant_axis(V, T[i, 0], T[i, 1], T[i, 2])
        return _orient2d(V, u, w, T[i, ci], ax) == _orient2d(V, u, w, T[j, cj], ax)
    return True  # the same three vertices twice


@jit
def _fill_cells(lo_cell, hi_cell, G0, G1, keys, ids):
    t = 0
    for i in range(lo_cell.shape[0]):
        for z in range(lo_cell[i, 2], hi_cell[i, 2] + 1):
            for y in range(lo_cell[i, 1], hi_cell[i, 1] + 1):
                for x in range(lo_cell[i, 0], hi_cell[i, 0] + 1):
                    keys[t] = x + G0 * (y + G1 * z)
                    ids[t] = i
                    t += 1


@jit
def _overlapping_pairs(V, T, lo, hi, origin, h, G0, G1, keys, ids, pl, sd, found):
    """Scan each grid cell's triangle pairs; store overlapping pairs in ``found`` (k, 2) until it is full.

    A pair is tested only in the cell holding the lower corner of the intersection of
    their bounding boxes, so each pair is tested once. Returns the number stored.
    """
    n = keys.shape[0]
    count = 0
    g = 0
    while g < n:
        e = g
        while e < n and keys[e] == keys[g]:
            e += 1
        for x in range(g, e):
            i = ids[x]
            for y in range(x + 1, e):
                j = ids[y]
                key = 0
                disjoint = False
                for c in range(3):
                    low = max(lo[i, c], lo[j, c])
                    if low > min(hi[i, c], hi[j, c]):
                        disjoint = True
                    cell = (low - origin[c]) // h
                    key += cell * (1 if c == 0 else (G0 if c == 1 else G0 * G1))
                if disjoint or key != keys[g]:
                    continue
                if _triangles_overlap(V, T, i, j, pl, sd):
                    found[count, 0] = min(i, j)
                    found[count, 1] = max(i, j)
                    count += 1
                    if count == found.shape[0]:
                        return count
        g = e
    return count


def _first_self_intersection(V: np.ndarray, T: np.ndarray) -> tuple[int, int] | None:
    """The first pair of faces that overlap (by a uniform grid of bounding boxes), or None."""
    pairs = self_intersections(V, T, limit=1)
    return None if not len(pairs) else (int(pairs[0, 0]), int(pairs[0, 1]))


def self_intersections(V: np.ndarray, T: np.ndarray, limit: int | None = None) -> np.ndarray:
    """The pairs of faces ``(i, j)``, i < j, that cross or touch away from the vertices and edge they share.

    Exact (integer vertices within the mesh budget); a uniform grid of bounding boxes finds the
    candidates. At most ``limit`` pairs (all by default): a ``(k, 2)`` int64 array.
    """
    n = T.shape[0]
    corners = V[T]  # (n, 3, 3)
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    origin = lo.min(axis=0)
    extent = hi.max(axis=0) - origin
    # Cells about the size of a typical face: O(1) faces per cell on a surface.
    h = max(1, int(np.ceil((hi - lo).max(axis=1).mean())))
    while True:
        G = extent // h + 1
        lo_cell, hi_cell = (lo - origin) // h, (hi - origin) // h
        total = int(np.prod(hi_cell - lo_cell + 1, axis=1).sum())
        if (G.astype(float).prod() < 2.0**62 and total <= 16 * n + 64) or G.max() == 1:
            break
        h *= 2
    keys = np.empty(total, np.int64)
    ids = np.empty(total, np.int64)
    _fill_cells(lo_cell, hi_cell, int(G[0]), int(G[1]), keys, ids)
    order = np.argsort(keys, kind="stable")
    pl = np.empty((1, 4), wide_dtype(128))
    sd = np.empty(1, wide_dtype(128))
    V, T, keys, ids = np.ascontiguousarray(V), np.ascontiguousarray(T), keys[order], ids[order]
    cap = limit if limit is not None else n + 16
    while True:
        found = np.empty((cap, 2), np.int64)
        count = _overlapping_pairs(V, T, lo, hi, origin, h, int(G[0]), int(G[1]), keys, ids, pl, sd, found)
        if count < cap or limit is not None:
            return found[:count]
        cap *= 4


# ---------------------------------------------------------------------------
# validation

WINDING_HINT = ("; or, to take the points the mesh winds around (overlapping parts as their union, folds removed; "
                "exact), pass fill='winding'")


def _describe_shell(k: int, shell: np.ndarray, first_face: np.ndarray) -> str:
    return f"shell {k} ({int(np.count_nonzero(shell == k))} faces, the first is face {int(first_face[k])})"


@jit
def _shell_windings(V, T, faces, P, Q, lo, hi, wind, pl, sd):
    """Add the signed crossings of the segment from row P to row Q of ``V`` with ``faces`` to ``wind``.

    ``wind[t]`` gains +1 where the segment leaves through face ``faces[t]`` along its outward
    normal and -1 where it enters; ``lo``, ``hi`` bound the segment. Returns False when the
    segment passes exactly through an edge or a vertex of a face, or runs inside a face's plane
    across it (the caller then tries another direction).
    """
    for t in range(faces.shape[0]):
        f = faces[t]
        a, b, c = T[f, 0], T[f, 1], T[f, 2]
        outside = False
        for k in range(3):
            if max(V[a, k], V[b, k], V[c, k]) < lo[k] or min(V[a, k], V[b, k], V[c, k]) > hi[k]:
                outside = True
        if outside:
            continue
        op = _orient3d(V, a, b, c, P, pl, sd)
        oq = _orient3d(V, a, b, c, Q, pl, sd)
        if op == 0 and oq == 0:
            # Inside the face's plane: only a path across the face itself is ambiguous.
            ax = _dominant_axis(V, a, b, c)
            if (_segments_meet_2d(V, P, Q, a, b, ax) or _segments_meet_2d(V, P, Q, b, c, ax)
                    or _segments_meet_2d(V, P, Q, c, a, ax)):
                return False
            continue
        if op == oq or op == 0 or oq == 0:
            continue  # both on one side, or touching the plane at an end (never inside the face: see caller)
        s1 = _orient3d(V, P, Q, a, b, pl, sd)
        s2 = _orient3d(V, P, Q, b, c, pl, sd)
        s3 = _orient3d(V, P, Q, c, a, pl, sd)
        if (s1 > 0 or s2 > 0 or s3 > 0) and (s1 < 0 or s2 < 0 or s3 < 0):
            continue  # the line passes beside the face
        if s1 == 0 or s2 == 0 or s3 == 0:
            return False  # through an edge or a vertex
        wind[t] = oq
    return True


def _check_nesting(W, T, shell, n_shells, volume6, first_face) -> None:
    """Raise unless every shell is an outer boundary at depth 0 or a cavity (facing inward) at depth 1.

    The winding number of the whole mesh must be 1 inside the solid and 0 outside. Crossing a
    face of shell k changes it by one, so both sides of every face are right exactly when the
    winding number of the *other* shells at that face -- the nesting depth of shell k -- is 0
    for an outward shell and 1 for an inward one. Depths are exact: the winding number of a
    face centroid of shell k (scaled by 3 to stay integral) with respect to each shell whose
    bounding box contains it, counted along a segment in a direction that meets no edge.
    """
    V3 = 3 * W
    lo = np.full((n_shells, 3), np.iinfo(np.int64).max)
    hi = np.full((n_shells, 3), np.iinfo(np.int64).min)
    corners = V3[T]  # (m, 3, 3)
    np.minimum.at(lo, shell, corners.min(axis=1))
    np.maximum.at(hi, shell, corners.max(axis=1))
    order = np.argsort(shell, kind="stable")
    bounds = np.searchsorted(shell[order], np.arange(n_shells + 1))
    far = int(V3[:, 0].max()) + 3
    span = int(V3.max() - V3.min()) + 3
    rng = np.random.default_rng(0)
    VX = np.concatenate([V3, np.zeros((2, 3), np.int64)])
    p_row, q_row = V3.shape[0], V3.shape[0] + 1
    pl = np.empty((1, 4), wide_dtype(128))
    sd = np.empty(1, wide_dtype(128))
    for k in range(n_shells):
        f = int(first_face[k])
        point = W[T[f]].sum(axis=0)  # 3 x the centroid of face f: inside the face, on no other shell
        holders = np.flatnonzero(np.all((lo < point) & (point < hi), axis=1))
        holders = holders[holders != k]
        depth, container = 0, -1
        if holders.size:
            faces = np.concatenate([order[bounds[j]:bounds[j + 1]] for j in holders])
            VX[p_row] = point
            for _ in range(64):
                VX[q_row] = (far + int(rng.integers(0, span)), point[1] + int(rng.integers(-span, span + 1)),
                             point[2] + int(rng.integers(-span, span + 1)))
                wind = np.zeros(faces.shape[0], np.int64)
                seg_lo, seg_hi = VX[[p_row, q_row]].min(axis=0), VX[[p_row, q_row]].max(axis=0)
                if _shell_windings(VX, T, faces, p_row, q_row, seg_lo, seg_hi, wind, pl, sd):
                    break
            else:  # pragma: no cover - 64 random directions all through an edge
                raise InternalError("no segment from a face centroid avoided every edge (a bug: please report)")
            per_shell = np.zeros(n_shells, np.int64)
            np.add.at(per_shell, shell[faces], wind)
            depth = int(per_shell.sum())
            inside_of = np.flatnonzero(per_shell)
            container = int(inside_of[-1]) if inside_of.size else -1
        outward = volume6[k] > 0
        if outward and depth == 0 or not outward and depth == 1:
            continue
        name = _describe_shell(k, shell, first_face)
        if outward and depth == 1:
            raise GeometryError(
                f"{name} lies inside shell {container} and also faces outward, so the space between them would "
                "be inside twice: if it is a cavity, reverse its faces (e.g. faces[shell_faces, ::-1]); if it "
                f"is a separate solid, move it out of the other one{WINDING_HINT}"
            )
        if not outward and depth == 0 and container >= 0:
            raise GeometryError(
                f"{name} is oriented inward but lies in empty space (inside the cavity shell {container}), so "
                "there is no material to cut it from: flip its faces to make it an island, or remove it"
            )
        if not outward and depth == 0:
            raise GeometryError(
                f"{name} is oriented inward (its exact volume {volume6[k]}/6 is negative) but lies inside no "
                "other shell: flip its faces (e.g. faces[shell_faces, ::-1]); only cavities face inward"
            )
        raise GeometryError(
            f"{name} faces {'outward' if outward else 'inward'} at nesting depth {depth} (inside shell "
            f"{container}): shells must alternate, an outward boundary around each inward cavity, without "
            "repeating; reverse or remove the shells that break the alternation"
        )


def _cancel_opposite_pairs(T: np.ndarray, F: np.ndarray, face_ids: np.ndarray):
    """Drop pairs of faces on the same three vertices facing opposite ways (a fin of zero thickness: rounding
    flattens a thin wedge onto itself, and mesh Booleans leave them where parts touch). A pair bounds no volume and
    its edges cancel, so the solid is unchanged. Returns ``(T, F, face_ids, number of faces dropped)``."""
    m = T.shape[0]
    if m == 0:
        return T, F, face_ids, 0
    # A face's rotation class: the smallest vertex first, the other two in order (orientation kept); its mirror
    # image swaps the last two. Rows are numbered by np.unique (no packed key that could overflow).
    r = np.argmin(T, axis=1)
    canon = np.stack([T[np.arange(m), (r + k) % 3] for k in range(3)], axis=1)
    _, ids = np.unique(np.r_[canon, canon[:, [0, 2, 1]]], axis=0, return_inverse=True)
    ids = ids.reshape(-1)
    own, mirror = ids[:m], ids[m:]
    waiting: dict[int, list[int]] = {}  # faces of each class not yet paired
    drop = np.zeros(m, bool)
    for f in np.flatnonzero(np.isin(own, mirror)).tolist():
        partners = waiting.get(int(mirror[f]))
        if partners:
            drop[f] = drop[partners.pop()] = True
        else:
            waiting.setdefault(int(own[f]), []).append(f)
    keep = np.flatnonzero(~drop)
    return T[keep], F[keep], face_ids[keep], int(drop.sum())


def _wedges_alternate(W: np.ndarray, T: np.ndarray, p: int, q: int, tails: np.ndarray, faces: np.ndarray) -> bool:
    """Whether the ``faces`` around the edge ``(p, q)`` (more than two: the solid pinches there, as where two parts
    touch along an edge, or where a mesh tool keeps two vertices at one point) bound wedges of solid that do not
    overlap: in angular order around the edge, the faces run along it alternately one way and the other, and no
    two lie in one half-plane. ``tails``: each face's half-edge's first vertex. Exact (Python integers)."""
    if len(faces) % 2:
        return False
    P = [int(x) for x in W[p]]
    d = [int(W[q][i]) - P[i] for i in range(3)]
    dd = sum(x * x for x in d)

    def det(u, v):  # (u x v) . d
        return (u[1] * v[2] - u[2] * v[1]) * d[0] + (u[2] * v[0] - u[0] * v[2]) * d[1] + \
            (u[0] * v[1] - u[1] * v[0]) * d[2]

    spokes = []
    for t, f in zip(tails.tolist(), faces.tolist(), strict=True):
        r = next(int(x) for x in T[f] if int(x) not in (p, q))
        u = [int(W[r][i]) - P[i] for i in range(3)]
        ud = sum(u[i] * d[i] for i in range(3))
        spokes.append(([dd * u[i] - ud * d[i] for i in range(3)], t == p))  # u's part across d, and the direction
    ref = spokes[0][0]

    def half(w) -> int:  # 0: angle in [0, pi) from ref around d, 1: [pi, 2 pi)
        s = det(ref, w)
        return 0 if s > 0 or (s == 0 and sum(x * y for x, y in zip(w, ref, strict=True)) > 0) else 1

    def before(x, y) -> int:  # a comparison: negative when x comes first counter-clockwise about d
        hx, hy = half(x[0]), half(y[0])
        return hx - hy if hx != hy else -det(x[0], y[0])

    ring = sorted(spokes, key=cmp_to_key(before))
    n = len(ring)
    for i in range(n):
        w, forward = ring[i]
        w2, forward2 = ring[(i + 1) % n]
        if forward == forward2 or (half(w) == half(w2) and det(w, w2) == 0):
            return False
    return True


def _describe_edge(first_index, V, a: int, b: int) -> str:
    return f"({int(first_index[a])}, {int(first_index[b])}) from {V[a].tolist()} to {V[b].tolist()}"


def _split_flat_faces(W, T, F, face_ids, first_index):
    """Remove flat faces (three distinct collinear corners) by splitting the neighbour across their long edge.

    A flat face ``(p, m, n)`` with ``m`` strictly between ``n`` and ``p`` covers no area: its long edge ``n -> p``
    is matched by one neighbour ``(p, n, x)``, and its short edges ``p -> m``, ``m -> n`` by the faces on the other
    side. Replacing the neighbour by ``(p, m, x)`` and ``(m, n, x)`` and dropping the flat face leaves the same
    surface, closed and oriented as before (what quantizing a fine mesh makes: a vertex rounded onto an edge). A
    piece that is flat in turn (the neighbour was flat too) is repaired the same way; a neighbour that is the flat
    face's mirror image ``(p, n, m)`` goes with it (the two pair each other's edges and bound nothing). A flat
    face whose long edge has no single neighbour is left for the caller's checks to refuse.

    Returns ``(T, F, face_ids, count)``: the faces (welded and input indices, their input face numbers) and how many
    flat faces were removed.
    """
    normal = np.cross(W[T[:, 1]] - W[T[:, 0]], W[T[:, 2]] - W[T[:, 0]])
    queue = np.flatnonzero(~normal.any(axis=1)).tolist()
    if not queue:
        return T, F, face_ids, 0
    tri, src, ids = T.tolist(), F.tolist(), face_ids.tolist()
    alive = [True] * len(tri)
    half_edges: dict[tuple[int, int], list[int]] = {}  # (a, b) -> faces with that half-edge (dead ones filtered)
    for g, (a, b, c) in enumerate(tri):
        for e in ((a, b), (b, c), (c, a)):
            half_edges.setdefault(e, []).append(g)
    count = 0
    while queue:
        f = queue.pop()
        if not alive[f]:
            continue
        P = W[tri[f]]
        axis = int(np.argmax(P.max(axis=0) - P.min(axis=0)))
        k = int(np.argsort(P[:, axis], kind="stable")[1])  # the middle corner
        m, n, p = tri[f][k], tri[f][(k + 1) % 3], tri[f][(k + 2) % 3]
        hits = [g for g in half_edges.get((p, n), []) if alive[g] and g != f]
        if len(hits) != 1:
            continue
        g = hits[0]
        x = next(tri[g][(r + 2) % 3] for r in range(3) if tri[g][r] == p and tri[g][(r + 1) % 3] == n)
        alive[f] = alive[g] = False
        # A neighbour that is f's mirror image (x == m, both flat) leaves no piece: the two pair each other's edges.
        # (Input pairs are cancelled before this; a mirror can still arise among the pieces of earlier splits.)
        for piece in ([p, m, x], [m, n, x]) if x != m else ():
            new = len(tri)
            tri.append(piece)
            src.append(first_index[piece].tolist())
            ids.append(ids[g])
            alive.append(True)
            a, b, c = piece
            for e in ((a, b), (b, c), (c, a)):
                half_edges.setdefault(e, []).append(new)
            if not np.cross(W[b] - W[a], W[c] - W[a]).any():
                queue.append(new)
        count += 1
    keep = np.flatnonzero(alive)
    return (np.array(tri, np.int64)[keep], np.array(src, np.int64)[keep], np.array(ids, np.int64)[keep], count)


def validate_mesh(vertices, faces, width: int = DEFAULT_WIDTH, *,
                  report: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Check that an integer triangle mesh bounds a solid; return it welded: ``(vertices, faces)``.

    Vertices at equal positions are merged first (a triangle soup with repeated
    corners is fine), and faces that merging collapsed (two corners at one point: what
    quantizing a fine float mesh onto a grid makes) are dropped -- such a face bounds no
    volume, and its two remaining edges cancel, so the rest closes up as before; their
    number goes to ``report["collapsed_faces"]`` when a dict is given. Flat faces (three
    distinct collinear corners: a vertex rounded onto the segment between two others) are
    removed by splitting the one neighbour across their long edge at the middle corner
    (the same surface; counted in ``report["flat_faces"]``). Then, in this
    order, the mesh must be: integer ``(n, 3)`` / ``(m, 3)`` arrays with valid indices;
    within the mesh budget of ``width``; free of flat faces that could not be split that
    way; closed (every edge has an
    opposite half-edge); edge-manifold (two faces per edge); consistently oriented; outward (positive exact volume);
    free of self-intersections (exact tests between faces whose bounding boxes
    overlap, including touching faces and coplanar faces folded over a shared edge);
    and, for meshes of several shells (connected components), properly nested: every
    shell that faces outward lies inside no other solid, every inward-facing shell is a
    cavity of exactly one (exact winding numbers).

    Vertices may be given as any integer dtype or as integral floats; non-integral
    coordinates are refused (quantize float meshes with :func:`csgnb.exact.quantize`).

    Returns
    -------
    vertices : (v, 3) int64
        The distinct positions.
    faces : (m, 3) int64
        Indices into them.

    Raises
    ------
    PrecisionError
        A coordinate exceeds ``budget(width).max_mesh_coordinate``.
    GeometryError
        Any other defect; the message names the faces or edge concerned.
    """
    W, T, F, face_ids, first_index, hint = repaired_mesh(vertices, faces, width, report)
    try:
        _check_closed_solid(W, T, F, face_ids, first_index)
    except GeometryError as exc:
        if not hint:
            raise
        raise GeometryError(f"{exc} -- {hint}") from None
    return W, T


def repaired_mesh(vertices, faces, width: int, report: dict | None = None):
    """The first half of :func:`validate_mesh`: the arrays checked, vertices welded, collapsed faces dropped,
    opposite pairs cancelled, flat faces split. Returns ``(W, T, F, face_ids, first_index, hint)``: the welded
    vertices and faces, each face's input corners and input row, each vertex's first input row, and what rounding
    did as a sentence (empty when nothing was merged, collapsed or split) for a refusal to add."""
    V = integer_array(vertices, "vertices")
    if V.ndim != 2 or V.shape[1] != 3:
        raise GeometryError(f"vertices must have shape (n, 3), got {V.shape}")
    try:
        F = integer_array(faces, "faces")
    except (PrecisionError, TypeError) as exc:
        raise GeometryError(f"faces must be integer vertex indices: {exc}") from None
    if F.ndim != 2 or F.shape[1] != 3:
        raise GeometryError(f"faces must have shape (m, 3) (triangles), got {F.shape}")
    if F.shape[0] < 4:
        raise GeometryError(f"a closed triangle mesh needs at least 4 faces, got {F.shape[0]}")
    if F.min() < 0 or F.max() >= V.shape[0]:
        bad = int(np.flatnonzero(((F < 0) | (F >= V.shape[0])).any(axis=1))[0])
        raise GeometryError(f"face {bad} {F[bad].tolist()} has a vertex index outside 0 .. {V.shape[0] - 1}")
    check_mesh_points(V, width, "vertices")

    W, first_index, inverse = np.unique(V, axis=0, return_index=True, return_inverse=True)
    T = inverse.reshape(-1)[F]
    repeated = (T[:, 0] == T[:, 1]) | (T[:, 1] == T[:, 2]) | (T[:, 2] == T[:, 0])
    if report is not None:
        report["collapsed_faces"] = int(repeated.sum())
    if repeated.any():
        keep = np.flatnonzero(~repeated)
        if keep.shape[0] < 4:
            raise GeometryError(f"only {keep.shape[0]} faces of {F.shape[0]} have three distinct corners (the rest "
                                "collapsed when equal vertices merged): no closed mesh is left")
        T, F = T[keep], F[keep]
        face_ids = keep
    else:
        face_ids = np.arange(T.shape[0])
    T, F, face_ids, cancelled = _cancel_opposite_pairs(T, F, face_ids)
    if report is not None:
        report["cancelled_faces"] = cancelled
    T, F, face_ids, split = _split_flat_faces(W, T, F, face_ids, first_index)
    if report is not None:
        report["flat_faces"] = split
    collapsed, merged = int(repeated.sum()), V.shape[0] - W.shape[0]
    hint = ""
    if collapsed + split + merged:
        # Merged vertices, collapsed and flat faces are what rounding a float mesh does when its detail is finer
        # than the grid: the likelier cause of a defect than the mesh itself (a welded mesh gets no hint).
        wider = [f"{budget(w).max_mesh_coordinate:,} at {w}" for w in (192, 256) if w > width]
        finer = (f"quantize it on a finer grid (|coordinate| <= {budget(width).max_mesh_coordinate:,} at {width} "
                 f"bits, {', '.join(wider)}) or coarsen the mesh first" if wider else
                 f"{width} bits allow no finer grid (|coordinate| <= {budget(width).max_mesh_coordinate:,}): "
                 "coarsen the mesh first (merge its near-duplicate vertices, remove its slivers)")
        hint = (f"before this check {merged} vertices fell on the grid points of others, {collapsed} faces "
                f"collapsed and {split} flat ones were split: if the mesh was quantized from a float mesh, its "
                f"detail is finer than the grid; {finer}")
    return W, T, F, face_ids, first_index, hint


def half_edges(W: np.ndarray, T: np.ndarray):
    """The faces' half-edges ``a -> b`` (and their ``face``), sorted by undirected edge: ``(a, b, face, starts,
    counts)``, each edge's half-edges at ``starts[i] : starts[i] + counts[i]``."""
    a = T.reshape(-1)
    b = T[:, [1, 2, 0]].reshape(-1)
    face = np.repeat(np.arange(T.shape[0]), 3)
    key = np.minimum(a, b) * W.shape[0] + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    key, a, b, face = key[order], a[order], b[order], face[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    counts = np.diff(np.r_[starts, key.shape[0]])
    return a, b, face, starts, counts


def _check_closed_solid(W: np.ndarray, T: np.ndarray, F: np.ndarray, face_ids: np.ndarray,
                        first_index: np.ndarray) -> None:
    """The topological and geometric checks of :func:`validate_mesh` on the welded, repaired faces ``T``
    (``F``: their input corners and ``face_ids`` their input rows, for the messages)."""
    normal = np.cross(W[T[:, 1]] - W[T[:, 0]], W[T[:, 2]] - W[T[:, 0]])  # fits int64 within the budget
    degenerate = np.flatnonzero(~normal.any(axis=1))
    if degenerate.size:
        f = int(degenerate[0])
        raise GeometryError(
            f"face {int(face_ids[f])} {F[f].tolist()} is flat: its corners {W[T[f]].tolist()} are three distinct "
            "collinear points, and the edge through the middle one is not shared by exactly one other face (so it "
            "cannot be split there); remove the face and split that edge"
        )

    # Half-edges (a -> b) of face f; an undirected edge must carry exactly one each way.
    m = T.shape[0]
    a, b, face, starts, counts = half_edges(W, T)
    if np.any(counts == 1):
        s = int(starts[np.argmax(counts == 1)])
        raise GeometryError(
            f"the mesh is open: edge {_describe_edge(first_index, W, a[s], b[s])} of face "
            f"{int(face_ids[face[s]])} has no "
            "opposite half-edge (a hole or a crack; weld or fill it)"
        )
    for g in np.flatnonzero(counts > 2).tolist():
        s, c = int(starts[g]), int(counts[g])
        if not _wedges_alternate(W, T, int(a[s]), int(b[s]), a[s : s + c], face[s : s + c]):
            faces_on = sorted(int(x) for x in face[s : s + c])
            raise GeometryError(
                f"the mesh is not manifold: edge {_describe_edge(first_index, W, a[s], b[s])} is shared by {c} faces "
                f"{faces_on} that do not alternate in and out around it (parts overlapping there, or a fold); split "
                f"the solid into parts that meet in at most an edge{WINDING_HINT}"
            )
    same = (a[starts] == a[starts + 1]) & (counts == 2)
    if np.any(same):
        s = int(starts[np.argmax(same)])
        raise GeometryError(
            f"the mesh is inconsistently oriented: faces {int(face_ids[face[s]])} and "
            f"{int(face_ids[face[s + 1]])} run along their shared "
            f"edge {_describe_edge(first_index, W, a[s], b[s])} in the same direction; reverse one of them"
        )

    # Shells: the connected components of the face graph (faces joined across edges),
    # numbered in the order of their first face.
    n_shells, shell = connected_components(
        coo_matrix((np.ones(starts.shape[0]), (face[starts], face[starts + 1])), shape=(m, m)), directed=False)
    # Six times the exact volume of each shell: sum of det(p, q, r) = p·(q x r) (q x r fits int64, the sum
    # does not).
    P, Q, R = W[T[:, 0]], W[T[:, 1]], W[T[:, 2]]
    terms = (P.astype(object) * np.cross(Q, R).astype(object)).sum(axis=1)
    volume6 = [0] * n_shells
    for s_, t in zip(shell.tolist(), terms.tolist(), strict=True):
        volume6[s_] += t
    first_face = np.full(n_shells, m, np.int64)
    np.minimum.at(first_face, shell, np.arange(m))
    if n_shells == 1:
        if volume6[0] < 0:
            raise GeometryError(
                f"the mesh is oriented inward (its exact volume {volume6[0]}/6 is negative); flip every face, "
                "e.g. faces[:, ::-1]"
            )
        if volume6[0] == 0:
            raise GeometryError("the mesh encloses zero volume (it is flat or folds back onto itself)")
    else:
        for k, v in enumerate(volume6):
            if v == 0:
                raise GeometryError(f"{_describe_shell(k, shell, first_face)} encloses zero volume (it is flat or "
                                    "folds back onto itself)")

    pair = _first_self_intersection(W, T)
    if pair is not None:
        i, j = pair
        raise GeometryError(
            f"the mesh intersects itself: faces {int(face_ids[i])} {F[i].tolist()} and "
            f"{int(face_ids[j])} {F[j].tolist()} "
            f"(corners {W[T[i]].tolist()} and {W[T[j]].tolist()}) cross or touch away from the vertices and edge "
            f"they share{WINDING_HINT}"
        )
    if n_shells > 1:
        _check_nesting(W, T, shell, n_shells, volume6, first_face)


def bsp_from_mesh(vertices, faces, *, width: int = DEFAULT_WIDTH, seed: int = 0, label: int = 1,
                  fill: str = "solid") -> BSPTree:
    """Return the BSP of the solid bounded by a closed, outward-oriented integer triangle mesh.

    With ``fill="winding"``, of the points a closed mesh winds around positively instead: meshes that overlap,
    cross or fold are accepted (:func:`csgnb.bsp.winding.winding_bsp`).

    Parameters
    ----------
    vertices : (n, 3) int64
        Within the mesh budget of ``width`` (``csgnb.exact.budget(width).max_mesh_coordinate``;
        quantize float meshes with :func:`csgnb.exact.quantize`).
    faces : (m, 3) int
        Triangles, counter-clockwise seen from outside.
    width : {128, 192, 256}
        Bit width of the predicates, and of the returned palette.
    seed : int
        Seed of the random insertion order.
    label : int
        Label of the solid's leaves (>= 1).
    fill : {"solid", "winding"}
        See :data:`csgnb.bsp.winding.FILLS`.

    Returns
    -------
    BSPTree

    Raises
    ------
    PrecisionError, GeometryError
        See :func:`validate_mesh` (``fill="winding"``: :func:`csgnb.bsp.winding.winding_bsp`).
    """
    from csgnb.bsp.winding import check_fill, winding_bsp

    if check_fill(fill) == "winding":
        return winding_bsp(vertices, faces, width=width, seed=seed, label=label)
    W, T = validate_mesh(vertices, faces, width)
    palette, polygons = polygons_from_triangles(W, T, width)
    return bsp_from_polygons(palette, polygons, seed=seed, label=label)
