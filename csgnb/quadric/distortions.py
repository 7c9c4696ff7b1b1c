"""Heightfield distortion δ(x, y) (paper eq. 13) and its bounds over axis-aligned rectangles (§3.4).

δ is the area stretch of the map (x, y) ↦ (x, y, t(x, y)): 1/|cos| of the angle between the
surface normal and the sampling-plane normal, δ² = 1 + |∇t|². With the normal components of
:func:`csgnb.quadric.frames.region_lines` — |n_t|² ∝ T, |n_x|² + |n_y|² ∝ N —

    δ² = 1 + N / T,    sheets (t² = H): N = |∇H|²/4, T = H;    graphs (t = H): N = |∇H|², T = 1,

and in (U, V) = (x² or x, y² or y) both N and T are affine (eq. 13 is the central case). So δ²
is linear-fractional: monotone along every line, extremal at a vertex of a convex polygon (the
paper's lemma). A rectangle within one quadrant is a rectangle in (U, V), so its four corners bound
δ; a rectangle straddling an axis is first folded into the quadrant (δ is even in a squared
coordinate). A corner where N = T = 0 (a cone's apex, the ruling of a wedge) is skipped: both
forms vanish there, so δ is constant along every ray from it and the opposite corners bound it.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb.errors import CsgnbError
from csgnb.quadric.arguments import as_points
from csgnb.quadric.evaluate import ieee_jit, inline_jit
from csgnb.quadric.frames import FORM_GRAPH, as_coordinates, as_heightfield

__all__ = ["distortion", "distortion_bounds", "delta_range", "delta_at_points"]


@inline_jit
def delta_range(form, ax, bx, ay, by, ac, x0, y0, x1, y1):
    """Return (min δ, max δ) over the rectangle [x0, x1] × [y0, y1] of a plane's heightfield.

    max is inf if a corner leaves the domain (T < 0, or T = 0 < N: the rim of a sheet); min is
    then taken over the valid corners (1 if there is none). See the module docstring.
    """
    if ax != 0.0:  # squared: fold into the quadrant
        u0, u1 = x0 * x0, x1 * x1
        uhi = max(u0, u1)
        ulo = 0.0 if x0 * x1 <= 0.0 else min(u0, u1)
    else:
        ulo, uhi = x0, x1
    if ay != 0.0:
        v0, v1 = y0 * y0, y1 * y1
        vhi = max(v0, v1)
        vlo = 0.0 if y0 * y1 <= 0.0 else min(v0, v1)
    else:
        vlo, vhi = y0, y1
    if form == FORM_GRAPH:
        tu, tv, tc = 0.0, 0.0, 0.25
        nu, nv, n0 = ax * ax, ay * ay, 0.0
    else:
        tu = ax if ax != 0.0 else bx
        tv = ay if ay != 0.0 else by
        tc = ac
        nu, nv = ax * ax, ay * ay
        n0 = 0.25 * (bx * bx + by * by)
    lo = math.inf
    hi = 0.0
    bad = False
    for c in range(4):
        u = uhi if c & 1 else ulo
        v = vhi if c & 2 else vlo
        T = tu * u + tv * v + tc
        N = nu * u + nv * v + n0
        if T > 0.0:
            r = N / T
            lo = min(lo, r)
            hi = max(hi, r)
        elif not (T == 0.0 and N == 0.0):
            bad = True
    if lo == math.inf:
        return 1.0, math.inf
    return math.sqrt(1.0 + lo), (math.inf if bad else math.sqrt(1.0 + hi))


@ieee_jit
def delta_at_points(form, ax, bx, ay, by, ac, x0, y0, x1, y1, x2, y2):
    """Return max δ at three points, skipping points where N = T = 0 (inf if one is off the domain).

    Over a region that is a triangle in (U, V) with these corners, δ² is linear-fractional, so
    this is its maximum over the region (not over the region's bounding box, as ``delta_range``).
    """
    hi = 0.0
    for c in range(3):
        x = x0 if c == 0 else (x1 if c == 1 else x2)
        y = y0 if c == 0 else (y1 if c == 1 else y2)
        gx = 2.0 * ax * x + bx
        gy = 2.0 * ay * y + by
        N = gx * gx + gy * gy
        if form == FORM_GRAPH:
            hi = max(hi, N)
            continue
        T = 4.0 * ((ax * x + bx) * x + (ay * y + by) * y + ac)
        if T > 0.0:
            hi = max(hi, N / T)
        elif not (T == 0.0 and N == 0.0):
            return math.inf
    return math.sqrt(1.0 + hi)


@ieee_jit
def _distortion_kernel(form, coef, x, y, out):
    """out[i] = δ(x, y); NaN outside the domain, inf on a sheet's rim; x, y, out : (n,)."""
    ax, bx, ay, by, ac = coef[0], coef[1], coef[2], coef[3], coef[4]
    graph = form == FORM_GRAPH
    for i in range(x.shape[0]):
        xi = x[i]
        yi = y[i]
        gx = 2.0 * ax * xi + bx
        gy = 2.0 * ay * yi + by
        if graph:
            out[i] = math.sqrt(1.0 + gx * gx + gy * gy)
        else:
            H = (ax * xi + bx) * xi + (ay * yi + by) * yi + ac
            # off the domain (H < 0) there is no surface point: NaN, as eq. 13's root of a negative
            out[i] = math.sqrt(1.0 + 0.25 * (gx * gx + gy * gy) / H) if H >= 0.0 else math.nan


@ieee_jit
def _distortion_bounds_kernel(form, coef, x_lo, y_lo, x_hi, y_hi, out_min, out_max):
    """out_min[i], out_max[i] = :func:`delta_range` over [x_lo, x_hi] × [y_lo, y_hi]."""
    ax, bx, ay, by, ac = coef[0], coef[1], coef[2], coef[3], coef[4]
    for i in range(x_lo.shape[0]):
        out_min[i], out_max[i] = delta_range(form, ax, bx, ay, by, ac, x_lo[i], y_lo[i], x_hi[i], y_hi[i])


def distortion(plane, x, y) -> np.ndarray:
    """Return the heightfield distortion δ(x, y) ≥ 1 (eq. 13) : (n,) float64.

    Parameters
    ----------
    plane : SamplingPlane, or (3,) float64 — a sampling plane, or (αₓ, α_y, α_c) of eq. 7.
    x, y : (n,) float64 — local plane coordinates (broadcast together).

    NaN outside a sheet's domain, inf on its rim (where t = 0).
    """
    form, coef = as_heightfield(plane)
    xs, ys = as_coordinates(x, y)
    out = np.empty(xs.shape[0])
    with np.errstate(all="ignore"):
        _distortion_kernel(form, coef, xs, ys, out)
    return out


def distortion_bounds(plane, rects) -> np.ndarray:
    """Return (min δ, max δ) over axis-aligned rectangles : (n, 2) float64.

    Parameters
    ----------
    plane : SamplingPlane, or (3,) float64 — as for :func:`distortion`.
    rects : (n, 4) float64 — rows (x_lo, y_lo, x_hi, y_hi) with x_lo ≤ x_hi, y_lo ≤ y_hi.

    Exact for rectangles inside the domain (the extrema of δ sit at corners of the folded
    rectangle); if a corner leaves the domain the maximum is inf.
    """
    form, coef = as_heightfield(plane)
    r = as_points(rects, "rects", dim=4)
    if np.any(r[:, 0] > r[:, 2]) or np.any(r[:, 1] > r[:, 3]):
        raise CsgnbError("rects rows must be (x_lo, y_lo, x_hi, y_hi) with lo ≤ hi")
    cols = [np.ascontiguousarray(r[:, k]) for k in range(4)]
    lo, hi = np.empty(r.shape[0]), np.empty(r.shape[0])
    _distortion_bounds_kernel(form, coef, *cols, lo, hi)
    return np.column_stack([lo, hi])
