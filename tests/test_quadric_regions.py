"""Low-distortion basic regions (§4.1, Figures 7–8): exact cover of the surface, δ ≤ √3."""

import numpy as np
import pytest

from csgnb.quadric import (
    QUADRIC_CONSTRUCTORS,
    REGION_KINDS,
    distortion,
    elliptic_paraboloid,
    low_distortion_regions,
    octant_case,
    owning_plane,
    principal_frame,
    region_contains,
    sampling_planes,
    to_plane_coordinates,
)

CENTRAL = [n for n in sorted(QUADRIC_CONSTRUCTORS) if "paraboloid" not in n and n != "plane"]
ALL = sorted(QUADRIC_CONSTRUCTORS)
SQRT3 = np.sqrt(3.0)


def _random_quadric(rng, name):
    M = np.eye(4)
    M[:3, :3] = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    M[:3, 3] = rng.normal(size=3)
    return QUADRIC_CONSTRUCTORS[name]().transformed(M)


def _surface_points_in_box(q, lo, hi, rng, n=3000):
    """Random surface points in the box: random lines, roots by numpy's polynomial solver."""
    p = rng.uniform(lo, hi, (n, 3))
    v = rng.normal(size=(n, 3))
    Q = q.matrix
    A, m, c = Q[:3, :3], Q[:3, 3], Q[3, 3]
    out = []
    for pk, vk in zip(p, v, strict=True):
        coeffs = [vk @ A @ vk, 2 * vk @ (A @ pk + m), pk @ A @ pk + 2 * m @ pk + c]
        if abs(coeffs[0]) <= 1e-12:  # a plane: the line's one root
            coeffs = coeffs[1:]
        for r in np.roots(coeffs):
            if abs(r.imag) < 1e-12:
                out.append(pk + r.real * vk)
    pts = np.array(out).reshape(-1, 3)
    return pts[np.all((pts >= lo) & (pts <= hi), axis=1)]


def _check_cover(q, lo, hi, rng):
    regions = low_distortion_regions(q, lo, hi)
    planes = sampling_planes(q)
    pts = _surface_points_in_box(q, lo, hi, rng)
    if len(pts) < 50:
        return None  # the box barely meets the surface: nothing to check
    counts = np.zeros(len(pts), dtype=int)
    owner = owning_plane(q, pts)
    for r in regions:
        assert r.kind in REGION_KINDS
        loc = to_plane_coordinates(planes[r.plane], pts)
        inside = region_contains(r, loc[:, :2], tol=1e-9)
        counts += inside
        if inside.any():
            d = distortion(planes[r.plane], loc[inside, 0], loc[inside, 1])
            assert np.all(d <= SQRT3 * (1 + 1e-6)), d.max()
            # the claiming plane is the least-distorted one (up to ties)
            n = np.abs(q.normal(pts[inside]) @ np.column_stack([p.normal for p in planes]))
            best = n.max(axis=1)
            assert np.all(n[:, r.plane] >= best - 1e-6)
    # points where two planes tie lie on region boundaries: they may be claimed twice
    n = np.sort(np.abs(q.normal(pts) @ np.column_stack([p.normal for p in planes])), axis=1)
    clear = (n[:, 2] - n[:, 1]) > 1e-6
    assert np.all(counts[clear] == 1), np.bincount(counts[clear])
    assert np.all(counts >= 1)
    assert clear.mean() > 0.95
    return regions, owner


def _anchor(q):
    f = principal_frame(q)
    k = int(np.argmax(np.abs(f.linear)))
    if f.linear[k] == 0.0:
        return f.center
    return f.center + f.axes[:, k] * f.constant / (2 * f.linear[k])


@pytest.mark.parametrize("name", ALL)
def test_regions_cover_the_surface_exactly_once(name):
    rng = np.random.default_rng(17)
    q = _random_quadric(rng, name)
    checked = 0
    for _ in range(2):
        c = _anchor(q) + rng.normal(size=3)
        lo, hi = c - rng.uniform(0.5, 3, 3), c + rng.uniform(0.5, 3, 3)
        checked += _check_cover(q, lo, hi, rng) is not None
    assert checked >= 1


