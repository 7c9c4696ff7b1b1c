"""Level of detail for the splat renderer: per view, the cloud whose splats are about a target size on screen.

The paper samples for a target pixel size. A cloud sampled finely for a close-up costs more than it needs from
far away: its splats are a pixel or two wide, and the per-splat passes (footprints, binning) dominate the frame,
while a coarser cloud of the same surface covers the same pixels with far fewer splats. Every cloud the sampler
makes carries the coverage guarantee at its own radius, and the renderer's local quadric ray tracing and clipping
make the picture from the surface, not from the samples: **any level gives the reference image, pixel for
pixel** -- only the time differs.

:class:`LevelsOfDetail` keeps the given cloud (level 0, radius r) and, sampled on first use from the cloud's own
normal form and bounds, clouds of radius ``r · √2^k``: coarser (k > 0) up to the model's size and, with
``finer=True``, finer (k < 0) while the estimated sample count (``len(cloud) · 2^-k``) stays within
:data:`FINER_MAX_SAMPLES`. Finer levels are off by default: where a coarse cloud's splats are large on screen the
renderer already ray traces the tiles they would make expensive, and at 1920×1080 finer levels were slower on three
of the four Table 2 models that reached them (1.1-2.4x; ``bench_render.py``'s lod column); they won on the
80-quadric plate's coarsest cloud at 640×480 (~25 %). For a camera it picks the
coarsest level whose splat radius is at most :data:`TARGET_FOOTPRINT_PX` pixels at the depth of the cloud's centre.
The levels sampled on the way are kept, the given cloud and the :data:`KEPT_LEVELS` used last. The target was
measured (``bench_render.py``'s viewer rows; chapter 08): on the 80-quadric
plate at 640×480 the frame time against the splat radius on screen is flat from ~8 to ~20 px and grows on both
sides -- below, the per-splat passes; above, fragments and ray-traced tiles.

Where the size rule asks for a finer level than the cloud, which one draws faster depends on the model: a coarse
cloud whose large splats are mostly clipped (the 80-quadric plate's "large", 229 -> 103 ms at 1920×1080 with the
finer level) against one whose splats are used whole (the 31-quadric block's "large", 70 -> 89 ms). The pictures
are the same, so :class:`LevelChooser` (the notebook viewer's) decides by measurement: it draws each candidate
(the given cloud and the finer level) for a few frames and keeps the faster.
"""

from __future__ import annotations

import math
import numbers
import time

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric.arguments import as_count, as_finite_array, as_flag, as_instance, as_positive
from csgnb.render.camera import Camera
from csgnb.render.scene import check_camera

__all__ = ["FINER_MAX_SAMPLES", "LEVEL_STEP", "TARGET_FOOTPRINT_PX", "LevelChooser", "LevelsOfDetail",
           "footprint_pixels"]

#: Splat radius on screen (pixels, at the depth of the cloud's centre) that levels are chosen for.
TARGET_FOOTPRINT_PX = 12.0
#: Ratio of the splat radii of consecutive levels.
LEVEL_STEP = math.sqrt(2.0)
#: Coarsest level: r · √2^16 = 256 r (a level stops earlier where its radius passes the model's half-diagonal).
MAX_LEVEL = 16
#: Finer levels than the given cloud only while their estimated sample count stays within this (sampling 500,000
#: samples of the 80-quadric plate takes ~0.3 s once; drawing them ~60 ms a frame at 640×480).
FINER_MAX_SAMPLES = 500_000
#: Sampled levels kept besides the given cloud (the least recently used is dropped).
KEPT_LEVELS = 4


def footprint_pixels(camera: Camera, radius: float, point) -> float:
    """Radius in pixels on screen of a sphere of world radius ``radius`` at ``point`` (3,) seen by ``camera``.

    Perspective: ``radius · height / (2 · depth · tan(fov / 2))`` with ``depth`` the distance of ``point`` from the
    eye along the view direction (``inf`` when the point is at or behind the eye); orthographic:
    ``radius · height / ortho_height``.
    """
    camera = check_camera(camera)
    radius = as_positive(radius, "radius")
    point = as_finite_array(point, (3,), "point")
    if camera.projection == "orthographic":
        return radius * camera.height / camera.ortho_height
    depth = float((point - camera.eye) @ camera.forward)
    if depth <= 0.0:
        return math.inf
    return radius * camera.height / (2.0 * depth * math.tan(math.radians(camera.fov) / 2.0))


