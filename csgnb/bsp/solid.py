"""``BSP``: an exact solid as a BSP tree in a box, with Booleans and exact volume (paper §3.5-3.7).

>>> import numpy as np
>>> from csgnb.bsp import BSP
>>> cube = BSP.box([0, 0, 0], [4, 4, 4])
>>> shifted = BSP.box([2, 2, 2], [6, 6, 6])
>>> (cube | shifted).volume(), (cube & shifted).volume(), (cube - shifted).volume()
(Fraction(120, 1), Fraction(8, 1), Fraction(56, 1))
"""

from __future__ import annotations

import os
from collections.abc import Callable
from fractions import Fraction

import numpy as np

from csgnb.bsp.build import bsp_from_mesh, check_seed
from csgnb.bsp.extract import check_corner, extract_boundary
from csgnb.bsp.merging import MergeResult, merge, remove_redundancy
from csgnb.bsp.surface import BoundarySurface
from csgnb.bsp.tree import BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.integral import exact_int, integer_array
from csgnb.exact.predicates import homogeneous_points
from csgnb.exact.wide import DEFAULT_WIDTH, check_width, to_width
from csgnb.mesh.halfedge import box_planes

__all__ = ["BSP", "UNION", "INTERSECTION", "DIFFERENCE", "SYMMETRIC_DIFFERENCE"]


def _labels(a, b) -> tuple[int, int]:
    return exact_int(a, "label a"), exact_int(b, "label b")


def UNION(a: int, b: int) -> int:  # noqa: N802 - merge functions read as constants
    """in if either is in (the larger material wins)."""
    a, b = _labels(a, b)
    return max(a, b)


def INTERSECTION(a: int, b: int) -> int:  # noqa: N802
    """in if both are in (A's material)."""
    a, b = _labels(a, b)
    return a if b else 0


def DIFFERENCE(a: int, b: int) -> int:  # noqa: N802
    """A's label where B is out."""
    a, b = _labels(a, b)
    return a if not b else 0


def SYMMETRIC_DIFFERENCE(a: int, b: int) -> int:  # noqa: N802
    """in where exactly one is in."""
    a, b = _labels(a, b)
    return (a or b) if not (a and b) else 0


# Functions of the two labels alone: csgnb.bsp.merging.merge_table tabulates each once per label range.
for _fn in (UNION, INTERSECTION, DIFFERENCE, SYMMETRIC_DIFFERENCE):
    _fn.pure_label_function = True
del _fn


def _non_negative(value, name: str) -> int:
    v = exact_int(value, name)
    if v < 0:
        raise GeometryError(f"{name} must be >= 0, got {v}")
    return v


def _read_mesh_file(path) -> tuple[np.ndarray, np.ndarray]:
    try:
        import meshio
    except ImportError:  # pragma: no cover - meshio is a dependency
        raise ImportError("reading mesh files needs meshio (pip install meshio)") from None
    if not os.path.exists(path):
        raise FileNotFoundError(f"no mesh file {os.fspath(path)!r}")
    return _mesh_arrays(meshio.read(path), None)


def _mesh_arrays(mesh, faces):
    """``(vertices, faces)`` of whatever :meth:`BSP.from_mesh` accepts."""
    if faces is not None:
        return mesh, faces
    if isinstance(mesh, str | os.PathLike):
        return _read_mesh_file(mesh)
    module = type(mesh).__module__.split(".")[0]
    if module == "pyvista":
        if not hasattr(mesh, "is_all_triangles"):
            raise TypeError(f"from_mesh takes a surface: got a pyvista {type(mesh).__name__}; pass "
                            "mesh.extract_surface()")
        if not mesh.is_all_triangles:
            mesh = mesh.triangulate()
        tri = np.asarray(mesh.faces).reshape(-1, 4)
        return np.asarray(mesh.points), tri[:, 1:]
    if module == "trimesh" and hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        return np.asarray(mesh.vertices), np.asarray(mesh.faces)
    if module == "meshio" and hasattr(mesh, "cells") and hasattr(mesh, "points"):
        blocks = [c for c in mesh.cells if c.type == "triangle"]
        others = sorted({c.type for c in mesh.cells} - {"triangle", "vertex", "line"})
        if others or not blocks:
            raise GeometryError(f"from_mesh needs a triangle surface; this meshio mesh has cells {others or 'none'} "
                                "(triangulate it first, e.g. pyvista.wrap(mesh).extract_surface().triangulate())")
        return np.asarray(mesh.points)[:, :3], np.concatenate([c.data for c in blocks])
    raise TypeError(
        "BSP.from_mesh takes (vertices, faces) arrays, a pyvista PolyData, a trimesh.Trimesh, a meshio.Mesh or the "
        f"path of a mesh file; got {type(mesh).__name__} without faces"
    )


