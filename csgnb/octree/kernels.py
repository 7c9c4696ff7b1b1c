"""numba kernels of the octree workpiece: Booleans with a tool, split and combine (paper §3.8, Figure 8).

One kernel call runs one Boolean over every touched cell (:func:`_boolean_kernel`): no
Python per cell. Per cell, with the mesh store reset:

1. the cell's BSP (or its uniform label) is copied into scratch (``ta``);
2. the tool is localised to the cell box: a convex tool keeps the planes that cross the box
   (a linear BSP); a mesh tool's plane-based polygons are clipped to the box exactly and a
   small BSP is built from the pieces (§3.9: never re-triangulated, no new planes). A cell
   the tool's surface does not cross is relabelled without a merge: inside or outside the
   tool is decided by an exact point classification;
3. a cell that kept its exact boundary (:mod:`csgnb.octree.piece_cache`; a uniform cell has none) is merged
   from the boundaries (:func:`csgnb.bsp.boundary_merge.push_pieces`): its pieces pushed down the tool's local
   tree, the tool's pieces in the box (a mesh tool's from step 2, a convex tool's: its facets on the crossing planes
   clipped to the walls, :func:`_hull_facets_in_box`, or without facets the box cut by those planes,
   :func:`boundary_in_box`) down the cell's, the kept fragments imported once -- no cut;
   otherwise merge by cutting (:func:`csgnb.bsp.merging.merge_cells`) in the cell box, then
4. redundancy removal (§3.7): the merged in-cells' faces are clipped against their
   opposite subtrees -- faces on the cell walls are skipped, the cell box bounds the BSP --
   and the pieces are imported again; the smaller tree is kept. No boundary inside the box
   means the cell is uniform. The pieces imported are the cell's boundary: kept for step 3 next time;
5. a BSP above the threshold is split into the eight children (BSP ∩ child box, then
   redundancy removal), recursively, down to unit cells (beyond that a cell is counted
   as pathological and kept).

:func:`_combine_kernel` merges eight leaf children back into their parent when their BSPs
fit: an axis-BSP over the children's BSPs, then redundancy removal in the parent box.

The big per-cell steps (tool clipping, merge + redundancy removal, extraction in a box, one
cell of a Boolean, a split, a combine) are separately compiled functions rather than inlined
ones, compiled without reference counting (``borrowing_jit``: they allocate nothing; with it, each
binding of a workspace array was an opaque ``NRT_incref``/``NRT_decref`` pair, dozens a cell): they
run once per cell, their call costs a few microseconds on unmanaged views, and
compiling them once instead of inlining them into every kernel keeps the first run's compile
time reasonable (issue 21: the inlined version took minutes; ``benchmarks/bench_compile.py``). They, and the
merge, extraction, clipping and BSP building they call, are ``@unlinked`` (:mod:`csgnb._unlinked`): called by
pointer, so their code is not copied into, and optimised again inside, every kernel above them.
Only small helpers are inlined at the numba IR level.

Kernels are resumable (:mod:`csgnb._resumable`): before a step that could overflow they
check room, and on a shortage return ``NEED_ROOM`` with ``need[0]`` naming the resource
(:data:`csgnb.octree.layout.RESOURCE_NAMES`); the cell in progress is redone from scratch,
since a cell's result is written only once it is complete.
"""

from __future__ import annotations

import numpy as np

from csgnb._jit import borrowing_jit, jit
from csgnb._resumable import DONE, FAILED, NEED_ROOM
from csgnb._shuffle import shuffle_order
from csgnb._unlinked import unlinked
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.bsp.boundary_merge import (
    NEED_ARENA,
    NEED_STACK,
    S_A_UNCHANGED,
    S_B_KEPT,
    S_NEED,
    S_PIECES,
    begin_push,
    push_pieces,
)
from csgnb.bsp.build import build_kernel
from csgnb.bsp.extract import PIECES, TreeArrays, clip_cell, extract_into
from csgnb.bsp.merging import CHANGED, merge_cells, merge_changes_a
from csgnb.bsp.polygon import copy_point, negative_piece_into
from csgnb.exact.intrinsics import box_plane_sides, classify_at, classify_wall_at, wide_sign_at
from csgnb.exact.wide_store import store_int64_at
from csgnb.mesh.float_box import cell_float_box
from csgnb.mesh.halfedge import FREE_F, FREE_H, FREE_V, NF, NH, NV, add_box_cell
from csgnb.octree.layout import (
    BSP,
    N_AXIS,
    N_FREE_BLOCKS,
    N_NODES,
    N_PAL,
    N_POOL,
    POOL_LIVE,
    R_AXIS,
    R_BUILD,
    R_BUILD_IN,
    R_EXTRACT,
    R_MERGE,
    R_MESH,
    R_NODES,
    R_PALETTE,
    R_PIECES,
    R_PIECES_OUT,
    R_POOL,
    R_PUSH_ARENA,
    R_PUSH_STACK,
    R_SPLIT_STACK,
    R_TOOL_ARENA,
    R_TREE_A,
    R_TREE_B,
    R_TREE_R,
    S_BOUNDARY_MERGES,
    S_BOUNDARY_SHORTCUTS,
    S_BOUNDARY_UNCHANGED,
    S_CELL_OPS,
    S_COMBINES,
    S_MERGES,
    S_PATHOLOGICAL,
    S_RELABELS,
    S_SIMPLIFIED,
    S_SPLITS,
    S_UNCHANGED,
    UNIFORM,
)
from csgnb.octree.piece_cache import MODE as PC_MODE
from csgnb.octree.piece_cache import ON as PC_ON
from csgnb.octree.piece_cache import cached_pieces, piece_room, pieces_of_cell, pieces_outside, store_cell_pieces
from csgnb.octree.workspace import unmanaged_workspace

__all__ = []

_EMPTY_KEY = -1
# tool kinds
CONVEX_TOOL, MESH_TOOL = 0, 1
# state columns of the Boolean kernel
ST_LEAF, ST_PHASE, ST_SPLIT_TOP, ST_SPLIT_CHILD, ST_CAND_TOP, ST_DONE, ST_REFINE = 0, 1, 2, 3, 4, 5, 6
R_CANDIDATES = 117  # need code: the candidate-index arena of the Boolean kernel
R_WORK = 118  # need code: the worklist or the list of processed cells


# ---------------------------------------------------------------------------
# wall planes


@jit(inline="always")
def _axis_key(axis, side, c):
    return ((axis * 2 + side) << 58) ^ (c + (1 << 56))


@jit(inline="always")
def axis_plane(amap, pal, oc, axis, side, c, need):
    """Palette row of the outward wall ``x_axis >= c`` (``side`` 0) or ``x_axis <= c`` (1); -1 when short of room."""
    keys = amap.keys
    mask = keys.shape[0] - 1
    key = _axis_key(axis, side, c)
    h = (key * np.int64(-7046029254386353131)) >> 20
    i = h & mask
    while keys[i] != _EMPTY_KEY:
        if keys[i] == key:
            return np.int64(amap.rows[i])
        i = (i + 1) & mask
    if 2 * (oc.counts[N_AXIS] + 1) > keys.shape[0]:
        need[0] = R_AXIS
        return -1
    row = oc.counts[N_PAL]
    if row >= pal.shape[0]:
        need[0] = R_PALETTE
        return -1
    for col in range(3):
        store_int64_at(pal, row, col, 0)
    if side == 0:
        store_int64_at(pal, row, axis, -1)
        store_int64_at(pal, row, 3, c)
    else:
        store_int64_at(pal, row, axis, 1)
        store_int64_at(pal, row, 3, -c)
    oc.counts[N_PAL] = row + 1
    keys[i] = key
    amap.rows[i] = row
    oc.counts[N_AXIS] += 1
    return row


