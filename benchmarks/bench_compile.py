"""Compile time of csgnb's numba kernels from a cold cache (issue 21).

Every figure is taken in a fresh child process whose ``NUMBA_CACHE_DIR`` is an empty temporary folder
(:mod:`csgnb._jit` caches there when the variable is set), on a copy of the package in a temporary folder
(so that an edit can be simulated without touching the checkout; the copy is what the child imports).
Wall time is the parent's clock around the child; CPU time is the child's user + system time from
``getrusage(RUSAGE_CHILDREN)`` (it includes the second process :func:`csgnb.warmup.warm_up` starts).

Stages (``--stages``, default all):

* **serial**: ``warm_up(part, parallel=False)`` for each part in the order of :data:`csgnb.warmup.PARTS`,
  in one process from a cold cache: wall and CPU seconds per part (a part pays only for the kernels the
  parts before it did not compile). With ``--kernels N`` the N kernels with the most exclusive compile time
  are listed (numba's ``numba:compile`` events: number of signatures, exclusive and inclusive seconds).
* **tour**: what ``notebooks/00_tour.ipynb`` runs, from a cold cache: ``warm_up()`` (both tracks, the
  second in a second process as the notebook does), then the notebook's computations without pyvista
  (``tour_extra``: the kernels ``warm_up`` did not compile, plus their run time).
* **edit**: after the tour, one comment line is appended to the copy's ``csgnb/octree/kernels.py`` (an
  edit of one octree module) and ``warm_up()`` runs again: the recompilation it causes.
* **warm**: ``warm_up()`` once more with nothing to compile (loading from the cache).

Targets (issue 21): tour <= 90 s wall on 2 cores; edit <= 60 s wall. ``--json PATH`` writes the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import shutil
import subprocess
import sys
import tempfile
import time

from _clock import load_average, nominal_clock_label

REPO = pathlib.Path(__file__).resolve().parent.parent
# csgnb.warmup.PARTS, in order
PARTS = ("exact", "mesh", "extraction", "bsp", "octree", "boundary", "tools", "quadric", "sampling", "render")
EDITED = pathlib.Path("csgnb", "octree", "kernels.py")

# -- the child ------------------------------------------------------------------------------------------------


class _CompileEvents:
    """Exclusive and inclusive seconds and signatures per kernel, from numba's ``numba:compile`` events."""

    def __init__(self):
        from numba.core import event

        self.stack: list[list] = []  # [name, start, child seconds]
        self.stats: dict[str, list] = {}  # name -> [signatures, exclusive s, inclusive s]
        self.signatures: dict[str, list[str]] = {}  # name -> argument types of each compilation

        outer = self

        class Listener(event.Listener):
            def on_start(self, ev):
                d = ev.data["dispatcher"]
                name = f"{d.py_func.__module__}.{d.py_func.__qualname__}"
                outer.stack.append([name, time.perf_counter(), 0.0])
                outer.signatures.setdefault(name, []).append(", ".join(str(a) for a in ev.data["args"]))

            def on_end(self, ev):
                name, t0, inner = outer.stack.pop()
                dt = time.perf_counter() - t0
                if outer.stack:
                    outer.stack[-1][2] += dt
                s = outer.stats.setdefault(name, [0, 0.0, 0.0])
                s[0] += 1
                s[1] += dt - inner
                s[2] += dt

        event.register("numba:compile", Listener())


