"""The skeletons people record today, registered beside Kinect v1 (``jaxproj.human.skeletons``).

Each is a ``Skeleton``: the format's joints in its own array order, their tree, the joints of each
canonical bone and the body frame. Every one is laid out so that its bones meet where Kinect v1's
do (``Skeleton.kinect_v1_sources``): the readers hand the pipeline Kinect v1 positions made
through the canonical bones (``skeletons.to_kinect_v1``), and a model trained on Kinect v1 reads
them. Where a format's joints are not Kinect v1's, the choice is written at the skeleton (and
measured in the formats guide):

- ``kinect_v2`` (Kinect for Windows SDK 2.0 ``JointType``, 25 joints; NTU RGB+D): joints 0-19 are
  Kinect v1's; the spine top is ``SpineShoulder`` (Kinect v1's ShoulderCenter), so the neck bone
  runs ``SpineShoulder -> Head`` past v2's own ``Neck`` joint.
- ``azure_kinect`` (Azure Kinect Body Tracking SDK ``k4abt_joint_id_t``, 32 joints): the spine top
  is ``NECK`` (the clavicle joints sit below and inside the shoulders; the canonical clavicle runs
  from the spine top to the shoulder joint), the spine middle ``SPINE_NAVEL``.
- ``smpl`` (SMPL's 24 joints, as AMASS and SMPL-based pose estimators give them): spine top
  ``neck``, spine middle ``spine2``; SMPL's ``head`` joint is the top of the neck (the skull's
  base), not the head's centre, so the neck bone is more upright than Kinect's.
- ``smplx`` (SMPL-X's first 22 body joints, SMPL's first 22): as ``smpl``, without hands.
- ``mediapipe_pose`` (MediaPipe Pose's 33 landmarks, world coordinates): no spine, no head
  centre; six joints are derived (``Skeleton.derived``): the pelvis centre (mid hips), the spine
  top (mid shoulders), the spine middle (mid of those two: both spine bones then lie along the
  body's up axis), the head centre (mid ears) and each hand (mid index and pinky knuckles).

Sources: Microsoft, "JointType Enumeration" (Kinect for Windows SDK 2.0) and the SDK's
BodyBasics sample (bone list); Microsoft, "Azure Kinect body tracking joints"
(learn.microsoft.com/azure/kinect-dk/body-joints); Loper et al., "SMPL" (2015) and the ``smplx``
package's ``JOINT_NAMES``; Google, "MediaPipe Pose landmarker" (33 landmarks,
ai.google.dev/edge/mediapipe/solutions/vision/pose_landmarker).
"""

from __future__ import annotations

from jaxproj.human.skeletons import BodyFrame, Skeleton, register


def _names(names: str) -> tuple[str, ...]:
    """Space-separated joint names, written out in the order the source lists them."""
    return tuple(names.split())


KINECT_V2 = Skeleton(
    name="kinect_v2",
    joints=_names(
        "SpineBase SpineMid Neck Head ShoulderLeft ElbowLeft WristLeft HandLeft ShoulderRight "
        "ElbowRight WristRight HandRight HipLeft KneeLeft AnkleLeft FootLeft HipRight KneeRight "
        "AnkleRight FootRight SpineShoulder HandTipLeft ThumbLeft HandTipRight ThumbRight"
    ),
    parents=(
        -1, 0, 20, 2, 20, 4, 5, 6, 20, 8, 9, 10, 0, 12, 13, 14, 0, 16, 17, 18, 1, 7, 6, 11, 10,
    ),
    bones={
        "spine_lower": ("SpineBase", "SpineMid"), "spine_upper": ("SpineMid", "SpineShoulder"),
        "neck": ("SpineShoulder", "Head"),
        "clavicle_left": ("SpineShoulder", "ShoulderLeft"),
        "upper_arm_left": ("ShoulderLeft", "ElbowLeft"),
        "forearm_left": ("ElbowLeft", "WristLeft"), "hand_left": ("WristLeft", "HandLeft"),
        "clavicle_right": ("SpineShoulder", "ShoulderRight"),
        "upper_arm_right": ("ShoulderRight", "ElbowRight"),
        "forearm_right": ("ElbowRight", "WristRight"), "hand_right": ("WristRight", "HandRight"),
        "pelvis_left": ("SpineBase", "HipLeft"), "thigh_left": ("HipLeft", "KneeLeft"),
        "shin_left": ("KneeLeft", "AnkleLeft"), "foot_left": ("AnkleLeft", "FootLeft"),
        "pelvis_right": ("SpineBase", "HipRight"), "thigh_right": ("HipRight", "KneeRight"),
        "shin_right": ("KneeRight", "AnkleRight"), "foot_right": ("AnkleRight", "FootRight"),
    },
    frame=BodyFrame(up=("SpineBase", "SpineShoulder"), left=("ShoulderRight", "ShoulderLeft")),
    description="Kinect for Windows SDK 2.0 (JointType order, 25 joints): NTU RGB+D, PKU-MMD and "
    "other Kinect v2 datasets",
)  # fmt: skip
"""Kinect v2: 25 joints in ``JointType`` order (SpineShoulder is joint 20, the hand tips and
thumbs 21-24)."""

