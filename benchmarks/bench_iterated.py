"""Iterated exact CSG on the octree workpiece (paper §5, Figures 11-14), against manifold3d in the same run.

Two set-ups from the paper, built with csgnb's own tools and sweeps (``csgnb.apps``):

* **drill** (Figures 13-14): a two-flute twist drill (896 triangles, radius 3, 118° point),
  axis 30° from vertical, spinning in 90 steps of 4° per turn. Each step's sweep -- the
  union of the per-triangle prisms between consecutive poses (each the exact hull of a
  triangle at two poses) -- is precomputed once with csgnb (timed apart from the steps: the prisms'
  exact hulls, then the unions; both count in the end-to-end figure) and used as a mesh
  tool; three turns with the feed as an exact translation give 270 subtractions from a
  block. manifold3d gets the same prisms (float hulls), unions them per step with
  ``batch_boolean`` (timed apart) and subtracts the same 270 translated steps.
  Steps 45-89 of each turn sweep exactly the volumes of steps 0-44 at the same place (the
  drill turns into itself every 180°): the workpiece skips them as differences it has
  already applied (``OpReport.repeated``); ``--no-memo`` applies them again (the A/B).
* **gear_sweep** (Figures 11-12): a spur gear (480 triangles) along a cubic Bézier with S
  sample positions; the prism of every triangle between consecutive positions is unioned
  one by one into an empty workpiece (S = 20: ~9,100 unions). manifold3d unions the same
  prisms one by one (``--mf-gear-ops`` of them, to keep its run short).

  The same 270 steps also run on every core: the workpiece in spatial shards on threads of
  this process (``ShardedWorkpiece(work, None)``, ``--shards``), exact volume compared with ``==``.
* **drill_mesh** (issue 22): the same drill with the 90 sweep volumes given as float
  triangle meshes (made by manifold3d before anything is timed: the input a user brings),
  end to end -- csgnb prepares a tool from each mesh once (quantize, repair, BSP) and
  translates it per turn; manifold3d builds a ``Manifold`` per mesh. Rounded onto the grid,
  manifold3d's unions fold in places: refused as solids (``--fill solid``), they are taken
  as the points they wind around (``--fill winding``, the default, what the refusal advises).
* **dome**: a hemisphere (radius 10 mm) minus 1,000 (``--dome-steps``) capsules along a
  spiral on its surface, each step building its tool from the capsule's points.
* **lattice**: 2,000 unions/differences of cubes on a 10 x 10 x 10 lattice (coplanar faces,
  touching edges), csgnb's exact volume change of every step checked against a voxel count.
* **boxes** (issue 22's "aligned boxes, 200 steps"): a 20 mm block minus 200 (``--box-steps``) axis-aligned boxes
  of random sizes (1-6 mm a side) at random places on a fine grid, each step building its tool from the box's eight
  corners (csgnb: the exact hull; manifold3d: ``Manifold.cube`` on the same grid points); the final exact volume
  checked against an independent count over the boxes' compressed coordinates.

Printed per workload: per-step times (median, max, first vs last tenth), totals, faces,
BSP work, exact volume vs manifold3d's. ``--json PATH`` writes the figures; ``--sweep``
times the gear sweep at several BSP thresholds (Figure 11).

Targets (issue 11): drill total <= manifold3d's; gear sweep <= 1 ms per union; the median
step of the last tenth <= 1.5x the first tenth's. Issue 22: every workload <= 0.5x
manifold3d's CPU time, the mesh drill <= 30 s end to end, the dome's 1,000 steps <= 3 s.
``--perf-map`` names the compiled kernels for ``perf record`` (``_perf_map.py``). This
machine: see the printed clock; CPU time is printed beside wall time (manifold3d runs two
threads).
"""

from __future__ import annotations

import argparse
import json
import time
from fractions import Fraction

import numpy as np
from _clock import nominal_clock_label

from csgnb.apps import sweep, tools
from csgnb.errors import GeometryError
from csgnb.exact import Grid
from csgnb.mesh.hull import convex_hull
from csgnb.octree import Tool, Workpiece
from csgnb.octree.layout import S_BOUNDARY_MERGES


