"""The LAFAN1 and Mixamo joint maps of the BVH reader (``jaxproj.io.formats.bvh``), on files
written here in the layouts the public data come in: chosen by the hierarchy alone (behind any
Mixamo namespace), centimetres read as metres, the performer's left kept left, a known elbow
rotation moving the wrist where it must, and hierarchies that fit no preset still refused.

The hierarchies follow published files (the sources are in ``bvh.joint_maps.JOINT_MAPS``'s
docstring): LAFAN1's 22 joints as in ``aiming1_subject1.bvh`` (root ``Xposition Yposition
Zposition Zrotation Yrotation Xrotation``, every other joint ``Zrotation Yrotation Xrotation``,
each bone along its joint's local +x, so the all-zero pose lies on its side and the root rotation
stands it up; End Sites at offset 0; the root's ``OFFSET`` the first frame's position; 6 decimals
and a space at each row's end; ``Frame Time: 0.033333``) and a Mixamo rig as exported to BVH
(``mixamorig:`` names, a T-pose rest pose facing +z with its left at +x, tab-separated offsets
with 4 decimals, ``HeadTop_End`` and finger chains; ``Frame Time: 0.0333333``). Offsets are those
skeletons' (cm, rounded); the poses and motion are made up here. Plain NumPy: no JAX program is
compiled."""

from __future__ import annotations

import numpy as np
import pytest

from jaxproj.errors import InputError
from jaxproj.human.skeleton import JOINT_NAMES
from jaxproj.io.formats import bvh
from jaxproj.io.readers import read_skeleton

K = {name: i for i, name in enumerate(JOINT_NAMES)}
ZYX = ("Zrotation", "Yrotation", "Xrotation")
ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", *ZYX)
FORWARD = np.array([0.0, 0.0, -1.0])
"""Kinect axes of the BVH +z both skeletons face here (``BVH_TO_KINECT``: a turn about y)."""
LEFT = np.array([-1.0, 0.0, 0.0])
"""Kinect axes of the BVH +x, the performer's left when facing +z (y up, right-handed)."""


def _side(side: str, rows: list[tuple]) -> list[tuple]:
    """``rows`` of the left side, for ``side`` (``Left`` kept, ``Right``: names swapped and the
    offsets' ``mirror`` component negated)."""
    if side == "Left":
        return [(n, p, o) for n, p, o, _ in rows]
    out = []
    for name, parent, offset, mirror in rows:
        o = list(offset)
        o[mirror] = -o[mirror]
        out.append((name.replace("Left", "Right"), parent and parent.replace("Left", "Right"), o))
    return out


# --- LAFAN1 --------------------------------------------------------------------------------------

# (name, parent, offset cm, component mirrored for the right side); file order as the dataset's
_LAFAN1_LEG = [
    ("LeftUpLeg", "Hips", (0.10, 1.86, 10.55), 2), ("LeftLeg", "LeftUpLeg", (43.50, 0, 0), 2),
    ("LeftFoot", "LeftLeg", (42.37, 0, 0), 2), ("LeftToe", "LeftFoot", (17.30, 0, 0), 2),
    ("End Site", "LeftToe", (0, 0, 0), 2),
]  # fmt: skip
_LAFAN1_ARM = [
    ("LeftShoulder", "Spine2", (19.75, -1.48, 6.00), 2),
    ("LeftArm", "LeftShoulder", (11.28, 0, 0), 2), ("LeftForeArm", "LeftArm", (33.00, 0, 0), 2),
    ("LeftHand", "LeftForeArm", (25.20, 0, 0), 2), ("End Site", "LeftHand", (0, 0, 0), 2),
]  # fmt: skip
LAFAN1 = [
    ("Hips", None, (0, 0, 0)), *_side("Left", _LAFAN1_LEG), *_side("Right", _LAFAN1_LEG),
    ("Spine", "Hips", (6.90, -2.60, 0)), ("Spine1", "Spine", (12.59, 0, 0)),
    ("Spine2", "Spine1", (12.34, 0, 0)), ("Neck", "Spine2", (25.83, 0, 0)),
    ("Head", "Neck", (11.77, 0, 0)), ("End Site", "Head", (0, 0, 0)),
    *_side("Left", _LAFAN1_ARM), *_side("Right", _LAFAN1_ARM),
]  # fmt: skip

