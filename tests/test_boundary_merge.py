"""Booleans from both operands' boundaries (``csgnb.bsp.boundary_merge``) and the cells that keep theirs
(``csgnb.octree.piece_cache``).

The reference is the merge by cutting (``csgnb.bsp.merge``): regions are compared exactly (the symmetric difference
of two trees, merged by cutting, has no inside cell). Inputs are chosen to meet each other's faces -- boxes on a
coarse grid share planes, faces and edges with each other, with earlier cuts and with the octree's cell walls --
which is where a piece lies in a plane of the other tree (its two sides then see different labels) and where a
boundary would be kept twice or not at all.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb.bsp import DIFFERENCE, INTERSECTION, SYMMETRIC_DIFFERENCE, UNION
from csgnb.bsp.boundary_merge import boolean_from_boundaries, boundary_polygons, strictly_outside
from csgnb.bsp.build import bsp_from_mesh, bsp_from_polygons
from csgnb.bsp.extract import tree_arrays
from csgnb.bsp.merging import merge, remove_redundancy
from csgnb.bsp.tree import BSPTree
from csgnb.exact import to_wide
from csgnb.exact.budgets import budget
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Tool, Workpiece
from csgnb.octree.layout import S_BOUNDARY_MERGES
from csgnb.octree.persist import WorkpieceFileError, read_arrays, write_arrays

LO, HI = (-16, -16, -16), (16, 16, 16)
FUNCTIONS = {"union": UNION, "intersection": INTERSECTION, "difference": DIFFERENCE, "xor": SYMMETRIC_DIFFERENCE}
_BOX_FACES = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4], [2, 6, 7], [2, 7, 3],
                       [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])


def box_mesh(lo, hi):
    """The 12 outward triangles of the box ``[lo, hi]``."""
    lo, hi = np.asarray(lo, np.int64), np.asarray(hi, np.int64)
    corners = np.array([[(hi if i & (1 << c) else lo)[c] for c in range(3)] for i in range(8)], np.int64)
    return corners, _BOX_FACES.copy()


def random_solid(rng, width, scale: int = 1):
    """A box on a grid of 2 (shared planes) or a tetrahedron with small integer corners, times ``scale``."""
    if rng.random() < 0.6:
        lo = 2 * rng.integers(-8, 6, 3)
        return bsp_from_mesh(*box_mesh(scale * lo, scale * (lo + 2 * rng.integers(1, 6, 3))), width=width)
    while True:
        v = rng.integers(-14, 15, (4, 3))
        # corners moved off the scaled lattice: the planes' offsets use the budget's full width
        v = scale * v + (rng.integers(-scale // 4, scale // 4 + 1, (4, 3)) if scale > 1 else 0)
        e = (v[1:] - v[0]).astype(object)
        det = e[0, 0] * (e[1, 1] * e[2, 2] - e[1, 2] * e[2, 1]) - e[0, 1] * (e[1, 0] * e[2, 2] - e[1, 2] * e[2, 0]) \
            + e[0, 2] * (e[1, 0] * e[2, 1] - e[1, 1] * e[2, 0])
        if abs(det) > scale**3:
            break
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return bsp_from_mesh(v, faces if det > 0 else faces[:, ::-1], width=width)


def same_region(t1: BSPTree, t2: BSPTree, lo=LO, hi=HI) -> bool:
    x = merge(t1, t2, SYMMETRIC_DIFFERENCE, lo, hi).tree
    return not np.any(x.label[x.plane < 0] == 1)


def tree_of(palette, pieces) -> BSPTree:
    """The BSP of ``pieces`` over the whole ``palette`` (bsp_from_polygons keeps only its nodes' rows: map back)."""
    r = bsp_from_polygons(palette, pieces)
    rows = {palette[i].tobytes(): i for i in range(palette.shape[0] - 1, -1, -1)}
    back = np.array([rows[r.palette[i].tobytes()] for i in range(r.palette.shape[0])], np.int32)
    plane = np.where(r.plane >= 0, back[np.maximum(r.plane, 0)], -1).astype(np.int32)
    return BSPTree(palette, plane, r.neg, r.pos, r.label, validate=False)


def check_one(a, b, fn, lo=LO, hi=HI) -> tuple[int, bool]:
    """The boundary merge of a and b against the merge by cutting; (pieces, result is A)."""
    ta, pa = boundary_polygons(a, lo, hi)
    tb, pb = boundary_polygons(b, lo, hi)
    palette, pieces, unchanged = boolean_from_boundaries(ta, pa, tb, pb, fn)
    reference = merge(a, b, fn, lo, hi)
    if len(pieces) == 0:
        labels = np.unique(reference.tree.label[reference.tree.plane < 0])
        assert labels.shape[0] == 1  # no boundary left: one label
    else:
        assert same_region(tree_of(palette, pieces), reference.tree, lo, hi)
    assert unchanged == (not reference.changed)
    return len(pieces), unchanged


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([128, 256]))
def test_the_boundary_merge_gives_the_merge_of_the_solids(seed, width):
    """Random boxes (coplanar faces galore) and tetrahedra, every Boolean, against the merge by cutting; and
    whether the result is A, piece for piece, exactly when the merge changed no label of A."""
    rng = np.random.default_rng(seed)
    a, b = random_solid(rng, width), random_solid(rng, width)
    for fn in FUNCTIONS.values():
        check_one(a, b, fn)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([128, 256]))
