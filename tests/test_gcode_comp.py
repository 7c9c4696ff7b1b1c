"""Cutter radius compensation (G40 G41 G42 G41.1 G42.1) as LinuxCNC computes it: entry, convex corners rounded about
the programmed corner, concave corners trimmed where the offset paths cross, gouges refused, exit; and the part a
compensated profile cuts is exactly the part of the same path offset by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from csgnb.apps import gcode, milling, tools
from csgnb.apps.gcode import GCodeError
from csgnb.exact import Grid
from csgnb.octree import Workpiece

HEAD = "G21 G90 G17\nG0 X{x0} Y{y0} Z5\nG1 Z-1 F100\n"


def geometry(moves) -> list[tuple]:
    """Each move as (kind, start, end[, centre, clockwise, turn]) rounded to 1e-9 mm."""
    out = []
    for m in moves:
        row = [m.kind, *np.round(m.start, 9).tolist(), *np.round(m.end, 9).tolist()]
        if m.kind == "arc":
            row += [*np.round(m.center[:2], 9).tolist(), m.clockwise, round(m.angle, 9)]
        out.append(tuple(0.0 if isinstance(v, float) and v == 0 else v for v in row))
    return out


SQUARE_CCW = "G1 X0 Y0\nX20\nY20\nX0\nY0\n"
SQUARE_CW = "G1 X0 Y0\nY20\nX20\nY0\nX0\n"


def test_an_outside_square_profile_is_offset_and_its_corners_rounded():
    program = HEAD.format(x0=-10, y0=0) + "G42.1 D6\n" + SQUARE_CCW + "G40\nG0 X-10 Y0\nZ5\nM2\n"
    moves = gcode.parse(program).moves[2:]
    r3 = math.pi / 2
    assert geometry(moves) == [
        ("linear", -10.0, 0.0, -1.0, 0.0, -3.0, -1.0),  # entry: to the programmed point, 3 mm right of its direction
        ("linear", 0.0, -3.0, -1.0, 20.0, -3.0, -1.0),
        ("arc", 20.0, -3.0, -1.0, 23.0, 0.0, -1.0, 20.0, 0.0, False, round(r3, 9)),  # convex: about the corner
        ("linear", 23.0, 0.0, -1.0, 23.0, 20.0, -1.0),
        ("arc", 23.0, 20.0, -1.0, 20.0, 23.0, -1.0, 20.0, 20.0, False, round(r3, 9)),
        ("linear", 20.0, 23.0, -1.0, 0.0, 23.0, -1.0),
        ("arc", 0.0, 23.0, -1.0, -3.0, 20.0, -1.0, 0.0, 20.0, False, round(r3, 9)),
        ("linear", -3.0, 20.0, -1.0, -3.0, 0.0, -1.0),
        ("rapid", -3.0, 0.0, -1.0, -10.0, 0.0, -1.0),  # exit: from where the compensated path ended
        ("rapid", -10.0, 0.0, -1.0, -10.0, 0.0, 5.0),
    ]
    assert {m.origin for m in moves if m.kind == "arc"} == {"G42.1 corner"}


def test_an_inside_pocket_profile_is_trimmed_at_its_concave_corners():
    program = HEAD.format(x0=10, y0=10) + "G41.1 D6\n" + "G1 X10 Y0\nX20\nY20\nX0\nY0\nX10\nG40\nG1 X10 Y10\nM2\n"
    moves = gcode.parse(program).moves[2:]
    assert geometry(moves) == [
        # the entry ends 3 mm left of (10, 0), at (13, 0), then LinuxCNC backs it up along the programmed direction
        # of the entry until it meets the first offset side y = 3 (not along the compensated entry line)
        ("linear", 10.0, 10.0, -1.0, 13.0, 3.0, -1.0),
        ("linear", 13.0, 3.0, -1.0, 17.0, 3.0, -1.0),
        ("linear", 17.0, 3.0, -1.0, 17.0, 17.0, -1.0),
        ("linear", 17.0, 17.0, -1.0, 3.0, 17.0, -1.0),
        ("linear", 3.0, 17.0, -1.0, 3.0, 3.0, -1.0),
        ("linear", 3.0, 3.0, -1.0, 10.0, 3.0, -1.0),
        ("linear", 10.0, 3.0, -1.0, 10.0, 10.0, -1.0),
    ]


def test_full_circles_keep_their_centre_and_turn_with_the_radius_grown_or_shrunk():
    for side, radius, entry in (("G41.1", 13.0, -3.0), ("G42.1", 7.0, 3.0)):
        program = HEAD.format(x0=0, y0=-10) + f"{side} D6\nG1 X0 Y0\nG2 X0 Y0 I10 J0\nG40\nG1 X0 Y10\nM2\n"
        arc = gcode.parse(program).moves[3]
        assert arc.kind == "arc" and arc.clockwise
        assert np.allclose(arc.start, [entry, 0, -1]) and np.allclose(arc.end, [entry, 0, -1])
        assert np.allclose(arc.center[:2], [10, 0]) and arc.radius == pytest.approx(radius)
        assert arc.angle == pytest.approx(2 * math.pi)


def test_a_z_move_in_a_concave_corner_follows_the_trimmed_end():
    program = (HEAD.format(x0=10, y0=10) + "G41.1 D6\nG1 X10 Y0\nX20\nG0 Z2\nG1 Z-1\nY20\nG40\nG1 X10 Y10\nM2\n")
    moves = gcode.parse(program).moves[2:]
    up, down = moves[2], moves[3]
    assert np.allclose(moves[1].end[:2], [17, 3])  # trimmed by the corner after the Z moves
    assert np.allclose(up.start[:2], [17, 3]) and np.allclose(up.end, [17, 3, 2])
    assert np.allclose(down.end, [17, 3, -1]) and np.allclose(moves[4].start, [17, 3, -1])


def test_a_line_meeting_an_arc_in_a_concave_corner_is_trimmed_on_the_offset_circle():
    # A slot end: a line into a half circle (radius 5) with the tool (radius 2) inside it (right of a clockwise arc);
    # the line (x = -5) is tangent where it meets the arc, so nothing is trimmed; then a line turning in (concave)
    # off the arc's end.
    program = (HEAD.format(x0=-5, y0=-20) + "G42.1 D4\nG1 X-5 Y-10\nY0\nG2 X5 Y0 I5 J0\nG1 X0 Y-5\nG40\n"
               "G1 X0 Y-20\nM2\n")
    moves = gcode.parse(program).moves[2:]
    arc = next(m for m in moves if m.kind == "arc")
    assert arc.radius == pytest.approx(3.0) and np.allclose(arc.start[:2], [-3, 0])
    after = moves[moves.index(arc) + 1]
    # The arc's end is pulled back to where the offset circle (radius 3) meets the line's offset (2 mm left of it).
    d = np.array([-5.0, -5.0]) / math.hypot(5, 5)
    right = np.array([d[1], -d[0]])
    p = np.array([5.0, 0.0]) + 2 * right  # a point of the offset line
    q = arc.end[:2] - p
    assert abs(d[0] * q[1] - d[1] * q[0]) < 1e-9  # on the offset line
    assert np.linalg.norm(arc.end[:2]) == pytest.approx(3.0)  # on the offset circle
    assert arc.angle < math.pi and np.allclose(after.start[:2], arc.end[:2])


@pytest.mark.parametrize("text, match", [
    ("G41.1 D6\nG1 X-8 Y0\n", "not longer than the tool radius"),  # entry 2 mm long, radius 3
    ("G41.1 D6\nG41.1 D6\n", "already on"),
    ("G41.1 D6\nG1 X0 Y0\nT1 M6\n", "tool change while cutter radius compensation"),
    ("G41.1 D6\nG1 X0 Y0\nG18\n", "another plane"),
    ("G41.1 D6\nG1 X0 Y0\nG20\n", "change of units"),
    ("G41.1 D6\nG1 X0 Y0\nG81 X5 Y5 Z-2 R1\n", "canned cycle"),
    ("G41.1 D6\nG1 X0 Y0\nG28\n", "cannot be compensated"),
    ("G41.1 D6\nG1 X0 Y0\nG55\n", "coordinate system"),
    ("G41.1 D6\nG1 X0 Y0\nG40\nG2 X5 Y0 R5\n", "after G40 .* must be straight"),
    ("G18 G41.1 D6\n", "XY plane"),
    ("G41 D3\n", "diameter of tool 3 is unknown"),
    ("G41\n", "no tool is loaded"),
    ("G41.1\n", "needs the tool diameter"),
    ("G41 D1.5\n", "tool number"),
    ("G41.1 D24\nG1 X20 Y0\nG3 X30 Y10 I0 J10\n", "not less than the arc's radius"),
])
def test_what_linuxcnc_refuses_is_an_error_naming_the_line(text, match):
    program = HEAD.format(x0=-10, y0=0) + text
    with pytest.raises(GCodeError, match=match) as exc:
        gcode.parse(program)
    assert exc.value.line >= 4


def test_a_notch_narrower_than_the_tool_is_a_gouge_error_naming_the_line():
    # A 4 mm wide notch in an outside profile, cut with a 6 mm tool on the outside.
    notch = "G1 X0 Y0\nX10\nY-5\nX14\nY0\nX30\n"
    with pytest.raises(GCodeError, match="without gouging") as exc:
        gcode.parse(HEAD.format(x0=-10, y0=0) + "G41.1 D6\n" + notch)
    assert exc.value.line in (8, 9)
    gcode.parse(HEAD.format(x0=-10, y0=0) + "G41.1 D3\n" + notch)  # a 3 mm tool fits


def test_diameters_come_from_the_table_the_loaded_tool_and_units():
    base = HEAD.format(x0=-10, y0=0)
    by_number = gcode.parse(base + "G42 D2\nG1 X0 Y0\n", tool_diameters={2: 6.0}).moves[-1]
    assert np.allclose(by_number.end[:2], [0, -3])
    loaded = gcode.parse(base + "T2 M6\nG42\nG1 X0 Y0\n", tool_diameters={2: 4.0}).moves[-1]
    assert np.allclose(loaded.end[:2], [0, -2])
    default = gcode.parse(base + "G42 D7\nG1 X0 Y0\n", tool_diameters={None: 8.0}).moves[-1]
    assert np.allclose(default.end[:2], [0, -4])
    inch = gcode.parse("G20 G90 G17\nG0 X0 Y0 Z0\nG42.1 D0.25\nG1 X1 Y0 F10\n").moves[-1]
    assert np.allclose(inch.end[:2], [25.4, -3.175])
    flipped = gcode.parse(base + "G42 D2\nG1 X0 Y0\n", tool_diameters={2: -6.0}).moves[-1]
    assert np.allclose(flipped.end[:2], [0, 3])  # a negative table diameter swaps the side (LinuxCNC)
    negative = gcode.parse(base + "G42.1 D-6\nG1 X0 Y0\n").moves[-1]
    assert np.allclose(negative.end[:2], [0, 3])
    off = gcode.parse(base + "G42 D0\nG1 X0 Y0\n").moves[-1]
    assert np.allclose(off.end[:2], [0, 0])  # D0: tool 0, no offset
    incremental = gcode.parse(base + "G42.1 D6\nG1 X0 Y0\nG91 X20\n").moves[-1]
    assert np.allclose(incremental.end[:2], [20, -3])  # G91 steps from the programmed point, not the offset one


# -- the part: compensated == offset by hand, exactly ---------------------------------------------------------------

SCALE = 32
GRID = Grid.from_resolution(1 / SCALE)
STOCK = ((-15, -15, -4), (35, 35, 0))

HAND = {
    # G42 outside the square, counter-clockwise (the path test_an_outside_square_profile... expects)
    "square right": ("G42.1 D6\n" + SQUARE_CCW, -10, 0,
                     "G1 X0 Y-3\nX20\nG3 X23 Y0 I0 J3\nG1 Y20\nG3 X20 Y23 I-3 J0\nG1 X0\nG3 X-3 Y20 I0 J-3\nG1 Y0\n"),
    # G41 outside the square, clockwise
    "square left": ("G41.1 D6\n" + SQUARE_CW, 0, -10,
                    "G1 X-3 Y0\nY20\nG2 X0 Y23 I3 J0\nG1 X20\nG2 X23 Y20 I0 J-3\nG1 Y0\nG2 X20 Y-3 I-3 J0\nG1 X0\n"),
    "circle outside": ("G41.1 D6\nG1 X0 Y0\nG2 X0 Y0 I10 J0\n", 0, -10, "G1 X-3 Y0\nG2 X-3 Y0 I13 J0\n"),
    "circle inside": ("G42.1 D6\nG1 X0 Y0\nG2 X0 Y0 I10 J0\n", 0, -10, "G1 X3 Y0\nG2 X3 Y0 I7 J0\n"),
}


@pytest.fixture(scope="module")
def flat():
    return tools.flat_end_mill(6, 8, segments=12).on(GRID)


@pytest.mark.parametrize("name", sorted(HAND))
def test_a_compensated_profile_cuts_exactly_the_hand_offset_part(name, flat):
    comp, x0, y0, hand = HAND[name]
    tail = "G40\nG0 Z5\nM2\n"
    compensated = gcode.parse(HEAD.format(x0=x0, y0=y0) + comp + tail)
    # after G40 the retract also takes the tool back to the programmed point (0, 0) where every profile ends
    by_hand = gcode.parse(HEAD.format(x0=x0, y0=y0) + hand + "G0 X0 Y0 Z5\nM2\n")
    assert geometry(compensated.moves) == geometry(by_hand.moves)
    volumes = []
    for program in (compensated, by_hand):
        w = Workpiece.box(*STOCK, grid=GRID)
        result = milling.simulate(w, program, flat, progress=False)
        volumes.append((result.removed, w.model_volume()))
    assert volumes[0] == volumes[1] and volumes[0][0] > 0


def test_the_mill_command_offsets_by_the_diameter_of_the_named_tool(tmp_path):
    from csgnb.mill import build_parser, prepare

    program = tmp_path / "profile.ngc"
    program.write_text("G21 G90 G17\nT1 M6\nG0 X-10 Y0 Z5\nM3 S1000\nG1 Z-1 F100\nG42 D1\n" + SQUARE_CCW + "G40\n"
                       "G0 X-10 Y0\nZ5\nM2\n")
    table = tmp_path / "tool.tbl"
    table.write_text("T1 P1 Z0 D4 ;flat:4\n")
    for extra, offset in ((["--tool", "1=flat:6"], 3.0), (["--tool-table", str(table)], 2.0),
                          (["--tool", "flat:5"], 2.5)):
        args = build_parser().parse_args([str(program), "--stock", "40", "40", "5", "--stock-origin", "-15", "-15",
                                          "-5", "--segments", "8", *extra])
        setup = prepare(args)
        entry = next(m for m in setup.program.moves if m.line == 7)
        assert np.allclose(entry.end[:2], [0, -offset]), extra


def _distance_to_polygon(p: np.ndarray, poly: np.ndarray) -> float:
    best = math.inf
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        best = min(best, float(np.linalg.norm(p - (a + t * (b - a)))))
    return best


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0, 2 * math.pi), min_size=3, max_size=8, unique=True), st.floats(15, 40),
       st.floats(0.5, 3.0), st.sampled_from(["G41", "G42"]), st.booleans())
def test_every_compensated_point_stays_one_radius_off_a_convex_profile(angles, size, r, side, ccw):
    """Property: around a convex polygon, outside or inside, the compensated path (after its entry) keeps exactly the
    tool radius from the contour -- rounded about convex corners, trimmed at concave ones, never closer."""
    angles = sorted(angles)
    poly = np.array([[size * math.cos(a), size * math.sin(a)] for a in angles])
    area2 = sum(a[0] * b[1] - a[1] * b[0] for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True))
    assume(area2 > 0)
    edges = [np.linalg.norm(b - a) for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True)]
    assume(min(edges) > 4 * r)
    path = poly if ccw else poly[::-1]
    inside = (side == "G41") == ccw  # left of a counter-clockwise contour is its inside
    centre = poly.mean(axis=0)
    if inside:  # the tool must fit well inside, and enters from the centroid
        apothem = min(abs((b - a)[0] * (centre - a)[1] - (b - a)[1] * (centre - a)[0]) / np.linalg.norm(b - a)
                      for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True))
        assume(apothem > 3 * r)
    start = centre if inside else centre + 3 * (path[0] - centre)  # from the centre or from far outside
    lines = [f"G21 G90 G17\nG0 X{start[0]:.12f} Y{start[1]:.12f} Z5\nG1 Z-1 F100\n{side}.1 D{2 * r:.12f}\n"]
    for x, y in [*path, path[0], path[1], path[2]]:
        lines.append(f"G1 X{x:.12f} Y{y:.12f}\n")
    lines.append("G40\nG0 Z5\nM2\n")
    try:
        program = gcode.parse("".join(lines))
    except GCodeError as exc:  # inside, a side shorter than the corners need vanishes: LinuxCNC refuses the gouge
        assert inside and "without gouging" in str(exc)
        return
    # every side once with both its corners: not the first side (its start depends on the entry, and a turn within
    # LinuxCNC's 0.05 rad tangent tolerance leaves it off by up to r (1 - cos 0.05)), nor the last line, into G40,
    # which keeps its untrimmed end; the first side comes again as the last but one
    body = [m for m in program.moves if 6 < m.line <= 6 + len(path)]
    assert body
    for m in body:
        for p in m.points(0.01):
            assert _distance_to_polygon(p[:2], poly) == pytest.approx(r, abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["G0", "G1", "G2", "G3", "Z"]), st.integers(-20, 20), st.integers(-20, 20),
                          st.integers(-8, 8), st.integers(-8, 8)), min_size=1, max_size=12),
       st.sampled_from(["G41.1", "G42.1"]), st.sampled_from([0.5, 2.0, 6.0]))
def test_random_compensated_programs_run_or_fail_with_a_gcode_error(steps, side, diameter):
    """Fuzz: lines, arcs (centre form), Z-only moves and rapids under compensation never raise anything but a
    GCodeError naming a line, and every move they give is finite."""
    lines = [f"G21 G90 G17 F100\nG0 X-30 Y-30 Z1\n{side} D{diameter}"]
    for code, x, y, i, j in steps:
        if code == "Z":
            lines.append(f"G1 Z{x / 10:g}")
        elif code in ("G2", "G3"):
            lines.append(f"{code} X{x} Y{y} I{i} J{j}")
        else:
            lines.append(f"{code} X{x} Y{y}")
    lines.append("G40\nG1 X-30 Y-30\nM2\n")
    try:
        program = gcode.parse("\n".join(lines))
    except GCodeError as exc:
        assert exc.line >= 1
        return
    for m in program.moves:
        assert np.all(np.isfinite(m.start)) and np.all(np.isfinite(m.end))
        if m.kind == "arc":
            assert m.angle > 0 and np.isfinite(m.angle) and np.all(np.isfinite(m.points(0.1)))
