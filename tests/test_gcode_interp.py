"""The G-code interpreter beyond single lines: full circles, numbers at the edge of a double, modal groups,
parameters and expressions, O-word control flow, coordinate systems, tool lengths, feed modes, canned cycles.

Every expected move list is worked out by hand in the comments (machine frame = the stock's frame).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from csgnb.apps.gcode import Arc, GCodeError, parse, parse_file


def ends(program):
    return [np.round(m.end, 9).tolist() for m in program]


# -- 1. full circles -------------------------------------------------------------------------------------------


def _turn(m: Arc) -> float:
    """Signed total turn of the polyline about the arc's axis (counter-clockwise positive)."""
    n = m.normal
    pts = m.points(0.01) - m.center
    u = pts[0] - (pts[0] @ n) * n
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    ang = np.unwrap(np.arctan2(pts @ v, pts @ u))
    return float(ang[-1] - ang[0])


PLANE_CASES = {  # plane code, the two offset letters, their axes, the normal axis letter
    "G17": ("IJ", (0, 1), "Z"), "G18": ("KI", (2, 0), "Y"), "G19": ("JK", (1, 2), "X")}


@pytest.mark.parametrize("plane", ["G17", "G18", "G19"])
@pytest.mark.parametrize("code", ["G2", "G3"])
@pytest.mark.parametrize("rise", [0.0, -1.0])
def test_an_arc_that_ends_where_it_starts_is_a_full_circle(plane, code, rise):
    # The program: start (0, 1.5) in the plane, centre offset (-1.5, -2.598076): radius 3.0000 and an end
    # point that equals the start, for which the old polyline turned by ±1e-17 rad: zero length (or a straight
    # line when the normal axis rises).
    letters, (iu, iv), normal = PLANE_CASES[plane]
    p0 = [0.0, 0.0, 0.0]
    p0[iu], p0[iv] = 0.0, 1.5
    axis_words = " ".join(f"{'XYZ'[i]}{p0[i]:g}" for i in range(3))
    end = list(p0)
    end["XYZ".index(normal)] += rise
    end_words = " ".join(f"{'XYZ'[i]}{end[i]:g}" for i in range(3))
    text = f"{plane} G0 {axis_words}\n{code} {end_words} {letters[0]}-1.5 {letters[1]}-2.598076 F300\n"
    _, arc = parse(text).moves
    assert isinstance(arc, Arc) and arc.angle == pytest.approx(2 * math.pi)
    turn = _turn(arc)
    # G2 is clockwise seen from the positive end of the normal: a negative turn about it.
    assert turn == pytest.approx(-2 * math.pi if code == "G2" else 2 * math.pi, abs=1e-9)
    r = arc.radius
    assert r == pytest.approx(3.0, abs=1e-6)
    assert arc.length(1e-5) == pytest.approx(math.hypot(2 * math.pi * r, rise), rel=1e-5)
    pts = arc.points(0.01)
    assert len(pts) > 30 and np.array_equal(pts[-1], arc.end)


def test_full_circles_as_linuxcnc_decides_them():
    # An end within CIRCLE_FUZZ (1e-6 rad) of the start, on either side, is a full turn; P adds turns;
    # an end 0.001 mm behind the start is a 359.98° arc one way and a 0.02° arc the other.
    start = "G0 X5 Y0\n"
    for code in ("G2", "G3"):
        for dy in (1e-7, -1e-7, 0.0):
            (arc,) = parse(start + f"{code} X5 Y{dy:.7f} I-5 J0 F100").moves[1:]
            assert arc.angle == pytest.approx(2 * math.pi, abs=1e-6)
    (arc,) = parse(start + "G3 X5 Y0 I-5 J0 P3 F100").moves[1:]
    assert arc.angle == pytest.approx(6 * math.pi) and _turn(arc) == pytest.approx(6 * math.pi, abs=1e-9)
    (short,) = parse(start + "G3 X5 Y0.001 I-5 J0 F100").moves[1:]
    (long_,) = parse(start + "G2 X5 Y0.001 I-5 J0 F100").moves[1:]
    assert short.angle == pytest.approx(0.001 / 5, rel=1e-4)
    assert long_.angle == pytest.approx(2 * math.pi - 0.001 / 5, rel=1e-9)


