"""Sampling tasks: for every quadric of a normal form, its jobs, plane frames and pruned eq. 22 data.

A task holds everything the sampling kernel needs for one quadric Q_ab:

* the box that contains the part of its surface that can be on the CSG surface (term box ∩ box
  of the quadric's convex side, ``csgnb.csg.bounds.surface_boxes``);
* its basic regions as triangle *jobs* on its sampling planes, each on one sheet (§4.1,
  :mod:`.domains`);
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

Everything is built by numba kernels for all quadrics at once and kept in one :class:`TaskSet`
of flat arrays, so that a model's set-up costs microseconds per quadric, not Python calls.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from csgnb._jit import jit
from csgnb.csg.distance import quadric_distance
from csgnb.quadric.arguments import as_finite_array, as_instance, as_positive
from csgnb.quadric.frames import frame_kernel
from csgnb.sampling.domains import JOBS_PER_QUADRIC, jobs_kernel

__all__ = ["TaskSet", "build_task_set", "build_tasks"]


class TaskSet(NamedTuple):
    """Input of the sampling kernels for all tasks of a model (t tasks, J jobs), flat arrays.

    quadric : (t,) int64 — normal-form index of each task's quadric; term : (t,) int64.
    box, own_box : (t, 6) float64 — where its samples can lie, and that box grown by ``rcap``.
    rcap : (t,) float64 — largest |d_Qab| used (distances are clamped to it).
    length : (t,) float64 — the smallest length of the quadric's heightfields (a radius of curvature:
        1/(2|α|) of a graph, |b|/2 of a parabolic sheet, √|α_c| of a central one): regions are not
        given up before they are far smaller than it (``tolerances.MIN_REGION``).
    own_ptr : (t + 1,) int64, own : int64 — other quadrics of its term that matter.
    other_ptr : (t + 1,) int64 — task i's other terms are slices ``slice_ptr[e]:slice_ptr[e + 1]``
        of ``other`` for e in ``other_ptr[i]:other_ptr[i + 1]`` (a slice may be empty: the term
        holds the whole neighbourhood).
    origin : (t, 3, 3), frame : (t, 3, 3, 3), coef : (t, 3, 5), form : (t, 3) int64 — per sampling
        plane its origin, columns (x axis, y axis, normal), heightfield and form code.
    job_ptr : (t + 1,) int64 — task i's jobs; job_task, job_plane : (J,) int64, job_sheet : (J,),
        job_tri : (J, 3, 2), job_uv : (J,) int64 (squared-coordinate flags), job_quadrant : (J, 2),
        job_flags : (J,) int64 (bit 0: a feature search already failed in this region).
    """

    quadric: np.ndarray
    term: np.ndarray
    box: np.ndarray
    own_box: np.ndarray
    rcap: np.ndarray
    length: np.ndarray
    own_ptr: np.ndarray
    own: np.ndarray
    other_ptr: np.ndarray
    slice_ptr: np.ndarray
    other: np.ndarray
    origin: np.ndarray
    frame: np.ndarray
    coef: np.ndarray
    form: np.ndarray
    job_ptr: np.ndarray
    job_task: np.ndarray
    job_plane: np.ndarray
    job_sheet: np.ndarray
    job_tri: np.ndarray
    job_uv: np.ndarray
    job_quadrant: np.ndarray
    job_flags: np.ndarray

    def lists(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return task ``i``'s own-term list, its term slices (into the third) and the other-term list."""
        own = self.own[self.own_ptr[i] : self.own_ptr[i + 1]]
        slices = self.slice_ptr[self.other_ptr[i] : self.other_ptr[i + 1] + 1]
        return np.ascontiguousarray(own), np.ascontiguousarray(slices), self.other

    def with_regions(self, UR: np.ndarray) -> TaskSet:
        """Return this task set with the regions ``UR`` (rows of ``kernel._record_region``) appended as jobs."""
        src = UR[:, 5].astype(np.int64)
        tri = UR[:, 6:12].reshape(-1, 3, 2)
        return self._replace(
            job_task=np.concatenate([self.job_task, self.job_task[src]]),
            job_plane=np.concatenate([self.job_plane, self.job_plane[src]]),
            job_sheet=np.concatenate([self.job_sheet, self.job_sheet[src]]),
            job_tri=np.ascontiguousarray(np.concatenate([self.job_tri, tri])),
            job_uv=np.concatenate([self.job_uv, self.job_uv[src]]),
            job_quadrant=np.ascontiguousarray(np.concatenate([self.job_quadrant, self.job_quadrant[src]])),
            job_flags=np.concatenate([self.job_flags, np.ones(len(src), dtype=np.int64)]),
        )


@jit
def _box_gap(a, b):
    g = 0.0
    for e in range(3):
        d = max(0.0, max(a[e] - b[3 + e], b[e] - a[3 + e]))
        g += d * d
    return math.sqrt(g)


