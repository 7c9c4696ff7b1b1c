"""The Quadric type: a symmetric 4×4 matrix, its constructors, transforms and complement.

A quadric surface is the zero set of ``Q(x) = xᵀ Q x`` for homogeneous ``x = (x, y, z, 1)``
(paper eq. 1). With the block decomposition of eq. 2,

    Q = [[ A,  -b],
         [-bᵀ,  c]],      Q(x) = xᵀ A x - 2 xᵀ b + c        (eq. 3)

``Q(x) < 0`` is *inside*, ``Q(x) > 0`` *outside*. Every constructor below follows that
convention (a sphere is negative in its interior), so negation is the Boolean complement.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cached_property

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_finite_array, as_matrix, as_real

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
    "transform_inverse",
]

#: Kept for callers of the former names (the values live in :mod:`csgnb.quadric.tolerances`).
SYMMETRY_TOLERANCE = tol.SYMMETRY
SINGULAR_CONDITION = tol.SINGULAR_CONDITION

# one finite-array check for quadrics and CSG transforms (csgnb.csg imports it under this name)
_as_finite_array = as_finite_array


def transform_inverse(M: np.ndarray, name: str = "transform") -> np.ndarray:
    """Return the inverse of the 4×4 map ``M``, or raise :class:`GeometryError` if it is singular.

    An affine ``M = [[L, t], [0, 1]]`` is inverted blockwise (``[[L⁻¹, -L⁻¹t], [0, 1]]``), so the
    last row stays exactly ``(0, 0, 0, 1)`` and a plane's zero A block stays exactly zero. Its
    conditioning is that of L — a translation, however far, is harmless. A projective M is
    judged by its own condition number. The bound is ``tolerances.SINGULAR_CONDITION``, measured
    as ``|L|_F |L⁻¹|_F`` (at most 3× the 2-norm condition number, and cheap).
    """
    if M[3, 0] == 0.0 and M[3, 1] == 0.0 and M[3, 2] == 0.0 and M[3, 3] != 0.0:
        L = M[:3, :3] / M[3, 3]
        t = M[:3, 3] / M[3, 3]
        det = float(np.linalg.det(L))
        Li = np.linalg.inv(L) if det != 0.0 and np.isfinite(det) else None
        cond = np.inf if Li is None else float(np.linalg.norm(L) * np.linalg.norm(Li))
        if not cond <= tol.SINGULAR_CONDITION:
            raise GeometryError(
                f"{name} is singular (condition number of its linear part ≈ {cond:.3g}, above "
                f"{tol.SINGULAR_CONDITION:.0e}); a quadric can only be mapped by an invertible matrix"
            )
        out = np.zeros((4, 4))
        out[:3, :3] = Li
        out[:3, 3] = -(Li @ t)
        out[3, 3] = 1.0
        return out
    cond = np.linalg.cond(M)
    if not cond <= tol.SINGULAR_CONDITION:
        raise GeometryError(
            f"{name} is singular (condition number {cond:.3g}, above {tol.SINGULAR_CONDITION:.0e}); "
            "a quadric can only be mapped by an invertible 4×4 matrix"
        )
    return np.linalg.inv(M)


def planes_mask(matrices: np.ndarray) -> np.ndarray:
    """Return which quadric matrices ``(..., 4, 4)`` are single planes (``Quadric.is_plane``, vectorised)."""
    M = np.asarray(matrices, dtype=np.float64)
    a = np.abs(M[..., :3, :3]).max(axis=(-2, -1))
    return (a == 0.0) | (a <= tol.PLANE * np.linalg.norm(M[..., :3, 3], axis=-1))


def apply_inverse(Q: np.ndarray, Minv: np.ndarray) -> np.ndarray:
    """Return ``Minv.T @ Q @ Minv`` (eq. 17), blockwise for affine ``Minv`` (exact zeros stay)."""
    if Minv[3, 0] == 0.0 and Minv[3, 1] == 0.0 and Minv[3, 2] == 0.0 and Minv[3, 3] == 1.0:
        Li, s = Minv[:3, :3], Minv[:3, 3]
        A, m, c = Q[:3, :3], Q[:3, 3], Q[3, 3]
        As_m = A @ s + m
        out = np.empty((4, 4))
        out[:3, :3] = Li.T @ A @ Li
        out[:3, 3] = out[3, :3] = Li.T @ As_m
        out[3, 3] = s @ (A @ s) + 2.0 * (m @ s) + c
        return out
    return Minv.T @ Q @ Minv


def _validated(q: np.ndarray, finite_checked: bool = True) -> np.ndarray:
    """The checks of :class:`Quadric` on a (4, 4) float64 array: its symmetrised, read-only copy (see the class)."""
    scale = float(np.max(np.abs(q)))
    if not finite_checked and not math.isfinite(scale):
        raise GeometryError("quadric matrix contains NaN or inf; pass finite numbers")
    if scale == 0.0:
        raise GeometryError("quadric matrix is zero: every point would lie on the surface")
    asym = float(np.max(np.abs(q - q.T)))
    if asym > tol.SYMMETRY * scale:
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
    return q


def moved_placements(quadrics, M: np.ndarray, Minv: np.ndarray) -> list[Quadric]:
    """Return ``[q.transformed(M) for q in quadrics]`` for an affine ``M`` (``Minv`` its checked inverse), all at once.

    Each quadric is moved through its placement (:attr:`Quadric.placement`; a quadric without one is its own
    local matrix at the origin): its local matrix is mapped by ``M``'s linear part ``L`` alone, its origin ``o``
    goes to ``L o + t``, and the world matrix is the new local one moved there -- the shape keeps its digits far
    from the origin. The arithmetic is the same element by element whatever the number of quadrics (einsum's
    loops, no BLAS), so a normal form mapped as a whole (``NormalForm.mapped``) has the matrices of its quadrics
    mapped one by one. A result that is not a quadric (an overflow to inf) raises :class:`GeometryError`.
    """
    n = len(quadrics)
    local = np.empty((n, 4, 4))
    origin = np.zeros((n, 3))
    for i, q in enumerate(quadrics):
        if q._origin is None:
            local[i] = q._matrix
        else:
            local[i] = q._local
            origin[i] = q._origin
    w = M[3, 3]
    L, t, Li = M[:3, :3] / w, M[:3, 3] / w, Minv[:3, :3]
    A, m = local[:, :3, :3], local[:, :3, 3]
    moved = np.empty_like(local)  # the local matrices mapped by L: Lᵢᵀ A Lᵢ, Lᵢᵀ m, c (Lᵢ = L⁻¹)
    moved[:, :3, :3] = np.einsum("nik,kl->nil", np.einsum("ji,njk->nik", Li, A), Li)
    moved[:, :3, 3] = moved[:, 3, :3] = np.einsum("ji,nj->ni", Li, m)
    moved[:, 3, 3] = local[:, 3, 3]
    to = np.einsum("ij,nj->ni", L, origin) + t
    s = -to  # the world matrix: the moved local one translated to ``to`` (eq. 17 with Minv = [I, -to])
    A2, m2 = moved[:, :3, :3], moved[:, :3, 3]
    A2s = np.einsum("nij,nj->ni", A2, s)
    world = np.empty_like(moved)
    world[:, :3, :3] = 0.5 * (A2 + A2.transpose(0, 2, 1))
    world[:, :3, 3] = world[:, 3, :3] = A2s + m2
    world[:, 3, 3] = np.einsum("ni,ni->n", s, A2s) + 2.0 * np.einsum("ni,ni->n", m2, s) + moved[:, 3, 3]
    scale = np.abs(world).max(axis=(1, 2))
    bad = ~(np.isfinite(scale) & (scale > 0.0) & np.any(world[:, :3, :] != 0.0, axis=(1, 2)))
    if bad.any():
        _validated(world[int(np.flatnonzero(bad)[0])], finite_checked=False)  # raises the reason
    world.setflags(write=False)
    moved.setflags(write=False)
    to.setflags(write=False)
    out = []
    for i in range(n):
        q = Quadric.__new__(Quadric)
        q._matrix, q._local, q._origin = world[i], moved[i], to[i]
        out.append(q)
    return out


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
        self._matrix = _validated(as_finite_array(matrix, (4, 4), "quadric matrix"))
        self._local: np.ndarray | None = None
        self._origin: np.ndarray | None = None

    @classmethod
    def _checked(cls, matrix: np.ndarray) -> Quadric:
        """``Quadric(matrix)`` for a (4, 4) float64 array csgnb computed: the same checks and errors, without the
        argument conversion (a normal form validates every mapped quadric: ~20 µs each the long way)."""
        out = cls.__new__(cls)
        out._matrix = _validated(matrix, finite_checked=False)
        out._local = None
        out._origin = None
        return out

    @classmethod
    def _trusted(cls, matrix: np.ndarray, symmetric: bool = False) -> Quadric:
        """Wrap a finite matrix computed by csgnb itself (no re-validation; symmetrised unless it is)."""
        out = cls.__new__(cls)
        m = np.array(matrix) if symmetric else 0.5 * (matrix + matrix.T)
        m.setflags(write=False)
        out._matrix = m
        out._local = None
        out._origin = None
        return out

    @classmethod
    def _placed(cls, local: np.ndarray, origin: np.ndarray) -> Quadric:
        """Return the quadric ``local`` moved by ``origin`` and remember both (see :attr:`placement`)."""
        o = np.array(origin, dtype=np.float64)
        T = np.eye(4)
        T[:3, 3] = -o
        out = cls._trusted(apply_inverse(local, T))
        loc = np.array(local, dtype=np.float64)
        loc.setflags(write=False)
        o.setflags(write=False)
        out._local, out._origin = loc, o
        return out

    @property
    def placement(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(local, origin)`` when this quadric was built in a frame of its own and moved by ``origin``.

        ``local`` : (4, 4) is the matrix before the translation, ``origin`` : (3,) the translation.
        The world :attr:`matrix` of a sphere of radius 1 at 10⁹ has c = 10¹⁸ − 1, where the 1 is
        lost; the placement keeps it, so that maps composed with ``origin`` first (the sampler's
        normalised frame, ``csgnb.csg.to_normal_form(frame=)``) see the exact shape. Centered
        constructors and affine :meth:`transformed` / :meth:`translated` keep one; ``None`` for
        quadrics given by their world matrix.
        """
        if self._origin is None:
            return None
        return self._local, self._origin

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_abc(cls, A, b, c: float) -> Quadric:
        """Return the quadric ``xᵀAx - 2xᵀb + c`` (eq. 3). ``A`` : (3, 3), ``b`` : (3,)."""
        A = as_finite_array(A, (3, 3), "A")
        b = as_finite_array(b, (3,), "b")
        c = as_real(c, "c")
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

    @property
    def is_plane(self) -> bool:
        """Whether this is a single plane: A = 0, or negligible next to b over a unit length.

        ``max|A| ≤ tolerances.PLANE · |b|`` (:func:`planes_mask`). Planes built by csgnb and their
        affine images have A exactly 0. The test assumes lengths of order 1; the sampler asks it
        in its normalised frame, where that is the model's size.
        """
        return bool(planes_mask(self._matrix))

    # -- transforms ----------------------------------------------------------------------
    def transformed(self, M) -> Quadric:
        """Return the image of this quadric under the 4×4 (affine or projective) map ``M``.

        ``Q' = M⁻ᵀ Q M⁻¹`` (eq. 17), so that ``Q'(M x) = Q(x)`` for homogeneous ``x``.
        A 3×4 affine matrix ``[R | t]`` is accepted too. A singular or ill-conditioned ``M``
        (see :func:`transform_inverse`) raises :class:`GeometryError`; affine maps are applied
        blockwise, so a plane stays a plane exactly.
        """
        M = as_matrix(M, "transform")
        return self._transformed(M, transform_inverse(M))

    def _transformed(self, M: np.ndarray, Minv: np.ndarray) -> Quadric:
        """:meth:`transformed` with ``M`` checked and ``Minv = transform_inverse(M)`` given (a map applied to
        many quadrics is inverted once)."""
        if M[3, 0] == 0.0 and M[3, 1] == 0.0 and M[3, 2] == 0.0 and M[3, 3] != 0.0 and (
                np.any(M[:3, 3]) or self._origin is not None):
            # affine with a translation: x ↦ L x + t is the linear map, then the move to t (or to
            # L o + t from a placed quadric's origin o) — the shape keeps its digits far away
            return moved_placements([self], M, Minv)[0]
        return Quadric._checked(apply_inverse(self._matrix, Minv))

    def translated(self, offset) -> Quadric:
        """Return this quadric moved by ``offset`` : (3,)."""
        m = np.eye(4)
        m[:3, 3] = as_finite_array(offset, (3,), "offset")
        return self.transformed(m)

    def complement(self) -> Quadric:
        """Return the complement (Boolean NOT): same surface, inside and outside swapped."""
        out = Quadric._trusted(-self._matrix, symmetric=True)  # (the negation of a valid matrix is one)
        if self._origin is not None:
            out._local = -self._local
            out._local.setflags(write=False)
            out._origin = self._origin
        return out

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


