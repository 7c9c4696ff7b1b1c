"""``Workpiece``: a persistent, exact solid for iterated CSG -- BSPs embedded in an octree (paper §3.8-3.9, §5).

>>> from csgnb.octree import Workpiece
>>> from csgnb.mesh.hull import convex_hull
>>> w = Workpiece.box([0, 0, 0], [8, 8, 8])
>>> w -= convex_hull([[4, 4, 4], [12, 4, 4], [4, 12, 4], [4, 4, 12]])
>>> w.volume()
Fraction(1376, 3)

Each Boolean touches only the octree cells that meet the tool's box; a cell the tool covers
or misses is relabelled without a merge; the merges of one operation run in one kernel call
(:mod:`csgnb.octree.kernels`). Cells whose BSP outgrows the threshold split, eight cells that
fit together again combine. Everything is exact: the result classifies every point exactly
as one BSP of the same sequence of Booleans would.

Coordinates: a workpiece lives on a :class:`csgnb.exact.Grid`. Integer arrays are grid
coordinates; tools are :class:`~csgnb.mesh.hull.ConvexHull`\\ s, :class:`csgnb.bsp.BSP`\\ s,
closed integer meshes ``(vertices, faces)``, or :class:`~csgnb.octree.tool.Tool`\\ s, all in
grid coordinates (float meshes: quantize them with the workpiece's grid first). Volumes are
in grid units cubed (``model_volume`` converts).
"""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from csgnb._resumable import DONE, FAILED, grown
from csgnb.bsp.extract import check_corner, extract_boundary
from csgnb.bsp.merging import constant_labels, merge_table
from csgnb.bsp.polygon import set_vertices_kernel
from csgnb.bsp.solid import BSP as SolidBSP
from csgnb.bsp.solid import DIFFERENCE, INTERSECTION, UNION
from csgnb.bsp.surface import BoundarySurface
from csgnb.bsp.tree import BSPTree
from csgnb.errors import GeometryError, InternalError, PrecisionError
from csgnb.exact.budgets import budget
from csgnb.exact.integral import integer_array, max_abs
from csgnb.exact.predicates import homogeneous_points, to_double_position
from csgnb.exact.quantization import Grid
from csgnb.exact.wide import DEFAULT_WIDTH, to_wide, wide_dtype
from csgnb.mesh.hull import ConvexHull
from csgnb.mesh.hull_facets import hull_facets_of_batch
from csgnb.octree import kernels as K
from csgnb.octree.batch import (
    B_NEXT,
    B_PALETTE_LIMIT,
    B_PHASE,
    R_COMPACT,
    REP_COMBINES,
    REP_LEAVES,
    REP_MERGES,
    REP_RELABELS,
    REP_SPLITS,
    REP_UNCHANGED,
    convex_batch_kernel,
    new_convex_batch,
    spread_orders,
)
from csgnb.octree.global_tree import _global_size, _global_tree_kernel
from csgnb.octree.layout import (
    BSP,
    N_NODES,
    N_PAL,
    N_POOL,
    POOL_LIVE,
    R_AXIS,
    R_NODES,
    R_PALETTE,
    R_PIECE_CACHE,
    R_POOL,
    R_SPLIT_STACK,
    RESOURCE_NAMES,
    S_BOUNDARY_MERGES,
    S_BOUNDARY_SHORTCUTS,
    S_CELL_OPS,
    S_COMBINES,
    S_MERGES,
    S_PATHOLOGICAL,
    S_RELABELS,
    S_SPLITS,
    S_UNCHANGED,
    UNIFORM,
    AxisMap,
    OctArrays,
    Pool,
    grown_octree,
    grown_pool,
    new_axis_map,
    new_octree,
    new_pool,
    new_tree_arrays,
)
from csgnb.octree.piece_cache import (
    MODE,
    MODE_NAMES,
    OFF,
    ON,
    USED,
    WAITING,
    PieceCache,
    compacted_piece_cache,
    grown_piece_cache,
    new_piece_cache,
    rekeyed_piece_cache,
    valid_entries,
)
from csgnb.octree.tool import (
    Tool,
    _exact_planes,
    convex_tool_tree,
    moved_points,
    split_planes_wide,
    store_int64_rows,
)
from csgnb.octree.volume import CellVolumes, LocalChange, cell_key, convex_change
from csgnb.octree.workspace import ToolArrays, grow, new_workspace, with_palette

__all__ = ["DEFAULT_THRESHOLD", "STOCK_CELL_DEPTH", "OpReport", "Workpiece"]

_DIFFERENCE = np.array([[0, 0], [1, 0]])  # merge tables (workpiece label, tool label) -> label
_UNION = np.array([[0, 1], [1, 1]])

DEFAULT_THRESHOLD = 150
"""Maximum BSP nodes per octree cell (the paper found 100-200 best; ``benchmarks/bench_iterated.py --sweep``)."""

STOCK_CELL_DEPTH = 7
"""A workpiece made from a stock (:meth:`Workpiece.box`, :meth:`Workpiece.from_mesh`) splits its cells down to
the stock's largest side over ``2**STOCK_CELL_DEPTH`` (its default ``min_cell``: :func:`_stock_min_cell`), not to
one grid unit. Where many surfaces meet at a point -- every sweep of a spinning drill passes through its axis -- no
split brings a cell under the threshold, and a chain of ever smaller cells grew down to one grid unit, each level
eight more cells to merge in every later step: the paper's drill on ``Grid.fit``'s finest 256-bit grid (2.4e-7 mm)
made 28-level chains, 70,848 cells. 40 of its steps took 106 s CPU with ``min_cell`` 1, and 34 / 26 / 22 / 19 / 52 s
with cells of at least 1/1300, 1/330, 1/168 (this default), 1/84 and 1/21 of the stock; at 128 bits (0.0039 mm,
chains of 14 levels at most) 90 steps took 10.6-11.6 s, 10.0-10.1 s with 1/336, 10.1-10.4 s with 1/168 and 8.8-9.9
s with 1/84. Shallower cells change no result, only the time. A workpiece begun empty keeps ``min_cell`` 1: it has
no stock to measure (the cube lattice, on a grid 100 times larger than its cubes, slowed down 1.5x with cells of
1/256 of the grid)."""

_MAX_RESUMPTIONS = 100

RUN_BATCH = 256
""":meth:`Workpiece.run` applies a run of convex hulls in compiled calls of at most this many (and never across a
checkpoint): the progress bar moves at least every ``RUN_BATCH`` operations."""

APPLIED_MEMO = 1024
"""Mesh-tool differences a workpiece remembers (the newest; see :meth:`Workpiece.boolean`): subtracting one again
before anything adds material is an exact no-op, and is skipped."""

PALETTE_COMPACT_ROWS = 1 << 16
"""The palette (every tool's planes are appended: ~150 rows a milling move, 7,192 a drill step) is compacted when it
holds at least this many rows and twice the rows the last compaction kept: planes no cell's BSP and no wall map entry
uses are dropped and the rest renumbered in their order (:meth:`Workpiece._compact_palette`)."""

PALETTE_COMPACT_LIVE = 0.5
"""... if at most this fraction of its rows is live (otherwise the next check waits for twice as many rows)."""


def _live_planes(plane: np.ndarray, amap: AxisMap, piece_rows: np.ndarray | None = None) -> np.ndarray:
    """The palette rows in use : sorted (k,) int64 -- by BSP nodes ``plane`` (-1 at leaves), the wall map and the
    cached boundary pieces' ``piece_rows`` (signed supports and edge planes).

    Marked in a boolean array over the rows, not ``np.unique`` of the references: a late 256-bit drill step's
    compaction reads ~6 million references to ~10^5 rows, which ``np.unique`` hashed in ~150 ms of its ~220."""
    parts = [plane[plane >= 0], amap.rows[amap.keys >= 0]]
    if piece_rows is not None:
        parts.append(np.where(piece_rows >= 0, piece_rows, ~piece_rows))
    rows = 1 + max((int(p.max()) for p in parts if p.size), default=-1)
    mark = np.zeros(rows, np.bool_)
    for p in parts:
        mark[p] = True
    return np.flatnonzero(mark).astype(np.int64)


def _renumbering(live: np.ndarray, used: int) -> np.ndarray:
    """Old palette row -> new row, keeping the order of the ``live`` rows : (used,) int32 (-1 for a dropped row)."""
    remap = np.full(max(used, 1), -1, np.int32)
    remap[live] = np.arange(live.shape[0], dtype=np.int32)
    return remap


def _loaded_piece_cache(oc: OctArrays, a: dict, nodes: int, *, mode: int) -> PieceCache:
    """The boundary cache of a saved workpiece (checked by :func:`csgnb.octree.persist.check_workpiece`): its entries
    keyed to the loaded cells' pool starts. Files written before the cache have none."""
    if "oc_pieces" not in a:
        return new_piece_cache(nodes, mode=mode)
    plen = a["oc_pieces"]
    total = int(plen.astype(np.int64).sum())
    pc = new_piece_cache(nodes, max(4096, 2 * total), mode=mode)
    cells = np.flatnonzero(plen > 0)
    lens = plen[cells].astype(np.int64)
    pc.key[cells] = oc.start[cells]
    pc.start[cells] = np.concatenate([[0], np.cumsum(lens)[:-1]]).astype(np.int64)
    pc.length[cells] = plen[cells]
    pc.rows[:total] = a["pieces_rows"]
    pc.size[:total] = a["pieces_size"]
    pc.counts[USED] = total
    return pc


def identity_grid(width: int = DEFAULT_WIDTH) -> Grid:
    """The grid on which model coordinates are the integers themselves (scale 1, origin 0)."""
    return Grid(scale=1.0, origin=(0.0, 0.0, 0.0), width=width, max_coordinate=budget(width).max_mesh_coordinate)


@dataclass
class OpReport:
    """What one Boolean did.

    ``cells`` touched, ``merges`` (cells merged with the tool's local BSP), ``relabels`` (cells
    the tool covers or misses), ``splits`` / ``combines`` of octree cells, ``seconds``, with
    ``track_volume=True`` the exact ``volume_change`` (grid units cubed; negative for a removal),
    and ``unchanged``: cells the tool reached whose solid it left as it was (nothing written;
    a merge that changed nothing skips redundancy removal).
    """

    cells: int
    merges: int
    relabels: int
    splits: int
    combines: int
    seconds: float
    volume_change: Fraction | None = None
    unchanged: int = 0
    repeated: bool = False
    """A difference with a mesh tool this workpiece had already subtracted, with no material added since: an exact
    no-op, skipped (no cell touched)."""

    @property
    def removed(self) -> Fraction | None:
        """Volume removed (``-volume_change``), when tracked."""
        return None if self.volume_change is None else -self.volume_change


