"""The same motion in every skeleton layout: how far each retargets from its Kinect v1 twin.

(Issue 45, items 3 and 4.) One motion, the two bundled CMU BVH clips (``tests/data/cmu_bvh``,
3 s of each at 10 fps), is written in the file format of every registered skeleton layout and
read back through ``jaxproj.io.readers.read_skeleton``; each reading is retargeted to both robots
with the IK and compared with the Kinect v1 reading of the same frames.

Part A, ``--write DIR``: the CMU hierarchy's forward kinematics (joint positions and each joint's
global rotation), then, per layout, the positions of the layout's recorded joints
(``Skeleton.sensor_joints``) made from the CMU joints through the joint maps below (``LAYOUT_MAPS``:
one line per joint, the CMU joint it is, or how it is made where CMU has none), each written in
its format's own file layout, units and axes:

- ``kinect_v1``: CSV, 60 columns (the reference: the ``cmu`` joint map of the BVH reader,
  ``JOINT_MAPS["cmu"]``, so it equals ``read_skeleton(bvh, bvh_map="cmu")``), Kinect camera space
  (metres; x to the sensor's left, y up, z away from the sensor; the performer ~3 m away);
- ``kinect_v2``: NTU RGB+D ``.skeleton`` text (frame count; per frame the body count; per body
  the 10-value body line, the joint count 25 and 25 lines of 12 values, trackingState 2), the
  same camera space;
- ``azure_kinect``: the Body Tracking SDK's offline processor JSON (``frames`` of ``bodies`` with
  32 ``joint_positions`` in millimetres, Azure depth-camera axes: x right, y down, z away from
  the camera);
- ``smpl`` (24 joints) and ``smplx`` (22): NPZ with ``joints`` ``(T, J, 3)`` metres in SMPL's own
  axes (y up, the body facing +z, its left at +x: the BVH's axes), ``skeleton`` and ``fps``;
- ``mediapipe_pose``: JSON, a list of frames of 33 ``{x, y, z, visibility}`` world landmarks
  (metres, origin midway between the hips, image axes: x right, y down, z away from the camera).

Part B, ``--measure [DIR]`` (default the committed ``tests/data/formats/same_motion``): per layout
and robot (NAO H25, ``bones="upper"``; Unitree G1, ``bones="full"``; ``method="ik"``, no smoothing,
the default neck levelling), the per-frame mean absolute joint-angle difference from the Kinect v1
reading over the robot's driven joints (deg; median and p95 over the frames of both clips) and
each driven joint's median / p95 / max; the descriptor difference per canonical bone (angle
between the two unit vectors, deg; the layouts' bones on the Kinect v1 layout the readers give);
and, as a check of writer and reader, the largest descriptor difference between the file's
reading and the in-memory positions it was written from. The NAO is also run without neck
levelling (``neck_neutral=None``), where a layout's neck difference reaches HeadPitch whole.

    python -m benchmarks.experiments.skeleton_layouts --write tests/data/formats/same_motion
    python -m benchmarks.experiments.skeleton_layouts --measure \\
        [--json benchmarks/results/skeleton_layouts_cpu.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import jax
import numpy as np

from jaxproj import robots
from jaxproj.human import skeletons
from jaxproj.human.skeleton import body_frame, descriptor
from jaxproj.human.skeletons import BONE_NAMES
from jaxproj.io.formats.bvh import (
    BVH_TO_KINECT,
    CMU_SCALE,
    JOINT_MAPS,
    kinect_positions,
    parse_bvh,
)
from jaxproj.io.formats.bvh.kinematics import joint_transforms
from jaxproj.io.formats.bvh.parser import BvhClip
from jaxproj.io.readers import read_skeleton
from jaxproj.motion.retarget import retarget

ROOT = Path(__file__).resolve().parents[2]
BVH_DIR = ROOT / "tests" / "data" / "cmu_bvh"
DEFAULT_DIR = ROOT / "tests" / "data" / "formats" / "same_motion"

CLIPS: dict[str, int] = {"131_01": 40, "131_03": 100}
"""Clip -> first frame (of the bundled 20 fps file) of the excerpt."""
STEP = 2
"""Every STEP-th frame of the bundled 20 fps files: 10 fps."""
FRAMES = 30
"""Frames per excerpt: 3 s at 10 fps."""
FPS = 20.0 / STEP

CAMERA_HEIGHT_M = 0.9
"""Kinect camera space: the sensor this high above the CMU floor (y = 0 there)."""
CAMERA_DISTANCE_M = 3.0
"""Kinect camera space: the performer's mean depth (z) over an excerpt."""

