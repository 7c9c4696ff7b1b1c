"""Every public function of csgnb.quadric, csgnb.csg and csgnb.sampling, walked with bad arguments.

For each function a valid call is listed; then every positional argument in turn is replaced by
each value of ``BAD`` (wrong types, NaN, wrong shapes, ragged lists, ...). The call must succeed
(some bad values are valid somewhere: -1.0 is a fine offset) or raise a csgnb error
(``CsgnbError``, a ``ValueError``) or a ``TypeError`` whose message names the problem — never a
raw ``AttributeError``, ``IndexError``, ``ZeroDivisionError``, ``KeyError`` or a numpy internal
error. Plain data records (``PrincipalFrame``, ``SamplingPlane``, ``BasicRegion``, ``NormalForm``,
``SampleCloud``, ``SamplingStats``, ``SamplingTrace``, ``TaskSet``) are not validated and are left
out; the catalogue checks that every other public callable is listed.
"""

from __future__ import annotations

import numpy as np
import pytest

import csgnb.csg as csg
import csgnb.quadric as cq
import csgnb.sampling as cs
from csgnb.errors import CsgnbError

RECORDS = {"PrincipalFrame", "SamplingPlane", "BasicRegion", "NormalForm", "SampleCloud", "SamplingStats",
           "SamplingTrace", "TaskSet", "Node"}

BAD = [None, "abc", 1 + 2j, np.nan, -1.0, 0, True, [], [[1.0, 2.0], [3.0]], np.zeros((2, 2)), np.full(3, np.inf),
       object(), {"a": 1}]


def _valid_calls():
    q = cq.sphere()
    plane = cq.sampling_planes(q)[0]
    region = cq.low_distortion_regions(q, (-2, -2, -2), (2, 2, 2))[0]
    nf = (csg.sphere() & csg.sphere((0.5, 0, 0))).normal_form()
    boxes, _ = csg.term_boxes(nf)
    pts = np.zeros((2, 3))
    return {
        # csgnb.quadric
        "Quadric": (np.diag([1.0, 1.0, 1.0, -1.0]),),
        "plane": ((0.0, 0.0, 1.0), 0.5),
        "parallel_planes": ((0.0, 0.0, 1.0), -1.0, 1.0),
        "sphere": ((0.0, 0.0, 0.0), 1.0),
        "ellipsoid": ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)),
        "elliptic_cylinder": ((1.0, 2.0), (0.0, 0.0, 0.0)),
        "elliptic_cone": ((1.0, 2.0), (0.0, 0.0, 0.0)),
        "hyperboloid_one_sheet": ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)),
        "hyperboloid_two_sheets": ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)),
        "elliptic_paraboloid": ((1.0, 2.0), (0.0, 0.0, 0.0)),
        "hyperbolic_paraboloid": ((1.0, 2.0), (0.0, 0.0, 0.0)),
        "value": (q, pts),
        "gradient": (q, pts),
        "normal": (q, pts),
        "intersect_lines": (q, pts, np.ones((2, 3))),
        "signed_distance": (q, pts),
        "principal_frame": (q,),
        "sampling_planes": (q,),
        "heightfield": (plane, [0.1], [0.2]),
        "heightfield_type": ([-1.0, -1.0, 1.0],),
        "to_plane_coordinates": (plane, pts),
        "from_plane_coordinates": (plane, pts),
        "distortion": (plane, [0.1], [0.2]),
        "distortion_bounds": (plane, [[0.0, 0.0, 0.1, 0.1]]),
        "low_distortion_regions": (q, (-2, -2, -2), (2, 2, 2)),
        "plane_regions": (q, plane, (-2, -2, -2), (2, 2, 2)),
        "octant_case": ([-1.0, -1.0, 1.0], "x"),
        "region_contains": (region, [[0.1, 0.1]], 0.0),
        "owning_plane": (q, pts + [1.0, 0, 0]),
        "region_mesh": (plane, region, 4, 1.0),
        # csgnb.csg
        "Leaf": (q, "ball"),
        "Union": ([csg.sphere(), csg.sphere()],),
        "Intersection": ([csg.sphere(), csg.sphere()],),
        "Difference": (csg.sphere(), [csg.sphere((0.5, 0, 0), 0.5)]),
        "Complement": (csg.sphere(),),
        "Transformed": (csg.sphere(), np.eye(4)),
        "leaf": (q, "ball"),
        "union": (csg.sphere(), csg.sphere((1, 0, 0))),
        "intersection": (csg.sphere(), csg.sphere((1, 0, 0))),
        "difference": (csg.sphere(), csg.sphere((1, 0, 0))),
        "complement": (csg.sphere(),),
        "transformed": (csg.sphere(), np.eye(4)),
        "as_node": (q,),
        "rotation_matrix": ((0.0, 0.0, 1.0), 0.5, (0.0, 0.0, 0.0)),
        "graph_leaves": (csg.sphere(),),
        "graph_size": (csg.sphere(),),
        "to_normal_form": (csg.sphere(), 16),
        "quadric_coefficients": ([q],),
        "csg_distance": (nf, pts),
        "csg_value": (nf, pts),
        "relative_distance": (nf, 0, pts),
        "term_boxes": (nf, np.array([-2.0, -2, -2, 2, 2, 2])),
        "surface_box": (q, np.array([-2.0, -2, -2, 2, 2, 2]), 2.0),
        "box": ((0, 0, 0), (1, 1, 1), "b"),
        "cylinder": ((0, 0, 0), (0, 0, 1), 0.5, "c"),
        "cone": ((0, 0, 0), (0, 0, 1), 0.5, 0.2, "k"),
        # (sphere and ellipsoid: the quadric ones are checked above; the csg ones below by name)
        "capsule": ((0, 0, 0), (0, 0, 1), 0.5, "p"),
        "rounded_box": ((0, 0, 0), (2, 2, 2), 0.3, "r"),
        # csgnb.sampling
        "sample_csg": (csg.sphere(), 0.5),
        "estimate_samples": (csg.sphere(), 0.5),
        "build_tasks": (nf, boxes, 0.5),
        "build_task_set": (nf, np.tile(boxes[0], (len(nf), 1)), boxes, 0.5, 1.0),
        "deduplicate_clip_sets": (np.array([0, 1, 2]), np.array([3, 3])),
        "quadric_jobs": (q, np.array([-2.0, -2, -2, 2, 2, 2]), 2.0),
        "domain_cache_clear": (),
    }


