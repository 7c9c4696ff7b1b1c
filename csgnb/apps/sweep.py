"""Swept volumes as exact convex hulls on the grid (paper §5): straight moves, rotating poses, arcs, paths.

A sweep is a list of :class:`csgnb.mesh.hull.ConvexHull` pieces in grid coordinates --
what a workpiece subtracts (milling) or adds (the gear sweep of Figure 12):

* a **convex tool** on a straight move: one piece, the exact hull of its grid vertices at
  both end poses. The tool at a pose is its grid offsets plus the tip's grid point, so the
  move is exactly the Minkowski sum of the tool and the segment between the two grid tips;
  nothing is rounded after quantization;
* a **non-convex tool**: one prism per triangle, the exact hull of the triangle at two
  consecutive poses (:func:`prisms`), as the paper does. For a translation these prisms and
  the tool at the end pose cover the swept volume exactly (every point swept but outside
  both end poses lies on a prism: follow it back along the move until it leaves the tool);
  with a rotation they approximate it. Prisms of zero volume (a triangle moving in its own
  plane) are skipped, counted in :attr:`Sweep.skipped`;
* **rotation** (the drill of Figure 13) as a sequence of poses (:func:`drill_poses`), each
  pose's vertices quantized after rotating the design;
* **arcs** split into chords within a stated tolerance (:func:`arc_polyline`), and paths
  such as a cubic Bézier (:func:`bezier_points`) as sequences of positions.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numba
import numpy as np

from csgnb.apps.tools import GridTool
from csgnb.errors import GeometryError
from csgnb.mesh.hull import ConvexHull, small_hulls
from csgnb.octree import Tool, Workpiece

__all__ = [
    "DrillSweeps",
    "Pose",
    "Sweep",
    "arc_polyline",
    "arc_segments",
    "bezier_points",
    "drill_poses",
    "drill_sweeps",
    "path_sweep",
    "pose_vertices",
    "prisms",
    "rotation_about",
    "straight_sweep",
    "union_hulls",
]


@dataclass(frozen=True)
class Pose:
    """A rigid placement of a tool: ``rotation`` (3x3) about the tip, then the tip at ``position`` (mm)."""

    position: np.ndarray
    rotation: np.ndarray | None = None  # None: the design's orientation (an exact translation)

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", np.asarray(self.position, float).reshape(3))
        if self.rotation is not None:
            R = np.asarray(self.rotation, float).reshape(3, 3)
            if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) <= 0:
                raise GeometryError(f"a pose rotation must be a proper rotation matrix, got {R.tolist()}")
            object.__setattr__(self, "rotation", R)


@dataclass
class Sweep:
    """The pieces a tool sweeps over one move (grid coordinates).

    Attributes
    ----------
    hulls : list of ConvexHull
        Convex pieces (one for a convex tool, one prism per triangle otherwise).
    end_pose : (n, 3) int64 or None
        The non-convex tool's vertices at the end pose (with :attr:`faces`): subtract it as a
        mesh too, to remove the inside of the tool there.
    faces : (m, 3) int64 or None
    skipped : int
        Prisms of zero volume left out.
    """

    hulls: list[ConvexHull] = field(default_factory=list)
    end_pose: np.ndarray | None = None
    faces: np.ndarray | None = None
    skipped: int = 0


def rotation_about(axis, angle_degrees: float) -> np.ndarray:
    """The 3x3 rotation by ``angle_degrees`` about ``axis`` (right-hand rule; Rodrigues' formula)."""
    a = np.asarray(axis, float).reshape(3)
    n = np.linalg.norm(a)
    if not n > 0:
        raise GeometryError("a rotation axis must be a non-zero vector")
    x, y, z = a / n
    t = np.radians(angle_degrees)
    c, s = np.cos(t), np.sin(t)
    K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def pose_vertices(tool: GridTool, pose: Pose) -> np.ndarray:
    """The tool's grid vertices ``(n, 3) int64`` at ``pose`` (an exact translation when it has no rotation)."""
    return tool.at(pose.position) if pose.rotation is None else tool.posed(pose.rotation, pose.position)


def prisms(a, b, faces, *, width: int, grid=None) -> tuple[list[ConvexHull], int]:
    """Per-triangle prisms: the exact hull of each triangle at vertices ``a`` and at ``b``.

    Parameters
    ----------
    a, b : (n, 3) int64
        The same mesh at two poses (grid coordinates).
    faces : (m, 3) int

    Returns
    -------
    hulls : list of ConvexHull
        One per triangle whose prism has volume.
    skipped : int
        Flat prisms (zero volume) left out.
    """
    a, b = np.asarray(a), np.asarray(b)
    F = np.asarray(faces)
    if a.shape != b.shape:
        raise GeometryError(f"the two poses need the same vertices, got shapes {a.shape} and {b.shape}")
    pts = np.concatenate([a[F], b[F]], axis=1)  # (m, 6, 3)
    found = small_hulls(pts, width=width, grid=grid)
    hulls = [h for h in found if h is not None]
    return hulls, len(found) - len(hulls)


def straight_sweep(tool: GridTool, start, end) -> Sweep:
    """The volume ``tool`` sweeps moving its tip in a straight line from ``start`` to ``end`` (mm, no rotation)."""
    if tool.convex:
        return Sweep([tool.hull_at(start, end)])
    a, b = tool.at(start), tool.at(end)
    hulls, skipped = prisms(a, b, tool.faces, width=tool.grid.width, grid=tool.grid)
    return Sweep(hulls, b, tool.faces, skipped)


def path_sweep(tool: GridTool, poses: list[Pose]) -> list[Sweep]:
    """Per consecutive pair of poses, the sweep of ``tool`` (per-triangle prisms; convex tools as one hull when the
    two poses differ by a translation only)."""
    if len(poses) < 2:
        raise GeometryError("a path sweep needs at least two poses")
    out = []
    prev = pose_vertices(tool, poses[0])
    for p, q in zip(poses[:-1], poses[1:], strict=True):
        cur = pose_vertices(tool, q)
        if tool.convex and p.rotation is None and q.rotation is None:
            out.append(Sweep([tool.hull_at(p.position, q.position)]))
        else:
            hulls, skipped = prisms(prev, cur, tool.faces, width=tool.grid.width, grid=tool.grid)
            out.append(Sweep(hulls, cur, tool.faces, skipped))
        prev = cur
    return out


# ---------------------------------------------------------------------------
# paths


def bezier_points(control, samples: int) -> np.ndarray:
    """``samples`` points ``(S, 3)`` of the cubic Bézier with ``control`` points ``(4, 3)``, uniform in t."""
    C = np.asarray(control, float)
    if C.shape != (4, 3) or not np.all(np.isfinite(C)):
        raise GeometryError(f"a cubic Bézier needs 4 finite control points (4, 3), got {C.shape}")
    if int(samples) != samples or samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples!r}")
    t = np.linspace(0.0, 1.0, int(samples))[:, None]
    return ((1 - t) ** 3 * C[0] + 3 * (1 - t) ** 2 * t * C[1] + 3 * (1 - t) * t**2 * C[2] + t**3 * C[3])


