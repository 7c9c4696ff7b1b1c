"""MeshStore's named topology reads agree with the half-edge invariants and with the raw columns."""

import numpy as np

from csgnb import exact
from csgnb.mesh import MeshStore, cut
from csgnb.mesh.halfedge import FACE, HE, NEXT, OPP, PLANE, TWIN, VERT


def _cut_box():
    store = MeshStore(exact.to_wide([[2, 3, 5, -19]], 128))
    parts = cut(store, store.add_box([0, 0, 0], [4, 4, 4]), 0)
    return store, parts


def test_accessors_read_the_columns_for_ints_and_arrays():
    store, parts = _cut_box()
    hs = store.cell_halfedges(parts.negative)
    for name, column in (("next_halfedge", NEXT), ("twin", TWIN), ("origin", VERT), ("face_of", FACE)):
        got = getattr(store, name)(hs)
        assert got.dtype == np.int64 and np.array_equal(got, store.he[hs, column])
        assert getattr(store, name)(int(hs[0])) == int(store.he[hs[0], column])
    fs = store.face_of(hs)
    assert np.array_equal(store.face_halfedge(fs), store.fc[fs, HE])
    assert np.array_equal(store.face_opposite(fs), store.fc[fs, OPP])
    assert np.array_equal(store.face_plane(fs, signed=True), store.fc[fs, PLANE])


def test_accessors_satisfy_the_half_edge_invariants():
    store, parts = _cut_box()
    hs = store.cell_halfedges(parts.positive)
    assert np.array_equal(store.twin(store.twin(hs)), hs)
    assert np.array_equal(store.origin(store.twin(hs)), store.origin(store.next_halfedge(hs)))
    assert np.array_equal(store.face_of(store.next_halfedge(hs)), store.face_of(hs))
    # The positive cap refers to the cutting plane flipped: row 0 as ~0, unsigned 0.
    cap = store.face_of(parts.positive)
    assert store.face_plane(cap, signed=True) == ~0 and store.face_plane(cap) == 0


def test_statistics_count_the_cut():
    store, parts = _cut_box()
    assert (store.classifications, store.constructions) == (parts.classifications, parts.constructions)
