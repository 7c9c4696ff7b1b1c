"""Carving placements (Figure 15a): dodecahedra on the grid outside a target surface, subtracted exactly."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from csgnb import GeometryError
from csgnb.apps import carving
from csgnb.apps.reference import BSPWorkpiece
from csgnb.exact import Grid
from csgnb.octree import Workpiece


def test_dodecahedron_is_regular_and_its_hull_exact():
    v = carving.dodecahedron_vertices(2.0)
    assert v.shape == (20, 3)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 2.0)
    d = np.linalg.norm(v[:, None] - v[None], axis=2)
    edge = np.min(d[d > 1e-9])
    assert np.sum(np.isclose(d, edge)) == 2 * 30  # 30 edges
    g = Grid.from_resolution(1 / 256)
    h = carving.dodecahedron((0.5, 0, 0), 2.0, np.eye(3), g)
    a = edge
    assert float(h.volume()) / g.scale**3 == pytest.approx((15 + 7 * 5**0.5) / 4 * a**3, rel=5e-3)  # rounding: 1/512 mm
    assert h.grid is g and len(h.points) == 20


@pytest.mark.parametrize("target", [carving.sphere_target((1, 0, 0), 5.0), carving.torus_target((0, 0, 0), 5, 2)])
def test_placements_touch_the_target_from_outside(target):
    g = Grid.fit([-12] * 3, [12] * 3)
    c = carving.carving_placements(target, 200, 0.6, grid=g, seed=3)
    assert len(c) == 200 and c.rotations.shape == (200, 3, 3)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", c.rotations, c.rotations), np.broadcast_to(np.eye(3),
                                                                                                    (200, 3, 3)),
                               atol=1e-12)
    if target.name.startswith("sphere"):
        dist = np.linalg.norm(c.centers - [1, 0, 0], axis=1)
        np.testing.assert_allclose(dist, 5.6)
        # Every grid vertex of every dodecahedron lies outside the sphere (up to one grid step).
        for i in range(0, 200, 20):
            p = g.to_model(c.hull(i).points)
            assert np.all(np.linalg.norm(p - [1, 0, 0], axis=1) >= 5 + 0.6 - 0.6 - g.resolution)
    # reproducible
    again = carving.carving_placements(target, 200, 0.6, grid=g, seed=3)
    np.testing.assert_array_equal(again.centers, c.centers)


def test_mesh_target_samples_on_the_mesh_with_outward_normals():
    import pyvista as pv

    s = pv.Sphere(radius=3.0, theta_resolution=16, phi_resolution=16).triangulate()
    t = carving.mesh_target(s.points, s.faces.reshape(-1, 4)[:, 1:])
    p, n = t.sample(500, np.random.default_rng(0))
    assert np.all(np.linalg.norm(p, axis=1) <= 3 + 1e-9)
    assert np.all(np.einsum("ij,ij->i", p, n) > 0)  # outward


def test_carve_removes_exact_volumes_from_a_block():
    """On the octree (small cells, so dodecahedra cross cells that split and combine) and on the single-BSP
    reference: the same exact volume per dodecahedron, summing to stock - part."""
    g = Grid.fit([-6] * 3, [6] * 3)
    c = carving.carving_placements(carving.sphere_target(radius=3.0), 12, 0.8, grid=g, seed=1)
    runs = []
    for w in (Workpiece.box((-4, -4, -4), (4, 4, 4), grid=g, threshold=24), BSPWorkpiece.box((-4, -4, -4),
                                                                                             (4, 4, 4), grid=g)):
        before = w.model_volume()
        removed, seconds = carving.carve(w, c, progress=False)
        assert len(removed) == 12 == len(seconds) and all(isinstance(r, Fraction) for r in removed)
        assert sum(r > 0 for r in removed) >= 10
        assert before - sum(removed) == w.model_volume()
        runs.append((removed, w.volume()))
    assert runs[0] == runs[1]
    w = Workpiece.box((-4, -4, -4), (4, 4, 4), grid=g)
    assert carving.carve(w, c, progress=False, track_volume=False)[0] is None and w.volume() == runs[0][1]
    with pytest.raises(GeometryError, match="budget box"):
        carving.carving_placements(carving.sphere_target(radius=20.0), 5, 0.5, grid=g)
    with pytest.raises(GeometryError, match="different grids"):
        carving.carve(w, carving.carving_placements(carving.sphere_target(radius=1), 2, 0.5,
                                                    grid=Grid.from_resolution(0.01)), progress=False)
