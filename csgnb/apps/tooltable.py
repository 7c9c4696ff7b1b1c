"""Tool tables: tool numbers (``T2 M6``) mapped to csgnb tool specs and lengths (``G43``).

Two formats, both in millimetres:

* LinuxCNC ``tool.tbl`` (any other suffix than ``.csv``): one tool a line,
  ``T2 P2 Z35.5 D6 ;ball:6 a 6 mm ball end mill``. ``T`` is the number, ``Z`` the length
  offset, ``D`` the diameter; ``P X Y A B C U V W I J Q`` are read and ignored (pocket, other
  offsets, lathe orientation). The shape comes from the comment when it starts with a csgnb
  spec (``flat:D``, ``ball:D``, ``bull:D:R``, ``vbit:D:ANGLE``, ``drill:D``); otherwise the tool
  is a flat end mill of diameter ``D``. A spec whose diameter disagrees with ``D`` is an error.
* CSV with a header naming ``tool`` and ``spec`` and optionally ``length``:
  ``tool,spec,length`` / ``2,ball:6,35.5``.

Every problem is a ``ValueError`` naming the file and the line.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

from csgnb.apps.tools import _KINDS

__all__ = ["ToolEntry", "read_tool_table"]

_TBL_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")


@dataclass(frozen=True)
class ToolEntry:
    """One tool of a table: its number, csgnb spec, length offset (mm) and where it was read."""

    number: int
    spec: str
    length: float
    line: int
    spec_from: str  # 'comment', 'diameter' or 'csv'


def _number(path, line, text, what) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{path}:{line}: {what} {text!r} is not a number") from None
    if not math.isfinite(v) or abs(v) > 1e6:
        raise ValueError(f"{path}:{line}: {what} {text!r} must be a finite number of mm (at most 1e6)")
    return v


def _tool_number(path, line, value: float) -> int:
    if value != int(value) or value < 0:
        raise ValueError(f"{path}:{line}: the tool number T{value:g} must be a non-negative integer")
    return int(value)


def _check_spec(path, line, spec: str) -> str:
    kind = spec.partition(":")[0]
    if kind not in _KINDS:
        raise ValueError(f"{path}:{line}: unknown tool kind in {spec!r}; use one of {sorted(_KINDS)} (e.g. ball:6)")
    return spec


def _read_tbl(path: Path, text: str) -> dict[int, ToolEntry]:
    out: dict[int, ToolEntry] = {}
    for line, raw in enumerate(text.splitlines(), start=1):
        code, _, comment = raw.partition(";")
        if not code.strip():
            continue
        words: dict[str, float] = {}
        pos, s = 0, code.strip()
        while pos < len(s):
            if s[pos].isspace():
                pos += 1
                continue
            m = _TBL_WORD.match(s, pos)
            if m is None or m.group(1).upper() not in "TPXYZABCUVWDIJQ":
                raise ValueError(f"{path}:{line}: cannot read {s[pos:pos + 12]!r}: a tool.tbl line is words like "
                                 "T1 P1 Z30 D6 and a ';' comment")
            letter = m.group(1).upper()
            if letter in words:
                raise ValueError(f"{path}:{line}: the word {letter} appears twice")
            words[letter] = _number(path, line, m.group(2), letter)
            pos = m.end()
        if "T" not in words:
            raise ValueError(f"{path}:{line}: a tool line needs its number T")
        number = _tool_number(path, line, words["T"])
        first = comment.strip().split()[0] if comment.strip() else ""
        diameter = words.get("D")
        if first.partition(":")[0] in _KINDS:
            spec, spec_from = _check_spec(path, line, first), "comment"
            if diameter is not None:
                try:
                    spec_d = float(first.split(":")[1])
                except (IndexError, ValueError):
                    raise ValueError(f"{path}:{line}: the spec {first!r} needs a diameter, e.g. ball:6") from None
                if abs(spec_d - diameter) > 1e-9 * max(1.0, abs(diameter)):
                    raise ValueError(f"{path}:{line}: D{diameter:g} disagrees with the spec {first!r} in the "
                                     f"comment (diameter {spec_d:g}); correct one of them")
        elif diameter is not None:
            if not diameter > 0:
                raise ValueError(f"{path}:{line}: the diameter D{diameter:g} must be positive")
            spec, spec_from = f"flat:{diameter:g}", "diameter"
        else:
            raise ValueError(f"{path}:{line}: tool T{number} has neither a diameter D nor a csgnb spec at the start "
                             "of its comment (e.g. ';ball:6')")
        if number in out:
            raise ValueError(f"{path}:{line}: tool T{number} is listed twice (first on line {out[number].line})")
        out[number] = ToolEntry(number, spec, words.get("Z", 0.0), line, spec_from)
    return out


def _read_csv(path: Path, text: str) -> dict[int, ToolEntry]:
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise ValueError(f"{path}: the tool table is empty")
    header = [h.strip().lower() for h in rows[0]]
    if "tool" not in header or "spec" not in header:
        raise ValueError(f"{path}:1: a CSV tool table starts with a header naming the columns tool, spec and "
                         f"optionally length; got {rows[0]!r}")
    unknown = set(header) - {"tool", "spec", "length"}
    if unknown:
        raise ValueError(f"{path}:1: unknown columns {sorted(unknown)} (tool, spec, length)")
    out: dict[int, ToolEntry] = {}
    for line, row in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise ValueError(f"{path}:{line}: {len(row)} fields where the header has {len(header)}")
        rec = dict(zip(header, (c.strip() for c in row), strict=True))
        number = _tool_number(path, line, _number(path, line, rec["tool"], "tool"))
        spec = _check_spec(path, line, rec["spec"])
        length = _number(path, line, rec["length"], "length") if rec.get("length") else 0.0
        if number in out:
            raise ValueError(f"{path}:{line}: tool {number} is listed twice (first on line {out[number].line})")
        out[number] = ToolEntry(number, spec, length, line, "csv")
    return out


def read_tool_table(path) -> dict[int, ToolEntry]:
    """Tool number -> :class:`ToolEntry` from a LinuxCNC ``tool.tbl`` or a ``.csv`` table (mm)."""
    path = Path(path)
    text = path.read_bytes().decode("utf-8-sig", errors="replace")
    table = _read_csv(path, text) if path.suffix.lower() == ".csv" else _read_tbl(path, text)
    if not table:
        raise ValueError(f"{path}: the tool table lists no tools")
    return table
