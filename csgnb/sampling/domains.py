"""The sampling domains of a quadric: its low-distortion regions as triangles in (U, V).

§4.1 partitions each sampling plane, per quadrant and octant, into the region where that plane
sees the surface with distortion δ ≤ √3. In (U, V) = (x² or x, y² or y) — a coordinate is squared
when the heightfield has a quadratic term in it — every boundary of such a region is a straight
line: the octant line, the conic of eq. 15/16 (``csgnb.quadric.frames.region_lines``) and the
bounding box; so the region is a convex polygon there (``csgnb.quadric.regions`` cuts the
polygons into Figure 8's basic-region kinds for pictures). The sampler takes the polygons as they
are: each is fan-triangulated *in (U, V)*, and a (U, V)-triangle is a basic region whose three
sides are images of (U, V)-segments — conic or parabola arcs, or straight lines. That one kind
covers all of Figure 8 (a rectangle is two of them) and is closed under bisection at
(U, V)-midpoints, which is how the sampler splits it (:mod:`.geometry`).

Every quadric type takes this path: central quadrics (eq. 7), paraboloids (parabolic sheets on
their side planes, a graph along their axis) and single planes (a flat graph, whose polygon is
also clipped by the box's faces, so that it is exactly the plane's polygon in the box). One numba
kernel builds the jobs of all quadrics of a model: microseconds per quadric.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_finite_array, as_positive
from csgnb.quadric.frames import FORM_GRAPH, FORM_NONE, FORM_SHEETS, frame_kernel, region_lines
from csgnb.quadric.quadric import Quadric

__all__ = ["quadric_jobs", "domain_cache_clear", "JOBS_PER_QUADRIC", "jobs_kernel"]

#: Upper bound on the jobs of one quadric: 3 planes × 4 quadrants × 2 octants × (a polygon of at
#: most 12 vertices: 10 fan triangles) × 2 sheets.
JOBS_PER_QUADRIC = 480


@jit
def _clip_uv(px, py, m, a, b, c, qx, qy):
    """Clip the convex polygon (px, py)[:m] to a·u + b·v + c ≥ 0 into (qx, qy); return its size."""
    n = 0
    for e in range(m):
        f = (e + 1) % m
        fe = a * px[e] + b * py[e] + c
        ff = a * px[f] + b * py[f] + c
        if fe >= 0.0:
            qx[n] = px[e]
            qy[n] = py[e]
            n += 1
            if ff < 0.0 and fe > 0.0:
                s = fe / (fe - ff)
                qx[n] = px[e] + s * (px[f] - px[e])
                qy[n] = py[e] + s * (py[f] - py[e])
                n += 1
        elif ff > 0.0:
            s = fe / (fe - ff)
            qx[n] = px[e] + s * (px[f] - px[e])
            qy[n] = py[e] + s * (py[f] - py[e])
            n += 1
    return n


@jit(inline="always")
def _copy_polygon(qx, qy, m, px, py):
    """px[:m], py[:m] = qx[:m], qy[:m] (element by element: numba's slice assignment types a shape-mismatch error
    message, seconds of compilation)."""
    for e in range(m):
        px[e] = qx[e]
        py[e] = qy[e]


@jit
def jobs_kernel(center, axes, form, coef, box, unit, jt, jplane, jsheet, juv, jquad, at):
    """Write the jobs of one quadric inside ``box`` (6,) from index ``at`` on; return the new count.

    ``center`` (3,), ``axes`` (3, 3), ``form`` (3,), ``coef`` (3, 5): the quadric's frame
    (``csgnb.quadric.frames.frame_kernel``). ``unit``: the model size (slivers thinner than
    ``tolerances.SLIVER``·unit are dropped). Per job: the triangle ``jt`` (·, 3, 2) in plane
    coordinates, its plane, sheet (±1), squared-coordinate flags ``juv`` and quadrant signs.
    """
    px = np.empty(24)
    py = np.empty(24)
    qx = np.empty(24)
    qy = np.empty(24)
    corners = np.empty((8, 3))
    for m in range(8):
        corners[m, 0] = box[3] if m & 1 else box[0]
        corners[m, 1] = box[4] if m & 2 else box[1]
        corners[m, 2] = box[5] if m & 4 else box[2]
    for k in range(3):
        fk = form[k]
        if fk == FORM_NONE:
            continue
        ax, bx, ay, by, ac = coef[k, 0], coef[k, 1], coef[k, 2], coef[k, 3], coef[k, 4]
        i = (k + 1) % 3
        j = (k + 2) % 3
        lo_x = math.inf
        hi_x = -math.inf
        lo_y = math.inf
        hi_y = -math.inf
        for m in range(8):
            dx = corners[m, 0] - center[0]
            dy = corners[m, 1] - center[1]
            dz = corners[m, 2] - center[2]
            lx = dx * axes[0, i] + dy * axes[1, i] + dz * axes[2, i]
            ly = dx * axes[0, j] + dy * axes[1, j] + dz * axes[2, j]
            lo_x, hi_x = min(lo_x, lx), max(hi_x, lx)
            lo_y, hi_y = min(lo_y, ly), max(hi_y, ly)
        xs = ax != 0.0
        ys = ay != 0.0
        uvflag = (1 if xs else 0) + (2 if ys else 0)
        flat = fk == FORM_GRAPH and not xs and not ys
        n_sheets = 1 if fk == FORM_GRAPH else 2
        if fk == FORM_SHEETS and ax == 0.0 and ay == 0.0 and bx == 0.0 and by == 0.0 and ac == 0.0:
            n_sheets = 1  # t² ≡ 0: one (double) plane
        w0 = region_lines(fk, ax, bx, ay, by, ac, 0)
        same_octants = w0[0] == 0.0 and w0[1] == 0.0 and w0[2] == 0.0
        for qs in range(4):
            sx = 1.0 if qs & 1 == 0 else -1.0
            sy = 1.0 if qs & 2 == 0 else -1.0
            if (not xs and sx < 0.0) or (not ys and sy < 0.0):
                continue  # a linear coordinate is not split at its axis
            if xs:
                xa, xb = (lo_x, hi_x) if sx > 0.0 else (-hi_x, -lo_x)
                xa = max(xa, 0.0)
                if xb <= xa:
                    continue
                u0, u1 = xa * xa, xb * xb
            else:
                u0, u1 = lo_x, hi_x
            if ys:
                ya, yb = (lo_y, hi_y) if sy > 0.0 else (-hi_y, -lo_y)
                ya = max(ya, 0.0)
                if yb <= ya:
                    continue
                v0, v1 = ya * ya, yb * yb
            else:
                v0, v1 = lo_y, hi_y
            big = max(max(abs(u0), abs(u1)), max(abs(v0), abs(v1)))
            area_tol = tol.DEGENERATE_AREA * big * big
            for octant in range(2):
                if same_octants and octant == 1:
                    continue  # both octants are the whole quadrant
                px[0], py[0], px[1], py[1] = u0, v0, u1, v0
                px[2], py[2], px[3], py[3] = u1, v1, u0, v1
                m = 4
                lines = region_lines(fk, ax, bx, ay, by, ac, octant)
                if not same_octants:
                    m = _clip_uv(px, py, np.int64(m), lines[0], lines[1], lines[2], qx, qy)
                    _copy_polygon(qx, qy, m, px, py)
                m = _clip_uv(px, py, np.int64(m), lines[3], lines[4], lines[5], qx, qy)
                _copy_polygon(qx, qy, m, px, py)
                if flat:  # a single plane: clip by the box's faces, exactly its polygon
                    tz = ac
                    for e in range(3):
                        # world coordinate e over (x, y): center + x uᵢ + y uⱼ + t uₖ
                        cu = axes[e, i]
                        cv = axes[e, j]
                        c0 = center[e] + tz * axes[e, k]
                        if m >= 3:
                            m = _clip_uv(px, py, np.int64(m), -cu, -cv, box[3 + e] - c0, qx, qy)
                            _copy_polygon(qx, qy, m, px, py)
                        if m >= 3:
                            m = _clip_uv(px, py, np.int64(m), cu, cv, c0 - box[e], qx, qy)
                            _copy_polygon(qx, qy, m, px, py)
                if m < 3:
                    continue
                area = 0.0
                for e in range(m):
                    f = (e + 1) % m
                    area += px[e] * py[f] - px[f] * py[e]
                if abs(area) <= area_tol:
                    continue
                for t in range(1, m - 1):
                    # the (U, V) fan triangle in (x, y)
                    tx0 = sx * math.sqrt(max(px[0], 0.0)) if xs else px[0]
                    ty0 = sy * math.sqrt(max(py[0], 0.0)) if ys else py[0]
                    tx1 = sx * math.sqrt(max(px[t], 0.0)) if xs else px[t]
                    ty1 = sy * math.sqrt(max(py[t], 0.0)) if ys else py[t]
                    tx2 = sx * math.sqrt(max(px[t + 1], 0.0)) if xs else px[t + 1]
                    ty2 = sy * math.sqrt(max(py[t + 1], 0.0)) if ys else py[t + 1]
                    # Clipping to a box whose face is within rounding of a plane's axis leaves
                    # slivers (e.g. 1e-8 thick) outside the object; proving them empty takes
                    # length/width subdivisions. The surface over them is within their width of a
                    # neighbouring triangle's: drop them.
                    e0 = math.sqrt((tx1 - tx0) ** 2 + (ty1 - ty0) ** 2)
                    e1 = math.sqrt((tx2 - tx1) ** 2 + (ty2 - ty1) ** 2)
                    e2 = math.sqrt((tx0 - tx2) ** 2 + (ty0 - ty2) ** 2)
                    longest = max(e0, max(e1, e2))
                    area2 = abs((tx1 - tx0) * (ty2 - ty0) - (ty1 - ty0) * (tx2 - tx0))
                    if not area2 > tol.SLIVER * unit * longest:
                        continue
                    for sh in range(n_sheets):
                        jt[at, 0, 0], jt[at, 0, 1] = tx0, ty0
                        jt[at, 1, 0], jt[at, 1, 1] = tx1, ty1
                        jt[at, 2, 0], jt[at, 2, 1] = tx2, ty2
                        jplane[at] = k
                        jsheet[at] = 1.0 if sh == 0 else -1.0
                        juv[at] = uvflag
                        jquad[at, 0] = sx
                        jquad[at, 1] = sy
                        at += 1
    return at


def quadric_jobs(q: Quadric, box, unit: float | None = None):
    """Return the sampling jobs of ``q`` inside ``box`` : (6,) (lo, hi).

    Returns ``(origin (3, 3), frame (3, 3, 3), coef (3, 5), form (3,) int64, plane (J,) int64,
    sheet (J,) ±1.0, triangle (J, 3, 2) plane coordinates, uv (J,) int64, quadrant (J, 2))``:
    per sampling plane k its origin, axes (x, y, normal as columns), heightfield
    (αₓ, bₓ, α_y, b_y, α_c) and form code (``csgnb.quadric.frames``); per job a triangle on plane
    ``plane[j]`` lifted to the sheet ``sheet[j]``, whose sides are (U, V)-segments in the quadrant
    ``quadrant[j]`` with squared-coordinate flags ``uv[j]`` (bit 0: x, bit 1: y; 0: straight).
    ``unit``: the model size for the sliver test (default: of the box).
    """
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a csgnb.quadric.Quadric, got {type(q).__name__}")
    box = as_finite_array(box, (6,), "box")
    unit = 0.5 * float(np.linalg.norm(box[3:] - box[:3])) if unit is None else as_positive(unit, "unit")
    center, axes, lam, beta = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty(3)
    form, coef = np.empty(3, dtype=np.int64), np.empty((3, 5))
    frame_kernel(np.array(q.matrix, np.float64, order="C"), center, axes, lam, beta, form, coef)
    jt = np.empty((JOBS_PER_QUADRIC, 3, 2))
    jp = np.empty(JOBS_PER_QUADRIC, dtype=np.int64)
    js = np.empty(JOBS_PER_QUADRIC)
    ju = np.empty(JOBS_PER_QUADRIC, dtype=np.int64)
    jq = np.empty((JOBS_PER_QUADRIC, 2))
    n = jobs_kernel(center, axes, form, coef, box, float(unit), jt, jp, js, ju, jq, 0)
    origin = np.tile(center, (3, 1))
    frame = np.array([axes[:, [(k + 1) % 3, (k + 2) % 3, k]] for k in range(3)])
    return origin, frame, coef, form, jp[:n], js[:n], jt[:n], ju[:n], jq[:n]


def domain_cache_clear() -> None:
    """Kept for callers of the former cache: the domains are built by a kernel and not cached."""
