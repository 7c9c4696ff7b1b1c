"""Compiling csgnb's numba kernels ahead of use, with a progress bar: the set-up runs it, notebooks call it first.

numba compiles a kernel the first time it is called with new argument types; csgnb caches the machine code on
disk (``NUMBA_CACHE_DIR``, see :mod:`csgnb._jit`), keyed on the sources of the kernel's module and of every csgnb
module it imports. So the first run after an install compiles for minutes, an edit recompiles the kernels that
depend on the edited module, and every later run loads the kernels from the cache in seconds. :func:`warm_up`
runs one small, typical workload per part of the package so that this
happens up front, visibly, instead of as a silent ``[*]`` in the middle of a notebook.

By default it compiles what the default settings use (the tour, the milling and sampling defaults); with
``variants=True`` also the alternatives a user picks by an argument: the naive mesh cut and BSP extraction the
chapters compare against, the 192-bit predicates, the BSP merge without redundancy removal, random and tangent-plane
BSPs, the sampler's traced and √3-distortion runs, every renderer option. Those otherwise compile on first use.

``python -m csgnb.warmup`` warms every part with the defaults (``scripts/demo.sh`` and ``scripts/lab.sh`` call it);
``python -m csgnb.warmup --variants`` adds the variants (``scripts/test.sh``: the tests use them all).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

__all__ = ["PARTS", "warm_up"]


def _exact(variants: bool) -> None:
    from csgnb import exact

    for width in exact.WIDTHS if variants else (exact.DEFAULT_WIDTH, 256):  # the tour's exact cells use 256
        planes = exact.plane_from_points([[0, 0, 0]], [[7, 0, 0]], [[0, 5, 0]], width=width)
        cut = exact.to_wide([[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 3, -1]], width)
        x = exact.intersect_3_planes(cut[0], cut[1], cut[2])
        exact.classify_vertex(x, planes[0])
        exact.classify_vertex(exact.homogeneous_points([[1, 2, 3]], width), planes)
        exact.to_double_position(x)
        exact.points_equal(x, x)
        exact.signed_distance([[1, 2, 3]], planes)
        exact.are_planes_parallel(planes, planes)
    exact.quantize(np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]), width=256)


def _mesh(variants: bool) -> None:
    from csgnb import exact
    from csgnb.mesh import MeshStore, cut

    for naive in (False, True) if variants else (False,):
        store = MeshStore(exact.to_wide([[2, 3, 5, -19]], 128))
        box = store.add_box([0, 0, 0], [4, 4, 4])
        parts = cut(store, box, 0, naive=naive)
        store.exact_volume(parts.negative)
        store.check_cell(parts.positive)
        store.positions(store.cell_vertices(parts.negative))


def _tools(variants: bool) -> None:
    from csgnb.apps import tools
    from csgnb.exact import Grid

    # a milling move's hull (the tour's tool): many points, so the float hull (scipy) proposes its faces and the
    # exact kernels check them
    tool = tools.flat_end_mill(6, 12, segments=12).on(Grid.fit([-12.0, -12.0, -22.0], [75.0, 65.0, 25.0]))
    tool.hull_at((0.0, 0.0, 5.0), (10.0, 3.0, 5.0))


def _bsp(variants: bool) -> None:
    from csgnb.bsp import BSP, DIFFERENCE, extract_cells, random_bsp, tangent_plane_bsp

    a, b = BSP.box([0, 0, 0], [4, 4, 4]), BSP.box([2, 2, 2], [6, 6, 6])
    results = [a | b, a & b, a - b] + ([a ^ b, a.merge(b, DIFFERENCE, simplify=False)] if variants else [])
    for result in results:
        result.volume()  # (the boundary's kernels: the "boundary" part)
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    octahedron = BSP.from_mesh(axes * [3, 2, 4] + 4, faces)
    (a - octahedron).classify([[1, 1, 1]])
    if variants:
        tree = random_bsp(8, seed=0, extent=16, max_normal=5)
        BSP(tree, [-16] * 3, [16] * 3).volume()
        for naive in (False, True):
            extract_cells(tangent_plane_bsp(16), [-8192] * 3, [8192] * 3, naive=naive)


def _extraction(variants: bool) -> None:
    from csgnb.bsp import BSP

    # a BSP's cells (clipped from its box) and their volume, no Boolean: what the bsp and octree parts call
    box = BSP.box([0, 0, 0], [4, 4, 4])
    box.volume()
    box.classify([[1, 1, 1]])


def _boundary(variants: bool) -> None:
    from csgnb.bsp import BSP
    from csgnb.octree import Workpiece

    # the boundary surface of a BSP and of a workpiece (assembly, vertex merging), no Boolean: so that this part
    # compiles in the second track without compiling the Booleans' kernels a second time
    BSP.box([0, 0, 0], [4, 4, 4]).surface().is_closed()
    Workpiece.box([-16, -16, -16], [16, 16, 16], threshold=16).surface()


def _octree(variants: bool) -> None:
    from csgnb.mesh.hull import convex_hull
    from csgnb.octree import Tool, Workpiece

    w = Workpiece.box([-16, -16, -16], [16, 16, 16], threshold=16)
    octahedron = convex_hull(np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]) * 9)
    w.difference(octahedron, track_volume=True)
    w.run([convex_hull(np.array([[0, 0, 0], [5, 0, 0], [0, 5, 0], [0, 0, 5]]))], "union")  # the batch kernel
    w &= Tool.from_hull(octahedron).translated([3, 0, 0])
    w.volume()  # (its boundary's kernels: the "boundary" part)
    w.classify([[0, 0, 0]])


def _quadric(variants: bool) -> None:
    import csgnb.quadric as cq

    q = cq.hyperboloid_one_sheet((1.0, 0.8, 1.2))
    planes = cq.sampling_planes(q)
    cq.signed_distance(q, [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    q.value(np.zeros((2, 3)))
    q.normal(np.ones((2, 3)))
    q.intersect_lines(np.zeros((2, 3)), np.ones((2, 3)))
    cq.distortion(planes[1].alpha, np.array([0.1]), np.array([0.2]))
    cq.distortion_bounds(planes[1].alpha, [[0.1, 0.1, 0.2, 0.2]])
    for region in cq.low_distortion_regions(q, (-2, -2, -2), (2, 2, 2))[:4]:
        cq.region_mesh(planes[region.plane], region, 4, 1.0)


def _sampling(variants: bool) -> None:
    import csgnb.csg as csg
    from csgnb.sampling import sample_csg

    solid = (csg.sphere((0, 0, 0), 1.0, "A") & csg.sphere((0.8, 0, 0), 1.0, "B")) | csg.box(
        (0.2, 0.2, -0.3), (1.2, 1.0, 0.3), "C")
    sample_csg(solid, 0.2)
    if variants:
        sample_csg(solid, 0.2, trace=True)
        sample_csg(solid, 0.2, distortion="sqrt3", refine=False)


def _render(variants: bool) -> None:
    import csgnb.csg as csg
    from csgnb.render import Camera, SplatRenderer, compare, raytrace, render
    from csgnb.sampling import sample_csg

    solid = csg.sphere((0, 0, 0), 1.0, "A") - csg.box((0.2, -2, -2), (2, 2, 2), "B")
    cloud = sample_csg(solid, 0.3)
    for projection in ("perspective", "orthographic") if variants else ("perspective",):
        cam = Camera.fit(cloud, 48, 32, projection=projection)
        reference = raytrace(solid, cam)
        for footprint in ("box", "sphere") if variants else ("box",):
            compare(render(cloud, cam, footprint=footprint, fallback="never"), reference)
        render(cloud, cam)
        if variants:
            render(cloud, cam, local="disc", clip=False, color_by="overdraw")
            render(cloud, cam, fallback="always")
            # the per-tile plan probes tiles whose splats would cost more: large splats on a small screen
            SplatRenderer(sample_csg(solid, 1.0)).render(cam.with_size(256, 192), color_by="normal")


#: The parts :func:`warm_up` knows, in the order of the two pipelines.
PARTS = {"exact": _exact, "mesh": _mesh, "extraction": _extraction, "bsp": _bsp, "octree": _octree,
         "boundary": _boundary, "tools": _tools, "quadric": _quadric, "sampling": _sampling, "render": _render}


#: The parts compiled in this process and in a second one, each track in its order, balanced on the measured compile
#: times (``bench_compile.py --stages tour``): the exact pipeline's Booleans in the first, the quadric pipeline and
#: the BSP boundary in the second. Both processes share the cache, so a kernel one of them has compiled is loaded by
#: the other instead of compiled again; the order makes that so: the boundary (which the tour's octree calls) follows
#: the sampling, by when the first track has compiled the BSP cells' extraction that the boundary calls.
TRACKS = (("mesh", "extraction", "bsp", "octree", "tools"), ("exact", "quadric", "sampling", "boundary", "render"))

#: A part of the second track that starts only once a part of the first is done, so that it loads that part's kernels
#: from the cache instead of compiling them a second time at the same moment (a safety: in the order above the first
#: track is done with it long before).
WAITS_FOR = {"boundary": "extraction"}

#: Seconds the second track waits for a part of the first at most (then it compiles on its own).
_WAIT_LIMIT = 600.0

#: In the second process: part name -> the event the first process sets when that part is done.
_DONE: dict = {}


def _set_done_events(events: dict) -> None:
    global _DONE
    _DONE = events


def _warm_parts(names: list[str], variants: bool = False) -> dict[str, float]:
    """Warm ``names`` in order, without output (run in a helper process by :func:`warm_up`)."""
    seconds = {}
    for name in names:
        done = _DONE.get(WAITS_FOR.get(name))
        if done is not None:
            done.wait(_WAIT_LIMIT)
        t0 = time.perf_counter()
        PARTS[name](variants)
        seconds[name] = time.perf_counter() - t0
    return seconds


def warm_up(*parts: str, progress: bool = True, parallel: bool | None = None,
            variants: bool = False) -> dict[str, float]:
    """Compile (or load from the cache) the kernels of ``parts`` (default: all of :data:`PARTS`).

    Prints what it does and shows a ``tqdm`` progress bar (a widget in a notebook) unless ``progress=False``.
    With ``parallel`` (default: when the machine has more than one core and both tracks are asked for) the
    second track of :data:`TRACKS` (the exact predicates, the BSP cells' boundary, the quadric pipeline) compiles
    in a second process while this one compiles the first (mesh, bsp, octree, the milling tool). ``variants``:
    also the kernels of the non-default settings (see the module's docstring); otherwise they compile on first use.
    Returns the seconds spent per part.
    """
    names = list(parts) or list(PARTS)
    unknown = [p for p in names if p not in PARTS]
    if unknown:
        raise ValueError(f"unknown part(s) {unknown}: warm_up knows {list(PARTS)}")
    here = sorted((n for n in names if n in TRACKS[0]), key=TRACKS[0].index)
    there = sorted((n for n in names if n not in TRACKS[0]), key=TRACKS[1].index)  # in the track's order
    if parallel is None:
        parallel = (os.cpu_count() or 1) > 1
    if not (parallel and here and there):
        here, there = names, []
    if progress:
        from tqdm.auto import tqdm

        print("Preparing csgnb's numba kernels for " + ", ".join(names) + ": compiled on the first run after an "
              "install or an edit of the modules they depend on (minutes), loaded from the cache (NUMBA_CACHE_DIR) "
              "afterwards." + (f" {', '.join(there)} compile in a second process." if there else ""), flush=True)
        bar = tqdm(total=len(names), desc="numba kernels", unit="part", leave=False)
    seconds: dict[str, float] = {}
    pool = future = None
    done_events: dict = {}
    if there:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        context = multiprocessing.get_context("spawn")
        done_events = {p: context.Event() for p in set(WAITS_FOR.values()) if p in here}
        pool = ProcessPoolExecutor(1, mp_context=context, initializer=_set_done_events, initargs=(done_events,))
        future = pool.submit(_warm_parts, there, variants)
    try:
        for name in here:
            if progress:
                bar.set_postfix_str(name)
            seconds.update(_warm_parts([name], variants))
            if name in done_events:
                done_events[name].set()
            if progress:
                bar.update(1)
        if future is not None:
            if progress:
                bar.set_postfix_str(", ".join(there))
            seconds.update(future.result())
            if progress:
                bar.update(len(there))
    finally:
        for event in done_events.values():  # never leave the second process waiting (an error above)
            event.set()
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    if progress:
        bar.close()
        print(f"Kernels ready ({sum(seconds.values()):.0f} s of compilation"
              + (", two processes)." if there else ")."), flush=True)
    return {n: seconds[n] for n in names}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m csgnb.warmup", description=__doc__.splitlines()[0])
    parser.add_argument("parts", nargs="*", help=f"parts to warm, of {', '.join(PARTS)} (default: all)")
    parser.add_argument("--variants", action="store_true",
                        help="also the kernels of non-default settings (naive cuts, other widths, renderer options)")
    args = parser.parse_args(argv)
    try:
        seconds = warm_up(*args.parts, variants=args.variants)
    except ValueError as err:
        parser.error(str(err))
    print("  " + ", ".join(f"{k} {v:.1f} s" for k, v in seconds.items()), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
