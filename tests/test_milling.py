"""Milling simulation: exact removed volumes, collisions, checkpoints, STL -- on the octree workpiece and on the
single-BSP reference workpiece, which must agree exactly.

The reference for straight cuts of a flat end mill is independent of the hull and BSP code:
a plunge removes area(P) x depth, a horizontal move then removes width(P across the move) x
depth more, where P is the tool's grid polygon (shoelace area and projections with Python
ints). Volumes are in mm³ as exact Fractions (the grid scale is a power of two). The
per-move volumes on the octree are measured locally (:mod:`csgnb.octree.volume`); tests here
check them against whole-workpiece volumes and against the reference engine.
"""

from __future__ import annotations

import json
from collections import Counter
from fractions import Fraction

import numpy as np
import pytest

from csgnb import GeometryError
from csgnb.apps import gcode, milling, sweep, tools
from csgnb.apps.reference import BSPWorkpiece
from csgnb.exact import Grid
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Workpiece
from tests.test_apps_sweep import polygon_area2

SCALE = 32
GRID = Grid.from_resolution(1 / SCALE)
STOCK = ((0, 0, -10), (40, 30, 0))

SLOTS = """G21 G90 G17
G0 Z5
G0 X8 Y8
M3 S10000
G1 Z-2 F100
G1 X30 F300
G0 Z5
G0 X10 Y22
G1 Z-3 F100
G1 X25 Y18 F300
G0 Z5
M5
M30
"""


@pytest.fixture(scope="module")
def flat():
    return tools.flat_end_mill(4, 8, segments=10).on(GRID)


class Octree:
    """The octree workpiece with a small BSP threshold, so these small parts split and combine cells."""

    @staticmethod
    def box(lo, hi, *, grid):
        return Workpiece.box(lo, hi, grid=grid, threshold=24)

    load = staticmethod(Workpiece.load)


@pytest.fixture(params=[Octree, BSPWorkpiece], ids=["octree", "bsp"])
def W(request):
    """The workpiece class under test (both give the same exact numbers)."""
    return request.param


def width_across(tool, v) -> int:
    proj = [int(x) for x in tool.offsets[:, :2] @ np.array([-v[1], v[0]])]
    return max(proj) - min(proj)


def test_flat_end_mill_slots_remove_the_exact_prism_volumes(W, flat, tmp_path):
    w = W.box(*STOCK, grid=GRID)
    stock = w.model_volume()
    assert stock == 40 * 30 * 10
    result = milling.simulate(w, gcode.parse(SLOTS), flat, progress=False)
    area = Fraction(polygon_area2(flat.offsets[:, :2]), 2)  # grid units²
    g3 = Fraction(SCALE) ** 3

    def cut(x0, y0, x1, y1, depth):
        v = (np.array([x1, y1]) - [x0, y0]) * SCALE
        return area * depth * SCALE / g3, width_across(flat, v.astype(np.int64)) * depth * SCALE / g3

    p1, s1 = cut(8, 8, 30, 8, 2)
    p2, s2 = cut(10, 22, 25, 18, 3)
    removed = [r.removed for r in result.records]
    kinds = [r.kind for r in result.records]
    assert kinds == ["rapid", "rapid", "linear", "linear", "rapid", "rapid", "linear", "linear", "rapid"]
    assert removed == [0, 0, p1, s1, 0, 0, p2, s2, 0]
    assert result.removed == p1 + s1 + p2 + s2
    assert stock - result.removed == w.model_volume()  # the exact identity
    assert not result.collisions
    # Cut time from the feed: the plunge is 7 mm at 100 mm/min.
    assert result.records[2].time_s == pytest.approx(60 * 7 / 100)
    assert result.records[3].time_s == pytest.approx(60 * 22 / 300)
    assert "stock - removed == part: True" in result.table()
    assert w.surface().is_closed()
    # STL through meshio: a closed triangle mesh whose float volume is the exact one, rounded.
    import meshio

    report = milling.export_stl(w, tmp_path / "part.stl")
    assert report.closed and report.watertight and report.dropped == 0
    assert report.volume == pytest.approx(float(w.model_volume()), rel=1e-6)
    m = meshio.read(report.path)
    assert len(m.cells_dict["triangle"]) == report.triangles == len(w.to_mesh(manifold=True)[1])
    V, T = m.points.astype(float), m.cells_dict["triangle"]
    V, inv = np.unique(V, axis=0, return_inverse=True)
    T = inv.reshape(-1)[T]
    use = Counter((int(a), int(b)) for t in T for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])))
    assert all(use[(b, a)] == n for (a, b), n in use.items())
    vol = np.sum(np.einsum("ij,ij->i", V[T[:, 0]], np.cross(V[T[:, 1]], V[T[:, 2]]))) / 6
    assert vol == pytest.approx(float(w.model_volume()), rel=1e-6)


