"""Carving (paper Figure 15a): many small dodecahedra subtracted from a block along a target surface.

:func:`carving_placements` samples points on a target surface (a sphere, a torus, or any
closed triangle mesh), and places one randomly turned dodecahedron outside the surface at
each, its centre ``offset`` along the outward normal, so that together they carve the
block down towards the target. Each dodecahedron is quantized onto the grid and becomes an
exact :class:`~csgnb.mesh.hull.ConvexHull` (rounding may split a pentagon into coplanar-free
pieces; the hull of the grid vertices is still exact). :func:`carve` subtracts them from a
workpiece one by one, with per-step exact removed volume (optional) and time.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from csgnb.errors import GeometryError
from csgnb.exact.quantization import Grid
from csgnb.mesh.hull import ConvexHull, convex_hull

__all__ = ["Carving", "Target", "carve", "carving_placements", "dodecahedron", "dodecahedron_vertices",
           "INRADIUS_RATIO", "mesh_target", "random_rotations", "sphere_target", "torus_target"]

PHI = (1 + 5**0.5) / 2
INRADIUS_RATIO = PHI**2 / (3**0.5 * (PHI**2 + 1) ** 0.5)
"""In-radius of a regular dodecahedron of circum-radius 1 (about 0.7947)."""


def dodecahedron_vertices(radius: float = 1.0) -> np.ndarray:
    """The 20 vertices ``(20, 3)`` of a regular dodecahedron of circum-radius ``radius`` centred at the origin."""
    a, b = 1 / PHI, PHI
    v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    for s in (-1, 1):
        for t in (-1, 1):
            v += [(0, s * a, t * b), (s * a, t * b, 0), (t * b, 0, s * a)]
    return np.array(v, float) * (float(radius) / np.sqrt(3))


def random_rotations(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` uniformly random rotation matrices ``(n, 3, 3)`` (from unit quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


def dodecahedron(center, radius: float, rotation, grid: Grid) -> ConvexHull:
    """An exact hull of a turned dodecahedron (model ``center``, circum-radius ``radius``) quantized on ``grid``."""
    R = np.asarray(rotation, float).reshape(3, 3)
    pts = dodecahedron_vertices(radius) @ R.T + np.asarray(center, float).reshape(1, 3)
    return convex_hull(grid.to_grid(pts), width=grid.width, grid=grid, name="dodecahedron vertices")


@dataclass(frozen=True)
class Target:
    """A target surface: ``sample(n, rng) -> (points (n, 3), unit outward normals (n, 3))`` and a name."""

    name: str
    sample: object


def sphere_target(center=(0.0, 0.0, 0.0), radius: float = 1.0) -> Target:
    """The sphere of ``radius`` about ``center``, sampled uniformly by area."""
    c = np.asarray(center, float).reshape(3)
    r = float(radius)
    if not r > 0:
        raise GeometryError(f"a sphere target needs a positive radius, got {radius!r}")

    def sample(n, rng):
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        return c + r * d, d

    return Target(f"sphere r={r:g}", sample)


def torus_target(center=(0.0, 0.0, 0.0), major: float = 2.0, minor: float = 0.75) -> Target:
    """A torus about the z axis through ``center``, sampled uniformly by area (rejection on the tube angle)."""
    c = np.asarray(center, float).reshape(3)
    R, r = float(major), float(minor)
    if not 0 < r < R:
        raise GeometryError(f"a torus target needs 0 < minor < major, got {minor!r}, {major!r}")

    def sample(n, rng):
        out_u, out_v = [], []
        while sum(len(u) for u in out_u) < n:
            u = rng.uniform(0, 2 * np.pi, 2 * n)
            v = rng.uniform(0, 2 * np.pi, 2 * n)
            keep = rng.uniform(0, R + r, 2 * n) < R + r * np.cos(v)  # area element ∝ R + r cos v
            out_u.append(u[keep])
            out_v.append(v[keep])
        u, v = np.concatenate(out_u)[:n], np.concatenate(out_v)[:n]
        normal = np.column_stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)])
        ring = np.column_stack([R * np.cos(u), R * np.sin(u), np.zeros(n)])
        return c + ring + r * normal, normal

    return Target(f"torus R={R:g} r={r:g}", sample)


def mesh_target(vertices, faces, *, name: str = "mesh") -> Target:
    """A closed outward triangle mesh (model units), sampled uniformly by area, with its face normals."""
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise GeometryError(f"a mesh target needs vertices (n, 3) and triangles (m, 3), got {V.shape}, {F.shape}")
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    cross = np.cross(B - A, C - A)
    area = np.linalg.norm(cross, axis=1)
    if not np.all(np.isfinite(area)) or area.sum() == 0:
        raise GeometryError("the target mesh has no area")
    normals = cross / np.where(area > 0, area, 1)[:, None]

    def sample(n, rng):
        f = rng.choice(len(F), size=n, p=area / area.sum())
        s, t = rng.random(n), rng.random(n)
        flip = s + t > 1
        s, t = np.where(flip, 1 - s, s), np.where(flip, 1 - t, t)
        return A[f] + s[:, None] * (B[f] - A[f]) + t[:, None] * (C[f] - A[f]), normals[f]

    return Target(name, sample)


@dataclass
class Carving:
    """Placements of dodecahedra along a target surface.

    Attributes
    ----------
    centers : (n, 3) float64
        Model centres.
    rotations : (n, 3, 3) float64
    radius : float
        Circum-radius of every dodecahedron (mm).
    grid : Grid
    """

    centers: np.ndarray
    rotations: np.ndarray
    radius: float
    grid: Grid

    def __len__(self) -> int:
        return int(self.centers.shape[0])

    def hull(self, i: int) -> ConvexHull:
        """Dodecahedron ``i`` as an exact hull on the grid."""
        return dodecahedron(self.centers[i], self.radius, self.rotations[i], self.grid)

    def hulls(self) -> Iterator[ConvexHull]:
        """Every dodecahedron, in order, built lazily (10,000 hulls take a few seconds)."""
        return (self.hull(i) for i in range(len(self)))


def carving_placements(target: Target, n: int, radius: float, *, grid: Grid, offset: float | None = None,
                       seed: int = 0) -> Carving:
    """Place ``n`` dodecahedra of circum-radius ``radius`` just outside ``target``.

    Each centre is a random surface point moved ``offset`` (default ``radius``: the solid
    at most touches a flat target) along the outward normal; each dodecahedron is turned
    by a uniformly random rotation. ``seed`` makes the placement reproducible.
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    r = float(radius)
    if not r > 0:
        raise ValueError(f"radius must be positive, got {radius!r}")
    rng = np.random.default_rng(seed)
    points, normals = target.sample(int(n), rng)
    off = r if offset is None else float(offset)
    centers = points + off * normals
    lo, hi = grid.model_bounds()
    if np.any(centers - r < lo) or np.any(centers + r > hi):
        raise GeometryError(f"some dodecahedra leave the grid's budget box {lo.tolist()}..{hi.tolist()}; fit the "
                            "grid to the block and the target (Grid.fit)")
    return Carving(centers, random_rotations(int(n), rng), r, grid)


