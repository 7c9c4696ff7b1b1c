"""Scalar geometry of one sampling region: lift, distortion bound, bulge, disc cover, lattices.

A region is a triangle on a sampling plane, given by its corners in (x, y). Its sides are either
straight (planes) or, in *(u, v) mode*, images of straight segments of (u, v) = (x², y²) within
one quadrant (:mod:`.domains`): arcs of axis-aligned conics centered at the origin, straight
when the segment is axis-parallel or points at the origin. Such an arc turns by at most 90°, so
it lies in the triangle spanned by its chord and its end tangents, and the region lies within a
*bulge* distance of its straight triangle (``region_bulge``). The sampler works on the straight
triangle and shortens every radius by the bulge: that bounds δ, tests disc covers and places
samples for the curved region (arcs flatten quadratically as regions shrink).

All functions are numba kernels on scalars and small arrays, called from the sampler.
"""

from __future__ import annotations

import math

from csgnb.csg.distance import inline_jit

__all__ = [
    "lift",
    "delta_range",
    "arc_midpoint",
    "region_bulge",
    "discs_cover",
    "corner_reach",
    "covering_radius",
    "enclosing_circle",
    "lattice_plan",
    "_norm2",
]


@inline_jit
def _norm2(x, y):
    """√(x² + y²) (libm's hypot guards against overflow we cannot have, at 10× the cost)."""
    return math.sqrt(x * x + y * y)


@inline_jit
def lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, ax, ay, ac, sheet, x, y):
    """Return the world point over (x, y) of a sampling plane on the sheet ``t = sheet·h(x, y)``.

    The plane is given by scalars: origin (o0, o1, o2), frame F (columns x axis, y axis, normal)
    and α = (ax, ay, ac) — scalars, not arrays, because numba reference-counts every array bound
    in an inlined call, which in the sampler's loops cost more than the arithmetic. Rounding just
    outside the heightfield's domain (h² < 0) is clamped to the rim, h = 0.
    """
    h2 = ax * x * x + ay * y * y + ac
    t = sheet * math.sqrt(h2) if h2 > 0.0 else 0.0
    return (
        o0 + x * f00 + y * f01 + t * f02,
        o1 + x * f10 + y * f11 + t * f12,
        o2 + x * f20 + y * f21 + t * f22,
    )


@inline_jit
def delta_range(ax, ay, ac, flat, x0, y0, x1, y1):
    """Return (min δ, max δ) (eq. 13) over the rectangle [x0, x1] × [y0, y1]; max is inf off the domain.

    As ``csgnb.quadric.distortion_bounds``: δ² - 1 is linear-fractional in (u, v) = (x², y²), so
    the corners of the rectangle folded into one quadrant bound it. At a cone's apex (α_c = 0,
    u = v = 0) δ is undefined but constant along rays, so the other corners bound it. ``flat``
    planes have δ = 1.
    """
    if flat:
        return 1.0, 1.0
    sx, sy = ax * ax, ay * ay
    u0, u1 = x0 * x0, x1 * x1
    v0, v1 = y0 * y0, y1 * y1
    uhi, vhi = max(u0, u1), max(v0, v1)
    ulo = 0.0 if x0 * x1 <= 0.0 else min(u0, u1)
    vlo = 0.0 if y0 * y1 <= 0.0 else min(v0, v1)
    lo = math.inf
    hi = 0.0
    for c in range(4):
        u = uhi if c & 1 else ulo
        v = vhi if c & 2 else vlo
        den = ax * u + ay * v + ac
        if den > 0.0:
            r = (sx * u + sy * v) / den
            lo = min(lo, r)
            hi = max(hi, r)
        elif ac == 0.0 and u == 0.0 and v == 0.0:
            continue
        else:
            return 1.0, math.inf
    return math.sqrt(1.0 + lo), math.sqrt(1.0 + hi)


@inline_jit
def arc_midpoint(ax, ay, bx, by, sx, sy):
    """Return the point of the (u, v)-segment a → b whose x (or y, if that spans more) is halfway.

    Any point of the segment keeps both halves (u, v)-segments; halving the larger coordinate
    span keeps the two pieces about equally long in (x, y).
    """
    if abs(bx - ax) >= abs(by - ay):
        xm = 0.5 * (ax + bx)
        s = (xm * xm - ax * ax) / (bx * bx - ax * ax)
        vm = ay * ay + s * (by * by - ay * ay)
        return xm, sy * math.sqrt(max(vm, 0.0))
    ym = 0.5 * (ay + by)
    s = (ym * ym - ay * ay) / (by * by - ay * ay)
    um = ax * ax + s * (bx * bx - ax * ax)
    return sx * math.sqrt(max(um, 0.0)), ym


