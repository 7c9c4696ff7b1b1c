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
from typing import NamedTuple

import numpy as np

from csgnb._jit import borrowing_jit, jit
from csgnb._resumable import DONE, FAILED, NEED_ROOM, grown, run_resumable
from csgnb._unlinked import unlinked
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.bsp.build import check_count
from csgnb.bsp.surface import BoundarySurface, assemble_surface
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.integral import integer_array
from csgnb.exact.intrinsics import classify_at, intersect_into
from csgnb.mesh.cutting import CUT_PROPER, cut_cell, cut_cell_naive
from csgnb.mesh.halfedge import (
    FACE,
    HE,
    NEXT,
    OPP,
    PLANE,
    TWIN,
    VERT,
    MeshStore,
    collect_cell_halfedges,
    face_plane_row,
    grown_mesh_arrays,
    halfedge_dest,
    release_cell,
    room_for_cut,
)

__all__ = ["ClipScratch", "Extraction", "Pieces", "TreeArrays", "boundary_pieces", "check_box", "check_corner",
           "check_tree", "extract_boundary", "extract_cells"]

# Cell-stack columns.
_NODE, _HANDLE, _FACE_BOUND = 0, 1, 2
# Extraction modes (bits).
KEEP_CELLS, PIECES, WALLS, NAIVE = 1, 2, 4, 8


class TreeArrays(NamedTuple):
    """The node arrays of a BSP (``(n,) int32`` each; see :mod:`csgnb.bsp.tree`), as one kernel argument."""

    plane: np.ndarray
    neg: np.ndarray
    pos: np.ndarray
    label: np.ndarray


def tree_arrays(tree: BSPTree) -> TreeArrays:
    """The :class:`TreeArrays` of a :class:`BSPTree`."""
    return TreeArrays(tree.plane, tree.neg, tree.pos, tree.label)


class Pieces(NamedTuple):
    """Raw boundary pieces: every polygon with its own exact vertex copies (output of the clipping kernels).

    vx : (n, 4) wide -- vertices, polygon after polygon;
    edge : (n,) int64 -- palette row of the plane the edge from each vertex to the next lies on;
    poly : (k, 5) int64 -- per polygon: first vertex row, vertex count, signed support row, label, source face;
    counts : (2,) int64 -- vertex rows and polygons in use.
    """

    vx: np.ndarray
    edge: np.ndarray
    poly: np.ndarray
    counts: np.ndarray


def new_pieces(dtype, vertices: int = 256, polygons: int = 64) -> Pieces:
    """Empty :class:`Pieces` with room for ``vertices`` vertex rows and ``polygons`` polygons."""
    return Pieces(np.empty((vertices, 4), dtype), np.empty(vertices, np.int64), np.empty((polygons, 5), np.int64),
                  np.zeros(2, np.int64))


def grown_pieces(p: Pieces, vertices: int = 0, polygons: int = 0) -> Pieces:
    """``p`` with room for at least this many more vertex rows and polygons (geometric growth)."""
    vx, edge, poly = p.vx, p.edge, p.poly
    if p.counts[0] + vertices > vx.shape[0]:
        size = int(p.counts[0]) + vertices
        vx, edge = grown(vx, size), grown(edge, size)
    if p.counts[1] + polygons > poly.shape[0]:
        poly = grown(poly, int(p.counts[1]) + polygons)
    return Pieces(vx, edge, poly, p.counts)


class ClipScratch(NamedTuple):
    """Scratch of the face-clipping kernel (all grown on demand).

    pool : (p, 4) wide -- vertices of the pieces of one face;
    arena_v, arena_e : (a,) int64 -- pieces as runs of (pool row, edge plane);
    stack : (q, 3) int64 -- pieces still to push down the tree: (start, size, node);
    rows, edges : (r,) int64 -- one face's vertex rows and edge planes;
    work : (w,) int32 -- the half-edges of one cell.
    """

    pool: np.ndarray
    arena_v: np.ndarray
    arena_e: np.ndarray
    stack: np.ndarray
    rows: np.ndarray
    edges: np.ndarray
    work: np.ndarray


