"""Quantization of float geometry onto the integer grid of a bit width.

Exact predicates need integer input. :func:`quantize` maps float vertices onto
integers within the mesh budget of a width (eq. 8), keeping the map so results
can be brought back. The scale is a power of two, so grid -> model is a single
exact multiplication by 2**-k followed by the offset addition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import GeometryError
from .budgets import budget

__all__ = ["Quantization", "quantize"]


@dataclass(frozen=True)
class Quantization:
    """The affine map between model coordinates and grid integers: ``grid = round((x - offset) * scale)``.

    Attributes
    ----------
    scale : float
        Grid units per model unit (a power of two).
    offset : (3,) float64
        The model point mapped to the grid origin.
    width : int
        The bit width whose mesh budget the grid respects.
    max_coordinate : int
        The largest |grid coordinate| allowed.
    """

    scale: float
    offset: np.ndarray
    width: int
    max_coordinate: int

    @property
    def resolution(self) -> float:
        """Model-space size of one grid step."""
        return 1.0 / self.scale

    def to_grid(self, points) -> np.ndarray:
        """Return ``(n, 3) int64`` grid points nearest to model ``points`` ``(n, 3) float``."""
        pts = _finite_points(points)
        grid = np.rint((pts - self.offset) * self.scale)
        if grid.size and np.max(np.abs(grid)) > self.max_coordinate:
            raise GeometryError(
                f"points fall outside the quantization box (|grid| <= {self.max_coordinate}); "
                "quantize all geometry of a scene together"
            )
        return grid.astype(np.int64)

    def to_model(self, points) -> np.ndarray:
        """Return model coordinates ``(n, 3) float64`` of grid or rational (float) ``points``."""
        return np.asarray(points, dtype=np.float64) / self.scale + self.offset


def _finite_points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or infinity; remove them before quantizing")
    return pts


def quantize(vertices, width: int = 256, *, max_coordinate: int | None = None) -> tuple[np.ndarray, Quantization]:
    """Return ``vertices`` rounded to the integer grid of ``width``, and the map back.

    The bounding box is centred on the origin and scaled by the largest power of
    two that keeps every coordinate within ``max_coordinate`` (default: the
    mesh budget of ``width``, eq. 8, so planes through any three grid vertices
    are exact).

    Parameters
    ----------
    vertices : (n, 3) float
    width : {128, 192, 256}
    max_coordinate : int, optional
        A smaller grid bound (coarser grid); may not exceed the mesh budget.

    Returns
    -------
    grid : (n, 3) int64
    quantization : Quantization
    """
    pts = _finite_points(vertices)
    if pts.shape[0] == 0:
        raise ValueError("cannot quantize an empty vertex array")
    limit = budget(width).max_mesh_coordinate
    if max_coordinate is None:
        max_coordinate = limit
    if not 1 <= max_coordinate <= limit:
        raise ValueError(f"max_coordinate must be in [1, {limit}] for {width} bits, got {max_coordinate}")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    offset = (lo + hi) / 2
    half_extent = float(np.max(hi - lo)) / 2
    if half_extent == 0.0:
        scale = 1.0
    else:
        # Largest power of two with half_extent * scale <= max_coordinate (rounding stays inside).
        # log2 of each term separately: their quotient overflows for subnormal extents.
        exponent = np.floor(np.log2(max(max_coordinate - 1, 1)) - np.log2(half_extent))
        scale = float(np.ldexp(1.0, int(np.clip(exponent, -1000, 1000))))
    q = Quantization(scale=float(scale), offset=offset, width=width, max_coordinate=max_coordinate)
    return q.to_grid(pts), q
