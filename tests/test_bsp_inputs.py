"""Bad and edge input of the BSP API: nested shells, integral values, boxes, mesh objects, widths, labels."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from csgnb import GeometryError, PrecisionError
from csgnb.bsp import BSP, bsp_from_mesh
from csgnb.bsp.merging import merge_table
from csgnb.bsp.tree import BSPTree


def box_mesh(lo, hi, *, inward=False):
    """The 12 outward (or inward) triangles of an axis-aligned box with integer corners."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    V = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], np.int64)
    F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return V, (F[:, ::-1] if inward else F).copy()


def soup(*meshes):
    Vs, Fs, offset = [], [], 0
    for V, F in meshes:
        Vs.append(V)
        Fs.append(F + offset)
        offset += V.shape[0]
    return np.concatenate(Vs), np.concatenate(Fs)


def test_box_mesh_is_outward():
    V, F = box_mesh([0, 0, 0], [2, 3, 4])
    assert BSP.from_mesh(V, F).volume() == 24


# ---------------------------------------------------------------------------
# nesting


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_nested_outward_shells_are_refused(seed):
    V, F = soup(box_mesh([0, 0, 0], [10, 10, 10]), box_mesh([3, 3, 3], [6, 6, 6]))
    with pytest.raises(GeometryError, match=r"shell 1 \(12 faces, the first is face 12\) lies inside shell 0 and "
                                            "also faces outward"):
        BSP.from_mesh(V, F, seed=seed)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_cavities_facing_inward_work(seed):
    V, F = soup(box_mesh([0, 0, 0], [10, 10, 10]), box_mesh([3, 3, 3], [6, 6, 6], inward=True))
    assert BSP.from_mesh(V, F, seed=seed).volume() == 1000 - 27
    # An island inside the cavity, facing outward again.
    V, F = soup(box_mesh([0, 0, 0], [10, 10, 10]), box_mesh([2, 2, 2], [8, 8, 8], inward=True),
                box_mesh([4, 4, 4], [6, 6, 6]))
    assert BSP.from_mesh(V, F, seed=seed).volume() == 1000 - 216 + 8


def test_bad_nestings_name_the_shell():
    with pytest.raises(GeometryError, match="shell 1 .* oriented inward .* lies inside no other shell"):
        bsp_from_mesh(*soup(box_mesh([0, 0, 0], [2, 2, 2]), box_mesh([5, 5, 5], [7, 7, 7], inward=True)))
    # A cavity inside a cavity.
    with pytest.raises(GeometryError, match="shell 2 .* inward but lies in empty space .* cavity shell 1"):
        bsp_from_mesh(*soup(box_mesh([0, 0, 0], [10, 10, 10]), box_mesh([2, 2, 2], [8, 8, 8], inward=True),
                            box_mesh([4, 4, 4], [6, 6, 6], inward=True)))
    # Three outward shells in a row.
    with pytest.raises(GeometryError, match="shell 1 .* lies inside shell 0"):
        bsp_from_mesh(*soup(box_mesh([0, 0, 0], [10, 10, 10]), box_mesh([2, 2, 2], [8, 8, 8]),
                            box_mesh([4, 4, 4], [6, 6, 6])))


def test_disjoint_and_touching_shells_are_fine():
    V, F = soup(box_mesh([0, 0, 0], [2, 2, 2]), box_mesh([5, 0, 0], [7, 2, 2]), box_mesh([0, 5, 0], [1, 6, 1]))
    assert BSP.from_mesh(V, F).volume() == 8 + 8 + 1
    # A cavity whose bounding box holds another outer shell's test point: only the winding number decides.
    V, F = soup(box_mesh([0, 0, 0], [10, 10, 10]), box_mesh([1, 1, 1], [9, 9, 9], inward=True),
                box_mesh([20, 0, 0], [22, 2, 2]))
    assert BSP.from_mesh(V, F).volume() == 1000 - 512 + 8


