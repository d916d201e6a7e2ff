"""Robot-motion files (jaxproj.io.motion_files): NPZ / CSV / NAOqi JSON round trips, atomic writes,
and one-line errors naming the file."""

import csv
import json
import math
import os

import numpy as np
import pytest

from jaxproj.errors import ConfigError, InputError
from jaxproj.io import motion_files as motion_io
from jaxproj.io.motion_files import Motion, load_motion, save_motion
from jaxproj.robots.nao_h25 import robot
from jaxproj.robots.nao_h25.naoqi import UPPER_JOINTS

# float32 values whose shortest decimal form is a trap for naive formatting: -0.0, subnormals,
# the extremes, and neighbours one ulp apart
_TRICKY = np.array(
    [-0.0, 1e-45, -1.4e-45, 1.1754944e-38, 3.4028235e38, -3.4028235e38, 0.1, 1 / 3, 2.0857,
     np.nextafter(np.float32(2.0857), np.float32(3)), 1e-8, 123456.79],
    dtype=np.float32,
)  # fmt: skip


def _motion(n: int = 40, t0: float = 12.345, positions: bool = True) -> Motion:
    """Random float32 angles (the tricky values in the first frames), irregular float64 times
    starting at ``t0``, two invalid frames, NaN positions at one of them, some meta."""
    rng = np.random.default_rng(7)
    angles = (robot.STANDING_POSTURE + rng.normal(0.0, 0.8, (n, robot.N_JOINTS))).astype(np.float32)
    angles.ravel()[: _TRICKY.size] = _TRICKY
    times = t0 + np.cumsum(rng.uniform(0.02, 0.1, n))
    valid = np.ones(n, dtype=bool)
    valid[[3, n - 2]] = False
    pos = None
    if positions:
        pos = rng.normal(0.0, 0.5, (n, 20, 3)).astype(np.float32)
        pos[n - 2] = np.nan
    meta = {"method": "relaxed", "smoothed": True, "feasible": False, "fps": 30, "scale": 0.5}
    return Motion(angles=angles, times=times, valid=valid, positions=pos, meta=meta)


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def test_npz_round_trip_is_lossless(tmp_path):
    m = _motion()
    out = save_motion(tmp_path / "m.npz", m)
    assert out == tmp_path / "m.npz" and out.is_file()
    back = load_motion(out)
    np.testing.assert_array_equal(_bits(back.angles), _bits(m.angles))
    assert back.angles.dtype == np.float32 and back.times.dtype == np.float64
    np.testing.assert_array_equal(back.times, m.times)
    np.testing.assert_array_equal(back.valid, m.valid)
    np.testing.assert_array_equal(_bits(back.positions), _bits(m.positions))  # NaNs included
    assert dict(back.meta) == dict(m.meta)
    assert [type(back.meta[k]) for k in m.meta] == [type(v) for v in m.meta.values()]
    with np.load(out) as z:
        assert set(z.files) == {"angles", "times", "valid", "joint_names", "positions", "meta"}
        assert list(z["joint_names"]) == list(robot.JOINT_NAMES)
        assert json.loads(str(z["meta"])) == dict(m.meta)
    # without positions there is no positions key
    out2 = save_motion(tmp_path / "n.npz", _motion(positions=False))
    with np.load(out2) as z:
        assert "positions" not in z.files
    assert load_motion(out2).positions is None


def test_csv_round_trip_is_bit_exact_and_plain(tmp_path):
    m = _motion()  # angles far outside the joint ranges: margin=None writes them as they are
    out = save_motion(tmp_path / "m.csv", m, margin=None)
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time", *robot.JOINT_NAMES]
    assert len(rows) == m.n_frames + 1 and all(len(r) == 27 for r in rows)
    assert all(not r[0].startswith("#") for r in rows)  # no comment lines
    back = load_motion(out)
    np.testing.assert_array_equal(_bits(back.angles), _bits(m.angles))
    np.testing.assert_array_equal(back.times, m.times)  # exact, float64
    assert back.valid.all() and back.positions is None and dict(back.meta) == {}
    # readable values: the shortest float32 form where it is exact (0.1 -> "0.1")
    assert rows[1][1 + 6] == "0.1"


