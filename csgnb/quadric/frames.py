"""Principal frames, sampling planes and their heightfields, for every quadric (paper §3.2, Fig. 3–5).

In the frame of a center q and the eigenvectors uᵢ of A, with d = x uᵢ + y uⱼ + t uₖ,

    Q(q + d) = λᵢx² + λⱼy² + λₖt² − 2βᵢx − 2βⱼy − 2βₖt + γ,      γ = c − qᵀb,

where q is the min-norm least-squares solution of A q = b and β = Uᵀ(b − A q) is the part of b in
the null space of A (zero for central quadrics; for paraboloids and single planes the null basis is
turned so that only one βₖ is nonzero). Seen from the sampling plane P_ij (normal uₖ) the surface is

* **two sheets** t = ±√H (λₖ ≠ 0), with H = αₓx² + bₓx + α_y y² + b_y y + α_c,
  αₓ = −λᵢ/λₖ, bₓ = 2βᵢ/λₖ (likewise y), α_c = −γ/λₖ — eq. 7 when β = 0, and a *parabolic*
  heightfield (one coordinate linear) on a paraboloid's side planes;
* **a graph** t = H (λₖ = 0, βₖ ≠ 0: a paraboloid seen along its axis, a single plane), with
  αₓ = λᵢ/(2βₖ), α_y = λⱼ/(2βₖ), α_c = γ/(2βₖ), no linear terms;
* **none** (λₖ = βₖ = 0): the surface contains lines along uₖ — a cylinder's axis.

A coordinate enters squared (αₓ ≠ 0) or linearly (αₓ = 0); with (U, V) = (x or x², y or y²)
every boundary of a low-distortion region is a line (:func:`region_lines`), which is what
:mod:`.regions` and the sampler build on. One numba kernel (:func:`frame_kernel`) computes all of
it; the Python API below and the sampler both call it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_finite_array, as_instance, as_points
from csgnb.quadric.evaluate import ieee_jit, inline_jit
from csgnb.quadric.quadric import Quadric

__all__ = [
    "PrincipalFrame",
    "SamplingPlane",
    "HEIGHTFIELD_TYPES",
    "FORMS",
    "principal_frame",
    "sampling_planes",
    "heightfield",
    "heightfield_type",
    "plane_kind",
    "as_coordinates",
    "to_plane_coordinates",
    "from_plane_coordinates",
    "frame_kernel",
    "region_lines",
    "plane_height",
]

#: Heightfield forms by code (``SamplingPlane.form``; the kernels use the codes).
FORMS = ("none", "sheets", "graph")
FORM_NONE, FORM_SHEETS, FORM_GRAPH = 0, 1, 2

#: Heightfield types. The first five are Figure 5's eq. 7 cases; then the degenerate eq. 7 cases,
#: the parabolic sheets of a paraboloid's side planes and the graphs seen along its axis.
HEIGHTFIELD_TYPES: dict[str, str] = {
    "elliptic-cap": "αₓ, α_y < 0 < α_c: a cap over the inside of an ellipse (ellipsoid)",
    "elliptic-bowl": "αₓ, α_y, α_c > 0: defined on the whole plane (two-sheet hyperboloid)",
    "elliptic-hole": "αₓ, α_y > 0 > α_c: defined outside an ellipse (one-sheet hyperboloid)",
    "hyperbolic-inner": "αₓα_y < 0 < α_c: defined between the branches of a hyperbola",
    "hyperbolic-outer": "αₓα_y < 0, α_c < 0: defined beyond the branches of a hyperbola",
    "cone": "α_c = 0, αₓ, α_y not both ≤ 0: the sheets meet at the center",
    "cylindrical": "exactly one of αₓ, α_y is 0: constant along one in-plane axis",
    "parallel-planes": "αₓ = α_y = 0 < α_c: two planes parallel to the sampling plane",
    "parabolic-inner": "t² = αx² + b y + α_c, α < 0: inside a parabola (elliptic paraboloid, side view)",
    "parabolic-outer": "t² = αx² + b y + α_c, α > 0: outside a parabola (hyperbolic paraboloid, side view)",
    "parabolic-half-plane": "t² = b y + α_c: a half-plane (parabolic cylinder, side view)",
    "elliptic-graph": "t = αₓx² + α_y y² + α_c, αₓα_y > 0: an elliptic paraboloid along its axis",
    "hyperbolic-graph": "t = αₓx² + α_y y² + α_c, αₓα_y < 0: a saddle along its axis",
    "parabolic-graph": "t = αx² + α_c: a parabolic cylinder across its rulings",
    "flat-graph": "t = α_c: a single plane seen from itself",
    "empty": "no real point (e.g. αₓ, α_y, α_c < 0), or only the center",
    "none": "λₖ = βₖ = 0: the surface contains lines normal to the plane; no heightfield",
}


@dataclass(frozen=True)
class PrincipalFrame:
    """Center and principal axes of a quadric (paper §3.2, Figure 3).

    center : (3,) float64 — min-norm least-squares solution of ``A q = b``.
    axes : (3, 3) float64 — columns are unit eigenvectors uᵢ of A, right-handed; within a null
        space of A they are turned so that at most one carries b's null part (``linear``).
    eigenvalues : (3,) float64 — λᵢ, ascending as computed, noise (``tolerances.EIGENVALUE_NOISE``) set to 0.
    central : bool — whether ``A q = b`` holds (false for paraboloids and single planes).
    linear : (3,) float64 — β = Uᵀ(b − A q), at most one entry nonzero.
    constant : float — γ = c − qᵀb, so that ``Q(q + U d) = Σλᵢdᵢ² − 2βᵀd + γ``.
    """

    center: np.ndarray
    axes: np.ndarray
    eigenvalues: np.ndarray
    central: bool
    linear: np.ndarray
    constant: float


@dataclass(frozen=True)
class SamplingPlane:
    """The sampling plane P_ij = {q + x uᵢ + y uⱼ} with normal uₖ and its heightfield.

    axis : int — k, the principal axis normal to the plane (i = k+1, j = k+2 mod 3).
    origin : (3,) float64 — the quadric center q.
    x_axis, y_axis, normal : (3,) float64 — uᵢ, uⱼ, uₖ (right-handed).
    alpha : (3,) float64 — (αₓ, α_y, α_c); NaN when ``form`` is ``"none"``.
    kind : str — a key of :data:`HEIGHTFIELD_TYPES`.
    linear : (2,) float64 — (bₓ, b_y), the linear terms of a parabolic heightfield (else 0).
    form : str — ``"sheets"`` (t = ±√H), ``"graph"`` (t = H) or ``"none"``.
    """

    axis: int
    origin: np.ndarray
    x_axis: np.ndarray
    y_axis: np.ndarray
    normal: np.ndarray
    alpha: np.ndarray
    kind: str
    linear: np.ndarray = field(default_factory=lambda: np.zeros(2))
    form: str = "sheets"

    @property
    def frame(self) -> np.ndarray:
        """(3, 3) float64: columns uᵢ, uⱼ, uₖ (local x, y, t)."""
        return np.column_stack([self.x_axis, self.y_axis, self.normal])

    @property
    def coefficients(self) -> np.ndarray:
        """(5,) float64 (αₓ, bₓ, α_y, b_y, α_c): the kernels' layout of the heightfield."""
        a = np.nan_to_num(self.alpha)
        return np.array([a[0], self.linear[0], a[1], self.linear[1], a[2]])

    @property
    def form_code(self) -> int:
        """The form as the kernels' code (index into :data:`FORMS`)."""
        return FORMS.index(self.form)


