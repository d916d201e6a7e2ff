"""The Unitree G1 MJCF (jaxproj/robots/unitree_g1/unitree_g1.xml) against its fact sheet.

Every number below is copied from shared/reference/unitree_g1_kinematics.md (29-DoF G1, rev 1.0),
not read from the model, so the model is checked against the sheet and not against itself.
"""

from __future__ import annotations

import importlib.util
import itertools
from pathlib import Path

import mujoco
import numpy as np
import pytest

# the installed package's file, found without importing jaxproj (and JAX with it)
_PACKAGE = Path(importlib.util.find_spec("jaxproj").origin).parent
XML = _PACKAGE / "robots" / "unitree_g1" / "unitree_g1.xml"
FREE_JOINT = "floating_base_joint"
PELVIS_HEIGHT = 0.793

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)

# The sheet's joints in Unitree's SDK order: (name, axis, lower, upper), rad.
SDK_JOINTS: tuple[tuple[str, tuple[float, ...], float, float], ...] = (
    ("left_hip_pitch_joint", Y, -2.5307, 2.8798),
    ("left_hip_roll_joint", X, -0.5236, 2.9671),
    ("left_hip_yaw_joint", Z, -2.7576, 2.7576),
    ("left_knee_joint", Y, -0.087267, 2.8798),
    ("left_ankle_pitch_joint", Y, -0.87267, 0.5236),
    ("left_ankle_roll_joint", X, -0.2618, 0.2618),
    ("right_hip_pitch_joint", Y, -2.5307, 2.8798),
    ("right_hip_roll_joint", X, -2.9671, 0.5236),
    ("right_hip_yaw_joint", Z, -2.7576, 2.7576),
    ("right_knee_joint", Y, -0.087267, 2.8798),
    ("right_ankle_pitch_joint", Y, -0.87267, 0.5236),
    ("right_ankle_roll_joint", X, -0.2618, 0.2618),
    ("waist_yaw_joint", Z, -2.618, 2.618),
    ("waist_roll_joint", X, -0.52, 0.52),
    ("waist_pitch_joint", Y, -0.52, 0.52),
    ("left_shoulder_pitch_joint", Y, -3.0892, 2.6704),
    ("left_shoulder_roll_joint", X, -1.5882, 2.2515),
    ("left_shoulder_yaw_joint", Z, -2.618, 2.618),
    ("left_elbow_joint", Y, -1.0472, 2.0944),
    ("left_wrist_roll_joint", X, -1.97222, 1.97222),
    ("left_wrist_pitch_joint", Y, -1.61443, 1.61443),
    ("left_wrist_yaw_joint", Z, -1.61443, 1.61443),
    ("right_shoulder_pitch_joint", Y, -3.0892, 2.6704),
    ("right_shoulder_roll_joint", X, -2.2515, 1.5882),
    ("right_shoulder_yaw_joint", Z, -2.618, 2.618),
    ("right_elbow_joint", Y, -1.0472, 2.0944),
    ("right_wrist_roll_joint", X, -1.97222, 1.97222),
    ("right_wrist_pitch_joint", Y, -1.61443, 1.61443),
    ("right_wrist_yaw_joint", Z, -1.61443, 1.61443),
)

