"""A Boolean of two solids from their boundaries: each operand's pieces pushed through the other's tree.

:func:`csgnb.bsp.merge` finds the result by cutting the box with every plane of A and, at A's
leaves, of B; its redundancy removal then clips every face of the merged cells to find the
boundary and re-imports it (§3.5, §3.7). When both operands' exact boundaries are at hand --
convex plane-based pieces, as the redundancy removal and the tool import produce them -- the
result's boundary follows without any cell: a point on the result's boundary lies on A's or
on B's, so

* each piece of A is pushed down B's tree (split where B's planes cross it) and each fragment
  learns B's labels just behind and just in front of it, and
* each piece of B is pushed down A's tree the same way;

a fragment is boundary of ``f(A, B)`` where the result's labels behind and in front of it
differ, facing the result's outside (flipped where ``f`` turns it round, as a difference does
with B's pieces). A fragment lying in a plane of the other tree (coplanar) has different labels
behind and in front: its behind point follows the subtree on its back, its front point the other
one (:func:`merge_boundaries` keeps two node cursors per fragment). Where a piece of B lies on A's
boundary (A's labels differ behind and in front of it) A's piece covers the same place and
decides it, so B's is dropped: nothing is kept twice.

The pieces are exact (plane-based, §3.6: vertices are plane triples, splits create no planes);
a piece whose fragments are all kept the same way is written whole, so boundaries are not cut
up by planes that change nothing on them. The labels must be in / out (0 and 1): a boundary
bounds one material.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from csgnb._jit import borrowing_jit, jit
from csgnb._resumable import DONE, NEED_ROOM, grown, run_resumable
from csgnb._unlinked import unlinked
from csgnb.bsp.extract import TreeArrays, boundary_pieces, tree_arrays
from csgnb.bsp.merging import merge, merge_table
from csgnb.bsp.polygon import PolygonSet, copy_point, polygon_set_vertices, split_polygon
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.intrinsics import classify_at, wide_sign_at
from csgnb.exact.wide import width_of

__all__ = ["PieceArrays", "PushScratch", "begin_push", "boolean_from_boundaries", "boundary_polygons",
           "merge_boundaries", "new_push_scratch", "push_pieces", "strictly_outside"]


class PieceArrays(NamedTuple):
    """Plane-based convex pieces with their vertices (the import's input format).

    support : (c,) int32 -- signed palette row (``~row`` flipped); the piece faces the positive side;
    offsets : (c,) int32 -- the same capacity c >= n + 1; piece i's edges are ``edges[offsets[i]:offsets[i + 1]]``;
    edges : (m,) int32 -- palette rows; vertex j = support ∩ edges[j] ∩ edges[j + 1];
    verts : (m, 4) wide -- those vertices (homogeneous), row-aligned with ``edges``.
    """

    support: np.ndarray
    offsets: np.ndarray
    edges: np.ndarray
    verts: np.ndarray


class PushScratch(NamedTuple):
    """Scratch of :func:`merge_boundaries`: a stack-ordered piece arena and the work stack.

    edges (cap,) int32, verts (cap, 4) wide, sides (cap,) int8; st_start, st_k, st_behind, st_front (s,) int64.
    """

    edges: np.ndarray
    verts: np.ndarray
    sides: np.ndarray
    st_start: np.ndarray
    st_k: np.ndarray
    st_behind: np.ndarray
    st_front: np.ndarray


def new_push_scratch(dtype, arena: int = 1024, stack: int = 256) -> PushScratch:
    """A :class:`PushScratch` for vertices of wide dtype ``dtype``."""
    return PushScratch(np.empty(arena, np.int32), np.empty((arena, 4), dtype), np.empty(arena, np.int8),
                       *(np.empty(stack, np.int64) for _ in range(4)))


#: merge_boundaries' ``state``: pieces and edges written, whether A is unchanged (1), fragments of B kept.
S_PIECES, S_EDGES, S_A_UNCHANGED, S_B_KEPT = 0, 1, 2, 3
#: What was short when :func:`merge_boundaries` returns NEED_ROOM (``state[4]``): the arena, the stack, the output.
S_NEED = 4
NEED_ARENA, NEED_STACK, NEED_OUT = 1, 2, 3
#: A fragment's fate: dropped, kept as it faces, kept turned round; MIXED: the fragments of a piece differ.
DROP, KEEP, FLIP, MIXED = 0, 1, -1, 9



@jit(inline="always")
def _same_orientation(pal, row, flipped, q):
    """Whether palette row ``q`` (coplanar with the piece) is oriented like the piece's facing plane.

    The facing plane is row ``row``, negated when ``flipped``. Coplanar planes have parallel normals,
    so the sign of the first non-zero normal component decides.
    """
    if q == row:
        return not flipped
    for c in range(3):
        a = wide_sign_at(pal, row, c)
        if a != 0:
            return (a == wide_sign_at(pal, q, c)) != flipped
    return not flipped


@jit(inline="always")
def _piece_side(pal, sc, start, k, row, q):
    """Where the piece at arena rows ``start .. start + k - 1`` (support ``row``) lies against plane ``q``:
    -1, +1, 0 (coplanar) or 2 (properly split); fills ``sc.sides`` only when it has to classify every vertex."""
    if q == row:
        return 0
    # A piece with an edge on q lies on one closed side of it (convex): the vertex after that edge decides,
    # unless it is on q too (as in the import, csgnb.bsp.build.build_kernel).
    for j in range(start, start + k):
        if sc.edges[j] == q:
            after = j + 1 if j + 1 < start + k else start
            side = classify_at(sc.verts, after, pal, q)
            if side != 0:
                return side
            break
    has_neg = False
    has_pos = False
    for j in range(start, start + k):
        c = classify_at(sc.verts, j, pal, q)
        if c < 0:
            has_neg = True
        elif c > 0:
            has_pos = True
    return 2 if has_neg and has_pos else (-1 if has_neg else (1 if has_pos else 0))


@jit(inline="always")
def _write_fragment(sc, start, k, s, flip, out, n, e):
    """Append the arena piece (support ``s``) to ``out`` as piece ``n`` at edge ``e``, turned round if ``flip``."""
    out.offsets[n] = e
    if flip:
        out.support[n] = ~s
        # reversed edges e'_j = e_(k-1-j): vertex'_j = e_(k-1-j) ∩ e_(k-2-j) = vertex_(k-2-j)
        for j in range(k):
            out.edges[e + j] = sc.edges[start + k - 1 - j]
            v = k - 2 - j
            copy_point(sc.verts, start + (v if v >= 0 else v + k), out.verts, e + j)
    else:
        out.support[n] = s
        for j in range(k):
            out.edges[e + j] = sc.edges[start + j]
            copy_point(sc.verts, start + j, out.verts, e + j)
    out.offsets[n + 1] = e + k


@jit(inline="always")
def _out_room(out, n, e, k):
    """Whether ``out`` has room for one more piece of ``k`` edges after ``n`` pieces and ``e`` edges."""
    return n + 2 <= out.offsets.shape[0] and n + 1 <= out.support.shape[0] and e + k <= out.edges.shape[0]


@jit(inline="always")
def _fate(in_a, table, t, behind, front):
    """What becomes of a fragment whose behind / front points are at leaves ``behind`` / ``front`` of the other
    operand's tree ``t``: :data:`KEEP` it, :data:`FLIP` it (the result's inside is in front) or :data:`DROP` it."""
    lb = t.label[behind]
    lf = t.label[front]
    if in_a:
        rb = table[1, lb]
        rf = table[0, lf]
    elif lb != lf:
        return DROP  # on A's boundary: A's piece there decides
    else:
        rb = table[lb, 1]
        rf = table[lf, 0]
    if rb == rf:
        return DROP
    return KEEP if rb != 0 else FLIP


@jit(inline="always")
def _next_node(t, behind, front):
    """The inner node of ``t`` a fragment's cursors meet next (the behind point's first), -1 when both are at leaves."""
    if t.plane[behind] >= 0:
        return behind
    return front if t.plane[front] >= 0 else -1


@jit(inline="always")
def _next_cursors(pal, row, flipped, t, behind, front, node, side):
    """The cursors (behind, front) after node ``node`` (the one a cursor is at) for a piece on ``side`` of it:
    -1 / +1 both to that child, 0 (in its plane) the behind point to the piece's back, the front to the other."""
    joint = behind == front
    if side != 0:
        child = t.neg[node] if side < 0 else t.pos[node]
        return (child if joint or node == behind else behind), (child if joint or node == front else front)
    same = _same_orientation(pal, row, flipped, t.plane[node])
    back = t.neg[node] if same else t.pos[node]
    ahead = t.pos[node] if same else t.neg[node]
    if joint:
        return back, ahead
    if node == behind:
        return back, front
    return behind, ahead