# -- the kernel ------------------------------------------------------------------------------------


@ieee_jit
def frame_kernel(Q, center, axes, lam, beta, form, coef):
    """Principal frame and plane forms of the quadric ``Q`` (4, 4); returns (central, γ, λ_min, λ_max).

    Writes ``center`` (3,), ``axes`` (3, 3) (columns), ``lam`` (3,) (noise set to 0), ``beta`` (3,)
    (b's null-space part in the axes), ``form`` (3,) int64 (codes of :data:`FORMS`) and ``coef``
    (3, 5): per plane k the heightfield (αₓ, bₓ, α_y, b_y, α_c) of the module docstring. λ_min,
    λ_max are the eigenvalues as computed (before the noise rule) — the bounds of eq. 10–11.
    """
    A = np.empty((3, 3))
    b = np.empty(3)
    for r in range(3):
        b[r] = -Q[r, 3]
        for s in range(3):
            A[r, s] = Q[r, s]
    c = Q[3, 3]
    w, U0 = np.linalg.eigh(A)
    U = np.ascontiguousarray(U0)
    lam_min, lam_max = w[0], w[2]
    _canonical_eigenvectors(w, U)
    anorm = 0.0
    for r in range(3):
        for s in range(3):
            anorm += A[r, s] * A[r, s]
    anorm = math.sqrt(anorm)
    # an eigenvalue below the rounding noise of the entries it came from is 0 (tolerances)
    for k in range(3):
        spread = 0.0
        res = 0.0
        for r in range(3):
            ar = 0.0
            for s in range(3):
                spread += abs(A[r, s]) * abs(U[r, k]) * abs(U[s, k])
                ar += A[r, s] * U[s, k]
            res += (ar - w[k] * U[r, k]) ** 2
        lam[k] = 0.0 if abs(w[k]) <= tol.EIGENVALUE_NOISE * spread + 8.0 * math.sqrt(res) else w[k]
    for r in range(3):
        for s in range(3):
            axes[r, s] = U[r, s]
    # min-norm center through the nonzero eigenvalues
    for r in range(3):
        center[r] = 0.0
    for k in range(3):
        if lam[k] != 0.0:
            f = (axes[0, k] * b[0] + axes[1, k] * b[1] + axes[2, k] * b[2]) / lam[k]
            for r in range(3):
                center[r] += f * axes[r, k]
    qn = math.sqrt(center[0] ** 2 + center[1] ** 2 + center[2] ** 2)
    bn = math.sqrt(b[0] ** 2 + b[1] ** 2 + b[2] ** 2)
    noise = tol.LINEAR_NOISE * (bn + anorm * qn + math.sqrt(anorm * abs(c)))
    # b's null-space part: turn a 2- or 3-dimensional null basis so that one vector carries it
    nz = 0
    w0 = 0.0
    w1 = 0.0
    w2 = 0.0
    for k in range(3):
        if lam[k] == 0.0:
            nz += 1
            bk = axes[0, k] * b[0] + axes[1, k] * b[1] + axes[2, k] * b[2]
            w0 += bk * axes[0, k]
            w1 += bk * axes[1, k]
            w2 += bk * axes[2, k]
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if nz >= 2 and wn > noise:
        w0, w1, w2 = w0 / wn, w1 / wn, w2 / wn
        first = -1
        second = -1
        other = -1
        for k in range(3):
            if lam[k] == 0.0:
                if first < 0:
                    first = k
                elif second < 0:
                    second = k
            else:
                other = k
        axes[0, first], axes[1, first], axes[2, first] = w0, w1, w2
        if other >= 0:  # rank 1: the second null vector is normal to ŵ and to the range
            e0, e1, e2 = axes[0, other], axes[1, other], axes[2, other]
        else:  # A = 0: any vector normal to ŵ
            e0, e1, e2 = (1.0, 0.0, 0.0) if abs(w0) < 0.9 else (0.0, 1.0, 0.0)
        v0 = e1 * w2 - e2 * w1
        v1 = e2 * w0 - e0 * w2
        v2 = e0 * w1 - e1 * w0
        vn = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        axes[0, second], axes[1, second], axes[2, second] = v0 / vn, v1 / vn, v2 / vn
        if other < 0:  # the third completes the frame
            third = 3 - first - second
            axes[0, third] = w1 * axes[2, second] - w2 * axes[1, second]
            axes[1, third] = w2 * axes[0, second] - w0 * axes[2, second]
            axes[2, third] = w0 * axes[1, second] - w1 * axes[0, second]
    # right-handed
    det = (axes[0, 0] * (axes[1, 1] * axes[2, 2] - axes[2, 1] * axes[1, 2])
           - axes[0, 1] * (axes[1, 0] * axes[2, 2] - axes[2, 0] * axes[1, 2])
           + axes[0, 2] * (axes[1, 0] * axes[2, 1] - axes[2, 0] * axes[1, 1]))
    if det < 0.0:
        for r in range(3):
            axes[r, 2] = -axes[r, 2]
    central = True
    for k in range(3):
        beta[k] = 0.0
        if lam[k] == 0.0:
            bk = axes[0, k] * b[0] + axes[1, k] * b[1] + axes[2, k] * b[2]
            if abs(bk) > noise:
                beta[k] = bk
                central = False
    qb = center[0] * b[0] + center[1] * b[1] + center[2] * b[2]
    gamma = c - qb
    if abs(gamma) <= tol.CONSTANT_NOISE * (abs(c) + abs(qb)):
        gamma = 0.0
    for k in range(3):
        i = (k + 1) % 3
        j = (k + 2) % 3
        for e in range(5):
            coef[k, e] = 0.0
        if lam[k] != 0.0:
            form[k] = FORM_SHEETS
            coef[k, 0] = -lam[i] / lam[k] + 0.0
            coef[k, 1] = 2.0 * beta[i] / lam[k] + 0.0
            coef[k, 2] = -lam[j] / lam[k] + 0.0
            coef[k, 3] = 2.0 * beta[j] / lam[k] + 0.0
            coef[k, 4] = -gamma / lam[k] + 0.0
        elif beta[k] != 0.0:
            form[k] = FORM_GRAPH
            coef[k, 0] = lam[i] / (2.0 * beta[k]) + 0.0
            coef[k, 2] = lam[j] / (2.0 * beta[k]) + 0.0
            coef[k, 4] = gamma / (2.0 * beta[k]) + 0.0
        else:
            form[k] = FORM_NONE
    return central, gamma, lam_min, lam_max


