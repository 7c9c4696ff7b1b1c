"""``csgnb.distributed``: batches of milling jobs on a 2-worker Dask ``LocalCluster``.

The batch must give what the same jobs give one by one in this process -- and what
``python -m csgnb.mill`` gives -- exactly: volumes compared with ``==`` on Fractions, STL files
byte for byte. Jobs are tiny (a 6-move slot, the shipped pocket on a 2 mm grid).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
from fractions import Fraction
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

from distributed import Client, LocalCluster, WorkerPlugin  # noqa: E402

import csgnb  # noqa: E402
from csgnb.distributed import JobResult, MillingJob, run_batch, run_job  # noqa: E402
from csgnb.distributed.batch import load_jobs  # noqa: E402
from csgnb.distributed.cluster import local_cluster_kwargs  # noqa: E402
from csgnb.mill import main as mill_main  # noqa: E402

SLOT = "G21 G90\nG0 Z2\nG0 X5 Y5\nM3 S8000\nG1 Z-1 F100\nG1 X15 F300\nG2 X15 Y10 R2.5\nG0 Z5\nM30\n"
TWO_TOOLS = "G21 G90\nT1 M6\nM3 S8000\nG0 X4 Y4 Z2\nG1 Z-1 F100\nG1 X12 F300\nG0 Z3\nT2 M6\nG0 X6 Y10\nG1 Z-2 F100\n" \
            "G1 X14 Y10 F300\nG0 Z5\nM30\n"


def _jobs() -> list[MillingJob]:
    return [
        MillingJob("slot", SLOT, (20, 15, 5), ("flat:3:6",), segments=8),
        MillingJob("two-tools", TWO_TOOLS, (18, 14, 4), ("1=flat:2:5", "2=ball:3:5"), segments=8),
        MillingJob.example("pocket.nc", name="pocket-2mm", resolution=2.0, segments=8),
        MillingJob("broken", "G0 X1\nG33 Z-1 K1\n", (10, 10, 3)),
    ]


@pytest.fixture(scope="module")
def client():
    with LocalCluster(**local_cluster_kwargs(2)) as cluster, Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def in_process():
    """Each job run here, one by one, without Dask."""
    return {j.name: run_job(j) for j in _jobs()}


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# -- jobs as plain data ---------------------------------------------------------------


def test_a_job_is_plain_data_and_bad_fields_are_refused():
    job = _jobs()[1]
    assert MillingJob.from_dict(json.loads(json.dumps(job.as_dict()))) == job
    assert job.digest == MillingJob.from_dict(job.as_dict()).digest
    assert job.digest != MillingJob.from_dict(dict(job.as_dict(), segments=9)).digest
    with pytest.raises(ValueError, match="job name"):
        MillingJob("a/b", SLOT, (1, 1, 1))
    with pytest.raises(ValueError, match="sizes must be positive"):
        MillingJob("s", SLOT, (1, 0, 1))
    with pytest.raises(ValueError, match="three finite numbers"):
        MillingJob("s", SLOT, (1, 1))
    with pytest.raises(TypeError, match="G-code text"):
        MillingJob("s", Path("x.nc"), (1, 1, 1))
    with pytest.raises(ValueError, match="tool specs"):
        MillingJob("s", SLOT, (1, 1, 1), tools=())
    with pytest.raises(ValueError, match="unknown key"):
        MillingJob.from_dict(dict(job.as_dict(), feed=3))
    with pytest.raises(ValueError, match="two jobs are named"):
        run_batch([job, job], client="never used")


def test_what_a_task_carries_is_a_function_by_name_and_plain_data():
    import cloudpickle

    from csgnb.distributed.batch import run_job_data

    payload = cloudpickle.dumps((run_job_data, _jobs()[2].as_dict()))
    assert b"csgnb.distributed.batch" in payload and b"run_job_data" in payload  # by reference, not by code
    assert b"numba" not in payload and b"Dispatcher" not in payload and len(payload) < 4000


def test_results_travel_as_text_and_come_back_exact(in_process):
    r = in_process["slot"]
    assert r.ok and r.stock_volume - r.removed == r.part_volume
    assert r.removed == sum(r.removed_per_move, Fraction(0)) > 0
    back = JobResult.from_report(json.loads(json.dumps(r.report())))
    assert back == r
    assert not in_process["broken"].ok and "G33" in in_process["broken"].error


def test_load_jobs_reads_a_batch_file(tmp_path):
    (tmp_path / "slot.nc").write_text(SLOT)
    f = tmp_path / "study.toml"
    f.write_text('[defaults]\nsegments = 8\n[[job]]\nprogram = "slot.nc"\nstock = [20, 15, 5]\ntools = ["flat:3:6"]\n'
                 '[[job]]\nname = "pocket-2mm"\nprogram = "pocket.nc"\nresolution = 2.0\n')
    jobs, out = load_jobs(f)
    assert out == tmp_path / "study-out"
    assert jobs == [_jobs()[0], _jobs()[2]]
    f.write_text('[[job]]\nprogram = "slot.nc"\nstock = [1, 1, 1]\nspeed = 3\n')
    with pytest.raises(ValueError, match="unknown key"):
        load_jobs(f)
    f.write_text('[[job]]\nprogram = "missing.nc"\nstock = [1, 1, 1]\n')
    with pytest.raises(ValueError, match="no G-code file"):
        load_jobs(f)
    f.write_text("out_dir = 'x'\n")
    with pytest.raises(ValueError, match="no jobs"):
        load_jobs(f)


# -- batches on the cluster -----------------------------------------------------------


def test_workers_import_this_csgnb_and_share_its_kernel_cache(client):
    files = client.run(lambda: __import__("csgnb").__file__)
    assert len(files) == 2 and set(files.values()) == {csgnb.__file__}
    caches = client.run(lambda: os.environ.get("NUMBA_CACHE_DIR"))
    assert set(caches.values()) == {os.environ.get("NUMBA_CACHE_DIR")}


def test_batch_equals_the_jobs_run_one_by_one(client, in_process, tmp_path):
    jobs = _jobs()
    results = run_batch(jobs, client, tmp_path, progress=False)
    assert [r.name for r in results] == [j.name for j in jobs]
    for r in results:
        ref = in_process[r.name]
        assert r.ok == ref.ok and not r.skipped
        if not r.ok:
            assert "G33" in r.error and json.loads(r.report_path.read_text())["error"] == r.error
            continue
        assert (r.stock_volume, r.removed, r.part_volume, r.removed_per_move) == (
            ref.stock_volume, ref.removed, ref.part_volume, ref.removed_per_move)
        assert r.stl_sha256 == ref.stl_sha256 == _sha(r.stl_path)
        assert r.workpiece_sha256 == _sha(r.workpiece_path)
        assert r.worker is not None and r.worker.startswith("tcp://")
    # Both workers took part (4 jobs, 2 single-threaded workers).
    assert len({r.worker for r in results if r.ok}) == 2


def test_batch_equals_the_command_line(client, tmp_path, capsys):
    job = _jobs()[0]
    (tmp_path / "slot.nc").write_text(SLOT)
    stl, js = tmp_path / "cli.stl", tmp_path / "cli.json"
    assert mill_main([str(tmp_path / "slot.nc"), "--stock", "20", "15", "5", "--tool", "flat:3:6", "--segments", "8",
                      "--out", str(stl), "--json", str(js), "--no-progress"]) == 0
    [r] = run_batch([job], client, tmp_path / "batch", progress=False)
    assert r.stl_path.read_bytes() == stl.read_bytes()
    assert [Fraction(m["removed_exact"]) for m in json.loads(js.read_text())["records"]] == r.removed_per_move


def test_a_rerun_skips_finished_jobs_and_redoes_damaged_or_changed_ones(client, tmp_path):
    jobs = _jobs()[:2]
    first = run_batch(jobs, client, tmp_path, progress=False)
    # Everything finished: no cluster is needed, so a client that is not one is never touched.
    again = run_batch(jobs, "not a client", tmp_path, progress=False)
    assert [r.skipped for r in again] == [True, True]
    for a, b in zip(first, again, strict=True):
        assert (a.part_volume, a.removed_per_move, a.stl_sha256) == (b.part_volume, b.removed_per_move, b.stl_sha256)
    stl = tmp_path / "slot" / "part.stl"
    stl.write_bytes(stl.read_bytes()[:-1])  # a damaged output is redone
    changed = MillingJob.from_dict(dict(jobs[1].as_dict(), segments=6))  # so is a job whose inputs changed
    third = run_batch([jobs[0], changed], client, tmp_path, progress=False)
    assert [r.skipped for r in third] == [False, False]
    assert third[0].stl_sha256 == first[0].stl_sha256 == _sha(stl)
    assert third[1].digest != first[1].digest and third[1].part_volume != first[1].part_volume


def test_without_a_client_a_local_cluster_is_started_and_closed(in_process, tmp_path):
    import gc

    def running() -> set[int]:
        gc.collect()
        found = set()
        for c in gc.get_objects():
            try:  # a weak proxy to a collected object raises on any use
                if isinstance(c, LocalCluster) and c.status.name == "running":
                    found.add(id(c))
            except ReferenceError:
                continue
        return found

    before = running()  # the module's cluster, when the other tests ran first
    [r] = run_batch([_jobs()[0]], out_dir=tmp_path, progress=False, n_workers=1)
    assert r.ok and r.worker.startswith("tcp://127.0.0.1")
    assert r.stl_sha256 == in_process["slot"].stl_sha256 and r.removed_per_move == in_process["slot"].removed_per_move
    assert running() <= before


class KillOnce(WorkerPlugin):
    """Kills its worker's process when a task whose key starts with ``prefix`` starts, once (a marker file)."""

    name = "test-kill-once"

    def __init__(self, prefix: str, marker: str) -> None:
        self.prefix, self.marker = prefix, marker

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and str(key).startswith(self.prefix) and not os.path.exists(self.marker):
            Path(self.marker).write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)


