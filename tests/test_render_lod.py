"""Levels of detail (csgnb.render.level_of_detail): per view the coarsest cloud whose splats are about a target size
on screen, and every level drawing the reference picture."""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgnb.csg.gallery import tour_part
from csgnb.errors import CsgnbError, GeometryError
from csgnb.render import Camera, LevelsOfDetail, SplatRenderer, Viewer, compare, footprint_pixels, raytrace
from csgnb.render.level_of_detail import FINER_MAX_SAMPLES, KEPT_LEVELS, LEVEL_STEP, TARGET_FOOTPRINT_PX
from csgnb.sampling import sample_csg

_cache: dict = {}


def tour_cloud():
    if "tour" not in _cache:
        shape = tour_part()
        _cache["tour"] = (shape, sample_csg(shape, 0.02))
    return _cache["tour"]


def test_footprint_in_pixels_follows_depth_and_projection():
    cam = Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0), width=400, height=300, fov=60)
    # radius · height / (2 · depth · tan(fov / 2))
    expected = 0.5 * 300 / (2 * 10 * math.tan(math.radians(30)))
    assert footprint_pixels(cam, 0.5, (0, 0, 0)) == pytest.approx(expected)
    assert footprint_pixels(cam, 0.5, (3, 2, 5)) == pytest.approx(2 * expected)  # half the depth
    assert footprint_pixels(cam, 0.5, (0, 0, 12)) == math.inf  # behind the eye
    ortho = Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0), width=400, height=300, projection="orthographic",
                           ortho_height=6.0)
    assert footprint_pixels(ortho, 0.5, (0, 0, -100)) == pytest.approx(0.5 * 300 / 6.0)


def test_levels_follow_the_zoom_and_stop_at_the_given_cloud():
    _, cloud = tour_cloud()
    cam = Camera.fit(cloud, 320, 240)
    coarser_only = LevelsOfDetail(cloud)  # the default: never finer than the cloud
    assert coarser_only.min_level == 0 and coarser_only.level_for(cam.orbited(zoom=64.0)) == 0
    assert coarser_only.level_for(cam) == LevelsOfDetail(cloud, finer=True).level_for(cam) > 0
    lod = LevelsOfDetail(cloud, finer=True)
    levels = [lod.level_for(cam.orbited(zoom=z)) for z in (0.25, 0.5, 1.0, 2.0, 4.0, 64.0)]
    assert levels == sorted(levels, reverse=True) and levels[0] > levels[2] > 0 and levels[-1] < 0
    for z in (0.5, 1.0, 2.0):
        c = cam.orbited(zoom=z)
        level = lod.level_for(c)
        # the coarsest level at most the target on screen: the next one would be larger
        px = footprint_pixels(c, lod.radius(level), lod.center)
        assert px <= TARGET_FOOTPRINT_PX * (1 + 1e-9)
        assert level == lod.max_level or px * LEVEL_STEP > TARGET_FOOTPRINT_PX
    # close up, finer levels -- as long as their estimated samples stay within the budget
    assert lod.min_level < 0 and len(cloud) * 2.0 ** -lod.min_level <= FINER_MAX_SAMPLES
    assert len(cloud) * 2.0 ** (1 - lod.min_level) > FINER_MAX_SAMPLES
    close = cam.orbited(zoom=32.0)
    assert lod.level_for(close) < 0 and footprint_pixels(close, lod.radius(0), lod.center) > TARGET_FOOTPRINT_PX
    assert lod.level_for(cam.with_size(4000, 3000).orbited(zoom=64.0)) == lod.min_level
    assert lod.cloud_at(0) is cloud
    with pytest.raises(CsgnbError, match="level must be in"):
        lod.cloud_at(lod.max_level + 1)
    with pytest.raises(CsgnbError, match="level must be in"):
        lod.cloud_at(lod.min_level - 1)
    with pytest.raises(GeometryError, match="target_pixels"):
        LevelsOfDetail(cloud, target_pixels=0)


