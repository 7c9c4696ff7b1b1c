"""The octree workpiece against independent references: voxel counts, one-BSP results, exact volumes."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgnb.bsp import BSP
from csgnb.errors import GeometryError, PrecisionError
from csgnb.exact import Grid, to_wide
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Tool, Workpiece
from csgnb.octree.persist import WorkpieceFileError

OPS = ("difference", "union", "intersection")
SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def box_hull(lo, hi):
    lo, hi = np.asarray(lo), np.asarray(hi)
    return convex_hull(np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)]))


def voxel_oracle(ops, size):
    """The same sequence on a boolean voxel grid (unit voxels of the box [0, size]^3)."""
    solid = np.zeros((size,) * 3, bool)
    for op, lo, hi in ops:
        tool = np.zeros_like(solid)
        tool[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = True
        solid = {"difference": solid & ~tool, "union": solid | tool, "intersection": solid & tool}[op]
    return solid


box_strategy = st.tuples(st.lists(st.integers(0, 15), min_size=3, max_size=3),
                         st.lists(st.integers(1, 9), min_size=3, max_size=3)).map(
    lambda t: (t[0], [min(16, a + b) for a, b in zip(t[0], t[1], strict=True)]))


@SETTINGS
@given(st.lists(st.tuples(st.sampled_from(OPS), box_strategy), min_size=1, max_size=7),
       st.sampled_from([16, 40]))
def test_box_sequences_match_voxel_counts(ops, threshold):
    w = Workpiece.box([0, 0, 0], [16, 16, 16], threshold=threshold)
    seq = [("union", [0, 0, 0], [16, 16, 16])]
    for op, (lo, hi) in ops:
        getattr(w, op)(box_hull(lo, hi))
        seq.append((op, lo, hi))
    solid = voxel_oracle(seq, 16)
    assert w.volume() == int(solid.sum())
    # every voxel centre classifies like the oracle: homogeneous (2i + 1, 2j + 1, 2k + 1, 2)
    idx = np.argwhere(np.ones_like(solid))
    pts = to_wide(np.column_stack([2 * idx + 1, np.full(len(idx), 2)]), 128)
    labels = w.classify(pts)
    assert np.array_equal(labels, solid[tuple(idx.T)].astype(labels.dtype))


def random_hull(rng, centre, radius):
    return convex_hull(centre + rng.integers(-radius, radius + 1, size=(9, 3)))


@pytest.mark.parametrize("seed", range(4))
def test_hull_sequences_match_one_bsp(seed):
    """Random convex hulls, coplanar and touching cases included (coarse integer lattice)."""
    rng = np.random.default_rng(seed)
    w = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    ref = BSP.box([0, 0, 0], [40, 40, 40])
    for _ in range(10):
        h = random_hull(rng, rng.integers(0, 40, size=3) // 4 * 4, int(rng.integers(2, 5)) * 3)
        op = OPS[int(rng.integers(0, 3))] if rng.random() < 0.2 else OPS[int(rng.integers(0, 2))]
        getattr(w, op)(h)
        ref = getattr(ref, op)(BSP(h.to_bsp().tree, [-60] * 3, [100] * 3))
    assert w.volume() == ref.volume()
    pts = rng.integers(-20, 180, size=(3000, 3))
    X = to_wide(np.column_stack([pts, np.full(len(pts), 3)]), 128)
    assert np.array_equal(w.classify(X), ref.tree.classify(X))


def test_surface_is_closed_conforming_and_measures_the_volume():
    rng = np.random.default_rng(7)
    w = Workpiece.box([0, 0, 0], [32, 32, 32], threshold=20)
    for _ in range(6):
        w -= random_hull(rng, rng.integers(0, 32, size=3), 7)
    s = w.surface()
    assert s.is_closed()
    assert s.exact_volume() == w.volume()
    assert w.n_cells > 8  # the threshold split cells: faces cross cell walls



def test_exports_in_model_units_and_the_manifold_option(tmp_path):
    import meshio

    grid = Grid.fit([-4, -4, -4], [4, 4, 4], width=128)
    w = Workpiece.box([-2, -2, -2], [2, 2, 2], grid=grid, threshold=20)
    # two boxes that touch the block's corner region along an edge: edges shared by four faces
    w -= convex_hull(grid.to_grid(np.array([[0, 0, -3], [3, 0, -3], [0, 3, -3], [3, 3, -3],
                                            [0, 0, 3], [3, 0, 3], [0, 3, 3], [3, 3, 3]], float)))
    w -= convex_hull(grid.to_grid(np.array([[-3, -3, -3], [0, -3, -3], [-3, 0, -3], [0, 0, -3],
                                            [-3, -3, 3], [0, -3, 3], [-3, 0, 3], [0, 0, 3]], float)))
    vertices, triangles = w.to_mesh()
    assert vertices.min() >= -2 and vertices.max() <= 2  # model units, not grid units
    signed = np.einsum("ij,ij->i", vertices[triangles[:, 0]],
                       np.cross(vertices[triangles[:, 1]], vertices[triangles[:, 2]])).sum() / 6
    assert abs(signed - float(w.model_volume())) < 1e-9 * float(w.model_volume())  # outward, closed
    v2, t2 = w.to_mesh(manifold=True)
    edges = np.sort(np.concatenate([t2[:, [0, 1]], t2[:, [1, 2]], t2[:, [2, 0]]]), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert np.all(uses == 2) and len(v2) > len(vertices)  # every edge has two faces; the shared edge was split
    path = w.save_mesh(tmp_path / "part.stl")
    back = meshio.read(path)
    assert back.cells_dict["triangle"].shape == triangles.shape
    assert w.to_polydata().n_cells == triangles.shape[0]

def test_split_then_combine_keeps_every_point():
    rng = np.random.default_rng(3)
    w = Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)
    for _ in range(5):
        w -= random_hull(rng, rng.integers(4, 20, size=3), 5)
    assert w.stats.splits > 0
    pts = rng.integers(-10, 80, size=(2000, 3))
    X = to_wide(np.column_stack([pts, np.full(len(pts), 3)]), 128)
    before = w.classify(X)
    vol = w.volume()
    # filling the holes back: cells become uniform and combine
    w |= box_hull([0, 0, 0], [24, 24, 24])
    assert w.volume() == 24**3
    assert w.stats.combines > 0
    # and cutting the same holes again gives the same solid
    rng = np.random.default_rng(3)
    for _ in range(5):
        w -= random_hull(rng, rng.integers(4, 20, size=3), 5)
    assert w.volume() == vol
    assert np.array_equal(w.classify(X), before)
    cells = w.cells()
    big = cells["nodes"] > w.threshold
    assert np.all(cells["size"][big] <= w.min_cell) or not big.any()


def tetra_mesh(a, s):
    a = np.asarray(a)
    V = np.array([a, a + [s, 0, 0], a + [0, s, 0], a + [0, 0, s]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return V, F


def test_mesh_and_bsp_tools_match_the_convex_tool():
    V, F = tetra_mesh([2, 3, 1], 14)
    hull = convex_hull(V)
    results = []
    for tool in (hull, (V, F), Tool.from_mesh(V, F, width=128), BSP(hull.to_bsp().tree, [-5] * 3, [30] * 3)):
        w = Workpiece.box([0, 0, 0], [12, 12, 12], threshold=16)
        w -= tool
        results.append(w.volume())
    assert len(set(results)) == 1
    assert results[0] == 12**3 - (BSP.box([0, 0, 0], [12, 12, 12]) & BSP(hull.to_bsp().tree, [-5] * 3, [30] * 3)
                                  ).volume()


@pytest.mark.parametrize("seed", range(3))
def test_finely_faceted_mesh_tools_match_the_convex_tool(seed):
    """A mesh tool of ~600 small facets over a workpiece of small cells: most facets lie strictly inside a cell
    they reach (copied whole, without the six wall splits) and the others are clipped; the result is the same
    solid as the hull used as a convex tool (volume, and every sampled point)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(600, 3))
    points = np.rint(d / np.linalg.norm(d, axis=1)[:, None] * 90).astype(np.int64) + rng.integers(60, 68, size=3)
    hull = convex_hull(points)
    V, F = hull.to_mesh()
    tool = Tool.from_mesh(V, F, width=128)
    a = Workpiece.box([0, 0, 0], [128, 128, 128], threshold=24)
    b = Workpiece.box([0, 0, 0], [128, 128, 128], threshold=24)
    a -= tool
    b -= hull
    assert a.volume() == b.volume()
    pts = rng.integers(-4, 260, size=(4000, 3))
    X = to_wide(np.column_stack([pts, np.full(len(pts), 2)]), 128)
    assert np.array_equal(a.classify(X), b.classify(X))


