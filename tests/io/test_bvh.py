"""BVH input (jaxproj.io.formats.bvh, read_skeleton(format="bvh")): parsing, forward kinematics
against an independent rotation library, joint maps, the real CMU excerpts through the
descriptor, the IK and a projector, resampling, bad files and the CLI.

The real data are every-6th-frame excerpts of two CMU clips shipped in ``tests/data/cmu_bvh``
(attribution and the documented bone lengths: ``tests/data/cmu_bvh/SOURCE.md``)."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import jax
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxproj.cli import main
from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import BONE_NAMES, JOINT_NAMES, descriptor
from jaxproj.io import datasets
from jaxproj.io.formats import bvh
from jaxproj.io.readers import read_skeleton, recording_format
from jaxproj.motion.retarget import retarget
from jaxproj.projection import api as engine
from jaxproj.robots.nao_h25 import ik, robot

DATA = Path(__file__).resolve().parents[1] / "data" / "cmu_bvh"
CLIPS = ("131_01_every6.bvh", "131_03_every6.bvh")

BONE_LENGTHS_M = {  # tests/data/cmu_bvh/SOURCE.md
    ("LeftShoulder", "LeftElbow"): 0.23995, ("RightShoulder", "RightElbow"): 0.25178,
    ("LeftElbow", "LeftWrist"): 0.18491, ("RightElbow", "RightWrist"): 0.19440,
    ("LeftHip", "LeftKnee"): 0.41147, ("RightHip", "RightKnee"): 0.40690,
    ("LeftKnee", "LeftAnkle"): 0.39075, ("RightKnee", "RightAnkle"): 0.39352,
    ("Hips", "Chest"): 0.11214, ("Chest", "Chest2"): 0.11234,
    ("lowerneck", "Neck"): 0.09108, ("Neck", "Head"): 0.09027,
}  # fmt: skip


_descriptor = jax.jit(descriptor, static_argnames=("bones", "mirror"))
"""The descriptor as one compiled program (eager, each new clip length compiles every op)."""


def _run(capsys, *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# --- a BVH writer and an independent forward kinematics (scipy) ----------------------------------


def bvh_text(joints: list[tuple], motion: np.ndarray, frame_time: float = 0.04) -> str:
    """A BVH file. ``joints``: ``(name, parent_name | None, offset, channels)`` in file order,
    End Sites as ``("End Site", parent, offset, ())``."""
    children: dict[str | None, list[tuple]] = {}
    for j in joints:
        children.setdefault(j[1], []).append(j)
    out = ["HIERARCHY"]

    def emit(j: tuple, depth: int) -> None:
        name, _, offset, channels = j
        pad = "\t" * depth
        head = "End Site" if name == "End Site" else ("ROOT " if depth == 0 else "JOINT ") + name
        out.append(pad + head)
        out.append(pad + "{")
        out.append(pad + "\tOFFSET " + " ".join(f"{v:.6f}" for v in offset))
        if channels:
            out.append(pad + f"\tCHANNELS {len(channels)} " + " ".join(channels))
        for c in children.get(name, []) if name != "End Site" else []:
            emit(c, depth + 1)
        out.append(pad + "}")

    emit(children[None][0], 0)
    out += ["MOTION", f"Frames: {len(motion)}", f"Frame Time: {frame_time}"]
    out += [" ".join(f"{v:.6f}" for v in row) for row in motion]
    return "\n".join(out) + "\n"


def scipy_fk(joints: list[tuple], motion: np.ndarray) -> dict[str, np.ndarray]:
    """Positions ``(T, 3)`` of each named joint (End Sites as ``<parent>_End``), rotations by
    ``scipy.spatial.transform.Rotation`` (intrinsic Euler angles in the channels' order)."""
    pos: dict[str, np.ndarray] = {}
    rot: dict[str, Rotation] = {}
    col = 0
    t = len(motion)
    for name, parent, offset, channels in joints:
        local = np.tile(np.asarray(offset, float), (t, 1))
        order, angles = "", []
        for ch in channels:
            if ch.endswith("position"):
                local[:, "XYZ".index(ch[0])] = motion[:, col]
            else:
                order += ch[0]
                angles.append(motion[:, col])
            col += 1
        r = Rotation.from_euler(order, np.stack(angles, 1), degrees=True) if order else None
        key = f"{parent}_End" if name == "End Site" else name
        if parent is None:
            pos[key], rot[key] = local, r
        else:
            pos[key] = pos[parent] + rot[parent].apply(local)
            rot[key] = rot[parent] if r is None else rot[parent] * r
    return pos


ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


def _rot(order: str) -> tuple[str, ...]:
    return tuple(f"{a}rotation" for a in order)


# A small humanoid in centimetres, facing +z, its left at +x; every Euler order appears, the
# root and LElbow also have position channels (LElbow's replace its OFFSET).
SYNTH: list[tuple] = [
    ("Hips", None, (0, 95, 0), ("Xposition", "Yposition", "Zposition", *_rot("YXZ"))),
    ("Spine", "Hips", (0, 20, 0), _rot("ZXY")),
    ("Neck", "Spine", (0, 28, 2), _rot("XYZ")),
    ("Head", "Neck", (0, 22, 3), _rot("YZX")),
    ("End Site", "Head", (0, 12, 0), ()),
    ("LShoulder", "Neck", (18, -3, 0), _rot("ZYX")),
    ("LElbow", "LShoulder", (27, 0, 0), ("Xposition", "Yposition", "Zposition", *_rot("XZY"))),
    ("LWrist", "LElbow", (25, 0, 0), _rot("YXZ")),
    ("RShoulder", "Neck", (-18, -3, 0), _rot("XZY")),
    ("RElbow", "RShoulder", (-27, 0, 0), _rot("ZYX")),
    ("RWrist", "RElbow", (-25, 0, 0), _rot("XYZ")),
    ("LHip", "Hips", (10, -5, 0), _rot("ZXY")),
    ("LKnee", "LHip", (0, -45, 0), _rot("YZX")),
    ("LAnkle", "LKnee", (0, -42, 0), _rot("ZYX")),
    ("End Site", "LAnkle", (0, -6, 14), ()),
    ("RHip", "Hips", (-10, -5, 0), _rot("XYZ")),
    ("RKnee", "RHip", (0, -45, 0), _rot("YXZ")),
    ("RAnkle", "RKnee", (0, -42, 0), _rot("XZY")),
    ("End Site", "RAnkle", (0, -6, 14), ()),
]  # fmt: skip
SYNTH_MAP = {
    "Head": "Head", "ShoulderLeft": "LShoulder", "ElbowLeft": "LElbow", "WristLeft": "LWrist",
    "ShoulderRight": "RShoulder", "ElbowRight": "RElbow", "WristRight": "RWrist",
    "HipLeft": "LHip", "KneeLeft": "LKnee", "AnkleLeft": "LAnkle",
    "HipRight": "RHip", "KneeRight": "RKnee", "AnkleRight": "RAnkle",
}  # fmt: skip


def _synth_motion(t: int = 6, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n_ch = sum(len(j[3]) for j in SYNTH)
    m = rng.uniform(-170, 170, size=(t, n_ch))  # every angle, far from small
    m[:, :3] = rng.uniform(-50, 50, size=(t, 3)) + [0, 95, 0]
    col = sum(len(j[3]) for j in SYNTH[:6])  # LElbow's position channels
    m[:, col : col + 3] = rng.uniform(20, 30, size=(t, 3))
    return np.round(m, 6)  # as written


def test_synthetic_bvh_in_every_euler_order_reads_back_to_known_positions(tmp_path):
    motion = _synth_motion()
    path = tmp_path / "synthetic.bvh"
    path.write_text(bvh_text(SYNTH, motion))
    want = scipy_fk(SYNTH, motion)
    clip = bvh.parse_bvh(path)
    assert clip.names[:4] == ("Hips", "Spine", "Neck", "Head") and clip.names[4] == "Head_End"
    assert clip.channels[clip.index("Neck")] == _rot("XYZ") and clip.fps == pytest.approx(25)
    got = bvh.forward_kinematics(clip)
    for name, p in want.items():
        np.testing.assert_allclose(got[:, clip.index(name)], p, atol=1e-9, err_msg=name)
    # through the reader: a user map (dict) with the derived joints, cm guessed, Kinect axes
    rec = read_skeleton(path, bvh_map=SYNTH_MAP)
    assert rec.format == "bvh" and "cm (guessed" in rec.time_source
    np.testing.assert_allclose(rec.times, np.arange(6) * 0.04)
    k = {n: want[b] for n, b in SYNTH_MAP.items()}
    k["HipCenter"] = want["Hips"]
    k["ShoulderCenter"] = (k["ShoulderLeft"] + k["ShoulderRight"]) / 2
    k["Spine"] = (k["HipCenter"] + k["ShoulderCenter"]) / 2
    for side in ("Left", "Right"):
        w, e = k[f"Wrist{side}"], k[f"Elbow{side}"]
        k[f"Hand{side}"] = w + bvh.HAND_EXTENSION * (w - e)
        k[f"Foot{side}"] = want[f"{side[0]}Ankle_End"]
    expected = np.stack([k[n] for n in JOINT_NAMES], axis=1) * 0.01 * [-1.0, 1.0, -1.0]
    np.testing.assert_allclose(rec.positions, expected, atol=2e-6)


def test_rest_and_t_pose_frames_give_the_documented_bone_lengths(tmp_path):
    clip = bvh.parse_bvh(DATA / CLIPS[1])
    rest = np.zeros((2, clip.motion.shape[1]))
    rest[:, :3] = clip.motion[0, :3]  # the root where the clip starts; every rotation 0
    cols = np.cumsum([0] + [len(c) for c in clip.channels])
    for side, sign in (("Left", 1.0), ("Right", -1.0)):  # frame 1: a T-pose (Zrotation first)
        j = clip.index(f"{side}Shoulder")
        assert clip.channels[j][0] == "Zrotation"
        rest[1, cols[j]] = 90.0 * sign
    tpose = dataclasses.replace(clip, motion=rest, lines=np.arange(2))
    p = bvh.forward_kinematics(tpose, bvh.CMU_SCALE)
    real = bvh.forward_kinematics(clip, bvh.CMU_SCALE)
    for (a, b), length in BONE_LENGTHS_M.items():
        ia, ib = clip.index(a), clip.index(b)
        np.testing.assert_allclose(np.linalg.norm(p[:, ib] - p[:, ia], axis=-1), length, atol=6e-6)
        np.testing.assert_allclose(
            np.linalg.norm(real[:, ib] - real[:, ia], axis=-1), length, atol=6e-6
        )  # rigid in every frame of the motion too
    n = clip.index
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        arm = p[:, n(f"{side}Wrist")] - p[:, n(f"{side}Shoulder")]
        np.testing.assert_allclose(arm[0] / np.linalg.norm(arm[0]), [0, -1, 0], atol=1e-9)
        np.testing.assert_allclose(arm[1] / np.linalg.norm(arm[1]), [sign, 0, 0], atol=1e-9)
    assert p[0, n("Hips"), 1] == pytest.approx(0.956, abs=0.002)  # hip height, the clip's root
    head = p[0, n("Head_End")] - p[0, n("Hips")]  # upright: the head straight above the hips
    assert 0.49 < head[1] < 0.51 and np.hypot(head[0], head[2]) < 0.02
    assert (p[0, [n("LeftAnkle"), n("RightAnkle")], 1] < 0.15).all()  # legs down to the floor
    # the T-pose through the Kinect map, the descriptor and the IK: each arm out to its own side
    d, ok = _descriptor(bvh.kinect_positions(tpose, bvh.JOINT_MAPS["cmu"], bvh.CMU_SCALE))
    assert np.asarray(ok).all()
    u = np.asarray(d)[1].reshape(5, 3)  # neck, upper_arm_left, forearm_left, upper_arm_right, ...
    assert u[1, 1] > 0.99 and u[3, 1] < -0.99  # along the body's left (+y) / right (-y) axis
    q = np.asarray(ik.solve(d))[1]
    assert q[robot.IDX["LShoulderRoll"]] == pytest.approx(robot.UPPER[robot.IDX["LShoulderRoll"]])
    assert q[robot.IDX["RShoulderRoll"]] == pytest.approx(robot.LOWER[robot.IDX["RShoulderRoll"]])


@pytest.fixture(scope="module")
def clips():
    return {name: read_skeleton(DATA / name) for name in CLIPS}


def test_real_clips_give_valid_descriptors_and_the_bvh_arm_directions(clips):
    for name, rec in clips.items():
        assert recording_format(DATA / name) == ("bvh", "")
        assert rec.format == "bvh" and "map cmu; scale cmu units" in rec.time_source
        assert rec.fps == pytest.approx(20.0, rel=1e-4) and rec.valid.all()
        d, ok = _descriptor(rec.positions, bones="full")
        assert np.asarray(ok).all() and np.isfinite(np.asarray(d)).all()
        # the same bones from the BVH's own joints, in a body frame made from them (BVH axes)
        clip = bvh.parse_bvh(DATA / name)
        p = bvh.forward_kinematics(clip, bvh.CMU_SCALE)
        names = ("Hips", "Neck", "LeftShoulder", "RightShoulder", "LeftElbow", "RightElbow",
                 "LeftWrist", "RightWrist")  # fmt: skip
        g = {n: p[:, clip.index(n)] for n in names}
        up = _unit(g["Neck"] - g["Hips"])
        left = g["LeftShoulder"] - g["RightShoulder"]
        left = _unit(left - np.sum(left * up, -1, keepdims=True) * up)
        frame = np.stack([np.cross(left, up), left, up], axis=1)
        dd = np.asarray(d).reshape(len(rec.valid), len(BONE_NAMES), 3)
        for bone, (a, b) in {
            "upper_arm_left": ("LeftShoulder", "LeftElbow"),
            "forearm_left": ("LeftElbow", "LeftWrist"),
            "upper_arm_right": ("RightShoulder", "RightElbow"),
            "forearm_right": ("RightElbow", "RightWrist"),
        }.items():
            want = np.einsum("tij,tj->ti", frame, _unit(g[b] - g[a]))
            np.testing.assert_allclose(dd[:, BONE_NAMES.index(bone)], want, atol=2e-5)
        # not mirrored: the feet point forward, out of the chest (a swapped map turns them back)
        foot = np.einsum("tij,tj->ti", frame, _unit(
            p[:, clip.index("LeftToe")] - p[:, clip.index("LeftAnkle")]))  # fmt: skip
        assert np.median(foot[:, 0]) > 0.5
        assert np.median(dd[:, BONE_NAMES.index("foot_left"), 0]) > 0.5


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@pytest.fixture(scope="module")
def small_model():
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3], actions=[1, 2, 5]))
    human = d[np.random.default_rng(0).choice(len(d), 300, replace=False)]
    cfg = engine.BuildConfig(
        chains="whole", landmarks=None, bandwidth=1.0, k=16, hidden=32, input_scale=1.0
    )  # one chain: half the compilation time of the per-chain default
    return engine.from_landmarks(human, np.asarray(ik.solve_driven(human)), cfg)


