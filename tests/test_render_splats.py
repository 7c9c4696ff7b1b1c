"""The splat renderer: pixel-perfect against the reference ray tracer, overdraw reductions that
leave the image unchanged, failure on a thinned cloud, modes, export, viewer, bad input."""

import dataclasses

import numpy as np
import pytest

from csgnb.csg.gallery import all_models, figure2, figure15, tour_part
from csgnb.errors import GeometryError
from csgnb.render import Camera, SplatRenderer, Viewer, compare, raytrace, render, verify
from csgnb.render.viewer import WHEEL_STEPS, ZOOM_STEPS
from csgnb.sampling import sample_csg

MODELS = all_models()
#: (azimuth, elevation, projection) of the views every model is checked from
VIEWS = [(-60, 30, "perspective"), (30, 60, "orthographic"), (150, -20, "perspective")]
SIZE = (120, 90)

_clouds: dict = {}


def cloud_of(name, rel):
    """Sample model ``name`` with splat radius ``rel`` × its extent (cached per session)."""
    key = (name, rel)
    if key not in _clouds:
        shape = MODELS[name]()
        ext = np.ptp(sample_csg(shape, 1.0).positions, axis=0).max()
        _clouds[key] = (shape, sample_csg(shape, rel * ext))
    return _clouds[key]


def assert_pixel_perfect(agreement):
    assert agreement.covered > 500
    assert agreement.holes == 0, f"{agreement.holes} holes"
    assert agreement.fraction >= 0.999, agreement
    assert agreement.off_edge == 0, agreement


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("rel", [0.02, 0.06])
def test_splats_are_pixel_perfect(name, rel):
    shape, cloud = cloud_of(name, rel)
    for az, el, proj in VIEWS:
        cam = Camera.fit(cloud, *SIZE, azimuth=az, elevation=el, projection=proj)
        a, splats, ref = verify(cloud, cam, shape)
        assert_pixel_perfect(a)
        # agreeing pixels have bit-identical depths: both renderers solve the same equation
        same = (splats.quadric == ref.quadric) & ref.covered
        assert np.array_equal(splats.depth[same], ref.depth[same])


@pytest.mark.slow
@pytest.mark.parametrize("name", list(MODELS))
def test_splats_are_pixel_perfect_at_640x480(name):
    shape, cloud = cloud_of(name, 0.03)
    for az, el, proj in VIEWS:
        a, _, _ = verify(cloud, Camera.fit(cloud, 640, 480, azimuth=az, elevation=el, projection=proj), shape)
        assert_pixel_perfect(a)


def test_a_thinned_cloud_fails_the_check():
    shape, cloud = cloud_of("tour", 0.02)
    keep = np.arange(len(cloud)) % 8 == 0
    thin = dataclasses.replace(
        cloud, positions=cloud.positions[keep], normals=cloud.normals[keep], quadric_ids=cloud.quadric_ids[keep],
        radii=cloud.radii[keep], clip_start=cloud.clip_start[keep], clip_count=cloud.clip_count[keep])
    cam = Camera.fit(cloud, *SIZE)
    a, _, _ = verify(thin, cam, shape)
    assert a.holes > 50 and a.off_edge > 50 and not a.ok
    assert verify(cloud, cam, shape)[0].ok


def _identical(a, b):
    return np.array_equal(a.quadric, b.quadric) and np.array_equal(a.depth, b.depth)


