"""The one numba jit policy of csgnb.

Every kernel in the package is compiled through :data:`jit` so that caching,
and the absence of ``fastmath``, are decided in one place:

* ``cache=True`` by default: compiled machine code is written to disk and reused
  by the next process. Set ``CSGNB_DISABLE_CACHE=1`` to switch it off.
* The cache of a csgnb kernel is keyed on the source of the *whole package*, not
  only on the file the kernel lives in (numba's default). Kernels inline
  wide-integer intrinsics from other modules; with numba's per-file key an edit
  of ``csgnb/exact/intrinsics.py`` would keep serving stale machine code.
* ``fastmath`` is never enabled: it allows reassociation and removes NaN/inf
  handling, which voids the IEEE error bounds the float filters and the
  conservative distances rely on.
* ``NUMBA_DISABLE_JIT=1`` is honoured for kernels that do not call wide-integer
  intrinsics (those exist only in compiled code).
"""

from __future__ import annotations

import functools
import hashlib
import os
import warnings
from pathlib import Path

import numba

__all__ = ["CACHE_ENABLED", "PACKAGE_SOURCE_HASH", "jit"]

_PACKAGE_DIR = Path(__file__).resolve().parent


def _env_flag(name: str) -> bool:
    return os.environ.get(name, "").strip().lower() in {"1", "true", "yes", "on"}


def _package_source_hash() -> str:
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE_DIR.rglob("*.py")):
        digest.update(str(path.relative_to(_PACKAGE_DIR)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


#: Whether compiled kernels are cached on disk (off when ``CSGNB_DISABLE_CACHE`` is set).
CACHE_ENABLED: bool = not _env_flag("CSGNB_DISABLE_CACHE")

#: SHA-256 of every ``.py`` file of the package: part of each cached kernel's key.
PACKAGE_SOURCE_HASH: str = _package_source_hash()


def _install_package_cache_locator() -> None:
    """Put a locator keyed on :data:`PACKAGE_SOURCE_HASH` first in numba's list, for csgnb files only."""
    from numba.core import caching, config

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
            if config.CACHE_DIR:  # honour NUMBA_CACHE_DIR like numba's own locator
                self._cache_path = os.path.join(config.CACHE_DIR, self.get_suitable_cache_subpath(py_file))

        def get_source_stamp(self):
            return (super().get_source_stamp(), PACKAGE_SOURCE_HASH)

        @classmethod
        def from_function(cls, py_func, py_file):
            try:
                inside = Path(py_file).resolve().is_relative_to(_PACKAGE_DIR)
            except OSError:
                inside = False
            return super().from_function(py_func, py_file) if inside else None

    if not any(c.__name__ == "PackageCacheLocator" for c in impl._locator_classes):
        impl._locator_classes.insert(0, PackageCacheLocator)


_install_package_cache_locator()

#: ``numba.njit`` with the package policy: cached, no fastmath, releases the GIL.
jit = functools.partial(numba.njit, cache=CACHE_ENABLED, fastmath=False, nogil=True)
