"""Bit budgets: which inputs a b-bit computation handles exactly, and their enforcement.

Derivation (paper §3.2, eq. 7-9). Let N bound every normal coefficient |a|, |b|,
|c| and D every offset |d| of a set of planes. All quantities the predicates
compute are integer polynomials in plane coefficients whose *final* values are
bounded by Hadamard's inequality (|det M| <= product of column norms):

* ``x4 = -det(n_p, n_q, n_r)``  (3x3, columns <= sqrt(3) N):     |x4|      <= 3^(3/2) N^3
* ``x1, x2, x3`` (3x3 with one column of offsets):                |x_i|     <= 3^(3/2) N^2 D
* classification ``x·s = det[s; p; q; r]`` (4x4, columns <= 2N, 2D): |x·s|  <= 16 N^3 D

Two's-complement arithmetic is exact modulo 2^b, so a b-bit computation is exact
exactly when each final value lies in [-2^(b-1), 2^(b-1)); intermediate
wrap-around cancels. The governing condition is the last one (eq. 7 with
``D = 3 v+ n+``: ``48 n+^4 v+ <= 2^(b-1)``); the 3x3 bounds only matter when all
offsets are zero.

Planes made from integer mesh vertices bounded by V (``n = (q-p) x (r-p)``) have
``N <= 8 V^2`` and ``D <= 24 V^3``, so ``16 N^3 D <= 48 * 8^4 * V^9`` (eq. 8), i.e.
``V <= 0.239 * 2^(b/9)`` (eq. 9). The largest V with ``48 * 8^4 * V^9 < 2^(b-1)``:

>>> [budget(w).max_mesh_coordinate for w in (128, 192, 256)]
[4567, 631462, 87298202]
>>> V = budget(128).max_mesh_coordinate
>>> 48 * 8**4 * V**9 < 2**127 <= 48 * 8**4 * (V + 1)**9
True
>>> budget(256).max_mesh_normal, budget(256).max_mesh_offset  # 8 V^2, 24 V^3
(60967808579462432, 15967140206601733320441792)

Every public predicate checks its inputs against these bounds, and raises
:class:`csgnb.PrecisionError` naming the bound and the value; nothing it returns was
computed out of budget. The check is cheap: one vector scan per array (fused, block
by block, into the predicate's own loop) yields per-limb maxima of one's-complement
magnitudes, whose upper bounds settle almost every input; only when they do not are
the exact maxima computed (a jitted arg-max by exact wide comparison, then Python
ints). Inputs exactly at a bound are accepted; one more is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from csgnb._jit import jit
from csgnb.errors import CsgnbError, GeometryError, PrecisionError
from csgnb.exact.integral import exact_int, max_abs
from csgnb.exact.intrinsics import scan_rows, wide_abs_greater_at, wide_sign_at
from csgnb.exact.planes import is_narrow_planes, plane_width_of
from csgnb.exact.wide import WIDTHS, check_width, from_wide, wide_dtype

__all__ = [
    "BitBudget",
    "budget",
    "integer_root",
    "check_mesh_points",
    "check_planes",
    "check_points_against_planes",
    "check_integer_points_against_planes",
    "check_plane_set",
    "check_cross_product",
    "check_zero_normals",
    "first_zero_normal",
    "first_zero_w",
    "new_scan",
    "scan",
    "scan_bounds",
]


def integer_root(value: int, k: int) -> int:
    """Return floor(value ** (1/k)) for a non-negative Python int (exact, no floats)."""
    value, k = exact_int(value, "value"), exact_int(k, "k")
    if value < 0 or k < 1:
        raise CsgnbError(f"integer_root needs value >= 0 and k >= 1, got value = {value}, k = {k}")
    if value < 2:
        return value
    x = 1 << -(-value.bit_length() // k)  # an upper bound
    while True:
        y = ((k - 1) * x + value // x ** (k - 1)) // k
        if y >= x:
            break
        x = y
    while x**k > value:
        x -= 1
    while (x + 1) ** k <= value:
        x += 1
    return x


@dataclass(frozen=True)
class BitBudget:
    """The exact input bounds of ``width``-bit predicates (paper eq. 7-9).

    All values are Python ints. ``limit = 2**(width-1)``: every final value must
    lie in ``[-limit, limit)``.
    """

    width: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", check_width(self.width))

    @property
    def limit(self) -> int:
        """2**(width-1): the magnitude no final value may reach."""
        return 1 << (self.width - 1)

    @cached_property
    def max_mesh_coordinate(self) -> int:
        """Largest |coordinate| V of integer mesh vertices: 48 * 8**4 * V**9 < 2**(b-1) (eq. 8)."""
        return integer_root((self.limit - 1) // (48 * 8**4), 9)

    @property
    def max_mesh_normal(self) -> int:
        """Largest normal coefficient of a plane through in-budget mesh vertices: 8 V**2."""
        return 8 * self.max_mesh_coordinate**2

    @property
    def max_mesh_offset(self) -> int:
        """Largest offset |d| of a plane through in-budget mesh vertices: 24 V**3."""
        return 24 * self.max_mesh_coordinate**3

    def max_vertex_coordinate(self, max_normal: int) -> int:
        """Largest vertex coordinate v+ usable with normals bounded by ``max_normal`` (eq. 7)."""
        max_normal = exact_int(max_normal, "max_normal")
        if max_normal < 1:
            raise PrecisionError(f"max_normal must be >= 1, got {max_normal}")
        return (self.limit - 1) // (48 * max_normal**4)

    def max_normal_coefficient(self, max_vertex: int) -> int:
        """Largest normal bound n+ usable with vertex coordinates bounded by ``max_vertex`` (eq. 7)."""
        max_vertex = exact_int(max_vertex, "max_vertex")
        if max_vertex < 1:
            raise PrecisionError(f"max_vertex must be >= 1, got {max_vertex}")
        return integer_root((self.limit - 1) // (48 * max_vertex), 4)

    def plane_violations(self, N: int, D: int) -> list[str]:
        """Return the bounds that planes with max normal ``N`` and max offset ``D`` break (empty if none)."""
        N, D = exact_int(N, "N"), exact_int(D, "D")
        if N < 0 or D < 0:
            raise PrecisionError(f"N and D are bounds on magnitudes (>= 0), got N = {N}, D = {D}")
        problems = []
        if 16 * N**3 * D >= self.limit:
            problems.append(
                f"the classification dot product x·s = det[s;p;q;r] is bounded by 16·N³·D = "
                f"{16 * N**3 * D}, which must be < 2**{self.width - 1}"
            )
        if 27 * N**6 >= self.limit**2:
            problems.append(
                f"the 3x3 determinant x4 is bounded by 3^(3/2)·N³ ≈ {int(5.196152422706632 * N**3)}, "
                f"which must be < 2**{self.width - 1}"
            )
        if 27 * N**4 * D**2 >= self.limit**2:
            problems.append(
                f"the 3x3 determinants x1..x3 are bounded by 3^(3/2)·N²·D ≈ "
                f"{int(5.196152422706632 * N**2 * D)}, which must be < 2**{self.width - 1}"
            )
        return problems


def budget(width: int) -> BitBudget:
    """Return the :class:`BitBudget` of ``width`` bits (128, 192 or 256)."""
    b = _BUDGETS.get(width) if type(width) is int else None
    return b if b is not None else _BUDGETS[check_width(width)]


_BUDGETS = {w: BitBudget(w) for w in WIDTHS}


# ---------------------------------------------------------------------------
# fast bounds: one vector scan per array (or a block of it, fused into a kernel)

_ALL_ONES = np.uint64(0xFFFFFFFFFFFFFFFF)


def new_scan(width: int) -> np.ndarray:
    """An empty scan accumulator for :func:`csgnb.exact.intrinsics.scan_rows`: ``(4k + 2,) uint64``."""
    k = width // 64
    acc = np.zeros(4 * k + 2, np.uint64)
    acc[4 * k:] = _ALL_ONES
    return acc


@jit
def _scan_all(arr, acc):
    scan_rows(arr, 0, arr.shape[0], acc)


def scan(arr: np.ndarray, width: int) -> np.ndarray:
    """The scan accumulator of every row of ``arr`` (``(n, 4)`` wide, or narrow planes)."""
    acc = new_scan(width)
    if arr.shape[0]:
        _scan_all(arr, acc)
    return acc


def scan_bounds(acc: np.ndarray, width: int) -> list[int]:
    """Upper bounds of |value| per column (Python ints) from a scan accumulator.

    With ``M_j`` the largest limb j of the one's-complement magnitudes and t the highest
    non-zero limb, every magnitude is below ``M_t 2^(64t) + (M_(t-1) + 1) 2^(64(t-1))``; the
    sign bit adds one. Tight to about ``2^-64`` relative unless the leading limb is tiny.
    """
    k = width // 64
    limbs = acc.tolist()
    bounds = []
    for c in range(4):
        col = limbs[c * k:(c + 1) * k]
        t = k - 1
        while t > 0 and not col[t]:
            t -= 1
        bound = col[0] if t == 0 else (col[t] << (64 * t)) + ((col[t - 1] + 1) << (64 * (t - 1)))
        bounds.append(bound + 1)
    return bounds


def scan_has_zero_normal(acc: np.ndarray) -> bool:
    """Whether a scanned plane array has a row with a = b = c = 0."""
    return int(acc[-2]) == 0


def scan_has_zero_w(acc: np.ndarray) -> bool:
    """Whether a scanned point array has a row with x4 = 0."""
    return int(acc[-1]) == 0


# ---------------------------------------------------------------------------
# exact maxima (the slow path, taken only when a fast bound does not settle a budget)


@jit
def _column_argmax_abs(arr, best):
    """Row of the largest |arr[row, col]| of every column, in one pass, into ``best`` ((ncols,) int64)."""
    best[:] = 0
    for r in range(1, arr.shape[0]):
        for c in range(arr.shape[1]):
            if wide_abs_greater_at(arr, r, c, arr, best[c], c):
                best[c] = r


@jit
def _first_zero_normal(planes):
    """Index of the first plane with a = b = c = 0 (wide rows), or -1."""
    for r in range(planes.shape[0]):
        if wide_sign_at(planes, r, 0) == 0 and wide_sign_at(planes, r, 1) == 0 and wide_sign_at(planes, r, 2) == 0:
            return r
    return -1


@jit
def _first_zero_w(points):
    """Index of the first point with x4 = 0, or -1."""
    for t in range(points.shape[0]):
        if wide_sign_at(points, t, 3) == 0:
            return t
    return -1


def first_zero_normal(planes: np.ndarray) -> int:
    """Index of the first plane (either layout) with a zero normal, or -1."""
    if is_narrow_planes(planes):
        zero = np.flatnonzero(~planes["normal"].any(axis=1))
        return int(zero[0]) if zero.size else -1
    return int(_first_zero_normal(planes)) if planes.shape[0] else -1


def first_zero_w(points: np.ndarray) -> int:
    """Index of the first homogeneous point with x4 = 0, or -1."""
    return int(_first_zero_w(points)) if points.shape[0] else -1


def _column_max_abs(arr: np.ndarray) -> list[tuple[int, int]]:
    """Exact (max |value|, row) of every column of a 2-D wide array, as Python ints."""
    if arr.shape[0] == 0:
        return [(0, -1)] * arr.shape[1]
    rows = np.empty(arr.shape[1], np.int64)
    _column_argmax_abs(arr, rows)
    return [(abs(int(from_wide(arr[r : r + 1, c])[0])), int(r)) for c, r in enumerate(rows)]


def _plane_maxima(planes: np.ndarray) -> tuple[int, int, int, int]:
    """(N, row of N, D, row of D) of planes in either layout, exactly."""
    if planes.shape[0] == 0:
        return 0, -1, 0, -1
    if is_narrow_planes(planes):
        normal = planes["normal"].astype(np.int64)
        nmax, nmin = int(normal.max()), int(normal.min())
        N, rn = (nmax, int(np.argmax(normal.max(axis=1)))) if nmax >= -nmin else (-nmin, int(np.argmin(
            normal.min(axis=1))))
        offset = planes["offset"]
        if offset.ndim == 1:
            omax, omin = int(offset.max()), int(offset.min())
            D, rd = (omax, int(np.argmax(offset))) if omax >= -omin else (-omin, int(np.argmin(offset)))
            return N, rn, D, rd
        wide = np.ascontiguousarray(offset).view(wide_dtype(128)).reshape(-1, 1)
        ((D, rd),) = _column_max_abs(wide)
        return N, rn, D, rd
    cols = _column_max_abs(planes)
    N, rn = max(cols[:3])
    D, rd = cols[3]
    return N, rn, D, rd


def _exact_plane_maxima(named: list[tuple[np.ndarray, str]]) -> tuple[int, str, int, str]:
    """(N, where, D, where) over several plane arrays, exactly."""
    N, wn, D, wd = -1, "", -1, ""
    for arr, name in named:
        n, rn, d, rd = _plane_maxima(arr)
        if n > N:
            N, wn = n, f"{name}[{rn}]"
        if d > D:
            D, wd = d, f"{name}[{rd}]"
    return max(N, 0), wn, max(D, 0), wd


# ---------------------------------------------------------------------------
# the checks


def check_zero_normals(named: list[tuple[np.ndarray, str]], scans: list[np.ndarray]) -> None:
    """Raise :class:`GeometryError` naming the first plane with a = b = c = 0 among scanned arrays."""
    _raise_zero_normal(named, scans)


def _raise_zero_normal(named: list[tuple[np.ndarray, str]], scans: list[np.ndarray]) -> None:
    for (arr, name), acc in zip(named, scans, strict=True):
        if scan_has_zero_normal(acc):
            raise GeometryError(f"{name}[{first_zero_normal(arr)}] has a zero normal (a = b = c = 0): "
                                "it is not a plane")


def check_plane_set(named: list[tuple[np.ndarray, str]], width: int, scans: list[np.ndarray] | None = None
                    ) -> tuple[int, int]:
    """Check planes (either layout) that are used together against the budget of ``width``.

    ``named`` pairs each array with its name for messages; ``scans`` are their scan
    accumulators if a kernel already computed them (else they are computed here).
    Returns upper bounds (N, D) within the budget (the exact maxima when the fast bounds
    did not settle it). Raises :class:`GeometryError` for a zero normal and
    :class:`PrecisionError` naming the bound, the values and the planes that reach them.
    """
    b = budget(width)
    if scans is None:
        scans = [scan(arr, width) for arr, _ in named]
    _raise_zero_normal(named, scans)
    N = D = 0
    for acc in scans:
        a, b_, c, d = scan_bounds(acc, width)
        N, D = max(N, a, b_, c), max(D, d)
    if not b.plane_violations(N, D):
        return N, D
    N, wn, D, wd = _exact_plane_maxima(named)
    problems = b.plane_violations(N, D)
    if problems:
        label = named[0][1] if len(named) == 1 else "planes"
        raise PrecisionError(
            f"{label} exceed the {b.width}-bit budget with N = max|a|,|b|,|c| = {N} ({wn}) "
            f"and D = max|d| = {D} ({wd}): " + "; ".join(problems)
            + ". Use a wider width or smaller coefficients (csgnb.exact.quantize)."
        )
    return N, D


#: The width at which are_planes_parallel forms n_p x n_q for full rows of each width.
CROSS_PRODUCT_BITS = {128: 128, 192: 128, 256: 192}


def check_cross_product(named: list[tuple[np.ndarray, str]], width: int, scans: list[np.ndarray]) -> None:
    """Check planes for :func:`csgnb.exact.are_planes_parallel`: no zero normal, and 2 N^2 < 2**(M-1).

    M is :data:`CROSS_PRODUCT_BITS`; planes within the width's budget always pass.
    """
    _raise_zero_normal(named, scans)
    M = CROSS_PRODUCT_BITS[width]
    N = max(max(scan_bounds(acc, width)[:3]) for acc in scans)
    if 2 * N * N < 1 << (M - 1):
        return
    N, wn, _, _ = _exact_plane_maxima(named)
    if 2 * N * N >= 1 << (M - 1):
        raise PrecisionError(
            f"the normals are too large for the {width}-bit parallel test: n_p x n_q is formed at {M} bits and "
            f"needs 2·N² < 2**{M - 1}, but N = max|a|,|b|,|c| = {N} ({wn}). Planes within the {width}-bit budget "
            "always pass; use a wider width or smaller coefficients."
        )


def check_planes(planes: np.ndarray, name: str = "planes") -> tuple[int, int]:
    """Check ``(n, 4)`` wide planes (or narrow plane records) against their width's budget.

    Returns bounds (N, D) within the budget. Raises :class:`PrecisionError` if the planes
    together break a bound of :meth:`BitBudget.plane_violations` and :class:`GeometryError`
    for a zero normal.
    """
    return check_plane_set([(planes, name)], plane_width_of(planes))


def check_mesh_points(points: np.ndarray, width: int, name: str = "points", V: int | None = None) -> int:
    """Check ``(n, 3) int64`` vertices against the mesh budget of eq. 8; return max |coordinate|.

    ``V``, the exact max |coordinate|, may be given if the caller computed it.
    """
    b = budget(width)
    if points.size == 0:
        return 0
    V = max_abs(points) if V is None else V
    if V > b.max_mesh_coordinate:
        V = max_abs(points)
        row = int(np.argmax(np.any((points == V) | (points == -V), axis=1)))
        raise PrecisionError(
            f"{name}[{row}] has a coordinate of magnitude {V}, above the {b.width}-bit mesh budget "
            f"V <= {b.max_mesh_coordinate} (48·8⁴·V⁹ < 2**{b.width - 1}, eq. 8). "
            f"Quantize to a coarser grid (csgnb.exact.quantize) or use a wider width."
        )
    return V


def check_points_against_planes(points: np.ndarray, planes: np.ndarray, point_scan: np.ndarray | None = None,
                                plane_scan: np.ndarray | None = None, plane_bounds: tuple[int, int] | None = None
                                ) -> None:
    """Check that every ``x·s`` of wide homogeneous ``points`` against ``planes`` fits the width.

    Conservative for arbitrary points: (|x1|+|x2|+|x3|)·N + |x4|·D < 2**(b-1) with
    column-wise maxima (fast bounds first, exact maxima if those do not settle it).
    ``plane_bounds``: (N, D) bounds already derived from ``plane_scan`` (:func:`check_plane_set`).
    """
    width = plane_width_of(planes)
    b = budget(width)
    point_scan = scan(points, width) if point_scan is None else point_scan
    plane_scan = scan(planes, width) if plane_scan is None else plane_scan
    X = scan_bounds(point_scan, width)
    if plane_bounds is None:
        P = scan_bounds(plane_scan, width)
        plane_bounds = (max(P[:3]), P[3])
    if (X[0] + X[1] + X[2]) * plane_bounds[0] + X[3] * plane_bounds[1] < b.limit:
        return
    N, _, D, _ = _plane_maxima(planes)
    X = [m for m, _ in _column_max_abs(points)]
    bound = (X[0] + X[1] + X[2]) * N + X[3] * D
    if bound >= b.limit:
        raise PrecisionError(
            f"classifying these points against these planes can exceed {b.width} bits: "
            f"(|x1|+|x2|+|x3|)·N + |x4|·D = {bound} must be < 2**{b.width - 1} "
            f"(max |x_i| = {X}, N = {N}, D = {D}). Use a wider width."
        )


def check_integer_points_against_planes(points: np.ndarray, planes: np.ndarray, V: int | None = None,
                                        plane_scan: np.ndarray | None = None) -> None:
    """Check that ``n·v + d`` of ``(n, 3) int64`` points and planes fits: 3·V·N + D < 2**(b-1)."""
    width = plane_width_of(planes)
    b = budget(width)
    V = max_abs(points) if V is None else V
    plane_scan = scan(planes, width) if plane_scan is None else plane_scan
    P = scan_bounds(plane_scan, width)
    if 3 * V * max(P[:3]) + P[3] < b.limit:
        return
    N, _, D, _ = _plane_maxima(planes)
    bound = 3 * V * N + D
    if bound >= b.limit:
        raise PrecisionError(
            f"signed distances of these points to these planes can exceed {b.width} bits: "
            f"3·V·N + D = {bound} must be < 2**{b.width - 1} (V = {V}, N = {N}, D = {D}). "
            f"Use a wider width."
        )
