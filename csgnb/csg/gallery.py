"""Named quadric CSG models: the ones the notebooks, tests and benchmarks share.

One definition of each model, so that a figure in a notebook, the check in a test and the row of
a benchmark are about the same solid:

* :data:`TABLE2` — the five models of the sampling benchmark (3, 5, 21, 31 and 80 quadrics), each
  with the three splat radii ("large", "medium", "small") chosen so that sample counts come near the
  paper's Table 2 rows with the same number of quadrics;
* :func:`figure2`, :func:`moved`, :func:`shared`, :func:`figure15`, :func:`tour_part` — the models of
  notebook 07 and of the tour.

>>> sorted(TABLE2)
['block', 'bracket', 'perforated plate', 'slotted cylinder', 'spheres']
>>> from csgnb.csg import graph_leaves
>>> len(graph_leaves(perforated_plate()))
80
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from csgnb.csg.graph import Node, difference, intersection, leaf, rotation_matrix, union
from csgnb.csg.solids import box, cylinder, frame_to_axis, sphere
from csgnb.quadric import Quadric, elliptic_cone, elliptic_cylinder, parallel_planes


def _hole(center, radius, axis=(0.0, 0.0, 1.0), name="hole"):
    """A through hole: an infinite cylinder (one quadric; subtracting it keeps one term)."""
    return leaf(elliptic_cylinder((radius, radius)).transformed(frame_to_axis(center, axis)), name)


def spheres() -> Node:
    """(A ∩ B) ∪ C of three spheres (Figure 2)."""
    A, B, C = sphere((0, 0, 0), 1, "A"), sphere((0.8, 0, 0), 1, "B"), sphere((0.4, 0.9, 0), 0.6, "C")
    return (A & B) | C


def slotted_cylinder() -> Node:
    """A capped cylinder cut by a slot (a slab: one quadric) with a spherical dimple: 5 quadrics."""
    body = cylinder((0, 0, 0), (0, 0, 2), 1.0, "body")
    slot = leaf(parallel_planes((1, 0, 0), -0.2, 0.2), "slot")
    dimple = sphere((0, 0.5, 2.1), 0.5, "dimple")
    return difference(body, slot, dimple)


def bracket() -> Node:
    """A plate with a boss, a bore, eight holes and three spherical dimples: 21 quadrics."""
    plate = box((0, 0, 0), (6, 4, 0.6), "plate")
    boss = cylinder((3, 2, 0.6), (3, 2, 1.8), 1.0, "boss")
    cuts = [_hole((3, 2, 0), 0.5, name="bore")]
    for k, (x, y) in enumerate([(0.6, 0.6), (2.0, 0.6), (4.0, 0.6), (5.4, 0.6),
                                (0.6, 3.4), (2.0, 3.4), (4.0, 3.4), (5.4, 3.4)]):
        cuts.append(_hole((x, y, 0), 0.25, name=f"hole {k}"))
    cuts += [sphere((x, 2.0, 0.75), 0.35, f"dimple {k}") for k, x in enumerate((0.9, 1.6, 5.1))]
    return difference(plate | boss, *cuts)


def block() -> Node:
    """A block rounded by a sphere, three axis bores, twelve holes, three bosses: 31 quadrics."""
    body = box((-1, -1, -1), (1, 1, 1), "block") & sphere((0, 0, 0), 1.55, "round")
    cuts = [_hole((0, 0, 0), 0.3, axis, f"bore {k}") for k, axis in enumerate(np.eye(3))]
    for a in range(3):
        for k, (u, w) in enumerate([(-0.6, -0.6), (-0.6, 0.6), (0.6, -0.6), (0.6, 0.6)]):
            cuts.append(_hole(np.roll([0.0, u, w], a), 0.12, np.eye(3)[a], f"hole {a}{k}"))
    bosses = [cylinder(np.eye(3)[k] * 0.9, np.eye(3)[k] * 1.35, 0.45, f"boss {k}") for k in range(3)]
    return union(difference(body, *cuts), *bosses)


def perforated_plate() -> Node:
    """A plate with 72 holes (cylinders and countersink cones) and two cross bores: 80 quadrics."""
    plate = box((0, 0, 0), (10, 9, 1), "plate")
    holes = []
    for i in range(9):
        for j in range(8):
            c = np.array([0.6 + i * 1.1, 0.6 + j * 1.1, 0.0])
            if (i + j) % 2 == 0:
                holes.append(leaf(elliptic_cylinder((0.3, 0.3)).translated(c), f"hole {i},{j}"))
            else:
                holes.append(leaf(elliptic_cone((0.35, 0.35)).translated(c + [0, 0, -1.2]), f"cone {i},{j}"))
    holes.append(_hole((0, 4.5, 0.5), 0.2, (1, 0, 0), "x bore"))
    holes.append(_hole((5, 0, 0.5), 0.2, (0, 1, 0), "y bore"))
    return difference(plate, *holes)


#: name → (builder, {splat: radius}); radii chosen so that sample counts come near the paper's
#: Table 2 rows with the same number of quadrics
TABLE2: dict[str, tuple[Callable[[], Node], dict[str, float]]] = {
    "spheres": (spheres, {"large": 0.106, "medium": 0.0427, "small": 0.0108}),
    "slotted cylinder": (slotted_cylinder, {"large": 0.1075, "medium": 0.045, "small": 0.0124}),
    "bracket": (bracket, {"large": 0.224, "medium": 0.0876, "small": 0.0429}),
    "block": (block, {"large": 0.114, "medium": 0.0523, "small": 0.0335}),
    "perforated plate": (perforated_plate, {"large": 1.0, "medium": 0.115, "small": 0.0456}),
}


def figure2():
    """(A ∩ B) ∪ C of three spheres (notebook 07, Figure 2)."""
    A, B, C = sphere((0, 0, 0), 1.0, "A"), sphere((0.8, 0, 0), 1.0, "B"), sphere((0.4, 0.9, 0), 0.6, "C")
    return (A & B) | C


def moved():
    """A − C under a rotation and a non-uniform scale (notebook 07, eq. 17)."""
    A, C = sphere((0, 0, 0), 1.0, "A"), sphere((0.4, 0.9, 0), 0.6, "C")
    M = rotation_matrix((1, 2, 0), 0.7, (0.5, 0, 0)) @ np.diag([1.0, 2.0, 0.5, 1.0])
    return (A - C).transformed(M)


def shared():
    """A ∩ (B' ∪ C'): one sphere reached through two terms (notebook 07)."""
    A = sphere((0, 0, 0), 1.0, "A")
    return A & (box((-2, -2, -2), (0.3, 2, 2), "B'") | box((-0.2, -2, -2), (2, 0.4, 2), "C'"))


def eight():
    """Figure 15's intersection of eight quadrics (a ball, three cylinders, four planes), rotated."""
    parts = [sphere((0, 0, 0), 1.0, "ball")]
    for k, r in enumerate((0.82, 0.8, 0.78)):
        axis = frame_to_axis((0, 0, 0), np.eye(3)[k])
        parts.append(leaf(elliptic_cylinder((r, r)).transformed(axis), f"cyl {k}"))
    for k, n in enumerate(((1, 1, 1), (-1, 1, 1), (1, -1, 1), (1, 1, -1))):
        q = Quadric.from_abc(np.zeros((3, 3)), -0.5 * np.array(n) / np.sqrt(3), -0.93)
        parts.append(leaf(q, f"cut {k}"))
    return intersection(*parts).transformed(rotation_matrix((1, 2, 3), 0.4))


