"""Unmanaged array views: how csgnb's kernels avoid numba's reference counting in hot loops.

numba reference-counts arrays: a function inlined at the IR level (``inline="always"``)
increfs every array it receives when it starts and decrefs it when it ends, and in
branchy code LLVM's reference-count pruning cannot pair these calls away. A cut passes
a dozen arrays to a dozen small helpers, so those atomic calls cost more than the exact
arithmetic (measured: an inlined three-array helper in a loop, 82 ns managed vs 1.6 ns
unmanaged).

:func:`unmanaged` returns the same array (data, shape, strides) with a null memory
owner. Reference counting a null owner is a no-op that LLVM folds away entirely once the
runtime's ``NRT_incref`` is inlined. Rules:

* call it only on a kernel's *arguments* (they stay alive for the whole call), never on an
  array the kernel allocates (numba may free the owner after its last use), and never
  return a view;
* a kernel that is called from Python converts its named tuples once at entry
  (:func:`unmanaged_tuple`) and passes the views down.

These views are an implementation detail of the kernels; nothing public returns one.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["unmanaged", "unmanaged_tuple"]


@intrinsic
def unmanaged(typingctx, arr):
    """The array ``arr`` without its memory owner (see the module docstring)."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        out = context.make_array(arr)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(out, name, getattr(src, name))
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()

    return arr(arr), codegen


@intrinsic
def unmanaged_tuple(typingctx, tup):
    """A named tuple (or tuple) of arrays and scalars with every array replaced by :func:`unmanaged` of it."""
    if not isinstance(tup, types.BaseTuple) or not all(
            isinstance(t, (types.Array, types.Number, types.Boolean)) for t in tup.types):
        return None

    def codegen(context, builder, signature, args):
        value = args[0]
        out = value
        for i, ty in enumerate(tup.types):
            if not isinstance(ty, types.Array):
                continue
            item = builder.extract_value(value, i)
            src = context.make_array(ty)(context, builder, value=item)
            view = context.make_array(ty)(context, builder)
            for name in ("nitems", "itemsize", "data", "shape", "strides"):
                setattr(view, name, getattr(src, name))
            view.meminfo = cgutils.get_null_value(view.meminfo.type)
            view.parent = cgutils.get_null_value(view.parent.type)
            out = builder.insert_value(out, view._getvalue(), i)
        return out

    return tup(tup), codegen
