"""Low-distortion regions of the sampling planes and their basic regions (paper §4.1, Fig. 7–8).

On a sampling plane the heightfield normal is n = (-αₓx, -α_y y, h). The plane owns the
surface where |n_t| is the largest component, so the map to the surface stretches by at
most √3. In a quadrant, with u = x² and v = y², every boundary of that region is a *line*:

* the octant line |αₓx| = |α_y y|            → αₓ²u - α_y²v = 0      (a line through 0),
* eq. 15, |n_t| = |n_x| in the x-octant       → (αₓ - αₓ²)u + α_y v + α_c = 0,
* eq. 16, |n_t| = |n_y| in the y-octant       → αₓu + (α_y - α_y²)v + α_c = 0,
* the bounding box                             → u, v between squared bounds.

So each (quadrant, octant) region is a convex polygon in (u, v) with at most one edge on the
conic line. Lines through the origin and axis-parallel lines are straight in (x, y) too; the
conic line maps to an axis-aligned ellipse or hyperbola centered at the origin. We cut the
conic edge off as a triangle whose two other sides are axis-parallel or pass through the
origin (an *elliptic* or *hyperbolic triangle*), and split the remaining straight convex
pieces into axis-aligned rectangles and triangles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.errors import GeometryError
from csgnb.quadric.evaluate import as_points, normal
from csgnb.quadric.heightfield import (
    SamplingPlane,
    heightfield,
    sampling_planes,
    to_plane_coordinates,
)
from csgnb.quadric.quadric import Quadric

__all__ = [
    "BasicRegion",
    "REGION_KINDS",
    "low_distortion_regions",
    "plane_regions",
    "octant_case",
    "region_contains",
    "owning_plane",
    "region_mesh",
]

#: The four kinds of basic region of Figure 8a.
REGION_KINDS = ("triangle", "rectangle", "elliptic-triangle", "hyperbolic-triangle")

_SPLIT_DEPTH = 12  # bisections of a conic edge before giving up (never reached in tests)


@dataclass(frozen=True)
class BasicRegion:
    """A basic region of a sampling plane, in that plane's local (x, y) coordinates.

    plane : int — index k of the sampling plane (its normal is the principal axis uₖ).
    kind : str — one of :data:`REGION_KINDS`.
    vertices : (m, 2) float64 — rectangle: 4 corners counter-clockwise from (x_lo, y_lo);
        triangle: 3 corners; elliptic/hyperbolic triangle: (A, E₀, E₁) where the side
        E₀ → E₁ is the conic arc and A–E₀, A–E₁ are straight (axis-parallel or through 0).
    conic : (3,) float64 or None — (a, b, c): the region lies where a x² + b y² + c ≥ 0.
    quadrant : (int, int) — signs of x and y in the region.
    case : str — the Figure 7 case of the (quadrant, octant) region it came from.

    The heightfield maps the region onto both sheets t = ±h(x, y) with distortion ≤ √3.
    """

    plane: int
    kind: str
    vertices: np.ndarray
    conic: np.ndarray | None
    quadrant: tuple[int, int]
    case: str

    def boundary(self, samples_per_arc: int = 24) -> np.ndarray:
        """Return a closed polyline (m, 2) along the boundary (the arc sampled exactly)."""
        v = self.vertices
        if self.conic is None:
            return np.vstack([v, v[:1]])
        sx, sy = self.quadrant
        uv0, uv1 = v[1] ** 2, v[2] ** 2  # the conic arc is a straight segment in (u, v)
        s = np.linspace(0.0, 1.0, samples_per_arc)[:, None]
        uv = (1.0 - s) * uv0 + s * uv1
        arc = np.sqrt(uv) * np.array([sx, sy])
        return np.vstack([v[:1], arc, v[:1]])


# -- convex polygons in (u, v) --------------------------------------------------------------


def _clip(poly: np.ndarray, tags: list[bool], line, conic_edge: bool):
    """Clip a convex polygon (CCW, (m, 2)) to a·u + b·v + c ≥ 0.

    ``tags[e]`` says whether edge e (vertex e → e+1) lies on the conic line; the new edge
    along the clip line gets ``conic_edge``. Returns (poly, tags), empty when nothing is left.
    """
    a, b, c = line
    m = len(poly)
    if m == 0:
        return poly, tags
    f = a * poly[:, 0] + b * poly[:, 1] + c
    out: list[np.ndarray] = []
    out_tags: list[bool] = []
    for e in range(m):
        n = (e + 1) % m
        fp, fq = f[e], f[n]
        if fp >= 0.0:
            out.append(poly[e])
            out_tags.append(tags[e])
            if fq < 0.0:
                if fp == 0.0:
                    out_tags[-1] = conic_edge
                else:
                    s = fp / (fp - fq)
                    out.append(poly[e] + s * (poly[n] - poly[e]))
                    out_tags.append(conic_edge)
        elif fq > 0.0:
            s = fp / (fp - fq)
            out.append(poly[e] + s * (poly[n] - poly[e]))
            out_tags.append(tags[e])
    if len(out) < 3:
        return np.empty((0, 2)), []
    return np.array(out), out_tags


def _area(poly: np.ndarray) -> float:
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _line_through(p: np.ndarray, q: np.ndarray):
    """(a, b, c) of the line through p and q, positive on the left of p → q."""
    d = q - p
    return (-d[1], d[0], d[1] * p[0] - d[0] * p[1])


def _inside(poly: np.ndarray, point: np.ndarray, tol: float) -> bool:
    for e in range(len(poly)):
        a, b, c = _line_through(poly[e], poly[(e + 1) % len(poly)])
        norm = np.hypot(a, b)
        if norm > 0.0 and (a * point[0] + b * point[1] + c) / norm < -tol:
            return False
    return True


def _apex_candidates(e0: np.ndarray, e1: np.ndarray):
    """Points A such that A–E₀ and A–E₁ are each axis-parallel or through the origin."""
    def lines(p):  # (a, b, c) of the vertical, horizontal and radial line through p
        return [(1.0, 0.0, -p[0]), (0.0, 1.0, -p[1]), (-p[1], p[0], 0.0)]

    for l0 in lines(e0):
        for l1 in lines(e1):
            det = l0[0] * l1[1] - l0[1] * l1[0]
            if det != 0.0:
                yield np.array([(l0[1] * l1[2] - l1[1] * l0[2]) / det,
                                (l1[0] * l0[2] - l0[0] * l1[2]) / det])


# -- the Figure 7 cases ---------------------------------------------------------------------


def _octant_lines(alpha: np.ndarray, octant: str):
    """(wedge line, conic line) in (u, v), each (a, b, c) meaning a u + b v + c ≥ 0."""
    ax, ay, ac = alpha
    if octant == "x":
        return (ax * ax, -ay * ay, 0.0), (ax - ax * ax, ay, ac)
    return (-ax * ax, ay * ay, 0.0), (ax, ay - ay * ay, ac)


def octant_case(alpha, octant: str) -> str:
    """Return the Figure 7 case of the low-distortion region in one octant of a quadrant.

    ``octant`` is ``"x"`` (between the x axis and the line |αₓx| = |α_y y|) or ``"y"``.
    The nine non-degenerate cases are ``"full"`` and ``f"{conic}/{side}"`` with conic one of
    ``ellipse``, ``hyperbola-axis`` (meets the axis only), ``hyperbola-line`` (meets the
    octant line only), ``hyperbola-axis+line`` and side ``inside`` (the region contains the
    origin) or ``outside``. ``"empty"`` and ``"degenerate"`` (the conic is a line) complete it.
    """
    if octant not in ("x", "y"):
        raise ValueError(f"octant must be 'x' or 'y', got {octant!r}")
    alpha = np.asarray(alpha, dtype=np.float64)
    a, b, c = _octant_lines(alpha, octant)[1]
    ax2, ay2 = alpha[0] ** 2, alpha[1] ** 2
    axis_dir = np.array([1.0, 0.0]) if octant == "x" else np.array([0.0, 1.0])
    line_dir = np.array([ay2, ax2])
    if a == 0.0 or b == 0.0 or c == 0.0 or not np.any(line_dir):
        return "degenerate"

    def crosses(d):
        den = a * d[0] + b * d[1]
        return den != 0.0 and -c / den > 0.0

    side = "inside" if c > 0.0 else "outside"
    if a * b > 0.0:
        if (a > 0.0) == (c > 0.0):
            return "full" if c > 0.0 else "empty"
        return f"ellipse/{side}"
    hit_axis, hit_line = crosses(axis_dir), crosses(line_dir)
    if not (hit_axis or hit_line):
        return "full" if c > 0.0 else "empty"
    where = "axis+line" if hit_axis and hit_line else ("axis" if hit_axis else "line")
    return f"hyperbola-{where}/{side}"


# -- decomposition ----------------------------------------------------------------------------


def _local_box(plane: SamplingPlane, box_lo, box_hi):
    lo = np.asarray(box_lo, dtype=np.float64)
    hi = np.asarray(box_hi, dtype=np.float64)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo) & np.isfinite(hi)):
        raise ValueError("box_lo and box_hi must be finite (3,) points")
    if np.any(lo >= hi):
        raise ValueError(f"empty bounding box: box_lo {lo} must be below box_hi {hi}")
    corners = np.array([[hi[0] if k & 1 else lo[0], hi[1] if k & 2 else lo[1],
                         hi[2] if k & 4 else lo[2]] for k in range(8)])
    loc = to_plane_coordinates(plane, corners)
    return loc[:, 0].min(), loc[:, 0].max(), loc[:, 1].min(), loc[:, 1].max()


def _abs_range(lo: float, hi: float, sign: int):
    """Range of |x| over [lo, hi] ∩ {sign·x ≥ 0}, or None."""
    a, b = (lo, hi) if sign > 0 else (-hi, -lo)
    a = max(a, 0.0)
    return (a, b) if b > a else None


class _Builder:
    def __init__(self, plane: SamplingPlane, sx: int, sy: int, case: str, conic, tol: float):
        self.plane, self.sx, self.sy, self.case = plane.axis, sx, sy, case
        self.conic_uv = np.array(conic, dtype=np.float64)
        a, b, _ = conic
        self.conic_kind = "elliptic-triangle" if a * b > 0.0 else "hyperbolic-triangle"
        self.tol = tol
        self.out: list[BasicRegion] = []

    def xy(self, uv: np.ndarray) -> np.ndarray:
        return np.sqrt(np.maximum(uv, 0.0)) * np.array([self.sx, self.sy], dtype=np.float64)

    def emit(self, kind: str, vertices: np.ndarray, conic=None) -> None:
        self.out.append(BasicRegion(self.plane, kind, vertices, conic, (self.sx, self.sy),
                                    self.case))

    def straight(self, poly_uv: np.ndarray) -> None:
        """Emit a convex polygon without conic edge as a rectangle or a fan of triangles."""
        if len(poly_uv) < 3 or abs(_area(poly_uv)) <= self.tol * self.tol:
            return
        pts = self.xy(poly_uv)
        keep = [0]
        for k in range(1, len(pts)):
            if np.max(np.abs(pts[k] - pts[keep[-1]])) > 1e-12 * (1.0 + np.max(np.abs(pts))):
                keep.append(k)
        if len(keep) > 1 and np.max(np.abs(pts[keep[-1]] - pts[0])) <= 1e-12 * (
            1.0 + np.max(np.abs(pts))
        ):
            keep.pop()
        pts = pts[keep]
        if len(pts) < 3:
            return
        if len(pts) == 4:
            xs, ys = np.unique(pts[:, 0]), np.unique(pts[:, 1])
            if len(xs) == 2 and len(ys) == 2:
                self.emit("rectangle", np.array([[xs[0], ys[0]], [xs[1], ys[0]],
                                                 [xs[1], ys[1]], [xs[0], ys[1]]]))
                return
        scale = 1.0 + float(np.max(np.abs(pts)))
        for k in range(1, len(pts) - 1):
            tri = pts[[0, k, k + 1]]
            if abs(_area(tri)) > 1e-14 * scale * scale:
                self.emit("triangle", tri)

    def curved(self, poly_uv: np.ndarray, tags: list[bool], depth: int = 0) -> None:
        """Cut the conic edge off as a curved triangle, then emit the straight rest."""
        if len(poly_uv) < 3 or abs(_area(poly_uv)) <= self.tol * self.tol:
            return
        if not any(tags):
            self.straight(poly_uv)
            return
        e = tags.index(True)
        e0, e1 = poly_uv[e], poly_uv[(e + 1) % len(poly_uv)]
        best, best_area = None, self.tol * self.tol
        for apex in _apex_candidates(e0, e1):
            if not _inside(poly_uv, apex, self.tol):
                continue
            area = abs(_area(np.array([apex, e0, e1])))
            if area > best_area:
                best, best_area = apex, area
        if best is None:
            if depth >= _SPLIT_DEPTH:
                raise GeometryError(
                    "could not split a low-distortion region into basic regions; "
                    "please report the quadric and bounding box"
                )
            mid = 0.5 * (e0 + e1)  # bisect the conic edge by the radial line through it
            radial = (-mid[1], mid[0], 0.0)
            for side in (radial, tuple(-v for v in radial)):
                part, part_tags = _clip(poly_uv, tags, side, False)
                self.curved(part, part_tags, depth + 1)
            return
        apex = best
        self.emit(self.conic_kind, self.xy(np.array([apex, e0, e1])), self.conic_uv)
        l0 = _line_through(apex, e0)  # E₁ is on its left or right; keep the far side
        s0 = np.sign(l0[0] * e1[0] + l0[1] * e1[1] + l0[2])
        l0_keep_e1 = tuple(s0 * v for v in l0)
        l0_away = tuple(-s0 * v for v in l0)
        l1 = _line_through(apex, e1)
        s1 = np.sign(l1[0] * e0[0] + l1[1] * e0[1] + l1[2])
        l1_away = tuple(-s1 * v for v in l1)
        rest0, _ = _clip(poly_uv, tags, l0_away, False)
        self.straight(rest0)
        rest1, _ = _clip(poly_uv, tags, l0_keep_e1, False)
        rest1, _ = _clip(rest1, [False] * len(rest1), l1_away, False)
        self.straight(rest1)


def plane_regions(q: Quadric, plane: SamplingPlane, box_lo, box_hi) -> list[BasicRegion]:
    """Return the basic regions of one sampling plane, cut to a world box (see module doc)."""
    if plane.kind in ("none", "empty"):
        return []
    alpha = np.asarray(plane.alpha, dtype=np.float64)
    xlo, xhi, ylo, yhi = _local_box(plane, box_lo, box_hi)
    out: list[BasicRegion] = []
    both_zero = alpha[0] == 0.0 and alpha[1] == 0.0
    for sx in (1, -1):
        xr = _abs_range(xlo, xhi, sx)
        if xr is None:
            continue
        for sy in (1, -1):
            yr = _abs_range(ylo, yhi, sy)
            if yr is None:
                continue
            u0, u1, v0, v1 = xr[0] ** 2, xr[1] ** 2, yr[0] ** 2, yr[1] ** 2
            tol = 1e-12 * max(u1, v1, 1.0)
            box = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
            for octant in ("x", "y"):
                if both_zero and octant == "y":
                    continue  # both octants are the whole quadrant: keep one
                wedge, conic = _octant_lines(alpha, octant)
                poly, tags = box, [False] * 4
                if not both_zero:
                    poly, tags = _clip(poly, tags, wedge, False)
                a, b, c = conic
                straight_conic = a == 0.0 or b == 0.0 or c == 0.0
                poly, tags = _clip(poly, tags, conic, not straight_conic)
                builder = _Builder(plane, sx, sy, octant_case(alpha, octant), conic, tol)
                builder.curved(poly, tags)
                out.extend(builder.out)
    return out


def low_distortion_regions(q: Quadric, box_lo, box_hi) -> list[BasicRegion]:
    """Return the basic regions of all three sampling planes of ``q`` inside a world box.

    Parameters
    ----------
    q : Quadric — a central quadric (paraboloids and single planes raise GeometryError).
    box_lo, box_hi : (3,) float64 — the axis-aligned world box; every surface point in it
        lies over exactly one basic region (up to shared boundaries) of the plane that
        sees it with the least distortion.

    Returns
    -------
    list of BasicRegion — each maps to the surface through its plane's heightfield
    (both sheets) with distortion δ ≤ √3.
    """
    planes = sampling_planes(q)
    if all(p.kind == "none" for p in planes):
        raise GeometryError(
            "low-distortion regions need a central quadric (A q = b solvable): paraboloids "
            "and single planes have no eq. 7 heightfields; this is not implemented"
        )
    regions: list[BasicRegion] = []
    for p in planes:
        regions.extend(plane_regions(q, p, box_lo, box_hi))
    return regions


def region_contains(region: BasicRegion, xy, tol: float = 0.0) -> np.ndarray:
    """Return whether local points ``xy`` : (n, 2) lie in ``region`` : (n,) bool.

    ``tol`` widens the region by that much (in the units of each test) to absorb rounding.
    """
    pts = as_points(xy, "xy", dim=2)
    v = region.vertices
    x, y = pts[:, 0], pts[:, 1]
    if region.kind == "rectangle":
        return (x >= v[0, 0] - tol) & (x <= v[2, 0] + tol) & (y >= v[0, 1] - tol) & (
            y <= v[2, 1] + tol
        )
    if region.kind == "triangle":
        s = np.sign(_area(v))
        ok = np.ones(len(pts), dtype=bool)
        for e in range(3):
            a, b, c = _line_through(v[e], v[(e + 1) % 3])
            ok &= s * (a * x + b * y + c) >= -tol * np.hypot(a, b)
        return ok
    # curved: a triangle in (u, v) within the region's quadrant
    sx, sy = region.quadrant
    ok = (sx * x >= -tol) & (sy * y >= -tol)
    uv = v**2
    s = np.sign(_area(uv))
    u, w = x * x, y * y
    for e in range(3):
        a, b, c = _line_through(uv[e], uv[(e + 1) % 3])
        ok &= s * (a * u + b * w + c) >= -tol * np.hypot(a, b)
    return ok


def owning_plane(q: Quadric, points) -> np.ndarray:
    """Return the index k of the sampling plane with the least distortion at ``points``.

    That is argmaxₖ |uₖ · N(p)| (§4.1): the plane whose normal is closest to the surface
    normal. ``points`` : (n, 3) on (or near) the surface; returns (n,) int64.
    """
    planes = sampling_planes(q)
    frame = np.column_stack([p.normal for p in planes])
    n = normal(q, points)
    return np.argmax(np.abs(n @ frame), axis=1)


def region_mesh(
    plane: SamplingPlane, region: BasicRegion, resolution: int = 8, sheet: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Return a triangle mesh of the surface patch over ``region`` (for drawing).

    The region is sampled on a barycentric grid — in (x, y) for triangles and rectangles,
    in (u, v) = (x², y²) for elliptic/hyperbolic triangles, where their conic side is
    straight — and lifted to the sheet ``t = sheet · h(x, y)``.

    Returns
    -------
    points : (m, 3) float64 — world coordinates.
    triangles : (k, 3) int64 — vertex indices.
    """
    n = int(resolution)
    if n < 1:
        raise ValueError(f"resolution must be ≥ 1, got {resolution}")
    v = region.vertices
    ij = [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]
    index = {p: k for k, p in enumerate(ij)}
    w = np.array([(i / n, j / n) for i, j in ij])
    tris = []
    for i in range(n):
        for j in range(n - i):
            tris.append((index[i, j], index[i + 1, j], index[i, j + 1]))
            if j < n - i - 1:
                tris.append((index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]))
    if region.kind == "rectangle":
        gx, gy = np.meshgrid(np.linspace(v[0, 0], v[2, 0], n + 1),
                             np.linspace(v[0, 1], v[2, 1], n + 1), indexing="ij")
        xy = np.column_stack([gx.ravel(), gy.ravel()])
        k = lambda a, b: a * (n + 1) + b  # noqa: E731
        tris = [t for a in range(n) for b in range(n)
                for t in ((k(a, b), k(a + 1, b), k(a + 1, b + 1)),
                          (k(a, b), k(a + 1, b + 1), k(a, b + 1)))]
    elif region.kind == "triangle":
        xy = v[0] + w[:, :1] * (v[1] - v[0]) + w[:, 1:] * (v[2] - v[0])
    else:
        uv = v**2
        uv = uv[0] + w[:, :1] * (uv[1] - uv[0]) + w[:, 1:] * (uv[2] - uv[0])
        xy = np.sqrt(np.maximum(uv, 0.0)) * np.array(region.quadrant, dtype=np.float64)
    h = np.nan_to_num(heightfield(plane.alpha, xy[:, 0], xy[:, 1]))  # rim rounding: h = 0
    local = np.column_stack([xy, sheet * h])
    return plane.origin + local @ plane.frame.T, np.array(tris, dtype=np.int64)
