"""Merging the coplanar pieces of a boundary surface back into larger convex polygons.

An octree workpiece's surface is cut wherever a face crosses a cell wall (and a BSP's
wherever a splitting plane crosses it): one facet of a tool comes back as several convex
pieces on the same plane, sharing edges on the walls. :func:`merge_coplanar` joins two
pieces across such an edge when that keeps the polygon convex, repeatedly, without
computing anything new: the pieces share exact vertices and each edge names the second
plane it lies on (``BoundarySurface.edge_planes``), so

* two polygons on the same supporting plane (same palette row and side), behind the same
  label, that use one edge once each way (no other polygon uses it) are candidates;
* their union is convex exactly when, at both ends of the shared edge, the edge entering
  the end and the edge leaving it lie on the same plane row (the same line: the end becomes
  a flat vertex) -- a conservative test (two different rows through one line are not
  recognised), decided on integers, never on coordinates;
* a union that would visit a vertex twice (pieces sharing more than one edge) is skipped.

A vertex left flat in every polygon that uses it (two pieces of each of two facets met there)
is no corner of anything and is dropped, from all of them at once; a flat vertex another
polygon needs as a corner stays (the surface stays conforming, without T-junctions), which
``BoundarySurface.triangulate`` handles exactly. The result encloses the same solid.

Known limit: the manifold split (``manifold=True`` exports) is refused on a merged surface: on
a part that touches itself along an edge it kept that edge shared by four triangles (found by
``tests/test_bsp_surface.py``); export a 2-manifold from the unmerged surface.
"""

from __future__ import annotations

import numpy as np

from csgnb.errors import GeometryError

__all__ = ["merge_coplanar"]


def _candidate_edges(s) -> np.ndarray:
    """``(c, 4) int64`` rows ``(polygon, twin polygon, tail, head)``: edges used once each way whose two polygons
    share support and label, each undirected edge once (tail < head), in polygon order."""
    sizes = np.diff(s.offsets)
    owner = np.repeat(np.arange(sizes.shape[0], dtype=np.int64), sizes)
    tails, heads = s._directed_edges(None)
    n = int(max(tails.max(initial=-1), heads.max(initial=-1))) + 1
    keys = tails * n + heads
    uniq, first, counts = np.unique(keys, return_index=True, return_counts=True)
    rev = heads * n + tails
    at = np.minimum(np.searchsorted(uniq, rev), max(uniq.shape[0] - 1, 0))
    found = (uniq[at] == rev) if uniq.shape[0] else np.zeros(0, bool)
    once = counts[np.searchsorted(uniq, keys)] == 1
    ok = found & once & (tails < heads)
    ok[ok] &= counts[at[ok]] == 1
    j = np.flatnonzero(ok)
    twin = owner[first[at[j]]]
    mine = owner[j]
    same = (s.support[mine] == s.support[twin]) & (s.labels[mine] == s.labels[twin]) & (mine != twin)
    return np.column_stack([mine, twin, tails[j], heads[j]])[same]


def merge_coplanar(s):
    """The surface ``s`` (a :class:`csgnb.bsp.surface.BoundarySurface` with ``edge_planes``) with coplanar
    neighbouring pieces joined into convex polygons (module docstring), in up to three passes. Same solid,
    same palette; the vertices that were corners of nothing dropped."""
    if s.edge_planes is None:
        raise GeometryError("merging coplanar pieces needs each edge's plane (edge_planes); build the surface with "
                            "assemble_surface (Workpiece.surface, extract_boundary(...).surface)")
    for _ in range(_PASSES):
        # a pass can free the next: two pieces that shared a straight run of edges share one edge once the
        # vertex between them, flat on both sides, is dropped
        m = _merge_pass(s)
        if m.n_polygons == s.n_polygons and m.n_vertices == s.n_vertices:
            break
        s = m
    return m


#: Passes at most: on the 1,000-capsule dome carve (55,000 pieces) the first three take it to 32,433
#: polygons, all seven to 32,373 (0.2 % more) at twice the time.
_PASSES = 3


def _merge_pass(s):
    """One pass of :func:`merge_coplanar` over the candidate edges, then the flat vertices dropped."""
    from csgnb.bsp.surface import BoundarySurface

    n_poly = s.n_polygons
    if n_poly == 0:
        return s
    idx = s.indices.tolist()
    planes = np.asarray(s.edge_planes).tolist()
    offsets = s.offsets.tolist()
    parent = list(range(n_poly))
    loops: dict[int, tuple[list[int], list[int]]] = {}

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def loop(g: int) -> tuple[list[int], list[int]]:
        got = loops.get(g)
        if got is None:
            got = loops[g] = (idx[offsets[g]:offsets[g + 1]], planes[offsets[g]:offsets[g + 1]])
        return got

    for i, k, a, b in _candidate_edges(s).tolist():
        g1, g2 = find(i), find(k)
        if g1 == g2:
            continue
        v1, e1 = loop(g1)
        v2, e2 = loop(g2)
        # orient: g1 holds a -> b, g2 holds b -> a (swap the names if it is the other way round)
        p1 = v1.index(a)
        if v1[(p1 + 1) % len(v1)] != b:
            a, b = b, a
            p1 = v1.index(a)
            if v1[(p1 + 1) % len(v1)] != b:
                continue
        p2 = v2.index(b)
        if v2[(p2 + 1) % len(v2)] != a:
            continue
        # g1 from b round to a, then g2 from a round to b; edge j runs from vertex j to vertex j + 1
        V1, E1 = v1[p1 + 1:] + v1[:p1 + 1], e1[p1 + 1:] + e1[:p1 + 1]
        V2, E2 = v2[p2 + 1:] + v2[:p2 + 1], e2[p2 + 1:] + e2[:p2 + 1]
        if E1[-2] != E2[0] or E2[-2] != E1[0]:
            continue  # a corner at a or at b: the union would not be convex (or not recognised as such)
        merged = V1 + V2[1:-1]
        if len(set(merged)) != len(merged):
            continue  # the pieces share more than this edge
        parent[g2] = g1
        loops[g1] = (merged, E1[:-1] + E2[:-1])
        loops.pop(g2, None)

    roots = [i for i in range(n_poly) if find(i) == i]
    # A vertex that is flat (its two edges on one plane row) in every polygon using it is no corner of anything:
    # it goes, in every polygon at once (their common edges stay common).
    uses = np.zeros(s.vertices.shape[0], np.int64)
    flat = np.zeros(s.vertices.shape[0], np.int64)
    for i in roots:
        v, e = loop(i)
        for j, x in enumerate(v):
            uses[x] += 1
            flat[x] += e[j - 1] == e[j]
    drop = (uses > 0) & (uses == flat)
    out_idx: list[int] = []
    out_planes: list[int] = []
    out_off = [0]
    for i in roots:
        v, e = loop(i)
        for j, x in enumerate(v):
            if not drop[x]:
                out_idx.append(x)
                out_planes.append(e[j])  # the edge leaving x runs on to the next kept vertex (one line)
        out_off.append(len(out_idx))
    keep = np.asarray(roots, np.int64)
    indices = np.asarray(out_idx, np.int64)
    used = np.unique(indices)
    remap = np.full(s.vertices.shape[0], -1, np.int64)
    remap[used] = np.arange(used.shape[0])
    positions = None if s._positions is None else s._positions[used]
    return BoundarySurface(s.palette, s.vertices[used], np.asarray(out_off, np.int64), remap[indices],
                           np.asarray(s.support)[keep], np.asarray(s.labels)[keep],
                           np.asarray(out_planes, np.int64), positions, is_merged=True)
