"""Rollouts of retargeted motions (jaxproj.eval.rollout): MJX against CPU MuJoCo (the protocol
written out here, and the ``backend="mujoco"`` rollout) and known answers; the Warp backend
against CPU MuJoCo where a CUDA GPU and warp-lang are present (CPU CI skips those tests, at no
cost: nothing is compiled before the skip).

MJX compiles are slow on CPU (~15 s for one rollout program on 2 cores), so every ``simulate``
test reads one module-scoped batch of six 10-frame motions, compiled once; ``hand_error_cm`` is
compiled once for N = 8.
"""

from __future__ import annotations

import json

import jax
import mujoco
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.eval import rollout, rollout_model, rollout_warp
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import robot

T = 10  # frames per motion (15 frames/s: 0.67 s)
SUBSTEPS = 33  # round((1/15) / 0.002)
STAND = robot.STANDING_POSTURE
IDX = robot.IDX
ARM_TORSO = rollout.CONTACT_GROUPS.index("arm_torso")

# rows of the batch
STANDING, STEP, COLLIDE, JUMP, PAD_NAN, PAD_WILD = range(6)
PAD_LEN = 5
STEP_FRAME = 1  # LShoulderPitch 1.4 -> 0.4 (hanging -> raised) from this frame on
JUMP_FRAME = 3  # RShoulderPitch 1.4 -> 0.4 from this frame on
OUT_OF_RANGE_FRAME = 6  # JUMP: LShoulderRoll target -0.6 (< -0.3142) from this frame on


def _pose(base: np.ndarray = STAND, **angles: float) -> np.ndarray:
    q = np.array(base, dtype=np.float32)
    for name, value in angles.items():
        q[IDX[name]] = value
    return q


def _motions() -> tuple[np.ndarray, np.ndarray]:
    hold = np.tile(STAND, (T, 1))
    step = hold.copy()
    step[STEP_FRAME:] = _pose(LShoulderPitch=0.4)
    # tests/robots/test_robot_model.py: left arm hanging, rolled inward, elbow fully flexed with
    # ElbowYaw = 0 swings the forearm through the torso
    collide = hold.copy()
    collide[2:] = _pose(LShoulderRoll=-0.3142, LElbowYaw=0.0, LElbowRoll=-1.5446)
    jump = hold.copy()
    jump[JUMP_FRAME:] = _pose(RShoulderPitch=0.4)
    jump[OUT_OF_RANGE_FRAME:, IDX["LShoulderRoll"]] = -0.6
    pad_nan = jump.copy()
    pad_nan[PAD_LEN:] = np.nan
    pad_wild = jump.copy()
    pad_wild[PAD_LEN:] = np.random.default_rng(0).uniform(-100.0, 100.0, (T - PAD_LEN, 26))
    targets = np.stack([hold, step, collide, jump, pad_nan, pad_wild]).astype(np.float32)
    lengths = np.array([T, T, T, T, PAD_LEN, PAD_LEN], dtype=np.int32)
    return targets, lengths


@pytest.fixture(scope="module")
def batch() -> tuple[np.ndarray, np.ndarray, rollout.RolloutResult]:
    targets, lengths = _motions()
    with jax.numpy_dtype_promotion("strict"), jax.numpy_rank_promotion("raise"):
        result = rollout.simulate(targets, lengths, backend="mjx")
    result = rollout.RolloutResult(*(np.asarray(x) for x in result))
    return targets, lengths, result


@pytest.fixture(scope="module")
def fixed() -> mujoco.MjModel:
    return robot.load_model("fixed")


def _cpu_rollout(model: mujoco.MjModel, targets: np.ndarray) -> dict[str, np.ndarray]:
    """The rollout protocol of jaxproj.eval.rollout written out with CPU MuJoCo (float64)."""
    qi, di = robot.joint_qpos_index(model), robot.joint_dof_index(model)
    act = robot.actuator_index(model)
    src = np.empty(model.nu, dtype=np.int64)  # joint driven by each actuator
    for i, a in enumerate(act):
        if robot.JOINT_NAMES[i] != "RHipYawPitch":
            src[a] = i
    lo, hi = model.actuator_ctrlrange.T
    groups = {("l", "torso"): ARM_TORSO, ("r", "torso"): ARM_TORSO}
    data = mujoco.MjData(model)
    data.qpos[:] = robot.config_to_qpos(model, np.clip(targets[0], robot.LOWER, robot.UPPER))
    qpos, contact, peak = [], [], np.zeros(26)
    prev = np.clip(targets[0][src], lo, hi)
    for target in targets:
        ctrl = np.clip(target[src], lo, hi)
        hit = np.zeros(3, dtype=bool)
        for k in range(1, SUBSTEPS + 1):  # the command ramps to the frame's target
            data.ctrl[:] = (
                ctrl if k == SUBSTEPS else prev + (ctrl - prev) * np.float32(k / SUBSTEPS)
            )
            mujoco.mj_step(model, data)
            peak = np.maximum(peak, np.abs(data.qvel[di]))
            for c in data.contact[: data.ncon]:
                names = sorted(model.geom(g).name.split("_")[0] for g in (c.geom1, c.geom2))
                if tuple(names) in groups:
                    hit[groups[tuple(names)]] = True
        prev = ctrl
        qpos.append(data.qpos[qi].copy())
        contact.append(hit)
    return {"qpos": np.array(qpos), "contact": np.array(contact), "max_speed": peak}


