"""Evaluation metrics: how far a projected pose is from the IK truth, and where the error is.

Joint space, in degrees over ``robot.DRIVEN_JOINTS`` (``n = 10``), against the analytic IK
(``jaxproj.robots.nao_h25.ik``):

* ``frame_errors``: the paper's per-frame ``M_max = max_j |r*_j - r_gt_j|`` and
  ``M_avg = mean_j |r*_j - r_gt_j|`` (section IV): the headline numbers, summarised by
  ``describe`` (mean / median / p95 / max);
* ``joint_percentiles``: p50 / p95 of ``|r*_j - r_gt_j|`` per driven joint;
* ``m_max_without``: ``M_max`` over the driven joints minus some, by default the two ElbowYaw
  joints (``NO_ELBOW_YAW``). With a near-straight arm the elbow's yaw turns the forearm about its
  own length: the IK truth's ElbowYaw is then ill-conditioned (set by Kinect noise, blended
  towards 0 below 30 deg of human elbow flexion, see ``jaxproj.robots.nao_h25.ik``), and a large ElbowYaw error
  there can be a small error of the pose.

Task space, from forward kinematics of the bundled MJCF (``robot.load_model("fixed")``: torso
welded at the origin, so positions are in the torso frame), per arm (``SIDES``), projected pose
against IK pose, with the MJCF's existing sites (``ARM_SITES``, none added):

* ``hand_cm``: distance between the wrist points (``l_wrist`` / ``r_wrist``: the origin of the
  wrist body, where the hand attaches, on the forearm axis; the undriven WristYaw cannot move
  it). Not the ``l_hand`` / ``r_hand`` sites of ``rollout.hand_error_cm``, which sit 1.2 cm off
  the forearm axis and so move with ElbowYaw even when the elbow is straight;
* ``elbow_cm``: distance between the elbow points (``l_elbow`` / ``r_elbow``);
* ``upper_arm_deg``: angle between the shoulder -> elbow directions (``l_shoulder`` ->
  ``l_elbow``: the physical segment, 8.13 deg off the ElbowYaw axis by the ElbowOffsetY, the
  segment the IK makes parallel to the human upper arm);
* ``forearm_deg``: angle between the elbow -> wrist directions.

Each is summarised like ``M_max`` (``describe``: mean / median / p95 / max / n). Angles between
directions are ``atan2(|a x b|, a . b)`` (accurate at small angles, unlike ``arccos``).

Numerics: forward kinematics and the task-space errors run in float32 (m, rad); the summaries
(``task_space_errors``, ``summarize_errors``) are in cm and degrees. The joint-space errors are
computed in float64 from the given angles (as the headline ``frame_errors`` always was).

FK: ``arm_points`` runs MJX (``mjx.kinematics``, JAX implementation) vmapped over fixed-size
batches of ``FK_BATCH`` frames (the last one padded), so one compile serves every frame count.
It runs on a copy of the MJCF with the head and leg subtrees (and the actuators, equality and
contact excludes, which kinematics never reads) removed (``arm_model``): those bodies cannot move
an arm site (the arms hang off the torso), and without them the program compiles in half the time
and runs ~4x faster. ``tests/test_metrics.py`` checks it against CPU MuJoCo on the whole
fixed-mount model to 1e-5 m. Measured on this project's shared 2-core CPU (25,000 random
configurations, median of 5): arm model 3.2 s compile, then 0.025 s per 10,000 frames; the whole
model 7.0 s compile, 0.094 s per 10,000; CPU ``mj_kinematics`` in a Python loop, no compile,
0.087 s per 10,000. So the one compile per process (~3 s) is the cost: warm, MJX is the fastest;
for a single cold call the CPU loop would be.

Strict promotion: the tests trace everything under strict dtype / rank promotion; MJX's own
internals rely on implicit promotion, so the ``mjx.kinematics`` call alone is traced inside
``jax.numpy_dtype_promotion("standard")`` / ``jax.numpy_rank_promotion("allow")`` (as in
``jaxproj.eval.rollout``). The rest of this module is strict-clean.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError, InputError
from jaxproj.robots.nao_h25 import robot

SIDES: tuple[str, str] = ("left", "right")
"""The arms, in the order of the side axis of ``arm_points`` / ``ArmErrors``."""

ARM_SITES: dict[str, tuple[str, str, str]] = {
    "left": ("l_shoulder", "l_elbow", "l_wrist"),
    "right": ("r_shoulder", "r_elbow", "r_wrist"),
}
"""MJCF sites (shoulder, elbow, wrist) of each arm: the joint origins of LShoulderPitch /
LElbowYaw / LWristYaw (and the right ones)."""

NO_ELBOW_YAW: tuple[str, str] = ("LElbowYaw", "RElbowYaw")
"""The joints ``m_max_without`` leaves out by default (ill-conditioned near a straight elbow)."""

TASK_METRICS: tuple[str, ...] = ("hand_cm", "elbow_cm", "upper_arm_deg", "forearm_deg")
"""The task-space summaries per side, in the order of ``ArmErrors``' fields."""

