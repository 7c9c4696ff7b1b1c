"""Cutter radius compensation ``G41``/``G42`` (``G41.1``/``G42.1``) in the XY plane, as LinuxCNC computes it.

The program describes the part's contour; under compensation the tool's *centre* runs one tool
radius to the left (``G41``) or right (``G42``) of it. The interpreter keeps the *programmed*
position (incremental moves and missing axes refer to it, as in LinuxCNC's ``find_ends``) and
sends each ``G0``/``G1``/``G2``/``G3`` here; this module turns it into the compensated moves.

LinuxCNC's rules (``interp_convert.cc``: ``convert_straight_comp1/2``, ``convert_arc_comp1/2``;
``interp_queue.cc``: ``move_endpoint_and_flush``), which this follows:

* **entry** (the first move after ``G41``/``G42``): a straight move from the current, uncompensated
  point to the programmed end moved one radius to the side of the move's direction; it must be
  longer than the radius. An entry arc ends one radius off its programmed end along the radius
  and turns about the point of the programmed centre line equidistant from its two ends.
* **every later move** ends one radius off its programmed end, on the side, along the normal of
  its direction there (lines: the line's normal; arcs: the radius, so a compensated arc keeps the
  centre and has radius R - r when the tool is inside it, R + r outside; R <= r is an error).
* **corners** between the last move's end and this move's start, by the turn ``beta`` of the
  direction seen from the tool's side (``TOLERANCE_CONCAVE_CORNER`` = 0.05 rad):
  convex (``beta`` > 0.05) -- an arc of radius r about the programmed corner is inserted (a straight
  rapid under ``G0``); concave (``beta`` < -0.05 or > π + 0.05, or a reversal past an arc the tool
  is outside of) -- the last move's end is pulled back to where the two offset paths cross, and a
  move that this would reverse (or an arc it would lengthen) is a gouge: an error naming the line;
  otherwise (tangent) the new move starts where the last one ended.
* moves without XY motion keep the compensated XY and follow when the end before them moves.
* **exit**: ``G40`` leaves the tool where the last compensated move ended; the next move (which must
  be straight) runs from there to its programmed point.

While compensation is on, what would move the tool elsewhere or change the frame (canned cycles,
``G28``/``G30``, ``G53``, ``M6``, units, plane, coordinate systems, ``G92``, ``G10``) is refused, as
LinuxCNC refuses most of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from csgnb.apps.gcode_expr import GCodeError

__all__ = ["CONCAVE_CORNER_RAD", "Compensation"]

CONCAVE_CORNER_RAD = 0.05
"""LinuxCNC's ``TOLERANCE_CONCAVE_CORNER``: turns within ±0.05 rad are tangent (no corner arc, no trimming)."""

_ARC_GOUGE_SLACK = 0.0254
"""LinuxCNC lets a trimmed arc's sweep grow by this (radians, its mm tolerance) before calling it a gouge."""


@dataclass
class _Queued:
    """A compensated move whose end may still move: its programmed XY direction (lines; zero for entry and Z-only
    moves) and, for arcs, the sweep before any trimming."""

    move: object
    direction: np.ndarray
    sweep: float | None = None


def _angle(v) -> float:
    return math.atan2(v[1], v[0])


def _unit(a: float) -> np.ndarray:
    return np.array([math.cos(a), math.sin(a)])


def _sweep(start, end, center, clockwise: bool) -> float:
    """Turn (radians, in [0, 2π)) from ``start`` to ``end`` about ``center`` in the arc's direction."""
    a0, a1 = _angle(start - center), _angle(end - center)
    return ((a0 - a1) if clockwise else (a1 - a0)) % (2 * math.pi)


