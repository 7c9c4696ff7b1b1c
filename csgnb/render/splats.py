"""The splat renderer of §6: local quadric ray-tracing and clipping per fragment, tiled on the CPU.

A frame is four kernels, each a data-parallel loop that maps one-to-one onto a GPU pass (on the CPU the loops run
in parts on ``numba.get_num_threads()`` threads, :func:`csgnb._threads.run_parts`: the one-thread image, bit for bit):

1. ``_footprint_kernel`` (per splat): back-face culling and the splat's screen footprint — the
   bounding rectangle of its sphere (s, r) (the paper's screen-aligned quad) or the convex hull
   of its surface-aligned box (§6.1), as up to six screen vertices and a pixel rectangle;
2. ``_bin_splats``: splats → screen tiles (a counting sort: the tile's list of splat indices);
3. ``_raster_kernel`` (per tile): for every pixel of every footprint (a *fragment*)
   intersect the pixel ray with the splat's own quadric (eq. 5), keep the nearest root that lies
   within r of the sample, discard it if a quadric of its clip set is positive there, depth test;
4. normals and shading of the visible points (:mod:`.shading`).

Bounds (all conservative, derived here from the quadric, not from the sampler's internals). For a
sample s on Q with g = ∇Q(s) = 2(As + m) ≠ 0 and x = p − s, |x| ≤ r, p on Q:
``gᵀx + xᵀAx = 0``, so the height over the tangent plane is ``n·x = -xᵀAx / |g|`` ∈
``[-max(λ_max, 0), -min(λ_min, 0)] · r² / |g|`` (λ the eigenvalues of A): the surface-aligned box
of eq. 23, from the quadric instead of the distortion bound. And ``(p - e)·∇Q(p) ≥ (s - e)·g -
ρ r² - 2 ρ r |s - e|`` (ρ the spectral radius of A; ``v·g - 2ρr`` for an orthographic direction
v): when positive, every point of the splat faces away from the eye and the splat is culled — a
point seen from outside faces the eye, so culling never changes the image of an outside view.
"""

from __future__ import annotations

import math
import time
import weakref

import numpy as np

from csgnb._jit import jit
from csgnb._threads import run_parts, threads
from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric.arguments import as_count, as_flag
from csgnb.render.camera import Camera
from csgnb.render.cuda import DEVICES, check_against_cpu
from csgnb.render.cuda import available as cuda_available
from csgnb.render.cuda import raster as cuda_raster
from csgnb.render.frame import Frame, RenderStats
from csgnb.render.rays import EPS, disc_hit, ray_point, ray_polynomials, ray_roots, row_gradient, row_value
from csgnb.render.raytracer import raytrace_tiles
from csgnb.render.scene import check_camera, check_choice, check_cloud, check_precision, eye_inside, scene_box
from csgnb.render.shading import COLOR_MODES, quadric_colors, shade, surface_normals
from csgnb.render.tile_costs import FALLBACKS, PROBE_STEP, plan_tiles, raytrace_is_cheaper

__all__ = [
    "SplatRenderer", "render", "renderer_for", "FOOTPRINTS", "LOCAL_MODES", "TILE", "FOOTPRINT_MARGIN",
    "CLIP_TOLERANCE",
]

#: ``footprint=`` choices: the sphere's screen rectangle (§6 step 1) or the surface-aligned box (§6.1).
FOOTPRINTS = ("sphere", "box")

#: ``local=`` choices: flat discs on the tangent plane (classical splats, Figure 11a) or local
#: quadric ray-tracing (Figure 11b–c).
LOCAL_MODES = ("disc", "quadric")

#: Tile edge in pixels for binning and the parallel raster loop.
TILE = 64

#: Relative growth of every footprint (box extents, sphere radius): keeps the pixel-centre test
#: conservative against the rounding of projection and rays (≈1e-13 px) by a wide margin.
FOOTPRINT_MARGIN = 1e-7

#: A clip quadric discards a fragment when Q(p) > CLIP_TOLERANCE · κ, κ bounding |Q| over the
#: scene (sum of the absolute terms at the scene's largest coordinate). Rounding of p and of Q(p)
#: stays far below it, so a point exactly on a feature edge is not lost to rounding (a hole);
#: geometrically it admits points within ~1e-14 relative of the clip surface.
CLIP_TOLERANCE = 64.0 * EPS

_CHUNK = 1024

#: Edge in pixels of the raster's occlusion blocks: a splat behind every pixel of the blocks it touches is skipped
#: whole (its fragments would all fail the early depth test; the image is the same, the fragment count lower).
_BLOCK = 8


