"""The G-code parser: every supported word on hand-written lines, arcs in all planes and both forms,
absolute/incremental, inch/mm, and each unsupported or malformed line a clear error with its line number.

Expected arc centres and mid-points are worked out by hand in the comments (clockwise = seen
from the positive end of the plane normal: +Z for G17, +Y for G18, +X for G19).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from csgnb.apps.gcode import Arc, GCodeError, Linear, Rapid, parse, parse_file
from csgnb.apps.sweep import arc_polyline, arc_segments


def one(text, **kw):
    p = parse(text, **kw)
    return p.moves


def test_every_supported_word_on_hand_written_lines():
    p = parse("""%
(a header comment) G21 G90 G17 G94 G40 G49 G80 G54
N10 G0 Z5 ; rapid up
N20 T3 M6 S12000 M3 M8
N30 X10 Y-2.5
N40 G1 Z-1 F150
G2 X20 Y-2.5 I5 J0
G3 X10 Y-2.5 R5
M5 M9
M4 S800
G1 X.5 F+200
M30
G0 X99 (after the end: not read)
%""")
    assert p.end_line == 12
    kinds = [m.kind for m in p]
    assert kinds == ["rapid", "rapid", "linear", "arc", "arc", "linear"]
    m0, m1, m2, m3, m4, m5 = p.moves
    assert m0.label == 10 and m0.line == 3 and m0.tool is None and not m0.spindle_on
    np.testing.assert_array_equal(m0.end, [0, 0, 5])
    assert m1.tool == 3 and m1.spindle == 12000 and m1.spindle_on and m1.label == 30
    np.testing.assert_array_equal(m1.end, [10, -2.5, 5])  # the modal G0 goes on
    assert isinstance(m2, Linear) and m2.feed == 150 and m2.label == 40
    assert isinstance(m3, Arc) and m3.clockwise and m3.plane == "XY" and m3.feed == 150
    np.testing.assert_array_equal(m3.center, [15, -2.5, -1])
    assert isinstance(m4, Arc) and not m4.clockwise
    np.testing.assert_allclose(m4.center, [15, -2.5, -1])
    assert m5.spindle == 800 and m5.spindle_on and m5.feed == 200  # M4: on, reversed
    np.testing.assert_array_equal(m5.end, [0.5, -2.5, -1])
    assert m3.start is not None and np.array_equal(m3.start, m2.end)
    assert not p.warnings


@pytest.mark.parametrize("code, start, center, mid", [
    # G17, clockwise from +Z: from angle 180° down through 90° -> (15, 5)
    ("G17 G2 X20 Y0 I5 J0", (10, 0, 0), (15, 0, 0), (15, 5, 0)),
    ("G17 G3 X20 Y0 I5 J0", (10, 0, 0), (15, 0, 0), (15, -5, 0)),
    # G18 (u = Z, v = X, normal +Y): start at (u, v) = (0, -5), angle -90°, clockwise to -180° -> z = -5
    ("G18 G2 X20 Z0 I5 K0", (10, 0, 0), (15, 0, 0), (15, 0, -5)),
    ("G18 G3 X20 Z0 I5 K0", (10, 0, 0), (15, 0, 0), (15, 0, 5)),
    # G19 (u = Y, v = Z, normal +X): start at angle 180°, clockwise to 90° -> z = +5
    ("G19 G2 Y20 Z0 J5 K0", (0, 10, 0), (0, 15, 0), (0, 15, 5)),
    ("G19 G3 Y20 Z0 J5 K0", (0, 10, 0), (0, 15, 0), (0, 15, -5)),
    # R form, quarter arcs from (0,0) to (5,5): clockwise small arc centred right of the chord at (5, 0)
    ("G17 G2 X5 Y5 R5", (0, 0, 0), (5, 0, 0), (5 - 5 / math.sqrt(2), 5 / math.sqrt(2), 0)),
    ("G17 G3 X5 Y5 R5", (0, 0, 0), (0, 5, 0), (5 / math.sqrt(2), 5 - 5 / math.sqrt(2), 0)),
    # R < 0: the 270° arc about the other centre; clockwise about (0, 5) from -90° the long way, via (-5, 5)
    ("G17 G2 X5 Y5 R-5", (0, 0, 0), (0, 5, 0), (-5, 5, 0)),
    ("G17 G3 X5 Y5 R-5", (0, 0, 0), (5, 0, 0), (10, 0, 0)),
    # R form in the other planes: G18 quarter from (x, z) = (0, 0) to (5, 5)
    ("G18 G2 X5 Z5 R5", (0, 0, 0), (0, 0, 5), (5 / math.sqrt(2), 0, 5 - 5 / math.sqrt(2))),
    ("G19 G2 Y5 Z5 R5", (0, 0, 0), (0, 5, 0), (0, 5 - 5 / math.sqrt(2), 5 / math.sqrt(2))),
])
def test_arcs_in_all_planes_and_both_forms(code, start, center, mid):
    (m,) = one(f"F100\n{code}", start=start)
    np.testing.assert_allclose(m.center, center, atol=1e-12)
    pts = m.points(1e-4)
    np.testing.assert_array_equal(pts[0], start)
    np.testing.assert_array_equal(pts[-1], m.end)
    r = m.radius
    n = m.normal
    rel = pts - m.center
    np.testing.assert_allclose(np.linalg.norm(rel - np.outer(rel @ n, n), axis=1), r, rtol=1e-9)
    # The arc passes through the expected mid-point (within one chord of a polyline point).
    chord = np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1))
    assert np.min(np.linalg.norm(pts - np.array(mid), axis=1)) <= chord
    # and turns the right way: its mid-sample is nearer the expected mid-point than the opposite one.
    opposite = 2 * np.array(m.center) - np.array(mid)
    opposite = opposite - ((opposite - np.array(m.center)) @ n) * n
    assert np.linalg.norm(pts[len(pts) // 2] - mid) < np.linalg.norm(pts[len(pts) // 2] - opposite)


def test_full_circle_and_helix():
    (m,) = one("G17 G2 I5 J0 F100", start=(0, 0, 0))
    np.testing.assert_array_equal(m.start, m.end)
    assert m.length(1e-5) == pytest.approx(2 * math.pi * 5, rel=1e-5)
    (h,) = one("G17 G3 X10 Y0 Z-3 I5 F100", start=(0, 0, 0))
    pts = h.points(0.01)
    assert np.all(np.diff(pts[:, 2]) < 0) and pts[-1, 2] == -3
    chord = np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1))
    assert np.min(np.linalg.norm(pts[:, :2] - [5, -5], axis=1)) <= chord


def test_chord_tolerance_is_respected():
    for r, tol in [(5.0, 0.01), (50.0, 0.001), (0.5, 0.1)]:
        pts = arc_polyline((r, 0, 0), (-r, 0, 0), (0, 0, 0), (0, 0, 1), False, tolerance=tol)
        mids = (pts[1:] + pts[:-1]) / 2
        assert np.all(r - np.linalg.norm(mids, axis=1) <= tol * (1 + 1e-9))
        assert len(pts) - 1 == arc_segments(r, math.pi, tol)


def test_absolute_incremental_inch_mm():
    moves = one("""G21 G90 G0 X1 Y2 Z3
