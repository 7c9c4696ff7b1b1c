"""A batch of milling jobs and a sharded carving on a Dask LocalCluster, against the same work in one process.

The batch: the two shipped programs (:mod:`csgnb.apps.examples`) with four tools each and two
feed scales (the feed changes the program's text, its digest and its cut time, not the part):
16 jobs by default, on a grid of ``--resolution`` mm (default 1.0: minutes in all on a busy
2-core machine; ``--resolution 0`` fits the grid as ``python -m csgnb.mill`` does).

Printed and written (``--json PATH``):

* ``serial``: the jobs run one by one here (:func:`csgnb.distributed.run_job`), wall and CPU s,
  after :func:`csgnb.distributed.cluster.warm_worker` -- the same warm-up every worker gets (kernels
  loaded, one small job run), so neither side times compilation or first-use imports;
* ``batch``: :func:`csgnb.distributed.run_batch` on a 2-worker ``LocalCluster`` (1 thread each),
  wall s, CPU s (this process and the workers, ``time.process_time`` deltas), the cluster's
  start-up with the kernel warm-up (timed apart), and per-task overhead: ``(workers x wall -
  time inside the tasks) / jobs`` (idle workers at the tail included);
* ``noop_task_ms``: the round trip of an empty task on the same cluster (Dask's own cost);
* the load average before and after: figures taken with a load above the core count are
  flagged ``"quiet": false`` (other processes shared the cores).

Every batch result is checked against its serial run: exact volumes ``==``, STL SHA-256 equal.

The sharded carving (``--workloads sharded``): ``--dodecahedra`` (default 1,000) turned dodecahedra
just outside a sphere subtracted from a block (the carving of ``bench_milling.py``), by one
:class:`csgnb.octree.Workpiece` in a fresh process and by a :class:`csgnb.distributed.sharded.ShardedWorkpiece`
of ``--shards`` (default 8) on the 2-worker cluster. Both build every hull from its float points
(tool preparation included). Printed: wall and CPU s of each (the sharded CPU adds this process and
the workers), the exact volumes (must be equal), the workers' time inside Booleans against the
time they had (the rest is communication and idling), Booleans per message, and memory: each
process's peak resident set during the carving (``VmHWM`` after ``clear_refs``), whole and above
its resident set before it (the loaded kernels and libraries every process carries).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time

import numpy as np
from distributed import Client, LocalCluster

from csgnb.distributed import MillingJob, run_batch, run_job
from csgnb.distributed.cluster import WarmUpPlugin, local_cluster_kwargs, warm_worker
from csgnb.exact.rational import fraction_text, parse_fraction

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


def _memory_kb() -> tuple[int, int]:
    """This process's resident set and its peak (kB) since the last :func:`_reset_peak`."""
    fields = dict(line.split(":", 1) for line in open("/proc/self/status").read().splitlines() if ":" in line)
    return int(fields["VmRSS"].split()[0]), int(fields["VmHWM"].split()[0])


def _reset_peak() -> int:
    """Start a new peak (``VmHWM``) for this process; return its resident set now (kB)."""
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
    return _memory_kb()[0]


def _carving(n: int, radius: float):
    from csgnb.apps import carving
    from csgnb.exact import Grid

    grid = Grid.fit([-6.0] * 3, [6.0] * 3)
    c = carving.carving_placements(carving.sphere_target(radius=4.0), n, radius, grid=grid, seed=15)
    return grid, c


def _single_carve(n: int, radius: float, threshold: int) -> dict:
    """In a fresh process: one workpiece carved, timed, its peak memory measured."""
    from csgnb.octree import Workpiece

    warm_worker()
    grid, c = _carving(n, radius)
    w = Workpiece.box([-4.6] * 3, [4.6] * 3, grid=grid, threshold=threshold)
    base = _reset_peak()
    cpu0, t0 = time.process_time(), time.perf_counter()
    for i in range(n):
        w.difference(c.hull(i))
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    return {"wall_s": wall, "cpu_s": cpu, "volume": fraction_text(w.volume()), "rss_before_kb": base,
            "peak_kb": _memory_kb()[1], "cells": w.n_cells}


