"""The flat BSP tree: a plane palette plus parallel node arrays (paper §3.1, §4.4).

A BSP is stored the way the paper stores it: every node is one row of four
``int32`` arrays, and planes are rows of a shared *palette* of exact integer planes
(``(m, 4)`` wide array, see :mod:`csgnb.exact.wide`), so that nodes split by the same
plane share one palette row.

* ``plane[i]`` : palette row of node ``i``'s splitting plane, ``-1`` for a leaf;
* ``neg[i]``, ``pos[i]`` : children on the negative (``a·x + b·y + c·z + d < 0``) and
  positive side, ``-1`` for a leaf;
* ``label[i]`` : a leaf's label, ``0`` = **out**, ``k >= 1`` = **in** with material ``k``;
  ``-1`` for inner nodes.

Node 0 is the root. Solids imported from meshes have outward face normals, so the
inside of a face is its plane's negative side.
"""

from __future__ import annotations

from dataclasses import InitVar, dataclass

import numpy as np

from csgnb._jit import jit
from csgnb.errors import GeometryError
from csgnb.exact.budgets import check_planes, check_points_against_planes
from csgnb.exact.integral import integer_array
from csgnb.exact.intrinsics import classify_at
from csgnb.exact.wide import is_wide, width_of

__all__ = ["OUT", "ON_BOUNDARY", "BSPTree", "box_face_sides", "check_index_array"]

OUT = 0
"""Label of an empty leaf."""

ON_BOUNDARY = -2
"""Classification of a point that lies on a plane separating cells of different labels."""


_INT32_MIN, _INT32_MAX = -(1 << 31), (1 << 31) - 1


