"""Many convex tools in one compiled call: each hull's octree Boolean and combine pass in turn (issue 22).

One convex Boolean called from Python costs ~0.2 ms around the kernel (the hull's planes made exact, put in
spread order, checked against the budget, written to the palette as wide integers, the tool's linear BSP, the
combine order, the reports) plus ~22 µs to unbox the kernel's named tuples: a quarter of a drill tool's 896 prism
unions (~0.7 ms each at 256 bits). A batch does that set-up for every hull at once (one concatenation, one budget
check, one conversion to wide integers, one compiled pass of spread orders) and :func:`convex_batch_kernel` runs,
per hull, what :meth:`csgnb.octree.Workpiece.boolean` runs: the planes appended to the palette, the Boolean kernel
(:func:`csgnb.octree.kernels._boolean_kernel`, called by pointer), the combine pass over the touched cells'
parents in the same order, and the same counters. It returns to Python only for room (the usual resumption:
``NEED_ROOM`` with ``need[0]`` naming the resource) and where one Boolean at a time would compact the pool or the
palette (``R_COMPACT``): those compactions then happen after the same hulls, so the workpiece ends with the very
arrays a loop of single Booleans gives (tested array for array).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb._resumable import DONE, FAILED, NEED_ROOM
from csgnb.bsp.polygon import copy_point
from csgnb.exact.predicates import homogeneous_points
from csgnb.exact.wide import width_of
from csgnb.octree.kernels import (
    COMBINE_ORDER_LEAVES,
    CONVEX_TOOL,
    ST_DONE,
    ST_LEAF,
    ST_REFINE,
    _boolean_kernel,
    combine_order,
    combine_upwards,
)
from csgnb.octree.layout import (
    N_PAL,
    N_POOL,
    POOL_LIVE,
    R_PALETTE,
    S_CELL_OPS,
    S_COMBINES,
    S_MERGES,
    S_RELABELS,
    S_SPLITS,
    S_UNCHANGED,
)
from csgnb.octree.tool import convex_tool_tree, spread_order
from csgnb.octree.workspace import ToolArrays

__all__ = ["ConvexBatch", "convex_batch_kernel", "spread_orders"]

# columns of ConvexBatch.state
B_NEXT, B_PHASE, B_ROW, B_PARENTS, B_COMBINED, B_PALETTE_LIMIT = range(6)
# phases of the hull in progress
P_START, P_BOOLEAN, P_COMBINE = 0, 1, 2
R_COMPACT = 119
"""need code: stop after this hull -- one Boolean at a time would compact the pool or the palette here."""
# columns of ConvexBatch.reports
(REP_LEAVES, REP_MERGES, REP_RELABELS, REP_SPLITS, REP_COMBINES, REP_UNCHANGED, REP_CELL_OPS) = range(7)
POOL_COMPACT_ROWS = 4096
"""The pool is compacted after a Boolean when it holds more rows than this and fewer than half are live."""


class ConvexBatch(NamedTuple):
    """Convex tools for one :func:`convex_batch_kernel` call, applied in order.

    planes : (r, 4) wide -- every hull's outward planes in spread order, hull after hull;
    starts : (n + 1,) int64 -- hull i's planes are rows ``starts[i]:starts[i + 1]``;
    lo, hi : (n, 3) int64 -- the open box of cells each Boolean touches;
    state : (8,) int64 -- the hull in progress and its phase (``B_*`` columns), resumable;
    before : (32,) int64 -- the octree counters when the hull in progress began;
    reports : (n, 7) int64 -- per hull: leaves touched, merges, relabels, splits, combines, merges found unchanged,
    cell operations (``REP_*`` columns);
    parents : (p,) int64 -- the combine order of the hull in progress (at least as long as the Boolean's ``done``);
    box_lo, box_hi : (3,) int64 -- scratch: the box of the hull in progress;
    no_i32, one_i32, no_verts, no_box -- the empty mesh-tool fields of a convex tool's ``ToolArrays``;
    f_has : (n,) bool -- whether hull i carries its facets (:mod:`csgnb.mesh.hull_facets`; none when the workpiece
    keeps no cell boundaries, which is what they are for);
    f_offsets : (r + 1,) int64, f_edges : int32 (hull-local plane indices), f_verts : (m, 4) wide, f_lo, f_hi :
    (r, 3) int64 -- plane g's facet is ``f_edges[f_offsets[g]:f_offsets[g + 1]]`` with its vertices and box.
    """

    planes: np.ndarray
    starts: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    state: np.ndarray
    before: np.ndarray
    reports: np.ndarray
    parents: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray
    no_i32: np.ndarray
    one_i32: np.ndarray
    no_verts: np.ndarray
    no_box: np.ndarray
    f_has: np.ndarray
    f_offsets: np.ndarray
    f_edges: np.ndarray
    f_verts: np.ndarray
    f_lo: np.ndarray
    f_hi: np.ndarray


def new_convex_batch(planes: np.ndarray, starts: np.ndarray, lo: np.ndarray, hi: np.ndarray, parents: int,
                     palette_limit: int, facets=None) -> ConvexBatch:
    """A batch over prepared arrays (see :class:`ConvexBatch`); ``parents`` rows of combine order,
    ``palette_limit`` the palette size at which the palette is to be compacted; ``facets`` the hulls' facets
    (:func:`csgnb.mesh.hull_facets.hull_facets_of_batch`) or None."""
    n = starts.shape[0] - 1
    r = planes.shape[0]
    state = np.zeros(8, np.int64)
    state[B_PALETTE_LIMIT] = palette_limit
    if facets is None:
        f_has, f_offsets, f_edges = np.zeros(n, np.bool_), np.zeros(r + 1, np.int64), np.zeros(0, np.int32)
        f_verts, f_lo, f_hi = np.zeros((0, 4), planes.dtype), np.zeros((r, 3), np.int64), np.zeros((r, 3), np.int64)
    else:
        f_has, f_offsets, f_edges, points, f_lo, f_hi = facets
        f_verts = homogeneous_points(points, width_of(planes))
    return ConvexBatch(planes, np.ascontiguousarray(starts, np.int64), np.ascontiguousarray(lo, np.int64),
                       np.ascontiguousarray(hi, np.int64), state, np.zeros(32, np.int64), np.zeros((n, 7), np.int64),
                       np.zeros(max(int(parents), 256), np.int64), np.zeros(3, np.int64), np.zeros(3, np.int64),
                       np.zeros(0, np.int32), np.zeros(1, np.int32), np.zeros((0, 4), planes.dtype),
                       np.zeros((0, 3), np.int64), f_has, f_offsets, f_edges, f_verts, f_lo, f_hi)


@jit
def _hull_tool(batch, i, first, k, rows):
    """Hull i's :class:`ToolArrays` (its planes at palette ``rows``, batch rows ``first:first + k``): with its facets
    over those rows where it has them, as :meth:`csgnb.octree.Workpiece._tool_arrays` makes a single hull's."""
    plane, neg, pos, label = convex_tool_tree(rows)
    if not batch.f_has[i]:
        return ToolArrays(rows, batch.no_i32, batch.one_i32, batch.no_i32, batch.no_verts, batch.no_box,
                          batch.no_box, plane, neg, pos, label)
    e0 = batch.f_offsets[first]
    m = batch.f_offsets[first + k] - e0
    support = np.empty(k, np.int32)
    offsets = np.empty(k + 1, np.int32)
    plo = np.empty((k, 3), np.int64)
    phi = np.empty((k, 3), np.int64)
    for j in range(k):
        support[j] = rows[j]
        offsets[j] = batch.f_offsets[first + j] - e0
        for c in range(3):
            plo[j, c] = batch.f_lo[first + j, c]
            phi[j, c] = batch.f_hi[first + j, c]
    offsets[k] = m
    edges = np.empty(m, np.int32)
    verts = np.empty((m, 4), batch.f_verts.dtype)
    for j in range(m):
        edges[j] = rows[0] + batch.f_edges[e0 + j]
        copy_point(batch.f_verts, e0 + j, verts, j)
    return ToolArrays(rows, support, offsets, edges, verts, plo, phi, plane, neg, pos, label)


@jit
def spread_orders(normals, starts):
    """Each segment ``starts[i]:starts[i + 1]`` of ``normals`` ``(r, 3)`` float64 in :func:`spread_order`
    (segments of four rows or fewer kept as they are, as :meth:`Tool.from_hull` does): ``(r,) int64`` global row
    indices."""
    order = np.arange(normals.shape[0])
    for i in range(starts.shape[0] - 1):
        s, e = starts[i], starts[i + 1]
        if e - s > 4:
            local = spread_order(np.ascontiguousarray(normals[s:e]))
            for j in range(e - s):
                order[s + j] = s + local[j]
    return order


@jit
def _parents_in_order(oc, leaves, out):
    """The combine pass's order of the parents of ``leaves`` (:func:`csgnb.octree.workpiece._combine_order`)
    written to ``out``; returns how many."""
    if leaves.shape[0] <= COMBINE_ORDER_LEAVES:
        p = combine_order(oc.parent, oc.size, leaves)
    else:
        u = np.unique(oc.parent[leaves])
        u = u[u >= 0].astype(np.int64)
        p = u[np.argsort(-oc.size[u], kind="mergesort")[::-1]]
    for j in range(p.shape[0]):
        out[j] = p[j]
    return p.shape[0]


@jit
def convex_batch_kernel(pal, oc, pool, amap, work, cand, done, batch, table, constant, ws, st, split_stack,
                        threshold, min_size, max_polygons, seed, need):
    """Apply ``batch``'s convex tools in order with the label table (resumable via ``batch.state`` and ``st``).

    For each hull what :meth:`csgnb.octree.Workpiece.boolean` does for one: its planes appended to the palette
    ``pal``, :func:`csgnb.octree.kernels._boolean_kernel` over its box, then the combine pass over the touched
    leaves' parents; ``batch.reports[i]`` gets its counters. Returns ``DONE``, ``FAILED`` or ``NEED_ROOM`` with
    ``need[0]`` a resource of :data:`csgnb.octree.layout.RESOURCE_NAMES`, ``R_WORK`` (grow ``work``, ``done`` and
    ``batch.parents``), ``R_CANDIDATES`` or :data:`R_COMPACT` (a hull is done; compact as one Boolean at a time
    would, then call again).
    """
    s = batch.state
    n = batch.starts.shape[0] - 1
    need[0] = 0
    while s[B_NEXT] < n:
        i = s[B_NEXT]
        first = batch.starts[i]
        k = batch.starts[i + 1] - first
        if s[B_PHASE] == P_START:
            row = oc.counts[N_PAL]
            if row + k + 64 > pal.shape[0]:  # the room a single Boolean makes before its kernel runs
                need[0] = R_PALETTE
                return NEED_ROOM
            for j in range(k):
                for c in range(4):
                    pal[row + j, c] = batch.planes[first + j, c]
            oc.counts[N_PAL] = row + k
            s[B_ROW] = row
            for c in range(batch.before.shape[0]):
                batch.before[c] = oc.counts[c]
            st[:] = 0
            st[ST_LEAF] = 1
            st[ST_REFINE] = -1
            work[0, 0] = 0
            work[0, 1] = 0
            work[0, 2] = 0
            work[0, 3] = 4
            for c in range(3):
                batch.box_lo[c] = batch.lo[i, c]
                batch.box_hi[c] = batch.hi[i, c]
            s[B_PHASE] = P_BOOLEAN
        if s[B_PHASE] == P_BOOLEAN:
            tool = _hull_tool(batch, i, first, k, np.arange(s[B_ROW], s[B_ROW] + k))
            status = _boolean_kernel(pal, oc, pool, amap, work, cand, done, np.int64(CONVEX_TOOL), tool,
                                     batch.box_lo, batch.box_hi, table, constant, ws, st, split_stack, threshold,
                                     min_size, max_polygons, seed, need)
            if status != DONE:
                return status
            s[B_PARENTS] = _parents_in_order(oc, done[:st[ST_DONE]], batch.parents)
            s[B_COMBINED] = 0
            s[B_PHASE] = P_COMBINE
        while s[B_COMBINED] < s[B_PARENTS]:
            if not combine_upwards(pal, oc, pool, amap, batch.parents[s[B_COMBINED]], ws, threshold, seed, need):
                return FAILED if need[0] == 0 else NEED_ROOM
            s[B_COMBINED] += 1
        rep = batch.reports
        b = batch.before
        rep[i, REP_LEAVES] = st[ST_DONE]
        rep[i, REP_MERGES] = oc.counts[S_MERGES] - b[S_MERGES]
        rep[i, REP_RELABELS] = oc.counts[S_RELABELS] - b[S_RELABELS]
        rep[i, REP_SPLITS] = oc.counts[S_SPLITS] - b[S_SPLITS]
        rep[i, REP_COMBINES] = oc.counts[S_COMBINES] - b[S_COMBINES]
        rep[i, REP_UNCHANGED] = oc.counts[S_UNCHANGED] - b[S_UNCHANGED]
        rep[i, REP_CELL_OPS] = oc.counts[S_CELL_OPS] - b[S_CELL_OPS]
        s[B_NEXT] = i + 1
        s[B_PHASE] = P_START
        used = oc.counts[N_POOL]
        if (used > POOL_COMPACT_ROWS and oc.counts[POOL_LIVE] < used // 2) or oc.counts[N_PAL] >= s[B_PALETTE_LIMIT]:
            need[0] = R_COMPACT
            return NEED_ROOM
    return DONE
