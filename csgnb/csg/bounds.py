"""Axis-aligned bounding boxes of normal-form terms and of quadric surfaces inside them.

The sampler needs a finite box per term (the paper asks for a bounding sphere; we derive boxes
where the quadrics allow it). A quadric whose solid ``{Q ≤ 0}`` is convex is contained in
supporting half-spaces (all from :func:`_cylinder_rows`: the solid ``Σ λₖ dₖ² ≤ ρ`` over the
positive eigen-directions, d = Uᵀ(x − q), has support ``u·q + √(ρ uᵀA⁺u)`` for u in their span):

* a half-space (a single plane) is one row;
* an ellipsoid, elliptic cylinder or slab (A ⪰ 0, central, ρ = qᵀb − c ≥ 0) gives rows along ±uₖ
  and along the world axes projected on the span;
* an elliptic paraboloid or parabolic cylinder (A ⪰ 0, non-central) gives its vertex half-space,
  and once its axial coordinate is bounded, the cylinder ``Σ λₖdₖ² ≤ 2βs − γ``;
* a cone or one-sheet hyperboloid (one negative λ) bounds nothing alone; once its axial coordinate
  s is bounded it lies in the cylinder ``Σ λ₊w² ≤ ρ + |λ₋| s²`` (a capped cone).

Intersecting a term's rows with a search box gives a polytope that contains the term; its extents
along the world axes and the axial directions come from a small 3-variable LP solved by vertex
enumeration (every feasible triple of planes), twice when axial bounds apply. If the polytope
reaches the search box (``tolerances.UNBOUNDED`` model sizes wide) the term is unbounded. Other
non-convex members (two-sheet hyperboloids, complements of convex solids) bound nothing, so a
bounded term can be reported unbounded — pass a bounding sphere then. Tolerances are relative to
the size of the data (``tolerances.SUPPORT_SLACK``), so boxes are the same at any scale.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_finite_array, as_instance, as_positive
from csgnb.quadric.frames import frame_kernel
from csgnb.quadric.quadric import Quadric

__all__ = [
    "support_halfspaces",
    "polytope_box",
    "polytope_extents",
    "term_boxes",
    "surface_box",
    "surface_boxes",
    "EMPTY_BOX",
    "box_is_empty",
    "intersect_boxes",
]

#: An empty box (lo > hi).
EMPTY_BOX = np.array([np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf])

#: At most this many support rows per quadric (2·3 eigen-directions + 2·3 projected axes).
MAX_ROWS = 12
#: Terms with more rows than this are bounded member by member (the LP is O(rows⁴)).
MAX_TERM_ROWS = 72

# axial records (a second round of rows once the axial coordinate is bounded)
_AXIAL_NONE, _AXIAL_CONE, _AXIAL_PARABOLOID = 0, 1, 2


def box_is_empty(box: np.ndarray) -> bool:
    """Return whether ``box`` : (6,) (lo, hi) holds no point."""
    return bool(np.any(box[:3] > box[3:]))


def intersect_boxes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the intersection of two boxes : (6,) float64 (empty when lo > hi)."""
    return np.concatenate([np.maximum(a[:3], b[:3]), np.minimum(a[3:], b[3:])])


# -- support rows ----------------------------------------------------------------------------------