# --- physics ------------------------------------------------------------------------------------


def test_result_shapes(batch) -> None:
    targets, lengths, r = batch
    b = len(lengths)
    assert r.qpos.shape == r.qvel.shape == (b, T, 26) and r.qpos.dtype == np.float32
    assert r.contact.shape == (b, T, 3) and r.contact.dtype == bool
    assert r.penetration.shape == (b, T)
    assert r.max_speed.shape == r.tracking_rms.shape == (b, 26)
    assert r.contact_frames.shape == (b, 3)
    valid = np.arange(T)[None, :] < lengths[:, None]
    assert np.all(np.isfinite(r.qpos[valid])) and np.all(np.isfinite(r.max_speed))


@pytest.mark.parametrize("row", [STANDING, STEP])
def test_mjx_matches_cpu_mujoco(batch, fixed: mujoco.MjModel, row: int) -> None:
    # No contact in these motions (JUMP's first frames: test_padding_is_ignored); STEP saturates
    # the shoulder servo (20 N m/rad * 1 rad >> the 1.329 N m effort), the case where plain
    # mjx.step drifts ~0.02 rad from CPU MuJoCo.
    # Float32 MJX vs float64 CPU over 330 steps: agreement within 1e-4 rad, 1e-2 rad/s.
    targets, _, r = batch
    cpu = _cpu_rollout(fixed, targets[row])
    np.testing.assert_allclose(r.qpos[row], cpu["qpos"], atol=1e-4)
    np.testing.assert_allclose(r.max_speed[row], cpu["max_speed"], atol=1e-2)
    assert not r.contact[row].any() and not cpu["contact"].any()


def test_standing_posture_is_held(batch) -> None:
    targets, _, r = batch
    assert np.abs(r.qpos[STANDING] - STAND).max() < 0.05
    assert r.max_speed[STANDING].max() < 0.5  # rad/s: only the initial gravity sag


def test_step_is_followed(batch) -> None:
    targets, _, r = batch
    j = IDX["LShoulderPitch"]
    err = np.abs(r.qpos[STEP, :, j] - 0.4)
    assert err[STEP_FRAME] > 0.3  # a physical lag: one frame (67 ms) is not enough for 1 rad
    settled = STEP_FRAME + 8  # frame end >= 0.5 s after the step
    assert np.all(err[settled:] < 0.1), err
    others = [k for k in range(26) if k != j]
    assert np.abs(r.qpos[STEP][:, others] - STAND[others]).max() < 0.05


def test_self_collision_detected(batch, fixed: mujoco.MjModel) -> None:
    targets, _, r = batch
    assert r.contact_frames[COLLIDE, ARM_TORSO] > 0
    assert r.contact_frames[COLLIDE].tolist()[1:] == [0, 0]  # no arm-head / arm-arm
    assert not r.contact[COLLIDE, :2].any()  # the forearm needs > 2 frames to swing in
    assert r.penetration[COLLIDE].max() > 0.0
    assert r.contact_frames[STANDING].tolist() == [0, 0, 0]
    assert r.penetration[STANDING].max() == 0.0
    # CPU MuJoCo finds arm-torso contact in about as many frames (MJX's capsule-box collider
    # returns one contact point where CPU MuJoCo returns two, so the motions differ slightly)
    cpu = _cpu_rollout(fixed, targets[COLLIDE])
    assert abs(int(cpu["contact"][:, ARM_TORSO].sum()) - r.contact_frames[COLLIDE, ARM_TORSO]) <= 1


