"""The sampler's guarantee (§4.2), tested against the independent ray-casting reference.

* every sample lies on its quadric (to float precision) and on the CSG surface (the graph's
  first-order distance vanishes there);
* coverage: every surface point found by ray casting the graph with 1D Booleans has a sample on
  a quadric through it within the splat radius — on simple models and on models with features
  thinner or smaller than the radius (Figure 15);
* clip sets hold every quadric of the sample's term that reaches into its splat, and are stored
  once each.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import csgnb.csg as csg
from csgnb.errors import CsgnbError
from csgnb.quadric import (
    elliptic_cone,
    elliptic_cylinder,
    elliptic_paraboloid,
    hyperbolic_paraboloid,
    parallel_planes,
    plane,
    signed_distance,
)
from csgnb.sampling import sample_csg
from tests.raycast_reference import (
    graph_first_order_distance,
    graph_value,
    random_rays,
    ray_surface_points,
    world_leaves,
)


def _spheres():
    A, B, C = csg.sphere((0, 0, 0), 1, "A"), csg.sphere((0.8, 0, 0), 1, "B"), csg.sphere((0.4, 0.9, 0), 0.6, "C")
    return (A & B) | C, ((0.4, 0.3, 0.0), 1.8)


def _capsule():
    return csg.capsule((0, 0, 0), (1.5, 0.5, 0.2), 0.4), ((0.75, 0.25, 0.1), 1.4)


def _plate():
    plate = csg.box((0, 0, 0), (3, 2, 0.5))
    holes = [csg.leaf(elliptic_cylinder((0.3, 0.3)).translated((0.7, 0.7, 0)), "hole"),
             csg.leaf(elliptic_cone((0.4, 0.4)).translated((1.9, 1.1, -0.8)), "countersink"),
             csg.leaf(elliptic_cylinder((0.12, 0.12)).transformed(csg.solids.frame_to_axis((0, 1.3, 0.25), (1, 0, 0))),
                      "cross bore")]
    boss = csg.cylinder((2.4, 0.5, 0.5), (2.4, 0.5, 0.9), 0.3, "boss")
    return csg.difference(plate | boss, *holes), ((1.5, 1.0, 0.4), 2.0)


def _shared():
    """A ∩ (B ∪ C) becomes (A ∩ B) ∪ (A ∩ C): A's surface reaches the normal form twice."""
    A = csg.sphere((0, 0, 0), 1.0, "A")
    B = csg.box((-2, -2, -2), (0.3, 2, 2), "B")
    C = csg.box((-0.2, -2, -2), (2, 0.4, 2), "C")
    touching = csg.box((1.2, -0.5, -0.5), (2.2, 0.5, 0.5), "D") | csg.box((2.2, -0.3, -0.3), (2.8, 0.3, 0.3), "E")
    return (A & (B | C)) | touching, ((0.9, 0.0, 0.0), 2.2)


def _thin():
    """Figure 15's point: features far below the splat radius are found and covered."""
    lens = csg.sphere((0, 0, -0.99), 1.0, "lens lo") & csg.sphere((0, 0, 0.99), 1.0, "lens hi")  # 0.02 thick
    fin = csg.box((1.0, -0.5, -0.3), (2.0, 0.5, -0.285), "fin")  # 0.015 thick
    pin = csg.sphere((0.5, 0.9, 0.3), 0.03, "pin")  # far smaller than the radius
    # a sharp tip: a cone's apex clipped by a sphere
    tip = csg.cone((1.5, 1.0, 0.0), (1.5, 1.0, 0.6), 0.0, 0.25, "tip") & csg.sphere((1.5, 1.0, 0.45), 0.5, "tip ball")
    return csg.union(lens, fin, pin, tip), ((0.9, 0.4, 0.0), 1.6)


def _eight():
    """An intersection of eight quadrics with small corners and slivers (like Figure 15)."""
    rot = csg.rotation_matrix((1, 2, 3), 0.4)
    parts = [csg.sphere((0, 0, 0), 1.0, "ball")]
    for k, r in enumerate((0.82, 0.8, 0.78)):
        axis = np.eye(3)[k]
        parts.append(csg.leaf(elliptic_cylinder((r, r)).transformed(csg.solids.frame_to_axis((0, 0, 0), axis)),
                              f"cyl {k}"))
    for k, n in enumerate(((1, 1, 1), (-1, 1, 1), (1, -1, 1), (1, 1, -1))):
        nn = np.array(n, float) / np.sqrt(3)
        parts.append(csg.leaf(csg.graph.Quadric.from_abc(np.zeros((3, 3)), -0.5 * nn, -0.93), f"cut {k}"))
    return csg.intersection(*parts).transformed(rot), ((0, 0, 0), 1.1)