LAFAN1_POSE = {  # standing, arms out (T-pose), Z Y X degrees; every other joint 0
    "Hips": (90, 0, 90),  # local +x (the spine) up, +y forward (+z), +z (the left hip) left (+x)
    "LeftUpLeg": (180, 0, 180), "RightUpLeg": (180, 0, 180),  # the legs down
    "LeftFoot": (70, 0, 0), "RightFoot": (70, 0, 0),  # the feet forward, toes 6 cm lower
    "LeftToe": (20, 0, 0), "RightToe": (20, 0, 0),
    "LeftShoulder": (0, -90, 0), "RightShoulder": (0, 90, 0),  # clavicles out to each side
}  # fmt: skip


def _lafan1_text(unit: float = 1.0) -> tuple[str, np.ndarray]:
    """A 4-frame LAFAN1 file (30 fps) walking 5 cm per frame forward, the left elbow bent 90 deg
    in frame 2; and the root positions (cm). ``unit`` scales lengths (0.01: a file in metres)."""
    root = np.array([[0.0, 92.0, 5.0 * k] for k in range(4)])
    names = [n for n, _, _ in LAFAN1 if n != "End Site"]
    rows = []
    for k in range(4):
        pose = {**LAFAN1_POSE, "LeftForeArm": (90, 0, 0)} if k == 2 else LAFAN1_POSE
        values = list(root[k] * unit)
        for name in names:
            values += pose.get(name, (0, 0, 0))
        rows.append(" ".join(f"{v:.6f}" for v in values) + " ")
    out = ["HIERARCHY"]
    depth: dict[str | None, int] = {None: -1}
    closing: list[int] = []
    for name, parent, offset in LAFAN1:
        d = depth[parent] + 1
        while closing and closing[-1] >= d:
            out.append("\t" * closing.pop() + "}")
        pad = "\t" * d
        head = "End Site" if name == "End Site" else ("ROOT " if d == 0 else "JOINT ") + name
        out += [pad + head, pad + "{"]
        o = np.asarray(root[0] if d == 0 else offset, float) * unit
        out.append(pad + "\tOFFSET " + " ".join(f"{v:.6f}" for v in o))
        if name != "End Site":
            channels = ROOT_CHANNELS if d == 0 else ZYX
            line = pad + f"\tCHANNELS {len(channels)} " + " ".join(channels)
            out.append(line + " " if d == 0 else line)  # the dataset's root line ends in a space
            depth[name] = d
        closing.append(d)
    while closing:
        out.append("\t" * closing.pop() + "}")
    out += ["MOTION", "Frames: 4", "Frame Time: 0.033333", *rows]
    return "\n".join(out) + "\n", root


# --- Mixamo --------------------------------------------------------------------------------------

_FINGERS = [  # LeftHandIndex and LeftHandThumb chains of the published rig
    ("LeftHandIndex1", "LeftHand", (11.97, -1.11, 3.73), 0),
    ("LeftHandIndex2", "LeftHandIndex1", (3.84, -0.64, -0.03), 0),
    ("LeftHandIndex3", "LeftHandIndex2", (3.33, -0.74, -0.01), 0),
    ("End Site", "LeftHandIndex3", (2.97, -0.80, 0.00), 0),
    ("LeftHandThumb1", "LeftHand", (3.33, -2.05, 3.58), 0),
    ("LeftHandThumb2", "LeftHandThumb1", (3.49, -1.48, 2.85), 0),
    ("LeftHandThumb3", "LeftHandThumb2", (3.41, -1.77, 2.11), 0),
    ("End Site", "LeftHandThumb3", (2.72, -1.16, 1.79), 0),
]
_MIXAMO_ARM = [
    ("LeftShoulder", "Spine2", (6.11, 9.11, 0.71), 0),
    ("LeftArm", "LeftShoulder", (12.65, -0.34, -2.60), 0),
    ("LeftForeArm", "LeftArm", (27.35, -0.96, -1.40), 0),
    ("LeftHand", "LeftForeArm", (27.56, -0.71, 1.55), 0),
]
_MIXAMO_LEG = [
    ("LeftUpLeg", "Hips", (9.12, -6.66, -0.06), 0), ("LeftLeg", "LeftUpLeg", (0, -40.56, -1.77), 0),
    ("LeftFoot", "LeftLeg", (-0.50, -41.96, -3.35), 0),
    ("LeftToeBase", "LeftFoot", (0.37, -10.49, 12.64), 0),
]  # fmt: skip