def new_clip_scratch(dtype) -> ClipScratch:
    """Initial :class:`ClipScratch` (grown by :func:`grown_clip_scratch` when a kernel runs short).

    Sized for the cells of an octree workpiece at its default threshold (~200 kB at 256 bits): a drill sweep's
    union of prisms grew a 16× smaller scratch four times, and an octree grows it together with the boundary
    pieces (the kernel does not say which array was short), ~20 MB of copies per scratch workpiece.
    """
    return ClipScratch(np.empty((1024, 4), dtype), np.empty(4096, np.int64), np.empty(4096, np.int64),
                       np.empty((1024, 3), np.int64), np.empty(1024, np.int64), np.empty(1024, np.int64),
                       np.empty(4096, np.int32))


def grown_clip_scratch(s: ClipScratch) -> ClipScratch:
    """Every array of ``s`` twice as large (rare: it only happens for unusually complex cells)."""
    return ClipScratch(*(grown(a) for a in s))


# ---------------------------------------------------------------------------
# clipping faces against their opposite subtree (Figure 6)


@jit(inline="always")
def _emit(out, src, rows, edges, n, support, lab, face):
    """Append one polygon (vertex ``rows`` of ``src``, edge planes) to ``out``; False if full."""
    c = out.counts
    nv = c[0]
    npoly = c[1]
    if nv + n > out.vx.shape[0] or npoly >= out.poly.shape[0]:
        return False
    for i in range(n):
        for k in range(4):
            out.vx[nv + i, k] = src[rows[i], k]
        out.edge[nv + i] = edges[i]
    out.poly[npoly, 0] = nv
    out.poly[npoly, 1] = n
    out.poly[npoly, 2] = support
    out.poly[npoly, 3] = lab
    out.poly[npoly, 4] = face
    c[0] = nv + n
    c[1] = npoly + 1
    return True


@jit(inline="always")
def clip_face(m, f, lab, tree, sc, out):
    """Clip face ``f`` (of a cell labelled ``lab``) against the subtree behind it; append the boundary pieces.

    Pieces reaching a leaf of another label are boundary (in-out, or between materials)
    and are appended to ``out``; the rest are interior. Returns False when a scratch or
    output array is too small (the caller rolls ``out`` back and grows).
    """
    he = m.he
    fc = m.fc
    vx = m.vx
    palette = m.palette
    rows = sc.rows
    edges = sc.edges
    pool = sc.pool
    arena_v = sc.arena_v
    arena_e = sc.arena_e
    pieces = sc.stack
    support = fc[f, PLANE]
    # The face as a vertex cycle; edge i runs from vertex i to i + 1 on the twin face's plane.
    k = 0
    g = np.int64(fc[f, HE])
    while True:
        if k >= rows.shape[0]:
            return False
        # unsigned row indices: numba wraps a signed one around on every step of the walk
        rows[k] = he[np.uint64(g), VERT]
        edges[k] = face_plane_row(fc, he[np.uint64(he[np.uint64(g), TWIN]), FACE])
        k += 1
        g = np.int64(he[np.uint64(g), NEXT])
        if g == fc[f, HE]:
            break
    o = fc[f, OPP]
    if o < 0 or tree.plane[o] < 0:
        other = OUT if o < 0 else tree.label[o]
        if other != lab:
            return _emit(out, vx, rows, edges, k, support, lab, f)
        return True
    # A vertex of the cell strictly behind the face (adjacent faces are never coplanar),
    # to route pieces lying in a node's plane to the side the face looks at.
    g0 = np.int64(fc[f, HE])
    behind = halfedge_dest(he, he[he[g0, TWIN], NEXT])
    if k > pool.shape[0] or k > arena_v.shape[0]:
        return False
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
    while n_pieces > 0:
        n_pieces -= 1
        start = pieces[n_pieces, 0]
        mm = pieces[n_pieces, 1]
        node = pieces[n_pieces, 2]
        if tree.plane[node] < 0:
            if tree.label[node] != lab:
                if mm > rows.shape[0]:
                    return False
                for i in range(mm):
                    rows[i] = arena_v[start + i]
                    edges[i] = arena_e[start + i]
                if not _emit(out, pool, rows, edges, mm, support, lab, f):
                    return False
            continue
        s = tree.plane[node]
        any_neg = False
        any_pos = False
        if mm > rows.shape[0]:
            return False
        for i in range(mm):
            side = classify_at(pool, arena_v[start + i], palette, s)
            rows[i] = side
            any_neg = any_neg or side < 0
            any_pos = any_pos or side > 0
        if not (any_neg and any_pos):
            if any_neg:
                child = tree.neg[node]
            elif any_pos:
                child = tree.pos[node]
            else:  # the piece lies in the node's plane: continue on the side the face looks at
                child = tree.neg[node] if classify_at(vx, behind, palette, s) > 0 else tree.pos[node]
            pieces[n_pieces, 2] = child
            n_pieces += 1
            continue
        # A proper split: each part has at most mm + 1 vertices, one new vertex per crossing.
        if (n_arena + 2 * mm + 4 > arena_v.shape[0] or n_pool + 2 > pool.shape[0]
                or n_pieces + 2 > pieces.shape[0]):
            return False
        neg_start = n_arena
        nn = 0
        pos_start = n_arena + mm + 2
        npp = 0
        for i in range(mm):
            j = i + 1 if i + 1 < mm else 0
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
                intersect_into(palette, face_plane_row(fc, f), palette, e, palette, s, pool, c)
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
        pieces[n_pieces, 2] = tree.neg[node]
        pieces[n_pieces + 1, 0] = pos_start
        pieces[n_pieces + 1, 1] = npp
        pieces[n_pieces + 1, 2] = tree.pos[node]
        n_pieces += 2
        if n_pool + 2 > pool.shape[0]:
            return False
    return True