@jit(inline="always")
def box_rows(amap, pal, oc, lo0, lo1, lo2, size, rows, need):
    """Fill ``rows`` (6,) with the outward walls of the box ``lo + [0, size]^3``; False when short of room."""
    los = (lo0, lo1, lo2)
    for axis in range(3):
        r = axis_plane(amap, pal, oc, axis, 0, los[axis], need)
        if r < 0:
            return False
        rows[2 * axis] = r
        r = axis_plane(amap, pal, oc, axis, 1, los[axis] + size, need)
        if r < 0:
            return False
        rows[2 * axis + 1] = r
    return True


# ---------------------------------------------------------------------------
# small tree utilities


@jit(inline="always")
def set_leaf(t, label):
    """Make ``t`` the one-leaf tree ``label``; return its node count (1)."""
    t.plane[0] = -1
    t.neg[0] = -1
    t.pos[0] = -1
    t.label[0] = label
    return 1


@jit(inline="always")
def copy_from_pool(pool, start, n, t, base):
    """Copy the pool BSP ``start .. start + n`` into ``t`` at node ``base`` (children relocated)."""
    for i in range(n):
        p = pool.plane[start + i]
        t.plane[base + i] = p
        t.label[base + i] = pool.label[start + i]
        if p >= 0:
            t.neg[base + i] = pool.neg[start + i] + base
            t.pos[base + i] = pool.pos[start + i] + base
        else:
            t.neg[base + i] = -1
            t.pos[base + i] = -1


@jit(inline="always")
def uniform_label(t, n):
    """The label of every leaf of ``t[:n]`` if they all agree, else -1."""
    lab = -1
    for i in range(n):
        if t.plane[i] < 0:
            if lab < 0:
                lab = t.label[i]
            elif t.label[i] != lab:
                return -1
    return lab


@jit(inline="always")
def only_in_out(t, n):
    """Whether every leaf label of ``t[:n]`` is 0 or 1 (redundancy removal by re-import keeps one material)."""
    for i in range(n):
        if t.plane[i] < 0 and t.label[i] > 1:
            return False
    return True


@jit(inline="always")
def mesh_reset(m):
    """Empty the mesh store (every row free again; the arrays are kept)."""
    c = m.counts
    c[NV] = 0
    c[NH] = 0
    c[NF] = 0
    c[FREE_V] = 0
    c[FREE_H] = 0
    c[FREE_F] = 0


@jit(inline="always")
def mesh_room(m, faces):
    """Room for a fresh box and enough cuts of cells with up to ``faces`` faces."""
    return m.vx.shape[0] >= 8 * faces + 64 and m.he.shape[0] >= 32 * faces + 256 and m.fc.shape[0] >= 8 * faces + 64 \
        and m.loop.shape[0] >= faces + 8


# ---------------------------------------------------------------------------
# point classification with a symbolic perturbation


@jit(inline="always")
def classify_perturbed(pal, t, pt):
    """Label of the homogeneous point ``pt[0]`` in tree ``t``, moved by (ε, ε², ε³) off any plane it lies on.

    Exact and never ambiguous: on a node's plane the side is the sign of the plane's
    first non-zero normal coefficient (the direction of the perturbation).
    """
    node = 0
    while t.plane[node] >= 0:
        row = t.plane[node]
        side = classify_at(pt, 0, pal, row)
        if side == 0:
            side = wide_sign_at(pal, row, 0)
            if side == 0:
                side = wide_sign_at(pal, row, 1)
            if side == 0:
                side = wide_sign_at(pal, row, 2)
        node = t.neg[node] if side < 0 else t.pos[node]
    return t.label[node]


# ---------------------------------------------------------------------------
# the tool, localised to a cell


@jit(inline="always")
def _corner_signs(pal, row, corners):
    """(any corner strictly negative, any strictly positive) of the box ``corners`` (:func:`_box_corners`: corner 0
    is lo, corner 7 lo + size) against palette ``row``: from the two extreme corners (``box_plane_sides``)."""
    sides = box_plane_sides(corners, 0, corners[7, 0] - corners[0, 0], pal, row)
    return (sides & 1) != 0, (sides & 2) != 0


@jit(inline="always")
def convex_tool_in_box(pal, rows, corners, tb):
    """Localise a convex tool (outward palette ``rows``) to the box with ``corners``.

    Returns (relation, nodes): relation 0 = the box interior is outside the tool, 1 = inside,
    2 = crossed (``tb`` is then the linear BSP of the crossing planes, ``nodes`` its size;
    -1 nodes when ``tb`` is too small).
    """
    k = 0
    for i in range(rows.shape[0]):
        neg, pos = _corner_signs(pal, rows[i], corners)
        if not neg:
            return 0, 0  # the whole box is on the outer side of a face plane
        if pos:
            k += 1
    if k == 0:
        return 1, 0
    n = 2 * k + 1
    if n > tb.plane.shape[0]:
        return 2, -1
    j = 0
    for i in range(rows.shape[0]):
        neg, pos = _corner_signs(pal, rows[i], corners)
        if neg and pos:
            node = 2 * j
            tb.plane[node] = rows[i]
            tb.neg[node] = node + 2
            tb.pos[node] = node + 1
            tb.label[node] = -1
            tb.plane[node + 1] = -1
            tb.neg[node + 1] = -1
            tb.pos[node + 1] = -1
            tb.label[node + 1] = 0
            j += 1
    tb.plane[n - 1] = -1
    tb.neg[n - 1] = -1
    tb.pos[n - 1] = -1
    tb.label[n - 1] = 1
    return 2, n


@jit(inline="always")
def _append_import_polygon(bi, n_out, e_out, support, edges, verts, first, k, need):
    """Append import polygon ``n_out`` (support row ``support``, edges and vertices ``first:first + k`` of ``edges``
    and ``verts``) at edge ``e_out`` of ``bi``; return the next free edge, or -1 when short of room."""
    if n_out + 1 >= bi.support.shape[0] or e_out + k > bi.edges.shape[0]:
        need[0] = R_BUILD_IN
        return -1
    bi.support[n_out] = support
    bi.offsets[n_out] = e_out
    for j in range(k):
        bi.edges[e_out + j] = edges[first + j]
        copy_point(verts, first + j, bi.verts, e_out + j)
    bi.offsets[n_out + 1] = e_out + k
    return e_out + k


@jit(inline="always")
def _classify_against_wall(pal, verts, start, k, row, axis, sides):
    """:func:`csgnb.bsp.polygon.classify_polygon` against the cell box wall ``row`` on ``axis`` (classify_wall_at)."""
    has_neg = False
    has_pos = False
    for j in range(k):
        c = classify_wall_at(verts, start + j, pal, row, axis)
        sides[j] = c
        has_neg = has_neg or c < 0
        has_pos = has_pos or c > 0
    if has_neg and has_pos:
        return 2
    return -1 if has_neg else (1 if has_pos else 0)


