"""The adaptive sampling kernel of §4.2: classify, split or cover the regions of one quadric.

For every job (a triangle of a basic region on one sheet) the kernel keeps a depth-first stack
of triangles with d_Qab (eq. 22) known at their corners. For each triangle, with δ the distortion
bound over its bounding polygon P (:mod:`.geometry`) and r the splat radius:

1. *single sample*: if a corner is on the CSG surface (d < 0, or |d| ≤ ``on_surface``: a point
   of a feature curve, in the closure of the surface) and the disc of radius r/δ around it holds
   P, emit that corner and stop (the sample covers the region whatever the rest is). Counting
   corners on feature curves matters when a curve runs along region edges (axis-aligned models):
   the regions outside it would otherwise never be classified (their discs there have radius 0);
2. *classify*: if all corners have the same sign and the discs of radius |d|/δ cover P, the
   region is kept (all of it is on the CSG surface: cover P with a triangular lattice of
   spacing such that every point is within r/δ of a lattice point) or discarded;
3. optionally (``min_size`` > 0) discard unclassified regions smaller than ``min_size``
   (faster, but can leave holes, as the paper says);
4. otherwise split the longest edge (in (u, v) mode at its (u, v)-midpoint, so that the halves
   are (u, v)-triangles again),
   evaluate d_Qab at the new corner and recurse. Regions below ``min_region`` (a few ulps of
   the radius) are given up and counted as unresolved.

Kept regions that would need many samples are split further without distance queries while
their distortion bound varies (``refine``): a lattice is as dense as its region's largest δ
demands. The world distance between two points over P is at most δ times their (x, y) distance
(the lift stretches by at most δ), which turns world radii into (x, y) radii. Each sample
carries its clip set: the quadrics of its term whose surface may pass within its radius (§6),
found from the corner distances when they prove the set empty and from d(Q_aj, s) otherwise.

Two passes keep the memory traffic low: ``subdivide_quadric`` records the emitting leaves,
``emit_quadric`` writes their samples into arrays the caller allocated with numpy (numpy asks
for huge pages; page faults on fresh numba buffers cost more than the sampling itself here).
Neither kernel re-binds an array inside its loops — numba reference-counts re-bound arrays with
atomic operations on every iteration, which cost 60 % of the time in a first version — so both
stop when a buffer is full and are resumed by the caller with a larger one (at a job, or a
leaf, boundary).
"""

from __future__ import annotations

import math

import numpy as np

from csgnb.csg.distance import box_distance, inline_jit, quadric_distance
from csgnb.quadric.evaluate import ieee_jit
from csgnb.sampling.geometry import (
    _norm2,
    arc_midpoint,
    delta_range,
    disc_contains,
    discs_cover,
    lattice_plan,
    lift,
    region_polygon,
)

__all__ = [
    "relative_distance_pruned",
    "subdivide_quadric",
    "emit_quadric",
    "STATUS",
    "OVERFLOW",
    "LEAF_FLOAT_FIELDS",
    "LEAF_INT_FIELDS",
]

#: Leaf status codes recorded in traces.
STATUS = {"single": 0, "kept": 1, "discarded": 2, "small": 3, "unresolved": 4}

#: Columns of the leaf buffers of pass 1: floats (polygon x₀ y₀ … x₅ y₅, δ, aux, reach) and
#: integers (job, kind, vertices, samples); see ``subdivide_quadric``.
LEAF_FLOAT_FIELDS = tuple(f"{a}{k}" for k in range(6) for a in "xy") + ("delta", "aux", "reach", "rho")
LEAF_INT_FIELDS = ("job", "kind", "corners", "count")
#: Overflow codes returned by ``subdivide_quadric``: which buffer to grow before resuming.
OVERFLOW = {"none": 0, "leaves": 1, "trace_leaves": 2, "trace_points": 3}

