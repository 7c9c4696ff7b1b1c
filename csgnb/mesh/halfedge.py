"""Convex polytopes as a flat half-edge store with exact homogeneous vertices (paper §3.3).

Many convex polytopes live in one :class:`MeshStore`; a polytope is named by any of
its half-edges (a *cell handle*). Cutting (:mod:`csgnb.mesh.cutting`) splits a
polytope in place into two, so handles of other polytopes stay valid.

Arrays (``int32`` unless noted; rows ``[:counts[NV]]`` etc. are in use):

* ``palette`` ``(m, 4)`` wide -- the exact planes every face refers to;
* ``vx`` ``(V, 4)`` wide -- homogeneous vertices (x1, x2, x3, x4) as built by
  ``intersect_3_planes``, never rounded; the point is (x1, x2, x3) / x4;
* ``he`` ``(H, 4)`` -- half-edge columns ``NEXT`` (next half-edge of the face,
  counter-clockwise seen from outside), ``TWIN``, ``VERT`` (origin vertex), ``FACE``;
* ``fc`` ``(F, 3)`` -- face columns ``PLANE`` (palette row ``k``, or ``~k`` when the
  face's outward normal is the row's negated normal), ``HE`` (one of its half-edges),
  ``OPP`` (the BSP node on the other side of the face, ``-1`` outside the domain);
* ``vmark`` ``(V,)`` int64 -- classification cache: ``stamp * 4 + side + 1`` of the
  cut that last classified the vertex;
* ``vdf`` ``(V, 2)`` float64 -- the filter doubles (:func:`csgnb.exact.lowering.filter_double`)
  of x·s, with the cut plane that classified the vertex (valid with its ``vmark`` stamp),
  and of x4: the descent's distance comparisons convert each wide value once per cut, not
  once per comparison, and form the exact products again only for close calls;
* ``hmark`` ``(H,)`` int64 -- traversal stamps;
* ``counts`` int64 -- ``NV, NH, NF`` (rows ever used: the high-water marks), ``STAMP``
  (cut counter), ``N_CLASSIFY``, ``N_CONSTRUCT`` (statistics), ``NP`` (palette rows in
  use), ``FREE_V, FREE_H, FREE_F`` (lengths of the free lists);
* ``free_v`` ``(V,)``, ``free_h`` ``(H,)``, ``free_f`` ``(F,)`` int32 -- rows of released
  polytopes, reused before the high-water mark grows (:func:`release_cell`), so a long
  extraction or merge that discards cells keeps a small, cache-resident store;
* ``loop`` ``(L, 5)`` int64 -- a cut's scratch: per vertex of the cut loop its row
  (``LOOP_V``), the loop half-edge (``LOOP_H``), its copy in the positive part
  (``LOOP_C``) and the two cap half-edges (``LOOP_M``, ``LOOP_P``).

All of them travel together as one :class:`MeshArrays` named tuple: kernels take
``m`` and read ``m.he[h, NEXT]``; every kernel called per cut or per vertex is inlined,
so the tuple costs nothing (a call that is not inlined would reference-count each array).

Faces are outward: the polytope lies on the negative side of every face plane.
"""

from __future__ import annotations

from fractions import Fraction
from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb._resumable import grown
from csgnb._views import unmanaged_tuple
from csgnb.errors import GeometryError
from csgnb.exact.budgets import budget, check_planes
from csgnb.exact.intrinsics import classify_at, intersect_into
from csgnb.exact.predicates import to_double_position
from csgnb.exact.wide import from_wide, is_wide, to_wide, width_of

__all__ = ["MeshArrays", "MeshStore", "NEXT", "TWIN", "VERT", "FACE", "PLANE", "HE", "OPP", "release_cell"]

NEXT, TWIN, VERT, FACE = 0, 1, 2, 3
PLANE, HE, OPP = 0, 1, 2
NV, NH, NF, STAMP, N_CLASSIFY, N_CONSTRUCT, NP, FREE_V, FREE_H, FREE_F = range(10)
LOOP_V, LOOP_H, LOOP_C, LOOP_M, LOOP_P = range(5)
N_COUNTS = 16


