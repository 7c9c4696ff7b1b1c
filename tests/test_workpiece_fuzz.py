"""The octree workpiece as the one owner of its cells: every answer exact after any sequence of Booleans.

A fuzz over random sequences (boxes on a lattice, random hulls, non-convex meshes, tools touching
faces / edges / vertices, tools outside, empty results, any label function, small thresholds that
split, combine and compact the BSP pool) checks after every operation:

* ``volume()`` against an independent oracle -- voxel counting for lattice boxes, a single
  :class:`csgnb.bsp.BSP` of the same sequence for hulls and meshes;
* ``track_volume`` against the difference of the oracle's volumes;
* ``classify`` of random points against the oracle;
* ``volume() == sum(cell_volume(c))`` over the public cell API.

The default run does a few hundred operations; ``-m slow`` runs 10^4.
"""

from __future__ import annotations

import os
from fractions import Fraction

import numpy as np
import pytest

from csgnb.bsp import BSP
from csgnb.errors import GeometryError, PrecisionError
from csgnb.exact import to_wide
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Workpiece

LATTICE = 16  # lattice boxes live in [0, 2 * LATTICE]^3, corners even: voxels of edge 2


def _box_hull(lo, hi):
    lo, hi = np.asarray(lo), np.asarray(hi)
    return convex_hull(np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)]))


def _label_functions(rng):
    """The named ops and a random label table (outside stays outside: material never fills the root box)."""
    table = [[0, int(rng.integers(0, 2))], [int(rng.integers(0, 2)), int(rng.integers(0, 2))]]
    return {
        "difference": (lambda a, b: a & (1 - b)),
        "union": (lambda a, b: a | b),
        "intersection": (lambda a, b: a & b),
        "xor": (lambda a, b: a ^ b),
        "table": (lambda a, b, t=table: t[a][b]),
    }


def _apply(w, name, fn, tool):
    if name in ("difference", "union", "intersection"):
        return getattr(w, name)(tool, track_volume=True)
    return w.boolean(tool, fn, track_volume=True)


class _CompactionCounter:
    def __init__(self, monkeypatch):
        self.calls = 0
        original = Workpiece._compact_pool

        def counting(w):
            self.calls += 1
            return original(w)

        monkeypatch.setattr(Workpiece, "_compact_pool", counting)


def _check_cells(w):
    cells = w.cells()["node"]
    assert w.volume() == sum((w.cell_volume(int(c)) for c in cells), Fraction(0))


def lattice_chain(seed: int, n_ops: int, *, check_cells_every: int = 10) -> None:
    """Random lattice boxes with every kind of label function, against a voxel grid.

    Voxels have edge 2 and cover lattice cells [-2, LATTICE + 4)^3 (grid [-4, 2 LATTICE + 8)), so tools that
    stick out of the stock or lie wholly outside it, and add material there, are counted too."""
    rng = np.random.default_rng(seed)
    threshold = int(rng.choice([8, 12, 24, 60]))
    off, n = 2, LATTICE + 6
    w = Workpiece.box([0, 0, 0], [2 * LATTICE] * 3, threshold=threshold)
    solid = np.zeros((n,) * 3, bool)
    solid[off:off + LATTICE, off:off + LATTICE, off:off + LATTICE] = True
    centres = np.argwhere(np.ones_like(solid))
    pts = to_wide(np.column_stack([2 * (centres - off) + 1, np.ones(len(centres), int)]), 128)
    volume = Fraction(8 * int(solid.sum()))
    for k in range(n_ops):
        fns = _label_functions(rng)
        name = str(rng.choice(list(fns)))
        lo = rng.integers(-off, LATTICE + 1, size=3)
        hi = np.minimum(lo + rng.integers(1, 9, size=3), LATTICE + 4)
        if rng.random() < 0.1:  # a tool wholly outside the stock
            lo, hi = np.array([LATTICE + 1] * 3), np.array([LATTICE + 3] * 3)
        tool = np.zeros_like(solid)
        tool[lo[0] + off:hi[0] + off, lo[1] + off:hi[1] + off, lo[2] + off:hi[2] + off] = True
        table = np.array([[fns[name](x, y) for y in (0, 1)] for x in (0, 1)])
        new = table[solid.astype(int), tool.astype(int)].astype(bool)
        report = _apply(w, name, fns[name], _box_hull(2 * lo, 2 * hi))
        new_volume = Fraction(8 * int(new.sum()))
        assert report.volume_change == new_volume - volume, (seed, k, name)
        assert w.volume() == new_volume, (seed, k, name)
        solid, volume = new, new_volume
        if k % 7 == 0 or k == n_ops - 1:
            labels = w.classify(pts)
            assert np.array_equal(labels, solid[tuple(centres.T)].astype(labels.dtype)), (seed, k)
        if k % check_cells_every == 0:
            _check_cells(w)


