"""Input checks shared by the renderers: shapes to normal forms, cameras, sample clouds."""

from __future__ import annotations

import numpy as np

from csgnb.csg.normal_form import NormalForm, to_normal_form
from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.quadric import Quadric
from csgnb.render.camera import Camera
from csgnb.render.rays import quadric_rows

__all__ = ["as_normal_form", "check_camera", "check_cloud", "check_same_shape", "check_precision", "scene_box",
           "check_choice", "check_frame", "eye_inside", "ON_QUADRIC", "EYE_GRID"]

#: A sample is on its quadric when |Q(s)| ≤ ON_QUADRIC · (|∇Q(s)| · scale + |Q|-scale) — far
#: above rounding, far below any offset between different surfaces.
ON_QUADRIC = 1e-7
#: Relative difference under which two normal forms' quadric coefficients are the same shape: the sampler
#: maps its quadrics back from a normalised frame, which leaves rounding noise of a few ulps.
SAME_QUADRIC = 1e-12
#: An orthographic camera's ray origins fill a rectangle: :func:`eye_inside` checks EYE_GRID × EYE_GRID of them.
EYE_GRID = 33


def as_normal_form(shape) -> NormalForm:
    """Return the normal form of ``shape`` (Node, Quadric, NormalForm or SampleCloud)."""
    from csgnb.sampling.cloud import SampleCloud

    if isinstance(shape, SampleCloud):
        return shape.normal_form
    if isinstance(shape, NormalForm):
        nf = shape
    else:
        try:
            nf = to_normal_form(shape)
        except TypeError as exc:
            raise TypeError(
                f"expected a CSG node, a Quadric, a NormalForm or a SampleCloud, got {type(shape).__name__}"
            ) from exc
    if nf.n_terms == 0:
        raise GeometryError("the CSG object is empty: its normal form has no term (e.g. A ∩ ¬A); nothing to render")
    return nf


def check_choice(value, choices: tuple, name: str) -> str:
    """Return ``value`` if it is one of the string ``choices``: TypeError for a non-str, CsgnbError else."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a str, one of {choices}, got {type(value).__name__}")
    if value not in choices:
        raise CsgnbError(f"{name} must be one of {choices}, got {value!r}")
    return value


def check_frame(frame, name: str = "frame"):
    """Return ``frame`` if it is a :class:`csgnb.render.Frame`, else raise TypeError naming ``name``."""
    from csgnb.render.frame import Frame

    if not isinstance(frame, Frame):
        raise TypeError(f"{name} must be a csgnb.render.Frame (from raytrace or render), got {type(frame).__name__}")
    return frame


def check_camera(camera) -> Camera:
    """Return ``camera`` if it is a Camera, else raise TypeError."""
    if not isinstance(camera, Camera):
        raise TypeError(f"expected a csgnb.render.Camera, got {type(camera).__name__}; "
                        "build one with Camera.look_at, Camera.orbit or Camera.fit")
    return camera


def check_cloud(cloud):
    """Validate a SampleCloud for rendering; return its quadric rows (n_q, 10) float64.

    Raises TypeError for another type and GeometryError for an empty cloud, inconsistent arrays
    (ids or clip indices out of range) or samples that are not on their quadrics (a cloud whose
    normal form belongs to another shape).
    """
    from csgnb.sampling.cloud import SampleCloud

    if not isinstance(cloud, SampleCloud):
        raise TypeError(f"expected a csgnb.sampling.SampleCloud (from sample_csg), got {type(cloud).__name__}")
    n = len(cloud.positions)
    if n == 0:
        raise GeometryError("the sample cloud is empty: nothing to render; sample a non-empty CSG surface")
    nq = len(cloud.normal_form)
    for name, arr, shape in (("positions", cloud.positions, (n, 3)), ("radii", cloud.radii, (n,)),
                             ("quadric_ids", cloud.quadric_ids, (n,)), ("clip_start", cloud.clip_start, (n,)),
                             ("clip_count", cloud.clip_count, (n,))):
        if np.shape(arr) != shape:
            raise GeometryError(f"cloud.{name} has shape {np.shape(arr)}, expected {shape}")
    ids = np.asarray(cloud.quadric_ids)
    if ids.min() < 0 or ids.max() >= nq:
        raise GeometryError(f"cloud quadric ids span [{ids.min()}, {ids.max()}] but its normal form has {nq} "
                            "quadrics: the cloud and its normal form do not belong together")
    cidx = np.asarray(cloud.clip_indices)
    end = np.asarray(cloud.clip_start, dtype=np.int64) + np.asarray(cloud.clip_count, dtype=np.int64)
    if np.any(np.asarray(cloud.clip_count) < 0) or np.any(np.asarray(cloud.clip_start) < 0) or \
            (n and end.max() > len(cidx)) or (len(cidx) and (cidx.min() < 0 or cidx.max() >= nq)):
        raise GeometryError("cloud clip sets point outside its clip indices or normal form")
    pos = np.asarray(cloud.positions, dtype=np.float64)
    rad = np.asarray(cloud.radii, dtype=np.float64)
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(rad)) and np.all(rad > 0.0)):
        raise GeometryError("cloud positions must be finite and radii positive")
    Q = np.ascontiguousarray(cloud.quadric_buffer(np.float64))
    _check_on_quadrics(Q, pos, ids)
    return Q


def _check_on_quadrics(Q, pos, ids) -> None:
    A = np.zeros((len(Q), 4, 4))
    iu = np.triu_indices(4)
    A[:, iu[0], iu[1]] = Q
    A[:, iu[1], iu[0]] = Q
    h = np.column_stack([pos, np.ones(len(pos))])
    M = A[ids]
    val = np.einsum("ni,nij,nj->n", h, M, h)
    grad = np.einsum("nij,nj->ni", M[:, :3, :], h)
    scale = np.abs(M).max(axis=(1, 2)) * (1.0 + np.abs(pos).max(axis=1)) ** 2
    bad = np.abs(val) > ON_QUADRIC * (np.linalg.norm(grad, axis=1) * (1.0 + np.abs(pos).max(axis=1)) + scale)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise GeometryError(
            f"{int(bad.sum())} of {len(pos)} samples are not on their quadric (sample {k}: Q = {val[k]:.3g}): "
            "the cloud was not sampled from this normal form (a cloud from another shape?)"
        )


def check_same_shape(cloud, shape) -> NormalForm:
    """Return the normal form of ``shape``, or raise GeometryError if ``cloud`` was sampled from another one."""
    nf = as_normal_form(shape)
    mine = cloud.normal_form
    if nf is mine:
        return nf
    same = len(nf) == len(mine) and np.array_equal(nf.term_start, mine.term_start)
    if same:
        a, b = quadric_rows(nf.quadrics), quadric_rows(mine.quadrics)
        scale = np.maximum(np.abs(a).max(axis=1, keepdims=True), np.finfo(float).tiny)
        same = bool(np.all(np.abs(a - b) <= SAME_QUADRIC * scale))
    if not same:
        raise GeometryError(
            f"the cloud was sampled from another shape: its normal form is {mine!r}, the shape's is {nf!r}; "
            "sample this shape (sample_csg) or pass the cloud's own shape"
        )
    return mine


def scene_box(shape) -> tuple[np.ndarray, float]:
    """Return (center (3,), half-diagonal) of what a renderer draws: a cloud's positions, else the frame
    of the shape's leaves (``csgnb.csg.normalisation``)."""
    from csgnb.csg.normalisation import graph_frame, quadrics_frame
    from csgnb.sampling.cloud import SampleCloud

    if isinstance(shape, SampleCloud):
        pos = np.asarray(shape.positions, dtype=np.float64)
        lo, hi = pos.min(axis=0), pos.max(axis=0)
        return 0.5 * (lo + hi), max(0.5 * float(np.linalg.norm(hi - lo)), float(np.max(shape.radii)))
    if isinstance(shape, NormalForm):
        F = quadrics_frame(shape.quadrics)
    elif isinstance(shape, Quadric):
        F = quadrics_frame([shape])
    else:
        F = graph_frame(shape)
    return F.center, F.scale