class MeshArrays(NamedTuple):
    """The arrays of a :class:`MeshStore`, as one argument for kernels (see the module docstring).

    palette : (P, 4) wide; vx : (V, 4) wide; vdf : (V, 2) float64; vmark : (V,) int64;
    he : (H, 4) int32; hmark : (H,) int64; fc : (F, 3) int32; counts : (16,) int64;
    free_v : (V,) int32; free_h : (H,) int32; free_f : (F,) int32; loop : (L, 5) int64.
    """

    palette: np.ndarray
    vx: np.ndarray
    vdf: np.ndarray
    vmark: np.ndarray
    he: np.ndarray
    hmark: np.ndarray
    fc: np.ndarray
    counts: np.ndarray
    free_v: np.ndarray
    free_h: np.ndarray
    free_f: np.ndarray
    loop: np.ndarray


def new_mesh_arrays(palette: np.ndarray, vertices: int, loop: int = 64) -> MeshArrays:
    """Empty arrays for ``vertices`` vertex rows (4x as many half-edges, 2x faces) over ``palette`` (copied)."""
    v = max(int(vertices), 64)
    dtype = palette.dtype
    pal = np.zeros((max(2 * palette.shape[0], 16), 4), dtype)
    pal[: palette.shape[0]] = palette
    counts = np.zeros(N_COUNTS, np.int64)
    counts[NP] = palette.shape[0]
    return MeshArrays(pal, np.zeros((v, 4), dtype), np.zeros((v, 2)), np.zeros(v, np.int64),
                      np.full((4 * v, 4), -1, np.int32), np.zeros(4 * v, np.int64), np.full((2 * v, 3), -1, np.int32),
                      counts, np.empty(v, np.int32), np.empty(4 * v, np.int32), np.empty(2 * v, np.int32),
                      np.empty((max(int(loop), BOX_HALFEDGES), 5), np.int64))


def grown_mesh_arrays(m: MeshArrays, vertices: int, halfedges: int, faces: int, loop: int = 0,
                      planes: int = 0) -> MeshArrays:
    """``m`` with room for at least this many *more* vertices, half-edges, faces, loop rows and palette rows.

    Arrays that are large enough are kept (the same objects); the others are copied into
    geometrically larger ones.
    """
    c = m.counts
    pal, vx, vdf, vmark, free_v = m.palette, m.vx, m.vdf, m.vmark, m.free_v
    he, hmark, free_h, fc, free_f, lp = m.he, m.hmark, m.free_h, m.fc, m.free_f, m.loop
    if c[NP] + planes > pal.shape[0]:
        pal = grown(pal, max(2 * pal.shape[0], int(c[NP]) + planes))
    if c[NV] - c[FREE_V] + vertices > vx.shape[0]:
        size = max(2 * vx.shape[0], int(c[NV] - c[FREE_V]) + vertices)
        # New rows of the stamp arrays must hold no stamp: a traversal or classification cache that
        # met a leftover value equal to a future stamp would skip a half-edge or reuse a stale side.
        vx, vdf, vmark = grown(vx, size, 0), grown(vdf, size, 0), grown(vmark, size, 0)
        free_v = grown(free_v, size)
    if c[NH] - c[FREE_H] + halfedges > he.shape[0]:
        size = max(2 * he.shape[0], int(c[NH] - c[FREE_H]) + halfedges)
        he, hmark, free_h = grown(he, size, -1), grown(hmark, size, 0), grown(free_h, size)
    if c[NF] - c[FREE_F] + faces > fc.shape[0]:
        size = max(2 * fc.shape[0], int(c[NF] - c[FREE_F]) + faces)
        fc, free_f = grown(fc, size, -1), grown(free_f, size)
    if loop > lp.shape[0]:
        lp = np.empty((max(2 * lp.shape[0], loop), 5), np.int64)
    return MeshArrays(pal, vx, vdf, vmark, he, hmark, fc, c, free_v, free_h, free_f, lp)

# A cube: vertex k has coordinates (k & 1, k >> 1 & 1, k >> 2 & 1) in {lo, hi};
# faces listed counter-clockwise seen from outside, with the palette row of their plane.
_CUBE_FACES = (
    (0, (0, 4, 6, 2)),  # x = lo, plane (-1, 0, 0, lo)
    (1, (1, 3, 7, 5)),  # x = hi, plane (1, 0, 0, -hi)
    (2, (0, 1, 5, 4)),  # y = lo
    (3, (2, 6, 7, 3)),  # y = hi
    (4, (0, 2, 3, 1)),  # z = lo
    (5, (4, 5, 7, 6)),  # z = hi
)


