"""Convex hulls in compiled batches (csgnb.octree.batch, ``Workpiece.run``): the workpiece one Boolean at a time
makes, array for array -- raw arrays, so the pool and palette compactions must happen after the same hulls."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import csgnb.octree.workpiece as workpiece_module
from csgnb.bsp import BSP
from csgnb.bsp.solid import DIFFERENCE, INTERSECTION, UNION
from csgnb.errors import GeometryError, PrecisionError
from csgnb.exact import Grid
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Workpiece
from csgnb.octree.layout import N_FREE_BLOCKS, N_NODES, N_PAL, N_POOL


def _hulls(seed: int, n: int, extent: int = 40, radius: tuple[int, int] = (2, 6), scale: int = 1,
           width: int | None = None):
    """Random convex hulls of 9 lattice points (coplanar and touching cases on the coarse lattice)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        centre = rng.integers(0, extent, size=3) // 4 * 4
        r = int(rng.integers(*radius)) * 3
        points = (centre + rng.integers(-r, r + 1, size=(9, 3))) * scale
        if scale > 1:  # off the coarse lattice, so the planes do not reduce to small ones
            points += rng.integers(-(scale // 2), scale // 2 + 1, size=(9, 3))
        out.append(convex_hull(points, width=width))
    return out


def _raw(w: Workpiece) -> dict[str, np.ndarray]:
    """The workpiece's arrays as they lie (not canonical): rows in use of the octree, the pool and the palette."""
    n, p, r = (int(w.oc.counts[k]) for k in (N_NODES, N_POOL, N_PAL))
    out = {f"oc_{k}": np.array(getattr(w.oc, k)[:n]) for k in w.oc._fields if k not in ("counts", "free_blocks")}
    out["oc_free_blocks"] = np.array(w.oc.free_blocks[:int(w.oc.counts[N_FREE_BLOCKS])])
    out["counts"] = w.oc.counts.copy()
    out.update({f"pool_{k}": np.array(getattr(w.pool, k)[:p]) for k in w.pool._fields})
    out["palette"] = np.array(w.palette[:r]).view(np.uint8)
    return out


def _same(a: Workpiece, b: Workpiece) -> None:
    ra, rb = _raw(a), _raw(b)
    assert ra.keys() == rb.keys()
    for name in ra:
        assert np.array_equal(ra[name], rb[name]), name


def _one_at_a_time(w: Workpiece, hulls, fn) -> list:
    return [w.boolean(h, fn) for h in hulls]


def _counters(reports) -> list[tuple]:
    return [(r.cells, r.merges, r.relabels, r.splits, r.combines, r.unchanged) for r in reports]


@pytest.mark.parametrize("op, fn", [("difference", DIFFERENCE), ("union", UNION), ("intersection", INTERSECTION)])
def test_a_batch_is_one_boolean_at_a_time(op, fn):
    hulls = _hulls(3, 40 if op != "intersection" else 4, radius=(3, 8))
    a = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    b = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    ra = _one_at_a_time(a, hulls, fn)
    rb = b.run(hulls, op)
    _same(a, b)
    assert _counters(ra) == _counters(rb)
    assert a.volume() == b.volume()
    assert (b.stats.operations, b.stats.merges, b.stats.splits) == (a.stats.operations, a.stats.merges, a.stats.splits)


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 30), st.sampled_from([8, 16, 40, 150]),
       st.sampled_from(["difference", "union"]))
def test_random_batches_equal_single_booleans(seed, n, threshold, op):
    """Tiny thresholds split and combine cells in almost every Boolean; an empty start (unions) grows every array
    from nothing, so the batch resumes for room mid-hull."""
    hulls = _hulls(seed, n)
    fn = DIFFERENCE if op == "difference" else UNION
    make = ((lambda: Workpiece.box([0, 0, 0], [40, 40, 40], threshold=threshold)) if op == "difference"
            else (lambda: Workpiece.empty(threshold=threshold)))
    a, b = make(), make()
    ra = _one_at_a_time(a, hulls, fn)
    rb = b._boolean_hulls(hulls, fn)
    _same(a, b)
    assert _counters(ra) == _counters(rb)