def test_translated_tools_are_exact():
    V, F = tetra_mesh([0, 0, 0], 6)
    tool = Tool.from_mesh(V, F, width=128)
    w1 = Workpiece.box([0, 0, 0], [20, 20, 20], threshold=16)
    w2 = Workpiece.box([0, 0, 0], [20, 20, 20], threshold=16)
    for t in ([3, 3, 3], [10, 4, 2], [5, 12, 9]):
        w1 -= tool.translated(np.array(t))
        w2 -= (V + t, F)
    assert w1.volume() == w2.volume() == 8000 - 3 * 36


def test_volume_tracking_reports_the_exact_change():
    w = Workpiece.box([0, 0, 0], [10, 10, 10])
    r = w.difference(box_hull([5, 5, 5], [15, 15, 15]), track_volume=True)
    assert r.removed == 125
    r = w.union(convex_hull([[10, 0, 0], [14, 0, 0], [10, 4, 0], [10, 0, 4]]), track_volume=True)
    assert r.volume_change == Fraction(64, 6)


def test_save_load_round_trip_and_interrupted_saves(tmp_path):
    rng = np.random.default_rng(5)
    w = Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)
    for _ in range(4):
        w -= random_hull(rng, rng.integers(0, 24, size=3), 6)
    path = tmp_path / "w.npz"
    w.save(path)
    r = Workpiece.load(path)
    for name, value in w._arrays().items():
        assert np.array_equal(value, r._arrays()[name]), name
    assert r.volume() == w.volume()
    # an interrupted save leaves the previous file loadable
    from csgnb.octree import persist

    w -= random_hull(rng, [12, 12, 12], 6)
    for limit in (0, 100, 5000):
        with pytest.raises(KeyboardInterrupt):
            persist.write_arrays(path, {}, w._arrays(), _fail_after=limit)
        assert Workpiece.load(path).volume() == r.volume()
    assert not list(tmp_path.glob("*.tmp"))
    # a truncated or corrupted file is a clear error
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(WorkpieceFileError):
        Workpiece.load(tmp_path / "cut.npz")
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0xFF
    (tmp_path / "bad.npz").write_bytes(bytes(bad))
    with pytest.raises(WorkpieceFileError):
        Workpiece.load(tmp_path / "bad.npz")


