"""Kernels of surface assembly: exact vertex merging and T-junction removal without gcds (paper §3.4).

:func:`csgnb.bsp.surface.assemble_surface` runs four kernels on the raw boundary pieces:

1. :func:`merge_vertices_kernel` -- vertex rows that are bitwise equal are merged by a hash of
   their limbs; each remaining representative is rounded to its nearest double position
   (correctly rounded, so *equal points round equally*, whatever their homogeneous scale), and
   a hash on those three doubles proposes candidates that are confirmed by exact
   cross-multiplication (x_c y_4 = y_c x_4). Points get ids in order of first appearance.
2. :func:`edge_pairs_kernel` -- every edge is checked exactly to lie on its polygon's support
   plane and on its edge plane (both endpoints), and the unordered plane pair is hashed.
3. :func:`pair_lines_kernel` -- pairs of planes through one line are merged: the line's key
   is canonical (k = axis of the largest direction component; u / u_k and the point where the
   line meets x_k = 0, both correctly rounded), and keys that agree are confirmed exactly
   (the other line's point lies on both planes, its direction is normal to both normals).
4. :func:`assemble_loops_kernel` -- each line's vertices (the endpoints of its edges) are
   sorted exactly along the line by coordinate k (strictly monotone along it since u_k != 0;
   doubles first, exact comparison on ties), and every edge receives the vertices strictly
   between its endpoints.

A vertex strictly inside an edge of a closed boundary is always an endpoint of another edge
on the same line (the surface near the edge is a set of half-planes hinged on it), so step 4
removes every T-junction; the tests check that independently with Fractions.

Status codes (``status[0]``) report bad input; the Python wrapper turns them into errors.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.bsp.surface_intrinsics import (
    compare_coordinate_at,
    copy_normalized_into,
    line_direction_into,
    normals_det_sign_at,
    on_plane_at,
)
from csgnb.errors import PrecisionError
from csgnb.exact.budgets import check_points_against_planes
from csgnb.exact.intrinsics import classify_at, intersect_into, points_equal_at, wide_sign_at
from csgnb.exact.predicates import ratio_to_double

__all__ = [
    "OK",
    "E_INFINITE",
    "E_OFF_PLANE",
    "E_NO_LINE",
    "E_ZERO_EDGE",
    "PieceArrays",
    "narrow_tests_exact",
    "on_plane",
    "merge_vertices_kernel",
    "edge_pairs_kernel",
    "pair_lines_kernel",
    "assemble_loops_kernel",
]

OK = 0
E_INFINITE = 1  # status[1]: vertex row with x4 = 0
E_OFF_PLANE = 2  # status[1:4]: vertex row, plane row, polygon
E_NO_LINE = 3  # status[1:4]: edge row, support row, edge plane row (parallel or equal planes)
E_ZERO_EDGE = 4  # status[1:3]: edge row, polygon (both endpoints are one point)

#: Groups of vertices on one line up to this size are sorted by insertion, larger ones by argsort first.
_SMALL_GROUP = 16


class PieceArrays(NamedTuple):
    """Raw boundary pieces as one kernel argument (see :func:`csgnb.bsp.surface.assemble_surface`).

    palette : (m, 4) wide; vx : (n, 4) wide; limbs : (n, 4 L) uint64, the limbs of ``vx``
    (same memory); edge_plane : (n,) int64; polys : (k, 5) int64 (first row, count, signed
    support, label, source face).
    """

    palette: np.ndarray
    vx: np.ndarray
    limbs: np.ndarray
    edge_plane: np.ndarray
    polys: np.ndarray


def narrow_tests_exact(points: np.ndarray, planes: np.ndarray) -> bool:
    """Whether ``classify_at`` (width w) is exact for every point of ``points`` against every plane of ``planes``.

    True when the conservative bound of :func:`csgnb.exact.budgets.check_points_against_planes`
    holds: (|x1|+|x2|+|x3|) N + |x4| D < 2^(w-1) with column maxima. Then x·s never leaves the
    w-bit range and the w-bit dot product (6 ns) decides x·s = 0 exactly; otherwise the kernels
    use :func:`on_plane_at` at 2w + 64 bits (33 ns), which is exact for any stored values.
    """
    if points.shape[0] == 0 or planes.shape[0] == 0:
        return True
    try:
        check_points_against_planes(points, planes)
    except PrecisionError:
        return False
    return True


@jit(inline="always")
def on_plane(narrow, X, i, S, j):
    """Whether point ``X[i]`` lies on plane ``S[j]``: at width w if ``narrow`` (see :func:`narrow_tests_exact`)."""
    if narrow:
        return classify_at(X, i, S, j) == 0
    return on_plane_at(X, i, S, j)


@jit(inline="always")
def _mix(h):
    """The splitmix64 finaliser of a uint64 (a well-spread hash step)."""
    h = h ^ (h >> np.uint64(30))
    h = h * np.uint64(0xBF58476D1CE4E5B9)
    h = h ^ (h >> np.uint64(27))
    h = h * np.uint64(0x94D049BB133111EB)
    return h ^ (h >> np.uint64(31))


@jit(inline="always")
def _table_mask(n):
    """Mask of an open-addressing table with at least 2 n + 16 slots (a power of two)."""
    size = 16
    while size < 2 * n + 16:
        size *= 2
    return size - 1


# Open-addressing tables (linear probing): a ``(size, 2) int64`` array of (value, hash) rows, value
# -1 for an empty slot, hash a non-negative int64 (:func:`_key`). Value and hash share a cache
# line, probes compare the hash before touching key data, and a table doubles (reinserting by
# stored hash) when half full, so it starts near the expected number of entries: tables of 2n
# slots cost more in page faults on first touch than the hashing itself (~15 ms of 74 at 216k rows).


@jit(inline="always")
def _key(h):
    """A uint64 hash as a non-negative int64 (its top 62 bits)."""
    return np.int64(h >> np.uint64(2))


@jit(inline="always")
def _new_table(expected):
    """An empty table with room for ``expected`` entries at load 1/2."""
    size = 16
    while size < 2 * expected:
        size *= 2
    return np.full((size, 2), -1, np.int64)


@jit
def _doubled(table):
    """The table with twice the slots, every entry reinserted by its stored hash."""
    size = 2 * table.shape[0]
    mask = size - 1
    new = np.full((size, 2), -1, np.int64)
    for i in range(table.shape[0]):
        if table[i, 0] >= 0:
            j = table[i, 1] & mask
            while new[j, 0] >= 0:
                j = (j + 1) & mask
            new[j, 0] = table[i, 0]
            new[j, 1] = table[i, 1]
    return new


_SEED = np.uint64(0x9E3779B97F4A7C15)


# Kernels that fill a growable table run as a resumable inner step (every array an argument, so
# it can drop reference counting with :func:`unmanaged`) inside a loop that grows the table and
# calls again: reassigning an array inside a hot loop makes numba incref and decref it on every
# iteration (measured: 18% of vertex merging in NRT_incref/NRT_decref).
_DONE = 0
_GROW_FIRST = 1
_GROW_SECOND = 2
_BAD = -1


@jit
def _merge_rows(vx, limbs, vid, vertices, pos, pos_bits, status, rows, points, first, state):
    """Merge rows from ``state[0]`` on (state: next row, bitwise-distinct rows, points); see the kernel."""
    vx, limbs, vid, vertices = unmanaged(vx), unmanaged(limbs), unmanaged(vid), unmanaged(vertices)
    pos, pos_bits, status, rows = unmanaged(pos), unmanaged(pos_bits), unmanaged(status), unmanaged(rows)
    points, first, state = unmanaged(points), unmanaged(first), unmanaged(state)
    n = vx.shape[0]
    nl = limbs.shape[1]
    n_rows = state[1]
    count = state[2]
    rmask = rows.shape[0] - 1
    pmask = points.shape[0] - 1
    for r in range(state[0], n):
        if 2 * (n_rows + 1) > rows.shape[0] or 2 * (count + 1) > points.shape[0]:
            state[0] = r
            state[1] = n_rows
            state[2] = count
            return _GROW_FIRST if 2 * (n_rows + 1) > rows.shape[0] else _GROW_SECOND
        h = _SEED
        for c in range(nl):
            h = _mix(h ^ limbs[r, c])
        hk = _key(h)
        i = hk & rmask
        hit = -1
        while rows[i, 0] >= 0:
            if rows[i, 1] == hk:
                q = rows[i, 0]
                same = True
                for c in range(nl):
                    if limbs[q, c] != limbs[r, c]:
                        same = False
                        break
                if same:
                    hit = q
                    break
            i = (i + 1) & rmask
        if hit >= 0:
            vid[r] = vid[hit]
            continue
        rows[i, 0] = r
        rows[i, 1] = hk
        n_rows += 1
        if wide_sign_at(vx, r, 3) == 0:
            status[0] = E_INFINITE
            status[1] = r
            return _BAD
        # The candidate's position goes into the next free row; it stays there if the point is new.
        for c in range(3):
            pos[count, c] = ratio_to_double(vx, r, c)
        h = _SEED
        for c in range(3):
            h = _mix(h ^ np.uint64(pos_bits[count, c]))
        hk = _key(h)
        i = hk & pmask
        hit = -1
        while points[i, 0] >= 0:
            p = points[i, 0]
            if (
                points[i, 1] == hk
                and pos_bits[p, 0] == pos_bits[count, 0]
                and pos_bits[p, 1] == pos_bits[count, 1]
                and pos_bits[p, 2] == pos_bits[count, 2]
                and points_equal_at(vx, r, vx, first[p])
            ):
                hit = p
                break
            i = (i + 1) & pmask
        if hit >= 0:
            vid[r] = hit
            continue
        points[i, 0] = count
        points[i, 1] = hk
        first[count] = r
        copy_normalized_into(vx, r, vertices, count)
        vid[r] = count
        count += 1
    state[0] = n
    state[1] = n_rows
    state[2] = count
    return _DONE


@jit
def merge_vertices_kernel(vx, limbs, vid, vertices, pos, pos_bits, status):
    """Merge the vertex rows of ``vx`` into distinct points; return their number (-1 on bad input).

    Writes ``vid`` (n,) int64 (point of each row), ``vertices[:count]`` ((n, 4) wide: the first
    row of each point, with x4 > 0) and ``pos[:count]`` ((n, 3) float64: correctly rounded
    positions; ``pos_bits`` is the same memory as int64).
    """
    n = vx.shape[0]
    # Expected sizes from extraction's pieces: ~40% of rows are bitwise distinct, ~27% distinct points.
    rows = _new_table(n // 2)
    points = _new_table(n // 3)
    first = np.empty(max(n, 1), np.int64)
    state = np.zeros(3, np.int64)
    while True:
        code = _merge_rows(vx, limbs, vid, vertices, pos, pos_bits, status, rows, points, first, state)
        if code == _GROW_FIRST:
            rows = _doubled(rows)
        elif code == _GROW_SECOND:
            points = _doubled(points)
        elif code == _DONE:
            return state[2]
        else:
            return -1


@jit
def _pairs_from(pc, vid, pair_of_edge, pair_planes, status, narrow, table, state):
    """Check and number edges from polygon ``state[0]`` on (state: next polygon, pairs); see the kernel."""
    pc = unmanaged_tuple(pc)
    vid, pair_of_edge, pair_planes, status = (
        unmanaged(vid),
        unmanaged(pair_of_edge),
        unmanaged(pair_planes),
        unmanaged(status),
    )
    table, state = unmanaged(table), unmanaged(state)
    m = pc.palette.shape[0]
    mask = table.shape[0] - 1
    count = state[1]
    for p in range(state[0], pc.polys.shape[0]):
        start = pc.polys[p, 0]
        size = pc.polys[p, 1]
        if 2 * (count + size) > table.shape[0]:  # a polygon adds at most one pair per edge
            state[0] = p
            state[1] = count
            return _GROW_FIRST
        s = pc.polys[p, 2]
        if s < 0:
            s = ~s
        for e in range(size):
            r = start + e
            nxt = start + (e + 1) % size
            t = pc.edge_plane[r]
            bad_row = -1
            bad_plane = -1
            if not on_plane(narrow, pc.vx, r, pc.palette, s):
                bad_row, bad_plane = r, s
            elif not on_plane(narrow, pc.vx, r, pc.palette, t):
                bad_row, bad_plane = r, t
            elif not on_plane(narrow, pc.vx, nxt, pc.palette, t):
                bad_row, bad_plane = nxt, t
            if bad_row >= 0:
                status[0] = E_OFF_PLANE
                status[1] = bad_row
                status[2] = bad_plane
                status[3] = p
                return _BAD
            if s == t:
                status[0] = E_NO_LINE
                status[1] = r
                status[2] = s
                status[3] = t
                return _BAD
            if vid[r] == vid[nxt]:
                status[0] = E_ZERO_EDGE
                status[1] = r
                status[2] = p
                return _BAD
            lo = min(s, t)
            hi = max(s, t)
            hk = _key(_mix(_SEED ^ np.uint64(lo * m + hi)))
            i = hk & mask
            while table[i, 0] >= 0:
                if table[i, 1] == hk:
                    q = table[i, 0]
                    if pair_planes[q, 0] == lo and pair_planes[q, 1] == hi:
                        break
                i = (i + 1) & mask
            if table[i, 0] < 0:
                table[i, 0] = count
                table[i, 1] = hk
                pair_planes[count, 0] = lo
                pair_planes[count, 1] = hi
                count += 1
            pair_of_edge[r] = table[i, 0]
    state[0] = pc.polys.shape[0]
    state[1] = count
    return _DONE


@jit
def edge_pairs_kernel(pc, vid, pair_of_edge, pair_planes, status, narrow):
    """Check every edge against its planes and number the distinct plane pairs; return their count (-1: bad input).

    ``pair_of_edge`` (n,) int64 receives each edge's pair, ``pair_planes`` ((n, 2) int64) the pairs
    (lower row first). Every vertex row is tested exactly on its polygon's support plane and on
    the edge planes of both edges at it (:func:`on_plane`; ``narrow`` from :func:`narrow_tests_exact`),
    so the lines built from the pairs really carry the vertices that are ordered along them.
    """
    table = _new_table(pc.vx.shape[0] // 5)  # ~1 distinct pair per 6 edges
    state = np.zeros(2, np.int64)
    while True:
        code = _pairs_from(pc, vid, pair_of_edge, pair_planes, status, narrow, table, state)
        if code == _GROW_FIRST:
            table = _doubled(table)
        elif code == _DONE:
            return state[1]
        else:
            return -1


@jit
def pair_lines_kernel(
    palette, pair_planes, axes, dirs, points, keys, key_bits, line_of_pair, line_planes, line_axis, status
):
    """Merge plane pairs that meet in the same line; return the number of lines (-1: bad input).

    For pair (s, t): u = n_s x n_t and k = argmax |u_k| (:func:`line_direction_into`, into
    ``dirs``), X = intersect(s, t, x_k = 0) (into ``points``; ``axes`` (3, 4) wide are the planes
    x_k = 0). The key (k; u_c / u_k and X_c / X_4 for c != k, correctly rounded into ``keys``,
    ``key_bits`` the same memory as int64) does not depend on which planes describe the line.

    Exactness at width w, **palette budget** (checked on entry): |u_c| <= 2 N^2 < 2^(w-1); X is a
    point of eq. 5 from palette planes and an axis plane (N >= 1, D unchanged), so its
    coordinates fit (3^(3/2) N^2 D, 3^(3/2) N^3); the confirmation tests X·s at 2w + 64 bits and
    det(n_s', n_t', n_s), an x4 of eq. 5 (< 2^(w-1)).

    Output: ``line_of_pair`` (p,), ``line_planes`` (p, 2) (the first pair of each line),
    ``line_axis`` (p,) k per line.
    """
    palette, pair_planes, axes, dirs, points = (
        unmanaged(palette),
        unmanaged(pair_planes),
        unmanaged(axes),
        unmanaged(dirs),
        unmanaged(points),
    )
    keys, key_bits, line_of_pair, line_planes = (
        unmanaged(keys),
        unmanaged(key_bits),
        unmanaged(line_of_pair),
        unmanaged(line_planes),
    )
    line_axis, status = unmanaged(line_axis), unmanaged(status)
    npairs = pair_planes.shape[0]
    mask = _table_mask(npairs)
    table = np.full(mask + 1, -1, np.int64)
    count = 0
    for q in range(npairs):
        s = pair_planes[q, 0]
        t = pair_planes[q, 1]
        k = line_direction_into(palette, s, t, dirs, count)
        if k < 0:
            status[0] = E_NO_LINE
            status[1] = q
            status[2] = s
            status[3] = t
            return -1
        intersect_into(palette, s, palette, t, axes, k, points, count)
        c2 = 0
        for c in range(3):
            if c != k:
                keys[count, c2] = ratio_to_double(dirs, np.int64(count), np.int64(c))
                keys[count, 2 + c2] = ratio_to_double(points, np.int64(count), np.int64(c))
                c2 += 1
        h = _mix(_SEED ^ np.uint64(k))
        for c in range(4):
            h = _mix(h ^ np.uint64(key_bits[count, c]))
        i = np.int64(h & np.uint64(mask))
        hit = -1
        while table[i] >= 0:
            g = table[i]
            if (
                line_axis[g] == k
                and key_bits[g, 0] == key_bits[count, 0]
                and key_bits[g, 1] == key_bits[count, 1]
                and key_bits[g, 2] == key_bits[count, 2]
                and key_bits[g, 3] == key_bits[count, 3]
            ):
                s2 = line_planes[g, 0]
                t2 = line_planes[g, 1]
                if (
                    on_plane_at(points, g, palette, s)
                    and on_plane_at(points, g, palette, t)
                    and normals_det_sign_at(palette, s2, t2, s) == 0
                    and normals_det_sign_at(palette, s2, t2, t) == 0
                ):
                    hit = g
                    break
            i = (i + 1) & mask
        if hit >= 0:
            line_of_pair[q] = hit
            continue
        table[i] = count
        line_planes[count, 0] = s
        line_planes[count, 1] = t
        line_axis[count] = k
        line_of_pair[q] = count
        count += 1
    return count


@jit(inline="always")
def _before(vertices, pos, v, w, k):
    """Whether point v comes before point w along axis k (doubles first; exact on a tie)."""
    a = pos[v, k]
    b = pos[w, k]
    if a != b:
        return a < b
    return compare_coordinate_at(vertices, v, vertices, w, k) < 0


@jit
def _entries_from(polys, vid, line_of_edge, npts, table, ent_line, ent_vert, edge_ent, state):
    """Number the distinct (line, point) entries of edge endpoints from polygon ``state[0]`` on (state: polygon, n)."""
    polys, vid, line_of_edge, table = unmanaged(polys), unmanaged(vid), unmanaged(line_of_edge), unmanaged(table)
    ent_line, ent_vert, edge_ent, state = (
        unmanaged(ent_line),
        unmanaged(ent_vert),
        unmanaged(edge_ent),
        unmanaged(state),
    )
    mask = table.shape[0] - 1
    ne = state[1]
    for p in range(state[0], polys.shape[0]):
        start = polys[p, 0]
        size = polys[p, 1]
        if 2 * (ne + 2 * size) > table.shape[0]:
            state[0] = p
            state[1] = ne
            return _GROW_FIRST
        for e in range(size):
            r = start + e
            g = line_of_edge[r]
            for side in range(2):
                v = vid[r] if side == 0 else vid[start + (e + 1) % size]
                hk = _key(_mix(_SEED ^ np.uint64(g * npts + v)))
                i = hk & mask
                while table[i, 0] >= 0 and not (
                    table[i, 1] == hk and ent_line[table[i, 0]] == g and ent_vert[table[i, 0]] == v
                ):
                    i = (i + 1) & mask
                if table[i, 0] < 0:
                    table[i, 0] = ne
                    table[i, 1] = hk
                    ent_line[ne] = g
                    ent_vert[ne] = v
                    ne += 1
                edge_ent[r, side] = table[i, 0]
    state[0] = polys.shape[0]
    state[1] = ne
    return _DONE


@jit
def _sort_lines(members, verts, first, line_axis, vertices, pos, scratch_keys, rank):
    """Sort every line's entries ``members[first[g]:first[g + 1]]`` exactly along its axis; write their ranks."""
    members, verts, first, line_axis = unmanaged(members), unmanaged(verts), unmanaged(first), unmanaged(line_axis)
    vertices, pos, scratch_keys, rank = unmanaged(vertices), unmanaged(pos), unmanaged(scratch_keys), unmanaged(rank)
    for g in range(line_axis.shape[0]):
        a = first[g]
        b = first[g + 1]
        k = line_axis[g]
        if b - a > _SMALL_GROUP:
            for i in range(a, b):
                scratch_keys[i - a] = pos[verts[members[i]], k]
            order = np.argsort(scratch_keys[: b - a], kind="mergesort")
            tmp = members[a:b].copy()
            for i in range(b - a):
                members[a + i] = tmp[order[i]]
        # Insertion: linear on the argsorted run (only ties of equal doubles move), exact throughout.
        for i in range(a + 1, b):
            e = members[i]
            j = i - 1
            while j >= a and _before(vertices, pos, verts[e], verts[members[j]], k):
                members[j + 1] = members[j]
                j -= 1
            members[j + 1] = e
        for i in range(a, b):
            rank[members[i]] = i - a


