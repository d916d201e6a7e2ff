"""The generic IK (jaxproj.robots.generic_ik) and its forward kinematics (robots.kinematics).

Its correctness test: on held-out MSR frames it agrees with the NAO's closed form wherever the
closed form solves the same problem (its rules for straight elbows and its joint-by-joint
clamping excepted, counted). Compiles: the NAO arms once (module fixture, one shape), the G1's
left arm twice (with and without the collision term).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError
from jaxproj.human import skeleton
from jaxproj.human.skeleton import UPPER_BODY
from jaxproj.io import datasets
from jaxproj.robots import NAO_H25, UNITREE_G1, generic_ik
from jaxproj.robots.generic_ik import (
    BonePair,
    Correspondence,
    GenericIK,
    IKConfig,
    TrackConfig,
    chain_rows,
    mjcf_collision_pairs,
    own_chains,
    row_turned_by,
)
from jaxproj.robots.kinematics import TreeFK, points_at
from jaxproj.robots.nao_h25 import ik as nao_ik

NAO_ARMS = nao_ik.ARM_CORRESPONDENCE
assert UNITREE_G1.generic is not None
G1_IK = UNITREE_G1.generic

N_FRAMES = 512


@pytest.mark.parametrize(
    ("robot", "points", "base"),
    [
        (NAO_H25, ("l_shoulder", "l_elbow", "l_wrist", "r_hand", "l_sole", "neck"), "torso"),
        (UNITREE_G1, ("left_elbow_site", "right_hand_site", "left_toe_site", "pelvis"),
         "torso_link"),
        # every point below the base: the tree starts at the base (waist joints skipped)
        (UNITREE_G1, ("left_elbow_site", "right_hand_site", "head_site"), "torso_link"),
    ],
)  # fmt: skip
def test_tree_fk_matches_mujoco(robot, points, base) -> None:
    model = robot.load_model("fixed")
    fk = TreeFK.from_model(model, robot.joint_names, points, base)
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.lower, robot.upper, (40, robot.n_joints)).astype(np.float32)
    want = np.stack([points_at(model, robot.joint_names, r, points, base) for r in q])
    # jitted, as the IK runs them (eager, every primitive compiled apart: ~10 s of a CPU)
    fk_points = jax.jit(fk.points)
    assert np.abs(np.asarray(fk_points(q)) - want).max() < 2e-6  # m, float32 chains of ~1 m
    # the analytic Jacobian against forward-mode differentiation, joints moving the base too
    cols = tuple(range(robot.n_joints))
    p, jac = jax.jit(fk.jacobian, static_argnums=1)(q[:8], cols)
    ref = jax.jit(jax.vmap(jax.jacfwd(fk.points)))(jnp.asarray(q[:8]))
    assert np.abs(np.asarray(jac) - np.asarray(ref)).max() < 1e-5
    assert np.array_equal(np.asarray(p), np.asarray(fk_points(q[:8])))
    # the generic IK's form: some points' derivatives only, a padding column (-1) all zeros
    frame, axis, anchor, sign = fk.columns((*cols[:3], -1))
    moved = np.array([len(points) - 1, 0])
    columns = jax.jit(fk.jacobian_columns)
    pm, dm = columns(q[:8], frame, axis, anchor, sign[:, moved], moved)
    assert np.array_equal(np.asarray(pm), np.asarray(p))
    assert np.abs(np.asarray(dm)[..., :3] - np.asarray(jac)[:, moved, :, :3]).max() < 1e-6
    assert not np.asarray(dm)[..., 3].any()


@pytest.fixture(scope="module")
def nao_case():
    """Held-out MSR descriptors, the closed form's answers and the generic IK's (one compile)."""
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    d = np.asarray(datasets.valid_descriptors(seqs))
    d = d[np.linspace(0, len(d) - 1, N_FRAMES).astype(int)]
    ik = GenericIK.build(NAO_H25, NAO_ARMS, chains=NAO_H25.chains[1:])
    solve = jax.jit(lambda x: ik.solve_info(x, "upper"))
    q, info = solve(d)
    return d, np.asarray(NAO_H25.solve_ik(d)), np.asarray(q), info, ik, solve


def test_generic_ik_agrees_with_the_nao_closed_form(nao_case) -> None:
    d, ref, q, info, _, _ = nao_case
    arms = [NAO_H25.driven_joints.index(j) for c in NAO_H25.chains[1:] for j in c.joints]
    err = np.degrees(np.abs(q[:, arms] - ref[:, arms]))
    assert np.median(err) <= 0.01  # deg, over frames and arm joints
    # where the closed form solves the same problem (elbow bent >= 30 deg: outside its
    # straight-elbow rule; no joint at a limit: no joint-by-joint clamping), they agree
    vec = d.reshape(len(d), len(UPPER_BODY), 3)
    for side, (u_i, f_i) in (("left", (1, 2)), ("right", (3, 4))):
        u, f = (vec[:, i] / np.linalg.norm(vec[:, i], axis=1, keepdims=True) for i in (u_i, f_i))
        flex = np.degrees(np.arccos(np.clip(np.sum(u * f, axis=1), -1, 1)))
        js = [NAO_H25.driven_joints.index(j) for j in NAO_H25.chain(f"{side}_arm").joints]
        lo, hi = NAO_H25.lower_driven[js], NAO_H25.upper_driven[js]
        at_limit = ((ref[:, js] - lo < 1e-5) | (hi - ref[:, js] < 1e-5)).any(axis=1)
        same = (flex >= 30) & ~at_limit
        assert same.sum() > 50, (side, same.sum())
        assert np.degrees(np.abs(q[same][:, js] - ref[same][:, js])).max() < 0.01, side
    assert np.isfinite(q).all()
    lo, hi = NAO_H25.lower_driven, NAO_H25.upper_driven
    assert ((q >= lo) & (q <= hi)).all()
    # untouched chain (the head) stays standing; diagnostics per chain
    head = [NAO_H25.driven_joints.index(j) for j in NAO_H25.chain("head").joints]
    assert np.array_equal(q[:, head], np.broadcast_to(NAO_H25.standing_driven[head], (len(q), 2)))
    assert info.objective.shape == (len(d), 2) and info.stationary.shape == (len(d), 2)
    assert np.asarray(info.stationary).mean() > 0.85


def test_generic_ik_deterministic_and_the_same_in_a_users_jit(nao_case) -> None:
    d, _, q, _, ik, solve = nao_case
    again, _ = solve(d)
    assert np.array_equal(np.asarray(again), q)
    # a user's own jit around the traceable solve, under the lowest default matmul precision
    with jax.default_matmul_precision("bfloat16"):
        mine = jax.jit(lambda x: ik.solve(x, "upper") * 1.0)(d)
    assert np.array_equal(np.asarray(mine), q)


def test_generic_ik_never_nan(nao_case) -> None:
    d, _, _, _, _, solve = nao_case
    bad = d.copy()
    bad[:5, 3:6] = 0.0  # zero-length left upper arm
    bad[5:10, 6:9] = np.nan  # non-finite left forearm
    bad[10:15] = np.inf
    q, _ = solve(bad)
    q = np.asarray(q)
    assert np.isfinite(q).all()
    assert ((q >= NAO_H25.lower_driven) & (q <= NAO_H25.upper_driven)).all()
    # a bone without usable input gets no weight: with both arm bones gone the arm stands
    left = [NAO_H25.driven_joints.index(j) for j in NAO_H25.chain("left_arm").joints]
    np.testing.assert_allclose(q[10:15][:, left], np.broadcast_to(
        NAO_H25.standing_driven[left], (5, 4)), atol=1e-6)  # fmt: skip


def test_collision_term_keeps_the_g1_forearm_out_of_its_torso() -> None:
    """Forearms across the chest: without the term the forearm passes through the torso. The
    left arm's solve keeps it out of the torso (its own pairs), not out of the right arm (the
    two arms' pairs are ``separate``'s): ``separate`` then leaves no contact at all."""
    bones = ("upper_arm_left", "forearm_left")
    d = np.array([[0, 0, -1, 0, -1, 0], [0, 0, -1, 0.2, -1, 0.1], [0.3, 0.1, -0.9, 0.1, -1, 0.3]],
                 np.float32)  # fmt: skip
    model = UNITREE_G1.load_model("fixed")
    data = mujoco.MjData(model)
    right_arm = {"right_shoulder_pitch_link", "right_shoulder_roll_link", "right_shoulder_yaw_link",
                 "right_elbow_link", "right_wrist_roll_link", "right_wrist_pitch_link",
                 "right_wrist_yaw_link"}  # fmt: skip

    def worst_gap(q: np.ndarray, own: bool = False) -> float:
        """Deepest contact (m; inf: none); ``own``: not counting contacts with the right arm."""
        worst = np.inf
        for row in q:
            data.qpos[:] = UNITREE_G1.driven_to_full(row)
            mujoco.mj_forward(model, data)
            for c in data.contact[: data.ncon]:
                bodies = {model.body(model.geom_bodyid[g]).name for g in (c.geom1, c.geom2)}
                if not (own and bodies & right_arm):
                    worst = min(worst, c.dist)
        return worst

    answers = {}
    for weight in (0.0, G1_IK.config.collision):
        cfg = IKConfig(collision=weight, starts=2, margin=G1_IK.config.margin)
        ik = GenericIK.build(
            UNITREE_G1, G1_IK.correspondence, cfg, chains=(UNITREE_G1.chain("left_arm"),)
        )
        answers[weight] = np.asarray(jax.jit(lambda x, ik=ik: ik.solve(x, bones))(d))
    assert worst_gap(answers[0.0], own=True) < -0.03  # m: the forearm inside the torso
    # no contact (MuJoCo's own) but with the right arm, which the left arm's solve leaves alone
    assert worst_gap(answers[G1_IK.config.collision], own=True) == np.inf
    assert worst_gap(answers[G1_IK.config.collision]) < 0
    # separate: the direction-only answers pushed out of the torso; a free pose is not moved
    free = np.zeros((1, UNITREE_G1.n_driven), np.float32)  # the left arm held out sideways
    free[0, UNITREE_G1.driven_joints.index("left_shoulder_roll_joint")] = 1.0
    free[0, UNITREE_G1.driven_joints.index("left_elbow_joint")] = 1.5
    q = np.concatenate([answers[0.0], free])
    out = np.asarray(jax.jit(ik.separate)(q))
    assert worst_gap(out) == np.inf
    np.testing.assert_array_equal(out[-1], free[0])
    assert np.all((out >= UNITREE_G1.lower_driven) & (out <= UNITREE_G1.upper_driven))


def test_ranges_narrow_the_box_to_the_human_branch() -> None:
    """A straight G1 arm stops at the straight elbow (+90 deg), not past it with the upper arm
    twisted half a turn: ``Correspondence.ranges``."""
    lo, hi = G1_IK.correspondence.box(UNITREE_G1, ("left_elbow_joint", "left_knee_joint"))
    np.testing.assert_allclose(hi[0], np.pi / 2, rtol=1e-6)
    assert lo[1] == 0.0 and hi[1] == np.float32(
        UNITREE_G1.upper[UNITREE_G1.index("left_knee_joint")]
    )
    # the yaws a person cannot turn past 45 deg: thighs and trunk (the G1's go to 158 / 150 deg)
    yaws = ("left_hip_yaw_joint", "right_hip_yaw_joint", "waist_yaw_joint")
    lo, hi = G1_IK.correspondence.box(UNITREE_G1, yaws)
    np.testing.assert_allclose(np.stack([lo, hi]), np.broadcast_to(
        np.float32([[-np.pi / 4], [np.pi / 4]]), (2, 3)), rtol=1e-6)  # fmt: skip
    assert all(UNITREE_G1.upper[UNITREE_G1.index(j)] > 2.5 for j in yaws)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: BonePair("elbow", "a", "b"), "unknown bone"),
        (lambda: BonePair("neck", "a", "a"), "same point"),
        (lambda: BonePair("neck", "a", "b", weight=0.0), "weight"),
        (lambda: BonePair("neck", "a", "b", minus="neck"), "minus"),
        (lambda: BonePair("neck", "a", "b", rest=(0.0, 0.0, 0.0)), "rest"),
        (lambda: Correspondence("torso", ()), "at least one"),
        (lambda: IKConfig(starts=0), "starts"),
        (lambda: TrackConfig(follow=-1.0), "follow must"),
        (lambda: TrackConfig(follow_error=0.0), "follow_error"),
        (lambda: Correspondence("torso", NAO_ARMS.pairs, ranges=(("HeadYaw", 1.0, 0.0),)), "lower"),
        (
            lambda: Correspondence("torso", NAO_ARMS.pairs, ranges=(("Tail", 0.0, 1.0),)).box(
                NAO_H25, ("HeadYaw",)
            ),
            "no such joint",
        ),
        (
            lambda: GenericIK.build(
                NAO_H25,
                Correspondence("torso", (BonePair("neck", "torso", "nowhere"),)),
                chains=NAO_H25.chains[:1],
            ),
            "no site or body",
        ),  # fmt: skip
        (lambda: GenericIK.build(NAO_H25, NAO_ARMS, chains=NAO_H25.chains[:1]), "head"),
        # a row no chain lists, and a row its chain's joints cannot turn: named
        (
            lambda: GenericIK.build(
                UNITREE_G1,
                Correspondence(
                    "torso_link",
                    (*G1_IK.correspondence.pairs, BonePair("neck", "torso_site", "head_site")),
                ),
            ),
            "read by no chain: 'neck'",
        ),
        (
            lambda: GenericIK.build(
                NAO_H25,
                Correspondence(
                    "torso", (*NAO_ARMS.pairs, BonePair("upper_arm_left", "torso", "neck"))
                ),
                chains=NAO_H25.chains[1:],
            ),
            "read by no chain: 'upper_arm_left' \\(torso -> neck\\)",
        ),
    ],
)
def test_bad_correspondence_is_refused(make, message) -> None:
    with pytest.raises(ConfigError, match=message):
        make()


ROWS_READ: dict[str, tuple[Correspondence, dict[str, tuple[str, ...]]]] = {
    # the NAO's closed form solves its head from the neck bone; the generic IK reads its arms
    "nao_h25": (
        NAO_ARMS,
        {
            "left_arm": ("upper_arm_left", "forearm_left"),
            "right_arm": ("upper_arm_right", "forearm_right"),
        },
    ),
    # the waist reads the hip line (its points hang from the hips, but the waist turns the
    # base); the legs list the waist's bones but read none of their rows
    "unitree_g1": (
        G1_IK.correspondence,
        {
            "waist": ("pelvis_left - pelvis_right", "spine_lower"),
            "left_arm": ("upper_arm_left", "forearm_left"),
            "right_arm": ("upper_arm_right", "forearm_right"),
            "left_leg": ("thigh_left", "shin_left", "foot_left"),
            "right_leg": ("thigh_right", "shin_right", "foot_right"),
        },
    ),
    # a yaw-only waist reads the hip line alone (no spine row); the arms are solved first
    "unitree_h1": (
        robots.get("unitree_h1").generic.correspondence,
        {
            "left_arm": ("upper_arm_left", "forearm_left"),
            "right_arm": ("upper_arm_right", "forearm_right"),
            "waist": ("pelvis_left - pelvis_right",),
            "left_leg": ("thigh_left", "shin_left", "foot_left"),
            "right_leg": ("thigh_right", "shin_right", "foot_right"),
        },
    ),
}
"""Per registered robot (the toy robot of ``tests/toy_robot.py`` has no correspondence: its
own closed form), its correspondence and, per chain the generic IK solves, the rows it reads."""


def _name(row: BonePair) -> str:
    return row.bone if row.minus is None else f"{row.bone} - {row.minus}"


def test_every_registered_robot_has_its_rows_listed() -> None:
    assert set(ROWS_READ) == set(robots.names())


@pytest.mark.parametrize("name", sorted(ROWS_READ))
def test_rows_each_chain_reads(name: str) -> None:
    """The rows per chain against the table, and the rule against the FK's own derivatives: a
    chain reads a row iff one of its joints moves the row's direction seen from the base at
    random poses (``TreeFK.jacobian``, which holds the base's joints apart)."""
    robot = robots.get(name)
    corr, want = ROWS_READ[name]
    model = robot.load_model("fixed")
    chains = [robot.chain(c) for c in want]
    got = {c.name: tuple(_name(r) for r in chain_rows(model, corr, c)) for c in chains}
    assert got == want
    # every row is read by some chain
    assert {_name(r) for r in corr.pairs} == {r for rows in want.values() for r in rows}
    # MuJoCo's own kinematics, central differences (h rad) at random poses
    points = sorted({p for r in corr.pairs for p in (r.start, r.end)}, key=str)
    q = np.random.default_rng(1).uniform(robot.lower, robot.upper, (3, robot.n_joints))
    h = 1e-4
    steps = np.concatenate([q[:, None] + h * np.eye(robot.n_joints), q[:, None] - h * np.eye(
        robot.n_joints)], axis=1).reshape(-1, robot.n_joints)  # fmt: skip
    pts = np.stack([points_at(model, robot.joint_names, s, points, corr.base) for s in steps])
    pts = pts.reshape(len(q), 2, robot.n_joints, len(points), 3)
    for r in corr.pairs:
        seg = pts[..., points.index(r.end), :] - pts[..., points.index(r.start), :]
        u = seg / np.linalg.norm(seg, axis=-1, keepdims=True)
        du = np.abs(u[:, 0] - u[:, 1]).max(axis=(0, 2)) / (2 * h)  # (n_joints,)
        turns = {j for j, v in zip(robot.joint_names, du, strict=True) if v > 1e-3}
        assert turns == row_turned_by(model, r, corr.base), _name(r)


def _twisted_skeleton(turn: float) -> np.ndarray:
    """``(20, 3)`` a person standing (x forward, y left, z up, m) with the upper body, from the
    Spine point up, turned ``turn`` deg about the vertical through the hip centre."""
    j = skeleton.JOINT_NAMES.index
    pos = np.zeros((20, 3))  # the hip centre at the origin
    (spine,) = G1_IK.correspondence.rows(("spine_lower",))
    pos[j("Spine")] = 0.1 * np.asarray(spine.rest)  # the calibrated rest: no waist pitch
    pos[j("ShoulderCenter")] = (0.0, 0.0, 0.45)
    pos[j("Head")] = (0.0, 0.0, 0.65)
    for side, y in (("Left", 1.0), ("Right", -1.0)):
        pos[j(f"Shoulder{side}")] = (0.0, 0.18 * y, 0.42)
        pos[j(f"Elbow{side}")] = (0.0, 0.2 * y, 0.15)
        pos[j(f"Wrist{side}")] = (0.0, 0.2 * y, -0.1)
        pos[j(f"Hand{side}")] = (0.02, 0.2 * y, -0.18)
        pos[j(f"Hip{side}")] = (0.03, 0.08 * y, -0.05)
        pos[j(f"Knee{side}")] = (0.03, 0.09 * y, -0.45)
        pos[j(f"Ankle{side}")] = (0.0, 0.09 * y, -0.85)
        pos[j(f"Foot{side}")] = (0.1, 0.09 * y, -0.88)
    c, s = np.cos(np.radians(turn)), np.sin(np.radians(turn))
    upper = [j(n) for n in skeleton.JOINT_NAMES[1:12]]  # Spine .. HandRight
    pos[upper] = pos[upper] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
    return pos


def test_the_stacked_chains_padding_is_inert() -> None:
    """The chains are padded to the largest's sizes and stacked (one scanned program): a padded
    joint has the box [0, 0], no Jacobian column and no start value, a padded row and pair
    weight 0, and a derivative slot points at the row's own moved point (no compile)."""
    ik = G1_IK.build()
    data, n_joints = ik.problems.data, UNITREE_G1.n_joints
    for i, (chain, rows) in enumerate(zip(ik.problems.chains, ik.problems.rows, strict=True)):
        n, r = len(chain.joints), len(rows)
        assert [UNITREE_G1.joint_names[j] for j in data.joints[i, :n]] == list(chain.joints)
        assert (data.joints[i, n:] == n_joints).all()
        for pad in (data.lo, data.hi, data.lim_lo, data.lim_hi):
            assert not pad[i, n:].any()
        assert not data.sign[i, n:].any() and not data.starts[i, :, n:].any()
        assert data.row_mask[i].sum() == r and not data.weights[i, r:].any()
        assert (data.weights[i, :r] > 0).all()
        m = len(data.moved[i])
        pairs = ((data.row_points[i, :r], data.row_slots[i, :r]),
                 (data.capsule_points[i], data.capsule_slots[i]))  # fmt: skip
        for points, slots in pairs:
            hit = slots.reshape(-1) < m
            assert hit.any()
            assert (data.moved[i][slots.reshape(-1)[hit]] == points.reshape(-1)[hit]).all()
    n_pairs = data.pair_mask.sum(axis=1)
    assert (n_pairs > 0).all() and n_pairs.max() == data.pair_mask.shape[1]


def test_a_chains_own_ik_is_the_whole_iks_problem_for_it() -> None:
    """A per-chain model's landmarks are labelled by the chain's own IK (``Chain.ik``: the
    chain and its ``own_chains``, from its descriptor columns); the projection stands in for the
    whole IK only if that is the whole IK's answer for the chain. So per chain both build the
    same problem (no compile): the same box, rows, starts and pairs, the same pairs counted per
    frame, and none of those moved by another chain's joints (an arm against a leg)."""
    whole = G1_IK.build()
    model = UNITREE_G1.load_model("fixed")
    pairs = mjcf_collision_pairs(model)
    for i, chain in enumerate(whole.problems.chains):
        own = own_chains(UNITREE_G1.chains, chain)
        alone = GenericIK.build(UNITREE_G1, G1_IK.correspondence, G1_IK.config, chains=own)
        a, w = alone.problems.take(np.array([-1])), whole.problems.take(np.array([i]))
        assert alone.problems.rows[-1] == whole.problems.rows[i]
        n, r, q = len(chain.joints), len(whole.problems.rows[i]), int(w.pair_mask[0].sum())
        assert int(a.pair_mask[0].sum()) == q
        for key, x, y in (
            ("box", np.stack([a.lo[0, :n], a.hi[0, :n]]), np.stack([w.lo[0, :n], w.hi[0, :n]])),
            ("weights", a.weights[0, :r], w.weights[0, :r]),
            ("starts", a.starts[0, :, :n], w.starts[0, :, :n]),
            ("pairs", a.collide[0, :q], w.collide[0, :q]),
            ("counted", a.own_mask[0, :q], w.own_mask[0, :q]),
        ):
            np.testing.assert_array_equal(x, y, err_msg=f"{chain.name}: {key}")
        # the counted pairs: moved by this chain, and by no joint of a chain outside its own
        mine = [pr for pr in pairs if set(chain.joints) & _moved(model, pr)]
        others = {j for c in UNITREE_G1.chains if c not in own for j in c.joints}
        expect = {pr for pr in mine if not (_moved(model, pr) & others)}
        caps = sorted({g for pr in mine for g in pr})  # the chain's capsules, as built
        counted = w.own_mask[0, :q]
        got = {(caps[a], caps[b]) for a, b in w.collide[0, :q][counted]}
        assert got == expect, chain.name
        k = len(expect)  # counted pairs first: the solve reads the first n_own pairs only
        assert counted[:k].all() and not counted[k:].any() and k <= whole.problems.n_own
        if chain.name != "waist":  # a limb against the body counts, a limb against a limb not
            assert 0 < k < len(mine), chain.name


def _moved(model: mujoco.MjModel, pair: tuple[str, str]) -> set[str]:
    """Joints that move one geom of ``pair`` against the other (on the path between them)."""

    def joints(geom: str) -> set[str]:
        b = int(model.geom_bodyid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)])
        out = set()
        while b > 0:
            adr, num = model.body_jntadr[b], model.body_jntnum[b]
            out |= {model.joint(j).name for j in range(adr, adr + num)}
            b = int(model.body_parentid[b])
        return out

    return joints(pair[0]) ^ joints(pair[1])