def _tenths(ts) -> tuple[float, float]:
    ts = np.asarray(ts)
    k = max(1, len(ts) // 10)
    return float(np.median(ts[:k])), float(np.median(ts[-k:]))


def _drill_steps(work, step_tools, feed, total: int, verbose: bool = False,
                 repeated: list | None = None) -> list[float]:
    """Subtract ``total`` drill steps from ``work``: step i is tool ``i mod 90`` moved down ``i // 90`` feeds (an
    exact translation of the prepared tool). Returns each step's seconds; ``repeated`` gets whether each step repeats
    an earlier one (the same tool object at the same turn: steps 45-89 of a turn subtract steps 0-44's sweeps again at
    the same place, the drill's 180° symmetry), exact no-ops the workpiece skips (``OpReport.repeated``) unless the
    memo is off."""
    ts = []
    seen = set()
    for i in range(total):
        turn, k = divmod(i, len(step_tools))
        t = time.perf_counter()
        report = work.difference(step_tools[k].translated(feed * turn))
        ts.append(time.perf_counter() - t)
        if repeated is not None:  # a repeat whether the workpiece skipped it or not (--no-memo): the same tool, turn
            key = (id(step_tools[k]), turn)
            assert key in seen or not report.repeated  # the workpiece skips only what repeats
            repeated.append(key in seen)
            seen.add(key)
        if verbose and i % 30 == 0:
            print(f"  drill step {i}: {ts[-1] * 1e3:.0f} ms, {work}")
    return ts


def _drill_grid(args) -> Grid:
    """The drill's grid: the finest that holds its box at ``--width`` bits, or ``--resolution`` mm at that width."""
    fitted = Grid.fit([-12, -12, -16], [12, 12, 8], width=args.width)
    if args.resolution is None:
        return fitted
    return Grid.from_resolution(args.resolution, origin=fitted.origin, width=args.width)


def _drill_on_shards(args, grid, box, step_tools, feed, total: int):
    """The drill's ``total`` steps (step i: tool ``i mod len(step_tools)`` moved ``i // len(step_tools)`` feeds) on a
    stock ``box`` split into ``args.shards`` shards on threads (``ShardedWorkpiece``): ``(figures, exact volume)``."""
    from csgnb.distributed.sharded import ShardedWorkpiece

    with ShardedWorkpiece(Workpiece.box(*box, grid=grid, threshold=args.threshold), None, args.shards) as sharded:
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(total):
            turn, k = divmod(i, len(step_tools))
            sharded.difference(step_tools[k].translated(feed * turn))
        sharded.flush()
        par = {"shards": list(sharded.counts), "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
               "cells": sum(st["cells"] for st in sharded.stats())}
        return par, sharded.model_volume()


def drill_workload(args) -> dict:
    import manifold3d as m3

    grid = _drill_grid(args)
    drill = tools.twist_drill().on(grid)
    # kernels loaded (compiled, on a first run after an edit) before anything is timed, as in the other workloads
    warm_ds = sweep.drill_sweeps(drill, feed_per_turn=args.feed, steps=1, symmetry=False)
    warm = Workpiece.box([-10.0, -10.0, -15.0], [10.0, 10.0, 6.0], grid=grid, threshold=args.threshold)
    warm -= warm_ds.tools(grid, threshold=args.threshold, threads=1)[0]
    # -- precompute: the poses' prisms (exact hulls, both libraries use their points), then the 90 sweep volumes
    # (timed apart from the steps; the volumes on every core) ----------------
    t0, c0 = time.perf_counter(), time.process_time()
    ds = sweep.drill_sweeps(drill, feed_per_turn=args.feed)
    prisms_s, prisms_cpu = time.perf_counter() - t0, time.process_time() - c0
    n_steps = len(ds)
    t0, c0 = time.perf_counter(), time.process_time()
    tools_c = ds.tools(grid, threshold=args.threshold)
    csg_pre, csg_pre_cpu = time.perf_counter() - t0 + prisms_s, time.process_time() - c0 + prisms_cpu
    t0 = time.perf_counter()
    # the same distinct sweeps as csgnb builds (the drill turns into itself every 180°: steps k and k + 45 share one)
    distinct_m = [m3.Manifold.batch_boolean([m3.Manifold.hull_points(grid.to_model(h.points)) for h in ds.steps[k]],
                                            m3.OpType.Add) for k in range(ds.period)]
    tools_m = [distinct_m[k % ds.period] for k in range(n_steps)]
    mf_pre = time.perf_counter() - t0
    # -- what a user runs after the precompute: the 270 subtractions on every core (the workpiece in spatial shards
    # on threads of this process), first, in the state the precompute leaves the process in --------------------
    total = args.turns * n_steps
    lo, hi = np.array([-10.0, -10.0, -15.0]), np.array([10.0, 10.0, 6.0])
    par, par_vol = _drill_on_shards(args, grid, (lo, hi), tools_c, ds.feed, total) if args.shards != 1 else (None, None)
    # -- the same steps on one workpiece, one core (the speed-up's reference) --------------------------------------
    work = Workpiece.box(lo, hi, grid=grid, threshold=args.threshold)
    c0 = time.process_time()
    repeated: list[bool] = []
    csg_t = _drill_steps(work, tools_c, ds.feed, total, args.verbose, repeated)
    csg_cpu = time.process_time() - c0
    vol = work.model_volume()
    if par is not None:
        par.update({"speed_up": float(sum(csg_t)) / par["wall_s"], "same_volume": bool(par_vol == vol)})
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
    mf_vol = cube.volume()
    surface = work.surface()
    first, last = _tenths([t for t, r in zip(csg_t, repeated, strict=True) if not r])  # the steps that cut
    mfirst, mlast = _tenths(mf_t)
    return {"steps": total, "csgnb_s": float(sum(csg_t)), "csgnb_cpu_s": csg_cpu, "every_core": par,
            "manifold3d_s": float(sum(mf_t)),
            "csgnb_precompute_s": csg_pre, "csgnb_precompute_cpu_s": csg_pre_cpu, "manifold3d_precompute_s": mf_pre,
            "csgnb_prisms_s": prisms_s, "csgnb_prisms_cpu_s": prisms_cpu, "distinct_sweeps": ds.period,
            "median_ms": float(np.median(csg_t) * 1e3), "max_ms": float(np.max(csg_t) * 1e3),
            "first_tenth_median_ms": first * 1e3, "last_tenth_median_ms": last * 1e3,
            "repeated_steps": int(sum(repeated)), "memo": not args.no_memo,
            "boundary_cache": not args.no_boundary_cache, "boundary_merges": int(work.oc.counts[S_BOUNDARY_MERGES]),
            "manifold3d_median_ms": float(np.median(mf_t) * 1e3), "manifold3d_first_tenth_median_ms": mfirst * 1e3,
            "manifold3d_last_tenth_median_ms": mlast * 1e3,
            "faces": surface.n_polygons, "faces_merged": surface.merged().n_polygons,
            "manifold3d_triangles": int(cube.num_tri()),
            "cells": work.n_cells, "bsp_nodes": work.n_bsp_nodes, "cell_merges": work.stats.merges,
            "volume": float(vol), "manifold3d_volume": float(mf_vol),
            "volume_rel_dev": float(abs(float(vol) - mf_vol) / float(vol)),
            "per_step_ms": [x * 1e3 for x in csg_t], "manifold3d_per_step_ms": [x * 1e3 for x in mf_t]}


def drill_mesh_workload(args) -> dict:
    """The drill of Figures 13-14 with its 90 sweep volumes given as **float triangle meshes** (each the union of
    the step's prisms, made by manifold3d before anything is timed: the input a user brings), end to end: csgnb
    quantizes each mesh onto the grid and prepares a tool once (``Tool.from_mesh``: validation, flat-face repair,
    BSP), then subtracts the 270 translated steps; manifold3d builds a ``Manifold`` from each mesh and subtracts the
    same translated steps. Tool preparation is timed with the steps on both sides. With ``--shards`` other than 1
    the same steps also run on every core (:class:`~csgnb.distributed.sharded.ShardedWorkpiece`), end to end with the
    tools prepared once."""
    import manifold3d as m3

    grid = _drill_grid(args)
    drill = tools.twist_drill().on(grid)
    ds = sweep.drill_sweeps(drill, feed_per_turn=args.feed)
    n_steps = len(ds)
    meshes = []
    for k in range(ds.period):  # the distinct sweeps (steps k and k + period are the same volume)
        union = m3.Manifold.batch_boolean([m3.Manifold.hull_points(grid.to_model(h.points)) for h in ds.steps[k]],
                                          m3.OpType.Add)
        mesh = union.to_mesh64()
        # copies: manifold3d's arrays are read-only views, which Mesh64 refuses to take back
        meshes.append((np.array(mesh.vert_properties, np.float64)[:, :3].copy(),
                       np.array(mesh.tri_verts, np.int64)))
    lo, hi = np.array([-10.0, -10.0, -15.0]), np.array([10.0, 10.0, 6.0])
    total = args.turns * n_steps
    # -- csgnb: tools once, then the steps ------------------------------------------------
    wall, cpu = time.perf_counter(), time.process_time()
    prepared = []
    refused = None
    for k, (V, F) in enumerate(meshes):
        try:
            # rounded onto the grid, manifold3d's unions fold in places: refused as solids, with the advice to
            # take them as winding fills (fill="winding"), which is what a user does next
            prepared.append(Tool.from_mesh(grid.to_grid(V), F, width=args.width, grid=grid, fill=args.fill))
        except GeometryError as exc:  # what a user gets: the reason, not a crash of the whole benchmark
            return {"refused": f"sweep {k}: {exc}", "tool_triangles": int(sum(len(F) for _, F in meshes))}
    if args.fill == "winding":
        try:
            Tool.from_mesh(grid.to_grid(meshes[0][0]), meshes[0][1], width=args.width, grid=grid)
        except GeometryError as exc:
            refused = str(exc).split(" -- ")[0][:160]
    prep_s, prep_cpu = time.perf_counter() - wall, time.process_time() - cpu
    step_tools = [prepared[k % ds.period] for k in range(n_steps)]
    par, par_vol = None, None
    if args.shards != 1:  # what a user runs on every core: the workpiece in spatial shards on threads, same tools
        par, par_vol = _drill_on_shards(args, grid, (lo, hi), step_tools, ds.feed, total)
        par["end_to_end_s"] = prep_s + par["wall_s"]
    # -- the same steps on one workpiece, one core ---------------------------------------
    c0 = time.process_time()
    work = Workpiece.box(lo, hi, grid=grid, threshold=args.threshold)
    repeated: list[bool] = []
    ts = _drill_steps(work, step_tools, ds.feed, total, args.verbose, repeated)
    csg_wall, csg_cpu = prep_s + float(sum(ts)), prep_cpu + time.process_time() - c0
    # -- manifold3d ---------------------------------------------------------------------
    lo_g, hi_g = grid.to_grid(np.stack([lo, hi]))
    lo_m, hi_m = grid.to_model(lo_g[None])[0], grid.to_model(hi_g[None])[0]
    wall, cpu = time.perf_counter(), time.process_time()
    tools_m = [m3.Manifold(m3.Mesh64(vert_properties=V, tri_verts=F.astype(np.uint64))) for V, F in meshes]
    cube = m3.Manifold.cube(list(hi_m - lo_m)).translate(list(lo_m))
    feed_model = ds.feed / grid.scale
    mts = []
    for i in range(total):
        turn, k = divmod(i, n_steps)
        t = time.perf_counter()
        cube = cube - tools_m[k % ds.period].translate(list(feed_model * turn))
        cube.num_tri()
        mts.append(time.perf_counter() - t)
    mf_wall, mf_cpu = time.perf_counter() - wall, time.process_time() - cpu
    t0, c0 = time.perf_counter(), time.process_time()
    exact_volume = work.model_volume()  # what a user asks at the end: every cell's exact volume, summed
    volume_s, volume_cpu = time.perf_counter() - t0, time.process_time() - c0
    vol = float(exact_volume)
    if par is not None:
        par.update({"speed_up": float(sum(ts)) / par["wall_s"], "same_volume": bool(par_vol == exact_volume)})
    first, last = _tenths([t for t, r in zip(ts, repeated, strict=True) if not r])  # over the steps that cut
    return {"steps": total, "repeated_steps": int(sum(repeated)), "every_core": par,
            "csgnb_s": csg_wall, "csgnb_cpu_s": csg_cpu, "csgnb_tool_preparation_s": prep_s,
            "manifold3d_s": mf_wall, "manifold3d_cpu_s": mf_cpu, "median_ms": float(np.median(ts) * 1e3),
            "first_tenth_median_ms": first * 1e3, "last_tenth_median_ms": last * 1e3,
            "manifold3d_median_ms": float(np.median(mts) * 1e3), "tool_triangles": int(sum(len(F) for _, F in meshes)),
            "fill": args.fill, "refused_as_solids": refused,
            "tool_polygons": int(sum(len(t.polygons) for t in prepared)),
            "faces": work.surface().n_polygons, "manifold3d_triangles": int(cube.num_tri()), "cells": work.n_cells,
            "boundary_cache": not args.no_boundary_cache, "boundary_merges": int(work.oc.counts[S_BOUNDARY_MERGES]),
            "bsp_nodes": work.n_bsp_nodes, "volume": vol, "manifold3d_volume": float(cube.volume()),
            "exact_volume_s": volume_s, "exact_volume_cpu_s": volume_cpu,
            "exact_volume_denominator_bits": exact_volume.denominator.bit_length(),
            "volume_rel_dev": abs(vol - float(cube.volume())) / vol}


def _unit_sphere(n_lat: int = 6, n_lon: int = 10) -> np.ndarray:
    """Points of a UV sphere of radius 1 ``(2 + (n_lat - 1) n_lon, 3)``, rings staggered."""
    pts = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]
    for i in range(1, n_lat):
        th = np.pi * i / n_lat
        ph = 2 * np.pi * (np.arange(n_lon) + 0.5 * (i % 2)) / n_lon
        pts += np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.full(n_lon, np.cos(th))], 1).tolist()
    return np.array(pts)


