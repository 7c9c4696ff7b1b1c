"""Scalar kernels shared by the reference ray tracer and the splat renderer.

Both renderers call these, so a pixel's ray and a quadric's root along it are computed by the
same instructions in both: where they pick the same surface their depths agree bit for bit.

A pixel with screen coordinates (x, y) (``Camera.screen_axes``) has the ray ``o + z d``:
perspective ``o = e``, ``d = f + x r + y u``; orthographic ``o = e + x r + y u``, ``d = f``.
Since ``d·f = 1`` the parameter z is the view-space depth in both cases. Along it a quadric is
``Q(o + z d) = a z² + 2 β z + γ`` with a, β, γ quadratic polynomials in (x, y), whose 18
coefficients per quadric are computed once per frame (:func:`ray_polynomials`): a root then
costs about 25 flops, a square root and two divisions.

Quadric rows are the paper's quadric buffer (§6, ``SampleCloud.quadric_buffer``):
``(q00, q01, q02, q03, q11, q12, q13, q22, q23, q33)``, the upper triangle of the symmetric 4×4
matrix Q, so ``Q(x) = xᵀAx + 2 mᵀx + c`` with ``A = Q[:3, :3]``, ``m = Q[:3, 3]``, ``c = Q[3, 3]``.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit

__all__ = [
    "inline_jit", "quadric_rows", "ray_polynomials", "ray_point", "ray_direction", "ray_roots", "row_value",
    "row_gradient", "EPS", "POLY_COLUMNS",
]

#: IEEE division (x/0 → inf/NaN), LLVM-inlined into the loops that call them (no per-call
#: reference counting of the array arguments). fastmath stays off.
inline_jit = jit(error_model="numpy", inline="always")

EPS = float(np.finfo(np.float64).eps)


def quadric_rows(quadrics) -> np.ndarray:
    """Return the quadric buffer of §6 in float64 : (n, 10) — as ``SampleCloud.quadric_buffer``."""
    iu = np.triu_indices(4)
    return np.ascontiguousarray(np.array([q.matrix[iu] for q in quadrics], dtype=np.float64).reshape(-1, 10))


#: Columns of :func:`ray_polynomials`: a (6), β (6), γ (6) — each ``c0 + cx x + cy y + cxx x² +
#: cxy x y + cyy y²`` — then the rounding bound factor of a (16 ε Σ|A_ij|) and a spare column.
POLY_COLUMNS = 20


@inline_jit
def _poly(P, k, c, x, y):
    return P[k, c] + x * (P[k, c + 1] + x * P[k, c + 3] + y * P[k, c + 4]) + y * (P[k, c + 2] + y * P[k, c + 5])


@inline_jit
def _bil(A, U, iu, V, iv):
    """Return U[iu]ᵀ A V[iv]."""
    s = 0.0
    for r in range(3):
        for t in range(3):
            s += U[iu, r] * A[r, t] * V[iv, t]
    return s


@jit(error_model="numpy")
def _ray_polynomials_kernel(cam, Q, P):
    ortho = cam[18] != 0.0
    # o = o0 + x o1 + y o2, d = d0 + x d1 + y d2
    o = np.zeros((3, 3))
    d = np.zeros((3, 3))
    for c in range(3):
        o[0, c] = cam[c]
        d[0, c] = cam[3 + c]
        if ortho:
            o[1, c], o[2, c] = cam[6 + c], cam[9 + c]
        else:
            d[1, c], d[2, c] = cam[6 + c], cam[9 + c]
    A = np.empty((3, 3))
    m = np.empty(3)
    for k in range(Q.shape[0]):
        A[0, 0], A[0, 1], A[0, 2], m[0] = Q[k, 0], Q[k, 1], Q[k, 2], Q[k, 3]
        A[1, 1], A[1, 2], m[1] = Q[k, 4], Q[k, 5], Q[k, 6]
        A[2, 2], m[2] = Q[k, 7], Q[k, 8]
        A[1, 0], A[2, 0], A[2, 1] = A[0, 1], A[0, 2], A[1, 2]
        c = Q[k, 9]
        # a = dᵀAd
        P[k, 0] = _bil(A, d, 0, d, 0)
        P[k, 1] = 2.0 * _bil(A, d, 0, d, 1)
        P[k, 2] = 2.0 * _bil(A, d, 0, d, 2)
        P[k, 3] = _bil(A, d, 1, d, 1)
        P[k, 4] = 2.0 * _bil(A, d, 1, d, 2)
        P[k, 5] = _bil(A, d, 2, d, 2)
        # β = dᵀ(A o + m)
        dm0 = d[0, 0] * m[0] + d[0, 1] * m[1] + d[0, 2] * m[2]
        dm1 = d[1, 0] * m[0] + d[1, 1] * m[1] + d[1, 2] * m[2]
        dm2 = d[2, 0] * m[0] + d[2, 1] * m[1] + d[2, 2] * m[2]
        P[k, 6] = _bil(A, d, 0, o, 0) + dm0
        P[k, 7] = _bil(A, d, 1, o, 0) + _bil(A, d, 0, o, 1) + dm1
        P[k, 8] = _bil(A, d, 2, o, 0) + _bil(A, d, 0, o, 2) + dm2
        P[k, 9] = _bil(A, d, 1, o, 1)
        P[k, 10] = _bil(A, d, 1, o, 2) + _bil(A, d, 2, o, 1)
        P[k, 11] = _bil(A, d, 2, o, 2)
        # γ = Q(o)
        om0 = o[0, 0] * m[0] + o[0, 1] * m[1] + o[0, 2] * m[2]
        om1 = o[1, 0] * m[0] + o[1, 1] * m[1] + o[1, 2] * m[2]
        om2 = o[2, 0] * m[0] + o[2, 1] * m[1] + o[2, 2] * m[2]
        P[k, 12] = _bil(A, o, 0, o, 0) + 2.0 * om0 + c
        P[k, 13] = 2.0 * (_bil(A, o, 1, o, 0) + om1)
        P[k, 14] = 2.0 * (_bil(A, o, 2, o, 0) + om2)
        P[k, 15] = _bil(A, o, 1, o, 1)
        P[k, 16] = 2.0 * _bil(A, o, 1, o, 2)
        P[k, 17] = _bil(A, o, 2, o, 2)
        s = 0.0
        for r in range(3):
            for t in range(3):
                s += abs(A[r, t])
        P[k, 18] = 16.0 * 2.220446049250313e-16 * s
        P[k, 19] = 0.0


def ray_polynomials(cam: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Return the per-frame ray polynomials of quadric rows Q : (n, POLY_COLUMNS) float64."""
    P = np.empty((Q.shape[0], POLY_COLUMNS))
    _ray_polynomials_kernel(np.ascontiguousarray(cam, dtype=np.float64), np.ascontiguousarray(Q), P)
    return P


