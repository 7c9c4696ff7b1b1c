"""Axis-aligned bounding boxes of normal-form terms and of quadric surfaces inside them.

The sampler needs a finite box per term (the paper asks for a bounding sphere; we derive boxes
where the quadrics allow it). A quadric whose solid ``{Q ≤ 0}`` is convex — a half-space, a slab,
an elliptic cylinder, an ellipsoid — is contained in its supporting half-spaces

    u·x ≤ h(u) = u·q + √(ρ uᵀA⁺u),   ρ = qᵀb - c,   for unit u in the range of A

(q the center). Intersecting those half-spaces over a term's convex members, with a huge box
around everything, gives a polytope that contains the term; its vertices, enumerated as
feasible triples of planes (a small 3-variable LP, solved exactly by enumeration), bound it.
If the polytope reaches the huge box the term is unbounded. A cone or one-sheet hyperboloid
bounds the term across its axis once the axial coordinate is bounded (``Σ λ₊w² ≤ ρ + |λ₋|s²``):
a capped cone gets its cylinder of half-spaces in a second round. Other non-convex members
(two-sheet hyperboloids, complements of convex solids) bound nothing, so a bounded term can be
reported unbounded — pass a bounding sphere then.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit
from csgnb.quadric.heightfield import principal_frame
from csgnb.quadric.quadric import Quadric

__all__ = [
    "frame_cache_clear",
    "support_halfspaces",
    "polytope_box",
    "polytope_extents",
    "term_boxes",
    "surface_box",
    "EMPTY_BOX",
    "box_is_empty",
    "intersect_boxes",
]

#: An empty box (lo > hi).
EMPTY_BOX = np.array([np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf])

_PSD_TOLERANCE = 1e-12

# principal frames by matrix: term boxes, surface boxes and axial bounds all need them
_FRAMES: dict[bytes, object] = {}


def _frame(q: Quadric):
    key = q.matrix.tobytes()
    f = _FRAMES.get(key)
    if f is None:
        if len(_FRAMES) > 8192:
            _FRAMES.clear()
        f = _FRAMES[key] = principal_frame(q)
    return f


def frame_cache_clear() -> None:
    """Empty the cache of principal frames used for bounds."""
    _FRAMES.clear()


def box_is_empty(box: np.ndarray) -> bool:
    """Return whether ``box`` : (6,) (lo, hi) holds no point."""
    return bool(np.any(box[:3] > box[3:]))


def intersect_boxes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the intersection of two boxes : (6,) float64 (empty when lo > hi)."""
    return np.concatenate([np.maximum(a[:3], b[:3]), np.minimum(a[3:], b[3:])])


def support_halfspaces(q: Quadric) -> tuple[np.ndarray, np.ndarray]:
    """Return half-spaces ``N x ≤ h`` that contain the solid ``{Q ≤ 0}`` when it is convex.

    Returns
    -------
    normals : (k, 3) float64 — unit normals; ``k = 0`` when the solid is not convex (or not
        bounded in any direction), so that nothing is claimed.
    offsets : (k,) float64 — ``+inf`` never occurs; an empty solid gives one impossible
        half-space (``0·x ≤ -1``).
    """
    A, b, c = q.A, q.b, q.c
    scale = float(np.max(np.abs(q.matrix)))
    if np.max(np.abs(A)) <= 1e-14 * scale:
        # half-space: Q = -2 bᵀx + c ≤ 0  ⇔  (-b̂)·x ≤ -c / (2|b|)
        nb = float(np.linalg.norm(b))
        return (-b / nb)[None, :], np.array([-c / (2.0 * nb)])
    frame = _frame(q)
    lam = frame.eigenvalues
    top = float(np.max(np.abs(lam)))
    if np.any(lam < -_PSD_TOLERANCE * top) or not frame.central:
        return np.empty((0, 3)), np.empty(0)
    rho = float(frame.center @ b) - c
    if rho < 0.0:
        return np.zeros((1, 3)), np.array([-1.0])
    pos = lam > _PSD_TOLERANCE * top
    U = frame.axes[:, pos]
    Ainv = (U / lam[pos]) @ U.T  # pseudo-inverse on the range of A
    dirs = [U.T, -U.T]
    proj = (U @ U.T)  # world axes projected on the range of A
    for k in range(3):
        v = proj[:, k]
        nv = float(np.linalg.norm(v))
        if nv > 1e-9:
            dirs += [v[None, :] / nv, -v[None, :] / nv]
    N = np.vstack(dirs)
    h = N @ frame.center + np.sqrt(np.maximum(rho * np.einsum("ki,ij,kj->k", N, Ainv, N), 0.0))
    return N, h