def test_real_clips_ik_and_projection_within_limits(clips, small_model):
    from jaxproj.motion.feasible import FeasibleConfig

    for rec in clips.values():  # 166 and 184 frames: one compiled length (256) for both
        q_ik = retarget(rec.positions, rec.valid, times=rec.times, smoothing=None).angles
        res = retarget(rec.positions, rec.valid, model=small_model, times=rec.times,
                       feasible=FeasibleConfig())  # fmt: skip
        for q in (q_ik, res.angles):
            assert res.valid.all() and np.isfinite(q).all()
            assert (q >= robot.LOWER).all() and (q <= robot.UPPER).all()
        # the robot's left arm follows the performer's left arm (BVH LeftShoulder/LeftElbow):
        # arm forward <-> ShoulderPitch down, arm out to the left <-> LShoulderRoll up
        d = np.asarray(_descriptor(rec.positions)[0]).reshape(-1, 5, 3)
        for side, bone in (("L", 1), ("R", 3)):
            pitch = q_ik[:, robot.IDX[f"{side}ShoulderPitch"]]
            roll = q_ik[:, robot.IDX[f"{side}ShoulderRoll"]]
            ok = np.abs(d[:, bone, 1]) < 0.7  # away from the arm-along-shoulder singularity
            assert np.corrcoef(pitch[ok], d[ok, bone, 0])[0, 1] < -0.8, side
            assert np.corrcoef(roll, d[:, bone, 1])[0, 1] > 0.9, side