# -- 2. numbers, modal groups, files ---------------------------------------------------------------------------


@pytest.mark.parametrize("text, word_start", [
    ("G0 X0\nG0 X1" + "0" * 400 + "\n", "1000"),
    ("G0 X0\nG1 X1 F" + "9" * 400 + "\n", "9999"),
    ("G0 X0\nG0 Y" + "1" * 10**7 + "\n", "1111"),
])
def test_numbers_that_overflow_a_double_are_errors_naming_the_line(text, word_start):
    t0 = time.perf_counter()
    with pytest.raises(GCodeError, match="too large for a double") as exc:
        parse(text)
    assert exc.value.line == 2 and exc.value.word.startswith(word_start)
    assert time.perf_counter() - t0 < 20  # linear work, not a hang (about 1 s on a shared core)


@pytest.mark.parametrize("text, match", [
    ("F10\nG2 X0 Y2 R1000000000000000\n", "beyond"),
    ("F10\nG2 X0 Y0 I1000000000000000 J0\n", "beyond"),
    ("F10\nG1 X[10 ** 15]\n", "beyond"),
    ("F10\nG2 X0 Y0 I[10 ** 300 * 10 ** 300] J0\n", "overflows"),
])
def test_huge_positions_and_radii_are_refused_at_parse(text, match):
    with pytest.raises(GCodeError, match=match) as exc:
        parse(text)
    assert exc.value.line == 2


@pytest.mark.parametrize("kw", [dict(start=[math.nan, 0, 0]), dict(start=[0, math.inf, 0]), dict(start=[1, 2]),
                                dict(home=[0, 0, 1e30]), dict(tool_lengths={1: math.nan})])
def test_bad_start_home_or_tool_lengths_are_refused(kw):
    with pytest.raises(ValueError, match="finite"):
        parse("G0 X1", **kw)


@pytest.mark.parametrize("codes, second", [("G17 G18", "G18"), ("G20 G21", "G21"), ("G90 G91", "G91"),
                                           ("G54 G55", "G55"), ("G93 G94", "G94"), ("G43 G49", "G49"),
                                           ("G98 G99", "G99"), ("G4 P1 G92 X0", "G92"), ("M3 M4", "M4"),
                                           ("M0 M2", "M2"), ("G61 G64", "G64")])
def test_two_codes_of_one_modal_group_on_a_line_are_an_error(codes, second):
    with pytest.raises(GCodeError, match="modal group|group: one per line") as exc:
        parse(f"G0 X1\n{codes}\n")
    assert exc.value.line == 2 and exc.value.word == second


def test_a_latin1_comment_or_a_byte_order_mark_does_not_refuse_a_file(tmp_path):
    f = tmp_path / "latin1.nc"
    f.write_bytes(b"(op\xe9ration 1: \xb0C)\nG0 X1\n")
    assert ends(parse_file(f)) == [[1, 0, 0]]
    f.write_bytes(b"\xef\xbb\xbfG0 X1 (\xc3\xa9t\xc3\xa9)\nG0 Y2\n")
    assert ends(parse_file(f)) == [[1, 0, 0], [1, 2, 0]]
    assert ends(parse("\ufeffG0 X3")) == [[3, 0, 0]]
    f.write_bytes(b"G0 X1\nG0 Y1 \xe9\n")
    with pytest.raises(GCodeError, match="cannot read") as exc:
        parse_file(f)
    assert exc.value.line == 2


def test_a_chord_tolerance_too_fine_for_an_arc_is_an_error_not_a_hang():
    (arc,) = parse("F10\nG2 X0 Y0 I5 J0").moves
    t0 = time.perf_counter()
    with pytest.raises(GCodeError, match="chords") as exc:
        arc.points(1e-12)
    assert exc.value.line == 2 and time.perf_counter() - t0 < 1
    assert len(arc.points(1e-6)) > 1000  # fine but within the bound
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="chord tolerance"):
            arc.points(bad)


