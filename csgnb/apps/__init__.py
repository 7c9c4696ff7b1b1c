"""Applications on the exact workpiece (paper §5): tools, sweeps, G-code, milling simulation, carving.

Modules: :mod:`~csgnb.apps.tools` (tool meshes in mm on a grid), :mod:`~csgnb.apps.sweep`
(swept volumes as exact convex hulls), :mod:`~csgnb.apps.gcode` (a G-code parser),
:mod:`~csgnb.apps.milling` (the simulation loop), :mod:`~csgnb.apps.carving` (Figure 15a
placements). The workpiece they drive is duck-typed (see :mod:`csgnb.apps.milling`);
:class:`~csgnb.apps._bsp_workpiece.BSPWorkpiece` is a slow, exact stand-in on one BSP.
"""
