"""A convex tool's facets as plane-based polygons: what a cell's boundary merge takes as the hull's pieces.

A boundary merge (:func:`csgnb.bsp.boundary_merge.merge_boundaries`) needs the tool's boundary inside the cell as
plane-based pieces. A mesh tool has them: its polygons clipped to the cell's walls
(:func:`csgnb.octree.kernels.clip_tool_polygons`, array work, most polygons copied whole). A convex hull had them
only by cutting the cell's box by every hull plane that crosses it in the mesh store and extracting the faces
(dozens of cuts where a cell sees a capsule's side). Its facets are the same kind of polygon: support the facet's
plane, edges the planes of the facets across its edges, vertices the hull's own grid points, so the hull's pieces
in a cell are its facets clipped to the walls as well -- made once per hull here, in one compiled pass.

Facet ``i`` follows the tool's plane order (:func:`csgnb.octree.tool.spread_order`): its support is tool plane
``i`` and its edges name tool planes, so the workpiece maps both to palette rows as it does a mesh tool's. The
import convention holds: edge ``j`` runs from vertex ``j - 1`` to vertex ``j``, and vertex ``j`` is the support met
by edges ``j`` and ``j + 1`` (the facet's ring is strictly convex and counter-clockwise seen from outside, and two
facets of a convex polytope share at most one edge, so consecutive edges name different planes).
"""

from __future__ import annotations

import numpy as np

from csgnb._jit import jit
from csgnb._unlinked import unlinked
from csgnb.exact.integral import max_abs
from csgnb.mesh.hull import _face_rings, _side_signs, _split_offsets, directed_edge_table, edge_slot

__all__ = ["FacetPolygons", "facet_polygons_of_hulls", "hull_facet_polygons", "hull_facets_of_batch"]

FacetPolygons = tuple
"""``(support (k,) int32, offsets (k + 1,) int32, edges (m,) int32, points (m, 3) int64, lo (k, 3) int64,
hi (k, 3) int64)``: support and edges are tool plane indices, ``points[j]`` vertex ``j``'s grid point, ``lo``/``hi``
each facet's exact integer box."""


@jit
def _dominant_axes(N):
    """Per normal of ``N`` (k, 3) int64: the axis of its largest |component| (the first of equals) and whether that
    component is negative -- what :func:`csgnb.mesh.hull._face_rings` projects along."""
    k = N.shape[0]
    ax = np.zeros(k, np.int64)
    flip = np.zeros(k, np.bool_)
    for j in range(k):
        best = 0
        for c in range(1, 3):
            if abs(N[j, c]) > abs(N[j, best]):
                best = c
        ax[j] = best
        flip[j] = N[j, best] < 0
    return ax, flip


_SIDES_SAFE = float(1 << 122)
"""Bound on 3·|n|·|x| (in doubles, below the i128 sums' 2**123 with room for rounding) under which the facet pass
takes a hull; offsets are bounded by their high words (``|high| < 2**60``)."""


@unlinked
@jit
def facet_polygons_kernel(L, N, dh, dl, origin, order):
    """The facets of a hull as plane-based polygons (see the module docstring).

    ``L`` (n, 3) int64 local points holding every vertex, ``N`` (k, 3) int64 outward normals and the local offsets
    split as ``d = dh·2**62 + dl`` (int64, :func:`csgnb.mesh.hull._split_offsets`), ``origin`` (3,) int64 (global =
    local + origin), ``order`` (k,) int64 the tool's plane order (tool plane ``i`` is hull facet ``order[i]``).

    Returns ``(ok, offsets, edges, points, lo, hi)`` as :data:`FacetPolygons` without the support (tool plane ``i``
    supports facet ``i``); ``ok`` False (and empty arrays) where the exact i128 side signs do not take the hull, a
    ring is not a proper polygon or an edge lacks its reverse: the caller keeps the extraction.
    """
    n = L.shape[0]
    k = N.shape[0]
    bad = (False, np.zeros(1, np.int32), np.zeros(0, np.int32), np.zeros((0, 3), np.int64),
           np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64))
    extent = 0
    for i in range(n):
        for c in range(3):
            extent = max(extent, abs(L[i, c]))
    normal = 0
    for j in range(k):
        for c in range(3):
            normal = max(normal, abs(N[j, c]))
        if abs(dh[j]) >= (1 << 60):
            return bad
    if extent >= (1 << 62) or 3.0 * float(normal) * float(extent) >= _SIDES_SAFE:
        return bad
    on = _side_signs(L, N, dh, dl) == 0
    ax, flip = _dominant_axes(N)
    offsets, ring = _face_rings(L, on, ax, flip)
    return polygons_of_rings(L, offsets, ring, origin, order)