def test_g1_waist_yaw_follows_the_shoulders_turn_against_the_hips() -> None:
    """Shoulders turned 20 deg to the left of the hips (about the vertical): the hip-line row,
    which the waist reads (``ROWS_READ``), is matched at a waist yaw of +20 deg (the torso
    turned left of the pelvis, as the person's), to -20 deg the other way. The person's hip
    line from the descriptor (the body frame built from the shoulders), the G1's from its FK
    over a grid of waist yaws (roll and pitch 0: the spine is at its calibrated rest). Without
    a compile of the IK: ``benchmarks/experiments/g1_waist_yaw.py`` runs the IK itself (the
    same +-20 deg to 0.1 deg)."""
    model = UNITREE_G1.load_model("fixed")
    (row,) = [r for r in G1_IK.correspondence.pairs if r.minus is not None]
    fk = TreeFK.from_model(model, UNITREE_G1.joint_names, (row.start, row.end), "torso_link")
    yaws = np.radians(np.arange(-45.0, 45.25, 0.25))
    q = np.zeros((len(yaws), UNITREE_G1.n_joints), np.float32)
    q[:, UNITREE_G1.index("waist_yaw_joint")] = yaws
    p = np.asarray(fk.points(q), np.float64)
    robot = (p[:, 1] - p[:, 0]) / np.linalg.norm(p[:, 1] - p[:, 0], axis=-1, keepdims=True)
    names = skeleton.resolve_bones("full")
    for turn in (20.0, -20.0):
        d, ok = skeleton.descriptor(_twisted_skeleton(turn)[None].astype(np.float32), "full")
        assert bool(np.asarray(ok)[0])
        vec = np.asarray(d, np.float64)[0].reshape(-1, 3)
        left, right = (vec[names.index(b)] / np.linalg.norm(vec[names.index(b)])
                       for b in (row.bone, row.minus))  # fmt: skip
        human = (left - right) / np.linalg.norm(left - right)
        err = np.linalg.norm(robot - human, axis=-1)
        best = np.degrees(yaws[np.argmin(err)])
        assert abs(best - turn) <= 0.25 and err.min() < 5e-3, (turn, best, err.min())
        assert err[np.argmin(np.abs(yaws))] > 0.3  # the waist held at 0: 20 deg off