@inline_jit
def ray_point(cam, x, y, z):
    """Return the point at depth z on the ray of screen point (x, y) (3 floats)."""
    if cam[18] != 0.0:
        return (cam[0] + x * cam[6] + y * cam[9] + z * cam[3],
                cam[1] + x * cam[7] + y * cam[10] + z * cam[4],
                cam[2] + x * cam[8] + y * cam[11] + z * cam[5])
    return (cam[0] + z * (cam[3] + x * cam[6] + y * cam[9]),
            cam[1] + z * (cam[4] + x * cam[7] + y * cam[10]),
            cam[2] + z * (cam[5] + x * cam[8] + y * cam[11]))


@inline_jit
def ray_direction(cam, x, y):
    """Return the (unnormalised, d·f = 1) direction of the ray of screen point (x, y) and |d|²."""
    if cam[18] != 0.0:
        return cam[3], cam[4], cam[5], 1.0
    dx = cam[3] + x * cam[6] + y * cam[9]
    dy = cam[4] + x * cam[7] + y * cam[10]
    dz = cam[5] + x * cam[8] + y * cam[11]
    return dx, dy, dz, 1.0 + (x * x + y * y)


@inline_jit
def row_value(Q, k, x, y, z):
    """Return Q_k(x, y, z) for quadric row ``Q[k]``."""
    return (
        x * (Q[k, 0] * x + 2.0 * (Q[k, 1] * y + Q[k, 2] * z + Q[k, 3]))
        + y * (Q[k, 4] * y + 2.0 * (Q[k, 5] * z + Q[k, 6]))
        + z * (Q[k, 7] * z + 2.0 * Q[k, 8])
        + Q[k, 9]
    )