def test_canonical_shapes_give_the_expected_region_kinds():
    rng = np.random.default_rng(3)
    lo, hi = np.array([-2.0, -2.0, -2.0]), np.array([2.0, 2.0, 2.0])
    sphere_regions, _ = _check_cover(QUADRIC_CONSTRUCTORS["sphere"](), lo, hi, rng)
    # 3 planes × 4 quadrants × 2 octants, each one elliptic triangle with apex at the center
    assert [r.kind for r in sphere_regions] == ["elliptic-triangle"] * 24
    hyp, _ = _check_cover(QUADRIC_CONSTRUCTORS["hyperboloid (one sheet)"](), lo, hi, rng)
    assert {"hyperbolic-triangle", "triangle"} <= {r.kind for r in hyp}
    slab, _ = _check_cover(QUADRIC_CONSTRUCTORS["parallel planes"](), lo, hi, rng)
    assert {r.kind for r in slab} == {"rectangle"}
    flat, _ = _check_cover(QUADRIC_CONSTRUCTORS["plane"](), lo, hi, rng)
    assert [r.kind for r in flat] == ["rectangle"]
    for name in ("elliptic paraboloid", "hyperbolic paraboloid"):
        par, _ = _check_cover(QUADRIC_CONSTRUCTORS[name](), lo, hi, rng)
        assert "parabolic-triangle" in {r.kind for r in par}


def test_all_nine_cases_of_figure_7_occur():
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(400):
        alpha = rng.normal(size=3) * rng.choice([0.3, 1.0, 3.0], 3)
        for octant in ("x", "y"):
            seen.add(octant_case(alpha, octant))
    nine = {"full"} | {
        f"{c}/{s}"
        for c in ("ellipse", "hyperbola-axis", "hyperbola-line", "hyperbola-axis+line")
        for s in ("inside", "outside")
    }
    assert nine <= seen


def test_octant_case_matches_dense_classification():
    """'full' ⇔ the whole octant is low-distortion; 'inside' ⇔ the origin is."""
    rng = np.random.default_rng(1)
    gx, gy = np.meshgrid(np.linspace(1e-3, 3, 120), np.linspace(1e-3, 3, 120))
    for _ in range(60):
        ax, ay, ac = rng.normal(size=3)
        for octant in ("x", "y"):
            case = octant_case([ax, ay, ac], octant)
            in_oct = (np.abs(ax * gx) >= np.abs(ay * gy)) if octant == "x" else (
                np.abs(ay * gy) >= np.abs(ax * gx)
            )
            h2 = ax * gx**2 + ay * gy**2 + ac
            good = (h2 >= (ax * gx) ** 2) & (h2 >= (ay * gy) ** 2) & in_oct
            if case == "full":
                assert good[in_oct].all()
            elif case == "empty":
                assert not good.any()
            elif case.endswith("/inside"):
                assert ac > 0
            elif case.endswith("/outside"):
                assert ac < 0


def test_region_errors():
    with pytest.raises(TypeError, match="Quadric"):
        low_distortion_regions("sphere", [-1, -1, -1], [1, 1, 1])
    assert low_distortion_regions(elliptic_paraboloid(), [-1, -1, -1], [1, 1, 1])  # supported now
    with pytest.raises(ValueError, match="empty bounding box"):
        low_distortion_regions(QUADRIC_CONSTRUCTORS["sphere"](), [1, 1, 1], [0, 2, 2])
    with pytest.raises(ValueError, match="octant"):
        octant_case([1.0, 1.0, 1.0], "z")


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(20))
def test_cover_many_random_quadrics_and_boxes(seed):
    rng = np.random.default_rng(100 + seed)
    checked = 0
    for name in ALL:
        q = _random_quadric(rng, name)
        c = _anchor(q) + rng.normal(size=3) * 1.5
        box = (c - rng.uniform(0.3, 3, 3), c + rng.uniform(0.3, 3, 3))
        checked += _check_cover(q, *box, rng) is not None
    assert checked >= 3
