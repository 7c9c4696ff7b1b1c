"""Exact in-place cutting of convex polytopes: checked against Python Fractions.

Every cut of random convex polytopes by random integer planes (through vertices, along
edges, coplanar with faces, touching at one vertex, or generic) must give two closed,
strictly convex parts whose exact volumes add up to the original, with every vertex on
the right side of the plane (checked with Fractions, not with the kernels), and edge
descent must agree with the naive baseline.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb import GeometryError
from csgnb.exact import to_wide
from csgnb.mesh.cutting import cut
from csgnb.mesh.halfedge import MeshStore

W = 128
EMPTY = to_wide(np.zeros((0, 4), np.int64), W)


def plane_value(plane, point) -> Fraction:
    a, b, c, d = plane
    return a * point[0] + b * point[1] + c * point[2] + d


def part_sides(store: MeshStore, cell: int, plane) -> set[int]:
    """Signs of n·p + d over the part's vertices, computed with Fractions."""
    pts = store.exact_vertices(store.cell_vertices(cell))
    return {(v > 0) - (v < 0) for v in (plane_value(plane, p) for p in pts)}


def random_plane(rng: np.random.Generator, palette_rows: list[list[int]]) -> list[int]:
    """An integer plane of one of the degenerate kinds, or a generic one.

    Drawn without looking at the polytopes, so that two runs (edge descent and naive)
    see the same planes.
    """
    kind = rng.integers(0, 5)
    n = rng.integers(-3, 4, 3)
    while not n.any():
        n = rng.integers(-3, 4, 3)
    if kind == 0 and palette_rows:  # coplanar with an earlier plane or a box face (same or flipped)
        row = palette_rows[rng.integers(0, len(palette_rows))]
        return row if rng.integers(0, 2) else [-x for x in row]
    if kind == 1:  # through a box corner or an integer point on a box edge
        p = rng.choice([-8, 8], 3)
        p[rng.integers(0, 3)] = rng.integers(-8, 9)
        return [*map(int, n), -int(n @ p)]
    if kind == 2:  # containing a box edge: normal perpendicular to an axis, through a corner
        axis = rng.integers(0, 3)
        n[axis] = 0
        if not n.any():
            n[(axis + 1) % 3] = 1
        corner = rng.choice([-8, 8], 3)
        return [*map(int, n), -int(n @ corner)]
    if kind == 3:  # touching a box corner only
        corner = rng.choice([-8, 8], 3)
        m = np.sign(corner) * rng.integers(1, 4, 3)
        return [*map(int, m), -int(m @ corner)]
    p = rng.integers(-7, 8, 3)
    return [*map(int, n), -int(n @ p)]


def _ints(row) -> list[int]:
    from csgnb.exact import from_wide

    return [int(x) for x in from_wide(row)]


def run_cuts(seed: int, n_cuts: int, naive: bool):
    rng = np.random.default_rng(seed)
    store = MeshStore(EMPTY)
    cells = [store.add_box([-8, -8, -8], [8, 8, 8])]
    rows = [_ints(r) for r in store.planes]
    outcomes = []
    for _ in range(n_cuts):
        plane = random_plane(rng, rows)
        rows.append(plane)
        row = int(store.add_planes(to_wide([plane], W))[0])
        new = []
        for cell in cells:
            before = store.exact_volume(cell)
            r = cut(store, cell, row, naive=naive)
            if r.proper:
                vn, vp = store.exact_volume(r.negative), store.exact_volume(r.positive)
                assert vn > 0 and vp > 0
                assert vn + vp == before
                assert part_sides(store, r.negative, plane) <= {-1, 0}
                assert part_sides(store, r.positive, plane) <= {0, 1}
                assert -1 in part_sides(store, r.negative, plane) and 1 in part_sides(store, r.positive, plane)
                store.check_cell(r.negative)
                store.check_cell(r.positive)
                new += [r.negative, r.positive]
                outcomes.append((True, vn, vp))
            else:
                assert store.exact_volume(cell) == before
                assert part_sides(store, cell, plane) <= {0, r.side}
                new.append(cell)
                outcomes.append((False, r.side, before))
        cells = new
    return store, cells, outcomes


@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 2**32 - 1))
def test_random_cuts_conserve_exact_volume_and_convexity(seed):
    store, cells, _ = run_cuts(seed, 5, naive=False)
    assert sum(store.exact_volume(c) for c in cells) == 16**3