def test_a_resumed_run_equals_an_uninterrupted_one(tmp_path):
    rng = np.random.default_rng(11)
    tools = [random_hull(rng, rng.integers(0, 24, size=3), 5) for _ in range(9)]
    whole = Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)
    whole.run(tools, "difference")
    path = tmp_path / "ck.npz"
    crashed = Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)
    crashed.run(tools[:5], "difference", checkpoint=path, checkpoint_every=2)  # "crashes" after 5
    resumed = Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)
    resumed.run(tools, "difference", checkpoint=path, checkpoint_every=2)
    assert resumed.volume() == whole.volume()
    for name, value in whole._arrays().items():
        if name != "oc_counts":
            assert np.array_equal(value, resumed._arrays()[name]), name


def test_bad_tools_are_clear_errors_and_leave_the_workpiece_unchanged():
    w = Workpiece.box([0, 0, 0], [10, 10, 10])
    before = w._arrays()
    V, F = tetra_mesh([0, 0, 0], 5)
    CV, CF = box_hull([1, 1, 1], [4, 4, 4]).to_mesh()
    with pytest.raises(GeometryError, match="open"):
        w -= (CV, CF[1:])
    with pytest.raises(TypeError, match="quantize"):
        w -= (V.astype(float), F)
    other = Grid.from_resolution(0.5, width=128)
    h = convex_hull(V, grid=other)
    with pytest.raises(GeometryError, match="grid"):
        w -= h
    with pytest.raises(PrecisionError):
        w -= box_hull([0, 0, 0], [5000, 10, 10])
    with pytest.raises(TypeError, match="ConvexHull"):
        w -= 5
    after = w._arrays()
    for name in before:
        assert np.array_equal(before[name], after[name]), name


def test_a_boolean_within_a_box_is_right_in_the_box_and_refuses_what_it_cannot_do():
    """``within=``: the cells meeting the box take the Boolean (labels there equal a full workpiece's), cells
    far outside keep the old solid; with ``track_volume`` or a bad box it refuses."""
    tool = convex_hull(np.array([[-6, -6, -6], [9, -6, -6], [-6, 9, -6], [-6, -6, 9]]))
    full, part = Workpiece.box([-8, -8, -8], [8, 8, 8], threshold=8), Workpiece.box([-8, -8, -8], [8, 8, 8],
                                                                                    threshold=8)
    rng = np.random.default_rng(3)
    for _ in range(30):  # small cuts all over: the octree splits into small cells
        c = rng.integers(-7, 7, 3)
        chip = convex_hull(c + np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]]))
        full.difference(chip)
        part.difference(chip)
    full.difference(tool)
    part.difference(tool, within=([0, 0, 0], [8, 8, 8]))
    r = np.arange(0, 9)
    inside = np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)
    assert part.classify(inside).tolist() == full.classify(inside).tolist()
    far_points = np.array([[-5, -5, -5], [-4, -5, -5], [-5, -4, -5], [-5, -5, -4], [-4, -4, -5]])
    assert part.classify(far_points).tolist() != full.classify(far_points).tolist()  # left behind out there
    with pytest.raises(GeometryError, match="track_volume"):
        part.difference(tool, within=([0, 0, 0], [8, 8, 8]), track_volume=True)
    with pytest.raises(GeometryError, match="lo <= hi"):
        part.difference(tool, within=([0, 0, 0], [-1, 8, 8]))
    before = part.volume()
    far = convex_hull(np.array([[-7, -7, -7], [-5, -7, -7], [-7, -5, -7], [-7, -7, -5]]))
    part.difference(far, within=([0, 0, 0], [8, 8, 8]))  # the tool's box misses the box: nothing changes
    assert part.volume() == before