def test_a_killed_workers_job_is_retried_and_the_batch_completes(client, in_process, tmp_path):
    marker = tmp_path / "killed"
    client.register_plugin(KillOnce("csgnb-mill-two-tools-", str(marker)), name=KillOnce.name)
    try:
        results = run_batch(_jobs()[:2], client, tmp_path / "out", progress=False)
    finally:
        client.unregister_worker_plugin(KillOnce.name)
    assert marker.exists()  # a worker really died running the job
    assert all(r.ok for r in results)
    for r in results:
        assert r.part_volume == in_process[r.name].part_volume
        assert r.stl_sha256 == in_process[r.name].stl_sha256
    client.wait_for_workers(2, timeout=60)


def test_command_line_batch_on_a_scheduler(client, tmp_path, capsys):
    (tmp_path / "slot.nc").write_text(SLOT)
    f = tmp_path / "jobs.toml"
    f.write_text('out_dir = "parts"\n[[job]]\nprogram = "slot.nc"\nstock = [20, 15, 5]\ntools = ["flat:3:6"]\n'
                 'segments = 8\n[[job]]\nname = "bad"\nprogram = "slot.nc"\nstock = [20, 15, 5]\ntools = ["mill:3"]\n')
    rc = mill_main(["--batch", str(f), "--scheduler", client.scheduler.address, "--no-progress"])
    out = capsys.readouterr().out
    assert rc == 2 and "1 of 2 jobs done" in out and "bad: FAILED" in out and "unknown tool kind" in out
    assert (tmp_path / "parts" / "slot" / "part.stl").exists()
    assert json.loads((tmp_path / "parts" / "slot" / "report.json").read_text())["digest"] == _jobs()[0].digest
    f.write_text("[[job]]\n")
    assert mill_main(["--batch", str(f), "--no-progress"]) == 2
    assert "needs program" in capsys.readouterr().err