CSG_OWN = {"sphere": ((0.0, 0.0, 0.0), 1.0, "s"), "ellipsoid": ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0), "e")}

MODULES = {"quadric": cq, "csg": csg, "sampling": cs}


def _public_callables():
    out = []
    for mod_name, mod in MODULES.items():
        for name in mod.__all__:
            obj = getattr(mod, name)
            if callable(obj) and name not in RECORDS:
                out.append((mod_name, name))
    return out


def test_the_catalogue_lists_every_public_callable():
    valid = _valid_calls()
    missing = [f"{m}.{n}" for m, n in _public_callables() if n not in valid and not (m == "csg" and n in CSG_OWN)]
    assert not missing, f"add these to the catalogue: {missing}"


def _call(mod, name, args):
    return getattr(mod, name)(*args)


@pytest.mark.parametrize("mod_name, name", _public_callables())
def test_bad_arguments_raise_clear_errors(mod_name, name):
    mod = MODULES[mod_name]
    args = CSG_OWN[name] if mod_name == "csg" and name in CSG_OWN else _valid_calls()[name]
    _call(mod, name, args)  # the valid call works
    for i in range(len(args)):
        for bad in BAD:
            trial = list(args)
            trial[i] = bad
            try:
                _call(mod, name, trial)
            except (CsgnbError, TypeError) as exc:
                assert str(exc), f"{mod_name}.{name} argument {i} = {bad!r}: an error without a message"
            except Exception as exc:  # noqa: BLE001 - the point of the test
                pytest.fail(f"{mod_name}.{name} argument {i} = {bad!r} raised {type(exc).__name__}: {exc}")


# -- csgnb.render and the keyword options of csgnb.sampling (issue 25, item 5) ------------------------

RENDER_BAD = [None, "abc", 1 + 2j, np.nan, np.inf, -1.0, 0, 0.0, True, [], [[1.0, 2.0], [3.0]], np.zeros((2, 2)),
              np.full(3, np.inf), object(), {"a": 1}, 10**12, 1e300, np.zeros((0, 3)), (np.zeros(3), 1.0)]

#: How a message may name an argument besides its own name.
ALIASES = {"fov": ["field of view"], "ortho_height": ["orthographic view height"], "shape": ["CSG"],
           "cloud": ["SampleCloud"], "camera": ["Camera"], "normal_form": ["NormalForm"]}


