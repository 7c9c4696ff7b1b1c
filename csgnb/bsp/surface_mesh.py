"""Triangle meshes of exact boundary surfaces: triangulation without degenerate triangles, 2-manifold split.

Two kernels on the arrays of a :class:`~csgnb.bsp.surface.BoundarySurface`:

* :func:`triangulate` -- each convex polygon becomes ``k - 2`` triangles, none of zero area.
  T-junction removal leaves *flat* vertices (valence 2, on a straight side between two
  corners); a fan would join three of them on one side into a flat triangle. A vertex is flat
  when its successor lies on the plane of its incoming edge (the edge lies on the support and
  that plane, so this is collinearity; decided exactly at 2w + 64 bits), or, for a surface
  without edge planes, when the 3 x 4 matrix of it and its neighbours has rank 2. While flat
  vertices remain, the ear at a corner next to one is clipped (its triangle has area, the chord
  it leaves is interior, so both neighbours are corners afterwards and the rest is convex with
  area); the flat-free rest is fanned.

* :func:`manifold_split` -- where a solid touches itself along an edge (two cells meeting only
  there), the edge is used by four faces (2j in general); a consumer that needs a 2-manifold
  needs each edge used once in each direction. Per label, the faces around such an edge are
  sorted exactly by angle around the edge line and each face is paired with the face that
  bounds the same solid wedge; then the corners of the faces at each vertex are joined across
  paired edges, and every vertex gets one copy per connected fan of corners (per label). So
  vertices are duplicated along non-manifold edges, at vertices where the solid touches itself
  in a single point, and where two labels meet (each label becomes its own closed shell).
  Positions are unchanged; copies coincide exactly.

Angles around an edge line with direction d = ±(n_s x n_t): a face with outward normal n that
uses the edge along d (against d) extends from it in direction w = n x d (w = d x n). For two
faces, sign det(d, w_a, w_b) = s_a s_b sign det(n_a, n_b, d) (from (a x d) x (b x d) =
d det(a, b, d)), and det(n_a, n_b, n_s x n_t) is a Binet-Cauchy product of dot products of
palette normals (:func:`~csgnb.bsp.surface_intrinsics.binet_cauchy_sign_at`, exact at 2w bits).
Rotating positively about d, the solid lies just after a face that uses the edge against d
and just before one that uses it along d, so faces alternate and each "against" face is
paired with the next face.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb._views import unmanaged
from csgnb.bsp.surface_intrinsics import (
    binet_cauchy_sign_at,
    collinear_at,
    compare_coordinate_at,
    line_direction_into,
    normals_dot_sign_at,
)
from csgnb.bsp.surface_kernels import narrow_tests_exact, on_plane
from csgnb.errors import GeometryError, InternalError
from csgnb.exact.intrinsics import wide_sign_at

__all__ = ["ManifoldSplit", "TriangleMesh", "manifold_split", "triangulate"]

_OK = 0
_ZERO_AREA = 1  # status[1]: polygon whose vertices are all collinear
_SHORT = 2  # status[1]: polygon with fewer than 3 vertices
_NO_PROGRESS = 3  # status[1]: polygon (internal)
_OPEN = 4  # status[1]: half-edge whose uses are unbalanced (surface not closed)
_COINCIDENT = 5  # status[1]: half-edge; two faces of one label on the same half-plane
_NOT_ALTERNATING = 6  # status[1]: half-edge; faces around the edge do not alternate in and out


class TriangleMesh(NamedTuple):
    """A triangulated boundary surface (:meth:`~csgnb.bsp.surface.BoundarySurface.triangulate`).

    vertices : (n, 3) float64 -- positions, correctly rounded from the exact vertices;
    triangles : (m, 3) int64 -- counter-clockwise seen from outside, none of zero area;
    polygon : (m,) int64 -- the surface polygon each triangle comes from;
    source : (n,) int64 -- the surface vertex of each mesh vertex (``arange`` unless split).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    polygon: np.ndarray
    source: np.ndarray


