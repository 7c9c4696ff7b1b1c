"""Workpiece files: structural checks on load, deterministic bytes, temporaries of killed saves, checkpoints."""

from __future__ import annotations

import builtins
import io
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgnb.errors import GeometryError
from csgnb.exact import to_wide
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Workpiece, persist
from csgnb.octree.layout import N_AXIS, N_FREE_BLOCKS, N_NODES, N_PAL, N_POOL, POOL_LIVE, R_NODES, R_POOL, S_MERGES
from csgnb.octree.persist import WorkpieceFileError

ROOT = Path(__file__).resolve().parents[1]


def random_hull(rng, centre, radius):
    return convex_hull(np.asarray(centre) + rng.integers(-radius, radius + 1, size=(9, 3)))


def build(seed=5, ops=8, grow=False):
    """A workpiece with BSP cells, splits, combines (free blocks) and wall planes."""
    rng = np.random.default_rng(seed)
    w = Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)
    if grow:  # the same workpiece in larger arrays: grown tails must not reach the file
        w._grow(R_NODES)
        w._grow(R_POOL)
        w._grow(R_NODES)
    for i in range(ops):
        w -= random_hull(rng, rng.integers(0, 24, size=3), 6)
        if i % 3 == 2:
            w |= random_hull(rng, rng.integers(4, 20, size=3), 5)
    w |= convex_hull(np.array([[x, y, z] for x in (0, 12) for y in (0, 12) for z in (0, 12)]))  # cells combine
    return w


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    w = build()
    path = tmp_path_factory.mktemp("saved") / "w.npz"
    w.save(path)
    header, arrays = persist.read_arrays(path)
    return w, path, header, arrays


def rewrite(path, header, arrays, **edits):
    """Write ``header`` / ``arrays`` with the checksum recomputed (a crafted file that passes it)."""
    h = {k: v for k, v in header.items() if k not in ("format", "version", "sha256")}
    a = dict(arrays)
    for k, v in edits.items():
        if k.startswith("h_"):
            if v is None:
                h.pop(k[2:])
            else:
                h[k[2:]] = v
        elif v is None:
            a.pop(k)
        else:
            a[k] = v
    persist.write_arrays(path, h, a)
    return path


def edited(arrays, name, index, value):
    a = arrays[name].copy()
    a[index] = value
    return a


def probe_points(rng, k=400):
    pts = rng.integers(-8, 33, size=(k, 3))
    return to_wide(np.column_stack([2 * pts + 1, np.full(k, 2)]), 128)


def same_solid(a: Workpiece, b: Workpiece) -> bool:
    X = probe_points(np.random.default_rng(0))
    return a.volume() == b.volume() and np.array_equal(a.classify(X), b.classify(X))


# -- 1. load checks the structure ----------------------------------------------------------------


def test_the_built_workpiece_exercises_every_part_of_the_format(saved):
    w, path, header, a = saved
    c = a["oc_counts"]
    assert c[N_FREE_BLOCKS] > 0 and c[N_POOL] > 0 and c[N_AXIS] > 0 and c[N_NODES] > 9
    r = Workpiece.load(path)
    assert same_solid(r, w)


def cycle_edit(a):
    """Q -> A -> B (inner nodes of one BSP, B's neg child X): make B -> A and Q -> X, every node keeping one parent."""
    plane, neg = a["pool_plane"], a["pool_neg"]
    cells = np.flatnonzero((a["oc_child"] == -1) & (a["oc_kind"] == 1))
    for c in cells:
        s, n = int(a["oc_start"][c]), int(a["oc_length"][c])
        for q in range(s, s + n):
            if plane[q] < 0:
                continue
            A = s + int(neg[q])
            if plane[A] < 0:
                continue
            B = s + int(neg[A])
            if plane[B] < 0:
                continue
            X = int(neg[B])
            nn = neg.copy()
            nn[B] = A - s
            nn[q] = X
            return {"pool_neg": nn}
    raise AssertionError("no BSP three inner nodes deep")


