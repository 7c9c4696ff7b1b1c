"""Rendering the sampling paper's Table 2 models: splats against the reference ray tracer, 1920×1080.

The five models and three splat sizes of ``bench_sampling.py`` (``csgnb.csg.gallery.TABLE2``; sampled with
the sampler's defaults: distortion bounds and reduced radii -- ``--full-radius`` gives every splat the radius
asked for; the comparison reports holes either way), seen by ``Camera.fit`` from azimuth -60°,
elevation 35° (about screen filling). In one process per model: the reference ray tracer (best of
``--rt-repeat``), then for each splat size the splat renderer (prepared once, not timed; best of
``--repeat`` frames) and the pixel comparison of the two. Kernels are compiled (or loaded from the cache) by an untimed
first call. Threads: numba's default (all cores) unless ``--threads``. Also the 640×480 viewer
frame (render and JPEG encoding, as the notebook viewer does) of the 80-quadric model, orbiting 2° per frame: with
its default level of detail (``csgnb.render.level_of_detail``: the coarsest cloud of the same surface whose splats are
about 12 px on screen, sampled once -- that one-off time is reported apart; where that is finer than the cloud, the
faster of the two as measured by ``LevelChooser``) and drawing the cloud itself, each frame
checked pixel for pixel against the ray tracer.

    python benchmarks/bench_render.py --json /tmp/bench_render.json

The splat renderer ray traces the tiles where its cost model (``csgnb.render.tile_costs``) expects splats to cost
more; "only splats" times every tile splatted. ``--calibrate`` fits that model's constants on one thread instead.

``--json PATH`` writes ``{"models": [{"name", "quadrics", "splat", "samples", "splat_ms",
"splat_cpu_ms", "raytrace_ms", "raytrace_cpu_ms", "speedup", "speedup_cpu", "splats_only_ms", "raytraced_tiles",
"tiles", "fragments", "overdraw", "covered", "disagree_fraction", "disagree", "holes", "off_edge", "stages_ms",
"lod_level", "lod_samples", "lod_ms", "lod_speedup", "lod_sampling_ms", "lod_holes", "lod_disagree",
"lod_overdraw"}], "viewer_640x480_ms": ..., "viewer_640x480": [{"splat", "samples", "ms", "render_ms", "level",
"drawn_samples", "drawn_radius", "level_sampling_ms", "cpu_ms", "ms_cloud_itself", "render_ms_cloud_itself",
"cpu_ms_cloud_itself"}], "threads": ...}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def _args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="splat frames per row, best is kept")
    parser.add_argument("--rt-repeat", type=int, default=1, help="ray-traced frames per model, best is kept")
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--threads", type=int, help="numba threads (default: all cores)")
    parser.add_argument("--full-radius", action="store_true",
                        help="every splat the radius asked for (the sampler's default reduces radii, §6.1, Figure 13e)")
    parser.add_argument("--only", nargs="*", help="model names to run (default: all)")
    parser.add_argument("--json", metavar="PATH", help="write the figures here")
    parser.add_argument("--calibrate", action="store_true",
                        help="fit the splat/ray-trace cost model (csgnb.render.tile_costs.COSTS) on one thread instead")
    return parser.parse_args(argv)


def calibrate(args) -> dict:
    """Fit ``tile_costs.COSTS`` on one thread: splat raster time against (rectangle pixels, binned splats), ray
    tracing time against (pixels, roots), least squares without negative coefficients, and the footprint and binning
    passes per splat, over every Table 2 model and splat size at two image sizes (so that the per-pixel and per-root
    costs separate). Splat fragments are counted as the planner estimates them: the rectangle pixels that occlusion
    culling leaves, judged from every tile's probe."""
    import numba
    import numpy as np
    from scipy.optimize import nnls

    from csgnb.csg.gallery import TABLE2
    from csgnb.render import Camera, SplatRenderer
    from csgnb.render.rays import quadric_rows, ray_polynomials
    from csgnb.render.raytracer import raytrace_tiles, tile_count
    from csgnb.render.tile_costs import plan_tiles
    from csgnb.sampling import sample_csg

    numba.set_num_threads(1)
    splat_rows, rt_rows, pass_rows = [], [], []
    for name, (build, radii) in TABLE2.items():
        if args.only and name not in args.only:
            continue
        shape = build()
        clouds = {s: sample_csg(shape, r) for s, r in radii.items()}
        nf = next(iter(clouds.values())).normal_form
        for W, H in ((args.width, args.height), (640, 480)):
            cam = Camera.fit(next(iter(clouds.values())), W, H, azimuth=-60.0, elevation=35.0)
            cp, (X, Y) = cam.params(), cam.screen_axes()
            P = ray_polynomials(cp, quadric_rows(nf.quadrics))
            ts = np.ascontiguousarray(nf.term_start, dtype=np.int64)
            ntx, nty = tile_count((H, W), 16)
            tiles = np.arange(ntx * nty, dtype=np.int64)
            work = np.empty(len(tiles), dtype=np.int64)
            bufs = (np.empty((H, W)), np.empty((H, W), dtype=np.int32), np.empty((H, W), dtype=np.int32))
            grid = np.array([16, 1, 1], dtype=np.int64)
            max_term = max(int(np.max(np.diff(ts))), 1)
            best = float("inf")
            for _ in range(1 + max(1, args.rt_repeat)):
                t0 = time.perf_counter()
                raytrace_tiles(cp, X, Y, P, ts, max_term, grid, tiles, *bufs, work)
                best = min(best, time.perf_counter() - t0)
            rt_rows.append((W * H, int(work.sum()), best * 1e9))
            for splat, cloud in clouds.items():
                r = SplatRenderer(cloud)
                r.render(cam, fallback="never")
                frames = [r.render(cam, fallback="never") for _ in range(max(1, args.repeat))]
                raster = min(f.stats.timings["raster"] for f in frames)
                passes = min(f.stats.timings["footprints"] + f.stats.timings["binning"] for f in frames)
                # every tile's estimate as the planner makes it: the fragments occlusion culling leaves
                start, tile, ntx_ = r.last_bins
                plan = plan_tiles("auto", (cp, X, Y, ray_polynomials(cp, r.Q), r.term_start, r.max_term),
                                  r.last_plan.fragments, start, tile, (H, W), nf.n_terms,
                                  visible=r._visible(start, tile, ntx_), probe_all=True)
                splat_rows.append((int(plan.fragments.sum()), int(plan.items.sum()), raster * 1e6))
                pass_rows.append((len(cloud), passes * 1e6))
                print(f"{name:18s} {splat:6s} {W}x{H}: raster {raster:7.1f} ms, {splat_rows[-1][0]:11d} unculled px, "
                      f"{splat_rows[-1][1]:8d} binned splats; ray tracing {best * 1e3:7.1f} ms, "
                      f"{rt_rows[-1][1]:11d} roots", flush=True)
    s = np.array(splat_rows, dtype=float)
    (fragment, item), _ = nnls(s[:, :2], s[:, 2])
    r = np.array(rt_rows, dtype=float)
    (ray, root), _ = nnls(r[:, :2], r[:, 2])
    p = np.array(pass_rows, dtype=float)
    splat = float(p[:, 0] @ p[:, 1] / (p[:, 0] @ p[:, 0]))  # footprint + binning ns per splat
    fit = {"fragment": fragment, "item": item, "ray": ray, "root": root, "splat": splat}
    print("COSTS = TileCosts(" + ", ".join(f"{k}={v:.3g}" for k, v in fit.items()) + ")  # ns, one thread")
    for name, rows_, cols in (("splats", s, (fragment, item)), ("ray tracing", r, (ray, root))):
        pred = rows_[:, :2] @ np.array(cols)
        print(f"  {name}: predicted / measured per frame {np.min(pred / rows_[:, 2]):.2f} … "
              f"{np.max(pred / rows_[:, 2]):.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"costs_ns": fit, "splat_rows": splat_rows, "raytrace_rows": rt_rows, "pass_rows": pass_rows}, fh,
                  indent=2)
        print(f"wrote {args.json}")
    return fit


