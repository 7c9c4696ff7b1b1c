"""Argument checks shared by the quadric track: numbers, finite arrays, points, flags, counts.

Each check names the argument and says what was expected. Wrong *types* (a string, ``None``, a
complex number, a bool where a number is meant) raise ``TypeError``; right types with unusable
values raise csgnb errors (``ValueError`` subclasses): :class:`GeometryError` for NaN, inf and
non-positive sizes, :class:`CsgnbError` for wrong shapes and ranges. (numpy would otherwise turn
``"1.5"`` into 1.5 and drop imaginary parts silently.)
"""

from __future__ import annotations

import numbers

import numpy as np

from csgnb.errors import CsgnbError, GeometryError

__all__ = ["as_real", "as_positive", "as_finite_array", "as_points", "as_flag", "as_count", "as_matrix", "as_instance"]


def as_instance(value, cls, name: str, what: str | None = None):
    """Return ``value`` if it is a ``cls``, else raise TypeError naming the argument and the type."""
    if not isinstance(value, cls):
        raise TypeError(f"{name} must be {what or 'a ' + cls.__name__}, got {_type_name(value)}")
    return value


def _type_name(value) -> str:
    return "None" if value is None else type(value).__name__


def as_real(value, name: str, *, finite: bool = True) -> float:
    """Return ``value`` as a float; a non-real type raises TypeError, NaN/inf GeometryError."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        if isinstance(value, np.ndarray) and value.shape == () and value.dtype.kind in "iuf":
            value = value.item()
        else:
            raise TypeError(f"{name} must be a real number, got {_type_name(value)} {value!r:.60}")
    v = float(value)
    if finite and not np.isfinite(v):
        raise GeometryError(f"{name} must be finite, got {v}")
    return v


def as_positive(value, name: str) -> float:
    """Return ``value`` as a positive finite float (TypeError for non-numbers)."""
    v = as_real(value, name)
    if not v > 0.0:
        raise GeometryError(f"{name} must be positive, got {v}")
    return v


def as_finite_array(values, shape: tuple[int, ...] | None, name: str, *, finite: bool = True) -> np.ndarray:
    """Return ``values`` as a float64 array of ``shape`` (any shape if None) with finite entries.

    ``finite=False`` keeps NaN and inf (for coordinates that kernels map to NaN).
    """
    if values is None or isinstance(values, str | bytes):
        raise TypeError(f"{name} must be an array of numbers, got {_type_name(values)}")
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError) as exc:  # ragged nesting
        raise TypeError(f"{name} must be an array of numbers, got {_type_name(values)}") from exc
    if arr.dtype.kind not in "iuf":
        what = {"c": "complex numbers", "b": "booleans", "U": "strings", "S": "bytes"}.get(arr.dtype.kind, "objects")
        if arr.dtype.kind == "O":
            try:
                arr = arr.astype(np.float64)
            except (TypeError, ValueError) as exc:
                raise TypeError(f"{name} must be an array of real numbers, got {what}") from exc
        else:
            raise TypeError(f"{name} must be an array of real numbers, got {what}")
    arr = arr.astype(np.float64)
    if shape is not None and arr.shape != shape:
        raise CsgnbError(f"{name} must have shape {shape}, got {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise GeometryError(f"{name} contains NaN or inf; pass finite numbers")
    return arr


def as_matrix(values, name: str) -> np.ndarray:
    """Return a 4×4 transform (a 3×4 affine ``[R | t]`` is completed with ``(0, 0, 0, 1)``)."""
    m = as_finite_array(values, None, name)
    if m.shape == (3, 4):
        m = np.vstack([m, [0.0, 0.0, 0.0, 1.0]])
    if m.shape != (4, 4):
        raise CsgnbError(f"{name} must be a 4×4 (or 3×4 affine) matrix, got shape {m.shape}")
    return m


def as_points(points, name: str = "points", dim: int = 3) -> np.ndarray:
    """Return ``points`` as a C-contiguous (n, dim) float64 array, or raise a clear error.

    A single point of shape (dim,) is accepted as one row. NaN and inf pass (kernels return NaN
    for them); wrong types and shapes do not.
    """
    if points is None or isinstance(points, str | bytes):
        raise TypeError(f"{name} must be an (n, {dim}) array of numbers, got {_type_name(points)}")
    try:
        arr = np.asarray(points)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an (n, {dim}) array of numbers, got {_type_name(points)}") from exc
    if arr.dtype.kind not in "iuf":
        try:
            if arr.dtype.kind != "O":
                raise TypeError
            arr = arr.astype(np.float64)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"{name} must be an (n, {dim}) array of real numbers, got dtype {arr.dtype}") from exc
    arr = arr.astype(np.float64, copy=False)
    if arr.ndim == 1 and arr.shape[0] == dim:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise CsgnbError(f"{name} must have shape (n, {dim}), got {arr.shape}")
    return np.ascontiguousarray(arr)


def as_flag(value, name: str) -> bool:
    """Return ``value`` as a bool; only ``True``/``False`` (and numpy bools) are accepted."""
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be True or False, got {_type_name(value)} {value!r:.60}")
    return bool(value)


def as_count(value, name: str, minimum: int = 0) -> int:
    """Return ``value`` as an int ≥ ``minimum`` (TypeError for floats, strings, bools)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {_type_name(value)} {value!r:.60}")
    v = int(value)
    if v < minimum:
        raise CsgnbError(f"{name} must be ≥ {minimum}, got {v}")
    return v