@jit
def _cylinder_rows(center, axes, lam, rhs, N, h, at):
    """Rows ``N x ≤ h`` (from row ``at`` on) containing ``{Σ_{λₖ>0} λₖ dₖ² ≤ rhs}``; returns the new count.

    The one support-half-space helper: ellipsoids, cylinders and slabs (rhs = ρ), the axial
    bounds of cones (rhs = ρ + |λ₋|s²) and paraboloids (rhs = 2βs − γ). Directions: ±uₖ for λₖ > 0
    and ± the world axes projected on their span; support u·q + √(rhs · Σ (u·uₖ)²/λₖ).
    rhs < 0 (an empty solid) gives one impossible row 0·x ≤ −1.
    """
    if rhs < 0.0:
        N[at, 0], N[at, 1], N[at, 2] = 0.0, 0.0, 0.0
        h[at] = -1.0
        return at + 1
    for k in range(3):
        if lam[k] > 0.0:
            for sgn in (1.0, -1.0):
                n0, n1, n2 = sgn * axes[0, k], sgn * axes[1, k], sgn * axes[2, k]
                N[at, 0], N[at, 1], N[at, 2] = n0, n1, n2
                h[at] = n0 * center[0] + n1 * center[1] + n2 * center[2] + math.sqrt(rhs / lam[k])
                at += 1
    for e in range(3):
        v0 = 0.0
        v1 = 0.0
        v2 = 0.0
        for k in range(3):
            if lam[k] > 0.0:
                v0 += axes[0, k] * axes[e, k]
                v1 += axes[1, k] * axes[e, k]
                v2 += axes[2, k] * axes[e, k]
        nv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if nv <= tol.SPAN:
            continue  # the world axis is normal to the span: the solid is unbounded along it
        for sgn in (1.0, -1.0):
            n0, n1, n2 = sgn * v0 / nv, sgn * v1 / nv, sgn * v2 / nv
            quad = 0.0
            for k in range(3):
                if lam[k] > 0.0:
                    p = n0 * axes[0, k] + n1 * axes[1, k] + n2 * axes[2, k]
                    quad += p * p / lam[k]
            N[at, 0], N[at, 1], N[at, 2] = n0, n1, n2
            h[at] = n0 * center[0] + n1 * center[1] + n2 * center[2] + math.sqrt(max(rhs * quad, 0.0))
            at += 1
    return at


@jit
def _support_kernel(Q, sign, N, h, axial_par, center, axes, lam):
    """Support rows of the solid ``{sign·Q ≤ 0}`` into N (MAX_ROWS, 3), h; returns (rows, axial kind).

    Also writes its principal frame (``center``, ``axes``, ``lam``) and, for an axial kind,
    ``axial_par`` = (axis (3), λ₋ or β, ρ or γ) for :func:`_axial_rhs`.
    """
    Qs = sign * Q
    beta = np.empty(3)
    form = np.empty(3, dtype=np.int64)
    coef = np.empty((3, 5))
    central, gamma, _, _ = frame_kernel(Qs, center, axes, lam, beta, form, coef)
    npos = 0
    nneg = 0
    for k in range(3):
        if lam[k] > 0.0:
            npos += 1
        elif lam[k] < 0.0:
            nneg += 1
    if npos == 0 and nneg == 0:  # a plane: -2βd + γ ≤ 0 along its β axis
        for k in range(3):
            if beta[k] != 0.0:
                s = 1.0 if beta[k] > 0.0 else -1.0
                qd = axes[0, k] * center[0] + axes[1, k] * center[1] + axes[2, k] * center[2]
                N[0, 0], N[0, 1], N[0, 2] = -s * axes[0, k], -s * axes[1, k], -s * axes[2, k]
                h[0] = -s * qd - s * gamma / (2.0 * beta[k])
                return 1, _AXIAL_NONE
        return 0, _AXIAL_NONE
    if nneg == 0 and central:
        return _cylinder_rows(center, axes, lam, -gamma, N, h, np.int64(0)), _AXIAL_NONE
    if nneg == 0:  # convex paraboloid: the vertex half-space, the rest once s is bounded
        for k in range(3):
            if beta[k] != 0.0:
                s = 1.0 if beta[k] > 0.0 else -1.0
                qd = axes[0, k] * center[0] + axes[1, k] * center[1] + axes[2, k] * center[2]
                N[0, 0], N[0, 1], N[0, 2] = -s * axes[0, k], -s * axes[1, k], -s * axes[2, k]
                h[0] = -s * qd - gamma / (2.0 * abs(beta[k]))
                axial_par[0], axial_par[1], axial_par[2] = axes[0, k], axes[1, k], axes[2, k]
                axial_par[3], axial_par[4] = beta[k], gamma
                return 1, _AXIAL_PARABOLOID
        return 0, _AXIAL_NONE
    if nneg == 1 and npos == 2 and central:  # cone / one-sheet hyperboloid
        for k in range(3):
            if lam[k] < 0.0:
                axial_par[0], axial_par[1], axial_par[2] = axes[0, k], axes[1, k], axes[2, k]
                axial_par[3], axial_par[4] = lam[k], -gamma
        return 0, _AXIAL_CONE
    return 0, _AXIAL_NONE


