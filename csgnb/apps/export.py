"""A milled part as an STL file that other programs can trust: one triangulation, checked as written.

There is one triangulation path for every export: the workpiece's own
(``workpiece.to_mesh(manifold=True)``, :meth:`csgnb.bsp.surface.BoundarySurface.triangulate`:
no flat triangle next to a T-junction vertex, vertices duplicated along edges that four faces
share). What this module adds is the file format's own problem: a binary STL stores each
triangle's corners as float32 and no vertex identity, so

* two exact vertices closer than a float32 step become one point, and a triangle with two such
  corners has no area (CAM tools reject it, slicers warn); such *collapsed* triangles are dropped
  -- a collapsed triangle's two coinciding corners are glued in every reader anyway, so the
  remaining triangles still close up -- and counted; a triangle whose three distinct corners
  become collinear cannot be dropped without opening the mesh (a neighbour's edge passes through
  its middle corner), so it is kept and counted as *flat*;
* readers weld corners by position, so an edge that the exact part touches itself along (two
  solid cells meeting only at that edge) is shared by four triangles in every reader, whatever
  the writer duplicated: the part is closed but not 2-manifold there. That is the true shape,
  so it is not hidden: the report counts such edges.

:func:`export_stl` writes the file, reads it back with meshio and reports what a reader sees
(:class:`StlReport`: triangles, dropped, flat, closed, non-manifold edges, the volume it encloses).
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from csgnb.errors import GeometryError

__all__ = ["StlReport", "check_triangle_soup", "export_stl"]


@dataclass
class StlReport:
    """What a reader of the written STL sees (all counts after welding corners by their float32 position).

    ``closed``: every edge is used equally often in both directions; ``non_manifold_edges``:
    edges used by more than two triangles; ``dropped``: triangles whose float32 corners
    coincide (no area), left out; ``flat``: triangles kept whose float32 corners are distinct but
    collinear; ``volume``: the enclosed volume (model units³, float64 sum).
    """

    path: str
    triangles: int
    vertices: int
    dropped: int
    closed: bool
    non_manifold_edges: int
    volume: float
    flat: int = 0

    @property
    def watertight(self) -> bool:
        """Closed and 2-manifold: every edge used by exactly two triangles, once in each direction."""
        return self.closed and self.non_manifold_edges == 0

    def as_dict(self) -> dict:
        return dict(asdict(self), watertight=self.watertight)

    def summary(self) -> str:
        text = (f"STL {self.path}: {self.triangles} triangles, closed: {'yes' if self.closed else 'NO'}, "
                f"2-manifold: {'yes' if self.non_manifold_edges == 0 else 'no'}")
        if self.non_manifold_edges:
            text += (f" ({self.non_manifold_edges} edges shared by four or more triangles: the exact part "
                     "touches itself along them)")
        if self.dropped:
            text += f"; {self.dropped} triangles collapsed by float32 rounding dropped"
        if self.flat:
            text += f"; {self.flat} triangles flattened by float32 rounding kept (they close the mesh)"
        return text


def check_triangle_soup(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """Weld ``points (n, 3)`` by exact position, drop triangles with coinciding corners; return the welded
    points, the kept triangles and ``{"dropped", "flat", "closed", "non_manifold_edges", "volume"}``."""
    try:
        points = np.asarray(points, dtype=np.float64)
        triangles = np.asarray(triangles)
    except (TypeError, ValueError):
        raise TypeError("points must be real (n, 3) and triangles integer (m, 3) arrays") from None
    if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
        raise GeometryError(f"points must be finite (n, 3) coordinates, got shape {points.shape}")
    if triangles.ndim != 2 or triangles.shape[1] != 3 or triangles.dtype.kind not in "iu" or (
            triangles.size and (triangles.min() < 0 or triangles.max() >= points.shape[0])):
        raise GeometryError(f"triangles must be (m, 3) indices into the {points.shape[0]} points")
    P, inverse = np.unique(points, axis=0, return_inverse=True)
    T = inverse.reshape(-1)[triangles.astype(np.int64)].reshape(-1, 3)
    collapsed = (T[:, 0] == T[:, 1]) | (T[:, 1] == T[:, 2]) | (T[:, 2] == T[:, 0])
    T = T[~collapsed]
    directed = Counter(map(tuple, np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]).tolist()))
    closed = all(directed.get((b, a), 0) == n for (a, b), n in directed.items())
    undirected = Counter()
    for (a, b), n in directed.items():
        undirected[(min(a, b), max(a, b))] += n
    Q = P.astype(np.float64)
    volume = float(np.sum(np.einsum("ij,ij->i", Q[T[:, 0]], np.cross(Q[T[:, 1]], Q[T[:, 2]])))) / 6.0
    # float32 corners as doubles: their differences and cross products are exact enough to see a zero
    flat = int(np.sum(~np.cross(Q[T[:, 1]] - Q[T[:, 0]], Q[T[:, 2]] - Q[T[:, 0]]).any(axis=1)))
    return P, T, {"dropped": int(collapsed.sum()), "flat": flat, "closed": bool(closed),
                  "non_manifold_edges": int(sum(1 for n in undirected.values() if n > 2)), "volume": volume}


def export_stl(workpiece, path, *, binary: bool = True) -> StlReport:
    """Write ``workpiece``'s exact boundary (model units) as an STL file through meshio; return what a reader sees.

    Corners are rounded to float32 (binary STL) first; triangles that rounding collapses are
    dropped. The file is read back and checked (:class:`StlReport`); it is written to a
    temporary name and renamed, so a failed export leaves no half-written file.
    """
    import meshio

    if not callable(getattr(workpiece, "to_mesh", None)):
        raise TypeError(f"export_stl takes a workpiece (csgnb.octree.Workpiece), got {type(workpiece).__name__}")
    if not isinstance(path, str | os.PathLike):
        raise TypeError(f"path must be a file name, got {type(path).__name__}")
    V, T = workpiece.to_mesh(manifold=True)
    if len(T) == 0:
        raise GeometryError("the workpiece is empty: there is no surface to export")
    V32 = np.asarray(V, np.float32)
    P, kept, _ = check_triangle_soup(V32, T)
    path = Path(path)
    tmp = path.with_name(f".{path.name}.writing")
    try:
        with np.errstate(invalid="ignore", divide="ignore"):  # meshio normalises the normal of a flat triangle
            meshio.write(tmp, meshio.Mesh(P.astype(np.float64), [("triangle", kept)]), file_format="stl",
                         binary=binary)
        back = meshio.read(tmp, file_format="stl")
        _, T2, seen = check_triangle_soup(back.points.astype(np.float32), back.cells_dict["triangle"])
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return StlReport(str(path), int(T2.shape[0]), int(P.shape[0]), int(T.shape[0] - T2.shape[0]), seen["closed"],
                     seen["non_manifold_edges"], seen["volume"], seen["flat"])
