"""The CSG models the render checks run on: notebook 07's, the tour's and Table 2's.

Table 2's builders are imported from ``benchmarks/bench_sampling.py`` (one definition of each
model); that script defaults NUMBA_NUM_THREADS to 1 on import, so the variable is pinned to the
running value first (numba refuses a change once its threads run).
"""

from __future__ import annotations

import importlib.util
import os
import pathlib

import numba
import numpy as np

import csgnb.csg as csg
from csgnb.quadric import elliptic_cylinder

ROOT = pathlib.Path(__file__).resolve().parents[1]


def bench_sampling_module():
    """Return ``benchmarks/bench_sampling.py`` as a module (its MODELS and builders)."""
    os.environ["NUMBA_NUM_THREADS"] = str(numba.config.NUMBA_NUM_THREADS)
    spec = importlib.util.spec_from_file_location("bench_sampling", ROOT / "benchmarks" / "bench_sampling.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def figure2():
    """(A ∩ B) ∪ C of three spheres (notebook 07, Figure 2)."""
    A, B, C = csg.sphere((0, 0, 0), 1.0, "A"), csg.sphere((0.8, 0, 0), 1.0, "B"), csg.sphere((0.4, 0.9, 0), 0.6, "C")
    return (A & B) | C


def moved():
    """A − C under a rotation and a non-uniform scale (notebook 07, eq. 17)."""
    A, C = csg.sphere((0, 0, 0), 1.0, "A"), csg.sphere((0.4, 0.9, 0), 0.6, "C")
    M = csg.rotation_matrix((1, 2, 0), 0.7, (0.5, 0, 0)) @ np.diag([1.0, 2.0, 0.5, 1.0])
    return (A - C).transformed(M)


def shared():
    """A ∩ (B' ∪ C'): one sphere reached through two terms (notebook 07)."""
    A = csg.sphere((0, 0, 0), 1.0, "A")
    return A & (csg.box((-2, -2, -2), (0.3, 2, 2), "B'") | csg.box((-0.2, -2, -2), (2, 0.4, 2), "C'"))


def eight():
    """Figure 15's intersection of eight quadrics (a ball, three cylinders, four planes), rotated."""
    parts = [csg.sphere((0, 0, 0), 1.0, "ball")]
    for k, r in enumerate((0.82, 0.8, 0.78)):
        axis = csg.solids.frame_to_axis((0, 0, 0), np.eye(3)[k])
        parts.append(csg.leaf(elliptic_cylinder((r, r)).transformed(axis), f"cyl {k}"))
    for k, n in enumerate(((1, 1, 1), (-1, 1, 1), (1, -1, 1), (1, 1, -1))):
        q = csg.graph.Quadric.from_abc(np.zeros((3, 3)), -0.5 * np.array(n) / np.sqrt(3), -0.93)
        parts.append(csg.leaf(q, f"cut {k}"))
    return csg.intersection(*parts).transformed(csg.rotation_matrix((1, 2, 3), 0.4))


def figure15():
    """Figure 15 with notebook 07's thin features: a 0.02 lens, a 0.015 fin, a pin of radius 0.03."""
    return csg.union(
        eight(),
        csg.sphere((2.3, 0, -0.99), 1.0, "lens lo") & csg.sphere((2.3, 0, 0.99), 1.0, "lens hi"),
        csg.box((1.6, -1.2, -0.6), (3.0, -0.9, -0.585), "fin"),
        csg.sphere((2.3, 0.9, 0.3), 0.03, "pin"),
    )


def tour_part():
    """The tour's plate with a boss, a dimple and a hole."""
    plate = csg.box((0, 0, 0), (3, 2, 0.6), "plate")
    boss = csg.cylinder((1.5, 1, 0.6), (1.5, 1, 1.4), 0.6, "boss")
    hole = csg.leaf(elliptic_cylinder((0.25, 0.25)).translated((0.5, 0.5, 0)), "hole")
    return csg.difference(plate | boss, csg.sphere((1.5, 1, 1.4), 0.45, "dimple"), hole)


def notebook_models() -> dict:
    """Name → builder of every model of notebook 07 and the tour."""
    return {"figure 2": figure2, "moved": moved, "shared": shared, "figure 15": figure15, "tour": tour_part}


def all_models() -> dict:
    """Name → builder of the notebook, tour and Table 2 models."""
    out = dict(notebook_models())
    for name, (build, _) in bench_sampling_module().MODELS.items():
        out[name] = build
    return out
