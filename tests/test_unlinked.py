"""Calls by pointer between kernels (csgnb._unlinked): same results, errors propagated, cache-safe, no copied code."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="compiled calls only")

_MODULE = textwrap.dedent(
    """
    import numpy as np
    from csgnb._jit import jit
    from csgnb._unlinked import unlinked

    @unlinked
    @jit
    def weighted(a, i):
        if i < 0:
            raise ValueError("negative weight")
        s = 0.0
        for k in range(a.shape[0]):
            s += a[k] * i
        return s

    @jit
    def middle(a, n):
        t = 0.0
        for i in range(n):
            t += weighted(a, i)
        return t

    @jit
    def top(a, n):
        return middle(a, n) + weighted(a, 2)
    """
)

_RUN = textwrap.dedent(
    """
    import sys
    import numpy as np
    sys.path.insert(0, sys.argv[1])
    import unlinked_demo as m
    a = np.arange(5.0)
    order = sys.argv[2]
    if order == "top-first":
        print(m.top(a, 4), m.middle(a, 4))
    else:
        print(m.middle(a, 4), m.top(a, 4))
    try:
        m.top(a, -1)
        m.middle(a, 0)
        m.weighted(a, -1)
    except ValueError as e:
        print("ValueError", e)
    """
)


def _run(folder, order):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(folder / "cache"))
    out = subprocess.run([sys.executable, "-c", _RUN, str(folder), order], capture_output=True, text=True, env=env,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.split("\n")


def test_calls_by_pointer_compile_load_from_the_cache_and_propagate_errors(tmp_path):
    (tmp_path / "unlinked_demo.py").write_text(_MODULE)
    total = np.arange(5.0).sum()
    first = _run(tmp_path, "middle-first")  # compiles and caches
    assert first[0].split() == [str(total * 6), str(total * 8)]
    assert first[1] == "ValueError negative weight"
    # Loaded from the cache in a new process, the caller before its callee and the other way round.
    for order in ("top-first", "middle-first"):
        again = _run(tmp_path, order)
        expect = [str(total * 8), str(total * 6)] if order == "top-first" else [str(total * 6), str(total * 8)]
        assert again[0].split() == expect
        assert again[1] == "ValueError negative weight"
    assert any(p.suffix == ".nbi" for p in (tmp_path / "cache").rglob("*"))


def _defined_functions(dispatcher):
    names = []
    for cres in dispatcher.overloads.values():
        library = cres.library
        module = library._shared_module if library._shared_module is not None else library._final_module
        names += [f.name for f in module.functions if not f.is_declaration]
    return names


def test_a_null_pointer_raises_instead_of_jumping_to_zero():
    import ctypes

    from csgnb._jit import jit
    from csgnb._unlinked import unlinked

    @unlinked
    @jit(cache=False)
    def callee(x):
        return x + 1

    @jit(cache=False)
    def caller(x):
        return callee(x) * 2

    assert caller(3) == 8
    (cres,) = caller.overloads.values()
    module = cres.library._final_module
    (name,) = [g.name for g in module.global_variables if g.name.startswith(".csgnb.unlinked$")]
    engine = cres.library._codegen._engine._ee
    slot = ctypes.c_void_p.from_address(engine.get_global_value_address(name))
    saved = slot.value
    slot.value = None
    try:
        with pytest.raises(RuntimeError, match="was not resolved"):
            caller(3)
    finally:
        slot.value = saved
    assert caller(4) == 10


def test_octree_kernels_hold_their_own_code_only():
    """The per-cell kernels call the merge, extraction, clipping, cut and BSP building by pointer: their compiled
    modules must not hold copies of them (numba linked each callee's code into every caller, issue 21)."""
    from csgnb.warmup import warm_up

    warm_up("octree", parallel=False)
    import csgnb.octree.kernels as kernels

    for caller in (kernels._boolean_kernel, kernels.boolean_cell, kernels.merge_and_simplify, kernels.split_step,
                   kernels.combine_parent, kernels._combine_kernel):
        defined = " ".join(_defined_functions(caller))
        assert defined, caller
        for callee in ("merge_cells", "extract_into", "clip_cell", "cut_cell", "build_kernel", "merge_and_simplify",
                       "simplify_in_box"):
            if callee in getattr(caller, "__name__", ""):
                continue
            assert f"{len(callee)}{callee}" not in defined, (caller, callee)