# -- 6. parameters and expressions ------------------------------------------------------------------------------


@pytest.mark.parametrize("expr, value", [
    ("[1 + 2 * 3]", 7), ("[[1 + 2] * 3]", 9), ("[2 ** 3 ** 2]", 64), ("[10 - 4 - 3]", 3), ("[12 / 4 / 3]", 1),
    ("[7 MOD 3]", 1), ("[-7 MOD 3]", 2), ("[7.5 mod 2]", 1.5), ("ATAN[1]/[1]", 45), ("ATAN[-1]/[-1]", -135),
    ("ABS[-2.5]", 2.5), ("ACOS[0]", 90), ("ASIN[1]", 90), ("COS[60]", 0.5), ("SIN[30]", 0.5), ("TAN[45]", 1),
    ("EXP[0]", 1), ("LN[1]", 0), ("SQRT[16]", 4), ("FIX[-2.5]", -3), ("FUP[-2.5]", -2), ("ROUND[2.5]", 3),
    ("ROUND[-2.5]", -3), ("[1 EQ 1.00001]", 1), ("[1 NE 1.00001]", 0), ("[2 GT 1]", 1), ("[1 GE 1]", 1),
    ("[1 LT 1]", 0), ("[1 LE 0.99999]", 1), ("[1 AND 0]", 0), ("[1 OR 0]", 1), ("[1 XOR 1]", 0),
    ("[1 + 2 LT 4 AND 1]", 1), ("-[2]", -2), ("[ 1 + sqrt [ 9 ] ]", 4), ("[#<_x> + 1]", 1),
])
def test_expressions_evaluate_as_rs274ngc(expr, value):
    assert parse(f"G0 X{expr}").moves[0].end[0] == pytest.approx(value, abs=1e-12)


@pytest.mark.parametrize("text, match", [
    ("G0 X[1/0]", "division by zero"), ("G0 X[2 MOD 0]", "modulo by zero"), ("G0 X SQRT[-1]", "SQRT"),
    ("G0 X LN[0]", "LN"), ("G0 X ACOS[2]", "ACOS"), ("G0 X#<nope>", "before any value"), ("G0 X#0", "#0"),
    ("#6000 = 1", "#6000"), ("#5221 = 1", "system parameter"), ("G0 X#5410", "does not track"),
    ("G0 X#5061", "does not track"), ("G0 X[1 + ]", "cannot read"),
    ("G0 X[1 + 2", "cannot read"), ("G0 X ATAN[1]", "ATAN"), ("G0 X[-1 ** 0.5]", "negative base"),
    ("G0 X EXP[1000]", "overflows"), ("#1 2", "cannot read"), ("G0 X" + "-" * 5000 + "1", "too deeply"),
    ("G0 X" + "#" * 5000 + "1", "too deeply"), ("G0 X[" + "1+" * 5000 + "1]", "too deeply"),
    ("G0 X" + "[" * 100 + "1" + "]" * 100, "nest deeper"), ("G92.1 X1", "takes no axis words"),
    ("G91 G53 G0 X1", "needs G90"), ("G0 X1 @2 ^30", "polar"), ("o[1] sub", "call only"),
])
def test_expression_errors_name_the_line(text, match):
    with pytest.raises(GCodeError, match=match) as exc:
        parse("G0 X0\n" + text)
    assert exc.value.line == 2


def test_assignments_take_effect_after_the_line_and_named_parameters_are_scoped():
    p = parse("#1 = 5\n#1 = 10 G0 X#1\nG0 Y#1\n#<a> = 2 #<_g> = 3\nG0 Z[#<a> * #<_g>]\n"
              "G0 X[EXISTS[#<a>] + EXISTS[#<b>] * 10]\n##1 = 7\nG0 Y#10\n")
    assert ends(p) == [[5, 0, 0], [5, 10, 0], [5, 10, 6], [1, 10, 6], [1, 7, 6]]


