"""Saving and loading workpieces bit for bit: a versioned ``.npz`` with a checksum, written atomically.

The file holds the plain arrays of :mod:`csgnb.octree.layout` (trimmed to the rows in use)
and a JSON header (format, version, grid, parameters, a SHA-256 of every array). It is
written to a temporary file in the same folder, flushed to disk and renamed over the
target, so a save killed at any point leaves the previous file intact. Loading checks the
format, version and checksum and raises :class:`WorkpieceFileError` (a ``ValueError``)
naming what is wrong; nothing is half-loaded.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from csgnb.errors import CsgnbError

__all__ = ["FORMAT", "VERSION", "WorkpieceFileError", "read_arrays", "write_arrays"]

FORMAT = "csgnb-workpiece"
VERSION = 1


class WorkpieceFileError(CsgnbError):
    """A workpiece file is unreadable: truncated, corrupted, of another format or version."""


def _digest(arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def write_arrays(path, header: dict, arrays: dict[str, np.ndarray], *, _fail_after: int | None = None) -> None:
    """Write ``arrays`` and ``header`` to ``path`` atomically (see the module docstring).

    ``_fail_after`` (tests only) raises after that many bytes, to simulate a killed save.
    """
    path = Path(path)
    header = dict(header, format=FORMAT, version=VERSION, sha256=_digest(arrays))
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            target = fh if _fail_after is None else _FailingWriter(fh, _fail_after)
            np.savez(target, header=np.array(json.dumps(header)), **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read_arrays(path) -> tuple[dict, dict[str, np.ndarray]]:
    """Read a file written by :func:`write_arrays`; raise :class:`WorkpieceFileError` if it is not intact."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            header = json.loads(str(z["header"]))
            arrays = {k: z[k] for k in z.files if k != "header"}
    except FileNotFoundError:
        raise
    except (OSError, EOFError, KeyError, ValueError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise WorkpieceFileError(f"{path} is not a readable workpiece file (truncated or corrupted?): {exc}") from exc
    if header.get("format") != FORMAT:
        raise WorkpieceFileError(f"{path} is not a csgnb workpiece file (format {header.get('format')!r})")
    if header.get("version") != VERSION:
        raise WorkpieceFileError(f"{path} is a version {header.get('version')} workpiece file; this csgnb reads "
                                 f"version {VERSION}")
    if _digest(arrays) != header.get("sha256"):
        raise WorkpieceFileError(f"{path} is corrupted: its checksum does not match its contents")
    return header, arrays


class _FailingWriter:
    """A file wrapper that raises after ``limit`` bytes (simulates a save killed midway)."""

    def __init__(self, fh, limit: int) -> None:
        self.fh = fh
        self.left = limit

    def write(self, data) -> int:
        if len(data) > self.left:
            self.fh.write(data[: self.left])
            self.left = 0
            raise KeyboardInterrupt("simulated interruption of a save")
        self.left -= len(data)
        return self.fh.write(data)

    def __getattr__(self, name):
        return getattr(self.fh, name)