@unlinked
@borrowing_jit
def clip_tool_polygons(pal, tool, cand, lo, size, brows, arena, bi, need):
    """Clip the candidate polygons ``cand`` (indices) whose boxes meet the cell box to it; write the pieces into ``bi``.

    ``bi`` is the import input (support, offsets, edges, verts: vertex j = support ∩ e_j ∩
    e_j+1). Pieces coplanar with a wall are dropped (the box bounds the cell BSP). Returns
    the number of pieces, or -1 when short of room (``need[0]`` says what).
    """
    n_out = 0
    e_out = 0
    cap = arena.edges.shape[0] // 3
    hi0 = lo[0] + size
    hi1 = lo[1] + size
    hi2 = lo[2] + size
    for c in range(cand.shape[0]):
        i = cand[c]
        if (tool.plo[i, 0] > hi0 or tool.phi[i, 0] < lo[0] or tool.plo[i, 1] > hi1 or tool.phi[i, 1] < lo[1]
                or tool.plo[i, 2] > hi2 or tool.phi[i, 2] < lo[2]):
            continue
        s = tool.support[i]
        srow = s if s >= 0 else -s - 1
        e0 = tool.offsets[i]
        k = tool.offsets[i + 1] - e0
        if (tool.plo[i, 0] > lo[0] and tool.phi[i, 0] < hi0 and tool.plo[i, 1] > lo[1] and tool.phi[i, 1] < hi1
                and tool.plo[i, 2] > lo[2] and tool.phi[i, 2] < hi2):
            # The polygon's box (which holds its exact vertices) lies strictly inside the cell box: every wall
            # would find it entirely on its inner side and leave it as it is -- copy it without the six splits.
            e_out = _append_import_polygon(bi, n_out, e_out, s, tool.edges, tool.verts, e0, k, need)
            if e_out < 0:
                return -1
            n_out += 1
            continue
        if k + 7 > cap:
            need[0] = R_TOOL_ARENA
            return -1
        start = np.int64(0)
        for j in range(k):
            arena.edges[j] = tool.edges[e0 + j]
            copy_point(tool.verts, e0 + j, arena.verts, j)
        keep = True
        for w in range(6):
            # A wall the polygon's box lies strictly inside of leaves it whole (every vertex strictly on the inner
            # side): no classification. Walls are x_a >= lo_a (w = 2a) and x_a <= lo_a + size (w = 2a + 1).
            a = w >> 1
            if (tool.plo[i, a] > lo[a]) if w & 1 == 0 else (tool.phi[i, a] < lo[a] + size):
                continue
            side = _classify_against_wall(pal, arena.verts, start, k, np.int64(brows[w]), a, arena.sides)
            if side == -1:
                continue
            if side == 2:
                # only the inner (negative) piece is kept: the outer one is never written
                o_neg = np.int64(cap if start == 0 else 0)
                k = negative_piece_into(pal, srow, brows[w], arena.edges, arena.verts, start, k, arena.sides, o_neg)
                start = o_neg
                continue
            keep = False  # outside, or on the wall
            break
        if not keep:
            continue
        e_out = _append_import_polygon(bi, n_out, e_out, s, arena.edges, arena.verts, start, k, need)
        if e_out < 0:
            return -1
        n_out += 1
    return n_out


# ---------------------------------------------------------------------------
# import (§3.6) of a cell's boundary pieces


@jit(inline="always")
def pieces_to_import(out, bi, need):
    """Convert boundary pieces (edge i runs from vertex i to i + 1) into import polygons; count or -1."""
    n = out.counts[1]
    if n + 1 > bi.support.shape[0] or out.counts[0] > bi.edges.shape[0]:
        need[0] = R_BUILD_IN
        return -1
    e = 0
    for i in range(n):
        start = out.poly[i, 0]
        k = out.poly[i, 1]
        bi.support[i] = out.poly[i, 2]
        bi.offsets[i] = e
        for j in range(k):
            # import convention: edge j runs from vertex j - 1 to vertex j
            bi.edges[e + j] = out.edge[start + (j - 1 if j > 0 else k - 1)]
            copy_point(out.vx, start + j, bi.verts, e + j)
        e += k
    bi.offsets[n] = e
    return n


@jit(inline="always")
def import_polygons(pal, bi, n, bs, seed, t, need):
    """Build the BSP of ``n`` import polygons into ``t`` (label 1 inside); its node count or -1."""
    shuffle_order(bs.order, n, seed)
    count = build_kernel(pal, bi.support[:n], bi.offsets[: n + 1], bi.edges, bi.verts, bs.order[:n], np.int64(1),
                          t.plane, t.neg, t.pos, t.label, bs.a_edges, bs.a_verts, bs.sides,
                          bs.st_node, bs.st_start, bs.st_k)
    if count == -1:
        need[0] = R_TREE_R
        return -1
    if count < 0:
        need[0] = R_BUILD
        return -1
    return count


# ---------------------------------------------------------------------------
# a cell's solid inside a box: extraction + redundancy removal


@jit(inline="always")
def boundary_in_box(pal, m, src, box, ws, need):
    """The boundary of tree ``src``'s solid inside the box whose walls are ``box`` (6 rows): the box cut down the
    tree, each in-cell's faces clipped (walls left out), the pieces written to ``ws.bi`` as import polygons.

    Returns their number (0: no boundary crosses the box interior; ``ws.ext_state[2:4]`` then say whether an in
    leaf was reached and its label), or -1 when short of room.
    """
    if not mesh_room(m, 8):
        need[0] = R_MESH
        return -1
    mesh_reset(m)
    h = add_box_cell(m, box, -1)
    st = ws.ext_state
    st[0] = 1
    st[1] = 0
    st[2] = 0
    st[3] = 0
    ws.ext_stack[0, 0] = 0
    ws.ext_stack[0, 1] = h
    ws.ext_stack[0, 2] = 6
    ws.out.counts[0] = 0
    ws.out.counts[1] = 0
    status = extract_into(m, src, ws.ext_stack, st, ws.cells, ws.sc, ws.out, np.int64(PIECES), ws.path)
    if status != DONE:
        need[0] = R_EXTRACT if status == NEED_ROOM else 0
        return -1
    if ws.out.counts[1] == 0:
        return 0
    return pieces_to_import(ws.out, ws.bi, need)


@unlinked
@borrowing_jit
def simplify_in_box(pal, m, src, box, ws, seed, need):
    """The solid of tree ``src`` inside the box whose walls are ``box`` (6 rows), rebuilt from its boundary.

    Returns (kind, value): (UNIFORM, label) when no boundary crosses the box interior,
    (BSP, nodes) with the rebuilt tree in ``ws.tr``; (-1, 0) when short of room.
    """
    n = boundary_in_box(pal, m, src, box, ws, need)
    if n < 0:
        return -1, 0
    if n == 0:
        st = ws.ext_state
        return UNIFORM, (st[3] if st[2] > 0 else 0)
    count = import_polygons(pal, ws.bi, n, ws.bs, seed, ws.tr, need)
    if count < 0:
        return -1, 0
    return BSP, count


# merge_state[4]: planes the float filter decided; [6]: merges skipped after asking first; [5]: a moving
# average (1/16 per merge, in 1/1024) of the share of cell merges that leave A unchanged. Asking first
# (merge_changes_a) costs a walk of B's cell and of A inside it before a merge that changes something,
# and saves the whole merge when nothing changes: it pays above about half (a drill's steps: 77 %
# unchanged, 17 % faster; the dome carve: 30 %, 30 % slower when always asked).
UNCHANGED_SHARE_TO_ASK = 512


