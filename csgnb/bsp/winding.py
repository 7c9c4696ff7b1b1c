"""Meshes that overlap or fold: the solid a closed triangle mesh winds around, exactly.

:func:`csgnb.bsp.build.validate_mesh` refuses a mesh whose parts overlap, cross or fold
back (an edge shared by faces that do not alternate in and out, faces that cross). Such
meshes are common among inputs written by others: a float mesh that was a valid solid
(the union that manifold3d returns for a drill's sweep volume) folds in places once its
vertices are rounded onto a grid, and a file may hold overlapping parts meant as their
union. For a mesh that is *closed as a cycle* -- every edge run as often one way as the
other -- the **winding number** ``w(x)`` (how many times the surface wraps around the
point ``x``, counted with orientation) is defined everywhere off the surface, and
``fill="winding"`` takes the solid ``{x : w(x) > 0}``: overlaps count once (their union),
folded-over slivers (``w <= 0``) are empty, a mesh that is a valid solid gives that solid.

The construction is exact and ends in the ordinary import (paper §3.6): it builds the
boundary of that solid as plane-based polygons over the mesh's own palette
(:func:`winding_boundary`), and :func:`csgnb.bsp.build.bsp_from_polygons` imports it.

* A face that no other face crosses or touches away from their shared corners and edge
  (:func:`csgnb.bsp.build.self_intersections`) sees one winding number just in front of it
  all along, and one more just behind: it is on the boundary, as it is, exactly when the
  value in front is 0. Faces joined across an edge of exactly two faces see the same space
  in front, so the value is counted once per such patch: the signed crossings of a segment
  from a face's centroid to a far point in front (exact integer orientation tests, another
  direction when the segment meets an edge or a corner).
* A face that is crossed is split by the planes of the faces that cross it (by the edge
  planes of those lying on its own plane), exactly, as homogeneous Python integers; no
  face crosses the inside of a piece, so each piece is on the boundary or not as a whole:
  the winding number just in front of its centroid is counted as above (doubles with a
  certified error bound decide each face they can; the centroid's own plane and close calls
  are decided in integers), the one behind differs by the faces on its plane that hold the
  centroid. A boundary piece is kept facing
  out of the solid, once where coplanar faces overlap.

Every polygon's support and edges are planes of the mesh's triangles, so nothing leaves
the width's budget; the pieces' vertices are checked as every import's are.
"""

from __future__ import annotations

from math import gcd, lcm

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from csgnb._jit import jit
from csgnb.bsp.build import (
    _describe_edge,
    _shell_windings,
    bsp_from_polygons,
    check_label,
    check_seed,
    half_edges,
    repaired_mesh,
    self_intersections,
)
from csgnb.bsp.polygon import PolygonSet, polygons_from_triangles
from csgnb.bsp.tree import BSPTree
from csgnb.errors import GeometryError, InternalError
from csgnb.exact.wide import DEFAULT_WIDTH, from_wide, to_wide, wide_dtype

__all__ = ["FILLS", "check_fill", "winding_boundary", "winding_bsp"]

FILLS = ("solid", "winding")
"""How a triangle mesh becomes a solid: ``"solid"`` (the default) accepts only a mesh that bounds a solid
(closed, edge-manifold, outward, not self-intersecting, properly nested) and refuses anything else, naming the
defect; ``"winding"`` takes the points its closed surface winds around positively (overlaps as their union, folds
removed), exact, for meshes that overlap or fold."""

_RETRIES = 64  # segment directions tried before a point counts as undecidable (a bug: every point has good ones)


def check_fill(fill) -> str:
    if fill not in FILLS:
        raise ValueError(f"fill must be one of {FILLS}, got {fill!r}")
    return fill


def winding_bsp(vertices, faces, *, width: int = DEFAULT_WIDTH, seed: int = 0, label: int = 1,
                report: dict | None = None) -> BSPTree:
    """The BSP of ``{x : w(x) > 0}``, ``w`` the winding number of a closed integer triangle mesh: the import
    (:func:`csgnb.bsp.build.bsp_from_polygons`) of :func:`winding_boundary`."""
    label = check_label(label)
    seed = check_seed(seed)
    palette, polygons = winding_boundary(vertices, faces, width=width, report=report)
    return bsp_from_polygons(palette, polygons, seed=seed, label=label)


