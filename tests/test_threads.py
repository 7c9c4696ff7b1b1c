"""Serial kernels run in parts on threads (csgnb._threads): part order, errors, nesting, and the renderer's images
bit for bit whatever the number of parts (more parts than this machine has cores included)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from csgnb import _threads
from csgnb._threads import run_parts


def test_parts_cover_the_loop_once_and_return_in_order():
    seen = []
    lock = threading.Lock()

    def kernel(out, part, parts):
        with lock:
            seen.append(part)
        out[part::parts] += 1
        return part * 10

    out = np.zeros(23, dtype=np.int64)
    assert run_parts(kernel, out, parts=4) == [0, 10, 20, 30]
    assert sorted(seen) == [0, 1, 2, 3] and np.all(out == 1)


def test_an_error_in_a_part_is_raised_after_every_part_finished():
    done = []

    def kernel(part, parts):
        if part == 1:
            raise ValueError("part 1 failed")
        done.append(part)

    with pytest.raises(ValueError, match="part 1 failed"):
        run_parts(kernel, parts=3)
    assert sorted(done) == [0, 2]


def test_a_call_from_inside_a_part_runs_its_parts_in_that_thread():
    names = []

    def inner(part, parts):
        names.append(threading.current_thread().name)

    def outer(part, parts):
        here = threading.current_thread().name
        run_parts(inner, parts=3)
        return here

    outers = run_parts(outer, parts=2)
    assert len(names) == 6 and set(names) == set(outers)


@pytest.mark.parametrize("parts", [2, 3, 7])
def test_splat_and_ray_traced_frames_do_not_depend_on_the_parts(monkeypatch, parts):
    import csgnb.csg as csg
    from csgnb.render import Camera, raytrace, render
    from csgnb.sampling import sample_csg

    solid = (csg.sphere((0, 0, 0), 1.0, "A") - csg.box((0.2, -2, -2), (2, 2, 2), "B")) | csg.cylinder(
        (0, 0, -1.2), (0, 0, 1.2), 0.3, "C")
    cloud = sample_csg(solid, 0.08)
    cam = Camera.fit(cloud, 200, 150, azimuth=-35, elevation=25)

    def frames():
        # splats everywhere, the cost model's choice, and the reference ray tracer
        return [render(cloud, cam, fallback="never"), render(cloud, cam, footprint="sphere"),
                render(cloud, cam, local="disc", clip=False, color_by="overdraw"), raytrace(solid, cam)]

    monkeypatch.setattr(_threads, "threads", lambda: 1)
    one = frames()
    monkeypatch.setattr(_threads, "threads", lambda: parts)
    many = frames()
    for a, b in zip(one, many, strict=True):
        for name in ("depth", "quadric", "normal", "overdraw", "rgb", "clip_count"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert a.stats.fragments == b.stats.fragments


def test_tasks_run_once_each_and_return_in_task_order():
    seen = []
    lock = threading.Lock()

    def task(k):
        with lock:
            seen.append(k)
        return k * k

    assert _threads.run_tasks(task, 11, parts=3) == [k * k for k in range(11)]
    assert sorted(seen) == list(range(11))
    assert _threads.run_tasks(task, 0) == []


def test_an_error_in_a_task_stops_the_others_taking_new_ones():
    started = []

    def task(k):
        started.append(k)
        if k == 0:
            raise ValueError("task 0 failed")
        threading.Event().wait(0.01)

    with pytest.raises(ValueError, match="task 0 failed"):
        _threads.run_tasks(task, 200, parts=2)
    assert len(started) < 200
