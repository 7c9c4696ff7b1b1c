"""Differences a workpiece has already applied (``Workpiece.boolean``, ``APPLIED_MEMO``): subtracting the same mesh
tool again -- same content, same translation, same ``within`` -- before anything adds material is an exact no-op
(A - T - X - T = A - T - X) and is skipped. Checked against the same sequences with the memo off (exact volumes and
point classification after every operation), through unions and intersections that must make it forget, boxes,
saves, resumed runs and pickled tools."""

from __future__ import annotations

import pickle
from fractions import Fraction

import numpy as np
import pytest

from csgnb.exact import to_wide
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Tool, Workpiece
from csgnb.octree.persist import WorkpieceFileError, read_arrays, write_arrays


def _mesh_tool(rng, centre, radius: int, n: int = 40) -> Tool:
    d = rng.normal(size=(n, 3))
    points = np.rint(d / np.linalg.norm(d, axis=1)[:, None] * radius).astype(np.int64) + np.asarray(centre)
    V, F = convex_hull(points).to_mesh()
    return Tool.from_mesh(V, F, width=128)


def _without_memo(w: Workpiece) -> Workpiece:
    w._applied_key = lambda tool, within: None  # this workpiece never skips: the reference
    return w


def _points(rng, n=3000):
    pts = rng.integers(-2, 66, size=(n, 3))
    return to_wide(np.column_stack([pts, np.full(n, 2)]), 128)


@pytest.mark.parametrize("seed", range(4))
def test_skipped_differences_leave_the_solid_of_the_full_sequence(seed):
    """Random sequences of mesh-tool differences (three tools, three translations: many exact repeats), unions and
    intersections: after every operation the same exact volume as a workpiece that applies everything, and the same
    classification of 3,000 points at the end; repeats skipped only between operations that add no material."""
    rng = np.random.default_rng(seed)
    tools = [_mesh_tool(rng, rng.integers(20, 44, size=3), int(rng.integers(6, 12))) for _ in range(3)]
    shifts = [np.zeros(3, np.int64), np.array([3, 0, 0]), np.array([0, -2, 4])]
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    ref = _without_memo(Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24))
    repeated = 0
    subtracted = set()
    for _ in range(60):
        r = rng.random()
        if r < 0.8:
            i, j = int(rng.integers(3)), int(rng.integers(3))
            tool = tools[i].translated(shifts[j])
            report = w.difference(tool)
            ref.difference(tool)
            assert report.repeated == ((i, j) in subtracted)
            subtracted.add((i, j))
            repeated += report.repeated
        elif r < 0.93:
            c = rng.integers(16, 48, size=3)
            hull = convex_hull(c + rng.integers(-8, 9, size=(8, 3)))
            if rng.random() < 0.5:
                w |= hull
                ref |= hull
            else:
                w.run([hull], "union")  # a compiled batch of hulls forgets too
                ref.run([hull], "union")
            subtracted.clear()
        else:
            box = convex_hull(np.array([[x, y, z] for x in (1, 63) for y in (2, 62) for z in (0, 61)]))
            w &= box
            ref &= box
            subtracted.clear()
        assert w.volume() == ref.volume()
    assert repeated > 0 and w.stats.repeated == repeated and ref.stats.repeated == 0
    X = _points(rng)
    assert np.array_equal(w.classify(X), ref.classify(X))


def test_a_union_makes_it_forget_and_a_repeat_measures_zero():
    rng = np.random.default_rng(3)
    tool = _mesh_tool(rng, [30, 30, 30], 10)
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    first = w.difference(tool, track_volume=True)
    again = w.difference(tool, track_volume=True)
    assert first.removed > 0 and not first.repeated
    assert again.repeated and again.removed == 0 and again.cells == 0
    w |= convex_hull(np.array([[26, 26, 26], [34, 26, 26], [26, 34, 26], [26, 26, 34]]))  # material inside the tool
    refill = w.difference(tool, track_volume=True)
    assert not refill.repeated and refill.removed == Fraction(8**3, 6)  # the tetrahedron, all of it


