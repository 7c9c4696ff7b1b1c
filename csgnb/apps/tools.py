"""Cutting tools and sweep shapes as closed triangle meshes, in millimetres, placed on a workpiece grid.

Every tool is built in its own frame: the tip at the origin, the spindle axis along +z,
the shank upwards. A :class:`ToolShape` is the float design (model units, mm);
:meth:`ToolShape.on` quantizes it onto a :class:`csgnb.exact.Grid` once, as integer offsets
from the tip, and validates the result with :func:`csgnb.bsp.build.validate_mesh`
(closed, outward, not self-intersecting). Moving a tool by a grid translation is then
exact; only rotated poses are quantized again.

Convex tools -- :func:`flat_end_mill`, :func:`ball_end_mill`, :func:`bull_nose`,
:func:`v_bit` and :func:`drill_envelope` (the body a spinning drill sweeps) -- are bodies
of revolution with a concave, non-decreasing radius profile. For them the solid used by
sweeps is the exact convex hull of the grid vertices (rounding can dent a quantized
convex polygon by up to half a grid step; the hull never is). :func:`twist_drill`
(two flutes, helical, 118° point: the drill of the paper's Figure 13) and
:func:`spur_gear` (Figure 12) are not convex: they sweep as per-triangle prisms
(:mod:`csgnb.apps.sweep`). :func:`mesh_tool` takes any closed mesh; whether it is convex
is decided exactly on the grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from functools import cached_property

import numpy as np

from csgnb.bsp.build import validate_mesh
from csgnb.errors import GeometryError
from csgnb.exact.quantization import Grid
from csgnb.mesh.hull import ConvexHull, convex_hull

__all__ = [
    "GridTool",
    "SpinSymmetry",
    "ToolShape",
    "ball_end_mill",
    "bull_nose",
    "drill_envelope",
    "flat_end_mill",
    "mesh_tool",
    "parse_tool",
    "spur_gear",
    "twist_drill",
    "v_bit",
]


def _positive(name: str, value) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive number of millimetres, got {value!r}")
    return v


def _count(name: str, value, minimum: int) -> int:
    if int(value) != value or int(value) < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _lathe(rings: list[np.ndarray], bottom, top) -> tuple[np.ndarray, np.ndarray]:
    """Close rings of vertices (each (M, 3), counter-clockwise seen from +z, bottom to top) with two poles.

    Bands are split along the shorter diagonal of each quad; faces are outward (bands face
    away from the axis, the bottom fan down, the top fan up).
    """
    M = rings[0].shape[0]
    V = np.vstack([np.asarray(bottom, float)[None, :], *rings, np.asarray(top, float)[None, :]])
    top_index = V.shape[0] - 1
    j = np.arange(M)
    jn = (j + 1) % M
    faces = [np.column_stack([np.zeros(M, int), 1 + jn, 1 + j])]  # bottom fan
    for k in range(len(rings) - 1):
        a, b = 1 + k * M + j, 1 + k * M + jn  # ring k
        c, d = a + M, b + M  # ring k + 1 (c above a, d above b)
        short = np.linalg.norm(V[b] - V[c], axis=1) <= np.linalg.norm(V[a] - V[d], axis=1)
        faces.append(np.where(short[:, None], np.column_stack([a, b, c]), np.column_stack([a, b, d])))
        faces.append(np.where(short[:, None], np.column_stack([b, d, c]), np.column_stack([a, d, c])))
    last = 1 + (len(rings) - 1) * M
    faces.append(np.column_stack([np.full(M, top_index), last + j, last + jn]))  # top fan
    return V, np.concatenate(faces).astype(np.int64)


def _revolve(profile: list[tuple[float, float]], segments: int) -> tuple[np.ndarray, np.ndarray]:
    """A body of revolution from an (r, z) profile that starts and ends on the axis (r = 0)."""
    if profile[0][0] != 0 or profile[-1][0] != 0 or any(r <= 0 for r, _ in profile[1:-1]):
        raise GeometryError("a revolution profile must start and end on the axis with r > 0 in between")
    phi = 2 * np.pi * np.arange(segments) / segments
    rings = [np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(segments, z)]) for r, z in profile[1:-1]]
    return _lathe(rings, (0, 0, profile[0][1]), (0, 0, profile[-1][1]))


@dataclass(frozen=True, eq=False)
class ToolShape:
    """A tool (or swept shape) designed in millimetres: tip at the origin, axis +z.

    Attributes
    ----------
    name : str
    vertices : (n, 3) float64
        Model units (mm).
    faces : (m, 3) int64
        Outward triangles.
    convex : bool or None
        Whether the design is convex (None: decide exactly on the grid, :func:`mesh_tool`).
    params : dict
        The parameters it was built from (mm, degrees, counts).
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    convex: bool | None
    params: dict = field(default_factory=dict)

    @property
    def n_triangles(self) -> int:
        """Number of triangles."""
        return int(self.faces.shape[0])

    @property
    def radius(self) -> float:
        """Largest distance of a vertex from the axis (mm)."""
        return float(np.max(np.linalg.norm(self.vertices[:, :2], axis=1)))

    @property
    def length(self) -> float:
        """Height above the tip (mm)."""
        return float(self.vertices[:, 2].max() - self.vertices[:, 2].min())

    def on(self, grid: Grid) -> GridTool:
        """Quantize onto ``grid`` (offsets from the tip, rounded once) and validate the mesh.

        Raises :class:`csgnb.GeometryError` when rounding makes the mesh degenerate or
        self-intersecting (use a finer grid or fewer segments).
        """
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a csgnb.exact.Grid, got {type(grid).__name__}")
        offsets = np.rint(self.vertices * grid.scale).astype(np.int64)
        report: dict = {}
        try:
            V, F = validate_mesh(offsets, self.faces, grid.width, report=report)
        except GeometryError as exc:
            raise GeometryError(
                f"tool {self.name!r} is not a valid solid on a grid of resolution {grid.resolution:g} mm: {exc}. "
                "Use a finer grid or a coarser angular resolution"
            ) from exc
        tool = GridTool(self, grid, V, F)
        # Faces whose corners rounding merged, or put on one line, bound no volume: dropped (a flat one after
        # splitting its neighbour at the middle corner; the solid is the rounded one, as for every point on the
        # grid); many of them mean the grid is coarse for this tool: callers report it.
        tool.collapsed_faces = sum(int(report.get(k, 0)) for k in ("collapsed_faces", "cancelled_faces", "flat_faces"))
        return tool

    def __repr__(self) -> str:
        kind = {True: "convex", False: "non-convex", None: "convexity decided on the grid"}[self.convex]
        return f"ToolShape({self.name!r}, {self.n_triangles} triangles, {kind}, {self.params})"


