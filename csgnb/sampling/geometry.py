"""Scalar geometry of one sampling region: lift, distortion bound, bounding polygon, disc cover.

A region is a triangle on a sampling plane, given by its corners in (x, y). Its sides are either
straight (planes) or, in *(u, v) mode*, images of straight segments of (u, v) = (x², y²) within
one quadrant (:mod:`.domains`): arcs of axis-aligned conics centered at the origin, straight
when the segment is axis-parallel or points at the origin. Such an arc turns by at most 90°, so
it lies in the triangle spanned by its chord and its end tangents. The region therefore lies in
the convex hull of its corners and the tangent points of its arcs — its *bounding polygon* (3 to
6 vertices), on which the sampler bounds δ, tests disc covers and places samples.

All functions are numba kernels on scalars and small arrays, called from the sampler.
"""

from __future__ import annotations

import math

from csgnb.csg.distance import inline_jit

__all__ = [
    "lift",
    "delta_range",
    "arc_midpoint",
    "region_polygon",
    "discs_cover",
    "disc_contains",
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
def lift(origin, frame, alpha, k, sheet, x, y):
    """Return the world point over (x, y) of sampling plane ``k`` on the sheet ``t = sheet·h(x, y)``.

    ``origin`` (3, 3), ``frame`` (3, 3, 3) (columns x axis, y axis, normal) and ``alpha`` (3, 3)
    hold the three planes (indexed, not sliced: a slice would be reference-counted). Rounding
    just outside the heightfield's domain (h² < 0) is clamped to the rim, h = 0.
    """
    h2 = alpha[k, 0] * x * x + alpha[k, 1] * y * y + alpha[k, 2]
    t = sheet * math.sqrt(h2) if h2 > 0.0 else 0.0
    return (
        origin[k, 0] + x * frame[k, 0, 0] + y * frame[k, 0, 1] + t * frame[k, 0, 2],
        origin[k, 1] + x * frame[k, 1, 0] + y * frame[k, 1, 1] + t * frame[k, 1, 2],
        origin[k, 2] + x * frame[k, 2, 0] + y * frame[k, 2, 1] + t * frame[k, 2, 2],
    )


@inline_jit
def delta_range(al, flat, x0, y0, x1, y1):
    """Return (min δ, max δ) (eq. 13) over the rectangle [x0, x1] × [y0, y1]; max is inf off the domain.

    As ``csgnb.quadric.distortion_bounds``: δ² - 1 is linear-fractional in (u, v) = (x², y²), so
    the corners of the rectangle folded into one quadrant bound it. At a cone's apex (α_c = 0,
    u = v = 0) δ is undefined but constant along rays, so the other corners bound it. ``flat``
    planes have δ = 1.
    """
    if flat:
        return 1.0, 1.0
    ax, ay, ac = al[0], al[1], al[2]
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
def region_polygon(v, uv, sx, sy, P, H):
    """Write the bounding polygon of a region into ``P`` : (6, 2); return (vertex count 3–6, bulge).

    ``H`` : (6, 2) scratch space. ``v`` : (3, 2) corners; ``uv``: whether the sides are (u, v)-segments in the
    quadrant of signs ``sx, sy``. The polygon is the convex hull of the corners and of the end-tangent intersection
    of every curved side (each arc lies in the triangle of its chord and that point), so it holds
    the region even when strongly curved sides make the straight triangle a poor guide (it can
    even have the opposite orientation). ``bulge`` is the largest distance from a polygon vertex
    to the straight triangle: every point of the region is within it of the triangle.
    """
    m = 3
    for e in range(3):
        P[e, 0] = v[e, 0]
        P[e, 1] = v[e, 1]
    if uv:
        for e in range(3):
            f = (e + 1) % 3
            x0, y0 = v[e, 0], v[e, 1]
            x1, y1 = v[f, 0], v[f, 1]
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
            P[m, 0] = x0 + w * t0x
            P[m, 1] = y0 + w * t0y
            m += 1
    if m == 3:
        return 3, 0.0
    # convex hull of the m ≤ 6 points (gift wrapping from the lowest-leftmost point)
    start = 0
    for i in range(1, m):
        if P[i, 1] < P[start, 1] or (P[i, 1] == P[start, 1] and P[i, 0] < P[start, 0]):
            start = i
    n = 0
    cur = start
    while n < 6:
        H[n, 0] = P[cur, 0]
        H[n, 1] = P[cur, 1]
        n += 1
        nxt = (cur + 1) % m
        for j in range(m):
            cr = (P[nxt, 0] - P[cur, 0]) * (P[j, 1] - P[cur, 1]) - (P[nxt, 1] - P[cur, 1]) * (P[j, 0] - P[cur, 0])
            if cr < 0.0 or (cr == 0.0 and (P[j, 0] - P[cur, 0]) ** 2 + (P[j, 1] - P[cur, 1]) ** 2
                            > (P[nxt, 0] - P[cur, 0]) ** 2 + (P[nxt, 1] - P[cur, 1]) ** 2):
                nxt = j
        cur = nxt
        if cur == start:
            break
    # distance of the hull vertices outside the straight triangle to it
    orient = (v[1, 0] - v[0, 0]) * (v[2, 1] - v[0, 1]) - (v[1, 1] - v[0, 1]) * (v[2, 0] - v[0, 0])
    bulge = 0.0
    for i in range(n):
        outside = False
        for e in range(3):
            f = (e + 1) % 3
            cr = (v[f, 0] - v[e, 0]) * (H[i, 1] - v[e, 1]) - (v[f, 1] - v[e, 1]) * (H[i, 0] - v[e, 0])
            if cr * orient < 0.0:
                outside = True
        if outside:
            dmin = math.inf
            for e in range(3):
                f = (e + 1) % 3
                dmin = min(dmin, _segment_distance(H[i, 0], H[i, 1], v[e, 0], v[e, 1], v[f, 0], v[f, 1]))
            bulge = max(bulge, dmin)
    for i in range(n):
        P[i, 0] = H[i, 0]
        P[i, 1] = H[i, 1]
    return n, bulge


@inline_jit
def _power(cx, cy, r2, x, y):
    """min_k |x - c_k|² - r_k² over three discs."""
    best = math.inf
    for k in range(3):
        dx, dy = x - cx[k], y - cy[k]
        best = min(best, dx * dx + dy * dy - r2[k])
    return best


@inline_jit
def discs_cover(P, m, v, rho):
    """Return whether the discs (v[k], rho[k]), k < 3, cover the convex polygon P[:m] (m ≤ 6).

    Exact up to rounding: the power function f(x) = min_k |x - v_k|² - ρ_k² is convex on each
    power cell, so its maximum over P is at a vertex of P, where a power bisector crosses an
    edge of P, or at the power center of the three discs if it lies in P.
    """
    # work relative to v[0]: the polygon is small compared with its position
    ox, oy = v[0, 0], v[0, 1]
    cx = (0.0, v[1, 0] - ox, v[2, 0] - ox)
    cy = (0.0, v[1, 1] - oy, v[2, 1] - oy)
    r2 = (rho[0] * rho[0], rho[1] * rho[1], rho[2] * rho[2])
    # P[m:] is never read (the array is always (6, 2))
    px = (P[0, 0] - ox, P[1, 0] - ox, P[2, 0] - ox, P[3, 0] - ox, P[4, 0] - ox, P[5, 0] - ox)
    py = (P[0, 1] - oy, P[1, 1] - oy, P[2, 1] - oy, P[3, 1] - oy, P[4, 1] - oy, P[5, 1] - oy)
    for k in range(m):
        if _power(cx, cy, r2, px[k], py[k]) > 0.0:
            return False
    area2 = 0.0
    for k in range(m):
        n = (k + 1) % m
        area2 += px[k] * py[n] - px[n] * py[k]
    for i in range(3):
        for j in range(i + 1, 3):
            nx, ny = cx[j] - cx[i], cy[j] - cy[i]
            kk = 0.5 * (cx[j] * cx[j] + cy[j] * cy[j] - cx[i] * cx[i] - cy[i] * cy[i] + r2[i] - r2[j])
            for e in range(m):
                f = (e + 1) % m
                dx, dy = px[f] - px[e], py[f] - py[e]
                den = nx * dx + ny * dy
                if den != 0.0:
                    t = (kk - nx * px[e] - ny * py[e]) / den
                    if 0.0 <= t <= 1.0:
                        if _power(cx, cy, r2, px[e] + t * dx, py[e] + t * dy) > 0.0:
                            return False
    # power center: equal power to all three discs
    a1x, a1y = cx[1] - cx[0], cy[1] - cy[0]
    a2x, a2y = cx[2] - cx[0], cy[2] - cy[0]
    b1 = 0.5 * (cx[1] * cx[1] + cy[1] * cy[1] - cx[0] * cx[0] - cy[0] * cy[0] + r2[0] - r2[1])
    b2 = 0.5 * (cx[2] * cx[2] + cy[2] * cy[2] - cx[0] * cx[0] - cy[0] * cy[0] + r2[0] - r2[2])
    det = a1x * a2y - a1y * a2x
    if det != 0.0:
        qx = (b1 * a2y - b2 * a1y) / det
        qy = (a1x * b2 - a2x * b1) / det
        inside = True
        for e in range(m):
            f = (e + 1) % m
            cr = (px[f] - px[e]) * (qy - py[e]) - (py[f] - py[e]) * (qx - px[e])
            if cr * area2 < 0.0:
                inside = False
                break
        if inside and _power(cx, cy, r2, qx, qy) > 0.0:
            return False
    return True


@inline_jit
def disc_contains(P, m, cx, cy, rho):
    """Return the largest distance from (cx, cy) to the vertices of P[:m] if ≤ rho, else -1.

    (P is convex, so the disc holds P iff it holds P's vertices.)
    """
    worst = 0.0
    for k in range(m):
        dx, dy = P[k, 0] - cx, P[k, 1] - cy
        worst = max(worst, dx * dx + dy * dy)
    worst = math.sqrt(worst)
    return worst if worst <= rho else -1.0


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
