"""Exact BSP merge by mesh cutting, and redundancy removal (paper §3.5, §3.7).

``merge(A, B, f)`` follows §3.5: start from the box and walk A; at each inner node cut
the current convex cell by A's plane -- a proper cut gives an output node with both
children, a cut without proper intersection drops the node and continues in the child
that contains the cell. At an A-leaf with label ``la`` the cell is walked through B the
same way ("fully cut", so B's planes that miss the cell never reach the output), and
B-leaves get ``f(la, lb)``. When ``f(la, .)`` is constant over B's labels the A-leaf
becomes that leaf at once.

Every output leaf comes with its convex cell, and every cap face knows the output node
behind it, so the boundary of the result is one clipping pass away
(:func:`csgnb.bsp.extract.boundary_pieces`). Redundancy removal re-imports that
boundary (:func:`csgnb.bsp.build.bsp_from_polygons`): the same solid, usually far
fewer nodes (Figure 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb._jit import borrowing_jit, jit
from csgnb._resumable import DONE, FAILED, NEED_ROOM, grown, run_resumable
from csgnb._unlinked import unlinked
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.bsp.build import bsp_from_polygons, check_seed
from csgnb.bsp.extract import TreeArrays, boundary_pieces, check_box, check_tree, tree_arrays
from csgnb.bsp.polygon import PolygonSet
from csgnb.bsp.surface import BoundarySurface, assemble_surface
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.integral import exact_int
from csgnb.exact.wide import width_of
from csgnb.mesh.cutting import CUT_PROPER, cut_cell, cut_cell_naive
from csgnb.mesh.float_box import BOX_COLUMNS, LAZY_CUTS, box_side, cell_float_box, copy_box
from csgnb.mesh.halfedge import MeshStore, grown_mesh_arrays, room_for_cut

__all__ = ["MergeResult", "merge", "merge_changes", "merge_table", "remove_redundancy"]

# Stack columns: which tree (0 = A, 1 = B), node, label of the A-leaf above (B only),
# cell handle, bound on the cell's face count, output node.
_TREE, _NODE, _ALABEL, _HANDLE, _BOUND, _OUT = 0, 1, 2, 3, 4, 5


# Compiled once and called per merge (on unmanaged views), not inlined into each caller (issue 21).
@unlinked
@borrowing_jit
def merge_cells(m, a, b, b_offset, table, constant, stack, state, o, cells, no_path, work, naive, boxes):
    """Merge A and B cell by cell (§3.5); resumable (see :mod:`csgnb._resumable`).

    ``a``, ``b``, ``o`` are :class:`~csgnb.bsp.extract.TreeArrays` (``o`` is filled:
    the output tree, with room for ``o.plane.shape[0]`` nodes); B's palette rows are
    ``b_offset`` + its rows. ``table[la, lb]`` is the merge function, ``constant[la]``
    its value when it does not depend on lb (else -1). ``state`` = (stack size, output
    nodes, cells, cells whose label differs from A's: 0 means the result is A, B planes the
    float filter decided). Output
    leaves are recorded in ``cells`` as (output node, handle); each cap face's ``OPP`` is
    the output node on its other side. ``naive`` cuts with the classify-every-vertex
    baseline (the benchmarks' reference), which needs ``work`` (int32) as long as ``m.he``.

    ``boxes`` (``(k, BOX_COLUMNS) float64``, k > the stack's rows) turns on the float filter
    (:mod:`csgnb.mesh.float_box`): an A-leaf walked through B gets a certified box of doubles
    once ``LAZY_CUTS`` exact cuts by B's planes missed its cell, and from then on a B plane that
    certainly misses it is followed without an exact cut (a convex tool's chain of facets mostly
    misses a cell); the parts of a proper cut keep their parent's box.
    The output is the same tree with or without it. It also uses ``work`` for the cell's
    half-edges (as long as the store's half-edges in use, else that cell goes unfiltered);
    ``naive`` turns it off. Returns DONE, NEED_ROOM or FAILED.
    """
    filtering = boxes.shape[0] > stack.shape[0] and not naive
    while state[0] > 0:
        top = state[0] - 1
        ut = np.uint64(top)  # unsigned row indices: numba wraps a signed one around on every access
        in_b = stack[ut, _TREE] == 1
        node = stack[ut, _NODE]
        un = np.uint64(node)
        h = stack[ut, _HANDLE]
        bound = stack[ut, _BOUND]
        out = stack[ut, _OUT]
        plane = b.plane[un] if in_b else a.plane[un]
        if plane < 0:
            if in_b:
                la = stack[ut, _ALABEL]
                lab = table[la, b.label[un]]
            else:
                la = a.label[un]
                if constant[la] < 0:
                    stack[top, _TREE] = 1  # walk the cell through B
                    stack[top, _NODE] = 0
                    stack[top, _ALABEL] = la
                    if filtering:
                        boxes[top, 0] = np.nan  # no box yet: computed after LAZY_CUTS exact cuts missed the cell
                        boxes[top, 6] = 0.0
                    continue
                lab = constant[la]
            if lab != la:
                state[3] += 1  # an output cell whose label differs from A's there: A has changed
            if state[2] >= cells.shape[0]:
                return NEED_ROOM
            o.plane[out] = -1
            o.neg[out] = -1
            o.pos[out] = -1
            o.label[out] = lab
            cells[state[2], 0] = out
            cells[state[2], 1] = h
            state[2] += 1
            state[0] = top
            continue
        if in_b and filtering:
            if boxes[top, 0] != boxes[top, 0] and boxes[top, 6] >= LAZY_CUTS:
                cell_float_box(m, h, work, boxes, top)
                boxes[top, 6] = -np.inf  # once per cell (it may have failed: then never)
            side = box_side(m.palette, plane + b_offset, boxes, top)
            if side != 0:
                # Certainly not a proper cut: the exact cut would leave the cell on this side.
                state[4] += 1
                stack[top, _NODE] = b.neg[node] if side < 0 else b.pos[node]
                continue
        if not room_for_cut(m, bound) or top + 2 > stack.shape[0] or state[1] + 2 > o.plane.shape[0]:
            return NEED_ROOM
        row = plane + b_offset if in_b else plane
        n1 = state[1]
        n2 = n1 + 1
        if naive:
            if work.shape[0] < m.he.shape[0]:
                return NEED_ROOM
            status, ca, cb = cut_cell_naive(m, work, np.int64(h), np.int64(row), np.int64(n2), np.int64(n1))
        else:
            status, ca, cb = cut_cell(m, np.int64(h), np.int64(row), np.int64(n2), np.int64(n1), no_path)
        if status == CUT_PROPER:
            state[1] += 2
            o.plane[out] = row
            o.neg[out] = n1
            o.pos[out] = n2
            o.label[out] = -1
            child_neg = b.neg[node] if in_b else a.neg[node]
            child_pos = b.pos[node] if in_b else a.pos[node]
            for c in range(6):
                stack[top + 1, c] = stack[top, c]
            stack[top, _NODE] = child_pos
            stack[top, _HANDLE] = cb
            stack[top, _BOUND] = bound + 1
            stack[top, _OUT] = n2
            stack[top + 1, _NODE] = child_neg
            stack[top + 1, _HANDLE] = ca
            stack[top + 1, _BOUND] = bound + 1
            stack[top + 1, _OUT] = n1
            state[0] = top + 2
            if in_b and filtering:
                # Both parts keep the parent's box and count (recomputing theirs measured slower on the dome carve).
                copy_box(boxes, top, top + 1)
        elif status == 0:
            if in_b:
                if filtering:
                    boxes[top, 6] += 1.0
                stack[top, _NODE] = b.neg[node] if ca < 0 else b.pos[node]
            else:
                stack[top, _NODE] = a.neg[node] if ca < 0 else a.pos[node]
        else:
            return FAILED
    return DONE


CHANGED = 2
"""Status of :func:`merge_changes_a` when the merge changes a label of A somewhere."""


@jit(inline="always")
def _keeps_a(table, lb):
    """Whether ``table[la, lb] == la`` for every label la of A (B's leaf ``lb`` changes nothing)."""
    for la in range(table.shape[0]):
        if table[la, lb] != la:
            return False
    return True


@unlinked
@borrowing_jit
def merge_changes_a(m, a, b, b_offset, table, stack, state, no_path, work, boxes):
    """Whether merging B into A with ``table`` changes A anywhere in the cell of ``stack[0]``: B first, then A.

    The merge walks every node of A to find out; most of a drill's cell merges find nothing
    changed (its lands slide along the wall they cut), so this asks first, the other way round:
    walk B's cell; at a B-leaf whose label changes no label of A (a difference's or a union's
    outside) stop, at any other walk A inside that leaf's cell, and stop at the first A-leaf whose
    label the table changes -- a cell of positive volume (only proper cuts split cells) where the
    merge's output differs from A. Every plane of both trees first meets the float filter
    (:mod:`csgnb.mesh.float_box`; ``boxes[0]`` holds the starting cell's box). Stack columns as in
    :func:`merge_cells` (tree 0 = B here, the label column holds the B-leaf's label); ``state[0]``
    the stack size, ``state[4]`` counts filtered planes. Returns :data:`CHANGED`, DONE (nothing
    changes), NEED_ROOM or FAILED. The mesh store is left with the walk's cuts (the caller resets it).
    """
    while state[0] > 0:
        top = state[0] - 1
        in_a = stack[top, _TREE] == 1
        node = stack[top, _NODE]
        h = stack[top, _HANDLE]
        bound = stack[top, _BOUND]
        plane = a.plane[node] if in_a else b.plane[node]
        if plane < 0:
            if in_a:
                la = a.label[node]
                if table[la, stack[top, _ALABEL]] != la:
                    return CHANGED
                state[0] = top
                continue
            lb = b.label[node]
            if _keeps_a(table, lb):
                state[0] = top
                continue
            stack[top, _TREE] = 1  # walk this part of B's cell through A
            stack[top, _NODE] = 0
            stack[top, _ALABEL] = lb
            cell_float_box(m, h, work, boxes, top)
            continue
        row = plane if in_a else plane + b_offset
        side = box_side(m.palette, row, boxes, top)
        if side != 0:
            state[4] += 1
        else:
            if not room_for_cut(m, bound) or top + 2 > stack.shape[0] or top + 2 >= boxes.shape[0]:
                return NEED_ROOM
            status, ca, cb = cut_cell(m, np.int64(h), np.int64(row), np.int64(-1), np.int64(-1), no_path)
            if status == CUT_PROPER:
                for c in range(6):
                    stack[top + 1, c] = stack[top, c]
                copy_box(boxes, top, top + 1)
                stack[top, _NODE] = b.pos[node] if not in_a else a.pos[node]
                stack[top, _HANDLE] = cb
                stack[top, _BOUND] = bound + 1
                stack[top + 1, _NODE] = b.neg[node] if not in_a else a.neg[node]
                stack[top + 1, _HANDLE] = ca
                stack[top + 1, _BOUND] = bound + 1
                state[0] = top + 2
                continue
            if status != 0:
                return FAILED
            side = ca
        if in_a:
            stack[top, _NODE] = a.neg[node] if side < 0 else a.pos[node]
        else:
            stack[top, _NODE] = b.neg[node] if side < 0 else b.pos[node]
    return DONE


@jit
def _merge_kernel(m, a, b, b_offset, table, constant, stack, state, o, cells, no_path, work, naive, boxes):
    m, a, b, o = unmanaged_tuple(m), unmanaged_tuple(a), unmanaged_tuple(b), unmanaged_tuple(o)
    return merge_cells(m, a, b, b_offset, unmanaged(table), unmanaged(constant), unmanaged(stack), unmanaged(state),
                       o, unmanaged(cells), unmanaged(no_path), unmanaged(work), naive, unmanaged(boxes))


def merge_table(fn, labels_a, labels_b) -> np.ndarray:
    """Tabulate a merge function ``fn(la, lb) -> label`` over the labels that occur, ``(La, Lb) int32``.

    ``fn`` must return integer labels in ``[0, 2**31 - 1]`` (0 = out; integral floats such as
    ``1.0`` are accepted); anything else -- 0.5, None, a string, 2**40 -- raises
    :class:`GeometryError` (or ``TypeError``) naming the labels it was called with.
    """
    if not callable(fn):
        raise TypeError(f"the merge function must be callable fn(label_a, label_b) -> label, got {fn!r}")
    la_max, lb_max = int(np.max(labels_a)), int(np.max(labels_b))
    pure = getattr(fn, "pure_label_function", False) is True
    if pure and (fn, la_max, lb_max) in _PURE_TABLES:
        # csgnb's own label functions (UNION, ...) depend on the labels only: tabulated once per label range
        return _PURE_TABLES[fn, la_max, lb_max].copy()
    table = np.zeros((la_max + 1, lb_max + 1), np.int32)
    top = int(np.iinfo(np.int32).max)
    for la in range(la_max + 1):
        for lb in range(lb_max + 1):
            raw = fn(la, lb)
            try:
                value = exact_int(raw, "label")
            except TypeError:
                raise TypeError(f"the merge function returned {raw!r} ({type(raw).__name__}) for labels ({la}, {lb}); "
                                "it must return an integer label (0 = out)") from None
            except ValueError:
                raise GeometryError(f"the merge function returned {raw!r} for labels ({la}, {lb}); labels are "
                                    "integers (0 = out, k >= 1 = material k)") from None
            if value < 0:
                raise GeometryError(f"the merge function returned {value} for labels ({la}, {lb}); labels are >= 0")
            if value > top:
                raise GeometryError(f"the merge function returned {value} for labels ({la}, {lb}); labels are int32, "
                                    f"at most {top}")
            table[la, lb] = value
    if pure and len(_PURE_TABLES) < 64:
        _PURE_TABLES[fn, la_max, lb_max] = table.copy()
    return table


_PURE_TABLES: dict = {}


@dataclass
class MergeResult:
    """The merged tree with the convex cell of every output leaf.

    ``cells`` rows are (output leaf, cell handle into ``store``).
    """

    tree: BSPTree
    store: MeshStore
    cells: np.ndarray
    prefiltered: int = 0
    """B planes the float filter found missing a cell (each an exact cut not made)."""
    changed: bool = True
    """Whether some output cell's label differs from A's there (False: the result is A's solid)."""

    def boundary_pieces(self):
        """Raw boundary pieces of the merged solid (see :func:`csgnb.bsp.extract.boundary_pieces`)."""
        return boundary_pieces(self.tree, self.store, self.cells)

    def surface(self) -> BoundarySurface:
        """The exact, closed, conforming boundary of the merged solid."""
        return assemble_surface(*self.boundary_pieces())


def constant_labels(table: np.ndarray, labels_b: np.ndarray) -> np.ndarray:
    """``(La,) int32``: the value of ``table[la, .]`` when it is the same over ``labels_b``, else -1."""
    present_b = np.unique(labels_b)
    rows = table[:, present_b]
    same = (rows == rows[:, :1]).all(axis=1)
    return np.where(same, rows[:, 0], -1).astype(np.int32)


def _walk_start(a: BSPTree, b: BSPTree, lo, hi):
    """The checked start of a walk of A and B inside the box (:func:`merge`, :func:`merge_changes`): a mesh store over
    both palettes holding the box, the walk's stack at the root of tree 0, and both trees as kernel arrays."""
    check_tree(a, "a")
    check_tree(b, "b")
    lo, hi = check_box(lo, hi)
    if width_of(a.palette) != width_of(b.palette):
        raise GeometryError(f"cannot merge a {a.width}-bit BSP with a {b.width}-bit BSP: convert one first")
    # Room for the cells a merge keeps (random BSPs of 50-200 nodes: 12 vertex rows an input node, at most 15):
    # every growth copied the whole store and resumed the kernel (a third of Figure 10's time at 8 a node).
    store = MeshStore(np.concatenate([a.palette, b.palette]), capacity=256 + 16 * (a.n_nodes + b.n_nodes))
    box = store.add_box(lo, hi)
    stack = np.zeros((max(64, 2 * (a.depth() + b.depth()) + 8), 6), np.int64)
    stack[0] = (0, 0, 0, box, 6, 0)
    return store, stack, tree_arrays(a), tree_arrays(b)


def _grow_walk(store: MeshStore, arrays: dict, state: np.ndarray, *, boxes: bool, work: bool) -> None:
    """Room for the next step of a walk that asked for it: the mesh store for the top cell's cuts, the stack (and
    the float filter's boxes, one row more), the half-edge scratch as long as the store's half-edges."""
    top = int(state[0]) - 1
    bound = int(arrays["stack"][top, _BOUND]) + 2
    store.m = grown_mesh_arrays(store.m, 2 * bound, 6 * bound + 2, bound + 2, loop=bound)
    if top + 2 > arrays["stack"].shape[0]:
        arrays["stack"] = grown(arrays["stack"])
        if boxes:
            arrays["boxes"] = grown(arrays["boxes"], arrays["stack"].shape[0] + 1)
    if work and arrays["work"].shape[0] < store.he.shape[0]:
        arrays["work"] = np.empty(store.he.shape[0], np.int32)


def merge(a: BSPTree, b: BSPTree, fn, lo, hi, *, naive: bool = False, prefilter: bool = True) -> MergeResult:
    """Merge BSPs ``a`` and ``b`` with the leaf-label function ``fn(la, lb)`` inside the box ``[lo, hi]``.

    Union is ``lambda a, b: max(a, b)`` for in/out labels, intersection ``min``; any function
    of two labels (materials included) works. Both trees must have the same width, and their
    planes together with the box planes must fit its budget (checked). ``naive=True`` cuts
    with the classify-every-vertex baseline instead of edge descent (same result, slower:
    the benchmarks' reference). ``prefilter=False`` makes an exact cut for every B plane an
    A-leaf's cell meets on its walk, instead of first asking the certified float filter of
    :mod:`csgnb.mesh.float_box` (same tree; the filter is off with ``naive`` too).

    Returns
    -------
    MergeResult
        The output tree (palette = a's planes, then b's, then the box's) and its cells.
    """
    if not callable(fn):
        raise TypeError(f"the merge function must be callable fn(label_a, label_b) -> label (e.g. csgnb.bsp.UNION), "
                        f"got {fn!r}")
    store, stack, ta, tb = _walk_start(a, b, lo, hi)
    lb = b.label[b.plane < 0]
    table = merge_table(fn, a.label[a.plane < 0], lb)
    constant = constant_labels(table, lb)
    state = np.array([1, 1, 0, 0, 0], np.int64)
    cap = 4 * (a.n_nodes + b.n_nodes) + 64
    filtering = prefilter and not naive
    arrays = {"o": TreeArrays(*(np.full(cap, -1, np.int32) for _ in range(4))), "cells": np.zeros((cap, 2), np.int64),
              "stack": stack, "work": np.empty(store.he.shape[0] if naive or filtering else 0, np.int32),
              "boxes": np.empty((stack.shape[0] + 1 if filtering else 0, BOX_COLUMNS))}
    no_path = np.zeros(1, np.int64)

    def step():
        return _merge_kernel(store.m, ta, tb, a.palette.shape[0], table, constant, arrays["stack"], state,
                             arrays["o"], arrays["cells"], no_path, arrays["work"], naive, arrays["boxes"])

    def grow():
        _grow_walk(store, arrays, state, boxes=filtering, work=naive or filtering)
        if state[1] + 2 > arrays["o"].plane.shape[0]:
            arrays["o"] = TreeArrays(*(grown(x, fill=-1) for x in arrays["o"]))
        if state[2] >= arrays["cells"].shape[0]:
            arrays["cells"] = grown(arrays["cells"])

    run_resumable(step, grow, "BSP merge")
    n = int(state[1])
    o = arrays["o"]
    tree = BSPTree(store.planes.copy(), o.plane[:n], o.neg[:n], o.pos[:n], o.label[:n], validate=False)
    return MergeResult(tree, store, arrays["cells"][: int(state[2])], int(state[4]), bool(state[3] > 0))


@jit
def _changes_kernel(m, a, b, b_offset, table, stack, state, no_path, work, boxes):
    m, a, b = unmanaged_tuple(m), unmanaged_tuple(a), unmanaged_tuple(b)
    if state[0] == 1 and stack[0, _TREE] == 0 and stack[0, _NODE] == 0:
        cell_float_box(m, np.int64(stack[0, _HANDLE]), unmanaged(work), unmanaged(boxes), np.int64(0))
    return merge_changes_a(m, a, b, b_offset, unmanaged(table), unmanaged(stack), unmanaged(state),
                           unmanaged(no_path), unmanaged(work), unmanaged(boxes))


def merge_changes(a: BSPTree, b: BSPTree, fn, lo, hi) -> bool:
    """Whether ``merge(a, b, fn, lo, hi)`` differs from ``a`` somewhere inside the box (a region of positive volume).

    Walks B first and A only inside B's leaves that change a label of A (:func:`merge_changes_a`), stopping at the
    first change: what the octree asks before merging a cell (a tool that only touches the solid changes nothing).
    """
    store, stack, ta, tb = _walk_start(a, b, lo, hi)
    table = merge_table(fn, a.label[a.plane < 0], b.label[b.plane < 0])
    state = np.array([1, 0, 0, 0, 0], np.int64)
    arrays = {"stack": stack, "boxes": np.empty((stack.shape[0] + 1, BOX_COLUMNS)),
              "work": np.empty(store.he.shape[0], np.int32)}
    no_path = np.zeros(1, np.int64)
    changed = [False]

    def step():
        status = int(_changes_kernel(store.m, ta, tb, a.palette.shape[0], table, arrays["stack"], state, no_path,
                                     arrays["work"], arrays["boxes"]))
        changed[0] = status == CHANGED
        return DONE if changed[0] else status

    def grow():
        _grow_walk(store, arrays, state, boxes=True, work=True)

    run_resumable(step, grow, "BSP merge check")
    return changed[0]


def remove_redundancy(result: MergeResult, *, seed: int = 0) -> BSPTree:
    """Return a BSP of the same solid as ``result.tree``, rebuilt from its exact boundary (§3.7).

    The boundary polygons of the merge's cells are re-imported in random order (``seed``).
    The rebuilt tree is returned only when it has fewer nodes; otherwise the merged tree
    is kept, so the node count never grows. Multi-material solids (labels other than
    0 and 1) are returned unchanged: importing a boundary gives one material.
    """
    if not isinstance(result, MergeResult):
        raise TypeError(f"remove_redundancy takes the MergeResult of csgnb.bsp.merge, got {type(result).__name__}; "
                        "to simplify a solid, merge it first (BSP.merge(..., simplify=True) does both)")
    seed = check_seed(seed)
    tree = result.tree
    labels = set(np.unique(tree.label[tree.plane < 0]).tolist())
    if not labels <= {OUT, 1}:
        return tree
    palette, _, edges, polys = result.boundary_pieces()
    if polys.shape[0] == 0:
        rebuilt = BSPTree.leaf(palette[:0], OUT)
    else:
        sizes = polys[:, 1]
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32)
        # each polygon's rows polys[i, 0] + 0 .. sizes[i] - 1, in one vectorised pass (an arange a polygon cost
        # ~80 us on a 21-node merge)
        order = np.repeat(polys[:, 0].astype(np.int64) - offsets[:-1], sizes) + np.arange(int(offsets[-1]))
        polygons = PolygonSet(polys[:, 2].astype(np.int32), offsets, edges[order].astype(np.int32))
        rebuilt = bsp_from_polygons(palette, polygons, seed=seed, label=1)
    return rebuilt if rebuilt.n_nodes < tree.n_nodes else tree