@jit
def _tasks_kernel(Ms, C, term_start, surface, orient, boxes, term_box, radius, unit,
                  t_quadric, t_term, t_box, t_rcap, t_length, own_ptr, own, other_ptr, slice_ptr, other,
                  origin, frame, coef, form, job_ptr, jt, jp, js, ju, jq, job_task):
    """Fill the task arrays (capacity n tasks); returns (tasks, own entries, slices, other entries, jobs)."""
    n = Ms.shape[0]
    T = term_start.shape[0] - 1
    term_of = np.empty(n, dtype=np.int64)
    for t in range(T):
        for q in range(term_start[t], term_start[t + 1]):
            term_of[q] = t
    term_live = np.empty(T, dtype=np.bool_)
    for t in range(T):
        b = term_box[t]
        term_live[t] = b[0] <= b[3] and b[1] <= b[4] and b[2] <= b[5]
    nt = 0
    no = 0
    ns = 0
    nx = 0
    nj = 0
    own_ptr[0] = 0
    other_ptr[0] = 0
    slice_ptr[0] = 0
    job_ptr[0] = 0
    center = np.empty(3)
    axes = np.empty((3, 3))
    lam = np.empty(3)
    beta = np.empty(3)
    fm = np.empty(3, dtype=np.int64)
    cf = np.empty((3, 5))
    row = np.empty(n)
    for s in range(n):
        bx = boxes[s]
        if not (bx[0] <= bx[3] and bx[1] <= bx[4] and bx[2] <= bx[5]):
            continue
        cx, cy, cz = 0.5 * (bx[0] + bx[3]), 0.5 * (bx[1] + bx[4]), 0.5 * (bx[2] + bx[5])
        half = 0.5 * math.sqrt((bx[3] - bx[0]) ** 2 + (bx[4] - bx[1]) ** 2 + (bx[5] - bx[2]) ** 2)
        rcap = max(half, 4.0 * radius)
        thr = half + 3.0 * rcap
        for j in range(n):
            row[j] = quadric_distance(C, j, cx, cy, cz)
        a = term_of[s]
        skip = False
        o0 = no
        for j in range(term_start[a], term_start[a + 1]):
            if j == s:
                continue
            if row[j] >= thr:
                skip = True  # another quadric of the term excludes the whole neighbourhood
                break
            if row[j] > -thr:
                own[no] = j
                no += 1
        if skip:
            no = o0
            continue
        x0, s0 = nx, ns
        for i in range(T):
            if i == a or not term_live[i] or _box_gap(term_box[i], bx) >= 2.0 * rcap:
                continue
            drop = False
            e0 = nx
            for j in range(term_start[i], term_start[i + 1]):
                if surface[j] == surface[s]:
                    if i > a and orient[j] == orient[s]:
                        drop = True  # the surface is emitted by the first term that has it
                        break
                    continue
                # Factors shared with the own term: where the own term holds (own max < 0) a shared
                # quadric is negative anyway, so term i holds iff its other quadrics do; where it
                # does not, d_Qab > 0 already. Dropping them keeps eq. 22 valid and avoids zero
                # radii along the shared quadric (A ∩ B ∪ A ∩ C, from distributing A ∩ (B ∪ C)).
                # A shared quadric of opposite orientation: term i never holds where the own does.
                shared = False
                for k in range(term_start[a], term_start[a + 1]):
                    if surface[k] == surface[j]:
                        if orient[k] != orient[j]:
                            drop = True
                        shared = True
                        break
                if drop:
                    break
                if shared:
                    continue
                if row[j] >= thr:
                    drop = True
                    break
                if row[j] > -thr:
                    other[nx] = j
                    nx += 1
            if drop:
                nx = e0
                continue
            ns += 1
            slice_ptr[ns] = nx
        # jobs
        frame_kernel(Ms[s], center, axes, lam, beta, fm, cf)
        j0 = nj
        nj = jobs_kernel(center, axes, fm, cf, bx, unit, jt, jp, js, ju, jq, np.int64(nj))
        if nj == j0:
            no, nx, ns = o0, x0, s0
            continue
        for j in range(j0, nj):
            job_task[j] = nt
        t_quadric[nt] = s
        t_term[nt] = a
        for e in range(6):
            t_box[nt, e] = bx[e]
        t_rcap[nt] = rcap
        length = math.inf
        for k in range(3):
            if fm[k] == 0:
                continue
            ax, bx, ay, by, ac = cf[k, 0], cf[k, 1], cf[k, 2], cf[k, 3], cf[k, 4]
            if fm[k] == 2:  # a graph t = αx² + ...: radius of curvature 1/(2|α|) at its vertex
                for a_ in (ax, ay):
                    if a_ != 0.0:
                        length = min(length, 0.5 / abs(a_))
            else:
                for b_ in (bx, by):
                    if b_ != 0.0:
                        length = min(length, 0.5 * abs(b_))
                if ac != 0.0:
                    length = min(length, math.sqrt(abs(ac)))
        t_length[nt] = length
        for k in range(3):
            for e in range(3):
                origin[nt, k, e] = center[e]
            i = (k + 1) % 3
            j = (k + 2) % 3
            for e in range(3):
                frame[nt, k, e, 0] = axes[e, i]
                frame[nt, k, e, 1] = axes[e, j]
                frame[nt, k, e, 2] = axes[e, k]
            for e in range(5):
                coef[nt, k, e] = cf[k, e]
            form[nt, k] = fm[k]
        nt += 1
        own_ptr[nt] = no
        other_ptr[nt] = ns
        job_ptr[nt] = nj
    return nt, no, ns, nx, nj


