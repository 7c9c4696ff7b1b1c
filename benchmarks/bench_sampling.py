"""Sampling quadric CSG surfaces against the paper's Table 2 and the "sampling" rows of Table 1.

Five models of 3, 5, 21, 31 and 80 quadrics, each at three splat radii ("large", "medium",
"small", chosen so that the sample counts are near the paper's rows of the same size class).
Each run is the whole pipeline — normal form, term boxes, sampling domains, subdivision,
emission, clip-set deduplication — from a CSG graph to a ``SampleCloud``; kernels are compiled
(or loaded from the cache) by an untimed first run, the domain cache is emptied before every
timed run, and the best of ``--repeat`` runs is kept. One thread, as in the paper; each row again on all cores
(``--threads``, default every core numba sees; one-thread and all-core runs alternate): the two passes run over
chunks of jobs and leaves in threads, the cloud bit-identical to the one-thread one.

    python benchmarks/bench_sampling.py --json /tmp/bench_sampling.json

``--json PATH`` writes ``{"models": [{"name", "quadrics", "splat", "samples",
"distance_queries", "clip_indices", "sampling_s", "sampling_threads_s", "threads", "unresolved", "feature_points",
"covered_by_neighbours"}, ...]}``. Rows print the regions left unresolved (0 on all five models), and how many
the two rules that close tangency curves handled (feature points, the neighbour rule).
"""

from __future__ import annotations

import argparse
import json
import time

import numba
import numpy as np

import csgnb.csg as csg
from csgnb.csg.gallery import TABLE2, perforated_plate, spheres
from csgnb.sampling import domain_cache_clear, sample_csg

#: name → (builder, {splat: radius}): the models live in csgnb.csg.gallery (one definition for the
#: notebooks, the tests and the benchmarks)
MODELS = TABLE2

#: Table 2 of the paper: (quadrics, splat) → (samples, distance queries, clip indices, sampling ms).
PAPER_TABLE2 = {
    (3, "large"): (5454, 22372, 2, 1.51), (3, "medium"): (23452, 47336, 2, 3.39),
    (3, "small"): (249014, 100398, 2, 8.51),
    (5, "large"): (8112, 103296, 52, 7.63), (5, "medium"): (35904, 215040, 23, 16.45),
    (5, "small"): (329856, 576048, 17, 66.87),
    (21, "large"): (7134, 30802, 78, 6.26), (21, "medium"): (31940, 85744, 37, 18.01),
    (21, "small"): (104972, 171958, 31, 37.91),
    (31, "large"): (28432, 196298, 51, 36.63), (31, "medium"): (91895, 325705, 34, 62.23),
    (31, "small"): (184533, 415847, 29, 83.36),
    (80, "large"): (10176, 194024, 299, 94.47), (80, "medium"): (141200, 558582, 244, 292.35),
    (80, "small"): (655727, 1182464, 236, 623.92),
}  # fmt: skip

#: Table 1 "sampling" rows, samples per second on one 4.8 GHz core.
PAPER_TABLE1 = {
    "single quadric, no subdivision": (135e6, 135e6),
    "single quadric, with subdivision": (40e6, 70e6),
    "simple CSG surface (Figure 9)": (10e6, 50e6),
    "complex CSG surface (Figure 1)": (0.5e6, 2e6),
}


def _time(shape, radius, repeat, threads=1, **kwargs):
    return _time_pair(shape, radius, repeat, (threads,), **kwargs)[0]


def _time_pair(shape, radius, repeat, thread_counts, **kwargs):
    """Best of ``repeat`` runs at each of ``thread_counts``, the counts alternating run by run (so that a slow
    spell of the machine falls on both sides of a ratio, not on one): ``[(seconds, cloud), ...]``."""
    best = [np.inf] * len(thread_counts)
    clouds = [None] * len(thread_counts)
    before = numba.get_num_threads()
    try:
        for threads in thread_counts:
            numba.set_num_threads(threads)
            sample_csg(shape, radius, **kwargs)  # compile / load the kernels outside the timing
        for _ in range(repeat):
            for i, threads in enumerate(thread_counts):
                numba.set_num_threads(threads)
                domain_cache_clear()  # (kept for comparison with earlier runs: the set-up is not cached)
                t0 = time.perf_counter()
                clouds[i] = sample_csg(shape, radius, **kwargs)
                best[i] = min(best[i], time.perf_counter() - t0)
    finally:
        numba.set_num_threads(before)
    return list(zip(best, clouds, strict=True))


