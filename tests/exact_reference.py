"""Independent references for the exact predicates: Python ints and fractions.Fraction only.

Nothing here calls csgnb: each formula is written from its definition (Cramer's
rule, the plane equation) rather than from the kernels' cofactor expansions.
"""

from fractions import Fraction


def sign(v) -> int:
    return (v > 0) - (v < 0)


def det3(m) -> int:
    return (
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    )


def solve_3_planes(p, q, r):
    """The intersection point of three planes as Fractions (Cramer on n·x = -d), or None."""
    A = [p[:3], q[:3], r[:3]]
    rhs = [-p[3], -q[3], -r[3]]
    det = det3(A)
    if det == 0:
        return None
    out = []
    for i in range(3):
        Ai = [list(row) for row in A]
        for k in range(3):
            Ai[k][i] = rhs[k]
        out.append(Fraction(det3(Ai), det))
    return out


def side(point, plane) -> int:
    """Sign of n·X + d for a Cartesian point given as Fractions."""
    return sign(sum(Fraction(c) * n for c, n in zip(point, plane[:3], strict=True)) + plane[3])


def cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