def carve(workpiece, carving: Carving, *, progress: bool = True, limit: int | None = None,
          track_volume: bool = True):
    """Subtract the carving's dodecahedra from ``workpiece`` in order; return per-step (removed mm³, seconds).

    Parameters
    ----------
    track_volume : bool
        Measure each step's exact removed volume (the workpiece measures it on the octree
        cells the dodecahedron reaches, :mod:`csgnb.octree.volume`); without it ``removed`` is None and
        the steps cost only the Booleans.

    Returns
    -------
    removed : list of Fraction, or None
        Exact removed volume per dodecahedron (mm³).
    seconds : list of float
        Wall time per subtraction (hull construction and volume measurement included).
    """
    from tqdm.auto import tqdm

    if not carving.grid.same_as(workpiece.grid):
        raise GeometryError("the carving and the workpiece lie on different grids")
    k = len(carving) if limit is None else min(int(limit), len(carving))
    removed, seconds = ([] if track_volume else None), []
    for i in tqdm(range(k), disable=not progress, desc="carving", unit="solid"):
        t0 = time.perf_counter()
        hull = carving.hull(i)
        report = workpiece.difference(hull, track_volume=track_volume)
        if track_volume:
            removed.append(carving.grid.model_volume(report.removed))
        seconds.append(time.perf_counter() - t0)
    return removed, seconds
