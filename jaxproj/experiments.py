"""The paper's synthetic benchmarks (section IV): eight basic poses, eight basic motions, the
landmark-set size study and the efficiency study.

The paper recorded its basic poses and motions from a person in front of a Kinect; we synthesise
them instead, so that every benchmark is reproducible: a pose is a set of 19 bone unit vectors in
the body frame (x forward, y left, z up; ``skeleton.body_frame``), turned into a Kinect v1
skeleton with the median bone lengths of the bundled MSR Action3D data
(``skeleton_from_directions``). A basic motion goes from the rest pose to a basic pose in ~2 s
(``interpolate_pose``: arm bones linear in shoulder pitch / elevation, so raised arms swing up
through the front and never over the shoulder axis, where the IK's ShoulderPitch is undefined;
ease-in-out) and gets Kinect-like per-joint Gaussian noise whose size is
measured from the recordings (``kinect_noise_std``). Errors are the paper's ``M_max`` / ``M_avg``
(degrees, ``evaluate.frame_errors``) of the projection against the analytic IK of the same frame.

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
``a = ik.HEAD_PITCH_NEUTRAL`` (-27.1 deg, i.e. tilted *backwards*, the median neck tilt of the
Kinect recordings, so HeadPitch = HeadYaw = 0); clavicles ``(0, +/-1, 0)``; pelvis
``(0, +/-0.6, -0.8)``; thighs and shins ``(0, 0, -1)`` (standing straight); feet ``(1, 0, 0)``;
each hand bone continues its forearm. Arms (left side; the right side mirrors ``y`` unless the
table gives it; ``bend(u, t, a)`` rotates ``u`` by ``a`` towards the direction ``t``):

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
  "T-pose" would need ShoulderRoll 90 - 8.1 = 81.9 deg, beyond the NAO's 76 deg limit (and the
  arm would lie on the shoulder axis, where ShoulderPitch is undefined), so we keep it reachable.
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

A straight human arm gives ``|ElbowRoll| = 8.1 deg``: the IK makes the NAO's shoulder->elbow
*segment* parallel to the upper arm, and that segment is 8.13 deg off the elbow's yaw axis. Its
``ElbowYaw`` of +/-15.9 deg is ill-defined: the forearm then lies exactly on the branch cut of the
IK's ``atan2`` (yaw +/-180 deg, clipped, times the straight-elbow blend weight 0.13), so the sign
is set by round-off (a 1e-6 change of the forearm flips it) and Kinect noise spreads it over
about +/-50 deg. This is why the summaries also report ``M_max`` without the ElbowYaw joints.

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

import dataclasses
import functools
import math
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj import datasets, engine, ik, robot
from jaxproj.evaluate import describe, frame_errors
from jaxproj.exceptions import ConfigError
from jaxproj.projection import FullConfig, Projector
from jaxproj.skeleton import BONE_NAMES, BONES, N_JOINTS, J, descriptor

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
    [math.sin(ik.HEAD_PITCH_NEUTRAL), 0.0, math.cos(ik.HEAD_PITCH_NEUTRAL)], np.float64
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


def _check_pose(name: str) -> np.ndarray:
    if name not in BASIC_POSES:
        raise ConfigError(f"unknown pose {name!r}; use one of {POSE_NAMES}")
    return BASIC_POSES[name]


def basic_pose_angles(bones: str = "upper") -> dict[str, dict[str, float]]:
    """IK ground truth of every basic pose: name -> {driven joint: degrees}."""
    out = {}
    for name, dirs in BASIC_POSES.items():
        d, _ = descriptor(skeleton_from_directions(dirs), bones=bones)
        q = np.degrees(np.asarray(ik.solve_driven(d, bones), np.float64))
        out[name] = {j: float(v) for j, v in zip(robot.DRIVEN_JOINTS, q, strict=True)}
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
    (y) axis (0 forward, +90 deg down, -90 deg up, as the NAO's ShoulderPitch), ``r`` is the
    elevation towards +y (left). Undefined (``p = 0``) along +/-y.
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
    so an arm raised from hanging to up swings through the front, as the NAO's ShoulderPitch
    does, and never over the shoulder axis (where ShoulderPitch is undefined and a
    sideways-horizontal arm would need more than the NAO's 76 deg of ShoulderRoll); every other
    bone is slerped. ``s = 0`` gives ``a``, ``s = 1`` gives ``b`` (up to round-off).
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
    target = _check_pose(pose_name).astype(np.float64)
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


# ------------------------------------------------------------------------------ experiments


def _bones_of(model: engine.Model | Projector) -> tuple[str, bool]:
    if isinstance(model, engine.Model):
        return model.config.bones, model.config.mirror
    return "upper", False


def _batch_size(n: int) -> int:
    """Power-of-two batch (256..4096): few distinct shapes, so few compiles."""
    return int(min(4096, max(256, 2 ** math.ceil(math.log2(max(n, 1))))))


def _ik(d: np.ndarray, bones: str) -> np.ndarray:
    """``ik.solve_driven`` on a padded power-of-two batch (one compile for many sizes)."""
    n = len(d)
    size = _batch_size(n) if n <= 4096 else n
    padded = np.concatenate([d, np.repeat(d[:1], size - n, axis=0)]) if size > n else d
    return np.asarray(ik.solve_driven(padded, bones))[:n]


def _descriptors(model: engine.Model | Projector, positions: np.ndarray) -> np.ndarray:
    """``(F, 20, 3)`` -> ``(F, m)`` descriptors with the model's bones; all must be valid."""
    bones, mirror = _bones_of(model)
    d, ok = descriptor(positions, bones=bones, mirror=mirror)
    d, ok = np.asarray(d), np.asarray(ok)
    if not ok.all():
        raise ConfigError(f"{int((~ok).sum())} synthetic frames have a degenerate descriptor")
    return d