MAX_SPIN_ORDER = 64  # the largest turn symmetry GridTool.spin_symmetry looks for (360/64 = 5.6 degrees)


@dataclass(frozen=True)
class SpinSymmetry:
    """Turns by 360/``order`` degrees about a tool's axis that map its grid mesh onto itself.

    Attributes
    ----------
    order : int
        1 when the tool has no such symmetry.
    permutation : (n,) int64
        Vertex ``i`` turned by 360/order degrees lands on vertex ``permutation[i]`` (grid offsets,
        exactly); the identity when ``order`` is 1.
    """

    order: int
    permutation: np.ndarray

    def turns(self, k: int) -> np.ndarray:
        """``(n,) int64``: where vertex i lands after ``k`` turns of 360/order degrees."""
        out = np.arange(len(self.permutation))
        for _ in range(int(k) % self.order):
            out = self.permutation[out]
        return out


def _canonical_triangles(faces: np.ndarray) -> np.ndarray:
    """Triangles ``(m, 3)`` each rolled to start at its smallest index (orientation kept), rows sorted."""
    F = np.asarray(faces, np.int64)
    k = np.argmin(F, axis=1)
    rolled = F[np.arange(len(F))[:, None], (k[:, None] + np.arange(3)[None, :]) % 3]
    return rolled[np.lexsort(rolled.T[::-1])]


def _spin_symmetry(design: np.ndarray, offsets: np.ndarray, faces: np.ndarray, scale: float) -> SpinSymmetry:
    """The largest n <= MAX_SPIN_ORDER whose turn maps the quantized mesh onto itself (see GridTool.spin_symmetry)."""
    index = {tuple(row): i for i, row in enumerate(offsets.tolist())}
    triangles = _canonical_triangles(faces)
    for order in range(MAX_SPIN_ORDER, 1, -1):
        t = 2 * np.pi / order
        c, s = np.cos(t), np.sin(t)
        turned = design @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
        landed = [index.get(tuple(row)) for row in np.rint(turned * scale).astype(np.int64).tolist()]
        if None in landed:
            continue
        perm = np.array(landed, np.int64)
        if len(np.unique(perm)) != len(perm):
            continue
        if np.array_equal(_canonical_triangles(perm[faces]), triangles):
            return SpinSymmetry(order, perm)
    return SpinSymmetry(1, np.arange(len(offsets), dtype=np.int64))


