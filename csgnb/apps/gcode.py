"""A G-code interpreter for 3-axis milling programs (RS274NGC as LinuxCNC reads it), into typed tool-tip moves in mm.

:func:`parse` runs a program and returns a :class:`Program` of :class:`Rapid`, :class:`Linear`
and :class:`Arc` moves of the **tool tip** in the stock's (machine) frame, absolute millimetres.
Supported:

* motion ``G0 G1 G2 G3`` (arcs in the centre form ``I J K`` -- incremental, or absolute under
  ``G90.1`` -- and the radius form ``R``; helical when the plane's normal axis moves; ``P`` full
  turns). An arc whose end lies on its start within LinuxCNC's ``CIRCLE_FUZZ`` (1e-6 rad of turn)
  is a full 360° circle, in every plane and both directions, as in LinuxCNC's ``pmCircleInit``;
* planes ``G17 G18 G19``, units ``G20 G21``, distance ``G90 G91``, arc centres ``G90.1 G91.1``,
  feed modes ``G93`` (inverse time) ``G94`` (per minute) ``G95`` (per revolution; times only);
* canned cycles ``G81 G82 G83 G73 G84 G85 G86 G89`` with ``G98``/``G99``, ``L`` repeats and ``G80``, in
  all three planes (:mod:`csgnb.apps.gcode_cycles`);
* coordinate systems: ``G53`` (machine coordinates, one line), ``G54``-``G59.3`` with offsets
  from ``G10 L2`` / ``G10 L20``; ``G92 G92.1 G92.2 G92.3``; ``G52`` (a local offset in G92's
  registers); ``G28 G30`` (via an intermediate point to the stored position) and ``G28.1 G30.1``
  (store it); the stored positions start at ``home`` (default: the start position);
* tool length ``G43 [H]``, ``G43.1``, ``G49`` with the lengths of ``tool_lengths``: the machine
  moves the controlled point (gauge line) to program + offsets + tool length offset, and the tip
  hangs the *loaded* tool's length below it -- so with ``G43 H<loaded tool>`` the tip is at the
  programmed point, and without a tool table (every length 0) always;
* ``F S T M6 M3 M4 M5``, ``G4 P`` dwell (time only), ``M0 M1`` (pauses), ``M2 M30`` (end);
* cutter radius compensation ``G41 G42 [D tool]``, ``G41.1 G42.1 D diameter``, ``G40``, with
  LinuxCNC's entry, corner and exit rules (:mod:`csgnb.apps.gcode_comp`; the diameters come from
  ``tool_diameters``); a corner the tool cannot reach without gouging is an error naming the line;
* no-ops by design (they do not change a 3-axis swept volume): ``G61 G61.1 G64 [P Q]`` (path
  blending only moves the path within the machine's tolerance, which this exact simulator does
  not model), coolant ``M7 M8 M9``;
* parameters ``#1``, ``#<name>``, ``#<_global>``, ``[ ]`` expressions and O-word control flow
  (:mod:`csgnb.apps.gcode_expr`), with a bound on loop passes; Fanuc-style subroutines ``O<n>`` ...
  ``M99`` called by ``M98 P<n> [L<count>]`` (parameters shared with the caller, as LinuxCNC); the
  modal state saved and restored by ``M70``-``M73``.

Anything else is refused with a :class:`GCodeError` naming the line and the word. Words that
cannot change the swept volume (spindle-speed modes ``G96 G97``, overrides ``M48``-``M53``,
``M19``, I/O ``M62``-``M68``, user codes ``M100``-``M199``) may instead be skipped with
``on_unsupported="warn"``: each is counted in :attr:`Program.skipped` (count and first line).
Words that change the cut (other axes ``A B C U V W``, ``G33``,
``G38.x``, unknown codes) are never skipped.

Within a line the RS274NGC order applies: feed mode, F, S, T, M6, spindle, coolant, dwell,
plane, units, cutter compensation, tool length, coordinate system, path mode, distance modes,
retract mode, G10/G28/G30/G92, motion, stop. Two codes of one modal group on a line are an error.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from csgnb.apps.gcode_comp import Compensation
from csgnb.apps.gcode_expr import Block, GCodeError, evaluate, positive_count, read_block
from csgnb.apps.gcode_flow import MAX_LOOP_PASSES, FlowMixin
from csgnb.apps.sweep import arc_polyline, arc_segments
from csgnb.errors import CsgnbError

__all__ = ["Arc", "GCodeError", "Linear", "Move", "Program", "Rapid", "Skipped", "parse", "parse_file", "read_text"]

INCH = 25.4
"""Millimetres per inch (G20)."""

RADIUS_TOLERANCE_MM = 0.002
"""An R-form arc's radius may fall this far (or 0.1 % of the radius, whichever is larger) short of half its chord."""

SPIRAL_TOLERANCE_MM = 2 * 0.01 * math.sqrt(2)
"""An I J K arc whose end lies off its start circle is a spiral, refused (as LinuxCNC's ``arc_data_ijk``) when the
radii differ by more than 100 times this, or by more than this and by more than :data:`SPIRAL_RELATIVE` of the
radius. Under G20 the tolerance is LinuxCNC's inch one, ``2 * 0.001 * sqrt(2)`` inch (0.0718 mm)."""

SPIRAL_TOLERANCE_INCH = 2 * 0.001 * math.sqrt(2)
""":data:`SPIRAL_TOLERANCE_MM` under G20, in inches."""

SPIRAL_RELATIVE = 0.001
"""LinuxCNC's ``SPIRAL_RELATIVE_TOLERANCE``."""

ZERO_RADIUS_MM = 0.00127
"""An arc whose start or end lies closer than this to its centre is a zero-radius arc (LinuxCNC: 0.00005 inch)."""

CIRCLE_FUZZ = 1e-6
"""An arc turning less than this (radians) from its start to its end is a full circle (LinuxCNC's ``CIRCLE_FUZZ``)."""

LIMIT_MM = 1e6
"""Every position, centre and offset must lie within ±1 km: beyond that no milling program is meant, and doubles
lose the precision a chord tolerance needs (an arc of radius 1e15 mm would need 10^9 chords)."""

MAX_ARC_CHORDS = 100_000
"""Most chords one arc may be split into; a finer chord tolerance is an error, not a hang."""

RAPID_DELTA_MM = 0.254
"""G73/G83 back-off and re-entry clearance (LinuxCNC: 0.010 inch)."""

_PLANES = {170: ("XY", (0, 1), 2, "IJ"), 180: ("ZX", (2, 0), 1, "KI"), 190: ("YZ", (1, 2), 0, "JK")}
_AXES = "XYZ"
_OFFSETS = "IJK"

