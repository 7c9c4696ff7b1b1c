"""Exact volumes of convex cells with homogeneous vertices, fast (paper §3.3's cells, issue: cheap exact volume).

The volume of a closed outward polyhedron is ``(1/6) Σ det(a, b, c)`` over a fan
triangulation of its faces (apex at the origin). With homogeneous vertices ``a = A / a4``
each term is ``det(A, B, C) / (a4 b4 c4)``: an integer over an integer. Both are
computed exactly by one LLVM intrinsic at four times the palette width (a 3x3
determinant of coordinates bounded by 3^(3/2) N² D, eq. 7), made positive in the
denominator, and written as raw 64-bit limbs.

Summing Fractions term by term in Python would cost microseconds each. Instead, where the terms
share denominators (box-like cells: a vertex's ``x4`` depends only on the normals of its three
planes), they are grouped by denominator and each group's numerators added in limbs by a kernel;
where the denominators are mostly distinct (a sweep's slanted cells) each term is read as it is.
Either way the integers are summed in GMP over a running common denominator
(:func:`csgnb.exact.rational.sum_fraction_pairs`), no Fraction per term.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from csgnb._jit import jit
from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.exact.lowering import load_row, row_pointer, wide_width
from csgnb.exact.rational import coprime_fraction, sum_fraction_pairs
from csgnb.exact.wide import width_of
from csgnb.mesh.halfedge import FACE, HE, NEXT, VERT, collect_cell_halfedges

__all__ = ["cells_volume", "grouped_cells_volumes", "sum_fractions", "term_limbs", "wide_polygons_volume"]


def term_limbs(width: int) -> int:
    """64-bit limbs of a volume term's numerator or denominator at palette ``width`` (4x the width)."""
    return 4 * width // 64


@intrinsic
def volume_term_into(typingctx, X, a, b, c, out, row):
    """``out[row] = (det(A, B, C) · s, a4 b4 c4 · s)`` as limbs, ``s`` = sign of the product (so it is positive).

    ``X`` (n, 4) wide homogeneous points; ``out`` (m, 2L) int64 with L = :func:`term_limbs`.
    """
    bits = wide_width(X, "volume_term_into")
    T = ir.IntType(bits)
    W = ir.IntType(4 * bits)
    limbs = 4 * bits // 64

    def codegen(context, builder, sig, args):
        def load(k):
            return [builder.sext(v, W) for v in load_row(context, builder, sig.args[0], args[0], args[k],
                                                         sig.args[k], T, 4)]

        A, B, C = load(1), load(2), load(3)

        def mul(x, y):
            return builder.mul(x, y)

        det = builder.add(
            builder.sub(mul(A[0], builder.sub(mul(B[1], C[2]), mul(B[2], C[1]))),
                        mul(A[1], builder.sub(mul(B[0], C[2]), mul(B[2], C[0])))),
            mul(A[2], builder.sub(mul(B[0], C[1]), mul(B[1], C[0]))))
        den = mul(mul(A[3], B[3]), C[3])
        negative = builder.icmp_signed("<", den, ir.Constant(W, 0))
        det = builder.select(negative, builder.neg(det), det)
        den = builder.select(negative, builder.neg(den), den)
        base = row_pointer(context, builder, sig.args[4], args[4], args[5], sig.args[5])
        i64 = ir.IntType(64)
        for k, value in enumerate((det, den)):
            for j in range(limbs):
                limb = builder.trunc(builder.lshr(value, ir.Constant(W, 64 * j)), i64)
                ptr = builder.bitcast(builder.gep(base, [ir.Constant(i64, 8 * (k * limbs + j))]), i64.as_pointer())
                builder.store(limb, ptr)
        return context.get_dummy_value()

    return types.none(X, a, b, c, out, row), codegen


@jit
def _terms_kernel(m, handles, work, out, ends):
    """Write the fan-triangle terms of every cell in ``handles`` into ``out``; return how many (more than ``out``
    holds: call again with that room). ``ends[i]``: the terms written up to and including cell ``i``."""
    m = unmanaged_tuple(m)
    handles = unmanaged(handles)
    work = unmanaged(work)
    out = unmanaged(out)
    ends = unmanaged(ends)
    he = m.he
    n = 0
    for i in range(handles.shape[0]):
        nh = collect_cell_halfedges(he, m.hmark, m.counts, handles[i], work)
        for j in range(nh):
            g = np.int64(work[j])
            f = np.int64(he[g, FACE])
            if m.fc[f, HE] != g:
                continue
            a = np.int64(he[g, VERT])
            h = np.int64(he[g, NEXT])
            while True:
                h2 = np.int64(he[h, NEXT])
                if h2 == g:
                    break
                if n < out.shape[0]:
                    volume_term_into(m.vx, a, he[h, VERT], he[h2, VERT], out, n)
                n += 1
                h = h2
        ends[i] = n
    return n


