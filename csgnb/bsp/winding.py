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

The construction is exact and reuses the BSP import (paper §3.6): every face is inserted
(:func:`csgnb.bsp.build.insert_polygons`), so no face crosses the interior of a leaf cell
and ``w`` is constant on each leaf. A leaf lies against the piece of the face that split
its parent (its *creator*), on one side, so its winding number is the winding number
just beside that piece:

* for a face that no other face crosses or touches away from their shared corners and
  edge (:func:`csgnb.bsp.build.self_intersections`), the winding number just in front
  of it is the same all along it, and just behind it one more. Faces joined across an
  edge of exactly two faces share the value in front, so it is counted once per such
  patch: the signed crossings of a segment from a face's centroid to a far point in
  front of it (exact integer orientation tests, another direction when the segment meets
  an edge or a corner);
* for a face that is crossed, the piece itself is rebuilt exactly (the face clipped by
  the planes on the path from the root, as rationals), and the segment starts at the
  centroid of the piece, towards the leaf's side.
"""

from __future__ import annotations

from math import gcd, lcm

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from csgnb.bsp.build import (
    _describe_edge,
    _shell_windings,
    check_label,
    check_seed,
    insert_polygons,
    repaired_mesh,
    self_intersections,
)
from csgnb.bsp.polygon import polygons_from_triangles
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import GeometryError, InternalError
from csgnb.exact.wide import DEFAULT_WIDTH, from_wide, to_wide, wide_dtype

__all__ = ["FILLS", "check_fill", "winding_bsp"]

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
    """The BSP of ``{x : w(x) > 0}``, ``w`` the winding number of a closed integer triangle mesh (module docstring).

    The mesh is welded and repaired as :func:`csgnb.bsp.build.validate_mesh` does (collapsed faces dropped,
    opposite pairs cancelled, flat faces split); then every edge must be run as often one way as the other (else
    the winding number is not defined: :class:`GeometryError` names the edge). Overlapping, crossing and folded
    faces are allowed. ``report`` (a dict) gets the repair counts, ``crossed_faces`` (faces another face crosses or
    touches) and ``leaves_from_pieces`` (leaves whose winding number came from a piece of such a face).
    """
    label = check_label(label)
    seed = check_seed(seed)
    W, T, F, face_ids, first_index, hint = repaired_mesh(vertices, faces, width, report)
    _check_cycle(W, T, F, face_ids, first_index, hint)
    if T.shape[0] == 0:  # every face cancelled an opposite one: the mesh winds around nothing
        if report is not None:
            report["crossed_faces"] = report["leaves_from_pieces"] = 0
        return BSPTree.leaf(to_wide(np.zeros((0, 4), np.int64), width), OUT)
    pairs = self_intersections(W, T)
    crossed = np.zeros(T.shape[0], bool)
    crossed[pairs.reshape(-1)] = True
    front = _front_windings(W, T, crossed)
    palette, polygons = polygons_from_triangles(W, T, width)
    tree, creator = insert_polygons(palette, polygons, seed=seed, label=label)
    winding, from_pieces = _leaf_windings(W, T, tree, creator, polygons.support, front, crossed)
    lab = np.where(tree.plane >= 0, -1, np.where(winding > 0, label, 0)).astype(np.int32)
    if report is not None:
        report["crossed_faces"] = int(crossed.sum())
        report["leaves_from_pieces"] = from_pieces
    return BSPTree(tree.palette, tree.plane, tree.neg, tree.pos, lab, validate=False)


def _check_cycle(W, T, F, face_ids, first_index, hint: str) -> None:
    """Every face has area and every undirected edge is run as often one way as the other."""
    normal = np.cross(W[T[:, 1]] - W[T[:, 0]], W[T[:, 2]] - W[T[:, 0]])
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


def _parents(tree: BSPTree) -> np.ndarray:
    parent = np.full(tree.plane.shape[0], -1, np.int64)
    inner = np.flatnonzero(tree.plane >= 0)
    parent[tree.neg[inner]] = inner
    parent[tree.pos[inner]] = inner
    return parent


def _front_windings(W: np.ndarray, T: np.ndarray, crossed: np.ndarray) -> np.ndarray:
    """(m,) int64: the winding number just in front of every face no other face crosses (0 elsewhere).

    Faces joined across an edge of exactly two faces, neither crossed, see the same space in front of them: one
    count per such patch, at the centroid of its first face."""
    m = T.shape[0]
    a = T.reshape(-1)
    b = T[:, [1, 2, 0]].reshape(-1)
    face = np.repeat(np.arange(m), 3)
    key = np.minimum(a, b) * W.shape[0] + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    key, face = key[order], face[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    counts = np.diff(np.r_[starts, key.shape[0]])
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
    normal = np.cross(W[T[:, 1]] - W[T[:, 0]], W[T[:, 2]] - W[T[:, 0]])
    extent = int(V3.max() - V3.min()) + 3
    VX = np.concatenate([V3, np.zeros((2, 3), np.int64)])
    p_row, q_row = V3.shape[0], V3.shape[0] + 1
    pl = np.empty((1, 4), wide_dtype(128))
    sd = np.empty(1, wide_dtype(128))
    rng = np.random.default_rng(0)
    values = {}
    for p, f in first.items():
        point = W[T[f]].sum(axis=0)  # 3 x the centroid: inside the face, on no other face (it is not crossed)
        n = normal[f]
        # a far point in front of the face: the normal scaled past the mesh, plus a random tilt
        scale = -(-2 * extent // int(np.abs(n).max()))
        VX[p_row] = point
        everything = np.arange(m)
        for _ in range(_RETRIES):
            tilt = rng.integers(-extent // 4 - 1, extent // 4 + 2, 3)
            q = point + scale * n + tilt
            if int(np.dot(q - point, n)) <= 0:
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


def _leaf_windings(W, T, tree: BSPTree, creator: np.ndarray, support: np.ndarray, front: np.ndarray,
                   crossed: np.ndarray) -> tuple[np.ndarray, int]:
    """(nodes,) int64: each leaf's winding number (0 at inner nodes), and how many came from pieces of crossed
    faces; see the module docstring."""
    n = tree.plane.shape[0]
    winding = np.zeros(n, np.int64)
    if n == 1:
        return winding, 0
    parent = _parents(tree)
    leaves = np.flatnonzero(tree.plane < 0)
    up = parent[leaves]
    f = creator[up]
    # the child behind the face (its inside): the negative side of its support, the positive one when flipped
    behind = np.where(support[f] >= 0, tree.neg[up], tree.pos[up]) == leaves
    winding[leaves] = front[f] + behind
    from_pieces = np.flatnonzero(crossed[f])
    if from_pieces.size:
        walker = _PieceWinding(W, T, from_wide(tree.palette).tolist(), tree, parent)
        for i in from_pieces.tolist():
            winding[leaves[i]] = walker.winding(int(leaves[i]), int(f[i]))
    return winding, int(from_pieces.size)


class _PieceWinding:
    """Winding numbers of leaves made by pieces of crossed faces: the piece rebuilt exactly, a segment from it."""

    def __init__(self, W, T, planes, tree: BSPTree, parent):
        self.W, self.T, self.planes, self.tree, self.parent = W, T, planes, tree, parent
        corners = W[T]
        self.lo, self.hi = corners.min(axis=1), corners.max(axis=1)
        self.extent = int(W.max() - W.min()) + 2
        self.rng = np.random.default_rng(1)
        self.Wi = [[int(c) for c in row] for row in W.tolist()]

    def winding(self, leaf: int, face: int) -> int:
        tree = self.tree
        node = int(self.parent[leaf])
        side = 1 if tree.pos[node] == leaf else -1
        piece = [self.Wi[v] + [1] for v in self.T[face].tolist()]  # homogeneous corners (x, y, z, w), w > 0
        child = node
        while True:
            up = int(self.parent[child])
            if up < 0:
                break
            piece = _clip(piece, self.planes[tree.plane[up]], 1 if tree.pos[up] == child else -1)
            child = up
        if len(piece) < 3:
            raise InternalError(f"the piece of face {face} that split node {node} vanished when rebuilt (a bug)")
        L = lcm(*(p[3] for p in piece))
        X = [sum(p[k] * (L // p[3]) for p in piece) for k in range(3)]
        D = L * len(piece)  # x = X / D, the centroid of the piece's corners: inside the piece
        n = self.planes[tree.plane[node]][:3]
        return self._winding_from(X, D, [side * c for c in n])

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
        xf = [c / D for c in X]
        seg_lo = np.minimum(np.floor(xf), q) - 1
        seg_hi = np.maximum(np.ceil(xf), q) + 1
        near = np.flatnonzero(np.all((self.lo <= seg_hi) & (self.hi >= seg_lo), axis=1))
        Q = [D * c for c in q]  # D q, so that x and q share the denominator D
        total = 0
        for g in near.tolist():
            a, b, c = (self.Wi[v] for v in self.T[g].tolist())
            A, B, C = ([D * t for t in p] for p in (a, b, c))
            op = _orient(A, B, C, X)
            if op == 0:
                continue  # x on the face's plane: the segment leaves it at once (see the module docstring)
            oq = _orient(A, B, C, Q)
            if op == oq or oq == 0:
                continue
            s1, s2, s3 = _orient(X, Q, A, B), _orient(X, Q, B, C), _orient(X, Q, C, A)
            if (s1 > 0 or s2 > 0 or s3 > 0) and (s1 < 0 or s2 < 0 or s3 < 0):
                continue
            if s1 == 0 or s2 == 0 or s3 == 0:
                return None  # through an edge or a corner: another direction
            total += oq
        return total


def _orient(a, b, c, d) -> int:
    """Sign of det[b - a, c - a, d - a] (Python ints)."""
    u = [b[k] - a[k] for k in range(3)]
    v = [c[k] - a[k] for k in range(3)]
    w = [d[k] - a[k] for k in range(3)]
    det = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
           + u[2] * (v[0] * w[1] - v[1] * w[0]))
    return (det > 0) - (det < 0)


def _clip(polygon, plane, side: int):
    """The convex polygon (homogeneous Python-int corners ``[x, y, z, w]``, w > 0) cut to the closed side ``side``
    (+1 / -1) of ``plane`` (a, b, c, d: a x + b y + c z + d)."""
    a, b, c, d = plane
    values = [side * (a * p[0] + b * p[1] + c * p[2] + d * p[3]) for p in polygon]
    if all(v >= 0 for v in values):
        return polygon
    out = []
    k = len(polygon)
    for i in range(k):
        p, vp = polygon[i], values[i]
        q, vq = polygon[(i + 1) % k], values[(i + 1) % k]
        if vp >= 0:
            out.append(p)
        if (vp > 0 and vq < 0) or (vp < 0 and vq > 0):
            # vp q - vq p is on the plane; its w = vp wq - vq wp has the sign of vp (wp, wq > 0)
            r = [vp * q[j] - vq * p[j] for j in range(4)]
            g = gcd(*r)
            out.append([x // g for x in r] if r[3] > 0 else [-x // g for x in r])
    return out