def test_resampling_keeps_or_changes_the_rate(clips, tmp_path):
    rec = clips[CLIPS[0]]
    r30 = read_skeleton(DATA / CLIPS[0], fps=30)
    n = int(np.floor(rec.times[-1] * 30 + 1e-9)) + 1
    assert r30.positions.shape == (n, 20, 3) and r30.valid.all()
    np.testing.assert_allclose(r30.times, np.arange(n) / 30)
    assert r30.fps == pytest.approx(30) and "resampled to 30 fps (linear)" in r30.time_source
    # 20 and 30 fps meet every 0.1 s (frame time .0499998: up to 2e-6 s apart): equal frames
    np.testing.assert_allclose(r30.positions[::3], rec.positions[::2][: len(r30.positions[::3])],
                               atol=5e-4)  # fmt: skip
    mid = 0.5 * (rec.positions[0] + rec.positions[1])  # t = 1/30 s: 2/3 of the way 0 -> 0.05 s
    two_thirds = rec.positions[0] + (2 / 3) * (rec.positions[1] - rec.positions[0])
    np.testing.assert_allclose(r30.positions[1], two_thirds, atol=1e-4)
    assert not np.allclose(r30.positions[1], mid, atol=1e-4)
    with pytest.raises(ConfigError, match="fps"):
        read_skeleton(DATA / CLIPS[0], fps=0.0)