def test_frictionless_contacts(batch, cpu_batch: rollout.RolloutResult) -> None:
    # contact_friction=False (condim 1): one constraint row per contact slot instead of four;
    # contact-free motions are bit-identical, the colliding one still reports its contact. Run
    # on the C backend (the config is the model's, both backends read it): an MJX compile of
    # its own costs ~50 s on 2 cores; benchmarks/bench_rollout.py --frictionless runs MJX.
    model = rollout._fixed_model(rollout.RolloutConfig(contact_friction=False), "whole", NAO_H25)
    assert np.all(model.geom_condim == 1)
    assert np.all(rollout._fixed_model(rollout.RolloutConfig(), "whole", NAO_H25).geom_condim == 3)
    targets, lengths, _ = batch
    r = cpu_batch
    rows = [STANDING, STEP, COLLIDE]
    cfg = rollout.RolloutConfig(contact_friction=False)
    f = rollout.simulate(targets[rows], lengths[rows], cfg, backend="mujoco")
    np.testing.assert_array_equal(np.asarray(f.qpos)[:2], r.qpos[[STANDING, STEP]])
    assert np.abs(np.asarray(f.qpos)[2] - r.qpos[COLLIDE]).max() > 0  # friction mattered
    assert np.asarray(f.contact_frames)[2, ARM_TORSO] > 0
    assert np.asarray(f.contact_frames)[:2].sum() == 0


def test_padding_is_ignored(batch, fixed: mujoco.MjModel) -> None:
    targets, lengths, r = batch
    # NaN and +-100 rad padding give identical results on the valid frames and statistics
    for field in ("qpos", "qvel", "contact", "penetration"):
        a, b = getattr(r, field)[PAD_NAN, :PAD_LEN], getattr(r, field)[PAD_WILD, :PAD_LEN]
        np.testing.assert_array_equal(a, b, err_msg=field)
    for field in ("max_speed", "contact_frames", "tracking_rms"):
        np.testing.assert_array_equal(getattr(r, field)[PAD_NAN], getattr(r, field)[PAD_WILD])
    assert np.all(np.isfinite(r.qpos[PAD_NAN])) and not r.contact[PAD_NAN].any()
    # ... and the same as the unpadded 5-frame motion (CPU MuJoCo reference)
    cpu = _cpu_rollout(fixed, targets[JUMP, :PAD_LEN])
    np.testing.assert_allclose(r.qpos[PAD_NAN, :PAD_LEN], cpu["qpos"], atol=1e-4)
    np.testing.assert_allclose(r.max_speed[PAD_NAN], cpu["max_speed"], atol=1e-2)
    rms = np.sqrt(np.mean((cpu["qpos"] - targets[JUMP, :PAD_LEN]) ** 2, axis=0))
    np.testing.assert_allclose(r.tracking_rms[PAD_NAN], rms, atol=1e-4)
    # the full JUMP motion goes on to push the left arm into the torso: not counted when padded
    assert r.contact_frames[JUMP, ARM_TORSO] > 0 and r.contact_frames[PAD_NAN].sum() == 0
    # the summary of a padded motion = summary of the same motion cut to its length
    sub = rollout.RolloutResult(*(x[[PAD_NAN, PAD_WILD]] for x in r))
    s_pad = rollout.summarize(sub, lengths[[PAD_NAN, PAD_WILD]], targets[[PAD_NAN, PAD_WILD]])
    rows = [PAD_NAN, PAD_WILD]
    cut = rollout.RolloutResult(
        *(x[rows, :PAD_LEN] for x in (r.qpos, r.qvel, r.contact, r.penetration)),
        *(x[rows] for x in (r.max_speed, r.contact_frames, r.tracking_rms)),
    )
    s_cut = rollout.summarize(cut, np.array([PAD_LEN, PAD_LEN]), targets[[JUMP, JUMP], :PAD_LEN])
    assert s_pad == s_cut
    assert s_pad["frames"] == 2 * PAD_LEN and s_pad["joint_limit_violations"]["target_frames"] == 0


# --- the CPU MuJoCo backend -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def cpu_batch(batch) -> rollout.RolloutResult:
    targets, lengths, _ = batch
    result = rollout.simulate(targets, lengths, backend="mujoco", threads=2)
    return rollout.RolloutResult(*(np.asarray(x) for x in result))


@pytest.mark.parametrize("row", [STANDING, STEP, COLLIDE])
def test_mujoco_backend_is_the_written_out_protocol(
    batch, cpu_batch: rollout.RolloutResult, fixed: mujoco.MjModel, row: int
) -> None:
    # the same float64 physics as _cpu_rollout: equal up to the float32 results' rounding
    targets, _, _ = batch
    cpu = _cpu_rollout(fixed, targets[row])
    np.testing.assert_allclose(cpu_batch.qpos[row], cpu["qpos"], atol=1e-6)
    np.testing.assert_allclose(cpu_batch.max_speed[row], cpu["max_speed"], atol=1e-5)
    np.testing.assert_array_equal(
        cpu_batch.contact[row, :, ARM_TORSO], cpu["contact"][:, ARM_TORSO]
    )