@ieee_jit
def _canonical_eigenvectors(w, U):
    """Make the eigenvectors ``U`` (columns) of A independent of rounding where A leaves them free.

    Within a repeated eigenvalue (a circular cylinder's pair, a sphere's triple: eigenvalues within
    ``tolerances.EIGENVECTOR_GAP`` of each other) any orthonormal basis is one; eigh returns one
    that depends on the last bits of A. Take the world axes instead (a pair: the axis with the
    largest part in the plane, then its normal in the plane; a triple: x, y, z), and give every
    vector the sign that makes its largest component positive. So a model and its scaled or
    translated copy get the same frames, and the same samples.
    """
    top = max(abs(w[0]), abs(w[2]))
    gap = tol.EIGENVECTOR_GAP * top
    same01 = abs(w[1] - w[0]) <= gap
    same12 = abs(w[2] - w[1]) <= gap
    if same01 and same12:
        for r in range(3):
            for c in range(3):
                U[r, c] = 1.0 if r == c else 0.0
        return
    if same01 or same12:
        m = 2 if same01 else 0  # the well-defined eigenvector
        k0, k1 = (0, 1) if same01 else (1, 2)
        n0, n1, n2 = U[0, m], U[1, m], U[2, m]
        big = 0
        for e in range(3):
            if abs(U[e, m]) > abs(U[big, m]):
                big = e
        if U[big, m] < 0.0:
            n0, n1, n2 = -n0, -n1, -n2
        U[0, m], U[1, m], U[2, m] = n0, n1, n2
        best = 0
        best_p = -1.0
        for e in range(3):  # the world axis with the largest part in the eigenplane
            ne = n0 if e == 0 else (n1 if e == 1 else n2)
            p = 1.0 - ne * ne
            if p > best_p + tol.TIE:
                best, best_p = e, p
        ne = n0 if best == 0 else (n1 if best == 1 else n2)
        u0, u1, u2 = -ne * n0, -ne * n1, -ne * n2
        if best == 0:
            u0 += 1.0
        elif best == 1:
            u1 += 1.0
        else:
            u2 += 1.0
        un = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        u0, u1, u2 = u0 / un, u1 / un, u2 / un
        U[0, k0], U[1, k0], U[2, k0] = u0, u1, u2
        U[0, k1] = n1 * u2 - n2 * u1
        U[1, k1] = n2 * u0 - n0 * u2
        U[2, k1] = n0 * u1 - n1 * u0
    for c in range(3):
        big = 0
        for e in range(3):
            if abs(U[e, c]) > abs(U[big, c]) + tol.TIE:
                big = e
        if U[big, c] < 0.0:
            for e in range(3):
                U[e, c] = -U[e, c]


