"""Table 1 of the BSP paper: the exact predicates at 128/192/256 bits, in cycles, against the paper and Python ints.

For every operation and width three figures, each the best of ``--repeat`` runs after a
warm-up call (compilation is never timed):

* **hot** -- the bare kernel (one intrinsic per element, no checks) on ``--hot-n`` elements
  that stay in L1/L2, called repeatedly, less the cost of calling it (measured on empty
  arrays, ~0.65 us per call here): the cost of the operation itself, which is what Table 1
  reports. Operations that read planes run on both plane layouts: full ``(n, 4)``
  rows and the paper's narrow records (§4.4: 20 B at 128 bits, 40 B at 192/256); the
  Table 1 comparison takes the narrow one, as the paper stores its planes that way.
* **stream** -- the same bare kernel on ``--n`` elements (default 10^5, beyond L2), and
* **api** -- the public, checked function on the same 10^5 elements (bit-budget scans,
  zero-normal / point-at-infinity checks, broadcasting, allocation of the result).
  Target: api <= 1.5 x stream.

Data sit at the mesh budget of their width (vertices up to ``budget(w).max_mesh_coordinate``,
planes through them, vertices of three such planes) -- the largest numbers the width is
meant for. Python ints compute the same results on the 256-bit data in the same process
(the role gmp plays in the paper) and check the kernels' results.

Cycles = CPU seconds x clock. The clock is measured in this process (a dependent
``imul``+``add`` chain, 4 cycles per step) and printed with the nominal one; times are CPU
time of this process (``time.process_time``), which keeps figures taken on a shared machine
from counting other processes' slices -- they are still provisional under load.

    python benchmarks/bench_predicates.py [--n 100000] [--hot-n 4096] [--clock-ghz 2.6] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
from fractions import Fraction

import numpy as np
from _clock import bare_jit, best_cpu_time, measure_clock_ghz, nominal_clock_ghz  # benchmarks/ is on sys.path

from csgnb import exact
from csgnb.exact import predicates as K
from csgnb.exact.budgets import budget
from csgnb.exact.intrinsics import (
    classify_at,
    intersect_into,
    plane_from_normal_into,
    planes_parallel_at,
    signed_distance_into,
)

PAPER_CYCLES = {  # Table 1: 128b, 192b, 256b, CGAL, gmp
    "plane_from_points": (226, 512, 761, 2770, 9100),
    "are_planes_parallel": (5, 15, 15, 910, 1840),
    "signed_distance": (4, 5, 11, 530, 1360),
    "to_double_position": (5, 62, 88, 31, 120),
    "intersect_3_planes": (23, 160, 402, 4200, 6380),
    "classify_vertex": (13, 103, 142, 710, 1540),
}
READS_PLANES = {"are_planes_parallel", "signed_distance", "intersect_3_planes", "classify_vertex"}
API_TARGET = 1.5


# ---------------------------------------------------------------------------
# bare kernels: the operation alone, no checks (what Table 1 times); not cached (see _clock.bare_jit).


@bare_jit
def _bare_pfp(P, Q, R, out):
    for t in range(out.shape[0]):
        x1, y1, z1 = Q[t, 0] - P[t, 0], Q[t, 1] - P[t, 1], Q[t, 2] - P[t, 2]
        x2, y2, z2 = R[t, 0] - P[t, 0], R[t, 1] - P[t, 1], R[t, 2] - P[t, 2]
        a = y1 * z2 - z1 * y2
        b = z1 * x2 - x1 * z2
        c = x1 * y2 - y1 * x2
        g = K.gcd3(a, b, c)
        if g > 1:
            a //= g
            b //= g
            c //= g
        plane_from_normal_into(a, b, c, P, t, out, t)


@bare_jit
def _bare_parallel(P, Q, out):
    for t in range(out.shape[0]):
        out[t] = planes_parallel_at(P, t, Q, t)


@bare_jit
def _bare_distance(V, S, out):
    for t in range(out.shape[0]):
        signed_distance_into(V, t, S, t, out, t)


@bare_jit
def _bare_to_double(X, out, counts):
    K._positions(X, 0, X.shape[0], out, counts)


@bare_jit
def _bare_intersect(P, Q, R, out):
    for t in range(out.shape[0]):
        intersect_into(P, t, Q, t, R, t, out, t)


@bare_jit
def _bare_classify(X, S, out):
    for t in range(out.shape[0]):
        out[t] = classify_at(X, t, S, t)


# ---------------------------------------------------------------------------
# data


def make_data(width: int, n: int, rng: np.random.Generator) -> dict:
    """Vertices, planes (both layouts) and homogeneous points at the mesh budget of ``width``."""
    V = budget(width).max_mesh_coordinate
    pts = rng.integers(-V, V + 1, size=(3, n, 3), dtype=np.int64)
    planes = exact.plane_from_points(pts[0], pts[1], pts[2], width=width)
    planes2, planes3 = np.roll(planes, 1, axis=0), np.roll(planes, 2, axis=0)
    points = exact.intersect_3_planes(planes, planes2, planes3)
    narrow = [exact.to_narrow_planes(p) for p in (planes, planes2, planes3)]
    return dict(pts=pts, planes=(planes, planes2, planes3), narrow=narrow, points=points)


def runs(d: dict, layout: str) -> tuple[dict, dict]:
    """Bare kernels and the public API on ``d``; planes in ``layout`` ("full" or "narrow")."""
    P, Q, R = d["planes"] if layout == "full" else d["narrow"]
    X = d["points"]
    n = X.shape[0]
    width = exact.width_of(X)
    a, b, c = d["pts"]
    out_planes = np.empty((n, 4), exact.wide_dtype(width))
    out_bool = np.empty(n, np.bool_)
    out_wide = np.empty(n, exact.wide_dtype(width))
    out_pts = np.empty_like(X)
    out_i8 = np.empty(n, np.int8)
    out_f = np.empty((n, 3))
    counts = np.zeros(1, np.int64)
    bare = {
        "plane_from_points": lambda: _bare_pfp(a, b, c, out_planes),
        "are_planes_parallel": lambda: _bare_parallel(P, Q, out_bool),
        "signed_distance": lambda: _bare_distance(a, P, out_wide),
        "to_double_position": lambda: _bare_to_double(X, out_f, counts),
        "intersect_3_planes": lambda: _bare_intersect(P, Q, R, out_pts),
        "classify_vertex": lambda: _bare_classify(X, P, out_i8),
    }
    api = {
        "plane_from_points": lambda: exact.plane_from_points(a, b, c, width=width),
        "are_planes_parallel": lambda: exact.are_planes_parallel(P, Q),
        "signed_distance": lambda: exact.signed_distance(a, P),
        "to_double_position": lambda: exact.to_double_position(X),
        "intersect_3_planes": lambda: exact.intersect_3_planes(P, Q, R),
        "classify_vertex": lambda: exact.classify_vertex(X, P),
    }
    return bare, api


def python_runs(d: dict) -> dict:
    """The same operations on Python ints (the role gmp plays in the paper), checked against the kernels."""
    pts = d["pts"].tolist()
    planes, planes2, planes3 = (exact.from_wide(p).tolist() for p in d["planes"])
    points = exact.from_wide(d["points"]).tolist()
    sign = lambda v: (v > 0) - (v < 0)  # noqa: E731

    def pfp():
        out = []
        for p, q, r in zip(pts[0], pts[1], pts[2], strict=True):
            e1 = [q[0] - p[0], q[1] - p[1], q[2] - p[2]]
            e2 = [r[0] - p[0], r[1] - p[1], r[2] - p[2]]
            nx, ny, nz = e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]
            g = math.gcd(nx, ny, nz)
            nx, ny, nz = nx // g, ny // g, nz // g
            out.append([nx, ny, nz, -(nx * p[0] + ny * p[1] + nz * p[2])])
        return out

    def parallel():
        return [p[1] * q[2] == p[2] * q[1] and p[2] * q[0] == p[0] * q[2] and p[0] * q[1] == p[1] * q[0]
                for p, q in zip(planes, planes2, strict=True)]

    def distance():
        return [v[0] * s[0] + v[1] * s[1] + v[2] * s[2] + s[3] for v, s in zip(pts[0], planes, strict=True)]

    def to_double():
        return [[x[0] / x[3], x[1] / x[3], x[2] / x[3]] for x in points]  # int / int is correctly rounded

    def intersect():
        out = []
        for (ap, bp, cp, dp), (aq, bq, cq, dq), (ar, br, cr, dr) in zip(planes, planes2, planes3, strict=True):
            m_ab, m_ac, m_ad = aq * br - ar * bq, aq * cr - ar * cq, aq * dr - ar * dq
            m_bc, m_bd, m_cd = bq * cr - br * cq, bq * dr - br * dq, cq * dr - cr * dq
            out.append([bp * m_cd - cp * m_bd + dp * m_bc, -(ap * m_cd - cp * m_ad + dp * m_ac),
                        ap * m_bd - bp * m_ad + dp * m_ab, -(ap * m_bc - bp * m_ac + cp * m_ab)])
        return out

    def classify():
        return [sign(x[0] * s[0] + x[1] * s[1] + x[2] * s[2] + x[3] * s[3]) * sign(x[3])
                for x, s in zip(points, planes, strict=True)]

    fns = {"plane_from_points": pfp, "are_planes_parallel": parallel, "signed_distance": distance,
           "to_double_position": to_double, "intersect_3_planes": intersect, "classify_vertex": classify}
    # The kernels must compute what Python computes, on both layouts.
    P, Q, R = d["planes"]
    N0, N1, N2 = d["narrow"]
    X = d["points"]
    assert pfp() == planes
    assert intersect() == points == exact.from_wide(exact.intersect_3_planes(N0, N1, N2)).tolist()
    assert classify() == exact.classify_vertex(X, P).tolist() == exact.classify_vertex(X, N0).tolist()
    assert parallel() == exact.are_planes_parallel(P, Q).tolist() == exact.are_planes_parallel(N0, N1).tolist()
    assert distance() == exact.from_wide(exact.signed_distance(d["pts"][0], N0)).tolist()
    assert to_double() == exact.to_double_position(X).tolist()
    assert to_double()[:50] == [[float(Fraction(v, x[3])) for v in x[:3]] for x in points[:50]]
    return fns


# ---------------------------------------------------------------------------


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000, help="elements for the stream and api figures (1e5)")
    parser.add_argument("--hot-n", type=int, default=4096, help="elements for the in-cache figures (4096)")
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per figure; the best is kept")
    parser.add_argument("--clock-ghz", type=float, default=None, help="clock for ns -> cycles (default: measured)")
    parser.add_argument("--json", type=pathlib.Path, default=None, help="write the figures to this file")
    args = parser.parse_args(argv)
    nominal = nominal_clock_ghz()
    measured = measure_clock_ghz()
    clock = args.clock_ghz or measured
    n, hot_n = args.n, args.hot_n
    inner = max(1, 200_000 // hot_n)
    rng = np.random.default_rng(2026)

    ops = list(PAPER_CYCLES)
    result = {"clock_ghz": clock, "clock_measured_ghz": measured, "clock_nominal_ghz": nominal, "n": n,
              "hot_n": hot_n, "ops": {op: {} for op in ops}}
    for width in exact.WIDTHS:
        big = make_data(width, n, rng)
        hot = make_data(width, hot_n, rng)
        empty = dict(pts=hot["pts"][:, :0], planes=tuple(p[:0] for p in hot["planes"]),
                     narrow=[p[:0] for p in hot["narrow"]], points=hot["points"][:0])
        for layout in ("full", "narrow"):
            bare_hot, _ = runs(hot, layout)
            bare_empty, _ = runs(empty, layout)
            bare, api = runs(big, layout)
            for op in ops:
                if layout == "narrow" and op not in READS_PLANES:
                    continue
                call = best_cpu_time(bare_empty[op], args.repeat, inner)
                hot_c = (best_cpu_time(bare_hot[op], args.repeat, inner) - call) / hot_n * 1e9 * clock
                stream_c = best_cpu_time(bare[op], args.repeat) / n * 1e9 * clock
                api_c = best_cpu_time(api[op], args.repeat) / n * 1e9 * clock
                result["ops"][op][f"{width}/{layout}"] = {"hot": hot_c, "call_us": call * 1e6, "stream": stream_c,
                                                          "api": api_c,
                                                          "api_over_stream": api_c / stream_c}
        if width == 256:
            for op, fn in python_runs(big).items():
                result["ops"][op]["python_int"] = best_cpu_time(fn, 1) / n * 1e9 * clock
    stats = {}
    exact.to_double_position(big["points"], stats=stats)
    result["to_double_exact_fallbacks"] = stats["exact"]

    nom = f", nominal {nominal:.2f} GHz" if nominal else ""
    print(f"Exact predicates: cycles per element at {clock:.2f} GHz (measured{nom}); CPU time, best of "
          f"{args.repeat}; hot = {hot_n} elements in cache, stream/api = {n} elements")
    print("Table 1 column: hot, narrow planes where the operation reads planes (the paper's storage).\n")
    header = (f"{'operation':<20}{'width':>6}{'layout':>8}{'hot':>8}{'paper':>8}{'':>3}"
              f"{'stream':>8}{'api':>8}{'api/str':>8}{'':>3}")
    print(header)
    print("-" * len(header))
    targets = {}
    for op in ops:
        row = result["ops"][op]
        for i, width in enumerate(exact.WIDTHS):
            for layout in ("full", "narrow"):
                f = row.get(f"{width}/{layout}")
                if f is None:
                    continue
                paper = PAPER_CYCLES[op][i]
                table1 = layout == "narrow" or op not in READS_PLANES
                ok_table = f["hot"] <= paper
                ok_api = f["api_over_stream"] <= API_TARGET
                if table1:
                    targets[f"{op} {width}b <= {paper} cycles (hot)"] = ok_table
                targets[f"{op} {width}b {layout}: api <= {API_TARGET} x stream"] = ok_api
                mark = ("ok" if ok_table else "MISS") if table1 else ""
                print(f"{op:<20}{width:>6}{layout:>8}{f['hot']:8.0f}{paper:8d}{mark:>5} {f['stream']:8.0f}"
                      f"{f['api']:8.0f}{f['api_over_stream']:8.2f}{'' if ok_api else ' MISS'}")
        print(f"{'':<20}{'python ints, 256-bit data':>30}{row['python_int']:10.0f}   (paper gmp "
              f"{PAPER_CYCLES[op][4]}, CGAL {PAPER_CYCLES[op][3]})")
    print(f"\nto_double_position: {result['to_double_exact_fallbacks']} of {3 * n} coordinates took the exact path")
    result["targets"] = targets
    missed = [k for k, v in targets.items() if not v]
    print(f"targets met: {len(targets) - len(missed)} of {len(targets)}" + ("; missed:" if missed else ""))
    for k in missed:
        print(f"  MISSED {k}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2))
        print(f"\nwrote {args.json}")
    return result


if __name__ == "__main__":
    main()
