"""Tools for the octree workpiece: convex hulls, closed meshes and BSPs, placed by exact integer translations.

A :class:`Tool` keeps its geometry in its own plane space (Python-int planes, plane-based
polygons over them, a BSP of the whole tool) so that it is prepared once and reused at any
integer offset: translating by ``t`` changes each plane's offset exactly, ``d' = d - n·t``,
and nothing else (the paper reuses its precomputed drill sweeps this way).

* **convex** (a :class:`~csgnb.mesh.hull.ConvexHull`): its outward facet planes; per cell the
  kernels keep the planes that cross the cell box (a linear BSP);
* **mesh** (a closed integer triangle mesh, validated like :meth:`csgnb.bsp.BSP.from_mesh`,
  or the exact boundary of a :class:`csgnb.bsp.BSP`): plane-based polygons; per cell the
  kernels clip the polygons to the box and build a small BSP from the pieces (§3.9);
* **empty** (a BSP with no material, e.g. an empty workpiece's ``to_bsp()``): a difference or
  union with it changes nothing, an intersection empties the workpiece.
"""

from __future__ import annotations

import numpy as np

from csgnb._jit import jit
from csgnb.bsp.build import bsp_from_polygons, validate_mesh
from csgnb.bsp.polygon import PolygonSet, polygons_from_triangles
from csgnb.bsp.winding import check_fill, winding_boundary
from csgnb.errors import GeometryError
from csgnb.exact.integral import integer_array, max_abs
from csgnb.exact.intrinsics import signed_distance_into, translate_point_into
from csgnb.exact.wide import from_wide, is_wide, to_wide, wide_dtype, wide_max_abs, width_of
from csgnb.exact.wide_store import store_int64_at
from csgnb.mesh.hull_facets import FacetPolygons, hull_facet_polygons

__all__ = ["Tool", "split_planes_wide"]


@jit
def spread_order(normals):
    """A farthest-first order of the directions ``normals[:, :3]`` (``(k, >= 3)``, integers or floats, not necessarily
    unit; a tool's ``(k, 4)`` planes will do): the first, then repeatedly the one whose largest cosine to those
    already chosen is smallest. ``(k,)`` int64.

    A convex tool's planes reach a cell in this order (its linear BSP): a cell beside the tool
    meets a plane facing it among the first few, and the walk through the chain ends there. In
    the hull's lexicographic order, neighbouring planes face nearly the same way, and a cell on
    the far side walked through most of them first (a dome carve's merges: -15 % time).
    """
    k = normals.shape[0]
    unit = np.empty((k, 3))
    for i in range(k):
        x, y, z = float(normals[i, 0]), float(normals[i, 1]), float(normals[i, 2])
        r = np.sqrt(x * x + y * y + z * z)
        unit[i, 0], unit[i, 1], unit[i, 2] = x / r, y / r, z / r
    order = np.empty(k, np.int64)
    taken = np.zeros(k, np.bool_)
    closest = np.full(k, -2.0)
    pick = 0
    for j in range(k):
        order[j] = pick
        taken[pick] = True
        best, nxt = 2.0, -1
        for i in range(k):
            if taken[i]:
                continue
            c = unit[i, 0] * unit[pick, 0] + unit[i, 1] * unit[pick, 1] + unit[i, 2] * unit[pick, 2]
            if c > closest[i]:
                closest[i] = c
            if closest[i] < best:
                best, nxt = closest[i], i
        pick = nxt
    return order


@jit
def convex_tool_tree(rows):
    """The linear BSP of a convex tool over its palette ``rows`` ``(k,) int64``: node arrays ``plane, neg, pos, label``
    ``(2k + 1,) int32`` -- node 2i tests row i (outside: an out leaf at 2i + 1; inside: on to 2i + 2), node 2k is
    the in leaf. One compiled call instead of four allocations and index assignments per Boolean."""
    k = rows.shape[0]
    plane = np.full(2 * k + 1, -1, np.int32)
    neg = np.full(2 * k + 1, -1, np.int32)
    pos = np.full(2 * k + 1, -1, np.int32)
    label = np.zeros(2 * k + 1, np.int32)
    for i in range(k):
        plane[2 * i] = rows[i]
        neg[2 * i] = 2 * i + 2
        pos[2 * i] = 2 * i + 1
        label[2 * i] = -1
    label[2 * k] = 1
    return plane, neg, pos, label


