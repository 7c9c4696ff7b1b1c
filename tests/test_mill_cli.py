"""``python -m csgnb.mill``: a program, a stock and a tool in, a summary table and an STL out.

The shipped example programs run in full only under ``-m slow`` (minutes on the single-BSP
stand-in); here they are parsed, and a small program runs end to end.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import meshio
import pytest

from csgnb.apps import gcode
from csgnb.mill import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "gcode"


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
    assert "line 1: rapid move (G0) cuts material" in capsys.readouterr().out
    bad = tmp_path / "bad.nc"
    bad.write_text("G0 X1\nG28\n")
    assert main([str(bad), "--stock", "10", "10", "3", "--no-progress"]) == 2
    assert "line 2: unsupported word G28" in capsys.readouterr().err
    assert main([str(bad), "--stock", "10", "10", "3", "--tool", "mill:3", "--no-progress"]) == 2
    assert "unknown tool kind" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["pocket.nc", "relief.nc"])
def test_shipped_programs_parse(name):
    p = gcode.parse_file(EXAMPLES / name)
    assert len(p) > 40 and p.end_line is not None and not p.warnings
    assert {m.tool for m in p if m.kind != "rapid"} == {1}


def test_relief_program_is_what_its_generator_writes():
    sys.path.insert(0, str(EXAMPLES))
    try:
        import make_relief
    finally:
        sys.path.pop(0)
    assert (EXAMPLES / "relief.nc").read_text() == make_relief.program()


@pytest.mark.slow
@pytest.mark.parametrize("name, stock, tool", [("pocket.nc", ["50", "40", "10"], "flat:6"),
                                               ("relief.nc", ["40", "30", "8"], "ball:4")])
def test_shipped_programs_simulate_exactly(tmp_path, name, stock, tool):
    out = tmp_path / "part.stl"
    run = subprocess.run([sys.executable, "-m", "csgnb.mill", str(EXAMPLES / name), "--stock", *stock, "--tool",
                          tool, "--segments", "16", "--out", str(out), "--no-progress"],
                         capture_output=True, text=True, cwd=ROOT, timeout=1800)
    assert run.returncode == 0, run.stderr
    assert "stock - removed == part: True (exact)" in run.stdout
    assert out.stat().st_size > 0