def test_subroutines_pass_arguments_return_values_and_restore_locals():
    p = parse("""o100 sub
  G0 X#1 Y#2
  #<local> = [#1 + #2]
  o100 return [#<local> * 2]
o100 endsub
#1 = 99
o100 call [3] [4]
G0 Z#<_value>
G0 X#1
o<named> call [0.5]
o<named> sub
  G0 Y[#1 * 10]
  o<named> if [EXISTS[#<local>]]
    G0 Y-1
  o<named> endif
o<named> endsub
""")
    # the call is answered by the sub defined after it; #<local> of o100 is gone in o<named>
    assert ends(p) == [[3, 4, 0], [3, 4, 14], [99, 4, 14], [99, 5, 14]]


def test_control_flow_while_repeat_do_if_break_continue():
    p = parse("""#1 = 0
o1 while [#1 LT 3]
  G0 X#1
  #1 = [#1 + 1]
o1 endwhile
o2 repeat [2]
  G0 Y#1
o2 endrepeat
o3 do
  #1 = [#1 - 1]
  o4 if [#1 EQ 1]
    o3 continue
  o4 elseif [#1 EQ 0]
    G0 Z100
  o4 else
    G0 Z#1
  o4 endif
o3 while [#1 GT 0]
#2 = 0
o5 while [1]
  #2 = [#2 + 1]
  o6 if [#2 GE 3]
    o5 break
  o6 endif
o5 endwhile
G0 X#2
""")
    assert ends(p) == [[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 3, 0], [2, 3, 0], [2, 3, 2], [2, 3, 100], [3, 3, 100]]


@pytest.mark.parametrize("text, line, match", [
    ("o1 while [1]\nG0 X1\no1 endwhile\n", 3, "loop passes"),
    ("o1 do\nG0 X1\no1 while [1]\n", 3, "loop passes"),
    ("o1 if [1]\no2 endif\n", 2, "closes no o2 if"),
    ("G0 X1\no1 while [1]\n", 2, "never closed"),
    ("o9 call\n", 1, "defines no o9 sub"),
    ("o1 sub\no1 call\no1 endsub\no1 call\n", 2, "nests deeper"),
    ("o1 break\n", 1, "not inside"),
    ("o1 repeat [1.5]\no1 endrepeat\n", 1, "integer"),
    ("o1 if\no1 endif\n", 1, "takes 1"),
])
def test_control_flow_errors_are_bounded_and_name_the_line(text, line, match):
    with pytest.raises(GCodeError, match=match) as exc:
        parse(text, max_loop_passes=1000)
    assert exc.value.line == line


# -- 7. modes, coordinate systems, tool lengths, feeds -----------------------------------------------------------


def test_coordinate_systems_g10_g92_g53():
    p = parse("""G10 L2 P2 X100 Y50 Z-10
G55 G0 X1 Y2 Z3
G54 G0 X1
G10 L20 P1 X0 Y0
G0 X5 Y5
G92 X0 Y0
G0 X1
G92.2
G0 X1
G92.3
G0 Y1
G92.1
G53 G0 Z0
G0 X0
G20 G10 L2 P3 X1
G56 G0 X1
""")
    assert ends(p) == [[101, 52, -7], [1, 52, -7], [6, 57, -7], [7, 57, -7], [2, 57, -7], [2, 58, -7], [2, 58, 0],
                       [1, 58, 0], [50.8, 58, 0]]


def test_g28_g30_go_home_through_the_intermediate_point():
    p = parse("""G0 X10 Y10 Z-1
G28 G91 Z0.
G90
G28 G91 X0. Y0.
G90 G0 X5 Y5 Z5
G28.1
G0 X20
G28
G30 Z7
""", start=(0, 0, 50))
    assert ends(p) == [[10, 10, -1], [10, 10, 50], [0, 0, 50], [5, 5, 5], [20, 5, 5], [5, 5, 5], [5, 5, 7],
                       [5, 5, 50]]
    assert [m.origin for m in p] == [None, "G28", "G28", None, None, "G28", "G30", "G30"]
    assert ends(parse("G28 G91 Z0.", start=(1, 2, 3), home=(0, 0, 40))) == [[1, 2, 40]]