#: Table 2's render columns (ms, RTX 2080 Ti): (quadrics, splat) → (ours, ray tracing).
PAPER_RENDER = {
    (3, "large"): (0.34, 0.36), (3, "medium"): (0.23, 0.36), (3, "small"): (0.27, 0.36),
    (5, "large"): (0.27, 1.14), (5, "medium"): (0.18, 1.14), (5, "small"): (0.26, 1.14),
    (21, "large"): (0.45, 0.72), (21, "medium"): (0.39, 0.72), (21, "small"): (0.33, 0.72),
    (31, "large"): (0.96, 4.43), (31, "medium"): (0.87, 4.43), (31, "small"): (0.69, 4.43),
    (80, "large"): (0.32, 9.15), (80, "medium"): (0.34, 9.15), (80, "small"): (0.47, 9.15),
}  # fmt: skip


def main(argv=None) -> None:
    args = _args(argv)
    if args.calibrate:
        calibrate(args)
        return
    import numba

    if args.threads:
        numba.set_num_threads(args.threads)
    threads = numba.get_num_threads()
    import csgnb.csg as csg
    from csgnb.csg.gallery import TABLE2
    from csgnb.render import Camera, LevelChooser, LevelsOfDetail, SplatRenderer, Viewer, compare, raytrace
    from csgnb.sampling import sample_csg

    W, H = args.width, args.height
    rows, viewer = [], []
    print(f"Table 2, render columns: {W}x{H}, {threads} thread(s); splats vs the reference ray tracer "
          "(figures under load are provisional)")
    print("splats ms: the default (tiles where splats would cost more are ray traced, 'rt tiles' of 'tiles'), its CPU "
          "time (every thread) beside, and the ray tracer's; "
          "only splats: every tile splatted; lod: the level of detail a viewer of the cloud draws for this view "
          "(csgnb.render.level_of_detail), its frame time, ratio to the ray tracer, and holes + disagreeing pixels")
    print(f"{'model':18s} {'q':>3s} {'splat':6s} {'samples':>8s} {'splats ms':>9s} {'cpu ms':>7s} {'only spl':>8s} "
          f"{'rt tiles':>8s} {'rt ms':>8s} {'rt cpu':>7s} {'ratio':>6s} {'cpu x':>6s} "
          f"{'fragments':>10s} {'overdraw':>8s} {'disagree':>8s} {'holes':>5s} {'paper ms':>9s} "
          f"{'paper rt':>8s} {'lod':>4s} {'lod ms':>7s} {'ratio':>6s} {'lod od':>6s} {'wrong':>5s}")
    for name, (build, radii) in TABLE2.items():
        if args.only and name not in args.only:
            continue
        shape = build()
        n_quadrics = len(csg.graph_leaves(shape))
        clouds = {s: sample_csg(shape, r, reduce_radius=not args.full_radius) for s, r in radii.items()}
        cam = Camera.fit(next(iter(clouds.values())), W, H, azimuth=-60.0, elevation=35.0)
        nf = next(iter(clouds.values())).normal_form
        raytrace(nf, cam.with_size(32, 18))  # compile / load outside the timing
        rt_ms, rt_cpu, ref = float("inf"), float("nan"), None
        for _ in range(max(1, args.rt_repeat)):
            c0 = time.process_time()
            ref = raytrace(nf, cam)
            if ref.stats.ms < rt_ms:  # CPU of every thread of this process, beside the wall time
                rt_ms, rt_cpu = ref.stats.ms, 1e3 * (time.process_time() - c0)
        for splat, cloud in clouds.items():
            renderer = SplatRenderer(cloud)
            renderer.render(cam.with_size(32, 18))
            best, best_cpu, stages, frame = float("inf"), float("nan"), {}, None
            only_splats = float("inf")
            for _ in range(max(1, args.repeat)):
                c0 = time.process_time()
                frame = renderer.render(cam)
                if frame.stats.ms < best:
                    best, best_cpu, stages = frame.stats.ms, 1e3 * (time.process_time() - c0), dict(frame.stats.timings)
                only_splats = min(only_splats, renderer.render(cam, fallback="never").stats.ms)
            a = compare(frame, ref)
            # the level of detail a viewer of this cloud draws for this view: the size rule's level, measured
            # against the cloud itself where that level is finer (LevelChooser; levels sampled once, not timed)
            lod = LevelsOfDetail(cloud, finer=True)
            chooser = LevelChooser(lod)
            renderers = {}
            for _ in range(2 * chooser.trials + max(1, args.repeat)):
                level = chooser.choose(cam)
                if level not in renderers:
                    renderers[level] = SplatRenderer(lod.cloud_at(level))
                    renderers[level].render(cam.with_size(32, 18))
                chooser.record(level, renderers[level].render(cam).stats.ms)
            level = chooser.choose(cam)
            lod_frame = min((renderers[level].render(cam) for _ in range(max(1, args.repeat))),
                            key=lambda f: f.stats.ms)
            lod_a = compare(lod_frame, ref)
            paper = PAPER_RENDER.get((n_quadrics, splat), (float("nan"), float("nan")))
            row = {
                "name": name, "quadrics": n_quadrics, "splat": splat, "samples": len(cloud), "splat_ms": best,
                "splat_cpu_ms": best_cpu, "raytrace_ms": rt_ms, "raytrace_cpu_ms": rt_cpu, "speedup": rt_ms / best,
                "speedup_cpu": rt_cpu / best_cpu, "splats_only_ms": only_splats,
                "raytraced_tiles": frame.stats.raytraced_tiles, "tiles": frame.stats.tiles,
                "fragments": frame.stats.fragments,
                "overdraw": frame.stats.overdraw, "covered": a.covered, "disagree_fraction": a.disagree_fraction,
                "disagree": a.disagree, "holes": a.holes, "off_edge": a.off_edge,
                "stages_ms": {k: round(v, 2) for k, v in stages.items()},
                "lod_level": level, "lod_samples": len(lod.cloud_at(level)), "lod_ms": lod_frame.stats.ms,
                "lod_speedup": rt_ms / lod_frame.stats.ms, "lod_sampling_ms": 1e3 * lod.seconds[level],
                "lod_holes": lod_a.holes, "lod_disagree": lod_a.disagree, "lod_overdraw": lod_frame.stats.overdraw,
            }
            rows.append(row)
            print(f"{name:18s} {n_quadrics:3d} {splat:6s} {len(cloud):8d} {best:9.1f} {best_cpu:7.1f} "
                  f"{only_splats:8.1f} {frame.stats.raytraced_tiles:4d}/{frame.stats.tiles:<3d} {rt_ms:8.0f} "
                  f"{rt_cpu:7.0f} {rt_ms / best:6.1f} {rt_cpu / best_cpu:6.1f} "
                  f"{frame.stats.fragments:10d} {frame.stats.overdraw:8.2f} {a.disagree:8d} {a.holes:5d} "
                  f"{paper[0]:9.2f} {paper[1]:8.2f} {level:4d} {lod_frame.stats.ms:7.1f} "
                  f"{rt_ms / lod_frame.stats.ms:6.1f} {lod_frame.stats.overdraw:6.1f} "
                  f"{lod_a.holes + lod_a.disagree:5d}")
            if n_quadrics == max(q for q, _ in PAPER_RENDER):
                entry = {"splat": splat, "samples": len(cloud)}
                for lod in (True, False):  # the viewer's default (a level of detail per view), and the cloud itself
                    v = Viewer(cloud, cam.with_size(640, 480), size=(640, 480), lod=lod)
                    times, renders, cpus = [], [], []
                    for _ in range(max(3, args.repeat)):
                        t0, c0 = time.perf_counter(), time.process_time()
                        v.update()
                        times.append(1e3 * (time.perf_counter() - t0))
                        cpus.append(1e3 * (time.process_time() - c0))  # every thread of this process
                        renders.append(v.frame.stats.ms)
                        v.camera = v.camera.orbited(2.0)
                    a = compare(v.frame, raytrace(shape, v.frame.camera))
                    if a.holes or a.disagree:
                        raise AssertionError(f"viewer, {splat}, lod={lod}: {a.holes} holes, {a.disagree} disagree")
                    key = "" if lod else "_cloud_itself"
                    entry["ms" + key] = min(times)
                    entry["render_ms" + key] = renders[times.index(min(times))]  # of the fastest frame
                    entry["cpu_ms" + key] = cpus[times.index(min(times))]
                    if lod:
                        level = v.level  # the level the viewer's chooser drew last
                        entry.update(level=level, drawn_samples=len(v.drawn), drawn_radius=v.drawn.radius,
                                     level_sampling_ms=1e3 * v.levels.seconds[level])
                viewer.append(entry)
        sys.stdout.flush()
    for row in rows:
        if row["quadrics"] == 80:
            print(f"  stages, {row['name']} {row['splat']}: " +
                  ", ".join(f"{k} {v:.1f}" for k, v in row["stages_ms"].items()))
    viewer_ms = max((v["ms"] for v in viewer), default=float("nan"))
    for v in viewer:
        print(f"viewer 640x480, 80 quadrics, {v['splat']:6s}: {v['ms']:.1f} ms per frame ({v['cpu_ms']:.1f} ms CPU) "
              f"(render {v['render_ms']:.1f} ms, the rest JPEG encoding; level of detail {v['level']}: "
              f"{v['drawn_samples']:,} of {v['samples']:,} samples, radius {v['drawn_radius']:.3g}, "
              f"sampled once in {v['level_sampling_ms']:.0f} ms); "
              f"the cloud itself {v['ms_cloud_itself']:.1f} ms ({v['cpu_ms_cloud_itself']:.1f} ms CPU); both "
              "pixel-perfect against the ray tracer")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"models": rows, "viewer_640x480_ms": viewer_ms, "viewer_640x480": viewer, "threads": threads,
                       "size": [W, H], "reduce_radius": not args.full_radius}, fh, indent=2)
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