# --- Part A: forward kinematics with rotations ---------------------------------------------------


def cmu_pose(clip: BvhClip) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J, 3)`` metres (BVH axes) and ``(T, J, 3, 3)`` global rotations of every joint
    (``jaxproj.io.formats.bvh.kinematics.joint_transforms``)."""
    return joint_transforms(clip, CMU_SCALE)


class Cmu(NamedTuple):
    """One excerpt's CMU joints: positions (metres, BVH axes) and global rotations, by name."""

    clip: BvhClip
    pos: np.ndarray
    rot: np.ndarray

    def p(self, name: str) -> np.ndarray:
        return self.pos[:, self.clip.index(name)]

    def at(self, name: str, offset: tuple[float, float, float]) -> np.ndarray:
        """The point ``offset`` (metres; the joint's rest-pose axes, which are the BVH's: x the
        performer's left, y up, z forward) from joint ``name``, turned with the joint."""
        r = self.rot[:, self.clip.index(name)]
        return self.p(name) + np.einsum("tij,j->ti", r, np.asarray(offset))


Rule = Callable[[Cmu], np.ndarray]


def J(name: str) -> Rule:  # noqa: N802  (a joint map's entry: read as "joint")
    """The CMU joint itself."""
    return lambda c: c.p(name)


def Mid(a: str, b: str) -> Rule:  # noqa: N802
    """Midway between two CMU joints."""
    return lambda c: 0.5 * (c.p(a) + c.p(b))


def Lerp(a: str, b: str, f: float) -> Rule:  # noqa: N802
    """The point a fraction ``f`` of the way from CMU joint ``a`` to ``b``."""
    return lambda c: (1.0 - f) * c.p(a) + f * c.p(b)


def At(name: str, x: float, y: float, z: float) -> Rule:  # noqa: N802
    """A point fixed to a CMU joint: ``(x left, y up, z forward)`` metres in its frame."""
    return lambda c: c.at(name, (x, y, z))


def _face(head: str = "Head") -> dict[str, Rule]:
    """Face landmarks fixed to the head (metres in the CMU ``Head`` joint's frame). The ``cmu``
    joint map takes CMU ``Head`` as Kinect's head (the centre of the head: the ``Head`` joint
    sits 0.09 m below the top of the head, ``Head_End``), so the ears lie either side of it
    (their midpoint, MediaPipe's derived head centre, is that joint), the eyes 0.02 m above it
    and 0.07-0.085 m forward, the nose tip 0.10 m forward and 0.02 m below, the mouth corners
    0.05 m below. Sizes of an adult head; only the ears' midpoint enters a bone."""
    out: dict[str, Rule] = {"nose": At(head, 0.0, -0.02, 0.10)}
    for side, s in (("left", 1.0), ("right", -1.0)):
        out[f"{side}_eye_inner"] = At(head, s * 0.015, 0.02, 0.085)
        out[f"{side}_eye"] = At(head, s * 0.032, 0.02, 0.08)
        out[f"{side}_eye_outer"] = At(head, s * 0.048, 0.02, 0.07)
        out[f"{side}_ear"] = At(head, s * 0.075, 0.0, 0.0)
        out[f"mouth_{side}"] = At(head, s * 0.025, -0.05, 0.085)
    return out


