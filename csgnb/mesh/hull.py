"""Exact convex hulls of integer points: integer facet planes, polygon faces, exact volume, a linear BSP.

A :class:`ConvexHull` is the currency of sweeps and tools: a convex tool at two poses, a
triangle's prism between two poses, a dodecahedron of a carving. Its facets are exact
integer planes through input points (gcd-reduced, outward), coplanar triangles merged
into one polygon per plane, so nothing is rounded after quantization.

How a hull is found (:func:`convex_hull`):

* up to :data:`BRUTE_FORCE_POINTS` points: every plane through three of them that has
  all points on or behind it is a facet plane -- exact by construction;
* more points, of a local extent below :data:`_COMPILED_FACETS_SAFE` (2**29: every width's mesh budget): a
  compiled exact incremental hull proposes triangles (exact signs, no rounding);
* wider sets (Python-int points): scipy's float hull (qhull) proposes them.

Either way each triangle becomes an exact integer plane, oriented by an interior point, and is
*verified*: all points on or behind it, and the faces built from it (the exact 2-D hull of the
points on each plane) close up, every edge shared by exactly two faces in opposite directions.
A closed surface of supporting faces is the whole boundary, so a verified result is exact. When
verification fails (qhull's float output can be wrong for nearly flat input; the incremental
hull falls back to qhull) an exact gift wrapping on faces runs instead.

Exact arithmetic: all tests run in coordinates local to one input point, where every
value is a polynomial in coordinate *differences* bounded by the extent E of the point
set (a normal coefficient by 8E², a signed distance by 48E³). The compiled kernels keep
normals in int64 and take every sign as n·(p - anchor) in i128 (below 2**29 that is exact at
every width's budget); the NumPy paths use int64 while the bound is below 2**63, Python ints
(object arrays) beyond. Inputs are checked against the mesh budget of the hull's width
(eq. 8), so every facet plane fits that width's predicates.
"""

from __future__ import annotations

from fractions import Fraction
from functools import cached_property
from math import gcd

import numpy as np

from csgnb._jit import jit
from csgnb._shuffle import shuffle_order
from csgnb._unlinked import unlinked
from csgnb.errors import GeometryError, InternalError
from csgnb.exact.budgets import check_mesh_points
from csgnb.exact.integral import max_abs
from csgnb.exact.intrinsics import cross_sign, plane_side_sign
from csgnb.exact.predicates import gcd3
from csgnb.exact.wide import DEFAULT_WIDTH, to_wide

__all__ = ["BRUTE_FORCE_POINTS", "ConvexHull", "convex_hull", "small_hulls"]

BRUTE_FORCE_POINTS = 10
"""Point sets up to this size are hulled by exact enumeration of point triples (C(10, 3) = 120 planes)."""

_INT64_SAFE = 1 << 62  # a bound below this keeps sums of a few int64 products exact


def _object(a: np.ndarray) -> np.ndarray:
    return a.astype(object)


def _maybe_int64(a: np.ndarray) -> np.ndarray:
    """``a`` as int64 when every value fits, else as an object array of Python ints."""
    if a.dtype != object:
        return a.astype(np.int64)
    if a.size == 0:
        return np.zeros(a.shape, np.int64)
    return a.astype(np.int64) if max_abs(a) < (1 << 63) else a


_SPLIT = 31  # _exact_row_dots: N = high * 2**31 + low
_SPLIT_POINTS = 1 << 29  # ... exact in int64 for |P| below this (each partial sum of three < 3 * 2**60)


