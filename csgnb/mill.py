"""Command line: simulate a G-code program on a stock box, exactly, and write the part as STL.

    python -m csgnb.mill PROGRAM.nc --stock X Y Z --tool flat:6 --out part.stl

The stock is the box ``[0, X] x [0, Y] x [-Z, 0]`` (the usual CAM set-up: origin at the
lower left corner of the top face; ``--stock-origin`` moves its lower corner). Tools are
short specs (:func:`csgnb.apps.tools.parse_tool`): ``flat:D``, ``ball:D``, ``bull:D:R``,
``vbit:D:ANGLE``, ``drill:D`` (diameters in mm, optionally ``:FLUTE_LENGTH`` last); give
``--tool N=SPEC`` for tool number N of ``T N M6``, and one spec without a number for every
other move. The grid is fitted to the stock, the tool path and the tools (the finest one in
the 128-bit budget) unless ``--resolution`` is given. Progress goes to stderr; a summary
table to stdout.

The workpiece is :class:`csgnb.octree.Workpiece` (``--reference`` runs the slow
single-BSP :class:`csgnb.apps.reference.BSPWorkpiece` instead, for comparison).
A PROGRAM that is not a file but the name of a shipped example (``pocket.nc``,
``relief.nc``: :mod:`csgnb.apps.examples`) runs that example.

    python -m csgnb.mill --batch JOBS.toml [--scheduler ADDRESS] [--out-dir DIR]

runs every job of a batch file on Dask (:func:`csgnb.distributed.batch.load_jobs` describes the
file; :func:`batch_main`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from csgnb.apps import gcode, milling, tools
from csgnb.apps.examples import EXAMPLES, example_path
from csgnb.errors import CsgnbError
from csgnb.exact import Grid


def workpiece_type(reference: bool = False):
    """The workpiece class: ``csgnb.octree.Workpiece``, or with ``reference`` the single-BSP ``BSPWorkpiece``."""
    if reference:
        from csgnb.apps.reference import BSPWorkpiece

        return BSPWorkpiece
    from csgnb.octree import Workpiece

    return Workpiece


def _tool_specs(specs: list[str], segments: int) -> dict:
    out: dict = {}
    for spec in specs:
        number, sep, rest = spec.partition("=")
        key = None
        if sep:
            if not number.strip().isdigit():
                raise ValueError(f"--tool {spec!r}: write N=SPEC with a tool number N, e.g. 2=ball:3")
            key, spec = int(number), rest
        if key in out:
            raise ValueError(f"--tool given twice for {'the default tool' if key is None else f'tool {key}'}")
        out[key] = tools.parse_tool(spec, segments=segments)
    return out


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m csgnb.mill``."""
    p = argparse.ArgumentParser(prog="python -m csgnb.mill", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("program", type=Path, help="G-code file (.nc, .ngc, .gcode), or pocket.nc / relief.nc (shipped)")
    p.add_argument("--stock", type=float, nargs=3, metavar=("X", "Y", "Z"), required=True,
                   help="stock size in mm: the box [0,X] x [0,Y] x [-Z,0]")
    p.add_argument("--stock-origin", type=float, nargs=3, metavar=("X0", "Y0", "Z0"), default=None,
                   help="lower corner of the stock (default 0 0 -Z)")
    p.add_argument("--tool", action="append", default=[], metavar="[N=]SPEC",
                   help="tool spec, e.g. flat:6, ball:4, bull:6:1, vbit:6:90, drill:5 (repeat for T numbers)")
    p.add_argument("--out", type=Path, default=None, help="write the part as STL here")
    p.add_argument("--resolution", type=float, default=None, help="grid step in mm (default: fitted)")
    p.add_argument("--segments", type=int, default=32, help="vertices around each tool (default 32)")
    p.add_argument("--chord-tolerance", type=float, default=milling.CHORD_TOLERANCE,
                   help=f"arc chord tolerance in mm (default {milling.CHORD_TOLERANCE})")
    p.add_argument("--rapid-rate", type=float, default=milling.RAPID_RATE, help="mm/min for G0 times")
    p.add_argument("--start", type=float, nargs=3, metavar=("X", "Y", "Z"), default=None,
                   help="tool tip position before the program (default: 10 mm above the stock's corner)")
    p.add_argument("--skip-unsupported", action="store_true", help="skip unsupported words with a warning")
    p.add_argument("--checkpoint", type=Path, default=None, help="save/resume here every --checkpoint-every moves")
    p.add_argument("--checkpoint-every", type=int, default=50)
    p.add_argument("--json", type=Path, default=None, help="write per-move records as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--reference", action="store_true",
                   help="simulate on the single-BSP reference workpiece (exact, slow) instead of the octree")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the simulation; return the exit status (0 ok, 1 collisions, 2 bad input)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if any(a == "--batch" or a.startswith("--batch=") for a in argv):
        return batch_main(argv)
    args = build_parser().parse_args(argv)
    try:
        return _run(args)
    except (CsgnbError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _run(args) -> int:
    size = np.asarray(args.stock, float)
    if np.any(size <= 0):
        raise ValueError(f"--stock sizes must be positive, got {size.tolist()}")
    lo = np.array([0.0, 0.0, -size[2]]) if args.stock_origin is None else np.asarray(args.stock_origin, float)
    hi = lo + size
    shapes = _tool_specs(args.tool or ["flat:6"], args.segments)
    start = np.array([lo[0], lo[1], hi[2] + 10.0]) if args.start is None else np.asarray(args.start, float)
    path = args.program
    if not path.exists() and path.name == str(path) and path.name in EXAMPLES:
        path = example_path(path.name)
    program = gcode.parse_file(path, start=start,
                               on_unsupported="warn" if args.skip_unsupported else "error")
    if not program.moves:
        raise ValueError(f"{args.program} has no moves")
    reach = max(max(s.radius, s.length) for s in shapes.values()) + 1.0
    p_lo, p_hi = program.bounds()
    box_lo = np.minimum(lo, p_lo - reach)
    box_hi = np.maximum(hi, p_hi + reach)
    if args.resolution is None:
        grid = Grid.fit(box_lo, box_hi)
    else:
        grid = Grid.from_resolution(args.resolution, origin=(box_lo + box_hi) / 2)
    placed = {k: s.on(grid) for k, s in shapes.items()}
    Workpiece = workpiece_type(args.reference)
    w = Workpiece.box(lo, hi, grid=grid)
    print(f"{args.program}: {len(program.moves)} moves; stock {size.tolist()} mm at {lo.tolist()}; grid "
          f"{grid.resolution:g} mm ({grid.width}-bit); workpiece {Workpiece.__name__}", file=sys.stderr)
    for k, t in placed.items():
        print(f"  tool {'*' if k is None else k}: {t}", file=sys.stderr)
    t0 = time.perf_counter()
    result = milling.simulate(w, program, placed if len(placed) > 1 else next(iter(placed.values())),
                              chord_tolerance=args.chord_tolerance, rapid_rate=args.rapid_rate,
                              progress=not args.no_progress, checkpoint=args.checkpoint,
                              checkpoint_every=args.checkpoint_every)
    wall = time.perf_counter() - t0
    print(result.table())
    print(f"simulated in {wall:.1f} s")
    if args.out is not None:
        milling.export_stl(result.workpiece, args.out)
        print(f"wrote {args.out}")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "program": str(args.program), "moves": len(result.records), "wall_s": wall,
            "stock_mm3": float(result.stock_volume), "removed_mm3": float(result.removed),
            "records": [dict(index=r.index, line=r.line, kind=r.kind, removed_mm3=float(r.removed),
                             removed_exact=f"{r.removed.numerator}/{r.removed.denominator}", time_s=r.time_s,
                             wall_s=r.wall_s, boolean_s=r.boolean_s, cells=r.cells, collision=r.collision)
                        for r in result.records]}, indent=1))
    return 1 if result.collisions else 0