@jit
def _emit_loops(polys, vid, line_of_edge, edge_plane, edge_ent, rank, first, members, verts, offsets, indices, planes):
    """Write each polygon's loop: every edge's tail, then the vertices strictly between its endpoints."""
    polys, vid, line_of_edge, edge_plane = (
        unmanaged(polys),
        unmanaged(vid),
        unmanaged(line_of_edge),
        unmanaged(edge_plane),
    )
    edge_ent, rank, first, members, verts = (
        unmanaged(edge_ent),
        unmanaged(rank),
        unmanaged(first),
        unmanaged(members),
        unmanaged(verts),
    )
    offsets, indices, planes = unmanaged(offsets), unmanaged(indices), unmanaged(planes)
    out = 0
    for p in range(polys.shape[0]):
        offsets[p] = out
        start = polys[p, 0]
        for e in range(polys[p, 1]):
            r = start + e
            base = first[line_of_edge[r]]
            ra = rank[edge_ent[r, 0]]
            rb = rank[edge_ent[r, 1]]
            step = 1 if rb > ra else -1
            j = ra
            while j != rb:
                indices[out] = verts[members[base + j]]
                planes[out] = edge_plane[r]
                out += 1
                j += step
    offsets[polys.shape[0]] = out


@jit
def assemble_loops_kernel(polys, vid, line_of_edge, line_axis, vertices, pos, edge_plane):
    """Polygon loops with every vertex strictly inside an edge inserted; returns (offsets, indices, edge planes).

    ``polys`` (k, 5) int64 raw polygons; ``vid`` (n,) point of each vertex row; ``line_of_edge``
    (n,) line of the edge from each row to the next; ``line_axis`` (l,) the axis each line is
    ordered by; ``vertices`` (p, 4) wide and ``pos`` (p, 3) the points. The edges a polygon's
    new vertices split keep their edge plane.
    """
    n = vid.shape[0]
    nlines = line_axis.shape[0]
    # 1. (line, point) entries, one per distinct pair, and each edge's two entries.
    table = _new_table(n + n // 8)  # ~1 distinct entry per edge (an edge and its twin share two)
    ent_line = np.empty(2 * n, np.int64)
    ent_vert = np.empty(2 * n, np.int64)
    edge_ent = np.empty((n, 2), np.int64)
    state = np.zeros(2, np.int64)
    while (
        _entries_from(polys, vid, line_of_edge, vertices.shape[0], table, ent_line, ent_vert, edge_ent, state)
        == _GROW_FIRST
    ):
        table = _doubled(table)
    ne = state[1]
    # 2. Entries grouped by line (counting sort), each group sorted along its line.
    first = np.zeros(nlines + 1, np.int64)
    for e in range(ne):
        first[ent_line[e] + 1] += 1
    largest = 0
    for g in range(nlines):
        largest = max(largest, first[g + 1])
        first[g + 1] += first[g]
    cursor = first[:nlines].copy()
    members = np.empty(ne, np.int64)
    for e in range(ne):
        g = ent_line[e]
        members[cursor[g]] = e
        cursor[g] += 1
    rank = np.empty(ne, np.int64)
    _sort_lines(members, ent_vert, first, line_axis, vertices, pos, np.empty(largest, np.float64), rank)
    # 3. Loops.
    total = 0
    for r in range(n):
        total += abs(rank[edge_ent[r, 0]] - rank[edge_ent[r, 1]])
    offsets = np.empty(polys.shape[0] + 1, np.int64)
    indices = np.empty(total, np.int64)
    planes = np.empty(total, np.int64)
    _emit_loops(
        polys, vid, line_of_edge, edge_plane, edge_ent, rank, first, members, ent_vert, offsets, indices, planes
    )
    return offsets, indices, planes
