"""Exact boundary surfaces: shared exact vertices, convex polygons, no T-junctions (paper §3.4).

:func:`assemble_surface` turns the raw boundary pieces of extraction (each polygon with
its own copies of its vertices and, per edge, the plane the edge lies on) into a
:class:`BoundarySurface`, in four numba kernels (:mod:`csgnb.bsp.surface_kernels`), exact
throughout and without gcds:

1. vertices are merged by exact identity: candidates share their correctly rounded double
   position (equal points round equally), equality is decided by cross-multiplication;
2. T-junctions are removed: edges are grouped by their exact supporting line (a canonical,
   correctly rounded key of the two planes meeting there, confirmed exactly), the line's
   vertices are ordered exactly along it, and every edge receives the vertices strictly
   inside it as valence-2 vertices. Afterwards every edge of a closed solid is used exactly
   twice, in opposite directions (four times where two solid cells touch along it).

:class:`BoundarySurface` exports what a user of the surface needs: exact positions and
volumes, float triangle meshes without degenerate triangles (:meth:`BoundarySurface.to_mesh`),
an optional 2-manifold split of edges where the solid touches itself
(``manifold=True``, :mod:`csgnb.bsp.surface_mesh`), ``pyvista``, ``trimesh`` and files
through meshio (STL, OBJ, PLY).

``_assemble_surface_reference`` keeps the first, pure-Python implementation (Python ints,
gcd-reduced keys, Fractions) as the reference the tests and ``benchmarks/bench_surface.py``
compare against.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from functools import cache
from math import gcd
from pathlib import Path

import numpy as np

from csgnb.bsp import surface_kernels as K
from csgnb.bsp.surface_mesh import ManifoldSplit, TriangleMesh, manifold_split, triangulate
from csgnb.errors import GeometryError, InternalError
from csgnb.exact.budgets import check_planes
from csgnb.exact.predicates import to_double_position
from csgnb.exact.wide import from_wide, to_wide, width_of

__all__ = ["BoundarySurface", "ManifoldSplit", "TriangleMesh", "assemble_surface"]


@dataclass(frozen=True)
class BoundarySurface:
    """A closed surface of exact convex polygons, outward, sharing exact vertices.

    Attributes
    ----------
    palette : (m, 4) wide
        The planes polygons lie on.
    vertices : (n, 4) wide
        Homogeneous vertices (x1, x2, x3, x4), x4 > 0, each point once (one representative
        of it, not necessarily gcd-reduced: compare points with :meth:`exact_positions`).
    offsets : (k + 1,) int64
        Polygon ``i`` has vertices ``indices[offsets[i]:offsets[i + 1]]``, counter-clockwise seen from outside.
    indices : (offsets[-1],) int64
    support : (k,) int64
        Palette row of each polygon's plane, ``~row`` when the polygon faces the row's negative side.
    labels : (k,) int64
        Label (material) of the solid behind each polygon.
    edge_planes : (offsets[-1],) int64 or None
        Palette row of the second plane the edge from ``indices[j]`` to the next vertex lies on
        (the first is the polygon's support): the edge's line is where the two meet. Set by
        :func:`assemble_surface`; needed for ``manifold=True``.
    """

    palette: np.ndarray
    vertices: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray
    support: np.ndarray
    labels: np.ndarray
    edge_planes: np.ndarray | None = None
    _positions: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: Made by :meth:`merged` (coplanar pieces joined): its manifold split is not supported yet.
    is_merged: bool = field(default=False, compare=False)

    @property
    def n_polygons(self) -> int:
        """Number of polygons."""
        return int(self.offsets.shape[0] - 1)

    @property
    def n_vertices(self) -> int:
        """Number of distinct vertices."""
        return int(self.vertices.shape[0])

    def polygon(self, i: int) -> np.ndarray:
        """Vertex ids of polygon ``i``, ``(k,) int64``."""
        return self.indices[self.offsets[i] : self.offsets[i + 1]]

    def polygons(self) -> list[np.ndarray]:
        """All polygons as vertex-id arrays."""
        return [self.polygon(i) for i in range(self.n_polygons)]

    def positions(self) -> np.ndarray:
        """Vertex positions correctly rounded to doubles, ``(n, 3) float64`` (a new array)."""
        if self._positions is not None:
            return self._positions.copy()
        if self.n_vertices == 0:
            return np.zeros((0, 3))
        return to_double_position(self.vertices)

    def exact_positions(self) -> list[tuple[Fraction, Fraction, Fraction]]:
        """Vertex positions as exact Fractions."""
        return [tuple(Fraction(int(x[i]), int(x[3])) for i in range(3)) for x in from_wide(self.vertices)]

    def exact_volume(self, label: int | None = None) -> Fraction:
        """Return the exact enclosed volume (of the polygons of one ``label``, or all).

        Each fan triangle's term is made exactly in limbs and the terms summed in GMP
        (:func:`csgnb.mesh.volume.wide_polygons_volume`); ``polygons_volume`` of :meth:`exact_positions` is the same
        value in Fraction arithmetic, ~20x slower."""
        from csgnb.mesh.volume import wide_polygons_volume

        keep = None if label is None else np.asarray(self.labels) == label
        return wide_polygons_volume(self.vertices, self.offsets, self.indices, keep)

    def _directed_edges(self, label: int | None, indices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(tails, heads) of every polygon edge (of one ``label``, or all), ``(h,) int64`` each."""
        idx = self.indices if indices is None else indices
        sizes = np.diff(self.offsets)
        pos = np.arange(idx.shape[0])
        start = np.repeat(self.offsets[:-1], sizes)
        nxt = start + (pos - start + 1) % np.maximum(np.repeat(sizes, sizes), 1)
        keep = slice(None) if label is None else np.repeat(self.labels == label, sizes)
        return idx[keep], idx[nxt][keep]

    def edge_use(self, label: int | None = None) -> dict[tuple[int, int], int]:
        """Count of every directed edge (a, b) over the polygons (of one ``label``, or all)."""
        use: dict[tuple[int, int], int] = defaultdict(int)
        for a, b in zip(*(x.tolist() for x in self._directed_edges(label)), strict=True):
            use[a, b] += 1
        return use

    def _edge_counts(self, label: int | None, indices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Counts of every used directed edge and of its reverse (0 where unused), ``(e,) int64`` each."""
        tails, heads = self._directed_edges(label, indices)
        n = int(max(tails.max(initial=-1), heads.max(initial=-1))) + 1
        keys, counts = np.unique(tails * n + heads, return_counts=True)
        rev = (keys % n) * n + keys // n
        at = np.minimum(np.searchsorted(keys, rev), max(keys.shape[0] - 1, 0))
        return counts, np.where(keys[at] == rev, counts[at], 0) if keys.shape[0] else counts

    def is_closed(self, label: int | None = None) -> bool:
        """Whether every edge is used as often in one direction as in the other (closed, consistently oriented).

        Where a solid touches itself along an edge (two cells meeting only there), the
        edge is used twice each way; everywhere else once each way (:meth:`is_manifold`).
        """
        counts, reverse = self._edge_counts(label)
        return bool(np.all(counts == reverse))

    def is_manifold(self, label: int | None = None) -> bool:
        """Whether every directed edge is used exactly once and its reverse exactly once."""
        counts, reverse = self._edge_counts(label)
        return bool(np.all((counts == 1) & (reverse == 1)))

    def merged(self) -> BoundarySurface:
        """This surface with coplanar neighbouring pieces (a face cut by octree cell walls or splitting planes)
        joined into larger convex polygons: the same vertices and solid, fewer polygons
        (:func:`csgnb.bsp.surface_merge.merge_coplanar`)."""
        from csgnb.bsp.surface_merge import merge_coplanar

        return merge_coplanar(self)

    # -- export -------------------------------------------------------------------

    def manifold_split(self) -> ManifoldSplit:
        """Polygon loops over duplicated vertices in which every edge is used once each way.

        Per label, the faces around an edge used by four faces (2j in general: the solid
        touches itself there) are ordered exactly by angle and paired by the solid wedge
        between them; then every vertex gets one copy per fan of corners joined across paired
        edges. So vertices are duplicated along such edges, where the solid touches itself at
        a single vertex, and where two labels meet (each label becomes its own closed shell).
        A surface that needs none of this comes back unchanged (``source == arange(n)``).
        See :mod:`csgnb.bsp.surface_mesh`.
        """
        if self.is_merged:
            raise GeometryError("manifold=True (the manifold split) is not supported on a merged surface yet: where "
                                "the solid touches itself along an edge it can keep that edge shared by four "
                                "triangles; export manifold=True from the unmerged surface (merged=False)")
        return manifold_split(self)

    def triangulate(self, manifold: bool = False) -> TriangleMesh:
        """Triangles of every polygon (k - 2 each), none of zero area, with their polygons and source vertices.

        Flat vertices (the valence-2 vertices T-junction removal adds on straight sides) are
        decided exactly, and no triangle joins three points of one side. ``manifold=True``
        splits vertices first (:meth:`manifold_split`): then every edge of the triangle mesh
        has exactly two triangles.
        """
        if manifold and self.is_merged:
            self.manifold_split()  # raises: not supported on a merged surface yet
        return triangulate(self, manifold)

    def to_mesh(
        self, manifold: bool = False, transform: Callable[[np.ndarray], np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return float vertices ``(n, 3)`` (correctly rounded) and outward triangles ``(m, 3) int64``.

        ``transform`` maps the positions (e.g. ``grid.to_model`` for model units); ``manifold``
        as in :meth:`triangulate`. Per-triangle labels: ``labels[triangulate().polygon]``.
        """
        mesh = self.triangulate(manifold)
        vertices = mesh.vertices if transform is None else np.asarray(transform(mesh.vertices), np.float64)
        return vertices, mesh.triangles

    def to_trimesh(self, manifold: bool = False, transform: Callable[[np.ndarray], np.ndarray] | None = None):
        """Return a ``trimesh.Trimesh`` of :meth:`to_mesh` (not processed: vertices stay as they are).

        Face attribute ``"label"`` holds each triangle's label. trimesh is optional
        (``pip install trimesh``) and imported only here.
        """
        try:
            import trimesh
        except ImportError as err:
            raise ImportError(
                "BoundarySurface.to_trimesh needs trimesh: pip install trimesh (or use to_mesh() for plain arrays)"
            ) from err
        mesh = self.triangulate(manifold)
        vertices = mesh.vertices if transform is None else np.asarray(transform(mesh.vertices), np.float64)
        return trimesh.Trimesh(
            vertices, mesh.triangles, process=False, face_attributes={"label": self.labels[mesh.polygon]}
        )

    def save(
        self,
        path,
        manifold: bool = False,
        transform: Callable[[np.ndarray], np.ndarray] | None = None,
        file_format: str | None = None,
    ) -> Path:
        """Write the triangulated surface (:meth:`to_mesh`) to ``path`` through meshio; return the path.

        The format follows the extension (``.stl`` binary, ``.obj``, ``.ply`` binary, or anything
        else meshio writes) unless ``file_format`` names one in meshio's terms. Positions are the
        correctly rounded doubles (binary STL stores them as float32). Labels are not written:
        these formats keep no per-face data through meshio (use :meth:`triangulate` for them).
        """
        import meshio

        path = Path(path)
        vertices, triangles = self.to_mesh(manifold, transform)
        fmt = file_format or {".stl": "stl", ".obj": "obj", ".ply": "ply"}.get(path.suffix.lower())
        if triangles.shape[0] and triangles.max() < 2**31:
            triangles = triangles.astype(np.int32)  # PLY has no 64-bit integers (meshio would warn and cast)
        mesh = meshio.Mesh(vertices, [("triangle", triangles)])
        if fmt == "stl":
            meshio.write(path, mesh, file_format=fmt, binary=True)
        else:
            meshio.write(path, mesh, file_format=fmt)
        return path

    def to_polydata(self, triangulate: bool = True, manifold: bool = False):
        """Return a pyvista ``PolyData`` (positions correctly rounded; triangulated without flat triangles).

        Cell data: ``"label"`` and ``"plane"`` (palette row) per polygon or triangle.
        """
        import pyvista as pv

        plane = np.where(self.support >= 0, self.support, ~self.support)
        if triangulate:
            mesh = self.triangulate(manifold)
            faces = np.column_stack([np.full(mesh.triangles.shape[0], 3), mesh.triangles]).reshape(-1)
            out = pv.PolyData(mesh.vertices, faces.astype(np.int64))
            out.cell_data["label"] = self.labels[mesh.polygon]
            out.cell_data["plane"] = plane[mesh.polygon]
            return out
        indices = self.manifold_split().indices if manifold else self.indices
        source = self.manifold_split().source if manifold else slice(None)
        sizes = np.diff(self.offsets)
        faces = np.insert(indices, self.offsets[:-1], sizes) if self.n_polygons else np.zeros(0, np.int64)
        out = pv.PolyData(self.positions()[source], faces.astype(np.int64))
        out.cell_data["label"] = self.labels.copy()
        out.cell_data["plane"] = plane
        return out

    def __repr__(self) -> str:
        return f"BoundarySurface({self.n_polygons} polygons, {self.n_vertices} vertices, {width_of(self.palette)}-bit)"


# ---------------------------------------------------------------------------
# assembly


@cache
def _axis_planes(width: int) -> np.ndarray:
    """The planes x = 0, y = 0, z = 0 as a (3, 4) wide array (read-only)."""
    axes = to_wide(np.eye(3, 4, dtype=np.int64), width)
    axes.flags.writeable = False
    return axes


def _empty_surface(palette: np.ndarray, dtype) -> BoundarySurface:
    z = np.zeros(0, np.int64)
    return BoundarySurface(
        palette, np.zeros((0, 4), dtype), np.zeros(1, np.int64), z, z.copy(), z.copy(), z.copy(), np.zeros((0, 3))
    )


def _checked_pieces(palette, vx, edge_plane, polys):
    """The pieces as C-contiguous arrays of the right types, with every index in range."""
    width = width_of(palette)
    if width_of(vx) != width:
        raise ValueError(f"palette and vertices have different widths ({width} and {width_of(vx)} bits)")
    if palette.ndim != 2 or palette.shape[1] != 4 or vx.ndim != 2 or vx.shape[1] != 4:
        raise ValueError(f"palette and vx must have shape (m, 4) and (n, 4), got {palette.shape} and {vx.shape}")
    edge_plane = np.asarray(edge_plane)
    polys = np.asarray(polys)
    for name, arr in (("edge_plane", edge_plane), ("polys", polys)):
        if arr.dtype.kind not in "iu":
            raise TypeError(f"{name} must be an integer array, got dtype {arr.dtype}")
    if edge_plane.shape != (vx.shape[0],):
        raise ValueError(f"edge_plane must have shape ({vx.shape[0]},) (one per vertex row), got {edge_plane.shape}")
    if polys.ndim != 2 or polys.shape[1] != 5:
        raise ValueError(f"polys must have shape (k, 5), got {polys.shape}")
    edge_plane = np.ascontiguousarray(edge_plane, np.int64)
    polys = np.ascontiguousarray(polys, np.int64)
    m, n = palette.shape[0], vx.shape[0]
    start, count, support = polys[:, 0], polys[:, 1], polys[:, 2]
    row = np.where(support >= 0, support, ~support)
    problems = [
        (count < 3, "has fewer than 3 vertices"),
        (start < 0, "starts before row 0"),
        (start + count > n, f"runs past the last vertex row ({n - 1})"),
        (row >= m, f"has a support row outside the palette (m = {m})"),
    ]
    for bad, what in problems:
        if np.any(bad):
            p = int(np.argmax(bad))
            raise GeometryError(f"polygon {p} (row {polys[p].tolist()}) {what}")
    if n and (edge_plane.min() < 0 or edge_plane.max() >= m):
        r = int(np.argmax((edge_plane < 0) | (edge_plane >= m)))
        raise GeometryError(f"edge_plane[{r}] = {int(edge_plane[r])} is not a palette row (m = {m})")
    return np.ascontiguousarray(palette), np.ascontiguousarray(vx), edge_plane, polys


def _raise_status(status: np.ndarray, polys: np.ndarray) -> None:
    code = int(status[0])
    a, b, c = (int(x) for x in status[1:4])
    if code == K.E_INFINITE:
        raise GeometryError(f"vertex row {a} has x4 = 0 (a point at infinity): boundary pieces need finite vertices")
    if code == K.E_OFF_PLANE:
        raise GeometryError(
            f"vertex row {a} of polygon {c} does not lie on palette plane {b} (its polygon's support "
            "or the plane of an edge at it): the pieces are inconsistent (extraction's pieces "
            "always satisfy this)"
        )
    if code == K.E_NO_LINE:
        raise GeometryError(
            f"edge row {a}: its planes {b} and {c} are equal or parallel, so they do not meet in "
            "a line (a palette with duplicate planes?)"
        )
    if code == K.E_ZERO_EDGE:
        raise GeometryError(f"edge row {a} of polygon {b} has both endpoints at the same point (a zero-length edge)")
    raise InternalError(f"surface assembly returned status {code} (a bug in csgnb: please report it)")


def assemble_surface(palette: np.ndarray, vx: np.ndarray, edge_plane: np.ndarray, polys: np.ndarray) -> BoundarySurface:
    """Merge raw boundary pieces into a conforming :class:`BoundarySurface`.

    Parameters
    ----------
    palette : (m, 4) wide
        Within its width's bit budget (:func:`csgnb.exact.budgets.check_planes`).
    vx : (n, 4) wide
        Every polygon's own vertex copies, polygon after polygon. Each vertex must lie on its
        polygon's support plane and on the edge planes of both its edges (checked exactly);
        the bounds the kernels rely on hold for intersections of palette planes.
    edge_plane : (n,) int64
        Palette row of the plane the edge from each vertex to the next lies on.
    polys : (k, 5) int64
        Per polygon: first vertex row, vertex count, signed support row, label, source face.

    Returns
    -------
    BoundarySurface
        Points numbered in order of first appearance in ``vx``; each represented by the first
        row that has it (sign-normalised to x4 > 0); every vertex that lies strictly inside an
        edge's segment of the edge's line inserted into it, in order.

    Raises
    ------
    GeometryError
        Inconsistent pieces (a vertex off its planes, a zero-length edge, parallel edge planes,
        an index out of range); :class:`PrecisionError` for a palette beyond its budget.
    """
    palette, vx, edge_plane, polys = _checked_pieces(palette, vx, edge_plane, polys)
    if polys.shape[0] == 0:
        return _empty_surface(palette, vx.dtype)
    check_planes(palette, "palette")
    n = vx.shape[0]
    limbs = vx["limbs"].reshape(n, -1)
    status = np.zeros(4, np.int64)
    vid = np.zeros(n, np.int64)
    vertices = np.empty((n, 4), vx.dtype)
    pos = np.empty((n, 3), np.float64)
    count = K.merge_vertices_kernel(vx, limbs, vid, vertices, pos, pos.view(np.int64), status)
    if count < 0:
        _raise_status(status, polys)
    pair_of_edge = np.zeros(n, np.int64)
    pair_planes = np.empty((n, 2), np.int64)
    npairs = K.edge_pairs_kernel(
        K.PieceArrays(palette, vx, limbs, edge_plane, polys),
        vid,
        pair_of_edge,
        pair_planes,
        status,
        K.narrow_tests_exact(vx, palette),
    )
    if npairs < 0:
        _raise_status(status, polys)
    pair_planes = pair_planes[:npairs].copy()
    dirs = np.empty((npairs, 4), vx.dtype)
    points = np.empty((npairs, 4), vx.dtype)
    keys = np.empty((npairs, 4), np.float64)
    line_of_pair = np.empty(npairs, np.int64)
    line_planes = np.empty((npairs, 2), np.int64)
    line_axis = np.empty(npairs, np.int64)
    nlines = K.pair_lines_kernel(
        palette,
        pair_planes,
        _axis_planes(width_of(palette)),
        dirs,
        points,
        keys,
        keys.view(np.int64),
        line_of_pair,
        line_planes,
        line_axis,
        status,
    )
    if nlines < 0:
        q = int(status[1])
        status[1] = int(np.argmax(pair_of_edge == q))
        _raise_status(status, polys)
    vertices = vertices[:count].copy()
    pos = pos[:count].copy()
    offsets, indices, planes = K.assemble_loops_kernel(
        polys, vid, line_of_pair[pair_of_edge], line_axis[:nlines].copy(), vertices, pos, edge_plane
    )
    return BoundarySurface(
        palette=palette,
        vertices=vertices,
        offsets=offsets,
        indices=indices,
        support=polys[:, 2].copy(),
        labels=polys[:, 3].copy(),
        edge_planes=planes,
        _positions=pos,
    )


def _primitive(x: list[int]) -> tuple[int, int, int, int]:
    g = gcd(*x)
    if x[3] < 0:
        g = -g
    return tuple(v // g for v in x)


def _line_key(p: list[int], q: list[int]) -> tuple[int, ...]:
    """Reduced Plücker coordinates (u, m) of the line where planes p and q meet."""
    u = (p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0])
    m = tuple(p[3] * q[i] - q[3] * p[i] for i in range(3))
    key = u + m
    g = gcd(*key)
    first = next(v for v in u if v != 0)
    if first < 0:
        g = -g
    return tuple(v // g for v in key)


def _assemble_surface_reference(
    palette: np.ndarray, vx: np.ndarray, edge_plane: np.ndarray, polys: np.ndarray
) -> BoundarySurface:
    """The first, pure-Python :func:`assemble_surface` (Python ints, gcds, Fractions): the reference for tests.

    Vertices are the gcd-reduced primitive representatives; lines are keyed by reduced
    Plücker coordinates; vertices are sorted along each line by Fractions. Slow (1.8 s for
    37k faces); kept so that tests and ``benchmarks/bench_surface.py`` compare against it.

    Parameters
    ----------
    palette : (m, 4) wide
    vx : (n, 4) wide
        Every polygon's own vertex copies, polygon after polygon.
    edge_plane : (n,) int64
        Palette row of the plane the edge from each vertex to the next lies on.
    polys : (k, 5) int64
        Per polygon: first vertex row, vertex count, signed support row, label, source face.
    """
    width = width_of(palette)
    X = [list(map(int, row)) for row in from_wide(vx)] if vx.shape[0] else []
    ids: dict[tuple[int, ...], int] = {}
    vid = np.empty(len(X), np.int64)
    for r, x in enumerate(X):
        vid[r] = ids.setdefault(_primitive(x), len(ids))
    points = list(ids)
    planes = [list(map(int, row)) for row in from_wide(palette)]

    # Group edges by their exact line; remember each polygon edge's group.
    line_of_pair: dict[tuple[int, int], int] = {}
    line_keys: dict[tuple[int, ...], int] = {}
    line_vertices: list[set[int]] = []
    line_dir: list[tuple[int, int, int]] = []
    poly_edges = []
    for start, n, support, _, _ in polys:
        row = int(support) if support >= 0 else ~int(support)
        loop = []
        for i in range(n):
            a, b = int(vid[start + i]), int(vid[start + (i + 1) % n])
            pair = (min(row, int(edge_plane[start + i])), max(row, int(edge_plane[start + i])))
            line = line_of_pair.get(pair)
            if line is None:
                key = _line_key(planes[pair[0]], planes[pair[1]])
                line = line_keys.setdefault(key, len(line_keys))
                if line == len(line_vertices):
                    line_vertices.append(set())
                    line_dir.append(key[:3])
                line_of_pair[pair] = line
            line_vertices[line].update((a, b))
            loop.append((a, b, line))
        poly_edges.append(loop)

    # Order each line's vertices exactly: t = (u·x) / x4 with x4 > 0.
    order: list[list[int]] = []
    where: list[dict[int, int]] = []
    for line, verts in enumerate(line_vertices):
        u = line_dir[line]
        ts = sorted(verts, key=lambda v: Fraction(sum(u[i] * points[v][i] for i in range(3)), points[v][3]))
        order.append(ts)
        where.append({v: k for k, v in enumerate(ts)})

    offsets = [0]
    indices: list[int] = []
    for loop in poly_edges:
        for a, b, line in loop:
            indices.append(a)
            ia, ib = where[line][a], where[line][b]
            if ia < ib:
                indices.extend(order[line][ia + 1 : ib])
            elif ia > ib + 1:
                indices.extend(order[line][ib + 1 : ia][::-1])
            elif ia == ib:
                raise InternalError("a boundary edge has coincident endpoints (a bug in csgnb: please report it)")
        offsets.append(len(indices))
    vertices = to_wide(np.array(points, dtype=object).reshape(-1, 4), width) if points else np.zeros((0, 4), vx.dtype)
    return BoundarySurface(
        palette=palette,
        vertices=vertices,
        offsets=np.asarray(offsets, np.int64),
        indices=np.asarray(indices, np.int64),
        support=polys[:, 2].copy(),
        labels=polys[:, 3].copy(),
    )
