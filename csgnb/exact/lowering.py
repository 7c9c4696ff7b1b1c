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

from .planes import plane_dtype
from .wide import WIDTHS

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


def power_of_two(builder, exponent):
    """2.0**exponent for an i64 exponent in the normal range, built from its IEEE bits."""
    biased = builder.add(exponent, ir.Constant(I64, 1023))
    return builder.bitcast(builder.shl(biased, ir.Constant(I64, 52)), F64)


def split_double(builder, v):
    """|v| truncated to its leading 106 bits as two doubles (hi, lo): hi = the top 53 bits, lo = the next 53.

    Both are exact doubles (53-bit integers times powers of two) and
    ``0 <= |v| - (hi + lo) < 2**-105 * |v|``; zero gives (0, 0).
    """
    T = v.type
    W = T.width
    magnitude = absolute(builder, v)
    lz = builder.call(bit_count_intrinsic(builder, "llvm.ctlz", T), [magnitude, ir.Constant(I1, 0)])
    norm = builder.shl(magnitude, lz)  # leading bit at W - 1 (or all zero)
    top = builder.trunc(builder.lshr(norm, ir.Constant(T, W - 64)), I64)
    hi_bits = builder.lshr(top, ir.Constant(I64, 11))  # 53 bits
    nxt = builder.trunc(builder.lshr(norm, ir.Constant(T, W - 128)), I64)  # the next 64 bits
    lo_bits = builder.or_(builder.shl(builder.and_(top, ir.Constant(I64, 0x7FF)), ir.Constant(I64, 42)),
                          builder.lshr(nxt, ir.Constant(I64, 22)))
    # |v| ~ hi_bits * 2**(W - 53 - lz) + lo_bits * 2**(W - 106 - lz)
    e = builder.sub(ir.Constant(I64, W - 53), builder.trunc(lz, I64))
    hi = builder.fmul(builder.uitofp(hi_bits, F64), power_of_two(builder, e))
    lo = builder.fmul(builder.uitofp(lo_bits, F64), power_of_two(builder, builder.sub(e, ir.Constant(I64, 53))))
    zero = builder.icmp_unsigned("==", magnitude, ir.Constant(T, 0))
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
    return f"i{t.width}"


def _declare(builder, name, ret, args, overload):
    """Declare the overloaded LLVM intrinsic ``name`` (llvmlite cannot mangle vector types itself)."""
    full = ".".join([name] + [_type_suffix(t) for t in overload])
    return cgutils.get_or_insert_function(builder.module, ir.FunctionType(ret, args), full)


