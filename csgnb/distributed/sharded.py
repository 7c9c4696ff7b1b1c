"""A workpiece split into spatial shards, each an ordinary :class:`csgnb.octree.Workpiece`, held by Dask actors
or by threads of this process (one workpiece's Booleans on every core).

>>> from csgnb.distributed.sharded import shard_boxes
>>> [(lo.tolist(), hi.tolist()) for lo, hi in shard_boxes([-8, -8, -8], 16, (2, 1, 1))]
[([-8, -8, -8], [0, 8, 8]), ([0, -8, -8], [8, 8, 8])]

The octree's root cube is cut into ``nx x ny x nz`` equal boxes (each count a power of two, so
the cuts lie on octree cell boundaries). Shard ``k`` holds the whole solid as seen from inside
its box ``S_k``: the same start (a box workpiece, or any workpiece given) and every Boolean
whose tool's closed box meets ``S_k`` -- a tool that misses ``S_k`` changes nothing in a
neighbourhood of it (for a label function with ``fn(a, 0) == a``: difference, union; an
intersection goes to every shard) -- applied to the octree cells whose interior meets the
interior of ``S_k`` only (``Workpiece.boolean(..., within=S_k)``; beyond ``S_k`` the shard's
solid is left behind, and nothing is asked of it there). So in the open box ``S_k`` the shard's
solid *is* the solid of one workpiece run through the same sequence, its cells the same cells,
no cell done twice but the few larger than a shard, and

* ``classify(points)`` asks, for each point, every shard whose closed box holds it, each reading
  a point on its walls from its own side (:func:`csgnb.bsp.tree.box_face_sides`); the answers
  agree, or the point is on the boundary: the labels are the single workpiece's, on shard walls too;
* ``volume()`` adds the shards' exact volumes inside their own boxes (``Fraction`` sums; the
  boxes tile the root cube, their common faces have no volume): equal with ``==``;
* a Boolean is sent only to the shards its tool's box meets, and they work in parallel;
* ``surface()`` extracts the boundary of one BSP made of axis planes at the shards' walls over
  each shard's tree (:func:`combine_shard_trees`): walls where solid continues leave no face,
  as cell walls inside one workpiece leave none;
* on Dask, Booleans are queued and sent ``batch`` at a time per shard (one message, one round
  trip), one batch in flight per shard, so the shards work while the caller prepares the next
  tools; in this process (``client=None``) each is handed to its shards' threads at once;
* ``save(folder, step=)`` is a checkpoint: each shard's workpiece (``Workpiece.save``, files
  named by content) and then a manifest, each written atomically; :meth:`ShardedWorkpiece.load`
  starts the actors again from them and gives back ``step``, where the caller's sequence resumes.

Tools are :class:`~csgnb.mesh.hull.ConvexHull`\\ s, :class:`~csgnb.octree.Tool`\\ s or integer
meshes ``(vertices, faces)`` in grid coordinates, as for a workpiece. ``track_volume`` is not
offered: a shard measures nothing outside its box; measure ``volume()`` before and after.

On two cores, ``ShardedWorkpiece(work, None, 2)`` ran the paper's 270-step drill (Figures 13-14) 1.75x faster
than one workpiece (``benchmarks/bench_iterated.py``), the same exact volume; small tools gain less (the Python
set-up of each Boolean holds the GIL).

Known limits: a shard lives on one worker (Dask actors are not moved or retried): a lost worker loses its
shards; the next call raises Dask's error and every later one :class:`ShardFailure` -- ``save``
regularly and :meth:`ShardedWorkpiece.load` to resume. ``volume()`` clips a copy of every shard (a save
and a load each).
"""

from __future__ import annotations

import hashlib
import json
import threading
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.exact.rational import fraction_text, parse_fraction
from csgnb.mesh.volume import sum_fractions

__all__ = ["Shard", "ShardFailure", "ShardedWorkpiece", "combine_shard_trees", "shard_boxes"]

MANIFEST = "shards.json"