def _paraboloids():
    """A cup (elliptic paraboloid cut by a plane) with a saddle-shaped lid, and a saddle-topped block."""
    cup = csg.leaf(elliptic_paraboloid((0.6, 0.5)), "cup") & csg.leaf(csg.graph.Quadric.from_abc(
        np.zeros((3, 3)), [0, 0, -0.5], 1.6), "rim")  # z ≤ 0.8
    saddle = csg.leaf(hyperbolic_paraboloid((0.9, 0.9)).translated((0, 0, 0.6)), "saddle")
    lid = (cup & saddle).rotated((1, 0.3, 0), 0.3)
    block = csg.box((1.2, -0.5, -0.3), (2.2, 0.5, 0.6), "block") - csg.leaf(
        hyperbolic_paraboloid((0.5, 0.5)).translated((1.7, 0, 0.3)), "saddle cut")
    return lid | block, ((1.0, 0.0, 0.3), 1.6)


def _sharp_paraboloids():
    """Figure 15 with paraboloids: a lens of two opposed cups with a sharp rim (0.04 thick at most),
    a saddle fin and a pointed spike, all thinner or smaller than the splat radius."""
    up = csg.leaf(elliptic_paraboloid((0.5, 0.5)).translated((0, 0, -0.02)), "lens up")
    down = csg.leaf(elliptic_paraboloid((0.5, 0.5)).transformed(np.diag([1.0, 1.0, -1.0, 1.0])).translated(
        (0, 0, 0.02)), "lens down")
    fin = (csg.leaf(hyperbolic_paraboloid((0.6, 0.6)).translated((1.2, 0, 0)), "fin saddle")
           & csg.leaf(parallel_planes((1.0, 0.0, 0.0), 1.19, 1.21), "fin slab")
           & csg.box((0.7, -0.5, -0.5), (1.7, 0.5, 0.5), "fin box"))
    spike = csg.leaf(elliptic_paraboloid((0.02, 0.02)).translated((0.5, 0.9, 0.0)), "spike") & csg.sphere(
        (0.5, 0.9, 0.2), 0.22, "spike ball")
    return csg.union(up & down, fin, spike), ((0.6, 0.3, 0.0), 1.4)


#: Regions left unresolved by design (see ``csgnb.sampling.kernel``, rule 5): the pointed cone of the
#: "thin" model has its cap plane through its apex; the cap's only surface point is the apex, an
#: isolated point where d_Qab touches 0 (found only to √EPS: d ≈ 6e-8 there), so no rule closes the
#: few regions around it. The apex itself is covered by the cone's samples.
DOCUMENTED_UNRESOLVED = {"thin": 16}

MODELS = {"spheres": _spheres, "capsule": _capsule, "plate": _plate, "shared": _shared, "thin": _thin,
          "eight": _eight, "paraboloids": _paraboloids, "sharp paraboloids": _sharp_paraboloids}


def _check_on_surface(shape, cloud, scale):
    nf = cloud.normal_form
    Q = np.array([q.matrix for q in nf.quadrics])[cloud.quadric_ids]
    h = np.column_stack([cloud.positions, np.ones(len(cloud))])
    val = np.einsum("ni,nij,nj->n", h, Q, h)
    grad = 2.0 * np.einsum("ni,nij->nj", h, Q[:, :, :3])
    gn = np.linalg.norm(grad, axis=1)
    apex = gn <= 1e-8 * np.median(gn)  # a cone's apex: on the quadric, no normal (takes its plane's)
    assert np.all(np.abs(val[apex]) <= 1e-12 * scale**2), "apex samples off their quadric"
    val, grad, gn = val[~apex], grad[~apex], gn[~apex]
    assert np.all(np.abs(val) / gn <= 1e-9 * scale), "samples off their quadric"
    assert np.allclose(np.einsum("ni,ni->n", cloud.normals[~apex], grad / gn[:, None]), 1.0, atol=1e-9)
    # the reference's first-order distance Q/|∇Q| is unstable at a singular point of any leaf (a
    # cone's apex): there the sample must make the CSG value itself vanish
    hom = np.column_stack([cloud.positions, np.ones(len(cloud))])
    singular = np.zeros(len(cloud), dtype=bool)
    for _, Qw in world_leaves(shape):
        singular |= np.linalg.norm(hom @ Qw[:, :3], axis=1) <= 1e-6
    assert np.all(np.abs(graph_value(shape, cloud.positions[singular])) <= 1e-12 * scale**2)
    f = graph_first_order_distance(shape, cloud.positions[~singular])
    assert np.all(np.abs(f) <= 1e-7 * scale), f"samples off the CSG surface: {np.sort(np.abs(f))[-5:]}"


