"""Calls between compiled kernels that do not copy the callee into the caller (compile time, issue 21).

numba links the LLVM module of every function a kernel calls into the kernel's own module and runs
the whole O3 pipeline and the machine-code generation over the result (``CodeLibrary.finalize``):
the mesh cut, the merge, clipping and BSP building were optimised and code-generated again inside
every octree kernel that reaches them, and again in each caller above that (the octree part: 41 of
its 62 s of compilation were this ``native_lowering``; its cache files held the same ~400 KiB of
code six times).

``unlinked(kernel)`` names a compiled kernel so that a call to it from another kernel goes through
a pointer instead: the caller's module gets a global ``.csgnb.unlinked$<caller>$<callee>`` (a null
pointer) and, beside it, the callee's module, name and argument types (pickled, in a constant
global), and is compiled without the callee's code. Every kernel compiled through
:data:`csgnb._jit.jit` resolves its pointers when it is compiled **or loaded from the cache**
(its dispatcher's ``add_overload``, before the kernel can run): it compiles or loads the callee
for those argument types and stores the address of its native entry point. The call itself is
numba's own calling convention (the status and exception of the callee are propagated as for a
linked call); a pointer still null when the call runs raises ``RuntimeError`` instead of jumping
to address 0. A callee's return type or argument types that differ from those recorded (a stale
cache) are refused when the caller is loaded.

The price: LLVM cannot inline the callee. That is why only big kernels called once per cell or per
cut are named this way (their call costs a few nanoseconds against microseconds of work).
With ``NUMBA_DISABLE_JIT=1`` an ``unlinked`` kernel is a plain call.
"""

from __future__ import annotations

import ctypes
import importlib
import pickle

from llvmlite import ir as llvmir
from numba.core import cgutils, datamodel, types
from numba.core.extending import register_model, typeof_impl
from numba.core.imputils import lower_constant

__all__ = ["Unlinked", "resolve_unlinked", "unlinked"]

_POINTER = ".csgnb.unlinked$"
#: Every :class:`Unlinked` kernel of this process by (module, qualified name): where a loaded caller finds its callees.
_KERNELS: dict = {}
_RECORD = ".csgnb.unlinked.record$"


