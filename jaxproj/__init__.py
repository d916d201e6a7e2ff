"""jaxproj: human-to-humanoid motion projection from sparsely sampled correspondence, in JAX.

Pipeline (one module per stage): ``readers`` / ``datasets`` / ``skeleton`` (data and the body-frame
bone descriptor) -> ``robot`` / ``ik`` (NAO H25 model and the analytic IK ground truth) ->
``meanshift`` (generic mean shift, bandwidth search) -> ``landmarks`` (mean-shift modes of the
training descriptors + their IK) -> ``kernels`` (ELM bank) -> ``search`` (kNN) -> ``projection``
(relaxed / full objectives; one projector per kinematic chain, stacked) -> ``smoothing`` /
``streaming`` -> ``retarget`` (whole motions, one compiled call) -> ``feasible`` (joint, speed
and acceleration limits) -> ``motion_io`` (NPZ / CSV / NAOqi JSON) and ``render`` (videos);
``engine`` holds the public build / project / save / load API (several devices: ``shard_map``)
and ``distributed`` spreads projection over hosts; ``metrics`` / ``evaluate`` score against the
IK. ``synthetic`` (the paper's basic poses and motions) and ``experiments`` (the paper's studies
on them) reproduce the paper's section IV.

Jit, precision, configs, errors and progress follow one policy each, stated in the README's
Development section (jit: ``jaxproj._internal.jit``).
"""

__version__ = "0.1.0"

from jaxproj.motion.smoothing import SmoothingParams, smooth, smooth_batch
from jaxproj.projection.api import BuildConfig, Model, build, load, project, save
from jaxproj.projection.objectives import FullConfig

__all__ = [
    "BuildConfig",
    "FullConfig",
    "Model",
    "SmoothingParams",
    "__version__",
    "build",
    "load",
    "project",
    "save",
    "smooth",
    "smooth_batch",
]
