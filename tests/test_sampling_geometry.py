"""Region geometry of the sampler against brute force: disc covers, bounding polygons, δ bounds,
lattices, and the (u, v)-triangle domains that partition each quadric surface."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb.quadric import (
    QUADRIC_CONSTRUCTORS,
    distortion,
    heightfield,
    principal_frame,
    sampling_planes,
    to_plane_coordinates,
)
from csgnb.sampling.domains import quadric_jobs
from csgnb.sampling.geometry import (
    arc_midpoint,
    corner_reach,
    delta_range,
    discs_cover,
    enclosing_circle,
    lattice_plan,
    region_bulge,
    segment_point,
)

SQRT3 = np.sqrt(3.0)


def _cross(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _segment_distance(p, a, b):
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    return np.linalg.norm(p - a - t[:, None] * (b - a), axis=1)


def _inside_convex(P, pts, tol=0.0):
    s = np.sign(_cross(P[1] - P[0], P[2] - P[0]))
    ok = np.ones(len(pts), dtype=bool)
    for e in range(len(P)):
        a, b = P[e], P[(e + 1) % len(P)]
        ok &= s * _cross(b - a, pts - a) >= -tol
    return ok


def _grid_in(P, n=120):
    lo, hi = P.min(axis=0), P.max(axis=0)
    g = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)), -1).reshape(-1, 2)
    return g[_inside_convex(P, g)]


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1))
def test_discs_cover_agrees_with_a_dense_check(seed):
    rng = np.random.default_rng(seed)
    v = rng.uniform(-1, 1, (3, 2))
    if abs(_cross(v[1] - v[0], v[2] - v[0])) < 0.05:
        return
    rho = rng.uniform(0.1, 1.5, 3)
    got = discs_cover(*v.ravel(), *rho)
    g = _grid_in(v)
    dist = np.min(np.linalg.norm(g[:, None, :] - v[None], axis=2) - rho[None], axis=1)
    if got:
        assert np.all(dist <= 1e-12)  # every grid point is covered
    else:
        # not covered: some point of the triangle is farther than rho from all centers; the dense
        # grid finds it unless the gap is tiny
        assert np.max(dist) > -0.02
    assert np.isclose(corner_reach(*v.ravel(), 1), max(np.linalg.norm(v - v[1], axis=1)))


def _to_uv(xy, flags):
    xy = np.asarray(xy, dtype=float)
    return np.stack([xy[..., 0] ** 2 if flags & 1 else xy[..., 0], xy[..., 1] ** 2 if flags & 2 else xy[..., 1]], -1)


def _from_uv(uv, flags, sx, sy):
    return np.stack([sx * np.sqrt(np.maximum(uv[..., 0], 0)) if flags & 1 else uv[..., 0],
                     sy * np.sqrt(np.maximum(uv[..., 1], 0)) if flags & 2 else uv[..., 1]], -1)


@pytest.mark.parametrize("flags", [1, 2, 3])
@pytest.mark.parametrize("seed", range(20))
def test_curved_regions_stay_within_their_bulge(seed, flags):
    """A (U, V)-triangle's region lies within ``region_bulge`` of its straight triangle, even when
    its sides curve so much that the straight triangle flips — conic arcs (both coordinates
    squared) and parabola arcs (one)."""
    rng = np.random.default_rng(seed)
    sx, sy = rng.choice([-1.0, 1.0], 2)
    v = rng.uniform(0, 1, (3, 2)) * [sx, sy]
    uv = _to_uv(v, flags)
    bulge = region_bulge(*v.ravel(), flags, sx, sy)
    w = rng.dirichlet(np.ones(3), 4000)
    pts = _from_uv(w @ uv, flags, sx, sy)
    outside = ~_inside_convex(v, pts, tol=1e-12)
    if outside.any():
        d = np.min([_segment_distance(pts[outside], v[e], v[(e + 1) % 3]) for e in range(3)], axis=0)
        assert np.all(d <= bulge + 1e-12)
    assert region_bulge(*v.ravel(), 0, sx, sy) == 0.0


@pytest.mark.parametrize("flags", [0, 1, 2, 3])
def test_arc_midpoint_stays_on_the_uv_segment(flags):
    rng = np.random.default_rng(1)
    for _ in range(200):
        sx, sy = rng.choice([-1.0, 1.0], 2)
        a, b = rng.uniform(0, 2, 2) * [sx, sy], rng.uniform(0, 2, 2) * [sx, sy]
        m = np.array(arc_midpoint(*a, *b, sx, sy, flags))
        ua, ub, um = _to_uv(a, flags), _to_uv(b, flags), _to_uv(m, flags)
        assert abs(_cross(ub - ua, um - ua)) <= 1e-9 * (1 + np.abs(ub - ua).max() ** 2)
        assert np.all(np.sign(m) * [sx, sy] >= 0)
        for t in (0.0, 0.3, 1.0):
            p = np.array(segment_point(*a, *b, sx, sy, flags, t))
            assert np.allclose(_to_uv(p, flags), ua + t * (ub - ua), atol=1e-12)


ALL_TYPES = sorted(QUADRIC_CONSTRUCTORS)


@pytest.mark.parametrize("name", ALL_TYPES)
def test_delta_range_bounds_the_distortion(name):
    rng = np.random.default_rng(0)
    for p in sampling_planes(QUADRIC_CONSTRUCTORS[name]()):
        if p.kind == "none":
            continue
        for _ in range(30):
            x0, y0 = rng.uniform(-1.5, 1.5, 2)
            x1, y1 = x0 + rng.uniform(0, 0.5), y0 + rng.uniform(0, 0.5)
            lo, hi = delta_range(p.form_code, *p.coefficients, x0, y0, x1, y1)
            gx, gy = np.meshgrid(np.linspace(x0, x1, 25), np.linspace(y0, y1, 25))
            d = distortion(p, gx.ravel(), gy.ravel())
            if np.isfinite(hi):
                assert np.all(np.isfinite(d)) and np.all(d <= hi * (1 + 1e-12)) and np.all(d >= lo * (1 - 1e-12))


@pytest.mark.parametrize("seed", range(12))
def test_lattices_cover_their_triangle(seed):
    rng = np.random.default_rng(seed)
    a, b, c = rng.uniform(-1, 1, (3, 2))
    rho = rng.uniform(0.05, 0.6)
    centers, n, count, reach, s, t = lattice_plan(*a, *b, *c, rho)
    e1, e2 = b - a, c - a
    if centers:
        pts = [a + ((i + s) * e1 + (j + t) * e2) / n for i in range(n) for j in range(n - i)]
        pts += [a + ((i + 1 - s) * e1 + (j + 1 - t) * e2) / n for i in range(n) for j in range(n - i) if i + j <= n - 2]
    else:
        pts = [a + (i * e1 + j * e2) / n for i in range(n + 1) for j in range(n + 1 - i)]
    pts = np.array(pts)
    assert len(pts) == count
    w = rng.dirichlet(np.ones(3), 3000)
    probe = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
    near = np.min(np.linalg.norm(probe[:, None] - pts[None], axis=2), axis=1)
    assert np.all(near <= reach * (1 + 1e-9)) and reach <= rho * (1 + 1e-12)
    cs, ct, r = enclosing_circle(*a, *b, *c)
    center = a + cs * e1 + ct * e2
    assert np.all(np.linalg.norm(np.array([a, b, c]) - center, axis=1) <= r * (1 + 1e-9))


def _random_quadric(rng, name):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return QUADRIC_CONSTRUCTORS[name]().transformed(M)


@pytest.mark.parametrize("name", ALL_TYPES)
def test_domains_partition_the_surface_with_low_distortion(name):
    rng = np.random.default_rng(4)
    q = _random_quadric(rng, name)
    f = principal_frame(q)
    anchor = f.center.copy()
    k = int(np.argmax(np.abs(f.linear)))
    if f.linear[k] != 0.0:  # planes, paraboloids: their point on the β axis
        anchor += f.axes[:, k] * f.constant / (2 * f.linear[k])
    c = anchor + rng.normal(size=3) * 0.5
    box = np.concatenate([c - 1.5, c + 1.5])
    origin, frame, coef, form, plane, sheet, tri, uv, quad = quadric_jobs(q, box)
    planes = sampling_planes(q)
    p = rng.uniform(box[:3], box[3:], (6000, 3))
    v = rng.normal(size=(6000, 3))
    t = q.intersect_lines(p, v)
    pts = (p[:, None, :] + t[..., None] * v[:, None, :]).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1) & np.all((pts >= box[:3]) & (pts <= box[3:]), axis=1)]
    assert len(pts) > 200
    counts = np.zeros(len(pts), dtype=int)
    for j in range(len(plane)):
        pl = planes[plane[j]]
        loc = to_plane_coordinates(pl, pts)
        if pl.form == "graph":
            on_sheet = np.abs(loc[:, 2] - heightfield(pl, loc[:, 0], loc[:, 1])) <= 1e-8
        else:
            on_sheet = (np.sign(loc[:, 2]) == sheet[j]) | (np.abs(loc[:, 2]) <= 1e-12)
        sx, sy = quad[j]
        flags = int(uv[j])
        in_quad = (((np.sign(loc[:, 0]) * sx >= 0) | (flags & 1 == 0))
                   & ((np.sign(loc[:, 1]) * sy >= 0) | (flags & 2 == 0)))
        inside = _inside_convex(_to_uv(tri[j], flags), _to_uv(loc[:, :2], flags), tol=1e-10) & in_quad & on_sheet
        counts += inside
        if inside.any():
            d = distortion(pl, loc[inside, 0], loc[inside, 1])
            assert np.all(d <= SQRT3 * (1 + 1e-6))
    # points where two planes tie lie on region boundaries and may count twice
    n = np.sort(np.abs(q.normal(pts) @ np.column_stack([pl.normal for pl in planes])), axis=1)
    clear = (n[:, 2] - n[:, 1]) > 1e-6
    assert np.all(counts >= 1)
    assert np.mean(counts[clear] == 1) > 0.97