def arc_segments(radius: float, sweep_radians: float, tolerance: float) -> int:
    """Chords needed so that no chord strays more than ``tolerance`` from an arc (sagitta r(1 - cos(θ/2)))."""
    r, total, tol = float(radius), abs(float(sweep_radians)), float(tolerance)
    if not tol > 0:
        raise ValueError(f"the chord tolerance must be positive, got {tolerance!r}")
    if r <= tol or total == 0:
        return 1 if total < np.pi else max(1, int(np.ceil(total / (np.pi / 2))))
    step = 2 * np.arccos(1 - tol / r)
    return max(1, int(np.ceil(total / step - 1e-12)))


def arc_polyline(start, end, center, normal, clockwise: bool, *, tolerance: float, turns: int = 0) -> np.ndarray:
    """Points ``(k + 1, 3)`` along a (helical) arc from ``start`` to ``end`` about ``center``, chord error <= tolerance.

    The arc turns about the axis through ``center`` along the unit ``normal`` (clockwise seen
    from the tip of ``normal`` when ``clockwise``); the coordinate along ``normal`` changes
    linearly (a helix). ``start == end`` in the plane is a full circle; ``turns`` adds full
    turns. The first point is ``start`` and the last ``end`` exactly.
    """
    s, e, c = (np.asarray(x, float).reshape(3) for x in (start, end, center))
    n = np.asarray(normal, float).reshape(3)
    n = n / np.linalg.norm(n)
    rs, re_ = s - c, e - c
    rs_p, re_p = rs - (rs @ n) * n, re_ - (re_ @ n) * n
    r = float(np.linalg.norm(rs_p))
    if not r > 0:
        raise GeometryError("an arc needs a start point away from its centre")
    u = rs_p / r
    v = np.cross(n, u)
    theta = float(np.arctan2(re_p @ v, re_p @ u))  # counter-clockwise angle from start to end, in (-pi, pi]
    if clockwise:
        theta = -((-theta) % (2 * np.pi))
        if theta == 0:
            theta = -2 * np.pi
    else:
        theta = theta % (2 * np.pi)
        if theta == 0:
            theta = 2 * np.pi
    theta += (-1 if clockwise else 1) * 2 * np.pi * int(turns)
    k = arc_segments(r, theta, tolerance)
    t = np.linspace(0.0, 1.0, k + 1)[:, None]
    ang = theta * t
    r_end = float(np.linalg.norm(re_p))
    rad = r + (r_end - r) * t  # a slightly unequal end radius (within the parser's tolerance) blends in
    h = (rs @ n) + ((re_ @ n) - (rs @ n)) * t
    pts = c + rad * (np.cos(ang) * u + np.sin(ang) * v) + h * n
    pts[0], pts[-1] = s, e
    return pts