class GridTool:
    """A tool quantized on a grid: integer offsets from the tip, a valid closed mesh.

    Attributes
    ----------
    shape : ToolShape
    grid : Grid
    offsets : (n, 3) int64
        Grid offsets of the vertices from the tip (welded by the validation).
    faces : (m, 3) int64
    """

    def __init__(self, shape: ToolShape, grid: Grid, offsets: np.ndarray, faces: np.ndarray) -> None:
        self.shape = shape
        self.grid = grid
        self.offsets = offsets
        self.faces = faces
        self.collapsed_faces = 0

    @property
    def name(self) -> str:
        """The shape's name."""
        return self.shape.name

    @cached_property
    def hull(self) -> ConvexHull:
        """Exact convex hull of the offsets (the tool's solid when it is convex)."""
        return convex_hull(self.offsets, width=self.grid.width, grid=self.grid, name="tool vertices")

    @cached_property
    def mesh_volume(self) -> Fraction:
        """Exact volume of the grid mesh (grid units cubed)."""
        P, Q, R = (self.offsets[self.faces[:, i]].astype(object) for i in range(3))
        return Fraction(int(np.sum(P * np.stack([Q[:, 1] * R[:, 2] - Q[:, 2] * R[:, 1],
                                                  Q[:, 2] * R[:, 0] - Q[:, 0] * R[:, 2],
                                                  Q[:, 0] * R[:, 1] - Q[:, 1] * R[:, 0]], axis=1))), 6)

    @cached_property
    def convex(self) -> bool:
        """Whether the tool sweeps as one hull: the design's flag, or, for a user mesh, exactly decided.

        A closed non-self-intersecting mesh is convex iff its volume equals its hull's.
        """
        if self.shape.convex is not None:
            return bool(self.shape.convex)
        return self.mesh_volume == self.hull.volume()

    def tip(self, position) -> np.ndarray:
        """The grid point ``(3,) int64`` of the tip at model ``position`` (mm)."""
        return self.grid.to_grid(np.asarray(position, float).reshape(1, 3))[0]

    def at(self, position) -> np.ndarray:
        """Vertices ``(n, 3) int64`` with the tip at model ``position``: an exact translation of the offsets."""
        return self.offsets + self.tip(position)

    def posed(self, rotation, position) -> np.ndarray:
        """Vertices ``(n, 3) int64`` of the tool rotated by ``rotation`` (3x3) about its tip, tip at ``position``.

        The rotated design is quantized again (a rotation is not a grid map); the offsets'
        vertex order is kept (vertices the validation welded take the design's first copy).
        """
        R = np.asarray(rotation, float).reshape(3, 3)
        model = self.design_vertices() @ R.T + np.asarray(position, float).reshape(1, 3)
        return self.grid.to_grid(model)

    def design_vertices(self) -> np.ndarray:
        """(n, 3) float64 model offsets matching :attr:`offsets` row by row."""
        if "_design" not in self.__dict__:
            raw = np.rint(self.shape.vertices * self.grid.scale).astype(np.int64)
            _, first = np.unique(raw, axis=0, return_index=True)
            self.__dict__["_design"] = self.shape.vertices[first]
        return self.__dict__["_design"]

    def hull_at(self, *positions) -> ConvexHull:
        """Exact hull of the tool's grid vertices with the tip at each model position (the sweep of a convex tool).

        One or two positions (a pose, a straight move) reuse the tool's hull: translated, or
        swept along the move (:meth:`csgnb.mesh.hull.ConvexHull.swept`, the same hull as
        :func:`~csgnb.mesh.hull.convex_hull` of both poses' vertices, several times faster).
        """
        if len(positions) in (1, 2):
            a = self.tip(positions[0])
            if len(positions) == 1:
                return self.hull.translated(a)
            return self.hull.swept(self.tip(positions[1]) - a, offset=a)
        pts = np.vstack([self.at(p) for p in positions])
        return convex_hull(pts, width=self.grid.width, grid=self.grid, name="tool vertices")

    @cached_property
    def spin_symmetry(self) -> SpinSymmetry:
        """The turns about the tool's axis (+z through the tip) that map its grid mesh exactly onto itself.

        Found, not assumed: for each order n from :data:`MAX_SPIN_ORDER` down to 2, the design
        turned by 360/n degrees is quantized again and must land on the grid offsets vertex for
        vertex (a bijection of integer points), and the permuted triangles, orientation kept,
        must be the tool's triangles. The first order found is the largest (a two-flute drill:
        2; a spur gear of 12 teeth: 12); :attr:`SpinSymmetry.order` 1 when there is none.
        A spinning tool's sweeps then repeat every 360/n degrees (:func:`csgnb.apps.sweep.drill_sweeps`).
        """
        return _spin_symmetry(self.design_vertices(), self.offsets, self.faces, self.grid.scale)

    def __repr__(self) -> str:
        kind = "convex" if self.convex else "non-convex"
        n = self.faces.shape[0]
        return f"GridTool({self.name!r}, {n} triangles, {kind}, resolution {self.grid.resolution:g} mm)"