def _check_coverage(shape, cloud, center, radius, rng, n_rays=1500):
    o, d, tmax = random_rays(rng, center, radius, n_rays)
    pts, mats = ray_surface_points(shape, o, d, tmax)
    assert len(pts) > 100
    tree = cKDTree(cloud.positions)
    near = tree.query_ball_point(pts, cloud.radius * (1 + 1e-9))
    Qs = np.array([q.matrix for q in cloud.normal_form.quadrics])
    missing = []
    for p, cand in zip(pts, near, strict=True):
        cand = np.asarray(cand, dtype=int)
        cand = cand[np.linalg.norm(cloud.positions[cand] - p, axis=1) <= cloud.radii[cand] * (1 + 1e-9)]
        if len(cand) == 0:
            missing.append(p)
            continue
        h = np.append(p, 1.0)
        Qc = Qs[cloud.quadric_ids[cand]]
        val = np.einsum("i,nij,j->n", h, Qc, h)
        gn = np.linalg.norm(2.0 * np.einsum("i,nij->nj", h, Qc[:, :, :3]), axis=1)
        if not np.any(np.abs(val) / gn <= 1e-7):
            missing.append(p)
    assert not missing, f"{len(missing)} of {len(pts)} surface points uncovered, e.g. {missing[:3]}"
    return len(pts)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_samples_lie_on_the_csg_surface_and_cover_it(name):
    shape, (center, radius) = MODELS[name]()
    r = 0.12 if name != "thin" else 0.1
    cloud = sample_csg(shape, r)
    _check_on_surface(shape, cloud, radius)
    _check_coverage(shape, cloud, center, radius, np.random.default_rng(7))
    assert cloud.stats.unresolved <= DOCUMENTED_UNRESOLVED.get(name, 0)


def _mapped_back(cloud, shape, scale, offset):
    """The samples of ``shape.scaled(scale).translated(offset)`` mapped back to ``shape``'s frame."""
    nf = shape.normal_form()
    assert nf.names == cloud.normal_form.names
    return type(cloud)((cloud.positions - offset) / scale, cloud.normals, cloud.quadric_ids, cloud.radii / scale,
                       cloud.clip_start, cloud.clip_count, cloud.clip_indices, cloud.radius / scale, nf, cloud.stats)


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("scale, offset", [(1e-6, 0.0), (1e7, 0.0), (1.0, 1e6)], ids=["1e-6", "1e7", "moved 1e6"])
def test_scaled_and_translated_models_give_the_same_samples(name, scale, offset):
    """Every tolerance is relative: a model scaled by 1e-6 or 1e7, or moved by 10⁶, is sampled like the
    model itself (same samples up to the map), on its surface and covering it."""
    shape, (center, radius) = MODELS[name]()
    r = 0.12 if name != "thin" else 0.1
    t = np.array([offset, 0.0, 0.0])
    moved = shape.scaled(scale).translated(t)
    cloud = _mapped_back(sample_csg(moved, r * scale), shape, scale, t)
    ref = sample_csg(shape, r)
    assert abs(len(cloud) - len(ref)) <= 0.01 * len(ref)
    near, _ = cKDTree(ref.positions).query(cloud.positions)
    # identical but for decisions within rounding of a threshold (the thin model's 0.015 fin)
    assert np.mean(near <= 1e-7 * radius) > (0.99 if name != "thin" else 0.9)
    _check_on_surface(shape, cloud, radius)
    _check_coverage(shape, cloud, center, radius, np.random.default_rng(9), n_rays=1500)
    assert cloud.stats.unresolved <= DOCUMENTED_UNRESOLVED.get(name, 0)


@pytest.mark.parametrize("options", [{"reduce_radius": True}, {"distortion": "sqrt3"}, {"refine": False}])
def test_guarantee_holds_for_every_option(options):
    shape, (center, radius) = _plate()
    cloud = sample_csg(shape, 0.1, **options)
    _check_on_surface(shape, cloud, radius)
    _check_coverage(shape, cloud, center, radius, np.random.default_rng(3), n_rays=800)
    if options.get("reduce_radius"):
        assert np.all(cloud.radii <= 0.1 * (1 + 1e-12)) and np.min(cloud.radii) < 0.05


@pytest.mark.parametrize("name", sorted(MODELS))
def test_reduced_radii_resolve_what_full_radii_resolve(name):
    """Reduced radii (``reduce_radius=True``) used to leave the regions at feature tips, which only a neighbour's
    full radius reaches, unresolved -- uncovered surface, reported in the stats and nowhere else. The neighbour
    rule now raises that neighbour's reduced radius to what the region needs (never past the radius asked for)."""
    shape, (center, radius) = MODELS[name]()
    r = 0.12 if name != "thin" else 0.1
    full, reduced = sample_csg(shape, r), sample_csg(shape, r, reduce_radius=True)
    assert reduced.stats.unresolved <= full.stats.unresolved
    assert np.all(reduced.radii <= r * (1 + 1e-12))
    _check_coverage(shape, reduced, center, radius, np.random.default_rng(5))


def test_reduced_radii_leave_no_region_of_the_80_quadric_plate_unresolved():
    """The 80-quadric plate at its large splat size: 130 regions were left unresolved with reduced radii (one-pixel
    holes at 1920x1080), none with full radii."""
    from csgnb.csg.gallery import TABLE2

    build, radii = TABLE2["perforated plate"]
    cloud = sample_csg(build(), radii["large"], reduce_radius=True)
    assert cloud.stats.unresolved == 0
    assert cloud.radii.max() <= radii["large"] * (1 + 1e-12) and cloud.radii.min() < 0.01 * radii["large"]