def test_a_converters_rest_frame_is_dropped_by_default(clips, tmp_path):
    """Frame 0 of every joint rotation 0 (the hierarchy's rest pose, as some CMU conversions
    begin) is left out unless kept; the bundled clips start with motion and lose nothing."""
    for name, rec in clips.items():
        assert not bvh.rest_pose_first(bvh.parse_bvh(DATA / name))
        assert len(rec.times) == bvh.parse_bvh(DATA / name).n_frames
        assert "dropped" not in rec.time_source
    lines = (DATA / CLIPS[0]).read_bytes().split(b"\n")
    m = next(i for i, line in enumerate(lines) if line.strip() == b"MOTION")
    first = lines[m + 3].split()
    rest = b" ".join(first[:6] + [b"0.0000"] * (len(first) - 6))  # the root kept, rotations 0
    n = int(lines[m + 1].split()[1])
    path = tmp_path / "with_rest.bvh"
    path.write_bytes(b"\n".join([*lines[: m + 1], b"Frames: %d" % (n + 1), lines[m + 2], rest,
                                  *lines[m + 3 :]]))  # fmt: skip
    assert bvh.rest_pose_first(bvh.parse_bvh(path))
    rec, orig = read_skeleton(path), clips[CLIPS[0]]
    np.testing.assert_array_equal(rec.positions, orig.positions)  # frame 1 of the file at t = 0
    np.testing.assert_array_equal(rec.times, orig.times)
    assert "frame 0 (the hierarchy's rest pose, all rotations 0) dropped" in rec.time_source
    kept = read_skeleton(path, rest_frame="keep")
    assert len(kept.times) == n + 1 and "dropped" not in kept.time_source
    np.testing.assert_array_equal(kept.positions[1:], orig.positions)
    with pytest.raises(ConfigError, match="rest_frame"):
        bvh.read_bvh(path, rest_frame="auto")