@pytest.mark.parametrize("ext", [".csv", ".json"])
def test_robot_files_hold_angles_a_margin_inside_the_limits(tmp_path, ext):
    """CSV and NAOqi JSON hold every angle EXPORT_MARGIN inside [lower, upper] (a strict
    URDF-limit check passes) and HeadPitch inside the head envelope; angles already inside
    are written bit-exactly; the NPZ keeps the motion's own angles."""
    m = _motion()  # frame 0 holds huge values, others normal(0.8 rad) noise: many beyond a limit
    margin = motion_io.EXPORT_MARGIN
    assert margin == 2e-4
    out = save_motion(tmp_path / f"m{ext}", m, joints="body")
    back = load_motion(out).angles.astype(np.float64)
    lo, hi = robot.LOWER.astype(np.float64), robot.UPPER.astype(np.float64)
    assert (back >= lo + margin).all() and (back <= hi - margin).all()
    env_lo = np.interp(back[:, 0], robot.HEAD_ENVELOPE_YAW, robot.HEAD_ENVELOPE_PITCH_MIN)
    env_hi = np.interp(back[:, 0], robot.HEAD_ENVELOPE_YAW, robot.HEAD_ENVELOPE_PITCH_MAX)
    assert (back[:, 1] >= env_lo - 1e-6).all() and (back[:, 1] <= env_hi + 1e-6).all()
    inside = (m.angles >= lo + margin) & (m.angles <= hi - margin)
    inside[:, 1] = False  # HeadPitch also depends on the (clipped) HeadYaw
    assert 0.2 < inside.mean() < 0.9  # the test motion has both kinds
    np.testing.assert_array_equal(_bits(back.astype(np.float32))[inside], _bits(m.angles)[inside])
    moved = ~inside
    moved[:, 1] = False
    assert (back[moved] != m.angles[moved]).all()  # outside the margin band: clipped
    np.testing.assert_array_equal(
        _bits(load_motion(save_motion(tmp_path / "m.npz", m)).angles), _bits(m.angles)
    )
    with pytest.raises(ConfigError, match="margin"):
        save_motion(tmp_path / f"x{ext}", m, margin=0.6)  # HeadPitch's range is 1.19 rad
    with pytest.raises(ConfigError, match="margin"):
        save_motion(tmp_path / f"x{ext}", m, margin=-1e-4)


def test_exact_strings_read_back_bit_exactly():
    rng = np.random.default_rng(1)
    values = rng.standard_normal(20000).astype(np.float32) * np.float32(3.0)
    values = np.concatenate([values, _TRICKY])
    text = motion_io.exact_strings(values)
    back = np.array([float(s) for s in text]).astype(np.float32)
    np.testing.assert_array_equal(_bits(back), _bits(values))


