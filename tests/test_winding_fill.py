"""``fill="winding"``: closed meshes that overlap, cross or fold, as the points they wind around positively.

References are independent of csgnb: winding numbers counted by brute force over every face with Python integers
(signed crossings of a segment to a random far point), and unit-voxel counts for unions of boxes.

``tests/data/drill_sweep_manifold3d.npz`` is a real input written by another library: manifold3d 3.5.4's union
(``Manifold.batch_boolean(..., OpType.Add)``, ``to_mesh64()``) of the 896 prisms of the paper's drill's first sweep
(``csgnb.apps.sweep.drill_sweeps(tools.twist_drill().on(grid), feed_per_turn=1.0).steps[0]``, hull points from
``Grid.fit([-12, -12, -16], [12, 12, 8], width)``), one mesh per width (128 and 256: ``vertices_W``, ``faces_W``,
``volume_W`` its volume by manifold3d). Rounded back onto the grid, both fold (refused as a solid); as a winding
fill they are the sweep.
"""

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb import GeometryError
from csgnb.bsp import BSP
from csgnb.bsp.build import bsp_from_mesh
from csgnb.bsp.tree import ON_BOUNDARY
from csgnb.bsp.winding import winding_bsp
from csgnb.exact import Grid
from csgnb.exact.budgets import budget
from csgnb.octree import Tool, Workpiece
from tests.test_bsp_build import SOLIDS, box, inverted, soup

DATA = Path(__file__).parent / "data" / "drill_sweep_manifold3d.npz"


# ---------------------------------------------------------------------------
# the reference: brute-force winding numbers (Python ints, every face)


def _orient(a, b, c, d):
    """Sign of det[b - a, c - a, d - a] for (k, 3) object arrays (rows broadcast)."""
    u, v, w = b - a, c - a, d - a
    det = (u[:, 0] * (v[:, 1] * w[:, 2] - v[:, 2] * w[:, 1]) - u[:, 1] * (v[:, 0] * w[:, 2] - v[:, 2] * w[:, 0])
           + u[:, 2] * (v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]))
    return np.array([(x > 0) - (x < 0) for x in det], np.int64)


def reference_winding(V, F, point, rng, tries: int = 20):
    """The winding number of the closed mesh at an integer point, or None on the surface (or undecided)."""
    A, B, C = (V[F[:, k]].astype(object) for k in range(3))
    keep = np.array([any(x) for x in np.cross(B - A, C - A)])  # faces of no area wind around nothing
    A, B, C = A[keep], B[keep], C[keep]
    p = np.array([int(x) for x in point], object)[None, :]
    span = int(np.abs(V).max()) * 4 + 10
    op = _orient(A, B, C, p)
    on_plane = op == 0
    if on_plane.any():  # on a face's plane: inside that face means on the surface
        a, b, c = A[on_plane], B[on_plane], C[on_plane]
        n = np.cross(b - a, c - a)
        inside = [all(np.dot(np.cross(e1 - e0, p[0] - e0), nn) >= 0 for e0, e1 in ((x, y), (y, z), (z, x)))
                  for x, y, z, nn in zip(a, b, c, n, strict=True)]
        if any(inside):
            return None
    for _ in range(tries):
        q = np.array([int(x) for x in rng.integers(-span, span, 3)], object)
        q[int(rng.integers(3))] = span * 3  # far outside
        oq = _orient(A, B, C, q[None, :])
        if np.any(on_plane & (oq == 0)):
            continue
        cross = (op * oq) < 0
        s = [_orient(np.repeat(p, cross.sum(), 0), np.repeat(q[None, :], cross.sum(), 0), X[cross], Y[cross])
             for X, Y in ((A, B), (B, C), (C, A))]
        s = np.stack(s, axis=1) if cross.any() else np.zeros((0, 3), np.int64)
        through = np.all(s >= 0, axis=1) | np.all(s <= 0, axis=1)
        if np.any(through & np.any(s == 0, axis=1)):
            continue  # through an edge or a corner
        return int(oq[cross][through].sum())
    return None


def voxel_winding_volume(boxes):
    """Unit voxels whose winding number is > 0 for boxes ``(lo, hi, +1 outward / -1 inward)``."""
    total = 0
    los = np.min([b[0] for b in boxes], axis=0)
    his = np.max([b[1] for b in boxes], axis=0)
    for x in range(los[0], his[0]):
        for y in range(los[1], his[1]):
            for z in range(los[2], his[2]):
                w = sum(s for lo, hi, s in boxes if all(lo[k] <= c < hi[k] for k, c in enumerate((x, y, z))))
                total += w > 0
    return total


