"""Whole-body motion (``jaxproj.motion.whole_body``) and its files.

Cheap by construction: the G1 holds its standing angles under a bundled clip's person (CMU 131_03,
every 6th frame: a walk of about 2.5 m with kicks), so nothing is retargeted or compiled; the
root, the contacts and the stance IK run on the host (MuJoCo's kinematics).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import J
from jaxproj.io.motion_files import Motion, load_motion, save_motion
from jaxproj.io.readers import read_skeleton
from jaxproj.motion import feet as feet_mod
from jaxproj.motion import whole_body as wb
from jaxproj.robots.base import joint_qpos_index
from tests.fuzzing import assert_one_line_error, run_cli

G1 = robots.get("unitree_g1")
CLIP = Path(__file__).resolve().parents[1] / "data" / "cmu_bvh" / "131_03_every6.bvh"


@pytest.fixture(scope="module")
def walk():
    rec = read_skeleton(CLIP)
    angles = np.tile(G1.standing, (len(rec.times), 1)).astype(np.float32)
    root = wb.root_trajectory(rec.positions, rec.valid, rec.times, angles, G1)
    return rec, angles, root


def _replay(root: wb.RootMotion):
    """Per frame: the lowest point of every robot geom, each foot's lowest point and up axis."""
    model = G1.load_model("free")
    data = mujoco.MjData(model)
    adr = joint_qpos_index(model, G1.joint_names)
    feet = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b, _ in G1.mjcf.figure.feet]
    lowest, foot_low, foot_up, torso_x = [], [], [], []
    torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso_link")
    for t in range(len(root.root_pos)):
        data.qpos[0:3] = root.root_pos[t]
        data.qpos[3:7] = np.roll(root.root_rot[t], 1)  # (x, y, z, w) -> MuJoCo's (w, x, y, z)
        data.qpos[adr] = root.angles[t]
        mujoco.mj_kinematics(model, data)
        pts, rad = feet_mod._foot_points(model, data, list(range(1, model.nbody)), 0)
        lowest.append(np.min(pts[:, 2] - rad))
        low = []
        for f in feet:
            p, r = feet_mod._foot_points(model, data, [f], 0)
            low.append(np.min(p[:, 2] - r))
        foot_low.append(low)
        foot_up.append([data.xmat[f].reshape(3, 3)[:, 2] for f in feet])
        torso_x.append(data.xmat[torso].reshape(3, 3)[:, 0])
    return np.array(lowest), np.array(foot_low), np.array(foot_up), np.array(torso_x)


