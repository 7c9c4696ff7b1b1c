"""``sample_csg``: samples on a quadric CSG surface with the coverage guarantee of §4.2.

Pipeline: normal form (eq. 17–18) → a box per term (or the user's bounding sphere) → per quadric
a task (:mod:`.tasks`: regions, plane frames, pruned eq. 22 data) → the adaptive kernel
(:mod:`.kernel`) → one point cloud with deduplicated clip sets (:mod:`.cloud`).
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time

import numpy as np

from csgnb import _threads
from csgnb.csg.bounds import box_is_empty, surface_boxes, term_boxes
from csgnb.csg.normal_form import NormalForm, to_normal_form
from csgnb.csg.normalisation import ModelFrame, box_frame, graph_frame, quadrics_frame
from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_count, as_finite_array, as_flag, as_positive, as_real
from csgnb.quadric.quadric import Quadric, planes_mask
from csgnb.sampling.cloud import SampleCloud, SamplingStats, SamplingTrace, _deduplicate
from csgnb.sampling.kernel import OVERFLOW, cover_by_neighbours, emit_all, subdivide_all
from csgnb.sampling.tasks import TaskSet, build_task_set

__all__ = ["sample_csg", "DISTORTION_MODES", "MIN_REGION", "ON_SURFACE", "DEFAULT_MAX_SAMPLES",
           "BYTES_PER_SAMPLE", "estimate_samples"]

#: ``distortion=`` choices: per-region bounds of δ (eq. 13, §3.4) or the worst case √3 (§4.1).
DISTORTION_MODES = ("bounds", "sqrt3")

#: Kept for callers of the former names (the values live in :mod:`csgnb.quadric.tolerances`).
MIN_REGION = tol.MIN_REGION
ON_SURFACE = tol.ON_SURFACE

#: ``max_samples`` default: about 5 GB of output (see ``BYTES_PER_SAMPLE``).
DEFAULT_MAX_SAMPLES = 50_000_000
#: Memory per sample while sampling: position, normal, radius (56 B), id, clip count and slice
#: (20 B), the clip pointers (8 B) and pass-1 leaves and clip indices (≈ 16 B amortised).
BYTES_PER_SAMPLE = 100
#: The estimate is _SAMPLES_PER_AREA · (area of the domains, δ ≤ √3) / r² + _SAMPLES_PER_JOB · jobs:
#: measured on the benchmark models the samples are 0.5–1.9 × area/r² once r is small against the
#: features (the memory that matters), and a few per job when it is not (up to 7 × area/r²).
_SAMPLES_PER_AREA = 2.0
_SAMPLES_PER_JOB = 4.0
#: Pass 1 runs on one thread below this many estimated samples, pass 2 below _PARALLEL_MIN_EMIT samples: two
#: threads cost more than they gain there (``bench_sampling.py``: 0.7-0.9x on the 5-7 ms rows at 20,000).
_PARALLEL_MIN_SAMPLES = 150_000
_PARALLEL_MIN_EMIT = 50_000


def _as_shape(shape):
    """Return ``shape`` as a NormalForm or a CSG node, or raise TypeError naming the argument."""
    if isinstance(shape, NormalForm):
        return shape
    from csgnb.csg.graph import as_node

    try:
        return as_node(shape)
    except TypeError as exc:
        raise TypeError(f"shape must be a csgnb.csg Node or a Quadric (or a NormalForm), got {type(shape).__name__}") \
            from exc


def _bounds_frame(bounds) -> tuple[ModelFrame, np.ndarray]:
    try:
        center, r = bounds
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"bounds must be a bounding sphere (center (3,), radius), got {type(bounds).__name__}"
        ) from exc
    try:
        c = as_finite_array(center, (3,), "bounds center")
    except GeometryError as exc:
        raise GeometryError(f"bounding sphere needs a finite center: {exc}") from exc
    except ValueError as exc:
        raise GeometryError(f"bounds must be a bounding sphere (center (3,), radius): {exc}") from exc
    try:
        r = as_positive(r, "bounds radius")
    except GeometryError as exc:
        raise GeometryError(f"bounding sphere needs a positive radius: {exc}") from exc
    return ModelFrame(c, r), np.concatenate([c - r, c + r])


def _flatten_planes(nf: NormalForm) -> NormalForm:
    """Replace quadrics that are planes up to rounding at the model scale by exact planes."""
    if not len(nf):
        return nf
    M = np.array([q.matrix for q in nf.quadrics])
    near = planes_mask(M) & np.any(M[:, :3, :3] != 0.0, axis=(1, 2))
    if not near.any():
        return nf
    qs = list(nf.quadrics)
    for k in np.flatnonzero(near):
        m = M[k].copy()
        m[:3, :3] = 0.0
        qs[k] = Quadric._trusted(m)
    return NormalForm(tuple(qs), nf.term_start, nf.names, nf.surface, nf.orientation)


def _normalised(shape, bounds, max_terms):
    """Return (normal form in the normalised frame, the frame, term boxes there, the world limit box)."""
    limit_world = None
    if bounds is not None:
        F0, limit_world = _bounds_frame(bounds)
    elif isinstance(shape, NormalForm):
        F0 = quadrics_frame(shape.quadrics)
    else:
        F0 = graph_frame(shape)
    nf0 = shape.mapped(F0.matrix) if isinstance(shape, NormalForm) else to_normal_form(shape, max_terms, F0.matrix)
    if nf0.n_terms == 0:
        raise GeometryError("the CSG object is empty: its normal form has no term (e.g. A ∩ ¬A); nothing to sample")
    limit0 = None if limit_world is None else F0.box_to_local(limit_world)
    boxes0, unbounded = term_boxes(nf0, limit0)
    if np.any(unbounded):
        i = int(np.flatnonzero(unbounded)[0])
        names = [nf0.names[k] or f"quadric {k}" for k in nf0.term(i)]
        raise GeometryError(
            f"term {i} of the normal form ({', '.join(names)}) is unbounded, or not bounded by its convex "
            "members; pass bounds=(center, radius), a bounding sphere of the region to sample"
        )
    F1 = box_frame(boxes0)
    if F1 is None:
        raise GeometryError("the CSG object is empty: every term of its normal form is empty" +
                            ("" if limit_world is None else " inside the bounding sphere"))
    F = F0.then(F1)
    if not isinstance(shape, NormalForm) and np.linalg.norm(F1.center) > 16.0 * F1.scale:
        # the first frame was far off (e.g. box faces built at 10⁶): redo the normal form from the
        # graph in the final frame, so that no precision is lost to the correction
        nf = to_normal_form(shape, max_terms, F.matrix)
        boxes, _ = term_boxes(nf, None if limit_world is None else F.box_to_local(limit_world))
    else:
        nf = nf0.mapped(F1.matrix)
        boxes = np.array([b if box_is_empty(b) else F1.box_to_local(b) for b in boxes0]).reshape(-1, 6)
        live = np.all(boxes[:, :3] <= boxes[:, 3:], axis=1)
        boxes[live, :3] -= 4.0 * tol.EPS  # the map's rounding, in units of the (unit) model
        boxes[live, 3:] += 4.0 * tol.EPS
    return _flatten_planes(nf), F, boxes


def world_rounding(frame: ModelFrame) -> float:
    """Return the bound on the rounding of a sample's world position (``tolerances.WORLD_ROUNDING``)."""
    return tol.WORLD_ROUNDING * tol.EPS * (float(np.max(np.abs(frame.center))) + frame.scale)


