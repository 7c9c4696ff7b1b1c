"""Canned drilling cycles G81 G82 G83 G73 G84 G85 G86 G89 as straight moves, in the G17 / G18 / G19 planes (LinuxCNC).

The drill axis is the plane's normal (Z for G17, Y for G18, X for G19), "up" its positive
direction. Per hole (``L`` repeats; under G91 the plane position steps by the increment each
time): if the tool is below the retract plane ``R`` it first rises to it, then a rapid to the
hole's position, a rapid down to ``R``, the cycle's cutting moves, and the retract to ``R``
(``G99``) or to the higher of ``R`` and the initial level (``G98``): where the tool stood when the
cycle mode began, kept while the same cycle repeats (LinuxCNC's ``cycle_il``). Under G91, ``R`` is
measured from the initial level and the bottom from ``R``. ``R``, the bottom, ``Q`` and
``P`` are sticky while cycles follow one another.

* G81 feed to the bottom; G82 the same and a dwell ``P`` (s);
* G83 peck: feed ``Q`` deeper, rapid out to ``R``, rapid back in to 0.254 mm above the last depth,
  and on; G73 chip break: the same with a 0.254 mm back-off instead of the retract to ``R``;
* G85 feed in and feed out to ``R``; G89 the same with a dwell at the bottom; G84 (right-hand
  tapping) the same path: the tap feeds in synchronised with the spindle, which reverses, and
  feeds out -- the swept volume is G85's (the thread itself is not modelled: the tap is its
  envelope);
* G86 (boring, spindle stop at the bottom, rapid out): G82's path (dwell ``P``, rapid out).
"""

from __future__ import annotations

import numpy as np

from csgnb.apps.gcode_expr import GCodeError, positive_count

__all__ = ["run_cycle"]


def run_cycle(it, line: int, label, code: int, values: dict, axes: dict) -> None:
    """Append the moves of one canned-cycle line to the interpreter ``it`` (a ``csgnb.apps.gcode._Interpreter``)."""
    from csgnb.apps.gcode import _PLANES, RAPID_DELTA_MM, Linear, Rapid

    word = f"G{code // 10}"
    if it.feed_mode == 930:
        raise GCodeError(line, f"{word}: canned cycles cannot run under G93 (inverse time feed); give G94", word)
    _, (iu, iv), a, _ = _PLANES[it.plane]
    f = it.factor
    letter = "XYZ"[a]
    old = it._program_position()
    if "R" in values:
        it.cycle["r"] = values["R"][0] * f
    if "r" not in it.cycle:
        raise GCodeError(line, f"{word} needs a retract plane R", word)
    # The initial level: where the normal axis stood when this cycle mode began (LinuxCNC's cycle_il); it stays while
    # the same cycle repeats, so G98 returns there and an incremental R counts from it, hole after hole
    if it.cycle.get("il_code") != code:
        it.cycle["il"], it.cycle["il_code"] = old[a], code
    initial = it.cycle["il"]
    r = it.cycle["r"] if it.absolute else initial + it.cycle["r"]
    if letter in axes:
        it.cycle["z"] = axes[letter][0] * f
    if "z" not in it.cycle:
        raise GCodeError(line, f"{word} needs the hole's bottom {letter} (the plane's normal axis)", word)
    bottom = it.cycle["z"] if it.absolute else r + it.cycle["z"]
    if bottom > r:
        raise GCodeError(line, f"{word}: the bottom {letter}{bottom / f:g} lies above the retract plane R{r / f:g}",
                         word)
    if code in (830, 730):
        if "Q" in values:
            it.cycle["q"] = values["Q"][0] * f
        if not it.cycle.get("q", 0) > 0:
            raise GCodeError(line, f"{word} needs a positive peck depth Q", values.get("Q", (0, word))[1])
    if code in (820, 860, 890):
        if "P" in values:
            if values["P"][0] < 0:
                raise GCodeError(line, f"{word}: the dwell P must not be negative", values["P"][1])
            it.cycle["p"] = values["P"][0]
    repeats = positive_count(values, "L", line, f"{word}: L (repeats)")
    clear = r if it.retract_r else max(initial, r)
    increments = {i: axes["XYZ"[i]][0] * f for i in (iu, iv) if "XYZ"[i] in axes}

    def go(cls, axis: int, value: float) -> None:
        target = it._program_position()
        target[axis] = value
        end = it._to_machine(target)
        feed = None
        if cls is Linear:
            feed = it._feed_rate(line, values, float(np.linalg.norm(end - it.mpos)))
        it._emit(cls, end, line, label, feed=feed, origin=word, skip_zero=True)

    for _ in range(repeats):
        cur = it._program_position()
        if cur[a] < r:
            go(Rapid, a, r)
        target = it._program_position()
        for i in (iu, iv):
            if i in increments:
                target[i] = increments[i] if it.absolute else cur[i] + increments[i]
        it._emit(Rapid, it._to_machine(target), line, label, origin=word, skip_zero=True)
        go(Rapid, a, r)
        if code in (830, 730):
            q = it.cycle["q"]
            depth = r - q
            while depth > bottom:
                go(Linear, a, depth)
                if code == 830:
                    go(Rapid, a, r)
                go(Rapid, a, depth + RAPID_DELTA_MM)
                depth -= q
        go(Linear, a, bottom)
        if code in (820, 860, 890):
            it.dwell += it.cycle.get("p", 0.0)
        if code in (840, 850, 890):
            go(Linear, a, r)
        go(Rapid, a, clear)
