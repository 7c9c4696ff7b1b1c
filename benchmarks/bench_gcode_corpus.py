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
from collections import Counter
from pathlib import Path

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
    print("unsupported words left (files):", result["unsupported"] or "none")
    print("skipped words (occurrences):", result["skipped"] or "none")
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    return 1 if c["crash"] else 0


if __name__ == "__main__":
    sys.exit(main())