# The CMU hierarchy (3dsMax-friendly release) has: Hips (root, ~0.09 m above the hip joints),
# lowerback (at Hips), Chest (0.11 m up), Chest2 (0.22 m), lowerneck (at Chest2), Neck (the base
# of the neck at shoulder height), Head, Head_End (top of the head); Left/RightCollar (at Chest2),
# *Shoulder, *Elbow, *Wrist, l/rhand (at the wrist), L/RFingers (the hand, 0.037 m on),
# L/RFingers_End (the fingertips), L/RThumb (at the wrist), L/RThumb_End (the thumb's tip);
# L/RHipJoint (at Hips), *Hip, *Knee, *Ankle, *Toe (ball of the foot), *Toe_End (the toes' tip).
# Rest pose: upright, arms hanging, palms facing the thighs with the thumbs forward.

KINECT_V1_MAP: dict[str, Rule] = {k: J(v) for k, v in JOINT_MAPS["cmu"].items()}
"""The reference: the BVH reader's ``cmu`` map (Spine = Chest, ShoulderCenter = Neck, Hand =
Fingers, Foot = Toe)."""

KINECT_V2_MAP: dict[str, Rule] = {
    # joints 0-19 mean what Kinect v1's do: the same CMU joints as the `cmu` map
    **{
        v2: KINECT_V1_MAP[v1]
        for v2, v1 in (
            ("SpineBase", "HipCenter"), ("SpineMid", "Spine"), ("Head", "Head"),
            ("SpineShoulder", "ShoulderCenter"),  # v2's spine top is v1's ShoulderCenter
            *((f"{j}{s}", f"{j}{s}") for s in ("Left", "Right")
              for j in ("Shoulder", "Elbow", "Wrist", "Hand", "Hip", "Knee", "Ankle", "Foot")),
        )
    },
    "Neck": Mid("Neck", "Head"),  # v2's own neck joint, midway up the neck (no CMU joint there)
    "HandTipLeft": J("LFingers_End"), "HandTipRight": J("RFingers_End"),  # fingertips
    "ThumbLeft": J("LThumb_End"), "ThumbRight": J("RThumb_End"),  # thumb tips
}  # fmt: skip
"""Kinect v2 (NTU RGB+D): every canonical bone at Kinect v1's joints: no difference expected."""

AZURE_MAP: dict[str, Rule] = {
    "PELVIS": J("Hips"),
    "SPINE_NAVEL": J("Chest"),  # the navel: Kinect v1's Spine joint
    "SPINE_CHEST": J("Chest2"),  # the chest, between the navel and the neck
    "NECK": J("Neck"),  # base of the neck: Kinect v1's ShoulderCenter
    # the clavicle joints sit inside and below the shoulders: a third of the way from the
    # clavicle's root (CMU *Collar, at Chest2) to the shoulder (no CMU joint there; no bone)
    "CLAVICLE_LEFT": Lerp("LeftCollar", "LeftShoulder", 1 / 3),
    "CLAVICLE_RIGHT": Lerp("RightCollar", "RightShoulder", 1 / 3),
    "HEAD": J("Head"),
    "NOSE": _face()["nose"],
    "EYE_LEFT": _face()["left_eye"], "EAR_LEFT": _face()["left_ear"],
    "EYE_RIGHT": _face()["right_eye"], "EAR_RIGHT": _face()["right_ear"],
    **{
        f"{j}_{side.upper()}": J(cmu)
        for side, s, h in (("left", "Left", "L"), ("right", "Right", "R"))
        for j, cmu in (
            ("SHOULDER", f"{s}Shoulder"), ("ELBOW", f"{s}Elbow"), ("WRIST", f"{s}Wrist"),
            ("HAND", f"{h}Fingers"), ("HANDTIP", f"{h}Fingers_End"), ("THUMB", f"{h}Thumb_End"),
            ("HIP", f"{s}Hip"), ("KNEE", f"{s}Knee"), ("ANKLE", f"{s}Ankle"),
            ("FOOT", f"{s}Toe"),
        )
    },
}  # fmt: skip
"""Azure Kinect: the canonical bones at Kinect v1's joints (the spine middle SPINE_NAVEL, the
spine top NECK): no difference expected."""

