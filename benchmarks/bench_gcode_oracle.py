"""csgnb's G-code interpreter against LinuxCNC's own: its regression tests' canonical output as the oracle.

    python benchmarks/bench_gcode_oracle.py DIR [--json PATH] [--tool-diameter MM]

LinuxCNC's source tree keeps, under ``tests/interp/``, one folder per interpreter test with a
program (``test.ngc`` or another ``.ngc``) and ``expected``: what LinuxCNC's interpreter printed for
it, one canonical machining call a line (``STRAIGHT_TRAVERSE(x, y, z, a, b, c)``,
``STRAIGHT_FEED(...)``, ``ARC_FEED(first_end, second_end, first_axis, second_axis, rotation,
axis_end, a, b, c)``, ``SET_G5X_OFFSET``, ``USE_LENGTH_UNITS``, ...) with 4 decimals. Those files
are GPL-2.0 and are not committed here: fetch the folders (e.g. to ``/tmp/linuxcnc_interp``) and
point this script at them. For every folder, csgnb's moves (:func:`csgnb.apps.gcode.parse`, start
at the origin) are compared move by move with LinuxCNC's, in machine coordinates (the canonical
positions plus the G5x, G92 and tool length offsets LinuxCNC reported), within the printed
precision (1e-4 of the program's unit). Each folder ends as

* **agree**: the same moves, in order;
* **differ**: the first move that differs (or a count mismatch), with both sides;
* **refused**: csgnb raised a :class:`~csgnb.apps.gcode.GCodeError` (the message says why);
* **skipped**: LinuxCNC's output holds calls csgnb does not simulate (probing, tapping, other axes);
* **crash**: any other exception (a bug).

``--json PATH`` writes ``{"folders": {NAME: {"status", ...}}, "counts": {...}}``.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import warnings
from pathlib import Path

import numpy as np

from csgnb.apps.gcode import INCH, GCodeError, parse, read_text

_CALL = re.compile(r"^\s*N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")
_MOVES = {"STRAIGHT_TRAVERSE": "rapid", "STRAIGHT_FEED": "linear", "ARC_FEED": "arc"}
_UNSIMULATED = {"STRAIGHT_PROBE", "RIGID_TAP", "START_SPEED_FEED_SYNCH", "NURBS_FEED", "SPLINE_FEED"}
_PLANE_AXES = {"CANON_PLANE_XY": (0, 1, 2), "CANON_PLANE_XZ": (2, 0, 1), "CANON_PLANE_YZ": (1, 2, 0)}


def _numbers(args: str) -> list[float]:
    return [float(v) for v in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", args)]


def expected_moves(text: str) -> tuple[list[dict], str | None]:
    """LinuxCNC's canonical output as moves ``{"kind", "end", "center", "ccw", "turns"}`` in machine mm; the second
    item names a call csgnb does not simulate (None when there is none)."""
    factor, plane, rotation = 1.0, "CANON_PLANE_XY", 0.0
    g5x, g92, tlo = np.zeros(3), np.zeros(3), np.zeros(3)

    def machine(p: np.ndarray) -> np.ndarray:  # LinuxCNC's canon: (program + G92) turned about Z, then G5x, TLO
        q = p * factor + g92
        c, s_ = math.cos(math.radians(rotation)), math.sin(math.radians(rotation))
        q[0], q[1] = c * q[0] - s_ * q[1], s_ * q[0] + c * q[1]
        return q + g5x + tlo

    moves: list[dict] = []
    for raw in text.splitlines():
        m = _CALL.match(raw)
        if m is None:
            continue
        name, args = m.groups()
        if name in _UNSIMULATED:
            return moves, name
        if name == "USE_LENGTH_UNITS":
            factor = INCH if "INCHES" in args else 10.0 if "CM" in args else 1.0
        elif name == "SELECT_PLANE":
            plane = args.strip()
        elif name == "SET_XY_ROTATION":
            rotation = _numbers(args)[0]
        elif name == "SET_G5X_OFFSET":
            g5x = np.array(_numbers(args)[1:4]) * factor
        elif name == "SET_G92_OFFSET":
            g92 = np.array(_numbers(args)[0:3]) * factor
        elif name == "USE_TOOL_LENGTH_OFFSET":
            tlo = np.array(_numbers(args)[0:3]) * factor
        elif name in _MOVES:
            v = _numbers(args)
            if name == "ARC_FEED":
                i, j, k = _PLANE_AXES[plane]
                end, center = np.zeros(3), np.zeros(3)
                end[i], end[j], end[k] = v[0], v[1], v[5]
                center[i], center[j] = v[2], v[3]
                moves.append({"kind": "arc", "end": machine(end), "center": machine(center), "axes": (i, j),
                              "ccw": v[4] > 0, "turns": abs(int(v[4])), "factor": factor})
            else:
                moves.append({"kind": _MOVES[name], "end": machine(np.array(v[:3])), "factor": factor})
    return moves, None


def _ours(move) -> dict:
    d = {"kind": move.kind, "end": np.asarray(move.end, float), "line": move.line}
    if move.kind == "arc":
        d.update(center=np.asarray(move.center, float), ccw=not move.clockwise,
                 turns=max(1, math.ceil(move.angle / (2 * math.pi) - 1e-9)))
    return d


def _close(a, b, tol) -> bool:
    return bool(np.all(np.abs(np.asarray(a) - np.asarray(b)) <= tol))


def _moving(moves: list[dict], start) -> list[dict]:
    """The moves without the straight ones that stay where they are (LinuxCNC prints some that csgnb skips, e.g. a
    cycle's rapid to the R plane when already there): the same path either way."""
    out, here = [], np.asarray(start, float)
    for m in moves:
        if m["kind"] != "arc" and _close(m["end"], here, 1e-9 + 1e-5 * m.get("factor", 1.0)):
            continue
        out.append(m)
        here = m["end"]
    return out


def compare(ours: list, theirs: list[dict]) -> dict | None:
    """None when the move lists agree within LinuxCNC's printed precision, else the first difference."""
    ours, theirs = _moving(ours, np.zeros(3)), _moving(theirs, np.zeros(3))
    for n, (a, b) in enumerate(zip(ours, theirs, strict=False)):
        tol = 1.01e-4 * b["factor"] + 1e-9
        same = a["kind"] == b["kind"] and _close(a["end"], b["end"], tol)
        if same and a["kind"] == "arc":
            ax = list(b["axes"])
            same = _close(a["center"][ax], b["center"][ax], tol) and a["ccw"] == b["ccw"] and a["turns"] == b["turns"]
        if not same:
            show = {k: (v.round(4).tolist() if isinstance(v, np.ndarray) else v) for k, v in a.items()}
            want = {k: (v.round(4).tolist() if isinstance(v, np.ndarray) else v) for k, v in b.items() if k != "axes"}
            return {"move": n, "ours": show, "linuxcnc": want}
    if len(ours) != len(theirs):
        return {"move": min(len(ours), len(theirs)), "ours_moves": len(ours), "linuxcnc_moves": len(theirs)}
    return None


def check_folder(folder: Path, tool_diameter: float | None = None) -> dict:
    """The verdict for one LinuxCNC test folder."""
    programs = sorted(folder.glob("*.ngc"))
    program = next((p for p in programs if p.name == "test.ngc"), programs[0])
    expected = (folder / "expected").read_text(errors="replace")
    theirs, unsimulated = expected_moves(expected)
    if unsimulated:
        return {"status": "skipped", "why": f"LinuxCNC's output calls {unsimulated}"}
    if not theirs and "MESSAGE(" in expected:
        return {"status": "skipped", "why": "LinuxCNC's expected output holds messages only, no moves"}
    text = read_text(program.read_bytes())
    # The test machine's units hold until the program sets its own: its first USE_LENGTH_UNITS after ON_RESET
    units = re.findall(r"USE_LENGTH_UNITS\((\w+)\)", expected.split("ON_RESET", 1)[0] if "ON_RESET" in expected
                       else expected)
    if units and units[0] == "CANON_UNITS_INCHES":
        text = "G20\n" + text if not text.lstrip().startswith("%") else text.replace("%", "%\nG20\n", 1)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ours = [_ours(m) for m in parse(text, on_unsupported="warn", block_delete=False,
                                            tool_diameters=None if tool_diameter is None
                                            else {None: tool_diameter}).moves]
    except GCodeError as exc:
        return {"status": "refused", "message": str(exc), "linuxcnc_moves": len(theirs)}
    except Exception as exc:  # noqa: BLE001 - the census records every failure
        return {"status": "crash", "message": f"{type(exc).__name__}: {exc}"}
    diff = compare(ours, theirs)
    if diff is None:
        return {"status": "agree", "moves": len(ours)}
    return {"status": "differ", **diff}


def _detail(r: dict) -> str:
    status = r["status"]
    if status == "agree":
        return f"{r['moves']} moves"
    if status == "differ":
        return json.dumps({k: v for k, v in r.items() if k != "status"})
    return r.get("why") or r["message"]


def folders(root: Path) -> list[Path]:
    """Every folder under ``root`` with an ``expected`` file and a program."""
    return sorted(p.parent for p in root.rglob("expected") if any(p.parent.glob("*.ngc")))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("root", type=Path, help="a copy of LinuxCNC's tests/interp (or any folders with expected + .ngc)")
    p.add_argument("--json", type=Path, default=None)
    p.add_argument("--tool-diameter", type=float, default=None, metavar="MM",
                   help="every tool's diameter for G41/G42 D<tool> (LinuxCNC's tests use its sim tool table)")
    args = p.parse_args(argv)
    results = {}
    for folder in folders(args.root):
        r = check_folder(folder, args.tool_diameter)
        name = str(folder.relative_to(args.root))
        results[name] = r
        detail = _detail(r)
        print(f"{r['status']:<8} {name}: {detail}")
    counts = {k: sum(r["status"] == k for r in results.values()) for k in
              ("agree", "differ", "refused", "skipped", "crash")}
    print(f"\n{len(results)} LinuxCNC interpreter tests: " + ", ".join(f"{v} {k}" for k, v in counts.items()))
    if args.json is not None:
        args.json.write_text(json.dumps({"folders": results, "counts": counts}, indent=1))
    return 1 if counts["crash"] else 0


if __name__ == "__main__":
    sys.exit(main())