def test_tool_length_offsets_move_the_tip_by_the_table_lengths():
    p = parse("""T1 M6
G43 H1
G0 Z5
T2 M6
G0 Z5
G43 H2 G0 Z5
G49 G0 Z5
G43.1 Z40
G0 Z5
""", start=(0, 0, 100), tool_lengths={1: 30.0, 2: 40.0})
    # T1 hangs 30 below the gauge line (at 100); G43 H1 puts its tip at Z5; T2 is 10 longer, so under H1 it
    # reaches Z-5; H2 corrects it; G49 drops the offset (gauge line at Z5, tip 40 below).
    assert [(m.start[2], m.end[2], m.tool) for m in p] == [(70, 5, 1), (-5, -5, 2), (-5, 5, 2), (5, -35, 2),
                                                          (-35, 5, 2)]
    with pytest.raises(GCodeError, match="tool 3 is not in the tool table") as exc:
        parse("G43 H3", tool_lengths={1: 30.0})
    assert exc.value.word == "H3"
    assert ends(parse("T1 M6\nG43 H1\nG0 Z5")) == [[0, 0, 5]]  # without a table every length is 0


def test_feed_modes_arc_centre_modes_dwell_stops_and_path_control():
    p = parse("""G93 G1 X10 F2
G94 G1 X20 F100
G95 S1000 G1 X30 F0.1
G94 G90.1 G0 X10 Y0
G3 X-10 Y0 I0 J0 F100
G91.1 G61
G61.1
G64 P0.01 Q0.01
G4 P2.5
M0
M1
G2 X10 Y0 I10 J0 M30
""")
    assert [round(m.feed or 0, 9) for m in p] == [20, 100, 100, 0, 100, 100]
    arc = p[4]
    assert arc.center.tolist() == [0, 0, 0] and arc.angle == pytest.approx(math.pi) and not arc.clockwise
    assert p[5].center.tolist() == [0, 0, 0] and p.end_line == 12 and p.dwell_s == 2.5
    for text, match in [("G93 G1 X1 F2\nG1 X2\n", "G93"), ("G95 G1 X1 F1\n", "spindle speed"),
                        ("G93 G1 X1 F2\nG94\nG1 X2\n", "feed rate"), ("F100\nG95 S100\nG1 X2\n", "feed rate"),
                        ("G4\n", "dwell"), ("G1 X1 F1 P3\n", "used by no code"), ("G0 X1 H2\n", "used by no code")]:
        with pytest.raises(GCodeError, match=match):
            parse(text)


def test_block_delete_must_be_decided():
    text = "G0 X1\n/G0 X5\nG0 Y1\n"
    with pytest.raises(GCodeError, match="block delete") as exc:
        parse(text)
    assert exc.value.line == 2 and exc.value.word == "/"
    assert ends(parse(text, block_delete=True)) == [[1, 0, 0], [1, 1, 0]]
    assert ends(parse(text, block_delete=False)) == [[1, 0, 0], [5, 0, 0], [5, 1, 0]]


def test_grbl_dialect_takes_the_spindle_as_running_and_skips_dollar_lines():
    text = "$32=0\nG0 X1\nG1 X2 F100\n"
    with pytest.raises(GCodeError, match="cannot read"):
        parse(text)
    with pytest.raises(GCodeError, match=r"\$32"):
        parse(text, dialect="grbl")
    with pytest.warns(UserWarning, match="GRBL system command"):
        p = parse(text, dialect="grbl", on_unsupported="warn")
    assert [m.spindle_on for m in p] == [True, True] and p.skipped["$32=0"].first_line == 1
    with pytest.raises(GCodeError, match="homing"):
        parse("$H\nG0 X1", dialect="grbl", on_unsupported="warn")
    assert [m.spindle_on for m in parse("G1 X2 F100")] == [False]