@inline_jit
def plane_height(form, ax, bx, ay, by, ac, sheet, x, y):
    """Return the height t over (x, y) on the sheet ``sheet`` (±1; graphs have one).

    Rounding just outside a sheet's domain (H < 0) is clamped to its rim, t = 0.
    """
    H = (ax * x + bx) * x + (ay * y + by) * y + ac
    if form == FORM_GRAPH:
        return H
    return sheet * math.sqrt(H) if H > 0.0 else 0.0


@inline_jit
def region_lines(form, ax, bx, ay, by, ac, octant):
    """Return the (wedge, conic) lines of one octant of a plane's low-distortion region in (U, V).

    (U, V) = (x² or x, y² or y): a coordinate is squared when its α is nonzero. With the squared
    normal components |n_t|² ∝ T, |n_x|² ∝ Nₓ, |n_y|² ∝ N_y — all affine in (U, V) —, octant "x"
    (``octant`` 0) is Nₓ ≥ N_y (the wedge) and T ≥ Nₓ (the conic, eq. 15); octant "y" (1) swaps
    x and y (eq. 16). Returns six floats (a, b, c, a', b', c'): the region is a U + b V + c ≥ 0
    and a' U + b' V + c' ≥ 0 (and the quadrant's box).
    """
    xs = ax != 0.0
    ys = ay != 0.0
    if form == FORM_GRAPH:
        tu, tv, tc = 0.0, 0.0, 0.25
        nxu, nx0 = ax * ax, 0.0
        nyv, ny0 = ay * ay, 0.0
    else:
        tu = ax if xs else bx
        tv = ay if ys else by
        tc = ac
        nxu = ax * ax if xs else 0.0
        nx0 = 0.0 if xs else 0.25 * bx * bx
        nyv = ay * ay if ys else 0.0
        ny0 = 0.0 if ys else 0.25 * by * by
    if octant == 0:
        return nxu, -nyv, nx0 - ny0, tu - nxu, tv, tc - nx0
    return -nxu, nyv, ny0 - nx0, tu, tv - nyv, tc - ny0