def test_rapid_through_the_stock_is_a_collision_and_above_it_is_not(W, flat):
    program = gcode.parse("""G0 Z5
G0 X10 Y10
G0 Z-2
G0 Z5
G0 X30 Y20
G0 X35 Y25 Z0.5
M5
G1 X35 Y5 Z-1 F200
""")
    w = W.box(*STOCK, grid=GRID)
    result = milling.simulate(w, program, flat, progress=False)
    hits = {r.line: r.collision for r in result.collisions}
    assert hits == {3: "rapid move (G0) cuts material", 8: "cut with the spindle stopped"}
    assert [r.removed > 0 for r in result.records] == [False, False, True, False, False, False, True]
    assert "line 3: rapid move (G0) cuts material" in result.table()


def test_ball_end_mill_arcs_keep_the_volume_identity(W):
    ball = tools.ball_end_mill(3, 6, segments=8, rings=2).on(GRID)
    program = gcode.parse("""G0 X20 Y15 Z2
M3
G1 Z-1 F100
G2 X20 Y15 I-5 J0 F400
G18 G3 X10 Z-1 R5
""", start=(20, 15, 5))
    w = W.box(*STOCK, grid=GRID)
    result = milling.simulate(w, program, ball, progress=False, chord_tolerance=0.5)
    full_circle, zx_arc = result.records[2], result.records[3]
    assert full_circle.pieces == gcode.Arc.points(program[2], 0.5).shape[0] - 1
    assert full_circle.removed > 0 and zx_arc.removed > 0
    assert result.stock_volume - result.removed == w.model_volume()


def test_non_convex_tool_moves_subtract_prisms_and_the_end_pose(W):
    gear = tools.spur_gear(teeth=5, module=1, thickness=1, flank_points=2).on(GRID)
    assert not gear.convex
    w = W.box((0, 0, -3), (8, 8, 0), grid=GRID)
    program = gcode.parse("M3\nG1 X4 Y4 Z-1 F100\nG1 X5 F100\n", start=(4, 4, -1))
    result = milling.simulate(w, program, gear, progress=False)
    r = result.records[-1]
    assert r.pieces > 1 and r.removed > 0
    assert result.stock_volume - result.removed == w.model_volume()


def test_checkpoints_resume_after_a_crash_with_an_identical_result(W, flat, tmp_path):
    program = gcode.parse(SLOTS)
    ref = milling.simulate(W.box(*STOCK, grid=GRID), program, flat, progress=False)

    class Crash(Exception):
        pass

    def crash_at_7(rec, wp):
        if rec.index == 6:
            raise Crash

    ckpt = tmp_path / "run.ckpt"
    with pytest.raises(Crash):
        milling.simulate(W.box(*STOCK, grid=GRID), program, flat, progress=False, checkpoint=ckpt,
                         checkpoint_every=3, on_move=crash_at_7)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.ckpt", "run.ckpt.6.wp"]
    seen = []
    resumed = milling.simulate(W.box(*STOCK, grid=GRID), program, flat, progress=False,
                               checkpoint=ckpt, checkpoint_every=3, on_move=lambda r, w: seen.append(r.index))
    assert seen == [6, 7, 8]
    assert [(r.line, r.removed, r.collision) for r in resumed.records] == \
        [(r.line, r.removed, r.collision) for r in ref.records]
    assert resumed.workpiece.volume() == ref.workpiece.volume()
    other = gcode.parse(SLOTS.replace("X30", "X31"))
    with pytest.raises(ValueError, match="another program"):
        milling.simulate(W.box(*STOCK, grid=GRID), other, flat, progress=False, checkpoint=ckpt)