def test_track_holds_a_loose_joint_the_limb_does_not_justify(nao_case) -> None:
    """The continuity pass against per-frame answers that flip a nearly straight arm's
    ElbowYaw by 1.5 rad on every other frame (the forearm's direction moves a few degrees):
    with the person's limbs still, the output's ElbowYaw moves at most ``min_step`` a frame,
    and the arm's directions stay those of the answers; on answers that move smoothly it
    follows them (within the continuity term's lag)."""
    d, _, q, _, ik, _ = nao_case
    cfg = TrackConfig()
    names = NAO_H25.driven_joints
    yaw, roll = names.index("LElbowYaw"), names.index("LElbowRoll")
    base = q[7].copy()
    base[roll] = NAO_H25.upper[NAO_H25.index("LElbowRoll")]  # as straight as it goes
    flips = np.repeat(base[None], 10, axis=0)
    flips[1::2, yaw] = np.clip(base[yaw] + 1.5, -2.0, 2.0)
    still = np.repeat(d[7][None], 10, axis=0)
    track = jax.jit(lambda a, v, h: ik.track(a, v, h, "upper", cfg))
    out = np.asarray(track(flips, np.ones(10, bool), still))
    assert np.abs(np.diff(out[:, yaw])).max() <= cfg.min_step + 1e-4
    # the pull toward the answer (TrackConfig.follow) is off (or all but off) while the
    # output's directions are the answer's (here a few degrees apart): the loose yaw is held,
    # under 1 deg a frame, not dragged along by the flipping answers ...
    assert np.abs(np.diff(out[1:, yaw])).max() < np.radians(1.0)
    # ... which it is where the pull's threshold is 0: a step bound a frame, back and forth
    eager = dataclasses.replace(cfg, follow_error=1e-6)
    dragged = np.asarray(ik.track(flips, np.ones(10, bool), still, "upper", eager))
    assert np.abs(np.diff(dragged[1:, yaw])).min() > np.radians(5.0)

    def off(a: np.ndarray, b: np.ndarray) -> float:  # deg, the worst row direction of an arm
        u = np.asarray(ik._directions(jnp.asarray(NAO_H25.driven_to_full(a))))
        v = np.asarray(ik._directions(jnp.asarray(NAO_H25.driven_to_full(b))))
        cos = np.sum(u * v, -1)[ik.problems.data.row_mask]  # every chain's real rows
        return float(np.degrees(np.arccos(np.clip(cos, -1, 1))).max())

    assert max(off(out[t], flips[t]) for t in range(10)) < 6.0
    # answers that move smoothly (a 0.3 rad shoulder swing): followed, not held (one compile:
    # the same still person, a radius of min_step, steps of 2 deg)
    smooth = np.repeat(q[3][None], 10, axis=0)
    smooth[:, names.index("LShoulderPitch")] += np.linspace(0.0, 0.3, 10, dtype=np.float32)
    out = np.asarray(track(smooth, np.ones(10, bool), still))
    assert max(off(out[t], smooth[t]) for t in range(10)) < 1.0