def _nearest_landmark_deg(p: Projector, d: np.ndarray) -> np.ndarray:
    """``(F, m)`` -> ``(F,)``: worst bone angle (deg) to the nearest landmark (Euclidean)."""
    human = np.asarray(p.human, np.float64)
    d = np.asarray(d, np.float64)
    idx = np.argmin(np.sum((d[:, None, :] - human[None]) ** 2, axis=-1), axis=1)
    a = d.reshape(len(d), -1, 3)
    b = human[idx].reshape(len(d), -1, 3)
    cos = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max(axis=-1)


def _motion_set(
    key: jax.Array,
    names: Sequence[str],
    seconds: float,
    fps: float,
    noise_std: float | np.ndarray | None,
    lengths: np.ndarray | None,
) -> np.ndarray:
    """``(len(names), T, 20, 3)``; motion ``POSE_i`` uses ``fold_in(key, i)``."""
    return np.stack(
        [
            basic_motion(
                n,
                seconds=seconds,
                fps=fps,
                noise_std=noise_std,
                key=jax.random.fold_in(key, POSE_NAMES.index(n) + 1),
                lengths=lengths,
            )
            for n in names
        ]
    )


def run_pose_experiments(
    model: engine.Model | Projector,
    *,
    n_l: int = 10,
    n_m: int = 10,
    objectives: Sequence[str] = ("relaxed", "full"),
    key: jax.Array,
    seconds: float = 2.0,
    fps: float = DEFAULT_FPS,
    noise_std: float | np.ndarray | None = None,
    lengths: np.ndarray | None = None,
    full: FullConfig | None = None,
    poses: Sequence[str] = POSE_NAMES,
) -> dict:
    """The paper's pose and motion benchmarks (figs. "pose reconstruct" and "statistics").

    Static poses are noise-free; motions are ``basic_motion`` with noise (motion ``POSE_i`` uses
    ``jax.random.fold_in(key, i)``, so the motions do not depend on which poses are run). Every
    error compares the projection of a frame with the IK of the same frame. ``coverage_deg``
    says how far a pose (or the farthest frame of its motion) lies from the landmarks: the
    largest bone angle between it and its nearest landmark.

    Args:
      model: a ``Model`` (its descriptor bones / mirror are used) or a bare ``Projector``
        (upper-body bones).
      n_l, n_m: ``L`` and ``M``.
      objectives: projection objectives to run.
      key: ``jax.random`` key of the motion noise.
      seconds, fps, noise_std, lengths: as in ``basic_motion``.
      full: settings of the full objective.
      poses: which basic poses / motions.

    Returns:
      JSON-ready dict::

        {"landmarks", "L", "M", "frames_per_motion", "fps", "noise_std_m" (pooled or given),
         "truth_deg": {pose: {joint: deg}},
         "coverage_deg": {pose: {"pose", "motion_max"}},
         "poses": {pose: {objective: {"M_max", "M_avg", "joint_errors_deg": {joint: deg}}}},
         "motions": {pose: {objective: {"M_max": [T], "M_avg": [T], "M_max_max", "M_max_mean",
                                        "M_avg_max", "M_avg_mean",
                                        "joint_max_deg": {joint: max over frames}}}},
         "summary": {objective: {"pose_M_max_max", "pose_M_avg_mean", "motion_M_max_max",
                                 "motion_M_avg_mean", "motions_within_10deg",
                                 "pose_M_max_max_excl_elbow_yaw",
                                 "motion_M_max_max_excl_elbow_yaw"}}}

    ElbowYaw is reported apart in the summary because the IK's ElbowYaw of a (nearly) straight
    arm is ill-defined (module docstring).
    """
    for n in poses:
        _check_pose(n)
    p = model.projector if isinstance(model, engine.Model) else model
    engine.check_neighbours(p, n_l, n_m)
    bones, _ = _bones_of(model)
    pose_pos = skeleton_from_directions(np.stack([BASIC_POSES[n] for n in poses]), lengths)
    motions = _motion_set(key, poses, seconds, fps, noise_std, lengths)
    n_p, t = len(poses), motions.shape[1]
    frames = np.concatenate([pose_pos, motions.reshape(-1, N_JOINTS, 3)])
    if noise_std is None:
        noise_val: float | list[float] = float(kinect_noise_std())
    else:
        arr = np.asarray(noise_std, np.float64)
        noise_val = float(arr) if arr.ndim == 0 else arr.tolist()
    out: dict = {
        "landmarks": int(p.n_landmarks),
        "L": n_l,
        "M": n_m,
        "frames_per_motion": int(t),
        "fps": float(fps),
        "noise_std_m": noise_val,
        "truth_deg": {},
        "coverage_deg": {},
        "poses": {n: {} for n in poses},
        "motions": {n: {} for n in poses},
        "summary": {},
    }
    d = _descriptors(model, frames)
    truth = _ik(d, bones)
    truth_deg = np.degrees(truth.astype(np.float64))
    cover = _nearest_landmark_deg(p, d)
    joints = robot.DRIVEN_JOINTS
    for objective in objectives:
        pred, _ = engine.project(
            model, d, objective, n_l=n_l, n_m=n_m, full=full, batch_size=_batch_size(len(d))
        )
        m_max, m_avg = frame_errors(pred, truth)
        err = np.degrees(np.abs(pred.astype(np.float64) - truth))  # (F, n)
        mm_max, mm_avg = m_max[n_p:].reshape(n_p, t), m_avg[n_p:].reshape(n_p, t)
        m_err = err[n_p:].reshape(n_p, t, -1)
        for i, n in enumerate(poses):
            out["poses"][n][objective] = {
                "M_max": float(m_max[i]),
                "M_avg": float(m_avg[i]),
                "joint_errors_deg": dict(zip(joints, err[i].tolist(), strict=True)),
            }
            out["motions"][n][objective] = {
                "M_max": mm_max[i].tolist(),
                "M_avg": mm_avg[i].tolist(),
                "M_max_max": float(mm_max[i].max()),
                "M_max_mean": float(mm_max[i].mean()),
                "M_avg_max": float(mm_avg[i].max()),
                "M_avg_mean": float(mm_avg[i].mean()),
                "joint_max_deg": dict(zip(joints, m_err[i].max(axis=0).tolist(), strict=True)),
            }
        no_yaw = err[:, [i for i, j in enumerate(joints) if "ElbowYaw" not in j]].max(axis=1)
        out["summary"][objective] = {
            "pose_M_max_max": float(m_max[:n_p].max()),
            "pose_M_avg_mean": float(m_avg[:n_p].mean()),
            "motion_M_max_max": float(mm_max.max()),
            "motion_M_avg_mean": float(mm_avg.mean()),
            "motions_within_10deg": int((mm_max.max(axis=1) < 10.0).sum()),
            "pose_M_max_max_excl_elbow_yaw": float(no_yaw[:n_p].max()),
            "motion_M_max_max_excl_elbow_yaw": float(no_yaw[n_p:].max()),
        }
    for i, n in enumerate(poses):
        out["truth_deg"][n] = dict(zip(joints, truth_deg[i].tolist(), strict=True))
        out["coverage_deg"][n] = {
            "pose": float(cover[i]),
            "motion_max": float(cover[n_p + i * t : n_p + (i + 1) * t].max()),
        }
    return out