def l_prism(height):
    """An L-shaped prism (the square [0, 8]^2 without [4, 8]^2), 0 <= z <= height, outward."""
    ring = [(0, 0), (8, 0), (8, 4), (4, 4), (4, 8), (0, 8)]
    V = np.array([[x, y, z] for z in (0, height) for x, y in ring], np.int64)
    cap = [(3, 4, 5), (3, 5, 0), (3, 0, 1), (3, 1, 2)]  # a fan from the reflex corner (4, 4)
    F = [list(t[::-1]) for t in cap] + [[i + 6 for i in t] for t in cap]
    for i in range(6):
        j = (i + 1) % 6
        F += [[i, j, j + 6], [i, j + 6, i + 6]]
    F = np.array(F)
    if (V[F[:, 0]] * np.cross(V[F[:, 1]], V[F[:, 2]])).sum() < 0:
        F = F[:, ::-1]
    return V, F


def test_nesting_against_a_non_convex_container():
    V, F = l_prism(4)
    assert BSP.from_mesh(V, F).volume() == 48 * 4
    # In the notch: inside the L's bounding box but outside the L.
    assert BSP.from_mesh(*soup((V, F), box_mesh([5, 5, 1], [6, 6, 2]))).volume() == 48 * 4 + 1
    with pytest.raises(GeometryError, match="lies inside shell 0"):
        BSP.from_mesh(*soup((V, F), box_mesh([1, 1, 1], [2, 2, 2])))
    assert BSP.from_mesh(*soup((V, F), box_mesh([1, 5, 1], [2, 7, 3], inward=True))).volume() == 48 * 4 - 4


# ---------------------------------------------------------------------------
# values that used to be truncated


def test_boxes_and_points_must_be_integral():
    with pytest.raises(PrecisionError, match=r"hi\[0\] = 2.7 is not an integer.*quantize"):
        BSP.box([0, 0, 0], [2.7] * 3)
    assert BSP.box([0, 0, 0], [2.0] * 3).volume() == 8
    cube = BSP.box([0, 0, 0], [4, 4, 4])
    with pytest.raises(PrecisionError, match=r"points\[0\] = 4.5 is not an integer"):
        cube.classify([4.5, 1, 1])
    assert cube.classify([[2.0, 1, 1], [5, 1, 1]]).tolist() == [1, 0]
    with pytest.raises(GeometryError, match="not finite"):
        cube.classify([np.nan, 1, 1])
    with pytest.raises(GeometryError, match="not finite"):
        BSP.box([0, 0, np.nan], [1, 1, 1])
    with pytest.raises(GeometryError, match=r"lo must be a point \(3,\)"):
        BSP.box([0, 0], [1, 1, 1])
    with pytest.raises(GeometryError, match=r"shape \(n, 3\)"):
        cube.classify([[1, 2]])


def test_label_functions_must_return_integer_labels():
    cube = BSP.box([0, 0, 0], [4, 4, 4])
    with pytest.raises(GeometryError, match=r"returned 0.5 for labels \(0, 0\)"):
        cube.merge(cube, lambda a, b: 0.5)
    with pytest.raises(TypeError, match="returned None"):
        cube.merge(cube, lambda a, b: None)
    with pytest.raises(TypeError, match="returned '1'"):
        cube.merge(cube, lambda a, b: "1")
    with pytest.raises(GeometryError, match="int32"):
        cube.merge(cube, lambda a, b: 2**40)
    with pytest.raises(TypeError, match="callable"):
        cube.merge(cube, 5)
    assert merge_table(lambda a, b: float(max(a, b)), [0, 1], [0, 1]).tolist() == [[0, 1], [1, 1]]
    assert (cube.merge(cube, lambda a, b: 1.0 if a or b else 0.0)).volume() == 64


def test_seeds_and_margins():
    V, F = box_mesh([0, 0, 0], [2, 2, 2])
    with pytest.raises(GeometryError, match="seed must be a non-negative integer"):
        BSP.from_mesh(V, F, seed=-1)
    with pytest.raises(TypeError, match="seed"):
        BSP.from_mesh(V, F, seed="x")
    with pytest.raises(GeometryError, match="margin must be >= 0"):
        BSP.from_mesh(V, F, margin=-1)
    with pytest.raises(PrecisionError, match="margin"):
        BSP.from_mesh(V, F, margin=0.5)
    with pytest.raises(GeometryError, match="label must be"):
        bsp_from_mesh(V, F, label=0.5)
    with pytest.raises(GeometryError, match="label must be"):
        bsp_from_mesh(V, F, label=2**40)


