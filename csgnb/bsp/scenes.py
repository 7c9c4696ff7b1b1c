"""Reference BSP scenes from the paper's evaluation (Figure 9's linear BSP of tangent planes)."""

from __future__ import annotations

import numpy as np

from csgnb.bsp.build import check_count, check_seed
from csgnb.bsp.tree import OUT, BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.wide import check_width, to_wide

__all__ = ["sphere_directions", "tangent_plane_bsp"]


def sphere_directions(n: int, order: str = "spiral") -> np.ndarray:
    """Return ``n`` near-uniform unit directions on the sphere, ``(n, 3) float64``.

    ``order="spiral"``: the generalized spiral of Saff and Kuijlaars, one continuous
    curve from pole to pole, so consecutive directions are neighbours (a coherent
    sequence, like a tool path). ``order="golden"``: the Fibonacci (golden-angle)
    lattice, where consecutive directions are about 137.5° apart in longitude.
    """
    if n < 1:
        raise GeometryError(f"need at least one direction, got n={n}")
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    if order == "golden":
        phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    elif order == "spiral":
        # Longitude advances by 3.6 / sqrt(n (1 - z^2)) per step: equal spacing along the curve.
        phi = np.cumsum(3.6 / np.sqrt(n * np.maximum(r * r, 1.0 / n)))
    else:
        raise GeometryError(f"order must be 'spiral' or 'golden', got {order!r}")
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def tangent_plane_bsp(n_planes: int, *, radius: int = 1 << 12, normal_scale: int = 1 << 10, width: int = 128,
                      order: str = "spiral", seed: int = 0) -> BSPTree:
    """Return the linear BSP of ``n_planes`` planes tangent to a sphere (paper Figure 9).

    Plane ``i`` has the integer normal ``round(normal_scale * u_i)`` for spiral direction
    ``u_i`` and offset ``-round(radius * |n_i|)``, so it touches the sphere of ``radius``
    up to rounding. Node ``i`` splits by plane ``i``; its positive child is an **out**
    leaf, its negative child node ``i + 1``; the last negative child is **in**: the tree
    is a convex polytope with (up to) ``n_planes`` faces, the deepest possible BSP.

    ``order``: ``"spiral"`` (neighbouring planes in sequence), ``"golden"`` (the Fibonacci
    lattice order: far apart in sequence) or ``"random"`` (shuffled with ``seed``).
    Extract inside the box ``[-2 * radius, 2 * radius]``.
    """
    n_planes = check_count(n_planes, "n_planes", 1)
    radius = check_count(radius, "radius", 1)
    normal_scale = check_count(normal_scale, "normal_scale", 1)
    width = check_width(width)
    seed = check_seed(seed)
    if not isinstance(order, str) or order not in ("spiral", "golden", "random"):
        raise GeometryError(f"order must be 'spiral', 'golden' or 'random', got {order!r}")
    directions = sphere_directions(n_planes, "golden" if order == "golden" else "spiral")
    normals = np.rint(normal_scale * directions).astype(np.int64)
    if order == "random":
        normals = normals[np.random.default_rng(seed).permutation(n_planes)]
    lengths = np.sqrt((normals.astype(np.float64) ** 2).sum(axis=1))
    offsets = -np.rint(radius * lengths).astype(np.int64)
    palette = to_wide(np.concatenate([normals, offsets[:, None]], axis=1), width)
    n = 2 * n_planes + 1
    plane = np.full(n, -1, np.int32)
    neg = np.full(n, -1, np.int32)
    pos = np.full(n, -1, np.int32)
    label = np.full(n, OUT, np.int32)
    # Inner nodes 0..n_planes-1 form the chain; leaves follow.
    idx = np.arange(n_planes)
    plane[idx] = idx
    neg[idx] = idx + 1
    neg[n_planes - 1] = n_planes  # the innermost cell
    pos[idx] = n_planes + 1 + idx
    label[idx] = -1
    label[n_planes] = 1
    return BSPTree(palette, plane, neg, pos, label)