def figure15():
    """Figure 15 with notebook 07's thin features: a 0.02 lens, a 0.015 fin, a pin of radius 0.03."""
    return union(
        eight(),
        sphere((2.3, 0, -0.99), 1.0, "lens lo") & sphere((2.3, 0, 0.99), 1.0, "lens hi"),
        box((1.6, -1.2, -0.6), (3.0, -0.9, -0.585), "fin"),
        sphere((2.3, 0.9, 0.3), 0.03, "pin"),
    )


def tour_part():
    """The tour's plate with a boss, a dimple and a hole."""
    plate = box((0, 0, 0), (3, 2, 0.6), "plate")
    boss = cylinder((1.5, 1, 0.6), (1.5, 1, 1.4), 0.6, "boss")
    hole = leaf(elliptic_cylinder((0.25, 0.25)).translated((0.5, 0.5, 0)), "hole")
    return difference(plate | boss, sphere((1.5, 1, 1.4), 0.45, "dimple"), hole)


def notebook_models() -> dict[str, Callable[[], Node]]:
    """Name → builder of every model of notebook 07 and the tour."""
    return {"figure 2": figure2, "moved": moved, "shared": shared, "figure 15": figure15, "tour": tour_part}


def all_models() -> dict[str, Callable[[], Node]]:
    """Name → builder of the notebook, tour and Table 2 models."""
    out = dict(notebook_models())
    out.update({name: build for name, (build, _) in TABLE2.items()})
    return out