@pytest.mark.parametrize("op", ["union_into_empty", "intersect_box"])
def test_first_cell_larger_than_the_empty_pool(op):
    """A many-faceted hull (553 facets) written into a workpiece whose BSP pool is still empty: the pool must grow
    (it used to be asked for room again and again, 100 times, and end in an InternalError)."""
    k = np.arange(313)
    z = 1 - 2 * (k + 0.5) / 313
    phi = k * np.pi * (3 - 5**0.5)
    pts = np.rint(400 * np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], 1))
    hull = convex_hull(pts.astype(np.int64), width=128)
    assert hull.planes.shape[0] > 500
    if op == "union_into_empty":
        w = Workpiece.empty(width=128)
        w |= hull
    else:
        w = Workpiece.box([-500] * 3, [500] * 3, width=128)
        w &= hull
    assert w.volume() == hull.volume()


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.integers(1, 40))
def test_combine_order_is_numpys(seed, n_leaves, n_nodes):
    """The compiled combine order (an insertion sort) equals the NumPy expression it replaced: distinct parents >= 0,
    smallest cell first, equal sizes by the larger index first -- with repeated parents, roots (-1) and ties; beyond
    COMBINE_ORDER_LEAVES leaves the NumPy path runs, and gives the same."""
    from csgnb.octree import kernels as K
    from csgnb.octree.workpiece import _combine_order

    rng = np.random.default_rng(seed)
    parent = rng.integers(-1, n_nodes, n_nodes + 5).astype(np.int32)
    size = (2 ** rng.integers(0, 4, n_nodes + 5)).astype(np.int64)
    leaves = rng.integers(0, n_nodes + 5, n_leaves).astype(np.int64)
    p = np.unique(parent[leaves])
    p = p[p >= 0]
    expect = p[np.argsort(-size[p], kind="stable")[::-1]].tolist()
    if n_leaves <= K.COMBINE_ORDER_LEAVES:
        assert K.combine_order(parent, size, leaves).tolist() == expect
    Oc = type("Oc", (), {"parent": parent, "size": size})
    assert _combine_order(Oc, leaves).tolist() == expect


def test_convex_tool_tree_is_the_linear_bsp():
    """A convex tool's compiled linear BSP is csgnb.mesh.hull.linear_bsp_arrays over its palette rows."""
    from csgnb.mesh.hull import linear_bsp_arrays
    from csgnb.octree.tool import convex_tool_tree

    for k in (0, 1, 4, 37):
        rows = np.arange(100, 100 + k, dtype=np.int64)[::-1].copy()
        got = convex_tool_tree(rows)
        plane, neg, pos, label = linear_bsp_arrays(k)
        expect = np.where(plane >= 0, rows[np.maximum(plane, 0)], -1) if k else plane
        assert got[0].dtype == np.int32 and got[0].tolist() == expect.tolist()
        for a, b in zip(got[1:], (neg, pos, label), strict=True):
            assert a.dtype == np.int32 and a.tolist() == b.tolist()


def test_int64_planes_are_stored_as_to_wide_stores_them():
    """store_int64_rows writes int64 planes into a palette as to_wide converts them (sign extension at 128,
    192 and 256 bits, the int64 extremes included); the hull's compiled global planes are the exact n, d - n·o."""
    from csgnb.exact.wide import wide_dtype
    from csgnb.octree.tool import store_int64_rows

    rng = np.random.default_rng(2)
    values = rng.integers(-(1 << 62), 1 << 62, (9, 4))
    values[0, 0], values[1, 1] = np.iinfo(np.int64).min, np.iinfo(np.int64).max
    for width in (128, 192, 256):
        palette = np.zeros((20, 4), wide_dtype(width))
        store_int64_rows(palette, 3, values)
        assert palette[3:12].tobytes() == to_wide(values, width).tobytes()
        assert not palette[:3]["limbs"].any() and not palette[12:]["limbs"].any()
    h = convex_hull(rng.integers(-50, 51, (40, 3)) + [10**6, -(10**5), 7], width=256)
    exact = [[int(a), int(b), int(c), int(e) - sum(int(x) * int(y) for x, y in zip((a, b, c), h._origin, strict=True))]
             for (a, b, c), e in zip(h._normals, h._d_local, strict=True)]
    assert h.planes.dtype == np.int64 and h.planes.tolist() == exact


