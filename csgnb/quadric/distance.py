"""Conservative signed distance to a quadric surface (paper §3.3, eq. 8–12, Figure 6).

Along any unit direction v, ``Q(x₀ + t v) = Q(x₀) + 2t (Ax₀ - b)ᵀv + t² vᵀAv`` (eq. 9) is
bounded by ``Q(x₀) ± 2t |Ax₀ - b| + t² λ_max/min`` (eq. 10–11), independently of v. The first
positive root of the bound that can change the sign of Q(x₀) is a radius that contains no
surface point: |d(x₀)| never exceeds the true distance.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb.quadric.evaluate import _check_quadric, as_points, ieee_jit
from csgnb.quadric.quadric import Quadric

__all__ = ["signed_distance"]


@ieee_jit
def _distance_kernel(Q, lam_min, lam_max, points, out):
    """out[i] = d(points[i]) (eq. 12); Q : (4, 4), points : (n, 3), out : (n,).

    With γ = Q(x₀), g = |Ax₀ - b| and λ = λ_max if γ < 0 else λ_min, the bound's first
    positive root is |γ| / (g + √(g² - λγ)) — one cancellation-free expression for all
    signs of λ (eq. 10–11 solved for t). No real root means the bound never reaches zero:
    no surface at all on that side, distance ±inf.
    """
    a00, a01, a02, a11, a12, a22 = Q[0, 0], Q[0, 1], Q[0, 2], Q[1, 1], Q[1, 2], Q[2, 2]
    m0, m1, m2, c = Q[0, 3], Q[1, 3], Q[2, 3], Q[3, 3]
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        g0 = a00 * x + a01 * y + a02 * z + m0  # (Ax₀ - b)
        g1 = a01 * x + a11 * y + a12 * z + m1
        g2 = a02 * x + a12 * y + a22 * z + m2
        # Q(x₀) = x₀ᵀ(Ax₀ - b) - x₀ᵀb + c = x₀ᵀg + (m·x₀) + c
        gamma = x * g0 + y * g1 + z * g2 + (m0 * x + m1 * y + m2 * z) + c
        g = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        if gamma < 0.0:
            disc = g * g - lam_max * gamma
            out[i] = gamma / (g + math.sqrt(disc)) if disc >= 0.0 else -math.inf
        elif gamma > 0.0:
            disc = g * g - lam_min * gamma
            out[i] = gamma / (g + math.sqrt(disc)) if disc >= 0.0 else math.inf
        else:
            out[i] = 0.0


def signed_distance(q: Quadric, points) -> np.ndarray:
    """Return the conservative signed distance d(x₀) to the surface of ``q`` (eq. 12).

    Parameters
    ----------
    q : Quadric
    points : (n, 3) float64

    Returns
    -------
    (n,) float64
        Negative inside (Q < 0), positive outside, 0 on the surface. No surface point lies
        closer to x₀ than |d(x₀)|; ±inf where the bound proves there is none on that side.
        The relative error tends to 0 as x₀ approaches the surface. (Rounding in Q(x₀)
        makes the bound hold up to a few ulps of the terms of Q(x₀).)
    """
    Q = _check_quadric(q)
    pts = as_points(points)
    lam = q.eigenvalues
    out = np.empty(pts.shape[0])
    _distance_kernel(Q, float(lam[0]), float(lam[-1]), pts, out)
    return out