_SQRT3 = math.sqrt(3.0)
_MAX_DEPTH = 200
#: Kept regions needing at least this many samples are split further (without distance queries)
#: while their distortion varies by more than ``_REFINE_RATIO``: a lattice is as dense as the
#: region's largest δ demands, so tighter bounds mean fewer samples.
_REFINE_SAMPLES = 256
_REFINE_RATIO = 1.2


@inline_jit
def relative_distance_pruned(C, act, a0, na, own_box, other_ptr, other_idx, rcap, x, y, z, keep_below, out, o0):
    """Return (d_Qab(S, p) clamped to [-rcap, rcap], n) from pruned lists (eq. 22).

    ``act[a0:a0 + na]`` are the quadrics of the own term still in play; the own max also holds
    the signed distance to ``own_box``, an exact distance to a superset of the quadric's surface in
    the term, so the bound stays conservative and reaches ``rcap`` beyond the neighbourhood where
    the lists hold. If ``keep_below`` > 0, the own-term quadrics with d > -keep_below — those
    that can still matter closer than that — are copied to ``out[o0:o0 + n]``.
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


@inline_jit
def _lattice_fan(P, m, rho):
    """Return (apex, samples) for covering the convex polygon P[:m] by per-triangle lattices.

    The polygon is fanned from the vertex (``apex``) that needs the fewest samples.
    """
    best, best_n = 0, -1
    for a in range(m if m > 3 else 1):
        total = 0
        for tri in range(m - 2):
            i = (a + tri + 1) % m
            j = (a + tri + 2) % m
            total += lattice_plan(P[a, 0], P[a, 1], P[i, 0], P[i, 1], P[j, 0], P[j, 1], rho)[2]
        if best_n < 0 or total < best_n:
            best, best_n = a, total
    return best, best_n


@ieee_jit
def subdivide_quadric(
    C,
    own,
    own_box,
    other_ptr,
    other_idx,
    rcap,
    origin,
    frame,
    alpha,
    flat,
    job_plane,
    job_sheet,
    job_tri,
    job_uv,
    job_quadrant,
    radius,
    min_size,
    min_region,
    on_surface,
    sqrt3_mode,
    refine,
    trace,
    LF,
    LI,
    TT,
    TI,
    TP,
    TJ,
    counters,
    job_start,
    nl,
    nt,
    npt,
):
    """Pass 1: classify and subdivide the jobs of one quadric from ``job_start`` on.

    Task arrays as in ``tasks.QuadricTask``. Writes, from the given fill levels on:

    * leaves that emit samples: ``LF`` (cap, 16) float64 (``LEAF_FLOAT_FIELDS``: the polygon —
      one point for a single sample, else the 3–4 vertices whose fan gets a lattice —, the
      distortion bound δ used, ``aux`` the distance from the samples below which no quadric of
      the term can come (single: |d_Qab| at the corner; lattice: the slack of the keep discs),
      ``reach`` the world radius covering a single sample's region, ``rho`` the plane spacing
      radius of a lattice), ``LI`` (cap, 4) int64
      (``LEAF_INT_FIELDS``: job, kind 0 single / 1 lattice, vertex count, sample count);
    * if ``trace``: final regions ``TT`` (tcap, 6) (triangle) and ``TI`` (tcap, 5) = (job, uv,
      status, depth, plane); distance evaluations ``TP`` (pcap, 3) = (x, y, d_Qab), ``TJ`` (pcap,)
      = job;
    * ``counters`` (4,) int64 += distance queries, regions visited, unresolved regions, jobs done.

    Returns ``(nl, nt, npt, next_job, overflow)``: fill levels, the first job not done and an
    ``OVERFLOW`` code. On overflow the unfinished job's output is rolled back; grow that buffer
    and call again from ``next_job``.
    """
    cap = LF.shape[0]
    tcap = TT.shape[0]
    pcap = TP.shape[0]
    smax = 2 * _MAX_DEPTH + 8
    S_v = np.empty((smax, 3, 2))
    S_d = np.empty((smax, 3))
    S_depth = np.empty(smax, dtype=np.int64)
    S_kept = np.zeros(smax, dtype=np.bool_)
    S_slack = np.empty(smax)
    # own-term quadrics in play per stack entry: a slice of A (lists of a DFS path nest)
    S_a0 = np.empty(smax, dtype=np.int64)
    S_an = np.empty(smax, dtype=np.int64)
    S_clamp = np.empty(smax)
    n_own = own.shape[0]
    A = np.empty((_MAX_DEPTH + 3) * n_own + 1, dtype=np.int64)
    A[:n_own] = own
    P = np.zeros((6, 2))
    H = np.zeros((6, 2))
    rho = np.empty(3)
    v = np.empty((3, 2))
    d = np.empty(3)

    for job in range(job_start, job_plane.shape[0]):
        nl0, nt0, npt0 = nl, nt, npt
        queries = 0
        visited = 0
        unresolved = 0
        overflow = 0
        k = job_plane[job]
        al = alpha[k]
        fl = flat[k]
        sheet = job_sheet[job]
        sx, sy = job_quadrant[job, 0], job_quadrant[job, 1]
        uv = job_uv[job] != 0
        for c in range(3):
            S_v[0, c, 0] = job_tri[job, c, 0]
            S_v[0, c, 1] = job_tri[job, c, 1]
            px, py, pz = lift(origin, frame, alpha, k, sheet, S_v[0, c, 0], S_v[0, c, 1])
            dd, _ = relative_distance_pruned(C, A, 0, n_own, own_box, other_ptr, other_idx, rcap, px, py, pz,
                                             0.0, A, n_own)
            S_d[0, c] = dd
            queries += 1
            if trace:
                if npt >= pcap:
                    overflow = 3
                    break
                TP[npt, 0], TP[npt, 1], TP[npt, 2] = S_v[0, c, 0], S_v[0, c, 1], dd
                TJ[npt] = job
                npt += 1
        S_depth[0] = 0
        S_kept[0] = False
        S_a0[0], S_an[0], S_clamp[0] = 0, n_own, rcap
        top = 1 if overflow == 0 else 0
        while top > 0:
            top -= 1
            visited += 1
            for c in range(3):
                v[c, 0] = S_v[top, c, 0]
                v[c, 1] = S_v[top, c, 1]
                d[c] = S_d[top, c]
            depth = S_depth[top]
            kept = S_kept[top]
            slack = S_slack[top]
            a0, an, clamp = S_a0[top], S_an[top], S_clamp[top]
            a_top = a0 + an  # lists above belong to finished subtrees
            m, bulge = region_polygon(v, uv, sx, sy, P, H)
            x0, y0, x1, y1 = P[0, 0], P[0, 1], P[0, 0], P[0, 1]
            for q in range(1, m):
                x0, y0 = min(x0, P[q, 0]), min(y0, P[q, 1])
                x1, y1 = max(x1, P[q, 0]), max(y1, P[q, 1])
            dlo, delta = delta_range(al, fl, x0, y0, x1, y1)
            if sqrt3_mode and not fl and m == 3 and not uv:
                dlo, delta = _SQRT3, _SQRT3  # a straight piece of a basic region: δ ≤ √3 (§4.1)
            rho_r = radius / delta
            status = -1
            emit_kind = -1
            split = False
            # 1. the single-sample rule
            best = -1
            best_w = 0.0
            for c in range(3):
                if kept or d[c] <= on_surface:
                    w = disc_contains(P, m, v[c, 0], v[c, 1], rho_r)
                    if w >= 0.0 and (best < 0 or w < best_w):
                        best, best_w = c, w
            if best >= 0:
                emit_kind = 0
                status = 0
            elif kept:
                emit_kind = 1
                status = 1
            else:
                neg = d[0] < 0.0 and d[1] < 0.0 and d[2] < 0.0
                posi = d[0] > 0.0 and d[1] > 0.0 and d[2] > 0.0
                covered = False
                if neg or posi:
                    for c in range(3):
                        rho[c] = abs(d[c]) / delta
                    covered = discs_cover(P, m, v, rho)
                if covered and posi:
                    status = 2
                elif covered:
                    # 2. kept: every sample in P stays this far from the term's other quadrics
                    slack = math.inf
                    for c in range(3):
                        far = 0.0
                        for q in range(m):
                            far = max(far, _norm2(P[q, 0] - v[c, 0], P[q, 1] - v[c, 1]))
                        slack = min(slack, -d[c] - delta * far)
                    kept = True
                    emit_kind = 1
                    status = 1
                else:
                    diam = 0.0
                    for a in range(m):
                        for b in range(a + 1, m):
                            diam = max(diam, _norm2(P[a, 0] - P[b, 0], P[a, 1] - P[b, 1]))
                    if min_size > 0.0 and diam * min(delta, _SQRT3) < min_size:
                        status = 3
                    elif diam < min_region or depth >= _MAX_DEPTH:
                        status = 4
                        unresolved += 1
                    else:
                        split = True
            count = 1
            apex = 0
            rho_l = rho_r
            lattice_on_triangle = False
            if emit_kind == 1:
                if m > 3 and bulge < 0.5 * rho_r:
                    # lattice the straight triangle, denser by the bulge: the region beyond it is
                    # within ``bulge`` of it (thin fan triangles of P would cost far more samples)
                    rho_l = rho_r - bulge
                    apex, count = _lattice_fan(v, 3, rho_l)
                    lattice_on_triangle = True
                else:
                    apex, count = _lattice_fan(P, m, rho_l)
                if refine and count >= _REFINE_SAMPLES and depth < _MAX_DEPTH and delta > _REFINE_RATIO * dlo:
                    split = True  # geometric split of a kept region: no distance query
                    emit_kind = -1
                    status = -1
            if emit_kind >= 0:
                if nl >= cap:
                    overflow = 1
                    break
                LI[nl, 0] = job
                LI[nl, 1] = emit_kind
                LI[nl, 3] = count
                LF[nl, 12] = delta
                if emit_kind == 0:
                    LF[nl, 0] = v[best, 0]
                    LF[nl, 1] = v[best, 1]
                    LI[nl, 2] = 1
                    LF[nl, 13] = slack if kept else max(-d[best], 0.0)
                    LF[nl, 14] = delta * best_w
                else:
                    if lattice_on_triangle:
                        m = 3
                        for q in range(3):
                            P[q, 0] = v[q, 0]
                            P[q, 1] = v[q, 1]
                    for q in range(m):  # rotated so that the fan apex comes first
                        LF[nl, 2 * q] = P[(q + apex) % m, 0]
                        LF[nl, 2 * q + 1] = P[(q + apex) % m, 1]
                    LI[nl, 2] = m
                    LF[nl, 13] = slack
                    LF[nl, 14] = radius
                    LF[nl, 15] = rho_l
                nl += 1
            if status >= 0:
                if trace:
                    if nt >= tcap:
                        overflow = 2
                        break
                    for c in range(3):
                        TT[nt, 2 * c] = v[c, 0]
                        TT[nt, 2 * c + 1] = v[c, 1]
                    TI[nt, 0], TI[nt, 1], TI[nt, 2] = job, uv, status
                    TI[nt, 3], TI[nt, 4] = depth, k
                    nt += 1
                continue
            if not split:
                continue
            # 3. split the longest edge (a (u, v)-side at its midpoint in (u, v))
            e = 0
            longest = -1.0
            for c in range(3):
                c1 = (c + 1) % 3
                L = _norm2(v[c1, 0] - v[c, 0], v[c1, 1] - v[c, 1])
                if L > longest:
                    longest, e = L, c
            e1 = (e + 1) % 3
            o = (e + 2) % 3
            if uv:
                mx, my = arc_midpoint(v[e, 0], v[e, 1], v[e1, 0], v[e1, 1], sx, sy)
            else:
                mx, my = 0.5 * (v[e, 0] + v[e1, 0]), 0.5 * (v[e, 1] + v[e1, 1])
            dm = -rcap
            c_a0, c_an, c_clamp = a0, an, clamp
            if not kept:
                # quadrics whose surface stays ≥ 3D from the midpoint (D: world diameter of this
                # region) stay ≥ 2D from the children: drop them there and clamp at 2D
                diam = 0.0
                for a in range(m):
                    for b in range(a + 1, m):
                        diam = max(diam, _norm2(P[a, 0] - P[b, 0], P[a, 1] - P[b, 1]))
                world = delta * diam
                keep_below = 3.0 * world if world < clamp else 0.0
                px, py, pz = lift(origin, frame, alpha, k, sheet, mx, my)
                dm, cnt = relative_distance_pruned(C, A, a0, an, own_box, other_ptr, other_idx, clamp,
                                                   px, py, pz, keep_below, A, a_top)
                if keep_below > 0.0:
                    c_a0, c_an, c_clamp = a_top, cnt, 2.0 * world
                queries += 1
                if trace:
                    if npt >= pcap:
                        overflow = 3
                        break
                    TP[npt, 0], TP[npt, 1], TP[npt, 2] = mx, my, dm
                    TJ[npt] = job
                    npt += 1
            # child A = (v_e, M, v_o), child B = (M, v_e1, v_o)
            for child in range(2):
                S_v[top, 0, 0] = v[e, 0] if child == 0 else mx
                S_v[top, 0, 1] = v[e, 1] if child == 0 else my
                S_v[top, 1, 0] = mx if child == 0 else v[e1, 0]
                S_v[top, 1, 1] = my if child == 0 else v[e1, 1]
                S_v[top, 2, 0] = v[o, 0]
                S_v[top, 2, 1] = v[o, 1]
                S_d[top, 0] = d[e] if child == 0 else dm
                S_d[top, 1] = dm if child == 0 else d[e1]
                S_d[top, 2] = d[o]
                S_depth[top] = depth + 1
                S_kept[top] = kept
                S_slack[top] = slack
                S_a0[top], S_an[top], S_clamp[top] = c_a0, c_an, c_clamp
                top += 1
        if overflow != 0:
            return nl0, nt0, npt0, job, overflow
        counters[0] += queries
        counters[1] += visited
        counters[2] += unresolved
        counters[3] += 1
    return nl, nt, npt, job_plane.shape[0], 0


@inline_jit
def _emit(C, qid, own, origin, frame, alpha, k, sheet, x, y, r_s, check_clip, pos, nrm, rad, ccount, cidx, n, nc):
    """Write sample n at plane point (x, y) (capacity is the caller's); return the clip-index count."""
    px, py, pz = lift(origin, frame, alpha, k, sheet, x, y)
    pos[n, 0], pos[n, 1], pos[n, 2] = px, py, pz
    g0 = C[qid, 0] * px + C[qid, 1] * py + C[qid, 2] * pz + C[qid, 6]
    g1 = C[qid, 1] * px + C[qid, 3] * py + C[qid, 4] * pz + C[qid, 7]
    g2 = C[qid, 2] * px + C[qid, 4] * py + C[qid, 5] * pz + C[qid, 8]
    gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    if gn > 0.0:
        nrm[n, 0], nrm[n, 1], nrm[n, 2] = g0 / gn, g1 / gn, g2 / gn
    else:  # a cone's apex: no normal; the sampling plane's, towards the sheet, is a fair choice
        nrm[n, 0], nrm[n, 1], nrm[n, 2] = sheet * frame[k, 0, 2], sheet * frame[k, 1, 2], sheet * frame[k, 2, 2]
    rad[n] = r_s
    c0 = nc
    if check_clip:
        for k in range(own.shape[0]):
            if abs(quadric_distance(C, own[k], px, py, pz)) < r_s:
                cidx[nc] = own[k]
                nc += 1
    ccount[n] = nc - c0
    return nc


@ieee_jit
def emit_quadric(C, qid, own, origin, frame, alpha, job_plane, job_sheet, LF, LI, radius, reduce_radius,
                 pos, nrm, rad, ccount, cidx, leaf_start, n, nc):
    """Pass 2: write the samples of one quadric's leaves ``LF``, ``LI`` from ``leaf_start`` on.

    ``pos``, ``nrm`` (N, 3), ``rad`` (N,) float64 and ``ccount`` (N,) int32 are the caller's
    output arrays, written from index ``n`` on; clip indices go to ``cidx`` from ``nc`` on, in
    sample order. Returns ``(next_leaf, n, nc)``; ``next_leaf`` < number of leaves means
    ``cidx`` may be too small for that leaf: grow it and call again with the returned values.
    """
    n_own = own.shape[0]
    ccap = cidx.shape[0]
    for leaf in range(leaf_start, LI.shape[0]):
        job = LI[leaf, 0]
        k = job_plane[job]
        sheet = job_sheet[job]
        delta = LF[leaf, 12]
        aux = LF[leaf, 13]
        if LI[leaf, 1] == 0:
            r_s = LF[leaf, 14] if reduce_radius else radius
            if nc + n_own > ccap:
                return leaf, n, nc
            nc = _emit(C, qid, own, origin, frame, alpha, k, sheet, LF[leaf, 0], LF[leaf, 1], r_s, aux < r_s,
                       pos, nrm, rad, ccount, cidx, n, nc)
            n += 1
            continue
        m = LI[leaf, 2]
        rho_l = LF[leaf, 15]
        extra = radius - delta * rho_l  # the bulge, in world units
        if nc + LI[leaf, 3] * n_own > ccap and aux < radius:  # radii never exceed ``radius``
            return leaf, n, nc
        for tri in range(m - 2):
            ax, ay = LF[leaf, 0], LF[leaf, 1]
            bx, by = LF[leaf, 2 * tri + 2], LF[leaf, 2 * tri + 3]
            qx, qy = LF[leaf, 2 * tri + 4], LF[leaf, 2 * tri + 5]
            centers, steps, _, reach, cs, ct = lattice_plan(ax, ay, bx, by, qx, qy, rho_l)
            r_s = delta * reach + extra if reduce_radius else radius
            check = aux < r_s
            inv = 1.0 / steps
            e1x, e1y, e2x, e2y = bx - ax, by - ay, qx - ax, qy - ay
            if centers:
                # copies a + (i, j)/n pointing like the triangle, and their point reflections
                for i in range(steps):
                    for j in range(steps - i):
                        for flip in range(2):
                            if flip == 1 and i + j > steps - 2:
                                continue
                            u = (i + cs) * inv if flip == 0 else (i + 1 - cs) * inv
                            w = (j + ct) * inv if flip == 0 else (j + 1 - ct) * inv
                            x = ax + u * e1x + w * e2x
                            y = ay + u * e1y + w * e2y
                            nc = _emit(C, qid, own, origin, frame, alpha, k, sheet, x, y, r_s, check,
                                       pos, nrm, rad, ccount, cidx, n, nc)
                            n += 1
            else:
                for i in range(steps + 1):
                    for j in range(steps + 1 - i):
                        x = ax + (i * inv) * e1x + (j * inv) * e2x
                        y = ay + (i * inv) * e1y + (j * inv) * e2y
                        nc = _emit(C, qid, own, origin, frame, alpha, k, sheet, x, y, r_s, check,
                                   pos, nrm, rad, ccount, cidx, n, nc)
                        n += 1
    return LI.shape[0], n, nc
