"""A certified float filter for cuts that cannot be proper: a polytope's box in doubles, a plane's side over it.

When a merge walks a cell through B (paper §3.5), most of B's planes miss the cell: a convex tool's
chain of ~100 facet planes reaches a cell of A that only a few of them cross, and each plane that
misses costs an exact edge descent (a few 128-bit classifications) to find out. The filter decides
those with doubles instead, and only when it is sure:

1. :func:`cell_float_box` bounds the polytope of a cell handle by a box of doubles that holds every
   exact vertex (x1, x2, x3) / x4: each quotient is computed to within 2**-100 relative and rounded
   (:func:`csgnb.exact.intrinsics.positions_into`: |x~ - x| <= (2**-53 + 2**-100) |x|, under
   2**-52 |x~|), then the box's corners are pushed outwards by :data:`WIDEN` of their magnitude
   (2**-50 > 2**-52 plus the rounding of that subtraction, 2**-53).
2. :func:`box_side` evaluates the plane's largest and smallest value over the box in doubles:
   max = d + sum_c max(a_c lo_c, a_c hi_c). The coefficients are converted within 4.001 units of 2**-53
   (``wide_filter_double_at``: limb by limb, several times cheaper than correct rounding at 256 bits),
   each product rounded once and the sum three times: the computed max is within ~9 * 2**-53 * T of
   the exact one, T = |d| + sum_c max(|a_c lo_c|, |a_c hi_c|). A side is returned only when the max
   is below -:data:`MARGIN` T (or the min above +MARGIN T), with MARGIN = 2**-48 (32 units in the
   last place, more than three times the bound): then every vertex is
   strictly on that side, the exact cut would have found no proper intersection and returned the
   same side, and the mesh is not touched. Otherwise (a plane through or near the box, a box that
   could not be bounded) it returns 0 and the exact cut decides.

Nothing here is a tolerance on the geometry: the filter never changes a result, it only skips exact
work whose outcome it has proved (tests: the exact side of every vertex against every plane the
filter decided; merges with and without it give identical trees). No ``fastmath``: the bounds rest
on IEEE rounding.
"""

from __future__ import annotations

import numpy as np

from csgnb._jit import jit
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.exact.intrinsics import positions_into, wide_filter_double_at, wide_sign_at
from csgnb.exact.wide import to_wide
from csgnb.mesh.halfedge import NH, STAMP, VERT, MeshStore, collect_cell_halfedges

__all__ = ["WIDEN", "MARGIN", "BOX_COLUMNS", "LAZY_CUTS", "cell_float_box", "copy_box", "box_side",
           "polytope_float_box", "plane_side_over_box"]

WIDEN = 2.0**-50
"""Relative outward push of a box corner: covers the vertex quotients' error (< 2**-52 of the value)."""

MARGIN = 2.0**-48
"""Relative margin of a certified side: five times the rounding error of the plane's extreme over the box."""

BOX_COLUMNS = 7
"""Columns of a box row: lo x, y, z, hi x, y, z, and a count the merge keeps (exact cuts made before the box)."""

LAZY_CUTS = 4
"""A merge computes an A-leaf's box after this many exact cuts by B's planes missed its cell, so that a short walk
through B (a prism's few facets) does not pay for it. Measured equal to computing every box at once (0 here) on the
dome carve (0.77 against 0.78-0.79 of the unfiltered time, in-process A/B) and on the drill's prism unions."""