def check_precision(camera: Camera, center, size: float) -> None:
    """Refuse a scene too far from the origin for world-coordinate rendering (``tolerances.RENDER_ROUNDING``).

    ``center`` (3,) and ``size`` (half-diagonal) describe the scene; the eye counts too (rays start there).
    """
    D = max(float(np.max(np.abs(center))) + size, float(np.max(np.abs(camera.eye))))
    size = max(size, np.finfo(float).tiny)
    pixel = 2.0 * size / max(camera.shape)
    error = tol.EPS * D * D / size
    if error > tol.RENDER_ROUNDING * pixel:
        raise GeometryError(
            f"the scene is too far from the origin to render in double precision: at distance {D:.3g} a surface "
            f"of size {size:.3g} is only placed to {error:.3g}, more than {tol.RENDER_ROUNDING:g} pixel "
            f"({pixel:.3g}) at {camera.shape[1]}×{camera.shape[0]}; build the model (and camera) nearer the origin"
        )


def eye_inside(normal_form: NormalForm, camera: Camera) -> bool:
    """Whether ``camera`` looks from inside the solid (or from its surface), where its rays start: the eye of a
    perspective camera; for an orthographic one, its ray origins at ``EYE_GRID`` × ``EYE_GRID`` pixels spread over
    the image (corners included). The splat renderer draws views from outside only (back-face culling, §6.1)."""
    if camera.projection == "perspective":
        points = np.asarray(camera.eye, dtype=np.float64)[None]
    else:
        rows = np.unique(np.linspace(0, camera.height - 1, EYE_GRID).round().astype(np.int64))
        cols = np.unique(np.linspace(0, camera.width - 1, EYE_GRID).round().astype(np.int64))
        r, c = (a.ravel() for a in np.meshgrid(rows, cols, indexing="ij"))
        points = camera.rays(r, c)[0]
    return bool(np.any(normal_form.classify(points) <= 0))
