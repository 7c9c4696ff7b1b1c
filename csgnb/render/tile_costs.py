"""Which screen tiles the splat renderer hands to the ray tracer: a measured cost model.

Splats win where few fragments cover a pixel; where many large splats overlap (a coarse cloud, a
close-up, a grazing view) a tile can cost more than ray tracing it. Per tile of the splat
renderer's binning both costs are estimated before the raster runs, and the cheaper path draws
the tile:

* splats: ``fragment`` ns per pixel of a binned splat's rectangle inside the tile (an upper bound
  on its fragments, summed by ``splats._tile_fragments``) plus ``item`` ns per binned splat;
* ray tracing: ``ray`` ns per pixel plus ``root`` ns per quadric root the reference ray tracer
  computes (:func:`csgnb.render.raytracer.trace_pixel` counts them), estimated by tracing every
  ``PROBE_STEP``-th pixel of the tile's rows and columns. Only tiles whose splat cost exceeds the
  cheapest possible ray tracing (one root per term per pixel) are probed.

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

__all__ = ["TileCosts", "TilePlan", "COSTS", "PROBE_STEP", "FALLBACKS", "plan_tiles"]

#: ``fallback=`` choices of the splat renderer: decide per tile, splats everywhere, ray tracing everywhere.
FALLBACKS = ("auto", "never", "always")

#: The probe traces one pixel in PROBE_STEP × PROBE_STEP (64 of a 64-pixel tile's 4,096).
PROBE_STEP = 8


@dataclass(frozen=True)
class TileCosts:
    """Nanoseconds per unit of work on one core (see the module docstring)."""

    fragment: float
    item: float
    ray: float
    root: float


#: Measured on this project's 2-core VM, one thread (``bench_render.py --calibrate``).
COSTS = TileCosts(fragment=3.1, item=240.0, ray=0.8, root=6.2)


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
               shape: tuple[int, int], n_terms: int, costs: TileCosts = COSTS) -> TilePlan:
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
    """
    H, W = shape
    ntiles = len(start) - 1
    ntx = (W + tile - 1) // tile
    t = np.arange(ntiles)
    rows = np.minimum((t // ntx) * tile + tile, H) - (t // ntx) * tile
    cols = np.minimum((t % ntx) * tile + tile, W) - (t % ntx) * tile
    pixels = (rows * cols).astype(np.float64)
    items = np.diff(start)
    splat_ns = costs.fragment * fragments + costs.item * items
    raytrace_ns = np.full(ntiles, np.nan)
    if mode == "never":
        return TilePlan(np.zeros(0, dtype=np.int64), fragments, items, splat_ns, raytrace_ns, 0)
    if mode == "always":
        return TilePlan(t.astype(np.int64), fragments, items, splat_ns, raytrace_ns, 0)
    floor = (costs.ray + costs.root * max(n_terms, 1)) * pixels
    candidates = np.flatnonzero(splat_ns > floor).astype(np.int64)
    if len(candidates) == 0:
        return TilePlan(candidates, fragments, items, splat_ns, raytrace_ns, 0)
    work = np.empty(len(candidates), dtype=np.int64)
    dummy_f = np.empty((H, W))
    dummy_i = np.empty((1, 1), dtype=np.int32)
    cam, X, Y, P, term_start, max_term = trace_args
    raytrace_tiles(cam, X, Y, P, term_start, max_term, np.array([tile, PROBE_STEP, 0], dtype=np.int64),
                   candidates, dummy_f, dummy_i, dummy_i, work)
    probed_px = np.maximum(_probe_count(rows[candidates], PROBE_STEP) * _probe_count(cols[candidates], PROBE_STEP), 1)
    per_px = costs.ray + costs.root * work / probed_px
    raytrace_ns[candidates] = per_px * pixels[candidates]
    chosen = candidates[raytrace_ns[candidates] < splat_ns[candidates]]
    return TilePlan(chosen, fragments, items, splat_ns, raytrace_ns, len(candidates))


def _probe_count(n: np.ndarray, step: int) -> np.ndarray:
    """Pixels ``step // 2, step // 2 + step, …`` below n: how many the probe traces along a side of n pixels."""
    return np.maximum((n - step // 2 + step - 1) // step, 0)
