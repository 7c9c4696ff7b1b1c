"""Pinhole and orthographic cameras: look-at frames, pixel rays, projection, orbit and fit-to-bounds.

Conventions (shared by the reference ray tracer and the splat renderer, so that both trace the
very same ray through a pixel):

* pixel ``(i, j)`` is row ``i`` (top to bottom) and column ``j`` (left to right); its ray passes
  through its centre, screen coordinates ``x = (2 (j + ½) / W - 1) · tx``,
  ``y = (1 - 2 (i + ½) / H) · ty`` (``tx``, ``ty``: half extents of the image plane at distance 1
  for a perspective camera, in world units for an orthographic one);
* perspective: origin the eye, direction ``d = f + x r + y u``; orthographic: origin
  ``eye + x r + y u``, direction ``d = f``. As ``d·f = 1`` the ray parameter z of ``o + z d`` is
  the view-space depth (distance from the image plane through the eye, along ``f``);
* ``depth`` buffers hold that z; only ``z > 0`` is visible (the near plane is the eye plane).
  Views are from outside the object, as in the paper (§7.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_finite_array, as_points, as_real

__all__ = ["Camera", "PROJECTIONS", "CAMERA_FIELDS"]

#: ``projection=`` choices.
PROJECTIONS = ("perspective", "orthographic")

#: Layout of :meth:`Camera.params`, the (20,) float64 array the kernels read: eye [0:3], forward
#: [3:6], right [6:9], up [9:12], (unused) [12:14], tx [14], ty [15], width [16], height [17],
#: orthographic flag [18], (unused) [19].
CAMERA_FIELDS = {"eye": 0, "forward": 3, "right": 6, "up": 9, "tx": 14, "ty": 15, "width": 16, "height": 17,
                 "orthographic": 18}


def _vec3(v, name: str) -> np.ndarray:
    try:
        a = as_finite_array(v, (3,), f"camera {name}", finite=False)
    except CsgnbError as exc:  # a wrong shape: name the argument and what it must be
        raise TypeError(f"camera {name} must be a 3-vector of numbers, got {v!r:.80}") from exc
    if not np.all(np.isfinite(a)):
        raise GeometryError(f"camera {name} must be finite, got {a.tolist()}")
    a = a.copy()
    if np.max(np.abs(a)) > tol.COORDINATE_LIMIT:
        raise GeometryError(f"camera {name} {a.tolist()} is beyond ±{tol.COORDINATE_LIMIT:g}: its products with "
                            "other coordinates would overflow; move the scene nearer the origin")
    return a


def _size(v, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer):
        raise TypeError(f"camera {name} must be an int (pixels), got {type(v).__name__}")
    if v <= 0:
        raise CsgnbError(f"camera {name} must be at least 1 pixel, got {v}")
    if v > 16384:
        raise CsgnbError(f"camera {name} of {v} pixels exceeds the limit of 16384")
    return int(v)


def _projection(v) -> str:
    if not isinstance(v, str):
        raise TypeError(f"projection must be a str, one of {PROJECTIONS}, got {type(v).__name__}")
    if v not in PROJECTIONS:
        raise CsgnbError(f"projection must be one of {PROJECTIONS}, got {v!r}")
    return v


def _angle(v, name: str) -> float:
    """An angle in degrees: a finite real number."""
    return as_real(v, name)


@dataclass(frozen=True, eq=False)
class Camera:
    """A look-at camera: eye, target, up, image size and projection.

    eye, target, up : (3,) float64 — ``up`` need not be orthogonal to the view direction, only
        not parallel to it.
    width, height : int — image size in pixels.
    fov : float — vertical field of view in degrees (perspective), in (0, 180).
    projection : "perspective" or "orthographic".
    ortho_height : float — height of the view in world units (orthographic).

    Build with :meth:`look_at`, :meth:`orbit` or :meth:`fit`; all validate (``GeometryError``
    for a degenerate frame, ``ValueError`` for a zero size).
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    width: int
    height: int
    fov: float = 40.0
    projection: str = "perspective"
    ortho_height: float = 2.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "eye", _vec3(self.eye, "eye"))
        object.__setattr__(self, "target", _vec3(self.target, "target"))
        object.__setattr__(self, "up", _vec3(self.up, "up"))
        object.__setattr__(self, "width", _size(self.width, "width"))
        object.__setattr__(self, "height", _size(self.height, "height"))
        _projection(self.projection)
        fov = as_real(self.fov, "fov (field of view, degrees)", finite=False)
        oh = as_real(self.ortho_height, "ortho_height (orthographic view height)", finite=False)
        if not (math.isfinite(fov) and 0.0 < fov < 180.0):
            raise GeometryError(f"field of view must be in (0, 180) degrees, got {self.fov!r}")
        if not (math.isfinite(oh) and oh > 0.0):
            raise GeometryError(f"orthographic view height must be positive and finite, got {self.ortho_height!r}")
        object.__setattr__(self, "fov", fov)
        object.__setattr__(self, "ortho_height", oh)
        d = self.target - self.eye
        dist = float(np.linalg.norm(d))
        scale = max(float(np.max(np.abs(self.eye))), float(np.max(np.abs(self.target))), 1e-300)
        if not dist > 1e-12 * scale:
            raise GeometryError(
                f"camera eye and target coincide ({self.eye.tolist()}); move the eye away from the target"
            )
        f = d / dist
        upn = float(np.linalg.norm(self.up))
        if not upn > 0.0:
            raise GeometryError("camera up vector is zero; pass a direction such as (0, 0, 1)")
        r = np.cross(f, self.up / upn)
        rn = float(np.linalg.norm(r))
        if rn < 1e-9:
            raise GeometryError(
                f"camera up {self.up.tolist()} is parallel to the view direction {f.tolist()}; pick another up vector"
            )
        r /= rn
        u = np.cross(r, f)
        object.__setattr__(self, "_frame", (f, r, u / np.linalg.norm(u), dist))

    # -- constructors ----------------------------------------------------------------------------
    @classmethod
    def look_at(cls, eye, target, up=(0.0, 0.0, 1.0), width: int = 640, height: int = 480, *,
                fov: float = 40.0, projection: str = "perspective", ortho_height: float | None = None) -> Camera:
        """Return a camera at ``eye`` looking at ``target``.

        For an orthographic camera without ``ortho_height`` the view height is the one a
        perspective camera of field of view ``fov`` sees at the target's distance.
        """
        if ortho_height is None:
            e, t = _vec3(eye, "eye"), _vec3(target, "target")
            fv = as_real(fov, "fov (field of view, degrees)")
            if not 0.0 < fv < 180.0:
                raise GeometryError(f"field of view must be in (0, 180) degrees, got {fov!r}")
            d = float(np.linalg.norm(t - e))
            ortho_height = 2.0 * max(d, 1e-300) * math.tan(math.radians(fv) / 2.0)
        return cls(eye, target, up, width, height, fov, projection, ortho_height)

    @classmethod
    def orbit(cls, target, azimuth: float, elevation: float, distance: float, width: int = 640, height: int = 480,
              *, up=(0.0, 0.0, 1.0), fov: float = 40.0, projection: str = "perspective",
              ortho_height: float | None = None) -> Camera:
        """Return a camera on a sphere around ``target`` (angles in degrees).

        azimuth : angle of the eye around the ``up`` axis, from the x axis (for ``up`` = +z: 0 puts
            the eye on +x, 90 on +y); elevation : above the plane ⟂ ``up``, in (-90, 90).
        """
        el = as_real(elevation, "elevation", finite=False)
        if not -90.0 < el < 90.0:
            raise GeometryError(f"orbit elevation must be in (-90, 90) degrees, got {elevation!r}")
        dist = as_real(distance, "distance", finite=False)
        if not (math.isfinite(dist) and 0.0 < dist <= tol.COORDINATE_LIMIT):
            raise GeometryError(f"orbit distance must be positive, finite and at most {tol.COORDINATE_LIMIT:g}, "
                                f"got {distance!r}")
        azimuth = _angle(azimuth, "azimuth")
        z = _vec3(up, "up")
        zn = float(np.linalg.norm(z))
        if zn == 0.0:
            raise GeometryError("camera up vector is zero; pass a direction such as (0, 0, 1)")
        z = z / zn
        x, y = _plane_axes(z)
        a, e = math.radians(azimuth), math.radians(el)
        offset = dist * (math.cos(e) * (math.cos(a) * x + math.sin(a) * y) + math.sin(e) * z)
        t = _vec3(target, "target")
        return cls.look_at(t + offset, t, z, width, height, fov=fov, projection=projection,
                           ortho_height=ortho_height)

    @classmethod
    def fit(cls, bounds, width: int = 640, height: int = 480, *, azimuth: float = -60.0, elevation: float = 30.0,
            up=(0.0, 0.0, 1.0), fov: float = 40.0, projection: str = "perspective", margin: float = 1.05) -> Camera:
        """Return an orbit camera that sees the whole box ``bounds`` (lo (3,), hi (3,)).

        ``bounds`` may also be a ``(6,)`` array ``(lo₀, lo₁, lo₂, hi₀, hi₁, hi₂)``, a
        ``SampleCloud`` (its positions' box) or an ``(n, 3)`` point array. The eye moves along the
        orbit direction until the box's corners, with ``margin``, just fit the view.
        """
        lo, hi = _bounds(bounds)
        azimuth, elevation = _angle(azimuth, "azimuth"), as_real(elevation, "elevation")
        fov = as_real(fov, "fov (field of view, degrees)")
        if not 0.0 < fov < 180.0:
            raise GeometryError(f"field of view must be in (0, 180) degrees, got {fov!r}")
        margin = as_real(margin, "margin")
        _projection(projection)
        center = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12 * max(1.0, float(np.max(np.abs(center)))))
        if not (0.0 < margin and radius * margin <= tol.COORDINATE_LIMIT):
            raise GeometryError(f"margin must be positive, and the box times it within ±{tol.COORDINATE_LIMIT:g}, "
                                f"got {margin!r}")
        radius *= margin
        _ = _size(width, "width"), _size(height, "height")
        half = math.radians(fov) / 2.0
        half_narrow = math.atan(math.tan(half) * min(1.0, width / height))
        dist = radius / math.sin(half_narrow)
        oh = 2.0 * radius * max(1.0, height / width)
        cam = cls.orbit(center, azimuth, elevation, dist, width, height, up=up, fov=fov, projection=projection,
                        ortho_height=oh)
        # tighten to the box's corners: the largest |screen coordinate| over the view's half extent
        corners = np.array([[(lo, hi)[a][0], (lo, hi)[b][1], (lo, hi)[c][2]]
                            for a in (0, 1) for b in (0, 1) for c in (0, 1)])

        def spill(d: float) -> float:
            c = cls.orbit(center, azimuth, elevation, d, width, height, up=up, fov=fov, projection=projection,
                          ortho_height=oh)
            px, z = c.project(corners)
            if projection == "perspective" and np.any(z <= 0.0):
                return math.inf
            ext = np.abs(px - [(width - 1) / 2.0, (height - 1) / 2.0]) / [width / 2.0, height / 2.0]
            return float(ext.max()) * float(margin)

        if projection == "perspective":
            lo_d, hi_d = 0.0, dist
            for _ in range(40):
                mid = 0.5 * (lo_d + hi_d)
                lo_d, hi_d = (lo_d, mid) if spill(mid) <= 1.0 else (mid, hi_d)
            return cls.orbit(center, azimuth, elevation, hi_d, width, height, up=up, fov=fov, projection=projection)
        return replace(cam, ortho_height=oh * max(spill(dist), 1e-12))

    # -- derived ---------------------------------------------------------------------------------
    @property
    def forward(self) -> np.ndarray:
        """Unit view direction : (3,) float64."""
        return self._frame[0].copy()

    @property
    def right(self) -> np.ndarray:
        """Unit screen-right direction : (3,) float64."""
        return self._frame[1].copy()

    @property
    def true_up(self) -> np.ndarray:
        """Unit screen-up direction (orthogonal to ``forward``) : (3,) float64."""
        return self._frame[2].copy()

    @property
    def distance(self) -> float:
        """Distance from the eye to the target."""
        return float(self._frame[3])

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(height, width)``."""
        return self.height, self.width

    @property
    def half_extents(self) -> tuple[float, float]:
        """``(tx, ty)``: half width and height of the image plane (at distance 1, or in world units)."""
        if self.projection == "perspective":
            ty = math.tan(math.radians(self.fov) / 2.0)
        else:
            ty = self.ortho_height / 2.0
        return ty * self.width / self.height, ty

    def params(self) -> np.ndarray:
        """Return the kernel layout : (20,) float64 (see ``CAMERA_FIELDS``)."""
        f, r, u, _ = self._frame
        tx, ty = self.half_extents
        ortho = float(self.projection == "orthographic")
        return np.concatenate([self.eye, f, r, u, [0.0, 0.0, tx, ty, self.width, self.height, ortho, 0.0]])

    def screen_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the screen coordinates of the pixel centres : X (W,), Y (H,) float64."""
        tx, ty = self.half_extents
        X = (2.0 * (np.arange(self.width) + 0.5) / self.width - 1.0) * tx
        Y = (1.0 - 2.0 * (np.arange(self.height) + 0.5) / self.height) * ty
        return X, Y

    def with_size(self, width: int, height: int) -> Camera:
        """Return the same view at another image size."""
        return replace(self, width=width, height=height)

    def orbited(self, d_azimuth: float = 0.0, d_elevation: float = 0.0, zoom: float = 1.0) -> Camera:
        """Return the camera turned around its target (degrees) and moved closer by ``zoom`` > 1.

        Azimuth turns about ``up``; the elevation is kept within ±89°.
        """
        up = self.up / np.linalg.norm(self.up)
        off = self.eye - self.target
        dist = float(np.linalg.norm(off))
        el = math.degrees(math.asin(max(-1.0, min(1.0, float(off @ up) / dist))))
        x, y = _plane_axes(up)
        az = math.degrees(math.atan2(float(off @ y), float(off @ x)))
        z = as_real(zoom, "zoom", finite=False)
        if not (math.isfinite(z) and z > 0.0):
            raise GeometryError(f"zoom must be positive and finite, got {zoom!r}")
        if not dist / z > 1e-12 * max(float(np.max(np.abs(self.target))), dist):
            raise GeometryError(f"zoom {zoom!r} would put the eye on the target (distance {dist:.3g}); zoom less")
        new_el = max(-89.0, min(89.0, el + _angle(d_elevation, "d_elevation")))
        return Camera.orbit(self.target, az + _angle(d_azimuth, "d_azimuth"), new_el, dist / z, self.width,
                            self.height,
                            up=self.up, fov=self.fov, projection=self.projection,
                            ortho_height=self.ortho_height / z)

    # -- numpy helpers (tests, pictures; the kernels use the same formulas) -------------------------
    def rays(self, rows=None, cols=None) -> tuple[np.ndarray, np.ndarray]:
        """Return ray origins and unit directions of pixels : two (n, 3) float64 arrays.

        rows, cols : (n,) int arrays (default: every pixel, row-major).
        """
        if rows is None and cols is None:
            rows, cols = (a.ravel() for a in np.indices(self.shape))
        rows, cols = _pixels(rows, "rows", self.height), _pixels(cols, "cols", self.width)
        if rows.shape != cols.shape:
            raise CsgnbError(f"rows and cols must have the same length, got {len(rows)} and {len(cols)}")
        X, Y = self.screen_axes()
        x = X[cols]
        y = Y[rows]
        f, r, u, _ = self._frame
        if self.projection == "perspective":
            d = f + x[:, None] * r + y[:, None] * u
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            return np.broadcast_to(self.eye, d.shape).copy(), d
        o = self.eye + x[:, None] * r + y[:, None] * u
        return o, np.broadcast_to(f, o.shape).copy()

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Return continuous pixel coordinates ``(col, row)`` and view depth of world points.

        points : (n, 3). Returns (n, 2) float64 (pixel centres are integers) and (n,) float64
        (distance along ``forward``; ≤ 0 behind the eye).
        """
        p = as_points(points, "points")
        if not np.all(np.isfinite(p)):
            raise GeometryError("points must be finite to be projected")
        p = p - self.eye
        f, r, u, _ = self._frame
        xc, yc, zc = p @ r, p @ u, p @ f
        tx, ty = self.half_extents
        if self.projection == "perspective":
            with np.errstate(divide="ignore", invalid="ignore"):
                xc, yc = xc / zc, yc / zc
        col = (xc / tx + 1.0) * (self.width / 2.0) - 0.5
        row = (1.0 - yc / ty) * (self.height / 2.0) - 0.5
        return np.column_stack([col, row]), zc

    def __repr__(self) -> str:
        e, t = np.round(self.eye, 4).tolist(), np.round(self.target, 4).tolist()
        extra = f"fov={self.fov:g}" if self.projection == "perspective" else f"ortho_height={self.ortho_height:g}"
        return f"Camera({self.projection}, {self.width}x{self.height}, eye={e}, target={t}, {extra})"


def _pixels(v, name: str, n: int) -> np.ndarray:
    """Return pixel indices ``v`` : (k,) int64 in [0, n), or raise naming the argument."""
    if v is None or isinstance(v, str | bytes):
        raise TypeError(f"{name} must be an array of pixel indices, got {type(v).__name__}")
    a = as_finite_array(v, None, name).reshape(-1)
    if np.any(a != np.round(a)) or (len(a) and (a.min() < 0 or a.max() >= n)):
        raise CsgnbError(f"{name} must hold integer pixel indices in [0, {n})")
    return a.astype(np.int64)


def _plane_axes(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return unit x, y spanning the plane ⟂ unit z (x = +x axis for z = +z)."""
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return x, np.cross(z, x)