@jit(inline="always")
def _note_unchanged(st, unchanged):
    x = 1024 if unchanged else 0
    st[5] += (x - st[5]) // 16


@jit(inline="always")
def _start_at_box(m, box, ms, st):
    """An empty store holding the cell's box, and a walk stack at it: the root of tree 0, output node 0."""
    mesh_reset(m)
    h = add_box_cell(m, box, -1)
    ms[0, 0] = 0
    ms[0, 1] = 0
    ms[0, 2] = 0
    ms[0, 3] = h
    ms[0, 4] = 6
    ms[0, 5] = 0
    st[0] = 1
    return h


@unlinked
@borrowing_jit
def merge_and_simplify(pal, m, ta, tb, table, constant, box, ws, seed, need):
    """A ∘ B inside the box (``table`` is the label function): merge by cutting, then redundancy removal.

    Returns (kind, value, where): UNIFORM with its label, or BSP with the node count and
    ``where`` 0 = ``ws.to`` (the merged tree: several materials) / 1 = ``ws.tr`` (rebuilt) / 2 = unchanged (the
    result is A: nothing to write) / 3 = ``ws.to`` (smaller than the rebuilt tree). After 1 and 3 the solid's
    boundary pieces are in ``ws.bi`` (``ws.out.counts[1]`` of them). (-1, 0, 0) when short of room.
    """
    if not mesh_room(m, 8):
        need[0] = R_MESH
        return -1, 0, 0
    ms = ws.merge_stack
    st = ws.merge_state
    ask_first = ws.merge_boxes.shape[0] > ms.shape[0] and st[5] > UNCHANGED_SHARE_TO_ASK
    if ask_first:
        # Ask first whether the tool changes anything here (B's cell first, then A inside it, both
        # through the float filter): most of a drill's cell merges would walk all of A to find nothing.
        h = _start_at_box(m, box, ms, st)
        cell_float_box(m, np.int64(h), ws.sc.work, ws.merge_boxes, np.int64(0))
        status = merge_changes_a(m, ta, tb, np.int64(0), table, ms, st, ws.path, ws.sc.work, ws.merge_boxes)
        if status == NEED_ROOM:
            need[0] = R_MERGE
            return -1, 0, 0
        if status != CHANGED:
            if status != DONE:
                need[0] = 0
                return -1, 0, 0
            _note_unchanged(st, True)
            st[6] += 1
            return BSP, 0, 2  # the solid is A's: nothing to write
    _start_at_box(m, box, ms, st)
    st[1] = 1
    st[2] = 0
    st[3] = 0
    status = merge_cells(m, ta, tb, np.int64(0), table, constant, ms, st, ws.to, ws.cells, ws.path, ws.sc.work,
                         np.bool_(False), ws.merge_boxes)
    if status == NEED_ROOM:
        need[0] = R_MERGE
        return -1, 0, 0
    if status != DONE:
        need[0] = 0
        return -1, 0, 0
    _note_unchanged(st, st[3] == 0)
    if st[3] == 0:
        # Every output cell kept A's label: the solid is A's, so A's tree stays (no redundancy
        # removal). A tool sliding along a wall it cut before (a drill's lands) hits this often.
        return BSP, 0, 2
    n_o = st[1]
    lab = uniform_label(ws.to, n_o)
    if lab >= 0:
        return UNIFORM, lab, 0
    if not only_in_out(ws.to, n_o):
        return BSP, n_o, 0
    # Redundancy removal: the interior faces of the merged in-cells, clipped against their
    # opposite subtrees (no new cutting: the merge left every output leaf's cell).
    ws.out.counts[0] = 0
    ws.out.counts[1] = 0
    for i in range(st[2]):
        leaf = ws.cells[i, 0]
        la = ws.to.label[leaf]
        if la == 0:
            continue
        if not clip_cell(m, np.int64(ws.cells[i, 1]), np.int64(la), ws.to, ws.sc, ws.out, np.bool_(False)):
            need[0] = R_PIECES
            return -1, 0, 0
    if ws.out.counts[1] == 0:
        # No boundary inside the box: every cell has the same label.
        return UNIFORM, ws.to.label[ws.cells[0, 0]], 0
    n = pieces_to_import(ws.out, ws.bi, need)
    if n < 0:
        return -1, 0, 0
    count = import_polygons(pal, ws.bi, n, ws.bs, seed, ws.tr, need)
    if count < 0:
        return -1, 0, 0
    if count < n_o:
        return BSP, count, 1
    return BSP, n_o, 3


# ---------------------------------------------------------------------------
# writing a cell


@jit(inline="always")
def write_cell(oc, pool, node, kind, value, t):
    """Store a cell result: UNIFORM ``value`` = label, or BSP ``value`` nodes of ``t``; False if the pool is full."""
    if oc.kind[node] == BSP:
        oc.counts[POOL_LIVE] -= oc.length[node]
    if kind == UNIFORM:
        oc.kind[node] = UNIFORM
        oc.label[node] = value
        oc.length[node] = 0
        return True
    start = oc.counts[N_POOL]
    if start + value > pool.plane.shape[0]:
        if oc.kind[node] == BSP:
            oc.counts[POOL_LIVE] += oc.length[node]
        return False
    for i in range(value):
        pool.plane[start + i] = t.plane[i]
        pool.neg[start + i] = t.neg[i]
        pool.pos[start + i] = t.pos[i]
        pool.label[start + i] = t.label[i]
    oc.counts[N_POOL] = start + value
    oc.counts[POOL_LIVE] += value
    oc.kind[node] = BSP
    oc.start[node] = start
    oc.length[node] = value
    return True


@jit(inline="always")
def cell_tree(oc, pool, node, t, need):
    """Copy cell ``node``'s solid into ``t``; its node count, or -1 when ``t`` is too small."""
    if oc.kind[node] == BSP:
        n = oc.length[node]
        if n > t.plane.shape[0]:
            need[0] = R_TREE_A
            return -1
        copy_from_pool(pool, oc.start[node], n, t, 0)
        return n
    return set_leaf(t, oc.label[node])


@jit(inline="always")
def relabel_cell(oc, pool, node, column, table, ta, need):
    """Apply ``table[., column]`` to the labels of cell ``node`` (the tool is uniform over it).

    Returns (changed, kind, value) where (kind, value) is as :func:`write_cell` takes with
    the tree in ``ta``; -1 kind when short of room.
    """
    if oc.kind[node] == UNIFORM:
        la = oc.label[node]
        lb = table[la, column]
        return lb != la, UNIFORM, lb
    n = cell_tree(oc, pool, node, ta, need)
    if n < 0:
        return False, -1, 0
    changed = False
    for i in range(n):
        if ta.plane[i] < 0:
            lb = table[ta.label[i], column]
            changed = changed or lb != ta.label[i]
            ta.label[i] = lb
    if not changed:
        return False, BSP, n
    lab = uniform_label(ta, n)
    if lab >= 0:
        return True, UNIFORM, lab
    return True, BSP, n


# ---------------------------------------------------------------------------
# one cell of a Boolean


@jit(inline="always")
def _box_corners(lo, size, corners):
    for k in range(8):
        corners[k, 0] = lo[0] + (size if k & 1 else 0)
        corners[k, 1] = lo[1] + (size if k & 2 else 0)
        corners[k, 2] = lo[2] + (size if k & 4 else 0)


