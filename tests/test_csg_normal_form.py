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