def scan_rows(builder, data, start, stop, k, acc_ptr):
    """Fold rows ``[start, stop)`` of an ``(n, 4)`` array of ``k``-limb values into ``acc_ptr``.

    ``acc_ptr`` points at ``4k + 2`` uint64: per (column, limb) the maximum of the
    one's-complement magnitude limbs (``v XOR sign``: |v| for v >= 0, |v| - 1 below), then
    the minimum over rows of the OR of all limbs of columns 0-2 (0 iff some row has a zero
    normal) and of column 3 (0 iff some row has x4 = 0). A whole row is one vector of
    ``4k`` limbs, so the loop body is a handful of SIMD instructions.
    """
    L = 4 * k
    V = ir.VectorType(I64, L)
    acc_vec_ptr = builder.bitcast(acc_ptr, V.as_pointer())
    acc = cgutils.alloca_once_value(builder, builder.load(acc_vec_ptr, align=8))
    acc_n = cgutils.alloca_once_value(builder, builder.load(builder.gep(acc_ptr, [ir.Constant(I64, L)]), align=8))
    acc_w = cgutils.alloca_once_value(builder, builder.load(builder.gep(acc_ptr, [ir.Constant(I64, L + 1)]), align=8))
    tops = ir.Constant(ir.VectorType(ir.IntType(32), L), [(i // k) * k + k - 1 for i in range(L)])
    normal = ir.Constant(ir.VectorType(ir.IntType(32), 3 * k), list(range(3 * k)))
    last = ir.Constant(ir.VectorType(ir.IntType(32), k), list(range(3 * k, 4 * k)))
    V3, Vk = ir.VectorType(I64, 3 * k), ir.VectorType(I64, k)
    umax = _declare(builder, "llvm.umax", V, [V, V], [V])
    reduce3 = _declare(builder, "llvm.vector.reduce.or", I64, [V3], [V3])
    reducek = _declare(builder, "llvm.vector.reduce.or", I64, [Vk], [Vk])
    umin = _declare(builder, "llvm.umin", I64, [I64, I64], [I64])
    shift = ir.Constant(V, [63] * L)
    with cgutils.for_range_slice(builder, start, stop, ir.Constant(I64, 1), intp=I64) as (r, _):
        ptr = builder.bitcast(builder.gep(data, [builder.mul(r, ir.Constant(I64, L))]), V.as_pointer())
        row = builder.load(ptr, align=8)
        sgn = builder.ashr(builder.shuffle_vector(row, row, tops), shift)
        builder.store(builder.call(umax, [builder.load(acc), builder.xor(row, sgn)]), acc)
        n_or = builder.call(reduce3, [builder.shuffle_vector(row, row, normal)])
        w_or = builder.call(reducek, [builder.shuffle_vector(row, row, last)])
        builder.store(builder.call(umin, [builder.load(acc_n), n_or]), acc_n)
        builder.store(builder.call(umin, [builder.load(acc_w), w_or]), acc_w)
    builder.store(builder.load(acc), acc_vec_ptr, align=8)
    builder.store(builder.load(acc_n), builder.gep(acc_ptr, [ir.Constant(I64, L)]), align=8)
    builder.store(builder.load(acc_w), builder.gep(acc_ptr, [ir.Constant(I64, L + 1)]), align=8)


def scan_narrow(builder, data, start, stop, layout: PlaneLayout, k, acc_ptr):
    """:func:`scan_rows` for narrow plane records: the same ``4k + 2`` accumulators, filled from the fields.

    Normals land in limb 0 of columns 0-2 and the offset in limbs 0-1 of column 3 (as
    one's-complement magnitudes), so one bound formula serves both layouts.
    """
    N, D = ir.IntType(layout.normal_bits), ir.IntType(layout.offset_bits)
    nb, size = layout.normal_bits // 8, 3 * layout.normal_bits // 8 + layout.offset_bits // 8
    slots = {s: cgutils.alloca_once_value(builder, builder.load(builder.gep(acc_ptr, [ir.Constant(I64, s)]),
                                                                 align=8))
             for s in (0, k, 2 * k, 3 * k, 3 * k + 1, 4 * k)}
    umax = _declare(builder, "llvm.umax", I64, [I64, I64], [I64])
    umin = _declare(builder, "llvm.umin", I64, [I64, I64], [I64])
    base = builder.bitcast(data, I8.as_pointer())

    def fold(slot, fn, value):
        builder.store(builder.call(fn, [builder.load(slots[slot]), value]), slots[slot])

    with cgutils.for_range_slice(builder, start, stop, ir.Constant(I64, 1), intp=I64) as (r, _):
        rec = builder.gep(base, [builder.mul(r, ir.Constant(I64, size))])
        normal_or = ir.Constant(I64, 0)
        for c in range(3):
            v = builder.sext(_load_at(builder, rec, c * nb, N), I64)
            fold(c * k, umax, builder.xor(v, builder.ashr(v, ir.Constant(I64, 63))))
            normal_or = builder.or_(normal_or, v)
        fold(4 * k, umin, normal_or)
        d = _load_at(builder, rec, 3 * nb, D)
        m = builder.xor(d, builder.ashr(d, ir.Constant(D, D.width - 1)))
        fold(3 * k, umax, builder.trunc(m, I64))
        if D.width > 64:
            fold(3 * k + 1, umax, builder.trunc(builder.lshr(m, ir.Constant(D, 64)), I64))
    for s, slot in slots.items():
        builder.store(builder.load(slot), builder.gep(acc_ptr, [ir.Constant(I64, s)]), align=8)