class ManifoldSplit(NamedTuple):
    """Polygon loops over duplicated vertices, so every edge is used once in each direction.

    source : (n',) int64 -- the surface vertex of each new vertex; the first copy of every
    vertex keeps its id (``source[:n] == arange(n)``), further copies are numbered from n on;
    indices : like ``BoundarySurface.indices``, over the new vertices.
    """

    source: np.ndarray
    indices: np.ndarray


# ---------------------------------------------------------------------------
# triangulation


@jit
def _triangulate_kernel(offsets, geo, loop, vertices, palette, edge_planes, use_planes, narrow, tris, tri_poly, status):
    """Triangles of every polygon (exact flat-vertex test, ear clipping next to flats, then a fan).

    ``geo`` are the polygon loops over ``vertices`` (used for the geometry), ``loop`` the ids
    written into ``tris`` ((sum(k) - 2 * polygons, 3) int64); ``tri_poly`` gets each triangle's polygon.
    """
    offsets, geo, loop, vertices, palette = (
        unmanaged(offsets),
        unmanaged(geo),
        unmanaged(loop),
        unmanaged(vertices),
        unmanaged(palette),
    )
    edge_planes, tris, tri_poly, status = (
        unmanaged(edge_planes),
        unmanaged(tris),
        unmanaged(tri_poly),
        unmanaged(status),
    )
    largest = 3
    for p in range(offsets.shape[0] - 1):
        largest = max(largest, offsets[p + 1] - offsets[p])
    nxt = np.empty(largest, np.int64)
    prv = np.empty(largest, np.int64)
    flat = np.empty(largest, np.bool_)
    t = 0
    for p in range(offsets.shape[0] - 1):
        a = offsets[p]
        n = offsets[p + 1] - a
        if n < 3:
            status[0] = _SHORT
            status[1] = p
            return
        nflat = 0
        for i in range(n):
            before = a + (i + n - 1) % n
            after = a + (i + 1) % n
            prv[i] = (i + n - 1) % n
            nxt[i] = (i + 1) % n
            if use_planes:
                flat[i] = on_plane(narrow, vertices, geo[after], palette, edge_planes[before])
            else:
                flat[i] = collinear_at(vertices, geo[before], geo[a + i], geo[after])
            if flat[i]:
                nflat += 1
        if nflat == n:
            status[0] = _ZERO_AREA
            status[1] = p
            return
        cur = 0
        left = n
        steps = 0
        while nflat > 0 and left > 3:
            if not flat[cur] and (flat[prv[cur]] or flat[nxt[cur]]):
                u = prv[cur]
                w = nxt[cur]
                tris[t, 0] = loop[a + u]
                tris[t, 1] = loop[a + cur]
                tris[t, 2] = loop[a + w]
                tri_poly[t] = p
                t += 1
                nxt[u] = w
                prv[w] = u
                for x in (u, w):
                    if flat[x]:
                        flat[x] = False
                        nflat -= 1
                left -= 1
                cur = w
            else:
                cur = nxt[cur]
            steps += 1
            if steps > 4 * n * n + 16:
                status[0] = _NO_PROGRESS
                status[1] = p
                return
        if nflat > 0:
            status[0] = _ZERO_AREA
            status[1] = p
            return
        x = nxt[cur]
        while nxt[x] != cur:
            tris[t, 0] = loop[a + cur]
            tris[t, 1] = loop[a + x]
            tris[t, 2] = loop[a + nxt[x]]
            tri_poly[t] = p
            t += 1
            x = nxt[x]


def _raise_triangulation(status: np.ndarray, surface) -> None:
    code, p = int(status[0]), int(status[1])
    if code == _OK:
        return
    if code == _SHORT:
        raise GeometryError(f"polygon {p} has fewer than 3 vertices: it cannot be triangulated")
    if code == _ZERO_AREA:
        raise GeometryError(
            f"polygon {p} ({surface.polygon(p).tolist()}) has all its vertices on one line: it has no area"
        )
    raise InternalError(f"triangulating polygon {p} made no progress (a bug in csgnb: please report it)")