@jit(inline="always")
def _centre_point(lo, size, pt):
    # (2 lo + size) / 2, homogeneous.
    for c in range(3):
        store_int64_at(pt, 0, c, 2 * lo[c] + size)
    store_int64_at(pt, 0, 3, 2)


@unlinked
@borrowing_jit
def boolean_cell(pal, oc, pool, amap, node, tool_kind, tool, cand, table, constant, ws, seed, need):
    """Apply the Boolean to one leaf cell and write its result. Returns 1 done, 0 short of room."""
    if oc.kind[node] == UNIFORM and constant[oc.label[node]] >= 0:
        # The result does not depend on the tool here (empty space under a difference, solid
        # under a union): nothing to localise or merge.
        lab = constant[oc.label[node]]
        if lab == oc.label[node]:
            oc.counts[S_UNCHANGED] += 1
        else:
            oc.label[node] = lab
            oc.counts[S_RELABELS] += 1
        return 1
    lo = oc.lo[node]
    size = oc.size[node]
    if not box_rows(amap, pal, oc, lo[0], lo[1], lo[2], size, ws.box, need):
        return 0
    _box_corners(lo, size, ws.corners)
    relation = 2
    nb = 0
    n_poly = 0
    if tool_kind == CONVEX_TOOL:
        relation, nb = convex_tool_in_box(pal, tool.rows, ws.corners, ws.tb)
        if nb < 0:
            need[0] = R_TREE_B
            return 0
    else:
        n_poly = clip_tool_polygons(pal, tool, cand, lo, size, ws.box, ws.arena, ws.bi, need)
        if n_poly < 0:
            return 0
        if n_poly == 0:
            _centre_point(lo, size, ws.point)
            tool_tree = TreeArrays(tool.t_plane, tool.t_neg, tool.t_pos, tool.t_label)
            relation = 1 if classify_perturbed(pal, tool_tree, ws.point) != 0 else 0
        else:
            nb = import_polygons(pal, ws.bi, n_poly, ws.bs, seed + 7 * node, ws.tb, need)
            if nb < 0:
                if need[0] == R_TREE_R:
                    need[0] = R_TREE_B
                return 0
    if relation != 2:
        return _relabel_whole_cell(oc, pool, node, relation, table, ws, need)
    na = cell_tree(oc, pool, node, ws.ta, need)
    if na < 0:
        return 0
    if (ws.pc.counts[PC_MODE] == PC_ON and _in_out_table(table)
            and ((oc.kind[node] == UNIFORM and oc.label[node] <= 1)
                 or (cached_pieces(ws.pc, oc, node) and only_in_out(ws.ta, na)))):
        if tool_kind == CONVEX_TOOL:
            # the hull's boundary in the cell: its facets on the crossing planes clipped to the walls, or (a tool
            # without facets) the box cut by those planes
            if tool.offsets.shape[0] > 1:
                n_poly = _hull_facets_in_box(pal, tool, nb, lo, size, ws, need)
            else:
                n_poly = boundary_in_box(pal, ws.m, ws.tb, ws.box, ws, need)
            if n_poly < 0:
                return 0
            if n_poly == 0:
                # planes cross the box but the hull's faces do not reach into it: the box lies outside the hull
                return _relabel_whole_cell(oc, pool, node, 0, table, ws, need)
        return _boundary_merge_cell(pal, oc, pool, node, n_poly, table, ws, seed + node, need)
    kind, value, where = merge_and_simplify(pal, ws.m, ws.ta, ws.tb, table, constant, ws.box, ws, seed + node, need)
    if kind < 0:
        return 0
    if where == 2:
        oc.counts[S_UNCHANGED] += 1
        return 1
    if (where == 1 or where == 3) and not piece_room(ws.pc, node, ws.bi, ws.out.counts[1], need):
        return 0
    if not write_cell(oc, pool, node, kind, value, ws.tr if where == 1 else ws.to):
        need[0] = R_POOL
        return 0
    oc.counts[S_MERGES] += 1
    if where == 1:
        oc.counts[S_SIMPLIFIED] += 1
    if where == 1 or where == 3:
        # the solid's boundary in the cell is the redundancy removal's input, still in ws.bi: the cell's next
        # Boolean with a mesh tool starts from it
        store_cell_pieces(ws.pc, oc, node, ws.bi, ws.out.counts[1])
    return 1


@jit(inline="always")
def _hull_facets_in_box(pal, tool, nb, lo, size, ws, need):
    """A convex tool's boundary in the cell box (lo, size) as import polygons in ``ws.bi``: the facets on the planes
    that cross the box (``ws.tb``'s linear tree of ``nb`` nodes, from :func:`convex_tool_in_box`; tool plane i is
    palette row ``tool.rows[0] + i``) clipped to its walls ``ws.box``. Only those facets can reach into the box: it
    lies inside every other plane. Their number, or -1 when short of room."""
    c = (nb - 1) // 2
    cand = ws.bs.order
    if c > cand.shape[0]:
        need[0] = R_BUILD_IN
        return -1
    first = tool.rows[0]
    for j in range(c):
        cand[j] = ws.tb.plane[2 * j] - first
    return clip_tool_polygons(pal, tool, cand[:c], lo, size, ws.box, ws.arena, ws.bi, need)


@jit(inline="always")
def _relabel_whole_cell(oc, pool, node, relation, table, ws, need):
    """Leaf ``node`` when the tool is uniform over it (``relation`` 0 outside, 1 inside): its labels mapped by
    ``table[., relation]``, written when they change. 1 done, 0 short of room."""
    changed, kind, value = relabel_cell(oc, pool, node, relation, table, ws.ta, need)
    if kind < 0:
        return 0
    if not changed:
        oc.counts[S_UNCHANGED] += 1
        return 1
    if not write_cell(oc, pool, node, kind, value, ws.ta):
        need[0] = R_POOL
        return 0
    oc.counts[S_RELABELS] += 1
    return 1


@jit(inline="always")
def _in_out_table(table):
    """Whether the label function maps in / out labels to in / out labels (a boundary bounds its result)."""
    if table.shape[0] < 2 or table.shape[1] < 2:
        return False
    for i in range(2):
        for j in range(2):
            if table[i, j] != 0 and table[i, j] != 1:
                return False
    return True


@jit(inline="always")
def _apart_keeps_a(table):
    """Whether the label function is the difference A - B or the union A + B of in / out labels (0 and 1): the two
    that leave A as it is where B lies wholly on the side of A's boundary it does not change (inside A for a union,
    outside for a difference)."""
    if table.shape[0] < 2 or table.shape[1] < 2 or table[0, 0] != 0 or table[1, 0] != 1:
        return False
    return (table[0, 1] == 0 and table[1, 1] == 0) or (table[0, 1] == 1 and table[1, 1] == 1)


@jit(inline="always")
def _push_failed(ws, need):
    """Translate the boundary merge's shortage into ``need[0]``."""
    short = ws.push_state[S_NEED]
    need[0] = R_PUSH_ARENA if short == NEED_ARENA else (R_PUSH_STACK if short == NEED_STACK else R_PIECES_OUT)


