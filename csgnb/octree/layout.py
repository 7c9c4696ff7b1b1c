"""The octree workpiece as plain arrays (paper §3.8, §4.4): octree nodes, a BSP pool, one plane palette.

Everything a workpiece is lives in a few flat numpy arrays, so it is pickleable, saved
bit for bit, and ready for per-cell parallelism:

* **Octree nodes** (:class:`OctArrays`), ``K`` rows: ``child`` (first of 8 consecutive
  children, -1 for a leaf), ``parent``, ``kind`` (:data:`UNIFORM`: the whole cell has
  ``label``; :data:`BSP`: the cell's solid is the BSP at ``start .. start + length`` of the
  pool), ``lo`` ``(K, 3)`` int64 and ``size`` (a power of two) of the cell box. Child
  ``c`` of a cell has corner ``lo + size/2 * (c & 1, c >> 1 & 1, c >> 2 & 1)``. Freed
  child blocks go to ``free_blocks``.
* **BSP pool** (:class:`Pool`): the node arrays of every cell's BSP (``plane``, ``neg``,
  ``pos``, ``label``, int32, children relative to the BSP's first node), appended; a
  replaced BSP becomes garbage until the pool is compacted.
* **Palette** ``(P, 4)`` wide: every plane any cell uses, tool planes and cell walls; the
  walls are found again through :class:`AxisMap` (a hash of (axis, side, coordinate)).
* ``counts`` (:data:`N_COUNTS`,) int64: the rows in use of each array and statistics.

The kernels (:mod:`csgnb.octree.kernels`) take these named tuples; the Python class
:class:`csgnb.octree.Workpiece` owns them and grows them when a kernel asks
(:mod:`csgnb._resumable`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._resumable import grown
from csgnb.bsp.extract import TreeArrays

__all__ = ["AxisMap", "OctArrays", "Pool", "BSP", "UNIFORM"]

UNIFORM, BSP = 0, 1

# counts
(N_NODES, N_FREE_BLOCKS, N_POOL, N_PAL, N_AXIS, POOL_LIVE,
 S_MERGES, S_RELABELS, S_SPLITS, S_COMBINES, S_PATHOLOGICAL, S_SIMPLIFIED, S_UNCHANGED, S_CELL_OPS,
 S_BOUNDARY_MERGES, S_BOUNDARY_UNCHANGED, S_BOUNDARY_SHORTCUTS) = range(17)
N_COUNTS = 32

# resources a kernel can run short of (need[0] after NEED_ROOM)
(R_MESH, R_CLIP, R_PIECES, R_MERGE, R_TREE_A, R_TREE_B, R_TREE_O, R_TREE_R, R_BUILD_IN, R_BUILD,
 R_POOL, R_NODES, R_PALETTE, R_AXIS, R_TOOL_ARENA, R_SPLIT_STACK, R_EXTRACT,
 R_PIECES_A, R_PIECES_OUT, R_PUSH_ARENA, R_PUSH_STACK, R_PIECE_CACHE) = range(1, 23)
RESOURCE_NAMES = {R_MESH: "mesh store", R_CLIP: "clip scratch", R_PIECES: "boundary pieces", R_MERGE: "merge scratch",
                  R_TREE_A: "cell tree", R_TREE_B: "tool tree", R_TREE_O: "merged tree", R_TREE_R: "rebuilt tree",
                  R_BUILD_IN: "import polygons", R_BUILD: "import scratch", R_POOL: "BSP pool",
                  R_NODES: "octree nodes", R_PALETTE: "plane palette", R_AXIS: "wall-plane map",
                  R_TOOL_ARENA: "tool clipping", R_SPLIT_STACK: "split stack", R_EXTRACT: "extraction scratch",
                  R_PIECES_A: "cell boundary pieces", R_PIECES_OUT: "boundary merge output",
                  R_PUSH_ARENA: "boundary merge arena", R_PUSH_STACK: "boundary merge stack",
                  R_PIECE_CACHE: "boundary piece cache"}


class OctArrays(NamedTuple):
    """Octree node arrays (see the module docstring)."""

    child: np.ndarray
    parent: np.ndarray
    kind: np.ndarray
    label: np.ndarray
    start: np.ndarray
    length: np.ndarray
    lo: np.ndarray
    size: np.ndarray
    counts: np.ndarray
    free_blocks: np.ndarray


class Pool(NamedTuple):
    """The BSP pool: node arrays of every cell's BSP, ``(M,) int32`` each."""

    plane: np.ndarray
    neg: np.ndarray
    pos: np.ndarray
    label: np.ndarray


class AxisMap(NamedTuple):
    """Open-addressing hash of wall planes: ``keys (H,) int64`` (-1 empty) -> palette ``rows (H,) int32``."""

    keys: np.ndarray
    rows: np.ndarray


def new_octree(lo, size: int, nodes: int = 64) -> OctArrays:
    """One uniform **out** root cell ``[lo, lo + size]``."""
    k = max(int(nodes), 16)
    oc = OctArrays(np.full(k, -1, np.int32), np.full(k, -1, np.int32), np.zeros(k, np.int8), np.zeros(k, np.int32),
                   np.zeros(k, np.int64), np.zeros(k, np.int32), np.zeros((k, 3), np.int64), np.zeros(k, np.int64),
                   np.zeros(N_COUNTS, np.int64), np.zeros(max(k // 8, 4), np.int32))
    oc.lo[0] = np.asarray(lo, np.int64)
    oc.size[0] = int(size)
    oc.counts[N_NODES] = 1
    return oc


def grown_octree(oc: OctArrays, more: int) -> OctArrays:
    """``oc`` with room for at least ``more`` more nodes."""
    n = int(oc.counts[N_NODES])
    if n + more <= oc.child.shape[0]:
        return oc
    size = max(2 * oc.child.shape[0], n + more)
    fills = {"child": -1, "parent": -1}
    arrays = {}
    for name in ("child", "parent", "kind", "label", "start", "length", "lo", "size"):
        arrays[name] = grown(getattr(oc, name), size, fill=fills.get(name, 0))
    free_blocks = grown(oc.free_blocks, size // 8 + 1)
    return OctArrays(**arrays, counts=oc.counts, free_blocks=free_blocks)


def new_pool(nodes: int = 1024) -> Pool:
    """An empty pool with room for ``nodes`` BSP nodes."""
    return Pool(*(np.empty(max(int(nodes), 64), np.int32) for _ in range(4)))


def grown_pool(pool: Pool, used: int, more: int) -> Pool:
    """``pool`` with room for ``more`` nodes after the first ``used``."""
    if used + more <= pool.plane.shape[0]:
        return pool
    return Pool(*(grown(a, used + more) for a in pool))


def new_axis_map(size: int = 1024) -> AxisMap:
    """An empty wall-plane map (power-of-two size)."""
    h = 1 << max(int(size) - 1, 15).bit_length()
    return AxisMap(np.full(h, -1, np.int64), np.zeros(h, np.int32))


def new_tree_arrays(nodes: int) -> TreeArrays:
    """Scratch node arrays for a tree of up to ``nodes`` nodes."""
    return TreeArrays(*(np.full(max(int(nodes), 16), -1, np.int32) for _ in range(4)))


def grown_tree_arrays(t: TreeArrays, nodes: int = 0) -> TreeArrays:
    """``t`` at least twice as large (and at least ``nodes``)."""
    return TreeArrays(*(grown(a, nodes, fill=-1) for a in t))