@jit
def _axial_rhs(kind, par, s_lo, s_hi):
    """The cylinder right-hand side of an axial record with the axial coordinate s in [s_lo, s_hi]."""
    if kind == _AXIAL_CONE:
        s = max(abs(s_lo), abs(s_hi))
        return par[4] + abs(par[3]) * s * s
    return 2.0 * par[3] * (s_hi if par[3] > 0.0 else s_lo) - par[4]


# -- the LP ----------------------------------------------------------------------------------------


@jit
def _extents_kernel(N, h, m, slack, D, nd, out):
    """Extremes of D[k]·x (k < nd) over the vertices of {x : N[:m] x ≤ h[:m] + slack}; returns the count.

    Every triple of planes with an invertible 3×3 system gives a candidate (Cramer's rule); the
    candidates inside all half-spaces (with ``slack``) are the polytope's vertices. out[k] = (min, max).
    """
    for k in range(nd):
        out[k, 0] = math.inf
        out[k, 1] = -math.inf
    count = 0
    for i in range(m):
        for j in range(i + 1, m):
            c0 = N[i, 1] * N[j, 2] - N[i, 2] * N[j, 1]
            c1 = N[i, 2] * N[j, 0] - N[i, 0] * N[j, 2]
            c2 = N[i, 0] * N[j, 1] - N[i, 1] * N[j, 0]
            for k in range(j + 1, m):
                det = N[k, 0] * c0 + N[k, 1] * c1 + N[k, 2] * c2
                if abs(det) < tol.PARALLEL:
                    continue
                jk0 = N[j, 1] * N[k, 2] - N[j, 2] * N[k, 1]
                jk1 = N[j, 2] * N[k, 0] - N[j, 0] * N[k, 2]
                jk2 = N[j, 0] * N[k, 1] - N[j, 1] * N[k, 0]
                ki0 = N[k, 1] * N[i, 2] - N[k, 2] * N[i, 1]
                ki1 = N[k, 2] * N[i, 0] - N[k, 0] * N[i, 2]
                ki2 = N[k, 0] * N[i, 1] - N[k, 1] * N[i, 0]
                x = (h[i] * jk0 + h[j] * ki0 + h[k] * c0) / det
                y = (h[i] * jk1 + h[j] * ki1 + h[k] * c1) / det
                z = (h[i] * jk2 + h[j] * ki2 + h[k] * c2) / det
                ok = True
                for r in range(m):
                    if N[r, 0] * x + N[r, 1] * y + N[r, 2] * z > h[r] + slack:
                        ok = False
                        break
                if ok:
                    count += 1
                    for q in range(nd):
                        val = D[q, 0] * x + D[q, 1] * y + D[q, 2] * z
                        out[q, 0] = min(out[q, 0], val)
                        out[q, 1] = max(out[q, 1], val)
    return count


@jit
def _box_rows(box, N, h, at):
    for e in range(3):
        N[at, 0], N[at, 1], N[at, 2] = 0.0, 0.0, 0.0
        N[at, e] = 1.0
        h[at] = box[3 + e]
        N[at + 1, 0], N[at + 1, 1], N[at + 1, 2] = 0.0, 0.0, 0.0
        N[at + 1, e] = -1.0
        h[at + 1] = -box[e]
        at += 2
    return at


@jit(inline="always")
def _copy_rows(N, h, m, M, H):
    """M[:m] = N[:m] and H[:m] = h[:m] for rows of 3 (element by element: numba's slice assignment types a
    shape-mismatch error message, str() of tuples included, costing seconds of compilation per kernel)."""
    for i in range(m):
        M[i, 0], M[i, 1], M[i, 2] = N[i, 0], N[i, 1], N[i, 2]
        H[i] = h[i]


@jit
def _polytope_box(N, h, m, box, slack, out):
    """out (6,) = AABB of {x ∈ box : N[:m] x ≤ h[:m]}, padded by ``slack`` and cut to ``box``; False if empty."""
    M = np.empty((m + 6, 3))
    H = np.empty(m + 6)
    _copy_rows(N, h, m, M, H)
    n = _box_rows(box, M, H, np.int64(m))
    D = np.eye(3)
    ext = np.empty((3, 2))
    if _extents_kernel(M, H, n, slack, D, np.int64(3), ext) == 0:
        for e in range(3):
            out[e], out[3 + e] = math.inf, -math.inf
        return False
    for e in range(3):
        out[e] = max(ext[e, 0] - slack, box[e])
        out[3 + e] = min(ext[e, 1] + slack, box[3 + e])
    return True