def _random_tool(rng):
    """A random convex hull (coplanar, touching cases frequent on a coarse lattice) or a tetrahedron mesh."""
    centre = rng.integers(0, 40, size=3) // 4 * 4
    if rng.random() < 0.25:
        a, s = centre, int(rng.integers(3, 12))
        V = np.array([a, a + [s, 0, 0], a + [0, s, 0], a + [0, 0, s]])
        F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        return (V, F), BSP.from_mesh(V, F, lo=[-60] * 3, hi=[100] * 3)
    r = int(rng.integers(1, 5)) * 3
    h = convex_hull(centre + rng.integers(-r, r + 1, size=(9, 3)))
    return h, BSP(h.to_bsp().tree, [-60] * 3, [100] * 3)


def hull_chain(seed: int, n_ops: int) -> None:
    """Random hulls and meshes against one BSP of the same sequence."""
    rng = np.random.default_rng(seed)
    w = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=int(rng.choice([12, 24, 150])))
    ref = BSP.box([0, 0, 0], [40, 40, 40])
    before = w.volume()
    for k in range(n_ops):
        tool, tool_bsp = _random_tool(rng)
        name = str(rng.choice(["difference", "difference", "union", "intersection", "xor"]))
        report = _apply(w, name, lambda a, b: a ^ b, tool)
        ref = ref ^ tool_bsp if name == "xor" else getattr(ref, name)(tool_bsp)
        after = ref.volume()
        assert w.volume() == after, (seed, k, name)
        assert report.volume_change == after - before, (seed, k, name)
        before = after
    pts = rng.integers(-20, 180, size=(2000, 3))
    X = to_wide(np.column_stack([pts, np.full(len(pts), 3)]), 128)
    assert np.array_equal(w.classify(X), ref.tree.classify(X))
    _check_cells(w)


def test_volume_stays_exact_after_the_pool_is_compacted(monkeypatch):
    """The issue's reproduction: xor with a box 144 times. The old cache was keyed on pool positions, which a
    compaction renumbers: volume() kept answering 1,126,853 (the volume after 71 xors) after 144."""
    counter = _CompactionCounter(monkeypatch)
    w = Workpiece.box([1] * 3, [100] * 3, threshold=8)
    box = BSP.box([0] * 3, [128] * 3)
    for _ in range(71):
        w.boolean(box, lambda a, b: a ^ b)
    assert w.volume() == 128**3 - 99**3
    for k in range(73):
        report = w.boolean(box, lambda a, b: a ^ b, track_volume=True)
        assert report.volume_change == (-1 if k % 2 == 0 else 1) * (128**3 - 2 * 99**3)
    assert counter.calls > 0  # the pool was compacted in between
    assert w.volume() == 99**3 == w.to_bsp().volume()


@pytest.mark.parametrize("seed", range(6))
def test_lattice_fuzz(seed):
    lattice_chain(seed, 60)


def test_lattice_fuzz_reaches_compaction(monkeypatch):
    counter = _CompactionCounter(monkeypatch)
    lattice_chain(101, 300, check_cells_every=50)
    assert counter.calls > 0


@pytest.mark.parametrize("seed", range(3))
def test_hull_and_mesh_fuzz(seed):
    hull_chain(seed, 12)


@pytest.mark.slow
def test_lattice_fuzz_ten_thousand_ops(monkeypatch):
    counter = _CompactionCounter(monkeypatch)
    n = int(os.environ.get("CSGNB_FUZZ_OPS", "10000"))
    for seed in range(1000, 1000 + n // 250):
        lattice_chain(seed, 250, check_cells_every=50)
    assert counter.calls > 0


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10, 30))
def test_hull_and_mesh_fuzz_long(seed):
    hull_chain(seed, 30)