@pytest.mark.parametrize("name", ["figure 2", "tour", "block", "figure 15"])
def test_each_overdraw_reduction_keeps_the_image_and_lowers_overdraw(name):
    shape = MODELS[name]()
    ext = np.ptp(sample_csg(shape, 1.0).positions, axis=0).max()
    r = 0.04 * ext
    worst = sample_csg(shape, r, distortion="sqrt3", refine=False, reduce_radius=False)  # Figure 13 (a)-(c)
    bounds = sample_csg(shape, r, reduce_radius=False)                 # (d)
    reduced = sample_csg(shape, r)                                     # (e): the default
    # the reduced radii may refine where the bound was loose, so the clouds need not share positions
    assert reduced.radii.max() <= bounds.radii.max() and np.mean(reduced.radii) <= np.mean(bounds.radii)
    cam = Camera.fit(bounds, *SIZE, azimuth=-50, elevation=35)
    paper = {"fallback": "never", "occlusion_culling": False}  # splats on every tile, every fragment counted
    steps = [
        render(worst, cam, footprint="sphere", backface_culling=False, **paper),
        render(worst, cam, footprint="box", backface_culling=False, **paper),
        render(worst, cam, footprint="box", backface_culling=True, **paper),
        render(bounds, cam, **paper),
        render(reduced, cam, **paper),
        render(reduced, cam, fallback="never"),  # + occlusion culling: the default
    ]
    ref = raytrace(shape, cam)
    for k, frame in enumerate(steps):
        assert_pixel_perfect(compare(frame, ref))
        if k:
            assert _identical(frame, steps[k - 1]), f"step {k} changed the image"
    fragments = [f.stats.fragments for f in steps]
    assert all(b < a for a, b in zip(fragments[:3], fragments[1:3], strict=False)), fragments
    assert fragments[3] < fragments[2] or len(bounds) >= len(worst), fragments
    assert fragments[4] < fragments[3] or np.all(reduced.radii == bounds.radii), fragments
    assert fragments[5] <= fragments[4], fragments
    assert fragments[5] < fragments[4] or name == "figure 15", fragments  # its views show no hidden layer
    assert steps[2].stats.splats_culled > 0.2 * len(worst)


def test_clipping_and_local_ray_tracing_are_what_make_it_exact():
    shape, cloud = cloud_of("figure 15", 0.04)
    cam = Camera.fit(cloud, *SIZE, azimuth=-60, elevation=30)
    ref = raytrace(shape, cam)
    unclipped = compare(render(cloud, cam, clip=False), ref)
    discs = compare(render(cloud, cam, local="disc", clip=False), ref)
    assert unclipped.off_edge > 0 and unclipped.extra > 0  # splats stick out over the features
    assert discs.fraction < 0.5  # flat splats have the wrong depth almost everywhere
    full = render(cloud, cam, color_by="clip_count")
    counts = full.clip_count[full.covered]
    assert counts.min() == 0 and counts.max() >= 2  # Figure 11d: 0, 1 and 2 clip quadrics occur


@pytest.mark.parametrize("color_by", ["quadric", "quadric_id", "term", "clip_count", "overdraw", "normal", "white"])
def test_color_modes_shade_covered_pixels_only(color_by):
    _, cloud = cloud_of("figure 2", 0.06)
    f = render(cloud, Camera.fit(cloud, 48, 36), color_by=color_by)
    assert f.rgb.shape == (36, 48, 3) and f.rgb.dtype == np.uint8
    shown = f.overdraw > 0 if color_by == "overdraw" else f.covered  # overdraw colours every fragment
    bg = f.rgb[~shown]
    assert np.all(bg == bg[0])
    assert len(np.unique(f.rgb[shown].reshape(-1, 3), axis=0)) > 3 or color_by == "white"
    assert np.array_equal(f.shaded(color_by), f.rgb)


