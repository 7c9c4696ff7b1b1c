"""Running one serial kernel on several threads: each thread takes one *part* of the work.

csgnb's data-parallel kernels (the renderer's per-splat, per-tile and per-row loops) are serial numba kernels that
release the GIL (``nogil``, the jit policy's default) and take two last arguments ``part, parts``: the call with
``part = p`` does the p-th share of the loop (a stride or a block of it). :func:`run_parts` calls such a kernel
once per part on a persistent pool of ``numba.get_num_threads()`` threads and returns when all are done.

Why not ``numba.prange``: a ``parallel=True`` kernel goes through numba's parfor passes and is compiled twice
(the kernel and its gufunc), which made the renderer's six kernels cost ~3x their serial compile time (the
footprint kernel: 8-9 s of CPU against 2.7-3.5 s serial, 2026-12-03), a large part of the first run's wait
(issue 21). A part writes only the outputs of its share of the loop, and what it computes there does not depend
on which thread runs it or how many there are: the result is the one-thread result, bit for bit.

The number of threads follows numba's setting (``NUMBA_NUM_THREADS``, ``numba.set_num_threads``) like the
sampler's threads. A call from inside a part (a kernel's caller that is itself run by :func:`run_parts`) runs its
parts in the calling thread, so the fixed pool never waits on itself.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["run_parts", "run_tasks", "threads"]

_POOL: ThreadPoolExecutor | None = None
_POOL_SIZE = 0
_POOL_LOCK = threading.Lock()
_INSIDE = threading.local()


def threads() -> int:
    """The threads csgnb's parallel passes use: numba's setting (``NUMBA_NUM_THREADS``, ``numba.set_num_threads``)."""
    return max(1, int(numba.get_num_threads()))


def _pool(size: int) -> ThreadPoolExecutor:
    global _POOL, _POOL_SIZE
    with _POOL_LOCK:
        if _POOL is None or _POOL_SIZE < size:
            if _POOL is not None:
                _POOL.shutdown(wait=False)
            _POOL, _POOL_SIZE = ThreadPoolExecutor(size, thread_name_prefix="csgnb-part"), size
        return _POOL


def _run_inside(kernel, args: tuple, part: int, parts: int):
    _INSIDE.active = True
    try:
        return kernel(*args, part, parts)
    finally:
        _INSIDE.active = False


def run_parts(kernel, *args, parts: int | None = None) -> list:
    """Call ``kernel(*args, part, parts)`` for ``part`` in ``range(parts)``, the parts on concurrent threads.

    ``parts`` defaults to :func:`threads`; with one part (or from inside a part) the calls run in this thread.
    Returns the parts' return values in part order; an exception raised by a part is raised here (after every
    part has finished, so no thread still writes into the caller's arrays).
    """
    parts = threads() if parts is None else max(1, int(parts))
    if parts == 1 or getattr(_INSIDE, "active", False):
        return [kernel(*args, p, parts) for p in range(parts)]
    pool = _pool(parts - 1)
    futures = [pool.submit(_run_inside, kernel, args, p, parts) for p in range(1, parts)]
    try:
        first = _run_inside(kernel, args, 0, parts)  # part 0 in this thread: one hand-off fewer
    finally:
        errors = [f.exception() for f in futures]  # waits for every part
    for e in errors:
        if e is not None:
            raise e
    return [first] + [f.result() for f in futures]


def run_tasks(task, count: int, parts: int | None = None) -> list:
    """Call ``task(k)`` for ``k`` in ``range(count)`` on ``parts`` threads (default :func:`threads`) of the persistent
    pool, each thread taking the next task not yet taken (tasks in order: a task that waits on the GIL does not hold
    up the others); returns the results in task order. ``task`` runs Python around GIL-releasing kernels or numpy
    copies (the sampler's chunks of jobs, of leaves, of the join). An exception raised by a task is raised here,
    after every thread has stopped taking tasks.
    """
    results: list = [None] * count
    taken = [iter(range(count))]
    lock = threading.Lock()

    def worker(part: int, parts: int) -> None:
        while True:
            with lock:
                k = next(taken[0], None)
            if k is None:
                return
            try:
                results[k] = task(k)
            except BaseException:
                with lock:
                    taken[0] = iter(())  # the other threads take no new task
                raise

    run_parts(worker, parts=min(count, threads() if parts is None else max(1, int(parts))) or 1)
    return results