def _render_calls():
    import csgnb.render as cr

    shape = csg.sphere((0, 0, 0), 1.0)
    cloud = cs.sample_csg(shape, 0.5)
    cam = cr.Camera.look_at((4, 0, 0), (0, 0, 0), (0, 0, 1), 16, 12)
    fr = cr.raytrace(shape, cam)
    lod = cr.LevelsOfDetail(cloud)
    chooser = cr.LevelChooser(lod)
    box = ((-1.0, -1, -1), (1.0, 1, 1))
    return {
        "Camera": (cr.Camera, dict(eye=(4.0, 0, 0), target=(0.0, 0, 0), up=(0.0, 0, 1), width=16, height=12,
                                   fov=40.0, projection="perspective", ortho_height=2.0)),
        "Camera.look_at": (cr.Camera.look_at, dict(eye=(4.0, 0, 0), target=(0.0, 0, 0), up=(0.0, 0, 1), width=16,
                                                   height=12, fov=40.0, projection="perspective", ortho_height=None)),
        "Camera.orbit": (cr.Camera.orbit, dict(target=(0.0, 0, 0), azimuth=10.0, elevation=20.0, distance=4.0,
                                               width=16, height=12, up=(0.0, 0, 1), fov=40.0)),
        "Camera.fit": (cr.Camera.fit, dict(bounds=box, width=16, height=12, azimuth=-60.0, elevation=30.0,
                                           up=(0.0, 0, 1), fov=40.0, projection="perspective", margin=1.05)),
        "Camera.orbited": (cam.orbited, dict(d_azimuth=1.0, d_elevation=1.0, zoom=1.0)),
        "Camera.with_size": (cam.with_size, dict(width=8, height=8)),
        "Camera.rays": (cam.rays, dict(rows=[0, 1], cols=[0, 1])),
        "Camera.project": (cam.project, dict(points=np.zeros((2, 3)))),
        "raytrace": (cr.raytrace, dict(shape=shape, camera=cam, color_by="quadric", lit=True)),
        "render": (cr.render, dict(cloud=cloud, camera=cam, footprint="box", backface_culling=True, local="quadric",
                                   clip=True, color_by="quadric", lit=True, tile=16, fallback="auto",
                                   occlusion_culling=True, device="cpu")),
        "SplatRenderer": (cr.SplatRenderer, dict(cloud=cloud)),
        "renderer_for": (cr.renderer_for, dict(cloud=cloud)),
        "compare": (cr.compare, dict(frame=fr, reference=fr, rel=1e-9)),
        "verify": (cr.verify, dict(cloud=cloud, camera=cam, shape=shape)),
        "edge_mask": (cr.edge_mask, dict(frame=fr)),
        "overdraw_colors": (cr.overdraw_colors, dict(top=30)),
        "quadric_colors": (cr.quadric_colors, dict(normal_form=cloud.normal_form)),
        "Lighting": (cr.Lighting, dict(ambient=0.2, diffuse=0.7, specular=0.2, shininess=16.0)),
        "Frame.shaded": (fr.shaded, dict(color_by="quadric", lit=True, lighting=None, palette=None)),
        "Frame.difference": (fr.difference, dict(other=fr)),
        "Frame.png_bytes": (fr.png_bytes, dict(rgb=None, fmt="png")),
        "Frame.to_pyvista": (fr.to_pyvista, dict(kind="points")),
        "LevelsOfDetail": (cr.LevelsOfDetail, dict(cloud=cloud, target_pixels=12.0, finer=False)),
        "LevelsOfDetail.level_for": (lod.level_for, dict(camera=cam)),
        "LevelsOfDetail.cloud_at": (lod.cloud_at, dict(level=1)),
        "LevelsOfDetail.cloud_for": (lod.cloud_for, dict(camera=cam)),
        "LevelChooser": (cr.LevelChooser, dict(levels=lod, trials=2, keep=3)),
        "LevelChooser.choose": (chooser.choose, dict(camera=cam)),
        "LevelChooser.record": (chooser.record, dict(level=0, ms=5.0)),
        "footprint_pixels": (cr.footprint_pixels, dict(camera=cam, radius=0.5, point=(0.0, 0.0, 0.0))),
        "sample_csg": (cs.sample_csg, dict(shape=shape, radius=0.5, bounds=None, distortion="bounds", min_size=0.0,
                                           reduce_radius=False, refine=True, trace=False, max_terms=4096,
                                           max_samples=10**6)),
        "estimate_samples": (cs.estimate_samples, dict(shape=shape, radius=0.5, bounds=None, max_terms=4096)),
    }


