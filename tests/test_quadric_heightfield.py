"""Principal frames, sampling planes, eq. 7 heightfields and the distortion δ (eq. 13)."""

import numpy as np
import pytest

from csgnb.errors import GeometryError
from csgnb.quadric import (
    QUADRIC_CONSTRUCTORS,
    distortion,
    distortion_bounds,
    ellipsoid,
    from_plane_coordinates,
    heightfield,
    heightfield_type,
    hyperboloid_one_sheet,
    principal_frame,
    sampling_planes,
    to_plane_coordinates,
)

CENTRAL = [n for n in sorted(QUADRIC_CONSTRUCTORS) if "paraboloid" not in n and n != "plane"]
ALL = sorted(QUADRIC_CONSTRUCTORS)


def _random_quadric(rng, name):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return QUADRIC_CONSTRUCTORS[name]().transformed(M)


@pytest.mark.parametrize("name", sorted(QUADRIC_CONSTRUCTORS))
def test_principal_frame(name):
    q = _random_quadric(np.random.default_rng(2), name)
    f = principal_frame(q)
    np.testing.assert_allclose(f.axes.T @ f.axes, np.eye(3), atol=1e-12)
    assert np.linalg.det(f.axes) > 0
    np.testing.assert_allclose(q.A @ f.axes, f.axes * f.eigenvalues, atol=1e-9)
    assert f.central == (name not in ("plane", "elliptic paraboloid", "hyperbolic paraboloid"))
    if f.central:
        np.testing.assert_allclose(q.A @ f.center, q.b, atol=1e-9)
    # min-norm: no component along the null space of A
    null = f.axes[:, f.eigenvalues == 0.0]
    np.testing.assert_allclose(null.T @ f.center, 0.0, atol=1e-9)


@pytest.mark.parametrize("name", ALL)
def test_heightfield_points_lie_on_the_surface(name):
    rng = np.random.default_rng(4)
    q = _random_quadric(rng, name)
    for p in sampling_planes(q):
        if p.kind == "none":
            continue
        xy = rng.normal(size=(300, 2))
        h = heightfield(p, xy[:, 0], xy[:, 1])
        if np.all(p.linear == 0) and p.form == "sheets":
            np.testing.assert_array_equal(h, heightfield(p.alpha, xy[:, 0], xy[:, 1]))  # eq. 7 from α alone
        ok = np.isfinite(h)
        for sheet in ((1.0, -1.0) if p.form == "sheets" else (1.0,)):
            pts = from_plane_coordinates(p, np.column_stack([xy[ok], sheet * h[ok]]))
            scale = 1 + np.abs(q.A).max() * (1 + np.abs(pts).max()) ** 2
            np.testing.assert_allclose(q.value(pts), 0.0, atol=1e-10 * scale)
        # round trip of the local frame
        pts = rng.normal(size=(10, 3))
        np.testing.assert_allclose(from_plane_coordinates(p, to_plane_coordinates(p, pts)), pts)
        # off the domain there is no surface point over (x, y): the vertical line misses
        miss = xy[~ok]
        if len(miss) and p.form == "sheets":
            lines = from_plane_coordinates(p, np.column_stack([miss, np.zeros(len(miss))]))
            t = q.intersect_lines(lines, np.tile(p.normal, (len(miss), 1)))
            assert np.all(np.isnan(t))