AZURE_KINECT = Skeleton(
    name="azure_kinect",
    joints=_names(
        "PELVIS SPINE_NAVEL SPINE_CHEST NECK CLAVICLE_LEFT SHOULDER_LEFT ELBOW_LEFT WRIST_LEFT "
        "HAND_LEFT HANDTIP_LEFT THUMB_LEFT CLAVICLE_RIGHT SHOULDER_RIGHT ELBOW_RIGHT WRIST_RIGHT "
        "HAND_RIGHT HANDTIP_RIGHT THUMB_RIGHT HIP_LEFT KNEE_LEFT ANKLE_LEFT FOOT_LEFT HIP_RIGHT "
        "KNEE_RIGHT ANKLE_RIGHT FOOT_RIGHT HEAD NOSE EYE_LEFT EAR_LEFT EYE_RIGHT EAR_RIGHT"
    ),
    parents=(
        -1, 0, 1, 2, 2, 4, 5, 6, 7, 8, 7, 2, 11, 12, 13, 14, 15, 14,
        0, 18, 19, 20, 0, 22, 23, 24, 3, 26, 26, 26, 26, 26,
    ),
    bones={
        "spine_lower": ("PELVIS", "SPINE_NAVEL"), "spine_upper": ("SPINE_NAVEL", "NECK"),
        "neck": ("NECK", "HEAD"),
        "clavicle_left": ("NECK", "SHOULDER_LEFT"),
        "upper_arm_left": ("SHOULDER_LEFT", "ELBOW_LEFT"),
        "forearm_left": ("ELBOW_LEFT", "WRIST_LEFT"), "hand_left": ("WRIST_LEFT", "HAND_LEFT"),
        "clavicle_right": ("NECK", "SHOULDER_RIGHT"),
        "upper_arm_right": ("SHOULDER_RIGHT", "ELBOW_RIGHT"),
        "forearm_right": ("ELBOW_RIGHT", "WRIST_RIGHT"),
        "hand_right": ("WRIST_RIGHT", "HAND_RIGHT"),
        "pelvis_left": ("PELVIS", "HIP_LEFT"), "thigh_left": ("HIP_LEFT", "KNEE_LEFT"),
        "shin_left": ("KNEE_LEFT", "ANKLE_LEFT"), "foot_left": ("ANKLE_LEFT", "FOOT_LEFT"),
        "pelvis_right": ("PELVIS", "HIP_RIGHT"), "thigh_right": ("HIP_RIGHT", "KNEE_RIGHT"),
        "shin_right": ("KNEE_RIGHT", "ANKLE_RIGHT"), "foot_right": ("ANKLE_RIGHT", "FOOT_RIGHT"),
    },
    frame=BodyFrame(up=("PELVIS", "NECK"), left=("SHOULDER_RIGHT", "SHOULDER_LEFT")),
    description="Azure Kinect Body Tracking SDK (k4abt_joint_id_t order, 32 joints, millimetres)",
)  # fmt: skip
"""Azure Kinect: 32 joints in ``k4abt_joint_id_t`` order."""

_SMPL_BODY = _names(
    "pelvis left_hip right_hip spine1 left_knee right_knee spine2 left_ankle right_ankle spine3 "
    "left_foot right_foot neck left_collar right_collar head left_shoulder right_shoulder "
    "left_elbow right_elbow left_wrist right_wrist"
)
_SMPL_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)
_SMPL_BONES = {
    "spine_lower": ("pelvis", "spine2"), "spine_upper": ("spine2", "neck"),
    "neck": ("neck", "head"),
    "clavicle_left": ("neck", "left_shoulder"),
    "upper_arm_left": ("left_shoulder", "left_elbow"),
    "forearm_left": ("left_elbow", "left_wrist"),
    "clavicle_right": ("neck", "right_shoulder"),
    "upper_arm_right": ("right_shoulder", "right_elbow"),
    "forearm_right": ("right_elbow", "right_wrist"),
    "pelvis_left": ("pelvis", "left_hip"), "thigh_left": ("left_hip", "left_knee"),
    "shin_left": ("left_knee", "left_ankle"), "foot_left": ("left_ankle", "left_foot"),
    "pelvis_right": ("pelvis", "right_hip"), "thigh_right": ("right_hip", "right_knee"),
    "shin_right": ("right_knee", "right_ankle"), "foot_right": ("right_ankle", "right_foot"),
}  # fmt: skip
_SMPL_FRAME = BodyFrame(up=("pelvis", "neck"), left=("right_shoulder", "left_shoulder"))