def box_planes(lo, hi, width: int) -> np.ndarray:
    """Return the six outward planes of the box ``[lo, hi]`` (integer corners) as a ``(6, 4)`` wide array.

    Row order: x = lo, x = hi, y = lo, y = hi, z = lo, z = hi.
    """
    lo = [int(v) for v in np.asarray(lo).reshape(3)]
    hi = [int(v) for v in np.asarray(hi).reshape(3)]
    if any(a >= b for a, b in zip(lo, hi, strict=True)):
        raise GeometryError(f"box needs lo < hi in every coordinate, got lo={lo}, hi={hi}")
    rows = []
    for axis in range(3):
        n = [0, 0, 0]
        n[axis] = -1
        rows.append([*n, lo[axis]])
        n = [0, 0, 0]
        n[axis] = 1
        rows.append([*n, -hi[axis]])
    if max(max(map(abs, lo)), max(map(abs, hi))) < _INT64_CORNER:
        # to_wide's vectorised int64 path: a merge from Python made its six rows through Python ints (~35 us)
        return to_wide(np.array(rows, np.int64), width)
    return to_wide(rows, width)


_INT64_CORNER = 1 << 62


# Inlined: called per half-edge step inside the cutting kernels (see csgnb.mesh.cutting).
@jit(inline="always")
def _rot(he, h):
    """The next outgoing half-edge around the origin of ``h``."""
    # Unsigned row indices: numba wraps a signed index around (sar, and, add on every hop of a walk).
    return he[np.uint64(he[np.uint64(h), TWIN]), NEXT]


@jit(inline="always")
def halfedge_dest(he, h):
    return he[np.uint64(he[np.uint64(h), NEXT]), VERT]


@jit(inline="always")
def face_plane_row(fc, f):
    p = fc[np.uint64(f), PLANE]
    return p if p >= 0 else ~p


@jit(inline="always")
def _new_stamp(counts):
    counts[STAMP] += 1
    return counts[STAMP]


@jit(inline="always")
def _new_vertex(m):
    """A free vertex row: a released one if any, else the next unused row (capacity checked by the caller)."""
    c = m.counts
    if c[FREE_V] > 0:
        c[FREE_V] -= 1
        return np.int64(m.free_v[c[FREE_V]])
    v = c[NV]
    c[NV] += 1
    return v


@jit(inline="always")
def _new_halfedge(m):
    c = m.counts
    if c[FREE_H] > 0:
        c[FREE_H] -= 1
        return np.int64(m.free_h[c[FREE_H]])
    h = c[NH]
    c[NH] += 1
    return h


@jit(inline="always")
def _new_face(m):
    c = m.counts
    if c[FREE_F] > 0:
        c[FREE_F] -= 1
        return np.int64(m.free_f[c[FREE_F]])
    f = c[NF]
    c[NF] += 1
    return f


@jit(inline="always")
def room_for_cut(m, faces):
    """Whether ``m`` can take one cut of a polytope with at most ``faces`` faces.

    A cut creates at most 2 vertices, 6 half-edges and 1 face per face of the polytope,
    plus two caps; the loop scratch needs a row per face.
    """
    c = m.counts
    need = faces + 2
    return (m.vx.shape[0] - c[NV] + c[FREE_V] >= 2 * need
            and m.he.shape[0] - c[NH] + c[FREE_H] >= 6 * need + 2
            and m.fc.shape[0] - c[NF] + c[FREE_F] >= need + 2
            and m.loop.shape[0] >= need)


