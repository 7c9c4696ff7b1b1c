"""Exact conversion of user input to integers: integral values pass, anything else is refused.

Exact predicates work on integers, and a silently truncated coordinate is a wrong
answer with no error (``int(2.7) == 2``). Every public entry point of the exact track
turns its integer arguments into integers through this module:

* integers of any kind (Python ``int``, numpy integers, ``uint8`` ... ``uint64``) are
  taken as they are (values beyond the target range raise :class:`PrecisionError`);
* *integral* floats, ``Fraction`` and ``Decimal`` values (``2.0``, ``Fraction(6, 3)``,
  ``Decimal("4")``) are accepted and converted exactly;
* non-integral numbers (``2.7``, ``Fraction(7, 2)``) raise :class:`PrecisionError` with
  the hint to put float geometry on a grid first (:func:`csgnb.exact.quantize`,
  :class:`csgnb.exact.Grid`); NaN and infinities raise :class:`GeometryError`;
* strings, complex numbers, ``None``, booleans and other objects raise ``TypeError``.

>>> integer_array([[0, 2.0, 3]], "corner")
array([[0, 2, 3]])
>>> integer_array([2.7], "corner")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
csgnb.errors.PrecisionError: corner[0] = 2.7 is not an integer: ... (csgnb.exact.quantize or csgnb.exact.Grid)
"""

from __future__ import annotations

import numbers
from decimal import Decimal
from fractions import Fraction

import numpy as np

from csgnb.errors import GeometryError, PrecisionError

__all__ = ["exact_int", "integer_array", "integer_scalar", "max_abs", "python_int_array"]

_HINT = "put float geometry on an integer grid first (csgnb.exact.quantize or csgnb.exact.Grid)"
_INT64_MIN, _INT64_MAX = -(1 << 63), (1 << 63) - 1


def _where(name: str, index) -> str:
    if index is None:
        return name
    if isinstance(index, tuple):
        return f"{name}[{', '.join(str(int(i)) for i in index)}]"
    return f"{name}[{int(index)}]"


def exact_int(value, name: str = "value", index=None) -> int:
    """Return ``value`` as a Python int if it is an integer or an integral real number; refuse it otherwise.

    Raises ``TypeError`` for non-numbers (strings, complex numbers, ``None``, booleans),
    :class:`GeometryError` for NaN or infinities and :class:`PrecisionError` for
    non-integral values. ``name`` and ``index`` name the argument in the message.
    """
    if type(value) is int:  # the common case, first
        return value
    where = _where(name, index)
    if isinstance(value, bool | np.bool_):
        raise TypeError(f"{where} is a boolean ({value!r}); pass an integer")
    if isinstance(value, numbers.Integral):  # int, numpy integers, sympy Integer, ...
        return int(value)
    if isinstance(value, float | np.floating):
        v = float(value)
        if not np.isfinite(v):
            raise GeometryError(f"{where} = {v} is not finite; exact geometry needs finite integer coordinates")
        if v != np.floor(v):
            raise PrecisionError(f"{where} = {value!r} is not an integer: exact geometry needs integer coordinates; "
                                 + _HINT)
        return int(v)
    if isinstance(value, Decimal):
        if not value.is_finite():
            raise GeometryError(f"{where} = {value} is not finite; exact geometry needs finite integer coordinates")
        if value != value.to_integral_value():
            raise PrecisionError(f"{where} = {value!r} is not an integer: exact geometry needs integer coordinates; "
                                 + _HINT)
        return int(value)
    if isinstance(value, numbers.Rational):  # Fraction, sympy Rational
        f = Fraction(int(value.numerator), int(value.denominator))
        if f.denominator != 1:
            raise PrecisionError(f"{where} = {value!r} is not an integer: exact geometry needs integer coordinates; "
                                 + _HINT)
        return int(f.numerator)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return exact_int(value.item(), name, index)
    raise TypeError(f"{where} must be an integer, got {type(value).__name__} {value!r}")


def integer_scalar(value, name: str, *, minimum: int | None = None, maximum: int | None = None) -> int:
    """Return the single integer ``value`` (see :func:`exact_int`), optionally checked against a range.

    A value outside ``[minimum, maximum]`` raises :class:`PrecisionError` naming the range.
    """
    if isinstance(value, np.ndarray | list | tuple):
        arr = np.asarray(value, dtype=object)
        if arr.size != 1:
            raise TypeError(f"{name} must be a single integer, got an array of shape {arr.shape}")
        value = arr.reshape(-1)[0]
    v = exact_int(value, name)
    if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
        lo = "-inf" if minimum is None else minimum
        hi = "inf" if maximum is None else maximum
        raise PrecisionError(f"{name} must lie in [{lo}, {hi}], got {v}")
    return v


