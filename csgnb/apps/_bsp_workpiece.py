"""STAND-IN workpiece on one whole-workpiece :class:`csgnb.bsp.BSP` -- exact, complete, and slow.

This is **not** the product's workpiece. It implements the workpiece interface the
applications are written against (the interface ``csgnb.octree.Workpiece`` provides, see
:mod:`csgnb.apps.milling`) on today's single-BSP engine, so the applications run and are
tested before the octree exists. Every Boolean here re-does the whole workpiece (a merge,
redundancy removal and a boundary extraction for the exact volume), so the cost per
operation grows with the part: fine for tests and small example programs, 10-100x too
slow for real ones. Replace it with ``csgnb.octree.Workpiece`` wherever speed matters.

Interface (all volumes exact :class:`fractions.Fraction` in **grid units cubed**;
``grid.scale ** 3`` grid units make one cubic model unit):

* ``Workpiece.box(lo, hi, *, grid)`` -- model-unit corners, quantized by ``grid``;
  ``Workpiece.from_mesh(vertices, faces, *, grid)`` -- a closed float mesh in model units;
  ``Workpiece.empty(grid)`` -- nothing (a start for unions such as the gear sweep);
* ``w.grid``; ``w.difference(tool)``, ``w.union(tool)``, ``w.intersection(tool)`` with a
  :class:`~csgnb.mesh.hull.ConvexHull` or a :class:`~csgnb.bsp.BSP` in grid coordinates,
  returning the exact volume removed (difference, intersection) or added (union);
* ``w.volume()``, ``w.to_mesh()`` (float model vertices ``(n, 3)``, triangles ``(m, 3)``),
  ``w.to_polydata()``, ``w.save(path)``, ``Workpiece.load(path)``.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import zipfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from csgnb.bsp.solid import BSP
from csgnb.bsp.tree import BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.quantization import Grid
from csgnb.exact.wide import from_wide, wide_dtype
from csgnb.mesh.hull import ConvexHull

__all__ = ["BSPWorkpiece"]

_FORMAT = "csgnb-bsp-workpiece"
_VERSION = 1


def _collinear(a, b, c) -> bool:
    """Whether three homogeneous integer points are collinear: every 3x3 minor of [a; b; c] is zero (exact)."""
    for skip in range(4):
        cols = [k for k in range(4) if k != skip]
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = ([p[k] for k in cols] for p in (a, b, c))
        if a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0):
            return False
    return True


def _ear_triangles(poly: list[int], X) -> list[tuple[int, int, int]]:
    """Triangles of a convex polygon whose edges carry extra (T-junction) vertices, none of zero area.

    A fan would join vertices on one edge into flat triangles. Instead, while a flat vertex
    (collinear with its neighbours, decided exactly) remains, the ear at a strict corner next
    to one is clipped -- which turns that flat vertex into a corner and keeps the rest a
    convex polygon with area -- and the flat-free rest is fanned.
    """
    poly = list(poly)
    out = []
    while len(poly) > 3:
        k = len(poly)
        flat = [_collinear(X[poly[i - 1]], X[poly[i]], X[poly[(i + 1) % k]]) for i in range(k)]
        if not any(flat):
            break
        for i in range(k):
            if not flat[i] and (flat[i - 1] or flat[(i + 1) % k]):
                out.append((poly[i - 1], poly[i], poly[(i + 1) % k]))
                del poly[i]
                break
        else:  # all flat: a zero-area polygon (not on a solid's boundary)
            return out
    out += [(poly[0], poly[i], poly[i + 1]) for i in range(1, len(poly) - 1)]
    return out


class BSPWorkpiece:
    """A workpiece as one exact BSP (the stand-in; see the module docstring).

    Attributes
    ----------
    grid : csgnb.exact.Grid
    bsp : csgnb.bsp.BSP
    """

    def __init__(self, bsp: BSP, grid: Grid) -> None:
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a csgnb.exact.Grid, got {type(grid).__name__}")
        if bsp.tree.width != grid.width:
            raise GeometryError(f"the BSP is {bsp.tree.width}-bit but the grid is {grid.width}-bit")
        self.bsp = bsp
        self.grid = grid
        self._volume: Fraction | None = None

    # -- construction ---------------------------------------------------------------

    @classmethod
    def box(cls, lo, hi, *, grid: Grid) -> BSPWorkpiece:
        """The box with model-unit corners ``lo``, ``hi`` (each rounded to the grid)."""
        g = grid.to_grid(np.stack([np.asarray(lo, float).reshape(3), np.asarray(hi, float).reshape(3)]))
        if np.any(g[0] >= g[1]):
            raise GeometryError(f"the stock box {np.asarray(lo).tolist()}..{np.asarray(hi).tolist()} is empty on a "
                                f"grid of resolution {grid.resolution:g}")
        return cls(BSP.box(g[0], g[1], width=grid.width), grid)

    @classmethod
    def from_mesh(cls, vertices, faces, *, grid: Grid) -> BSPWorkpiece:
        """A closed, outward float mesh in model units, quantized by ``grid`` (validated like ``BSP.from_mesh``)."""
        V = grid.to_grid(np.asarray(vertices, float))
        return cls(BSP.from_mesh(V, np.asarray(faces), width=grid.width), grid)

    @classmethod
    def empty(cls, grid: Grid) -> BSPWorkpiece:
        """No material (unions grow it)."""
        palette = np.zeros((0, 4), wide_dtype(grid.width))
        return cls(BSP(BSPTree.leaf(palette, 0), (-1, -1, -1), (1, 1, 1)), grid)

    # -- Booleans -------------------------------------------------------------------

    def _tool(self, tool) -> BSP:
        # A hull's linear BSP is cheap to build; building it first keeps every check in one place.
        if isinstance(tool, ConvexHull):
            if tool.grid is not None and not tool.grid.same_as(self.grid):
                raise GeometryError(f"the tool lies on {tool.grid}, the workpiece on {self.grid}: quantize both on "
                                    "one grid")
            box = np.stack([tool.lo, tool.hi])
            if np.abs(box).max() > self.grid.max_coordinate:
                raise GeometryError(f"the tool's box {tool.lo.tolist()}..{tool.hi.tolist()} leaves the grid's budget "
                                    f"box |coordinate| <= {self.grid.max_coordinate}")
            return tool.to_bsp(self.grid.width)
        if isinstance(tool, BSP):
            if tool.tree.width != self.grid.width:
                raise GeometryError(f"the tool BSP is {tool.tree.width}-bit, the workpiece {self.grid.width}-bit")
            return tool
        raise TypeError(f"a tool must be a ConvexHull or a csgnb.bsp.BSP, got {type(tool).__name__}")

    def _disjoint(self, tool) -> bool:
        lo, hi = (tool.lo, tool.hi) if isinstance(tool, ConvexHull) else (np.array(tool.lo), np.array(tool.hi))
        return bool(np.any(np.asarray(hi) <= np.array(self.bsp.lo)) or np.any(np.asarray(lo) >= np.array(self.bsp.hi)))

    def _apply(self, tool, op: str) -> Fraction:
        b = self._tool(tool)  # refuses a bad tool before anything else
        before = self.volume()
        if op == "difference" and (before == 0 or self._disjoint(tool)):
            return Fraction(0)
        result = getattr(self.bsp, op)(b)
        self.bsp = result
        self._volume = None
        after = self.volume()
        return after - before if op == "union" else before - after

    def difference(self, tool) -> Fraction:
        """Subtract ``tool``; return the exact volume removed (grid units cubed)."""
        return self._apply(tool, "difference")

    def union(self, tool) -> Fraction:
        """Add ``tool``; return the exact volume added."""
        return self._apply(tool, "union")

    def intersection(self, tool) -> Fraction:
        """Keep what lies in ``tool``; return the exact volume removed."""
        return self._apply(tool, "intersection")

    def __isub__(self, tool):
        self.difference(tool)
        return self

    def __ior__(self, tool):
        self.union(tool)
        return self

    def __iand__(self, tool):
        self.intersection(tool)
        return self

    # -- queries --------------------------------------------------------------------

    def volume(self) -> Fraction:
        """Exact volume (grid units cubed)."""
        if self._volume is None:
            tree = self.bsp.tree
            self._volume = Fraction(0) if tree.n_inner == 0 and int(tree.label[0]) == 0 else self.bsp.volume()
        return self._volume

    def model_volume(self) -> Fraction:
        """Exact volume in model units cubed (the grid scale is a power of two)."""
        return self.volume() / Fraction(self.grid.scale) ** 3

    @property
    def n_nodes(self) -> int:
        """BSP nodes of the whole workpiece (what makes the stand-in slow as it grows)."""
        return self.bsp.n_nodes

    def to_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """The exact boundary as float model vertices ``(n, 3)`` and outward triangles ``(m, 3) int64``."""
        if self.volume() == 0:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
        s = self.bsp.surface()
        X = [tuple(int(x) for x in row) for row in from_wide(s.vertices)]
        tris = [t for f in s.polygons() for t in _ear_triangles([int(i) for i in f], X)]
        return self.grid.to_model(s.positions()), np.array(tris, np.int64).reshape(-1, 3)

    def to_polydata(self):
        """The boundary as a pyvista ``PolyData`` in model units."""
        import pyvista as pv

        V, T = self.to_mesh()
        return pv.PolyData(V, np.column_stack([np.full(len(T), 3), T]).reshape(-1) if len(T) else None)

    # -- persistence ------------------------------------------------------------------

    def _arrays(self) -> dict[str, np.ndarray]:
        t = self.bsp.tree
        return {"limbs": np.ascontiguousarray(t.palette["limbs"]), "plane": t.plane, "neg": t.neg, "pos": t.pos,
                "label": t.label, "box": np.array([self.bsp.lo, self.bsp.hi], np.int64)}

    def save(self, path) -> None:
        """Write the workpiece to ``path`` (a versioned .npz with a checksum; written to a temporary file, then
        renamed, so an interrupted save leaves the previous file intact)."""
        path = Path(path)
        arrays = self._arrays()
        digest = hashlib.sha256(b"".join(a.tobytes() for a in arrays.values())).hexdigest()
        header = {"format": _FORMAT, "version": _VERSION, "width": self.grid.width, "scale": self.grid.scale,
                  "origin": self.grid.origin.tolist(), "max_coordinate": self.grid.max_coordinate, "sha256": digest}
        fd, tmp = tempfile.mkstemp(dir=path.parent or ".", prefix=path.name + ".", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(fh, header=np.array(json.dumps(header)), **arrays)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    @classmethod
    def load(cls, path) -> BSPWorkpiece:
        """Read a workpiece written by :meth:`save`; a corrupted or truncated file is a clear ``ValueError``."""
        try:
            with np.load(Path(path), allow_pickle=False) as z:
                header = json.loads(str(z["header"]))
                arrays = {k: z[k] for k in ("limbs", "plane", "neg", "pos", "label", "box")}
        except (OSError, EOFError, KeyError, ValueError, zipfile.BadZipFile) as exc:
            raise ValueError(f"{path} is not a readable workpiece file (truncated or corrupted?): {exc}") from exc
        if header.get("format") != _FORMAT or header.get("version") != _VERSION:
            raise ValueError(f"{path} is a {header.get('format')} v{header.get('version')} file; this reads "
                             f"{_FORMAT} v{_VERSION}")
        digest = hashlib.sha256(b"".join(a.tobytes() for a in arrays.values())).hexdigest()
        if digest != header["sha256"]:
            raise ValueError(f"{path} is corrupted: its checksum does not match its contents")
        grid = Grid(scale=header["scale"], origin=header["origin"], width=header["width"],
                    max_coordinate=header["max_coordinate"])
        limbs = arrays["limbs"]
        if limbs.ndim != 3 or limbs.shape[1:] != (4, grid.width // 64):
            raise ValueError(f"{path} is corrupted: its plane palette has shape {limbs.shape}")
        palette = np.zeros(limbs.shape[:2], wide_dtype(grid.width))
        palette["limbs"] = limbs
        tree = BSPTree(palette, arrays["plane"], arrays["neg"], arrays["pos"], arrays["label"])
        return cls(BSP(tree, arrays["box"][0], arrays["box"][1]), grid)

    def __repr__(self) -> str:
        return f"BSPWorkpiece(stand-in, {self.n_nodes} BSP nodes, {self.grid})"