# The sheet's left side and spine: body -> (parent, offset, body rotation (w, x, y, z) or None).
LEFT_AND_SPINE: dict[str, tuple[str, tuple[float, float, float], tuple[float, ...] | None]] = {
    "left_hip_pitch_link": ("pelvis", (0.0, 0.064452, -0.1027), None),
    "left_hip_roll_link": (
        "left_hip_pitch_link",
        (0.0, 0.052, -0.030465),
        (0.996179, 0.0, -0.0873386, 0.0),
    ),
    "left_hip_yaw_link": ("left_hip_roll_link", (0.025001, 0.0, -0.12412), None),
    "left_knee_link": (
        "left_hip_yaw_link",
        (-0.078273, 0.0021489, -0.17734),
        (0.996179, 0.0, 0.0873386, 0.0),
    ),
    "left_ankle_pitch_link": ("left_knee_link", (0.0, -9.4445e-05, -0.30001), None),
    "left_ankle_roll_link": ("left_ankle_pitch_link", (0.0, 0.0, -0.017558), None),
    "waist_yaw_link": ("pelvis", (0.0, 0.0, 0.0), None),
    "waist_roll_link": ("waist_yaw_link", (-0.0039635, 0.0, 0.044), None),
    "torso_link": ("waist_roll_link", (0.0, 0.0, 0.0), None),
    "head_link": ("torso_link", (0.004, 0.0, 0.43), None),  # the sheet's head centre
    "left_shoulder_pitch_link": (
        "torso_link",
        (0.0039563, 0.10022, 0.24778),
        (0.990264, 0.139201, 1.387e-05, -9.869e-05),
    ),
    "left_shoulder_roll_link": (
        "left_shoulder_pitch_link",
        (0.0, 0.038, -0.013831),
        (0.990268, -0.139172, 0.0, 0.0),
    ),
    "left_shoulder_yaw_link": ("left_shoulder_roll_link", (0.0, 0.00624, -0.1032), None),
    "left_elbow_link": ("left_shoulder_yaw_link", (0.015783, 0.0, -0.080518), None),
    "left_wrist_roll_link": ("left_elbow_link", (0.1, 0.00188791, -0.01), None),
    "left_wrist_pitch_link": ("left_wrist_roll_link", (0.038, 0.0, 0.0), None),
    "left_wrist_yaw_link": ("left_wrist_pitch_link", (0.046, 0.0, 0.0), None),
}
PALM = (0.08, 0.0, 0.0)  # left palm point in left_wrist_yaw_link
FOOT = (0.04, 0.0, -0.037)  # foot point in the ankle roll link
SOLE_BOTTOM_Z = -0.025 - 0.01  # sole box centre z minus its half height, ankle roll link

# max torque (N m) by joint kind
MAX_TORQUE = {
    "hip_pitch": 88,
    "hip_roll": 139,
    "hip_yaw": 88,
    "knee": 139,
    "ankle": 50,
    "waist_yaw": 88,
    "waist_roll": 50,
    "waist_pitch": 50,
    "shoulder": 25,
    "elbow": 25,
    "wrist_roll": 25,
    "wrist_pitch": 5,
    "wrist_yaw": 5,
}

# armature (kg m^2) by joint kind; the sheet's "hips, knee and waist yaw 0.01-0.025" split by
# motor (the 88 N m joints 0.01, the 139 N m ones 0.025), see the MJCF header
ARMATURE = {
    "hip_pitch": 0.01,
    "hip_roll": 0.025,
    "hip_yaw": 0.01,
    "knee": 0.025,
    "ankle": 0.0072,
    "waist_yaw": 0.01,
    "waist_roll": 0.0072,
    "waist_pitch": 0.0072,
    "shoulder": 0.0036,
    "elbow": 0.0036,
    "wrist_roll": 0.0036,
    "wrist_pitch": 0.00425,
    "wrist_yaw": 0.00425,
}


def _kind(name: str) -> str:
    """The MAX_TORQUE / ARMATURE key of a joint name."""
    return next(k for k in MAX_TORQUE if f"_{k}_" in f"_{name}")


def _mirror(name: str) -> str:
    return name.replace("left_", "right_")


def _sheet_tree() -> dict[str, tuple[str, tuple[float, ...], tuple[float, ...] | None]]:
    """The whole tree: the sheet's left side and spine plus the right side as its mirror."""
    tree = dict(LEFT_AND_SPINE)
    for body, (parent, (x, y, z), quat) in LEFT_AND_SPINE.items():
        if body.startswith("left_"):
            mq = None if quat is None else (quat[0], -quat[1], quat[2], -quat[3])
            tree[_mirror(body)] = (_mirror(parent), (x, -y, z), mq)
    return tree


