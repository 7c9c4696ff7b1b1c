"""Fetch the public G-code programs and LinuxCNC interpreter tests listed in tests/data/gcode/corpus/SOURCES.md.

    python scripts/fetch_gcode_corpus.py DIR [--dry-run]

Third-party programs are not committed (their licences are their own; this project commits no
third-party code): SOURCES.md lists each with the commit it was read at, and this script
downloads exactly those versions from raw.githubusercontent.com into

* ``DIR/programs/OWNER__REPO/PATH`` (for ``benchmarks/bench_gcode_corpus.py``), and
* ``DIR/linuxcnc_interp/PATH`` (LinuxCNC's ``tests/interp``, for ``benchmarks/bench_gcode_oracle.py``).

``--dry-run`` prints the URLs only. A file that cannot be fetched is reported and the others go on;
the exit status is 1 if any failed.
"""

from __future__ import annotations

import argparse
import sys
import urllib.request
from pathlib import Path

SOURCES = Path(__file__).resolve().parent.parent / "tests" / "data" / "gcode" / "corpus" / "SOURCES.md"
RAW = "https://raw.githubusercontent.com/{repo}/{commit}/{path}"


def listed(sources: Path = SOURCES) -> list[tuple[str, Path]]:
    """(URL, destination relative to DIR) for every row of the two tables of ``sources``."""
    out, section = [], None
    for line in sources.read_text().splitlines():
        if line.startswith("### Programs"):
            section = "programs"
        elif line.startswith("### LinuxCNC interpreter tests"):
            section = "interp"
        if section is None or not line.startswith("| ") or line.startswith(("| repository", "| path")):
            continue
        cells = [c.strip() for c in line.strip("|").split("|")]
        if section == "programs" and len(cells) >= 3:
            repo, path, commit = cells[:3]
            out.append((RAW.format(repo=repo, commit=commit, path=path),
                        Path("programs") / repo.replace("/", "__") / path))
        elif section == "interp" and len(cells) >= 2:
            path, commit = cells[:2]
            out.append((RAW.format(repo="LinuxCNC/linuxcnc", commit=commit, path=f"tests/interp/{path}"),
                        Path("linuxcnc_interp") / path))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dir", type=Path)
    p.add_argument("--dry-run", action="store_true", help="print the URLs, fetch nothing")
    args = p.parse_args(argv)
    rows = listed()
    failed = 0
    for url, rel in rows:
        if args.dry_run:
            print(url, "->", args.dir / rel)
            continue
        dest = args.dir / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        try:
            with urllib.request.urlopen(url, timeout=30) as r:  # noqa: S310 - fixed https URLs from SOURCES.md
                dest.write_bytes(r.read())
        except OSError as exc:
            failed += 1
            print(f"could not fetch {url}: {exc}", file=sys.stderr)
    print(f"{len(rows) - failed} of {len(rows)} files {'listed' if args.dry_run else 'fetched'} into {args.dir}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
