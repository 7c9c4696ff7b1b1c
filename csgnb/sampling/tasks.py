"""Sampling tasks: for each quadric of a normal form, its regions, plane frames and pruned eq. 22 data.

A task holds everything the sampling kernel needs for one quadric Q_ab:

* the box ``box`` that contains the part of its surface that can be on the CSG surface (term
  box ∩ box of the quadric's convex side, :mod:`csgnb.csg.bounds`);
* its basic regions as triangle *jobs* on its sampling planes, each on one sheet ``t = ±h``
  (§4.1, :mod:`.domains`; a plane gets its polygon in the box);
* the quadrics that can matter to d_Qab near the box (eq. 22), found once from conservative
  distances at the box center. With ``R`` the largest |d_Qab| the kernel uses (``rcap``, it
  clamps to it) the kernel evaluates quadrics only at points within ``2R`` of the box: its own
  term's max includes the signed distance to the box grown by ``R`` (``own_box``, a superset of
  the quadric's surface in the term, so the max stays conservative), which reaches ``R`` — and
  ends the evaluation — farther out. A quadric whose surface stays farther than ``R`` from that
  neighbourhood (its conservative distance at the box center exceeds the box's half diagonal
  plus ``3R``) either cannot change a clamped value (its side holds the neighbourhood: dropped)
  or decides its whole term (it excludes the neighbourhood: the term is dropped; for the own
  term the quadric has no task). Terms whose box is farther than ``2R`` are dropped too.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.csg.bounds import box_is_empty, intersect_boxes, surface_box
from csgnb.csg.distance import quadric_distance
from csgnb.csg.normal_form import NormalForm
from csgnb.quadric.evaluate import ieee_jit
from csgnb.sampling.domains import quadric_jobs

__all__ = ["QuadricTask", "build_tasks"]


@dataclass(frozen=True)
class QuadricTask:
    """Input of the sampling kernel for one quadric (see the module docstring).

    index : int — the quadric's index in the normal form; term : int — its term.
    scale : float — size of the model (largest |coordinate| of the term boxes, at least 1).
    box : (6,) float64 — (lo, hi) where its samples can lie; its regions are cut to it.
    own_box : (6,) float64 — ``box`` grown by ``rcap`` (part of the own term's max).
    rcap : float — largest |d_Qab| used (distances are clamped to it).
    own : (k,) int64 — other quadrics of its term that matter (sorted).
    other_ptr : (m + 1,) int64, other_idx : int64 — the other terms that matter, term e being
        ``other_idx[other_ptr[e]:other_ptr[e + 1]]`` (possibly empty: the term holds the whole
        neighbourhood).
    origin : (3, 3), frame : (3, 3, 3), alpha : (3, 3) float64, flat : (3,) bool — sampling
        plane k's origin, columns (x axis, y axis, normal), (αₓ, α_y, α_c) and whether δ ≡ 1.
    job_plane : (J,) int64, job_sheet : (J,) float64 (±1), job_tri : (J, 3, 2) float64,
        job_arc : (J,) int64 (edge e = v[e] → v[e+1] is a conic arc, -1 none),
        job_quadrant : (J, 2) float64 (signs of the arc's quadrant).
    """

    index: int
    term: int
    scale: float
    box: np.ndarray
    own_box: np.ndarray
    rcap: float
    own: np.ndarray
    other_ptr: np.ndarray
    other_idx: np.ndarray
    origin: np.ndarray
    frame: np.ndarray
    alpha: np.ndarray
    flat: np.ndarray
    job_plane: np.ndarray
    job_sheet: np.ndarray
    job_tri: np.ndarray
    job_uv: np.ndarray
    job_quadrant: np.ndarray


# -- pruning for eq. 22 ----------------------------------------------------------------------------


@ieee_jit
def _distance_matrix_kernel(C, points, out):
    """out[s, j] = d(Q_j, points[s]) (eq. 12)."""
    for s in range(points.shape[0]):
        for j in range(C.shape[0]):
            out[s, j] = quadric_distance(C, j, points[s, 0], points[s, 1], points[s, 2])


def _box_gap(a: np.ndarray, b: np.ndarray) -> float:
    gap = np.maximum(0.0, np.maximum(a[:3] - b[3:], b[:3] - a[3:]))
    return float(np.linalg.norm(gap))


def build_tasks(nf: NormalForm, term_box: np.ndarray, radius: float) -> list[QuadricTask]:
    """Return one task per quadric whose surface can contribute (see the module docstring).

    Parameters
    ----------
    nf : NormalForm
    term_box : (T, 6) float64 — a finite box per term (``csgnb.csg.term_boxes``); empty rows skip the term.
    radius : float — the splat radius (the clamp ``rcap`` is at least 4 radii, so that clip sets,
        which look a radius around a sample, never miss a pruned quadric).
    """
    n = len(nf)
    scale = float(np.max(np.abs(term_box[np.isfinite(term_box)]), initial=1.0))
    term_of, surface, orient = nf.term_of, nf.surface, nf.orientation
    boxes = np.empty((n, 6))
    for s in range(n):
        tb = term_box[term_of[s]]
        boxes[s] = tb if box_is_empty(tb) else intersect_boxes(surface_box(nf.quadrics[s], tb, scale), tb)
    live = np.array([not box_is_empty(b) for b in boxes], dtype=bool)
    centers = np.zeros((n, 3))
    centers[live] = 0.5 * (boxes[live, :3] + boxes[live, 3:])
    D = np.empty((n, n))
    _distance_matrix_kernel(np.ascontiguousarray(nf.coefficients), np.ascontiguousarray(centers), D)
    term_live = np.array([not box_is_empty(b) for b in term_box], dtype=bool)
    tasks = []
    for s in np.flatnonzero(live):
        box = boxes[s]
        half = 0.5 * float(np.linalg.norm(box[3:] - box[:3]))
        rcap = max(half, 4.0 * radius)
        thr = half + 3.0 * rcap
        a = int(term_of[s])
        row = D[s]
        own = nf.term(a)
        own = own[own != s]
        if np.any(row[own] >= thr):
            continue  # another quadric of the term excludes the whole neighbourhood
        own = own[row[own] > -thr]
        ptr, idx = [0], []
        own_keys = {(int(surface[j]), int(orient[j])) for j in nf.term(a)}
        for i in range(nf.n_terms):
            if i == a or not term_live[i] or _box_gap(term_box[i], box) >= 2.0 * rcap:
                continue
            members = nf.term(i)
            twin = surface[members] == surface[s]
            if i > a and np.any(twin & (orient[members] == orient[s])):
                continue
            members = members[~twin]
            # Factors shared with the own term: where the own term holds (own max < 0) a shared
            # quadric is negative anyway, so term i holds iff its other quadrics do; where it does
            # not, d_Qab > 0 already. Dropping them keeps eq. 22 valid and avoids zero radii along
            # the shared quadric (A ∩ B ∪ A ∩ C, from distributing A ∩ (B ∪ C)). A shared quadric
            # of opposite orientation means term i never holds where the own term does.
            keys = [(int(surface[j]), int(orient[j])) for j in members]
            if any((k, -o) in own_keys for k, o in keys):
                continue
            members = members[[key not in own_keys for key in keys]] if len(members) else members
            if np.any(row[members] >= thr):
                continue
            members = members[row[members] > -thr]
            idx.extend(members.tolist())
            ptr.append(len(idx))
        jobs = quadric_jobs(nf.quadrics[s], box)
        if len(jobs[4]) == 0:
            continue
        tasks.append(
            QuadricTask(
                int(s),
                a,
                scale,
                box,
                np.concatenate([box[:3] - rcap, box[3:] + rcap]),
                rcap,
                np.ascontiguousarray(own, dtype=np.int64),
                np.array(ptr, dtype=np.int64),
                np.array(idx, dtype=np.int64),
                *jobs,
            )
        )
    return tasks