def test_every_level_draws_the_reference_picture():
    """A coarser level changes the time, not the picture: the same colours, visible quadric and term at every
    pixel as the given cloud, and no hole against the ray tracer."""
    shape, cloud = tour_cloud()
    lod = LevelsOfDetail(cloud)
    cam = Camera.fit(cloud, 320, 240, azimuth=-50, elevation=30)
    base = SplatRenderer(cloud).render(cam, fallback="never")
    reference = raytrace(shape, cam)
    chosen = lod.level_for(cam)
    assert chosen >= 2
    for level in sorted({1, chosen // 2, chosen}):
        drawn = lod.cloud_at(level)
        assert len(drawn) < len(cloud) and drawn.radius == pytest.approx(cloud.radius * LEVEL_STEP**level)
        frame = SplatRenderer(drawn).render(cam, fallback="never")
        for field in ("rgb", "quadric", "term"):
            assert np.array_equal(getattr(frame, field), getattr(base, field)), (level, field)
        agreement = compare(frame, reference)
        assert agreement.holes == 0 and agreement.disagree == 0, level
        assert lod.cloud_at(level) is drawn  # sampled once, kept
    others = [k for k in range(1, lod.max_level + 1) if k != chosen][-KEPT_LEVELS:]  # the coarse ones: quick
    assert len(others) == KEPT_LEVELS
    for level in others:  # the least recently used levels are dropped, never the cloud itself
        lod.cloud_at(level)
    assert len(lod.levels) == 1 + KEPT_LEVELS and lod.levels[0] is cloud and chosen not in lod.levels


def test_a_bounded_cloud_keeps_its_bounds_at_every_level():
    """An unbounded surface (an infinite cylinder) sampled inside a bounding sphere is resampled inside the same
    sphere's box: a level draws the same piece of it, not a larger one (resampling in the box of the cloud's
    normalised frame instead reached z = ±2.12)."""
    from csgnb.csg import leaf
    from csgnb.quadric import elliptic_cylinder

    bounds = ((0.0, 0.0, 0.0), 2.0)
    cloud = sample_csg(leaf(elliptic_cylinder((0.5, 0.5))), 0.02, bounds=bounds)
    assert cloud.bounds is not None and cloud.bounds[1] == 2.0
    lod = LevelsOfDetail(cloud)
    for level in (2, 5):
        coarse = lod.cloud_at(level)
        assert np.array_equal(coarse.bounds[0], cloud.bounds[0]) and coarse.bounds[1] == 2.0
        z = coarse.positions[:, 2]
        assert z.min() >= -2.0 - 1e-9 and z.max() <= 2.0 + 1e-9 and z.max() > 1.9


def test_the_viewer_draws_a_level_of_detail_and_says_so():
    shape, cloud = tour_cloud()
    v = Viewer(cloud, size=(160, 120))
    assert v.drawn is not cloud and len(v.drawn) < len(cloud)
    assert "level of detail" in v.label.value
    far = len(v.drawn)
    v.zoom.value = v.zoom.max  # x8, closer: finer splats
    assert len(v.drawn) > far
    # the picture is the reference's: forced on beside a reference, the difference shows no hole
    checked = Viewer(cloud, shape=shape, size=(160, 120), lod=True)
    assert checked.drawn is not cloud and "holes 0" in checked.label.value
    plain = Viewer(cloud, size=(160, 120), lod=False)
    assert plain.drawn is cloud and plain.levels is None and "the cloud itself" not in plain.label.value
    assert np.array_equal(plain.frame.rgb, Viewer(cloud, size=(160, 120)).frame.rgb)


def test_a_viewer_with_a_reference_checks_the_cloud_itself():
    """Beside a reference the difference is about the cloud given: a thinned cloud's holes must show, not a
    resampled level's flawless picture (the default lod is off there)."""
    import dataclasses

    shape, cloud = tour_cloud()
    keep = np.arange(0, len(cloud), 8)
    thin = dataclasses.replace(cloud, positions=cloud.positions[keep], normals=cloud.normals[keep],
                               quadric_ids=cloud.quadric_ids[keep], radii=cloud.radii[keep],
                               clip_start=cloud.clip_start[keep], clip_count=cloud.clip_count[keep])
    v = Viewer(thin, shape=shape, size=(160, 120))
    assert v.levels is None and v.drawn is thin
    assert "holes 0" not in v.label.value  # the thinned cloud's holes are shown
    assert "holes 0" in Viewer(thin, shape=shape, size=(160, 120), lod=True).label.value  # a level would hide them


def test_the_chooser_measures_where_the_size_rule_asks_for_finer_splats():
    """Where the size rule wants a level finer than the cloud, the chooser draws each candidate ``trials`` times
    (the cloud first), then the one with the lower median of its recent frame times; a zoom that changes the
    candidates starts the measurement afresh. Times are booked by hand here, so the test is deterministic."""
    from csgnb.render import LevelChooser

    _, cloud = tour_cloud()
    cam = Camera.fit(cloud, 320, 240)
    lod = LevelsOfDetail(cloud, finer=True)
    close = cam.orbited(zoom=32.0)
    fine = lod.level_for(close)
    assert fine < 0 and lod.level_for(cam) > 0
    chooser = LevelChooser(lod, trials=2, keep=3)
    drawn = []
    for ms in (10.0, 10.0, 4.0, 4.0):  # two trials each: the cloud, then the finer level
        drawn.append(chooser.choose(close))
        chooser.record(drawn[-1], ms)
    assert drawn == [0, 0, fine, fine] and chooser.candidates == (0, fine)
    assert chooser.choose(close) == fine  # faster
    for _ in range(3):  # it became slower (the view changed): the cloud's older times win
        chooser.record(fine, 30.0)
    assert chooser.choose(close) == 0
    chooser.record(7, 1.0)  # not a candidate: ignored
    assert chooser.choose(cam) == lod.level_for(cam) and chooser.times == {lod.level_for(cam): []}
    assert chooser.choose(close) == 0 and chooser.times == {0: [], fine: []}  # measured afresh
    with pytest.raises(GeometryError, match="ms"):
        chooser.record(0, -1.0)
    with pytest.raises(TypeError, match="level"):
        chooser.record(0.5, 1.0)
    with pytest.raises(TypeError, match="levels"):
        LevelChooser(cloud)


def test_the_viewer_draws_the_faster_candidate_and_the_same_picture():
    """Zoomed in on the tour part, the viewer's chooser tries the cloud and the finer level and keeps drawing one of
    them; both draw the same picture (colour, visible quadric and term at every pixel: a level is sampled from the
    cloud's normal form afresh, so depths may differ in the last bit)."""
    _, cloud = tour_cloud()
    # splats on every tile (a close-up of this dense cloud is otherwise ray traced whole, whatever the level), the
    # eye outside the part
    v = Viewer(cloud, Camera.fit(cloud, 640, 480, azimuth=-50, elevation=30).orbited(zoom=6.0), size=(640, 480),
               fallback="never")
    frames = {}
    for _ in range(6):
        v.update()
        frames[v.level] = v.frame
    assert set(frames) == set(v.chooser.candidates) and len(frames) == 2
    a, b = frames.values()
    assert a.covered.sum() > 1000 and a.stats.fragments > 0 and b.stats.fragments > 0
    for buffer in ("rgb", "quadric", "term"):
        assert np.array_equal(getattr(a, buffer), getattr(b, buffer)), buffer
    assert "measured" in v.label.value