def test_compactions_happen_after_the_same_hulls(monkeypatch):
    """Pool compaction (more than 4,096 rows, under half live) and palette compaction (a small threshold here)
    inside a batch happen where single Booleans make them: the raw arrays agree, row for row."""
    calls = {"pool": 0, "palette": 0}
    pool, palette = Workpiece._compact_pool, Workpiece._compact_palette

    def counted_pool(self):
        calls["pool"] += 1
        return pool(self)

    def counted_palette(self):
        calls["palette"] += 1
        return palette(self)

    monkeypatch.setattr(Workpiece, "_compact_pool", counted_pool)
    monkeypatch.setattr(Workpiece, "_compact_palette", counted_palette)
    monkeypatch.setattr(workpiece_module, "PALETTE_COMPACT_ROWS", 512)
    hulls = _hulls(5, 160, extent=80, radius=(2, 5))
    a = Workpiece.box([0, 0, 0], [80, 80, 80], threshold=48)
    b = Workpiece.box([0, 0, 0], [80, 80, 80], threshold=48)
    _one_at_a_time(a, hulls, DIFFERENCE)
    single = dict(calls)
    b.run(hulls, "difference")
    assert single["pool"] > 0 and single["palette"] > 0, single  # the test reaches both compactions
    assert calls["pool"] == 2 * single["pool"] and calls["palette"] == 2 * single["palette"]
    _same(a, b)


def test_batches_at_256_bits_with_python_int_planes():
    """Planes whose offsets exceed int64 (Python ints): one conversion for the whole batch, the same palette."""
    hulls = _hulls(9, 12, extent=40, scale=1 << 20, width=256)
    assert any(h.planes.dtype == object for h in hulls)
    assert all(h._split_planes() is not None for h in hulls)  # the batch takes the split planes (int64 normals)
    a = Workpiece.empty(width=256)
    b = Workpiece.empty(width=256)
    _one_at_a_time(a, hulls, UNION)
    b.run(hulls, "union")
    _same(a, b)
    assert a.volume() == b.volume() > 0


def test_a_mixed_run_and_its_checkpoints(tmp_path):
    """Hulls batched between a BSP tool and checkpoints (a batch never crosses one): the same workpiece, and a
    resumed run equals an uninterrupted one."""
    hulls = _hulls(7, 30)
    tools = hulls[:11] + [BSP.box([4, 4, 4], [30, 12, 20])] + hulls[11:]
    a = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    for t in tools:
        a -= t
    b = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    assert len(b.run(tools, "difference", progress=True)) == len(tools)
    _same(a, b)
    path = tmp_path / "ck.npz"
    crashed = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    crashed.run(tools[:17], "difference", checkpoint=path, checkpoint_every=4)
    resumed = Workpiece.box([0, 0, 0], [40, 40, 40], threshold=24)
    resumed.run(tools, "difference", checkpoint=path, checkpoint_every=4)
    assert resumed.volume() == a.volume()


def test_a_bad_hull_anywhere_in_a_batch_leaves_the_workpiece_unchanged():
    w = Workpiece.box([0, 0, 0], [40, 40, 40])
    before = _raw(w)
    good = _hulls(2, 5)
    other = convex_hull(np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, 4]]), grid=Grid.from_resolution(0.5,
                                                                                                            width=128))
    with pytest.raises(GeometryError, match="grid"):
        w.run(good + [other], "difference")
    huge = convex_hull(np.array([[0, 0, 0], [5000, 0, 0], [0, 10, 0], [0, 0, 10]]), width=256)
    with pytest.raises(PrecisionError, match="budget"):
        w.run(good + [huge] + good, "difference")
    after = _raw(w)
    for name in before:
        assert np.array_equal(before[name], after[name]), name
    assert w.stats.operations == 1  # the stock only


def _python_int_planes(hull) -> np.ndarray:
    """The hull's facet planes ``(k, 4)`` object, computed here from its points and faces with Python ints (n = the
    cross product of two edges from the face's first corner, d = -n·p, outward: every point on or behind), an
    independent reference for the planes the workpiece and its batches derive (split planes, int64 parts)."""
    P = [[int(x) for x in p] for p in hull.points]
    rows = []
    for face in hull.faces:
        a = P[int(face[0])]
        for j in range(1, len(face) - 1):
            b, c = P[int(face[j])], P[int(face[j + 1])]
            u = [b[i] - a[i] for i in range(3)]
            v = [c[i] - a[i] for i in range(3)]
            n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
            if any(n):
                break
        d = -sum(n[i] * a[i] for i in range(3))
        sides = [sum(n[i] * p[i] for i in range(3)) + d for p in P]
        if max(sides) > 0:  # the face's corners listed the other way round
            n, d = [-x for x in n], -d
        assert max(sum(n[i] * p[i] for i in range(3)) + d for p in P) == 0
        rows.append(n + [d])
    return np.array(rows, dtype=object)