SMPL_MAP: dict[str, Rule] = {
    "pelvis": J("Hips"),  # SMPL's pelvis joint, like CMU's Hips, sits above the hip joints
    "spine1": Mid("Hips", "Chest"),  # lumbar (CMU lowerback coincides with Hips)
    "spine2": J("Chest"),  # the spine middle: Kinect v1's Spine joint
    "spine3": J("Chest2"),  # the chest
    "neck": J("Neck"),  # the base of the neck: Kinect v1's ShoulderCenter
    # SMPL's head joint is the top of the neck (the skull's base), not the head's centre:
    # 0.05 m below CMU Head (the head centre in the `cmu` map) along the head's own up axis, so
    # the neck bone differs from Kinect's where the head tilts on the neck
    "head": At("Head", 0.0, -0.05, 0.0),
    # the collar joints: inside and below the shoulders, as Azure's clavicles (no bone)
    "left_collar": Lerp("LeftCollar", "LeftShoulder", 1 / 3),
    "right_collar": Lerp("RightCollar", "RightShoulder", 1 / 3),
    **{
        f"{side}_{j}": J(cmu)
        for side, s, h in (("left", "Left", "L"), ("right", "Right", "R"))
        for j, cmu in (
            ("hip", f"{s}Hip"), ("knee", f"{s}Knee"), ("ankle", f"{s}Ankle"),
            ("foot", f"{s}Toe"),  # SMPL's foot joint is the ball of the foot
            ("shoulder", f"{s}Shoulder"), ("elbow", f"{s}Elbow"), ("wrist", f"{s}Wrist"),
            ("hand", f"{h}Fingers"),  # SMPL's hand joint: the knuckles (SMPL-X has none)
        )
    },
}  # fmt: skip
"""SMPL: Kinect v1's joints but the head (the skull's base): the neck bone differs."""

SMPLX_MAP: dict[str, Rule] = {j: SMPL_MAP[j] for j in skeletons.get("smplx").sensor_joints}
"""SMPL-X's first 22 joints: SMPL's without the hands."""

MEDIAPIPE_MAP: dict[str, Rule] = {
    **_face(),  # nose, eyes, ears (their midpoint: CMU Head), mouth
    **{
        f"{side}_{j}": rule
        for side, s, h in (("left", "Left", "L"), ("right", "Right", "R"))
        for j, rule in (
            ("shoulder", J(f"{s}Shoulder")), ("elbow", J(f"{s}Elbow")), ("wrist", J(f"{s}Wrist")),
            # the index and pinky knuckles: 0.02 m either side of the middle of the knuckles
            # (CMU *Fingers) across the palm (the hand's forward axis, where the thumb points in
            # the rest pose): their midpoint, MediaPipe's derived hand, is CMU *Fingers
            ("index", At(f"{h}Fingers", 0.0, 0.0, 0.02)),
            ("pinky", At(f"{h}Fingers", 0.0, 0.0, -0.02)),
            ("thumb", J(f"{h}Thumb_End")),  # the thumb's tip
            # the hips are the hip joints themselves: their midpoint (the derived pelvis centre)
            # lies ~0.09 m below and 0.04 m in front of CMU Hips, Kinect v1's HipCenter
            ("hip", J(f"{s}Hip")), ("knee", J(f"{s}Knee")), ("ankle", J(f"{s}Ankle")),
            # heel: 0.06 m below and 0.05 m behind the ankle, turned with it (no CMU joint)
            ("heel", At(f"{s}Ankle", 0.0, -0.06, -0.05)),
            ("foot_index", J(f"{s}Toe_End")),  # the tip of the toes, not the ball of the foot
        )
    },
}  # fmt: skip
"""MediaPipe Pose: no spine joints; the derived spine top (mid shoulders) lies ~0.02 m below and
behind CMU Neck, the pelvis centre (mid hips) below CMU Hips: the body frame's up axis, hence
every bone in it, tilts, and the spine, pelvis, clavicle, neck and foot bones differ."""