def test_translated_mesh_tools_reuse_their_sources_boxes():
    """A mesh tool's polygon boxes (one reduction per polygon) are the per-vertex minima and maxima, floored/ceiled
    and grown by one; a translated tool takes its source's boxes moved by the translation, which hold its exact
    vertices; subtracting it gives the workpiece that recomputed boxes give, and a pickled tool leaves its source
    behind."""
    import pickle

    from csgnb.exact.predicates import to_double_position
    from csgnb.exact.wide import from_wide
    from csgnb.octree.workpiece import _polygon_geometry

    tool = Tool.from_bsp(BSP.box([0, 0, 0], [6, 4, 4]) | BSP.box([2, 2, 2], [5, 9, 7]))  # an L-shaped mesh tool
    verts, plo, phi = _polygon_geometry(tool, 128)
    pos = to_double_position(verts)
    owner = np.repeat(np.arange(len(tool.polygons)), tool.polygons.sizes)
    lo, hi = np.full_like(pos[: len(tool.polygons)], np.inf), np.full_like(pos[: len(tool.polygons)], -np.inf)
    np.minimum.at(lo, owner, pos)
    np.maximum.at(hi, owner, pos)
    assert plo.tolist() == (np.floor(lo) - 1).astype(np.int64).tolist()
    assert phi.tolist() == (np.ceil(hi) + 1).astype(np.int64).tolist()
    t = np.array([3, -2, 1])
    moved = tool.translated(t).translated(t)
    mverts, mlo, mhi = _polygon_geometry(moved, 128)
    assert mlo.tolist() == (plo + 2 * t).tolist() and mhi.tolist() == (phi + 2 * t).tolist()
    exact = [[Fraction(int(x), int(v[3])) for x in v[:3]] for v in from_wide(mverts).reshape(-1, 4)]
    owner_m = np.repeat(np.arange(len(moved.polygons)), moved.polygons.sizes)
    assert all(mlo[o, c] <= p[c] <= mhi[o, c] for o, p in zip(owner_m, exact, strict=True) for c in range(3))
    fresh = pickle.loads(pickle.dumps(moved))  # no source: its boxes are computed from its own vertices
    assert "_moved_from" not in fresh.__dict__
    fresh._geometry = {}
    results = []
    for tl in (moved, fresh):
        w = Workpiece.box([-20, -20, -20], [20, 20, 20], threshold=60)
        w -= tl
        results.append((w.volume(), w.n_cells, w.n_bsp_nodes))
    assert results[0] == results[1]