def test_rotated_model_keeps_the_guarantee():
    shape, (center, radius) = _spheres()
    M = csg.rotation_matrix((0.3, -1.0, 0.5), 1.1, center)
    rotated = shape.transformed(M)
    cloud = sample_csg(rotated, 0.08)
    _check_on_surface(rotated, cloud, radius)
    _check_coverage(rotated, cloud, center, radius, np.random.default_rng(11), n_rays=800)


def test_thin_features_get_samples_even_below_the_radius():
    shape, _ = _thin()
    cloud = sample_csg(shape, 0.1)
    names = np.array(cloud.normal_form.names, dtype=object)[cloud.quadric_ids]
    for part in ("lens lo", "lens hi", "fin -z", "fin +z", "fin +x", "pin", "tip side"):
        assert np.sum(names == part) >= 1, part
    # the fin's side faces are 0.015 high: still covered along their whole length
    side = cloud.positions[names == "fin +x"]
    assert np.ptp(side[:, 1]) >= 1.0 - 2 * 0.1


def _bump(h: float, shift: float = 0.0):
    """A ball cut by a tilted plane, with a smaller ball poking ``h`` out of the cut face.

    The bump's surface on the CSG object is a cap of radius √(2 · 0.3 · h) (7.7e-4 for h = 1e-6), far
    below ``min_size · radius``, in a generic direction of the bump's heightfield planes (never at a
    region corner). Its sphere's box is the whole ball, so pass 1 sees regions with every corner off
    the surface and no sign change on their edges: deferred, no sample of the bump nearby for the
    neighbour rule, and only pass 1b's subdivision down to the cap's size finds it — exactly what
    ``min_size`` cuts short. ``shift`` moves the bump by a few ulps: the premise holds whatever the
    rounding.
    """
    n = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    body = csg.sphere((0, 0, 0), 1.0, "body") & csg.leaf(plane(n, 0.0), "cut")
    return body | csg.sphere(-(0.3 - h) * n + shift, 0.3, "bump"), n


@pytest.mark.parametrize("shift", [0.0, 1e-16, 1e-15])
def test_min_size_threshold_is_faster_but_may_drop_tiny_parts(shift):
    """``min_size`` only acts on regions still unclassified after the feature search (pass 1b): the
    former premise (the "thin" model) had such regions only by rounding — around its cone's apex,
    where d_Qab ≈ 6e-8 is found to √EPS — so moving the apex by 1e-16 (or another BLAS) left none and
    ``min_size`` changed nothing. Here the dropped part is a real one, and its loss is asserted."""
    shape, n = _bump(1e-6, shift)
    full = sample_csg(shape, 0.2)
    fast = sample_csg(shape, 0.2, min_size=0.1)
    assert fast.stats.distance_queries < 0.5 * full.stats.distance_queries
    names = np.array(full.normal_form.names, dtype=object)
    on_bump = full.positions[names[full.quadric_ids] == "bump"]
    # the full run covers the cap (it pokes 1e-6 above the cut face): its samples are on it
    assert len(on_bump) > 0 and np.all(on_bump @ n >= -1e-12)
    assert np.all(names[fast.quadric_ids] != "bump"), "min_size=0.1 should drop the 7.7e-4 cap"
    # the rest of the surface is sampled the same way
    assert full.stats.unresolved == fast.stats.unresolved == 0


def test_clip_sets_hold_every_quadric_reaching_into_the_splat():
    shape, _ = _plate()
    cloud = sample_csg(shape, 0.1)
    nf = cloud.normal_form
    rng = np.random.default_rng(5)
    with_clip = np.flatnonzero(cloud.clip_count > 0)
    assert len(with_clip) > 50
    term = nf.term_of
    # candidates near features: samples with clip sets and samples next to them
    picks = rng.choice(len(cloud), 400, replace=False)
    picks = np.concatenate([picks, rng.choice(with_clip, 200, replace=False)])
    ball = rng.normal(size=(300, 3))
    ball *= (rng.uniform(0, 1, 300) ** (1 / 3) / np.linalg.norm(ball, axis=1))[:, None]
    for i in picks:
        s, q, r_s = cloud.positions[i], cloud.quadric_ids[i], cloud.radii[i]
        clip = set(cloud.clip_set(i).tolist())
        assert q not in clip and all(term[j] == term[q] for j in clip)
        pts = s + 0.999 * r_s * ball
        for j in nf.term(term[q]):
            if j == q or j in clip:
                continue
            v = nf.quadrics[j].value(pts)
            assert np.all(v > 0) or np.all(v < 0), f"quadric {j} reaches into the splat of sample {i}"
            assert np.abs(signed_distance(nf.quadrics[j], s[None]))[0] > 0.0
    # each distinct set is stored once
    sets = {tuple(cloud.clip_set(i).tolist()) for i in with_clip}
    starts = {(int(cloud.clip_start[i]), int(cloud.clip_count[i])) for i in with_clip}
    assert len(sets) == len(starts)
    assert cloud.stats.clip_indices == len(cloud.clip_indices) == sum(len(t) for t in sets)