# Modal groups (G codes as integers x 10: G92.1 -> 921). Two codes of one group on a line are an error.
_G_GROUPS = {
    "motion": {0, 10, 20, 30, 800, 810, 820, 830, 730, 840, 850, 860, 890},
    "plane": {170, 180, 190},
    "distance": {900, 910},
    "arc distance": {901, 911},
    "feed rate mode": {930, 940, 950},
    "units": {200, 210},
    "cutter compensation": {400, 410, 411, 420, 421},
    "tool length offset": {430, 431, 490},
    "canned cycle return": {980, 990},
    "coordinate system": {540, 550, 560, 570, 580, 590, 591, 592, 593},
    "path control": {610, 611, 640},
    "non-modal": {40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923},
}
_G_GROUP_OF = {code: group for group, codes in _G_GROUPS.items() for code in codes}
_CS_NUMBER = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}
_CYCLES = {810, 820, 830, 730, 840, 850, 860, 890}
_AXIS_USERS = {100, 280, 300, 520, 920, 431}  # codes that read X Y Z themselves (no motion from them)

# Known but refused: they change the cut, so they are never skipped.
_G_REFUSED = {
    432: "additive tool length offsets are not supported", 330: "spindle-synchronised motion (threading)",
    331: "rigid tapping", 760: "a lathe threading cycle", 382: "probing", 383: "probing", 384: "probing",
    385: "probing", 50: "splines", 51: "splines", 52: "NURBS", 70: "lathe diameter mode", 80: "lathe radius mode",
    171: "UVW planes", 181: "UVW planes", 191: "UVW planes", 740: "tapping",
    870: "back boring", 880: "boring with a manual retract",
}
# Known, unsupported, and without effect on a 3-axis swept volume: skippable with on_unsupported="warn".
_G_SKIPPABLE = {960: "constant surface speed (spindle speed only)", 970: "spindle speed mode (RPM only)"}
_M_SKIPPABLE = {19: "spindle orientation", 48: "overrides", 49: "overrides", 50: "feed override",
                51: "spindle override", 52: "adaptive feed", 53: "feed stop", 62: "digital output",
                63: "digital output", 64: "digital output", 65: "digital output", 66: "wait on input",
                67: "analog output", 68: "analog output"}
_M_GROUPS = {"stopping": {0, 1, 2, 30}, "tool change": {6}, "spindle": {3, 4, 5}}
_LETTERS = set("DEFGHIJKLMNPQRSTXYZ")


class Skipped:
    """A word skipped under ``on_unsupported="warn"``: how often, where first, and why it may be skipped."""

    __slots__ = ("count", "first_line", "why", "word")

    def __init__(self, word: str, first_line: int, why: str) -> None:
        self.word, self.first_line, self.why, self.count = word, first_line, why, 0

    def as_dict(self) -> dict:
        return {"word": self.word, "count": self.count, "first_line": self.first_line, "why": self.why}

    def __repr__(self) -> str:
        return f"Skipped({self.word!r}, count={self.count}, first_line={self.first_line})"


@dataclass(frozen=True)
class Move:
    """A motion of the tool tip from ``start`` to ``end`` (absolute mm, the stock's frame).

    Attributes
    ----------
    start, end : (3,) float64
    feed : float or None
        Feed rate in mm/min (None for rapids).
    spindle : float
        Spindle speed (the last ``S``).
    spindle_on : bool
        Whether ``M3``/``M4`` is in effect (always True under ``dialect="grbl"``).
    tool : int or None
        The tool loaded by the last ``M6`` (None before any).
    line : int
        1-based source line.
    label : int or None
        The line's ``N`` number.
    origin : str or None
        The code that generated the move when it is not the line's own G0-G3 (``G81``, ``G28``, ...).
    """

    start: np.ndarray
    end: np.ndarray
    feed: float | None
    spindle: float
    spindle_on: bool
    tool: int | None
    line: int
    label: int | None
    origin: str | None = None

    kind = "move"

    def points(self, tolerance: float = 0.01) -> np.ndarray:
        """Tip positions ``(k + 1, 3)`` along the move (a straight move: its two ends)."""
        return np.stack([self.start, self.end])

    def length(self, tolerance: float = 0.01) -> float:
        """Path length in mm (arcs: of their chords within ``tolerance``)."""
        p = self.points(tolerance)
        return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


@dataclass(frozen=True)
class Rapid(Move):
    """``G0``: a positioning move at the machine's rapid rate; it must not cut."""

    kind = "rapid"


@dataclass(frozen=True)
class Linear(Move):
    """``G1``: a straight cut at ``feed``."""

    kind = "linear"


@dataclass(frozen=True)
class Arc(Move):
    """``G2``/``G3``: a circular (helical) cut about ``center`` in ``plane`` ('XY', 'ZX' or 'YZ').

    ``angle`` is the total turn in radians (> 0; 2π for a full circle, more with ``P`` turns), decided
    once by the parser; None only for arcs built by hand, whose turn :func:`arc_polyline` decides.
    """

    center: np.ndarray = field(default=None)
    plane: str = "XY"
    clockwise: bool = True
    angle: float | None = None

    kind = "arc"

    @property
    def normal(self) -> np.ndarray:
        """Unit normal of the plane (the arc turns about it)."""
        n = np.zeros(3)
        n[{"XY": 2, "ZX": 1, "YZ": 0}[self.plane]] = 1.0
        return n

    @property
    def radius(self) -> float:
        """Radius at the start point (mm)."""
        n = self.normal
        r = self.start - self.center
        return float(np.linalg.norm(r - (r @ n) * n))

    def points(self, tolerance: float = 0.01) -> np.ndarray:
        """Points along the arc with every chord within ``tolerance`` mm of it (at most :data:`MAX_ARC_CHORDS`)."""
        if self.angle is None:
            return arc_polyline(self.start, self.end, self.center, self.normal, self.clockwise, tolerance=tolerance)
        r = self.radius
        k = _chords(r, self.angle, tolerance, self.line)
        n = self.normal
        s, e, c = self.start, self.end, self.center
        rs, re_ = s - c, e - c
        rs_p, re_p = rs - (rs @ n) * n, re_ - (re_ @ n) * n
        u = rs_p / r
        v = np.cross(n, u)
        theta = -self.angle if self.clockwise else self.angle
        t = np.linspace(0.0, 1.0, k + 1)[:, None]
        rad = r + (float(np.linalg.norm(re_p)) - r) * t  # an end radius within the parser's tolerance blends in
        h = (rs @ n) + ((re_ @ n) - (rs @ n)) * t
        pts = c + rad * (np.cos(theta * t) * u + np.sin(theta * t) * v) + h * n
        pts[0], pts[-1] = s, e
        return pts


def _chords(radius: float, angle: float, tolerance: float, line: int) -> int:
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise CsgnbError(f"the chord tolerance must be a positive finite number of mm, got {tolerance!r}")
    if radius <= tolerance:
        return max(1, math.ceil(angle / (math.pi / 2)))
    step = 2 * math.acos(max(1 - tolerance / radius, -1.0))
    need = angle / step if step > 0 else math.inf
    if not need <= MAX_ARC_CHORDS:
        raise GCodeError(line, f"the arc (radius {radius:.6g} mm, {math.degrees(angle):.6g}°) needs "
                         f"{need:.3g} chords at a chord tolerance of {tolerance:g} mm, more than the "
                         f"{MAX_ARC_CHORDS} allowed: use a larger chord tolerance")
    return max(1, arc_segments(radius, angle, tolerance))