class Compensation:
    """The state of one ``G41``/``G42`` span: side, radius, the programmed point and the moves still open.

    Parameters
    ----------
    left : bool
        ``G41`` (tool left of the path) or ``G42``.
    radius : float
        Tool radius in mm (> 0).
    word : str
        The word that turned it on (for messages).
    """

    def __init__(self, left: bool, radius: float, word: str) -> None:
        self.left, self.radius, self.word = left, radius, word
        self.first = True
        self.queue: list[_Queued] = []
        self.programmed: np.ndarray | None = None  # (2,) the last programmed XY end

    # -- geometry --------------------------------------------------------------------------------------------
    @property
    def _gamma(self) -> float:
        return math.pi / 2 if self.left else -math.pi / 2

    def _tool_inside(self, clockwise: bool) -> bool:
        return self.left != clockwise  # LinuxCNC's TOOL_INSIDE_ARC: left of a CCW arc, right of a CW one

    def _current(self) -> np.ndarray:
        return np.asarray(self.queue[-1].move.end[:2], float)

    def _beta(self, alpha: float) -> float:
        """The corner's turn seen from the tool's side, in [-π/2, 3π/2) (LinuxCNC's beta)."""
        theta = _angle(self._current() - self.programmed)
        beta = (theta - alpha if self.left else alpha - theta) - math.pi / 2
        return (beta + math.pi / 2) % (2 * math.pi) - math.pi / 2

    # -- the queue -------------------------------------------------------------------------------------------
    def _flush(self, it) -> None:
        it.moves.extend(q.move for q in self.queue)
        self.queue = []

    def _move_end(self, it, xy: np.ndarray, line: int) -> None:
        """Pull the end of the queued moves to ``xy`` (a concave corner), refusing a gouge, then flush them."""
        for i, q in enumerate(self.queue):
            m = q.move
            end = m.end.copy()
            end[:2] = xy
            if m.kind == "arc":
                centre = m.center[:2]
                whole = 2 * math.pi * (math.ceil(q.sweep / (2 * math.pi)) - 1)  # turns beyond the first (P > 1)
                new = _sweep(m.start[:2], xy, centre, m.clockwise) + whole
                if new > q.sweep + _ARC_GOUGE_SLACK:
                    raise GCodeError(line, "cutter compensation: the arc before this move (line "
                                     f"{m.line}) cannot reach the concave corner without gouging: the tool is "
                                     "too large for the corner (use a smaller tool or change the contour)",
                                     self.word)
                self.queue[i] = replace(q, move=replace(m, end=end, angle=new))
            else:
                if float(q.direction @ (xy - self.queue[0].move.start[:2])) < 0:  # from where the queue begins
                    raise GCodeError(line, "cutter compensation: the straight move on line "
                                     f"{m.line} cannot reach the concave corner without gouging: it is shorter than "
                                     "the tool needs to turn there (use a smaller tool or change the contour)",
                                     self.word)
                start = m.start.copy()
                if i > 0:  # a move without XY motion after the trimmed one follows it
                    start[:2] = xy
                self.queue[i] = replace(q, move=replace(m, start=start, end=end))
        self._flush(it)

    def _gouge(self, line: int, what: str) -> GCodeError:
        return GCodeError(line, f"cutter compensation: {what} (use a smaller tool or change the contour)", self.word)

    def _concave(self, it, new: dict, beta: float, line: int) -> np.ndarray:
        """Trim at a concave corner: the point where the queued XY move's offset path meets the new move's, chosen as
        LinuxCNC chooses it for each pair of a line and an arc; the queued moves end there and are flushed."""
        prev = self.queue[0].move
        here, corner, r = self._current(), self.programmed, self.radius
        normal = _angle(here - corner)  # the tool's side of the last move, at its end
        if prev.kind != "arc" and new["kind"] == "line":
            half = (beta + math.pi) / 2
            if math.tan(half) == 0:
                raise self._gouge(line, "a zero-degree inside corner")
            xy = here + (r / math.tan(half)) * _unit(normal + self._gamma)  # back along the last offset line
        elif prev.kind == "arc" and new["kind"] == "line":
            pc, ccw = np.asarray(prev.center[:2], float), not prev.clockwise
            old = float(np.linalg.norm(prev.end[:2] - pc))
            inside = self._tool_inside(prev.clockwise)
            theta = new["direction"] + (math.pi / 2 if ccw else -math.pi / 2)
            d = (old + r if inside else old - r) * math.cos(theta - _angle(pc - corner))
            ratio = (d - r if inside else d + r) / old
            if not -1 <= ratio <= 1:
                raise self._gouge(line, "the arc before this line makes a corner the tool cannot fit in without "
                                  "gouging")
            turn = math.acos(ratio)
            sign = (-1 if ccw else 1) if inside else (1 if ccw else -1)
            xy = pc + old * _unit(sign * turn + theta + math.pi)
        elif prev.kind != "arc":  # line -> arc
            c, big, ccw, inside = new["center"], new["radius"], new["ccw"], new["inside"]
            tangent = normal - self._gamma
            cy = big * math.sin(beta - math.pi / 2)
            dist = big - r if inside else big + r
            ratio = (cy + r if inside else cy - r) / dist
            if not -1 <= ratio <= 1:
                raise self._gouge(line, "the arc after this corner cannot be reached by the tool without gouging")
            turn = math.asin(ratio)
            if inside:
                ang = tangent + turn if ccw else tangent - turn
            else:
                ang = tangent + math.pi - turn if ccw else tangent + math.pi + turn
            xy = c + dist * _unit(ang)
        else:  # arc -> arc
            pc = np.asarray(prev.center[:2], float)
            old = float(np.linalg.norm(prev.end[:2] - pc))
            c, big, ccw = new["center"], new["radius"], new["ccw"]
            newrad = big - r if new["inside"] else big + r
            apart = float(np.linalg.norm(pc - c))
            if old == 0 or apart == 0:
                raise self._gouge(line, "two arcs about the same centre meet in a corner")
            a = (old * old + apart * apart - newrad * newrad) / (2 * old * apart)
            if not -1 <= a <= 1:
                raise self._gouge(line, "two arcs make a corner the tool cannot fit in without gouging")
            pullback = math.acos(a)
            toward = _angle(c - pc)
            sign = (1 if ccw else -1) if self._tool_inside(prev.clockwise) else (-1 if ccw else 1)
            xy = pc + old * _unit(toward + sign * pullback)
        self._move_end(it, xy, line)
        return xy

    def _corner(self, it, alpha: float, mid: np.ndarray, new: dict, rapid: bool, template, line: int) -> np.ndarray:
        """Join the queued moves to a new XY move that starts along ``alpha`` at ``mid``; return where it starts."""
        beta = self._beta(alpha)
        small = CONCAVE_CORNER_RAD
        last = self.queue[0].move
        if new["kind"] == "arc":  # atop an "m" or an "h": a reversal onto an arc the tool is outside of
            reversal = abs(beta - math.pi) < small and not new["inside"]
        else:  # a reversal off an arc the tool is outside of
            reversal = beta > math.pi - small and last.kind == "arc" and not self._tool_inside(last.clockwise)
        if beta < -small or beta > math.pi + small or reversal:
            return self._concave(it, new, beta, line)
        here = self._current()
        self._flush(it)
        if beta > small:  # convex: round the corner about the programmed point (a straight rapid under G0)
            z = last.end[2]
            corner = np.array([*self.programmed, z])
            start, end = np.array([*here, z]), np.array([*mid, z])
            if rapid:
                it.moves.append(replace(template, start=start, end=end))
            else:
                from csgnb.apps.gcode import Arc

                clockwise = self.left
                sweep = _sweep(here, mid, self.programmed, clockwise)
                fields = {k: getattr(template, k) for k in ("feed", "spindle", "spindle_on", "tool", "line", "label")}
                it.moves.append(Arc(start=start, end=end, center=corner, plane="XY", clockwise=clockwise,
                                    angle=sweep, origin=f"{self.word} corner", **fields))
            return mid
        return here

    # -- moves -----------------------------------------------------------------------------------------------
    def straight(self, it, move, programmed_start: np.ndarray, programmed_end: np.ndarray, line: int) -> None:
        """Compensate the straight move ``move`` (a Rapid or Linear in tip coordinates, uncompensated XY)."""
        p0, p1 = np.asarray(programmed_start[:2], float), np.asarray(programmed_end[:2], float)
        rapid = move.kind == "rapid"
        if self.first:
            here = np.asarray(move.start[:2], float)
            distance = float(np.hypot(*(p1 - here)))
            if not distance > self.radius:
                raise GCodeError(line, f"cutter compensation: the entry move after {self.word} is {distance:.6g} mm "
                                 f"long in XY, not longer than the tool radius {self.radius:g} mm: start the "
                                 "compensated contour from farther away", self.word)
            alpha = _angle(p1 - here) + self._gamma
            end = move.end.copy()
            end[:2] = p1 + self.radius * _unit(alpha)
            self.queue = [_Queued(replace(move, end=end), np.zeros(2))]
            self.first = False
        elif np.array_equal(p0, p1):  # no XY motion: stay at the compensated XY
            here = self._current()
            start, end = move.start.copy(), move.end.copy()
            start[:2], end[:2] = here, here
            self.queue.append(_Queued(replace(move, start=start, end=end), np.zeros(2)))
        else:
            alpha = _angle(p1 - p0)
            normal = _unit(alpha + self._gamma)
            mid = p0 + self.radius * normal
            begin = self._corner(it, alpha, mid, {"kind": "line", "direction": alpha}, rapid, move, line)
            start, end = move.start.copy(), move.end.copy()
            start[:2], end[:2] = begin, p1 + self.radius * normal
            self.queue = [_Queued(replace(move, start=start, end=end), p1 - p0)]
        self.programmed = p1

    def arc(self, it, move, programmed_start: np.ndarray, line: int) -> None:
        """Compensate the arc ``move`` (an Arc in tip coordinates about its programmed centre, uncompensated)."""
        c = np.asarray(move.center[:2], float)
        p0, p1 = np.asarray(programmed_start[:2], float), np.asarray(move.end[:2], float)
        big = float(np.hypot(*(p1 - c)))
        inside = self._tool_inside(move.clockwise)
        if inside and not big > self.radius:
            raise GCodeError(line, f"cutter compensation: the tool radius {self.radius:g} mm is not less than the "
                             f"arc's radius {big:.6g} mm, and the tool runs inside it", self.word)
        toward = (c - p1) / big if inside else (p1 - c) / big
        end_xy = p1 + self.radius * toward
        if self.first:
            here = np.asarray(move.start[:2], float)
            if not float(np.hypot(*(p1 - here))) > self.radius:
                raise GCodeError(line, "cutter compensation: the entry arc's chord is not longer than the tool radius",
                                 self.word)
            # The centre on the line from the compensated end toward the programmed centre, as far from both ends.
            u = (c - end_xy) / np.linalg.norm(c - end_xy)
            w = here - end_xy
            den = 2 * float(u @ w)
            if abs(den) < 1e-12 * max(1.0, float(w @ w)):
                raise GCodeError(line, "cutter compensation: no arc from the start reaches the compensated end of this "
                                 "entry arc (the tool radius is not less than the arc radius)", self.word)
            centre = end_xy + (float(w @ w) / den) * u
            start, end = move.start.copy(), move.end.copy()
            end[:2] = end_xy
            new_centre = move.center.copy()
            new_centre[:2] = centre
            sweep = _sweep(here, end_xy, centre, move.clockwise) + (move.angle - _sweep(p0, p1, c, move.clockwise))
            if not sweep > 0:
                sweep += 2 * math.pi
            self.queue = [_Queued(replace(move, start=start, end=end, center=new_centre, angle=sweep), np.zeros(2),
                                  sweep)]
            self.first = False
            self.programmed = p1
            return
        radial0 = (p0 - c) / float(np.hypot(*(p0 - c)))
        tangent = np.array([radial0[1], -radial0[0]]) if move.clockwise else np.array([-radial0[1], radial0[0]])
        alpha = _angle(tangent)
        mid = p0 + self.radius * (-radial0 if inside else radial0)
        new = {"kind": "arc", "center": c, "radius": big, "ccw": not move.clockwise, "inside": inside}
        begin = self._corner(it, alpha, mid, new, False, move, line)
        start, end = move.start.copy(), move.end.copy()
        start[:2], end[:2] = begin, end_xy
        # The programmed turn, less what the start moved on and plus what the end moved on (full circles stay full).
        moved = (_angle(begin - c) - _angle(mid - c) + math.pi) % (2 * math.pi) - math.pi
        sweep = move.angle - (moved if not move.clockwise else -moved)
        self.queue = [_Queued(replace(move, start=start, end=end, angle=sweep), np.zeros(2), sweep)]
        self.programmed = p1

    def finish(self, it) -> np.ndarray | None:
        """``G40`` or the program's end: the queued moves as they are; the XY where the tool stands (None if no
        compensated move ran)."""
        if self.first:
            return None
        here = self._current()
        self._flush(it)
        return here
