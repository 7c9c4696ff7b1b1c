"""The exact plane predicates of the paper's Table 1, vectorized over numpy arrays.

Every function takes wide arrays (see :mod:`csgnb.exact.wide`) or ``int64`` integer
points; planes may be ``(n, 4)`` wide rows or narrow plane records
(:mod:`csgnb.exact.planes`). Operands broadcast along the first axis: an operand with
one row (or a single 1-D plane/point) is used for every row of the others.

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

How the checks stay cheap: each function is one jitted call that walks its rows in
blocks of :data:`BLOCK`; for every block it first folds the block's inputs into a
scan accumulator (a few SIMD instructions per row, :func:`csgnb.exact.intrinsics.scan_rows`)
and then computes the block's results while the rows are still in cache. Only then are
the accumulated bounds compared with the bit budget (exactly, in Python ints, once per
call): an input outside the budget raises, and the speculatively computed -- possibly
wrapped -- results are never returned.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit
from csgnb.errors import GeometryError, PrecisionError
from csgnb.exact.blocks import classify_rows, distance_rows, intersect_rows, parallel_rows, points_equal_rows
from csgnb.exact.budgets import (
    check_cross_product,
    check_integer_points_against_planes,
    check_mesh_points,
    check_plane_set,
    check_points_against_planes,
    check_zero_normals,
    first_zero_w,
    new_scan,
    scan_has_zero_w,
)
from csgnb.exact.integral import integer_array
from csgnb.exact.intrinsics import (
    compare_ratio_dyadic_at,
    plane_from_normal_into,
    planes_parallel_at,
    positions_into,
    scan_rows,
    trailing_zeros,
    wide_sign_at,
    wide_to_float_at,
)
from csgnb.exact.planes import as_planes, is_narrow_planes, plane_dtype, plane_width_of
from csgnb.exact.wide import check_width, to_wide, wide_dtype, width_of

__all__ = [
    "BLOCK",
    "homogeneous_points",
    "plane_from_points",
    "are_planes_parallel",
    "signed_distance",
    "intersect_3_planes",
    "classify_vertex",
    "to_double_position",
    "points_equal",
]

#: Rows per block of the fused check-and-compute loops: the block's inputs stay in L1/L2
#: between the scan and the computation (256 rows of 256-bit planes and points: 64 KiB).
BLOCK = 256

# ---------------------------------------------------------------------------
# kernels: one loop each; ``k if many else 0`` broadcasts single-row operands.


@jit
def _scan_operand(arr, many, start, stop, acc):
    """Scan rows [start, stop) of a broadcast operand (its single row once, at the first block).

    """
    if many:
        scan_rows(arr, start, stop, acc)
    elif start == 0:
        scan_rows(arr, 0, 1, acc)


@jit
def _classify_kernel(points, planes, out, acc_x, acc_s):
    classify_rows(points, points.shape[0] != 1, planes, planes.shape[0] != 1, 0, out.shape[0], out, acc_x, acc_s)


@jit
def _intersect_kernel(P, Q, R, out, acc_p, acc_q, acc_r, acc_out):
    intersect_rows(P, P.shape[0] != 1, Q, Q.shape[0] != 1, R, R.shape[0] != 1, 0, out.shape[0], out,
                   acc_p, acc_q, acc_r, acc_out)


@jit
def _gcd(u, v):
    """gcd of non-negative int64 ``u``, ``v``: binary, branch-free steps.

    Each step is v <- |v - u| >> tz(v - u), u <- min(u, v): the trailing zeros are counted on
    the difference itself, in parallel with its absolute value, and the loop stops as soon as
    u reaches 1 (measured: 141 instead of 233 cycles for three 28-bit normals).
    """
    if u == 0:
        return v
    if v == 0:
        return u
    shift = trailing_zeros(u | v)
    u >>= trailing_zeros(u)
    v >>= trailing_zeros(v)
    while u != v:
        d = v - u
        t = trailing_zeros(d)
        u = min(u, v)
        v = abs(d) >> t
        if u == 1:
            break
    return u << shift


@jit
def gcd3(a, b, c):
    """gcd(|a|, |b|, |c|); the third operand is first reduced modulo the (usually small) gcd of the others."""
    g = _gcd(abs(a), abs(b))
    if g > 1:
        r = abs(c) % g
        if r:
            g = _gcd(g, r)
    elif g == 0:
        g = abs(c)
    return g


@jit
def _extremes(arr, start, stop, ext):
    """Fold min/max of rows [start, stop) of an (n, 3) int64 array into ext = [max, min]."""
    hi, lo = ext[0], ext[1]
    for t in range(start, stop):
        for c in range(3):
            v = arr[t, c]
            hi = max(hi, v)
            lo = min(lo, v)
    ext[0], ext[1] = hi, lo


@jit
def _plane_from_points_kernel(P, Q, R, out, canonical, ext, state):
    """Planes through P, Q, R (int64, within the mesh budget: normals exact in int64); state[0] = first collinear."""
    mp, mq, mr = P.shape[0] != 1, Q.shape[0] != 1, R.shape[0] != 1
    n = out.shape[0]
    state[0] = -1
    for b in range(0, n, BLOCK):
        e = min(b + BLOCK, n)
        for arr, many in ((P, mp), (Q, mq), (R, mr)):
            if many:
                _extremes(arr, b, e, ext)
            elif b == 0:
                _extremes(arr, 0, 1, ext)
        for t in range(b, e):
            i, j, k = t if mp else 0, t if mq else 0, t if mr else 0
            x1, y1, z1 = Q[j, 0] - P[i, 0], Q[j, 1] - P[i, 1], Q[j, 2] - P[i, 2]
            x2, y2, z2 = R[k, 0] - P[i, 0], R[k, 1] - P[i, 1], R[k, 2] - P[i, 2]
            a = y1 * z2 - z1 * y2
            bb = z1 * x2 - x1 * z2
            c = x1 * y2 - y1 * x2
            if canonical:
                g = gcd3(a, bb, c)
                if g > 1:
                    # d = -n·p is formed after the division, so it is reduced as well.
                    a //= g
                    bb //= g
                    c //= g
            if a == 0 and bb == 0 and c == 0 and state[0] < 0:
                state[0] = t
            plane_from_normal_into(a, bb, c, P, i, out, t)


@jit
def _signed_distance_kernel(points, planes, out, ext, acc_s):
    distance_rows(points, points.shape[0] != 1, planes, planes.shape[0] != 1, 0, out.shape[0], out, ext, acc_s)


@jit
def _parallel_kernel(P, Q, out, acc_p, acc_q):
    parallel_rows(P, P.shape[0] != 1, Q, Q.shape[0] != 1, 0, out.shape[0], out, acc_p, acc_q)


@jit
def _parallel_plain_kernel(P, Q, out):
    mp, mq = P.shape[0] != 1, Q.shape[0] != 1
    for t in range(out.shape[0]):
        out[t] = planes_parallel_at(P, t if mp else 0, Q, t if mq else 0)


@jit
def _points_equal_kernel(X, Y, out, acc_x, acc_y):
    points_equal_rows(X, X.shape[0] != 1, Y, Y.shape[0] != 1, 0, out.shape[0], out, acc_x, acc_y)


_TWO_POW_53 = 9007199254740992.0
_TWO_POW_52 = 4503599627370496


@jit
def ratio_to_double(points, i, c):
    """x_c / x_4 of ``points[i]`` rounded to the nearest double, ties to even (the exact path).

    A float estimate (within 2 ulp) is corrected by exact comparisons of the
    rational with the dyadic midpoints between adjacent doubles, at twice the width.
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
def _positions(points, start, stop, out, counts):
    """out[t] = (x1, x2, x3) / x4, correctly rounded, for t in [start, stop).

    A certified double-double quotient, else the exact path (one call per block: passing
    arrays to a per-row function would cost reference counting per row).

    With A = |x_c|, B = |x4| split into 106-bit double-doubles (ah + al, bh + bl; relative
    truncation < 2**-105) and r = 1/bh: q1 = ah·r; the residual A - q1·B is formed from
    the exact product q1·bh = ph + pl (FMA; ah - ph is exact by Sterbenz) and al - q1·bl
    (one FMA), with error < 2**-102 A; c = residual·r then gives |A/B - (q1 + c)| < 2**-100 A/B.
    s + tail = q1 + c exactly (Fast2Sum), and round(A/B) = s whenever tail stays more than
    2**-96 s inside the half-gaps to the neighbouring doubles (the midpoints); otherwise -- a
    tie or a near-tie, about 2**-42 of random quotients -- the exact comparison decides.
    """
    for t in range(start, stop):
        if wide_sign_at(points, t, 3) == 0:
            for c in range(3):
                out[t, c] = np.nan
            continue
        certified = positions_into(points, t, out, t)
        if certified != 7:
            for c in range(3):
                if not (certified >> c) & 1:
                    counts[0] += 1
                    out[t, c] = ratio_to_double(points, t, c)