def test_track_both_ways_joins_the_passes_per_chain_and_only_where_a_step_allows(
    nao_case, monkeypatch
) -> None:
    """``GenericIK._join_ways`` (``TrackConfig.both_ways``, the default) on made-up passes of a
    still person (every frame the answer ``a``; frame 2 invalid). Left arm: the forward pass
    is on ``a`` until frame 6 and stuck 0.5 rad off in shoulder pitch after; the backward pass
    the reverse, off until 5 and on ``a`` from 6: the two meet at ``a`` around frame 6, so the
    join follows ``a`` on every frame. Right arm: the forward pass on ``a`` until 4 and off
    from 5, the backward off until 5 and on ``a`` from 6: they never meet on ``a``, and a change
    of pass would be a 0.5 rad step (over the 15 deg bound), so the whole backward pass is
    kept (6 frames off against the forward pass's 7). Without a compile of the pass."""
    d, _, q, _, ik, _ = nao_case
    cfg = TrackConfig()
    names = NAO_H25.driven_joints
    left = [names.index(j) for j in NAO_H25.chain("left_arm").joints]
    right = [names.index(j) for j in NAO_H25.chain("right_arm").joints]
    lp, rp = names.index("LShoulderPitch"), names.index("RShoulderPitch")
    n_t = 12
    a = np.repeat(q[7][None], n_t, axis=0)
    fwd, bwd = a.copy(), a.copy()
    fwd[7:, lp] += 0.5
    bwd[:6, lp] += 0.5
    fwd[5:, rp] += 0.5
    bwd[:6, rp] += 0.5
    valid = np.ones(n_t, bool)
    valid[2] = False
    h = np.repeat(d[7][None], n_t, axis=0)
    upper = skeleton.resolve_bones("upper")

    def joined() -> jax.stages.Wrapped:
        return jax.jit(lambda f, b, v: ik._join_ways(f, b, jnp.asarray(a), v, jnp.asarray(h),
                                                     upper, cfg))  # fmt: skip

    join = joined()
    out = np.asarray(join(fwd, bwd, valid))
    ok = valid
    np.testing.assert_allclose(out[ok][:, left], a[ok][:, left], atol=1e-6)
    np.testing.assert_array_equal(out[ok][:, right], bwd[ok][:, right])
    # the same passes the other way round: the right arm now keeps the (new) backward pass,
    # which is the old forward one read backwards
    out_r = np.asarray(join(bwd[::-1], fwd[::-1], valid[::-1]))[::-1]
    np.testing.assert_allclose(out_r[ok][:, left], a[ok][:, left], atol=1e-6)
    np.testing.assert_array_equal(out_r[ok][:, right], bwd[ok][:, right])
    # a robot of more chains than JOIN_CHAINS joins whole poses: the right arm cannot change
    # pass, so neither can the left, and the backward pass (10 chain-frames off, against the
    # forward's 12) is kept whole
    monkeypatch.setattr(generic_ik, "JOIN_CHAINS", 1)
    np.testing.assert_array_equal(np.asarray(joined()(fwd, bwd, valid))[ok], bwd[ok])