def test_clip_set_hash_wraps_explicitly_and_the_same_jitted_or_not():
    """The clip-set hash is FNV-1a mod 2⁶³ from 32-bit limbs: no int64 overflow (numpy warned
    "overflow encountered in scalar multiply" under NUMBA_DISABLE_JIT), same values either way."""
    import warnings

    from csgnb.sampling.cloud import _FNV_OFFSET, _fnv_step, deduplicate_clip_sets

    prime, mask = 1099511628211, (1 << 63) - 1
    rng = np.random.default_rng(4)
    hs = [0, 1, mask, _FNV_OFFSET, *rng.integers(0, mask, 50, dtype=np.int64).tolist()]
    vs = [0, 1, 7, mask, *rng.integers(0, 1 << 40, 50, dtype=np.int64).tolist()]
    step_py = getattr(_fnv_step, "py_func", _fnv_step)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for h, v in zip(hs, vs, strict=False):
            want = ((h ^ v) * prime) & mask
            assert int(_fnv_step(np.int64(h), np.int64(v))) == want
            assert int(step_py(np.int64(h), np.int64(v))) == want
        big = 2**31 - 1
        ptr = np.array([0, 2, 4, 5, 7])
        idx = np.array([3, big, 3, big, 9, 3, big])
        start, count, buf = deduplicate_clip_sets(ptr, idx)
    assert count.tolist() == [2, 2, 1, 2]
    assert start[0] == start[1] == start[3] != start[2] and buf.tolist() == [3, big, 9]
    with pytest.raises(CsgnbError, match="idx"):
        deduplicate_clip_sets(np.array([0, 2]), np.array([3, 2**40]))  # would not fit the int32 buffer


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(st.integers(0, 4), max_size=3), max_size=40))
def test_clip_sets_deduplicated_like_a_dictionary_of_first_occurrences(sets):
    """Each distinct clip set stored once, at its first occurrence, every sample pointing at its own set: runs of
    equal sets (a leaf's samples, taken without a lookup) broken by empty sets and by other sets included."""
    from csgnb.sampling.cloud import deduplicate_clip_sets

    sets = [sorted(set(x)) for x in sets]
    ptr = np.concatenate([[0], np.cumsum([len(x) for x in sets])]).astype(np.int64)
    idx = np.array([v for x in sets for v in x], dtype=np.int64)
    start, count, buf = deduplicate_clip_sets(ptr, idx)
    first, want = {}, []
    for x in sets:
        if x and tuple(x) not in first:
            first[tuple(x)] = len(want)
            want.extend(x)
    assert buf.tolist() == want
    for i, x in enumerate(sets):
        assert count[i] == len(x)
        if x:
            assert start[i] == first[tuple(x)]
            assert buf[start[i] : start[i] + count[i]].tolist() == x


def test_point_cloud_output():
    shape, _ = _spheres()
    cloud = sample_csg(shape, 0.1)
    pc = cloud.to_pyvista()
    assert pc.n_points == len(cloud)
    for key in ("normals", "quadric_id", "radius", "clip_count"):
        assert key in pc.point_data
    assert np.array_equal(pc.point_data["quadric_id"], cloud.quadric_ids)
    assert cloud.quadric_buffer().shape == (len(cloud.normal_form), 10)
    assert "samples" in repr(cloud)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("r", [0.05, 0.2])
def test_guarantee_many_rays(name, r):
    shape, (center, radius) = MODELS[name]()
    cloud = sample_csg(shape, r)
    _check_on_surface(shape, cloud, radius)
    _check_coverage(shape, cloud, center, radius, np.random.default_rng(int(r * 1000)), n_rays=6000)


