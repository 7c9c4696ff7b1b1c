"""Exact wide-integer intrinsics of surface assembly and export (:mod:`csgnb.bsp.surface_kernels`).

Small LLVM intrinsics in the style of :mod:`csgnb.exact.intrinsics` (same loaders, same
``(array, row, ...)`` operands, one compiled version per width). Each docstring states the
width its arithmetic runs at and why that width is exact; ``w`` is the width of the operands
(128, 192 or 256 bits).

Two kinds of guarantee appear:

* **any stored values** -- exact for any ``w``-bit entries (|v| <= 2^(w-1)), no budget needed;
* **palette budget** -- exact for planes that pass :func:`csgnb.exact.budgets.check_planes`
  (max normal coefficient N, max offset D with 16 N^3 D < 2^(w-1), 27 N^6 < 2^(2w-2),
  27 N^4 D^2 < 2^(2w-2); paper eq. 7), which :func:`~csgnb.bsp.surface.assemble_surface`
  checks on entry.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core.errors import TypingError
from numba.extending import intrinsic

# Only the loaders and sign helpers come from csgnb.exact.lowering (the public code-generation helpers every
# package's intrinsics use); the integer arithmetic below is local, so it does not follow that module's layout.
from csgnb.exact.lowering import absolute, element_pointer, load, load_row, row_pointer, sign, wide_width

__all__ = [
    "on_plane_at",
    "line_direction_into",
    "normals_det_sign_at",
    "normals_dot_sign_at",
    "binet_cauchy_sign_at",
    "compare_coordinate_at",
    "copy_normalized_into",
    "collinear_at",
]


def _same_width(name: str, *atys) -> int:
    """The common width of wide arrays ``atys``; a typing error if they differ."""
    widths = {wide_width(a, name) for a in atys}
    if len(widths) != 1:
        raise TypingError(f"{name}: operands have different widths {sorted(widths)}")
    return widths.pop()


def _det2(builder, a, b, c, d):
    """a*d - b*c, at the operands' type."""
    return builder.sub(builder.mul(a, d), builder.mul(b, c))


def _dot(builder, xs, ys):
    """Σ x_k y_k, at the operands' type."""
    acc = builder.mul(xs[0], ys[0])
    for x, y in zip(xs[1:], ys[1:], strict=True):
        acc = builder.add(acc, builder.mul(x, y))
    return acc


_I8 = ir.IntType(8)
_I64 = ir.IntType(64)


@intrinsic
def on_plane_at(typingctx, X, i, S, j):
    """Whether point ``X[i]`` lies on plane ``S[j]``: x·s = 0, computed at 2w + 64 bits.

    Exact for **any stored values**: each product is at most 2^(2w-2) in magnitude, the sum of
    four at most 2^(2w), which a (2w + 64)-bit integer holds. So a vertex that does not come
    from the palette (a bad input) is still classified exactly instead of wrapping around.
    """
    bits = _same_width("on_plane_at", X, S)
    T = ir.IntType(bits)
    W = ir.IntType(2 * bits + 64)

    def codegen(context, builder, sig, args):
        x = [builder.sext(v, W) for v in load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)]
        s = [builder.sext(v, W) for v in load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 4)]
        return builder.icmp_signed("==", _dot(builder, x, s), ir.Constant(W, 0))

    return types.boolean(X, i, S, j), codegen


