"""A convex hull's facets as plane-based polygons (``csgnb.mesh.hull_facets``): the pieces a cell's boundary merge
takes for a convex tool in place of the cell's box cut by the hull's planes.

Checked exactly with Python integers: every vertex lies on its facet's plane and on the planes of both facets across
its edges, each ring turns counter-clockwise seen from outside, and each facet's points are the hull's own face.
Then in the workpiece: Booleans with the facets and with the box cut give the same exact solid, single Booleans and
compiled batches alike, on lattice-aligned boxes (faces on cell walls and on earlier cuts) and round hulls.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import csgnb.octree.workpiece as wp
from csgnb.exact import to_wide
from csgnb.mesh.hull import convex_hull
from csgnb.mesh.hull_facets import hull_facet_polygons, hull_facets_of_batch
from csgnb.octree import Tool, Workpiece
from csgnb.octree import tool as tool_module
from csgnb.octree.batch import spread_orders
from csgnb.octree.layout import S_BOUNDARY_MERGES


def _check_facets(hull, tool):
    """The facets of ``tool`` (from ``hull``), exactly: vertex j on its support and on edges j and j + 1, rings
    counter-clockwise seen from outside, each facet's points the hull face's points, boxes holding them."""
    support, offsets, edges, points, lo, hi = tool.facets
    planes = [[int(v) for v in row] for row in tool.planes.tolist()]
    faces = {tuple(sorted(map(tuple, hull.points[f].tolist()))) for f in hull.faces}
    assert support.tolist() == list(range(len(planes))) and offsets[-1] == len(edges) == len(points)

    def value(plane, p):
        return plane[0] * int(p[0]) + plane[1] * int(p[1]) + plane[2] * int(p[2]) + plane[3]

    for i, plane in enumerate(planes):
        ring = points[offsets[i]:offsets[i + 1]].tolist()
        e = edges[offsets[i]:offsets[i + 1]].tolist()
        k = len(ring)
        assert k >= 3 and tuple(sorted(map(tuple, ring))) in faces
        for j in range(k):
            assert value(plane, ring[j]) == 0
            assert value(planes[e[j]], ring[j]) == 0 and value(planes[e[(j + 1) % k]], ring[j]) == 0
            assert e[j] != e[(j + 1) % k] and e[j] != i
            a, b, c = (np.array(ring[(j + d) % k], dtype=object) for d in (0, 1, 2))
            turn = np.cross((b - a).tolist(), (c - b).tolist())
            # counter-clockwise seen from outside
            assert sum(int(x) * y for x, y in zip(turn, plane[:3], strict=True)) > 0
        assert (np.min(ring, axis=0) == lo[i]).all() and (np.max(ring, axis=0) == hi[i]).all()


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([128, 256]), st.integers(4, 40))
def test_facets_are_the_hulls_faces_over_its_planes(seed, width, n):
    rng = np.random.default_rng(seed)
    scale = 10**6 if width == 256 else 50
    points = rng.integers(-scale, scale, size=(n, 3))
    try:
        hull = convex_hull(points, width=width)
    except Exception:  # flat point sets have no hull
        return
    tool = Tool.from_hull(hull)
    _check_facets(hull, tool)
    if "_rings" in hull.__dict__:  # the verification's rings, kept: the same polygons as the sign pass finds
        del hull.__dict__["_rings"]
        again = hull_facet_polygons(hull, tool._hull[1])
        for a, b in zip(tool.facets, again, strict=True):
            assert np.array_equal(a, b)


def test_points_on_edges_and_faces_are_not_vertices():
    """A box with points at its edges' midpoints and its faces' centres (and a hull of many coplanar points):
    every ring is strictly convex -- consecutive edges name different planes, so every vertex is a proper point."""
    corners = np.array([[x, y, z] for x in (0, 8) for y in (0, 8) for z in (0, 8)])
    extra = np.array([[4, 0, 0], [0, 4, 0], [0, 0, 4], [8, 4, 8], [4, 4, 0], [4, 4, 8], [0, 4, 4], [8, 4, 4],
                      [4, 8, 4], [4, 0, 4], [2, 0, 0], [6, 8, 8]])
    hull = convex_hull(np.concatenate([corners, extra]))
    tool = Tool.from_hull(hull)
    _check_facets(hull, tool)
    assert np.diff(tool.facets[1]).tolist() == [4] * 6
    grid_pts = np.array([[x, y, z] for x in range(0, 9, 2) for y in range(0, 9, 2) for z in (0, 3)])
    _check_facets(convex_hull(grid_pts), Tool.from_hull(convex_hull(grid_pts)))


def test_a_translated_or_pickled_tool_keeps_its_facets():
    rng = np.random.default_rng(4)
    hull = convex_hull(rng.integers(-30, 30, size=(25, 3)))
    tool = Tool.from_hull(hull)
    t = np.array([7, -3, 11])
    made_after = tool.translated(t).facets  # from the hull, moved
    made_before = tool.facets
    moved = tool.translated(t)
    assert "_facets" in moved.__dict__  # made already: moved, not made again
    for a, b, c in zip(made_after, moved.facets, made_before, strict=True):
        assert np.array_equal(a, b)
        if a.ndim == 2:
            assert np.array_equal(a, c + t)
    _check_facets(hull.translated(t), moved)
    copy = pickle.loads(pickle.dumps(moved))
    assert "_hull" not in copy.__dict__
    for a, b in zip(copy.facets, moved.facets, strict=True):
        assert np.array_equal(a, b)


def test_a_batch_gets_each_hulls_own_facets():
    """The batch's facet pass gives every hull the facets a single tool made from it has."""
    rng = np.random.default_rng(9)
    hulls = [convex_hull(rng.integers(-20, 20, size=(int(rng.integers(4, 30)), 3)) + rng.integers(-99, 99, 3))
             for _ in range(12)]
    starts = np.zeros(len(hulls) + 1, np.int64)
    np.cumsum([h.n_planes for h in hulls], out=starts[1:])
    P = np.concatenate([h.planes for h in hulls])
    order = spread_orders(P[:, :3].astype(np.float64), starts)
    has, offsets, edges, points, lo, hi = hull_facets_of_batch(hulls, starts, order)
    assert has.all()
    for i, h in enumerate(hulls):
        single = hull_facet_polygons(h, order[starts[i]:starts[i + 1]] - starts[i])
        s, e = starts[i], starts[i + 1]
        assert np.array_equal(offsets[s:e + 1] - offsets[s], single[1])
        assert np.array_equal(edges[offsets[s]:offsets[e]], single[2])
        assert np.array_equal(points[offsets[s]:offsets[e]], single[3])
        assert np.array_equal(lo[s:e], single[4]) and np.array_equal(hi[s:e], single[5])


