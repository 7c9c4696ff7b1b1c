"""Scalar geometry of one sampling region: lift, distortion bound, bulge, disc cover, lattices.

A region is a triangle on a sampling plane, given by its corners in (x, y). Its sides are images of
straight segments in (U, V) = (x² or x, y² or y) within one quadrant (:mod:`.domains`): ``uv``
flags say which coordinates are squared (bit 0: x, bit 1: y; 0: all sides straight). With both
squared the sides are arcs of axis-aligned conics centered at the origin, with one a parabola arc;
they are straight when the segment is axis-parallel (or, both squared, points at the origin).
Such an arc is convex and turns by at most 90°, so it lies in the triangle spanned by its chord
and its end tangents, and the region lies within a *bulge* distance of its straight triangle
(``region_bulge``). The sampler works on the straight triangle and shortens every radius by the
bulge: that bounds δ, tests disc covers and places samples for the curved region (arcs flatten
quadratically as regions shrink).

All functions are numba kernels on scalars and small arrays, called from the sampler.

The few the sampler's loop runs on every region (``lift``, ``_arc_deviation``, ``discs_cover``) are inlined
into it; the rest (``arc_midpoint``, ``region_bulge``, ``corner_reach``, ``lattice_plan``, and
``distortions.delta_at_points``) are called: inlined, each copy was typed and optimised again inside
``subdivide_all`` (19.7 s of compilation, the largest kernel of the quadric pipeline), and the smaller loop
ran as fast or faster (2026-12-03, alternating runs of ``bench_sampling.py`` on one thread: e.g. the
bracket rows 15.2 / 22.1 / 36.5 → 12.7 / 19.4 / 29.5 ms).
"""

from __future__ import annotations

import math

from csgnb.quadric.distortions import delta_range
from csgnb.quadric.evaluate import ieee_jit, inline_jit
from csgnb.quadric.frames import plane_height