# -- term boxes --------------------------------------------------------------------------------------


@jit
def _term_boxes_kernel(Ms, term_start, search, has_limit, boxes, unbounded):
    """boxes (T, 6), unbounded (T,) of the normal form with matrices Ms (n, 4, 4); returns the scale used."""
    n = Ms.shape[0]
    rowsN = np.empty((n, MAX_ROWS, 3))
    rowsH = np.empty((n, MAX_ROWS))
    nrows = np.zeros(n, dtype=np.int64)
    kind = np.zeros(n, dtype=np.int64)
    par = np.zeros((n, 5))
    centers = np.empty((n, 3))
    axes = np.empty((n, 3, 3))
    lams = np.empty((n, 3))
    scale = 0.0
    for q in range(n):
        nrows[q], kind[q] = _support_kernel(Ms[q], 1.0, rowsN[q], rowsH[q], par[q], centers[q], axes[q], lams[q])
        for r in range(nrows[q]):
            scale = max(scale, abs(rowsH[q, r]))
    if has_limit:
        for e in range(6):
            scale = max(scale, abs(search[e]))
    if scale == 0.0:
        scale = 1.0  # every row passes through the origin: no length in the data
    huge = tol.UNBOUNDED * scale
    box = np.empty(6)
    if has_limit:
        for e in range(6):
            box[e] = search[e]
    else:
        for e in range(3):
            box[e], box[3 + e] = -huge, huge
    slack = tol.SUPPORT_SLACK * scale
    T = term_start.shape[0] - 1
    for t in range(T):
        a, b = term_start[t], term_start[t + 1]
        m = 0
        n_axial = 0
        for q in range(a, b):
            m += nrows[q]
            if kind[q] != _AXIAL_NONE:
                n_axial += 1
        cap = m + MAX_ROWS * n_axial + 6
        N = np.empty((cap, 3))
        H = np.empty(cap)
        at = 0
        for q in range(a, b):
            for r in range(nrows[q]):
                N[at, 0], N[at, 1], N[at, 2] = rowsN[q, r, 0], rowsN[q, r, 1], rowsN[q, r, 2]
                H[at] = rowsH[q, r]
                at += 1
        out = boxes[t]
        if at > MAX_TERM_ROWS:  # member by member: the intersection of their boxes
            for e in range(6):
                out[e] = box[e]
            for q in range(a, b):
                if nrows[q] == 0:
                    continue
                mb = np.empty(6)
                if not _polytope_box(rowsN[q], rowsH[q], nrows[q], box, slack, mb):
                    for e in range(3):
                        out[e], out[3 + e] = math.inf, -math.inf
                    break
                for e in range(3):
                    out[e] = max(out[e], mb[e])
                    out[3 + e] = min(out[3 + e], mb[3 + e])
            ok = out[0] <= out[3] and out[1] <= out[4] and out[2] <= out[5]
        else:
            ok = _polytope_box(N, H, np.int64(at), box, slack, out)
            rounds = 2 if n_axial > 0 else 0
            D = np.empty((n_axial, 3))
            ext = np.empty((n_axial, 2))
            base = at
            for _ in range(rounds):
                if not ok:
                    break
                k = 0
                for q in range(a, b):
                    if kind[q] != _AXIAL_NONE:
                        D[k, 0], D[k, 1], D[k, 2] = par[q, 0], par[q, 1], par[q, 2]
                        k += 1
                M = np.empty((at + 6, 3))
                HM = np.empty(at + 6)
                _copy_rows(N, H, at, M, HM)
                nm = _box_rows(box, M, HM, np.int64(at))
                if _extents_kernel(M, HM, nm, slack, D, np.int64(n_axial), ext) == 0:
                    ok = False
                    break
                k = 0
                grown = base
                for q in range(a, b):
                    if kind[q] == _AXIAL_NONE:
                        continue
                    lo, hi = ext[k, 0], ext[k, 1]
                    k += 1
                    if max(abs(lo), abs(hi)) >= 0.5 * huge and not has_limit:
                        continue
                    qa = par[q, 0] * centers[q, 0] + par[q, 1] * centers[q, 1] + par[q, 2] * centers[q, 2]
                    rhs = _axial_rhs(kind[q], par[q], lo - qa - slack, hi - qa + slack)
                    grown = _cylinder_rows(centers[q], axes[q], lams[q], rhs, N, H, np.int64(grown))
                at = grown
                ok = _polytope_box(N, H, np.int64(at), box, slack, out)
        if not ok:
            for e in range(3):
                out[e], out[3 + e] = math.inf, -math.inf
            unbounded[t] = False
        else:
            far = False
            for e in range(6):
                if abs(out[e]) >= 0.5 * huge:
                    far = True
            unbounded[t] = far and not has_limit
    return scale