def triangulate(surface, manifold: bool = False) -> TriangleMesh:
    """Return the triangles of ``surface`` (a :class:`~csgnb.bsp.surface.BoundarySurface`), none of zero area.

    With ``manifold=True`` the vertices are first split by :func:`manifold_split`.
    """
    offsets = np.ascontiguousarray(surface.offsets, np.int64)
    geo = np.ascontiguousarray(surface.indices, np.int64)
    if manifold:
        split = manifold_split(surface)
        loop, source = split.indices, split.source
    else:
        loop, source = geo, np.arange(surface.n_vertices, dtype=np.int64)
    m = int(geo.shape[0] - 2 * surface.n_polygons)
    tris = np.empty((max(m, 0), 3), np.int64)
    tri_poly = np.empty(max(m, 0), np.int64)
    if surface.n_polygons:
        status = np.zeros(2, np.int64)
        planes = surface.edge_planes
        use_planes = planes is not None
        planes = np.ascontiguousarray(planes if use_planes else np.zeros(0, np.int64), np.int64)
        narrow = use_planes and narrow_tests_exact(surface.vertices, surface.palette)
        _triangulate_kernel(
            offsets, geo, loop, surface.vertices, surface.palette, planes, use_planes, narrow, tris, tri_poly, status
        )
        _raise_triangulation(status, surface)
    positions = surface.positions()
    return TriangleMesh(positions[source] if manifold else positions, tris, tri_poly, source)


# ---------------------------------------------------------------------------
# 2-manifold split


@jit(inline="always")
def _find(parent, x):
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@jit(inline="always")
def _union(parent, x, y):
    rx = _find(parent, x)
    ry = _find(parent, y)
    if rx != ry:
        if rx < ry:
            parent[ry] = rx
        else:
            parent[rx] = ry


@jit(inline="always")
def _angle_sign(palette, rows, signs, sigma, a, b, s, t):
    """sign det(d, w_a, w_b) of half-edges a, b around d = sigma (n_s x n_t) (see the module docstring).

    w_h = s_h (n_h x d) with n_h = eps_h n_row; ``signs[h]`` = eps_h s_h. Then
    det(d, w_a, w_b) = |d|^2 signs[a] signs[b] sigma det(n_row_a, n_row_b, n_s x n_t).
    """
    return signs[a] * signs[b] * sigma * binet_cauchy_sign_at(palette, rows[a], rows[b], s, t)