def test_tools_on_another_grid_and_bad_tools_are_refused(W, flat):
    w = W.box(*STOCK, grid=GRID)
    other = tools.flat_end_mill(4, 8, segments=10).on(Grid.from_resolution(1 / 16))
    with pytest.raises(GeometryError, match="one grid|workpiece.grid"):
        milling.simulate(w, gcode.parse("G0 X1"), other, progress=False)
    with pytest.raises(GeometryError, match="one grid"):
        w.difference(other.hull_at((0, 0, 0)))
    with pytest.raises(GeometryError, match="one grid"):
        w.difference(other.hull_at((0, 0, 0)), track_volume=True)
    with pytest.raises(TypeError):
        w.difference(np.zeros((3, 3)))
    with pytest.raises(TypeError, match="quantize"):
        w.difference((flat.offsets.astype(float), flat.faces), track_volume=True)
    with pytest.raises(GeometryError, match="no tool 2"):
        milling.simulate(w, gcode.parse("T2 M6\nG0 X1"), {1: flat}, progress=False)
    assert w.model_volume() == 40 * 30 * 10


@pytest.mark.parametrize("cls", [Workpiece, BSPWorkpiece], ids=["octree", "bsp"])
def test_workpiece_booleans_return_exact_volume_changes(cls):
    g = Grid.from_resolution(1.0)
    w = cls.empty(g)
    meter = _Measured(w)
    assert w.volume() == 0
    a = convex_hull(np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, 4]]), grid=g)
    b = convex_hull(np.array([[10, 0, 0], [12, 0, 0], [10, 3, 0], [10, 0, 6], [12, 3, 6]]), grid=g)
    assert meter.union(a)[0] == a.volume() == Fraction(64, 6)
    assert meter.union(b)[0] == b.volume()
    assert meter.union(a)[0] == 0
    box = convex_hull(np.array([[x, y, z] for x in (-1, 5) for y in (-1, 5) for z in (-1, 5)]), grid=g)
    assert w.intersection(box, track_volume=True).volume_change == -b.volume()
    assert w.volume() == a.volume()
    assert meter.difference(a)[0] == a.volume() and w.volume() == 0
    assert w.surface().n_polygons == 0


class _Measured:
    """``op(tool) -> (exact change, report)`` through ``track_volume=True``: removed volume for a difference."""

    def __init__(self, w):
        self.w = w

    def difference(self, tool):
        report = self.w.difference(tool, track_volume=True)
        return -report.volume_change, report

    def union(self, tool):
        report = self.w.union(tool, track_volume=True)
        return report.volume_change, report


def tetra(a, s):
    a = np.asarray(a)
    return (np.array([a, a + [s, 0, 0], a + [0, s, 0], a + [0, 0, s]]),
            np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))


