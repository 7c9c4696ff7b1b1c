"""A G-code parser for the subset 3-axis milling programs use, into typed moves in absolute millimetres.

Supported (RS274/NGC semantics, as LinuxCNC reads them):

* motion ``G0`` (rapid), ``G1`` (linear), ``G2``/``G3`` (clockwise / counter-clockwise arcs,
  helical when the axis normal to the plane moves) in the centre form (``I J K``, offsets
  from the start point) and the radius form (``R``; negative for arcs over 180°);
* planes ``G17`` (XY, offsets I J), ``G18`` (ZX, offsets K I), ``G19`` (YZ, offsets J K); a
  clockwise arc turns clockwise seen from the plane normal's positive end (+Z, +Y, +X);
* units ``G20`` (inch) / ``G21`` (mm), distance ``G90`` (absolute) / ``G91`` (incremental; arc
  offsets are always incremental);
* ``F`` (feed, units per minute), ``S`` (spindle speed), ``T`` with ``M6`` (tool change),
  ``M3``/``M4``/``M5`` (spindle on / on reversed / stop), ``M2``/``M30`` (end of program);
* comments ``( ... )`` and ``; ...``, line numbers ``N``, ``%`` tape marks;
* codes that only restate the state this simulation assumes are accepted as no-ops:
  ``G94`` (feed per minute), ``G40`` (no cutter compensation), ``G49`` (no tool length
  offset), ``G80`` (no canned cycle), ``G54`` (the one work coordinate system), and coolant
  ``M7``/``M8``/``M9``.

Anything else is an **unsupported word**: a :class:`GCodeError` naming the line and the
word, or -- with ``on_unsupported="warn"`` -- a warning and the word skipped. A malformed
line (text that is not a word, a word given twice, two motions on one line, an arc without
centre or radius, a feed move without a feed rate, an arc whose end is not on its circle)
is always an error with its line number.

Within a line the RS274/NGC order applies: F, S, T, M6, spindle, plane, units,
distance mode, then the motion, so ``G20 G91 X1`` moves one inch incrementally. A feed
rate is a number read in the units in force at each move (``F`` is inches per minute
under G20), as LinuxCNC does.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from csgnb.apps.sweep import arc_polyline

__all__ = ["Arc", "GCodeError", "Linear", "Move", "Program", "Rapid", "parse", "parse_file"]

INCH = 25.4
"""Millimetres per inch (G20)."""

RADIUS_TOLERANCE_MM = 0.002
"""An arc's end may be this far (or 0.1 % of the radius, whichever is larger) off its circle."""

_NO_OP_G = {94.0: "feed per minute", 40.0: "cutter compensation off", 49.0: "tool length offset off",
            80.0: "canned cycle off", 54.0: "work coordinate system 1"}
_NO_OP_M = {7.0: "mist coolant", 8.0: "flood coolant", 9.0: "coolant off"}
_PLANES = {17.0: ("XY", (0, 1), 2, "IJ"), 18.0: ("ZX", (2, 0), 1, "KI"), 19.0: ("YZ", (1, 2), 0, "JK")}
_AXES = "XYZ"
_OFFSETS = "IJK"
_WORD = re.compile(r"([A-Za-z])([+-]?(?:\d+\.?\d*|\.\d+))")


class GCodeError(ValueError):
    """A G-code line could not be used; ``line`` is its 1-based number, ``word`` the offending word (if one)."""

    def __init__(self, line: int, message: str, word: str | None = None) -> None:
        self.line = line
        self.word = word
        super().__init__(f"line {line}: {message}")


