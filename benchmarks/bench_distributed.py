"""A batch of milling jobs on a Dask LocalCluster against the same jobs one by one in this process.

The batch: the two shipped programs (:mod:`csgnb.apps.examples`) with four tools each and two
feed scales (the feed changes the program's text, its digest and its cut time, not the part):
16 jobs by default, on a grid of ``--resolution`` mm (default 1.0: minutes in all on a busy
2-core machine; ``--resolution 0`` fits the grid as ``python -m csgnb.mill`` does).

Printed and written (``--json PATH``):

* ``serial``: the jobs run one by one here (:func:`csgnb.distributed.run_job`), wall and CPU s
  (kernels loaded first, so no compilation is timed);
* ``batch``: :func:`csgnb.distributed.run_batch` on a 2-worker ``LocalCluster`` (1 thread each),
  wall s, CPU s (this process and the workers, ``time.process_time`` deltas), the cluster's
  start-up with the kernel warm-up (timed apart), and per-task overhead: ``(workers x wall -
  time inside the tasks) / jobs`` (idle workers at the tail included);
* ``noop_task_ms``: the round trip of an empty task on the same cluster (Dask's own cost);
* the load average before and after: figures taken with a load above the core count are
  flagged ``"quiet": false`` (other processes shared the cores).

Every batch result is checked against its serial run: exact volumes ``==``, STL SHA-256 equal.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time

from distributed import Client, LocalCluster

from csgnb.distributed import MillingJob, run_batch, run_job
from csgnb.distributed.cluster import WarmUpPlugin, local_cluster_kwargs
from csgnb.warmup import warm_up

TOOLS = {"pocket.nc": ["flat:6", "flat:5", "bull:6:1", "ball:6"], "relief.nc": ["ball:4", "ball:3", "bull:4:1",
                                                                              "flat:4"]}


def _scale_feeds(program: str, factor: float) -> str:
    return re.sub(r"F(\d+(?:\.\d*)?)", lambda m: f"F{float(m.group(1)) * factor:g}", program)


def jobs(resolution: float | None, n: int) -> list[MillingJob]:
    """``n`` jobs (of 16): each shipped program with four tools and feeds x1 and x1.5."""
    out = []
    for name, specs in TOOLS.items():
        base = MillingJob.example(name, resolution=resolution)
        for spec in specs:
            for factor in (1.0, 1.5):
                tag = f"{name.removesuffix('.nc')}-{spec.replace(':', '_')}-f{factor:g}"
                out.append(MillingJob.from_dict(dict(base.as_dict(), name=tag, tools=[spec],
                                                     program=_scale_feeds(base.program, factor))))
    return out[:n]


def _load() -> float:
    return os.getloadavg()[0]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", default=None, help="write the figures here")
    p.add_argument("--resolution", type=float, default=1.0, help="grid step in mm (0: fitted as the CLI does)")
    p.add_argument("--jobs", type=int, default=16, help="how many of the 16 jobs")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    batch = jobs(args.resolution or None, args.jobs)
    load_before = _load()
    warm_up("exact", "mesh", "bsp", "octree", progress=False, parallel=False)

    cpu0, t0 = time.process_time(), time.perf_counter()
    serial = [run_job(j) for j in batch]
    serial_wall, serial_cpu = time.perf_counter() - t0, time.process_time() - cpu0
    print(f"serial: {len(batch)} jobs in {serial_wall:.1f} s wall, {serial_cpu:.1f} s CPU", flush=True)

    t0 = time.perf_counter()
    cluster = LocalCluster(**local_cluster_kwargs(args.workers))
    client = Client(cluster)
    client.register_plugin(WarmUpPlugin(), name=WarmUpPlugin.name)
    startup = time.perf_counter() - t0
    try:
        t0 = time.perf_counter()
        client.gather([client.submit(int, k, pure=False) for k in range(20)])  # connections up
        k = 200
        client.gather([client.submit(int, i, pure=False) for i in range(k)])
        noop_ms = (time.perf_counter() - t0) * 1000 / (k + 20)
        worker_cpu0 = sum(client.run(time.process_time).values())
        cpu0, t0 = time.process_time(), time.perf_counter()
        with tempfile.TemporaryDirectory() as out:
            results = run_batch(batch, client, out, progress=sys.stderr.isatty())
        batch_wall = time.perf_counter() - t0
        batch_cpu = time.process_time() - cpu0 + sum(client.run(time.process_time).values()) - worker_cpu0
    finally:
        client.close()
        cluster.close()
    load_after = _load()
    bad = [r.name for r, s in zip(results, serial, strict=True)
           if not r.ok or (r.part_volume, r.removed_per_move, r.stl_sha256)
           != (s.part_volume, s.removed_per_move, s.stl_sha256)]
    if bad:
        print(f"MISMATCH between the batch and the serial runs: {bad}", file=sys.stderr)
        return 1
    inside = sum(r.wall_s for r in results)
    overhead_ms = (args.workers * batch_wall - inside) * 1000 / len(batch)
    quiet = max(load_before, load_after) <= (os.cpu_count() or 1)
    print(f"batch:  {len(batch)} jobs on {args.workers} workers in {batch_wall:.1f} s wall, {batch_cpu:.1f} s CPU "
          f"(cluster start + warm-up {startup:.1f} s, not included); speed-up {serial_wall / batch_wall:.2f}x")
    print(f"per-task overhead {overhead_ms:.0f} ms (idle tail included); empty task round trip {noop_ms:.2f} ms")
    print(f"load average {load_before:.1f} before, {load_after:.1f} after, {os.cpu_count()} cores"
          + ("" if quiet else ": NOT QUIET, other processes shared the cores; the figures are provisional"))
    print("exact volumes and STL bytes: batch == serial for every job")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"jobs": len(batch), "workers": args.workers, "resolution_mm": args.resolution,
                       "serial": {"wall_s": serial_wall, "cpu_s": serial_cpu},
                       "batch": {"wall_s": batch_wall, "cpu_s": batch_cpu, "startup_s": startup,
                                 "task_s": inside, "per_task_overhead_ms": overhead_ms},
                       "noop_task_ms": noop_ms, "speedup": serial_wall / batch_wall,
                       "load_before": load_before, "load_after": load_after, "cores": os.cpu_count(),
                       "quiet": quiet, "per_job": {r.name: {"serial_s": s.wall_s, "batch_task_s": r.wall_s,
                                                             "moves": r.moves} for r, s in zip(results, serial,
                                                                                                strict=True)}},
                      fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
