"""Normals from the depth buffer, Lambert / Blinn-Phong shading and colour palettes.

Both renderers end in the same two kernels: :func:`surface_normals` (the normal of eq. 4 at the
visible point ``p = o + t v`` of the pixel's quadric) and :func:`shade` (a base colour per pixel
from a palette indexed by a key buffer — quadric id, clip count, overdraw, ... — lit by a
headlight and a key light with Blinn-Phong highlights).
"""

from __future__ import annotations

import math

import numpy as np

from csgnb._jit import jit
from csgnb._threads import run_parts
from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric.arguments import as_count, as_instance, as_real
from csgnb.render.rays import ray_direction, ray_point, row_gradient

__all__ = [
    "COLOR_MODES",
    "BACKGROUND",
    "CLIP_COLORS",
    "quadric_colors",
    "overdraw_colors",
    "surface_normals",
    "shade",
    "Lighting",
]

#: ``color_by=`` choices: per-quadric colours (by surface, so one surface keeps its colour in
#: every term), a colour per quadric index, per term, by clip-set size (Figure 11d), by overdraw
#: (Figure 13), the normal as RGB, or plain white.
COLOR_MODES = ("quadric", "quadric_id", "term", "clip_count", "overdraw", "normal", "white")

#: Background colour (RGB in [0, 1]).
BACKGROUND = (0.30, 0.30, 0.30)

#: Figure 11d: white 0, green 1, orange 2, red 3 or more clip quadrics.
CLIP_COLORS = np.array([[1.0, 1.0, 1.0], [0.17, 0.63, 0.17], [1.0, 0.50, 0.05], [0.84, 0.15, 0.16]])

_TAB20 = np.array([
    [0.12, 0.47, 0.71], [1.00, 0.50, 0.05], [0.17, 0.63, 0.17], [0.84, 0.15, 0.16], [0.58, 0.40, 0.74],
    [0.55, 0.34, 0.29], [0.89, 0.47, 0.76], [0.50, 0.50, 0.50], [0.74, 0.74, 0.13], [0.09, 0.75, 0.81],
    [0.68, 0.78, 0.91], [1.00, 0.73, 0.47], [0.60, 0.87, 0.54], [1.00, 0.60, 0.59], [0.77, 0.69, 0.84],
    [0.77, 0.61, 0.58], [0.97, 0.71, 0.82], [0.78, 0.78, 0.78], [0.86, 0.86, 0.55], [0.62, 0.85, 0.90],
])  # fmt: skip


class Lighting:
    """Light parameters: ``ambient``, ``diffuse``, ``specular`` weights and the Blinn-Phong exponent
    ``shininess`` (rounded to a power of two, 1 … 1024)."""

    def __init__(self, ambient: float = 0.22, diffuse: float = 0.78, specular: float = 0.25,
                 shininess: float = 32.0) -> None:
        vals = {n: as_real(v, n) for n, v in (("ambient", ambient), ("diffuse", diffuse), ("specular", specular),
                                                ("shininess", shininess))}
        for n, v in vals.items():
            if v < 0.0:
                raise GeometryError(f"{n} must be ≥ 0, got {v}")
        self.ambient, self.diffuse, self.specular, self.shininess = (vals["ambient"], vals["diffuse"],
                                                                     vals["specular"], vals["shininess"])

    def array(self) -> np.ndarray:
        squarings = int(round(math.log2(min(max(float(self.shininess), 1.0), 1024.0))))
        return np.array([self.ambient, self.diffuse, self.specular, squarings], dtype=np.float64)


def quadric_colors(normal_form) -> np.ndarray:
    """Return a colour per quadric : (n, 3) float64 — by surface id, so shared surfaces match."""
    from csgnb.csg.normal_form import NormalForm

    as_instance(normal_form, NormalForm, "normal_form", "a csgnb.csg.NormalForm")
    sid = np.asarray(normal_form.surface, dtype=np.int64)
    return _TAB20[sid % len(_TAB20)].copy() if len(sid) else np.zeros((0, 3))


def index_colors(n: int) -> np.ndarray:
    """Return ``n`` distinct-looking colours : (n, 3) float64 (tab20, repeated)."""
    return _TAB20[np.arange(max(n, 1)) % len(_TAB20)].copy()


def overdraw_colors(top: int = 30) -> np.ndarray:
    """Return the Figure 13 ramp : (top + 1, 3) float64 — index 0 unused, green at 1, red at ``top``+."""
    top = as_count(top, "top", 2)
    if top > 1 << 16:
        raise CsgnbError(f"top must be at most {1 << 16} (a colour per overdraw count), got {top}")
    s = np.clip((np.arange(top + 1) - 1.0) / (top - 1.0), 0.0, 1.0)
    # green → yellow → red through the HSV hue
    hue = (1.0 - s) * (1.0 / 3.0)
    h6 = hue * 6.0
    x = 1.0 - np.abs(h6 % 2.0 - 1.0)
    rgb = np.where((h6 < 1.0)[:, None], np.column_stack([np.ones_like(x), x, 0 * x]),
                   np.column_stack([x, np.ones_like(x), 0 * x]))
    rgb[0] = 1.0
    return 0.15 + 0.85 * rgb