def term_boxes(nf, limit: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Return a bounding box per term of a normal form and whether the term is unbounded.

    Parameters
    ----------
    nf : NormalForm
    limit : (6,) float64 or None — a box every result is cut to (from the user's bounding sphere).

    Returns
    -------
    boxes : (T, 6) float64 — (lo, hi) per term; ``EMPTY_BOX`` rows for provably empty terms.
    unbounded : (T,) bool — the convex members do not bound the term (only possible without
        ``limit``; the row then reaches the search box).
    """
    from csgnb.csg.normal_form import NormalForm

    as_instance(nf, NormalForm, "nf", "a NormalForm (csgnb.csg.to_normal_form)")
    Ms = np.ascontiguousarray(np.array([q.matrix for q in nf.quadrics]).reshape(-1, 4, 4))
    return term_boxes_of_matrices(Ms, np.ascontiguousarray(nf.term_start), limit)


def term_boxes_of_matrices(Ms: np.ndarray, term_start: np.ndarray, limit=None):
    """As :func:`term_boxes`, for quadric matrices ``Ms`` : (n, 4, 4) and ``term_start`` : (T + 1,)."""
    T = len(term_start) - 1
    boxes = np.empty((T, 6))
    unbounded = np.zeros(T, dtype=np.bool_)
    search = np.zeros(6) if limit is None else as_finite_array(limit, (6,), "limit")
    _term_boxes_kernel(Ms, term_start, search, limit is not None, boxes, unbounded)
    return boxes, unbounded


# -- surface boxes -----------------------------------------------------------------------------------


@jit
def _surface_boxes_kernel(Ms, term_of, term_box, scale, out):
    """out[q] (6,) = a box containing the part of quadric q's surface inside its term's box."""
    N = np.empty((MAX_ROWS * 2 + 2, 3))
    H = np.empty(MAX_ROWS * 2 + 2)
    par = np.empty(5)
    center = np.empty(3)
    axes = np.empty((3, 3))
    lam = np.empty(3)
    slack = tol.SUPPORT_SLACK * scale
    for q in range(Ms.shape[0]):
        tb = term_box[term_of[q]]
        o = out[q]
        if tb[0] > tb[3] or tb[1] > tb[4] or tb[2] > tb[5]:
            for e in range(6):
                o[e] = tb[e]
            continue
        m, _ = _support_kernel(Ms[q], 1.0, N, H, par, center, axes, lam)
        if m == 1 and lam[0] == 0.0 and lam[1] == 0.0 and lam[2] == 0.0:  # a plane: its polygon
            N[1, 0], N[1, 1], N[1, 2] = -N[0, 0], -N[0, 1], -N[0, 2]
            H[1] = -H[0]
            _polytope_box(N, H, np.int64(2), tb, slack, o)
            continue
        if m == 0:  # the convex side may be the outside (a hole's cylinder)
            m, _ = _support_kernel(Ms[q], -1.0, N, H, par, center, axes, lam)
        if m > 0:
            _polytope_box(N, H, np.int64(m), tb, slack, o)
        else:
            for e in range(6):
                o[e] = tb[e]


def surface_boxes(nf, term_box: np.ndarray, scale: float) -> np.ndarray:
    """Return per quadric a box containing its surface inside its term's box : (n, 6) float64.

    A plane gives the box of its polygon; a quadric with a convex side (``Q ≤ 0`` or ``Q ≥ 0``)
    the box of that side within the term box (the surface bounds it); others the term box.
    ``scale`` : the model size, for the rounding slack.
    """
    from csgnb.csg.normal_form import NormalForm

    as_instance(nf, NormalForm, "nf", "a NormalForm (csgnb.csg.to_normal_form)")
    term_box = as_finite_array(term_box, (nf.n_terms, 6), "term_box", finite=False)
    Ms = np.ascontiguousarray(np.array([q.matrix for q in nf.quadrics]).reshape(-1, 4, 4))
    out = np.empty((len(Ms), 6))
    _surface_boxes_kernel(Ms, np.ascontiguousarray(nf.term_of), np.ascontiguousarray(term_box, dtype=np.float64),
                          float(scale), out)
    return out


def surface_box(q: Quadric, box: np.ndarray, scale: float | None = None) -> np.ndarray:
    """Return a box containing the part of the surface ``Q = 0`` inside ``box`` : (6,) float64."""
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a csgnb.quadric.Quadric, got {type(q).__name__}")
    box = as_finite_array(box, (6,), "box")
    scale = float(np.max(np.abs(box))) if scale is None else as_positive(scale, "scale")
    out = np.empty((1, 6))
    _surface_boxes_kernel(np.ascontiguousarray(q.matrix)[None], np.zeros(1, dtype=np.int64), box[None],
                          float(scale), out)
    return out[0]


def support_halfspaces(q: Quadric) -> tuple[np.ndarray, np.ndarray]:
    """Return half-spaces ``N x ≤ h`` that contain the solid ``{Q ≤ 0}`` when it is convex.

    Returns
    -------
    normals : (k, 3) float64 — unit normals; ``k = 0`` when the solid is not convex (or not
        bounded in any direction), so that nothing is claimed.
    offsets : (k,) float64 — an empty solid gives one impossible half-space (``0·x ≤ -1``).
    """
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a csgnb.quadric.Quadric, got {type(q).__name__}")
    N, h = np.empty((MAX_ROWS, 3)), np.empty(MAX_ROWS)
    m, _ = _support_kernel(np.ascontiguousarray(q.matrix), 1.0, N, h, np.empty(5), np.empty(3), np.empty((3, 3)),
                           np.empty(3))
    return N[:m].copy(), h[:m].copy()


def polytope_extents(normals, offsets, box, directions, scale: float | None = None) -> np.ndarray | None:
    """Return (min, max) of ``directions[k]·x`` over ``{x ∈ box : normals x ≤ offsets}`` : (k, 2).

    ``None`` when the set is empty. ``box`` : (6,) finite (lo, hi); ``scale`` the model size for
    the feasibility slack (default: of ``box``).
    """
    box = as_finite_array(box, (6,), "box")
    N0 = as_finite_array(normals, None, "normals").reshape(-1, 3)
    h0 = as_finite_array(offsets, None, "offsets").reshape(-1)
    N = np.empty((len(N0) + 6, 3))
    h = np.empty(len(N0) + 6)
    N[: len(N0)], h[: len(N0)] = N0, h0
    n = _box_rows(box, N, h, len(N0))
    if scale is None:
        scale = float(np.max(np.abs(box)))
    D = np.ascontiguousarray(as_finite_array(directions, None, "directions").reshape(-1, 3))
    out = np.empty((len(D), 2))
    if _extents_kernel(N, h, n, tol.SUPPORT_SLACK * float(scale), D, len(D), out) == 0:
        return None
    return out


def polytope_box(normals, offsets, box, scale: float | None = None) -> np.ndarray:
    """Return the AABB of ``{x ∈ box : normals x ≤ offsets}`` : (6,) float64 (``EMPTY_BOX`` if empty).

    ``box`` : (6,) finite (lo, hi). ``scale`` is the size of the model (default: of ``box``); the
    result is enlarged by ``tolerances.SUPPORT_SLACK``·scale so that rounding never makes it
    smaller than the true box.
    """
    box = as_finite_array(box, (6,), "box")
    N = np.ascontiguousarray(as_finite_array(normals, None, "normals").reshape(-1, 3))
    h = np.ascontiguousarray(as_finite_array(offsets, None, "offsets").reshape(-1))
    if scale is None:
        scale = float(np.max(np.abs(box)))
    out = np.empty(6)
    if not _polytope_box(N, h, len(h), box, tol.SUPPORT_SLACK * float(scale), out):
        return EMPTY_BOX.copy()
    return out
