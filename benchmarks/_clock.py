"""The clock the benchmarks' cycle figures assume: measured in the process, printed with the nominal one.

Cycles = CPU seconds x clock. :func:`measure_clock_ghz` times a dependent ``imul`` + ``add``
chain (4 cycles per step, not vectorizable, not foldable) with ``time.process_time``, so a
figure taken on a shared machine does not count other processes' slices (it is still
provisional under load); :func:`nominal_clock_ghz` reads ``/proc/cpuinfo``.
"""

from __future__ import annotations

import math
import pathlib
import platform
import time
from functools import partial

from csgnb._jit import jit

# Not cached: numba keys a cache outside the package on the file alone and would keep serving
# kernels compiled against an older csgnb.
bare_jit = partial(jit, cache=False)


@bare_jit
def _clock_chain(n, m):
    x = m
    for i in range(n):
        x = x * m + i  # imul (3 cycles) + add (1), loop-carried: not vectorizable, not foldable
    return x


def measure_clock_ghz(steps: int = 100_000_000) -> float:
    """The clock of this core in GHz, best of five runs of the dependent chain."""
    _clock_chain(10, 3)
    best = math.inf
    for _ in range(5):
        t0 = time.process_time()
        _clock_chain(steps, 3)
        best = min(best, time.process_time() - t0)
    return 4 * steps / best / 1e9


def nominal_clock_ghz() -> float | None:
    """The clock ``/proc/cpuinfo`` reports in GHz, or None."""
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("cpu MHz"):
                return float(line.split(":")[1]) / 1000
    except OSError:
        pass
    return None


def nominal_clock_label() -> str:
    """The nominal clock as printed beside wall-clock figures ("2600 MHz"), or the processor's name."""
    ghz = nominal_clock_ghz()
    return f"{ghz * 1000:.0f} MHz" if ghz else (platform.processor() or "unknown clock")


def load_average() -> tuple[float, float, float] | None:
    """The 1, 5 and 15 minute load averages (``uptime``), or None: the benchmarks print them with the figures."""
    try:
        return tuple(float(x) for x in pathlib.Path("/proc/loadavg").read_text().split()[:3])
    except (OSError, ValueError):
        return None


def best_cpu_time(fn, repeat: int, inner: int = 1) -> float:
    """Best CPU seconds per call of ``fn`` over ``repeat`` runs of ``inner`` calls (after a warm-up call)."""
    fn()
    best = math.inf
    for _ in range(repeat):
        t0 = time.process_time()
        for _ in range(inner):
            fn()
        best = min(best, (time.process_time() - t0) / inner)
    return best