@jit(inline="always")
def _probe(pal, sc, k, row, flipped, t, in_a, table):
    """The fate every fragment of the whole piece at arena rows 0 .. k - 1 would meet, or :data:`MIXED`.

    Walks the other tree with the whole piece, into both children where a plane crosses it: the leaves it
    reaches hold every leaf its fragments would reach, so one fate there is every fragment's -- decided without
    splitting (most pieces lie far from the other operand's boundary). Uses the scratch stack's cursor columns;
    :data:`MIXED` also when the stack is short."""
    cap = sc.st_behind.shape[0]
    sc.st_behind[0] = 0
    sc.st_front[0] = 0
    top = 1
    fate = -9
    while top > 0:
        top -= 1
        behind = sc.st_behind[top]
        front = sc.st_front[top]
        while True:
            node = _next_node(t, behind, front)
            if node < 0:
                f = _fate(in_a, table, t, behind, front)
                if fate == -9:
                    fate = f
                elif f != fate:
                    return MIXED
                break
            side = _piece_side(pal, sc, 0, k, row, t.plane[node])
            if side == 2:
                if top >= cap:
                    return MIXED
                sc.st_behind[top], sc.st_front[top] = _next_cursors(pal, row, flipped, t, behind, front, node, 1)
                top += 1
                side = -1
            behind, front = _next_cursors(pal, row, flipped, t, behind, front, node, side)
    return fate


