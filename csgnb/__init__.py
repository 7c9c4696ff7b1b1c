"""csgnb: exact constructive solid geometry, in notebooks that run as tests.

Two pipelines (see docs/ARCHITECTURE.md):

* exact iterated CSG: :mod:`csgnb.exact` (128/192/256-bit plane predicates) → mesh
  cutting → BSP Booleans → octree → applications;
* quadric CSG surfaces: :mod:`csgnb.quadric` → CSG graphs → sampling → rendering.
"""

from csgnb.errors import CsgnbError, GeometryError, InternalError, PrecisionError

__version__ = "0.1.0"

__all__ = ["CsgnbError", "GeometryError", "InternalError", "PrecisionError", "__version__"]