@jit
def _group_sums(terms, order, starts, limbs, sums):
    """Sum the numerators of each group (rows ``order[starts[g]:starts[g + 1]]``) into ``sums[g]`` (limbs, exact)."""
    for g in range(starts.shape[0] - 1):
        for j in range(limbs):
            sums[g, j] = 0
        for r in range(starts[g], starts[g + 1]):
            row = order[r]
            carry = np.uint64(0)
            for j in range(limbs):
                x = np.uint64(sums[g, j])
                y = np.uint64(terms[row, j])
                s = x + y
                c1 = np.uint64(1) if s < x else np.uint64(0)
                s2 = s + carry
                c2 = np.uint64(1) if s2 < s else np.uint64(0)
                sums[g, j] = np.int64(s2)
                carry = c1 | c2


def cells_volume(store, handles) -> Fraction:
    """Exact total volume of the convex cells ``handles`` of a :class:`~csgnb.mesh.MeshStore`.

    The terms are made in limbs by one kernel call and summed as the module docstring says.
    """
    handles = np.ascontiguousarray(np.asarray(handles, np.int64).reshape(-1))
    if handles.shape[0] == 0:
        return Fraction(0)
    terms, _ = _cell_terms(store, handles)
    return _terms_volume(terms, term_limbs(store.width))


def grouped_cells_volumes(store, handles, group_ends) -> list[Fraction]:
    """Exact volumes of groups of convex cells of a :class:`~csgnb.mesh.MeshStore`, the terms of all of them made
    in **one** kernel call: group ``g`` is ``handles[group_ends[g - 1]:group_ends[g]]`` (``group_ends`` ascending,
    its last entry ``len(handles)``; an empty group has volume 0). What :func:`cells_volume` of each group gives.
    """
    handles = np.ascontiguousarray(np.asarray(handles, np.int64).reshape(-1))
    group_ends = np.asarray(group_ends, np.int64).reshape(-1)
    if group_ends.shape[0] and int(group_ends[-1]) != handles.shape[0]:
        raise ValueError(f"the last group must end at the last handle ({handles.shape[0]}), got {group_ends[-1]}")
    L = term_limbs(store.width)
    terms, ends = _cell_terms(store, handles)
    # the term range of each group: from the end of its first cell's predecessor to the end of its last cell
    cut = np.concatenate([[0], ends])[group_ends]
    starts = np.concatenate([[0], cut[:-1]])
    return [_terms_volume(terms[a:b], L) for a, b in zip(starts.tolist(), cut.tolist(), strict=True)]


