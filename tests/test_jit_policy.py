"""The jit policy: one module, no fastmath, and an on-disk cache that really fills and is reused."""

import ast
import json
import os
import pathlib
import shutil
import subprocess
import sys
import textwrap

import pytest

import csgnb

PACKAGE = pathlib.Path(csgnb.__file__).parent

SCRIPT = textwrap.dedent(
    """
    import json
    from csgnb import exact
    from csgnb.exact import predicates
    planes = exact.to_wide([[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, -3]], 192)
    exact.intersect_3_planes(planes[0], planes[1], planes[2])
    stats = predicates._intersect_kernel.stats
    print(json.dumps({"hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values())}))
    """
)


def _run(cache_dir, **env):
    environ = {k: v for k, v in os.environ.items() if k != "CSGNB_DISABLE_CACHE"}
    environ.update(NUMBA_CACHE_DIR=str(cache_dir), **env)
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=environ, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_cache_fills_and_is_reused(tmp_path):
    first = _run(tmp_path)
    assert first["misses"] >= 1 and first["hits"] == 0
    assert any(tmp_path.rglob("*.nbi")) and any(tmp_path.rglob("*.nbc"))
    second = _run(tmp_path)
    assert second["hits"] >= 1 and second["misses"] == 0


def test_cache_can_be_switched_off(tmp_path):
    _run(tmp_path, CSGNB_DISABLE_CACHE="1")
    assert not any(tmp_path.rglob("*.nbi"))


def test_cache_key_covers_the_kernels_import_closure():
    from csgnb._jit import dependency_hash, module_dependencies
    from csgnb.exact import predicates

    locator = predicates._classify_kernel._cache._impl.locator
    assert dependency_hash(predicates.__file__) in locator.get_source_stamp()
    deps = {p.relative_to(PACKAGE).as_posix() for p in module_dependencies(predicates.__file__)}
    # the intrinsics a predicate inlines, and the policy module itself
    assert {"exact/predicates.py", "exact/intrinsics.py", "exact/lowering.py", "_jit.py"} <= deps
    assert not any(d.startswith(("octree/", "apps/", "quadric/")) for d in deps)


def test_an_edit_invalidates_only_the_kernels_that_depend_on_it(tmp_path):
    """Edit one module in a copy of the package: exactly the modules importing it (transitively) get a new key."""
    from csgnb._jit import dependency_hash, module_dependencies

    # (each file is parsed once per process while it is unchanged: the edits below must be seen through that memo)
    copy = tmp_path / "csgnb"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    modules = sorted(copy.rglob("*.py"))
    before = {p: dependency_hash(p, copy) for p in modules}
    for edited in ("octree/kernels.py", "apps/gcode.py", "exact/intrinsics.py"):
        target = copy / edited
        target.write_text(target.read_text() + "\n# an edit\n")
        after = {p: dependency_hash(p, copy) for p in modules}
        changed = {p for p in modules if after[p] != before[p]}
        dependants = {p for p in modules if target in module_dependencies(p, copy)}
        assert changed == dependants, edited
        before = after
        rel = {p.relative_to(copy).as_posix() for p in changed}
        if edited == "octree/kernels.py":  # the octree's dependants, never the layers below it
            assert "octree/workpiece.py" in rel
            assert not any(r.startswith(("exact/", "mesh/", "bsp/", "quadric/", "sampling/")) for r in rel)
        if edited == "apps/gcode.py":
            assert not any(r.startswith(("exact/", "mesh/", "bsp/", "octree/")) for r in rel)
        if edited == "exact/intrinsics.py":  # what inlines the intrinsics recompiles
            assert {"exact/predicates.py", "mesh/cutting.py", "octree/kernels.py"} <= rel


