"""Each cell's exact boundary, kept beside its BSP: what the next Boolean there starts from.

A cell merge by cutting (:func:`csgnb.octree.kernels.merge_and_simplify`) re-cuts the cell's whole tree from its box
and clips every face of the result to find the boundary it re-imports -- to insert a tool's few local nodes. The
redundancy removal's input *is* the cell's boundary: convex plane-based pieces facing out of the solid. Kept, the
next Boolean there is a boundary merge (:func:`csgnb.bsp.boundary_merge.merge_boundaries`): the cell's pieces pushed
down the tool's local tree, the tool's pieces (a mesh tool's: what its import in the cell made anyway; a convex
hull's: its facets clipped to the cell, :mod:`csgnb.mesh.hull_facets`) down the cell's, then one import -- the cell
is not cut.

A cache, not part of the workpiece: an entry is valid while the cell's tree is the one it was stored with, i.e.
while ``key[node]`` equals the cell's pool start (every write of a cell's tree appends to the pool, so a start names
one tree until the pool is compacted, which re-keys the entries it keeps). Anything else -- a split, a combine, a
relabel, a merge that kept the merged tree, a loaded file -- leaves the cell without an entry, and its next merge
cuts as before and stores the boundary its redundancy removal imports.

Arrays (:class:`PieceCache`): per octree node ``key`` (int64, -1: none), ``start`` (int64) and ``length`` (int32,
rows); ``rows`` (int32) holds each piece as its signed support row followed by its ``k`` edge planes (palette rows),
``size`` (int32) holds ``k`` at the support's row and 0 at the edges'; ``counts`` = (rows used, the cache's mode).
A kernel short of room asks for more (``R_PIECE_CACHE``) before it writes the cell, so every entry is stored
whatever the arrays' sizes: the trees never depend on them.

Saved with the workpiece (:meth:`csgnb.octree.Workpiece.save`: ``oc_pieces``, the rows of each BSP cell's entry,
``pieces_rows`` and ``pieces_size`` in cell order): the cache decides how the next Booleans build their trees, so a
run resumed from a checkpoint stays identical to one that was never interrupted.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb._resumable import grown
from csgnb.bsp.boundary_merge import strictly_outside
from csgnb.exact.intrinsics import intersect_into
from csgnb.octree.layout import BSP, R_PIECE_CACHE, R_PIECES_A

__all__ = ["PieceCache", "new_piece_cache", "grown_piece_cache", "compacted_piece_cache", "rekeyed_piece_cache",
           "valid_entries", "cached_pieces", "pieces_of_cell", "pieces_outside", "piece_room", "store_cell_pieces",
           "USED", "MODE", "OFF", "WAITING", "ON", "MODE_NAMES"]

#: counts: rows used (live or not: the valid entries' rows are counted when room is needed), the cache's mode
USED, MODE = 0, 1
#: Modes: never store (off); store from the first Boolean on (waiting: a workpiece built or loaded and only looked
#: at pays nothing for it); store (on).
OFF, WAITING, ON = 0, 1, 2
MODE_NAMES = ("off", "waiting", "on")


class PieceCache(NamedTuple):
    """The cells' boundary pieces (see the module docstring)."""

    key: np.ndarray
    start: np.ndarray
    length: np.ndarray
    rows: np.ndarray
    size: np.ndarray
    counts: np.ndarray


def new_piece_cache(nodes: int = 64, rows: int = 4096, *, mode: int = WAITING) -> PieceCache:
    """An empty cache for ``nodes`` octree nodes in ``mode`` (:data:`OFF`: never stores, so every merge cuts)."""
    k = max(int(nodes), 16)
    r = max(int(rows), 256)
    return PieceCache(np.full(k, -1, np.int64), np.zeros(k, np.int64), np.zeros(k, np.int32),
                      np.empty(r, np.int32), np.empty(r, np.int32), np.array([0, int(mode)], np.int64))


def grown_piece_cache(pc: PieceCache, nodes: int, rows: int) -> PieceCache:
    """``pc`` with room for at least ``nodes`` octree nodes and ``rows`` rows."""
    if nodes > pc.key.shape[0]:
        pc = pc._replace(key=grown(pc.key, nodes, fill=-1), start=grown(pc.start, nodes, fill=0),
                         length=grown(pc.length, nodes, fill=0))
    if rows > pc.rows.shape[0]:
        pc = pc._replace(rows=grown(pc.rows, rows), size=grown(pc.size, rows))
    return pc


def valid_entries(pc: PieceCache, oc) -> np.ndarray:
    """The octree nodes whose entry is valid ``(k,) int64``: leaves holding the tree their pieces were stored with."""
    k = min(pc.key.shape[0], int(oc.child.shape[0]))
    key = pc.key[:k]
    ok = (key >= 0) & (oc.child[:k] < 0) & (oc.kind[:k] == BSP) & (key == oc.start[:k]) & (pc.length[:k] > 0)
    return np.flatnonzero(ok)