def test_mjcf_collision_pairs_are_what_mujoco_collides() -> None:
    """``mjcf_collision_pairs`` of the G1: every self-contact MuJoCo's own pipeline reports
    between two capsules or spheres, over random poses, is one of its pairs; none of its pairs
    is an excluded (adjacent) or welded one; none touches at the standing posture."""
    model = UNITREE_G1.load_model("fixed")
    pairs = {frozenset(p) for p in mjcf_collision_pairs(model)}
    assert len(pairs) == 262
    capsules = {int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_SPHERE)}
    name = lambda g: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)  # noqa: E731
    data = mujoco.MjData(model)
    adr = [model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]
           for j in UNITREE_G1.joint_names]  # fmt: skip
    rng = np.random.default_rng(0)
    seen = 0
    for q in rng.uniform(UNITREE_G1.lower, UNITREE_G1.upper, (300, UNITREE_G1.n_joints)):
        data.qpos[adr] = q
        mujoco.mj_forward(model, data)
        for c in data.contact[: data.ncon]:
            if {int(model.geom_type[c.geom1]), int(model.geom_type[c.geom2])} <= capsules:
                assert frozenset((name(c.geom1), name(c.geom2))) in pairs
                seen += 1
    assert seen > 100  # random poses of the G1 do collide
    for a, b in ((("torso_geom", "left_upper_arm_geom")), ("pelvis_geom", "left_hip_geom")):
        assert frozenset((a, b)) not in pairs  # excluded as adjacent in the MJCF
    data.qpos[:] = 0
    mujoco.mj_forward(model, data)
    assert data.ncon == 0


