"""Principal frame, sampling planes and heightfields of a quadric (paper §3.2, eq. 7, Fig. 5).

In the frame of the center q and the eigenvectors uᵢ of A, a central quadric reads
``λᵢx² + λⱼy² + λₖt² + (c - qᵀb) = 0``; seen from the sampling plane P_ij (normal uₖ) the
surface is the two-sheeted graph ``t = ±h(x, y)`` with

    h(x, y) = √(αₓx² + α_y y² + α_c),  αₓ = -λᵢ/λₖ,  α_y = -λⱼ/λₖ,  α_c = (qᵀb - c)/λₖ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from csgnb.errors import GeometryError
from csgnb.quadric.evaluate import as_points, ieee_jit
from csgnb.quadric.quadric import Quadric

__all__ = [
    "PrincipalFrame",
    "SamplingPlane",
    "HEIGHTFIELD_TYPES",
    "principal_frame",
    "sampling_planes",
    "heightfield",
    "heightfield_type",
    "as_coordinates",
    "to_plane_coordinates",
    "from_plane_coordinates",
]

#: Eigenvalues below this fraction of the largest |λ| are zero (cylinders, cones, paraboloids
#: built from exact zeros pick up rounding noise of this order under rotations).
ZERO_EIGENVALUE = 1e-12

#: Heightfield types by the signs of (αₓ, α_y, α_c); the first five are Figure 5's cases.
HEIGHTFIELD_TYPES: dict[str, str] = {
    "elliptic-cap": "αₓ, α_y < 0 < α_c: a cap over the inside of an ellipse (ellipsoid)",
    "elliptic-bowl": "αₓ, α_y, α_c > 0: defined on the whole plane (two-sheet hyperboloid)",
    "elliptic-hole": "αₓ, α_y > 0 > α_c: defined outside an ellipse (one-sheet hyperboloid)",
    "hyperbolic-inner": "αₓα_y < 0 < α_c: defined between the branches of a hyperbola",
    "hyperbolic-outer": "αₓα_y < 0, α_c < 0: defined beyond the branches of a hyperbola",
    "cone": "α_c = 0, αₓ, α_y not both ≤ 0: the sheets meet at the center",
    "cylindrical": "exactly one of αₓ, α_y is 0: constant along one in-plane axis",
    "parallel-planes": "αₓ = α_y = 0 < α_c: two planes parallel to the sampling plane",
    "empty": "no real point (e.g. αₓ, α_y, α_c < 0), or only the center",
    "none": "λₖ = 0 or a non-central quadric: the surface is no heightfield of this form",
}


@dataclass(frozen=True)
class PrincipalFrame:
    """Center and principal axes of a quadric (paper §3.2, Figure 3).

    center : (3,) float64 — min-norm solution of ``A q = b`` (least squares if none exists).
    axes : (3, 3) float64 — columns are the unit eigenvectors uᵢ of A, right-handed.
    eigenvalues : (3,) float64 — λᵢ ascending, tiny ones (``ZERO_EIGENVALUE``) set to 0.
    central : bool — whether ``A q = b`` holds (false for paraboloids and single planes).
    """

    center: np.ndarray
    axes: np.ndarray
    eigenvalues: np.ndarray
    central: bool


@dataclass(frozen=True)
class SamplingPlane:
    """The sampling plane P_ij = {q + x uᵢ + y uⱼ} with normal uₖ and its heightfield (eq. 7).

    axis : int — k, the principal axis normal to the plane (i = k+1, j = k+2 mod 3).
    origin : (3,) float64 — the quadric center q.
    x_axis, y_axis, normal : (3,) float64 — uᵢ, uⱼ, uₖ (right-handed).
    alpha : (3,) float64 — (αₓ, α_y, α_c); NaN when the type is ``"none"``.
    kind : str — a key of :data:`HEIGHTFIELD_TYPES`.
    """

    axis: int
    origin: np.ndarray
    x_axis: np.ndarray
    y_axis: np.ndarray
    normal: np.ndarray
    alpha: np.ndarray
    kind: str

    @property
    def frame(self) -> np.ndarray:
        """(3, 3) float64: columns uᵢ, uⱼ, uₖ (local x, y, t)."""
        return np.column_stack([self.x_axis, self.y_axis, self.normal])


def principal_frame(q: Quadric) -> PrincipalFrame:
    """Return the center, principal axes and eigenvalues of ``q`` (via SVD / eigh)."""
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a Quadric, got {type(q).__name__}")
    A, b = q.A, q.b
    lam, U = np.linalg.eigh(A)
    scale = float(np.max(np.abs(lam)))
    lam = np.where(np.abs(lam) <= ZERO_EIGENVALUE * scale, 0.0, lam)
    if np.linalg.det(U) < 0.0:
        U[:, 2] = -U[:, 2]
    # min-norm least-squares solution of A q = b through the SVD, cut at the same threshold
    W, s, Vt = np.linalg.svd(A)
    keep = s > ZERO_EIGENVALUE * (s[0] if s[0] > 0 else 1.0)
    center = Vt[keep].T @ ((W[:, keep].T @ b) / s[keep])
    residual = b - A @ center
    tol = 1e-10 * (np.linalg.norm(b) + np.linalg.norm(A) * np.linalg.norm(center)) + 1e-300
    central = bool(np.linalg.norm(residual) <= tol)
    return PrincipalFrame(center, U, lam, central)


def heightfield_type(alpha) -> str:
    """Return the heightfield type (a key of :data:`HEIGHTFIELD_TYPES`) of (αₓ, α_y, α_c)."""
    ax, ay, ac = (float(v) for v in np.asarray(alpha, dtype=np.float64).reshape(3))
    if not (math.isfinite(ax) and math.isfinite(ay) and math.isfinite(ac)):
        return "none"
    sx, sy, sc = np.sign(ax), np.sign(ay), np.sign(ac)
    if sx == 0 and sy == 0:
        return "parallel-planes" if sc > 0 else "empty"
    if sx <= 0 and sy <= 0 and sc <= 0:
        return "empty"
    if sx == 0 or sy == 0:
        return "cylindrical"
    if sc == 0:
        return "cone"
    if sx > 0 and sy > 0:
        return "elliptic-bowl" if sc > 0 else "elliptic-hole"
    if sx < 0 and sy < 0:
        return "elliptic-cap"
    return "hyperbolic-inner" if sc > 0 else "hyperbolic-outer"


def sampling_planes(q: Quadric) -> tuple[SamplingPlane, SamplingPlane, SamplingPlane]:
    """Return the three sampling planes P₁₂, P₂₀, P₀₁ (normal u₀, u₁, u₂) with eq. 7's α.

    For a non-central quadric (paraboloids, a single plane) or a plane whose normal is a
    zero-eigenvalue axis (λₖ = 0, e.g. a cylinder's axis), ``alpha`` is NaN and ``kind``
    is ``"none"``: eq. 7 does not describe the surface from that plane.
    """
    f = principal_frame(q)
    lam, U, center = f.eigenvalues, f.axes, f.center
    rhs = float(center @ q.b) - q.c
    planes = []
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        if f.central and lam[k] != 0.0:
            alpha = np.array([-lam[i] / lam[k], -lam[j] / lam[k], rhs / lam[k]]) + 0.0
            # α_c is a difference of rounded terms; snap it to 0 at the rounding level
            ref = (abs(float(center @ q.b)) + abs(q.c)) / abs(lam[k])
            if abs(alpha[2]) <= 1e-12 * ref:
                alpha[2] = 0.0
            kind = heightfield_type(alpha)
        else:
            alpha = np.full(3, np.nan)
            kind = "none"
        alpha.setflags(write=False)
        axes = (U[:, i].copy(), U[:, j].copy(), U[:, k].copy())
        planes.append(SamplingPlane(k, center.copy(), *axes, alpha, kind))
    return tuple(planes)


def to_plane_coordinates(plane: SamplingPlane, points) -> np.ndarray:
    """Return local coordinates (x, y, t) : (n, 3) of world ``points`` : (n, 3)."""
    pts = as_points(points)
    return (pts - plane.origin) @ plane.frame


def from_plane_coordinates(plane: SamplingPlane, xyt) -> np.ndarray:
    """Return world points : (n, 3) of local coordinates ``xyt`` : (n, 3) (x, y, t)."""
    loc = as_points(xyt, "xyt")
    return plane.origin + loc @ plane.frame.T


@ieee_jit
def _heightfield_kernel(alpha, x, y, out):
    """out[i] = √(αₓx² + α_y y² + α_c), NaN outside the domain; x, y, out : (n,).

    Separate x and y arrays (not (n, 2) rows) let the loop vectorise: twice the throughput.
    """
    ax, ay, ac = alpha[0], alpha[1], alpha[2]
    for i in range(x.shape[0]):
        xi = x[i]
        yi = y[i]
        out[i] = math.sqrt(ax * xi * xi + ay * yi * yi + ac)


def as_coordinates(x, y) -> tuple[np.ndarray, np.ndarray]:
    """Return ``x``, ``y`` broadcast to two C-contiguous (n,) float64 arrays."""
    xa, ya = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    return np.ascontiguousarray(xa.reshape(-1)), np.ascontiguousarray(ya.reshape(-1))


def _as_alpha(alpha) -> np.ndarray:
    a = np.asarray(alpha, dtype=np.float64).reshape(-1)
    if a.shape != (3,):
        raise ValueError(f"alpha must be (αₓ, α_y, α_c), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise GeometryError("alpha is NaN: this sampling plane has no eq. 7 heightfield")
    return a


def heightfield(alpha, x, y) -> np.ndarray:
    """Return h(x, y) = √(αₓx² + α_y y² + α_c) (eq. 7), NaN off the domain.

    Parameters
    ----------
    alpha : (3,) float64 — (αₓ, α_y, α_c), e.g. ``sampling_planes(q)[k].alpha``.
    x, y : (n,) float64 — local coordinates on the sampling plane (broadcast together).

    Returns
    -------
    (n,) float64 — the height t ≥ 0 of the upper sheet; the lower sheet is -h.
    """
    a = _as_alpha(alpha)
    xs, ys = as_coordinates(x, y)
    out = np.empty(xs.shape[0])
    _heightfield_kernel(a, xs, ys, out)
    return out
