"""A workpiece split into spatial shards, each an ordinary :class:`csgnb.octree.Workpiece` held by a Dask actor.

>>> from csgnb.distributed.sharded import shard_boxes
>>> [(lo.tolist(), hi.tolist()) for lo, hi in shard_boxes([-8, -8, -8], 16, (2, 1, 1))]
[([-8, -8, -8], [0, 8, 8]), ([0, -8, -8], [8, 8, 8])]

The octree's root cube is cut into ``nx x ny x nz`` equal boxes (each count a power of two, so
the cuts lie on octree cell boundaries). Shard ``k`` holds the whole solid as seen from its
closed box ``S_k``: the same start (a box workpiece, or any workpiece given) and every Boolean
whose tool's closed box meets ``S_k`` -- a tool that misses ``S_k`` changes nothing in a
neighbourhood of it (for a label function with ``fn(a, 0) == a``: difference, union; an
intersection goes to every shard). So on ``S_k`` the shard's solid *is* the solid of one
workpiece run through the same sequence, and

* ``classify(points)`` asks, for each point, a shard whose closed box holds it: the labels are
  the single workpiece's, on shard boundaries too;
* ``volume()`` adds the shards' exact volumes inside their own boxes (``Fraction`` sums; the
  boxes tile the root cube, their common faces have no volume): equal with ``==``;
* a Boolean is sent only to the shards its tool's box meets, and they work in parallel;
* ``save(folder)`` writes each shard's workpiece (``Workpiece.save``) and a manifest;
  :meth:`ShardedWorkpiece.load` starts the actors again from them.

Tools are :class:`~csgnb.mesh.hull.ConvexHull`\\ s, :class:`~csgnb.octree.Tool`\\ s or integer
meshes ``(vertices, faces)`` in grid coordinates, as for a workpiece. ``track_volume`` is not
offered: a shard's change includes its solid outside its box; measure ``volume()`` before and after.

Known limits: a shard lives on one worker (Dask actors are not moved or retried): a lost worker loses its
shards, and the next call raises Dask's "Worker holding Actor was lost" -- ``save`` regularly and
:meth:`ShardedWorkpiece.load` to resume. ``volume()`` clips a copy of every shard (a save and a load each).
"""

from __future__ import annotations

import hashlib
import json
from fractions import Fraction
from pathlib import Path

import numpy as np

from csgnb.errors import GeometryError
from csgnb.exact.rational import fraction_text, parse_fraction

__all__ = ["Shard", "ShardedWorkpiece", "shard_boxes"]

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