LAYOUT_MAPS: dict[str, dict[str, Rule]] = {
    "kinect_v1": KINECT_V1_MAP,
    "kinect_v2": KINECT_V2_MAP,
    "azure_kinect": AZURE_MAP,
    "smpl": SMPL_MAP,
    "smplx": SMPLX_MAP,
    "mediapipe_pose": MEDIAPIPE_MAP,
}
"""Layout -> (its recorded joint -> how it is made from the CMU joints)."""

SUFFIX = {
    "kinect_v1": "csv",
    "kinect_v2": "skeleton",
    "azure_kinect": "json",
    "smpl": "npz",
    "smplx": "npz",
    "mediapipe_pose": "json",
}


def excerpt(name: str) -> Cmu:
    clip = parse_bvh(BVH_DIR / f"{name}_every6.bvh")
    pos, rot = cmu_pose(clip)
    keep = slice(CLIPS[name], CLIPS[name] + STEP * FRAMES, STEP)
    if len(pos[keep]) != FRAMES:
        raise SystemExit(f"{name}: fewer than {FRAMES} frames from {CLIPS[name]}")
    return Cmu(clip, pos[keep], rot[keep])


def layout_positions(cmu: Cmu, layout: str) -> np.ndarray:
    """``(T, len(sensor_joints), 3)`` metres, BVH axes: the layout's recorded joints."""
    rules = LAYOUT_MAPS[layout]
    want = skeletons.get(layout).sensor_joints
    if set(rules) != set(want):
        raise AssertionError(f"{layout}: map {sorted(set(rules) ^ set(want))} differ")
    return np.stack([rules[j](cmu) for j in want], axis=1)


def to_camera(p: np.ndarray, root: np.ndarray) -> np.ndarray:
    """BVH axes (metres, floor y = 0) -> Kinect camera space: turned 180 deg about y
    (``BVH_TO_KINECT``), the sensor ``CAMERA_HEIGHT_M`` up, the root's mean ``CAMERA_DISTANCE_M``
    away and centred in x."""
    k = p @ BVH_TO_KINECT.T
    r = root @ BVH_TO_KINECT.T
    shift = np.array([-r[:, 0].mean(), -CAMERA_HEIGHT_M, CAMERA_DISTANCE_M - r[:, 2].mean()])
    return k + shift


KINECT_TO_AZURE = np.diag([-1.0, -1.0, 1.0])
"""Kinect camera space (x left, y up, z forward) -> Azure / image axes (x right, y down, z
forward): a half turn about z (a rotation, det +1)."""


def write_kinect_v1(path: Path, cam: np.ndarray) -> None:
    names = skeletons.get("kinect_v1").joints
    header = ",".join(f"{j}_{a}" for j in names for a in "xyz")
    rows = [",".join(f"{v:.5f}" for v in frame.ravel()) for frame in cam]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")


# pinhole projections of the Kinect v2's depth (512 x 424) and colour (1920 x 1080) cameras,
# for the NTU file's depthX/Y and colorX/Y columns (approximate; no reader uses them)
_DEPTH = (365.0, 256.0, 212.0)
_COLOR = (1060.0, 960.0, 540.0)


def write_ntu(path: Path, cam: np.ndarray) -> None:
    lines = [str(len(cam))]
    for frame in cam:
        # bodyID clipedEdges handLeftConfidence handLeftState handRightConfidence
        # handRightState isRestricted leanX leanY trackingState
        lines += ["1", "72057594037931101 0 1 1 1 1 0 0.0 0.0 2", str(len(frame))]
        for x, y, z in frame:
            proj = [f"{c + f * x / z:.2f} {cy - f * y / z:.2f}" for f, c, cy in (_DEPTH, _COLOR)]
            # x y z depthX depthY colorX colorY orientationW X Y Z trackingState
            lines.append(f"{x:.5f} {y:.5f} {z:.5f} {proj[0]} {proj[1]} 0 0 0 0 2")
    path.write_text("\n".join(lines) + "\n")