@jit
def _polytope_extents_kernel(N, h, tol, D, out):
    """Extremes of D[k]·x over the vertices of {x : N x ≤ h + tol}; returns the vertex count.

    Every triple of planes with an invertible 3×3 system gives a candidate (Cramer's rule); the
    candidates inside all half-spaces (with ``tol`` slack) are the polytope's vertices.
    out[k] = (min, max).
    """
    m = N.shape[0]
    for k in range(D.shape[0]):
        out[k, 0] = math.inf
        out[k, 1] = -math.inf
    count = 0
    for i in range(m):
        for j in range(i + 1, m):
            # n_i × n_j, reused for every third plane
            c0 = N[i, 1] * N[j, 2] - N[i, 2] * N[j, 1]
            c1 = N[i, 2] * N[j, 0] - N[i, 0] * N[j, 2]
            c2 = N[i, 0] * N[j, 1] - N[i, 1] * N[j, 0]
            for k in range(j + 1, m):
                det = N[k, 0] * c0 + N[k, 1] * c1 + N[k, 2] * c2
                if abs(det) < 1e-12:
                    continue
                # x = (h_i (n_j × n_k) + h_j (n_k × n_i) + h_k (n_i × n_j)) / det
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
                    if N[r, 0] * x + N[r, 1] * y + N[r, 2] * z > h[r] + tol:
                        ok = False
                        break
                if ok:
                    count += 1
                    for q in range(D.shape[0]):
                        val = D[q, 0] * x + D[q, 1] * y + D[q, 2] * z
                        out[q, 0] = min(out[q, 0], val)
                        out[q, 1] = max(out[q, 1], val)
    return count