class LevelsOfDetail:
    """Clouds of one CSG surface at splat radii ``r · √2^k`` (k = 0 is the given cloud), chosen per view.

    Parameters
    ----------
    cloud : SampleCloud
        Level 0. Coarser levels are sampled from ``cloud.normal_form`` in the bounds the cloud was sampled in
        (``cloud.bounds``) with the sampler's defaults, on first use, and kept.
    target_pixels : float
        Splat radius on screen that :meth:`level_for` aims at (default :data:`TARGET_FOOTPRINT_PX`).
    finer : bool
        Also offer levels finer than ``cloud`` (within :data:`FINER_MAX_SAMPLES` estimated samples). Default False.

    ``levels`` maps each level kept to its cloud; ``seconds`` each level sampled so far to the time it took.
    ``min_level`` ≤ 0 ≤ ``max_level`` bound the levels.
    """

    def __init__(self, cloud, *, target_pixels: float = TARGET_FOOTPRINT_PX, finer: bool = False) -> None:
        from csgnb.sampling.cloud import SampleCloud

        # Type and size only: the renderer validates the arrays when it draws (a full check_cloud costs ~0.2 s on
        # 615,642 samples, and every SplatRenderer already does it).
        if not isinstance(cloud, SampleCloud):
            raise TypeError(f"expected a csgnb.sampling.SampleCloud (from sample_csg), got {type(cloud).__name__}")
        if len(cloud) == 0:
            raise GeometryError("the sample cloud is empty: there is nothing to draw at any level of detail")
        target = as_positive(target_pixels, "target_pixels")
        finer = as_flag(finer, "finer")
        self.cloud = cloud
        self.target_pixels = target
        lo, hi = cloud.positions.min(axis=0), cloud.positions.max(axis=0)
        self.center = 0.5 * (lo + hi)
        self.levels: dict[int, object] = {0: cloud}
        self.seconds: dict[int, float] = {0: 0.0}
        # Beyond the model's half-diagonal a splat covers the whole model: no coarser level can help.
        half_diagonal = 0.5 * float(np.linalg.norm(hi - lo))
        self.max_level = 0
        while self.max_level < MAX_LEVEL and self.radius(self.max_level + 1) <= max(half_diagonal, cloud.radius):
            self.max_level += 1
        self.min_level = 0
        while finer and len(cloud) * 2.0 ** (1 - self.min_level) <= FINER_MAX_SAMPLES:
            self.min_level -= 1

    def radius(self, level: int) -> float:
        """Splat radius of ``level`` (world units)."""
        return float(self.cloud.radius) * LEVEL_STEP**level

    def level_for(self, camera: Camera) -> int:
        """The coarsest level in ``min_level..max_level`` whose splats are at most ``target_pixels`` wide (radius)
        on screen at the depth of the cloud's centre; ``min_level`` where even that one's are larger, 0 where the
        centre is at or behind the eye."""
        px = footprint_pixels(check_camera(camera), float(self.cloud.radius), self.center)
        if not math.isfinite(px):
            return 0
        # px · √2^k ≤ target  ⇔  k ≤ 2 log2(target / px)
        level = int(math.floor(2.0 * math.log2(self.target_pixels / px) + 1e-9))
        return max(self.min_level, min(level, self.max_level))

    def cloud_at(self, level: int):
        """The cloud of ``level``, sampled now if it is not yet (``csgnb.sampling.sample_csg`` of the cloud's normal
        form at ``radius(level)`` in ``cloud.bounds``)."""
        from csgnb.sampling import sample_csg

        if isinstance(level, bool | np.bool_) or not isinstance(level, numbers.Integral):
            raise TypeError(f"level must be an integer, got {type(level).__name__} {level!r:.40}")
        level = int(level)
        if not self.min_level <= level <= self.max_level:
            raise CsgnbError(f"level must be in {self.min_level}..{self.max_level} for this cloud, got {level}")
        hit = self.levels.pop(level, None)
        if hit is None:
            t0 = time.perf_counter()
            hit = sample_csg(self.cloud.normal_form, self.radius(level), bounds=self.cloud.bounds)
            self.seconds[level] = time.perf_counter() - t0
        self.levels[level] = hit  # the most recently used last
        for old in [k for k in self.levels if k != 0][: max(0, len(self.levels) - 1 - KEPT_LEVELS)]:
            del self.levels[old]
        return hit

    def cloud_for(self, camera: Camera):
        """The cloud to draw for ``camera``: ``cloud_at(level_for(camera))``."""
        return self.cloud_at(self.level_for(camera))


class LevelChooser:
    """The level of detail to draw per view, measured where the size rule leaves a choice.

    For a camera, ``levels.level_for(camera)`` is the size rule's level; when it is finer than the given cloud
    (k < 0), the given cloud (k = 0) is the other candidate. Each candidate is drawn ``trials`` times (coarser
    first), then the one with the lower median of its last ``keep`` recorded frame times is drawn, and keeps being
    measured. The measurements start afresh when the candidates change (a zoom). Every level draws the same
    picture (see the module docstring), so the choice changes the frame time only.

    Parameters
    ----------
    levels : LevelsOfDetail
        Usually with ``finer=True`` (otherwise there is never a choice to measure).
    trials : int
        Frames per candidate before choosing (default 2).
    keep : int
        Frame times kept per level (default 3).
    """

    def __init__(self, levels: LevelsOfDetail, *, trials: int = 2, keep: int = 3) -> None:
        self.levels = as_instance(levels, LevelsOfDetail, "levels", "a csgnb.render.LevelsOfDetail")
        self.trials = as_count(trials, "trials", 1)
        self.keep = max(as_count(keep, "keep", 1), self.trials)
        self.candidates: tuple[int, ...] = ()
        self.times: dict[int, list[float]] = {}

    def choose(self, camera: Camera) -> int:
        """The level to draw for ``camera`` (record its frame time with :meth:`record`)."""
        level = self.levels.level_for(camera)
        candidates = (0, level) if level < 0 else (level,)
        if candidates != self.candidates:
            self.candidates, self.times = candidates, {k: [] for k in candidates}
        if len(candidates) == 1:
            return level
        for k in candidates:
            if len(self.times[k]) < self.trials:
                return k
        return min(candidates, key=lambda k: (float(np.median(self.times[k])), -k))

    def record(self, level: int, ms: float) -> None:
        """Book a frame of ``level`` drawn in ``ms`` milliseconds (ignored for a level that is not a candidate)."""
        ms = as_positive(ms, "ms")
        if isinstance(level, bool | np.bool_) or not isinstance(level, numbers.Integral):
            raise TypeError(f"level must be an integer, got {type(level).__name__} {level!r:.40}")
        times = self.times.get(int(level))
        if times is not None:
            times.append(ms)
            del times[: max(0, len(times) - self.keep)]