# clip_cell and extract_into are compiled once and called (on unmanaged views) by the extraction
# kernels here and by the octree's per-cell steps; inlining them at the numba IR level re-typed a
# copy per caller (issue 21). Callers pass int64 scalars and numpy bools, never literals: each
# distinct argument type (Literal[int](2), int32) is one more compilation.
@unlinked
@borrowing_jit
def clip_cell(m, h, lab, tree, sc, out, walls):
    """Clip every face of the cell ``h`` (label ``lab``) against its opposite subtree (:func:`clip_face`).

    Faces on the domain box (``OPP == -1``) are clipped only when ``walls`` is true.
    Returns False when scratch or output ran short (``out`` must then be rolled back).
    """
    # A cell never has more half-edges than the store has rows in use; the work array holds them.
    if sc.work.shape[0] < m.counts[1]:
        return False
    nh = collect_cell_halfedges(m.he, m.hmark, m.counts, h, sc.work)
    for i in range(nh):
        g = np.int64(sc.work[i])
        f = np.int64(m.he[np.uint64(g), FACE])
        if m.fc[np.uint64(f), HE] != g:
            continue
        if not walls and m.fc[f, OPP] < 0:
            continue
        if not clip_face(m, f, lab, tree, sc, out):
            return False
    return True


# ---------------------------------------------------------------------------
# extraction: cells by cutting, pieces at the leaves, cells released (one kernel call)