# -- the sharded workpiece ---------------------------------------------------------------


def _sequence():
    """Booleans that cross the shards' common faces (x, y, z = 0), with a union and an intersection."""
    import numpy as np

    from csgnb.bsp.solid import DIFFERENCE, INTERSECTION, UNION
    from csgnb.mesh.hull import convex_hull

    tet = np.array([[0, 0, 0], [9, 0, 0], [0, 9, 0], [0, 0, 9]])
    octa = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    box = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    return [
        (convex_hull(tet * 2 - [7, 5, 6]), DIFFERENCE),
        (convex_hull(tet + [3, 4, 5]), DIFFERENCE),   # in the x, y, z > 0 shard only
        (convex_hull(box * [30, 6, 6] + [-8, -3, 14]), UNION),  # sticks out of the stock
        (convex_hull(octa * 29 + [1, 0, 0]), INTERSECTION),
        (convex_hull(octa * 5 + [0, 0, -3]), DIFFERENCE),
    ]


def _points():
    import numpy as np

    r = np.arange(-21, 22, 3)
    grid = np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)
    faces = np.array([[0, y, z] for y in range(-12, 13, 4) for z in range(-12, 20, 4)])  # on the shards' faces
    return np.concatenate([grid, faces, faces[:, [1, 0, 2]], faces[:, [1, 2, 0]], [[0, 0, 0], [0, 0, 18]]])


