"""CSG distances: eq. 19 is a conservative signed distance; eq. 22 classifies a neighbourhood on its quadric."""

import numpy as np
import pytest

import csgnb.csg as csg
from csgnb.csg.bounds import term_boxes
from csgnb.quadric import plane
from csgnb.sampling.kernel import relative_distance_pruned
from csgnb.sampling.tasks import build_tasks
from tests.raycast_reference import graph_first_order_distance, graph_value, ray_surface_points


def _model():
    A, B = csg.sphere((0, 0, 0), 1.0, "A"), csg.sphere((0.9, 0.1, 0), 0.8, "B")
    C = csg.cylinder((0.2, 0.6, -1), (0.2, 0.6, 1), 0.35, "C")
    return ((A & B) | C) - csg.leaf(plane((0, 0, -1), -0.5), "lid")


def _unique_surfaces(nf):
    """Quadrics whose surface reaches the normal form once (a shared one is emitted by one term only)."""
    ids, counts = np.unique(nf.surface, return_counts=True)
    return [k for k in range(len(nf)) if counts[np.searchsorted(ids, nf.surface[k])] == 1]


def _fibonacci(n):
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    th = np.pi * (1 + 5**0.5) * k
    return np.column_stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)])


def test_csg_distance_is_conservative_and_signed():
    S = _model()
    nf = S.normal_form()
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1.5, 1.5, (60, 3))
    d = nf.signed_distance(pts)
    assert np.array_equal(np.sign(d), np.sign(graph_value(S, pts)))
    dirs = _fibonacci(3000)
    for p, dp in zip(pts, d, strict=True):
        hits, _ = ray_surface_points(S, np.repeat(p[None], len(dirs), 0), dirs, 10.0)
        if len(hits):
            assert abs(dp) <= np.min(np.linalg.norm(hits - p, axis=1)) + 1e-12


def _points_on(Q, rng, n, center, spread):
    """Random points of the quadric surface Q (world 4×4) near ``center``."""
    o = center + rng.normal(size=(n, 3)) * spread
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    p = _points_on_lines(Q, o, v)
    return p[np.all(np.isfinite(p), axis=1) & (np.linalg.norm(p - center, axis=1) < 3 * spread)]


def _project(Q, q0):
    """Move points onto the surface along their gradient line (exact root)."""
    h = np.column_stack([q0, np.ones(len(q0))])
    gdir = h @ Q[:, :3]
    gdir /= np.linalg.norm(gdir, axis=1, keepdims=True)
    return _points_on_lines(Q, q0, gdir)


def _points_on_lines(Q, o, v):
    A, m, c = Q[:3, :3], Q[:3, 3], Q[3, 3]
    a = np.einsum("ni,ij,nj->n", v, A, v)
    b = np.einsum("ni,ni->n", v, o @ A + m)
    g = np.einsum("ni,ij,nj->n", o, A, o) + 2 * o @ m + c
    with np.errstate(all="ignore"):
        s = np.sqrt(b * b - a * g)  # NaN: the line misses the surface
        t1, t2 = (-b - s) / a, (-b + s) / a
        tl = -g / (2 * b)
    t = np.where(np.abs(a) > 1e-12, np.where(np.abs(t1) < np.abs(t2), t1, t2), tl)
    return o + t[:, None] * v


def _check_neighbourhoods(S, distance_fn, index, Q, rng):
    on = _points_on(Q, rng, 400, np.zeros(3), 0.8)
    d = distance_fn(index, on)
    f_on = graph_first_order_distance(S, on)
    checked = 0
    for p, dp, fp in zip(on, d, f_on, strict=True):
        if not np.isfinite(dp) or abs(dp) < 1e-3:
            continue
        keep = dp < 0
        assert (abs(fp) < 1e-9) == keep, (p, dp, fp)
        q = _project(Q, p + rng.normal(size=(20, 3)) * abs(dp) * 0.5)
        q = q[np.linalg.norm(q - p, axis=1) < 0.999 * abs(dp)]  # NaN rows drop out here
        fq = graph_first_order_distance(S, q)
        assert np.all((np.abs(fq) < 1e-9) == keep)
        checked += len(q)
    assert checked > 100


@pytest.mark.parametrize("k", range(5))
def test_relative_distance_classifies_its_neighbourhood(k):
    """Eq. 22: sign = on the CSG surface or not, and the same for all points of Q_ab within |d|."""
    S = _model()
    nf = S.normal_form()
    index = _unique_surfaces(nf)[k]
    rng = np.random.default_rng(index)
    _check_neighbourhoods(S, nf.relative_distance, index, nf.quadrics[index].matrix, rng)


@pytest.mark.parametrize("k", range(5))
def test_pruned_relative_distance_of_the_sampler_classifies_too(k):
    S = _model()
    nf = S.normal_form()
    index = _unique_surfaces(nf)[k]
    boxes, _ = term_boxes(nf)
    ts = build_tasks(nf, boxes, 0.05)
    hit = np.flatnonzero(ts.quadric == index)
    if not len(hit):
        assert nf.names[index] == "C cap 1"  # cut away by the lid: no task
        return
    i = int(hit[0])
    own, slices, other = ts.lists(i)
    C = np.ascontiguousarray(nf.coefficients)
    scratch = np.empty(len(own) + 1, dtype=np.int64)

    def dist(_, pts):
        return np.array([relative_distance_pruned(C, own, 0, len(own), ts.own_box[i], slices, other, ts.rcap[i], *p,
                                                  0.0, scratch, 0)[0] for p in pts])

    _check_neighbourhoods(S, dist, index, nf.quadrics[index].matrix, np.random.default_rng(10 + index))


def test_shared_surface_is_claimed_by_one_term():
    """A ∩ (B ∪ C): A's surface is in both terms; each point of it is kept by exactly one."""
    A = csg.sphere((0, 0, 0), 1.0, "A")
    B = csg.box((-2, -2, -2), (0.3, 2, 2), "B")
    C = csg.box((-0.2, -2, -2), (2, 0.4, 2), "C")
    nf = (A & (B | C)).normal_form()
    ia = [k for k in range(len(nf)) if nf.names[k] == "A"]
    rng = np.random.default_rng(0)
    p = rng.normal(size=(2000, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    kept = np.array([nf.relative_distance(k, p) < 0 for k in ia])
    inside = (p[:, 0] < 0.3) | ((p[:, 0] > -0.2) & (p[:, 1] < 0.4))
    assert np.array_equal(kept.sum(axis=0), inside.astype(int))
