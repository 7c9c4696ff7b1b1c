"""The reference CSG ray tracer of §7.2: per pixel, per term, sorted quadric hits and 1D CSG.

For each pixel ray and each intersection term of the normal form (eq. 18) every quadric of the
term is intersected with the ray (:func:`csgnb.render.rays.ray_roots`), the hits with 0 < t <
(best so far) are sorted, and the term's inside count is followed along the ray starting from
the signs of the quadrics at the ray origin: the first hit where all m quadrics of the term are
entered is the term's first surface point. The nearest over the terms is the surface of the root
union seen from outside. No acceleration structure, as the paper's fragment-shader ray tracer;
two exact prunings only: hits behind the best point are dropped, and a term is skipped as soon as
one of its quadrics has no hit before the best point while the ray starts outside it.
"""

from __future__ import annotations

import math
import time

import numpy as np

from csgnb._jit import jit
from csgnb._threads import run_parts
from csgnb.quadric.arguments import as_flag
from csgnb.render.camera import Camera
from csgnb.render.frame import Frame, RenderStats
from csgnb.render.rays import inline_jit, quadric_rows, ray_polynomials, ray_roots
from csgnb.render.scene import as_normal_form, check_camera, check_choice, check_precision, scene_box
from csgnb.render.shading import COLOR_MODES, quadric_colors, shade, surface_normals

__all__ = ["raytrace", "raytrace_tiles", "trace_pixel", "tile_count", "RAYTRACE_TILE"]

#: Tile edge (pixels) of the parallel loop.
RAYTRACE_TILE = 16


@inline_jit
def trace_pixel(P, term_start, x, y, dd, hit_t, hit_k, inside):
    """Return ``(depth, quadric, term, roots)`` of the pixel ray (x, y): the nearest entry into a term.

    ``depth`` is +inf and ``quadric``, ``term`` are -1 where the ray meets nothing; ``roots`` counts the
    quadric intersections computed (the work, for the splat renderer's cost model). ``hit_t``, ``hit_k``
    (2·max term,) and ``inside`` (max term,) are scratch.
    """
    n_terms = term_start.shape[0] - 1
    best = math.inf
    bq = -1
    bt = -1
    roots = 0
    for a in range(n_terms):
        s0 = term_start[a]
        m = term_start[a + 1] - s0
        count = 0
        nh = 0
        possible = True
        for k in range(s0, s0 + m):
            t1, t2, gamma = ray_roots(P, k, x, y, dd)
            roots += 1
            ins = gamma < 0.0
            inside[k - s0] = ins
            if ins:
                count += 1
            found = False
            if t1 > 0.0 and t1 < best:
                hit_t[nh] = t1
                hit_k[nh] = k - s0
                nh += 1
                found = True
            if t2 > 0.0 and t2 < best:
                hit_t[nh] = t2
                hit_k[nh] = k - s0
                nh += 1
                found = True
            if not found and not ins:
                possible = False  # outside quadric k all the way to the best point
                break
        if not possible or count == m:
            continue  # count == m: the ray starts inside the term (views are from outside)
        # insertion sort by t (few hits per term and pixel)
        for h in range(1, nh):
            t = hit_t[h]
            kk = hit_k[h]
            g = h - 1
            while g >= 0 and hit_t[g] > t:
                hit_t[g + 1] = hit_t[g]
                hit_k[g + 1] = hit_k[g]
                g -= 1
            hit_t[g + 1] = t
            hit_k[g + 1] = kk
        for h in range(nh):
            kk = hit_k[h]
            if inside[kk]:
                inside[kk] = False
                count -= 1
            else:
                inside[kk] = True
                count += 1
                if count == m:
                    best = hit_t[h]
                    bq = s0 + kk
                    bt = a
                    break
    return best, bq, bt, roots