# ---------------------------------------------------------------------------
# the rotating drill of Figure 13


def drill_poses(position=(0.0, 0.0, 0.0), *, tilt_degrees: float = 30.0, steps: int = 90,
                step_degrees: float = 4.0) -> list[Pose]:
    """``steps + 1`` poses of a drill spinning ``step_degrees`` per step about its own axis, tilted from vertical.

    The axis is tilted by ``tilt_degrees`` about +x; the tip stays at ``position``. The
    default is the paper's 90 poses of 4° per turn (pose 90 = pose 0 turned once).
    """
    tilt = rotation_about((1, 0, 0), tilt_degrees)
    return [Pose(position, tilt @ rotation_about((0, 0, 1), k * step_degrees)) for k in range(int(steps) + 1)]


@dataclass
class DrillSweeps:
    """The per-step sweeps of a spinning drill, precomputed once, replayed turn after turn by exact translation.

    Attributes
    ----------
    steps : list of list of ConvexHull
        ``steps[k]``: the prisms between pose k and k + 1.
    feed : (3,) int64
        Grid translation per turn (along the tilted axis, into the material).
    skipped : int
        Flat prisms left out.
    poses : list of (n, 3) int64
        The drill's grid vertices at each pose (``poses[k]`` starts step k), with :attr:`faces`.
        The prisms only cover the path of the drill's *surface* (as in the paper); where a turn's
        feed jump moves the drill into material, subtract the posed drill itself too
        (``BSP.from_mesh(pose + turn * feed, faces)``) so no material is left inside it.
    faces : (m, 3) int64
    period : int
        The sweeps repeat every ``period`` steps: ``steps[k]`` is the very list ``steps[k % period]``
        (a drill with a turn symmetry of order n spins into itself every 360/n degrees;
        :func:`drill_sweeps`). :meth:`tools` builds ``period`` tools, not ``len(self)``.
    """

    steps: list[list[ConvexHull]]
    feed: np.ndarray
    skipped: int
    poses: list[np.ndarray] = field(default_factory=list)
    faces: np.ndarray | None = None
    period: int | None = None

    def __post_init__(self) -> None:
        n = len(self.steps)
        if self.period is None:
            self.period = n
        if (n and not 1 <= self.period <= n) or any(self.steps[k] is not self.steps[k % self.period]
                                                       for k in range(n)):
            raise GeometryError(f"period {self.period} must divide the steps into repeats of the first "
                                f"{self.period} (steps[k] is steps[k % period])")

    def __len__(self) -> int:
        return len(self.steps)

    def tools(self, grid, *, threshold: int | None = None, threads: int | None = None, progress: bool = False) -> list:
        """Prepare each step's sweep as one :class:`csgnb.octree.Tool` (the union of its prisms), once.

        Step k's tool is what ``work -= tool.translated(turn * feed)`` subtracts at global step
        ``turn * len(self) + k`` (Figure 13's drill: 90 tools replayed turn after turn). Steps that
        repeat (:attr:`period`) share one tool: the paper's two-flute drill builds 45. The steps are
        independent: they are built on ``threads`` threads (default: every core numba uses; the
        Boolean kernels release the GIL), each tool the one a single thread builds.

        Parameters
        ----------
        grid : csgnb.exact.Grid
            The workpiece's grid (the prisms lie on it).
        threshold : int, optional
            Octree split threshold of the scratch workpiece each union runs in (default: the workpiece's).
        threads : int, optional
        progress : bool
            A tqdm bar over the steps.

        Returns
        -------
        list of csgnb.octree.Tool, one per step (repeating steps: the same object)
        """
        if threads is None:
            threads = numba.get_num_threads()
        if not isinstance(threads, int | np.integer) or isinstance(threads, bool) or threads < 1:
            raise TypeError(f"threads must be a positive integer, got {threads!r}")
        options = {} if threshold is None else {"threshold": threshold}

        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=self.period, desc="drill sweeps", unit="step")

        def build(k: int):
            swept = Workpiece.empty(grid, **options)
            swept.run(self.steps[k], "union")  # the prisms in compiled batches (csgnb.octree.batch)
            if bar is not None:
                bar.update(1)
            return Tool.from_bsp(swept.to_bsp(), grid=grid)

        try:
            if threads == 1:
                distinct = [build(k) for k in range(self.period)]
            else:
                with ThreadPoolExecutor(int(threads)) as pool:
                    distinct = list(pool.map(build, range(self.period)))
            return [distinct[k % self.period] for k in range(len(self.steps))]
        finally:
            if bar is not None:
                bar.close()

    def step(self, i: int) -> list[ConvexHull]:
        """The prisms of global step ``i`` (turn ``i // len(self)``): step ``i % len`` moved by turn x feed."""
        turn, k = divmod(int(i), len(self.steps))
        if turn == 0:
            return self.steps[k]
        t = self.feed * turn
        return [h.translated(t) for h in self.steps[k]]


