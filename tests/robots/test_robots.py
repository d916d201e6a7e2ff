"""The robot spec (jaxproj.robots): validation, the registry, derived helpers, the NAO instance
against its module constants, and the robot seam proved with a toy robot (tests/toy_robot.py):
its IK, motion files and metrics run with no NAO number in sight."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import numpy as np
import pytest
from toy_robot import CHAINS, DRIVEN, JOINTS, LOWER, STANDING, UPPER, arm_fk, make_toy_robot

from jaxproj import robots
from jaxproj.errors import ConfigError, InputError
from jaxproj.eval import metrics
from jaxproj.io.motion_files import Motion, load_motion, save_motion
from jaxproj.robots import NAO_H25, Chain, Robot
from jaxproj.robots.nao_h25 import ik, naoqi, robot


@pytest.fixture(scope="module")
def toy(tmp_path_factory: pytest.TempPathFactory):
    """The toy robot with its MJCF, registered for the module."""
    r = robots.register(make_toy_robot(tmp_path_factory.mktemp("toy")))
    yield r
    robots.unregister(r.name)


def _bits(a: object) -> bytes:
    return np.asarray(a).tobytes()


# --- the NAO instance ---------------------------------------------------------------------------


def test_nao_is_built_from_its_module_constants() -> None:
    r = robots.get()
    assert r is NAO_H25 and r is robots.get("nao_h25") and robots.DEFAULT == "nao_h25"
    assert r.joint_names == robot.JOINT_NAMES and r.n_joints == robot.N_JOINTS
    assert r.driven_joints == robot.DRIVEN_JOINTS and r.n_driven == len(robot.DRIVEN_JOINTS)
    for mine, theirs in ((r.lower, robot.LOWER), (r.upper, robot.UPPER),
                         (r.standing, robot.STANDING_POSTURE),
                         (r.velocity_limits, robot.VELOCITY_LIMITS),
                         (r.rated_speeds, robot.RATED_SPEEDS),
                         (r.driven_index, robot.DRIVEN_INDEX)):  # fmt: skip
        assert mine.dtype == theirs.dtype and _bits(mine) == _bits(theirs)
        assert not mine.flags.writeable
    assert r.chains == ik.CHAINS and r.ik is ik.solve_driven
    assert r.coupled_joints == (robot.COUPLED_JOINTS,)
    assert r.exports == {".json": naoqi.EXPORT} and r.title == robot.NAME
    assert r.require_mjcf().path == robot.mjcf_path()
    assert all(r.index(n) == robot.IDX[n] for n in robot.JOINT_NAMES)


def test_nao_helpers_match_the_ik_module() -> None:
    rng = np.random.default_rng(1)
    q = rng.normal(size=(7, robot.N_JOINTS)).astype(np.float32)
    drv = q[:, robot.DRIVEN_INDEX]
    assert _bits(NAO_H25.driven_to_full(drv)) == _bits(ik.driven_to_full(drv))
    assert _bits(jax.jit(NAO_H25.driven_to_full)(drv)) == _bits(ik.driven_to_full(drv))
    # the box limits, then HeadPitch into the head envelope at the clipped HeadYaw (NumPy)
    boxed = np.clip(q, robot.LOWER, robot.UPPER)
    yaw, pitch = robot.IDX["HeadYaw"], robot.IDX["HeadPitch"]
    env = [np.interp(boxed[:, yaw], robot.HEAD_ENVELOPE_YAW, b)
           for b in (robot.HEAD_ENVELOPE_PITCH_MIN, robot.HEAD_ENVELOPE_PITCH_MAX)]  # fmt: skip
    boxed[:, pitch] = np.clip(boxed[:, pitch], *env)
    tol = 8 * 2.0**-24  # float32 interpolation (a few roundings) of angles below 1 rad
    np.testing.assert_allclose(NAO_H25.clip(q), boxed, rtol=0, atol=tol)
    np.testing.assert_allclose(NAO_H25.clip_driven(drv), boxed[:, robot.DRIVEN_INDEX], rtol=0,
                               atol=tol)  # fmt: skip
    # each chain's IK is ik.solve_chain on its own columns
    x = rng.normal(size=(5, 15)).astype(np.float32)
    for chain in NAO_H25.chains:
        cols = list(ik.chain_columns(chain))
        assert _bits(chain.solve(x[:, cols])) == _bits(ik.solve_chain(x[:, cols], chain))
    coupled = NAO_H25.couple(q)
    lead, follow = (robot.IDX[n] for n in robot.COUPLED_JOINTS)
    np.testing.assert_array_equal(coupled[:, follow], q[:, lead])


def test_nao_rated_speeds_are_aldebarans_nominal_speeds() -> None:
    """Aldebaran's nominal speeds (deg/s of the motor page) where published; 0.75 x no-load for
    WristYaw and Hand; the left and right sides alike; ``speed_limits`` picks either kind."""
    rated = NAO_H25.speed_limits("rated")
    assert rated is NAO_H25.rated_speeds
    assert NAO_H25.speed_limits("no-load") is NAO_H25.velocity_limits
    published = {"HeadYaw": 351.77, "LShoulderPitch": 351.77, "RElbowYaw": 351.77,
                 "HeadPitch": 305.16, "RShoulderRoll": 305.16, "LElbowRoll": 305.16,
                 "LHipRoll": 188.67, "RKneePitch": 290.25}  # fmt: skip
    for name, deg_s in published.items():
        assert rated[robot.IDX[name]] == pytest.approx(np.radians(deg_s), rel=1e-6)
    for name in ("LWristYaw", "RHand"):
        i = robot.IDX[name]
        assert rated[i] == pytest.approx(0.75 * robot.VELOCITY_LIMITS[i], rel=1e-6)
    ratio = rated / robot.VELOCITY_LIMITS
    assert ((ratio > 0.73) & (ratio < 0.80)).all()
    left = [i for i, n in enumerate(robot.JOINT_NAMES) if n[0] == "L"]
    right = [robot.IDX["R" + robot.JOINT_NAMES[i][1:]] for i in left]
    np.testing.assert_array_equal(rated[left], rated[right])
    # a robot with no rated speeds gets 0.75 x no-load; an unknown kind is refused
    toy = make_toy_robot()
    np.testing.assert_allclose(toy.speed_limits(), 0.75 * toy.velocity_limits, rtol=1e-7)
    with pytest.raises(ConfigError, match="speeds must be one of"):
        NAO_H25.speed_limits("peak")


# --- validation ---------------------------------------------------------------------------------


def _fields() -> dict:
    r = make_toy_robot()
    return {f.name: getattr(r, f.name) for f in dataclasses.fields(r)}


@pytest.mark.parametrize(
    "change, message",
    [
        ({"name": "not a name"}, "identifier"),
        ({"joint_names": JOINTS[:-1] + ("waist",)}, "twice"),
        ({"lower": LOWER[:-1]}, r"lower must have shape \(9,\)"),
        ({"upper": np.where(np.arange(9) == 3, -3.0, UPPER)}, "lower > upper"),
        ({"standing": np.where(np.arange(9) == 5, 3.0, STANDING)}, "outside the limits"),
        ({"standing": np.full(9, np.nan)}, "finite"),
        ({"driven_joints": DRIVEN + ("tail",)}, "not in joint_names"),
        ({"chains": CHAINS[:2]}, "exactly once"),
        ({"chains": ()}, "non-empty"),
        ({"chains": (CHAINS[0], CHAINS[0], *CHAINS[1:])}, "repeat"),
        ({"chains": (Chain("head", ("tail",), DRIVEN[:2]), *CHAINS[1:])}, "unknown or no bones"),
        ({"chains": (Chain("head", ("neck",), DRIVEN[1::-1]), *CHAINS[1:])}, "order"),
        ({"velocity_limits": np.zeros(9)}, "velocity_limits must be > 0"),
        ({"rated_speeds": np.full(9, 6.0)}, "must not exceed"),
        ({"rated_speeds": np.full(9, 2.0), "velocity_limits": None}, "need velocity_limits"),
        ({"coupled_joints": (("waist", "tail"),)}, "coupled_joints"),
        ({"loose_joints": ("waist",)}, "loose_joints"),
        ({"exports": {".csv": naoqi.EXPORT}}, "exports"),
        ({"mjcf": "toy.xml"}, "mjcf must be an Mjcf"),
        ({"track": lambda q, v, d, b: q}, "both track and track_step or neither"),
        ({"track_step": lambda y, p, q, a, b, c: q}, "both track and track_step or neither"),
    ],
)
def test_validation_names_what_to_change(change: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        Robot(**{**_fields(), **change})


def test_registry() -> None:
    toy = make_toy_robot(name="toy_registry")
    assert "toy_registry" not in robots.names()
    assert robots.register(toy) is toy and robots.get("toy_registry") is toy
    assert robots.register(toy) is toy  # the same robot again is fine
    with pytest.raises(ConfigError, match="already registered"):
        robots.register(make_toy_robot(name="toy_registry"))
    other = robots.register(make_toy_robot(name="toy_registry"), replace=True)
    assert robots.get("toy_registry") is other
    assert robots.get(other) is other
    robots.unregister("toy_registry")
    assert robots.names() == ("nao_h25", "unitree_g1", "unitree_h1")
    with pytest.raises(ConfigError, match="unknown robot 'toy_registry'"):
        robots.get("toy_registry")
    with pytest.raises(ConfigError, match="cannot be unregistered"):
        robots.unregister("nao_h25")
    with pytest.raises(ConfigError, match="needs a jaxproj.robots.Robot"):
        robots.register("nao_h25")  # type: ignore[arg-type]


# --- the toy robot ------------------------------------------------------------------------------


def test_toy_helpers(toy: Robot) -> None:
    assert robots.get("toy") is toy and toy.n_joints == 9 and toy.n_driven == 8
    assert toy.index("l_elbow") == 5 and toy.driven_index.tolist() == list(range(1, 9))
    with pytest.raises(ConfigError, match="no joint 'LElbowYaw'"):
        toy.index("LElbowYaw")
    drv = np.arange(16, dtype=np.float32).reshape(2, 8) / 10
    full = np.asarray(toy.driven_to_full(drv))
    assert full.shape == (2, 9) and full.dtype == np.float32
    np.testing.assert_array_equal(full[:, 0], STANDING[0])  # the waist stands
    np.testing.assert_array_equal(full[:, 1:], drv)
    wild = np.full((3, 9), 10.0, np.float32)
    np.testing.assert_array_equal(toy.clip(wild), np.broadcast_to(UPPER, (3, 9)))
    np.testing.assert_array_equal(toy.clip(-wild), np.broadcast_to(LOWER, (3, 9)))
    cols = toy.from_columns(["r_elbow", "waist"], np.array([[1.5, 0.25]], np.float32))
    expect = STANDING.copy()
    expect[[8, 0]] = (1.5, 0.25)
    np.testing.assert_array_equal(cols, expect[None])
    with pytest.raises(ConfigError, match="joint names repeated"):
        toy.from_columns(["waist", "waist"], np.zeros((1, 2), np.float32))
    assert toy.chain("left_elbow").joints == DRIVEN[4:5]
    with pytest.raises(ConfigError, match="no chain"):
        toy.chain("tail")
    with pytest.raises(ConfigError, match="no MJCF"):
        make_toy_robot().load_model("fixed")


def test_toy_ik_inverts_its_fk(toy: Robot) -> None:
    # random arm angles -> FK bone directions -> the chain IK gives the angles back
    rng = np.random.default_rng(3)
    q = np.tile(STANDING, (64, 1))
    q[:, 3:] = rng.uniform(LOWER[3:] + 0.05, UPPER[3:] - 0.05, size=(64, 6))
    q[:, [5, 8]] = rng.uniform(0.2, 1.9, size=(64, 2))  # elbow away from straight
    pts = arm_fk(q)
    for chain in toy.chains[1:]:  # each shoulder reads its upper arm, each elbow both bones
        i = 0 if chain.name.startswith("left") else 1
        u = (pts[:, i, 1] - pts[:, i, 0]) / 0.1
        f = (pts[:, i, 2] - pts[:, i, 1]) / 0.1
        x = np.concatenate([u, f][: len(chain.bones)], axis=1).astype(np.float32)
        k = [toy.index(j) for j in chain.joints]
        np.testing.assert_allclose(chain.solve(x), q[:, k], atol=2e-5)
    # the whole-robot IK is the chains side by side
    d = np.concatenate([np.tile([0.0, 0.0, 1.0], (64, 1)),
                        (pts[:, 0, 1] - pts[:, 0, 0]) / 0.1, (pts[:, 0, 2] - pts[:, 0, 1]) / 0.1,
                        (pts[:, 1, 1] - pts[:, 1, 0]) / 0.1, (pts[:, 1, 2] - pts[:, 1, 1]) / 0.1],
                       axis=1).astype(np.float32)  # fmt: skip
    assert toy.ik is not None
    np.testing.assert_allclose(np.asarray(toy.ik(d))[:, 2:], q[:, 3:], atol=2e-5)
    np.testing.assert_allclose(np.asarray(toy.ik(d))[:, :2], 0.0, atol=1e-7)


def test_toy_motion_files(toy: Robot, tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    angles = rng.uniform(LOWER, UPPER, size=(6, 9)).astype(np.float32)
    m = Motion(angles, np.arange(6) / 15.0, np.ones(6, bool), meta={"src": "toy"}, robot=toy)
    for name in ("m.npz", "m.csv"):
        back = load_motion(save_motion(tmp_path / name, m), robot=toy)
        assert back.robot is toy and _bits(back.angles) == _bits(m.angles)
    assert (tmp_path / "m.csv").read_text().splitlines()[0] == "time," + ",".join(JOINTS)
    with pytest.raises(ConfigError, match=r"use one of \.npz, \.csv$"):
        save_motion(tmp_path / "m.json", m)  # the toy has no controller document
    with pytest.raises(ConfigError, match=r"\(T, 9\)"):
        Motion(np.zeros((2, 26), np.float32), np.arange(2.0), np.ones(2, bool), robot=toy)
    assert load_motion(tmp_path / "m.csv").robot is toy  # registered: found by its joint names
    with pytest.raises(InputError, match="unknown joint names"):
        load_motion(tmp_path / "m.npz", robot="nao_h25")  # the toy's names are not the NAO's


def test_toy_metrics(toy: Robot) -> None:
    rng = np.random.default_rng(5)
    truth = rng.uniform(LOWER, UPPER, size=(40, 9)).astype(np.float32)
    pred = np.clip(truth + rng.normal(scale=0.05, size=truth.shape), LOWER, UPPER)
    pred = pred.astype(np.float32)
    err = np.degrees(np.abs(pred.astype(np.float64) - truth))[:, 1:]
    np.testing.assert_allclose(metrics.joint_errors_deg(pred, truth, robot=toy), err)
    np.testing.assert_allclose(metrics.m_max_without(pred, truth, robot=toy),
                               err[:, [0, 1, 2, 3, 5, 6]].max(axis=1))  # fmt: skip
    per_joint = metrics.joint_percentiles(pred, truth, robot=toy)
    assert list(per_joint) == list(DRIVEN)
    # FK of the arm sites against the toy's own NumPy FK (an independent reference)
    pts = metrics.arm_points(truth, robot=toy)
    assert pts.shape == (40, 2, 3, 3)
    np.testing.assert_allclose(pts, arm_fk(truth), atol=1e-5)
    drv = metrics.arm_points(truth[:, 1:], robot=toy)  # driven angles: the waist stands
    np.testing.assert_allclose(drv, pts, atol=1e-6)
    block = metrics.summarize_errors(pred, truth, robot=toy)
    assert block["M_max"] == metrics.describe(err.max(axis=1))
    hand = block["task_space"]["left"]["hand_cm"]["max"]
    ref = 100 * np.linalg.norm(arm_fk(pred)[:, 0, 2] - arm_fk(truth)[:, 0, 2], axis=-1).max()
    assert hand == pytest.approx(ref, abs=1e-3)
    with pytest.raises(ConfigError, match=r"\(F, 8\) \(driven joints\) or \(F, 9\)"):
        metrics.joint_errors_deg(truth[:, :5], truth[:, :5], robot=toy)


def test_playable_clips_then_separates_then_clips(toy: Robot) -> None:
    """``Robot.playable``: the pipeline's last stage (``pipeline.clip_to_limits``) runs the
    robot's ``separate`` between two clips; without one it is ``clip_driven``."""
    from jaxproj.motion import pipeline

    q = np.stack([toy.standing_driven, toy.upper_driven + 1.0]).astype(np.float32)
    np.testing.assert_array_equal(pipeline.clip_to_limits(q, toy), toy.clip_driven(q))
    seen = []

    def separate(x: jax.Array, start: jax.Array | None = None) -> jax.Array:
        seen.append(np.asarray(x))
        return x - 0.05

    moved = dataclasses.replace(toy, separate=separate)
    out = np.asarray(pipeline.clip_to_limits(q, moved))
    np.testing.assert_array_equal(seen[0], toy.clip_driven(q))  # separate sees clipped angles
    np.testing.assert_array_equal(out, toy.clip_driven(toy.clip_driven(q) - 0.05))