G91 G0 X1 Y1 Z-1
G0 X1
G20 G0 X1
G90 G0 X1
G21 G0 Y5
G20 F10 G1 X0
G21 G1 X1
G20 G91 G2 X0.2 Y0 I0.1 J0
""")
    ends = [m.end.tolist() for m in moves]
    assert ends[:6] == [[1, 2, 3], [2, 3, 2], [3, 3, 2], [3 + 25.4, 3, 2], [25.4, 3, 2], [25.4, 5, 2]]
    assert moves[6].feed == pytest.approx(254.0) and moves[6].end.tolist() == [0, 5, 2]
    assert moves[7].feed == pytest.approx(10.0)  # F10 read in mm once G21 is back
    arc = moves[8]
    np.testing.assert_allclose(arc.end, [0.2 * 25.4 + 1, 5, 2])
    np.testing.assert_allclose(arc.center, [1 + 0.1 * 25.4, 5, 2])


def test_tool_and_spindle_state_travels_with_moves():
    moves = one("T1 M6\nM3 S1000\nG1 X1 F10\nT2\nG1 X2\nM6\nM5\nG1 X3\n")
    assert [(m.tool, m.spindle_on) for m in moves] == [(1, True), (1, True), (2, False)]


@pytest.mark.parametrize("text, line, word", [
    ("G0 X1\nG0 A10\n", 2, "A10"),
    ("G0 X1\nG1 X2 W3 F5\n", 2, "W3"),
    ("G17\n\nG33.1 Z-5 K1\n", 3, "G33.1"),
    ("G43.2 H1\n", 1, "G43.2"),
    ("G33 Z-5 K1\n", 1, "G33"),
    ("G38.2 Z-5 F10\n", 1, "G38.2"),
    ("G76 P1 Z-5\n", 1, "G76"),
    ("G12 I5\n", 1, "G12"),
    ("M60\n", 1, "M60"),
    ("G1 X1 E5 F10\n", 1, "E5"),
])
def test_words_that_change_the_cut_are_errors_never_skipped(text, line, word):
    for mode in ("error", "warn"):
        with pytest.raises(GCodeError) as exc:
            parse(text, on_unsupported=mode)
        assert exc.value.line == line and exc.value.word == word
        assert str(exc.value).startswith(f"line {line}: unsupported word {word}")


def test_skippable_words_are_errors_or_counted_in_the_skipped_table():
    text = "G97 S100\nM48\nG0 X1\nM48\nM100 P1\nM48 G0 Y1\n"
    with pytest.raises(GCodeError) as exc:
        parse(text)
    assert exc.value.line == 1 and exc.value.word == "G97" and "on_unsupported='warn'" in str(exc.value)
    with pytest.warns(UserWarning, match="unsupported word") as caught:
        p = parse(text, on_unsupported="warn")
    assert [str(w.message).split(":")[0] for w in caught] == ["line 1", "line 2", "line 5"]  # once per word
    assert [m.end.tolist() for m in p] == [[1, 0, 0], [1, 1, 0]]  # the line's other words still count
    assert {w: (s.count, s.first_line) for w, s in p.skipped.items()} == {"G97": (1, 1), "M48": (3, 2),
                                                                          "M100": (1, 5)}
    assert "M48" in p.skipped_table() and len(p.warnings) == 3
    with pytest.raises(ValueError, match="on_unsupported"):
        parse("G0 X1", on_unsupported="ignore")


@pytest.mark.parametrize("text, line, match", [
    ("G0 X1\nG1 X2\n", 2, "feed rate"),
    ("G1 X2 F0\n", 1, "feed rate"),
    ("F100\nX5\n", 2, "without a motion mode"),
    ("G0 X1 X2\n", 1, "appears twice"),
    ("G0 G1 X1 F10\n", 1, "both in the motion modal group"),
    ("G1 X1.2.3 F10\n", 1, "cannot read"),
    ("G1 X F10\n", 1, "cannot read"),
    ("G1 X1 F10 #1\n", 1, "cannot read"),
    ("F10\nG2 X1 Y1\n", 2, "needs a centre"),
    ("F10\nG2 X1 Y0 I0.5 R0.5\n", 2, "either I J K offsets or R"),
    ("F10\nG2 X10 Y1 I5 J0\n", 2, "off the arc's circle"),
    ("F10\nG17 G2 X1 Y0 K1\n", 2, "not an offset of the XY plane"),
    ("F10\nG2 X0 Y0 R5\n", 2, "cannot be a full circle"),
    ("F10\nG2 X10 Y0 R2\n", 2, "less than half the chord"),
    ("F10\nG2 X1 Y0 I0 J0\n", 2, "zero-radius arc"),
    ("G0 X1 I5\n", 1, "no G2/G3 arc"),
    ("G1 X1 F-5\n", 1, "must not be negative"),
    ("S-1\n", 1, "must not be negative"),
    ("T1.5\n", 1, "non-negative integer"),
    ("M6\n", 1, "no T word"),
    ("N-1 G0 X1\n", 1, "line number must not be negative"),
    ("G0 X1 (open comment\n", 1, "not closed"),
    ("G0 X1 (a (nested) one)\n", 1, "nested"),
    ("G0 X1 )\n", 1, "closes no comment"),
    ("M3 M5\n", 1, "both in the spindle group"),
])
def test_malformed_lines_are_errors_with_their_line(text, line, match):
    with pytest.raises(GCodeError, match=match) as exc:
        parse(text, on_unsupported="warn")
    assert exc.value.line == line
    assert str(exc.value).startswith(f"line {line}: ")


def test_parse_file_and_program_helpers(tmp_path):
    f = tmp_path / "p.nc"
    f.write_text("G0 X1 Y1 Z1\nG1 X3 F100\n")
    p = parse_file(f)
    assert len(p) == 2 and isinstance(p[0], Rapid)
    lo, hi = p.bounds()
    assert lo.tolist() == [0, 0, 0] and hi.tolist() == [3, 1, 1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parse("G0 X0 ; fine\n(only a comment)\n\n%\n")


@pytest.mark.parametrize("text, ok", [
    # LinuxCNC's arc_data_ijk: the end radius may differ by 0.0283 mm (0.00283 inch under G20), or by 0.1 %, but by
    # no more than 100 x 0.0283 mm
    ("G21 F10\nG2 X50.028 Y0 I25 J0\n", True),  # 0.028 mm on a 25 mm radius (LinuxCNC's good-arc test)
    ("G21 F10\nG2 X50.029 Y0 I25 J0\n", False),  # 0.029 mm and 0.116 %
    ("G21 F10\nG2 X400.05 Y0 I200 J0\n", True),  # 0.05 mm but 0.025 % of 200 mm
    ("G21 F10\nG2 X6002.9 Y0 I3000 J0\n", False),  # 2.9 mm: beyond 100 x the tolerance even at 0.1 %
    ("G20 F10\nG2 X2.0028 Y0 I1 J0\n", True),  # 0.0028 inch
    ("G20 F10\nG2 X2.0029 Y0 I1 J0\n", False),
])
def test_arc_end_radius_tolerance_is_linuxcncs(text, ok):
    if ok:
        arc = parse(text).moves[-1]
        assert arc.kind == "arc" and arc.angle == pytest.approx(math.pi)
    else:
        with pytest.raises(GCodeError, match="off the arc's circle"):
            parse(text)


def test_fractional_line_numbers_are_labels_as_in_linuxcnc():
    assert [m.label for m in parse("N4567.789 G0 X1\nN10 G0 X2\n").moves] == [4567.789, 10]


def test_g52_is_a_local_offset_in_g92s_registers():
    moves = parse("G0 X1 Y1\nG52 X10 Y5\nG0 X0 Y0\nG52 X0\nG0 X0 Y0\nG92.1\nG0 X0 Y0\nG20 G52 Y1\nG0 Y0\n").moves
    assert [m.end[:2].tolist() for m in moves] == [[1, 1], [10, 5], [0, 5], [0, 0], [0, 25.4]]
    with pytest.raises(GCodeError, match="both use the axis words"):
        parse("G52 G0 X1\n")


@pytest.mark.parametrize("code, path, dwell", [
    ("G84", [("rapid", 5), ("rapid", 2), ("linear", -5), ("linear", 2), ("rapid", 5)], 0.0),  # tap: feed in and out
    ("G86", [("rapid", 5), ("rapid", 2), ("linear", -5), ("rapid", 5)], 0.5),  # bore: dwell, rapid out
])
def test_tapping_and_boring_cycles_sweep_as_linuxcnc_moves_them(code, path, dwell):
    p = parse(f"G0 X0 Y0 Z5\nF100 S500 M3\n{code} X10 Y0 Z-5 R2 P0.5\nG80\n")
    assert [(m.kind, float(m.end[2])) for m in p.moves[1:]] == path
    assert all(m.origin == code for m in p.moves[1:]) and p.dwell_s == dwell


FANUC = """G21 G90 F100
#1 = 0
G0 X0 Y0 Z5
M98 P1000 L3
M98 P1000 L0
G0 Z10
M30
O1000
G91 G0 X10
#1 = [#1 + 1]
G90 G1 Z[-#1]
G0 Z5
M99
"""


def test_fanuc_subroutines_run_by_m98_with_repeats_and_shared_parameters():
    p = parse(FANUC)
    cuts = [m.end.tolist() for m in p.moves if m.kind == "linear"]
    assert cuts == [[10, 0, -1], [20, 0, -2], [30, 0, -3]]  # three calls; #1 is shared with the caller
    assert p.moves[-1].end.tolist() == [30, 0, 10] and p.end_line == 7  # L0 calls nothing; the body is not run
    assert "O1000" not in p.skipped


@pytest.mark.parametrize("text, match", [
    ("M98 P7\nM30\n", "defines no subroutine O7"),
    ("M98\n", "needs P"),
    ("M98 P1 L-1\nM30\nO1\nM99\n", "non-negative integer"),
    ("G0 X1\nM99\n", "M99 outside an M98 call"),
    ("M98 P1\nM30\nO1\nM98 P1\nM99\n", "nests deeper"),
])
def test_fanuc_subroutine_errors_name_the_line(text, match):
    with pytest.raises(GCodeError, match=match):
        parse(text)


def test_incremental_canned_cycles_count_r_from_the_initial_level_hole_after_hole():
    # LinuxCNC's cycle_il: under G91 the R plane is R above where the tool stood when G81 began, for every hole
    p = parse("G0 X0 Y0 Z0.25\nF40\nG91 G99 G81 X1 Z-1 R0.25\nG81 X1 Z-1 R0.25\nG80\n")
    assert [m.end.round(6).tolist() for m in p.moves if m.kind == "linear"] == [[1, 0, -0.5], [2, 0, -0.5]]


def test_rotated_coordinate_systems_turn_moves_and_arcs_about_their_origin():
    p = parse("G10 L2 P1 X10 Y0 R90\nG0 X1 Y0\nF100\nG2 X0 Y-1 I-1 J0\nG91 G1 X1\nG90 G10 L2 P1 R0\nG0 X1 Y0\n")
    ends = [m.end.round(9).tolist() for m in p.moves]
    assert ends == [[10, 1, 0], [11, 0, 0], [11, 1, 0], [11, 0, 0]]  # program (1, 0) -> machine (10, 1), ...
    arc = p.moves[1]
    assert arc.center.round(9).tolist() == [10, 0, 0] and arc.clockwise  # I J turn with the system
    with pytest.raises(GCodeError, match="rotated coordinate system"):
        parse("G10 L2 P1 R30\nG18 F10\nG2 X1 Z0 I0.5 K0\n")
    # G10 L20 in a rotated system: the current point becomes the given program coordinates
    q = parse("G10 L2 P1 R90\nG0 X5 Y0\nG10 L20 P1 X0 Y0\nG0 X1 Y0\n").moves
    assert q[0].end.round(9).tolist() == [0, 5, 0] and q[1].end.round(9).tolist() == [0, 6, 0]


def test_modal_state_saved_and_restored_by_m70_to_m73():
    p = parse("G21 G90 F100\nM70\nG20 G91\nG1 X1\nM72\nG1 X1\n"
              "o<sub> sub\nM73\nG20 G91\nG1 X1\no<sub> endsub\no<sub> call\nG1 X2\n")
    assert [m.end[0].round(9) for m in p.moves] == [25.4, 1.0, 26.4, 2.0]  # inch, relative; then mm, absolute
    with pytest.raises(GCodeError, match="none is saved"):
        parse("M72\n")
    with pytest.raises(GCodeError, match="inside an o-word sub"):
        parse("M73\n")
    with pytest.raises(GCodeError, match="while cutter compensation is on"):
        parse("G0 X-10\nM70\nG20\nG41.1 D0.1\nG1 X0 F10\nM72\n")