def test_heightfield_types_of_figure_5():
    kinds = {n: sorted(p.kind for p in sampling_planes(QUADRIC_CONSTRUCTORS[n]())) for n in CENTRAL}
    assert kinds["ellipsoid"] == ["elliptic-cap"] * 3
    assert kinds["hyperboloid (one sheet)"] == ["elliptic-hole", "hyperbolic-inner",
                                                "hyperbolic-inner"]
    assert kinds["hyperboloid (two sheets)"] == ["elliptic-bowl", "hyperbolic-outer",
                                                 "hyperbolic-outer"]
    assert kinds["elliptic cone"] == ["cone"] * 3
    assert kinds["elliptic cylinder"] == ["cylindrical", "cylindrical", "none"]
    assert sorted(p.kind for p in sampling_planes(QUADRIC_CONSTRUCTORS["elliptic paraboloid"]())) == [
        "elliptic-graph", "parabolic-inner", "parabolic-inner"]
    assert sorted(p.kind for p in sampling_planes(QUADRIC_CONSTRUCTORS["hyperbolic paraboloid"]())) == [
        "hyperbolic-graph", "parabolic-outer", "parabolic-outer"]
    assert sorted(p.kind for p in sampling_planes(QUADRIC_CONSTRUCTORS["plane"]())) == ["flat-graph", "none", "none"]
    assert heightfield_type([-1.0, -1.0, -1.0]) == "empty"
    assert heightfield_type([np.nan, 1.0, 1.0]) == "none"


def test_distortion_is_one_over_normal_alignment():
    """δ(x, y) = 1 / |uₖ · N| at the surface point over (x, y) — an independent formula."""
    rng = np.random.default_rng(8)
    for name in ALL:
        q = _random_quadric(rng, name)
        for p in sampling_planes(q):
            if p.kind in ("none", "empty"):
                continue
            xy = rng.normal(size=(200, 2))
            h = heightfield(p, xy[:, 0], xy[:, 1])
            ok = np.isfinite(h) & ((h > 1e-3) | (p.form == "graph"))
            pts = from_plane_coordinates(p, np.column_stack([xy[ok], h[ok]]))
            ref = 1.0 / np.abs(q.normal(pts) @ p.normal)
            np.testing.assert_allclose(distortion(p, xy[ok, 0], xy[ok, 1]), ref, rtol=1e-7)


@pytest.mark.parametrize("plane", ["hyperboloid", "paraboloid side", "saddle axis"])
def test_distortion_bounds_match_dense_sampling(plane):
    rng = np.random.default_rng(9)
    alpha = {"hyperboloid": sampling_planes(hyperboloid_one_sheet((1.0, 0.8, 1.2)))[1].alpha,
             "paraboloid side": sampling_planes(QUADRIC_CONSTRUCTORS["elliptic paraboloid"]())[1],
             "saddle axis": sampling_planes(QUADRIC_CONSTRUCTORS["hyperbolic paraboloid"]())[1]}[plane]
    checked = 0
    for _ in range(150):
        lo = rng.uniform(-1.0, 0.8, 2)
        hi = lo + rng.uniform(0.01, 0.6, 2)
        b = distortion_bounds(alpha, [[lo[0], lo[1], hi[0], hi[1]]])[0]
        axes = [np.union1d(np.linspace(lo[k], hi[k], 41), [0.0] if lo[k] < 0 < hi[k] else [])
                for k in range(2)]
        gx, gy = np.meshgrid(*axes)
        d = distortion(alpha, gx.ravel(), gy.ravel())
        if np.isinf(b[1]):  # some point of the rectangle is off the domain or on its rim
            assert np.any(~np.isfinite(d)) or np.any(d > 1e3)
            continue
        assert np.all(np.isfinite(d))
        # the extrema are at the corners of the folded rectangle: grid values lie inside,
        # and the grid (which contains the corners, or the axis fold) attains them
        assert d.min() >= b[0] * (1 - 1e-12) and d.max() <= b[1] * (1 + 1e-12)
        assert d.max() == pytest.approx(b[1], rel=1e-12)
        assert d.min() == pytest.approx(b[0], rel=1e-12)
        checked += 1
    assert checked > 15


def test_heightfield_rejects_planes_without_one():
    p = sampling_planes(ellipsoid((1.0, 2.0, 3.0)))[0]
    assert p.kind == "elliptic-cap"
    with pytest.raises(GeometryError, match="NaN"):
        heightfield([np.nan, 1.0, 1.0], [0.0], [0.0])
    with pytest.raises(ValueError, match="alpha"):
        distortion([1.0, 2.0], [0.0], [0.0])
    with pytest.raises(ValueError, match="lo ≤ hi"):
        distortion_bounds(p.alpha, [[1.0, 0.0, 0.0, 1.0]])
