"""Adaptive sampling of quadric CSG surfaces with a coverage guarantee (paper §4.2, §6).

:func:`sample_csg` turns a CSG graph (:mod:`csgnb.csg`) into a :class:`SampleCloud`: points on
the CSG surface with normals, quadric ids, radii and deduplicated clip sets, such that every
point of the surface has a sample on the same quadric within the splat radius. Modules: the
sampling domains of a quadric (:mod:`.domains`), region geometry kernels (:mod:`.geometry`),
per-quadric tasks (:mod:`.tasks`), the adaptive kernel (:mod:`.kernel`), the output
(:mod:`.cloud`) and the driver (:mod:`.sampler`).
"""

from csgnb.sampling.cloud import SampleCloud, SamplingStats, SamplingTrace, deduplicate_clip_sets
from csgnb.sampling.domains import domain_cache_clear, quadric_jobs
from csgnb.sampling.kernel import COUNTERS, STATUS
from csgnb.sampling.sampler import (
    BYTES_PER_SAMPLE,
    DEFAULT_MAX_SAMPLES,
    DISTORTION_MODES,
    MIN_REGION,
    estimate_samples,
    sample_csg,
)
from csgnb.sampling.tasks import TaskSet, build_task_set, build_tasks

__all__ = [
    "sample_csg",
    "SampleCloud",
    "SamplingStats",
    "SamplingTrace",
    "STATUS",
    "COUNTERS",
    "DEFAULT_MAX_SAMPLES",
    "BYTES_PER_SAMPLE",
    "estimate_samples",
    "TaskSet",
    "build_task_set",
    "DISTORTION_MODES",
    "MIN_REGION",
    "deduplicate_clip_sets",
    "build_tasks",
    "domain_cache_clear",
    "quadric_jobs",
]
