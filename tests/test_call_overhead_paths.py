"""The fast paths that trim a Python-level merge's set-up keep every check of the paths they bypass.

``MeshStore.add_planes`` checks new planes against running bounds of the palette instead of re-scanning it, box
planes within int64 skip Python ints, box corners of three Python ints skip the exact conversion, and
csgnb's own label functions are tabulated once. Each test below fails if its fast path drops a check or shares
state it must not: a joint budget violation split over two calls, a corner beyond int64, a cached table a caller
changed.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb import GeometryError, PrecisionError
from csgnb.bsp import DIFFERENCE, UNION, merge, random_bsp
from csgnb.bsp.extract import check_box, check_corner
from csgnb.bsp.merging import constant_labels, merge_table
from csgnb.exact import from_wide, to_wide
from csgnb.exact.budgets import budget
from csgnb.mesh.halfedge import MeshStore, box_planes


def test_planes_added_apart_are_checked_together():
    # Each set is within the 128-bit budget alone; together N = 2**30 and D = 2**100 break 16 N^3 D < 2**127.
    store = MeshStore(to_wide([[2**30, 0, 0, 1]], 128))
    with pytest.raises(PrecisionError, match="16·N³·D"):
        store.add_planes(to_wide([[1, 0, 0, -(2**100)]], 128))
    assert store.planes.shape[0] == 1
    # ... and in the other order, through the box a merge adds
    store = MeshStore(to_wide([[0, 1, 0, 2**100]], 128))
    with pytest.raises(PrecisionError):
        store.add_planes(to_wide([[0, 0, 2**30, 0]], 128))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 2**34), st.integers(0, 2**70)), min_size=1, max_size=5))
def test_running_bounds_agree_with_a_whole_palette_check(rows):
    # The store accepts a sequence of additions exactly when the whole palette is within the budget.
    b = budget(128)
    store = MeshStore(to_wide([[1, 0, 0, 0]], 128))
    whole = [(1, 0)]
    for n, d in rows:
        whole.append((n, d))
        N, D = max(x for x, _ in whole), max(y for _, y in whole)
        ok = not b.plane_violations(N, D)
        try:
            store.add_planes(to_wide([[0, n, 0, -d]], 128))
            accepted = True
        except PrecisionError:
            accepted = False
            whole.pop()
        assert accepted == ok


def test_box_planes_fast_path_equals_the_python_int_path():
    lo, hi = (-5, 7, -(2**40)), (3, 2**61, 9)
    fast = box_planes(lo, hi, 256)
    ints = [[-1, 0, 0, -5], [1, 0, 0, -3], [0, -1, 0, 7], [0, 1, 0, -(2**61)], [0, 0, -1, -(2**40)], [0, 0, 1, -9]]
    assert from_wide(fast).tolist() == ints
    huge = box_planes((0, 0, -(2**70)), (1, 1, 1), 256)  # beyond int64: the Python-int path
    assert from_wide(huge)[4].tolist() == [0, 0, -1, -(2**70)]


def test_corners_of_python_ints_are_still_checked():
    assert check_corner([1, -2, 3], "lo") == (1, -2, 3)
    assert check_corner(np.array([1, -2, 3]), "lo") == (1, -2, 3)
    assert check_corner((-(2**63), 0, 2**63 - 1), "lo") == (-(2**63), 0, 2**63 - 1)
    with pytest.raises(PrecisionError):
        check_corner([2**63, 0, 0], "lo")
    with pytest.raises((GeometryError, TypeError)):
        check_corner([1, 2], "lo")
    with pytest.raises(TypeError):
        check_corner([True, 0, 0], "lo")
    with pytest.raises(GeometryError, match="lo < hi"):
        check_box([0, 0, 0], [1, 0, 1])


def test_cached_label_tables_are_copies():
    for _ in range(2):  # the first call fills the cache, the second reads it
        table = merge_table(UNION, [0, 1], [0, 1])
        assert table.tolist() == [[0, 1], [1, 1]]
        table[0, 0] = 7  # a caller's change must not reach the next merge
    assert merge_table(UNION, np.array([0, 1]), np.array([1, 0])).tolist() == [[0, 1], [1, 1]]
    assert merge_table(DIFFERENCE, [0, 1, 2], [0, 1]).tolist() == [[0, 0], [1, 0], [2, 0]]
    calls = []

    def traced(a, b):  # not csgnb's: called every time
        calls.append((a, b))
        return max(a, b)

    merge_table(traced, [0, 1], [0, 1])
    merge_table(traced, [0, 1], [0, 1])
    assert len(calls) == 8


def test_constant_labels_over_the_labels_present():
    table = np.array([[0, 1, 1], [1, 1, 1], [2, 0, 2]], np.int32)
    assert constant_labels(table, np.array([1, 2, 1])).tolist() == [1, 1, -1]
    assert constant_labels(table, np.array([0, 2])).tolist() == [-1, 1, 2]


def test_small_merges_are_unchanged_by_the_fast_paths():
    a = random_bsp(10, seed=3, extent=64, max_normal=16)
    b = random_bsp(10, seed=4, extent=64, max_normal=16)
    lo, hi = [-64] * 3, [64] * 3
    r1 = merge(a, b, UNION, lo, hi)
    r2 = merge(a, b, UNION, np.array(lo, np.int64), np.array(hi, np.int64))
    r3 = merge(a, b, UNION, [-64.0] * 3, [64.0] * 3)  # integral floats: the exact conversion
    for r in (r2, r3):
        assert np.array_equal(r.tree.plane, r1.tree.plane) and np.array_equal(r.tree.label, r1.tree.label)
    assert r1.surface().exact_volume() == r2.surface().exact_volume()