def test_the_boundary_merge_at_the_edge_of_the_bit_budget(seed, width):
    """The same with corners up to ~90 % of the width's largest mesh coordinate (tetrahedra off the lattice: planes
    with offsets at the top of the budget, vertices as three-plane intersections at full width)."""
    v = budget(width).max_mesh_coordinate
    scale = v // 32
    rng = np.random.default_rng(seed)
    a, b = random_solid(rng, width, scale), random_solid(rng, width, scale)
    for fn in FUNCTIONS.values():
        check_one(a, b, fn, (-v, -v, -v), (v, v, v))


def test_shared_faces_are_kept_once_or_not_at_all():
    """Two boxes side by side: their union has no face at the contact (both sides in), their difference keeps A's
    face there once (A's piece decides; B's, on A's boundary, is dropped); a box with itself; a box minus its lower
    half, which shares five of its planes."""
    a = bsp_from_mesh(*box_mesh((0, 0, 0), (8, 8, 8)), width=128)
    b = bsp_from_mesh(*box_mesh((8, 0, 0), (12, 8, 8)), width=128)
    inner = bsp_from_mesh(*box_mesh((0, 0, 0), (8, 8, 4)), width=128)  # shares five faces' planes with a
    # the box [0, 12] x [0, 8]^2: both end faces, the four sides of each box (coplanar neighbours stay two
    # pieces), and nothing at the contact
    assert check_one(a, b, UNION)[0] == 2 + 4 + 4
    assert check_one(a, b, DIFFERENCE) == (6, True)  # b touches a only: a, piece for piece
    assert check_one(a, a, DIFFERENCE)[0] == 0
    assert check_one(a, a, UNION) == (6, True)
    assert check_one(a, a, INTERSECTION) == (6, True)
    # the upper half: a's top face whole, the upper parts of its four sides, inner's top face turned round; a's
    # bottom face (inner's too, the same orientation) dropped
    assert check_one(a, inner, DIFFERENCE) == (1 + 4 + 1, False)


@pytest.mark.parametrize("width", [128, 256])
def test_boundaries_passed_on_through_many_booleans(width):
    """A chain of 40 Booleans where each result's pieces are the next step's boundary of A (as the octree's cells
    keep them), compared with merge + redundancy removal at every step."""
    rng = np.random.default_rng(width)
    a = bsp_from_mesh(*box_mesh((-10, -10, -10), (10, 10, 10)), width=width)
    ta, pa = boundary_polygons(a, LO, HI)
    reference = a
    for step in range(40):
        b = random_solid(rng, width)
        fn = [DIFFERENCE, UNION, DIFFERENCE, INTERSECTION, SYMMETRIC_DIFFERENCE][step % 5 if step % 3 else 0]
        tb, pb = boundary_polygons(b, LO, HI)
        palette, pieces, _ = boolean_from_boundaries(ta, pa, tb, pb, fn)
        reference = remove_redundancy(merge(reference, b, fn, LO, HI))
        if len(pieces) == 0:
            labels = np.unique(reference.label[reference.plane < 0])
            assert labels.shape[0] == 1
            ta, pa = BSPTree.leaf(palette, int(labels[0])), pieces
            continue
        ta, pa = tree_of(palette, pieces), pieces
        assert same_region(ta, reference), step


