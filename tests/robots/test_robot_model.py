"""The bundled NAO H25 MJCF against the reference numbers (shared/reference/nao_h25_kinematics.md).

Every expected number below is typed in from the reference document (sections 3, 4, 6, 9), not
taken from ``jaxproj.robots.nao_h25.robot``, so a wrong constant or a wrong XML value makes a
test fail.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from jaxproj.errors import ConfigError
from jaxproj.robots.nao_h25 import robot

# Reference section 3: official limits (rad) and URDF efforts (N m), per joint.
REF_LIMITS = {
    "HeadYaw": (-2.0857, 2.0857, 1.547),
    "HeadPitch": (-0.6720, 0.5149, 1.532),
    "LShoulderPitch": (-2.0857, 2.0857, 1.329),
    "LShoulderRoll": (-0.3142, 1.3265, 1.7835),
    "LElbowYaw": (-2.0857, 2.0857, 1.547),
    "LElbowRoll": (-1.5446, -0.0349, 1.532),
    "LWristYaw": (-1.8238, 1.8238, 0.4075),
    "LHand": (0.0, 1.0, 0.292),
    "RShoulderPitch": (-2.0857, 2.0857, 1.329),
    "RShoulderRoll": (-1.3265, 0.3142, 1.783),
    "RElbowYaw": (-2.0857, 2.0857, 1.547),
    "RElbowRoll": (0.0349, 1.5446, 1.532),
    "RWristYaw": (-1.8238, 1.8238, 0.4075),
    "RHand": (0.0, 1.0, 0.292),
    "LHipYawPitch": (-1.145303, 0.740810, 3.348),
    "LHipRoll": (-0.379472, 0.790477, 3.348),
    "LHipPitch": (-1.535889, 0.484090, 3.023),
    "LKneePitch": (-0.092346, 2.112528, 3.023),
    "LAnklePitch": (-1.189516, 0.922747, 3.023),
    "LAnkleRoll": (-0.397880, 0.769001, 3.348),
    "RHipYawPitch": (-1.145303, 0.740810, 3.348),
    "RHipRoll": (-0.790477, 0.379472, 3.348),
    "RHipPitch": (-1.535889, 0.484090, 3.023),
    "RKneePitch": (-0.103083, 2.120198, 3.023),
    "RAnklePitch": (-1.186448, 0.932056, 3.023),
    "RAnkleRoll": (-0.768992, 0.397935, 3.348),
}

# Reference sections 1 and 4: zero-pose positions in the torso frame (m), left side.
REF_ZERO_LEFT = {
    "shoulder": (0.0, 0.098, 0.100),
    "elbow": (0.105, 0.113, 0.100),
    "wrist": (0.16095, 0.113, 0.100),
    "hand": (0.2187, 0.113, 0.08769),
    "hip": (0.0, 0.050, -0.085),
    "knee": (0.0, 0.050, -0.185),
    "ankle": (0.0, 0.050, -0.2879),
    "sole": (0.0, 0.050, -0.33309),
}
REF_TOTAL_MASS = 5.3054  # kg, V5 URDF total (reference section 6)

ZERO = np.zeros(26)


@pytest.fixture(scope="module")
def fixed() -> mujoco.MjModel:
    return robot.load_model("fixed")


@pytest.fixture(scope="module")
def free() -> mujoco.MjModel:
    return robot.load_model("free")


def _pose(base: np.ndarray = ZERO, **angles: float) -> np.ndarray:
    q = np.array(base, dtype=np.float64)
    for name, value in angles.items():
        q[robot.JOINT_NAMES.index(name)] = value
    return q


def _sites(model: mujoco.MjModel, q: np.ndarray, *names: str) -> np.ndarray:
    return robot.site_positions(model, q, names)


# --- structure, limits, mass ------------------------------------------------------------------


def test_loads_with_both_mounts(fixed: mujoco.MjModel, free: mujoco.MjModel) -> None:
    assert robot.mjcf_path().is_absolute() and robot.mjcf_path().is_file()
    model = mujoco.MjModel.from_xml_path(str(robot.mjcf_path()))
    assert model.njnt == 27 and model.nq == 33 and model.nv == 32
    assert free.nq == 33 and free.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert mujoco.mj_id2name(free, mujoco.mjtObj.mjOBJ_JOINT, 0) == "root"
    assert fixed.njnt == 26 and fixed.nq == 26 and fixed.nv == 26
    assert not np.any(fixed.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    for model in (fixed, free):
        assert model.nu == 25
        assert model.opt.timestep == pytest.approx(0.002)
    with pytest.raises(ConfigError):
        robot.load_model("floating")  # type: ignore[arg-type]


def _names(model: mujoco.MjModel, obj: mujoco.mjtObj, n: int) -> set[str]:
    return {mujoco.mj_id2name(model, obj, i) for i in range(n)}


def test_parts_without_subtrees(fixed: mujoco.MjModel) -> None:
    # the head and arms, and the legs: every joint, actuator and geom lands in exactly one part
    upper = robot.load_model("fixed", without=robot.LEG_ROOTS)
    legs = robot.load_model("fixed", without=robot.UPPER_ROOTS)
    assert (upper.nv, upper.nu, upper.neq, upper.nexclude) == (14, 14, 0, 0)
    assert (legs.nv, legs.nu, legs.neq, legs.nexclude) == (12, 11, 1, 3)  # one hip motor
    j = mujoco.mjtObj.mjOBJ_JOINT
    uj, lj = _names(upper, j, upper.njnt), _names(legs, j, legs.njnt)
    assert uj | lj == set(robot.JOINT_NAMES) and not uj & lj
    assert {"HeadYaw", "LHand", "RWristYaw"} <= uj and {"LHipYawPitch", "RAnkleRoll"} <= lj
    g = mujoco.mjtObj.mjOBJ_GEOM
    ug, lg = _names(upper, g, upper.ngeom), _names(legs, g, legs.ngeom)
    assert ug & lg == {"torso_geom"} and ug | lg == _names(fixed, g, fixed.ngeom)
    a = mujoco.mjtObj.mjOBJ_ACTUATOR
    assert _names(upper, a, upper.nu) | _names(legs, a, legs.nu) == _names(fixed, a, fixed.nu)
    # a part keeps the whole model's inertia for its joints (the torso is welded: no coupling)
    for part in (upper, legs):
        for name in _names(part, j, part.njnt):
            jp, jf = part.joint(name), fixed.joint(name)
            assert part.body_mass[jp.bodyid[0]] == fixed.body_mass[jf.bodyid[0]]
            assert part.dof_armature[jp.dofadr[0]] == fixed.dof_armature[jf.dofadr[0]]
    # ... and the same mass matrix block and bias forces at a random configuration
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.LOWER, robot.UPPER)
    q[robot.IDX["RHipYawPitch"]] = q[robot.IDX["LHipYawPitch"]]
    whole = mujoco.MjData(fixed)
    whole.qpos[robot.joint_qpos_index(fixed)] = q
    whole.qvel[:] = rng.normal(size=fixed.nv)
    mujoco.mj_forward(fixed, whole)
    m_whole = np.zeros((fixed.nv, fixed.nv))
    mujoco.mj_fullM(fixed, whole, m_whole)
    for part in (upper, legs):
        names = [mujoco.mj_id2name(part, j, i) for i in range(part.njnt)]
        dof_w = np.array([fixed.joint(n).dofadr[0] for n in names])
        d = mujoco.MjData(part)
        for n in names:
            d.qpos[part.joint(n).qposadr[0]] = whole.qpos[fixed.joint(n).qposadr[0]]
            d.qvel[part.joint(n).dofadr[0]] = whole.qvel[fixed.joint(n).dofadr[0]]
        mujoco.mj_forward(part, d)
        m_part = np.zeros((part.nv, part.nv))
        mujoco.mj_fullM(part, d, m_part)
        dof_p = np.array([part.joint(n).dofadr[0] for n in names])
        np.testing.assert_allclose(m_part[np.ix_(dof_p, dof_p)], m_whole[np.ix_(dof_w, dof_w)],
                                   atol=1e-12)  # fmt: skip
        np.testing.assert_allclose(d.qfrc_bias[dof_p], whole.qfrc_bias[dof_w], atol=1e-12)
        others = np.setdiff1d(np.arange(fixed.nv), dof_w)
        assert np.all(m_whole[np.ix_(dof_w, others)] == 0.0)  # no inertial coupling
    with pytest.raises(ConfigError, match="fixed mount"):
        robot.load_model("free", without=robot.LEG_ROOTS)
    with pytest.raises(ConfigError, match="Knee"):
        robot.load_model("fixed", without=("Knee",))
    with pytest.raises(ConfigError, match="torso"):
        robot.load_model("fixed", without=("torso",))


@pytest.mark.parametrize("mount", ["free", "fixed"])
def test_joint_ranges_match_reference(mount: str) -> None:
    model = robot.load_model(mount)  # type: ignore[arg-type]
    assert len(REF_LIMITS) == 26
    for name, (lo, hi, _) in REF_LIMITS.items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert jid >= 0, name
        assert model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_HINGE, name
        assert model.jnt_limited[jid], name
        np.testing.assert_allclose(model.jnt_range[jid], (lo, hi), atol=1e-9, err_msg=name)


def test_robot_constants_match_reference() -> None:
    for name, (lo, hi, _) in REF_LIMITS.items():
        i = robot.JOINT_NAMES.index(name)
        assert robot.LOWER[i] == pytest.approx(lo, abs=1e-6), name
        assert robot.UPPER[i] == pytest.approx(hi, abs=1e-6), name


def test_actuators(fixed: mujoco.MjModel, free: mujoco.MjModel) -> None:
    for model in (fixed, free):
        act = robot.actuator_index(model)
        assert act.shape == (26,)
        for i, name in enumerate(robot.JOINT_NAMES):
            driver = "LHipYawPitch" if name == "RHipYawPitch" else name
            assert mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, act[i]) == driver
            lo, hi, effort = REF_LIMITS[driver]
            np.testing.assert_allclose(model.actuator_ctrlrange[act[i]], (lo, hi), atol=1e-9)
            np.testing.assert_allclose(
                model.actuator_forcerange[act[i]], (-effort, effort), atol=1e-9
            )
            assert model.actuator_gainprm[act[i], 0] > 0  # a position servo: kp > 0
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "RHipYawPitch") == -1
        assert len(set(act.tolist())) == 25


def test_total_mass() -> None:
    for mount in ("free", "fixed"):
        model = robot.load_model(mount)  # type: ignore[arg-type]
        assert abs(model.body_mass.sum() - REF_TOTAL_MASS) < 1e-3
    # spot checks of the V5 URDF masses (reference section 6)
    model = robot.load_model("free")
    for body, mass in (("torso", 1.04956), ("Head", 0.60533), ("l_wrist", 0.18533),
                       ("LThigh", 0.38968), ("r_ankle", 0.17184)):  # fmt: skip
        assert model.body(body).mass[0] == pytest.approx(mass, abs=1e-9), body


def test_index_helpers(fixed: mujoco.MjModel, free: mujoco.MjModel) -> None:
    for model in (fixed, free):
        qi = robot.joint_qpos_index(model)
        di = robot.joint_dof_index(model)
        assert qi.shape == di.shape == (26,)
        assert len(set(qi.tolist())) == 26
        for i, name in enumerate(robot.JOINT_NAMES):
            assert model.jnt_qposadr[model.joint(name).id] == qi[i]
            assert model.jnt_dofadr[model.joint(name).id] == di[i]
    assert robot.joint_qpos_index(free).min() == 7 and robot.joint_dof_index(free).min() == 6
    assert robot.joint_qpos_index(fixed).min() == 0


# --- kinematics -------------------------------------------------------------------------------


@pytest.mark.parametrize("mount", ["free", "fixed"])
def test_zero_pose_positions(mount: str) -> None:
    model = robot.load_model(mount)  # type: ignore[arg-type]
    names = list(REF_ZERO_LEFT)
    left = _sites(model, ZERO, *[f"l_{n}" for n in names])
    right = _sites(model, ZERO, *[f"r_{n}" for n in names])
    expected = np.array([REF_ZERO_LEFT[n] for n in names])
    np.testing.assert_allclose(left, expected, atol=1e-6)
    np.testing.assert_allclose(right, expected * np.array([1.0, -1.0, 1.0]), atol=1e-6)
    np.testing.assert_allclose(_sites(model, ZERO, "torso", "neck"), [[0, 0, 0], [0, 0, 0.1265]],
                               atol=1e-9)  # fmt: skip


def test_site_positions_batch(free: mujoco.MjModel) -> None:
    rng = np.random.default_rng(0)
    lo = np.array([REF_LIMITS[n][0] for n in robot.JOINT_NAMES])
    hi = np.array([REF_LIMITS[n][1] for n in robot.JOINT_NAMES])
    qs = rng.uniform(lo, hi, size=(4, 26))
    batch = robot.site_positions(free, qs, ["l_hand", "r_sole"])
    assert batch.shape == (4, 2, 3)
    for t in range(4):
        single = robot.site_positions(free, qs[t], ["l_hand", "r_sole"])
        np.testing.assert_allclose(batch[t], single)
    assert not np.allclose(batch[0], batch[1])
    with pytest.raises(ConfigError):
        robot.site_positions(free, np.zeros(25), ["l_hand"])
    with pytest.raises(ConfigError):
        robot.site_positions(free, ZERO, ["no_such_site"])


def test_sign_conventions(fixed: mujoco.MjModel) -> None:
    # ShoulderPitch +pi/2: the arm hangs down (elbow a full upper arm below the shoulder)
    sh, el = _sites(fixed, _pose(LShoulderPitch=np.pi / 2), "l_shoulder", "l_elbow")
    assert el[2] < sh[2] - 0.1 and abs(el[0] - sh[0]) < 1e-6
    # LShoulderRoll > 0: left elbow outward (+y); RShoulderRoll < 0: right elbow to -y
    y0 = _sites(fixed, ZERO, "l_elbow", "r_elbow")[:, 1]
    yl = _sites(fixed, _pose(LShoulderRoll=0.5), "l_elbow")[0, 1]
    yr = _sites(fixed, _pose(RShoulderRoll=-0.5), "r_elbow")[0, 1]
    assert yl > y0[0] + 0.04 and yr < y0[1] - 0.04
    # LElbowRoll < 0 / RElbowRoll > 0 flex the elbow: the hand comes closer to the shoulder
    for side, sign in (("l", -1.0), ("r", 1.0)):
        joint = f"{side.upper()}ElbowRoll"
        sh0, hand0 = _sites(fixed, ZERO, f"{side}_shoulder", f"{side}_hand")
        sh1, hand1 = _sites(fixed, _pose(**{joint: sign * 1.2}), f"{side}_shoulder", f"{side}_hand")
        assert np.linalg.norm(hand1 - sh1) < np.linalg.norm(hand0 - sh0) - 0.03
        el, wr = _sites(fixed, _pose(**{joint: sign * 1.2}), f"{side}_elbow", f"{side}_wrist")
        # ElbowYaw = 0, arm forward: flexion swings the forearm medially (towards the midline)
        assert abs(wr[1]) < abs(el[1]) - 0.04
    # arm hanging, elbow bent 90 deg: LElbowYaw = -pi/2 (RElbowYaw = +pi/2) -> forearm forward
    for side, sign in (("L", 1.0), ("R", -1.0)):
        q = _pose(**{f"{side}ShoulderPitch": np.pi / 2, f"{side}ElbowRoll": -sign * np.pi / 2,
                     f"{side}ElbowYaw": -sign * np.pi / 2})  # fmt: skip
        el, wr = _sites(fixed, q, f"{side.lower()}_elbow", f"{side.lower()}_wrist")
        d = (wr - el) / np.linalg.norm(wr - el)
        np.testing.assert_allclose(d, [1.0, 0.0, 0.0], atol=1e-6)
        # and ElbowYaw = 0 points it across the body instead
        q[robot.JOINT_NAMES.index(f"{side}ElbowYaw")] = 0.0
        el, wr = _sites(fixed, q, f"{side.lower()}_elbow", f"{side.lower()}_wrist")
        assert sign * (wr - el)[1] < -0.05


def test_coupled_hip(fixed: mujoco.MjModel, free: mujoco.MjModel) -> None:
    q = _pose(LHipYawPitch=0.3, RHipYawPitch=-0.2)
    for model in (fixed, free):
        qpos = robot.config_to_qpos(model, q)
        qi = robot.joint_qpos_index(model)
        assert qpos.shape == (model.nq,)
        assert qpos[qi[robot.JOINT_NAMES.index("RHipYawPitch")]] == pytest.approx(0.3)
        assert qpos[qi[robot.JOINT_NAMES.index("LHipYawPitch")]] == pytest.approx(0.3)
    qpos = robot.config_to_qpos(free, q)
    np.testing.assert_array_equal(qpos[:7], [0, 0, 0, 1, 0, 0, 0])
    assert q[robot.JOINT_NAMES.index("RHipYawPitch")] == -0.2  # input not modified
    e = free.eq("hip_yaw_pitch_coupling").id
    assert free.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT
    joint1, joint2 = free.joint(int(free.eq_obj1id[e])), free.joint(int(free.eq_obj2id[e]))
    assert (joint1.name, joint2.name) == ("RHipYawPitch", "LHipYawPitch")  # q_R = f(q_L)
    np.testing.assert_allclose(free.eq_data[e][:5], [0, 1, 0, 0, 0])


@pytest.mark.parametrize("hyp", [-0.6, 0.0, 0.4])
def test_leg_mirror_symmetry(fixed: mujoco.MjModel, hyp: float) -> None:
    # mirror: pitch joints keep their sign, roll joints flip it; HipYawPitch is shared
    left = {"HipRoll": 0.2, "HipPitch": -0.7, "KneePitch": 1.1, "AnklePitch": -0.5,
            "AnkleRoll": 0.15}  # fmt: skip
    flip = {"HipRoll": -1.0, "AnkleRoll": -1.0}
    angles = {"LHipYawPitch": hyp}
    for k, v in left.items():
        angles["L" + k] = v
        angles["R" + k] = flip.get(k, 1.0) * v
    q = _pose(**angles)
    names = ("knee", "ankle", "sole")
    lpos = _sites(fixed, q, *[f"l_{n}" for n in names])
    rpos = _sites(fixed, q, *[f"r_{n}" for n in names])
    np.testing.assert_allclose(rpos, lpos * np.array([1.0, -1.0, 1.0]), atol=1e-9)
    assert not np.allclose(lpos[0], REF_ZERO_LEFT["knee"], atol=1e-3)


def test_hip_yaw_pitch_axis(fixed: mujoco.MjModel) -> None:
    # reference section 5: left q = +0.3 swings the leg backwards: direction (-0.21, 0.02, -0.98)
    hip, ankle = _sites(fixed, _pose(LHipYawPitch=0.3), "l_hip", "l_ankle")
    d = (ankle - hip) / np.linalg.norm(ankle - hip)
    np.testing.assert_allclose(d, [-0.21, 0.02, -0.98], atol=0.01)


# --- collision --------------------------------------------------------------------------------


def _contact_pairs(model: mujoco.MjModel, q: np.ndarray) -> list[tuple[str, str]]:
    data = mujoco.MjData(model)
    data.qpos[:] = robot.config_to_qpos(model, q)
    mujoco.mj_forward(model, data)
    name = lambda g: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)  # noqa: E731
    return [(name(c.geom1), name(c.geom2)) for c in data.contact[: data.ncon]]


def test_no_contacts_at_rest_postures(fixed: mujoco.MjModel) -> None:
    for q in (ZERO, np.asarray(robot.STANDING_POSTURE, dtype=np.float64)):
        assert _contact_pairs(fixed, q) == []


def _group(geom_name: str) -> str:
    return geom_name.split("_")[0]


def test_crossing_poses_collide(fixed: mujoco.MjModel) -> None:
    # left arm hanging, shoulder rolled inward, elbow fully flexed with ElbowYaw = 0: the
    # forearm swings medially through the torso
    q = _pose(robot.STANDING_POSTURE, LShoulderRoll=-0.3142, LElbowYaw=0.0, LElbowRoll=-1.5446)
    pairs = _contact_pairs(fixed, q)
    assert any({_group(a), _group(b)} == {"l", "torso"} for a, b in pairs), pairs
    # both arms forward, rolled inward, elbows flexed: the forearms cross in front of the chest
    q = _pose(LShoulderRoll=-0.3142, LElbowRoll=-1.5446, RShoulderRoll=0.3142, RElbowRoll=1.5446)
    pairs = _contact_pairs(fixed, q)
    assert any({_group(a), _group(b)} == {"l", "r"} for a, b in pairs), pairs


def test_collision_filter_bits(fixed: mujoco.MjModel) -> None:
    names = [mujoco.mj_id2name(fixed, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(fixed.ngeom)]
    assert set(names) >= {"torso_geom", "head_geom", "l_upperarm_geom", "l_forearm_geom",
                          "l_hand_geom", "r_upperarm_geom", "r_forearm_geom", "r_hand_geom",
                          "l_thigh_geom", "l_tibia_geom", "l_foot_geom", "r_thigh_geom",
                          "r_tibia_geom", "r_foot_geom"}  # fmt: skip
    assert all(fixed.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH for g in range(fixed.ngeom))
    arm = {"upperarm", "forearm", "hand"}
    idx = {n: i for i, n in enumerate(names)}

    def can_collide(a: str, b: str) -> bool:
        ia, ib = idx[a], idx[b]
        ct, ca = fixed.geom_contype, fixed.geom_conaffinity
        return bool((ct[ia] & ca[ib]) or (ct[ib] & ca[ia]))

    for side, other in (("l", "r"), ("r", "l")):
        for a in arm:
            ga = f"{side}_{a}_geom"
            assert can_collide(ga, "torso_geom") and can_collide(ga, "head_geom")
            for b in arm:
                assert not can_collide(ga, f"{side}_{b}_geom")  # never inside one arm
                assert can_collide(ga, f"{other}_{b}_geom")  # left arm vs right arm
            for leg in ("thigh", "tibia", "foot"):
                assert not can_collide(ga, f"{side}_{leg}_geom")
                assert not can_collide(ga, f"{other}_{leg}_geom")
    assert not can_collide("torso_geom", "head_geom")


# --- MJX --------------------------------------------------------------------------------------

# The compile is the slow part of a first mjx.step on CPU; this test only checks the model is
# MJX-compatible, so compile without XLA's optimisation passes. MJX's own code relies on implicit
# dtype / rank promotion, so the strict mode of conftest.py is relaxed around the MJX call only.
_FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}


# the "fixed" mount runs through MJX in every rollout test (tests/eval/test_rollout.py, against
# CPU MuJoCo); this checks the other one, the free-floating robot
@pytest.mark.parametrize("mount", ["free"])
def test_mjx_step(mount: str) -> None:
    model = robot.load_model(mount)  # type: ignore[arg-type]
    mx = mjx.put_model(model)
    dx = mjx.make_data(mx)
    dx = dx.replace(
        qpos=jnp.asarray(robot.config_to_qpos(model, robot.STANDING_POSTURE)),
        ctrl=jnp.asarray(np.asarray(robot.STANDING_POSTURE)[_unique_actuated(model)]),
    )
    with jax.numpy_dtype_promotion("standard"), jax.numpy_rank_promotion("allow"):
        step = jax.jit(mjx.step).lower(mx, dx).compile(compiler_options=_FAST_COMPILE)
        out = step(mx, dx)
    qpos = np.asarray(out.qpos)
    assert qpos.shape == (model.nq,) and np.all(np.isfinite(qpos))
    assert np.all(np.isfinite(np.asarray(out.qvel)))
    assert np.asarray(out.time) == pytest.approx(0.002)


def _unique_actuated(model: mujoco.MjModel) -> np.ndarray:
    """(nu,) index into JOINT_NAMES of the joint each actuator drives."""
    act = robot.actuator_index(model)
    order = np.empty(model.nu, dtype=np.int64)
    for i, a in enumerate(act):
        if robot.JOINT_NAMES[i] != "RHipYawPitch":
            order[a] = i
    return order


# --- position servos --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("joint", "start", "target"),
    [
        ("LShoulderPitch", 1.4, 0.4),  # hanging -> raised, against gravity
        ("LShoulderPitch", 0.0, 1.0),
        ("RShoulderPitch", 1.4, 0.4),
        ("LShoulderRoll", 0.15, 1.15),
        ("RShoulderRoll", -0.15, -1.15),
        ("LElbowYaw", -1.2, -0.2),
        ("LElbowRoll", -0.05, -1.05),
        ("RElbowRoll", 1.5, 0.5),
    ],
)
def test_arm_step_response(fixed: mujoco.MjModel, joint: str, start: float, target: float) -> None:
    assert fixed.opt.gravity[2] == pytest.approx(-9.81)
    i = robot.JOINT_NAMES.index(joint)
    qi = robot.joint_qpos_index(fixed)[i]
    act = robot.actuator_index(fixed)[i]
    order = _unique_actuated(fixed)
    q = _pose(robot.STANDING_POSTURE, **{joint: start})
    data = mujoco.MjData(fixed)
    data.qpos[:] = robot.config_to_qpos(fixed, q)
    data.ctrl[:] = q[order]
    for _ in range(250):  # settle 0.5 s under gravity
        mujoco.mj_step(fixed, data)
    assert abs(data.qpos[qi] - start) < 0.05
    data.ctrl[act] = target
    n = round(0.3 / fixed.opt.timestep)
    for _ in range(n):
        mujoco.mj_step(fixed, data)
    assert abs(data.qpos[qi] - target) < 0.05, (joint, data.qpos[qi])
    assert np.all(np.isfinite(data.qpos))
