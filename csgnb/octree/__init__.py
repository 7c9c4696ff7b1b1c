"""Octree-embedded BSPs (paper §3.8-3.9, §4.4-4.5): a persistent, exact workpiece for iterated CSG.

:class:`Workpiece` is the API; :mod:`~csgnb.octree.layout` the plain arrays it is made of,
:mod:`~csgnb.octree.kernels` the per-cell Booleans, splits and combines,
:mod:`~csgnb.octree.tool` the tools (convex hulls, meshes, BSPs, translated exactly),
:mod:`~csgnb.octree.global_tree` the whole workpiece as one BSP (export, classification),
:mod:`~csgnb.octree.volume` exact cell volumes cached by cell content and the exact volume change
of a Boolean, :mod:`~csgnb.octree.persist` saving and loading.
"""

from csgnb.octree.tool import Tool
from csgnb.octree.workpiece import DEFAULT_THRESHOLD, STOCK_CELL_DEPTH, OpReport, Workpiece

__all__ = ["DEFAULT_THRESHOLD", "STOCK_CELL_DEPTH", "OpReport", "Tool", "Workpiece"]