def coefficient_rounding(q: Quadric) -> float:
    """Return how far rounding of ``q``'s world coefficients may move its surface (``tolerances.COEFFICIENT_ROUNDING``).

    0 for placed quadrics (:attr:`Quadric.placement`: their shape is exact) and for planes.
    """
    if q.placement is not None or not np.any(q.A):
        return 0.0
    from csgnb.quadric.frames import principal_frame

    f = principal_frame(q)
    top = float(np.max(np.abs(f.eigenvalues)))
    if not top > 0.0:
        return 0.0
    noise = tol.COEFFICIENT_ROUNDING * tol.EPS * (abs(q.c) + abs(float(f.center @ q.b)))
    if noise == 0.0:
        return 0.0
    return noise / (2.0 * math.sqrt(top * max(abs(f.constant), noise)))


def _check_leaves(shape, r: float) -> None:
    """Refuse leaves whose world coefficients lost the digits of their shape at this radius."""
    if isinstance(shape, NormalForm):
        named = [(q, shape.names[k] or f"quadric {k}") for k, q in enumerate(shape.quadrics)]
    else:
        from csgnb.csg.graph import graph_leaves

        named = [(leaf.quadric, leaf.name or "a leaf") for leaf in graph_leaves(shape)]
    for q, name in named:
        moved = coefficient_rounding(q)
        if moved > tol.FAR_FROM_ORIGIN * r:
            raise GeometryError(
                f"{name} is given by world coefficients too far from the origin for double precision: their "
                f"rounding may move its surface by {moved:.3g}, more than {tol.FAR_FROM_ORIGIN:g} of the radius "
                f"{r:.3g}; build it at the origin and move it (Quadric.translated / .transformed, the csg solids' "
                "centers, or a CSG edge), which keeps its shape exact"
            )


def _covering_radius(r: float, frame: ModelFrame) -> float:
    """Return the radius to cover with in the normalised frame: ``r`` less the world rounding, or refuse."""
    rounding = world_rounding(frame)
    if rounding > tol.FAR_FROM_ORIGIN * r:
        far = float(np.max(np.abs(frame.center)))
        raise GeometryError(
            f"the model is too far from the origin for double precision at this splat radius: its coordinates "
            f"reach {far:.3g}, where doubles are {np.spacing(far):.3g} apart, so samples could be off the surface by "
            f"up to {rounding:.3g}, more than {tol.FAR_FROM_ORIGIN:g} of the radius {r:.3g}; move the model nearer "
            "the origin (sample it there and add the offset yourself) or pass a larger radius"
        )
    return (r - rounding) / frame.scale