def dome_setup(steps: int, width: int, radius: float = 10.0, groove: float = 0.6, turns: int = 10):
    """A hemisphere (radius 10 mm, 313 points) and ``steps`` capsules (radius 0.6 mm, 102 points each) whose axes
    follow a spiral on its surface from the pole down to 8 % above the rim: grid points, model ``(grid, dome,
    [capsule points])``. Consecutive capsules overlap most of their length, like a ball-nose groove."""
    grid = Grid.fit([-radius - 2, -radius - 2, -1.0], [radius + 2, radius + 2, radius + 2], width=width)
    rings = [np.zeros((1, 3)) + [0, 0, radius]]
    for i in range(1, 13):
        th = 0.5 * np.pi * i / 12
        ph = 2 * np.pi * np.arange(24) / 24
        rings.append(radius * np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.full(24, np.cos(th))], 1))
    dome = np.concatenate(rings + [rings[-1] * [1, 1, 0]])
    t = np.linspace(0.0, 1.0, steps + 1)
    th = 0.05 + t * (0.46 * np.pi - 0.05)
    ph = 2 * np.pi * turns * t
    path = radius * np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    ball = groove * _unit_sphere()
    caps = [grid.to_grid(np.concatenate([path[i] + ball, path[i + 1] + ball])) for i in range(steps)]
    return grid, grid.to_grid(dome), caps