def test_the_drills_256_bit_sweep_from_batches_equals_one_from_python_int_planes():
    """The paper's drill on the finest 256-bit grid that holds it (the benchmark's): one step's prisms unioned in
    compiled batches (split planes) enclose exactly the volume of the same prisms given as tools of Python-int
    planes computed here. A shift N·origin between 2**62 and 2**63 once came back int64 from the split planes and
    wrapped: 25 of the drill's 45 sweeps were built with plane offsets off by 2**64, a change of ~1e-10 mm, no
    error -- and a different cell structure at the end of the benchmark was the only sign."""
    from csgnb.apps import sweep, tools
    from csgnb.octree.tool import Tool

    grid = Grid.fit([-12, -12, -16], [12, 12, 8], width=256)
    ds = sweep.drill_sweeps(tools.twist_drill().on(grid), feed_per_turn=1.0, steps=1, symmetry=False)
    prisms = ds.steps[0]
    assert any(h._split_planes() is not None and h._split_planes()[1].dtype == object for h in prisms)
    batched = Workpiece.empty(grid)
    batched.run(prisms, "union")
    reference = Workpiece.empty(grid)
    for h in prisms:
        reference |= Tool("convex", _python_int_planes(h), h.lo, h.hi)
    assert batched.volume() == reference.volume() > 0


def _hull_near_the_int64_edge(rng, fraction: float, limit: int):
    """A hull of 12 random points (extent ~2**20) moved along x so that one facet's shift N·origin of its split planes
    lies in (2**63 - |d_local|, 2**63): an int64 shift whose difference with the local offset passes 2**63 -- the
    window where the split once wrapped. None when this draw cannot reach it within the budget."""
    size = 1 << 20
    points = rng.integers(-size, size + 1, size=(12, 3))
    hull = convex_hull(points, width=256)
    N = np.asarray(hull._normals).astype(object)
    d_local = np.asarray(hull._d_local).astype(object)
    origin = [int(v) for v in hull._origin]
    big = [i for i in range(N.shape[0]) if d_local[i] < -4 * abs(N[i, 0]) and abs(N[i, 0]) >= 1 << 37]
    if not big:
        return None
    i = max(big, key=lambda r: abs(N[r, 0]))
    nx = int(N[i, 0])
    base = sum(int(N[i, c]) * origin[c] for c in range(3))
    target = (1 << 63) - 2 * abs(nx) - int(fraction * (-int(d_local[i]) - 4 * abs(nx)))
    tx = round(Fraction(target - base, nx))
    if abs(tx) + 2 * size > limit:
        return None
    moved = convex_hull(points + np.array([tx, 0, 0]), width=256)
    shifts = [sum(int(a) * int(b) for a, b in zip(n, moved._origin, strict=True)) for n in moved._normals]
    d_moved = [int(v) for v in moved._d_local]
    assert any((1 << 62) <= s_ < (1 << 63) and abs(d - s_) >= 1 << 63 for s_, d in zip(shifts, d_moved, strict=True))
    return moved


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), log_size=st.integers(12, 22),
       fraction=st.floats(0.0, 0.999))
def test_wide_hulls_anywhere_in_the_256_bit_budget_match_python_int_planes(seed, n, log_size, fraction):
    """A fuzz over the whole 256-bit mesh budget: one hull whose split planes meet the int64 edge (a shift N·origin in
    (2**63 - |d_local|, 2**63)) and ``n`` hulls of 12 random points (extent 2**log_size, centres anywhere within the
    budget: normals up to ~2**45, shifts up to ~2**72), a union and a difference in compiled batches (split planes)
    against the same hulls as tools of Python-int planes computed here. Fails on 0909b0b (the wrap of 13ea747)."""
    from hypothesis import assume

    from csgnb.exact import budget
    from csgnb.octree.tool import Tool

    rng = np.random.default_rng(seed)
    limit = budget(256).max_mesh_coordinate
    edge = _hull_near_the_int64_edge(rng, fraction, limit)
    assume(edge is not None)
    size = 1 << log_size
    hulls = [edge]
    for _ in range(n):
        centre = rng.integers(-(limit - size), limit - size + 1, size=3)
        hulls.append(convex_hull(centre + rng.integers(-size, size + 1, size=(12, 3)), width=256))
    stock = convex_hull(np.array([[i, j, k] for i in (-limit, limit) for j in (-limit, limit)
                                  for k in (-limit, limit)]), width=256)
    for op in ("union", "difference"):
        batched = Workpiece.empty(width=256)
        reference = Workpiece.empty(width=256)
        if op == "difference":
            batched |= stock
            reference |= stock
        batched.run(hulls, op)
        for h in hulls:
            reference.boolean(Tool("convex", _python_int_planes(h), h.lo, h.hi), UNION if op == "union" else DIFFERENCE)
        assert batched.volume() == reference.volume(), op