@jit(inline="always")
def strictly_outside(pal, v, i, t, stack):
    """Whether the homogeneous point ``v[i]`` lies strictly outside the solid of tree ``t`` (labels 0 / 1): some
    ball around it holds no point of the solid.

    On a node's plane the point is followed down both sides: a point whose every side ends at an outside leaf has
    no inside point near it on either side of that plane, so it is not on the solid's boundary either (a regular
    solid has no boundary without inside next to it). ``stack`` (s,) int64 is scratch; False also when it is
    short (the caller takes its exact path)."""
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        while t.plane[node] >= 0:
            side = classify_at(v, i, pal, t.plane[node])
            if side == 0:
                if top >= stack.shape[0]:
                    return False
                stack[top] = t.pos[node]
                top += 1
                node = t.neg[node]
            else:
                node = t.neg[node] if side < 0 else t.pos[node]
        if t.label[node] != 0:
            return False
    return True


@jit(inline="always")
def begin_push(out, state):
    """Start a boundary merge's output: no pieces in ``out``, A unchanged so far, no fragment of B kept."""
    state[S_PIECES] = 0
    state[S_EDGES] = 0
    state[S_A_UNCHANGED] = 1
    state[S_B_KEPT] = 0
    out.offsets[0] = 0


@unlinked
@borrowing_jit
def push_pieces(pal, p, n, in_a, t, table, out, sc, state):
    """Push one operand's pieces ``p[:n]`` (A's when ``in_a``) down the other operand's tree ``t`` and append the
    fragments that bound ``table[A, B]`` to ``out`` after the ``state[S_PIECES]`` pieces already there
    (:func:`begin_push` starts; the counts of :func:`merge_boundaries` are kept up to date, so that the operands
    can be pushed in either order and a caller can stop between them). Returns DONE, or NEED_ROOM with
    ``state[S_NEED]`` naming the array that was short (start again from :func:`begin_push` after growing it)."""
    n_out = state[S_PIECES]
    e_out = state[S_EDGES]
    a_unchanged = state[S_A_UNCHANGED] == 1
    b_kept = state[S_B_KEPT]
    cap = sc.edges.shape[0]
    cap_stack = sc.st_start.shape[0]
    for j in range(n):
        s = p.support[j]
        row = s if s >= 0 else ~s
        flipped = s < 0
        e0 = p.offsets[j]
        k0 = p.offsets[j + 1] - e0
        if 3 * k0 + 2 > cap:
            state[S_NEED] = NEED_ARENA
            return NEED_ROOM
        for r in range(k0):
            sc.edges[r] = p.edges[e0 + r]
            copy_point(p.verts, e0 + r, sc.verts, r)
        fate = _probe(pal, sc, k0, row, flipped, t, in_a, table)
        if fate != MIXED:
            # every fragment meets the same fate: the piece whole, or nothing
            if in_a:
                a_unchanged = a_unchanged and fate == KEEP
            if fate != DROP:
                if not _out_room(out, n_out, e_out, k0):
                    state[S_NEED] = NEED_OUT
                    return NEED_ROOM
                _write_fragment(sc, 0, k0, s, fate == FLIP, out, n_out, e_out)
                n_out += 1
                e_out += k0
                if not in_a:
                    b_kept += 1
            continue
        # the walk: the piece split where its fragments' fates differ (the probe's leaves are a superset: they can
        # all meet the same fate after all -- then the piece is written whole)
        n_first = n_out
        e_first = e_out
        b_first = b_kept
        fate_all = -9
        sc.st_start[0] = 0
        sc.st_k[0] = k0
        sc.st_behind[0] = 0
        sc.st_front[0] = 0
        top = 1
        while top > 0:
            top -= 1
            start = sc.st_start[top]
            k = sc.st_k[top]
            behind = sc.st_behind[top]
            front = sc.st_front[top]
            while True:
                node = _next_node(t, behind, front)
                if node < 0:
                    fate = _fate(in_a, table, t, behind, front)
                    fate_all = fate if fate_all == -9 or fate_all == fate else MIXED
                    if fate != DROP:
                        if not _out_room(out, n_out, e_out, k):
                            state[S_NEED] = NEED_OUT
                            return NEED_ROOM
                        _write_fragment(sc, start, k, s, fate == FLIP, out, n_out, e_out)
                        n_out += 1
                        e_out += k
                        if not in_a:
                            b_kept += 1
                    break
                q = t.plane[node]
                side = _piece_side(pal, sc, start, k, row, q)
                if side == 2:
                    o_pos = start + k
                    o_neg = start + 2 * k + 1
                    if o_neg + k + 1 > cap:
                        state[S_NEED] = NEED_ARENA
                        return NEED_ROOM
                    if top >= cap_stack:
                        state[S_NEED] = NEED_STACK
                        return NEED_ROOM
                    side, k_neg, k_pos = split_polygon(pal, row, q, sc.edges, sc.verts, start, k, sc.sides, o_neg,
                                                       o_pos)
                    sc.st_start[top] = o_pos
                    sc.st_k[top] = k_pos
                    sc.st_behind[top], sc.st_front[top] = _next_cursors(pal, row, flipped, t, behind, front, node, 1)
                    top += 1
                    start = o_neg
                    k = k_neg
                    side = -1
                behind, front = _next_cursors(pal, row, flipped, t, behind, front, node, side)
        if in_a:
            a_unchanged = a_unchanged and fate_all == KEEP
        if fate_all != MIXED:
            n_out = n_first
            e_out = e_first
            b_kept = b_first
            if fate_all != DROP:
                for r in range(k0):
                    sc.edges[r] = p.edges[e0 + r]
                    copy_point(p.verts, e0 + r, sc.verts, r)
                _write_fragment(sc, 0, k0, s, fate_all == FLIP, out, n_out, e_out)  # (room: its fragments fitted)
                n_out += 1
                e_out += k0
                if not in_a:
                    b_kept += 1
    state[S_PIECES] = n_out
    state[S_EDGES] = e_out
    state[S_A_UNCHANGED] = 1 if a_unchanged and b_kept == 0 else 0
    state[S_B_KEPT] = b_kept
    return DONE


