"""Rendering quadric CSG surfaces: a reference ray tracer and pixel-perfect splats (paper §6, §7.2).

:class:`Camera` (look-at, perspective / orthographic, orbit, fit-to-bounds, :mod:`.camera`);
:func:`raytrace`, the reference CSG ray tracer over the normal form (sorted quadric hits and 1D
CSG per term, :mod:`.raytracer`); :func:`render`, the splat renderer with local quadric
ray-tracing, clipping and the overdraw reductions of §6.1 (:mod:`.splats`); both return a
:class:`Frame` of buffers (depth, normal, quadric, term, RGB, overdraw, ...) with PNG and pyvista
export (:mod:`.frame`, shading in :mod:`.shading`); :func:`compare` checks pixel-perfect agreement
(:mod:`.agreement`); :class:`Viewer` is the interactive notebook viewer (:mod:`.viewer`), drawing per view
the level of detail whose splats are about a target size on screen (:class:`LevelsOfDetail`,
:mod:`.level_of_detail`).
"""

from csgnb.render.agreement import Agreement, compare, edge_mask, verify
from csgnb.render.camera import PROJECTIONS, Camera
from csgnb.render.frame import Frame, RenderStats
from csgnb.render.level_of_detail import LevelChooser, LevelsOfDetail, footprint_pixels
from csgnb.render.raytracer import raytrace
from csgnb.render.shading import CLIP_COLORS, COLOR_MODES, Lighting, overdraw_colors, quadric_colors
from csgnb.render.splats import FOOTPRINTS, LOCAL_MODES, SplatRenderer, render, renderer_for
from csgnb.render.viewer import Viewer

__all__ = [
    "Camera",
    "PROJECTIONS",
    "raytrace",
    "render",
    "SplatRenderer",
    "renderer_for",
    "Frame",
    "RenderStats",
    "compare",
    "verify",
    "Agreement",
    "edge_mask",
    "FOOTPRINTS",
    "LOCAL_MODES",
    "COLOR_MODES",
    "CLIP_COLORS",
    "Lighting",
    "overdraw_colors",
    "quadric_colors",
    "Viewer",
    "LevelChooser",
    "LevelsOfDetail",
    "footprint_pixels",
]