def _object_array(values) -> np.ndarray:
    """``values`` as a numpy array without numpy's own lossy conversions (big ints stay ints)."""
    if isinstance(values, np.ndarray):
        return values
    if isinstance(values, str | bytes):
        raise TypeError(f"expected integers, got the string {values!r}")
    try:
        arr = np.array(values, dtype=object)
    except (ValueError, TypeError) as exc:  # ragged nesting
        raise GeometryError(f"could not read the values as a rectangular array: {exc}") from None
    if arr.dtype == object and arr.size:
        # Nested sequences numpy could not make rectangular come back as 1-D arrays of lists.
        first = arr.reshape(-1)[0]
        if isinstance(first, list | tuple | np.ndarray):
            raise GeometryError("could not read the values as a rectangular array (ragged rows)")
    return arr


def python_int_array(values, name: str = "values") -> np.ndarray:
    """Return ``values`` (any shape) as an object array of Python ints, each converted by :func:`exact_int`."""
    arr = _object_array(values)
    if arr.dtype.kind in "iu":
        out = np.empty(arr.shape, dtype=object)
        out.reshape(-1)[:] = arr.reshape(-1).tolist()
        return out
    if arr.dtype.kind not in "fO":
        _refuse_dtype(arr, name)
    flat = arr.reshape(-1)
    out = np.empty(arr.shape, dtype=object)
    shape = arr.shape
    out.reshape(-1)[:] = [exact_int(v, name, np.unravel_index(i, shape) if len(shape) > 1 else i)
                          for i, v in enumerate(flat.tolist() if arr.dtype.kind == "f" else flat)]
    return out


def _refuse_dtype(arr: np.ndarray, name: str) -> None:
    if arr.dtype.kind == "b":
        raise TypeError(f"{name} are booleans (dtype bool); pass integers")
    if arr.dtype.kind == "c":
        raise TypeError(f"{name} are complex numbers (dtype {arr.dtype}); exact geometry needs real integers")
    if arr.dtype.kind in "USa":
        raise TypeError(f"{name} are strings (dtype {arr.dtype}); pass numbers")
    raise TypeError(f"{name} must be integers, got dtype {arr.dtype}")


def integer_array(values, name: str = "values", *, dtype=np.int64) -> np.ndarray:
    """Return ``values`` (any shape) as an ``int64`` array, exactly (see :func:`exact_int`).

    Integer arrays of any width are range-checked (a ``uint64`` beyond ``2**63 - 1`` raises
    :class:`PrecisionError`); float arrays must hold integral, finite values; lists may mix
    ints, integral floats, Fractions and Decimals.
    """
    arr = _object_array(values)
    kind = arr.dtype.kind
    if kind in "iu":
        if arr.dtype == np.uint64 and arr.size and int(arr.max()) > _INT64_MAX:
            bad = np.unravel_index(int(np.argmax(arr)), arr.shape)
            raise PrecisionError(f"{_where(name, bad if arr.ndim != 1 else bad[0])} = {int(arr.max())} is beyond "
                                 "int64; exact geometry takes coordinates of at most 63 bits")
        return arr.astype(dtype, copy=False)
    if kind == "f":
        finite = np.isfinite(arr)
        if not finite.all():
            bad = np.argwhere(~finite)[0]
            index = tuple(bad) if arr.ndim != 1 else bad[0]
            raise GeometryError(f"{_where(name, index)} = {arr[tuple(bad)].item()} is not finite; exact geometry needs "
                                "finite integer coordinates")
        integral = arr == np.floor(arr)
        if not integral.all():
            bad = np.argwhere(~integral)[0]
            index = tuple(bad) if arr.ndim != 1 else bad[0]
            raise PrecisionError(f"{_where(name, index)} = {arr[tuple(bad)].item()!r} is not an integer: exact "
                                 "geometry needs integer coordinates; " + _HINT)
        if arr.size and (arr.max() >= 2.0**63 or arr.min() < -(2.0**63)):
            raise PrecisionError(f"{name} has values beyond int64; exact geometry takes coordinates of at most 63 bits")
        return arr.astype(dtype)
    if kind != "O":
        _refuse_dtype(arr, name)
    ints = python_int_array(arr, name)
    flat = ints.reshape(-1)
    for i, v in enumerate(flat):
        if not _INT64_MIN <= v <= _INT64_MAX:
            raise PrecisionError(f"{_where(name, i if ints.ndim == 1 else np.unravel_index(i, ints.shape))} = {v} is "
                                 "beyond int64; exact geometry takes coordinates of at most 63 bits")
    return np.array(flat.tolist(), dtype=dtype).reshape(ints.shape)


def max_abs(values: np.ndarray) -> int:
    """Exact max |v| of an int64 or Python-int (object) array as a Python int; 0 when empty.

    From the largest and the smallest value: no |v| array, which would wrap at -2**63 in int64 and make new
    objects in Python ints. An object array whose values fit in int64 is reduced in numpy's int64 loops (a
    256-bit hull's normals; its offsets often do not fit, and take the object loops).
    """
    if values.size == 0:
        return 0
    if values.dtype == object:
        try:
            values = values.astype(np.int64)
        except OverflowError:
            pass
    return max(int(values.max()), -int(values.min()))
