"""Every float tolerance of the quadric track (``csgnb.quadric``, ``csgnb.csg``, ``csgnb.sampling``).

The exact track (``exact``, ``mesh``, ``bsp``) has none: its predicates are exact. Here floats are
unavoidable, and each tolerance says *relative to what* it is, so that no decision depends on the
units of a model. Two kinds occur:

* **relative to the terms of a computation** (units cancel): a quantity is treated as zero when it
  is below ``TOL × (the magnitude of the terms it was computed from)`` — e.g. an eigenvalue against
  the entries of A it came from, α_c against |qᵀb| + |c|. These hold at any scale.
* **relative to the model's scale**: the sampler works in a *normalised frame* where the model's
  box has half-diagonal ≈ 1 (``csgnb.sampling.frame``); tolerances on lengths and areas there are
  fractions of the model size. Functions that take a world box use its size the same way.

The values are far above rounding (≈ 1e-16 per operation) and far below any feature a user can
mean; the comment on each says why it sits where it does.
"""

from __future__ import annotations

EPS = 2.220446049250313e-16
"""Machine epsilon of float64 (unit roundoff × 2)."""

# -- quadric matrices (csgnb.quadric.quadric) ---------------------------------------------------

SYMMETRY = 1e-12
"""|Q − Qᵀ| above this × max|Q| rejects a matrix: rounding of a symmetric product stays far below."""

SINGULAR_CONDITION = 1e12
"""Condition number of a transform's linear part (affine maps) or of the matrix (projective ones)
above which it is refused as singular: Q' = M⁻ᵀQM⁻¹ would amplify rounding by cond² ≈ 1/EPS."""

PLANE = 1e-13
"""A quadric is a single plane when max|A| ≤ PLANE × |b| (over a unit length the quadratic term
is rounding next to the linear one). Exact zeros (planes built by csgnb, affine images of them)
always pass; the sampler asks in its normalised frame, where the unit length is the model size."""

LENGTH_MIN = 1e-75
LENGTH_MAX = 1e75
"""Radii and slopes given to the quadric constructors lie in [LENGTH_MIN, LENGTH_MAX]: coefficients are
their squares or inverse squares (a sphere's c = −r², an ellipsoid's A = diag(1/rᵢ²)), and the
intersection discriminants (eq. 5–6) and distances (eq. 10–12) multiply two coefficients, i.e. up to
fourth powers, which must stay normal doubles (1e-308 … 1e308). Beyond, r² underflows to 0 (a sphere of
radius 1e-200 becomes a point) or overflows (1e200: c = −inf) — rescale the model instead."""

COORDINATE_LIMIT = 1e150
"""Camera positions and distances (``csgnb.render.Camera``) are refused beyond ±COORDINATE_LIMIT: the
ray arithmetic squares coordinates, and 1e150² is near the top of the double range (1.8e308)."""

# -- principal frames (csgnb.quadric.frames) ----------------------------------------------------

EIGENVALUE_NOISE = 2.0**-40
"""An eigenvalue λ of A with unit eigenvector u is zero when |λ| ≤ EIGENVALUE_NOISE · uᵀ|A|u:
entry-wise rounding of A (from transforms, ≈ a few EPS per entry) moves λ by at most EPS · uᵀ|A|u
(first order), so smaller eigenvalues are indistinguishable from 0 — a rotated cylinder's third
eigenvalue. An eigenvalue of an exactly diagonal A is never noise (uᵀ|A|u = |λ|)."""

EIGENVECTOR_GAP = 1e-8
"""Eigenvalues of A within EIGENVECTOR_GAP × max|λ| of each other are one repeated eigenvalue: their
eigenvectors are determined only to EPS / gap ≥ 1e-8, so the frame takes canonical ones (world
axes) — the same for a model and its scaled or translated copy (``frames._canonical_eigenvectors``)."""

LINEAR_NOISE = 2.0**-40
"""The null-space part β of b (paraboloids, single planes) is zero when |β| ≤ LINEAR_NOISE ·
(|b| + |A| |q| + √(|A| |c|)) — the magnitude of the terms of b − Aq, and of the rounding that a
transform leaves in b (|A| times a length, here √(|c|/|A|): a cylinder through the origin has
b ≈ 0 and |q| ≈ 0, yet its b carries noise of order EPS·|A|·radius). Nonzero β makes the
quadric non-central."""

CONSTANT_NOISE = 2.0**-46
"""γ = c − qᵀb (the constant term at the center) is zero when |γ| ≤ CONSTANT_NOISE · (|c| + |qᵀb|)
(64 EPS: the two terms carry a few EPS each): cones, planes through the center. Kept tight because
a sphere of radius 1 at distance 10⁶ has γ = −1 next to terms of 10¹²."""

# -- CSG normal form and bounds (csgnb.csg) -------------------------------------------------------

SURFACE = 1e-12
"""Two quadrics are one surface when their matrices, each scaled to max|entry| = 1, agree (up to
sign) within SURFACE. Matched in the normalised frame, where all entries have comparable units."""