class Unlinked:
    """A compiled kernel called by pointer from other kernels (see the module's docstring)."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        py_func = getattr(dispatcher, "py_func", dispatcher)
        self.key = (py_func.__module__, py_func.__qualname__)
        self.__name__ = py_func.__name__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = dispatcher
        _KERNELS[self.key] = self

    def __call__(self, *args):
        return self.dispatcher(*args)

    def __getattr__(self, name):  # overloads, py_func, inspect_*: the dispatcher's
        if name == "dispatcher":
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self):
        return f"unlinked({self.key[0]}.{self.key[1]})"


def unlinked(dispatcher) -> Unlinked:
    """``dispatcher`` (a kernel compiled through :data:`csgnb._jit.jit`), called by pointer from kernels."""
    return Unlinked(dispatcher)


class UnlinkedType(types.Callable, types.Opaque):
    """The numba type of an :class:`Unlinked` kernel: typed as the kernel, lowered as a call by pointer."""

    def __init__(self, obj: Unlinked):
        self.obj = obj
        self._dispatcher_type = types.Dispatcher(obj.dispatcher)
        super().__init__(f"unlinked({obj.key[0]}.{obj.key[1]})")

    @property
    def key(self):
        return self.obj.key

    def get_call_type(self, context, args, kws):
        return self._dispatcher_type.get_call_type(context, args, kws)

    def get_call_signatures(self):
        return self._dispatcher_type.get_call_signatures()

    def get_impl_key(self, sig):
        _register_call(self, sig)
        return self


@typeof_impl.register(Unlinked)
def _typeof_unlinked(val, c):
    return UnlinkedType(val)


@register_model(UnlinkedType)
class _UnlinkedModel(datamodel.models.OpaqueModel):
    pass


@lower_constant(UnlinkedType)
def _lower_unlinked_constant(context, builder, ty, pyval):
    return context.get_dummy_value()


_REGISTERED: set = set()


def _register_call(fnty: UnlinkedType, sig) -> None:
    """Register, once per callee signature, the lowering of a call by pointer."""
    from numba.core.registry import cpu_target

    cres = fnty.obj.dispatcher.overloads[tuple(sig.args)]
    fndesc = cres.fndesc
    token = (fnty, fndesc.mangled_name)
    if token in _REGISTERED:
        return
    _REGISTERED.add(token)
    record = pickle.dumps((fnty.obj.key, tuple(fndesc.argtypes), fndesc.restype))
    record = len(record).to_bytes(8, "little") + record

    def call_by_pointer(context, builder, call_sig, args):
        module = builder.module
        void_ptr = llvmir.IntType(8).as_pointer()
        # one pointer per caller function: weak, so that a caller linked into another keeps one copy
        suffix = builder.function.name + "$" + fndesc.mangled_name
        try:
            pointer = module.get_global(_POINTER + suffix)
        except KeyError:
            pointer = llvmir.GlobalVariable(module, void_ptr, name=_POINTER + suffix)
            pointer.linkage = "weak_odr"
            pointer.initializer = llvmir.Constant(void_ptr, None)
            data_type = llvmir.ArrayType(llvmir.IntType(8), len(record))
            data = llvmir.GlobalVariable(module, data_type, name=_RECORD + suffix)
            data.linkage = "weak_odr"
            data.global_constant = True
            data.initializer = llvmir.Constant(data_type, bytearray(record))
        address = builder.load(pointer)
        with cgutils.if_unlikely(builder, cgutils.is_null(builder, address)):
            context.call_conv.return_user_exc(
                builder, RuntimeError, (f"csgnb: the call of {fnty.obj!r} was not resolved when its caller was "
                                        "loaded (clear the numba cache: NUMBA_CACHE_DIR or csgnb/__pycache__)",))
        function_type = context.call_conv.get_function_type(fndesc.restype, fndesc.argtypes)
        function = builder.bitcast(address, function_type.as_pointer())
        status, result = context.call_conv.call_function(builder, function, fndesc.restype, fndesc.argtypes, args)
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return result

    call_by_pointer.signature = fndesc.argtypes
    call_by_pointer.libs = ()
    cpu_target.target_context._defns[fnty].append(call_by_pointer, call_by_pointer.signature)


def _callee(key: tuple[str, str]):
    """The dispatcher of the :class:`Unlinked` kernel ``key`` (importing its module if no caller did)."""
    if key not in _KERNELS:
        importlib.import_module(key[0])
    if key not in _KERNELS:
        raise RuntimeError(f"csgnb: a cached kernel calls {key[0]}.{key[1]}, which no longer exists: clear the numba "
                           "cache (NUMBA_CACHE_DIR or csgnb/__pycache__)")
    return _KERNELS[key].dispatcher


def resolve_unlinked(library) -> int:
    """Store the callee addresses of every call by pointer in a just compiled or loaded ``library``.

    Returns how many pointers were set. Raises ``RuntimeError`` when a callee no longer has the
    argument and return types the caller was compiled against.
    """
    module = library._shared_module if getattr(library, "_shared_module", None) is not None \
        else library._final_module
    names = [gv.name for gv in module.global_variables if gv.name.startswith(_POINTER)]
    if not names:
        return 0
    engine = library._codegen._engine._ee
    for name in names:
        suffix = name[len(_POINTER):]
        where = engine.get_global_value_address(_RECORD + suffix)
        size = int.from_bytes(ctypes.string_at(where, 8), "little")
        key, argtypes, restype = pickle.loads(ctypes.string_at(where + 8, size))
        dispatcher = _callee(key)
        dispatcher.compile(argtypes)
        cres = dispatcher.overloads[tuple(argtypes)]
        if cres.fndesc.restype != restype or tuple(cres.fndesc.argtypes) != tuple(argtypes):
            raise RuntimeError(f"csgnb: {key[0]}.{key[1]} now takes {cres.fndesc.argtypes} -> "
                               f"{cres.fndesc.restype}; a cached caller was compiled against {argtypes} -> "
                               f"{restype}: clear the numba cache (NUMBA_CACHE_DIR or csgnb/__pycache__)")
        target = cres.library.get_pointer_to_function(cres.fndesc.mangled_name)
        if not target:
            raise RuntimeError(f"csgnb: no native entry point for {key[0]}.{key[1]}{tuple(argtypes)}")
        ctypes.c_void_p.from_address(engine.get_global_value_address(name)).value = target
    return len(names)