@pytest.fixture(scope="module")
def single():
    from csgnb.octree import Workpiece

    w = Workpiece.box([-16, -16, -16], [16, 16, 16])
    volumes = [w.volume()]
    for tool, fn in _sequence():
        w.boolean(tool, fn)
        volumes.append(w.volume())
    return w, volumes


def _oriented_area_per_plane(surface) -> dict:
    """Exact oriented area vector summed per supporting plane (plane as primitive integers): two closed surfaces
    with equal dicts cover the same oriented regions of every plane, however their polygons are cut."""
    import math

    from csgnb.exact import from_wide

    pos = surface.exact_positions()
    planes = from_wide(surface.palette)
    out: dict = {}
    for i, poly in enumerate(surface.polygons()):
        sup = int(surface.support[i])  # ~row: the polygon faces the row's negative side
        row = [int(v) if sup >= 0 else -int(v) for v in planes[sup if sup >= 0 else ~sup]]
        g = math.gcd(*row)
        key = tuple(v // g for v in row)
        pts = [pos[v] for v in poly]
        area = [Fraction(0)] * 3
        for a, b in zip(pts, pts[1:] + pts[:1], strict=True):
            area = [area[0] + a[1] * b[2] - a[2] * b[1], area[1] + a[2] * b[0] - a[0] * b[2],
                    area[2] + a[0] * b[1] - a[1] * b[0]]
        total = out.get(key, [Fraction(0)] * 3)
        out[key] = [x + y for x, y in zip(total, area, strict=True)]
    return {k: tuple(v) for k, v in out.items() if any(v)}


def _same_surface(sharded, w) -> None:
    got, expected = sharded.surface(), w.surface()
    assert got.is_closed()
    assert got.exact_volume() == expected.exact_volume() == w.volume()
    assert _oriented_area_per_plane(got) == _oriented_area_per_plane(expected)


@pytest.mark.parametrize("shards", [1, 2, 8])
def test_sharded_workpiece_equals_one_workpiece(client, single, shards, tmp_path):
    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.octree import Workpiece

    w, volumes = single
    s = ShardedWorkpiece(Workpiece.box([-16, -16, -16], [16, 16, 16]), client, shards, batch=1)
    assert s.volume() == volumes[0]
    reached = []
    for (tool, fn), v in zip(_sequence(), volumes[1:], strict=True):
        reached.append(s.boolean(tool, fn))
        assert s.volume() == v
    if shards == 8:  # the second tool lies in the x, y, z > 0 octant: one shard; the intersection: all
        assert reached[1] == [7] and reached[3] == list(range(8)) and len(reached[0]) == 8
    if shards == 2:
        assert reached[1] == [1]
    pts = _points()
    expected = w.classify(pts)
    assert set(expected.tolist()) == {-2, 0, 1}
    assert s.classify(pts).tolist() == expected.tolist()
    _same_surface(s, w)
    back = ShardedWorkpiece.load(s.save(tmp_path / "saved", step=5), client)
    assert back.step == 5
    assert back.volume() == volumes[-1]
    assert back.classify(pts).tolist() == expected.tolist()


def _random_sequence(seed: int, n: int):
    """Random hulls over the stock and across the shards' walls, with every named Boolean (as the octree fuzz)."""
    import numpy as np

    from csgnb.bsp.solid import DIFFERENCE, INTERSECTION, UNION
    from csgnb.mesh.hull import convex_hull

    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        centre = rng.integers(-14, 15, 3)
        size = rng.integers(2, 12)
        pts = centre + rng.integers(-size, size + 1, (int(rng.integers(5, 10)), 3))
        if np.linalg.matrix_rank(pts[1:] - pts[0]) < 3:
            continue
        fn = INTERSECTION if i % 9 == 8 else (UNION if rng.random() < 0.25 else DIFFERENCE)
        if fn is INTERSECTION:
            pts = rng.integers(-20, 21, 3) // 4 + np.array([[x, y, z] for x in (-18, 18) for y in (-18, 18)
                                                               for z in (-18, 18)])
        out.append((convex_hull(pts), fn))
    return out