def _counts(shards) -> tuple[int, int, int]:
    if isinstance(shards, int | np.integer):
        table = {1: (1, 1, 1), 2: (2, 1, 1), 4: (2, 2, 1), 8: (2, 2, 2), 16: (4, 2, 2), 32: (4, 4, 2), 64: (4, 4, 4)}
        if int(shards) not in table:
            raise ValueError(f"shards={shards!r}: give a power of two up to 64, or counts per axis (nx, ny, nz)")
        return table[int(shards)]
    c = tuple(int(n) for n in shards)
    if len(c) != 3 or any(n < 1 or n & (n - 1) for n in c):
        raise ValueError(f"shards={shards!r}: counts per axis must be three powers of two, e.g. (2, 2, 1)")
    return c


_THREAD_QUEUE = 64  # batches queued per shard thread before the caller waits (bounds the tools held)
WORKER_WAIT_S = 60.0  # how long placing shards waits for a running Dask worker (one may be restarting)


def _running_workers(client, timeout: float | None = None) -> list[str]:
    """The addresses of the scheduler's running workers, asked afresh, waiting up to ``timeout`` seconds
    (default :data:`WORKER_WAIT_S`) for at least one.

    Not ``Client.scheduler_info()``: when its query fails (a connection reset just after a worker died) it
    answers silently from a cache that lists no workers at all.
    """
    timeout = WORKER_WAIT_S if timeout is None else float(timeout)
    deadline = time.monotonic() + timeout
    while True:
        info = client.sync(client.scheduler.identity, n_workers=-1)
        workers = sorted(a for a, ws in info["workers"].items() if ws.get("status", "running") == "running")
        if workers:
            return workers
        if time.monotonic() >= deadline:
            raise ShardFailure(f"the Dask cluster has no running worker to hold the shards (waited {timeout:g} s): "
                               "start workers, or pass client=None to run the shards in threads of this process")
        time.sleep(0.1)


def _default_shards(client) -> int:
    """8 shards on a Dask client; in this process, one per core numba uses (a power of two)."""
    if client is not None:
        return 8
    import numba

    return 1 << (max(1, int(numba.get_num_threads())).bit_length() - 1)