SUPPORT_SLACK = 1e-9
"""Feasibility slack of the bounding-box LP and padding of its boxes, × the size of the data
(largest |offset| or |coordinate|): a box is never smaller than the true one by rounding."""

PARALLEL = 1e-12
"""Three unit plane normals with |det| below this span no vertex in the LP enumeration."""

UNBOUNDED = 1e6
"""The LP searches a box this many model sizes wide; a term reaching it is reported unbounded."""

# -- sampling (csgnb.sampling) --------------------------------------------------------------------

ON_SURFACE = 1e-12
"""A region corner with |d_Qab| ≤ ON_SURFACE (× model size) is on a feature curve — in the closure
of the CSG surface — and may carry a sample: rounding puts points of aligned curves at ±1e-16."""

SLIVER = 1e-7
"""Domain triangles thinner than SLIVER × model size are dropped: they come from clipping at a box
face within rounding of a plane's axis, and the surface over them is that close to a neighbour's."""

DEGENERATE_AREA = 1e-24
"""(u, v)-polygons with |area| ≤ DEGENERATE_AREA × (largest (u, v))² are empty (areas in (u, v)
scale as length⁴: this is a (1e-6 · size)²-wide polygon)."""

MIN_REGION = 2.0**-8
"""Regions still unclassified below MIN_REGION × splat radius are given up (``stats.unresolved``,
see ``csgnb.sampling.kernel``): only isolated tangency points are left there."""

CURVED_SIDE = 1e-12
"""A (u, v)-side whose end tangents are parallel to within CURVED_SIDE (relative) is straight."""

MIN_RADIUS = 1e-9
"""Splat radii below MIN_RADIUS × model size are refused: samples would be lifted with less
precision than their own radius (and would need > 1e18 samples)."""

WORLD_ROUNDING = 8.0
"""Samples are computed in the normalised frame and written in world coordinates: the frame's map and
that write round them by at most WORLD_ROUNDING · EPS · D, D = |frame center|∞ + model size (a few
roundings of numbers of size D; 1.8e-6 at D = 10¹⁰). The sampler covers with its radius shortened by
that much, so the guarantee holds at the requested radius wherever the model is."""

COEFFICIENT_ROUNDING = 4.0
"""A quadric given by its world matrix (no ``Quadric.placement``) carries rounding of about
COEFFICIENT_ROUNDING · EPS · (|c| + |qᵀb|) in its constant at the center γ = c − qᵀb, which moves its
surface by that over |∇Q| ≈ 2√(λ_max |γ|): a unit sphere at 10⁹ given by its matrix has c = 10¹⁸ − 1
and no radius left. The sampler refuses leaves moved more than FAR_FROM_ORIGIN × the radius."""

FAR_FROM_ORIGIN = 1e-3
"""A model whose world rounding (WORLD_ROUNDING · EPS · D) exceeds FAR_FROM_ORIGIN × the splat radius
is refused: double precision cannot place its samples that close to the surface (a unit sphere at
10¹² with radius 0.2: coordinates there are 1.2e-4 apart). Move it nearer the origin, or sample
with a larger radius."""

RENDER_ROUNDING = 0.1
"""The renderers (``csgnb.render``) work in world coordinates: a quadric of size L at distance D from
the origin has coefficients of size D² (a sphere's c = D² − L²), whose rounding EPS · D² moves its
surface by EPS · D² / L. A scene where that exceeds RENDER_ROUNDING of a pixel (2 L / the larger
image side: the scene filling the view) is refused rather than drawn wrong."""

FEATURE_REGION = 0.25
"""Regions with all corners off the surface but not proven off, once smaller than FEATURE_REGION of a
sample's reach, are searched for a point of a tangency curve (``csgnb.sampling.kernel``, rule 3)
and, if none is found, handed to the neighbour rule: small enough that a sample next to them covers
them, large enough that tangency bands (where d_Qab grows quadratically) are not cut into tiny
regions first."""

# -- small relative margins (dimensionless) -----------------------------------------------------

TIE = 1e-12
"""Ties between unit-vector components (which world axis a canonical eigenvector follows, which
component sets its sign) are broken towards the first axis unless one is larger by TIE: rounding
must not flip the choice between a model and its scaled copy."""

SAME_POINT = 1e-12
"""Region polygon vertices closer than SAME_POINT × the largest |coordinate| are one vertex
(``csgnb.quadric.regions``); fan triangles with |area| ≤ (1e2 · SAME_POINT)·scale² are dropped."""

SPAN = 1e-9
"""A world axis whose projection on the span of a quadric's positive eigen-directions is shorter
than SPAN is normal to it (``csgnb.csg.bounds``: no support row along it)."""

ROOT_INTERVAL = 1e-15
"""The feature-point root search stops when its bracket on the edge parameter is this short."""

NEIGHBOUR_MARGIN = 1e-12
"""The neighbour rule covers a region by a sample only with this relative margin on the radius."""

LATTICE_FLOOR = 1e-3
"""A lattice's plane covering radius r/δ − bulge is never below LATTICE_FLOOR · r/δ (the bulge
reaches r/δ only at the depth limit, so this only keeps the arithmetic finite)."""