def _mb_text() -> str:
    """The 131_03 excerpt with the MotionBuilder-friendly release's joint names."""
    rename = {
        "LeftHip": "LeftUpLeg", "LeftKnee": "LeftLeg", "LeftAnkle": "LeftFoot",
        "LeftToe": "LeftToeBase", "lowerback": "LowerBack", "Chest": "Spine",
        "Chest2": "Spine1", "lowerneck": "Neck", "Neck": "Neck1", "LeftCollar": "LeftShoulder",
        "LeftShoulder": "LeftArm", "LeftElbow": "LeftForeArm", "LeftWrist": "LeftHand",
        "lhand": "LeftFingerBase", "LFingers": "LeftHandIndex1",
    }  # fmt: skip
    rename.update({k.replace("Left", "Right"): v.replace("Left", "Right") for k, v in
                   rename.items() if "Left" in k})  # fmt: skip
    rename.update({"rhand": "RightFingerBase", "RFingers": "RightHandIndex1"})
    text = (DATA / CLIPS[1]).read_text()
    return re.sub(r"(JOINT|ROOT) (\S+)", lambda m: f"{m[1]} {rename.get(m[2], m[2])}", text)


def test_joint_maps_presets_files_and_errors(clips, tmp_path):
    ref = clips[CLIPS[1]]
    mb = tmp_path / "mb.bvh"
    mb.write_text(_mb_text())
    rec = read_skeleton(mb)  # detected: cmu-mb, the same joints as cmu under other names
    assert "map cmu-mb" in rec.time_source
    np.testing.assert_array_equal(rec.positions, ref.positions)
    # a user map: JSON and TOML files, a dict; the cmu table itself gives the same positions
    table = bvh.JOINT_MAPS["cmu"]
    (tmp_path / "map.json").write_text(json.dumps(table))
    (tmp_path / "map.toml").write_text("".join(f'{k} = "{v}"\n' for k, v in table.items()))
    for m in (tmp_path / "map.json", tmp_path / "map.toml", dict(table)):
        got = read_skeleton(DATA / CLIPS[1], bvh_map=m, scale="cmu")
        np.testing.assert_array_equal(got.positions, ref.positions)
    # no preset fits: the error lists what each could not map
    bad = tmp_path / "renamed.bvh"
    bad.write_text((DATA / CLIPS[1]).read_text().replace("JOINT LeftElbow", "JOINT LElb"))
    with pytest.raises(InputError) as e:
        read_skeleton(bad)
    msg = str(e.value)
    assert "\n" not in msg and str(bad) in msg
    assert "'cmu' could not map ElbowLeft (LeftElbow not in the hierarchy)" in msg
    assert "--bvh-map" in msg
    two = r"could not map 2 Kinect joint\(s\): Head \(nope not in the hierarchy\), WristLeft \(no "
    with pytest.raises(InputError, match=two):
        read_skeleton(DATA / CLIPS[1], bvh_map={**table, "WristLeft": "no", "Head": "nope"})
    with pytest.raises(InputError, match="Head \\(not in the map\\)"):
        read_skeleton(DATA / CLIPS[1], bvh_map={k: v for k, v in table.items() if k != "Head"})
    with pytest.raises(ConfigError, match="unknown Kinect joint.*20 joints of the kinect_v1"):
        read_skeleton(DATA / CLIPS[1], bvh_map={"Elbow": "LeftElbow"})
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(InputError, match="broken.json: not a joint map"):
        read_skeleton(DATA / CLIPS[1], bvh_map=tmp_path / "broken.json")
    with pytest.raises(ConfigError, match="not a built-in map"):
        read_skeleton(DATA / CLIPS[1], bvh_map="cmu-typo")
    with pytest.raises(ConfigError, match="bvh scale"):
        read_skeleton(DATA / CLIPS[1], scale="furlong")
    half = read_skeleton(DATA / CLIPS[1], scale=bvh.CMU_SCALE / 2)
    np.testing.assert_allclose(half.positions, ref.positions / 2, rtol=1e-6, atol=1e-7)


