"""``sample_csg``: samples on a quadric CSG surface with the coverage guarantee of §4.2.

Pipeline: normal form (eq. 17–18) → a box per term (or the user's bounding sphere) → per quadric
a task (:mod:`.tasks`: regions, plane frames, pruned eq. 22 data) → the adaptive kernel
(:mod:`.kernel`) → one point cloud with deduplicated clip sets (:mod:`.cloud`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from csgnb.csg.bounds import box_is_empty, term_boxes
from csgnb.csg.normal_form import NormalForm, to_normal_form
from csgnb.errors import CsgnbError, GeometryError
from csgnb.sampling.cloud import SampleCloud, SamplingStats, SamplingTrace, deduplicate_clip_sets
from csgnb.sampling.kernel import OVERFLOW, emit_quadric, subdivide_quadric
from csgnb.sampling.tasks import QuadricTask, build_tasks

__all__ = ["sample_csg", "DISTORTION_MODES", "MIN_REGION", "ON_SURFACE"]

#: ``distortion=`` choices: per-region bounds of δ (eq. 13, §3.4) or the worst case √3 (§4.1).
DISTORTION_MODES = ("bounds", "sqrt3")

#: Regions still unclassified when their plane diameter falls below this fraction of the radius
#: are given up (``stats.unresolved``). This happens along curves where a quadric touches the
#: CSG surface without contributing area — a cap inside a capsule's sphere, the bottom disc of a
#: boss on a plate — where d_Qab is positive on both sides and zero on the curve, so no disc
#: cover can ever close. Only surface features smaller than this (1/256 of a splat; the paper
#: suggests discarding at 1/10) could be missed there.
MIN_REGION = 2.0**-8

#: A corner with |d_Qab| below this fraction of the model size is on a feature curve (closure of
#: the surface) and may carry a sample: rounding puts points of aligned curves at ±1e-16.
ON_SURFACE = 1e-12


def _bounds_box(bounds) -> np.ndarray:
    try:
        center, r = bounds
        c = np.asarray(center, dtype=np.float64).reshape(3)
        r = float(r)
    except (TypeError, ValueError) as exc:
        raise CsgnbError("bounds must be a bounding sphere (center (3,), radius)") from exc
    if not (np.all(np.isfinite(c)) and math.isfinite(r) and r > 0.0):
        raise GeometryError(f"bounding sphere needs a finite center and a positive radius, got {c.tolist()}, {r}")
    return np.concatenate([c - r, c + r])


def _check_radius(radius) -> float:
    r = float(radius)
    if not (math.isfinite(r) and r > 0.0):
        raise GeometryError(f"splat radius must be positive and finite, got {radius!r}")
    return r


def sample_csg(
    shape,
    radius: float,
    *,
    bounds=None,
    distortion: str = "bounds",
    min_size: float = 0.0,
    reduce_radius: bool = False,
    refine: bool = True,
    trace: bool = False,
    progress: bool = False,
    max_terms: int = 4096,
) -> SampleCloud:
    """Return samples on the surface of a CSG object with splat radius ``radius`` (§4.2, §5).

    Parameters
    ----------
    shape : Node, Quadric or NormalForm
        The CSG graph (``csgnb.csg``) or its normal form.
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
        Give samples of small regions the smaller radius that covers their region (less overdraw).
    refine : bool
        Split kept regions further (no distance queries) where their distortion varies, so that
        the sample lattice follows the local δ: fewer samples for the same guarantee.
    trace : bool
        Record leaves and distance evaluations (``SampleCloud.trace``, for Figure 9).
    progress : bool
        Show a tqdm bar over the quadrics.
    max_terms : int
        Limit for the normal form (see ``csgnb.csg.to_normal_form``).

    Returns
    -------
    SampleCloud

    Raises
    ------
    GeometryError
        If the object is empty, unbounded without ``bounds``, or has no surface in the bounds;
        if the radius is not positive; if a quadric is a paraboloid (not supported).
    """
    t0 = time.perf_counter()
    r = _check_radius(radius)
    if distortion not in DISTORTION_MODES:
        raise CsgnbError(f"distortion must be one of {DISTORTION_MODES}, got {distortion!r}")
    min_size = float(min_size)
    if not (math.isfinite(min_size) and min_size >= 0.0):
        raise CsgnbError(f"min_size must be ≥ 0 (a fraction of the radius), got {min_size}")
    nf = shape if isinstance(shape, NormalForm) else to_normal_form(shape, max_terms=max_terms)
    if nf.n_terms == 0:
        raise GeometryError("the CSG object is empty: its normal form has no term (e.g. A ∩ ¬A); nothing to sample")
    limit = None if bounds is None else _bounds_box(bounds)
    boxes, unbounded = term_boxes(nf, limit)
    if np.any(unbounded):
        i = int(np.flatnonzero(unbounded)[0])
        names = [nf.names[k] or f"quadric {k}" for k in nf.term(i)]
        raise GeometryError(
            f"term {i} of the normal form ({', '.join(names)}) is unbounded, or not bounded by its convex "
            "members; pass bounds=(center, radius), a bounding sphere of the region to sample"
        )
    if all(box_is_empty(b) for b in boxes):
        raise GeometryError("the CSG object is empty: every term of its normal form is empty" +
                            ("" if limit is None else " inside the bounding sphere"))
    tasks = build_tasks(nf, boxes, r)
    C = np.ascontiguousarray(nf.coefficients)
    iterator = tasks
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(tasks, desc="subdividing", unit="quadric")
    leaves = [_subdivide(C, task, r, min_size * r, distortion == "sqrt3", refine, trace) for task in iterator]
    return _emit_all(nf, C, tasks, leaves, r, reduce_radius, trace, t0)


class _Leaves:
    """Pass-1 output of one task (see ``kernel.subdivide_quadric``)."""

    def __init__(self, LF, LI, LA, TT, TI, TP, TJ, counters) -> None:
        self.LF, self.LI, self.LA, self.TT, self.TI, self.TP, self.TJ = LF, LI, LA, TT, TI, TP, TJ
        self.counters = counters
        self.samples = int(LI[:, 3].sum())


def _grown(a: np.ndarray, used: int) -> np.ndarray:
    b = np.empty((4 * a.shape[0],) + a.shape[1:], dtype=a.dtype)
    b[:used] = a[:used]
    return b


def _subdivide(C, task: QuadricTask, radius, min_size, sqrt3, refine, trace) -> _Leaves:
    jobs = len(task.job_plane)
    cap = 64 * jobs + 1024
    LF, LI = np.empty((cap, 16)), np.empty((cap, 6), dtype=np.int64)
    LA = np.empty(4 * cap, dtype=np.int64)
    tcap = 16 * jobs + 64 if trace else 1
    TT, TI = np.empty((tcap, 6)), np.empty((tcap, 5), dtype=np.int64)
    TP, TJ = np.empty((tcap, 3)), np.empty(tcap, dtype=np.int64)
    counters = np.zeros(5, dtype=np.int64)
    nl = nla = nt = npt = job = 0
    while True:
        nl, nla, nt, npt, job, overflow = subdivide_quadric(
            C, task.own, task.own_box, task.other_ptr, task.other_idx, task.rcap,
            task.origin, task.frame, task.alpha, task.flat,
            task.job_plane, task.job_sheet, task.job_tri, task.job_uv, task.job_quadrant,
            radius, min_size, MIN_REGION * radius, ON_SURFACE * task.scale, sqrt3, refine, trace,
            LF, LI, LA, TT, TI, TP, TJ, counters, job, nl, nla, nt, npt,
        )  # fmt: skip
        if overflow == OVERFLOW["none"]:
            break
        if overflow == OVERFLOW["leaves"]:
            LF, LI = _grown(LF, nl), _grown(LI, nl)
        elif overflow == OVERFLOW["clip_lists"]:
            LA = _grown(LA, nla)
        elif overflow == OVERFLOW["trace_leaves"]:
            TT, TI = _grown(TT, nt), _grown(TI, nt)
        else:
            TP, TJ = _grown(TP, npt), _grown(TJ, npt)
    return _Leaves(LF[:nl], LI[:nl], LA[:nla], TT[:nt], TI[:nt], TP[:npt], TJ[:npt], counters)


def _emit_all(nf: NormalForm, C, tasks, leaves, radius: float, reduce_radius: bool, trace: bool, t0: float):
    counts = [lv.samples for lv in leaves]
    n = int(sum(counts))
    if n == 0:
        raise GeometryError(
            "the CSG surface is empty (inside the bounds): no point of any quadric lies on it; "
            "check the operands, or the bounding sphere"
        )
    positions = np.empty((n, 3))
    normals = np.empty((n, 3))
    radii = np.empty(n)
    clip_count = np.empty(n, dtype=np.int32)
    ids = np.empty(n, dtype=np.int32)
    cidx = np.empty(1 << 16, dtype=np.int64)
    at = nc = 0
    for task, lv, c in zip(tasks, leaves, counts, strict=True):
        if c == 0:
            continue
        leaf, end = 0, at
        while True:
            leaf, end, nc = emit_quadric(
                C, task.index, task.origin, task.frame, task.alpha, task.job_plane, task.job_sheet,
                lv.LF, lv.LI, lv.LA, radius, reduce_radius, positions, normals, radii, clip_count, cidx, leaf, end, nc,
            )  # fmt: skip
            if leaf >= len(lv.LI):
                break
            need = nc + int(lv.LI[leaf, 3] * lv.LI[leaf, 5])
            grown = np.empty(max(4 * len(cidx), need), dtype=np.int64)
            grown[:nc] = cidx[:nc]
            cidx = grown
        ids[at : at + c] = task.index
        at += c
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(clip_count, out=ptr[1:])
    start, count, buf = deduplicate_clip_sets(ptr, cidx[:nc])
    counters = np.sum([lv.counters for lv in leaves], axis=0)
    tr = _trace(tasks, leaves) if trace else None
    stats = SamplingStats(
        samples=n,
        distance_queries=int(counters[0]),
        clip_indices=len(buf),
        regions=int(counters[1]),
        unresolved=int(counters[2]),
        quadrics=len(nf),
        sampled_quadrics=len(tasks),
        terms=nf.n_terms,
        seconds=time.perf_counter() - t0,
    )
    return SampleCloud(positions, normals, ids, radii, start, count, buf, radius, nf, stats, tr)


def _trace(tasks, leaves) -> SamplingTrace:
    cols: dict[str, list] = {k: [] for k in (
        "lq", "lp", "ls", "lt", "la", "lquad", "lst", "ld", "pq", "pp", "ps", "pxy", "pw", "pd")}
    planes = {}
    for task, lv in zip(tasks, leaves, strict=True):
        tri, info, pts, pjob = lv.TT.reshape(-1, 3, 2), lv.TI, lv.TP, lv.TJ
        job = info[:, 0]
        cols["lq"].append(np.full(len(info), task.index))
        cols["lp"].append(info[:, 4])
        cols["ls"].append(task.job_sheet[job])
        cols["lt"].append(tri)
        cols["la"].append(info[:, 1])
        cols["lquad"].append(task.job_quadrant[job])
        cols["lst"].append(info[:, 2])
        cols["ld"].append(info[:, 3])
        k = task.job_plane[pjob]
        sheet = task.job_sheet[pjob]
        cols["pq"].append(np.full(len(pts), task.index))
        cols["pp"].append(k)
        cols["ps"].append(sheet)
        cols["pxy"].append(pts[:, :2])
        cols["pd"].append(pts[:, 2])
        al = task.alpha[k]
        h2 = al[:, 0] * pts[:, 0] ** 2 + al[:, 1] * pts[:, 1] ** 2 + al[:, 2]
        t = sheet * np.sqrt(np.maximum(h2, 0.0))
        local = np.column_stack([pts[:, 0], pts[:, 1], t])
        cols["pw"].append(task.origin[k] + np.einsum("nij,nj->ni", task.frame[k], local))
        for p in range(3):
            planes[(task.index, p)] = (task.origin[p], task.frame[p], task.alpha[p])

    def cat(key, shape):
        return np.concatenate(cols[key]) if cols[key] else np.empty(shape)

    return SamplingTrace(
        cat("lq", 0).astype(np.int64), cat("lp", 0).astype(np.int64), cat("ls", 0), cat("lt", (0, 3, 2)),
        cat("la", 0).astype(np.int64), cat("lquad", (0, 2)), cat("lst", 0).astype(np.int64),
        cat("ld", 0).astype(np.int64), cat("pq", 0).astype(np.int64), cat("pp", 0).astype(np.int64),
        cat("ps", 0), cat("pxy", (0, 2)), cat("pw", (0, 3)), cat("pd", 0), planes,
    )  # fmt: skip