def test_mujoco_backend_matches_mjx(batch, cpu_batch: rollout.RolloutResult) -> None:
    # every row, padding included: float64 C MuJoCo vs float32 MJX
    targets, lengths, r = batch
    c = cpu_batch
    assert [x.shape for x in c] == [x.shape for x in r]
    assert [x.dtype for x in c] == [x.dtype for x in r]
    valid = np.arange(T)[None, :] < lengths[:, None]
    free = [STANDING, STEP, PAD_NAN, PAD_WILD]  # no self-contact in their valid frames
    assert r.contact_frames[free].sum() == 0 and c.contact_frames[free].sum() == 0
    ok = valid[free]
    np.testing.assert_allclose(c.qpos[free][ok], r.qpos[free][ok], atol=1e-4)
    np.testing.assert_allclose(c.max_speed[free], r.max_speed[free], atol=1e-2)
    np.testing.assert_allclose(c.tracking_rms[free], r.tracking_rms[free], atol=1e-4)
    # in contact the two constraint solvers part (MJX's own Newton solver in float32, both
    # capped at RolloutConfig's 8 iterations): measured up to 0.058 rad on COLLIDE
    touch = [COLLIDE, JUMP]
    assert np.abs(c.qpos[touch] - r.qpos[touch]).max() < 0.1
    # contact at the threshold may flip in one frame (as MJX against _cpu_rollout)
    assert np.abs(c.contact_frames - r.contact_frames).max() <= 1
    assert c.contact_frames[COLLIDE, ARM_TORSO] > 0 and c.contact_frames[STANDING].sum() == 0
    np.testing.assert_allclose(c.penetration, r.penetration, atol=1e-3)
    assert not c.contact[~valid].any() and np.all(c.penetration[~valid] == 0)
    s_c, s_r = (rollout.summarize(x, lengths, targets) for x in (c, r))
    assert (
        s_c["frames"] == s_r["frames"]
        and s_c["speed"]["worst_joint"] == s_r["speed"]["worst_joint"]
    )


def test_backend_choice(monkeypatch) -> None:
    assert rollout.resolve_backend("auto") == "mujoco"  # the tests run on a CPU
    assert rollout.resolve_backend("auto", jax.devices("cpu")) == "mjx"  # devices: MJX shards
    assert rollout.resolve_backend("mjx") == "mjx"
    assert rollout.resolve_backend("warp") == "warp"
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert rollout.resolve_backend("auto") == ("warp" if rollout_warp.warp_usable() else "mjx")
    monkeypatch.setattr(rollout, "warp_usable", lambda devices=None: True)
    assert rollout.resolve_backend("auto") == "warp"  # a CUDA GPU with warp-lang
    assert rollout.resolve_backend("auto", robot="unitree_g1") == "mjx"  # not validated on Warp
    assert rollout.resolve_backend("warp", robot="unitree_g1") == "warp"
    monkeypatch.setattr(rollout, "warp_usable", lambda devices=None: False)
    assert rollout.resolve_backend("auto") == "mjx"
    with pytest.raises(ConfigError, match="unknown rollout backend 'physx'"):
        rollout.resolve_backend("physx")
    q = np.tile(STAND, (1, 2, 1)).astype(np.float32)
    with pytest.raises(ConfigError, match="devices must be None"):
        rollout.simulate(q, backend="mujoco", devices=jax.devices("cpu"))


# --- the Warp backend (MJX's Warp implementation; CUDA GPUs with warp-lang only) -----------------


def _warp_skip_reason() -> str | None:
    """Why the Warp backend cannot run here (None: it can); cheap, nothing compiled."""
    if not rollout_warp._warp_installed():
        return 'warp-lang is not installed (the optional extra: pip install "jaxproj[warp]")'
    try:
        jax.devices("cuda")
    except RuntimeError:
        return "no CUDA GPU: MJX's Warp implementation runs on CUDA GPUs only (CPU CI)"
    return None


@pytest.fixture(scope="module")
def warp_batch() -> rollout.RolloutResult:
    reason = _warp_skip_reason()
    if reason is not None:
        pytest.skip(reason)
    targets, lengths = _motions()
    with jax.numpy_dtype_promotion("strict"), jax.numpy_rank_promotion("raise"):
        result = rollout.simulate(targets, lengths, backend="warp")
    return rollout.RolloutResult(*(np.asarray(x) for x in result))


@pytest.mark.parametrize("row", [STANDING, STEP])
def test_warp_matches_cpu_mujoco(warp_batch, fixed: mujoco.MjModel, row: int) -> None:
    # contact-free, STEP saturating the shoulder servo: MuJoCo Warp leaves the kv of clamped
    # servos out of the implicit damping as C MuJoCo does; the MJX-JAX tolerances hold
    targets, _ = _motions()
    cpu = _cpu_rollout(fixed, targets[row])
    np.testing.assert_allclose(warp_batch.qpos[row], cpu["qpos"], atol=1e-4)
    np.testing.assert_allclose(warp_batch.max_speed[row], cpu["max_speed"], atol=1e-2)
    assert not warp_batch.contact[row].any() and not cpu["contact"].any()