def test_kernels_outside_the_package_are_keyed_on_what_they_import(tmp_path):
    """A test's or a script's kernel inlines csgnb's intrinsics: its cache key must change when they do (keyed on
    its own file only, a test compiled against an old ``lowering.py`` kept passing after it changed)."""
    from csgnb._jit import dependency_hash, keyed_on_dependencies, module_dependencies

    assert keyed_on_dependencies(__file__)
    script = tmp_path / "user_script.py"
    script.write_text("from csgnb.exact.intrinsics import classify_at\n")
    names = {p.name for p in module_dependencies(script)}
    assert {"user_script.py", "intrinsics.py", "lowering.py", "_jit.py"} <= names
    plain = tmp_path / "plain.py"
    plain.write_text("import numpy\n")
    assert keyed_on_dependencies(script) and not keyed_on_dependencies(plain)
    assert not keyed_on_dependencies(tmp_path / "missing.py") and not keyed_on_dependencies("<ipython-input-1>")
    # an edit of the package (in a copy) changes the script's key
    copy = tmp_path / "pkg" / "csgnb"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = dependency_hash(script, copy)
    lowering = copy / "exact" / "lowering.py"
    lowering.write_text(lowering.read_text() + "\n# an edit\n")
    assert dependency_hash(script, copy) != before


def test_an_unwritable_cache_folder_falls_back_with_a_warning(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    script = ("import warnings; warnings.simplefilter('always')\n"
              "import csgnb._jit as j; print('ROOT', j.CACHE_ROOT, j.CACHE_ENABLED)\n"
              "from csgnb import exact\n"
              "exact.intersect_3_planes(*exact.to_wide([[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, -3]], 128))\n")
    environ = {k: v for k, v in os.environ.items() if k != "CSGNB_DISABLE_CACHE"}
    environ.update(NUMBA_CACHE_DIR=str(locked / "cache"), XDG_CACHE_HOME=str(tmp_path / "user"))
    if os.geteuid() == 0:  # root writes anywhere: make the folder a file instead
        locked.chmod(0o700)
        (locked / "cache").write_text("not a folder")
    out = subprocess.run([sys.executable, "-c", script], env=environ, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert f"ROOT {tmp_path / 'user'}" in out.stdout and "True" in out.stdout
    assert "cannot write the numba cache folder" in out.stderr


def test_no_fastmath_and_one_jit_policy():
    """Every kernel goes through csgnb._jit.jit; nobody calls numba.njit/jit or asks for fastmath."""
    for path in PACKAGE.rglob("*.py"):
        if path.name == "_jit.py":
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "numba":
                assert node.attr not in {"njit", "jit", "vectorize", "guvectorize"}, f"{path}: numba.{node.attr}"
            if isinstance(node, ast.keyword):
                assert node.arg != "fastmath", f"{path}: fastmath"
            if isinstance(node, ast.ImportFrom) and node.module == "numba":
                assert not {a.name for a in node.names} & {"njit", "jit"}, f"{path}: from numba import jit"


def test_borrowing_kernels_return_no_arrays():
    """A kernel compiled without reference counting (csgnb._jit.borrowing_jit) must hand back no array: a caller that
    counts references would release one the kernel never took. Every signature compiled or loaded is checked; one
    that returns an array (here its argument, which numba would allow) is refused with a clear error. The hot loops
    are registered, and nothing else switches reference counting off."""
    import numpy as np

    import csgnb.octree  # noqa: F401 -- imports every module with a borrowing kernel
    from csgnb._jit import BORROWING_KERNELS, borrowing_jit

    names = {k.py_func.__name__ for k in BORROWING_KERNELS}
    assert {"merge_cells", "clip_cell", "extract_into", "cut_cell", "build_kernel"} <= names

    def first_row(a):
        return a[0]

    def itself(a):
        return a

    assert borrowing_jit(first_row)(np.arange(3.0)) == 0.0
    with pytest.raises(TypeError, match="returns array.*needs csgnb._jit.jit"):
        borrowing_jit(itself)(np.arange(3.0))
    for path in PACKAGE.rglob("*.py"):
        if path.name != "_jit.py":
            assert "_nrt" not in path.read_text(), f"{path}: reference counting switched off outside csgnb._jit"


def test_a_new_import_is_seen_by_the_parse_memo(tmp_path):
    """Imports are parsed once per file and process; an edit that adds one must change the dependencies."""
    from csgnb._jit import module_dependencies

    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "b.py").write_text("y = 2\n")
    assert [p.name for p in module_dependencies(tmp_path / "a.py", tmp_path)] == ["a.py"]
    with open(tmp_path / "a.py", "a") as fh:
        fh.write("from csgnb.b import y\n")
    assert [p.name for p in module_dependencies(tmp_path / "a.py", tmp_path)] == ["a.py", "b.py"]