@jit
def _to_double_kernel(points, out, acc, counts):
    n = points.shape[0]
    for b in range(0, n, BLOCK):
        e = min(b + BLOCK, n)
        scan_rows(points, b, e, acc)
        _positions(points, b, e, out, counts)


@jit
def _to_double_exact_kernel(points, out):
    """The exact path alone (the reference the fast path is measured against)."""
    for t in range(points.shape[0]):
        for c in range(3):
            out[t, c] = ratio_to_double(points, t, c)


# ---------------------------------------------------------------------------
# argument handling


def _points(arr, name: str) -> np.ndarray:
    """Homogeneous wide points as a C-contiguous ``(n, 4)`` array (a 1-D point becomes one row)."""
    width_of(arr)
    rows = arr[None, :] if arr.ndim == 1 else arr
    if rows.ndim != 2 or rows.shape[1] != 4:
        raise GeometryError(f"{name} must have shape (n, 4) or (4,), got {arr.shape}")
    return np.ascontiguousarray(rows)


def _integer_points(arr, name: str) -> np.ndarray:
    """Integer points as a C-contiguous ``(n, 3) int64`` array (integral floats accepted)."""
    rows = integer_array(arr, name)
    if rows.ndim == 1:
        rows = rows[None, :]
    if rows.ndim != 2 or rows.shape[1] != 3:
        raise GeometryError(f"{name} must have shape (n, 3) or (3,), got {np.shape(arr)}")
    return np.ascontiguousarray(rows)