def test_warp_padding_matches_cpu_mujoco(warp_batch, fixed: mujoco.MjModel) -> None:
    targets, lengths = _motions()
    r = warp_batch
    cpu = _cpu_rollout(fixed, targets[JUMP, :PAD_LEN])
    for row in (PAD_NAN, PAD_WILD):
        np.testing.assert_allclose(r.qpos[row, :PAD_LEN], cpu["qpos"], atol=1e-4)
        np.testing.assert_allclose(r.max_speed[row], cpu["max_speed"], atol=1e-2)
        assert r.contact_frames[row].sum() == 0 and np.all(np.isfinite(r.qpos[row]))


def test_warp_contact_matches_cpu_mujoco(warp_batch, fixed: mujoco.MjModel) -> None:
    # in self-contact MuJoCo Warp's float32 Newton solver (its own line search) stays close to
    # C MuJoCo's, both capped at 8 / 4 iterations (MJX-JAX's parts by up to 0.058 rad here):
    # COLLIDE and JUMP within WARP_CONTACT_ATOL; contact in as many frames, give or take one
    targets, _ = _motions()
    r = warp_batch
    for row in (COLLIDE, JUMP):
        cpu = _cpu_rollout(fixed, targets[row])
        assert np.abs(r.qpos[row] - cpu["qpos"]).max() < WARP_CONTACT_ATOL
        cpu_frames = int(cpu["contact"][:, ARM_TORSO].sum())
        assert cpu_frames > 0 and abs(r.contact_frames[row, ARM_TORSO] - cpu_frames) <= 1
    assert r.penetration[COLLIDE].max() > 0.0 and r.contact_frames[COLLIDE].tolist()[1:] == [0, 0]


WARP_CONTACT_ATOL = 1e-3
"""rad: Warp against C MuJoCo in self-contact (measured on an H100: at most 6.4e-5 rad over 206
random motions with contact, ``benchmarks/results/rollout_warp_h100.json``)."""


def test_warp_backend_needs_the_extra(monkeypatch) -> None:
    # CPU CI: without warp-lang the backend names the extra to install, before any work
    q = np.tile(STAND, (1, 2, 1)).astype(np.float32)
    monkeypatch.setattr(rollout_warp, "_warp_installed", lambda: False)
    with pytest.raises(ConfigError, match=r'pip install "jaxproj\[warp\]"'):
        rollout.simulate(q, backend="warp")
    with pytest.raises(ConfigError, match="unknown rollout backend"):
        rollout.simulate(q, backend="warp-jax")


def test_warp_backend_needs_a_cuda_gpu(monkeypatch) -> None:
    from mujoco.mjx import warp as mjx_warp

    def no_cuda(backend: str | None = None) -> list:
        raise RuntimeError("no cuda backend")

    monkeypatch.setattr(rollout_warp, "_warp_installed", lambda: True)
    monkeypatch.setattr(mjx_warp, "WARP_INSTALLED", True)
    monkeypatch.setattr(jax, "devices", no_cuda)
    with pytest.raises(ConfigError, match="needs a CUDA GPU"):
        rollout_warp.check_warp(None)


# --- split_legs: head-and-arms and legs as two models --------------------------------------------


@pytest.fixture(scope="module")
def whole(batch) -> rollout.RolloutResult:
    targets, lengths, _ = batch
    result = rollout.simulate(
        targets, lengths, rollout.RolloutConfig(split_legs=False), backend="mjx"
    )
    return rollout.RolloutResult(*(np.asarray(x) for x in result))


def test_split_matches_whole_model(batch, whole: rollout.RolloutResult) -> None:
    # the default (split_legs=True) against the whole 26-joint model: the parts share no degree
    # of freedom, so only the constraint solver's stopping test and line search (per part
    # instead of joint) and float32 rounding differ: measured 4.5e-7 rad on the contact-free
    # rows on CPU; on COLLIDE, in self-contact for 7 frames, the capped (8-iteration) solver
    # stops at different points of the two problems: 2.9e-4 rad with the ramped targets
    # (RolloutConfig.interpolate; 1.3e-6 with the zero-order hold)
    targets, lengths, r = batch
    assert rollout.RolloutConfig().split_legs
    free = [i for i in range(len(lengths)) if i != COLLIDE]
    _same_rollout(rollout.RolloutResult(*(x[free] for x in r)),
                  rollout.RolloutResult(*(x[free] for x in whole)))  # fmt: skip
    # COLLIDE: the angles and tracking to 1e-3 rad; its speeds in contact part by up to 0.14
    # rad/s (the solvers' different stopping points), so they are not compared
    np.testing.assert_allclose(r.qpos[COLLIDE], whole.qpos[COLLIDE], atol=1e-3)
    np.testing.assert_allclose(r.tracking_rms[COLLIDE], whole.tracking_rms[COLLIDE], atol=1e-3)
    np.testing.assert_array_equal(r.contact_frames, whole.contact_frames)
    assert r.contact_frames[COLLIDE, ARM_TORSO] > 0  # the comparison covers a contact