def winding_boundary(vertices, faces, *, width: int = DEFAULT_WIDTH,
                     report: dict | None = None) -> tuple[np.ndarray, PolygonSet]:
    """The exact boundary of ``{x : w(x) > 0}`` as outward plane-based polygons ``(palette, polygons)``.

    The mesh is welded and repaired as :func:`csgnb.bsp.build.validate_mesh` does (collapsed faces dropped,
    opposite pairs cancelled, flat faces split); then every edge must be run as often one way as the other (else
    the winding number is not defined: :class:`GeometryError` names the edge). Overlapping, crossing and folded
    faces are allowed. ``report`` (a dict) gets the repair counts, ``crossed_faces`` (faces another face crosses or
    touches), ``pieces`` (what they were split into) and ``boundary_polygons``.
    """
    W, T, F, face_ids, first_index, hint = repaired_mesh(vertices, faces, width, report)
    # (q - p) x (r - p) of every face (p, q, r): int64 holds it within any width's mesh budget (<= 8 V^2)
    normal = np.cross(W[T[:, 1]] - W[T[:, 0]], W[T[:, 2]] - W[T[:, 0]])
    _check_cycle(W, T, F, face_ids, first_index, hint, normal)
    palette, polygons = polygons_from_triangles(W, T, width) if T.shape[0] else (
        to_wide(np.zeros((0, 4), np.int64), width), None)
    if polygons is None:  # every face cancelled an opposite one: the mesh winds around nothing
        empty = PolygonSet(np.zeros(0, np.int32), np.zeros(1, np.int32), np.zeros(0, np.int32))
        if report is not None:
            report.update(crossed_faces=0, pieces=0, boundary_polygons=0)
        return palette, empty
    pairs = self_intersections(W, T)
    crossed = np.zeros(T.shape[0], bool)
    crossed[pairs.reshape(-1)] = True
    front = _front_windings(W, T, crossed, normal)
    support, offsets, edges = polygons.support, polygons.offsets, polygons.edges
    # uncrossed faces with 0 in front: on the boundary as they are
    whole = np.flatnonzero(~crossed & (front == 0))
    whole_sizes = (offsets[whole + 1] - offsets[whole]).astype(np.int64)
    starts = np.repeat(offsets[whole].astype(np.int64) - np.r_[0, np.cumsum(whole_sizes)[:-1]], whole_sizes)
    whole_edges = edges[starts + np.arange(int(whole_sizes.sum()))]
    out_support, out_sizes, out_edges = [], [], []
    n_pieces = 0
    if pairs.shape[0]:
        pieces = _CrossedFaces(W, T, normal, from_wide(palette).tolist(), polygons, pairs)
        for f in np.flatnonzero(crossed).tolist():
            kept, count = pieces.boundary_of(f)
            for s_, e_ in kept:
                out_support.append(s_)
                out_sizes.append(len(e_))
                out_edges.extend(e_)
            n_pieces += count
    sizes = np.r_[whole_sizes, np.array(out_sizes, np.int64)]
    support_out = np.r_[support[whole].astype(np.int64), np.array(out_support, np.int64)]
    edges_out = np.r_[whole_edges.astype(np.int64), np.array(out_edges, np.int64)]
    # only the planes the boundary uses (the supports and edges of faces inside the solid drop out)
    used = np.unique(np.r_[np.where(support_out >= 0, support_out, ~support_out), edges_out])
    renumber = np.full(palette.shape[0], -1, np.int64)
    renumber[used] = np.arange(used.shape[0])
    support_out = np.where(support_out >= 0, renumber[np.maximum(support_out, 0)],
                           ~renumber[np.maximum(~support_out, 0)])
    palette = np.ascontiguousarray(palette[used])
    result = PolygonSet(support_out.astype(np.int32), np.r_[0, np.cumsum(sizes)].astype(np.int32),
                        renumber[edges_out].astype(np.int32))
    if report is not None:
        report.update(crossed_faces=int(crossed.sum()), pieces=n_pieces, boundary_polygons=len(result))
    return palette, result