@dataclass(frozen=True)
class Move:
    """A motion of the tool tip from ``start`` to ``end`` (absolute mm).

    Attributes
    ----------
    start, end : (3,) float64
    feed : float or None
        Feed rate in mm/min (None for rapids).
    spindle : float
        Spindle speed (the last ``S``).
    spindle_on : bool
        Whether ``M3``/``M4`` is in effect.
    tool : int or None
        The tool loaded by the last ``M6`` (None before any).
    line : int
        1-based source line.
    label : int or None
        The line's ``N`` number.
    """

    start: np.ndarray
    end: np.ndarray
    feed: float | None
    spindle: float
    spindle_on: bool
    tool: int | None
    line: int
    label: int | None

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
    """``G2``/``G3``: a circular (helical) cut about ``center`` in ``plane`` ('XY', 'ZX' or 'YZ')."""

    center: np.ndarray = field(default=None)
    plane: str = "XY"
    clockwise: bool = True

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
        """Points along the arc with every chord within ``tolerance`` mm of it (:func:`arc_polyline`)."""
        return arc_polyline(self.start, self.end, self.center, self.normal, self.clockwise, tolerance=tolerance)


@dataclass
class Program:
    """A parsed program: its moves, the warnings for skipped words, and where it ended."""

    moves: list[Move]
    warnings: list[str]
    end_line: int | None  # the M2/M30 line, if any

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


def _strip_comments(text: str, line: int) -> str:
    out = []
    depth = False
    for ch in text:
        if depth:
            if ch == "(":
                raise GCodeError(line, "a comment opens inside a comment '(' ... '(' (nested comments are not G-code)")
            if ch == ")":
                depth = False
            continue
        if ch == "(":
            depth = True
        elif ch == ";":
            break
        elif ch == ")":
            raise GCodeError(line, "a ')' closes no comment")
        else:
            out.append(ch)
    if depth:
        raise GCodeError(line, "a comment '(' is not closed on its line")
    return "".join(out)


def _words(code: str, line: int) -> list[tuple[str, float, str]]:
    """(letter, value, text) of each word of a comment-free line; anything else is an error."""
    s = re.sub(r"\s+", "", code)
    words, pos = [], 0
    while pos < len(s):
        m = _WORD.match(s, pos)
        if m is None:
            bad = s[pos:pos + 12]
            raise GCodeError(line, f"cannot read {bad!r}: every word is a letter followed by a number (e.g. X1.5)",
                             bad)
        words.append((m.group(1).upper(), float(m.group(2)), m.group(1).upper() + m.group(2)))
        pos = m.end()
    return words