def test_joint_maps_map_onto_the_registered_kinect_v1_skeleton():
    target = bvh.TARGET_SKELETON
    assert target is skeletons.get("kinect_v1") and target.joints == JOINT_NAMES
    # required and derived joints split the skeleton's joints; the presets name only its joints,
    # every required one (the CMU presets all 20; LAFAN1 and Mixamo derive the hands)
    assert set(bvh.REQUIRED_JOINTS) | set(bvh.DERIVED_JOINTS) == set(target.joints)
    assert not set(bvh.REQUIRED_JOINTS) & set(bvh.DERIVED_JOINTS)
    for name, table in bvh.JOINT_MAPS.items():
        assert set(bvh.REQUIRED_JOINTS) <= set(table) <= set(target.joints), name
        assert set(target.joints) - set(table) == (
            set() if name.startswith("cmu") else {"HandLeft", "HandRight"}
        ), name


# --- bad files -----------------------------------------------------------------------------------

_N_CH = sum(len(j[3]) for j in SYNTH)
_GOOD = bvh_text(SYNTH, np.zeros((3, _N_CH)) + np.eye(1, _N_CH, 1) * 95)  # standing, root y 95
_MOTION_LINE = _GOOD.splitlines().index("MOTION") + 1  # then Frames, Frame Time and 3 rows
_ROW = _MOTION_LINE + 3  # line of the first frame row
_SPINE_OFFSET = next(i for i, ln in enumerate(_GOOD.splitlines(), 1) if "OFFSET 0.000000 20." in ln)
_ZEROS = " ".join(["0"] * (_N_CH - 1))


