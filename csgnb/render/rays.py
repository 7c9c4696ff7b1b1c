"""Scalar kernels shared by the reference ray tracer and the splat renderer.

Both renderers call these, so a pixel's ray and a quadric's root along it are computed by the
same instructions in both: where they pick the same surface their depths agree bit for bit.

Quadric rows are the paper's quadric buffer (§6, ``SampleCloud.quadric_buffer``):
``(q00, q01, q02, q03, q11, q12, q13, q22, q23, q33)``, the upper triangle of the symmetric 4×4
matrix Q, so ``Q(x) = xᵀAx + 2 mᵀx + c`` with ``A = Q[:3, :3]``, ``m = Q[:3, 3]``, ``c = Q[3, 3]``.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit

__all__ = ["inline_jit", "quadric_rows", "pixel_ray", "ray_roots", "row_value", "row_gradient", "EPS"]

#: IEEE division (x/0 → inf/NaN), LLVM-inlined into the loops that call them (no per-call
#: reference counting of the array arguments). fastmath stays off.
inline_jit = jit(error_model="numpy", inline="always")

EPS = float(np.finfo(np.float64).eps)


def quadric_rows(quadrics) -> np.ndarray:
    """Return the quadric buffer of §6 in float64 : (n, 10) — as ``SampleCloud.quadric_buffer``."""
    iu = np.triu_indices(4)
    return np.ascontiguousarray(np.array([q.matrix[iu] for q in quadrics], dtype=np.float64).reshape(-1, 10))


@inline_jit
def pixel_ray(cam, X, Y, i, j):
    """Return the ray of pixel (i, j): origin (3 floats) and unit direction (3 floats).

    cam : (20,) ``Camera.params()``; X : (W,), Y : (H,) screen coordinates of the pixel centres.
    """
    x, y = X[j], Y[i]
    if cam[18] != 0.0:  # orthographic
        ox = cam[0] + x * cam[6] + y * cam[9]
        oy = cam[1] + x * cam[7] + y * cam[10]
        oz = cam[2] + x * cam[8] + y * cam[11]
        return ox, oy, oz, cam[3], cam[4], cam[5]
    dx = cam[3] + x * cam[6] + y * cam[9]
    dy = cam[4] + x * cam[7] + y * cam[10]
    dz = cam[5] + x * cam[8] + y * cam[11]
    inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
    return cam[0], cam[1], cam[2], dx * inv, dy * inv, dz * inv


@inline_jit
def row_value(Q, k, x, y, z):
    """Return Q_k(x, y, z) for quadric row ``Q[k]`` (the γ of :func:`ray_roots`, same rounding)."""
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
def ray_roots(Q, k, px, py, pz, vx, vy, vz):
    """Return the roots (t₁ ≤ t₂) of Q_k(p + t v) = 0, NaN for missing ones (eq. 5–6), and Q_k(p).

    The form of ``csgnb.quadric.evaluate`` (cancellation-free roots, eq. 6 when vᵀAv is below
    its rounding bound): with a = vᵀAv, β = vᵀ(Ap + m), γ = Q(p), q = -(β + sign(β)√(β² - aγ)),
    the roots are q/a and γ/q. A linear equation gives one root (t₂ NaN); a line inside the
    surface gives (-inf, inf).
    """
    avx = Q[k, 0] * vx + Q[k, 1] * vy + Q[k, 2] * vz
    avy = Q[k, 1] * vx + Q[k, 4] * vy + Q[k, 5] * vz
    avz = Q[k, 2] * vx + Q[k, 5] * vy + Q[k, 7] * vz
    a = vx * avx + vy * avy + vz * avz
    ax, ay, az = abs(vx), abs(vy), abs(vz)
    abound = (
        ax * (abs(Q[k, 0]) * ax + abs(Q[k, 1]) * ay + abs(Q[k, 2]) * az)
        + ay * (abs(Q[k, 1]) * ax + abs(Q[k, 4]) * ay + abs(Q[k, 5]) * az)
        + az * (abs(Q[k, 2]) * ax + abs(Q[k, 5]) * ay + abs(Q[k, 7]) * az)
    ) * (4.0 * 2.220446049250313e-16)
    beta = avx * px + avy * py + avz * pz + (vx * Q[k, 3] + vy * Q[k, 6] + vz * Q[k, 8])
    gamma = (
        px * (Q[k, 0] * px + 2.0 * (Q[k, 1] * py + Q[k, 2] * pz + Q[k, 3]))
        + py * (Q[k, 4] * py + 2.0 * (Q[k, 5] * pz + Q[k, 6]))
        + pz * (Q[k, 7] * pz + 2.0 * Q[k, 8])
        + Q[k, 9]
    )
    if abs(a) <= abound:
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