def check_index_array(values, name: str) -> np.ndarray:
    """Return ``values`` as a contiguous 1-D ``int32`` array (indices or labels); a clear error otherwise.

    An ``int32`` array passes without a copy; anything else is read exactly by
    :func:`csgnb.exact.integral.integer_array` (so 2.7, NaN or strings are refused) and must
    fit ``int32``.
    """
    if isinstance(values, np.ndarray) and values.dtype == np.int32:
        arr = values
    elif is_wide(values) or isinstance(values, str | bytes):
        what = "a wide-integer array (those hold planes and points)" if is_wide(values) else f"the string {values!r}"
        raise TypeError(f"{name} must be a 1-D array of int32 indices, got {what}")
    else:
        arr = integer_array(values, name)
        if arr.size and (int(arr.min()) < _INT32_MIN or int(arr.max()) > _INT32_MAX):
            raise GeometryError(f"{name} holds values beyond int32 ({int(arr.min())} .. {int(arr.max())}); "
                                "node, plane and edge indices and labels are int32")
    if arr.ndim != 1:
        raise GeometryError(f"{name} must be a 1-D array of int32 indices, got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.int32)


@jit
def _classify_points_kernel(plane, neg, pos, label, palette, points, forced, out):
    # Points exactly on a splitting plane descend both ways (or only the side forced[row]
    # names, when non-zero); if the sides give different labels the point is on the
    # boundary between them.
    stack = np.empty(2 * plane.shape[0] + 2, np.int32)
    for t in range(points.shape[0]):
        result = -3  # nothing seen yet
        top = 0
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            while plane[node] >= 0:
                side = classify_at(points, t, palette, plane[node])
                if side == 0:
                    side = forced[plane[node]]
                if side < 0:
                    node = neg[node]
                elif side > 0:
                    node = pos[node]
                else:
                    stack[top] = pos[node]
                    top += 1
                    node = neg[node]
            lab = label[node]
            if result == -3:
                result = lab
            elif result != lab:
                result = -2
        out[t] = result


@jit
def _depths_kernel(neg, pos, plane, depth):
    # Nodes are stored parents-before-children in every tree csgnb builds, but a
    # user-supplied tree need not be: walk from the root with an explicit stack and
    # return how many distinct nodes are reachable (-1 if a node is reached twice).
    seen = np.zeros(neg.shape[0], np.bool_)
    stack = np.empty(neg.shape[0] + 1, np.int32)
    stack[0] = 0
    depth[0] = 0
    top = 1
    count = 0
    while top > 0:
        top -= 1
        node = stack[top]
        if seen[node]:
            return -1
        seen[node] = True
        count += 1
        if plane[node] >= 0:
            for child in (neg[node], pos[node]):
                depth[child] = depth[node] + 1
                stack[top] = child
                top += 1
    return count


@dataclass(frozen=True)
class BSPTree:
    """An exact BSP tree: plane palette and flat node arrays (see the module docstring).

    Attributes
    ----------
    palette : (m, 4) wide
        Exact integer planes (a, b, c, d) of one width.
    plane, neg, pos, label : (n,) int32
        The node arrays; node 0 is the root.
    validate : bool
        Check the arrays (shapes, a tree rooted at 0, labels, the palette's budget).
        csgnb's own kernels pass ``False`` for the trees they build, which are valid by
        construction; everything that comes from outside is checked.
    """

    palette: np.ndarray
    plane: np.ndarray
    neg: np.ndarray
    pos: np.ndarray
    label: np.ndarray
    validate: InitVar[bool] = True

    def __post_init__(self, validate: bool = True) -> None:
        if not validate:
            for name in ("plane", "neg", "pos", "label"):
                object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.int32))
            object.__setattr__(self, "palette", np.ascontiguousarray(self.palette))
            return
        if not is_wide(self.palette):
            raise TypeError(f"palette must be an (m, 4) wide array of planes (csgnb.exact.to_wide), got "
                            f"{type(self.palette).__name__} {getattr(self.palette, 'dtype', '')}".rstrip())
        if not (self.palette.ndim == 2 and self.palette.shape[1] == 4):
            raise GeometryError(f"palette must be an (m, 4) wide array of planes, got shape {self.palette.shape}")
        arrays = {name: check_index_array(getattr(self, name), name) for name in ("plane", "neg", "pos", "label")}
        n = arrays["plane"].shape[0]
        if n == 0:
            raise GeometryError("a BSP needs at least one node (a single leaf)")
        for name, arr in arrays.items():
            if arr.shape != (n,):
                raise GeometryError(f"{name} must have shape ({n},) like plane, got {arr.shape}")
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "palette", np.ascontiguousarray(self.palette))
        inner = self.plane >= 0
        if np.any(self.plane >= self.palette.shape[0]):
            raise GeometryError("a node refers to a plane beyond the palette")
        for name in ("neg", "pos"):
            child = getattr(self, name)
            if np.any(inner & ((child < 1) | (child >= n))) or np.any(~inner & (child != -1)):
                raise GeometryError(f"{name} children must be node indices 1..{n - 1} at inner nodes, -1 at leaves")
        if np.any(~inner & (self.label < 0)) or np.any(inner & (self.label != -1)):
            raise GeometryError("leaves need labels >= 0 (0 = out) and inner nodes label -1")
        if self.palette.shape[0]:
            check_planes(self.palette, "palette")
        depth = np.zeros(n, np.int32)
        if int(_depths_kernel(self.neg, self.pos, self.plane, depth)) != n:
            raise GeometryError("the node arrays do not form a tree rooted at node 0 (a node is shared or unreachable)")

    # -- construction -------------------------------------------------------

    @classmethod
    def leaf(cls, palette: np.ndarray, label: int = OUT) -> BSPTree:
        """Return the one-leaf BSP labelled ``label`` over ``palette``."""
        one = np.array([-1], np.int32)
        return cls(palette, one, one.copy(), one.copy(), np.array([label], np.int32))

    # -- queries ------------------------------------------------------------

    @property
    def width(self) -> int:
        """Bit width of the palette's planes (128, 192 or 256)."""
        return width_of(self.palette)

    @property
    def n_nodes(self) -> int:
        """Number of nodes, inner nodes and leaves together."""
        return int(self.plane.shape[0])

    @property
    def n_inner(self) -> int:
        """Number of inner (splitting) nodes."""
        return int(np.count_nonzero(self.plane >= 0))

    def depth(self) -> int:
        """Length of the longest root-to-leaf path (0 for a single leaf)."""
        depth = np.zeros(self.n_nodes, np.int32)
        _depths_kernel(self.neg, self.pos, self.plane, depth)
        return int(depth.max())

    def classify(self, points: np.ndarray, *, forced_sides: np.ndarray | None = None) -> np.ndarray:
        """Return the label of the cell containing each homogeneous point.

        Parameters
        ----------
        points : (n, 4) wide, same width as the palette
            Homogeneous points (x1, x2, x3, x4), x4 != 0 (see
            :func:`csgnb.exact.homogeneous_points` for integer points).
        forced_sides : (m,) int8, optional
            Per palette row: 0, or the only side (-1 / +1) a point *on* that plane looks at --
            the tree is right only on that side of it (a shard's tree at its box's faces,
            :func:`box_face_sides`).

        Returns
        -------
        (n,) int32: the leaf label, or :data:`ON_BOUNDARY` (-2) for a point on a
        splitting plane whose two sides have different labels.
        """
        if not (is_wide(points) and points.ndim == 2 and points.shape[1] == 4):
            raise GeometryError(f"points must be an (n, 4) wide array of homogeneous points, got {points.shape}")
        if width_of(points) != self.width:
            raise GeometryError(f"points are {width_of(points)}-bit but the BSP is {self.width}-bit")
        if self.palette.shape[0]:
            check_points_against_planes(points, self.palette)
        if forced_sides is None:
            forced = np.zeros(self.palette.shape[0], np.int8)
        else:
            forced = np.ascontiguousarray(forced_sides, np.int8)
            if forced.shape != (self.palette.shape[0],) or np.any(np.abs(forced) > 1):
                raise GeometryError(f"forced_sides must be ({self.palette.shape[0]},) values in -1, 0, 1 (one per "
                                    f"palette row), got shape {forced.shape}")
        out = np.empty(points.shape[0], np.int32)
        _classify_points_kernel(self.plane, self.neg, self.pos, self.label, self.palette,
                                np.ascontiguousarray(points), forced, out)
        return out

    def __repr__(self) -> str:
        return f"BSPTree({self.n_nodes} nodes, {self.n_inner} inner, {self.palette.shape[0]} planes, {self.width}-bit)"