def positive_lengths(values, n: int, name: str) -> np.ndarray:
    arr = as_finite_array(values, None, name)
    if arr.shape not in ((), (1,), (n,)):
        raise CsgnbError(f"{name} must be a number or {n} numbers, got shape {arr.shape}")
    arr = np.broadcast_to(arr, (n,)).copy()
    if np.any(arr <= 0.0):
        raise GeometryError(f"{name} must be positive, got {arr.tolist()}")
    if np.any(arr < tol.LENGTH_MIN) or np.any(arr > tol.LENGTH_MAX):
        raise GeometryError(
            f"{name} must lie in [{tol.LENGTH_MIN:g}, {tol.LENGTH_MAX:g}], got {arr.tolist()}: the quadric's "
            "coefficients are squares or inverse squares of it and the intersection and distance formulas multiply "
            "two of them, which must stay normal doubles (r² would underflow to 0 or overflow to inf); build the "
            "model in other units"
        )
    return arr


def _diag(a: np.ndarray, b=(0.0, 0.0, 0.0), c: float = 0.0, center=None) -> Quadric:
    q = Quadric.from_abc(np.diag(a), b, c)
    if center is not None:
        q = q.translated(center)
    return q


def plane(normal, offset: float = 0.0) -> Quadric:
    """Return the plane ``n·x = offset`` (inside where ``n·x < offset``). ``normal`` : (3,)."""
    n = as_finite_array(normal, (3,), "normal")
    offset = as_real(offset, "offset")
    norm = float(np.linalg.norm(n))
    if norm == 0.0:
        raise GeometryError("plane normal is zero; pass a non-zero direction")
    n = n / norm
    # Q(x) = n·x - d  ⇔  A = 0, -2b = n, c = -d
    return Quadric.from_abc(np.zeros((3, 3)), -0.5 * n, -offset / norm)


