"""Disjunctive normal form (eq. 17–18): classification preserved, transforms in the leaves, simplifications."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import csgnb.csg as csg
from csgnb.errors import CsgnbError
from csgnb.quadric import QUADRIC_CONSTRUCTORS, Quadric
from tests.raycast_reference import graph_value

NAMES = sorted(QUADRIC_CONSTRUCTORS)


def _random_leaf(rng, name=None):
    name = name or NAMES[rng.integers(len(NAMES))]
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) * 0.5 + np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return csg.leaf(QUADRIC_CONSTRUCTORS[name]().transformed(M), name)


def _random_graph(rng, depth, leaves):
    """A random DAG: operations, complements, transforms, and reuse of earlier sub-graphs."""
    if depth == 0 or rng.random() < 0.2:
        if leaves and rng.random() < 0.3:
            return leaves[rng.integers(len(leaves))]  # a shared sub-graph
        leaf = _random_leaf(rng)
        leaves.append(leaf)
        return leaf
    kind = rng.integers(6)
    kids = [_random_graph(rng, depth - 1, leaves) for _ in range(rng.integers(1, 4))]
    if kind == 0:
        node = csg.union(*kids)
    elif kind == 1:
        node = csg.intersection(*kids)
    elif kind == 2:
        node = csg.difference(kids[0], *(kids[1:] or [_random_leaf(rng)]))
    elif kind == 3:
        node = ~kids[0]
    else:
        M = np.eye(4)
        M[:3, :3] = rng.normal(size=(3, 3)) * 0.3 + np.eye(3)
        M[:3, 3] = rng.normal(size=3) * 0.5
        if kind == 5:
            M[3, :3] = rng.normal(size=3) * 0.02  # a mildly projective edge
        node = csg.union(*kids).transformed(M)
    leaves.append(node)
    return node


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1))
def test_normal_form_preserves_classification_of_random_points(seed):
    rng = np.random.default_rng(seed)
    g = _random_graph(rng, 4, [])
    try:
        nf = csg.to_normal_form(g, max_terms=2000)
    except CsgnbError:
        return  # an exponential case beyond the limit: tested separately
    pts = rng.normal(size=(500, 3)) * 2.0
    expected = np.sign(graph_value(g, pts))
    got = nf.classify(pts)
    ok = expected != 0
    assert np.array_equal(got[ok], expected[ok])


def test_transforms_are_pushed_into_the_leaves():
    rng = np.random.default_rng(0)
    q = QUADRIC_CONSTRUCTORS["ellipsoid"]()
    M1, M2 = np.eye(4), np.eye(4)
    M1[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M2[:3, 3] = (1.0, -2.0, 0.5)
    g = csg.leaf(q).transformed(M1).transformed(M2)
    nf = g.normal_form()
    (only,) = nf.quadrics
    expected = np.linalg.inv(M2 @ M1).T @ q.matrix @ np.linalg.inv(M2 @ M1)  # eq. 17 with M = M₂M₁
    assert np.allclose(only.matrix, 0.5 * (expected + expected.T))


def test_simplifications():
    a = csg.sphere((0, 0, 0), 1, "a")
    b = csg.sphere((1, 0, 0), 1, "b")
    c = csg.sphere((0, 1, 0), 1, "c")
    assert len((a & a).normal_form()) == 1  # a ∩ a = a
    assert (a & ~a).normal_form().n_terms == 0  # empty
    assert (a | (a & b)).normal_form().n_terms == 1  # absorption
    nf = (a & (b | c)).normal_form()
    assert nf.n_terms == 2 and len(nf) == 4
    # a reaches both terms: one surface, same orientation
    ka = [k for k in range(4) if nf.names[k] == "a"]
    assert len(set(nf.surface[ka])) == 1 and set(nf.orientation[ka]) == {1}
    # a complement is the same surface with the other orientation
    nf2 = (a | ~a.translated((0, 0, 0))).normal_form()
    assert len(set(nf2.surface)) == 1 and sorted(nf2.orientation) == [-1, 1]
    assert "terms" in repr(nf)


def test_scaled_matrices_are_one_surface():
    a = csg.leaf(Quadric(2.0 * QUADRIC_CONSTRUCTORS["sphere"]().matrix))
    b = csg.sphere((0, 0, 0), 1.0)
    nf = (a & b).normal_form()
    assert len(nf) == 1


def test_exponential_growth_is_limited():
    parts = [csg.sphere((k, 0, 0), 1) | csg.sphere((k, 1, 0), 1) for k in range(14)]
    with pytest.raises(CsgnbError, match="max_terms"):
        csg.intersection(*parts).normal_form(max_terms=1000)


def _placed_quadrics(rng, n):
    from csgnb.quadric import ellipsoid, elliptic_cone, elliptic_cylinder, sphere

    makers = [lambda c: sphere(c, rng.uniform(0.2, 2.0)), lambda c: ellipsoid(rng.uniform(0.2, 2.0, 3), c),
              lambda c: elliptic_cylinder(rng.uniform(0.2, 2.0, 2), c), lambda c: elliptic_cone((1.0, 0.5), c)]
    return [makers[i % 4](rng.normal(size=3) * 10.0 ** rng.integers(0, 7)) for i in range(n)]


def _random_affine(rng):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2.0 * np.eye(3)
    M[:3, 3] = rng.normal(size=3) * 10.0 ** rng.integers(0, 6)
    return M


@pytest.mark.parametrize("seed", range(4))
def test_quadrics_moved_together_are_the_quadrics_moved_one_by_one(seed):
    """``moved_placements`` maps a batch of placed quadrics at once (the normal form's leaves, its world mapping);
    each result must be the same bits as the quadric mapped alone (``Quadric.transformed``), and the map of eq. 17:
    ``Q'(M x) = Q(x)``."""
    from csgnb.quadric.quadric import moved_placements, transform_inverse

    rng = np.random.default_rng(seed)
    qs = _placed_quadrics(rng, 9)
    M = _random_affine(rng)
    together = moved_placements(qs, M, transform_inverse(M))
    for q, t in zip(qs, together, strict=True):
        alone = q.transformed(M)
        assert np.array_equal(t.matrix, alone.matrix)
        assert np.array_equal(t.placement[0], alone.placement[0]) and np.array_equal(t.placement[1],
                                                                                     alone.placement[1])
        local, origin = q.placement
        x = rng.normal(size=(20, 3))  # points near the quadric's own origin
        want = Quadric(local).value(x)
        got = Quadric(t.placement[0]).value(x @ M[:3, :3].T)  # (translations cancel in the placement)
        assert np.allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
        assert np.allclose(t.placement[1], M[:3, :3] @ origin + M[:3, 3], rtol=1e-12, atol=0.0)


def test_a_normal_form_maps_its_placed_quadrics_as_each_alone():
    rng = np.random.default_rng(7)
    qs = _placed_quadrics(rng, 8)
    pairs = zip(qs[::2], qs[1::2], strict=True)
    g = csg.union(*[csg.intersection(csg.leaf(a), csg.complement(csg.leaf(b))) for a, b in pairs])
    nf = g.normal_form()
    M = _random_affine(rng)
    for q, m in zip(nf.quadrics, nf.mapped(M).quadrics, strict=True):
        assert np.array_equal(m.matrix, q.transformed(M).matrix)
    # leaves under one path map are mapped in one batch when the normal form is built: the same bits as alone
    F = _random_affine(rng)
    framed = csg.to_normal_form(g.transformed(M), frame=F)
    for q, got in zip(qs, [q for q in framed.quadrics if q.placement is not None][: len(qs)], strict=False):
        assert np.array_equal(abs(got.matrix), abs(q.transformed(F @ M).matrix))


def test_a_map_that_overflows_a_quadric_is_refused():
    from csgnb.errors import GeometryError
    from csgnb.quadric import sphere

    M = np.eye(4)
    M[:3, 3] = (1e200, 0.0, 0.0)  # |o|² = 10⁴⁰⁰: the world matrix's constant is inf
    with pytest.raises(GeometryError, match="NaN or inf"):
        sphere().transformed(M)
    with pytest.raises(GeometryError, match="NaN or inf"):
        csg.union(csg.leaf(sphere()), csg.leaf(sphere((3.0, 0.0, 0.0)))).normal_form().mapped(M)
