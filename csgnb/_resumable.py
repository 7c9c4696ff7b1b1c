"""One resumable-kernel mechanism: status codes and the growth policy shared by csgnb's kernels.

Kernels that fill arrays whose final size is not known up front (extraction, merge,
import, the octree operations) never allocate in their hot loops. Before a step that
could overflow, a kernel checks its capacity; if an array is short it returns
:data:`NEED_ROOM` *before* changing anything for that step, the Python driver grows
what was short (geometrically, so a run resumes O(log n) times) and calls the kernel
again, which continues where it stopped (its progress lives in a ``state`` array).
Sized well, a call never resumes on the common path.

* :data:`DONE` -- finished; :data:`NEED_ROOM` -- grow and call again;
  :data:`FAILED` -- an internal invariant failed (raise :class:`~csgnb.errors.InternalError`).
* :func:`grown` -- the one growth rule (at least double, at least what is needed).
* :func:`run_resumable` -- the driver loop.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from csgnb.errors import InternalError

__all__ = ["DONE", "NEED_ROOM", "FAILED", "grown", "run_resumable"]

DONE = 0
NEED_ROOM = 1
FAILED = -1

#: How many times a driver may resume before it decides the kernel is not making progress.
MAX_RESUMPTIONS = 200


def grown(arr: np.ndarray, rows: int | None = None, fill=None) -> np.ndarray:
    """A copy of ``arr`` with at least twice its rows (and at least ``rows``); old rows copied.

    New rows are uninitialised unless ``fill`` is given: kernels write rows before they read them.
    """
    size = max(2 * arr.shape[0], int(rows or 0), 16)
    out = np.empty((size,) + arr.shape[1:], arr.dtype)
    out[: arr.shape[0]] = arr
    if fill is not None:
        out[arr.shape[0]:] = fill  # the new rows only: the old ones are copied over
    return out


def run_resumable(step: Callable[[], int], grow: Callable[[], None], what: str) -> int:
    """Call ``step()`` until it returns :data:`DONE`, calling ``grow()`` after each :data:`NEED_ROOM`.

    Returns the number of resumptions. :data:`FAILED` (or no progress after
    :data:`MAX_RESUMPTIONS` growths) raises :class:`~csgnb.errors.InternalError` naming ``what``.
    """
    for resumptions in range(MAX_RESUMPTIONS + 1):
        status = int(step())
        if status == DONE:
            return resumptions
        if status == FAILED:
            raise InternalError(f"{what}: an internal invariant failed (a bug in csgnb: please report it)")
        if status != NEED_ROOM:
            raise InternalError(f"{what}: unknown kernel status {status} (a bug in csgnb: please report it)")
        grow()
    raise InternalError(f"{what}: still short of room after {MAX_RESUMPTIONS} growths "
                        "(a bug in csgnb: please report it)")