def _estimate_from_tasks(ts: TaskSet, radius: float) -> float:
    """Return an estimate of the samples of a task set at splat radius ``radius`` (its units).

    From the area of the domains' jobs (plane area × δ², δ ≤ √3 in low-distortion regions): the
    area of every quadric's surface inside its box, whether or not it is on the CSG surface.
    """
    if not len(ts.job_tri):
        return 0.0
    return float(_job_weights(ts, radius).sum())


def estimate_samples(shape, radius: float, *, bounds=None, max_terms: int = 4096) -> float:
    """Return the sampler's estimate of the number of samples of ``shape`` at ``radius``.

    It runs only the set-up (normal form, boxes, domains; milliseconds) and counts every quadric's
    surface inside its box, on the CSG surface or not: on the benchmark models it is 1–4× the
    count at small radii. :func:`sample_csg` refuses to start when it is above ``max_samples`` —
    and checks the exact count again after its first pass, before allocating the samples.
    Multiply by ``BYTES_PER_SAMPLE`` for the memory.
    """
    r = as_positive(radius, "radius")
    max_terms = as_count(max_terms, "max_terms", 1)
    shape = _as_shape(shape)
    nf, frame, boxes = _normalised(shape, bounds, max_terms)
    rn = r / frame.scale
    if rn < tol.MIN_RADIUS:
        return math.inf
    rn = _covering_radius(r, frame)
    ts = build_task_set(nf, surface_boxes(nf, boxes, 1.0), boxes, rn, 1.0)
    return _estimate_from_tasks(ts, rn)


def _check_estimate(count: float, max_samples: int | None, exact: bool, bound: str = "") -> None:
    if max_samples is None or count <= max_samples:
        return
    gib = count * BYTES_PER_SAMPLE / 2**30
    what = f"needs {bound + ' ' if bound else ''}{int(count)}" if exact else f"would need about {count:.3g}"
    raise CsgnbError(
        f"sampling {what} samples (≈ {gib:.3g} GiB), above max_samples={max_samples:_}; "
        "pass a larger radius, a bounding sphere around the part of interest, or a larger max_samples "
        "(None: no limit)"
    )