def _combine_order(oc, leaves: np.ndarray) -> np.ndarray:
    """The parents of the leaves a Boolean touched, in the order the combine pass takes them (smallest cell first,
    equal sizes by the larger index first: children before a parent that holds them)."""
    if leaves.shape[0] <= K.COMBINE_ORDER_LEAVES:
        return K.combine_order(oc.parent, oc.size, leaves)
    parents = np.unique(oc.parent[leaves])
    parents = parents[parents >= 0]
    return parents[np.argsort(-oc.size[parents], kind="stable")[::-1]].astype(np.int64)


def _content_digest(tool: Tool, width: int) -> str:
    """SHA-256 of what a mesh tool is at ``width`` bits (kind, wide planes, polygons, tree, box, offset), once per
    tool and width (a tool is not changed in place; :meth:`Tool.translated` makes a new one)."""
    cache = tool.__dict__.setdefault("_digests", {})
    found = cache.get(width)
    if found is None:
        h = hashlib.sha256(tool.kind.encode())
        parts = [tool.planes_wide(width).view(np.uint8), tool.lo, tool.hi, tool.offset]
        if tool.polygons is not None:
            parts += [tool.polygons.support, tool.polygons.offsets, tool.polygons.edges]
        if tool.tree is not None:
            parts += [np.asarray(a) for a in tool.tree]
        for a in parts:
            a = np.ascontiguousarray(a)
            h.update(f"{a.dtype}{a.shape}|".encode())
            h.update(a.tobytes())
        found = cache[width] = h.hexdigest()
    return found


def _facet_vertices(tool: Tool, points: np.ndarray, width: int) -> np.ndarray:
    """A convex tool's facet vertices ``(m, 4)`` wide of ``width`` bits: its grid points ``points`` (m, 3) int64 as
    ``(x, y, z, 1)``, made once per tool and width."""
    cache = tool.__dict__.setdefault("_geometry", {})
    key = ("facets", width)
    if key not in cache:
        cache[key] = homogeneous_points(points, width)
    return cache[key]


def _polygon_geometry(tool: Tool, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mesh tool's polygon vertices ``(m, 4)`` wide and each polygon's integer box grown by one ``(n, 3)``
    int64 (lo, hi), from the tool's own planes; computed once per tool and width (a translated tool is a new
    tool) and shared by every workpiece it is applied to -- the shards of a sharded workpiece too.

    The vertices are always computed exactly. A tool translated from a source has its source's geometry (made
    once) moved: the vertices by :func:`csgnb.octree.tool.moved_points` (bit for bit the moved planes'
    intersections), the boxes by the translation (still integer boxes that hold every polygon) -- no three-plane
    intersections and no ~50,000 vertices converted to doubles for each of a drill's 270 steps."""
    cache = tool.__dict__.setdefault("_geometry", {})
    found = cache.get(width)
    if found is not None:
        return found
    polys = tool.polygons
    source, shift = tool.__dict__.get("_moved_from", (None, None))
    # a translated tool's geometry is its source's moved: the source's made once (a drill's 90 tools are only ever
    # applied translated, turn 0 by zero)
    base = None if source is None or not len(polys) else _polygon_geometry(source, width)
    if base is not None:
        # the source's vertices moved: x + t·x4, bit for bit the moved planes' intersections (translate_point_into),
        # two wide-by-word products a coordinate instead of three 3x3 determinants a vertex; the moved planes
        # passed the workpiece's budget before this (_add_planes), so the moved points fit the width
        verts = moved_points(base[0], shift)
        plo, phi = base[1] + shift, base[2] + shift
    elif len(polys):
        verts = np.empty((polys.edges.shape[0], 4), wide_dtype(width))
        set_vertices_kernel(tool.planes_wide(width), polys.support, polys.offsets, polys.edges, verts)
        pos = to_double_position(verts)
        first = polys.offsets[:-1].astype(np.intp)  # every polygon has three or more vertices
        plo = (np.floor(np.minimum.reduceat(pos, first, axis=0)) - 1).astype(np.int64)
        phi = (np.ceil(np.maximum.reduceat(pos, first, axis=0)) + 1).astype(np.int64)
    else:
        verts = np.empty((polys.edges.shape[0], 4), wide_dtype(width))
        plo, phi = np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64)
    found = (verts, plo, phi)
    cache[width] = found
    return found


@dataclass
class WorkpieceStats:
    """Counters over the workpiece's life and the per-operation times."""

    operations: int = 0
    cell_ops: int = 0
    merges: int = 0
    relabels: int = 0
    splits: int = 0
    combines: int = 0
    pathological: int = 0
    prefiltered: int = 0
    """Planes the merges' float filter decided without an exact cut (:mod:`csgnb.mesh.float_box`), since the
    workpiece was made or loaded. A diagnostic: a cell redone after a scratch array grew is counted again, so
    the figure follows the workspace's sizes (chapter 05's drill: 49,306 with the former small clip scratch,
    49,299 now), while the solid does not."""
    repeated: int = 0
    """Differences skipped because the same mesh tool (same content, same translation, same ``within``) had been
    subtracted since material was last added (:meth:`Workpiece.boolean`)."""
    skipped_merges: int = 0
    """Cell merges not made because asking first (:func:`csgnb.bsp.merging.merge_changes_a`) found that the tool
    changes nothing there, since the workpiece was made or loaded."""
    boundary_merges: int = 0
    """Cell Booleans with a mesh tool made from the cell's kept boundary and the tool's pieces, without cutting
    (:mod:`csgnb.octree.piece_cache`), those that found nothing to change included, over the workpiece's life (a
    saved statistic)."""
    boundary_shortcuts: int = 0
    """Of those, differences found to change nothing at one vertex a kept piece, without pushing the cell's pieces
    (the tool keeps none of its boundary in the cell and every piece has a vertex strictly outside it;
    :func:`csgnb.octree.piece_cache.pieces_outside`), over the workpiece's life (a saved statistic)."""
    seconds: list[float] = field(default_factory=list)


def _stock_min_cell(points) -> int:
    """The default ``min_cell`` of a workpiece made from a stock whose grid points are ``points``: the largest power
    of two at most the stock's largest side over ``2**STOCK_CELL_DEPTH`` (:data:`STOCK_CELL_DEPTH`), at least 1.

    >>> _stock_min_cell([[0, 0, 0], [140, 20, 20]]), _stock_min_cell([[-10**6] * 3, [10**6] * 3])
    (1, 8192)
    """
    P = np.asarray(points)
    extent = max(int(P[:, c].max()) - int(P[:, c].min()) for c in range(3))
    return 1 << max(0, (extent >> STOCK_CELL_DEPTH).bit_length() - 1)