def _carve(args, grid, stock, tools_, warm: int, mf_stock, mf_tool):
    """The hull of the grid points ``stock`` minus the hull of each of ``tools_`` (point arrays), the hull built in its
    step and both timed; then manifold3d's ``mf_stock`` minus ``mf_tool(points)`` the same way (``warm`` steps run on
    a scratch workpiece first, so that no kernel loads inside the timed loop).

    Returns the workpiece and the figures both workloads print (times, faces, volumes).
    """
    scratch = Workpiece.empty(grid, threshold=args.threshold)
    scratch |= convex_hull(stock, grid=grid)
    for points in tools_[:warm]:
        scratch -= convex_hull(points, grid=grid)
    w = Workpiece.empty(grid, threshold=args.threshold)
    w |= convex_hull(stock, grid=grid)
    wall, cpu = time.perf_counter(), time.process_time()
    ts = []
    for points in tools_:
        t = time.perf_counter()
        w -= convex_hull(points, grid=grid)
        ts.append(time.perf_counter() - t)
    csg_wall, csg_cpu = time.perf_counter() - wall, time.process_time() - cpu
    solid = mf_stock
    wall, cpu = time.perf_counter(), time.process_time()
    mts = []
    for points in tools_:
        t = time.perf_counter()
        solid = solid - mf_tool(points)
        solid.num_tri()  # manifold3d evaluates lazily: force the Boolean
        mts.append(time.perf_counter() - t)
    mf_wall, mf_cpu = time.perf_counter() - wall, time.process_time() - cpu
    vol = float(w.model_volume())
    first, last = _tenths(ts)
    return w, {"steps": len(tools_), "csgnb_s": csg_wall, "csgnb_cpu_s": csg_cpu, "manifold3d_s": mf_wall,
               "manifold3d_cpu_s": mf_cpu, "median_ms": float(np.median(ts) * 1e3),
               "manifold3d_median_ms": float(np.median(mts) * 1e3), "first_tenth_median_ms": first * 1e3,
               "last_tenth_median_ms": last * 1e3, "faces": w.surface().n_polygons,
               "faces_merged": w.surface(merged=True).n_polygons,
               "manifold3d_triangles": int(solid.num_tri()), "cells": w.n_cells, "bsp_nodes": w.n_bsp_nodes,
               "volume": vol, "manifold3d_volume": float(solid.volume()),
               "volume_rel_dev": abs(vol - float(solid.volume())) / vol}


def dome_workload(args, steps: int) -> dict:
    """The hemisphere minus ``steps`` capsules; each step builds its tool from the capsule's points (csgnb: the exact
    hull; manifold3d: ``hull_points`` of the same grid points) and subtracts it, both timed."""
    import manifold3d as m3

    grid, dome, caps = dome_setup(steps, args.width)
    return _carve(args, grid, dome, caps, 3, m3.Manifold.hull_points(grid.to_model(dome)),
                  lambda c: m3.Manifold.hull_points(grid.to_model(c)))[1]


