"""Where inside one compiled csgnb kernel the samples fall: instruction windows of ``perf`` samples over ``objdump``.

``perf report`` names csgnb's kernels through :mod:`_perf_map`, but cannot annotate them (their machine code is not
in a file). With the objects kept (``_perf_map.write_perf_map(keep_objects="/tmp/objs")``), this script bins the
samples that fall in one kernel by instruction, groups them in windows of 16 instructions and prints the hottest
windows with their disassembly -- enough to tell wide-integer products (``mulx``/``adc`` chains), conversions
(``vcvtusi2sd``, shifts through the stack) and walks (dependent loads) apart::

    perf record -F 999 -o perf.data python my_workload.py      # calls write_perf_map(keep_objects="/tmp/objs")
    python benchmarks/_perf_hot.py perf.data /tmp/objs cutting8cut_cell --windows 8 --time 30%-95%
"""

from __future__ import annotations

import argparse
import bisect
import collections
import json
import subprocess


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("data", help="perf.data")
    parser.add_argument("objects", help="the folder write_perf_map(keep_objects=...) filled")
    parser.add_argument("name", help="a substring of the kernel's mangled symbol, e.g. cutting8cut_cell")
    parser.add_argument("--windows", type=int, default=8, help="hottest windows to print")
    parser.add_argument("--time", default=None, help="perf's --time filter, e.g. 30%%-95%%")
    args = parser.parse_args()

    index = json.load(open(f"{args.objects}/index.json"))
    # the kernel itself, not its CPython or cfunc wrappers; the largest match when a name is ambiguous
    found = [e for e in index if args.name in e[2] and not e[2].startswith(("cfunc", "_ZN7cpython"))]
    if not found:
        raise SystemExit(f"no kernel symbol contains {args.name!r}")
    address, size, symbol, obj, offset = max(found, key=lambda e: e[1])
    cmd = ["perf", "script", "-i", args.data, "-F", "ip"] + (["--time", args.time] if args.time else [])
    samples = collections.Counter()
    for word in subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.split():
        ip = int(word, 16)
        if address <= ip < address + size:
            samples[ip - address] += 1
    total = sum(samples.values())
    print(f"{symbol[:80]}: {total} samples in {size} bytes")
    if not total:
        return
    dis = subprocess.run(["objdump", "-d", "--no-show-raw-insn", f"--start-address={offset}",
                          f"--stop-address={offset + size}", obj], capture_output=True, text=True, check=True).stdout
    lines = {}
    for line in dis.splitlines():
        head, _, rest = line.strip().partition(":")
        try:
            lines[int(head, 16) - offset] = rest.strip()
        except ValueError:
            continue
    starts = sorted(lines)
    windows = collections.Counter()
    for at, count in samples.items():
        windows[max(0, bisect.bisect_right(starts, at) - 1) // 16] += count
    for w, count in windows.most_common(args.windows):
        print(f"--- window at {starts[w * 16]:#x}: {100 * count / total:.1f} %")
        for at in starts[w * 16:(w + 1) * 16]:
            print(f"{samples.get(at, 0):6d} {at:#8x} {lines[at][:100]}")


if __name__ == "__main__":
    main()