@jit
def store_int64_rows(palette, start, values):
    """Write int64 ``values`` (k, c) into rows ``start:start + k`` of the wide array ``palette`` (sign-extended,
    exact: :func:`csgnb.exact.wide_store.store_int64_at`) -- what ``to_wide`` and a slice assignment do, in one
    compiled pass without the wide copy."""
    for j in range(values.shape[0]):
        for c in range(values.shape[1]):
            store_int64_at(palette, start + j, c, values[j, c])


_SMALL = 1 << 62  # int64 planes stay below this, so a sum of two never overflows


def _as_int64(values: np.ndarray, bound: int) -> np.ndarray | None:
    """``values`` (Python ints) as int64 when every one is within ±``bound`` (< 2⁶³), else None."""
    try:
        small = values.astype(np.int64)
    except OverflowError:
        return None
    return small if small.size == 0 or int(np.abs(small).max()) < bound else None


def _object_planes(planes) -> np.ndarray:
    """(k, 4) object array of Python ints from int64 / object / wide planes."""
    if is_wide(planes):
        return from_wide(planes).astype(object).reshape(-1, 4)
    p = np.asarray(planes)
    if p.dtype == object:
        if p.size and set(map(type, p.reshape(-1).tolist())) <= {int}:  # Python ints already: one pass over types
            return p.reshape(-1, 4).copy()
        return np.array([[int(x) for x in row] for row in p], dtype=object).reshape(-1, 4)
    if p.dtype.kind not in "iu":
        raise TypeError(f"planes must be integers, got dtype {p.dtype}")
    return p.astype(object).reshape(-1, 4)


def _exact_planes(planes, *, python_ints: bool = False) -> np.ndarray:
    """(k, 4) exact planes: int64 when every value is within ±2⁶² (the common case: no Python ints
    on the per-Boolean path), else an object array of Python ints. ``python_ints``: an object
    array already holds Python ints (not numpy scalars), so it is not rebuilt."""
    p = planes if isinstance(planes, np.ndarray) else np.asarray(planes)
    if p.dtype == np.int64:
        if p.size == 0 or (int(p.max()) < _SMALL and int(p.min()) > -_SMALL):  # no |p| copy: two reductions
            return p.reshape(-1, 4)
        return p.astype(object).reshape(-1, 4)
    obj = p.reshape(-1, 4) if python_ints and p.dtype == object else _object_planes(p)
    small = _as_int64(obj, _SMALL)
    return obj if small is None else small


@jit
def _moved_offsets_kernel(planes, minus_t, out):
    """``out[i] = d_i - n_i·t`` of the wide planes ``planes`` (k, 4) moved by ``t`` (``minus_t`` = -t as a (1, 3) int64
    row): the signed distance of the point -t, at the planes' width (callers bound it)."""
    for i in range(planes.shape[0]):
        signed_distance_into(minus_t, 0, planes, i, out, i)


@jit
def _moved_points_kernel(points, shift, out):
    for i in range(points.shape[0]):
        translate_point_into(points, i, shift, 0, out, i)