@jit(inline="always")
def _boundary_merge_cell(pal, oc, pool, node, n_tool, table, ws, seed, need):
    """The Boolean of leaf ``node`` (tree in ``ws.ta``, valid cached pieces) and the tool's local part (tree
    ``ws.tb``, its ``n_tool`` pieces in ``ws.bi``) from their boundaries
    (:func:`csgnb.bsp.boundary_merge.push_pieces`: the tool's pieces first, then the cell's), then one import;
    writes the cell. 1 done, 0 short.

    A difference (a union) whose tool keeps none of its boundary here -- it lies nowhere inside (outside) the cell's
    solid -- leaves the cell as it is when every cached piece has a vertex strictly outside the tool
    (:func:`csgnb.octree.piece_cache.pieces_outside`): one vertex a piece instead of all of them, no piece of the
    cell pushed -- the drill's cells along the hole's wall, which each step's tool reaches and rarely cuts, and a
    sweep's cells where the next prism lies in what earlier ones covered."""
    begin_push(ws.po, ws.push_state)
    if push_pieces(pal, ws.bi, n_tool, False, ws.ta, table, ws.po, ws.push, ws.push_state) != DONE:
        _push_failed(ws, need)
        return 0
    n_a = 0
    if oc.kind[node] == BSP:
        if (ws.push_state[S_B_KEPT] == 0 and _apart_keeps_a(table)
                and pieces_outside(pal, ws.pc, node, ws.tb, ws.pa.verts, ws.push.st_start)):
            oc.counts[S_UNCHANGED] += 1
            oc.counts[S_BOUNDARY_MERGES] += 1
            oc.counts[S_BOUNDARY_UNCHANGED] += 1
            oc.counts[S_BOUNDARY_SHORTCUTS] += 1
            return 1
        n_a = pieces_of_cell(pal, ws.pc, node, ws.pa, need)
        if n_a < 0:
            return 0
    if push_pieces(pal, ws.pa, n_a, True, ws.tb, table, ws.po, ws.push, ws.push_state) != DONE:
        _push_failed(ws, need)
        return 0
    # (statistics are counted where the cell is done: a cell short of room is done again)
    if ws.push_state[S_A_UNCHANGED] == 1:
        oc.counts[S_UNCHANGED] += 1
        oc.counts[S_BOUNDARY_MERGES] += 1
        oc.counts[S_BOUNDARY_UNCHANGED] += 1
        return 1
    n = ws.push_state[S_PIECES]
    if n == 0:
        # no boundary left in the cell: one label, the result's at any inner point
        _centre_point(oc.lo[node], oc.size[node], ws.point)
        lab = table[classify_perturbed(pal, ws.ta, ws.point), classify_perturbed(pal, ws.tb, ws.point)]
        if not write_cell(oc, pool, node, UNIFORM, lab, ws.tr):
            need[0] = R_POOL
            return 0
        oc.counts[S_MERGES] += 1
        oc.counts[S_BOUNDARY_MERGES] += 1
        return 1
    if n > ws.bs.order.shape[0]:
        need[0] = R_PIECES_OUT
        return 0
    if not piece_room(ws.pc, node, ws.po, n, need):
        return 0
    count = import_polygons(pal, ws.po, n, ws.bs, seed, ws.tr, need)
    if count < 0:
        return 0
    if not write_cell(oc, pool, node, BSP, count, ws.tr):
        need[0] = R_POOL
        return 0
    store_cell_pieces(ws.pc, oc, node, ws.po, n)
    oc.counts[S_MERGES] += 1
    oc.counts[S_SIMPLIFIED] += 1
    oc.counts[S_BOUNDARY_MERGES] += 1
    return 1


# ---------------------------------------------------------------------------
# split (Figure 8): BSP ∩ child boxes


@jit(inline="always")
def _alloc_children(oc, node):
    """Index of a free block of 8 nodes for the children of ``node`` (room checked by the caller)."""
    c = oc.counts
    if c[N_FREE_BLOCKS] > 0:
        c[N_FREE_BLOCKS] -= 1
        first = np.int64(oc.free_blocks[c[N_FREE_BLOCKS]]) * 8 + 1
    else:
        first = c[N_NODES]
        c[N_NODES] += 8
    half = oc.size[node] // 2
    for k in range(8):
        ch = first + k
        oc.child[ch] = -1
        oc.parent[ch] = node
        oc.kind[ch] = UNIFORM
        oc.label[ch] = 0
        oc.length[ch] = 0
        oc.start[ch] = 0
        oc.size[ch] = half
        oc.lo[ch, 0] = oc.lo[node, 0] + (half if k & 1 else 0)
        oc.lo[ch, 1] = oc.lo[node, 1] + (half if k & 2 else 0)
        oc.lo[ch, 2] = oc.lo[node, 2] + (half if k & 4 else 0)
    oc.child[node] = first
    return first


@unlinked
@borrowing_jit
def split_step(pal, oc, pool, amap, node, st, ws, threshold, min_size, seed, need):
    """Split cell ``node`` into its 8 children (resumable per child). Returns 1 done, 0 short of room."""
    if oc.child[node] < 0:
        if oc.counts[N_NODES] + 8 > oc.child.shape[0]:
            need[0] = R_NODES
            return 0
        _alloc_children(oc, node)
        st[ST_SPLIT_CHILD] = 0
    first = oc.child[node]
    n_src = oc.length[node]
    if n_src > ws.ta.plane.shape[0]:
        need[0] = R_TREE_A
        return 0
    copy_from_pool(pool, oc.start[node], n_src, ws.ta, 0)
    for k in range(st[ST_SPLIT_CHILD], 8):
        ch = first + k
        if not box_rows(amap, pal, oc, oc.lo[ch, 0], oc.lo[ch, 1], oc.lo[ch, 2], oc.size[ch], ws.box, need):
            return 0
        kind, value = simplify_in_box(pal, ws.m, ws.ta, ws.box, ws, seed + 8 * ch, need)
        if kind < 0:
            return 0
        if kind == BSP and value >= n_src:
            # The re-import did not shrink it: keep the parent's tree, restricted by the box.
            kind = BSP
            value = n_src
            for i in range(n_src):
                ws.tr.plane[i] = ws.ta.plane[i]
                ws.tr.neg[i] = ws.ta.neg[i]
                ws.tr.pos[i] = ws.ta.pos[i]
                ws.tr.label[i] = ws.ta.label[i]
        if kind == BSP and not piece_room(ws.pc, ch, ws.bi, ws.out.counts[1], need):
            return 0
        if not write_cell(oc, pool, ch, kind, value, ws.tr):
            need[0] = R_POOL
            return 0
        if kind == BSP:
            store_cell_pieces(ws.pc, oc, ch, ws.bi, ws.out.counts[1])  # the child's boundary, found by the import
        st[ST_SPLIT_CHILD] = k + 1
    oc.counts[POOL_LIVE] -= oc.length[node]
    oc.kind[node] = UNIFORM
    oc.length[node] = 0
    oc.counts[S_SPLITS] += 1
    st[ST_SPLIT_CHILD] = 0
    return 1


@jit(inline="always")
def _needs_split(oc, node, threshold, min_size):
    return oc.kind[node] == BSP and oc.length[node] > threshold and oc.size[node] > min_size


# ---------------------------------------------------------------------------
# the Boolean kernel


@jit(inline="always")
def _boxes_meet_open(lo, size, tlo, thi):
    """Whether the open cell box meets the open box ``(tlo, thi)``."""
    for c in range(3):
        if lo[c] >= thi[c] or lo[c] + size <= tlo[c]:
            return False
    return True