# ---------------------------------------------------------------------------
# valid solids: the same solid as fill="solid"


@pytest.mark.parametrize("name", sorted(SOLIDS))
def test_a_valid_solid_is_the_same_solid(name):
    V, F = SOLIDS[name]
    solid, winding = BSP.from_mesh(V, F), BSP.from_mesh(V, F, fill="winding")
    assert winding.volume() == solid.volume()
    lo, hi = V.min(axis=0) - 1, V.max(axis=0) + 1
    grid = np.stack(np.meshgrid(*(np.arange(lo[k], hi[k] + 1) for k in range(3)), indexing="ij"), -1).reshape(-1, 3)
    a, b = solid.classify(grid), winding.classify(grid)
    decided = (a != ON_BOUNDARY) & (b != ON_BOUNDARY)
    assert np.array_equal(a[decided], b[decided])


# ---------------------------------------------------------------------------
# overlapping, crossing, inverted parts: exact against voxel counts


def test_overlapping_boxes_are_their_union():
    report = {}
    V, F = soup(box([0, 0, 0], [4, 4, 4]), box([2, 1, 1], [6, 3, 3]))
    with pytest.raises(GeometryError, match="fill='winding'"):  # refused as a solid, and told what to pass
        bsp_from_mesh(V, F)
    winding_bsp(V, F, width=128, report=report)
    assert report["crossed_faces"] > 0 and report["pieces"] > 0
    assert BSP.from_mesh(V, F, fill="winding").volume() == 64 + 8


def test_inverted_parts_remove_and_cancel():
    outer, inner = box([0, 0, 0], [4, 4, 4]), box([1, 1, 1], [3, 3, 3])
    assert BSP.from_mesh(*soup(outer, inverted(inner)), fill="winding").volume() == 64 - 8  # a cavity
    assert BSP.from_mesh(*soup(outer, inner), fill="winding").volume() == 64  # wound twice: inside once
    assert BSP.from_mesh(*inverted(inner), fill="winding").volume() == 0  # inward alone: nothing
    assert BSP.from_mesh(*soup(inner, inverted(inner)), fill="winding").volume() == 0  # cancels face by face


_corner = st.integers(0, 5)


@st.composite
def _boxes(draw):
    boxes = []
    for _ in range(draw(st.integers(1, 4))):
        a = [draw(_corner) for _ in range(3)]
        b = [draw(_corner) for _ in range(3)]
        if any(x == y for x, y in zip(a, b, strict=True)):
            continue
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        boxes.append((lo, hi, draw(st.sampled_from([1, 1, -1]))))
    return boxes


@settings(max_examples=60, deadline=None)
@given(_boxes(), st.integers(0, 3))
def test_any_boxes_wind_to_the_voxel_count(boxes, seed):
    """Boxes anywhere in a 5-unit cube, overlapping, sharing planes and faces, some inward: the winding fill's
    exact volume is the number of unit voxels the boxes wind around positively."""
    if not boxes:
        return
    meshes = [box(lo, hi) if s > 0 else inverted(box(lo, hi)) for lo, hi, s in boxes]
    V, F = soup(*meshes)
    solid = BSP.from_mesh(V, F, fill="winding", seed=seed)
    assert solid.volume() == voxel_winding_volume(boxes)


def test_open_meshes_are_refused_with_the_edge():
    V, F = box([0, 0, 0], [4, 4, 4])
    with pytest.raises(GeometryError, match="not closed: edge .* run [+-]1 more times one way"):
        bsp_from_mesh(V, F[1:], fill="winding")
    with pytest.raises(ValueError, match="fill must be one of"):
        bsp_from_mesh(V, F, fill="nonzero")


# ---------------------------------------------------------------------------
# a real input: manifold3d's drill sweep, rounded onto the grid


def _drill_sweep(width):
    data = np.load(DATA)
    grid = Grid.fit([-12, -12, -16], [12, 12, 8], width=width)
    return grid, grid.to_grid(data[f"vertices_{width}"]), data[f"faces_{width}"].astype(np.int64), \
        float(data[f"volume_{width}"])