def test_boxes_and_translations_are_part_of_what_was_applied():
    rng = np.random.default_rng(4)
    tool = _mesh_tool(rng, [30, 30, 30], 12)
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    left, right = (np.array([0, 0, 0]), np.array([30, 64, 64])), (np.array([30, 0, 0]), np.array([64, 64, 64]))
    assert not w.difference(tool, within=left).repeated
    assert not w.difference(tool, within=right).repeated  # another box: the right half is still to cut
    assert w.difference(tool, within=left).repeated
    assert not w.difference(tool.translated(np.array([1, 0, 0])), within=left).repeated
    assert w.difference(tool.translated(np.array([1, 0, 0])).translated(np.array([-1, 0, 0])), within=left).repeated
    ref = _without_memo(Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24))
    ref -= tool
    ref.difference(tool.translated(np.array([1, 0, 0])), within=left)
    assert w.volume() == ref.volume()


def test_pickled_moved_tools_are_their_own_content():
    """A moved tool sent elsewhere (pickled: it travels without its source) is keyed on its own planes: the source
    subtracted first does not make the moved one a repeat."""
    rng = np.random.default_rng(5)
    tool = _mesh_tool(rng, [30, 30, 30], 10)
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    w -= tool
    moved = pickle.loads(pickle.dumps(tool.translated(np.array([6, 0, 0]))))
    assert "_digests" not in moved.__dict__ and "_moved_from" not in moved.__dict__
    assert not w.difference(moved).repeated
    assert w.difference(pickle.loads(pickle.dumps(moved))).repeated  # the same content again
    ref = _without_memo(Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24))
    ref -= tool
    ref -= tool.translated(np.array([6, 0, 0]))
    assert w.volume() == ref.volume()


def test_saved_and_resumed_workpieces_remember_what_they_applied(tmp_path):
    rng = np.random.default_rng(6)
    a, b = _mesh_tool(rng, [24, 30, 30], 9), _mesh_tool(rng, [40, 30, 30], 9)
    tools = [a, b, a, b.translated(np.array([0, 2, 0])), a, b.translated(np.array([0, 2, 0])), b]
    whole = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    reports = whole.run(tools, "difference")
    assert [r.repeated for r in reports] == [False, False, True, False, True, True, True]
    path = tmp_path / "ck.npz"
    crashed = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    crashed.run(tools[:3], "difference", checkpoint=path, checkpoint_every=2)  # "crashes" after 3
    resumed = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    later = resumed.run(tools, "difference", checkpoint=path, checkpoint_every=2)
    assert [r.repeated for r in later] == [False, True, True, True]  # from the checkpoint after 3: a is known
    assert resumed._state_digest() == whole._state_digest()
    assert resumed._applied == whole._applied and len(whole._applied) == 3
    saved = tmp_path / "w.npz"
    whole.save(saved)
    loaded = Workpiece.load(saved)
    assert loaded.difference(a).repeated and not loaded.difference(a.translated(np.array([1, 1, 1]))).repeated


@pytest.mark.parametrize("bad", [["0" * 63], ["g" * 64], ["a" * 64, "a" * 64], [], "a" * 64])
def test_a_file_with_a_bad_list_of_applied_differences_is_refused(tmp_path, bad):
    w = Workpiece.box([0, 0, 0], [64, 64, 64], threshold=24)
    w -= _mesh_tool(np.random.default_rng(7), [30, 30, 30], 10)
    path = tmp_path / "w.npz"
    w.save(path)
    header, arrays = read_arrays(path)
    assert len(header["applied"]) == 1
    header = {k: v for k, v in header.items() if k not in ("format", "version", "sha256")}
    header["applied"] = bad
    write_arrays(path, header, arrays)
    with pytest.raises(WorkpieceFileError, match="applied"):
        Workpiece.load(path)
