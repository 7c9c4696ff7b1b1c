"""An independent reference for CSG graphs: point classification and ray casting with 1D Booleans.

Nothing here uses csgnb's kernels or its normal form: leaf matrices are transformed with numpy
(Q' = M⁻ᵀ Q M⁻¹ along each root-to-leaf path), points are classified by recursion over the graph,
and rays find the CSG surface where the classification changes between consecutive roots of
the leaf quadrics (a 1D Boolean evaluation on the ray). Test modules import it; its own checks
are in ``tests/test_csg_raycast.py``.
"""

from __future__ import annotations

import numpy as np

from csgnb.csg import Complement, Difference, Intersection, Leaf, Transformed, Union

# -- reference evaluation ------------------------------------------------------------------------


def world_leaves(node, M=None, out=None):
    """List (leaf, world matrix) per root-to-leaf path (shared sub-graphs once per path)."""
    out = [] if out is None else out
    if isinstance(node, Leaf):
        Q = node.quadric.matrix
        if M is not None:
            Minv = np.linalg.inv(M)
            Q = Minv.T @ Q @ Minv
        out.append((node, 0.5 * (Q + Q.T)))
    elif isinstance(node, Transformed):
        world_leaves(node.child, node.matrix if M is None else M @ node.matrix, out)
    else:
        for c in node.children():
            world_leaves(c, M, out)
    return out


def _eval(node, pts, M, leaf_fn, it):
    if isinstance(node, Leaf):
        return leaf_fn(next(it), pts)
    if isinstance(node, Transformed):
        return _eval(node.child, pts, node.matrix if M is None else M @ node.matrix, leaf_fn, it)
    if isinstance(node, Complement):
        return -_eval(node.child, pts, M, leaf_fn, it)
    vals = [_eval(c, pts, M, leaf_fn, it) for c in node.children()]
    if isinstance(node, Union):
        return np.min(vals, axis=0)
    if isinstance(node, Intersection):
        return np.max(vals, axis=0)
    if isinstance(node, Difference):
        return np.max([vals[0]] + [-v for v in vals[1:]], axis=0)
    raise TypeError(type(node))


def _homog(pts):
    return np.column_stack([pts, np.ones(len(pts))])


def graph_value(node, pts):
    """min/max combination of leaf values Q(p): its sign classifies p (negative inside)."""
    mats = iter([Q for _, Q in world_leaves(node)])
    return _eval(node, pts, None, lambda Q, p: np.einsum("ni,ij,nj->n", _homog(p), Q, _homog(p)), mats)


def graph_first_order_distance(node, pts):
    """min/max combination of Q(p)/|∇Q(p)|: zero exactly on the CSG surface, sign as above."""

    def leaf(Q, p):
        h = _homog(p)
        g = 2.0 * (h @ Q[:, :3])
        return np.einsum("ni,ij,nj->n", h, Q, h) / np.linalg.norm(g, axis=1)

    return _eval(node, pts, None, leaf, iter([Q for _, Q in world_leaves(node)]))


def ray_surface_points(node, origins, dirs, t_max):
    """Points where rays o + t v, 0 < t < t_max, cross the CSG surface, with the leaf matrix there.

    Returns points (k, 3) and the world matrices (k, 4, 4) of the leaf whose root it is.
    """
    leaves = [Q for _, Q in world_leaves(node)]
    R = len(origins)
    roots, owner = [], []
    for li, Q in enumerate(leaves):
        A, m, c = Q[:3, :3], Q[:3, 3], Q[3, 3]
        a = np.einsum("ni,ij,nj->n", dirs, A, dirs)
        b = np.einsum("ni,ni->n", dirs, origins @ A + m)
        g = np.einsum("ni,ij,nj->n", origins, A, origins) + 2 * origins @ m + c
        with np.errstate(all="ignore"):
            disc = b * b - a * g
            s = np.sqrt(np.where(disc > 0, disc, np.nan))
            quad = np.abs(a) > 1e-12 * (np.abs(b) + 1)
            r1 = np.where(quad, (-b - s) / a, -g / (2 * b))
            r2 = np.where(quad, (-b + s) / a, np.nan)
        for r in (r1, r2):
            roots.append(np.where((r > 1e-9) & (r < t_max - 1e-9), r, np.nan))
            owner.append(np.full(R, li))
    T = np.column_stack(roots)
    O = np.column_stack(owner)
    order = np.argsort(np.where(np.isnan(T), np.inf, T), axis=1)
    T = np.take_along_axis(T, order, axis=1)
    O = np.take_along_axis(O, order, axis=1)
    bounds = np.column_stack([np.zeros(R), np.where(np.isnan(T), t_max, T), np.full(R, t_max)])
    bounds = np.maximum.accumulate(bounds, axis=1)
    mids = 0.5 * (bounds[:, :-1] + bounds[:, 1:])
    pts = origins[:, None, :] + mids[..., None] * dirs[:, None, :]
    inside = (graph_value(node, pts.reshape(-1, 3)) < 0).reshape(mids.shape)
    # a root is on the surface if the classification differs on its two sides and the two
    # sub-intervals are not degenerate (tangent rays, repeated roots)
    width_lo = bounds[:, 1:-1] - bounds[:, :-2]
    width_hi = bounds[:, 2:] - bounds[:, 1:-1]
    change = (inside[:, :-1] != inside[:, 1:]) & ~np.isnan(T) & (width_lo > 1e-9) & (width_hi > 1e-9)
    rr, kk = np.nonzero(change)
    hit = origins[rr] + T[rr, kk][:, None] * dirs[rr]
    return hit, np.array([leaves[i] for i in O[rr, kk]]).reshape(-1, 4, 4)


def random_rays(rng, center, radius, n):
    """Rays through a ball: origins on a sphere of 2·radius aimed at random points of the ball."""
    center = np.asarray(center, dtype=float)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    origins = center + 2.0 * radius * u
    targets = center + radius * rng.uniform(-1, 1, (n, 3))
    d = targets - origins
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return origins, d, 4.0 * radius