@jit(error_model="numpy")
def _normals_kernel(cam, X, Y, Q, depth, qid, normal, part, parts):
    """normal[i, j] = N(p) of quadric ``qid[i, j]`` at p = o + z d (eq. 4); zero where empty (rows of block
    ``part`` of ``parts``)."""
    H, W = depth.shape
    for i in range(H * part // parts, H * (part + 1) // parts):
        for j in range(W):
            k = qid[i, j]
            if k < 0:
                normal[i, j, 0] = 0.0
                normal[i, j, 1] = 0.0
                normal[i, j, 2] = 0.0
                continue
            px, py, pz = ray_point(cam, X[j], Y[i], depth[i, j])
            g0, g1, g2 = row_gradient(Q, k, px, py, pz)
            n2 = g0 * g0 + g1 * g1 + g2 * g2
            inv = 1.0 / math.sqrt(n2) if n2 > 0.0 else 0.0
            normal[i, j, 0] = g0 * inv
            normal[i, j, 1] = g1 * inv
            normal[i, j, 2] = g2 * inv


@jit(error_model="numpy")
def _shade_kernel(cam, X, Y, normal, key, palette, light, lit, background, rgb, part, parts):
    """rgb[i, j] = palette[key[i, j]] under a headlight and a key light (Blinn-Phong); rows of block ``part``."""
    H, W = key.shape
    # key light: up-left of the view direction, in world coordinates
    lx = -0.45 * cam[6] + 0.6 * cam[9] - 0.66 * cam[3]
    ly = -0.45 * cam[7] + 0.6 * cam[10] - 0.66 * cam[4]
    lz = -0.45 * cam[8] + 0.6 * cam[11] - 0.66 * cam[5]
    ln = 1.0 / math.sqrt(lx * lx + ly * ly + lz * lz)
    lx, ly, lz = lx * ln, ly * ln, lz * ln
    amb, dif, spe = light[0], light[1], light[2]
    shin = int(light[3])
    for i in range(H * part // parts, H * (part + 1) // parts):
        for j in range(W):
            c = key[i, j]
            if c < 0:
                for ch in range(3):
                    rgb[i, j, ch] = np.uint8(min(255.0, background[ch] * 255.0 + 0.5))
                continue
            c = min(c, palette.shape[0] - 1)
            f = 1.0
            s = 0.0
            if lit:
                dx, dy, dz, dd = ray_direction(cam, X[j], Y[i])
                inv = 1.0 / math.sqrt(dd)
                vx, vy, vz = dx * inv, dy * inv, dz * inv
                nx, ny, nz = normal[i, j, 0], normal[i, j, 1], normal[i, j, 2]
                if nx * vx + ny * vy + nz * vz > 0.0:  # seen from behind: light the side we see
                    nx, ny, nz = -nx, -ny, -nz
                head = max(0.0, -(nx * vx + ny * vy + nz * vz))
                key_l = max(0.0, nx * lx + ny * ly + nz * lz)
                f = amb + dif * (0.55 * head + 0.45 * key_l)
                hx, hy, hz = lx - vx, ly - vy, lz - vz
                hn = math.sqrt(hx * hx + hy * hy + hz * hz)
                if hn > 0.0 and key_l > 0.0:
                    c_h = max(0.0, (nx * hx + ny * hy + nz * hz) / hn)
                    for _ in range(shin):  # shininess 2^shin by squaring (pow costs an exp and a log)
                        c_h = c_h * c_h
                    s = spe * c_h
            for ch in range(3):
                v = palette[c, ch] * f + s
                rgb[i, j, ch] = np.uint8(max(0.0, min(255.0, v * 255.0 + 0.5)))


def surface_normals(cam: np.ndarray, X, Y, Q, depth, qid) -> np.ndarray:
    """Return unit outward normals at the visible points : (H, W, 3) float32 (zero where empty)."""
    out = np.empty(depth.shape + (3,), dtype=np.float32)
    run_parts(_normals_kernel, cam, X, Y, Q, depth, qid, out)
    return out


def shade(cam: np.ndarray, X, Y, normal, key, palette, *, lit: bool = True, lighting: Lighting | None = None,
          background=BACKGROUND) -> np.ndarray:
    """Return an RGB image : (H, W, 3) uint8.

    key : (H, W) int32 — palette row per pixel, negative for background; palette : (k, 3) in [0, 1].
    """
    if lighting is not None:
        as_instance(lighting, Lighting, "lighting", "a csgnb.render.Lighting or None")
    light = (lighting or Lighting()).array()
    out = np.empty(key.shape + (3,), dtype=np.uint8)
    run_parts(_shade_kernel, cam, X, Y, normal, np.ascontiguousarray(key, dtype=np.int32),
                  np.ascontiguousarray(palette, dtype=np.float64), light, bool(lit),
                  np.asarray(background, dtype=np.float64), out)
    return out
