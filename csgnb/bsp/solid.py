"""``BSP``: an exact solid as a BSP tree in a box, with Booleans and exact volume (paper §3.5-3.7).

>>> import numpy as np
>>> from csgnb.bsp import BSP
>>> cube = BSP.box([0, 0, 0], [4, 4, 4])
>>> shifted = BSP.box([2, 2, 2], [6, 6, 6])
>>> (cube | shifted).volume(), (cube & shifted).volume(), (cube - shifted).volume()
(Fraction(120, 1), Fraction(8, 1), Fraction(56, 1))
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction

import numpy as np

from csgnb.bsp.build import bsp_from_mesh
from csgnb.bsp.extract import extract_boundary
from csgnb.bsp.merging import MergeResult, merge, remove_redundancy
from csgnb.bsp.surface import BoundarySurface
from csgnb.bsp.tree import BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.predicates import homogeneous_points
from csgnb.exact.wide import DEFAULT_WIDTH
from csgnb.mesh.halfedge import box_planes

__all__ = ["BSP", "UNION", "INTERSECTION", "DIFFERENCE", "SYMMETRIC_DIFFERENCE"]


def UNION(a: int, b: int) -> int:  # noqa: N802 - merge functions read as constants
    """in if either is in (the larger material wins)."""
    return max(a, b)


def INTERSECTION(a: int, b: int) -> int:  # noqa: N802
    """in if both are in (A's material)."""
    return a if b else 0


def DIFFERENCE(a: int, b: int) -> int:  # noqa: N802
    """A's label where B is out."""
    return a if not b else 0


def SYMMETRIC_DIFFERENCE(a: int, b: int) -> int:  # noqa: N802
    """in where exactly one is in."""
    return (a or b) if not (a and b) else 0


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
        self.tree = tree
        self.lo = tuple(int(v) for v in np.asarray(lo).reshape(3))
        self.hi = tuple(int(v) for v in np.asarray(hi).reshape(3))
        if any(a >= b for a, b in zip(self.lo, self.hi, strict=True)):
            raise GeometryError(f"the box needs lo < hi in every coordinate, got {self.lo}, {self.hi}")
        self._surface: BoundarySurface | None = None

    # -- construction -------------------------------------------------------

    @classmethod
    def from_mesh(cls, vertices, faces, *, width: int = DEFAULT_WIDTH, seed: int = 0, margin: int = 1, lo=None,
                  hi=None) -> BSP:
        """Import a closed, outward, non-self-intersecting triangle mesh with integer vertices.

        ``vertices`` : (n, 3) int64; ``faces`` : (m, 3) int. The box defaults to the
        vertices' bounding box grown by ``margin``. Raises :class:`GeometryError` (open,
        non-manifold, inward or self-intersecting meshes) or :class:`PrecisionError`.
        """
        v = np.asarray(vertices)
        tree = bsp_from_mesh(vertices, faces, width=width, seed=seed)
        lo = v.min(axis=0) - margin if lo is None else lo
        hi = v.max(axis=0) + margin if hi is None else hi
        return cls(tree, lo, hi)

    @classmethod
    def box(cls, lo, hi, *, width: int = DEFAULT_WIDTH, domain_margin: int = 1) -> BSP:
        """The box ``[lo, hi]`` as a solid (six planes), in a domain ``domain_margin`` larger."""
        planes = box_planes(lo, hi, width)
        k = 6
        plane = np.r_[np.arange(k), -np.ones(k + 1, int)]
        neg = np.r_[np.arange(1, k + 1), -np.ones(k + 1, int)]
        pos = np.r_[np.arange(k + 1, 2 * k + 1), -np.ones(k + 1, int)]
        label = np.r_[-np.ones(k, int), 1, np.zeros(k, int)]
        tree = BSPTree(planes, plane, neg, pos, label)
        lo, hi = np.asarray(lo), np.asarray(hi)
        return cls(tree, lo - domain_margin, hi + domain_margin)

    # -- Booleans -------------------------------------------------------------

    def merge(self, other: BSP, fn: Callable[[int, int], int], *, simplify: bool = True, seed: int = 0) -> BSP:
        """Return the solid with labels ``fn(self label, other label)`` (Naylor's merge by mesh cutting).

        The result lives in the bounding box of both boxes. With ``simplify`` the merged
        tree is replaced by a re-import of its exact boundary when that is smaller.
        """
        lo = np.minimum(self.lo, other.lo)
        hi = np.maximum(self.hi, other.hi)
        result = self.merge_result(other, fn, lo, hi)
        tree = remove_redundancy(result, seed=seed) if simplify else result.tree
        return BSP(tree, lo, hi)

    def merge_result(self, other: BSP, fn, lo=None, hi=None) -> MergeResult:
        """The raw merge (tree before redundancy removal, with its cells) in the box [lo, hi]."""
        lo = np.minimum(self.lo, other.lo) if lo is None else lo
        hi = np.maximum(self.hi, other.hi) if hi is None else hi
        return merge(self.tree, other.tree, fn, lo, hi)

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
        """Labels of integer points ``(n, 3) int64`` (0 out, -2 on a splitting plane between labels)."""
        p = np.atleast_2d(np.asarray(points, np.int64))
        inside = np.all((p >= self.lo) & (p <= self.hi), axis=1)
        labels = self.tree.classify(homogeneous_points(p, self.tree.width))
        return np.where(inside, labels, 0)

    def __repr__(self) -> str:
        return f"BSP({self.n_nodes} nodes, box {self.lo}..{self.hi}, {self.tree.width}-bit)"