@jit(inline="always")
def _mean_extent(tool, cand, cs, cn):
    """Mean largest side of the boxes of polygons ``cand[cs:cs + cn]``."""
    total = 0
    for j in range(cs, cs + cn):
        i = cand[j]
        e = 0
        for c in range(3):
            e = max(e, tool.phi[i, c] - tool.plo[i, c])
        total += e
    return total // max(cn, 1)


@jit(inline="always")
def split_uniform(oc, node, need):
    """Split a uniform cell into 8 uniform children with its label; 0 when short of nodes."""
    if oc.counts[N_NODES] + 8 > oc.child.shape[0] and oc.counts[N_FREE_BLOCKS] == 0:
        need[0] = R_NODES
        return 0
    lab = oc.label[node]
    first = _alloc_children(oc, node)
    for k in range(8):
        oc.label[first + k] = lab
    oc.counts[S_SPLITS] += 1
    return 1


@unlinked
@jit
def _boolean_kernel(pal, oc, pool, amap, work, cand, done, tool_kind, tool, tlo, thi, table, constant, ws, st,
                    split_stack, threshold, min_size, max_polygons, seed, need):
    """Apply one Boolean to every leaf whose open box meets the open box ``(tlo, thi)`` (resumable via ``st``).

    The octree is walked from the entries of ``work`` (``(node, start, count, parent's count)`` rows,
    ``st[ST_LEAF]`` of them; the root to start with): every entry carries the indices
    ``cand[start:start + count]`` of the mesh tool's polygons whose boxes meet its cell, and
    a child keeps the subset that meets it -- a triangle octree of the tool built on the fly,
    so a cell never scans polygons far away. A leaf reached by more than ``max_polygons`` of
    them is split first (its local tool BSP stays small, as the paper's import keeps imports
    local); other leaves get the Boolean (:func:`boolean_cell`) and are recorded in ``done``.
    Cells whose BSP grows beyond ``threshold`` nodes are split until under it or down to
    ``min_size`` (then counted as pathological).
    """
    oc = unmanaged_tuple(oc)
    pool = unmanaged_tuple(pool)
    amap = unmanaged_tuple(amap)
    tool = unmanaged_tuple(tool)
    pal = unmanaged(pal)
    work = unmanaged(work)
    cand = unmanaged(cand)
    done = unmanaged(done)
    tlo = unmanaged(tlo)
    thi = unmanaged(thi)
    table = unmanaged(table)
    constant = unmanaged(constant)
    st = unmanaged(st)
    split_stack = unmanaged(split_stack)
    need = unmanaged(need)
    ws = unmanaged_workspace(ws)
    need[0] = 0
    mesh = tool_kind == MESH_TOOL
    while True:
        if st[ST_PHASE] == 1:
            while st[ST_SPLIT_TOP] > 0:
                top = st[ST_SPLIT_TOP] - 1
                if top + 8 > split_stack.shape[0]:
                    need[0] = R_SPLIT_STACK
                    return NEED_ROOM
                x = split_stack[top]
                if split_step(pal, oc, pool, amap, x, st, ws, threshold, min_size, seed, need) == 0:
                    return FAILED if need[0] == 0 else NEED_ROOM
                st[ST_SPLIT_TOP] = top
                first = oc.child[x]
                for k in range(8):
                    ch = first + k
                    if _needs_split(oc, ch, threshold, min_size):
                        split_stack[st[ST_SPLIT_TOP]] = ch
                        st[ST_SPLIT_TOP] += 1
                    elif oc.kind[ch] == BSP and oc.length[ch] > threshold:
                        oc.counts[S_PATHOLOGICAL] += 1
            st[ST_PHASE] = 0
        if st[ST_LEAF] == 0:
            break
        top = st[ST_LEAF] - 1
        node = work[top, 0]
        cs = work[top, 1]
        cn = work[top, 2]
        # Refine only while cells are larger than the polygons that reach them: below that,
        # splitting cannot separate them (each would reach every child) and would not end.
        if st[ST_REFINE] == node or (oc.child[node] < 0 and mesh and cn > max_polygons
                                     and oc.size[node] > min_size
                                     and not (oc.kind[node] == UNIFORM and constant[oc.label[node]] >= 0)
                                     and oc.size[node] > 2 * _mean_extent(tool, cand, cs, cn)):
            # too much of the tool here: split the leaf first, then walk into it (a split that ran
            # short of room is resumed: st[ST_REFINE] names it)
            st[ST_REFINE] = node
            if oc.kind[node] == BSP or oc.child[node] >= 0:
                if split_step(pal, oc, pool, amap, node, st, ws, threshold, min_size, seed, need) == 0:
                    return FAILED if need[0] == 0 else NEED_ROOM
            elif split_uniform(oc, node, need) == 0:
                return NEED_ROOM
            st[ST_REFINE] = -1
        if oc.child[node] >= 0:
            # an inner cell: its children that meet the tool, each with the polygons that reach it
            if top + 8 > work.shape[0]:
                need[0] = R_WORK
                return NEED_ROOM
            if mesh and st[ST_CAND_TOP] + 8 * cn > cand.shape[0]:
                need[0] = R_CANDIDATES
                return NEED_ROOM
            first = oc.child[node]
            w = top
            for k in range(8):
                ch = first + k
                lo = oc.lo[ch]
                size = oc.size[ch]
                if not _boxes_meet_open(lo, size, tlo, thi):
                    continue
                start = st[ST_CAND_TOP]
                n = 0
                if mesh:
                    for j in range(cs, cs + cn):
                        i = cand[j]
                        if (tool.plo[i, 0] > lo[0] + size or tool.phi[i, 0] < lo[0]
                                or tool.plo[i, 1] > lo[1] + size or tool.phi[i, 1] < lo[1]
                                or tool.plo[i, 2] > lo[2] + size or tool.phi[i, 2] < lo[2]):
                            continue
                        cand[start + n] = i
                        n += 1
                    st[ST_CAND_TOP] = start + n
                work[w, 0] = ch
                work[w, 1] = start
                work[w, 2] = n
                work[w, 3] = cn
                w += 1
            st[ST_LEAF] = w
            continue
        if st[ST_DONE] >= done.shape[0]:
            need[0] = R_WORK
            return NEED_ROOM
        if boolean_cell(pal, oc, pool, amap, node, tool_kind, tool, cand[cs:cs + cn], table, constant, ws, seed,
                        need) == 0:
            return FAILED if need[0] == 0 else NEED_ROOM
        oc.counts[S_CELL_OPS] += 1
        done[st[ST_DONE]] = node
        st[ST_DONE] += 1
        st[ST_LEAF] = top
        st[ST_PHASE] = 1
        st[ST_SPLIT_TOP] = 0
        if _needs_split(oc, node, threshold, min_size):
            split_stack[0] = node
            st[ST_SPLIT_TOP] = 1
    return DONE


# ---------------------------------------------------------------------------
# combine (Figure 8)