SMPL = Skeleton(
    name="smpl",
    joints=(*_SMPL_BODY, "left_hand", "right_hand"),
    parents=(*_SMPL_PARENTS, 20, 21),
    bones={
        **_SMPL_BONES,
        "hand_left": ("left_wrist", "left_hand"),
        "hand_right": ("right_wrist", "right_hand"),
    },
    frame=_SMPL_FRAME,
    description="SMPL body model joints (24; AMASS, SMPL-based pose estimators), metres",
)
"""SMPL: 24 joints in the body model's order (``left_hand`` / ``right_hand`` at the knuckles)."""

SMPLX = Skeleton(
    name="smplx",
    joints=_SMPL_BODY,
    parents=_SMPL_PARENTS,
    bones=_SMPL_BONES,
    frame=_SMPL_FRAME,
    description="SMPL-X body model, its first 22 (body) joints, metres; no hand bones",
)
"""SMPL-X: the first 22 joints of the model's joint array (SMPL's first 22). SMPL-X's own hand
joints (finger bases, from index 25) are not read: the skeleton has no hand bones."""

_MP_SENSOR = _names(
    "nose left_eye_inner left_eye left_eye_outer right_eye_inner right_eye right_eye_outer "
    "left_ear right_ear mouth_left mouth_right left_shoulder right_shoulder left_elbow "
    "right_elbow left_wrist right_wrist left_pinky right_pinky left_index right_index "
    "left_thumb right_thumb left_hip right_hip left_knee right_knee left_ankle right_ankle "
    "left_heel right_heel left_foot_index right_foot_index"
)
_MP_DERIVED = (
    ("hip_centre", ("left_hip", "right_hip")),
    ("shoulder_centre", ("left_shoulder", "right_shoulder")),
    ("spine_mid", ("hip_centre", "shoulder_centre")),
    ("head_centre", ("left_ear", "right_ear")),
    ("left_hand", ("left_index", "left_pinky")),
    ("right_hand", ("right_index", "right_pinky")),
)
_MP_JOINTS = (*_MP_SENSOR, *(d for d, _ in _MP_DERIVED))


def _mp_parents() -> tuple[int, ...]:
    idx = {j: i for i, j in enumerate(_MP_JOINTS)}
    parent = {
        "hip_centre": None, "spine_mid": "hip_centre", "shoulder_centre": "spine_mid",
        "head_centre": "shoulder_centre",
        **{j: "head_centre" for j in _MP_SENSOR[:11]},
        **{f"{s}_shoulder": "shoulder_centre" for s in ("left", "right")},
        **{f"{s}_elbow": f"{s}_shoulder" for s in ("left", "right")},
        **{f"{s}_wrist": f"{s}_elbow" for s in ("left", "right")},
        **{f"{s}_{f}": f"{s}_wrist" for s in ("left", "right")
           for f in ("pinky", "index", "thumb", "hand")},
        **{f"{s}_hip": "hip_centre" for s in ("left", "right")},
        **{f"{s}_knee": f"{s}_hip" for s in ("left", "right")},
        **{f"{s}_ankle": f"{s}_knee" for s in ("left", "right")},
        **{f"{s}_{f}": f"{s}_ankle" for s in ("left", "right") for f in ("heel", "foot_index")},
    }  # fmt: skip
    return tuple(-1 if (p := parent[j]) is None else idx[p] for j in _MP_JOINTS)


MEDIAPIPE_POSE = Skeleton(
    name="mediapipe_pose",
    joints=_MP_JOINTS,
    parents=_mp_parents(),
    bones={
        "spine_lower": ("hip_centre", "spine_mid"),
        "spine_upper": ("spine_mid", "shoulder_centre"),
        "neck": ("shoulder_centre", "head_centre"),
        **{
            f"{b}_{s}": pair
            for s in ("left", "right")
            for b, pair in (
                ("clavicle", ("shoulder_centre", f"{s}_shoulder")),
                ("upper_arm", (f"{s}_shoulder", f"{s}_elbow")),
                ("forearm", (f"{s}_elbow", f"{s}_wrist")),
                ("hand", (f"{s}_wrist", f"{s}_hand")),
                ("pelvis", ("hip_centre", f"{s}_hip")),
                ("thigh", (f"{s}_hip", f"{s}_knee")),
                ("shin", (f"{s}_knee", f"{s}_ankle")),
                ("foot", (f"{s}_ankle", f"{s}_foot_index")),
            )
        },
    },
    frame=BodyFrame(up=("hip_centre", "shoulder_centre"), left=("right_shoulder", "left_shoulder")),
    description="MediaPipe Pose world landmarks (33, metres, hips at the origin) and 6 derived "
    "joints (spine, head centre, hands)",
    derived=_MP_DERIVED,
)
"""MediaPipe Pose: the 33 landmarks in the landmarker's order, then the 6 derived joints."""

BUILT_IN: tuple[Skeleton, ...] = (KINECT_V2, AZURE_KINECT, SMPL, SMPLX, MEDIAPIPE_POSE)
"""The skeletons this module registers (after ``kinect_v1``), in registration order."""

for _s in BUILT_IN:
    register(_s)
