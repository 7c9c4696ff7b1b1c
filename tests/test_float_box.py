"""The certified float filter of merges (``csgnb.mesh.float_box``): never wrong, often decisive, changes no tree.

A merge walks each A-leaf's cell through B; the filter skips the exact cut of a B plane when doubles prove
the cell lies strictly on one side. Checked here against Python Fractions: the float box holds every exact
vertex, and every side the filter claims is the side of every exact vertex, strictly -- at 128 and 256 bits,
with coordinates far from 1 and planes through or one unit beside a vertex. Then merges and octree Booleans
with and without the filter give identical trees.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb.bsp import DIFFERENCE, INTERSECTION, SYMMETRIC_DIFFERENCE, UNION, merge, random_bsp
from csgnb.bsp.merging import merge_changes
from csgnb.exact import Grid, to_wide
from csgnb.mesh.cutting import cut
from csgnb.mesh.float_box import plane_side_over_box, polytope_float_box
from csgnb.mesh.halfedge import MeshStore
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Workpiece
from csgnb.octree.kernels import UNCHANGED_SHARE_TO_ASK


def _value(plane, p) -> Fraction:
    return plane[0] * p[0] + plane[1] * p[1] + plane[2] * p[2] + plane[3]


def random_polytope(rng, width: int, scale: int, normal: int, cuts: int = 6):
    """A convex polytope: the box [-scale, scale]^3 cut by ``cuts`` random planes (one part kept each time)."""
    store = MeshStore(to_wide(np.zeros((0, 4), np.int64), width))
    cell = store.add_box([-scale] * 3, [scale] * 3)
    for _ in range(cuts):
        n = rng.integers(-normal, normal + 1, 3)
        if not n.any():
            continue
        p = rng.integers(-scale // 2, scale // 2 + 1, 3)
        plane = [int(x) for x in n] + [-int(sum(int(a) * int(b) for a, b in zip(n, p, strict=True)))]
        row = int(store.add_planes(to_wide(np.asarray([plane], dtype=object), width))[0])
        r = cut(store, cell, row)
        if r.proper:
            cell = r.negative if rng.integers(0, 2) else r.positive
    return store, cell, store.exact_vertices(store.cell_vertices(cell))


def candidate_planes(rng, vertices, normal: int, count: int):
    """Planes through an exact vertex's rounded position, then shifted by -2..2 units (near and on vertices),
    and planes far on either side."""
    out = []
    for _ in range(count):
        n = [int(x) for x in rng.integers(-normal, normal + 1, 3)]
        if not any(n):
            n[0] = 1
        v = vertices[int(rng.integers(0, len(vertices)))]
        d = -round(sum(a * b for a, b in zip(n, v, strict=True)))
        out.append(n + [d + int(rng.integers(-2, 3))])
    return out


@settings(deadline=None, max_examples=40)
@given(seed=st.integers(0, 2**32 - 1),
       case=st.sampled_from([(128, 2**10, 7), (128, 2**20, 3), (256, 2**40, 2**12), (256, 3, 2**30)]))
def test_the_box_holds_every_vertex_and_every_claimed_side_is_exact(seed, case):
    width, scale, normal = case
    rng = np.random.default_rng(seed)
    store, cell, vertices = random_polytope(rng, width, scale, normal)
    box = polytope_float_box(store, cell)
    for p in vertices:
        for c in range(3):
            assert Fraction(box[0, c]) <= p[c] <= Fraction(box[1, c])
    for plane in candidate_planes(rng, vertices, normal, 40):
        side = plane_side_over_box(plane, box)
        if side:
            values = [_value(plane, p) for p in vertices]
            assert all(v * side > 0 for v in values), (plane, side, values)


def test_the_filter_decides_planes_that_clearly_miss_and_never_one_through_a_vertex():
    store, cell, vertices = random_polytope(np.random.default_rng(1), 128, 2**10, 7)
    box = polytope_float_box(store, cell)
    assert plane_side_over_box([1, 0, 0, -2**11], box) == -1  # x = 2048: the cell lies below
    assert plane_side_over_box([1, 0, 0, 2**11], box) == 1
    # A plane through a vertex with integer coordinates (a box corner survives most cuts: use the box's own).
    store2 = MeshStore(to_wide(np.zeros((0, 4), np.int64), 128))
    box2 = polytope_float_box(store2, store2.add_box([0, 0, 0], [4, 4, 4]))
    assert plane_side_over_box([1, 1, 1, -12], box2) == 0  # touches the corner (4, 4, 4)
    assert plane_side_over_box([1, 1, 1, -13], box2) == -1
    assert plane_side_over_box([1, 0, 0, 0], box2) == 0  # contains a face


def test_a_box_at_infinity_decides_nothing():
    assert plane_side_over_box([1, 0, 0, -5], np.full((2, 3), np.nan)) == 0


OPS = [UNION, INTERSECTION, DIFFERENCE, SYMMETRIC_DIFFERENCE]


def test_merges_with_and_without_the_filter_build_the_same_tree():
    decided = 0
    for seed in range(8):
        rng = np.random.default_rng(seed)
        na, nb = int(rng.integers(5, 60)), int(rng.integers(20, 90))
        a = random_bsp(na, seed=seed, extent=32, max_normal=7)
        b = random_bsp(nb, seed=seed + 50, extent=32, max_normal=7)
        decided += _same_trees(a, b)
    assert decided > 0  # the filter did decide planes here (a box is made after LAZY_CUTS misses)


def _same_trees(a, b) -> int:
    decided = 0
    for fn in OPS:
        filtered = merge(a, b, fn, [-32] * 3, [32] * 3)
        exact = merge(a, b, fn, [-32] * 3, [32] * 3, prefilter=False)
        assert exact.prefiltered == 0
        decided += filtered.prefiltered
        for name in ("plane", "neg", "pos", "label"):
            np.testing.assert_array_equal(getattr(filtered.tree, name), getattr(exact.tree, name))
        np.testing.assert_array_equal(filtered.cells, exact.cells)
    return decided


@settings(deadline=None, max_examples=30)
@given(seed=st.integers(0, 2**31 - 1), sizes=st.tuples(st.integers(1, 50), st.integers(1, 50)),
       op=st.sampled_from(OPS))
def test_asking_first_agrees_with_the_merge_on_whether_a_changes(seed, sizes, op):
    # merge_changes walks B first and stops at the first change; merge walks everything and counts the cells
    # whose label differs from A's. Small B trees inside A's solid, or beside it, make "nothing changes" common.
    a = random_bsp(sizes[0], seed=seed, extent=32, max_normal=5)
    b = random_bsp(sizes[1], seed=seed + 7, extent=32, max_normal=5, p_in=0.3)
    assert merge_changes(a, b, op, [-32] * 3, [32] * 3) == merge(a, b, op, [-32] * 3, [32] * 3).changed


def test_a_merge_that_changes_nothing_is_found_without_walking_a():
    a = random_bsp(30, seed=3, extent=32, max_normal=5)
    assert not merge_changes(a, a, UNION, [-32] * 3, [32] * 3)  # A with itself
    assert not merge_changes(a, a, INTERSECTION, [-32] * 3, [32] * 3)
    assert merge_changes(a, a, SYMMETRIC_DIFFERENCE, [-32] * 3, [32] * 3) == (volume_of(a) > 0)


def volume_of(tree):
    from csgnb.bsp import extract_boundary

    return extract_boundary(tree, [-32] * 3, [32] * 3).surface.exact_volume()


def _capsules(grid, n):
    t = np.linspace(0.0, 1.0, n + 1)
    path = np.stack([6 * np.cos(5 * t), 6 * np.sin(5 * t), 8 - 3 * t], 1)
    ball = 0.9 * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
                           [0.6, 0.6, 0.5], [-0.6, 0.6, -0.5], [0.6, -0.6, -0.5], [-0.6, -0.6, 0.5]])
    return [grid.to_grid(np.concatenate([path[i] + ball, path[i + 1] + ball])) for i in range(n)]


def test_octree_carving_with_and_without_the_filter_is_identical():
    # Each capsule is subtracted twice: the second time nothing changes, so the share of unchanged cell
    # merges climbs past the point where the octree asks first (merge_changes_a) -- both paths run here.
    grid = Grid.fit([-10, -10, -1], [10, 10, 10], width=128)
    dome = grid.to_grid(np.array([[x, y, z] for x in (-8, 8) for y in (-8, 8) for z in (0, 8)]))
    works, shares = [], []
    for filtering in (True, False):
        w = Workpiece.empty(grid, threshold=40)
        w.boundary_cache = False  # every cell merge cuts: the filter's path (hulls merge from cells' boundaries else)
        if not filtering:
            w.ws = w.ws._replace(merge_boxes=np.zeros((0, 6)))
        w |= convex_hull(dome, grid=grid)
        for c in _capsules(grid, 30):
            hull = convex_hull(c, grid=grid)
            w -= hull
            w -= hull
            w -= hull
            shares.append(int(w.ws.merge_state[5]))
        works.append(w)
    on, off = works
    assert on.stats.prefiltered > 0 and off.stats.prefiltered == 0
    assert on.stats.skipped_merges > 0 and off.stats.skipped_merges == 0
    assert max(shares[:30]) > UNCHANGED_SHARE_TO_ASK
    assert off.ws.merge_boxes.shape[0] == 0  # stays off when the merge scratch grows
    assert on.volume() == off.volume()
    assert (on.n_cells, on.n_bsp_nodes) == (off.n_cells, off.n_bsp_nodes)
    a, b = on.global_tree(), off.global_tree()
    for name in ("plane", "neg", "pos", "label"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
