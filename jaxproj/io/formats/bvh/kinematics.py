"""BVH forward kinematics and the Kinect skeleton of a clip.

Step 2 of ``jaxproj.io.formats.bvh`` (``forward_kinematics``: every joint of every frame in the
file's axes and units, vectorised over frames) and the last step of step 3 (``kinect_positions``:
the 20 Kinect joints from a resolved joint map, derived joints filled in, scaled, turned into
Kinect camera axes by ``BVH_TO_KINECT``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from jaxproj.errors import InputError
from jaxproj.io.formats.bvh.joint_maps import HAND_EXTENSION, TARGET_SKELETON
from jaxproj.io.formats.bvh.parser import POSITION_AXES, ROTATION_AXES, BvhClip

BVH_TO_KINECT = np.diag([-1.0, 1.0, -1.0])
"""BVH axes -> Kinect camera-space axes: a 180 degree turn about y (a rotation, det +1)."""


def _axis_rotations(angles: np.ndarray, axis: int) -> np.ndarray:
    """``(T,)`` radians about ``axis`` (0 x, 1 y, 2 z) -> ``(T, 3, 3)`` rotation matrices."""
    c, s = np.cos(angles), np.sin(angles)
    r = np.zeros(angles.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r[:, axis, axis] = 1.0
    r[:, i, i] = c
    r[:, j, j] = c
    r[:, i, j] = -s
    r[:, j, i] = s
    return r


def forward_kinematics(clip: BvhClip, scale: float = 1.0) -> np.ndarray:
    """Positions of every joint (End Sites included) in every frame.

    Args:
      clip: from ``parse_bvh``.
      scale: multiplies offsets and position channels (e.g. ``CMU_SCALE`` for metres).

    Returns:
      ``(T, J, 3)`` float64 positions in the file's axes (``clip.names`` order); frames with
      non-finite channel values give non-finite positions.
    """
    return joint_transforms(clip, scale)[0]


def joint_transforms(clip: BvhClip, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Positions and global rotations of every joint in every frame (``forward_kinematics``
    with the rotations too: rotation channels multiplied in file order, ``R_joint = R_parent @
    R_local``, ``p = p_parent + R_parent @ offset``).

    Returns:
      ``(T, J, 3)`` float64 positions (file axes, ``scale`` applied) and ``(T, J, 3, 3)``
      global rotations (a joint without rotation channels keeps its parent's).
    """
    t = clip.n_frames
    n = len(clip.names)
    pos = np.zeros((t, n, 3))
    rot = np.zeros((t, n, 3, 3))
    col = 0
    with np.errstate(invalid="ignore", over="ignore"):
        for j in range(n):
            local_t = np.broadcast_to(clip.offsets[j] * scale, (t, 3)).copy()
            local_r = None
            for name in clip.channels[j]:
                values = clip.motion[:, col]
                col += 1
                if name in POSITION_AXES:
                    local_t[:, POSITION_AXES[name]] = values * scale
                else:
                    r = _axis_rotations(np.radians(values), ROTATION_AXES[name])
                    local_r = r if local_r is None else local_r @ r
            p = int(clip.parents[j])
            if p < 0:
                pos[:, j] = local_t
                rot[:, j] = np.eye(3) if local_r is None else local_r
            else:
                pos[:, j] = pos[:, p] + np.einsum("tij,tj->ti", rot[:, p], local_t)
                rot[:, j] = rot[:, p] if local_r is None else rot[:, p] @ local_r
    return pos, rot


def kinect_positions(
    clip: BvhClip, table: Mapping[str, str], scale: float, points: np.ndarray | None = None
) -> np.ndarray:
    """The 20 Kinect joints of every frame from a resolved joint map (missing joints derived), in
    the joint order of ``TARGET_SKELETON`` (Kinect v1).

    Args:
      clip: the parsed file.
      table: Kinect joint -> BVH joint (``resolve_joint_map``).
      scale: metres per file unit.
      points: ``forward_kinematics(clip, scale)`` if already computed.

    Returns:
      ``(T, 20, 3)`` float64 metres in Kinect SDK joint order and Kinect axes
      (``BVH_TO_KINECT``).
    """
    p = forward_kinematics(clip, scale) if points is None else points
    out = np.zeros((p.shape[0], TARGET_SKELETON.n_joints, 3))
    k = TARGET_SKELETON.index

    def get(name: str) -> np.ndarray:
        return out[:, k[name]]

    for name, joint in table.items():
        out[:, k[name]] = p[:, clip.index(joint)]
    with np.errstate(invalid="ignore", over="ignore"):
        if "HipCenter" not in table:
            out[:, k["HipCenter"]] = p[:, 0]
        if "ShoulderCenter" not in table:
            out[:, k["ShoulderCenter"]] = 0.5 * (get("ShoulderLeft") + get("ShoulderRight"))
        if "Spine" not in table:
            out[:, k["Spine"]] = 0.5 * (get("HipCenter") + get("ShoulderCenter"))
        for side in ("Left", "Right"):
            wrist, elbow = get(f"Wrist{side}"), get(f"Elbow{side}")
            if f"Hand{side}" not in table:
                out[:, k[f"Hand{side}"]] = wrist + HAND_EXTENSION * (wrist - elbow)
            if f"Foot{side}" not in table:
                ankle = clip.index(table[f"Ankle{side}"])
                children = np.flatnonzero(clip.parents == ankle)
                if not children.size:
                    raise InputError(
                        clip.source,
                        f"cannot derive Foot{side}: the ankle's BVH joint {clip.names[ankle]} "
                        f"has no child; map Foot{side} in the joint map",
                    )
                out[:, k[f"Foot{side}"]] = p[:, int(children[0])]
    return out @ BVH_TO_KINECT.T
