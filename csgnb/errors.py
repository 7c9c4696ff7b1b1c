"""Exceptions raised by csgnb, each naming what was wrong and what to do."""

from __future__ import annotations

__all__ = ["CsgnbError", "PrecisionError", "GeometryError", "InternalError"]


class CsgnbError(ValueError):
    """Base class of csgnb's errors (a ``ValueError``: the input was unusable)."""


class PrecisionError(CsgnbError):
    """An input lies outside the bit budget of the chosen integer width.

    Raised where data enters (points, planes, meshes), before any kernel can
    overflow. The message names the quantity, its bound and the offending value.
    """


class GeometryError(CsgnbError):
    """An input is geometrically invalid (degenerate, open, non-manifold, ...)."""


class InternalError(RuntimeError):
    """An internal invariant of csgnb failed: a bug in csgnb, not a problem with the input.

    Deliberately *not* a ``ValueError``: callers that catch bad-input errors must not
    swallow it. Please report it with the input that caused it.
    """