def lattice_ops(n: int, seed: int = 7) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``n`` Booleans of axis-aligned cubes on a 10 x 10 x 10 lattice (pitch 10, integer corners): cubes of side 12
    (overlapping their neighbours, so faces are coplanar and edges meet) unioned, and cubes of side 6 centred on
    lattice points or on cell centres subtracted, two unions to one difference, in a random order."""
    rng = np.random.default_rng(seed)
    ops = []
    for i in range(n):
        site = rng.integers(0, 10, 3) * 10 + 20
        if i % 3 == 2:
            centre = site + (5 if rng.random() < 0.5 else 0)
            ops.append(("difference", centre - 3, centre + 3))
        else:
            ops.append(("union", site - 6, site + 6))
    return ops


def _box_points(lo, hi, dtype=np.int64) -> np.ndarray:
    return np.array([[(hi if k & (1 << a) else lo)[a] for a in range(3)] for k in range(8)], dtype)


def lattice_workload(args, n: int) -> dict:
    """The cube lattice on the identity grid: csgnb with the exact volume change of every step (``track_volume``)
    checked against an independent voxel count (each cube covers whole unit voxels), manifold3d on the same cubes
    with its volume compared at every step."""
    import manifold3d as m3

    ops = lattice_ops(n)
    occupancy = np.zeros((140, 140, 140), bool)  # unit voxels [0, 140)^3 hold every cube
    w = Workpiece.empty(width=args.width, threshold=args.threshold)
    warm = Workpiece.empty(width=args.width, threshold=args.threshold)  # kernels loaded before anything is timed
    for op, lo, hi in ops[:6]:
        getattr(warm, op)(convex_hull(_box_points(lo, hi), width=args.width), track_volume=True)
    ts, volume, mismatches, csg_cpu = [], Fraction(0), 0, 0.0
    for op, lo, hi in ops:
        t, cpu = time.perf_counter(), time.process_time()
        report = getattr(w, op)(convex_hull(_box_points(lo, hi), width=args.width), track_volume=True)
        ts.append(time.perf_counter() - t)
        csg_cpu += time.process_time() - cpu
        volume += report.volume_change
        occupancy[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = op == "union"
        mismatches += volume != int(occupancy.sum())
    exact_final = w.volume() == int(occupancy.sum())
    solid = m3.Manifold()
    mts, mf_dev = [], 0.0
    cpu = time.process_time()
    for op, lo, hi in ops:
        t = time.perf_counter()
        cube = m3.Manifold.cube((hi - lo).astype(float).tolist()).translate(lo.astype(float).tolist())
        solid = solid + cube if op == "union" else solid - cube
        solid.num_tri()
        mts.append(time.perf_counter() - t)
    mf_cpu = time.process_time() - cpu
    mf_dev = abs(float(solid.volume()) - int(occupancy.sum())) / int(occupancy.sum())
    return {"ops": n, "csgnb_s": float(sum(ts)), "csgnb_cpu_s": csg_cpu, "manifold3d_s": float(sum(mts)),
            "manifold3d_cpu_s": mf_cpu, "median_ms": float(np.median(ts) * 1e3),
            "manifold3d_median_ms": float(np.median(mts) * 1e3), "volume": int(occupancy.sum()),
            "exact_volume_mismatches": int(mismatches), "exact_final_volume": bool(exact_final),
            "manifold3d_volume_rel_dev": mf_dev, "cells": w.n_cells, "bsp_nodes": w.n_bsp_nodes,
            "faces": w.surface().n_polygons, "faces_merged": w.surface(merged=True).n_polygons,
            "manifold3d_triangles": int(solid.num_tri())}


def boxes_setup(n: int, width: int, seed: int = 3):
    """A 20 mm block and ``n`` axis-aligned boxes (centres anywhere in it, half-sides 0.5-3 mm) as grid corner points
    on the finest grid of ``width`` bits for the 24 mm cube around them: ``(grid, block, [box corners])``."""
    rng = np.random.default_rng(seed)
    grid = Grid.fit([-12.0] * 3, [12.0] * 3, width=width)
    block = grid.to_grid(_box_points(np.full(3, -10.0), np.full(3, 10.0), float))
    boxes = []
    for _ in range(n):
        centre, half = rng.uniform(-10.0, 10.0, 3), rng.uniform(0.5, 3.0, 3)
        boxes.append(grid.to_grid(_box_points(centre - half, centre + half, float)))
    return grid, block, boxes


def boxes_exact_volume(block: np.ndarray, boxes: list[np.ndarray]) -> int:
    """The block minus the boxes, in grid units cubed, independently of csgnb: every box's faces are grid planes, so
    between consecutive distinct x coordinates the solid is a prism over a 2-D region, whose area is counted over the
    compressed y and z coordinates of the boxes spanning that slab (Python ints: exact)."""
    lo, hi = block.min(0), block.max(0)
    clipped = [(bl, bh) for bl, bh in ((np.maximum(b.min(0), lo), np.minimum(b.max(0), hi)) for b in boxes)
               if np.all(bl < bh)]
    xs = np.unique(np.concatenate([[lo[0], hi[0]]] + [[bl[0], bh[0]] for bl, bh in clipped]))
    volume = 0
    for x0, x1 in zip(xs[:-1], xs[1:], strict=True):
        active = [(bl, bh) for bl, bh in clipped if bl[0] <= x0 and bh[0] >= x1]
        ys, zs = (np.unique(np.concatenate([[lo[a], hi[a]]] + [[bl[a], bh[a]] for bl, bh in active])) for a in (1, 2))
        solid = np.ones((len(ys) - 1, len(zs) - 1), bool)
        for bl, bh in active:
            (j0, j1), (k0, k1) = np.searchsorted(ys, (bl[1], bh[1])), np.searchsorted(zs, (bl[2], bh[2]))
            solid[j0:j1, k0:k1] = False
        heights = solid.astype(np.int64) @ np.diff(zs)  # each at most the block's height: int64
        area = sum(int(dy) * int(h) for dy, h in zip(np.diff(ys), heights, strict=True))
        volume += int(x1 - x0) * area
    return volume


def boxes_workload(args, n: int) -> dict:
    """The block minus ``n`` boxes; each step builds its tool from the box's corners, both libraries timed alike."""
    import manifold3d as m3

    grid, block, boxes = boxes_setup(n, args.width)

    def cube(points):
        m = grid.to_model(points)
        return m3.Manifold.cube((m.max(0) - m.min(0)).tolist()).translate(m.min(0).tolist())

    # 40 warm-up steps: kernels loaded, splits and combines included, before anything is timed
    w, figures = _carve(args, grid, block, boxes, 40, cube(block), cube)
    return figures | {"exact_volume_equal": bool(w.volume() == boxes_exact_volume(block, boxes))}


