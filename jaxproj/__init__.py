"""jaxproj: human-to-humanoid motion projection from sparsely sampled correspondence, in JAX.

The package is layered; each layer imports only the ones before it (``tests/test_layers.py``):

1. ``errors``, ``_internal`` (jit policy, the one atomic NPZ writer, progress bars);
2. ``human`` (Kinect skeleton, body frame, bone descriptor), ``io`` (recording formats, the
   bundled datasets, motion files), ``robots`` (the ``Robot`` spec and the registry of robots);
3. ``projection`` (mean shift, landmarks, the ELM bank, k-NN search, relaxed and full objectives,
   build / project / save / load; GPU kernels under ``projection.ops``);
4. ``motion`` (the one pipeline from a recording to playable angles: descriptor -> project ->
   fill invalid frames -> smooth -> clip -> feasible; ``retarget`` and ``streaming``);
5. ``eval`` (metrics, forward kinematics, baselines, evaluate, MJX rollout), ``viz`` (render,
   report, notebook helpers), ``paper`` (the paper's section IV and the demo), ``cli``;
   ``testing`` (the float64 reference) and ``timing`` are tools beside them.

This module is the public surface: read a recording, build or load a model, project poses,
retarget motions, save and load motion files.
"""

__version__ = "0.2.0"

import jaxproj._internal.mujoco_gl  # noqa: F401  (first: imports MuJoCo whatever MUJOCO_GL says)
from jaxproj import errors, robots
from jaxproj.io.motion_files import Motion, load_motion, save_motion
from jaxproj.io.readers import Recording
from jaxproj.io.readers import read_skeleton as read
from jaxproj.motion import streaming
from jaxproj.motion.offline import OfflineSmoothing
from jaxproj.motion.retarget import RetargetResult, retarget, retarget_many
from jaxproj.motion.smoothing import SmoothingParams, smooth, smooth_batch
from jaxproj.projection.api import BuildConfig, Model, build, load, project, save
from jaxproj.projection.config import FullConfig

__all__ = [
    "BuildConfig",
    "FullConfig",
    "Model",
    "Motion",
    "OfflineSmoothing",
    "Recording",
    "RetargetResult",
    "SmoothingParams",
    "__version__",
    "build",
    "errors",
    "load",
    "load_motion",
    "project",
    "read",
    "retarget",
    "retarget_many",
    "robots",
    "save",
    "save_motion",
    "smooth",
    "smooth_batch",
    "streaming",
]
