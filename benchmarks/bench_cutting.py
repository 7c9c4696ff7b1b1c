"""Figure 9: exact mesh cutting and boundary extraction on the deepest BSP, edge descent vs naive.

Two measurements, in one process and on one core, 128-bit:

* **slab micro-benchmark** -- one cut of a convex cell: a box in a
  :class:`~csgnb.mesh.halfedge.MeshStore` cut by one plane (a *slab* plane crossing its 4
  vertical edges, and a *diagonal* one crossing 6), with edge descent and with the naive
  classify-every-vertex baseline, in a kernel loop that restores the box after each cut
  (its 24 half-edge rows, 6 face rows and the row counts are copied back; the cut's new rows
  are reused by the next one, the classification stamp keeps counting, so nothing is cached
  between cuts). The same loop without the cut is timed too and subtracted. The store stays
  a few KB (in L1) and every cut takes the same path, so this is the best case of one cut.
  A cross-check loop adds the box, cuts it and releases both parts (less the same loop
  without the cut: that difference also holds releasing the rows the cut created).
* **Figure 9** -- the linear BSP of N planes tangent to a sphere (integer normals):
  extracting it cuts one ever more complex convex polytope N times. Per N: the cell phase
  with edge descent (``extract_cells``) and with the naive baseline (``naive=True``), in
  cuts per second and cycles per cut; the full extraction (``extract_boundary``: cells,
  face clipping, T-junctions); exact vertex classifications and constructions per cut; and
  the extraction kernel alone (``kernel ns``: the store, box and stack set up untimed), which
  says how much of a small N's cost is Python set-up.

Times are CPU time of this process (``time.process_time``), best of ``--repeats``; cycles use
the clock measured in this process (``benchmarks/_clock.py``), printed with the nominal one
and the load average -- figures taken on a shared machine are provisional.

Usage: ``python benchmarks/bench_cutting.py [--sizes 50 100 ...] [--order spiral|random] [--json PATH]``.
Targets (issue 10, from paper §4.2: 2.5 M cuts/s at 4.2 GHz): <= 1,700 cycles per cut, i.e.
>= 1.25 M cuts/s at ~2.1 GHz, at every N up to 2,000; per-cut cost growing sub-linearly with N
while the naive baseline grows linearly.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _clock import bare_jit, best_cpu_time, load_average, measure_clock_ghz, nominal_clock_ghz

from csgnb._views import unmanaged, unmanaged_tuple
from csgnb.bsp.extract import KEEP_CELLS, Extractor, extract_boundary, extract_cells
from csgnb.bsp.scenes import tangent_plane_bsp
from csgnb.exact.wide import to_wide
from csgnb.mesh.cutting import CUT_PROPER, cut, cut_cell_inline, cut_cell_naive
from csgnb.mesh.halfedge import (
    FREE_F,
    FREE_H,
    FREE_V,
    N_CLASSIFY,
    N_CONSTRUCT,
    NF,
    NH,
    NV,
    MeshStore,
    add_box_cell,
    box_planes,
    release_cell,
)

TARGET_CUTS_PER_SECOND = 1.25e6
TARGET_CYCLES_PER_CUT = 1700
RADIUS = 1 << 12
SLAB_PLANES = {  # through (about) the box centre; the section is a quadrilateral / a hexagon
    "slab (4 crossings)": [3, 5, 64, -7],
    "diagonal (6 crossings)": [7, 11, 13, -3],
}
NO_CUT, EDGE, NAIVE = 0, 1, 2


# ---------------------------------------------------------------------------
# slab micro-benchmark


@bare_jit
def _slab_restore_kernel(m, h, he0, fc0, counts0, plane, reps, mode, work, path):
    """``reps`` times: cut the box of handle ``h`` by ``plane`` (mode EDGE / NAIVE; NO_CUT: no cut), then
    restore the box from ``he0``, ``fc0`` and ``counts0``. Returns how many cuts were not proper (0 expected)."""
    m = unmanaged_tuple(m)
    he0, fc0, counts0 = unmanaged(he0), unmanaged(fc0), unmanaged(counts0)
    work, path = unmanaged(work), unmanaged(path)
    misses = 0
    for _ in range(reps):
        if mode != NO_CUT:
            if mode == EDGE:
                status, a, b = cut_cell_inline(m, h, plane, -1, -1, path)
            else:
                status, a, b = cut_cell_naive(m, work, h, plane, -1, -1)
            if status != CUT_PROPER:
                misses += 1
        for i in range(he0.shape[0]):
            for c in range(4):
                m.he[i, c] = he0[i, c]
        for i in range(fc0.shape[0]):
            for c in range(3):
                m.fc[i, c] = fc0[i, c]
        for k in (NV, NH, NF, FREE_V, FREE_H, FREE_F):  # not STAMP: cached sides must not survive a cut
            m.counts[k] = counts0[k]
    return misses


@bare_jit
def _slab_add_release_kernel(m, rows, plane, reps, mode, work, path):
    """``reps`` times: add the box of palette ``rows``, cut it by ``plane`` (mode EDGE / NAIVE; NO_CUT: no
    cut) and release what is left. Returns how many cuts were not proper (0 expected)."""
    m = unmanaged_tuple(m)
    work, path = unmanaged(work), unmanaged(path)
    misses = 0
    for _ in range(reps):
        h = add_box_cell(m, rows, -1)
        if mode == NO_CUT:
            release_cell(m, h)
            continue
        if mode == EDGE:
            status, a, b = cut_cell_inline(m, h, plane, -1, -1, path)
        else:
            status, a, b = cut_cell_naive(m, work, h, plane, -1, -1)
        if status == CUT_PROPER:
            release_cell(m, a)
            release_cell(m, b)
        else:
            misses += 1
            release_cell(m, h)
    return misses


def measure_slab(name: str, plane, reps: int, repeats: int, clock: float) -> dict:
    lo, hi = [-RADIUS] * 3, [RADIUS] * 3
    store = MeshStore(to_wide([plane], 128))
    store.reserve(256, 1024, 128, loop=32)
    box = store.add_box(lo, hi)
    whole = store.exact_volume(box)
    he0, fc0, counts0 = store.he[: store.counts[NH]].copy(), store.fc[: store.counts[NF]].copy(), store.counts.copy()
    work = np.empty(store.he.shape[0], np.int32)
    path = np.zeros(1, np.int64)
    ns, counted = {}, {}
    for mode in (NO_CUT, EDGE, NAIVE):
        def loop(mode=mode):
            assert _slab_restore_kernel(store.m, box, he0, fc0, counts0, 0, reps, mode, work, path) == 0

        before = store.counts[[N_CLASSIFY, N_CONSTRUCT]].copy()
        ns[mode] = best_cpu_time(loop, repeats) / reps * 1e9  # the warm-up call compiles
        counted[mode] = (store.counts[[N_CLASSIFY, N_CONSTRUCT]] - before) / (reps * (repeats + 1))
    check = cut(store, box, 0)  # after the loops: the restored box cuts into parts of its volume
    assert check.proper and store.exact_volume(check.negative) + store.exact_volume(check.positive) == whole

    # cross-check: add / cut / release
    store = MeshStore(np.concatenate([to_wide([plane], 128), box_planes(lo, hi, 128)]))
    store.reserve(256, 1024, 128, loop=32)
    rows = np.arange(1, 7, dtype=np.int64)
    work = np.empty(store.he.shape[0], np.int32)
    add_ns = {}
    for mode in (NO_CUT, EDGE, NAIVE):
        def loop(mode=mode):
            assert _slab_add_release_kernel(store.m, rows, 0, reps, mode, work, path) == 0

        add_ns[mode] = best_cpu_time(loop, repeats) / reps * 1e9
    edge_ns, naive_ns = ns[EDGE] - ns[NO_CUT], ns[NAIVE] - ns[NO_CUT]
    return {"plane": name, "coefficients": [int(c) for c in plane], "reps": reps, "restore_ns": ns[NO_CUT],
            "edge_ns": edge_ns, "naive_ns": naive_ns, "edge_cycles": edge_ns * clock,
            "naive_cycles": naive_ns * clock, "edge_cuts_per_second": 1e9 / edge_ns,
            "classifications_per_cut": float(counted[EDGE][0]), "constructions_per_cut": float(counted[EDGE][1]),
            "naive_classifications_per_cut": float(counted[NAIVE][0]), "add_release_ns": add_ns[NO_CUT],
            "edge_ns_via_add_release": add_ns[EDGE] - add_ns[NO_CUT],
            "naive_ns_via_add_release": add_ns[NAIVE] - add_ns[NO_CUT]}


# ---------------------------------------------------------------------------
# Figure 9


def measure(n: int, order: str, repeats: int, clock: float) -> dict:
    tree = tangent_plane_bsp(n, radius=RADIUS, order=order)
    lo, hi = [-2 * RADIUS] * 3, [2 * RADIUS] * 3
    store, _ = extract_cells(tree, lo, hi)  # warm-up (compiles on the first size)
    extract_cells(tree, lo, hi, naive=True)
    extract_boundary(tree, lo, hi)
    cut_s = best_cpu_time(lambda: extract_cells(tree, lo, hi), repeats)
    kernel_s = float("inf")  # the kernel call(s) alone: the store, box and stack set up outside the timing
    for _ in range(repeats):
        ex = Extractor(tree, lo, hi, KEEP_CELLS, 1024)
        t0 = time.process_time()
        ex.run()
        kernel_s = min(kernel_s, time.process_time() - t0)
    naive_s = best_cpu_time(lambda: extract_cells(tree, lo, hi, naive=True), max(1, repeats // 2))
    extract_s = best_cpu_time(lambda: extract_boundary(tree, lo, hi), max(1, repeats // 2))
    return {
        "n_planes": n,
        "extract_s": extract_s,
        "cells_s": cut_s,
        "naive_cells_s": naive_s,
        "per_cut_ns": cut_s / n * 1e9,
        "kernel_per_cut_ns": kernel_s / n * 1e9,
        "naive_per_cut_ns": naive_s / n * 1e9,
        "cuts_per_second": n / cut_s,
        "naive_cuts_per_second": n / naive_s,
        "cycles_per_cut": cut_s / n * 1e9 * clock,
        "naive_cycles_per_cut": naive_s / n * 1e9 * clock,
        "classifications_per_cut": int(store.counts[N_CLASSIFY]) / n,
        "constructions_per_cut": int(store.counts[N_CONSTRUCT]) / n,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 500, 1000, 2000])
    parser.add_argument("--order", choices=["spiral", "golden", "random"], default="spiral")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--slab-reps", type=int, default=100_000, help="cuts per timed slab loop")
    parser.add_argument("--clock-ghz", type=float, default=None, help="clock for ns -> cycles (default: measured)")
    parser.add_argument("--json", type=str, default=None, help="write the figures to this file")
    args = parser.parse_args()

    nominal = nominal_clock_ghz()
    measured = measure_clock_ghz()
    clock = args.clock_ghz or measured
    load = load_average()
    slabs = [measure_slab(name, plane, args.slab_reps, args.repeats, clock) for name, plane in SLAB_PLANES.items()]
    rows = [measure(n, args.order, args.repeats, clock) for n in args.sizes]

    nom = f", nominal {nominal:.2f} GHz" if nominal else ""
    print(f"clock {clock:.2f} GHz (measured{nom}); CPU time of this process, best of {args.repeats}; "
          f"load average {load}")
    print(f"\nSlab micro-benchmark -- one cut of the box [-{RADIUS}, {RADIUS}]^3, 128-bit, a kernel loop of "
          f"{args.slab_reps} cut / restore (less the loop without the cut)")
    print(f"{'plane':>24} {'edge ns':>8} {'naive ns':>9} {'edge cyc':>9} {'naive cyc':>10} {'class/cut':>9} "
          f"{'naive cls':>9} {'constr/cut':>10} {'restore ns':>10} | {'via add/release: edge, naive ns':>32}")
    for s in slabs:
        print(f"{s['plane']:>24} {s['edge_ns']:>8.0f} {s['naive_ns']:>9.0f} {s['edge_cycles']:>9.0f} "
              f"{s['naive_cycles']:>10.0f} {s['classifications_per_cut']:>9.1f} "
              f"{s['naive_classifications_per_cut']:>9.1f} {s['constructions_per_cut']:>10.1f} "
              f"{s['restore_ns']:>10.0f} | {s['edge_ns_via_add_release']:>15.0f}, {s['naive_ns_via_add_release']:.0f}"
              f" (add+release {s['add_release_ns']:.0f})")
    print(f"target: one cut <= {TARGET_CYCLES_PER_CUT} cycles = {TARGET_CYCLES_PER_CUT / clock:.0f} ns at "
          f"{clock:.2f} GHz (>= {clock * 1e9 / TARGET_CYCLES_PER_CUT / 1e6:.2f} M cuts/s)")

    print(f"\nFigure 9 -- linear BSP of N tangent planes ({args.order} order), 128-bit, one core; "
          f"cells phase (extract_cells), naive baseline in the same run")
    print(f"{'N':>6} {'M cuts/s':>9} {'naive M/s':>9} {'cut ns':>8} {'kernel ns':>9} {'naive ns':>9} "
          f"{'cycles':>7} {'naive cyc':>9} {'naive/cut':>9} {'class/cut':>9} {'constr/cut':>10} {'cells s':>8} "
          f"{'extract s':>9}")
    for r in rows:
        print(f"{r['n_planes']:>6} {r['cuts_per_second'] / 1e6:>9.3f} {r['naive_cuts_per_second'] / 1e6:>9.3f} "
              f"{r['per_cut_ns']:>8.0f} {r['kernel_per_cut_ns']:>9.0f} {r['naive_per_cut_ns']:>9.0f} "
              f"{r['cycles_per_cut']:>7.0f} "
              f"{r['naive_cycles_per_cut']:>9.0f} {r['naive_per_cut_ns'] / r['per_cut_ns']:>9.1f} "
              f"{r['classifications_per_cut']:>9.1f} {r['constructions_per_cut']:>10.2f} {r['cells_s']:>8.4f} "
              f"{r['extract_s']:>9.4f}")
    total_cuts = sum(r["n_planes"] for r in rows)
    cuts_per_second = total_cuts / sum(r["cells_s"] for r in rows)
    worst = min(r["cuts_per_second"] for r in rows)
    worst_cycles = max(r["cycles_per_cut"] for r in rows)
    sizes = np.log([r["n_planes"] for r in rows])
    growth = naive_growth = float("nan")
    if len(set(sizes)) > 1:
        growth = float(np.polyfit(sizes, np.log([r["per_cut_ns"] for r in rows]), 1)[0])
        naive_growth = float(np.polyfit(sizes, np.log([r["naive_per_cut_ns"] for r in rows]), 1)[0])
    rate_ok = "met" if worst >= TARGET_CUTS_PER_SECOND else "NOT met"
    cycles_ok = "met" if worst_cycles <= TARGET_CYCLES_PER_CUT else "NOT met"
    print(f"\ncuts per second: {cuts_per_second / 1e6:.3f} M over all sizes, {worst / 1e6:.3f} M at the slowest N; "
          f"target >= {TARGET_CUTS_PER_SECOND / 1e6:.2f} M at every N: {rate_ok}")
    print(f"cycles per cut at the slowest N: {worst_cycles:.0f}; target <= {TARGET_CYCLES_PER_CUT} "
          f"(paper: 2.5 M cuts/s at 4.2 GHz): {cycles_ok}")
    print(f"per-cut cost grows like N^{growth:.2f} (edge descent) vs N^{naive_growth:.2f} (naive)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"clock_ghz": clock, "clock_measured_ghz": measured, "clock_nominal_ghz": nominal,
                       "load_average": load, "target_cuts_per_second": TARGET_CUTS_PER_SECOND,
                       "target_cycles_per_cut": TARGET_CYCLES_PER_CUT, "slab": slabs,
                       "cuts_per_second": cuts_per_second, "cuts_per_second_slowest_n": worst,
                       "cycles_per_cut_slowest_n": worst_cycles, "order": args.order,
                       "per_cut_growth_exponent": growth, "naive_per_cut_growth_exponent": naive_growth,
                       "rows": rows}, fh, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
