"""Exact volumes of a workpiece's cells, cached by cell **content**, and the exact volume change of a Boolean.

The octree owns these answers; applications (the milling meter, carving, the CLI) ask the
workpiece (:meth:`~csgnb.octree.Workpiece.volume`, ``boolean(..., track_volume=True)``,
:meth:`~csgnb.octree.Workpiece.cell_volume`) and never read its arrays.

* **A cell's volume is keyed on what the cell is**: its box and a digest of its BSP's node
  arrays (:func:`cell_key`). The arrays name palette rows, which are never rewritten, so equal
  digests are equal solids; the key holds no pool offset, so a pool compaction (which moves
  every BSP) or Booleans the cache did not see can never make a cached volume stale. (An
  earlier key of pool start and length did: after a compaction a cell could meet another
  cell's old key and return its volume.)
* **A Boolean's change is measured where the solid can change** (:class:`LocalChange`): the
  leaves ``T`` meeting the tool's box, before and after; a leaf that combined into a larger
  one after is measured only inside the old cell's box. A convex tool's change is computed
  before the Boolean from the tool and the cells alone (:func:`convex_change`): per leaf
  ``vol(S_b ∩ H)`` (removed by a difference) or ``vol(H ∩ b) − vol(S_b ∩ H)`` (added by a
  union), with leaves certainly outside or inside ``H`` decided by a certified float test.
* Cell volumes come from the cell's BSP over a compact palette (only the planes it uses),
  extracted in the cell box and summed exactly (:func:`csgnb.mesh.volume.cells_volume`); a
  part's total is summed pairwise (:func:`csgnb.mesh.volume.sum_fractions`): a long run's
  total has a denominator of 10^5 digits, and a running sum would cost O(cells²).
"""

from __future__ import annotations

import hashlib
from fractions import Fraction

import numpy as np

from csgnb.bsp.extract import extract_cells
from csgnb.bsp.tree import BSPTree
from csgnb.errors import InternalError
from csgnb.mesh.hull import linear_bsp_arrays
from csgnb.mesh.volume import cells_volume, sum_fractions
from csgnb.octree.layout import BSP, N_PAL

__all__ = ["CellVolumes", "LocalChange", "bsp_volume", "cell_key", "convex_change", "sum_fractions"]

_ROUNDING = 1e-12
"""Relative size, against the sum of the absolute terms, below which a float plane value decides nothing (the
rounding of the int-to-float conversions, products and sums is below 1e-15 of it)."""


def cell_key(w, node: int):
    """Leaf ``node``'s content: its box and a digest of its BSP's node arrays (None for a uniform leaf)."""
    oc = w.oc
    if oc.kind[node] != BSP:
        return None
    s, n = int(oc.start[node]), int(oc.length[node])
    p = w.pool
    h = hashlib.blake2b(p.plane[s:s + n].tobytes(), digest_size=16)
    for a in (p.neg, p.pos, p.label):
        h.update(a[s:s + n].tobytes())
    return (h.digest(), int(oc.lo[node, 0]), int(oc.lo[node, 1]), int(oc.lo[node, 2]), int(oc.size[node]))


class CellVolumes:
    """Exact solid volumes of a workpiece's leaves (grid units cubed), cached by :func:`cell_key`."""

    def __init__(self) -> None:
        self._cache: dict[tuple, Fraction] = {}

    def __len__(self) -> int:
        return len(self._cache)

    def clear(self) -> None:
        self._cache.clear()

    def volume(self, w, node: int, lo=None, size: int | None = None, *, key=None) -> Fraction:
        """Volume of leaf ``node`` (only inside the sub-box ``[lo, lo + size]`` of it when given); ``key``: its
        :func:`cell_key` when the caller has it already."""
        oc = w.oc
        whole = lo is None
        if oc.kind[node] != BSP:
            edge = int(oc.size[node]) if whole else int(size)
            return Fraction(edge**3) if oc.label[node] > 0 else Fraction(0)
        if not whole:
            lo = np.asarray(lo, np.int64)
            return bsp_volume(w, node, lo, lo + int(size))
        key = cell_key(w, node) if key is None else key
        v = self._cache.get(key)
        if v is None:
            lo = np.asarray(w.oc.lo[node], np.int64)
            v = bsp_volume(w, node, lo, lo + int(oc.size[node]))
            self._cache[key] = v
        return v

    def forget(self, key) -> None:
        if key is not None:
            self._cache.pop(key, None)

    def total(self, w, leaves: np.ndarray) -> Fraction:
        """The exact total over ``leaves`` (every leaf of ``w``); entries of cells no longer present are dropped."""
        leaves = leaves.tolist()
        keys = [cell_key(w, n) for n in leaves]  # one digest per cell, used twice
        live = set(keys)
        for key in [k for k in self._cache if k not in live]:
            del self._cache[key]
        return sum_fractions(self.volume(w, n, key=k) for n, k in zip(leaves, keys, strict=True))


class LocalChange:
    """The exact volume change of one Boolean over the region its tool's box reaches (see the module docstring).

    ``LocalChange(w, volumes, lo, hi)`` before the Boolean, :meth:`finish` after it.
    """

    def __init__(self, w, volumes: CellVolumes, lo, hi) -> None:
        self.w, self.volumes = w, volumes
        before = w.cells_meeting(lo, hi).tolist()
        self.boxes = [(w.oc.lo[b].copy(), int(w.oc.size[b])) for b in before]
        self.keys = [cell_key(w, b) for b in before]
        self.before = sum_fractions(volumes.volume(w, b, key=k) for b, k in zip(before, self.keys, strict=True))
        self.nodes = before

    def finish(self) -> Fraction:
        w, volumes = self.w, self.volumes
        terms = []
        for lo, size in self.boxes:
            for a in w.cells_meeting(lo, lo + size).tolist():
                if int(w.oc.size[a]) <= size:
                    terms.append(volumes.volume(w, a))
                else:  # a parent that combined: only its part inside the old cell
                    terms.append(volumes.volume(w, a, lo, size))
        for b, key in zip(self.nodes, self.keys, strict=True):  # replaced contents are not asked for again
            if key is not None and cell_key(w, b) != key:
                volumes.forget(key)
        return sum_fractions(terms) - self.before


