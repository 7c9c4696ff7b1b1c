"""The exact plane predicates of the paper's Table 1, vectorized over numpy arrays.

Every function takes wide arrays (see :mod:`csgnb.exact.wide`) or ``int64``
integer points, checks them against the bit budget of their width
(:mod:`csgnb.exact.budgets`) and runs one jitted loop over the rows. Operands
broadcast along the first axis: an operand with one row (or a single 1-D
plane/point) is used for every row of the others.

=======================  =====================================  ======================
operation                inputs                                 result
=======================  =====================================  ======================
plane_from_points        3 x (n, 3) int64 points                (n, 4) wide planes
are_planes_parallel      2 x (n, 4) wide planes                 (n,) bool
signed_distance          (n, 3) int64 points, (n, 4) planes     (n,) wide  (n·v + d)
intersect_3_planes       3 x (n, 4) wide planes                 (n, 4) wide points
classify_vertex          (n, 4) wide points, (n, 4) planes      (n,) int8 in {-1, 0, 1}
to_double_position       (n, 4) wide points                     (n, 3) float64
points_equal             2 x (n, 4) wide points                 (n,) bool
=======================  =====================================  ======================
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit
from ..errors import GeometryError, PrecisionError
from .budgets import (
    _first_zero_normal,
    check_integer_points_against_planes,
    check_mesh_points,
    check_planes,
    check_points_against_planes,
)
from .integral import integer_array
from .intrinsics import (
    classify_at,
    compare_ratio_dyadic_at,
    intersect_into,
    plane_from_points_into,
    planes_parallel_at,
    points_equal_at,
    signed_distance_into,
    wide_divexact_at,
    wide_sign_at,
    wide_to_float_at,
    wide_to_int64_at,
)
from .wide import check_width, to_wide, wide_dtype, width_of

__all__ = [
    "homogeneous_points",
    "plane_from_points",
    "are_planes_parallel",
    "signed_distance",
    "intersect_3_planes",
    "classify_vertex",
    "to_double_position",
    "points_equal",
]

# ---------------------------------------------------------------------------
# kernels: one loop each; ``k if many else 0`` broadcasts single-row operands.


@jit
def _classify_kernel(points, planes, out):
    many_x, many_s = points.shape[0] != 1, planes.shape[0] != 1
    for t in range(out.shape[0]):
        out[t] = classify_at(points, t if many_x else 0, planes, t if many_s else 0)


@jit
def _intersect_kernel(P, Q, R, out):
    mp, mq, mr = P.shape[0] != 1, Q.shape[0] != 1, R.shape[0] != 1
    for t in range(out.shape[0]):
        intersect_into(P, t if mp else 0, Q, t if mq else 0, R, t if mr else 0, out, t)


@jit
def _plane_from_points_kernel(P, Q, R, out):
    mp, mq, mr = P.shape[0] != 1, Q.shape[0] != 1, R.shape[0] != 1
    for t in range(out.shape[0]):
        plane_from_points_into(P, t if mp else 0, Q, t if mq else 0, R, t if mr else 0, out, t)


@jit
def _gcd(a, b):
    while b != 0:
        a, b = b, a % b
    return a


@jit
def _canonicalize_kernel(planes):
    # Normals of planes through in-budget mesh points fit in int64 (8 V^2 < 2^57),
    # so the gcd is taken on machine words and only the division is wide.
    for t in range(planes.shape[0]):
        a = abs(wide_to_int64_at(planes, t, 0))
        b = abs(wide_to_int64_at(planes, t, 1))
        c = abs(wide_to_int64_at(planes, t, 2))
        g = _gcd(_gcd(a, b), c)
        if g > 1:
            for col in range(4):
                wide_divexact_at(planes, t, col, g)


@jit
def _signed_distance_kernel(points, planes, out):
    many_v, many_s = points.shape[0] != 1, planes.shape[0] != 1
    for t in range(out.shape[0]):
        signed_distance_into(points, t if many_v else 0, planes, t if many_s else 0, out, t)


@jit
def _parallel_kernel(P, Q, out):
    mp, mq = P.shape[0] != 1, Q.shape[0] != 1
    for t in range(out.shape[0]):
        out[t] = planes_parallel_at(P, t if mp else 0, Q, t if mq else 0)


@jit
def _points_equal_kernel(X, Y, out):
    mx, my = X.shape[0] != 1, Y.shape[0] != 1
    for t in range(out.shape[0]):
        out[t] = points_equal_at(X, t if mx else 0, Y, t if my else 0)


@jit
def _first_zero_w(points):
    for t in range(points.shape[0]):
        if wide_sign_at(points, t, 3) == 0:
            return t
    return -1


_TWO_POW_53 = 9007199254740992.0
_TWO_POW_52 = 4503599627370496


@jit
def _ratio_to_double(points, i, c):
    """x_c / x_4 of ``points[i]`` rounded to the nearest double, ties to even.

    A float estimate (within 2 ulp) is corrected by exact comparisons of the
    rational with the dyadic midpoints between adjacent doubles.
    """
    sn = wide_sign_at(points, i, c)
    if sn == 0:
        return 0.0
    sw = wide_sign_at(points, i, 3)
    q = abs(wide_to_float_at(points, i, c)) / abs(wide_to_float_at(points, i, 3))
    for _ in range(8):
        m, e = math.frexp(q)
        mant = np.int64(m * _TWO_POW_53)  # q = mant * 2**(e - 53), 2**52 <= mant < 2**53
        exp = np.int64(e - 53)
        up = compare_ratio_dyadic_at(points, i, c, 3, 2 * mant + 1, exp - 1)
        if up > 0 or (up == 0 and (mant & 1) == 1):
            q = np.nextafter(q, np.inf)
            continue
        if mant == _TWO_POW_52:  # the double below q is half an ulp closer
            down = compare_ratio_dyadic_at(points, i, c, 3, 4 * mant - 1, exp - 2)
        else:
            down = compare_ratio_dyadic_at(points, i, c, 3, 2 * mant - 1, exp - 1)
        if down < 0 or (down == 0 and (mant & 1) == 1):
            q = np.nextafter(q, 0.0)
            continue
        break
    return q if sn * sw > 0 else -q


@jit
def _to_double_kernel(points, out):
    for t in range(points.shape[0]):
        for c in range(3):
            out[t, c] = _ratio_to_double(points, t, c)


# ---------------------------------------------------------------------------
# argument handling


def _rows(arr, ncols: int, name: str, *, wide: bool) -> np.ndarray:
    """``arr`` as a C-contiguous 2-D array of ``ncols`` columns (a 1-D row becomes one row)."""
    if wide:
        width_of(arr)
    else:
        arr = integer_array(arr, name)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != ncols:
        raise GeometryError(f"{name} must have shape (n, {ncols}) or ({ncols},), got {arr.shape}")
    return np.ascontiguousarray(arr)


def _broadcast_length(**arrays: np.ndarray) -> int:
    lengths = {a.shape[0] for a in arrays.values()} - {1}
    if len(lengths) > 1:
        shapes = ", ".join(f"{k}: {v.shape}" for k, v in arrays.items())
        raise GeometryError(f"operands have different numbers of rows and cannot broadcast ({shapes})")
    return lengths.pop() if lengths else 1


def _same_width(**arrays: np.ndarray) -> int:
    widths = {k: width_of(a) for k, a in arrays.items()}
    if len(set(widths.values())) != 1:
        raise PrecisionError(f"operands have different widths {widths}; convert them to one width "
                             "(csgnb.exact.to_width)")
    return next(iter(widths.values()))


def _squeeze(result: np.ndarray, *inputs) -> np.ndarray:
    """Drop the row axis again when every input was a single 1-D row."""
    if all(np.ndim(x) == 1 for x in inputs):
        return result[0]
    return result


# ---------------------------------------------------------------------------
# public API


def homogeneous_points(points, width: int = 256) -> np.ndarray:
    """Return integer points ``(n, 3) int64`` as homogeneous wide points ``(n, 4)`` with x4 = 1."""
    width = check_width(width)
    P = _rows(points, 3, "points", wide=False)
    out = np.concatenate([P, np.ones((P.shape[0], 1), np.int64)], axis=1)
    return _squeeze(to_wide(out, width), points)


def plane_from_points(p, q, r, *, width: int = 256, canonical: bool = True) -> np.ndarray:
    """Return the integer planes (a, b, c, d) through the integer points p, q, r.

    ``n = (q - p) x (r - p)`` and ``d = -n·p``, so p, q, r run counter-clockwise
    seen from the positive side. With ``canonical=True`` the four coefficients are
    divided by gcd(a, b, c), which makes equal planes compare equal.

    Parameters
    ----------
    p, q, r : (n, 3) or (3,) int64
        Vertices within the mesh budget of ``width`` (eq. 8: |coordinate| <=
        ``budget(width).max_mesh_coordinate``).
    width : {128, 192, 256}

    Returns
    -------
    (n, 4) wide array of ``width`` bits ((4,) for 1-D inputs).

    Raises
    ------
    PrecisionError
        A coordinate exceeds the mesh budget.
    GeometryError
        Three points of a row are collinear (the normal is zero).
    """
    width = check_width(width)
    P, Q, R = (_rows(x, 3, name, wide=False) for x, name in ((p, "p"), (q, "q"), (r, "r")))
    for arr, name in ((P, "p"), (Q, "q"), (R, "r")):
        check_mesh_points(arr, width, name)
    n = _broadcast_length(p=P, q=Q, r=R)
    out = np.empty((n, 4), wide_dtype(width))
    _plane_from_points_kernel(P, Q, R, out)
    zero = int(_first_zero_normal(out))
    if zero >= 0:
        raise GeometryError(f"points p[{zero}], q[{zero}], r[{zero}] are collinear: they span no plane")
    if canonical:
        _canonicalize_kernel(out)
    return _squeeze(out, p, q, r)


def are_planes_parallel(p, q) -> np.ndarray:
    """Return whether the normals of planes p and q are parallel (n_p x n_q = 0, eq. 1).

    Opposite orientations count as parallel. ``p, q`` : (n, 4) wide planes.
    Returns (n,) bool.
    """
    P, Q = _rows(p, 4, "p", wide=True), _rows(q, 4, "q", wide=True)
    _same_width(p=P, q=Q)
    check_planes(np.concatenate([P, Q]), "planes")
    out = np.empty(_broadcast_length(p=P, q=Q), np.bool_)
    _parallel_kernel(P, Q, out)
    return _squeeze(out, p, q)


def signed_distance(points, planes) -> np.ndarray:
    """Return ``n·v + d`` for integer points v and planes (n, d): the distance times |n|.

    ``points`` : (n, 3) int64; ``planes`` : (n, 4) wide. Returns an (n,) wide array
    of the planes' width (convert with :func:`csgnb.exact.from_wide`).
    """
    V = _rows(points, 3, "points", wide=False)
    S = _rows(planes, 4, "planes", wide=True)
    check_planes(S)
    check_integer_points_against_planes(V, S)
    out = np.empty(_broadcast_length(points=V, planes=S), S.dtype)
    _signed_distance_kernel(V, S, out)
    return _squeeze(out, points, planes)


def intersect_3_planes(p, q, r) -> np.ndarray:
    """Return the homogeneous intersection points (x1, x2, x3, x4) of planes p, q, r (eq. 5).

    The Cartesian point is (x1, x2, x3) / x4; ``x·s = det[s; p; q; r]`` for any plane
    s. ``p, q, r`` : (n, 4) wide planes of one width, together within its budget.
    Returns an (n, 4) wide array.

    Raises
    ------
    GeometryError
        The normals of a row are linearly dependent (no unique point; x4 = 0).
    """
    P, Q, R = (_rows(x, 4, name, wide=True) for x, name in ((p, "p"), (q, "q"), (r, "r")))
    _same_width(p=P, q=Q, r=R)
    check_planes(np.concatenate([P, Q, R]), "planes")
    out = np.empty((_broadcast_length(p=P, q=Q, r=R), 4), P.dtype)
    _intersect_kernel(P, Q, R, out)
    bad = int(_first_zero_w(out))
    if bad >= 0:
        raise GeometryError(
            f"planes p[{bad}], q[{bad}], r[{bad}] have linearly dependent normals: "
            "they do not meet in a single point"
        )
    return _squeeze(out, p, q, r)


def classify_vertex(points, planes) -> np.ndarray:
    """Return on which side of each plane each homogeneous point lies: sign(x·s)·sign(x4) (eq. 6).

    ``points`` : (n, 4) wide homogeneous points (x4 != 0); ``planes`` : (n, 4) wide,
    same width. Returns (n,) int8: +1 positive side, -1 negative side, 0 on the plane.
    """
    X = _rows(points, 4, "points", wide=True)
    S = _rows(planes, 4, "planes", wide=True)
    _same_width(points=X, planes=S)
    bad = int(_first_zero_w(X))
    if bad >= 0:
        raise GeometryError(f"points[{bad}] has x4 = 0: a point at infinity lies on no side of a plane")
    check_planes(S)
    check_points_against_planes(X, S)
    out = np.empty(_broadcast_length(points=X, planes=S), np.int8)
    _classify_kernel(X, S, out)
    return _squeeze(out, points, planes)


def to_double_position(points) -> np.ndarray:
    """Return the Cartesian positions (x1, x2, x3) / x4, each correctly rounded to the nearest double.

    ``points`` : (n, 4) wide homogeneous points. Returns (n, 3) float64 ((3,) for a
    single 1-D point). Raises :class:`GeometryError` for a point at infinity (x4 = 0).
    """
    X = _rows(points, 4, "points", wide=True)
    bad = int(_first_zero_w(X))
    if bad >= 0:
        raise GeometryError(f"points[{bad}] has x4 = 0: a point at infinity has no position")
    out = np.empty((X.shape[0], 3), np.float64)
    _to_double_kernel(X, out)
    return _squeeze(out, points)


def points_equal(x, y) -> np.ndarray:
    """Return whether homogeneous points x and y are the same point (x_i·y4 = y_i·x4).

    Exact for any two points of one width (products are formed at twice the width).
    Returns (n,) bool.
    """
    X, Y = _rows(x, 4, "x", wide=True), _rows(y, 4, "y", wide=True)
    _same_width(x=X, y=Y)
    for arr, name in ((X, "x"), (Y, "y")):
        bad = int(_first_zero_w(arr))
        if bad >= 0:
            raise GeometryError(f"{name}[{bad}] has x4 = 0: a point at infinity")
    out = np.empty(_broadcast_length(x=X, y=Y), np.bool_)
    _points_equal_kernel(X, Y, out)
    return _squeeze(out, x, y)
