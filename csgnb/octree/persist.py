"""Saving and loading workpieces bit for bit: a versioned ``.npz`` with a checksum, written atomically.

The file is a zip of ``.npy`` arrays: the plain arrays of :mod:`csgnb.octree.layout` in a
canonical form (trimmed to the rows in use, dead rows zeroed, the BSP pool compacted; see
:meth:`csgnb.octree.Workpiece.save`) and a JSON header (format, version, grid, parameters,
the digests of the mesh-tool differences it would skip as already applied, if any, a SHA-256
of the header and every array). The zip is written deterministically (fixed
member order and timestamps, no compression), so the same workpiece always gives the same
bytes. It is written to a temporary file in the same folder (named after the target, this
host and the writing process), flushed to disk and renamed over the target, so a save
killed at any point leaves the previous file intact; a later save of the same target
deletes the temporaries whose writer is gone.

Loading checks the format, version and checksum, and then the *structure*
(:func:`check_workpiece`): every index in range, the octree a tree of octants, the BSPs
trees, the counts, the palette within the bit budget, the header consistent with the
arrays. A file that passes is a valid workpiece, whatever wrote it; anything else raises
:class:`WorkpieceFileError` (a ``ValueError``) naming what is wrong; nothing is half-loaded.
A checksum cannot tell a deliberate edit of the geometry itself (a plane's coefficients, a
cell's label 0 or 1) from the original: such a file loads as the solid it describes.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import socket
import threading
import zipfile
import zlib
from pathlib import Path

import numpy as np

from csgnb.errors import CsgnbError

__all__ = ["FORMAT", "VERSION", "WorkpieceFileError", "check_workpiece", "read_arrays", "write_arrays"]

FORMAT = "csgnb-workpiece"
VERSION = 2


class WorkpieceFileError(CsgnbError):
    """A workpiece file is unreadable: truncated, corrupted, inconsistent, of another format or version."""


# -- checksum -------------------------------------------------------------------------


def _digest(header: dict, arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of the header (without its ``sha256`` field) and of every array (name, dtype, shape, bytes)."""
    h = hashlib.sha256()
    h.update(json.dumps({k: v for k, v in header.items() if k != "sha256"}, sort_keys=True).encode())
    for name in sorted(arrays):
        a = np.asarray(arrays[name], order="C")  # (np.ascontiguousarray would make a 0-d array 1-d)
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


# -- writing ----------------------------------------------------------------------------

_HOST = hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]
_ACTIVE: set[str] = set()  # temporaries this process is writing now
_ACTIVE_LOCK = threading.Lock()
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def _temp_pattern(name: str) -> re.Pattern:
    return re.compile(re.escape(name) + r"\.([0-9a-f]{8})\.([0-9]+)\.([0-9a-f]{8})\.tmp")


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # PermissionError: it exists, owned by another user
        return True
    return True


def _clean_stale_temporaries(path: Path) -> None:
    """Delete temporaries of ``path`` left by saves that were killed: written on this host by a process now gone
    (or by an earlier process with this one's id), not by a save in progress."""
    if os.name == "nt":  # os.kill(pid, 0) would terminate the process there
        return
    pattern = _temp_pattern(path.name)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    me = os.getpid()
    for entry in entries:
        m = pattern.fullmatch(entry.name)
        if m is None or m[1] != _HOST:
            continue
        pid = int(m[2])
        if pid == me:
            with _ACTIVE_LOCK:
                if entry.name in _ACTIVE:
                    continue
        elif _pid_alive(pid):
            continue
        try:
            os.unlink(entry.path)
        except OSError:
            pass