def build_task_set(nf, boxes: np.ndarray, term_box: np.ndarray, radius: float, unit: float = 1.0) -> TaskSet:
    """Return the :class:`TaskSet` of a normal form (see the module docstring).

    Parameters
    ----------
    nf : NormalForm
    boxes : (n, 6) float64 — per quadric the box of its surface within its term box (empty rows:
        no task); term_box : (T, 6) float64 — the term boxes.
    radius : float — the splat radius (the clamp ``rcap`` is at least 4 radii, so that clip sets,
        which look a radius around a sample, never miss a pruned quadric).
    unit : float — the model size (the sliver test of the domains).
    """
    from csgnb.csg.normal_form import NormalForm

    as_instance(nf, NormalForm, "nf", "a NormalForm (csgnb.csg.to_normal_form)")
    n = len(nf)
    T = nf.n_terms
    boxes = as_finite_array(boxes, (n, 6), "boxes", finite=False)
    term_box = as_finite_array(term_box, (T, 6), "term_box", finite=False)
    radius = as_positive(radius, "radius")
    unit = as_positive(unit, "unit")
    Ms = np.ascontiguousarray(np.array([q.matrix for q in nf.quadrics]).reshape(-1, 4, 4))
    C = np.ascontiguousarray(nf.coefficients)
    t_quadric = np.empty(n, dtype=np.int64)
    t_term = np.empty(n, dtype=np.int64)
    t_box = np.empty((n, 6))
    t_rcap = np.empty(n)
    t_length = np.empty(n)
    own_ptr = np.empty(n + 1, dtype=np.int64)
    own = np.empty(max(n * n, 1), dtype=np.int64)
    other_ptr = np.empty(n + 1, dtype=np.int64)
    slice_ptr = np.empty(n * T + 1, dtype=np.int64)
    other = np.empty(max(n * n, 1), dtype=np.int64)
    origin = np.empty((n, 3, 3))
    frame = np.empty((n, 3, 3, 3))
    coef = np.empty((n, 3, 5))
    form = np.empty((n, 3), dtype=np.int64)
    job_ptr = np.empty(n + 1, dtype=np.int64)
    J = JOBS_PER_QUADRIC * n
    jt = np.empty((J, 3, 2))
    jp = np.empty(J, dtype=np.int64)
    js = np.empty(J)
    ju = np.empty(J, dtype=np.int64)
    jq = np.empty((J, 2))
    job_task = np.empty(J, dtype=np.int64)
    nt, no, ns, nx, nj = _tasks_kernel(
        Ms, C, np.ascontiguousarray(nf.term_start), np.ascontiguousarray(nf.surface),
        np.ascontiguousarray(nf.orientation), np.ascontiguousarray(boxes), np.ascontiguousarray(term_box),
        float(radius), float(unit), t_quadric, t_term, t_box, t_rcap, t_length, own_ptr, own, other_ptr, slice_ptr,
        other, origin, frame, coef, form, job_ptr, jt, jp, js, ju, jq, job_task,
    )  # fmt: skip
    box = t_box[:nt]
    rc = t_rcap[:nt]
    own_box = np.concatenate([box[:, :3] - rc[:, None], box[:, 3:] + rc[:, None]], axis=1)
    return TaskSet(
        t_quadric[:nt], t_term[:nt], box, own_box, rc, t_length[:nt], own_ptr[: nt + 1], own[:no], other_ptr[: nt + 1],
        slice_ptr[: ns + 1], other[:nx], origin[:nt], frame[:nt], coef[:nt], form[:nt], job_ptr[: nt + 1],
        job_task[:nj], jp[:nj], js[:nj], jt[:nj], ju[:nj], jq[:nj], np.zeros(nj, dtype=np.int64),
    )  # fmt: skip


def build_tasks(nf, term_box: np.ndarray, radius: float) -> TaskSet:
    """Return the :class:`TaskSet` of a normal form with finite term boxes (surface boxes derived here)."""
    from csgnb.csg.bounds import surface_boxes
    from csgnb.csg.normal_form import NormalForm

    as_instance(nf, NormalForm, "nf", "a NormalForm (csgnb.csg.to_normal_form)")
    term_box = np.ascontiguousarray(as_finite_array(term_box, (nf.n_terms, 6), "term_box", finite=False))
    finite = term_box[np.all(np.isfinite(term_box), axis=1)]
    unit = float(np.max(np.abs(finite))) if len(finite) else 1.0
    return build_task_set(nf, surface_boxes(nf, term_box, unit), term_box, radius, unit or 1.0)
