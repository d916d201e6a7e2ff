"""Hips made from the shoulders: a body frame for upper-body robots when the hips are hidden.

The descriptor reads every bone in the person's body frame, whose up axis runs from the pelvis
centre to the spine top (``skeleton.body_frame``). A desk webcam sees the head, the shoulders
and the arms; the hips are below the table or out of the picture, and a tracker that still
places them (MediaPipe: visibility 0.26-0.34 on such a recording) guesses. A robot whose chains
read no bone below the spine top (``skeletons.UPPER_BODY``: the neck and the arms, a robot of
head and arms) needs the hips for that one axis only, so ``hips_from_shoulders`` makes them:

* the **up axis** of a frame with hidden hips is the capture's up (+y, every reader's output)
  made orthogonal to the shoulder line, then turned about the shoulder line by the trunk's
  **median tilt** against that axis on the frames that show the hips (the person's lean and the
  camera's pitch; 0 where no frame shows them: a person sitting upright before a level camera);
* the pelvis centre (Kinect v1 ``HipCenter``) lies that axis times the **trunk's median
  length** below the spine top (on the frames that show the hips; else ``TRUNK_PER_SHOULDERS``
  times the median shoulder width); the spine's middle halfway; the hip joints
  ``HIP_PER_SHOULDERS`` of the shoulder width apart along the shoulder line; the legs hang
  straight below them (for figures only: a robot that reads a leg bone must not read such a
  frame, and ``retarget`` uses this only where none does).

The body frame of such a frame is then the capture-up frame (tilted by the median lean), its
left axis the shoulder line as before, so the arms and the neck are read as before against an
upright trunk. Measured against the hips' own frame on recordings that have both:
``python -m benchmarks.upper_frame`` (the results page, "Upper body without hips").
"""

from __future__ import annotations

import numpy as np

from jaxproj.human import skeletons

TRUNK_PER_SHOULDERS = 1.35
"""Trunk length (pelvis centre -> spine top) per shoulder width where no frame shows the hips (an
adult's 0.50 m over 0.37 m; the bundled MSR Action3D's median ratio is 1.3-1.4)."""

HIP_PER_SHOULDERS = 0.5
"""Distance between the made hip joints per shoulder width (Kinect v1's hips: about 0.18 m)."""

THIGH_PER_TRUNK = 0.85
"""Made thigh (and shin) length per trunk length (an adult's 0.42 m over 0.50 m)."""

_K = skeletons.KINECT_V1.index


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def shoulder_axes(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T, 3)`` unit shoulder line (right -> left) and ``(T, 3)`` capture up (+y) made
    orthogonal to it, of ``(T, 20, 3)`` Kinect v1 positions."""
    p = np.asarray(positions, np.float64)
    left = _unit(p[:, _K["ShoulderLeft"]] - p[:, _K["ShoulderRight"]])
    up = np.broadcast_to(np.array([0.0, 1.0, 0.0]), left.shape)
    up = _unit(up - np.sum(up * left, axis=-1, keepdims=True) * left)
    return left, up


def trunk_tilt(positions: np.ndarray, frames: np.ndarray) -> float:
    """Median signed angle (rad) about the shoulder line from the capture's up (made orthogonal
    to it) to the trunk (pelvis centre -> spine top), over ``frames`` ((T,) bool); 0 if none.
    Positive: the trunk leans forward (towards ``left x up``)."""
    idx = np.flatnonzero(np.asarray(frames, bool))
    if idx.size == 0:
        return 0.0
    p = np.asarray(positions, np.float64)[idx]
    left, up = shoulder_axes(p)
    trunk = p[:, _K["ShoulderCenter"]] - p[:, _K["HipCenter"]]
    trunk = _unit(trunk - np.sum(trunk * left, axis=-1, keepdims=True) * left)
    forward = np.cross(left, up)
    return float(np.median(np.arctan2(np.sum(trunk * forward, -1), np.sum(trunk * up, -1))))


def hips_from_shoulders(
    positions: np.ndarray, hidden: np.ndarray, seen: np.ndarray
) -> tuple[np.ndarray, float]:
    """Kinect v1 positions with the pelvis, spine and legs of the ``hidden`` frames made from the
    shoulders (module doc).

    Args:
      positions: ``(T, 20, 3)`` Kinect v1 layout, y up (every reader's output).
      hidden: ``(T,)`` bool, the frames whose hips are to be made.
      seen: ``(T,)`` bool, frames whose hips are the person's (the median tilt and trunk length).

    Returns:
      ``((T, 20, 3)`` float32 positions (the other frames unchanged), the tilt used, rad).
    """
    out = np.array(positions, np.float32)
    hidden = np.asarray(hidden, bool)
    seen = np.asarray(seen, bool) & ~hidden
    tilt = trunk_tilt(out, seen)
    if not hidden.any():
        return out, tilt
    p = out.astype(np.float64)
    width = np.linalg.norm(p[:, _K["ShoulderLeft"]] - p[:, _K["ShoulderRight"]], axis=-1)
    if seen.any():
        trunk = np.linalg.norm(p[:, _K["ShoulderCenter"]] - p[:, _K["HipCenter"]], axis=-1)
        length = float(np.median(trunk[seen]))
    else:
        length = TRUNK_PER_SHOULDERS * float(np.median(width[hidden]))
    h = p[hidden]
    left, up = shoulder_axes(h)
    forward = np.cross(left, up)
    up = np.cos(tilt) * up + np.sin(tilt) * forward  # the median lean, about the shoulder line
    forward = np.cross(left, up)
    top = h[:, _K["ShoulderCenter"]]
    centre = top - length * up
    half = 0.5 * HIP_PER_SHOULDERS * width[hidden, None] * left
    leg = THIGH_PER_TRUNK * length * up
    made = {
        "HipCenter": centre,
        "Spine": 0.5 * (centre + top),
        "HipLeft": centre + half,
        "HipRight": centre - half,
    }
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        hip = centre + sign * half
        made[f"Knee{side}"] = hip - leg
        made[f"Ankle{side}"] = hip - 2.0 * leg
        made[f"Foot{side}"] = hip - 2.0 * leg + 0.25 * length * forward
    for name, value in made.items():
        h[:, _K[name]] = value
    out[hidden] = h.astype(np.float32)
    return out, tilt


HIP_BONES = frozenset(
    ("spine_lower", "pelvis_left", "pelvis_right", "thigh_left", "thigh_right", "shin_left",
     "shin_right", "foot_left", "foot_right")
)  # fmt: skip
"""The canonical bones that read the hips or the legs."""


def hips_rule(bones: str | tuple[str, ...], root: str) -> str:
    """``read_skeleton(hips=)`` for a retargeting: ``"shoulders"`` where the descriptor reads no
    bone of the hips or legs and the base is fixed (``root="fixed"``: a frame whose hips are
    hidden still drives the arms and the head), else ``"required"``."""
    if root == "fixed" and not HIP_BONES & set(skeletons.resolve_bones(bones)):
        return "shoulders"
    return "required"
