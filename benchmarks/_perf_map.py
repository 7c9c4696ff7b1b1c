"""Name csgnb's compiled kernels for ``perf``: a ``/tmp/perf-PID.map`` from numba's object code.

numba's machine code lives in anonymous memory, so ``perf report`` shows bare addresses for
it. Import this module **before** csgnb loads its kernels (from the numba cache or by
compiling them), run the workload, then call :func:`write_perf_map`: it finds every compiled
csgnb function in the process, reads the symbol sizes from the object code numba loaded
(``readelf``), asks numba for their addresses, and writes the map ``perf`` reads for JIT
code. Functions inlined into their callers have no symbol of their own and count towards
the caller. With ``keep_objects`` the object files and an index (address, size, symbol,
file, offset) are kept, so hot instructions can be found with ``objdump -d``::

    perf record -o perf.data python benchmarks/bench_iterated.py --workloads dome --perf-map
    perf report -i perf.data --no-children --sort sym
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from numba.core import codegen as _codegen

_original_set = _codegen.CPUCodeLibrary._set_compiled_object


def _keep_object(self, value):
    # numba drops the object code once it is loaded; keep a reference for the symbol table.
    self._perf_map_object = value
    return _original_set(self, value)


_codegen.CPUCodeLibrary._set_compiled_object = _keep_object


def _short_name(symbol: str) -> str:
    """``module.function`` from a numba-mangled symbol (``_ZN5csgnb3bsp7merging11merge_cells...``)."""
    if "_ZN" not in symbol:
        return symbol
    i = symbol.index("_ZN") + 3
    names = []
    while i < len(symbol) and symbol[i].isdigit():
        j = i
        while symbol[j].isdigit():
            j += 1
        n = int(symbol[i:j])
        names.append(symbol[j:j + n])
        i = j + n
    return ".".join(names[-2:]) if names else symbol


def write_perf_map(keep_objects: str | None = None) -> Path:
    """Write ``/tmp/perf-<pid>.map`` for every compiled function of csgnb in this process; return its path."""
    folder = Path(keep_objects or tempfile.mkdtemp(prefix="csgnb-perf-"))
    folder.mkdir(parents=True, exist_ok=True)
    seen, rows = set(), []
    for name, module in list(sys.modules.items()):
        if not name.startswith("csgnb"):
            continue
        for obj in list(vars(module).values()):
            overloads = getattr(obj, "overloads", None)
            if not isinstance(overloads, dict):
                continue
            for cres in overloads.values():
                lib = getattr(cres, "library", None)
                data = getattr(lib, "_perf_map_object", None)
                if data is None or id(lib) in seen:
                    continue
                seen.add(id(lib))
                path = folder / f"{len(seen)}.o"
                path.write_bytes(data)
                table = subprocess.run(["readelf", "-sW", str(path)], capture_output=True, text=True).stdout
                for line in table.splitlines():
                    p = line.split()
                    if len(p) >= 8 and p[3] == "FUNC" and p[6] != "UND":
                        try:
                            address = lib.get_pointer_to_function(p[7])
                        except Exception:  # a symbol numba does not export
                            continue
                        if address:
                            rows.append((address, int(p[2], 0), p[7], str(path), int(p[1], 16)))
    rows = sorted(set(rows))
    out = Path(f"/tmp/perf-{os.getpid()}.map")
    with open(out, "w") as fh:
        for address, size, symbol, _, _ in rows:
            fh.write(f"{address:x} {max(size, 1):x} {_short_name(symbol)}\n")
    if keep_objects:
        (folder / "index.json").write_text(json.dumps(rows))
    print(f"perf map: {len(rows)} compiled functions named in {out}", file=sys.stderr)
    return out