@unlinked
@borrowing_jit
def merge_boundaries(pal, ta, pa, na, tb, pb, nb, table, out, sc, state):
    """The boundary of ``table[A, B]`` from A's pieces ``pa[:na]`` and B's ``pb[:nb]`` (module docstring).

    ``ta``, ``tb`` are the operands' trees (:class:`~csgnb.bsp.extract.TreeArrays`, root 0, labels 0 / 1) over
    the palette ``pal``, which also holds every plane of the pieces (:class:`PieceArrays`, facing out of their
    solid). ``table`` (2, 2) is the label function. The result's pieces are written to ``out`` (a
    :class:`PieceArrays`), facing out of the result, A's first. ``state`` (>= 5,) int64 receives the counts
    (:data:`S_PIECES`, :data:`S_EDGES`), whether the result is A (:data:`S_A_UNCHANGED`: every piece of A kept as
    it was, none of B) and the fragments of B kept. Returns DONE, or NEED_ROOM with ``state[S_NEED]`` naming
    the array that was short (start again after growing it: nothing else is kept).
    """
    begin_push(out, state)
    status = push_pieces(pal, pa, na, True, tb, table, out, sc, state)
    if status != DONE:
        return status
    return push_pieces(pal, pb, nb, False, ta, table, out, sc, state)