@jit(inline="always")
def cell_float_box(m, h, work, boxes, r):
    """Store a box of doubles holding every vertex of the polytope of handle ``h`` in ``boxes[r, 0:6]``.

    ``boxes`` is ``(n, BOX_COLUMNS) float64`` (lo x, y, z, hi x, y, z, a count); its last row is scratch. ``work`` is an
    int32 array for the polytope's half-edges: when it is shorter than the store's half-edges in use, or
    a vertex is at infinity, the box is marked unknown (NaN) and :func:`box_side` decides nothing.
    Stamps the polytope's half-edges and vertices with a fresh traversal stamp (the next cut takes its own).
    """
    scratch = boxes.shape[0] - 1
    boxes[r, 0] = np.nan
    if work.shape[0] < m.counts[NH]:
        return
    nh = collect_cell_halfedges(m.he, m.hmark, m.counts, h, work)
    stamp = m.counts[STAMP]
    lo0 = np.inf
    lo1 = np.inf
    lo2 = np.inf
    hi0 = -np.inf
    hi1 = -np.inf
    hi2 = -np.inf
    for i in range(nh):
        v = np.int64(m.he[work[i], VERT])
        if (m.vmark[v] >> 2) == stamp:
            continue  # seen from another of its half-edges
        m.vmark[v] = stamp * 4
        if wide_sign_at(m.vx, v, 3) == 0:
            return
        positions_into(m.vx, v, boxes, scratch)
        x = boxes[scratch, 0]
        y = boxes[scratch, 1]
        z = boxes[scratch, 2]
        lo0 = min(lo0, x)
        hi0 = max(hi0, x)
        lo1 = min(lo1, y)
        hi1 = max(hi1, y)
        lo2 = min(lo2, z)
        hi2 = max(hi2, z)
    boxes[r, 0] = lo0 - abs(lo0) * WIDEN
    boxes[r, 1] = lo1 - abs(lo1) * WIDEN
    boxes[r, 2] = lo2 - abs(lo2) * WIDEN
    boxes[r, 3] = hi0 + abs(hi0) * WIDEN
    boxes[r, 4] = hi1 + abs(hi1) * WIDEN
    boxes[r, 5] = hi2 + abs(hi2) * WIDEN


@jit(inline="always")
def copy_box(boxes, src, dst):
    """``boxes[dst] = boxes[src]`` (a part of a polytope lies in its box)."""
    for c in range(BOX_COLUMNS):
        boxes[dst, c] = boxes[src, c]


@jit(inline="always")
def box_side(palette, row, boxes, r):
    """-1 / +1 when every point of box ``boxes[r]`` is certainly strictly on that side of palette plane ``row``;
    0 when the doubles cannot tell (the plane meets the box or nearly, or the box is unknown)."""
    if boxes[r, 0] != boxes[r, 0]:
        return 0
    d = wide_filter_double_at(palette, row, 3)
    smax = d
    smin = d
    t = abs(d)
    for c in range(3):
        a = wide_filter_double_at(palette, row, c)
        x = a * boxes[r, c]
        y = a * boxes[r, 3 + c]
        smax += max(x, y)
        smin += min(x, y)
        t += max(abs(x), abs(y))
    margin = t * MARGIN
    if smax < -margin:
        return -1
    if smin > margin:
        return 1
    return 0


@jit
def _float_box_kernel(m, h, work, boxes):
    cell_float_box(unmanaged_tuple(m), h, unmanaged(work), unmanaged(boxes), np.int64(0))


@jit
def _side_kernel(planes, row, boxes):
    return box_side(unmanaged(planes), row, unmanaged(boxes), np.int64(0))


def polytope_float_box(store: MeshStore, cell: int) -> np.ndarray:
    """``(2, 3) float64`` (lo, hi): the certified box of doubles around the polytope of ``cell`` in ``store``.

    Every exact vertex lies in it (NaN rows when a vertex is at infinity).
    """
    boxes = np.empty((2, BOX_COLUMNS))
    _float_box_kernel(store.m, np.int64(cell), np.empty(store.he.shape[0], np.int32), boxes)
    return boxes[0, :6].reshape(2, 3)


def plane_side_over_box(plane, box) -> int:
    """-1 / +1 when the integer plane ``(a, b, c, d)`` (``a x + b y + c z + d``) is certainly negative /
    positive over the whole float ``box`` ``(2, 3)`` (lo, hi); 0 when doubles cannot tell."""
    planes = to_wide(np.asarray([[int(c) for c in plane]], dtype=object), 256)
    boxes = np.empty((2, BOX_COLUMNS))
    boxes[0, :6] = np.asarray(box, np.float64).reshape(6)
    return int(_side_kernel(planes, np.int64(0), boxes))