def _held_out_metrics(
    model: engine.Model, eval_descriptors: np.ndarray, objective: str, n_l: int, n_m: int
) -> dict[str, float]:
    bones = model.config.bones
    h = np.asarray(eval_descriptors, np.float32)
    truth = _ik(h, bones)
    pred, _ = engine.project(model, h, objective, n_l=n_l, n_m=n_m, batch_size=_batch_size(len(h)))
    m_max, m_avg = frame_errors(pred, truth)
    a, x = describe(m_avg), describe(m_max)
    return {
        "M_avg_median": a["median"],
        "M_avg_mean": a["mean"],
        "M_max_median": x["median"],
        "M_max_p95": x["p95"],
        "eval_frames": a["n"],
    }


def landmark_size_study(
    train_descriptors: np.ndarray,
    sizes: Sequence[int] = (1644, 961, 86),
    *,
    objective: str = "relaxed",
    key: jax.Array,
    eval_descriptors: np.ndarray | None = None,
    config: engine.BuildConfig | None = None,
    n_l: int = 10,
    n_m: int = 10,
    noise_std: float | np.ndarray | None = None,
    progress: bool = False,
) -> dict:
    """The paper's landmark-size study: one model per target size, POSE_8 and its motion.

    Args:
      train_descriptors: ``(N, m)`` valid training descriptors.
      sizes: target landmark counts (the mean-shift bandwidth is bisected to reach each).
      objective: projection objective.
      key: ``jax.random`` key of the POSE_8 motion noise (the same motion for every size).
      eval_descriptors: optional ``(E, m)`` held-out valid descriptors.
      config: base ``BuildConfig`` (its ``landmarks`` / ``bandwidth`` are replaced per size).
      n_l, n_m: ``L`` and ``M`` (clipped to the landmark count for tiny sets).
      noise_std: motion noise, as in ``basic_motion``.
      progress: print one line per size.

    Returns:
      ``{"objective", "L", "M", "sizes": [row, ...]}``, one row per size with ``"target"``,
      ``"landmarks"`` (count reached), ``"bandwidth"``, ``"build_s"``, ``"pose8_static_M_max"``,
      ``"pose8_static_M_avg"`` (the noise-free pose), ``"pose8_M_max"`` (max M_max over the
      POSE_8 motion, the value ``report.plot_landmark_size`` draws), ``"pose8_M_max_mean"``,
      ``"pose8_M_avg_mean"``, ``"pose8_M_max_frames"`` (per frame) and, with
      ``eval_descriptors``, ``"M_avg_median"``, ``"M_avg_mean"``, ``"M_max_median"``,
      ``"M_max_p95"``, ``"eval_frames"``.
    """
    base = config or engine.BuildConfig()
    rows = []
    for size in sizes:
        cfg = dataclasses.replace(base, landmarks=int(size), bandwidth=None)
        t0 = time.perf_counter()
        model = engine.build(train_descriptors, cfg)
        build_s = time.perf_counter() - t0
        k = model.n_landmarks
        ll, mm = min(n_l, k), min(n_m, k)
        res = run_pose_experiments(
            model, n_l=ll, n_m=mm, objectives=(objective,), key=key, noise_std=noise_std,
            poses=("POSE_8",),
        )  # fmt: skip
        pose = res["poses"]["POSE_8"][objective]
        motion = res["motions"]["POSE_8"][objective]
        row = {
            "target": int(size),
            "landmarks": int(k),
            "bandwidth": model.bandwidth,
            "build_s": build_s,
            "L": ll,
            "M": mm,
            "pose8_static_M_max": pose["M_max"],
            "pose8_static_M_avg": pose["M_avg"],
            "pose8_M_max": motion["M_max_max"],
            "pose8_M_max_mean": motion["M_max_mean"],
            "pose8_M_avg_mean": motion["M_avg_mean"],
            "pose8_M_max_frames": motion["M_max"],
        }
        if eval_descriptors is not None:
            row.update(_held_out_metrics(model, eval_descriptors, objective, ll, mm))
        rows.append(row)
        if progress:
            print(f"landmarks {size}: {k} reached, build {build_s:.1f} s", flush=True)
    return {"objective": objective, "L": n_l, "M": n_m, "sizes": rows}


