"""Milling simulation: a stock workpiece, a G-code program, tools; every move's sweep subtracted exactly.

:func:`simulate` walks the moves of a :class:`csgnb.apps.gcode.Program`. Each move is split
into straight pieces (arcs into chords within ``chord_tolerance``), each piece's sweep
(:func:`csgnb.apps.sweep.straight_sweep`) is subtracted from the workpiece, and the move is
recorded with its exact removed volume, its time from the feed, and a collision when a
rapid (``G0``) -- or a feed move with the spindle stopped -- removed material. Progress
goes to a ``tqdm.auto`` bar; ``checkpoint=PATH`` saves the workpiece and the records every
``checkpoint_every`` moves and resumes from them after a crash.

The workpiece is a :class:`csgnb.octree.Workpiece` (or anything with its API: ``grid``,
``difference(tool, track_volume=...) -> OpReport``, ``volume()``, ``surface()``,
``save(path)``, ``type(w).load(path)``; the tests run the single-BSP reference
:class:`csgnb.apps.reference.BSPWorkpiece` too). Each move's exact removed volume is
measured by the workpiece on the octree cells its sweep reaches (``difference(piece,
track_volume=True)``, :mod:`csgnb.octree.volume`), so it costs the same at move 10 as at move
10,000. A run that fails part-way re-raises the error with the moves done attached
(``error.partial_result``, a :class:`MillingResult`), so a caller can still report them.
Non-convex tools are sent as meshes (the octree clips them per cell). Programmed positions are the tool tip (the
lowest point of its axis).
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass
from fractions import Fraction
from functools import cached_property
from pathlib import Path

import numpy as np

from csgnb._files import write_atomic
from csgnb.apps.export import export_stl
from csgnb.apps.gcode import Move, Program
from csgnb.apps.sweep import straight_sweep
from csgnb.apps.tools import GridTool
from csgnb.errors import GeometryError
from csgnb.exact.rational import describe_fraction, fraction_text, parse_fraction

__all__ = ["MillingResult", "MoveRecord", "export_stl", "move_pieces", "simulate", "summary_table"]

RAPID_RATE = 5000.0
"""Default rapid traverse rate (mm/min) for the time of G0 moves."""

CHORD_TOLERANCE = 0.01
"""Default chord tolerance (mm) for splitting arcs."""


@dataclass
class MoveRecord:
    """What one move did.

    Attributes
    ----------
    index : int
        Position in the program's move list.
    line : int
        Source line.
    kind : str
        'rapid', 'linear' or 'arc'.
    tool : int or None
    length_mm : float
    time_s : float
        From the feed (rapids: the rapid rate).
    removed : Fraction
        Exact volume removed, mm³ (the grid's scale is a power of two, so grid units convert exactly).
    pieces : int
        Straight pieces subtracted (arcs: chords; non-convex tools: per-triangle prisms).
    collision : str or None
        Why the move is a collision, if it is one.
    wall_s : float
        Simulation time spent on the move (sweeps, Booleans and volume measurement).
    boolean_s : float
        Of which in the workpiece's Booleans (the ``OpReport`` seconds).
    cells : int
        Octree cells the move's Booleans touched.
    """

    index: int
    line: int
    kind: str
    tool: int | None
    length_mm: float
    time_s: float
    removed: Fraction
    pieces: int
    collision: str | None
    wall_s: float
    boolean_s: float = 0.0
    cells: int = 0


@dataclass
class MillingResult:
    """The simulated part and the per-move records."""

    workpiece: object
    records: list[MoveRecord]
    stock_volume: Fraction

    @property
    def removed(self) -> Fraction:
        """Total exact removed volume (mm³)."""
        return sum((r.removed for r in self.records), Fraction(0))

    @cached_property
    def part_volume(self) -> Fraction:
        """Exact volume of the part (mm³), computed once (``workpiece.volume()``)."""
        return _mm3(self.workpiece.volume(), self.workpiece.grid)

    @property
    def collisions(self) -> list[MoveRecord]:
        """The moves that cut where they must not."""
        return [r for r in self.records if r.collision]

    @property
    def cut_time_s(self) -> float:
        """Machine time of the program (s)."""
        return float(sum(r.time_s for r in self.records))

    def table(self) -> str:
        """A plain-text summary (see :func:`summary_table`)."""
        return summary_table(self)


def _mm3(volume: Fraction, grid) -> Fraction:
    return grid.model_volume(volume)


def _move_time(move: Move, length: float, rapid_rate: float) -> float:
    rate = rapid_rate if move.kind == "rapid" else move.feed
    return 60.0 * length / rate if rate else 0.0


def move_pieces(move: Move, tool: GridTool, chord_tolerance: float = CHORD_TOLERANCE) -> list:
    """The solids one move subtracts, in order: ``ConvexHull`` sweeps, and for a non-convex tool also the end pose
    of each straight piece as ``(vertices (n, 3) int64, faces (m, 3))`` grid meshes.

    The same pieces :func:`simulate` subtracts, for feeding another engine (a benchmark's peer)
    the identical tool sweeps: ``hull.to_mesh()`` and ``grid.to_model`` give float meshes.
    """
    if not isinstance(move, Move):
        raise TypeError(f"move must be a csgnb.apps.gcode.Move, got {type(move).__name__}")
    if not isinstance(tool, GridTool):
        raise TypeError(f"tool must be a GridTool (shape.on(grid)), got {type(tool).__name__}")
    points = move.points(chord_tolerance)
    out: list = []
    for a, b in zip(points[:-1], points[1:], strict=True):
        if np.array_equal(a, b):
            continue
        sweep = straight_sweep(tool, a, b)
        out += sweep.hulls
        if sweep.end_pose is not None:
            out.append((sweep.end_pose, sweep.faces))
    return out


def _subtract(workpiece, tool: GridTool, move: Move, chord_tolerance: float):
    """Subtract one move's pieces; return (exact removed grid units³, pieces, Boolean seconds, cells touched)."""
    removed, pieces, seconds, cells = Fraction(0), 0, 0.0, 0
    for piece in move_pieces(move, tool, chord_tolerance):
        report = workpiece.difference(piece, track_volume=True)
        removed -= report.volume_change
        pieces += 1
        seconds += report.seconds
        cells += report.cells
    return removed, pieces, seconds, cells


def _tool_for(move: Move, tools) -> GridTool:
    if isinstance(tools, GridTool):
        return tools
    key = move.tool if move.tool in tools else None
    if key not in tools:
        raise GeometryError(f"line {move.line}: no tool {move.tool} among the tools given ({sorted(tools, key=str)}); "
                            "pass tools={number: tool} or one tool for all")
    return tools[key]


def _record_json(r: MoveRecord) -> dict:
    d = asdict(r)
    d["removed"] = fraction_text(r.removed)
    return d


def _record_from_json(d: dict) -> MoveRecord:
    return MoveRecord(**dict(d, removed=parse_fraction(d["removed"])))


def _checkpoint(path: Path, workpiece, records: list[MoveRecord], stock: Fraction, program_key: str) -> None:
    # The workpiece goes to a file named by the move count, then the index that names it, then the old file is
    # removed: a crash at any point leaves an index whose workpiece file exists and matches it.
    done = len(records)
    wp_path = path.with_name(f"{path.name}.{done}.wp")
    workpiece.save(wp_path)
    digest = hashlib.sha256(wp_path.read_bytes()).hexdigest()
    old = json.loads(path.read_text())["workpiece"] if path.exists() else None
    index = {"done": done, "workpiece": wp_path.name, "sha256": digest, "program": program_key,
             "stock": fraction_text(stock), "records": [_record_json(r) for r in records]}
    write_atomic(path, json.dumps(index).encode())
    if old and old != wp_path.name:
        path.with_name(old).unlink(missing_ok=True)


def _resume(path: Path, workpiece_type, program_key: str):
    index = json.loads(path.read_text())
    if index["program"] != program_key:
        raise GeometryError(f"the checkpoint {path} belongs to another program or tool set; delete it to start afresh")
    wp_path = path.with_name(index["workpiece"])
    if hashlib.sha256(wp_path.read_bytes()).hexdigest() != index["sha256"]:
        raise GeometryError(f"the checkpoint's workpiece {wp_path} does not match its index (corrupted)")
    return (workpiece_type.load(wp_path), [_record_from_json(r) for r in index["records"]],
            parse_fraction(index["stock"]))


def _program_key(program: Program, tools, chord_tolerance: float) -> str:
    h = hashlib.sha256()
    for m in program.moves:
        h.update(np.r_[m.start, m.end, m.feed or 0.0].tobytes())
        h.update(f"{m.kind}{m.line}{m.tool}".encode())
    names = tools.name if isinstance(tools, GridTool) else sorted((str(k), t.name) for k, t in tools.items())
    h.update(f"{names}{chord_tolerance}".encode())
    return h.hexdigest()


def simulate(workpiece, program: Program, tools, *, chord_tolerance: float = CHORD_TOLERANCE,
             rapid_rate: float = RAPID_RATE, progress: bool = True, checkpoint=None, checkpoint_every: int = 50,
             on_move=None) -> MillingResult:
    """Mill ``program`` out of ``workpiece`` (modified in place); return the per-move records.

    Parameters
    ----------
    workpiece : Workpiece
        A :class:`csgnb.octree.Workpiece` (or the reference
        :class:`csgnb.apps.reference.BSPWorkpiece`).
    program : Program
        From :func:`csgnb.apps.gcode.parse`.
    tools : GridTool or dict
        One tool for every move, or ``{tool number: GridTool}`` (key ``None``: before any M6).
        Every tool must lie on the workpiece's grid.
    chord_tolerance : float
        Arcs are split into chords no further than this from the arc (mm).
    rapid_rate : float
        mm/min for the time of rapids.
    progress : bool
        A ``tqdm.auto`` progress bar.
    checkpoint : path, optional
        Save every ``checkpoint_every`` moves; if the checkpoint exists, resume from it.
    on_move : callable, optional
        ``on_move(record, workpiece)`` after each move (e.g. to keep snapshots for a slider).
    """
    from tqdm.auto import tqdm

    if not all(hasattr(workpiece, a) for a in ("grid", "difference", "volume", "save")):
        raise TypeError(f"workpiece must be a csgnb.octree.Workpiece (or the reference BSPWorkpiece), got "
                        f"{type(workpiece).__name__}")
    if not isinstance(program, Program):
        raise TypeError(f"program must be a csgnb.apps.gcode.Program (gcode.parse), got {type(program).__name__}")
    if not (isinstance(tools, GridTool) or (isinstance(tools, dict) and tools
                                              and all(isinstance(t, GridTool) for t in tools.values()))):
        raise TypeError("tools must be a GridTool (shape.on(workpiece.grid)) or {tool number: GridTool}")
    grid = workpiece.grid
    for t in ([tools] if isinstance(tools, GridTool) else list(tools.values())):
        if not t.grid.same_as(grid):
            raise GeometryError(f"tool {t.name!r} lies on {t.grid}, the workpiece on {grid}: build the tool with "
                                "shape.on(workpiece.grid)")
    records: list[MoveRecord] = []
    stock = _mm3(workpiece.volume(), grid)
    key = _program_key(program, tools, chord_tolerance)
    path = Path(checkpoint) if checkpoint is not None else None
    if path is not None and path.exists():
        workpiece, records, stock = _resume(path, type(workpiece), key)
    bar = tqdm(total=len(program.moves), initial=len(records), disable=not progress, unit="move", desc="milling")
    total = float(sum(r.removed for r in records))  # for the bar only: an exact running sum grows with the part
    try:
        for i in range(len(records), len(program.moves)):
            move = program.moves[i]
            t0 = time.perf_counter()
            tool = _tool_for(move, tools)
            points = move.points(chord_tolerance)
            length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
            removed, pieces, boolean_s, cells = (_subtract(workpiece, tool, move, chord_tolerance) if length > 0
                                                 else (Fraction(0), 0, 0.0, 0))
            removed = _mm3(removed, grid)
            collision = None
            if removed > 0 and move.kind == "rapid":
                collision = "rapid move (G0) cuts material"
            elif removed > 0 and not move.spindle_on:
                collision = "cut with the spindle stopped"
            rec = MoveRecord(i, move.line, move.kind, move.tool, length, _move_time(move, length, rapid_rate),
                             removed, pieces, collision, time.perf_counter() - t0, boolean_s, cells)
            records.append(rec)
            if on_move is not None:
                on_move(rec, workpiece)
            if path is not None and (len(records) % checkpoint_every == 0 or len(records) == len(program.moves)):
                _checkpoint(path, workpiece, records, stock, key)
            total += float(rec.removed)
            bar.update(1)
            bar.set_postfix(removed=f"{total:.5g} mm³", refresh=False)
    except (Exception, KeyboardInterrupt) as exc:
        # The moves done so far are kept: the caller gets them (a partial report), and a checkpointed run
        # resumes from its last checkpoint (written every checkpoint_every moves, never mid-move).
        done = len(records)
        line = program.moves[done].line if done < len(program.moves) else None
        exc.partial_result = MillingResult(workpiece, records, stock)
        exc.add_note(f"csgnb milling stopped at move {done} of {len(program.moves)} (line {line}); the moves done "
                     "are in the exception's partial_result" + (f", checkpointed in {path}" if path else ""))
        raise
    finally:
        bar.close()
    return MillingResult(workpiece, records, stock)


def _exact_text(v: Fraction) -> str:
    return describe_fraction(v)


def summary_table(result: MillingResult) -> str:
    """A plain-text summary: totals, the exact volume identity, collisions, the slowest moves."""
    if not isinstance(result, MillingResult):
        raise TypeError(f"summary_table takes a MillingResult (simulate's), got {type(result).__name__}")
    final = result.part_volume
    lines = [
        f"moves            {len(result.records)}",
        f"cut time         {result.cut_time_s / 60:.2f} min (rapids at the rapid rate)",
        f"stock volume     {float(result.stock_volume):.6g} mm³",
        f"removed volume   {float(result.removed):.6g} mm³ ({_exact_text(result.removed)})",
        f"part volume      {float(final):.6g} mm³",
        f"stock - removed == part: {result.stock_volume - result.removed == final} (exact)",
        f"collisions       {len(result.collisions)}",
    ]
    for r in result.collisions:
        lines.append(f"  line {r.line}: {r.collision}, {float(r.removed):.4g} mm³")
    by_kind: dict[str, list[MoveRecord]] = {}
    for r in result.records:
        by_kind.setdefault(r.kind, []).append(r)
    lines.append(f"{'kind':<8}{'moves':>7}{'length mm':>12}{'time s':>10}{'removed mm³':>14}{'sim s':>9}")
    for kind, rs in by_kind.items():
        lines.append(f"{kind:<8}{len(rs):>7}{sum(r.length_mm for r in rs):>12.1f}{sum(r.time_s for r in rs):>10.1f}"
                     f"{float(sum(r.removed for r in rs)):>14.6g}{sum(r.wall_s for r in rs):>9.2f}")
    return "\n".join(lines)
