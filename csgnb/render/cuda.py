"""The splat raster on a CUDA GPU (``numba.cuda``): one thread per pixel, the CPU raster's arithmetic in its order.

``SplatRenderer.render(camera, device="cuda")`` runs the footprints, the binning, the tile plan, the resolve, normals
and shading on the CPU as always, and the raster -- the per-fragment local ray tracing, clipping and depth test,
nearly all of a frame's work -- here. A thread owns one pixel and walks its tile's splats front to back as the CPU
kernel does, with the same per-pixel memos (in registers instead of buffers) and the same instructions (the
functions of :mod:`csgnb.render.rays`, compiled for the device), so the depth, the winning splat and the fragment
count of every pixel are the CPU's bit for bit -- the CPU's with ``occlusion_culling=False``: the occlusion test
is a tile-serial decision, and the GPU tests every fragment instead.

Bit for bit holds only if the device rounds as the CPU does: no fused multiply-add contraction, IEEE division and
square root (``fastmath`` off; CUDA contracts ``a * b + c`` into an FMA unless told not to, which changes the last
bit of a root). So the first frame of every renderer on the device is also drawn on the CPU and compared
(:func:`check_against_cpu`); a difference raises :class:`csgnb.errors.CsgnbError` instead of drawing a picture that is
not the CPU's. Without a GPU, ``device="cuda"`` is refused with the reason; the test suite runs this module under
numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``), which executes the same kernel on the CPU.
"""

from __future__ import annotations

import math

import numpy as np

from csgnb.errors import CsgnbError
from csgnb.render.rays import disc_hit, ray_point, ray_roots, row_value

__all__ = ["DEVICES", "BLOCK", "available", "raster", "check_against_cpu"]

cuda = None  # numba.cuda, bound into the kernel's globals when it is built (importing it costs; CPU frames never do)

#: ``device=`` choices of the splat renderer.
DEVICES = ("cpu", "cuda")

#: Threads per block along each screen axis.
BLOCK = 16

_KERNEL = None


def available() -> bool:
    """Whether a CUDA device (or numba's CUDA simulator) is there to run :func:`raster`."""
    try:
        from numba import cuda
    except ImportError:  # pragma: no cover - numba ships its CUDA target
        return False
    try:
        return bool(cuda.is_available())
    except Exception:  # a broken driver install is "not available", not a crash
        return False