def test_the_coverage_check_finds_holes():
    """The check above can fail: drop the samples of one spot and it reports the hole."""
    shape, (center, radius) = _spheres()
    cloud = sample_csg(shape, 0.1)
    spot = cloud.positions[len(cloud) // 2]
    keep = np.linalg.norm(cloud.positions - spot, axis=1) > 0.35
    holed = type(cloud)(cloud.positions[keep], cloud.normals[keep], cloud.quadric_ids[keep], cloud.radii[keep],
                        cloud.clip_start[keep], cloud.clip_count[keep], cloud.clip_indices, cloud.radius,
                        cloud.normal_form, cloud.stats)
    with pytest.raises(AssertionError, match="uncovered"):
        _check_coverage(shape, holed, center, radius, np.random.default_rng(1), n_rays=3000)


def _far_models(o):
    """Solids built at ``o`` (their constructors move origin-centred quadrics: ``Quadric.placement``)."""
    return {
        "sphere": csg.sphere(o, 1.0),
        "cone": csg.cone(o, o + (0.3, 0.0, 1.0), 0.2, 0.6),
        "capsule": csg.capsule(o, o + (1.0, 1.0, 0.0), 0.4),
        "box - sphere": csg.box(o - 1.0, o + 1.0) - csg.sphere(o + 0.5, 0.9),
    }


@pytest.mark.parametrize("distance", [1.0, 1e3, 1e6, 5e7, 1e8, 3e8, 1e9, 1e10, 1e11, 1e12])
def test_models_far_from_the_origin_are_sampled_on_their_surface_or_refused(distance):
    """Issue 25: a unit sphere at 10⁹ gave 48 samples at its centre (its world c = 10¹⁸ − 1 lost the
    radius), at 10⁸ or 10¹⁰ "the CSG surface is empty". Now every sample is within the world rounding
    bound of the surface and the surface is covered at the radius — or, where doubles cannot place
    samples within ``FAR_FROM_ORIGIN`` of the radius, a clear refusal."""
    from csgnb.errors import GeometryError
    from csgnb.quadric import tolerances as tol

    r = 0.2
    o = np.array([1.0, -0.3, 0.7]) * distance
    rounding = tol.WORLD_ROUNDING * tol.EPS * (np.abs(o).max() + 3.0)
    models = _far_models(o)
    if rounding > tol.FAR_FROM_ORIGIN * r:
        for shape in models.values():
            with pytest.raises(GeometryError, match="too far from the origin for double precision"):
                sample_csg(shape, r)
        return
    near = _far_models(np.zeros(3))
    # the world normal form too: its quadrics keep their placement (``Quadric.placement``)
    models["sphere (normal form)"] = models["sphere"].normal_form()
    near["sphere (normal form)"] = near["sphere"]
    for name, shape in models.items():
        cloud = sample_csg(shape, r)
        local = cloud.positions - o  # exact (Sterbenz) for points near o
        off = np.abs(graph_first_order_distance(near[name], local))
        # the world rounding, plus the sampler's own accuracy (as in _check_on_surface: 1e-9 × model size)
        assert off.max() <= rounding + 1e-9 * 3.0, f"{name}: samples {off.max():.3g} off the surface at {distance:g}"
        # coverage at the requested radius, checked on the model built at the origin
        back = _mapped_back(cloud, near[name], 1.0, o)
        _check_coverage(near[name], back, (0.2, 0.2, 0.2), 1.8, np.random.default_rng(1), n_rays=800)


def _cloud_arrays(cloud):
    arrays = {f: getattr(cloud, f) for f in ("positions", "normals", "radii", "quadric_ids", "clip_start",
                                             "clip_count", "clip_indices")}
    if cloud.trace is not None:
        for f in ("leaf_quadric", "leaf_triangle", "leaf_status", "leaf_depth", "point_xy", "point_distance"):
            arrays["trace." + f] = getattr(cloud.trace, f)
    return arrays


@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="pure-Python sampling of 100,000+ samples takes minutes; "
                    "the joins are the same code in the jitted run")
@pytest.mark.parametrize(("name", "splat", "trace"), [
    ("perforated plate", "medium", False), ("block", "small", False), ("spheres", "small", True),
    ("slotted cylinder", "small", True)])
def test_two_threads_give_the_one_thread_samples_bit_for_bit(name, splat, trace, monkeypatch):
    """Both passes run over chunks of jobs / leaves on all threads and join their buffers in order: every array
    of the cloud (and of its trace) must be the one-thread result, bit for bit."""
    import dataclasses

    import csgnb.sampling.sampler as sampler
    from csgnb.csg.gallery import TABLE2
    from csgnb.sampling import domain_cache_clear

    joins = []
    join = sampler._joined
    monkeypatch.setattr(sampler, "_joined", lambda *a: joins.append(1) or join(*a))

    build, radii = TABLE2[name]
    shape = build()
    before = numba.get_num_threads()
    clouds = []
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            domain_cache_clear()
            clouds.append(sample_csg(shape, radii[splat], trace=trace))
    finally:
        numba.set_num_threads(before)
    one, two = clouds
    assert len(one) > sampler._PARALLEL_MIN_EMIT and joins  # both passes ran on threads
    a, b = _cloud_arrays(one), _cloud_arrays(two)
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    assert dataclasses.replace(one.stats, seconds=0.0) == dataclasses.replace(two.stats, seconds=0.0)


@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="the neighbour rule over 78,000 leaves in pure Python")
def test_the_neighbour_rule_on_parts_of_tasks_is_the_one_pass_in_region_order(monkeypatch):
    """The neighbour rule shares tasks out among threads; a region's raise of a sample's radius can cover a later
    region of its task, so each part must do its tasks' regions in order: covered regions, the count and every
    raised radius as on one thread, on a model where raises happen in several tasks."""
    import csgnb.sampling.sampler as sampler
    from csgnb.csg.gallery import TABLE2
    from csgnb.sampling.kernel import cover_by_neighbours

    seen = []
    rule = sampler.cover_by_neighbours
    monkeypatch.setattr(sampler, "cover_by_neighbours",
                        lambda ts, LF, LI, UR, *a: seen.append((ts, LF.copy(), LI, UR.copy(), *a[:2])) or
                        rule(ts, LF, LI, UR, *a))
    build, radii = TABLE2["block"]
    sample_csg(build(), radii["small"])
    ts, LF, LI, UR, radius, reduce_radius = seen[0]
    before = numba.get_num_threads()
    results = []
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            lf, covered = LF.copy(), np.zeros(len(UR), dtype=np.bool_)
            results.append((cover_by_neighbours(ts, lf, LI, UR, radius, reduce_radius, covered), covered, lf))
    finally:
        numba.set_num_threads(before)
    (n1, c1, lf1), (n2, c2, lf2) = results
    raised = np.flatnonzero(lf1[:, 9] != LF[:, 9])
    assert reduce_radius and len(np.unique(ts.job_task[LI[raised, 0]])) > 1  # raises in several tasks
    assert n1 == n2 == c1.sum() and np.array_equal(c1, c2)
    assert np.array_equal(lf1, lf2)