@unlinked
@jit
def polygons_of_rings(L, offsets, ring, origin, order):
    """:func:`facet_polygons_kernel` from the facets' rings (``ring[offsets[j]:offsets[j + 1]]``: facet j's points,
    indices into ``L``, as :func:`csgnb.mesh.hull._face_rings` orders them): the edges' planes from the facet
    across each edge, the points, the boxes, in the tool's plane order."""
    n = L.shape[0]
    k = offsets.shape[0] - 1
    bad = (False, np.zeros(1, np.int32), np.zeros(0, np.int32), np.zeros((0, 3), np.int64),
           np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64))
    total = offsets[k] - offsets[0]  # (a batch's rings lie in one array: offsets need not start at 0)
    ok, keys, owner, mask = directed_edge_table(offsets, ring, n)
    if not ok:
        return bad
    place = np.empty(k, np.int64)
    for i in range(k):
        place[order[i]] = i
    out_offsets = np.zeros(k + 1, np.int32)
    edges = np.empty(total, np.int32)
    points = np.empty((total, 3), np.int64)
    lo = np.empty((k, 3), np.int64)
    hi = np.empty((k, 3), np.int64)
    pos = 0
    for i in range(k):
        f = order[i]
        s = offsets[f]
        m = offsets[f + 1] - s
        for t in range(m):
            v = ring[s + t]
            prev = ring[s + (t - 1) % m]
            # edge t runs from prev to v; the facet across it holds v -> prev
            slot = edge_slot(keys, mask, v * n + prev)
            if slot < 0:
                return bad  # an edge without its reverse
            edges[pos + t] = place[owner[slot]]
            for c in range(3):
                points[pos + t, c] = L[v, c] + origin[c]
        for t in range(m):
            if edges[pos + t] == edges[pos + (t + 1) % m] or edges[pos + t] == i:
                return bad
        for c in range(3):
            a = points[pos, c]
            b = points[pos, c]
            for t in range(1, m):
                a = min(a, points[pos + t, c])
                b = max(b, points[pos + t, c])
            lo[i, c] = a
            hi[i, c] = b
        pos += m
        out_offsets[i + 1] = pos
    return True, out_offsets, edges, points, lo, hi


@jit
def facet_polygons_of_hulls(L, lstarts, N, dh, dl, origins, starts, order, rings):
    """:func:`facet_polygons_kernel` for many hulls: hull i's local points are ``L[lstarts[i]:lstarts[i + 1]]``, its
    normals and split offsets rows ``starts[i]:starts[i + 1]`` of ``N``, ``dh``, ``dl``, its origin ``origins[i]``
    and ``order`` (r,) int64 the global row order of the batch's planes (each hull's rows in spread order).
    ``rings`` = ``(at, ring_offsets, ring)``: hull i's known rings (:func:`polygons_of_rings`) are
    ``ring_offsets[at[i]:at[i] + k + 1]`` (into ``ring``) where ``at[i] >= 0``.

    Returns ``(has, offsets, edges, points, lo, hi)``: ``has`` (n,) bool whether hull i has facets; tool plane g's
    facet (g a global row) is ``edges[offsets[g]:offsets[g + 1]]`` (local plane indices of its hull) with
    ``points`` beside them, ``lo[g]``/``hi[g]`` its box -- empty for a hull without facets.
    """
    n = starts.shape[0] - 1
    r = starts[n]
    has = np.zeros(n, np.bool_)
    offsets = np.zeros(r + 1, np.int64)
    cap = 8 * r + 16
    edges = np.empty(cap, np.int32)
    points = np.empty((cap, 3), np.int64)
    lo = np.zeros((r, 3), np.int64)
    hi = np.zeros((r, 3), np.int64)
    pos = 0
    at, ring_offsets, ring = rings
    for i in range(n):
        s, e = starts[i], starts[i + 1]
        local = order[s:e] - s
        Li = np.ascontiguousarray(L[lstarts[i]:lstarts[i + 1]])
        if at[i] >= 0:
            ok, off, ed, pts, flo, fhi = polygons_of_rings(
                Li, np.ascontiguousarray(ring_offsets[at[i]:at[i] + e - s + 1]), ring, np.ascontiguousarray(origins[i]),
                local)
        else:
            ok, off, ed, pts, flo, fhi = facet_polygons_kernel(
                Li, np.ascontiguousarray(N[s:e]), np.ascontiguousarray(dh[s:e]), np.ascontiguousarray(dl[s:e]),
                np.ascontiguousarray(origins[i]), local)
        m = off[off.shape[0] - 1] if ok else 0
        if pos + m > cap:
            cap = max(2 * cap, pos + m)
            grown_edges = np.empty(cap, np.int32)
            grown_edges[:pos] = edges[:pos]
            grown_points = np.empty((cap, 3), np.int64)
            grown_points[:pos] = points[:pos]
            edges, points = grown_edges, grown_points
        for j in range(e - s):
            offsets[s + j] = pos + (off[j] if ok else 0)
        if ok:
            has[i] = True
            edges[pos:pos + m] = ed
            points[pos:pos + m] = pts
            lo[s:e] = flo
            hi[s:e] = fhi
            pos += m
        offsets[e] = pos
    return has, offsets, edges[:pos], points[:pos], lo, hi