FK_BATCH = 4096
"""Frames per compiled forward-kinematics call (the last batch is padded)."""

_REMOVED_BODIES = ("Neck", "LPelvis", "RPelvis")  # head and legs: they cannot move the arms
_FREE_JOINT = "root"


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


def _angles(x: np.ndarray | jax.Array, name: str) -> np.ndarray:
    """``(F, 10)`` or ``(F, 26)`` finite angles as float64; ConfigError otherwise."""
    a = np.asarray(x, np.float64)
    if a.ndim != 2 or a.shape[1] not in (len(robot.DRIVEN_JOINTS), robot.N_JOINTS):
        raise ConfigError(
            f"{name} must have shape (F, {len(robot.DRIVEN_JOINTS)}) (driven joints) or "
            f"(F, {robot.N_JOINTS}) (configurations), got {a.shape}"
        )
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        raise ConfigError(
            f"{name} has non-finite angles in {int(bad.sum())} of {len(a)} frames "
            f"(first: frame {int(np.argmax(bad))})"
        )
    return a


def _pair(pred: np.ndarray | jax.Array, truth: np.ndarray | jax.Array) -> tuple[np.ndarray, ...]:
    p, t = _angles(pred, "pred"), _angles(truth, "truth")
    if p.shape != t.shape:
        raise ConfigError(f"pred and truth must have the same shape, got {p.shape} and {t.shape}")
    return p, t


def _driven(a: np.ndarray) -> np.ndarray:
    """``(F, 10 | 26)`` -> ``(F, 10)`` driven joints."""
    return a if a.shape[1] == len(robot.DRIVEN_JOINTS) else a[:, robot.DRIVEN_INDEX]


def joint_errors_deg(pred: np.ndarray | jax.Array, truth: np.ndarray | jax.Array) -> np.ndarray:
    """``|pred - truth|`` per driven joint, float64 degrees.

    Args:
      pred, truth: ``(F, 10)`` driven angles (``robot.DRIVEN_JOINTS`` order) or ``(F, 26)``
        configurations (``robot.JOINT_NAMES`` order), rad, both the same shape.

    Returns:
      ``(F, 10)`` in ``robot.DRIVEN_JOINTS`` order.

    Raises:
      ConfigError: bad or different shapes, non-finite angles.
    """
    p, t = _pair(pred, truth)
    return np.degrees(np.abs(_driven(p) - _driven(t)))


def _percentiles(err: np.ndarray) -> dict[str, dict[str, float]]:
    if len(err) == 0:
        return {j: {"p50": 0.0, "p95": 0.0} for j in robot.DRIVEN_JOINTS}
    p50, p95 = np.percentile(err, [50, 95], axis=0)
    return {
        j: {"p50": float(a), "p95": float(b)}
        for j, a, b in zip(robot.DRIVEN_JOINTS, p50, p95, strict=True)
    }


def joint_percentiles(
    pred: np.ndarray | jax.Array, truth: np.ndarray | jax.Array
) -> dict[str, dict[str, float]]:
    """p50 / p95 of the error of each driven joint, degrees.

    Args:
      pred, truth: ``(F, 10)`` driven angles or ``(F, 26)`` configurations, rad.

    Returns:
      ``{joint: {"p50": deg, "p95": deg}}`` for every joint of ``robot.DRIVEN_JOINTS`` (zeros
      when ``F = 0``).

    Raises:
      ConfigError: bad or different shapes, non-finite angles.
    """
    return _percentiles(joint_errors_deg(pred, truth))