def _tour_extra() -> None:
    """The computations of ``notebooks/00_tour.ipynb`` without pyvista (an icosahedron for its icosphere)."""
    from fractions import Fraction

    import numpy as np

    import csgnb.csg as csg
    import csgnb.quadric as cq
    from csgnb import exact
    from csgnb.apps import milling, tools
    from csgnb.apps.examples import example_program
    from csgnb.bsp import BSP
    from csgnb.exact import Grid
    from csgnb.mesh import MeshStore, cut
    from csgnb.mesh.hull import convex_hull
    from csgnb.octree import Workpiece
    from csgnb.quadric import elliptic_cylinder
    from csgnb.render import Camera, compare, raytrace, render
    from csgnb.sampling import sample_csg

    g = (1 + 5 ** 0.5) / 2
    pts = np.array([[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g], [0, 1, g], [0, -1, -g], [0, 1, -g],
                    [g, 0, -1], [g, 0, 1], [-g, 0, -1], [-g, 0, 1]], float)
    tri = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                    [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                    [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    grid, quant = exact.quantize(pts, width=256)
    planes = exact.plane_from_points(grid[tri[:, 0]], grid[tri[:, 1]], grid[tri[:, 2]], width=256)
    exact.from_wide(planes[0])
    around = np.flatnonzero((tri == 7).any(axis=1))[:3]
    corner = exact.intersect_3_planes(planes[around[0]], planes[around[1]], planes[around[2]])
    quant.to_model(exact.to_double_position(corner)[None])
    c = exact.plane_from_points(grid[0], grid[1], grid[2] + [0, 0, 1], width=256)
    exact.classify_vertex(exact.homogeneous_points(grid, 256), c)

    q = cq.hyperboloid_one_sheet((1.0, 0.8, 1.2))
    planes_q = cq.sampling_planes(q)
    cq.signed_distance(q, [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    for region in cq.low_distortion_regions(q, (-2, -2, -2), (2, 2, 2)):
        for sheet in (1.0, -1.0):
            cq.region_mesh(planes_q[region.plane], region, 6, sheet)

    store = MeshStore(exact.to_wide([[2, 3, 5, -19]], 128))
    box = store.add_box([0, 0, 0], [4, 4, 4])
    parts = cut(store, box, 0)
    store.exact_volume(parts.negative) + store.exact_volume(parts.positive)
    new = store.cell_vertices(parts.negative)[-1]
    store.exact_vertices([new])

    cube = BSP.box([0, 0, 0], [12, 12, 12])
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    octahedron = BSP.from_mesh(axes * [8, 7, 9] + [12, 12, 12],
                               [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    carved = cube - octahedron
    carved.surface().is_closed()
    assert carved.volume() == 12**3 - Fraction(4, 3) * 8 * 7 * 9 / 8
    assert carved.volume() == cube.volume() - (cube & octahedron).volume()

    work = Workpiece.box([-40, -40, -40], [40, 40, 40])
    tetra = np.array([[0, 0, 0], [7, 0, 0], [0, 7, 0], [0, 0, 7]])
    t = np.linspace(0, 1, 300)
    angles, radii = 6 * np.pi * t, 6 + 30 * t
    spiral = np.rint(np.c_[radii * np.cos(angles), radii * np.sin(angles), np.full(300, 38)]).astype(np.int64)
    for p in spiral:
        work -= convex_hull(tetra + p - 3)
    assert work.volume() == work.to_bsp().volume()
    work.surface().is_closed()

    program = example_program("pocket.nc", start=(0, 0, 20))
    stock_lo, stock_hi = np.array([0.0, 0.0, -10.0]), np.array([50.0, 40.0, 0.0])
    mill_grid = Grid.fit(stock_lo - 12, stock_hi + 25)
    stock = Workpiece.box(stock_lo, stock_hi, grid=mill_grid)
    result = milling.simulate(stock, program, tools.flat_end_mill(6, 12, segments=12).on(mill_grid),
                              chord_tolerance=0.02, progress=False)
    assert result.removed == result.stock_volume - stock.model_volume()
    stock.surface().is_closed()

    plate = csg.box((0, 0, 0), (3, 2, 0.6), "plate")
    boss = csg.cylinder((1.5, 1, 0.6), (1.5, 1, 1.4), 0.6, "boss")
    hole = csg.leaf(elliptic_cylinder((0.25, 0.25)).translated((0.5, 0.5, 0)), "hole")
    part = csg.difference(plate | boss, csg.sphere((1.5, 1, 1.4), 0.45, "dimple"), hole)
    cloud = sample_csg(part, 0.04)
    camera = Camera.fit(cloud, 480, 320, azimuth=-55, elevation=35)
    compare(render(cloud, camera), raytrace(part, camera))


def child(stage: str, kernels: int, parts: list[str]) -> dict:
    events = _CompileEvents() if kernels else None
    t0, c0 = time.perf_counter(), time.process_time()
    from csgnb.warmup import warm_up

    out: dict = {"csgnb": __import__("csgnb").__file__, "import_s": time.perf_counter() - t0}
    if stage == "serial":
        out["parts"] = {}
        for name in parts:
            t, c = time.perf_counter(), time.process_time()
            warm_up(name, progress=False, parallel=False)
            out["parts"][name] = {"wall_s": time.perf_counter() - t, "cpu_s": time.process_time() - c}
    else:
        out["parts"] = {k: {"wall_s": v} for k, v in warm_up(progress=False).items()}
        if stage == "tour":
            t, c = time.perf_counter(), time.process_time()
            _tour_extra()
            out["tour_extra"] = {"wall_s": time.perf_counter() - t, "cpu_s": time.process_time() - c}
    out["child_wall_s"], out["child_cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
    if events is not None:
        ranked = sorted(events.stats.items(), key=lambda kv: -kv[1][1])
        out["kernels"] = [{"kernel": k, "signatures": s[0], "exclusive_s": s[1], "inclusive_s": s[2],
                           "argument_types": events.signatures[k] if s[0] > 1 else []} for k, s in ranked[:kernels]]
        out["n_kernels"] = len(ranked)
        out["n_signatures"] = sum(s[0] for s in events.stats.values())
    return out


# -- the parent -----------------------------------------------------------------------------------------------


def run_child(stage: str, package_root: pathlib.Path, cache: pathlib.Path, kernels: int, parts: list[str]) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(package_root), CSGNB_DISABLE_CACHE="")
    env.pop("NUMBA_DISABLE_JIT", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, __file__, "--child", stage, "--kernels", str(kernels), "--parts", *parts],
                          env=env,
                          cwd=package_root, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        sys.stderr.write(proc.stdout + proc.stderr)
        raise SystemExit(f"bench_compile: the {stage} child failed ({proc.returncode})")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    if not result["csgnb"].startswith(str(package_root)):
        raise SystemExit(f"bench_compile: the child imported {result['csgnb']}, not the copy in {package_root}")
    result["wall_s"] = wall
    result["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return result


def _print_stage(name: str, r: dict, verbose: bool) -> None:
    print(f"{name:>7}: {r['wall_s']:7.1f} s wall, {r['cpu_s']:7.1f} s CPU (import {r['import_s']:.1f} s)")
    for part, f in r["parts"].items():
        cpu = f" {f['cpu_s']:7.1f} s CPU" if "cpu_s" in f else ""
        print(f"         {part:>9} {f['wall_s']:7.1f} s wall{cpu}")
    if "tour_extra" in r:
        f = r["tour_extra"]
        print(f"         {'tour rest':>9} {f['wall_s']:7.1f} s wall {f['cpu_s']:7.1f} s CPU")
    if "kernels" in r:
        print(f"         {r['n_kernels']} kernels, {r['n_signatures']} signatures compiled; by exclusive time:")
        for k in r["kernels"]:
            print(f"         {k['exclusive_s']:7.1f} s excl {k['inclusive_s']:7.1f} s incl "
                  f"{k['signatures']:3d} sig  {k['kernel']}")
            if verbose:
                for a in k["argument_types"]:
                    print(f"                ({a})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stages", nargs="+", default=["serial", "tour", "edit", "warm"],
                        choices=["serial", "tour", "edit", "warm"])
    parser.add_argument("--kernels", type=int, default=25, help="list the N slowest kernels of the serial stage")
    parser.add_argument("--parts", nargs="+", default=list(PARTS), choices=PARTS,
                        help="the parts of the serial stage (default: all)")
    parser.add_argument("--signatures", action="store_true",
                        help="print the argument types of the listed kernels compiled more than once")
    parser.add_argument("--json", type=str, default=None)
    parser.add_argument("--child", type=str, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child, args.kernels, args.parts)))
        return 0
    if any(s in args.stages for s in ("edit", "warm")) and "tour" not in args.stages:
        parser.error("the edit and warm stages follow the tour stage (they reuse its cache)")
    print(f"csgnb compile times, cold numba cache; {os.cpu_count()} cores, {nominal_clock_label()}, "
          f"load {load_average()}")
    out: dict = {"cores": os.cpu_count(), "load_before": load_average(), "stages": {}}
    with tempfile.TemporaryDirectory(prefix="csgnb-bench-compile-") as tmp:
        root = pathlib.Path(tmp, "src")
        shutil.copytree(REPO / "csgnb", root / "csgnb", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        for stage in ("serial", "tour", "edit", "warm"):
            if stage not in args.stages:
                continue
            cache = pathlib.Path(tmp, "cache-serial" if stage == "serial" else "cache")
            if stage == "edit":
                with open(root / EDITED, "a") as fh:
                    fh.write("\n# bench_compile: an edit of one octree module\n")
            r = run_child(stage, root, cache, args.kernels if stage == "serial" else 0, args.parts)
            out["stages"][stage] = r
            _print_stage(stage, r, args.signatures)
    out["load_after"] = load_average()
    if "tour" in out["stages"]:
        print(f"targets: tour {out['stages']['tour']['wall_s']:.0f} s wall (<= 90 s)"
              + (f", edit {out['stages']['edit']['wall_s']:.0f} s wall (<= 60 s)" if "edit" in out["stages"] else ""))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
