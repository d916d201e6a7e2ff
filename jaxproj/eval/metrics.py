"""Evaluation metrics: how far a projected pose is from the IK truth, and where the error is.

Every function takes the ``robot: Robot`` (``jaxproj.robots``; no default) whose joint
order and driven joints the angles follow: ``(F, n_driven)`` driven angles
(``robot.driven_joints`` order) or ``(F, n_joints)`` configurations (``robot.joint_names``).

Joint space, in degrees over ``robot.driven_joints``, against the robot's analytic IK:

* ``frame_errors``: the paper's per-frame ``M_max = max_j |r*_j - r_gt_j|`` and
  ``M_avg = mean_j |r*_j - r_gt_j|`` (section IV): the headline numbers, summarised by
  ``describe`` (mean / median / p95 / max);
* ``joint_percentiles``: p50 / p95 of ``|r*_j - r_gt_j|`` per driven joint;
* ``confidence_deciles``: error against the per-frame confidence, by decile;
* ``lag_frames``: how many frames a motion trails the IK's (best cross-correlation shift);
* ``m_max_without``: ``M_max`` over the driven joints minus some, by default the robot's
  ``loose_joints`` (the default robot's: the two elbow-yaw joints). With a near-straight arm the
  elbow's yaw turns the forearm about its own length: the IK truth's elbow yaw is then
  ill-conditioned (set by Kinect noise, blended towards 0 below 30 deg of human elbow flexion, see
  the default robot's ``ik`` module), and a large elbow-yaw error there can be a small error of the
  pose.

Task space, from forward kinematics of the robot's MJCF (``robot.mjcf``, fixed mount: base welded
at the origin, so positions are in the torso frame), per arm (``robot.mjcf.arm_sites``: side ->
shoulder, elbow, wrist sites; ``sides(robot)``), projected pose against IK pose:

* ``hand_cm``: distance between the wrist points (the default robot's ``l_wrist`` /
  ``r_wrist``, the origin of the wrist body, where the hand attaches, on the forearm axis; the
  undriven wrist yaw cannot move it). Not the ``l_hand`` / ``r_hand`` sites of
  ``rollout.hand_error_cm``, which sit 1.2 cm off the forearm axis and so move with the elbow yaw
  even when the elbow is straight;
* ``elbow_cm``: distance between the elbow points;
* ``upper_arm_deg``: angle between the shoulder -> elbow directions (the default robot's: the
  physical segment, 8.13 deg off the elbow-yaw axis by the ElbowOffsetY, the segment the IK makes
  parallel to the human upper arm);
* ``forearm_deg``: angle between the elbow -> wrist directions.

Each is summarised like ``M_max`` (``describe``: mean / median / p95 / max / n). Angles between
directions are ``atan2(|a x b|, a . b)`` (accurate at small angles, unlike ``arccos``).

Numerics: forward kinematics and the task-space errors run in float32 (m, rad); the summaries
(``task_space_errors``, ``summarize_errors``) are in cm and degrees. The joint-space errors are
computed in float64 from the given angles (as the headline ``frame_errors`` always was).

FK: ``arm_points`` runs MJX (``mjx.kinematics``, JAX implementation) vmapped over fixed-size
batches of ``FK_BATCH`` frames (the last one padded), so one compile per robot serves every frame
count. It runs on a copy of the MJCF with the bodies of ``robot.mjcf.fk_without`` (the default
robot's: the head and leg subtrees) and the actuators, equality and contact excludes (which
kinematics never reads) removed (``arm_model``): those bodies cannot move an arm site (the arms hang
off the torso), and without them the program compiles in half the time and runs ~4x faster
(``jaxproj.eval.fk``). ``tests/eval/test_metrics.py`` checks it against CPU MuJoCo on the whole
fixed-mount model to 1e-5 m.
Measured on this project's shared 2-core CPU (25,000 random configurations, median of 5): arm model
3.2 s compile, then 0.025 s per 10,000 frames; the whole model 7.0 s compile, 0.094 s per 10,000;
CPU ``mj_kinematics`` in a Python loop, no compile, 0.087 s per 10,000. So the one compile per
process (~3 s) is the cost: warm, MJX is the fastest; for a single cold call the CPU loop would be.

Strict promotion: the tests trace everything under strict dtype / rank promotion; MJX's own
internals rely on implicit promotion, so the ``mjx.kinematics`` call alone is traced inside
``jax.numpy_dtype_promotion("standard")`` / ``jax.numpy_rank_promotion("allow")`` (in
``jaxproj.eval.fk``; as in ``jaxproj.eval.rollout``). The rest is strict-clean.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import jax
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.eval.fk import FK_BATCH, arm_model, arm_points, check_angles
from jaxproj.projection.confidence import LOW_CONFIDENCE
from jaxproj.robots import Robot

__all__ = ["FK_BATCH", "TASK_METRICS", "ArmErrors", "arm_errors", "arm_model", "arm_points",
           "describe", "frame_errors", "joint_errors_deg", "joint_percentiles", "m_max_without",
           "sides", "summarize_errors", "task_space_errors"]  # fmt: skip


def sides(robot: Robot) -> tuple[str, ...]:
    """The robot's arms (``robot.mjcf.arm_sites`` keys; e.g. ``("left", "right")``): the order
    of the side axis of ``arm_points`` / ``ArmErrors``. ConfigError for a robot without MJCF."""
    return tuple(robot.require_mjcf().arm_sites)


TASK_METRICS: tuple[str, ...] = ("hand_cm", "elbow_cm", "upper_arm_deg", "forearm_deg")
"""The task-space summaries per side, in the order of ``ArmErrors``' fields."""