def parse(text: str, *, start=(0.0, 0.0, 0.0), on_unsupported: str = "error") -> Program:
    """Parse G-code ``text`` into typed moves in absolute millimetres.

    Parameters
    ----------
    text : str
    start : (3,) float
        The tool tip's position before the program (mm).
    on_unsupported : {"error", "warn"}
        An unsupported word raises :class:`GCodeError`, or is skipped with a warning.

    Raises
    ------
    GCodeError
        Naming the 1-based line (and the word) of the first unusable line.
    """
    if on_unsupported not in ("error", "warn"):
        raise ValueError(f"on_unsupported must be 'error' or 'warn', got {on_unsupported!r}")
    pos = np.asarray(start, float).reshape(3).copy()
    factor, absolute, plane = 1.0, True, 17.0
    motion: float | None = None
    feed: float | None = None
    spindle, spindle_on = 0.0, False
    selected: int | None = None
    loaded: int | None = None
    moves: list[Move] = []
    notes: list[str] = []

    def unsupported(line: int, word: str, why: str) -> None:
        msg = f"unsupported word {word} ({why})"
        if on_unsupported == "error":
            raise GCodeError(line, msg + "; remove it, or parse with on_unsupported='warn' to skip it", word)
        note = f"line {line}: {msg}: skipped"
        notes.append(note)
        warnings.warn(note, stacklevel=3)

    for number, raw in enumerate(text.splitlines(), start=1):
        code = _strip_comments(raw, number).strip()
        if code in ("", "%"):
            continue
        if code.startswith("/"):
            unsupported(number, "/", "block delete")
            continue
        words = _words(code, number)
        g_codes, m_codes, values = [], [], {}
        label = None
        for letter, value, text_word in words:
            if letter == "G":
                g_codes.append((value, text_word))
            elif letter == "M":
                m_codes.append((value, text_word))
            elif letter in "XYZIJKRFSTN":
                if letter in values or (letter == "N" and label is not None):
                    raise GCodeError(number, f"the word {letter} appears twice", text_word)
                if letter == "N":
                    if value != int(value) or value < 0:
                        raise GCodeError(number, f"a line number must be a non-negative integer, got {text_word}",
                                         text_word)
                    label = int(value)
                else:
                    values[letter] = (value, text_word)
            else:
                unsupported(number, text_word, f"the letter {letter} is not part of the supported subset")
        # -- classify the G and M codes ---------------------------------------------------
        line_motion = None
        line_plane = line_units = line_distance = None
        for value, w in g_codes:
            if value in (0.0, 1.0, 2.0, 3.0):
                if line_motion is not None:
                    raise GCodeError(number, f"two motion codes on one line ({line_motion[1]} and {w})", w)
                line_motion = (value, w)
            elif value in _PLANES:
                line_plane = value
            elif value in (20.0, 21.0):
                line_units = value
            elif value in (90.0, 91.0):
                line_distance = value
            elif value in _NO_OP_G:
                pass
            else:
                unsupported(number, w, "not in G0-G3, G17-G19, G20/G21, G90/G91, G40, G49, G54, G80, G94")
        change_tool = False
        spindle_word = None
        end_program = False
        for value, w in m_codes:
            if value == 6.0:
                change_tool = True
            elif value in (3.0, 4.0, 5.0):
                if spindle_word is not None:
                    raise GCodeError(number, f"two spindle codes on one line ({spindle_word} and {w})", w)
                spindle_word = w
                spindle_on = value != 5.0
            elif value in (2.0, 30.0):
                end_program = True
            elif value in _NO_OP_M:
                pass
            else:
                unsupported(number, w, "not in M2, M3, M4, M5, M6, M7, M8, M9, M30")
        # -- modal state, in RS274/NGC order ------------------------------------------------
        if line_units is not None:
            factor = INCH if line_units == 20.0 else 1.0
        if "F" in values:
            f = values["F"][0]
            if f < 0:
                raise GCodeError(number, f"a feed rate must not be negative, got {values['F'][1]}", values["F"][1])
            feed = f  # in the units in force at each move (LinuxCNC keeps F as a number, like this)
        if "S" in values:
            if values["S"][0] < 0:
                raise GCodeError(number, f"a spindle speed must not be negative, got {values['S'][1]}",
                                 values["S"][1])
            spindle = values["S"][0]
        if "T" in values:
            t = values["T"][0]
            if t != int(t) or t < 0:
                raise GCodeError(number, f"a tool number must be a non-negative integer, got {values['T'][1]}",
                                 values["T"][1])
            selected = int(t)
        if change_tool:
            if selected is None:
                raise GCodeError(number, "M6 changes to the selected tool, but no T word selected one", "M6")
            loaded = selected
        if line_plane is not None:
            plane = line_plane
        if line_distance is not None:
            absolute = line_distance == 90.0
        if line_motion is not None:
            motion = line_motion[0]
        # -- the motion --------------------------------------------------------------------
        axes = {a: values[a] for a in _AXES if a in values}
        offsets = {a: values[a] for a in _OFFSETS if a in values}
        radius = values.get("R")
        moving = bool(axes) or (line_motion is not None and line_motion[0] in (2.0, 3.0) and (offsets or radius))
        if (offsets or radius) and (motion not in (2.0, 3.0) or not moving):
            w = (next(iter(offsets.values())) if offsets else radius)[1]
            raise GCodeError(number, f"{w} gives an arc centre or radius, but the line is no G2/G3 arc", w)
        if moving:
            if motion is None:
                w = next(iter(axes.values()))[1]
                raise GCodeError(number, f"axis word {w} without a motion mode: start with G0, G1, G2 or G3", w)
            end = pos.copy()
            for a, (v, _) in axes.items():
                i = _AXES.index(a)
                end[i] = v * factor if absolute else pos[i] + v * factor
            common = dict(start=pos.copy(), end=end, spindle=spindle, spindle_on=spindle_on, tool=loaded,
                          line=number, label=label)
            if motion == 0.0:
                moves.append(Rapid(feed=None, **common))
            else:
                if not feed:
                    raise GCodeError(number, "a feed move (G1/G2/G3) needs a positive feed rate: give an F word", "F")
                if motion == 1.0:
                    moves.append(Linear(feed=feed * factor, **common))
                else:
                    moves.append(_arc(number, common, feed * factor, plane, motion == 2.0, offsets, radius, factor))
            pos = end
        if end_program:
            return Program(moves, notes, number)
    return Program(moves, notes, None)