def crafted_cases(header, a):
    """(name, edits, what the error must name): the attacks of issue 25 and one per check."""
    n = a["oc_child"].shape[0]
    inner = np.flatnonzero(a["oc_child"] >= 0)
    leaves = np.flatnonzero((a["oc_child"] == -1) & (a["oc_parent"] >= 0))
    bsp = leaves[a["oc_kind"][leaves] == 1]
    uniform = leaves[a["oc_kind"][leaves] == 0]
    # the longest BSP among cells that can still split (a cell of min_cell may legitimately exceed the threshold)
    splittable = bsp[a["oc_size"][bsp] > header["min_cell"]]
    big = int(splittable[np.argmax(a["oc_length"][splittable])])
    small = int(bsp[np.argmin(a["oc_length"][bsp])])
    used = np.flatnonzero(a["axis_keys"] >= 0)
    pin = np.flatnonzero(a["pool_plane"] >= 0)
    free0 = int(a["oc_free_blocks"][0]) * 8 + 1
    counts = a["oc_counts"]
    return [
        ("threshold lowered", {"h_threshold": int(a["oc_length"][big]) - 1}, "threshold"),
        ("threshold huge (a huge workspace)", {"h_threshold": 10**9}, "threshold"),
        ("max_coordinate 10", {"h_max_coordinate": 10}, "root_lo"),
        ("root moved with max_coordinate", {"h_max_coordinate": 10, "h_root_lo": [-16] * 3, "h_root_size": 32},
         "oc_lo|root"),
        ("width", {"h_width": 64}, "width"),
        ("exponent", {"h_exponent": "2"}, "exponent"),
        ("unknown header field", {"h_colour": "red"}, "colour"),
        ("missing header field", {"h_seed": None}, "seed"),
        ("max_normal understated", {"h_max_normal": "1"}, "max_normal"),
        ("max_offset beyond the budget", {"h_max_offset": str(1 << 120)}, "budget"),
        ("cell box moved", {"oc_lo": edited(a, "oc_lo", (int(leaves[3]), 0), a["oc_lo"][leaves[3], 0] + 1)},
         "oc_lo"),
        ("cell size doubled", {"oc_size": edited(a, "oc_size", int(leaves[2]), 2 * a["oc_size"][leaves[2]])},
         "oc_size"),
        ("negative child", {"oc_child": edited(a, "oc_child", int(inner[0]), -5)}, "oc_child"),
        ("child out of range", {"oc_child": edited(a, "oc_child", int(inner[-1]), n + 7)}, "oc_child"),
        ("child not a block", {"oc_child": edited(a, "oc_child", int(inner[-1]), a["oc_child"][inner[-1]] + 1)},
         "oc_child"),
        ("leaf made inner", {"oc_child": edited(a, "oc_child", int(uniform[0]), 1)}, "oc_child"),
        ("wrong parent", {"oc_parent": edited(a, "oc_parent", int(leaves[0]), 0 if a["oc_parent"][leaves[0]] else 1)},
         "oc_parent"),
        ("label 7", {"oc_label": edited(a, "oc_label", int(uniform[0]), 7)}, "oc_label"),
        ("kind 2", {"oc_kind": edited(a, "oc_kind", int(uniform[0]), 2)}, "oc_kind"),
        ("uniform made BSP", {"oc_kind": edited(a, "oc_kind", int(uniform[0]), 1)}, "oc_length"),
        ("cell length + 10**6", {"oc_length": edited(a, "oc_length", big, a["oc_length"][big] + 10**6)},
         "oc_length"),
        ("cell length + 1", {"oc_length": edited(a, "oc_length", small, a["oc_length"][small] + 1)},
         "oc_start|pool"),
        ("cell start moved", {"oc_start": edited(a, "oc_start", int(bsp[-1]), a["oc_start"][bsp[-1]] - 1)},
         "oc_start"),
        ("pool child beyond the BSP", {"pool_neg": edited(a, "pool_neg", int(pin[0]), 10**6)}, "pool_neg"),
        ("pool cycle", {"pool_pos": edited(a, "pool_pos", int(pin[1]), 0)}, "pool_pos"),
        ("pool cycle apart from the root", cycle_edit(a), "cycle"),
        ("pool shared node", {"pool_pos": edited(a, "pool_pos", int(pin[0]), a["pool_neg"][pin[0]])}, "parents"),
        ("pool plane beyond palette", {"pool_plane": edited(a, "pool_plane", int(pin[0]), counts[N_PAL] + 3)},
         "pool_plane"),
        ("pool label 5", {"pool_label": edited(a, "pool_label", int(np.flatnonzero(a["pool_plane"] < 0)[0]), 5)},
         "pool_label"),
        ("free block in use", {"oc_free_blocks": edited(a, "oc_free_blocks", 0, (a["oc_child"][0] - 1) // 8)},
         "oc_free_blocks"),
        ("free node not clean", {"oc_size": edited(a, "oc_size", free0, 4)}, "oc_size"),
        ("N_NODES huge (a 754 GiB allocation)", {"oc_counts": edited(a, "oc_counts", N_NODES, 10**11)}, "shape"),
        ("N_POOL off", {"oc_counts": edited(a, "oc_counts", N_POOL, counts[N_POOL] + 1)}, "shape|POOL"),
        ("POOL_LIVE off", {"oc_counts": edited(a, "oc_counts", POOL_LIVE, 3)}, "POOL_LIVE"),
        ("N_AXIS off", {"oc_counts": edited(a, "oc_counts", N_AXIS, counts[N_AXIS] + 1)}, "N_AXIS"),
        ("negative stat", {"oc_counts": edited(a, "oc_counts", S_MERGES, -1)}, "oc_counts"),
        ("wall row wrong", {"axis_rows": edited(a, "axis_rows", int(used[0]), (a["axis_rows"][used[0]] + 1) %
                                                counts[N_PAL])}, "axis_rows"),
        ("wall key moved", {"axis_keys": np.roll(a["axis_keys"], 1), "axis_rows": np.roll(a["axis_rows"], 1)},
         "axis_keys"),
        ("palette beyond budget", {"palette_limbs": edited(a, "palette_limbs", (0, 3, 1), 1 << 40)}, "palette"),
        ("palette zero normal", {"palette_limbs": edited(a, "palette_limbs", (0, slice(0, 3)), 0)}, "palette"),
        ("dtype", {"oc_child": a["oc_child"].astype(np.int64)}, "dtype"),
        ("shape", {"oc_size": a["oc_size"][:-1]}, "shape"),
        ("missing array", {"axis_rows": None}, "axis_rows"),
        ("extra array", {"notes": np.zeros(3)}, "notes"),
    ]


def test_crafted_files_are_clear_errors_naming_the_field(saved, tmp_path):
    w, path, header, a = saved
    cases = crafted_cases(header, a)
    for name, edits, what in cases:
        bad = rewrite(tmp_path / "bad.npz", header, a, **edits)
        with pytest.raises(WorkpieceFileError, match=what):
            Workpiece.load(bad)
        print(f"{name}: refused")
    # the untouched arrays and header rewritten the same way load as the same solid
    same = Workpiece.load(rewrite(tmp_path / "same.npz", header, a))
    assert same.grid.same_as(w.grid) and same_solid(same, w)


def test_the_header_is_under_the_checksum(saved, tmp_path):
    """scale 2 (model volume / 8), threshold 20: a header edited without recomputing the checksum is refused."""
    import json
    import zipfile

    w, path, header, a = saved
    for field, value in (("exponent", header["exponent"] + 1), ("threshold", 20), ("max_coordinate", 10**6)):
        h = dict(header, **{field: value})
        out = tmp_path / f"{field}.npz"
        with zipfile.ZipFile(path) as src, zipfile.ZipFile(out, "w") as dst:
            for info in src.infolist():
                if info.filename == "header.npy":
                    buf = io.BytesIO()
                    np.save(buf, np.array(json.dumps(h)))
                    dst.writestr(info, buf.getvalue())
                else:
                    dst.writestr(info, src.read(info))
        with pytest.raises(WorkpieceFileError, match="checksum"):
            Workpiece.load(out)


# -- 2. other files, permissions ---------------------------------------------------------------------


def test_a_npy_or_any_non_zip_file_is_a_workpiece_file_error(saved, tmp_path):
    np.save(tmp_path / "w.npy", np.zeros(4))
    (tmp_path / "text.npz").write_text("hello")
    (tmp_path / "empty.npz").write_bytes(b"")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    for name in ("w.npy", "text.npz", "empty.npz", "other.npz"):
        with pytest.raises(WorkpieceFileError):
            Workpiece.load(tmp_path / name)
    with pytest.raises(FileNotFoundError):
        Workpiece.load(tmp_path / "missing.npz")


def test_files_follow_the_umask_and_permission_errors_say_so(saved, tmp_path, monkeypatch):
    w = saved[0]
    old = os.umask(0o022)
    try:
        w.save(tmp_path / "w.npz")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "w.npz").stat().st_mode) == 0o644
    locked = tmp_path / "w.npz"
    if os.geteuid() != 0:
        locked.chmod(0)
    else:  # root reads anything: refuse the open as the OS would
        real_open = builtins.open

        def refusing_open(file, *args, **kw):
            if os.fspath(file) == os.fspath(locked):
                raise PermissionError(13, "Permission denied", os.fspath(file))
            return real_open(file, *args, **kw)

        monkeypatch.setattr(builtins, "open", refusing_open)
        monkeypatch.setattr(io, "open", refusing_open)
    with pytest.raises(PermissionError, match="Permission denied"):
        Workpiece.load(locked)


