"""Landmarks (the paper's "marker poses", section II-B): mean-shift modes of human descriptors.

The paper extracts its landmark set from recorded human motion with mean-shift clustering
(Comaniciu & Meer 2002) and gives each landmark its robot pose by IK. ``build_landmarks`` does the
same: the training points are the descriptors (``skeleton.descriptor``, default ``bones="upper"``:
15 numbers) of the *valid* frames (``datasets.valid_descriptors``), each landmark's human side
is a mode (``meanshift.mean_shift``; the algorithm, kernels and merge rule are described
there), its robot side the robot's IK of the mode (``Robot.ik``; a chain's: ``Chain.ik``).
The landmark count is set through the bandwidth
(``meanshift.find_bandwidth``).

On MSR Action3D subjects 1, 3, 5, 7, 9 (all 20 actions: 292 sequences, 11,280 valid frames) most
landmarks at the larger counts are single frames: isolated frames (nearest neighbour farther than
~2 h) are modes of the Gaussian density by themselves, while the densest mode (arms down) gathers
about half the frames (5726 of 11,280 at h = 0.1354, 1635 landmarks).

Measured times (bandwidth search to 1644 / 961 / 86 landmarks; the earlier figures there also
give the whole build with the IK): section "Mean shift / landmark build times" of
``benchmarks/RESULTS.md``; rerun the search timings with ``benchmarks/bench_build.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypedDict

import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.human.descriptors import valid_descriptors
from jaxproj.projection.meanshift import (
    MAX_ITER,
    MERGE_FRACTION,
    TOL,
    Kernel,
    check_options,
    find_bandwidth,
    mean_shift,
)
from jaxproj.robots import Chain, Robot, get


class _MeanShiftOptions(TypedDict):
    """The options ``build_landmarks`` passes on to ``find_bandwidth`` / ``mean_shift``."""

    kernel: Kernel
    max_iter: int
    tol: float
    merge_fraction: float


@dataclass(frozen=True)
class Landmarks:
    """Sparse human <-> robot correspondence: mean-shift modes and their IK poses.

    Attributes:
      human: ``(K, 3 * n_bones)`` float32 descriptor modes (``skeleton.descriptor`` layout; mean
        shift averages unit vectors, so each bone vector is slightly shorter than 1).
      robot: ``(K, n)`` float32 IK of ``human`` (the robot's driven joints, or a chain's; rad).
      counts: ``(K,)`` int64 training frames that converged to each landmark.
      bandwidth: mean-shift bandwidth used.
      n_frames: training frames used (valid frames only).
      kernel: mean-shift kernel.
      bones: the descriptor's bone subset.
      mirror: whether the descriptor was mirrored.
    """

    human: np.ndarray
    robot: np.ndarray
    counts: np.ndarray
    bandwidth: float
    n_frames: int
    kernel: str = "gaussian"
    bones: str | tuple[str, ...] = "upper"
    mirror: bool = False

    @property
    def n_landmarks(self) -> int:
        """``K``."""
        return int(self.human.shape[0])


def build_landmarks(
    sequences_or_points: Any,
    *,
    target: int | None = None,
    bandwidth: float | None = None,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    chain: Chain | None = None,
    robot: Robot | str | None = None,
    kernel: Kernel = "gaussian",
    rel_tol: float = 0.05,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    merge_fraction: float = MERGE_FRACTION,
) -> Landmarks:
    """Landmarks (the paper's marker poses) of training motions: mean-shift modes + their IK.

    Give exactly one of ``target`` (a landmark count, reached by ``find_bandwidth`` within
    ``rel_tol``) or ``bandwidth`` (one ``mean_shift`` run).

    Args:
      sequences_or_points: training data, as ``datasets.valid_descriptors`` takes it.
      target: wanted number of landmarks.
      bandwidth: mean-shift bandwidth.
      bones, mirror: descriptor options.
      chain: landmarks of one kinematic chain (``Robot.chains``): mean shift runs on the
        chain's columns of the descriptor only, and the robot side is the chain's joints
        (``Chain.ik``). ``None``: the whole descriptor and all driven joints (``Robot.ik``).
      robot: the robot (a ``Robot`` or a registered name; ``None``: the default robot).
      kernel, rel_tol, max_iter, tol, merge_fraction: as in ``find_bandwidth`` / ``mean_shift``.

    Returns:
      ``Landmarks`` with ``human (K, m)`` (the chain's columns, or the whole descriptor),
      ``robot (K, n)`` its IK (the chain's joints, or all driven joints), ``counts (K,)``.

    Raises:
      ConfigError: both or neither of ``target`` / ``bandwidth``; bad data or options (the
        options are checked before the descriptors are computed).
    """
    if (target is None) == (bandwidth is None):
        raise ConfigError("give exactly one of target (landmark count) or bandwidth")
    # options first, before the descriptors are computed (the target's upper bound, N, is
    # checked by find_bandwidth once the descriptors are known)
    check_options(kernel, max_iter, tol, merge_fraction, bandwidth=bandwidth)
    if target is not None and int(target) < 1:
        raise ConfigError(f"target must be >= 1, got {target}")
    spec = get(robot)
    points = valid_descriptors(sequences_or_points, bones=bones, mirror=mirror)
    if chain is not None:
        points = np.ascontiguousarray(points[:, list(spec.chain_columns(chain, bones))])
    options = _MeanShiftOptions(
        kernel=kernel, max_iter=max_iter, tol=tol, merge_fraction=merge_fraction
    )
    if target is not None:
        h, res = find_bandwidth(points, target, rel_tol=rel_tol, **options)
    else:
        assert bandwidth is not None  # checked above: exactly one of target / bandwidth
        res = mean_shift(points, bandwidth, **options)
        h = res.bandwidth
    if chain is None:
        robot_pose = np.asarray(spec.solve_ik(jnp.asarray(res.modes), bones), np.float32)
    else:
        robot_pose = np.asarray(chain.solve(res.modes), np.float32)
    return Landmarks(
        human=res.modes,
        robot=robot_pose,
        counts=res.counts,
        bandwidth=h,
        n_frames=int(points.shape[0]),
        kernel=kernel,
        bones=bones,
        mirror=mirror,
    )