def _same_rollout(r: rollout.RolloutResult, w: rollout.RolloutResult) -> None:
    """Two rollouts of contact-free motions agree to the solvers' float32 round-off."""
    np.testing.assert_allclose(r.qpos, w.qpos, atol=1e-5)
    np.testing.assert_allclose(r.qvel, w.qvel, atol=1e-2)
    np.testing.assert_array_equal(r.contact, w.contact)
    np.testing.assert_allclose(r.penetration, w.penetration, atol=1e-4)
    np.testing.assert_allclose(r.max_speed, w.max_speed, atol=1e-2)
    np.testing.assert_allclose(r.tracking_rms, w.tracking_rms, atol=1e-4)


def test_split_with_moving_legs(batch, whole: rollout.RolloutResult) -> None:
    # motions whose legs move get a leg rollout of their own: bend the left knee from frame 4 in
    # every motion, so the batch still has one distinct leg motion and runs the programs the
    # module's batch compiled (a second distinct leg motion compiles a leg program of 2, ~60 s
    # on 2 cores; the routing of several leg motions: test_leg_motions_dedup)
    targets, lengths, _ = batch
    moved = targets.copy()
    knee = IDX["LKneePitch"]
    moved[:, 4:, knee] = 1.0
    legs = np.asarray(rollout._setup(rollout.RolloutConfig(), "legs", NAO_H25)[0].joints)
    rows, inverse = rollout._leg_motions(moved, lengths, legs)
    assert rows.shape == (1, T, 12) and set(inverse.tolist()) == {0}
    assert rows[0, -1, list(legs).index(knee)] == 1.0
    r = rollout.simulate(moved, lengths, backend="mjx")
    q = np.asarray(r.qpos)
    assert abs(q[STEP, -1, knee] - 1.0) < 0.05 and abs(q[STANDING, -1, knee] - 1.0) < 0.05
    # the arms and head do not feel the legs (the parts share no degree of freedom): to the bit
    legs_mask = np.isin(np.arange(26), legs)
    np.testing.assert_array_equal(q[..., ~legs_mask], np.asarray(batch[2].qpos)[..., ~legs_mask])
    # and the moving legs against the whole model
    w = rollout.simulate(moved, lengths, rollout.RolloutConfig(split_legs=False), backend="mjx")
    free = [i for i in range(len(lengths)) if i != COLLIDE]  # COLLIDE: see the test above
    np.testing.assert_allclose(q[free], np.asarray(w.qpos)[free], atol=1e-4)
    np.testing.assert_allclose(q[COLLIDE], np.asarray(w.qpos)[COLLIDE], atol=1e-3)
    np.testing.assert_allclose(np.asarray(r.tracking_rms), np.asarray(w.tracking_rms), atol=1e-3)


def test_leg_motions_dedup() -> None:
    # padded frames count as the last valid one; sizes pad to a power of two
    legs = np.arange(8, 20)
    q = np.tile(STAND, (5, 4, 1)).astype(np.float32)
    n = np.array([4, 2, 2, 4, 3], dtype=np.int32)
    q[1, 2:, legs] = 7.0  # padding of a 2-frame motion: same leg motion as motion 0
    q[3, 1:, legs[0]] = 0.5  # a different leg motion
    q[4, 3, legs[1]] = 0.3  # differs only in padding: same as motion 0
    rows, inverse = rollout._leg_motions(q, n, legs)
    assert rows.shape == (2, 4, 12) and rows.dtype == np.float32
    assert inverse.tolist() == [inverse[0]] * 3 + [1 - inverse[0], inverse[0]]
    np.testing.assert_array_equal(rows[inverse[3]], q[3][:, legs])
    q[2, :, legs[2]] = 0.1  # a third distinct motion: padded to 4 rows
    rows, inverse = rollout._leg_motions(q, n, legs)
    assert rows.shape == (4, 4, 12) and len(set(inverse.tolist())) == 3
    for b in range(5):
        frames = np.minimum(np.arange(4), n[b] - 1)
        np.testing.assert_array_equal(rows[inverse[b]], q[b, frames][:, legs])