def parallel_planes(normal, offset0: float, offset1: float) -> Quadric:
    """Return the slab between the planes ``n·x = offset0`` and ``n·x = offset1`` (inside)."""
    n = as_finite_array(normal, (3,), "normal")
    offset0, offset1 = as_real(offset0, "offset0"), as_real(offset1, "offset1")
    norm = float(np.linalg.norm(n))
    if norm == 0.0:
        raise GeometryError("plane normal is zero; pass a non-zero direction")
    if offset0 == offset1:
        raise GeometryError("parallel planes coincide; pass two different offsets")
    n = n / norm
    d0, d1 = offset0 / norm, offset1 / norm
    # (n·x - d0)(n·x - d1): negative strictly between the planes
    return Quadric.from_abc(np.outer(n, n), 0.5 * (d0 + d1) * n, d0 * d1)


def sphere(center=(0.0, 0.0, 0.0), radius: float = 1.0) -> Quadric:
    """Return the sphere ``|x - center|² = radius²``."""
    r = positive_lengths(radius, 1, "radius")[0]
    return _diag(np.ones(3), c=-r * r, center=as_finite_array(center, (3,), "center"))


def ellipsoid(radii=(1.0, 1.0, 1.0), center=None) -> Quadric:
    """Return the axis-aligned ellipsoid ``Σ (xᵢ / rᵢ)² = 1``. ``radii`` : (3,)."""
    r = positive_lengths(radii, 3, "radii")
    return _diag(1.0 / r**2, c=-1.0, center=center)