@pytest.mark.parametrize("threshold", [12, 40])
def test_tracked_changes_equal_whole_volume_differences_through_splits_and_combines(threshold):
    """Random hulls and meshes cut and filled back: every measured change is the exact difference of the
    whole workpiece's volumes, and the reference engine measures the same numbers."""
    rng = np.random.default_rng(threshold)
    g = Grid.from_resolution(1.0)
    w = Workpiece.box([0, 0, 0], [32, 32, 32], grid=g, threshold=threshold)
    ref = BSPWorkpiece.box([0, 0, 0], [32, 32, 32], grid=g)
    meter, ref_meter = _Measured(w), _Measured(ref)
    before = w.volume()
    ops = []
    for i in range(14):
        if i % 5 == 4:  # a non-convex tool as a mesh
            tool = tetra(rng.integers(0, 24, size=3), int(rng.integers(6, 12)))
        else:
            tool = convex_hull(rng.integers(0, 32, size=3) + rng.integers(-6, 7, size=(9, 3)), grid=g)
        ops.append(("difference", tool))
    ops.append(("union", convex_hull(np.array([[x, y, z] for x in (0, 32) for y in (0, 16) for z in (0, 32)]),
                                     grid=g)))
    for op, tool in ops:
        change, report = getattr(meter, op)(tool)
        after = w.volume()
        assert change == (before - after if op == "difference" else after - before)
        assert getattr(ref_meter, op)(tool)[0] == change
        before = after
    assert w.stats.splits > 0 and w.stats.combines > 0
    assert w.volume() == ref.volume()
    # Booleans measured by no one (here a plain one) do not fool the cache.
    w -= convex_hull(np.array([[4, 20, 4], [20, 20, 4], [4, 30, 4], [4, 20, 20]]), grid=g)
    v = w.volume()
    cut = convex_hull(np.array([[2, 2, 2], [30, 4, 2], [4, 30, 6], [6, 6, 30]]), grid=g)
    assert meter.difference(cut)[0] == v - w.volume()


