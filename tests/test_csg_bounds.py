"""Bounding boxes of normal-form terms (support half-spaces + exact 3-variable LP by enumeration)."""

import numpy as np
import pytest

import csgnb.csg as csg
from csgnb.csg.bounds import box_is_empty, polytope_box, support_halfspaces, surface_box, term_boxes
from csgnb.quadric import QUADRIC_CONSTRUCTORS, elliptic_cylinder, plane
from tests.raycast_reference import graph_value


def _random_rigid(rng):
    A = rng.normal(size=(3, 3))
    Qr, _ = np.linalg.qr(A)
    M = np.eye(4)
    M[:3, :3] = Qr * np.sign(np.linalg.det(Qr))
    M[:3, 3] = rng.normal(size=3)
    return M


@pytest.mark.parametrize("seed", range(6))
def test_term_boxes_contain_the_terms(seed):
    rng = np.random.default_rng(seed)
    parts = [
        csg.cylinder((0, 0, 0), (1.0, 0.3, 0.2), 0.4),
        csg.box((-0.5, -0.5, -0.5), (0.8, 0.6, 0.7)),
        csg.ellipsoid((0.9, 0.5, 0.7)),
        csg.cone((0, 0, -0.5), (0, 0, 0.8), 0.6, 0.1),
    ]
    g = csg.union(*(p.transformed(_random_rigid(rng)) for p in parts)) - csg.sphere((0, 0, 0), 0.3)
    nf = g.normal_form()
    boxes, unbounded = term_boxes(nf)
    assert not unbounded.any()
    pts = rng.uniform(-4, 4, (200000, 3))
    inside = pts[graph_value(g, pts) < 0]
    assert len(inside) > 500
    covered = np.zeros(len(inside), dtype=bool)
    for b in boxes:
        if not box_is_empty(b):
            covered |= np.all((inside >= b[:3]) & (inside <= b[3:]), axis=1)
    assert covered.all()
    # and they are reasonably tight: the union of boxes is not much larger than the object's box
    live = boxes[[not box_is_empty(b) for b in boxes]]
    extent = live[:, 3:].max(axis=0) - live[:, :3].min(axis=0)
    assert np.all(extent <= (inside.max(axis=0) - inside.min(axis=0)) * 1.3 + 0.2)


def test_axis_aligned_solids_get_exact_boxes():
    boxes, _ = term_boxes(csg.box((1, 2, 3), (4, 5, 6)).normal_form())
    assert np.allclose(boxes[0], [1, 2, 3, 4, 5, 6], atol=1e-6)
    boxes, _ = term_boxes(csg.sphere((1, 1, 1), 2).normal_form())
    assert np.allclose(boxes[0], [-1, -1, -1, 3, 3, 3], atol=1e-6)


@pytest.mark.parametrize(
    "shape, unbounded",
    [
        (~csg.sphere(), True),
        (csg.leaf(plane((0, 0, 1))), True),
        (csg.leaf(elliptic_cylinder((1, 1))), True),
        (csg.leaf(elliptic_cylinder((1, 1))) & csg.leaf(plane((0, 0, 1), 1)) & csg.leaf(plane((0, 0, -1), 1)), False),
        (csg.sphere() - csg.leaf(plane((1, 0, 0))), False),
    ],
)
def test_unbounded_terms_are_reported(shape, unbounded):
    _, flags = term_boxes(shape.normal_form())
    assert bool(flags.any()) == unbounded
    boxes, flags = term_boxes(shape.normal_form(), limit=np.array([-2, -2, -2, 2, 2, 2.0]))
    assert not flags.any() and np.all(boxes[:, :3] >= -2) and np.all(boxes[:, 3:] <= 2)


def test_empty_terms_get_empty_boxes():
    g = csg.box((0, 0, 0), (1, 1, 1)) & csg.box((2, 0, 0), (3, 1, 1))
    boxes, _ = term_boxes(g.normal_form())
    assert box_is_empty(boxes[0])
    N, h = support_halfspaces(QUADRIC_CONSTRUCTORS["sphere"]())
    assert len(h) > 0


def test_nonconvex_quadrics_claim_nothing_and_surface_boxes_contain_the_surface():
    for name in ("hyperboloid (one sheet)", "elliptic cone"):
        N, h = support_halfspaces(QUADRIC_CONSTRUCTORS[name]())
        assert len(h) == 0
    rng = np.random.default_rng(2)
    box = np.array([-1.5, -1.5, -1.5, 1.5, 1.5, 1.5])
    for name in ("sphere", "elliptic cylinder", "plane", "hyperboloid (two sheets)"):
        q = QUADRIC_CONSTRUCTORS[name]().transformed(_random_rigid(rng))
        sb = surface_box(q, box)
        p = rng.uniform(-1.5, 1.5, (20000, 3))
        v = rng.normal(size=(20000, 3))
        t = q.intersect_lines(p, v)
        hits = (p[:, None, :] + t[..., None] * v[:, None, :]).reshape(-1, 3)
        hits = hits[np.all(np.isfinite(hits), axis=1) & np.all((hits >= box[:3]) & (hits <= box[3:]), axis=1)]
        assert len(hits) > 100
        assert np.all((hits >= sb[:3] - 1e-9) & (hits <= sb[3:] + 1e-9)), name


def test_polytope_box_of_a_simplex():
    N = np.array([[-1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0], np.ones(3) / np.sqrt(3)])
    h = np.array([0.0, 0.0, 0.0, 1 / np.sqrt(3)])
    b = polytope_box(N, h, np.array([-5, -5, -5, 5, 5, 5.0]))
    assert np.allclose(b, [0, 0, 0, 1, 1, 1], atol=1e-6)
