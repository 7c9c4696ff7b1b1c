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
  the winding number just in front of its centroid is counted as above, the one behind
  differs by the faces on its plane that hold the centroid. A boundary piece is kept facing
  out of the solid, once where coplanar faces overlap.

Every polygon's support and edges are planes of the mesh's triangles, so nothing leaves
the width's budget; the pieces' vertices are checked as every import's are.
"""

from __future__ import annotations

from math import gcd, lcm

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

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
    out_support, out_edges = [], []
    for f in np.flatnonzero(~crossed & (front == 0)).tolist():  # uncrossed, 0 in front: boundary as they are
        out_support.append(int(support[f]))
        out_edges.append(edges[offsets[f]:offsets[f + 1]].tolist())
    n_pieces = 0
    if pairs.shape[0]:
        pieces = _CrossedFaces(W, T, normal, from_wide(palette).tolist(), polygons, pairs)
        for f in np.flatnonzero(crossed).tolist():
            kept, count = pieces.boundary_of(f)
            for s_, e_ in kept:
                out_support.append(s_)
                out_edges.append(e_)
            n_pieces += count
    sizes = np.array([len(e) for e in out_edges], np.int64)
    support_out = np.array(out_support, np.int64)
    edges_out = np.array([x for e in out_edges for x in e], np.int64)
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
        passes through an edge or a corner. Orientations in integers scaled by D > 0 (signs unchanged): a face's
        side of x is sign(n·X - D n·a), of q sign(n·q - n·a); the segment's side of an edge a -> b is
        sign((D q - X)·((D a - X) x (b - a)))."""
        xf = [c / D for c in X]
        seg_lo = np.minimum(np.floor(xf), q) - 1
        seg_hi = np.maximum(np.ceil(xf), q) + 1
        near = np.flatnonzero(np.all((self.lo <= seg_hi) & (self.hi >= seg_lo), axis=1))
        x0, x1, x2 = X
        q0, q1, q2 = q
        t = (D * q0 - x0, D * q1 - x1, D * q2 - x2)
        total = 0
        for g in near.tolist():
            (n0, n1, n2), nd = self.normal[g], self.offset[g]
            op = n0 * x0 + n1 * x1 + n2 * x2 - D * nd
            if op == 0:
                continue  # x on the face's plane: the segment leaves it at once (see the module docstring)
            oq = n0 * q0 + n1 * q1 + n2 * q2 - nd
            if oq == 0 or (op > 0) == (oq > 0):
                continue
            corners = [self.Wi[v] for v in self.T[g].tolist()]
            sides = []
            for k in range(3):
                a, b = corners[k], corners[(k + 1) % 3]
                r0, r1, r2 = D * a[0] - x0, D * a[1] - x1, D * a[2] - x2
                e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                side = t[0] * (r1 * e2 - r2 * e1) + t[1] * (r2 * e0 - r0 * e2) + t[2] * (r0 * e1 - r1 * e0)
                sides.append((side > 0) - (side < 0))
            if 1 in sides and -1 in sides:
                continue  # the line passes beside the face
            if 0 in sides:
                return None  # through an edge or a corner: another direction
            total += 1 if oq > 0 else -1
        return total


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