@jit(inline="always")
def release_cell(m, h0):
    """Put every vertex, half-edge and face of the polytope of ``h0`` on the free lists; return its half-edge count.

    The traversal queue is the free list of half-edges itself (released half-edges are
    exactly the ones visited), so no scratch is needed. Each vertex and face belongs to
    one polytope (cuts copy the loop's vertices), so each is released once: faces
    through their recorded half-edge, vertices through a release stamp in ``vmark``.
    """
    he = m.he
    c = m.counts
    stamp = _new_stamp(c)
    released = -stamp - 1  # never a classification entry (those are >= 0)
    base = c[FREE_H]
    top = base
    m.free_h[top] = h0
    m.hmark[h0] = stamp
    top += 1
    i = base
    while i < top:
        h = np.int64(m.free_h[i])
        i += 1
        g = np.int64(he[h, NEXT])
        if m.hmark[g] != stamp:
            m.hmark[g] = stamp
            m.free_h[top] = g
            top += 1
        g = np.int64(he[h, TWIN])
        if m.hmark[g] != stamp:
            m.hmark[g] = stamp
            m.free_h[top] = g
            top += 1
        f = np.int64(he[h, FACE])
        if m.fc[f, HE] == h:
            m.free_f[c[FREE_F]] = f
            c[FREE_F] += 1
        v = np.int64(he[h, VERT])
        if m.vmark[v] != released:
            m.vmark[v] = released
            m.free_v[c[FREE_V]] = v
            c[FREE_V] += 1
    c[FREE_H] = top
    return top - base


@jit
def _release_cell_kernel(m, h0):
    return release_cell(unmanaged_tuple(m), h0)


@jit
def collect_cell_halfedges(he, hmark, counts, h0, out):
    """Write every half-edge of the polytope of ``h0`` into ``out``; return how many."""
    stamp = _new_stamp(counts)
    n = 0
    out[0] = h0
    hmark[h0] = stamp
    n = 1
    i = 0
    while i < n:
        h = np.uint64(out[i])  # unsigned: no wrap-around of a negative index on every step of the walk
        i += 1
        for g in (he[h, NEXT], he[h, TWIN]):
            if hmark[np.uint64(g)] != stamp:
                hmark[np.uint64(g)] = stamp
                out[n] = g
                n += 1
    return n


_CUBE_CYCLES = np.array([cycle for _, cycle in _CUBE_FACES], np.int64)

BOX_HALFEDGES = 24
"""Half-edges of a box cell; the loop scratch has at least this many rows (:func:`add_box_cell` uses it)."""


def _cube_twins(cycles: np.ndarray) -> np.ndarray:
    """For each of the box's 24 directed edges (4 f + i: corner i to i + 1 of face f), the edge running back."""
    index = {(int(cycles[f, i]), int(cycles[f, (i + 1) % 4])): 4 * f + i for f in range(6) for i in range(4)}
    return np.array([index[(int(cycles[f, (i + 1) % 4]), int(cycles[f, i]))] for f in range(6) for i in range(4)],
                    np.int64)


_CUBE_TWINS = _cube_twins(_CUBE_CYCLES)


@jit(inline="always")
def add_box_cell(m, rows, opp):
    """Build the box with outward palette planes ``rows`` (x lo, x hi, y lo, y hi, z lo, z hi); return a handle.

    Rows come from the free lists when possible; the caller checked room for 8 vertices,
    24 half-edges and 6 faces. The new rows are held in the loop scratch while the box is
    wired (no cut runs meanwhile): nothing is allocated, so kernels compiled without
    reference counting can build boxes.
    """
    scratch = m.loop
    for k in range(8):
        v = _new_vertex(m)
        scratch[k, 0] = v
        intersect_into(m.palette, rows[(k & 1)], m.palette, rows[2 + ((k >> 1) & 1)], m.palette,
                       rows[4 + ((k >> 2) & 1)], m.vx, v)
        m.vmark[v] = 0
    for i in range(BOX_HALFEDGES):
        scratch[i, 1] = _new_halfedge(m)
    for f in range(6):
        face = _new_face(m)
        m.fc[face, PLANE] = rows[f]
        m.fc[face, HE] = scratch[4 * f, 1]
        m.fc[face, OPP] = opp
        for i in range(4):
            h = scratch[4 * f + i, 1]
            m.he[h, NEXT] = scratch[4 * f + (i + 1) % 4, 1]
            m.he[h, VERT] = scratch[_CUBE_CYCLES[f, i], 0]
            m.he[h, FACE] = face
            m.he[h, TWIN] = scratch[_CUBE_TWINS[4 * f + i], 1]
    return scratch[0, 1]


