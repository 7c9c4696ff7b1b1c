"""Fused check-and-compute loops: one predicate over many rows, with the bit-budget scan of its inputs.

The public predicates (:mod:`csgnb.exact.predicates`) must check their inputs against
the budget of the width, and at 10^5 rows the check would cost as much as the predicate
if it were a second pass over the data (the predicates are memory-bound). So each loop
here reads a row once: it folds the row's operands into their scan accumulators
(:class:`csgnb.exact.lowering.Scan`: a few SIMD instructions, accumulators in registers)
and computes the predicate on the same row while it is in L1, emitting the per-row code
of the matching intrinsic of :mod:`csgnb.exact.intrinsics` unchanged. The caller decides
from the accumulators, once, whether the results may be returned; a row computed out of
budget is never seen.

Every loop takes, per operand, the array, a flag ``many`` (false: a single row used for
all, scanned once) and its accumulator (``None``: not scanned), then ``start, stop`` and the
output.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from csgnb.exact import lowering as lw
from csgnb.exact.intrinsics import (
    classify_at,
    intersect_into,
    planes_parallel_at,
    points_equal_at,
    signed_distance_into,
)
from csgnb.exact.lowering import I64

__all__ = ["classify_rows", "intersect_rows", "parallel_rows", "distance_rows", "points_equal_rows"]

_ROW = types.int64


def _element(intrinsic_fn, typingctx, *atys):
    """(signature, codegen) of an element intrinsic for the given operand types, rows as int64."""
    return intrinsic_fn._defn(typingctx, *atys)


def _loop(context, builder, sig, args, operands, start, stop, body):
    """Emit ``for r in [start, stop)``: scan each operand's row, then ``body(r, rows)``.

    ``operands``: (array index, many index, accumulator index) into ``args``. Single-row
    operands (many false) are scanned once before the loop and read at row 0.
    """
    scans, datas, manys, sizes = [], [], [], []
    for a, m, acc in operands:
        # An accumulator passed as None: the operand is not scanned (the caller needs no bound on it).
        skip = isinstance(sig.args[acc], types.NoneType)
        scans.append(None if skip else lw.begin_scan(context, builder, sig.args[a], args[a], sig.args[acc], args[acc]))
        datas.append(lw.data_pointer(context, builder, sig.args[a], args[a]))
        manys.append(context.cast(builder, args[m], sig.args[m], types.boolean))
        sizes.append(lw.row_bytes(sig.args[a]))
    lo = context.cast(builder, args[start], sig.args[start], types.int64)
    hi = context.cast(builder, args[stop], sig.args[stop], types.int64)
    zero = ir.Constant(I64, 0)
    nonempty = builder.icmp_signed("<", lo, hi)
    for scan, data, many in zip(scans, datas, manys, strict=True):
        if scan is not None:
            with builder.if_then(builder.and_(builder.not_(many), nonempty)):
                scan.row(data)
    with cgutils.for_range_slice(builder, lo, hi, ir.Constant(I64, 1), intp=I64) as (r, _):
        rows = []
        for scan, data, many, size in zip(scans, datas, manys, sizes, strict=True):
            if scan is None:
                rows.append(builder.select(many, r, zero))
                continue
            with builder.if_then(many, likely=True):
                base = lw.row_base(builder, data, r, size)
                for line in range(0, size, 64):
                    _prefetch(builder, builder.gep(base, [ir.Constant(I64, PREFETCH_ROWS * size + line)]))
                scan.row(base)
            rows.append(builder.select(many, r, zero))
        body(r, rows)
    for scan in scans:
        if scan is not None:
            scan.end()


#: How many rows ahead the loops prefetch: a row of these loops is 100-300 instructions, so the
#: out-of-order window alone keeps only a few rows' loads in flight.
PREFETCH_ROWS = 16


def _prefetch(builder, ptr):
    """``llvm.prefetch`` for reading into L1 (a hint: never faults, also past the end of an array)."""
    i32 = ir.IntType(32)
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32]),
                                        "llvm.prefetch.p0")
    builder.call(fn, [ptr, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])


def _store(context, builder, aty, aval, r, value):
    ary = context.make_array(aty)(context, builder, aval)
    builder.store(value, cgutils.get_item_pointer(context, builder, aty, ary, [r]))


@intrinsic
def classify_rows(typingctx, X, mx, S, ms, start, stop, out, acc_x, acc_s):
    """out[r] = classify_at(X, r, S, r) for r in [start, stop), scanning X and S (int8 ``out``)."""
    esig, emit = _element(classify_at, typingctx, X, _ROW, S, _ROW)

    def codegen(context, builder, sig, args):
        def body(r, rows):
            side = emit(context, builder, esig, [args[0], rows[0], args[2], rows[1]])
            _store(context, builder, sig.args[6], args[6], r, side)

        _loop(context, builder, sig, args, [(0, 1, 7), (2, 3, 8)], 4, 5, body)
        return context.get_dummy_value()

    return types.none(X, mx, S, ms, start, stop, out, acc_x, acc_s), codegen


@intrinsic
def intersect_rows(typingctx, P, mp, Q, mq, R, mr, start, stop, out, acc_p, acc_q, acc_r, acc_out):
    """out[r] = intersect(P[r], Q[r], R[r]) for r in [start, stop), scanning P, Q, R.

    ``acc_out``'s x4 flag (its last slot) becomes 0 if some result has x4 = 0; its other slots
    are left alone.
    """
    esig, emit = _element(intersect_into, typingctx, P, _ROW, Q, _ROW, R, _ROW, out, _ROW)

    def codegen(context, builder, sig, args):
        # Only x4 = 0 matters in the result (linearly dependent normals): tested on the values in
        # registers -- reloading the row just stored as one vector would stall store forwarding.
        acc_ptr = builder.bitcast(context.make_array(sig.args[12])(context, builder, args[12]).data,
                                  I64.as_pointer())
        T = ir.IntType(lw.wide_width(sig.args[8], "intersect_rows"))
        flag_ptr = builder.gep(acc_ptr, [ir.Constant(I64, 4 * (T.width // 64) + 1)])
        flag = cgutils.alloca_once_value(builder, builder.load(flag_ptr))

        def body(r, rows):
            eargs = [args[0], rows[0], args[2], rows[1], args[4], rows[2], args[8], r]
            x = emit.values(context, builder, esig, eargs)
            lw.store_row(context, builder, sig.args[8], args[8], r, types.int64, T, x)
            nonzero = builder.icmp_unsigned("!=", x[3], ir.Constant(T, 0))
            builder.store(builder.and_(builder.load(flag), builder.zext(nonzero, I64)), flag)

        _loop(context, builder, sig, args, [(0, 1, 9), (2, 3, 10), (4, 5, 11)], 6, 7, body)
        builder.store(builder.load(flag), flag_ptr)
        return context.get_dummy_value()

    return types.none(P, mp, Q, mq, R, mr, start, stop, out, acc_p, acc_q, acc_r, acc_out), codegen


@intrinsic
def parallel_rows(typingctx, P, mp, Q, mq, start, stop, out, acc_p, acc_q):
    """out[r] = planes_parallel_at(P, r, Q, r) for r in [start, stop), scanning P and Q (bool ``out``)."""
    esig, emit = _element(planes_parallel_at, typingctx, P, _ROW, Q, _ROW)

    def codegen(context, builder, sig, args):
        def body(r, rows):
            value = emit(context, builder, esig, [args[0], rows[0], args[2], rows[1]])
            _store(context, builder, sig.args[6], args[6], r, context.get_value_as_data(builder, types.boolean, value))

        _loop(context, builder, sig, args, [(0, 1, 7), (2, 3, 8)], 4, 5, body)
        return context.get_dummy_value()

    return types.none(P, mp, Q, mq, start, stop, out, acc_p, acc_q), codegen


@intrinsic
def distance_rows(typingctx, V, mv, S, ms, start, stop, out, acc_v, acc_s):
    """out[r] = n·v + d of V[r] (int64 points) and S[r] for r in [start, stop); V's [max, min] into acc_v."""
    esig, emit = _element(signed_distance_into, typingctx, V, _ROW, S, _ROW, out, _ROW)

    def codegen(context, builder, sig, args):
        def body(r, rows):
            emit(context, builder, esig, [args[0], rows[0], args[2], rows[1], args[6], r])

        _loop(context, builder, sig, args, [(0, 1, 7), (2, 3, 8)], 4, 5, body)
        return context.get_dummy_value()

    return types.none(V, mv, S, ms, start, stop, out, acc_v, acc_s), codegen


@intrinsic
def points_equal_rows(typingctx, X, mx, Y, my, start, stop, out, acc_x, acc_y):
    """out[r] = points_equal_at(X, r, Y, r) for r in [start, stop), scanning X and Y (bool ``out``)."""
    esig, emit = _element(points_equal_at, typingctx, X, _ROW, Y, _ROW)

    def codegen(context, builder, sig, args):
        def body(r, rows):
            value = emit(context, builder, esig, [args[0], rows[0], args[2], rows[1]])
            _store(context, builder, sig.args[6], args[6], r, context.get_value_as_data(builder, types.boolean, value))

        _loop(context, builder, sig, args, [(0, 1, 7), (2, 3, 8)], 4, 5, body)
        return context.get_dummy_value()

    return types.none(X, mx, Y, my, start, stop, out, acc_x, acc_y), codegen