def _keep_columns(exclude: Sequence[str]) -> np.ndarray:
    unknown = [j for j in exclude if j not in robot.DRIVEN_JOINTS]
    if unknown:
        raise ConfigError(f"not driven joints: {unknown}; use names of {robot.DRIVEN_JOINTS}")
    keep = np.array([j not in exclude for j in robot.DRIVEN_JOINTS])
    if not keep.any():
        raise ConfigError("m_max_without: every driven joint is excluded")
    return keep


def m_max_without(
    pred: np.ndarray | jax.Array,
    truth: np.ndarray | jax.Array,
    exclude: Sequence[str] = NO_ELBOW_YAW,
) -> np.ndarray:
    """Per-frame ``M_max`` over the driven joints not in ``exclude``.

    Args:
      pred, truth: ``(F, 10)`` driven angles or ``(F, 26)`` configurations, rad.
      exclude: names of driven joints to leave out (default: LElbowYaw and RElbowYaw).

    Returns:
      ``(F,)`` float64 degrees.

    Raises:
      ConfigError: bad shapes or angles, a name that is not a driven joint, nothing left.
    """
    keep = _keep_columns(exclude)
    return joint_errors_deg(pred, truth)[:, keep].max(axis=1)


# ------------------------------------------------------------------------------- task space


class _FK(NamedTuple):
    """Device-side arm-only model for ``arm_points`` (pytrees of arrays)."""

    mx: mjx.Model
    d0: mjx.Data
    src: jax.Array  # (nq,) int32: index into JOINT_NAMES of each qpos entry of the arm model
    sids: jax.Array  # (6,) int32 site ids, ARM_SITES left then right


def arm_model() -> mujoco.MjModel:
    """The fixed-mount MJCF without the head and legs: the model ``arm_points`` evaluates.

    The same bodies, joints and sites as ``robot.load_model("fixed")`` for the torso and both
    arms; the head / leg subtrees, actuators, the hip equality and the contact excludes removed
    (forward kinematics of the arms reads none of them).

    Raises:
      InputError: the bundled MJCF is missing or does not compile.
      ConfigError: the MJCF lacks a body / joint this relies on.
    """
    path = robot.mjcf_path()
    if not path.is_file():
        raise InputError(path, "bundled MJCF model is missing")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        root = spec.joint(_FREE_JOINT)
        if root is not None:
            spec.delete(root)
        for name in _REMOVED_BODIES:
            body = spec.body(name)
            if body is None:
                raise ConfigError(f"{path}: no body {name!r} to leave out of the arm model")
            spec.delete(body)
        for items in (spec.equalities, spec.actuators, spec.excludes):
            for item in list(items):
                spec.delete(item)
        return spec.compile()
    except ValueError as err:  # mujoco reports XML / compile errors as ValueError
        if isinstance(err, (ConfigError, InputError)):
            raise
        raise InputError(path, f"MuJoCo cannot compile the arm model: {err}") from err


@functools.lru_cache(maxsize=1)
def _fk_setup() -> _FK:
    model = arm_model()
    src = []
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            raise ConfigError("the arm model must have hinge joints only")
        src.append(robot.IDX[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)])
    order = np.argsort(model.jnt_qposadr)  # qpos entry k <- joint with the k-th address
    sids = []
    for side in SIDES:
        for name in ARM_SITES[side]:
            sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
            if sid < 0:
                raise ConfigError(f"the MJCF has no site named {name!r}")
            sids.append(sid)
    mx = mjx.put_model(model, impl="jax")
    return _FK(
        mx=mx,
        d0=mjx.make_data(mx, impl="jax"),
        src=jnp.asarray(np.asarray(src)[order], dtype=jnp.int32),
        sids=jnp.asarray(sids, dtype=jnp.int32),
    )


