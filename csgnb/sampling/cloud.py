"""The sampler's output: a point cloud with normals, quadric ids, radii and deduplicated clip sets.

Layout follows the paper's renderer (§6): per sample a position, the index of its quadric in the
normal form and a (start, count) slice of one *clip indirection buffer* that lists, once per
distinct set, the quadrics of the sample's term that may cut its splat. ``quadric_buffer`` gives
the matching *quadric buffer* (10 coefficients per quadric).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import types
from numba.typed import Dict

from csgnb._jit import jit
from csgnb.csg.normal_form import NormalForm
from csgnb.csg.normalisation import ModelFrame
from csgnb.errors import CsgnbError
from csgnb.quadric.arguments import as_finite_array

__all__ = ["SampleCloud", "SamplingStats", "SamplingTrace", "deduplicate_clip_sets"]


@dataclass(frozen=True)
class SamplingStats:
    """Counters of one sampling run (the columns of the paper's Table 2).

    samples : int — points emitted.
    distance_queries : int — evaluations of d_Qab (eq. 22) at region corners.
    clip_indices : int — length of the clip indirection buffer.
    regions : int — triangles visited (basic-region pieces and their subdivisions).
    unresolved : int — regions given up below the size floor (``tolerances.MIN_REGION``): only
        around isolated tangency points (see ``csgnb.sampling.kernel``, rule 5).
    quadrics : int — quadrics of the normal form; sampled_quadrics : int — those with a task.
    terms : int — terms of the normal form.
    seconds : float — wall time of the whole run (normal form, bounds, regions, kernels, output).
    feature_points : int — single samples placed on tangency curves by the edge search (rule 3).
    covered_by_neighbours : int — regions given up below the size floor but covered by a single
        sample of the same quadric (the neighbour rule); not counted in ``unresolved``.
    """

    samples: int
    distance_queries: int
    clip_indices: int
    regions: int
    unresolved: int
    quadrics: int
    sampled_quadrics: int
    terms: int
    seconds: float
    feature_points: int = 0
    covered_by_neighbours: int = 0


@dataclass(frozen=True)
class SamplingTrace:
    """What the adaptive subdivision did, for pictures (Figure 9) and checks.

    Leaves (one row per final region): ``leaf_quadric``, ``leaf_plane``, ``leaf_sheet`` (±1),
    ``leaf_triangle`` (t, 3, 2) plane coordinates, ``leaf_uv`` (squared-coordinate flags of its
    (U, V)-sides: bit 0 x, bit 1 y; 0 straight), ``leaf_quadrant`` (t, 2), ``leaf_status`` (codes
    of ``kernel.STATUS``), ``leaf_depth``. Distance evaluations: ``point_quadric``,
    ``point_plane``, ``point_sheet``, ``point_xy`` (e, 2) plane coordinates, ``point_world``
    (e, 3), ``point_distance`` (e,) the value of d_Qab. ``planes[(quadric, k)]``: the
    :class:`~csgnb.quadric.SamplingPlane` those plane coordinates refer to. All in world units.
    """

    leaf_quadric: np.ndarray
    leaf_plane: np.ndarray
    leaf_sheet: np.ndarray
    leaf_triangle: np.ndarray
    leaf_uv: np.ndarray
    leaf_quadrant: np.ndarray
    leaf_status: np.ndarray
    leaf_depth: np.ndarray
    point_quadric: np.ndarray
    point_plane: np.ndarray
    point_sheet: np.ndarray
    point_xy: np.ndarray
    point_world: np.ndarray
    point_distance: np.ndarray
    planes: dict

    def leaf_outline(self, i: int, samples_per_side: int = 12) -> np.ndarray:
        """Return the boundary of leaf ``i`` in its plane coordinates : (m, 2) (sides as the curves they are)."""
        tri = self.leaf_triangle[i]
        flags = int(self.leaf_uv[i])
        sq = np.array([flags & 1, flags & 2], dtype=bool)
        quad = self.leaf_quadrant[i]
        uv = np.where(sq, tri**2, tri)
        s = np.linspace(0.0, 1.0, samples_per_side, endpoint=False)[:, None]
        sides = [(1.0 - s) * uv[e] + s * uv[(e + 1) % 3] for e in range(3)]
        pts = np.vstack(sides + [uv[:1]])
        return np.where(sq, np.sqrt(np.maximum(pts, 0.0)) * quad, pts)


@dataclass(frozen=True)
class SampleCloud:
    """Samples on a CSG surface.

    positions : (n, 3) float64 — on the surface of quadric ``quadric_ids[i]``.
    normals : (n, 3) float64 — unit outward normals of that quadric (eq. 4).
    quadric_ids : (n,) int32 — index into ``normal_form.quadrics``.
    radii : (n,) float64 — splat radius (the requested radius, or less with ``reduce_radius``).
    clip_start, clip_count : (n,) int32 — slice of ``clip_indices`` holding the sample's clip set.
    clip_indices : (k,) int32 — the clip indirection buffer (normal-form indices, each distinct
        set stored once).
    radius : float — the requested splat radius.
    normal_form : NormalForm — what was sampled (world coordinates).
    stats : SamplingStats; trace : SamplingTrace or None.
    frame : ModelFrame or None — the normalised frame the sampler worked in
        (:mod:`csgnb.csg.normalisation`): ``frame.to_local(positions)`` gives coordinates of unit
        size, where the quadrics keep full precision even for models far from the origin.
    bounds : (center (3,) float64, radius float) or None — the bounding sphere the cloud was sampled in
        (``sample_csg(bounds=...)``), None if none was given: what to pass to sample the same region again.

    Guarantee (§4.2): every sample lies on the CSG surface, and every point of the CSG surface
    (inside the bounds) has a sample on the same quadric within its radius.
    """

    positions: np.ndarray
    normals: np.ndarray
    quadric_ids: np.ndarray
    radii: np.ndarray
    clip_start: np.ndarray
    clip_count: np.ndarray
    clip_indices: np.ndarray
    radius: float
    normal_form: NormalForm
    stats: SamplingStats
    trace: SamplingTrace | None = None
    frame: ModelFrame | None = None
    bounds: tuple | None = None

    def __len__(self) -> int:
        return len(self.positions)

    def clip_set(self, i: int) -> np.ndarray:
        """Return the clip set of sample ``i`` : (c,) int32 normal-form indices."""
        s = int(self.clip_start[i])
        return self.clip_indices[s : s + int(self.clip_count[i])]

    def quadric_buffer(self, dtype=np.float32) -> np.ndarray:
        """Return the quadric buffer of §6 : (n_quadrics, 10) — a00 a01 a02 a03 a11 a12 a13 a22 a23 a33."""
        iu = np.triu_indices(4)
        return np.array([q.matrix[iu] for q in self.normal_form.quadrics], dtype=dtype).reshape(-1, 10)

    def to_pyvista(self):
        """Return a ``pyvista.PolyData`` point cloud with point data.

        Point data: ``normals`` (n, 3), ``quadric_id``, ``radius``, ``clip_count``.
        """
        try:
            import pyvista as pv
        except ImportError as exc:  # pragma: no cover - pyvista is a dependency
            raise ImportError("SampleCloud.to_pyvista needs pyvista: pip install pyvista") from exc
        cloud = pv.PolyData(np.ascontiguousarray(self.positions))
        cloud.point_data["normals"] = self.normals
        cloud.point_data["quadric_id"] = self.quadric_ids
        cloud.point_data["radius"] = self.radii
        cloud.point_data["clip_count"] = self.clip_count
        cloud.set_active_vectors("normals")
        return cloud

    def __repr__(self) -> str:
        s = self.stats
        return (
            f"SampleCloud({s.samples} samples on {s.sampled_quadrics}/{s.quadrics} quadrics, radius {self.radius:g}, "
            f"{s.distance_queries} distance queries, {s.clip_indices} clip indices)"
        )


#: FNV-1a on 63 bits, written so that no operation overflows an int64 (jitted or not, the same hashes):
#: the offset basis masked to 63 bits, the prime 2⁴⁰ + 435 split into 32-bit limbs.
_MASK63 = (1 << 63) - 1
_MASK32 = (1 << 32) - 1
_MASK31 = (1 << 31) - 1
_FNV_OFFSET = 0xCBF29CE484222325 & _MASK63
_FNV_PRIME_LO = 435
_FNV_PRIME_HI = 1 << 8


@jit
def _fnv_step(h, v):
    """Return (h ^ v) · FNV prime mod 2⁶³ for 0 ≤ h, v < 2⁶³, from 32-bit limbs (every product < 2⁴³)."""
    x = h ^ v
    lo = x & _MASK32
    hi = x >> 32
    p = lo * _FNV_PRIME_LO
    mid = (p >> 32) + hi * _FNV_PRIME_LO + lo * _FNV_PRIME_HI
    return ((mid & _MASK31) << 32) | (p & _MASK32)


@jit
def _dedup_kernel(ptr, idx, start, count, buf):
    """Store each distinct clip set once in ``buf``; returns the buffer length.

    Sets are hashed (FNV-1a on 63 bits, ``_fnv_step``, over their ascending indices) into a dict of
    buffer offsets and compared element-wise, with linear probing on a hash collision.
    """
    offsets = Dict.empty(key_type=types.int64, value_type=types.int64)
    lengths = Dict.empty(key_type=types.int64, value_type=types.int64)
    nb = 0
    prev_a, prev_c, prev_s = 0, -1, 0  # the last non-empty set and where it is stored (a leaf's samples
    # mostly share theirs)
    for i in range(start.shape[0]):
        a, b = ptr[i], ptr[i + 1]
        c = b - a
        count[i] = c
        if c == 0:
            start[i] = 0
            continue
        if c == prev_c:
            same = True
            for k in range(c):
                if idx[prev_a + k] != idx[a + k]:
                    same = False
                    break
            if same:  # the very set stored last: no hashing, no lookup
                start[i] = prev_s
                prev_a = a
                continue
        prev_a, prev_c = a, c
        h = _FNV_OFFSET
        for k in range(a, b):
            h = _fnv_step(h, idx[k])
        h = h ^ c
        while True:
            if h in offsets:
                s = offsets[h]
                same = lengths[h] == c
                if same:
                    for k in range(c):
                        if buf[s + k] != idx[a + k]:
                            same = False
                            break
                if same:
                    start[i] = s
                    prev_s = s
                    break
                h = (h + 1) & _MASK63
            else:
                offsets[h] = nb
                lengths[h] = c
                for k in range(c):
                    buf[nb + k] = idx[a + k]
                start[i] = nb
                prev_s = nb
                nb += c
                break
    return nb


def _as_index_array(values, name: str) -> np.ndarray:
    arr = as_finite_array(values, None, name).reshape(-1) if not (
        isinstance(values, np.ndarray) and values.dtype.kind in "iu") else values.reshape(-1)
    if np.any(arr != np.round(arr)):
        raise CsgnbError(f"{name} must hold integers")
    return arr.astype(np.int64)


def deduplicate_clip_sets(ptr: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (start, count, buffer) with every distinct clip set stored once (§6).

    ptr : (n + 1,) int64 and idx : (m,) int64 — sample i's set is ``idx[ptr[i]:ptr[i + 1]]``.
    Returns start, count : (n,) int32 and buffer : (k,) int32.
    """
    ptr = _as_index_array(ptr, "ptr")
    idx = _as_index_array(idx, "idx")
    if len(ptr) == 0 or ptr[0] != 0 or np.any(np.diff(ptr) < 0) or ptr[-1] != len(idx):
        raise CsgnbError("ptr must start at 0, be non-decreasing and end at len(idx)")
    if len(idx) and (idx.min() < 0 or idx.max() > np.iinfo(np.int32).max):
        raise CsgnbError(f"idx must hold quadric indices in [0, 2**31) (the buffer is int32), got values in "
                         f"[{idx.min()}, {idx.max()}]")
    return _deduplicate(ptr, idx)


def _deduplicate(ptr: np.ndarray, idx: np.ndarray):
    """``deduplicate_clip_sets`` for the sampler's own (valid, int64) arrays."""
    n = len(ptr) - 1
    start = np.empty(n, dtype=np.int32)
    count = np.empty(n, dtype=np.int32)
    buf = np.empty(max(len(idx), 1), dtype=np.int32)
    nb = _dedup_kernel(ptr, idx, start, count, buf)
    return start, count, buf[:nb].copy()
