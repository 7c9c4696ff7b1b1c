"""Milling and carving on the octree workpiece (paper §5, Figure 15), against manifold3d in the same run.

Three workloads, each run by csgnb and by manifold3d on the same float-exact solids:

* **pocket** and **relief**: the shipped G-code programs (:mod:`csgnb.apps.examples`), set up
  as ``python -m csgnb.mill`` sets them up (stock box, fitted grid, tool spec and segments).
  csgnb runs :func:`csgnb.apps.milling.simulate` on :class:`csgnb.octree.Workpiece`: per move
  the sweep hulls are built, subtracted, and the move's exact removed volume measured (all
  timed). manifold3d gets the identical pieces (:func:`csgnb.apps.milling.move_pieces`: the
  grid points of each sweep hull, in model units, which are exact doubles), and per move
  builds their hulls (``hull_points``) and subtracts them from its stock box (the same grid
  box); ``num_tri()`` forces its lazy evaluation every move.
* **carving**: ``--dodecahedra`` (default 10,000) randomly turned dodecahedra just outside a
  sphere, subtracted from a block (:func:`csgnb.apps.carving.carve`, Figure 15a); manifold3d
  subtracts the hulls of the same grid vertices. Exact per-step volumes are off unless
  ``--carve-volumes`` (the final volume is exact either way). manifold3d's time per
  subtraction grows with its mesh (about 0.1 s per dodecahedron after 2,000 here), so
  ``--mf-dodecahedra N`` runs only its first N, compared with csgnb's first N (time and
  exact volume of a second csgnb run of N, untimed).

Printed per workload: total times, per-move medians of the first and the last tenth (over
the moves that sweep something: zero-length moves are skipped), faces (csgnb: exact polygons
of the boundary; manifold3d: triangles), the exact volume against manifold3d's. ``--json
PATH`` writes ``{"programs": {NAME: {"moves", "csgnb_s", "manifold3d_s",
"first_tenth_median_ms", "last_tenth_median_ms", "volume_rel_dev", ...}}}``. ``--moves N``
and ``--dodecahedra N`` make quick runs; ``--profile`` prints csgnb's top functions.

Targets (issue 12): csgnb total <= manifold3d's on each workload, and per-move time flat over
the run (last tenth <= 1.5x first tenth).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import sys
import time
from fractions import Fraction

import numpy as np
from _clock import nominal_clock_label

from csgnb.apps import carving, gcode, milling, tools
from csgnb.apps.examples import EXAMPLES, example_path
from csgnb.exact import Grid
from csgnb.octree import Workpiece


def _tenths(ts) -> tuple[float, float]:
    ts = np.asarray(ts, float)
    if ts.shape[0] == 0:
        return float("nan"), float("nan")
    k = max(1, len(ts) // 10)
    return float(np.median(ts[:k])), float(np.median(ts[-k:]))


def program_setup(name: str, segments: int | None, moves: int | None):
    """The shipped program ``name`` as ``python -m csgnb.mill`` sets it up: (program, stock lo, hi, grid, tool)."""
    ex = EXAMPLES[name]
    size = np.asarray(ex.stock, float)
    lo = np.array([0.0, 0.0, -size[2]])
    hi = lo + size
    shape = tools.parse_tool(ex.tool, segments=segments or ex.segments or 32)
    program = gcode.parse_file(example_path(name), start=(lo[0], lo[1], hi[2] + 10.0))
    if moves is not None:
        program.moves = program.moves[:moves]
    reach = max(shape.radius, shape.length) + 1.0
    p_lo, p_hi = program.bounds()
    grid = Grid.fit(np.minimum(lo, p_lo - reach), np.maximum(hi, p_hi + reach))
    return program, lo, hi, grid, shape.on(grid)


def _manifold_hull(points_model):
    import manifold3d as m3

    return m3.Manifold.hull_points(np.ascontiguousarray(points_model, np.float64))


def _manifold_piece(piece, grid):
    import manifold3d as m3

    if isinstance(piece, tuple):  # a non-convex tool's end pose: an integer grid mesh
        V, F = piece
        mesh = m3.Mesh(vert_properties=np.ascontiguousarray(grid.to_model(V), np.float32),
                       tri_verts=np.ascontiguousarray(F, np.uint32))
        return m3.Manifold(mesh)
    return _manifold_hull(grid.to_model(piece.points))


def _manifold_box(lo_model, hi_model):
    import manifold3d as m3

    return m3.Manifold.cube(list(hi_model - lo_model)).translate(list(lo_model))


def _phase(text: str) -> None:
    print(f"  [{time.strftime('%H:%M:%S')}] {text}", file=sys.stderr, flush=True)


def _profiled(enabled: bool, fn, *a, **kw):
    if not enabled:
        return fn(*a, **kw)
    prof = cProfile.Profile()
    out = prof.runcall(fn, *a, **kw)
    pstats.Stats(prof).sort_stats("cumulative").print_stats(30)
    return out


def milling_workload(name: str, args) -> dict:
    program, lo, hi, grid, tool = program_setup(name, args.segments, args.moves)
    # csgnb --------------------------------------------------------------------------------
    w = Workpiece.box(lo, hi, grid=grid, threshold=args.threshold)
    t0, c0 = time.perf_counter(), time.process_time()
    result = _profiled(args.profile, milling.simulate, w, program, tool, chord_tolerance=args.chord_tolerance,
                       progress=args.progress)
    csg_total, csg_cpu = time.perf_counter() - t0, time.process_time() - c0
    sweeping = [r for r in result.records if r.pieces > 0]
    csg_t = [r.wall_s for r in sweeping]
    vol = result.part_volume
    surface = result.workpiece.surface()
    assert surface.is_closed(), f"{name}: the milled part's boundary is not closed"
    exact_identity = result.stock_volume - result.removed == vol
    # manifold3d on the same pieces -------------------------------------------------------------
    g = grid.to_grid(np.stack([lo, hi]))
    solid = _manifold_box(grid.to_model(g[0]), grid.to_model(g[1]))
    mf_t, mf_cpu = [], 0.0
    for move, rec in zip(program.moves, result.records, strict=True):
        pieces = milling.move_pieces(move, tool, args.chord_tolerance) if rec.pieces > 0 else []
        if not pieces:
            continue
        t, c = time.perf_counter(), time.process_time()
        for piece in pieces:
            solid = solid - _manifold_piece(piece, grid)
        solid.num_tri()  # manifold3d evaluates lazily: force the Booleans of this move
        mf_t.append(time.perf_counter() - t)
        mf_cpu += time.process_time() - c
    mf_vol = float(solid.volume())
    first, last = _tenths(csg_t)
    mfirst, mlast = _tenths(mf_t)
    return {"moves": len(result.records), "sweeping_moves": len(sweeping),
            "pieces": sum(r.pieces for r in result.records), "grid_mm": grid.resolution, "tool": tool.name,
            "csgnb_s": csg_total, "csgnb_boolean_s": float(sum(r.boolean_s for r in result.records)),
            "manifold3d_s": float(sum(mf_t)), "csgnb_cpu_s": csg_cpu, "manifold3d_cpu_s": mf_cpu,
            "median_ms": float(np.median(csg_t) * 1e3), "max_ms": float(np.max(csg_t) * 1e3),
            "first_tenth_median_ms": first * 1e3, "last_tenth_median_ms": last * 1e3,
            "manifold3d_first_tenth_median_ms": mfirst * 1e3, "manifold3d_last_tenth_median_ms": mlast * 1e3,
            "faces": surface.n_polygons, "manifold3d_triangles": int(solid.num_tri()),
            "cells": result.workpiece.n_cells, "bsp_nodes": result.workpiece.n_bsp_nodes,
            "volume": float(vol), "manifold3d_volume": mf_vol,
            "volume_rel_dev": abs(float(vol) - mf_vol) / float(vol), "exact_identity": bool(exact_identity),
            "collisions": len(result.collisions),
            "per_move_ms": [x * 1e3 for x in csg_t], "manifold3d_per_move_ms": [x * 1e3 for x in mf_t]}


def carving_workload(args) -> dict:
    n = args.dodecahedra
    half = 4.6
    grid = Grid.fit([-6.0] * 3, [6.0] * 3)
    c = carving.carving_placements(carving.sphere_target(radius=4.0), n, args.dodecahedron_radius, grid=grid,
                                   seed=15)
    box = ([-half] * 3, [half] * 3)
    w = Workpiece.box(*box, grid=grid, threshold=args.threshold)
    before = w.model_volume()
    t0 = time.perf_counter()
    removed, csg_t = _profiled(args.profile, carving.carve, w, c, progress=args.progress,
                               track_volume=args.carve_volumes)
    csg_total = time.perf_counter() - t0
    _phase(f"csgnb carved {n} dodecahedra in {csg_total:.1f} s")
    t = time.perf_counter()
    vol = w.volume() / Fraction(grid.scale) ** 3
    volume_s = time.perf_counter() - t
    if removed is not None:
        assert before - sum(removed) == vol
    _phase(f"exact volume of the part: {volume_s:.1f} s")
    t = time.perf_counter()
    surface = w.surface()
    assert surface.is_closed(), "the carved block's boundary is not closed"
    surface_s = time.perf_counter() - t
    _phase(f"boundary extracted and checked: {surface_s:.1f} s")
    # manifold3d: the first m of the same dodecahedra (its time per subtraction grows with the part; --mf-dodecahedra
    # caps the run), compared with csgnb over the same m.
    m = n if args.mf_dodecahedra is None else min(n, args.mf_dodecahedra)
    g = grid.to_grid(np.array(box, float))
    solid = _manifold_box(grid.to_model(g[0]), grid.to_model(g[1]))
    mf_t = []
    for i in range(m):
        t = time.perf_counter()
        solid = solid - _manifold_hull(grid.to_model(c.hull(i).points))
        solid.num_tri()
        mf_t.append(time.perf_counter() - t)
    _phase(f"manifold3d carved {m} dodecahedra in {sum(mf_t):.1f} s")
    mf_vol = float(solid.volume())
    if m < n:
        wm = Workpiece.box(*box, grid=grid, threshold=args.threshold)
        carving.carve(wm, c, progress=False, limit=m, track_volume=False)
        vol_m = wm.volume() / Fraction(grid.scale) ** 3
    else:
        vol_m = vol
    # The hull's construction is inside csgnb's step time and outside manifold3d's (it makes the grid points both
    # get); rebuild them once to say how much that is.
    t = time.perf_counter()
    for i in range(n):
        c.hull(i)
    hulls_s = time.perf_counter() - t
    first, last = _tenths(csg_t)
    mfirst, mlast = _tenths(mf_t)
    return {"moves": n, "csgnb_s": csg_total, "csgnb_hull_construction_s": hulls_s,
            "csgnb_volume_s": volume_s, "csgnb_surface_s": surface_s,
            "manifold3d_moves": m, "manifold3d_s": float(sum(mf_t)), "csgnb_s_same_moves": float(sum(csg_t[:m])),
            "median_ms": float(np.median(csg_t) * 1e3), "max_ms": float(np.max(csg_t) * 1e3),
            "first_tenth_median_ms": first * 1e3, "last_tenth_median_ms": last * 1e3,
            "manifold3d_first_tenth_median_ms": mfirst * 1e3, "manifold3d_last_tenth_median_ms": mlast * 1e3,
            "faces": surface.n_polygons, "manifold3d_triangles": int(solid.num_tri()),
            "cells": w.n_cells, "bsp_nodes": w.n_bsp_nodes, "volume": float(vol), "volume_same_moves": float(vol_m),
            "manifold3d_volume": mf_vol, "volume_rel_dev": abs(float(vol_m) - mf_vol) / float(vol_m),
            "exact_volumes_per_step": args.carve_volumes,
            "per_move_ms": [x * 1e3 for x in csg_t], "manifold3d_per_move_ms": [x * 1e3 for x in mf_t]}


def _warm_up(args) -> None:
    """Compile (or load) every kernel the workloads use, on a few moves, before anything is timed."""
    program, lo, hi, grid, tool = program_setup("pocket.nc", 8, 12)
    milling.simulate(Workpiece.box(lo, hi, grid=grid, threshold=args.threshold), program, tool, progress=False)
    g = Grid.fit([-6.0] * 3, [6.0] * 3)
    c = carving.carving_placements(carving.sphere_target(radius=4.0), 20, 0.5, grid=g, seed=1)
    w = Workpiece.box([-4.6] * 3, [4.6] * 3, grid=g, threshold=args.threshold)
    carving.carve(w, c, progress=False)
    w.surface()


def _report(name: str, d: dict) -> None:
    m = d.get("manifold3d_moves", d["moves"])
    ours = d["csgnb_s"] if m == d["moves"] else d["csgnb_s_same_moves"]
    speed = "met" if ours <= d["manifold3d_s"] else "NOT met"
    flat = "met" if d["last_tenth_median_ms"] <= 1.5 * d["first_tenth_median_ms"] else "NOT met"
    print(f"\n{name}: {d['moves']} moves; csgnb {d['csgnb_s']:.2f} s", end="")
    if m != d["moves"]:
        print(f" ({ours:.2f} s for the first {m})", end="")
    print(f" vs manifold3d {d['manifold3d_s']:.2f} s for {m} (target csgnb <= manifold3d: {speed})")
    if "csgnb_cpu_s" in d:
        print(f"  CPU time: csgnb {d['csgnb_cpu_s']:.2f} s, manifold3d {d['manifold3d_cpu_s']:.2f} s "
              f"(ratio {d['csgnb_cpu_s'] / max(d['manifold3d_cpu_s'], 1e-9):.2f})")
    if "csgnb_boolean_s" in d:
        print(f"  csgnb: {d['pieces']} sweep pieces, {d['csgnb_boolean_s']:.2f} s of it in the octree Booleans; grid "
              f"{d['grid_mm']:g} mm; tool {d['tool']}")
    if "csgnb_hull_construction_s" in d:
        print(f"  csgnb: {d['csgnb_hull_construction_s']:.2f} s of it building the exact hulls; exact per-step volumes "
              f"{'on' if d['exact_volumes_per_step'] else 'off'}; then the part's exact volume "
              f"{d['csgnb_volume_s']:.1f} s, its boundary {d['csgnb_surface_s']:.1f} s (not in the total)")
    print(f"  per move: median {d['median_ms']:.1f} ms, max {d['max_ms']:.1f} ms, first/last tenth "
          f"{d['first_tenth_median_ms']:.1f}/{d['last_tenth_median_ms']:.1f} ms (flat within 1.5x: {flat}); "
          f"manifold3d first/last tenth {d['manifold3d_first_tenth_median_ms']:.1f}/"
          f"{d['manifold3d_last_tenth_median_ms']:.1f} ms")
    extra = f"; stock - removed == part: {d['exact_identity']}" if "exact_identity" in d else ""
    same = f" after the first {m}" if m != d["moves"] else ""
    print(f"  result: {d['faces']} exact polygons ({d['cells']} cells, {d['bsp_nodes']} BSP nodes), volume "
          f"{d['volume']:.6f} mm^3; manifold3d {d['manifold3d_triangles']} triangles{same}; volume"
          f"{same} {d.get('volume_same_moves', d['volume']):.6f} vs {d['manifold3d_volume']:.6f} mm^3 "
          f"(rel. dev. {d['volume_rel_dev']:.2e}){extra}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workloads", nargs="+", default=["pocket", "relief", "carving"],
                        choices=["pocket", "relief", "carving"])
    parser.add_argument("--moves", type=int, default=None, help="only the first N moves of each program")
    parser.add_argument("--dodecahedra", type=int, default=10_000, help="dodecahedra of the carving")
    parser.add_argument("--dodecahedron-radius", type=float, default=0.5, help="their circum-radius (mm)")
    parser.add_argument("--mf-dodecahedra", type=int, default=None,
                        help="subtract only the first N dodecahedra in manifold3d (its steps grow with the part)")
    parser.add_argument("--carve-volumes", action="store_true", help="measure each dodecahedron's exact volume")
    parser.add_argument("--segments", type=int, default=None, help="vertices around each tool (default: the "
                        "example's, as python -m csgnb.mill runs it)")
    parser.add_argument("--chord-tolerance", type=float, default=milling.CHORD_TOLERANCE)
    parser.add_argument("--threshold", type=int, default=150)
    parser.add_argument("--progress", action="store_true", help="tqdm bars")
    parser.add_argument("--profile", action="store_true", help="cProfile the csgnb runs")
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()

    print(f"csgnb milling vs manifold3d, threshold {args.threshold}, one core, clock {nominal_clock_label()}")
    t = time.perf_counter()
    _warm_up(args)
    print(f"warm-up (compile or load the kernels): {time.perf_counter() - t:.1f} s, not timed below")
    out = {"clock": nominal_clock_label(), "threshold": args.threshold, "moves_cap": args.moves, "programs": {}}
    for name in args.workloads:
        d = carving_workload(args) if name == "carving" else milling_workload(f"{name}.nc", args)
        out["programs"][name] = d
        _report(name, d)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
