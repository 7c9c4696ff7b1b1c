"""Figure 9: exact mesh cutting and boundary extraction on the deepest BSP, edge descent vs naive.

The scene is a linear BSP of N planes tangent to a sphere (integer normals, 128-bit):
extracting it cuts one ever more complex convex polytope N times. For each N the
benchmark times, in one process and on one core,

* the cell phase with edge descent (``extract_cells``) and with the naive
  classify-every-vertex baseline (``naive=True``): nanoseconds per cut;
* the full extraction (``extract_boundary``: cells, face clipping, T-junctions);
* exact vertex classifications and constructions per cut (deterministic counts).

Usage: ``python benchmarks/bench_cutting.py [--sizes 50 100 ...] [--order spiral|random] [--json PATH]``.
Target (paper §4.2): >= 2.5 M mesh-plane cuts per second on one core; per-cut cost growing
sub-linearly with N while the naive baseline grows linearly.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from csgnb.bsp.extract import extract_boundary, extract_cells
from csgnb.bsp.scenes import tangent_plane_bsp
from csgnb.mesh.halfedge import N_CLASSIFY, N_CONSTRUCT

TARGET_CUTS_PER_SECOND = 2.5e6
RADIUS = 1 << 12


def best_time(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def measure(n: int, order: str, repeats: int) -> dict:
    tree = tangent_plane_bsp(n, radius=RADIUS, order=order)
    lo, hi = [-2 * RADIUS] * 3, [2 * RADIUS] * 3
    store, _ = extract_cells(tree, lo, hi)  # warm-up (compiles on the first size)
    extract_cells(tree, lo, hi, naive=True)
    extract_boundary(tree, lo, hi)
    cut_s = best_time(lambda: extract_cells(tree, lo, hi), repeats)
    naive_s = best_time(lambda: extract_cells(tree, lo, hi, naive=True), max(1, repeats // 2))
    extract_s = best_time(lambda: extract_boundary(tree, lo, hi), max(1, repeats // 2))
    return {
        "n_planes": n,
        "extract_s": extract_s,
        "cells_s": cut_s,
        "per_cut_ns": cut_s / n * 1e9,
        "naive_per_cut_ns": naive_s / n * 1e9,
        "classifications_per_cut": int(store.counts[N_CLASSIFY]) / n,
        "constructions_per_cut": int(store.counts[N_CONSTRUCT]) / n,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 500, 1000, 2000])
    parser.add_argument("--order", choices=["spiral", "golden", "random"], default="spiral")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", type=str, default=None, help="write the figures to this file")
    args = parser.parse_args()

    rows = [measure(n, args.order, args.repeats) for n in args.sizes]
    print(f"Figure 9 -- linear BSP of N tangent planes ({args.order} order), 128-bit, one core")
    print(f"{'N':>6} {'cut ns':>9} {'naive ns':>9} {'naive/cut':>9} {'class/cut':>9} {'constr/cut':>10} "
          f"{'cells s':>9} {'extract s':>9}")
    for r in rows:
        print(f"{r['n_planes']:>6} {r['per_cut_ns']:>9.0f} {r['naive_per_cut_ns']:>9.0f} "
              f"{r['naive_per_cut_ns'] / r['per_cut_ns']:>9.1f} {r['classifications_per_cut']:>9.1f} "
              f"{r['constructions_per_cut']:>10.2f} {r['cells_s']:>9.4f} {r['extract_s']:>9.4f}")
    total_cuts = sum(r["n_planes"] for r in rows)
    cuts_per_second = total_cuts / sum(r["cells_s"] for r in rows)
    sizes = np.array([r["n_planes"] for r in rows], float)
    growth = np.polyfit(np.log(sizes), np.log([r["per_cut_ns"] for r in rows]), 1)[0]
    naive_growth = np.polyfit(np.log(sizes), np.log([r["naive_per_cut_ns"] for r in rows]), 1)[0]
    verdict = "met" if cuts_per_second >= TARGET_CUTS_PER_SECOND else "NOT met"
    print(f"\ncuts per second (all sizes): {cuts_per_second / 1e6:.2f} M   "
          f"target >= {TARGET_CUTS_PER_SECOND / 1e6:.1f} M: {verdict}")
    print(f"per-cut cost grows like N^{growth:.2f} (edge descent) vs N^{naive_growth:.2f} (naive)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"cuts_per_second": cuts_per_second, "order": args.order, "per_cut_growth_exponent": growth,
                       "naive_per_cut_growth_exponent": naive_growth, "rows": rows}, fh, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
