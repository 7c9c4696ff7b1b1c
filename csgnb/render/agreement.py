"""Pixel-perfect agreement of two frames (splats against the reference ray tracer).

Two pixels agree when they show the same quadric (normal-form index) at the same depth (relative
``DEPTH_TOLERANCE``). A disagreement is *explained* when it lies within one pixel of an edge of
the reference image: a silhouette (a neighbour shows another quadric or nothing) or a
surface-surface edge (a neighbour shows another quadric), or a depth jump on one quadric (a
self-occluding silhouette). There the two renderers decide the same geometric question — which
side of a feature curve a pixel centre falls on — with differently rounded arithmetic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric.arguments import as_real

__all__ = ["Agreement", "compare", "verify", "edge_mask", "DEPTH_TOLERANCE", "REQUIRED_FRACTION", "DEPTH_JUMP"]

#: Relative depth tolerance of an agreeing pixel.
DEPTH_TOLERANCE = 1e-9
#: Fraction of the reference's pixels that must agree for ``Agreement.ok``.
REQUIRED_FRACTION = 0.999
#: A same-quadric neighbour whose depth differs by more than this fraction is across a silhouette.
DEPTH_JUMP = 0.02


def _neighbours(a: np.ndarray, fill):
    """Yield the 8 shifted copies of ``a`` (padded with ``fill``)."""
    H, W = a.shape
    p = np.pad(a, 1, constant_values=fill)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                yield p[1 + di : 1 + di + H, 1 + dj : 1 + dj + W]


def edge_mask(frame) -> np.ndarray:
    """Return the pixels within one pixel of an edge of ``frame`` : (H, W) bool.

    A pixel is on an edge when one of its 8 neighbours shows another quadric (or nothing, or is
    outside the image while the pixel shows a surface), or the same quadric at a depth more than
    ``DEPTH_JUMP`` relative away.
    """
    from csgnb.render.scene import check_frame

    check_frame(frame, "frame")
    q = frame.quadric
    d = np.where(np.isfinite(frame.depth), frame.depth, 0.0)
    out = np.zeros(q.shape, dtype=bool)
    for nq, nd in zip(_neighbours(q, -1), _neighbours(d, 0.0), strict=True):
        out |= nq != q
        out |= (nq == q) & (q >= 0) & (np.abs(nd - d) > DEPTH_JUMP * np.maximum(d, 1e-300))
    return out


@dataclass(frozen=True, eq=False)
class Agreement:
    """Per-pixel comparison of a frame with a reference frame.

    covered : int — pixels the reference covers. agree : int — of those, same quadric and depth.
    holes : int — covered by the reference, empty in the frame. extra : int — covered only in the
    frame. disagree : int — reference pixels not agreeing, plus ``extra``. off_edge : int — of the
    disagreeing pixels, those not within one pixel of an edge (see module docstring).
    masks: ``disagree_mask``, ``hole_mask``, ``extra_mask``, ``edge`` (H, W) bool.
    """

    covered: int
    agree: int
    holes: int
    extra: int
    disagree: int
    off_edge: int
    disagree_mask: np.ndarray
    hole_mask: np.ndarray
    extra_mask: np.ndarray
    edge: np.ndarray
    frame_covered: np.ndarray
    reference_covered: np.ndarray

    @property
    def fraction(self) -> float:
        """Agreeing fraction of the reference's pixels (1.0 when it covers none)."""
        return self.agree / self.covered if self.covered else 1.0

    @property
    def disagree_fraction(self) -> float:
        """Disagreeing pixels (``disagree``) per reference pixel."""
        return self.disagree / self.covered if self.covered else float(self.disagree > 0)

    @property
    def ok(self) -> bool:
        """≥ REQUIRED_FRACTION agree, no hole, every disagreement within one pixel of an edge."""
        return self.fraction >= REQUIRED_FRACTION and self.holes == 0 and self.off_edge == 0

    def picture(self) -> np.ndarray:
        """Return the difference image : (H, W, 3) uint8.

        Grey: both empty; white: agree; red: another quadric or depth; yellow: a hole (covered
        by the reference only); blue: covered by the frame only.
        """
        img = np.full(self.edge.shape + (3,), 77, dtype=np.uint8)
        img[self.reference_covered] = (235, 235, 235)
        img[self.disagree_mask] = (214, 39, 40)
        img[self.hole_mask] = (255, 215, 0)
        img[self.extra_mask] = (31, 119, 180)
        return img

    def __repr__(self) -> str:
        return (f"Agreement({self.agree}/{self.covered} = {self.fraction:.5%} agree, {self.holes} holes, "
                f"{self.extra} extra, {self.off_edge} disagreeing off an edge, ok={self.ok})")


def compare(frame, reference, *, rel: float = DEPTH_TOLERANCE) -> Agreement:
    """Return the agreement of ``frame`` with ``reference`` (same camera and normal form).

    Raises ValueError if the two frames differ in size.
    """
    from csgnb.render.scene import check_frame

    check_frame(frame, "frame")
    check_frame(reference, "reference")
    rel = as_real(rel, "rel")
    if rel < 0.0:
        raise GeometryError(f"rel must be ≥ 0 (a relative depth tolerance), got {rel}")
    if frame.shape != reference.shape:
        raise CsgnbError(f"frame and reference differ in size: {frame.shape} vs {reference.shape}")
    rq, fq = reference.quadric, frame.quadric
    rc, fc = rq >= 0, fq >= 0
    with np.errstate(invalid="ignore"):
        same = rc & fc & (rq == fq) & (np.abs(frame.depth - reference.depth) <= rel * np.abs(reference.depth))
    holes = rc & ~fc
    extra = fc & ~rc
    dis = (rc & ~same) | extra
    edge = edge_mask(reference)
    return Agreement(
        covered=int(rc.sum()), agree=int(same.sum()), holes=int(holes.sum()), extra=int(extra.sum()),
        disagree=int(dis.sum()), off_edge=int((dis & ~edge).sum()), disagree_mask=dis & ~holes & ~extra,
        hole_mask=holes, extra_mask=extra, edge=edge, frame_covered=fc, reference_covered=rc,
    )


def verify(cloud, camera, shape=None, **options):
    """Render ``cloud`` as splats and its shape with the reference; return (Agreement, splats, reference).

    shape : the CSG object the cloud should have been sampled from (default: the cloud's own
    normal form); GeometryError if the cloud belongs to another shape. ``options`` go to ``render``;
    every tile is splatted (``fallback="never"``) unless they say otherwise: a ray-traced tile
    would check the reference against itself and hide a hole in the cloud.
    """
    from csgnb.render.raytracer import raytrace
    from csgnb.render.scene import check_cloud, check_same_shape
    from csgnb.render.splats import render

    check_cloud(cloud)
    nf = cloud.normal_form if shape is None else check_same_shape(cloud, shape)
    splats = render(cloud, camera, **{"fallback": "never", **options})
    reference = raytrace(nf, camera, color_by=options.get("color_by", "quadric"))
    return compare(splats, reference), splats, reference
