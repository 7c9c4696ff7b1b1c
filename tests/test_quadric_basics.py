"""Quadric construction, validation, transforms and complement."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb.errors import GeometryError
from csgnb.quadric import (
    QUADRIC_CONSTRUCTORS,
    Quadric,
    ellipsoid,
    elliptic_cone,
    hyperboloid_two_sheets,
    parallel_planes,
    plane,
    sphere,
)

RNG = np.random.default_rng(1234)


def _homogeneous_value(Q, pts):
    """Independent reference: xᵀQx with x = (p, 1), plain numpy."""
    h = np.hstack([pts, np.ones((len(pts), 1))])
    return np.einsum("ni,ij,nj->n", h, Q, h)


@pytest.mark.parametrize("name", sorted(QUADRIC_CONSTRUCTORS))
def test_value_matches_homogeneous_form(name):
    q = QUADRIC_CONSTRUCTORS[name]()
    pts = RNG.normal(size=(200, 3)) * 2
    np.testing.assert_allclose(q.value(pts), _homogeneous_value(q.matrix, pts), atol=1e-12)
    # eq. 2/3 decomposition: xᵀAx - 2xᵀb + c
    ref = np.einsum("ni,ij,nj->n", pts, q.A, pts) - 2 * pts @ q.b + q.c
    np.testing.assert_allclose(q.value(pts), ref, atol=1e-12)


def test_constructors_have_the_intended_surfaces():
    s = sphere((1.0, 2.0, 3.0), 2.0)
    assert s.value([[3.0, 2.0, 3.0]])[0] == pytest.approx(0.0)
    assert s.value([[1.0, 2.0, 3.0]])[0] < 0 < s.value([[4.0, 2.0, 3.0]])[0]
    e = ellipsoid((3.0, 2.0, 1.0))
    np.testing.assert_allclose(e.value([[3, 0, 0], [0, 2, 0], [0, 0, 1]]), 0.0, atol=1e-15)
    p = plane((0.0, 0.0, 2.0), 4.0)  # z = 2
    assert p.value([[5.0, -1.0, 2.0]])[0] == pytest.approx(0.0)
    assert p.value([[0.0, 0.0, 0.0]])[0] < 0
    slab = parallel_planes((1.0, 0.0, 0.0), -1.0, 2.0)
    assert slab.value([[0.5, 0, 0]])[0] < 0 < slab.value([[3.0, 0, 0]])[0]
    np.testing.assert_allclose(slab.value([[-1.0, 7, 7], [2.0, -3, 1]]), 0.0, atol=1e-15)
    cone = elliptic_cone((2.0, 1.0))
    assert cone.value([[2.0, 0.0, 1.0]])[0] == pytest.approx(0.0)
    two = hyperboloid_two_sheets((1.0, 1.0, 1.0))
    assert two.value([[0.0, 0.0, 2.0]])[0] < 0 < two.value([[0.0, 0.0, 0.0]])[0]


@pytest.mark.parametrize(
    "matrix, match",
    [
        (np.zeros((4, 4)), "zero"),
        (np.diag([1.0, 1.0, 1.0, -1.0]) + np.triu(np.ones((4, 4)), 1), "not symmetric"),
        (np.diag([np.nan, 1.0, 1.0, -1.0]), "NaN or inf"),
        (np.diag([np.inf, 1.0, 1.0, -1.0]), "NaN or inf"),
        (np.diag([0.0, 0.0, 0.0, 1.0]), "no surface"),
    ],
)
def test_bad_matrices_raise_clear_errors(matrix, match):
    with pytest.raises(GeometryError, match=match):
        Quadric(matrix)


def test_bad_shapes_and_transforms():
    with pytest.raises(ValueError, match="shape"):
        Quadric(np.eye(3))
    with pytest.raises(TypeError):
        Quadric("not a matrix")
    M = np.eye(4)
    M[2, 2] = 0.0
    with pytest.raises(GeometryError, match="singular"):
        sphere().transformed(M)
    with pytest.raises(GeometryError, match="NaN"):
        sphere().transformed(np.full((4, 4), np.nan))
    with pytest.raises(GeometryError, match="positive"):
        sphere(radius=-1.0)
    with pytest.raises(GeometryError, match="zero"):
        plane((0.0, 0.0, 0.0))


def _random_affine(rng):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return M


@pytest.mark.parametrize("name", sorted(QUADRIC_CONSTRUCTORS))
def test_affine_transform_commutes_with_evaluation(name):
    rng = np.random.default_rng(7)
    q = QUADRIC_CONSTRUCTORS[name]()
    M = _random_affine(rng)
    qt = q.transformed(M)
    pts = rng.normal(size=(100, 3))
    mapped = pts @ M[:3, :3].T + M[:3, 3]
    np.testing.assert_allclose(qt.value(mapped), q.value(pts), rtol=1e-9, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(sorted(QUADRIC_CONSTRUCTORS)))
def test_projective_transform_commutes_up_to_w_squared(seed, name):
    rng = np.random.default_rng(seed)
    q = QUADRIC_CONSTRUCTORS[name]()
    M = _random_affine(rng)
    M[3, :3] = 0.2 * rng.normal(size=3)  # a projective row
    cond = np.linalg.cond(M)
    if cond > 1e6:
        return
    qt = q.transformed(M)
    pts = rng.normal(size=(50, 3))
    h = np.hstack([pts, np.ones((50, 1))]) @ M.T
    keep = np.abs(h[:, 3]) > 0.1
    w = h[keep, 3]
    image = h[keep, :3] / w[:, None]
    # Q'(dehomogenised Mx) · w² = Q(x), up to rounding amplified by the conditioning of M
    tol = max(1e-8, 1e-15 * cond**2)
    np.testing.assert_allclose(qt.value(image) * w**2, q.value(pts[keep]), rtol=tol, atol=tol)


def test_transform_accepts_3x4_and_translation_composes():
    q = sphere(radius=2.0)
    a = q.transformed(np.hstack([np.eye(3), [[1.0], [2.0], [3.0]]]))
    b = q.translated((1.0, 2.0, 3.0))
    np.testing.assert_allclose(a.matrix, b.matrix)
    np.testing.assert_allclose(a.matrix, sphere((1.0, 2.0, 3.0), 2.0).matrix, atol=1e-14)


def test_complement_swaps_inside_and_outside():
    q = ellipsoid((1.0, 2.0, 3.0))
    pts = RNG.normal(size=(100, 3)) * 2
    np.testing.assert_array_equal((-q).value(pts), -q.value(pts))
    np.testing.assert_array_equal(q.complement().matrix, -q.matrix)
    d, dn = q.signed_distance(pts), (-q).signed_distance(pts)
    np.testing.assert_allclose(np.abs(d), np.abs(dn), rtol=1e-12)
    assert np.all(np.sign(d) == -np.sign(dn))


def test_matrix_is_read_only_and_symmetrised():
    m = np.diag([1.0, 2.0, 3.0, -1.0])
    m[0, 1] = 1e-17  # rounding-level asymmetry is averaged away
    q = Quadric(m)
    assert np.array_equal(q.matrix, q.matrix.T)
    with pytest.raises(ValueError):
        q.matrix[0, 0] = 5.0


def test_is_plane_is_one_rule_at_unit_scale():
    from csgnb.quadric.quadric import planes_mask

    assert plane((1.0, 2.0, 3.0), 4.0).is_plane
    M = _random_affine(np.random.default_rng(3))
    assert plane((0.0, 0.0, 1.0), 1.0).transformed(M).is_plane  # affine maps keep A exactly 0
    assert not np.any(plane((0.0, 0.0, 1.0)).transformed(M).A)
    assert not sphere((0, 0, 0), 1e7).is_plane  # A = 1e-14 but b = 0: a (huge) sphere
    assert not sphere().is_plane and not parallel_planes((1, 0, 0), -1, 1).is_plane
    nearly = Quadric.from_abc(1e-15 * np.eye(3), (0.0, 0.0, 0.5), 0.0)  # a sphere of radius ~1e15
    assert nearly.is_plane
    mats = np.array([q.matrix for q in (plane((0, 0, 1)), sphere(), nearly)])
    assert planes_mask(mats).tolist() == [True, False, True]


def test_float_tolerances_live_in_one_module():
    """No scientific-notation float literal in the quadric track outside ``tolerances.py``."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "csgnb"
    literal = re.compile(r"(?<![\w.])\d+(\.\d*)?e-\d+")
    found = []
    for package in ("quadric", "csg", "sampling"):
        for path in sorted((root / package).glob("*.py")):
            if path.name == "tolerances.py":
                continue
            for n, line in enumerate(path.read_text().splitlines(), 1):
                code = line.split("#")[0]
                if literal.search(code) and '"""' not in code and not code.strip().startswith(("*", "-")):
                    found.append(f"{path.name}:{n}: {line.strip()}")
    assert not found, "float tolerances belong in csgnb/quadric/tolerances.py:\n" + "\n".join(found)