RENDER_CALLS = ["Camera", "Camera.look_at", "Camera.orbit", "Camera.fit", "Camera.orbited", "Camera.with_size",
                "Camera.rays", "Camera.project", "raytrace", "render", "SplatRenderer", "renderer_for", "compare",
                "verify", "edge_mask", "overdraw_colors", "quadric_colors", "Lighting", "Frame.shaded",
                "Frame.difference", "Frame.png_bytes", "Frame.to_pyvista", "LevelsOfDetail", "LevelsOfDetail.level_for",
                "LevelsOfDetail.cloud_at", "LevelsOfDetail.cloud_for", "LevelChooser", "LevelChooser.choose",
                "LevelChooser.record", "footprint_pixels", "sample_csg",
                "estimate_samples"]


def _split(f, kw):
    import inspect

    args, kws = [], {}
    for n, p in inspect.signature(f).parameters.items():
        if n in kw:
            (kws.__setitem__(n, kw[n]) if p.kind == p.KEYWORD_ONLY else args.append(kw[n]))
    return args, kws


def test_the_render_catalogue_lists_every_public_callable():
    import csgnb.render as cr

    listed = set(RENDER_CALLS) | {"Viewer", "Frame", "RenderStats", "Agreement"}  # (widgets and records)
    missing = [n for n in cr.__all__ if callable(getattr(cr, n)) and n not in listed]
    assert not missing, f"add these to the render catalogue: {missing}"
    assert set(_render_calls()) == set(RENDER_CALLS)


@pytest.mark.parametrize("name", RENDER_CALLS)
def test_render_and_sampling_options_name_the_bad_argument(name):
    """Every argument (positional or keyword) of the render API and of the sampler's options, replaced by
    each bad value: the call works, or raises a csgnb error or TypeError whose message names the argument
    — no raw numpy/Python error, no numpy warning (a silent overflow)."""
    import warnings

    f, kw = _render_calls()[name]
    a, k = _split(f, kw)
    f(*a, **k)
    problems = []
    for p in kw:
        for bad in RENDER_BAD:
            trial = dict(kw)
            trial[p] = bad
            a, k = _split(f, trial)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    f(*a, **k)
            except (CsgnbError, TypeError) as exc:
                if not any(n in str(exc) for n in [p, p.replace("_", " "), *ALIASES.get(p, [])]):
                    problems.append(f"{p}={bad!r:.30}: {type(exc).__name__} not naming it: {str(exc)[:100]}")
            except Exception as exc:  # noqa: BLE001 - the point of the test
                problems.append(f"{p}={bad!r:.30}: raw {type(exc).__name__}: {str(exc)[:100]}")
    assert not problems, f"{name}:\n" + "\n".join(problems)


@pytest.mark.parametrize("radius", [1e-200, 1e200, 1e-76, 1e76])
@pytest.mark.parametrize("make", ["quadric.sphere", "csg.sphere", "csg.cylinder", "csg.ellipsoid", "csg.capsule"])
def test_radii_beyond_the_double_range_are_refused_with_the_bound(make, radius):
    """Item 4: r² underflowed (a sphere of radius 1e-200 became a point; an ellipsoid with a 1e200 axis a
    cylinder — both without error) or overflowed ("c must be finite, got -inf"). Now the bound and why."""
    from csgnb.errors import GeometryError

    makers = {"quadric.sphere": lambda r: cq.sphere((0, 0, 0), r), "csg.sphere": lambda r: csg.sphere((0, 0, 0), r),
              "csg.cylinder": lambda r: csg.cylinder((0, 0, 0), (0, 0, 1), r),
              "csg.ellipsoid": lambda r: csg.ellipsoid((r, 1.0, 1.0)),
              "csg.capsule": lambda r: csg.capsule((0, 0, 0), (0, 0, 1), r)}
    with pytest.raises(GeometryError, match=r"must lie in \[1e-75, 1e\+75\].*normal doubles") as info:
        makers[make](radius)
    assert "radius" in str(info.value) or "radii" in str(info.value)
    makers[make](1e-60)  # inside the range: fine
    makers[make](1e60)