def test_tools_moved_beyond_int64_take_their_sources_planes_and_vertices_moved(monkeypatch):
    """A mesh tool whose offsets are beyond int64 (a 256-bit drill's tools) makes its moved copies' (k, 4) Python
    ints only when asked: a copy's wide planes are the source's with d - n·t formed in a compiled loop, its budget
    extremes come from them, and its polygons' vertices are the source's moved by x + t·x4 -- each bit for bit what
    the Python-int planes and the three-plane intersections give; translating twice is translating by the sum; a
    workpiece cut by it equals one cut by the same tool sent through pickle (no source: every value made the old
    way: the same canonical arrays); and where the source's extremes could not promise the width, the Python ints
    are taken."""
    import pickle

    from csgnb.bsp.polygon import set_vertices_kernel
    from csgnb.exact.integral import max_abs
    from csgnb.octree.workpiece import _polygon_geometry, identity_grid

    width = 256
    # an oblique tetrahedron with a notch, near the 256-bit mesh budget (~2**26): normals ~2**48, offsets ~2**72
    V, F = tetra_mesh([0, 0, 0], 1 << 24)
    V = V + np.array([[0, 0, 0], [0, 3, 0], [0, 0, 5], [7, 0, 0]])
    notch = tetra_mesh([1 << 21, 1 << 21, -1], 1 << 22)
    tool = Tool.from_bsp(BSP.from_mesh(V, F, width=width) - BSP.from_mesh(*notch, width=width))
    assert tool.kind == "mesh" and max_abs(tool.planes[:, 3]) > (1 << 62)
    rng = np.random.default_rng(4)
    for trial in range(6):
        t = rng.integers(-(1 << 22), 1 << 22, 3)
        moved = tool.translated(t)
        assert "planes" not in moved.__dict__  # not made
        wide = moved.planes_wide(width)
        extremes = moved.plane_extremes(width)
        verts = _polygon_geometry(moved, width)[0]
        assert "planes" not in moved.__dict__
        planes = moved.planes  # made now, in Python ints
        assert np.array_equal(wide, to_wide(planes, width))
        assert extremes == (max_abs(planes[:, :3]), max_abs(planes[:, 3]))
        ref = np.empty_like(verts)
        set_vertices_kernel(wide, moved.polygons.support, moved.polygons.offsets, moved.polygons.edges, ref)
        assert np.array_equal(verts, ref)
        t2 = rng.integers(-(1 << 20), 1 << 20, 3)
        twice = moved.translated(t2) if trial % 2 else tool.translated(t2).translated(t)
        assert np.array_equal(twice.planes_wide(width), tool.translated(t + t2).planes_wide(width))
        assert twice.n_planes == tool.n_planes and np.array_equal(twice.planes, tool.translated(t + t2).planes)
    t = np.array([1 << 22, -(1 << 21), 3])
    results = []
    for tl in (tool.translated(t), pickle.loads(pickle.dumps(tool.translated(t)))):
        w = Workpiece.box(t + [1 << 20] * 3, t + [3 << 22] * 3, grid=identity_grid(width), threshold=60)
        w -= tl
        results.append((w.volume(), w.n_cells, w.n_bsp_nodes, w._arrays()))
    (volume, cells, nodes, arrays), (volume_p, cells_p, nodes_p, arrays_p) = results
    assert (volume, cells, nodes) == (volume_p, cells_p, nodes_p)
    assert 0 < volume < Fraction(((3 << 22) - (1 << 20)) ** 3)
    assert arrays.keys() == arrays_p.keys() and all(np.array_equal(arrays[k], arrays_p[k]) for k in arrays)
    # the source's extremes too large to promise the width: the Python-int planes, converted
    monkeypatch.setattr(Tool, "plane_extremes", lambda self, w: (1 << 200, 1 << 255))
    far = tool.translated(t)
    assert far._moved_wide(width) is None
    assert np.array_equal(far.planes_wide(width), to_wide(tool.translated(t).planes, width))


def _needles(grid, apex, n, seed):
    """Thin tetrahedra from one apex in random directions: n x 3 planes through one point."""
    rng = np.random.default_rng(seed)
    hulls = []
    for _ in range(n):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        pts = np.vstack([apex, apex + 6 * (u + 0.08 * rng.normal(size=(3, 3)))])
        hulls.append(convex_hull(grid.to_grid(pts), width=grid.width))
    return hulls


def test_a_stock_workpiece_stops_splitting_at_its_share_of_the_stock(tmp_path):
    """Where surfaces meet at one point no split separates them: cells of a workpiece made from a stock end at the
    stock's side over 2**STOCK_CELL_DEPTH instead of a chain of cells down to one grid unit; the solid is the same."""
    from csgnb.octree import STOCK_CELL_DEPTH

    grid = Grid.fit([-8] * 3, [8] * 3, width=128)
    needles = _needles(grid, np.array([0.3, 0.2, 0.1]), 80, seed=5)
    deep = Workpiece.box([-7] * 3, [7] * 3, grid=grid, min_cell=1)
    capped = Workpiece.box([-7] * 3, [7] * 3, grid=grid)
    side = int(np.ptp(grid.to_grid(np.array([[-7.0] * 3, [7.0] * 3])), axis=0).max())
    assert capped.min_cell == 1 << ((side >> STOCK_CELL_DEPTH).bit_length() - 1) > 1
    for h in needles:
        deep -= h
        capped -= h
    d, c = deep.cells(), capped.cells()
    assert d["size"].min() == 1  # the needles' apex made a chain of cells down to one grid unit
    assert c["size"].min() >= capped.min_cell  # the stock's workpiece stopped at its minimum cell
    assert capped.n_cells < deep.n_cells
    over = c["nodes"] > capped.threshold
    assert over.any() and np.all(c["size"][over] == capped.min_cell)  # left whole there, as min_cell promises
    assert capped.volume() == deep.volume()
    rng = np.random.default_rng(0)
    X = grid.to_grid(np.array([0.3, 0.2, 0.1]) + rng.normal(scale=0.05, size=(3000, 3)))
    assert np.array_equal(capped.classify(X), deep.classify(X))
    # the minimum cell is saved with the workpiece, and its cells over the threshold load
    capped.save(tmp_path / "capped.npz")
    r = Workpiece.load(tmp_path / "capped.npz")
    assert r.min_cell == capped.min_cell and r.volume() == capped.volume()
    # an explicit min_cell is kept; a workpiece made from a mesh gets its stock's default too
    assert Workpiece.box([-7] * 3, [7] * 3, grid=grid, min_cell=4).min_cell == 4
    V = np.array([[0, 0, 0], [4096, 0, 0], [0, 4096, 0], [0, 0, 4096]], np.int64)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    assert Workpiece.from_mesh(V, F).min_cell == 4096 >> STOCK_CELL_DEPTH


