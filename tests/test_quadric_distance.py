"""The conservative signed distance d(x₀) (eq. 10–12) against dense sampling + root finding."""

import numpy as np
import pytest
from scipy.optimize import minimize

from csgnb.quadric import QUADRIC_CONSTRUCTORS, signed_distance, sphere

NAMES = sorted(QUADRIC_CONSTRUCTORS)


def _random_quadric(rng, name):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return QUADRIC_CONSTRUCTORS[name]().transformed(M)


def _fibonacci_sphere(n):
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    theta = np.pi * (1 + 5**0.5) * k
    return np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])


def _first_hit(Q, x0, dirs):
    """Smallest t > 0 with Q(x₀ + t v) = 0 per direction (numpy, independent of csgnb)."""
    A, m, c = Q[:3, :3], Q[:3, 3], Q[3, 3]
    a = np.einsum("ni,ij,nj->n", dirs, A, dirs)
    b = dirs @ (A @ x0 + m)
    g = x0 @ A @ x0 + 2 * m @ x0 + c
    t = np.full(len(dirs), np.inf)
    lin = np.abs(a) < 1e-14
    with np.errstate(all="ignore"):
        tl = -g / (2 * b)
        disc = b * b - a * g
        s = np.sqrt(np.where(disc >= 0, disc, np.nan))
        r1, r2 = (-b - s) / a, (-b + s) / a
    for r in (r1, r2):
        ok = ~lin & (r > 0) & np.isfinite(r)
        t[ok] = np.minimum(t[ok], r[ok])
    ok = lin & (tl > 0)
    t[ok] = np.minimum(t[ok], tl[ok])
    return t


def _true_distance(Q, x0, dirs):
    """Distance to the surface: dense ray casting, then local minimisation over directions."""
    t = _first_hit(Q, x0, dirs)
    best = np.min(t)
    for k in np.argsort(t)[:3]:
        if not np.isfinite(t[k]):
            continue
        v = dirs[k]
        start = [np.arccos(np.clip(v[2], -1, 1)), np.arctan2(v[1], v[0])]

        def f(ang):
            d = np.array([np.sin(ang[0]) * np.cos(ang[1]), np.sin(ang[0]) * np.sin(ang[1]),
                          np.cos(ang[0])])
            val = _first_hit(Q, x0, d[None])[0]
            return val if np.isfinite(val) else 1e300

        res = minimize(f, start, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-13})
        best = min(best, res.fun)
    return best


@pytest.mark.parametrize("name", NAMES)
def test_distance_is_a_lower_bound_with_the_right_sign(name):
    rng = np.random.default_rng(21)
    dirs = _fibonacci_sphere(4000)
    q = _random_quadric(rng, name)
    pts = rng.normal(size=(12, 3)) * 1.5
    d = signed_distance(q, pts)
    val = q.value(pts)
    assert np.all(np.sign(d) == np.sign(val))
    useful = 0
    for x0, dk in zip(pts, d, strict=True):
        true = _true_distance(q.matrix, x0, dirs)
        assert abs(dk) <= true * (1 + 1e-9) + 1e-12, (x0, dk, true)
        useful += np.isfinite(true) and abs(dk) > 0.05 * true
    assert useful >= 6  # not vacuous: the bound is usually within a factor 20


@pytest.mark.parametrize("name", [n for n in NAMES if n != "plane"])
def test_relative_error_vanishes_near_the_surface(name):
    rng = np.random.default_rng(5)
    q = _random_quadric(rng, name)
    p = rng.normal(size=(200, 3))
    v = rng.normal(size=(200, 3))
    t = q.intersect_lines(p, v)[:, 0]
    surf = (p + t[:, None] * v)[np.isfinite(t)][:20]
    n = q.normal(surf)
    for eps in (1e-3, 1e-5, 1e-7):
        for sign in (1.0, -1.0):
            d = signed_distance(q, surf + sign * eps * n)
            # the true distance is at most eps (the foot point), |d| ≤ it, and → it
            assert np.all(np.sign(d) == sign)
            ratio = np.abs(d) / eps
            # (the foot point itself is a float root: allow its ~1e-12 rounding)
            assert np.all(ratio <= 1 + 1e-11 / eps)
            assert np.all(ratio >= 1 - 200 * eps), ratio.min()


def test_planes_and_spheres_are_exact():
    s = sphere((1.0, 0.0, 0.0), 2.0)
    np.testing.assert_allclose(s.signed_distance([[4.0, 0, 0], [1.5, 0, 0]]), [1.0, -1.5])
    from csgnb.quadric import plane

    np.testing.assert_allclose(plane((0, 0, 1.0), 1.0).signed_distance([[3, 4, 5.0]]), [4.0])


def test_no_surface_gives_infinite_distance():
    from csgnb.quadric import Quadric

    empty = Quadric(np.diag([1.0, 1.0, 1.0, 1.0]))  # x² + y² + z² + 1 > 0 everywhere
    assert signed_distance(empty, [[0.3, 0.1, 0.0]])[0] == np.inf