def _facet_inputs(hull):
    """A hull's local points, normals, split offsets, origin (int64) and its kept rings (or None) as the facet pass
    takes them, or None where it does not take the hull. Offsets are split only where no rings are kept (their
    signs are what finds the rings)."""
    L, N, d, o = hull._candidates, hull._normals, hull._d_local, hull._origin
    if L.dtype == object or N.dtype == object or o.dtype == object:
        return None
    L, N, o = L.astype(np.int64, copy=False), N.astype(np.int64, copy=False), o.astype(np.int64, copy=False)
    known = hull.__dict__.get("_rings")
    if known is not None:
        zero = np.zeros(N.shape[0], np.int64)
        return L, N, zero, zero, o, known
    if d.dtype == object and max_abs(d) >= (1 << 120):
        return None
    dh, dl = _split_offsets(d)
    return L, N, dh, dl, o, None


def hull_facet_polygons(hull, order: np.ndarray) -> FacetPolygons | None:
    """The facets of the :class:`~csgnb.mesh.hull.ConvexHull` ``hull`` as plane-based polygons over the tool planes
    ``hull.planes[order]`` (:data:`FacetPolygons`), or None where the compiled pass does not take it (its exact
    i128 side signs, or no closed convex surface): the workpiece then cuts the cell's box by the hull's planes."""
    inputs = _facet_inputs(hull)
    if inputs is None:
        return None
    L, N, dh, dl, origin, known = inputs
    if known is not None:  # the hull's verification built them
        ok, offsets, edges, points, lo, hi = polygons_of_rings(
            np.ascontiguousarray(L), known[0], known[1], np.ascontiguousarray(origin),
            np.ascontiguousarray(order, np.int64))
    else:
        ok, offsets, edges, points, lo, hi = facet_polygons_kernel(
            np.ascontiguousarray(L), np.ascontiguousarray(N), dh, dl, np.ascontiguousarray(origin),
            np.ascontiguousarray(order, np.int64))
    if not ok:
        return None
    return np.arange(N.shape[0], dtype=np.int32), offsets, edges, points, lo, hi


def hull_facets_of_batch(hulls: list, starts: np.ndarray, order: np.ndarray):
    """:func:`hull_facet_polygons` of every hull of a batch (:mod:`csgnb.octree.batch`) in one compiled pass, the
    same facets hull by hull: ``(has, offsets, edges, points, lo, hi)`` of :func:`facet_polygons_of_hulls`."""
    n = len(hulls)
    Ls, Ns, dhs, dls = [], [], [], []
    origins = np.zeros((n, 3), np.int64)
    sizes = np.zeros(n + 1, np.int64)
    at = np.full(n, -1, np.int64)
    ring_offsets, ring_lists, ring_base, offsets_used = [], [], 0, 0
    for i, h in enumerate(hulls):
        inputs = _facet_inputs(h)
        known = inputs[5] if inputs is not None else None
        if known is not None:
            at[i] = offsets_used
            ring_offsets.append(known[0] + ring_base)
            ring_lists.append(known[1])
            offsets_used += known[0].shape[0]
            ring_base += known[1].shape[0]
        if inputs is None:  # no facets: a hull with no points fails the pass
            k = int(starts[i + 1] - starts[i])
            inputs = (np.zeros((0, 3), np.int64), np.zeros((k, 3), np.int64), np.zeros(k, np.int64),
                      np.zeros(k, np.int64), np.zeros(3, np.int64))
        L, N, dh, dl, origins[i] = inputs[:5]
        Ls.append(L)
        Ns.append(N)
        dhs.append(dh)
        dls.append(dl)
        sizes[i + 1] = L.shape[0]
    rings = (at, np.concatenate(ring_offsets) if ring_offsets else np.zeros(1, np.int64),
             np.concatenate(ring_lists) if ring_lists else np.zeros(0, np.int64))
    return facet_polygons_of_hulls(np.concatenate(Ls), np.cumsum(sizes), np.concatenate(Ns), np.concatenate(dhs),
                                   np.concatenate(dls), origins, np.ascontiguousarray(starts, np.int64),
                                   np.ascontiguousarray(order, np.int64), rings)
