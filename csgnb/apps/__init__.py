"""Applications on the exact workpiece (paper §5): tools, sweeps, G-code, milling simulation, carving.

Modules: :mod:`~csgnb.apps.tools` (tool meshes in mm on a grid), :mod:`~csgnb.apps.sweep`
(swept volumes as exact convex hulls), :mod:`~csgnb.apps.gcode` (a G-code parser),
:mod:`~csgnb.apps.milling` (the simulation loop; the workpiece measures each move's exact
removed volume), :mod:`~csgnb.apps.export` (a checked STL),
:mod:`~csgnb.apps.carving` (Figure 15a placements), :mod:`~csgnb.apps.examples` (the shipped
G-code programs). The workpiece they drive is :class:`csgnb.octree.Workpiece`, through its
public API only (no octree array is read here);
:class:`~csgnb.apps.reference.BSPWorkpiece` (one whole-workpiece BSP, exact and slow)
is the tests' independent reference.
"""