@dataclass
class Program:
    """A parsed program: its moves, where it ended, and what was skipped.

    Attributes
    ----------
    moves : list of Move
    warnings : list of str
        One line per skipped word kind (first occurrence).
    end_line : int or None
        The M2/M30 (or closing ``%``) line, if any.
    skipped : dict
        Word -> :class:`Skipped` (count, first line, why it does not change the cut).
    dwell_s : float
        Total G4 / G82 / G89 dwell (seconds).
    dialect : str
    tool_changes : list of (line, tool)
        Every ``M6`` in execution order.
    """

    moves: list[Move]
    warnings: list[str]
    end_line: int | None
    skipped: dict = field(default_factory=dict)
    dwell_s: float = 0.0
    dialect: str = "linuxcnc"
    tool_changes: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.moves)

    def __iter__(self):
        return iter(self.moves)

    def __getitem__(self, i):
        return self.moves[i]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box ``(lo, hi)`` of every tip position (arcs sampled at 0.01 mm)."""
        pts = np.vstack([m.points() for m in self.moves]) if self.moves else np.zeros((1, 3))
        return pts.min(axis=0), pts.max(axis=0)

    def skipped_table(self) -> str:
        """The skipped words as a plain-text table (empty string when none)."""
        if not self.skipped:
            return ""
        rows = [f"{'skipped':<10}{'count':>7}{'first line':>12}  why it does not change the cut"]
        rows += [f"{s.word:<10}{s.count:>7}{s.first_line:>12}  {s.why}" for s in self.skipped.values()]
        return "\n".join(rows)


def _code_text(code: int) -> str:
    return f"{code // 10}" if code % 10 == 0 else f"{code // 10}.{code % 10}"


class _Interpreter(FlowMixin):
    def __init__(self, blocks: list[Block], *, start, on_unsupported, dialect, tool_lengths, home, block_delete,
                 max_loop_passes, tool_diameters=None):
        self.blocks = blocks
        self.on_unsupported, self.dialect, self.block_delete = on_unsupported, dialect, block_delete
        self.tool_lengths = dict(tool_lengths or {})
        self.tool_diameters = dict(tool_diameters or {})
        self.comp_on, self.comp_word = False, ""  # G41/G42 in effect (even with a zero radius), and its word
        self.comp: Compensation | None = None  # ... with a positive radius: moves are offset
        self.actual_xy: np.ndarray | None = None  # after G40: where the tool stands, off the programmed point
        self.exit_straight = False  # after G40 the next move must be straight
        self.max_loop_passes = max_loop_passes
        self.mpos = np.asarray(start, float).copy()  # the controlled point (gauge line) in machine coordinates
        self.factor, self.absolute, self.arc_absolute, self.plane = 1.0, True, False, 170
        self.feed_mode, self.retract_r = 940, False
        self.motion: int | None = None
        self.feed: float | None = None
        self.spindle, self.spindle_on = 0.0, False
        self.selected: int | None = None
        self.loaded: int | None = None
        self.cs = 1
        self.g5x = {k: np.zeros(3) for k in range(1, 10)}
        self.rotation = {k: 0.0 for k in range(1, 10)}  # degrees about Z of each coordinate system (G10 L2 R)
        self.g92, self.g92_saved, self.g92_on = np.zeros(3), np.zeros(3), False
        self.tlo = np.zeros(3)
        h = np.asarray(start if home is None else home, float)
        self.g28, self.g30 = h.copy(), h.copy()
        self.cycle = {}
        self.numbered: dict[int, float] = {}
        self.globals: dict[str, float] = {"_value": 0.0, "_value_returned": 0.0}
        self.frames: list = []  # gcode_flow._Frame per active call
        self.main_locals: dict[str, float] = {}
        self.moves: list[Move] = []
        self.skipped: dict[str, Skipped] = {}
        self.notes: list[str] = []
        self.dwell = 0.0
        self.passes = 0
        self.tool_changes: list = []
        self.repeat_left: dict = {}
        self._structure()

    # -- positions -----------------------------------------------------------------------------------------
    def _offset(self) -> np.ndarray:
        return self.g5x[self.cs] + self.g92 + self.tlo

    def _turn(self, xy_vector: np.ndarray, sign: float = 1.0) -> np.ndarray:
        """``xy_vector`` (3,) turned about Z by the current system's rotation (``sign=-1``: back)."""
        a = math.radians(sign * self.rotation[self.cs])
        c, s_ = math.cos(a), math.sin(a)
        out = np.asarray(xy_vector, float).copy()
        out[0], out[1] = c * xy_vector[0] - s_ * xy_vector[1], s_ * xy_vector[0] + c * xy_vector[1]
        return out

    def _to_machine(self, prog: np.ndarray) -> np.ndarray:
        """Program coordinates (mm) to the controlled point in machine coordinates: the G92/G52 offset, the
        system's rotation about its origin (LinuxCNC's G10 L2 R), its G5x origin, the tool length offset."""
        if self.rotation[self.cs] == 0:
            return prog + self._offset()
        return self._turn(prog + self.g92) + self.g5x[self.cs] + self.tlo

    def _program_position(self) -> np.ndarray:
        if self.rotation[self.cs] == 0:
            return self.mpos - self._offset()
        return self._turn(self.mpos - self.g5x[self.cs] - self.tlo, -1.0) - self.g92

    def _length(self, tool) -> float:
        return float(self.tool_lengths.get(tool, 0.0)) if tool is not None else 0.0

    def _tip(self, mpos: np.ndarray) -> np.ndarray:
        return mpos - np.array([0.0, 0.0, self._length(self.loaded)])

    def _check_position(self, p: np.ndarray, line: int, what: str) -> None:
        if not all(-LIMIT_MM <= v <= LIMIT_MM for v in p.tolist()):  # NaN fails the comparison too
            raise GCodeError(line, f"{what} at {np.round(p, 6).tolist()} mm lies beyond ±{LIMIT_MM:g} mm (1 km); "
                             "check the program's units and values")

    # -- skipping ------------------------------------------------------------------------------------------
    def _skip(self, line: int, word: str, why: str) -> None:
        if self.on_unsupported == "error":
            raise GCodeError(line, f"unsupported word {word} ({why}); remove it, or parse with on_unsupported='warn' "
                             "(--skip-unsupported) to skip it: it does not change the cut", word)
        s = self.skipped.get(word)
        if s is None:
            s = self.skipped[word] = Skipped(word, line, why)
            note = f"line {line}: unsupported word {word} ({why}): skipped (no effect on the cut)"
            self.notes.append(note)
            warnings.warn(note, stacklevel=4)
        s.count += 1

    # -- moves ---------------------------------------------------------------------------------------------
    def _emit(self, cls, end_mpos: np.ndarray, line: int, label, *, feed=None, origin=None, skip_zero=False,
              compensate=False, **extra) -> None:
        """Append the move to ``end_mpos`` (the controlled point, machine frame); ``compensate``: a G0-G3 of the
        program, offset by cutter radius compensation when it is on."""
        self._check_position(end_mpos, line, "the move's end")
        start, end = self._tip(self.mpos), self._tip(end_mpos)
        if self.actual_xy is not None:  # the move after G40 starts where the compensated path ended
            start[:2] = self.actual_xy
            self.actual_xy = None
        programmed_start = self.mpos
        self.mpos = end_mpos.copy()
        if skip_zero and np.array_equal(start, end):
            return
        move = cls(start=start, end=end, feed=feed, spindle=self.spindle,
                   spindle_on=self.spindle_on or self.dialect == "grbl", tool=self.loaded, line=line, label=label,
                   origin=origin, **extra)
        if compensate and self.comp is not None:
            if cls is Arc:
                self.comp.arc(self, move, programmed_start, line)
            else:
                self.comp.straight(self, move, programmed_start, end_mpos, line)
            return
        self.moves.append(move)

    def _feed_rate(self, line: int, values: dict, length: float | None = None) -> float:
        """mm/min of a feed move (G93: from the move's length, G95: from S)."""
        if self.feed_mode == 930:
            if "F" not in values:
                raise GCodeError(line, "G93 (inverse time) needs an F word on every feed move line", "F")
            f = values["F"][0]
            if not f > 0:
                raise GCodeError(line, "a G93 F word must be positive (1/minutes for the move)", values["F"][1])
            return (length or 0.0) * f
        if not self.feed:
            raise GCodeError(line, "a feed move (G1/G2/G3/canned cycle) needs a positive feed rate: give an F word",
                             "F")
        if self.feed_mode == 950:
            if not self.spindle > 0:
                raise GCodeError(line, "G95 (feed per revolution) needs a spindle speed: give an S word", "F")
            return self.feed * self.factor * self.spindle
        return self.feed * self.factor

    # -- one line ------------------------------------------------------------------------------------------
    def run(self) -> Program:
        pc, n = 0, len(self.blocks)
        end_line = None
        percent_seen = False
        while pc < n:
            b = self.blocks[pc]
            if b.percent:
                if percent_seen:  # the second '%' ends the program
                    end_line = b.line
                    break
                percent_seen = True
                pc += 1
                continue
            if b.delete:
                if self.block_delete is None:
                    raise GCodeError(b.line, "the line starts with '/' (block delete): say whether such lines are "
                                     "skipped (block_delete=True, --block-delete on) or run (False, off)", "/")
                if self.block_delete:
                    pc += 1
                    continue
            if b.oword is not None:
                nxt = self._control(pc, b)
                pc = nxt
                continue
            if self._line(b):
                end_line = b.line
                break
            pc = self._fanuc_jump(pc, b) if self.fanuc_pending is not None else pc + 1
        if self.fanuc_frames:
            start = self.blocks[self.fanuc_frames[-1][1]]
            raise GCodeError(start.line, f"O{start.oword[0]} (called by M98) ran past the end of the program without "
                             "its M99", f"O{start.oword[0]}")
        if self.comp is not None:  # the program ends under G41/G42: its last moves as compensated
            self.comp.finish(self)
        return Program(self.moves, self.notes, end_line, self.skipped, self.dwell, self.dialect, self.tool_changes)

    def _line(self, b: Block) -> bool:
        """Execute one line; True when it ends the program."""
        line = b.line
        values: dict[str, tuple[float, str]] = {}
        g_codes: list[tuple[int, str]] = []
        m_codes: list[tuple[int, str]] = []
        label = b.label
        for letter, node, text in b.words:
            value = evaluate(node, self, line, text)
            if letter == "G":
                code = round(value * 10)
                if abs(value * 10 - code) > 1e-6 or code < 0:
                    raise GCodeError(line, f"unknown G code {text}", text)
                g_codes.append((code, text))
            elif letter == "M":
                if value != int(value) or value < 0:
                    raise GCodeError(line, f"unknown M code {text}", text)
                m_codes.append((int(value), text))
            elif letter == "N":
                if label is not None:
                    raise GCodeError(line, "the word N appears twice", text)
                if value < 0:
                    raise GCodeError(line, f"a line number must not be negative, got {text}", text)
                label = int(value) if value == int(value) else value  # LinuxCNC reads N12.5 too
            elif letter in _LETTERS:
                if letter in values:
                    raise GCodeError(line, f"the word {letter} appears twice", text)
                values[letter] = (value, text)
            elif letter in "ABCUVW":
                raise GCodeError(line, f"unsupported word {text} (the {letter} axis: this simulator has the three "
                                 "axes X Y Z; post-process the program for a 3-axis machine)", text)
            else:
                raise GCodeError(line, f"unsupported word {text} (the letter {letter} is not RS274NGC milling G-code)",
                                 text)
        assigned = [(ref if isinstance(ref, str) else evaluate(ref, self, line, text),
                     evaluate(node, self, line, text), text) for ref, node, text in b.assigns]
        for ref, value, text in assigned:
            self._assign(ref, value, line, text)
        if not b.words:
            return False
        return self._execute(line, label, values, g_codes, m_codes)

    def _execute(self, line, label, values, g_codes, m_codes) -> bool:
        used = set("FSTN")
        modal: dict[str, tuple[int, str]] = {}
        for code, w in g_codes:
            group = _G_GROUP_OF.get(code)
            if group is None:
                if code in _G_SKIPPABLE:
                    self._skip(line, f"G{_code_text(code)}", _G_SKIPPABLE[code])
                    continue
                why = _G_REFUSED.get(code) or "not a G code this simulator knows"
                raise GCodeError(line, f"unsupported word {w} ({why}; it would change the cut, so it cannot be "
                                 "skipped)", w)
            if group in modal:
                raise GCodeError(line, f"{modal[group][1]} and {w} are both in the {group} modal group: one per line "
                                 "(RS274NGC)", w)
            modal[group] = (code, w)
        m_modal: dict[str, tuple[int, str]] = {}
        coolant = []
        for code, w in m_codes:
            if code in (70, 71, 72, 73):
                if "modal state" in m_modal:
                    raise GCodeError(line, f"{m_modal['modal state'][1]} and {w} on one line", w)
                m_modal["modal state"] = (code, w)
                continue
            if code in (98, 99):
                if "fanuc" in m_modal:
                    raise GCodeError(line, f"{m_modal['fanuc'][1]} and {w} on one line", w)
                m_modal["fanuc"] = (code, w)
                continue
            group = next((g for g, codes in _M_GROUPS.items() if code in codes), None)
            if group is None:
                if code in (7, 8, 9):
                    coolant.append(code)
                    continue
                if code in _M_SKIPPABLE or 100 <= code <= 199:
                    if 100 <= code <= 199:
                        used.update("PQ")  # a user M code's two arguments
                    if 62 <= code <= 68:
                        used.update("PLQE")  # I/O pin, wait mode, value or timeout, analog channel
                    self._skip(line, f"M{code}", _M_SKIPPABLE.get(code, "a user-defined M code (no axis motion)"))
                    continue
                why = {60: "pallet change"}.get(
                    code, "not an M code this simulator knows")
                raise GCodeError(line, f"unsupported word {w} ({why}; it may change the cut, so it cannot be skipped)",
                                 w)
            if group in m_modal:
                raise GCodeError(line, f"{m_modal[group][1]} and {w} are both in the {group} group: one per line", w)
            m_modal[group] = (code, w)
        g = {grp: c for grp, (c, _) in modal.items()}
        nonmodal = g.get("non-modal")
        motion_code = g.get("motion")
        axis_user = nonmodal in _AXIS_USERS or g.get("tool length offset") == 431
        axes = {a: values[a] for a in _AXES if a in values}
        if axis_user and motion_code is not None and axes:
            other = modal.get("non-modal", modal.get("tool length offset"))[1]
            raise GCodeError(line, f"{modal['motion'][1]} and {other} both use the axis words of the line: put them "
                             "on separate lines", modal["motion"][1])
        if self.comp_on:
            self._refuse_under_compensation(line, g, modal, m_modal, axes)
        if "modal state" in m_modal:  # M70 save, M71 invalidate, M72 restore, M73 save and restore on return
            self._modal_state(line, *m_modal["modal state"])
        # -- feed mode, F, S, T, M6, spindle -------------------------------------------------------------
        if "feed rate mode" in g:
            self.feed_mode = g["feed rate mode"]
            if self.feed_mode in (940, 950):
                self.feed = None  # LinuxCNC's convert_feed_mode: G94 / G95 need a new F (an old one meant another mode)
        if "F" in values:
            f = values["F"][0]
            if f < 0:
                raise GCodeError(line, f"a feed rate must not be negative, got {values['F'][1]}", values["F"][1])
            self.feed = f
        if "S" in values:
            if values["S"][0] < 0:
                raise GCodeError(line, f"a spindle speed must not be negative, got {values['S'][1]}", values["S"][1])
            self.spindle = values["S"][0]
        if "T" in values:
            t = values["T"][0]
            if t != int(t) or t < 0:
                raise GCodeError(line, f"a tool number must be a non-negative integer, got {values['T'][1]}",
                                 values["T"][1])
            self.selected = int(t)
        if "tool change" in m_modal:
            if self.selected is None:
                raise GCodeError(line, "M6 changes to the selected tool, but no T word selected one", "M6")
            self.loaded = self.selected
            self.tool_changes.append((line, self.loaded))
        if "spindle" in m_modal:
            self.spindle_on = m_modal["spindle"][0] != 5
        # -- dwell, plane, units, compensation, length, coordinate system, path, distance, retract ------
        if nonmodal == 40:
            used.add("P")
            if "P" not in values or values["P"][0] < 0:
                raise GCodeError(line, "G4 needs a dwell time P (seconds, not negative)", "G4")
            self.dwell += values["P"][0]
        if "plane" in g:
            self.plane = g["plane"]
        if "units" in g:
            self.factor = INCH if g["units"] == 200 else 1.0
        if "cutter compensation" in g:
            self._compensation(line, *modal["cutter compensation"], values, used)
        if "tool length offset" in g:
            self._tool_length(line, g["tool length offset"], values, used)
        if "coordinate system" in g:
            self.cs = _CS_NUMBER[g["coordinate system"]]
        if "path control" in g:
            used.update("PQ")  # G64 P Q: the blending tolerance; no effect on the swept volume here
        if "distance" in g:
            self.absolute = g["distance"] == 900
        if "arc distance" in g:
            self.arc_absolute = g["arc distance"] == 901
        if "canned cycle return" in g:
            self.retract_r = g["canned cycle return"] == 990
        # -- G10, G28, G30, G92 ------------------------------------------------------------------------
        if nonmodal in (100, 280, 281, 300, 301, 520, 920, 921, 922, 923):
            used.update("XYZ")
            axis_user = True
            self._nonmodal(line, label, nonmodal, modal["non-modal"][1], values, used)
        # -- motion ------------------------------------------------------------------------------------
        if motion_code is not None:
            self.motion = motion_code
            if motion_code not in _CYCLES:
                self.cycle = {}  # R, Z, Q, P of canned cycles are sticky only while cycles follow each other
            if motion_code == 800:
                if axes:
                    w = next(iter(axes.values()))[1]
                    raise GCodeError(line, "G80 (cancel canned cycle) takes no axis words", w)
        if not axis_user:
            self._motion(line, label, values, axes, motion_code, nonmodal == 530, used)
        if "fanuc" in m_modal:
            self._fanuc_word(line, *m_modal["fanuc"], values, used)
        for letter, (_, w) in values.items():
            if letter not in used:
                if letter == "E":
                    raise GCodeError(line, f"unsupported word {w} (E is an extruder or analog channel, not a milling "
                                     "axis)", w)
                raise GCodeError(line, f"the word {w} is used by no code on this line", w)
        # -- stop --------------------------------------------------------------------------------------
        return m_modal.get("stopping", (None,))[0] in (2, 30)

    _MODAL = ("factor", "absolute", "arc_absolute", "plane", "feed_mode", "feed", "spindle", "spindle_on", "cs",
              "retract_r")

    def _modal_state(self, line, code, word) -> None:
        """LinuxCNC's M70-M73: units, distance modes, plane, feed mode and rate, spindle, coordinate system and
        retract mode, saved and restored."""
        if code == 70:
            self.saved_modal = {k: getattr(self, k) for k in self._MODAL}
        elif code == 71:
            self.saved_modal = None
        elif code == 72:
            if getattr(self, "saved_modal", None) is None:
                raise GCodeError(line, "M72 restores the modal state saved by M70, but none is saved", word)
            self._restore_modal(self.saved_modal, line)
        else:
            if not self.frames:
                raise GCodeError(line, "M73 saves the caller's modal state for the end of a subroutine: use it inside "
                                 "an o-word sub", word)
            self.frames[-1].autorestore = {k: getattr(self, k) for k in self._MODAL}

    def _restore_modal(self, state: dict, line: int) -> None:
        if self.comp_on and (state["factor"] != self.factor or state["plane"] != self.plane
                             or state["cs"] != self.cs):
            raise GCodeError(line, "restoring the modal state would change units, plane or coordinate system while "
                             "cutter compensation is on", "M72")
        for k, v in state.items():
            setattr(self, k, v)

    def _fanuc_word(self, line, code, word, values, used) -> None:
        """M98 P<n> [L<count>]: call O<n> (ended by M99) count times (default once); M99: return from it."""
        if code == 99:
            self.fanuc_pending = ("return",)
            return
        used.update("PL")
        if "P" not in values:
            raise GCodeError(line, "M98 needs P, the number of the O subroutine to call", word)
        n, count = values["P"][0], values.get("L", (1.0, ""))[0]
        if n != int(n) or n < 0:
            raise GCodeError(line, f"M98 P{values['P'][1][1:]}: P is an O number (a non-negative integer)", word)
        if count != int(count) or count < 0:
            raise GCodeError(line, f"M98: L (how many times) must be a non-negative integer, got {values['L'][1]}",
                             values["L"][1])
        if int(n) not in self.fanuc_subs:
            raise GCodeError(line, f"M98 P{int(n)}: the file defines no subroutine O{int(n)} (an O{int(n)} line, its "
                             "body, then M99)", word)
        self.fanuc_pending = ("call", int(n), int(count))

    def _refuse_under_compensation(self, line, g, modal, m_modal, axes) -> None:
        """What LinuxCNC refuses while G41/G42 is on (a tool change, another plane, units or frame, a move that
        cannot be compensated)."""
        why = None
        if "tool change" in m_modal:
            why, word = "a tool change", m_modal["tool change"][1]
        elif g.get("plane", 170) != 170:
            why, word = "another plane (compensation works in G17)", modal["plane"][1]
        elif "units" in g and (INCH if g["units"] == 200 else 1.0) != self.factor:
            why, word = "a change of units", modal["units"][1]
        elif g.get("cutter compensation") != 400:  # these are fine on the line that turns compensation off
            motion = g.get("motion", self.motion)
            if "coordinate system" in g and _CS_NUMBER[g["coordinate system"]] != self.cs:
                why, word = "a change of coordinate system", modal["coordinate system"][1]
            elif g.get("non-modal") in (100, 280, 300, 520, 530, 920, 921, 922, 923):
                why, word = "a move or offset that cannot be compensated", modal["non-modal"][1]
            elif motion in _CYCLES and (axes or "motion" in g):
                why, word = "a canned cycle", modal.get("motion", (0, f"G{_code_text(motion)}"))[1]
        if why is not None:
            raise GCodeError(line, f"{word}: {why} while cutter radius compensation ({self.comp_word}) is on: turn "
                             "it off with G40 first", word)

    def _compensation(self, line, code, word, values, used) -> None:
        """G40 / G41 / G42 [D tool] / G41.1 / G42.1 D diameter."""
        if code == 400:
            if self.comp is not None:
                here = self.comp.finish(self)
                if here is not None:
                    self.actual_xy, self.exit_straight = here, True
            self.comp_on, self.comp = False, None
            return
        if self.comp_on:
            raise GCodeError(line, f"{word}: cutter radius compensation is already on ({self.comp_word}): give G40 "
                             "first", word)
        if self.plane != 170:
            raise GCodeError(line, f"{word}: cutter radius compensation works in the XY plane: give G17 first", word)
        used.add("D")
        d = values.get("D")
        if code in (411, 421):  # G41.1 / G42.1 D<diameter>
            if d is None:
                raise GCodeError(line, f"{word} needs the tool diameter D (mm or inch; a negative one swaps the side)",
                                 word)
            diameter = d[0] * self.factor
        else:
            if d is not None:
                if d[0] != int(d[0]) or d[0] < 0:
                    raise GCodeError(line, f"{word}: D names a tool number of the tool table, got {d[1]}", d[1])
                tool = int(d[0])
            elif self.loaded is None:
                raise GCodeError(line, f"{word} without D takes the loaded tool's diameter, but no tool is loaded: "
                                 "give D<tool number> or load one with T.. M6", word)
            else:
                tool = self.loaded
            if tool == 0:
                diameter = 0.0
            else:
                diameter = self.tool_diameters.get(tool, self.tool_diameters.get(None))
                if diameter is None:
                    raise GCodeError(line, f"{word}: the diameter of tool {tool} is unknown: give the tool diameters "
                                     "(parse(tool_diameters=...); python -m csgnb.mill: --tool-table, or "
                                     f"--tool {tool}=SPEC), or give the diameter itself with "
                                     f"{'G41.1' if code == 410 else 'G42.1'} D<diameter>", d[1] if d else word)
        left = code in (410, 411)
        if diameter < 0:  # a negative diameter (G41.1 D or the table's) swaps the side (LinuxCNC)
            left, diameter = not left, -diameter
        self.comp_on, self.comp_word = True, word
        self.comp = Compensation(left, diameter / 2, word) if diameter > 0 else None

    def _tool_length(self, line, code, values, used) -> None:
        if code == 490:
            self.tlo = np.zeros(3)
        elif code == 430:
            used.add("H")
            if "H" in values:
                h = values["H"][0]
                if h != int(h) or h < 0:
                    raise GCodeError(line, f"H must be a tool number, got {values['H'][1]}", values["H"][1])
                tool = int(h)
            else:
                tool = self.loaded
            if tool and self.tool_lengths and tool not in self.tool_lengths:
                raise GCodeError(line, f"G43 H{tool}: tool {tool} is not in the tool table",
                                 values.get("H", ("", "G43"))[1])
            self.tlo = np.array([0.0, 0.0, self._length(tool) if tool else 0.0])
        else:  # G43.1: dynamic offset from the axis words
            used.update("XYZ")
            tlo = np.zeros(3)
            for a in _AXES:
                if a in values:
                    tlo[_AXES.index(a)] = values[a][0] * self.factor
            self.tlo = tlo

    def _nonmodal(self, line, label, code, word, values, used) -> None:
        f = self.factor
        given = {_AXES.index(a): values[a][0] * f for a in _AXES if a in values}
        if code == 100:
            used.update("LPR")
            if "L" not in values or values["L"][0] not in (2.0, 20.0):
                raise GCodeError(line, "G10 is supported as G10 L2 / G10 L20 (coordinate system offsets); other L "
                                 "forms (tool table, L1/L10/L11) are not", word)
            if "P" not in values or values["P"][0] not in range(0, 10):
                raise GCodeError(line, "G10 L2/L20 needs P0..P9 (0: the current coordinate system)", word)
            p = int(values["P"][0]) or self.cs
            off = self.g5x[p].copy()
            rotation = values["R"][0] if "R" in values else self.rotation[p]
            if values["L"][0] == 2.0:
                for i, v in given.items():
                    off[i] = v
            else:  # L20: the current position becomes the given coordinates in system p (turned by its rotation)
                cs, self.cs = self.cs, p
                saved, self.rotation[p] = self.rotation[p], rotation
                here = self._program_position()
                for i, v in given.items():
                    here[i] = v
                off = self.g5x[p] + self.mpos - self._to_machine(here)
                self.cs, self.rotation[p] = cs, saved
            if not (math.isfinite(rotation) and abs(rotation) <= 360 * 1000):
                raise GCodeError(line, f"G10 R{rotation:g}: the rotation must be a finite angle in degrees",
                                 values["R"][1])
            self._check_position(off, line, f"the G5x offset of system {p}")
            self.g5x[p], self.rotation[p] = off, float(rotation)
        elif code in (280, 300):
            # Through the intermediate point (program coordinates, G90/G91), then the named axes (all when none)
            # to the stored position.
            prog = self._program_position()
            if self.rotation[self.cs] == 0:
                mid = self.mpos.copy()
                for i, v in given.items():
                    mid[i] = (v if self.absolute else prog[i] + v) + self._offset()[i]
            else:
                for i, v in given.items():
                    prog[i] = v if self.absolute else prog[i] + v
                mid = self._to_machine(prog)
            self._emit(Rapid, mid, line, label, origin=word.upper(), skip_zero=True)
            target = self.mpos.copy()
            stored = self.g28 if code == 280 else self.g30
            for i in (given or range(3)):
                target[i] = stored[i]
            self._emit(Rapid, target, line, label, origin=word.upper(), skip_zero=True)
        elif code in (281, 301):
            if given:
                raise GCodeError(line, f"{word} stores the current position and takes no axis words", word)
            (self.g28 if code == 281 else self.g30)[:] = self.mpos
        elif code == 520:  # G52: a local offset, kept in G92's registers (LinuxCNC); the axes not named keep theirs
            for i, v in given.items():
                self.g92[i] = v
            self._check_position(self.g92, line, "the G52 offset")
            self.g92_on, self.g92_saved = True, self.g92.copy()
        elif code == 920:
            if not given:
                raise GCodeError(line, "G92 needs at least one axis word", word)
            base = self._program_position() + self.g92  # where the point is, before any G92 offset
            for i, v in given.items():
                self.g92[i] = base[i] - v
            self._check_position(self.g92, line, "the G92 offset")
            self.g92_on, self.g92_saved = True, self.g92.copy()
        elif given and code in (921, 922, 923):
            raise GCodeError(line, f"{word} takes no axis words", word)
        elif code == 921:
            self.g92, self.g92_saved, self.g92_on = np.zeros(3), np.zeros(3), False
        elif code == 922:
            self.g92, self.g92_on = np.zeros(3), False
        elif code == 923:
            self.g92, self.g92_on = self.g92_saved.copy(), True

    def _motion(self, line, label, values, axes, motion_code, machine, used) -> None:
        motion = self.motion
        cycle = motion in _CYCLES
        arc = motion in (20, 30)
        used.update("XYZ")
        if arc:
            used.update("IJKRP")
        if cycle:
            used.update("RLPQ")
        stray = [values[a][1] for a in ("" if arc else "IJK" if cycle else "IJKR") if a in values]
        if stray:
            raise GCodeError(line, f"{stray[0]} gives an arc centre or radius, but the line is no G2/G3 arc", stray[0])
        arc_words = arc and (any(a in values for a in _OFFSETS) or "R" in values)
        moving = bool(axes) or (motion_code in (20, 30) and arc_words) or (motion_code in _CYCLES)
        if not moving:
            if arc_words:
                raise GCodeError(line, "arc centre or radius words without an axis word or an explicit G2/G3", "G2")
            return
        if motion is None:
            w = next(iter(axes.values()))[1]
            raise GCodeError(line, f"axis word {w} without a motion mode: start with G0, G1, G2 or G3", w)
        if motion == 800:
            raise GCodeError(line, "axis words under G80 (no motion mode): give G0 or G1", next(iter(axes.values()))[1])
        if machine and motion not in (0, 10):
            raise GCodeError(line, "G53 applies to G0 and G1 only", "G53")
        if machine and not self.absolute:
            raise GCodeError(line, "G53 (machine coordinates) needs G90: it is absolute", "G53")
        if cycle:
            from csgnb.apps.gcode_cycles import run_cycle

            run_cycle(self, line, label, motion, values, axes)
            return
        end = self.mpos.copy()
        if machine:
            for a, (v, _) in axes.items():
                end[_AXES.index(a)] = v * self.factor
        elif self.rotation[self.cs] == 0:
            prog = self._program_position()
            off = self._offset()
            for a, (v, _) in axes.items():
                i = _AXES.index(a)
                end[i] = (v * self.factor if self.absolute else prog[i] + v * self.factor) + off[i]
        else:  # a rotated system: the new point in program coordinates, then turned into the machine's
            prog = self._program_position()
            for a, (v, _) in axes.items():
                i = _AXES.index(a)
                prog[i] = v * self.factor if self.absolute else prog[i] + v * self.factor
            end = self._to_machine(prog)
        if motion in (0, 10):
            self.exit_straight = False
        elif self.exit_straight:
            raise GCodeError(line, "the move after G40 (compensation off) must be straight: it leaves the "
                             "compensated path (LinuxCNC)", f"G{motion // 10}")
        if motion == 0:
            self._emit(Rapid, end, line, label, compensate=True)
        elif motion == 10:
            length = float(np.linalg.norm(end - self.mpos))
            self._emit(Linear, end, line, label, feed=self._feed_rate(line, values, length), compensate=True)
        else:
            self._arc(line, label, values, end, motion == 20)

    def _arc(self, line, label, values, end, clockwise) -> None:
        name, (iu, iv), normal_axis, letters = _PLANES[self.plane]
        offsets = {a: values[a] for a in _OFFSETS if a in values}
        radius = values.get("R")
        start = self.mpos
        g = f"G{2 if clockwise else 3}"
        if offsets and radius is not None:
            raise GCodeError(line, "an arc takes either I J K offsets or R, not both", radius[1])
        if not offsets and radius is None:
            raise GCodeError(line, f"a {g} arc needs a centre ({letters[0]} {letters[1]} in the {name} plane) or a "
                             "radius R", g)
        turns = positive_count(values, "P", line, "an arc's P (turns)")
        if self.rotation[self.cs] != 0 and self.plane != 170:
            raise GCodeError(line, f"a G{self.plane // 10} arc in a rotated coordinate system (G10 R) leaves the "
                             "machine's planes; only G17 arcs are supported there", g)
        center = start.copy()
        if offsets:
            for a, (_, w) in offsets.items():
                if a not in letters:
                    raise GCodeError(line, f"{w} is not an offset of the {name} plane (G{self.plane // 10} uses "
                                     f"{letters[0]} and {letters[1]})", w)
            word = next(iter(offsets.values()))[1]
            given_c = np.zeros(3)
            for axis, letter in ((iu, letters[0]), (iv, letters[1])):
                given_c[axis] = offsets.get(letter, (0.0, ""))[0] * self.factor
            if self.arc_absolute:  # G90.1: the centre in program coordinates
                prog_c = self._program_position()
                prog_c[iu], prog_c[iv] = given_c[iu], given_c[iv]
                c_machine = self._to_machine(prog_c)
                center[iu], center[iv] = c_machine[iu], c_machine[iv]
            else:  # the offsets turn with the system
                turned = self._turn(given_c) if self.rotation[self.cs] != 0 else given_c
                center[iu], center[iv] = start[iu] + turned[iu], start[iv] + turned[iv]
            self._check_position(center, line, "the arc's centre")
            r0 = math.hypot(start[iu] - center[iu], start[iv] - center[iv])
            r1 = math.hypot(end[iu] - center[iu], end[iv] - center[iv])
            if min(r0, r1) < ZERO_RADIUS_MM:
                raise GCodeError(line, f"a zero-radius arc: its {'start' if r0 < r1 else 'end'} lies on the centre",
                                 word)
            spiral = SPIRAL_TOLERANCE_INCH * INCH if self.factor == INCH else SPIRAL_TOLERANCE_MM
            err = abs(r1 - r0)
            if err > 100 * spiral or (err > spiral and err > SPIRAL_RELATIVE * max(r0, r1)):
                raise GCodeError(line, f"the end point is {err:.4g} mm off the arc's circle (radius {r0:.6g} mm at "
                                 f"the start, {r1:.6g} mm at the end; LinuxCNC allows {spiral:.4g} mm or 0.1 %)",
                                 word)
        else:
            word = radius[1]
            r = radius[0] * self.factor
            du, dv = end[iu] - start[iu], end[iv] - start[iv]
            c = math.hypot(du, dv)
            if c == 0:
                raise GCodeError(line, "an R-form arc cannot be a full circle (start = end); use I J K offsets", word)
            if r == 0:
                raise GCodeError(line, "an arc radius must not be zero", word)
            if abs(r) > LIMIT_MM:
                raise GCodeError(line, f"the arc radius {abs(r):.6g} mm lies beyond {LIMIT_MM:g} mm", word)
            if abs(r) < c / 2 - max(RADIUS_TOLERANCE_MM, 1e-3 * abs(r)):
                raise GCodeError(line, f"radius {abs(r):.6g} mm is less than half the chord ({c / 2:.6g} mm)", word)
            h = math.sqrt(max(r * r - c * c / 4, 0.0))
            # Counter-clockwise arcs up to 180° have their centre left of the chord; clockwise, right; R < 0 flips.
            side = (1.0 if not clockwise else -1.0) * (1.0 if r > 0 else -1.0)
            center[iu] = start[iu] + du / 2 - side * h * dv / c
            center[iv] = start[iv] + dv / 2 + side * h * du / c
        # The turn, as LinuxCNC's pmCircleInit: the angle from start to end in the direction of travel, in
        # [0, 2π); under CIRCLE_FUZZ it is a full circle; P adds whole turns.
        a0 = math.atan2(start[iv] - center[iv], start[iu] - center[iu])
        a1 = math.atan2(end[iv] - center[iv], end[iu] - center[iu])
        angle = (a0 - a1) if clockwise else (a1 - a0)
        angle %= 2 * math.pi
        if angle < CIRCLE_FUZZ:
            angle = 2 * math.pi
        angle += 2 * math.pi * (turns - 1)
        r = math.hypot(start[iu] - center[iu], start[iv] - center[iv])
        length = math.hypot(r * angle, end[normal_axis] - start[normal_axis])
        feed = self._feed_rate(line, values, length)
        tip_shift = self._tip(np.zeros(3))
        self._emit(Arc, end, line, label, feed=feed, center=center + tip_shift, plane=name, clockwise=clockwise,
                   angle=angle, compensate=True)