def _strictly_outside_all(tree, points, width):
    """:func:`strictly_outside` of each integer point (n, 3) in ``tree``, from Python."""
    v = to_wide(np.column_stack([points, np.ones(len(points), np.int64)]), width)
    stack = np.empty(8, np.int64)  # small: a point on many planes at once runs out, and is then "not outside"
    t = tree_arrays(tree)
    return np.array([strictly_outside(tree.palette, v, i, t, stack) for i in range(len(points))])


@pytest.mark.parametrize("width", [128, 256])
@pytest.mark.parametrize("at_budget", [False, True])
def test_strictly_outside_never_claims_a_point_of_the_closed_solid(width, at_budget):
    """The boundary merge's shortcut rests on :func:`strictly_outside`: True only where a ball around the point
    misses the solid. Unions of grid boxes (planes shared, faces meeting) at every point of a lattice through their
    corners, edges and faces: never True on a closed box (exact: integer corners), always True two units away from
    all of them; for one box exactly the points off the closed box. ``at_budget``: the lattice scaled and moved to
    reach ~7/8 of the width's largest mesh coordinate (offsets and products at the top of the budget)."""
    rng = np.random.default_rng(width)
    v = budget(width).max_mesh_coordinate
    scale, shift = (v // 8, -6 * (v // 8)) if at_budget else (1, 0)  # the lattice -1 .. 13 to -7/8 v .. 7/8 v
    bounds = ((-v, -v, -v), (v, v, v)) if at_budget else (LO, HI)
    pts = np.array([[x, y, z] for x in range(-1, 14) for y in range(-1, 14) for z in range(-1, 14)], np.int64)
    for trial in range(12):
        boxes = []
        tree = None
        for _ in range(1 + trial % 3):
            lo = 2 * rng.integers(0, 4, 3)
            hi = lo + 2 * rng.integers(1, 3, 3)
            boxes.append((lo, hi))
            b = bsp_from_mesh(*box_mesh(shift + scale * lo, shift + scale * hi), width=width)
            tree = b if tree is None else remove_redundancy(merge(tree, b, UNION, *bounds))
        closed = np.zeros(len(pts), bool)
        far = np.ones(len(pts), bool)
        for lo, hi in boxes:
            closed |= np.all((pts >= lo) & (pts <= hi), axis=1)
            far &= np.any((pts < lo - 1) | (pts > hi + 1), axis=1)
        out = _strictly_outside_all(tree, shift + scale * pts, width)
        assert not np.any(out & closed), trial
        assert np.all(out[far]), trial
        if len(boxes) == 1:
            assert np.array_equal(out, ~closed), trial


def _box_tool(lo, hi, width, convex=False):
    if convex:  # the hull of the corners: its six planes (a convex tool)
        corners = [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        return convex_hull(np.array(corners))
    return Tool.from_mesh(*box_mesh(lo, hi), width=width)


def _hull_tool(rng, centre, radius, width, convex=False):
    d = rng.normal(size=(30, 3))
    points = np.rint(d / np.linalg.norm(d, axis=1)[:, None] * radius).astype(np.int64) + np.asarray(centre)
    if convex:
        return convex_hull(points)
    return Tool.from_mesh(*convex_hull(points).to_mesh(), width=width)


def _run(width, seed, cache: bool, steps: int = 24, tools: str = "mesh") -> Workpiece:
    """Random Booleans on a 64-unit block: lattice blocks, grid boxes and round hulls as ``tools`` ("mesh": mesh
    tools, "convex": convex hulls, "mixed": either, by chance)."""
    rng = np.random.default_rng(seed)
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24, width=width)
    w.boundary_cache = cache
    w.oc.counts[S_BOUNDARY_MERGES] = 0  # (building the box may have merged its cell from its boundary)
    for i in range(steps):
        r = rng.random()
        convex = tools == "convex" or (tools == "mixed" and rng.random() < 0.5)
        if r < 0.4:  # blocks of a lattice of 6: faces on earlier cuts, the same way round and the other
            lo = 6 * rng.integers(0, 10, 3) + 1
            tool = _box_tool(lo, lo + 6 * rng.integers(1, 3, 3), width, convex)
        elif r < 0.7:  # boxes on a grid of 4: faces on cell walls too
            lo = 4 * rng.integers(-2, 15, 3)
            tool = _box_tool(lo, lo + 4 * rng.integers(1, 6, 3), width, convex)
        else:
            tool = _hull_tool(rng, rng.integers(0, 64, 3), int(rng.integers(5, 14)), width, convex)
        op = "union" if i % 5 == 4 else ("intersection" if i == steps - 3 else "difference")
        getattr(w, op)(tool)
    return w


# (128, 1), (128, 6) and (256, 20) fail when a coplanar fragment's behind and front points are swapped
@pytest.mark.parametrize(("width", "seed"), [(128, 0), (128, 1), (128, 6), (256, 20)])
def test_cells_that_keep_their_boundary_carve_the_same_solid(width, seed):
    """Mesh-tool Booleans in a workpiece with the boundary cache (the default) and without it: the same exact volume
    and the same side for thousands of points after a run that merged most cells from their boundaries."""
    with_cache, without = _run(width, seed, True, steps=40), _run(width, seed, False, steps=40)
    assert with_cache.oc.counts[S_BOUNDARY_MERGES] > 50 and without.oc.counts[S_BOUNDARY_MERGES] == 0
    assert with_cache.stats.boundary_shortcuts > 0 and without.stats.boundary_shortcuts == 0
    assert with_cache.volume() == without.volume()
    pts = np.random.default_rng(seed).integers(-1, 66, size=(4000, 3))
    x = to_wide(np.column_stack([2 * pts + 1, np.full(len(pts), 2)]), width)  # half-integers: off every grid plane
    assert np.array_equal(with_cache.classify(x), without.classify(x))


@pytest.mark.parametrize(("width", "offset"), [(128, 0), (128, 1), (256, 1)])
def test_lattice_blocks_carved_and_filled_against_a_voxel_count(width, offset):
    """Blocks of a lattice of 4 removed and added back (mesh tools): each shares faces with the cavities and
    material earlier blocks left, the same way round and the other, and with offset 0 with the octree's cell
    walls; the exact volume after every Boolean equals the count of unit voxels of the same sequence."""
    rng = np.random.default_rng(11 + offset)
    w = Workpiece.box([0, 0, 0], [48, 48, 48], threshold=24, width=width)
    voxels = np.ones((48, 48, 48), bool)
    for step in range(60):
        lo = 4 * rng.integers(0, 11, 3) + offset
        hi = np.minimum(lo + 4 * rng.integers(1, 4, 3), 47)
        tool = _box_tool(lo, hi, width)
        if step % 4 == 3:
            w |= tool
            voxels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = True  # (the stock box bounds nothing: w is not clipped)
        else:
            w -= tool
            voxels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = False
        assert w.volume() == int(voxels.sum()), step
    assert w.oc.counts[S_BOUNDARY_MERGES] > 50


@pytest.mark.parametrize(("width", "seed", "tools"), [(128, 2, "convex"), (256, 3, "convex"), (128, 4, "mixed"),
                                                      (256, 5, "mixed")])
def test_convex_tools_merge_from_the_boundary_and_carve_the_same_solid(width, seed, tools):
    """Convex hulls merge a cell from its boundary too (their pieces: the cell's box cut by their crossing planes):
    with the cache and without, the same exact volume and the same side for thousands of points."""
    with_cache, without = _run(width, seed, True, 40, tools), _run(width, seed, False, 40, tools)
    assert with_cache.oc.counts[S_BOUNDARY_MERGES] > 50 and without.oc.counts[S_BOUNDARY_MERGES] == 0
    assert with_cache.stats.boundary_shortcuts > 0
    assert with_cache.volume() == without.volume()
    pts = np.random.default_rng(seed).integers(-1, 66, size=(4000, 3))
    x = to_wide(np.column_stack([2 * pts + 1, np.full(len(pts), 2)]), width)
    assert np.array_equal(with_cache.classify(x), without.classify(x))


#: 27 small boxes on a lattice of 12 in a 48-unit block (islands in a cavity, or voids)
_LATTICE_BOXES = [((8 + 12 * i, 8 + 12 * j, 8 + 12 * k), (12 + 12 * i, 12 + 12 * j, 12 + 12 * k))
                  for i in range(3) for j in range(3) for k in range(3)]


class _VoxelBlock:
    """A 48-unit block and its unit voxels: boxes subtracted or added to both, the exact volume checked each time."""

    def __init__(self, width, convex):
        self.width, self.convex = width, convex
        self.w = Workpiece.box([0, 0, 0], [48, 48, 48], threshold=24, width=width)
        self.voxels = np.ones((48, 48, 48), bool)

    def apply(self, lo, hi, union):
        tool = _box_tool(np.array(lo), np.array(hi), self.width, self.convex)
        if union:
            self.w.union(tool)
        else:
            self.w.difference(tool)
        self.voxels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = union
        assert self.w.volume() == int(self.voxels.sum())

    def round_each(self, union):
        """Boxes 2 units round each lattice box, and beside every other one a thin box that misses it."""
        shortcuts = self.w.stats.boundary_shortcuts
        for n, (lo, hi) in enumerate(_LATTICE_BOXES):
            if n % 2:
                self.apply((lo[0] + 5, lo[1] - 2, lo[2] - 2), (lo[0] + 7, hi[1] + 2, hi[2] + 2), union)
            self.apply(tuple(c - 2 for c in lo), tuple(c + 2 for c in hi), union)
        assert self.w.stats.boundary_shortcuts > shortcuts


@pytest.mark.parametrize(("width", "convex"), [(128, False), (128, True), (256, False)])
def test_a_tool_around_islands_removes_them(width, convex):
    """Where a difference's tool keeps none of its boundary in a cell (it runs through the cavity around an island
    of material), the cell changes only if some island lies inside the tool: islands in a cavity, each tool a box
    round one island with its faces in the cavity -- the shortcut must not call those cells unchanged -- and boxes
    in the cavity that miss the islands, which it should. Exact volumes against a voxel count."""
    block = _VoxelBlock(width, convex)
    block.apply((4, 4, 4), (44, 44, 44), False)  # the cavity
    for lo, hi in _LATTICE_BOXES:
        block.apply(lo, hi, True)
    block.round_each(False)  # the islands go
    assert block.w.volume() == 48**3 - 40**3


@pytest.mark.parametrize(("width", "convex"), [(128, False), (128, True), (256, False)])
def test_a_tool_around_voids_fills_them(width, convex):
    """The union's side of it: voids in a block, each tool a box round one void with its faces in the material
    (it keeps none of its boundary) -- the void must be filled -- and boxes in the material beside the voids, which
    change nothing. Exact volumes against a voxel count."""
    block = _VoxelBlock(width, convex)
    for lo, hi in _LATTICE_BOXES:
        block.apply(lo, hi, False)
    block.round_each(True)  # the voids are filled
    assert block.w.volume() == 48**3


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([128, 256]), st.booleans())
def test_islands_and_boxes_against_a_voxel_count(seed, width, convex):
    """A fuzz of the same: small blocks added in a cavity and boxes on a grid of 2 subtracted and added at random
    (round islands, beside them, through them, on their faces); the exact volume after every Boolean equals the
    voxel count."""
    rng = np.random.default_rng(seed)
    w = Workpiece.box([0, 0, 0], [32, 32, 32], threshold=16, width=width)
    voxels = np.ones((32, 32, 32), bool)
    w.difference(_box_tool(np.array([2, 2, 2]), np.array([30, 30, 30]), width, convex))
    voxels[2:30, 2:30, 2:30] = False
    for step in range(30):
        union = step < 8 or rng.random() < 0.2
        size = 2 * rng.integers(1, 3 if union else 6, 3)
        lo = 2 * rng.integers(1, 14, 3)
        hi = np.minimum(lo + size, 30)
        if union:
            w.union(_box_tool(lo, hi, width, convex))
        else:
            w.difference(_box_tool(lo, hi, width, convex))
        voxels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = union
        assert w.volume() == int(voxels.sum()), step