def write_azure(path: Path, cam: np.ndarray) -> None:
    mm = cam @ KINECT_TO_AZURE.T * 1000.0
    frames = []
    for i, frame in enumerate(mm):
        frames.append({
            "bodies": [{
                "body_id": 1,
                "joint_orientations": [[1, 0, 0, 0]] * len(frame),
                "joint_positions": [[round(float(v), 2) for v in j] for j in frame],
            }],
            "frame_id": i,
            "num_bodies": 1,
            "timestamp_usec": int(round(i * 1e6 / FPS)),
        })  # fmt: skip
    az = skeletons.get("azure_kinect")
    doc = {
        "bone_list": [[az.joints[p], j] for j, p in zip(az.joints, az.parents, strict=True)
                      if p >= 0],
        "frames": frames,
        "joint_names": list(az.joints),
        "k4abt_sdk_version": "1.1.2",
        "source_file": f"{path.stem}.mkv (synthetic: see SOURCE.md)",
    }  # fmt: skip
    path.write_text(json.dumps(doc, separators=(",", ":")) + "\n")


def write_smpl(path: Path, p: np.ndarray, layout: str) -> None:
    np.savez_compressed(path, joints=p.astype(np.float32), skeleton=layout, fps=FPS)


def write_mediapipe(path: Path, cam: np.ndarray) -> None:
    mp = skeletons.get("mediapipe_pose")
    img = cam @ KINECT_TO_AZURE.T
    hips = 0.5 * (img[:, mp.index["left_hip"]] + img[:, mp.index["right_hip"]])
    world = img - hips[:, None]
    frames = [
        [{"x": round(float(x), 5), "y": round(float(y), 5), "z": round(float(z), 5),
          "visibility": 0.99} for x, y, z in frame]
        for frame in world
    ]  # fmt: skip
    path.write_text(
        "[\n" + ",\n".join(json.dumps(f, separators=(",", ":")) for f in frames) + "\n]\n"
    )