def test_cell_api_is_keyed_on_content_and_checked():
    w = Workpiece.box([0, 0, 0], [16, 16, 16], threshold=12)
    w -= convex_hull(np.array([[4, 4, 4], [20, 4, 4], [4, 20, 4], [4, 4, 20]]))
    nodes = w.cells_meeting([3, 3, 3], [9, 9, 9])
    assert nodes.shape[0] >= 1
    for n in nodes.tolist():
        lo, size = w.cell_box(n)
        assert np.all(lo < 9) and np.all(lo + size > 3)
        assert 0 <= w.cell_volume(n) <= size**3
    with pytest.raises(GeometryError, match="not a leaf"):
        w.cell_volume(0)  # the root has children
    with pytest.raises(GeometryError, match="not a leaf"):
        w.cell_box(10**9)


def test_box_on_the_identity_grid_refuses_a_corner_it_would_round():
    with pytest.raises(PrecisionError, match="2.5 is not an integer"):
        Workpiece.box([0, 0, 0], [2.5] * 3)
    assert Workpiece.box([0, 0, 0], [2.0] * 3).volume() == 8  # integral floats are integers


def test_classify_accepts_integral_float_points_and_refuses_others():
    w = Workpiece.box([0, 0, 0], [4, 4, 4])
    assert w.classify(np.array([[1.0, 1.0, 1.0], [9.0, 9.0, 9.0]])).tolist() == \
        w.classify(np.array([[1, 1, 1], [9, 9, 9]])).tolist()
    with pytest.raises(PrecisionError, match="0.5 is not an integer"):
        w.classify([[0.5, 1, 1]])


def test_an_empty_workpiece_is_a_no_op_tool():
    w = Workpiece.box([0, 0, 0], [8, 8, 8])
    empty = Workpiece.empty()
    report = w.difference(empty.to_bsp(), track_volume=True)
    assert report.volume_change == 0 and w.volume() == 512
    assert w.union(empty.to_bsp(), track_volume=True).volume_change == 0


def _check_volume_cache(w):
    """The volume cache names only present cells, each with its own exact volume (checked right after a palette
    compaction: not re-keyed, the cache kept keys that name other rows, possibly another cell's content)."""
    from csgnb.octree.layout import BSP as BSP_KIND
    from csgnb.octree.volume import bsp_volume, cell_key

    cells = {cell_key(w, c): c for c in w._leaves().tolist() if w.oc.kind[c] == BSP_KIND}
    assert set(w._volumes._cache) <= set(cells)
    for key, v in w._volumes._cache.items():
        c = cells[key]
        lo = np.asarray(w.oc.lo[c], np.int64)
        assert v == bsp_volume(w, c, lo, lo + int(w.oc.size[c]))


def _watch_compactions(monkeypatch, w) -> list:
    """Check the volume cache after every palette compaction of ``w``; return the palette sizes seen after each
    check for compaction (the list fills as ``w`` runs)."""
    from csgnb.octree.layout import N_PAL

    sizes, compact, maybe = [], w._compact_palette, w._maybe_compact_palette

    def compacted():
        before = int(w.oc.counts[N_PAL])
        compact()
        if int(w.oc.counts[N_PAL]) < before:
            sizes.append(-1)  # a marker: a compaction that renumbered
            _check_volume_cache(w)

    def checked():
        maybe()
        sizes.append(int(w.oc.counts[N_PAL]))

    monkeypatch.setattr(w, "_compact_palette", compacted)
    monkeypatch.setattr(w, "_maybe_compact_palette", checked)
    return sizes


def _same_run(plain, compacted, changes_plain, changes_compacted):
    """The two runs of one sequence, with and without palette compaction, are the same workpiece."""
    assert changes_compacted == changes_plain
    assert compacted._state_digest() == plain._state_digest()
    assert compacted.volume() == plain.volume()
    lo, hi = plain.oc.lo[0], plain.oc.lo[0] + plain.oc.size[0]
    pts = np.random.default_rng(1).integers(lo, hi, size=(3000, 3))
    X = to_wide(np.column_stack([pts, np.ones(len(pts), np.int64)]), plain.width)
    assert np.array_equal(compacted.classify(X), plain.classify(X))