def elliptic_cylinder(radii=(1.0, 1.0), center=None) -> Quadric:
    """Return the cylinder ``(x/a)² + (y/b)² = 1`` along z. ``radii`` : (2,)."""
    r = positive_lengths(radii, 2, "radii")
    return _diag(np.array([1.0 / r[0] ** 2, 1.0 / r[1] ** 2, 0.0]), c=-1.0, center=center)


def elliptic_cone(slopes=(1.0, 1.0), center=None) -> Quadric:
    """Return the double cone ``(x/a)² + (y/b)² = z²`` with apex at ``center``."""
    s = positive_lengths(slopes, 2, "slopes")
    return _diag(np.array([1.0 / s[0] ** 2, 1.0 / s[1] ** 2, -1.0]), center=center)


def hyperboloid_one_sheet(radii=(1.0, 1.0, 1.0), center=None) -> Quadric:
    """Return ``(x/a)² + (y/b)² - (z/c)² = 1`` (one sheet around the z axis)."""
    r = positive_lengths(radii, 3, "radii")
    return _diag(np.array([1.0, 1.0, -1.0]) / r**2, c=-1.0, center=center)


def hyperboloid_two_sheets(radii=(1.0, 1.0, 1.0), center=None) -> Quadric:
    """Return ``(z/c)² - (x/a)² - (y/b)² = 1`` (two sheets along z, inside = within a sheet)."""
    r = positive_lengths(radii, 3, "radii")
    return _diag(np.array([1.0, 1.0, -1.0]) / r**2, c=1.0, center=center)


def elliptic_paraboloid(radii=(1.0, 1.0), center=None) -> Quadric:
    """Return ``z = (x/a)² + (y/b)²`` (inside above the vertex at ``center``)."""
    r = positive_lengths(radii, 2, "radii")
    return _diag(np.array([1.0 / r[0] ** 2, 1.0 / r[1] ** 2, 0.0]), b=(0, 0, 0.5), center=center)


def hyperbolic_paraboloid(radii=(1.0, 1.0), center=None) -> Quadric:
    """Return the saddle ``z = (x/a)² - (y/b)²``."""
    r = positive_lengths(radii, 2, "radii")
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