def test_largest_magnitudes_of_planes_are_exact_in_every_representation():
    """``max_abs`` (the budget check of a tool's planes): int64 at -2**63 (where |v| would wrap), Python
    ints that fit in int64 and ones that do not, negative and positive extremes."""
    from csgnb.exact.integral import max_abs

    cases = [[3, -7, 5], [-(1 << 63), 1, 2], [(1 << 63) - 1, -5], [1 << 63, -3], [-(1 << 63) - 1, 4],
             [-(1 << 200), 1 << 199]]
    for values in cases:
        expected = max(abs(v) for v in values)
        assert max_abs(np.array(values, dtype=object)) == expected, values
        if all(-(1 << 63) <= v < (1 << 63) for v in values):
            assert max_abs(np.array(values, dtype=np.int64)) == expected, values


def test_python_int_planes_are_refused_exactly_at_the_budget():
    """A 256-bit workpiece takes planes whose offsets exceed int64 (Python ints) up to the budget and refuses one
    unit beyond it, with the bound named; the workpiece is unchanged after the refusal."""
    from csgnb.exact import budget
    from csgnb.octree.tool import Tool

    w = Workpiece.box([0, 0, 0], [10, 10, 10], width=256)
    limit = budget(256).limit
    N = 1 << 40
    D = (limit - 1) // (16 * N**3)  # the largest offset with 16 N^3 D < 2**255 (the other bounds are looser here)
    assert not budget(256).plane_violations(N, D) and budget(256).plane_violations(N, D + 1)
    ok = np.array([[N, 0, 0, -D], [-1, 0, 0, 0], [0, 1, 0, -5], [0, -1, 0, 0], [0, 0, 1, -5], [0, 0, -1, 0]], object)
    w._check_planes(ok, "planes")
    w2 = Workpiece.box([0, 0, 0], [10, 10, 10], width=256)
    before = w2._arrays()
    bad = ok.copy()
    bad[0, 3] = -(D + 1)
    with pytest.raises(PrecisionError, match="16·N³·D"):
        w2 -= Tool("convex", bad, [0, 0, 0], [5, 5, 5])
    after = w2._arrays()
    for name in before:
        assert np.array_equal(before[name], after[name]), name


def test_hull_tools_with_offsets_beyond_int64_keep_split_planes_and_give_the_same_part():
    """On a 256-bit grid a capsule's facet offsets exceed int64: ``Tool.from_hull`` keeps int64 normals and a column
    of Python ints (no (k, 4) object array on the per-Boolean path). Its planes (made on request) are the ones the
    (k, 4) path gives, in the same order; its wide planes are those planes; a translated copy has its own planes;
    and Booleans with it leave the workpiece bit for bit as a tool built from the materialised planes does."""
    from csgnb.exact import Grid, to_wide
    from csgnb.octree.tool import Tool, _exact_planes, spread_order

    grid = Grid.fit([-12.0, -12.0, -1.0], [12.0, 12.0, 12.0], width=256)
    rng = np.random.default_rng(3)
    w_split = Workpiece.empty(grid, threshold=150)
    w_plain = Workpiece.empty(grid, threshold=150)
    dome = convex_hull(grid.to_grid(rng.normal(size=(60, 3)) * 6 + [0, 0, 5]), grid=grid)
    w_split |= dome
    w_plain |= dome
    for _ in range(6):
        centre = rng.uniform(-4, 4, 3) + [0, 0, 5]
        hull = convex_hull(grid.to_grid(centre + rng.normal(size=(40, 3)) * 0.7), grid=grid)
        tool = Tool.from_hull(hull)
        assert tool.split_planes is not None and tool.split_planes[1].dtype == object
        planes = _exact_planes(hull.planes)
        expected = planes[spread_order(planes[:, :3].astype(np.float64))]
        wide = tool.planes_wide(256)
        assert "planes" not in tool.__dict__  # nothing made the object array so far
        assert expected.tolist() == tool.planes.tolist()
        assert wide.tobytes() == to_wide(expected, 256).tobytes()
        assert tool.n_planes == expected.shape[0]
        moved = tool.translated(np.array([5, -3, 2]))
        assert moved.split_planes is None
        assert moved.planes[:, 3].tolist() == [d - (a * 5 - b * 3 + c * 2) for a, b, c, d in expected.tolist()]
        w_split -= Tool.from_hull(hull)
        plain = Tool("convex", expected, hull.lo, hull.hi, grid=grid)
        plain._hull = tool._hull  # the same facets (the boundary merge's pieces): the same trees
        w_plain -= plain
    a, b = w_split._arrays(), w_plain._arrays()
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    assert w_split.volume() == w_plain.volume()