def _broadcast_length(**arrays: np.ndarray) -> int:
    lengths = {a.shape[0] for a in arrays.values()} - {1}
    if len(lengths) > 1:
        shapes = ", ".join(f"{k}: {v.shape}" for k, v in arrays.items())
        raise GeometryError(f"operands have different numbers of rows and cannot broadcast ({shapes})")
    return lengths.pop() if lengths else 1


def _same_width(**arrays: np.ndarray) -> int:
    widths = {k: plane_width_of(a) for k, a in arrays.items()}
    if len(set(widths.values())) != 1:
        raise PrecisionError(f"operands have different widths {widths}; convert them to one width "
                             "(csgnb.exact.to_width)")
    return next(iter(widths.values()))


def _single(x) -> bool:
    """Whether a user argument was one point or plane (no row axis)."""
    names = getattr(getattr(x, "dtype", None), "names", None)
    if names is not None and "normal" in names:
        return np.ndim(x) == 0
    return np.ndim(x) == 1


def _squeeze(result: np.ndarray, *inputs) -> np.ndarray:
    """Drop the row axis again when every input was a single point or plane."""
    if all(_single(x) for x in inputs):
        return result[0]
    return result


def _raise_zero_w(acc, arr, name) -> None:
    if scan_has_zero_w(acc):
        raise GeometryError(f"{name}[{first_zero_w(arr)}] has x4 = 0: a point at infinity")


# ---------------------------------------------------------------------------
# public API


def homogeneous_points(points, width: int = 256) -> np.ndarray:
    """Return integer points ``(n, 3) int64`` as homogeneous wide points ``(n, 4)`` with x4 = 1."""
    width = check_width(width)
    P = _integer_points(points, "points")
    out = np.concatenate([P, np.ones((P.shape[0], 1), np.int64)], axis=1)
    return _squeeze(to_wide(out, width), points)