def run_table2(repeat: int, only=None, threads: int = 1) -> list[dict]:
    rows = []
    for name, (build, radii) in MODELS.items():
        if only and name not in only:
            continue
        shape = build()
        n_quadrics = len(csg.graph_leaves(shape))
        for splat, r in radii.items():
            (seconds, cloud), (parallel, cloud_n) = _time_pair(shape, r, repeat, (1, threads))
            same = all(np.array_equal(getattr(cloud, f), getattr(cloud_n, f)) for f in (
                "positions", "normals", "radii", "quadric_ids", "clip_start", "clip_count", "clip_indices"))
            if not same:
                raise AssertionError(f"{name} {splat}: {threads} threads changed the samples")
            rows.append({
                "sampling_threads_s": parallel, "threads": threads,
                "name": name, "quadrics": n_quadrics, "splat": splat, "samples": len(cloud),
                "distance_queries": cloud.stats.distance_queries, "clip_indices": cloud.stats.clip_indices,
                "sampling_s": seconds, "radius": r, "normal_form": len(cloud.normal_form),
                "unresolved": cloud.stats.unresolved, "feature_points": cloud.stats.feature_points,
                "covered_by_neighbours": cloud.stats.covered_by_neighbours,
            })  # fmt: skip
    return rows


def run_table1(repeat: int) -> dict[str, float]:
    from csgnb.quadric import hyperboloid_one_sheet

    cases = {
        "single quadric, no subdivision": (csg.sphere((0, 0, 0), 1.0), 0.002, {}),
        "single quadric, with subdivision": (csg.leaf(hyperboloid_one_sheet((1.0, 0.8, 1.2))), 0.004,
                                             {"bounds": ((0, 0, 0), 2.0)}),
        "simple CSG surface (Figure 9)": (spheres(), 0.0108, {}),
        "complex CSG surface (Figure 1)": (perforated_plate(), 0.0456, {}),
    }  # fmt: skip
    out = {}
    for label, (shape, r, kw) in cases.items():
        seconds, cloud = _time(shape, r, repeat, **kw)
        out[label] = len(cloud) / seconds
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per row, best is kept")
    parser.add_argument("--json", metavar="PATH", help="write {'models': [...]} here")
    parser.add_argument("--only", nargs="*", help="model names to run (default: all)")
    parser.add_argument("--no-table1", action="store_true", help="skip the Table 1 rows")
    parser.add_argument("--threads", type=int, default=numba.config.NUMBA_NUM_THREADS,
                        help="threads of the second timing of each row (default: every core)")
    args = parser.parse_args(argv)

    rows = run_table2(args.repeat, args.only, args.threads)
    head = (f"{'model':18s} {'q':>3s} {'dnf':>4s} {'splat':6s} {'radius':>7s} {'samples':>8s} {'paper':>8s} "
            f"{'queries':>8s} {'paper':>8s} {'clip':>5s} {'paper':>5s} {'time ms':>8s} {'paper':>7s} {'ratio':>6s} "
            f"{'unres':>5s} {'feat':>5s} {'nbr':>5s} {f'{args.threads}t ms':>8s} {'x':>5s}")
    print("Table 2 (sampling; ours on this machine vs. the paper's 4.8 GHz core)")
    print(head)
    for row in rows:
        p = PAPER_TABLE2.get((row["quadrics"], row["splat"]))
        ms = 1e3 * row["sampling_s"]
        print(f"{row['name']:18s} {row['quadrics']:3d} {row['normal_form']:4d} {row['splat']:6s} {row['radius']:7.4f} "
              f"{row['samples']:8d} {p[0]:8d} {row['distance_queries']:8d} {p[1]:8d} {row['clip_indices']:5d} "
              f"{p[2]:5d} {ms:8.2f} {p[3]:7.2f} {ms / p[3]:6.2f} {row['unresolved']:5d} {row['feature_points']:5d} "
              f"{row['covered_by_neighbours']:5d} {1e3 * row['sampling_threads_s']:8.2f} "
              f"{row['sampling_s'] / row['sampling_threads_s']:5.2f}")
    within = sum(1e3 * row["sampling_s"] <= 2.0 * PAPER_TABLE2[(row["quadrics"], row["splat"])][3] for row in rows)
    print(f"rows within 2x of the paper's time: {within} of {len(rows)}; regions left unresolved: "
          f"{sum(row['unresolved'] for row in rows)}")
    numba.set_num_threads(1)
    if not args.no_table1:
        print("\nTable 1, sampling rows (samples per second)")
        print(f"{'case':34s} {'ours (M/s)':>10s} {'paper (M/s)':>12s}")
        for label, rate in run_table1(args.repeat).items():
            lo, hi = PAPER_TABLE1[label]
            paper = f"{lo / 1e6:g}" if lo == hi else f"{lo / 1e6:g}–{hi / 1e6:g}"
            print(f"{label:34s} {rate / 1e6:10.2f} {paper:>12s}")
    if args.json:
        keys = ("name", "quadrics", "splat", "samples", "distance_queries", "clip_indices", "sampling_s",
                "sampling_threads_s", "threads", "unresolved", "feature_points", "covered_by_neighbours")
        with open(args.json, "w") as fh:
            json.dump({"models": [{k: row[k] for k in keys} for row in rows]}, fh, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