def drill_sweeps(tool: GridTool, position=(0.0, 0.0, 0.0), *, tilt_degrees: float = 30.0, steps: int = 90,
                 step_degrees: float = 4.0, feed_per_turn: float = 0.5, symmetry: bool = True) -> DrillSweeps:
    """Precompute the per-step prism sweeps of ``tool`` spinning at ``position`` (Figure 13's set-up).

    ``feed_per_turn`` (mm) moves the drill along its tilted axis towards the tip each turn,
    rounded once to a grid vector, so every later turn is an exact translation.

    With ``symmetry`` (default), a tool that turns into itself every 360/n degrees
    (:attr:`csgnb.apps.tools.GridTool.spin_symmetry`, found exactly on the grid) is posed
    directly for the first ``period = 360 / (n * step_degrees)`` poses only (when that is a
    whole number of steps), and pose ``k + period`` is pose ``k`` with its vertices renamed by
    the symmetry: the same grid points, each still the rounding of its vertex's true position,
    so step ``k + period`` has step k's prisms and the very same sweep (``DrillSweeps.period``).
    The paper's two-flute drill: 45 sweeps to build instead of 90, the same volumes.
    ``symmetry=False`` poses every step directly.
    """
    steps = int(steps)
    if steps < 0:
        raise GeometryError(f"steps must be a count of poses to sweep between, got {steps}")
    period, perm = steps, None
    if symmetry and steps > 1:
        sym = tool.spin_symmetry
        for d in range(sym.order, 1, -1):  # the largest usable turn: the shortest period
            p = 360.0 / (d * float(step_degrees))
            if sym.order % d == 0 and abs(p - round(p)) < 1e-9 and 1 <= round(p) < steps:
                period, perm = int(round(p)), sym.turns(sym.order // d)
                break
    poses = drill_poses(position, tilt_degrees=tilt_degrees, steps=period, step_degrees=step_degrees)
    verts = [pose_vertices(tool, p) for p in poses[:period]]
    if perm is None:
        verts.append(pose_vertices(tool, poses[period]))
    else:
        for k in range(period, steps + 1):
            verts.append(verts[k - period][perm])
    out, skipped = [], 0
    for k in range(steps):
        if k < period:
            hulls, s = prisms(verts[k], verts[k + 1], tool.faces, width=tool.grid.width, grid=tool.grid)
            out.append(hulls)
            skipped += s
        else:
            out.append(out[k - period])
            skipped += len(tool.faces) - len(out[k])
    axis = rotation_about((1, 0, 0), tilt_degrees) @ np.array([0.0, 0.0, -1.0])  # towards the tip
    feed = np.rint(axis * float(feed_per_turn) * tool.grid.scale).astype(np.int64)
    return DrillSweeps(out, feed, skipped, verts[:steps], tool.faces, period)


def union_hulls(hulls: list[ConvexHull], *, width: int | None = None):
    """The union of hulls as one :class:`csgnb.bsp.BSP` (balanced pairwise merges on single BSPs; slow, exact).

    What an octree workpiece does faster by iterated union (``Workpiece.empty(grid)`` and
    ``w |= hull``); kept for building a non-convex tool (a drill step) as one solid on the
    single-BSP engine.
    """
    if not hulls:
        raise GeometryError("the union of no hulls is empty; nothing to build")
    level = [h.to_bsp(width) for h in hulls]
    while len(level) > 1:
        level = [level[i] | level[i + 1] if i + 1 < len(level) else level[i] for i in range(0, len(level), 2)]
    return level[0]
