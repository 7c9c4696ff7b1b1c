"""The splat raster on a CUDA GPU (csgnb.render.cuda): the CPU's pixels bit for bit, checked under numba's CUDA
simulator here (no GPU on this machine) and on the device itself wherever one is present."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from csgnb.csg.gallery import tour_part
from csgnb.errors import CsgnbError
from csgnb.render import Camera, SplatRenderer, render
from csgnb.render.cuda import available, check_against_cpu
from csgnb.sampling import sample_csg

_SIMULATED = textwrap.dedent('''
    import numpy as np
    from csgnb.csg.gallery import tour_part
    from csgnb.render import Camera, SplatRenderer
    from csgnb.sampling import sample_csg

    cloud = sample_csg(tour_part(), 0.08)
    for view, options in (((-50, 30, "perspective"), {}), ((120, -25, "orthographic"), {"local": "disc"}),
                          ((-50, 30, "perspective"), {"fallback": "auto", "tile": 8})):
        cam = Camera.fit(cloud, 36, 28, azimuth=view[0], elevation=view[1], projection=view[2])
        options = {"fallback": "never", "tile": 16, **options}
        renderer = SplatRenderer(cloud)
        gpu = renderer.render(cam, device="cuda", **options)  # the first frame is also checked inside
        cpu = renderer.render(cam, occlusion_culling=False, **options)
        for name in ("depth", "sample", "overdraw", "quadric", "rgb"):
            assert np.array_equal(getattr(gpu, name), getattr(cpu, name)), (view, options, name)
        assert gpu.stats.covered > 150, gpu.stats
        assert gpu.stats.fragments > 0 or options["fallback"] == "auto", gpu.stats
        print("same", view, options, gpu.stats.fragments)
    print("ALL SAME")
''')


def test_the_cuda_raster_draws_the_cpu_pixels_under_the_simulator():
    """Under NUMBA_ENABLE_CUDASIM=1 the kernel runs as Python on the CPU: the same depth, winning splat, fragment
    count, quadric and colour at every pixel as the CPU raster testing every fragment, in both local modes, both
    projections, and with the default fallback (here every tile is ray traced on the CPU)."""
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    out = subprocess.run([sys.executable, "-c", _SIMULATED], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "ALL SAME" in out.stdout


@pytest.mark.skipif(available(), reason="a CUDA device is present")
def test_cuda_without_a_gpu_is_refused_with_the_reason():
    cloud = sample_csg(tour_part(), 0.08)
    with pytest.raises(CsgnbError, match="needs a CUDA GPU"):
        render(cloud, Camera.fit(cloud, 32, 24), device="cuda")
    with pytest.raises(CsgnbError, match="device must be one of"):
        render(cloud, Camera.fit(cloud, 32, 24), device="gpu")


def test_a_device_that_rounds_otherwise_is_refused():
    """The guard of the first GPU frame: one depth a unit in the last place off is a different picture."""
    cloud = sample_csg(tour_part(), 0.08)
    frame = SplatRenderer(cloud).render(Camera.fit(cloud, 32, 24), fallback="never", occlusion_culling=False)
    check_against_cpu(frame, frame)
    import dataclasses

    covered = np.argwhere(np.isfinite(frame.depth))[0]
    depth = frame.depth.copy()
    depth[tuple(covered)] = np.nextafter(depth[tuple(covered)], np.inf)
    with pytest.raises(CsgnbError, match="differs from the CPU's"):
        check_against_cpu(dataclasses.replace(frame, depth=depth), frame)


@pytest.mark.skipif(not available() or os.environ.get("NUMBA_ENABLE_CUDASIM") == "1", reason="no CUDA device")
def test_the_cuda_raster_draws_the_cpu_pixels_on_the_device():  # pragma: no cover - runs where a GPU is present
    cloud = sample_csg(tour_part(), 0.02)
    for w, h in ((320, 240), (1280, 720)):
        cam = Camera.fit(cloud, w, h, azimuth=-50, elevation=30)
        renderer = SplatRenderer(cloud)
        gpu = renderer.render(cam, device="cuda", fallback="never")
        cpu = renderer.render(cam, fallback="never", occlusion_culling=False)
        for name in ("depth", "sample", "overdraw", "rgb"):
            assert np.array_equal(getattr(gpu, name), getattr(cpu, name)), name
