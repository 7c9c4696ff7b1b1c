"""The corpus census: every program under tests/data/gcode/corpus (and the folders in CSGNB_GCODE_CORPUS) parses or
is refused with a GCodeError naming a line -- never a raw Python exception."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest

from csgnb.apps.gcode import GCodeError, parse_file

ROOT = Path(__file__).resolve().parent.parent
CORPUS = ROOT / "tests" / "data" / "gcode" / "corpus"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_gcode_corpus", ROOT / "benchmarks" / "bench_gcode_corpus.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_corpus_program_parses_or_fails_with_a_clear_error(tmp_path):
    bench = _bench()
    extra = [Path(p) for p in os.environ.get("CSGNB_GCODE_CORPUS", "").split(":") if p]
    result = bench.census([CORPUS, *extra])
    assert result["counts"]["crash"] == 0, {p: r for p, r in result["files"].items() if r["status"] == "crash"}
    ours = {Path(p).name: r for p, r in result["files"].items() if Path(p).parent == CORPUS / "csgnb"}
    assert set(ours) == {"cam_haas_style.nc", "grbl_style.gcode", "inch_drilling.tap"}
    assert all(r["status"] == "ok" and r["moves"] > 10 for r in ours.values()), ours
    assert bench.main([str(CORPUS), "--json", str(tmp_path / "c.json")]) == 0


def test_a_crash_would_be_counted_and_a_refusal_tallied(tmp_path, monkeypatch):
    bench = _bench()
    (tmp_path / "a.nc").write_text("G0 X1\nG33 Z-5 K1\n")
    (tmp_path / "b.ngc").write_text("G0 A5\n")
    (tmp_path / "c.nc").write_text("G0 X1\n")
    result = bench.census([tmp_path])
    assert result["counts"] == {"ok": 1, "refused": 2, "crash": 0}
    assert result["unsupported"] == {"G33": 1, "A": 1}

    def boom(*a, **k):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(bench, "parse_file", boom)
    assert bench.census([tmp_path])["counts"]["crash"] == 3


def test_the_cam_style_program_runs_as_a_haas_control_would():
    with pytest.raises(GCodeError, match="O1001") as exc:
        parse_file(CORPUS / "csgnb" / "cam_haas_style.nc")
    assert exc.value.line == 2
    with pytest.warns(UserWarning, match="O1001"):
        p = parse_file(CORPUS / "csgnb" / "cam_haas_style.nc", on_unsupported="warn", start=(0, 0, 50))
    assert p.skipped["O1001"].first_line == 2 and p.end_line == 52
    # G28 G91 Z0. at the home height (the start) moves nothing; then the contour at Z-3 and the pecks to Z-8
    assert p[0].line == 15 and p[0].end.tolist() == [-4, -4, 50]
    assert min(m.end[2] for m in p if m.origin is None) == -3 and min(m.end[2] for m in p if m.origin == "G83") == -8
    drilled = sorted({(m.end[0], m.end[1]) for m in p if m.origin == "G83" and m.end[2] == -8})
    assert drilled == [(10, 10), (40, 10), (40, 20)]
    assert {m.tool for m in p if m.origin == "G83"} == {2}
    assert np.array_equal(p[-1].end[:2], [0, 0]) and p[-1].origin == "G28"


def test_the_census_mills_a_program_end_to_end_and_checks_its_stl(tmp_path):
    bench = _bench()
    prog = tmp_path / "slot.ngc"
    prog.write_text("G21 G90\nT2 M6\nG0 X0 Y0 Z5\nM3 S1000\nG1 Z-1 F100\nG1 X10\nG0 Z5\nM2\n")
    r = bench.run_one(prog, "linuxcnc", "flat:3", 3.0, 100, tmp_path)
    assert r["run"] == "ok" and r["stl_watertight"] and r["moves"] == 4, r
    assert bench.run_one(prog, "linuxcnc", "flat:3", 3.0, 2, tmp_path)["run"] == "skipped"
    lo, hi = bench.stock_for(parse_file(prog), 1.5)
    assert lo.tolist() == [-2.5, -2.5, -2.0] and hi.tolist() == [12.5, 2.5, 0.0]


def test_the_fetch_script_lists_every_source_row_at_its_commit():
    spec = importlib.util.spec_from_file_location("fetch", ROOT / "scripts" / "fetch_gcode_corpus.py")
    fetch = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fetch)
    rows = fetch.listed()
    programs = [r for r in rows if r[1].parts[0] == "programs"]
    interp = [r for r in rows if r[1].parts[0] == "linuxcnc_interp"]
    assert len(programs) >= 85 and len(interp) >= 50
    assert all(u.startswith("https://raw.githubusercontent.com/") and "/tests/interp/" in u for u, _ in interp)
    url, rel = next(r for r in programs if r[1].name == "cds.ngc")
    assert "/LinuxCNC/linuxcnc/" in url and rel.parts[1] == "LinuxCNC__linuxcnc"