@pytest.mark.parametrize("width", [128, 256])
def test_leaves_measured_together_have_the_volumes_measured_alone(width):
    """``CellVolumes.measure`` (many BSP leaves in one forest extraction, the in-cells told apart by their block,
    their terms made in one kernel call) gives each leaf the volume ``bsp_volume`` gives it alone, also in batches
    smaller than the leaves; the workpiece's total is the sum of the single measurements."""
    from csgnb.octree import volume as V

    rng = np.random.default_rng(width)
    w = Workpiece.box([0, 0, 0], [64, 64, 64], width=width, threshold=8)
    for _ in range(12):
        c = rng.integers(4, 60, 3)
        r = rng.integers(3, 9, 3)
        w -= convex_hull(np.array([c + [x, y, z] for x in (-r[0], r[0]) for y in (-r[1], 0, r[1])
                                   for z in (-r[2], r[2])]), width=width)
    leaves = [n for n in w._leaves().tolist() if w.oc.kind[n] == V.BSP]
    assert len(leaves) > 20
    alone = {n: V.bsp_volume(w, n, w.oc.lo[n].astype(np.int64), w.oc.lo[n].astype(np.int64) + int(w.oc.size[n]))
             for n in leaves}
    keys = [V.cell_key(w, n) for n in leaves]
    batch = V.MEASURE_BATCH
    try:
        for size in (batch, 7):
            V.MEASURE_BATCH = size
            volumes = V.CellVolumes()
            volumes.measure(w, leaves, keys)
            assert len(volumes) == len(set(keys))
            assert all(volumes.volume(w, n, key=k) == alone[n] for n, k in zip(leaves, keys, strict=True))
    finally:
        V.MEASURE_BATCH = batch
    fresh = V.CellVolumes()
    assert fresh.total(w, w._leaves()) == w.volume() == sum(
        (V.CellVolumes().volume(w, n) for n in w._leaves().tolist()), Fraction(0))


def test_grouped_cell_volumes_are_each_group_s_volume():
    """``grouped_cells_volumes``: one kernel call, each group's volume as ``cells_volume`` of the group (empty
    groups 0); a grouping that does not end at the last cell is refused."""
    from csgnb.bsp import extract_cells, random_bsp
    from csgnb.mesh.volume import cells_volume, grouped_cells_volumes

    tree = random_bsp(60, seed=3, extent=500)
    store, cells = extract_cells(tree, [-500] * 3, [500] * 3)
    handles = cells[:, 1]
    ends = [0, 3, 3, 10, handles.shape[0]]
    got = grouped_cells_volumes(store, handles, ends)
    starts = [0] + ends[:-1]
    assert got == [cells_volume(store, handles[a:b]) if b > a else Fraction(0)
                   for a, b in zip(starts, ends, strict=True)]
    assert sum(got, Fraction(0)) == cells_volume(store, handles)
    with pytest.raises(ValueError, match="last group"):
        grouped_cells_volumes(store, handles, [1, 2])


def test_volume_terms_sum_alike_grouped_or_one_by_one():
    """``_terms_volume`` reads mostly-distinct denominators term by term and groups shared ones in limbs: both ways
    give the Fraction sum of the terms (the same terms, then each repeated four times, which sends them the other
    way)."""
    from csgnb.bsp import extract_cells, random_bsp
    from csgnb.mesh.volume import _cell_terms, _terms_volume, cells_volume, term_limbs

    tree = random_bsp(40, seed=11, extent=300, max_normal=9)
    store, cells = extract_cells(tree, [-300] * 3, [300] * 3)
    terms, _ = _cell_terms(store, cells[:, 1])
    L = term_limbs(store.width)

    def value(row) -> int:
        return int.from_bytes(row.tobytes(), "little", signed=True)

    def expected(rows) -> Fraction:
        return sum((Fraction(value(r[:L]), value(r[L:])) for r in rows), Fraction(0)) / 6

    assert 4 * np.unique(terms[:, L]).shape[0] > 3 * terms.shape[0]  # mostly distinct: read one by one
    volume = _terms_volume(terms, L)
    assert volume == expected(terms) == cells_volume(store, cells[:, 1])
    repeated = np.repeat(terms, 4, axis=0)  # every denominator four times: grouped in limbs
    assert _terms_volume(repeated, L) == 4 * volume == expected(repeated)
