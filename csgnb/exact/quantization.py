"""Quantization of float geometry onto the integer grid of a bit width.

Exact predicates need integer input. :func:`quantize` maps float vertices onto
integers within the mesh budget of a width (eq. 8), keeping the map so results
can be brought back. The scale is a power of two, so grid -> model is a single
exact multiplication by 2**-k followed by the offset addition.
"""

from __future__ import annotations

import math
import numbers
from fractions import Fraction

import numpy as np

from csgnb.errors import GeometryError, PrecisionError
from csgnb.exact.budgets import budget
from csgnb.exact.integral import exact_int, integer_scalar
from csgnb.exact.rational import times_power_of_two
from csgnb.exact.wide import DEFAULT_WIDTH, check_width

__all__ = ["Grid", "Quantization", "quantize"]


class Grid:
    """The integer grid of a scene: ``grid = round((x - origin) * 2**exponent)``.

    One grid serves a workpiece and every tool applied to it: geometry quantized on
    different grids cannot be combined (:meth:`same_as`). Because the scale is a power
    of two, grid -> model is exact up to the final addition of ``origin``.

    Parameters
    ----------
    scale : float, optional
        Grid units per model unit, a positive power of two (or give ``exponent``).
    origin : (3,) float
        The model point mapped to the grid origin.
    width : {128, 192, 256}
        The bit width whose mesh budget the grid respects.
    max_coordinate : int, optional
        The largest |grid coordinate| allowed (default and maximum: the mesh budget of
        ``width``, eq. 8).
    exponent : int, optional
        ``scale = 2**exponent``; the exact form, which also covers scales beyond the
        double range (grids for subnormal model extents).

    Attributes
    ----------
    exponent : int
    scale : float
        ``2.0**exponent`` (``inf`` when the exponent exceeds the double range; use ``exponent``).
    origin : (3,) float64, read-only
    width, max_coordinate : int
    """

    __slots__ = ("exponent", "origin", "width", "max_coordinate")

    def __init__(self, scale=None, origin=(0.0, 0.0, 0.0), width: int = DEFAULT_WIDTH,
                 max_coordinate: int | None = None, *, exponent: int | None = None) -> None:
        width = check_width(width)
        if (scale is None) == (exponent is None):
            raise TypeError("give a grid either scale (a power of two) or exponent (scale = 2**exponent)")
        if exponent is not None:
            exponent = exact_int(exponent, "exponent")
        else:
            if not isinstance(scale, numbers.Real) or isinstance(scale, bool):
                raise TypeError(f"a grid scale must be a real number, got {type(scale).__name__} {scale!r}")
            scale = float(scale)
            if not (np.isfinite(scale) and scale > 0 and np.frexp(scale)[0] == 0.5):
                raise PrecisionError(f"a grid scale must be a positive power of two, got {scale!r}")
            exponent = int(np.frexp(scale)[1]) - 1
        origin = _real_array(origin, "origin")
        if origin.shape not in ((3,), (1, 3)):
            raise GeometryError(f"a grid origin must be a point (3,), got shape {origin.shape}")
        origin = origin.reshape(3).copy()
        if not np.all(np.isfinite(origin)):
            raise GeometryError(f"a grid origin must be finite, got {origin.tolist()}")
        limit = budget(width).max_mesh_coordinate
        max_coordinate = limit if max_coordinate is None else integer_scalar(max_coordinate, "max_coordinate")
        if not 1 <= max_coordinate <= limit:
            raise PrecisionError(f"max_coordinate must be in [1, {limit}] for {width} bits (the mesh budget, eq. 8), "
                                 f"got {max_coordinate}")
        origin.setflags(write=False)
        for name, value in (("exponent", exponent), ("origin", origin), ("width", width),
                            ("max_coordinate", max_coordinate)):
            object.__setattr__(self, name, value)

    def __setattr__(self, name, value):
        raise AttributeError("a Grid is immutable")

    def __reduce__(self):  # pickling and copying (the immutable slots cannot be set one by one)
        return _restore_grid, (self.exponent, tuple(self.origin.tolist()), self.width, self.max_coordinate)

    # -- construction ---------------------------------------------------------

    @classmethod
    def fit(cls, lo, hi, *, width: int = DEFAULT_WIDTH, max_coordinate: int | None = None) -> Grid:
        """The finest grid whose budget box holds the model box ``[lo, hi]`` (centred on it).

        The scale is the largest power of two for which both corners -- rounded exactly as
        :meth:`to_grid` rounds them -- stay within ``max_coordinate``; any model extent
        between the smallest subnormal and the largest double fits.
        """
        width = check_width(width)
        pts = _finite_points(np.stack([_real_array(lo, "lo").reshape(-1), _real_array(hi, "hi").reshape(-1)])
                             if np.size(lo) == 3 and np.size(hi) == 3 else _corner_error(lo, hi))
        limit = budget(width).max_mesh_coordinate
        max_coordinate = limit if max_coordinate is None else integer_scalar(max_coordinate, "max_coordinate")
        if not 1 <= max_coordinate <= limit:
            raise PrecisionError(f"max_coordinate must be in [1, {limit}] for {width} bits (the mesh budget, eq. 8), "
                                 f"got {max_coordinate}")
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        with np.errstate(over="ignore"):
            total = lo + hi
        # (lo + hi) / 2 overflows near the double range; halving first is exact there.
        origin = np.where(np.isfinite(total), total / 2, lo / 2 + hi / 2)
        offsets = np.concatenate([lo - origin, hi - origin])  # what to_grid computes for the corners
        extent = float(np.max(np.abs(offsets)))
        if extent == 0.0:
            return cls(origin=origin, width=width, max_coordinate=max_coordinate, exponent=0)
        # extent < 2**e, so 2**k with e + k = floor(log2(max_coordinate)) always fits; one
        # step finer may fit as well (the rounding of the corners decides).
        e = int(np.frexp(extent)[1])
        k = (max_coordinate.bit_length() - 1) - e
        if _corners_fit(offsets, k + 1, max_coordinate):
            k += 1
        return cls(origin=origin, width=width, max_coordinate=max_coordinate, exponent=k)

    @classmethod
    def from_resolution(cls, resolution: float, *, origin=(0.0, 0.0, 0.0), width: int = DEFAULT_WIDTH) -> Grid:
        """A grid at least as fine as ``resolution`` model units per step (scale rounded up to a power of two)."""
        if not isinstance(resolution, numbers.Real) or isinstance(resolution, bool):
            raise TypeError(f"resolution must be a real number, got {type(resolution).__name__} {resolution!r}")
        resolution = float(resolution)
        if not (np.isfinite(resolution) and resolution > 0):
            raise GeometryError(f"resolution must be a positive finite number, got {resolution!r}")
        # resolution = m * 2**e with m in [0.5, 1): the smallest power of two >= 1/resolution is 2**(1 - e).
        exponent = 1 - int(np.frexp(resolution)[1])
        return cls(origin=origin, width=width, exponent=exponent)

    # -- queries --------------------------------------------------------------

    @property
    def scale(self) -> float:
        """Grid units per model unit, ``2.0**exponent`` (``inf`` beyond the double range)."""
        return math.ldexp(1.0, self.exponent) if self.exponent <= 1023 else math.inf

    def model_volume(self, volume):
        """An exact volume in grid units cubed (a Fraction or an int) in model units cubed, exactly.

        The scale is ``2**exponent``, so this is a shift of the exact value (``times_power_of_two``): no gcd of its
        parts, which run to millions of bits for a 256-bit part carved by float meshes, and no double of the scale
        (``inf`` beyond 2**1023). Anything but an exact rational (a float, a string) is refused: a float volume
        would already have lost what this keeps.
        """
        if not isinstance(volume, numbers.Rational):
            raise TypeError(f"model_volume needs an exact volume (a Fraction or an int in grid units cubed, as "
                            f"Workpiece.volume() gives), got {type(volume).__name__} {volume!r:.40}")
        return times_power_of_two(Fraction(volume), -3 * self.exponent)

    @property
    def resolution(self) -> float:
        """Model-space size of one grid step, ``2.0**-exponent`` (0.0 when that underflows)."""
        return math.ldexp(1.0, -self.exponent) if self.exponent >= -1023 else math.inf

    @property
    def offset(self) -> np.ndarray:
        """Alias of ``origin`` (the name :func:`quantize` used)."""
        return self.origin

    def model_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The model-space box ``(lo, hi)`` whose points quantize within the budget."""
        half = np.ldexp(float(self.max_coordinate), -self.exponent)
        return self.origin - half, self.origin + half

    def same_as(self, other: Grid) -> bool:
        """Whether ``other`` is the same grid (scale, origin, width and bound)."""
        return (isinstance(other, Grid) and self.exponent == other.exponent and self.width == other.width
                and self.max_coordinate == other.max_coordinate and bool(np.array_equal(self.origin, other.origin)))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Grid) and self.same_as(other)

    def __hash__(self) -> int:
        return hash((self.exponent, tuple(self.origin.tolist()), self.width, self.max_coordinate))

    def to_grid(self, points) -> np.ndarray:
        """Return ``(n, 3) int64`` grid points nearest to model ``points`` ``(n, 3) float``."""
        pts = _finite_points(points)
        grid = np.rint(np.ldexp(pts - self.origin, self.exponent))
        if grid.size and np.max(np.abs(grid)) > self.max_coordinate:
            worst = int(np.argmax(np.max(np.abs(grid), axis=1)))
            lo, hi = self.model_bounds()
            raise PrecisionError(
                f"point {worst} ({pts[worst].tolist()}) lies outside this grid's budget box "
                f"(|grid coordinate| <= {self.max_coordinate} at {self.width} bits, model box "
                f"{lo.tolist()}..{hi.tolist()}); fit the grid to all geometry of the scene (Grid.fit) or use a "
                "wider width"
            )
        return grid.astype(np.int64)

    def to_model(self, points) -> np.ndarray:
        """Return model coordinates ``(n, 3) float64`` of grid or rational (float) ``points``."""
        pts = _real_array(points, "points")
        if pts.shape[-1:] != (3,):
            raise GeometryError(f"points must have shape (n, 3) or (3,), got {pts.shape}")
        return np.ldexp(pts, -self.exponent) + self.origin

    def __repr__(self) -> str:
        return (f"Grid(resolution=2**{-self.exponent} ({self.resolution:g}), origin={self.origin.tolist()}, "
                f"width={self.width}, max_coordinate={self.max_coordinate})")


def _restore_grid(exponent: int, origin, width: int, max_coordinate: int) -> Grid:
    return Grid(origin=origin, width=width, max_coordinate=max_coordinate, exponent=exponent)


Quantization = Grid
"""The name :func:`quantize` has always returned (an alias of :class:`Grid`)."""


def _corners_fit(offsets: np.ndarray, k: int, max_coordinate: int) -> bool:
    return bool(np.max(np.abs(np.rint(np.ldexp(offsets, k)))) <= max_coordinate)


def _corner_error(lo, hi):
    raise GeometryError(f"lo and hi must be points (3,), got shapes {np.shape(lo)} and {np.shape(hi)}")


def _real_array(values, name: str) -> np.ndarray:
    """``values`` as a float64 array; refuse strings, complex numbers, booleans and other non-numbers."""
    arr = np.asarray(values) if not isinstance(values, str | bytes) else np.asarray([values])
    kind = arr.dtype.kind
    if kind == "O":
        for v in arr.reshape(-1):
            if not isinstance(v, numbers.Real) or isinstance(v, bool | np.bool_):
                raise TypeError(f"{name} must be real numbers, got {type(v).__name__} {v!r}")
        return arr.astype(np.float64)
    if kind == "c":
        raise TypeError(f"{name} are complex numbers (dtype {arr.dtype}); geometry needs real coordinates")
    if kind in "USa":
        raise TypeError(f"{name} are strings (dtype {arr.dtype}); pass numbers")
    if kind not in "iuf":
        raise TypeError(f"{name} must be real numbers, got dtype {arr.dtype}")
    return arr.astype(np.float64, copy=False)


def _finite_points(points) -> np.ndarray:
    pts = _real_array(points, "points")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise GeometryError(f"points must have shape (n, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        row = int(np.argmax(~np.all(np.isfinite(pts), axis=1)))
        raise GeometryError(f"points[{row}] = {pts[row].tolist()} contains NaN or infinity; remove it before "
                            "quantizing")
    return pts


def quantize(vertices, width: int = DEFAULT_WIDTH, *, max_coordinate: int | None = None) -> tuple[np.ndarray, Grid]:
    """Return ``vertices`` rounded to the integer grid of ``width``, and the map back.

    The bounding box is centred on the origin and scaled by the largest power of
    two that keeps every coordinate within ``max_coordinate`` (default: the
    mesh budget of ``width``, eq. 8, so planes through any three grid vertices
    are exact). Any finite float vertices fit, from subnormal to the largest doubles.

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

    Raises
    ------
    GeometryError
        Wrong shape, NaN or infinite coordinates, no vertices.
    PrecisionError
        A bad ``width`` or ``max_coordinate``.
    TypeError
        Strings, complex numbers or other non-numbers.
    """
    pts = _finite_points(vertices)
    if pts.shape[0] == 0:
        raise GeometryError("cannot quantize an empty vertex array")
    q = Grid.fit(pts.min(axis=0), pts.max(axis=0), width=width, max_coordinate=max_coordinate)
    return q.to_grid(pts), q