# -- 3. deterministic bytes ------------------------------------------------------------------------


def test_the_same_workpiece_saves_the_same_bytes(saved, tmp_path):
    w, path, header, a = saved
    first = path.read_bytes()
    time.sleep(2.1)  # zip timestamps have a 2 s resolution
    Workpiece.load(path).save(tmp_path / "again.npz")
    assert (tmp_path / "again.npz").read_bytes() == first
    # built again in arrays grown differently: the same state, the same bytes
    build(grow=True).save(tmp_path / "grown.npz")
    assert (tmp_path / "grown.npz").read_bytes() == first
    # an empty workpiece too (no pool, no palette)
    empty = Workpiece.empty(threshold=16)
    empty.save(tmp_path / "empty.npz")
    back = Workpiece.load(tmp_path / "empty.npz")
    assert back.volume() == 0 and back.n_cells == 1
    back.save(tmp_path / "empty2.npz")
    assert (tmp_path / "empty.npz").read_bytes() == (tmp_path / "empty2.npz").read_bytes()
    # and it goes on identically after a load
    rng = np.random.default_rng(99)
    cut = random_hull(rng, [12, 12, 12], 7)
    x, y = build(), Workpiece.load(path)
    x -= cut
    y -= cut
    x.save(tmp_path / "x.npz")
    y.save(tmp_path / "y.npz")
    assert (tmp_path / "x.npz").read_bytes() == (tmp_path / "y.npz").read_bytes()


