"""Convenience solids built from quadric leaves: box, capped cylinder and cone, sphere, rounded shapes.

Each returns a CSG node whose leaves are named after their role (``"box +x"``, ``"cylinder side"``,
...), so normal forms and sample clouds can be read. Quadrics per solid: box 6, cylinder 3,
cone 3 (also when pointed: the cap at the apex keeps the cone's other nappe out), sphere 1,
ellipsoid 1, capsule 5, rounded box 62.
"""

from __future__ import annotations

import numpy as np

from csgnb.csg.graph import Leaf, Node, intersection, union
from csgnb.errors import GeometryError
from csgnb.quadric.arguments import as_finite_array, as_positive, as_real
from csgnb.quadric.quadric import ellipsoid as _ellipsoid
from csgnb.quadric.quadric import elliptic_cone, elliptic_cylinder, plane
from csgnb.quadric.quadric import positive_lengths as _length
from csgnb.quadric.quadric import sphere as _sphere

__all__ = ["box", "cylinder", "cone", "sphere", "ellipsoid", "capsule", "rounded_box", "frame_to_axis"]


def _vec(v, name: str) -> np.ndarray:
    return as_finite_array(v, (3,), name)


def _positive(v, name: str) -> float:
    """A radius: positive and within ``tolerances.LENGTH_MIN`` … ``LENGTH_MAX`` (see there why)."""
    return float(_length(as_positive(v, name), 1, name)[0])


def frame_to_axis(origin, axis) -> np.ndarray:
    """Return a rigid 4×4 map taking the z axis through 0 to ``axis`` through ``origin``."""
    o = _vec(origin, "origin")
    a = _vec(axis, "axis")
    n = float(np.linalg.norm(a))
    if n == 0.0:
        raise GeometryError("axis is zero: the two end points coincide")
    z = a / n
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, :3] = np.column_stack([x, y, z])
    m[:3, 3] = o
    return m


def box(lo, hi, name: str = "box") -> Node:
    """Return the axis-aligned box ``[lo, hi]`` as the intersection of 6 half-spaces."""
    lo, hi = _vec(lo, "lo"), _vec(hi, "hi")
    if np.any(lo >= hi):
        raise GeometryError(f"box needs lo < hi in every axis, got lo={lo.tolist()}, hi={hi.tolist()}")
    faces = []
    for k, axis in enumerate("xyz"):
        e = np.zeros(3)
        e[k] = 1.0
        faces.append(Leaf(plane(e, hi[k]), f"{name} +{axis}"))
        faces.append(Leaf(plane(-e, -lo[k]), f"{name} -{axis}"))
    return intersection(*faces)


def _caps(p0: np.ndarray, p1: np.ndarray, name: str) -> list[Leaf]:
    z = (p1 - p0) / np.linalg.norm(p1 - p0)
    return [Leaf(plane(z, float(z @ p1)), f"{name} cap 1"), Leaf(plane(-z, float(-z @ p0)), f"{name} cap 0")]


def cylinder(p0, p1, radius: float, name: str = "cylinder") -> Node:
    """Return the capped circular cylinder with axis ``p0 → p1`` and ``radius`` (3 quadrics)."""
    p0, p1 = _vec(p0, "p0"), _vec(p1, "p1")
    r = _positive(radius, "radius")
    side = elliptic_cylinder((r, r)).transformed(frame_to_axis(p0, p1 - p0))
    return intersection(Leaf(side, f"{name} side"), *_caps(p0, p1, name))


def cone(p0, p1, r0: float, r1: float, name: str = "cone") -> Node:
    """Return the capped (truncated) circular cone from radius ``r0`` at ``p0`` to ``r1`` at ``p1``.

    One radius may be 0 (a pointed cone); equal radii give a cylinder. Always 3 quadrics: the
    side and two caps (the cap at an apex keeps the cone's other nappe out).
    """
    p0, p1 = _vec(p0, "p0"), _vec(p1, "p1")
    r0, r1 = as_real(r0, "r0"), as_real(r1, "r1")
    if r0 < 0.0 or r1 < 0.0 or max(r0, r1) == 0.0:
        raise GeometryError(f"cone radii must be ≥ 0, finite and not both 0, got {r0}, {r1}")
    if r0 == r1:
        return cylinder(p0, p1, r0, name)
    length = float(np.linalg.norm(p1 - p0))
    if length == 0.0:
        raise GeometryError("cone end points coincide")
    slope = abs(r1 - r0) / length
    apex = p0 + (p1 - p0) * (-r0 / (r1 - r0))
    side = elliptic_cone((slope, slope)).transformed(frame_to_axis(apex, p1 - p0))
    return intersection(Leaf(side, f"{name} side"), *_caps(p0, p1, name))


def sphere(center=(0.0, 0.0, 0.0), radius: float = 1.0, name: str = "sphere") -> Leaf:
    """Return a sphere leaf."""
    return Leaf(_sphere(_vec(center, "center"), _positive(radius, "radius")), name)


def ellipsoid(radii, center=(0.0, 0.0, 0.0), name: str = "ellipsoid") -> Leaf:
    """Return an axis-aligned ellipsoid leaf with semi-axes ``radii`` : (3,)."""
    return Leaf(_ellipsoid(radii, _vec(center, "center")), name)


def capsule(p0, p1, radius: float, name: str = "capsule") -> Node:
    """Return a capsule (a rounded cylinder): a capped cylinder and two spheres (5 quadrics)."""
    p0, p1 = _vec(p0, "p0"), _vec(p1, "p1")
    return union(
        cylinder(p0, p1, radius, name),
        sphere(p0, radius, f"{name} end 0"),
        sphere(p1, radius, f"{name} end 1"),
    )


def rounded_box(lo, hi, radius: float, name: str = "rounded box") -> Node:
    """Return the box ``[lo, hi]`` with edges and corners rounded by ``radius`` (62 quadrics).

    The union of three boxes (each shrunk by ``radius`` across two axes), 12 edge cylinders and
    8 corner spheres. Many of its faces coincide; the normal form and the sampler handle that.
    """
    lo, hi = _vec(lo, "lo"), _vec(hi, "hi")
    r = _positive(radius, "radius")
    if np.any(hi - lo <= 2.0 * r):
        raise GeometryError("rounded box: radius must be less than half of every side")
    a, b = lo + r, hi - r
    parts: list[Node] = []
    for k in range(3):
        blo, bhi = a.copy(), b.copy()
        blo[k], bhi[k] = lo[k], hi[k]
        parts.append(box(blo, bhi, f"{name} slab {'xyz'[k]}"))
    corners = np.array([[(a, b)[(m >> k) & 1][k] for k in range(3)] for m in range(8)])
    for k in range(3):
        for m in range(8):
            if (m >> k) & 1:
                continue
            p0, p1 = corners[m], corners[m | (1 << k)]
            parts.append(cylinder(p0, p1, r, f"{name} edge {m}{'xyz'[k]}"))
    parts += [sphere(c, r, f"{name} corner {m}") for m, c in enumerate(corners)]
    return union(*parts)
