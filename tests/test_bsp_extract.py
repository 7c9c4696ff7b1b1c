"""Boundary extraction of random BSPs, checked exactly with Python Fractions.

For random trees (paper §4.3) the extracted surface must be closed (every edge used as
often in each direction), free of T-junctions (no surface vertex strictly inside an
edge), enclose exactly the volume of the in-cells, and the in-cells must be the leaf
cells the tree says (a point inside each classifies to its label, walking the tree with
Fractions). Solid and complement together fill the box exactly.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb import GeometryError, PrecisionError
from csgnb._resumable import run_resumable
from csgnb.bsp.extract import extract_boundary, extract_cells
from csgnb.bsp.random_tree import random_bsp
from csgnb.bsp.scenes import tangent_plane_bsp
from csgnb.bsp.tree import BSPTree
from csgnb.exact import from_wide, to_wide

EXTENT = 32
LO, HI = [-EXTENT] * 3, [EXTENT] * 3


def classify_fraction(tree: BSPTree, point) -> int:
    """The label of the leaf containing ``point`` (Fractions), strictly inside a cell."""
    planes = [[int(x) for x in row] for row in from_wide(tree.palette)]
    node = 0
    while tree.plane[node] >= 0:
        a, b, c, d = planes[tree.plane[node]]
        v = a * point[0] + b * point[1] + c * point[2] + d
        assert v != 0, "an interior point lies on a splitting plane"
        node = tree.neg[node] if v < 0 else tree.pos[node]
    return int(tree.label[node])


def t_junctions(surface) -> list[tuple[int, int, int]]:
    """(a, b, v): surface vertex v strictly inside edge (a, b); exact, with a float prefilter."""
    pos = surface.exact_positions()
    fpos = surface.positions()
    found = []
    for poly in surface.polygons():
        for a, b in zip(poly, np.roll(poly, -1), strict=True):
            lo = np.minimum(fpos[a], fpos[b]) - 1e-9
            hi = np.maximum(fpos[a], fpos[b]) + 1e-9
            near = np.flatnonzero(np.all((fpos >= lo) & (fpos <= hi), axis=1))
            pa, pb = pos[a], pos[b]
            d = [pb[i] - pa[i] for i in range(3)]
            for v in near:
                if v in (a, b):
                    continue
                e = [pos[v][i] - pa[i] for i in range(3)]
                cross = (d[1] * e[2] - d[2] * e[1], d[2] * e[0] - d[0] * e[2], d[0] * e[1] - d[1] * e[0])
                if any(cross):
                    continue
                t = sum(d[i] * e[i] for i in range(3)) / sum(d[i] * d[i] for i in range(3))
                if 0 < t < 1:
                    found.append((int(a), int(b), int(v)))
    return found


def check_extraction(tree: BSPTree) -> None:
    ex = extract_boundary(tree, LO, HI)
    s = ex.surface
    cell_volume = {}
    for node, handle in ex.cells:
        ex.store.check_cell(int(handle))
        verts = ex.store.exact_vertices(ex.store.cell_vertices(int(handle)))
        centre = [sum(p[i] for p in verts) / len(verts) for i in range(3)]
        label = int(tree.label[node])
        assert classify_fraction(tree, centre) == label
        cell_volume[label] = cell_volume.get(label, 0) + ex.store.exact_volume(int(handle))
    assert s.is_closed()
    for label, volume in cell_volume.items():
        assert s.is_closed(label)
        assert s.exact_volume(label) == volume
    assert not t_junctions(s)
    return ex


@settings(deadline=None, max_examples=30)
@given(n_inner=st.integers(0, 24), seed=st.integers(0, 2**32 - 1))
def test_random_bsp_extraction_is_closed_conforming_and_exact(n_inner, seed):
    tree = random_bsp(n_inner, seed=seed, extent=EXTENT, max_normal=5)
    check_extraction(tree)


@settings(deadline=None, max_examples=10)
@given(n_inner=st.integers(1, 16), seed=st.integers(0, 2**32 - 1))
def test_multi_material_surfaces_close_per_material(n_inner, seed):
    tree = random_bsp(n_inner, seed=seed, extent=EXTENT, max_normal=4, materials=3, p_in=0.7)
    check_extraction(tree)


@settings(deadline=None, max_examples=15)
@given(n_inner=st.integers(0, 24), seed=st.integers(0, 2**32 - 1))
def test_solid_and_complement_fill_the_box(n_inner, seed):
    tree = random_bsp(n_inner, seed=seed, extent=EXTENT, max_normal=5)
    inner = tree.plane >= 0
    flipped = BSPTree(tree.palette, tree.plane, tree.neg, tree.pos, np.where(inner, -1, 1 - np.minimum(tree.label, 1)))
    v_in = extract_boundary(tree, LO, HI).surface.exact_volume()
    v_out = extract_boundary(flipped, LO, HI).surface.exact_volume()
    assert v_in + v_out == (2 * EXTENT) ** 3


@pytest.mark.slow
@settings(deadline=None, max_examples=200)
@given(n_inner=st.integers(0, 120), seed=st.integers(0, 2**32 - 1))
def test_random_bsp_extraction_long(n_inner, seed):
    check_extraction(random_bsp(n_inner, seed=seed, extent=EXTENT, max_normal=7))


def cube_tree(lo: int, hi: int) -> BSPTree:
    """The cube [lo, hi]^3 as a chain of six planes, inside = negative side."""
    rows = []
    for axis in range(3):
        for sign, bound in ((1, hi), (-1, lo)):
            n = [0, 0, 0]
            n[axis] = sign
            rows.append([*n, -sign * bound])
    k = len(rows)
    plane = list(range(k)) + [-1] * (k + 1)
    neg = list(range(1, k + 1)) + [-1] * (k + 1)
    pos = [k + 1 + i for i in range(k)] + [-1] * (k + 1)
    label = [-1] * k + [1] + [0] * k
    return BSPTree(to_wide(rows, 128), np.array(plane), np.array(neg), np.array(pos), np.array(label))


def test_cube_extracts_six_squares():
    ex = check_extraction(cube_tree(-3, 5))
    s = ex.surface
    assert s.n_polygons == 6 and s.n_vertices == 8
    assert s.exact_volume() == 8**3
    assert s.is_manifold()
    assert sorted(map(tuple, s.positions().tolist()))[0] == (-3.0, -3.0, -3.0)


def test_box_clips_the_solid():
    # The cube reaches beyond the box: the box faces close it.
    ex = check_extraction(cube_tree(-3, 50))
    assert ex.surface.exact_volume() == (EXTENT + 3) ** 3


def test_touching_cells_give_non_manifold_but_closed_edges():
    # Two cells meeting along one edge: x < 0 & y < 0 and x > 0 & y > 0.
    rows = [[1, 0, 0, 0], [0, 1, 0, 0]]
    plane = [0, 1, 1, -1, -1, -1, -1]
    neg = [1, 3, 5, -1, -1, -1, -1]
    pos = [2, 4, 6, -1, -1, -1, -1]
    label = [-1, -1, -1, 1, 0, 0, 1]
    tree = BSPTree(to_wide(rows, 128), np.array(plane), np.array(neg), np.array(pos), np.array(label))
    s = check_extraction(tree).surface
    assert s.is_closed() and not s.is_manifold()
    assert s.exact_volume() == 2 * (EXTENT * EXTENT * 2 * EXTENT)


def test_tangent_sphere_polytope():
    tree = tangent_plane_bsp(60, radius=1000, normal_scale=200)
    ex = extract_boundary(tree, [-2000] * 3, [2000] * 3)
    s = ex.surface
    assert s.n_polygons == 60 and s.is_manifold()
    (_, handle), = ex.cells
    assert s.exact_volume() == ex.store.exact_volume(int(handle))
    r = np.linalg.norm(s.positions(), axis=1)
    assert r.min() >= 1000 - 1 and s.exact_volume() > Fraction(4, 3) * 3 * 1000**3


def test_polydata_view():
    pd = extract_boundary(cube_tree(0, 4), LO, HI).surface.to_polydata()
    assert pd.n_cells == 12 and pd.n_points == 8
    assert np.isclose(pd.volume, 64.0)


def test_bad_input():
    tree = cube_tree(0, 4)
    with pytest.raises(GeometryError, match="lo < hi"):
        extract_boundary(tree, [0, 0, 0], [0, 4, 4])
    with pytest.raises(PrecisionError):
        extract_boundary(tree, [-(1 << 124)] * 3, [1 << 124] * 3)
    with pytest.raises(GeometryError, match="tree"):
        BSPTree(tree.palette, np.array([0, -1, -1]), np.array([1, -1, -1]), np.array([1, -1, -1]),
                np.array([-1, 1, 0]))
    cells = extract_cells(BSPTree.leaf(tree.palette, 0), LO, HI)[1]
    assert cells.shape == (0, 2)


@pytest.mark.parametrize("seed", range(4))
def test_keeping_cells_grows_no_pieces_and_resumes_only_for_the_store(seed):
    """An extraction that keeps cells (what every exact volume runs) sizes its cell list by the tree's leaves and
    never grows the pieces or clip scratch it does not write: it used to start with 16 cell rows and, at every
    resumption, grow both anyway (a relief milling run: 350 resumptions, 1.6 GB of wide piece rows copied for
    nothing, a fifth of its time). The cells are the same either way."""
    from csgnb.bsp.extract import KEEP_CELLS, Extractor

    tree = random_bsp(300, seed=seed, extent=1000)
    ex = Extractor(tree, [-1000] * 3, [1000] * 3, KEEP_CELLS, capacity=1 << 16)
    pieces, scratch = ex.out.vx.shape[0], ex.sc.pool.shape[0]
    resumptions = run_resumable(ex.step, ex.grow, "extraction")
    kept = ex.cells[: ex.state[1]]
    assert kept.shape[0] > 16 and resumptions == 0
    assert ex.out.vx.shape[0] == pieces and ex.sc.pool.shape[0] == scratch
    # a store too small to start with resumes, for the store alone, and keeps the same cells
    small = Extractor(tree, [-1000] * 3, [1000] * 3, KEEP_CELLS, capacity=64)
    assert run_resumable(small.step, small.grow, "extraction") > 0
    assert small.out.vx.shape[0] == pieces and small.sc.pool.shape[0] == scratch
    assert np.array_equal(small.cells[: small.state[1], 0], kept[:, 0])


@settings(deadline=None, max_examples=25)
@given(n_inner=st.integers(1, 40), seed=st.integers(0, 2**32 - 1), width=st.sampled_from([128, 192, 256]))
def test_the_wide_surface_volume_is_the_fraction_volume(n_inner, seed, width):
    """``BoundarySurface.exact_volume`` (terms made in limbs, summed in GMP) equals Fraction arithmetic on the exact
    vertex positions, per label and in all, at every width."""
    from csgnb.mesh.halfedge import polygons_volume
    from csgnb.mesh.volume import wide_polygons_volume

    tree = random_bsp(n_inner, seed=seed, extent=EXTENT, max_normal=7, materials=3, width=width)
    s = extract_boundary(tree, LO, HI).surface
    pos = s.exact_positions()
    polygons = s.polygons()
    for label in [None, *sorted(set(s.labels.tolist()))]:
        chosen = [p for i, p in enumerate(polygons) if label is None or s.labels[i] == label]
        assert s.exact_volume(label) == polygons_volume([[pos[v] for v in p] for p in chosen])
    with pytest.raises(ValueError, match="one entry per polygon"):
        wide_polygons_volume(s.vertices, s.offsets, s.indices, np.ones(s.n_polygons + 1, bool))
