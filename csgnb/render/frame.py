"""A rendered frame: the buffers of one image, its statistics, re-shading, PNG and pyvista export."""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np

from csgnb.errors import CsgnbError
from csgnb.quadric.arguments import as_finite_array, as_flag, as_instance
from csgnb.render.camera import Camera
from csgnb.render.shading import (
    CLIP_COLORS,
    COLOR_MODES,
    Lighting,
    index_colors,
    overdraw_colors,
    quadric_colors,
    shade,
)

__all__ = ["Frame", "RenderStats"]


@dataclass(frozen=True)
class RenderStats:
    """Counters and timings of one frame.

    method : "splats" or "raytrace".
    covered : int — pixels showing a surface.
    fragments : int — fragment invocations (pixels inside a splat footprint; splats only).
    overdraw : float — fragments / covered pixels of the splatted tiles (the paper's overdraw factor).
    splats_drawn, splats_culled, splats_offscreen : int — splats rasterized, back-face culled,
        outside the view (splats only).
    ms : float — wall time of the whole call (setup, raster / trace, normals, shading).
    timings : dict — milliseconds per stage.
    raytraced_tiles, tiles : int — screen tiles the splat renderer ray traced (its cost model chose
        them, :mod:`csgnb.render.tile_costs`), of all tiles (splats only).
    """

    method: str
    covered: int
    fragments: int = 0
    overdraw: float = 0.0
    splats_drawn: int = 0
    splats_culled: int = 0
    splats_offscreen: int = 0
    ms: float = 0.0
    timings: dict = field(default_factory=dict)
    raytraced_tiles: int = 0
    tiles: int = 0