def test_the_cache_starts_with_the_first_boolean_of_any_tool():
    """A workpiece keeps no boundary until its first Boolean ("waiting": a loaded or built workpiece that is only
    looked at pays nothing); from the first convex hull on, every merge stores its cell's boundary and the next
    convex or mesh tool reads it."""
    w = Workpiece.empty(threshold=24)
    assert w.ws.pc.counts[0] == 0 and w._header()["boundary_cache"] == "waiting"
    for c in ([10, 10, 30], [30, 30, 30], [20, 20, 40]):
        w |= convex_hull(np.array(c) + np.array([[x, y, z] for x in (-9, 9) for y in (-9, 9) for z in (-9, 9)]))
    assert w.ws.pc.counts[0] > 0 and w._header()["boundary_cache"] == "on"
    assert w.stats.boundary_merges > 0


@pytest.fixture(scope="module")
def carved(tmp_path_factory):
    """A workpiece cut by mesh tools (its cells hold boundary pieces), saved."""
    w = _run(128, 7, True, steps=10)
    path = tmp_path_factory.mktemp("cache") / "w.npz"
    w.save(path)
    return w, path


def test_the_boundary_cache_is_saved_and_a_resumed_workpiece_goes_on_the_same(carved):
    """The cache decides how the next Booleans build their trees: saved with the workpiece, a loaded copy is the
    same state (digest) and stays the same through more Booleans; a file without it (written before it) loads
    with an empty cache and carves the same solid."""
    w, path = carved
    header, arrays = read_arrays(path)
    assert header["boundary_cache"] == "on" and arrays["pieces_rows"].shape[0] > 0
    loaded = Workpiece.load(path)
    assert loaded._state_digest() == w._state_digest()
    rng = np.random.default_rng(3)
    tools = [_hull_tool(rng, rng.integers(0, 64, 3), 9, 128) for _ in range(3)]
    same = Workpiece.load(path)
    for t in tools:
        loaded -= t
        same -= t
    assert loaded._state_digest() == same._state_digest()
    old = {k: v for k, v in arrays.items() if k not in ("oc_pieces", "pieces_rows", "pieces_size")}
    h = {k: v for k, v in header.items() if k not in ("format", "version", "sha256", "boundary_cache")}
    write_arrays(path.with_name("old.npz"), h, old)
    before = Workpiece.load(path.with_name("old.npz"))
    assert before.ws.pc.counts[0] == 0
    for t in tools:
        before -= t
    assert before.volume() == loaded.volume()


