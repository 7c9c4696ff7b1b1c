"""Iterated exact CSG on the octree workpiece (paper §5, Figures 11-14), against manifold3d in the same run.

Two set-ups from the paper, built with csgnb's own tools and sweeps (``csgnb.apps``):

* **drill** (Figures 13-14): a two-flute twist drill (896 triangles, radius 3, 118° point),
  axis 30° from vertical, spinning in 90 steps of 4° per turn. Each step's sweep -- the
  union of the per-triangle prisms between consecutive poses (each the exact hull of a
  triangle at two poses) -- is precomputed once with csgnb (timed apart) and used as a mesh
  tool; three turns with the feed as an exact translation give 270 subtractions from a
  block. manifold3d gets the same prisms (float hulls), unions them per step with
  ``batch_boolean`` (timed apart) and subtracts the same 270 translated steps.
* **gear_sweep** (Figures 11-12): a spur gear (480 triangles) along a cubic Bézier with S
  sample positions; the prism of every triangle between consecutive positions is unioned
  one by one into an empty workpiece (S = 20: ~9,100 unions). manifold3d unions the same
  prisms one by one (``--mf-gear-ops`` of them, to keep its run short).

Printed per workload: per-step times (median, max, first vs last tenth), totals, faces,
BSP work, exact volume vs manifold3d's. ``--json PATH`` writes the figures; ``--sweep``
times the gear sweep at several BSP thresholds (Figure 11).

Targets (issue 11): drill total <= manifold3d's; gear sweep <= 1 ms per union; the median
step of the last tenth <= 1.5x the first tenth's. This machine: see the printed clock.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _clock import nominal_clock_label

from csgnb.apps import sweep, tools
from csgnb.exact import Grid
from csgnb.octree import Tool, Workpiece


def _tenths(ts) -> tuple[float, float]:
    ts = np.asarray(ts)
    k = max(1, len(ts) // 10)
    return float(np.median(ts[:k])), float(np.median(ts[-k:]))


def drill_workload(args) -> dict:
    import manifold3d as m3

    grid = Grid.fit([-12, -12, -16], [12, 12, 8], width=args.width)
    drill = tools.twist_drill().on(grid)
    ds = sweep.drill_sweeps(drill, feed_per_turn=args.feed)
    n_steps = len(ds)
    # -- precompute the 90 sweep volumes (timed apart) -----------------------------------
    t0 = time.perf_counter()
    tools_c = []
    for k in range(n_steps):
        w = Workpiece.empty(grid, threshold=args.threshold)
        for h in ds.steps[k]:
            w |= h
        tools_c.append(Tool.from_bsp(w.to_bsp(), grid=grid))
    csg_pre = time.perf_counter() - t0
    t0 = time.perf_counter()
    tools_m = [m3.Manifold.batch_boolean([m3.Manifold.hull_points(grid.to_model(h.points)) for h in ds.steps[k]],
                                         m3.OpType.Add) for k in range(n_steps)]
    mf_pre = time.perf_counter() - t0
    # -- 270 subtractions ----------------------------------------------------------------
    total = args.turns * n_steps
    lo, hi = np.array([-10.0, -10.0, -15.0]), np.array([10.0, 10.0, 6.0])
    work = Workpiece.box(lo, hi, grid=grid, threshold=args.threshold)
    csg_t = []
    for i in range(total):
        turn, k = divmod(i, n_steps)
        t = time.perf_counter()
        work -= tools_c[k].translated(ds.feed * turn)
        csg_t.append(time.perf_counter() - t)
        if args.verbose and i % 30 == 0:
            print(f"  drill step {i}: {csg_t[-1] * 1e3:.0f} ms, {work}")
    lo_g, hi_g = grid.to_grid(np.stack([lo, hi]))
    cube = m3.Manifold.cube(list(grid.to_model(hi_g[None])[0] - grid.to_model(lo_g[None])[0])).translate(
        list(grid.to_model(lo_g[None])[0]))
    feed_model = ds.feed / grid.scale
    mf_t = []
    for i in range(total):
        turn, k = divmod(i, n_steps)
        tool = tools_m[k].translate(list(feed_model * turn))
        t = time.perf_counter()
        cube = cube - tool
        cube.num_tri()  # manifold3d evaluates lazily: force the Boolean
        mf_t.append(time.perf_counter() - t)
    vol = work.model_volume()
    mf_vol = cube.volume()
    surface = work.surface()
    first, last = _tenths(csg_t)
    mfirst, mlast = _tenths(mf_t)
    return {"steps": total, "csgnb_s": float(sum(csg_t)), "manifold3d_s": float(sum(mf_t)),
            "csgnb_precompute_s": csg_pre, "manifold3d_precompute_s": mf_pre,
            "median_ms": float(np.median(csg_t) * 1e3), "max_ms": float(np.max(csg_t) * 1e3),
            "first_tenth_median_ms": first * 1e3, "last_tenth_median_ms": last * 1e3,
            "manifold3d_median_ms": float(np.median(mf_t) * 1e3), "manifold3d_first_tenth_median_ms": mfirst * 1e3,
            "manifold3d_last_tenth_median_ms": mlast * 1e3,
            "faces": surface.n_polygons, "manifold3d_triangles": int(cube.num_tri()),
            "cells": work.n_cells, "bsp_nodes": work.n_bsp_nodes, "cell_merges": work.stats.merges,
            "volume": float(vol), "manifold3d_volume": float(mf_vol),
            "volume_rel_dev": float(abs(float(vol) - mf_vol) / float(vol)),
            "per_step_ms": [x * 1e3 for x in csg_t], "manifold3d_per_step_ms": [x * 1e3 for x in mf_t]}


def gear_hulls(samples: int, width: int):
    grid = Grid.fit([-10, -20, -10], [70, 40, 20], width=width)
    gear = tools.spur_gear().on(grid)
    control = np.array([[0, 0, 0], [20, 30, 5], [40, -10, 10], [60, 20, 0]], float)
    sweeps = sweep.path_sweep(gear, [sweep.Pose(p) for p in sweep.bezier_points(control, samples)])
    return grid, [h for s in sweeps for h in s.hulls]


def gear_workload(args, samples: int, threshold: int, with_manifold: bool = True) -> dict:
    grid, hulls = gear_hulls(samples, args.width)
    w = Workpiece.empty(grid, threshold=threshold)
    ts = []
    for h in hulls:
        t = time.perf_counter()
        w |= h
        ts.append(time.perf_counter() - t)
    first, last = _tenths(ts)
    out = {"samples": samples, "threshold": threshold, "unions": len(hulls), "csgnb_s": float(sum(ts)),
           "csgnb_ms_per_op": float(np.mean(ts) * 1e3), "median_ms": float(np.median(ts) * 1e3),
           "max_ms": float(np.max(ts) * 1e3), "first_tenth_median_ms": first * 1e3,
           "last_tenth_median_ms": last * 1e3, "cells": w.n_cells, "bsp_nodes": w.n_bsp_nodes}
    if with_manifold:
        import manifold3d as m3

        n = min(len(hulls), args.mf_gear_ops)
        acc = m3.Manifold()
        mts = []
        for h in hulls[:n]:
            piece = m3.Manifold.hull_points(grid.to_model(h.points))
            t = time.perf_counter()
            acc = acc + piece
            acc.num_tri()
            mts.append(time.perf_counter() - t)
        # the same first n unions in csgnb, for a volume comparison
        wn = Workpiece.empty(grid, threshold=threshold)
        for h in hulls[:n]:
            wn |= h
        vol = float(wn.model_volume())
        out.update({"manifold3d_unions": n, "manifold3d_ms_per_op": float(np.mean(mts) * 1e3),
                    "csgnb_ms_per_op_first_n": float(np.mean(ts[:n]) * 1e3),
                    "volume_first_n": vol, "manifold3d_volume_first_n": float(acc.volume()),
                    "volume_rel_dev": abs(vol - float(acc.volume())) / vol})
    out["faces"] = w.surface().n_polygons if args.faces else None
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workloads", nargs="+", default=["drill", "gear_sweep"], choices=["drill", "gear_sweep"])
    parser.add_argument("--width", type=int, default=128)
    parser.add_argument("--threshold", type=int, default=150)
    parser.add_argument("--turns", type=int, default=3)
    parser.add_argument("--feed", type=float, default=1.0, help="drill feed per turn (mm)")
    parser.add_argument("--samples", type=int, nargs="+", default=[20], help="gear sweep sample positions")
    parser.add_argument("--mf-gear-ops", type=int, default=2000, help="gear unions manifold3d runs (one by one)")
    parser.add_argument("--sweep", type=int, nargs="*", default=None, help="thresholds for the Figure 11 sweep")
    parser.add_argument("--faces", action="store_true", help="extract the gear sweep's surface to count faces")
    parser.add_argument("--verbose", action="store_true")
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()

    print(f"csgnb iterated CSG, {args.width}-bit, threshold {args.threshold}, one core, clock {nominal_clock_label()}")
    result = {"clock": nominal_clock_label(), "width": args.width, "threshold": args.threshold, "workloads": {}}
    if "drill" in args.workloads:
        d = drill_workload(args)
        result["workloads"]["drill"] = d
        verdict = "met" if d["csgnb_s"] <= d["manifold3d_s"] else "NOT met"
        flat = d["last_tenth_median_ms"] <= 1.5 * d["first_tenth_median_ms"]
        print(f"\ndrill: {d['steps']} subtractions; csgnb {d['csgnb_s']:.1f} s vs manifold3d {d['manifold3d_s']:.1f} s "
              f"(target csgnb <= manifold3d: {verdict})")
        print(f"  sweeps precomputed: csgnb {d['csgnb_precompute_s']:.1f} s, manifold3d "
              f"{d['manifold3d_precompute_s']:.1f} s (timed apart)")
        print(f"  per step: median {d['median_ms']:.0f} ms, max {d['max_ms']:.0f} ms, first tenth "
              f"{d['first_tenth_median_ms']:.0f} ms, last tenth {d['last_tenth_median_ms']:.0f} ms "
              f"(flat within 1.5x: {'met' if flat else 'NOT met'}); manifold3d median {d['manifold3d_median_ms']:.0f} "
              f"ms, first/last tenth {d['manifold3d_first_tenth_median_ms']:.0f}/"
              f"{d['manifold3d_last_tenth_median_ms']:.0f} ms")
        print(f"  result: {d['faces']} exact polygons ({d['cells']} cells, {d['bsp_nodes']} BSP nodes, "
              f"{d['cell_merges']} cell merges); manifold3d {d['manifold3d_triangles']} triangles; volume "
              f"{d['volume']:.6f} vs {d['manifold3d_volume']:.6f} mm^3 (rel. dev. {d['volume_rel_dev']:.2e})")
    if "gear_sweep" in args.workloads:
        gears = {}
        for s in args.samples:
            g = gear_workload(args, s, args.threshold)
            gears[s] = g
            verdict = "met" if g["csgnb_ms_per_op"] <= 1.0 else "NOT met"
            print(f"\ngear sweep, S = {s}: {g['unions']} unions, csgnb {g['csgnb_s']:.1f} s = "
                  f"{g['csgnb_ms_per_op']:.2f} ms per union (target <= 1 ms: {verdict}); median {g['median_ms']:.2f}, "
                  f"first/last tenth {g['first_tenth_median_ms']:.2f}/{g['last_tenth_median_ms']:.2f} ms")
            print(f"  manifold3d: {g['manifold3d_ms_per_op']:.2f} ms per union over the first "
                  f"{g['manifold3d_unions']} (csgnb {g['csgnb_ms_per_op_first_n']:.2f} ms over the same); volume "
                  f"rel. dev. {g['volume_rel_dev']:.2e}; {g['cells']} cells, {g['bsp_nodes']} BSP nodes")
        main_gear = gears[args.samples[0]]
        result["workloads"]["gear_sweep"] = main_gear
        result["workloads"]["gear_sweep_by_samples"] = {str(k): v for k, v in gears.items()}
    if args.sweep:
        print(f"\nFigure 11: gear sweep (S = {args.samples[0]}) total time by BSP threshold")
        rows = []
        for th in args.sweep:
            g = gear_workload(args, args.samples[0], th, with_manifold=False)
            rows.append({"threshold": th, "csgnb_s": g["csgnb_s"], "cells": g["cells"], "bsp_nodes": g["bsp_nodes"]})
            print(f"  threshold {th:>4}: {g['csgnb_s']:.2f} s, {g['cells']} cells, {g['bsp_nodes']} BSP nodes")
        result["threshold_sweep"] = rows
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=1)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