@jit
def _add_box_kernel(m, rows, opp):
    return add_box_cell(unmanaged_tuple(m), rows, opp)


class MeshStore:
    """Flat storage for many exact convex polytopes (see the module docstring).

    Parameters
    ----------
    palette : (m, 4) wide
        Planes the polytopes' faces and cuts refer to; more can be added with
        :meth:`add_planes`. All planes together must stay within the budget of
        their width (checked).
    capacity : int
        Initial number of vertex rows; the store grows as needed.
    """

    def __init__(self, palette: np.ndarray, capacity: int = 1024) -> None:
        if not (is_wide(palette) and palette.ndim == 2 and palette.shape[1] == 4):
            raise GeometryError(f"palette must be an (m, 4) wide array of planes, got shape {np.shape(palette)}")
        self.width = width_of(palette)
        # Upper bounds (N, D) on the normals and offsets of the palette's rows: each add_planes checks the new
        # rows with them (the budget's bounds are joint in N and D) instead of re-scanning the whole palette.
        self._bounds = check_planes(palette, "palette") if palette.shape[0] else (0, 0)
        self.m = new_mesh_arrays(palette, capacity)

    # The arrays, by name (kernels take ``self.m`` whole).
    palette = property(lambda self: self.m.palette)
    vx = property(lambda self: self.m.vx)
    vdf = property(lambda self: self.m.vdf)
    vmark = property(lambda self: self.m.vmark)
    he = property(lambda self: self.m.he)
    hmark = property(lambda self: self.m.hmark)
    fc = property(lambda self: self.m.fc)
    counts = property(lambda self: self.m.counts)

    # -- capacity -----------------------------------------------------------

    def reserve(self, vertices: int, halfedges: int, faces: int, loop: int = 0) -> None:
        """Make room for at least this many *more* vertices, half-edges and faces (and loop rows)."""
        self.m = grown_mesh_arrays(self.m, vertices, halfedges, faces, loop)

    def add_planes(self, planes: np.ndarray) -> np.ndarray:
        """Append ``(k, 4)`` wide planes to the palette; return their rows ``(k,) int64``."""
        planes = np.atleast_2d(planes)
        if width_of(planes) != self.width:
            raise GeometryError(f"planes are {width_of(planes)}-bit but the store is {self.width}-bit")
        np_ = int(self.counts[NP])
        if planes.shape[0]:
            n_new, d_new = check_planes(planes, "palette")
            N, D = max(self._bounds[0], n_new), max(self._bounds[1], d_new)
            if budget(self.width).plane_violations(N, D):
                # the bounds of two checks are not the exact maxima: the whole palette decides (and names the rows)
                N, D = check_planes(np.concatenate([self.palette[:np_], planes]), "palette")
            self._bounds = (N, D)
        self.m = grown_mesh_arrays(self.m, 0, 0, 0, planes=planes.shape[0])
        self.palette[np_ : np_ + planes.shape[0]] = planes
        self.counts[NP] = np_ + planes.shape[0]
        return np.arange(np_, np_ + planes.shape[0])

    def release(self, cell: int) -> int:
        """Free the rows of polytope ``cell`` for reuse (its handles become invalid); return its half-edge count."""
        return int(_release_cell_kernel(self.m, int(cell)))

    @property
    def planes(self) -> np.ndarray:
        """The palette rows in use, ``(m, 4)`` wide (a view)."""
        return self.palette[: int(self.counts[NP])]

    # -- construction -------------------------------------------------------

    def add_box(self, lo, hi, opp: int = -1) -> int:
        """Add the box ``[lo, hi]`` (integer corners) as a polytope; return its cell handle.

        The six box planes are appended to the palette; every face gets ``opp``.
        """
        rows = self.add_planes(box_planes(lo, hi, self.width))
        self.reserve(8, 24, 6)
        return int(_add_box_kernel(self.m, rows.astype(np.int64), int(opp)))

    # -- inspection ---------------------------------------------------------

    def cell_halfedges(self, cell: int) -> np.ndarray:
        """Return the half-edges ``(k,) int32`` of the polytope named by ``cell``."""
        out = np.empty(int(self.counts[NH]), np.int32)
        n = collect_cell_halfedges(self.he, self.hmark, self.counts, int(cell), out)
        return out[:n]

    def cell_faces(self, cell: int) -> list[list[int]]:
        """Return the faces of a polytope as lists of half-edges, counter-clockwise from outside."""
        faces: dict[int, list[int]] = {}
        for h in self.cell_halfedges(cell):
            f = int(self.he[h, FACE])
            if f in faces:
                continue
            cycle, g = [], int(self.fc[f, HE])
            while True:
                cycle.append(g)
                g = int(self.he[g, NEXT])
                if g == cycle[0]:
                    break
                if len(cycle) > self.he.shape[0]:
                    raise GeometryError(f"face {f} does not close: the half-edge structure is corrupt")
            faces[f] = cycle
        return list(faces.values())

    def cell_vertices(self, cell: int) -> np.ndarray:
        """Return the vertex rows ``(k,) int64`` of a polytope, sorted."""
        return np.unique(self.he[self.cell_halfedges(cell), VERT].astype(np.int64))

    def face_polygons(self, cell: int) -> tuple[list[int], list[list[int]]]:
        """Return (face ids, vertex rows per face) of a polytope, counter-clockwise from outside."""
        faces = self.cell_faces(cell)
        return [int(self.he[c[0], FACE]) for c in faces], [[int(self.he[h, VERT]) for h in c] for c in faces]

    # Named reads of the topology columns, for notebooks and callers outside the kernels (which index ``he``
    # and ``fc`` directly). Each takes an int or an integer array and returns the same shape, ``int64``.

    def next_halfedge(self, h):
        """Return the half-edge after ``h`` around its face (counter-clockwise seen from outside)."""
        return self._column(self.he, h, NEXT)

    def twin(self, h):
        """Return the half-edge opposite ``h`` (same edge, other face, other direction)."""
        return self._column(self.he, h, TWIN)

    def origin(self, h):
        """Return the vertex row ``h`` starts at."""
        return self._column(self.he, h, VERT)

    def face_of(self, h):
        """Return the face ``h`` belongs to."""
        return self._column(self.he, h, FACE)

    def face_plane(self, f, *, signed: bool = False):
        """Return the palette row of face ``f``'s plane; ``signed=True`` gives ``~row`` for a flipped face."""
        p = self._column(self.fc, f, PLANE)
        if signed:
            return p
        return np.where(p >= 0, p, ~p) if np.ndim(p) else (p if p >= 0 else ~p)

    def face_halfedge(self, f):
        """Return one half-edge of face ``f``."""
        return self._column(self.fc, f, HE)

    def face_opposite(self, f):
        """Return the BSP node on the other side of face ``f`` (``-1``: outside the domain)."""
        return self._column(self.fc, f, OPP)

    @property
    def classifications(self) -> int:
        """How many vertex classifications the cuts on this store have made (a statistic)."""
        return int(self.counts[N_CLASSIFY])

    @property
    def constructions(self) -> int:
        """How many vertices the cuts on this store have built (a statistic)."""
        return int(self.counts[N_CONSTRUCT])

    @staticmethod
    def _column(table, rows, column):
        if np.ndim(rows) == 0:
            return int(table[int(rows), column])
        return table[np.asarray(rows, np.int64), column].astype(np.int64)

    def exact_vertices(self, rows) -> list[tuple[Fraction, Fraction, Fraction]]:
        """Return the Cartesian positions of vertex ``rows`` as exact Fractions."""
        ints = from_wide(self.vx[np.asarray(rows, np.int64)])
        return [tuple(Fraction(int(x[i]), int(x[3])) for i in range(3)) for x in ints]

    def positions(self, rows) -> np.ndarray:
        """Return the positions of vertex ``rows`` correctly rounded to doubles, ``(k, 3) float64``."""
        return to_double_position(self.vx[np.asarray(rows, np.int64)])

    def exact_volume(self, cell: int) -> Fraction:
        """Return the exact volume of a polytope as a Fraction (divergence theorem over its faces)."""
        _, polys = self.face_polygons(cell)
        rows = sorted({v for p in polys for v in p})
        pos = dict(zip(rows, self.exact_vertices(rows), strict=True))
        return polygons_volume([[pos[v] for v in p] for p in polys])

    def to_polydata(self, cells):
        """Return the polytopes ``cells`` as one pyvista ``PolyData`` (float positions, for display).

        Cell data ``"cell"`` says which polytope a face belongs to, ``"plane"`` its palette row.
        """
        import pyvista as pv

        cells = [int(c) for c in np.atleast_1d(cells)]
        points, faces, owner, planes = [], [], [], []
        base = 0
        for k, cell in enumerate(cells):
            fids, polys = self.face_polygons(cell)
            rows = sorted({v for p in polys for v in p})
            where = {v: base + i for i, v in enumerate(rows)}
            points.append(self.positions(rows))
            for f, p in zip(fids, polys, strict=True):
                faces.append([len(p), *(where[v] for v in p)])
                owner.append(k)
                plane = int(self.fc[f, PLANE])
                planes.append(plane if plane >= 0 else ~plane)
            base += len(rows)
        mesh = pv.PolyData(np.concatenate(points), np.concatenate(faces))
        mesh.cell_data["cell"] = np.asarray(owner)
        mesh.cell_data["plane"] = np.asarray(planes)
        return mesh

    def check_cell(self, cell: int) -> None:
        """Raise :class:`GeometryError` unless the polytope is a closed, strictly convex, consistent mesh.

        Checked exactly: twins pair up with opposite directions; every face has >= 3
        vertices, all on its plane; every vertex of the polytope lies on or inside every
        face plane; adjacent faces have different planes; every vertex has degree >= 3.
        """
        hs = self.cell_halfedges(cell)
        he = self.he
        for h in hs:
            t = he[h, TWIN]
            if he[t, TWIN] != h or he[he[t, NEXT], VERT] != he[h, VERT] or he[he[h, NEXT], VERT] != he[t, VERT]:
                raise GeometryError(f"half-edge {h} and its twin {t} do not run in opposite directions")
            if he[h, FACE] == he[t, FACE]:
                raise GeometryError(f"half-edge {h} has its twin in the same face")
            if face_plane_row(self.fc, he[h, FACE]) == face_plane_row(self.fc, he[t, FACE]):
                raise GeometryError(f"faces {he[h, FACE]} and {he[t, FACE]} are adjacent and coplanar")
        fids, polys = self.face_polygons(cell)
        verts = np.unique([v for p in polys for v in p])
        degree = {int(v): 0 for v in verts}
        for h in hs:
            degree[int(he[h, VERT])] += 1
        low = [v for v, d in degree.items() if d < 3]
        if low:
            raise GeometryError(f"vertices {low[:5]} have degree < 3")
        for f, p in zip(fids, polys, strict=True):
            if len(p) < 3 or len(set(p)) != len(p):
                raise GeometryError(f"face {f} has vertices {p}")
            row = face_plane_row(self.fc, f)
            flip = -1 if self.fc[f, PLANE] < 0 else 1
            sides = _classify_rows(self.vx, verts, self.palette, row) * flip
            on = set(int(v) for v in verts[sides == 0])
            if not set(p) <= on:
                raise GeometryError(f"face {f} has vertices off its plane")
            if np.any(sides > 0):
                raise GeometryError(f"the polytope is not convex: a vertex lies outside face {f}")


def polygons_volume(polygons) -> Fraction:
    """Return the exact signed volume enclosed by closed, outward polygons of Fraction points."""
    total = Fraction(0)
    for poly in polygons:
        a = poly[0]
        for b, c in zip(poly[1:-1], poly[2:], strict=True):
            total += (
                a[0] * (b[1] * c[2] - b[2] * c[1])
                - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])
            )
    return total / 6


@jit
def _intersect_rows(palette, p, q, r, vx, out_row):
    intersect_into(palette, p, palette, q, palette, r, vx, out_row)


@jit
def _classify_rows_kernel(vx, rows, palette, plane, out):
    for i in range(rows.shape[0]):
        out[i] = classify_at(vx, rows[i], palette, plane)


def _classify_rows(vx, rows, palette, plane) -> np.ndarray:
    out = np.empty(len(rows), np.int8)
    _classify_rows_kernel(vx, np.asarray(rows, np.int64), palette, int(plane), out)
    return out.astype(np.int64)
