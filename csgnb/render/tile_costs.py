"""Which screen tiles the splat renderer hands to the ray tracer: a measured cost model.

Splats win where few fragments cover a pixel; where many large splats overlap (a coarse cloud, a
close-up, a grazing view) a tile can cost more than ray tracing it. Per tile of the splat
renderer's binning both costs are estimated before the raster runs, and the cheaper path draws
the tile:

* splats: ``fragment`` ns per pixel of a binned splat's rectangle inside the tile (an upper bound
  on its fragments, summed by ``splats._tile_fragments``) plus ``item`` ns per binned splat; for a probed tile,
  only the rectangles that the raster's occlusion culling would not skip count, judged from the probe's depths
  (``splats._visible_fragments``: hidden layers cost the raster one test per splat);
* ray tracing: ``ray`` ns per pixel plus ``root`` ns per quadric root the reference ray tracer
  computes (:func:`csgnb.render.raytracer.trace_pixel` counts them), estimated by tracing every
  ``PROBE_STEP``-th pixel of the tile's rows and columns. Only tiles whose splat cost exceeds the
  cheapest possible ray tracing (one root per term per pixel) are probed.

Before any of that, the whole frame: a cloud of many small splats seen small costs ``splat`` ns per
splat in the footprint and binning passes whatever their fragments; when ray tracing the whole
frame (probed at one pixel in ``FRAME_PROBE_STEP``²) costs less, the frame is ray traced
(:func:`raytrace_is_cheaper`).

Both paths solve the same per-pixel equation with the same instructions
(:mod:`csgnb.render.rays`), so a ray-traced tile shows the reference ray tracer's pixels; the
choice changes the speed, not the picture (up to the one-pixel feature-edge disagreements that
``csgnb.render.agreement`` explains). The constants below were measured on one thread with
``benchmarks/bench_render.py --calibrate`` (a least-squares fit over the Table 2 models' frames);
only their ratios matter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.render.raytracer import raytrace_tiles

__all__ = [
    "TileCosts", "TilePlan", "COSTS", "PROBE_STEP", "FRAME_PROBE_STEP", "FALLBACKS", "plan_tiles",
    "raytrace_is_cheaper",
]

#: ``fallback=`` choices of the splat renderer: decide per tile, splats everywhere, ray tracing everywhere.
FALLBACKS = ("auto", "never", "always")

#: The probe traces one pixel in PROBE_STEP × PROBE_STEP (64 of a 64-pixel tile's 4,096).
PROBE_STEP = 8

#: The whole-frame probe traces one pixel in FRAME_PROBE_STEP × FRAME_PROBE_STEP.
FRAME_PROBE_STEP = 16


@dataclass(frozen=True)
class TileCosts:
    """Nanoseconds per unit of work on one core (see the module docstring)."""

    fragment: float
    item: float
    ray: float
    root: float
    splat: float


#: Measured on this project's 2-core VM, one thread (``bench_render.py --calibrate``; splat fragments as the planner
#: counts them, after occlusion culling).
COSTS = TileCosts(fragment=5.3, item=267.0, ray=8.0, root=7.75, splat=125.0)


@dataclass(frozen=True)
class TilePlan:
    """The tiles to ray trace and the estimates behind the choice.

    raytraced : (m,) int64 — tile indices (row-major, ``ntx`` across).
    fragments, items : (ntiles,) int64 — splat-rectangle pixels and binned splats per tile.
    splat_ns, raytrace_ns : (ntiles,) float64 — estimated costs; ``raytrace_ns`` is NaN where the
        tile was not probed (its splats were cheaper than any ray tracing could be).
    probed : int — tiles probed.
    """

    raytraced: np.ndarray
    fragments: np.ndarray
    items: np.ndarray
    splat_ns: np.ndarray
    raytrace_ns: np.ndarray
    probed: int


def plan_tiles(mode: str, trace_args: tuple, fragments: np.ndarray, start: np.ndarray, tile: int,
               shape: tuple[int, int], n_terms: int, costs: TileCosts = COSTS, visible=None,
               probe_all: bool = False) -> TilePlan:
    """Return the tiles the splat renderer ray traces instead of splatting.

    Parameters
    ----------
    mode : "auto", "never" or "always"
    trace_args : tuple
        ``(cam, X, Y, P, term_start, max_term)`` of :func:`csgnb.render.raytracer.raytrace_tiles`.
    fragments : (ntiles,) int64
        Splat-rectangle pixels per tile.
    start : (ntiles + 1,) int64
        The binning's offsets (splats per tile = ``np.diff(start)``).
    tile : int
        Tile edge in pixels; ``shape`` (H, W) the image.
    n_terms : int
        Intersection terms of the normal form (every ray computes at least one root per term).
    visible : callable, optional
        ``visible(probe_depth, tiles) -> (len(tiles),) int64``: the splat-rectangle pixels of the listed tiles that
        the raster's occlusion culling would not skip, given the probe's depths (an (H, W) float64 buffer holding
        the visible depth at every probed pixel, ∞ where the ray missed). Probed tiles are then costed with these
        instead of ``fragments`` (hidden layers cost the raster one test per splat, not a test per pixel).
    probe_all : bool
        Probe every tile (not only those whose splats could cost more than ray tracing) and choose nothing:
        the estimates of every tile, for calibration.
    """
    ntiles = len(start) - 1
    t = np.arange(ntiles)
    rows, cols = _tile_sides(shape, tile)
    pixels = (rows * cols).astype(np.float64)
    items = np.diff(start)
    splat_ns = costs.fragment * fragments + costs.item * items
    raytrace_ns = np.full(ntiles, np.nan)
    if mode == "never":
        return TilePlan(np.zeros(0, dtype=np.int64), fragments, items, splat_ns, raytrace_ns, 0)
    if mode == "always":
        return TilePlan(t.astype(np.int64), fragments, items, splat_ns, raytrace_ns, 0)
    floor = (costs.ray + costs.root * max(n_terms, 1)) * pixels
    candidates = t.astype(np.int64) if probe_all else np.flatnonzero(splat_ns > floor).astype(np.int64)
    if len(candidates) == 0:
        return TilePlan(candidates, fragments, items, splat_ns, raytrace_ns, 0)
    probe_depth = np.empty(shape) if visible is not None else None
    per_px = costs.ray + costs.root * _roots_per_pixel(trace_args, shape, tile, candidates, PROBE_STEP, probe_depth)
    raytrace_ns[candidates] = per_px * pixels[candidates]
    if visible is not None:
        fragments = fragments.copy()
        fragments[candidates] = visible(probe_depth, candidates)
        splat_ns = costs.fragment * fragments + costs.item * items
    chosen = candidates[raytrace_ns[candidates] < splat_ns[candidates]]
    if probe_all:
        chosen = chosen[:0]
    return TilePlan(chosen, fragments, items, splat_ns, raytrace_ns, len(candidates))


def raytrace_is_cheaper(trace_args: tuple, shape: tuple[int, int], tile: int, n_splats: int, n_terms: int,
                        costs: TileCosts = COSTS) -> bool:
    """Return whether ray tracing the whole frame costs less than the splats' per-splat passes (``splat`` ns each).

    Probes the frame (one pixel in ``FRAME_PROBE_STEP``²) only when even the cheapest ray tracing (one root per
    term per pixel) could win.
    """
    H, W = shape
    budget = costs.splat * n_splats
    if (costs.ray + costs.root * max(n_terms, 1)) * H * W >= budget:
        return False
    rows, cols = _tile_sides(shape, tile)
    tiles = np.arange(len(rows), dtype=np.int64)
    roots = np.sum(_roots_per_pixel(trace_args, shape, tile, tiles, FRAME_PROBE_STEP) * rows * cols)
    return costs.ray * H * W + costs.root * roots < budget


def _roots_per_pixel(trace_args: tuple, shape: tuple[int, int], tile: int, tiles: np.ndarray, step: int,
                     depth: np.ndarray | None = None) -> np.ndarray:
    """Trace one pixel in step² of each listed tile (writing its visible depth into ``depth`` (H, W) if given,
    nothing else); return the mean roots per traced pixel."""
    work = np.empty(len(tiles), dtype=np.int64)
    rows, cols = _tile_sides(shape, tile)
    write = 2 if depth is not None else 0  # 2: the depth only
    no_image = np.empty((1, 1), dtype=np.int32)  # a probe never writes the quadric and term buffers
    raytrace_tiles(*trace_args, np.array([tile, step, write], dtype=np.int64), tiles,
                   depth if depth is not None else np.empty(shape), no_image, no_image, work)
    return work / np.maximum(_probe_count(rows[tiles], step) * _probe_count(cols[tiles], step), 1)


def _tile_sides(shape: tuple[int, int], tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the rows and columns of every tile : two (ntiles,) int64 (the last row and column of tiles are cut)."""
    H, W = shape
    ntx, nty = (W + tile - 1) // tile, (H + tile - 1) // tile
    t = np.arange(ntx * nty)
    rows = np.minimum((t // ntx) * tile + tile, H) - (t // ntx) * tile
    cols = np.minimum((t % ntx) * tile + tile, W) - (t % ntx) * tile
    return rows, cols


def _probe_count(n: np.ndarray, step: int) -> np.ndarray:
    """Pixels ``step // 2, step // 2 + step, …`` below n: how many the probe traces along a side of n pixels."""
    return np.maximum((n - step // 2 + step - 1) // step, 0)