def sample_csg(
    shape,
    radius: float,
    *,
    bounds=None,
    distortion: str = "bounds",
    min_size: float = 0.0,
    reduce_radius: bool = True,
    refine: bool = True,
    trace: bool = False,
    progress: bool = False,
    max_terms: int = 4096,
    max_samples: int | None = DEFAULT_MAX_SAMPLES,
) -> SampleCloud:
    """Return samples on the surface of a CSG object with splat radius ``radius`` (§4.2, §5).

    Parameters
    ----------
    shape : Node, Quadric or NormalForm
        The CSG graph (``csgnb.csg``) or its normal form. Every quadric type may occur: central
        quadrics, elliptic and hyperbolic paraboloids, single planes.
    radius : float
        Splat radius r: every point of the CSG surface gets a sample on the same quadric within r.
    bounds : (center (3,), radius) or None
        A bounding sphere; only the surface inside its box is sampled. Required when a term of
        the normal form is unbounded (e.g. a single plane, or ``¬A``).
    distortion : "bounds" or "sqrt3"
        Turn world radii into plane radii with the per-region bound of δ (§3.4, fewer samples)
        or assume the worst case √3 of the low-distortion regions (§4.1; a region whose bound
        exceeds √3 — one reaching beyond its low-distortion region — keeps its bound).
    min_size : float
        If > 0, discard regions still unclassified once smaller than ``min_size · radius`` (the
        paper's speed-up, e.g. 0.1). Off by default: it can leave holes at features smaller
        than that.
    reduce_radius : bool
        Give samples of small regions the smaller radius that covers their region (the default: less overdraw,
        the same guarantee -- where a region at a feature tip is covered only by a neighbouring sample, that
        sample's radius is raised to reach it, never past ``radius``). ``False`` gives every sample ``radius``.
    refine : bool
        Split kept regions further (no distance queries) where their distortion varies, so that
        the sample lattice follows the local δ: fewer samples for the same guarantee.
    trace : bool
        Record leaves and distance evaluations (``SampleCloud.trace``, for Figure 9).
    progress : bool
        Show a tqdm bar over the quadrics.
    max_terms : int
        Limit for the normal form (see ``csgnb.csg.to_normal_form``).
    max_samples : int or None
        Refuse (with :class:`CsgnbError`, naming the estimate and its memory) to sample when the
        estimated — and, after the first pass, the exact — number of samples is above this.

    Returns
    -------
    SampleCloud

    Raises
    ------
    TypeError
        If an argument has the wrong type (a string or None radius, a non-bool flag, ...).
    GeometryError
        If the object is empty, unbounded without ``bounds``, or has no surface in the bounds; if
        the radius is not positive or below ``tolerances.MIN_RADIUS`` of the model's size; if the
        model is so far from the origin that double precision cannot place samples within
        ``tolerances.FAR_FROM_ORIGIN`` of the radius (a unit sphere at 10¹² with radius 0.2).
    CsgnbError
        If an option is unknown, or the sample count is above ``max_samples``.

    All tolerances are relative to the model: it is sampled in a normalised frame (its box
    centered at 0 with half-diagonal 1, :mod:`csgnb.csg.normalisation`), so a model and a scaled
    or translated copy give the same samples up to the map. Leaves built in a frame of their own and
    moved (``csg.sphere(center=...)``, ``.translated``; see ``Quadric.placement``) keep their shape's
    digits however far away; the samples' world coordinates are rounded by at most
    ``world_rounding(frame)`` (two millionths at 10¹⁰), which the sampler takes off the radius it covers
    with, so the guarantee holds at ``radius``.
    """
    t0 = time.perf_counter()
    r = as_positive(radius, "radius")
    if not isinstance(distortion, str):
        raise TypeError(f"distortion must be a str, one of {DISTORTION_MODES}, got {type(distortion).__name__}")
    if distortion not in DISTORTION_MODES:
        raise CsgnbError(f"distortion must be one of {DISTORTION_MODES}, got {distortion!r}")
    min_size = as_real(min_size, "min_size")
    if min_size < 0.0:
        raise CsgnbError(f"min_size must be ≥ 0 (a fraction of the radius), got {min_size}")
    reduce_radius = as_flag(reduce_radius, "reduce_radius")
    refine = as_flag(refine, "refine")
    trace = as_flag(trace, "trace")
    progress = as_flag(progress, "progress")
    max_terms = as_count(max_terms, "max_terms", 1)
    if max_samples is not None:
        max_samples = as_count(max_samples, "max_samples", 0)
    shape = _as_shape(shape)
    try:
        nf, frame, boxes = _normalised(shape, bounds, max_terms)
    except GeometryError:
        _check_leaves(shape, r)  # the cause, if a leaf's coefficients lost its shape (then "empty" is wrong)
        raise
    rn = r / frame.scale
    if rn < tol.MIN_RADIUS:
        raise GeometryError(
            f"splat radius {r:.3g} is below {tol.MIN_RADIUS:g} of the model's size ({frame.scale:.3g}): samples "
            "could not be placed that precisely (and would be far too many); pass a larger radius"
        )
    _check_leaves(shape, r)
    rn = _covering_radius(r, frame)
    ts = build_task_set(nf, surface_boxes(nf, boxes, 1.0), boxes, rn, 1.0)
    _check_estimate(_estimate_from_tasks(ts, rn), max_samples, False)
    C = np.ascontiguousarray(nf.coefficients)
    ts, leaves = _subdivide(C, ts, rn, min_size * rn, distortion == "sqrt3", refine, trace, progress, reduce_radius,
                            max_samples)
    _check_estimate(leaves.samples, max_samples, True)
    kept = None if bounds is None else _bounds_frame(bounds)[0]
    cloud = _emit(nf, C, ts, leaves, rn, reduce_radius, trace, frame, t0, r)
    return cloud if kept is None else dataclasses.replace(cloud, bounds=(kept.center.copy(), kept.scale))


class _Leaves:
    """Pass-1 output (see ``kernel.subdivide_all``)."""

    def __init__(self, LF, LI, LA, TT, TI, TP, TJ, UR, counters) -> None:
        self.LF, self.LI, self.LA, self.TT, self.TI, self.TP, self.TJ = LF, LI, LA, TT, TI, TP, TJ
        self.UR = UR
        self.counters = counters
        self.samples = int(LI[:, 3].sum())


def _grown(a: np.ndarray, used: int, limit: int | None = None) -> np.ndarray:
    size = max(4 * a.shape[0], 64) if limit is None else max(min(4 * a.shape[0], limit), used + 1)
    b = np.empty((size,) + a.shape[1:], dtype=a.dtype)
    b[:used] = a[:used]
    return b