@jit(error_model="numpy")
def _prepare_kernel(Q, lam, pos, nrm, rad, ids, SD, part, parts):
    """Static per-splat data SD (n, 12): s, r, unit normal, |∇Q(s)|, box heights, ρ (block ``part`` of ``parts``)."""
    n = pos.shape[0]
    for k in range(n * part // parts, n * (part + 1) // parts):
        q = ids[k]
        sx, sy, sz, r = pos[k, 0], pos[k, 1], pos[k, 2], rad[k]
        g0, g1, g2 = row_gradient(Q, q, sx, sy, sz)
        gn = 2.0 * math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        rho = max(abs(lam[q, 0]), abs(lam[q, 1]))
        SD[k, 0], SD[k, 1], SD[k, 2], SD[k, 3] = sx, sy, sz, r
        if gn > 0.0:
            inv = 2.0 / gn
            SD[k, 4], SD[k, 5], SD[k, 6] = g0 * inv, g1 * inv, g2 * inv
            SD[k, 8] = max(-r, -max(lam[q, 1], 0.0) * r * r / gn)
            SD[k, 9] = min(r, -min(lam[q, 0], 0.0) * r * r / gn)
        else:  # a cone's apex: no tangent plane; the box becomes the cube around the ball
            SD[k, 4], SD[k, 5], SD[k, 6] = nrm[k, 0], nrm[k, 1], nrm[k, 2]
            SD[k, 8], SD[k, 9] = -r, r
        SD[k, 7] = gn
        SD[k, 10] = rho
        SD[k, 11] = 0.0


@jit(error_model="numpy", inline="always")
def _tangent_range(c, z, R):
    """Slopes (lo, hi) of the lines x = m z through the eye tangent to the disc (c, z), radius R; z > R."""
    d = z * z - R * R
    s = R * math.sqrt(max(c * c + d, 0.0))
    return (c * z - s) / d, (c * z + s) / d


@jit(error_model="numpy", inline="always")
def _to_camera(cam, x, y, z):
    """Return a world vector (x, y, z) in camera coordinates (right, up, forward)."""
    return (x * cam[6] + y * cam[7] + z * cam[8], x * cam[9] + y * cam[10] + z * cam[11],
            x * cam[3] + y * cam[4] + z * cam[5])


@jit(error_model="numpy")
def _footprint_kernel(cam, SD, footprint, cull, bbox, hull, nh, flag, zmin, part, parts):
    """Per splat: flag (0 drawn, 1 culled, 2 off screen), pixel rectangle, footprint hull, nearest depth (the chunks
    of ``_CHUNK`` splats ``part``, ``part + parts``, ...)."""
    n = SD.shape[0]
    W, H = cam[16], cam[17]
    ortho = cam[18] != 0.0
    # pixel coordinates: col = X · sx + cx, row = -Y · sy + cy (X, Y screen coordinates)
    sx, cx = 0.5 * W / cam[14], 0.5 * W - 0.5
    sy, cy = 0.5 * H / cam[15], 0.5 * H - 0.5
    # a ball outside a side plane of the frustum (x = ±tx z, y = ±ty z through the eye) is off screen: its distance
    # (Sx - tx Sz) / √(1 + tx²) beyond R
    tx, ty = cam[14], cam[15]
    side_x, side_y = math.sqrt(1.0 + tx * tx), math.sqrt(1.0 + ty * ty)
    n_chunks = (n + _CHUNK - 1) // _CHUNK
    px = np.empty(8)
    py = np.empty(8)
    order = np.empty(8, dtype=np.int64)
    hx = np.empty(17)
    hy = np.empty(17)
    for c in range(part, n_chunks, parts):
        for k in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
            r = SD[k, 3]
            nx, ny, nz, gn = SD[k, 4], SD[k, 5], SD[k, 6], SD[k, 7]
            rho = SD[k, 10]
            nh[k] = 0
            bbox[k, 0], bbox[k, 1], bbox[k, 2], bbox[k, 3] = 0, 0, -1, -1
            ex, ey, ez = SD[k, 0] - cam[0], SD[k, 1] - cam[1], SD[k, 2] - cam[2]
            Sx, Sy, Sz = _to_camera(cam, ex, ey, ez)
            if cull and gn > 0.0:
                if ortho:
                    facing = gn * (cam[3] * nx + cam[4] * ny + cam[5] * nz)
                    bound = 2.0 * rho * r
                else:
                    facing = gn * (ex * nx + ey * ny + ez * nz)
                    bound = rho * r * (r + 2.0 * math.sqrt(ex * ex + ey * ey + ez * ez))
                if facing > bound * (1.0 + 1e-9):
                    flag[k] = 1
                    continue
            R = r * (1.0 + FOOTPRINT_MARGIN)
            zmin[k] = Sz - R
            if not ortho:
                if Sz + R <= 0.0:
                    flag[k] = 2
                    continue
                # outside the frustum: off screen (without this, a splat straddling the eye's plane beside the
                # camera took the whole screen: close-ups drew thousands of fragments per pixel)
                reach_x, reach_y = R * side_x, R * side_y
                if (Sx - tx * Sz > reach_x or -Sx - tx * Sz > reach_x or Sy - ty * Sz > reach_y
                        or -Sy - ty * Sz > reach_y):
                    flag[k] = 2
                    continue
            # the ball's screen rectangle first: it bounds every fragment (the raster keeps points within r of the
            # sample), so a ball between pixel centres -- most splats of a dense cloud seen small -- is dropped here,
            # and a box footprint is clipped to it
            if ortho:
                c_lo, c_hi = (Sx - R) * sx + cx, (Sx + R) * sx + cx
                r_lo, r_hi = cy - (Sy + R) * sy, cy - (Sy - R) * sy
            elif Sz - R <= 1e-9 * R:
                c_lo, c_hi, r_lo, r_hi = -1.0, W, -1.0, H  # the ball reaches the eye's plane: the whole screen
            else:
                m_lo, m_hi = _tangent_range(Sx, Sz, R)
                c_lo, c_hi = m_lo * sx + cx, m_hi * sx + cx
                m_lo, m_hi = _tangent_range(Sy, Sz, R)
                r_lo, r_hi = cy - m_hi * sy, cy - m_lo * sy
            j0 = max(int(math.ceil(max(c_lo, -1.0))), 0)
            i0 = max(int(math.ceil(max(r_lo, -1.0))), 0)
            j1 = min(int(math.floor(min(c_hi, W))), int(W) - 1)
            i1 = min(int(math.floor(min(r_hi, H))), int(H) - 1)
            if j1 < j0 or i1 < i0:
                flag[k] = 2
                continue
            if footprint == 1 and gn > 0.0:
                # surface-aligned box: tangents t1, t2 ⟂ n, heights [h0, h1] along n
                if abs(nx) < 0.6:
                    ax, ay, az = 0.0, nz, -ny
                else:
                    ax, ay, az = -nz, 0.0, nx
                an = 1.0 / math.sqrt(ax * ax + ay * ay + az * az)
                t1x, t1y, t1z = ax * an, ay * an, az * an
                t2x, t2y, t2z = ny * t1z - nz * t1y, nz * t1x - nx * t1z, nx * t1y - ny * t1x
                T1x, T1y, T1z = _to_camera(cam, t1x, t1y, t1z)
                T2x, T2y, T2z = _to_camera(cam, t2x, t2y, t2z)
                Nx, Ny, Nz = _to_camera(cam, nx, ny, nz)
                grow = FOOTPRINT_MARGIN * r
                h0, h1 = SD[k, 8] - grow, SD[k, 9] + grow
                near = False
                zlo = math.inf
                for v in range(8):
                    a = R if (v & 1) else -R
                    b = R if (v & 2) else -R
                    h = h1 if (v & 4) else h0
                    Cx = Sx + a * T1x + b * T2x + h * Nx
                    Cy = Sy + a * T1y + b * T2y + h * Ny
                    Cz = Sz + a * T1z + b * T2z + h * Nz
                    zlo = min(zlo, Cz)
                    if ortho:
                        px[v], py[v] = Cx * sx + cx, cy - Cy * sy
                    else:
                        if not Cz > 1e-9 * r:
                            near = True
                            break
                        inv = 1.0 / Cz
                        px[v], py[v] = Cx * inv * sx + cx, cy - Cy * inv * sy
                if not near:
                    zmin[k] = zlo
                    # convex hull (Andrew's monotone chain) of the 8 projected corners
                    for v in range(8):
                        order[v] = v
                    for v in range(1, 8):
                        w = order[v]
                        u = v - 1
                        while u >= 0 and (px[order[u]] > px[w] or (px[order[u]] == px[w] and py[order[u]] > py[w])):
                            order[u + 1] = order[u]
                            u -= 1
                        order[u + 1] = w
                    m = 0
                    for v0 in range(8):
                        w = order[v0]
                        while m >= 2 and ((hx[m - 1] - hx[m - 2]) * (py[w] - hy[m - 2])
                                          - (hy[m - 1] - hy[m - 2]) * (px[w] - hx[m - 2])) <= 0.0:
                            m -= 1
                        hx[m] = px[w]
                        hy[m] = py[w]
                        m += 1
                    lower = m + 1
                    for v0 in range(6, -1, -1):
                        w = order[v0]
                        while m >= lower and ((hx[m - 1] - hx[m - 2]) * (py[w] - hy[m - 2])
                                              - (hy[m - 1] - hy[m - 2]) * (px[w] - hx[m - 2])) <= 0.0:
                            m -= 1
                        hx[m] = px[w]
                        hy[m] = py[w]
                        m += 1
                    m -= 1  # the first point closes the chain
                    b_lo, b_hi, q_lo, q_hi = hx[0], hx[0], hy[0], hy[0]  # the hull's columns and rows
                    for v in range(1, m):
                        b_lo = min(b_lo, hx[v])
                        b_hi = max(b_hi, hx[v])
                        q_lo = min(q_lo, hy[v])
                        q_hi = max(q_hi, hy[v])
                    if 3 <= m <= 6:
                        nh[k] = m
                        for v in range(m):
                            hull[k, 2 * v] = hx[v]
                            hull[k, 2 * v + 1] = hy[v]
                    j0 = max(j0, int(math.ceil(max(b_lo, -1.0))))
                    i0 = max(i0, int(math.ceil(max(q_lo, -1.0))))
                    j1 = min(j1, int(math.floor(min(b_hi, W))))
                    i1 = min(i1, int(math.floor(min(q_hi, H))))
            if j1 < j0 or i1 < i0:
                flag[k] = 2
                continue
            flag[k] = 0
            bbox[k, 0], bbox[k, 1], bbox[k, 2], bbox[k, 3] = j0, i0, j1, i1


_BUCKETS = 4096


#: Chunks of the binning's passes (fixed: the result is the serial order whatever the number of threads).
_BIN_CHUNKS = 16


@jit(error_model="numpy")
def _bin_depths(flag, zmin, los, his, drawn, part, parts):
    """Per chunk of splats: the nearest depths' range and the drawn splats (chunks ``part``, ``part + parts``, ...)."""
    n = flag.shape[0]
    size = (n + _BIN_CHUNKS - 1) // _BIN_CHUNKS
    for c in range(part, _BIN_CHUNKS, parts):
        lo, hi, d = math.inf, -math.inf, 0
        for k in range(c * size, min(n, (c + 1) * size)):
            if flag[k] == 0:
                lo = min(lo, zmin[k])
                hi = max(hi, zmin[k])
                d += 1
        los[c], his[c], drawn[c] = lo, hi, d


@jit(error_model="numpy")
def _bin_buckets(flag, zmin, lo, scale, hist, order, scatter, part, parts):
    """Per chunk c of splats: count the drawn splats per depth bucket into ``hist[c]``, or with ``scatter`` (``hist[c]``
    then holds each bucket's first slot for the chunk) write them there, in splat order."""
    n = flag.shape[0]
    size = (n + _BIN_CHUNKS - 1) // _BIN_CHUNKS
    for c in range(part, _BIN_CHUNKS, parts):
        for k in range(c * size, min(n, (c + 1) * size)):
            if flag[k] == 0:
                b = int((zmin[k] - lo) * scale)
                if scatter:
                    order[hist[c, b]] = k
                hist[c, b] += 1


@jit(error_model="numpy")
def _bin_tiles(bbox, order, tile, ntx, count, items, scatter, part, parts):
    """Per chunk c of the depth order: count each tile's splats into ``count[c]``, or with ``scatter`` (``count[c]``
    then holds each tile's first slot for the chunk) write them there, in depth order."""
    drawn = order.shape[0]
    osize = (drawn + _BIN_CHUNKS - 1) // _BIN_CHUNKS
    for c in range(part, _BIN_CHUNKS, parts):
        for o in range(c * osize, min(drawn, (c + 1) * osize)):
            k = order[o]
            for ty in range(bbox[k, 1] // tile, bbox[k, 3] // tile + 1):
                for tx in range(bbox[k, 0] // tile, bbox[k, 2] // tile + 1):
                    t = ty * ntx + tx
                    if scatter:
                        items[count[c, t]] = k
                    count[c, t] += 1


def _first_slots(counts: np.ndarray) -> np.ndarray:
    """Exclusive prefix sums of ``counts`` (chunks, keys) laid out key-major, chunk-minor: every key's slots keep the
    chunks in order, so the output is the serial one. Returns (chunks, keys) int64; the total is ``counts.sum()``."""
    flat = counts.T.ravel()
    slots = np.cumsum(flat) - flat
    return np.ascontiguousarray(slots.reshape(counts.shape[::-1]).T)


def _bin_splats(bbox, flag, zmin, tile, ntx, nty, start, items) -> int:
    """Counting sort of the drawn splats into tiles, front to back within a tile (by nearest depth,
    in 4096 buckets): tile t holds items[start[t]:start[t + 1]]. Returns the pair count (if it
    exceeds ``items``, nothing is written: grow it and call again).

    Both sorts run over ``_BIN_CHUNKS`` chunks of splats, on the threads (:func:`csgnb._threads.run_parts`), with
    per-chunk counts; offsets are laid out key-major, chunk-minor, so every key's entries keep the serial
    (increasing splat, then increasing order) sequence: the output is the one-thread output, bit for bit."""
    nch = _BIN_CHUNKS
    parts = min(threads(), nch)
    los, his = np.full(nch, math.inf), np.full(nch, -math.inf)
    drawn_c = np.zeros(nch, dtype=np.int64)
    run_parts(_bin_depths, flag, zmin, los, his, drawn_c, parts=parts)
    lo, hi, drawn = float(los.min()), float(his.max()), int(drawn_c.sum())
    scale = (_BUCKETS - 1) / (hi - lo) if hi > lo else 0.0
    hist = np.zeros((nch, _BUCKETS), dtype=np.int64)
    order = np.empty(drawn, dtype=np.int32)
    run_parts(_bin_buckets, flag, zmin, lo, scale, hist, order, False, parts=parts)
    run_parts(_bin_buckets, flag, zmin, lo, scale, _first_slots(hist), order, True, parts=parts)
    count = np.zeros((nch, ntx * nty), dtype=np.int64)
    run_parts(_bin_tiles, bbox, order, tile, ntx, count, items, False, parts=parts)
    start[0] = 0
    np.cumsum(count.sum(axis=0), out=start[1:])
    total = int(start[-1])
    if total <= items.shape[0]:
        run_parts(_bin_tiles, bbox, order, tile, ntx, _first_slots(count), items, True, parts=parts)
    return total


@jit(error_model="numpy")
def _tile_fragments(bbox, start, items, tile, ntx, H, W, fragments, part, parts):
    """Per tile, the pixels of its splats' rectangles inside it (an upper bound on its fragments) : (ntiles,) int64
    (the tiles ``part``, ``part + parts``, ...)."""
    for t in range(part, start.shape[0] - 1, parts):
        ti0 = (t // ntx) * tile
        tj0 = (t % ntx) * tile
        ti1 = min(ti0 + tile, H) - 1
        tj1 = min(tj0 + tile, W) - 1
        f = 0
        for b in range(start[t], start[t + 1]):
            k = items[b]
            f += (min(bbox[k, 3], ti1) - max(bbox[k, 1], ti0) + 1) * (min(bbox[k, 2], tj1) - max(bbox[k, 0], tj0) + 1)
        fragments[t] = f


@jit(error_model="numpy")
def _visible_fragments(bbox, zmin, start, items, tiles, probe, tile, ntx, step, fragments, part, parts):
    """Per listed tile, the pixels of its splats' rectangles inside it that occlusion culling would not skip, judged
    from the probe's depths (``probe`` (H, W): the visible depth at the pixels ``step // 2 + k · step`` of the
    tile's rows and columns): a splat counts unless its nearest depth lies behind the largest probed depth of every
    _BLOCK-pixel block its rectangle touches (a block without a probed pixel counts as open). An estimate of the
    raster's fragments for the cost model (the raster judges with every pixel, as they are drawn)."""
    H, W = probe.shape
    nb = (tile + _BLOCK - 1) // _BLOCK
    pmax = np.empty(nb * nb)
    for n in range(part, tiles.shape[0], parts):
        t = tiles[n]
        ti0 = (t // ntx) * tile
        tj0 = (t % ntx) * tile
        ti1 = min(ti0 + tile, H) - 1
        tj1 = min(tj0 + tile, W) - 1
        for blk in range(nb * nb):
            pmax[blk] = -math.inf
        for i in range(ti0 + step // 2, ti1 + 1, step):
            for j in range(tj0 + step // 2, tj1 + 1, step):
                blk = ((i - ti0) // _BLOCK) * nb + (j - tj0) // _BLOCK
                pmax[blk] = max(pmax[blk], probe[i, j])
        for blk in range(nb * nb):
            if pmax[blk] == -math.inf:
                pmax[blk] = math.inf  # nothing probed there: open
        f = 0
        for b in range(start[t], start[t + 1]):
            k = items[b]
            i0, i1 = max(bbox[k, 1], ti0), min(bbox[k, 3], ti1)
            j0, j1 = max(bbox[k, 0], tj0), min(bbox[k, 2], tj1)
            zk = zmin[k]
            hidden = zk < math.inf
            for bi in range((i0 - ti0) // _BLOCK, (i1 - ti0) // _BLOCK + 1):
                for bj in range((j0 - tj0) // _BLOCK, (j1 - tj0) // _BLOCK + 1):
                    if not zk > pmax[bi * nb + bj]:
                        hidden = False
            if not hidden:
                f += (i1 - i0 + 1) * (j1 - j0 + 1)
        fragments[n] = f


@jit(error_model="numpy")
def _open_blocks(rows, cols, nb, blocks):
    """Start a tile of ``rows`` × ``cols`` pixels (all at depth ∞): every block open, its pixels in the image."""
    bopen, bmax, bdirty = blocks
    for bi in range(nb):
        for bj in range(nb):
            h = min((bi + 1) * _BLOCK, rows) - bi * _BLOCK
            w = min((bj + 1) * _BLOCK, cols) - bj * _BLOCK
            bopen[bi * nb + bj] = max(h, 0) * max(w, 0)
            bmax[bi * nb + bj] = math.inf
            bdirty[bi * nb + bj] = False


@jit(error_model="numpy")
def _hidden(zk, rect, origin, nb, blocks, depth):
    """Whether a splat whose nearest depth is ``zk`` is behind every pixel of the tile-local rectangle
    ``rect = (r0, r1, c0, c1)`` (rows r0..r1, columns c0..c1 of the tile at pixel ``origin = (ti0, tj0)``), so that
    each of its fragments would fail the early depth test. ``blocks = (bopen, bmax, bdirty)``: per block of the tile
    (``nb`` across), its pixels still at ∞, an upper bound on its depths, whether that bound is stale. Every block
    the rectangle touches is
    covered and its largest depth is below zk. A block's ``bmax`` only goes stale upwards (depths only decrease), so
    a stale bound that already rejects needs no recount; a dirty block is recounted when it decides."""
    if not zk < math.inf:  # NaN or infinite: leave it to the per-pixel test
        return False
    r0, r1, c0, c1 = rect
    ti0, tj0 = origin
    bopen, bmax, bdirty = blocks
    for bi in range(r0 // _BLOCK, r1 // _BLOCK + 1):
        for bj in range(c0 // _BLOCK, c1 // _BLOCK + 1):
            blk = bi * nb + bj
            if bopen[blk] > 0:
                return False
            if zk > bmax[blk]:
                continue
            if not bdirty[blk]:
                return False
            top = -math.inf
            for i in range(ti0 + bi * _BLOCK, min(ti0 + (bi + 1) * _BLOCK, depth.shape[0])):
                for j in range(tj0 + bj * _BLOCK, min(tj0 + (bj + 1) * _BLOCK, depth.shape[1])):
                    top = max(top, depth[i, j])
            bmax[blk] = top
            bdirty[blk] = False
            if not zk > top:
                return False
    return True


@jit(error_model="numpy")
def _written(li, lj, nb, old, blocks):
    """Book a depth write at tile-local pixel (li, lj) whose depth was ``old``: its block's bound is stale."""
    blk = (li // _BLOCK) * nb + lj // _BLOCK
    if old == math.inf:
        blocks[0][blk] -= 1
    blocks[2][blk] = True


@jit(error_model="numpy")
def _raster_kernel(cam, X, Y, P, Q, ctol, SD, SI, cidx, bbox, hull, nh, zmin, start, items, tile, ntx, skip, local,
                   clip, occlusion, rtol, depth, winner, qwin, qclip, qlast, zr1, zr2, od, part, parts):
    """Rasterize the binned footprints tile by tile: fragments, local ray-tracing, clipping, depth test.

    Two per-pixel memos skip fragments before any arithmetic without changing the image. A
    quadric's roots at a pixel do not depend on the splat, and neither does clipping (a clip
    quadric missing from a splat's clip set is negative within r of it, so such a root would fail
    that splat's distance test): once every root of q in (0, depth) is clipped at a pixel, no
    later fragment of q can change it. ``qwin[i, j]``: the visible quadric when that holds for it
    (its earlier root, if any, is clipped — for a hole's far wall, the second root, the near wall
    is); ``qclip[i, j]``: a quadric all of whose roots in (0, depth) are clipped there. And
    ``qlast``, ``zr1``, ``zr2`` keep the roots of the last quadric computed at each pixel: the
    overlapping splats of one surface reuse them. With ``occlusion``, a splat behind every pixel of the
    _BLOCK-pixel blocks its rectangle touches is skipped before any of its fragments (:func:`_hidden`; the splats come
    front to back, so the hidden layers of a tile mostly cost one test each). Tiles with ``skip[t]`` are left alone
    (ray traced instead).
    This call draws the tiles ``part``, ``part + parts``, ... (a stride spreads a crowded region over the threads).
    """
    H, W = depth.shape
    nty = (H + tile - 1) // tile
    persp = cam[18] == 0.0
    # hull edges of the current splat: y range, x at the lower y, dx/dy (no division per row)
    ey0 = np.empty(6)
    ey1 = np.empty(6)
    ex0 = np.empty(6)
    esl = np.empty(6)
    # the tile's blocks of _BLOCK × _BLOCK pixels: uncovered pixels, an upper bound on the depth, stale or not
    nb = (tile + _BLOCK - 1) // _BLOCK
    bopen = np.empty(nb * nb, dtype=np.int64)
    bmax = np.empty(nb * nb)
    bdirty = np.empty(nb * nb, dtype=np.bool_)
    blocks = (bopen, bmax, bdirty)
    for t in range(part, ntx * nty, parts):
        if skip[t]:
            continue
        ti0 = (t // ntx) * tile
        tj0 = (t % ntx) * tile
        ti1 = min(ti0 + tile, H) - 1
        tj1 = min(tj0 + tile, W) - 1
        _open_blocks(ti1 - ti0 + 1, tj1 - tj0 + 1, nb, blocks)
        for b in range(start[t], start[t + 1]):
            k = items[b]
            zk = zmin[k]
            i0, i1 = max(bbox[k, 1], ti0), min(bbox[k, 3], ti1)
            j0, j1 = max(bbox[k, 0], tj0), min(bbox[k, 2], tj1)
            if occlusion and _hidden(zk, (i0 - ti0, i1 - ti0, j0 - tj0, j1 - tj0), (ti0, tj0), nb, blocks, depth):
                continue
            sx, sy, sz, r = SD[k, 0], SD[k, 1], SD[k, 2], SD[k, 3]
            rr = (r + rtol) * (r + rtol)
            q, c0, cn = SI[k, 0], SI[k, 1], SI[k, 2]
            m = nh[k]
            ne = 0
            for e in range(m):
                xa, ya = hull[k, 2 * e], hull[k, 2 * e + 1]
                e1 = e + 1 if e + 1 < m else 0
                xb, yb = hull[k, 2 * e1], hull[k, 2 * e1 + 1]
                if ya == yb:
                    continue  # a horizontal edge: its end points belong to its neighbours
                if ya > yb:
                    xa, ya, xb, yb = xb, yb, xa, ya
                ey0[ne], ey1[ne], ex0[ne] = ya, yb, xa
                esl[ne] = (xb - xa) / (yb - ya)
                ne += 1
            for i in range(i0, i1 + 1):
                ja, jb = bbox[k, 0], bbox[k, 2]
                if m > 0:
                    # the hull's span on this row: min / max over the edges that straddle it
                    lo, hi = math.inf, -math.inf
                    yc = float(i)
                    for e in range(ne):
                        if ey0[e] <= yc <= ey1[e]:
                            x = ex0[e] + (yc - ey0[e]) * esl[e]
                            lo = min(lo, x)
                            hi = max(hi, x)
                    if hi < lo:
                        continue
                    ja = max(ja, int(math.ceil(lo)))
                    jb = min(jb, int(math.floor(hi)))
                y = Y[i]
                for j in range(max(ja, tj0), min(jb, tj1) + 1):
                    od[i, j] += 1
                    best = depth[i, j]
                    if zk > best or qwin[i, j] == q or qclip[i, j] == q:
                        continue  # early depth test; this quadric is resolved at this pixel
                    x = X[j]
                    if local == 0:  # a flat disc on the tangent plane
                        zz = disc_hit(cam, SD, k, x, y, best, rr)
                        if zz < math.inf:
                            _written(i - ti0, j - tj0, nb, best, blocks)
                            depth[i, j] = zz
                            winner[i, j] = k
                        continue
                    if qlast[i, j] == q:  # the roots of q here are known (bit for bit the same)
                        z1, z2 = zr1[i, j], zr2[i, j]
                    else:
                        dd = 1.0 + (x * x + y * y) if persp else 1.0
                        z1, z2, _ = ray_roots(P, q, x, y, dd)
                        qlast[i, j] = q
                        zr1[i, j] = z1
                        zr2[i, j] = z2
                    # done: every root of q in (0, new depth) is clipped here (splat-independent)
                    done = True
                    won = False
                    for root in range(2):
                        zz = z1 if root == 0 else z2
                        if not zz <= best:
                            break  # NaN or behind the visible point: the other root is too
                        if not zz > 0.0:
                            continue
                        if zz == best and not (winner[i, j] >= 0 and q < SI[winner[i, j], 0]):
                            continue  # a tie goes to the lower quadric index (the reference's term order)
                        px, py, pz = ray_point(cam, x, y, zz)
                        ex, ey, ez = px - sx, py - sy, pz - sz
                        if ex * ex + ey * ey + ez * ez > rr:
                            done = False  # beyond this splat's radius: another splat may take it
                            continue
                        ok = True
                        if clip:
                            for c in range(c0, c0 + cn):
                                kq = cidx[c]
                                if row_value(Q, kq, px, py, pz) > ctol[kq]:
                                    ok = False
                                    break
                        if ok:
                            _written(i - ti0, j - tj0, nb, best, blocks)
                            depth[i, j] = zz
                            winner[i, j] = k
                            won = True
                            break
                    if won:
                        qwin[i, j] = q if done else -1
                    elif done:
                        qclip[i, j] = q


@jit(error_model="numpy")
def _resolve_kernel(winner, SI, nrm, term_of, local, qid, tid, ccount, normal, part, parts):
    """Per pixel, from the visible splat: quadric, term, clip-set size (and the disc normal); rows of block ``part``."""
    H, W = winner.shape
    for i in range(H * part // parts, H * (part + 1) // parts):
        for j in range(W):
            k = winner[i, j]
            if k < 0:
                qid[i, j] = -1
                tid[i, j] = -1
                ccount[i, j] = -1
                continue
            q = SI[k, 0]
            qid[i, j] = q
            tid[i, j] = term_of[q]
            ccount[i, j] = SI[k, 2]
            if local == 0:
                normal[i, j, 0] = nrm[k, 0]
                normal[i, j, 1] = nrm[k, 1]
                normal[i, j, 2] = nrm[k, 2]


class SplatRenderer:
    """Render one SampleCloud from any camera; keeps the view-independent per-splat data.

    ``SplatRenderer(cloud).render(camera)`` is what :func:`render` does; build one when rendering
    many frames (the viewer, benchmarks) to prepare the cloud once.
    """

    def __init__(self, cloud) -> None:
        self.Q = check_cloud(cloud)
        self.cloud = cloud
        nf = cloud.normal_form
        self.normal_form = nf
        n = len(cloud.positions)
        lam = np.array([[q.eigenvalues[0], q.eigenvalues[-1]] for q in nf.quadrics], dtype=np.float64)
        self.SD = np.empty((n, 12))
        run_parts(_prepare_kernel, self.Q, lam, np.ascontiguousarray(cloud.positions, dtype=np.float64),
                  np.ascontiguousarray(cloud.normals, dtype=np.float64),
                  np.ascontiguousarray(cloud.radii, dtype=np.float64),
                  np.ascontiguousarray(cloud.quadric_ids, dtype=np.int32), self.SD)
        self.SI = np.ascontiguousarray(np.column_stack([cloud.quadric_ids, cloud.clip_start, cloud.clip_count]),
                                       dtype=np.int32)
        self.cidx = np.ascontiguousarray(cloud.clip_indices, dtype=np.int32)
        if len(self.cidx) == 0:
            self.cidx = np.zeros(1, dtype=np.int32)
        self.term_of = np.ascontiguousarray(nf.term_of, dtype=np.int32)
        self.term_start = np.ascontiguousarray(nf.term_start, dtype=np.int64)
        self.max_term = max(int(np.max(np.diff(self.term_start))) if nf.n_terms else 1, 1)
        self.normals = np.ascontiguousarray(cloud.normals, dtype=np.float64)
        self.palette = quadric_colors(nf)
        self.extent = float(np.max(np.abs(cloud.positions)) + np.max(cloud.radii))
        self._scene = scene_box(cloud)
        # scratch, reused across frames
        self._hull = np.empty((n, 12))
        self._bbox = np.empty((n, 4), dtype=np.int32)
        self._nh = np.empty(n, dtype=np.int32)
        self._flag = np.empty(n, dtype=np.int8)
        self._zmin = np.empty(n)
        self._items = np.empty(2 * n + 1024, dtype=np.int32)
        self._memo = None
        self.last_plan = None
        self.last_bins = None
        self._device_checked = False  # the first GPU frame is checked against the CPU's

    def splat_boxes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Return each splat's surface-aligned box (§6.1, eq. 23): centres (n, 3), unit normals (n, 3), radii (n,)
        and heights (n, 2) float64, the range of ``n · (p - s)`` over the points p of the splat's quadric within r
        of its sample s (``[-max(λ_max, 0), -min(λ_min, 0)] · r² / |∇Q(s)|``, clamped to ±r). The box is
        ``s + a t₁ + b t₂ + h n`` with |a|, |b| ≤ r and h in that range, t₁, t₂ any tangent frame."""
        sd = self.SD
        return sd[:, 0:3].copy(), sd[:, 4:7].copy(), sd[:, 3].copy(), sd[:, 8:10].copy()

    def _visible(self, start: np.ndarray, tile: int, ntx: int):
        """The cost model's estimate of the fragments occlusion culling leaves (:func:`_visible_fragments`)."""

        def visible(probe: np.ndarray, tiles: np.ndarray) -> np.ndarray:
            out = np.empty(len(tiles), dtype=np.int64)
            run_parts(_visible_fragments, self._bbox, self._zmin, start, self._items, tiles, probe, tile, ntx,
                      PROBE_STEP, out)
            return out

        return visible

    def _scratch(self, H: int, W: int):
        """Per-pixel memo buffers of the raster kernel, kept between frames of one size."""
        if self._memo is None or self._memo[0].shape != (H, W):
            self._memo = tuple(np.empty((H, W), dtype=np.int32) for _ in range(3)) + (
                np.empty((H, W)), np.empty((H, W)))
        for a in self._memo[:3]:
            a.fill(-1)
        return self._memo

    def clip_tolerances(self, camera: Camera) -> np.ndarray:
        """Return CLIP_TOLERANCE · κ per quadric : (n_q,) float64 (κ at the scene's extent, eye included)."""
        R = max(self.extent, float(np.max(np.abs(camera.eye))), 1.0)
        A = np.abs(self.Q)
        quad = A[:, 0] + A[:, 4] + A[:, 7] + 2.0 * (A[:, 1] + A[:, 2] + A[:, 5])
        lin = 2.0 * (A[:, 3] + A[:, 6] + A[:, 8])
        return CLIP_TOLERANCE * (quad * R * R + lin * R + A[:, 9])

    def render(self, camera: Camera, *, footprint: str = "box", backface_culling: bool = True,
               local: str = "quadric", clip: bool = True, color_by: str = "quadric", lit: bool = True,
               tile: int = TILE, fallback: str = "auto", occlusion_culling: bool = True,
               device: str = "cpu") -> Frame:
        """Return the splat render of the cloud (§6).

        Parameters
        ----------
        camera : Camera
        footprint : "box" or "sphere"
            Surface-aligned box (§6.1) or the sphere's screen rectangle (§6 step 1) per splat.
        backface_culling : bool
            Drop splats all of whose points face away from the eye (§6.1; outside views).
        local : "quadric" or "disc"
            Local quadric ray-tracing, or flat discs on the tangent plane (classical splats).
        clip : bool
            Local clipping with the sample's clip set (§6 step 3).
        color_by : str
            See ``shading.COLOR_MODES``.
        tile : int
            Tile edge in pixels (binning and the parallel loop).
        fallback : "auto", "never" or "always"
            Ray trace the tiles where splats would cost more (:mod:`.tile_costs`: estimated per tile
            before the raster, ``stats.raytraced_tiles``; the whole frame when ray tracing it costs
            less than the splats' footprint and binning passes alone), never, or everywhere. Only with local
            quadric ray-tracing and clipping (the exact picture) and a colouring that is not about
            the splats (``overdraw``, ``clip_count``); otherwise splats draw every tile.
        occlusion_culling : bool
            Skip a splat whose nearest depth lies behind every pixel already drawn under its footprint (blocks of
            8 × 8 pixels): the same picture with fewer fragments (``False`` counts every fragment of every footprint,
            as the paper's overdraw figures do).
        device : "cpu" or "cuda"
            Where the raster runs (:mod:`csgnb.render.cuda`: one GPU thread per pixel, the CPU's arithmetic; every
            fragment tested, as with ``occlusion_culling=False``). The first frame a renderer draws on the GPU is
            also drawn on the CPU and compared bit for bit (a difference raises). Without a GPU, "cuda" raises.

        Returns
        -------
        Frame
            With the overdraw buffer and counts (``stats.fragments``, ``stats.overdraw``); ray-traced
            tiles have no fragments, clip counts or samples (-1).

        Raises
        ------
        GeometryError
            For a camera inside the solid (:func:`csgnb.render.scene.eye_inside`) unless the frame can be ray traced
            instead (``fallback="auto"`` or ``"always"`` with the exact options): from inside, back-face culling
            drops the walls the eye sees, so the splats would not draw the surface's picture.
        """
        t0 = time.perf_counter()
        check_camera(camera)
        check_precision(camera, *self._scene)
        check_choice(footprint, FOOTPRINTS, "footprint")
        check_choice(local, LOCAL_MODES, "local")
        check_choice(color_by, COLOR_MODES, "color_by")
        check_choice(fallback, FALLBACKS, "fallback")
        backface_culling, clip, lit = (as_flag(backface_culling, "backface_culling"), as_flag(clip, "clip"),
                                       as_flag(lit, "lit"))
        occlusion_culling = as_flag(occlusion_culling, "occlusion_culling")
        check_choice(device, DEVICES, "device")
        if device == "cuda":
            if not cuda_available():
                raise CsgnbError("device='cuda' needs a CUDA GPU, and numba.cuda finds none here; use device='cpu'")
            occlusion_culling = False  # a tile-serial decision: the GPU tests every fragment
        tile = as_count(tile, "tile", 4)
        if not 4 <= tile <= 1024:
            raise CsgnbError(f"tile must be in [4, 1024] pixels, got {tile}")
        cam = camera.params()
        X, Y = camera.screen_axes()
        H, W = camera.shape
        ctol = self.clip_tolerances(camera)
        rtol = 64.0 * EPS * max(self.extent, float(np.max(np.abs(camera.eye))), 1.0)
        P = ray_polynomials(cam, self.Q)
        li = LOCAL_MODES.index(local)
        exact = li == 1 and clip and color_by not in ("overdraw", "clip_count")
        trace_args = (cam, X, Y, P, self.term_start, self.max_term)
        ntx, nty = (W + tile - 1) // tile, (H + tile - 1) // tile
        start = np.zeros(ntx * nty + 1, dtype=np.int64)
        n_terms = self.normal_form.n_terms
        inside = eye_inside(self.normal_form, camera)
        if inside and not (exact and fallback != "never"):
            raise GeometryError(
                "the camera looks from inside the solid (its eye, or an orthographic camera's ray origins): splats "
                "draw views from outside only (back-face culling, §6.1), so this picture would not be the surface's; "
                "move the camera out (zoom out), or render with fallback='auto' and the default local quadric "
                "ray-tracing, clipping and colouring, which ray trace such a view")
        # the whole frame ray traced when that costs less than the splats' per-splat passes alone, or from inside
        whole = exact and (inside or fallback == "always" or (
            fallback == "auto" and raytrace_is_cheaper(trace_args, (H, W), tile, len(self.SD), n_terms)))
        if not whole:
            run_parts(_footprint_kernel, cam, self.SD, FOOTPRINTS.index(footprint), bool(backface_culling),
                      self._bbox, self._hull, self._nh, self._flag, self._zmin)
        t1 = time.perf_counter()
        if not whole:
            total = _bin_splats(self._bbox, self._flag, self._zmin, tile, ntx, nty, start, self._items)
            if total > len(self._items):
                self._items = np.empty(int(total * 1.25) + 1024, dtype=np.int32)
                _bin_splats(self._bbox, self._flag, self._zmin, tile, ntx, nty, start, self._items)
        t2 = time.perf_counter()
        fragments_est = np.zeros(ntx * nty, dtype=np.int64)
        if not whole:
            run_parts(_tile_fragments, self._bbox, start, self._items, tile, ntx, H, W, fragments_est)
        mode = "always" if whole else (fallback if exact else "never")
        plan = plan_tiles(mode, trace_args, fragments_est, start, tile, (H, W), n_terms,
                          visible=self._visible(start, tile, ntx) if occlusion_culling else None)
        self.last_plan = plan  # the cost model's inputs and choice (benchmarks calibrate it from these)
        self.last_bins = (start, tile, ntx)
        skip = np.zeros(ntx * nty, dtype=np.uint8)
        skip[plan.raytraced] = 1
        t2b = time.perf_counter()
        depth = np.full((H, W), np.inf)
        winner = np.full((H, W), -1, dtype=np.int32)
        qwin, qclip, qlast, zr1, zr2 = self._scratch(H, W)
        od = np.zeros((H, W), dtype=np.int32)
        if device == "cuda":
            frame_args = (cam, X, Y, P, self.Q, ctol, self.SD, self.SI, self.cidx, self._bbox, self._hull, self._nh,
                          self._zmin)
            cuda_raster(frame_args, (start, self._items, tile, ntx), skip, (li, bool(clip)), rtol, (depth, winner, od))
        else:
            run_parts(_raster_kernel, cam, X, Y, P, self.Q, ctol, self.SD, self.SI, self.cidx, self._bbox,
                      self._hull, self._nh, self._zmin, start, self._items, tile, ntx, skip, li, bool(clip),
                      occlusion_culling, rtol, depth, winner, qwin, qclip, qlast, zr1, zr2, od)
        t3 = time.perf_counter()
        qid = np.empty((H, W), dtype=np.int32)
        tid = np.empty((H, W), dtype=np.int32)
        ccount = np.empty((H, W), dtype=np.int32)
        if li == 0:
            normal = np.zeros((H, W, 3), dtype=np.float32)
            run_parts(_resolve_kernel, winner, self.SI, self.normals, self.term_of, li, qid, tid, ccount, normal)
        else:
            run_parts(_resolve_kernel, winner, self.SI, self.normals, self.term_of, li, qid, tid, ccount,
                      np.empty((1, 1, 3), dtype=np.float32))
        t3b = time.perf_counter()
        if len(plan.raytraced):  # after the resolve, which clears the pixels no splat won
            raytrace_tiles(*trace_args, np.array([tile, 1, 1], dtype=np.int64), plan.raytraced, depth, qid, tid,
                           np.empty(len(plan.raytraced), dtype=np.int64))
        t3c = time.perf_counter()
        if li == 1:
            normal = surface_normals(cam, X, Y, self.Q, depth, qid)
        t4 = time.perf_counter()
        frame = Frame(camera, depth, normal, qid, tid, np.empty((0, 0, 3), np.uint8), od, ccount, winner,
                      stats=None, normal_form=self.normal_form, _palette=self.palette)
        if color_by == "quadric":
            rgb = shade(cam, X, Y, normal, qid, self.palette, lit=lit)
        else:
            rgb = frame.shaded(color_by, lit=lit)
        t5 = time.perf_counter()
        covered = int(np.count_nonzero(qid >= 0))
        splatted = covered - _covered_in(qid, plan.raytraced, tile, ntx)
        fragments = int(od.sum(dtype=np.int64))
        flags = np.zeros(3, dtype=np.int64) if whole else np.bincount(self._flag, minlength=3)
        stats = RenderStats(
            "splats", covered, fragments, fragments / splatted if splatted else 0.0,
            int(flags[0]), int(flags[1]), int(flags[2]), 1e3 * (time.perf_counter() - t0),
            {"footprints": 1e3 * (t1 - t0), "binning": 1e3 * (t2 - t1), "plan": 1e3 * (t2b - t2),
             "raster": 1e3 * (t3 - t2b), "raytrace": 1e3 * (t3c - t3b), "normals": 1e3 * (t4 - t3c),
             "shade": 1e3 * (t5 - t4)},
            raytraced_tiles=len(plan.raytraced), tiles=ntx * nty,
        )
        out = Frame(camera, depth, normal, qid, tid, rgb, od, ccount, winner, stats, self.normal_form, self.palette)
        if device == "cuda" and not self._device_checked:
            # the device's rounding must be the CPU's: the first frame drawn there is drawn here too
            check_against_cpu(out, self.render(camera, footprint=footprint, backface_culling=backface_culling,
                                               local=local, clip=clip, color_by=color_by, lit=lit, tile=tile,
                                               fallback=fallback, occlusion_culling=False))
            self._device_checked = True
        return out


def _covered_in(qid: np.ndarray, tiles: np.ndarray, tile: int, ntx: int) -> int:
    """Covered pixels (qid ≥ 0) inside the listed tiles."""
    n = 0
    for t in tiles.tolist():
        i0, j0 = (t // ntx) * tile, (t % ntx) * tile
        n += int(np.count_nonzero(qid[i0 : i0 + tile, j0 : j0 + tile] >= 0))
    return n


_RENDERERS: dict[int, tuple[weakref.ref, SplatRenderer]] = {}


def renderer_for(cloud) -> SplatRenderer:
    """Return a (cached) SplatRenderer of ``cloud``: the last few clouds keep their prepared data."""
    key = id(cloud)
    hit = _RENDERERS.get(key)
    if hit is not None and hit[0]() is cloud:
        return hit[1]
    r = SplatRenderer(cloud)
    try:
        ref = weakref.ref(cloud)
    except TypeError:  # pragma: no cover - dataclasses support weak references
        return r
    _RENDERERS[key] = (ref, r)
    while len(_RENDERERS) > 4:
        _RENDERERS.pop(next(iter(_RENDERERS)))
    return r


def render(cloud, camera: Camera, **options) -> Frame:
    """Return the splat render of ``cloud`` seen by ``camera`` (§6, §6.1).

    Options as :meth:`SplatRenderer.render` (``footprint``, ``backface_culling``, ``local``,
    ``clip``, ``color_by``, ``lit``, ``tile``). Raises TypeError for a non-cloud or non-camera,
    GeometryError for an empty cloud or one whose samples are not on its normal form's quadrics.
    """
    if not isinstance(camera, Camera):
        check_camera(camera)
    return renderer_for(cloud).render(camera, **options)

