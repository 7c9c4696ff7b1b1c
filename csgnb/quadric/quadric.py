"""The Quadric type: a symmetric 4×4 matrix, its constructors, transforms and complement.

A quadric surface is the zero set of ``Q(x) = xᵀ Q x`` for homogeneous ``x = (x, y, z, 1)``
(paper eq. 1). With the block decomposition of eq. 2,

    Q = [[ A,  -b],
         [-bᵀ,  c]],      Q(x) = xᵀ A x - 2 xᵀ b + c        (eq. 3)

``Q(x) < 0`` is *inside*, ``Q(x) > 0`` *outside*. Every constructor below follows that
convention (a sphere is negative in its interior), so negation is the Boolean complement.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property

import numpy as np

from csgnb.errors import GeometryError

__all__ = [
    "Quadric",
    "QUADRIC_CONSTRUCTORS",
    "plane",
    "parallel_planes",
    "sphere",
    "ellipsoid",
    "elliptic_cylinder",
    "elliptic_cone",
    "hyperboloid_one_sheet",
    "hyperboloid_two_sheets",
    "elliptic_paraboloid",
    "hyperbolic_paraboloid",
]

#: Relative asymmetry |Q - Qᵀ| / max|Q| above which a matrix is rejected (rounding is far below).
SYMMETRY_TOLERANCE = 1e-12
#: Condition number above which a transform is treated as singular (its inverse is noise).
SINGULAR_CONDITION = 1e12


def _as_finite_array(values, shape: tuple[int, ...], name: str) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of numbers, got {type(values).__name__}") from exc
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise GeometryError(f"{name} contains NaN or inf: {arr.tolist()}; pass finite numbers")
    return arr


class Quadric:
    """A quadric surface ``xᵀ Q x = 0`` with ``Q`` symmetric 4×4 (inside where negative).

    Parameters
    ----------
    matrix : (4, 4) float64
        Symmetric coefficient matrix. A relative asymmetry up to ``SYMMETRY_TOLERANCE`` is
        averaged away; more raises :class:`GeometryError`, as do NaN/inf entries, the zero
        matrix and matrices whose ``A`` and ``b`` blocks vanish (a constant has no surface).
    """

    def __init__(self, matrix) -> None:
        q = _as_finite_array(matrix, (4, 4), "quadric matrix")
        scale = float(np.max(np.abs(q)))
        if scale == 0.0:
            raise GeometryError("quadric matrix is zero: every point would lie on the surface")
        asym = float(np.max(np.abs(q - q.T)))
        if asym > SYMMETRY_TOLERANCE * scale:
            raise GeometryError(
                f"quadric matrix is not symmetric (max |Q - Qᵀ| = {asym:.3g}, max |Q| = "
                f"{scale:.3g}); pass (Q + Q.T) / 2 if the asymmetry is intended noise"
            )
        q = 0.5 * (q + q.T)
        if not np.any(q[:3, :]):
            raise GeometryError(
                "quadric has A = 0 and b = 0: Q(x) is the constant c and has no surface"
            )
        q.setflags(write=False)
        self._matrix = q

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_abc(cls, A, b, c: float) -> Quadric:
        """Return the quadric ``xᵀAx - 2xᵀb + c`` (eq. 3). ``A`` : (3, 3), ``b`` : (3,)."""
        A = _as_finite_array(A, (3, 3), "A")
        b = _as_finite_array(b, (3,), "b")
        c = float(_as_finite_array(c, (), "c"))
        m = np.empty((4, 4))
        m[:3, :3] = A
        m[:3, 3] = -b
        m[3, :3] = -b
        m[3, 3] = c
        return cls(m)

    # -- blocks of eq. 2 -----------------------------------------------------------------
    @property
    def matrix(self) -> np.ndarray:
        """The symmetric coefficient matrix Q : (4, 4) float64 (read-only)."""
        return self._matrix

    @property
    def A(self) -> np.ndarray:  # noqa: N802 (the paper's name)
        """The quadratic block A : (3, 3) float64."""
        return self._matrix[:3, :3]

    @property
    def b(self) -> np.ndarray:
        """The linear block b : (3,) float64 (Q's last column is ``-b``)."""
        return -self._matrix[:3, 3]

    @property
    def c(self) -> float:
        """The constant term c."""
        return float(self._matrix[3, 3])

    @cached_property
    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues λ of A in ascending order : (3,) float64."""
        return np.linalg.eigvalsh(self.A)

    # -- transforms ----------------------------------------------------------------------
    def transformed(self, M) -> Quadric:
        """Return the image of this quadric under the 4×4 (affine or projective) map ``M``.

        ``Q' = M⁻ᵀ Q M⁻¹`` (eq. 17), so that ``Q'(M x) = Q(x)`` for homogeneous ``x``.
        A 3×4 affine matrix ``[R | t]`` is accepted too. Singular or ill-conditioned
        ``M`` (condition number above ``SINGULAR_CONDITION``) raises :class:`GeometryError`.
        """
        M = np.asarray(M, dtype=np.float64)
        if M.shape == (3, 4):
            M = np.vstack([M, [0.0, 0.0, 0.0, 1.0]])
        M = _as_finite_array(M, (4, 4), "transform")
        cond = np.linalg.cond(M)
        if not np.isfinite(cond) or cond > SINGULAR_CONDITION:
            raise GeometryError(
                f"transform is singular (condition number {cond:.3g}); a quadric can only be "
                "mapped by an invertible 4×4 matrix"
            )
        Minv = np.linalg.inv(M)
        q = Minv.T @ self._matrix @ Minv
        return Quadric(0.5 * (q + q.T))

    def translated(self, offset) -> Quadric:
        """Return this quadric moved by ``offset`` : (3,)."""
        m = np.eye(4)
        m[:3, 3] = _as_finite_array(offset, (3,), "offset")
        return self.transformed(m)

    def complement(self) -> Quadric:
        """Return the complement (Boolean NOT): same surface, inside and outside swapped."""
        return Quadric(-self._matrix)

    def __neg__(self) -> Quadric:
        return self.complement()

    # -- evaluation (thin wrappers; the kernels live in evaluate.py / distance.py) ---------
    def value(self, points) -> np.ndarray:
        """Return Q(x) : (n,) float64 for ``points`` : (n, 3)."""
        from csgnb.quadric.evaluate import value

        return value(self, points)

    def gradient(self, points) -> np.ndarray:
        """Return ∇Q(x) = 2(Ax - b) : (n, 3) float64 (eq. 4)."""
        from csgnb.quadric.evaluate import gradient

        return gradient(self, points)

    def normal(self, points) -> np.ndarray:
        """Return the unit normal N(x) : (n, 3) float64, NaN where ∇Q = 0 (eq. 4)."""
        from csgnb.quadric.evaluate import normal

        return normal(self, points)

    def intersect_lines(self, origins, directions) -> np.ndarray:
        """Return the line parameters ``t`` : (n, 2) of ``Q(p + t v) = 0`` (eq. 5–6)."""
        from csgnb.quadric.evaluate import intersect_lines

        return intersect_lines(self, origins, directions)

    def signed_distance(self, points) -> np.ndarray:
        """Return the conservative signed distance d(x₀) : (n,) float64 (eq. 10–12)."""
        from csgnb.quadric.distance import signed_distance

        return signed_distance(self, points)

    def __repr__(self) -> str:
        rows = ", ".join("[" + ", ".join(f"{v:.6g}" for v in r) + "]" for r in self._matrix)
        return f"Quadric([{rows}])"


# -- constructors (canonical pose; move them with .transformed / .translated) ----------------


def _positive(values, n: int, name: str) -> np.ndarray:
    arr = _as_finite_array(np.broadcast_to(np.asarray(values, dtype=np.float64), (n,)), (n,), name)
    if np.any(arr <= 0.0):
        raise GeometryError(f"{name} must be positive, got {arr.tolist()}")
    return arr


def _diag(a: np.ndarray, b=(0.0, 0.0, 0.0), c: float = 0.0, center=None) -> Quadric:
    q = Quadric.from_abc(np.diag(a), b, c)
    if center is not None:
        q = q.translated(center)
    return q


def plane(normal, offset: float = 0.0) -> Quadric:
    """Return the plane ``n·x = offset`` (inside where ``n·x < offset``). ``normal`` : (3,)."""
    n = _as_finite_array(normal, (3,), "normal")
    norm = float(np.linalg.norm(n))
    if norm == 0.0:
        raise GeometryError("plane normal is zero; pass a non-zero direction")
    n = n / norm
    # Q(x) = n·x - d  ⇔  A = 0, -2b = n, c = -d
    return Quadric.from_abc(np.zeros((3, 3)), -0.5 * n, -float(offset) / norm)


def parallel_planes(normal, offset0: float, offset1: float) -> Quadric:
    """Return the slab between the planes ``n·x = offset0`` and ``n·x = offset1`` (inside)."""
    n = _as_finite_array(normal, (3,), "normal")
    norm = float(np.linalg.norm(n))
    if norm == 0.0:
        raise GeometryError("plane normal is zero; pass a non-zero direction")
    if offset0 == offset1:
        raise GeometryError("parallel planes coincide; pass two different offsets")
    n = n / norm
    d0, d1 = float(offset0) / norm, float(offset1) / norm
    # (n·x - d0)(n·x - d1): negative strictly between the planes
    return Quadric.from_abc(np.outer(n, n), 0.5 * (d0 + d1) * n, d0 * d1)


def sphere(center=(0.0, 0.0, 0.0), radius: float = 1.0) -> Quadric:
    """Return the sphere ``|x - center|² = radius²``."""
    r = _positive(radius, 1, "radius")[0]
    return _diag(np.ones(3), c=-r * r, center=center)


def ellipsoid(radii=(1.0, 1.0, 1.0), center=None) -> Quadric:
    """Return the axis-aligned ellipsoid ``Σ (xᵢ / rᵢ)² = 1``. ``radii`` : (3,)."""
    r = _positive(radii, 3, "radii")
    return _diag(1.0 / r**2, c=-1.0, center=center)


def elliptic_cylinder(radii=(1.0, 1.0), center=None) -> Quadric:
    """Return the cylinder ``(x/a)² + (y/b)² = 1`` along z. ``radii`` : (2,)."""
    r = _positive(radii, 2, "radii")
    return _diag(np.array([1.0 / r[0] ** 2, 1.0 / r[1] ** 2, 0.0]), c=-1.0, center=center)


def elliptic_cone(slopes=(1.0, 1.0), center=None) -> Quadric:
    """Return the double cone ``(x/a)² + (y/b)² = z²`` with apex at ``center``."""
    s = _positive(slopes, 2, "slopes")
    return _diag(np.array([1.0 / s[0] ** 2, 1.0 / s[1] ** 2, -1.0]), center=center)


def hyperboloid_one_sheet(radii=(1.0, 1.0, 1.0), center=None) -> Quadric:
    """Return ``(x/a)² + (y/b)² - (z/c)² = 1`` (one sheet around the z axis)."""
    r = _positive(radii, 3, "radii")
    return _diag(np.array([1.0, 1.0, -1.0]) / r**2, c=-1.0, center=center)


def hyperboloid_two_sheets(radii=(1.0, 1.0, 1.0), center=None) -> Quadric:
    """Return ``(z/c)² - (x/a)² - (y/b)² = 1`` (two sheets along z, inside = within a sheet)."""
    r = _positive(radii, 3, "radii")
    return _diag(np.array([1.0, 1.0, -1.0]) / r**2, c=1.0, center=center)


def elliptic_paraboloid(radii=(1.0, 1.0), center=None) -> Quadric:
    """Return ``z = (x/a)² + (y/b)²`` (inside above the vertex at ``center``)."""
    r = _positive(radii, 2, "radii")
    return _diag(np.array([1.0 / r[0] ** 2, 1.0 / r[1] ** 2, 0.0]), b=(0, 0, 0.5), center=center)


def hyperbolic_paraboloid(radii=(1.0, 1.0), center=None) -> Quadric:
    """Return the saddle ``z = (x/a)² - (y/b)²``."""
    r = _positive(radii, 2, "radii")
    return _diag(np.array([1.0 / r[0] ** 2, -1.0 / r[1] ** 2, 0.0]), b=(0, 0, 0.5), center=center)


#: The paper's quadric types (Figure 3) by name, each with default, unit-sized parameters.
QUADRIC_CONSTRUCTORS: dict[str, Callable[[], Quadric]] = {
    "plane": lambda: plane((0.0, 0.0, 1.0)),
    "parallel planes": lambda: parallel_planes((0.0, 0.0, 1.0), -1.0, 1.0),
    "sphere": sphere,
    "ellipsoid": lambda: ellipsoid((1.5, 1.0, 0.7)),
    "elliptic cylinder": lambda: elliptic_cylinder((1.0, 0.6)),
    "elliptic cone": lambda: elliptic_cone((1.0, 0.6)),
    "hyperboloid (one sheet)": lambda: hyperboloid_one_sheet((1.0, 0.8, 1.2)),
    "hyperboloid (two sheets)": lambda: hyperboloid_two_sheets((1.0, 0.8, 0.6)),
    "elliptic paraboloid": lambda: elliptic_paraboloid((1.0, 0.7)),
    "hyperbolic paraboloid": lambda: hyperbolic_paraboloid((1.0, 0.7)),
}