@pytest.mark.parametrize("seed, shards, batch", [(1, 2, 4), (2, 8, 32), (3, (4, 2, 1), 1)])
def test_sharded_workpiece_fuzz(client, seed, shards, batch):
    """Random sequences, queued in batches: volume, labels of random points and the surface equal one
    workpiece's after the sequence, and the volume half-way."""
    import numpy as np

    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.octree import Workpiece

    seq = _random_sequence(seed, 24)
    w = Workpiece.box([-12, -12, -12], [12, 12, 12], threshold=12)
    s = ShardedWorkpiece(Workpiece.box([-12, -12, -12], [12, 12, 12], threshold=12), client, shards, batch=batch)
    for i, (tool, fn) in enumerate(seq):
        w.boolean(tool, fn)
        s.boolean(tool, fn)
        if i == len(seq) // 2:
            assert s.volume() == w.volume()
    assert s.volume() == w.volume()
    pts = np.random.default_rng(seed).integers(-20, 21, (400, 3))
    assert s.classify(pts).tolist() == w.classify(pts).tolist()
    _same_surface(s, w)
    if batch > 1:
        assert s.calls < s.messages  # Booleans travelled several to a message


@pytest.mark.parametrize("shards", [2, 8])
def test_shards_on_threads_equal_one_workpiece(single, shards, tmp_path):
    """``client=None``: the shards on threads of this process give the single workpiece's volumes after every
    Boolean, its labels (points on the shards' walls included) and its surface; a checkpoint loads back."""
    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.octree import Workpiece

    w, volumes = single
    with ShardedWorkpiece(Workpiece.box([-16, -16, -16], [16, 16, 16]), None, shards) as s:
        assert "threads" in repr(s)
        assert s.volume() == volumes[0]
        for (tool, fn), v in zip(_sequence(), volumes[1:], strict=True):
            s.boolean(tool, fn)
            assert s.volume() == v
        pts = _points()
        assert s.classify(pts).tolist() == w.classify(pts).tolist()
        _same_surface(s, w)
        assert sum(st["applied"] for st in s.stats()) == s.messages
        back = ShardedWorkpiece.load(s.save(tmp_path / "saved", step=5))
    with back:
        assert back.step == 5 and back.client is None
        assert back.volume() == volumes[-1]
        assert back.classify(pts).tolist() == w.classify(pts).tolist()