def moved_points(points: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Homogeneous wide points ``(m, 4)`` moved by the integer vector ``t`` (3,): ``(x + t·x4, x4)`` each, a new array
    of their width -- the vertices of the polygons of a tool translated by ``t``, bit for bit (see
    :func:`csgnb.exact.intrinsics.translate_point_into`); the caller keeps them within the width."""
    out = np.empty_like(points)
    _moved_points_kernel(points, np.asarray(t, np.int64).reshape(1, 3), out)
    return out


def split_planes_wide(N: np.ndarray, d: np.ndarray, width: int) -> np.ndarray:
    """``(k, 4)`` wide planes of ``width`` bits from int64 normals ``N`` (k, 3) and offsets ``d`` (k,) (int64 or
    Python ints): the normals in numpy's int64 loops, the offsets' column as bytes -- no (k, 4) object array."""
    wide = np.empty((N.shape[0], 4), wide_dtype(width))
    wide[:, :3] = to_wide(N, width)
    wide[:, 3] = to_wide(d, width)
    return wide


class Tool:
    """A solid to combine with a workpiece, in grid coordinates (see the module docstring).

    Build one with :meth:`from_hull`, :meth:`from_mesh` or :meth:`from_bsp`; workpiece
    Booleans also accept those objects directly. ``lo``/``hi`` bound the tool's points.
    A tool is never changed in place (:meth:`translated` makes a new one): its wide planes,
    polygon geometry and content digest are cached on it.
    """

    def __init__(self, kind: str, planes: np.ndarray | None, lo, hi, *, polygons: PolygonSet | None = None,
                 tree=None, grid=None, _exact: bool = False, _split: tuple | None = None) -> None:
        self.kind = kind
        if _split is not None:  # (N int64, d): ``planes`` is made from them on first use (__getattr__)
            self._split = _split
        else:
            # (k, 4) exact: int64 below 2**62, else Python ints (object); ``_exact``: the caller made them so already
            self.planes = planes if _exact else _exact_planes(planes)
        self.lo = np.asarray(lo, np.int64).reshape(3)
        self.hi = np.asarray(hi, np.int64).reshape(3)
        self.polygons = polygons
        self.tree = tree  # (plane, neg, pos, label) over this tool's plane rows, or None (convex)
        self.grid = grid
        self.offset = np.zeros(3, np.int64)
        self._wide: dict[int, np.ndarray] = {}

    # -- construction -----------------------------------------------------------

    @classmethod
    def from_hull(cls, hull) -> Tool:
        """A convex tool from a :class:`~csgnb.mesh.hull.ConvexHull` (its exact facet planes, in
        :func:`spread_order`)."""
        from csgnb.mesh.hull import ConvexHull

        if not isinstance(hull, ConvexHull):
            raise TypeError(f"Tool.from_hull takes a csgnb.mesh.hull.ConvexHull, got {type(hull).__name__}")
        split = hull._split_planes()
        if split is not None and split[1].dtype == object:
            # offsets beyond int64 (a 256-bit grid's hulls): int64 normals and a column of Python ints, the same
            # order as below, and no (k, 4) object array unless someone asks for ``planes``
            N, d = split
            order = np.arange(N.shape[0], dtype=np.int64)
            if N.shape[0] > 4:
                order = spread_order(N.astype(np.float64))
                N, d = N[order], d[order]
            tool = cls("convex", None, hull.lo, hull.hi, grid=getattr(hull, "grid", None), _split=(N, d))
        else:
            planes = _exact_planes(hull.planes)
            order = np.arange(planes.shape[0], dtype=np.int64)
            if planes.shape[0] > 4:
                order = spread_order(planes if planes.dtype == np.int64 else planes[:, :3].astype(np.float64))
                planes = planes[order]
            tool = cls("convex", planes, hull.lo, hull.hi, grid=getattr(hull, "grid", None), _exact=True)
        tool._hull = (hull, order)  # its facets, made when a boundary merge first asks (facets)
        return tool

    def __getattr__(self, name: str):
        # ``planes`` made on first use: of a tool made from split planes (see from_hull), the (k, 4) Python ints; of a
        # tool translated beyond int64 (see translated), its source's planes with d - n·t in Python ints
        split = self.__dict__.get("_split")
        moved = self.__dict__.get("_translation")
        if name != "planes" or (split is None and moved is None):
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        if split is not None:
            N, d = split
            planes = np.column_stack([N.astype(object), d.astype(object)])
        else:
            base, t = moved
            planes = base.astype(object)
            planes[:, 3] = planes[:, 3] - planes[:, :3] @ t.astype(object)
            planes = _exact_planes(planes, python_ints=True)
        self.__dict__["planes"] = planes
        return planes

    @property
    def facets(self) -> FacetPolygons | None:
        """A convex tool's facets as plane-based polygons over its planes (:data:`csgnb.mesh.hull_facets.
        FacetPolygons`), made on first use; None for other tools and for hulls the compiled pass does not take."""
        found = self.__dict__.get("_facets", False)
        if found is False:
            found = None
            source = self.__dict__.get("_hull")
            if source is not None:
                found = _shifted(hull_facet_polygons(*source), self.offset)
            self._facets = found
        return found

    @property
    def split_planes(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(N (k, 3) int64, d (k,) Python ints)`` when the tool keeps its planes split (a hull whose offsets exceed
        int64: the workpiece then writes them without a (k, 4) object array), else None."""
        return self.__dict__.get("_split")

    @classmethod
    def from_mesh(cls, vertices, faces, *, width: int, grid=None, seed: int = 0, fill: str = "solid") -> Tool:
        """A tool bounded by a closed, outward, non-self-intersecting integer triangle mesh (grid coordinates).

        ``fill="winding"``: any closed mesh, overlapping, crossing or folded, as the points it winds around
        positively (:mod:`csgnb.bsp.winding`): the tool's polygons are that solid's exact boundary.
        """
        if check_fill(fill) == "winding":
            palette, polygons = winding_boundary(vertices, faces, width=width)
            W = integer_array(vertices, "vertices")
            if not len(polygons):  # it winds around nothing
                return cls("empty", np.zeros((0, 4), object), np.zeros(3, np.int64), np.zeros(3, np.int64), grid=grid)
        else:
            W, T = validate_mesh(vertices, faces, width)
            palette, polygons = polygons_from_triangles(W, T, width)
        tree = bsp_from_polygons(palette, polygons, seed=seed)
        # bsp_from_polygons keeps the palette rows it uses, in first-use order: map them back.
        rows = _rows_of(tree.palette, palette)
        plane = np.where(tree.plane >= 0, rows[np.maximum(tree.plane, 0)], -1).astype(np.int32)
        return cls("mesh", _object_planes(palette), W.min(axis=0), W.max(axis=0), polygons=polygons,
                   tree=(plane, tree.neg, tree.pos, tree.label), grid=grid)

    @classmethod
    def from_bsp(cls, bsp, *, grid=None, seed: int = 0) -> Tool:
        """A tool from a :class:`csgnb.bsp.BSP`: its exact boundary (plane-based pieces) and its tree."""
        from csgnb.bsp.solid import BSP

        if not isinstance(bsp, BSP):
            raise TypeError(f"Tool.from_bsp takes a csgnb.bsp.BSP, got {type(bsp).__name__}")
        from csgnb.bsp.extract import PIECES, WALLS, Extractor, pieces_tuple

        ex = Extractor(bsp.tree, bsp.lo, bsp.hi, PIECES | WALLS, 1024).run()
        palette, vx, edge, poly = pieces_tuple(ex.store.planes.copy(), ex.out)
        sizes = poly[:, 1]
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32)
        # import convention: edge j runs from vertex j - 1 to vertex j: each polygon's edges rolled by one
        first = np.repeat(poly[:, 0].astype(np.int64), sizes)
        count = np.repeat(sizes.astype(np.int64), sizes)
        local = np.arange(offsets[-1]) - np.repeat(offsets[:-1].astype(np.int64), sizes)
        edges = edge[first + (local - 1) % count] if len(sizes) else np.zeros(0, np.int64)
        polygons = PolygonSet(poly[:, 2].astype(np.int32), offsets, edges.astype(np.int32))
        if not len(sizes):  # no boundary in its box (walls included): no material at all
            return cls("empty", np.zeros((0, 4), object), np.zeros(3, np.int64), np.zeros(3, np.int64), grid=grid)
        lo, hi = np.asarray(bsp.lo), np.asarray(bsp.hi)
        if len(sizes):
            from csgnb.exact.predicates import to_double_position

            pos = to_double_position(vx)
            lo = np.floor(pos.min(axis=0)).astype(np.int64)
            hi = np.ceil(pos.max(axis=0)).astype(np.int64)
        n = bsp.tree.palette.shape[0]
        tree = (bsp.tree.plane.copy(), bsp.tree.neg, bsp.tree.pos, bsp.tree.label)
        del n
        return cls("mesh", _object_planes(palette), lo, hi, polygons=polygons, tree=tree, grid=grid)

    # -- placement ------------------------------------------------------------------

    def translated(self, t) -> Tool:
        """The tool moved by the integer vector ``t`` (exact: ``d' = d - n·t``)."""
        t = np.asarray(t)
        if t.shape != (3,) or t.dtype.kind not in "iu":
            raise TypeError(f"a translation must be a (3,) integer vector, got {t.dtype} {t.shape}")
        moved = Tool.__new__(Tool)
        lazy = self._pending_translation
        planes = None if lazy is not None else self.planes
        moved.__dict__.update(self.__dict__)
        moved.__dict__.pop("_split", None)  # the moved tool's planes are its own
        moved.__dict__.pop("_digests", None)  # and so is its content (csgnb.octree.workpiece._content_digest)
        moved.__dict__.pop("_extremes", None)  # and their largest coefficients
        moved.__dict__.pop("_translation", None)
        facets = moved.__dict__.pop("_facets", False)
        if facets is not False:  # made already: moved with the planes
            moved._facets = _shifted(facets, t.astype(np.int64))
        shift = int(np.abs(t).max(initial=0))
        if lazy is not None:  # this tool's own planes were never made: move its source's by both translations
            moved.__dict__.pop("planes", None)
            moved._translation = (lazy[0], lazy[1] + t.astype(np.int64))
        elif planes.dtype == np.int64 and planes.size and \
                3 * int(np.abs(planes[:, :3]).max()) * shift + int(np.abs(planes[:, 3]).max()) < _SMALL:
            planes = planes.copy()  # no value can overflow: exact in int64
            planes[:, 3] -= planes[:, :3] @ t.astype(np.int64)
            moved.planes = _exact_planes(planes, python_ints=True)
        else:
            # offsets beyond int64 (a 256-bit drill's tools): the (k, 4) Python ints only when someone asks for
            # ``planes``; a workpiece takes the wide planes, moved from the source's in a compiled loop (planes_wide)
            moved.__dict__.pop("planes", None)
            moved._translation = (planes, t.astype(np.int64))
        moved.lo = self.lo + t.astype(np.int64)
        moved.hi = self.hi + t.astype(np.int64)
        moved.offset = self.offset + t.astype(np.int64)
        moved._wide = {}
        moved._geometry = {}  # polygon vertices and boxes (csgnb.octree.workpiece): moved with the planes
        source, shift = self.__dict__.get("_moved_from", (self, np.zeros(3, np.int64)))
        moved._moved_from = (source, shift + t.astype(np.int64))  # its boxes, moved, are this tool's boxes
        return moved

    def __getstate__(self) -> dict:
        # A pickled tool (sent to a Dask worker) travels without the tool it was translated from.
        state = dict(self.__dict__)
        state.pop("_moved_from", None)
        state.pop("_digests", None)  # recomputed where it is used (a moved tool arrives without its source)
        if "_hull" in state:  # a convex tool travels with its facets, not with the hull they came from
            state["_facets"] = self.facets
            del state["_hull"]
        return state

    def planes_wide(self, width: int) -> np.ndarray:
        """The planes as a ``(k, 4)`` wide array (cached per width)."""
        if width not in self._wide:
            split = self.split_planes
            moved = None if split is not None else self._moved_wide(width)
            if split is not None:
                self._wide[width] = split_planes_wide(*split, width)
            elif moved is not None:
                self._wide[width] = moved
            else:
                # int64 planes (the common case) take to_wide's vectorised path, no Python ints
                self._wide[width] = to_wide(self.planes, width)
        return self._wide[width]

    @property
    def _pending_translation(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(source planes, t)`` while this tool's own planes, translated beyond int64, are not made yet; else None."""
        return None if "planes" in self.__dict__ else self.__dict__.get("_translation")

    def _moved_wide(self, width: int) -> np.ndarray | None:
        """A translated tool's wide planes from its source's at ``width`` bits: ``d - n·t`` for every row in a
        compiled loop (exact: no value can wrap, checked first from the source's largest coefficients), instead of
        ``(k, 4)`` Python ints converted limb by limb (a 256-bit drill tool's ~7,000 planes: ~4 ms a step). None
        when the tool was not translated from a source, or the check cannot promise the width."""
        source, shift = self.__dict__.get("_moved_from", (None, None))
        if source is None or self._pending_translation is None:
            return None
        normal, offset = source.plane_extremes(width)
        if offset + 3 * normal * int(np.abs(shift).max(initial=0)) >= 1 << (width - 1):
            return None
        base = source.planes_wide(width)
        d = np.empty(base.shape[0], base.dtype)
        _moved_offsets_kernel(base, (-shift).astype(np.int64).reshape(1, 3), d)
        wide = base.copy()
        wide[:, 3] = d
        self.__dict__.setdefault("_extremes", {})[width] = (normal, wide_max_abs(d))
        return wide

    def plane_extremes(self, width: int) -> tuple[int, int]:
        """The largest |normal coefficient| and |offset| of the planes, exact Python ints (cached per width): what a
        workpiece checks against its budget. A tool translated beyond int64 takes them from its wide planes (the
        normals are its source's), without making its ``(k, 4)`` Python ints."""
        cache = self.__dict__.setdefault("_extremes", {})
        if width not in cache:
            if self._pending_translation is not None:
                self.planes_wide(width)  # fills the cache when the compiled translation applies
            if width not in cache:
                split = self.split_planes
                if split is not None:
                    cache[width] = (max_abs(split[0]), max_abs(split[1]))
                else:
                    planes = self.planes
                    cache[width] = (max_abs(planes[:, :3]), max_abs(planes[:, 3])) if planes.shape[0] else (0, 0)
        return cache[width]

    @property
    def n_planes(self) -> int:
        """Number of planes."""
        split = self.split_planes
        if split is not None:
            return int(split[0].shape[0])
        pending = self._pending_translation
        if pending is not None:
            return int(pending[0].shape[0])
        return int(self.planes.shape[0])

    def __repr__(self) -> str:
        what = f"{len(self.polygons)} polygons" if self.polygons is not None else f"{self.n_planes} facets"
        return f"Tool({self.kind}, {what}, box {self.lo.tolist()}..{self.hi.tolist()})"


def _shifted(facets: FacetPolygons | None, t: np.ndarray) -> FacetPolygons | None:
    """``facets`` moved by the integer vector ``t`` (3,) int64: their points and boxes; planes are named, not
    stored."""
    if facets is None or not t.any():
        return facets
    support, offsets, edges, points, lo, hi = facets
    return support, offsets, edges, points + t, lo + t, hi + t


def _rows_of(subset: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """For each row of the wide ``subset``, its row in ``palette`` (exact equality of limbs)."""
    if subset.shape[0] == 0:
        return np.zeros(0, np.int64)
    if width_of(subset) != width_of(palette):
        raise GeometryError("palettes of different widths")
    key = np.ascontiguousarray(palette).view(np.dtype((np.void, palette.dtype.itemsize * 4))).reshape(-1)
    sub = np.ascontiguousarray(subset).view(np.dtype((np.void, palette.dtype.itemsize * 4))).reshape(-1)
    index = {bytes(k): i for i, k in enumerate(key)}
    return np.array([index[bytes(k)] for k in sub], np.int64)
