"""The jit policy: one module, no fastmath, and an on-disk cache that really fills and is reused."""

import ast
import json
import os
import pathlib
import subprocess
import sys
import textwrap

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


def test_cache_key_includes_the_whole_package_source():
    from csgnb._jit import PACKAGE_SOURCE_HASH
    from csgnb.exact import predicates

    locator = predicates._classify_kernel._cache._impl.locator
    assert PACKAGE_SOURCE_HASH in locator.get_source_stamp()


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
