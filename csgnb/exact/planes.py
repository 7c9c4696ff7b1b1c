"""Plane storage: full-width rows, and the narrow plane record of paper §4.4.

A plane (a, b, c, d) can be stored two ways, and every predicate and intrinsic of
:mod:`csgnb.exact` accepts both (the layout is read from the dtype at typing time, so
a kernel written for one compiles for the other unchanged):

* **full rows**: an ``(n, 4)`` wide array (:func:`csgnb.exact.wide_dtype`), every
  coefficient at the full width -- 64 / 96 / 128 B per plane;
* **narrow planes**: an ``(n,)`` array of the record :func:`plane_dtype`, normals at a
  quarter of the width and the offset at half of it (§4.4: "plane coefficients are
  significantly smaller than the largest intermediate result") -- 20 B at 128 bits
  (3 x int32 + int64), 40 B at 192 and 256 bits (3 x int64 + int128).

The narrow fields hold every plane through mesh vertices within the mesh budget of the
width (``N <= 8 V^2``, ``D <= 24 V^3``, eq. 8) -- :func:`narrow_fields_hold_the_mesh_budget`
checks this exactly -- but not every plane the general budget (eq. 7) admits:
:func:`to_narrow_planes` raises :class:`PrecisionError` for those.

>>> from csgnb import exact
>>> full = exact.to_wide([[1, -2, 3, -40], [0, 0, 1, 5]], 128)
>>> narrow = exact.to_narrow_planes(full)
>>> narrow.dtype.itemsize, narrow["normal"].tolist(), narrow["offset"].tolist()
(20, [[1, -2, 3], [0, 0, 1]], [-40, 5])
>>> exact.from_wide(exact.to_full_planes(narrow)).tolist()
[[1, -2, 3, -40], [0, 0, 1, 5]]
"""

from __future__ import annotations

import numpy as np

from csgnb.errors import GeometryError, PrecisionError
from csgnb.exact.wide import WIDTHS, check_width, from_wide, is_wide, to_wide, wide_dtype, width_of

__all__ = [
    "plane_dtype",
    "is_narrow_planes",
    "plane_width_of",
    "to_narrow_planes",
    "to_full_planes",
    "narrow_field_bits",
    "narrow_fields_hold_the_mesh_budget",
]

#: (normal bits, offset bits) of the narrow plane record per width.
_FIELD_BITS = {128: (32, 64), 192: (64, 128), 256: (64, 128)}


def _narrow_dtype(width: int) -> np.dtype:
    n_bits, d_bits = _FIELD_BITS[width]
    # The title carries the width: the 192- and 256-bit records have the same fields and
    # size, and a kernel must know which width it computes at.
    normal = ((f"normal ({width}-bit plane)", "normal"), f"<i{n_bits // 8}", (3,))
    offset = ("offset", "<i8") if d_bits == 64 else ("offset", "<u8", (2,))
    return np.dtype([normal, offset])


_NARROW = {w: _narrow_dtype(w) for w in WIDTHS}
_WIDTH_OF_NARROW = {dt: w for w, dt in _NARROW.items()}


def plane_dtype(width: int) -> np.dtype:
    """Return the narrow plane record of ``width`` bits: fields ``normal`` (3,) and ``offset``.

    ``normal`` is int32 (128 bits) or int64 (192, 256 bits); ``offset`` is int64 at 128 bits
    and a little-endian int128 (two ``uint64`` limbs) at 192 and 256 bits.
    """
    return _NARROW[check_width(width)]


def narrow_field_bits(width: int) -> tuple[int, int]:
    """(normal bits, offset bits) of the narrow plane record of ``width`` bits."""
    return _FIELD_BITS[check_width(width)]


def is_narrow_planes(arr) -> bool:
    """Return whether ``arr`` is an array of narrow plane records (:func:`plane_dtype`), or one record."""
    return isinstance(arr, np.ndarray | np.void) and arr.dtype in _WIDTH_OF_NARROW


def plane_width_of(planes) -> int:
    """Width in bits of planes in either layout (``(n, 4)`` wide rows or narrow records); ``TypeError`` otherwise."""
    if is_narrow_planes(planes):
        return _WIDTH_OF_NARROW[planes.dtype]
    if is_wide(planes):
        return width_of(planes)
    raise TypeError(
        "expected planes: an (n, 4) wide array (csgnb.exact.to_wide) or narrow plane records "
        f"(csgnb.exact.to_narrow_planes); got {getattr(planes, 'dtype', type(planes).__name__)!r}"
    )


def _field_limits(width: int) -> tuple[int, int]:
    n_bits, d_bits = _FIELD_BITS[width]
    # The most negative value is excluded, so that |value| fits and products of two
    # normals (int64 at 128 bits) cannot overflow: (2^31 - 1)^2 * 2 < 2^63.
    return (1 << (n_bits - 1)) - 1, (1 << (d_bits - 1)) - 1


def narrow_fields_hold_the_mesh_budget(width: int) -> bool:
    """Whether planes through vertices within the mesh budget (|n| <= 8 V^2, |d| <= 24 V^3) fit the narrow fields."""
    from csgnb.exact.budgets import budget  # budgets checks planes of both layouts: imported here, not at the top

    b = budget(width)
    n_max, d_max = _field_limits(check_width(width))
    return b.max_mesh_normal <= n_max and b.max_mesh_offset <= d_max