def mixamo_joints(fingers: bool, end_joints: bool) -> list[tuple]:
    """A Mixamo rig, bare names, in the file order of the published one (spine, head, arms, then
    right and left leg). ``fingers``: the index and thumb chains (else the "no fingers" rig, an
    End Site at the wrist); ``end_joints``: ``HeadTop_End`` / ``LeftToe_End`` as joints with an End
    Site at 0 (as exporters write the rig's end bones), else End Sites."""

    def end(name: str, parent: str, offset: tuple, mirror: int = 0) -> list[tuple]:
        if end_joints:
            return [(name, parent, offset, mirror), ("End Site", name, (0, 0, 0), mirror)]
        return [("End Site", parent, offset, mirror)]

    hand = _FINGERS if fingers else [("End Site", "LeftHand", (9.0, 0, 0), 0)]
    head = [
        ("Hips", None, (0, 0, 0), 0), ("Spine", "Hips", (0, 9.92, -1.23), 0),
        ("Spine1", "Spine", (0, 11.65, -1.42), 0), ("Spine2", "Spine1", (0, 13.36, -1.63), 0),
        ("Neck", "Spine2", (0, 15.03, 0.79), 0), ("Head", "Neck", (0, 10.32, 3.14), 0),
        *end("HeadTop_End", "Head", (0, 18.47, 6.64)),
    ]  # fmt: skip
    leg = [*_MIXAMO_LEG, *end("LeftToe_End", "LeftToeBase", (0, 0, 9.99))]
    return [
        *_side("Left", head), *_side("Left", _MIXAMO_ARM + hand),
        *_side("Right", _MIXAMO_ARM + hand), *_side("Right", leg), *_side("Left", leg),
    ]  # fmt: skip


def mixamo_text(joints: list[tuple], prefix: str) -> tuple[str, np.ndarray]:
    """A 3-frame Mixamo BVH (30 fps): the T-pose (the head nodded 8 deg, as captured motion never
    holds every joint at 0), 5 cm forward, then the left elbow bent 90 deg (``LeftForeArm``
    Yrotation -90: the forearm from +x to +z, forward); and the root positions (cm)."""
    root = np.array([[0.0, 98.29, 5.0 * k] for k in range(3)])
    names = [n for n, _, _ in joints if n != "End Site"]
    rows = []
    for k in range(3):
        pose = {"Head": (0, 0, 8), "LeftForeArm": (0, -90, 0) if k == 2 else (0, 0, 0)}
        values = list(root[k])
        for name in names:
            values += pose.get(name, (0, 0, 0))
        rows.append(" ".join(f"{v:.4f}" for v in values) + " ")
    out = ["HIERARCHY"]
    depth: dict[str | None, int] = {None: -1}
    closing: list[int] = []
    for name, parent, offset in joints:
        d = depth[parent] + 1
        while closing and closing[-1] >= d:
            out.append("\t" * closing.pop() + "}")
        pad = "\t" * d
        if name == "End Site":
            values = " ".join(f"{v:.4f}" for v in offset)
            out += [pad + "End Site", pad + "{", pad + "\tOFFSET " + values]
        else:
            out += [pad + ("ROOT " if d == 0 else "JOINT ") + prefix + name, pad + "{"]
            if d == 0:
                out.append(pad + "\tOFFSET 0.00 0.00 0.00")
            else:
                out.append(pad + "\tOFFSET\t" + "\t".join(f"{v:.4f}" for v in offset))
            channels = ROOT_CHANNELS if d == 0 else ZYX
            out.append(pad + f"\tCHANNELS {len(channels)} " + " ".join(channels))
            depth[name] = d
        closing.append(d)
    while closing:
        out.append("\t" * closing.pop() + "}")
    out += ["MOTION", "Frames: 3", "Frame Time: 0.0333333", *rows]
    return "\n".join(out) + "\n", root


# --- checks --------------------------------------------------------------------------------------