def _replace_line(text: str, line: int, new: str | None) -> str:
    lines = text.splitlines()
    if new is None:
        del lines[line - 1]
    else:
        lines[line - 1] = new
    return "\n".join(lines) + "\n"


BAD_BVH = [
    ("missing-motion", _GOOD.split("MOTION")[0], ["no MOTION section"]),
    ("motion-keyword-lost", _replace_line(_GOOD, _MOTION_LINE, None),
     [f"line {_MOTION_LINE}: 'Frames:' after the skeleton closed", "expected MOTION"]),
    ("channel-count", _replace_line(_GOOD, _ROW + 1, _ZEROS),
     [f"line {_ROW + 1}: found {_N_CH - 1} values, expected {_N_CH} (the channels"]),
    ("non-numeric", _replace_line(_GOOD, _ROW + 2, _ZEROS + " abc"),
     [f"line {_ROW + 2}, column {_N_CH}: non-numeric token 'abc'"]),
    ("truncated-row", _GOOD[: _GOOD.rindex(" ")], [f"line {_ROW + 2}: found {_N_CH - 1} values"]),
    ("missing-rows", _replace_line(_GOOD, _ROW + 2, None),
     [f"line {_ROW + 1}: the file ends after 2 frame rows", "'Frames: 3'", "truncated"]),
    ("extra-rows", _GOOD + _ZEROS + " 0\n",
     [f"line {_ROW + 3}: the file has 4 frame rows", "'Frames: 3'"]),
    ("frame-time", _GOOD.replace("Frame Time: 0.04", "Frame Time: 0"),
     [f"line {_MOTION_LINE + 2}: Frame Time '0' is not a time step"]),
    ("frames-word", _GOOD.replace("Frames: 3", "Frames: three"),
     [f"line {_MOTION_LINE + 1}: the frame count 'three' is not a whole number"]),
    ("unknown-channel", _GOOD.replace("Zrotation", "Wrotation", 1),
     ["unknown channel 'Wrotation'"]),
    ("offset", _GOOD.replace("OFFSET 0.000000 20.000000", "OFFSET 0.000000 x", 1),
     [f"line {_SPINE_OFFSET}: non-numeric OFFSET value 'x'"]),
    ("channels-short", _GOOD.replace("Yrotation Xrotation Zrotation", "Yrotation Xrotation", 1),
     ["line 5: CHANNELS 6 of joint Hips lists 5 channel(s)"]),
    ("unclosed", _GOOD.split("MOTION")[0].rsplit("}", 1)[0] + "MOTION\n",
     ["the HIERARCHY ends early"]),
    ("no-hierarchy", "ROOT Hips\n{\n}\n", ["not a BVH file: line 1: found 'ROOT'"]),
    ("duplicate-joint", _GOOD.replace("JOINT Neck", "JOINT Spine"), ["'Spine' appears twice"]),
]  # fmt: skip


@pytest.mark.parametrize(("text", "words"), [c[1:] for c in BAD_BVH], ids=[c[0] for c in BAD_BVH])
def test_bad_bvh_is_a_one_line_error_naming_file_and_line(tmp_path, text, words):
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        bvh.parse_bvh(path)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{path}: ")
    for w in words:
        assert w in msg, (w, msg)


def test_every_damaged_variant_reads_or_is_a_one_line_error(tmp_path):
    """Each line of a good file deleted, and the file cut every 37 bytes: it reads (a finite
    recording) or raises a one-line ``InputError`` naming the file, nothing else."""
    lines = _GOOD.splitlines(keepends=True)
    variants = ["".join(lines[:i] + lines[i + 1 :]) for i in range(len(lines))]
    variants += [_GOOD[:cut] for cut in range(1, len(_GOOD), 37)]
    path = tmp_path / "damaged.bvh"
    errors = 0
    for text in variants:
        path.write_text(text)
        try:
            rec = read_skeleton(path, bvh_map=SYNTH_MAP)
        except InputError as e:
            errors += 1
            assert "\n" not in str(e) and str(e).startswith(f"{path}: "), str(e)
        else:
            assert np.isfinite(rec.positions).all()
    assert errors >= len(variants) - 5


