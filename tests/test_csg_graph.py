"""CSG graph API: operators, variadic flattening, transforms on edges, shared sub-graphs, solids, errors."""

import numpy as np
import pytest

import csgnb.csg as csg
from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import sphere as qsphere
from tests.raycast_reference import graph_value


def test_operators_build_the_expected_nodes():
    a, b, c = csg.sphere((0, 0, 0), 1), csg.sphere((1, 0, 0), 1), csg.sphere((0, 1, 0), 1)
    u = a | b | c
    assert isinstance(u, csg.Union) and len(u.operands) == 3  # flattened, variadic
    i = a & b & c
    assert isinstance(i, csg.Intersection) and len(i.operands) == 3
    d = a - b
    assert isinstance(d, csg.Difference) and d.base is a and d.subtrahends == (b,)
    assert isinstance(~a, csg.Complement)
    assert isinstance(qsphere() | a, csg.Union)  # quadrics become leaves
    assert csg.difference(a, b, c).subtrahends == (b, c)
    assert "Union" in repr(u)


def test_shared_subgraphs_count_once():
    a = csg.sphere((0, 0, 0), 1, "a")
    b = csg.sphere((1, 0, 0), 1, "b")
    shared = a & b
    g = (shared | shared.translated((3, 0, 0))) - shared.scaled(0.5)
    assert len(csg.graph_leaves(g)) == 2
    assert csg.graph_size(g) == 7  # leaves a, b; ∩; 2 transforms; ∪; difference
    # the normal form instantiates it once per path: three copies of (a ∩ b)
    assert len(g.normal_form()) > 4


def test_transforms_on_edges_move_the_solid():
    b = csg.box((0, 0, 0), (1, 1, 1))
    M = csg.rotation_matrix((0, 0, 1), np.pi / 2, (0.5, 0.5, 0))
    moved = b.translated((2, 0, 0)).transformed(M)
    pts = np.array([[0.5, 0.5, 0.5], [2.5, 0.5, 0.5]])
    # rotating by 90° about (0.5, 0.5): (2.5, 0.5) → (0.5, 2.5)
    probe = np.array([[0.5, 2.5, 0.5], [2.5, 0.5, 0.5]])
    assert np.all(graph_value(b, pts[:1]) < 0)
    assert list(graph_value(moved, probe) < 0) == [True, False]
    sc = b.scaled((2, 1, 1))
    assert graph_value(sc, np.array([[1.5, 0.5, 0.5]]))[0] < 0


@pytest.mark.parametrize(
    "make, exc, match",
    [
        (lambda: csg.union(), CsgnbError, "at least one"),
        (lambda: csg.difference(csg.sphere()), CsgnbError, "subtrahend"),
        (lambda: csg.union(csg.sphere(), 3), TypeError, "Node or a Quadric"),
        (lambda: csg.sphere().transformed(np.full((4, 4), np.nan)), GeometryError, "NaN"),
        (lambda: csg.sphere().transformed(np.diag([1, 1, 0, 1.0])), GeometryError, "singular"),
        (lambda: csg.sphere().transformed(np.eye(3)), ValueError, "shape"),
        (lambda: csg.sphere().translated((np.inf, 0, 0)), GeometryError, "NaN or inf"),
        (lambda: csg.rotation_matrix((0, 0, 0), 1.0), GeometryError, "axis is zero"),
        (lambda: csg.box((0, 0, 0), (1, 0, 1)), GeometryError, "lo < hi"),
        (lambda: csg.cylinder((0, 0, 0), (0, 0, 0), 1), GeometryError, "coincide"),
        (lambda: csg.cylinder((0, 0, 0), (0, 0, 1), -1), GeometryError, "positive"),
        (lambda: csg.cone((0, 0, 0), (0, 0, 1), 0, 0), GeometryError, "not both 0"),
        (lambda: csg.rounded_box((0, 0, 0), (1, 1, 1), 0.6), GeometryError, "half of every side"),
        (lambda: csg.leaf("sphere"), TypeError, "Quadric"),
    ],
)
def test_bad_input_raises_clear_errors(make, exc, match):
    with pytest.raises(exc, match=match):
        make()


def test_a_3x4_affine_edge_is_completed():
    t = csg.sphere().transformed(np.hstack([np.eye(3), [[1.0], [2.0], [3.0]]]))
    assert t.matrix.shape == (4, 4) and t.matrix[3, 3] == 1.0


@pytest.mark.parametrize(
    "solid, quadrics, inside, outside",
    [
        (csg.box((0, 0, 0), (1, 2, 3)), 6, [0.5, 1.9, 2.9], [0.5, 2.1, 1.0]),
        (csg.cylinder((0, 0, 0), (1, 1, 1), 0.3), 3, [0.9, 0.9, 0.9], [1.1, 1.1, 1.1]),
        (csg.cone((0, 0, 0), (0, 0, 2), 1.0, 0.2), 3, [0.0, 0.55, 1.0], [0.0, 0.7, 1.0]),
        (csg.cone((0, 0, 0), (0, 0, 1), 0.0, 0.5), 3, [0.0, 0.0, 0.5], [0.0, 0.0, -0.5]),
        (csg.capsule((0, 0, 0), (2, 0, 0), 0.5), 5, [-0.45, 0, 0], [1.0, 0.55, 0]),
        (csg.rounded_box((0, 0, 0), (2, 2, 2), 0.3), 62, [1.0, 1.0, 1.95], [0.02, 0.02, 0.02]),
        (csg.ellipsoid((1, 2, 3)), 1, [0, 1.9, 0], [0, 0, 3.1]),
    ],
)
def test_solids_have_their_quadric_counts_and_shapes(solid, quadrics, inside, outside):
    assert len(csg.graph_leaves(solid)) == quadrics
    v = graph_value(solid, np.array([inside, outside], dtype=float))
    assert v[0] < 0 < v[1]
