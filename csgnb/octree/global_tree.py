"""The whole workpiece as one BSP: the octree's axis-BSPs with the cells' BSPs below (paper §1: "a single
gigantic BSP where the upper levels follow an octree structure").

Exporting, classifying points and measuring the whole workpiece use this tree: boundary
extraction of it clips every cell face against *everything* behind it, octree walls
included, so faces between two solid cells vanish exactly and nothing else does.
"""

from __future__ import annotations

import numpy as np

from csgnb._jit import jit
from csgnb._views import unmanaged_tuple
from csgnb.octree.kernels import axis_plane
from csgnb.octree.layout import BSP

__all__ = []


@jit
def _global_size(oc):
    """Nodes of the global tree: 7 per inner octree node, a leaf's BSP (or 1)."""
    n = 0
    stack = np.empty(64 * 8, np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        if oc.child[node] >= 0:
            n += 7
            for k in range(8):
                stack[top] = oc.child[node] + k
                top += 1
        elif oc.kind[node] == BSP:
            n += oc.length[node]
        else:
            n += 1
    return n


@jit
def _global_tree_kernel(pal, oc, pool, amap, t, need):
    """Write the global tree into ``t`` (sized by :func:`_global_size`); False when a wall plane needs room."""
    oc = unmanaged_tuple(oc)
    pool = unmanaged_tuple(pool)
    amap = unmanaged_tuple(amap)
    t = unmanaged_tuple(t)
    # stack of (octree node, tree slot to fill)
    stack = np.empty((64 * 8, 2), np.int64)
    stack[0, 0] = 0
    stack[0, 1] = 0
    top = 1
    free = 1
    while top > 0:
        top -= 1
        node = stack[top, 0]
        slot = stack[top, 1]
        if oc.child[node] >= 0:
            half = oc.size[node] // 2
            rows = np.empty(3, np.int64)
            for axis in range(3):
                r = axis_plane(amap, pal, oc, axis, 1, oc.lo[node, axis] + half, need)
                if r < 0:
                    return False
                rows[axis] = r
            # slot = x node; then y nodes, z nodes, as in the combine step
            base = free
            free += 6
            ids = (slot, base, base + 1, base + 2, base + 3, base + 4, base + 5)
            t.plane[ids[0]] = rows[0]
            t.neg[ids[0]] = ids[1]
            t.pos[ids[0]] = ids[2]
            for bx in range(2):
                y = ids[1 + bx]
                t.plane[y] = rows[1]
                t.neg[y] = ids[3 + 2 * bx]
                t.pos[y] = ids[4 + 2 * bx]
            for i in range(7):
                t.label[ids[i]] = -1
            first = oc.child[node]
            for bx in range(2):
                for by in range(2):
                    z = ids[3 + 2 * bx + by]
                    t.plane[z] = rows[2]
                    for bz in range(2):
                        ch = first + bx + 2 * by + 4 * bz
                        s = free
                        free += 1
                        if bz == 0:
                            t.neg[z] = s
                        else:
                            t.pos[z] = s
                        stack[top, 0] = ch
                        stack[top, 1] = s
                        top += 1
        elif oc.kind[node] == BSP:
            n = oc.length[node]
            # the BSP's root goes into ``slot``, the rest after ``free``
            start = oc.start[node]
            base = free - 1  # node i of the BSP (i >= 1) at base + i
            for i in range(n):
                dst = slot if i == 0 else base + i
                p = pool.plane[start + i]
                t.plane[dst] = p
                t.label[dst] = pool.label[start + i]
                if p >= 0:
                    a = pool.neg[start + i]
                    b = pool.pos[start + i]
                    t.neg[dst] = slot if a == 0 else base + a
                    t.pos[dst] = slot if b == 0 else base + b
                else:
                    t.neg[dst] = -1
                    t.pos[dst] = -1
            free += n - 1
        else:
            t.plane[slot] = -1
            t.neg[slot] = -1
            t.pos[slot] = -1
            t.label[slot] = oc.label[node]
    return True

