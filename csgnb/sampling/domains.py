"""The sampling domains of a quadric: its low-distortion regions as triangles in (u, v) = (x², y²).

§4.1 partitions each sampling plane, per quadrant and octant, into the region where that plane
sees the surface with distortion δ ≤ √3. In (u, v) = (x², y²) every boundary of such a region is
a straight line — the octant line, the conic of eq. 15/16 and the bounding box — so the region is
a convex polygon there (``csgnb.quadric.regions`` derives this and cuts the polygons into the
four basic-region kinds of Figure 8). The sampler takes the polygons as they are: each is
fan-triangulated *in (u, v)*, and a (u, v)-triangle is a basic region whose three sides are
images of (u, v)-segments — arcs of axis-aligned conics centered at the origin, or straight
lines when the segment is axis-parallel or points at the origin. That one kind covers all of
Figure 8's (a rectangle is two of them) and is closed under bisection at (u, v)-midpoints, which
is how the sampler splits it (:mod:`.geometry`).

Built by a numba kernel (Sutherland–Hodgman clipping of a box by two lines, per quadrant and
octant): microseconds per quadric, where the Python construction of ``quadric.regions`` takes
milliseconds. A plane (A = 0) gets its polygon inside the box, fan-triangulated in its own
(x, y) with straight sides. Results are cached per (quadric, box).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from csgnb._jit import jit
from csgnb.csg.bounds import frame_cache_clear
from csgnb.errors import GeometryError
from csgnb.quadric.heightfield import sampling_planes
from csgnb.quadric.quadric import Quadric

__all__ = ["quadric_jobs", "plane_polygon", "domain_cache_clear", "SLIVER", "is_plane"]

#: Triangles thinner than this fraction of the model size are dropped (see ``quadric_jobs``).
SLIVER = 1e-7


def is_plane(q: Quadric) -> bool:
    """Return whether ``q`` is a single plane (A = 0)."""
    return bool(np.max(np.abs(q.A)) <= 1e-14 * float(np.max(np.abs(q.matrix))))


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


@jit
def _octant_triangles_kernel(alpha, lo_x, hi_x, lo_y, hi_y, out_tri, out_quad):
    """Write the (u, v)-fan triangles of the low-distortion regions of one sampling plane.

    ``alpha`` (3,) — (αₓ, α_y, α_c); the box [lo_x, hi_x] × [lo_y, hi_y] in plane coordinates.
    Writes triangles as (x, y) vertices into ``out_tri`` (cap, 3, 2) and their quadrant signs
    into ``out_quad`` (cap, 2); returns the count (at most 48).
    """
    ax, ay, ac = alpha[0], alpha[1], alpha[2]
    both_zero = ax == 0.0 and ay == 0.0
    px = np.empty(16)
    py = np.empty(16)
    qx = np.empty(16)
    qy = np.empty(16)
    n = 0
    for qs in range(4):
        sx = 1.0 if qs & 1 == 0 else -1.0
        sy = 1.0 if qs & 2 == 0 else -1.0
        # range of |x| over [lo, hi] ∩ {sx·x ≥ 0}
        xa, xb = (lo_x, hi_x) if sx > 0 else (-hi_x, -lo_x)
        ya, yb = (lo_y, hi_y) if sy > 0 else (-hi_y, -lo_y)
        xa, ya = max(xa, 0.0), max(ya, 0.0)
        if xb <= xa or yb <= ya:
            continue
        u0, u1, v0, v1 = xa * xa, xb * xb, ya * ya, yb * yb
        tol = 1e-24 * max(max(u1, v1), 1.0) ** 2
        for octant in range(2):
            if both_zero and octant == 1:
                continue  # both octants are the whole quadrant
            px[0], py[0], px[1], py[1] = u0, v0, u1, v0
            px[2], py[2], px[3], py[3] = u1, v1, u0, v1
            m = 4
            if octant == 0:  # |n_x| ≥ |n_y| side; eq. 15
                wa, wb, wc = ax * ax, -ay * ay, 0.0
                ca, cb, cc = ax - ax * ax, ay, ac
            else:  # eq. 16
                wa, wb, wc = -ax * ax, ay * ay, 0.0
                ca, cb, cc = ax, ay - ay * ay, ac
            if not both_zero:
                m = _clip_uv(px, py, m, wa, wb, wc, qx, qy)
                px[:m] = qx[:m]
                py[:m] = qy[:m]
            m = _clip_uv(px, py, m, ca, cb, cc, qx, qy)
            if m < 3:
                continue
            area = 0.0
            for e in range(m):
                f = (e + 1) % m
                area += qx[e] * qy[f] - qx[f] * qy[e]
            if abs(area) <= tol:
                continue
            for t in range(1, m - 1):
                for c in range(3):
                    w = 0 if c == 0 else t + c - 1
                    out_tri[n, c, 0] = sx * math.sqrt(max(qx[w], 0.0))
                    out_tri[n, c, 1] = sy * math.sqrt(max(qy[w], 0.0))
                out_quad[n, 0] = sx
                out_quad[n, 1] = sy
                n += 1
    return n


_BOX_EDGES = [(a, a | (1 << k)) for k in range(3) for a in range(8) if not a & (1 << k)]


def _corners(box: np.ndarray) -> np.ndarray:
    lo, hi = box[:3], box[3:]
    return np.array([[hi[k] if m >> k & 1 else lo[k] for k in range(3)] for m in range(8)])


def plane_polygon(normal: np.ndarray, offset: float, box: np.ndarray) -> np.ndarray:
    """Return the convex polygon ``{n·x = offset} ∩ box`` as (k, 3) vertices in order (k may be 0)."""
    corners = _corners(box)
    s = corners @ normal - offset
    pts = [corners[m] for m in range(8) if s[m] == 0.0]
    for a, b in _BOX_EDGES:
        if s[a] * s[b] < 0.0:
            t = s[a] / (s[a] - s[b])
            pts.append(corners[a] + t * (corners[b] - corners[a]))
    if len(pts) < 3:
        return np.empty((0, 3))
    P = np.array(pts)
    c = P.mean(axis=0)
    ex, ey = _tangents(normal)
    ang = np.arctan2((P - c) @ ey, (P - c) @ ex)
    P = P[np.argsort(ang)]
    keep = [0]
    tol = 1e-12 * (1.0 + float(np.max(np.abs(P))))
    for k in range(1, len(P)):
        if np.max(np.abs(P[k] - P[keep[-1]])) > tol:
            keep.append(k)
    if len(keep) > 1 and np.max(np.abs(P[keep[-1]] - P[0])) <= tol:
        keep.pop()
    return P[keep] if len(keep) >= 3 else np.empty((0, 3))


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = np.cross(helper, n)
    ex /= np.linalg.norm(ex)
    return ex, np.cross(n, ex)


@functools.lru_cache(maxsize=4096)
def _cached_jobs(matrix_bytes: bytes, box_bytes: bytes):
    q = Quadric(np.frombuffer(matrix_bytes).reshape(4, 4))
    box = np.frombuffer(box_bytes)
    origin = np.zeros((3, 3))
    frame = np.zeros((3, 3, 3))
    alpha = np.zeros((3, 3))
    flat = np.zeros(3, dtype=bool)
    tri_parts, plane_parts, uv_parts, quad_parts = [], [], [], []
    if is_plane(q):
        b = q.b
        nb = float(np.linalg.norm(b))
        n = -b / nb  # ∇Q = -2b points outwards
        offset = -q.c / (2.0 * nb)
        ex, ey = _tangents(n)
        origin[0], frame[0], flat[0] = n * offset, np.column_stack([ex, ey, n]), True
        poly = plane_polygon(n, offset, box)
        if len(poly):
            xy = (poly - origin[0]) @ frame[0][:, :2]
            fan = np.array([[xy[0], xy[k], xy[k + 1]] for k in range(1, len(xy) - 1)])
            tri_parts.append(fan)
            plane_parts.append(np.zeros(len(fan), dtype=np.int64))
            uv_parts.append(np.zeros(len(fan), dtype=np.int64))
            quad_parts.append(np.ones((len(fan), 2)))
    else:
        planes = sampling_planes(q)
        if all(p.kind == "none" for p in planes):
            raise GeometryError(
                "the sampler handles planes and central quadrics; paraboloids have no eq. 7 heightfields "
                "(replace them by an ellipsoid or a cylinder clipped to the region of interest)"
            )
        corners = _corners(box)
        tri = np.empty((48, 3, 2))
        quad = np.empty((48, 2))
        for p in planes:
            origin[p.axis] = p.origin
            frame[p.axis] = p.frame
            alpha[p.axis] = np.nan_to_num(p.alpha)
            flat[p.axis] = p.kind == "parallel-planes"
            if p.kind in ("none", "empty"):
                continue
            loc = (corners - p.origin) @ p.frame
            k = _octant_triangles_kernel(np.ascontiguousarray(p.alpha), loc[:, 0].min(), loc[:, 0].max(),
                                         loc[:, 1].min(), loc[:, 1].max(), tri, quad)
            tri_parts.append(tri[:k].copy())
            plane_parts.append(np.full(k, p.axis, dtype=np.int64))
            uv_parts.append(np.ones(k, dtype=np.int64))
            quad_parts.append(quad[:k].copy())
    tris = np.concatenate(tri_parts) if tri_parts else np.empty((0, 3, 2))
    plane_k = np.concatenate(plane_parts) if plane_parts else np.empty(0, dtype=np.int64)
    uv = np.concatenate(uv_parts) if uv_parts else np.empty(0, dtype=np.int64)
    quads = np.concatenate(quad_parts) if quad_parts else np.empty((0, 2))
    # Clipping to a box whose face is within rounding of a plane's axis leaves slivers (e.g.
    # 1e-8 thick) outside the object; proving them empty takes length/width subdivisions. The
    # surface over them is within their width of a neighbouring triangle's: drop them.
    e = np.roll(tris, -1, axis=1) - tris
    longest = np.max(np.linalg.norm(e, axis=2), axis=1, initial=0.0)
    area2 = np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    keep = area2 > SLIVER * (1.0 + float(np.max(np.abs(box)))) * longest
    # every triangle is sampled on both sheets t = ±h (a plane has one)
    sheets = np.where(flat[plane_k] & (alpha[plane_k, 2] == 0.0), 1, 2)[keep]
    reps = np.repeat(np.flatnonzero(keep), sheets)
    sheet = np.ones(len(reps))
    sheet[np.cumsum(sheets) - 1] = np.where(sheets == 2, -1.0, 1.0)
    out = (origin, frame, alpha, flat, plane_k[reps], sheet, tris[reps], uv[reps], quads[reps])
    for a in out:
        a.setflags(write=False)
    return out


def quadric_jobs(q: Quadric, box: np.ndarray):
    """Return the sampling jobs of ``q`` inside ``box`` : (6,) (lo, hi), cached.

    Returns ``(origin (3, 3), frame (3, 3, 3), alpha (3, 3), flat (3,) bool, plane (J,) int64,
    sheet (J,) ±1.0, triangle (J, 3, 2) plane coordinates, uv (J,) int64, quadrant (J, 2))``:
    per sampling plane k its origin, axes (x, y, normal as columns), α and whether δ ≡ 1; per job
    a triangle on plane ``plane[j]``, lifted to the sheet ``t = sheet[j]·h``, whose sides are
    (u, v)-segments in the quadrant ``quadrant[j]`` if ``uv[j]`` else straight. Raises
    :class:`GeometryError` for paraboloids.
    """
    return _cached_jobs(np.ascontiguousarray(q.matrix).tobytes(), np.ascontiguousarray(box, dtype=np.float64).tobytes())


def domain_cache_clear() -> None:
    """Empty the caches of jobs per (quadric, box) and of principal frames (``csg.bounds``)."""
    _cached_jobs.cache_clear()
    frame_cache_clear()
