"""Growing a mesh store must not leave anything a kernel could mistake for a stamp.

The half-edge store marks visited half-edges (``hmark``) and classified vertices (``vmark``)
with a per-traversal / per-cut stamp. New rows of a grown store used to be uninitialised
memory: when that memory held an old array's stamps, a traversal met "already visited"
half-edges and a cut met stale cached sides, and an extraction now and then returned a wrong
(still closed) surface. The first two checks fail on that bug every time; the last one, a
repeated extraction in memory earlier extractions freed, failed on it with probability ~0.99.
"""

from __future__ import annotations

import numpy as np

from csgnb import exact
from csgnb.bsp import BSP, INTERSECTION, SYMMETRIC_DIFFERENCE, UNION, random_bsp
from csgnb.mesh.halfedge import STAMP, grown_mesh_arrays, new_mesh_arrays


def test_grown_rows_hold_no_stamp_and_no_link():
    palette = exact.to_wide(np.array([[1, 0, 0, -1]]), 128)
    m = new_mesh_arrays(palette, 64)
    m.vmark[:] = 4 * 9 + 1  # "classified in cut 9"
    m.hmark[:] = 9
    m.counts[STAMP] = 9
    g = grown_mesh_arrays(m, 1000, 4000, 2000)
    assert g.vx.shape[0] > 64 and g.he.shape[0] > 256 and g.fc.shape[0] > 128
    assert np.all(g.vmark[64:] == 0) and np.all(g.hmark[256:] == 0)
    assert np.all(g.he[256:] == -1) and np.all(g.fc[128:] == -1)
    assert np.all(g.vmark[:64] == 37) and np.all(g.hmark[:256] == 9)  # old rows copied
    assert g.counts[STAMP] == 9


def test_octree_store_growth_keeps_the_stamp_counter():
    from csgnb.octree.workspace import _grown_mesh

    palette = exact.to_wide(np.array([[1, 0, 0, -1]]), 128)
    m = new_mesh_arrays(palette, 64)
    m.hmark[:] = 500
    m.counts[STAMP] = 500
    g = _grown_mesh(m)
    # the next stamp (501) must be new to every row, copied or not
    assert g.counts[STAMP] == 500 and g.hmark.max() <= 500


def test_repeated_extraction_is_exact_and_identical():
    """Notebook 03's 80 + 80 random pair: |A △ B| = |A ∪ B| − |A ∩ B| in every one of 20 extractions.

    Each extraction builds its store in memory the previous ones freed (their stamps): with the
    old uninitialised growth, about one extraction in five of this tree came out wrong.
    """
    box = ([-32] * 3, [32] * 3)
    a = BSP(random_bsp(80, seed=6, extent=32, max_normal=5), *box)
    b = BSP(random_bsp(80, seed=7, extent=32, max_normal=5), *box)
    union, inter, sym = (a.merge(b, fn) for fn in (UNION, INTERSECTION, SYMMETRIC_DIFFERENCE))
    assert union.volume() + inter.volume() == a.volume() + b.volume()
    expected = union.volume() - inter.volume()
    wrong = [k for k in range(20) if BSP(sym.tree, sym.lo, sym.hi).volume() != expected]
    assert not wrong, f"extractions {wrong} of 20 gave a wrong volume"
