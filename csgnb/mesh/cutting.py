"""In-place exact cutting of a convex polytope by a plane: edge descent + marching (paper §3.3).

``cut`` splits the polytope of a cell handle into its negative and positive parts,
in place, each closed by a new face on the cutting plane (Figure 3):

1. *Edge descent* from the handle's vertex: move to the neighbour that is strictly
   closer to the plane (exact comparison of (x·s)/x4, :func:`compare_filtered_values_at`:
   the doubles the classification kept decide where they certainly can; a close call forms
   both dot products again and compares their products at twice the width)
   until a vertex on the far side of the plane is seen. A linear function on a convex
   polytope has no local minima, so a vertex without a closer neighbour is the global
   minimum: the plane then has no *proper* intersection (one part would have zero
   volume) and the polytope is left unchanged.
2. *Marching* around the cut from an on-plane vertex: at each on-plane vertex, the
   neighbours' signs form one negative and one non-negative block (convexity); the
   face between them is either split (Figure 4a: walk it to the far crossing, split
   that edge) by a diagonal on the plane, or bounded by an existing on-plane edge.
   This visits only the faces the plane crosses.
3. The loop of on-plane vertices is duplicated, half-edges on the positive side are
   re-attached to the copies, and two cap faces close both parts: the negative part's
   cap lies on the plane as given, the positive part's on its flip.

Only vertices next to the path are classified (cached per cut in ``vmark``), and new
vertices are built once per crossed edge by ``intersect_3_planes`` of the edge's two
faces and the cutting plane. The naive baseline (:func:`cut_naive`) classifies every
vertex first, then marches the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb._jit import borrowing_jit, jit
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.errors import GeometryError, InternalError
from csgnb.exact.intrinsics import compare_filtered_values_at, intersect_into, plane_value_filtered_into
from csgnb.mesh.halfedge import (
    FACE,
    HE,
    LOOP_C,
    LOOP_H,
    LOOP_M,
    LOOP_P,
    LOOP_V,
    N_CLASSIFY,
    N_CONSTRUCT,
    NEXT,
    NH,
    NP,
    NV,
    OPP,
    PLANE,
    STAMP,
    TWIN,
    VERT,
    MeshStore,
    _new_face,
    _new_halfedge,
    _new_stamp,
    _new_vertex,
    _rot,
    collect_cell_halfedges,
    face_plane_row,
    halfedge_dest,
)

__all__ = ["CutResult", "cut", "cut_cell", "cut_cell_inline", "cut_cell_naive", "CUT_PROPER", "CUT_ERROR"]

CUT_PROPER = 2
"""Status of a cut that split the polytope into two parts of non-zero volume."""

CUT_ERROR = -9
"""Status of a cut that found an inconsistent mesh (never expected; reported, not hidden)."""


# The per-vertex and per-edge helpers below are inlined at the numba IR level into the cut
# (a call that is not inlined reference-counts each array it is passed, which costs more than
# a classification). The cut itself is inlined only into :func:`cut_cell`, its one compiled copy, which every
# kernel that cuts calls -- the merge and extraction loops included: their call once cost ~10 % of a carving, but
# with the mesh arrays passed unmanaged (``borrowing_jit``) it measured within the noise (2026-12-03), while
# inlining it there re-typed and re-optimised two more copies (17 s of compilation). Inlining the loops into their
# callers too (the octree's per-cell steps) re-typed and re-optimised a copy of the cut per caller:
# minutes of compilation (issue 21). The naive baseline is a compiled function of its own.
# Callers pass int64 scalars (``np.int64``) so that one specialisation serves them all.
@jit(inline="always")
def _side(m, v, s):
    """Cached exact side (-1, 0, +1) of vertex ``v`` against palette plane ``s`` in this cut."""
    counts = m.counts
    stamp = counts[STAMP]
    mk = m.vmark[np.uint64(v)]  # unsigned row indices here and below: numba wraps a signed one around
    if (mk >> 2) == stamp:
        return (mk & 3) - 1
    side = np.int64(plane_value_filtered_into(m.vx, v, m.palette, s, m.vdf))
    m.vmark[np.uint64(v)] = stamp * 4 + side + 1
    counts[N_CLASSIFY] += 1
    return side


@jit(inline="always")
def _mark_on_plane(m, v):
    m.vmark[v] = m.counts[STAMP] * 4 + 1


@jit(inline="always")
def _record(path, v):
    if path[0] + 1 < path.shape[0]:
        path[0] += 1
        path[path[0]] = v


@jit(inline="always")
def _descend(m, h0, s, path):
    """Edge descent. Returns (kind, value):

    kind 1: ``value`` is a half-edge from a vertex strictly on one side to one strictly
    on the other (a crossing edge); kind 2: ``value`` is an outgoing half-edge of an
    on-plane vertex with neighbours on both sides; kind 0: no proper intersection,
    ``value`` is the side (+1/-1) the polytope lies on.
    """
    he = m.he
    v = np.int64(he[np.uint64(h0), VERT])
    hv = h0
    _record(path, v)
    sv = _side(m, v, s)
    if sv == 0:
        pos = False
        neg = False
        h = hv
        while True:
            su = _side(m, halfedge_dest(he, h), s)
            pos = pos or su > 0
            neg = neg or su < 0
            h = _rot(he, h)
            if h == hv:
                break
        if pos and neg:
            return 2, hv
        return 0, 1 if pos else -1
    sign0 = sv
    while True:
        best = -1
        best_side = 1
        h = hv
        while True:
            u = halfedge_dest(he, h)
            su = _side(m, u, s)
            if su == -sign0:
                if sv != 0:
                    return 1, h
                return 2, hv
            # Strictly closer to the plane: sign0 * (f(u) - f(v)) < 0. Both sides are known
            # here, so their doubles are kept in vdf; an on-plane u (f = 0) is the closest.
            if sv == 0:
                pass  # f(v) = 0 and no neighbour across: nothing is strictly closer
            elif su == 0:
                if best < 0 or best_side != 0:
                    best = h
                    best_side = 0
            elif best_side != 0 and sign0 * compare_filtered_values_at(m.vdf, u, v, m.vx, m.palette, s) < 0:
                if best < 0 or sign0 * compare_filtered_values_at(m.vdf, u, halfedge_dest(he, best), m.vx,
                                                                  m.palette, s) < 0:
                    best = h
            h = _rot(he, h)
            if h == hv:
                break
        if best < 0:
            # A global minimum of sign0 * f on the polytope, at distance >= 0.
            return 0, sign0
        v = halfedge_dest(he, best)
        hv = np.int64(he[np.uint64(best), TWIN])  # runs from the new v back: an outgoing half-edge of v
        _record(path, v)
        sv = _side(m, v, s)


@jit(inline="always")
def _split_edge(m, h, s):
    """Insert the crossing point of edge ``h`` with plane ``s``; return the new vertex.

    Afterwards ``h`` ends at the new vertex and ``he[h, NEXT]`` starts there; the
    twin edge is split the same way.
    """
    he = m.he
    fc = m.fc
    t = np.int64(he[h, TWIN])
    w = _new_vertex(m)
    intersect_into(m.palette, face_plane_row(fc, he[h, FACE]), m.palette, face_plane_row(fc, he[t, FACE]), m.palette, s,
                   m.vx, w)
    m.counts[N_CONSTRUCT] += 1
    _mark_on_plane(m, w)
    h2 = _new_halfedge(m)
    t2 = _new_halfedge(m)
    he[h2, NEXT] = he[h, NEXT]
    he[h2, TWIN] = t
    he[h2, VERT] = w
    he[h2, FACE] = he[h, FACE]
    he[t2, NEXT] = he[t, NEXT]
    he[t2, TWIN] = h
    he[t2, VERT] = w
    he[t2, FACE] = he[t, FACE]
    he[h, NEXT] = h2
    he[h, TWIN] = t2
    he[t, NEXT] = t2
    he[t, TWIN] = h2
    return w


@jit(inline="always")
def _march_and_separate(m, z0, hz0, s, opp_neg, opp_pos):
    """Marching and separation from on-plane vertex ``z0`` (outgoing half-edge ``hz0``).

    Returns (negative cap half-edge, positive cap half-edge), or (-1, -1) on an
    inconsistent mesh.
    """
    he = m.he
    fc = m.fc
    vx = m.vx
    loop = m.loop
    n = 0
    z = z0
    hz = hz0
    while True:
        # The transition, rotating around z, from a negative neighbour to a non-negative one.
        h = hz
        found = False
        for _ in range(he.shape[0]):
            if _side(m, halfedge_dest(he, h), s) < 0 and _side(m, halfedge_dest(he, _rot(he, h)), s) >= 0:
                found = True
                break
            h = _rot(he, h)
            if h == hz:
                break
        if not found:
            return -1, -1
        r = _rot(he, h)  # z -> b, in the face G between the two neighbours
        b = halfedge_dest(he, r)
        if _side(m, b, s) == 0:
            loop[n, LOOP_H] = r  # an on-plane edge already: no face to split (Figure 4, last sentence)
            znext = b
        else:
            # Walk G from b to its other on-plane point (Figure 4a: split an edge there).
            e = r
            while _side(m, halfedge_dest(he, e), s) > 0:
                e = np.int64(he[np.uint64(e), NEXT])
            if _side(m, halfedge_dest(he, e), s) < 0:
                _split_edge(m, e, s)
            w = halfedge_dest(he, e)
            g = np.int64(he[r, FACE])
            prev_r = np.int64(he[h, TWIN])
            d1 = _new_halfedge(m)
            d2 = _new_halfedge(m)
            g_plus = _new_face(m)
            he[d1, NEXT] = r
            he[d1, TWIN] = d2
            he[d1, VERT] = w
            he[d1, FACE] = g_plus
            he[d2, NEXT] = he[e, NEXT]
            he[d2, TWIN] = d1
            he[d2, VERT] = z
            he[d2, FACE] = g
            he[e, NEXT] = d1
            he[prev_r, NEXT] = d2
            k = r
            while k != d1:
                he[np.uint64(k), FACE] = g_plus
                k = np.int64(he[np.uint64(k), NEXT])
            fc[g_plus, PLANE] = fc[g, PLANE]
            fc[g_plus, HE] = r
            fc[g_plus, OPP] = fc[g, OPP]
            fc[g, HE] = d2
            loop[n, LOOP_H] = d2
            znext = w
        loop[n, LOOP_V] = z
        n += 1
        if znext == z0:
            break
        if n >= loop.shape[0]:
            return -1, -1
        z = znext
        hz = np.int64(he[loop[n - 1, LOOP_H], TWIN])
    # Separation: copy the loop vertices for the positive part and re-attach its half-edges.
    for i in range(n):
        zc = _new_vertex(m)
        loop[i, LOOP_C] = zc
        zi = loop[i, LOOP_V]
        for c in range(4):
            vx[zc, c] = vx[zi, c]
        _mark_on_plane(m, zc)
    for i in range(n):
        stop = he[loop[i - 1 if i > 0 else n - 1, LOOP_H], TWIN]
        h = _rot(he, loop[i, LOOP_H])
        zc = loop[i, LOOP_C]
        while True:
            he[np.uint64(h), VERT] = zc
            if h == stop:
                break
            h = _rot(he, h)
    # Two caps: M_i (negative part, z_{i+1} -> z_i) and P_i (positive part, z_i' -> z_{i+1}').
    for i in range(n):
        loop[i, LOOP_M] = _new_halfedge(m)
        loop[i, LOOP_P] = _new_halfedge(m)
    f_neg = _new_face(m)
    f_pos = _new_face(m)
    for i in range(n):
        ell = loop[i, LOOP_H]
        t = np.int64(he[ell, TWIN])
        nxt = i + 1 if i + 1 < n else 0
        prv = i - 1 if i > 0 else n - 1
        mi = loop[i, LOOP_M]
        p = loop[i, LOOP_P]
        he[mi, NEXT] = loop[prv, LOOP_M]
        he[mi, TWIN] = ell
        he[mi, VERT] = loop[nxt, LOOP_V]
        he[mi, FACE] = f_neg
        he[p, NEXT] = loop[nxt, LOOP_P]
        he[p, TWIN] = t
        he[p, VERT] = loop[i, LOOP_C]
        he[p, FACE] = f_pos
        he[ell, TWIN] = mi
        he[t, TWIN] = p
    fc[f_neg, PLANE] = s
    fc[f_neg, HE] = loop[0, LOOP_M]
    fc[f_neg, OPP] = opp_neg
    fc[f_pos, PLANE] = ~s
    fc[f_pos, HE] = loop[0, LOOP_P]
    fc[f_pos, OPP] = opp_pos
    return loop[0, LOOP_M], loop[0, LOOP_P]


@borrowing_jit
def _march_and_separate_call(m, z0, hz0, s, opp_neg, opp_pos):
    """:func:`_march_and_separate`, compiled once for the naive baseline (not a hot path)."""
    return _march_and_separate(m, z0, hz0, s, opp_neg, opp_pos)


@jit(inline="always")
def cut_cell_inline(m, h0, s, opp_neg, opp_pos, path):
    """Cut the polytope of ``h0`` by palette plane ``s`` (edge descent + marching), in place.

    Returns (status, a, b): status CUT_PROPER with the negative and positive parts'
    handles a, b; status 0 with a = the side (+1/-1) when the plane does not cut
    properly (mesh unchanged); CUT_ERROR on an inconsistent mesh. The caller must have
    checked :func:`~csgnb.mesh.halfedge.room_for_cut` for the polytope's face count.
    ``path`` records the descent's vertices when longer than 1 (``path[0]`` = count).
    :func:`cut_cell` is its compiled entry (see above); ``bench_cutting.py`` times this inlined form.
    """
    _new_stamp(m.counts)
    kind, value = _descend(m, h0, s, path)
    if kind == 0:
        return 0, value, -1
    if kind == 1:
        z0 = _split_edge(m, value, s)
        hz = np.int64(m.he[value, NEXT])
    else:
        z0 = np.int64(m.he[value, VERT])
        hz = value
    a, b = _march_and_separate(m, z0, hz, s, opp_neg, opp_pos)
    if a < 0:
        return CUT_ERROR, -1, -1
    return CUT_PROPER, a, b


@borrowing_jit
def cut_cell(m, h0, s, opp_neg, opp_pos, path):
    """:func:`cut_cell_inline` as a compiled function: one copy that every caller calls, the merge and extraction
    loops included (inlined there, each re-typed and re-optimised its own copy -- 17 s of compilation -- for no
    measurable speed; ``bench_cutting.py`` still times the inlined form)."""
    return cut_cell_inline(m, h0, s, opp_neg, opp_pos, path)


@borrowing_jit
def cut_cell_naive(m, work, h0, s, opp_neg, opp_pos):
    """The baseline: classify every vertex of the polytope, then march as :func:`cut_cell`.

    ``work`` (int32) holds at least the polytope's half-edges.
    """
    he = m.he
    nh = collect_cell_halfedges(he, m.hmark, m.counts, h0, work)
    _new_stamp(m.counts)
    pos = False
    neg = False
    zero_h = -1
    cross_h = -1
    for i in range(nh):
        h = np.int64(work[i])
        sv = _side(m, np.int64(he[h, VERT]), s)
        pos = pos or sv > 0
        neg = neg or sv < 0
        if sv == 0:
            zero_h = h
        elif sv > 0 and cross_h < 0:
            if _side(m, halfedge_dest(he, h), s) < 0:
                cross_h = h
    if not (pos and neg):
        return 0, 1 if pos else -1, -1
    if zero_h >= 0:
        z0 = np.int64(he[zero_h, VERT])
        hz = zero_h
    else:
        z0 = _split_edge(m, cross_h, s)
        hz = np.int64(he[cross_h, NEXT])
    a, b = _march_and_separate_call(m, z0, hz, s, opp_neg, opp_pos)
    if a < 0:
        return CUT_ERROR, -1, -1
    return CUT_PROPER, a, b


@jit
def _cut_kernel(m, h0, s, opp_neg, opp_pos, path):
    return cut_cell(unmanaged_tuple(m), h0, s, opp_neg, opp_pos, unmanaged(path))


@jit
def _cut_naive_kernel(m, work, h0, s, opp_neg, opp_pos):
    return cut_cell_naive(unmanaged_tuple(m), unmanaged(work), h0, s, opp_neg, opp_pos)


@dataclass(frozen=True)
class CutResult:
    """Outcome of :func:`cut`.

    ``proper`` is True when both parts have non-zero volume; then ``negative`` and
    ``positive`` are the parts' cell handles (each a half-edge of its cap face on the
    cutting plane). Otherwise the polytope is unchanged, ``side`` says on which side
    of the plane it lies (+1/-1), and the whole polytope's handle is returned as the
    part of that side.

    ``classifications`` and ``constructions`` count exact vertex classifications and
    new vertices built; ``descent`` lists the vertex rows edge descent visited and
    ``classified`` every vertex row classified during this cut (for pictures).
    """

    proper: bool
    negative: int
    positive: int
    side: int
    classifications: int
    constructions: int
    descent: tuple[int, ...] = ()
    classified: tuple[int, ...] = ()


def _count_faces(store: MeshStore, cell: int) -> int:
    return len({int(store.he[h, FACE]) for h in store.cell_halfedges(cell)})


def cut(store: MeshStore, cell: int, plane: int, *, opp_negative: int = -1, opp_positive: int = -1,
        naive: bool = False) -> CutResult:
    """Cut the polytope ``cell`` of ``store`` by palette plane ``plane``, in place.

    Parameters
    ----------
    store : MeshStore
    cell : int
        Any half-edge of the polytope; descent starts at its origin vertex.
    plane : int
        Palette row of the cutting plane (add planes with :meth:`MeshStore.add_planes`).
    opp_negative, opp_positive : int
        ``OPP`` annotations of the two new cap faces (the BSP node on the other side).
    naive : bool
        Use the classify-every-vertex baseline instead of edge descent.

    Returns
    -------
    CutResult
    """
    n_planes = int(store.counts[NP])
    if not 0 <= plane < n_planes:
        raise GeometryError(f"plane {plane} is not a palette row (the palette has {n_planes} planes)")
    if not 0 <= cell < int(store.counts[NH]):
        raise GeometryError(f"cell {cell} is not a half-edge of the store")
    faces = _count_faces(store, cell) + 2
    store.reserve(2 * faces, 6 * faces + 2, faces + 2, loop=faces)
    path = np.zeros(int(store.counts[NV]) + 2, np.int64)
    before = store.counts[[N_CLASSIFY, N_CONSTRUCT]].copy()
    nv_before = int(store.counts[NV])
    if naive:
        work = np.empty(store.he.shape[0], np.int32)
        status, a, b = _cut_naive_kernel(store.m, work, cell, plane, opp_negative, opp_positive)
    else:
        status, a, b = _cut_kernel(store.m, cell, plane, opp_negative, opp_positive, path)
    n_cls, n_con = (int(x) for x in store.counts[[N_CLASSIFY, N_CONSTRUCT]] - before)
    if status == CUT_ERROR:
        raise InternalError("cutting found an inconsistent half-edge mesh (a bug in csgnb: please report it)")
    classified = tuple(int(v) for v in np.flatnonzero((store.vmark[:nv_before] >> 2) == store.counts[STAMP]))
    descent = tuple(int(v) for v in path[1 : 1 + path[0]])
    if status == CUT_PROPER:
        return CutResult(True, int(a), int(b), 0, n_cls, n_con, descent, classified)
    side = int(a)
    return CutResult(False, cell if side < 0 else -1, cell if side > 0 else -1, side, n_cls, n_con, descent,
                     classified)