# ---------------------------------------------------------------------------
# milling tools (convex bodies of revolution)


def flat_end_mill(diameter: float, flute_length: float | None = None, *, segments: int = 32) -> ToolShape:
    """A flat end mill: a cylinder of ``diameter`` and ``flute_length`` (default 3 diameters), convex.

    ``segments`` vertices around (on the circle: the polygon is inscribed).
    """
    D = _positive("diameter", diameter)
    L = 3 * D if flute_length is None else _positive("flute_length", flute_length)
    n = _count("segments", segments, 3)
    V, F = _revolve([(0, 0), (D / 2, 0), (D / 2, L), (0, L)], n)
    return ToolShape(f"flat end mill D{D:g}", V, F, True, dict(diameter=D, flute_length=L, segments=n))


def ball_end_mill(diameter: float, flute_length: float | None = None, *, segments: int = 32,
                  rings: int | None = None) -> ToolShape:
    """A ball end mill: a hemisphere of ``diameter`` below a cylinder, convex.

    ``rings`` latitude steps on the quarter arc (default ``segments // 4``).
    """
    D = _positive("diameter", diameter)
    R = D / 2
    L = 3 * D if flute_length is None else _positive("flute_length", flute_length)
    if L < R:
        raise ValueError(f"flute_length {L} must be at least the ball radius {R}")
    n = _count("segments", segments, 3)
    k = max(2, n // 4) if rings is None else _count("rings", rings, 1)
    phi = np.pi / 2 * np.arange(1, k + 1) / k
    profile = [(0.0, 0.0)] + [(R * np.sin(p), R - R * np.cos(p)) for p in phi]
    if L > R:
        profile.append((R, L))
    profile.append((0.0, L))
    V, F = _revolve(profile, n)
    return ToolShape(f"ball end mill D{D:g}", V, F, True, dict(diameter=D, flute_length=L, segments=n, rings=k))


def bull_nose(diameter: float, corner_radius: float, flute_length: float | None = None, *, segments: int = 32,
              rings: int | None = None) -> ToolShape:
    """A bull-nose (corner-radius) end mill: flat bottom, a torus corner of ``corner_radius``, convex."""
    D = _positive("diameter", diameter)
    R = D / 2
    rc = _positive("corner_radius", corner_radius)
    if rc > R:
        raise ValueError(f"corner_radius {rc} cannot exceed the radius {R} (corner_radius = radius is a ball mill)")
    L = 3 * D if flute_length is None else _positive("flute_length", flute_length)
    if L < rc:
        raise ValueError(f"flute_length {L} must be at least the corner radius {rc}")
    n = _count("segments", segments, 3)
    k = max(2, n // 4) if rings is None else _count("rings", rings, 1)
    phi = np.pi / 2 * np.arange(1, k + 1) / k
    profile = [(0.0, 0.0)]
    if R - rc > 0:
        profile.append((R - rc, 0.0))
    profile += [(R - rc + rc * np.sin(p), rc - rc * np.cos(p)) for p in phi]
    if L > rc:
        profile.append((R, L))
    profile.append((0.0, L))
    V, F = _revolve(profile, n)
    return ToolShape(f"bull nose D{D:g} R{rc:g}", V, F, True,
                     dict(diameter=D, corner_radius=rc, flute_length=L, segments=n, rings=k))


def v_bit(diameter: float, angle: float = 90.0, flute_length: float | None = None, *, segments: int = 32) -> ToolShape:
    """A V-bit / chamfer mill: a cone of included ``angle`` (degrees) up to ``diameter``, then a cylinder; convex."""
    D = _positive("diameter", diameter)
    a = float(angle)
    if not 0 < a < 180:
        raise ValueError(f"angle must be an included angle in (0, 180) degrees, got {angle!r}")
    R = D / 2
    h = R / np.tan(np.radians(a) / 2)
    L = max(h, 3 * D) if flute_length is None else _positive("flute_length", flute_length)
    n = _count("segments", segments, 3)
    profile = [(0.0, 0.0), (R, h)] + ([(R, L)] if L > h else []) + [(0.0, max(L, h))]
    V, F = _revolve(profile, n)
    return ToolShape(f"V-bit D{D:g} {a:g}°", V, F, True, dict(diameter=D, angle=a, flute_length=max(L, h),
                                                               segments=n))


def drill_envelope(diameter: float, flute_length: float | None = None, *, point_angle: float = 118.0,
                   segments: int = 32) -> ToolShape:
    """The solid a spinning twist drill sweeps: a cylinder with a ``point_angle`` cone tip; convex."""
    shape = v_bit(diameter, point_angle, flute_length, segments=segments)
    return ToolShape(f"drill D{shape.params['diameter']:g}", shape.vertices, shape.faces, True,
                     dict(shape.params, point_angle=float(point_angle)))


# ---------------------------------------------------------------------------
# non-convex shapes: the drill of Figure 13 and the gear of Figure 12


def twist_drill(diameter: float = 6.0, flute_length: float = 12.0, *, point_angle: float = 118.0,
                helix_angle: float = 30.0, web: float = 0.2, profile_points: int = 28,
                layers: int = 16) -> ToolShape:
    """A two-flute twist drill (default: radius 3, 118° point, 30° helix, 896 triangles), not convex.

    The cross-section has two lands at the full radius and two flutes that reach in to the
    web (``web`` x diameter thick); it twists along the helix and is cut by the point cone
    (each vertex's radius is capped by the cone). ``layers`` cross-sections from the point
    to the top; triangles = 2 · profile_points · (layers - 1) + 2 · profile_points.
    """
    D = _positive("diameter", diameter)
    R = D / 2
    L = _positive("flute_length", flute_length)
    M = _count("profile_points", profile_points, 8)
    K = _count("layers", layers, 3)
    if not 0 < web < 0.9:
        raise ValueError(f"web must be a fraction of the diameter in (0, 0.9), got {web!r}")
    if not 60 <= float(point_angle) < 180:
        raise ValueError(f"point_angle must be in [60, 180) degrees, got {point_angle!r}")
    if not 0 <= float(helix_angle) < 60:
        raise ValueError(f"helix_angle must be in [0, 60) degrees, got {helix_angle!r}")
    tan_half = np.tan(np.radians(point_angle) / 2)
    z_point = R / tan_half  # the cone reaches the full radius here
    if L <= z_point:
        raise ValueError(f"flute_length {L} must exceed the point height {z_point:.3f}")
    r_web = web * D / 2
    phi = 2 * np.pi * np.arange(M) / M
    # Two flutes per turn: lands over 45 % of each half turn, a smooth flute over the rest.
    t = (phi % np.pi) / np.pi
    land = 0.45
    s = np.clip((t - land) / (1 - land), 0, 1)
    r_profile = R - (R - r_web) * np.sin(np.pi * s) ** 2
    # Layers: a third in the point region (radius capped by the cone), the rest up the flutes.
    n_point = max(1, K // 3)
    z = np.r_[z_point * np.arange(1, n_point + 1) / n_point,
              z_point + (L - z_point) * np.arange(1, K - n_point + 1) / (K - n_point)]
    twist = np.tan(np.radians(helix_angle)) / R  # radians per mm along the axis
    rings = []
    for zk in z:
        r = np.minimum(r_profile, zk * tan_half)
        a = phi + twist * zk
        rings.append(np.column_stack([r * np.cos(a), r * np.sin(a), np.full(M, zk)]))
    V, F = _lathe(rings, (0, 0, 0), (0, 0, L))
    return ToolShape(f"twist drill D{D:g}", V, F, False,
                     dict(diameter=D, flute_length=L, point_angle=float(point_angle),
                          helix_angle=float(helix_angle), web=float(web), profile_points=M, layers=K))


def spur_gear(teeth: int = 12, module: float = 1.0, thickness: float = 2.0, *, pressure_angle: float = 20.0,
              flank_points: int = 4) -> ToolShape:
    """A spur gear with involute teeth, centred on the axis, ``thickness`` along z (default 480 triangles).

    Pitch radius ``module · teeth / 2``, addendum ``module``, dedendum ``1.25 module``. Each
    tooth has ``flank_points`` points per flank and two on the root circle; the cap
    polygons are star-shaped about the axis, fanned from their centres. Not convex.
    """
    N = _count("teeth", teeth, 3)
    m = _positive("module", module)
    t = _positive("thickness", thickness)
    F = _count("flank_points", flank_points, 2)
    alpha = np.radians(float(pressure_angle))
    rp = m * N / 2
    rb = rp * np.cos(alpha)
    r_tip, r_root = rp + m, rp - 1.25 * m
    if r_root <= 0:
        raise ValueError(f"{N} teeth of module {m} leave no root circle; use more teeth")

    def inv(a):
        return np.tan(a) - a

    def half_thickness(r):  # angular half-thickness of a tooth at radius r (involute)
        return np.pi / (2 * N) + inv(alpha) - inv(np.arccos(np.clip(rb / r, -1, 1)))

    r_flank = np.linspace(max(rb, r_root), r_tip, F)
    psi = half_thickness(r_flank)
    gap = np.pi / N - psi[0]  # half the tooth space at the flank start
    angles, radii = [], []
    for i in range(N):
        c = 2 * np.pi * i / N
        angles += [c - psi[0] - gap / 2, *(c - psi), *(c + psi[::-1]), c + psi[0] + gap / 2]
        radii += [r_root, *r_flank, *r_flank[::-1], r_root]
    a, r = np.array(angles), np.array(radii)
    ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
    M = ring.shape[0]
    bottom = np.column_stack([ring, np.full(M, -t / 2)])
    top = np.column_stack([ring, np.full(M, t / 2)])
    V, Fc = _lathe([bottom, top], (0, 0, -t / 2), (0, 0, t / 2))
    return ToolShape(f"spur gear {N}T m{m:g}", V, Fc, False,
                     dict(teeth=N, module=m, thickness=t, pressure_angle=float(pressure_angle), flank_points=F))


def mesh_tool(vertices, faces, *, name: str = "mesh tool", convex: bool | None = None) -> ToolShape:
    """A user mesh as a tool (mm, tip at the origin, axis +z); convexity decided exactly on the grid unless given."""
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces)
    if V.ndim != 2 or V.shape[1] != 3 or not np.all(np.isfinite(V)):
        raise ValueError(f"vertices must be a finite (n, 3) float array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or F.dtype.kind not in "iu":
        raise ValueError(f"faces must be an (m, 3) integer array of triangles, got {F.dtype} {F.shape}")
    return ToolShape(name, V, F.astype(np.int64), convex, dict(source="mesh"))


_KINDS = {
    "flat": (flat_end_mill, ("diameter", "flute_length")),
    "ball": (ball_end_mill, ("diameter", "flute_length")),
    "bull": (bull_nose, ("diameter", "corner_radius", "flute_length")),
    "vbit": (v_bit, ("diameter", "angle", "flute_length")),
    "drill": (drill_envelope, ("diameter", "flute_length")),
}


def parse_tool(spec: str, *, segments: int = 32) -> ToolShape:
    """A tool from a short spec: ``flat:6``, ``ball:6:20`` (diameter, flute length), ``bull:6:1`` (corner
    radius), ``vbit:6:90`` (included angle), ``drill:6`` (a spinning drill's envelope); sizes in mm."""
    kind, _, rest = spec.strip().partition(":")
    if kind not in _KINDS:
        raise ValueError(f"unknown tool kind {kind!r} in {spec!r}; use one of {sorted(_KINDS)} (e.g. flat:6)")
    make, names = _KINDS[kind]
    try:
        values = [float(x) for x in rest.split(":")] if rest else []
    except ValueError:
        raise ValueError(f"tool spec {spec!r}: the sizes after the kind must be numbers (mm), e.g. {kind}:6") from None
    if not values or len(values) > len(names):
        raise ValueError(f"tool spec {spec!r}: give {kind}:" + ":".join(names) + " (the first is required)")
    if kind == "bull" and len(values) < 2:
        raise ValueError(f"tool spec {spec!r}: a bull-nose needs a corner radius, e.g. bull:6:1")
    return make(**dict(zip(names, values, strict=False)), segments=segments)