def box_face_sides(palette: np.ndarray, lo, hi) -> np.ndarray:
    """``(m,) int8``: for each palette row that is an axis plane on a face of the box ``[lo, hi]``
    (integer corners, ``lo < hi``), the side of it the box's interior lies on; 0 for every other row.

    With these as ``forced_sides``, :meth:`BSPTree.classify` reads a point on the box's faces
    from the box's side only (a tree that is right inside the box and stale beyond it).
    """
    from csgnb.exact.wide import from_wide

    lo = [int(v) for v in np.asarray(lo).reshape(3)]
    hi = [int(v) for v in np.asarray(hi).reshape(3)]
    out = np.zeros(palette.shape[0], np.int8)
    if palette.shape[0] == 0:
        return out
    limbs = palette["limbs"]  # (m, 4, k) two's complement limbs
    zero = ~np.any(limbs != 0, axis=2)  # (m, 4): value == 0
    axis_rows = np.flatnonzero(zero[:, :3].sum(axis=1) == 2)
    if axis_rows.shape[0] == 0:
        return out
    rows = from_wide(palette[axis_rows])
    for r, row in zip(axis_rows.tolist(), rows.tolist(), strict=True):
        a = next(i for i in range(3) if int(row[i]) != 0)
        n, d = int(row[a]), int(row[3])
        sign = 1 if n > 0 else -1
        if n * lo[a] + d == 0:
            out[r] = sign  # the interior, x_a > lo_a, is where n x_a + d has n's sign
        elif n * hi[a] + d == 0:
            out[r] = -sign
    return out