def _arm_points(fk: _FK, q: jax.Array) -> jax.Array:
    """``(B, 26)`` float32 configurations -> ``(B, 2, 3, 3)`` float32 site positions, m."""

    def one(qi: jax.Array) -> jax.Array:
        d = fk.d0.replace(qpos=qi[fk.src].astype(fk.d0.qpos.dtype))
        # MJX internals need implicit promotion; see the module docstring.
        with jax.numpy_dtype_promotion("standard"), jax.numpy_rank_promotion("allow"):
            d = mjx.kinematics(fk.mx, d)
        return d.site_xpos[fk.sids].astype(jnp.float32).reshape(len(SIDES), 3, 3)

    return jax.vmap(one)(q)


# The policy's full float32 matmul precision: the FK is compared with CPU MuJoCo to 1e-5 m, which
# a TF32 product on a GPU would not keep (MJX's kinematics is mostly elementwise anyway).
_arm_points_jit = jit(_arm_points)


def _configurations(x: np.ndarray | jax.Array, name: str) -> np.ndarray:
    """``(F, 10 | 26)`` -> ``(F, 26)`` float32 (driven joints into the standing posture)."""
    a = _angles(x, name).astype(np.float32)
    if a.shape[1] == robot.N_JOINTS:
        return a
    full = np.tile(robot.STANDING_POSTURE, (len(a), 1))
    full[:, robot.DRIVEN_INDEX] = a
    return full


def arm_points(angles: np.ndarray | jax.Array) -> np.ndarray:
    """Forward kinematics of the arm sites (MJX, jitted, ``FK_BATCH`` frames per call).

    Args:
      angles: ``(F, 10)`` driven angles (``robot.DRIVEN_JOINTS`` order; the other joints at
        ``robot.STANDING_POSTURE``, as ``ik.driven_to_full``) or ``(F, 26)`` configurations
        (``robot.JOINT_NAMES`` order), rad.

    Returns:
      ``(F, 2, 3, 3)`` float32 positions in the torso frame, m: ``[frame, side (SIDES),
      point (shoulder, elbow, wrist: ARM_SITES), xyz]``.

    Raises:
      ConfigError: bad shape or non-finite angles.
    """
    q = _configurations(angles, "angles")
    n = len(q)
    if n == 0:
        return np.zeros((0, len(SIDES), 3, 3), np.float32)
    fk = _fk_setup()
    out = []
    for s in range(0, n, FK_BATCH):
        chunk = q[s : s + FK_BATCH]
        pad = FK_BATCH - len(chunk)
        if pad:
            chunk = np.concatenate([chunk, np.repeat(chunk[:1], pad, axis=0)])
        out.append(np.asarray(_arm_points_jit(fk, jnp.asarray(chunk)))[: FK_BATCH - pad])
    return np.concatenate(out)


class ArmErrors(NamedTuple):
    """Task-space errors per frame and side (columns in ``SIDES`` order), float32.

    Attributes:
      hand: ``(F, 2)`` distance between the wrist points, m.
      elbow: ``(F, 2)`` distance between the elbow points, m.
      upper_arm: ``(F, 2)`` angle between the shoulder -> elbow directions, rad.
      forearm: ``(F, 2)`` angle between the elbow -> wrist directions, rad.
    """

    hand: np.ndarray
    elbow: np.ndarray
    upper_arm: np.ndarray
    forearm: np.ndarray


