"""A reproducible pseudo-random order in compiled code, shared by csgnb's kernels.

The paper inserts a BSP's faces in a random order (§3.6: no balancing heuristic needed inside an octree cell), and an
incremental convex hull inserts its points in one (sorted points would see most faces at every step). Both want the
same order on every run and platform, without numpy's generator inside a kernel: Fisher-Yates driven by a 64-bit
linear congruential generator (Knuth's MMIX constants).
"""

from __future__ import annotations

import numpy as np

from csgnb._jit import jit

__all__ = ["shuffle_order"]


@jit(inline="always")
def shuffle_order(order, n, seed):
    """``order[:n]`` := a permutation of ``0 .. n - 1`` fixed by ``seed`` (int64 ``order``, ``n <= len(order)``)."""
    x = np.uint64(seed) * np.uint64(6364136223846793005) + np.uint64(1442695040888963407)
    for i in range(n):
        order[i] = i
    for i in range(n - 1, 0, -1):
        x = x * np.uint64(6364136223846793005) + np.uint64(1442695040888963407)
        j = np.int64((x >> np.uint64(33)) % np.uint64(i + 1))
        t = order[i]
        order[i] = order[j]
        order[j] = t
