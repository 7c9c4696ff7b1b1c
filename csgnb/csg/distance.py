"""Conservative distances to a CSG surface in normal form (paper §5, eq. 19–22).

With d(Q, p) the conservative signed distance to one quadric (eq. 12, negative inside):

* eq. 19, the distance to the CSG surface: ``d(S, p) = minᵢ maxⱼ d(Q_ij, p)``;
* eq. 22, the distance *relative to quadric Q_ab*, for points p on Q_ab:

      d_Qab(S, p) = max( -min_{i≠a} maxⱼ d(Q_ij, p),  max_{j≠b} d(Q_aj, p) )

  negative: p is on the CSG surface and so is every point of Q_ab within |d_Qab|; positive: p is
  not, and neither is any point of Q_ab within d_Qab.

One surface reached through several terms (after the normal form duplicated a shared sub-graph,
e.g. ``A ∩ (B ∪ C) = (A ∩ B) ∪ (A ∩ C)``) needs care that eq. 22 does not take: there the other
term's max is exactly 0 on the shared surface and eq. 22 would discard it everywhere. For a term i
that holds the surface of Q_ab (``surface`` equal):

* with the same orientation, only terms i < a may discard (each point is emitted by the first term
  that has it on its boundary), and they do so through their other quadrics;
* with the opposite orientation the two solids touch along the surface; the term discards through
  its other quadrics (a face shared by two touching solids is interior).

Kernels take the coefficient rows of :func:`csgnb.csg.normal_form.quadric_coefficients`.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb.csg.normal_form import NormalForm
from csgnb.errors import CsgnbError
from csgnb.quadric.arguments import as_count
from csgnb.quadric.evaluate import as_points, ieee_jit, inline_jit

__all__ = ["csg_distance", "relative_distance", "csg_value", "quadric_distance", "box_distance", "inline_jit"]


@inline_jit
def quadric_value(C, j, x, y, z):
    """Return Q_j(x, y, z) from coefficient row ``C[j]`` (see ``quadric_coefficients``)."""
    g0 = C[j, 0] * x + C[j, 1] * y + C[j, 2] * z + C[j, 6]
    g1 = C[j, 1] * x + C[j, 3] * y + C[j, 4] * z + C[j, 7]
    g2 = C[j, 2] * x + C[j, 4] * y + C[j, 5] * z + C[j, 8]
    return x * g0 + y * g1 + z * g2 + (C[j, 6] * x + C[j, 7] * y + C[j, 8] * z) + C[j, 9]


@inline_jit
def quadric_distance(C, j, x, y, z):
    """Return the conservative signed distance d(Q_j, p) of eq. 12 (as ``quadric.distance``)."""
    g0 = C[j, 0] * x + C[j, 1] * y + C[j, 2] * z + C[j, 6]  # A p - b
    g1 = C[j, 1] * x + C[j, 3] * y + C[j, 4] * z + C[j, 7]
    g2 = C[j, 2] * x + C[j, 4] * y + C[j, 5] * z + C[j, 8]
    gamma = x * g0 + y * g1 + z * g2 + (C[j, 6] * x + C[j, 7] * y + C[j, 8] * z) + C[j, 9]
    g = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    if gamma < 0.0:
        disc = g * g - C[j, 11] * gamma
        return gamma / (g + math.sqrt(disc)) if disc >= 0.0 else -math.inf
    if gamma > 0.0:
        disc = g * g - C[j, 10] * gamma
        return gamma / (g + math.sqrt(disc)) if disc >= 0.0 else math.inf
    return 0.0


@inline_jit
def box_distance(B, x, y, z):
    """Return the signed Euclidean distance to the box ``B = (lo₀, lo₁, lo₂, hi₀, hi₁, hi₂)``.

    Exact (negative inside: minus the distance to the nearest face), so it is a valid member of
    any max in eq. 19–22 for a box that contains the term.
    """
    e0 = max(B[0] - x, x - B[3])
    e1 = max(B[1] - y, y - B[4])
    e2 = max(B[2] - z, z - B[5])
    if e0 <= 0.0 and e1 <= 0.0 and e2 <= 0.0:
        return max(e0, max(e1, e2))
    o0, o1, o2 = max(e0, 0.0), max(e1, 0.0), max(e2, 0.0)
    return math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)


@ieee_jit
def _csg_distance_kernel(C, term_start, points, out):
    """out[k] = minᵢ maxⱼ d(Q_ij, p_k) (eq. 19); +inf for an empty normal form."""
    for k in range(points.shape[0]):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        best = math.inf
        for i in range(term_start.shape[0] - 1):
            m = -math.inf
            for j in range(term_start[i], term_start[i + 1]):
                m = max(m, quadric_distance(C, j, x, y, z))
                if m >= best:
                    break
            best = min(best, m)
        out[k] = best


@ieee_jit
def _csg_value_kernel(C, term_start, points, out):
    """out[k] = minᵢ maxⱼ Q_ij(p_k): its sign classifies p_k."""
    for k in range(points.shape[0]):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        best = math.inf
        for i in range(term_start.shape[0] - 1):
            m = -math.inf
            for j in range(term_start[i], term_start[i + 1]):
                m = max(m, quadric_value(C, j, x, y, z))
            best = min(best, m)
        out[k] = best


@ieee_jit
def _relative_distance_kernel(C, term_start, surface, orient, index, points, out):
    """out[k] = d_Qab(S, p_k) (eq. 22) with the shared-surface rule of the module docstring."""
    n_terms = term_start.shape[0] - 1
    a = 0
    for i in range(n_terms):
        if term_start[i] <= index < term_start[i + 1]:
            a = i
    s_ab, o_ab = surface[index], orient[index]
    for k in range(points.shape[0]):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        own = -math.inf
        for j in range(term_start[a], term_start[a + 1]):
            if j != index:
                own = max(own, quadric_distance(C, j, x, y, z))
        other = math.inf
        for i in range(n_terms):
            if i == a:
                continue
            skip = False
            for j in range(term_start[i], term_start[i + 1]):
                if surface[j] == s_ab and orient[j] == o_ab and i > a:
                    skip = True
            if skip:
                continue
            m = -math.inf
            for j in range(term_start[i], term_start[i + 1]):
                if surface[j] != s_ab:
                    m = max(m, quadric_distance(C, j, x, y, z))
            other = min(other, m)
        out[k] = max(-other, own)


def _prepare(nf: NormalForm, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not isinstance(nf, NormalForm):
        raise TypeError(f"expected a NormalForm (csgnb.csg.to_normal_form), got {type(nf).__name__}")
    pts = as_points(points)
    return np.ascontiguousarray(nf.coefficients), np.ascontiguousarray(nf.term_start), pts


def csg_distance(nf: NormalForm, points) -> np.ndarray:
    """Return the conservative signed distance to the CSG surface (eq. 19).

    Parameters
    ----------
    nf : NormalForm
    points : (n, 3) float64

    Returns
    -------
    (n,) float64 — negative inside the object, positive outside; no point of the surface is
    closer than |d|. (+inf everywhere for an empty normal form.)
    """
    C, ts, pts = _prepare(nf, points)
    out = np.empty(pts.shape[0])
    _csg_distance_kernel(C, ts, pts, out)
    return out


def csg_value(nf: NormalForm, points) -> np.ndarray:
    """Return ``minᵢ maxⱼ Q_ij(p)`` : (n,) float64 — negative inside, positive outside."""
    C, ts, pts = _prepare(nf, points)
    out = np.empty(pts.shape[0])
    _csg_value_kernel(C, ts, pts, out)
    return out


def relative_distance(nf: NormalForm, index: int, points) -> np.ndarray:
    """Return the quadric-relative conservative signed distance d_Qab(S, p) (eq. 20–22).

    Parameters
    ----------
    nf : NormalForm
    index : int — the quadric Q_ab, an index into ``nf.quadrics``.
    points : (n, 3) float64 — points on Q_ab (elsewhere the value has no guarantee).

    Returns
    -------
    (n,) float64 — negative where p belongs to the CSG surface, and then so does every point of
    Q_ab within |d|; positive where it does not, and neither does any point of Q_ab within d.
    """
    C, ts, pts = _prepare(nf, points)
    index = as_count(index, "index")
    if not index < len(nf):
        raise CsgnbError(f"quadric index {index} out of range for {len(nf)} quadrics")
    out = np.empty(pts.shape[0])
    _relative_distance_kernel(
        C, ts, np.ascontiguousarray(nf.surface), np.ascontiguousarray(nf.orientation), int(index), pts, out
    )
    return out