@jit
def _manifold_kernel(
    offsets, indices, labels, support, edge_planes, vertices, palette, n_vertices, scratch, new_indices, source, status
):
    """Pair the uses of every edge (per label, by angle where more than two), join corners, number the fans.

    Writes ``new_indices`` (h,) and ``source`` (n_vertices + h,) and returns the number of new vertices.
    """
    h_count = indices.shape[0]
    face = np.empty(h_count, np.int64)
    nexth = np.empty(h_count, np.int64)
    for p in range(offsets.shape[0] - 1):
        a = offsets[p]
        n = offsets[p + 1] - a
        for i in range(n):
            face[a + i] = p
            nexth[a + i] = a + (i + 1) % n
    # Undirected edges per label: hash on (min * n + max, label).
    size = 16
    while size < 2 * h_count + 16:
        size *= 2
    mask = size - 1
    table = np.full(size, -1, np.int64)
    group = np.empty(h_count, np.int64)
    key_edge = np.empty(h_count, np.int64)
    key_label = np.empty(h_count, np.int64)
    ngroups = 0
    for h in range(h_count):
        u = indices[h]
        v = indices[nexth[h]]
        e = min(u, v) * n_vertices + max(u, v)
        lab = labels[face[h]]
        x = np.uint64(e) * np.uint64(0x9E3779B97F4A7C15) ^ np.uint64(lab) * np.uint64(0xC2B2AE3D27D4EB4F)
        x = x ^ (x >> np.uint64(29))
        i = np.int64(x & np.uint64(mask))
        while table[i] >= 0 and not (key_edge[table[i]] == e and key_label[table[i]] == lab):
            i = (i + 1) & mask
        if table[i] < 0:
            table[i] = ngroups
            key_edge[ngroups] = e
            key_label[ngroups] = lab
            ngroups += 1
        group[h] = table[i]
    first = np.zeros(ngroups + 1, np.int64)
    for h in range(h_count):
        first[group[h] + 1] += 1
    for g in range(ngroups):
        first[g + 1] += first[g]
    cursor = first[:ngroups].copy()
    members = np.empty(h_count, np.int64)
    for h in range(h_count):
        members[cursor[group[h]]] = h
        cursor[group[h]] += 1
    partner = np.full(h_count, -1, np.int64)
    rows = np.empty(h_count, np.int64)
    signs = np.empty(h_count, np.int64)
    half = np.empty(h_count, np.int64)
    for g in range(ngroups):
        a = first[g]
        b = first[g + 1]
        lo = key_edge[g] // n_vertices
        hi = key_edge[g] % n_vertices
        along = 0
        for j in range(a, b):
            if indices[members[j]] == lo:
                along += 1
        if 2 * along != b - a:
            status[0] = _OPEN
            status[1] = members[a]
            return 0
        if b - a == 2:
            h0 = members[a]
            h1 = members[a + 1]
            partner[h0] = h1
            partner[h1] = h0
            continue
        # Several solid wedges meet here: sort the faces by angle about d (from lo to hi).
        h0 = members[a]
        s = support[face[h0]]
        s = s if s >= 0 else ~s
        t = edge_planes[h0]
        k = line_direction_into(palette, s, t, scratch, 0)
        # d = sigma u points from lo to hi: coordinate k grows along d exactly when sigma u_k > 0.
        sigma = np.int64(wide_sign_at(scratch, 0, 3)) * compare_coordinate_at(vertices, hi, vertices, lo, k)
        for j in range(a, b):
            h = members[j]
            row = support[face[h]]
            rows[h] = row if row >= 0 else ~row
            # eps (outward normal = eps n_row) times s (+1 along d, -1 against).
            signs[h] = (1 if row >= 0 else -1) * (1 if indices[h] == lo else -1)
        for j in range(a, b):
            h = members[j]
            if h == h0:
                half[h] = 0
                continue
            c = _angle_sign(palette, rows, signs, sigma, h0, h, s, t)
            if c > 0:
                half[h] = 1
            elif c < 0:
                half[h] = 3
            else:
                # Coplanar normals n_row_h = lam n_row_h0: w_h = (signs[h] / signs[h0]) lam w_h0.
                same = signs[h0] * signs[h] * normals_dot_sign_at(palette, rows[h0], rows[h])
                if same > 0:
                    status[0] = _COINCIDENT
                    status[1] = h
                    return 0
                half[h] = 2
        for j in range(a + 1, b):  # insertion sort by (half, angle within the half)
            h = members[j]
            i = j - 1
            while i >= a:
                o = members[i]
                if half[o] < half[h]:
                    break
                if half[o] == half[h]:
                    c = _angle_sign(palette, rows, signs, sigma, o, h, s, t)
                    if c == 0:
                        status[0] = _COINCIDENT
                        status[1] = h
                        return 0
                    if c > 0:
                        break
                members[i + 1] = o
                i -= 1
            members[i + 1] = h
        for j in range(a, b):
            h = members[j]
            if indices[h] == hi:  # against d: the solid follows, up to the next face, which must run along d
                nx = members[j + 1] if j + 1 < b else members[a]
                if indices[nx] != lo:
                    status[0] = _NOT_ALTERNATING
                    status[1] = h
                    return 0
                partner[h] = nx
                partner[nx] = h
    for h in range(h_count):
        if partner[h] < 0:
            status[0] = _NO_PROGRESS
            status[1] = h
            return 0
    return _number_fans(
        indices,
        nexth,
        partner,
        np.arange(h_count),
        np.full(h_count, -1, np.int64),
        np.zeros(n_vertices, np.bool_),
        new_indices,
        source,
    )