def gear_hulls(samples: int, width: int):
    grid = Grid.fit([-10, -20, -10], [70, 40, 20], width=width)
    gear = tools.spur_gear().on(grid)
    control = np.array([[0, 0, 0], [20, 30, 5], [40, -10, 10], [60, 20, 0]], float)
    sweeps = sweep.path_sweep(gear, [sweep.Pose(p) for p in sweep.bezier_points(control, samples)])
    return grid, [h for s in sweeps for h in s.hulls]


def gear_workload(args, samples: int, threshold: int, with_manifold: bool = True) -> dict:
    grid, hulls = gear_hulls(samples, args.width)
    warm = Workpiece.empty(grid, threshold=threshold)  # kernels loaded (or compiled) before anything is timed:
    for h in hulls[:8]:  # after a kernel edit the batch kernel alone compiles for ~30 s inside the timed run
        warm |= h
    Workpiece.empty(grid, threshold=threshold).run(hulls[:64], "union")
    w = Workpiece.empty(grid, threshold=threshold)
    ts = []
    for h in hulls:
        t = time.perf_counter()
        w |= h
        ts.append(time.perf_counter() - t)
    first, last = _tenths(ts)
    # the same unions as a user runs many: Workpiece.run, convex hulls in compiled batches (csgnb.octree.batch)
    wb = Workpiece.empty(grid, threshold=threshold)
    t0, c0 = time.perf_counter(), time.process_time()
    wb.run(hulls, "union")
    batched_s, batched_cpu = time.perf_counter() - t0, time.process_time() - c0
    out = {"samples": samples, "threshold": threshold, "unions": len(hulls), "csgnb_s": float(sum(ts)),
           "csgnb_run_s": batched_s, "csgnb_run_cpu_s": batched_cpu,
           "csgnb_run_ms_per_op": batched_cpu / len(hulls) * 1e3, "same_volume_run": bool(wb.volume() == w.volume()),
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
    parser.add_argument("--workloads", nargs="+",
                        default=["drill", "drill_mesh", "gear_sweep", "dome", "lattice", "boxes"],
                        choices=["drill", "drill_mesh", "gear_sweep", "dome", "lattice", "boxes"])
    parser.add_argument("--width", type=int, default=128)
    parser.add_argument("--threshold", type=int, default=150)
    parser.add_argument("--resolution", type=float, default=None,
                        help="the drill's grid step in mm (default: the finest its box allows at --width bits; "
                             "2**-8 = 0.00390625 is the 128-bit one)")
    parser.add_argument("--turns", type=int, default=3)
    parser.add_argument("--fill", choices=["winding", "solid"], default="winding",
                        help="how drill_mesh takes manifold3d's sweep meshes (Tool.from_mesh's fill)")
    parser.add_argument("--feed", type=float, default=1.0, help="drill feed per turn (mm)")
    parser.add_argument("--shards", type=int, default=None,
                        help="drill on every core: shards on threads (default one per core; 1: skip)")
    parser.add_argument("--samples", type=int, nargs="+", default=[20], help="gear sweep sample positions")
    parser.add_argument("--mf-gear-ops", type=int, default=2000, help="gear unions manifold3d runs (one by one)")
    parser.add_argument("--sweep", type=int, nargs="*", default=None, help="thresholds for the Figure 11 sweep")
    parser.add_argument("--faces", action="store_true", help="extract the gear sweep's surface to count faces")
    parser.add_argument("--dome-steps", type=int, nargs="+", default=[1000], help="capsules per dome carve")
    parser.add_argument("--lattice-ops", type=int, default=2000, help="cube lattice Booleans")
    parser.add_argument("--box-steps", type=int, default=200, help="boxes subtracted from the block")
    parser.add_argument("--perf-map", action="store_true",
                        help="name the compiled kernels for perf (run under perf record; see _perf_map.py)")
    parser.add_argument("--no-memo", action="store_true",
                        help="apply repeated mesh-tool differences again instead of skipping them (the drill's "
                             "repeated half-turns: the cost without Workpiece's memo of applied differences)")
    parser.add_argument("--no-boundary-cache", action="store_true",
                        help="cells do not keep their boundary: every mesh-tool cell merge cuts (the A/B of "
                             "Workpiece.boundary_cache)")
    parser.add_argument("--verbose", action="store_true")
    parser.add_argument("--json", type=str, default=None)
    args = parser.parse_args()
    if args.no_memo:  # every workpiece of this run applies repeated differences again (the A/B of the memo)
        Workpiece._applied_key = lambda self, tool, within: None
    if args.no_boundary_cache:
        plain_init = Workpiece.__init__

        def init_without_cache(self, *a, **kw):
            plain_init(self, *a, **kw)
            self.boundary_cache = False

        Workpiece.__init__ = init_without_cache
    if args.perf_map:
        import _perf_map  # noqa: F401 -- before the first kernel is loaded

    print(f"csgnb iterated CSG, {args.width}-bit, threshold {args.threshold}, one core (the drill also on every "
          f"core), clock {nominal_clock_label()}")
    result = {"clock": nominal_clock_label(), "width": args.width, "threshold": args.threshold,
              "resolution": args.resolution, "workloads": {}}
    if "drill" in args.workloads:
        d = drill_workload(args)
        result["workloads"]["drill"] = d
        verdict = "met" if d["csgnb_s"] <= d["manifold3d_s"] else "NOT met"
        flat = d["last_tenth_median_ms"] <= 1.5 * d["first_tenth_median_ms"]
        print(f"\ndrill: {d['steps']} subtractions; csgnb {d['csgnb_s']:.1f} s vs manifold3d {d['manifold3d_s']:.1f} s "
              f"(target csgnb <= manifold3d: {verdict})")
        par = d["every_core"]
        if par is not None:
            end = d["csgnb_precompute_s"] + par["wall_s"]
            print(f"  on every core ({par['shards']} shards on threads, ShardedWorkpiece(work, None)): "
                  f"{par['wall_s']:.1f} s wall / {par['cpu_s']:.1f} s CPU against one workpiece's "
                  f"{d['csgnb_s']:.1f} s wall / {d['csgnb_cpu_s']:.1f} s CPU: {par['speed_up']:.2f}x "
                  f"(target >= 1.7x: {'met' if par['speed_up'] >= 1.7 else 'NOT met'}); exact volume equal: "
                  f"{par['same_volume']}; end to end with the precompute {end:.1f} s (target <= 30 s: "
                  f"{'met' if end <= 30 else 'NOT met'})")
        print(f"  sweeps precomputed ({d['distinct_sweeps']} distinct of {d['steps'] // args.turns}, the drill's turn "
              f"symmetry; both libraries build only those): csgnb {d['csgnb_precompute_s']:.1f} s wall / "
              f"{d['csgnb_precompute_cpu_s']:.1f} s "
              f"CPU (the prisms' exact hulls, drill_sweeps, {d['csgnb_prisms_s']:.1f} s; then DrillSweeps.tools, every "
              f"core), manifold3d {d['manifold3d_precompute_s']:.1f} s from the same prisms' points (timed apart)")
        print(f"  per step: median {d['median_ms']:.0f} ms, max {d['max_ms']:.0f} ms; {d['repeated_steps']} steps "
              f"repeat an earlier sweep at the same place (exact no-ops, "
              f"{'skipped' if d['memo'] else 'applied again: --no-memo'}); over the steps that cut, first tenth "
              f"{d['first_tenth_median_ms']:.0f} ms, last tenth {d['last_tenth_median_ms']:.0f} ms "
              f"(flat within 1.5x: {'met' if flat else 'NOT met'}); manifold3d median {d['manifold3d_median_ms']:.0f} "
              f"ms, first/last tenth {d['manifold3d_first_tenth_median_ms']:.0f}/"
              f"{d['manifold3d_last_tenth_median_ms']:.0f} ms")
        print(f"  result: {d['faces']} exact polygons ({d['faces_merged']} with coplanar pieces merged, "
              f"{d['faces_merged'] / d['manifold3d_triangles']:.2f}x manifold3d's triangles; target <= 1.5x) "
              f"({d['cells']} cells, {d['bsp_nodes']} BSP nodes, "
              f"{d['cell_merges']} cell merges); manifold3d {d['manifold3d_triangles']} triangles; volume "
              f"{d['volume']:.6f} vs {d['manifold3d_volume']:.6f} mm^3 (rel. dev. {d['volume_rel_dev']:.2e})")
    if "drill_mesh" in args.workloads:
        d = drill_mesh_workload(args)
        result["workloads"]["drill_mesh"] = d
        if "refused" in d:
            print(f"\ndrill, tools as meshes ({d['tool_triangles']} triangles in the 45 distinct sweeps): csgnb "
                  "REFUSED "
                  f"{d['refused']}")
        else:
            half = d["csgnb_cpu_s"] <= 0.5 * d["manifold3d_cpu_s"]
            flat = d["last_tenth_median_ms"] <= 1.5 * d["first_tenth_median_ms"]
            print(f"\ndrill, tools as meshes ({d['tool_triangles']} triangles in the 45 distinct sweeps), end to end: "
                  "csgnb "
                  f"{d['csgnb_s']:.1f} s wall / {d['csgnb_cpu_s']:.1f} s CPU (tools prepared in "
                  f"{d['csgnb_tool_preparation_s']:.1f} s), manifold3d {d['manifold3d_s']:.1f} s / "
                  f"{d['manifold3d_cpu_s']:.1f} s CPU (target CPU <= 0.5x: {'met' if half else 'NOT met'}; <= 30 s: "
                  f"{'met' if d['csgnb_s'] <= 30 else 'NOT met'})")
            print(f"  per step: median {d['median_ms']:.0f} ms ({d['repeated_steps']} repeats skipped), over the steps "
                  f"that cut first/last tenth {d['first_tenth_median_ms']:.0f}/"
                  f"{d['last_tenth_median_ms']:.0f} ms (growth <= 1.5x: {'met' if flat else 'NOT met'}); manifold3d "
                  f"median {d['manifold3d_median_ms']:.0f} ms; {d['faces']} polygons vs "
                  f"{d['manifold3d_triangles']} triangles; volume rel. dev. {d['volume_rel_dev']:.1e}; the exact "
                  f"volume ({d['exact_volume_denominator_bits']}-bit denominator) in "
                  f"{d['exact_volume_cpu_s']:.1f} s CPU")
            print(f"  tools: fill={d['fill']!r}, {d['tool_polygons']} exact polygons from the 45 meshes; as solids "
                  f"they are refused: {d['refused_as_solids']}")
            par = d["every_core"]
            if par is not None:
                print(f"  on {par['shards']} shards (threads): steps {par['wall_s']:.1f} s wall / "
                      f"{par['cpu_s']:.1f} s CPU ({par['speed_up']:.2f}x one workpiece; the same exact volume: "
                      f"{par['same_volume']}); end to end with the tools {par['end_to_end_s']:.1f} s (<= 30 s: "
                      f"{'met' if par['end_to_end_s'] <= 30 else 'NOT met'})")
    if "gear_sweep" in args.workloads:
        gears = {}
        for s in args.samples:
            g = gear_workload(args, s, args.threshold)
            gears[s] = g
            verdict = "met" if g["csgnb_ms_per_op"] <= 1.0 else "NOT met"
            print(f"\ngear sweep, S = {s}: {g['unions']} unions, csgnb {g['csgnb_s']:.1f} s = "
                  f"{g['csgnb_ms_per_op']:.2f} ms per union (target <= 1 ms: {verdict}); median {g['median_ms']:.2f}, "
                  f"first/last tenth {g['first_tenth_median_ms']:.2f}/{g['last_tenth_median_ms']:.2f} ms")
            print(f"  as Workpiece.run (compiled batches): {g['csgnb_run_s']:.1f} s wall / "
                  f"{g['csgnb_run_cpu_s']:.1f} s CPU = {g['csgnb_run_ms_per_op']:.2f} ms per union; the same volume: "
                  f"{g['same_volume_run']}")
            print(f"  manifold3d: {g['manifold3d_ms_per_op']:.2f} ms per union over the first "
                  f"{g['manifold3d_unions']} (csgnb {g['csgnb_ms_per_op_first_n']:.2f} ms over the same); volume "
                  f"rel. dev. {g['volume_rel_dev']:.2e}; {g['cells']} cells, {g['bsp_nodes']} BSP nodes")
        main_gear = gears[args.samples[0]]
        result["workloads"]["gear_sweep"] = main_gear
        result["workloads"]["gear_sweep_by_samples"] = {str(k): v for k, v in gears.items()}
    if "dome" in args.workloads:
        domes = {}
        for n in args.dome_steps:
            d = dome_workload(args, n)
            domes[str(n)] = d
            half = d["csgnb_cpu_s"] <= 0.5 * d["manifold3d_cpu_s"]
            print(f"\ndome carve, {n} capsules: csgnb {d['csgnb_s']:.2f} s wall / {d['csgnb_cpu_s']:.2f} s CPU, "
                  f"manifold3d {d['manifold3d_s']:.2f} s wall / {d['manifold3d_cpu_s']:.2f} s CPU (target csgnb "
                  f"CPU <= 0.5x manifold3d's: {'met' if half else 'NOT met'}; 1,000 steps <= 3 s: "
                  f"{'-' if n != 1000 else 'met' if d['csgnb_s'] <= 3 else 'NOT met'})")
            print(f"  per step: median {d['median_ms']:.2f} ms (manifold3d {d['manifold3d_median_ms']:.2f}), "
                  f"first/last tenth {d['first_tenth_median_ms']:.2f}/{d['last_tenth_median_ms']:.2f} ms; "
                  f"{d['faces']} polygons ({d['faces_merged']} merged: "
                  f"{d['faces_merged'] / d['manifold3d_triangles']:.2f}x, target <= 1.5x) vs "
                  f"{d['manifold3d_triangles']} triangles; volume rel. dev. {d['volume_rel_dev']:.1e}")
        result["workloads"]["dome"] = domes
    if "lattice" in args.workloads:
        d = lattice_workload(args, args.lattice_ops)
        result["workloads"]["lattice"] = d
        half = d["csgnb_cpu_s"] <= 0.5 * d["manifold3d_cpu_s"]
        print(f"\ncube lattice, {d['ops']} Booleans: csgnb {d['csgnb_s']:.2f} s / {d['csgnb_cpu_s']:.2f} s CPU (exact "
              f"volume tracked every step), manifold3d {d['manifold3d_s']:.2f} s / {d['manifold3d_cpu_s']:.2f} s CPU "
              f"(target csgnb CPU <= 0.5x: {'met' if half else 'NOT met'}); median {d['median_ms']:.2f} vs "
              f"{d['manifold3d_median_ms']:.2f} ms")
        print(f"  exact volume vs voxel count: {d['exact_volume_mismatches']} mismatches in {d['ops']} steps, final "
              f"{'equal' if d['exact_final_volume'] else 'DIFFERENT'}; manifold3d final rel. dev. "
              f"{d['manifold3d_volume_rel_dev']:.1e}; {d['faces']} polygons ({d['faces_merged']} merged) vs "
              f"{d['manifold3d_triangles']} triangles")
    if "boxes" in args.workloads:
        d = boxes_workload(args, args.box_steps)
        result["workloads"]["boxes"] = d
        half = d["csgnb_cpu_s"] <= 0.5 * d["manifold3d_cpu_s"]
        print(f"\naligned boxes, a block minus {d['steps']}: csgnb {d['csgnb_s']:.3f} s / {d['csgnb_cpu_s']:.3f} s CPU "
              f"(hulls included), manifold3d {d['manifold3d_s']:.3f} s / {d['manifold3d_cpu_s']:.3f} s CPU (target "
              f"csgnb CPU <= 0.5x: {'met' if half else 'NOT met'}); median {d['median_ms']:.2f} vs "
              f"{d['manifold3d_median_ms']:.2f} ms, first/last tenth {d['first_tenth_median_ms']:.2f}/"
              f"{d['last_tenth_median_ms']:.2f} ms")
        same = "equal" if d["exact_volume_equal"] else "DIFFERENT"
        print(f"  exact volume vs the compressed-coordinate count: {same}; manifold3d rel. dev. "
              f"{d['volume_rel_dev']:.1e}; {d['faces']} polygons ({d['faces_merged']} merged) "
              f"vs {d['manifold3d_triangles']} triangles; {d['cells']} cells, {d['bsp_nodes']} BSP nodes")
    if args.sweep:
        print(f"\nFigure 11: gear sweep (S = {args.samples[0]}) total time by BSP threshold")
        rows = []
        for th in args.sweep:
            g = gear_workload(args, args.samples[0], th, with_manifold=False)
            rows.append({"threshold": th, "csgnb_s": g["csgnb_s"], "cells": g["cells"], "bsp_nodes": g["bsp_nodes"]})
            print(f"  threshold {th:>4}: {g['csgnb_s']:.2f} s, {g['cells']} cells, {g['bsp_nodes']} BSP nodes")
        result["threshold_sweep"] = rows
    if args.perf_map:
        import _perf_map

        _perf_map.write_perf_map()
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=1)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
