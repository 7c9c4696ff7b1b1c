"""The one numba jit policy of csgnb.

Every kernel in the package is compiled through :data:`jit` so that caching,
and the absence of ``fastmath``, are decided in one place:

* ``cache=True`` by default: compiled machine code is written to disk and reused
  by the next process. Set ``CSGNB_DISABLE_CACHE=1`` to switch it off.
* The cache of a csgnb kernel is keyed on the sources of its module **and of every
  csgnb module that module imports, transitively** (:func:`dependency_hash`), not
  only on the file the kernel lives in (numba's default). Kernels inline
  wide-integer intrinsics from other modules; with numba's per-file key an edit
  of ``csgnb/exact/intrinsics.py`` would keep serving stale machine code. A kernel
  can only call what its module's globals name, and those come from its imports,
  so the import closure covers everything it inlines; an edit of
  ``csgnb/apps/gcode.py`` recompiles only the kernels whose modules import it,
  not the exact, mesh, bsp and octree kernels (minutes of compilation). Kernels in
  files outside the package that import csgnb (tests, benchmarks, scripts) are keyed
  the same way (:func:`keyed_on_dependencies`).
* A cache folder that cannot be written (a read-only install, another user's
  ``NUMBA_CACHE_DIR``) falls back to a per-user folder, then to no cache, with a
  warning, instead of failing at import.
* ``fastmath`` is never enabled: it allows reassociation and removes NaN/inf
  handling, which voids the IEEE error bounds the float filters and the
  conservative distances rely on.
* ``NUMBA_DISABLE_JIT=1`` is honoured for kernels that do not call wide-integer
  intrinsics (those exist only in compiled code).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import os
import tempfile
import warnings
from pathlib import Path

import numba

from csgnb._unlinked import resolve_unlinked

__all__ = ["BORROWING_KERNELS", "CACHE_ENABLED", "PACKAGE_SOURCE_HASH", "borrowing_jit", "dependency_hash", "jit",
           "keyed_on_dependencies", "module_dependencies"]

_PACKAGE_DIR = Path(__file__).resolve().parent


def _env_flag(name: str) -> bool:
    return os.environ.get(name, "").strip().lower() in {"1", "true", "yes", "on"}


def _package_source_hash() -> str:
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE_DIR.rglob("*.py")):
        digest.update(str(path.relative_to(_PACKAGE_DIR)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _module_file(name: str, package_dir: Path) -> Path | None:
    """The source file of csgnb module ``name`` (``csgnb.a.b``) under ``package_dir``, or None."""
    parts = name.split(".")
    if parts[0] != "csgnb":
        return None
    base = package_dir.joinpath(*parts[1:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _imported_modules(path: Path, package_dir: Path) -> frozenset[Path]:
    """The csgnb source files whose globals ``path`` can reach through its imports (lazy ones included).

    ``from csgnb.a.b import x`` reaches ``csgnb/a/b.py`` (or ``csgnb/a/b/__init__.py``) and ``csgnb/a/b/x.py``
    when ``x`` is a submodule; ``import csgnb.a.b`` binds ``csgnb``, so every package on the way counts.
    Running ``csgnb/a/__init__.py`` on the way does not matter: a kernel sees only the names it imports.

    Parsed once per file and process (while the file's size and modification time stay the same): every module
    with kernels walks the import closure, so the package's ~60 files were parsed ~600 times at import, 6-11 s
    of every process's start before this memo (2026-12-03)."""
    stat = path.stat()
    key = (path, package_dir, stat.st_mtime_ns, stat.st_size)
    found = _IMPORTS_MEMO.get(key)
    if found is None:
        found = _IMPORTS_MEMO[key] = frozenset(_parse_imports(path, package_dir))
    return found


_IMPORTS_MEMO: dict[tuple, frozenset[Path]] = {}


def _parse_imports(path: Path, package_dir: Path) -> set[Path]:
    """:func:`_imported_modules` of ``path``, from its source."""
    out: set[Path] = set()
    tree = ast.parse(path.read_bytes(), filename=str(path))
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                names.extend(".".join(parts[:k]) for k in range(2, len(parts) + 1))
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
            names.extend(f"{node.module}.{a.name}" for a in node.names)  # `from pkg import submodule`
    for name in names:
        f = _module_file(name, package_dir)
        if f is not None:
            out.add(f)
    return out


def module_dependencies(path, package_dir=None) -> list[Path]:
    """The csgnb source files the module at ``path`` depends on: itself, this policy module and every
    csgnb module it imports, transitively (sorted). ``package_dir`` defaults to this package."""
    package_dir = Path(package_dir or _PACKAGE_DIR).resolve()
    start = Path(path).resolve()
    seen = {start, package_dir / "_jit.py"}
    todo = [start]
    while todo:
        for dep in _imported_modules(todo.pop(), package_dir):
            if dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return sorted(p for p in seen if p.is_file())


def dependency_hash(path, package_dir=None) -> str:
    """SHA-256 over the sources of :func:`module_dependencies` of ``path``: part of its kernels' cache key."""
    root = Path(package_dir or _PACKAGE_DIR).resolve()
    digest = hashlib.sha256()
    for dep in module_dependencies(path, root):
        # a file outside the package (a test, a benchmark, a user's script) is named by its absolute path
        digest.update(str(dep.relative_to(root) if dep.is_relative_to(root) else dep).encode())
        digest.update(dep.read_bytes())
    return digest.hexdigest()


#: One computation per module and process (a module's kernels share it).
_process_dependency_hash = functools.cache(dependency_hash)


#: Whether compiled kernels are cached on disk (off when ``CSGNB_DISABLE_CACHE`` is set).
CACHE_ENABLED: bool = not _env_flag("CSGNB_DISABLE_CACHE")

#: SHA-256 of every ``.py`` file of the package (a version stamp; cache keys use :func:`dependency_hash`).
PACKAGE_SOURCE_HASH: str = _package_source_hash()


def _writable(folder: str) -> bool:
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def _cache_roots() -> list[str]:
    """Where csgnb kernels may be cached, in order of preference: ``NUMBA_CACHE_DIR`` when set, else the
    package's ``__pycache__`` folders (numba's default); then a per-user folder."""
    from numba.core import config

    roots = [config.CACHE_DIR] if config.CACHE_DIR else [str(_PACKAGE_DIR / "__pycache__")]
    user = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    roots.append(os.path.join(user, "csgnb", "numba"))
    return roots


def _choose_cache_root() -> str | None:
    """The first writable cache root; a warning when it is not the preferred one; None when none is."""
    roots = _cache_roots()
    for k, root in enumerate(roots):
        if _writable(root):
            if k:
                warnings.warn(f"csgnb: cannot write the numba cache folder {roots[0]}; caching compiled kernels "
                              f"in {root} instead (set NUMBA_CACHE_DIR to a writable folder to choose)",
                              RuntimeWarning, stacklevel=3)
            return root
    warnings.warn(f"csgnb: none of the numba cache folders {roots} can be written; kernels are compiled in "
                  "every process (set NUMBA_CACHE_DIR to a writable folder to cache them)",
                  RuntimeWarning, stacklevel=3)
    return None


#: The folder compiled kernels are cached under (None: caching off or impossible).
CACHE_ROOT: str | None = _choose_cache_root() if CACHE_ENABLED else None
if CACHE_ROOT is None:
    CACHE_ENABLED = False


def keyed_on_dependencies(py_file) -> bool:
    """Whether kernels of ``py_file`` are cached under :func:`dependency_hash`: csgnb's own modules, and any other
    file that imports csgnb (tests, benchmarks, a user's script). Keyed on the file alone, a kernel there that
    inlines csgnb's intrinsics outlives an edit of them: a test compiled against the old lowering kept passing
    after it changed (2026-12-04). Files that do not import csgnb keep numba's own locator."""
    try:
        path = Path(py_file).resolve()
        return path.is_relative_to(_PACKAGE_DIR) or (path.is_file() and bool(_imported_modules(path, _PACKAGE_DIR)))
    except (OSError, SyntaxError, ValueError):
        return False


def _install_package_cache_locator() -> None:
    """Put a locator keyed on :func:`dependency_hash` first in numba's list, for the files
    :func:`keyed_on_dependencies` names."""
    from numba.core import caching

    # numba renamed these from private to public names over its versions.
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    base = getattr(caching, "InTreeCacheLocator", None) or getattr(caching, "_InTreeCacheLocator", None)
    if impl is None or base is None:
        warnings.warn(
            "csgnb: this numba has no cache-locator hooks; cached kernels are keyed per file, "
            "so clear NUMBA_CACHE_DIR after editing csgnb sources",
            RuntimeWarning,
            stacklevel=2,
        )
        return

    class PackageCacheLocator(base):
        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = os.path.join(CACHE_ROOT, self.get_suitable_cache_subpath(py_file))

        def get_source_stamp(self):
            return (super().get_source_stamp(), _process_dependency_hash(self._py_file))

        @classmethod
        def from_function(cls, py_func, py_file):
            return super().from_function(py_func, py_file) if CACHE_ROOT and keyed_on_dependencies(py_file) else None

    if not any(c.__name__ == "PackageCacheLocator" for c in impl._locator_classes):
        impl._locator_classes.insert(0, PackageCacheLocator)


_install_package_cache_locator()


def _resolving(dispatcher):
    """``dispatcher``, resolving the calls by pointer (:mod:`csgnb._unlinked`) of every signature it compiles or
    loads from the cache, before that signature can run."""
    add_overload = getattr(dispatcher, "add_overload", None)
    if add_overload is None:  # NUMBA_DISABLE_JIT: a plain Python function
        return dispatcher

    def resolving_add_overload(cres):
        resolve_unlinked(cres.library)
        add_overload(cres)

    dispatcher.add_overload = resolving_add_overload
    return dispatcher


def jit(fn=None, **options):
    """``numba.njit`` with the package policy: cached, no fastmath, releases the GIL; ``@jit`` or ``@jit(**options)``.

    Every kernel resolves, when compiled or loaded from the cache, the kernels it calls by pointer
    (:func:`csgnb._unlinked.unlinked`).
    """
    options = {"cache": CACHE_ENABLED, "fastmath": False, "nogil": True, **options}
    if fn is None:
        return lambda f: _resolving(numba.njit(f, **options))
    return _resolving(numba.njit(fn, **options))


#: The compiled inner loops that only borrow arrays (see :func:`borrowing_jit`), for the test that checks them.
BORROWING_KERNELS: list = []


def borrowing_jit(fn):
    """:data:`jit` without reference counting (numba's ``_nrt=False``), for the hot inner loops that **borrow**
    arrays: they take arrays and views from their caller, never allocate (numba refuses ``np.empty`` and the like
    in them at compile time), and return scalars only (every signature compiled or loaded is checked).

    Every binding of an array or of a member of a NamedTuple of arrays to a name emits an
    ``NRT_incref`` / ``NRT_decref`` call pair, even on the unmanaged views (no meminfo) csgnb's
    kernels pass around (:mod:`csgnb._views`); the calls are opaque to LLVM, so values are
    reloaded around them. In the cut, merge, clip and extraction loops they cost a third of a
    carving's time (a dome carve of 1,000 capsules: 5.2 s -> 3.5 s without them).
    """
    dispatcher = _resolving(numba.njit(fn, cache=CACHE_ENABLED, fastmath=False, nogil=True, _nrt=False))
    add_overload = dispatcher.add_overload  # resolves the calls by pointer

    def checked_add_overload(cres):
        # Every signature compiled or loaded passes here: refuse one that hands an array back.
        if _holds_array(cres.signature.return_type):
            raise TypeError(f"{fn.__qualname__} is compiled without reference counting (borrowing_jit) and returns "
                            f"{cres.signature.return_type}: a kernel that hands back arrays needs csgnb._jit.jit")
        add_overload(cres)

    dispatcher.add_overload = checked_add_overload
    BORROWING_KERNELS.append(dispatcher)
    return dispatcher


def _holds_array(t) -> bool:
    if isinstance(t, numba.types.ArrayCompatible):
        return True
    return isinstance(t, numba.types.BaseTuple) and any(_holds_array(x) for x in t.types)
