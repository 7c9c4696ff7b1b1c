"""Package boundaries: no csgnb module imports a private name (or a private module) of another sub-package.

Sub-packages talk through public names only (a kernel another package calls has a public name where it is
defined); the package-wide infrastructure at the top (``csgnb._jit``, ``csgnb._unlinked``, ``csgnb._views``,
``csgnb._resumable``, ``csgnb._files``) is private to csgnb and shared by all of its sub-packages. Tests and
benchmarks may reach into internals.
"""

from __future__ import annotations

import ast
import pathlib

import csgnb

PACKAGE = pathlib.Path(csgnb.__file__).parent
SHARED = {"csgnb._jit", "csgnb._threads", "csgnb._unlinked", "csgnb._views", "csgnb._resumable", "csgnb._files",
          "csgnb._shuffle"}


def _subpackage(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (PACKAGE / parts[1]).is_dir() else ""


def crossings(package: pathlib.Path = PACKAGE) -> list[str]:
    found = []
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package)
        here = rel.parts[0] if len(rel.parts) > 1 else ""
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("csgnb.")):
                continue
            if node.module in SHARED:
                continue
            there = _subpackage(node.module)
            if there == here:
                continue
            private_module = any(p.startswith("_") for p in node.module.split(".")[1:])
            for alias in node.names:
                if private_module or alias.name.startswith("_"):
                    found.append(f"{rel}: from {node.module} import {alias.name}")
    return found


def test_no_private_name_crosses_a_package_boundary():
    assert crossings() == []


def test_the_check_finds_a_crossing(tmp_path):
    fake = tmp_path / "csgnb"
    (fake / "bsp").mkdir(parents=True)
    (fake / "octree").mkdir()
    (fake / "octree" / "kernels.py").write_text("from csgnb.bsp.build import _build_kernel\n")
    (fake / "bsp" / "helpers.py").write_text("from csgnb.bsp.build import _private_is_fine_here\n")
    assert crossings(fake) == ["octree/kernels.py: from csgnb.bsp.build import _build_kernel"]
