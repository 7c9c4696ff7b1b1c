"""Point-wise quadric kernels: value Q(x), gradient, unit normal (eq. 4) and line intersection
(eq. 5 with the degenerate linear case of eq. 6).

Each ``_kernel`` is a numba loop over rows writing into ``out``; the public functions validate
shapes and dtypes and allocate the outputs.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit
from csgnb.errors import CsgnbError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_points
from csgnb.quadric.quadric import Quadric

__all__ = ["value", "gradient", "normal", "intersect_lines", "as_points", "ieee_jit", "inline_jit"]

#: The package jit with IEEE division semantics: x/0 gives ±inf/NaN instead of raising.
#: The kernels rely on that (a normal at a singular point is NaN) and it keeps the loops
#: free of the per-division zero checks that block vectorisation. fastmath stays off.
ieee_jit = jit(error_model="numpy")

#: ieee_jit for scalar helpers called from loops: LLVM always inlines them, which also removes the
#: reference counting of their array arguments (a call per sample would otherwise cost ~100 ns).
inline_jit = jit(error_model="numpy", inline="always")


def _check_quadric(q) -> np.ndarray:
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a csgnb.quadric.Quadric, got {type(q).__name__}")
    return np.ascontiguousarray(q.matrix)


# -- kernels -------------------------------------------------------------------------------


@ieee_jit
def _value_kernel(Q, points, out):
    """out[i] = Q(points[i]); Q : (4, 4), points : (n, 3), out : (n,)."""
    a00, a01, a02, a11, a12, a22 = Q[0, 0], Q[0, 1], Q[0, 2], Q[1, 1], Q[1, 2], Q[2, 2]
    # the off-diagonal and linear terms appear twice in xᵀQx; fold the factor 2 in once
    t01, t02, t12 = 2.0 * a01, 2.0 * a02, 2.0 * a12
    l0, l1, l2, c = 2.0 * Q[0, 3], 2.0 * Q[1, 3], 2.0 * Q[2, 3], Q[3, 3]
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        out[i] = (
            x * (a00 * x + t01 * y + t02 * z + l0)
            + y * (a11 * y + t12 * z + l1)
            + z * (a22 * z + l2)
        ) + c


@ieee_jit
def _gradient_kernel(Q, points, out):
    """out[i] = 2 (A x - b); Q : (4, 4), points : (n, 3), out : (n, 3)."""
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for r in range(3):
            out[i, r] = 2.0 * (Q[r, 0] * x + Q[r, 1] * y + Q[r, 2] * z + Q[r, 3])


@ieee_jit
def _normal_kernel(Q, points, out):
    """out[i] = ∇Q / |∇Q| (NaN where the gradient vanishes); shapes as _gradient_kernel."""
    a00, a01, a02, a11, a12, a22 = Q[0, 0], Q[0, 1], Q[0, 2], Q[1, 1], Q[1, 2], Q[2, 2]
    m0, m1, m2 = Q[0, 3], Q[1, 3], Q[2, 3]
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        # the factor 2 of eq. 4 cancels in the normalisation
        g0 = a00 * x + a01 * y + a02 * z + m0
        g1 = a01 * x + a11 * y + a12 * z + m1
        g2 = a02 * x + a12 * y + a22 * z + m2
        n2 = g0 * g0 + g1 * g1 + g2 * g2
        inv = 1.0 / math.sqrt(n2) if n2 > 0.0 else math.nan  # a select: keeps it vectorised
        out[i, 0] = g0 * inv
        out[i, 1] = g1 * inv
        out[i, 2] = g2 * inv


@ieee_jit
def _line_intersection_kernel(Q, origins, directions, out):
    """Solve Q(p + t v) = 0 per row: out[i] = (t₁, t₂) ascending, NaN for missing roots.

    The quadratic is ``a t² + 2 β t + γ`` with a = vᵀAv, β = vᵀ(Ap - b), γ = Q(p). It is
    solved in the cancellation-free form t = q/a, γ/q with q = -(β + sign(β)√(β² - aγ)),
    which tends to eq. 6 as a → 0. When |a| is below its own rounding error the equation
    is treated as linear (eq. 6): one root, second slot NaN. A line lying in the surface
    (a = β = γ = 0) gives (-inf, +inf).
    """
    for i in range(origins.shape[0]):
        px, py, pz = origins[i, 0], origins[i, 1], origins[i, 2]
        vx, vy, vz = directions[i, 0], directions[i, 1], directions[i, 2]
        avx = Q[0, 0] * vx + Q[0, 1] * vy + Q[0, 2] * vz
        avy = Q[1, 0] * vx + Q[1, 1] * vy + Q[1, 2] * vz
        avz = Q[2, 0] * vx + Q[2, 1] * vy + Q[2, 2] * vz
        a = vx * avx + vy * avy + vz * avz
        # rounding bound of a: 4 ε Σ|A_rs||v_r||v_s|
        ax, ay, az = abs(vx), abs(vy), abs(vz)
        abound = (
            ax * (abs(Q[0, 0]) * ax + abs(Q[0, 1]) * ay + abs(Q[0, 2]) * az)
            + ay * (abs(Q[1, 0]) * ax + abs(Q[1, 1]) * ay + abs(Q[1, 2]) * az)
            + az * (abs(Q[2, 0]) * ax + abs(Q[2, 1]) * ay + abs(Q[2, 2]) * az)
        ) * (4.0 * tol.EPS)
        # Q is symmetric: vᵀ(Ap - b) = (Av)ᵀp + vᵀQ[:3, 3]
        beta = avx * px + avy * py + avz * pz + (vx * Q[0, 3] + vy * Q[1, 3] + vz * Q[2, 3])
        gamma = (
            px * (Q[0, 0] * px + 2.0 * (Q[0, 1] * py + Q[0, 2] * pz + Q[0, 3]))
            + py * (Q[1, 1] * py + 2.0 * (Q[1, 2] * pz + Q[1, 3]))
            + pz * (Q[2, 2] * pz + 2.0 * Q[2, 3])
            + Q[3, 3]
        )
        if abs(a) <= abound:
            # eq. 6: the quadratic term is zero (up to its rounding): a linear equation
            if beta == 0.0:
                if gamma == 0.0:
                    out[i, 0] = -math.inf
                    out[i, 1] = math.inf
                else:
                    out[i, 0] = math.nan
                    out[i, 1] = math.nan
            else:
                out[i, 0] = -0.5 * gamma / beta
                out[i, 1] = math.nan
            continue
        disc = beta * beta - a * gamma
        if disc < 0.0:
            out[i, 0] = math.nan
            out[i, 1] = math.nan
            continue
        s = math.sqrt(disc)
        qq = -(beta + s) if beta >= 0.0 else -(beta - s)
        if qq == 0.0:  # beta = 0 and gamma = 0: double root at the origin of the line
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            continue
        t1 = qq / a
        t2 = gamma / qq
        if t1 <= t2:
            out[i, 0] = t1
            out[i, 1] = t2
        else:
            out[i, 0] = t2
            out[i, 1] = t1


# -- public API ----------------------------------------------------------------------------


def value(q: Quadric, points) -> np.ndarray:
    """Return the quadric value ``Q(x) = xᵀAx - 2xᵀb + c`` (eq. 3).

    Parameters
    ----------
    q : Quadric
    points : (n, 3) float64

    Returns
    -------
    (n,) float64 — negative inside, zero on the surface, positive outside.
    """
    Q = _check_quadric(q)
    pts = as_points(points)
    out = np.empty(pts.shape[0])
    _value_kernel(Q, pts, out)
    return out


def gradient(q: Quadric, points) -> np.ndarray:
    """Return the gradient ``∇Q(x) = 2 (Ax - b)`` (eq. 4) : (n, 3) float64."""
    Q = _check_quadric(q)
    pts = as_points(points)
    out = np.empty_like(pts)
    _gradient_kernel(Q, pts, out)
    return out


def normal(q: Quadric, points) -> np.ndarray:
    """Return the unit normal ``N(x) = ∇Q / |∇Q|`` (eq. 4) : (n, 3) float64.

    Points where the gradient vanishes (the center of a sphere, the apex of a cone) get NaN.
    The normal points outwards (towards positive Q).
    """
    Q = _check_quadric(q)
    pts = as_points(points)
    out = np.empty_like(pts)
    _normal_kernel(Q, pts, out)
    return out


def intersect_lines(q: Quadric, origins, directions) -> np.ndarray:
    """Return the parameters ``t`` where the lines ``p + t v`` meet the surface (eq. 5–6).

    Parameters
    ----------
    q : Quadric
    origins : (n, 3) float64
        Points ``p`` on the lines.
    directions : (n, 3) float64
        Directions ``v`` (need not be unit length; ``t`` is measured in multiples of ``v``).

    Returns
    -------
    (n, 2) float64
        Roots in ascending order; NaN fills missing roots (a line that misses the surface
        gives two NaN, a line on which the equation is linear — eq. 6, e.g. parallel to a
        cylinder or paraboloid axis — gives one root and NaN). A line lying entirely in the
        surface gives (-inf, +inf).
    """
    Q = _check_quadric(q)
    p = as_points(origins, "origins")
    v = as_points(directions, "directions")
    if p.shape != v.shape:
        raise CsgnbError(f"origins {p.shape} and directions {v.shape} must have the same shape")
    if np.any(~np.any(v != 0.0, axis=1)):
        raise CsgnbError("directions contains a zero vector; a line needs a non-zero direction")
    out = np.empty((p.shape[0], 2))
    _line_intersection_kernel(Q, p, v, out)
    return out
