"""Scratch of the octree kernels: one :class:`Workspace` reused by every cell of every Boolean.

The per-cell problems are small (cell BSPs below the threshold, a tool's local part), so
after the first few operations nothing grows: a Boolean allocates nothing. When a kernel
runs short (``NEED_ROOM`` with a resource code, :mod:`csgnb.octree.layout`), :func:`grow`
enlarges that part and the kernel resumes.

Also the tool as kernels see it (:class:`ToolArrays`): a convex tool is its outward palette
rows; a mesh tool is plane-based polygons with exact vertices and integer boxes, plus a
BSP of the whole tool for classifying cells its surface does not reach.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb._resumable import grown
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.bsp.boundary_merge import PieceArrays, PushScratch, new_push_scratch
from csgnb.bsp.extract import (
    ClipScratch,
    Pieces,
    TreeArrays,
    grown_clip_scratch,
    grown_pieces,
    new_clip_scratch,
    new_pieces,
)
from csgnb.mesh.float_box import BOX_COLUMNS
from csgnb.mesh.halfedge import STAMP, MeshArrays, grown_mesh_arrays, new_mesh_arrays
from csgnb.octree.layout import (
    R_BUILD,
    R_BUILD_IN,
    R_CLIP,
    R_EXTRACT,
    R_MERGE,
    R_MESH,
    R_PIECES,
    R_PIECES_A,
    R_PIECES_OUT,
    R_PUSH_ARENA,
    R_PUSH_STACK,
    R_TOOL_ARENA,
    R_TREE_A,
    R_TREE_B,
    R_TREE_O,
    R_TREE_R,
    grown_tree_arrays,
    new_tree_arrays,
)
from csgnb.octree.piece_cache import PieceCache, new_piece_cache

__all__ = ["ImportInput", "BuildScratch", "ToolArena", "ToolArrays", "Workspace", "new_workspace", "grow"]


#: Plane-based polygons to import: ``support``, ``offsets``, ``edges`` (int32), ``verts (m, 4)`` wide -- the
#: boundary merge's pieces (one type: a tool's pieces in a cell are both).
ImportInput = PieceArrays


class BuildScratch(NamedTuple):
    """Scratch of :func:`csgnb.bsp.build.build_kernel` (insertion order, piece arena, work stack)."""

    order: np.ndarray
    a_edges: np.ndarray
    a_verts: np.ndarray
    sides: np.ndarray
    st_node: np.ndarray
    st_start: np.ndarray
    st_k: np.ndarray


class ToolArena(NamedTuple):
    """Scratch for clipping one tool polygon to a box: three regions of ``edges``/``verts``, ``sides``."""

    edges: np.ndarray
    verts: np.ndarray
    sides: np.ndarray


class ToolArrays(NamedTuple):
    """A tool as the kernels see it (all planes are palette rows).

    rows : (k,) int64 -- outward planes of a convex tool (empty for a mesh tool);
    support, offsets, edges : int32, verts : (m, 4) wide -- a mesh tool's polygons;
    plo, phi : (n, 3) int64 -- integer boxes holding each polygon;
    t_plane, t_neg, t_pos, t_label : int32 -- a BSP of the whole tool (point classification).
    """

    rows: np.ndarray
    support: np.ndarray
    offsets: np.ndarray
    edges: np.ndarray
    verts: np.ndarray
    plo: np.ndarray
    phi: np.ndarray
    t_plane: np.ndarray
    t_neg: np.ndarray
    t_pos: np.ndarray
    t_label: np.ndarray


class Workspace(NamedTuple):
    """Every scratch array of the octree kernels (see the module docstring)."""

    m: MeshArrays
    sc: ClipScratch
    out: Pieces
    bi: ImportInput
    bs: BuildScratch
    arena: ToolArena
    ta: TreeArrays
    tb: TreeArrays
    to: TreeArrays
    tr: TreeArrays
    box: np.ndarray
    corners: np.ndarray
    axis3: np.ndarray
    point: np.ndarray
    cells: np.ndarray
    merge_stack: np.ndarray
    merge_state: np.ndarray
    merge_boxes: np.ndarray
    ext_stack: np.ndarray
    ext_state: np.ndarray
    path: np.ndarray
    pa: PieceArrays
    po: PieceArrays
    push: PushScratch
    push_state: np.ndarray
    pc: PieceCache


@jit(inline="always")
def unmanaged_workspace(ws):
    """``ws`` with every array replaced by its unmanaged view (:mod:`csgnb._views`)."""
    return Workspace(unmanaged_tuple(ws.m), unmanaged_tuple(ws.sc), unmanaged_tuple(ws.out), unmanaged_tuple(ws.bi),
                     unmanaged_tuple(ws.bs), unmanaged_tuple(ws.arena), unmanaged_tuple(ws.ta),
                     unmanaged_tuple(ws.tb), unmanaged_tuple(ws.to), unmanaged_tuple(ws.tr), unmanaged(ws.box),
                     unmanaged(ws.corners), unmanaged(ws.axis3), unmanaged(ws.point),
                     unmanaged(ws.cells), unmanaged(ws.merge_stack), unmanaged(ws.merge_state),
                     unmanaged(ws.merge_boxes), unmanaged(ws.ext_stack), unmanaged(ws.ext_state), unmanaged(ws.path),
                     unmanaged_tuple(ws.pa), unmanaged_tuple(ws.po), unmanaged_tuple(ws.push),
                     unmanaged(ws.push_state), unmanaged_tuple(ws.pc))


def _import_input(dtype, polygons: int, edges: int) -> ImportInput:
    return ImportInput(np.zeros(polygons + 1, np.int32), np.zeros(polygons + 1, np.int32), np.zeros(edges, np.int32),
                       np.zeros((edges, 4), dtype))


def _piece_arrays(dtype, pieces: int, edges: int) -> PieceArrays:
    return PieceArrays(np.zeros(pieces + 1, np.int32), np.zeros(pieces + 1, np.int32), np.zeros(edges, np.int32),
                       np.zeros((edges, 4), dtype))


def _grown_piece_arrays(p: PieceArrays) -> PieceArrays:
    return PieceArrays(grown(p.support), grown(p.offsets), grown(p.edges), grown(p.verts))


def _build_scratch(dtype, polygons: int, arena: int, stack: int) -> BuildScratch:
    return BuildScratch(np.zeros(polygons, np.int32), np.zeros(arena, np.int32), np.zeros((arena, 4), dtype),
                        np.zeros(arena, np.int8), np.zeros(stack, np.int32), np.zeros(stack, np.int32),
                        np.zeros(stack, np.int32))


def new_workspace(palette: np.ndarray, threshold: int) -> Workspace:
    """A workspace sized for cells of about ``threshold`` BSP nodes over ``palette`` (the octree's palette)."""
    dtype = palette.dtype
    t = max(int(threshold), 16)
    m = new_mesh_arrays(palette[:0], 64 * t, loop=4 * t)
    m = m._replace(palette=palette)
    return Workspace(
        m=m,
        sc=new_clip_scratch(dtype),
        out=new_pieces(dtype, 64 * t, 16 * t),
        bi=_import_input(dtype, 16 * t, 64 * t),
        bs=_build_scratch(dtype, 16 * t, 256 * t, 16 * t),
        arena=ToolArena(np.zeros(3 * 64, np.int32), np.zeros((3 * 64, 4), dtype), np.zeros(64, np.int8)),
        ta=new_tree_arrays(8 * t), tb=new_tree_arrays(8 * t), to=new_tree_arrays(64 * t), tr=new_tree_arrays(32 * t),
        box=np.zeros(6, np.int64), corners=np.zeros((8, 3), np.int64), axis3=np.zeros(3, np.int64),
        point=np.zeros((1, 4), dtype),
        cells=np.zeros((64 * t, 2), np.int64), merge_stack=np.zeros((16 * t, 6), np.int64),
        merge_state=np.zeros(7, np.int64), merge_boxes=np.zeros((16 * t + 1, BOX_COLUMNS)),
        ext_stack=np.zeros((16 * t, 3), np.int64), ext_state=np.zeros(4, np.int64),
        path=np.zeros(1, np.int64),
        pa=_piece_arrays(dtype, 16 * t, 64 * t),
        po=_piece_arrays(dtype, 16 * t, 64 * t),
        push=new_push_scratch(dtype, 64 * t, 16 * t),
        push_state=np.zeros(5, np.int64),
        pc=new_piece_cache(),
    )


def with_palette(ws: Workspace, palette: np.ndarray) -> Workspace:
    """``ws`` over a new palette array (after the palette grew)."""
    return ws._replace(m=ws.m._replace(palette=palette))


def sharing_scratch(shared: Workspace, own: Workspace, palette: np.ndarray) -> Workspace:
    """``shared``'s scratch arrays for a workpiece whose own state is in ``own`` (workpieces of one process taking
    turns with one scratch): over its ``palette``, with its cells' boundary cache (``pc``: keyed by its octree
    nodes and naming its palette rows, another workpiece's entries would read as its own cells' boundaries) and
    its merge statistics (``merge_state``)."""
    return with_palette(shared, palette)._replace(pc=own.pc, merge_state=own.merge_state)


def _grown_mesh(m: MeshArrays) -> MeshArrays:
    """A larger, empty mesh store (the kernel empties it before each cell anyway).

    The stamp counter is carried over: the copied rows hold stamps up to its value, and a
    counter started again from zero would meet them (a skipped half-edge, a stale side).
    """
    v = m.vx.shape[0]
    counts = np.zeros_like(m.counts)
    counts[STAMP] = m.counts[STAMP]
    return grown_mesh_arrays(m._replace(counts=counts), 2 * v, 8 * v, 4 * v, loop=2 * m.loop.shape[0])


def grow(ws: Workspace, resource: int) -> Workspace:
    """``ws`` with the part named by ``resource`` enlarged (geometrically)."""
    if resource == R_MESH:
        return ws._replace(m=_grown_mesh(ws.m))
    if resource in (R_CLIP, R_PIECES, R_EXTRACT):
        sc = grown_clip_scratch(ws.sc)
        out = grown_pieces(ws.out, 2 * ws.out.vx.shape[0], 2 * ws.out.poly.shape[0])
        ws = ws._replace(sc=sc, out=out, ext_stack=grown(ws.ext_stack), cells=grown(ws.cells))
        if resource == R_EXTRACT:
            ws = ws._replace(m=_grown_mesh(ws.m))
        return ws
    if resource == R_MERGE:
        return ws._replace(m=_grown_mesh(ws.m), merge_stack=grown(ws.merge_stack),
                           merge_boxes=grown(ws.merge_boxes, 2 * ws.merge_stack.shape[0] + 1)
                           if ws.merge_boxes.shape[0] else ws.merge_boxes,  # empty: the float filter is off
                           to=grown_tree_arrays(ws.to), cells=grown(ws.cells))
    if resource == R_TREE_A:
        return ws._replace(ta=grown_tree_arrays(ws.ta), ext_stack=grown(ws.ext_stack))
    if resource == R_TREE_B:
        return ws._replace(tb=grown_tree_arrays(ws.tb))
    if resource == R_TREE_O:
        return ws._replace(to=grown_tree_arrays(ws.to))
    if resource == R_TREE_R:
        return ws._replace(tr=grown_tree_arrays(ws.tr))
    if resource == R_BUILD_IN:
        bi = ws.bi
        return ws._replace(bi=ImportInput(grown(bi.support), grown(bi.offsets), grown(bi.edges), grown(bi.verts)),
                           bs=ws.bs._replace(order=grown(ws.bs.order)))
    if resource == R_BUILD:
        return ws._replace(bs=BuildScratch(*(grown(a) for a in ws.bs)))
    if resource == R_TOOL_ARENA:
        a = ws.arena
        return ws._replace(arena=ToolArena(grown(a.edges), grown(a.verts), grown(a.sides)))
    if resource == R_PIECES_A:
        return ws._replace(pa=_grown_piece_arrays(ws.pa))
    if resource == R_PIECES_OUT:
        # the import of the result reads it: its order array grows with it
        return ws._replace(po=_grown_piece_arrays(ws.po), bs=ws.bs._replace(order=grown(ws.bs.order)))
    if resource == R_PUSH_ARENA:
        u = ws.push
        return ws._replace(push=u._replace(edges=grown(u.edges), verts=grown(u.verts), sides=grown(u.sides)))
    if resource == R_PUSH_STACK:
        u = ws.push
        return ws._replace(push=u._replace(st_start=grown(u.st_start), st_k=grown(u.st_k),
                                           st_behind=grown(u.st_behind), st_front=grown(u.st_front)))
    raise ValueError(f"not a workspace resource: {resource}")