@inline_jit
def row_gradient(Q, k, x, y, z):
    """Return ∇Q_k / 2 = A x + m at (x, y, z) (3 floats)."""
    return (
        Q[k, 0] * x + Q[k, 1] * y + Q[k, 2] * z + Q[k, 3],
        Q[k, 1] * x + Q[k, 4] * y + Q[k, 5] * z + Q[k, 6],
        Q[k, 2] * x + Q[k, 5] * y + Q[k, 7] * z + Q[k, 8],
    )


@inline_jit
def ray_roots(P, k, x, y, dd):
    """Return the depths (z₁ ≤ z₂) where the ray of (x, y) meets quadric k, NaN for missing ones,
    and γ = Q(o) (its sign: is the ray origin inside).

    P : ray polynomials (:func:`ray_polynomials`); dd = |d|² of the ray (1 + x² + y² for a
    perspective camera, 1 for an orthographic one). Cancellation-free roots q/a and γ/q with
    q = -(β + sign(β)√(β² - aγ)) (eq. 5); eq. 6 (one root) when |a| is below its rounding bound;
    a ray inside the surface gives (-inf, inf).
    """
    a = _poly(P, k, 0, x, y)
    beta = _poly(P, k, 6, x, y)
    gamma = _poly(P, k, 12, x, y)
    if abs(a) <= P[k, 18] * dd:
        if beta == 0.0:
            if gamma == 0.0:
                return -math.inf, math.inf, gamma
            return math.nan, math.nan, gamma
        return -0.5 * gamma / beta, math.nan, gamma
    disc = beta * beta - a * gamma
    if disc < 0.0:
        return math.nan, math.nan, gamma
    s = math.sqrt(disc)
    qq = -(beta + s) if beta >= 0.0 else -(beta - s)
    if qq == 0.0:
        return 0.0, 0.0, gamma
    t1 = qq / a
    t2 = gamma / qq
    if t1 <= t2:
        return t1, t2, gamma
    return t2, t1, gamma


@inline_jit
def disc_hit(cam, SD, k, x, y, best, rr):
    """The depth where the ray of (x, y) meets splat k's flat disc (centre ``SD[k, 0:3]``, unit normal ``SD[k, 4:7]``)
    within squared radius ``rr`` in front of ``best``; ∞ where it does not (classical splats, Figure 11a)."""
    nx, ny, nz = SD[k, 4], SD[k, 5], SD[k, 6]
    dx, dy, dz, _ = ray_direction(cam, x, y)
    den = nx * dx + ny * dy + nz * dz
    if den == 0.0:
        return math.inf
    ox, oy, oz = ray_point(cam, x, y, 0.0)
    sx, sy, sz = SD[k, 0], SD[k, 1], SD[k, 2]
    zz = (nx * (sx - ox) + ny * (sy - oy) + nz * (sz - oz)) / den
    if not (zz > 0.0 and zz < best):
        return math.inf
    px, py, pz = ray_point(cam, x, y, zz)
    ex, ey, ez = px - sx, py - sy, pz - sz
    if ex * ex + ey * ey + ez * ez <= rr:
        return zz
    return math.inf
