"""Synthetic poses and motions for the paper's benchmarks (section IV): eight basic poses and the
eight basic motions from the rest pose to them, with Kinect-like noise.

The paper recorded its basic poses and motions from a person in front of a Kinect; we synthesise
them instead, so that every benchmark is reproducible: a pose is a set of 19 bone unit vectors in
the body frame (x forward, y left, z up; ``skeleton.body_frame``), turned into a Kinect v1
skeleton with the median bone lengths of the bundled MSR Action3D data
(``skeleton_from_directions``). A basic motion goes from the rest pose to a basic pose in ~2 s
(``interpolate_pose``: arm bones linear in shoulder pitch / elevation, so raised arms swing up
through the front and never over the shoulder axis, where the IK's ShoulderPitch is undefined;
ease-in-out) and gets Kinect-like per-joint Gaussian noise whose size is
measured from the recordings (``kinect_noise_std``). The studies that project them are in
``experiments``.

Consistency of a synthetic skeleton. The descriptor expresses every bone in the body frame the
skeleton itself defines: ``up`` = HipCenter -> ShoulderCenter, ``left`` = ShoulderRight ->
ShoulderLeft made orthogonal to ``up``. Directions given in the body frame are recovered exactly
only if the skeleton built from them defines that same frame, i.e. if
``L_spine_lower * d_spine_lower + L_spine_upper * d_spine_upper`` points along +z and the
horizontal part of ``L_clav_left * d_clav_left - L_clav_right * d_clav_right`` along +y. Every
basic pose therefore has both spine bones along +z and the clavicles along +/-y (any other choice
changes the frame and hence every other bone's descriptor). The neck, arm, pelvis, leg and foot
bones are free.

Common to all poses: spine bones ``(0, 0, 1)``; neck ``(sin a, 0, cos a)`` with
``a = skeleton.NECK_TILT_REFERENCE`` (-27.1 deg, i.e. tilted *backwards*, the median neck tilt
of the Kinect recordings, the default robot's IK's neutral, so HeadPitch = HeadYaw = 0); clavicles
``(0, +/-1, 0)``; pelvis ``(0, +/-0.6, -0.8)``; thighs and shins ``(0, 0, -1)`` (standing
straight); feet ``(1, 0, 0)``; each hand bone continues its forearm. Arms (left side; the right
side mirrors ``y`` unless the table gives it; ``bend(u, t, a)`` rotates ``u`` by ``a`` towards
the direction ``t``):

========  ==================================  ==============================
pose      upper arm ``u``                     forearm ``f``
========  ==================================  ==============================
POSE_1    ``(0, sin 10, -cos 10)``            ``bend(u, +x, 5 deg)``
POSE_2    ``(0, sin 75, -cos 75)``            ``= u``
POSE_3    ``(1, 0, 0)``                       ``= u``
POSE_4    ``(0, 0, 1)``                       ``= u``
POSE_5    L ``(0, 0, 1)``, R ``(1, 0, 0)``    ``= u``
POSE_6    ``(0, sin 10, -cos 10)``            ``bend(u, +x, 80 deg)``
POSE_7    ``(0, cos 30, sin 30)``             ``(0, -sin 15, cos 15)``
POSE_8    L ``unit(1, 0.15, -1)``             L ``= u``
          R ``(0, -cos 20, sin 20)``          R ``unit(0.5, -0.2, 0.85)``
========  ==================================  ==============================

What they mean, and their IK (left arm ShoulderPitch / ShoulderRoll / ElbowYaw / ElbowRoll in
degrees; the right arm of a symmetric pose has roll, yaw and elbow roll negated; head 0 / 0):

* POSE_1 rest: arms hanging 10 deg away from the body, elbows almost straight:
  90 / 1.9 / -23.0 / -9.5.
* POSE_2 arms out sideways, 15 deg below horizontal: 90 / 66.9 / -15.9 / -8.1. A horizontal
  "T-pose" would need ShoulderRoll 90 - 8.1 = 81.9 deg, beyond the default robot's 76 deg limit (and
  the arm would lie on the shoulder axis, where ShoulderPitch is undefined), so we keep it
  reachable.
* POSE_3 both arms straight forward: 0 / -8.1 / -15.9 / -8.1.
* POSE_4 both arms straight up: -90 / -8.1 / 15.9 / -8.1.
* POSE_5 left arm up (as POSE_4), right arm forward (as POSE_3): R 0 / 8.1 / 15.9 / 8.1.
* POSE_6 upper arms hanging, elbows bent 80 deg, forearms forward (hands in front of the belly):
  90 / 1.9 / -91.4 / -80.1 (ElbowRoll limit 88.5 deg).
* POSE_7 upper arms raised sideways 30 deg above horizontal, forearms up and leaning in towards
  the head (human elbow angle 75 deg): -90 / 51.9 / 0.0 / -66.9.
* POSE_8 mixed: left arm straight, forward-down 45 deg: 45 / -2.1 / 15.9 / -8.1; right upper arm
  raised sideways 20 deg above horizontal, elbow bent 62 deg, forearm up and forward:
  R -90 / -61.9 / -37.3 / 55.0.

A straight human arm gives ``|ElbowRoll| = 8.1 deg``: the IK makes the default robot's
shoulder->elbow *segment* parallel to the upper arm, and that segment is 8.13 deg off the elbow's
yaw axis. Its ``ElbowYaw`` of +/-15.9 deg is ill-defined: the forearm then lies exactly on the
branch cut of the IK's ``atan2`` (yaw +/-180 deg, clipped, times the straight-elbow blend weight
0.13), so the sign is set by round-off (a 1e-6 change of the forearm flips it) and Kinect noise
spreads it over about +/-50 deg. This is why the summaries also report ``M_max`` without the
ElbowYaw joints.

``basic_pose_angles()`` gives the IK angles of every pose (the ground truth).

Kinect noise (``kinect_noise_std``): the second difference ``x[t+1] - 2 x[t] + x[t-1]`` of a
coordinate with white noise of std ``s`` has std ``sqrt(6) s`` and hardly any motion content in
quiet stretches. We take every (frame, joint) of the bundled recordings whose displacement
between ``t - 3`` and ``t + 3`` is below 1 cm (the joint is still; the displacement window does not
overlap the second-difference window, so the selection does not bias the noise estimate of white
noise) and pool ``sqrt(mean(d2^2) / 6)`` over the three axes. Result: 3.7 mm pooled over all
joints (18,895 windows, 25,645 still joint-samples); per joint from 2.5 mm (knees) and 2.9 mm
(HipCenter) over 3.8-4.9 mm (spine, shoulders, elbows, wrists, hips, head) to 7.1 / 8.1 mm
(right / left hand). ``basic_motion`` uses the per-joint values by default. (The second
difference slightly underestimates noise that is correlated from frame to frame; the residual
about a centred 5-frame moving average, ``sqrt(mean(r^2) / 0.8)``, gives ~4.5 mm on the same
samples, the upper end of the plausible range since it leaks some motion.)
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import BONE_NAMES, BONES, N_JOINTS, NECK_TILT_REFERENCE, J, descriptor
from jaxproj.io import datasets
from jaxproj.robots import Robot
from jaxproj.robots import get as get_robot

N_BONES = len(BONES)
POSE_NAMES: tuple[str, ...] = tuple(f"POSE_{i}" for i in range(1, 9))
REST = "POSE_1"
DEFAULT_FPS = 15.0
"""Frame rate of the synthetic motions (MSR Action3D's rate)."""

_PARENT = np.array([J[a] for a, _ in BONES])
_CHILD = np.array([J[b] for _, b in BONES])
_B = {name: i for i, name in enumerate(BONE_NAMES)}

NOISE_STILL_DISPLACEMENT = 0.01
"""Metres: a joint counts as still at ``t`` if it moved less than this between ``t-3`` and
``t+3``."""
NOISE_MIN_SAMPLES = 30
"""A joint with fewer still samples than this takes the pooled noise estimate."""


# ------------------------------------------------------------------------------ data statistics


def _valid_positions() -> np.ndarray:
    seqs = datasets.msr_action3d()
    return np.concatenate([s.positions[s.valid] for s in seqs]).astype(np.float64)


@functools.lru_cache(maxsize=1)
def _median_bone_lengths() -> np.ndarray:
    p = _valid_positions()
    lengths = np.linalg.norm(p[:, _CHILD] - p[:, _PARENT], axis=-1)  # (N, 19)
    return np.median(lengths, axis=0).astype(np.float32)


def median_bone_lengths() -> np.ndarray:
    """Median length of each bone over all valid frames of the bundled MSR Action3D data.

    Returns:
      ``(19,)`` float32 metres in ``skeleton.BONES`` order (e.g. upper arm ~0.28 m).
    """
    return _median_bone_lengths().copy()


@functools.lru_cache(maxsize=1)
def _noise_stats() -> tuple[np.ndarray, float, np.ndarray]:
    sq_sum = np.zeros(N_JOINTS)
    count = np.zeros(N_JOINTS, np.int64)
    for s in datasets.msr_action3d():
        p = s.positions.astype(np.float64)
        v = s.valid
        if len(p) < 7:
            continue
        t = np.arange(3, len(p) - 3)
        t = t[np.all([v[t + o] for o in range(-3, 4)], axis=0)]
        d2 = p[t + 1] - 2.0 * p[t] + p[t - 1]  # (n, 20, 3)
        disp = np.linalg.norm(p[t + 3] - p[t - 3], axis=-1)  # (n, 20)
        still = disp < NOISE_STILL_DISPLACEMENT
        sq_sum += np.sum(np.sum(d2**2, axis=-1) * still, axis=0)
        count += still.sum(axis=0)
    pooled = float(np.sqrt(sq_sum.sum() / (3 * 6 * count.sum())))
    per_joint = np.sqrt(sq_sum / np.maximum(3 * 6 * count, 1))
    per_joint = np.where(count >= NOISE_MIN_SAMPLES, per_joint, pooled)
    return per_joint.astype(np.float32), pooled, count


def kinect_noise_std(per_joint: bool = False) -> float | np.ndarray:
    """Std (metres, per coordinate) of the Kinect joint noise, estimated from the recordings.

    Method (module docstring): ``sqrt(mean(d2^2) / 6)`` of the second differences at still
    joints (moved < ``NOISE_STILL_DISPLACEMENT`` between ``t - 3`` and ``t + 3``).

    Args:
      per_joint: return one value per joint instead of the pooled value.

    Returns:
      the pooled std (float, ~0.0037 m), or ``(20,)`` float32 per joint (SDK order).
    """
    per, pooled, _ = _noise_stats()
    return per.copy() if per_joint else pooled


# ------------------------------------------------------------------------------- skeletons


def skeleton_from_directions(
    directions: np.ndarray | jax.Array, lengths: np.ndarray | None = None
) -> np.ndarray:
    """Joint positions from bone directions, HipCenter at the origin.

    Walks ``skeleton.BONES`` (each parent placed before its children):
    ``child = parent + length * unit(direction)``. Directions are in the body frame (x forward,
    y left, z up); ``descriptor(..., bones="full")`` recovers them exactly when they are
    consistent with the body frame (module docstring: spine along +z, clavicles along +/-y).

    Args:
      directions: ``(..., 19, 3)`` bone directions in ``BONES`` order (normalised here; a zero
        vector is an error).
      lengths: ``(19,)`` metres; default ``median_bone_lengths()``.

    Returns:
      ``(..., 20, 3)`` float32 positions in Kinect SDK joint order (metres, body frame).

    Raises:
      ConfigError: wrong shapes, or a zero / non-finite direction or length.
    """
    d = np.asarray(directions, np.float64)
    if d.shape[-2:] != (N_BONES, 3):
        raise ConfigError(f"directions must be (..., {N_BONES}, 3), got {d.shape}")
    lengths = median_bone_lengths() if lengths is None else lengths
    ln = np.asarray(lengths, np.float64)
    if ln.shape != (N_BONES,) or not (np.isfinite(ln).all() and (ln > 0).all()):
        raise ConfigError(f"lengths must be ({N_BONES},) positive finite, got {ln}")
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    if not (np.isfinite(norm).all() and (norm > 1e-9).all()):
        raise ConfigError("every bone direction must be finite and non-zero")
    vec = d / norm * ln[:, None]
    pos = np.zeros((*d.shape[:-2], N_JOINTS, 3))
    for b, (parent, child) in enumerate(zip(_PARENT, _CHILD, strict=True)):
        pos[..., child, :] = pos[..., parent, :] + vec[..., b, :]
    return pos.astype(np.float32)


def _unit(*v: float) -> np.ndarray:
    a = np.asarray(v, np.float64)
    return a / np.linalg.norm(a)


def _bend(u: np.ndarray, toward: np.ndarray, deg: float) -> np.ndarray:
    """``u`` rotated by ``deg`` towards ``toward`` (in the plane of the two)."""
    t = toward - np.dot(toward, u) * u
    t = t / np.linalg.norm(t)
    a = math.radians(deg)
    return math.cos(a) * u + math.sin(a) * t


def _mirror(v: np.ndarray) -> np.ndarray:
    return v * np.array([1.0, -1.0, 1.0])


def _sd(deg: float) -> float:
    return math.sin(math.radians(deg))


def _cd(deg: float) -> float:
    return math.cos(math.radians(deg))


NEUTRAL_NECK = np.array(
    [math.sin(NECK_TILT_REFERENCE), 0.0, math.cos(NECK_TILT_REFERENCE)], np.float64
)
"""Neck direction whose IK is HeadPitch = HeadYaw = 0 (tilted back by 27.1 deg)."""

_X, _Z = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


def _pose(lu: np.ndarray, lf: np.ndarray, ru: np.ndarray, rf: np.ndarray) -> np.ndarray:
    """``(19, 3)`` directions: the common body plus the given arm bones."""
    d = {
        "spine_lower": _Z,
        "spine_upper": _Z,
        "neck": NEUTRAL_NECK,
        "clavicle_left": np.array([0.0, 1.0, 0.0]),
        "clavicle_right": np.array([0.0, -1.0, 0.0]),
        "upper_arm_left": lu,
        "forearm_left": lf,
        "hand_left": lf,
        "upper_arm_right": ru,
        "forearm_right": rf,
        "hand_right": rf,
        "pelvis_left": np.array([0.0, 0.6, -0.8]),
        "pelvis_right": np.array([0.0, -0.6, -0.8]),
        "thigh_left": -_Z,
        "shin_left": -_Z,
        "foot_left": _X,
        "thigh_right": -_Z,
        "shin_right": -_Z,
        "foot_right": _X,
    }
    out = np.stack([_unit(*d[n]) for n in BONE_NAMES]).astype(np.float32)
    out.flags.writeable = False
    return out


def _symmetric(lu: np.ndarray, lf: np.ndarray) -> np.ndarray:
    return _pose(lu, lf, _mirror(lu), _mirror(lf))


def _basic_poses() -> dict[str, np.ndarray]:
    hang = _unit(0.0, _sd(10), -_cd(10))
    side75 = _unit(0.0, _sd(75), -_cd(75))
    up_side = _unit(0.0, _cd(30), _sd(30))
    fore_in = _unit(0.0, -_sd(15), _cd(15))
    l8 = _unit(1.0, 0.15, -1.0)
    r8u = _unit(0.0, -_cd(20), _sd(20))
    r8f = _unit(0.5, -0.2, 0.85)
    return {
        "POSE_1": _symmetric(hang, _bend(hang, _X, 5.0)),
        "POSE_2": _symmetric(side75, side75),
        "POSE_3": _symmetric(_X, _X),
        "POSE_4": _symmetric(_Z, _Z),
        "POSE_5": _pose(_Z, _Z, _X, _X),
        "POSE_6": _symmetric(hang, _bend(hang, _X, 80.0)),
        "POSE_7": _symmetric(up_side, fore_in),
        "POSE_8": _pose(l8, l8, r8u, r8f),
    }


BASIC_POSES: dict[str, np.ndarray] = _basic_poses()
"""The eight basic poses: name -> ``(19, 3)`` float32 body-frame bone directions (read-only).
See the table in the module docstring."""

POSE_DESCRIPTIONS: dict[str, str] = {
    "POSE_1": "rest: arms hanging, elbows almost straight",
    "POSE_2": "arms out sideways, 15 deg below horizontal (reachable T-pose)",
    "POSE_3": "both arms straight forward",
    "POSE_4": "both arms straight up",
    "POSE_5": "left arm up, right arm forward",
    "POSE_6": "upper arms hanging, elbows bent 80 deg, forearms forward",
    "POSE_7": "upper arms raised sideways, forearms up towards the head",
    "POSE_8": "mixed: left arm forward-down, right arm raised sideways with elbow bent",
}


def check_pose(name: str) -> np.ndarray:
    """The ``(19, 3)`` bone directions of the basic pose ``name`` (read-only).

    Raises:
      ConfigError: ``name`` is not one of ``POSE_NAMES``.
    """
    if name not in BASIC_POSES:
        raise ConfigError(f"unknown pose {name!r}; use one of {POSE_NAMES}")
    return BASIC_POSES[name]


def basic_pose_angles(
    bones: str = "upper", robot: Robot | str | None = None
) -> dict[str, dict[str, float]]:
    """IK ground truth of every basic pose: name -> {driven joint: degrees}, for ``robot`` (a
    ``Robot`` or a registered name; ``None``: the default robot, the paper's)."""
    robot = get_robot(robot)
    out = {}
    for name, dirs in BASIC_POSES.items():
        d, _ = descriptor(skeleton_from_directions(dirs), bones=bones)
        q = np.degrees(np.asarray(robot.solve_ik(d, bones), np.float64))
        out[name] = {j: float(v) for j, v in zip(robot.driven_joints, q, strict=True)}
    return out


# ------------------------------------------------------------------------------- motions


def _slerp(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Slerp between unit vectors ``a``, ``b`` ``(B, 3)`` at fractions ``s`` ``(T,)`` ->
    ``(T, B, 3)``. Antiparallel pairs turn through the forward (+x) direction (or +z)."""
    dot = np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)  # (B,)
    omega = np.arccos(dot)
    # direction orthogonal to a in the plane of the rotation
    perp = b - dot[:, None] * a
    n = np.linalg.norm(perp, axis=-1)
    fallback = np.where(np.abs(a[:, :1]) < 0.9, _X, _Z)  # (B, 3)
    fallback = fallback - np.sum(fallback * a, axis=-1, keepdims=True) * a
    perp = np.where((n > 1e-6)[:, None], perp, fallback)
    perp = perp / np.linalg.norm(perp, axis=-1, keepdims=True)
    ang = s[:, None] * omega[None, :]  # (T, B)
    return np.cos(ang)[..., None] * a[None] + np.sin(ang)[..., None] * perp[None]


ARM_BONES: tuple[str, ...] = tuple(
    f"{b}_{side}" for side in ("left", "right") for b in ("upper_arm", "forearm", "hand")
)
"""Bones interpolated in shoulder coordinates by ``basic_motion`` (the others are slerped)."""
_ARM_INDEX = np.array([_B[b] for b in ARM_BONES])


def shoulder_coordinates(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(..., 3)`` body-frame directions -> ``(pitch, elevation)`` radians, ``(...,)`` each.

    ``v = (cos r cos p, sin r, -cos r sin p)``: ``p = atan2(-v_z, v_x)`` turns about the lateral
    (y) axis (0 forward, +90 deg down, -90 deg up, as the default robot's ShoulderPitch), ``r`` is
    the elevation towards +y (left). Undefined (``p = 0``) along +/-y.
    """
    v = np.asarray(v, np.float64)
    p = np.arctan2(-v[..., 2], v[..., 0])
    r = np.arctan2(v[..., 1], np.hypot(v[..., 0], v[..., 2]))
    return p, r


def from_shoulder_coordinates(p: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Inverse of ``shoulder_coordinates``: ``(...,)`` x2 -> ``(..., 3)`` unit vectors."""
    p, r = np.asarray(p, np.float64), np.asarray(r, np.float64)
    return np.stack([np.cos(r) * np.cos(p), np.sin(r), -np.cos(r) * np.sin(p)], axis=-1)


def interpolate_pose(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Bone directions between two poses: ``(19, 3)`` x2, fractions ``(T,)`` -> ``(T, 19, 3)``.

    Arm bones (``ARM_BONES``) go linearly in shoulder coordinates (``shoulder_coordinates``),
    so an arm raised from hanging to up swings through the front, as the default robot's
    ShoulderPitch does, and never over the shoulder axis (where ShoulderPitch is undefined and a
    sideways-horizontal arm would need more than the default robot's 76 deg of ShoulderRoll); every
    other bone is slerped. ``s = 0`` gives ``a``, ``s = 1`` gives ``b`` (up to round-off).
    """
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    s = np.asarray(s, np.float64)
    out = _slerp(a, b, s)
    pa, ra = shoulder_coordinates(a[_ARM_INDEX])
    pb, rb = shoulder_coordinates(b[_ARM_INDEX])
    p = pa[None] + s[:, None] * (pb - pa)[None]
    r = ra[None] + s[:, None] * (rb - ra)[None]
    out[:, _ARM_INDEX] = from_shoulder_coordinates(p, r)
    return out


def ease_in_out(t: np.ndarray) -> np.ndarray:
    """``0.5 - 0.5 cos(pi t)`` for ``t`` in [0, 1]: zero speed at both ends."""
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(t, 0.0, 1.0))


def n_motion_frames(seconds: float = 2.0, fps: float = DEFAULT_FPS) -> int:
    """Frames of a basic motion: ``round(seconds * fps) + 1`` (rest first, pose last)."""
    return int(round(seconds * fps)) + 1


def basic_motion(
    pose_name: str,
    *,
    seconds: float = 2.0,
    fps: float = DEFAULT_FPS,
    noise_std: float | np.ndarray | None = None,
    key: jax.Array,
    lengths: np.ndarray | None = None,
) -> np.ndarray:
    """The basic motion from the rest pose (POSE_1) to ``pose_name``, with Kinect-like noise.

    The bones move from rest to the pose by ``interpolate_pose`` (arms in shoulder coordinates,
    through the front; other bones slerped) with an ease-in-out profile (``ease_in_out``);
    frame 0 is the rest pose, the last frame the pose. Noise: independent isotropic Gaussian per
    joint and frame, drawn with ``key`` (deterministic for a key).

    Args:
      pose_name: ``"POSE_1"`` .. ``"POSE_8"``.
      seconds, fps: duration and frame rate; ``n_motion_frames(seconds, fps)`` frames.
      noise_std: metres per coordinate: a float, ``(20,)`` per joint, or ``None`` for
        ``kinect_noise_std(per_joint=True)``; ``0`` for a noise-free motion.
      key: ``jax.random`` key.
      lengths: ``(19,)`` bone lengths; default ``median_bone_lengths()``.

    Returns:
      ``(T, 20, 3)`` float32 positions (metres, body frame of the rest pose).
    """
    target = check_pose(pose_name).astype(np.float64)
    rest = BASIC_POSES[REST].astype(np.float64)
    if not (seconds > 0 and fps > 0):
        raise ConfigError(f"seconds={seconds} and fps={fps} must be > 0")
    t = n_motion_frames(seconds, fps)
    s = ease_in_out(np.linspace(0.0, 1.0, t))
    dirs = interpolate_pose(rest, target, s)  # (T, 19, 3)
    dirs[0], dirs[-1] = rest, target
    pos = skeleton_from_directions(dirs, lengths)
    std = kinect_noise_std(per_joint=True) if noise_std is None else noise_std
    std = np.broadcast_to(np.asarray(std, np.float32), (N_JOINTS,))
    if not (np.isfinite(std).all() and (std >= 0).all()):
        raise ConfigError(f"noise_std must be finite and >= 0, got {noise_std}")
    noise = jax.random.normal(key, pos.shape, jnp.float32)
    return (pos + np.asarray(noise) * std[None, :, None]).astype(np.float32)


__all__ = [
    "ARM_BONES",
    "BASIC_POSES",
    "DEFAULT_FPS",
    "NEUTRAL_NECK",
    "POSE_DESCRIPTIONS",
    "POSE_NAMES",
    "REST",
    "basic_motion",
    "basic_pose_angles",
    "check_pose",
    "ease_in_out",
    "from_shoulder_coordinates",
    "interpolate_pose",
    "kinect_noise_std",
    "median_bone_lengths",
    "n_motion_frames",
    "shoulder_coordinates",
    "skeleton_from_directions",
]
