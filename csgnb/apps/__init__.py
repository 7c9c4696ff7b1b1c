"""Applications on the exact workpiece (paper §5): tools, sweeps, G-code, milling simulation, carving.

Modules: :mod:`~csgnb.apps.tools` (tool meshes in mm on a grid), :mod:`~csgnb.apps.sweep`
(swept volumes as exact convex hulls), :mod:`~csgnb.apps.gcode` (a G-code parser),
:mod:`~csgnb.apps.milling` (the simulation loop), :mod:`~csgnb.apps.meter` (exact per-move
removed volumes on the octree cells a tool reaches), :mod:`~csgnb.apps.export` (STL),
:mod:`~csgnb.apps.carving` (Figure 15a placements), :mod:`~csgnb.apps.examples` (the shipped
G-code programs). The workpiece they drive is :class:`csgnb.octree.Workpiece`;
:class:`~csgnb.apps._bsp_workpiece.BSPWorkpiece` (one whole-workpiece BSP, exact and slow)
is the tests' independent reference.
"""
