"""Exact BSP solids (paper §3.4-3.7): flat trees over a plane palette, boundary extraction,
import from meshes, Booleans by mesh cutting and redundancy removal.

Modules, in pipeline order: :mod:`~csgnb.bsp.tree` (the flat tree), :mod:`~csgnb.bsp.polygon`
(plane-based polygons, exact splitting), :mod:`~csgnb.bsp.build` (mesh / polygon soup → BSP),
:mod:`~csgnb.bsp.extract` (cells and boundary), :mod:`~csgnb.bsp.surface` (conforming exact
surfaces), :mod:`~csgnb.bsp.merging` (Booleans, redundancy removal), :mod:`~csgnb.bsp.solid`
(the :class:`BSP` API), :mod:`~csgnb.bsp.random_tree` and :mod:`~csgnb.bsp.scenes` (test and
benchmark scenes).
"""

from csgnb.bsp.build import bsp_from_mesh, bsp_from_polygons
from csgnb.bsp.extract import Extraction, extract_boundary, extract_cells
from csgnb.bsp.merging import MergeResult, merge, remove_redundancy
from csgnb.bsp.polygon import PolygonSet
from csgnb.bsp.random_tree import random_bsp
from csgnb.bsp.scenes import tangent_plane_bsp
from csgnb.bsp.solid import BSP, DIFFERENCE, INTERSECTION, SYMMETRIC_DIFFERENCE, UNION
from csgnb.bsp.surface import BoundarySurface
from csgnb.bsp.tree import ON_BOUNDARY, OUT, BSPTree

__all__ = [
    "BSP",
    "BSPTree",
    "BoundarySurface",
    "DIFFERENCE",
    "Extraction",
    "INTERSECTION",
    "MergeResult",
    "ON_BOUNDARY",
    "OUT",
    "PolygonSet",
    "SYMMETRIC_DIFFERENCE",
    "UNION",
    "bsp_from_mesh",
    "bsp_from_polygons",
    "extract_boundary",
    "extract_cells",
    "merge",
    "random_bsp",
    "remove_redundancy",
    "tangent_plane_bsp",
]