@settings(deadline=None, max_examples=15)
@given(seed=st.integers(0, 2**32 - 1))
def test_edge_descent_agrees_with_naive_baseline(seed):
    _, _, fast = run_cuts(seed, 4, naive=False)
    _, _, naive = run_cuts(seed, 4, naive=True)
    assert fast == naive


def _box_store():
    store = MeshStore(EMPTY)
    return store, store.add_box([0, 0, 0], [4, 4, 4])


@pytest.mark.parametrize(
    ("plane", "proper", "side"),
    [
        ([1, 0, 0, -4], False, -1),   # coplanar with the face x = 4, box behind it
        ([-1, 0, 0, 4], False, 1),    # the same plane flipped
        ([1, 1, 0, -8], False, -1),   # contains the edge x = y = 4 only
        ([1, 1, 1, -12], False, -1),  # touches the corner (4, 4, 4) only
        ([1, 1, 1, 0], False, 1),     # touches the corner (0, 0, 0) only
        ([1, 0, 0, -9], False, -1),   # misses the box
        ([1, 1, 0, -4], True, 0),     # through two opposite edges (vertices on the plane)
        ([1, 0, 0, -2], True, 0),     # parallel to two faces, through the middle
        ([1, 1, 1, -6], True, 0),     # hexagonal section through edge midpoints
        ([1, -1, 0, 0], True, 0),     # diagonal plane through four vertices
    ],
)
def test_degenerate_planes(plane, proper, side):
    store, cell = _box_store()
    row = int(store.add_planes(to_wide([plane], W))[0])
    r = cut(store, cell, row)
    assert r.proper is proper
    if proper:
        assert store.exact_volume(r.negative) + store.exact_volume(r.positive) == 64
        store.check_cell(r.negative)
        store.check_cell(r.positive)
    else:
        assert r.side == side
        assert store.exact_volume(cell) == 64
        store.check_cell(cell)


def test_hexagonal_section_vertices_are_exact_midpoints():
    store, cell = _box_store()
    row = int(store.add_planes(to_wide([[1, 1, 1, -6]], W))[0])
    r = cut(store, cell, row)
    cap = [p for p in store.face_polygons(r.negative)[1] if len(p) == 6]
    assert len(cap) == 1
    pts = set(store.exact_vertices(cap[0]))
    expected = {(4, 2, 0), (4, 0, 2), (2, 4, 0), (0, 4, 2), (2, 0, 4), (0, 2, 4)}
    assert pts == {tuple(Fraction(x) for x in p) for p in expected}


def test_fractional_vertices_stay_exact_through_repeated_cuts():
    # Planes with coprime normals put vertices at fractional positions; cut again through them.
    store = MeshStore(EMPTY)
    cells = [store.add_box([-5, -5, -5], [5, 5, 5])]
    planes = [[3, 5, 7, -2], [7, -3, 2, 1], [-2, 7, 3, 4], [5, 2, -7, -3], [1, 1, 1, 0]]
    for plane in planes:
        row = int(store.add_planes(to_wide([plane], W))[0])
        new = []
        for c in cells:
            r = cut(store, c, row)
            new += [r.negative, r.positive] if r.proper else [c]
        cells = new
    assert sum(store.exact_volume(c) for c in cells) == 1000
    dens = {x.denominator for c in cells for p in store.exact_vertices(store.cell_vertices(c)) for x in p}
    assert max(dens) > 1  # really fractional


def test_descent_visits_few_vertices_on_a_large_polytope():
    from csgnb.bsp.extract import extract_cells
    from csgnb.bsp.scenes import tangent_plane_bsp
    from csgnb.mesh.halfedge import N_CLASSIFY

    tree = tangent_plane_bsp(400)
    r = 1 << 12
    store, _ = extract_cells(tree, [-2 * r] * 3, [2 * r] * 3)
    naive, _ = extract_cells(tree, [-2 * r] * 3, [2 * r] * 3, naive=True)
    assert store.counts[N_CLASSIFY] * 4 < naive.counts[N_CLASSIFY]


def test_bad_input():
    store, cell = _box_store()
    with pytest.raises(GeometryError, match="not a palette row"):
        cut(store, cell, 99)
    with pytest.raises(GeometryError, match="not a half-edge"):
        cut(store, 10**6, 0)
    with pytest.raises(GeometryError, match="lo < hi"):
        store.add_box([0, 0, 0], [0, 1, 1])
    with pytest.raises(GeometryError, match="bit"):
        store.add_planes(to_wide([[1, 0, 0, 0]], 256))