@pytest.mark.parametrize("seed, shards", [(4, 2), (5, (2, 2, 1)), (6, 8)])
def test_shards_on_threads_fuzz(seed, shards):
    """Random sequences handed to the shards' threads without waiting: volume, labels of random points and of
    points on every wall, and the surface equal one workpiece's."""
    import numpy as np

    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.octree import Workpiece

    seq = _random_sequence(seed, 30)
    w = Workpiece.box([-12, -12, -12], [12, 12, 12], threshold=12)
    with ShardedWorkpiece(Workpiece.box([-12, -12, -12], [12, 12, 12], threshold=12), None, shards) as s:
        for tool, fn in seq:
            w.boolean(tool, fn)
            s.boolean(tool, fn)
        assert s.volume() == w.volume()
        rng = np.random.default_rng(seed)
        pts = rng.integers(-20, 21, (400, 3))
        walls = rng.integers(-20, 21, (300, 3))
        walls[:100, 0] = 0
        walls[100:200, 1] = 0
        walls[200:, :2] = 0  # on two walls at once
        for p in (pts, walls):
            assert s.classify(p).tolist() == w.classify(p).tolist()
        _same_surface(s, w)


def test_shards_on_threads_refuse_a_bad_tool_at_once_and_stay_usable():
    """A label function making a third material, or a tool that is no tool, raises in the caller before any shard
    applies it; the sharded workpiece goes on."""
    import numpy as np

    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.errors import GeometryError
    from csgnb.mesh.hull import convex_hull
    from csgnb.octree import Workpiece

    hull = convex_hull(np.array([[x, y, z] for x in (-3, 3) for y in (-1, 1) for z in (-1, 1)]))
    with ShardedWorkpiece(Workpiece.box([-8, -8, -8], [8, 8, 8]), None, 2) as s:
        with pytest.raises(GeometryError, match="one material"):
            s.boolean(hull, lambda a, b: 2 * max(a, b))
        with pytest.raises(TypeError, match="ConvexHull"):
            s.difference("a hull")
        s.difference(hull)
        assert s.volume() == 16**3 - 6 * 2 * 2


