"""csgnb's interpreter against LinuxCNC's own outputs (benchmarks/bench_gcode_oracle.py).

LinuxCNC's regression tests (``tests/interp/*/expected``: what its interpreter printed for each program) are GPL-2.0
and not committed; set ``CSGNB_LINUXCNC_INTERP`` to a copy of that folder to run the comparison here. The
comparator itself is tested on canonical output written for this file."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _oracle():
    spec = importlib.util.spec_from_file_location("bench_gcode_oracle", ROOT / "benchmarks" / "bench_gcode_oracle.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


PROGRAM = "G20 G90 G17\nG10 L2 P1 X1\nG0 X1 Y0 Z0.5\nG1 Z-0.1 F10\nG3 X0 Y1 I-1 J0\nG2 X0 Y1 I0 J-1 P2\n"
CANON = """ N..... USE_LENGTH_UNITS(CANON_UNITS_INCHES)
 N..... SET_G5X_OFFSET(1, 1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
 N..... STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.5000, 0.0000, 0.0000, 0.0000)
 N..... SET_FEED_RATE(10.0000)
 N..... STRAIGHT_FEED(1.0000, 0.0000, -0.1000, 0.0000, 0.0000, 0.0000)
 N..... ARC_FEED(0.0000, 1.0000, 0.0000, 0.0000, 1, -0.1000, 0.0000, 0.0000, 0.0000)
 N..... ARC_FEED(0.0000, 1.0000, 0.0000, 0.0000, -2, -0.1000, 0.0000, 0.0000, 0.0000)
"""


def test_the_comparator_reads_canonical_output_with_offsets_units_and_turns(tmp_path):
    oracle = _oracle()
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "test.ngc").write_text(PROGRAM)
    (tmp_path / "t" / "expected").write_text(CANON)
    assert oracle.check_folder(tmp_path / "t") == {"status": "agree", "moves": 4}
    (tmp_path / "t" / "expected").write_text(CANON.replace("-2, -0.1000", "-1, -0.1000"))
    r = oracle.check_folder(tmp_path / "t")
    assert r["status"] == "differ" and r["move"] == 3  # one turn where the program asks for two
    (tmp_path / "t" / "expected").write_text(CANON.replace("ARC_FEED(0.0000, 1.0000, 0.0000, 0.0000, 1",
                                                           "ARC_FEED(0.0000, 1.0001, 0.0000, 0.0000, 1"))
    assert oracle.check_folder(tmp_path / "t")["status"] == "agree"  # within the printed precision
    (tmp_path / "t" / "expected").write_text(CANON.replace("STRAIGHT_FEED(1.0000", "STRAIGHT_FEED(1.0010"))
    assert oracle.check_folder(tmp_path / "t")["move"] == 1
    (tmp_path / "t" / "test.ngc").write_text("G0 A1\n")
    assert oracle.check_folder(tmp_path / "t")["status"] == "refused"


@pytest.mark.skipif(not os.environ.get("CSGNB_LINUXCNC_INTERP"), reason="set CSGNB_LINUXCNC_INTERP to a copy of "
                    "LinuxCNC's tests/interp to compare with its interpreter")
def test_every_linuxcnc_program_we_run_gives_linuxcncs_moves(tmp_path):
    oracle = _oracle()
    root = Path(os.environ["CSGNB_LINUXCNC_INTERP"])
    results = {str(f.relative_to(root)): oracle.check_folder(f) for f in oracle.folders(root)}
    assert results
    wrong = {k: r for k, r in results.items() if r["status"] in ("differ", "crash")}
    assert not wrong, wrong