def _rot(quat: tuple[float, ...] | None) -> np.ndarray:
    if quat is None:
        return np.eye(3)
    w, x, y, z = np.asarray(quat, dtype=np.float64) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _chain(body: str) -> tuple[np.ndarray, np.ndarray]:
    """World position and rotation of ``body`` at zero angles, chained by hand from the sheet."""
    tree = _sheet_tree()
    path = []
    while body != "pelvis":
        path.append(body)
        body = tree[body][0]
    pos, rot = np.array([0.0, 0.0, PELVIS_HEIGHT]), np.eye(3)
    for name in reversed(path):
        _, offset, quat = tree[name]
        pos = pos + rot @ np.asarray(offset)
        rot = rot @ _rot(quat)
    return pos, rot


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(XML))


@pytest.fixture(scope="module")
def zero_pose(model: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(model)  # qpos0: pelvis at (0, 0, 0.793), identity, every hinge at 0
    mujoco.mj_forward(model, data)
    return data


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    assert i >= 0, f"no {kind} named {name!r}"
    return i


def test_loads_with_a_free_pelvis(model: mujoco.MjModel) -> None:
    assert (model.nq, model.nv, model.nu) == (7 + 29, 6 + 29, 29)
    free = _id(model, mujoco.mjtObj.mjOBJ_JOINT, FREE_JOINT)
    assert model.jnt_type[free] == mujoco.mjtJoint.mjJNT_FREE
    assert model.body(model.jnt_bodyid[free]).name == "pelvis"
    np.testing.assert_array_equal(model.qpos0[:7], [0, 0, PELVIS_HEIGHT, 1, 0, 0, 0])


def test_fixed_base_by_deleting_the_free_joint() -> None:
    spec = mujoco.MjSpec.from_file(str(XML))
    spec.delete(spec.joint(FREE_JOINT))
    fixed = spec.compile()
    assert (fixed.nq, fixed.nv, fixed.nu) == (29, 29, 29)
    assert [fixed.joint(i).name for i in range(fixed.njnt)] == [j[0] for j in SDK_JOINTS]
    data = mujoco.MjData(fixed)
    mujoco.mj_kinematics(fixed, data)
    np.testing.assert_array_equal(data.body("pelvis").xpos, [0, 0, PELVIS_HEIGHT])


def test_29_hinges_in_sdk_order_with_the_sheets_ranges_and_axes(model: mujoco.MjModel) -> None:
    hinges = [i for i in range(model.njnt) if model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE]
    assert len(hinges) == model.njnt - 1 == 29
    assert [model.joint(i).name for i in hinges] == [j[0] for j in SDK_JOINTS]
    # file order = qpos order: the hinges follow the free joint in SDK order
    np.testing.assert_array_equal(model.jnt_qposadr[hinges], np.arange(7, 36))
    for i, (name, axis, lo, hi) in zip(hinges, SDK_JOINTS, strict=True):
        assert model.jnt_limited[i], name
        np.testing.assert_array_equal(model.jnt_range[i], [lo, hi], err_msg=name)
        np.testing.assert_array_equal(model.jnt_axis[i], axis, err_msg=name)


def test_servos_in_sdk_order(model: mujoco.MjModel) -> None:
    for a, (name, _, lo, hi) in enumerate(SDK_JOINTS):
        assert model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
        assert model.joint(model.actuator_trnid[a, 0]).name == name
        np.testing.assert_array_equal(model.actuator_ctrlrange[a], [lo, hi])
        kp = 20.0 if ("ankle" in name or "wrist" in name) else 75.0
        np.testing.assert_array_equal(model.actuator_gainprm[a, :1], [kp], err_msg=name)
        np.testing.assert_array_equal(model.actuator_biasprm[a, :3], [0, -kp, -2.0], err_msg=name)
        tau = MAX_TORQUE[_kind(name)]
        np.testing.assert_array_equal(model.actuator_forcerange[a], [-tau, tau], err_msg=name)
        dof = model.jnt_dofadr[model.actuator_trnid[a, 0]]
        assert model.dof_armature[dof] == ARMATURE[_kind(name)], name


def test_body_tree_matches_the_sheet(model: mujoco.MjModel) -> None:
    tree = _sheet_tree()
    names = {model.body(i).name for i in range(1, model.nbody)}
    assert names == set(tree) | {"pelvis"}
    assert model.body(int(model.body("pelvis").parentid[0])).name == "world"
    for body, (parent, offset, quat) in tree.items():
        b = model.body(body)
        assert model.body(int(b.parentid[0])).name == parent, body
        np.testing.assert_allclose(b.pos, offset, rtol=0, atol=1e-12, err_msg=body)
        expected = np.array((1.0, 0.0, 0.0, 0.0) if quat is None else quat)
        expected /= np.linalg.norm(expected)
        np.testing.assert_allclose(b.quat, expected, rtol=0, atol=1e-12, err_msg=body)
    # the sheet's masses (kg), left side; the right side equals it by the mirror test
    masses = {
        "pelvis": 3.813,
        "left_hip_pitch_link": 1.35,
        "left_hip_roll_link": 1.52,
        "left_hip_yaw_link": 1.702,
        "left_knee_link": 1.932,
        "left_ankle_pitch_link": 0.074,
        "left_ankle_roll_link": 0.608,
        "waist_yaw_link": 0.214,
        "waist_roll_link": 0.086,
        "torso_link": 7.818,
        "head_link": 1.036,
        "left_shoulder_pitch_link": 0.718,
        "left_shoulder_roll_link": 0.643,
        "left_shoulder_yaw_link": 0.734,
        "left_elbow_link": 0.6,
        "left_wrist_roll_link": 0.0854,
        "left_wrist_pitch_link": 0.484,
        "left_wrist_yaw_link": 0.255,
    }
    for body, mass in masses.items():
        assert model.body(body).mass[0] == pytest.approx(mass, abs=1e-12), body


def test_left_right_mirror_symmetry(model: mujoco.MjModel) -> None:
    flip = np.array([1.0, -1.0, 1.0])
    qflip = np.array([1.0, -1.0, 1.0, -1.0])
    mirror = np.diag(flip)
    pairs = 0
    for i in range(model.nbody):
        name = model.body(i).name
        if not name.startswith("left_"):
            continue
        left, right = model.body(name), model.body(_mirror(name))
        np.testing.assert_array_equal(right.pos, left.pos * flip, err_msg=name)
        np.testing.assert_array_equal(right.quat, left.quat * qflip, err_msg=name)
        np.testing.assert_allclose(right.ipos, left.ipos * flip, atol=1e-15, err_msg=name)
        np.testing.assert_array_equal(right.mass, left.mass, err_msg=name)
        pairs += 1
    assert pairs == 13
    for kind, count in (
        (mujoco.mjtObj.mjOBJ_SITE, model.nsite),
        (mujoco.mjtObj.mjOBJ_GEOM, model.ngeom),
    ):
        get = model.site if kind == mujoco.mjtObj.mjOBJ_SITE else model.geom
        for i in range(count):
            name = get(i).name
            if not name.startswith("left_"):
                continue
            left, right = get(name), get(_mirror(name))
            assert model.body(int(right.bodyid[0])).name == _mirror(
                model.body(int(left.bodyid[0])).name
            )
            np.testing.assert_allclose(right.pos, left.pos * flip, atol=1e-15, err_msg=name)
            # frames as matrices (a capsule's quaternion is not unique): R_right = M R_left M
            rl, rr = (_rot(tuple(q)) for q in (left.quat, right.quat))
            np.testing.assert_allclose(rr, mirror @ rl @ mirror, atol=1e-12, err_msg=name)
            np.testing.assert_array_equal(right.size, left.size, err_msg=name)
    for name, _, lo, hi in SDK_JOINTS[:6] + SDK_JOINTS[15:22]:
        right = model.joint(_mirror(name)).range
        # roll joints (x axis) mirror their range, the others keep it
        expected = [-hi, -lo] if "roll" in name else [lo, hi]
        np.testing.assert_array_equal(right, expected, err_msg=name)


@pytest.mark.parametrize(
    "body",
    ["left_wrist_yaw_link", "right_wrist_yaw_link", "left_ankle_roll_link", "head_link"],
)
def test_zero_pose_fk_matches_the_sheet_chained_by_hand(
    model: mujoco.MjModel, zero_pose: mujoco.MjData, body: str
) -> None:
    pos, rot = _chain(body)
    np.testing.assert_allclose(zero_pose.body(body).xpos, pos, rtol=0, atol=1e-6)
    np.testing.assert_allclose(zero_pose.body(body).xmat.reshape(3, 3), rot, rtol=0, atol=1e-6)


def test_zero_pose_sites_match_the_sheet(zero_pose: mujoco.MjData) -> None:
    hand_pos, hand_rot = _chain("left_wrist_yaw_link")
    palm = hand_pos + hand_rot @ np.asarray(PALM)
    np.testing.assert_allclose(zero_pose.site("left_hand_site").xpos, palm, rtol=0, atol=1e-6)
    foot_pos, foot_rot = _chain("left_ankle_roll_link")
    foot = foot_pos + foot_rot @ np.asarray(FOOT)
    np.testing.assert_allclose(zero_pose.site("left_foot_site").xpos, foot, rtol=0, atol=1e-6)
    for site, body in (
        ("left_elbow_site", "left_elbow_link"),
        ("left_knee_site", "left_knee_link"),
    ):
        np.testing.assert_allclose(zero_pose.site(site).xpos, _chain(body)[0], rtol=0, atol=1e-6)
    # zero angles: upper arm hangs down, forearm points forward, legs straight
    shoulder, elbow, wrist = (
        zero_pose.site(f"left_{p}_site").xpos for p in ("shoulder", "elbow", "wrist")
    )
    upper, fore = elbow - shoulder, wrist - elbow
    assert upper[2] / np.linalg.norm(upper) < -0.99
    assert fore[0] / np.linalg.norm(fore) > 0.99
    hip, knee, ankle = (zero_pose.site(f"left_{p}_site").xpos for p in ("hip", "knee", "ankle"))
    assert (knee - hip)[2] / np.linalg.norm(knee - hip) < -0.95
    assert (ankle - knee)[2] / np.linalg.norm(ankle - knee) < -0.9999


def test_pelvis_height_puts_the_soles_on_the_floor(zero_pose: mujoco.MjData) -> None:
    # 0.793 m with straight legs: the sole (box bottom) and the foot point within 2 mm of z = 0
    assert zero_pose.body("pelvis").xpos[2] == PELVIS_HEIGHT
    for side in ("left", "right"):
        ankle_pos, _ = _chain(f"{side}_ankle_roll_link")
        assert abs(ankle_pos[2] + SOLE_BOTTOM_Z) < 2e-3
        assert abs(zero_pose.site(f"{side}_sole_site").xpos[2]) < 2e-3
        assert abs(zero_pose.site(f"{side}_foot_site").xpos[2]) < 2e-3


def test_no_self_collision_at_zero_pose(model: mujoco.MjModel, zero_pose: mujoco.MjData) -> None:
    robot = [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] != 0 and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]
    assert len(robot) == model.ngeom  # every geom is a robot collision geom (no floor here)
    contacts = [
        (model.geom(c.geom1).name, model.geom(c.geom2).name)
        for c in zero_pose.contact[: zero_pose.ncon]
        if model.geom_bodyid[c.geom1] != 0 and model.geom_bodyid[c.geom2] != 0
    ]
    assert contacts == []
    # collision geoms for every part named in issue 44 exist and are enabled
    names = {model.geom(g).name for g in robot}
    for part in (
        "torso",
        "head",
        "pelvis",
        "upper_arm",
        "forearm",
        "hand",
        "thigh",
        "shin",
        "foot",
    ):
        assert any(part in n for n in names), part
    # hands can hit the thighs and the head (non-adjacent links are not filtered out)
    for a, b in itertools.product(
        ("left_hand_geom", "right_hand_geom"), ("head_geom", "left_thigh_geom")
    ):
        ga, gb = model.geom(a), model.geom(b)
        ok = (ga.contype & gb.conaffinity) or (gb.contype & ga.conaffinity)
        assert ok, (a, b)