# -- 8. canned cycles --------------------------------------------------------------------------------------------


def _kz(p, axis=2):
    return [(m.kind[0], round(float(m.end[axis]), 9)) for m in p]


def test_g81_with_g98_and_g99():
    p98 = parse("G0 X0 Y0 Z10\nG98 G81 X5 Y5 Z-2 R1 F100\nX10\nG80\nG0 Z20\n")
    assert ends(p98) == [[0, 0, 10], [5, 5, 10], [5, 5, 1], [5, 5, -2], [5, 5, 10], [10, 5, 10], [10, 5, 1],
                         [10, 5, -2], [10, 5, 10], [10, 5, 20]]
    assert [m.kind for m in p98][1:5] == ["rapid", "rapid", "linear", "rapid"] and p98[3].feed == 100
    assert {m.origin for m in p98[1:9]} == {"G81"}
    p99 = parse("G0 X0 Y0 Z10\nG99 G81 X5 Y5 Z-2 R1 F100\nX10\n")
    assert ends(p99) == [[0, 0, 10], [5, 5, 10], [5, 5, 1], [5, 5, -2], [5, 5, 1], [10, 5, 1], [10, 5, -2],
                         [10, 5, 1]]


def test_peck_cycles_g83_and_g73():
    p = parse("G0 X0 Y0 Z5\nG99 G83 X0 Y0 Z-3 R1 Q1.2 F60\n")
    z = [1, -0.2, 1, 0.054, -1.4, 1, -1.146, -2.6, 1, -2.346, -3, 1]
    assert [k for k, _ in _kz(p)[1:]] == list("rlrrlrrlrrlr")
    np.testing.assert_allclose([v for _, v in _kz(p)[1:]], z, atol=1e-9)
    p = parse("G0 X0 Y0 Z5\nG99 G73 X0 Y0 Z-3 R1 Q1.2 F60\n")
    assert [k for k, _ in _kz(p)[1:]] == list("rlrlrlrlr")
    np.testing.assert_allclose([v for _, v in _kz(p)[1:]], [1, -0.2, 0.054, -1.4, -1.146, -2.6, -2.346, -3, 1],
                               atol=1e-9)


def test_g82_g85_g89_and_incremental_repeats():
    p = parse("G0 Z5\nG99 G82 X1 Z-1 R1 P0.5 F10\nG85 X2\nG89 X3 P2\n")
    assert _kz(p) == [("r", 5), ("r", 5), ("r", 1), ("l", -1), ("r", 1),  # G82
                      ("r", 1), ("l", -1), ("l", 1),  # G85: feed out
                      ("r", 1), ("l", -1), ("l", 1)]  # G89
    assert p.dwell_s == 2.5
    p = parse("G0 X0 Y0 Z5\nG91 G81 X10 Y0 Z-4 R-3 L3 F100\n")
    assert ends(p)[1:] == [[10, 0, 5], [10, 0, 2], [10, 0, -2], [10, 0, 5], [20, 0, 5], [20, 0, 2], [20, 0, -2],
                           [20, 0, 5], [30, 0, 5], [30, 0, 2], [30, 0, -2], [30, 0, 5]]


def test_canned_cycles_in_the_zx_and_yz_planes():
    p = parse("G18 G0 X0 Y10 Z0\nG99 G81 X5 Z5 Y-2 R1 F50\n")
    assert ends(p)[1:] == [[5, 10, 5], [5, 1, 5], [5, -2, 5], [5, 1, 5]]
    p = parse("G19 G0 X10 Y0 Z0\nG99 G81 Y5 Z5 X-2 R1 F50\n")
    assert ends(p)[1:] == [[10, 5, 5], [1, 5, 5], [-2, 5, 5], [1, 5, 5]]