def _arc(number: int, common: dict, feed: float, plane: float, clockwise: bool, offsets: dict, radius,
         factor: float) -> Arc:
    """The arc of one G2/G3 line: centre from I J K offsets or from R, the end checked on the circle."""
    name, (iu, iv), _, letters = _PLANES[plane]
    start, end = common["start"], common["end"]
    if offsets and radius is not None:
        raise GCodeError(number, "an arc takes either I J K offsets or R, not both", radius[1])
    if not offsets and radius is None:
        raise GCodeError(number, f"a G{2 if clockwise else 3} arc needs a centre ({letters[0]} {letters[1]} in the "
                         f"{name} plane) or a radius R", f"G{2 if clockwise else 3}")
    center = start.copy()
    if offsets:
        for a, (_, w) in offsets.items():
            if a not in letters:
                raise GCodeError(number, f"{w} is not an offset of the {name} plane (G{int(plane)} uses "
                                 f"{letters[0]} and {letters[1]})", w)
        center[iu] = start[iu] + offsets.get(letters[0], (0.0, ""))[0] * factor
        center[iv] = start[iv] + offsets.get(letters[1], (0.0, ""))[0] * factor
        r0 = math.hypot(start[iu] - center[iu], start[iv] - center[iv])
        r1 = math.hypot(end[iu] - center[iu], end[iv] - center[iv])
        if r0 == 0:
            raise GCodeError(number, "the arc centre is the start point (zero radius)", next(iter(offsets.values()))[1])
        if abs(r1 - r0) > max(RADIUS_TOLERANCE_MM, 1e-3 * r0):
            raise GCodeError(number, f"the end point is {abs(r1 - r0):.4g} mm off the arc's circle (radius {r0:.6g} mm "
                             f"at the start, {r1:.6g} mm at the end)", next(iter(offsets.values()))[1])
    else:
        r = radius[0] * factor
        du, dv = end[iu] - start[iu], end[iv] - start[iv]
        c = math.hypot(du, dv)
        if c == 0:
            raise GCodeError(number, "an R-form arc cannot be a full circle (start = end); use I J K offsets",
                             radius[1])
        if r == 0:
            raise GCodeError(number, "an arc radius must not be zero", radius[1])
        if abs(r) < c / 2 - max(RADIUS_TOLERANCE_MM, 1e-3 * abs(r)):
            raise GCodeError(number, f"radius {abs(r):.6g} mm is less than half the chord ({c / 2:.6g} mm)", radius[1])
        h = math.sqrt(max(r * r - c * c / 4, 0.0))
        # Counter-clockwise arcs up to 180° have their centre left of the chord; clockwise, right; R < 0 flips.
        side = (1.0 if not clockwise else -1.0) * (1.0 if r > 0 else -1.0)
        center[iu] = start[iu] + du / 2 - side * h * dv / c
        center[iv] = start[iv] + dv / 2 + side * h * du / c
    return Arc(feed=feed, center=center, plane=name, clockwise=clockwise, **common)


def parse_file(path, **kw) -> Program:
    """:func:`parse` the G-code file at ``path`` (UTF-8 or ASCII)."""
    return parse(Path(path).read_text(encoding="utf-8", errors="strict"), **kw)