def read_text(data: bytes) -> str:
    """G-code file bytes as text: UTF-8 (a byte-order mark is dropped), else Latin-1 (every byte is a character: a
    stray accented byte in a comment does not refuse the file; outside comments it is an error naming its line)."""
    if isinstance(data, str):
        return data.removeprefix("\ufeff")
    if not isinstance(data, bytes | bytearray | memoryview):
        raise TypeError(f"read_text takes the bytes of a G-code file, got {type(data).__name__}")
    data = bytes(data)
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def parse(text: str, *, start=(0.0, 0.0, 0.0), on_unsupported: str = "error", dialect: str = "linuxcnc",
          tool_lengths: dict | None = None, home=None, block_delete: bool | None = None,
          max_loop_passes: int = MAX_LOOP_PASSES, tool_diameters: dict | None = None) -> Program:
    """Run G-code ``text``; return its tool-tip moves in absolute millimetres.

    Parameters
    ----------
    text : str
    start : (3,) float
        The tool tip's position before the program (mm, the stock's frame).
    on_unsupported : {"error", "warn"}
        An unsupported word that cannot change the cut raises :class:`GCodeError`, or is
        skipped, warned about once and counted in :attr:`Program.skipped`. Words that change the
        cut always raise.
    dialect : {"linuxcnc", "grbl"}
        ``"grbl"``: the spindle is taken to run throughout (machines with a hand-switched router;
        no collision for cutting without ``M3``); ``$`` lines other than ``$H``/``$J`` are skipped.
    tool_lengths : dict, optional
        Tool number -> length (mm) for ``G43``; without it every length is 0.
    tool_diameters : dict, optional
        Tool number -> diameter (mm) for cutter radius compensation ``G41``/``G42`` (``D`` names the
        tool; without ``D``, the loaded one); the key ``None`` gives every other tool's diameter.
    home : (3,) float, optional
        The stored ``G28`` / ``G30`` positions (default: ``start``).
    block_delete : bool or None
        Lines starting with ``/`` are skipped (True) or run (False); None: such a line is an error.
    max_loop_passes : int
        Bound on O-word loop passes (an endless loop is an error, not a hang).

    Raises
    ------
    GCodeError
        Naming the 1-based line (and the word) of the first unusable line.
    """
    if not isinstance(text, str):
        raise TypeError(f"parse takes the G-code text (str; parse_file reads a file), got {type(text).__name__}")
    if not isinstance(on_unsupported, str) or on_unsupported not in ("error", "warn"):
        raise CsgnbError(f"on_unsupported must be 'error' or 'warn', got {on_unsupported!r}")
    if not isinstance(dialect, str) or dialect not in ("linuxcnc", "grbl"):
        raise CsgnbError(f"dialect must be 'linuxcnc' or 'grbl', got {dialect!r}")
    for what, v in (("start", start), ("home", home)):
        if v is None and what == "home":
            continue
        try:
            a = np.asarray(v, float)
        except (TypeError, ValueError):
            a = np.full(1, np.nan)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.any(np.abs(a) > LIMIT_MM):
            raise CsgnbError(f"{what} must be three finite coordinates within ±{LIMIT_MM:g} mm, got {v!r:.60}")
    for name, table in (("length", tool_lengths), ("diameter", tool_diameters)):
        if table is not None and not isinstance(table, dict):
            raise TypeError(f"tool_{name}s must be a dict {{tool number: {name} in mm}}, got {type(table).__name__}")
        for k, v in (table or {}).items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and abs(v) <= LIMIT_MM):
                raise CsgnbError(f"tool {k}: the {name} must be a finite number of mm, got {v!r}")
    text = text.removeprefix("\ufeff")
    blocks = []
    skipped_dollar: list[tuple[int, str]] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        stripped = raw.strip()
        if stripped == "%":
            blocks.append(Block(number, percent=True))
            continue
        if stripped.startswith("$") and dialect == "grbl":
            cmd = stripped.split()[0].upper()
            if cmd.startswith(("$H", "$J")):
                raise GCodeError(number, f"unsupported GRBL command {cmd} (homing / jogging moves the machine)", cmd)
            skipped_dollar.append((number, cmd))
            continue
        b = read_block(raw, number)
        if not b.empty or b.delete:
            blocks.append(b)
    interp = _Interpreter(blocks, start=start, on_unsupported=on_unsupported, dialect=dialect,
                          tool_lengths=tool_lengths, home=home, block_delete=block_delete,
                          max_loop_passes=max_loop_passes, tool_diameters=tool_diameters)
    for number, cmd in skipped_dollar:
        interp._skip(number, cmd, "a GRBL system command (settings, status), no motion")
    return interp.run()


def parse_file(path, **kw) -> Program:
    """:func:`parse` the G-code file at ``path`` (UTF-8 with or without a byte-order mark, or Latin-1)."""
    return parse(read_text(Path(path).read_bytes()), **kw)
