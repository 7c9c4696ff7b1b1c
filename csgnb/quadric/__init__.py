"""Quadric fundamentals (paper: Trettner & Kobbelt, *Sampling from quadric-based CSG surfaces*).

Quadrics and their constructors (:mod:`.quadric`), point kernels (:mod:`.evaluate`),
principal frames, sampling planes and heightfields of every quadric type (:mod:`.frames`), the
conservative signed distance (:mod:`.distance`), heightfield distortion (:mod:`.distortions`),
the low-distortion basic regions (:mod:`.regions`), argument checks (:mod:`.arguments`) and
every float tolerance of the quadric track (:mod:`.tolerances`).
"""

from csgnb.quadric.distance import signed_distance
from csgnb.quadric.distortions import distortion, distortion_bounds
from csgnb.quadric.evaluate import gradient, intersect_lines, normal, value
from csgnb.quadric.frames import (
    FORMS,
    HEIGHTFIELD_TYPES,
    PrincipalFrame,
    SamplingPlane,
    from_plane_coordinates,
    heightfield,
    heightfield_type,
    principal_frame,
    sampling_planes,
    to_plane_coordinates,
)
from csgnb.quadric.quadric import (
    QUADRIC_CONSTRUCTORS,
    Quadric,
    ellipsoid,
    elliptic_cone,
    elliptic_cylinder,
    elliptic_paraboloid,
    hyperbolic_paraboloid,
    hyperboloid_one_sheet,
    hyperboloid_two_sheets,
    parallel_planes,
    plane,
    sphere,
)
from csgnb.quadric.regions import (
    REGION_KINDS,
    BasicRegion,
    low_distortion_regions,
    octant_case,
    owning_plane,
    plane_regions,
    region_contains,
    region_mesh,
)

__all__ = [
    "Quadric",
    "QUADRIC_CONSTRUCTORS",
    "plane",
    "parallel_planes",
    "sphere",
    "ellipsoid",
    "elliptic_cylinder",
    "elliptic_cone",
    "hyperboloid_one_sheet",
    "hyperboloid_two_sheets",
    "elliptic_paraboloid",
    "hyperbolic_paraboloid",
    "value",
    "gradient",
    "normal",
    "intersect_lines",
    "signed_distance",
    "PrincipalFrame",
    "SamplingPlane",
    "HEIGHTFIELD_TYPES",
    "FORMS",
    "principal_frame",
    "sampling_planes",
    "heightfield",
    "heightfield_type",
    "to_plane_coordinates",
    "from_plane_coordinates",
    "distortion",
    "distortion_bounds",
    "BasicRegion",
    "REGION_KINDS",
    "low_distortion_regions",
    "plane_regions",
    "octant_case",
    "region_contains",
    "owning_plane",
    "region_mesh",
]