def test_the_good_file_of_the_bad_cases_reads(tmp_path):
    path = tmp_path / "good.bvh"
    path.write_text(_GOOD.replace("\n", "\r\n"))  # Windows line ends too
    clip = bvh.parse_bvh(path)
    assert clip.n_frames == 3 and clip.lines.tolist() == [_ROW, _ROW + 1, _ROW + 2]
    nan = tmp_path / "nan.bvh"  # a non-finite value is an invalid frame, not an error
    nan.write_text(_replace_line(_GOOD, _ROW + 1, _ZEROS + " nan"))
    rec = read_skeleton(nan, bvh_map=SYNTH_MAP)
    assert rec.valid.tolist() == [True, False, True] and np.isfinite(rec.positions).all()
    assert (rec.positions[1] == 0).all()


# --- the command line ----------------------------------------------------------------------------


def test_cli_retarget_bvh_relaxed_resampled_with_plot(tmp_path, capsys, small_model):
    model = tmp_path / "p.npz"
    engine.save(small_model, model)
    out, plot = tmp_path / "m.json", tmp_path / "m.png"
    # 8.25 s at 30 fps: 248 frames, the compiled length of the tests above (256)
    code, stdout, err = _run(capsys, "retarget", DATA / CLIPS[0], "--format", "bvh", "--bvh-map",
                             "cmu", "--fps", "30", "--method", "relaxed", "--model", model,
                             "--out", out, "--plot", plot)  # fmt: skip
    assert code == 0, err
    assert "map cmu" in stdout and "resampled to 30 fps" in stdout and "[feasible]" in stdout
    assert plot.stat().st_size > 10_000 and "plot ->" in stdout
    d = json.loads(out.read_text())
    steps = np.diff(d["timeLists"][0])
    np.testing.assert_allclose(steps, 1 / 30, atol=1e-6)
    # errors: one line, exit 2, naming the file (and the flag for settings)
    bad = tmp_path / "bad.bvh"
    bad.write_text(BAD_BVH[2][1])
    code, _, err = _run(capsys, "retarget", bad, "--out", tmp_path / "x.npz")
    assert code == 2 and len(err.strip().splitlines()) == 1 and str(bad) in err
    assert f"found {_N_CH - 1} values" in err and "Traceback" not in err
    code, _, err = _run(capsys, "retarget", DATA / CLIPS[1], "--bvh-map", tmp_path / "none.json",
                        "--out", tmp_path / "x.npz")  # fmt: skip
    assert code == 2 and "not a built-in map" in err
    assert not (tmp_path / "x.npz").exists()


def test_a_folder_of_bvh_files_is_what_build_and_evaluate_read(tmp_path, capsys):
    """``--data FOLDER`` (build, evaluate) reads through ``cli._load`` -> ``load_folder``; what
    follows is format-blind (tested on Kinect folders in test_cli; evaluated on the full CMU clips
    by hand, see the README)."""
    from jaxproj.cli.options import load_data as _load

    contents = datasets.load_folder(DATA)
    assert [s.name for s in contents.sequences] == [Path(c).stem for c in CLIPS]
    assert [(s.subject, s.take) for s in contents.sequences] == [(131, 1), (131, 3)]
    assert dict(contents.skipped)["SOURCE.md"]
    for seq, name in zip(contents.sequences, CLIPS, strict=True):
        np.testing.assert_array_equal(seq.positions, read_skeleton(DATA / name).positions)
        assert seq.times is not None and seq.times[1] == pytest.approx(0.05, abs=1e-6)
    seqs, found = _load(str(DATA), [131], "test", False, "cmu")
    assert len(seqs) == 2 and found is not None and not found.unreadable
    folder = tmp_path / "mixed"
    folder.mkdir()
    (folder / "good_131_01.bvh").write_bytes((DATA / CLIPS[0]).read_bytes())
    (folder / "bad.bvh").write_text(BAD_BVH[2][1])
    contents = datasets.load_folder(folder, strict=False, bvh_map="cmu")
    assert len(contents.sequences) == 1 and contents.unreadable[0][0] == "bad.bvh"
    with pytest.raises(InputError, match="bad.bvh: line"):
        datasets.load_folder(folder)
    model = tmp_path / "p.npz"  # evaluate's command line takes the flag and reports the file
    code, _, err = _run(capsys, "evaluate", "--model", model, "--data", folder, "--bvh-map",
                        "cmu-mb", "--json", tmp_path / "r.json", "--strict")  # fmt: skip
    assert code == 2 and "p.npz" in err
