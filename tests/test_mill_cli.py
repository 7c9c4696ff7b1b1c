"""``python -m csgnb.mill``: a program, a stock and a tool in, a summary table and an STL out.

The shipped example programs (package data, :mod:`csgnb.apps.examples`) run in full only under
``-m slow``; here they are parsed, and a small program runs end to end on the octree workpiece.
"""

from __future__ import annotations

import json
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
    assert "line 1: rapid move (G0) cuts material" in capsys.readouterr().out
    bad = tmp_path / "bad.nc"
    bad.write_text("G0 X1\nG28\n")
    assert main([str(bad), "--stock", "10", "10", "3", "--no-progress"]) == 2
    assert "line 2: unsupported word G28" in capsys.readouterr().err
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