def _check_points(x: np.ndarray | jax.Array, name: str) -> np.ndarray:
    a = np.asarray(x, np.float32)
    if a.ndim != 4 or a.shape[1:] != (len(SIDES), 3, 3):
        raise ConfigError(f"{name} must have shape (F, 2, 3, 3) (arm_points), got {a.shape}")
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
      pred_points, truth_points: ``(F, 2, 3, 3)`` from ``arm_points``, m.

    Returns:
      ``ArmErrors`` of ``(F, 2)`` float32 arrays (m, rad).

    Raises:
      ConfigError: bad or different shapes.
    """
    p = _check_points(pred_points, "pred_points")
    t = _check_points(truth_points, "truth_points")
    if p.shape != t.shape:
        raise ConfigError(f"point sets differ in shape: {p.shape} and {t.shape}")
    dist = np.linalg.norm(p - t, axis=-1)  # (F, 2, 3): shoulder, elbow, wrist
    up_p, up_t = p[:, :, 1] - p[:, :, 0], t[:, :, 1] - t[:, :, 0]
    fo_p, fo_t = p[:, :, 2] - p[:, :, 1], t[:, :, 2] - t[:, :, 1]
    return ArmErrors(
        hand=dist[:, :, 2].astype(np.float32),
        elbow=dist[:, :, 1].astype(np.float32),
        upper_arm=_angle_between(up_p, up_t),
        forearm=_angle_between(fo_p, fo_t),
    )


def _summarize_arm(err: ArmErrors) -> dict[str, dict[str, dict[str, float]]]:
    scale = {"hand_cm": 100.0, "elbow_cm": 100.0}
    out: dict[str, dict[str, dict[str, float]]] = {}
    for i, side in enumerate(SIDES):
        out[side] = {}
        for key, values in zip(TASK_METRICS, err, strict=True):
            v = values[:, i].astype(np.float64)
            out[side][key] = describe(v * scale[key] if key in scale else np.degrees(v))
    return out


def _points_for(
    angles26: np.ndarray, points: np.ndarray | jax.Array | None, name: str = "truth"
) -> np.ndarray:
    """``arm_points(angles26)``, or the given ``points`` of them checked against their frames."""
    if points is None:
        return arm_points(angles26)
    t = _check_points(points, f"{name}_points")
    if len(t) != len(angles26):
        raise ConfigError(f"{name}_points has {len(t)} frames, {name} {len(angles26)}")
    return t


def task_space_errors(
    pred26: np.ndarray | jax.Array,
    truth26: np.ndarray | jax.Array,
    *,
    truth_points: np.ndarray | jax.Array | None = None,
) -> dict[str, dict[str, dict[str, float]]]:
    """Task-space errors of ``pred26`` against ``truth26``, summarised per side.

    Args:
      pred26, truth26: ``(F, 26)`` configurations (or ``(F, 10)`` driven angles, the rest at the
        standing posture), rad, both the same shape.
      truth_points: ``arm_points(truth26)`` when already computed (one FK of the truth serves
        every method), else computed here.

    Returns:
      ``{side: {"hand_cm" | "elbow_cm" | "upper_arm_deg" | "forearm_deg": describe}}`` for
      ``side`` in ``SIDES`` (cm / degrees; see the module doc).

    Raises:
      ConfigError: bad or different shapes, non-finite angles, ``truth_points`` not matching.
    """
    _pair(pred26, truth26)
    t_pts = _points_for(truth26, truth_points)
    return _summarize_arm(arm_errors(arm_points(pred26), t_pts))


def summarize_errors(
    pred: np.ndarray | jax.Array,
    truth: np.ndarray | jax.Array,
    *,
    truth_points: np.ndarray | jax.Array | None = None,
    pred_points: np.ndarray | jax.Array | None = None,
) -> dict:
    """Every metric of one method, JSON-ready (plain floats and ints).

    Args:
      pred, truth: ``(F, 10)`` driven angles (``robot.DRIVEN_JOINTS`` order; the task space puts
        the other joints at the standing posture) or ``(F, 26)`` configurations, rad.
      truth_points: ``arm_points(truth)`` when already computed (pass it to score several
        methods against one truth with one FK of the truth).
      pred_points: ``arm_points(pred)`` when already computed (the caller uses them too).

    Returns:
      ``{"M_max": describe, "M_avg": describe`` (the headline, ``frame_errors`` over the driven
      joints), ``"per_joint": {joint: {"p50", "p95"}}``, ``"M_max_no_elbow_yaw": describe``
      (``m_max_without`` the two ElbowYaw joints), ``"task_space": task_space_errors(...)}``;
      degrees and cm.

    Raises:
      ConfigError: bad or different shapes, non-finite angles, ``truth_points`` not matching.
    """
    p, t = _pair(pred, truth)
    err = np.degrees(np.abs(_driven(p) - _driven(t)))
    m_max, m_avg = frame_errors(_driven(p), _driven(t))
    keep = _keep_columns(NO_ELBOW_YAW)
    t_pts = _points_for(t, truth_points)
    return {
        "M_max": describe(m_max),
        "M_avg": describe(m_avg),
        "per_joint": _percentiles(err),
        "M_max_no_elbow_yaw": describe(err[:, keep].max(axis=1)),
        "task_space": _summarize_arm(arm_errors(_points_for(p, pred_points, "pred"), t_pts)),
    }