def test_step_bounds_follow_the_limbs_turn(nao_case) -> None:
    """``GenericIK.step_bounds``: a joint's bound into a frame is ``max(min_step, step_gain *
    turn)`` of its own chain (the left forearm turns 20 deg: the left arm's joints may move
    36 deg, the right arm's ``min_step``), ``inf`` at the first frame, into and out of an
    invalid frame and for a joint of no chain (the head)."""
    d, _, _, _, ik, _ = nao_case
    cfg = TrackConfig()
    frames = np.repeat(d[7][None], 5, axis=0).astype(np.float64)
    fore = UPPER_BODY.index("forearm_left")
    v = frames[2].reshape(len(UPPER_BODY), 3)[fore]
    axis = np.cross(v, [0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis)
    a = np.radians(20.0)  # Rodrigues about an axis normal to the bone: a turn of exactly a
    turned = v * np.cos(a) + np.cross(axis, v) * np.sin(a)
    frames[2:, 3 * fore : 3 * fore + 3] = turned
    valid = np.array([True, True, True, False, True])
    bound = np.asarray(ik.step_bounds(valid, frames.astype(np.float32), "upper", cfg))
    names = NAO_H25.driven_joints
    left = [names.index(j) for j in NAO_H25.chain("left_arm").joints]
    right = [names.index(j) for j in NAO_H25.chain("right_arm").joints]
    head = [names.index(j) for j in NAO_H25.chain("head").joints]
    assert bound.shape == (5, NAO_H25.n_driven) and bound.dtype == np.float32
    assert np.isinf(bound[0]).all() and np.isinf(bound[3:]).all() and np.isinf(bound[:, head]).all()
    np.testing.assert_allclose(bound[1, left + right], cfg.min_step, rtol=1e-6)
    np.testing.assert_allclose(bound[2, left], cfg.step_gain * a, rtol=1e-3)
    np.testing.assert_allclose(bound[2, right], cfg.min_step, rtol=1e-6)


def test_bound_steps_shortens_only_what_overshoots() -> None:
    """``Robot.bound_steps``: a step within its bound is kept to the bit, one over it is
    shortened to the bound and the frames after follow from there; a robot without
    ``track_bounds`` (or a call without descriptors) returns its input."""
    rng = np.random.default_rng(3)
    n = NAO_H25.n_driven
    q = np.cumsum(rng.normal(0, 0.05, (6, n)), axis=0).astype(np.float32)
    q[3, 0] = q[2, 0] + 0.5  # an overshoot of 0.3 over a bound of 0.2
    bound = np.full((6, n), np.inf, np.float32)
    bound[1:, 0] = 0.2
    robot = dataclasses.replace(NAO_H25, track_bounds=lambda v, d, b: jnp.asarray(bound))
    d = np.zeros((6, 3 * len(UPPER_BODY)), np.float32)
    out = np.asarray(jax.jit(lambda x: robot.bound_steps(x, jnp.ones(6, bool), d, "upper"))(q))
    assert np.array_equal(out[:, 1:], q[:, 1:]) and np.array_equal(out[:3], q[:3])
    assert out[3, 0] == np.float32(q[2, 0] + np.float32(0.2))
    assert np.abs(np.diff(out[:, 0])).max() <= 0.2 + 1e-6
    assert np.abs(out[5, 0] - q[5, 0]) < np.abs(out[3, 0] - q[3, 0])  # catching up, bounded
    assert NAO_H25.bound_steps(q, np.ones(6, bool), d) is q
    assert robot.bound_steps(q, np.ones(6, bool), None) is q


# The G1's per-frame IK answer for a person standing with the hands at the hips (CMU 131_03,
# frame 0; deg): the arm chains' solve does not count the pairs between chains, and both hands
# are 2-5 cm inside the hip capsules.
_HANDS_IN_HIPS = {
    "left_hip_pitch_joint": -11.5, "left_hip_roll_joint": 3.1, "left_hip_yaw_joint": 9.0,
    "left_knee_joint": 32.5, "left_ankle_pitch_joint": -20.8, "right_hip_pitch_joint": -8.7,
    "right_hip_roll_joint": 0.9, "right_hip_yaw_joint": 2.2, "right_knee_joint": 30.9,
    "right_ankle_pitch_joint": -23.1, "waist_yaw_joint": -0.8, "waist_roll_joint": -0.1,
    "waist_pitch_joint": -0.2, "left_shoulder_pitch_joint": 15.9, "left_shoulder_roll_joint": 2.7,
    "left_shoulder_yaw_joint": -16.8, "left_elbow_joint": 41.1, "right_shoulder_pitch_joint": 14.4,
    "right_shoulder_roll_joint": 2.5, "right_shoulder_yaw_joint": 6.5, "right_elbow_joint": 49.8,
}  # fmt: skip


def test_g1_track_clears_a_hand_in_the_hip_with_the_arm_and_holds_the_standing_leg() -> None:
    """That answer held for 16 frames (the person still): the continuity pass clears the hands
    from the hips with the arms (``separate`` visits the limbs before the trunk) and holds the
    legs and the waist at the answer's angles on every frame. Before, the pass cleared the pair
    each frame by a step of the last chain, a leg: the left hip pitch walked 10 deg away from
    the hand in 10 frames while the person stood still."""
    g1 = UNITREE_G1
    q = np.radians([_HANDS_IN_HIPS[n] for n in g1.driven_joints]).astype(np.float32)
    answers = np.repeat(q[None], 16, axis=0)
    # no descriptor (zeros: no usable bone, no turn): the pass's step bound is min_step; the
    # program is tests/motion/test_streaming.py's whole-motion pass, served by the run's
    # compilation cache when that test compiled it first
    still = np.zeros((16, 3 * len(skeleton.resolve_bones("full"))), np.float32)
    out = np.asarray(jax.jit(lambda q, d: g1.continuous(q, np.ones(len(q), bool), d, "full"))(
        answers, still))  # fmt: skip
    model = g1.load_model("fixed")
    data = mujoco.MjData(model)

    def deepest(row: np.ndarray) -> float:  # m, MuJoCo's own contacts (0: none)
        data.qpos[:] = g1.driven_to_full(row)
        mujoco.mj_forward(model, data)
        return min([0.0, *(c.dist for c in data.contact[: data.ncon])])

    assert deepest(q) < -0.02  # the answer: a hand 2 cm or more inside a hip
    assert min(deepest(row) for row in out) > -1e-3  # the output: no contact over 1 mm
    arms = [i for i, n in enumerate(g1.driven_joints) if "shoulder" in n or "elbow" in n]
    rest = [i for i in range(g1.n_driven) if i not in arms]
    off = np.degrees(np.abs(out[:, rest] - q[rest]))
    assert off.max() < 2.0 and off[-4:].max() < 0.2  # the legs and waist: no walk
    assert np.degrees(np.abs(np.diff(out[-5:], axis=0))).max() < 0.1  # settled


BOX_XML = """
<mujoco><worldbody><body name="foot">
  <geom name="sole" type="box" size="0.1 0.02 0.02"/>
  <geom name="inside" type="capsule" size="0.02" fromto="-0.08 0 0  0.08 0 0"/>
  <geom name="through" type="capsule" size="0.01" fromto="0 0 -0.05  0 0 0.05"/>
  <body name="other" pos="0 0.5 0"><geom name="alone" type="sphere" size="0.03"/></body>
</body></worldbody></mujoco>
"""


def test_a_capsule_inside_a_box_is_widened_by_how_far_the_box_stands_out() -> None:
    model = mujoco.MjModel.from_xml_string(BOX_XML)
    # the box's corners, (0.02, 0.02, 0.02) from the capsule's ends: sqrt(3) 0.02 - 0.02
    assert generic_ik.box_overhang(model, "inside") == pytest.approx(0.02 * (3**0.5 - 1), abs=1e-9)
    # a capsule that leaves the box, and one on a body without a box, are not widened
    assert generic_ik.box_overhang(model, "through") == 0.0
    assert generic_ik.box_overhang(model, "alone") == 0.0
    with pytest.raises(ConfigError, match="no geom named"):
        generic_ik.box_overhang(model, "nothing")
    # the G1's soles: three capsules inside each box, whose short ends stand 9.1 mm out of them
    g1 = UNITREE_G1.load_model()
    for side in ("left", "right"):
        for part in ("inner", "mid", "outer"):
            got = generic_ik.box_overhang(g1, f"{side}_foot_{part}_geom")
            assert got == pytest.approx(0.00907, abs=1e-5)
    assert generic_ik.box_overhang(g1, "left_shin_geom") == 0.0
    # and the G1's IK (its collision term and separation) takes them so widened
    radii = np.asarray(UNITREE_G1.track.__self__.build().problems.data.radii)  # type: ignore[union-attr]
    assert np.isclose(radii, 0.01 + 0.00907, atol=1e-5).any()
    assert not np.isclose(radii, 0.01, atol=1e-6).any()  # the soles' own radius: none left
