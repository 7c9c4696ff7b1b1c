"""The checked STL export: one triangulation (the workpiece's), float32 collapses dropped, what a reader sees."""

from __future__ import annotations

import numpy as np
import pytest

from csgnb.apps.export import check_triangle_soup, export_stl
from csgnb.errors import GeometryError
from csgnb.exact import Grid
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Workpiece
from csgnb.octree.workpiece import identity_grid


def _box(lo, hi):
    lo, hi = np.asarray(lo), np.asarray(hi)
    return convex_hull(np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)]))


def test_the_stl_is_the_workpiece_triangulation_read_back_and_checked(tmp_path):
    w = Workpiece.box([0, 0, 0], [16, 16, 16], threshold=16)
    w -= convex_hull(np.array([[4, 4, 4], [20, 4, 4], [4, 20, 4], [4, 4, 20]]))
    report = export_stl(w, tmp_path / "part.stl")
    V, T = w.to_mesh(manifold=True)
    assert report.triangles == T.shape[0] and report.dropped == 0
    assert report.closed and report.watertight and report.non_manifold_edges == 0
    assert report.volume == pytest.approx(float(w.volume()), rel=1e-6)
    assert "closed: yes, 2-manifold: yes" in report.summary()
    assert not list(tmp_path.glob(".*writing"))  # no temporary left


def test_a_part_touching_itself_along_an_edge_is_reported_not_hidden(tmp_path):
    """Two solid cells meeting only along an edge: every STL reader welds by position, so the edge has four
    triangles whatever the writer duplicated; the report says so."""
    w = Workpiece.box([0, 0, 0], [8, 8, 8])
    w -= _box([4, 4, -1], [9, 9, 9])
    w -= _box([-1, -1, -1], [4, 4, 9])
    report = export_stl(w, tmp_path / "part.stl")
    assert report.closed and not report.watertight and report.non_manifold_edges >= 1
    assert "touches itself" in report.summary()


def test_triangles_that_float32_collapses_are_dropped_and_the_rest_stays_closed(tmp_path):
    """At 5e7 float32 steps are 4 units: exact vertices 1 unit apart become one point."""
    grid = identity_grid(256)
    base = 50_000_000
    w = Workpiece.box([base] * 3, [base + 64] * 3, grid=grid)
    # a thin wedge through the top face: its section there has corners 0.7 units apart
    w -= convex_hull(np.array([[base + 20, base + 20, base + 70], [base + 21, base + 20, base + 70],
                               [base + 20, base + 30, base + 70], [base + 20, base + 20, base + 50]]), grid=grid)
    report = export_stl(w, tmp_path / "part.stl")
    assert report.dropped > 0 and report.closed
    assert report.flat >= 0 and report.triangles + report.dropped == len(w.to_mesh(manifold=True)[1])
    assert f"{report.dropped} triangles collapsed by float32 rounding dropped" in report.summary()


def test_check_triangle_soup_counts_collapses_and_open_edges():
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1]], np.float32)
    T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [3, 4, 0]])
    _, kept, info = check_triangle_soup(P, T)
    assert info["dropped"] == 1 and info["closed"] and kept.shape[0] == 4
    _, _, open_info = check_triangle_soup(P, T[1:])
    assert not open_info["closed"]


def test_an_empty_part_has_no_stl(tmp_path):
    with pytest.raises(GeometryError, match="empty"):
        export_stl(Workpiece.empty(Grid.from_resolution(1.0)), tmp_path / "x.stl")
    assert not (tmp_path / "x.stl").exists()
