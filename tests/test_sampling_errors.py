"""Bad input to the sampler raises clear errors (empty, unbounded, NaN, unsupported quadrics)."""

import numpy as np
import pytest

import csgnb.csg as csg
from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import elliptic_paraboloid, plane
from csgnb.sampling import sample_csg


@pytest.mark.parametrize(
    "shape, kwargs, exc, match",
    [
        (csg.sphere() & ~csg.sphere(), {}, GeometryError, "empty"),
        (csg.box((0, 0, 0), (1, 1, 1)) & csg.box((2, 0, 0), (3, 1, 1)), {}, GeometryError, "empty"),
        (~csg.sphere(), {}, GeometryError, "unbounded.*bounds=\\(center, radius\\)"),
        (csg.leaf(plane((0, 0, 1))), {}, GeometryError, "unbounded"),
        (csg.sphere(), {"bounds": ((10, 10, 10), 1.0)}, GeometryError, "empty"),
        (csg.sphere(), {"bounds": ((np.nan, 0, 0), 1.0)}, GeometryError, "finite center"),
        (csg.sphere(), {"bounds": (0, 1)}, CsgnbError, "bounding sphere"),
        (csg.leaf(elliptic_paraboloid()), {"bounds": ((0, 0, 0), 1.0)}, GeometryError, "paraboloid"),
        (csg.sphere(), {"distortion": "none"}, CsgnbError, "distortion must be"),
        (csg.sphere(), {"min_size": -1.0}, CsgnbError, "min_size"),
    ],
)
def test_bad_input(shape, kwargs, exc, match):
    with pytest.raises(exc, match=match):
        sample_csg(shape, 0.2, **kwargs)


@pytest.mark.parametrize("radius", [0.0, -1.0, np.nan, np.inf])
def test_bad_radius(radius):
    with pytest.raises(GeometryError, match="radius"):
        sample_csg(csg.sphere(), radius)


def test_nan_transforms_are_refused_where_the_edge_is_built():
    M = np.eye(4)
    M[0, 3] = np.nan
    with pytest.raises(GeometryError, match="NaN"):
        csg.sphere().transformed(M)


def test_unbounded_objects_sample_inside_a_bounding_sphere():
    cloud = sample_csg(csg.leaf(plane((0, 0, 1), 0.25)), 0.2, bounds=((0, 0, 0), 1.0))
    assert np.allclose(cloud.positions[:, 2], 0.25)
    assert np.all(np.abs(cloud.positions[:, :2]) <= 1.0 + 1e-9)
    # the complement of a sphere: its surface is the sphere
    cloud = sample_csg(~csg.sphere((0, 0, 0), 0.5), 0.1, bounds=((0, 0, 0), 2.0))
    assert np.allclose(np.linalg.norm(cloud.positions, axis=1), 0.5)
    assert np.allclose(np.einsum("ni,ni->n", cloud.normals, cloud.positions / 0.5), -1.0)