# -- Python API ------------------------------------------------------------------------------------


def _frame_arrays(q: Quadric):
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a csgnb.quadric.Quadric, got {type(q).__name__}")
    center, axes, lam, beta = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty(3)
    form, coef = np.empty(3, dtype=np.int64), np.empty((3, 5))
    central, gamma, _, _ = frame_kernel(np.array(q.matrix, np.float64, order="C"), center, axes, lam, beta, form, coef)
    return center, axes, lam, beta, form, coef, bool(central), float(gamma)


def principal_frame(q: Quadric) -> PrincipalFrame:
    """Return the center, principal axes and eigenvalues of ``q`` (eigh, min-norm center)."""
    center, axes, lam, beta, _, _, central, gamma = _frame_arrays(q)
    return PrincipalFrame(center, axes, lam, central, beta, gamma)


def heightfield_type(alpha) -> str:
    """Return the type (a key of :data:`HEIGHTFIELD_TYPES`) of the eq. 7 heightfield (αₓ, α_y, α_c)."""
    a = as_finite_array(alpha, None, "alpha", finite=False).reshape(-1)
    if a.shape != (3,):
        raise CsgnbError(f"alpha must be (αₓ, α_y, α_c), got shape {a.shape}")
    ax, ay, ac = (float(v) for v in a)
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


def plane_kind(form: int, coef) -> str:
    """Return the heightfield type of a plane given as a form code and (αₓ, bₓ, α_y, b_y, α_c)."""
    ax, bx, ay, by, ac = (float(v) for v in coef)
    if form == FORM_NONE:
        return "none"
    if form == FORM_GRAPH:
        if ax != 0.0 and ay != 0.0:
            return "elliptic-graph" if ax * ay > 0.0 else "hyperbolic-graph"
        return "flat-graph" if ax == 0.0 and ay == 0.0 else "parabolic-graph"
    if bx == 0.0 and by == 0.0:
        return heightfield_type([ax, ay, ac])
    a = ay if bx != 0.0 else ax  # the squared coordinate's α
    if a == 0.0:
        return "parabolic-half-plane"
    return "parabolic-inner" if a < 0.0 else "parabolic-outer"


def sampling_planes(q: Quadric) -> tuple[SamplingPlane, SamplingPlane, SamplingPlane]:
    """Return the three sampling planes P₁₂, P₂₀, P₀₁ (normal u₀, u₁, u₂) with their heightfields.

    Every quadric type has them: central quadrics get eq. 7 (``form="sheets"``); paraboloids get
    parabolic sheets on their side planes and a graph along their axis; a single plane is a flat
    graph over itself. Planes whose normal is a ruling direction (λₖ = βₖ = 0, e.g. a cylinder's
    axis) have ``form="none"``, ``kind="none"`` and NaN ``alpha``.
    """
    center, U, _, _, form, coef, _, _ = _frame_arrays(q)
    planes = []
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        if form[k] == FORM_NONE:
            alpha, lin = np.full(3, np.nan), np.zeros(2)
        else:
            alpha, lin = coef[k, [0, 2, 4]].copy(), coef[k, [1, 3]].copy()
        alpha.setflags(write=False)
        lin.setflags(write=False)
        axes = (U[:, i].copy(), U[:, j].copy(), U[:, k].copy())
        planes.append(SamplingPlane(k, center.copy(), *axes, alpha, plane_kind(int(form[k]), coef[k]), lin,
                                    FORMS[int(form[k])]))
    return tuple(planes)