def test_png_and_pyvista_export(tmp_path):
    from PIL import Image

    shape, cloud = cloud_of("tour", 0.06)
    f = render(cloud, Camera.fit(cloud, 64, 48))
    f.save_png(tmp_path / "f.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "f.png").convert("RGB")), f.rgb)
    pts = f.to_pyvista()
    assert pts.n_points == int(f.covered.sum())
    assert np.array_equal(pts.point_data["rgb"], f.rgb[f.covered])
    # the points sit on their quadrics, where the surface is in the world
    Q = np.array([cloud.normal_form.quadrics[k].matrix for k in pts.point_data["quadric"]])
    h = np.column_stack([pts.points, np.ones(pts.n_points)])
    assert np.max(np.abs(np.einsum("ni,nij,nj->n", h, Q, h))) < 1e-5  # pyvista stores float32 points
    img = f.to_pyvista("image")
    assert img.dimensions == (64, 48, 1) and img.n_points == 64 * 48
    with pytest.raises(ValueError, match="kind"):
        f.to_pyvista("mesh")


def test_viewer_renders_on_drag_and_checks_its_shape():
    shape, cloud = cloud_of("figure 2", 0.06)
    v = Viewer(cloud, shape=shape, size=(64, 48))
    first = v.camera
    frame = v.drag(40, -10)
    assert frame.shape == (48, 64) and not np.allclose(v.camera.eye, first.eye)
    assert "ms per frame" in v.label.value and "holes 0" in v.label.value
    assert v.reference_image.value and v.difference_image.value
    # The sliders show the dragged angles in whole degrees: a value the browser's slider keeps as it is
    # (test_notebooks_in_browser.py checks that it sends none back).
    azimuth, elevation = v._angles()
    assert (v.azimuth.value, v.elevation.value) == (round(azimuth), round(elevation)) != (-60, 30)
    assert all(type(s.value) is int for s in (v.azimuth, v.elevation, v.zoom))
    steep = Viewer(cloud, size=(32, 24))
    steep.drag(0, 400)  # 160 degrees up: the camera stops short of the pole, the slider at its end
    assert steep.elevation.value == steep.elevation.max == 89 and type(steep.elevation.value) is int
    v.zoom.value = ZOOM_STEPS
    assert v.zoom_factor == 2.0 and v.zoom_readout.value == "x2.00"
    assert v.frame.stats.covered > frame.stats.covered
    # The wheel zooms through the slider: the slider shows what the wheel did, and the picture follows it.
    covered, distance = v.frame.stats.covered, np.linalg.norm(v.camera.eye - v.camera.target)
    for _ in range(3):
        v._on_event({"type": "wheel", "deltaY": -100})
    assert v.zoom.value == ZOOM_STEPS + 3 * WHEEL_STEPS and v.zoom_factor > 2.0 * 1.2
    assert np.linalg.norm(v.camera.eye - v.camera.target) < distance and v.frame.stats.covered > covered
    for _ in range(200):  # out as far as the slider goes, and no further
        v._on_event({"type": "wheel", "deltaY": 100})
    assert v.zoom.value == v.zoom.min and v.zoom_factor == 0.25 and v.zoom_readout.value == "x0.25"
    with pytest.raises(GeometryError, match="another shape"):
        Viewer(cloud, shape=tour_part(), size=(32, 24))


def test_bad_input_is_a_clear_error():
    shape, cloud = cloud_of("figure 2", 0.06)
    cam = Camera.fit(cloud, 32, 24)
    _, other = cloud_of("tour", 0.06)
    with pytest.raises(GeometryError, match="another shape"):
        verify(cloud, cam, tour_part())
    # a cloud whose normal form is another shape's: its samples are not on those quadrics
    foreign = dataclasses.replace(cloud, normal_form=figure15().normal_form())
    with pytest.raises(GeometryError, match="not on their quadric"):
        render(foreign, cam)
    mixed = dataclasses.replace(other, normal_form=cloud.normal_form)
    with pytest.raises(GeometryError, match="do not belong together|not on their quadric"):
        render(mixed, cam)
    empty = dataclasses.replace(cloud, positions=np.empty((0, 3)), normals=np.empty((0, 3)),
                                quadric_ids=np.empty(0, np.int32), radii=np.empty(0),
                                clip_start=np.empty(0, np.int32), clip_count=np.empty(0, np.int32))
    with pytest.raises(GeometryError, match="empty"):
        render(empty, cam)
    with pytest.raises(TypeError, match="SampleCloud"):
        render(figure2(), cam)
    with pytest.raises(TypeError, match="Camera"):
        render(cloud, (0, 0, 5))
    for bad in ({"footprint": "quad"}, {"local": "mesh"}, {"color_by": "rainbow"}, {"tile": 0}):
        with pytest.raises(ValueError):
            render(cloud, cam, **bad)
    with pytest.raises(ValueError, match="size"):
        compare(render(cloud, cam), raytrace(shape, cam.with_size(16, 12)))
    assert isinstance(SplatRenderer(cloud).render(cam).stats.ms, float)


def test_reduced_radii_leave_no_hole_on_the_80_quadric_plate_at_1080p():
    """The camera where reduced radii left a one-pixel hole (the sampler's unresolved feature tips)."""
    from csgnb.csg.gallery import TABLE2

    build, radii = TABLE2["perforated plate"]
    shape = build()
    cloud = sample_csg(shape, radii["large"], reduce_radius=True)
    cam = Camera.fit(cloud, 1920, 1080, azimuth=-60, elevation=35)
    agreement = compare(render(cloud, cam), raytrace(shape, cam))
    assert agreement.holes == 0
    assert_pixel_perfect(agreement)


OCCLUSION_VIEWS = [  # (model, relative radius, azimuth, elevation, projection, zoom): outside views, close-ups
    ("block", 0.06, -60, 35, "perspective", 1.0), ("block", 0.02, 120, -30, "orthographic", 1.0),
    ("tour", 0.04, -40, 30, "perspective", 4.0), ("figure 15", 0.03, 30, 60, "perspective", 1.0),
    ("figure 2", 0.06, 200, 10, "perspective", 2.5),
]


@pytest.mark.parametrize(("name", "rel", "az", "el", "proj", "zoom"), OCCLUSION_VIEWS)
@pytest.mark.parametrize("local", ["quadric", "disc"])
@pytest.mark.parametrize("tile", [64, 12])
def test_occlusion_culling_changes_the_fragment_count_not_the_picture(name, rel, az, el, proj, zoom, local, tile):
    """A splat behind every drawn pixel of the 8x8 blocks under its footprint is skipped whole: every buffer but the
    overdraw count is bit for bit the one drawn with every fragment tested (a culled splat that could have won a pixel
    would show here), and the fragments only drop."""
    _, cloud = cloud_of(name, rel)
    cam = Camera.fit(cloud, 200, 150, azimuth=az, elevation=el, projection=proj).orbited(zoom=zoom)
    options = {"fallback": "never", "local": local, "tile": tile}  # 12: blocks cut by the tile's edge
    culled, every = (render(cloud, cam, occlusion_culling=flag, **options) for flag in (True, False))
    assert culled.stats.covered > 2000
    for buffer in ("depth", "quadric", "sample", "clip_count", "normal", "rgb"):
        assert np.array_equal(getattr(culled, buffer), getattr(every, buffer)), buffer
    assert np.all(culled.overdraw <= every.overdraw)
    assert culled.stats.fragments < every.stats.fragments


def test_frames_are_bit_identical_on_one_and_two_threads():
    """The raster runs over screen tiles on all cores: each tile is one thread's, so the image must not depend on
    how many there are (depth, quadric, overdraw and colour buffers compared bit for bit)."""
    import numba

    shape = tour_part()
    cloud = sample_csg(shape, 0.05)
    cam = Camera.fit(cloud, 320, 240, azimuth=-40, elevation=30)
    before = numba.get_num_threads()
    frames = []
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            frames.append(render(cloud, cam))
    finally:
        numba.set_num_threads(before)
    a, b = frames
    for name in ("depth", "quadric", "overdraw", "rgb", "clip_count"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.stats.fragments == b.stats.fragments


def test_close_ups_cull_splats_beside_the_camera():
    """Zoomed far in, splats straddling the eye's plane beside the camera each took the whole screen: thousands of
    fragments per pixel and frames 30x slower than ray tracing (the 80-quadric plate at zoom 20: overdraw 2,928 at
    1920x1080). Balls outside a side plane of the view frustum are now off screen; the image is unchanged."""
    from csgnb.csg.gallery import TABLE2

    build, radii = TABLE2["perforated plate"]
    shape = build()
    cloud = sample_csg(shape, radii["medium"])
    cam = Camera.fit(cloud, 480, 270, azimuth=-60, elevation=35).orbited(zoom=20)
    frame = render(cloud, cam)
    assert frame.stats.overdraw < 150, frame.stats.overdraw
    assert_pixel_perfect(compare(frame, raytrace(shape, cam)))


def _bins_reference(bbox, flag, zmin, tile, ntx, nty):
    """The binning in plain Python: drawn splats by depth bucket (4096 between the nearest and farthest), then
    index; each tile lists the splats whose rectangle meets it, in that order."""
    drawn = [k for k in range(len(flag)) if flag[k] == 0]
    if not drawn:
        return np.zeros(ntx * nty + 1, dtype=np.int64), np.zeros(0, dtype=np.int32)
    lo, hi = min(zmin[k] for k in drawn), max(zmin[k] for k in drawn)
    scale = 4095 / (hi - lo) if hi > lo else 0.0
    order = sorted(drawn, key=lambda k: (int((zmin[k] - lo) * scale), k))
    tiles = [[] for _ in range(ntx * nty)]
    for k in order:
        for ty in range(bbox[k, 1] // tile, bbox[k, 3] // tile + 1):
            for tx in range(bbox[k, 0] // tile, bbox[k, 2] // tile + 1):
                tiles[ty * ntx + tx].append(k)
    start = np.cumsum([0] + [len(t) for t in tiles]).astype(np.int64)
    return start, np.array([k for t in tiles for k in t], dtype=np.int32)


def test_binning_matches_the_serial_definition_on_random_footprints():
    """The binning runs in parallel chunks; its tiles must list the same splats in the same order as the serial
    definition (depth bucket, then splat index), ties and empty frames included."""
    from csgnb.render.splats import _bin_splats

    rng = np.random.default_rng(4)
    for trial in range(25):
        n = int(rng.integers(0, 3000))
        W, H, tile = int(rng.integers(16, 300)), int(rng.integers(16, 200)), int(rng.choice([8, 16, 32]))
        ntx, nty = (W + tile - 1) // tile, (H + tile - 1) // tile
        j0, i0 = rng.integers(0, W, n), rng.integers(0, H, n)
        bbox = np.stack([j0, i0, np.minimum(W - 1, j0 + rng.integers(0, 50, n)),
                         np.minimum(H - 1, i0 + rng.integers(0, 50, n))], axis=1).astype(np.int64)
        flag = rng.choice(np.array([0, 0, 0, 1, 2], dtype=np.int8), n)
        zmin = rng.normal(size=n)
        if trial % 4 == 0:
            zmin = np.round(zmin, 1)  # many ties within a bucket
        start, items = np.empty(ntx * nty + 1, dtype=np.int64), np.empty(400_000, dtype=np.int32)
        total = _bin_splats(bbox, flag, zmin, tile, ntx, nty, start, items)
        ref_start, ref_items = _bins_reference(bbox, flag, zmin, tile, ntx, nty)
        assert total == len(ref_items)
        assert np.array_equal(start, ref_start) and np.array_equal(items[:total], ref_items), trial


def test_fallback_tiles_show_the_ray_tracer_and_the_rest_the_splats():
    """Where splats cost more than ray tracing (large, overlapping splats), the cost model ray traces the tile:
    those tiles are the reference ray tracer's pixels bit for bit, the others the splats' own, and the frame stays
    pixel-perfect."""
    from csgnb.csg.gallery import TABLE2

    build, radii = TABLE2["perforated plate"]
    shape = build()
    cloud = sample_csg(shape, radii["large"])
    cam = Camera.fit(cloud, 480, 270, azimuth=-60, elevation=35)
    renderer = SplatRenderer(cloud)
    auto = renderer.render(cam)
    plan = renderer.last_plan
    splats = renderer.render(cam, fallback="never")
    everywhere = renderer.render(cam, fallback="always")
    ref = raytrace(cloud, cam)  # the cloud's own normal form: the same quadric rows, so bit-identical depths
    assert 0 < auto.stats.raytraced_tiles < auto.stats.tiles == len(plan.splat_ns)
    assert np.array_equal(everywhere.quadric, ref.quadric) and np.array_equal(everywhere.depth, ref.depth)
    assert everywhere.stats.fragments == 0 and everywhere.stats.raytraced_tiles == everywhere.stats.tiles
    ntx = -(-480 // 64)
    traced = np.zeros(auto.quadric.shape, dtype=bool)
    for t in plan.raytraced:
        traced[(t // ntx) * 64 : (t // ntx) * 64 + 64, (t % ntx) * 64 : (t % ntx) * 64 + 64] = True
    for name in ("quadric", "depth", "term"):
        a, s, r = getattr(auto, name), getattr(splats, name), getattr(ref, name)
        assert np.array_equal(a[traced], r[traced]), name
        assert np.array_equal(a[~traced], s[~traced]), name
    assert np.all(auto.sample[traced] == -1) and np.all(auto.overdraw[traced] == 0)
    assert auto.stats.fragments < splats.stats.fragments
    # the frame's statistics (counted in one compiled pass) against their definitions
    covered = auto.quadric >= 0
    assert auto.stats.covered == int(covered.sum()) and auto.stats.fragments == int(auto.overdraw.sum())
    assert auto.stats.overdraw == auto.stats.fragments / int((covered & ~traced).sum())
    # the choice: probed tiles whose estimated ray tracing is cheaper, and only those
    probed = ~np.isnan(plan.raytrace_ns)
    cheaper = np.flatnonzero(probed & (plan.raytrace_ns < plan.splat_ns))
    assert np.array_equal(np.sort(plan.raytraced), cheaper)
    assert_pixel_perfect(compare(auto, raytrace(shape, cam)))


def test_a_small_view_of_a_dense_cloud_is_ray_traced_whole():
    """236,000 splats seen at 160x120: their footprint and binning passes alone cost more than ray tracing the frame
    (the probe says so), so the frame is ray traced, the reference's pixels bit for bit; at 1920x1080 it is not."""
    from csgnb.csg.gallery import TABLE2
    from csgnb.render.tile_costs import raytrace_is_cheaper

    build, radii = TABLE2["spheres"]
    cloud = sample_csg(build(), radii["small"])
    cam = Camera.fit(cloud, 160, 120, azimuth=-60, elevation=35)
    frame = render(cloud, cam)
    ref = raytrace(cloud, cam)
    assert frame.stats.raytraced_tiles == frame.stats.tiles and frame.stats.splats_drawn == 0
    assert np.array_equal(frame.quadric, ref.quadric) and np.array_equal(frame.depth, ref.depth)
    assert np.array_equal(frame.rgb, ref.rgb)
    big = render(cloud, cam.with_size(1920, 1080))
    assert big.stats.raytraced_tiles < big.stats.tiles and big.stats.splats_drawn > 0
    few = SplatRenderer(cloud)
    args = (cam.params(), *cam.screen_axes(), None, few.term_start, few.max_term)
    assert not raytrace_is_cheaper(args, (120, 160), 64, 10, 1)  # 10 splats: no probe, splats win


def test_verification_splats_every_tile():
    """verify() and a viewer with a reference check the splats: a ray-traced tile would compare the reference with
    itself and hide a hole (the thinned cloud of test_a_thinned_cloud_fails_the_check is caught either way)."""
    from csgnb.csg.gallery import TABLE2

    build, radii = TABLE2["perforated plate"]
    shape = build()
    cloud = sample_csg(shape, radii["large"])
    cam = Camera.fit(cloud, 480, 270, azimuth=-60, elevation=35)
    assert render(cloud, cam).stats.raytraced_tiles > 0
    _, splats, _ = verify(cloud, cam, shape)
    assert splats.stats.raytraced_tiles == 0
    assert verify(cloud, cam, shape, fallback="auto")[1].stats.raytraced_tiles > 0
    v = Viewer(cloud, cam, shape=shape, size=(480, 270))
    v.update(reference=True)
    assert v.frame.stats.raytraced_tiles == 0
    plain = Viewer(cloud, cam, size=(480, 270))
    plain.update()
    assert plain.frame.stats.raytraced_tiles > 0 and "ray traced" in plain.label.value


def test_fallback_is_off_where_the_picture_is_about_the_splats():
    shape, cloud = cloud_of("figure 15", 0.06)
    cam = Camera.fit(cloud, *SIZE)
    renderer = SplatRenderer(cloud)
    for options in ({"color_by": "overdraw"}, {"color_by": "clip_count"}, {"local": "disc"}, {"clip": False}):
        frame = renderer.render(cam, fallback="always", **options)
        assert frame.stats.raytraced_tiles == 0, options
    with pytest.raises(ValueError, match="fallback"):
        renderer.render(cam, fallback="sometimes")


def test_the_probe_counts_the_ray_tracers_work():
    """The cost model's probe counts the roots the ray tracer computes: at step 1 over every tile it is the
    whole frame's work, and a probe at step 8 extrapolates it within a factor 2 on a real model."""
    from csgnb.render.rays import quadric_rows, ray_polynomials
    from csgnb.render.raytracer import raytrace_tiles, tile_count

    shape, cloud = cloud_of("block", 0.06)
    nf = cloud.normal_form
    cam = Camera.fit(cloud, 256, 192, azimuth=-60, elevation=35)
    X, Y = cam.screen_axes()
    P = ray_polynomials(cam.params(), quadric_rows(nf.quadrics))
    ts = np.asarray(nf.term_start, dtype=np.int64)
    ntx, nty = tile_count((192, 256), 64)
    tiles = np.arange(ntx * nty, dtype=np.int64)
    out = (np.full((192, 256), np.inf), np.full((192, 256), -7, dtype=np.int32), np.full((192, 256), -7, np.int32))
    full = np.empty(len(tiles), dtype=np.int64)
    probe = np.empty(len(tiles), dtype=np.int64)
    max_term = int(np.max(np.diff(ts)))
    raytrace_tiles(cam.params(), X, Y, P, ts, max_term, np.array([64, 8, 0]), tiles, *out, probe)
    assert np.all(out[1] == -7)  # a probe writes nothing
    raytrace_tiles(cam.params(), X, Y, P, ts, max_term, np.array([64, 1, 1]), tiles, *out, full)
    ref = raytrace(cloud, cam)
    assert np.array_equal(out[1], ref.quadric) and np.array_equal(out[0], ref.depth)
    assert full.sum() >= 192 * 256 * nf.n_terms  # at least one root per term and pixel
    assert 0.5 < probe.sum() * 64 / full.sum() < 2.0


def test_box_footprints_stay_inside_the_balls_rectangle():
    """A fragment must lie within r of its sample, so the ball's screen rectangle bounds every footprint: the box's
    corners reach beyond the ball and used to widen it (more fragments, same image)."""
    from csgnb.render.splats import _footprint_kernel

    _, cloud = cloud_of("block", 0.06)
    renderer = SplatRenderer(cloud)
    cam = Camera.fit(cloud, 320, 240, azimuth=-60, elevation=35)
    n = len(cloud)
    out = {}
    for mode in (0, 1):
        bufs = (np.empty((n, 4), np.int32), np.empty((n, 12)), np.empty(n, np.int32), np.empty(n, np.int8), np.empty(n))
        _footprint_kernel(cam.params(), renderer.SD, mode, True, *bufs, 0, 1)
        out[mode] = bufs
    sphere, box = out[0][0], out[1][0]
    drawn = out[1][3] == 0
    assert drawn.sum() > 1000 and np.all(out[0][3][drawn] == 0)  # a drawn box is a drawn ball
    assert np.all(box[drawn, :2] >= sphere[drawn, :2]) and np.all(box[drawn, 2:] <= sphere[drawn, 2:])
    assert np.mean(np.prod(box[drawn, 2:] - box[drawn, :2] + 1, axis=1)) < np.mean(
        np.prod(sphere[drawn, 2:] - sphere[drawn, :2] + 1, axis=1))
    frames = [render(cloud, cam, footprint=f, fallback="never") for f in ("sphere", "box")]
    assert _identical(*frames) and frames[1].stats.fragments < frames[0].stats.fragments


def test_splat_boxes_hold_the_surface_within_the_radius():
    """Every point of a splat's quadric within r of its sample lies in its surface-aligned box (eq. 23 from the
    quadric's eigenvalues): checked with the other samples of the same quadric, which are points on it."""
    from scipy.spatial import cKDTree

    for name in ("figure 2", "tour", "block"):
        shape, cloud = cloud_of(name, 0.06)
        centres, normals, radii, heights = SplatRenderer(cloud).splat_boxes()
        assert np.allclose(np.linalg.norm(normals, axis=1), 1.0) and np.all(heights[:, 0] <= heights[:, 1])
        tree = cKDTree(centres)
        checked = 0
        for k in range(0, len(centres), 7):
            for j in tree.query_ball_point(centres[k], radii[k]):
                if cloud.quadric_ids[j] != cloud.quadric_ids[k]:
                    continue
                d = centres[j] - centres[k]
                h = d @ normals[k]
                tol = 1e-9 * (1.0 + np.abs(centres[k]).max())
                assert heights[k, 0] - tol <= h <= heights[k, 1] + tol, (name, k, j, h, heights[k])
                checked += 1
        assert checked > 1000, (name, checked)


def test_hidden_splats_are_behind_every_pixel_of_their_rectangle():
    """The raster's occlusion test against its definition on random tiles (partial ones at the image's edge
    included): after random depth writes (each only nearer, ties too), a rectangle is reported hidden exactly when
    every pixel of the 8x8 blocks it touches is drawn and lies nearer than the splat's nearest depth -- so no pixel
    of the rectangle could pass the early depth test."""
    from csgnb.render.splats import _BLOCK, _hidden, _open_blocks, _written

    rng = np.random.default_rng(7)
    hidden = 0
    for case in range(60):
        H, W, tile = int(rng.integers(20, 90)), int(rng.integers(20, 90)), int(rng.choice([16, 24, 32, 64]))
        ti0, tj0 = (int(rng.integers(0, (H - 1) // tile + 1)) * tile, int(rng.integers(0, (W - 1) // tile + 1)) * tile)
        rows, cols = min(tile, H - ti0), min(tile, W - tj0)
        nb = (tile + _BLOCK - 1) // _BLOCK
        bopen, bmax, bdirty = np.empty(nb * nb, np.int64), np.empty(nb * nb), np.empty(nb * nb, np.bool_)
        blocks = (bopen, bmax, bdirty)
        _open_blocks(rows, cols, nb, blocks)
        depth = np.full((H, W), np.inf)
        for step in range(300):
            if rng.random() < 0.6:  # a splat's writes: pixels of a small rectangle, each nearer or equal
                i0, j0 = int(rng.integers(0, rows)), int(rng.integers(0, cols))
                for i in range(ti0 + i0, ti0 + min(rows, i0 + int(rng.integers(1, 12)))):
                    for j in range(tj0 + j0, tj0 + min(cols, j0 + int(rng.integers(1, 12)))):
                        old = depth[i, j]
                        tie = np.isfinite(old) and rng.random() < 0.2
                        _written(i - ti0, j - tj0, nb, old, blocks)
                        depth[i, j] = old if tie else min(old, float(rng.uniform(1.0, 10.0)))
                continue
            r0, c0 = int(rng.integers(0, rows)), int(rng.integers(0, cols))
            r1, c1 = int(rng.integers(r0, rows)), int(rng.integers(c0, cols))
            zk = float(rng.choice([rng.uniform(0.5, 11.0), np.nan, np.inf]))
            got = _hidden(zk, (r0, r1, c0, c1), (ti0, tj0), nb, blocks, depth)
            under = depth[ti0 + (r0 // _BLOCK) * _BLOCK: ti0 + (r1 // _BLOCK + 1) * _BLOCK,
                          tj0 + (c0 // _BLOCK) * _BLOCK: tj0 + (c1 // _BLOCK + 1) * _BLOCK]
            expected = bool(np.isfinite(zk) and np.all(zk > under))
            assert got == expected, (case, step, zk, r0, r1, c0, c1)
            if got:
                assert np.all(zk > depth[ti0 + r0: ti0 + r1 + 1, tj0 + c0: tj0 + c1 + 1])
            hidden += got
    assert hidden > 200, hidden  # the test saw both answers


def test_the_planner_costs_only_the_fragments_occlusion_culling_leaves():
    """The cost model's fragment estimate of a probed tile: every rectangle pixel where the probe saw nothing, fewer
    where it saw the front layer (the hidden layers of the block model), never more than the rectangles."""
    from csgnb.render.splats import _tile_fragments, _visible_fragments
    from csgnb.render.tile_costs import PROBE_STEP

    shape, cloud = cloud_of("block", 0.04)
    renderer = SplatRenderer(cloud)
    cam = Camera.fit(cloud, 320, 240, azimuth=-60, elevation=35)
    frame = renderer.render(cam, fallback="never")
    start, tile, ntx = renderer.last_bins
    tiles = np.arange(len(start) - 1, dtype=np.int64)
    rect = np.empty(len(tiles), np.int64)
    _tile_fragments(renderer._bbox, start, renderer._items, tile, ntx, 240, 320, rect, 0, 1)
    est = {}
    for name, probe in (("nothing", np.full((240, 320), np.inf)), ("front", frame.depth)):
        est[name] = np.empty(len(tiles), np.int64)
        _visible_fragments(renderer._bbox, renderer._zmin, start, renderer._items, tiles, probe, tile, ntx,
                           PROBE_STEP, est[name], 0, 1)
    assert np.array_equal(est["nothing"], rect)
    assert np.all(est["front"] <= rect) and est["front"].sum() < 0.8 * rect.sum(), (est["front"].sum(), rect.sum())
    assert est["front"].sum() >= 0.5 * frame.stats.fragments  # about what the raster drew


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_a_camera_inside_the_solid_is_ray_traced_or_refused(projection):
    """Zoomed until the rays start inside the tour part, every-tile splats drew a picture with thousands of holes
    against the reference and no error (back-face culling drops the walls seen from inside). Now the default
    ray traces such a view (the reference's picture) and splats on every tile refuse it with the reason; the viewer
    says so instead of drawing."""
    from csgnb.render.scene import eye_inside

    shape, cloud = cloud_of("tour", 0.02)
    cam = Camera.fit(cloud, 320, 240, azimuth=-50, elevation=30, projection=projection)
    outside = cam.orbited(zoom=2.0)
    inside = cam.orbited(zoom=24.0)
    assert not eye_inside(cloud.normal_form, outside) and eye_inside(cloud.normal_form, inside)
    frame = render(cloud, inside)
    assert frame.stats.raytraced_tiles == frame.stats.tiles and frame.stats.fragments == 0
    agreement = compare(frame, raytrace(shape, inside))
    assert agreement.covered > 1000 and agreement.holes == 0 and agreement.disagree == 0
    for options in ({"fallback": "never"}, {"color_by": "overdraw"}, {"local": "disc"}):
        with pytest.raises(GeometryError, match="inside the solid"):
            render(cloud, inside, **options)
    with pytest.raises(GeometryError, match="inside the solid"):
        verify(cloud, inside, shape)
    v = Viewer(cloud, outside.with_size(160, 120), shape=shape, size=(160, 120))
    v.camera = inside.with_size(160, 120)
    v.update()
    assert "not drawn" in v.label.value and "inside the solid" in v.label.value
