"""Quantization of float geometry onto the integer grid of a bit width.

Exact predicates need integer input. :func:`quantize` maps float vertices onto
integers within the mesh budget of a width (eq. 8), keeping the map so results
can be brought back. The scale is a power of two, so grid -> model is a single
exact multiplication by 2**-k followed by the offset addition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.errors import PrecisionError
from csgnb.exact.budgets import budget
from csgnb.exact.wide import DEFAULT_WIDTH

__all__ = ["Grid", "Quantization", "quantize"]


@dataclass(frozen=True, eq=False)
class Grid:
    """The integer grid of a scene: ``grid = round((x - origin) * scale)``, ``scale`` a power of two.

    One grid serves a workpiece and every tool applied to it: geometry quantized on
    different grids cannot be combined (:meth:`same_as`). Because the scale is a power
    of two, grid -> model is exact up to the final addition of ``origin``.

    Attributes
    ----------
    scale : float
        Grid units per model unit (a power of two).
    origin : (3,) float64
        The model point mapped to the grid origin.
    width : int
        The bit width whose mesh budget the grid respects (128, 192 or 256).
    max_coordinate : int
        The largest |grid coordinate| allowed (at most the mesh budget of ``width``, eq. 8).
    """

    scale: float
    origin: np.ndarray
    width: int
    max_coordinate: int

    def __post_init__(self) -> None:
        scale = float(self.scale)
        if not (np.isfinite(scale) and scale > 0 and np.frexp(scale)[0] == 0.5):
            raise ValueError(f"a grid scale must be a positive power of two, got {self.scale!r}")
        origin = np.asarray(self.origin, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(origin)):
            raise ValueError(f"a grid origin must be finite, got {origin}")
        limit = budget(self.width).max_mesh_coordinate
        if not 1 <= int(self.max_coordinate) <= limit:
            raise ValueError(f"max_coordinate must be in [1, {limit}] for {self.width} bits, got {self.max_coordinate}")
        origin.setflags(write=False)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "max_coordinate", int(self.max_coordinate))

    # -- construction ---------------------------------------------------------

    @classmethod
    def fit(cls, lo, hi, *, width: int = DEFAULT_WIDTH, max_coordinate: int | None = None) -> Grid:
        """The finest grid whose budget box holds the model box ``[lo, hi]`` (centred on it)."""
        lo = np.asarray(lo, dtype=np.float64).reshape(3)
        hi = np.asarray(hi, dtype=np.float64).reshape(3)
        pts = _finite_points(np.stack([lo, hi]))
        limit = budget(width).max_mesh_coordinate
        max_coordinate = limit if max_coordinate is None else int(max_coordinate)
        if not 1 <= max_coordinate <= limit:
            raise ValueError(f"max_coordinate must be in [1, {limit}] for {width} bits, got {max_coordinate}")
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        origin = (lo + hi) / 2
        half_extent = float(np.max(hi - lo)) / 2
        if half_extent == 0.0:
            scale = 1.0
        else:
            # Largest power of two with half_extent * scale <= max_coordinate (rounding stays inside).
            # log2 of each term separately: their quotient overflows for subnormal extents.
            exponent = np.floor(np.log2(max(max_coordinate - 1, 1)) - np.log2(half_extent))
            scale = float(np.ldexp(1.0, int(np.clip(exponent, -1000, 1000))))
        return cls(scale=scale, origin=origin, width=width, max_coordinate=max_coordinate)

    @classmethod
    def from_resolution(cls, resolution: float, *, origin=(0.0, 0.0, 0.0), width: int = DEFAULT_WIDTH) -> Grid:
        """A grid at least as fine as ``resolution`` model units per step (scale rounded up to a power of two)."""
        resolution = float(resolution)
        if not (np.isfinite(resolution) and resolution > 0):
            raise ValueError(f"resolution must be a positive finite number, got {resolution!r}")
        mantissa, exponent = np.frexp(1.0 / resolution)
        scale = float(np.ldexp(1.0, int(exponent) - (1 if mantissa == 0.5 else 0)))
        return cls(scale=scale, origin=origin, width=width, max_coordinate=budget(width).max_mesh_coordinate)

    # -- queries --------------------------------------------------------------

    @property
    def resolution(self) -> float:
        """Model-space size of one grid step."""
        return 1.0 / self.scale

    @property
    def offset(self) -> np.ndarray:
        """Alias of ``origin`` (the name :func:`quantize` used)."""
        return self.origin

    def model_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The model-space box ``(lo, hi)`` whose points quantize within the budget."""
        half = self.max_coordinate / self.scale
        return self.origin - half, self.origin + half

    def same_as(self, other: Grid) -> bool:
        """Whether ``other`` is the same grid (scale, origin, width and bound)."""
        return (isinstance(other, Grid) and self.scale == other.scale and self.width == other.width
                and self.max_coordinate == other.max_coordinate and bool(np.array_equal(self.origin, other.origin)))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Grid) and self.same_as(other)

    def __hash__(self) -> int:
        return hash((self.scale, tuple(self.origin.tolist()), self.width, self.max_coordinate))

    def to_grid(self, points) -> np.ndarray:
        """Return ``(n, 3) int64`` grid points nearest to model ``points`` ``(n, 3) float``."""
        pts = _finite_points(points)
        grid = np.rint((pts - self.origin) * self.scale)
        if grid.size and np.max(np.abs(grid)) > self.max_coordinate:
            worst = int(np.argmax(np.max(np.abs(grid), axis=1)))
            raise PrecisionError(
                f"point {worst} ({pts[worst].tolist()}) lies outside this grid's budget box "
                f"(|grid coordinate| <= {self.max_coordinate} at {self.width} bits, model box "
                f"{self.model_bounds()[0].tolist()}..{self.model_bounds()[1].tolist()}); "
                "fit the grid to all geometry of the scene (Grid.fit) or use a wider width"
            )
        return grid.astype(np.int64)

    def to_model(self, points) -> np.ndarray:
        """Return model coordinates ``(n, 3) float64`` of grid or rational (float) ``points``."""
        return np.asarray(points, dtype=np.float64) / self.scale + self.origin

    def __repr__(self) -> str:
        return (f"Grid(resolution={self.resolution:g}, origin={self.origin.tolist()}, width={self.width}, "
                f"max_coordinate={self.max_coordinate})")


Quantization = Grid
"""The name :func:`quantize` has always returned (an alias of :class:`Grid`)."""


def _finite_points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or infinity; remove them before quantizing")
    return pts


def quantize(vertices, width: int = DEFAULT_WIDTH, *, max_coordinate: int | None = None) -> tuple[np.ndarray, Grid]:
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
    grid_map : Grid
        The grid (an alias: :data:`Quantization`).
    """
    pts = _finite_points(vertices)
    if pts.shape[0] == 0:
        raise ValueError("cannot quantize an empty vertex array")
    q = Grid.fit(pts.min(axis=0), pts.max(axis=0), width=width, max_coordinate=max_coordinate)
    return q.to_grid(pts), q