def to_plane_coordinates(plane: SamplingPlane, points) -> np.ndarray:
    """Return local coordinates (x, y, t) : (n, 3) of world ``points`` : (n, 3)."""
    as_instance(plane, SamplingPlane, "plane")
    pts = as_points(points)
    with np.errstate(invalid="ignore"):  # NaN/inf points give NaN coordinates
        return (pts - plane.origin) @ plane.frame


def from_plane_coordinates(plane: SamplingPlane, xyt) -> np.ndarray:
    """Return world points : (n, 3) of local coordinates ``xyt`` : (n, 3) (x, y, t)."""
    as_instance(plane, SamplingPlane, "plane")
    loc = as_points(xyt, "xyt")
    with np.errstate(invalid="ignore"):
        return plane.origin + loc @ plane.frame.T


def as_coordinates(x, y) -> tuple[np.ndarray, np.ndarray]:
    """Return ``x``, ``y`` broadcast to two C-contiguous (n,) float64 arrays."""
    xa = as_finite_array(x, None, "x", finite=False)
    ya = as_finite_array(y, None, "y", finite=False)
    try:
        xa, ya = np.broadcast_arrays(xa, ya)
    except ValueError as exc:
        raise CsgnbError(f"x {np.shape(x)} and y {np.shape(y)} do not broadcast together") from exc
    return np.ascontiguousarray(xa.reshape(-1)), np.ascontiguousarray(ya.reshape(-1))


def as_heightfield(plane_or_alpha) -> tuple[int, np.ndarray]:
    """Return (form code, (αₓ, bₓ, α_y, b_y, α_c)) of a :class:`SamplingPlane` or an eq. 7 α (3,)."""
    if isinstance(plane_or_alpha, SamplingPlane):
        if plane_or_alpha.form == "none":
            raise GeometryError(f"sampling plane {plane_or_alpha.axis} has no heightfield (kind 'none')")
        return plane_or_alpha.form_code, plane_or_alpha.coefficients
    if plane_or_alpha is None or isinstance(plane_or_alpha, str | bytes):
        raise TypeError(f"expected a SamplingPlane or alpha (3,), got {type(plane_or_alpha).__name__}")
    a = as_finite_array(plane_or_alpha, None, "alpha", finite=False).reshape(-1)
    if a.shape != (3,):
        raise CsgnbError(f"alpha must be (αₓ, α_y, α_c), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise GeometryError("alpha is NaN: this sampling plane has no eq. 7 heightfield")
    return FORM_SHEETS, np.array([a[0], 0.0, a[1], 0.0, a[2]])


@ieee_jit
def _heightfield_kernel(form, coef, x, y, out):
    """out[i] = the upper sheet's height (NaN off the domain) or the graph's; x, y, out : (n,).

    Separate x and y arrays (not (n, 2) rows) let the loop vectorise: twice the throughput.
    """
    ax, bx, ay, by, ac = coef[0], coef[1], coef[2], coef[3], coef[4]
    graph = form == FORM_GRAPH
    for i in range(x.shape[0]):
        xi = x[i]
        yi = y[i]
        H = (ax * xi + bx) * xi + (ay * yi + by) * yi + ac
        out[i] = H if graph else math.sqrt(H)


def heightfield(plane, x, y) -> np.ndarray:
    """Return the height over (x, y) of a sampling plane's heightfield (eq. 7 and its forms).

    Parameters
    ----------
    plane : SamplingPlane, or (3,) float64 — a plane of :func:`sampling_planes`, or (αₓ, α_y, α_c)
        of an eq. 7 heightfield.
    x, y : (n,) float64 — local coordinates on the sampling plane (broadcast together).

    Returns
    -------
    (n,) float64 — sheets: t = √H ≥ 0 of the upper sheet (the lower is −t), NaN off the domain;
    graphs: t = H.
    """
    form, coef = as_heightfield(plane)
    xs, ys = as_coordinates(x, y)
    out = np.empty(xs.shape[0])
    _heightfield_kernel(form, coef, xs, ys, out)
    return out