def _exact_row_dots(N: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Exact row-wise N·P of int64 ``N`` (k, 3) and ``P`` (k, 3), |P| < 2**29: int64 when every value fits in
    int64 (up to 2**63 - 1: a caller adding to it bounds it itself), else Python ints (object) -- a 256-bit hull's
    offsets reach 2**70, and forming them as Python ints (3k conversions and products) was most of a capsule hull's
    extra cost at 256 bits. N is split into high * 2**31 + low (|high| <= 2**32, 0 <= low < 2**31), so each half's
    dot is exact in int64 (three products below 2**61 and 2**60); only the k results are joined in Python ints,
    and only when they do not fit."""
    high = N >> _SPLIT
    low = N & ((1 << _SPLIT) - 1)
    s_high = np.einsum("ij,ij->i", high, P)
    s_low = np.einsum("ij,ij->i", low, P)
    if s_high.size == 0 or int(np.abs(s_high).max()) < (1 << 29):  # |total| < 2**60 + 3 * 2**60 <= 2**62
        return (s_high << _SPLIT) + s_low
    return _maybe_int64(s_high.astype(object) * (1 << _SPLIT) + s_low.astype(object))


def _arith(extent: int, scale: int = 12) -> type:
    """int64 when ``scale · extent³`` (the largest local signed distance) stays below 2**62, else object."""
    return np.int64 if scale * extent**3 < _INT64_SAFE else object


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Exact cross product of (..., 3) integer arrays (int64 or object)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _reduce_planes(N: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Divide each plane (N, d) by the gcd of its normal (d, a multiple of it for planes through grid points)."""
    if N.dtype == object:
        g = np.array([gcd(*(int(x) for x in row)) for row in N], dtype=object)
    else:
        g = np.gcd.reduce(np.abs(N), axis=1)
    g = np.where(g == 0, 1, g)
    return N // g[:, None], d // g


def _polygon_order(L: np.ndarray, normal) -> np.ndarray:
    """Indices of the strictly convex 2-D hull of coplanar local points ``L`` (m, 3), CCW seen along ``normal``.

    Projects along the normal's dominant axis (which keeps the orientation up to its sign)
    and runs Andrew's monotone chain with exact integer cross products; collinear points
    are dropped, so adjacent faces share exactly the edge's two end vertices.
    """
    n = [int(x) for x in normal]
    ax = max(range(3), key=lambda i: abs(n[i]))
    u, v = (ax + 1) % 3, (ax + 2) % 3
    pts = sorted({(int(p[u]), int(p[v])): i for i, p in enumerate(L)}.items())
    if len(pts) < 3:
        return np.array([i for _, i in pts], np.int64)

    def chain(seq):
        out = []
        for (x, y), i in seq:
            while len(out) >= 2:
                (x1, y1), _ = out[-2]
                (x2, y2), _ = out[-1]
                if (x2 - x1) * (y - y1) - (y2 - y1) * (x - x1) > 0:
                    break
                out.pop()
            out.append(((x, y), i))
        return out

    lower, upper = chain(pts), chain(pts[::-1])
    ring = [i for _, i in lower[:-1] + upper[:-1]]
    if n[ax] < 0:
        ring = ring[::-1]
    return np.array(ring, np.int64)


_RING_SAFE = 1 << 62
"""Local coordinates below this keep the face kernels' coordinate differences in int64 (their 2-D cross products
are taken in i128: :func:`csgnb.exact.intrinsics.cross_sign`)."""


def _ring_inputs(N: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`_face_rings` needs from facet normals ``N`` (k, 3) and signed values ``S`` (n, k), int64 or
    Python ints: ``on`` (n, k) bool (the point lies on the facet), ``ax`` (k,) int64 (the normal's dominant
    axis, the first of equals, as Python's ``max``) and ``flip`` (k,) bool (that component is negative)."""
    on = np.asarray(S == 0, dtype=np.bool_)
    absN = np.abs(N)
    ax = np.zeros(N.shape[0], np.int64)
    for c in (1, 2):  # strictly greater: the first of equals wins
        ax = np.where(np.asarray(absN[:, c] > absN[np.arange(N.shape[0]), ax], dtype=np.bool_), c, ax)
    flip = np.asarray(N[np.arange(N.shape[0]), ax] < 0, dtype=np.bool_)
    return np.ascontiguousarray(on), ax, flip


@jit
def _row_less(K, i, j):
    """Whether row i of ``K`` (r, c) int64 comes before row j in lexicographic order."""
    for c in range(K.shape[1]):
        if K[i, c] != K[j, c]:
            return K[i, c] < K[j, c]
    return False


@jit
def _lex_order(K):
    """Indices ``(r,)`` int64 of the rows of ``K`` (r, c) int64 in lexicographic order (equal rows in any order).

    A heapsort: the hull kernels sort a few hundred rows, and numba's own sorts (argsort, ndarray.sort) cost
    over a second of compilation each on a cold cache."""
    m = K.shape[0]
    order = np.arange(m)
    for start in range(m // 2 - 1, -1, -1):
        _sift_down(K, order, start, m)
    for end in range(m - 1, 0, -1):
        order[0], order[end] = order[end], order[0]
        _sift_down(K, order, 0, end)
    return order


@jit
def _sift_down(K, order, root, end):
    while True:
        child = 2 * root + 1
        if child >= end:
            return
        if child + 1 < end and _row_less(K, order[child], order[child + 1]):
            child += 1
        if not _row_less(K, order[root], order[child]):
            return
        order[root], order[child] = order[child], order[root]
        root = child


@jit
def _face_rings(L, on, ax, flip):
    """Every facet's polygon, as :func:`_polygon_order` orders it, for int64 points in one compiled pass.

    ``L`` (n, 3) int64 local points (every ``|L| < _RING_SAFE``); ``on``, ``ax``, ``flip`` from
    :func:`_ring_inputs`. Returns ``offsets`` (k + 1,) int64 and ``ring`` int64: facet j's vertices are
    ``ring[offsets[j]:offsets[j + 1]]`` (fewer than three when its points are collinear). The points on each
    facet are gathered in index order and handed to :func:`_face_rings_of_members`.
    """
    n, k = on.shape
    starts = np.zeros(k + 1, np.int64)
    for j in range(k):
        m = 0
        for i in range(n):
            if on[i, j]:
                m += 1
        starts[j + 1] = starts[j] + m
    members = np.empty(starts[k], np.int64)
    for j in range(k):
        m = starts[j]
        for i in range(n):
            if on[i, j]:
                members[m] = i
                m += 1
    return _face_rings_of_members(L, starts, members, ax, flip)


_INSERTION_SORT_POINTS = 16
"""Facets with at most this many points sort them by insertion in place (a capsule's are triangles); larger
ones by :func:`_lex_order`."""


@unlinked
@jit
def _face_rings_of_members(L, starts, members, ax, flip):
    """:func:`_face_rings` from the points on each facet: ``members[starts[j]:starts[j + 1]]`` (int64, ascending)
    lie on facet j. Points are sorted by their projected (u, v) coordinates (lexicographic; no two coincide,
    since the projection along the dominant axis is one to one on a plane) and Andrew's monotone chain decides
    with exact i128 cross products."""
    k = starts.shape[0] - 1
    ring = np.empty(starts[k], np.int64)
    offsets = np.zeros(k + 1, np.int64)
    most = 0
    for j in range(k):
        most = max(most, starts[j + 1] - starts[j])
    sorted_pts = np.empty(most, np.int64)
    chain = np.empty(2 * most + 2, np.int64)
    pos = 0
    for j in range(k):
        u, v = (ax[j] + 1) % 3, (ax[j] + 2) % 3
        m = starts[j + 1] - starts[j]
        if m <= _INSERTION_SORT_POINTS:
            for t in range(m):  # insertion sort by (u, v)
                p = members[starts[j] + t]
                q = t
                while q > 0:
                    r = sorted_pts[q - 1]
                    if L[r, u] < L[p, u] or (L[r, u] == L[p, u] and L[r, v] < L[p, v]):
                        break
                    sorted_pts[q] = r
                    q -= 1
                sorted_pts[q] = p
        else:
            uv = np.empty((m, 2), np.int64)
            for t in range(m):
                p = members[starts[j] + t]
                uv[t, 0], uv[t, 1] = L[p, u], L[p, v]
            by_uv = _lex_order(uv)
            for t in range(m):
                sorted_pts[t] = members[starts[j] + by_uv[t]]
        if m < 3:
            for t in range(m):
                ring[pos + t] = sorted_pts[t]
            pos += m
            offsets[j + 1] = pos
            continue
        c = 0
        for sweep in range(2):  # the lower chain over sorted points, then the upper one over them reversed
            base = c
            for t in range(m):
                p = sorted_pts[t] if sweep == 0 else sorted_pts[m - 1 - t]
                while c - base >= 2:
                    a, b = chain[c - 2], chain[c - 1]
                    if cross_sign(L[b, u] - L[a, u], L[p, v] - L[a, v], L[b, v] - L[a, v], L[p, u] - L[a, u]) > 0:
                        break
                    c -= 1
                chain[c] = p
                c += 1
            c -= 1  # each chain's last point starts the other
        if flip[j]:
            for t in range(c):
                ring[pos + t] = chain[c - 1 - t]
        else:
            for t in range(c):
                ring[pos + t] = chain[t]
        pos += c
        offsets[j + 1] = pos
    return offsets, ring[:pos]


_SIDE_SAFE = 1 << 123
"""Bound on |n·x| and |d| under which :func:`_side_signs` sums them exactly in i128."""


def _split_offsets(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plane offsets (int64 or Python ints) as ``(high, low)`` int64 with ``d = high·2**62 + low``, 0 ≤ low < 2**62."""
    if d.dtype != object:
        d = d.astype(np.int64)
        return d >> 62, d & ((1 << 62) - 1)
    return (np.array([int(v) >> 62 for v in d], np.int64),
            np.array([int(v) & ((1 << 62) - 1) for v in d], np.int64))


def _signs_fit(E: int, N: np.ndarray, d: np.ndarray) -> bool:
    """Whether :func:`_side_signs` takes local points of extent E against planes (N, d): int64 normals, and the
    terms n·x and d below _SIDE_SAFE."""
    if N.dtype == object or E >= (1 << 62):
        return False
    n = int(np.abs(N).max(initial=0))
    D = max((abs(int(v)) for v in d), default=0) if d.dtype == object else int(np.abs(d).max(initial=0))
    return 3 * n * E < _SIDE_SAFE and D < _SIDE_SAFE


@jit
def _side_signs(L, N, dh, dl):
    """(n, k) int8 signs of ``N[j]·L[i] + d[j]`` (d split by :func:`_split_offsets`), exact in i128."""
    n, k = L.shape[0], N.shape[0]
    out = np.empty((n, k), np.int8)
    for i in range(n):
        for j in range(k):
            out[i, j] = plane_side_sign(N[j, 0], N[j, 1], N[j, 2], L[i, 0], L[i, 1], L[i, 2], dh[j], dl[j])
    return out


@jit
def directed_edge_table(offsets, ring, n):
    """The directed edges of the polygons ``ring[offsets[j]:offsets[j + 1]]`` over ``n`` points in an
    open-addressing hash table (keys a·n + b, at most half full): ``(ok, keys, owner, mask)`` with ``owner[slot]``
    the polygon of the edge at ``slot``; ``ok`` False when a ring has fewer than three vertices or an edge occurs
    twice in one direction. Linear time, no sort (numba's sorts cost over a second of compilation each)."""
    total = offsets[offsets.shape[0] - 1] - offsets[0]
    size = 16
    while size < 2 * total:
        size *= 2
    keys = np.full(size, -1, np.int64)
    owner = np.empty(size, np.int64)
    mask = size - 1
    for j in range(offsets.shape[0] - 1):
        s, e = offsets[j], offsets[j + 1]
        if e - s < 3:
            return False, keys, owner, mask
        for t in range(s, e):
            key = ring[t] * n + ring[s + (t + 1 - s) % (e - s)]
            slot = (key * 0x9E3779B1) & mask
            while keys[slot] != -1:
                if keys[slot] == key:
                    return False, keys, owner, mask  # an edge twice in one direction
                slot = (slot + 1) & mask
            keys[slot] = key
            owner[slot] = j
    return True, keys, owner, mask


@jit
def edge_slot(keys, mask, key):
    """The slot of ``key`` in a :func:`directed_edge_table`, or -1 when it is not there."""
    slot = (key * 0x9E3779B1) & mask
    while keys[slot] != key:
        if keys[slot] == -1:
            return -1
        slot = (slot + 1) & mask
    return slot


@unlinked
@jit
def _rings_close(offsets, ring, n):
    """Whether the polygons ``ring[offsets[j]:offsets[j + 1]]`` over ``n`` points form a closed surface:
    every ring has three or more vertices, and every directed edge occurs once, its reverse once
    (:func:`directed_edge_table`)."""
    ok, keys, _, mask = directed_edge_table(offsets, ring, n)
    if not ok:
        return False
    for slot in range(keys.shape[0]):
        key = keys[slot]
        if key != -1 and edge_slot(keys, mask, (key % n) * n + key // n) < 0:
            return False  # an edge without its reverse
    return True


def _rings_fit_int64(L: np.ndarray) -> bool:
    """Whether the compiled face kernels take these local points (int64, every coordinate below _RING_SAFE)."""
    return L.dtype != object and int(np.abs(L).max(initial=0)) < _RING_SAFE


class ConvexHull:
    """An exact convex polytope with integer vertices: outward integer facet planes and polygon faces.

    Build one with :func:`convex_hull` (or :func:`small_hulls` for many small ones).

    Attributes
    ----------
    planes : (k, 4) int64, or object (Python ints) where a value does not fit int64
        One outward plane ``a x + b y + c z + d = 0`` per facet (inside: ``< 0``),
        ``gcd(a, b, c) = 1``, rows in lexicographic order of the local representation.
    lo, hi : (3,) int64
        Bounding box of the vertices.
    width : int
        The bit width whose mesh budget (eq. 8) the vertices were checked against.
    grid : csgnb.exact.Grid or None
        The grid the coordinates live on, when known (tools and sweeps set it).
    points : (v, 3) int64
        The hull's vertices (lazily computed, lexicographically sorted).
    faces : list of (k_i,) int64
        One polygon per plane (same order), indices into ``points``, counter-clockwise
        seen from outside; coplanar input triangles are one polygon.
    """

    __slots__ = ("_candidates", "_normals", "_d_local", "_origin", "lo", "hi", "width", "grid", "__dict__")

    def __init__(self, candidates: np.ndarray, origin: np.ndarray, normals: np.ndarray, d_local: np.ndarray, *,
                 width: int, grid=None, box: tuple[np.ndarray, np.ndarray] | None = None, rings=None) -> None:
        # Internal constructor: ``candidates`` (local int64 points containing all vertices), ``normals`` and
        # ``d_local`` the verified, reduced facet planes in coordinates local to ``origin``; ``box`` the
        # candidates' (lo, hi) in global coordinates when the caller has it; ``rings`` the facets' polygons when
        # the verification built them (``(offsets, ring)`` over the candidates, as :func:`_face_rings` gives).
        if rings is not None:
            self._rings = rings
        self._candidates = candidates
        self._origin = origin
        self._normals = normals
        self._d_local = d_local
        if box is None:
            box = (candidates.min(axis=0) + origin, candidates.max(axis=0) + origin)
        self.lo, self.hi = box
        self.width = width
        self.grid = grid

    # -- exact planes -----------------------------------------------------------

    @cached_property
    def planes(self) -> np.ndarray:
        """(k, 4) outward facet planes in global coordinates (int64 where every value fits)."""
        N, o = self._normals, self._origin
        if N.dtype != object and self._d_local.dtype != object:
            planes = _global_planes(N.astype(np.int64), self._d_local.astype(np.int64), o.astype(np.int64))
            if planes.shape[0] == N.shape[0]:
                return planes
        split = self._split_planes()
        if split is not None:
            N, d = split
        else:
            d = _object(self._d_local) - _object(N) @ _object(o)
        return _maybe_int64(np.column_stack([_object(N), _object(d)]))

    def _split_planes(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(N (k, 3) int64, d (k,))`` global planes with int64 normals and their offsets as int64 or Python ints
        (a 1-D object array), without the ``(k, 4)`` object array :attr:`planes` makes; None when a normal does
        not fit in int64 or the origin is too far for the exact int64 split (then :attr:`planes` is the way)."""
        N, o = self._normals, self._origin
        if o.dtype == object or max_abs(o) >= _SPLIT_POINTS:
            return None
        try:  # the brute-force facets keep Python ints even where every normal fits in int64
            N = N.astype(np.int64)
        except OverflowError:
            return None
        shift = _exact_row_dots(N, np.broadcast_to(o.astype(np.int64), N.shape))
        d_local = self._d_local
        if d_local.dtype != object and shift.dtype != object and max(max_abs(d_local), max_abs(shift)) < _INT64_SAFE:
            d = d_local.astype(np.int64) - shift  # both below 2**62: no wrap (an int64 shift may reach 2**63)
        else:
            d = _maybe_int64(_object(d_local) - _object(shift))
        return N, d

    @property
    def n_planes(self) -> int:
        """Number of facets."""
        return int(self._normals.shape[0])

    def planes_wide(self, width: int | None = None) -> np.ndarray:
        """The facet planes as a ``(k, 4)`` wide array of ``width`` bits (default: the hull's width).

        Raises :class:`csgnb.PrecisionError` when the vertices exceed the mesh budget of ``width``.
        """
        width = self.width if width is None else width
        if width != self.width:
            check_mesh_points(np.stack([self.lo, self.hi]), width, "hull box corners")
        return to_wide(self.planes, width)

    # -- faces and vertices -------------------------------------------------------

    def _side(self, L: np.ndarray) -> np.ndarray:
        """(n, k) exact signed values n·p + d of local points ``L`` against every facet."""
        E = int(max(np.abs(L).max(initial=0), np.abs(self._candidates).max(initial=0)))
        if _arith(E, 24) is np.int64 and self._normals.dtype != object and self._d_local.dtype != object:
            return L @ self._normals.T + self._d_local[None, :]
        return _object(L) @ _object(self._normals).T + _object(self._d_local)[None, :]

    @cached_property
    def _faces_local(self) -> list[np.ndarray]:
        known = self.__dict__.get("_rings")
        if known is not None:  # the verification's own rings
            offsets, ring = known
            return [ring[offsets[j]:offsets[j + 1]] for j in range(self.n_planes)]
        L = self._candidates
        if L.dtype != object and _signs_fit(int(np.abs(L).max(initial=0)), self._normals, self._d_local):
            S = _side_signs(L.astype(np.int64), self._normals.astype(np.int64), *_split_offsets(self._d_local))
        else:
            S = self._side(L)
        if _rings_fit_int64(self._candidates):
            offsets, ring = _face_rings(self._candidates, *_ring_inputs(self._normals, S))
            return [ring[offsets[j]:offsets[j + 1]] for j in range(self.n_planes)]
        faces = []
        for j in range(self.n_planes):
            on = np.flatnonzero(S[:, j] == 0)
            ring = _polygon_order(self._candidates[on], self._normals[j])
            faces.append(on[ring])
        return faces

    @cached_property
    def points(self) -> np.ndarray:
        """(v, 3) int64 hull vertices, lexicographically sorted."""
        used = np.unique(np.concatenate(self._faces_local)) if self.n_planes else np.zeros(0, np.int64)
        return self._candidates[used] + self._origin

    @cached_property
    def faces(self) -> list[np.ndarray]:
        """One polygon per facet plane: (k_i,) int64 indices into :attr:`points`, CCW seen from outside."""
        used = np.unique(np.concatenate(self._faces_local))
        remap = np.full(self._candidates.shape[0], -1, np.int64)
        remap[used] = np.arange(used.shape[0])
        return [remap[f] for f in self._faces_local]

    def to_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """The boundary as ``(points (v, 3) int64, triangles (t, 3) int64)``, faces fan-triangulated, outward."""
        tris = [np.column_stack([np.full(len(f) - 2, f[0]), f[1:-1], f[2:]]) for f in self.faces]
        return self.points, np.concatenate(tris).astype(np.int64)

    def to_polydata(self):
        """The boundary as a pyvista ``PolyData`` (model units when :attr:`grid` is set, else grid units)."""
        import pyvista as pv

        pts = self.points.astype(np.float64) if self.grid is None else self.grid.to_model(self.points)
        cells = np.concatenate([np.r_[len(f), f] for f in self.faces])
        return pv.PolyData(pts, cells)

    # -- exact queries ----------------------------------------------------------

    def volume(self) -> Fraction:
        """Exact volume (grid units cubed)."""
        P = [tuple(int(x) for x in p - self.points[0]) for p in self.points]
        six = 0
        for f in self.faces:
            a = P[f[0]]
            for i in range(1, len(f) - 1):
                b, c = P[f[i]], P[f[i + 1]]
                six += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                        + a[2] * (b[0] * c[1] - b[1] * c[0]))
        return Fraction(six, 6)

    def contains(self, points, *, strict: bool = False) -> np.ndarray:
        """Whether integer ``points`` (n, 3) lie in the closed hull (``strict``: in its interior); exact."""
        p = np.atleast_2d(np.asarray(points))
        if p.ndim != 2 or p.shape[1] != 3 or p.dtype.kind not in "iu":
            raise TypeError(f"points must be an (n, 3) integer array, got {p.dtype} {p.shape}")
        if p.dtype == np.uint64 and p.size and p.max() > np.iinfo(np.int64).max:
            L = _object(p) - _object(self._origin)
            S = L @ _object(self._normals).T + _object(self._d_local)[None, :]
        else:
            big = int(np.abs(p.astype(object)).max(initial=0)) + int(np.abs(self._origin).max(initial=0))
            if big < (1 << 62):
                S = self._side(p.astype(np.int64) - self._origin)
            else:
                L = _object(p) - _object(self._origin)
                S = L @ _object(self._normals).T + _object(self._d_local)[None, :]
        return np.all(S < 0, axis=1) if strict else np.all(S <= 0, axis=1)

    def translated(self, t) -> ConvexHull:
        """The hull moved by the integer vector ``t`` (exact: d' = d − n·t), with the same width and grid."""
        t = np.asarray(t)
        if t.shape != (3,) or t.dtype.kind not in "iu":
            raise TypeError(f"a translation must be a (3,) integer vector, got {t.dtype} {t.shape}")
        moved = ConvexHull(self._candidates, self._origin + t.astype(np.int64), self._normals, self._d_local,
                           width=self.width, grid=self.grid)
        check_mesh_points(np.stack([moved.lo, moved.hi]), self.width, "translated hull box corners")
        for name in ("_faces_local", "faces", "_edges", "_rings"):  # indices, the same for the moved hull
            if name in self.__dict__:
                moved.__dict__[name] = self.__dict__[name]
        return moved

    @cached_property
    def _edges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every edge once: ``(a, b, j, k)`` with the directed edge a -> b (indices into :attr:`points`) in face j's
        counter-clockwise ring and b -> a in face k's."""
        face_of = {}
        for j, f in enumerate(self.faces):
            for a, b in zip(f.tolist(), np.roll(f, -1).tolist(), strict=True):
                face_of[(a, b)] = j
        rows = [(a, b, j, face_of[(b, a)]) for (a, b), j in face_of.items() if a < b]
        e = np.array(rows, np.int64).reshape(-1, 4)
        return e[:, 0], e[:, 1], e[:, 2], e[:, 3]

    def swept(self, t, *, offset=None) -> ConvexHull:
        """The volume the hull sweeps moving by the integer vector ``t``: its Minkowski sum with the segment
        ``[0, t]``, which is ``conv(hull ∪ (hull + t))`` -- the sweep of a convex tool along a straight move.
        With ``offset``, the sweep of the hull translated by it (``translated(offset).swept(t)``, reusing
        this hull's faces and edges: a tool's hull serves every move).

        Built from this hull's facets and edges, with no new hull search: a facet ``n·x + d = 0``
        with ``n·t <= 0`` bounds the sum at the start pose, one with ``n·t > 0`` at the end pose
        (``d - n·t``); an edge a -> b of a face with ``n·t < 0`` whose other face has ``n·t > 0``
        (the silhouette seen along ``t``) spans the facet through a, b and a + t, with outward
        normal ``t × (b - a)`` (the face's inside lies along ``n × (b - a)``, and
        ``(t × e)·(n × e) = |e|² n·t < 0``). These are exactly the facets :func:`convex_hull`
        finds for the vertices at both poses, reduced and in the same order (the same local
        origin, the smallest point), so the result is the same hull, found in about a tenth of
        the time.
        """
        t = np.asarray(t)
        u = np.zeros(3, np.int64) if offset is None else np.asarray(offset)
        for name, vec in (("sweep vector", t), ("offset", u)):
            if vec.shape != (3,) or vec.dtype.kind not in "iu":
                raise TypeError(f"the {name} must be a (3,) integer vector, got {vec.dtype} {vec.shape}")
        t, u = t.astype(np.int64), u.astype(np.int64)
        if not t.any():
            return self.translated(u) if u.any() else self
        V = self.points + u
        P = np.unique(np.vstack([V, V + t]), axis=0)
        check_mesh_points(np.stack([P[0], P[-1], P.min(axis=0), P.max(axis=0)]), self.width, "swept hull points")
        origin = P[0].copy()
        L, Vl = P - origin, V - origin
        N = self._normals
        shift = origin - self._origin - u
        E = int(max(np.abs(L).max(initial=0), np.abs(t).max(), np.abs(shift).max()))
        fits = _arith(E, 48) is np.int64 and N.dtype != object and self._d_local.dtype != object
        tt = t if fits else _object(t)
        # Facets in the new local frame: d = d_old + n·(origin - old origin), then minus n·t at the end pose.
        shift = shift if fits else _object(shift)
        Nk = N if fits else _object(N)
        s = Nk @ tt
        d = (self._d_local if fits else _object(self._d_local)) + Nk @ shift
        d = np.where(s > 0, d - s, d)
        a, b, j, k = self._edges
        sa, sb = s[j], s[k]
        back = (sa < 0) & (sb > 0)  # a -> b lies in the face with n·t < 0
        front = (sa > 0) & (sb < 0)  # b -> a does
        A = Vl if fits else _object(Vl)
        tail = np.concatenate([a[back], b[front]])
        head = np.concatenate([b[back], a[front]])
        M = _cross(np.broadcast_to(tt, (tail.shape[0], 3)), A[head] - A[tail])
        dm = -np.sum(M * A[tail], axis=1)
        M, dm = _reduce_planes(M, dm)
        normals, d_local = _sorted_unique_planes(np.vstack([Nk, M]), np.concatenate([d, dm]))
        return ConvexHull(L, origin, normals, d_local, width=self.width, grid=self.grid)

    def to_bsp(self, width: int | None = None, *, margin: int = 1):
        """The hull as a :class:`csgnb.bsp.BSP`: a linear tree, each facet's positive child an out leaf.

        Node 2i splits by plane i (positive child 2i + 1 out, negative child 2i + 2), the
        last negative child is the in leaf. The box is the hull's box grown by ``margin``.
        """
        from csgnb.bsp.solid import BSP
        from csgnb.bsp.tree import BSPTree

        tree = BSPTree(self.planes_wide(width), *linear_bsp_arrays(self.n_planes))
        return BSP(tree, self.lo - margin, self.hi + margin)

    def __repr__(self) -> str:
        return (f"ConvexHull({self.n_planes} facets, box {self.lo.tolist()}..{self.hi.tolist()}, "
                f"{self.width}-bit budget)")


# ---------------------------------------------------------------------------
# construction


@jit
def _global_planes(N, d, o):
    """``(k, 4) int64`` planes (n, d - n·o) of local planes ``N`` (k, 3), ``d`` (k,) int64 at ``origin`` (3,) int64;
    an empty ``(0, 4)`` array when 3 max|n| max|o| + max|d| reaches 2**62 (the caller takes Python ints then).
    The bound is checked first in floats with a wide margin, so no int64 product can wrap."""
    k = N.shape[0]
    big_n = 0.0
    big_d = 0.0
    for j in range(k):
        big_d = max(big_d, abs(float(d[j])))
        for c in range(3):
            big_n = max(big_n, abs(float(N[j, c])))
    big_o = max(abs(float(o[0])), abs(float(o[1])), abs(float(o[2])))
    if 3.0 * big_n * big_o + big_d >= 2.0**61:  # float error < 2**-50 relative: far from 2**62
        return np.zeros((0, 4), np.int64)
    out = np.empty((k, 4), np.int64)
    for j in range(k):
        out[j, 0], out[j, 1], out[j, 2] = N[j, 0], N[j, 1], N[j, 2]
        out[j, 3] = d[j] - (N[j, 0] * o[0] + N[j, 1] * o[1] + N[j, 2] * o[2])
    return out


def _checked_points(points, width: int, name: str = "points") -> np.ndarray:
    P = np.asarray(points)
    if P.ndim != 2 or P.shape[1] != 3:
        raise GeometryError(f"{name} must have shape (n, 3), got {P.shape}")
    if P.dtype.kind not in "iu":
        raise TypeError(f"{name} must be integer grid points (int64), got dtype {P.dtype}; quantize them with "
                        "csgnb.exact.Grid.to_grid")
    if P.dtype == np.uint64 and P.size and P.max() > np.iinfo(np.int64).max:
        raise GeometryError(f"{name} have values beyond int64")
    P = P.astype(np.int64)
    check_mesh_points(P, width, name)
    return P


def _independent(L: np.ndarray) -> np.ndarray | None:
    """Indices of 4 affinely independent rows of local points (row 0 first), or None if the set is flat."""
    E = int(np.abs(L).max(initial=0))
    if L.dtype != object and E < _COMPILED_FACETS_SAFE:
        basis = _independent_int64(L.astype(np.int64))
        return basis if basis[3] >= 0 else None
    A = L.astype(_arith(E))
    nz = np.flatnonzero(np.any(A != 0, axis=1))
    if nz.size == 0:
        return None
    i1 = int(nz[0])
    c = _cross(A[i1][None, :], A)
    nc = np.flatnonzero(np.any(c != 0, axis=1))
    if nc.size == 0:
        return None
    i2 = int(nc[0])
    n = c[i2]
    det = A @ n
    nd = np.flatnonzero(det != 0)
    if nd.size == 0:
        return None
    return np.array([0, i1, i2, int(nd[0])])


@jit
def _independent_int64(L):
    """:func:`_independent` for int64 local points of extent E below :data:`_COMPILED_FACETS_SAFE`: the same four
    indices (the first nonzero row, the first row off its line, the first row off their plane), compiled; the cross
    products (below 2E² < 2**59) in int64, the last test's sign in i128 (``plane_side_sign``: 6E³ reaches 2**90 on
    a 256-bit grid, where the Python-int fallback was most of a capsule hull's extra cost); ``basis[3] == -1``
    when the set is flat."""
    basis = np.array([0, -1, -1, -1], np.int64)
    n = L.shape[0]
    for i in range(n):
        if L[i, 0] != 0 or L[i, 1] != 0 or L[i, 2] != 0:
            basis[1] = i
            break
    if basis[1] < 0:
        return basis
    a = L[basis[1]]
    for i in range(n):
        c0 = a[1] * L[i, 2] - a[2] * L[i, 1]
        c1 = a[2] * L[i, 0] - a[0] * L[i, 2]
        c2 = a[0] * L[i, 1] - a[1] * L[i, 0]
        if c0 != 0 or c1 != 0 or c2 != 0:
            basis[2] = i
            break
    if basis[2] < 0:
        return basis
    zero = np.int64(0)
    for i in range(n):
        if plane_side_sign(c0, c1, c2, L[i, 0], L[i, 1], L[i, 2], zero, zero) != 0:
            basis[3] = i
            break
    return basis


def _flat_error(P: np.ndarray, name: str) -> GeometryError:
    L = P - P[0]
    A = L.astype(_arith(int(np.abs(L).max(initial=0))))
    if not np.any(A):
        what = "all the same point"
    elif not np.any(_cross(A[np.flatnonzero(np.any(A != 0, axis=1))[0]][None, :], A)):
        what = "collinear"
    else:
        what = "coplanar"
    return GeometryError(f"the convex hull of these {len(P)} {name} is degenerate: they are {what}, so it has no "
                         "volume. A sweep of a flat piece along its own plane has zero volume and can be skipped")


def linear_bsp_arrays(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Node arrays ``plane, neg, pos, label`` ``(2k + 1,) int32`` of a convex solid's linear BSP over ``k`` planes.

    Node 2i tests plane i (outside: an out leaf at 2i + 1; inside: on to 2i + 2); node 2k is the
    in leaf (where another tree can be grafted).
    """
    idx = np.arange(k)
    plane = np.full(2 * k + 1, -1, np.int32)
    neg = np.full(2 * k + 1, -1, np.int32)
    pos = np.full(2 * k + 1, -1, np.int32)
    label = np.zeros(2 * k + 1, np.int32)
    plane[2 * idx] = idx
    neg[2 * idx] = 2 * idx + 2
    pos[2 * idx] = 2 * idx + 1
    label[2 * idx] = -1
    label[2 * k] = 1
    return plane, neg, pos, label


def convex_hull(points, *, width: int | None = None, grid=None, name: str = "points") -> ConvexHull:
    """Return the exact convex hull of integer grid points.

    Parameters
    ----------
    points : (n, 3) int64
        Grid points within the mesh budget of ``width`` (repeated points are fine).
    width : {128, 192, 256}, optional
        The predicate width the facet planes must fit (eq. 8); default: the grid's, else
        :data:`csgnb.exact.DEFAULT_WIDTH`.
    grid : csgnb.exact.Grid, optional
        Recorded on the hull, so a workpiece can refuse tools from another grid.

    Raises
    ------
    GeometryError
        Fewer than four affinely independent points (a flat, collinear or single-point set).
    PrecisionError
        A coordinate above the mesh budget of ``width`` (names the bound of eq. 8).
    TypeError
        Non-integer points.
    """
    if width is None:
        width = grid.width if grid is not None else DEFAULT_WIDTH
    elif grid is not None and width != grid.width:
        raise GeometryError(f"width={width} but the grid is {grid.width}-bit: pass one of them")
    P = _unique_rows(_checked_points(points, width, name))
    if P.shape[0] < 4:
        raise _flat_error(P, name) if P.shape[0] else GeometryError(f"the convex hull of no {name} is empty")
    origin = P[0].copy()
    L = P - origin
    basis = _independent(L)
    if basis is None:
        raise _flat_error(P, name)
    box = _box_facets(L)
    if box is not None:
        N, d = box
    elif P.shape[0] <= BRUTE_FORCE_POINTS:
        N, d = _enumerate_facets(L)
    else:
        rings = []
        found = _incremental_facets(L, basis, rings)
        if found is None:
            found = _qhull_facets(L, basis)
        N, d = found if found is not None else _gift_wrap(L)
        if rings:
            return ConvexHull(L, origin, N, d, width=width, grid=grid, rings=rings[0])
    return ConvexHull(L, origin, N, d, width=width, grid=grid)


def _unique_rows(M: np.ndarray) -> np.ndarray:
    """The distinct rows of ``M`` (n, k) in lexicographic order, as tuples of its numbers sort: ``np.unique(M,
    axis=0)``, which for small integer arrays costs ~80 µs of set-up (a structured view, a copy) against ~10 µs for
    a lexsort and a neighbour comparison (a capsule's hull did two of them per Boolean of the dome carve)."""
    if M.dtype.kind not in "iu" or M.ndim != 2 or M.shape[0] < 2:
        return np.unique(M, axis=0)
    S = M[np.lexsort(M.T[::-1])]
    keep = np.empty(S.shape[0], dtype=np.bool_)
    keep[0] = True
    np.any(S[1:] != S[:-1], axis=1, out=keep[1:])
    return S[keep]


def _sorted_unique_planes(N: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct planes (N, d) in lexicographic order of (a, b, c, d)."""
    if N.dtype != object and d.dtype != object:  # int64 rows sort lexicographically, as tuples sort
        M = _unique_rows(np.column_stack([N.astype(np.int64), d.astype(np.int64)]))
        return M[:, :3], M[:, 3]
    rows = sorted({tuple(int(x) for x in r) + (int(e),) for r, e in zip(N, d, strict=True)})
    M = _maybe_int64(np.array(rows, dtype=object))
    return M[:, :3], M[:, 3]


_AXES = np.vstack([np.eye(3, dtype=np.int64), -np.eye(3, dtype=np.int64)])


def _box_facets(L: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The six facet planes of an axis-aligned box, when the distinct local points ``L`` (n, 3) are its eight corners;
    else None.

    Eight distinct points whose coordinates each take one of two values per axis are the eight corners, and their
    hull's facets are the planes x_c = lo_c and x_c = hi_c: no enumeration of the 56 point triples, which at 192 and
    256 bits (coordinates beyond 2**31) runs on Python ints (~0.3 ms a box). The same sorted planes as
    :func:`_enumerate_facets` (``tests/test_hull.py``).
    """
    if L.shape[0] != 8 or L.dtype.kind not in "iu":
        return None
    lo, hi = L.min(axis=0), L.max(axis=0)
    if np.any(lo == hi) or not np.all((L == lo) | (L == hi)):
        return None
    return _sorted_unique_planes(_AXES, np.concatenate([-hi, lo]).astype(np.int64))


def _enumerate_facets(L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All supporting planes through three local points: exact facet enumeration (small sets)."""
    n = L.shape[0]
    E = int(np.abs(L).max(initial=0))
    A = L.astype(_arith(E))
    i, j, k = (np.array(t) for t in zip(*[(a, b, c) for a in range(n) for b in range(a + 1, n)
                                          for c in range(b + 1, n)], strict=True))
    N = _cross(A[j] - A[i], A[k] - A[i])
    d = -np.einsum("ij,ij->i", N, A[i]) if A.dtype != object else -np.sum(N * A[i], axis=1)
    S = N @ A.T + d[:, None]
    below = np.all(S <= 0, axis=1)
    above = np.all(S >= 0, axis=1)
    real = np.any(N != 0, axis=1)
    keep = real & (below | above)
    sign = np.where(below, 1, -1)
    N, d = N[keep] * sign[keep, None], d[keep] * sign[keep]
    N, d = _reduce_planes(N, d)
    return _sorted_unique_planes(N, d)


def _faces_close(L: np.ndarray, N: np.ndarray, d: np.ndarray, S: np.ndarray) -> bool:
    """Whether the faces of these supporting planes form a closed surface (every edge once each way)."""
    if _rings_fit_int64(L):
        offsets, ring = _face_rings(L, *_ring_inputs(N, S))
        return bool(_rings_close(offsets, ring, L.shape[0]))
    return _faces_close_py(L, N, S)


def _faces_close_py(L: np.ndarray, N: np.ndarray, S: np.ndarray) -> bool:
    """:func:`_faces_close` in Python integers (any size; the reference the compiled path is tested against)."""
    half = {}
    for j in range(N.shape[0]):
        on = np.flatnonzero(S[:, j] == 0)
        ring = on[_polygon_order(L[on], N[j])]
        if ring.shape[0] < 3:
            return False
        for a, b in zip(ring, np.roll(ring, -1), strict=True):
            key = (int(a), int(b))
            if key in half:
                return False
            half[key] = j
    return all((b, a) in half for (a, b) in half)


def _incremental_facets(L: np.ndarray, basis: np.ndarray,
                        rings: list | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """Facets of int64 local points of extent below :data:`_COMPILED_FACETS_SAFE` by the compiled exact incremental
    hull, verified like qhull's (:func:`_verified_facets`); None for other points or when a check fails. ``rings``:
    a list that receives the verified facet rings (see :func:`_checked_facets`)."""
    if L.dtype == object or int(np.abs(L).max(initial=0)) >= _COMPILED_FACETS_SAFE:
        return None
    L = np.ascontiguousarray(L, np.int64)
    basis = np.asarray(basis, np.int64)
    return _checked_facets(L, _incremental_triangles(L, basis), basis, rings)


def _checked_facets(L: np.ndarray, simplices: np.ndarray, basis: np.ndarray,
                    rings: list | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_verified_facets` of triangles over int64 local points (extent below :data:`_COMPILED_FACETS_SAFE`),
    with each facet's offset d = -n·(its anchor point): int64 where 24E³ fits, Python ints beyond. ``rings``: a
    list that receives ``(offsets, ring)``, the facets' polygons the verification built (a hull keeps them:
    :attr:`ConvexHull.faces` and a tool's facets need not find them again)."""
    ok, N, anchor, offsets, ring = _verified_facets(L, np.ascontiguousarray(simplices, np.int64),
                                                    np.asarray(basis, np.int64))
    if not ok:
        return None
    if rings is not None:
        rings.append((offsets, ring))
    E = int(np.abs(L).max(initial=0))
    A = L[anchor]
    if 24 * E**3 < _INT64_SAFE:
        return N, -np.einsum("ij,ij->i", N, A)
    return N, -_exact_row_dots(N, A)  # |A| <= E < 2**29 (_COMPILED_FACETS_SAFE)


def _qhull_facets(L: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Facets proposed by qhull and verified exactly; None when qhull fails or a check does not hold."""
    from scipy.spatial import ConvexHull as _Qhull
    from scipy.spatial import QhullError

    try:
        simplices = _Qhull(L.astype(np.float64)).simplices
    except (QhullError, ValueError):
        return None
    E = int(np.abs(L).max(initial=0))
    if L.dtype != object and E < _COMPILED_FACETS_SAFE:
        return _checked_facets(L.astype(np.int64), simplices, basis)
    A = L.astype(_arith(E, 48))
    N = _cross(A[simplices[:, 1]] - A[simplices[:, 0]], A[simplices[:, 2]] - A[simplices[:, 0]])
    d = -np.sum(N * A[simplices[:, 0]], axis=1)
    # Orient by 4x the centroid of four independent points (strictly inside the hull).
    c4 = A[basis].sum(axis=0)
    s = N @ c4 + 4 * d
    if np.any(s == 0):
        return None
    flip = np.where(s > 0, -1, 1)
    N, d = _reduce_planes(N * flip[:, None], d * flip)
    N, d = _sorted_unique_planes(N, d)
    S = (A @ N.T + d[None, :]) if N.dtype != object and A.dtype != object else \
        _object(L) @ _object(N).T + _object(d)[None, :]
    if np.any(S > 0) or not _faces_close(L, N, d, S):
        return None
    return N, d


_COMPILED_FACETS_SAFE = 1 << 29
"""Local extents below this take the compiled hull kernels (every width's mesh budget): normals below 8E² < 2**62 in
int64, each sign of a point against a facet n·(p - anchor) in i128 (below 48E³ < 2**93)."""


@jit
def _verified_facets(L, simplices, basis):
    """Triangles made into exact facet planes and verified, compiled, for int64 local points of extent below
    :data:`_COMPILED_FACETS_SAFE` (a dome carve's capsule hull: ~0.45 ms of NumPy calls before, ~0.07 ms here).

    ``L`` (n, 3) int64 local points, ``simplices`` (t, 3) int64 proposed triangles (the incremental hull's or
    qhull's), ``basis`` (4,) int64 indices of four affinely independent points. Each triangle's normal is
    oriented away from the four points' centroid (the triangle refused when its plane passes through it) and
    divided by its gcd; the distinct normals in lexicographic order (two facets of a convex polytope never share
    an outward normal, so this is the order of the planes (a, b, c, d), and a plane repeated by several
    triangles is one); verified: every point on or behind every plane, and the faces (the exact 2-D hulls of
    the points on each plane) close up. Every sign is n·(p - anchor) in i128, the anchor a point of the
    triangle: no offset is formed. Returns ``(ok, N (k, 3) int64, anchor (k,) int64, offsets (k + 1,) int64, ring
    int64)``; the offsets are d = -N·L[anchor], and facet j's polygon is ``ring[offsets[j]:offsets[j + 1]]`` (as
    :func:`_face_rings` orders it).
    """
    t = simplices.shape[0]
    n = L.shape[0]
    if t < 4:  # no closed surface has fewer than four triangles (and none would pass as "every edge paired")
        return False, np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.int64)
    c4 = np.zeros(3, np.int64)
    for q in range(4):
        for c in range(3):
            c4[c] += L[basis[q], c]
    P = np.empty((t, 3), np.int64)
    tri_anchor = np.empty(t, np.int64)
    for r in range(t):
        i, j, k = simplices[r, 0], simplices[r, 1], simplices[r, 2]
        u0, u1, u2 = L[j, 0] - L[i, 0], L[j, 1] - L[i, 1], L[j, 2] - L[i, 2]
        v0, v1, v2 = L[k, 0] - L[i, 0], L[k, 1] - L[i, 1], L[k, 2] - L[i, 2]
        a, b, c = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        # the side of 4 x the centroid: n·(c4 - 4 L[i])
        s = plane_side_sign(a, b, c, c4[0] - 4 * L[i, 0], c4[1] - 4 * L[i, 1], c4[2] - 4 * L[i, 2],
                            np.int64(0), np.int64(0))
        if s == 0:  # a flat triangle, or a plane through the interior point: the proposal was wrong
            return (False, np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(1, np.int64),
                    np.zeros(0, np.int64))
        if s > 0:
            a, b, c = -a, -b, -c
        g = gcd3(a, b, c)
        P[r, 0], P[r, 1], P[r, 2] = a // g, b // g, c // g
        tri_anchor[r] = i
    order = _lex_order(P)
    keep = np.empty(t, np.int64)
    k = 0
    for r in range(t):
        o = order[r]
        if k == 0 or (P[o, 0] != P[keep[k - 1], 0] or P[o, 1] != P[keep[k - 1], 1] or P[o, 2] != P[keep[k - 1], 2]):
            keep[k] = o
            k += 1
    N = np.empty((k, 3), np.int64)
    anchor = np.empty(k, np.int64)
    for r in range(k):
        N[r, 0], N[r, 1], N[r, 2], anchor[r] = P[keep[r], 0], P[keep[r], 1], P[keep[r], 2], tri_anchor[keep[r]]
    starts = np.zeros(k + 1, np.int64)
    members = np.empty(8 * n, np.int64)  # grown when needed: each point lies on a few facets
    ax = np.zeros(k, np.int64)
    flip = np.zeros(k, np.bool_)
    zero = np.int64(0)
    for j in range(k):
        a, b, c, o = N[j, 0], N[j, 1], N[j, 2], anchor[j]
        m = starts[j]
        if m + n > members.shape[0]:
            grown = np.empty(2 * members.shape[0] + n, np.int64)
            for t in range(m):  # a loop, not a slice assignment: those compile seconds of shape-error code
                grown[t] = members[t]
            members = grown
        for i in range(n):
            s = plane_side_sign(a, b, c, L[i, 0] - L[o, 0], L[i, 1] - L[o, 1], L[i, 2] - L[o, 2], zero, zero)
            if s > 0:
                return False, N, anchor, starts, members
            if s == 0:
                members[m] = i
                m += 1
        starts[j + 1] = m
        for col in (1, 2):  # strictly greater: the first of equals wins, as _ring_inputs
            if abs(N[j, col]) > abs(N[j, ax[j]]):
                ax[j] = col
        flip[j] = N[j, ax[j]] < 0
    offsets, ring = _face_rings_of_members(L, starts, members, ax, flip)
    return _rings_close(offsets, ring, n), N, anchor, offsets, ring


@jit
def _new_face(fv, fp, nb, f, a, b, c, L):
    """Face ``f`` := triangle (a, b, c) (indices into ``L``) with its normal n = (b - a) × (c - a) in ``fp[f]``."""
    fv[f, 0], fv[f, 1], fv[f, 2] = a, b, c
    u0, u1, u2 = L[b, 0] - L[a, 0], L[b, 1] - L[a, 1], L[b, 2] - L[a, 2]
    v0, v1, v2 = L[c, 0] - L[a, 0], L[c, 1] - L[a, 1], L[c, 2] - L[a, 2]
    fp[f, 0], fp[f, 1], fp[f, 2] = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    nb[f, 0] = nb[f, 1] = nb[f, 2] = -1


@jit
def _sees(fv, fp, f, L, p):
    """Whether point ``p`` lies strictly in front of face ``f``: n·(p - a) > 0, a its first vertex (i128)."""
    a = fv[f, 0]
    return plane_side_sign(fp[f, 0], fp[f, 1], fp[f, 2], L[p, 0] - L[a, 0], L[p, 1] - L[a, 1], L[p, 2] - L[a, 2],
                           np.int64(0), np.int64(0)) > 0


@jit
def _incremental_triangles(L, basis):
    """A triangulated convex hull of int64 local points ``L`` (n, 3) of extent below :data:`_COMPILED_FACETS_SAFE`,
    by exact incremental construction: ``(t, 3)`` int64 outward triangles (counter-clockwise seen from outside).

    Starts from the tetrahedron on ``basis`` (four affinely independent indices); each further point, in a fixed
    pseudo-random order, replaces the faces it sees strictly (n·(p - a) > 0) by the fan from it to their
    horizon. A point on a face's plane does not see it: it is on the hull or adds coplanar triangles, and no
    new triangle is flat (its apex is strictly beyond the plane through its base edge). Every value is exact
    (normals below 8E² in int64, signs n·(p - a) in i128). What it returns is checked by
    :func:`_verified_facets` like qhull's triangles, so a fault here costs time, never exactness.
    """
    n = L.shape[0]
    cap = 32 * n + 64
    fv = np.empty((cap, 3), np.int64)  # vertices
    fp = np.empty((cap, 3), np.int64)  # normals
    nb = np.empty((cap, 3), np.int64)  # neighbour across edge e: fv[f, e] -> fv[f, (e + 1) % 3]
    nf = 0
    b = basis
    for q in range(4):  # the tetrahedron: each face oriented away from the fourth vertex
        i, j, k = b[(q + 1) % 4], b[(q + 2) % 4], b[(q + 3) % 4]
        _new_face(fv, fp, nb, nf, i, j, k, L)
        if _sees(fv, fp, nf, L, b[q]):
            _new_face(fv, fp, nb, nf, i, k, j, L)
        nf += 1
    for f in range(4):  # neighbours of the tetrahedron: the face holding the reversed edge
        for e in range(3):
            a, c = fv[f, e], fv[f, (e + 1) % 3]
            for g in range(4):
                for h in range(3):
                    if g != f and fv[g, h] == c and fv[g, (h + 1) % 3] == a:
                        nb[f, e] = g
    faces = np.empty(cap, np.int64)  # the alive faces, in a list
    for f in range(4):
        faces[f] = f
    n_alive = 4
    visible = np.zeros(cap, np.bool_)
    seen = np.empty(cap, np.int64)
    from_vertex = np.full(n, -1, np.int64)  # per horizon vertex: the new face whose base edge starts there
    to_vertex = np.full(n, -1, np.int64)  # ... and the one whose base edge ends there
    order = np.empty(n, np.int64)
    shuffle_order(order, n, np.int64(0))  # sorted points would see most faces at every step
    for r in range(n):
        p = order[r]
        if p == b[0] or p == b[1] or p == b[2] or p == b[3]:
            continue
        n_seen = 0
        for t in range(n_alive):
            f = faces[t]
            if _sees(fv, fp, f, L, p):
                visible[f] = True
                seen[n_seen] = f
                n_seen += 1
        if n_seen == 0:
            continue  # inside the hull, or on it
        if nf + 3 * n_seen + 4 > cap:  # the fan has at most (horizon) <= 3 * seen faces; a random order creates
            return np.zeros((0, 3), np.int64)  # ~6n in all: this many is a pathological order, left to qhull
        first_new = nf
        for t in range(n_seen):
            f = seen[t]
            for e in range(3):
                g = nb[f, e]
                if g < 0:  # a broken neighbourhood: a fault; the caller falls back
                    return np.zeros((0, 3), np.int64)
                if visible[g]:
                    continue
                a, c = fv[f, e], fv[f, (e + 1) % 3]
                _new_face(fv, fp, nb, nf, a, c, p, L)
                nb[nf, 0] = g
                for h in range(3):
                    if nb[g, h] == f:
                        nb[g, h] = nf
                from_vertex[a] = nf
                to_vertex[c] = nf
                nf += 1
        for f in range(first_new, nf):  # the fan's own edges: c -> p meets the face from c, p -> a the face to a
            nb[f, 1] = from_vertex[fv[f, 1]]
            nb[f, 2] = to_vertex[fv[f, 0]]
        m = 0
        for t in range(n_alive):
            f = faces[t]
            if visible[f]:
                visible[f] = False
            else:
                faces[m] = f
                m += 1
        for f in range(first_new, nf):
            faces[m] = f
            m += 1
        n_alive = m
    out = np.empty((n_alive, 3), np.int64)
    for t in range(n_alive):
        for c in range(3):
            out[t, c] = fv[faces[t], c]
    return out


def _wrap(A: np.ndarray, a: np.ndarray, b: np.ndarray, q: int) -> tuple[np.ndarray, object]:
    """Rotate the plane through the line (a, b) and point A[q] until it supports every point of ``A``.

    The plane's normal is ``(b - a) × (A[q] - a)``; while a point lies strictly in front,
    the most distant one replaces q. Each step turns the plane further the same way
    around the line, and the line lies in a supporting plane, so this ends (exactly).
    """
    u = b - a
    while True:
        n = _cross(u[None, :], (A[q] - a)[None, :])[0]
        s = A @ n - (a @ n)
        best = int(np.argmax(s))
        if not s[best] > 0:
            return n, -(a @ n)
        q = best


def _gift_wrap(L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact hull by gift wrapping on faces (a BFS over face edges); slow but never wrong."""
    E = int(np.abs(L).max(initial=0)) + 1
    A = L.astype(_arith(E, 48))
    a = int(np.lexsort(A.T[::-1])[0])  # lexicographic minimum: a vertex on the plane x = min x
    zero = A[a] - A[a]
    ez = zero.copy()
    ez[2] = 1
    others = np.flatnonzero(np.any(A != A[a], axis=1))
    n1, _ = _wrap(A, A[a], A[a] + ez, int(others[0]))
    s1 = A @ n1 - A[a] @ n1
    # A second point on that supporting plane, then a facet through the line between them.
    on1 = [i for i in np.flatnonzero(s1 == 0) if i != a]
    b = int(on1[0])
    off_line = np.flatnonzero(np.any(_cross((A[b] - A[a])[None, :], A - A[a]) != 0, axis=1))
    n0, d0 = _wrap(A, A[a], A[b], int(off_line[0]))
    planes: dict[tuple, tuple[np.ndarray, object]] = {}
    half: set[tuple[int, int]] = set()
    todo = [(n0, d0)]
    while todo:
        n, dd = todo.pop()
        (n,), (dd,) = _reduce_planes(n[None, :], np.array([dd], dtype=A.dtype))
        key = tuple(int(x) for x in n) + (int(dd),)
        if key in planes:
            continue
        planes[key] = (n, dd)
        s = A @ n + dd
        on = np.flatnonzero(s == 0)
        ring = on[_polygon_order(L[on], n)]
        behind = int(np.flatnonzero(s < 0)[0])
        for i, j in zip(ring, np.roll(ring, -1), strict=True):
            half.add((int(i), int(j)))
            if (int(j), int(i)) not in half:
                todo.append(_wrap(A, A[j], A[i], behind))
    if not all((j, i) in half for (i, j) in half):
        raise InternalError("gift wrapping left an unmatched hull edge")
    rows = np.array(sorted(planes), dtype=object)
    M = _maybe_int64(rows)
    return M[:, :3], M[:, 3]


def small_hulls(points, *, width: int = DEFAULT_WIDTH, grid=None) -> list[ConvexHull | None]:
    """Exact hulls of many small point sets at once (vectorized facet enumeration).

    Parameters
    ----------
    points : (m, k, 3) int64
        ``m`` sets of ``k <= BRUTE_FORCE_POINTS`` grid points each (a triangle at two poses: k = 6).

    Returns
    -------
    list of ConvexHull or None
        ``None`` for a flat set (zero volume: coplanar, collinear or one point), which a
        union or difference can skip exactly.
    """
    P = np.asarray(points)
    if P.ndim != 3 or P.shape[2] != 3:
        raise GeometryError(f"points must have shape (m, k, 3), got {P.shape}")
    m, k = P.shape[0], P.shape[1]
    if k > BRUTE_FORCE_POINTS:
        raise GeometryError(f"small_hulls takes at most {BRUTE_FORCE_POINTS} points per set, got {k}; use "
                            "convex_hull for larger sets")
    P = _checked_points(P.reshape(-1, 3), width).reshape(m, k, 3)
    if m == 0:
        return []
    origin = P[:, 0, :]
    L = P - origin[:, None, :]
    E = int(np.abs(L).max(initial=0))
    if _arith(E) is not np.int64 and E <= SMALL_HULLS_FILTERED_EXTENT:
        # 256-bit grids: normals still fit int64, the distances do not -- signs from doubles where certified
        out = []
        for at in range(0, m, SMALL_HULLS_CHUNK):
            out += _small_hulls_filtered(P[at:at + SMALL_HULLS_CHUNK], width=width, grid=grid)
        return out
    if _arith(E) is not np.int64:  # enormous pieces: the general exact path, one by one
        out = []
        for S in P:
            try:
                out.append(convex_hull(S, width=width, grid=grid))
            except GeometryError:
                out.append(None)
        return out
    tri = np.array([(a, b, c) for a in range(k) for b in range(a + 1, k) for c in range(b + 1, k)])
    Ai, Aj, Ak = L[:, tri[:, 0]], L[:, tri[:, 1]], L[:, tri[:, 2]]  # (m, t, 3)
    N = _cross(Aj - Ai, Ak - Ai)
    d = -np.einsum("mtc,mtc->mt", N, Ai)
    S = np.einsum("mtc,mpc->mtp", N, L) + d[:, :, None]  # (m, t, k)
    below = np.all(S <= 0, axis=2)
    above = np.all(S >= 0, axis=2)
    real = np.any(N != 0, axis=2) & ~np.all(S == 0, axis=2)
    keep = real & (below | above)
    sign = np.where(below, 1, -1)
    N = N * sign[:, :, None]
    d = d * sign
    g = np.gcd.reduce(np.abs(N), axis=2)
    g = np.where(g == 0, 1, g)
    N, d = N // g[:, :, None], d // g
    mid, tid = np.nonzero(keep)
    rows = np.column_stack([mid, N[mid, tid], d[mid, tid]])
    rows = np.unique(rows, axis=0)
    starts = np.searchsorted(rows[:, 0], np.arange(m + 1))
    points, first, lo, hi = _unique_rows_per_set(np.ascontiguousarray(L))
    lo += origin
    hi += origin
    out: list[ConvexHull | None] = []
    for h in range(m):
        r = rows[starts[h]:starts[h + 1]]
        if r.shape[0] < 4:  # flat: no supporting plane with a point strictly behind
            out.append(None)
            continue
        out.append(ConvexHull(points[first[h]:first[h + 1]], origin[h].copy(), np.ascontiguousarray(r[:, 1:4]),
                              np.ascontiguousarray(r[:, 4]), width=width, grid=grid, box=(lo[h].copy(), hi[h].copy())))
    return out


SMALL_HULLS_FILTERED_EXTENT = 1 << 29  # cross products of local differences (<= 2**30) stay below 2**61
SMALL_HULLS_CHUNK = 8192  # sets per pass of the filtered path: (chunk, 20, 6) arrays of a few MB
# A double evaluation of N . p - N . a (N rounded once to a double, three products and sums a side, one difference)
# is within ~6 units of 2**-53 of the sum of its terms' magnitudes; 2**-48 is five times that.
SMALL_HULL_SIGN_BOUND = 2.0**-48


def _small_hulls_filtered(P: np.ndarray, *, width: int, grid) -> list[ConvexHull | None]:
    """:func:`small_hulls` for sets whose local extent E fits ``SMALL_HULLS_FILTERED_EXTENT`` but not int64 distances.

    Every candidate plane through three of a set's points has an exact int64 normal N (|N| <= 2 (2E)^2 < 2**62);
    the signed distances N . (p - a) of the set's points (up to ~2**91) are evaluated in doubles with a certified
    bound (:data:`SMALL_HULL_SIGN_BOUND` x the sum of the terms' magnitudes) and exactly, in
    Python integers, only where the double is within its bound (and set to zero, exactly, for the plane's own three
    points). The kept facets' offsets are exact Python integers; the planes and points are those the int64 path
    (and :func:`convex_hull`) gives.
    """
    m, k = P.shape[0], P.shape[1]
    if m == 0:
        return []
    origin = P[:, 0, :]
    L = P - origin[:, None, :]
    tri = np.array([(a, b, c) for a in range(k) for b in range(a + 1, k) for c in range(b + 1, k)])
    t = tri.shape[0]
    Ai, Aj, Ak = L[:, tri[:, 0]], L[:, tri[:, 1]], L[:, tri[:, 2]]  # (m, t, 3), |.| <= E
    N = _cross(Aj - Ai, Ak - Ai)  # exact int64
    Nf, Lf, Af = N.astype(np.float64), L.astype(np.float64), Ai.astype(np.float64)
    Sf = np.einsum("mtc,mpc->mtp", Nf, Lf) - np.einsum("mtc,mtc->mt", Nf, Af)[:, :, None]
    bound = SMALL_HULL_SIGN_BOUND * (np.einsum("mtc,mpc->mtp", np.abs(Nf), np.abs(Lf))
                                     + np.einsum("mtc,mtc->mt", np.abs(Nf), np.abs(Af))[:, :, None])
    sign = np.sign(Sf).astype(np.int8)
    unsure = np.abs(Sf) <= bound
    own = np.zeros((t, k), bool)
    own[np.arange(t)[:, None], tri] = True  # a plane's own three points: distance zero by construction
    sign[:, own] = 0
    unsure[:, own] = False
    hm, ht, hp = np.nonzero(unsure)
    if hm.size:  # exact: Python integers for the close calls only
        Nh = N[hm, ht].astype(object)
        Dh = (L[hm, hp] - Ai[hm, ht]).astype(object)
        exact = (Nh * Dh).sum(axis=1)
        sign[hm, ht, hp] = np.array([(v > 0) - (v < 0) for v in exact.tolist()], np.int8)
    below = np.all(sign <= 0, axis=2)
    above = np.all(sign >= 0, axis=2)
    real = np.any(N != 0, axis=2) & ~np.all(sign == 0, axis=2)
    keep = real & (below | above)
    N = N * np.where(below, 1, -1)[:, :, None]
    g = np.gcd.reduce(np.abs(N), axis=2)
    N = N // np.where(g == 0, 1, g)[:, :, None]
    mid, tid = np.nonzero(keep)
    # one supporting plane per outward normal: dedupe on (set, normal), the offsets follow
    key = np.column_stack([mid, N[mid, tid]])
    key, first_row = np.unique(key, axis=0, return_index=True)
    mid, tid = mid[first_row], tid[first_row]
    Nk, Ak_ = N[mid, tid], Ai[mid, tid]  # |N| < 2**62, |A| <= 2**29
    hi_part, lo_part = Nk >> 31, Nk & ((1 << 31) - 1)  # N = hi 2**31 + lo, each product below 2**61
    d_hi = -(hi_part * Ak_).sum(axis=1)
    d_lo = -(lo_part * Ak_).sum(axis=1)
    starts = np.searchsorted(mid, np.arange(m + 1))
    points, first, lo, hi = _unique_rows_per_set(np.ascontiguousarray(L))
    lo += origin
    hi += origin
    # Each set's offsets as int64 when every one fits, decided in bulk: wherever |d| < 2**83, d_hi (< 2**52) converts
    # exactly, so the double of d = d_hi 2**31 + d_lo is within 2**8 (d_lo) + 2**11 (the sum, below 2**65) of it, and
    # beyond that it is far above 2**63: one beyond 2**63 + 2**12 does not fit, one within 2**63 - 2**12 does -- and
    # then the int64 sum, wrapping mod 2**64 on the way, is d exactly. A set with a value between asks _maybe_int64:
    # the same arrays as it gives every set, without its max over each set's Python ints.
    df = np.abs(d_hi.astype(np.float64) * float(1 << 31) + d_lo.astype(np.float64))
    d64 = d_hi * (1 << 31) + d_lo
    state = np.where(df <= 2.0**63 - 2.0**12, 0, np.where(df >= 2.0**63 + 2.0**12, 2, 1))  # fits, unsure, not
    set_state = np.zeros(m, np.int64)
    if mid.size:
        np.maximum.at(set_state, mid, state)
    # the offsets as Python ints only when some set needs them (a drill's prisms: none)
    d = d_hi.astype(object) * (1 << 31) + d_lo.astype(object) if np.any(set_state) else None
    out: list[ConvexHull | None] = []
    for h in range(m):
        a, b = starts[h], starts[h + 1]
        if b - a < 4:  # flat: no supporting plane with a point strictly behind
            out.append(None)
            continue
        if set_state[h] == 0:
            offsets = d64[a:b]
        elif set_state[h] == 1:
            offsets = _maybe_int64(d[a:b])
        else:
            offsets = d[a:b]
        out.append(ConvexHull(points[first[h]:first[h + 1]], origin[h].copy(), np.ascontiguousarray(Nk[a:b]),
                              offsets, width=width, grid=grid, box=(lo[h].copy(), hi[h].copy())))
    return out


@jit
def _unique_rows_per_set(L):
    """The distinct rows of each set ``L[h]`` (``L`` (m, k, 3) int64) in lexicographic order, as :func:`_unique_rows`
    gives them, for all sets in one compiled pass (an insertion sort of k <= 10 rows each): ``points`` (total, 3),
    ``first`` (m + 1,) with set h's rows at ``points[first[h]:first[h + 1]]``, and each set's box ``lo``, ``hi``
    (m, 3). A drill's 80,640 prisms took 0.95 s in per-set NumPy calls."""
    m, k = L.shape[0], L.shape[1]
    points = np.empty((m * k, 3), np.int64)
    first = np.zeros(m + 1, np.int64)
    lo = np.empty((m, 3), np.int64)
    hi = np.empty((m, 3), np.int64)
    at = 0
    for h in range(m):
        n = 0
        for i in range(k):
            x, y, z = L[h, i, 0], L[h, i, 1], L[h, i, 2]
            j = n
            duplicate = False
            while j > 0:
                p = at + j - 1
                if points[p, 0] == x and points[p, 1] == y and points[p, 2] == z:
                    duplicate = True
                    break
                if points[p, 0] < x or (points[p, 0] == x and (points[p, 1] < y or (points[p, 1] == y
                                                                                      and points[p, 2] < z))):
                    break
                j -= 1
            if duplicate:
                continue
            for q in range(at + n, at + j, -1):
                points[q, 0], points[q, 1], points[q, 2] = points[q - 1, 0], points[q - 1, 1], points[q - 1, 2]
            points[at + j, 0], points[at + j, 1], points[at + j, 2] = x, y, z
            n += 1
        for c in range(3):
            lo[h, c] = L[h, 0, c]
            hi[h, c] = L[h, 0, c]
            for i in range(1, k):
                lo[h, c] = min(lo[h, c], L[h, i, c])
                hi[h, c] = max(hi[h, c], L[h, i, c])
        at += n
        first[h + 1] = at
    return points[:at], first, lo, hi