def test_shards_on_threads_measure_a_256_bit_workpiece():
    """The shards' volumes at 256 bits (each clips its solid by a box at the workpiece's width: a 128-bit box was
    refused beyond the 128-bit budget), equal to the single workpiece's, on a fine grid and on the identity grid."""
    import numpy as np

    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.exact import Grid
    from csgnb.mesh.hull import convex_hull
    from csgnb.octree import Workpiece

    for grid in (Grid.fit([-12] * 3, [12] * 3, width=256), Grid.fit([-12] * 3, [12] * 3, width=192), None):
        kw = {"grid": grid} if grid is not None else {"width": 256}
        g = grid if grid is not None else Workpiece(width=256).grid
        lo, hi = g.to_grid(np.array([[-3.0, -1.0, -1.0], [3.0, 1.0, 1.0]])) if grid else ([-3] * 3, [3] * 3)
        corners = [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        hull = convex_hull(np.array(corners), width=g.width)
        single = Workpiece.box([-8] * 3, [8] * 3, **kw)
        single -= hull
        with ShardedWorkpiece(Workpiece.box([-8] * 3, [8] * 3, **kw), None, 2) as s:
            s.difference(hull)
            assert s.volume() == single.volume() > 0


def test_a_shard_reads_points_on_its_walls_from_its_own_side():
    """A workpiece changed only inside a box (``within=``) is stale beyond it: points on the box's faces read with
    ``box_face_sides`` get the labels of the workpiece that saw every change; read both ways, some do not."""
    import numpy as np

    from csgnb.bsp.solid import DIFFERENCE
    from csgnb.bsp.tree import box_face_sides
    from csgnb.errors import GeometryError
    from csgnb.exact import homogeneous_points
    from csgnb.mesh.hull import convex_hull
    from csgnb.octree import Workpiece

    lo, hi = np.array([-16, -16, -16]), np.array([0, 16, 16])
    slab = convex_hull(np.array([[x, y, z] for x in (-4, 6) for y in (-6, 6) for z in (-6, 20)]))
    tet = np.array([[0, 0, 0], [3, 0, 0], [0, 3, 0], [0, 0, 3]])
    dents = [convex_hull(tet + [x, y, z]) for x in (-9, -5, 2, 6) for y in (-9, 7) for z in (-9, 7)]
    whole = Workpiece.box([-12, -12, -12], [12, 12, 12], threshold=8)
    part = Workpiece.box([-12, -12, -12], [12, 12, 12], threshold=8)
    for dent in dents:  # fine cells on both sides of x = 0
        whole.boolean(dent, DIFFERENCE)
        part.boolean(dent, DIFFERENCE)
    whole.boolean(slab, DIFFERENCE)
    part.boolean(slab, DIFFERENCE, within=(lo, hi))  # the x > 0 half of the slot is left behind
    pts = np.array([[0, y, z] for y in range(-12, 13, 3) for z in range(-12, 13, 3)])
    tree = part.global_tree()
    p = homogeneous_points(pts, part.width)
    own_side = tree.classify(p, forced_sides=box_face_sides(tree.palette, lo, hi))
    both_ways = tree.classify(p)
    assert own_side.tolist() == whole.classify(pts - [1, 0, 0]).tolist()  # on the wall as just inside it
    assert set(own_side.tolist()) == {-2, 0, 1}
    assert both_ways.tolist() != own_side.tolist()  # read both ways, the stale half shows through
    with pytest.raises(GeometryError, match="forced_sides"):
        tree.classify(p, forced_sides=np.zeros(3, np.int8))


async def _die():
    os.kill(os.getpid(), signal.SIGKILL)  # the worker's process, as the OOM killer would


def test_killed_sharded_run_resumes_from_its_checkpoint(client, single, tmp_path):
    """A worker holding shards is killed mid-run: the next call fails clearly, and the run resumes from the
    last checkpoint (its step stored in the manifest) to the single workpiece's answers."""
    from csgnb.distributed.sharded import ShardedWorkpiece, ShardFailure
    from csgnb.octree import Workpiece

    w, volumes = single
    seq = _sequence()
    s = ShardedWorkpiece(Workpiece.box([-16, -16, -16], [16, 16, 16]), client, 2, batch=2)
    folder = tmp_path / "run"
    for i, (tool, fn) in enumerate(seq[:3]):
        s.boolean(tool, fn)
        if i == 1:
            s.save(folder, step=i + 1)
    victim = s.actors[1]._address
    client.run(_die, workers=[victim], wait=False)
    with pytest.raises(Exception):  # noqa: B017 (Dask's own error for a lost actor)
        s.flush()
        s.volume()
    with pytest.raises(ShardFailure, match="load the last checkpoint"):
        s.boolean(*seq[3])
    client.wait_for_workers(2, timeout=60)
    back = ShardedWorkpiece.load(folder, client)
    assert back.step == 2 and back.volume() == volumes[2]
    for tool, fn in seq[back.step:]:
        back.boolean(tool, fn)
    assert back.volume() == volumes[-1]
    assert back.classify(_points()).tolist() == w.classify(_points()).tolist()


def test_sharded_checkpoint_is_replaced_whole(client, tmp_path):
    """A second save leaves only the files its manifest names; a damaged or missing shard file is refused."""
    from csgnb.distributed.sharded import MANIFEST, ShardedWorkpiece
    from csgnb.mesh.hull import convex_hull
    from csgnb.octree import Workpiece

    s = ShardedWorkpiece(Workpiece.box([-4, -4, -4], [4, 4, 4]), client, 2)
    folder = s.save(tmp_path / "s", step=0)
    first = sorted(p.name for p in folder.glob("shard-*.wp"))
    s.difference(convex_hull([[-1, -1, -1], [3, -1, -1], [-1, 3, -1], [-1, -1, 3]]))
    s.save(folder, step=1)
    manifest = json.loads((folder / MANIFEST).read_text())
    names = sorted(e["file"] for e in manifest["shards"])
    assert sorted(p.name for p in folder.glob("shard-*.wp")) == names != first
    assert manifest["step"] == 1 and not list(folder.glob(".*.tmp"))
    (folder / names[0]).unlink()
    with pytest.raises(ValueError, match="does not match the manifest"):
        ShardedWorkpiece.load(folder, client)
    with pytest.raises(ValueError, match="is missing"):
        ShardedWorkpiece.load(tmp_path / "nothing", client)


def test_sharded_workpiece_refuses_bad_input(client, tmp_path):
    from csgnb.distributed.sharded import MANIFEST, ShardedWorkpiece, shard_boxes
    from csgnb.octree import Workpiece

    with pytest.raises(ValueError, match="power of two"):
        shard_boxes([0, 0, 0], 16, 3)
    with pytest.raises(ValueError, match="powers of two"):
        shard_boxes([0, 0, 0], 16, (3, 1, 1))
    with pytest.raises(TypeError, match="csgnb.octree.Workpiece"):
        ShardedWorkpiece("box", client, 2)
    with pytest.raises(ValueError, match="batch must be a positive integer"):
        ShardedWorkpiece(Workpiece.box([-4, -4, -4], [4, 4, 4]), client, 2, batch=0)
    s = ShardedWorkpiece(Workpiece.box([-4, -4, -4], [4, 4, 4]), client, 2)
    with pytest.raises(TypeError, match="ConvexHull"):
        s.difference("tool")
    folder = s.save(tmp_path / "s")
    name = json.loads((folder / MANIFEST).read_text())["shards"][1]["file"]
    (folder / name).write_bytes(b"junk")
    with pytest.raises(ValueError, match="does not match the manifest"):
        ShardedWorkpiece.load(folder, client)


def test_shards_wait_for_a_running_worker(monkeypatch):
    """Placing shards asks the scheduler afresh for running workers: none within the wait is a clear
    ShardFailure (it was a ZeroDivisionError when the client's cached answer listed none, as after a kill),
    and a worker that arrives during the wait gets the shards."""
    import csgnb.distributed.sharded as sharded
    from csgnb.octree import Workpiece

    start = Workpiece.box([-4, -4, -4], [4, 4, 4])
    monkeypatch.setattr(sharded, "WORKER_WAIT_S", 1.0)
    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster, Client(cluster) as c:
        with pytest.raises(sharded.ShardFailure, match="no running worker"):
            sharded.ShardedWorkpiece(start, c, 2)
        monkeypatch.setattr(sharded, "WORKER_WAIT_S", 60.0)
        threading.Timer(0.5, cluster.scale, args=(1,)).start()
        s = sharded.ShardedWorkpiece(start, c, 2)
        assert s.volume() == 512


@pytest.mark.parametrize("mesh", [False, True])
def test_shards_taking_turns_with_one_scratch_keep_their_own_cell_boundaries(mesh):
    """The shards on one Dask worker take turns with one scratch workspace (``Shard._take_scratch``); the cells'
    boundary cache is keyed by octree node and names palette rows, so a shard reading another's entries carved the
    wrong solid with no error (8 shards on 2 workers: 596 million cubic units for 32,467). Eight shards of one
    process, the Booleans of the sharded test as hulls and as meshes, after every step against one workpiece (no
    Dask needed: the sharing is the same)."""
    from csgnb.distributed.sharded import Shard, _to_bytes, shard_boxes
    from csgnb.octree import Tool, Workpiece

    single = Workpiece.box([-16, -16, -16], [16, 16, 16])
    shards = [Shard(lo, hi, _to_bytes(single)) for lo, hi in shard_boxes(single.root_lo, single.root_size, 8)]
    for step, (hull, fn) in enumerate(_sequence()):
        tool = Tool.from_mesh(*hull.to_mesh(), width=128) if mesh else hull
        single.boolean(tool, fn)
        for shard in shards:
            shard.apply([(tool, fn)])
        assert sum(Fraction(s.volume()) for s in shards) == single.volume(), step