def test_palette_compaction_of_a_real_milling_run(monkeypatch):
    """Every tool appends its planes to the palette (~150 rows a move here; 7,192 a drill step) and nothing dropped
    them: a long run's palette grew without bound (the shipped relief program: 18,141 rows after 121 moves, 1,753
    in use). Compacting it (the planes no cell and no wall map entry uses dropped, the rest renumbered in order)
    keeps it small and leaves the run the same: canonical arrays (hence digest and saved file), every move's exact
    removed volume, the classification, and the volume cache, whose keys name palette rows, re-keyed."""
    import sys
    from pathlib import Path

    import csgnb.octree.workpiece as wp_module
    from csgnb.apps import milling

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_milling import program_setup

    program, lo, hi, grid, tool = program_setup("relief.nc", None, None)
    runs = {}
    for rows in (1 << 40, 1024):
        monkeypatch.setattr(wp_module, "PALETTE_COMPACT_ROWS", rows)
        w = Workpiece.box(lo, hi, grid=grid)
        sizes = _watch_compactions(monkeypatch, w)
        result = milling.simulate(w, program, tool, progress=False)
        runs[rows] = (w, [r.removed for r in result.records], sizes)
    (plain, plain_removed, plain_sizes), (small, small_removed, small_sizes) = runs[1 << 40], runs[1024]
    assert -1 not in plain_sizes and small_sizes.count(-1) >= 3
    # (the cells' cached boundaries keep their pieces' edge planes alive too -- a hull's pieces are its facets, whose
    # edges are the facets' neighbours: 9,373 rows at most, 18,143 never compacted)
    assert max(plain_sizes) > 15_000 and max(small_sizes) < 0.6 * max(plain_sizes), (small_sizes, max(plain_sizes))
    _same_run(plain, small, plain_removed, small_removed)


def test_palette_compaction_fuzz(monkeypatch):
    """Random convex cuts and unions, the palette compacted whenever it doubles (whatever its live share), against
    the same sequence never compacted."""
    import csgnb.octree.workpiece as wp_module

    def run(compact):
        monkeypatch.setattr(wp_module, "PALETTE_COMPACT_ROWS", 1 if compact else 1 << 40)
        monkeypatch.setattr(wp_module, "PALETTE_COMPACT_LIVE", 1.0)
        rng = np.random.default_rng(5)
        w = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=int(rng.choice([12, 24])))
        sizes = _watch_compactions(monkeypatch, w)
        changes = []
        for k in range(80):
            centre = rng.integers(8, 33, size=3)
            tool = convex_hull(centre + rng.integers(-7, 8, size=(10, 3)))
            fn = (lambda a, b: a & ~b) if k % 4 else (lambda a, b: a | b)
            changes.append(w.boolean(tool, fn, track_volume=True).volume_change)
            if k % 9 == 0:
                w.volume()  # fill the cache between operations
        return w, changes, sizes

    plain, plain_changes, plain_sizes = run(False)
    compacted, compacted_changes, sizes = run(True)
    assert -1 not in plain_sizes and sizes.count(-1) >= 4, sizes
    _same_run(plain, compacted, plain_changes, compacted_changes)


def test_live_planes_are_the_sorted_distinct_rows_referenced():
    """The compaction's live rows (marked in a boolean array since 2026-12-06) are exactly ``np.unique`` of the
    references: BSP node planes (-1 at leaves), the wall map's rows where its key is set, and the cached pieces'
    rows, flipped supports stored as ``~row`` -- including the largest row, a row referenced only as ``~row``, and
    nothing referenced at all."""
    from types import SimpleNamespace

    from csgnb.octree.workpiece import _live_planes

    rng = np.random.default_rng(11)
    for trial in range(300):
        used = int(rng.integers(1, 400))
        plane = rng.integers(-1, used, int(rng.integers(0, 2000))).astype(np.int32)
        keys = rng.integers(-1, 3, 30)
        amap = SimpleNamespace(keys=keys, rows=rng.integers(0, used, 30).astype(np.int32))
        pieces = rng.integers(-used, used, int(rng.integers(0, 2000))).astype(np.int32) if trial % 3 else None
        if trial % 5 == 0 and pieces is not None:
            pieces[0] = ~np.int32(used - 1)  # the last row, only as a flipped support
        refs = [plane[plane >= 0], amap.rows[keys >= 0]]
        if pieces is not None:
            refs.append(np.where(pieces >= 0, pieces, ~pieces))
        live = _live_planes(plane, amap, pieces)
        assert live.dtype == np.int64
        assert np.array_equal(live, np.unique(np.concatenate(refs).astype(np.int64))), trial
    nothing = SimpleNamespace(keys=np.full(4, -1), rows=np.zeros(4, np.int32))
    assert _live_planes(np.full(5, -1, np.int32), nothing).shape == (0,)