def test_playable_motion_starts_each_frame_from_the_last_answer(toy: Robot) -> None:
    """``Robot.playable_motion``: ``playable`` in time order, each frame's ``separate`` given
    the previous frame's answer as a second start (the first frame: its own angles)."""
    rng = np.random.default_rng(0)
    lo, hi = toy.lower_driven, toy.upper_driven
    q = rng.uniform(lo - 0.5, hi + 0.5, size=(6, toy.n_driven)).astype(np.float32)
    assert np.array_equal(np.asarray(toy.playable_motion(q)), np.asarray(toy.clip_driven(q)))

    def separate(x: jax.Array, start: jax.Array | None = None) -> jax.Array:
        assert start is not None and start.shape == x.shape
        return 0.5 * (x + start)  # depends on the start: the test sees which one it got

    moved = dataclasses.replace(toy, separate=separate)
    out = np.asarray(jax.jit(moved.playable_motion)(q))
    c = np.asarray(toy.clip_driven(q))
    want = [c[0]]
    for t in range(1, len(q)):
        want.append(np.asarray(toy.clip_driven(0.5 * (c[t] + want[-1]))))
    np.testing.assert_allclose(out, np.stack(want), rtol=0, atol=1e-6)


@pytest.mark.parametrize("name", ["unitree_g1", "unitree_h1"])
def test_acceleration_tables_are_the_torques_over_the_inertias(name: str) -> None:
    from jaxproj.robots.mjcf import torque_accelerations

    robot = robots.get(name)
    assert robot.acceleration_limits is not None
    got = torque_accelerations(robot.load_model("fixed"), robot.joint_names, robot.lower,
                               robot.upper)  # fmt: skip
    # the table: the smaller side, rounded down (so never above what the physics gives)
    table = robot.acceleration_limits
    assert (table <= got).all() and (got - table < 2.0).all()
    if name == "unitree_g1":  # a joint's bound falls with what it carries: waist << elbow (the
        # H1's uniform 0.1 kg m^2 armature dominates its light links: there the two are alike)
        assert got[robot.index("waist_pitch_joint")] < got[robot.index("left_elbow_joint")] / 10