def _check_cycle(W, T, F, face_ids, first_index, hint: str, normal: np.ndarray) -> None:
    """Every face has area and every undirected edge is run as often one way as the other."""
    flat = np.flatnonzero(~normal.any(axis=1))
    if flat.size:
        f = int(flat[0])
        raise GeometryError(f"face {int(face_ids[f])} {F[f].tolist()} is flat (its corners {W[T[f]].tolist()} are "
                            "collinear) and could not be split away: remove it and split the edge through its "
                            f"middle corner{' -- ' + hint if hint else ''}")
    a = T.reshape(-1)
    b = T[:, [1, 2, 0]].reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keys, inverse = np.unique(lo * W.shape[0] + hi, return_inverse=True)
    balance = np.zeros(keys.shape[0], np.int64)
    np.add.at(balance, inverse.reshape(-1), np.where(a < b, 1, -1))
    bad = np.flatnonzero(balance)
    if bad.size:
        k = int(keys[bad[0]])
        p, q = divmod(k, W.shape[0])
        raise GeometryError(
            f"the mesh is not closed: edge {_describe_edge(first_index, W, p, q)} is run "
            f"{int(balance[bad[0]]):+d} more times one way than the other (a hole, a crack or a face missing; the "
            f"winding number is defined only for a closed surface){' -- ' + hint if hint else ''}"
        )