@intrinsic
def line_direction_into(typingctx, P, i, j, out, row):
    """Store (u1, u2, u3, u_k) into ``out[row]`` for u = n_i x n_j of planes ``P[i]``, ``P[j]``; return k.

    ``k`` is the axis of the largest |u_k| (ties: the lowest axis), a choice that does not
    change when u is scaled by any non-zero factor, so it is the same for every pair of planes
    through one line. Returns -1 when u = 0 (parallel planes: no line).

    Width w, **palette budget**: |u_c| <= 2 N^2, and 27 N^6 < 2^(2w-2) gives N^3 < 2^(w-1) / 5.19,
    so 2 N^2 <= 2 N^3 < 2^(w-1) for N >= 1 (at 128 bits N < 2^41.7, 2 N^2 < 2^84.4).
    """
    bits = _same_width("line_direction_into", P, out)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        a1, b1, c1 = load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 3)
        a2, b2, c2 = load_row(context, builder, sig.args[0], args[0], args[2], sig.args[2], T, 3)
        u = [_det2(builder, b1, c1, b2, c2), _det2(builder, c1, a1, c2, a2), _det2(builder, a1, b1, a2, b2)]
        mags = [absolute(builder, v) for v in u]
        k = ir.Constant(_I64, 0)
        best = mags[0]
        uk = u[0]
        for axis in (1, 2):
            better = builder.icmp_unsigned(">", mags[axis], best)
            k = builder.select(better, ir.Constant(_I64, axis), k)
            best = builder.select(better, mags[axis], best)
            uk = builder.select(better, u[axis], uk)
        base = row_pointer(context, builder, sig.args[3], args[3], args[4], sig.args[4])
        for c, v in enumerate([*u, uk]):
            builder.store(v, element_pointer(builder, base, c, T), align=8)
        zero = builder.icmp_unsigned("==", best, ir.Constant(T, 0))
        return builder.select(zero, ir.Constant(_I64, -1), k)

    return types.int64(P, i, j, out, row), codegen


@intrinsic
def normals_det_sign_at(typingctx, P, i, j, k):
    """int8 sign of det(n_i, n_j, n_k) for planes ``P[i]``, ``P[j]``, ``P[k]``.

    Width w, **palette budget**: the value is an x4 of eq. 5, |det| <= 3^(3/2) N^3 < 2^(w-1)
    (27 N^6 < 2^(2w-2)); partial sums may wrap, the final value cannot.
    """
    bits = _same_width("normals_det_sign_at", P)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        n = [load_row(context, builder, sig.args[0], args[0], args[c], sig.args[c], T, 3) for c in (1, 2, 3)]
        (a1, b1, c1), (a2, b2, c2), (a3, b3, c3) = n
        det = _dot(
            builder,
            [a1, b1, c1],
            [_det2(builder, b2, c2, b3, c3), _det2(builder, c2, a2, c3, a3), _det2(builder, a2, b2, a3, b3)],
        )
        return sign(builder, det)

    return types.int8(P, i, j, k), codegen


@intrinsic
def normals_dot_sign_at(typingctx, P, i, j):
    """int8 sign of n_i · n_j, at 2w + 64 bits (exact for **any stored values**: three products of 2^(2w-2))."""
    bits = _same_width("normals_dot_sign_at", P)
    T = ir.IntType(bits)
    W = ir.IntType(2 * bits + 64)

    def codegen(context, builder, sig, args):
        a = [builder.sext(v, W) for v in load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 3)]
        b = [builder.sext(v, W) for v in load_row(context, builder, sig.args[0], args[0], args[2], sig.args[2], T, 3)]
        return sign(builder, _dot(builder, a, b))

    return types.int8(P, i, j), codegen


@intrinsic
def binet_cauchy_sign_at(typingctx, P, a, b, s, t):
    """int8 sign of (n_a x n_b) · (n_s x n_t) = (n_a·n_s)(n_b·n_t) - (n_a·n_t)(n_b·n_s) (Binet-Cauchy).

    This is det(n_a, n_b, u) for the direction u = n_s x n_t of the line where planes s and t
    meet: the exact angular comparison of two faces around an edge on that line.

    Width 2w, **palette budget**: each dot product is at most 3 N^2, the value at most 18 N^4;
    N^3 < 2^(w-1) / 5.19 gives 18 N^4 < 2^(4(w-1)/3 + 1.97) < 2^(2w-1) (at 128 bits: 2^171.3 < 2^255).
    """
    bits = _same_width("binet_cauchy_sign_at", P)
    T = ir.IntType(bits)
    T2 = ir.IntType(2 * bits)

    def codegen(context, builder, sig, args):
        def normal(c):
            return [
                builder.sext(v, T2)
                for v in load_row(context, builder, sig.args[0], args[0], args[c], sig.args[c], T, 3)
            ]

        na, nb, ns, nt = normal(1), normal(2), normal(3), normal(4)
        value = _det2(
            builder, _dot(builder, na, ns), _dot(builder, na, nt), _dot(builder, nb, ns), _dot(builder, nb, nt)
        )
        return sign(builder, value)

    return types.int8(P, a, b, s, t), codegen


