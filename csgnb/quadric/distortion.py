"""Heightfield distortion δ(x, y) (paper eq. 13) and its bounds over axis-aligned rectangles.

δ is the area stretch of the map (x, y) ↦ (x, y, h(x, y)): 1/|cos| of the angle between the
surface normal and the sampling-plane normal. In u = x², v = y² it reads

    δ² = 1 + (αₓ²u + α_y²v) / (αₓu + α_y v + α_c),

a linear-fractional function, hence monotone along every line and extremal at a vertex of a
convex polygon (the paper's lemma). A rectangle inside one quadrant is a rectangle in (u, v),
so evaluating its four corners bounds δ over it; δ is even in x and y, so a rectangle that
straddles an axis is first folded into the quadrant.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb.quadric.evaluate import as_points, ieee_jit
from csgnb.quadric.heightfield import _as_alpha, as_coordinates

__all__ = ["distortion", "distortion_bounds"]


@ieee_jit
def _distortion_kernel(alpha, x, y, out):
    """out[i] = δ(x, y) (eq. 13); NaN outside the domain, inf where h = 0; x, y, out : (n,)."""
    ax, ay, ac = alpha[0], alpha[1], alpha[2]
    bx, by = ax + ax * ax, ay + ay * ay
    for i in range(x.shape[0]):
        u = x[i] * x[i]
        v = y[i] * y[i]
        out[i] = math.sqrt((bx * u + by * v + ac) / (ax * u + ay * v + ac))


@ieee_jit
def _distortion_bounds_kernel(alpha, x_lo, y_lo, x_hi, y_hi, out_min, out_max):
    """out_min[i], out_max[i] = min δ, max δ over [x_lo, x_hi] × [y_lo, y_hi].

    δ² - 1 = (αₓ²u + α_y²v) / (αₓu + α_y v + α_c) at the four corners of the folded
    rectangle in (u, v) = (x², y²). A corner outside the domain (h² ≤ 0) counts as +inf:
    the maximum becomes inf, the minimum is taken over the valid corners. Written
    branch-free (selects only) so that the loop vectorises.
    """
    ax, ay, ac = alpha[0], alpha[1], alpha[2]
    sx, sy = ax * ax, ay * ay
    inf = math.inf
    for i in range(x_lo.shape[0]):
        x0, y0, x1, y1 = x_lo[i], y_lo[i], x_hi[i], y_hi[i]
        u0, u1 = x0 * x0, x1 * x1
        v0, v1 = y0 * y0, y1 * y1
        uhi, vhi = max(u0, u1), max(v0, v1)
        # a rectangle straddling an axis folds onto [0, max] (δ is even in x and y)
        ulo = 0.0 if x0 * x1 <= 0.0 else min(u0, u1)
        vlo = 0.0 if y0 * y1 <= 0.0 else min(v0, v1)
        den00 = ax * ulo + ay * vlo + ac
        den10 = ax * uhi + ay * vlo + ac
        den01 = ax * ulo + ay * vhi + ac
        den11 = ax * uhi + ay * vhi + ac
        r00 = (sx * ulo + sy * vlo) / den00 if den00 > 0.0 else inf
        r10 = (sx * uhi + sy * vlo) / den10 if den10 > 0.0 else inf
        r01 = (sx * ulo + sy * vhi) / den01 if den01 > 0.0 else inf
        r11 = (sx * uhi + sy * vhi) / den11 if den11 > 0.0 else inf
        out_min[i] = math.sqrt(1.0 + min(min(r00, r10), min(r01, r11)))
        out_max[i] = math.sqrt(1.0 + max(max(r00, r10), max(r01, r11)))


def distortion(alpha, x, y) -> np.ndarray:
    """Return the heightfield distortion δ(x, y) ≥ 1 (eq. 13) : (n,) float64.

    Parameters
    ----------
    alpha : (3,) float64 — (αₓ, α_y, α_c) of a sampling plane.
    x, y : (n,) float64 — local plane coordinates (broadcast together).

    NaN outside the heightfield's domain, inf on its boundary (where h = 0).
    """
    a = _as_alpha(alpha)
    xs, ys = as_coordinates(x, y)
    out = np.empty(xs.shape[0])
    _distortion_kernel(a, xs, ys, out)
    return out


def distortion_bounds(alpha, rects) -> np.ndarray:
    """Return (min δ, max δ) over axis-aligned rectangles : (n, 2) float64.

    Parameters
    ----------
    alpha : (3,) float64 — (αₓ, α_y, α_c).
    rects : (n, 4) float64 — rows (x_lo, y_lo, x_hi, y_hi) with x_lo ≤ x_hi, y_lo ≤ y_hi.

    Exact for rectangles inside the domain (the extrema of δ sit at corners of the folded
    rectangle); if a corner leaves the domain the maximum is inf.
    """
    a = _as_alpha(alpha)
    r = as_points(rects, "rects", dim=4)
    if np.any(r[:, 0] > r[:, 2]) or np.any(r[:, 1] > r[:, 3]):
        raise ValueError("rects rows must be (x_lo, y_lo, x_hi, y_hi) with lo ≤ hi")
    cols = [np.ascontiguousarray(r[:, k]) for k in range(4)]
    lo, hi = np.empty(r.shape[0]), np.empty(r.shape[0])
    _distortion_bounds_kernel(a, *cols, lo, hi)
    return np.column_stack([lo, hi])
