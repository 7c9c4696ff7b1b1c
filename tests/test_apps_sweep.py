"""Tools (csgnb.apps.tools) and sweeps (csgnb.apps.sweep): valid meshes on a grid, convexity, exact swept volumes.

References are independent of the hull code: the area of a convex polygon by the shoelace
formula with Python ints, the width of a polygon across a direction, the Minkowski-sum
volume of a prism and a segment, and BSP unions (mesh cutting) for the prism covers.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from csgnb import GeometryError
from csgnb.apps import sweep, tools
from csgnb.exact import Grid
from csgnb.mesh.hull import convex_hull

GRID = Grid.from_resolution(1 / 64, origin=(0.0, 0.0, 0.0))


def polygon_area2(xy) -> int:
    """Twice the area of the convex hull of integer points (monotone chain + shoelace, Python ints)."""
    pts = sorted({(int(x), int(y)) for x, y in xy})

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    ring = half(pts)[:-1] + half(pts[::-1])[:-1]
    return sum(a[0] * b[1] - a[1] * b[0] for a, b in zip(ring, ring[1:] + ring[:1], strict=True))


@pytest.mark.parametrize("shape, convex", [
    (tools.flat_end_mill(6, 12, segments=12), True),
    (tools.ball_end_mill(6, 12, segments=12), True),
    (tools.bull_nose(6, 1.5, 12, segments=12), True),
    (tools.v_bit(6, 60, segments=12), True),
    (tools.drill_envelope(6, 12, segments=12), True),
    (tools.twist_drill(profile_points=12, layers=6), False),
    (tools.spur_gear(teeth=8, flank_points=3), False),
])
def test_tools_are_valid_meshes_on_the_grid(shape, convex):
    t = shape.on(GRID)
    assert t.convex is convex
    assert t.mesh_volume > 0
    hull = t.hull.volume()
    assert hull >= t.mesh_volume
    if convex:  # rounding to the grid can only dent a convex polygon by a sliver
        assert float(t.mesh_volume / hull) > 0.99
    else:
        assert float(t.mesh_volume / hull) < 0.95
    assert np.array_equal(t.at((1, 2, 3)), t.offsets + GRID.to_grid([[1, 2, 3]])[0])


def test_default_drill_and_gear_are_the_papers_sizes():
    d = tools.twist_drill()
    assert d.n_triangles == 896 and d.radius == pytest.approx(3.0) and d.params["point_angle"] == 118
    g = tools.spur_gear()
    assert g.n_triangles == 480
    d.on(Grid.from_resolution(0.01))
    g.on(Grid.from_resolution(0.01))


def test_flat_end_mill_volume_is_its_polygon_prism():
    t = tools.flat_end_mill(6, 10, segments=16).on(GRID)
    area2 = polygon_area2(t.offsets[:, :2])
    height = int(t.offsets[:, 2].max() - t.offsets[:, 2].min())
    assert t.hull.volume() == Fraction(area2, 2) * height
    assert t.mesh_volume == t.hull.volume()  # both rings round alike: the quantized prism is exact


def test_user_meshes_are_classified_exactly():
    cube_v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    cube_f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                       [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    assert tools.mesh_tool(cube_v, cube_f).on(GRID).convex
    # The gear's own mesh as a user tool: not convex, decided on the grid.
    g = tools.spur_gear(teeth=8, flank_points=3)
    assert not tools.mesh_tool(g.vertices, g.faces).on(GRID).convex
    # A 0.1 mm mill on a 0.05 mm grid: its 64-gon rounds to a few grid points; the faces that rounding collapses
    # bound no volume and are dropped, and counted so that a caller can say the grid is coarse for the tool.
    coarse = tools.flat_end_mill(0.1, 1, segments=64).on(Grid.from_resolution(0.05))
    assert coarse.collapsed_faces > 0 and tools.flat_end_mill(6, 18).on(GRID).collapsed_faces == 0
    with pytest.raises(ValueError, match="faces"):
        tools.mesh_tool(cube_v, cube_f.astype(float))


def test_tool_parameters_are_checked():
    with pytest.raises(ValueError, match="diameter"):
        tools.flat_end_mill(-1)
    with pytest.raises(ValueError, match="corner_radius"):
        tools.bull_nose(6, 4)
    with pytest.raises(ValueError, match="angle"):
        tools.v_bit(6, 180)
    with pytest.raises(ValueError, match="segments"):
        tools.ball_end_mill(6, segments=2)
    assert tools.parse_tool("bull:6:1").params["corner_radius"] == 1
    assert tools.parse_tool("vbit:10:60").params["angle"] == 60
    assert tools.parse_tool("drill:3:20").params["flute_length"] == 20
    for bad in ("flat", "mill:6", "flat:x", "bull:6", "flat:6:1:2"):
        with pytest.raises(ValueError):
            tools.parse_tool(bad)


def test_convex_sweep_is_the_minkowski_sum_of_the_tool_and_the_move():
    """Flat end mill moving horizontally: volume = (area(P) + width of P across the move) x height, exactly."""
    t = tools.flat_end_mill(4, 5, segments=10).on(GRID)
    area2 = polygon_area2(t.offsets[:, :2])
    height = int(t.offsets[:, 2].max())
    for a, b in [((0, 0, 0), (7, 0, 0)), ((1, 1, 0), (-2, 5.5, 0)), ((0, 0, 0), (3.25, -1.75, 0))]:
        s = sweep.straight_sweep(t, a, b)
        assert len(s.hulls) == 1 and s.end_pose is None
        v = GRID.to_grid([b])[0] - GRID.to_grid([a])[0]
        perp = np.array([-v[1], v[0]])
        proj = [int(x) for x in t.offsets[:, :2] @ perp]
        expect = (Fraction(area2, 2) + max(proj) - min(proj)) * height
        assert s.hulls[0].volume() == expect
    # A plunge: the prism grows by the depth.
    s = sweep.straight_sweep(t, (0, 0, 2), (0, 0, -3))
    assert s.hulls[0].volume() == Fraction(area2, 2) * (height + 5 * 64)


def test_prisms_and_end_poses_cover_a_translated_non_convex_tool():
    """For a translation, the per-triangle prisms plus both end poses are the exact Minkowski sum.

    Tool: an L made of two boxes; the Minkowski sum of each box and the segment is the hull of the
    box at both poses, and their union is the reference (BSP unions, mesh cutting).
    """
    from csgnb.bsp import BSP

    def box_mesh(lo, hi):
        v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], float)
        return v

    boxes = [((0, 0, 0), (2, 0.5, 1)), ((0, 0, 0), (0.5, 2, 1))]
    # The L as one closed mesh: the union of the two boxes' boundary, via the BSP.
    grid = GRID
    solids = [convex_hull(grid.to_grid(box_mesh(*b))).to_bsp() for b in boxes]
    from csgnb.apps.reference import BSPWorkpiece

    V, T = BSPWorkpiece(solids[0] | solids[1], grid).to_mesh()
    shape = tools.mesh_tool(V, T)
    t = shape.on(grid)
    assert not t.convex
    move = (1.5, 0.75, 0.0)  # horizontal: the top and bottom triangles slide in their planes (flat prisms)
    s = sweep.straight_sweep(t, (0, 0, 0), move)
    assert s.skipped > 0 and len(s.hulls) + s.skipped == len(t.faces)
    covered = sweep.union_hulls(s.hulls)
    covered = covered | BSP.from_mesh(s.end_pose, s.faces) | BSP.from_mesh(t.at((0, 0, 0)), t.faces)
    d = grid.to_grid([move])[0]
    ref = None
    for b in boxes:
        P = grid.to_grid(box_mesh(*b))
        piece = convex_hull(np.vstack([P, P + d])).to_bsp()
        ref = piece if ref is None else ref | piece
    assert covered.volume() == ref.volume()
    assert (covered ^ ref).volume() == 0


def test_drill_sweeps_rotate_and_feed_by_exact_translation():
    t = tools.twist_drill(profile_points=8, layers=4).on(Grid.from_resolution(1 / 32))
    ds = sweep.drill_sweeps(t, (0, 0, 0), steps=6, step_degrees=60, feed_per_turn=1.0)
    assert len(ds) == 6 and all(len(s) > 0 for s in ds.steps)
    assert ds.skipped + sum(len(s) for s in ds.steps) == 6 * len(t.faces)
    # The feed runs along the axis tilted 30° from vertical, towards the tip.
    f = ds.feed / 32
    assert np.linalg.norm(f) == pytest.approx(1.0, abs=0.05)
    assert f[2] == pytest.approx(-np.cos(np.radians(30)), abs=0.05)
    assert len(ds.poses) == 6 and np.array_equal(ds.faces, t.faces)
    np.testing.assert_array_equal(ds.poses[0], sweep.pose_vertices(t, sweep.drill_poses(steps=0)[0]))
    moved = ds.step(6 + 2)
    for h0, h1 in zip(ds.steps[2], moved, strict=True):
        assert np.array_equal(h1.points, h0.points + ds.feed)
        assert h1.volume() == h0.volume()
    # Poses: pose k is the tilted drill turned k steps; the last pose of a full turn equals the first.
    poses = sweep.drill_poses(steps=90, step_degrees=4)
    assert len(poses) == 91
    np.testing.assert_allclose(poses[90].rotation, poses[0].rotation, atol=1e-12)
    axis = poses[0].rotation @ [0, 0, 1]
    assert np.degrees(np.arccos(axis[2])) == pytest.approx(30)


def test_gear_along_a_bezier():
    g = tools.spur_gear(teeth=6, flank_points=2).on(GRID)
    pts = sweep.bezier_points([[0, 0, 0], [5, 10, 0], [15, -10, 2], [20, 0, 2]], 5)
    np.testing.assert_array_equal(pts[0], [0, 0, 0])
    np.testing.assert_array_equal(pts[-1], [20, 0, 2])
    steps = sweep.path_sweep(g, [sweep.Pose(p) for p in pts])
    assert len(steps) == 4
    for s, p, q in zip(steps, pts[:-1], pts[1:], strict=True):
        assert len(s.hulls) + s.skipped == len(g.faces)
        # Each prism holds its triangle at both (exactly translated) poses.
        A, B = g.at(p), g.at(q)
        assert all(h.contains(np.vstack([A[f], B[f]])).all() for h, f in zip(s.hulls[:5], g.faces[:5], strict=False))
    with pytest.raises(GeometryError):
        sweep.bezier_points(np.zeros((3, 3)), 4)


def test_poses_and_rotations_are_checked():
    R = sweep.rotation_about((0, 0, 1), 90)
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    with pytest.raises(GeometryError):
        sweep.Pose((0, 0, 0), np.diag([1, 1, -1]))
    with pytest.raises(GeometryError):
        sweep.path_sweep(tools.flat_end_mill(2).on(GRID), [sweep.Pose((0, 0, 0))])


def test_drill_step_tools_are_the_union_of_their_prisms_on_any_thread_count():
    """DrillSweeps.tools builds step k's tool as the union of its prisms (exact volume against the single-BSP union),
    the same tool on one thread and on two (the steps run in parallel)."""
    from csgnb.octree import Workpiece

    grid = Grid.from_resolution(1 / 32)
    t = tools.twist_drill(profile_points=8, layers=4).on(grid)
    ds = sweep.drill_sweeps(t, (0, 0, 0), steps=4, step_degrees=90, feed_per_turn=1.0)
    one = ds.tools(grid, threads=1)
    two = ds.tools(grid, threads=2, progress=True)
    assert len(one) == len(two) == 4
    for k, (a, b) in enumerate(zip(one, two, strict=True)):
        assert a.kind == b.kind == "mesh"
        assert np.array_equal(a.planes, b.planes) and np.array_equal(a.polygons.edges, b.polygons.edges)
        w = Workpiece.empty(grid)
        w |= a
        assert w.volume() == sweep.union_hulls(ds.steps[k], width=grid.width).volume()
    with pytest.raises(TypeError, match="threads"):
        ds.tools(grid, threads=0)


@pytest.mark.parametrize("width", [128, 256])
def test_a_tools_turn_symmetry_is_found_exactly_on_the_grid(width):
    """GridTool.spin_symmetry: the two-flute drill turns into itself every 180°, a 12-tooth gear every 30°; each
    vertex turned lands exactly on the grid offset the permutation names; a drill with one vertex moved has none."""
    grid = Grid.fit([-12, -12, -16], [12, 12, 8], width=width)
    for shape, order in [(tools.twist_drill(), 2), (tools.spur_gear(teeth=12), 12)]:
        t = shape.on(grid)
        sym = t.spin_symmetry
        assert sym.order == order
        turned = t.design_vertices() @ sweep.rotation_about((0, 0, 1), 360 / order).T
        np.testing.assert_array_equal(t.offsets[sym.permutation], np.rint(turned * grid.scale).astype(np.int64))
        assert sorted(sym.permutation.tolist()) == list(range(len(t.offsets)))
        np.testing.assert_array_equal(sym.turns(order), np.arange(len(t.offsets)))
    shape = tools.twist_drill(profile_points=8, layers=4)
    moved = shape.vertices.copy()
    moved[np.argmax(np.linalg.norm(moved[:, :2], axis=1))] *= [0.97, 0.97, 1.0]  # one land vertex pulled in
    lopsided = tools.ToolShape("lopsided drill", moved, shape.faces, convex=False).on(grid)
    assert lopsided.spin_symmetry.order == 1
    flipped = shape.faces.copy()
    flipped[:2] = [[0, 3, 1], [3, 2, 1]]  # the vertices still symmetric, one quad's diagonal not
    assert tools.ToolShape("flipped", shape.vertices, flipped, convex=False).on(grid).spin_symmetry.order == 1
    assert sweep.drill_sweeps(lopsided, steps=90, step_degrees=4).period == 90


def test_a_symmetric_drill_sweeps_each_distinct_step_once_with_the_same_prisms_as_posing_every_step():
    """Pose k + 45 of the two-flute drill is pose k renamed by its 180° symmetry: every vertex within half a grid
    unit of its true turned position, and every step's prisms the same set of hulls as posing each step directly."""
    grid = Grid.from_resolution(1 / 32)
    t = tools.twist_drill(profile_points=8, layers=4).on(grid)
    ds = sweep.drill_sweeps(t, (0.25, 0, 0), steps=90, step_degrees=4, feed_per_turn=1.0)
    direct = sweep.drill_sweeps(t, (0.25, 0, 0), steps=90, step_degrees=4, feed_per_turn=1.0, symmetry=False)
    assert (ds.period, direct.period, len(ds), ds.skipped) == (45, 90, 90, direct.skipped)
    assert all(ds.steps[k] is ds.steps[k - 45] for k in range(45, 90))
    poses = sweep.drill_poses((0.25, 0, 0), steps=90, step_degrees=4)

    def prism_set(hulls):
        return sorted(tuple(sorted(map(tuple, np.asarray(h.points).tolist()))) for h in hulls)

    for k in range(90):
        exact = (t.design_vertices() @ poses[k].rotation.T + poses[k].position - grid.origin) * grid.scale
        assert np.abs(ds.poses[k] - exact).max() <= 0.5 + 1e-9
        assert prism_set(ds.steps[k]) == prism_set(direct.steps[k])
    # a turn that is not a whole number of steps: every step posed
    assert sweep.drill_sweeps(t, steps=30, step_degrees=7).period == 30
    with pytest.raises(GeometryError, match="period"):
        sweep.DrillSweeps([ds.steps[0], ds.steps[1]], ds.feed, 0, period=1)
