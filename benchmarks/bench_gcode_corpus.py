"""A census of real G-code programs: how many the interpreter runs, and which unsupported words are left.

    python benchmarks/bench_gcode_corpus.py [DIR ...] [--json PATH] [--dialect grbl]

Every ``.nc .ngc .gcode .tap .cnc .txt`` file under the directories (default
``tests/data/gcode/corpus``) is parsed with :func:`csgnb.apps.gcode.parse_file` (skippable words
skipped and counted). Each file ends in one of three ways:

* **ok**: its moves (and the words skipped);
* **refused**: a :class:`csgnb.apps.gcode.GCodeError` naming a line -- for an unsupported word, the
  word is tallied (``G41``, ``A``, ...), so the census says what to implement next;
* **crash**: any other exception -- a bug (``tests/test_gcode_corpus.py`` asserts there is none).

Third-party programs are not committed (their licences differ from the project's):
``tests/data/gcode/corpus/SOURCES.md`` lists where to fetch them (repository, path, licence).
``--tool-diameter MM`` gives every tool that diameter for cutter compensation (``G41``/``G42``
without a tool table). ``--json PATH`` writes ``{"files": {PATH: {"status", "moves", "line", "message", "seconds"}},
"unsupported": {WORD: files}, "skipped": {WORD: count}, "counts": {"ok", "refused", "crash"}}``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from csgnb.apps.gcode import GCodeError, parse_file

SUFFIXES = {".nc", ".ngc", ".gcode", ".tap", ".cnc", ".txt"}
DEFAULT_DIR = Path(__file__).resolve().parent.parent / "tests" / "data" / "gcode" / "corpus"


def corpus_files(dirs) -> list[Path]:
    """Every G-code file under ``dirs`` (sorted)."""
    out = []
    for d in dirs:
        d = Path(d)
        out += [p for p in d.rglob("*") if p.is_file() and p.suffix.lower() in SUFFIXES] if d.is_dir() else [d]
    return sorted(out)


def _word_kind(word: str) -> str:
    """``G42`` and ``M60`` as they are; other words by their letter (``A10`` -> ``A``)."""
    return word.upper() if word[:1].upper() in "GM$" else word[:1].upper()


def census_one(path: Path, dialect: str = "linuxcnc", tool_diameter: float | None = None) -> dict:
    """``{"status": "ok" | "refused" | "crash", ...}`` for one file (``tool_diameter``: every tool's, for G41/G42)."""
    t0 = time.perf_counter()
    diameters = None if tool_diameter is None else {None: tool_diameter}
    try:
        program = parse_file(path, on_unsupported="warn", dialect=dialect, block_delete=False,
                             tool_diameters=diameters)
    except GCodeError as exc:
        m = re.match(r"line \d+: unsupported (?:word|GRBL command) (\S+)", str(exc))
        return {"status": "refused", "line": exc.line, "word": exc.word, "message": str(exc),
                "unsupported": _word_kind(m.group(1)) if m else None,
                "seconds": time.perf_counter() - t0}
    except Exception as exc:  # noqa: BLE001 - a census records every failure; the test asserts there are none
        return {"status": "crash", "message": f"{type(exc).__name__}: {exc}", "seconds": time.perf_counter() - t0}
    return {"status": "ok", "moves": len(program.moves), "skipped": {w: s.count for w, s in program.skipped.items()},
            "seconds": time.perf_counter() - t0}


def stock_for(program, tool_radius: float) -> tuple[np.ndarray, np.ndarray] | None:
    """A stock box for a program of unknown set-up: its feed moves' extent in XY (plus the tool and 1 mm), the top at
    Z0 when the cuts go below it (else half-way up the cutting span), 1 mm of floor below the deepest cut; None when
    the program has no feed move."""
    feeds = [m for m in program.moves if m.kind != "rapid"]
    if not feeds:
        return None
    pts = np.vstack([m.points(0.05) for m in feeds])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    zmin, zmax = float(lo[2]), float(hi[2])
    top = 0.0 if zmin < 0 else (zmin + zmax) / 2 if zmax > zmin else zmin + 1.0
    pad = tool_radius + 1.0
    return (np.array([lo[0] - pad, lo[1] - pad, zmin - max(1.0, 0.2 * (top - zmin))]),
            np.array([hi[0] + pad, hi[1] + pad, top]))


def run_one(path: Path, dialect: str, tool: str, tool_diameter: float, max_moves: int, work: Path) -> dict:
    """Mill one program end to end with ``python -m csgnb.mill`` (in-process; every tool number it loads gets the
    tool ``tool``): ``{"run": "ok" | "collisions" | "failed" | "skipped", "stl_watertight", "seconds", ...}``."""
    import contextlib
    import io

    from csgnb.mill import main as mill

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        program = parse_file(path, on_unsupported="warn", dialect=dialect, block_delete=False,
                             tool_diameters={None: tool_diameter})
    if len(program.moves) > max_moves:
        return {"run": "skipped", "why": f"{len(program.moves)} moves > --max-moves {max_moves}"}
    box = stock_for(program, tool_diameter / 2)
    if box is None:
        return {"run": "skipped", "why": "no feed move"}
    lo, hi = box
    out_json, out_stl = work / (path.stem + ".json"), work / (path.stem + ".stl")
    argv = [str(path), "--stock", *map(repr, (hi - lo).tolist()), "--stock-origin", *map(repr, lo.tolist()),
            "--start", repr(float(lo[0])), repr(float(lo[1])), repr(float(max(hi[2], program.bounds()[1][2])) + 5.0),
            "--tool", tool, *[f"--tool={n}={tool}" for n in sorted({t for _, t in program.tool_changes})],
            "--segments", "12", "--no-progress", "--skip-unsupported", "--block-delete", "off",
            "--dialect", dialect, "--json", str(out_json), "--out", str(out_stl)]
    t0, c0 = time.perf_counter(), time.process_time()
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            code = mill(argv)
    except Exception as exc:  # noqa: BLE001 - the census records every failure
        return {"run": "failed", "message": f"{type(exc).__name__}: {exc}", "seconds": time.perf_counter() - t0}
    r = {"seconds": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "exit": code}
    report = json.loads(out_json.read_text()) if out_json.exists() else None
    if report is None or not report.get("complete"):
        tail = buf.getvalue().strip().splitlines()[-1:] or [""]
        return {**r, "run": "failed", "message": (report or {}).get("error") or tail[0]}
    stl = report.get("stl") or {}
    return {**r, "run": "collisions" if report["collision_lines"] else "ok", "moves": report["moves"],
            "stl_watertight": bool(stl.get("watertight")), "triangles": stl.get("triangles"),
            "first_collision_lines": report["collision_lines"][:3]}


def census(dirs, dialect: str = "linuxcnc", tool_diameter: float | None = None) -> dict:
    """The census of every file under ``dirs`` (see the module docstring for the layout)."""
    import warnings

    files, unsupported, skipped = {}, Counter(), Counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for path in corpus_files(dirs):
            r = census_one(path, dialect, tool_diameter)
            files[str(path)] = r
            if r.get("unsupported"):
                unsupported[r["unsupported"]] += 1
            for w, n in r.get("skipped", {}).items():
                skipped[w] += n
    counts = Counter(r["status"] for r in files.values())
    return {"files": files, "unsupported": dict(unsupported.most_common()), "skipped": dict(skipped.most_common()),
            "counts": {k: counts.get(k, 0) for k in ("ok", "refused", "crash")}}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dirs", nargs="*", type=Path, default=[DEFAULT_DIR])
    p.add_argument("--json", type=Path, default=None)
    p.add_argument("--dialect", choices=("linuxcnc", "grbl"), default="linuxcnc")
    p.add_argument("--run", action="store_true", help="also mill every program that parses, end to end (python -m "
                   "csgnb.mill on a stock box fitted to its cuts, --tool flat:D), and check its STL")
    p.add_argument("--max-moves", type=int, default=5000, help="--run skips longer programs")
    p.add_argument("--tool-diameter", type=float, default=None, metavar="MM",
                   help="the diameter cutter compensation (G41 D.., G42) takes for every tool: a census has no tool "
                        "tables (default: none, so such programs are refused naming the unknown diameter)")
    args = p.parse_args(argv)
    result = census(args.dirs, args.dialect, args.tool_diameter)
    for path, r in result["files"].items():
        detail = f"{r['moves']} moves" if r["status"] == "ok" else r["message"]
        print(f"{r['status']:<8} {path}: {detail}")
    c = result["counts"]
    print(f"\n{sum(c.values())} files: {c['ok']} parse, {c['refused']} refused with a csgnb error, {c['crash']} crash")
    if args.run:
        import tempfile

        diameter = args.tool_diameter or 3.0
        runs = {}
        with tempfile.TemporaryDirectory() as tmp:
            for path, r in result["files"].items():
                if r["status"] == "ok" and r["moves"]:
                    runs[path] = run_one(Path(path), args.dialect, f"flat:{diameter:g}", diameter, args.max_moves,
                                         Path(tmp))
                    x = runs[path]
                    print(f"  {x['run']:<10} {path}: " + (f"{x.get('moves')} moves, {x['seconds']:.1f} s, STL "
                          f"watertight {x.get('stl_watertight')}" if x["run"] in ("ok", "collisions")
                          else x.get("why") or x.get("message", "")))
        result["runs"] = runs
        done = [x for x in runs.values() if x["run"] in ("ok", "collisions")]
        tried = [x for x in runs.values() if x["run"] != "skipped"]
        print(f"end to end: {len(done)} of {len(tried)} milled ({sum(x['run'] == 'collisions' for x in done)} "
              f"report collisions), {sum(x['stl_watertight'] for x in done)} closed 2-manifold STLs; "
              f"{len(runs) - len(tried)} skipped")
    print("unsupported words left (files):", result["unsupported"] or "none")
    print("skipped words (occurrences):", result["skipped"] or "none")
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    return 1 if c["crash"] else 0


if __name__ == "__main__":
    sys.exit(main())
