"""Exact boundary surfaces: shared exact vertices, convex polygons, no T-junctions (paper §3.4).

:func:`assemble_surface` turns the raw boundary pieces of extraction (each polygon with
its own copies of its vertices and, per edge, the plane the edge lies on) into a
:class:`BoundarySurface`:

1. vertices are merged by exact identity (the primitive integer representative of
   the homogeneous point, x4 > 0);
2. T-junctions are removed: edges are grouped by their exact supporting line (the
   Plücker coordinates of the two planes meeting there, reduced by their gcd), the
   group's vertices are ordered exactly along the line, and every edge receives the
   vertices strictly inside it as valence-2 vertices. Afterwards every edge of a
   closed solid is used exactly twice, in opposite directions.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from fractions import Fraction
from math import gcd

import numpy as np

from csgnb.errors import InternalError
from csgnb.exact.predicates import to_double_position
from csgnb.exact.wide import from_wide, to_wide, width_of

__all__ = ["BoundarySurface", "assemble_surface"]


@dataclass(frozen=True)
class BoundarySurface:
    """A closed surface of exact convex polygons, outward, sharing exact vertices.

    Attributes
    ----------
    palette : (m, 4) wide
        The planes polygons lie on.
    vertices : (n, 4) wide
        Homogeneous vertices (x1, x2, x3, x4), x4 > 0, each point once.
    offsets : (k + 1,) int64
        Polygon ``i`` has vertices ``indices[offsets[i]:offsets[i + 1]]``, counter-clockwise seen from outside.
    indices : (offsets[-1],) int64
    support : (k,) int64
        Palette row of each polygon's plane, ``~row`` when the polygon faces the row's negative side.
    labels : (k,) int64
        Label (material) of the solid behind each polygon.
    """

    palette: np.ndarray
    vertices: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray
    support: np.ndarray
    labels: np.ndarray

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
        """Vertex positions correctly rounded to doubles, ``(n, 3) float64``."""
        if self.n_vertices == 0:
            return np.zeros((0, 3))
        return to_double_position(self.vertices)

    def exact_positions(self) -> list[tuple[Fraction, Fraction, Fraction]]:
        """Vertex positions as exact Fractions."""
        return [tuple(Fraction(int(x[i]), int(x[3])) for i in range(3)) for x in from_wide(self.vertices)]

    def exact_volume(self, label: int | None = None) -> Fraction:
        """Return the exact enclosed volume (of the polygons of one ``label``, or all)."""
        from csgnb.mesh.halfedge import polygons_volume

        pos = self.exact_positions()
        polys = [p for i, p in enumerate(self.polygons()) if label is None or self.labels[i] == label]
        return polygons_volume([[pos[v] for v in p] for p in polys])

    def edge_use(self, label: int | None = None) -> dict[tuple[int, int], int]:
        """Count of every directed edge (a, b) over the polygons (of one ``label``, or all)."""
        use: dict[tuple[int, int], int] = defaultdict(int)
        for i, p in enumerate(self.polygons()):
            if label is not None and self.labels[i] != label:
                continue
            for a, b in zip(p, np.roll(p, -1), strict=True):
                use[int(a), int(b)] += 1
        return use

    def is_closed(self, label: int | None = None) -> bool:
        """Whether every edge is used as often in one direction as in the other (closed, consistently oriented).

        Where a solid touches itself along an edge (two cells meeting only there), the
        edge is used twice each way; everywhere else once each way (:meth:`is_manifold`).
        """
        use = self.edge_use(label)
        return all(use.get((b, a), 0) == n for (a, b), n in use.items())

    def is_manifold(self, label: int | None = None) -> bool:
        """Whether every directed edge is used exactly once and its reverse exactly once."""
        use = self.edge_use(label)
        return all(n == 1 and use.get((b, a), 0) == 1 for (a, b), n in use.items())

    def to_polydata(self, triangulate: bool = True):
        """Return a pyvista ``PolyData`` (positions correctly rounded; triangulated for display).

        Cell data: ``"label"`` and ``"plane"`` (palette row) per polygon.
        """
        import pyvista as pv

        faces = np.concatenate([[len(p), *p] for p in self.polygons()]) if self.n_polygons else np.zeros(0, int)
        mesh = pv.PolyData(self.positions(), faces.astype(np.int64))
        mesh.cell_data["label"] = self.labels.copy()
        mesh.cell_data["plane"] = np.where(self.support >= 0, self.support, ~self.support)
        return mesh.triangulate() if triangulate else mesh

    def __repr__(self) -> str:
        return f"BoundarySurface({self.n_polygons} polygons, {self.n_vertices} vertices, {width_of(self.palette)}-bit)"


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


def assemble_surface(palette: np.ndarray, vx: np.ndarray, edge_plane: np.ndarray, polys: np.ndarray) -> BoundarySurface:
    """Merge raw boundary pieces into a conforming :class:`BoundarySurface`.

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