@unlinked
@borrowing_jit
def extract_into(m, tree, stack, state, cells, sc, out, mode, no_path):
    """Cut the box cell down the tree; at each leaf clip, record or release the cell.

    ``stack`` rows are (node, cell handle, bound on the cell's face count); ``state`` is
    (stack size, cells recorded, in leaves reached, label of the last one). At an **in**
    leaf: with ``PIECES`` its faces are clipped into ``out`` (``WALLS``: box faces too); with
    ``KEEP_CELLS`` (leaf, handle) is recorded in ``cells``, otherwise the cell is released for
    reuse. Out cells are always released. ``NAIVE`` cuts with the classify-every-vertex
    baseline. Returns DONE, NEED_ROOM (nothing of the pending step done: grow and call
    again) or FAILED.
    """
    mode = np.int64(mode)
    keep = (mode & KEEP_CELLS) != 0
    naive = (mode & NAIVE) != 0
    walls = (mode & WALLS) != 0
    while state[0] > 0:
        top = state[0] - 1
        node = stack[top, _NODE]
        h = stack[top, _HANDLE]
        bound = stack[top, _FACE_BOUND]
        if tree.plane[node] < 0:
            lab = tree.label[node]
            if lab != OUT:
                if keep and state[1] >= cells.shape[0]:
                    return NEED_ROOM
                if (mode & PIECES) != 0:
                    mark_v = out.counts[0]
                    mark_p = out.counts[1]
                    if not clip_cell(m, np.int64(h), np.int64(lab), tree, sc, out, walls):
                        out.counts[0] = mark_v
                        out.counts[1] = mark_p
                        return NEED_ROOM
                state[2] += 1
                state[3] = lab
                if keep:
                    cells[state[1], 0] = node
                    cells[state[1], 1] = h
                    state[1] += 1
                else:
                    release_cell(m, h)
            else:
                release_cell(m, h)
            state[0] = top
            continue
        if not room_for_cut(m, bound) or top + 2 > stack.shape[0]:
            return NEED_ROOM
        if naive:
            if sc.work.shape[0] < m.he.shape[0]:
                return NEED_ROOM
            status, a, b = cut_cell_naive(m, sc.work, np.int64(h), np.int64(tree.plane[node]),
                                          np.int64(tree.pos[node]), np.int64(tree.neg[node]))
        else:
            # The caps face the other child: the negative part's cap looks into pos[node].
            status, a, b = cut_cell(m, np.int64(h), np.int64(tree.plane[node]), np.int64(tree.pos[node]),
                                    np.int64(tree.neg[node]), no_path)
        if status == CUT_PROPER:
            # The child processed first goes on top. A leaf child first: its cell is done
            # (and released) at once instead of waiting below a whole subtree.
            first_pos = tree.plane[tree.pos[node]] < 0 and tree.plane[tree.neg[node]] >= 0
            lower, upper = (1, 0) if first_pos else (0, 1)
            stack[top + lower, _NODE] = tree.pos[node]
            stack[top + lower, _HANDLE] = b
            stack[top + lower, _FACE_BOUND] = bound + 1
            stack[top + upper, _NODE] = tree.neg[node]
            stack[top + upper, _HANDLE] = a
            stack[top + upper, _FACE_BOUND] = bound + 1
            state[0] = top + 2
        elif status == 0:
            stack[top, _NODE] = tree.neg[node] if a < 0 else tree.pos[node]
        else:
            return FAILED
    return DONE


@jit
def _extract_kernel(m, tree, stack, state, cells, sc, out, mode, no_path):
    m, tree, sc, out = unmanaged_tuple(m), unmanaged_tuple(tree), unmanaged_tuple(sc), unmanaged_tuple(out)
    return extract_into(m, tree, unmanaged(stack), unmanaged(state), unmanaged(cells), sc, out, mode,
                        unmanaged(no_path))