def _pass(C, ts: TaskSet, radius, min_size, sqrt3, refine, trace, defer, job_range, bar, bufs, max_samples):
    """Run ``kernel.subdivide_all`` over ``job_range`` (chunked for the progress bar), growing buffers."""
    for start, end in job_range:
        job = start
        while True:
            LF, LI, LA, TT, TI, TP, TJ, UR, counters, fill = bufs
            nl, nla, nt, npt, nur = fill
            nl, nla, nt, npt, nur, job, overflow = subdivide_all(
                C, ts, radius, min_size, tol.MIN_REGION, tol.ON_SURFACE, sqrt3, refine, trace, defer,
                LF, LI, LA, TT, TI, TP, TJ, UR, counters, job, int(end), nl, nla, nt, npt, nur,
            )  # fmt: skip
            fill = [nl, nla, nt, npt, nur]
            if overflow == OVERFLOW["leaves"]:
                if max_samples is not None and nl >= max_samples:  # every leaf has ≥ 1 sample
                    _check_estimate(nl + 1, max_samples, True, "at least")
                limit = None if max_samples is None else max_samples + 1024
                LF, LI = _grown(LF, nl, limit), _grown(LI, nl, limit)
            elif overflow == OVERFLOW["clip_lists"]:
                LA = _grown(LA, nla)
            elif overflow == OVERFLOW["trace_leaves"]:
                TT, TI = _grown(TT, nt), _grown(TI, nt)
            elif overflow == OVERFLOW["trace_points"]:
                TP, TJ = _grown(TP, npt), _grown(TJ, npt)
            elif overflow == OVERFLOW["unresolved"]:
                UR = _grown(UR, nur)
            bufs[:] = [LF, LI, LA, TT, TI, TP, TJ, UR, counters, fill]
            if overflow == OVERFLOW["none"]:
                break
        if bar is not None:
            bar.update(1)


def _new_buffers(jobs: int, trace: bool, expected: float = 0.0) -> list:
    """Pass-1 buffers for ``jobs`` jobs expected to make about ``expected`` leaves: LF, LI, LA, TT, TI, TP, TJ, UR,
    counters and their fill levels."""
    cap = 64 * jobs + 1024 + int(expected)
    tcap = 16 * jobs + 64 if trace else 1
    return [np.empty((cap, 16)), np.empty((cap, 6), dtype=np.int64), np.empty(4 * cap, dtype=np.int64),
            np.empty((tcap, 6)), np.empty((tcap, 5), dtype=np.int64), np.empty((tcap, 3)),
            np.empty(tcap, dtype=np.int64), np.empty((256, 14)), np.zeros(7, dtype=np.int64), [0, 0, 0, 0, 0]]


class _TwoEnds:
    """The jobs not yet taken, ``lo:hi``, handed out in chunks from both ends (:func:`_parallel_pass`): thread 0
    takes the next chunk from the front, the others from the back, so that thread 0's chunks are a prefix of the
    output, already in place for the join.

    A chunk is about a ``4 × threads``-th of the estimated work still between the ends (guided, on the jobs'
    ``weights``: domain area over r²) and no less than a ``64 × threads``-th of the whole (a job heavier than its
    share alone). The estimate misses how much a surface's curvature multiplies its regions (on the 80-quadric
    plate the two last tasks cost 3–4× their estimate per unit), so where the two ends meet is not known in advance:
    sizing each chunk when it is taken, from what is left between the ends, makes the chunks small wherever they
    meet, and no thread waits long for another's last chunk.
    """

    def __init__(self, weights: np.ndarray, threads: int) -> None:
        self.cum = np.concatenate([[0.0], np.cumsum(weights)])
        self.lo, self.hi = 0, len(weights)
        self.threads = threads
        self.floor = float(self.cum[-1]) / (64 * threads)
        self.lock = threading.Lock()

    def take(self, front: bool) -> tuple[int, int] | None:
        """The next chunk ``(start, end)`` of jobs from the front or the back; None when every job is taken."""
        with self.lock:
            lo, hi, cum = self.lo, self.hi, self.cum
            if lo >= hi:
                return None
            size = max(self.floor, float(cum[hi] - cum[lo]) / (4 * self.threads))
            if front:
                end = min(hi, max(lo + 1, int(np.searchsorted(cum, cum[lo] + size))))
                self.lo = end
                return lo, end
            start = max(lo, min(hi - 1, int(np.searchsorted(cum, cum[hi] - size, side="right")) - 1))
            self.hi = start
            return start, hi