@dataclass(frozen=True, eq=False)
class Frame:
    """The buffers of one rendered image (row 0 at the top).

    camera : Camera.
    depth : (H, W) float64 — view-space depth z of the visible point (its distance from the
        image plane through the eye, along ``camera.forward``); +inf where empty.
    normal : (H, W, 3) float32 — unit outward normal of the visible quadric (eq. 4), 0 where empty.
    quadric : (H, W) int32 — normal-form index of the visible quadric, -1 where empty.
    term : (H, W) int32 — its intersection term, -1 where empty.
    rgb : (H, W, 3) uint8 — the shaded image.
    overdraw : (H, W) int32 — fragments per pixel (0 for the ray tracer).
    clip_count : (H, W) int32 — clip-set size of the visible splat (-1 where empty or ray traced).
    sample : (H, W) int32 — index of the visible splat's sample (-1 where empty or ray traced).
    stats : RenderStats.
    """

    camera: Camera
    depth: np.ndarray
    normal: np.ndarray
    quadric: np.ndarray
    term: np.ndarray
    rgb: np.ndarray
    overdraw: np.ndarray
    clip_count: np.ndarray
    sample: np.ndarray
    stats: RenderStats
    normal_form: object = None
    _palette: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(H, W)``."""
        return self.depth.shape

    @property
    def covered(self) -> np.ndarray:
        """Pixels that show a surface : (H, W) bool."""
        return self.quadric >= 0

    def points(self) -> np.ndarray:
        """Return the visible surface points of covered pixels : (k, 3) float64 (row-major order)."""
        rows, cols = np.nonzero(self.covered)
        o, v = self.camera.rays(rows, cols)
        # z is measured along forward: the unit ray reaches depth z at t = z / (v·f)
        return o + (self.depth[rows, cols] / (v @ self.camera.forward))[:, None] * v

    # -- colour ------------------------------------------------------------------------------------
    def shaded(self, color_by: str = "quadric", *, lit: bool = True, lighting: Lighting | None = None,
               palette=None) -> np.ndarray:
        """Return the frame shaded with another colour mode : (H, W, 3) uint8 (see ``COLOR_MODES``).

        ``palette`` (k, 3) in [0, 1] overrides the mode's colours (indexed by the mode's key).
        """
        lit = as_flag(lit, "lit")
        if lighting is not None:
            as_instance(lighting, Lighting, "lighting", "a csgnb.render.Lighting or None")
        key, pal, lit_mode = _key_and_palette(self, color_by, palette)
        cam = self.camera.params()
        X, Y = self.camera.screen_axes()
        return shade(cam, X, Y, self.normal, key, pal, lit=lit and lit_mode, lighting=lighting)

    def difference(self, other: Frame) -> np.ndarray:
        """Return an RGB picture of where ``other`` differs : (H, W, 3) uint8.

        Grey: both empty; white: same quadric and depth (relative 1e-9); red: a different quadric
        or depth; blue: covered here only; yellow: covered in ``other`` only (a hole here).
        """
        from csgnb.render.agreement import compare
        from csgnb.render.scene import check_frame

        return compare(self, check_frame(other, "other")).picture()

    # -- export ------------------------------------------------------------------------------------
    def png_bytes(self, rgb=None, fmt: str = "png") -> bytes:
        """Return the image (or ``rgb``) encoded as PNG (``fmt="jpeg"`` for a faster, lossy one)."""
        from PIL import Image

        from csgnb.render.scene import check_choice

        check_choice(fmt.lower() if isinstance(fmt, str) else fmt, ("png", "jpeg", "jpg"), "fmt")
        if rgb is not None:
            rgb = _as_rgb(rgb)
        buf = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(self.rgb if rgb is None else rgb)).save(
            buf, format=fmt.upper(), **({"quality": 90} if fmt.lower() in ("jpeg", "jpg") else {"compress_level": 1}))
        return buf.getvalue()

    def save_png(self, path, rgb=None) -> None:
        """Write the image (or ``rgb``, (H, W, 3) uint8) to ``path`` as PNG."""
        with open(path, "wb") as fh:
            fh.write(self.png_bytes(rgb))

    def to_pyvista(self, kind: str = "points"):
        """Return the buffers as a pyvista data set.

        kind="points": a ``PolyData`` of the visible surface points (where they are in the world,
        so the image sits in a pyvista scene), point data ``rgb`` (uint8, k × 3), ``normals``,
        ``quadric``, ``term``, ``depth``, ``overdraw``, ``clip_count``.
        kind="image": an ``ImageData`` of W × H × 1 points (row 0 at the top, y growing upwards in
        the image), point data as above for every pixel.
        """
        import pyvista as pv

        from csgnb.render.scene import check_choice

        check_choice(kind, ("points", "image"), "kind")
        names = ("quadric", "term", "depth", "overdraw", "clip_count")
        if kind == "points":
            mask = self.covered
            cloud = pv.PolyData(self.points())
            cloud.point_data["rgb"] = self.rgb[mask]
            cloud.point_data["normals"] = self.normal[mask]
            for name in names:
                cloud.point_data[name] = getattr(self, name)[mask]
            return cloud
        if kind == "image":
            H, W = self.shape
            img = pv.ImageData(dimensions=(W, H, 1))
            flip = slice(None, None, -1)  # VTK images start at the bottom row
            img.point_data["rgb"] = self.rgb[flip].reshape(-1, 3)
            img.point_data["normals"] = self.normal[flip].reshape(-1, 3)
            for name in names:
                img.point_data[name] = getattr(self, name)[flip].ravel()
            return img
        raise ValueError(f"kind must be 'points' or 'image', got {kind!r}")

    def __repr__(self) -> str:
        s = self.stats
        H, W = self.shape
        extra = f", {s.fragments} fragments, overdraw {s.overdraw:.2f}" if s.method == "splats" else ""
        return f"Frame({s.method}, {W}x{H}, {s.covered} covered pixels{extra}, {s.ms:.1f} ms)"


def _as_rgb(rgb) -> np.ndarray:
    """Return an image ``rgb`` : (H, W, 3) or (H, W) uint8, or raise naming the argument."""
    if isinstance(rgb, str | bytes) or not hasattr(rgb, "__len__"):
        raise TypeError(f"rgb must be an (H, W, 3) uint8 image, got {type(rgb).__name__}")
    try:
        arr = np.asarray(rgb)
    except ValueError as exc:
        raise TypeError(f"rgb must be an (H, W, 3) uint8 image, got a ragged {type(rgb).__name__}") from exc
    if arr.dtype != np.uint8:
        raise TypeError(f"rgb must be an (H, W, 3) uint8 image, got dtype {arr.dtype}")
    if not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] == 3)) or arr.size == 0:
        raise CsgnbError(f"rgb must be an (H, W, 3) uint8 image, got shape {arr.shape}")
    return arr


def _key_and_palette(frame: Frame, color_by: str, palette):
    from csgnb.render.scene import check_choice

    check_choice(color_by, COLOR_MODES, "color_by")
    q = frame.quadric
    empty = q < 0
    lit = True
    if color_by == "quadric":
        key, pal = q, (frame._palette if frame._palette is not None else quadric_colors(frame.normal_form))
    elif color_by == "quadric_id":
        key, pal = q, index_colors(int(q.max()) + 1)
    elif color_by == "term":
        key, pal = frame.term, index_colors(int(frame.term.max()) + 1)
    elif color_by == "clip_count":
        key, pal = np.where(empty, -1, np.clip(frame.clip_count, 0, 3)), CLIP_COLORS
    elif color_by == "overdraw":
        key, pal, lit = np.where(frame.overdraw > 0, np.minimum(frame.overdraw, 30), -1), overdraw_colors(30), False
    elif color_by == "normal":
        n = frame.normal
        lut = np.clip(0.5 + 0.5 * n.reshape(-1, 3).astype(np.float64), 0, 1)
        key, pal, lit = np.where(empty.ravel(), -1, np.arange(lut.shape[0])).reshape(q.shape), lut, False
    else:
        key, pal = np.where(empty, -1, 0), np.ones((1, 3))
    if palette is not None:
        pal = as_finite_array(palette, None, "palette")
        if pal.ndim != 2 or pal.shape[1] != 3 or np.any(pal < 0.0) or np.any(pal > 1.0):
            raise CsgnbError(f"palette must be (k, 3) colours in [0, 1], got shape {pal.shape}")
    if len(pal) == 0:
        pal = np.ones((1, 3))
    return np.ascontiguousarray(key, dtype=np.int32), pal, lit
