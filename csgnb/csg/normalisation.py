"""The normalised frame of a model: a translation and a uniform scale that make it unit-sized.

Every tolerance of the sampler is relative (``csgnb.quadric.tolerances``); lengths are relative to
the model's size. So the sampler maps the model into a frame where its box is centered at 0 with
half-diagonal 1, samples there, and maps the samples back: a model and its copy scaled by any
factor or translated anywhere give the same samples up to the map (and rounding).

The map is applied *at the root of the CSG graph* (``to_normal_form(..., frame=)``), composed with
the edge transforms before any leaf is transformed, so that a model translated far from the origin
keeps the precision of its leaves (its world coefficients would not: ``(x − 10⁶)²`` loses 12
digits). :func:`graph_frame` gives a first frame from the leaves alone — covariant under any
similarity map — in which the term boxes are computed; :func:`box_frame` gives the final one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgnb.csg.graph import _leaf_paths
from csgnb.quadric.arguments import as_finite_array, as_positive
from csgnb.quadric.frames import principal_frame
from csgnb.quadric.quadric import Quadric, apply_inverse, transform_inverse

__all__ = ["ModelFrame", "graph_frame", "quadrics_frame", "box_frame"]


@dataclass(frozen=True)
class ModelFrame:
    """The map x ↦ (x − center) / scale from world to normalised coordinates.

    center : (3,) float64; scale : float > 0 (a length: the model's half-diagonal).
    """

    center: np.ndarray
    scale: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", as_finite_array(self.center, (3,), "center"))
        object.__setattr__(self, "scale", as_positive(self.scale, "scale"))

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) float64: world → normalised."""
        m = np.eye(4) / self.scale
        m[3, 3] = 1.0
        m[:3, 3] = -self.center / self.scale
        return m

    @property
    def inverse(self) -> np.ndarray:
        """(4, 4) float64: normalised → world."""
        m = np.eye(4) * self.scale
        m[3, 3] = 1.0
        m[:3, 3] = self.center
        return m

    def to_local(self, points) -> np.ndarray:
        """Return normalised coordinates of world ``points`` : (n, 3)."""
        return (np.asarray(points, dtype=np.float64) - self.center) / self.scale

    def to_world(self, points) -> np.ndarray:
        """Return world coordinates of normalised ``points`` : (n, 3)."""
        return self.center + self.scale * np.asarray(points, dtype=np.float64)

    def box_to_local(self, box) -> np.ndarray:
        """Return a world box (6,) (lo, hi) in normalised coordinates."""
        b = np.asarray(box, dtype=np.float64)
        return np.concatenate([(b[:3] - self.center) / self.scale, (b[3:] - self.center) / self.scale])

    def then(self, inner: ModelFrame) -> ModelFrame:
        """Return the frame of ``inner`` (given in this frame's coordinates) in world terms."""
        return ModelFrame(self.center + self.scale * inner.center, self.scale * inner.scale)


def _anchor(q: Quadric) -> tuple[np.ndarray, float]:
    """A point of the quadric's natural frame and a length: center and √(|γ|/max|λ|), or a plane's foot."""
    cached = q.__dict__.get("_anchor")
    if cached is not None:
        return cached
    placement = q.placement
    if placement is not None:  # the shape from its own frame (exact), then the move
        p, size = _anchor(Quadric._trusted(placement[0], symmetric=True))
        q.__dict__["_anchor"] = (placement[1] + p, size)
        return q.__dict__["_anchor"]
    f = principal_frame(q)
    p = f.center.copy()
    k = int(np.argmax(np.abs(f.linear)))
    if f.linear[k] != 0.0:  # planes and paraboloids: their point (vertex) on the β axis
        p = p + f.axes[:, k] * (f.constant / (2.0 * f.linear[k]))
    top = float(np.max(np.abs(f.eigenvalues)))
    size = float(np.sqrt(abs(f.constant) / top)) if top > 0.0 else 0.0
    q.__dict__["_anchor"] = (p, size)
    return p, size


def _plane(matrix: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Return (unit n, d) with the plane n·x = d when ``matrix`` is an exact plane (A = 0), else None."""
    if np.any(matrix[:3, :3]):
        return None
    g = 2.0 * matrix[:3, 3]  # Q(x) = g·x + c
    norm = float(np.linalg.norm(g))
    if not norm > 0.0:
        return None
    return g / norm, -float(matrix[3, 3]) / norm


def _frame_of(points: list[np.ndarray], sizes: list[float],
              planes: list[tuple[np.ndarray, float]] | None = None) -> ModelFrame:
    """The frame of anchor ``points`` (with lengths ``sizes``) and of ``planes`` (n, d).

    A plane has no point of its own: it is anchored at the foot of the other anchors' center (or,
    for planes only, of their least-squares point — a box's center), never at the foot of the
    world origin, which for a box face far from the origin lies far from the box.
    """
    if planes:
        if points:
            P = np.array(points)
            x0 = 0.5 * (P.min(axis=0) + P.max(axis=0))
        else:
            N = np.array([n for n, _ in planes])
            x0 = np.linalg.lstsq(N, np.array([d for _, d in planes]), rcond=None)[0]
        points = list(points) + [x0 + (d - float(n @ x0)) * n for n, d in planes]
        sizes = list(sizes) + [0.0] * len(planes)
    if not points:
        return ModelFrame(np.zeros(3), 1.0)
    P = np.array(points)
    lo, hi = P.min(axis=0), P.max(axis=0)
    center = 0.5 * (lo + hi)
    scale = max(0.5 * float(np.linalg.norm(hi - lo)), max(sizes, default=0.0))
    if not scale > 0.0:  # a single point-like quadric (a cone): no length in the data
        scale = float(np.linalg.norm(center)) or 1.0
    return ModelFrame(center, scale)


def quadrics_frame(quadrics) -> ModelFrame:
    """Return a first normalised frame from the anchors of world quadrics."""
    pts, sizes, planes = [], [], []
    for q in quadrics:
        pl = _plane(q.matrix)
        if pl is not None:
            planes.append(pl)
            continue
        p, s = _anchor(q)
        pts.append(p)
        sizes.append(s)
    return _frame_of(pts, sizes, planes)


def graph_frame(root) -> ModelFrame:
    """Return a first normalised frame of a CSG graph from its leaves' anchors along every path.

    Covariant: the frame of ``root.transformed(S)`` is S applied to the frame of ``root`` for any
    similarity S (up to rounding). It is only a first guess — the sampler refines it from the
    term boxes (:func:`box_frame`).
    """
    pts: list[np.ndarray] = []
    sizes: list[float] = []
    planes: list[tuple[np.ndarray, float]] = []
    for node, M in _leaf_paths(root):
        pl = _plane(node.quadric.matrix)
        if pl is not None:
            if M is not None:
                pl = _plane(apply_inverse(node.quadric.matrix, transform_inverse(M)))
            if pl is not None:
                planes.append(pl)
            continue
        p, s = _anchor(node.quadric)
        if M is not None:
            h = M @ np.append(p, 1.0)
            if h[3] == 0.0:
                continue
            p = h[:3] / h[3]
            s = s * float(np.max(np.linalg.norm(M[:3, :3], axis=0))) / abs(h[3])
        pts.append(p)
        sizes.append(s)
    return _frame_of(pts, sizes, planes)


def box_frame(boxes: np.ndarray) -> ModelFrame | None:
    """Return the frame centered on the union of the non-empty ``boxes`` (k, 6), half-diagonal 1."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 6)
    b = b[np.all(b[:, :3] <= b[:, 3:], axis=1)]
    if not len(b):
        return None
    lo, hi = b[:, :3].min(axis=0), b[:, 3:].max(axis=0)
    scale = 0.5 * float(np.linalg.norm(hi - lo))
    if not scale > 0.0:
        return None
    return ModelFrame(0.5 * (lo + hi), scale)
