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

Paraboloids and planes take the same path (``frames.region_lines``): a coordinate that enters
the heightfield linearly is used as it is (U = x instead of x²), the plane is not split at that
axis, and a conic line with one squared coordinate is a parabola (a *parabolic triangle*, whose
straight sides are axis-parallel). A flat graph (a single plane) is one rectangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_count, as_finite_array, as_instance, as_points, as_real
from csgnb.quadric.evaluate import normal
from csgnb.quadric.frames import (
    FORM_GRAPH,
    FORM_SHEETS,
    SamplingPlane,
    heightfield,
    region_lines,
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

#: The four kinds of basic region of Figure 8a, and the parabolic triangles of paraboloids.
REGION_KINDS = ("triangle", "rectangle", "elliptic-triangle", "hyperbolic-triangle", "parabolic-triangle")

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
    quadrant : (int, int) — signs of x and y in the region (+1 for a linear coordinate).
    case : str — the Figure 7 case of the (quadrant, octant) region it came from (``"parabolic"``,
        ``"graph"`` for paraboloids and planes).
    squared : (bool, bool) — whether x and y enter as U = x², V = y² (else U = x, V = y); the
        conic side is a segment in (U, V).

    The heightfield maps the region onto both sheets t = ±h(x, y) (a graph: its one sheet) with
    distortion ≤ √3.
    """

    plane: int
    kind: str
    vertices: np.ndarray
    conic: np.ndarray | None
    quadrant: tuple[int, int]
    case: str
    squared: tuple[bool, bool] = (True, True)

    def to_uv(self, xy: np.ndarray) -> np.ndarray:
        """Return (U, V) of plane points ``xy`` : (n, 2)."""
        xy = np.asarray(xy, dtype=np.float64)
        return np.column_stack([xy[:, k] ** 2 if self.squared[k] else xy[:, k] for k in range(2)])

    def from_uv(self, uv: np.ndarray) -> np.ndarray:
        """Return plane points (x, y) of (U, V) in this region's quadrant."""
        uv = np.asarray(uv, dtype=np.float64)
        return np.column_stack([self.quadrant[k] * np.sqrt(np.maximum(uv[:, k], 0.0)) if self.squared[k]
                                else uv[:, k] for k in range(2)])

    def boundary(self, samples_per_arc: int = 24) -> np.ndarray:
        """Return a closed polyline (m, 2) along the boundary (the arc sampled exactly)."""
        v = self.vertices
        if self.conic is None:
            return np.vstack([v, v[:1]])
        uv0, uv1 = self.to_uv(v[1:3])  # the conic arc is a straight segment in (U, V)
        s = np.linspace(0.0, 1.0, samples_per_arc)[:, None]
        arc = self.from_uv((1.0 - s) * uv0 + s * uv1)
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


def _apex_candidates(e0: np.ndarray, e1: np.ndarray, radial: bool):
    """Points A such that A–E₀ and A–E₁ are each axis-parallel or (if ``radial``) through 0."""
    def lines(p):  # (a, b, c) of the vertical, horizontal and radial line through p
        out = [(1.0, 0.0, -p[0]), (0.0, 1.0, -p[1])]
        return out + [(-p[1], p[0], 0.0)] if radial else out

    for l0 in lines(e0):
        for l1 in lines(e1):
            det = l0[0] * l1[1] - l0[1] * l1[0]
            if det != 0.0:
                yield np.array([(l0[1] * l1[2] - l1[1] * l0[2]) / det,
                                (l1[0] * l0[2] - l0[0] * l1[2]) / det])


# -- the Figure 7 cases ---------------------------------------------------------------------


def _octant_lines(alpha: np.ndarray, octant: str, form: int = FORM_SHEETS, linear=(0.0, 0.0)):
    """(wedge line, conic line) in (U, V), each (a, b, c) meaning a U + b V + c ≥ 0."""
    ax, ay, ac = (float(v) for v in alpha)
    w = region_lines(form, ax, float(linear[0]), ay, float(linear[1]), ac, 0 if octant == "x" else 1)
    return tuple(w[:3]), tuple(w[3:])


def octant_case(alpha, octant: str) -> str:
    """Return the Figure 7 case of the low-distortion region in one octant of a quadrant.

    ``octant`` is ``"x"`` (between the x axis and the line |αₓx| = |α_y y|) or ``"y"``.
    The nine non-degenerate cases are ``"full"`` and ``f"{conic}/{side}"`` with conic one of
    ``ellipse``, ``hyperbola-axis`` (meets the axis only), ``hyperbola-line`` (meets the
    octant line only), ``hyperbola-axis+line`` and side ``inside`` (the region contains the
    origin) or ``outside``. ``"empty"`` and ``"degenerate"`` (the conic is a line) complete it.
    """
    if not isinstance(octant, str) or octant not in ("x", "y"):
        raise CsgnbError(f"octant must be 'x' or 'y', got {octant!r:.40}")
    alpha = as_finite_array(alpha, (3,), "alpha")
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
    lo = as_finite_array(box_lo, (3,), "box_lo")
    hi = as_finite_array(box_hi, (3,), "box_hi")
    if np.any(lo >= hi):
        raise GeometryError(f"empty bounding box: box_lo {lo} must be below box_hi {hi}")
    corners = np.array([[hi[0] if k & 1 else lo[0], hi[1] if k & 2 else lo[1],
                         hi[2] if k & 4 else lo[2]] for k in range(8)])
    loc = to_plane_coordinates(plane, corners)
    return loc[:, 0].min(), loc[:, 0].max(), loc[:, 1].min(), loc[:, 1].max()


def _abs_range(lo: float, hi: float, sign: int, squared: bool = True):
    """Range of |x| over [lo, hi] ∩ {sign·x ≥ 0} (or of x itself if not ``squared``), or None."""
    if not squared:
        return (lo, hi) if hi > lo else None
    a, b = (lo, hi) if sign > 0 else (-hi, -lo)
    a = max(a, 0.0)
    return (a, b) if b > a else None


class _Builder:
    def __init__(self, plane: SamplingPlane, sx: int, sy: int, case: str, conic, eps: float,
                 squared: tuple[bool, bool]):
        self.plane, self.sx, self.sy, self.case = plane.axis, sx, sy, case
        self.conic_uv = np.array(conic, dtype=np.float64)
        self.squared = squared
        a, b, _ = conic
        if squared[0] and squared[1]:
            self.conic_kind = "elliptic-triangle" if a * b > 0.0 else "hyperbolic-triangle"
        else:
            self.conic_kind = "parabolic-triangle"
        self.eps = eps
        self.out: list[BasicRegion] = []

    def xy(self, uv: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv, dtype=np.float64)
        out = uv.copy()
        for k, sign in enumerate((self.sx, self.sy)):
            if self.squared[k]:
                out[..., k] = sign * np.sqrt(np.maximum(uv[..., k], 0.0))
        return out

    def emit(self, kind: str, vertices: np.ndarray, conic=None) -> None:
        self.out.append(BasicRegion(self.plane, kind, vertices, conic, (self.sx, self.sy),
                                    self.case, self.squared))

    def straight(self, poly_uv: np.ndarray) -> None:
        """Emit a convex polygon without conic edge as a rectangle or a fan of triangles."""
        if len(poly_uv) < 3 or abs(_area(poly_uv)) <= self.eps * self.eps:
            return
        pts = self.xy(poly_uv)
        same = tol.SAME_POINT * float(np.max(np.abs(pts)))
        keep = [0]
        for k in range(1, len(pts)):
            if np.max(np.abs(pts[k] - pts[keep[-1]])) > same:
                keep.append(k)
        if len(keep) > 1 and np.max(np.abs(pts[keep[-1]] - pts[0])) <= same:
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
        scale = float(np.max(np.abs(pts)))
        for k in range(1, len(pts) - 1):
            tri = pts[[0, k, k + 1]]
            if abs(_area(tri)) > 1e2 * tol.SAME_POINT * scale * scale:
                self.emit("triangle", tri)

    def curved(self, poly_uv: np.ndarray, tags: list[bool], depth: int = 0) -> None:
        """Cut the conic edge off as a curved triangle, then emit the straight rest."""
        if len(poly_uv) < 3 or abs(_area(poly_uv)) <= self.eps * self.eps:
            return
        if not any(tags):
            self.straight(poly_uv)
            return
        e = tags.index(True)
        e0, e1 = poly_uv[e], poly_uv[(e + 1) % len(poly_uv)]
        best, best_area = None, self.eps * self.eps
        radial = self.squared[0] and self.squared[1]  # lines through 0 are straight in (x, y) too
        for apex in _apex_candidates(e0, e1, radial):
            if not _inside(poly_uv, apex, self.eps):
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
            mid = 0.5 * (e0 + e1)  # bisect the conic edge by a straight line through it
            cut = (-mid[1], mid[0], 0.0) if radial else (1.0, 0.0, -mid[0])
            for side in (cut, tuple(-v for v in cut)):
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


def _straight_in_xy(line, squared: tuple[bool, bool]) -> bool:
    """Whether the (U, V)-line a U + b V + c = 0 is a straight line in (x, y)."""
    a, b, c = line
    if not squared[0] and not squared[1]:
        return True
    if (squared[0] and a == 0.0) or (squared[1] and b == 0.0):
        return True  # U or V constant: an axis-parallel line
    if squared[0] != squared[1]:
        return (a == 0.0) or (b == 0.0)
    return c == 0.0  # v/u constant: through the origin


def plane_regions(q: Quadric, plane: SamplingPlane, box_lo, box_hi) -> list[BasicRegion]:
    """Return the basic regions of one sampling plane, cut to a world box (see module doc)."""
    as_instance(q, Quadric, "q", "a csgnb.quadric.Quadric")
    as_instance(plane, SamplingPlane, "plane", "a SamplingPlane (from sampling_planes)")
    if plane.kind in ("none", "empty"):
        return []
    alpha = np.asarray(plane.alpha, dtype=np.float64)
    lin = np.asarray(plane.linear, dtype=np.float64)
    form = plane.form_code
    squared = (bool(alpha[0] != 0.0), bool(alpha[1] != 0.0))
    xlo, xhi, ylo, yhi = _local_box(plane, box_lo, box_hi)
    out: list[BasicRegion] = []
    w0, _ = _octant_lines(alpha, "x", form, lin)
    same_octants = w0 == (0.0, 0.0, 0.0)  # N_x ≡ N_y: both octants are the whole quadrant
    if form == FORM_SHEETS and not squared[0] and not squared[1] and np.all(lin == 0.0):
        case = "flat"
    elif form == FORM_GRAPH:
        case = "graph"
    elif np.any(lin != 0.0):
        case = "parabolic"
    else:
        case = None
    for sx in ((1, -1) if squared[0] else (1,)):
        xr = _abs_range(xlo, xhi, sx, squared[0])
        if xr is None:
            continue
        for sy in ((1, -1) if squared[1] else (1,)):
            yr = _abs_range(ylo, yhi, sy, squared[1])
            if yr is None:
                continue
            u0, u1 = (xr[0] ** 2, xr[1] ** 2) if squared[0] else xr
            v0, v1 = (yr[0] ** 2, yr[1] ** 2) if squared[1] else yr
            eps = tol.SAME_POINT * max(abs(u0), abs(u1), abs(v0), abs(v1))
            box = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
            for octant in ("x", "y"):
                if same_octants and octant == "y":
                    continue
                wedge, conic = _octant_lines(alpha, octant, form, lin)
                poly, tags = box, [False] * 4
                if not same_octants:
                    poly, tags = _clip(poly, tags, wedge, False)
                poly, tags = _clip(poly, tags, conic, not _straight_in_xy(conic, squared))
                builder = _Builder(plane, sx, sy, case or octant_case(alpha, octant), conic, eps, squared)
                builder.curved(poly, tags)
                out.extend(builder.out)
    return out


def low_distortion_regions(q: Quadric, box_lo, box_hi) -> list[BasicRegion]:
    """Return the basic regions of all three sampling planes of ``q`` inside a world box.

    Parameters
    ----------
    q : Quadric — any quadric (central ones, paraboloids, single planes).
    box_lo, box_hi : (3,) float64 — the axis-aligned world box; every surface point in it
        lies over exactly one basic region (up to shared boundaries) of the plane that
        sees it with the least distortion.

    Returns
    -------
    list of BasicRegion — each maps to the surface through its plane's heightfield
    (both sheets) with distortion δ ≤ √3.
    """
    if not isinstance(q, Quadric):
        raise TypeError(f"expected a csgnb.quadric.Quadric, got {type(q).__name__}")
    planes = sampling_planes(q)
    regions: list[BasicRegion] = []
    for p in planes:
        regions.extend(plane_regions(q, p, box_lo, box_hi))
    return regions


def region_contains(region: BasicRegion, xy, tol: float = 0.0) -> np.ndarray:
    """Return whether local points ``xy`` : (n, 2) lie in ``region`` : (n,) bool.

    ``tol`` widens the region by that much (in the units of each test) to absorb rounding.
    """
    as_instance(region, BasicRegion, "region", "a BasicRegion (from low_distortion_regions)")
    tol = as_real(tol, "tol")
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
    # curved: a triangle in (U, V) within the region's quadrant
    sx, sy = region.quadrant
    ok = np.ones(len(pts), dtype=bool)
    if region.squared[0]:
        ok &= sx * x >= -tol
    if region.squared[1]:
        ok &= sy * y >= -tol
    uv = region.to_uv(v)
    s = np.sign(_area(uv))
    u, w = region.to_uv(pts).T
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
    in (U, V) for curved triangles, where their conic side is straight — and lifted to the
    sheet ``t = sheet · h(x, y)`` (a graph has one sheet: ``sheet`` is ignored).

    Returns
    -------
    points : (m, 3) float64 — world coordinates.
    triangles : (k, 3) int64 — vertex indices.
    """
    as_instance(plane, SamplingPlane, "plane", "a SamplingPlane (from sampling_planes)")
    as_instance(region, BasicRegion, "region", "a BasicRegion (from low_distortion_regions)")
    sheet = as_real(sheet, "sheet")
    n = as_count(resolution, "resolution", 1)
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
        uv = region.to_uv(v)
        uv = uv[0] + w[:, :1] * (uv[1] - uv[0]) + w[:, 1:] * (uv[2] - uv[0])
        xy = region.from_uv(uv)
    h = np.nan_to_num(heightfield(plane, xy[:, 0], xy[:, 1]))  # rim rounding: h = 0
    local = np.column_stack([xy, (1.0 if plane.form == "graph" else sheet) * h])
    return plane.origin + local @ plane.frame.T, np.array(tris, dtype=np.int64)