@pytest.mark.parametrize("joints", ["upper", "body", ["RElbowRoll", "HeadYaw", "LKneePitch"]])
def test_json_is_naoqi_angle_interpolation(tmp_path, joints):
    m = _motion()
    out = save_motion(tmp_path / "m.json", m, joints=joints, lead_in=1.5, margin=None)
    with open(out) as fh:
        doc = json.load(fh)
    assert set(doc) == {"names", "angleLists", "timeLists", "isAbsolute", "jaxproj"}
    sets = {"upper": list(UPPER_JOINTS), "body": list(robot.JOINT_NAMES)}
    want = sets[joints] if isinstance(joints, str) else joints
    assert doc["names"] == want
    assert doc["isAbsolute"] is True
    assert len(doc["angleLists"]) == len(doc["timeLists"]) == len(doc["names"])
    for angles, times in zip(doc["angleLists"], doc["timeLists"], strict=True):
        assert len(angles) == len(times) == m.n_frames
        assert all(type(v) is float and math.isfinite(v) for v in angles + times)
        assert times[0] == 1.5 and all(b > a for a, b in zip(times, times[1:], strict=False))
    assert doc["jaxproj"]["t0"] == m.times[0] and doc["jaxproj"]["lead_in_s"] == 1.5
    assert doc["jaxproj"]["joints"] == joints
    assert doc["jaxproj"]["method"] == "relaxed"
    back = load_motion(out)
    idx = [robot.IDX[n] for n in want]
    others = [i for i in range(robot.N_JOINTS) if i not in idx]
    np.testing.assert_array_equal(_bits(back.angles[:, idx]), _bits(m.angles[:, idx]))
    np.testing.assert_array_equal(
        back.angles[:, others],
        np.broadcast_to(robot.STANDING_POSTURE[others], (m.n_frames, 26 - len(idx))),
    )
    np.testing.assert_allclose(back.times, m.times, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.valid, m.valid)
    assert dict(back.meta) == dict(m.meta)
    assert back.positions is None


def test_json_upper_joints_are_the_naoqi_head_and_arm_chains():
    assert UPPER_JOINTS == (
        "HeadYaw", "HeadPitch",
        "LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll", "LWristYaw", "LHand",
        "RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll", "RWristYaw", "RHand",
    )  # fmt: skip
    order = [robot.IDX[n] for n in UPPER_JOINTS]
    assert order == sorted(order)


def test_hand_written_naoqi_json_loads(tmp_path):
    """Without a jaxproj block: NAOqi's times as they are, one shared time list allowed."""
    path = tmp_path / "wave.json"
    doc = {
        "names": ["RShoulderPitch", "RElbowRoll"],
        "angleLists": [[-1.0, -1.2, -1.0], [1.0, 0.5, 1]],
        "timeLists": [0.5, 1.0, 1.5],
        "isAbsolute": True,
    }
    path.write_text(json.dumps(doc))
    m = load_motion(path)
    np.testing.assert_array_equal(m.times, [0.5, 1.0, 1.5])
    np.testing.assert_array_equal(m.angles[:, robot.IDX["RElbowRoll"]], np.float32([1.0, 0.5, 1]))
    np.testing.assert_array_equal(m.angles[1, :2], robot.STANDING_POSTURE[:2])
    assert m.valid.all() and m.fps == pytest.approx(2.0)


def test_retarget_npz_without_times_loads_at_the_default_rate(tmp_path):
    path = tmp_path / "r.npz"
    angles = np.tile(robot.STANDING_POSTURE, (4, 1))
    np.savez(path, angles=angles, joint_names=np.array(robot.JOINT_NAMES),
             valid=np.array([True, False, True, True]), method=np.array("ik"),
             smoothed=np.array(True))  # fmt: skip
    m = load_motion(path)
    np.testing.assert_allclose(m.times, np.arange(4) / motion_io.DEFAULT_FPS)
    assert m.valid.tolist() == [True, False, True, True]
    assert dict(m.meta) == {"method": "ik", "smoothed": True}


def _fail_mid_write(*args, **kwargs):
    fh = args[0]
    fh.write(b"PK\x03\x04 half an archive")
    raise OSError(28, "No space left on device")


def test_write_is_atomic_when_the_writer_fails(tmp_path, monkeypatch):
    target = tmp_path / "m.npz"
    target.write_bytes(b"old content")
    monkeypatch.setattr(np.lib.format, "write_array", _fail_mid_write)
    with pytest.raises(InputError) as e:
        save_motion(target, _motion())
    assert str(target) in str(e.value) and "No space left" in str(e.value)
    assert sorted(os.listdir(tmp_path)) == ["m.npz"]  # no temporary file left
    assert target.read_bytes() == b"old content"
    # and a fresh target is not created at all
    with pytest.raises(InputError):
        save_motion(tmp_path / "new.npz", _motion())
    assert sorted(os.listdir(tmp_path)) == ["m.npz"]