class Workpiece:
    """An exact solid in an octree of BSP cells (see the module docstring).

    Parameters
    ----------
    grid : csgnb.exact.Grid, optional
        The integer grid (default: the identity grid of ``width``).
    width : int, optional
        Bit width when no grid is given (default :data:`csgnb.exact.DEFAULT_WIDTH`).
    threshold : int
        Maximum BSP nodes per cell before it splits (:data:`DEFAULT_THRESHOLD`).
    min_cell : int
        Cells this size (grid units, a power of two) never split further; their BSPs are
        accepted as they are and counted as pathological when above the threshold (``box`` and
        ``from_mesh`` default to :func:`_stock_min_cell` of the stock).
    max_tool_polygons : int
        A cell that more polygons of a mesh tool reach is split before it is merged, so each
        cell merges with a small local part of the tool (default: ``threshold // 2``).
    seed : int
        Seed of the random insertion orders of redundancy removal.
    """

    def __init__(self, grid: Grid | None = None, *, width: int | None = None, threshold: int = DEFAULT_THRESHOLD,
                 min_cell: int = 1, max_tool_polygons: int | None = None, seed: int = 0) -> None:
        if grid is None:
            grid = identity_grid(DEFAULT_WIDTH if width is None else width)
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a csgnb.exact.Grid, got {type(grid).__name__}")
        if width is not None and width != grid.width:
            raise GeometryError(f"width={width} but the grid is {grid.width}-bit")
        if not (isinstance(threshold, int | np.integer) and threshold >= 8):
            raise ValueError(f"threshold must be an int >= 8 (BSP nodes per cell), got {threshold!r}")
        if not (isinstance(min_cell, int | np.integer) and min_cell >= 1 and (min_cell & (min_cell - 1)) == 0):
            raise ValueError(f"min_cell must be a power of two >= 1, got {min_cell!r}")
        self.grid = grid
        self.width = grid.width
        self.threshold = int(threshold)
        self.min_cell = int(min_cell)
        self.max_tool_polygons = max(8, self.threshold // 2) if max_tool_polygons is None else int(max_tool_polygons)
        self.seed = int(seed)
        half = 1 << max(int(grid.max_coordinate), 1).bit_length()  # >= max_coordinate
        self.root_lo = np.array([-half] * 3, np.int64)
        self.root_size = 2 * half
        self.oc: OctArrays = new_octree(self.root_lo, self.root_size)
        self.pool: Pool = new_pool()
        self.palette = np.zeros((256, 4), wide_dtype(self.width))
        self.amap: AxisMap = new_axis_map()
        self.ws = new_workspace(self.palette, self.threshold)
        self._max_normal, self._max_offset = 1, self.root_size
        self._volumes = CellVolumes()
        self._palette_kept = 0  # rows the last palette compaction kept (or found live)
        self._meta: dict = {}
        self._tables: dict = {}
        self._prepared_fns: dict = {}  # fn -> (table, constant labels, keeps labels outside the tool)
        # keys of the mesh-tool differences applied since material was last added (oldest first): part of the state
        self._applied: dict[str, None] = {}
        self.stats = WorkpieceStats()

    # -- construction ---------------------------------------------------------------

    @classmethod
    def box(cls, lo, hi, *, grid: Grid | None = None, **kw) -> Workpiece:
        """The box ``[lo, hi]``: integer corners on the identity grid (the default), model units on another ``grid``.

        On the identity grid model coordinates are grid coordinates, so a corner such as 2.5 is
        refused (as :meth:`csgnb.bsp.BSP.box` refuses it) rather than rounded to 2 or 3; on a
        scaled grid corners are quantized like every model point (rounded to the nearest grid
        point, at most half of ``grid.resolution`` away).
        """
        w = cls(grid, **kw)
        if w.grid.exponent == 0 and not np.any(w.grid.origin):
            g = np.stack([np.asarray(check_corner(lo, "lo"), np.int64), np.asarray(check_corner(hi, "hi"), np.int64)])
        else:
            g = w.grid.to_grid(np.stack([_real_corner(lo, "lo"), _real_corner(hi, "hi")]))
        if np.any(g[0] >= g[1]):
            raise GeometryError(f"the box {np.asarray(lo).tolist()}..{np.asarray(hi).tolist()} is empty on this grid "
                                f"(resolution {w.grid.resolution:g})")
        if "min_cell" not in kw:
            w.min_cell = _stock_min_cell(g)
        w.union(_box_hull(g[0], g[1], w.width))
        return w

    @classmethod
    def empty(cls, grid: Grid | None = None, **kw) -> Workpiece:
        """No material (unions add it)."""
        return cls(grid, **kw)

    @classmethod
    def from_mesh(cls, vertices, faces=None, *, grid: Grid | None = None, fill: str = "solid", **kw) -> Workpiece:
        """A closed, outward mesh: ``(vertices, faces)`` arrays, a pyvista/trimesh mesh, or a file path (meshio).

        Float vertices are model units, quantized on ``grid`` (default: a grid fitted to the mesh);
        integer vertices are grid coordinates. Validated like :meth:`csgnb.bsp.BSP.from_mesh`;
        ``fill="winding"`` takes any closed mesh, overlapping or folded, as the points it winds around.
        """
        V, F = _mesh_arrays(vertices, faces)
        if grid is None and V.dtype.kind == "f":
            grid = Grid.fit(V.min(axis=0), V.max(axis=0), width=kw.pop("width", DEFAULT_WIDTH))
        w = cls(grid, **kw)
        if V.dtype.kind == "f":
            V = w.grid.to_grid(V)
        if "min_cell" not in kw:
            w.min_cell = _stock_min_cell(V)
        w.union(Tool.from_mesh(V, F, width=w.width, grid=w.grid, fill=fill))
        return w

    # -- tools ------------------------------------------------------------------------

    def _tool(self, tool) -> Tool:
        if isinstance(tool, Tool):
            t = tool
        elif isinstance(tool, ConvexHull):
            t = Tool.from_hull(tool)
        elif isinstance(tool, SolidBSP):
            if tool.tree.width != self.width:
                raise GeometryError(f"the tool BSP is {tool.tree.width}-bit, the workpiece {self.width}-bit; convert "
                                    "it with BSP.to_width or quantize on the workpiece's grid")
            t = Tool.from_bsp(tool, grid=self.grid)
        elif isinstance(tool, Workpiece):
            raise TypeError("to combine two workpieces, pass the other's BSP (other.to_bsp()) as the tool")
        elif isinstance(tool, tuple) and len(tool) == 2:
            V, F = _mesh_arrays(*tool)
            if V.dtype.kind == "f":
                raise TypeError("a tool mesh must have integer grid coordinates; quantize it with the workpiece's "
                                "grid first (w.grid.to_grid(vertices))")
            t = Tool.from_mesh(V, F, width=self.width, grid=self.grid)
        else:
            raise TypeError(f"a tool must be a ConvexHull, a csgnb.bsp.BSP, a Tool or (vertices, faces), "
                            f"got {type(tool).__name__}")
        if t.grid is not None and t.grid is not self.grid and not t.grid.same_as(self.grid):
            raise GeometryError(f"the tool lies on {t.grid}, the workpiece on {self.grid}: quantize both on one grid")
        limit = self.grid.max_coordinate
        if t.kind != "empty" and np.abs(np.stack([t.lo, t.hi])).max() > limit:
            raise PrecisionError(f"the tool's box {t.lo.tolist()}..{t.hi.tolist()} leaves the grid's budget box "
                                 f"|coordinate| <= {limit} ({self.width}-bit)")
        return t

    def _add_planes(self, tool: Tool) -> np.ndarray:
        """Append the tool's planes to the palette (checked against the width's budget); return their rows."""
        split = tool.split_planes
        if split is not None:  # a 256-bit grid's hull: no (k, 4) Python-int array on the way
            self._check_extremes(max_abs(split[0]), max_abs(split[1]), "the tool's planes")
            small = None
        elif tool._pending_translation is not None:  # a tool translated beyond int64: its wide planes, moved
            self._check_extremes(*tool.plane_extremes(self.width), "the tool's planes")
            small = None
        else:
            planes = tool.planes
            self._check_planes(planes, "the tool's planes")
            small = planes if planes.dtype == np.int64 else None
        k = tool.n_planes
        start = int(self.oc.counts[N_PAL])
        self._palette_room(k)
        if small is not None and k:
            store_int64_rows(self.palette, start, small)  # no wide copy of the tool's planes
        else:
            self.palette[start:start + k] = tool.planes_wide(self.width)
        self.oc.counts[N_PAL] = start + k
        return np.arange(start, start + k, dtype=np.int64)

    def _check_planes(self, planes: np.ndarray, what: str) -> None:
        """Refuse ``planes`` (k, 4) int64 or Python ints that break the width's budget together with the
        workpiece's; otherwise record their largest normal and offset."""
        if not planes.shape[0]:
            return
        self._check_extremes(max_abs(planes[:, :3]), max_abs(planes[:, 3]), what)

    def _check_extremes(self, normal: int, offset: int, what: str) -> None:
        """Refuse planes whose largest normal and offset break the width's budget together with the workpiece's;
        otherwise record the new extremes."""
        N = max(self._max_normal, normal)
        D = max(self._max_offset, offset)
        problems = budget(self.width).plane_violations(N, D)
        if problems:
            raise PrecisionError(f"{what} break the {self.width}-bit budget together with the "
                                 f"workpiece's (N = {N}, D = {D}): " + "; ".join(problems))
        self._max_normal, self._max_offset = N, D

    def _palette_room(self, k: int) -> None:
        used = int(self.oc.counts[N_PAL])
        if used + k + 64 > self.palette.shape[0]:
            self.palette = grown(self.palette, used + k + 64)
            self.ws = with_palette(self.ws, self.palette)

    def _tool_arrays(self, tool: Tool, rows: np.ndarray) -> tuple[int, ToolArrays]:
        dtype = self.palette.dtype
        empty_i32 = np.zeros(0, np.int32)
        if tool.kind == "convex":
            plane, neg, pos, label = convex_tool_tree(rows)
            facets = tool.facets if self.ws.pc.counts[MODE] != OFF else None  # only a boundary merge reads them
            if facets is None:  # the kernels cut the cell's box by the hull's planes instead
                return K.CONVEX_TOOL, ToolArrays(rows, empty_i32, np.zeros(1, np.int32), empty_i32,
                                                 np.zeros((0, 4), dtype), np.zeros((0, 3), np.int64),
                                                 np.zeros((0, 3), np.int64), plane, neg, pos, label)
            support, offsets, edges, points, plo, phi = facets
            return K.CONVEX_TOOL, ToolArrays(rows, rows[support].astype(np.int32), offsets,
                                             rows[edges].astype(np.int32), _facet_vertices(tool, points, self.width),
                                             plo, phi, plane, neg, pos, label)
        polys = tool.polygons
        support = np.where(polys.support >= 0, rows[np.maximum(polys.support, 0)],
                           ~rows[np.maximum(~polys.support, 0)]).astype(np.int32)
        edges = rows[polys.edges].astype(np.int32)
        verts, plo, phi = _polygon_geometry(tool, self.width)
        tp, tn, tq, tl = tool.tree
        plane = np.where(tp >= 0, rows[np.maximum(tp, 0)], -1).astype(np.int32)
        return K.MESH_TOOL, ToolArrays(np.zeros(0, np.int64), support, polys.offsets, edges, verts, plo, phi,
                                       plane, np.ascontiguousarray(tn, np.int32), np.ascontiguousarray(tq, np.int32),
                                       np.ascontiguousarray(tl, np.int32))

    # -- Booleans -----------------------------------------------------------------------

    def boolean(self, tool, fn: Callable[[int, int], int], *, track_volume: bool = False,
                within=None) -> OpReport:
        """Replace the solid by ``fn(workpiece label, tool label)`` everywhere (labels 0 = out, 1 = in).

        Only the cells that meet the tool's box are touched (unless ``fn`` changes labels outside
        the tool, as an intersection does). Returns an :class:`OpReport`; with ``track_volume`` it
        carries the exact volume change.

        ``within=(lo, hi)`` (integer grid corners) touches only the cells whose interior meets the box's
        interior: the solid stays right inside the open box and is left behind outside it (on its faces
        too: read a point there from the box's side, :func:`csgnb.bsp.tree.box_face_sides`). That is what a shard of
        :class:`csgnb.distributed.sharded.ShardedWorkpiece` wants (it answers for its box only); a
        workpiece used so answers for that box only. It cannot be combined with ``track_volume``.
        """
        t0 = time.perf_counter()
        if within is not None:
            if track_volume:
                raise GeometryError("track_volume measures every cell the tool reaches; with within= only those in "
                                    "the box change: measure volume() before and after instead")
            w_lo, w_hi = (integer_array(c, "within") for c in within)
            if w_lo.shape != (3,) or w_hi.shape != (3,) or np.any(w_lo > w_hi):
                raise GeometryError(f"within must be two integer corners (lo, hi) with lo <= hi, got {within!r}")
        tool = self._tool(tool)
        table, constant, outside_identity = self._prepared(fn)
        if outside_identity:
            lo, hi = tool.lo, tool.hi  # cells outside the tool's box keep their labels
        else:
            lo, hi = self.root_lo - 1, self.root_lo + self.root_size + 1
        if within is not None:
            lo, hi = np.maximum(lo, w_lo), np.minimum(hi, w_hi)
            if np.any(lo > hi):
                return self._empty_tool(True, False, t0)  # no cell to touch: nothing changes in the box
        is_difference = np.array_equal(table, _DIFFERENCE)
        key = self._applied_key(tool, None if within is None else (w_lo, w_hi)) if is_difference else None
        if key is not None and key in self._applied:
            return self._repeated(track_volume, t0)
        if not is_difference:
            self._applied = {}  # material may be added (a union) or the label function is another: forget them all
        if tool.kind == "empty":
            if not outside_identity and int(table[0, 0]) != 0:
                raise GeometryError("the tool is empty and the label function makes material outside it "
                                    "(fn(0, 0) = 1): that fills the whole octree root box; use a tool box instead")
            return self._empty_tool(outside_identity, track_volume, t0)
        change = measure = before = None
        if track_volume:  # measured where the solid can change (csgnb.octree.volume)
            if not outside_identity:
                before = self.volume()
            elif tool.kind == "convex" and (np.array_equal(table, _DIFFERENCE) or np.array_equal(table, _UNION)):
                change = convex_change(self, self._volumes, tool, union=np.array_equal(table, _UNION))
            else:
                measure = LocalChange(self, self._volumes, tool.lo, tool.hi)
        rows = self._add_planes(tool)
        kind, ta = self._tool_arrays(tool, rows)
        counts_before = self.oc.counts.copy()
        leaves = self._run_boolean(kind, ta, lo, hi, table, constant)
        if leaves.shape[0]:
            parents = _combine_order(self.oc, leaves)
            if parents.shape[0]:
                self._run_combine(parents)
        self._maybe_compact()
        c = self.oc.counts - counts_before
        report = OpReport(int(leaves.shape[0]), int(c[S_MERGES]), int(c[S_RELABELS]), int(c[S_SPLITS]),
                          int(c[S_COMBINES]), 0.0, unchanged=int(c[S_UNCHANGED]))
        if track_volume:
            if before is not None:
                change = self.volume() - before
            elif measure is not None:
                change = measure.finish()
            report.volume_change = change
        self._maybe_compact_palette()  # after the volume measurement, whose cache keys name palette rows
        if key is not None:
            self._applied[key] = None
            if len(self._applied) > APPLIED_MEMO:
                del self._applied[next(iter(self._applied))]
        report.seconds = time.perf_counter() - t0
        s = self.stats
        s.operations += 1
        s.cell_ops += int(c[S_CELL_OPS])
        s.merges += report.merges
        s.relabels += report.relabels
        s.splits += report.splits
        s.combines += report.combines
        s.pathological = int(self.oc.counts[S_PATHOLOGICAL])
        s.prefiltered = int(self.ws.merge_state[4])
        s.skipped_merges = int(self.ws.merge_state[6])
        s.boundary_merges = int(self.oc.counts[S_BOUNDARY_MERGES])
        s.boundary_shortcuts = int(self.oc.counts[S_BOUNDARY_SHORTCUTS])
        s.seconds.append(report.seconds)
        return report

    def _prepared(self, fn: Callable[[int, int], int]) -> tuple[np.ndarray, np.ndarray, bool]:
        """The label table of ``fn``, its constant labels and whether it keeps the workpiece outside the tool."""
        prepared = self._prepared_fns.get(fn)
        if prepared is None:
            labels_a = [0, 1]  # one material: boolean() refuses label functions that make others
            table = self._tables.get(fn)
            if table is None:
                table = merge_table(fn, labels_a, [0, 1])
                self._tables[fn] = table
            if int(table.max()) > 1:
                raise GeometryError("the octree workpiece holds one material (labels 0 and 1); the label function "
                                    f"returned {int(table.max())}")
            prepared = (table, constant_labels(table, np.array([0, 1])),
                        all(int(table[la, 0]) == la for la in labels_a))
            self._prepared_fns[fn] = prepared
        return prepared

    def _applied_key(self, tool: Tool, within) -> str | None:
        """The key of subtracting mesh tool ``tool`` (``within`` = the box it is confined to, or None) in the memo of
        differences applied since material was last added; None for other tools (a hull's Boolean costs little more
        than a digest would). A translated tool is its source's content digest and the translation: the same planes
        ``d - n·t``, polygons and tree."""
        if tool.kind != "mesh":
            return None
        source, shift = tool.__dict__.get("_moved_from", (tool, tool.offset * 0))
        h = hashlib.sha256(_content_digest(source, self.width).encode())
        h.update(np.asarray(shift, np.int64).tobytes())
        if within is not None:
            h.update(b"within")
            h.update(np.asarray(within, np.int64).tobytes())
        return h.hexdigest()

    def _repeated(self, track_volume: bool, t0: float) -> OpReport:
        """The report of a difference already applied with nothing added since: A - T - ... - T = A - T - ..."""
        report = OpReport(0, 0, 0, 0, 0, time.perf_counter() - t0,
                          volume_change=Fraction(0) if track_volume else None, repeated=True)
        self.stats.operations += 1
        self.stats.repeated += 1
        self.stats.seconds.append(report.seconds)
        return report

    def _empty_tool(self, outside_identity: bool, track_volume: bool, t0: float) -> OpReport:
        """A Boolean with no tool material: nothing changes where ``fn(a, 0) == a`` (a difference, a union);
        otherwise (``fn(0, 0) = 0`` is checked by the caller) ``fn(1, 0) = 0``: the workpiece becomes empty."""
        before = self.volume() if track_volume and not outside_identity else Fraction(0)
        if not outside_identity:
            fresh = Workpiece(self.grid, threshold=self.threshold, min_cell=self.min_cell,
                              max_tool_polygons=self.max_tool_polygons, seed=self.seed)
            for name in ("oc", "pool", "palette", "amap", "ws", "_max_normal", "_max_offset", "_volumes",
                         "_palette_kept"):
                setattr(self, name, getattr(fresh, name))
        report = OpReport(0, 0, 0, 0, 0, time.perf_counter() - t0,
                          volume_change=-before if track_volume else None)
        self.stats.operations += 1
        self.stats.seconds.append(report.seconds)
        return report

    def _boolean_hulls(self, hulls: list, fn: Callable[[int, int], int]) -> list[OpReport]:
        """``boolean(hull, fn)`` for each convex hull in turn, in one compiled call (:mod:`csgnb.octree.batch`).

        The workpiece ends exactly as a loop of :meth:`boolean` leaves it (the same kernels in the same order, the
        pool and palette compacted after the same hulls) and the reports carry the same counters; their
        ``seconds`` is the batch's time shared equally. Every hull is checked (type, grid, budget) before any is
        applied: a bad one leaves the workpiece as it was.
        """
        t0 = time.perf_counter()
        n = len(hulls)
        if n == 0:
            return []
        table, constant, outside_identity = self._prepared(fn)
        if not np.array_equal(table, _DIFFERENCE):
            self._applied = {}  # hulls that may add material: the mesh-tool differences remembered no longer hold
        lo, hi = np.empty((n, 3), np.int64), np.empty((n, 3), np.int64)
        for i, h in enumerate(hulls):
            if not isinstance(h, ConvexHull):
                raise TypeError(f"_boolean_hulls takes ConvexHulls, got {type(h).__name__} at {i}")
            g = h.grid
            if g is not None and g is not self.grid and not g.same_as(self.grid):
                raise GeometryError(f"the tool lies on {g}, the workpiece on {self.grid}: quantize both on one grid")
            lo[i], hi[i] = h.lo, h.hi
        limit = self.grid.max_coordinate
        outside = np.flatnonzero((np.abs(lo) > limit).any(axis=1) | (np.abs(hi) > limit).any(axis=1))
        if outside.shape[0]:
            j = int(outside[0])
            raise PrecisionError(f"the tool's box {lo[j].tolist()}..{hi[j].tolist()} leaves the grid's budget box "
                                 f"|coordinate| <= {limit} ({self.width}-bit)")
        starts = np.zeros(n + 1, np.int64)
        np.cumsum([h.n_planes for h in hulls], out=starts[1:])
        max_normal, max_offset = self._max_normal, self._max_offset
        splits = [h._split_planes() for h in hulls]
        if all(sp is not None for sp in splits) and any(sp[1].dtype == object for sp in splits):
            # offsets beyond int64 (a 256-bit grid): int64 normals and one column of Python ints, as Tool.from_hull
            N = np.concatenate([sp[0] for sp in splits])
            d = np.concatenate([sp[1].astype(object) for sp in splits])
            order = spread_orders(N.astype(np.float64), starts)  # as Tool.from_hull orders each hull's planes
            N, d = N[order], d[order]
            self._check_extremes(max_abs(N), max_abs(d), "the tools' planes")
            W = split_planes_wide(N, d, self.width)
        else:
            P = _exact_planes(np.concatenate([h.planes for h in hulls]))  # int64 beside object rows: Python ints
            order = spread_orders(P[:, :3].astype(np.float64), starts)  # as Tool.from_hull orders each hull's planes
            P = P[order]
            self._check_planes(P, "the tools' planes")
            if P.dtype == np.int64:
                W = np.zeros((P.shape[0], 4), self.palette.dtype)
                store_int64_rows(W, 0, P)
            else:
                W = to_wide(P, self.width)
        if not outside_identity:
            lo[:] = self.root_lo - 1
            hi[:] = self.root_lo + self.root_size + 1
        biggest = int(np.diff(starts).max())
        self._palette_room(biggest + 64)
        if not hasattr(self, "_split_stack"):
            self._split_stack = np.zeros(512, np.int64)
        self._boundary_cache_starts()
        work, cand, done = self._walk_arrays(0)
        # the hulls' facets: a cell's boundary merge takes them as the tool's pieces (as _tool_arrays gives them)
        facets = hull_facets_of_batch(hulls, starts, order) if self.ws.pc.counts[MODE] != OFF else None
        batch = new_convex_batch(W, starts, lo, hi, done.shape[0], max(PALETTE_COMPACT_ROWS, 2 * self._palette_kept),
                                 facets)
        st, need = np.zeros(8, np.int64), np.zeros(4, np.int64)
        counts_before = self.oc.counts.copy()
        shortages = 0
        try:
            while True:
                status = convex_batch_kernel(self.palette, self.oc, self.pool, self.amap, work, cand, done, batch,
                                             table, constant, self.ws, st, self._split_stack, self.threshold,
                                             self.min_cell, self.max_tool_polygons, self.seed, need)
                if status == DONE:
                    break
                if status == FAILED:
                    raise InternalError("an octree Boolean failed an internal check (a bug in csgnb: please report "
                                        "it)")
                code = int(need[0])
                if code == R_COMPACT:  # where one Boolean at a time compacts: after the same hull
                    self._maybe_compact()
                    self._maybe_compact_palette()
                    batch.state[B_PALETTE_LIMIT] = max(PALETTE_COMPACT_ROWS, 2 * self._palette_kept)
                    shortages = 0
                    continue
                shortages += 1
                if shortages > _MAX_RESUMPTIONS:
                    raise InternalError("an octree Boolean kept running short of room (a bug in csgnb: please "
                                        "report it)")
                if code in (K.R_WORK, K.R_CANDIDATES):
                    work, cand, done = self._grow_walk(code, work, cand, done)
                    batch = batch._replace(parents=grown(batch.parents, done.shape[0]))
                else:
                    self._grow(code)
                    self._palette_room(biggest + 64)
        except BaseException:
            if int(batch.state[B_NEXT]) == 0 and int(batch.state[B_PHASE]) == 0:
                self._max_normal, self._max_offset = max_normal, max_offset
            raise
        # (the kernel stopped for every compaction due, after the last hull too)
        seconds = (time.perf_counter() - t0) / n
        c = self.oc.counts - counts_before
        stats = self.stats
        stats.operations += n
        stats.cell_ops += int(c[S_CELL_OPS])
        stats.merges += int(c[S_MERGES])
        stats.relabels += int(c[S_RELABELS])
        stats.splits += int(c[S_SPLITS])
        stats.combines += int(c[S_COMBINES])
        stats.pathological = int(self.oc.counts[S_PATHOLOGICAL])
        stats.prefiltered = int(self.ws.merge_state[4])
        stats.skipped_merges = int(self.ws.merge_state[6])
        stats.boundary_merges = int(self.oc.counts[S_BOUNDARY_MERGES])
        stats.boundary_shortcuts = int(self.oc.counts[S_BOUNDARY_SHORTCUTS])
        stats.seconds.extend([seconds] * n)
        return [OpReport(int(r[REP_LEAVES]), int(r[REP_MERGES]), int(r[REP_RELABELS]), int(r[REP_SPLITS]),
                         int(r[REP_COMBINES]), seconds, unchanged=int(r[REP_UNCHANGED]))
                for r in batch.reports]

    def difference(self, tool, **kw) -> OpReport:
        """Subtract ``tool``."""
        return self.boolean(tool, DIFFERENCE, **kw)

    def union(self, tool, **kw) -> OpReport:
        """Add ``tool``."""
        return self.boolean(tool, UNION, **kw)

    def intersection(self, tool, **kw) -> OpReport:
        """Keep only what lies in ``tool``."""
        return self.boolean(tool, INTERSECTION, **kw)

    def __isub__(self, tool) -> Workpiece:
        self.difference(tool)
        return self

    def __ior__(self, tool) -> Workpiece:
        self.union(tool)
        return self

    def __iand__(self, tool) -> Workpiece:
        self.intersection(tool)
        return self

    def run(self, tools: Iterable, op: str | Callable = "difference", *, progress: bool = False,
            track_volume: bool = False, checkpoint=None, checkpoint_every: int = 0) -> list[OpReport]:
        """Apply ``op`` with every tool in turn; a tqdm progress bar with ``progress=True``.

        With ``checkpoint`` (a path) and ``checkpoint_every=k`` the workpiece is saved there
        every ``k`` operations (atomically, with the number done). If that file already holds
        a checkpoint of this run, the workpiece is first restored from it and the operations it
        had done are skipped, so a run killed at any point and started again ends with a
        result identical to an uninterrupted one. A checkpoint carries digests of the workpiece
        the run started from, of the label function and of the tools it has applied; a file
        written by any other run (another start, operation or tool sequence) is refused with a
        ``GeometryError`` saying what differs. Returns the reports of the operations run.

        Without ``track_volume``, a run of convex hulls goes through one compiled call for up to
        :data:`RUN_BATCH` of them (:mod:`csgnb.octree.batch`; a drill tool's 896 prism unions: -27 %
        CPU): the workpiece and the reports' counters are those of one Boolean at a time, the reports'
        ``seconds`` is their batch's time shared equally, and every hull of a batch is checked (grid,
        budget) before any of it is applied.
        """
        if isinstance(op, str):
            if op not in ("difference", "union", "intersection"):
                raise ValueError(f"op must be 'difference', 'union', 'intersection' or a label function, got {op!r}")
            fn = {"difference": DIFFERENCE, "union": UNION, "intersection": INTERSECTION}[op]
        elif callable(op):
            fn = op
        else:
            raise TypeError(f"op must be a name or a label function, got {type(op).__name__}")
        tools = list(tools)
        done = 0
        identity = None
        if checkpoint is not None:
            if not (isinstance(checkpoint_every, int | np.integer) and checkpoint_every >= 1):
                raise ValueError(f"checkpoint_every must be an int >= 1 with a checkpoint, got {checkpoint_every!r}")
            from pathlib import Path

            # what the checkpoint must match: this starting workpiece, the label function, and the tools done
            prefix = [hashlib.sha256(b"csgnb-tools").hexdigest()]
            for t in tools:
                prefix.append(hashlib.sha256((prefix[-1] + self._tool_digest(t)).encode()).hexdigest())
            table = self._tables.get(fn)
            if table is None:
                table = merge_table(fn, [0, 1], [0, 1])
            op_digest = hashlib.sha256(np.ascontiguousarray(table, np.int64).tobytes()).hexdigest()
            identity = {"start": self._state_digest(), "op": op_digest}
            if Path(checkpoint).exists():
                restored = Workpiece.load(checkpoint)
                done = self._check_checkpoint(checkpoint, restored, identity, prefix)
                self._adopt(restored)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(desc=f"csgnb {op if isinstance(op, str) else 'boolean'}", unit="op", initial=done,
                       total=len(tools))
        reports = []
        i = done
        try:
            while i < len(tools):
                if not track_volume and isinstance(tools[i], ConvexHull):
                    # a run of convex hulls: one compiled call each RUN_BATCH of them (csgnb.octree.batch)
                    end = min(len(tools), i + RUN_BATCH)
                    if checkpoint is not None:
                        end = min(end, (i // checkpoint_every + 1) * checkpoint_every)
                    j = i + 1
                    while j < end and isinstance(tools[j], ConvexHull):
                        j += 1
                    reports.extend(self._boolean_hulls(tools[i:j], fn))
                else:
                    j = i + 1
                    reports.append(self.boolean(tools[i], fn, track_volume=track_volume))
                if bar is not None:
                    bar.update(j - i)
                i = j
                if checkpoint is not None and (i % checkpoint_every == 0 or i == len(tools)):
                    self.save(checkpoint, completed=i, checkpoint=dict(identity, tools=prefix[i]))
        finally:
            if bar is not None:
                bar.close()
        return reports

    def _check_checkpoint(self, path, restored: Workpiece, identity: dict, prefix: list[str]) -> int:
        """The number of operations the checkpoint ``restored`` has done; a clear error if it belongs to another run."""
        meta = restored._meta.get("checkpoint")
        done = int(restored._meta.get("completed", 0))
        what = "delete it to start afresh, or pass another checkpoint path"
        if meta is None:
            raise GeometryError(f"{path} is a saved workpiece, not a checkpoint of run(): {what}")
        differ = []
        if not restored.grid.same_as(self.grid):
            differ.append(f"the grid ({restored.grid} there, {self.grid} here)")
        if restored.threshold != self.threshold:
            differ.append(f"the threshold ({restored.threshold} there, {self.threshold} here)")
        if meta["start"] != identity["start"]:
            differ.append("the starting workpiece")
        if meta["op"] != identity["op"]:
            differ.append("the operation")
        if done > len(prefix) - 1:
            differ.append(f"the tools (it has done {done} operations, {len(prefix) - 1} tools are given)")
        elif meta["tools"] != prefix[done]:
            differ.append(f"the tools (its first {done} differ from the ones given)")
        if differ:
            raise GeometryError(f"the checkpoint {path} belongs to another run: " + ", ".join(differ)
                                + f" differ; {what}")
        return done

    def _tool_digest(self, tool) -> str:
        """SHA-256 of what defines a tool (its type and arrays), for checkpoint identities."""
        h = hashlib.sha256()

        def put(*values) -> None:
            for v in values:
                if isinstance(v, np.ndarray):
                    a = np.ascontiguousarray(v)
                    h.update(f"{a.dtype}{a.shape}".encode())
                    h.update(repr(a.tolist()).encode() if a.dtype == object else a.tobytes())
                elif isinstance(v, Grid):
                    h.update(repr((v.exponent, v.origin.tolist(), v.width, v.max_coordinate)).encode())
                else:
                    h.update(repr(v).encode())
                h.update(b"|")

        if isinstance(tool, ConvexHull):
            put("hull", tool.planes, tool.lo, tool.hi, tool.width, tool.grid)
        elif isinstance(tool, SolidBSP):
            t = tool.tree
            put("bsp", t.palette.view(np.uint8), t.plane, t.neg, t.pos, t.label, np.asarray(tool.lo),
                np.asarray(tool.hi))
        elif isinstance(tool, tuple) and len(tool) == 2:
            put("mesh", np.asarray(tool[0]), np.asarray(tool[1]))
        else:
            t = tool if isinstance(tool, Tool) else self._tool(tool)
            put("tool", t.kind, np.asarray(t.planes, object), t.lo, t.hi, t.offset, t.grid)
            if t.polygons is not None:
                put(t.polygons.support, t.polygons.offsets, t.polygons.edges)
            if t.tree is not None:
                put(*(np.asarray(a) for a in t.tree))
        return h.hexdigest()

    # -- persistence -------------------------------------------------------------------

    def _header(self) -> dict:
        g = self.grid
        header = {"width": self.width, "exponent": int(g.exponent), "origin": [float(x) for x in g.origin],
                  "max_coordinate": int(g.max_coordinate), "threshold": self.threshold, "min_cell": self.min_cell,
                  "max_tool_polygons": self.max_tool_polygons, "seed": self.seed,
                  "root_lo": [int(x) for x in self.root_lo], "root_size": int(self.root_size),
                  "max_normal": str(self._max_normal), "max_offset": str(self._max_offset)}
        if self._applied:  # the differences it would skip are part of what the workpiece does next (a resumed run)
            header["applied"] = list(self._applied)
        header["boundary_cache"] = MODE_NAMES[int(self.ws.pc.counts[MODE])]  # what it stores next: part of the state
        return header

    def _arrays(self) -> dict[str, np.ndarray]:
        """The workpiece's arrays in canonical form: the same solid built the same way gives the same arrays.

        Rows in use only; the fields no query reads are zeroed (free octree nodes entirely; the kind, label,
        start and length of inner nodes; the start of uniform cells and the label of BSP cells); the BSP pool
        is compacted (the cells' BSPs back to back in node order, no garbage), and so is the palette (the planes
        the cells and the wall map use, in their order).
        """
        from csgnb.octree.layout import N_FREE_BLOCKS

        oc = self.oc
        n = int(oc.counts[N_NODES])
        a = {f"oc_{name}": np.array(getattr(oc, name)[:n]) for name in
             ("child", "parent", "kind", "label", "start", "length", "lo", "size")}
        n_free = int(oc.counts[N_FREE_BLOCKS])
        free = np.array(oc.free_blocks[:n_free])
        dead = (free.astype(np.int64)[:, None] * 8 + 1 + np.arange(8)).reshape(-1)
        for name in ("child", "parent"):
            a[f"oc_{name}"][dead] = -1
        for name in ("kind", "label", "start", "length", "lo", "size"):
            a[f"oc_{name}"][dead] = 0
        alive = np.ones(n, bool)
        alive[dead] = False
        inner = alive & (a["oc_child"] >= 0)
        for name in ("kind", "label", "start", "length"):
            a[f"oc_{name}"][inner] = 0
        leaf = alive & ~inner
        uniform = leaf & (a["oc_kind"] == UNIFORM)
        a["oc_start"][uniform] = 0
        a["oc_length"][uniform] = 0
        cells = np.flatnonzero(leaf & (a["oc_kind"] == BSP))
        lens = a["oc_length"][cells].astype(np.int64)
        starts = np.concatenate([[0], np.cumsum(lens)[:-1]]).astype(np.int64)
        rows = (np.repeat(a["oc_start"][cells] - starts, lens) + np.arange(int(lens.sum()))).astype(np.int64)
        a["oc_start"][cells] = starts
        a["oc_label"][cells] = 0
        for name in ("plane", "neg", "pos", "label"):
            a[f"pool_{name}"] = getattr(self.pool, name)[rows]
        # the boundary cache's valid entries, cell after cell (csgnb.octree.piece_cache): they decide how the next
        # Booleans build their trees, so they are part of the state
        pc = self.ws.pc
        valid = valid_entries(pc, oc)
        plen = np.zeros(n, np.int32)
        plen[valid] = pc.length[valid]
        plen[~(leaf & (a["oc_kind"] == BSP))] = 0
        pcells = cells[plen[cells] > 0]
        plens = plen[pcells].astype(np.int64)
        pstarts = np.concatenate([[0], np.cumsum(plens)[:-1]]).astype(np.int64)
        src = (np.repeat(pc.start[pcells] - pstarts, plens) + np.arange(int(plens.sum()))).astype(np.int64)
        a["oc_pieces"] = plen
        piece_rows = pc.rows[src]
        a["pieces_size"] = pc.size[src]
        # the palette's live rows only, in their order (so compaction in memory, whenever it ran, changes nothing)
        live = _live_planes(a["pool_plane"], self.amap, piece_rows)
        remap = _renumbering(live, int(oc.counts[N_PAL]))
        inner = a["pool_plane"] >= 0
        a["pool_plane"][inner] = remap[a["pool_plane"][inner]]
        up = piece_rows >= 0
        piece_rows[up] = remap[piece_rows[up]]
        piece_rows[~up] = ~remap[~piece_rows[~up]]
        a["pieces_rows"] = piece_rows
        a["axis_keys"] = self.amap.keys.copy()
        a["axis_rows"] = self.amap.rows.copy()
        walls = a["axis_keys"] >= 0
        a["axis_rows"][walls] = remap[a["axis_rows"][walls]]
        counts = oc.counts.copy()
        counts[N_POOL] = counts[POOL_LIVE] = rows.shape[0]
        counts[N_PAL] = live.shape[0]
        a["oc_counts"] = counts
        a["oc_free_blocks"] = free
        a["palette_limbs"] = np.array(self.palette[live]["limbs"])
        return a

    def _state_digest(self) -> str:
        """SHA-256 of the workpiece's parameters and canonical arrays (the same for the same workpiece)."""
        from csgnb.octree.persist import _digest

        return _digest(self._header(), self._arrays())

    def save(self, path, *, completed: int | None = None, checkpoint: dict | None = None) -> None:
        """Write the workpiece to ``path`` bit for bit: versioned, checksummed, atomic (an interrupted save
        leaves the previous file intact) and deterministic (the same workpiece gives the same bytes).

        :meth:`load` reads it back. ``completed`` and ``checkpoint`` are for :meth:`run`'s checkpoints.
        """
        from csgnb.octree.persist import write_arrays

        header = self._header()
        if completed is not None:
            header["completed"] = int(completed)
        if checkpoint is not None:
            header["checkpoint"] = dict(checkpoint)
        write_arrays(path, header, self._arrays())

    @classmethod
    def load(cls, path) -> Workpiece:
        """Read a workpiece written by :meth:`save`.

        The file's checksum and its whole structure are checked first
        (:func:`csgnb.octree.persist.check_workpiece`): a damaged, truncated, foreign or inconsistent file raises
        ``WorkpieceFileError`` naming what is wrong; a file that loads is a valid workpiece.
        """
        from csgnb.octree.layout import N_FREE_BLOCKS
        from csgnb.octree.persist import check_workpiece, read_arrays

        header, a = read_arrays(path)
        ok = check_workpiece(path, header, a)
        w = cls(ok["grid"], threshold=ok["threshold"], min_cell=ok["min_cell"],
                max_tool_polygons=ok["max_tool_polygons"], seed=ok["seed"])
        n = a["oc_child"].shape[0]
        cap = max(n, 16)
        oc = new_octree(ok["root_lo"], ok["root_size"], cap)
        for name in ("child", "parent", "kind", "label", "start", "length", "lo", "size"):
            getattr(oc, name)[:n] = a[f"oc_{name}"]
        oc.counts[:] = a["oc_counts"]
        n_free = int(oc.counts[N_FREE_BLOCKS])
        free = np.zeros(max(cap // 8 + 1, n_free, 4), np.int32)
        free[:n_free] = a["oc_free_blocks"]
        oc = oc._replace(free_blocks=free)
        m = a["pool_plane"].shape[0]
        pool = new_pool(max(m, 64))
        for name in ("plane", "neg", "pos", "label"):
            getattr(pool, name)[:m] = a[f"pool_{name}"]
        limbs = a["palette_limbs"]
        palette = np.zeros((max(limbs.shape[0] + 64, 256), 4), wide_dtype(w.width))
        palette[: limbs.shape[0]]["limbs"] = limbs
        w.oc, w.pool, w.palette = oc, pool, palette
        w.amap = AxisMap(np.ascontiguousarray(a["axis_keys"]), np.ascontiguousarray(a["axis_rows"]))
        w.ws = with_palette(w.ws, palette)
        mode = MODE_NAMES.index(header.get("boundary_cache", "waiting"))
        w.ws = w.ws._replace(pc=_loaded_piece_cache(oc, a, cap, mode=mode))
        w.root_lo = ok["root_lo"]
        w.root_size = ok["root_size"]
        w._max_normal, w._max_offset = ok["max_normal"], ok["max_offset"]
        w._palette_kept = limbs.shape[0]
        w._applied = dict.fromkeys(header.get("applied", []))
        w._meta = header
        return w

    def _adopt(self, other: Workpiece) -> None:
        if not other.grid.same_as(self.grid) or other.threshold != self.threshold:
            raise GeometryError("the checkpoint was made with another grid or threshold: it belongs to another run")
        self.__dict__.update(other.__dict__)

    # -- kernels and growth ------------------------------------------------------------------

    def _grow(self, resource: int) -> None:
        if resource == R_POOL:
            # At least double: a kernel asks again with the same need, and an empty pool (used = 0) must grow too.
            size = self.pool.plane.shape[0]
            self.pool = grown_pool(self.pool, max(int(self.oc.counts[N_POOL]), size), max(1024, size))
        elif resource == R_NODES:
            self.oc = grown_octree(self.oc, max(64, self.oc.child.shape[0]))
            self.ws = self.ws._replace(pc=grown_piece_cache(self.ws.pc, self.oc.child.shape[0], 0))
        elif resource == R_PIECE_CACHE:
            self._grow_piece_cache()
        elif resource == R_PALETTE:
            self._palette_room(max(256, self.palette.shape[0]))
        elif resource == R_AXIS:
            self._grow_axis_map()
        elif resource == R_SPLIT_STACK:
            self._split_stack = grown(self._split_stack)
        elif resource in RESOURCE_NAMES:
            self.ws = grow(self.ws, resource)
        else:
            raise InternalError(f"an octree kernel failed (resource code {resource}; a bug in csgnb: please report it)")

    def _grow_axis_map(self) -> None:
        old = self.amap
        new = new_axis_map(2 * old.keys.shape[0])
        used = old.keys >= 0
        # re-insert: the kernel hashes, so let it (a tiny kernel call per key is cheap enough here)
        _reinsert(old.keys[used], old.rows[used], new)
        self.amap = new

    def _walk_arrays(self, n_poly: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The Boolean kernel's worklist ``(w, 4) int64``, candidate arena ``(c,) int32`` (room for ``16 n_poly``) and
        list of touched cells ``(d,) int64``. They live with the workpiece and only grow: fresh ones resumed a drill
        step ~5 times to grow (each redoing a cell) and touched ~1 MB of new pages every step."""
        work, cand, done = self.__dict__.get("_walk") or (np.zeros((512, 4), np.int64), np.empty(1024, np.int32),
                                                           np.empty(256, np.int64))
        if cand.shape[0] < 16 * n_poly:
            cand = np.empty(16 * n_poly, np.int32)
        self._walk = (work, cand, done)
        return self._walk

    def _grow_walk(self, code: int, work, cand, done) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The walk arrays after the kernel ran short of ``code`` (``R_WORK``: worklist and cell list; else the
        candidates), kept with the workpiece."""
        if code == K.R_WORK:
            work, done = grown(work), grown(done)
        else:
            cand = grown(cand)
        self._walk = (work, cand, done)
        return self._walk

    def _boundary_cache_starts(self) -> None:
        """At the first Boolean (mode ``"waiting"``): the cells keep their boundary from now on."""
        if self.ws.pc.counts[MODE] == WAITING:
            self.ws.pc.counts[MODE] = ON

    def _run_boolean(self, kind: int, tool: ToolArrays, lo, hi, table, constant) -> np.ndarray:
        """Run the Boolean kernel from the root over the open box ``(lo, hi)``; return the leaves it processed."""
        st = np.zeros(8, np.int64)
        need = np.zeros(4, np.int64)
        if not hasattr(self, "_split_stack"):
            self._split_stack = np.zeros(512, np.int64)
        self._boundary_cache_starts()
        n_poly = tool.support.shape[0] if kind == K.MESH_TOOL else 0  # a hull's facets are not walked
        work, cand, done = self._walk_arrays(n_poly)
        cand[:n_poly] = np.arange(n_poly, dtype=np.int32)
        work[0] = (0, 0, n_poly, 4 * n_poly + 4)
        st[K.ST_LEAF] = 1
        st[K.ST_CAND_TOP] = n_poly
        st[K.ST_REFINE] = -1
        tlo = np.ascontiguousarray(lo, np.int64)
        thi = np.ascontiguousarray(hi, np.int64)
        for _ in range(_MAX_RESUMPTIONS):
            self._palette_room(64)
            status = K._boolean_kernel(self.palette, self.oc, self.pool, self.amap, work, cand, done, kind, tool,
                                       tlo, thi, table, constant, self.ws, st, self._split_stack, self.threshold,
                                       self.min_cell, self.max_tool_polygons, self.seed, need)
            if status == DONE:
                return done[: st[K.ST_DONE]]
            if status == FAILED:
                raise InternalError("an octree Boolean failed an internal check (a bug in csgnb: please report it)")
            if need[0] in (K.R_WORK, K.R_CANDIDATES):
                work, cand, done = self._grow_walk(int(need[0]), work, cand, done)
            else:
                self._grow(int(need[0]))
        raise InternalError("an octree Boolean kept running short of room (a bug in csgnb: please report it)")

    def _run_combine(self, parents: np.ndarray) -> None:
        st = np.zeros(2, np.int64)
        need = np.zeros(4, np.int64)
        parents = np.ascontiguousarray(parents, np.int64)
        for _ in range(_MAX_RESUMPTIONS):
            self._palette_room(64)
            status = K._combine_kernel(self.palette, self.oc, self.pool, self.amap, parents, self.ws, st,
                                       self.threshold, self.seed, need)
            if status == DONE:
                return
            if status == FAILED:
                raise InternalError("an octree combine failed an internal check (a bug in csgnb: please report it)")
            self._grow(int(need[0]))
        raise InternalError("an octree combine kept running short of room (a bug in csgnb: please report it)")

    @property
    def boundary_cache(self) -> bool:
        """Whether cells keep their exact boundary for their next Boolean (default on, from the first Boolean).

        With it a cell's merge pushes the cell's boundary pieces through the tool's local tree and the tool's pieces
        in the cell (a mesh tool's polygons or a convex hull's facets, clipped to the cell) through the cell's tree
        (:mod:`csgnb.octree.piece_cache`) instead of cutting the cell by both trees; off, every merge cuts. Both give
        the same solid; the trees may differ. Setting it empties the cache."""
        return int(self.ws.pc.counts[MODE]) != OFF

    @boundary_cache.setter
    def boundary_cache(self, on: bool) -> None:
        self.ws = self.ws._replace(pc=new_piece_cache(self.oc.child.shape[0], mode=WAITING if on else OFF))

    def _grow_piece_cache(self) -> None:
        """Room in the boundary cache (:mod:`csgnb.octree.piece_cache`) for every octree node and more rows: by
        compaction when at most half its rows are live, else by growth."""
        pc = self.ws.pc
        used = int(pc.counts[USED])
        live = int(pc.length[valid_entries(pc, self.oc)].sum())
        if live < used // 2:
            pc = compacted_piece_cache(pc, self.oc, used)
        else:
            pc = grown_piece_cache(pc, 0, 2 * pc.rows.shape[0])
        self.ws = self.ws._replace(pc=grown_piece_cache(pc, self.oc.child.shape[0], 0))

    def _maybe_compact(self) -> None:
        used = int(self.oc.counts[N_POOL])
        live = int(self.oc.counts[POOL_LIVE])
        if used > 4096 and live < used // 2:
            self._compact_pool()

    def _maybe_compact_palette(self) -> None:
        used = int(self.oc.counts[N_PAL])
        if used >= max(PALETTE_COMPACT_ROWS, 2 * self._palette_kept):
            self._compact_palette()

    def _compact_palette(self) -> None:
        """Drop the palette rows no cell's BSP and no wall map entry uses; renumber the rest in their order.

        Rows keep their relative order, so every decision a kernel makes by comparing rows is unchanged and the
        workpiece stays the same solid with the same canonical arrays (:meth:`_arrays` drops the same rows). Only
        done when at most ``PALETTE_COMPACT_LIVE`` of the rows are live; otherwise the next check waits for twice as
        many rows. The volume cache, whose keys name palette rows, is re-keyed.
        """
        used = int(self.oc.counts[N_PAL])
        self._compact_pool()  # every pool row then belongs to a live cell
        pc = compacted_piece_cache(self.ws.pc, self.oc)  # and every cached row to a valid entry
        self.ws = self.ws._replace(pc=pc)
        n = int(self.oc.counts[N_POOL])
        piece_rows = pc.rows[: int(pc.counts[USED])]
        live = _live_planes(self.pool.plane[:n], self.amap, piece_rows)
        if live.shape[0] > PALETTE_COMPACT_LIVE * used:
            self._palette_kept = used
            return
        remap = _renumbering(live, used)
        cells = old_keys = None
        if len(self._volumes):  # the volume cache's keys name palette rows (nothing to re-key when it is empty)
            leaves = self._leaves()
            cells = leaves[self.oc.kind[leaves] == BSP].tolist()
            old_keys = [cell_key(self, c) for c in cells]
        plane = self.pool.plane[:n]
        inner = plane >= 0
        plane[inner] = remap[plane[inner]]
        # cached pieces: edge planes and supports as stored (>= 0), flipped supports as ~row
        up = piece_rows >= 0
        piece_rows[up] = remap[piece_rows[up]]
        piece_rows[~up] = ~remap[~piece_rows[~up]]
        if cells is not None:
            self._volumes.rekey({k: cell_key(self, c) for k, c in zip(old_keys, cells, strict=True)})
        walls = self.amap.keys >= 0
        self.amap.rows[walls] = remap[self.amap.rows[walls]]
        k = live.shape[0]
        palette = np.zeros((max(256, k + max(k // 2, 1024)), 4), self.palette.dtype)
        palette[:k] = self.palette[live]
        self.palette = palette
        self.ws = with_palette(self.ws, palette)
        self.oc.counts[N_PAL] = k
        self._palette_kept = k

    def _compact_pool(self) -> None:
        leaves = self._leaves()
        bsp = leaves[self.oc.kind[leaves] == BSP]
        lengths = self.oc.length[bsp].astype(np.int64)
        total = int(lengths.sum())
        pool = new_pool(max(1024, 2 * total))
        # the cells' rows back to back in leaf order: one gather per array (a Python loop over ~10^4 cells cost
        # ~8 ms a compaction on the drill)
        new_start = np.zeros(bsp.shape[0], np.int64)
        np.cumsum(lengths[:-1], out=new_start[1:])
        rows = np.repeat(self.oc.start[bsp].astype(np.int64) - new_start, lengths) + np.arange(total)
        for dst, src in zip(pool, self.pool, strict=True):
            dst[:total] = src[rows]
        rekeyed_piece_cache(self.ws.pc, bsp, self.oc.start[bsp].astype(np.int64), new_start)
        self.oc.start[bsp] = new_start
        at = total
        self.pool = pool
        self.oc.counts[N_POOL] = at
        self.oc.counts[POOL_LIVE] = at

    # -- queries -------------------------------------------------------------------------

    def _labels_present(self) -> list[int]:
        leaves = self._leaves()
        labels = set(int(x) for x in self.oc.label[leaves[self.oc.kind[leaves] == UNIFORM]])
        for node in leaves[self.oc.kind[leaves] == BSP]:
            s, n = int(self.oc.start[node]), int(self.oc.length[node])
            lab = self.pool.label[s:s + n]
            labels.update(int(x) for x in np.unique(lab[self.pool.plane[s:s + n] < 0]))
        return sorted(labels | {0})

    def _leaves(self) -> np.ndarray:
        out = np.empty(int(self.oc.counts[N_NODES]), np.int64)
        n = int(K._leaf_list(self.oc, out))
        return out[:n]

    def cells_meeting(self, lo, hi) -> np.ndarray:
        """The leaves (octree node ids, ``(k,) int64``) whose box meets the open box ``(lo, hi)`` (grid units).

        Node ids name cells until the next Boolean (which may split, combine or replace them)."""
        return self._leaves_meeting(check_corner(lo, "lo"), check_corner(hi, "hi"))

    def cell_box(self, node: int) -> tuple[np.ndarray, int]:
        """Leaf ``node``'s box: its low corner ``(3,) int64`` and edge length (grid units)."""
        self._check_leaf(node)
        return self.oc.lo[node].copy(), int(self.oc.size[node])

    def _check_leaf(self, node) -> None:
        n = int(self.oc.counts[N_NODES])
        if not isinstance(node, int | np.integer) or not 0 <= int(node) < n or self.oc.child[node] >= 0:
            raise GeometryError(f"{node!r} is not a leaf of this workpiece (cells(), cells_meeting() list them)")

    def _leaves_meeting(self, lo, hi) -> np.ndarray:
        out = np.empty(64, np.int64)
        lo = np.asarray(lo, np.int64)
        hi = np.asarray(hi, np.int64)
        n = int(K._leaves_meeting_box(self.oc, lo, hi, out))
        if n > out.shape[0]:
            out = np.empty(n, np.int64)
            K._leaves_meeting_box(self.oc, lo, hi, out)
        return out[:n]

    @property
    def n_cells(self) -> int:
        """Number of octree leaves."""
        return int(self._leaves().shape[0])

    @property
    def n_bsp_nodes(self) -> int:
        """BSP nodes over all cells."""
        leaves = self._leaves()
        return int(self.oc.length[leaves[self.oc.kind[leaves] == BSP]].sum())

    def cells(self) -> dict[str, np.ndarray]:
        """The octree leaves: ``lo`` (k, 3), ``size``, ``kind`` (0 uniform, 1 BSP), ``label``, ``nodes`` (BSP size)."""
        leaves = self._leaves()
        return {"node": leaves, "lo": self.oc.lo[leaves].copy(), "size": self.oc.size[leaves].copy(),
                "kind": self.oc.kind[leaves].copy(), "label": self.oc.label[leaves].copy(),
                "nodes": np.where(self.oc.kind[leaves] == BSP, self.oc.length[leaves], 0)}

    def cell_bsp(self, node: int) -> BSPTree:
        """The BSP of leaf ``node`` over a palette of only the planes it uses (a copy).

        The workpiece's palette holds every plane any cell ever used (hundreds of thousands
        after a long run); a cell's extraction copies its tree's palette, so it gets its own.
        """
        self._check_leaf(node)
        if self.oc.kind[node] != BSP:
            raise GeometryError(f"octree node {node} is a uniform leaf (label {int(self.oc.label[node])}), no BSP")
        s, n = int(self.oc.start[node]), int(self.oc.length[node])
        p = self.pool
        plane = p.plane[s:s + n]
        used, local = np.unique(plane[plane >= 0], return_inverse=True)
        rows = plane.copy()
        rows[plane >= 0] = local.astype(np.int32)
        return BSPTree(self.palette[used], rows, p.neg[s:s + n].copy(), p.pos[s:s + n].copy(),
                       p.label[s:s + n].copy(), validate=False)

    def global_tree(self) -> BSPTree:
        """The whole workpiece as one BSP (octree axis-BSPs over the cells' BSPs), in the root box."""
        n = int(_global_size(self.oc))
        need = np.zeros(4, np.int64)
        for _ in range(_MAX_RESUMPTIONS):
            self._palette_room(64)
            t = new_tree_arrays(n)
            if _global_tree_kernel(self.palette, self.oc, self.pool, self.amap, t, need):
                break
            self._grow(int(need[0]))
        return BSPTree(self.palette[: int(self.oc.counts[N_PAL])].copy(), t.plane[:n], t.neg[:n], t.pos[:n],
                       t.label[:n], validate=False)

    def to_bsp(self) -> SolidBSP:
        """The workpiece as a :class:`csgnb.bsp.BSP` (the global tree in the root box)."""
        return SolidBSP(self.global_tree(), self.root_lo, self.root_lo + self.root_size)

    def classify(self, points) -> np.ndarray:
        """Labels of points: integer ``(n, 3)`` grid points or homogeneous wide ``(n, 4)`` (-2: on the boundary)."""
        p = points if isinstance(points, np.ndarray) and points.dtype.names else None
        if p is None:  # grid points: integers, or integral floats (2.0), converted exactly; 2.5 is refused
            q = integer_array(points, "points")
            if q.ndim not in (1, 2) or q.shape[-1] != 3:
                raise GeometryError(f"points must be integer grid points (n, 3) or wide homogeneous (n, 4), "
                                    f"got shape {q.shape}")
            p = homogeneous_points(np.atleast_2d(q), self.width)
        return self.global_tree().classify(p)

    def volume(self) -> Fraction:
        """Exact volume (grid units cubed): the cells' volumes (cached by cell content), summed pairwise."""
        return self._volumes.total(self, self._leaves())

    def cell_volume(self, node: int) -> Fraction:
        """Exact solid volume of leaf ``node`` (grid units cubed), cached by the cell's content."""
        self._check_leaf(node)
        return self._volumes.volume(self, int(node))

    def model_volume(self) -> Fraction:
        """Exact volume in model units cubed (the grid scale is a power of two)."""
        return self.grid.model_volume(self.volume())

    def surface(self, *, merged: bool = False) -> BoundarySurface:
        """The exact, closed, conforming boundary (faces between solid cells removed, no T-junctions).

        ``merged=True`` joins the pieces a face was cut into by the cell walls back into larger convex
        polygons (:meth:`BoundarySurface.merged`: same vertices and solid, fewer polygons)."""
        ex = extract_boundary(self.global_tree(), self.root_lo, self.root_lo + self.root_size, keep_cells=False)
        return ex.surface.merged() if _flag(merged, "merged") else ex.surface

    def to_polydata(self, manifold: bool = False, *, merged: bool = False):
        """The boundary as a triangulated pyvista ``PolyData`` in model units (positions correctly rounded).

        ``manifold=True`` duplicates vertices along edges shared by four faces, so every edge has
        exactly two triangles (what manifold3d and other 2-manifold consumers need). ``merged=True``
        triangulates :meth:`surface` ``(merged=True)``: the same solid in fewer triangles (the faces'
        pieces joined across cell walls, the vertices that were corners of nothing dropped).
        """
        mesh = self.surface(merged=_flag(merged, "merged")).to_polydata(manifold=_flag(manifold, "manifold"))
        mesh.points = self.grid.to_model(mesh.points)
        return mesh

    def to_mesh(self, manifold: bool = False, *, merged: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Float vertices ``(n, 3)`` in model units and outward triangles ``(m, 3) int64`` of the boundary
        (``merged``: as for :meth:`to_polydata`)."""
        return self.surface(merged=_flag(merged, "merged")).to_mesh(_flag(manifold, "manifold"),
                                                                     transform=self.grid.to_model)

    def to_trimesh(self, manifold: bool = False):
        """The boundary as a ``trimesh.Trimesh`` in model units (trimesh is optional: ``pip install trimesh``)."""
        return self.surface().to_trimesh(_flag(manifold, "manifold"), transform=self.grid.to_model)

    def save_mesh(self, path, *, manifold: bool = False, file_format: str | None = None, merged: bool = False):
        """Write the boundary in model units through meshio (``.stl``, ``.obj``, ``.ply``, ...); return the path.

        ``save`` / ``load`` keep the exact workpiece; this writes the float triangles other tools read
        (``merged=True``: fewer of them, as for :meth:`to_polydata`).
        """
        if not isinstance(path, str | os.PathLike):
            raise TypeError(f"path must be a file name, got {type(path).__name__}")
        if file_format is None and Path(path).suffix.lower() not in _MESH_SUFFIXES:
            raise GeometryError(f"cannot tell the mesh format of {str(path)!r}: end it in "
                                f"{', '.join(sorted(_MESH_SUFFIXES))} or pass file_format= (a meshio format name)")
        return self.surface(merged=_flag(merged, "merged")).save(path, _flag(manifold, "manifold"), self.grid.to_model,
                                                                 file_format)

    def __repr__(self) -> str:
        return (f"Workpiece({self.n_cells} cells, {self.n_bsp_nodes} BSP nodes, {self.width}-bit, "
                f"threshold {self.threshold})")


_MESH_SUFFIXES = {".stl", ".obj", ".ply", ".off", ".vtk", ".vtu"}


def _flag(value, name: str) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be True or False, got {value!r:.40}")
    return bool(value)


def _real_corner(value, name: str) -> np.ndarray:
    """A model-unit box corner as ``(3,) float64``; a clear error for another shape or a non-number."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a point of 3 real numbers, got {value!r}") from None
    if arr.size != 3:
        raise GeometryError(f"{name} must be a point of 3 coordinates, got shape {arr.shape}")
    return arr.reshape(3)


def _box_hull(lo, hi, width: int) -> ConvexHull:
    from csgnb.mesh.hull import convex_hull

    lo = np.asarray(lo, np.int64)
    hi = np.asarray(hi, np.int64)
    corners = np.array([[(hi if k & (1 << a) else lo)[a] for a in range(3)] for k in range(8)], np.int64)
    return convex_hull(corners, width=width)


def _mesh_arrays(vertices, faces):
    """(V, F) from arrays, a pyvista PolyData, a trimesh.Trimesh or a mesh file path (meshio)."""
    if faces is not None:
        return np.asarray(vertices), np.asarray(faces)
    obj = vertices
    if isinstance(obj, str) or hasattr(obj, "__fspath__"):
        import meshio

        if not os.path.exists(obj):
            raise FileNotFoundError(f"no mesh file {obj!r}")
        try:
            mesh = meshio.read(obj)
        except meshio.ReadError as exc:
            raise GeometryError(f"cannot read {obj} as a mesh ({exc}); meshio reads .stl, .obj, .ply, .off, ...") \
                from None
        tris = [c.data for c in mesh.cells if c.type == "triangle"]
        if not tris:
            raise GeometryError(f"{obj} has no triangles (cell types: {[c.type for c in mesh.cells]})")
        return np.asarray(mesh.points), np.concatenate(tris)
    if hasattr(obj, "faces") and hasattr(obj, "vertices"):  # trimesh
        return np.asarray(obj.vertices), np.asarray(obj.faces)
    if hasattr(obj, "points") and hasattr(obj, "faces"):  # pyvista
        tri = obj.triangulate()
        return np.asarray(tri.points), np.asarray(tri.faces).reshape(-1, 4)[:, 1:]
    raise TypeError(f"expected (vertices, faces), a pyvista or trimesh mesh, or a file path; got {type(obj).__name__}")


def _reinsert(keys: np.ndarray, rows: np.ndarray, new: AxisMap) -> None:
    mask = new.keys.shape[0] - 1
    for key, row in zip(keys.tolist(), rows.tolist(), strict=True):
        h = ((key * -7046029254386353131) & ((1 << 64) - 1))
        h = (h - (1 << 64) if h >= (1 << 63) else h) >> 20
        i = h & mask
        while new.keys[i] != -1:
            i = (i + 1) & mask
        new.keys[i] = key
        new.rows[i] = row