__all__ = [
    "lift",
    "delta_range",
    "arc_midpoint",
    "segment_point",
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
def lift(o0, o1, o2, f00, f01, f02, f10, f11, f12, f20, f21, f22, form, ax, bx, ay, by, ac, sheet, x, y):
    """Return the world point over (x, y) of a sampling plane on the sheet ``t = sheet·√H`` (or t = H).

    The plane is given by scalars: origin (o0, o1, o2), frame F (columns x axis, y axis, normal),
    its form and heightfield (αₓ, bₓ, α_y, b_y, α_c) (``csgnb.quadric.frames``) — scalars, not
    arrays, because numba reference-counts every array bound in an inlined call, which in the
    sampler's loops cost more than the arithmetic. Rounding just outside a sheet's domain (H < 0)
    is clamped to the rim, t = 0.
    """
    t = plane_height(form, ax, bx, ay, by, ac, sheet, x, y)
    return (
        o0 + x * f00 + y * f01 + t * f02,
        o1 + x * f10 + y * f11 + t * f12,
        o2 + x * f20 + y * f21 + t * f22,
    )


@inline_jit
def _to_uv(v, squared):
    return v * v if squared else v


@ieee_jit
def arc_midpoint(ax, ay, bx, by, sx, sy, uv):
    """Return the point of the (U, V)-segment a → b whose x (or y, if that spans more) is halfway.

    ``uv``: the squared-coordinate flags (bit 0 x, bit 1 y). Any point of the segment keeps both
    halves (U, V)-segments; halving the larger coordinate span keeps the two pieces about equally
    long in (x, y).
    """
    xs = (uv & 1) != 0
    ys = (uv & 2) != 0
    if abs(bx - ax) >= abs(by - ay):
        xm = 0.5 * (ax + bx)
        den = _to_uv(bx, xs) - _to_uv(ax, xs)
        s = (_to_uv(xm, xs) - _to_uv(ax, xs)) / den if den != 0.0 else 0.5
        va, vb = _to_uv(ay, ys), _to_uv(by, ys)
        vm = va + s * (vb - va)
        return xm, (sy * math.sqrt(max(vm, 0.0)) if ys else vm)
    ym = 0.5 * (ay + by)
    den = _to_uv(by, ys) - _to_uv(ay, ys)
    s = (_to_uv(ym, ys) - _to_uv(ay, ys)) / den if den != 0.0 else 0.5
    ua, ub = _to_uv(ax, xs), _to_uv(bx, xs)
    um = ua + s * (ub - ua)
    return (sx * math.sqrt(max(um, 0.0)) if xs else um), ym


@inline_jit
def segment_point(ax, ay, bx, by, sx, sy, uv, s):
    """Return the point at parameter ``s`` ∈ [0, 1] of the (U, V)-segment a → b (straight if ``uv`` = 0)."""
    xs = (uv & 1) != 0
    ys = (uv & 2) != 0
    ua, ub = _to_uv(ax, xs), _to_uv(bx, xs)
    va, vb = _to_uv(ay, ys), _to_uv(by, ys)
    u = ua + s * (ub - ua)
    v = va + s * (vb - va)
    return (sx * math.sqrt(max(u, 0.0)) if xs else u), (sy * math.sqrt(max(v, 0.0)) if ys else v)


@inline_jit
def _segment_distance(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0.0 else min(max(((px - ax) * dx + (py - ay) * dy) / L2, 0.0), 1.0)
    ex, ey = px - ax - t * dx, py - ay - t * dy
    return math.sqrt(ex * ex + ey * ey)


@inline_jit
def _arc_deviation(x0, y0, x1, y1, sx, sy, xs, ys):
    """Return the largest distance of the (U, V)-segment's arc x0 y0 → x1 y1 from its chord.

    The arc P(s) = (x(U(s)), y(V(s))), U and V linear in s, is convex and turns by at most 90°
    within a quadrant, so it is a graph over its chord and its distance n·(P(s) − P(0)) from the
    chord is extremal where n·P'(s) = 0 — a closed form: with a = nₓ·dx/dU-part, b = n_y·(…),
    a²V = b²U (both coordinates squared) or √U = −a/(2 b) (one squared).
    """
    cx, cy = x1 - x0, y1 - y0
    c = math.sqrt(cx * cx + cy * cy)
    if c == 0.0:
        return 0.0
    nx, ny = -cy / c, cx / c
    u0 = x0 * x0 if xs else x0
    u1 = x1 * x1 if xs else x1
    v0 = y0 * y0 if ys else y0
    v1 = y1 * y1 if ys else y1
    du, dv = u1 - u0, v1 - v0
    s = -1.0
    if xs and ys:
        a = nx * sx * du
        b = ny * sy * dv
        den = a * a * dv - b * b * du
        if a * b < 0.0 and den != 0.0:
            s = (b * b * u0 - a * a * v0) / den
    elif xs:
        a = nx * sx * du
        b = ny * dv
        if a * b < 0.0:
            r = -a / (2.0 * b)
            s = (r * r - u0) / du
    elif ys:
        a = ny * sy * dv
        b = nx * du
        if a * b < 0.0:
            r = -a / (2.0 * b)
            s = (r * r - v0) / dv
    if not (0.0 < s < 1.0):
        return 0.0
    u = u0 + s * du
    v = v0 + s * dv
    px = sx * math.sqrt(max(u, 0.0)) if xs else u
    py = sy * math.sqrt(max(v, 0.0)) if ys else v
    return abs(nx * (px - x0) + ny * (py - y0))


@ieee_jit
def region_bulge(v0x, v0y, v1x, v1y, v2x, v2y, uv, sx, sy):
    """Return how far the region over the triangle v0 v1 v2 reaches beyond the straight triangle.

    ``uv``: the squared-coordinate flags of its (U, V)-sides in the quadrant of signs ``sx, sy``
    (0: the region is the triangle, bulge 0). The region differs from the straight triangle only by
    the lenses between each side's arc and its chord (a winding-number argument that holds even
    when strongly curved sides flip the straight triangle's orientation), and each lens is within
    the arc's largest distance from its chord (``_arc_deviation``, exact). The sampler works on the
    straight triangle with every radius shortened by this bound.
    """
    if uv == 0:
        return 0.0
    xs = (uv & 1) != 0
    ys = (uv & 2) != 0
    return max(_arc_deviation(v0x, v0y, v1x, v1y, sx, sy, xs, ys),
               max(_arc_deviation(v1x, v1y, v2x, v2y, sx, sy, xs, ys),
                   _arc_deviation(v2x, v2y, v0x, v0y, sx, sy, xs, ys)))


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


@ieee_jit
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


@ieee_jit
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
