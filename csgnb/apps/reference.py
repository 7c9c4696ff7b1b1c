"""Reference workpiece on one whole-workpiece :class:`csgnb.bsp.BSP` -- exact, complete, and slow.

:class:`BSPWorkpiece` has the API of :class:`csgnb.octree.Workpiece` that the applications
use, built on the single-BSP engine: every Boolean re-does the whole workpiece (a merge and
redundancy removal; a boundary extraction for the exact volume), so its cost grows with the
part. It is not the product's workpiece (``csgnb.mill`` and the notebooks use the octree);
the tests keep it as an independent reference -- the octree's exact volumes and
classifications must agree with it on the same tool sweeps.

Interface (volumes exact :class:`fractions.Fraction` in **grid units cubed**;
``grid.scale ** 3`` grid units make one cubic model unit):

* ``BSPWorkpiece.box(lo, hi, *, grid)`` -- model-unit corners, quantized by ``grid``;
  ``from_mesh(vertices, faces, *, grid)`` -- a closed float mesh in model units;
  ``empty(grid)`` -- nothing (a start for unions);
* ``w.grid``; ``w.difference(tool, track_volume=False)``, ``union``, ``intersection`` with a
  :class:`~csgnb.mesh.hull.ConvexHull`, a :class:`~csgnb.bsp.BSP` or an integer mesh
  ``(vertices, faces)`` in grid coordinates, returning a :class:`csgnb.octree.OpReport`
  (``volume_change`` with ``track_volume=True``);
* ``w.volume()``, ``w.model_volume()``, ``w.surface()``, ``w.to_polydata()``,
  ``w.save(path)``, ``BSPWorkpiece.load(path)``.
"""

from __future__ import annotations

import time
from fractions import Fraction

import numpy as np

from csgnb.bsp.solid import BSP
from csgnb.bsp.surface import BoundarySurface
from csgnb.bsp.tree import BSPTree
from csgnb.errors import GeometryError
from csgnb.exact.quantization import Grid
from csgnb.exact.wide import wide_dtype
from csgnb.mesh.hull import ConvexHull
from csgnb.octree import OpReport

__all__ = ["BSPWorkpiece"]