def test_head_ball_known_answer() -> None:
    # MJCF: the head sphere (r = 0.065) sits 0.055 above the neck joint (0, 0, 0.1265), about
    # which both head joints turn; the arm geoms cannot collide with a leg geom
    center, reach, margin, names = rollout._head_ball(NAO_H25)
    np.testing.assert_allclose(center, [0.0, 0.0, robot.NECK_OFFSET_Z], atol=1e-12)
    assert reach == pytest.approx(0.055 + 0.065) and margin == 0.0 and names == {"head_geom"}
    legs, _ = rollout._setup(rollout.RolloutConfig(), "legs", NAO_H25)
    assert legs.guard_geom.shape == (6,)  # thighs, tibias, feet: their filter bits meet the head's
    upper, _ = rollout._setup(rollout.RolloutConfig(), "upper", NAO_H25)
    assert upper.guard_geom.shape == (0,)


def test_split_guard_falls_back(batch, whole: rollout.RolloutResult, monkeypatch) -> None:
    # a head ball reaching the legs fails the certificate: the whole model runs instead
    targets, lengths, _ = batch
    center, _, margin, names = rollout._head_ball(NAO_H25)
    rollout._setup.cache_clear()
    monkeypatch.setattr(rollout_model, "_head_ball", lambda robot: (center, 0.3, margin, names))
    try:
        r = rollout.simulate(targets, lengths, backend="mjx")
    finally:
        monkeypatch.undo()
        rollout._setup.cache_clear()
    for field in ("qpos", "qvel", "contact_frames", "max_speed"):
        np.testing.assert_array_equal(np.asarray(getattr(r, field)), getattr(whole, field))


# --- summary ------------------------------------------------------------------------------------


def test_summary_of_batch(batch) -> None:
    targets, lengths, r = batch
    s = rollout.summarize(r, lengths, targets)
    json.dumps(s)  # plain numbers only
    assert s["motions"] == 6 and s["frames"] == 4 * T + 2 * PAD_LEN
    # JUMP asks for LShoulderRoll = -0.6 (limit -0.3142) in frames 6..9; the servo target is
    # clipped to the range, so the simulated arm stays inside it
    assert s["joint_limit_violations"]["target_frames"] == T - OUT_OF_RANGE_FRAME
    assert s["joint_limit_violations"]["achieved_frames"] == 0
    coll = s["self_collision_frames"]
    assert coll["arm_torso"] == int(r.contact_frames[:, ARM_TORSO].sum()) > 0
    assert coll["any"] == coll["arm_torso"] and coll["motions"] == 2  # COLLIDE and JUMP
    # a 1 rad jump in one frame drives RShoulderPitch to more than half its no-load speed
    j = IDX["RShoulderPitch"]
    assert r.max_speed[JUMP, j] / robot.VELOCITY_LIMITS[j] > 0.5
    assert r.max_speed[STANDING, j] / robot.VELOCITY_LIMITS[j] < 0.05
    assert 0.5 < s["speed"]["max_ratio"] < 1.0 and s["speed"]["joints_over_limit"] == 0
    err = s["tracking_error_deg"]
    assert 0.0 < err["mean"] < err["p95"] <= err["max"]
    assert set(err["per_joint_p95"]) == set(robot.DRIVEN_JOINTS)