class Extractor:
    """Drives :func:`_extract_kernel` over a fresh store (the growth between resumptions)."""

    def __init__(self, tree: BSPTree, lo, hi, mode: int, capacity: int) -> None:
        self.tree = tree
        self.ta = tree_arrays(tree)
        depth = tree.depth()
        # Live cells are the ones on the stack: the deepest one has at most depth + 6 faces, and
        # a cut needs room for 2 vertices and 6 half-edges per face on top of it.
        self.store = MeshStore(tree.palette, capacity=max(capacity, 8 * (depth + 8)))
        self.store.reserve(0, 0, 0, loop=depth + 8)
        box = self.store.add_box(lo, hi)
        self.stack = np.zeros((max(64, 2 * depth + 8), 3), np.int64)
        self.stack[0] = (0, box, 6)
        self.state = np.array([1, 0, 0, 0], np.int64)
        # an in-cell per leaf at most ((n + 1) / 2 of a tree's n nodes): KEEP_CELLS never resumes for this array
        self.cells = np.zeros((tree.n_nodes // 2 + 2 if mode & KEEP_CELLS else 16, 2), np.int64)
        self.sc = new_clip_scratch(tree.palette.dtype)
        n = tree.n_nodes
        self.out = new_pieces(tree.palette.dtype, 256 + 16 * n, 64 + 4 * n) if mode & PIECES else new_pieces(
            tree.palette.dtype)
        self.mode = mode
        self.no_path = np.zeros(1, np.int64)

    def step(self) -> int:
        return _extract_kernel(self.store.m, self.ta, self.stack, self.state, self.cells, self.sc, self.out,
                               self.mode, self.no_path)

    def grow(self) -> None:
        m = self.store.m
        top = int(self.state[0]) - 1
        bound = int(self.stack[top, _FACE_BOUND]) + 2 if top >= 0 else 8
        self.store.m = grown_mesh_arrays(m, 2 * bound, 6 * bound + 2, bound + 2, loop=bound)
        if top + 2 > self.stack.shape[0]:
            self.stack = grown(self.stack)
        if self.state[1] >= self.cells.shape[0]:
            self.cells = grown(self.cells)
        sc = self.sc
        if sc.work.shape[0] < self.store.m.he.shape[0]:
            sc = sc._replace(work=np.empty(self.store.m.he.shape[0], np.int32))
        self.sc = sc
        if self.mode & PIECES:  # only clipping a leaf's faces writes pieces and uses the clip scratch
            if top >= 0 and self.tree.plane[self.stack[top, _NODE]] < 0:
                self.sc = grown_clip_scratch(sc)
            self.out = grown_pieces(self.out, 4 * self.sc.arena_v.shape[0], self.sc.stack.shape[0])

    def run(self) -> Extractor:
        run_resumable(self.step, self.grow, "boundary extraction")
        return self


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


_INT64_MIN = -(1 << 63)


def check_corner(value, name: str) -> tuple[int, int, int]:
    """A box corner as three exact ints (integral floats accepted; 2.7, NaN or a wrong shape refused)."""
    if isinstance(value, list | tuple) and len(value) == 3 and all(type(v) is int and _INT64_MIN <= v < -_INT64_MIN
                                                                   for v in value):
        return tuple(value)  # the common case, three Python ints: nothing to convert (~7 us a corner otherwise)
    if isinstance(value, np.ndarray) and value.dtype == np.int64 and value.shape == (3,):
        return tuple(value.tolist())
    arr = integer_array(value, name)
    if arr.shape not in ((3,), (1, 3)):
        raise GeometryError(f"{name} must be a point (3,) of integers, got shape {arr.shape}")
    return tuple(int(v) for v in arr.reshape(3))


def check_box(lo, hi) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    """The box ``[lo, hi]`` as two corners of exact ints with ``lo < hi`` in every coordinate."""
    lo, hi = check_corner(lo, "lo"), check_corner(hi, "hi")
    if any(a >= b for a, b in zip(lo, hi, strict=True)):
        raise GeometryError(f"the box needs lo < hi in every coordinate, got {lo}, {hi}")
    return lo, hi


def check_tree(tree, name: str = "tree") -> BSPTree:
    """Return ``tree`` if it is a :class:`BSPTree`; ``TypeError`` naming what to pass otherwise."""
    if not isinstance(tree, BSPTree):
        hint = " (a BSP solid: pass its .tree)" if hasattr(tree, "tree") else ""
        raise TypeError(f"{name} must be a csgnb.bsp.BSPTree, got {type(tree).__name__}{hint}; build one with "
                        "bsp_from_mesh, random_bsp or BSP.from_mesh(...).tree")
    return tree


def extract_cells(tree: BSPTree, lo, hi, *, capacity: int = 1024, naive: bool = False
                  ) -> tuple[MeshStore, np.ndarray]:
    """Return the convex cells of the **in** leaves of ``tree`` inside the box ``[lo, hi]``.

    ``naive=True`` cuts with the classify-every-vertex baseline instead of edge descent.

    Returns (store, cells): ``cells`` is ``(k, 2) int64`` rows of (leaf node, cell
    handle into ``store``). Out leaves are released; cells of zero volume never occur
    (cuts without a proper intersection send the whole cell to one side).
    """
    check_tree(tree)
    lo, hi = check_box(lo, hi)
    capacity = check_count(capacity, "capacity", 1)
    mode = KEEP_CELLS | (NAIVE if naive else 0)
    ex = Extractor(tree, lo, hi, mode, capacity).run()
    cells = ex.cells[: ex.state[1]]
    return ex.store, cells[tree.label[cells[:, 0]] != OUT]


def pieces_tuple(palette: np.ndarray, out: Pieces):
    nv, npoly = (int(c) for c in out.counts)
    return palette, out.vx[:nv], out.edge[:nv], out.poly[:npoly]


def boundary_pieces(tree: BSPTree, store: MeshStore, cells: np.ndarray, *, walls: bool = True):
    """Clip the faces of the in-cells ``cells`` (rows (leaf, handle)) against their opposite subtrees.

    Returns the raw boundary pieces ``(palette, vertices, edge planes, polygons)`` that
    :func:`~csgnb.bsp.surface.assemble_surface` merges (see :class:`Pieces`); with
    ``walls=False`` faces on the domain box are left out.
    """
    ta = tree_arrays(tree)
    state = np.zeros(1, np.int64)
    cells = np.ascontiguousarray(cells, np.int64).reshape(-1, 2)
    sc = new_clip_scratch(store.vx.dtype)
    sc = sc._replace(work=np.empty(store.he.shape[0], np.int32))
    box = {"out": new_pieces(store.vx.dtype, max(256, 32 * cells.shape[0]), max(64, 8 * cells.shape[0])), "sc": sc}

    def step():
        return _clip_cells_kernel(store.m, ta, cells, state, box["sc"], box["out"], walls)

    def grow():
        box["sc"] = grown_clip_scratch(box["sc"])
        box["out"] = grown_pieces(box["out"], 4 * box["sc"].arena_v.shape[0], box["sc"].stack.shape[0])

    run_resumable(step, grow, "boundary clipping")
    return pieces_tuple(store.planes.copy(), box["out"])


@jit
def _clip_cells_kernel(m, tree, cells, state, sc, out, walls):
    """Clip the faces of every in-cell of ``cells`` from ``state[0]`` on; resumable per cell."""
    m, tree, sc, out = unmanaged_tuple(m), unmanaged_tuple(tree), unmanaged_tuple(sc), unmanaged_tuple(out)
    cells, state = unmanaged(cells), unmanaged(state)
    while state[0] < cells.shape[0]:
        node = cells[state[0], 0]
        lab = tree.label[node]
        if lab != OUT:
            mark_v = out.counts[0]
            mark_p = out.counts[1]
            if not clip_cell(m, np.int64(cells[state[0], 1]), np.int64(lab), tree, sc, out, np.bool_(walls)):
                out.counts[0] = mark_v
                out.counts[1] = mark_p
                return NEED_ROOM
        state[0] += 1
    return DONE


def extract_boundary(tree: BSPTree, lo, hi, *, keep_cells: bool = True) -> Extraction:
    """Return the exact boundary of the solid ``tree`` represents inside the box ``[lo, hi]``.

    One kernel call cuts the cells down the tree and clips each in-cell's faces against
    their opposite subtrees at its leaf (Figures 5-6); with ``keep_cells=False`` every
    cell is released as soon as it is done, so the store stays as small as the deepest
    path of the tree needs.

    Parameters
    ----------
    tree : BSPTree
    lo, hi : (3,) int
        Integer box corners; the box planes join the palette, so they must fit the
        tree's bit budget. Space outside the box counts as **out**.
    keep_cells : bool
        Keep the in-cells (``Extraction.cells``, ``Extraction.store``) for inspection.

    Returns
    -------
    Extraction
        ``surface``: closed, conforming, exact polygons (see
        :class:`~csgnb.bsp.surface.BoundarySurface`), ``surface.to_polydata()`` for display.
    """
    check_tree(tree)
    lo, hi = check_box(lo, hi)
    mode = PIECES | WALLS | (KEEP_CELLS if keep_cells else 0)
    ex = Extractor(tree, lo, hi, mode, 1024).run()
    cells = ex.cells[: ex.state[1]] if keep_cells else np.zeros((0, 2), np.int64)
    surface = assemble_surface(*pieces_tuple(ex.store.planes.copy(), ex.out))
    return Extraction(tree, ex.store, cells, surface)