def compacted_piece_cache(pc: PieceCache, oc, extra_rows: int = 0) -> PieceCache:
    """The valid entries back to back (one gather), room for ``extra_rows`` more; the others dropped."""
    cells = valid_entries(pc, oc)
    lengths = pc.length[cells].astype(np.int64)
    total = int(lengths.sum())
    new_start = np.zeros(cells.shape[0], np.int64)
    np.cumsum(lengths[:-1], out=new_start[1:])
    src = np.repeat(pc.start[cells] - new_start, lengths) + np.arange(total)
    cap = max(4096, 2 * (total + int(extra_rows)))
    rows = np.empty(cap, np.int32)
    size = np.empty(cap, np.int32)
    rows[:total] = pc.rows[src]
    size[:total] = pc.size[src]
    key = np.full(pc.key.shape[0], -1, np.int64)
    key[cells] = pc.key[cells]
    start = np.zeros_like(pc.start)
    start[cells] = new_start
    length = np.zeros_like(pc.length)
    length[cells] = pc.length[cells]
    return PieceCache(key, start, length, rows, size, np.array([total, pc.counts[MODE]], np.int64))


def rekeyed_piece_cache(pc: PieceCache, cells: np.ndarray, old_start: np.ndarray, new_start: np.ndarray) -> None:
    """After a compaction of the BSP pool moved cell ``cells[i]`` from ``old_start[i]`` to ``new_start[i]``: the
    entries stored with those trees follow them, every other entry is dropped (in place)."""
    k = pc.key.shape[0]
    inside = cells < k
    cells, old_start, new_start = cells[inside], old_start[inside], new_start[inside]
    keep = pc.key[cells] == old_start
    key = np.full(k, -1, np.int64)
    key[cells[keep]] = new_start[keep]
    pc.key[:] = key


@jit(inline="always")
def cached_pieces(pc, oc, node):
    """Whether leaf ``node`` has valid boundary pieces in the cache."""
    return (node < pc.key.shape[0] and oc.kind[node] == BSP and pc.key[node] == oc.start[node]
            and pc.length[node] > 0)


@jit(inline="always")
def pieces_of_cell(pal, pc, node, p, need):
    """Write cell ``node``'s pieces into ``p`` (a :class:`~csgnb.bsp.boundary_merge.PieceArrays`), vertices
    computed (support ∩ edge j ∩ edge j + 1); their number, or -1 when ``p`` is short (``need[0]`` set)."""
    r = pc.start[node]
    end = r + pc.length[node]
    n = 0
    e = 0
    p.offsets[0] = 0
    while r < end:
        k = pc.size[r]
        if n + 2 > p.offsets.shape[0] or n + 1 > p.support.shape[0] or e + k > p.edges.shape[0]:
            need[0] = R_PIECES_A
            return -1
        s = pc.rows[r]
        srow = s if s >= 0 else ~s
        p.support[n] = s
        for j in range(k):
            p.edges[e + j] = pc.rows[r + 1 + j]
        for j in range(k):
            nxt = j + 1 if j + 1 < k else 0
            intersect_into(pal, srow, pal, p.edges[e + j], pal, p.edges[e + nxt], p.verts, e + j)
        e += k
        n += 1
        p.offsets[n] = e
        r += k + 1
    return n


@jit(inline="always")
def pieces_outside(pal, pc, node, t, v, stack):
    """Whether every cached piece of cell ``node`` has a vertex strictly outside the solid of tree ``t``
    (:func:`csgnb.bsp.boundary_merge.strictly_outside`; its vertices computed one at a time into ``v[0]``, a
    wide (>= 1, 4) row, until one is). False as soon as a piece has none.

    With the tool's boundary nowhere inside the cell's solid, this proves that a difference leaves the cell as it
    is, at one vertex a piece: each component of the solid in the cell is behind some piece and meets no point of
    the tool's boundary, so it lies wholly inside the tool or wholly outside -- outside, since a point near that
    vertex behind the piece is. With the tool's boundary nowhere outside the solid, the same for a union: each
    component of the cell's empty space is in front of some piece, so wholly outside the tool."""
    r = pc.start[node]
    end = r + pc.length[node]
    while r < end:
        k = pc.size[r]
        s = pc.rows[r]
        srow = s if s >= 0 else ~s
        found = False
        for j in range(k):
            nxt = j + 1 if j + 1 < k else 0
            intersect_into(pal, srow, pal, pc.rows[r + 1 + j], pal, pc.rows[r + 1 + nxt], v, 0)
            if strictly_outside(pal, v, 0, t, stack):
                found = True
                break
        if not found:
            return False
        r += k + 1
    return True


@jit(inline="always")
def piece_room(pc, node, p, n, need):
    """Whether the cache can take pieces ``p[:n]`` for leaf ``node``; else ``need[0] = R_PIECE_CACHE`` (checked
    before the cell is written, so that the caller can stop and be run again: an entry is never left out for want
    of room, which would make the trees depend on array sizes)."""
    if pc.counts[MODE] != ON:
        return True
    if node >= pc.key.shape[0] or pc.counts[USED] + p.offsets[n] - p.offsets[0] + n > pc.rows.shape[0]:
        need[0] = R_PIECE_CACHE
        return False
    return True


@jit(inline="always")
def store_cell_pieces(pc, oc, node, p, n):
    """Store pieces ``p[:n]`` as the boundary of leaf ``node``'s current tree (written just before; room checked
    by :func:`piece_room` before that)."""
    if pc.counts[MODE] != ON:
        return
    total = p.offsets[n] - p.offsets[0] + n
    used = pc.counts[USED]
    r = used
    for i in range(n):
        e0 = p.offsets[i]
        k = p.offsets[i + 1] - e0
        pc.rows[r] = p.support[i]
        pc.size[r] = k
        for j in range(k):
            pc.rows[r + 1 + j] = p.edges[e0 + j]
            pc.size[r + 1 + j] = 0
        r += k + 1
    pc.key[node] = oc.start[node]
    pc.start[node] = used
    pc.length[node] = total
    pc.counts[USED] = used + total
