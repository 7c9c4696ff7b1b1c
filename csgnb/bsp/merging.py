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

from .._jit import jit
from ..errors import GeometryError, InternalError
from ..exact.integral import exact_int
from ..exact.wide import width_of
from ..mesh.cutting import CUT_PROPER, _cut_kernel, _room_for_cut
from ..mesh.halfedge import MeshStore
from .build import bsp_from_polygons
from .extract import _grow, _room_for_next_cut, boundary_pieces
from .polygon import PolygonSet
from .surface import BoundarySurface, assemble_surface
from .tree import OUT, BSPTree

__all__ = ["MergeResult", "merge", "merge_table", "remove_redundancy"]

_NEED_MORE_ROOM, _DONE, _FAILED = 1, 0, -1
# Stack columns: which tree (0 = A, 1 = B), node, label of the A-leaf above (B only),
# cell handle, bound on the cell's face count, output node.
_TREE, _NODE, _ALABEL, _HANDLE, _BOUND, _OUT = 0, 1, 2, 3, 4, 5


@jit
def _merge_kernel(palette, vx, he, fc, vmark, vdot, counts, loop_v, loop_h,
                  a_plane, a_neg, a_pos, a_label, b_plane, b_neg, b_pos, b_label, b_offset,
                  table, constant, stack, state, o_plane, o_neg, o_pos, o_label, cells):
    """Merge A and B cell by cell; resumable like :func:`csgnb.bsp.extract._cells_kernel`.

    ``table[la, lb]`` is the merge function, ``constant[la]`` its value when it does not
    depend on lb (else -1). ``state`` = (stack size, output nodes, cells). Output leaves
    are recorded in ``cells`` as (output node, handle). Returns 0 done, 1 grow, -1 error.
    """
    no_path = np.zeros(1, np.int64)
    while state[0] > 0:
        top = state[0] - 1
        in_b = stack[top, _TREE] == 1
        node = stack[top, _NODE]
        h = stack[top, _HANDLE]
        bound = stack[top, _BOUND]
        out = stack[top, _OUT]
        plane = b_plane[node] if in_b else a_plane[node]
        if plane < 0:
            if in_b:
                lab = table[stack[top, _ALABEL], b_label[node]]
            else:
                la = a_label[node]
                if constant[la] < 0:
                    stack[top, _TREE] = 1  # walk the cell through B
                    stack[top, _NODE] = 0
                    stack[top, _ALABEL] = la
                    continue
                lab = constant[la]
            if state[2] >= cells.shape[0]:
                return _NEED_MORE_ROOM
            o_plane[out] = -1
            o_neg[out] = -1
            o_pos[out] = -1
            o_label[out] = lab
            cells[state[2], 0] = out
            cells[state[2], 1] = h
            state[2] += 1
            state[0] = top
            continue
        if (not _room_for_cut(counts, vx, he, fc, loop_v, bound) or top + 2 > stack.shape[0]
                or state[1] + 2 > o_plane.shape[0]):
            return _NEED_MORE_ROOM
        row = plane + b_offset if in_b else plane
        n1 = state[1]
        n2 = n1 + 1
        status, a, b = _cut_kernel(palette, vx, he, fc, vmark, vdot, counts, loop_v, loop_h, h, row, n2, n1, no_path)
        if status == CUT_PROPER:
            state[1] += 2
            o_plane[out] = row
            o_neg[out] = n1
            o_pos[out] = n2
            o_label[out] = -1
            child_neg = b_neg[node] if in_b else a_neg[node]
            child_pos = b_pos[node] if in_b else a_pos[node]
            for c in range(6):
                stack[top + 1, c] = stack[top, c]
            stack[top, _NODE] = child_pos
            stack[top, _HANDLE] = b
            stack[top, _BOUND] = bound + 1
            stack[top, _OUT] = n2
            stack[top + 1, _NODE] = child_neg
            stack[top + 1, _HANDLE] = a
            stack[top + 1, _BOUND] = bound + 1
            stack[top + 1, _OUT] = n1
            state[0] = top + 2
        elif status == 0:
            if in_b:
                stack[top, _NODE] = b_neg[node] if a < 0 else b_pos[node]
            else:
                stack[top, _NODE] = a_neg[node] if a < 0 else a_pos[node]
        else:
            return _FAILED
    return _DONE


def merge_table(fn, labels_a, labels_b) -> np.ndarray:
    """Tabulate a merge function ``fn(la, lb) -> label`` over the labels that occur, ``(La, Lb) int32``.

    ``fn`` must return integer labels in ``[0, 2**31 - 1]`` (0 = out; integral floats such as
    ``1.0`` are accepted); anything else -- 0.5, None, a string, 2**40 -- raises
    :class:`GeometryError` (or ``TypeError``) naming the labels it was called with.
    """
    if not callable(fn):
        raise TypeError(f"the merge function must be callable fn(label_a, label_b) -> label, got {fn!r}")
    la_max, lb_max = int(max(labels_a)), int(max(labels_b))
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
    return table