def _carve(width, seed, facets: bool, batch: bool) -> Workpiece:
    """A block minus lattice boxes and round hulls (unions now and then), convex tools only, with the hulls'
    facets or with the box cut (the tool without facets)."""
    rng = np.random.default_rng(seed)
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24, width=width)
    w.oc.counts[S_BOUNDARY_MERGES] = 0
    hulls = []
    for _ in range(36):
        if rng.random() < 0.5:
            lo = 4 * rng.integers(-1, 15, 3)
            hi = lo + 4 * rng.integers(1, 5, 3)
            pts = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        else:
            d = rng.normal(size=(30, 3))
            pts = np.rint(d / np.linalg.norm(d, axis=1)[:, None] * rng.integers(5, 14)).astype(np.int64)
            pts += rng.integers(0, 64, 3)
        hulls.append(convex_hull(pts, width=width))
    with pytest.MonkeyPatch.context() as mp:
        if not facets:
            mp.setattr(tool_module.Tool, "facets", property(lambda self: None))
            mp.setattr(wp, "hull_facets_of_batch", lambda *a: None)
        for at in range(0, len(hulls), 6):
            group = hulls[at:at + 6]
            op = "union" if at % 18 == 12 else "difference"
            if batch:
                w.run(group, op)
            else:
                for h in group:
                    getattr(w, op)(h)
    return w


@pytest.mark.parametrize(("width", "seed", "batch"), [(128, 1, False), (256, 2, False), (128, 3, True),
                                                      (256, 4, True)])
def test_booleans_with_facets_carve_the_solid_the_box_cut_carves(width, seed, batch):
    with_facets, cut = _carve(width, seed, True, batch), _carve(width, seed, False, batch)
    assert with_facets.oc.counts[S_BOUNDARY_MERGES] > 50
    assert with_facets.volume() == cut.volume()
    pts = np.random.default_rng(seed).integers(-1, 66, size=(4000, 3))
    x = to_wide(np.column_stack([2 * pts + 1, np.full(len(pts), 2)]), width)  # half-integers: off every grid plane
    assert np.array_equal(with_facets.classify(x), cut.classify(x))


@pytest.mark.parametrize("bits", [10, 18, 30, 50, 58])
def test_hulls_near_the_256_bit_mesh_budget_give_exact_facets_or_none(bits):
    """Few points (facets enumerated, no kept rings: the facet pass finds its own signs) with coordinates from 2^10
    to 2^58: where the normals fit int64 the facets are exact; beyond (Python-int normals) there are none and the
    workpiece cuts the box instead -- never inexact ones."""
    from csgnb.exact.budgets import budget

    limit = min(1 << bits, budget(256).max_mesh_coordinate)
    rng = np.random.default_rng(bits)
    for _ in range(5):
        hull = convex_hull(rng.integers(-limit, limit, size=(9, 3)), width=256)
        assert "_rings" not in hull.__dict__
        tool = Tool.from_hull(hull)
        if tool.facets is not None:
            _check_facets(hull, tool)
        else:
            assert hull._normals.dtype == object
        assert (tool.facets is not None) == (bits <= 18)