def _length(p: np.ndarray, a: str, b: str) -> np.ndarray:
    return np.linalg.norm(p[:, K[b]] - p[:, K[a]], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _check_body(p: np.ndarray, root_cm: np.ndarray, bones_m: dict[tuple[str, str], float]) -> None:
    """What both skeletons must show in Kinect axes (metres): the root where the file puts it,
    bone lengths of an adult, rigid; upright; the performer's left at their left (-x); arms out
    to the side in frames 0 and 1."""
    np.testing.assert_allclose(p[:, K["HipCenter"]], root_cm * 0.01 * [-1, 1, -1], atol=1e-6)
    for (a, b), length in bones_m.items():
        np.testing.assert_allclose(_length(p, a, b), length, atol=2e-3, err_msg=f"{a}-{b}")
    for side in ("Left", "Right"):
        assert (0.2 < _length(p, f"Shoulder{side}", f"Elbow{side}")).all()
        assert (_length(p, f"Shoulder{side}", f"Elbow{side}") < 0.4).all()
        assert (0.35 < _length(p, f"Hip{side}", f"Knee{side}")).all()
        assert (_length(p, f"Hip{side}", f"Knee{side}") < 0.5).all()
    height = p[:, K["Head"], 1] - p[:, K["AnkleLeft"], 1]
    assert ((1.3 < height) & (height < 1.7)).all()  # the head joint (skull base) over the ankle
    y = p[..., 1]
    assert (y[:, K["Head"]] > y[:, K["ShoulderCenter"]]).all()
    assert (y[:, K["ShoulderCenter"]] > y[:, K["Spine"]]).all()
    assert (y[:, K["Spine"]] > y[:, K["HipCenter"]]).all()
    assert (y[:, K["HipCenter"]] > y[:, K["KneeLeft"]]).all()
    assert (y[:, K["KneeLeft"]] > y[:, K["AnkleLeft"]]).all()
    # left is left, without trusting any axis: (up x forward) points to the performer's left,
    # forward from the toes; and in Kinect axes, their left at smaller x
    up = _unit(p[:, K["ShoulderCenter"]] - p[:, K["HipCenter"]])
    for side in ("Left", "Right"):
        toes = p[:, K[f"Foot{side}"]] - p[:, K[f"Ankle{side}"]]
        toes = _unit(toes - np.sum(toes * up, -1, keepdims=True) * up)
        assert (toes @ FORWARD > 0.99).all(), side  # the toes point forward
        left = np.cross(up, toes)
        for a in ("Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle"):
            d = p[:, K[f"{a}Left"]] - p[:, K[f"{a}Right"]]
            assert (np.sum(d * left, -1) > 0.1).all(), (a, side)
            assert (p[:, K[f"{a}Left"], 0] < p[:, K[f"{a}Right"], 0]).all(), a
    for side, sign in (("Left", 1.0), ("Right", -1.0)):  # T-pose: each arm along its own side
        arm = _unit(p[:2, K[f"Wrist{side}"]] - p[:2, K[f"Shoulder{side}"]])
        assert (arm @ (sign * LEFT) > 0.99).all(), side


def _check_elbow(p: np.ndarray, before: int, bent: int, forearm_m: float) -> None:
    """Frame ``bent`` turned the left forearm 90 deg forward from frame ``before`` (the root moved
    in between): the left wrist now ``forearm_m`` in front of the elbow, square to the upper arm;
    nothing else moved relative to the root."""
    rel = p - p[:, K["HipCenter"]][:, None]
    forearm = rel[bent, K["WristLeft"]] - rel[bent, K["ElbowLeft"]]
    assert np.linalg.norm(forearm) == pytest.approx(forearm_m, abs=2e-3)
    assert _unit(forearm) @ FORWARD > 0.99
    upper = _unit(rel[bent, K["ElbowLeft"]] - rel[bent, K["ShoulderLeft"]])
    assert abs(upper @ _unit(forearm)) < 0.12  # the elbow at ~90 deg
    moved = np.linalg.norm(rel[bent] - rel[before], axis=-1)
    assert moved[K["WristLeft"]] > 0.3 and moved[K["HandLeft"]] > 0.3
    still = [j for j in JOINT_NAMES if j not in ("WristLeft", "HandLeft")]
    np.testing.assert_allclose(moved[[K[j] for j in still]], 0.0, atol=1e-5)


# --- tests ---------------------------------------------------------------------------------------


def test_lafan1_hierarchy_is_recognised_read_in_metres_left_kept_left(tmp_path):
    text, root = _lafan1_text()
    path = tmp_path / "aiming1_subject1.bvh"
    path.write_text(text)
    clip = bvh.parse_bvh(path)
    assert len([n for n, e in zip(clip.names, clip.end_site, strict=True) if not e]) == 22
    assert bvh.detect_joint_map(clip) == "lafan1"
    rec = read_skeleton(path)
    assert rec.format == "bvh" and rec.valid.all() and rec.positions.shape == (4, 20, 3)
    assert "map lafan1; scale cm (guessed" in rec.time_source and "prefixed" not in rec.time_source
    assert rec.fps == pytest.approx(30.0, rel=1e-4)
    p = rec.positions.astype(np.float64)
    bones = {("ShoulderLeft", "ElbowLeft"): 0.33, ("ElbowLeft", "WristLeft"): 0.252,
             ("HipLeft", "KneeLeft"): 0.435, ("KneeLeft", "AnkleLeft"): 0.4237,
             ("ShoulderRight", "ElbowRight"): 0.33, ("ElbowRight", "WristRight"): 0.252,
             ("HipRight", "KneeRight"): 0.435, ("KneeRight", "AnkleRight"): 0.4237}  # fmt: skip
    _check_body(p, root, bones)
    # ShoulderCenter is the Neck joint: 25.83 - 19.75 cm above the shoulder joints
    sc = p[:, K["ShoulderCenter"], 1] - p[:, K["ShoulderLeft"], 1]
    np.testing.assert_allclose(sc, 0.0608, atol=1e-4)
    assert p[0, K["AnkleLeft"], 1] == pytest.approx(0.92 + 0.001 - 0.8587, abs=1e-4)
    _check_elbow(p, before=1, bent=2, forearm_m=0.252)
    # the same file converted to metres: the unit guessed, the same positions
    metres = tmp_path / "aiming1_subject1_m.bvh"
    metres.write_text(_lafan1_text(unit=0.01)[0])
    rec_m = read_skeleton(metres)
    assert "map lafan1; scale m (guessed" in rec_m.time_source
    np.testing.assert_allclose(rec_m.positions, rec.positions, atol=2e-6)


MIXAMO_BONES = {
    ("ShoulderLeft", "ElbowLeft"): 0.2739,
    ("ElbowLeft", "WristLeft"): 0.2761,
    ("HipLeft", "KneeLeft"): 0.4060,
    ("KneeLeft", "AnkleLeft"): 0.4210,
}


@pytest.mark.parametrize(
    ("prefix", "fingers", "end_joints"),
    [("mixamorig:", True, True), ("mixamorig2:", False, True), ("", True, False)],
    ids=["mixamorig", "mixamorig2-no-fingers", "no-prefix"],
)
def test_mixamo_hierarchy_is_recognised_behind_any_namespace(tmp_path, prefix, fingers, end_joints):
    joints = mixamo_joints(fingers, end_joints)
    text, root = mixamo_text(joints, prefix)
    path = tmp_path / "Walking.bvh"
    path.write_text(text)
    clip = bvh.parse_bvh(path)
    assert clip.names[0] == f"{prefix}Hips" and f"{prefix}LeftToeBase" in clip.names
    assert bvh.namespaces(clip)[0] == prefix
    assert bvh.detect_joint_map(clip) == "mixamo"
    rec = read_skeleton(path)
    named = f"map mixamo (joint names prefixed {prefix!r})" if prefix else "map mixamo;"
    assert named in rec.time_source and "scale cm (guessed" in rec.time_source
    assert rec.valid.all() and rec.positions.shape == (3, 20, 3)
    assert rec.fps == pytest.approx(30.0, rel=1e-4)
    p = rec.positions.astype(np.float64)
    _check_body(p, root, MIXAMO_BONES | {(a.replace("Left", "Right"), b.replace("Left", "Right")): v
                                         for (a, b), v in MIXAMO_BONES.items()})  # fmt: skip
    # ShoulderCenter is the Neck joint, 15.03 - 8.77 cm above the shoulder joints (LeftArm)
    sc = p[:, K["ShoulderCenter"], 1] - p[:, K["ShoulderLeft"], 1]
    np.testing.assert_allclose(sc, 0.1503 - 0.0877, atol=1e-4)
    _check_elbow(p, before=1, bent=2, forearm_m=0.2761)
    # the preset by name takes the namespace too, and gives the same
    named_rec = read_skeleton(path, bvh_map="mixamo")
    np.testing.assert_array_equal(named_rec.positions, rec.positions)
    table = bvh.resolve_joint_map(clip, "mixamo")[1]
    assert (
        table["ShoulderLeft"] == f"{prefix}LeftArm" and table["FootLeft"] == f"{prefix}LeftToeBase"
    )
    # and a preset that does not fit names what it lacks
    with pytest.raises(InputError, match=rf"joint map 'lafan1' could not map 2 Kinect joint\(s\): "
                                         rf"FootLeft \({prefix}LeftToe not in"):  # fmt: skip
        read_skeleton(path, bvh_map="lafan1")


def test_hierarchies_that_fit_no_preset_are_refused_with_what_each_lacks(tmp_path):
    text, _ = mixamo_text(mixamo_joints(True, True), "mixamorig:")
    renamed = tmp_path / "renamed.bvh"  # an elbow under another name
    renamed.write_text(text.replace("mixamorig:LeftForeArm", "mixamorig:LeftLowerArm"))
    with pytest.raises(InputError) as e:
        read_skeleton(renamed)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{renamed}: no built-in joint map fits")
    assert "'mixamo' could not map ElbowLeft (mixamorig:LeftForeArm not in the hierarchy)" in msg
    assert "'lafan1' could not map ElbowLeft (mixamorig:LeftForeArm not in the hierarchy), " \
           "FootLeft (mixamorig:LeftToe not in the hierarchy)" in msg  # fmt: skip
    assert "'cmu' could not map" in msg and "--bvh-map" in msg
    # two spine joints, as in CMU's MotionBuilder release, and no Neck1: neither mixamo nor cmu-mb
    two = tmp_path / "two_spine_joints.bvh"
    two.write_text(text.replace("mixamorig:Spine2", "mixamorig:Chest"))
    with pytest.raises(InputError) as e:
        read_skeleton(two)
    msg = str(e.value)
    assert "'mixamo' lacks mixamorig:Spine2 (which a mixamo hierarchy has)" in msg
    assert "'cmu-mb' could not map ShoulderCenter (mixamorig:Neck1 not in the hierarchy)" in msg
    # a map given by name still reads it: the marks only choose among presets
    rec = read_skeleton(two, bvh_map="mixamo")
    assert rec.valid.all() and "map mixamo (joint names prefixed 'mixamorig:')" in rec.time_source
    # a namespace must hold for every joint of the map
    mixed = tmp_path / "mixed.bvh"
    mixed.write_text(text.replace("mixamorig:RightHand\n", "mixamorig1:RightHand\n"))
    with pytest.raises(
        InputError, match=r"'mixamo' could not map WristRight \(mixamorig:RightHand"
    ):
        read_skeleton(mixed)


def test_the_presets_tell_each_hierarchy_apart():
    """Each preset's joints (and marks) fit its own hierarchy and no other's: auto never has to
    choose between two."""
    lafan1 = [n for n, _, _ in LAFAN1 if n != "End Site"]
    mixamo = [n for n, _, _ in mixamo_joints(True, True) if n != "End Site"]
    mb = ["Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint",
          "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase", "LowerBack", "Spine", "Spine1",
          "Neck", "Neck1", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
          "LeftFingerBase", "LeftHandIndex1", "LThumb", "RightShoulder", "RightArm",
          "RightForeArm", "RightHand", "RightFingerBase", "RightHandIndex1", "RThumb"]  # fmt: skip
    for own, names in (("lafan1", lafan1), ("mixamo", mixamo), ("cmu-mb", mb)):
        for preset, table in bvh.JOINT_MAPS.items():
            needed = set(table.values()) | set(bvh.DETECTION_MARKS.get(preset, ()))
            assert needed <= set(names) if preset == own else not needed <= set(names), preset
