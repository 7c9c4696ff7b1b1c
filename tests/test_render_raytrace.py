"""The reference ray tracer against an independent ray caster over the CSG graph itself.

The independent caster (numpy, no csgnb kernels, no normal form) intersects each pixel ray with
every leaf of the graph (matrices transformed along the root-to-leaf paths), and finds the first
root where the graph's min/max classification turns from outside to inside.
"""

import numpy as np
import pytest

from csgnb.csg.gallery import figure2, figure15, moved, shared, tour_part
from csgnb.errors import GeometryError
from csgnb.render import Camera, edge_mask, raytrace
from tests.raycast_reference import graph_value, world_leaves


def first_entry(node, origins, dirs):
    """Return t of the first entry into the object along unit rays (inf if none) : (n,)."""
    leaves = [Q for _, Q in world_leaves(node)]
    roots = []
    for Q in leaves:
        A, m, c = Q[:3, :3], Q[:3, 3], Q[3, 3]
        a = np.einsum("ni,ij,nj->n", dirs, A, dirs)
        b = np.einsum("ni,ni->n", dirs, origins @ A + m)
        g = np.einsum("ni,ij,nj->n", origins, A, origins) + 2 * origins @ m + c
        with np.errstate(all="ignore"):
            s = np.sqrt(np.where(b * b - a * g >= 0, b * b - a * g, np.nan))
            quad = np.abs(a) > 1e-12 * (np.abs(b) + 1)
            roots += [np.where(quad, (-b - s) / a, -g / (2 * b)), np.where(quad, (-b + s) / a, np.nan)]
    T = np.sort(np.where(np.column_stack(roots) > 0, np.column_stack(roots), np.inf), axis=1)
    out = np.full(len(origins), np.inf)
    prev = np.zeros(len(origins))
    for k in range(T.shape[1]):
        t = T[:, k]
        ok = np.isfinite(t) & ~np.isfinite(out)
        nxt = np.where(k + 1 < T.shape[1], T[:, min(k + 1, T.shape[1] - 1)], np.inf)
        after = np.where(np.isfinite(nxt), 0.5 * (t + nxt), t + 1e-6 * (1 + t))
        before = 0.5 * (prev + t)
        idx = np.flatnonzero(ok)
        if len(idx):
            v_after = graph_value(node, origins[idx] + after[idx, None] * dirs[idx])
            v_before = graph_value(node, origins[idx] + before[idx, None] * dirs[idx])
            enter = (v_after < 0) & (v_before > 0)
            out[idx[enter]] = t[idx[enter]]
        prev = np.where(np.isfinite(t), t, prev)
    return out


@pytest.mark.parametrize("build", [figure2, moved, shared, figure15, tour_part])
@pytest.mark.parametrize("proj", ["perspective", "orthographic"])
def test_raytrace_matches_an_independent_caster(build, proj):
    shape = build()
    nf = shape.normal_form()
    cam = Camera.fit(_bounds(shape), 64, 48, azimuth=-50, elevation=25, projection=proj)
    frame = raytrace(shape, cam)
    o, v = cam.rays()
    t = first_entry(shape, o, v)
    z_ref = (t * (v @ cam.forward)).reshape(cam.shape)
    covered_ref = np.isfinite(z_ref)
    edge = edge_mask(frame)
    # coverage agrees away from silhouettes, depth to 1e-9 wherever both see a surface
    assert np.all((covered_ref == frame.covered) | edge)
    both = covered_ref & frame.covered
    assert both.sum() > 150
    rel = np.abs(frame.depth[both] - z_ref[both]) / z_ref[both]
    assert np.all((rel < 1e-9) | edge[both])
    assert np.mean(rel < 1e-9) > 0.98
    # the reported quadric passes through the visible point, and its normal is unit
    p = frame.points()
    Q = np.array([nf.quadrics[k].matrix for k in frame.quadric[frame.covered]])
    h = np.column_stack([p, np.ones(len(p))])
    val = np.einsum("ni,nij,nj->n", h, Q, h)
    assert np.max(np.abs(val) / np.abs(Q).max(axis=(1, 2))) < 1e-9
    assert np.allclose(np.linalg.norm(frame.normal[frame.covered], axis=1), 1.0, atol=1e-6)


def _bounds(shape):
    """A coarse cloud of the object: its box is what the camera fits."""
    from csgnb.sampling import sample_csg

    return sample_csg(shape, 1.0)


def test_raytrace_of_a_sphere_is_analytic():
    from csgnb.csg import sphere

    cam = Camera.look_at((0, -6, 0), (0, 0, 0), width=40, height=30)
    f = raytrace(sphere((0.2, 0.1, -0.1), 1.0), cam)
    o, v = cam.rays()
    c = np.array([0.2, 0.1, -0.1])
    b = np.einsum("ni,ni->n", v, o - c)
    disc = b * b - (np.sum((o - c) ** 2, axis=1) - 1.0)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0))
    z = np.where(hit, t * (v @ cam.forward), np.inf).reshape(cam.shape)
    assert np.array_equal(np.isfinite(z), f.covered)
    assert np.allclose(f.depth[f.covered], z[f.covered], rtol=1e-12)
    assert np.all(f.term[f.covered] == 0)


def test_raytrace_bad_input():
    cam = Camera.look_at((0, -6, 0), (0, 0, 0), width=8, height=6)
    with pytest.raises(TypeError, match="Camera"):
        raytrace(figure2(), "camera")
    with pytest.raises(TypeError, match="CSG node"):
        raytrace(42, cam)
    from csgnb.csg import complement, intersection, sphere

    A = sphere((0, 0, 0), 1.0)
    with pytest.raises(GeometryError, match="empty"):
        raytrace(intersection(A, complement(A)), cam)


def test_scenes_far_from_the_origin_render_right_or_are_refused():
    """Issue 25 for the renderers: they work in world coordinates, where a unit sphere at 10⁹ has
    c = 10¹⁸ − 1 (the radius lost): it drew every pixel (ray tracer) or none (splats). Now such a
    scene is refused with a clear error; near enough, it renders as at the origin."""
    import csgnb.csg as csg
    from csgnb.render import render
    from csgnb.sampling import sample_csg

    ref = None
    for x in (0.0, 1e3, 1e9):
        o = np.array([x, -0.5 * x, 0.25 * x])
        shape = csg.sphere(o, 1.0)
        cam = Camera.fit((o - 1.0, o + 1.0), 64, 48)
        cloud = sample_csg(shape, 0.2)
        if x == 1e9:
            with pytest.raises(GeometryError, match="too far from the origin to render"):
                raytrace(shape, cam)
            with pytest.raises(GeometryError, match="too far from the origin to render"):
                render(cloud, cam)
            continue
        traced, splats = raytrace(shape, cam), render(cloud, cam)
        if ref is None:
            ref = traced
        assert np.array_equal(np.isfinite(traced.depth), np.isfinite(ref.depth))
        hit = np.isfinite(ref.depth)
        assert np.allclose(traced.depth[hit], ref.depth[hit], rtol=1e-9)
        assert np.array_equal(np.isfinite(splats.depth), np.isfinite(ref.depth))
