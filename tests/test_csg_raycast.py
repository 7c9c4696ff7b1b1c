"""Checks of the independent ray-casting reference (``tests/raycast_reference.py``) itself."""

from __future__ import annotations

import numpy as np
import pytest

from csgnb.csg import box, sphere
from tests.raycast_reference import graph_first_order_distance, random_rays, ray_surface_points

# -- checks of the reference itself ----------------------------------------------------------------


def test_ray_cast_sphere_matches_analytic_points():
    rng = np.random.default_rng(0)
    S = sphere((0.3, -0.2, 0.1), 0.8)
    o, d, tmax = random_rays(rng, (0.3, -0.2, 0.1), 0.8, 200)
    pts, mats = ray_surface_points(S, o, d, tmax)
    assert len(pts) > 200
    assert np.allclose(np.linalg.norm(pts - [0.3, -0.2, 0.1], axis=1), 0.8, atol=1e-9)


def test_ray_cast_box_difference_lies_on_the_faces():
    rng = np.random.default_rng(1)
    S = box((0, 0, 0), (1, 1, 1)) - sphere((1, 1, 1), 0.5)
    o, d, tmax = random_rays(rng, (0.5, 0.5, 0.5), 1.0, 300)
    pts, _ = ray_surface_points(S, o, d, tmax)
    on_face = np.any(np.isclose(pts, 0.0, atol=1e-9) | np.isclose(pts, 1.0, atol=1e-9), axis=1)
    on_ball = np.isclose(np.linalg.norm(pts - 1.0, axis=1), 0.5, atol=1e-9)
    assert np.all(on_face | on_ball)
    assert on_ball.sum() > 5 and on_face.sum() > 50
    # no face point inside the cut-away ball is reported
    assert not np.any(on_face & (np.linalg.norm(pts - 1.0, axis=1) < 0.5 - 1e-9))


@pytest.mark.parametrize("seed", range(3))
def test_first_order_distance_vanishes_on_ray_hits(seed):
    rng = np.random.default_rng(seed)
    A, B = sphere((0, 0, 0), 1.0), sphere((0.9, 0.1, 0), 0.8)
    S = (A & B) | sphere((0.3, 0.8, 0.2), 0.5)
    o, d, tmax = random_rays(rng, (0.3, 0.3, 0), 1.5, 300)
    pts, _ = ray_surface_points(S, o, d, tmax)
    assert len(pts) > 100
    assert np.max(np.abs(graph_first_order_distance(S, pts))) < 1e-9
