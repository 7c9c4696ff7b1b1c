"""Fixed-width integers stored as little-endian uint64 limbs, and their conversions.

A *wide array* is an ordinary numpy array whose dtype is one of the three record
dtypes below: each element is one 128-, 192- or 256-bit two's-complement integer
stored as 2, 3 or 4 little-endian ``uint64`` limbs. The width travels with the
dtype, so a kernel compiled for a wide array knows its width, and
``arr["limbs"]`` is a plain ``(..., k) uint64`` view of the same memory.

Conversions to and from Python's unbounded ``int`` are part of the public API so
that every result can be checked and shown exactly.
"""

from __future__ import annotations

import numpy as np

from csgnb.errors import PrecisionError
from csgnb.exact.integral import exact_int, integer_array, python_int_array

__all__ = [
    "DEFAULT_WIDTH",
    "WIDTHS",
    "wide_dtype",
    "width_of",
    "to_wide",
    "to_width",
    "from_wide",
    "wide_max_abs",
    "is_wide",
    "check_width",
]

#: The supported integer widths in bits.
WIDTHS: tuple[int, ...] = (128, 192, 256)

DEFAULT_WIDTH: int = 128
"""The width every csgnb constructor uses unless told otherwise (quantize, Grid, BSP, workpieces):
the fastest, with a mesh budget of |coordinate| <= 4567 (eq. 8). Pass ``width=192`` or ``256`` for finer grids."""