def test_write_is_atomic_when_the_rename_fails(tmp_path, monkeypatch):
    def refuse(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", refuse)
    for name in ("m.json", "m.csv"):
        with pytest.raises(InputError, match="Permission denied") as e:
            save_motion(tmp_path / name, _motion())
        assert str(tmp_path / name) in str(e.value)
    assert os.listdir(tmp_path) == []


def test_write_into_an_impossible_folder(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ConfigError, match="is not a folder") as e:
        save_motion(blocker / "m.json", _motion())
    assert str(blocker / "m.json") in str(e.value)
    assert sorted(os.listdir(tmp_path)) == ["file"]


@pytest.mark.parametrize("ext", ["npz", "csv", "json"])
def test_no_folder_is_created(tmp_path, ext):
    """A missing folder is the CLI's error (``--out``), not a folder made on the fly: a typo
    such as ``/nope/x.json`` once created ``/nope``."""
    target = tmp_path / "a" / "b" / f"m.{ext}"
    with pytest.raises(ConfigError) as e:
        save_motion(target, _motion())
    msg = str(e.value)
    assert msg.startswith(f"{target}: folder {target.parent} does not exist"), msg
    assert "creates no folder" in msg and "\n" not in msg
    assert os.listdir(tmp_path) == []


def test_save_rejects_bad_settings(tmp_path):
    m = _motion()
    with pytest.raises(ConfigError, match=r"\.npz, \.csv, \.json"):
        save_motion(tmp_path / "m.txt", m)
    with pytest.raises(ConfigError, match="unknown joint"):
        save_motion(tmp_path / "m.json", m, joints=["HeadYaw", "Tail"])
    with pytest.raises(ConfigError, match="joints must be one of"):
        save_motion(tmp_path / "m.json", m, joints="legs")
    with pytest.raises(ConfigError, match="lead_in"):
        save_motion(tmp_path / "m.json", m, lead_in=0.0)
    bad_meta = Motion(m.angles, m.times, m.valid, meta={"t0": 1.0})
    with pytest.raises(ConfigError, match="reserved"):
        save_motion(tmp_path / "m.json", bad_meta)
    assert os.listdir(tmp_path) == []


def test_motion_validates_itself():
    m = _motion(n=5, positions=False)
    a, t, v = m.angles, m.times, m.valid
    with pytest.raises(ConfigError, match=r"\(T, 26\)"):
        Motion(a[:, :10], t, v)
    nan = a.copy()
    nan[2, 3] = np.nan
    with pytest.raises(ConfigError, match="frame 2"):
        Motion(nan, t, v)
    with pytest.raises(ConfigError, match="increase strictly"):
        Motion(a, t[::-1], v)
    with pytest.raises(ConfigError, match="finite"):
        Motion(a, np.array([0, 1, 2, 3, np.inf]), v)
    with pytest.raises(ConfigError, match="bool"):
        Motion(a, t, v.astype(int))
    with pytest.raises(ConfigError, match="positions"):
        Motion(a, t, v, positions=np.zeros((5, 20, 2)))
    with pytest.raises(ConfigError, match="meta"):
        Motion(a, t, v, meta={"x": [1, 2]})
    with pytest.raises(ConfigError, match="at least one frame"):
        Motion(a[:0], t[:0], v[:0])
    # arrays are copied, typed and read-only
    m2 = Motion(a.astype(np.float64), t.astype(np.float32), v)
    assert m2.angles.dtype == np.float32 and m2.times.dtype == np.float64
    with pytest.raises(ValueError):
        m2.angles[0, 0] = 1.0
    assert m.fps == pytest.approx(1.0 / np.median(np.diff(t)))


def _npz(path, **arrays):
    base = {
        "angles": np.zeros((3, 26), np.float32),
        "joint_names": np.array(robot.JOINT_NAMES),
        "times": np.array([0.0, 0.1, 0.2]),
    }
    base.update(arrays)
    np.savez(path, **{k: v for k, v in base.items() if v is not None})


def _json(path, **changes):
    doc = {
        "names": ["HeadYaw", "HeadPitch"],
        "angleLists": [[0.0, 0.1], [0.2, 0.3]],
        "timeLists": [[1.0, 2.0], [1.0, 2.0]],
        "isAbsolute": True,
    }
    doc.update(changes)
    path.write_text(json.dumps({k: v for k, v in doc.items() if v is not None}))


_HEADER = "time," + ",".join(robot.JOINT_NAMES)
_ROW = ",".join(["0.0"] * 27)

BAD_FILES = {
    "missing.npz": (None, "no such file"),
    "no_angles.npz": (lambda p: _npz(p, angles=None), "missing key 'angles'"),
    "shape.npz": (lambda p: _npz(p, angles=np.zeros((3, 25))), r"\(T, 26\)"),
    "name.npz": (
        lambda p: _npz(p, joint_names=np.array(("Tail",) + robot.JOINT_NAMES[1:])),
        "unknown joint names",
    ),
    "times.npz": (lambda p: _npz(p, times=np.array([0.0, 0.2, 0.1])), "increase strictly"),
    "nan.npz": (lambda p: _npz(p, angles=np.full((3, 26), np.nan)), "frame 0: angles"),
    "garbage.npz": (lambda p: p.write_bytes(b"not a zip"), "not a readable .npz"),
    "text.csv": (lambda p: p.write_text(f"{_HEADER}\n{_ROW}\n0.1,abc{',0' * 25}\n"), "line 3"),
    "ragged.csv": (lambda p: p.write_text(f"{_HEADER}\n{_ROW}\n0.1,0\n"), "expected 27 columns"),
    "joint.csv": (lambda p: p.write_text("time,Tail\n0.0,1.0\n"), "unknown joint names"),
    "header.csv": (lambda p: p.write_text(f"{_ROW}\n{_ROW}\n"), "header"),
    "empty.csv": (lambda p: p.write_text(""), "empty file"),
    "order.csv": (
        lambda p: p.write_text(f"{_HEADER}\n{_ROW}\n{_ROW}\n"),
        "increase strictly",
    ),
    "keys.json": (lambda p: _json(p, timeLists=None), r"missing keys \['timeLists'\]"),
    "ragged.json": (lambda p: _json(p, angleLists=[[0.0, 0.1], [0.2]]), "1 angles for 2 times"),
    "count.json": (lambda p: _json(p, angleLists=[[0.0, 0.1]]), "list of 2 lists"),
    "joint.json": (lambda p: _json(p, names=["HeadYaw", "Tail"]), "unknown joint names"),
    "twice.json": (lambda p: _json(p, names=["HeadYaw", "HeadYaw"]), "repeated"),
    "type.json": (lambda p: _json(p, angleLists=[[0.0, "x"], [0.2, 0.3]]), "must hold numbers"),
    "relative.json": (lambda p: _json(p, isAbsolute=False), "isAbsolute"),
    "times.json": (lambda p: _json(p, timeLists=[[2.0, 1.0], [2.0, 1.0]]), "increase strictly"),
    "bases.json": (lambda p: _json(p, timeLists=[[1.0, 2.0], [1.0, 3.0]]), "one time base"),
    "broken.json": (lambda p: p.write_text("{'names': "), "not valid JSON"),
    "list.json": (lambda p: p.write_text("[1, 2]"), "JSON object"),
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_files_raise_input_error_naming_the_file(tmp_path, name):
    make, problem = BAD_FILES[name]
    path = tmp_path / name
    if make is not None:
        make(path)
    with pytest.raises(InputError, match=problem) as e:
        load_motion(path)
    msg = str(e.value)
    assert msg.startswith(str(path)) and "\n" not in msg


def test_load_rejects_an_unknown_extension(tmp_path):
    with pytest.raises(ConfigError, match=r"\.npz, \.csv, \.json"):
        load_motion(tmp_path / "m.bvh")


@pytest.mark.parametrize("ext", [".npz", ".json"])
def test_confidence_round_trips(tmp_path, ext):
    n = 6
    angles = np.tile(robot.STANDING_POSTURE, (n, 1)).astype(np.float32)
    conf = np.array([0.0, 0.25, 1 / 3, 0.9999, 1.0, 0.5], np.float32)
    m = Motion(angles, np.arange(n) / 15.0, np.ones(n, bool), confidence=conf)
    back = load_motion(save_motion(tmp_path / f"m{ext}", m))
    np.testing.assert_array_equal(back.confidence, conf)
    plain = load_motion(save_motion(tmp_path / f"p{ext}", Motion(angles, m.times, m.valid)))
    assert plain.confidence is None
    with pytest.raises(ConfigError, match=r"confidence must lie in \[0, 1\]; frame 2"):
        Motion(angles, m.times, m.valid, confidence=np.array([0, 1, 1.5, 0, 0, 0], np.float32))


def test_the_csv_is_time_and_the_robots_joints_only(tmp_path):
    """A robot's tool reads the CSV: time + every joint in the robot's SDK order, nothing else;
    a CSV with the confidence column jaxproj 0.2.0 wrote still reads."""
    n = 4
    angles = np.tile(robot.STANDING_POSTURE, (n, 1)).astype(np.float32)
    conf = np.array([0.0, 0.5, 1.0, 0.25], np.float32)
    m = Motion(angles, np.arange(n) / 15.0, np.ones(n, bool), confidence=conf)
    path = save_motion(tmp_path / "m.csv", m, margin=None)
    lines = path.read_text().splitlines()
    assert lines[0].split(",") == ["time", *robot.JOINT_NAMES] and len(lines) == n + 1
    assert all(len(line.split(",")) == 1 + robot.N_JOINTS for line in lines)
    assert load_motion(path).confidence is None
    legacy = tmp_path / "old.csv"
    rows = [f"{row},{c}" for row, c in zip(lines[1:], conf, strict=True)]
    legacy.write_text("\n".join([lines[0] + ",confidence", *rows]))
    back = load_motion(legacy)
    np.testing.assert_array_equal(back.confidence, conf)
    np.testing.assert_array_equal(back.angles, angles)


@pytest.mark.parametrize("ext", [".npz", ".csv"])
def test_load_motion_finds_the_robot_by_its_joint_names(tmp_path, ext):
    """Without robot=, a file's joint names say whose motion it is (a G1 file reads as the G1,
    the NAO's and a subset of its joints as the NAO); names of no robot are an InputError."""
    from jaxproj import robots

    for r in map(robots.get, robots.names()):
        q = np.tile(r.standing, (3, 1)).astype(np.float32)
        q[1] = np.clip(q[1] + 0.1, r.lower + 1e-3, r.upper - 1e-3)
        m = Motion(q, np.arange(3) / 30.0, np.ones(3, bool), robot=r)
        back = load_motion(save_motion(tmp_path / f"{r.name}{ext}", m, margin=None))
        assert back.robot is r
        np.testing.assert_array_equal(back.angles, q)
    head = tmp_path / f"head{ext}"  # two of the default robot's joints: the others standing
    cols = ["HeadYaw", "HeadPitch"]
    if ext == ".csv":
        head.write_text("time,HeadYaw,HeadPitch\n0.0,0.1,0.2\n")
    else:
        np.savez(head, angles=np.array([[0.1, 0.2]], np.float32), joint_names=np.array(cols))
    assert load_motion(head).robot is robots.get()
    bad = tmp_path / f"bad{ext}"
    if ext == ".csv":
        bad.write_text("time,left_knee_joint,HeadYaw\n0.0,0.1,0.2\n")
    else:
        np.savez(bad, angles=np.zeros((1, 2), np.float32),
                 joint_names=np.array(["left_knee_joint", "HeadYaw"]))  # fmt: skip
    with pytest.raises(InputError, match=r"unknown joint names \['left_knee_joint'\]"):
        load_motion(bad)