# ------------------------------------------------------------------------------ joint space


def frame_errors(pred: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's per-frame metrics, in degrees.

    Args:
      pred: ``(F, n)`` angles, rad.
      truth: ``(F, n)`` angles, rad (same joints, same order).

    Returns:
      ``M_max (F,)`` and ``M_avg (F,)``: max and mean over the ``n`` joints of
      ``|pred - truth|``, float64 degrees.
    """
    err = np.degrees(np.abs(np.asarray(pred, np.float64) - np.asarray(truth, np.float64)))
    return err.max(axis=1), err.mean(axis=1)


def lag_frames(
    pred: np.ndarray,
    truth: np.ndarray,
    lengths: np.ndarray,
    valid: np.ndarray | None = None,
    max_shift: int = 5,
) -> float:
    """How many frames ``pred`` trails ``truth``: the shift of best cross-correlation, pooled.

    For each whole shift ``k`` in ``[-max_shift, max_shift]`` the mean over every motion's
    frames ``t`` (both ``t`` and ``t + k`` within its length and valid) of
    ``|pred[t + k] - truth[t]|^2`` (all joints); the least one's ``k``, refined to a fraction of
    a frame by the parabola through it and its neighbours. Positive: ``pred`` is late (a
    causal smoother); 0: no lag.

    Args:
      pred, truth: ``(S, T, n)`` padded motions (rad).
      lengths: ``(S,)`` true lengths.
      valid: optional ``(S, T)`` bool; ``None``: every frame within its length.
      max_shift: the largest shift tried, frames.

    Returns:
      The lag in frames (float); 0.0 when no motion is long enough to shift.
    """
    pred, truth = np.asarray(pred, np.float64), np.asarray(truth, np.float64)
    n_t = pred.shape[1]
    ok = np.arange(n_t)[None, :] < np.asarray(lengths)[:, None]
    if valid is not None:
        ok = ok & np.asarray(valid, bool)
    shifts = np.arange(-max_shift, max_shift + 1)
    cost = np.full(len(shifts), np.inf)
    for i, k in enumerate(shifts.tolist()):
        lo, hi = max(0, -k), min(n_t, n_t - k)
        if hi <= lo:
            continue
        both = ok[:, lo:hi] & ok[:, lo + k : hi + k]
        if both.any():
            d = pred[:, lo + k : hi + k] - truth[:, lo:hi]
            cost[i] = float(np.sum(d[both] ** 2) / both.sum())
    if not np.isfinite(cost).any():
        return 0.0
    i = int(np.argmin(cost))
    if 0 < i < len(shifts) - 1 and np.isfinite(cost[i - 1]) and np.isfinite(cost[i + 1]):
        curve = cost[i - 1] - 2 * cost[i] + cost[i + 1]
        if curve > 0:
            return float(shifts[i] + 0.5 * (cost[i - 1] - cost[i + 1]) / curve)
    return float(shifts[i])


def confidence_deciles(
    confidence: np.ndarray, m_max: np.ndarray, m_avg: np.ndarray, over: float = 30.0
) -> dict:
    """Error against confidence: the frames in ten equal groups from the least to the most
    confident.

    Args:
      confidence: ``(F,)`` per-frame confidence (``projection.confidence``).
      m_max, m_avg: ``(F,)`` the frames' errors, degrees.
      over: the M_max (deg) a frame must exceed to count as a gross error.

    Returns:
      ``{"deciles": [{"confidence_max", "M_max_median", "M_max_p95", "M_avg_median",
      "share_over"}, ...] (least confident first), "over_deg", "share_over" (all frames),
      "low_share" (frames below ``LOW_CONFIDENCE``), "low_recall" (share of the gross errors
      among them), "worst_decile_share_over"}``.
    """
    conf = np.asarray(confidence, np.float64)
    m_max, m_avg = np.asarray(m_max, np.float64), np.asarray(m_avg, np.float64)
    order = np.argsort(conf, kind="stable")
    gross = m_max > over
    rows = []
    for part in np.array_split(order, 10):
        if len(part) == 0:
            continue
        rows.append({
            "confidence_max": float(conf[part].max()),
            "M_max_median": float(np.median(m_max[part])),
            "M_max_p95": float(np.percentile(m_max[part], 95)),
            "M_avg_median": float(np.median(m_avg[part])),
            "share_over": float(gross[part].mean()),
        })  # fmt: skip
    low = conf < LOW_CONFIDENCE
    return {
        "deciles": rows,
        "over_deg": over,
        "share_over": float(gross.mean()) if len(conf) else 0.0,
        "low_share": float(low.mean()) if len(conf) else 0.0,
        "low_recall": float(gross[low].sum() / max(int(gross.sum()), 1)),
        "worst_decile_share_over": rows[0]["share_over"] if rows else 0.0,
    }


def describe(x: np.ndarray) -> dict[str, float]:
    """mean / median / p95 / max / n of a 1-D array (NaN-free; empty -> NaN-free zeros)."""
    if len(x) == 0:
        return {"mean": 0.0, "median": 0.0, "p95": 0.0, "max": 0.0, "n": 0}
    return {
        "mean": float(np.mean(x)),
        "median": float(np.median(x)),
        "p95": float(np.percentile(x, 95)),
        "max": float(np.max(x)),
        "n": int(len(x)),
    }


def _pair(
    pred: np.ndarray | jax.Array, truth: np.ndarray | jax.Array, robot: Robot
) -> tuple[np.ndarray, ...]:
    p, t = check_angles(pred, "pred", robot), check_angles(truth, "truth", robot)
    if p.shape != t.shape:
        raise ConfigError(f"pred and truth must have the same shape, got {p.shape} and {t.shape}")
    return p, t


def _driven(a: np.ndarray, robot: Robot) -> np.ndarray:
    """``(F, n_driven | n_joints)`` -> ``(F, n_driven)`` driven joints."""
    return a if a.shape[1] == robot.n_driven else a[:, robot.driven_index]


def joint_errors_deg(
    pred: np.ndarray | jax.Array, truth: np.ndarray | jax.Array, *, robot: Robot
) -> np.ndarray:
    """``|pred - truth|`` per driven joint, float64 degrees.

    Args:
      pred, truth: ``(F, n_driven)`` driven angles (``robot.driven_joints`` order) or
        ``(F, n_joints)`` configurations (``robot.joint_names`` order), rad, both the same shape.
      robot: the robot.

    Returns:
      ``(F, n_driven)`` in ``robot.driven_joints`` order.

    Raises:
      ConfigError: bad or different shapes, non-finite angles.
    """
    p, t = _pair(pred, truth, robot)
    return np.degrees(np.abs(_driven(p, robot) - _driven(t, robot)))


def _percentiles(err: np.ndarray, robot: Robot) -> dict[str, dict[str, float]]:
    if len(err) == 0:
        return {j: {"p50": 0.0, "p95": 0.0} for j in robot.driven_joints}
    p50, p95 = np.percentile(err, [50, 95], axis=0)
    return {
        j: {"p50": float(a), "p95": float(b)}
        for j, a, b in zip(robot.driven_joints, p50, p95, strict=True)
    }


def joint_percentiles(
    pred: np.ndarray | jax.Array, truth: np.ndarray | jax.Array, *, robot: Robot
) -> dict[str, dict[str, float]]:
    """p50 / p95 of the error of each driven joint, degrees.

    Args:
      pred, truth: ``(F, n_driven)`` driven angles or ``(F, n_joints)`` configurations, rad.
      robot: the robot.

    Returns:
      ``{joint: {"p50": deg, "p95": deg}}`` for every joint of ``robot.driven_joints`` (zeros
      when ``F = 0``).

    Raises:
      ConfigError: bad or different shapes, non-finite angles.
    """
    return _percentiles(joint_errors_deg(pred, truth, robot=robot), robot)


def _keep_columns(exclude: Sequence[str], robot: Robot) -> np.ndarray:
    driven = robot.driven_joints
    unknown = [j for j in exclude if j not in driven]
    if unknown:
        raise ConfigError(f"not driven joints: {unknown}; use names of {driven}")
    keep = np.array([j not in exclude for j in driven])
    if not keep.any():
        raise ConfigError("m_max_without: every driven joint is excluded")
    return keep


def m_max_without(
    pred: np.ndarray | jax.Array,
    truth: np.ndarray | jax.Array,
    exclude: Sequence[str] | None = None,
    *,
    robot: Robot,
) -> np.ndarray:
    """Per-frame ``M_max`` over the driven joints not in ``exclude``.

    Args:
      pred, truth: ``(F, n_driven)`` driven angles or ``(F, n_joints)`` configurations, rad.
      exclude: names of driven joints to leave out (``None``, the default: the robot's
        ``loose_joints``; the default robot's: the two elbow-yaw joints).
      robot: the robot.

    Returns:
      ``(F,)`` float64 degrees.

    Raises:
      ConfigError: bad shapes or angles, a name that is not a driven joint, nothing left.
    """
    keep = _keep_columns(robot.loose_joints if exclude is None else exclude, robot)
    return joint_errors_deg(pred, truth, robot=robot)[:, keep].max(axis=1)


# ------------------------------------------------------------------------------- task space


class ArmErrors(NamedTuple):
    """Task-space errors per frame and side (columns in ``arm_sites`` order), float32.

    Attributes:
      hand: ``(F, n_sides)`` distance between the wrist points, m.
      elbow: ``(F, n_sides)`` distance between the elbow points, m.
      upper_arm: ``(F, n_sides)`` angle between the shoulder -> elbow directions, rad.
      forearm: ``(F, n_sides)`` angle between the elbow -> wrist directions, rad.
    """

    hand: np.ndarray
    elbow: np.ndarray
    upper_arm: np.ndarray
    forearm: np.ndarray


def _check_points(x: np.ndarray | jax.Array, name: str) -> np.ndarray:
    a = np.asarray(x, np.float32)
    if a.ndim != 4 or a.shape[2:] != (3, 3):
        raise ConfigError(f"{name} must have shape (F, n_sides, 3, 3) (arm_points), got {a.shape}")
    return a


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., 3)`` x2 -> ``(...)`` float32 angle, rad, ``atan2(|a x b|, a . b)``."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.arctan2(cross, np.sum(a * b, axis=-1)).astype(np.float32)


def arm_errors(
    pred_points: np.ndarray | jax.Array, truth_points: np.ndarray | jax.Array
) -> ArmErrors:
    """Task-space errors between two sets of ``arm_points``.

    Args:
      pred_points, truth_points: ``(F, n_sides, 3, 3)`` from ``arm_points``, m.

    Returns:
      ``ArmErrors`` of ``(F, n_sides)`` float32 arrays (m, rad).

    Raises:
      ConfigError: bad or different shapes.
    """
    p = _check_points(pred_points, "pred_points")
    t = _check_points(truth_points, "truth_points")
    if p.shape != t.shape:
        raise ConfigError(f"point sets differ in shape: {p.shape} and {t.shape}")
    dist = np.linalg.norm(p - t, axis=-1)  # (F, n_sides, 3): shoulder, elbow, wrist
    up_p, up_t = p[:, :, 1] - p[:, :, 0], t[:, :, 1] - t[:, :, 0]
    fo_p, fo_t = p[:, :, 2] - p[:, :, 1], t[:, :, 2] - t[:, :, 1]
    return ArmErrors(
        hand=dist[:, :, 2].astype(np.float32),
        elbow=dist[:, :, 1].astype(np.float32),
        upper_arm=_angle_between(up_p, up_t),
        forearm=_angle_between(fo_p, fo_t),
    )


def _summarize_arm(err: ArmErrors, robot: Robot) -> dict[str, dict[str, dict[str, float]]]:
    scale = {"hand_cm": 100.0, "elbow_cm": 100.0}
    out: dict[str, dict[str, dict[str, float]]] = {}
    for i, side in enumerate(robot.require_mjcf().arm_sites):
        out[side] = {}
        for key, values in zip(TASK_METRICS, err, strict=True):
            v = values[:, i].astype(np.float64)
            out[side][key] = describe(v * scale[key] if key in scale else np.degrees(v))
    return out


def _points_for(
    angles: np.ndarray | jax.Array,
    points: np.ndarray | jax.Array | None,
    robot: Robot,
    name: str = "truth",
) -> np.ndarray:
    """``arm_points(angles)``, or the given ``points`` of them checked against their frames."""
    if points is None:
        return arm_points(angles, robot=robot)
    t = _check_points(points, f"{name}_points")
    if len(t) != len(angles):
        raise ConfigError(f"{name}_points has {len(t)} frames, {name} {len(angles)}")
    return t


def task_space_errors(
    pred: np.ndarray | jax.Array,
    truth: np.ndarray | jax.Array,
    *,
    truth_points: np.ndarray | jax.Array | None = None,
    robot: Robot,
) -> dict[str, dict[str, dict[str, float]]]:
    """Task-space errors of ``pred`` against ``truth``, summarised per side.

    Args:
      pred, truth: ``(F, n_joints)`` configurations (or ``(F, n_driven)`` driven angles, the
        rest at the standing posture), rad, both the same shape.
      truth_points: ``arm_points(truth)`` when already computed (one FK of the truth serves
        every method), else computed here.
      robot: the robot.

    Returns:
      ``{side: {"hand_cm" | "elbow_cm" | "upper_arm_deg" | "forearm_deg": describe}}`` for
      each side of ``robot.mjcf.arm_sites`` (cm / degrees; see the module doc).

    Raises:
      ConfigError: bad or different shapes, non-finite angles, ``truth_points`` not matching.
    """
    _pair(pred, truth, robot)
    t_pts = _points_for(truth, truth_points, robot)
    return _summarize_arm(arm_errors(arm_points(pred, robot=robot), t_pts), robot)


def summarize_errors(
    pred: np.ndarray | jax.Array,
    truth: np.ndarray | jax.Array,
    *,
    truth_points: np.ndarray | jax.Array | None = None,
    pred_points: np.ndarray | jax.Array | None = None,
    robot: Robot,
) -> dict:
    """Every metric of one method, JSON-ready (plain floats and ints).

    Args:
      pred, truth: ``(F, n_driven)`` driven angles (``robot.driven_joints`` order; the task
        space puts the other joints at the standing posture) or ``(F, n_joints)``
        configurations, rad.
      truth_points: ``arm_points(truth)`` when already computed (pass it to score several
        methods against one truth with one FK of the truth).
      pred_points: ``arm_points(pred)`` when already computed (the caller uses them too).
      robot: the robot.

    Returns:
      ``{"M_max": describe, "M_avg": describe`` (the headline, ``frame_errors`` over the driven
      joints), ``"per_joint": {joint: {"p50", "p95"}}``, ``"M_max_no_elbow_yaw": describe``
      (``m_max_without`` the robot's ``loose_joints``; the key keeps its name from the default
      robot's loose joints), ``"task_space": task_space_errors(...)}``; degrees and cm.

    Raises:
      ConfigError: bad or different shapes, non-finite angles, ``truth_points`` not matching.
    """
    p, t = _pair(pred, truth, robot)
    err = np.degrees(np.abs(_driven(p, robot) - _driven(t, robot)))
    m_max, m_avg = frame_errors(_driven(p, robot), _driven(t, robot))
    keep = _keep_columns(robot.loose_joints, robot)
    t_pts = _points_for(t, truth_points, robot)
    pred_pts = _points_for(p, pred_points, robot, "pred")
    return {
        "M_max": describe(m_max),
        "M_avg": describe(m_avg),
        "per_joint": _percentiles(err, robot),
        "M_max_no_elbow_yaw": describe(err[:, keep].max(axis=1)),
        "task_space": _summarize_arm(arm_errors(pred_pts, t_pts), robot),
    }