def _bounds(bounds) -> tuple[np.ndarray, np.ndarray]:
    positions = getattr(bounds, "positions", None)
    if positions is not None:
        pts = np.asarray(positions, dtype=np.float64)
        if len(pts) == 0:
            raise GeometryError("cannot fit a camera to an empty cloud")
        return pts.min(axis=0), pts.max(axis=0)
    if bounds is None or isinstance(bounds, str | bytes):
        raise TypeError(f"bounds must be (lo, hi), a (6,) box, (n, 3) points or a SampleCloud, got "
                        f"{type(bounds).__name__}")
    try:
        arr = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"bounds must be (lo, hi), a (6,) box, (n, 3) points or a SampleCloud of numbers, got "
                        f"{bounds!r:.80}") from exc
    if arr.shape == (6,):
        lo, hi = arr[:3], arr[3:]
    elif arr.shape == (2, 3):
        lo, hi = arr[0], arr[1]
    elif arr.ndim == 2 and arr.shape[1] == 3 and len(arr) > 0:
        lo, hi = arr.min(axis=0), arr.max(axis=0)
    else:
        raise GeometryError(f"bounds must be (lo, hi), a (6,) box or (n, 3) points, got shape {arr.shape}")
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi >= lo)):
        raise GeometryError(f"bounds must be finite with lo <= hi, got {lo.tolist()}, {hi.tolist()}")
    if max(float(np.max(np.abs(lo))), float(np.max(np.abs(hi)))) > tol.COORDINATE_LIMIT:
        raise GeometryError(f"bounds reach beyond ±{tol.COORDINATE_LIMIT:g}; move the scene nearer the origin")
    return lo, hi