@jit(error_model="numpy")
def _raytrace_tiles_kernel(cam, X, Y, P, term_start, max_term, grid, tiles, depth, qid, tid, work, part, parts):
    """The listed tiles ``part``, ``part + parts``, ... of :func:`raytrace_tiles`."""
    H, W = depth.shape
    tile, step, write = grid[0], grid[1], grid[2]
    ntx = (W + tile - 1) // tile
    persp = cam[18] == 0.0
    hit_t = np.empty(2 * max_term)
    hit_k = np.empty(2 * max_term, dtype=np.int64)
    inside = np.empty(max_term, dtype=np.bool_)
    for n in range(part, tiles.shape[0], parts):
        i0 = (tiles[n] // ntx) * tile
        j0 = (tiles[n] % ntx) * tile
        roots = 0
        for i in range(i0 + step // 2, min(i0 + tile, H), step):
            for j in range(j0 + step // 2, min(j0 + tile, W), step):
                x, y = X[j], Y[i]
                dd = 1.0 + (x * x + y * y) if persp else 1.0
                best, bq, bt, r = trace_pixel(P, term_start, x, y, dd, hit_t, hit_k, inside)
                roots += r
                if write != 0:
                    depth[i, j] = best
                if write == 1:
                    qid[i, j] = bq
                    tid[i, j] = bt
        work[n] = roots


def raytrace_tiles(cam, X, Y, P, term_start, max_term, grid, tiles, depth, qid, tid, work) -> None:
    """Trace the pixels of the listed screen tiles, the tiles shared among ``numba.get_num_threads()`` threads.

    grid : (tile, step, write) int64 — tile edge in pixels (tile t covers rows ``(t // ntx) · tile``
    on, columns ``(t % ntx) · tile`` on, ntx = ⌈W / tile⌉); every ``step``-th pixel of a tile's rows
    and columns is traced (1: all of them; more: a probe of the tile's cost); ``write`` 0 leaves
    the buffers alone, 2 writes the depth only (``qid`` and ``tid`` may then be (1, 1)). tiles : (n,) int64.
    depth (view z), qid, tid : (H, W), written at the traced
    pixels. work : (n,) int64, set to the roots computed in ``tiles[n]``.
    """
    run_parts(_raytrace_tiles_kernel, cam, X, Y, P, term_start, max_term, grid, tiles, depth, qid, tid, work)


def tile_count(shape: tuple[int, int], tile: int) -> tuple[int, int]:
    """Return ``(ntx, nty)``: the tiles of ``tile`` pixels across and down an image of ``shape`` (H, W)."""
    H, W = shape
    return (W + tile - 1) // tile, (H + tile - 1) // tile


def raytrace(shape, camera: Camera, *, color_by: str = "quadric", lit: bool = True) -> Frame:
    """Return the reference ray-traced frame of a CSG object (§7.2).

    Parameters
    ----------
    shape : Node, Quadric, NormalForm or SampleCloud
        The object (a cloud stands for the normal form it was sampled from, so that quadric
        indices match its splat render).
    camera : Camera
        Seen from outside the object (a ray that starts inside a term does not see that term).
    color_by : str
        One of ``shading.COLOR_MODES`` (``clip_count`` and ``overdraw`` are empty here).

    Returns
    -------
    Frame
        depth, normal, quadric, term and rgb buffers; ``overdraw`` is zero, ``clip_count`` and
        ``sample`` are -1.
    """
    t0 = time.perf_counter()
    check_camera(camera)
    check_choice(color_by, COLOR_MODES, "color_by")
    lit = as_flag(lit, "lit")
    nf = as_normal_form(shape)
    check_precision(camera, *scene_box(shape))
    Q = quadric_rows(nf.quadrics)
    ts = np.ascontiguousarray(nf.term_start, dtype=np.int64)
    max_term = int(np.max(np.diff(ts))) if nf.n_terms else 1
    cam = camera.params()
    X, Y = camera.screen_axes()
    H, W = camera.shape
    depth = np.empty((H, W))
    qid = np.empty((H, W), dtype=np.int32)
    tid = np.empty((H, W), dtype=np.int32)
    t1 = time.perf_counter()
    P = ray_polynomials(cam, Q)
    ntx, nty = tile_count((H, W), RAYTRACE_TILE)
    work = np.empty(ntx * nty, dtype=np.int64)
    raytrace_tiles(cam, X, Y, P, ts, max(max_term, 1), np.array([RAYTRACE_TILE, 1, 1], dtype=np.int64),
                   np.arange(ntx * nty, dtype=np.int64), depth, qid, tid, work)
    t2 = time.perf_counter()
    normal = surface_normals(cam, X, Y, Q, depth, qid)
    palette = quadric_colors(nf)
    frame_kw = dict(overdraw=np.zeros((H, W), dtype=np.int32), clip_count=np.full((H, W), -1, dtype=np.int32),
                    sample=np.full((H, W), -1, dtype=np.int32))
    if color_by == "quadric":
        rgb = shade(cam, X, Y, normal, qid, palette, lit=lit)
        t3 = time.perf_counter()
        stats = RenderStats("raytrace", int(np.count_nonzero(qid >= 0)), ms=1e3 * (t3 - t0),
                            timings={"setup": 1e3 * (t1 - t0), "trace": 1e3 * (t2 - t1), "shade": 1e3 * (t3 - t2)})
        return Frame(camera, depth, normal, qid, tid, rgb, stats=stats, normal_form=nf, _palette=palette, **frame_kw)
    stub = Frame(camera, depth, normal, qid, tid, np.zeros((H, W, 3), np.uint8), stats=None, normal_form=nf,
                 _palette=palette, **frame_kw)
    rgb = stub.shaded(color_by, lit=lit)
    t3 = time.perf_counter()
    stats = RenderStats("raytrace", int(np.count_nonzero(qid >= 0)), ms=1e3 * (t3 - t0),
                        timings={"setup": 1e3 * (t1 - t0), "trace": 1e3 * (t2 - t1), "shade": 1e3 * (t3 - t2)})
    return Frame(camera, depth, normal, qid, tid, rgb, stats=stats, normal_form=nf, _palette=palette, **frame_kw)
