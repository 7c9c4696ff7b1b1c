"""Exact BSP Booleans (merge by mesh cutting) and redundancy removal, fuzzed as in paper §4.3.

For random BSP pairs and every operation: (a) the label the result gives random rational
points (walked with Fractions) equals the merge function of the inputs' labels; (b) exact
volumes satisfy |A∪B| + |A∩B| = |A| + |B| and |A−B| = |A| − |A∩B|; (c) redundancy removal
changes no classification and never increases the node count.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb import GeometryError
from csgnb.bsp import (
    BSP,
    DIFFERENCE,
    INTERSECTION,
    SYMMETRIC_DIFFERENCE,
    UNION,
    BSPTree,
    extract_boundary,
    merge,
    random_bsp,
    remove_redundancy,
)
from csgnb.exact import from_wide

EXTENT = 32
LO, HI = [-EXTENT] * 3, [EXTENT] * 3
OPS = {"union": UNION, "intersection": INTERSECTION, "difference": DIFFERENCE, "xor": SYMMETRIC_DIFFERENCE}


def label_at(tree: BSPTree, point) -> int | None:
    """Label at a rational point, walking the tree with Fractions; None on a splitting plane."""
    planes = [[int(x) for x in row] for row in from_wide(tree.palette)]
    node = 0
    while tree.plane[node] >= 0:
        a, b, c, d = planes[tree.plane[node]]
        v = a * point[0] + b * point[1] + c * point[2] + d
        if v == 0:
            return None
        node = tree.neg[node] if v < 0 else tree.pos[node]
    return int(tree.label[node])


def random_points(rng, n):
    return [tuple(Fraction(int(rng.integers(-EXTENT * 97, EXTENT * 97)), 97) for _ in range(3)) for _ in range(n)]


def volume(tree: BSPTree) -> Fraction:
    return extract_boundary(tree, LO, HI).surface.exact_volume()


def check_pair(a: BSPTree, b: BSPTree, rng, n_points: int = 40) -> int:
    va, vb = volume(a), volume(b)
    points = random_points(rng, n_points)
    vols, cases = {}, 0
    for name, fn in OPS.items():
        result = merge(a, b, fn, LO, HI)
        simple = remove_redundancy(result, seed=int(rng.integers(0, 1000)))
        assert simple.n_nodes <= result.tree.n_nodes
        surface = result.surface()
        assert surface.is_closed()
        vols[name] = surface.exact_volume()
        assert volume(result.tree) == vols[name]
        assert volume(simple) == vols[name]
        for p in points:
            la, lb, lr, ls = (label_at(t, p) for t in (a, b, result.tree, simple))
            if None in (la, lb, lr, ls):
                continue  # on a plane: measure zero for random points, skipped
            assert lr == fn(la, lb)
            assert ls == lr
            cases += 1
    assert vols["union"] + vols["intersection"] == va + vb
    assert vols["difference"] == va - vols["intersection"]
    assert vols["xor"] == vols["union"] - vols["intersection"]
    return cases


@settings(deadline=None, max_examples=12)
@given(na=st.integers(0, 12), nb=st.integers(0, 12), seed=st.integers(0, 2**32 - 1))
def test_random_booleans_classify_and_measure_exactly(na, nb, seed):
    rng = np.random.default_rng(seed)
    a = random_bsp(na, seed=seed, extent=EXTENT, max_normal=5)
    b = random_bsp(nb, seed=seed ^ 0x5EED, extent=EXTENT, max_normal=5)
    check_pair(a, b, rng)


@pytest.mark.slow
def test_random_booleans_long_fuzz():
    rng = np.random.default_rng(2026)
    pairs = cases = 0
    for _ in range(150):
        na, nb = (int(x) for x in rng.integers(1, 100, 2))
        seed = int(rng.integers(0, 2**31))
        a = random_bsp(na, seed=seed, extent=EXTENT, max_normal=7)
        b = random_bsp(nb, seed=seed + 1, extent=EXTENT, max_normal=7)
        cases += check_pair(a, b, rng, n_points=20)
        pairs += 1
    print(f"long fuzz: {pairs} BSP pairs x {len(OPS)} operations, {cases} point classifications checked")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_naive_cut_merges_like_edge_descent(seed):
    # The benchmarks' baseline: the naive cut must build the same output tree and the same solid.
    rng = np.random.default_rng(seed)
    na, nb = (int(x) for x in rng.integers(5, 40, 2))
    a = random_bsp(na, seed=seed, extent=EXTENT, max_normal=7)
    b = random_bsp(nb, seed=seed + 100, extent=EXTENT, max_normal=7)
    for fn in OPS.values():
        edge, naive = merge(a, b, fn, LO, HI), merge(a, b, fn, LO, HI, naive=True)
        for name in ("plane", "neg", "pos", "label"):
            np.testing.assert_array_equal(getattr(naive.tree, name), getattr(edge.tree, name))
        assert naive.surface().exact_volume() == edge.surface().exact_volume() == volume(edge.tree)


def test_multi_material_merge_function():
    a = random_bsp(8, seed=3, extent=EXTENT, max_normal=4, materials=3, p_in=0.8)
    b = random_bsp(8, seed=4, extent=EXTENT, max_normal=4, materials=2, p_in=0.8)

    def paint(la, lb):  # B's material paints over A's, offset so materials stay distinct
        return lb + 3 if lb else la

    result = merge(a, b, paint, LO, HI)
    rng = np.random.default_rng(0)
    for p in random_points(rng, 60):
        la, lb, lr = (label_at(t, p) for t in (a, b, result.tree))
        if None not in (la, lb, lr):
            assert lr == paint(la, lb)
    surface = result.surface()
    for label in set(surface.labels.tolist()):
        assert surface.is_closed(label)
    assert remove_redundancy(result) is result.tree  # multi-material: kept as merged


CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
CUBE_F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                   [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
TET_V = np.array([[0, 0, 0], [6, 0, 0], [0, 6, 0], [0, 0, 6]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
OCT_V = np.array([[4, 0, 0], [-4, 0, 0], [0, 4, 0], [0, -4, 0], [0, 0, 4], [0, 0, -4]])
OCT_F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])


@pytest.mark.parametrize(("vertices", "faces", "expected"), [
    (CUBE_V * 4 - 2, CUBE_F, Fraction(64)),
    (TET_V, TET_F, Fraction(36)),
    (OCT_V, OCT_F, Fraction(256, 3)),
])
def test_meshes_import_with_exact_volumes(vertices, faces, expected):
    solid = BSP.from_mesh(vertices, faces, lo=[-8] * 3, hi=[8] * 3)
    assert solid.volume() == expected
    assert solid.surface().is_closed()


def test_booleans_of_meshes_with_shared_faces_and_edges():
    cube = BSP.from_mesh(CUBE_V * 4, CUBE_F, lo=[-8] * 3, hi=[8] * 3)      # [0, 4]^3
    neighbour = BSP.from_mesh(CUBE_V * 4 + [4, 0, 0], CUBE_F, lo=[-8] * 3, hi=[8] * 3)  # shares the face x = 4
    diagonal = BSP.from_mesh(CUBE_V * 4 + [4, 4, 0], CUBE_F, lo=[-8] * 3, hi=[8] * 3)  # shares an edge
    octa = BSP.from_mesh(OCT_V, OCT_F, lo=[-8] * 3, hi=[8] * 3)
    u = cube | neighbour
    assert u.volume() == 128 and u.surface().is_manifold()
    assert (cube & neighbour).volume() == 0
    assert (cube - neighbour).volume() == 64
    e = cube | diagonal
    assert e.volume() == 128 and e.surface().is_closed() and not e.surface().is_manifold()
    # The octahedron's positive octant is the tetrahedron x + y + z <= 4: 32/3.
    assert (octa & cube).volume() == Fraction(32, 3)
    assert (octa | cube).volume() == Fraction(256, 3) + 64 - Fraction(32, 3)
    assert (octa ^ cube).volume() == Fraction(256, 3) + 64 - 2 * Fraction(32, 3)


def test_box_solids_doc_example():
    a, b = BSP.box([0, 0, 0], [4, 4, 4]), BSP.box([2, 2, 2], [6, 6, 6])
    assert ((a | b).volume(), (a & b).volume(), (a - b).volume(), (a ^ b).volume()) == (120, 8, 56, 112)
    assert (a | b).classify([[1, 1, 1], [5, 5, 5], [5, 1, 1], [10, 10, 10]]).tolist() == [1, 1, 0, 0]


def test_iterated_differences_stay_exact_and_small():
    block = BSP.box([0, 0, 0], [40, 40, 8])
    expected = Fraction(40 * 40 * 8)
    for k in range(12):
        x = 2 + 3 * k
        block = block - BSP.box([x, 10, 4], [x + 2, 30, 12])
        expected -= 2 * 20 * 4
    assert block.volume() == expected
    assert block.n_nodes < 200


def test_bad_input():
    a = BSP.box([0, 0, 0], [4, 4, 4])
    wide = BSP.box([0, 0, 0], [4, 4, 4], width=256)
    with pytest.raises(GeometryError, match="bit"):
        a | wide
    with pytest.raises(GeometryError, match="labels are >= 0"):
        a.merge(a, lambda x, y: -1)
    with pytest.raises(GeometryError):
        BSP.from_mesh(CUBE_V, CUBE_F[:-1])  # open
