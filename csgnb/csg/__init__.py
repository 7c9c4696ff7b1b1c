"""CSG graphs over quadrics, their disjunctive normal form and CSG distances (paper §5).

Graphs (:mod:`.graph`): leaves, variadic union / intersection, difference, complement and
transforms on edges, shared sub-graphs allowed. Convenience solids (:mod:`.solids`). The normal
form with transforms pushed into the leaves (:mod:`.normal_form`, eq. 17–18), the conservative
distance to the CSG surface and the quadric-relative distance (:mod:`.distance`, eq. 19–22), and
bounding boxes of terms (:mod:`.bounds`).
"""

from csgnb.csg.bounds import surface_box, term_boxes
from csgnb.csg.distance import csg_distance, csg_value, relative_distance
from csgnb.csg.graph import (
    Complement,
    Difference,
    Intersection,
    Leaf,
    Node,
    Transformed,
    Union,
    as_node,
    complement,
    difference,
    graph_leaves,
    graph_size,
    intersection,
    leaf,
    rotation_matrix,
    transformed,
    union,
)
from csgnb.csg.normal_form import NormalForm, quadric_coefficients, to_normal_form
from csgnb.csg.solids import box, capsule, cone, cylinder, ellipsoid, rounded_box, sphere

__all__ = [
    "Node",
    "Leaf",
    "Union",
    "Intersection",
    "Difference",
    "Complement",
    "Transformed",
    "leaf",
    "union",
    "intersection",
    "difference",
    "complement",
    "transformed",
    "as_node",
    "rotation_matrix",
    "graph_leaves",
    "graph_size",
    "NormalForm",
    "to_normal_form",
    "quadric_coefficients",
    "csg_distance",
    "csg_value",
    "relative_distance",
    "term_boxes",
    "surface_box",
    "box",
    "cylinder",
    "cone",
    "sphere",
    "ellipsoid",
    "capsule",
    "rounded_box",
]
