"""csgnb beyond one process, on Dask: batches of milling jobs (:mod:`csgnb.distributed.batch`) and the clients
they run on (:mod:`csgnb.distributed.cluster`: an embedded ``LocalCluster`` or any scheduler address).

>>> from csgnb.distributed import MillingJob, run_batch
>>> jobs = [MillingJob.example("pocket.nc", name=f"pocket-{r}", resolution=r) for r in (1.0, 0.5)]
>>> results = run_batch(jobs, out_dir="out/batch")          # doctest: +SKIP
>>> [r.part_volume for r in results]                         # doctest: +SKIP

Needs ``dask[distributed]`` (a dependency of csgnb).
"""

from __future__ import annotations

from csgnb.distributed.batch import JobResult, MillingJob, run_batch, run_job
from csgnb.distributed.cluster import WarmUpPlugin, connect

__all__ = ["JobResult", "MillingJob", "WarmUpPlugin", "connect", "run_batch", "run_job"]