def sharded_workload(args) -> dict:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from csgnb.distributed.sharded import ShardedWorkpiece
    from csgnb.octree import Workpiece

    n = args.dodecahedra
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        single = pool.submit(_single_carve, n, args.dodecahedron_radius, args.threshold).result()
    print(f"single workpiece: {n} dodecahedra in {single['wall_s']:.1f} s wall, {single['cpu_s']:.1f} s CPU; "
          f"peak {single['peak_kb'] / 1024:.0f} MB ({(single['peak_kb'] - single['rss_before_kb']) / 1024:.0f} MB "
          "above its start)", flush=True)
    cluster = LocalCluster(**local_cluster_kwargs(args.workers))
    client = Client(cluster)
    client.register_plugin(WarmUpPlugin(), name=WarmUpPlugin.name)
    try:
        grid, c = _carving(n, args.dodecahedron_radius)
        s = ShardedWorkpiece(Workpiece.box([-4.6] * 3, [4.6] * 3, grid=grid, threshold=args.threshold), client,
                             args.shards, batch=args.batch)
        bases = client.run(_reset_peak)
        worker_cpu0 = sum(client.run(time.process_time).values())
        cpu0, t0 = time.process_time(), time.perf_counter()
        for i in range(n):
            s.difference(c.hull(i))
        s.flush()
        wall = time.perf_counter() - t0
        cpu = time.process_time() - cpu0 + sum(client.run(time.process_time).values()) - worker_cpu0
        peaks = {a: kb[1] for a, kb in client.run(_memory_kb).items()}
        stats = s.stats()
        volume = s.volume()
    finally:
        client.close()
        cluster.close()
    if volume != parse_fraction(single["volume"]):
        raise SystemExit("MISMATCH: the sharded volume differs from the single workpiece's")
    busy: dict[str, float] = {}
    for st in stats:
        busy[st["worker"]] = busy.get(st["worker"], 0.0) + st["busy_s"]
    idle = args.workers * wall - sum(busy.values())
    peak_worker = max(peaks.values())
    above = max(peaks[a] - bases[a] for a in peaks)
    single_above = single["peak_kb"] - single["rss_before_kb"]
    print(f"sharded ({s.n_shards} shards {s.counts}, {args.workers} workers, batch {args.batch}): {wall:.1f} s wall, "
          f"{cpu:.1f} s CPU -- {wall / single['wall_s']:.2f}x the single workpiece's wall time")
    print(f"  Booleans routed {s.messages} ({s.messages / n:.2f} shards per dodecahedron) in {s.calls} messages; "
          f"workers inside Booleans {sum(busy.values()):.1f} s of {args.workers * wall:.1f} s "
          f"(communication and idling {idle:.1f} s)")
    print(f"  memory: worker peak {peak_worker / 1024:.0f} MB ({above / 1024:.0f} MB above its start) against "
          f"{single['peak_kb'] / 1024:.0f} MB ({single_above / 1024:.0f} MB) for the single workpiece: "
          f"{peak_worker / single['peak_kb']:.0%} whole, {above / max(single_above, 1):.0%} above the start")
    print("  exact volumes: sharded == single")
    single = {k: v for k, v in single.items() if k != "volume"}  # ~100,000 digits; equality is checked above
    return {"dodecahedra": n, "shards": s.n_shards, "batch": args.batch, "single": single,
            "sharded": {"wall_s": wall, "cpu_s": cpu, "messages": s.messages, "calls": s.calls,
                        "busy_s_per_worker": busy, "idle_s": idle, "worker_peak_kb": peaks,
                        "worker_start_kb": bases, "per_shard": stats},
            "wall_ratio": wall / single["wall_s"], "memory_ratio": peak_worker / single["peak_kb"],
            "memory_ratio_above_start": above / max(single_above, 1)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", default=None, help="write the figures here")
    p.add_argument("--resolution", type=float, default=0.0,
                   help="grid step in mm (default 0: fitted as `python -m csgnb.mill` does; 1.0 for a quick run)")
    p.add_argument("--jobs", type=int, default=16, help="how many of the 16 jobs")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--workloads", nargs="+", default=["batch", "sharded"], choices=["batch", "sharded"])
    p.add_argument("--dodecahedra", type=int, default=1000, help="dodecahedra of the sharded carving")
    p.add_argument("--dodecahedron-radius", type=float, default=0.5)
    p.add_argument("--threshold", type=int, default=150, help="the workpieces' BSP threshold (as bench_milling)")
    p.add_argument("--shards", type=int, default=8)
    p.add_argument("--batch", type=int, default=32, help="Booleans per message to a shard")
    args = p.parse_args(argv)
    figures = {}
    if "batch" in args.workloads:
        figures["batch"] = batch_workload(args)
        if figures["batch"] is None:
            return 1
    if "sharded" in args.workloads:
        figures["sharded"] = sharded_workload(args)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(figures, fh, indent=1, default=str)
    return 0


def batch_workload(args) -> dict | None:
    batch = jobs(args.resolution or None, args.jobs)
    load_before = _load()
    warm_worker()  # as every worker is warmed: kernels loaded, first-use imports done

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
        return None
    inside = sum(r.wall_s for r in results)
    overhead_ms = (args.workers * batch_wall - inside) * 1000 / len(batch)
    quiet = max(load_before, load_after) <= (os.cpu_count() or 1)
    print(f"batch:  {len(batch)} jobs on {args.workers} workers in {batch_wall:.1f} s wall, {batch_cpu:.1f} s CPU "
          f"(cluster start + warm-up {startup:.1f} s, not included); speed-up {serial_wall / batch_wall:.2f}x")
    median = float(np.median([r.wall_s for r in results]))
    print(f"per-task overhead {overhead_ms:.0f} ms ({overhead_ms / 10 / median:.1f}% of the median job, "
          f"{median:.2f} s; idle tail included); empty task round trip {noop_ms:.2f} ms")
    print(f"load average {load_before:.1f} before, {load_after:.1f} after, {os.cpu_count()} cores"
          + ("" if quiet else ": NOT QUIET, other processes shared the cores; the figures are provisional"))
    print("exact volumes and STL bytes: batch == serial for every job")
    return {"jobs": len(batch), "workers": args.workers, "resolution_mm": args.resolution,
            "serial": {"wall_s": serial_wall, "cpu_s": serial_cpu},
            "batch": {"wall_s": batch_wall, "cpu_s": batch_cpu, "startup_s": startup, "task_s": inside,
                      "per_task_overhead_ms": overhead_ms},
            "median_job_s": float(np.median([r.wall_s for r in results])),
            "noop_task_ms": noop_ms, "speedup": serial_wall / batch_wall,
            "load_before": load_before, "load_after": load_after, "cores": os.cpu_count(), "quiet": quiet,
            "per_job": {r.name: {"serial_s": s.wall_s, "batch_task_s": r.wall_s, "moves": r.moves}
                        for r, s in zip(results, serial, strict=True)}}


if __name__ == "__main__":
    sys.exit(main())
