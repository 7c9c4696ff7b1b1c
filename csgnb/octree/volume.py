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
from csgnb.exact.wide import to_wide, wide_dtype
from csgnb.mesh.hull import linear_bsp_arrays
from csgnb.mesh.volume import cells_volume, grouped_cells_volumes, sum_fractions
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


#: Leaves measured together in one forest extraction by :meth:`CellVolumes.measure`.
MEASURE_BATCH = 512


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

    def rekey(self, renamed: dict) -> None:
        """Keep only the entries whose key is in ``renamed`` (old key -> new key), under their new keys: after the
        palette is renumbered, a cell's key names other rows, and an old key could name another cell's content."""
        self._cache = {new: self._cache[old] for old, new in renamed.items() if old in self._cache}

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
        self.measure(w, leaves, keys)
        return sum_fractions(self.volume(w, n, key=k) for n, k in zip(leaves, keys, strict=True))

    def measure(self, w, leaves: list[int], keys: list) -> None:
        """Cache the volumes of the BSP ``leaves`` (with their :func:`cell_key` ``keys``) not cached yet,
        :data:`MEASURE_BATCH` at a time, each batch in **one** extraction of a forest (:func:`_forest_volume`):
        a leaf measured alone costs ~0.3 ms of set-up around a kernel call of a few microseconds (a fresh
        workpiece of 9,000 BSP cells: 3.4 s, most of it that)."""
        todo: dict = {}
        for n, k in zip(leaves, keys, strict=True):
            if k is not None and k not in self._cache:
                todo.setdefault(k, n)
        if len(todo) < 2:
            return
        items = list(todo.items())
        everything = (np.zeros((0, 4), wide_dtype(w.width)), *linear_bsp_arrays(0))  # no tool: its in leaf only
        for i in range(0, len(items), MEASURE_BATCH):
            part = items[i:i + MEASURE_BATCH]
            volumes = _forest_volume(w, [n for _, n in part], everything, solid=True, per_leaf=True)
            for (k, _), v in zip(part, volumes, strict=True):
                self._cache[k] = v


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
    if planes.dtype == object:
        P = np.array([[float(x) for x in row] for row in planes], np.float64).reshape(-1, 4)
    else:
        P = planes.astype(np.float64).reshape(-1, 4)
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
    (negative) for a difference, added volume for a union. Call it before the Boolean.

    Leaves certainly inside the tool count whole (their cached volume); the leaves it cuts are
    measured together, in **one** extraction of a forest (:func:`_forest_volume`): a split on
    axis planes between the octree cells, each cell's box, the tool's planes and the cell's BSP
    -- one pass through the extraction kernel per Boolean instead of one per cell (the
    per-call set-up was most of a milling move's time)."""
    oc = w.oc
    leaves = w.cells_meeting(tool.lo, tool.hi)
    outside, inside = _boxes_against_planes(tool.planes, oc.lo[leaves], oc.size[leaves])
    terms, cut = [], []
    for b, out, inn in zip(leaves.tolist(), outside.tolist(), inside.tolist(), strict=True):
        if out:
            continue
        if inn:
            sb = volumes.volume(w, b)
            terms.append(Fraction(int(oc.size[b]) ** 3) - sb if union else -sb)
        elif union or oc.kind[b] == BSP or oc.label[b] > 0:  # a uniform empty cell loses nothing to a difference
            cut.append(b)
    if cut:
        chain = _chain(tool.planes_wide(w.width))
        if union:  # vol(H ∩ b) - vol(S_b ∩ H): the tool's part of each cell, less the solid's part of it
            terms.append(_forest_volume(w, cut, chain, solid=False) - _forest_volume(w, cut, chain, solid=True))
        else:
            terms.append(-_forest_volume(w, cut, chain, solid=True))
    return sum_fractions(terms)


def _split(boxes: list[tuple]) -> tuple[int, int, list, list]:
    """An axis plane between disjoint boxes ``(lo, hi)`` (octree cells) that cuts none of them, as balanced as it
    comes: ``(axis, coordinate, below, above)``."""
    best = None
    for axis in range(3):
        order = sorted(boxes, key=lambda bx: bx[0][axis])
        reach = -(1 << 200)
        for i in range(1, len(order)):
            reach = max(reach, order[i - 1][1][axis])
            c = order[i][0][axis]
            if reach <= c and order[i - 1][0][axis] < c:
                score = abs(2 * i - len(order))
                if best is None or score < best[0]:
                    best = (score, axis, c, order[:i], order[i:])
    if best is None:
        raise InternalError("octree cells that no axis plane separates (they overlap: a bug)")
    return best[1:]


def _forest_volume(w, nodes: list[int], chain, *, solid: bool, per_leaf: bool = False):
    """Exact volume of ``H ∩ (S_b ∩ b)`` summed over the leaves ``nodes`` (``solid=False``: of ``H ∩ b``), where
    ``H`` is the convex ``chain`` (:func:`_chain`), in one extraction: the leaves' boxes are told apart by axis
    planes (:func:`_split`), and under each box come its six faces, ``H`` and the leaf's tree. ``per_leaf``: the
    list of each leaf's volume instead (in the order of ``nodes``), the cells of the extraction told apart by the
    block their leaf lies in.

    Node layout: the ``len(nodes) - 1`` splitting nodes first (the root is node 0), then one block
    per leaf: six face tests, each with its out leaf (12 nodes), the chain (its in leaf replaced by
    the leaf's tree, which follows)."""
    oc, pool = w.oc, w.pool
    cp, cplane, cneg, cpos, clabel = chain
    k = cplane.shape[0] - 1  # the chain's nodes but its in leaf (node k, where the cell's tree goes)
    c_plane, c_label = cplane[:k].astype(np.int64), clabel[:k].astype(np.int64)
    c_neg, c_pos = cneg[:k].astype(np.int64), cpos[:k].astype(np.int64)
    axis_rows: dict[tuple[int, int], int] = {}  # (axis, c) -> row among the axis planes x_axis - c = 0

    def axis_plane(axis: int, c: int) -> int:
        return -2 - axis_rows.setdefault((axis, c), len(axis_rows))  # a placeholder until the palette is laid out

    n_split = len(nodes) - 1
    split_rows: list[list[int]] = []  # [plane, neg, pos] of the splitting nodes, in index order
    blocks: list[tuple[np.ndarray, ...]] = []
    palettes: list[np.ndarray] = []
    next_row = [cp.shape[0]]  # palette rows: the chain's, then each cell's own planes, then the axis planes
    total = [n_split]  # index of the next block's first node
    bases: list[tuple[int, int]] = []  # (first node, octree leaf) of each block, ascending

    face = np.arange(6)
    inner_low = np.array([False, True, False, True, False, True])  # x <= hi faces keep the inside below the plane

    def block(b: int) -> int:
        base = total[0]
        bases.append((base, b))
        lo = [int(v) for v in oc.lo[b]]
        size = int(oc.size[b])
        faces = np.array([axis_plane(a, lo[a] + (size if hi else 0)) for a in range(3) for hi in (False, True)])
        plane = np.full(12, -1, np.int64)
        neg = np.full(12, -1, np.int64)
        pos = np.full(12, -1, np.int64)
        label = np.zeros(12, np.int64)
        tests = base + 2 * face
        plane[2 * face], label[2 * face] = faces, -1
        nxt = np.append(tests[1:], base + 12)  # the next test, then the chain
        neg[2 * face] = np.where(inner_low, nxt, tests + 1)
        pos[2 * face] = np.where(inner_low, tests + 1, nxt)
        chain_base = base + 12
        parts = [(plane, neg, pos, label),
                 (c_plane, np.where(c_neg >= 0, c_neg + chain_base, -1), np.where(c_pos >= 0, c_pos + chain_base, -1),
                  c_label)]
        root = chain_base + k
        if solid and oc.kind[b] == BSP:
            s, n = int(oc.start[b]), int(oc.length[b])
            pl = pool.plane[s:s + n].astype(np.int64)
            inner = pl >= 0
            used = np.unique(pl[inner])
            if used.shape[0] and int(used[-1]) >= int(oc.counts[N_PAL]):
                raise InternalError(f"octree cell {b} refers to plane {int(used[-1])} beyond the palette (a bug)")
            palettes.append(used)
            pl[inner] = np.searchsorted(used, pl[inner]) + next_row[0]
            next_row[0] += used.shape[0]
            nn, pp = pool.neg[s:s + n].astype(np.int64), pool.pos[s:s + n].astype(np.int64)
            parts.append((pl, np.where(nn >= 0, nn + root, -1), np.where(pp >= 0, pp + root, -1),
                          pool.label[s:s + n].astype(np.int64)))
        else:  # all in: a uniform in leaf, or the box itself
            lab = 1 if (not solid or oc.label[b] > 0) else 0
            parts.append((np.array([-1]), np.array([-1]), np.array([-1]), np.array([lab])))
        arrays = tuple(np.concatenate(col) for col in zip(*parts, strict=True))
        blocks.append(arrays)
        total[0] += arrays[0].shape[0]
        return base

    def forest(boxes: list[tuple]) -> int:
        if len(boxes) == 1:
            return block(boxes[0][2])
        axis, c, below, above = _split(boxes)
        t = len(split_rows)
        split_rows.append([axis_plane(axis, c), -1, -1])
        split_rows[t][1] = forest(below)  # x - c < 0
        split_rows[t][2] = forest(above)
        return t

    boxes = [(tuple(int(v) for v in oc.lo[b]), tuple(int(v) + int(oc.size[b]) for v in oc.lo[b]), b) for b in nodes]
    forest(boxes)
    split = np.array(split_rows, np.int64).reshape(-1, 3)
    plane = np.concatenate([split[:, 0]] + [bl[0] for bl in blocks])
    neg = np.concatenate([split[:, 1]] + [bl[1] for bl in blocks])
    pos = np.concatenate([split[:, 2]] + [bl[2] for bl in blocks])
    label = np.concatenate([np.full(split.shape[0], -1, np.int64)] + [bl[3] for bl in blocks])
    rows = np.zeros((len(axis_rows), 4), np.int64)
    for (axis, c), i in axis_rows.items():
        rows[i, axis] = 1
        rows[i, 3] = -c
    palette = np.concatenate([cp] + [w.palette[u] for u in palettes] + [to_wide(rows, w.width)])
    placeholder = plane <= -2
    plane[placeholder] = next_row[0] + (-2 - plane[placeholder])
    tree = BSPTree(palette, plane.astype(np.int32), neg.astype(np.int32), pos.astype(np.int32), label.astype(np.int32),
                   validate=False)
    lo = np.min([bx[0] for bx in boxes], axis=0)
    hi = np.max([bx[1] for bx in boxes], axis=0)
    store, cells = extract_cells(tree, lo, hi)
    if not per_leaf:
        return cells_volume(store, cells[:, 1])
    first = np.array([bs for bs, _ in bases], np.int64)
    owner = np.searchsorted(first, cells[:, 0], side="right") - 1  # the block each in-cell's leaf lies in
    order = np.argsort(owner, kind="stable")
    ends = np.searchsorted(owner[order], np.arange(len(bases)), side="right")
    volumes = grouped_cells_volumes(store, cells[order, 1], ends)
    by_leaf = {b: v for (_, b), v in zip(bases, volumes, strict=True)}
    return [by_leaf[b] for b in nodes]


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