def _parallel_pass(C, ts: TaskSet, radius, min_size, sqrt3, refine, trace, ranges, bar, max_samples) -> list:
    """Pass 1 over the job ranges, on ``threads()`` threads when the model is large enough to gain from it.

    The jobs are handed out in chunks from both ends (:class:`_TwoEnds`): the first thread takes them in order
    from the front, the others from the back, until they meet, so that the first thread's chunks are a prefix of
    the output. Each thread appends to buffers of its own (reused across its chunks: fresh small buffers per chunk
    cost four times the page faults; the first thread's are sized like the one-thread ones, their pages touched
    only as they fill) and records the span each chunk filled. The spans are joined in job order
    (:func:`_joined`: the others' spans copied after the first thread's, in its buffers): the one-thread output
    bit for bit, since a job's output does not depend on the jobs before it (only the LA offsets in LI, the trace
    rows in UR and the counters are adjusted).
    """
    threads = _threads.threads()
    jobs = len(ts.job_task)
    weights = _job_weights(ts, radius)
    if threads == 1 or weights.sum() < _PARALLEL_MIN_SAMPLES:
        bufs = _new_buffers(jobs, trace)
        _pass(C, ts, radius, min_size, sqrt3, refine, trace, True, ranges, bar, bufs, max_samples)
        return bufs
    if bar is not None:  # the bar counts jobs now, not quadrics
        bar.unit = "job"
        bar.reset(total=jobs + 1)
    expected = 0.5 * float(weights.sum())
    workers = [_new_buffers(jobs, trace, expected)]
    workers += [_new_buffers(jobs // threads, trace, expected / threads) for _ in range(threads - 1)]
    spans: list = []
    ends = _TwoEnds(weights, threads)

    def work(w):
        bufs = workers[w]
        while (chunk := ends.take(front=w == 0)) is not None:
            before = list(bufs[9])
            _pass(C, ts, radius, min_size, sqrt3, refine, trace, True, [chunk], None, bufs, max_samples)
            spans.append((chunk[0], w, before, list(bufs[9])))  # (list.append is atomic)
            if bar is not None:
                bar.update(chunk[1] - chunk[0])

    _threads.run_parts(lambda part, parts: work(part), parts=threads)
    return _joined(workers, [span[1:] for span in sorted(spans)])


def _job_weights(ts: TaskSet, radius: float) -> np.ndarray:
    """Estimated samples per job (see ``_estimate_from_tasks``) : (jobs,) float64."""
    t = ts.job_tri
    area2 = np.abs((t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) *
                   (t[:, 2, 0] - t[:, 0, 0]))
    return _SAMPLES_PER_AREA * 3.0 * 0.5 * area2 / (radius * radius) + _SAMPLES_PER_JOB


def _joined(workers: list, spans: list) -> list:
    """Join the spans ``(worker, fill before, fill after)`` of the workers' pass-1 buffers in order (see
    ``_parallel_pass``): fill levels are (leaves, clip-list indices, trace leaves, trace points, regions).

    When worker 0's spans are the first ones, filled in order (as ``_parallel_pass`` takes them), they already
    lie where the joined arrays want them: the other spans are copied after them into worker 0's buffers (an
    array too small for the total is first copied into one of the total's size). Otherwise the arrays are
    allocated once and every span is copied. The copies run on ``threads()`` threads (numpy's copies release the
    GIL; on the 615,642-sample plate a join into fresh arrays moved ~50 MB, whose first touch of fresh pages was
    most of its time): the same arrays as concatenating the spans in order.
    """
    field_fill = (0, 0, 1, 2, 2, 3, 3, 4)  # the fill level counting each array's rows
    starts, at = [], np.zeros(5, dtype=np.int64)
    for _, before, after in spans:
        starts.append(at.copy())
        at += np.array(after) - np.array(before)
    first = workers[0]
    placed = 0  # worker 0's leading spans, already in their joined place
    while placed < len(spans) and spans[placed][0] == 0 and list(spans[placed][1]) == starts[placed].tolist():
        placed += 1
    if any(w == 0 for w, _, _ in spans[placed:]):
        placed = 0  # a later span of worker 0 could be overwritten before it is copied
    kept = starts[placed] if placed < len(spans) else at
    out = []
    for i, f in enumerate(field_fill):
        a = first[i]
        if placed and a.shape[0] >= at[f]:
            out.append(a)
            continue
        b = np.empty((int(at[f]),) + a.shape[1:], dtype=a.dtype)
        if placed:
            b[: kept[f]] = a[: kept[f]]
        out.append(b)

    def copy(k: int) -> None:
        w, before, after = spans[k]
        bufs, to = workers[w], starts[k]
        for i, f in enumerate(field_fill):
            out[i][to[f] : to[f] + after[f] - before[f]] = bufs[i][before[f] : after[f]]
        li = out[1][to[0] : to[0] + after[0] - before[0]]
        li[:, 4] += to[1] - before[1]  # clip-list offsets into the joined LA
        ur = out[7][to[4] : to[4] + after[4] - before[4]]
        ur[:, 13] = np.where(ur[:, 13] >= 0, ur[:, 13] + (to[2] - before[2]), ur[:, 13])  # trace rows

    _threads.run_tasks(lambda k: copy(placed + k), len(spans) - placed)
    counters = np.sum([b[8] for b in workers], axis=0).astype(np.int64)
    return out + [counters, [int(x) for x in at]]


def _subdivide(C, ts: TaskSet, radius, min_size, sqrt3, refine, trace, progress, reduce_radius, max_samples=None):
    """Pass 1 (with deferral of failed feature searches), the neighbour rule, pass 1b on the rest."""
    jobs = len(ts.job_task)
    bar = None
    ranges = [(0, jobs)]
    if progress:
        from tqdm.auto import tqdm

        ends = ts.job_ptr[1:]
        ranges = list(zip(ts.job_ptr[:-1], ends, strict=True))
        bar = tqdm(total=len(ranges) + 1, desc="subdividing", unit="quadric")
    bufs = _parallel_pass(C, ts, radius, min_size, sqrt3, refine, trace, ranges, bar, max_samples)
    fill = bufs[9]
    nl, nur = fill[0], fill[4]
    UR = bufs[7][:nur].copy()
    LF, LI = bufs[0][:nl], bufs[1][:nl]
    covered = np.zeros(len(UR), dtype=np.bool_)
    if len(UR):
        cover_by_neighbours(ts, LF, LI, UR, radius, reduce_radius, covered)
    deferred = UR[:, 12] == 1.0
    redo = UR[deferred & ~covered]
    done = UR[covered]
    ts_all = ts
    if len(redo):  # pass 1b: the deferred regions not covered by a neighbour, searched no more
        ts_all = ts.with_regions(redo)
        bufs[9][4] = 0
        _pass(C, ts_all, radius, min_size, sqrt3, refine, trace, False, [(jobs, len(ts_all.job_task))], None, bufs,
              max_samples)
        fill = bufs[9]
        nl, nur = fill[0], fill[4]
        UR2 = bufs[7][:nur].copy()
        covered2 = np.zeros(len(UR2), dtype=np.bool_)
        if len(UR2):
            cover_by_neighbours(ts_all, bufs[0][:nl], bufs[1][:nl], UR2, radius, reduce_radius, covered2)
        UR = np.concatenate([UR[~deferred], UR2])
        covered = np.concatenate([covered[~deferred], covered2])
        done = np.concatenate([done, UR2[covered2]])
    if bar is not None:
        bar.update(1)
        bar.close()
    LF, LI, LA, TT, TI, TP, TJ, _, counters, fill = bufs
    nl, nla, nt, npt, _ = fill
    lv = _Leaves(LF[:nl], LI[:nl], LA[:nla], TT[:nt], TI[:nt], TP[:npt], TJ[:npt], UR, counters)
    lv.unresolved = int(np.sum(~covered & (UR[:, 12] == 0.0))) if len(UR) else 0
    lv.by_neighbours = len(done)
    if trace:
        _trace_neighbours(lv, done)
    return ts_all, lv


def _trace_neighbours(lv: _Leaves, done: np.ndarray) -> None:
    """Trace the regions the neighbour rule covered with status ``neighbour``."""
    from csgnb.sampling.kernel import STATUS

    rows = done[:, 13].astype(np.int64)
    old = rows[rows >= 0]
    lv.TI[old, 2] = STATUS["neighbour"]
    new = done[rows < 0]
    if len(new):
        ti = np.zeros((len(new), 5), dtype=np.int64)
        ti[:, 0] = new[:, 5].astype(np.int64)
        ti[:, 2] = STATUS["neighbour"]
        ti[:, 3] = -1  # depth not recorded for deferred regions
        lv.TT = np.concatenate([lv.TT, new[:, 6:12]])
        lv.TI = np.concatenate([lv.TI, ti])


def _emit(nf: NormalForm, C, ts: TaskSet, lv: _Leaves, radius: float, reduce_radius: bool, trace: bool,
          frame: ModelFrame, t0: float, world_radius: float):
    n = lv.samples
    if n == 0:
        raise GeometryError(
            "the CSG surface is empty (inside the bounds): no point of any quadric lies on it; "
            "check the operands, or the bounding sphere"
        )
    positions = np.empty((n, 3))
    normals = np.empty((n, 3))
    radii = np.empty(n)
    ptr = np.empty(n + 1, dtype=np.int64)
    ptr[0] = 0
    ids = np.empty(n, dtype=np.int32)
    cidx, nc = _emit_parallel(C, ts, lv, radius, reduce_radius, frame, (positions, normals, radii, ptr, ids))
    start, count, buf = _deduplicate(ptr, cidx[:nc])
    world = nf.mapped(frame.inverse)
    counters = lv.counters
    tr = _trace(ts, lv, frame) if trace else None
    stats = SamplingStats(
        samples=n,
        distance_queries=int(counters[0]),
        clip_indices=len(buf),
        regions=int(counters[1]),
        unresolved=lv.unresolved,
        quadrics=len(nf),
        sampled_quadrics=len(ts.quadric),
        terms=nf.n_terms,
        seconds=time.perf_counter() - t0,
        feature_points=int(counters[6]),
        covered_by_neighbours=lv.by_neighbours,
    )
    return SampleCloud(positions, normals, ids, radii, start, count, buf, world_radius, world, stats, tr, frame)


def _emit_leaves(C, ts: TaskSet, LF, LI, LA, radius, reduce_radius, frame: ModelFrame, out) -> tuple[np.ndarray, int]:
    """Run ``kernel.emit_all`` over the leaves ``LF``, ``LI`` into ``out`` = (positions, normals, radii, ptr, ids)
    from sample 0 on (``ptr[0]`` is left to the caller), growing the clip indices; return them and their count."""
    positions, normals, radii, ptr, ids = out
    cidx = np.empty(1 << 16, dtype=np.int64)
    leaf = at = nc = 0
    while True:  # samples straight into world coordinates
        leaf, at, nc = emit_all(C, ts, LF, LI, LA, radius, reduce_radius, frame.center, frame.scale,
                                positions, normals, radii, ptr, ids, cidx, leaf, at, nc)
        if leaf >= len(LI):
            return cidx, nc
        need = nc + int(LI[leaf, 3] * LI[leaf, 5])
        grown = np.empty(max(4 * len(cidx), need), dtype=np.int64)
        grown[:nc] = cidx[:nc]
        cidx = grown


def _emit_parallel(C, ts: TaskSet, lv: _Leaves, radius, reduce_radius, frame: ModelFrame, out):
    """Pass 2 on ``threads()`` threads: consecutive chunks of leaves write their samples into their slice of the
    outputs (a leaf's first sample is the running sum of the counts before it) and their clip indices into a
    buffer of their own; the buffers are joined in order and each chunk's ``ptr`` shifted by the indices before
    it -- the one-thread output bit for bit."""
    threads = _threads.threads()
    counts = lv.LI[:, 3]
    n_leaves = len(counts)
    if threads == 1 or lv.samples < _PARALLEL_MIN_EMIT:
        return _emit_leaves(C, ts, lv.LF, lv.LI, lv.LA, radius, reduce_radius, frame, out)
    first = np.concatenate([[0], np.cumsum(counts)])
    parts = 4 * threads
    cuts = np.searchsorted(first, np.linspace(0, first[-1], parts + 1)[1:-1])
    bounds = [0, *sorted(set(int(c) for c in cuts if 0 < c < n_leaves)), n_leaves]
    positions, normals, radii, ptr, ids = out

    def run(k):
        l0, l1 = bounds[k], bounds[k + 1]
        s0, s1 = first[l0], first[l1]
        view = (positions[s0:s1], normals[s0:s1], radii[s0:s1], ptr[s0 : s1 + 1], ids[s0:s1])
        return _emit_leaves(C, ts, lv.LF[l0:l1], lv.LI[l0:l1], lv.LA, radius, reduce_radius, frame, view)

    results = _threads.run_tasks(run, len(bounds) - 1)
    at = 0
    for k, (_, nc) in enumerate(results):
        s0, s1 = first[bounds[k]], first[bounds[k + 1]]
        ptr[s0 + 1 : s1 + 1] += at
        at += nc
    return np.concatenate([c[:nc] for c, nc in results]), at


def _world_plane(ts: TaskSet, t: int, k: int, frame: ModelFrame):
    """The sampling plane k of task t in world coordinates (lengths × scale)."""
    from csgnb.quadric.frames import FORM_GRAPH, FORMS, SamplingPlane, plane_kind

    s = frame.scale
    ax, bx, ay, by, ac = ts.coef[t, k]
    form = int(ts.form[t, k])
    if form == FORM_GRAPH:  # t_w = s t(x_w / s)
        c = np.array([ax / s, 0.0, ay / s, 0.0, ac * s])
    else:  # t_w² = s² t²(x_w / s)
        c = np.array([ax, bx * s, ay, by * s, ac * s * s])
    F = ts.frame[t, k]
    alpha = c[[0, 2, 4]] if form else np.full(3, np.nan)
    return SamplingPlane(k, frame.to_world(ts.origin[t, k]), F[:, 0].copy(), F[:, 1].copy(), F[:, 2].copy(),
                         alpha, plane_kind(form, c), c[[1, 3]], FORMS[form])


def _trace(ts: TaskSet, lv: _Leaves, frame: ModelFrame) -> SamplingTrace:
    s = frame.scale
    job = lv.TI[:, 0]
    pjob = lv.TJ
    t_of = ts.job_task
    pts = lv.TP
    k = ts.job_plane[pjob]
    task = t_of[pjob]
    sheet = ts.job_sheet[pjob]
    from csgnb.quadric.frames import plane_height

    world = np.empty((len(pts), 3))
    for i in range(len(pts)):
        c = ts.coef[task[i], k[i]]
        h = plane_height(int(ts.form[task[i], k[i]]), c[0], c[1], c[2], c[3], c[4], sheet[i], pts[i, 0], pts[i, 1])
        world[i] = ts.origin[task[i], k[i]] + ts.frame[task[i], k[i]] @ np.array([pts[i, 0], pts[i, 1], h])
    planes = {}
    for t in range(len(ts.quadric)):
        for kk in range(3):
            planes[(int(ts.quadric[t]), kk)] = _world_plane(ts, t, kk, frame)
    return SamplingTrace(
        ts.quadric[t_of[job]].astype(np.int64), ts.job_plane[job].astype(np.int64), ts.job_sheet[job],
        lv.TT.reshape(-1, 3, 2) * s, ts.job_uv[job].astype(np.int64), ts.job_quadrant[job],
        lv.TI[:, 2].astype(np.int64), lv.TI[:, 3].astype(np.int64), ts.quadric[task].astype(np.int64),
        k.astype(np.int64), sheet, pts[:, :2] * s, frame.to_world(world), pts[:, 2] * s, planes,
    )  # fmt: skip
