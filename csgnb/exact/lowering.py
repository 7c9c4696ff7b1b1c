"""LLVM code generation shared by the intrinsics: typing of operands, loads and stores, integer helpers.

Everything here runs at numba typing or lowering time and emits llvmlite IR; nothing is
callable from Python. :mod:`csgnb.exact.intrinsics` builds the predicates from it.

Operand kinds, decided from numba types (so one kernel source compiles for each):

* *wide arrays* -- C-contiguous arrays whose record dtype is ``[("limbs", "<u8", (k,))]``
  (:mod:`csgnb.exact.wide`); planes and homogeneous points are ``(n, 4)``;
* *narrow planes* -- C-contiguous 1-D arrays of the records of :func:`csgnb.exact.planes.plane_dtype`
  (normals int32 / int64, offset int64 / int128, the width in the field title);
* *integer points* -- C-contiguous ``(n, 3) int64`` arrays.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError

from csgnb.exact.planes import plane_dtype
from csgnb.exact.wide import WIDTHS

I1 = ir.IntType(1)
I8 = ir.IntType(8)
I64 = ir.IntType(64)
F64 = ir.DoubleType()

_NARROW_RECORDS = {numba.from_dtype(plane_dtype(w)): w for w in WIDTHS}


class PlaneLayout(NamedTuple):
    """How a plane operand is stored: ``narrow`` or full rows, the width, the narrow field sizes."""

    narrow: bool
    bits: int
    normal_bits: int  # the stored size of a, b, c
    offset_bits: int  # the stored size of d


# ---------------------------------------------------------------------------
# typing


def wide_width(aty, name: str) -> int:
    """Width in bits of a wide array type; a numba typing error otherwise."""
    if not (
        isinstance(aty, types.Array)
        and isinstance(aty.dtype, types.Record)
        and aty.dtype.size in (16, 24, 32)
        and aty.layout == "C"
        and list(aty.dtype.fields) == ["limbs"]
    ):
        raise TypingError(f"{name}: expected a C-contiguous wide-integer array, got {aty}")
    return aty.dtype.size * 8


def plane_layout(aty, name: str) -> PlaneLayout:
    """The layout of a plane operand: ``(n, 4)`` wide rows or 1-D narrow plane records."""
    if isinstance(aty, types.Array) and aty.layout == "C" and aty.dtype in _NARROW_RECORDS and aty.ndim == 1:
        bits = _NARROW_RECORDS[aty.dtype]
        return PlaneLayout(True, bits, 32 if bits == 128 else 64, 64 if bits == 128 else 128)
    bits = wide_width(aty, name)
    return PlaneLayout(False, bits, bits, bits)


def int_array(aty, name: str) -> None:
    if not (isinstance(aty, types.Array) and aty.dtype == types.int64 and aty.layout == "C"):
        raise TypingError(f"{name}: expected a C-contiguous int64 array, got {aty}")


def same_width(name: str, *atys) -> int:
    """The common width of wide arrays and plane operands; a typing error if they differ."""
    widths = {plane_layout(a, name).bits for a in atys}
    if len(widths) != 1:
        raise TypingError(f"{name}: operands have different widths {sorted(widths)}")
    return widths.pop()


# ---------------------------------------------------------------------------
# addressing, loads and stores


def row_pointer(context, builder, aty, aval, row, row_ty):
    """Byte pointer (i8*) to the first element of row ``row`` (or element ``row`` of a 1-D array)."""
    ary = context.make_array(aty)(context, builder, aval)
    row = context.cast(builder, row, row_ty, types.intp)
    index = [row] + [ir.Constant(I64, 0)] * (aty.ndim - 1)
    ptr = cgutils.get_item_pointer(context, builder, aty, ary, index)
    return builder.bitcast(ptr, I8.as_pointer())


def element_pointer(builder, base, col, T):
    """Pointer to column ``col`` (int or i64 value) of a row of ``T`` elements.

    Addressed in bytes: LLVM pads ``i192`` to a 32-byte allocation, so a typed
    GEP would stride past the 24-byte elements of a 192-bit array.
    """
    size = T.width // 8
    offset = ir.Constant(I64, col * size) if isinstance(col, int) else builder.mul(col, ir.Constant(I64, size))
    return builder.bitcast(builder.gep(base, [offset]), T.as_pointer())


def load(builder, base, col, T):
    return builder.load(element_pointer(builder, base, col, T), align=8)


def _load_at(builder, base, byte_offset, T):
    ptr = builder.bitcast(builder.gep(base, [ir.Constant(I64, byte_offset)]), T.as_pointer())
    return builder.load(ptr, align=4)  # narrow records are packed (20 B at 128 bits)


def resize(builder, v, T):
    """``v`` sign-extended or truncated to ``T`` (truncation is exact modulo 2**T.width)."""
    if v.type.width == T.width:
        return v
    return builder.sext(v, T) if v.type.width < T.width else builder.trunc(v, T)


def load_row(context, builder, aty, aval, row, row_ty, T, ncols):
    """Load ``ncols`` values of a row as ``T`` integers (int64 rows are sign-extended)."""
    base = row_pointer(context, builder, aty, aval, row, row_ty)
    if isinstance(aty.dtype, types.Record):
        W = ir.IntType(aty.dtype.size * 8)
        return [resize(builder, load(builder, base, c, W), T) for c in range(ncols)]
    return [builder.sext(load(builder, base, c, I64), T) for c in range(ncols)]


def load_plane(context, builder, aty, aval, row, row_ty, T=None):
    """The four coefficients (a, b, c, d) of plane ``row``, as ``T`` (default: as stored, narrow fields narrow)."""
    layout = plane_layout(aty, "plane")
    base = row_pointer(context, builder, aty, aval, row, row_ty)
    if not layout.narrow:
        W = ir.IntType(layout.bits)
        values = [load(builder, base, c, W) for c in range(4)]
    else:
        N, D = ir.IntType(layout.normal_bits), ir.IntType(layout.offset_bits)
        nb = layout.normal_bits // 8
        values = [_load_at(builder, base, c * nb, N) for c in range(3)] + [_load_at(builder, base, 3 * nb, D)]
    return values if T is None else [resize(builder, v, T) for v in values]


def store_row(context, builder, aty, aval, row, row_ty, T, values):
    base = row_pointer(context, builder, aty, aval, row, row_ty)
    for c, v in enumerate(values):
        builder.store(v, element_pointer(builder, base, c, T), align=8)


def store_plane(context, builder, aty, aval, row, row_ty, values):
    """Store (a, b, c, d) into plane ``row`` of either layout (truncated to the narrow fields: callers bound them)."""
    layout = plane_layout(aty, "plane")
    base = row_pointer(context, builder, aty, aval, row, row_ty)
    if not layout.narrow:
        W = ir.IntType(layout.bits)
        for c, v in enumerate(values):
            builder.store(resize(builder, v, W), element_pointer(builder, base, c, W), align=8)
        return
    N, D = ir.IntType(layout.normal_bits), ir.IntType(layout.offset_bits)
    nb = layout.normal_bits // 8
    for c, (v, T, off) in enumerate(zip(values, (N, N, N, D), (0, nb, 2 * nb, 3 * nb), strict=True)):
        ptr = builder.bitcast(builder.gep(base, [ir.Constant(I64, off)]), T.as_pointer())
        builder.store(resize(builder, v, T), ptr, align=4)
        del c


# ---------------------------------------------------------------------------
# integer helpers


def sign(builder, v):
    """int8 sign (-1, 0, +1) of the signed integer ``v``."""
    zero = ir.Constant(v.type, 0)
    pos = builder.zext(builder.icmp_signed(">", v, zero), I8)
    neg = builder.zext(builder.icmp_signed("<", v, zero), I8)
    return builder.sub(pos, neg)


def sign_times_sign(builder, a, b):
    """int8 sign(a)·sign(b) without a multiplication: sign(a), negated when b < 0, zero when b = 0."""
    s = sign(builder, a)
    top = builder.trunc(builder.lshr(b, ir.Constant(b.type, b.type.width - 8)), I8)
    mask = builder.ashr(top, ir.Constant(I8, 7))  # 0 or -1
    s = builder.sub(builder.xor(s, mask), mask)
    return builder.select(builder.icmp_unsigned("==", b, ir.Constant(b.type, 0)), ir.Constant(I8, 0), s)


def absolute(builder, v):
    """|v| as an unsigned value of the same width (exact also for the minimum)."""
    neg = builder.icmp_signed("<", v, ir.Constant(v.type, 0))
    return builder.select(neg, builder.neg(v), v)


def bit_count_intrinsic(builder, name, T):
    """Declare ``llvm.ctlz``/``llvm.cttz`` for ``T`` with both arguments (llvmlite omits the i1 flag)."""
    return builder.module.declare_intrinsic(name, [T], ir.FunctionType(T, [T, I1]))


def mul_exact(builder, a, b, T):
    """a * b as ``T``: formed at the width the product needs (or ``T``, modulo 2**T.width, if smaller).

    A product of two sign-extended 64-bit values is one ``imul``; letting LLVM see the
    operands at their stored width keeps it from emitting the full wide multiplication.
    """
    P = ir.IntType(min(T.width, max(64, -(-(a.type.width + b.type.width) // 64) * 64)))
    if P.width > 64 and min(a.type.width, b.type.width) <= 64 < max(a.type.width, b.type.width):
        # A wide value times a machine word: sext(w) = zext(w) - 2**64 [w < 0], so one 64-bit
        # multiply per limb and a conditional subtraction -- LLVM would multiply the sign limbs too.
        wide, word = (a, b) if a.type.width > 64 else (b, a)
        wide, word = resize(builder, wide, P), resize(builder, word, I64)
        product = builder.mul(wide, builder.zext(word, P))
        negative = builder.icmp_signed("<", word, ir.Constant(I64, 0))
        shifted = builder.shl(wide, ir.Constant(P, 64))
        product = builder.sub(product, builder.select(negative, shifted, ir.Constant(P, 0)))
        return resize(builder, product, T)
    return resize(builder, builder.mul(resize(builder, a, P), resize(builder, b, P)), T)


def det2(builder, a, b, c, d, T=None):
    """a*d - b*c (at ``T``, default the operands' type)."""
    if T is None:
        return builder.sub(builder.mul(a, d), builder.mul(b, c))
    return builder.sub(mul_exact(builder, a, d, T), mul_exact(builder, b, c, T))


def dot(builder, xs, ys, T=None):
    """Σ x_k y_k (at ``T``, default the operands' type)."""
    if T is None:
        acc = builder.mul(xs[0], ys[0])
        for x, y in zip(xs[1:], ys[1:], strict=True):
            acc = builder.add(acc, builder.mul(x, y))
        return acc
    acc = mul_exact(builder, xs[0], ys[0], T)
    for x, y in zip(xs[1:], ys[1:], strict=True):
        acc = builder.add(acc, mul_exact(builder, x, y, T))
    return acc


def plane_dot(builder, x, s, T):
    """x·s of a point ``x`` (four ``T`` integers) and a plane ``s`` (as loaded: full rows or narrow records) at ``T``.

    A full-width row whose normal (a, b, c) fits in 64 bits -- the common case: on the 256-bit dome grid the normals
    reach 2^46 and the offsets 2^72 -- takes its three normal products as wide-times-word (:func:`mul_exact`: one
    64-bit multiply per limb) instead of wide-times-wide; which way is decided at run time from the row, and both
    give the same value modulo 2**T.width, so the same exact result. At 128 bits the plain code is kept: its
    bulk loops (the public predicates) vectorize, and the branch made them slower (classification 23 -> 40 cycles
    in ``bench_predicates.py``) for no gain in the Booleans.
    """
    if all(v.type.width <= 64 for v in s[:3]) or T.width <= 128:
        return dot(builder, x, s, T)
    return branch_values(
        builder, fits_in_word(builder, s[:3]),
        lambda: [dot(builder, x, [builder.trunc(v, I64) for v in s[:3]] + [s[3]], T)],
        lambda: [dot(builder, x, s, T)])[0]


def fits_in_word(builder, values):
    """i1: every one of the integer ``values`` equals the sign extension of its low 64 bits."""
    fits = None
    for v in values:
        ok = builder.icmp_signed("==", builder.sext(builder.trunc(v, I64), v.type), v)
        fits = ok if fits is None else builder.and_(fits, ok)
    return fits


def branch_values(builder, condition, if_true, if_false):
    """The values ``if_true()`` computes where ``condition`` holds (the likely side), ``if_false()``'s elsewhere:
    both emitted behind one branch, their lists (of equal types) joined by phis."""
    with builder.if_else(condition, likely=True) as (then, otherwise):
        with then:
            first = if_true()
            first_block = builder.basic_block
        with otherwise:
            second = if_false()
            second_block = builder.basic_block
    joined = []
    for a, b in zip(first, second, strict=True):
        phi = builder.phi(a.type)
        phi.add_incoming(a, first_block)
        phi.add_incoming(b, second_block)
        joined.append(phi)
    return joined


def to_double(builder, v):
    """``v`` rounded to the nearest double (ties to even), without compiler-rt calls.

    LLVM lowers a 128-bit ``sitofp`` to ``__floattidf``, which numba cannot link,
    and folds widening tricks back to it; so: normalise |v| with ``ctlz``, keep
    the top 64 bits with a sticky bit for everything below (enough for correct
    rounding to 53 bits), convert those, and scale by an exact power of two.
    """
    T = v.type
    W = T.width
    magnitude = absolute(builder, v)
    ctlz = bit_count_intrinsic(builder, "llvm.ctlz", T)
    lz = builder.call(ctlz, [magnitude, ir.Constant(I1, 0)])
    norm = builder.shl(magnitude, lz)
    top = builder.trunc(builder.lshr(norm, ir.Constant(T, W - 64)), I64)
    sticky = builder.icmp_unsigned("!=", builder.trunc(norm, ir.IntType(W - 64)), ir.Constant(ir.IntType(W - 64), 0))
    top = builder.or_(top, builder.zext(sticky, I64))
    f = builder.uitofp(top, F64)
    exponent = builder.sub(ir.Constant(I64, W - 64), builder.trunc(lz, I64))  # in [-63, W - 64]
    f = builder.fmul(f, power_of_two(builder, exponent))
    f = builder.select(builder.icmp_signed("<", v, ir.Constant(T, 0)), builder.fneg(f), f)
    return builder.select(builder.icmp_signed("==", v, ir.Constant(T, 0)), ir.Constant(F64, 0.0), f)


def filter_double(builder, v):
    """A double within 4.001 units of 2**-53 (relative) of the signed integer ``v``: for filters, not for output.

    |v| is split into its k <= 4 limbs of 64 bits, each converted (one rounding) and scaled by its exact power of
    two, and the non-negative terms are summed from the top (k - 1 roundings): no term meets more than k roundings,
    so the relative error is at most (1 + 2**-53)**4 - 1 < 4.001 units at 256 bits -- and no ``ctlz``, no
    variable-width shift of the wide value (which LLVM spills through the stack), no sticky bit, unlike the
    correctly rounded :func:`to_double`, which costs several times as much at 256 bits. Zero gives 0.0.
    """
    T = v.type
    magnitude = absolute(builder, v)
    f = None
    for k in reversed(range(T.width // 64)):
        limb = builder.trunc(builder.lshr(magnitude, ir.Constant(T, 64 * k)) if k else magnitude, I64)
        term = builder.uitofp(limb, F64)
        if k:
            term = builder.fmul(term, ir.Constant(F64, 2.0 ** (64 * k)))
        f = term if f is None else builder.fadd(f, term)
    return builder.select(builder.icmp_signed("<", v, ir.Constant(T, 0)), builder.fneg(f), f)


#: Relative bound for deciding sign(a/b - c/d) = sign(a d - c b)·sign(b)·sign(d) from doubles
#: (:func:`quotient_difference_sign`): each of a, b, c, d is within 4.001 units of 2**-53 (:func:`filter_double`), each
#: product within 9.01 units of its exact value, so the computed p - q is within 9.02 units of |p| + |q| of a d - c b;
#: 2**-48 is 32 units (the bound's own two roundings and the difference's cost under one): sound with room. A closer
#: call goes to the exact products.
QUOTIENT_FILTER_BOUND = 2.0**-48


def fabs(builder, x):
    """|x| of a double (``llvm.fabs``)."""
    f = builder.module.declare_intrinsic("llvm.fabs", [F64], ir.FunctionType(F64, [F64]))
    return builder.call(f, [x])


def exact_quotient_difference_sign(builder, a, b, c, d, T2):
    """int8 sign(a/b - c/d) = sign(a d - c b)·sign(b)·sign(d) of four signed integers of one width, the cross products
    formed exactly at ``T2`` (twice that width): the exact answer every quotient comparison falls back to."""
    return builder.mul(builder.mul(sign(builder, det2(builder, a, c, b, d, T2)), sign(builder, b)), sign(builder, d))


def quotient_difference_sign(builder, a, b, c, d, exact):
    """int8 sign(a/b - c/d) of four signed integers of one width, decided by doubles where that is certain.

    The cross products p = a d and q = c b are formed from :func:`filter_double` approximations; where |p - q|
    exceeds :data:`QUOTIENT_FILTER_BOUND` times |p| + |q|, sign(p - q)·sign(b)·sign(d) is the exact sign. Otherwise
    -- a close call, a zero denominator -- ``exact(builder)`` emits the exact sign. Doubles never overflow here
    (|p|, |q| < 2**512) and non-zero products of integers are at least 1, far above the subnormals, so the relative
    bounds hold. Products, not quotients: two multiplications instead of two divisions (~4 vs ~13 cycles of latency).
    """
    fa, fb, fc, fd = (filter_double(builder, v) for v in (a, b, c, d))
    return quotient_difference_sign_of_doubles(builder, fa, fb, fc, fd, exact)


def quotient_difference_sign_of_doubles(builder, fa, fb, fc, fd, exact):
    """:func:`quotient_difference_sign` from the :func:`filter_double` values of a, b, c, d (computed before, e.g.
    kept beside the integers): the same decisions, the same close calls sent to ``exact(builder)``."""
    p = builder.fmul(fa, fd)
    q = builder.fmul(fc, fb)
    diff = builder.fsub(p, q)
    bound = builder.fmul(builder.fadd(fabs(builder, p), fabs(builder, q)), ir.Constant(F64, QUOTIENT_FILTER_BOUND))
    zero = ir.Constant(F64, 0.0)
    denominators = builder.fmul(fb, fd)  # |b d| >= 1 unless one is zero: no underflow
    decided = builder.and_(builder.fcmp_ordered(">", fabs(builder, diff), bound),
                           builder.fcmp_ordered("!=", denominators, zero))
    result = cgutils.alloca_once(builder, I8)
    with builder.if_else(decided, likely=True) as (then, otherwise):
        with then:
            # sign(p - q) flipped when b d < 0: the same as the sign of (p - q)·(b d), both non-zero here.
            positive = builder.xor(builder.fcmp_ordered(">", diff, zero), builder.fcmp_ordered("<", denominators, zero))
            builder.store(builder.select(positive, ir.Constant(I8, 1), ir.Constant(I8, -1)), result)
        with otherwise:
            builder.store(exact(builder), result)
    return builder.load(result)


def power_of_two(builder, exponent):
    """2.0**exponent for an i64 exponent in the normal range, built from its IEEE bits."""
    biased = builder.add(exponent, ir.Constant(I64, 1023))
    return builder.bitcast(builder.shl(biased, ir.Constant(I64, 52)), F64)


def split_double(builder, v):
    """|v| truncated to its leading 106 bits as two doubles (hi, lo): hi = the top 53 bits, lo = the next 53.

    Both are exact doubles (53-bit integers times powers of two) and
    ``0 <= |v| - (hi + lo) < 2**-105 * |v|``; zero gives (0, 0). Only the leading limb and
    the two below it are shifted (a funnel shift by the leading zeros), never the whole value.
    """
    T = v.type
    k = T.width // 64
    magnitude = absolute(builder, v)
    limbs = [builder.trunc(builder.lshr(magnitude, ir.Constant(T, 64 * j)), I64) if j else builder.trunc(magnitude, I64)
             for j in range(k)]
    zero64 = ir.Constant(I64, 0)
    # (a, b, c): the leading non-zero limb and the two below it; j: its index.
    a, b_, c, j = limbs[0], zero64, zero64, ir.Constant(I64, 0)
    for i in range(1, k):
        nz = builder.icmp_unsigned("!=", limbs[i], zero64)
        a = builder.select(nz, limbs[i], a)
        b_ = builder.select(nz, limbs[i - 1], b_)
        c = builder.select(nz, limbs[i - 2] if i >= 2 else zero64, c)
        j = builder.select(nz, ir.Constant(I64, i), j)
    lz = builder.call(bit_count_intrinsic(builder, "llvm.ctlz", I64), [a, ir.Constant(I1, 0)])
    fshl = builder.module.declare_intrinsic("llvm.fshl", [I64], ir.FunctionType(I64, [I64, I64, I64]))
    top = builder.call(fshl, [a, b_, lz])  # the leading 64 bits, leading bit at 63
    nxt = builder.call(fshl, [b_, c, lz])  # the next 64
    hi_bits = builder.lshr(top, ir.Constant(I64, 11))  # 53 bits
    lo_bits = builder.or_(builder.shl(builder.and_(top, ir.Constant(I64, 0x7FF)), ir.Constant(I64, 42)),
                          builder.lshr(nxt, ir.Constant(I64, 22)))
    # The leading bit has weight 2**(64 j + 63 - lz); hi_bits' unit is 2**(64 j + 11 - lz).
    e = builder.sub(builder.add(builder.mul(j, ir.Constant(I64, 64)), ir.Constant(I64, 11)), lz)
    hi = builder.fmul(builder.uitofp(hi_bits, F64), power_of_two(builder, e))
    lo = builder.fmul(builder.uitofp(lo_bits, F64), power_of_two(builder, builder.sub(e, ir.Constant(I64, 53))))
    zero = builder.icmp_unsigned("==", a, zero64)
    hi = builder.select(zero, ir.Constant(F64, 0.0), hi)
    lo = builder.select(zero, ir.Constant(F64, 0.0), lo)
    return hi, lo


def divexact(builder, v, g):
    """``v / g`` for an int64 ``g != 0`` that divides ``v`` exactly, without a division.

    Exact division is an arithmetic shift by the twos in ``g`` followed by a
    multiplication with the inverse of its odd part modulo 2**W (Newton's
    iteration doubles the correct low bits each step, from 3).
    """
    return divexact_by(builder, v, *odd_inverse(builder, g, v.type))


def odd_inverse(builder, g, T):
    """(negative, twos, inverse) of an int64 ``g != 0``: its sign, its trailing zeros, 1/odd(|g|) mod 2**T.width.

    Newton's iteration runs at 64 bits as far as it can (cheap multiplications) and only the
    last steps at ``T``.
    """
    negative = builder.icmp_signed("<", g, ir.Constant(I64, 0))
    g = builder.select(negative, builder.neg(g), g)
    twos = builder.call(bit_count_intrinsic(builder, "llvm.cttz", I64), [g, ir.Constant(I1, 1)])
    odd = builder.lshr(g, twos)
    inverse = odd  # correct to 3 bits: odd * odd = 1 mod 8
    two = ir.Constant(I64, 2)
    for _ in range(5):  # 3 -> 6 -> 12 -> 24 -> 48 -> 96 >= 64 bits
        inverse = builder.mul(inverse, builder.sub(two, builder.mul(odd, inverse)))
    if T.width > 64:
        odd_t, inv_t, two_t = builder.zext(odd, T), builder.zext(inverse, T), ir.Constant(T, 2)
        bits = 64
        while bits < T.width:
            inv_t = builder.mul(inv_t, builder.sub(two_t, builder.mul(odd_t, inv_t)))
            bits *= 2
        inverse = inv_t
    return negative, twos, inverse


def divexact_by(builder, v, negative, twos, inverse):
    """``v / g`` from :func:`odd_inverse`'s (negative, twos, inverse) of ``g`` (resized to ``v``'s width)."""
    T = v.type
    shifted = builder.ashr(v, resize(builder, twos, T))
    q = builder.mul(shifted, resize(builder, inverse, T))
    return builder.select(negative, builder.neg(q), q)


# ---------------------------------------------------------------------------
# vector scans of wide rows (the fast budget checks)


def _type_suffix(t) -> str:
    if isinstance(t, ir.VectorType):
        return f"v{t.count}{_type_suffix(t.element)}"
    if isinstance(t, ir.DoubleType):
        return "f64"
    return f"i{t.width}"


def _declare(builder, name, ret, args, overload):
    """Declare the overloaded LLVM intrinsic ``name`` (llvmlite cannot mangle vector types itself)."""
    full = ".".join([name] + [_type_suffix(t) for t in overload])
    return cgutils.get_or_insert_function(builder.module, ir.FunctionType(ret, args), full)


class Scan:
    """The running bounds of one operand inside a loop (accumulators promoted to registers).

    The accumulator array holds ``4k + 2`` uint64 (k = width / 64): per (column, limb) the
    maximum of the one's-complement magnitude limbs (``v XOR sign``: |v| for v >= 0, |v| - 1
    below), then two flags that become 0 once a row has a zero normal (columns 0-2 all
    zero) or a zero x4 (column 3). A wide row is one vector of ``4k`` limbs: the magnitudes
    cost a shift, a shuffle, an xor and an unsigned max; the zero tests one vector compare
    into a mask register and a few scalar bit operations (no horizontal reductions).
    Narrow plane records fill the same slots from their fields (normals in limb 0 of
    columns 0-2, the offset in limbs 0-1 of column 3). ``(n, 3) int64`` points keep their
    [max, min] instead (a 2-element int64 accumulator).
    """

    def __init__(self, builder, kind: str, acc_ptr, k: int = 0, layout: PlaneLayout | None = None, last=None):
        self.builder, self.kind, self.acc_ptr, self.k, self.layout = builder, kind, acc_ptr, k, layout
        self.last = last  # narrow: address of the last record (no vector over-read there)
        if kind == "wide":
            L = 4 * k
            # A row in vectors of at most 8 lanes (one zmm): LLVM keeps a <12 x i64> accumulator
            # in scalar registers, so 192-bit rows are an 8-lane and a 4-lane vector.
            self.chunks = [(lo, min(lo + 8, L)) for lo in range(0, L, 8)]
            self.vecs = []
            for lo, hi in self.chunks:
                V = ir.VectorType(I64, hi - lo)
                ptr = builder.bitcast(builder.gep(acc_ptr, [ir.Constant(I64, lo)]), V.as_pointer())
                self.vecs.append(cgutils.alloca_once_value(builder, builder.load(ptr, align=8)))
            self.slots = {s: self._slot(s) for s in (L, L + 1)}
        elif kind == "narrow":
            self.slots = {s: self._slot(s) for s in (0, k, 2 * k, 3 * k, 3 * k + 1, 4 * k)}
            # Vector path: the record plus what follows it, 8 lanes of the normal field's size
            # (lanes 0-2 normals, 3-4 the offset), its maxima folded into the slots at the end.
            self.NV = ir.VectorType(ir.IntType(layout.normal_bits), 8)
            self.nvec = cgutils.alloca_once_value(builder, ir.Constant(self.NV, [0] * 8))
        else:  # int3: [max, min]
            self.slots = {s: self._slot(s) for s in (0, 1)}

    def _slot(self, s):
        return cgutils.alloca_once_value(self.builder, self.builder.load(self._ptr(s), align=8))

    def _ptr(self, s):
        return self.builder.gep(self.acc_ptr, [ir.Constant(I64, s)])

    def _fold(self, s, op, value):
        b = self.builder
        if op == "and":
            new = b.and_(b.load(self.slots[s]), value)
        else:
            new = b.call(_declare(b, f"llvm.{op}", I64, [I64, I64], [I64]), [b.load(self.slots[s]), value])
        b.store(new, self.slots[s])

    def row(self, base):
        """Fold the row at byte pointer ``base``."""
        b = self.builder
        if self.kind == "wide":
            k, L = self.k, 4 * self.k
            base64 = b.bitcast(base, I64.as_pointer())
            parts = []
            for lo, hi in self.chunks:
                V = ir.VectorType(I64, hi - lo)
                parts.append(b.load(b.bitcast(b.gep(base64, [ir.Constant(I64, lo)]), V.as_pointer()), align=8))
            zero_lanes = ir.Constant(ir.IntType(L), 0)
            for j, ((lo, hi), part) in enumerate(zip(self.chunks, parts, strict=True)):
                n = hi - lo
                V = ir.VectorType(I64, n)
                # The top limb of each lane's column, from this chunk or the next one.
                nxt = parts[j + 1] if j + 1 < len(parts) else part
                if nxt.type.count != n:
                    nxt = b.shuffle_vector(nxt, nxt, ir.Constant(ir.VectorType(ir.IntType(32), n),
                                                                 [i % nxt.type.count for i in range(n)]))
                tops = [((lane // k) * k + k - 1) - lo for lane in range(lo, hi)]
                tops = ir.Constant(ir.VectorType(ir.IntType(32), n), tops)
                sgn = b.ashr(b.shuffle_vector(part, nxt, tops), ir.Constant(V, [63] * n))
                umax = _declare(b, "llvm.umax", V, [V, V], [V])
                b.store(b.call(umax, [b.load(self.vecs[j]), b.xor(part, sgn)]), self.vecs[j])
                zeros = b.zext(b.bitcast(b.icmp_unsigned("==", part, ir.Constant(V, [0] * n)), ir.IntType(n)),
                               ir.IntType(L))
                zero_lanes = b.or_(zero_lanes, b.shl(zeros, ir.Constant(ir.IntType(L), lo)))
            M = ir.IntType(L)
            for slot, lanes in ((L, (1 << (3 * k)) - 1), (L + 1, ((1 << k) - 1) << (3 * k))):
                mask = ir.Constant(M, lanes)
                all_zero = b.icmp_unsigned("==", b.and_(zero_lanes, mask), mask)
                self._fold(slot, "and", b.zext(b.not_(all_zero), I64))
        elif self.kind == "narrow":
            last = b.icmp_unsigned(">=", b.ptrtoint(base, I64), self.last)
            with b.if_else(last, likely=False) as (scalar, vector):
                with scalar:
                    self._narrow_scalar(base)
                with vector:
                    self._narrow_vector(base)
        else:  # the row's max and min first: one fold per row on each loop-carried accumulator
            v = [load(b, base, c, I64) for c in range(3)]
            smax = _declare(b, "llvm.smax", I64, [I64, I64], [I64])
            smin = _declare(b, "llvm.smin", I64, [I64, I64], [I64])
            self._fold(0, "smax", b.call(smax, [b.call(smax, [v[0], v[1]]), v[2]]))
            self._fold(1, "smin", b.call(smin, [b.call(smin, [v[0], v[1]]), v[2]]))

    def _narrow_vector(self, base):
        """One narrow record as a vector (reads up to 24 bytes of the next record, never past the array)."""
        b, NV = self.builder, self.NV
        W = NV.element.width
        v = b.load(b.bitcast(base, NV.as_pointer()), align=4)
        tops = ir.Constant(ir.VectorType(ir.IntType(32), 8), [0, 1, 2, 4, 4, 5, 6, 7])
        sgn = b.ashr(b.shuffle_vector(v, v, tops), ir.Constant(NV, [W - 1] * 8))
        umax = _declare(b, "llvm.umax", NV, [NV, NV], [NV])
        b.store(b.call(umax, [b.load(self.nvec), b.xor(v, sgn)]), self.nvec)
        zeros = b.bitcast(b.icmp_unsigned("==", v, ir.Constant(NV, [0] * 8)), ir.IntType(8))
        all_zero = b.icmp_unsigned("==", b.and_(zeros, ir.Constant(ir.IntType(8), 7)), ir.Constant(ir.IntType(8), 7))
        self._fold(4 * self.k, "and", b.zext(b.not_(all_zero), I64))

    def _narrow_scalar(self, base):
        b = self.builder
        k, layout = self.k, self.layout
        N, D = ir.IntType(layout.normal_bits), ir.IntType(layout.offset_bits)
        nb = layout.normal_bits // 8
        normal_or = ir.Constant(I64, 0)
        for c in range(3):
            v = b.sext(_load_at(b, base, c * nb, N), I64)
            self._fold(c * k, "umax", b.xor(v, b.ashr(v, ir.Constant(I64, 63))))
            normal_or = b.or_(normal_or, v)
        self._fold(4 * k, "and", b.zext(b.icmp_unsigned("!=", normal_or, ir.Constant(I64, 0)), I64))
        d = _load_at(b, base, 3 * nb, D)
        m = b.xor(d, b.ashr(d, ir.Constant(D, D.width - 1)))
        self._fold(3 * k, "umax", b.trunc(m, I64))
        if D.width > 64:
            self._fold(3 * k + 1, "umax", b.trunc(b.lshr(m, ir.Constant(D, 64)), I64))

    def end(self):
        b = self.builder
        if self.kind == "narrow":
            # Lane maxima are per-field (offsets: per half) upper bounds; fold them into the limb slots.
            v, k = b.load(self.nvec), self.k
            lane = [b.zext(b.extract_element(v, ir.Constant(ir.IntType(32), i)), I64) for i in range(5)]
            for c in range(3):
                self._fold(c * k, "umax", lane[c])
            if self.NV.element.width == 32:  # offset halves: max(hi) * 2**32 + max(lo) bounds max(offset)
                self._fold(3 * k, "umax", b.or_(b.shl(lane[4], ir.Constant(I64, 32)), lane[3]))
            else:
                self._fold(3 * k, "umax", lane[3])
                self._fold(3 * k + 1, "umax", lane[4])
        if self.kind == "wide":
            for (lo, hi), vec in zip(self.chunks, self.vecs, strict=True):
                V = ir.VectorType(I64, hi - lo)
                b.store(b.load(vec), b.bitcast(b.gep(self.acc_ptr, [ir.Constant(I64, lo)]), V.as_pointer()), align=8)
        for s, slot in self.slots.items():
            b.store(b.load(slot), self._ptr(s), align=8)


def row_bytes(aty) -> int:
    """Bytes per row of a wide (n, 4) array, narrow planes or (n, 3) int64 points."""
    if isinstance(aty.dtype, types.Record):
        return aty.dtype.size * (4 if aty.ndim == 2 else 1)
    return 8 * 3


def begin_scan(context, builder, aty, aval, acc_ty, acc_val) -> Scan:
    """A :class:`Scan` for operand type ``aty`` folding into the accumulator array ``acc_val``."""
    acc_ptr = builder.bitcast(context.make_array(acc_ty)(context, builder, acc_val).data, I64.as_pointer())
    if isinstance(aty.dtype, types.Record):
        layout = plane_layout(aty, "scan")
        if not layout.narrow:
            return Scan(builder, "wide", acc_ptr, layout.bits // 64, layout)
        ary = context.make_array(aty)(context, builder, aval)
        n = cgutils.unpack_tuple(builder, ary.shape, 1)[0]
        last = builder.add(builder.ptrtoint(ary.data, I64),
                           builder.mul(builder.sub(n, ir.Constant(I64, 1)), ir.Constant(I64, row_bytes(aty))))
        return Scan(builder, "narrow", acc_ptr, layout.bits // 64, layout, last)
    return Scan(builder, "int3", acc_ptr)


def data_pointer(context, builder, aty, aval):
    return builder.bitcast(context.make_array(aty)(context, builder, aval).data, I8.as_pointer())


def row_base(builder, data, row, nbytes):
    return builder.gep(data, [builder.mul(row, ir.Constant(I64, nbytes))])


def scan_rows(context, builder, aty, aval, acc_ty, acc_val, start, stop):
    """Fold rows ``[start, stop)`` of ``aval`` into its accumulator (see :class:`Scan`)."""
    scan = begin_scan(context, builder, aty, aval, acc_ty, acc_val)
    data = data_pointer(context, builder, aty, aval)
    nbytes = row_bytes(aty)
    with cgutils.for_range_slice(builder, start, stop, ir.Constant(I64, 1), intp=I64) as (r, _):
        scan.row(row_base(builder, data, r, nbytes))
    scan.end()


#: The fast quotient of :func:`certified_quotients` is within 2**-100 |x/w| of the true one; its
#: rounding is certified only when the tail stays this much (relative) farther from a midpoint.
CERTIFY = 2.0**-96


def _v4(builder, T, values):
    return ir.Constant(ir.VectorType(T, 4), values if isinstance(values, list) else [values] * 4)


def split_double_v4(builder, limbs, k):
    """:func:`split_double` of four values at once: ``limbs[j]`` is the <4 x i64> of limb j of each value.

    Returns (hi, lo, negative): <4 x double> truncated double-doubles of the magnitudes and
    the <4 x i1> signs. The same arithmetic as the scalar version, lane by lane (vplzcntq,
    vpshldvq, vcvtuqq2pd on AVX-512).
    """
    V = ir.VectorType(I64, 4)
    zero = _v4(builder, I64, 0)
    sign = builder.ashr(limbs[k - 1], _v4(builder, I64, 63))
    negative = builder.icmp_signed("<", limbs[k - 1], zero)
    carry = builder.and_(sign, _v4(builder, I64, 1))
    mags = []
    for j in range(k):  # |v| = (v XOR sign) + (1 if negative), carried limb by limb
        m = builder.add(builder.xor(limbs[j], sign), carry)
        mags.append(m)
        carry = builder.and_(carry, builder.zext(builder.icmp_unsigned("==", m, zero), V))
    a, b_, c, idx = mags[0], zero, zero, zero
    for i in range(1, k):
        nz = builder.icmp_unsigned("!=", mags[i], zero)
        a = builder.select(nz, mags[i], a)
        b_ = builder.select(nz, mags[i - 1], b_)
        c = builder.select(nz, mags[i - 2] if i >= 2 else zero, c)
        idx = builder.select(nz, _v4(builder, I64, i), idx)
    ctlz = _declare(builder, "llvm.ctlz", V, [V, I1], [V])
    lz = builder.call(ctlz, [a, ir.Constant(I1, 0)])
    fshl = _declare(builder, "llvm.fshl", V, [V, V, V], [V])
    top = builder.call(fshl, [a, b_, lz])
    nxt = builder.call(fshl, [b_, c, lz])
    hi_bits = builder.lshr(top, _v4(builder, I64, 11))
    lo_bits = builder.or_(builder.shl(builder.and_(top, _v4(builder, I64, 0x7FF)), _v4(builder, I64, 42)),
                          builder.lshr(nxt, _v4(builder, I64, 22)))
    e = builder.sub(builder.add(builder.shl(idx, _v4(builder, I64, 6)), _v4(builder, I64, 11)), lz)
    D = ir.VectorType(F64, 4)

    def pow2(x):
        return builder.bitcast(builder.shl(builder.add(x, _v4(builder, I64, 1023)), _v4(builder, I64, 52)), D)

    hi = builder.fmul(builder.uitofp(hi_bits, D), pow2(e))
    lo = builder.fmul(builder.uitofp(lo_bits, D), pow2(builder.sub(e, _v4(builder, I64, 53))))
    is_zero = builder.icmp_unsigned("==", a, zero)
    dzero = ir.Constant(D, [0.0] * 4)
    return builder.select(is_zero, dzero, hi), builder.select(is_zero, dzero, lo), negative


def certified_quotients(builder, limbs, k, certify):
    """x_c / x4 (c = 0, 1, 2) of one homogeneous point, with a mask of the lanes certified correctly rounded.

    ``limbs[j]`` holds limb j of (x1, x2, x3, x4), x4 != 0. Returns (<4 x double> quotients in
    lanes 0-2, i8 bit mask of the certified lanes 0-2). See
    :func:`csgnb.exact.predicates._positions` for the error bound behind ``certify``.
    """
    D = ir.VectorType(F64, 4)
    hi, lo, negative = split_double_v4(builder, limbs, k)
    three = ir.Constant(ir.VectorType(ir.IntType(32), 4), [3] * 4)
    bh = builder.shuffle_vector(hi, hi, three)
    bl = builder.shuffle_vector(lo, lo, three)
    r = builder.fdiv(ir.Constant(D, [1.0] * 4), bh)
    fma = _declare(builder, "llvm.fma", D, [D, D, D], [D])
    q1 = builder.fmul(hi, r)
    ph = builder.fmul(q1, bh)
    pl = builder.call(fma, [q1, bh, builder.fneg(ph)])
    rho = builder.fadd(builder.fsub(builder.fsub(hi, ph), pl), builder.call(fma, [builder.fneg(q1), bl, lo]))
    corr = builder.fmul(rho, r)
    s = builder.fadd(q1, corr)
    tail = builder.fsub(corr, builder.fsub(s, q1))
    V = ir.VectorType(I64, 4)
    bits = builder.bitcast(s, V)
    up = builder.bitcast(builder.sub(builder.and_(bits, _v4(builder, I64, 0x7FF << 52)), _v4(builder, I64, 53 << 52)),
                         D)
    pow2 = builder.icmp_unsigned("==", builder.and_(bits, _v4(builder, I64, (1 << 52) - 1)), _v4(builder, I64, 0))
    down = builder.select(pow2, builder.fmul(up, ir.Constant(D, [0.5] * 4)), up)
    err = builder.fmul(s, ir.Constant(D, [certify] * 4))
    ok = builder.and_(builder.fcmp_ordered("<", builder.fadd(tail, err), up),
                      builder.fcmp_ordered(">", builder.fsub(tail, err), builder.fneg(down)))
    zero_num = builder.fcmp_ordered("==", hi, ir.Constant(D, [0.0] * 4))
    ok = builder.or_(ok, zero_num)
    # The sign: x_c / x4 is negative when exactly one of them is.
    flip = builder.xor(negative, builder.shuffle_vector(negative, negative, three))
    signed = builder.select(flip, builder.fneg(s), s)
    result = builder.select(zero_num, ir.Constant(D, [0.0] * 4), signed)
    mask = builder.and_(builder.bitcast(ok, ir.IntType(4)), ir.Constant(ir.IntType(4), 7))
    return result, builder.zext(mask, I8)