def _write_zip(fh, header_json: str, arrays: dict[str, np.ndarray]) -> None:
    """A deterministic ``.npz``: the header first, then the arrays by name; fixed timestamps, stored."""
    with zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, arr in [("header", np.array(header_json))] + sorted(arrays.items()):
            info = zipfile.ZipInfo(name + ".npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            info.create_system = 3
            with zf.open(info, "w", force_zip64=True) as out:
                np.lib.format.write_array(out, np.asarray(arr, order="C"), allow_pickle=False)


def write_arrays(path, header: dict, arrays: dict[str, np.ndarray], *, file_format: str = FORMAT,
                 version: int = VERSION, _fail_after: int | None = None) -> None:
    """Write ``arrays`` and ``header`` to ``path`` atomically and deterministically (see the module docstring).

    ``_fail_after`` (tests only) raises after that many bytes, to simulate a killed save.
    """
    path = Path(path)
    header = dict(header, format=file_format, version=version)
    header["sha256"] = _digest(header, arrays)
    header_json = json.dumps(header, sort_keys=True)
    _clean_stale_temporaries(path)
    folder = path.parent if str(path.parent) else Path(".")
    name = f"{path.name}.{_HOST}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    tmp = folder / name
    with _ACTIVE_LOCK:
        _ACTIVE.add(name)
    try:
        # 0o666 & ~umask, as for any file the user writes (mkstemp would make it 0o600)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
        try:
            with os.fdopen(fd, "wb") as fh:
                target = fh if _fail_after is None else _FailingWriter(fh, _fail_after)
                _write_zip(target, header_json, arrays)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        _fsync_folder(folder)
    finally:
        with _ACTIVE_LOCK:
            _ACTIVE.discard(name)


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# -- reading ----------------------------------------------------------------------------


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    """One ``.npy`` member, its declared size checked against the zip entry before anything is allocated."""
    with zf.open(info) as fh:
        major, _ = np.lib.format.read_magic(fh)
        if major == 1:
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
        elif major in (2, 3):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        else:
            raise ValueError(f"unsupported .npy version {major}")
        if dtype.hasobject:
            raise ValueError("it holds Python objects")
        count = 1
        for s in shape:
            count *= int(s)
        nbytes = count * dtype.itemsize
        if fh.tell() + nbytes != info.file_size:
            raise ValueError(f"its size ({info.file_size} bytes) does not match its shape {shape} and dtype {dtype}")
        data = fh.read(nbytes)
        if len(data) != nbytes:
            raise EOFError("it ends early")
    arr = np.frombuffer(data, dtype=dtype, count=count)
    return arr.reshape(shape, order="F" if fortran else "C").copy()


def read_arrays(path, *, file_format: str = FORMAT, version: int = VERSION) -> tuple[dict, dict[str, np.ndarray]]:
    """Read a file written by :func:`write_arrays`; raise :class:`WorkpieceFileError` if it is not intact.

    A missing or unreadable file (``FileNotFoundError``, ``PermissionError``, ``IsADirectoryError``) raises
    that error; only the *contents* are judged here.
    """
    path = Path(path)
    try:
        zf = zipfile.ZipFile(path)
    except (FileNotFoundError, PermissionError, IsADirectoryError):
        raise
    except (OSError, EOFError, ValueError, zipfile.BadZipFile) as exc:
        raise WorkpieceFileError(f"{path} is not a {file_format} file (.npz): it is not a zip archive "
                                 f"(another kind of file, or truncated or corrupted?): {exc}") from exc
    members: dict[str, np.ndarray] = {}
    try:
        with zf:
            for info in zf.infolist():
                name = info.filename
                if not name.endswith(".npy") or "/" in name or name[:-4] in members:
                    raise WorkpieceFileError(f"{path} is not a {file_format} file: it holds the unexpected "
                                             f"member {name!r}")
                try:
                    members[name[:-4]] = _read_member(zf, info)
                except (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error, NotImplementedError) as exc:
                    if isinstance(exc, WorkpieceFileError):
                        raise
                    raise WorkpieceFileError(f"{path}: its array {name[:-4]!r} is unreadable (truncated or "
                                             f"corrupted?): {exc}") from exc
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise WorkpieceFileError(f"{path} is not a readable {file_format} file (truncated or corrupted?): "
                                 f"{exc}") from exc
    raw = members.pop("header", None)
    if raw is None or raw.shape != () or raw.dtype.kind != "U":
        raise WorkpieceFileError(f"{path} is not a {file_format} file: it has no header")
    try:
        header = json.loads(str(raw))
    except (ValueError, RecursionError) as exc:
        raise WorkpieceFileError(f"{path} has an unreadable header (corrupted?): {exc}") from exc
    if not isinstance(header, dict):
        raise WorkpieceFileError(f"{path} has an unreadable header (not a JSON object)")
    if header.get("format") != file_format:
        raise WorkpieceFileError(f"{path} is not a {file_format} file (format {header.get('format')!r})")
    if header.get("version") != version:
        raise WorkpieceFileError(f"{path} is a version {header.get('version')!r} {file_format} file; this csgnb "
                                 f"reads version {version}")
    if _digest(header, members) != header.get("sha256"):
        raise WorkpieceFileError(f"{path} is corrupted: its checksum does not match its contents")
    return header, members


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


# -- the structure of a workpiece -----------------------------------------------------------------

_OC_DTYPES = {"child": np.int32, "parent": np.int32, "kind": np.int8, "label": np.int32, "start": np.int64,
              "length": np.int32, "lo": np.int64, "size": np.int64}
_POOL_NAMES = ("plane", "neg", "pos", "label")
ARRAY_NAMES = frozenset([f"oc_{k}" for k in _OC_DTYPES] + ["oc_counts", "oc_free_blocks"]
                        + [f"pool_{k}" for k in _POOL_NAMES] + ["palette_limbs", "axis_keys", "axis_rows"])
HEADER_FIELDS = {"width", "exponent", "origin", "max_coordinate", "threshold", "min_cell", "max_tool_polygons",
                 "seed", "root_lo", "root_size", "max_normal", "max_offset"}
OPTIONAL_HEADER_FIELDS = {"completed", "checkpoint", "format", "version", "sha256", "applied", "boundary_cache"}
#: The boundary cache (csgnb.octree.piece_cache): all three or none (files written before it have none).
PIECE_ARRAY_NAMES = frozenset(["oc_pieces", "pieces_rows", "pieces_size"])
_AXIS_MULTIPLIER = np.int64(-7046029254386353131)
_MAX_THRESHOLD = 1 << 16  # BSP nodes per cell (the paper's best: 100-200); the workspace grows with it


class _Bad(Exception):
    """A failed check: the field and what is wrong (turned into a WorkpieceFileError naming the file)."""


def _int(header: dict, key: str, lo: int | None = None) -> int:
    v = header.get(key)
    if not (isinstance(v, int) and not isinstance(v, bool)):
        raise _Bad(f"header field {key!r} must be an integer, got {v!r}")
    if lo is not None and v < lo:
        raise _Bad(f"header field {key!r} must be >= {lo}, got {v}")
    return v


def _int_string(header: dict, key: str) -> int:
    v = header.get(key)
    if not (isinstance(v, str) and re.fullmatch(r"[0-9]{1,100}", v)):
        raise _Bad(f"header field {key!r} must be a decimal integer string, got {v!r}")
    return int(v)


def _array(arrays: dict, name: str, dtype, shape: tuple) -> np.ndarray:
    a = arrays[name]
    if a.dtype != np.dtype(dtype):
        raise _Bad(f"array {name!r} has dtype {a.dtype}, expected {np.dtype(dtype)}")
    if a.ndim != len(shape) or any(s is not None and a.shape[i] != s for i, s in enumerate(shape)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise _Bad(f"array {name!r} has shape {a.shape}, expected {want}")
    return a


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def check_workpiece(path, header: dict, arrays: dict[str, np.ndarray]) -> dict:
    """Check that ``header`` and ``arrays`` (as :func:`read_arrays` returns them) form a valid workpiece.

    Returns the parsed parameters (``grid``, ``threshold``, ``min_cell``, ``max_tool_polygons``, ``seed``,
    ``root_lo``, ``root_size``, ``max_normal``, ``max_offset``). Raises :class:`WorkpieceFileError` naming the
    field that is wrong. Vectorised: a workpiece of 10^5 octree nodes is checked in a fraction of a second.
    """
    try:
        return _check(header, arrays)
    except _Bad as exc:
        raise WorkpieceFileError(f"{path} is not a valid workpiece: {exc}") from None


def _check(header: dict, arrays: dict[str, np.ndarray]) -> dict:  # noqa: C901 (one list of checks)
    from csgnb.exact.budgets import budget, check_planes
    from csgnb.exact.quantization import Grid
    from csgnb.exact.wide import WIDTHS, wide_dtype
    from csgnb.octree.layout import (
        BSP,
        N_AXIS,
        N_COUNTS,
        N_FREE_BLOCKS,
        N_NODES,
        N_PAL,
        N_POOL,
        POOL_LIVE,
        S_BOUNDARY_SHORTCUTS,
        UNIFORM,
    )

    # -- header ---------------------------------------------------------------------
    missing = sorted(HEADER_FIELDS - header.keys())
    if missing:
        raise _Bad(f"the header lacks the field(s) {', '.join(missing)}")
    unknown = sorted(header.keys() - HEADER_FIELDS - OPTIONAL_HEADER_FIELDS)
    if unknown:
        raise _Bad(f"the header has unknown field(s) {', '.join(unknown)}")
    width = _int(header, "width")
    if width not in WIDTHS:
        raise _Bad(f"header field 'width' must be one of {WIDTHS}, got {width}")
    origin = header["origin"]
    if not (isinstance(origin, list) and len(origin) == 3
            and all(isinstance(x, int | float) and not isinstance(x, bool) for x in origin)):
        raise _Bad(f"header field 'origin' must be a list of 3 numbers, got {origin!r}")
    try:
        grid = Grid(exponent=_int(header, "exponent"), origin=[float(x) for x in origin], width=width,
                    max_coordinate=_int(header, "max_coordinate"))
    except (CsgnbError, TypeError) as exc:
        raise _Bad(f"the header's grid is invalid: {exc}") from None
    threshold = _int(header, "threshold", 8)
    if threshold > _MAX_THRESHOLD:
        raise _Bad(f"header field 'threshold' = {threshold} is beyond {_MAX_THRESHOLD} (the workspace is sized by it)")
    min_cell = _int(header, "min_cell", 1)
    if min_cell & (min_cell - 1):
        raise _Bad(f"header field 'min_cell' must be a power of two, got {min_cell}")
    max_tool_polygons = _int(header, "max_tool_polygons", 1)
    seed = _int(header, "seed")
    if not -(1 << 62) <= seed < 1 << 62:
        raise _Bad(f"header field 'seed' is out of range: {seed}")
    half = 1 << max(int(grid.max_coordinate), 1).bit_length()
    root_lo = header["root_lo"]
    if root_lo != [-half] * 3:
        raise _Bad(f"header field 'root_lo' must be {[-half] * 3} on this grid (max_coordinate "
                   f"{grid.max_coordinate}), got {root_lo!r}")
    root_size = _int(header, "root_size")
    if root_size != 2 * half:
        raise _Bad(f"header field 'root_size' must be {2 * half} on this grid (max_coordinate "
                   f"{grid.max_coordinate}), got {root_size}")
    max_normal, max_offset = _int_string(header, "max_normal"), _int_string(header, "max_offset")
    if max_normal < 1 or max_offset < root_size:
        raise _Bad(f"header fields 'max_normal' ({max_normal}) and 'max_offset' ({max_offset}) must be >= 1 and >= "
                   f"the root size {root_size}")
    problems = budget(width).plane_violations(max_normal, max_offset)
    if problems:
        raise _Bad(f"header fields 'max_normal' and 'max_offset' break the {width}-bit budget: {'; '.join(problems)}")
    if "applied" in header:
        from csgnb.octree.workpiece import APPLIED_MEMO

        ap = header["applied"]
        if not (isinstance(ap, list) and 0 < len(ap) <= APPLIED_MEMO and len(set(ap)) == len(ap)
                and all(isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v) for v in ap)):
            raise _Bad(f"header field 'applied' must list 1 to {APPLIED_MEMO} distinct digests of applied differences")
    if "completed" in header:
        _int(header, "completed", 0)
    if "checkpoint" in header:
        ck = header["checkpoint"]
        if not (isinstance(ck, dict) and set(ck) == {"start", "tools", "op"}
                and all(isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v) for v in ck.values())):
            raise _Bad(f"header field 'checkpoint' must hold the digests 'start', 'tools' and 'op', got {ck!r}")
        if "completed" not in header:
            raise _Bad("header field 'checkpoint' needs the field 'completed'")

    # -- arrays: names, dtypes, shapes -----------------------------------------------------
    if "boundary_cache" in header and header["boundary_cache"] not in ("off", "waiting", "on"):
        raise _Bad(f"header field 'boundary_cache' must be 'off', 'waiting' or 'on', got {header['boundary_cache']!r}")
    names = set(arrays)
    has_pieces = bool(names & PIECE_ARRAY_NAMES)
    if has_pieces and not PIECE_ARRAY_NAMES <= names:
        raise _Bad("the file lacks " + ", ".join(sorted(PIECE_ARRAY_NAMES - names)) + " (the boundary cache's arrays "
                   "come together)")
    names -= PIECE_ARRAY_NAMES
    if names != ARRAY_NAMES:
        parts = []
        if ARRAY_NAMES - names:
            parts.append("lacks " + ", ".join(sorted(ARRAY_NAMES - names)))
        if names - ARRAY_NAMES:
            parts.append("has unknown " + ", ".join(sorted(names - ARRAY_NAMES)))
        raise _Bad("the file " + " and ".join(parts))
    counts = _array(arrays, "oc_counts", np.int64, (N_COUNTS,))
    if np.any(counts < 0):
        raise _Bad(f"array 'oc_counts' has a negative entry at {_first(counts < 0)}")
    if np.any(counts[S_BOUNDARY_SHORTCUTS + 1:] != 0):
        raise _Bad("array 'oc_counts' has entries in its unused tail")
    n = int(counts[N_NODES])
    oc = {k: _array(arrays, f"oc_{k}", dt, (n, 3) if k == "lo" else (n,)) for k, dt in _OC_DTYPES.items()}
    if n < 1 or n % 8 != 1:
        raise _Bad(f"oc_counts[N_NODES] = {n}: the octree has 1 + 8k nodes")
    n_free = int(counts[N_FREE_BLOCKS])
    free = _array(arrays, "oc_free_blocks", np.int32, (n_free,))
    m = int(counts[N_POOL])
    pool = {k: _array(arrays, f"pool_{k}", np.int32, (m,)) for k in _POOL_NAMES}
    if int(counts[POOL_LIVE]) != m:
        raise _Bad(f"oc_counts[POOL_LIVE] = {int(counts[POOL_LIVE])} must equal oc_counts[N_POOL] = {m} "
                   "(a saved pool is compact)")
    p = int(counts[N_PAL])
    limbs = _array(arrays, "palette_limbs", np.uint64, (p, 4, width // 64))
    keys = arrays["axis_keys"]
    _array(arrays, "axis_keys", np.int64, (None,))
    h = keys.shape[0]
    if h < 16 or h & (h - 1):
        raise _Bad(f"array 'axis_keys' must have a power-of-two length >= 16, got {h}")
    rows = _array(arrays, "axis_rows", np.int32, (h,))

    # -- the octree: a tree of octants from the root ------------------------------------------
    child, parent, kind, label = oc["child"], oc["parent"], oc["kind"], oc["label"]
    start, length, lo, size = oc["start"], oc["length"], oc["lo"], oc["size"]
    if parent[0] != -1 or np.any(lo[0] != -half) or size[0] != root_size:
        raise _Bad(f"octree node 0 (the root) must have parent -1 and the box {[-half] * 3} + {root_size}, got "
                   f"parent {int(parent[0])}, lo {lo[0].tolist()}, size {int(size[0])}")
    if np.any((kind != UNIFORM) & (kind != BSP)):
        i = _first((kind != UNIFORM) & (kind != BSP))
        raise _Bad(f"oc_kind[{i}] = {int(kind[i])} (0 uniform or 1 BSP)")
    n_blocks = (n - 1) // 8
    block_seen = np.zeros(n_blocks, bool)
    reached = np.zeros(n, bool)
    reached[0] = True
    octant = np.array([[k & 1, k >> 1 & 1, k >> 2 & 1] for k in range(8)], np.int64)
    frontier = np.zeros(1, np.int64)
    while frontier.shape[0]:
        c = child[frontier].astype(np.int64)
        bad = (c < -1) | ((c >= 0) & ((c < 1) | (c > n - 8) | ((c - 1) % 8 != 0)))
        if np.any(bad):
            i = int(frontier[_first(bad)])
            raise _Bad(f"oc_child[{i}] = {int(child[i])} is not -1 or the first of a block of 8 nodes (1 + 8k < {n})")
        inner = frontier[c >= 0]
        c = c[c >= 0]
        if not inner.shape[0]:
            break
        blocks = (c - 1) // 8
        if np.any(block_seen[blocks]) or np.unique(blocks).shape[0] != blocks.shape[0]:
            i = int(inner[_first(block_seen[blocks])]) if np.any(block_seen[blocks]) else int(inner[0])
            raise _Bad(f"oc_child: the children block of octree node {i} is shared with another node")
        block_seen[blocks] = True
        if np.any(size[inner] < 2):
            i = int(inner[_first(size[inner] < 2)])
            raise _Bad(f"oc_size[{i}] = {int(size[i])}: a cell of size 1 cannot have children")
        kids = (c[:, None] + np.arange(8)).reshape(-1)
        owner = np.repeat(inner, 8)
        if np.any(parent[kids] != owner):
            i = int(kids[_first(parent[kids] != owner)])
            raise _Bad(f"oc_parent[{i}] = {int(parent[i])}, but node {i} is a child of {int(owner[i == kids][0])}")
        halfsize = size[owner] // 2
        if np.any(size[kids] != halfsize):
            i = int(kids[_first(size[kids] != halfsize)])
            raise _Bad(f"oc_size[{i}] = {int(size[i])}, but its parent's size is {int(size[parent[i]])}: a child is "
                       "half its parent")
        want = lo[owner] + halfsize[:, None] * np.tile(octant, (inner.shape[0], 1))
        wrong = np.any(lo[kids] != want, axis=1)
        if np.any(wrong):
            j = _first(wrong)
            raise _Bad(f"oc_lo[{int(kids[j])}] = {lo[kids[j]].tolist()}, but it is octant {j % 8} of node "
                       f"{int(owner[j])}: expected {want[j].tolist()}")
        reached[kids] = True
        frontier = kids
    if np.any((free < 0) | (free >= n_blocks)):
        raise _Bad(f"oc_free_blocks[{_first((free < 0) | (free >= n_blocks))}] is not a block index in "
                   f"[0, {n_blocks})")
    if np.unique(free).shape[0] != n_free or np.any(block_seen[free]):
        raise _Bad("oc_free_blocks lists a block twice or a block in use")
    if n_free + int(block_seen.sum()) != n_blocks:
        i = 1 + 8 * _first(~block_seen & ~np.isin(np.arange(n_blocks), free))
        raise _Bad(f"octree node {i} is neither reachable from the root nor in a free block")
    leaf = reached & (child == -1)
    inner = reached & (child >= 0)
    dead = ~reached
    for name, arr, value in (("child", child, -1), ("parent", parent, -1), ("kind", kind, 0), ("label", label, 0),
                             ("start", start, 0), ("length", length, 0), ("size", size, 0)):
        if np.any(dead & (arr != value)):
            raise _Bad(f"oc_{name}[{_first(dead & (arr != value))}] of a free node must be {value}")
    if np.any(dead[:, None] & (lo != 0)):
        raise _Bad(f"oc_lo[{_first(dead & np.any(lo != 0, axis=1))}] of a free node must be 0")
    for name, arr in (("kind", kind), ("label", label), ("start", start), ("length", length)):
        if np.any(inner & (arr != 0)):
            raise _Bad(f"oc_{name}[{_first(inner & (arr != 0))}] of an inner octree node must be 0")
    uniform = leaf & (kind == UNIFORM)
    bsp = leaf & (kind == BSP)
    if np.any(uniform & ((label < 0) | (label > 1))):
        i = _first(uniform & ((label < 0) | (label > 1)))
        raise _Bad(f"oc_label[{i}] = {int(label[i])}: a uniform cell is 0 (out) or 1 (in)")
    if np.any(uniform & ((start != 0) | (length != 0))):
        raise _Bad(f"oc_start / oc_length of uniform cell {_first(uniform & ((start != 0) | (length != 0)))} "
                   "must be 0")
    if np.any(bsp & ((length < 1) | (length > m))):
        i = _first(bsp & ((length < 1) | (length > m)))
        raise _Bad(f"oc_length[{i}] = {int(length[i])}: a BSP cell has 1 .. {m} (the pool's size) nodes")
    if np.any(bsp & (label != 0)):
        raise _Bad(f"oc_label[{_first(bsp & (label != 0))}] of a BSP cell must be 0")
    over = bsp & (length > threshold) & (size > min_cell)
    if np.any(over):
        i = _first(over)
        raise _Bad(f"oc_length[{i}] = {int(length[i])} is above the threshold {threshold} in a cell of size "
                   f"{int(size[i])} > min_cell {min_cell} (it would have been split): the threshold or the cell is "
                   "wrong")

    # -- the pool: the BSP cells' trees, back to back in node order ------------------------------------
    cells = np.flatnonzero(bsp)
    lens = length[cells].astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]]) if cells.shape[0] else np.zeros(0, np.int64)
    if np.any(start[cells] != starts):
        j = _first(start[cells] != starts)
        raise _Bad(f"oc_start[{int(cells[j])}] = {int(start[cells[j]])}, expected {int(starts[j])} (a saved pool "
                   "holds the cells' BSPs back to back in node order)")
    if int(lens.sum()) != m:
        raise _Bad(f"the BSP cells hold {int(lens.sum())} nodes but the pool has {m} (oc_counts[N_POOL])")
    base = np.repeat(starts, lens)
    seg_len = np.repeat(lens, lens)
    rel = np.arange(m, dtype=np.int64) - base
    plane, neg, pos, plabel = pool["plane"], pool["neg"], pool["pos"], pool["label"]
    is_inner = plane >= 0
    if np.any(is_inner & (plane >= p)):
        i = _first(is_inner & (plane >= p))
        raise _Bad(f"pool_plane[{i}] = {int(plane[i])} is beyond the palette ({p} planes)")
    is_leaf = ~is_inner
    if np.any(is_leaf & (plane != -1)):
        raise _Bad(f"pool_plane[{_first(is_leaf & (plane != -1))}] must be a palette row or -1 (a leaf)")
    for name, arr in (("neg", neg), ("pos", pos)):
        badc = is_inner & ((arr < 1) | (arr >= seg_len))
        if np.any(badc):
            i = _first(badc)
            raise _Bad(f"pool_{name}[{i}] = {int(arr[i])} is not a node 1 .. {int(seg_len[i]) - 1} of its cell's BSP")
        if np.any(is_leaf & (arr != -1)):
            raise _Bad(f"pool_{name}[{_first(is_leaf & (arr != -1))}] of a leaf must be -1")
    if np.any(is_inner & (plabel != -1)):
        raise _Bad(f"pool_label[{_first(is_inner & (plabel != -1))}] of an inner BSP node must be -1")
    if np.any(is_leaf & ((plabel < 0) | (plabel > 1))):
        i = _first(is_leaf & ((plabel < 0) | (plabel > 1)))
        raise _Bad(f"pool_label[{i}] = {int(plabel[i])}: a BSP leaf is 0 (out) or 1 (in)")
    targets = np.concatenate([base[is_inner] + neg[is_inner], base[is_inner] + pos[is_inner]])
    indegree = np.bincount(targets, minlength=m) if m else np.zeros(0, np.int64)
    wrong = indegree != (rel != 0)
    if np.any(wrong):
        i = _first(wrong)
        raise _Bad(f"BSP pool node {i} (node {int(rel[i])} of its cell's BSP) has {int(indegree[i])} parents: the "
                   "nodes of a cell's BSP must form a tree from its first node")
    # one parent each is a tree unless some nodes form a cycle apart from the root: climb (doubling) to the roots
    inner_rows = np.flatnonzero(is_inner)
    up = np.arange(m, dtype=np.int64)
    up[targets] = np.concatenate([inner_rows, inner_rows])
    for _ in range(int(lens.max(initial=1)).bit_length() + 1):
        up = up[up]
    cyc = rel[up] != 0
    if np.any(cyc):
        i = _first(cyc)
        raise _Bad(f"BSP pool node {i} (node {int(rel[i])} of its cell's BSP) lies on a cycle: the nodes of a cell's "
                   "BSP must form a tree from its first node")

    if has_pieces:
        _check_pieces(arrays, n, bsp, p)

    # -- the palette and the wall-plane map -----------------------------------------------------
    palette = np.zeros((p, 4), wide_dtype(width))
    palette["limbs"] = limbs
    if p:
        try:
            check_planes(palette, "the palette")
        except CsgnbError as exc:
            raise _Bad(f"array 'palette_limbs': {exc}") from None
        N, D = _max_magnitude(limbs[:, :3]), _max_magnitude(limbs[:, 3:])
        if N > max_normal or D > max_offset:
            raise _Bad(f"the palette's planes (max |normal| {N}, max |offset| {D}) exceed the header's "
                       f"'max_normal' {max_normal} / 'max_offset' {max_offset}")
    used = keys != -1
    n_axis = int(used.sum())
    if n_axis != int(counts[N_AXIS]):
        raise _Bad(f"oc_counts[N_AXIS] = {int(counts[N_AXIS])} but 'axis_keys' holds {n_axis} keys")
    if 2 * n_axis > h:
        raise _Bad(f"'axis_keys' is more than half full ({n_axis} of {h})")
    if np.any(~used & (rows != 0)):
        raise _Bad(f"axis_rows[{_first(~used & (rows != 0))}] of an empty slot must be 0")
    k = keys[used]
    code = k >> 58
    coord = (k & ((1 << 58) - 1)) - (1 << 56)
    badk = (k < 0) | (code > 5) | (coord < -half) | (coord > half)
    if np.any(badk):
        i = int(np.flatnonzero(used)[_first(badk)])
        raise _Bad(f"axis_keys[{i}] = {int(keys[i])} is not a wall of the root box")
    if np.unique(k).shape[0] != n_axis:
        raise _Bad("'axis_keys' holds a key twice")
    r = rows[used].astype(np.int64)
    if np.any((r < 0) | (r >= p)):
        i = int(np.flatnonzero(used)[_first((r < 0) | (r >= p))])
        raise _Bad(f"axis_rows[{i}] = {int(rows[i])} is beyond the palette ({p} planes)")
    axis, side = code // 2, code % 2
    expect = np.zeros((n_axis, 4), np.int64)
    expect[np.arange(n_axis), axis] = np.where(side == 0, -1, 1)
    expect[:, 3] = np.where(side == 0, coord, -coord)
    want_limbs = np.repeat(np.where(expect < 0, np.uint64(0xFFFFFFFFFFFFFFFF), np.uint64(0))[:, :, None],
                           width // 64, axis=2)
    want_limbs[:, :, 0] = expect.view(np.uint64)
    wrong = np.any(limbs[r] != want_limbs, axis=(1, 2))
    if np.any(wrong):
        i = int(np.flatnonzero(used)[_first(wrong)])
        raise _Bad(f"axis_rows[{i}] = {int(rows[i])}: that palette row is not the wall plane of key {int(keys[i])}")
    # every key must be found by the kernel's linear probing from its hash (no empty slot on the way)
    with np.errstate(over="ignore"):
        home = ((k * _AXIS_MULTIPLIER) >> 20) & (h - 1)
    at = np.flatnonzero(used)
    dist = (at - home) & (h - 1)
    empty_before = np.concatenate([[0], np.cumsum(np.concatenate([~used, ~used]))])
    lost = empty_before[home + dist] - empty_before[home] != 0
    if np.any(lost):
        raise _Bad(f"axis_keys[{int(at[_first(lost)])}] is not where the hash map's probing finds it")
    return {"grid": grid, "threshold": threshold, "min_cell": min_cell, "max_tool_polygons": max_tool_polygons,
            "seed": seed, "root_lo": np.array(root_lo, np.int64), "root_size": root_size, "max_normal": max_normal,
            "max_offset": max_offset}


def _check_pieces(arrays: dict, n: int, bsp: np.ndarray, p: int) -> None:
    """The boundary cache's arrays: entries only at BSP cells, back to back in node order, each a run of pieces
    (a signed support row, then ``k >= 3`` edge rows of the palette; ``pieces_size`` holds k at the support, 0 at
    the edges). That the pieces bound the cell's solid is not checked here (the file's checksum guards it)."""
    plen = _array(arrays, "oc_pieces", np.int32, (n,))
    if np.any(plen < 0) or np.any(~bsp & (plen != 0)):
        i = _first((plen < 0) | (~bsp & (plen != 0)))
        raise _Bad(f"oc_pieces[{i}] = {int(plen[i])}: only a BSP cell has boundary pieces (a count of rows >= 0)")
    total = int(plen.astype(np.int64).sum())
    rows = _array(arrays, "pieces_rows", np.int32, (total,))
    size = _array(arrays, "pieces_size", np.int32, (total,))
    if total == 0:
        return
    supports = np.flatnonzero(size != 0)
    k = size[supports].astype(np.int64)
    ends = supports + k + 1
    if np.any(size < 0) or supports.shape[0] == 0 or supports[0] != 0 or np.any(k < 3) or ends[-1] != total or \
            np.any(ends[:-1] != supports[1:]):
        raise _Bad("'pieces_size' is not a run of pieces (k >= 3 at each support row, 0 at its k edge rows)")
    cell_starts = np.concatenate([[0], np.cumsum(plen[plen > 0].astype(np.int64))[:-1]])
    if not np.all(np.isin(cell_starts, supports)):
        raise _Bad("'oc_pieces' splits a piece between two cells")
    edge = np.ones(total, bool)
    edge[supports] = False
    r = rows.astype(np.int64)
    if np.any(edge & ((r < 0) | (r >= p))) or np.any(~edge & ((r < -p) | (r >= p))):
        i = _first((edge & ((r < 0) | (r >= p))) | (~edge & ((r < -p) | (r >= p))))
        raise _Bad(f"pieces_rows[{i}] = {int(rows[i])} is not a plane of the palette ({p} planes)")


def _max_magnitude(limbs: np.ndarray) -> int:
    """The largest ``|x|`` of the two's complement integers stored as little-endian uint64 limbs ``(..., L)``,
    exactly: negatives are negated limb by limb (with carries), the magnitudes compared from the top limb."""
    flat = np.ascontiguousarray(limbs).reshape(-1, limbs.shape[-1])
    if flat.shape[0] == 0:
        return 0
    negative = (flat[:, -1] >> np.uint64(63)).astype(bool)
    mag = np.where(negative[:, None], ~flat, flat)
    carry = negative.astype(np.uint64)
    for k in range(mag.shape[1]):  # + 1 for the negated rows
        total = mag[:, k] + carry
        carry = (carry.astype(bool) & (total == 0)).astype(np.uint64)
        mag[:, k] = total
    best = int(np.lexsort(mag.T)[-1])  # lexsort's last key is the primary one: the top limb
    return int.from_bytes(mag[best].astype("<u8").tobytes(), "little")
