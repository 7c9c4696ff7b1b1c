"""Figure 10: exact BSP Booleans on random BSP pairs, time against output size; naive cut as the baseline.

Random BSPs as in the paper's §4.3 (random points in a cube, the leaf there split along a
random direction, random in/out labels), 1-200 nodes each, a random operation among
union, intersection and difference. For each pair, in one process and on one core, 128-bit:

* the merge (mesh cutting, §3.5; ``csgnb.bsp.merge``) with edge descent, and the same merge
  with the naive classify-every-vertex cut (``naive=True``) as the baseline (the same output
  tree, checked);
* redundancy removal (§3.7: extract + re-import, ``remove_redundancy``), timed apart and
  compared with the merge it follows;
* bytes of mesh store per output BSP node: the rows of the merge's store in use (up to its
  high-water marks, free lists included) and the arrays allocated, over the output nodes.

Then a merge of two ~20-node BSPs called from Python end to end, median per call:
``merge(a, b, fn, lo, hi)`` and ``A.merge(B, fn)`` with and without redundancy removal.

Each pair's figures are the best CPU time (``time.process_time``) of ``--repeats`` runs; the
end-to-end figure is a median of wall-clock calls. The clock is measured in this process
(``benchmarks/_clock.py``) and printed with the load average: figures taken on a shared
machine are provisional. There is no BSP library to run side by side (manifold3d and trimesh
operate on meshes, not BSPs); the naive cut is the baseline.

Usage: ``python benchmarks/bench_booleans.py [--pairs 200] [--seed 0] [--json PATH]``.
Targets (issue 10): >= 20 M output BSP nodes per second (the paper: 40-50 M, ~90 cycles per
node at 4.2 GHz); redundancy removal <= the merge's time; a ~20-node merge from Python
<= 30 us end to end; mesh store per BSP node: the paper's 600-850 B.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _clock import load_average, measure_clock_ghz, nominal_clock_ghz

from csgnb.bsp import BSP, DIFFERENCE, INTERSECTION, UNION, merge, random_bsp, remove_redundancy
from csgnb.mesh.halfedge import NF, NH, NP, NV

TARGET_NODES_PER_SECOND = 20e6
TARGET_SMALL_MERGE_US = 30
PAPER_BYTES_PER_NODE = (600, 850)
EXTENT = 64
OPS = {"union": UNION, "intersection": INTERSECTION, "difference": DIFFERENCE}
# The store's arrays by the count of rows in use (the others -- counts, the loop scratch -- count whole).
_ROWS_IN_USE = {"palette": NP, "vx": NV, "vdf": NV, "vmark": NV, "free_v": NV, "he": NH, "hmark": NH, "free_h": NH,
                "fc": NF, "free_f": NF}


def best_of(fn, repeats: int):
    """(best CPU seconds of ``repeats`` calls, the last call's result)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def store_bytes(store) -> tuple[int, int]:
    """(bytes of the rows in use, bytes allocated) of a mesh store's arrays."""
    m, counts = store.m, store.counts
    allocated = sum(a.nbytes for a in m)
    used = 0
    for name, a in zip(m._fields, m, strict=True):
        rows = int(counts[_ROWS_IN_USE[name]]) if name in _ROWS_IN_USE else a.shape[0]
        used += a.nbytes // max(a.shape[0], 1) * rows
    return used, allocated


def measure_pair(a, b, op: str, repeats: int, lo, hi) -> dict:
    fn = OPS[op]
    seconds, result = best_of(lambda: merge(a, b, fn, lo, hi), repeats)
    naive_seconds, naive = best_of(lambda: merge(a, b, fn, lo, hi, naive=True), repeats)
    assert np.array_equal(naive.tree.plane, result.tree.plane) and np.array_equal(naive.tree.label, result.tree.label)
    simplify_seconds, simple = best_of(lambda: remove_redundancy(result), repeats)
    used, allocated = store_bytes(result.store)
    return {"nodes_a": a.n_nodes, "nodes_b": b.n_nodes, "op": op, "output_nodes": result.tree.n_nodes,
            "seconds": seconds, "naive_seconds": naive_seconds, "simplified_nodes": simple.n_nodes,
            "simplify_seconds": simplify_seconds, "store_bytes_used": used, "store_bytes_allocated": allocated}


def measure_small_merges(n_inner: int, calls: int, seed: int) -> dict:
    """Median microseconds per call of a merge of two (2 n_inner + 1)-node BSPs, from Python, end to end."""
    rng = np.random.default_rng(seed)
    lo, hi = [-EXTENT] * 3, [EXTENT] * 3
    pairs = [(BSP(random_bsp(n_inner, seed=int(rng.integers(2**31)), extent=EXTENT, max_normal=16), lo, hi),
              BSP(random_bsp(n_inner, seed=int(rng.integers(2**31)), extent=EXTENT, max_normal=16), lo, hi))
             for _ in range(16)]
    ways = {
        "merge(a, b, fn, lo, hi)": lambda A, B: merge(A.tree, B.tree, UNION, lo, hi),
        "A.merge(B, fn, simplify=False)": lambda A, B: A.merge(B, UNION, simplify=False),
        "A.merge(B, fn) (with redundancy removal)": lambda A, B: A.merge(B, UNION),
    }
    out = {"nodes_per_operand": 2 * n_inner + 1, "calls": calls,
           "mean_output_nodes": float(np.mean([merge(A.tree, B.tree, UNION, lo, hi).tree.n_nodes
                                               for A, B in pairs])), "median_us": {}}
    for name, call in ways.items():
        call(*pairs[0])  # warm
        times = np.empty(calls)
        for i in range(calls):
            A, B = pairs[i % len(pairs)]
            t0 = time.perf_counter()
            call(A, B)
            times[i] = time.perf_counter() - t0
        out["median_us"][name] = float(np.median(times) * 1e6)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--max-nodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="best of this many runs per pair")
    parser.add_argument("--small-calls", type=int, default=2000, help="calls of the ~20-node merge")
    parser.add_argument("--clock-ghz", type=float, default=None, help="clock for ns -> cycles (default: measured)")
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()

    nominal = nominal_clock_ghz()
    measured = measure_clock_ghz()
    clock = args.clock_ghz or measured
    load = load_average()
    rng = np.random.default_rng(args.seed)
    lo, hi = [-EXTENT] * 3, [EXTENT] * 3
    warm = random_bsp(10, seed=1, extent=EXTENT, max_normal=16)
    remove_redundancy(merge(warm, warm, UNION, lo, hi))  # compile outside the timings
    merge(warm, warm, UNION, lo, hi, naive=True)
    rows = []
    for _ in range(args.pairs):
        # n inner nodes give 2n + 1 nodes: sizes 1 .. max_nodes.
        na, nb = (int(x) for x in rng.integers(0, (args.max_nodes - 1) // 2 + 1, 2))
        op = str(rng.choice(list(OPS)))
        a = random_bsp(na, seed=int(rng.integers(2**31)), extent=EXTENT, max_normal=16)
        b = random_bsp(nb, seed=int(rng.integers(2**31)), extent=EXTENT, max_normal=16)
        rows.append(measure_pair(a, b, op, args.repeats, lo, hi))
    small = measure_small_merges(10, args.small_calls, args.seed + 1)

    out_nodes = np.array([r["output_nodes"] for r in rows], float)
    secs = np.array([r["seconds"] for r in rows])
    naive_secs = np.array([r["naive_seconds"] for r in rows])
    simp_secs = np.array([r["simplify_seconds"] for r in rows])
    used = np.array([r["store_bytes_used"] for r in rows], float)
    alloc = np.array([r["store_bytes_allocated"] for r in rows], float)
    big = out_nodes >= np.percentile(out_nodes, 75)
    rate, rate_big = out_nodes.sum() / secs.sum(), out_nodes[big].sum() / secs[big].sum()
    naive_rate, naive_rate_big = out_nodes.sum() / naive_secs.sum(), out_nodes[big].sum() / naive_secs[big].sum()
    removal_ratio, removal_ratio_big = simp_secs.sum() / secs.sum(), simp_secs[big].sum() / secs[big].sum()
    bytes_used, bytes_alloc = used[big].sum() / out_nodes[big].sum(), alloc[big].sum() / out_nodes[big].sum()

    nom = f", nominal {nominal:.2f} GHz" if nominal else ""
    print(f"clock {clock:.2f} GHz (measured{nom}); CPU time of this process, best of {args.repeats} per pair; "
          f"load average {load}")
    print(f"\nFigure 10 -- {len(rows)} random BSP pairs (1-{args.max_nodes} nodes), one core, 128-bit; "
          f"naive cut in the same run")
    print(f"{'output nodes':>13} {'pairs':>5} {'merge ms':>9} {'M nodes/s':>9} {'cyc/node':>8} {'naive ms':>9} "
          f"{'naive M/s':>9} {'naive/edge':>10} {'removal ms':>10} {'rem/merge':>9} {'simplified':>10} "
          f"{'B/node used':>11} {'B/node alloc':>12}")
    edges = [0, 10, 100, 1000, 10000, 10**9]
    for lo_n, hi_n in zip(edges[:-1], edges[1:], strict=True):
        sel = (out_nodes >= lo_n) & (out_nodes < hi_n)
        if not sel.any():
            continue
        n, s, ns, ss = out_nodes[sel].sum(), secs[sel].sum(), naive_secs[sel].sum(), simp_secs[sel].sum()
        k = int(sel.sum())
        print(f"{f'{lo_n}-{hi_n - 1}':>13} {k:>5} {1e3 * s / k:>9.3f} {n / s / 1e6:>9.3f} {s / n * 1e9 * clock:>8.0f} "
              f"{1e3 * ns / k:>9.3f} {n / ns / 1e6:>9.3f} {ns / s:>10.2f} {1e3 * ss / k:>10.3f} {ss / s:>9.2f} "
              f"{np.mean([r['simplified_nodes'] for r, t in zip(rows, sel, strict=True) if t]):>10.1f} "
              f"{used[sel].sum() / n:>11.0f} {alloc[sel].sum() / n:>12.0f}")
    verdict = "met" if rate >= TARGET_NODES_PER_SECOND else "NOT met"
    print(f"\noutput nodes per second: {rate / 1e6:.3f} M overall, {rate_big / 1e6:.3f} M on the largest quarter "
          f"(naive cut: {naive_rate / 1e6:.3f} M, {naive_rate_big / 1e6:.3f} M); "
          f"{secs[big].sum() / out_nodes[big].sum() * 1e9 * clock:.0f} cycles per node on the largest quarter; "
          f"target >= {TARGET_NODES_PER_SECOND / 1e6:.0f} M: {verdict} (paper: 40-50 M)")
    verdict = "met" if removal_ratio <= 1 else "NOT met"
    print(f"redundancy removal / merge time: {removal_ratio:.2f} overall, {removal_ratio_big:.2f} on the largest "
          f"quarter; target <= 1: {verdict}")
    for name, us in small["median_us"].items():
        verdict = "met" if us <= TARGET_SMALL_MERGE_US else "NOT met"
        print(f"{small['nodes_per_operand']}-node pair, {name}: median {us:.1f} us "
              f"(mean {small['mean_output_nodes']:.0f} output nodes); target <= {TARGET_SMALL_MERGE_US} us: {verdict}")
    lo_b, hi_b = PAPER_BYTES_PER_NODE
    print(f"mesh store per output node (largest quarter): {bytes_used:.0f} B in use, {bytes_alloc:.0f} B allocated; "
          f"paper: {lo_b}-{hi_b} B")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"clock_ghz": clock, "clock_measured_ghz": measured, "clock_nominal_ghz": nominal,
                       "load_average": load, "output_nodes_per_second": rate,
                       "output_nodes_per_second_largest_quarter": rate_big,
                       "naive_output_nodes_per_second": naive_rate,
                       "naive_output_nodes_per_second_largest_quarter": naive_rate_big,
                       "removal_over_merge_time": removal_ratio,
                       "removal_over_merge_time_largest_quarter": removal_ratio_big,
                       "store_bytes_per_node_used_largest_quarter": bytes_used,
                       "store_bytes_per_node_allocated_largest_quarter": bytes_alloc, "small_merge": small,
                       "targets": {"output_nodes_per_second": TARGET_NODES_PER_SECOND, "removal_over_merge": 1,
                                   "small_merge_us": TARGET_SMALL_MERGE_US, "paper_bytes_per_node":
                                       PAPER_BYTES_PER_NODE}, "rows": rows}, fh, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