# -- batches on Dask ---------------------------------------------------------------


def batch_main(argv: list[str]) -> int:
    """``--batch JOBS.toml``: run the file's jobs on Dask; return 0 (all done), 1 (collisions), 2 (failures)."""
    p = argparse.ArgumentParser(prog="python -m csgnb.mill --batch", description="Run a batch file's milling jobs "
                                "on Dask: a LocalCluster of one worker per core, or --scheduler.")
    p.add_argument("--batch", type=Path, required=True, metavar="JOBS.toml", help="the batch file (TOML)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--workers", type=int, default=None, help="local workers (default: one per core)")
    p.add_argument("--out-dir", type=Path, default=None, help="output folder (default: the file's out_dir)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    from csgnb.distributed.batch import load_jobs, run_batch

    try:
        jobs, out_dir = load_jobs(args.batch)
        results = run_batch(jobs, out_dir=args.out_dir or out_dir, scheduler=args.scheduler,
                            n_workers=args.workers, progress=not args.no_progress)
    except (CsgnbError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for r in results:
        print(r.summary())
    print(f"{sum(r.ok for r in results)} of {len(results)} jobs done ({sum(r.skipped for r in results)} kept from "
          f"an earlier run); outputs in {args.out_dir or out_dir}")
    if not all(r.ok for r in results):
        return 2
    return 1 if any(r.collisions for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