# -- 4. temporaries of killed saves -------------------------------------------------------------------

WRITER = """
import sys, numpy as np
from csgnb.octree import persist
arrays = {"x": np.zeros(30_000_000 // 8)}
while True:
    persist.write_arrays(sys.argv[1], {}, arrays)
"""


def test_temporaries_of_a_killed_save_are_cleaned_by_the_next_save(saved, tmp_path):
    w = saved[0]
    target = tmp_path / "w.npz"
    w.save(target)
    before = target.read_bytes()
    other = tmp_path / "other.npz.abcdef01.1.deadbeef.tmp"  # another target's name pattern: not ours
    other.write_bytes(b"x")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    left = []
    for _ in range(20):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target)], env=env)
        try:
            deadline = time.time() + 120
            while time.time() < deadline and not list(tmp_path.glob("w.npz.*.tmp")):
                time.sleep(0.005)
            os.kill(proc.pid, signal.SIGKILL)
        finally:
            proc.wait()
        left = list(tmp_path.glob("w.npz.*.tmp"))
        if left:
            break
    assert left, "no kill landed during a save"
    assert proc.returncode == -signal.SIGKILL
    # the target is the previous file or a complete one written by the killed process
    data = target.read_bytes()
    if data != before:
        assert persist.read_arrays(target)[1]["x"].shape == (30_000_000 // 8,)
    # a temporary whose writer is alive is left alone
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        host = left[0].name.split(".")[2]
        alive = tmp_path / f"w.npz.{host}.{sleeper.pid}.0badcafe.tmp"
        alive.write_bytes(b"in progress")
        w.save(target)
        assert sorted(tmp_path.iterdir()) == sorted([target, alive, other])
    finally:
        sleeper.kill()
        sleeper.wait()
    w.save(target)
    assert sorted(tmp_path.iterdir()) == sorted([target, other])
    assert Workpiece.load(target).volume() == w.volume()


def test_an_interrupted_save_leaves_the_previous_file_and_no_temporary(saved, tmp_path):
    w, path, header, a = saved
    target = tmp_path / "w.npz"
    w.save(target)
    for limit in (0, 100, 5000):
        with pytest.raises(KeyboardInterrupt):
            persist.write_arrays(target, {}, {"x": np.zeros(10_000)}, _fail_after=limit)
        assert target.read_bytes() == path.read_bytes()
    assert [p.name for p in tmp_path.iterdir()] == ["w.npz"]


# -- 5. a checkpoint of another run is refused ---------------------------------------------------------


class Interrupt(Exception):
    pass


def test_a_checkpoint_of_another_run_is_refused_and_its_own_run_resumes(tmp_path, monkeypatch):
    rng = np.random.default_rng(11)
    tools_a = [random_hull(rng, rng.integers(0, 24, size=3), 5) for _ in range(7)]
    tools_b = [random_hull(rng, rng.integers(0, 24, size=3), 5) for _ in range(7)]

    def start():
        return Workpiece.box([0, 0, 0], [24, 24, 24], threshold=16)

    whole = start()
    whole.run(tools_a)
    path = tmp_path / "ck.npz"
    batch = Workpiece._boolean_hulls
    calls = []

    def interrupted(self, *args, **kw):  # operations 5-6 of the run (one batch between checkpoints) are interrupted
        calls.append(1)
        if len(calls) == 3:
            raise Interrupt
        return batch(self, *args, **kw)

    monkeypatch.setattr(Workpiece, "_boolean_hulls", interrupted)
    crashed = start()
    with pytest.raises(Interrupt):
        crashed.run(tools_a, checkpoint=path, checkpoint_every=2)
    monkeypatch.setattr(Workpiece, "_boolean_hulls", batch)
    assert Workpiece.load(path)._meta["completed"] == 4
    ck = path.read_bytes()
    # same grid and threshold, other tools / operation / start: refused, the file untouched
    with pytest.raises(GeometryError, match="belongs to another run: the tools .* delete it .* another checkpoint"):
        start().run(tools_b, checkpoint=path, checkpoint_every=2)
    with pytest.raises(GeometryError, match="the operation"):
        start().run(tools_a, "union", checkpoint=path, checkpoint_every=2)
    other_start = start()
    other_start -= random_hull(rng, [3, 3, 3], 2)
    with pytest.raises(GeometryError, match="the starting workpiece"):
        other_start.run(tools_a, checkpoint=path, checkpoint_every=2)
    with pytest.raises(GeometryError, match="not a checkpoint"):
        whole.save(tmp_path / "plain.npz")
        start().run(tools_a, checkpoint=tmp_path / "plain.npz", checkpoint_every=2)
    assert path.read_bytes() == ck
    # the run that wrote it resumes and ends identically
    resumed = start()
    reports = resumed.run(tools_a, checkpoint=path, checkpoint_every=2)
    assert len(reports) == 3
    assert resumed.volume() == whole.volume()
    a, b = whole._arrays(), resumed._arrays()
    for name in a:
        if name != "oc_counts":
            assert np.array_equal(a[name], b[name]), name


# -- 6. random edits: an error or the same solid, never another one or a crash ----------------------

STRUCTURAL = ["oc_child", "oc_parent", "oc_kind", "oc_label", "oc_start", "oc_length", "oc_lo", "oc_size",
              "oc_counts", "oc_free_blocks", "pool_plane", "pool_neg", "pool_pos", "pool_label", "axis_keys",
              "axis_rows"]


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(st.data())
def test_random_edits_are_refused_or_change_nothing(saved, tmp_path, data):
    w, path, header, a = saved
    name = data.draw(st.sampled_from(STRUCTURAL + ["header"]), "field")
    if name == "header":
        key = data.draw(st.sampled_from(["root_lo", "root_size", "max_coordinate", "width", "threshold", "min_cell",
                                         "max_normal", "max_offset", "max_tool_polygons"]), "key")
        old = header[key]
        if isinstance(old, list):
            new = [v + data.draw(st.integers(-3, 3)) for v in old]
        elif isinstance(old, str):
            new = str(max(0, int(old) + data.draw(st.sampled_from([-1, 1, -int(old) // 2, int(old)]))))
        else:
            new = data.draw(st.sampled_from([old - 1, old + 1, old * 2, old // 2, 0, -1]))
        edits = {f"h_{key}": new}
        # parameters, not geometry: a valid value loads the same solid (the grid's budget may differ)
        may_load = key in ("max_tool_polygons", "threshold", "min_cell", "max_coordinate") or \
            (key in ("max_normal", "max_offset") and int(new) > int(old))
    else:
        arr = a[name]
        assume_nonempty = arr.size > 0
        if not assume_nonempty:
            return
        flat = data.draw(st.integers(0, arr.size - 1), "index")
        index = np.unravel_index(flat, arr.shape)
        old = int(arr[index])
        new = data.draw(st.sampled_from([old + 1, old - 1, old + 8, old - 8, -1, 0, 1, 2 * old, old + 10**6,
                                         -(2**31) if arr.dtype.itemsize == 4 else -(2**40)]), "value")
        if arr.dtype == np.int8:
            new = int(np.clip(new, -128, 127))
        elif arr.dtype == np.int32:
            new = int(np.clip(new, -(2**31), 2**31 - 1))
        edits = {name: edited(a, name, index, new)}
        # an edit of the geometry itself makes another valid solid that only the checksum can tell apart:
        # a leaf's label 0 <-> 1, an inner BSP node's plane to another palette row
        row = index[0]
        leaf = (name == "oc_label" and a["oc_child"][row] == -1 and a["oc_kind"][row] == 0
                and a["oc_parent"][row] >= 0) or (name == "pool_label" and a["pool_plane"][row] < 0)
        if leaf and {old, new} <= {0, 1}:
            return
        if name == "pool_plane" and old >= 0 and 0 <= new < a["palette_limbs"].shape[0]:
            return
        # the counters of statistics change no solid
        may_load = name == "oc_counts" and flat >= N_AXIS + 2
    bad = rewrite(tmp_path / "edit.npz", header, a, **edits)
    try:
        r = Workpiece.load(bad)
    except WorkpieceFileError:
        return
    changed = any(not np.array_equal(v, a[k]) for k, v in edits.items() if not k.startswith("h_")) or \
        any(header[k[2:]] != v for k, v in edits.items() if k.startswith("h_"))
    assert may_load or not changed, f"an edit of {name} loaded without an error: {edits}"
    assert same_solid(r, w)


# -- load speed --------------------------------------------------------------------------------------


def synthetic_file(path, levels=5, extra=8192, seed=0):
    """A valid file of ~10^5 octree nodes: a full octree of ``levels`` levels, ``extra`` leaves split once more;
    leaves uniform or a 3-node BSP (the half-space x + y + z < 0 inside the cell)."""
    w = Workpiece.empty(threshold=16)
    header = w._header()
    rng = np.random.default_rng(seed)
    half = -int(w.root_lo[0])
    lo = [np.array([[-half] * 3], np.int64)]
    size = [2 * half]
    child_blocks = []
    for level in range(levels + 1):
        parents = lo[-1].shape[0] if level < levels else min(extra, lo[-1].shape[0])
        child_blocks.append(parents)
        s = size[-1] // 2
        kids = (lo[-1][:parents, None, :] + s * np.array([[k & 1, k >> 1 & 1, k >> 2 & 1] for k in range(8)])
                ).reshape(-1, 3)
        lo.append(kids)
        size.append(s)
    n = sum(x.shape[0] for x in lo)
    child = np.full(n, -1, np.int32)
    parent = np.full(n, -1, np.int32)
    los = np.concatenate(lo)
    sizes = np.concatenate([np.full(x.shape[0], s, np.int64) for x, s in zip(lo, size, strict=True)])
    first = 0
    nxt = 1
    for level, parents in enumerate(child_blocks):
        idx = first + np.arange(parents)
        child[idx] = nxt + 8 * np.arange(parents)
        parent[nxt:nxt + 8 * parents] = np.repeat(idx, 8)
        first += lo[level].shape[0]
        nxt += 8 * parents
    leaf = child == -1
    kind = np.where(leaf & (rng.random(n) < 0.3), 1, 0).astype(np.int8)
    label = np.where(leaf & (kind == 0), rng.integers(0, 2, n), 0).astype(np.int32)
    cells = np.flatnonzero(kind == 1)
    length = np.where(kind == 1, 3, 0).astype(np.int32)
    start = np.zeros(n, np.int64)
    start[cells] = 3 * np.arange(cells.shape[0])
    m = 3 * cells.shape[0]
    plane = np.tile(np.array([0, -1, -1], np.int32), cells.shape[0])
    neg = np.tile(np.array([1, -1, -1], np.int32), cells.shape[0])
    pos = np.tile(np.array([2, -1, -1], np.int32), cells.shape[0])
    plab = np.tile(np.array([-1, 1, 0], np.int32), cells.shape[0])
    counts = np.zeros(32, np.int64)
    counts[N_NODES], counts[N_POOL], counts[POOL_LIVE], counts[N_PAL] = n, m, m, 1
    arrays = {"oc_child": child, "oc_parent": parent, "oc_kind": kind, "oc_label": label, "oc_start": start,
              "oc_length": length, "oc_lo": los, "oc_size": sizes, "oc_counts": counts,
              "oc_free_blocks": np.zeros(0, np.int32), "pool_plane": plane, "pool_neg": neg, "pool_pos": pos,
              "pool_label": plab, "palette_limbs": to_wide(np.array([[1, 1, 1, 0]]), 128)["limbs"],
              "axis_keys": np.full(1024, -1, np.int64), "axis_rows": np.zeros(1024, np.int32)}
    persist.write_arrays(path, header, arrays)
    return n


def test_a_large_file_loads_fast(tmp_path):
    n = synthetic_file(tmp_path / "big.npz")
    assert n > 100_000
    t0 = time.perf_counter()
    header, arrays = persist.read_arrays(tmp_path / "big.npz")
    t1 = time.perf_counter()
    persist.check_workpiece("big", header, arrays)
    t2 = time.perf_counter()
    w = Workpiece.load(tmp_path / "big.npz")
    print(f"{n} octree nodes: read {t1 - t0:.3f} s, checked {t2 - t1:.3f} s")
    assert t2 - t1 < 2.0
    assert w.n_cells == int((arrays["oc_child"] == -1).sum())
    X = to_wide(np.array([[1, 1, 1, 1], [-1, -1, -1, 1]]), 128)
    assert w.classify(X).shape == (2,)


def test_palette_maxima_from_limbs_are_exact_at_the_edges_of_the_width():
    """persist reads max |normal| and |offset| from the stored limbs (two's complement, little-endian): checked
    against Python ints, with the most negative value of the width and random values of every size."""
    import random

    from csgnb.exact import to_wide
    from csgnb.octree.persist import _max_magnitude

    rng = random.Random(5)
    for width in (128, 192, 256):
        for _ in range(50):
            vals = [rng.choice([-1, 1]) * rng.getrandbits(rng.randint(0, width - 2)) for _ in range(rng.randint(1, 9))]
            if rng.random() < 0.3:
                vals.append(-(1 << (width - 1)))
            assert _max_magnitude(to_wide(vals, width)["limbs"]) == max(abs(v) for v in vals)