@intrinsic
def compare_coordinate_at(typingctx, X, i, Y, j, c):
    """int8 sign of x_c / x_4 - y_c / y_4 for homogeneous points ``X[i]``, ``Y[j]`` and axis ``c`` (0, 1, 2).

    Cross-multiplied at 2w bits, exact for **any stored values**: |x_c y_4|, |y_c x_4| <= 2^(2w-2),
    so the difference lies in (-2^(2w-1), 2^(2w-1)). Both x_4 and y_4 must be non-zero.
    """
    bits = _same_width("compare_coordinate_at", X, Y)
    T = ir.IntType(bits)
    T2 = ir.IntType(2 * bits)

    def codegen(context, builder, sig, args):
        col = context.cast(builder, args[4], sig.args[4], types.intp)
        bx = row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        by = row_pointer(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        xc, x4 = load(builder, bx, col, T), load(builder, bx, 3, T)
        yc, y4 = load(builder, by, col, T), load(builder, by, 3, T)
        diff = builder.sub(
            builder.mul(builder.sext(xc, T2), builder.sext(y4, T2)),
            builder.mul(builder.sext(yc, T2), builder.sext(x4, T2)),
        )
        return builder.mul(builder.mul(sign(builder, diff), sign(builder, x4)), sign(builder, y4))

    return types.int8(X, i, Y, j, c), codegen


@intrinsic
def copy_normalized_into(typingctx, X, i, out, o):
    """Store ``X[i]`` into ``out[o]``, negated when x_4 < 0, so the stored point has x_4 > 0.

    Negation is exact: homogeneous points of the palette have |x_c| < 2^(w-1) (eq. 7), so
    -2^(w-1), the one value without a negation, never occurs.
    """
    bits = _same_width("copy_normalized_into", X, out)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        x = load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        negative = builder.icmp_signed("<", x[3], ir.Constant(T, 0))
        base = row_pointer(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        for c, v in enumerate(x):
            builder.store(builder.select(negative, builder.neg(v), v), element_pointer(builder, base, c, T), align=8)
        return context.get_dummy_value()

    return types.none(X, i, out, o), codegen


def _det3(builder, m):
    """Determinant of the 3x3 matrix ``m`` (rows of LLVM values), by the first row."""
    (a1, b1, c1), (a2, b2, c2), (a3, b3, c3) = m
    return _dot(
        builder,
        [a1, b1, c1],
        [_det2(builder, b2, c2, b3, c3), _det2(builder, c2, a2, c3, a3), _det2(builder, a2, b2, a3, b3)],
    )


@intrinsic
def collinear_at(typingctx, X, a, b, c):
    """Whether homogeneous points ``X[a]``, ``X[b]``, ``X[c]`` are collinear: every 3x3 minor of [a; b; c] is 0.

    The 3 x 4 matrix of three finite points has rank <= 2 exactly when they lie on one line.
    At 3w + 64 bits, exact for **any stored values**: a minor is 6 products of three entries,
    at most 6 * 2^(3w-3) < 2^(3w) in magnitude.
    """
    bits = _same_width("collinear_at", X)
    T = ir.IntType(bits)
    W = ir.IntType(3 * bits + 64)

    def codegen(context, builder, sig, args):
        rows = [
            [builder.sext(v, W) for v in load_row(context, builder, sig.args[0], args[0], args[k], sig.args[k], T, 4)]
            for k in (1, 2, 3)
        ]
        zero = ir.Constant(W, 0)
        result = ir.Constant(ir.IntType(1), 1)
        for cols in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
            minor = _det3(builder, [[r[q] for q in cols] for r in rows])
            result = builder.and_(result, builder.icmp_signed("==", minor, zero))
        return result

    return types.boolean(X, a, b, c), codegen
