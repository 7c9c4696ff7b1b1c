"""Cameras: orthonormal look-at frames, rays through pixel centres, projection, orbit, fit, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from csgnb.errors import GeometryError
from csgnb.render import Camera

angles = st.floats(-179.0, 179.0)
elevations = st.floats(-80.0, 80.0)


@given(angles, elevations, st.floats(0.5, 50.0), st.sampled_from(["perspective", "orthographic"]))
def test_orbit_frame_is_orthonormal_and_looks_at_the_target(az, el, dist, proj):
    cam = Camera.orbit((1.0, -2.0, 0.5), az, el, dist, 64, 48, projection=proj)
    F = np.array([cam.forward, cam.right, cam.true_up])
    assert np.allclose(F @ F.T, np.eye(3), atol=1e-12)
    assert np.allclose(cam.eye + dist * cam.forward, cam.target, atol=1e-9 * dist)
    assert np.isclose(np.linalg.det(F), -1.0)  # (right, up, -forward) is right-handed: right = f × up
    # elevation above the xy plane, azimuth from +x
    off = cam.eye - cam.target
    assert math.isclose(math.degrees(math.asin(off[2] / dist)), el, abs_tol=1e-7)


@given(angles, elevations, st.sampled_from(["perspective", "orthographic"]), st.integers(0, 47), st.integers(0, 63))
def test_a_point_on_a_pixel_ray_projects_to_that_pixel_centre(az, el, proj, row, col):
    cam = Camera.orbit((0.0, 0.0, 0.0), az, el, 5.0, 64, 48, projection=proj)
    o, v = cam.rays([row], [col])
    assert np.isclose(np.linalg.norm(v), 1.0)
    p = o + 3.7 * v
    px, z = cam.project(p)
    assert np.allclose(px[0], [col, row], atol=1e-9)
    assert np.isclose(z[0], 3.7 * (v[0] @ cam.forward))


def test_orthographic_rays_are_parallel_and_perspective_rays_start_at_the_eye():
    o, v = Camera.look_at((0, -5, 0), (0, 0, 0), width=8, height=6, projection="orthographic").rays()
    assert np.allclose(v, [0, 1, 0]) and np.ptp(o[:, 0]) > 0
    cam = Camera.look_at((0, -5, 0), (0, 0, 0), width=8, height=6)
    o, v = cam.rays()
    assert np.allclose(o, cam.eye)
    # the vertical field of view spans the image height (pixel centres are half a pixel inside)
    X, Y = cam.screen_axes()
    assert np.isclose(Y[0], math.tan(math.radians(20.0)) * (1 - 1 / 6))


@pytest.mark.parametrize("proj", ["perspective", "orthographic"])
def test_fit_sees_every_corner_of_the_bounds(proj):
    lo, hi = np.array([-1.0, 0.0, 2.0]), np.array([3.0, 0.5, 2.2])
    for az, el in ((-60, 30), (10, 80), (170, -45)):
        cam = Camera.fit((lo, hi), 160, 90, azimuth=az, elevation=el, projection=proj)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        px, z = cam.project(corners)
        assert np.all(z > 0)
        assert np.all(px >= -0.5) and np.all(px[:, 0] <= 159.5) and np.all(px[:, 1] <= 89.5)
        # and is tight: some corner is near the border
        ext = np.abs(px - [79.5, 44.5]) / [80, 45]
        assert ext.max() > 0.85


def test_orbited_turns_around_the_target_and_zooms():
    cam = Camera.orbit((0, 0, 0), 0.0, 10.0, 4.0)
    turned = cam.orbited(90.0, 20.0, zoom=2.0)
    assert np.allclose(turned.eye, Camera.orbit((0, 0, 0), 90.0, 30.0, 2.0).eye, atol=1e-12)
    assert cam.with_size(10, 20).shape == (20, 10)


def test_degenerate_cameras_and_sizes_are_clear_errors():
    with pytest.raises(GeometryError, match="coincide"):
        Camera.look_at((1, 1, 1), (1, 1, 1))
    with pytest.raises(GeometryError, match="parallel"):
        Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 0, 1))
    with pytest.raises(GeometryError, match="up vector is zero"):
        Camera.look_at((0, 5, 0), (0, 0, 0), up=(0, 0, 0))
    for fov in (0.0, 180.0, float("nan")):
        with pytest.raises(GeometryError, match="field of view"):
            Camera.look_at((0, 5, 0), (0, 0, 0), fov=fov)
    with pytest.raises(GeometryError, match="finite"):
        Camera.look_at((0, float("inf"), 0), (0, 0, 0))
    with pytest.raises(ValueError, match="at least 1 pixel"):
        Camera.look_at((0, 5, 0), (0, 0, 0), width=0)
    with pytest.raises(ValueError, match="at least 1 pixel"):
        Camera.fit(((0, 0, 0), (1, 1, 1)), 10, -3)
    with pytest.raises(TypeError, match="int"):
        Camera.look_at((0, 5, 0), (0, 0, 0), width=10.5)
    with pytest.raises(ValueError, match="projection"):
        Camera.look_at((0, 5, 0), (0, 0, 0), projection="fisheye")
    with pytest.raises(GeometryError, match="elevation"):
        Camera.orbit((0, 0, 0), 0, 90, 1)
    with pytest.raises(GeometryError, match="distance"):
        Camera.orbit((0, 0, 0), 0, 0, 0)
    with pytest.raises(GeometryError, match="bounds"):
        Camera.fit(np.zeros((2, 2)))
