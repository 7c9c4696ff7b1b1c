"""``python -m csgnb.mill``: a program, a stock and a tool in, a summary table and an STL out.

The shipped example programs (package data, :mod:`csgnb.apps.examples`) run in full only under
``-m slow``; here they are parsed, and a small program runs end to end on the octree workpiece.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import meshio
import pytest

from csgnb.apps.examples import EXAMPLES, example_path, example_program, make_relief
from csgnb.mill import build_parser, main


def test_a_small_program_end_to_end(tmp_path, capsys):
    prog = tmp_path / "slot.nc"
    prog.write_text("G21 G90\nG0 Z2\nG0 X5 Y5\nM3 S8000\nG1 Z-1 F100\nG1 X15 F300\nG2 X15 Y10 R2.5\nG0 Z5\nM30\n")
    out, js = tmp_path / "part.stl", tmp_path / "moves.json"
    rc = main([str(prog), "--stock", "20", "15", "5", "--tool", "flat:3:6", "--segments", "8", "--out", str(out),
               "--json", str(js), "--no-progress"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "stock - removed == part: True (exact)" in text and "collisions       0" in text
    assert meshio.read(out).cells_dict["triangle"].shape[0] > 12
    records = json.loads(js.read_text())["records"]
    assert [r["kind"] for r in records] == ["rapid", "rapid", "linear", "linear", "arc", "rapid"]


def test_collisions_set_the_exit_status_and_bad_input_is_reported(tmp_path, capsys):
    prog = tmp_path / "crash.nc"
    prog.write_text("G0 X5 Y5 Z-1\nG0 Z5\n")
    assert main([str(prog), "--stock", "10", "10", "3", "--tool", "flat:2", "--segments", "6", "--no-progress"]) == 1
    out, err = capsys.readouterr()
    assert "line 1: rapid move (G0) cuts material" in out and "1 collision(s), first at line(s) 1" in err
    bad = tmp_path / "bad.nc"
    bad.write_text("G0 X1\nG33 Z-5 K1\n")
    assert main([str(bad), "--stock", "10", "10", "3", "--no-progress"]) == 2
    assert "line 2: unsupported word G33" in capsys.readouterr().err
    assert main([str(bad), "--stock", "10", "10", "3", "--tool", "mill:3", "--no-progress"]) == 2
    assert "unknown tool kind" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["pocket.nc", "relief.nc"])
def test_shipped_programs_parse(name):
    p = example_program(name)
    assert len(p) > 40 and p.end_line is not None and not p.warnings
    assert {m.tool for m in p if m.kind != "rapid"} == {1}
    assert example_path(name.removesuffix(".nc")) == example_path(name) == EXAMPLES[name].path
    assert example_path(name).parent.parent.name == "apps"  # package data, not a path from the repository root
    with pytest.raises(KeyError, match="pocket.nc"):
        example_path("nope.nc")


def test_relief_program_is_what_its_generator_writes():
    assert example_path("relief.nc").read_text() == make_relief.program()


def test_a_shipped_example_runs_by_name(tmp_path, capsys, monkeypatch):
    """A bare example name that is not a file in the working directory runs the shipped program (here its first
    moves, standing in for it)."""
    import csgnb.mill

    short = tmp_path / "short.nc"
    short.write_text("\n".join(example_path("pocket.nc").read_text().splitlines()[:14]) + "\n")
    asked = []
    monkeypatch.setattr(csgnb.mill, "example_path", lambda name: asked.append(name) or short)
    monkeypatch.chdir(tmp_path)
    assert main(["pocket.nc", "--stock", "50", "40", "10", "--tool", "flat:6", "--segments", "8",
                 "--no-progress"]) == 0
    assert asked == ["pocket.nc"]
    assert "stock - removed == part: True (exact)" in capsys.readouterr().out
    args = build_parser().parse_args(EXAMPLES["relief.nc"].cli_args())
    assert args.program == example_path("relief.nc") and args.segments == 16 and args.tool == ["ball:4"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pocket.nc", "relief.nc"])
def test_shipped_programs_simulate_exactly(tmp_path, name):
    out = tmp_path / "part.stl"
    run = subprocess.run([sys.executable, "-m", "csgnb.mill", name, *EXAMPLES[name].cli_args()[1:], "--out", str(out),
                          "--no-progress"], capture_output=True, text=True, cwd=tmp_path, timeout=1800)
    assert run.returncode == 0, run.stderr
    assert "stock - removed == part: True (exact)" in run.stdout
    assert out.stat().st_size > 0


# -- arguments, tools, dialects (no simulation: they fail or are decided before it) ---------------------------------


@pytest.mark.parametrize("extra, match", [
    (["--rapid-rate", "0"], "--rapid-rate"), (["--rapid-rate", "-100"], "--rapid-rate"),
    (["--rapid-rate", "nan"], "--rapid-rate"), (["--checkpoint-every", "-3"], "--checkpoint-every"),
    (["--checkpoint-every", "0"], "--checkpoint-every"), (["--chord-tolerance", "1e-12"], "--chord-tolerance"),
    (["--chord-tolerance", "0"], "--chord-tolerance"), (["--chord-tolerance", "inf"], "--chord-tolerance"),
    (["--resolution", "-1"], "--resolution"), (["--start", "0", "nan", "0"], "--start"),
    (["--segments", "2"], "--segments"),
])
def test_bad_numeric_options_are_refused(tmp_path, capsys, extra, match):
    prog = tmp_path / "p.nc"
    prog.write_text("M3\nG1 X1 F100\n")
    assert main([str(prog), "--stock", "10", "10", "3", "--no-progress", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and match in err


@pytest.mark.parametrize("text, tools, match", [
    ("T2 M6\nM3\nG1 X1 F100\n", ["--tool", "1=flat:3"], "line 1: the program loads tool 2 (T2 M6)"),
    ("T1 M6\nG0 X1\nT2 M6\nG0 X2\n", ["--tool", "flat:3"], "line 1: the program loads tool 1"),
    ("T1 M6\nG0 X1\nT2 M6\nG0 X2\n", ["--tool", "1=flat:3", "--tool", "flat:2"], "line 3: the program loads tool 2"),
    ("G0 X1\n", ["--tool", "1=flat:3", "--tool", "2=flat:2"], "loads no tool"),
    ("G0 X1\nG33 X2 K1\n", ["--skip-unsupported"], "line 2: unsupported word G33"),
    ("G0 X1\nG41 D3\nG1 X20 F100\n", ["--tool", "1=flat:3"], "line 2: G41: the diameter of tool 3 is unknown"),
    ("G0 X1\n/G0 X2\n", [], "line 2: the line starts with '/'"),
])
def test_missing_tools_and_unskippable_words_are_errors_before_milling(tmp_path, capsys, text, tools, match):
    prog = tmp_path / "p.nc"
    prog.write_text(text)
    assert main([str(prog), "--stock", "10", "10", "3", "--no-progress", *tools]) == 2
    assert match in capsys.readouterr().err


def test_tool_tables_map_numbers_to_specs_and_lengths(tmp_path):
    from csgnb.apps import gcode, tools
    from csgnb.apps.tooltable import read_tool_table
    from csgnb.mill import resolve_tools

    tbl = tmp_path / "tool.tbl"
    tbl.write_text("; a LinuxCNC tool table\nT1 P1 Z30 D6 ;6 mm end mill\nT2 P2 Z+40.5 D4 ;ball:4 ball nose\n"
                   "T3 P3 Z0 ;vbit:6:90\n")
    table = read_tool_table(tbl)
    assert {k: (e.spec, e.length, e.spec_from) for k, e in table.items()} == {
        1: ("flat:6", 30.0, "diameter"), 2: ("ball:4", 40.5, "comment"), 3: ("vbit:6:90", 0.0, "comment")}
    csv = tmp_path / "tools.csv"
    csv.write_text("tool,spec,length\n1,flat:6,30\n2,bull:6:1,\n")
    assert {k: (e.spec, e.length) for k, e in read_tool_table(csv).items()} == {1: ("flat:6", 30.0),
                                                                               2: ("bull:6:1", 0.0)}
    for text, match in [("T1 D6\nT1 D4\n", "listed twice"), ("T1 Z3\n", "neither a diameter"),
                        ("T1 D6 ;ball:4\n", "disagrees"), ("T1.5 D6\n", "non-negative integer"),
                        ("T1 D6 %\n", "cannot read"), ("T1 D1e999\n", "cannot read")]:
        tbl.write_text(text)
        with pytest.raises(ValueError, match=match):
            read_tool_table(tbl)
    shapes = {k: tools.parse_tool(e.spec, segments=6) for k, e in table.items()}
    program = gcode.parse("G0 Z5\nT2 M6\nG43\nG0 X1 Z0\nT1 M6\nG43 H1\nG0 X2\nG0 Z0\n", start=(0, 0, 50),
                          tool_lengths={k: e.length for k, e in table.items()})
    chosen, notes = resolve_tools(program, {}, shapes)
    assert chosen == {2: shapes[2], 1: shapes[1], None: shapes[2]} and "tool 2" in notes[0]
    # T1 is 10.5 shorter than T2: after the change its tip hangs 10.5 higher until Z is programmed again
    assert [(m.tool, m.end[2]) for m in program] == [(None, 5.0), (2, 0.0), (1, 10.5), (1, 0.0)]
    # the first tool loaded moves nothing: the moves before it still get its shape
    program = gcode.parse("G0 Z5\nT3 M6\nT1 M6\nG0 X1\n")
    chosen, notes = resolve_tools(program, {}, shapes)
    assert chosen == {1: shapes[1], None: shapes[3]} and "tool 3" in notes[0]


def test_tool_table_dialect_and_skipped_words_end_to_end(tmp_path, capsys):
    """A GRBL program without M3 (spindle switched by hand), two tools from a table, a skipped override word."""
    prog = tmp_path / "grbl.nc"
    prog.write_text("G21 G90\nT1 M6\nG0 X5 Y5 Z2\nM48\nG1 Z-1 F100\nG1 X10\nG0 Z2\nT2 M6\nG0 X3 Y10\nG1 Z-1\n"
                    "G1 X12\nM48\nG0 Z5\n")
    tbl = tmp_path / "tools.csv"
    tbl.write_text("tool,spec\n1,flat:3:6\n2,ball:2:6\n")
    js = tmp_path / "moves.json"
    args = [str(prog), "--stock", "15", "15", "3", "--tool-table", str(tbl), "--segments", "6", "--no-progress",
            "--json", str(js)]
    assert main(args) == 2  # M48 is not skipped unless asked
    assert "line 4: unsupported word M48" in capsys.readouterr().err
    with pytest.warns(UserWarning, match="M48"):
        assert main([*args, "--skip-unsupported"]) == 1  # no M3: cutting with the spindle stopped
    out, err = capsys.readouterr()
    assert "4 collision(s), first at line(s) 5, 6, 10, 11" in err and "M48" in out
    with pytest.warns(UserWarning, match="M48"):
        assert main([*args, "--skip-unsupported", "--dialect", "grbl"]) == 0
    out = capsys.readouterr().out
    assert "collisions       0" in out and "stock - removed == part: True (exact)" in out
    assert re.search(r"^M48\s+2\s+4\s+overrides$", out, re.M)
    data = json.loads(js.read_text())
    assert data["skipped"] == [{"word": "M48", "count": 2, "first_line": 4, "why": "overrides"}]
    assert data["dialect"] == "grbl" and data["collision_lines"] == []
    cutting = [r for r in data["records"] if r["removed_mm3"] > 0]
    assert {r["line"] for r in cutting} == {5, 6, 10, 11}


@pytest.mark.parametrize("code", ["G2", "G3"])
def test_a_full_circle_cuts_the_whole_ring(tmp_path, code):
    """Issue 20's program: the circle ends where it starts; the old parser cut only the plunge (3.12 mm³) with G2."""
    prog = tmp_path / "circle.nc"
    prog.write_text(f"G0 X0 Y1.5 Z5\nM3\nG1 Z-1 F100\n{code} X0 Y1.5 I-1.5 J-2.598076 F300\nG0 Z5\n")
    js = tmp_path / "moves.json"
    # the circle: centre (-1.5, -1.098), radius 3; with the 1 mm tool radius it spans [-5.5, 2.5] x [-5.1, 2.9]
    assert main([str(prog), "--stock", "12", "12", "3", "--stock-origin", "-7", "-7", "-3", "--tool", "flat:2",
                 "--segments", "16", "--no-progress", "--json", str(js)]) == 0
    records = json.loads(js.read_text())["records"]
    assert [r["kind"] for r in records] == ["rapid", "linear", "arc", "rapid"]
    plunge, arc = records[1]["removed_mm3"], records[2]["removed_mm3"]
    # a 16-gon of circumradius 1 (area 3.06) plunged 1 mm; the ring pi (4² - 2²) = 37.7 mm³ (a little less for the
    # polygon) less the plunge's hole. The old parser removed nothing more with G2.
    assert plunge == pytest.approx(8 * math.sin(math.pi / 8), rel=5e-3)  # the fitted grid rounds the vertices
    assert 33 < arc < 35
