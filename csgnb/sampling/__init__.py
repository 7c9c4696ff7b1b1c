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
from csgnb.sampling.kernel import STATUS
from csgnb.sampling.sampler import DISTORTION_MODES, MIN_REGION, sample_csg
from csgnb.sampling.tasks import build_tasks

__all__ = [
    "sample_csg",
    "SampleCloud",
    "SamplingStats",
    "SamplingTrace",
    "STATUS",
    "DISTORTION_MODES",
    "MIN_REGION",
    "deduplicate_clip_sets",
    "build_tasks",
    "domain_cache_clear",
    "quadric_jobs",
]
