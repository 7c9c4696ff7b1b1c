"""Exact boundary extraction of a BSP inside a box (paper §3.4, Figures 5-6).

Two kernels, each resumable so that the Python wrapper can grow the arrays they
fill and call again without losing work:

1. :func:`_cells_kernel` -- convex cells of the **in** leaves: start from the box and
   cut by every inner node's plane (in place, :mod:`csgnb.mesh.cutting`). Each new cap
   face is annotated with the node on the other side of its cutting plane (``OPP``).
2. :func:`_boundary_kernel` -- each face of an in-cell is clipped against its opposite
   subtree (convex polygon against plane, exact); pieces reaching a leaf of another
   label are boundary (in-out, or between materials), the rest are interior and dropped.

The T-junction pass (:mod:`csgnb.bsp.surface`) then splits boundary edges at the
vertices other polygons have on them, so the surface is closed and conforming.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb._jit import jit
from csgnb.bsp.surface import BoundarySurface, assemble_surface
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import InternalError
from csgnb.exact.intrinsics import classify_at, intersect_into
from csgnb.mesh.cutting import (
    CUT_PROPER,
    FACES_PER_FACE,
    HALFEDGES_PER_FACE,
    VERTICES_PER_FACE,
    _cut_kernel,
    _cut_naive_kernel,
    _room_for_cut,
)
from csgnb.mesh.halfedge import FACE, HE, NEXT, OPP, PLANE, TWIN, VERT, MeshStore, _dest, _plane_row

__all__ = ["Extraction", "boundary_pieces", "extract_boundary", "extract_cells"]

_NEED_MORE_ROOM, _DONE, _FAILED = 1, 0, -1
# Cell-stack columns.
_NODE, _HANDLE, _FACE_BOUND = 0, 1, 2


@jit
def _cells_kernel(palette, vx, he, fc, vmark, vdot, hmark, counts, loop_v, loop_h, plane, neg, pos, label, stack, state,
                  cells, naive):
    """Cut the box cell down the tree; record (leaf, handle) of every **in** leaf reached.

    ``stack`` rows are (node, cell handle, bound on the cell's face count); ``state`` is
    (stack size, cells recorded). Returns 0 when done, 1 when an array is too small
    (nothing of the pending step done; grow and call again), -1 on an inconsistent mesh.
    ``naive`` uses the classify-every-vertex cut (the baseline of Figure 9).
    """
    no_path = np.zeros(1, np.int64)
    work = np.empty(he.shape[0] if naive else 1, np.int32)
    while state[0] > 0:
        top = state[0] - 1
        node = stack[top, _NODE]
        h = stack[top, _HANDLE]
        bound = stack[top, _FACE_BOUND]
        if plane[node] < 0:
            if label[node] != OUT:
                if state[1] >= cells.shape[0]:
                    return _NEED_MORE_ROOM
                cells[state[1], 0] = node
                cells[state[1], 1] = h
                state[1] += 1
            state[0] = top
            continue
        if not _room_for_cut(counts, vx, he, fc, loop_v, bound) or top + 2 > stack.shape[0]:
            return _NEED_MORE_ROOM
        # The caps face the other child: the negative part's cap looks into pos[node].
        if naive:
            if work.shape[0] < he.shape[0]:
                return _NEED_MORE_ROOM  # the caller grew the store: restart to size the work array
            status, a, b = _cut_naive_kernel(palette, vx, he, fc, vmark, vdot, hmark, counts, loop_v, loop_h, work, h,
                                             plane[node], pos[node], neg[node])
        else:
            status, a, b = _cut_kernel(palette, vx, he, fc, vmark, vdot, counts, loop_v, loop_h, h, plane[node],
                                       pos[node], neg[node], no_path)
        if status == CUT_PROPER:
            stack[top, _NODE] = pos[node]
            stack[top, _HANDLE] = b
            stack[top, _FACE_BOUND] = bound + 1
            stack[top + 1, _NODE] = neg[node]
            stack[top + 1, _HANDLE] = a
            stack[top + 1, _FACE_BOUND] = bound + 1
            state[0] = top + 2
        elif status == 0:
            stack[top, _NODE] = neg[node] if a < 0 else pos[node]
        else:
            return _FAILED
    return _DONE


@jit
def _emit(out_vx, out_vert, out_edge, out_poly, counts, src, rows, edges, n, support, lab, face):
    """Append one polygon (vertex ``rows`` of ``src``, edge planes) to the output; False if full."""
    nv = counts[0]
    npoly = counts[1]
    if nv + n > out_vx.shape[0] or npoly >= out_poly.shape[0]:
        return False
    for i in range(n):
        for c in range(4):
            out_vx[nv + i, c] = src[rows[i], c]
        out_vert[nv + i] = nv + i
        out_edge[nv + i] = edges[i]
    out_poly[npoly, 0] = nv
    out_poly[npoly, 1] = n
    out_poly[npoly, 2] = support
    out_poly[npoly, 3] = lab
    out_poly[npoly, 4] = face
    counts[0] = nv + n
    counts[1] = npoly + 1
    return True


@jit
def _boundary_kernel(palette, vx, he, fc, plane, neg, pos, label, faces, face_label, state,
                     pool, arena_v, arena_e, pieces, out_vx, out_vert, out_edge, out_poly, out_counts):
    """Clip every in-cell face (``faces``, labels ``face_label``) against its opposite subtree.

    Boundary pieces are appended to ``out_*`` (vertices copied exactly; per polygon
    ``out_poly`` = (first vertex, vertex count, signed support plane, label, face)).
    ``state[0]`` is the next face to do. Returns 0 when done, 1 when a scratch or output
    array is too small for the current face (its output is rolled back; grow and call again).
    """
    rows = np.empty(arena_v.shape[0], np.int64)
    edges = np.empty(arena_v.shape[0], np.int64)
    while state[0] < faces.shape[0]:
        f = faces[state[0]]
        lab = face_label[state[0]]
        mark_v = out_counts[0]
        mark_p = out_counts[1]
        support = fc[f, PLANE]
        # The face as a vertex cycle; edge i runs from vertex i to i + 1 on the twin face's plane.
        k = 0
        g = fc[f, HE]
        while True:
            if k >= rows.shape[0]:
                return _NEED_MORE_ROOM
            rows[k] = he[g, VERT]
            edges[k] = _plane_row(fc, he[he[g, TWIN], FACE])
            k += 1
            g = he[g, NEXT]
            if g == fc[f, HE]:
                break
        o = fc[f, OPP]
        if o < 0 or plane[o] < 0:
            other = OUT if o < 0 else label[o]
            if other != lab and not _emit(out_vx, out_vert, out_edge, out_poly, out_counts, vx, rows, edges, k,
                                          support, lab, f):
                return _NEED_MORE_ROOM
            state[0] += 1
            continue
        # A vertex of the cell strictly behind the face (adjacent faces are never coplanar),
        # to route pieces lying in a node's plane to the side the face looks at.
        g0 = fc[f, HE]
        behind = _dest(he, he[he[g0, TWIN], NEXT])
        if k > pool.shape[0] or k > arena_v.shape[0]:
            return _NEED_MORE_ROOM
        for i in range(k):
            for c in range(4):
                pool[i, c] = vx[rows[i], c]
            arena_v[i] = i
            arena_e[i] = edges[i]
        n_pool = k
        n_arena = k
        pieces[0, 0] = 0
        pieces[0, 1] = k
        pieces[0, 2] = o
        n_pieces = 1
        ok = True
        while n_pieces > 0 and ok:
            n_pieces -= 1
            start = pieces[n_pieces, 0]
            m = pieces[n_pieces, 1]
            node = pieces[n_pieces, 2]
            if plane[node] < 0:
                if label[node] != lab:
                    for i in range(m):
                        rows[i] = arena_v[start + i]
                        edges[i] = arena_e[start + i]
                    if not _emit(out_vx, out_vert, out_edge, out_poly, out_counts, pool, rows, edges, m,
                                 support, lab, f):
                        ok = False
                continue
            s = plane[node]
            any_neg = False
            any_pos = False
            for i in range(m):
                side = classify_at(pool, arena_v[start + i], palette, s)
                rows[i] = side
                any_neg = any_neg or side < 0
                any_pos = any_pos or side > 0
            if not (any_neg and any_pos):
                if any_neg:
                    child = neg[node]
                elif any_pos:
                    child = pos[node]
                else:  # the piece lies in the node's plane: continue on the side the face looks at
                    child = neg[node] if classify_at(vx, behind, palette, s) > 0 else pos[node]
                pieces[n_pieces, 2] = child
                n_pieces += 1
                continue
            # A proper split: each part has at most m + 1 vertices, one new vertex per crossing.
            if (n_arena + 2 * m + 4 > arena_v.shape[0] or n_pool + 2 > pool.shape[0]
                    or n_pieces + 2 > pieces.shape[0]):
                ok = False
                break
            neg_start = n_arena
            nn = 0
            pos_start = n_arena + m + 2
            npp = 0
            for i in range(m):
                j = i + 1 if i + 1 < m else 0
                si = rows[i]
                sj = rows[j]
                v = arena_v[start + i]
                e = arena_e[start + i]
                # Each part keeps its own vertices; the edge leaving an on-plane vertex
                # towards the other side becomes an edge along the cut plane.
                if si <= 0:
                    arena_v[neg_start + nn] = v
                    arena_e[neg_start + nn] = s if (si == 0 and sj > 0) else e
                    nn += 1
                if si >= 0:
                    arena_v[pos_start + npp] = v
                    arena_e[pos_start + npp] = s if (si == 0 and sj < 0) else e
                    npp += 1
                if si * sj < 0:
                    c = n_pool
                    n_pool += 1
                    intersect_into(palette, _plane_row(fc, f), palette, e, palette, s, pool, c)
                    # The part being left continues along the cut; the part being entered along e.
                    arena_v[neg_start + nn] = c
                    arena_e[neg_start + nn] = s if si < 0 else e
                    nn += 1
                    arena_v[pos_start + npp] = c
                    arena_e[pos_start + npp] = s if si > 0 else e
                    npp += 1
            n_arena = pos_start + npp
            pieces[n_pieces, 0] = neg_start
            pieces[n_pieces, 1] = nn
            pieces[n_pieces, 2] = neg[node]
            pieces[n_pieces + 1, 0] = pos_start
            pieces[n_pieces + 1, 1] = npp
            pieces[n_pieces + 1, 2] = pos[node]
            n_pieces += 2
            if n_pool + 2 > pool.shape[0]:
                ok = False
        if not ok:
            out_counts[0] = mark_v
            out_counts[1] = mark_p
            return _NEED_MORE_ROOM
        state[0] += 1
    return _DONE


@dataclass
class Extraction:
    """Everything boundary extraction computed.

    Attributes
    ----------
    store : MeshStore
        The cut polytopes; ``cells`` name the **in** leaves' convex cells in it.
    cells : (k, 2) int64
        (leaf node, cell handle) per in-cell.
    surface : BoundarySurface
        The exact, closed, conforming boundary polygons.
    """

    tree: BSPTree
    store: MeshStore
    cells: np.ndarray
    surface: BoundarySurface

    @property
    def cell_labels(self) -> np.ndarray:
        """Label of each in-cell, ``(k,) int32``."""
        return self.tree.label[self.cells[:, 0]]


def _grow(arr: np.ndarray, fill: int = 0) -> np.ndarray:
    out = np.full((2 * arr.shape[0],) + arr.shape[1:], fill, arr.dtype)
    out[: arr.shape[0]] = arr
    return out


def _room_for_next_cut(store: MeshStore, stack: np.ndarray, bound_column: int, top: int, loop_v: np.ndarray,
                       loop_h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grow what a resumable cutting kernel ran short of before cutting the cell on ``stack[top]``.

    Returns (stack, loop_v, loop_h), each the old array or a larger one.
    """
    bound = int(stack[top, bound_column]) + 2
    store.reserve(VERTICES_PER_FACE * bound, HALFEDGES_PER_FACE * bound + 2, FACES_PER_FACE * bound + 2)
    if top + 2 > stack.shape[0]:
        stack = _grow(stack)
    if bound > loop_v.shape[0]:
        loop_v = np.empty(2 * bound, np.int64)
        loop_h = np.empty(2 * bound, np.int64)
    return stack, loop_v, loop_h


def extract_cells(tree: BSPTree, lo, hi, *, capacity: int = 1024, naive: bool = False
                  ) -> tuple[MeshStore, np.ndarray]:
    """Return the convex cells of the **in** leaves of ``tree`` inside the box ``[lo, hi]``.

    ``naive=True`` cuts with the classify-every-vertex baseline instead of edge descent.

    Returns (store, cells): ``cells`` is ``(k, 2) int64`` rows of (leaf node, cell
    handle into ``store``). Out leaves are dropped; cells of zero volume never occur
    (cuts without a proper intersection send the whole cell to one side).
    """
    store = MeshStore(tree.palette, capacity=capacity)
    box = store.add_box(lo, hi)
    stack = np.zeros((64, 3), np.int64)
    stack[0] = (0, box, 6)
    state = np.array([1, 0], np.int64)
    cells = np.zeros((16, 2), np.int64)
    loop_v = np.empty(64, np.int64)
    loop_h = np.empty(64, np.int64)
    while True:
        status = _cells_kernel(store.palette, store.vx, store.he, store.fc, store.vmark, store.vdot, store.hmark,
                               store.counts, loop_v, loop_h, tree.plane, tree.neg, tree.pos, tree.label, stack, state,
                               cells, naive)
        if status == _DONE:
            return store, cells[: state[1]]
        if status == _FAILED:
            raise InternalError("cutting found an inconsistent half-edge mesh during extraction"
                                " (a bug in csgnb: please report it)")
        stack, loop_v, loop_h = _room_for_next_cut(store, stack, _FACE_BOUND, int(state[0]) - 1, loop_v, loop_h)
        if state[1] >= cells.shape[0]:
            cells = _grow(cells)


def boundary_pieces(tree: BSPTree, store: MeshStore, cells: np.ndarray):
    """Clip the faces of the in-cells ``cells`` (rows (leaf, handle)) against their opposite subtrees.

    Returns the raw boundary pieces (palette, vertices, edge planes, polygons) that
    :func:`~csgnb.bsp.surface.assemble_surface` merges; see :func:`_boundary_kernel`.
    """
    faces, face_label = [], []
    for node, handle in cells:
        if tree.label[node] == OUT:
            continue
        hs = store.cell_halfedges(int(handle))
        fids = np.unique(store.he[hs, FACE])
        faces.append(fids)
        face_label.append(np.full(fids.shape[0], tree.label[node], np.int64))
    faces = np.concatenate(faces).astype(np.int64) if faces else np.zeros(0, np.int64)
    face_label = np.concatenate(face_label) if face_label else np.zeros(0, np.int64)
    n_guess = max(64, 8 * faces.shape[0])
    pool = np.zeros((64, 4), store.vx.dtype)
    arena_v = np.zeros(256, np.int64)
    arena_e = np.zeros(256, np.int64)
    pieces = np.zeros((64, 3), np.int64)
    out_vx = np.zeros((n_guess, 4), store.vx.dtype)
    out_vert = np.zeros(n_guess, np.int64)
    out_edge = np.zeros(n_guess, np.int64)
    out_poly = np.zeros((max(16, 2 * faces.shape[0]), 5), np.int64)
    out_counts = np.zeros(2, np.int64)
    state = np.zeros(1, np.int64)
    while True:
        status = _boundary_kernel(store.palette, store.vx, store.he, store.fc, tree.plane, tree.neg, tree.pos,
                                  tree.label, faces, face_label, state, pool, arena_v, arena_e, pieces,
                                  out_vx, out_vert, out_edge, out_poly, out_counts)
        if status == _DONE:
            break
        # Grow everything that could have been short; rare, and the face is redone.
        pool, arena_v, arena_e, pieces = _grow(pool), _grow(arena_v), _grow(arena_e), _grow(pieces)
        if out_counts[0] + 4 * arena_v.shape[0] > out_vx.shape[0]:
            out_vx, out_vert, out_edge = _grow(out_vx), _grow(out_vert), _grow(out_edge)
        if out_counts[1] + pieces.shape[0] >= out_poly.shape[0]:
            out_poly = _grow(out_poly)
    nv, npoly = (int(c) for c in out_counts)
    return store.planes.copy(), out_vx[:nv], out_edge[:nv], out_poly[:npoly]


def extract_boundary(tree: BSPTree, lo, hi) -> Extraction:
    """Return the exact boundary of the solid ``tree`` represents inside the box ``[lo, hi]``.

    Parameters
    ----------
    tree : BSPTree
    lo, hi : (3,) int
        Integer box corners; the box planes join the palette, so they must fit the
        tree's bit budget. Space outside the box counts as **out**.

    Returns
    -------
    Extraction
        The cells, and ``surface``: closed, conforming, exact polygons (see
        :class:`~csgnb.bsp.surface.BoundarySurface`), ``surface.to_polydata()`` for display.
    """
    store, cells = extract_cells(tree, lo, hi)
    surface = assemble_surface(*boundary_pieces(tree, store, cells))
    return Extraction(tree, store, cells, surface)