def _boxes_against_planes(planes, lo, size) -> tuple[np.ndarray, np.ndarray]:
    """For boxes ``[lo, lo + size]`` (``(m, 3)``, ``(m,)``) and a convex solid's outward planes ``(k, 4)`` (ints):
    ``outside`` (m,) -- certainly beyond one plane; ``inside`` (m,) -- certainly strictly behind every plane.

    Computed in float64 and trusted only where the value is farther from zero than its rounding
    bound, so both answers are exact when True (False means: not decided here)."""
    m = lo.shape[0]
    if m == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    P = np.array([[float(x) for x in row] for row in planes], np.float64).reshape(-1, 4)
    n, d = P[:, :3], P[:, 3]
    L = lo.astype(np.float64)
    s = size.astype(np.float64)[:, None]
    base = L @ n.T + d[None, :]
    low = base + s * np.minimum(n, 0).sum(axis=1)[None, :]
    high = base + s * np.maximum(n, 0).sum(axis=1)[None, :]
    err = _ROUNDING * ((np.abs(L) + s) @ np.abs(n).T + np.abs(d)[None, :])
    return np.any(low > err, axis=1), np.all(high < -err, axis=1)


def _chain(planes: np.ndarray):
    """A convex solid's linear BSP over its ``k`` wide planes (:func:`csgnb.mesh.hull.linear_bsp_arrays`)."""
    return (planes, *linear_bsp_arrays(planes.shape[0]))


def convex_change(w, volumes: CellVolumes, tool, union: bool) -> Fraction:
    """The exact change a convex ``tool`` (an octree :class:`~csgnb.octree.Tool`) *will* make: removed volume
    (negative) for a difference, added volume for a union. Call it before the Boolean."""
    oc = w.oc
    leaves = w.cells_meeting(tool.lo, tool.hi)
    outside, inside = _boxes_against_planes(tool.planes, oc.lo[leaves], oc.size[leaves])
    chain = None
    terms = []
    for b, out, inn in zip(leaves.tolist(), outside.tolist(), inside.tolist(), strict=True):
        if out:
            continue
        size = int(oc.size[b])
        uniform_in = oc.kind[b] != BSP and oc.label[b] > 0
        if inn:
            sb = volumes.volume(w, b)
            terms.append(Fraction(size**3) - sb if union else -sb)
            continue
        if chain is None:
            chain = _chain(tool.planes_wide(w.width))
        lo = np.asarray(oc.lo[b], np.int64)
        hi = lo + size
        hb = bsp_volume(w, -1, lo, hi, chain) if (uniform_in or union) else None
        if oc.kind[b] == BSP:
            sb = bsp_volume(w, b, lo, hi, chain)
        else:
            sb = hb if uniform_in else Fraction(0)
        terms.append(hb - sb if union else -sb)
    return sum_fractions(terms)


def bsp_volume(w, node: int, lo: np.ndarray, hi: np.ndarray, chain=None) -> Fraction:
    """Exact volume of leaf ``node``'s BSP (``node = -1``: all material) inside the box ``[lo, hi]`` -- and inside
    the convex ``chain`` (:func:`_chain`) when given, grafted above the cell's tree.

    The tree gets a palette of the planes it uses only (a cell uses tens of the workpiece's up
    to millions of planes, and a store copies and checks its palette)."""
    if node >= 0:
        s, n = int(w.oc.start[node]), int(w.oc.length[node])
        pool = w.pool
        plane = pool.plane[s:s + n]
        inner = plane >= 0
        used = np.unique(plane[inner])
        if used.shape[0] and int(used[-1]) >= int(w.oc.counts[N_PAL]):
            raise InternalError(f"octree cell {node} refers to plane {int(used[-1])} beyond the palette (a bug)")
        local = np.full(n, -1, np.int32)
        local[inner] = np.searchsorted(used, plane[inner]).astype(np.int32)
        palette = w.palette[used]
        neg, pos, label = pool.neg[s:s + n], pool.pos[s:s + n], pool.label[s:s + n]
    else:  # one in leaf
        palette = w.palette[:0]
        local, neg, pos, label = (np.array([x], np.int32) for x in (-1, -1, -1, 1))
    if chain is not None:
        cp, cplane, cneg, cpos, clabel = chain
        k, m = cplane.shape[0] - 1, cp.shape[0]  # the cell's tree replaces the chain's inside leaf, node k
        local = np.concatenate([cplane[:k], np.where(local >= 0, local + m, -1)]).astype(np.int32)
        neg = np.concatenate([cneg[:k], np.where(neg >= 0, neg + k, -1)]).astype(np.int32)
        pos = np.concatenate([cpos[:k], np.where(pos >= 0, pos + k, -1)]).astype(np.int32)
        label = np.concatenate([clabel[:k], label]).astype(np.int32)
        palette = np.concatenate([cp, palette])
    else:
        neg, pos, label = neg.copy(), pos.copy(), label.copy()
    tree = BSPTree(np.ascontiguousarray(palette), local, neg, pos, label, validate=False)
    store, cells = extract_cells(tree, lo, hi)
    return cells_volume(store, cells[:, 1])
