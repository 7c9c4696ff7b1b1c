"""Writing small integers into wide arrays from numba code (planes and points built inside kernels).

Kernels that create planes or points themselves (octree walls, box centres) store
int64 values into wide elements here, sign-extended to the array's width; reading
back goes through :mod:`csgnb.exact.intrinsics`.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from csgnb.exact.intrinsics import _element_pointer, _row_pointer, _wide_width

__all__ = ["store_int64_at"]


@intrinsic
def store_int64_at(typingctx, arr, i, j, value):
    """Store the int64 ``value`` into the wide element ``arr[i, j]`` (sign-extended, exact)."""
    bits = _wide_width(arr, "store_int64_at")
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        base = _row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        col = context.cast(builder, args[2], sig.args[2], types.intp)
        v = builder.sext(context.cast(builder, args[3], sig.args[3], types.int64), T)
        builder.store(v, _element_pointer(builder, base, col, T), align=8)
        return context.get_dummy_value()

    return types.none(arr, i, j, value), codegen