@jit
def _number_fans(indices, nexth, partner, parent, owner, taken, new_indices, source):
    """Join corners across paired edges (union-find over ``parent``) and number each vertex's fans.

    A half-edge stands for the corner at its tail. The first fan of vertex v keeps id v, later
    fans get ids from n on. Returns the number of new vertices.
    """
    indices, nexth, partner, parent = unmanaged(indices), unmanaged(nexth), unmanaged(partner), unmanaged(parent)
    owner, taken, new_indices, source = unmanaged(owner), unmanaged(taken), unmanaged(new_indices), unmanaged(source)
    h_count = indices.shape[0]
    n_vertices = taken.shape[0]
    for h in range(h_count):
        q = partner[h]
        _union(parent, h, nexth[q])
        _union(parent, nexth[h], q)
    for v in range(n_vertices):
        source[v] = v
    count = n_vertices
    for h in range(h_count):
        r = _find(parent, h)
        if owner[r] < 0:
            v = indices[h]
            if taken[v]:
                owner[r] = count
                source[count] = v
                count += 1
            else:
                owner[r] = v
                taken[v] = True
        new_indices[h] = owner[r]
    return count


def manifold_split(surface) -> ManifoldSplit:
    """Duplicate vertices so that every edge is used once in each direction (see the module docstring).

    Raises :class:`GeometryError` for a surface that is not closed per label, or whose faces around
    an edge do not alternate between solid and empty wedges; ``ValueError`` for a surface without
    edge planes (every surface :func:`~csgnb.bsp.surface.assemble_surface` builds has them).
    """
    if surface.edge_planes is None:
        raise ValueError(
            "manifold_split needs the surface's edge planes (BoundarySurface.edge_planes); "
            "build the surface with csgnb.bsp.surface.assemble_surface"
        )
    indices = np.ascontiguousarray(surface.indices, np.int64)
    n = surface.n_vertices
    new_indices = np.empty_like(indices)
    source = np.empty(n + indices.shape[0], np.int64)
    status = np.zeros(2, np.int64)
    scratch = np.empty((1, 4), surface.vertices.dtype)
    count = _manifold_kernel(
        np.ascontiguousarray(surface.offsets, np.int64),
        indices,
        np.ascontiguousarray(surface.labels, np.int64),
        np.ascontiguousarray(surface.support, np.int64),
        np.ascontiguousarray(surface.edge_planes, np.int64),
        surface.vertices,
        surface.palette,
        n,
        scratch,
        new_indices,
        source,
        status,
    )
    code, h = int(status[0]), int(status[1])
    if code == _NO_PROGRESS:
        raise InternalError(f"manifold_split left half-edge {h} unpaired (a bug in csgnb: please report it)")
    if code != _OK:
        p = int(np.searchsorted(surface.offsets, h, side="right") - 1)
        what = {
            _OPEN: "is not used equally often in both directions by the polygons of its label: the surface "
            "is not closed",
            _COINCIDENT: "has two faces of one label on the same half-plane",
            _NOT_ALTERNATING: "has faces of one label that do not alternate between solid and empty wedges",
        }[code]
        raise GeometryError(
            f"the edge at index {h} (polygon {p}, label {int(surface.labels[p])}) {what}; "
            "manifold_split needs a closed boundary such as extraction produces"
        )
    return ManifoldSplit(source[:count].copy(), new_indices)