@dataclass
class MergeResult:
    """The merged tree with the convex cell of every output leaf.

    ``cells`` rows are (output leaf, cell handle into ``store``).
    """

    tree: BSPTree
    store: MeshStore
    cells: np.ndarray

    def boundary_pieces(self):
        """Raw boundary pieces of the merged solid (see :func:`csgnb.bsp.extract.boundary_pieces`)."""
        return boundary_pieces(self.tree, self.store, self.cells)

    def surface(self) -> BoundarySurface:
        """The exact, closed, conforming boundary of the merged solid."""
        return assemble_surface(*self.boundary_pieces())


def merge(a: BSPTree, b: BSPTree, fn, lo, hi) -> MergeResult:
    """Merge BSPs ``a`` and ``b`` with the leaf-label function ``fn(la, lb)`` inside the box ``[lo, hi]``.

    Union is ``lambda a, b: max(a, b)`` for in/out labels, intersection ``min``; any function
    of two labels (materials included) works. Both trees must have the same width, and their
    planes together with the box planes must fit its budget (checked).

    Returns
    -------
    MergeResult
        The output tree (palette = a's planes, then b's, then the box's) and its cells.
    """
    if width_of(a.palette) != width_of(b.palette):
        raise GeometryError(f"cannot merge a {a.width}-bit BSP with a {b.width}-bit BSP: convert one first")
    palette = np.concatenate([a.palette, b.palette])
    store = MeshStore(palette, capacity=1024)
    box = store.add_box(lo, hi)
    la = a.label[a.plane < 0]
    lb = b.label[b.plane < 0]
    table = merge_table(fn, la, lb)
    present_b = np.unique(lb)
    constant = np.full(table.shape[0], -1, np.int32)
    for label in range(table.shape[0]):
        values = np.unique(table[label, present_b])
        if values.shape[0] == 1:
            constant[label] = values[0]
    stack = np.zeros((64, 6), np.int64)
    stack[0] = (0, 0, 0, box, 6, 0)
    state = np.array([1, 1, 0], np.int64)
    cap = 64
    o_plane, o_neg, o_pos, o_label = (np.full(cap, -1, np.int32) for _ in range(4))
    cells = np.zeros((32, 2), np.int64)
    loop_v = np.empty(64, np.int64)
    loop_h = np.empty(64, np.int64)
    while True:
        status = _merge_kernel(store.palette, store.vx, store.he, store.fc, store.vmark, store.vdot, store.counts,
                               loop_v, loop_h, a.plane, a.neg, a.pos, a.label, b.plane, b.neg, b.pos, b.label,
                               a.palette.shape[0], table, constant, stack, state, o_plane, o_neg, o_pos, o_label,
                               cells)
        if status == _DONE:
            break
        if status == _FAILED:
            raise InternalError("cutting found an inconsistent half-edge mesh during a merge"
                                " (a bug in csgnb: please report it)")
        stack, loop_v, loop_h = _room_for_next_cut(store, stack, _BOUND, int(state[0]) - 1, loop_v, loop_h)
        if state[1] + 2 > o_plane.shape[0]:
            o_plane, o_neg, o_pos, o_label = (_grow(x, -1) for x in (o_plane, o_neg, o_pos, o_label))
        if state[2] >= cells.shape[0]:
            cells = _grow(cells)
    n = int(state[1])
    tree = BSPTree(store.planes.copy(), o_plane[:n], o_neg[:n], o_pos[:n], o_label[:n])
    return MergeResult(tree, store, cells[: int(state[2])])


def remove_redundancy(result: MergeResult, *, seed: int = 0) -> BSPTree:
    """Return a BSP of the same solid as ``result.tree``, rebuilt from its exact boundary (§3.7).

    The boundary polygons of the merge's cells are re-imported in random order (``seed``).
    The rebuilt tree is returned only when it has fewer nodes; otherwise the merged tree
    is kept, so the node count never grows. Multi-material solids (labels other than
    0 and 1) are returned unchanged: importing a boundary gives one material.
    """
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
        order = np.concatenate([np.arange(s, s + k) for s, k in zip(polys[:, 0], sizes, strict=True)])
        polygons = PolygonSet(polys[:, 2].astype(np.int32), offsets, edges[order].astype(np.int32))
        rebuilt = bsp_from_polygons(palette, polygons, seed=seed, label=1)
    return rebuilt if rebuilt.n_nodes < tree.n_nodes else tree