@inline_jit
def _segment_distance(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0.0 else min(max(((px - ax) * dx + (py - ay) * dy) / L2, 0.0), 1.0)
    ex, ey = px - ax - t * dx, py - ay - t * dy
    return math.sqrt(ex * ex + ey * ey)


@inline_jit
def region_bulge(v0x, v0y, v1x, v1y, v2x, v2y, uv, sx, sy):
    """Return how far the region over the triangle v0 v1 v2 reaches beyond the straight triangle.

    ``uv``: whether the sides are (u, v)-segments in the quadrant of signs ``sx, sy`` (else the
    region is the triangle: 0). Each arc lies in the triangle of its chord and the intersection T
    of its end tangents, so the lens between arc and chord is within dist(T, chord) of the chord;
    the region differs from the straight triangle only by such lenses (a winding-number argument
    that holds even when strongly curved sides flip the straight triangle's orientation). The
    sampler works on the straight triangle with every radius shortened by this bound.
    """
    if not uv:
        return 0.0
    bulge = 0.0
    vx = (v0x, v1x, v2x)
    vy = (v0y, v1y, v2y)
    for e in range(3):
        f = (e + 1) % 3
        x0, y0 = vx[e], vy[e]
        x1, y1 = vx[f], vy[f]
        du = x1 * x1 - x0 * x0
        dv = y1 * y1 - y0 * y0
        # tangent of s ↦ (sx √u(s), sy √v(s)), scaled by 2√u√v to stay finite on the axes
        t0x, t0y = sx * du * abs(y0), sy * dv * abs(x0)
        t1x, t1y = sx * du * abs(y1), sy * dv * abs(x1)
        det = t1x * t0y - t0x * t1y
        tn = math.sqrt(t0x * t0x + t0y * t0y) * math.sqrt(t1x * t1x + t1y * t1y)
        if not abs(det) > 1e-12 * tn:
            continue  # a straight side (axis-parallel or radial), or too short to bulge
        w = ((x1 - x0) * (-t1y) + t1x * (y1 - y0)) / det
        bulge = max(bulge, _segment_distance(x0 + w * t0x, y0 + w * t0y, x0, y0, x1, y1))
    return bulge


@inline_jit
def _power(cx, cy, r2, x, y):
    """min_k |x - c_k|² - r_k² over three discs."""
    best = math.inf
    for k in range(3):
        dx, dy = x - cx[k], y - cy[k]
        best = min(best, dx * dx + dy * dy - r2[k])
    return best


@inline_jit
def discs_cover(v0x, v0y, v1x, v1y, v2x, v2y, r0, r1, r2):
    """Return whether the discs of radii r0, r1, r2 around the corners cover the triangle v0 v1 v2.

    Exact up to rounding: the power function f(x) = min_k |x - v_k|² - r_k² is convex on each
    power cell, so its maximum over the triangle is at a corner (where it is ≤ 0), where a power
    bisector crosses an edge, or at the power center of the three discs if it lies inside.
    """
    # work relative to v0: the triangle is small compared with its position
    cx = (0.0, v1x - v0x, v2x - v0x)
    cy = (0.0, v1y - v0y, v2y - v0y)
    r2 = (r0 * r0, r1 * r1, r2 * r2)
    for i in range(3):
        for j in range(i + 1, 3):
            nx, ny = cx[j] - cx[i], cy[j] - cy[i]
            kk = 0.5 * (cx[j] * cx[j] + cy[j] * cy[j] - cx[i] * cx[i] - cy[i] * cy[i] + r2[i] - r2[j])
            for e in range(3):
                f = (e + 1) % 3
                dx, dy = cx[f] - cx[e], cy[f] - cy[e]
                den = nx * dx + ny * dy
                if den != 0.0:
                    t = (kk - nx * cx[e] - ny * cy[e]) / den
                    if 0.0 <= t <= 1.0:
                        if _power(cx, cy, r2, cx[e] + t * dx, cy[e] + t * dy) > 0.0:
                            return False
    # power center: equal power to all three discs
    a1x, a1y = cx[1], cy[1]
    a2x, a2y = cx[2], cy[2]
    b1 = 0.5 * (a1x * a1x + a1y * a1y + r2[0] - r2[1])
    b2 = 0.5 * (a2x * a2x + a2y * a2y + r2[0] - r2[2])
    det = a1x * a2y - a1y * a2x
    if det != 0.0:
        qx = (b1 * a2y - b2 * a1y) / det
        qy = (a1x * b2 - a2x * b1) / det
        # barycentric test: q = s·a1 + t·a2 with s, t ≥ 0, s + t ≤ 1
        s_ = (qx * a2y - qy * a2x) / det
        t_ = (a1x * qy - a1y * qx) / det
        if s_ >= 0.0 and t_ >= 0.0 and s_ + t_ <= 1.0 and _power(cx, cy, r2, qx, qy) > 0.0:
            return False
    return True


@inline_jit
def corner_reach(v0x, v0y, v1x, v1y, v2x, v2y, c):
    """Return the largest distance from corner ``c`` to the other corners of the triangle."""
    vx = (v0x, v1x, v2x)
    vy = (v0y, v1y, v2y)
    worst = 0.0
    for k in range(3):
        dx, dy = vx[k] - vx[c], vy[k] - vy[c]
        worst = max(worst, dx * dx + dy * dy)
    return math.sqrt(worst)


@inline_jit
def covering_radius(ax, ay, bx, by, cx, cy):
    """Return a bound on the distance from any point of triangle abc to its nearest corner.

    The circumradius bounds it for every triangle (a point of the triangle is in the circumdisc
    and the nearest corner's Voronoi cell within the triangle stays inside it); the longest edge
    bounds it too and is used for slivers.
    """
    la = _norm2(bx - cx, by - cy)
    lb = _norm2(ax - cx, ay - cy)
    lc = _norm2(ax - bx, ay - by)
    longest = max(la, max(lb, lc))
    area2 = abs((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))
    if area2 > 0.0:
        circ = la * lb * lc / (2.0 * area2)
        return min(circ, longest)
    return longest


@inline_jit
def enclosing_circle(ax, ay, bx, by, cx, cy):
    """Return (s, t, radius) of the smallest disc holding triangle abc, center a + s(b - a) + t(c - a).

    The midpoint of the longest edge for a right or obtuse triangle, else the circumcenter.
    """
    e1x, e1y = bx - ax, by - ay
    e2x, e2y = cx - ax, cy - ay
    l1 = e1x * e1x + e1y * e1y  # |ab|²
    l2 = e2x * e2x + e2y * e2y  # |ac|²
    l3 = (cx - bx) * (cx - bx) + (cy - by) * (cy - by)  # |bc|²
    if l3 >= l1 + l2:  # angle at a ≥ 90°: longest edge bc
        return 0.5, 0.5, 0.5 * math.sqrt(l3)
    if l2 >= l1 + l3:  # at b: longest edge ac
        return 0.0, 0.5, 0.5 * math.sqrt(l2)
    if l1 >= l2 + l3:  # at c: longest edge ab
        return 0.5, 0.0, 0.5 * math.sqrt(l1)
    g = e1x * e2x + e1y * e2y
    det = l1 * l2 - g * g
    s = 0.5 * (l1 * l2 - g * l2) / det
    t = 0.5 * (l1 * l2 - g * l1) / det
    ox, oy = s * e1x + t * e2x, s * e1y + t * e2y
    return s, t, math.sqrt(ox * ox + oy * oy)


@inline_jit
def lattice_plan(ax, ay, bx, by, cx, cy, rho):
    """Return how to cover triangle abc with points so every point is within ``rho`` of one.

    Two uniform patterns on the n × n subdivision of the triangle into copies of itself:
    its (n + 1)(n + 2)/2 vertices (covering radius: circumradius / n), or the n² centers of the
    copies' smallest enclosing discs (radius: that disc's / n) — fewer points for small n, and
    none on the triangle's edges, where neighbouring regions would duplicate them.

    Returns (centers, n, count, reach, s, t): the pattern, n, the number of points, the covering
    radius per point (in plane units) and the enclosing-disc center parameters (see
    ``enclosing_circle``).
    """
    cr = covering_radius(ax, ay, bx, by, cx, cy)
    nv = max(1, int(math.ceil(cr / rho)))
    s, t, mr = enclosing_circle(ax, ay, bx, by, cx, cy)
    nc = max(1, int(math.ceil(mr / rho)))
    count_v = (nv + 1) * (nv + 2) // 2
    count_c = nc * nc
    if count_c <= count_v:
        return True, nc, count_c, mr / nc, s, t
    return False, nv, count_v, cr / nv, s, t