_FORMAT = "csgnb-bsp-workpiece"
_VERSION = 2


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
        if isinstance(tool, tuple) and len(tool) == 2:
            V, F = np.asarray(tool[0]), np.asarray(tool[1])
            if V.dtype.kind not in "iu":
                raise TypeError("a tool mesh must have integer grid coordinates; quantize it with the workpiece's "
                                "grid first (w.grid.to_grid(vertices))")
            if np.abs(V).max() > self.grid.max_coordinate:
                raise GeometryError(f"the tool mesh leaves the grid's budget box |coordinate| <= "
                                    f"{self.grid.max_coordinate}")
            return BSP.from_mesh(V, F, width=self.grid.width)
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
        raise TypeError(f"a tool must be a ConvexHull, a csgnb.bsp.BSP or (vertices, faces), got {type(tool).__name__}")

    def _disjoint(self, tool: BSP) -> bool:
        return bool(np.any(np.asarray(tool.hi) <= np.array(self.bsp.lo)) or
                    np.any(np.asarray(tool.lo) >= np.array(self.bsp.hi)))

    def _apply(self, tool, op: str, track_volume: bool) -> OpReport:
        t0 = time.perf_counter()
        b = self._tool(tool)  # refuses a bad tool before anything else
        before = self.volume() if track_volume else None
        if not (op == "difference" and (self._is_empty() or self._disjoint(b))):
            self.bsp = getattr(self.bsp, op)(b)
            self._volume = None
        report = OpReport(1, 1, 0, 0, 0, 0.0)
        if track_volume:
            report.volume_change = self.volume() - before
        report.seconds = time.perf_counter() - t0
        return report

    def _is_empty(self) -> bool:
        tree = self.bsp.tree
        return tree.n_inner == 0 and int(tree.label[0]) == 0

    def difference(self, tool, *, track_volume: bool = False) -> OpReport:
        """Subtract ``tool``; with ``track_volume`` the report's ``removed`` is the exact volume removed."""
        return self._apply(tool, "difference", track_volume)

    def union(self, tool, *, track_volume: bool = False) -> OpReport:
        """Add ``tool``; with ``track_volume`` the report's ``volume_change`` is the exact volume added."""
        return self._apply(tool, "union", track_volume)

    def intersection(self, tool, *, track_volume: bool = False) -> OpReport:
        """Keep what lies in ``tool``."""
        return self._apply(tool, "intersection", track_volume)

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
            self._volume = Fraction(0) if self._is_empty() else self.bsp.volume()
        return self._volume

    def model_volume(self) -> Fraction:
        """Exact volume in model units cubed (the grid scale is a power of two)."""
        return self.grid.model_volume(self.volume())

    @property
    def n_nodes(self) -> int:
        """BSP nodes of the whole workpiece (what makes the stand-in slow as it grows)."""
        return self.bsp.n_nodes

    def surface(self) -> BoundarySurface:
        """The exact, closed boundary (grid coordinates)."""
        return self.bsp.surface()

    def to_mesh(self, manifold: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The exact boundary as float model vertices ``(n, 3)`` and outward triangles ``(m, 3) int64``
        (the triangulation of :meth:`csgnb.octree.Workpiece.to_mesh`)."""
        return self.surface().to_mesh(manifold, transform=self.grid.to_model)

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
        """Write the workpiece to ``path`` (:mod:`csgnb.octree.persist`: a versioned .npz with a checksum, written
        deterministically to a temporary file, then renamed, so an interrupted save leaves the previous file
        intact)."""
        from csgnb.octree.persist import write_arrays

        g = self.grid
        header = {"width": g.width, "exponent": int(g.exponent), "origin": [float(x) for x in g.origin],
                  "max_coordinate": int(g.max_coordinate)}
        write_arrays(path, header, self._arrays(), file_format=_FORMAT, version=_VERSION)

    @classmethod
    def load(cls, path) -> BSPWorkpiece:
        """Read a workpiece written by :meth:`save`; a corrupted, truncated or inconsistent file is a clear
        ``WorkpieceFileError`` (a ``ValueError``)."""
        from csgnb.errors import CsgnbError
        from csgnb.octree.persist import WorkpieceFileError, read_arrays

        header, arrays = read_arrays(path, file_format=_FORMAT, version=_VERSION)
        names = {"limbs", "plane", "neg", "pos", "label", "box"}
        if set(arrays) != names:
            raise WorkpieceFileError(f"{path} is not a valid BSP workpiece: it holds the arrays {sorted(arrays)}, "
                                     f"expected {sorted(names)}")
        extra = set(header) - {"width", "exponent", "origin", "max_coordinate", "format", "version", "sha256"}
        if extra:
            raise WorkpieceFileError(f"{path} is not a valid BSP workpiece: unknown header field(s) {sorted(extra)}")
        try:
            if not all(isinstance(header.get(k), int) and not isinstance(header.get(k), bool)
                       for k in ("width", "exponent", "max_coordinate")):
                raise GeometryError("the header's width, exponent and max_coordinate must be integers")
            grid = Grid(exponent=header["exponent"], origin=header["origin"], width=header["width"],
                        max_coordinate=header["max_coordinate"])
            limbs, box = arrays["limbs"], arrays["box"]
            if limbs.dtype != np.uint64 or limbs.ndim != 3 or limbs.shape[1:] != (4, grid.width // 64):
                raise GeometryError(f"its plane palette has dtype {limbs.dtype} and shape {limbs.shape}, expected "
                                    f"uint64 (m, 4, {grid.width // 64})")
            if box.dtype != np.int64 or box.shape != (2, 3):
                raise GeometryError(f"its box has dtype {box.dtype} and shape {box.shape}, expected int64 (2, 3)")
            for name in ("plane", "neg", "pos", "label"):
                if arrays[name].dtype != np.int32 or arrays[name].ndim != 1:
                    raise GeometryError(f"its array {name!r} must be 1-D int32, got {arrays[name].dtype} "
                                        f"{arrays[name].shape}")
            palette = np.zeros(limbs.shape[:2], wide_dtype(grid.width))
            palette["limbs"] = limbs
            tree = BSPTree(palette, arrays["plane"], arrays["neg"], arrays["pos"], arrays["label"])  # validated
            return cls(BSP(tree, box[0], box[1]), grid)
        except (CsgnbError, TypeError, KeyError) as exc:
            raise WorkpieceFileError(f"{path} is not a valid BSP workpiece: {exc}") from None

    def __repr__(self) -> str:
        return f"BSPWorkpiece(stand-in, {self.n_nodes} BSP nodes, {self.grid})"