def _cell_terms(store, handles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fan-triangle terms of the cells ``handles`` ((n, 2L) int64, cell after cell) and, per cell, the end of
    its terms ((len(handles),) int64)."""
    L = term_limbs(store.width)
    work = np.empty(store.he.shape[0], np.int32)
    ends = np.zeros(handles.shape[0], np.int64)
    out = np.empty((max(64, 32 * handles.shape[0]), 2 * L), np.int64)
    n = int(_terms_kernel(store.m, handles, work, out, ends))
    if n > out.shape[0]:
        out = np.empty((n, 2 * L), np.int64)
        n = int(_terms_kernel(store.m, handles, work, out, ends))
    return out[:n], ends


@jit
def _polygon_terms_kernel(X, offsets, indices, keep, out):
    """Write the fan-triangle terms of every kept polygon ``indices[offsets[p]:offsets[p + 1]]`` of points ``X``
    into ``out`` (room for all of them); return how many."""
    n = 0
    for p in range(offsets.shape[0] - 1):
        if not keep[p]:
            continue
        first = offsets[p]
        a = indices[first]
        for j in range(first + 1, offsets[p + 1] - 1):
            volume_term_into(X, a, indices[j], indices[j + 1], out, n)
            n += 1
    return n


def wide_polygons_volume(vertices: np.ndarray, offsets: np.ndarray, indices: np.ndarray,
                         keep: np.ndarray | None = None) -> Fraction:
    """Exact signed volume enclosed by closed, outward polygons over homogeneous wide points.

    ``vertices`` (n, 4) wide with x4 > 0 -- or of either sign, consistently per point; polygon ``p`` is
    ``indices[offsets[p]:offsets[p + 1]]``, counter-clockwise seen from outside; ``keep`` (k,) bool selects
    polygons (default: all). The same fans and sum as :func:`csgnb.mesh.halfedge.polygons_volume` on the points as
    Fractions, but each term ``det(A, B, C) / (a4 b4 c4)`` made exactly in limbs by a kernel and the terms summed
    by :func:`_terms_volume` -- a drilled block's boundary (160,000 triangles) in well under a second instead of
    ~8 s of Fraction arithmetic.
    """
    offsets = np.ascontiguousarray(offsets, np.int64)
    indices = np.ascontiguousarray(indices, np.int64)
    k = offsets.shape[0] - 1
    keep = np.ones(k, np.bool_) if keep is None else np.ascontiguousarray(keep, np.bool_)
    if keep.shape != (k,):
        raise ValueError(f"keep must have one entry per polygon ({k}), got shape {keep.shape}")
    sizes = np.diff(offsets)
    n = int(np.maximum(sizes[keep] - 2, 0).sum())
    if n == 0:
        return Fraction(0)
    L = term_limbs(width_of(vertices))
    out = np.empty((n, 2 * L), np.int64)
    written = int(_polygon_terms_kernel(np.ascontiguousarray(vertices), offsets, indices, keep, out))
    return _terms_volume(out[:written], L)


def _terms_volume(terms: np.ndarray, L: int) -> Fraction:
    """``(1/6) Σ num / den`` over the rows of ``terms`` (m, 2L) int64: each row a term's numerator and its positive
    denominator as ``L`` little-endian limbs each (:func:`volume_term_into`), exactly."""
    n = terms.shape[0]
    if n == 0:
        return Fraction(0)
    if 4 * np.unique(terms[:, L]).shape[0] > 3 * n:
        # Mostly distinct denominators (a sweep's slanted cells; told by their lowest limbs alone): grouping would
        # find next to nothing to add in limbs, so every term is read as it is (a carved part's volume: -7 %).
        # Box-like cells, whose terms share a few denominators (1 most of all), are grouped below (half the time
        # of reading every term there).
        nums, dens = terms[:, :L], terms[:, L:]
    else:
        den = np.ascontiguousarray(terms[:, L:]).view(np.dtype((np.void, 8 * L))).reshape(-1)
        uniq, inverse = np.unique(den, return_inverse=True)
        order = np.argsort(inverse, kind="stable").astype(np.int64)
        starts = np.searchsorted(inverse[order], np.arange(uniq.shape[0] + 1)).astype(np.int64)
        nums = np.empty((uniq.shape[0], L), np.int64)
        # The sum of a group fits: at most n terms of at most 2^(3b) each, far below 2^(4b - 1).
        _group_sums(terms, order, starts, L, nums)
        dens = terms[order[starts[:-1]], L:]
    # Numerators over their denominators as plain integers, added over a running common denominator (the terms'
    # denominators share their factors; pairwise where they do not: csgnb.exact.rational.sum_fraction_pairs).
    k = 8 * L
    nb = np.ascontiguousarray(nums).tobytes()
    db = np.ascontiguousarray(dens).tobytes()
    frac = [(int.from_bytes(nb[i * k:(i + 1) * k], "little", signed=True),
             int.from_bytes(db[i * k:(i + 1) * k], "little", signed=True)) for i in range(nums.shape[0])]
    num, den = sum_fraction_pairs(frac)  # reduced: only the factors of 6 can cancel against the numerator
    g = math.gcd(num, 6)
    return coprime_fraction(num // g, (6 // g) * den)


def sum_fractions(values) -> Fraction:
    """The exact sum of Fractions: numerators of equal denominators added first, then the groups in GMP over a
    running common denominator, pairwise where the denominators share little
    (:func:`csgnb.exact.rational.sum_fraction_pairs`).

    >>> sum_fractions([Fraction(1, 3), Fraction(1, 6), Fraction(1, 2)])
    Fraction(1, 1)
    """
    groups: dict[int, int] = {}
    for v in values:
        groups[v.denominator] = groups.get(v.denominator, 0) + v.numerator
    num, den = sum_fraction_pairs([(n, d) for d, n in groups.items()])
    return coprime_fraction(num, den)