@unlinked
@borrowing_jit
def combine_parent(pal, oc, pool, amap, node, ws, threshold, seed, need):
    """Replace the 8 leaf children of ``node`` by one cell if their solid fits ``threshold`` nodes.

    Returns 1 combined, 2 left as it is, 0 short of room.
    """
    first = oc.child[node]
    if oc.counts[N_FREE_BLOCKS] >= oc.free_blocks.shape[0]:
        need[0] = R_NODES
        return 0
    total = 0
    lab = -2
    for k in range(8):
        ch = first + k
        if oc.child[ch] >= 0:
            return 2
        if oc.kind[ch] == BSP:
            total += oc.length[ch]
            lab = -1
        elif lab == -2:
            lab = oc.label[ch]
        elif lab != oc.label[ch]:
            lab = -1
    if lab >= 0:
        kind = UNIFORM
        value = lab
    else:
        # Hysteresis: children combine only when well below the threshold, so a region that
        # the next tool will refine again is not combined after every operation.
        if 4 * (total + 15) > threshold:
            return 2
        # The axis-BSP (COMBINE A): x, then y, then z mid planes; the children's trees below.
        half = oc.size[node] // 2
        mid = (oc.lo[node, 0] + half, oc.lo[node, 1] + half, oc.lo[node, 2] + half)
        rows = ws.axis3
        for axis in range(3):
            r = axis_plane(amap, pal, oc, axis, 1, mid[axis], need)
            if r < 0:
                return 0
            rows[axis] = r
        if total + 15 > ws.ta.plane.shape[0]:
            need[0] = R_TREE_A
            return 0
        t = ws.ta
        # nodes 0 (x), 1-2 (y), 3-6 (z); octant c = bx + 2 by + 4 bz
        t.plane[0] = rows[0]
        t.neg[0] = 1
        t.pos[0] = 2
        for bx in range(2):
            t.plane[1 + bx] = rows[1]
            t.neg[1 + bx] = 3 + 2 * bx
            t.pos[1 + bx] = 4 + 2 * bx
        for i in range(7):
            t.label[i] = -1
        base = 7
        for bx in range(2):
            for by in range(2):
                zn = 3 + 2 * bx + by
                t.plane[zn] = rows[2]
                for bz in range(2):
                    ch = first + bx + 2 * by + 4 * bz
                    root = base
                    if oc.kind[ch] == BSP:
                        copy_from_pool(pool, oc.start[ch], oc.length[ch], t, base)
                        base += oc.length[ch]
                    else:
                        t.plane[base] = -1
                        t.neg[base] = -1
                        t.pos[base] = -1
                        t.label[base] = oc.label[ch]
                        base += 1
                    if bz == 0:
                        t.neg[zn] = root
                    else:
                        t.pos[zn] = root
        if not box_rows(amap, pal, oc, oc.lo[node, 0], oc.lo[node, 1], oc.lo[node, 2], oc.size[node], ws.box, need):
            return 0
        kind, value = simplify_in_box(pal, ws.m, t, ws.box, ws, seed + node, need)
        if kind < 0:
            return 0
        if kind == BSP and value > threshold:
            return 2
    if kind == BSP and oc.counts[N_POOL] + value > pool.plane.shape[0]:
        need[0] = R_POOL
        return 0
    if kind == BSP and not piece_room(ws.pc, node, ws.bi, ws.out.counts[1], need):
        return 0
    # free the children
    for k in range(8):
        ch = first + k
        if oc.kind[ch] == BSP:
            oc.counts[POOL_LIVE] -= oc.length[ch]
        oc.kind[ch] = UNIFORM
        oc.length[ch] = 0
        oc.parent[ch] = -1
    oc.free_blocks[oc.counts[N_FREE_BLOCKS]] = (first - 1) // 8
    oc.counts[N_FREE_BLOCKS] += 1
    oc.child[node] = -1
    oc.kind[node] = UNIFORM
    oc.length[node] = 0
    write_cell(oc, pool, node, kind, value, ws.tr)
    if kind == BSP:
        store_cell_pieces(ws.pc, oc, node, ws.bi, ws.out.counts[1])
    oc.counts[S_COMBINES] += 1
    return 1


@jit(inline="always")
def combine_upwards(pal, oc, pool, amap, node, ws, threshold, seed, need):
    """Combine ``node``'s children, then its parent's, and so on while they combine; False when short of room."""
    while node >= 0 and oc.child[node] >= 0:
        r = combine_parent(pal, oc, pool, amap, node, ws, threshold, seed, need)
        if r == 0:
            return False
        if r == 2:
            break
        node = oc.parent[node]
    return True


@jit
def _combine_kernel(pal, oc, pool, amap, parents, ws, st, threshold, seed, need):
    """Try to combine each of ``parents`` (resumable via ``st[0]``); combined parents are tried upwards."""
    oc = unmanaged_tuple(oc)
    pool = unmanaged_tuple(pool)
    amap = unmanaged_tuple(amap)
    pal = unmanaged(pal)
    parents = unmanaged(parents)
    st = unmanaged(st)
    need = unmanaged(need)
    ws = unmanaged_workspace(ws)
    need[0] = 0
    while st[0] < parents.shape[0]:
        if not combine_upwards(pal, oc, pool, amap, parents[st[0]], ws, threshold, seed, need):
            return FAILED if need[0] == 0 else NEED_ROOM
        st[0] += 1
    return DONE


# ---------------------------------------------------------------------------
# queries


COMBINE_ORDER_LEAVES = 256
"""Up to this many leaves a Boolean touched, :func:`combine_order` orders their parents (an insertion sort);
beyond, NumPy does (``np.unique`` and a stable argsort: the same order)."""


@jit
def combine_order(parent, size, leaves):
    """The distinct parents (``>= 0``) of ``leaves`` in the order the combine pass visits them: smallest cell
    first, equal sizes by the larger node index first -- what ``p = np.unique(parent[leaves]); p = p[p >= 0];
    p[np.argsort(-size[p], kind="stable")[::-1]]`` gives, without its ~60 µs of NumPy calls per Boolean (an
    insertion sort: for :data:`COMBINE_ORDER_LEAVES` leaves at most). ``(p,) int64``."""
    out = np.empty(leaves.shape[0], np.int64)
    m = 0
    for i in range(leaves.shape[0]):
        p = np.int64(parent[leaves[i]])
        if p < 0:
            continue
        seen = False
        for q in range(m):
            if out[q] == p:
                seen = True
                break
        if seen:
            continue
        j = m
        while j > 0 and (size[out[j - 1]] > size[p] or (size[out[j - 1]] == size[p] and out[j - 1] < p)):
            out[j] = out[j - 1]
            j -= 1
        out[j] = p
        m += 1
    return out[:m]


@jit
def _leaves_meeting_box(oc, lo, hi, out):
    """Leaves whose open box meets the open box ``(lo, hi)``; return how many were written (or -needed)."""
    stack = np.empty(64 * 8, np.int64)
    top = 1
    stack[0] = 0
    n = 0
    while top > 0:
        top -= 1
        node = stack[top]
        s = oc.size[node]
        if (oc.lo[node, 0] >= hi[0] or oc.lo[node, 0] + s <= lo[0] or oc.lo[node, 1] >= hi[1]
                or oc.lo[node, 1] + s <= lo[1] or oc.lo[node, 2] >= hi[2] or oc.lo[node, 2] + s <= lo[2]):
            continue
        if oc.child[node] < 0:
            if n < out.shape[0]:
                out[n] = node
            n += 1
            continue
        first = oc.child[node]
        for k in range(8):
            stack[top] = first + k
            top += 1
    return n


@jit
def _leaf_list(oc, out):
    """Every leaf (depth first); return how many (``out`` must hold the node count)."""
    stack = np.empty(64 * 8, np.int64)
    top = 1
    stack[0] = 0
    n = 0
    while top > 0:
        top -= 1
        node = stack[top]
        if oc.child[node] < 0:
            out[n] = node
            n += 1
            continue
        first = oc.child[node]
        for k in range(8):
            stack[top] = first + k
            top += 1
    return n

