"""The adaptive sampling kernel of §4.2: classify, split or cover the regions of every quadric.

For every job (a triangle of a basic region on one sheet) the kernel keeps a depth-first stack
of triangles with d_Qab (eq. 22) known at their corners. A region lies within ``bulge`` of its
straight triangle T (:mod:`.geometry`; 0 for straight sides), so every radius below is shortened
by the bulge and tested on T. With δ the distortion bound over T's box grown by the bulge and r
the splat radius:

1. *single sample*: if a corner is on the CSG surface (d < 0, or d ≤ ``on_surface``: a point
   of a feature curve, in the closure of the surface) and the disc of radius r/δ around it holds
   the region, emit that corner and stop (the sample covers the region whatever the rest is).
   Counting corners on feature curves matters when a curve runs along region edges
   (axis-aligned models): the regions outside it would otherwise never be classified;
2. *classify*: if all corners have the same sign and the discs of radius |d|/δ cover the region
   (an exact power-diagram test on T), it is kept — all of it is on the CSG surface: cover it with
   a triangular lattice such that every point is within r/δ of a lattice point — or discarded;
3. *feature point* (tangency curves): a region whose corners are all off the surface (d > 0) but
   whose discs do not cover it, once smaller than ``tolerances.FEATURE_REGION`` of a sample's
   reach, is searched along its edges for a point with d ≤ ``on_surface`` — a root of either
   part of eq. 22 (own term, other terms) where that part changes sign between the corners (once
   per lineage of regions). Such a point is in the closure of the CSG surface on Q_ab
   (the criterion corners meet in rule 1), and one sample there covers the region: rule 1 at a
   searched point. This resolves curves where d_Qab is positive on both sides and zero on the
   curve (a capsule's cap inside its sphere, a boss's base on a plate, the tip where a curve
   meets a box edge), where no disc cover can close. Counted in ``counters[6]``;
4. optionally (``min_size`` > 0) discard unclassified regions smaller than ``min_size``
   (faster, but can leave holes, as the paper says);
5. otherwise split the longest edge (at a point of its (U, V)-segment, so that the halves are
   (U, V)-triangles again), evaluate d_Qab at the new corner and recurse. Regions below
   ``tolerances.MIN_REGION`` of the radius (and of the quadric's radius of curvature, ``tasks``) are
   given up — and then resolved after pass 1 if a
   single sample of the same quadric covers them (``cover_by_neighbours``: the tips of surface
   patches, where d_Qab vanishes only at the tip); the rest is counted as unresolved: isolated
   points where d_Qab touches 0 with no sample of the quadric nearby (a sphere touching a plane
   from inside at one point).

Kept regions that would need many samples are split further without distance queries while
their distortion bound varies (``refine``): a lattice is as dense as its region's largest δ
demands. The world distance between two points of a region is at most δ times their (x, y)
distance (the lift stretches by at most δ), which turns world radii into (x, y) radii. Each
sample carries its clip set: the quadrics of its term whose surface may pass within its radius
(§6), from per-region lists of the quadrics still in play (pruned as regions shrink) unless the
corner distances prove the set empty.

Two passes keep the memory traffic low: ``subdivide_all`` records the emitting leaves of all
tasks (:class:`.tasks.TaskSet`), ``emit_all`` writes their samples into arrays the caller
allocated with numpy (numpy asks
for huge pages; page faults on fresh numba buffers cost more than the sampling itself here).
Neither kernel binds an array to a new name inside its loops — numba reference-counts such
bindings (re-bound buffers, array arguments of inlined helpers) with atomic operations, which
cost 60 % of the time in a first version. So the helpers take scalars, the distance and the
emission are written out in the loops, and both kernels stop when a buffer is full and are
resumed by the caller with a larger one (at a job, or a leaf, boundary).
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._threads import run_parts, threads
from csgnb.csg.distance import box_distance, quadric_distance
from csgnb.quadric import tolerances as tol
from csgnb.quadric.distortions import delta_at_points
from csgnb.quadric.evaluate import ieee_jit, inline_jit
from csgnb.quadric.frames import FORM_SHEETS
from csgnb.sampling.geometry import (
    _arc_deviation,
    _norm2,
    arc_midpoint,
    corner_reach,
    delta_range,
    discs_cover,
    lattice_plan,
    lift,
    segment_point,
)

__all__ = [
    "relative_distance_pruned",
    "relative_distance_parts",
    "subdivide_all",
    "emit_all",
    "cover_by_neighbours",
    "COUNTERS",
    "STATUS",
    "OVERFLOW",
    "LEAF_FLOAT_FIELDS",
    "LEAF_INT_FIELDS",
]

#: Leaf status codes recorded in traces.
STATUS = {"single": 0, "kept": 1, "discarded": 2, "small": 3, "unresolved": 4, "neighbour": 5}

#: Columns of the leaf buffers of pass 1: floats (triangle x₀ y₀ … x₂ y₂, the world point of its first
#: vertex, δ, aux, reach, rho) and
#: integers (job, kind, vertices, samples); see ``subdivide_quadric``.
LEAF_FLOAT_FIELDS = tuple(f"{a}{k}" for k in range(3) for a in "xy") + ("wx", "wy", "wz", "_9", "_10", "_11") + (
    "delta", "aux", "reach", "rho")
LEAF_INT_FIELDS = ("job", "kind", "corners", "count", "clip_start", "clip_len")
#: Counters of ``subdivide_all`` (``counters[k]``).
COUNTERS = ("distance_queries", "regions", "unresolved", "jobs", "quadric_distances", "feature_searches",
            "feature_points")
#: Overflow codes returned by ``subdivide_all``: which buffer to grow before resuming.
OVERFLOW = {"none": 0, "leaves": 1, "trace_leaves": 2, "trace_points": 3, "clip_lists": 4, "unresolved": 5}

_SQRT3 = math.sqrt(3.0)
_MAX_DEPTH = 200
#: Kept regions needing at least this many samples are split further (without distance queries)
#: while their distortion varies by more than ``_REFINE_RATIO``: a lattice is as dense as the
#: region's largest δ demands, so tighter bounds mean fewer samples.
_REFINE_SAMPLES = 256
_REFINE_RATIO = 1.2
#: Illinois steps of the feature-point search (superlinear: rounding is reached in about 10).
_ROOT_STEPS = 40


@inline_jit
def relative_distance_pruned(C, act, a0, na, own_box, other_ptr, other_idx, rcap, x, y, z, keep_below, out, o0):
    """Return (d_Qab(S, p) clamped to [-rcap, rcap], n) from pruned lists (eq. 22).

    ``act[a0:a0 + na]`` are the quadrics of the own term still in play; the own max also holds
    the signed distance to ``own_box``, an exact distance to a superset of the quadric's surface in
    the term, so the bound stays conservative and reaches ``rcap`` beyond the neighbourhood where
    the lists hold. ``other_ptr`` (m + 1,) slices ``other_idx`` into the other terms. If
    ``keep_below`` > 0, the own-term quadrics with d > -keep_below — those that can still matter
    closer than that — are copied to ``out[o0:o0 + n]``. (The sampling kernel repeats this code
    inline in its loop; this function is its reference and its entry for the first corners.)
    """
    own_d = box_distance(own_box, x, y, z)
    n = 0
    for k in range(a0, a0 + na):
        j = act[k]
        dj = quadric_distance(C, j, x, y, z)
        own_d = max(own_d, dj)
        if keep_below > 0.0 and dj > -keep_below:
            out[o0 + n] = j
            n += 1
    if own_d >= rcap:
        return rcap, n
    other = math.inf
    for e in range(other_ptr.shape[0] - 1):
        m = -math.inf
        for k in range(other_ptr[e], other_ptr[e + 1]):
            m = max(m, quadric_distance(C, other_idx[k], x, y, z))
            if m >= other:
                break
        other = min(other, m)
        if other <= -rcap:
            return rcap, n
    d = max(-other, own_d)
    return min(max(d, -rcap), rcap), n


@ieee_jit
def relative_distance_parts(C, act, a0, na, own_box, slices, other_idx, x, y, z):
    """Return the two parts of eq. 22 at (x, y, z): (own-term max, −(min over the other terms)).

    d_Qab = max of the two. Unclamped, from the same pruned lists as ``relative_distance_pruned``
    (``slices`` (m + 1,) into ``other_idx``).
    """
    own_d = box_distance(own_box, x, y, z)
    for k in range(a0, a0 + na):
        own_d = max(own_d, quadric_distance(C, act[k], x, y, z))
    other = math.inf
    for e in range(slices.shape[0] - 1):
        m = -math.inf
        for k in range(slices[e], slices[e + 1]):
            m = max(m, quadric_distance(C, other_idx[k], x, y, z))
        other = min(other, m)
    return own_d, -other


@ieee_jit
def _feature_point(C, act, a0, na, own_box, slices, other_idx, plane, uv, sx, sy, v, on_surface):
    """Search the edges of the region ``v`` (6,) for a point with d_Qab ≤ ``on_surface``.

    ``plane`` (20,): origin, frame (row-major), form, (αₓ, bₓ, α_y, b_y, α_c), sheet. On every edge
    (a (U, V)-segment) where a part of eq. 22 (own term, other terms) changes sign between the
    corners, its root by the Illinois method: at a tangency curve both parts vanish there, so d_Qab
    does. Returns (found, x, y, evaluations).
    """
    form = int(plane[12])
    own_c = np.empty(3)
    oth_c = np.empty(3)
    for c in range(3):
        px, py, pz = lift(plane[0], plane[1], plane[2], plane[3], plane[4], plane[5], plane[6], plane[7], plane[8],
                          plane[9], plane[10], plane[11], form, plane[13], plane[14], plane[15], plane[16], plane[17],
                          plane[18], v[2 * c], v[2 * c + 1])
        own_c[c], oth_c[c] = relative_distance_parts(C, act, a0, na, own_box, slices, other_idx, px, py, pz)
    evals = 3
    for e in range(3):
        f = (e + 1) % 3
        ax_, ay_ = v[2 * e], v[2 * e + 1]
        bx_, by_ = v[2 * f], v[2 * f + 1]
        for part in range(2):
            fa = own_c[e] if part == 0 else oth_c[e]
            fb = own_c[f] if part == 0 else oth_c[f]
            if not (fa * fb < 0.0):
                continue
            lo, hi = 0.0, 1.0
            side = 0
            for _ in range(_ROOT_STEPS):
                s = (lo * fb - hi * fa) / (fb - fa)  # regula falsi, Illinois variant
                if not (lo < s < hi):
                    s = 0.5 * (lo + hi)
                x, y = segment_point(ax_, ay_, bx_, by_, sx, sy, uv, s)
                px, py, pz = lift(plane[0], plane[1], plane[2], plane[3], plane[4], plane[5], plane[6], plane[7],
                                  plane[8], plane[9], plane[10], plane[11], form, plane[13], plane[14], plane[15],
                                  plane[16], plane[17], plane[18], x, y)
                po, pt = relative_distance_parts(C, act, a0, na, own_box, slices, other_idx, px, py, pz)
                evals += 1
                if max(po, pt) <= on_surface:
                    return True, x, y, evals
                fs = po if part == 0 else pt
                if fs == 0.0 or hi - lo <= tol.ROOT_INTERVAL:
                    break
                if (fs < 0.0) == (fa < 0.0):
                    lo, fa = s, fs
                    if side == -1:
                        fb *= 0.5
                    side = -1
                else:
                    hi, fb = s, fs
                    if side == 1:
                        fa *= 0.5
                    side = 1
    return False, 0.0, 0.0, evals


@ieee_jit
def subdivide_all(
    C,
    ts,
    radius,
    min_size,
    min_region_factor,
    on_surface,
    sqrt3_mode,
    refine,
    trace,
    defer,
    LF,
    LI,
    LA,
    TT,
    TI,
    TP,
    TJ,
    UR,
    counters,
    job_start,
    job_end,
    nl,
    nla,
    nt,
    npt,
    nur,
):
    """Pass 1: classify and subdivide the jobs ``job_start:job_end`` of the tasks ``ts`` (a ``tasks.TaskSet``).

    Writes, from the given fill levels on:

    * leaves that emit samples: ``LF`` (cap, 16) float64 (``LEAF_FLOAT_FIELDS``: the triangle —
      its sample point alone for a single sample —, the world point of that first vertex, the
      distortion bound δ used, ``aux`` the
      distance from the samples below which no quadric of the term can come (single: |d_Qab| at
      the point; lattice: the slack of the keep discs), ``reach`` the world radius covering a
      single sample's region, ``rho`` the plane covering radius of a lattice), ``LI`` (cap, 6)
      int64 (``LEAF_INT_FIELDS``: global job, kind 0 single / 1 lattice, vertex count, sample
      count, and the slice of ``LA`` listing the quadrics that may reach into the leaf's splats —
      empty when the corner distances prove that none can);
    * if ``trace``: final regions ``TT`` (tcap, 6) (triangle) and ``TI`` (tcap, 5) = (job, uv,
      status, depth, plane); distance evaluations ``TP`` (pcap, 3) = (x, y, d_Qab), ``TJ`` (pcap,)
      = job;
    * regions for the neighbour rule ``UR`` (ucap, 14) (``_record_region``): those given up below
      ``min_region``, and — if ``defer`` — those whose feature search failed (to be re-subdivided
      by a second call with their triangles as jobs, ``job_flags`` bit 0 set, unless a neighbour
      sample covers them);
    * ``counters`` (7,) int64 += the ``COUNTERS``.

    Returns ``(nl, nla, nt, npt, nur, next_job, overflow)``: fill levels, the first job not done and an
    ``OVERFLOW`` code. On overflow the unfinished job's output is rolled back; grow that buffer
    and call again from ``next_job``.
    """
    own_ptr, own_all, other_ptr, slice_ptr, other_idx = ts.own_ptr, ts.own, ts.other_ptr, ts.slice_ptr, ts.other
    t_own_box, t_rcap, t_length = ts.own_box, ts.rcap, ts.length
    origin, frame, coef, pform = ts.origin, ts.frame, ts.coef, ts.form
    job_task, job_plane, job_sheet, job_tri = ts.job_task, ts.job_plane, ts.job_sheet, ts.job_tri
    job_uv, job_quadrant, job_flags = ts.job_uv, ts.job_quadrant, ts.job_flags
    n_jobs = min(job_end, job_task.shape[0])
    cap = LF.shape[0]
    tcap = TT.shape[0]
    pcap = TP.shape[0]
    smax = 2 * _MAX_DEPTH + 8
    S_v = np.empty((smax, 6))
    S_d = np.empty((smax, 3))
    S_b = np.empty((smax, 3))  # arc deviations of the sides v0→v1, v1→v2, v2→v0 (the bulge is their max)
    S_depth = np.empty(smax, dtype=np.int64)
    S_kept = np.zeros(smax, dtype=np.bool_)
    S_slack = np.empty(smax)
    # own-term quadrics in play per stack entry: a slice of A (lists of a DFS path nest)
    S_a0 = np.empty(smax, dtype=np.int64)
    S_an = np.empty(smax, dtype=np.int64)
    S_clamp = np.empty(smax)
    S_searched = np.zeros(smax, dtype=np.bool_)  # a feature search ran in this region's lineage
    longest_own = 0
    for t in range(own_ptr.shape[0] - 1):
        longest_own = max(longest_own, own_ptr[t + 1] - own_ptr[t])
    A = np.empty((_MAX_DEPTH + 3) * longest_own + 1, dtype=np.int64)
    own_box = np.empty(6)
    plane = np.empty(20)
    region = np.empty(6)
    task = -1
    n_own = 0
    rcap = 0.0
    t0 = 0
    t1 = 0
    s0 = 0
    min_region = 0.0
    b0, b1, b2, b3, b4, b5 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0

    for job in range(job_start, n_jobs):
        if job_task[job] != task:
            task = job_task[job]
            n_own = own_ptr[task + 1] - own_ptr[task]
            for i in range(n_own):
                A[i] = own_all[own_ptr[task] + i]
            for e in range(6):
                own_box[e] = t_own_box[task, e]
            b0, b1, b2, b3, b4, b5 = own_box[0], own_box[1], own_box[2], own_box[3], own_box[4], own_box[5]
            rcap = t_rcap[task]
            # give up regions far below the splat and far below the quadric's own curvature
            # (but never below MIN_REGION² of the radius: a needle 1e-11 thin would split forever)
            floor = min(radius, 1.0)
            min_region = min_region_factor * max(min(floor, t_length[task]), min_region_factor * floor)
            t0, t1 = other_ptr[task], other_ptr[task + 1]  # this task's slices: slice_ptr[t0:t1 + 1]
            s0 = slice_ptr[t0]
        slices = slice_ptr[t0 : t1 + 1]
        n_other = slice_ptr[t1] - s0
        nl0, nla0, nt0, npt0, nur0 = nl, nla, nt, npt, nur
        queries = 0
        visited = 0
        unresolved = 0
        evaluated = 0
        searches = 0
        features = 0
        overflow = 0
        k = job_plane[job]
        o0, o1, o2 = origin[task, k, 0], origin[task, k, 1], origin[task, k, 2]
        f00, f01, f02 = frame[task, k, 0, 0], frame[task, k, 0, 1], frame[task, k, 0, 2]
        f10, f11, f12 = frame[task, k, 1, 0], frame[task, k, 1, 1], frame[task, k, 1, 2]
        f20, f21, f22 = frame[task, k, 2, 0], frame[task, k, 2, 1], frame[task, k, 2, 2]
        fm = pform[task, k]
        ax, bx, ay, by, ac = coef[task, k, 0], coef[task, k, 1], coef[task, k, 2], coef[task, k, 3], coef[task, k, 4]
        sheet = job_sheet[job]
        sx, sy = job_quadrant[job, 0], job_quadrant[job, 1]
        uv = job_uv[job]
        apex_plane = fm == FORM_SHEETS and ac == 0.0 and bx == 0.0 and by == 0.0 and uv == 3
        # the plane as one array, for the rarely called helpers
        plane[0], plane[1], plane[2] = o0, o1, o2
        plane[3], plane[4], plane[5] = f00, f01, f02
        plane[6], plane[7], plane[8] = f10, f11, f12
        plane[9], plane[10], plane[11] = f20, f21, f22
        plane[12] = fm
        plane[13], plane[14], plane[15], plane[16], plane[17] = ax, bx, ay, by, ac
        plane[18] = sheet
        for c in range(3):
            S_v[0, 2 * c] = job_tri[job, c, 0]
            S_v[0, 2 * c + 1] = job_tri[job, c, 1]
            px, py, pz = lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, fm, ax, bx, ay, by, ac, sheet,
                              S_v[0, 2 * c], S_v[0, 2 * c + 1])
            dd, _ = relative_distance_pruned(C, A, 0, n_own, own_box, slices, other_idx, rcap, px, py, pz,
                                             0.0, A, n_own)
            S_d[0, c] = dd
            queries += 1
            evaluated += n_own + n_other
            if trace:
                if npt >= pcap:
                    overflow = 3
                    break
                TP[npt, 0], TP[npt, 1], TP[npt, 2] = S_v[0, 2 * c], S_v[0, 2 * c + 1], dd
                TJ[npt] = job
                npt += 1
        xs_ = (uv & 1) != 0
        ys_ = (uv & 2) != 0
        for c in range(3):
            cn = (c + 1) % 3
            S_b[0, c] = _arc_deviation(S_v[0, 2 * c], S_v[0, 2 * c + 1], S_v[0, 2 * cn], S_v[0, 2 * cn + 1], sx, sy,
                                       xs_, ys_) if uv != 0 else 0.0
        S_depth[0] = 0
        S_kept[0] = False
        S_a0[0], S_an[0], S_clamp[0] = 0, n_own, rcap
        S_searched[0] = (job_flags[job] & 1) != 0
        top = 1 if overflow == 0 else 0
        while top > 0:
            top -= 1
            visited += 1
            v0x, v0y, v1x, v1y, v2x, v2y = S_v[top, 0], S_v[top, 1], S_v[top, 2], S_v[top, 3], S_v[top, 4], S_v[top, 5]
            d0, d1, d2 = S_d[top, 0], S_d[top, 1], S_d[top, 2]
            depth = S_depth[top]
            kept = S_kept[top]
            slack = S_slack[top]
            a0, an, clamp = S_a0[top], S_an[top], S_clamp[top]
            searched = S_searched[top]
            a_top = a0 + an  # lists above belong to finished subtrees
            # the region is within ``bulge`` of the straight triangle (``geometry.region_bulge``, its
            # sides' deviations kept on the stack: a split computes three for two children)
            sb0, sb1, sb2 = S_b[top, 0], S_b[top, 1], S_b[top, 2]
            bulge = max(sb0, max(sb1, sb2))
            x0 = min(v0x, min(v1x, v2x)) - bulge
            y0 = min(v0y, min(v1y, v2y)) - bulge
            x1 = max(v0x, max(v1x, v2x)) + bulge
            y1 = max(v0y, max(v1y, v2y)) + bulge
            dlo, delta = delta_range(fm, ax, bx, ay, by, ac, x0, y0, x1, y1)
            if sqrt3_mode:  # assume the worst case of the low-distortion regions (§4.1), never less
                delta = max(delta, _SQRT3)
                dlo = delta
            rho_r = radius / delta
            status = -1
            emit_kind = -1
            split = False
            fx, fy = 0.0, 0.0
            # side lengths (v0v1, v1v2, v2v0), once: a corner's reach is the longer of its two sides
            l0 = _norm2(v1x - v0x, v1y - v0y)
            l1 = _norm2(v2x - v1x, v2y - v1y)
            l2 = _norm2(v0x - v2x, v0y - v2y)
            reach0, reach1, reach2 = max(l0, l2), max(l0, l1), max(l1, l2)
            # 1. the single-sample rule
            best = -1
            best_w = 0.0
            for c in range(3):
                dc = d0 if c == 0 else (d1 if c == 1 else d2)
                if kept or dc <= on_surface:
                    w = (reach0 if c == 0 else (reach1 if c == 1 else reach2)) + bulge
                    if w <= rho_r and (best < 0 or w < best_w):
                        best, best_w = c, w
            if best < 0 and apex_plane and delta == math.inf:
                # A cone's apex: t is homogeneous of degree 1, so the radial line from the apex to
                # any point of the region stays in it (a (U, V)-segment from 0) and lifts to a
                # straight ray of slope ≤ δ; δ over the region is its maximum at the (U, V) corners
                # (finite even where the region's box leaves the domain). A sample at the apex then
                # covers the region if δ_R · (distance to the farthest corner) ≤ r.
                for c in range(3):
                    cx_ = v0x if c == 0 else (v1x if c == 1 else v2x)
                    cy_ = v0y if c == 0 else (v1y if c == 1 else v2y)
                    dc = d0 if c == 0 else (d1 if c == 1 else d2)
                    if cx_ == 0.0 and cy_ == 0.0 and (kept or dc <= on_surface):
                        d_r = delta_at_points(fm, ax, bx, ay, by, ac, v0x, v0y, v1x, v1y, v2x, v2y)
                        w = corner_reach(v0x, v0y, v1x, v1y, v2x, v2y, c)
                        if d_r < math.inf and w * d_r <= radius:
                            best, best_w = c, w
                            delta = d_r
                            rho_r = radius / delta
            if best >= 0:
                emit_kind = 0
                status = 0
            elif kept:
                emit_kind = 1
                status = 1
            else:
                neg = d0 < 0.0 and d1 < 0.0 and d2 < 0.0
                posi = d0 > 0.0 and d1 > 0.0 and d2 > 0.0
                covered = False
                if neg or posi:
                    covered = discs_cover(v0x, v0y, v1x, v1y, v2x, v2y, max(abs(d0) / delta - bulge, 0.0),
                                          max(abs(d1) / delta - bulge, 0.0), max(abs(d2) / delta - bulge, 0.0))
                if covered and posi:
                    status = 2
                elif covered:
                    # 2. kept: every sample of the region stays this far from the term's other quadrics
                    slack = min(-d0 - delta * (reach0 + bulge),
                                min(-d1 - delta * (reach1 + bulge), -d2 - delta * (reach2 + bulge)))
                    kept = True
                    emit_kind = 1
                    status = 1
                else:
                    diam = max(l0, max(l1, l2))
                    if posi and not searched and diam + bulge <= tol.FEATURE_REGION * rho_r and depth < _MAX_DEPTH:
                        # 3. a point of a tangency curve in the region: one sample there covers it
                        region[0], region[1], region[2], region[3], region[4], region[5] = (
                            v0x, v0y, v1x, v1y, v2x, v2y)
                        found, fx, fy, ev = _feature_point(C, A, a0, an, own_box, slices, other_idx, plane, uv,
                                                           sx, sy, region, on_surface)
                        searches += 1
                        searched = True
                        evaluated += ev * (an + n_other)  # (not corner queries: counted apart)
                        if found:
                            features += 1
                            best = 3
                            best_w = diam + bulge
                            emit_kind = 0
                            status = 0
                        elif defer:
                            status = 6  # deferred: the neighbour rule, else pass 1b (not traced here)
                            if nur >= UR.shape[0]:
                                overflow = 5
                                break
                            region[0], region[1], region[2], region[3], region[4], region[5] = (
                                v0x, v0y, v1x, v1y, v2x, v2y)
                            _record_region(UR, nur, plane, region, delta, bulge, task, job, 1.0, -1)
                            nur += 1
                    if status < 0:
                        if min_size > 0.0 and diam * min(delta, _SQRT3) < min_size:
                            status = 3
                        elif diam < min_region or depth >= _MAX_DEPTH:
                            status = 4
                            unresolved += 1
                            if nur >= UR.shape[0]:
                                overflow = 5
                                break
                            row = nt if trace else -1
                            region[0], region[1], region[2], region[3], region[4], region[5] = (
                                v0x, v0y, v1x, v1y, v2x, v2y)
                            _record_region(UR, nur, plane, region, delta, bulge, task, job, 0.0, row)
                            nur += 1
                        else:
                            split = True
            count = 1
            rho_l = max(rho_r - bulge, tol.LATTICE_FLOOR * rho_r)  # (bulge ≥ rho_r only at _MAX_DEPTH: never)
            if emit_kind == 1:
                # a strongly curved region would get a needlessly dense lattice: split it (no
                # distance query), as one whose distortion bound is loose (``refine``)
                curved = bulge > 0.5 * rho_r
                if not curved:
                    count = lattice_plan(v0x, v0y, v1x, v1y, v2x, v2y, rho_l)[2]
                if (curved or (refine and count >= _REFINE_SAMPLES and delta > _REFINE_RATIO * dlo)) \
                        and depth < _MAX_DEPTH:
                    split = True
                    emit_kind = -1
                    status = -1
                elif curved:
                    count = lattice_plan(v0x, v0y, v1x, v1y, v2x, v2y, rho_l)[2]
            if emit_kind >= 0:
                if nl >= cap:
                    overflow = 1
                    break
                # the quadrics that may reach into this leaf's splats (its own-term list), unless
                # the corner distances already prove that none does
                dbest = d0 if best == 0 else (d1 if best == 1 else (d2 if best == 2 else 0.0))
                if (slack if kept else max(-dbest, 0.0)) >= radius:
                    LI[nl, 4], LI[nl, 5] = 0, 0
                else:
                    if nla + an > LA.shape[0]:
                        overflow = 4
                        break
                    for i in range(an):
                        LA[nla + i] = A[a0 + i]
                    LI[nl, 4], LI[nl, 5] = nla, an
                    nla += an
                LI[nl, 0] = job
                LI[nl, 1] = emit_kind
                LI[nl, 3] = count
                LF[nl, 9] = 0.0  # the radius the neighbour rule may raise a reduced radius to
                # every column written, the unused ones zero: leaf rows are a function of the input alone (the
                # buffers are np.empty; garbage there -- a NaN now and then -- made equal runs compare unequal)
                LF[nl, 10] = 0.0
                LF[nl, 11] = 0.0
                LF[nl, 12] = delta
                if emit_kind == 0:
                    LF[nl, 0] = v0x if best == 0 else (v1x if best == 1 else (v2x if best == 2 else fx))
                    LF[nl, 1] = v0y if best == 0 else (v1y if best == 1 else (v2y if best == 2 else fy))
                    LF[nl, 2], LF[nl, 3], LF[nl, 4], LF[nl, 5] = 0.0, 0.0, 0.0, 0.0  # (one vertex)
                    LI[nl, 2] = 1
                    LF[nl, 13] = slack if kept else max(-dbest, 0.0)
                    LF[nl, 14] = delta * best_w
                    LF[nl, 15] = 0.0
                else:
                    LF[nl, 0], LF[nl, 1], LF[nl, 2], LF[nl, 3], LF[nl, 4], LF[nl, 5] = v0x, v0y, v1x, v1y, v2x, v2y
                    LI[nl, 2] = 3
                    LF[nl, 13] = slack
                    LF[nl, 14] = radius
                    LF[nl, 15] = rho_l
                # the world point of the leaf's first vertex (for the neighbour rule)
                LF[nl, 6], LF[nl, 7], LF[nl, 8] = lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, fm, ax,
                                                       bx, ay, by, ac, sheet, LF[nl, 0], LF[nl, 1])
                nl += 1
            if status == 6:
                continue
            if status >= 0:
                if trace:
                    if nt >= tcap:
                        overflow = 2
                        break
                    TT[nt, 0], TT[nt, 1], TT[nt, 2], TT[nt, 3], TT[nt, 4], TT[nt, 5] = v0x, v0y, v1x, v1y, v2x, v2y
                    TI[nt, 0], TI[nt, 1], TI[nt, 2] = job, uv, status
                    TI[nt, 3], TI[nt, 4] = depth, k
                    nt += 1
                continue
            if not split:
                continue
            # 5. split the longest edge (at a point of its (U, V)-segment)
            if l0 >= l1 and l0 >= l2:  # edge v0 v1, opposite v2
                ex0, ey0, ex1, ey1, ox, oy, de0, de1, do = v0x, v0y, v1x, v1y, v2x, v2y, d0, d1, d2
                b_e1o, b_oe0 = sb1, sb2
            elif l1 >= l2:  # edge v1 v2, opposite v0
                ex0, ey0, ex1, ey1, ox, oy, de0, de1, do = v1x, v1y, v2x, v2y, v0x, v0y, d1, d2, d0
                b_e1o, b_oe0 = sb2, sb0
            else:  # edge v2 v0, opposite v1
                ex0, ey0, ex1, ey1, ox, oy, de0, de1, do = v2x, v2y, v0x, v0y, v1x, v1y, d2, d0, d1
                b_e1o, b_oe0 = sb0, sb1
            if uv != 0:
                mx, my = arc_midpoint(ex0, ey0, ex1, ey1, sx, sy, uv)
                b_e0m = _arc_deviation(ex0, ey0, mx, my, sx, sy, xs_, ys_)
                b_me1 = _arc_deviation(mx, my, ex1, ey1, sx, sy, xs_, ys_)
                b_mo = _arc_deviation(mx, my, ox, oy, sx, sy, xs_, ys_)
            else:
                mx, my = 0.5 * (ex0 + ex1), 0.5 * (ey0 + ey1)
                b_e0m, b_me1, b_mo = 0.0, 0.0, 0.0
            dm = -rcap
            c_a0, c_an, c_clamp = a0, an, clamp
            if not kept:
                # The children's points lie within 2D of the midpoint (D: world diameter of this
                # region). Quadrics whose surface stays ≥ max(4D, r + 3D) from the midpoint stay
                # ≥ 2D from them, and farther than a splat radius from their samples: drop them
                # there and clamp at 2D. (The distance of eq. 22, written out; see
                # ``relative_distance_pruned``.)
                world = delta * (max(l0, max(l1, l2)) + 2.0 * bulge)
                keep_below = max(4.0 * world, radius + 3.0 * world) if 2.0 * world < clamp else 0.0
                px, py, pz = lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, fm, ax, bx, ay, by, ac,
                                  sheet, mx, my)
                e0 = max(b0 - px, px - b3)
                e1 = max(b1 - py, py - b4)
                e2 = max(b2 - pz, pz - b5)
                if e0 <= 0.0 and e1 <= 0.0 and e2 <= 0.0:
                    own_d = max(e0, max(e1, e2))
                else:
                    q0, q1, q2 = max(e0, 0.0), max(e1, 0.0), max(e2, 0.0)
                    own_d = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
                cnt = 0
                for i in range(a0, a0 + an):
                    j = A[i]
                    dj = quadric_distance(C, j, px, py, pz)
                    own_d = max(own_d, dj)
                    if keep_below > 0.0 and dj > -keep_below:
                        A[a_top + cnt] = j
                        cnt += 1
                if own_d >= clamp:
                    dm = clamp
                else:
                    other = math.inf
                    for e in range(t0, t1):
                        mm = -math.inf
                        for i in range(slice_ptr[e], slice_ptr[e + 1]):
                            mm = max(mm, quadric_distance(C, other_idx[i], px, py, pz))
                            if mm >= other:
                                break
                        other = min(other, mm)
                        if other <= -clamp:
                            break
                    dm = min(max(max(-other, own_d), -clamp), clamp)
                if keep_below > 0.0:
                    c_a0, c_an, c_clamp = a_top, cnt, 2.0 * world
                queries += 1
                evaluated += an + n_other
                if trace:
                    if npt >= pcap:
                        overflow = 3
                        break
                    TP[npt, 0], TP[npt, 1], TP[npt, 2] = mx, my, dm
                    TJ[npt] = job
                    npt += 1
            # children (e0, M, o) and (M, e1, o), same orientation as the parent
            for child in range(2):
                if child == 0:
                    S_v[top, 0], S_v[top, 1], S_v[top, 2], S_v[top, 3] = ex0, ey0, mx, my
                    S_d[top, 0], S_d[top, 1] = de0, dm
                    S_b[top, 0], S_b[top, 1], S_b[top, 2] = b_e0m, b_mo, b_oe0
                else:
                    S_v[top, 0], S_v[top, 1], S_v[top, 2], S_v[top, 3] = mx, my, ex1, ey1
                    S_d[top, 0], S_d[top, 1] = dm, de1
                    S_b[top, 0], S_b[top, 1], S_b[top, 2] = b_me1, b_e1o, b_mo
                S_v[top, 4], S_v[top, 5] = ox, oy
                S_d[top, 2] = do
                S_depth[top] = depth + 1
                S_kept[top] = kept
                S_slack[top] = slack
                S_a0[top], S_an[top], S_clamp[top] = c_a0, c_an, c_clamp
                S_searched[top] = searched
                top += 1
        if overflow != 0:
            return nl0, nla0, nt0, npt0, nur0, job, overflow
        counters[0] += queries
        counters[1] += visited
        counters[2] += unresolved
        counters[3] += 1
        counters[4] += evaluated
        counters[5] += searches
        counters[6] += features
    return nl, nla, nt, npt, nur, n_jobs, 0


@ieee_jit
def _record_region(UR, i, plane, v, delta, bulge, task, job, kind, trace_row):
    """UR[i] = (world point, radius of a world ball around it holding the region, task, job,
    triangle (6), kind: 0 given up, 1 deferred, its trace row or -1); ``plane`` as in ``_feature_point``."""
    v0x, v0y, v1x, v1y, v2x, v2y = v[0], v[1], v[2], v[3], v[4], v[5]
    ux, uy, uz = lift(plane[0], plane[1], plane[2], plane[3], plane[4], plane[5], plane[6], plane[7], plane[8],
                      plane[9], plane[10], plane[11], int(plane[12]), plane[13], plane[14], plane[15], plane[16],
                      plane[17], plane[18], v0x, v0y)
    UR[i, 0], UR[i, 1], UR[i, 2] = ux, uy, uz
    UR[i, 3] = delta * (corner_reach(v0x, v0y, v1x, v1y, v2x, v2y, 0) + bulge)
    UR[i, 4], UR[i, 5] = task, job
    UR[i, 6], UR[i, 7], UR[i, 8], UR[i, 9], UR[i, 10], UR[i, 11] = v0x, v0y, v1x, v1y, v2x, v2y
    UR[i, 12] = kind
    UR[i, 13] = trace_row


@inline_jit
def _reorder(values, a0, idx):
    """values[a0 + i] = values[a0 + idx[i]] (before the call) for i < len(idx): a segment put in sorted order.

    Element by element: numba's slice assignment ``values[a0:b0] = values[a0:b0][idx]`` types a shape-mismatch
    error message (str() of tuples included), seconds of compilation for one line."""
    seg = values[a0:a0 + idx.shape[0]].copy()
    for i in range(idx.shape[0]):
        values[a0 + i] = seg[idx[i]]


def cover_by_neighbours(ts, LF, LI, UR, radius, reduce_radius, covered):
    """Mark the regions ``UR`` (``_record_region``) that a sample of the same quadric covers; return the count.

    The neighbour rule: a region inside the world ball (c, ρ) is covered when a sample s of the
    same task has |s − c| + ρ ≤ its radius — every point of the region, on the CSG surface or not,
    then has a sample on its quadric within the radius. It resolves the regions left at the tips of
    surface patches (where two feature curves meet at a corner: d_Qab > 0 outside, zero only at the
    tip) and along tangencies without a sign change (a sphere inside a cylinder of its radius),
    which sit next to the samples of the patch itself. ``covered`` (u,) bool is written.

    With reduced radii, a region no sample covers at its own radius raises the radius of the sample that
    would cover it at the full one (``LF[leaf, 9]``), so a later region may find that sample covering: the
    rule is a pass in region order. Only the samples of a region's own task are searched or raised, so the
    tasks are independent: they are shared out among ``csgnb._threads`` parts of about equal work (leaves to
    index, regions to search), each doing its tasks' regions in order -- the one-thread result, bit for bit.
    """
    covered[:] = False
    if UR.shape[0] == 0:
        return 0
    count_t, order, regions_t = _neighbour_groups(ts, LI, UR)
    n_tasks = len(regions_t)
    # work per task: its leaves (when it has regions) and its regions (a search each: ~4 leaves' worth, fitted
    # on the per-task times of the perforated plate, 0.10 µs a leaf and 0.42 µs a region, 2026-12-04)
    work = np.where(regions_t > 0, np.diff(count_t) + 4 * regions_t, 0)
    parts = min(threads(), int(np.count_nonzero(work))) or 1
    owner = np.zeros(n_tasks, dtype=np.int64)
    load = np.zeros(parts)
    for t in np.argsort(-work, kind="stable"):  # the largest first, each to the least loaded part
        p = int(np.argmin(load))
        owner[t] = p
        load[p] += work[t]
    n_leaves = LI.shape[0]
    index = (np.empty((n_leaves, 4)), np.empty(3 * n_tasks + 1, dtype=np.int64), np.empty(n_leaves, dtype=np.int64),
             np.empty(n_leaves), np.zeros(3 * n_tasks), np.empty(n_leaves, dtype=np.int64))
    index[1][::3] = count_t  # every task's span starts its singles and ends the task before it
    counts = run_parts(_neighbour_part, ts, LF, LI, UR, count_t, order, regions_t, owner, index, radius,
                       reduce_radius, covered, parts=parts)
    return int(sum(counts))


@ieee_jit
def _neighbour_groups(ts, LI, UR):
    """``(count_t, order, regions_t)``: the leaves of task t are ``order[count_t[t]:count_t[t + 1]]`` (in leaf
    order), and ``regions_t[t]`` regions of ``UR`` are task t's."""
    job_task = ts.job_task
    n_leaves = LI.shape[0]
    n_tasks = ts.quadric.shape[0]
    # leaves are in job order, jobs in task order — pass 1b's jobs follow, so collect by task explicitly
    count_t = np.zeros(n_tasks + 1, dtype=np.int64)
    for leaf in range(n_leaves):
        count_t[job_task[LI[leaf, 0]] + 1] += 1
    for t in range(n_tasks):
        count_t[t + 1] += count_t[t]
    order = np.empty(n_leaves, dtype=np.int64)
    fill = count_t[:n_tasks].copy()
    for leaf in range(n_leaves):
        t = job_task[LI[leaf, 0]]
        order[fill[t]] = leaf
        fill[t] += 1
    regions_t = np.zeros(n_tasks, dtype=np.int64)
    for u in range(UR.shape[0]):
        regions_t[int(UR[u, 4])] += 1
    return count_t, order, regions_t


@ieee_jit
def _index_task(LF, LI, t, count_t, order, radius, index):
    """Index the leaves of task t in ``index = (P, kind_first, sorted_leaf, key, widest, cell)``, within the task's
    span ``count_t[t]:count_t[t + 1]``.

    ``P`` (leaves, 4): a world ball per leaf (its first vertex, recorded by pass 1, and the world reach of its
    triangle); the groups ``g = 3 t + kind`` (singles, small lattices with reach ≤ 4 radii, large lattices) are
    ``sorted_leaf[kind_first[g]:kind_first[g + 1]]``, singles sorted by their grid ``cell`` of one radius
    (feature curves often lie in planes x = const), lattices in leaf order with the x of their ball centers in
    ``key`` (:func:`_sort_lattices` sorts them by it: a window of x ± (radius + ``widest[g]``, the group's largest
    reach) then holds every leaf that can cover a region; the few large lattices are one wide window).
    """
    P, kind_first, sorted_leaf, key, widest, cell = index
    for o in range(count_t[t], count_t[t + 1]):
        leaf = order[o]
        P[leaf, 0], P[leaf, 1], P[leaf, 2] = LF[leaf, 6], LF[leaf, 7], LF[leaf, 8]
        if LI[leaf, 1] == 0:
            P[leaf, 3] = 0.0
        else:
            P[leaf, 3] = LF[leaf, 12] * corner_reach(LF[leaf, 0], LF[leaf, 1], LF[leaf, 2], LF[leaf, 3],
                                                     LF[leaf, 4], LF[leaf, 5], 0)
    at = count_t[t]
    for kind in range(3):
        g = 3 * t + kind
        if kind > 0:  # (kind_first[3 t] = count_t[t] is set by the caller: a neighbour task reads it as its end)
            kind_first[g] = at
        widest[g] = 0.0
        for o in range(count_t[t], count_t[t + 1]):
            leaf = order[o]
            group = 0 if LI[leaf, 1] == 0 else (1 if P[leaf, 3] <= 4.0 * radius else 2)
            if group == kind:
                sorted_leaf[at] = leaf
                key[at] = P[leaf, 0]
                widest[g] = max(widest[g], P[leaf, 3])
                at += 1
    a0, b0 = kind_first[3 * t], kind_first[3 * t + 1]
    for o in range(a0, b0):
        leaf = sorted_leaf[o]
        cell[o] = _cell_key(P[leaf, 0], P[leaf, 1], P[leaf, 2], radius)
    idx = np.argsort(cell[a0:b0])
    _reorder(sorted_leaf, a0, idx)
    _reorder(cell, a0, idx)


@ieee_jit
def _sort_lattices(index, t):
    """Sort task t's lattice groups of ``index`` (:func:`_index_task`) by their leaves' x, in place."""
    _, kind_first, sorted_leaf, key, _, _ = index
    for g in range(3 * t + 1, 3 * t + 3):
        a0, b0 = kind_first[g], kind_first[g + 1]
        idx = np.argsort(key[a0:b0])
        _reorder(sorted_leaf, a0, idx)
        _reorder(key, a0, idx)


@inline_jit
def _singles_cover(LF, UR, u, index, radius, reduce_radius, best_need, best_leaf):
    """``(covered, best_need, best_leaf)``: does a single sample of region u's task cover it, at the radii in
    ``LF`` now; with reduced radii, the closest that would at the full radius, if it is closer than ``best_need``.
    """
    P, kind_first, sorted_leaf, _, _, cell = index
    t = int(UR[u, 4])
    cx, cy, cz, rho = UR[u, 0], UR[u, 1], UR[u, 2], UR[u, 3]
    h = radius
    # a covering one is within one radius of the center, so in the ≤ 8 cells of the box center ± radius
    a0, b0 = kind_first[3 * t], kind_first[3 * t + 1]
    ix0, ix1 = int(math.floor((cx - h) / h)), int(math.floor((cx + h) / h))
    iy0, iy1 = int(math.floor((cy - h) / h)), int(math.floor((cy + h) / h))
    iz0, iz1 = int(math.floor((cz - h) / h)), int(math.floor((cz + h) / h))
    for ix in range(ix0, ix1 + 1):
        for iy in range(iy0, iy1 + 1):
            for iz in range(iz0, iz1 + 1):
                kc = _cell_id(ix, iy, iz)
                lo, hi = a0, b0
                while lo < hi:  # first entry ≥ kc
                    mid = (lo + hi) >> 1
                    if cell[mid] < kc:
                        lo = mid + 1
                    else:
                        hi = mid
                o = lo
                while o < b0 and cell[o] == kc:
                    leaf = sorted_leaf[o]
                    dx, dy, dz = P[leaf, 0] - cx, P[leaf, 1] - cy, P[leaf, 2] - cz
                    need = (math.sqrt(dx * dx + dy * dy + dz * dz) + rho) / (1.0 - tol.NEIGHBOUR_MARGIN)
                    r_s = max(LF[leaf, 14], LF[leaf, 9]) if reduce_radius else radius
                    if need <= r_s:
                        return True, best_need, best_leaf
                    if need <= radius and need < best_need:  # (reduced radii only: r_s < radius)
                        best_need, best_leaf = need, leaf
                    o += 1
    return False, best_need, best_leaf


@inline_jit
def _lattices_cover(ts, LF, LI, UR, u, index, radius, reduce_radius, best_need, best_leaf):
    """:func:`_singles_cover` for the nearest points of the task's lattices (sorted: :func:`_sort_lattices`)."""
    P, kind_first, sorted_leaf, key, widest, _ = index
    t = int(UR[u, 4])
    cx, cy, cz, rho = UR[u, 0], UR[u, 1], UR[u, 2], UR[u, 3]
    for kind in range(1, 3):
        g = 3 * t + kind
        a0, b0 = kind_first[g], kind_first[g + 1]
        half = radius + widest[g]
        lo = a0 + np.searchsorted(key[a0:b0], cx - half)
        hi = a0 + np.searchsorted(key[a0:b0], cx + half, side="right")
        for o in range(lo, hi):
            leaf = sorted_leaf[o]
            dx, dy, dz = P[leaf, 0] - cx, P[leaf, 1] - cy, P[leaf, 2] - cz
            if abs(dy) > half or abs(dz) > half:
                continue
            dist = math.sqrt(dx * dx + dy * dy + dz * dz)
            if dist - P[leaf, 3] + rho <= radius:
                need, r_s = _lattice_need(ts, LF, LI, leaf, cx, cy, cz, rho, radius, reduce_radius)
                if need <= r_s:
                    return True, best_need, best_leaf
                if need <= radius and need < best_need:
                    best_need, best_leaf = need, leaf
    return False, best_need, best_leaf


@ieee_jit
def _neighbour_part(ts, LF, LI, UR, count_t, order, regions_t, owner, index, radius, reduce_radius, covered,
                    part, parts):
    """The neighbour rule for the tasks ``owner`` gives this part: index their leaves, then do their regions in
    order (singles, then lattices, then the radius raise); return the count covered."""
    n_tasks = regions_t.shape[0]
    lattices_sorted = np.zeros(n_tasks, dtype=np.bool_)
    for t in range(n_tasks):
        if owner[t] == part and regions_t[t] > 0:
            _index_task(LF, LI, t, count_t, order, radius, index)
    count = 0
    for u in range(UR.shape[0]):
        t = int(UR[u, 4])
        if owner[t] != part or not UR[u, 3] < radius:
            continue
        c, best_need, best_leaf = _singles_cover(LF, UR, u, index, radius, reduce_radius, np.inf, -1)
        if not c:
            if not lattices_sorted[t]:
                _sort_lattices(index, t)
                lattices_sorted[t] = True
            c, best_need, best_leaf = _lattices_cover(ts, LF, LI, UR, u, index, radius, reduce_radius,
                                                      best_need, best_leaf)
        if not c and reduce_radius and best_leaf >= 0:
            LF[best_leaf, 9] = max(LF[best_leaf, 9], best_need)
            c = True
        covered[u] = c
        if c:
            count += 1
    return count


@inline_jit
def _cell_key(x, y, z, h):
    """A grid cell id of (x, y, z) for cells of size h (coordinates within 2²⁰ cells of 0)."""
    return _cell_id(int(math.floor(x / h)), int(math.floor(y / h)), int(math.floor(z / h)))


@inline_jit
def _cell_id(ix, iy, iz):
    """The id of grid cell (ix, iy, iz), each index within 2²⁰ of 0: one int64, ordered by ix, then iy, then iz."""
    return ((ix + (1 << 20)) << 42) | ((iy + (1 << 20)) << 21) | (iz + (1 << 20))


@inline_jit
def _lattice_need(ts, LF, LI, leaf, cx, cy, cz, rho, radius, reduce_radius):
    """``(need, r_s)``: the smallest radius a lattice point of ``leaf`` near the ball (c, ρ) needs to cover it
    (``inf`` if none is near), and the radius the leaf's samples have (see ``cover_by_neighbours``)."""
    origin, frame, coef, pform = ts.origin, ts.frame, ts.coef, ts.form
    job = LI[leaf, 0]
    task = ts.job_task[job]
    k = ts.job_plane[job]
    sheet = ts.job_sheet[job]
    v0x, v0y, v1x, v1y, v2x, v2y = LF[leaf, 0], LF[leaf, 1], LF[leaf, 2], LF[leaf, 3], LF[leaf, 4], LF[leaf, 5]
    rho_l = LF[leaf, 15]
    centers, steps, _, reach, cs, ct = lattice_plan(v0x, v0y, v1x, v1y, v2x, v2y, rho_l)
    r_s = max(LF[leaf, 12] * reach + (radius - LF[leaf, 12] * rho_l), LF[leaf, 9]) if reduce_radius else radius
    best = np.inf
    inv = 1.0 / steps
    e1x, e1y, e2x, e2y = v1x - v0x, v1y - v0y, v2x - v0x, v2y - v0y
    # the ball's center in the leaf's plane, in lattice coordinates: only the lattice points around
    # it are candidates (any candidate that passes the exact world test covers the ball)
    dx, dy, dz = cx - origin[task, k, 0], cy - origin[task, k, 1], cz - origin[task, k, 2]
    lx = dx * frame[task, k, 0, 0] + dy * frame[task, k, 1, 0] + dz * frame[task, k, 2, 0] - v0x
    ly = dx * frame[task, k, 0, 1] + dy * frame[task, k, 1, 1] + dz * frame[task, k, 2, 1] - v0y
    det = e1x * e2y - e1y * e2x
    if det == 0.0:
        return best, r_s
    a_ = (lx * e2y - ly * e2x) / det * steps
    b_ = (e1x * ly - e1y * lx) / det * steps
    for flip in range(2 if centers else 1):
        if centers:
            ia = a_ - cs if flip == 0 else a_ - 1.0 + cs
            ib = b_ - ct if flip == 0 else b_ - 1.0 + ct
        else:
            ia, ib = a_, b_
        i0 = int(math.floor(ia))
        j0 = int(math.floor(ib))
        for i in range(i0 - 1, i0 + 3):
            for j in range(j0 - 1, j0 + 3):
                if i < 0 or j < 0:
                    continue
                if centers:
                    if (flip == 0 and i + j > steps - 1) or (flip == 1 and i + j > steps - 2):
                        continue
                    uu = (i + cs) * inv if flip == 0 else (i + 1 - cs) * inv
                    ww = (j + ct) * inv if flip == 0 else (j + 1 - ct) * inv
                else:
                    if i + j > steps:
                        continue
                    uu, ww = i * inv, j * inv
                x, y = v0x + uu * e1x + ww * e2x, v0y + uu * e1y + ww * e2y
                px, py, pz = lift(
                    origin[task, k, 0], origin[task, k, 1], origin[task, k, 2],
                    frame[task, k, 0, 0], frame[task, k, 0, 1], frame[task, k, 0, 2],
                    frame[task, k, 1, 0], frame[task, k, 1, 1], frame[task, k, 1, 2],
                    frame[task, k, 2, 0], frame[task, k, 2, 1], frame[task, k, 2, 2],
                    pform[task, k], coef[task, k, 0], coef[task, k, 1], coef[task, k, 2],
                    coef[task, k, 3], coef[task, k, 4], sheet, x, y)  # fmt: skip
                ex, ey, ez = px - cx, py - cy, pz - cz
                need = (math.sqrt(ex * ex + ey * ey + ez * ez) + rho) / (1.0 - tol.NEIGHBOUR_MARGIN)
                if need <= r_s:
                    return need, r_s
                best = min(best, need)
    return best, r_s


@ieee_jit
def emit_all(C, ts, LF, LI, LA, radius, reduce_radius, center, scale, pos, nrm, rad, cptr, ids, cidx, leaf_start, n,
             nc):
    """Pass 2: write the samples of the leaves ``LF``, ``LI``, ``LA`` (of all tasks) from ``leaf_start`` on.

    ``pos``, ``nrm`` (N, 3), ``rad`` (N,) float64 and ``ids`` (N,) int32 (the normal-form index of
    the sample's quadric) are the caller's output arrays, written from index ``n`` on, positions
    and radii mapped to the world by ``center + scale · p``; clip indices go to ``cidx`` from
    ``nc`` on, in sample order, and ``cptr`` (N + 1,) int64 gets their offsets (``cptr[n + 1]``). Returns ``(next_leaf,
    n, nc)``; ``next_leaf`` < number of leaves means ``cidx`` may be too small for that leaf: grow
    it and call again with the returned values. Each sample gets its position, the unit normal
    of its quadric (the sampling plane's, towards the sheet, at a cone's apex where there is
    none), its radius and its clip set: the quadrics of the leaf's list with |d(Q, s)| below the
    radius.
    """
    origin, frame, coef, pform = ts.origin, ts.frame, ts.coef, ts.form
    job_task, job_plane, job_sheet, t_quadric = ts.job_task, ts.job_plane, ts.job_sheet, ts.quadric
    ccap = cidx.shape[0]
    cw0, cw1, cw2 = center[0], center[1], center[2]
    longest = 0
    for leaf in range(LI.shape[0]):
        longest = max(longest, LI[leaf, 5])
    local = np.empty(longest + 1, dtype=np.int64)
    most = 1
    for leaf in range(LI.shape[0]):
        most = max(most, LI[leaf, 3])
    X = np.empty(most)
    Y = np.empty(most)
    for leaf in range(leaf_start, LI.shape[0]):
        la0, lan = LI[leaf, 4], LI[leaf, 5]
        if nc + LI[leaf, 3] * lan > ccap:
            return leaf, n, nc
        job = LI[leaf, 0]
        task = job_task[job]
        qid = t_quadric[task]
        q00, q01, q02, q11, q12, q22 = C[qid, 0], C[qid, 1], C[qid, 2], C[qid, 3], C[qid, 4], C[qid, 5]
        m0, m1, m2 = C[qid, 6], C[qid, 7], C[qid, 8]
        k = job_plane[job]
        sheet = job_sheet[job]
        o0, o1, o2 = origin[task, k, 0], origin[task, k, 1], origin[task, k, 2]
        f00, f01, f02 = frame[task, k, 0, 0], frame[task, k, 0, 1], frame[task, k, 0, 2]
        f10, f11, f12 = frame[task, k, 1, 0], frame[task, k, 1, 1], frame[task, k, 1, 2]
        f20, f21, f22 = frame[task, k, 2, 0], frame[task, k, 2, 1], frame[task, k, 2, 2]
        fm = pform[task, k]
        ax, bx, ay, by, ac = coef[task, k, 0], coef[task, k, 1], coef[task, k, 2], coef[task, k, 3], coef[task, k, 4]
        delta = LF[leaf, 12]
        single = LI[leaf, 1] == 0
        v0x, v0y, v1x, v1y, v2x, v2y = LF[leaf, 0], LF[leaf, 1], LF[leaf, 2], LF[leaf, 3], LF[leaf, 4], LF[leaf, 5]
        if single:
            r_s = max(LF[leaf, 14], LF[leaf, 9]) if reduce_radius else radius
            centers, steps, reach, cs, ct = False, 0, 0.0, 0.0, 0.0
            n_loc = lan
            for i in range(lan):
                local[i] = LA[la0 + i]
        else:
            rho_l = LF[leaf, 15]
            centers, steps, _, reach, cs, ct = lattice_plan(v0x, v0y, v1x, v1y, v2x, v2y, rho_l)
            # the bulge, in world units, for reduced radii
            r_s = max(delta * reach + (radius - delta * rho_l), LF[leaf, 9]) if reduce_radius else radius
            # keep the quadrics that can reach a splat of this lattice: a surface that stays
            # farther than radius + (world reach of the triangle) from its first vertex cannot
            n_loc = 0
            if lan > 0:
                far = max(_norm2(v1x - v0x, v1y - v0y), _norm2(v2x - v0x, v2y - v0y))
                px, py, pz = lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, fm, ax, bx, ay, by, ac,
                                  sheet, v0x, v0y)
                for i in range(la0, la0 + lan):
                    if abs(quadric_distance(C, LA[i], px, py, pz)) < radius + delta * far:
                        local[n_loc] = LA[i]
                        n_loc += 1
        inv = 1.0 / steps if steps > 0 else 0.0
        r_w = r_s * scale
        e1x, e1y, e2x, e2y = v1x - v0x, v1y - v0y, v2x - v0x, v2y - v0y
        # the leaf's plane points first (a single point, lattice vertices or copy centers), then
        # one straight loop over them: lift, normal, output
        m = 0
        if single:
            X[0], Y[0] = v0x, v0y
            m = 1
        elif centers:
            for i in range(steps):
                for j in range(steps - i):
                    u = (i + cs) * inv
                    w = (j + ct) * inv
                    X[m], Y[m] = v0x + u * e1x + w * e2x, v0y + u * e1y + w * e2y
                    m += 1
                    if i + j <= steps - 2:
                        u = (i + 1 - cs) * inv
                        w = (j + 1 - ct) * inv
                        X[m], Y[m] = v0x + u * e1x + w * e2x, v0y + u * e1y + w * e2y
                        m += 1
        else:
            for i in range(steps + 1):
                for j in range(steps + 1 - i):
                    X[m], Y[m] = v0x + (i * inv) * e1x + (j * inv) * e2x, v0y + (i * inv) * e1y + (j * inv) * e2y
                    m += 1
        for t0 in range(m):
            px, py, pz = lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, fm, ax, bx, ay, by, ac, sheet,
                              X[t0], Y[t0])
            pos[n, 0], pos[n, 1], pos[n, 2] = cw0 + scale * px, cw1 + scale * py, cw2 + scale * pz
            g0 = q00 * px + q01 * py + q02 * pz + m0
            g1 = q01 * px + q11 * py + q12 * pz + m1
            g2 = q02 * px + q12 * py + q22 * pz + m2
            gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
            if gn > 0.0:
                ig = 1.0 / gn
                nrm[n, 0], nrm[n, 1], nrm[n, 2] = g0 * ig, g1 * ig, g2 * ig
            else:  # a cone's apex: no normal; take the sampling plane's towards the sheet
                nrm[n, 0], nrm[n, 1], nrm[n, 2] = sheet * f02, sheet * f12, sheet * f22
            rad[n] = r_w
            ids[n] = qid
            for t in range(n_loc):
                if abs(quadric_distance(C, local[t], px, py, pz)) < r_s:
                    cidx[nc] = local[t]
                    nc += 1
            cptr[n + 1] = nc
            n += 1
    return LI.shape[0], n, nc
