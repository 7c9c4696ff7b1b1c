"""Figure 10: exact BSP Booleans on random BSP pairs, time against output size.

Random BSPs as in the paper's §4.3 (random points in a cube, the leaf there split along a
random direction, random in/out labels), 1-200 nodes each, a random operation among
union, intersection and difference. Each merge (mesh cutting, §3.5) is timed on one core;
redundancy removal (extract + re-import, §3.7) is timed separately. There is no BSP
baseline to run side by side (manifold3d and trimesh operate on meshes, not BSPs); the
paper's figure is printed for comparison.

Usage: ``python benchmarks/bench_booleans.py [--pairs 200] [--seed 0] [--json PATH]``.
Target: >= 20 M output BSP nodes per second on one core (the paper reports 40-50 M).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from csgnb.bsp import DIFFERENCE, INTERSECTION, UNION, merge, random_bsp, remove_redundancy

TARGET_NODES_PER_SECOND = 20e6
EXTENT = 64
OPS = {"union": UNION, "intersection": INTERSECTION, "difference": DIFFERENCE}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--max-nodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    lo, hi = [-EXTENT] * 3, [EXTENT] * 3
    warm = random_bsp(10, seed=1, extent=EXTENT, max_normal=16)
    remove_redundancy(merge(warm, warm, UNION, lo, hi))  # compile outside the timings
    rows = []
    for _ in range(args.pairs):
        # n inner nodes give 2n + 1 nodes: sizes 1 .. max_nodes.
        na, nb = (int(x) for x in rng.integers(0, (args.max_nodes - 1) // 2 + 1, 2))
        op = str(rng.choice(list(OPS)))
        a = random_bsp(na, seed=int(rng.integers(2**31)), extent=EXTENT, max_normal=16)
        b = random_bsp(nb, seed=int(rng.integers(2**31)), extent=EXTENT, max_normal=16)
        t0 = time.perf_counter()
        result = merge(a, b, OPS[op], lo, hi)
        t1 = time.perf_counter()
        simple = remove_redundancy(result)
        t2 = time.perf_counter()
        rows.append({"nodes_a": a.n_nodes, "nodes_b": b.n_nodes, "op": op, "output_nodes": result.tree.n_nodes,
                     "seconds": t1 - t0, "simplified_nodes": simple.n_nodes, "simplify_seconds": t2 - t1})
    out_nodes = np.array([r["output_nodes"] for r in rows], float)
    secs = np.array([r["seconds"] for r in rows])
    rate = out_nodes.sum() / secs.sum()
    big = out_nodes >= np.percentile(out_nodes, 75)
    rate_big = out_nodes[big].sum() / secs[big].sum()
    print(f"Figure 10 -- {len(rows)} random BSP pairs (1-{args.max_nodes} nodes), one core, 128-bit")
    print(f"{'output nodes':>14} {'pairs':>6} {'merge ms':>10} {'M nodes/s':>10} {'simplified':>11} "
          f"{'simplify ms':>12}")
    edges = [0, 10, 100, 1000, 10000, 10**9]
    for lo_n, hi_n in zip(edges[:-1], edges[1:], strict=True):
        sel = [r for r in rows if lo_n <= r["output_nodes"] < hi_n]
        if not sel:
            continue
        n = sum(r["output_nodes"] for r in sel)
        s = sum(r["seconds"] for r in sel)
        print(f"{f'{lo_n}-{hi_n - 1}':>14} {len(sel):>6} {1e3 * s / len(sel):>10.3f} {n / s / 1e6:>10.3f} "
              f"{np.mean([r['simplified_nodes'] for r in sel]):>11.1f} "
              f"{1e3 * np.mean([r['simplify_seconds'] for r in sel]):>12.3f}")
    verdict = "met" if rate >= TARGET_NODES_PER_SECOND else "NOT met"
    print(f"\noutput nodes per second: {rate / 1e6:.3f} M overall, {rate_big / 1e6:.3f} M on the largest quarter; "
          f"target >= {TARGET_NODES_PER_SECOND / 1e6:.0f} M: {verdict} (paper: 40-50 M)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"output_nodes_per_second": rate, "output_nodes_per_second_largest_quarter": rate_big,
                       "rows": rows}, fh, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