def test_summary_known_answers() -> None:
    # a hand-made result: every number below is counted by hand
    b, t = 2, 4
    q = np.tile(STAND, (b, t, 1)).astype(np.float32)
    targets = q.copy()
    q[0, 1, IDX["HeadYaw"]] += np.radians(10.0)  # 10 deg tracking error, one joint, one frame
    q[0, 2, IDX["LElbowRoll"]] = robot.UPPER[IDX["LElbowRoll"]] + 0.01  # outside by 0.01 rad
    q[0, 3, IDX["LElbowRoll"]] = robot.UPPER[IDX["LElbowRoll"]] + 5e-4  # within tolerance
    q[1, 3] = 99.0  # padding of motion 1 (length 3): must not count anywhere
    targets[1, 0, IDX["HeadPitch"]] = robot.LOWER[IDX["HeadPitch"]] - 0.1  # target out of range
    targets[1, 3] = np.nan
    contact = np.zeros((b, t, 3), dtype=bool)
    contact[0, 1, 0] = contact[0, 1, 2] = True  # one frame, two groups
    contact[1, 0, 1] = True
    contact[1, 3, :] = True  # padding
    speed = np.zeros((b, 26), dtype=np.float32)
    speed[0, IDX["LWristYaw"]] = 1.5 * robot.VELOCITY_LIMITS[IDX["LWristYaw"]]
    speed[0, IDX["HeadYaw"]] = 1.2 * robot.VELOCITY_LIMITS[IDX["HeadYaw"]]
    speed[1, IDX["RElbowRoll"]] = 0.5 * robot.VELOCITY_LIMITS[IDX["RElbowRoll"]]
    result = rollout.RolloutResult(
        qpos=q, qvel=np.zeros_like(q), contact=contact, penetration=np.zeros((b, t), np.float32),
        max_speed=speed, contact_frames=contact.sum(axis=1), tracking_rms=np.zeros((b, 26)),
    )  # fmt: skip
    lengths = np.array([4, 3])
    s = rollout.summarize(result, lengths, targets)
    json.dumps(s)
    assert s["frames"] == 7
    err = s["tracking_error_deg"]
    elbow = np.degrees(0.01 + robot.UPPER[IDX["LElbowRoll"]] - STAND[IDX["LElbowRoll"]])  # 27 deg
    head = np.degrees(STAND[IDX["HeadPitch"]] - robot.LOWER[IDX["HeadPitch"]] + 0.1)  # 44 deg
    assert err["max"] == pytest.approx(max(10.0, elbow, head), abs=1e-3)
    # 4 nonzero errors among 7 frames x 10 driven joints (the padded frame has 99 rad, unused)
    assert err["mean"] == pytest.approx(
        (10.0 + elbow + np.degrees(5e-4 + robot.UPPER[IDX["LElbowRoll"]] - STAND[IDX["LElbowRoll"]])
         + head) / 70.0, abs=1e-3)  # fmt: skip
    assert s["self_collision_frames"] == {
        "arm_torso": 1, "arm_head": 1, "arm_arm": 1, "any": 2, "motions": 2,
        "max_penetration_mm": 0.0,
    }  # fmt: skip
    lim = s["joint_limit_violations"]
    assert lim["achieved_frames"] == 1 and lim["target_frames"] == 1
    assert lim["achieved_max_excess_deg"] == pytest.approx(np.degrees(0.01), abs=1e-3)
    sp = s["speed"]
    assert sp["max_ratio"] == pytest.approx(1.5, rel=1e-6) and sp["worst_joint"] == "LWristYaw"
    assert sp["joints_over_limit"] == 2 and sp["motions_over_limit"] == 1


# --- kinematics ---------------------------------------------------------------------------------


def test_hand_error_cm(fixed: mujoco.MjModel) -> None:
    rng = np.random.default_rng(1)
    a = rng.uniform(robot.LOWER, robot.UPPER, (8, 26)).astype(np.float32)
    b = rng.uniform(robot.LOWER, robot.UPPER, (8, 26)).astype(np.float32)
    b[0] = a[0]
    b[1] = a[1]
    b[1, IDX["LShoulderPitch"]] += 0.3  # left arm only
    err = np.asarray(rollout.hand_error_cm(a, b))
    assert err.shape == (8, 2) and err.dtype == np.float32
    sites = list(NAO_H25.require_mjcf().hand_sites)
    pa = robot.site_positions(fixed, a.astype(np.float64), sites)
    pb = robot.site_positions(fixed, b.astype(np.float64), sites)
    ref = 100.0 * np.linalg.norm(pa - pb, axis=-1)
    np.testing.assert_allclose(err, ref, atol=1e-3)
    assert err[0].tolist() == [0.0, 0.0]
    assert err[1, 0] > 1.0 and err[1, 1] == 0.0
    same = np.asarray(rollout.hand_error_cm(b, b))  # same N: no recompile
    assert np.all(same == 0.0)


# --- validation ---------------------------------------------------------------------------------


def test_bad_inputs() -> None:
    q = np.tile(STAND, (1, 3, 1))
    with pytest.raises(ConfigError):
        rollout.simulate(q[0])  # (T, 26): no batch axis
    with pytest.raises(ConfigError):
        rollout.simulate(q, np.array([4]))  # longer than T
    with pytest.raises(ConfigError):
        rollout.simulate(q, np.array([0]))
    with pytest.raises(ConfigError):
        rollout.simulate(q, np.array([2.0]))  # not integers
    bad = q.copy()
    bad[0, 1, 0] = np.nan
    with pytest.raises(ConfigError, match="frame 1"):
        rollout.simulate(bad)  # NaN inside the valid frames
    with pytest.raises(ConfigError):
        rollout.simulate(q, config=rollout.RolloutConfig(frame_dt=0.0))
    with pytest.raises(ConfigError, match="contact_friction"):
        rollout.simulate(q, config=rollout.RolloutConfig(contact_friction=1))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="split_legs"):
        rollout.RolloutConfig(split_legs="yes")  # type: ignore[arg-type]
    with pytest.raises(ConfigError):
        rollout.hand_error_cm(np.zeros((2, 26)), np.zeros((3, 26)))