def _broken(path, header, arrays, **edits):
    h = {k: v for k, v in header.items() if k not in ("format", "version", "sha256")}
    a = dict(arrays)
    for k, v in edits.items():
        if k.startswith("h_"):
            h[k[2:]] = v
        elif v is None:
            a.pop(k)
        else:
            a[k] = v
    out = path.with_name("broken.npz")
    write_arrays(out, h, a)
    return out


def test_a_damaged_boundary_cache_is_refused(carved):
    """Crafted files (their checksum recomputed) whose cache arrays do not describe pieces of the palette."""
    _, path = carved
    header, a = read_arrays(path)
    size, rows, plen = a["pieces_size"], a["pieces_rows"], a["oc_pieces"]
    cases = {"pieces_size": {"pieces_size": np.where(np.arange(size.shape[0]) == 0, 2, size).astype(np.int32)},
             "not a plane": {"pieces_rows": np.where(np.arange(rows.shape[0]) == 1, 10**6, rows).astype(np.int32)},
             "only a BSP cell": {"oc_pieces": np.where(np.arange(plen.shape[0]) == 0, 5, plen).astype(np.int32)},
             "come together": {"pieces_size": None},
             "boundary_cache": {"h_boundary_cache": "sometimes"}}
    for message, edits in cases.items():
        with pytest.raises(WorkpieceFileError, match=message):
            Workpiece.load(_broken(path, header, a, **edits))


@pytest.mark.slow
@pytest.mark.parametrize("width", [128, 256])
def test_long_runs_with_and_without_the_cache(width):
    """Twelve runs of 120 Booleans each (lattice blocks, grid boxes, hulls as meshes; differences, unions and an
    intersection), with and without the boundary cache: the same exact volume and the same side of every sample
    point at the end of each."""
    for seed in range(12):
        a, b = _run(width, 100 + seed, True, steps=120), _run(width, 100 + seed, False, steps=120)
        assert a.volume() == b.volume(), seed
        pts = np.random.default_rng(seed).integers(-1, 66, size=(3000, 3))
        x = to_wide(np.column_stack([2 * pts + 1, np.full(len(pts), 2)]), width)
        assert np.array_equal(a.classify(x), b.classify(x)), seed
