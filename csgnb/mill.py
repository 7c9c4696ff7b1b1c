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

Tools: ``--tool N=SPEC`` (repeatable) and/or ``--tool-table tool.tbl`` (LinuxCNC format, or
``.csv``: :mod:`csgnb.apps.tooltable`; its lengths drive ``G43``). An unnumbered ``--tool SPEC``
is the tool in the spindle before the first ``M6``, and the tool of the program's one tool
number when it loads only one; a program that loads a tool number not given is an error
naming the line, never milled with another tool.

``--dialect grbl`` takes the spindle as running throughout (a router switched by hand: no
``M3`` needed). Words that cannot change the cut may be skipped with ``--skip-unsupported``;
they are listed (count, first line) in the summary and the ``--json`` output. Exit status: 0
ok, 1 collisions (the first lines are named), 2 bad input.

    python -m csgnb.mill --batch JOBS.toml [--scheduler ADDRESS] [--out-dir DIR]

runs every job of a batch file on Dask (:func:`csgnb.distributed.batch.load_jobs` describes the
file; :func:`batch_main`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgnb.apps import gcode, milling, tools
from csgnb.apps.examples import EXAMPLES, example_path
from csgnb.apps.tooltable import read_tool_table
from csgnb.errors import CsgnbError
from csgnb.exact import Grid
from csgnb.exact.rational import fraction_text


def workpiece_type(reference: bool = False):
    """The workpiece class: ``csgnb.octree.Workpiece``, or with ``reference`` the single-BSP ``BSPWorkpiece``."""
    if reference:
        from csgnb.apps.reference import BSPWorkpiece

        return BSPWorkpiece
    from csgnb.octree import Workpiece

    return Workpiece


MIN_CHORD_TOLERANCE = 1e-6
"""The finest ``--chord-tolerance`` accepted (mm): a nanometre, far below any machine, far above double rounding."""


def _tool_specs(specs: list[str], segments: int) -> dict:
    """``--tool`` values as {number or None: ToolShape}."""
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
    p.add_argument("--width", type=int, choices=(128, 192, 256), default=128,
                   help="bit width of the exact predicates (default 128): wider widths allow finer grids over the "
                        "same extent (the summary states the grid step)")
    p.add_argument("--segments", type=int, default=32, help="vertices around each tool (default 32)")
    p.add_argument("--chord-tolerance", type=float, default=milling.CHORD_TOLERANCE,
                   help=f"arc chord tolerance in mm (default {milling.CHORD_TOLERANCE})")
    p.add_argument("--rapid-rate", type=float, default=milling.RAPID_RATE, help="mm/min for G0 times")
    p.add_argument("--start", type=float, nargs=3, metavar=("X", "Y", "Z"), default=None,
                   help="tool tip position before the program (default: 10 mm above the stock's corner)")
    p.add_argument("--home", type=float, nargs=3, metavar=("X", "Y", "Z"), default=None,
                   help="the stored G28/G30 positions (default: the start position)")
    p.add_argument("--tool-table", type=Path, default=None,
                   help="LinuxCNC tool.tbl or CSV (tool,spec,length): tool numbers -> specs and G43 lengths")
    p.add_argument("--dialect", choices=("linuxcnc", "grbl"), default="linuxcnc",
                   help="grbl: the spindle is taken to run throughout (no M3 needed)")
    p.add_argument("--block-delete", choices=("on", "off"), default=None,
                   help="lines starting with '/': skipped (on) or run (off); without it such a line is an error")
    p.add_argument("--skip-unsupported", action="store_true",
                   help="skip words that cannot change the cut (listed in the summary); others are still errors")
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


def _finite(name: str, values, *, positive: bool = False) -> None:
    for v in np.atleast_1d(np.asarray(values, float)):
        if not math.isfinite(v) or (positive and not v > 0):
            raise ValueError(f"{name} must be {'a positive' if positive else 'a'} finite number, got {v!r}")


def check_arguments(args) -> None:
    """Refuse arguments that would give a wrong answer or no answer (ValueError naming the option)."""
    _finite("--stock sizes", args.stock, positive=True)
    for name in ("stock_origin", "start", "home"):
        if getattr(args, name) is not None:
            _finite(f"--{name.replace('_', '-')}", getattr(args, name))
    _finite("--rapid-rate (mm/min)", args.rapid_rate, positive=True)
    _finite("--chord-tolerance (mm)", args.chord_tolerance, positive=True)
    if args.chord_tolerance < MIN_CHORD_TOLERANCE:
        raise ValueError(f"--chord-tolerance {args.chord_tolerance:g} mm is below the {MIN_CHORD_TOLERANCE:g} mm "
                         "this simulator accepts (arcs would need millions of chords)")
    if args.resolution is not None:
        _finite("--resolution (mm)", args.resolution, positive=True)
    if args.checkpoint_every < 1:
        raise ValueError(f"--checkpoint-every must be a positive number of moves, got {args.checkpoint_every}")
    if args.segments < 3:
        raise ValueError(f"--segments must be at least 3, got {args.segments}")


def resolve_tools(program: gcode.Program, given: dict, table: dict) -> tuple[dict, list[str]]:
    """{None or tool number: ToolShape} for every tool the program uses, and notes on the choices made.

    ``given``: ``--tool`` shapes (key None: the unnumbered one); ``table``: tool-table shapes. A tool
    number the program loads that neither names is an error naming the line of its ``M6``, unless
    the program loads only that one tool number and an unnumbered tool is given.
    """
    numbered = dict(table)
    for k, v in given.items():
        if k is not None:
            if k in numbered:
                raise ValueError(f"tool {k} is given both by --tool and by the tool table; give it once")
            numbered[k] = v
    default = given.get(None)
    first_load: dict[int, int] = {}
    for line, tool in program.tool_changes:
        first_load.setdefault(tool, line)
    used = {m.tool for m in program.moves}
    out: dict = {}
    notes: list[str] = []
    for tool, line in first_load.items():
        if tool not in used:
            continue
        if tool in numbered:
            out[tool] = numbered[tool]
        elif default is not None and len(first_load) == 1:
            out[tool] = default
            notes.append(f"tool {tool} (line {line}): the unnumbered --tool")
        else:
            have = sorted(numbered) or "none"
            raise ValueError(f"line {line}: the program loads tool {tool} (T{tool} M6), but no tool {tool} was given "
                             f"(numbered tools: {have}): add --tool {tool}=SPEC or a tool-table entry")
    if None in used:
        if default is not None:
            out[None] = default
        elif first_load:
            tool, line = next(iter(first_load.items()))
            shape = out.get(tool, numbered.get(tool))
            if shape is None:
                raise ValueError(f"line {line}: the program loads tool {tool} (T{tool} M6), but no tool {tool} was "
                                 f"given: add --tool {tool}=SPEC or a tool-table entry")
            out[None] = shape
            notes.append(f"moves before line {line}'s M6: tool {tool} (the first the program loads; give an "
                         "unnumbered --tool for another)")
        elif len(numbered) == 1:
            (tool, shape), = numbered.items()
            out[None] = shape
            notes.append(f"the program loads no tool (no M6): tool {tool}, the only one given")
        else:
            raise ValueError("the program loads no tool (no T.. M6): give one unnumbered --tool SPEC for its moves")
    return out, notes


@dataclass
class Setup:
    """What :func:`prepare` makes of the arguments: the stock workpiece, the program, the placed tools."""

    workpiece: object
    program: gcode.Program
    tools: dict
    grid: Grid
    stock_lo: np.ndarray
    stock_hi: np.ndarray
    notes: list[str]


def prepare(args, program_text: str | None = None) -> Setup:
    """Stock, program, tools and grid as ``python -m csgnb.mill`` sets them up from its arguments ``args``
    (an ``argparse.Namespace`` of :func:`build_parser`); ``program_text`` replaces reading ``args.program``
    (the batch jobs of :mod:`csgnb.distributed` use this, so a job and the command line mill alike)."""
    check_arguments(args)
    size = np.asarray(args.stock, float)
    lo = np.array([0.0, 0.0, -size[2]]) if args.stock_origin is None else np.asarray(args.stock_origin, float)
    hi = lo + size
    table = read_tool_table(args.tool_table) if args.tool_table is not None else {}
    given = _tool_specs(args.tool or ([] if table else ["flat:6"]), args.segments)
    table_shapes = {k: tools.parse_tool(e.spec, segments=args.segments) for k, e in table.items()}
    start = np.array([lo[0], lo[1], hi[2] + 10.0]) if args.start is None else np.asarray(args.start, float)
    # Cutter compensation (G41 D<n>) offsets by the diameter of the tool the program names: the table's, or --tool's
    diameters = {k: s.params["diameter"] for k, s in {**table_shapes, **given}.items() if "diameter" in s.params}
    options = dict(start=start, home=args.home, dialect=args.dialect,
                   tool_lengths={k: e.length for k, e in table.items()}, tool_diameters=diameters,
                   block_delete=None if args.block_delete is None else args.block_delete == "on",
                   on_unsupported="warn" if args.skip_unsupported else "error")
    if program_text is not None:
        program = gcode.parse(program_text, **options)
    else:
        path = args.program
        if not path.exists() and path.name == str(path) and path.name in EXAMPLES:
            path = example_path(path.name)
        program = gcode.parse_file(path, **options)
    if not program.moves:
        raise ValueError(f"{args.program} has no moves")
    shapes, notes = resolve_tools(program, given, table_shapes)
    reach = max(max(s.radius, s.length) for s in shapes.values()) + 1.0
    p_lo, p_hi = program.bounds()
    box_lo = np.minimum(lo, p_lo - reach)
    box_hi = np.maximum(hi, p_hi + reach)
    if args.resolution is None:
        grid = Grid.fit(box_lo, box_hi, width=args.width)
    else:
        grid = Grid.from_resolution(args.resolution, origin=(box_lo + box_hi) / 2, width=args.width)
    placed = {k: s.on(grid) for k, s in shapes.items()}
    w = workpiece_type(args.reference).box(lo, hi, grid=grid)
    return Setup(w, program, placed, grid, lo, hi, notes)


def _grid_line(grid: Grid) -> str:
    return (f"grid             {grid.resolution:g} mm per step ({grid.width}-bit; every coordinate is rounded to it "
            "once, then everything is exact)")


def _report(args, setup: Setup, result, wall: float, stl=None, error: str | None = None) -> dict:
    program, grid = setup.program, setup.grid
    collisions = result.collisions
    return {
        "program": str(args.program), "complete": error is None, "error": error,
        "moves": len(program.moves), "moves_done": len(result.records), "wall_s": wall,
        "grid": {"resolution_mm": grid.resolution, "width": grid.width}, "dialect": program.dialect,
        "skipped": [s.as_dict() for s in program.skipped.values()], "dwell_s": program.dwell_s,
        "collision_lines": [r.line for r in collisions],
        "stock_mm3": float(result.stock_volume), "removed_mm3": float(result.removed),
        "removed_exact": fraction_text(result.removed),
        "stl": None if stl is None else stl.as_dict(),
        "records": [dict(index=r.index, line=r.line, kind=r.kind, removed_mm3=float(r.removed),
                         removed_exact=fraction_text(r.removed), time_s=r.time_s,
                         wall_s=r.wall_s, boolean_s=r.boolean_s, cells=r.cells, collision=r.collision)
                    for r in result.records]}


def _run(args) -> int:
    setup = prepare(args)
    program, grid, w, placed = setup.program, setup.grid, setup.workpiece, setup.tools
    for note in setup.notes:
        print(f"note: {note}", file=sys.stderr)
    size = setup.stock_hi - setup.stock_lo
    print(f"{args.program}: {len(program.moves)} moves; stock {size.tolist()} mm at {setup.stock_lo.tolist()}; grid "
          f"{grid.resolution:g} mm ({grid.width}-bit); workpiece {type(w).__name__}", file=sys.stderr)
    for k, t in placed.items():
        print(f"  tool {'*' if k is None else k}: {t}", file=sys.stderr)
        if t.collapsed_faces:
            print(f"note: tool {'*' if k is None else k}: rounding to the {grid.resolution:g} mm grid merged corners "
                  f"of {t.collapsed_faces} of its {len(t.shape.faces)} faces or put them on one line (dropped: the "
                  "tool is the rounded one); "
                  "a finer --resolution or --width 256 keeps more of its shape", file=sys.stderr)
    t0 = time.perf_counter()
    try:
        result = milling.simulate(w, program, placed,
                                  chord_tolerance=args.chord_tolerance, rapid_rate=args.rapid_rate,
                                  progress=not args.no_progress, checkpoint=args.checkpoint,
                                  checkpoint_every=args.checkpoint_every)
    except Exception as exc:
        partial = getattr(exc, "partial_result", None)
        if partial is not None and args.json is not None:  # what was computed is kept: a partial report
            _write_text(args.json, json.dumps(_report(args, setup, partial, time.perf_counter() - t0,
                                                      error=f"{type(exc).__name__}: {exc}"), indent=1))
            print(f"wrote a partial report ({len(partial.records)} of {len(program.moves)} moves) to {args.json}",
                  file=sys.stderr)
        raise
    wall = time.perf_counter() - t0
    print(result.table())
    print(_grid_line(grid))
    if program.skipped:
        print(program.skipped_table())
    if program.dwell_s:
        print(f"dwell            {program.dwell_s:g} s (not in the cut time)")
    print(f"simulated in {wall:.1f} s")
    collisions = result.collisions
    if collisions:
        first = ", ".join(str(r.line) for r in collisions[:10])
        print(f"{len(collisions)} collision(s), first at line(s) {first}{' ...' if len(collisions) > 10 else ''}",
              file=sys.stderr)
    stl = None
    if args.out is not None:
        stl = milling.export_stl(result.workpiece, args.out)
        print(stl.summary())
        if not stl.closed:  # never silently: a reader would get an open part
            print(f"warning: the STL {args.out} is not closed", file=sys.stderr)
    if args.json is not None:
        _write_text(args.json, json.dumps(_report(args, setup, result, wall, stl), indent=1))
    return 1 if collisions else 0


def _write_text(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.writing")
    tmp.write_text(text)
    tmp.replace(path)


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
