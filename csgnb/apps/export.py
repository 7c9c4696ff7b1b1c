"""A workpiece's exact boundary as float triangles (model units) and as an STL file (meshio).

The boundary (:class:`csgnb.bsp.surface.BoundarySurface`) is conforming: an edge of one
polygon that carries a vertex of a neighbour (a T-junction) carries it too. Such polygons
have *flat* vertices (collinear with both neighbours); a plain fan would join vertices of
one edge into zero-area triangles. :func:`surface_triangles` clips ears at strict corners
next to flat vertices first (deciding collinearity exactly on the homogeneous integer
vertices), so every triangle has area and the mesh stays closed edge for edge.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from csgnb.errors import GeometryError
from csgnb.exact.wide import from_wide

__all__ = ["export_stl", "part_mesh", "surface_triangles"]

_FLAT_CANDIDATE = 1e-9
"""Relative size of a float cross product below which collinearity is decided exactly (the positions are correctly
rounded doubles, so a clearly larger cross product is never that of three collinear points)."""


def _collinear(a, b, c) -> bool:
    """Whether three homogeneous integer points are collinear: every 3x3 minor of [a; b; c] is zero (exact)."""
    for skip in range(4):
        cols = [k for k in range(4) if k != skip]
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = ([p[k] for k in cols] for p in (a, b, c))
        if a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0):
            return False
    return True


def _ear_triangles(poly: list[int], flat_at) -> list[tuple[int, int, int]]:
    """Triangles of a convex polygon whose edges may carry extra (T-junction) vertices, none of zero area.

    While a flat vertex remains, the ear at a strict corner next to one is clipped -- which
    turns that flat vertex into a corner and keeps the rest a convex polygon with area -- and
    the flat-free rest is fanned. ``flat_at(a, b, c)`` decides whether b is flat between a, c.
    """
    poly = list(poly)
    out = []
    while len(poly) > 3:
        k = len(poly)
        flat = [flat_at(poly[i - 1], poly[i], poly[(i + 1) % k]) for i in range(k)]
        if not any(flat):
            break
        for i in range(k):
            if not flat[i] and (flat[i - 1] or flat[(i + 1) % k]):
                out.append((poly[i - 1], poly[i], poly[(i + 1) % k]))
                del poly[i]
                break
        else:  # all flat: a zero-area polygon (not on a solid's boundary)
            return out
    out += [(poly[0], poly[i], poly[i + 1]) for i in range(1, len(poly) - 1)]
    return out


def surface_triangles(surface) -> tuple[np.ndarray, np.ndarray]:
    """The boundary's vertices ``(n, 3) float64`` (grid coordinates, correctly rounded) and outward triangles
    ``(m, 3) int64`` with no zero-area triangle."""
    if surface.n_polygons == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    P = surface.positions()
    scale = float(np.abs(P).max()) or 1.0
    exact: dict[int, tuple[int, ...]] = {}

    def homogeneous(i: int) -> tuple[int, ...]:
        if i not in exact:
            exact[i] = tuple(int(x) for x in from_wide(surface.vertices[i:i + 1])[0])
        return exact[i]

    def flat_at(a: int, b: int, c: int) -> bool:
        cross = np.cross(P[a] - P[b], P[c] - P[b])
        if float(np.abs(cross).max()) > _FLAT_CANDIDATE * scale * scale:
            return False
        return _collinear(homogeneous(a), homogeneous(b), homogeneous(c))

    tris: list[tuple[int, int, int]] = []
    for f in surface.polygons():
        poly = [int(i) for i in f]
        if len(poly) == 3:
            tris.append((poly[0], poly[1], poly[2]))
        else:
            tris += _ear_triangles(poly, flat_at)
    return P, np.array(tris, np.int64).reshape(-1, 3)


def part_mesh(workpiece) -> tuple[np.ndarray, np.ndarray]:
    """``workpiece``'s exact boundary as float model vertices ``(n, 3)`` and outward triangles ``(m, 3) int64``."""
    V, T = surface_triangles(workpiece.surface())
    return workpiece.grid.to_model(V) if len(V) else V, T


def export_stl(workpiece, path, *, binary: bool = True) -> Path:
    """Write ``workpiece``'s exact boundary (float model coordinates) as an STL file through meshio."""
    import meshio

    V, T = part_mesh(workpiece)
    if len(T) == 0:
        raise GeometryError("the workpiece is empty: there is no surface to export")
    path = Path(path)
    meshio.write(path, meshio.Mesh(np.asarray(V, np.float64), [("triangle", np.asarray(T, np.int64))]),
                 file_format="stl", binary=binary)
    return path
