"""Table 1 of the BSP paper: the exact predicates at 128/192/256 bits against Python ints.

Each operation runs over arrays of ``--n`` elements (default 10^5) after a
warm-up call, on data at the mesh budget of its width (vertices up to
``budget(w).max_mesh_coordinate``, planes through them, vertices from three such
planes) -- the largest numbers the width is meant for. The Python-int baseline
computes the same results on the 256-bit data, element by element, in the same
process. Figures are the best of ``--repeat`` runs.

    python benchmarks/bench_predicates.py [--n 100000] [--clock-ghz 2.0] [--json out.json]

Cycles are ns x clock; the clock is read from the CPU's maximum frequency unless
given, and printed with the table.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import time

import numpy as np

from csgnb import exact
from csgnb.exact import predicates as K
from csgnb.exact.budgets import budget

PAPER_CYCLES = {  # Table 1: 128b, 192b, 256b, gmp
    "plane_from_points": (226, 512, 761, 9100),
    "are_planes_parallel": (5, 15, 15, 1840),
    "signed_distance": (4, 5, 11, 1360),
    "to_double_position": (5, 62, 88, 120),
    "intersect_3_planes": (23, 160, 402, 6380),
    "classify_vertex": (13, 103, 142, 1540),
}


def cpu_clock_ghz() -> float:
    for path in ("/sys/devices/system/cpu/cpu0/cpufreq/cpuinfo_max_freq",):
        try:
            return int(pathlib.Path(path).read_text()) / 1e6
        except (OSError, ValueError):
            pass
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("cpu MHz"):
                return float(line.split(":")[1]) / 1000
    except OSError:
        pass
    return 3.0


def best_time(fn, repeat: int) -> float:
    fn()  # warm-up: compilation and first-touch are not timed
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def make_data(width: int, n: int, rng: np.random.Generator):
    """Vertices, planes and homogeneous points at the mesh budget of ``width``."""
    V = budget(width).max_mesh_coordinate
    pts = rng.integers(-V, V + 1, size=(3, n, 3), dtype=np.int64)
    planes = exact.plane_from_points(pts[0], pts[1], pts[2], width=width)
    planes2 = np.roll(planes, 1, axis=0)
    planes3 = np.roll(planes, 2, axis=0)
    points = exact.intersect_3_planes(planes, planes2, planes3)
    return dict(pts=pts, planes=planes, planes2=planes2, planes3=planes3, points=points)


def kernel_runs(d, n):
    """Bare kernels on pre-validated data (what Table 1 times) and the checked public API."""
    P = d["planes"]
    out_planes = np.empty_like(P)
    out_bool = np.empty(n, np.bool_)
    out_wide = np.empty(n, P.dtype)
    out_pts = np.empty_like(d["points"])
    out_i8 = np.empty(n, np.int8)
    out_f = np.empty((n, 3))
    a, b, c = d["pts"]

    def pfp():
        K._plane_from_points_kernel(a, b, c, out_planes)
        K._canonicalize_kernel(out_planes)

    kernels = {
        "plane_from_points": pfp,
        "are_planes_parallel": lambda: K._parallel_kernel(P, d["planes2"], out_bool),
        "signed_distance": lambda: K._signed_distance_kernel(a, P, out_wide),
        "to_double_position": lambda: K._to_double_kernel(d["points"], out_f),
        "intersect_3_planes": lambda: K._intersect_kernel(P, d["planes2"], d["planes3"], out_pts),
        "classify_vertex": lambda: K._classify_kernel(d["points"], P, out_i8),
    }
    api = {
        "plane_from_points": lambda: exact.plane_from_points(a, b, c, width=exact.width_of(P)),
        "are_planes_parallel": lambda: exact.are_planes_parallel(P, d["planes2"]),
        "signed_distance": lambda: exact.signed_distance(a, P),
        "to_double_position": lambda: exact.to_double_position(d["points"]),
        "intersect_3_planes": lambda: exact.intersect_3_planes(P, d["planes2"], d["planes3"]),
        "classify_vertex": lambda: exact.classify_vertex(d["points"], P),
    }
    return kernels, api


def python_runs(d, n):
    """The same operations on Python ints (the role gmp plays in the paper)."""
    pts = d["pts"].tolist()
    planes = exact.from_wide(d["planes"]).tolist()
    planes2 = exact.from_wide(d["planes2"]).tolist()
    planes3 = exact.from_wide(d["planes3"]).tolist()
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
            out.append((nx, ny, nz, -(nx * p[0] + ny * p[1] + nz * p[2])))
        return out

    def parallel():
        return [
            p[1] * q[2] == p[2] * q[1] and p[2] * q[0] == p[0] * q[2] and p[0] * q[1] == p[1] * q[0]
            for p, q in zip(planes, planes2, strict=True)
        ]

    def distance():
        return [v[0] * s[0] + v[1] * s[1] + v[2] * s[2] + s[3] for v, s in zip(pts[0], planes, strict=True)]

    def to_double():
        return [(x[0] / x[3], x[1] / x[3], x[2] / x[3]) for x in points]

    def intersect():
        out = []
        for (ap, bp, cp, dp), (aq, bq, cq, dq), (ar, br, cr, dr) in zip(planes, planes2, planes3, strict=True):
            m_ab, m_ac, m_ad = aq * br - ar * bq, aq * cr - ar * cq, aq * dr - ar * dq
            m_bc, m_bd, m_cd = bq * cr - br * cq, bq * dr - br * dq, cq * dr - cr * dq
            out.append(
                (
                    bp * m_cd - cp * m_bd + dp * m_bc,
                    -(ap * m_cd - cp * m_ad + dp * m_ac),
                    ap * m_bd - bp * m_ad + dp * m_ab,
                    -(ap * m_bc - bp * m_ac + cp * m_ab),
                )
            )
        return out

    def classify():
        return [
            sign(x[0] * s[0] + x[1] * s[1] + x[2] * s[2] + x[3] * s[3]) * sign(x[3])
            for x, s in zip(points, planes, strict=True)
        ]

    runs = {
        "plane_from_points": pfp,
        "are_planes_parallel": parallel,
        "signed_distance": distance,
        "to_double_position": to_double,
        "intersect_3_planes": intersect,
        "classify_vertex": classify,
    }
    # The baseline must compute what the kernels compute.
    assert [list(r) for r in intersect()] == exact.from_wide(d["points"]).tolist()
    assert classify() == exact.classify_vertex(d["points"], d["planes"]).tolist()
    return runs


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000, help="elements per operation (default 1e5)")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs per figure; the best is kept")
    parser.add_argument("--clock-ghz", type=float, default=None, help="clock used to convert ns to cycles")
    parser.add_argument("--json", type=pathlib.Path, default=None, help="write the figures to this file")
    args = parser.parse_args(argv)
    clock = args.clock_ghz or cpu_clock_ghz()
    n = args.n
    rng = np.random.default_rng(2026)

    ops = list(PAPER_CYCLES)
    result = {"clock_ghz": clock, "n": n, "ops": {op: {} for op in ops}}
    for width in exact.WIDTHS:
        d = make_data(width, n, rng)
        kernels, api = kernel_runs(d, n)
        for op in ops:
            ns = best_time(kernels[op], args.repeat) / n * 1e9
            api_ns = best_time(api[op], max(1, args.repeat // 2)) / n * 1e9
            result["ops"][op][str(width)] = {"ns": ns, "cycles": ns * clock, "api_ns": api_ns}
        if width == 256:
            for op, fn in python_runs(d, n).items():
                ns = best_time(fn, 1) / n * 1e9
                result["ops"][op]["python_int"] = {"ns": ns, "cycles": ns * clock}

    print(f"Exact predicates, {n} elements per operation, best of {args.repeat}; cycles at {clock:.2f} GHz")
    print("(kernel figures; 'api' adds the bit-budget checks of the public functions)\n")
    header = f"{'operation':<20}" + "".join(f"{w + 'b':>9}" for w in ("128", "192", "256"))
    header += f"{'python':>10}{'paper 256b':>12}{'speed-up vs py':>16}{'api 256b':>10}"
    print(header)
    print("-" * len(header))
    for op in ops:
        row = result["ops"][op]
        cyc = [row[str(w)]["cycles"] for w in exact.WIDTHS]
        speedup = row["python_int"]["ns"] / row["256"]["ns"]
        row["speedup_256_vs_python"] = speedup
        print(
            f"{op:<20}" + "".join(f"{c:9.0f}" for c in cyc) + f"{row['python_int']['cycles']:10.0f}"
            f"{PAPER_CYCLES[op][2]:12d}{speedup:15.0f}x{row['256']['api_ns'] * clock:10.0f}"
        )
    print("\n(cycles per operation; paper: Table 1, 4.2 GHz i7-7700K)")
    targets = {
        "classify_vertex 256b <= 142 cycles": result["ops"]["classify_vertex"]["256"]["cycles"] <= 142,
        "intersect_3_planes 256b <= 402 cycles": result["ops"]["intersect_3_planes"]["256"]["cycles"] <= 402,
        "every op >= 50x faster than Python ints": all(
            result["ops"][op]["speedup_256_vs_python"] >= 50 for op in ops
        ),
    }
    result["targets"] = targets
    for name, ok in targets.items():
        print(f"  [{'met' if ok else 'MISSED'}] {name}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2))
        print(f"\nwrote {args.json}")
    return result


if __name__ == "__main__":
    main()