def _raster_pixel(cam, X, Y, P, Q, ctol, SD, SI, cidx, bbox, hull, nh, zmin, start, items, tile, ntx, skip, local,
                  clip, rtol, depth, winner, od):
    """One pixel's raster (the CUDA kernel; flat arguments, as a kernel takes them): see the module docstring and
    ``splats._raster_kernel``, whose arguments these are."""
    i, j = cuda.grid(2)
    H, W = depth.shape
    if i >= H or j >= W:
        return
    t = (i // tile) * ntx + j // tile
    best, win, count = math.inf, -1, 0
    if skip[t] == 0:
        persp = cam[18] == 0.0
        x, y = X[j], Y[i]
        yc = float(i)
        qwin, qclip, qlast = -1, -1, -1
        z1, z2 = math.nan, math.nan
        for b in range(start[t], start[t + 1]):
            k = items[b]
            if i < bbox[k, 1] or i > bbox[k, 3] or j < bbox[k, 0] or j > bbox[k, 2]:
                continue
            m = nh[k]
            if m > 0:  # the hull's span on this row, as the CPU computes it
                lo, hi = math.inf, -math.inf
                for e in range(m):
                    xa, ya = hull[k, 2 * e], hull[k, 2 * e + 1]
                    e1 = e + 1 if e + 1 < m else 0
                    xb, yb = hull[k, 2 * e1], hull[k, 2 * e1 + 1]
                    if ya == yb:
                        continue
                    if ya > yb:
                        xa, ya, xb, yb = xb, yb, xa, ya
                    if ya <= yc <= yb:
                        xx = xa + (yc - ya) * ((xb - xa) / (yb - ya))
                        lo = min(lo, xx)
                        hi = max(hi, xx)
                if hi < lo or j < math.ceil(lo) or j > math.floor(hi):
                    continue
            count += 1
            q = SI[k, 0]
            if zmin[k] > best or qwin == q or qclip == q:
                continue
            sx, sy, sz, r = SD[k, 0], SD[k, 1], SD[k, 2], SD[k, 3]
            rr = (r + rtol) * (r + rtol)
            if local == 0:  # a flat disc on the tangent plane
                zz = disc_hit(cam, SD, k, x, y, best, rr)
                if zz < math.inf:
                    best, win = zz, k
                continue
            if qlast != q:
                dd = 1.0 + (x * x + y * y) if persp else 1.0
                z1, z2, _ = ray_roots(P, q, x, y, dd)
                qlast = q
            done, won = True, False
            for root in range(2):
                zz = z1 if root == 0 else z2
                if not zz <= best:
                    break
                if not zz > 0.0:
                    continue
                if zz == best and not (win >= 0 and q < SI[win, 0]):
                    continue
                px, py, pz = ray_point(cam, x, y, zz)
                ex, ey, ez = px - sx, py - sy, pz - sz
                if ex * ex + ey * ey + ez * ez > rr:
                    done = False
                    continue
                ok = True
                if clip:
                    for c in range(SI[k, 1], SI[k, 1] + SI[k, 2]):
                        kq = cidx[c]
                        if row_value(Q, kq, px, py, pz) > ctol[kq]:
                            ok = False
                            break
                if ok:
                    best, win, won = zz, k, True
                    break
            if won:
                qwin = q if done else -1
            elif done:
                qclip = q
    depth[i, j] = best
    winner[i, j] = win
    od[i, j] = count


def _for_simulator(fn, done: dict):
    """``fn`` (a csgnb jit function) as plain Python calling plain Python: numba's CUDA simulator runs kernels as
    Python on its own array type, which compiled CPU functions do not accept. On a device, numba compiles the jit
    functions a kernel calls for the device itself."""
    from numba.core.registry import CPUDispatcher

    if fn in done:
        return done[fn]
    py = fn.py_func
    names = {}
    for name in py.__code__.co_names:
        g = py.__globals__.get(name)
        if isinstance(g, CPUDispatcher):
            names[name] = _for_simulator(g, done)
    done[fn] = _rebound(py, names)
    return done[fn]


def _kernel():
    global _KERNEL
    if _KERNEL is None:
        from numba import config, cuda

        bound = {"cuda": cuda}
        if config.ENABLE_CUDASIM:
            done: dict = {}
            rays = (disc_hit, ray_point, ray_roots, row_value)
            bound.update({f.__name__: _for_simulator(f, done) for f in rays})
        _KERNEL = cuda.jit(_rebound(_raster_pixel, bound))  # numba.cuda's default: no fastmath (csgnb._jit's rule)
    return _KERNEL


def _rebound(fn, bound: dict):
    """``fn`` with some of its globals rebound (the kernel's ``cuda`` and, under the simulator, plain-Python rays)."""
    import types

    return types.FunctionType(fn.__code__, {**fn.__globals__, **bound}, fn.__name__, fn.__defaults__, fn.__closure__)


def raster(frame_args: tuple, bins: tuple, skip: np.ndarray, flags: tuple, rtol: float, out: tuple) -> None:
    """Rasterize every tile not skipped on the CUDA device; fill ``out = (depth, winner, od)`` (H, W) on the host.

    frame_args : ``(cam, X, Y, P, Q, ctol, SD, SI, cidx, bbox, hull, nh, zmin)`` of the CPU raster;
    bins : ``(start, items, tile, ntx)``; skip : (ntiles,) uint8, 1 for a ray-traced tile (left at ∞ / -1 / 0);
    flags : ``(local, clip)`` as the CPU raster takes them.
    """
    if not available():
        raise CsgnbError("device='cuda' needs a CUDA GPU, and numba.cuda finds none here; use device='cpu'")
    from numba import cuda

    depth, winner, od = out
    H, W = depth.shape
    start, items, tile, ntx = bins
    send = [cuda.to_device(np.ascontiguousarray(a)) for a in frame_args]
    d_out = [cuda.device_array_like(a) for a in out]
    grid = ((H + BLOCK - 1) // BLOCK, (W + BLOCK - 1) // BLOCK)
    _kernel()[grid, (BLOCK, BLOCK)](*send, cuda.to_device(start), cuda.to_device(items), int(tile), int(ntx),
                                      cuda.to_device(skip), int(flags[0]), bool(flags[1]), float(rtol), *d_out)
    for host, dev in zip(out, d_out, strict=True):
        dev.copy_to_host(host)


def check_against_cpu(gpu, cpu) -> None:
    """Raise CsgnbError unless two frames of one view, drawn on the device and on the CPU (every fragment tested),
    agree bit for bit: depth, winning splat, fragments per pixel."""
    for name in ("depth", "sample", "overdraw"):
        a, b = getattr(gpu, name), getattr(cpu, name)
        if not np.array_equal(a, b, equal_nan=True):
            n = int(np.count_nonzero(~((a == b) | (np.isnan(a) & np.isnan(b)) if a.dtype.kind == "f" else a == b)))
            raise CsgnbError(f"the CUDA raster differs from the CPU's on this device ({name}: {n} pixels): its "
                             "rounding is not the CPU's (fused multiply-add?); render with device='cpu'")
