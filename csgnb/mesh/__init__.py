"""Exact convex polytopes in a flat half-edge store, cut in place by planes (paper §3.3).

:class:`MeshStore` holds many polytopes with homogeneous integer vertices; :func:`cut`
splits one by a palette plane with edge descent and marching (or the naive baseline).
"""

from csgnb.mesh.cutting import CutResult, cut
from csgnb.mesh.halfedge import MeshStore, box_planes, polygons_volume

__all__ = ["CutResult", "MeshStore", "box_planes", "cut", "polygons_volume"]