def _front_windings(W: np.ndarray, T: np.ndarray, crossed: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(m,) int64: the winding number just in front of every face no other face crosses (0 elsewhere).

    Faces joined across an edge of exactly two faces, neither crossed, see the same space in front of them: one
    count per such patch, at the centroid of its first face."""
    m = T.shape[0]
    _, _, face, starts, counts = half_edges(W, T)
    pair = starts[counts == 2]
    f0, f1 = face[pair], face[pair + 1]
    keep = ~crossed[f0] & ~crossed[f1]
    _, patch = connected_components(coo_matrix((np.ones(int(keep.sum())), (f0[keep], f1[keep])), shape=(m, m)),
                                    directed=False)
    front = np.zeros(m, np.int64)
    first = {}
    for f in np.flatnonzero(~crossed).tolist():
        first.setdefault(int(patch[f]), f)
    V3 = 3 * W
    corners = V3[T]
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    extent = int(V3.max() - V3.min()) + 3
    VX = np.concatenate([V3, np.zeros((2, 3), np.int64)])
    p_row, q_row = V3.shape[0], V3.shape[0] + 1
    pl = np.empty((1, 4), wide_dtype(128))
    sd = np.empty(1, wide_dtype(128))
    rng = np.random.default_rng(0)
    everything = np.arange(m)
    values = {}
    for p, f in first.items():
        point = W[T[f]].sum(axis=0)  # 3 x the centroid: inside the face, on no other face (it is not crossed)
        n = [int(c) for c in normal[f]]
        big = max(abs(c) for c in n)
        VX[p_row] = point
        for _ in range(_RETRIES):
            # a far point in front of the face: the normal scaled to twice the mesh's extent, tilted at random --
            # in Python ints (at 256 bits a normal times a distance exceeds int64), and never farther than ~3
            # extents, which keeps _shell_windings' 128-bit orientations exact
            tilt = rng.integers(-extent // 4 - 1, extent // 4 + 2, 3).tolist()
            q = [int(point[k]) + (n[k] * 2 * extent) // big + tilt[k] for k in range(3)]
            if sum((q[k] - int(point[k])) * n[k] for k in range(3)) <= 0:
                continue
            VX[q_row] = q
            seg_lo, seg_hi = np.minimum(point, q), np.maximum(point, q)
            near = everything[np.all((lo <= seg_hi) & (hi >= seg_lo), axis=1) & (everything != f)]
            wind = np.zeros(near.shape[0], np.int64)
            if _shell_windings(VX, T, near, p_row, q_row, seg_lo, seg_hi, wind, pl, sd):
                values[p] = int(wind.sum())
                break
        else:  # pragma: no cover - every direction met an edge
            raise InternalError("no segment from a face centroid avoided every edge (a bug: please report)")
    for f in np.flatnonzero(~crossed).tolist():
        front[f] = values[int(patch[f])]
    return front


class _CrossedFaces:
    """Crossed faces split by the planes of the faces crossing them; which pieces bound the winding solid."""

    def __init__(self, W, T, normal, planes, polygons: PolygonSet, pairs: np.ndarray):
        self.T, self.planes, self.polygons = T, planes, polygons
        self.Wi = [[int(c) for c in row] for row in W.tolist()]
        corners = W[T]
        self.lo, self.hi = corners.min(axis=1), corners.max(axis=1)
        self.extent = int(W.max() - W.min()) + 2
        self.rng = np.random.default_rng(1)
        self.partners: dict[int, list[int]] = {}
        for i, j in pairs.tolist():
            self.partners.setdefault(i, []).append(j)
            self.partners.setdefault(j, []).append(i)
        self.normal = normal.tolist()  # Python ints: the offsets and every product below exceed int64 at 256 bits
        self.offset = [sum(n[k] * self.Wi[self.T[f, 0]][k] for k in range(3)) for f, n in enumerate(self.normal)]
        # the segment tests' doubles: vertices exact (a mesh's coordinates stay below 2**31), normals rounded once
        self.Vf, self.Nf = W.astype(np.float64), normal.astype(np.float64)
        self.unsure = np.empty(T.shape[0], np.int64)

    def _coplanar(self, f, g) -> bool:
        n, p = self.normal[f], self.Wi[self.T[f, 0]]
        return all(sum(n[k] * (self.Wi[v][k] - p[k]) for k in range(3)) == 0 for v in self.T[g].tolist())

    def boundary_of(self, f: int) -> tuple[list, int]:
        """The boundary pieces on face ``f`` -- (signed support, edge rows) each, facing out of the solid -- and
        how many pieces ``f`` was split into."""
        pg = self.polygons
        e0, e1 = int(pg.offsets[f]), int(pg.offsets[f + 1])
        rows = pg.edges[e0:e1].tolist()
        # the triangle as (corner, edge plane into that corner): corner j lies on edges j and j + 1
        piece = [(self.Wi[v] + [1], rows[j]) for j, v in enumerate(self.T[f].tolist())]
        coplanar = [g for g in self.partners[f] if self._coplanar(f, g)]
        cutters = {int(pg.support[g]) if pg.support[g] >= 0 else ~int(pg.support[g])
                   for g in self.partners[f] if g not in coplanar}
        for g in coplanar:  # a face on the same plane: split along its edges
            cutters.update(pg.edges[pg.offsets[g]:pg.offsets[g + 1]].tolist())
        pieces = [piece]
        for h in sorted(cutters):
            split = []
            for pc in pieces:
                split.extend(part for part in (_clip_edges(pc, self.planes[h], h, +1),
                                               _clip_edges(pc, self.planes[h], h, -1)) if len(part) >= 3)
            pieces = split
        kept = []
        s = int(pg.support[f])
        n = self.normal[f]
        for pc in pieces:
            L = lcm(*(v[3] for v, _ in pc))
            X = [sum(v[k] * (L // v[3]) for v, _ in pc) for k in range(3)]
            D = L * len(pc)  # x = X / D: the centroid of the piece's corners, inside it
            holders = [g for g in coplanar if self._holds(g, X, D)]
            if any(g < f for g in holders):
                continue  # the same piece of plane comes with a face before this one
            w_front = self._winding_from(X, D, n)
            jump = 1 + sum(1 if sum(a * b for a, b in zip(self.normal[g], n, strict=True)) > 0 else -1
                           for g in holders)
            inside_behind, inside_front = w_front + jump > 0, w_front > 0
            if inside_behind == inside_front:
                continue
            edges = [e for _, e in pc]
            if inside_behind:
                kept.append((s, edges))
            else:  # the solid lies in front: the piece faces the other way, its edges in reverse order
                kept.append((~s, [edges[0]] + edges[:0:-1]))
        return kept, len(pieces)

    def _holds(self, g, X, D) -> bool:
        """Whether x = X / D (on g's plane) lies strictly inside triangle g."""
        n = self.normal[g]
        corners = [[D * c for c in self.Wi[v]] for v in self.T[g].tolist()]
        for k in range(3):
            a, b = corners[k], corners[(k + 1) % 3]
            u = [b[i] - a[i] for i in range(3)]
            v = [X[i] - a[i] for i in range(3)]
            c = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
            if sum(c[i] * n[i] for i in range(3)) <= 0:
                return False
        return True

    def _winding_from(self, X, D, toward) -> int:
        """The winding number just beside x = X / D on the side ``toward`` points to (``toward``: a normal).

        The segment runs nearly along the axis of the normal's largest coefficient, past the mesh, tilted a little
        at random: it meets few faces' boxes, and leaves x into the side wanted (its dot with ``toward`` > 0)."""
        axis = max(range(3), key=lambda k: abs(toward[k]))
        reach = 4 * self.extent
        for _ in range(_RETRIES):
            tilt = self.rng.integers(-self.extent // 64 - 1, self.extent // 64 + 2, 3).tolist()
            tilt[axis] = reach if toward[axis] > 0 else -reach
            q = [X[k] // D + tilt[k] for k in range(3)]
            if sum((D * q[k] - X[k]) * toward[k] for k in range(3)) <= 0:
                continue
            total = self._crossings(X, D, q)
            if total is not None:
                return total
        raise InternalError("no segment from a piece's centroid avoided every edge (a bug: please report)")

    def _crossings(self, X, D, q):
        """Signed crossings of the segment from x = X / D to the integer point q with the faces, or None when it
        passes through an edge or a corner. Doubles decide every face they can (:func:`_filtered_crossings`); the
        faces they leave undecided -- those x lies on or near, the segment's close calls -- are decided exactly."""
        xf = np.array([c / D for c in X])  # each correctly rounded (Python's int / int)
        qa = np.array(q, np.float64)
        total, n_unsure = _filtered_crossings(xf, qa, self.Vf, self.Nf, self.T, self.lo, self.hi, self.unsure)
        t = (D * q[0] - X[0], D * q[1] - X[1], D * q[2] - X[2])
        for g in self.unsure[:n_unsure].tolist():
            c = self._exact_crossing(g, X, D, q, t)
            if c is None:
                return None
            total += c
        return total

    def _exact_crossing(self, g, X, D, q, t):
        """+1 / -1 where the segment x = X / D -> q (t = D q - X) leaves / enters through face g, 0 where it misses
        it, None where it passes through an edge or a corner. Orientations in integers scaled by D > 0 (signs
        unchanged): a face's side of x is sign(n·X - D n·a), of q sign(n·q - n·a); the segment's side of an edge
        a -> b is sign((D q - X)·((D a - X) x (b - a)))."""
        x0, x1, x2 = X
        (n0, n1, n2), nd = self.normal[g], self.offset[g]
        op = n0 * x0 + n1 * x1 + n2 * x2 - D * nd
        if op == 0:
            return 0  # x on the face's plane: the segment leaves it at once (see the module docstring)
        oq = n0 * q[0] + n1 * q[1] + n2 * q[2] - nd
        if oq == 0 or (op > 0) == (oq > 0):
            return 0
        corners = [self.Wi[v] for v in self.T[g].tolist()]
        sides = []
        for k in range(3):
            a, b = corners[k], corners[(k + 1) % 3]
            r0, r1, r2 = D * a[0] - x0, D * a[1] - x1, D * a[2] - x2
            e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
            side = t[0] * (r1 * e2 - r2 * e1) + t[1] * (r2 * e0 - r0 * e2) + t[2] * (r0 * e1 - r1 * e0)
            sides.append((side > 0) - (side < 0))
        if 1 in sides and -1 in sides:
            return 0  # the line passes beside the face
        if 0 in sides:
            return None  # through an edge or a corner: another direction
        return 1 if oq > 0 else -1


#: Relative bound of the doubles in :func:`_filtered_crossings`. x is within 1 unit of 2**-53 (u) of X / D, a
#: rounded normal within 1 u, vertices and q exact. n·(x - a): each difference within u|x| + u|x - a|, each product
#: one more u, the sum two: within ~5 u of sum |n_k| (|x_k| + |a_k|); n·(q - a) within ~4 u of sum |n_k| |q_k - a_k|;
#: (q - x)·((a - x) x e): t and r within 2 u of |q| + |x| and |a| + |x| a coordinate, the cross product within 5 u
#: of R_j E_k + R_k E_j, the dot product within ~10 u of its terms' magnitudes. 2**-48 is 32 u: sound with room; a
#: value within it goes to the exact integers.
CROSSING_FILTER_BOUND = 2.0**-48


@jit
def _filtered_crossings(x, q, V, N, T, lo, hi, unsure):
    """Signed crossings of the segment x -> q with the faces that doubles decide with certainty.

    ``x`` (3,) float64: the start, within 1 unit of 2**-53 of the exact point; ``q`` (3,) float64: the integer end
    (exact); ``V`` (n, 3) float64: the vertices (exact: below 2**53); ``N`` (m, 3) float64: the faces' normals
    (q - p) x (r - p), each rounded once; ``T`` (m, 3) int64; ``lo``, ``hi`` (m, 3) int64: the faces' boxes.
    Returns ``(total, k)``: the sum of +1 (leaving through a face along its normal) and -1 (entering) over the
    decided faces, and the number ``k`` of faces written to ``unsure[:k]`` that doubles could not decide (an
    orientation within :data:`CROSSING_FILTER_BOUND` of zero: x on or near the face's plane, the segment near an
    edge or a corner); a face decided as missed adds nothing.
    """
    seg_lo = np.empty(3)
    seg_hi = np.empty(3)
    for k in range(3):
        seg_lo[k] = min(x[k], q[k]) - 1.0
        seg_hi[k] = max(x[k], q[k]) + 1.0
    total = 0
    n_unsure = 0
    for g in range(T.shape[0]):
        if (lo[g, 0] > seg_hi[0] or hi[g, 0] < seg_lo[0] or lo[g, 1] > seg_hi[1] or hi[g, 1] < seg_lo[1]
                or lo[g, 2] > seg_hi[2] or hi[g, 2] < seg_lo[2]):
            continue
        a = T[g, 0]
        op = 0.0
        op_size = 0.0
        oq = 0.0
        oq_size = 0.0
        for k in range(3):
            n = N[g, k]
            op += n * (x[k] - V[a, k])
            op_size += abs(n) * (abs(x[k]) + abs(V[a, k]))
            oq += n * (q[k] - V[a, k])
            oq_size += abs(n) * abs(q[k] - V[a, k])
        if abs(op) <= CROSSING_FILTER_BOUND * op_size or abs(oq) <= CROSSING_FILTER_BOUND * oq_size:
            unsure[n_unsure] = g
            n_unsure += 1
            continue
        if (op > 0.0) == (oq > 0.0):
            continue  # both ends on one side of the face's plane
        positive = False
        negative = False
        close = False
        for k in range(3):
            a = T[g, k]
            b = T[g, (k + 1) % 3]
            side = 0.0
            size = 0.0
            for i in range(3):
                j = (i + 1) % 3
                m = (i + 2) % 3
                c = (V[a, j] - x[j]) * (V[b, m] - V[a, m]) - (V[a, m] - x[m]) * (V[b, j] - V[a, j])
                c_size = ((abs(V[a, j]) + abs(x[j])) * abs(V[b, m] - V[a, m])
                          + (abs(V[a, m]) + abs(x[m])) * abs(V[b, j] - V[a, j]))
                side += (q[i] - x[i]) * c
                size += (abs(q[i]) + abs(x[i])) * c_size
            if abs(side) <= CROSSING_FILTER_BOUND * size:
                close = True
            elif side > 0.0:
                positive = True
            else:
                negative = True
        if positive and negative:
            continue  # the line passes beside the face
        if close:
            unsure[n_unsure] = g
            n_unsure += 1
            continue
        total += 1 if oq > 0.0 else -1
    return total, n_unsure


def _clip_edges(piece, plane, row: int, side: int):
    """The convex piece ``[(corner, edge row into it), ...]`` (homogeneous Python-int corners, w > 0) cut to the
    closed side ``side`` of ``plane`` (palette row ``row``: a, b, c, d); the cut runs along ``row``."""
    a, b, c, d = plane
    values = [side * (a * v[0] + b * v[1] + c * v[2] + d * v[3]) for v, _ in piece]
    if all(x >= 0 for x in values):
        return piece
    if all(x <= 0 for x in values):
        return []
    out = []
    k = len(piece)
    for j in range(k):
        (p, _), vp = piece[j - 1], values[j - 1]
        (q, edge), vq = piece[j], values[j]  # the segment p -> q runs along `edge`
        if vp >= 0 and vq >= 0:
            out.append((q, edge))
        elif vp > 0 > vq:
            out.append((_cross(p, vp, q, vq), edge))  # leaving: the corner on the plane, reached along `edge`
        elif vp < 0 <= vq:
            if vq > 0:
                out.append((_cross(p, vp, q, vq), row))  # entering: reached along the cut
                out.append((q, edge))
            else:
                out.append((q, row))
    return _without_flat_corners(out)


def _without_flat_corners(piece):
    """The piece without corners in the middle of a straight run (a corner the cut landed on exactly can be one:
    its two edge planes would meet the support in one line, and the corner would not be a point)."""
    k = 0
    while k < len(piece) and len(piece) >= 3:
        a, b, c = piece[k - 1][0], piece[k][0], piece[(k + 1) % len(piece)][0]
        u = [b[i] * a[3] - a[i] * b[3] for i in range(3)]
        v = [c[i] * a[3] - a[i] * c[3] for i in range(3)]
        if u[1] * v[2] == u[2] * v[1] and u[2] * v[0] == u[0] * v[2] and u[0] * v[1] == u[1] * v[0]:
            del piece[k]  # the next corner keeps its edge: the same line
            k = 0
        else:
            k += 1
    return piece


def _cross(p, vp, q, vq):
    """The point of segment p q on the plane (values vp, vq of opposite signs), homogeneous, w > 0, reduced."""
    r = [vp * q[j] - vq * p[j] for j in range(4)]
    g = gcd(*r)
    return [x // g for x in r] if r[3] > 0 else [-x // g for x in r]