def _bytes_per_query(p: Projector, n_l: int, n_m: int) -> int:
    """Rough peak memory of one projection in a vmapped batch: the ``L x M`` backward kernels
    it evaluates are gathered per query (``out``: hidden x m, plus bias and features)."""
    bank = p.backward
    return 4 * n_l * n_m * bank.hidden * (bank.d_out + 3)


def efficiency_study(
    model: engine.Model | Projector,
    descriptors: np.ndarray,
    ls: Sequence[int] = (10, 20, 30, 40, 50),
    objective: str = "relaxed",
    batch: int = 4096,
    *,
    repeats: int = 3,
    full: FullConfig | None = None,
    max_bytes: int = 2**31,
) -> dict:
    """Time per projection and accuracy for ``L = M`` in ``ls`` (paper: "efficiency").

    Timing: one jitted batch (the first descriptors, repeated if fewer); the first call
    (compile included) is timed apart as ``compile_s``, then the median of ``repeats`` calls,
    each ended by ``block_until_ready``, divided by the batch size. Accuracy: all of
    ``descriptors`` projected and compared with their IK.

    The batch is ``batch`` halved until its estimated working set fits ``max_bytes``: a
    vmapped projection gathers its ``L x M`` backward kernels per query (~5.8 kB each for
    hidden 96, m 15), so 4096 queries at ``L = M = 50`` would need ~60 GB. Each row reports the
    batch it used.

    Args:
      model: a ``Model`` or a bare ``Projector`` (upper-body bones).
      descriptors: ``(B, m)`` valid descriptors.
      ls: neighbourhood sizes (``L = M``), each ``<=`` the landmark count.
      objective: ``"relaxed"`` or ``"full"``.
      batch: largest number of queries per call.
      repeats: timed calls per size.
      full: settings of the full objective.
      max_bytes: memory budget of one batch (estimate).

    Returns:
      ``{"objective", "batch", "device", "n_queries", "rows": [{"L", "M", "batch",
      "us_per_projection", "compile_s", "M_avg_median", "M_avg_mean", "M_max_p95"}, ...]}``.
    """
    p = model.projector if isinstance(model, engine.Model) else model
    bones, _ = _bones_of(model)
    if objective not in ("relaxed", "full"):
        raise ConfigError(f"objective must be 'relaxed' or 'full', got {objective!r}")
    if repeats < 1 or batch < 1:
        raise ConfigError("repeats and batch must be >= 1")
    h = np.asarray(descriptors, np.float32)
    if h.ndim != 2 or len(h) == 0:
        raise ConfigError(f"descriptors must be (B >= 1, m), got {h.shape}")
    for n in ls:
        engine.check_neighbours(p, n, n)
    full = FullConfig() if full is None else full
    truth = _ik(h, bones)
    rows = []
    for n in ls:
        b = int(batch)
        while b > 1 and b * _bytes_per_query(p, n, n) > max_bytes:
            b //= 2
        chunk = jnp.asarray(np.resize(h, (b, h.shape[1])))
        t0 = time.perf_counter()
        jax.block_until_ready(engine.project_chunk(p, chunk, objective, n, n, full))
        compile_s = time.perf_counter() - t0
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(engine.project_chunk(p, chunk, objective, n, n, full))
            times.append(time.perf_counter() - t0)
        pred, _ = engine.project(model, h, objective, n_l=n, n_m=n, full=full, batch_size=b)
        m_max, m_avg = frame_errors(pred, truth)
        rows.append(
            {
                "L": int(n),
                "M": int(n),
                "batch": b,
                "us_per_projection": float(np.median(times)) / b * 1e6,
                "compile_s": compile_s,
                "M_avg_median": float(np.median(m_avg)),
                "M_avg_mean": float(np.mean(m_avg)),
                "M_max_p95": float(np.percentile(m_max, 95)),
            }
        )
    return {
        "objective": objective,
        "batch": int(batch),
        "device": str(jax.devices()[0]),
        "n_queries": int(len(h)),
        "rows": rows,
    }


__all__ = [
    "BASIC_POSES",
    "NEUTRAL_NECK",
    "POSE_DESCRIPTIONS",
    "POSE_NAMES",
    "basic_motion",
    "basic_pose_angles",
    "ARM_BONES",
    "ease_in_out",
    "from_shoulder_coordinates",
    "interpolate_pose",
    "shoulder_coordinates",
    "efficiency_study",
    "kinect_noise_std",
    "landmark_size_study",
    "median_bone_lengths",
    "n_motion_frames",
    "run_pose_experiments",
    "skeleton_from_directions",
]