@pytest.mark.parametrize("text, match", [
    ("G81 X1 Z-1 F10\n", "retract plane R"), ("G81 X1 R1 F10\n", "bottom Z"), ("G81 X1 Z2 R1 F10\n", "above"),
    ("G83 X1 Z-1 R1 F10\n", "peck depth Q"), ("G81 X1 Z-1 R1 L0 F10\n", "L"), ("G93 G81 X1 Z-1 R1 F10\n", "G93"),
    ("G81 X1 Z-1 R1\n", "feed rate"), ("G80 X1\n", "no axis words"),
])
def test_canned_cycle_errors(text, match):
    with pytest.raises(GCodeError, match=match):
        parse(text)


def test_system_parameters_read_the_interpreter_state():
    # #5220 system, #5221+ G54 offsets, #5241+ G55, #5211+ G92, #5161+ G28, #5400 tool, #5420+ position (program
    # units: the G20 line reads inches)
    p = parse("""G10 L2 P2 X10 Y20
G55 G0 X1 Y2 Z3
G92 Z0
T4 M6
G28.1
G0 X#5220 Y#5241
G0 X#5242 Y#5213
G0 X#5400 Y[#5420 + #5163]
G20 G0 Y#5241
G0 X#5241
""", start=(0, 0, 0))
    # words are read before their line runs: the G20 line reads #5241 in mm (10, then taken as inches)
    assert ends(p) == [[11, 22, 3], [12, 30, 3], [30, 23, 3], [14, 43, 3], [14, 274, 3], [20, 274, 3]]


def test_computed_call_numbers_io_words_and_more_refusals():
    p = parse("o101 sub\nG0 X#1\no101 endsub\no[100 + 1] call [7]\n")
    assert ends(p) == [[7, 0, 0]]
    with pytest.warns(UserWarning) as caught:
        p = parse("M64 P1\nM66 P2 L0 Q5\nM68 E2 Q3\nG0 X1\n", on_unsupported="warn")
    assert len(caught) == 3
    assert {w: s.count for w, s in p.skipped.items()} == {"M64": 1, "M66": 1, "M68": 1} and ends(p) == [[1, 0, 0]]
    for text, line, match in [("G0 X1\nG1 G28 X0 F1\n", 2, "both use the axis words"),
                              ("G0 X1\nG28.1 X2\n", 2, "takes no axis words"),
                              ("G0 X1\nG10 L1 P1 Z3\n", 2, "L2 / G10 L20"),
                              ("G0 X1\nG10 L2 P1 R30 X1\nG19 G2 Y1 Z0 J0.5 F9\n", 3, "rotated"),
                              ("G0 X1\nG92\n", 2, "at least one axis"),
                              ("G0 X1\nM61 Q2\n", 2, "unsupported word M61"),
                              ("G0 X1\nM60\n", 2, "unsupported word M60"),
                              ("G0 X1\nG2 X1 Y1 R1 P1.5 F1\n", 2, "turns")]:
        with pytest.raises(GCodeError, match=match) as exc:
            parse(text)
        assert exc.value.line == line
    with pytest.raises(GCodeError, match="jogging"):
        parse("$J=G91 X10 F100\n", dialect="grbl", on_unsupported="warn")


def test_helical_turns_and_g30_positions():
    # P2: two full turns about (5, 0) while Z falls 4 mm; the polyline turns -4π (clockwise) and falls linearly
    (arc,) = parse("G0 X10 Y0 Z0\nG2 X10 Y0 Z-4 I-5 J0 P2 F100\n").moves[1:]
    assert arc.angle == pytest.approx(4 * math.pi) and _turn(arc) == pytest.approx(-4 * math.pi, abs=1e-9)
    pts = arc.points(0.01)
    assert np.all(np.diff(pts[:, 2]) < 0) and arc.length(1e-5) == pytest.approx(math.hypot(20 * math.pi, 4), 1e-5)
    p = parse("G0 X1 Y2 Z3\nG30.1\nG0 X9 Y9 Z9\nG30 X5\n")
    assert ends(p)[2:] == [[5, 9, 9], [1, 9, 9]]