def test_every_column_of_a_leaf_row_is_written(monkeypatch):
    """Pass 1's leaf buffers are ``np.empty``: a column a leaf does not use held whatever the memory held -- a NaN
    now and then, which made two equal runs of the neighbour rule compare unequal (the test above failed about once
    in a full run of the suite). With the buffers filled with NaN first, no leaf row keeps one."""
    import csgnb.sampling.sampler as sampler
    from csgnb.csg.gallery import TABLE2

    new_buffers = sampler._new_buffers

    def poisoned(*args, **kwargs):
        bufs = new_buffers(*args, **kwargs)
        for b in bufs:
            if isinstance(b, np.ndarray) and b.dtype.kind == "f":
                b.fill(np.nan)
        return bufs

    seen = []
    rule = sampler.cover_by_neighbours
    monkeypatch.setattr(sampler, "_new_buffers", poisoned)
    monkeypatch.setattr(sampler, "cover_by_neighbours",
                        lambda ts, LF, LI, *a: seen.append((LF.copy(), LI.copy())) or rule(ts, LF, LI, *a))
    build, radii = TABLE2["block"]
    sample_csg(build(), radii["small"])
    LF, LI = seen[0]
    assert np.any(LI[:, 1] == 0) and np.any(LI[:, 1] == 1)  # single samples and lattices
    assert np.all(np.isfinite(LF))


def test_joining_chunk_buffers_shifts_clip_list_offsets_and_trace_rows():
    """Two workers' buffers, three chunks: worker 0 filled chunks 0 and 2, worker 1 chunk 1."""
    from csgnb.sampling.sampler import _joined, _new_buffers

    workers = [_new_buffers(4, True), _new_buffers(4, True)]
    spans = []
    for k, (w, nl, nla, nt, nur) in enumerate([(0, 2, 3, 4, 1), (1, 3, 5, 2, 2), (0, 1, 1, 1, 1)]):
        b = workers[w]
        before = list(b[9])
        b[1][before[0] : before[0] + nl, 4] = before[1] + np.arange(nl)  # LA offsets within the worker's buffer
        b[2][before[1] : before[1] + nla] = 100 * k + np.arange(nla)
        b[3][before[2] : before[2] + nt] = k
        b[7][before[4] : before[4] + nur, 13] = [before[2] + 1, -1][:nur]
        b[8][:] += 1
        b[9] = [before[0] + nl, before[1] + nla, before[2] + nt, 0, before[4] + nur]
        spans.append((w, before, list(b[9])))
    LF, LI, LA, TT, TI, TP, TJ, UR, counters, fill = _joined(workers, spans)
    assert fill == [6, 9, 7, 0, 4] and len(LF) == len(LI) == 6 and len(LA) == 9 and len(TT) == len(TI) == 7
    assert LI[:, 4].tolist() == [0, 1, 3, 4, 5, 8]  # each chunk's lists start after the previous chunks' indices
    assert LA.tolist() == [0, 1, 2, 100, 101, 102, 103, 104, 200]
    assert TT[:, 0].tolist() == [0, 0, 0, 0, 1, 1, 2]
    assert UR[:, 13].tolist() == [1, 5, -1, 7]  # trace rows shifted to the joined rows; -1 stays
    assert counters.tolist() == [3] * 7


def _filled_workers(chunks, caps=(64, 4)):
    """Workers' pass-1 buffers filled chunk by chunk as ``_parallel_pass`` would: ``chunks`` lists
    ``(worker, leaves, clip indices, trace leaves, regions)``; worker 0 has room for ``caps[0]`` jobs, the others
    for ``caps[1]``. Returns (workers, spans in job order, the expected joined LA, LI offsets, TT rows, UR rows)."""
    from csgnb.sampling.sampler import _new_buffers

    workers = [_new_buffers(caps[0], True)] + [_new_buffers(caps[1], True) for _ in range(2)]
    spans, la, tt, ur = [], [], [], []
    for k, (w, nl, nla, nt, nur) in enumerate(chunks):
        b = workers[w]
        before = list(b[9])
        if b[7].shape[0] < before[4] + nur:
            b[7] = np.concatenate([b[7], np.empty_like(b[7])])
        b[1][before[0] : before[0] + nl, 4] = before[1] + np.arange(nl) % max(nla, 1)
        b[2][before[1] : before[1] + nla] = 100 * k + np.arange(nla)
        b[3][before[2] : before[2] + nt, 0] = k
        rows = before[2] + np.arange(nur) % max(nt, 1)
        b[7][before[4] : before[4] + nur, 13] = np.where(np.arange(nur) % 2 == 0, rows, -1)
        b[8][:] += 1
        b[9] = [before[0] + nl, before[1] + nla, before[2] + nt, 0, before[4] + nur]
        spans.append((w, before, list(b[9])))
        la += list(100 * k + np.arange(nla))
        tt += [k] * nt
        ur += [(len(tt) - nt + i % max(nt, 1)) if i % 2 == 0 else -1 for i in range(nur)]
    return workers, spans, la, tt, ur