_DTYPES = {w: np.dtype([("limbs", "<u8", (w // 64,))]) for w in WIDTHS}
_WIDTH_OF_DTYPE = {dt: w for w, dt in _DTYPES.items()}


def check_width(width) -> int:
    """Return ``width`` as an int if it is one of :data:`WIDTHS`; raise :class:`PrecisionError` otherwise.

    A non-integer (``"128"``, ``None``) raises ``TypeError``; ``128.0`` is accepted.
    """
    if type(width) is int and width in _DTYPES:
        return width
    try:
        w = exact_int(width, "width")
    except TypeError:
        raise TypeError(f"width must be one of {WIDTHS} bits (an int), got {width!r}") from None
    except ValueError:
        raise PrecisionError(f"width must be one of {WIDTHS} bits, got {width!r}") from None
    if w not in _DTYPES:
        raise PrecisionError(f"width must be one of {WIDTHS} bits, got {width!r}")
    return w


def wide_dtype(width: int) -> np.dtype:
    """Return the record dtype of a ``width``-bit integer (``width`` in 128, 192, 256)."""
    return _DTYPES[check_width(width)]


def is_wide(arr: np.ndarray) -> bool:
    """Return whether ``arr`` is a wide-integer array (one of the dtypes of :func:`wide_dtype`)."""
    return isinstance(arr, np.ndarray) and arr.dtype in _WIDTH_OF_DTYPE


def width_of(arr: np.ndarray) -> int:
    """Return the width in bits of the wide array ``arr``; raise ``TypeError`` otherwise."""
    if not is_wide(arr):
        raise TypeError(
            "expected a wide-integer array (dtype from csgnb.exact.wide_dtype); "
            f"got {getattr(arr, 'dtype', type(arr))!r}. Convert Python ints with csgnb.exact.to_wide."
        )
    return arr.dtype.itemsize * 8


def to_wide(values, width: int) -> np.ndarray:
    """Return ``values`` (integers of any shape) as a wide array of ``width`` bits.

    Parameters
    ----------
    values : array_like of int
        Python ints (any size), numpy integers, or integral floats, Fractions and
        Decimals (converted exactly); any shape.
    width : int
        128, 192 or 256.

    Returns
    -------
    (...) wide array with the shape of ``values``.

    Raises
    ------
    PrecisionError
        If a value does not fit in ``width``-bit two's complement, or is not an
        integer (``0.5``: quantize float geometry first, :func:`csgnb.exact.quantize`).
    TypeError
        For strings, complex numbers, booleans and other non-numbers.
    """
    dtype = wide_dtype(width)
    width = check_width(width)
    k = width // 64
    if is_wide(values):
        return to_width(values, width)
    arr = values if isinstance(values, np.ndarray) else None
    if arr is not None and arr.dtype.kind == "f" and arr.size and np.all(np.abs(arr) < 2.0**63):
        arr = integer_array(arr, "values")  # integral floats within int64: checked, then the fast path
    if arr is not None and arr.dtype.kind in "iu" and arr.dtype.itemsize <= 8:
        # Fast path: sign-extend 64-bit integers limb by limb, no Python loop.
        out = np.zeros(arr.shape, dtype)
        limbs = out["limbs"]
        if arr.dtype.kind == "u":
            limbs[..., 0] = arr.astype(np.uint64)
        else:
            signed = arr.astype(np.int64)
            limbs[..., 0] = signed.view(np.uint64)
            limbs[..., 1:] = np.where(signed < 0, np.uint64(0xFFFFFFFFFFFFFFFF), np.uint64(0))[
                ..., None
            ]
        return out
    if arr is not None and arr.dtype == object and arr.size and _only_python_ints(arr):
        return _python_ints_to_wide(arr, width)
    # Everything else goes through exact Python ints (numpy would turn ints beyond 64 bits into floats).
    ints = python_int_array(values, "values")
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    chunks = []
    for v in ints.reshape(-1):
        if not lo <= v <= hi:
            raise PrecisionError(
                f"integer {v} does not fit in {width} bits: the signed range is "
                f"[-2**{width - 1}, 2**{width - 1} - 1]; choose a wider width or smaller inputs"
            )
        chunks.append(v.to_bytes(8 * k, "little", signed=True))
    out = np.frombuffer(b"".join(chunks), dtype=dtype).copy()
    return out.reshape(ints.shape)


def _only_python_ints(arr: np.ndarray) -> bool:
    """Whether every element of the object array ``arr`` is a Python ``int`` (not a bool, not a numpy scalar)."""
    return set(map(type, arr.reshape(-1).tolist())) <= {int}


def _python_ints_to_wide(arr: np.ndarray, width: int) -> np.ndarray:
    """An object array of Python ints as a wide array. Along the last axis (a tool's planes: a, b, c, d), a column
    whose values all fit in int64 takes numpy's int64 loops (at 256 bits a hull's normals fit, its offsets often
    do not); the others are written as little-endian two's-complement bytes (``int.to_bytes``), which are the
    limbs. A hull's 100 planes at 256 bits: all four columns limb by limb in numpy's object loops ~0.25 ms, this
    ~0.05 ms."""
    k = width // 64
    out = np.zeros(arr.shape, wide_dtype(width))
    limbs = out["limbs"]
    columns = arr.reshape(-1, arr.shape[-1]) if arr.ndim >= 2 else arr.reshape(-1, 1)
    dst = limbs.reshape(columns.shape + (k,))
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    for c in range(columns.shape[1]):  # a few columns (the last axis): the loop is over them, not the values
        col = columns[:, c]
        try:
            small = col.astype(np.int64)
        except OverflowError:
            small = None
        if small is not None:
            dst[:, c, 0] = small.view(np.uint64)
            dst[:, c, 1:] = np.where(small < 0, np.uint64(0xFFFFFFFFFFFFFFFF), np.uint64(0))[:, None]
            continue
        values = col.tolist()
        try:  # to_bytes refuses exactly the values outside the signed range of ``width`` bits
            raw = b"".join([v.to_bytes(8 * k, "little", signed=True) for v in values])
        except OverflowError:
            v = next(v for v in values if not lo <= v <= hi)
            raise PrecisionError(
                f"integer {v} does not fit in {width} bits: the signed range is "
                f"[-2**{width - 1}, 2**{width - 1} - 1]; choose a wider width or smaller inputs"
            ) from None
        dst[:, c, :] = np.frombuffer(raw, np.uint64).reshape(-1, k)
    return out


def wide_max_abs(arr: np.ndarray) -> int:
    """Exact max |v| over the wide array ``arr`` as a Python int (0 when empty), without a Python int per value.

    The magnitudes are formed limb by limb (two's complement negated where the sign limb says so, the carry
    carried up), ordered as unsigned numbers by ``np.lexsort`` with the top limb as the first key, and only the
    largest is converted. |-2**(w-1)| = 2**(w-1) is an unsigned w-bit number, so nothing wraps."""
    width_of(arr)
    limbs = np.ascontiguousarray(arr).reshape(-1)["limbs"]
    if limbs.shape[0] == 0:
        return 0
    k = limbs.shape[1]
    negative = (limbs[:, k - 1] >> np.uint64(63)).astype(np.bool_)
    magnitude = np.where(negative[:, None], ~limbs, limbs)
    carry = negative
    for i in range(k):  # + 1 where negated: ~v + 1 = -v
        column = magnitude[:, i] + carry.astype(np.uint64)
        carry = carry & (column == 0)
        magnitude[:, i] = column
    top = magnitude[np.lexsort(tuple(magnitude[:, i] for i in range(k)))[-1]]
    return int.from_bytes(np.ascontiguousarray(top).tobytes(), "little")


def to_width(arr: np.ndarray, width: int) -> np.ndarray:
    """Return the wide array ``arr`` converted to ``width`` bits (same values, same shape).

    Widening always succeeds (sign extension); narrowing raises :class:`PrecisionError`
    naming the first value that does not fit. Returns ``arr`` itself when the width is
    already ``width``.
    """
    old = width_of(arr)
    width = check_width(width)
    if old == width:
        return arr
    k_old, k_new = old // 64, width // 64
    src = np.ascontiguousarray(arr)["limbs"]
    out = np.empty(arr.shape, wide_dtype(width))
    dst = out["limbs"]
    k = min(k_old, k_new)
    dst[..., :k] = src[..., :k]
    if k_new > k_old:
        sign = np.where(src[..., k_old - 1] >> np.uint64(63), np.uint64(0xFFFFFFFFFFFFFFFF), np.uint64(0))
        dst[..., k_old:] = sign[..., None]
    else:
        # Fits iff every dropped limb, and the top bit of the kept ones, repeat the sign.
        kept_sign = np.where(src[..., k_new - 1] >> np.uint64(63), np.uint64(0xFFFFFFFFFFFFFFFF), np.uint64(0))
        ok = np.all(src[..., k_new:] == kept_sign[..., None], axis=-1)
        if not ok.all():
            bad = np.argwhere(~ok)[0]
            value = int(from_wide(np.asarray(arr)[tuple(bad)][None])[0])
            where = ", ".join(str(int(i)) for i in bad)
            raise PrecisionError(
                f"value [{where}] = {value} does not fit in {width} bits (signed range "
                f"[-2**{width - 1}, 2**{width - 1} - 1]); keep the {old}-bit width or use smaller inputs"
            )
    return out


def from_wide(arr: np.ndarray) -> np.ndarray:
    """Return the wide array ``arr`` as an object array of Python ints of the same shape."""
    width_of(arr)
    size = arr.dtype.itemsize
    flat = np.ascontiguousarray(arr).reshape(-1)
    limbs = flat["limbs"]
    low = limbs[:, 0].view(np.int64)
    # most values fit one word (the upper limbs repeat its sign): numpy makes those Python ints in one pass
    fits = np.all(limbs[:, 1:] == (low >> 63).view(np.uint64)[:, None], axis=1)
    out = low.astype(object)
    if not fits.all():
        buf = flat.tobytes()
        for i in np.flatnonzero(~fits).tolist():
            out[i] = int.from_bytes(buf[i * size:(i + 1) * size], "little", signed=True)
    return out.reshape(arr.shape)