def polytope_extents(normals, offsets, box, directions, scale: float | None = None) -> np.ndarray | None:
    """Return (min, max) of ``directions[k]·x`` over ``{x ∈ box : normals x ≤ offsets}`` : (k, 2).

    ``None`` when the set is empty. ``box`` : (6,) finite (lo, hi); ``scale`` the model size for
    the feasibility slack (default: of ``box``).
    """
    box = np.asarray(box, dtype=np.float64)
    eye = np.eye(3)
    N = np.vstack([np.asarray(normals, dtype=np.float64).reshape(-1, 3), eye, -eye])
    h = np.concatenate([np.asarray(offsets, dtype=np.float64).reshape(-1), box[3:], -box[:3]])
    if scale is None:
        scale = float(np.max(np.abs(box)))
    scale = float(scale) + 1e-300
    D = np.ascontiguousarray(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
    out = np.empty((len(D), 2))
    if _polytope_extents_kernel(np.ascontiguousarray(N), np.ascontiguousarray(h), 1e-9 * scale, D, out) == 0:
        return None
    return out


def polytope_box(normals: np.ndarray, offsets: np.ndarray, box: np.ndarray, scale: float | None = None) -> np.ndarray:
    """Return the AABB of ``{x ∈ box : normals x ≤ offsets}`` : (6,) float64 (``EMPTY_BOX`` if empty).

    ``box`` : (6,) finite (lo, hi). ``scale`` is the size of the model (default: of ``box``); the
    result is enlarged by 1e-9·scale so that rounding never makes it smaller than the true box.
    """
    box = np.asarray(box, dtype=np.float64)
    if scale is None:
        scale = float(np.max(np.abs(box)))
    ext = polytope_extents(normals, offsets, box, np.eye(3), scale)
    if ext is None:
        return EMPTY_BOX.copy()
    pad = 1e-9 * (float(scale) + 1e-300)
    out = np.concatenate([ext[:, 0] - pad, ext[:, 1] + pad])
    return intersect_boxes(out, box)


def _axial_bound(q: Quadric):
    """For a central quadric with one negative eigenvalue (cone, one-sheet hyperboloid): the data
    that bounds ``{Q ≤ 0}`` across its axis once the axial coordinate is bounded.

    Returns (center, axis, λ_neg, U_pos, λ_pos, ρ) or None. Inside, with s the axial coordinate
    and w the others, ``Σ λ_pos w² ≤ ρ + |λ_neg| s²``.
    """
    A = q.A
    if np.max(np.abs(A)) <= 1e-14 * float(np.max(np.abs(q.matrix))):
        return None
    frame = _frame(q)
    lam = frame.eigenvalues
    top = float(np.max(np.abs(lam)))
    neg = lam < -_PSD_TOLERANCE * top
    pos = lam > _PSD_TOLERANCE * top
    if not frame.central or neg.sum() != 1 or pos.sum() != 2:
        return None
    rho = float(frame.center @ q.b) - q.c
    return frame.center, frame.axes[:, neg][:, 0], float(lam[neg][0]), frame.axes[:, pos], lam[pos], rho


def _axial_halfspaces(data, s_range):
    """Half-spaces containing the solid of ``_axial_bound`` data with the axial coordinate in s_range."""
    center, axis, lam_neg, U, lam, rho = data
    s_max = max(abs(s_range[0] - axis @ center), abs(s_range[1] - axis @ center))
    rhs = rho + abs(lam_neg) * s_max * s_max
    if rhs < 0.0:
        return np.zeros((1, 3)), np.array([-1.0])
    Ainv = (U / lam) @ U.T
    dirs = [U.T, -U.T]
    proj = U @ U.T
    for k in range(3):
        v = proj[:, k]
        nv = float(np.linalg.norm(v))
        if nv > 1e-9:
            dirs += [v[None, :] / nv, -v[None, :] / nv]
    N = np.vstack(dirs)
    return N, N @ center + np.sqrt(np.maximum(rhs * np.einsum("ki,ij,kj->k", N, Ainv, N), 0.0))


def _is_plane(q: Quadric) -> bool:
    return bool(np.max(np.abs(q.A)) <= 1e-14 * float(np.max(np.abs(q.matrix))))


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
        ``limit``; the row then holds the huge search box).
    """
    spaces = [support_halfspaces(q) for q in nf.quadrics]
    offsets = [abs(h[np.isfinite(h)]).max() for _, h in spaces if len(h)]
    scale = 1.0 + max(offsets, default=0.0)
    if limit is not None:
        scale = max(scale, float(np.max(np.abs(limit))))
    huge = 1e6 * scale
    search = np.array([-huge] * 3 + [huge] * 3) if limit is None else np.asarray(limit, dtype=np.float64)
    boxes = np.empty((nf.n_terms, 6))
    unbounded = np.zeros(nf.n_terms, dtype=bool)
    axial = [_axial_bound(q) for q in nf.quadrics]
    for i in range(nf.n_terms):
        idx = nf.term(i)
        N = np.vstack([spaces[k][0] for k in idx] + [np.empty((0, 3))])
        h = np.concatenate([spaces[k][1] for k in idx] + [np.empty(0)])
        cones = [axial[k] for k in idx if axial[k] is not None]
        box = polytope_box(N, h, search, scale)
        # cones and one-sheet hyperboloids bound the term across their axis once the axial
        # coordinate is bounded (a capped cone): add those half-spaces and solve again
        for _ in range(2 if cones else 0):
            if box_is_empty(box):
                break
            extra_N, extra_h = [N], [h]
            for data in cones:
                s_range = polytope_extents(N, h, search, data[1][None, :], scale)
                if s_range is None or np.max(np.abs(s_range)) >= 0.5 * huge:
                    continue
                n2, h2 = _axial_halfspaces(data, s_range[0])
                extra_N.append(n2)
                extra_h.append(h2)
            N, h = np.vstack(extra_N), np.concatenate(extra_h)
            box = polytope_box(N, h, search, scale)
        boxes[i] = box
        if limit is None and not box_is_empty(box):
            unbounded[i] = bool(np.any(np.abs(box) >= 0.5 * huge))
    return boxes, unbounded


def surface_box(q: Quadric, box: np.ndarray, scale: float | None = None) -> np.ndarray:
    """Return a box containing the part of the surface ``Q = 0`` inside ``box`` : (6,) float64.

    A plane gives the box of its polygon in ``box``; a quadric with a convex side (``Q ≤ 0`` or
    ``Q ≥ 0``) the box of that side within ``box`` (the surface bounds it); others ``box`` itself.
    """
    if _is_plane(q):
        N, h = support_halfspaces(q)
        return polytope_box(np.vstack([N, -N]), np.concatenate([h, -h]), box, scale)
    for side in (q, -q):
        N, h = support_halfspaces(side)
        if len(h):
            return polytope_box(N, h, box, scale)
    return np.asarray(box, dtype=np.float64).copy()