def test_a_box_smaller_than_the_mesh_is_refused():
    V, F = box_mesh([0, 0, 0], [4, 4, 4])
    with pytest.raises(GeometryError, match=r"does not contain the mesh .* \[0, 0, 0\]..\[4, 4, 4\]"):
        BSP.from_mesh(V, F, lo=[1, 0, 0], hi=[9, 9, 9])
    with pytest.raises(GeometryError, match="does not contain the mesh"):
        BSP.from_mesh(V, F, lo=[-1, -1, -1], hi=[3, 5, 5])
    assert BSP.from_mesh(V, F, margin=0).volume() == 64  # touching the box is fine


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.uint32, np.int8, np.int16])
def test_small_integer_dtypes_do_not_wrap(dtype):
    hi = np.iinfo(dtype).max
    V, F = box_mesh([hi - 4] * 3, [hi] * 3) if hi <= 4567 else box_mesh([2000, 2000, 2000], [2004, 2004, 2004])
    solid = BSP.from_mesh(V.astype(dtype), F)
    assert solid.volume() == 64
    assert max(solid.hi) == int(V.max()) + 1


# ---------------------------------------------------------------------------
# operands and mesh objects


def test_booleans_with_non_bsps_say_what_to_pass():
    import pyvista as pv

    cube = BSP.box([0, 0, 0], [4, 4, 4])
    with pytest.raises(TypeError, match="combines only with another BSP, got int"):
        cube | 5
    with pytest.raises(TypeError, match="got PolyData: import it first with BSP.from_mesh"):
        cube - pv.Cube()
    with pytest.raises(TypeError, match="BSPTree"):
        BSP(5, [0, 0, 0], [1, 1, 1])


def test_from_mesh_reads_mesh_objects_and_files(tmp_path):
    import pyvista as pv

    cube = pv.Box(bounds=(0, 4, 0, 4, 0, 4))  # quads, float32 integral points
    assert BSP.from_mesh(cube).volume() == 64
    tri = cube.triangulate()
    path = tmp_path / "cube.stl"
    tri.save(path)
    assert BSP.from_mesh(path).volume() == 64
    assert BSP.from_mesh(str(path)).volume() == 64
    import meshio

    mesh = meshio.read(path)
    assert BSP.from_mesh(mesh).volume() == 64
    with pytest.raises(PrecisionError, match="quantize"):
        BSP.from_mesh(pv.Sphere())
    with pytest.raises(FileNotFoundError):
        BSP.from_mesh(tmp_path / "missing.stl")
    with pytest.raises(TypeError, match="pyvista PolyData, a trimesh.Trimesh, a meshio.Mesh"):
        BSP.from_mesh(5)
    trimesh = pytest.importorskip("trimesh")
    assert BSP.from_mesh(trimesh.creation.box(extents=(2, 2, 2))).volume() == 8


# ---------------------------------------------------------------------------
# widths


def test_to_width_converts_and_checks_the_budget():
    a = BSP.box([0, 0, 0], [4, 4, 4])
    b = BSP.box([2, 2, 2], [6, 6, 6], width=256)
    with pytest.raises(GeometryError, match=r"128-bit BSP with a 256-bit BSP: convert one first, e.g. "
                                            r"other.to_width\(128\)"):
        a | b
    assert (a | b.to_width(128)).volume() == 120
    assert (a.to_width(256) | b).volume() == 120
    assert a.to_width(128) is a and a.to_width(192).tree.width == 192
    # A 256-bit plane beyond the 128-bit budget cannot come down.
    V, F = box_mesh([0, 0, 0], [10**6, 10**6, 1])
    big = BSP.from_mesh(V, F, width=256)
    assert big.volume() == Fraction(10**12)
    tilted = BSPTree(big.tree.palette.copy(), big.tree.plane, big.tree.neg, big.tree.pos, big.tree.label)
    from csgnb import exact

    tilted.palette[0] = exact.to_wide([2**40, 1, 1, 2**80], 256)
    with pytest.raises(PrecisionError):
        BSP(tilted, big.lo, big.hi).to_width(128)