@pytest.mark.parametrize("chunks", [
    [(0, 2, 3, 4, 1), (0, 3, 5, 2, 2), (1, 1, 1, 1, 1), (2, 4, 2, 0, 3)],  # worker 0's spans first: joined in place
    [(0, 2, 3, 4, 1), (1, 3, 5, 2, 300), (2, 1, 1, 1, 1)],  # worker 0's UR too small for the total: copied once
    [(1, 2, 3, 4, 1), (0, 3, 5, 2, 2), (1, 1, 1, 1, 1)],  # worker 0 not first: fresh arrays
    [(0, 2, 3, 4, 1), (1, 3, 5, 2, 2), (0, 1, 1, 1, 1)],  # worker 0 also later: fresh arrays
])
def test_joining_in_place_or_not_is_concatenating_the_spans(chunks):
    from csgnb.sampling.sampler import _joined

    workers, spans, la, tt, ur = _filled_workers(chunks)
    first_lf = workers[0][0]
    LF, LI, LA, TT, TI, TP, TJ, UR, counters, fill = _joined(workers, spans)
    n_leaves = sum(c[1] for c in chunks)
    assert fill == [n_leaves, len(la), len(tt), 0, len(ur)]
    assert LA[: len(la)].tolist() == la and TT[: len(tt), 0].tolist() == tt and UR[: len(ur), 13].tolist() == ur
    at, offsets = 0, []
    for _, nl, nla, _, _ in chunks:
        offsets += list(at + np.arange(nl) % max(nla, 1))
        at += nla
    assert LI[:n_leaves, 4].tolist() == offsets
    assert counters.tolist() == [len(chunks)] * 7
    of_0 = [k for k, c in enumerate(chunks) if c[0] == 0]
    assert (LF is first_lf) == (of_0 == list(range(len(of_0))) != [])  # worker 0's spans a prefix: in place


@given(st.lists(st.floats(0.0, 100.0), min_size=1, max_size=60), st.integers(2, 5),
       st.lists(st.booleans(), min_size=200, max_size=200))
@settings(max_examples=200, deadline=None)
def test_two_ended_chunks_cover_every_job_once_the_front_ones_a_prefix(weights, threads, fronts):
    """Thread 0 takes chunks from the front, the others from the back, in any interleaving: every job lands in
    exactly one chunk, thread 0's chunks are consecutive from job 0 (a prefix, joined in place), and chunks never
    grow as the two ends close in."""
    from csgnb.sampling.sampler import _TwoEnds

    ends = _TwoEnds(np.array(weights) + 1e-3, threads)
    taken, front_end = [], 0
    for front in fronts:
        chunk = ends.take(front)
        if chunk is None:
            break
        start, end = chunk
        assert start < end
        if front:
            assert start == front_end
            front_end = end
        taken.append(chunk)
    else:
        while (chunk := ends.take(True)) is not None:
            taken.append(chunk)
    jobs = sorted(j for s, e in taken for j in range(s, e))
    assert jobs == list(range(len(weights)))


@pytest.mark.skipif(numba.config.DISABLE_JIT or numba.config.NUMBA_NUM_THREADS < 2,
                    reason="threads need the jit and two of them")
@pytest.mark.parametrize("trace", [False, True])
def test_threads_on_every_model_however_few_its_jobs_give_the_one_thread_samples(trace, monkeypatch):
    """With the size thresholds off, every Table 2 model at its largest splat runs both passes on two threads --
    a handful of jobs, a thread that gets one chunk or none, regions in one thread's buffers only: every array of
    the cloud and of its trace must still be the one-thread result, bit for bit."""
    import csgnb.sampling.sampler as sampler
    from csgnb.csg.gallery import TABLE2

    monkeypatch.setattr(sampler, "_PARALLEL_MIN_SAMPLES", 0)
    monkeypatch.setattr(sampler, "_PARALLEL_MIN_EMIT", 0)
    before = numba.get_num_threads()
    try:
        for name, (build, radii) in TABLE2.items():
            shape = build()
            radius = max(radii.values())
            clouds = []
            for threads in (1, 2):
                numba.set_num_threads(threads)
                clouds.append(sample_csg(shape, radius, trace=trace))
            a, b = (_cloud_arrays(c) for c in clouds)
            for key in a:
                assert np.array_equal(a[key], b[key]), (name, key)
    finally:
        numba.set_num_threads(before)