def to_narrow_planes(planes: np.ndarray) -> np.ndarray:
    """Return ``(n, 4)`` wide planes (or one ``(4,)`` plane) as narrow plane records ``(n,)`` (or ``()``).

    Raises :class:`PrecisionError` naming the first plane whose normal does not fit the
    narrow normal field (|a|, |b|, |c| < 2**31 at 128 bits, < 2**63 at 192/256) or whose
    offset does not fit half the width; planes from in-budget meshes always fit.
    """
    if is_narrow_planes(planes):
        return planes
    width = width_of(planes)
    planes = np.asarray(planes)
    if planes.shape[-1:] != (4,) or planes.ndim not in (1, 2):
        raise GeometryError(f"planes must have shape (n, 4) or (4,), got {planes.shape}")
    rows = np.ascontiguousarray(planes).reshape(-1, 4)
    k = width // 64
    limbs = rows["limbs"]  # (n, 4, k)
    n_max, d_max = _field_limits(width)
    n_bits, d_bits = _FIELD_BITS[width]
    signed = limbs.view(np.int64)
    # A value fits in 64 * j bits iff the limbs from j on repeat its sign; 32 bits: also the low limb's range.
    sign = signed[..., k - 1] >> 63  # (n, 4) of 0 / -1
    ok_high_n = np.all(signed[:, :3, 1:] == sign[:, :3, None], axis=-1)
    low_n = signed[:, :3, 0]
    ok_n = (ok_high_n & (np.abs(low_n) <= n_max) & ((low_n < 0) == (sign[:, :3] < 0))
            & (low_n != np.iinfo(np.int64).min))
    dj = d_bits // 64
    ok_d = np.all(signed[:, 3, dj:] == sign[:, 3, None], axis=-1) if k > dj else np.ones(rows.shape[0], bool)
    if dj == 1:
        ok_d &= ((signed[:, 3, 0] < 0) == (sign[:, 3] < 0)) & (signed[:, 3, 0] != np.iinfo(np.int64).min)
    else:
        ok_d &= ((signed[:, 3, 1] < 0) == (sign[:, 3] < 0)) & ~((limbs[:, 3, 1] == np.uint64(1 << 63))
                                                                 & (limbs[:, 3, 0] == 0))
    bad = np.flatnonzero(~(ok_n.all(axis=1) & ok_d))
    if bad.size:
        r = int(bad[0])
        values = [int(v) for v in from_wide(rows[r])]
        raise PrecisionError(
            f"plane {r} {values} does not fit the narrow {width}-bit plane record (normals |a|, |b|, |c| <= "
            f"{n_max} = 2**{n_bits - 1} - 1, offset |d| <= 2**{d_bits - 1} - 1); planes through vertices within "
            "the mesh budget always fit -- keep this one in full rows"
        )
    out = np.empty(rows.shape[0], _NARROW[width])
    out["normal"] = low_n.astype(out["normal"].dtype)
    if dj == 1:
        out["offset"] = signed[:, 3, 0]
    else:
        out["offset"] = limbs[:, 3, :2]
    return out.reshape(planes.shape[:-1])


def to_full_planes(planes: np.ndarray) -> np.ndarray:
    """Return narrow plane records ``(n,)`` (or ``()``) as ``(n, 4)`` (or ``(4,)``) wide rows of their width."""
    if is_wide(planes):
        return planes
    width = plane_width_of(planes)
    planes = np.asarray(planes)
    flat = np.ascontiguousarray(planes).reshape(-1)
    out = np.zeros((flat.shape[0], 4), wide_dtype(width))
    normal = flat["normal"].astype(np.int64)
    out[:, :3] = to_wide(normal, width)
    if _FIELD_BITS[width][1] == 64:
        out[:, 3] = to_wide(flat["offset"].astype(np.int64), width)
    else:
        limbs = out["limbs"]
        limbs[:, 3, :2] = flat["offset"]
        top = flat["offset"][:, 1] >> np.uint64(63)
        limbs[:, 3, 2:] = np.where(top, np.uint64(0xFFFFFFFFFFFFFFFF), np.uint64(0))[:, None]
    return out.reshape(planes.shape + (4,))


def as_planes(planes, name: str = "planes") -> np.ndarray:
    """``planes`` in either layout as a C-contiguous array of rows: ``(n, 4)`` wide or ``(n,)`` narrow."""
    if is_narrow_planes(planes):
        arr = np.ascontiguousarray(np.asarray(planes))
        return arr.reshape(1) if arr.ndim == 0 else arr
    if is_wide(planes):
        arr = planes[None, :] if planes.ndim == 1 else planes
        if arr.ndim != 2 or arr.shape[1] != 4:
            raise GeometryError(f"{name} must have shape (n, 4) or (4,), got {planes.shape}")
        return np.ascontiguousarray(arr)
    plane_width_of(planes)  # raises the TypeError
    raise AssertionError  # pragma: no cover