class BSP:
    """An exact solid: a :class:`BSPTree` and the integer box it lives in.

    Space outside the box is out. Booleans merge by mesh cutting and then, by default,
    remove redundancy (extract the boundary exactly, re-import it), so trees stay small
    under iterated CSG.

    Parameters
    ----------
    tree : BSPTree
    lo, hi : (3,) int
        The box.
    """

    def __init__(self, tree: BSPTree, lo, hi) -> None:
        if not isinstance(tree, BSPTree):
            raise TypeError(f"a BSP needs a BSPTree, got {type(tree).__name__}; build solids with BSP.from_mesh or "
                            "BSP.box")
        self.tree = tree
        self.lo = check_corner(lo, "lo")
        self.hi = check_corner(hi, "hi")
        if any(a >= b for a, b in zip(self.lo, self.hi, strict=True)):
            raise GeometryError(f"the box needs lo < hi in every coordinate, got {self.lo}, {self.hi}")
        self._surface: BoundarySurface | None = None

    # -- construction -------------------------------------------------------

    @classmethod
    def from_mesh(cls, vertices, faces=None, *, width: int = DEFAULT_WIDTH, seed: int = 0, margin: int = 1,
                  lo=None, hi=None, fill: str = "solid") -> BSP:
        """Import a closed, outward, non-self-intersecting triangle mesh with integer vertices.

        Parameters
        ----------
        vertices : (n, 3) int, or a mesh
            Integer (or integral float) vertices with ``faces`` : (m, 3) int; or, without
            ``faces``, a pyvista ``PolyData`` (triangulated if needed), a ``trimesh.Trimesh``,
            a ``meshio.Mesh`` or the path of a mesh file meshio reads. Float meshes must be put
            on an integer grid first (:func:`csgnb.exact.quantize`).
        width, seed :
            As for :func:`csgnb.bsp.bsp_from_mesh`.
        margin : int >= 0
            The box defaults to the vertices' bounding box grown by ``margin``.
        lo, hi : (3,) int, optional
            An explicit box; it must contain every vertex.
        fill : {"solid", "winding"}
            ``"winding"`` accepts meshes that overlap, cross or fold: the solid is the points the
            closed mesh winds around positively (:mod:`csgnb.bsp.winding`).

        Raises :class:`GeometryError` (open, non-manifold, inward, badly nested or
        self-intersecting meshes, a box that does not hold the mesh) or :class:`PrecisionError`
        (outside the budget, non-integral coordinates).
        """
        vertices, faces = _mesh_arrays(vertices, faces)
        v = integer_array(vertices, "vertices")
        margin = _non_negative(margin, "margin")
        width = check_width(width)
        seed = check_seed(seed)
        tree = bsp_from_mesh(v, faces, width=width, seed=seed, fill=fill)
        lo = tuple(int(x) - margin for x in v.min(axis=0)) if lo is None else check_corner(lo, "lo")
        hi = tuple(int(x) + margin for x in v.max(axis=0)) if hi is None else check_corner(hi, "hi")
        vmin, vmax = v.min(axis=0).tolist(), v.max(axis=0).tolist()
        if any(a > b for a, b in zip(lo, vmin, strict=True)) or any(a < b for a, b in zip(hi, vmax, strict=True)):
            raise GeometryError(f"the box {lo}..{hi} does not contain the mesh (its vertices span {vmin}..{vmax}); "
                                "space outside the box is out, so the solid would be clipped: pass a larger box")
        return cls(tree, lo, hi)

    @classmethod
    def box(cls, lo, hi, *, width: int = DEFAULT_WIDTH, domain_margin: int = 1) -> BSP:
        """The box ``[lo, hi]`` (integer corners) as a solid (six planes), in a domain ``domain_margin`` larger."""
        lo, hi = check_corner(lo, "lo"), check_corner(hi, "hi")
        width = check_width(width)
        domain_margin = _non_negative(domain_margin, "domain_margin")
        planes = box_planes(lo, hi, width)
        k = 6
        plane = np.r_[np.arange(k), -np.ones(k + 1, int)]
        neg = np.r_[np.arange(1, k + 1), -np.ones(k + 1, int)]
        pos = np.r_[np.arange(k + 1, 2 * k + 1), -np.ones(k + 1, int)]
        label = np.r_[-np.ones(k, int), 1, np.zeros(k, int)]
        tree = BSPTree(planes, plane, neg, pos, label)
        return cls(tree, [v - domain_margin for v in lo], [v + domain_margin for v in hi])

    def to_width(self, width: int) -> BSP:
        """Return the same solid with its planes at ``width`` bits (128, 192 or 256).

        Widening always works; narrowing raises :class:`csgnb.PrecisionError` when a plane
        does not fit the smaller width or its budget (eq. 7). Merging needs one width.
        """
        width = check_width(width)
        if width == self.tree.width:
            return self
        t = self.tree
        return BSP(BSPTree(to_width(t.palette, width), t.plane, t.neg, t.pos, t.label), self.lo, self.hi)

    # -- Booleans -------------------------------------------------------------

    def merge(self, other: BSP, fn: Callable[[int, int], int], *, simplify: bool = True, seed: int = 0) -> BSP:
        """Return the solid with labels ``fn(self label, other label)`` (Naylor's merge by mesh cutting).

        The result lives in the bounding box of both boxes. With ``simplify`` the merged
        tree is replaced by a re-import of its exact boundary when that is smaller.
        """
        self._check_operand(other, fn)
        seed = check_seed(seed)
        lo = np.minimum(self.lo, other.lo)
        hi = np.maximum(self.hi, other.hi)
        result = self.merge_result(other, fn, lo, hi)
        tree = remove_redundancy(result, seed=seed) if simplify else result.tree
        return BSP(tree, lo, hi)

    def merge_result(self, other: BSP, fn, lo=None, hi=None) -> MergeResult:
        """The raw merge (tree before redundancy removal, with its cells) in the box [lo, hi]."""
        self._check_operand(other, fn)
        lo = np.minimum(self.lo, other.lo) if lo is None else check_corner(lo, "lo")
        hi = np.maximum(self.hi, other.hi) if hi is None else check_corner(hi, "hi")
        return merge(self.tree, other.tree, fn, lo, hi)

    def _check_operand(self, other, fn) -> None:
        if not isinstance(other, BSP):
            hint = ("import it first with BSP.from_mesh(mesh) (integer vertices; quantize float meshes with "
                    "csgnb.exact.quantize)") if hasattr(other, "faces") or hasattr(other, "points") else (
                    "build one with BSP.box or BSP.from_mesh")
            raise TypeError(f"a BSP combines only with another BSP, got {type(other).__name__}: {hint}")
        if not callable(fn):
            raise TypeError(f"the merge function must be callable fn(label_a, label_b) -> label, got {fn!r}")
        if other.tree.width != self.tree.width:
            raise GeometryError(f"cannot merge a {self.tree.width}-bit BSP with a {other.tree.width}-bit BSP: "
                                f"convert one first, e.g. other.to_width({self.tree.width})")

    def union(self, other: BSP, **kw) -> BSP:
        """A ∪ B."""
        return self.merge(other, UNION, **kw)

    def intersection(self, other: BSP, **kw) -> BSP:
        """A ∩ B."""
        return self.merge(other, INTERSECTION, **kw)

    def difference(self, other: BSP, **kw) -> BSP:
        """A − B."""
        return self.merge(other, DIFFERENCE, **kw)

    def symmetric_difference(self, other: BSP, **kw) -> BSP:
        """A △ B."""
        return self.merge(other, SYMMETRIC_DIFFERENCE, **kw)

    __or__ = union
    __and__ = intersection
    __sub__ = difference
    __xor__ = symmetric_difference

    # -- queries --------------------------------------------------------------

    @property
    def n_nodes(self) -> int:
        """Number of BSP nodes."""
        return self.tree.n_nodes

    def surface(self) -> BoundarySurface:
        """The exact, closed, conforming boundary inside the box (computed once)."""
        if self._surface is None:
            self._surface = extract_boundary(self.tree, self.lo, self.hi).surface
        return self._surface

    def volume(self) -> Fraction:
        """Exact volume inside the box."""
        return self.surface().exact_volume()

    def to_polydata(self):
        """The boundary as a triangulated pyvista ``PolyData`` (positions correctly rounded)."""
        return self.surface().to_polydata()

    def classify(self, points) -> np.ndarray:
        """Labels of integer points ``(n, 3) int64`` (0 out, -2 on a splitting plane between labels).

        Integral floats are accepted; 4.5 is refused (classify it on a finer grid).
        """
        p = np.atleast_2d(integer_array(points, "points"))
        if p.ndim != 2 or p.shape[1] != 3:
            raise GeometryError(f"points must have shape (n, 3) or (3,), got {np.shape(points)}")
        inside = np.all((p >= self.lo) & (p <= self.hi), axis=1)
        labels = self.tree.classify(homogeneous_points(p, self.tree.width))
        return np.where(inside, labels, 0)

    def __repr__(self) -> str:
        return f"BSP({self.n_nodes} nodes, box {self.lo}..{self.hi}, {self.tree.width}-bit)"