def write(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name in CLIPS:
        cmu = excerpt(name)
        root = cmu.p("Hips")
        ref = layout_positions(cmu, "kinect_v1")
        # the reference is what the BVH reader gives (its map, scale and axes)
        bvh = kinect_positions(cmu.clip, JOINT_MAPS["cmu"], CMU_SCALE, cmu.pos)
        np.testing.assert_allclose(ref @ BVH_TO_KINECT.T, bvh, atol=1e-9)
        for layout in LAYOUT_MAPS:
            p = layout_positions(cmu, layout)
            path = out / f"{name}.{layout}.{SUFFIX[layout]}"
            if layout == "kinect_v1":
                write_kinect_v1(path, to_camera(p, root))
            elif layout == "kinect_v2":
                write_ntu(path, to_camera(p, root))
            elif layout == "azure_kinect":
                write_azure(path, to_camera(p, root))
            elif layout in ("smpl", "smplx"):
                write_smpl(path, p, layout)
            else:
                write_mediapipe(path, to_camera(p, root))
            print(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: "
                  f"{len(p)} frames, {path.stat().st_size / 1024:.1f} KiB")  # fmt: skip


# --- Part B: measure -------------------------------------------------------------------------


def in_memory(name: str, layout: str) -> np.ndarray:
    """The Kinect v1 layout (``to_kinect_v1``) of the positions written for ``layout``, before
    any file: what the file's reading should give, up to rotation, translation and rounding."""
    s = skeletons.get(layout)
    return skeletons.to_kinect_v1(s.complete(layout_positions(excerpt(name), layout)), s)


def bone_angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(T, 57)`` full descriptors -> ``(T, 19)`` deg between the bones' unit vectors
    (``atan2(|a x b|, a . b)`` in float64: exact near 0, where ``arccos`` of a float32 dot
    product is off by ~0.02 deg)."""
    ua = np.asarray(a, np.float64).reshape(len(a), -1, 3)
    ub = np.asarray(b, np.float64).reshape(len(b), -1, 3)
    cross = np.linalg.norm(np.cross(ua, ub), axis=-1)
    return np.degrees(np.arctan2(cross, np.sum(ua * ub, axis=-1)))


def _stats(x: np.ndarray) -> dict[str, float]:
    return {
        "median": round(float(np.median(x)), 3),
        "p95": round(float(np.percentile(x, 95)), 3),
        "max": round(float(np.max(x)), 3),
    }


ROBOTS = (("nao_h25", "upper", "recording"), ("unitree_g1", "full", "recording"),
          ("nao_h25", "upper", None))  # fmt: skip
"""(robot, the IK's bones, neck_neutral) of each comparison."""

JITTER_M = 0.001
"""The control: the Kinect v1 reading with this much Gaussian noise (metres, per coordinate, a
fixed seed) added, retarget and compared like a layout: how much the IK's answer moves for a
change of the input that is no layout's."""
CONTROL = "kinect_v1_jitter_1mm"


def frame_angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(T, 20, 3)`` Kinect v1 positions twice, the same axes -> ``(T,)`` deg, the rotation
    between their body frames (``body_frame``)."""
    ra, rb = (np.asarray(body_frame(np.asarray(x, np.float32))[0], np.float64) for x in (a, b))
    # |Ra - Rb|_F = 2 sqrt(2) sin(angle / 2): exact near 0, where arccos of the trace is not
    chord = np.linalg.norm(ra - rb, axis=(-2, -1)) / (2.0 * np.sqrt(2.0))
    return np.degrees(2.0 * np.arcsin(np.clip(chord, 0.0, 1.0)))


def _read(folder: Path) -> dict[str, list]:
    """Layout -> its recordings (one per clip), read from ``folder``; plus the control."""
    recs: dict[str, list] = {k: [] for k in LAYOUT_MAPS}
    for name in CLIPS:
        for layout in LAYOUT_MAPS:
            path = folder / f"{name}.{layout}.{SUFFIX[layout]}"
            rec = read_skeleton(path, fps=FPS)
            if rec.skeleton != layout or not rec.valid.all():
                raise AssertionError(f"{path.name}: skeleton {rec.skeleton!r}, valid frames "
                                     f"{int(rec.valid.sum())} of {len(rec.valid)}")  # fmt: skip
            recs[layout].append(rec)
    rng = np.random.default_rng(0)
    recs[CONTROL] = [
        dataclasses.replace(r, positions=(r.positions + rng.normal(0, JITTER_M, r.positions.shape))
                            .astype(np.float32))
        for r in recs["kinect_v1"]
    ]  # fmt: skip
    return recs


def measure(folder: Path) -> dict:
    recs = _read(folder)
    compared = [k for k in recs if k != "kinect_v1"]
    out: dict = {"frames": sum(len(r.positions) for r in recs["kinect_v1"]), "layouts": {}}
    desc = {k: [np.asarray(descriptor(r.positions, "full")[0]) for r in v] for k, v in recs.items()}
    for layout in compared:
        s = skeletons.get(recs[layout][0].skeleton)
        row: dict = {}
        ang = np.concatenate([
            bone_angles(d, r) for d, r in zip(desc[layout], desc["kinect_v1"], strict=True)
        ])  # fmt: skip
        row["bones_deg"] = {
            b: (_stats(ang[:, i]) if b in s.bones else "not in the layout (filled)")
            for i, b in enumerate(BONE_NAMES)
        }
        if layout in LAYOUT_MAPS:
            mem = {name: in_memory(name, layout) for name in CLIPS}
            ref = {name: in_memory(name, "kinect_v1") for name in CLIPS}
            # the body frame (every bone is read in it), from the positions before any file
            row["body_frame_deg"] = _stats(
                np.concatenate([frame_angles(mem[n], ref[n]) for n in CLIPS])
            )
            # writer and reader: the file's reading against the positions it was written from
            own = [BONE_NAMES.index(b) for b in s.bones]
            row["file_vs_memory_max_deg"] = round(max(
                float(bone_angles(d, np.asarray(descriptor(mem[n], "full")[0]))[:, own].max())
                for n, d in zip(CLIPS, desc[layout], strict=True)
            ), 4)  # fmt: skip
        out["layouts"][layout] = row
    for robot, bones, neck in ROBOTS:
        spec = robots.get(robot)
        key = robot if neck == "recording" else f"{robot}_neck_neutral_none"
        t0 = time.perf_counter()
        angles = {}
        for layout, rs in recs.items():
            angles[layout] = np.concatenate([
                retarget(r.positions, r.valid, method="ik", robot=robot, bones=bones,
                         smoothing=None, times=r.times, skeleton=r.skeleton,
                         neck_neutral=neck).angles[:, spec.driven_index]
                for r in rs
            ])  # fmt: skip
        out.setdefault("retarget_wall_s", {})[key] = round(time.perf_counter() - t0, 1)
        for layout in compared:
            diff = np.degrees(np.abs(angles[layout] - angles["kinect_v1"]))
            out["layouts"][layout][key] = {
                "frame_mean_abs_deg": _stats(diff.mean(axis=1)),
                "joints_deg": {j: _stats(diff[:, i]) for i, j in enumerate(spec.driven_joints)},
            }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", metavar="DIR", type=Path, help="write the same-motion files")
    ap.add_argument(
        "--measure",
        metavar="DIR",
        type=Path,
        nargs="?",
        const=DEFAULT_DIR,
        help=f"measure the files in DIR (default {DEFAULT_DIR.relative_to(ROOT)})",
    )
    ap.add_argument("--json", type=Path, help="write the measurement here")
    args = ap.parse_args()  # fmt: skip
    if args.write is None and args.measure is None:
        ap.error("give --write DIR and/or --measure [DIR]")
    if args.write is not None:
        write(args.write)
    if args.measure is not None:
        t0 = time.perf_counter()
        res = {
            "device": str(jax.devices()[0].device_kind),
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "jax": jax.__version__,
            "clips": {
                k: {"first_frame": v, "step": STEP, "frames": FRAMES} for k, v in CLIPS.items()
            },
            "fps": FPS,
            **measure(args.measure),
        }
        res["wall_s"] = round(time.perf_counter() - t0, 1)
        _print(res)
        if args.json:
            args.json.write_text(json.dumps(res, indent=1) + "\n")


def _print(res: dict) -> None:
    keys = [k for k in next(iter(res["layouts"].values())) if k.startswith(("nao", "unitree"))]
    print(f"{res['frames']} frames; per-frame mean |angle difference| from Kinect v1, deg "
          "(median / p95)")  # fmt: skip
    for layout, row in res["layouts"].items():
        cells = [f"{k} {row[k]['frame_mean_abs_deg']['median']:.2f} / "
                 f"{row[k]['frame_mean_abs_deg']['p95']:.2f}" for k in keys]  # fmt: skip
        worst = {b: v["median"] for b, v in row["bones_deg"].items() if isinstance(v, dict)}
        top = sorted(worst, key=lambda b: -worst[b])[:4]
        extra = ""
        if "body_frame_deg" in row:
            extra = (f"; body frame {row['body_frame_deg']['median']:.2f}; file vs memory "
                     f"{row['file_vs_memory_max_deg']:.4f}")  # fmt: skip
        print(f"  {layout}: " + ", ".join(cells))
        print("    bones (median deg): " + ", ".join(f"{b} {worst[b]:.2f}" for b in top) + extra)


if __name__ == "__main__":
    main()
