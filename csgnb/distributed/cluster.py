"""Dask clients for csgnb: an embedded ``LocalCluster`` sized to the machine, or any scheduler, with warm kernels.

:func:`connect` returns ``(client, owned)``: the client given, a client of the scheduler at an
address (``"tcp://host:8786"``), or -- with neither -- a new ``LocalCluster`` of one
single-threaded worker process per core (csgnb's work is numba kernels between Python steps, so
processes, not threads, run it in parallel). The local workers get this process's
``PYTHONPATH`` and ``NUMBA_CACHE_DIR`` with the folder that holds the imported ``csgnb`` first,
so they import the same csgnb (a source checkout too) and share its kernel cache.

Every worker compiles or loads csgnb's numba kernels once, when it starts (:class:`WarmUpPlugin`,
registered under one name so a second registration replaces the first, and run again on a worker
that replaces a lost one). No jitted function is ever pickled: tasks are plain functions of this
package that import the kernels where they run.
"""

from __future__ import annotations

import os
from pathlib import Path

from distributed import Client, LocalCluster, WorkerPlugin

import csgnb

__all__ = ["WARM_PARTS", "WarmUpPlugin", "close", "connect", "local_cluster_kwargs", "warm_worker",
           "worker_environment"]

#: The parts of :func:`csgnb.warmup.warm_up` a milling worker needs (the exact track; no quadrics).
WARM_PARTS = ("exact", "mesh", "bsp", "octree")


class WarmUpPlugin(WorkerPlugin):
    """Loads (or compiles) csgnb's numba kernels on each worker as it starts, so the first task is not slow."""

    name = "csgnb-warm-up"

    def __init__(self, parts: tuple[str, ...] = WARM_PARTS) -> None:
        self.parts = tuple(parts)

    def setup(self, worker) -> None:
        warm_worker(self.parts)


def warm_worker(parts: tuple[str, ...] = WARM_PARTS) -> None:
    """Load csgnb's kernels for ``parts`` in this process and, with the octree, run one small milling job.

    The kernels alone leave a milling task's first run ~0.3-0.5 s slower than the next ones: the modules it
    imports on first use (the G-code reader, scipy's hull for the tool, the STL writer) and the first calls of
    kernels the warm-up does not call. A 2 mm grid job of the shipped pocket program touches all of them
    (~0.3 s once per worker).
    """
    from csgnb.warmup import warm_up

    # One process per worker already: the warm-up must not start a second one.
    warm_up(*parts, progress=False, parallel=False)
    if "octree" in parts:
        from csgnb.distributed.batch import MillingJob, run_job

        run_job(MillingJob.example("pocket.nc", resolution=2.0))


def worker_environment() -> dict[str, str]:
    """The environment variables local workers need to import this csgnb and share its numba cache."""
    source = str(Path(csgnb.__file__).resolve().parents[1])
    paths = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = {"PYTHONPATH": os.pathsep.join([source] + [p for p in paths if p != source])}
    for name in ("NUMBA_CACHE_DIR", "CSGNB_DISABLE_CACHE", "NUMBA_DISABLE_JIT"):
        if name in os.environ:
            env[name] = os.environ[name]
    return env


def local_cluster_kwargs(n_workers: int | None = None) -> dict:
    """Keyword arguments of the embedded ``LocalCluster``: one single-threaded process per core; the
    scheduler's HTTP server (dashboard when bokeh is installed) on a free port, so several clusters can run."""
    n = (os.cpu_count() or 1) if n_workers is None else int(n_workers)
    if n < 1:
        raise ValueError(f"n_workers must be at least 1, got {n_workers!r}")
    return dict(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                env=worker_environment())


def connect(client=None, scheduler: str | None = None, n_workers: int | None = None,
            warm: bool = True) -> tuple[Client, bool]:
    """A ready client and whether the caller owns it (and must close it and its cluster).

    ``client``: used as it is; ``scheduler``: an address such as ``"tcp://10.0.0.5:8786"`` (its
    workers must have csgnb installed); neither: a new ``LocalCluster`` (:func:`local_cluster_kwargs`).
    With ``warm`` every worker loads the kernels first (:class:`WarmUpPlugin`).
    """
    if client is not None and scheduler is not None:
        raise ValueError("give a client or a scheduler address, not both")
    owned = client is None
    if client is None:
        if scheduler is not None:
            if not isinstance(scheduler, str) or not scheduler.strip():
                raise ValueError(f"a scheduler address is a string such as 'tcp://host:8786', got {scheduler!r}")
            client = Client(scheduler, timeout="30s")
        else:
            client = Client(LocalCluster(**local_cluster_kwargs(n_workers)))
    elif not isinstance(client, Client):
        raise TypeError(f"client must be a distributed.Client, got {type(client).__name__}")
    if warm and not client.run_on_scheduler(_has_worker_plugin, name=WarmUpPlugin.name):
        client.register_plugin(WarmUpPlugin(), name=WarmUpPlugin.name)
    return client, owned


def _has_worker_plugin(dask_scheduler=None, name: str = "") -> bool:
    # Registering again would run the warm-up again on every worker: once per cluster is enough.
    return name in dask_scheduler.worker_plugins


def close(client: Client) -> None:
    """Close a client made by :func:`connect` and the ``LocalCluster`` it started, if any."""
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()