@pytest.mark.parametrize("width", [128, 256])
def test_manifold3ds_drill_sweep_folds_when_rounded_and_winds_to_the_sweep(width):
    grid, V, F, volume = _drill_sweep(width)
    with pytest.raises(GeometryError, match="not manifold|intersects itself"):
        Tool.from_mesh(V, F, width=width, grid=grid)
    report = {}
    tree = winding_bsp(V, F, width=width, report=report)
    assert report["collapsed_faces"] > 0 and report["crossed_faces"] > 0 and report["pieces"] > 0
    lo, hi = V.min(axis=0) - 1, V.max(axis=0) + 1
    solid = BSP(tree, tuple(lo.tolist()), tuple(hi.tolist()))
    # the Tool and Workpiece paths hold the same solid, exactly
    work = Workpiece.from_mesh(V, F, grid=grid, fill="winding")
    assert work.volume() == solid.volume()
    # within rounding of manifold3d's float volume (the grid: 2^-8 mm at 128 bits, 2^-22 mm at 256)
    model = float(work.model_volume())
    assert model == float(solid.volume() / Fraction(grid.scale) ** 3)
    assert abs(model - volume) / volume < (1e-3 if width == 128 else 1e-7)
    # every decided point has the label of its brute-force winding number
    rng = np.random.default_rng(width)
    points = rng.integers(lo, hi + 1, (60, 3))
    points = np.r_[points, (V[F[rng.integers(0, len(F), 60)]].sum(axis=1) // 3)]  # near the surface too
    labels = solid.classify(points)
    seen = set()
    for p, label in zip(points, labels, strict=True):
        w = reference_winding(V, F, p, rng)
        if w is None or label == ON_BOUNDARY:
            continue
        assert label == (1 if w > 0 else 0), (p.tolist(), w, label)
        seen.add(label)
    assert seen == {0, 1}


def _hull_mesh(points):
    """The convex hull of integer points as an outward triangle mesh (scipy's facets, oriented exactly)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    centre = points[hull.vertices].sum(axis=0)
    faces = []
    for f in hull.simplices:
        a, b, c = (points[i].astype(object) for i in f)
        if np.dot(np.cross(b - a, c - a), len(hull.vertices) * a - centre) < 0:
            f = f[::-1]
        faces.append(f)
    return points, np.array(faces, np.int64)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_crossing_hulls_classify_as_their_winding_numbers(seed):
    """Two or three convex hulls of random integer points, crossing at any angle (pieces with rational corners),
    one of them perhaps inward: every decided integer point has the label of its brute-force winding number."""
    rng = np.random.default_rng(seed)
    meshes, k = [], int(rng.integers(2, 4))
    for i in range(k):
        pts = rng.integers(-20, 21, (8, 3)) + rng.integers(-6, 7, 3)
        if np.linalg.matrix_rank(pts[1:] - pts[0]) < 3:
            return
        mesh = _hull_mesh(pts)
        meshes.append(inverted(mesh) if i == k - 1 and rng.random() < 0.3 else mesh)
    V, F = soup(*meshes)
    solid = BSP.from_mesh(V, F, fill="winding", seed=int(rng.integers(4)))
    points = rng.integers(V.min(axis=0) - 1, V.max(axis=0) + 2, (40, 3))
    for p, label in zip(points, solid.classify(points), strict=True):
        w = reference_winding(V, F, p, rng)
        if w is not None and label != ON_BOUNDARY:
            assert label == (1 if w > 0 else 0), (p.tolist(), w, label)


@pytest.mark.parametrize("seed", [4, 11, 13, 19])
def test_at_256_bits_the_segments_stay_in_integers_and_exact(seed):
    """A small hull (faces of normal ~1e10) beside a large far one (the mesh's extent ~1e9): at 256 bits a face's
    normal times the segment's reach exceeds int64. The far point's side was once checked in int64 (it wrapped:
    "no segment from a face centroid avoided every edge", 3 of the drill's 45 sweeps at 256 bits failed so); the
    points the result classifies must still have the labels of their brute-force winding numbers."""
    rng = np.random.default_rng(seed)
    small, large = rng.integers(-60_000, 60_001, (8, 3)), rng.integers(-80_000_000, 80_000_001, (8, 3))
    V, F = soup(_hull_mesh(small), _hull_mesh(large))
    solid = BSP.from_mesh(V, F, fill="winding", width=256)
    points = np.r_[rng.integers(-60_000, 60_001, (15, 3)), rng.integers(-80_000_000, 80_000_001, (15, 3))]
    for p, label in zip(points, solid.classify(points), strict=True):
        w = reference_winding(V, F, p, rng)
        if w is not None and label != ON_BOUNDARY:
            assert label == (1 if w > 0 else 0), (p.tolist(), w, label)


def _fraction_crossings(V, F, x, q):
    """Signed crossings of the segment x -> q (Fractions, ints) with every face, counted in Fractions; faces whose
    plane holds x count 0 (the segment leaves them at once); None where it passes through an edge or a corner."""
    def det(u, v, w):
        return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))

    total = 0
    for f in F.tolist():
        a, b, c = ([int(t) for t in V[i]] for i in f)
        u, v = [b[k] - a[k] for k in range(3)], [c[k] - a[k] for k in range(3)]
        op = det(u, v, [x[k] - a[k] for k in range(3)])
        oq = det(u, v, [q[k] - a[k] for k in range(3)])
        if op == 0 or oq == 0 or (op > 0) == (oq > 0):
            continue
        t = [q[k] - x[k] for k in range(3)]
        sides = [det(t, [s[k] - x[k] for k in range(3)], [e[k] - s[k] for k in range(3)])
                 for s, e in ((a, b), (b, c), (c, a))]
        if any(s > 0 for s in sides) and any(s < 0 for s in sides):
            continue
        if any(s == 0 for s in sides):
            return None
        total += 1 if oq > 0 else -1
    return total


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(4, 26), st.sampled_from(["inside", "near an edge", "at a corner"]),
       st.booleans())
def test_the_pieces_segment_counts_are_exact_at_any_magnitude(seed, bits, where, through_a_corner):
    """The segment count a crossed face's piece is kept or dropped by (doubles first, the undecided faces in
    integers) against Fractions over every face: from a rational point on a face's plane (where every piece's
    centroid is: doubles cannot tell its own face's side) -- inside the face, a hair from an edge, or at a
    corner -- to a far integer point or through a corner of another face, on crossing hulls of coordinates out to
    the 256-bit mesh budget's edge (~2**26.4). A filter bound too small for the doubles' error fails this."""
    from csgnb.bsp.winding import _CrossedFaces

    rng = np.random.default_rng(seed)
    reach = budget(256).max_mesh_coordinate - 2**bits  # centres out to the 256-bit mesh budget's edge
    centre = rng.integers(-reach, reach + 1, 3)
    meshes = []
    for _ in range(2):
        pts = centre + rng.integers(-(2**bits) // 2, 2**bits // 2 + 1, (8, 3))
        if np.linalg.matrix_rank(pts[1:] - pts[0]) < 3:
            return
        meshes.append(_hull_mesh(pts))
    V, F = soup(*meshes)
    V = np.asarray(V, np.int64)
    normal = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    faces = _CrossedFaces(V, F, normal, None, None, np.zeros((0, 2), np.int64))
    for _ in range(6):
        f = int(rng.integers(F.shape[0]))
        weights = [int(w) for w in rng.integers(1, 2**20, 3)]
        if where == "near an edge":
            weights[int(rng.integers(3))] = 1
            weights = [w * 2**30 if w > 1 else w for w in weights]
        elif where == "at a corner":
            weights = [1, 0, 0]
        corners = [[int(c) for c in V[i]] for i in F[f]]
        D = sum(weights)
        X = [sum(w * c[k] for w, c in zip(weights, corners, strict=True)) for k in range(3)]
        if through_a_corner:  # beyond a corner a of any face: q = a + D a - X passes through it
            a = [int(c) for c in V[int(rng.integers(V.shape[0]))]]
            q = [(D + 1) * a[k] - X[k] for k in range(3)]
            if max(abs(c) for c in q) >= 2**52 or q == [X[k] // D for k in range(3)]:
                continue
        else:
            reach = 4 * int(V.max() - V.min())
            q = [X[k] // D + int(c) for k, c in enumerate(rng.integers(-reach, reach + 1, 3))]
        x = [Fraction(X[k], D) for k in range(3)]
        assert faces._crossings(X, D, q) == _fraction_crossings(V, F, x, q), (f, X, D, q)