def shard_boxes(root_lo, root_size: int, counts) -> list[tuple[np.ndarray, np.ndarray]]:
    """The shards' boxes ``(lo (3,) int64, hi (3,) int64)``, x fastest: ``counts`` equal parts of the root cube."""
    counts = _counts(counts)
    root_lo = np.asarray(root_lo, np.int64)
    step = np.array([root_size // n for n in counts], np.int64)
    if np.any(step * counts != root_size):
        raise ValueError(f"the root cube (edge {root_size}) does not split into {counts} equal boxes")
    out = []
    for k in range(counts[2]):
        for j in range(counts[1]):
            for i in range(counts[0]):
                lo = root_lo + step * [i, j, k]
                out.append((lo, lo + step))
    return out


_SCRATCH: dict = {}  # (width, threshold) -> the octree kernels' Workspace shared by this process's shards
_SCRATCH_LOCK = threading.Lock()


class Shard:
    """A Dask actor: one :class:`csgnb.octree.Workpiece` and the box it answers for.

    The shards on one worker share one scratch workspace (:class:`csgnb.octree.workspace.Workspace`,
    tens of MB once grown): each workpiece would otherwise keep its own, and a worker holds several
    shards. They take turns (a lock; Dask runs an actor's calls on one thread anyway). What in the
    workspace is a workpiece's own -- its cells' boundary cache and merge statistics -- stays with each
    shard (:func:`csgnb.octree.workspace.sharing_scratch`).
    """

    def __init__(self, lo, hi, workpiece_bytes: bytes) -> None:
        self.lo = np.asarray(lo, np.int64)
        self.hi = np.asarray(hi, np.int64)
        self.w = _from_bytes(workpiece_bytes)
        self.busy_s = 0.0  # time spent applying Booleans (the benchmark's communication overhead is the rest)
        self.applied = 0

    def apply(self, steps: list) -> list[int]:
        """Apply ``[(tool, fn), ...]`` in order; return the cells each touched.

        A step that fails raises :class:`ShardFailure` naming how many of ``steps`` were applied.
        """
        t0 = time.perf_counter()
        cells = []
        with _SCRATCH_LOCK:
            self._take_scratch()
            try:
                self._apply(steps, cells)
            finally:
                _SCRATCH[self._scratch_key] = self.w.ws  # grown, perhaps
                self.applied += len(cells)
                self.busy_s += time.perf_counter() - t0
        return cells

    @property
    def _scratch_key(self) -> tuple[int, int]:
        return self.w.width, self.w.threshold

    def _take_scratch(self) -> None:
        from csgnb.octree.workspace import sharing_scratch

        shared = _SCRATCH.get(self._scratch_key)
        if shared is not None and shared is not self.w.ws:
            # the scratch only: the cells' boundary cache and the merge statistics stay this shard's own
            self.w.ws = sharing_scratch(shared, self.w.ws, self.w.palette)

    def _apply(self, steps: list, cells: list) -> None:
        for i, (tool, fn) in enumerate(steps):
            try:
                # Only the cells whose interior meets this shard's box's interior: the solid is right in the
                # open box; a point on its walls is read from the box's side (classify).
                cells.append(self.w.boolean(tool, fn, within=(self.lo, self.hi)).cells)
            except Exception as exc:
                raise ShardFailure(f"Boolean {self.applied + i} of this shard (box {self.lo.tolist()}.."
                                   f"{self.hi.tolist()}) failed after {i} of the {len(steps)} sent with it: "
                                   f"{type(exc).__name__}: {exc}") from exc

    def boolean(self, tool, fn) -> int:
        """Apply ``fn`` with ``tool``; return the cells touched."""
        return self.apply([(tool, fn)])[0]

    def volume(self) -> str:
        """The exact volume of the solid inside this shard's box (grid units³), as text."""
        from csgnb.bsp.solid import INTERSECTION
        from csgnb.mesh.hull import convex_hull

        # No solid lies outside the grid's budget box (stock and tools are refused there), and the clipping box
        # must stay inside it too.
        limit = int(self.w.grid.max_coordinate)
        lo, hi = np.maximum(self.lo, -limit), np.minimum(self.hi, limit)
        if np.any(lo >= hi):
            return "0"
        clipped = _from_bytes(_to_bytes(self.w))  # a copy: the shard keeps its (stale) solid beyond its box
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                           np.int64)
        clipped.boolean(convex_hull(corners, width=self.w.width), INTERSECTION)
        return fraction_text(clipped.volume())

    def classify(self, points: np.ndarray) -> np.ndarray:
        """Labels of integer grid points ``(n, 3)`` in this shard's closed box, a point on its walls read from
        the box's side only (beyond them the shard's solid is stale)."""
        from csgnb.bsp.tree import box_face_sides
        from csgnb.exact import homogeneous_points

        q = np.asarray(points, np.int64).reshape(-1, 3)
        if q.shape[0] == 0:
            return np.zeros(0, np.int32)
        tree = self.w.global_tree()
        return np.asarray(tree.classify(homogeneous_points(q, self.w.width),
                                        forced_sides=box_face_sides(tree.palette, self.lo, self.hi)))

    def tree(self) -> tuple[np.ndarray, ...]:
        """The shard's whole solid as one BSP: ``(palette, plane, neg, pos, label)`` arrays."""
        t = self.w.global_tree()
        return t.palette, t.plane, t.neg, t.pos, t.label

    def workpiece_bytes(self) -> bytes:
        """The shard's workpiece as ``Workpiece.save`` writes it."""
        return _to_bytes(self.w)

    def n_cells(self) -> int:
        return self.w.n_cells

    def stats(self) -> dict:
        """Time applying Booleans, Booleans applied, cells, BSP nodes, the worker holding this shard."""
        from csgnb.distributed.batch import _worker_address

        return {"busy_s": self.busy_s, "applied": self.applied, "cells": self.w.n_cells,
                "bsp_nodes": self.w.n_bsp_nodes, "worker": _worker_address()}


class _ThreadShard(Shard):
    """A shard of this process on its own thread: its own scratch workspace, no lock (the kernels release the
    GIL, so the shards' Booleans run on every core)."""

    def apply(self, steps: list) -> list[int]:
        t0 = time.perf_counter()
        cells: list = []
        try:
            self._apply(steps, cells)
        finally:
            self.applied += len(cells)
            self.busy_s += time.perf_counter() - t0
        return cells

    def stats(self) -> dict:
        return {"busy_s": self.busy_s, "applied": self.applied, "cells": self.w.n_cells,
                "bsp_nodes": self.w.n_bsp_nodes, "worker": f"thread {threading.current_thread().name}"}


class _ThreadActor:
    """What a Dask actor handle offers, for a shard on a thread of this process: each method call is queued
    on the shard's one thread (so its calls run in order) and returns a future."""

    def __init__(self, shard: Shard, name: str) -> None:
        from concurrent.futures import ThreadPoolExecutor

        self._shard = shard
        self._pool = ThreadPoolExecutor(1, thread_name_prefix=name)

    def __getattr__(self, name: str):
        method = getattr(self._shard, name)
        return lambda *args, **kw: self._pool.submit(method, *args, **kw)

    def shutdown(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class ShardFailure(CsgnbError):
    """A shard could not apply a Boolean: the shards no longer hold one solid (load the last checkpoint)."""


def _to_bytes(w) -> bytes:
    import tempfile

    with tempfile.TemporaryDirectory(prefix="csgnb-shard-") as tmp:
        path = Path(tmp) / "shard.wp"
        w.save(path)
        return path.read_bytes()


def _from_bytes(data: bytes):
    import tempfile

    from csgnb.octree import Workpiece

    with tempfile.TemporaryDirectory(prefix="csgnb-shard-") as tmp:
        path = Path(tmp) / "shard.wp"
        path.write_bytes(data)
        return Workpiece.load(path)


def _tool(tool, w):
    """``tool`` as a :class:`csgnb.octree.Tool` (its box routes it to the shards)."""
    from csgnb.mesh.hull import ConvexHull
    from csgnb.octree import Tool

    if isinstance(tool, Tool):
        return tool
    if isinstance(tool, ConvexHull):
        return Tool.from_hull(tool)
    if isinstance(tool, tuple) and len(tool) == 2:
        V = np.asarray(tool[0])
        if V.dtype.kind not in "iu":
            raise TypeError("a tool mesh must have integer grid coordinates; quantize it with the workpiece's grid "
                            "first (w.grid.to_grid(vertices))")
        return Tool.from_mesh(V.astype(np.int64), np.asarray(tool[1], np.int64), width=w.width, grid=w.grid)
    raise TypeError(f"a sharded workpiece takes a ConvexHull, a csgnb.octree.Tool or (vertices, faces), "
                    f"got {type(tool).__name__}")


class ShardedWorkpiece:
    """A :class:`csgnb.octree.Workpiece` cut into ``shards`` spatial shards (module docstring), held by Dask
    actors or by threads of this process.

    Parameters
    ----------
    workpiece : Workpiece
        The start (e.g. ``Workpiece.box(...)``); every shard gets a copy.
    client : distributed.Client or None
        The actors are placed round-robin on its workers. ``None``: the shards live in this process,
        each on its own thread -- the octree kernels release the GIL, so one workpiece's Booleans
        run on every core (the cells a Boolean touches are split by the shards' boxes).
    shards : int or (3,) int, optional
        1, 2, 4, 8, ... shards, or counts per axis (powers of two). Default: 8 on a client; in this
        process one per core numba uses (a power of two, split along x first).
    batch : int, optional
        On a client: Booleans queued per shard before they are sent in one message (default 32): a
        shard works on one batch while the next is queued, and a message's round trip is paid once
        per batch, not per Boolean. ``batch=1`` sends every Boolean at once and waits for it. Queued
        Booleans are sent by :meth:`flush`, which every query (``volume``, ``classify``, ``surface``,
        ``save``) calls. In this process (default 1): Booleans handed to a shard's thread at once, the
        caller going on while they run; at most 64 batches wait per shard.
    """

    def __init__(self, workpiece, client=None, shards=None, *, batch: int | None = None) -> None:
        from csgnb.octree import Workpiece

        if not isinstance(workpiece, Workpiece):
            raise TypeError(f"workpiece must be a csgnb.octree.Workpiece, got {type(workpiece).__name__}")
        counts = _counts(_default_shards(client) if shards is None else shards)
        self._start(client, workpiece, counts, [_to_bytes(workpiece)] * int(np.prod(counts)), batch)

    def _start(self, client, template, counts, blobs: list[bytes], batch: int | None) -> None:
        if client is not None:
            from distributed import Client

            if not isinstance(client, Client):
                raise TypeError(f"client must be a distributed.Client or None (threads of this process), "
                                f"got {type(client).__name__}")
        if batch is None:
            batch = 32 if client is not None else 1
        if int(batch) != batch or batch < 1:
            raise ValueError(f"batch must be a positive integer (Booleans per message), got {batch!r}")
        self.client = client
        self.batch = int(batch)
        self.grid, self.width = template.grid, template.width
        self.template = template  # the tool conversions' grid and width; holds no solid of interest
        self.root_lo, self.root_size = np.asarray(template.root_lo, np.int64), int(template.root_size)
        self.counts = counts
        self.boxes = shard_boxes(template.root_lo, template.root_size, counts)
        if client is None:
            self.actors = [_ThreadActor(_ThreadShard(lo, hi, blob), f"csgnb-shard-{k}")
                           for k, ((lo, hi), blob) in enumerate(zip(self.boxes, blobs, strict=True))]
        else:
            workers = _running_workers(client)
            futures = [client.submit(Shard, lo, hi, blob, actor=True, workers=[workers[k % len(workers)]],
                                     allow_other_workers=False)
                       for k, ((lo, hi), blob) in enumerate(zip(self.boxes, blobs, strict=True))]
            self.actors = [f.result() for f in futures]
        self.messages = 0  # Booleans routed (one per shard reached)
        self.calls = 0  # messages sent to the shards' actors with Booleans
        self.step: int | None = None  # the caller's step count stored by the checkpoint this was loaded from
        self._pending: list[list] = [[] for _ in self.actors]
        self._inflight: list[list] = [[] for _ in self.actors]
        self._broken: str | None = None

    @property
    def n_shards(self) -> int:
        return len(self.actors)

    def shards_meeting(self, lo, hi) -> list[int]:
        """The shards whose closed box meets the closed box ``[lo, hi]``."""
        lo, hi = np.asarray(lo, np.int64), np.asarray(hi, np.int64)
        return [k for k, (a, b) in enumerate(self.boxes) if np.all(a <= hi) and np.all(lo <= b)]

    def _check_usable(self) -> None:
        if self._broken is not None:
            raise ShardFailure(f"this sharded workpiece is inconsistent since a shard failed ({self._broken}); "
                               "load the last checkpoint (ShardedWorkpiece.load) and go on from its step")

    def boolean(self, tool, fn) -> list[int]:
        """Apply ``fn(workpiece label, tool label)`` with ``tool`` on the shards it can change; return their indices.

        The tool is checked and converted here (a bad tool raises at once); the Boolean is queued and
        sent with the next batch (see ``batch``).
        """
        from csgnb.bsp.merging import merge_table

        self._check_usable()
        t = _tool(tool, self.template)
        table = merge_table(fn, [0, 1], [0, 1])
        if int(table.max()) > 1:  # refused here, before any shard applies it (the shards would each refuse it)
            raise GeometryError("the octree workpiece holds one material (labels 0 and 1); the label function "
                                f"returned {int(table.max())}")
        if all(int(table[a, 0]) == a for a in (0, 1)):
            targets = [] if t.kind == "empty" else self.shards_meeting(t.lo, t.hi)
        else:
            targets = list(range(self.n_shards))
        for k in targets:
            self._pending[k].append((t, fn))
            if len(self._pending[k]) >= self.batch:
                self._send(k)
        self.messages += len(targets)
        if self.batch == 1 and self.client is not None:
            self.flush()
        return targets

    def _send(self, k: int) -> None:
        # On Dask, one batch in flight per shard: an actor's calls are not ordered among themselves, its batches
        # must be. A shard's thread runs its calls in order: up to _THREAD_QUEUE batches wait for it.
        limit = 1 if self.client is not None else _THREAD_QUEUE
        while len(self._inflight[k]) >= limit:
            self._wait_oldest(k)
        steps, self._pending[k] = self._pending[k], []
        self._inflight[k].append(self.actors[k].apply(steps))
        self.calls += 1

    def _wait(self, k: int) -> None:
        while self._inflight[k]:
            self._wait_oldest(k)

    def _wait_oldest(self, k: int) -> None:
        future = self._inflight[k].pop(0)
        try:
            future.result()
        except ShardFailure as exc:
            self._broken = f"shard {k}: {exc}"
            raise ShardFailure(f"shard {k}: {exc}; the shards no longer hold one solid: load the last "
                               "checkpoint (ShardedWorkpiece.load) and go on from its step") from exc
        except Exception:
            self._broken = f"shard {k} was lost (its worker died?)"
            raise

    def flush(self) -> None:
        """Send every queued Boolean and wait until every shard has applied them."""
        self._check_usable()
        for k in range(self.n_shards):
            if self._pending[k]:
                self._send(k)
        for k in range(self.n_shards):
            self._wait(k)

    def difference(self, tool) -> list[int]:
        """Subtract ``tool``; return the shards it reached."""
        from csgnb.bsp.solid import DIFFERENCE

        return self.boolean(tool, DIFFERENCE)

    def union(self, tool) -> list[int]:
        """Add ``tool``; return the shards it reached."""
        from csgnb.bsp.solid import UNION

        return self.boolean(tool, UNION)

    def intersection(self, tool) -> list[int]:
        """Keep only what lies in ``tool`` (sent to every shard)."""
        from csgnb.bsp.solid import INTERSECTION

        return self.boolean(tool, INTERSECTION)

    def volume(self) -> Fraction:
        """Exact volume (grid units³): the shards' volumes inside their boxes, gathered and added."""
        self.flush()
        calls = [a.volume() for a in self.actors]
        return sum_fractions(parse_fraction(c.result()) for c in calls)

    def model_volume(self) -> Fraction:
        """Exact volume in model units cubed."""
        return self.grid.model_volume(self.volume())

    def classify(self, points) -> np.ndarray:
        """Labels of integer grid points ``(n, 3)`` (-2: on the boundary), each asked of a shard whose box holds it."""
        from csgnb.exact.integral import integer_array

        self.flush()
        q = integer_array(points, "points")
        if q.ndim != 2 or q.shape[1] != 3:
            raise GeometryError(f"points must be integer grid points (n, 3), got shape {q.shape}")
        # Each point is read by every shard whose closed box holds it, from that box's side (a shard's solid is
        # right in its open box only); on a wall the answers of both sides agree, or the point is on the boundary.
        out = np.full(len(q), -3, np.int64)  # -3: no shard asked yet
        calls = {}
        for k, (lo, hi) in enumerate(self.boxes):
            mine = np.flatnonzero(np.all((q >= lo) & (q <= hi), axis=1))
            if mine.shape[0]:
                calls[k] = (mine, self.actors[k].classify(q[mine]))
        for mine, c in calls.values():
            got = np.asarray(c.result(), np.int64)
            seen = out[mine]
            out[mine] = np.where(seen == -3, got, np.where(seen == got, got, -2))
        if np.any(out == -3):
            raise GeometryError("points outside the octree's root box: "
                                f"{q[out == -3][:3].tolist()} (the grid's budget box holds every solid)")
        return out

    def global_tree(self):
        """The whole solid as one :class:`csgnb.bsp.BSPTree`: axis splits at the shards' walls, each shard's tree
        in its box (:func:`combine_shard_trees`)."""
        self.flush()
        calls = [a.tree() for a in self.actors]
        return combine_shard_trees([c.result() for c in calls], self.boxes, self.counts)

    def surface(self):
        """The exact, closed boundary (:class:`csgnb.bsp.surface.BoundarySurface`), shard walls removed where
        solid continues across them -- as a single workpiece removes its cell walls."""
        from csgnb.bsp.extract import extract_boundary

        tree = self.global_tree()
        return extract_boundary(tree, self.root_lo, self.root_lo + self.root_size, keep_cells=False).surface

    def stats(self) -> list[dict]:
        """Per shard: time spent applying Booleans, Booleans applied, cells, BSP nodes, worker address."""
        self.flush()
        calls = [a.stats() for a in self.actors]
        return [c.result() for c in calls]

    def save(self, folder, *, step: int | None = None) -> Path:
        """Write a checkpoint into ``folder``: every shard's workpiece, then the manifest (``shards.json``).

        Shard files are named by their content's SHA-256 and written atomically; the manifest is
        replaced atomically after them and names the files it needs, and only then are files of an
        older checkpoint removed. A crash at any point leaves the previous checkpoint or the new one
        whole. ``step`` (e.g. how many Booleans of a sequence are applied) is stored with it and comes
        back as :attr:`step` from :meth:`load`, to resume the sequence there.
        """
        from csgnb._files import write_atomic

        self.flush()
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        calls = [a.workpiece_bytes() for a in self.actors]
        entries = []
        for k, c in enumerate(calls):
            data = c.result()
            digest = hashlib.sha256(data).hexdigest()
            name = f"shard-{k:03d}-{digest[:16]}.wp"
            write_atomic(folder / name, data)
            entries.append({"file": name, "sha256": digest})
        manifest = {"format": 2, "counts": list(self.counts), "step": None if step is None else int(step),
                    "shards": entries}
        write_atomic(folder / MANIFEST, json.dumps(manifest, indent=1).encode())
        keep = {e["file"] for e in entries}
        for old in folder.glob("shard-*.wp"):
            if old.name not in keep:
                old.unlink(missing_ok=True)
        self.step = manifest["step"]
        return folder

    @classmethod
    def load(cls, folder, client=None, *, batch: int | None = None) -> ShardedWorkpiece:
        """The sharded workpiece checkpointed in ``folder`` (its :attr:`step` as saved), actors on ``client``'s
        workers (``None``: threads of this process)."""
        folder = Path(folder)
        path = folder / MANIFEST
        if not path.is_file():
            raise ValueError(f"{folder} holds no sharded workpiece: {MANIFEST} is missing")
        manifest = json.loads(path.read_text())
        if manifest.get("format") not in (1, 2):
            raise ValueError(f"{path}: unknown format {manifest.get('format')!r} (this csgnb reads 1 and 2)")
        blobs = []
        for e in manifest["shards"]:
            file = folder / e["file"]
            data = file.read_bytes() if file.is_file() else b""
            if hashlib.sha256(data).hexdigest() != e["sha256"]:
                raise ValueError(f"{file} does not match the manifest (damaged, replaced or missing)")
            blobs.append(data)
        self = cls.__new__(cls)
        self._start(client, _from_bytes(blobs[0]), _counts(manifest["counts"]), blobs, batch)
        self.step = manifest.get("step")
        return self

    def close(self) -> None:
        """Release the actors (their workpieces are dropped on the workers, or the threads end); queued Booleans
        are dropped."""
        for a in self.actors:
            if isinstance(a, _ThreadActor):
                a.shutdown()
        self.actors, self._pending, self._inflight = [], [], []

    def __enter__(self) -> ShardedWorkpiece:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        where = "threads of this process" if self.client is None else "Dask actors"
        return f"ShardedWorkpiece({int(np.prod(self.counts))} shards {self.counts} on {where}, {self.width}-bit)"


def combine_shard_trees(trees, boxes, counts):
    """One BSP of the whole solid from the shards' trees.

    Parameters
    ----------
    trees : list of (palette (m, 4) wide, plane, neg, pos, label (n,) int32)
        Shard ``k``'s whole solid (right inside its box ``boxes[k]``, stale outside it).
    boxes : list of (lo (3,), hi (3,)) int
        The shards' boxes, x fastest (:func:`shard_boxes`).
    counts : (3,) int

    Returns
    -------
    BSPTree
        Axis-plane nodes at the shards' walls (halving the widest count first), shard ``k``'s tree as
        the subtree of box ``k``. Equal planes of different shards share one palette row, as in a
        single workpiece's palette.
    """
    from csgnb.bsp.tree import BSPTree
    from csgnb.exact.wide import to_wide, width_of

    width = width_of(trees[0][0])
    nx, ny, nz = counts
    lo0 = np.asarray(boxes[0][0], np.int64)
    step = np.asarray(boxes[0][1], np.int64) - lo0
    walls: list[np.ndarray] = []  # the wall planes, in the order their nodes are made
    wall_of: dict[int, int] = {}  # top node -> its wall plane
    plane, neg, pos, label = [], [], [], []
    shard_leaf = [-1] * (nx * ny * nz)  # the top node each shard's tree root replaces

    def build(lo_idx, hi_idx) -> int:
        node = len(plane)
        plane.append(-1), neg.append(-1), pos.append(-1), label.append(-1)
        span = [h - lo for lo, h in zip(lo_idx, hi_idx, strict=True)]
        if max(span) == 1:
            shard_leaf[lo_idx[0] + nx * (lo_idx[1] + ny * lo_idx[2])] = node
            return node
        axis = int(np.argmax(span))  # x first on ties
        mid = (lo_idx[axis] + hi_idx[axis]) // 2
        row = np.zeros(4, np.int64)
        row[axis], row[3] = 1, -(int(lo0[axis]) + mid * int(step[axis]))  # x_axis = wall: negative side below
        wall_of[node] = len(walls)
        walls.append(row)
        below, above = list(hi_idx), list(lo_idx)
        below[axis] = above[axis] = mid
        neg[node] = build(lo_idx, below)
        pos[node] = build(above, hi_idx)
        return node

    build([0, 0, 0], [nx, ny, nz])
    # The palette: the wall planes, then every shard's rows; byte-equal rows share one row (first one kept).
    parts = [to_wide(np.array(walls, np.int64).reshape(-1, 4), width)] + [t[0] for t in trees]
    stacked = np.ascontiguousarray(np.concatenate(parts))
    keys = stacked.view(np.dtype((np.void, stacked.dtype.itemsize * 4))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    remap = rank[inverse.ravel()]  # stacked row -> palette row
    palette = stacked[np.sort(first)]
    for node, r in wall_of.items():
        plane[node] = int(remap[r])
    top = [np.array(a, np.int64) for a in (plane, neg, pos, label)]
    pieces = [top]
    offset, base = len(plane), len(walls)
    for k, (pal, p, n, q, lab) in enumerate(trees):
        p, n, q, lab = (np.asarray(x, np.int64) for x in (p, n, q, lab))
        # Shard node 0 (its root) takes the place of its top leaf; node i >= 1 goes to offset + i - 1 (no child
        # is a root, so children map by the offset alone).
        mapped = np.where(p >= 0, remap[base + np.maximum(p, 0)], -1)
        n2, q2 = np.where(n >= 0, n + offset - 1, -1), np.where(q >= 0, q + offset - 1, -1)
        leaf = shard_leaf[k]
        top[0][leaf], top[1][leaf], top[2][leaf], top[3][leaf] = mapped[0], n2[0], q2[0], lab[0]
        pieces.append([mapped[1:], n2[1:], q2[1:], lab[1:]])
        offset += len(p) - 1
        base += len(pal)
    plane_a, neg_a, pos_a, label_a = (np.concatenate([piece[i] for piece in pieces]).astype(np.int32)
                                      for i in range(4))
    return BSPTree(palette, plane_a, neg_a, pos_a, label_a)