def plane_from_points(p, q, r, *, width: int = 256, canonical: bool = True, narrow: bool = False) -> np.ndarray:
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
    narrow : bool
        Return narrow plane records (:func:`csgnb.exact.plane_dtype`) instead of wide rows;
        the mesh budget guarantees they fit.

    Returns
    -------
    (n, 4) wide array of ``width`` bits ((4,) for 1-D inputs), or (n,) narrow planes.

    Raises
    ------
    PrecisionError
        A coordinate exceeds the mesh budget.
    GeometryError
        Three points of a row are collinear (the normal is zero).
    """
    width = check_width(width)
    P, Q, R = (_integer_points(x, name) for x, name in ((p, "p"), (q, "q"), (r, "r")))
    n = _broadcast_length(p=P, q=Q, r=R)
    out = np.empty(n, plane_dtype(width)) if narrow else np.empty((n, 4), wide_dtype(width))
    ext = np.array([np.iinfo(np.int64).min, np.iinfo(np.int64).max], np.int64)
    state = np.empty(1, np.int64)
    _plane_from_points_kernel(P, Q, R, out, bool(canonical), ext, state)
    V = max(int(ext[0]), -int(ext[1])) if n else 0
    try:
        check_mesh_points(P[:1], width, "p", V=V)
    except PrecisionError:
        for arr, name in ((P, "p"), (Q, "q"), (R, "r")):
            check_mesh_points(arr, width, name)
        raise
    zero = int(state[0])
    if zero >= 0:
        raise GeometryError(f"points p[{zero}], q[{zero}], r[{zero}] are collinear: they span no plane")
    if narrow:
        return out[0] if all(np.ndim(x) == 1 for x in (p, q, r)) else out
    return _squeeze(out, p, q, r)


def are_planes_parallel(p, q) -> np.ndarray:
    """Return whether the normals of planes p and q are parallel (n_p x n_q = 0, eq. 1).

    Opposite orientations count as parallel. ``p, q`` : (n, 4) wide planes or narrow planes.
    Returns (n,) bool. Only the normals matter: narrow planes are always exact (their normals
    are at most a quarter of the width), full rows need ``2 N^2 < 2**(M-1)`` for the width M
    the cross product is formed at (128, 128, 192 bits for 128-, 192-, 256-bit planes), which
    every plane within the width's budget meets.
    """
    P, Q = as_planes(p, "p"), as_planes(q, "q")
    width = _same_width(p=P, q=Q)
    out = np.empty(_broadcast_length(p=P, q=Q), np.bool_)
    if is_narrow_planes(P) and is_narrow_planes(Q):
        _parallel_plain_kernel(P, Q, out)
        # A zero normal is parallel to everything: only rows reported parallel can hide one.
        hits = np.flatnonzero(out)
        for arr, name in ((P, "p"), (Q, "q")) if hits.size else ():
            rows = hits if arr.shape[0] != 1 else np.zeros(1, np.intp)
            zero = np.flatnonzero(~arr["normal"][rows].any(axis=1))
            if zero.size:
                raise GeometryError(f"{name}[{int(rows[zero[0]])}] has a zero normal (a = b = c = 0): "
                                    "it is not a plane")
        return _squeeze(out, p, q)
    scans = [new_scan(width), new_scan(width)]
    _parallel_kernel(P, Q, out, *scans)
    check_cross_product([(P, "p"), (Q, "q")], width, scans)
    return _squeeze(out, p, q)


def signed_distance(points, planes) -> np.ndarray:
    """Return ``n·v + d`` for integer points v and planes (n, d): the distance times |n|.

    ``points`` : (n, 3) int64; ``planes`` : (n, 4) wide or narrow. Returns an (n,) wide array
    of the planes' width (convert with :func:`csgnb.exact.from_wide`). Only the value itself
    must fit: ``3·V·N + D < 2**(b-1)`` for full rows (V = max |coordinate|); narrow planes
    always fit.
    """
    V = _integer_points(points, "points")
    S = as_planes(planes)
    width = plane_width_of(S)
    out = np.empty(_broadcast_length(points=V, planes=S), wide_dtype(width))
    acc = new_scan(width)
    if is_narrow_planes(S):
        # Narrow fields bound every product: 3 * 2**63 * N + D < 2**(b-1) for any int64 point
        # (N < 2**31, D < 2**63 at 128 bits; N < 2**63, D < 2**127 above), so only zero normals
        # are looked for.
        _signed_distance_kernel(V, S, out, None, acc)
        check_zero_normals([(S, "planes")], [acc])
        return _squeeze(out, points, planes)
    ext = np.array([np.iinfo(np.int64).min, np.iinfo(np.int64).max], np.int64)
    _signed_distance_kernel(V, S, out, ext, acc)
    check_zero_normals([(S, "planes")], [acc])
    check_integer_points_against_planes(V, S, V=max(int(ext[0]), -int(ext[1])), plane_scan=acc)
    return _squeeze(out, points, planes)


def intersect_3_planes(p, q, r) -> np.ndarray:
    """Return the homogeneous intersection points (x1, x2, x3, x4) of planes p, q, r (eq. 5).

    The Cartesian point is (x1, x2, x3) / x4; ``x·s = det[s; p; q; r]`` for any plane
    s. ``p, q, r`` : (n, 4) wide planes (or narrow planes) of one width, together within
    its budget. Returns an (n, 4) wide array.

    Raises
    ------
    GeometryError
        The normals of a row are linearly dependent (no unique point; x4 = 0).
    """
    P, Q, R = (as_planes(x, name) for x, name in ((p, "p"), (q, "q"), (r, "r")))
    width = _same_width(p=P, q=Q, r=R)
    out = np.empty((_broadcast_length(p=P, q=Q, r=R), 4), wide_dtype(width))
    scans = [new_scan(width) for _ in range(4)]
    _intersect_kernel(P, Q, R, out, *scans)
    check_plane_set([(P, "p"), (Q, "q"), (R, "r")], width, scans[:3])
    if scan_has_zero_w(scans[3]):
        bad = first_zero_w(out)
        raise GeometryError(
            f"planes p[{bad}], q[{bad}], r[{bad}] have linearly dependent normals: "
            "they do not meet in a single point"
        )
    return _squeeze(out, p, q, r)


def classify_vertex(points, planes) -> np.ndarray:
    """Return on which side of each plane each homogeneous point lies: sign(x·s)·sign(x4) (eq. 6).

    ``points`` : (n, 4) wide homogeneous points (x4 != 0); ``planes`` : (n, 4) wide or narrow,
    same width. Returns (n,) int8: +1 positive side, -1 negative side, 0 on the plane.
    """
    X = _points(points, "points")
    S = as_planes(planes)
    width = _same_width(points=X, planes=S)
    out = np.empty(_broadcast_length(points=X, planes=S), np.int8)
    acc_x, acc_s = new_scan(width), new_scan(width)
    _classify_kernel(X, S, out, acc_x, acc_s)
    if scan_has_zero_w(acc_x):
        raise GeometryError(f"points[{first_zero_w(X)}] has x4 = 0: a point at infinity lies on no side of a plane")
    bounds = check_plane_set([(S, "planes")], width, [acc_s])
    check_points_against_planes(X, S, acc_x, acc_s, bounds)
    return _squeeze(out, points, planes)


def to_double_position(points, *, stats: dict | None = None) -> np.ndarray:
    """Return the Cartesian positions (x1, x2, x3) / x4, each correctly rounded to the nearest double.

    ``points`` : (n, 4) wide homogeneous points. Returns (n, 3) float64 ((3,) for a
    single 1-D point), bit-identical to ``float(Fraction(x_i, x4))``. Raises
    :class:`GeometryError` for a point at infinity (x4 = 0). A certified double-double
    quotient settles almost every coordinate; ties and near-ties take an exact comparison
    (pass a dict as ``stats`` to receive ``{"exact": count}``).
    """
    X = _points(points, "points")
    width = width_of(X)
    out = np.empty((X.shape[0], 3), np.float64)
    acc = new_scan(width)
    counts = np.zeros(1, np.int64)
    _to_double_kernel(X, out, acc, counts)
    if scan_has_zero_w(acc):
        raise GeometryError(f"points[{first_zero_w(X)}] has x4 = 0: a point at infinity has no position")
    if stats is not None:
        stats["exact"] = int(counts[0])
    return _squeeze(out, points)


def points_equal(x, y) -> np.ndarray:
    """Return whether homogeneous points x and y are the same point (x_i·y4 = y_i·x4).

    Exact for any two points of one width (products are formed at twice the width).
    Returns (n,) bool.
    """
    X, Y = _points(x, "x"), _points(y, "y")
    width = _same_width(x=X, y=Y)
    out = np.empty(_broadcast_length(x=X, y=Y), np.bool_)
    acc_x, acc_y = new_scan(width), new_scan(width)
    _points_equal_kernel(X, Y, out, acc_x, acc_y)
    _raise_zero_w(acc_x, X, "x")
    _raise_zero_w(acc_y, Y, "y")
    return _squeeze(out, x, y)
