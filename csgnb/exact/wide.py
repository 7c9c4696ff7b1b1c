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

__all__ = [
    "DEFAULT_WIDTH",
    "WIDTHS",
    "wide_dtype",
    "width_of",
    "to_wide",
    "from_wide",
    "is_wide",
]

#: The supported integer widths in bits.
WIDTHS: tuple[int, ...] = (128, 192, 256)

DEFAULT_WIDTH: int = 128
"""The width every csgnb constructor uses unless told otherwise (quantize, Grid, BSP, workpieces):
the fastest, with a mesh budget of |coordinate| <= 4567 (eq. 8). Pass ``width=192`` or ``256`` for finer grids."""

_DTYPES = {w: np.dtype([("limbs", "<u8", (w // 64,))]) for w in WIDTHS}


def wide_dtype(width: int) -> np.dtype:
    """Return the record dtype of a ``width``-bit integer (``width`` in 128, 192, 256)."""
    try:
        return _DTYPES[int(width)]
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"width must be one of {WIDTHS} bits, got {width!r}") from None


def is_wide(arr: np.ndarray) -> bool:
    """Return whether ``arr`` is a wide-integer array (one of the dtypes of :func:`wide_dtype`)."""
    return isinstance(arr, np.ndarray) and arr.dtype in _DTYPES.values()


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
        Python ints (any size) or a numpy integer array; any shape.
    width : int
        128, 192 or 256.

    Returns
    -------
    (...) wide array with the shape of ``values``.

    Raises
    ------
    PrecisionError
        If a value does not fit in ``width``-bit two's complement.
    """
    dtype = wide_dtype(width)
    k = width // 64
    # Lists go through object arrays: numpy would turn ints beyond 64 bits into floats.
    arr = values if isinstance(values, np.ndarray) else np.array(values, dtype=object)
    if arr.dtype.kind in "iu" and arr.dtype.itemsize <= 8:
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
    if arr.dtype.kind not in "iuO":
        raise TypeError(f"to_wide needs integers, got dtype {arr.dtype}")
    flat = arr.reshape(-1)
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    chunks = []
    for v in flat:
        v = int(v)
        if not lo <= v <= hi:
            raise PrecisionError(
                f"integer {v} does not fit in {width} bits: the signed range is "
                f"[-2**{width - 1}, 2**{width - 1} - 1]; choose a wider width or smaller inputs"
            )
        chunks.append(v.to_bytes(8 * k, "little", signed=True))
    out = np.frombuffer(b"".join(chunks), dtype=dtype).copy()
    return out.reshape(arr.shape)


def from_wide(arr: np.ndarray) -> np.ndarray:
    """Return the wide array ``arr`` as an object array of Python ints of the same shape."""
    width_of(arr)
    size = arr.dtype.itemsize
    buf = np.ascontiguousarray(arr).tobytes()
    ints = [int.from_bytes(buf[i : i + size], "little", signed=True) for i in range(0, len(buf), size)]
    out = np.empty(arr.shape, dtype=object)
    out.reshape(-1)[:] = ints
    return out