# ---------------------------------------------------------------------------
# from Python


def _pieces_of(palette: np.ndarray, polygons: PolygonSet, shift: int) -> PieceArrays:
    """The :class:`PieceArrays` of ``polygons`` (rows of ``palette``) with every row moved by ``shift``."""
    verts = polygon_set_vertices(palette, polygons)
    n = len(polygons)
    support = np.empty(n + 1, np.int32)
    support[:n] = np.where(polygons.support >= 0, polygons.support + shift, polygons.support - shift)
    return PieceArrays(support, polygons.offsets.astype(np.int32), (polygons.edges + shift).astype(np.int32),
                       np.ascontiguousarray(verts))


def boolean_from_boundaries(a: BSPTree, a_pieces: PolygonSet, b: BSPTree, b_pieces: PolygonSet, fn):
    """The boundary of ``fn(A, B)`` from both operands' trees and boundary pieces (see the module docstring).

    Parameters
    ----------
    a, b : BSPTree
        In / out solids (labels 0 and 1) of the same width.
    a_pieces, b_pieces : PolygonSet
        Their exact boundaries as convex pieces over their own palettes, facing out of the solid: for a solid
        inside a box, its boundary inside the box (:func:`boundary_polygons`).
    fn : callable
        The label function, ``fn(la, lb)`` in {0, 1} (``csgnb.bsp.UNION``, ``INTERSECTION``, ``DIFFERENCE``...).

    Returns
    -------
    (palette, pieces, a_unchanged)
        ``palette`` is a's rows then b's; ``pieces`` the result's boundary (a :class:`PolygonSet` over it, facing
        out: :func:`~csgnb.bsp.build.bsp_from_polygons` gives its BSP); ``a_unchanged`` whether the result's
        boundary is A's, piece for piece.
    """
    if width_of(a.palette) != width_of(b.palette):
        raise GeometryError(f"cannot combine a {a.width}-bit BSP with a {b.width}-bit BSP: convert one first")
    for name, tree in (("a", a), ("b", b)):
        labels = set(np.unique(tree.label[tree.plane < 0]).tolist())
        if not labels <= {OUT, 1}:
            raise GeometryError(f"{name} has labels {sorted(labels)}: a boundary bounds one material (labels 0 and 1)")
    table = merge_table(fn, np.array([0, 1], np.int32), np.array([0, 1], np.int32))
    if not np.isin(table, (0, 1)).all():
        raise GeometryError(f"fn must give labels 0 or 1 on in / out operands, got the table {table.tolist()}")
    shift = a.palette.shape[0]
    palette = np.ascontiguousarray(np.concatenate([a.palette, b.palette]))
    pa = _pieces_of(a.palette, a_pieces, 0)
    pb = _pieces_of(b.palette, b_pieces, shift)
    ta = tree_arrays(a)
    tb = TreeArrays(np.where(b.plane >= 0, b.plane + shift, -1).astype(np.int32), b.neg, b.pos, b.label)
    n_in = len(a_pieces) + len(b_pieces)
    edges_in = int(a_pieces.offsets[-1] + b_pieces.offsets[-1])
    box = {"out": PieceArrays(np.empty(2 * n_in + 8, np.int32), np.zeros(2 * n_in + 8, np.int32),
                              np.empty(2 * edges_in + 16, np.int32), np.empty((2 * edges_in + 16, 4), palette.dtype)),
           "sc": new_push_scratch(palette.dtype, max(1024, 8 * int(max(a_pieces.sizes.max(initial=3),
                                                                       b_pieces.sizes.max(initial=3)))))}
    state = np.zeros(5, np.int64)

    def step():
        return merge_boundaries(palette, ta, pa, len(a_pieces), tb, pb, len(b_pieces), table, box["out"], box["sc"],
                                state)

    def grow():
        what = int(state[S_NEED])
        if what == NEED_ARENA:
            sc = box["sc"]
            box["sc"] = sc._replace(edges=grown(sc.edges), verts=grown(sc.verts), sides=grown(sc.sides))
        elif what == NEED_STACK:
            sc = box["sc"]
            box["sc"] = sc._replace(**{f: grown(getattr(sc, f)) for f in ("st_start", "st_k", "st_behind",
                                                                           "st_front")})
        else:
            o = box["out"]
            box["out"] = PieceArrays(grown(o.support), grown(o.offsets), grown(o.edges), grown(o.verts))

    run_resumable(step, grow, "boundary merge")
    n, m = int(state[S_PIECES]), int(state[S_EDGES])
    o = box["out"]
    pieces = PolygonSet(o.support[:n].copy(), o.offsets[: n + 1].copy() if n else np.zeros(1, np.int32),
                        o.edges[:m].copy())
    return palette, pieces, bool(state[S_A_UNCHANGED])


def boundary_polygons(tree: BSPTree, lo, hi) -> tuple[BSPTree, PolygonSet]:
    """A solid inside the box ``[lo, hi]`` as :func:`boolean_from_boundaries` takes it: its tree inside the box
    (over a palette with the box's planes added) and its boundary pieces inside the box, facing out."""
    result = merge(tree, BSPTree.leaf(tree.palette[:0], OUT), lambda x, _: x, lo, hi)
    palette, _, edges, polys = boundary_pieces(result.tree, result.store, result.cells, walls=False)
    if polys.shape[0] == 0:
        return BSPTree(palette, *tree_arrays(result.tree), validate=False), PolygonSet(
            np.zeros(0, np.int32), np.zeros(1, np.int32), np.zeros(0, np.int32))
    sizes = polys[:, 1]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32)
    order = np.repeat(polys[:, 0].astype(np.int64) - offsets[:-1], sizes) + np.arange(int(offsets[-1]))
    return (BSPTree(palette, *tree_arrays(result.tree), validate=False),
            PolygonSet(polys[:, 2].astype(np.int32), offsets, edges[order].astype(np.int32)))