class Shard:
    """A Dask actor: one :class:`csgnb.octree.Workpiece` and the box it answers for."""

    def __init__(self, lo, hi, workpiece_bytes: bytes) -> None:
        self.lo = np.asarray(lo, np.int64)
        self.hi = np.asarray(hi, np.int64)
        self.w = _from_bytes(workpiece_bytes)

    def boolean(self, tool, fn) -> int:
        """Apply ``fn`` with ``tool``; return the cells touched."""
        return self.w.boolean(tool, fn).cells

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
        clipped = _from_bytes(_to_bytes(self.w))  # a copy: the shard keeps its solid beyond its box
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                           np.int64)
        clipped.boolean(convex_hull(corners), INTERSECTION)
        return fraction_text(clipped.volume())

    def classify(self, points: np.ndarray) -> np.ndarray:
        """The workpiece's labels of integer grid points ``(n, 3)``."""
        return np.asarray(self.w.classify(points))

    def workpiece_bytes(self) -> bytes:
        """The shard's workpiece as ``Workpiece.save`` writes it."""
        return _to_bytes(self.w)

    def n_cells(self) -> int:
        return self.w.n_cells


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
    """A :class:`csgnb.octree.Workpiece` cut into ``shards`` spatial shards held by Dask actors (module docstring).

    Parameters
    ----------
    workpiece : Workpiece
        The start (e.g. ``Workpiece.box(...)``); every shard gets a copy.
    client : distributed.Client
        The actors are placed round-robin on its workers.
    shards : int or (3,) int
        1, 2, 4, 8, ... shards, or counts per axis (powers of two).
    """

    def __init__(self, workpiece, client, shards=8) -> None:
        from csgnb.octree import Workpiece

        if not isinstance(workpiece, Workpiece):
            raise TypeError(f"workpiece must be a csgnb.octree.Workpiece, got {type(workpiece).__name__}")
        self._start(client, workpiece, _counts(shards), [_to_bytes(workpiece)] * int(np.prod(_counts(shards))))

    def _start(self, client, template, counts, blobs: list[bytes]) -> None:
        from distributed import Client

        if not isinstance(client, Client):
            raise TypeError(f"client must be a distributed.Client, got {type(client).__name__}")
        self.client = client
        self.grid, self.width = template.grid, template.width
        self.template = template  # the tool conversions' grid and width; holds no solid of interest
        self.counts = counts
        self.boxes = shard_boxes(template.root_lo, template.root_size, counts)
        workers = sorted(client.scheduler_info(n_workers=-1)["workers"])
        futures = [client.submit(Shard, lo, hi, blob, actor=True, workers=[workers[k % len(workers)]],
                                 allow_other_workers=False)
                   for k, ((lo, hi), blob) in enumerate(zip(self.boxes, blobs, strict=True))]
        self.actors = [f.result() for f in futures]
        self.messages = 0  # Booleans sent (one per shard reached)

    @property
    def n_shards(self) -> int:
        return len(self.actors)

    def shards_meeting(self, lo, hi) -> list[int]:
        """The shards whose closed box meets the closed box ``[lo, hi]``."""
        lo, hi = np.asarray(lo, np.int64), np.asarray(hi, np.int64)
        return [k for k, (a, b) in enumerate(self.boxes) if np.all(a <= hi) and np.all(lo <= b)]

    def boolean(self, tool, fn) -> list[int]:
        """Apply ``fn(workpiece label, tool label)`` with ``tool`` on the shards it can change; return their indices."""
        from csgnb.bsp.merging import merge_table

        t = _tool(tool, self.template)
        table = merge_table(fn, [0, 1], [0, 1])
        if all(int(table[a, 0]) == a for a in (0, 1)):
            targets = [] if t.kind == "empty" else self.shards_meeting(t.lo, t.hi)
        else:
            targets = list(range(self.n_shards))
        calls = [self.actors[k].boolean(t, fn) for k in targets]
        for c in calls:
            c.result()
        self.messages += len(targets)
        return targets

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
        calls = [a.volume() for a in self.actors]
        return sum((parse_fraction(c.result()) for c in calls), Fraction(0))

    def classify(self, points) -> np.ndarray:
        """Labels of integer grid points ``(n, 3)`` (-2: on the boundary), each asked of a shard whose box holds it."""
        from csgnb.exact.integral import integer_array

        q = integer_array(points, "points")
        if q.ndim != 2 or q.shape[1] != 3:
            raise GeometryError(f"points must be integer grid points (n, 3), got shape {q.shape}")
        lo0 = self.boxes[0][0]
        step = self.boxes[0][1] - lo0
        # A point on a common face belongs to both shards; either answers for it (the lower one is asked).
        cell = np.clip((q - lo0 - 1) // step, 0, np.asarray(self.counts) - 1) if len(q) else np.zeros((0, 3), int)
        index = cell[:, 0] + self.counts[0] * (cell[:, 1] + self.counts[1] * cell[:, 2])
        out = np.empty(len(q), np.int64)
        calls = {k: self.actors[k].classify(q[index == k]) for k in np.unique(index).tolist()}
        for k, c in calls.items():
            out[index == k] = c.result()
        return out

    def save(self, folder) -> Path:
        """Write every shard's workpiece and a manifest (``shards.json``, with SHA-256s) into ``folder``."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        calls = [a.workpiece_bytes() for a in self.actors]
        entries = []
        for k, c in enumerate(calls):
            data = c.result()
            (folder / f"shard-{k:03d}.wp").write_bytes(data)
            entries.append({"file": f"shard-{k:03d}.wp", "sha256": hashlib.sha256(data).hexdigest()})
        (folder / MANIFEST).write_text(json.dumps({"format": 1, "counts": list(self.counts), "shards": entries},
                                                  indent=1))
        return folder

    @classmethod
    def load(cls, folder, client) -> ShardedWorkpiece:
        """The sharded workpiece saved in ``folder``, its actors started on ``client``'s workers."""
        folder = Path(folder)
        manifest = json.loads((folder / MANIFEST).read_text())
        blobs = []
        for e in manifest["shards"]:
            data = (folder / e["file"]).read_bytes()
            if hashlib.sha256(data).hexdigest() != e["sha256"]:
                raise ValueError(f"{folder / e['file']} does not match the manifest (damaged or replaced)")
            blobs.append(data)
        self = cls.__new__(cls)
        self._start(client, _from_bytes(blobs[0]), _counts(manifest["counts"]), blobs)
        return self

    def close(self) -> None:
        """Release the actors (their workpieces are dropped on the workers)."""
        self.actors = []

    def __repr__(self) -> str:
        return f"ShardedWorkpiece({self.n_shards} shards {self.counts}, {self.width}-bit)"