def test_the_root_walks_with_the_person_over_the_floor(walk) -> None:
    """No robot geom below the floor; the feet in contact on it (but where the standing legs
    cannot reach: a straight leg under the person's leaning trunk) and level inside each
    contact (away from the fades); the root starts at the origin facing +x and, with no foot in
    contact, steps as the person's scaled pelvis; unit quaternions with w >= 0; the same
    answer twice."""
    rec, angles, root = walk
    n = len(rec.times)
    assert root.root_pos.shape == (n, 3) and root.root_rot.shape == (n, 4)
    assert root.root_pos.dtype == root.root_rot.dtype == root.angles.dtype == np.float32
    assert np.allclose(np.linalg.norm(root.root_rot, axis=1), 1, atol=1e-5)
    assert (root.root_rot[:, 3] >= 0).all()
    lowest, foot_low, foot_up, torso_x = _replay(root)
    assert lowest.min() > -1e-4  # m
    inside = np.zeros_like(root.contacts)
    for k in range(2):
        for t0, t1 in feet_mod._runs(root.contacts[:, k]):
            inside[t0 + 1 : t1 - 1, k] = True
    assert inside.sum() > n // 2
    height = np.abs(foot_low[inside])  # m; standing angles under a walking trunk: the legs
    assert np.median(height) < 0.005 and (height < 0.02).mean() > 0.9  # cannot always reach
    tilt = np.degrees(np.arccos(np.clip(foot_up[inside][:, 2], -1, 1)))
    assert np.median(tilt) < 1.0
    assert np.linalg.norm(root.root_pos[0, :2]) < 0.05
    heading = torso_x[0, :2] / np.linalg.norm(torso_x[0, :2])
    assert heading[0] > np.cos(np.radians(30))
    # without a foot in contact the root steps as the person's scaled pelvis (here the
    # standing robot cannot walk: its feet stay, and it moves on only between contacts)
    hip = root.world.to_world(rec.positions[:, J["HipCenter"]])
    flight = ~root.contacts.any(axis=1)
    both = flight[1:] & flight[:-1]
    assert both.sum() >= 5
    steps = np.diff(root.root_pos[:, :2].astype(np.float64), axis=0)[both]
    assert np.abs(steps - np.diff(hip[:, :2], axis=0)[both]).max() < 1e-5
    # and no step of the root exceeds the pelvis's by more than the slack (issue 59's 2 cm)
    root_step = np.linalg.norm(np.diff(root.root_pos.astype(np.float64), axis=0), axis=1)
    hip_step = np.linalg.norm(np.diff(hip, axis=0), axis=1)
    assert (root_step - hip_step).max() <= feet_mod.ROOT_SLACK + wb.LIFT_SLACK + 1e-6
    again = wb.root_trajectory(rec.positions, rec.valid, rec.times, angles, G1)
    for a, b in zip(root[:3], again[:3], strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(root.angles, again.angles)
    # only the legs' joints moved (the stance IK), the rest as given
    legs = {j for j in G1.joint_names if any(w in j for w in ("hip", "knee", "ankle"))}
    rest = [G1.index(j) for j in G1.joint_names if j not in legs]
    assert np.array_equal(root.angles[:, rest], angles[:, rest])


def test_a_hip_centred_recording_moves_its_root_by_the_feet(walk) -> None:
    """The walk centred on its pelvis in every frame (as MediaPipe writes world landmarks):
    its pelvis steps are all 0, so the root's steps are not bounded by them (``CENTRED``) but by
    the stance feet's: they move the root, more than the slack in a frame, and no step exceeds
    the planned horizontal one by more than the slack."""
    rec, angles, _ = walk
    centred = rec.positions - rec.positions[:, J["HipCenter"]][:, None]
    root = wb.root_trajectory(centred, rec.valid, rec.times, angles, G1)
    steps = np.linalg.norm(np.diff(root.root_pos.astype(np.float64), axis=0), axis=1)
    assert steps.max() > feet_mod.ROOT_SLACK + wb.LIFT_SLACK
    budget = wb._prepare(centred, rec.valid, rec.times, angles, G1).budget[1:]
    assert np.isfinite(budget).all() and (budget >= feet_mod.ROOT_SLACK).all()
    assert (steps - budget).max() <= wb.LIFT_SLACK + 1e-6


def test_a_lift_rises_and_falls_within_its_rate() -> None:
    """``_spread``: the least profile at or above the lift whose steps stay within the rate:
    a peak keeps its height and slopes down on both sides; where the rate allows, it is the
    lift itself."""
    lift = np.array([0.0, 0.0, 0.0, 0.10, 0.0, 0.0, 0.0, 0.0])
    rate = np.full(8, 0.04)
    got = wb._spread(lift, rate)
    assert np.allclose(got, [0.0, 0.02, 0.06, 0.10, 0.06, 0.02, 0.0, 0.0])
    assert (got >= lift).all() and (np.abs(np.diff(got)) <= rate[1:] + 1e-12).all()
    steps = np.array([0.0, 0.01, 0.02, 0.01, 0.0])
    assert np.array_equal(wb._spread(steps, np.full(5, 0.05)), steps)
    # a step's own rate (into frame t) binds it either way
    got = wb._spread(np.array([0.0, 0.0, 0.3]), np.array([0.0, 0.1, 0.2]))
    assert np.allclose(got, [0.0, 0.1, 0.3])


def test_contacts_of_a_person_who_lifts_a_foot() -> None:
    """A person standing still is in contact with both feet; a foot held 20 cm up for ten
    frames is not, there; a one-frame blip of contact is dropped (``min_frames``)."""
    rec = read_skeleton(CLIP)
    still = np.repeat(rec.positions[:1], 40, axis=0).astype(np.float64)
    lifted = still.copy()
    for j in ("AnkleLeft", "FootLeft"):
        lifted[10:20, J[j], 1] += 0.2  # +y: up in the readers' capture frame
    lifted[14, J["AnkleLeft"], 1] -= 0.2  # one frame back down: too short to count
    lifted[14, J["FootLeft"], 1] -= 0.2
    times = np.arange(40) / 30.0
    valid = np.ones(40, bool)
    world = wb.world_frame(lifted, valid, G1)
    contact, clear = wb.contacts_of(lifted, valid, times, world)
    assert contact[:, 1].all() and contact[:9, 0].all() and contact[22:, 0].all()
    assert not contact[10:20, 0].any()
    assert clear[12, 0] > 0.1 and clear[0].max() < 0.01
    world = wb.world_frame(still, valid, G1)
    assert wb.contacts_of(still, valid, times, world)[0].all()
    with pytest.raises(ConfigError, match="min_frames"):
        wb.ContactConfig(min_frames=0)


def test_a_robot_without_legs_is_refused() -> None:
    with pytest.raises(ConfigError, match="thigh_left"):
        wb.check_robot(robots.get("nao_h25"))


def test_whole_body_files_read_back_bit_exact(walk, tmp_path) -> None:
    """NPZ (root_pos, root_rot, dof_pos, fps, contacts) and the LAFAN1-layout CSV (no header,
    root 7 + 29 columns, read at ``fps=``) give back the written arrays to the bit; the CSV's
    robot is found by its column count."""
    rec, _, root = walk
    motion = Motion(root.angles, rec.times, rec.valid, rec.positions, robot=G1,
                    root_pos=root.root_pos, root_rot=root.root_rot,
                    contacts=root.contacts)  # fmt: skip
    assert motion.whole_body
    save_motion(tmp_path / "m.npz", motion)
    with np.load(tmp_path / "m.npz") as z:
        assert {"root_pos", "root_rot", "dof_pos", "fps", "contacts"} <= set(z.files)
        assert np.array_equal(z["dof_pos"], motion.angles) and float(z["fps"]) == motion.fps
    back = load_motion(tmp_path / "m.npz")
    for name in ("root_pos", "root_rot", "contacts", "angles", "times"):
        assert np.array_equal(getattr(back, name), getattr(motion, name)), name
    save_motion(tmp_path / "m.csv", motion, margin=None)
    lines = (tmp_path / "m.csv").read_text().splitlines()
    assert len(lines) == motion.n_frames and len(lines[0].split(",")) == 7 + G1.n_joints
    csv = load_motion(tmp_path / "m.csv", fps=motion.fps)
    assert csv.robot is G1 and csv.meta["fps"] == motion.fps
    for name in ("root_pos", "root_rot", "angles"):
        assert np.array_equal(getattr(csv, name), getattr(motion, name)), name
    assert np.allclose(csv.times, np.arange(motion.n_frames) / motion.fps)
    assert load_motion(tmp_path / "m.csv").times[1] == pytest.approx(1 / 30)  # LAFAN1's rate


def test_whole_body_files_refuse_what_they_cannot_hold(walk, tmp_path) -> None:
    rec, _, root = walk
    n = len(rec.times)
    with pytest.raises(ConfigError, match="come together"):
        Motion(root.angles, rec.times, rec.valid, robot=G1, root_pos=root.root_pos)
    bad = root.root_rot.copy()
    bad[3] *= 2
    with pytest.raises(ConfigError, match="frame 3 has norm"):
        Motion(root.angles, rec.times, rec.valid, robot=G1, root_pos=root.root_pos, root_rot=bad)
    uneven = rec.times.copy()
    uneven[5:] += 0.01
    motion = Motion(root.angles, uneven, rec.valid, robot=G1, root_pos=root.root_pos,
                    root_rot=root.root_rot)  # fmt: skip
    with pytest.raises(ConfigError, match="evenly spaced"):
        save_motion(tmp_path / "u.csv", motion)
    assert not (tmp_path / "u.csv").exists()
    (tmp_path / "w.csv").write_text("0.0,1.0,2.0\n")
    with pytest.raises(InputError, match="fits 0 registered robots"):
        load_motion(tmp_path / "w.csv")
    with pytest.raises(InputError, match="has 36"):
        load_motion(tmp_path / "w.csv", robot=G1)
    with pytest.raises(ConfigError, match="fps="):
        load_motion(tmp_path / "w.npz", fps=30)
    assert n > 10


def test_the_command_line_writes_the_root(walk, tmp_path, capsys, monkeypatch) -> None:
    """``retarget --root world``: what it writes is ``root_trajectory`` of the retargeted angles
    (here the retargeting replaced by the standing posture: the wiring is under test, not the
    IK), retargeted without the legs' levelling; refusals come before any work, in one line."""
    from jaxproj.motion import retarget as rt

    rec, angles, root = walk

    seen = {}

    def standing(positions, valid, **kwargs):
        seen.update(kwargs)
        return rt.RetargetResult(angles, np.asarray(valid), kwargs["times"])

    monkeypatch.setattr(rt, "retarget", standing)
    code, out, err = run_cli(capsys, "retarget", str(CLIP), "--robot", "unitree_g1", "--root",
                             "world", "--out", str(tmp_path / "m.npz"))  # fmt: skip
    assert code == 0, err
    assert "whole body: scale" in out
    assert seen["level_legs"] is False  # the legs keep the person's own body frame
    m = load_motion(tmp_path / "m.npz")
    assert m.meta["root"] == "world"
    assert np.array_equal(m.root_pos, root.root_pos) and np.array_equal(m.angles, root.angles)
    for argv, words in (
        (["--out", str(tmp_path / "o.npz")], "whole-body motion needs correspondence rows"),
        (["--out", str(tmp_path / "o.json")], "holds joint angles only"),
        (["--robot", "unitree_g1", "--rate", "input", "--out", str(tmp_path / "o.npz")],
         "evenly spaced frames"),
    ):  # fmt: skip
        code, _, err = run_cli(capsys, "retarget", str(CLIP), "--root", "world", *argv)
        assert_one_line_error(code, err, words)


def test_planted_legs_leave_no_self_contact(walk) -> None:
    """The arms hanging at the hips (a G1 IK answer for a person standing so, CMU 131_03): the
    stance IK moves the legs into the hands on some frames; the last stage run once more
    (``separate=True``, the default) leaves no two robot geoms in contact (> 1 mm, MuJoCo) on
    any frame; the arms yield (the limbs before the trunk: the waist moves less than 1 deg)."""
    rec, angles, _ = walk
    arms = {"left_shoulder_pitch_joint": 15.9, "left_shoulder_roll_joint": 2.7,
            "left_shoulder_yaw_joint": -16.8, "left_elbow_joint": 41.1,
            "right_shoulder_pitch_joint": 14.4, "right_shoulder_roll_joint": 2.5,
            "right_shoulder_yaw_joint": 6.5, "right_elbow_joint": 49.8}  # fmt: skip
    q = angles.copy()
    for name, deg in arms.items():
        q[:, G1.index(name)] = np.radians(deg)
    model = G1.load_model("fixed")
    data = mujoco.MjData(model)
    adr = joint_qpos_index(model, G1.joint_names)

    def touching(a: np.ndarray) -> int:
        frames = 0
        for row in a:
            data.qpos[adr] = row
            mujoco.mj_forward(model, data)
            frames += any(c.dist < -1e-3 for c in data.contact[: data.ncon])
        return frames

    raw = wb.root_trajectory(rec.positions, rec.valid, rec.times, q, G1, separate=False)
    out = wb.root_trajectory(rec.positions, rec.valid, rec.times, q, G1)
    assert touching(raw.angles) > 10 and touching(out.angles) == 0
    moved = np.degrees(np.abs(out.angles - raw.angles).max(axis=0))
    assert moved[[G1.index(n) for n in arms]].max() > 5.0  # the arms yielded
    assert moved[[G1.index(n) for n in G1.joint_names if n.startswith("waist")]].max() < 1.0


def test_every_format_with_feet_gets_a_root(tmp_path, capsys, monkeypatch) -> None:
    """``retarget --root world`` of the same motion written in other skeleton layouts
    (``tests/data/formats/same_motion``: Kinect v2, SMPL): the readers give Kinect v1's 20
    joints whatever the file recorded, and the root is the Kinect v1 file's to 1 mm (the files'
    rounding; the
    command once passed the file's layout along with the converted positions: a KeyError).
    The retargeting and the last separation are replaced (the wiring is under test)."""
    from jaxproj.motion import retarget as rt

    def standing(positions, valid, **kwargs):
        q = np.tile(G1.standing, (len(valid), 1)).astype(np.float32)
        return rt.RetargetResult(q, np.asarray(valid), kwargs["times"])

    monkeypatch.setattr(rt, "retarget", standing)
    monkeypatch.setattr(rt, "separate_motion", lambda q, robot: q)
    folder = CLIP.parents[1] / "formats" / "same_motion"
    roots = {}
    for name, extra in (("kinect_v1.csv", ["--fps", "10"]), ("kinect_v2.skeleton", ["--fps", "10"]),
                        ("smpl.npz", [])):  # fmt: skip
        out = tmp_path / f"{name}.npz"
        argv = [str(folder / f"131_03.{name}"), "--robot", "unitree_g1", "--root", "world"]
        code, _, err = run_cli(capsys, "retarget", *argv, "--out", str(out), *extra)
        assert code == 0, err
        roots[name] = load_motion(out).root_pos
    # the root walks on (0.87 m: the standing legs cannot step, so the root, held while they
    # cannot reach, catches up at most ROOT_SLACK a frame faster than the pelvis; 2.84 m over
    # the whole clip with its retargeted legs, benchmarks.whole_body)
    assert np.linalg.norm(roots["kinect_v1.csv"][-1, :2] - roots["kinect_v1.csv"][0, :2]) > 0.7
    for name in ("kinect_v2.skeleton", "smpl.npz"):
        np.testing.assert_allclose(roots[name], roots["kinect_v1.csv"], atol=1e-3)  # files round


def test_a_batch_plants_its_motions_together_as_each_alone(walk, monkeypatch) -> None:
    """``root_trajectories``: the motions of one length bucket planted in one vmapped program
    (``stance.plant_many``); each motion's root and angles are those ``root_trajectory`` (one
    motion: ``stance.plant``) gives it alone (float rounding apart: the
    batched program's products round differently), a motion that cannot be done is its error
    and stops no other."""
    from jaxproj.motion import feet

    rec, angles, _ = walk
    centred = rec.positions - rec.positions[:, J["HipCenter"]][:, None]
    calls = []
    real = feet.plant_planned

    def spy(robot, plans, together):
        calls.append([len(p.angles) for p in plans])
        return real(robot, plans, together)

    def part(pos: np.ndarray, n: int, start: int = 0) -> tuple:
        cut = slice(start, start + n)
        return pos[cut], rec.valid[cut], rec.times[cut], angles[cut]

    monkeypatch.setattr(wb, "plant_planned", spy)
    # all three padded to 64 rows (fine_bucket, a CPU) and planted together, a stack of 4
    wrong = part(rec.positions, 60)[:3] + (angles[:3],)  # angles that disagree
    motions = [part(rec.positions, 60), part(centred, 56, 40), wrong, part(rec.positions, 50, 120)]
    got = wb.root_trajectories(motions, G1, separate=False, together=True)  # stacked on a CPU too
    assert calls == [[60, 56, 50]] and isinstance(got[2], ConfigError)
    for i in (0, 1, 3):
        one, many = wb.root_trajectory(*motions[i], G1, separate=False), got[i]
        assert np.array_equal(one.contacts, many.contacts) and one.contacts.any()
        step = np.abs(one.root_pos - many.root_pos).max(axis=1)
        turn = np.abs(one.angles - many.angles).max(axis=1)
        # 0.1 mm and 1 mrad on the median: the float32 port itself is 0.4 mm (median) from the
        # float64 host solver it replaced (stance module doc); the solves amplify rounding
        assert np.median(step) < 1e-4 and np.median(turn) < 1e-3
        assert (step < 1e-3).mean() > 0.95 and (turn < 1e-2).mean() > 0.95


def test_the_stance_ik_differentiates_the_feet_as_mujoco_does() -> None:
    """``stance.foot_jacobians`` at a random pose (root placed and turned, legs bent) equals
    MuJoCo's on the free model: each sole's reference point and axes (``mj_kinematics``), the
    point's translation Jacobian and the foot's rotation Jacobian (``mj_jac``) by the root's
    position and the legs' joints."""
    import functools

    import jax
    import jax.numpy as jnp

    from jaxproj.motion import stance

    feet = stance.feet_of(G1)
    rng = np.random.default_rng(3)
    q = (G1.standing + rng.normal(0.0, 0.3, G1.n_joints)).clip(G1.lower, G1.upper)
    root = np.array([0.3, -0.2, 0.7])
    wxyz = rng.normal(size=4)
    wxyz /= np.linalg.norm(wxyz)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, wxyz)
    rot = rot.reshape(3, 3)
    x = np.concatenate([root, q[feet.cols]])
    jacobians = jax.jit(functools.partial(stance.foot_jacobians, feet))
    point, j_point, axes, j_turn = (
        np.asarray(a, np.float64)
        for a in jacobians(jnp.asarray(x, jnp.float32), jnp.asarray(q, jnp.float32),
                           jnp.asarray(rot, jnp.float32))
    )  # fmt: skip
    model = G1.load_model("free")
    data = mujoco.MjData(model)
    adr = joint_qpos_index(model, G1.joint_names)
    data.qpos[0:3], data.qpos[3:7], data.qpos[adr] = root, wxyz, q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    dofs = np.concatenate([[0, 1, 2], [model.jnt_dofadr[model.jnt_qposadr.tolist().index(a)]
                                       for a in adr[feet.cols]]])  # fmt: skip
    for k, (name, _) in enumerate(G1.mjcf.figure.feet[:2]):
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        r = data.xmat[body].reshape(3, 3)
        np.testing.assert_allclose(axes[k], r, atol=2e-6)
        jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jac(model, data, jp, jr, point[k], body)
        np.testing.assert_allclose(j_point[k], jp[:, dofs], atol=2e-5)
        np.testing.assert_allclose(j_turn[k], jr[:, dofs], atol=2e-5)
        assert np.abs(j_point[k][:, 3:]).max() > 0.1 and np.abs(j_turn[k][:, 3:]).max() > 0.5