def test_save_and_load_are_bit_exact_and_refuse_damaged_files(flat, tmp_path, monkeypatch):
    w = BSPWorkpiece.box(*STOCK, grid=GRID)
    w.difference(sweep.straight_sweep(flat, (5, 5, -1), (20, 12, -1)).hulls[0])
    path = tmp_path / "w.npz"
    w.save(path)
    back = BSPWorkpiece.load(path)
    assert back.grid == w.grid and back.volume() == w.volume()
    for name in ("plane", "neg", "pos", "label"):
        assert np.array_equal(getattr(back.bsp.tree, name), getattr(w.bsp.tree, name))
    assert back.bsp.tree.palette.tobytes() == w.bsp.tree.palette.tobytes()
    data = path.read_bytes()
    (tmp_path / "short.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="truncated or corrupted"):
        BSPWorkpiece.load(tmp_path / "short.npz")
    # Damage the palette's bytes: the zip's own CRC or our checksum catches it.
    raw = bytearray(data)
    k = raw.find(b"limbs.npy")
    raw[k + 200] ^= 0xFF
    (tmp_path / "bad.npz").write_bytes(bytes(raw))
    with pytest.raises(ValueError):
        BSPWorkpiece.load(tmp_path / "bad.npz")

    # A save interrupted half-way leaves the previous file intact and no temporary behind.
    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(np.lib.format, "write_array", boom)
    w.difference(sweep.straight_sweep(flat, (30, 20, -1), (35, 20, -1)).hulls[0])
    with pytest.raises(KeyboardInterrupt):
        w.save(path)
    assert path.read_bytes() == data
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.npz", "short.npz", "w.npz"]


def test_a_ball_mill_cut_matches_an_independent_halfspace_intersection(W):
    """The first cut of a tilted ball-mill move is vol(hull ∩ stock), a convex polytope: scipy's float64
    halfspace intersection (qhull, independent of csgnb) agrees with the exact volume to float rounding."""
    from scipy.spatial import ConvexHull as Qhull
    from scipy.spatial import HalfspaceIntersection

    ball = tools.ball_end_mill(4, 10, segments=16, rings=4).on(GRID)
    rng = np.random.default_rng(4)
    for _ in range(4):
        a = np.r_[rng.uniform(5, 35), rng.uniform(5, 25), 3.0]
        b = np.r_[rng.uniform(5, 35), rng.uniform(5, 25), rng.uniform(-4, -1)]
        w = W.box(*STOCK, grid=GRID)
        (hull,) = sweep.straight_sweep(ball, a, b).hulls
        removed, _ = _Measured(w).difference(hull)
        g = GRID.to_grid(np.array(STOCK, float)).astype(float)
        box = np.array([[-1, 0, 0, g[0, 0]], [1, 0, 0, -g[1, 0]], [0, -1, 0, g[0, 1]], [0, 1, 0, -g[1, 1]],
                        [0, 0, -1, g[0, 2]], [0, 0, 1, -g[1, 2]]])
        H = np.vstack([hull.planes.astype(float), box])
        tip = GRID.to_grid([b])[0].astype(float) + [0, 0, 0.5 * SCALE]  # inside the ball at the end, below the top
        assert np.all(H[:, :3] @ tip + H[:, 3] < 0)
        reference = Qhull(HalfspaceIntersection(H, tip).intersections).volume
        assert float(removed) == pytest.approx(reference, rel=1e-9)


BALL_ARCS = """G0 X12 Y10 Z2
M3
G1 Z-1.5 F100
G2 X12 Y10 I-4 J0 F400
G18 G3 X6 Z-1 R4
"""
GEAR_MOVES = """G17 T2 M6
G0 Z2
G0 X20 Y20 Z1
G1 Z-1 F100
G1 X23 Y21 F100
"""


@pytest.mark.parametrize("text, chord_tolerance", [pytest.param(BALL_ARCS + GEAR_MOVES, 0.5, marks=pytest.mark.slow),
                                                   (BALL_ARCS, 1.5)], ids=["ball-and-gear", "ball"])
def test_octree_and_reference_agree_move_for_move(text, chord_tolerance):
    """A ball end mill (arcs in two planes) and (slow) a non-convex gear: the same exact volume for every move.
    (The gear's prisms cost the single-BSP reference seconds each move; tests above cover it on small cuts.)"""
    ball = tools.ball_end_mill(3, 6, segments=8, rings=2).on(GRID)
    gear = tools.spur_gear(teeth=5, module=1, thickness=1, flank_points=2).on(GRID)
    program = gcode.parse(text, start=(12, 10, 5))
    results = []
    for cls in (Octree, BSPWorkpiece):
        w = cls.box(*STOCK, grid=GRID)
        results.append(milling.simulate(w, program, {None: ball, 2: gear}, progress=False,
                                        chord_tolerance=chord_tolerance))
    octree, ref = results
    assert [r.removed for r in octree.records] == [r.removed for r in ref.records]
    assert sum(r.removed > 0 for r in octree.records) >= 3
    assert octree.workpiece.volume() == ref.workpiece.volume()
    assert octree.workpiece.surface().is_closed()


def test_exact_values_of_any_size_survive_checkpoints_and_summaries():
    """A long job's exact volumes have denominators of 10^4+ digits; Python refuses to convert such ints to
    decimal text (4,300 digits), which made a 1,153-move job fail at its end with no STL and no JSON."""
    from csgnb.apps.milling import MillingResult, MoveRecord, _record_from_json, _record_json, summary_table

    huge = Fraction(7, 3**20000)
    rec = MoveRecord(0, 1, "linear", None, 1.0, 0.1, huge, 1, None, 0.01)
    back = _record_from_json(json.loads(json.dumps(_record_json(rec))))
    assert back.removed == huge and back == rec

    class _Part:
        grid = Grid.from_resolution(1.0)

        def volume(self):
            return Fraction(10**6) - huge

    table = summary_table(MillingResult(_Part(), [rec], Fraction(10**6)))
    assert "stock - removed == part: True" in table and "digits" in table


def test_a_failing_run_keeps_the_moves_done(W, flat, monkeypatch):
    program = gcode.parse("G0 X5 Y5 Z5\nG1 Z-1 F100\nG1 X20\nG1 Y20\nG1 X5")
    w = W.box(*STOCK, grid=GRID)
    calls = {"n": 0}
    original = type(w).difference

    def failing(self, tool, **kw):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("disk full")
        return original(self, tool, **kw)

    monkeypatch.setattr(type(w), "difference", failing)
    with pytest.raises(RuntimeError, match="disk full") as info:
        milling.simulate(w, program, flat, progress=False)
    partial = info.value.partial_result
    assert 0 < len(partial.records) < len(program.moves)
    assert any("partial_result" in note for note in info.value.__notes__)
