"""Gradient, normal and line intersection against independent references (mpmath)."""

import mpmath
import numpy as np
import pytest

from csgnb.quadric import (
    QUADRIC_CONSTRUCTORS,
    elliptic_cylinder,
    elliptic_paraboloid,
    gradient,
    intersect_lines,
    normal,
    parallel_planes,
    sphere,
)

NAMES = sorted(QUADRIC_CONSTRUCTORS)


def _random_quadric(rng, name):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return QUADRIC_CONSTRUCTORS[name]().transformed(M)


@pytest.mark.parametrize("name", NAMES)
def test_gradient_matches_central_differences(name):
    rng = np.random.default_rng(3)
    q = _random_quadric(rng, name)
    pts = rng.normal(size=(50, 3))
    g = gradient(q, pts)
    h = 1e-5
    fd = np.column_stack(
        [(q.value(pts + h * e) - q.value(pts - h * e)) / (2 * h) for e in np.eye(3)]
    )
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6)
    n = normal(q, pts)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(np.sum(n * g, axis=1), np.linalg.norm(g, axis=1), rtol=1e-12)


def test_normal_is_nan_at_singular_points():
    assert np.all(np.isnan(normal(sphere(), [[0.0, 0.0, 0.0]])))


def _mp_roots(Q, p, v):
    """Roots of Q(p + t v) = 0 in 60-digit arithmetic from the exact float inputs."""
    mpmath.mp.dps = 60
    Qm = mpmath.matrix([[mpmath.mpf(float(x)) for x in row] for row in Q])
    P = mpmath.matrix([mpmath.mpf(float(x)) for x in p] + [1])
    V = mpmath.matrix([mpmath.mpf(float(x)) for x in v] + [0])
    a = (V.T * Qm * V)[0]
    b = (V.T * Qm * P)[0]
    c = (P.T * Qm * P)[0]
    if a == 0:
        return [-c / (2 * b)] if b != 0 else []
    disc = b * b - a * c
    if disc < 0:
        return []
    s = mpmath.sqrt(disc)
    return sorted([(-b - s) / a, (-b + s) / a]), disc, a, b


@pytest.mark.parametrize("name", NAMES)
def test_line_intersection_matches_mpmath(name):
    rng = np.random.default_rng(11)
    q = _random_quadric(rng, name)
    p = rng.normal(size=(40, 3)) * 2
    v = rng.normal(size=(40, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    t = intersect_lines(q, p, v)
    checked = 0
    for k in range(len(p)):
        ref = _mp_roots(q.matrix, p[k], v[k])
        if isinstance(ref, list):
            assert np.all(np.isnan(t[k])) or name == "plane"
            continue
        roots, disc, a, b = ref
        scale = float(abs(b) + mpmath.sqrt(abs(disc)))
        if float(mpmath.sqrt(disc)) < 1e-6 * scale or abs(float(a)) < 1e-6:
            continue  # near-tangent or near-linear: the float roots are ill-conditioned
        for got, want in zip(t[k], roots, strict=True):
            assert abs(got - float(want)) <= 1e-10 * (1 + abs(float(want))), (t[k], roots)
        checked += 1
    if name != "plane":
        assert checked >= 5


def test_line_intersection_missing_roots_are_nan():
    t = intersect_lines(sphere(), [[0.0, 0.0, 5.0]], [[1.0, 0.0, 0.0]])
    assert np.all(np.isnan(t))


def test_degenerate_linear_case_eq6():
    # parallel to a paraboloid's axis: the quadratic term vanishes, one root (eq. 6)
    q = elliptic_paraboloid((1.0, 2.0))
    t = intersect_lines(q, [[1.0, 2.0, -3.0]], [[0.0, 0.0, 2.0]])[0]
    # surface z = 1 + 1 = 2 reached at -3 + 2 t = 2
    assert t[0] == pytest.approx(2.5) and np.isnan(t[1])
    # rotated copy: a = vᵀAv is rounding noise, still one root, found accurately
    R = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))[0]
    M = np.eye(4)
    M[:3, :3] = R
    qr = q.transformed(M)
    tr = intersect_lines(qr, [R @ [1.0, 2.0, -3.0]], [R @ [0.0, 0.0, 2.0]])[0]
    assert tr[0] == pytest.approx(2.5, rel=1e-12) and np.isnan(tr[1])
    # along a cylinder's axis: no root inside/outside, whole line on the surface
    cyl = elliptic_cylinder((1.0, 1.0))
    assert np.all(np.isnan(intersect_lines(cyl, [[0.2, 0, 0]], [[0, 0, 1.0]])))
    assert np.array_equal(intersect_lines(cyl, [[1.0, 0, 0]], [[0, 0, 1.0]])[0], [-np.inf, np.inf])
    # a plane of a slab, approached head-on: a ≠ 0 here, two roots
    slab = parallel_planes((0, 0, 1.0), -1.0, 1.0)
    np.testing.assert_allclose(intersect_lines(slab, [[0, 0, 0.0]], [[0, 0, 1.0]])[0], [-1, 1])


def test_line_intersection_rejects_bad_input():
    with pytest.raises(ValueError, match="zero vector"):
        intersect_lines(sphere(), [[0.0, 0, 0]], [[0.0, 0, 0]])
    with pytest.raises(ValueError, match="shape"):
        intersect_lines(sphere(), [[0.0, 0, 0]], [[1.0, 0]])
    with pytest.raises(TypeError):
        intersect_lines(np.eye(4), [[0.0, 0, 0]], [[1.0, 0, 0]])
