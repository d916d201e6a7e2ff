"""The registered skeletons of today's capture formats (``jaxproj.human.layouts``) and their
Kinect v1 layout (``skeletons.to_kinect_v1``): same descriptor on every bone a skeleton defines,
derived joints, filled hands, and the checks that refuse an inconsistent spec."""

from __future__ import annotations

import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError
from jaxproj.human import layouts, skeletons
from jaxproj.human.skeleton import descriptor
from jaxproj.human.skeletons import BONE_NAMES, KINECT_V1, BodyFrame, Skeleton, to_kinect_v1
from jaxproj.motion.retarget import check_skeleton

NAMES = ("kinect_v1", "kinect_v2", "azure_kinect", "smpl", "smplx", "mediapipe_pose")


def _poses(s: Skeleton, n: int = 6, seed: int = 0) -> np.ndarray:
    raw = np.random.default_rng(seed).normal(size=(n, len(s.sensor_joints), 3))
    return s.complete(raw.astype(np.float32))


def test_registered_in_order():
    assert skeletons.names() == NAMES
    assert tuple(s.name for s in layouts.BUILT_IN) == NAMES[1:]


@pytest.mark.parametrize("name", NAMES)
def test_kinect_v1_layout_keeps_every_defined_bone(name):
    s = skeletons.get(name)
    p = _poses(s)
    k = to_kinect_v1(p, name)
    assert k.shape == (6, 20, 3) and k.dtype == np.float32
    bones = tuple(b for b in BONE_NAMES if b in s.bones)
    d_native, ok_native = descriptor(p, bones, skeleton=name)
    d_kinect, ok_kinect = descriptor(k, bones)
    np.testing.assert_array_equal(np.asarray(d_native), np.asarray(d_kinect))
    assert np.asarray(ok_native).all() and np.asarray(ok_kinect).all()
    _, ok_full = descriptor(k, "full")  # filled bones keep every frame a valid Kinect skeleton
    assert np.asarray(ok_full).all()


def test_kinect_v2_is_kinect_v1_with_spine_shoulder():
    src = skeletons.get("kinect_v2").kinect_v1_sources
    v2 = layouts.KINECT_V2.joints
    renamed = {"HipCenter": "SpineBase", "Spine": "SpineMid", "ShoulderCenter": "SpineShoulder"}
    assert [v2[i] for i in src] == [renamed.get(j, j) for j in KINECT_V1.joints]


def test_smplx_hands_continue_the_forearm():
    s = skeletons.get("smplx")
    assert s.missing(["hand_left", "hand_right", "forearm_left"]) == ("hand_left", "hand_right")
    k = to_kinect_v1(_poses(s), s)
    j = KINECT_V1.index
    for side in ("Left", "Right"):
        forearm = k[:, j[f"Wrist{side}"]] - k[:, j[f"Elbow{side}"]]
        hand = k[:, j[f"Hand{side}"]] - k[:, j[f"Wrist{side}"]]
        np.testing.assert_allclose(hand, skeletons.FILL_FRACTION * forearm, atol=1e-6)


def test_mediapipe_derived_joints():
    s = skeletons.get("mediapipe_pose")
    assert len(s.sensor_joints) == 33 and s.n_joints == 39
    raw = np.random.default_rng(1).normal(size=(4, 33, 3)).astype(np.float32)
    p = s.complete(raw)
    np.testing.assert_array_equal(p[:, :33], raw)
    i = s.index
    hips = (raw[:, i["left_hip"]] + raw[:, i["right_hip"]]) / 2
    shoulders = (raw[:, i["left_shoulder"]] + raw[:, i["right_shoulder"]]) / 2
    np.testing.assert_allclose(p[:, i["hip_centre"]], hips, atol=1e-6)
    np.testing.assert_allclose(p[:, i["spine_mid"]], (hips + shoulders) / 2, atol=1e-6)
    with pytest.raises(ConfigError, match="records 33 joints"):
        s.complete(p)


def _spec(legs: bool = False, **changes):
    joints = ["root", "mid", "top", "head", "l", "r", "le", "re", "lw", "rw"]
    parents = [-1, 0, 1, 2, 2, 2, 4, 5, 6, 7]
    bones = {
        "spine_lower": ("root", "mid"), "spine_upper": ("mid", "top"), "neck": ("top", "head"),
        "clavicle_left": ("top", "l"), "clavicle_right": ("top", "r"),
        "upper_arm_left": ("l", "le"), "upper_arm_right": ("r", "re"),
        "forearm_left": ("le", "lw"), "forearm_right": ("re", "rw"),
    }  # fmt: skip
    if legs:
        for s in ("left", "right"):
            joints += [f"hip_{s}", f"knee_{s}", f"ankle_{s}"]
            parents += [0, len(joints) - 3, len(joints) - 2]
            bones |= {
                f"pelvis_{s}": ("root", f"hip_{s}"),
                f"thigh_{s}": (f"hip_{s}", f"knee_{s}"),
                f"shin_{s}": (f"knee_{s}", f"ankle_{s}"),
            }
    base = dict(
        name="tiny", joints=tuple(joints), parents=tuple(parents), bones=bones,
        frame=BodyFrame(up=("root", "top"), left=("r", "l")),
    )  # fmt: skip
    base.update(changes)
    return Skeleton(**base)


def test_inconsistent_specs_are_refused():
    with pytest.raises(ConfigError, match="cannot be laid out as Kinect v1: it lacks bone 'pelvis"):
        _ = _spec().kinect_v1_sources  # no legs: only hands and feet may be missing
    ok = _spec(legs=True)
    k = to_kinect_v1(_poses(ok), ok)  # no feet: filled
    assert k.shape == (6, 20, 3)
    bones = dict(ok.bones) | {"neck": ("mid", "head")}  # the neck leaves from the spine middle
    with pytest.raises(ConfigError, match="put joints 'top' and 'mid' where Kinect v1 has one"):
        _ = _spec(legs=True, bones=bones).kinect_v1_sources
    frame = BodyFrame(up=("root", "head"), left=("r", "l"))
    with pytest.raises(ConfigError, match="body frame's up axis"):
        _ = _spec(legs=True, frame=frame).kinect_v1_sources
    j, p = ok.joints, ok.parents
    with pytest.raises(ConfigError, match="derived joint 'x' must be joint"):
        _spec(joints=(*j, "x", "y"), parents=(*p, 0, 0), derived=(("x", ("l", "r")),), legs=True)
    with pytest.raises(ConfigError, match="must average earlier joints"):
        _spec(joints=(*j, "x"), parents=(*p, 0), derived=(("x", ("x",)),), legs=True)


def test_retarget_refuses_a_skeleton_without_a_bone_the_robot_reads():
    check_skeleton("smplx", robots.get("unitree_g1"))  # no hands: the G1 reads none
    check_skeleton(_spec(), robots.get("nao_h25"))  # arms and neck: all the NAO reads
    with pytest.raises(ConfigError, match="'tiny' has no pelvis_left, pelvis_right.*unitree_g1"):
        check_skeleton(_spec(), robots.get("unitree_g1"))
