"""Exact integer geometry: fixed-width 128/192/256-bit plane predicates (paper §3.2).

Wide integers live in numpy arrays of a record dtype (little-endian uint64 limbs,
:func:`wide_dtype`); :func:`to_wide` / :func:`from_wide` convert to and from Python
ints. Every predicate checks its inputs against the bit budget of the width
(:func:`budget`) and raises :class:`csgnb.PrecisionError` rather than overflow.

>>> import numpy as np
>>> from csgnb import exact
>>> planes = exact.to_wide([[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, -3]], 128)
>>> x = exact.intersect_3_planes(planes[0], planes[1], planes[2])
>>> exact.to_double_position(x)
array([1., 2., 3.])
"""

from csgnb.exact.budgets import BitBudget, budget, integer_root
from csgnb.exact.integral import exact_int, integer_array
from csgnb.exact.planes import is_narrow_planes, plane_dtype, plane_width_of, to_full_planes, to_narrow_planes
from csgnb.exact.predicates import (
    are_planes_parallel,
    classify_vertex,
    homogeneous_points,
    intersect_3_planes,
    plane_from_points,
    points_equal,
    signed_distance,
    to_double_position,
)
from csgnb.exact.quantization import Grid, Quantization, quantize
from csgnb.exact.wide import (
    DEFAULT_WIDTH,
    WIDTHS,
    check_width,
    from_wide,
    is_wide,
    to_wide,
    to_width,
    wide_dtype,
    width_of,
)

__all__ = [
    "WIDTHS",
    "BitBudget",
    "DEFAULT_WIDTH",
    "Grid",
    "Quantization",
    "are_planes_parallel",
    "budget",
    "check_width",
    "classify_vertex",
    "exact_int",
    "from_wide",
    "homogeneous_points",
    "integer_array",
    "integer_root",
    "intersect_3_planes",
    "is_narrow_planes",
    "is_wide",
    "plane_dtype",
    "plane_from_points",
    "plane_width_of",
    "points_equal",
    "quantize",
    "signed_distance",
    "to_double_position",
    "to_full_planes",
    "to_narrow_planes",
    "to_wide",
    "to_width",
    "wide_dtype",
    "width_of",
]
