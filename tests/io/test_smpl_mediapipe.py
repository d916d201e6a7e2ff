"""NPZ of any registered skeleton (J-count dispatch, the ``skeleton`` key, ``up="z"``) and
MediaPipe Pose world landmarks (JSON, CSV, NPZ; visibility -> valid; MediaPipe's axes turned into
Kinect's). NumPy only: no model is built, the whole file runs in about a second.

The files in ``tests/data/formats/`` were written by us, following the formats guide:

- ``mediapipe_pose.json``: ``{"fps": 15, "frames": [...]}``; frame 0 a standing pose (with
  ``presence``), frame 1 the left arm raised sideways (a ``{"landmarks": ...}`` frame), frame 2
  no detection (``[]``), frame 3 the right forearm pointing at the camera with the right elbow's
  visibility 0.31. Legs have visibility 0.2 (cut off) everywhere.
- ``mediapipe_pose.csv``: the same poses under a header variant (a ``frame`` column, spaces
  after the commas, ``NOSE_*`` in upper case, ``_visibility`` columns): frames 0, 1, 2 (= JSON
  frames 0, 1, 3), 4 (frame 3 left out; = frame 0) and 5 (no detection: empty fields).
- ``mediapipe_pose.npz``: ``joints`` (3, 33, 3) and ``visibility`` (3, 33): JSON frames 0, 1, 3.
- ``smpl_24.npz``: SMPL's 24 joints, y up, ``skeleton="smpl"``, ``fps=30``; three frames (arms
  lowered 0, 30, 60 degrees, a step forward each frame).
- ``smplx_body_yup.npz``: its first 22 joints (``joints``; J = 22 -> smplx).
- ``amass_smplh_zup.npz``: the same body as SMPL-H's 52 joints, z up (AMASS), ``fps=120``.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from helpers import person_joints

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.io.formats import mediapipe, table
from jaxproj.io.readers import read_skeleton, recording_format
from jaxproj.io.text import Head

DATA = Path(__file__).resolve().parents[1] / "data" / "formats"
K = skeletons.KINECT_V1.index
ATOL = 1e-6

# MediaPipe Pose landmark numbers, from the Pose landmarker guide's figure (not from our module)
MP = {
    "nose": 0, "left_ear": 7, "right_ear": 8, "left_shoulder": 11, "right_shoulder": 12,
    "left_elbow": 13, "right_elbow": 14, "left_wrist": 15, "right_wrist": 16, "left_pinky": 17,
    "right_pinky": 18, "left_index": 19, "right_index": 20, "left_hip": 23, "right_hip": 24,
    "left_knee": 25, "right_knee": 26, "left_ankle": 27, "right_ankle": 28,
    "left_foot_index": 31, "right_foot_index": 32,
}  # fmt: skip
# Kinect v1 joint <- the mean of these MediaPipe landmarks (the formats guide's table)
FROM_MP = {
    "HipCenter": ("left_hip", "right_hip"),
    "Spine": ("left_hip", "right_hip", "left_shoulder", "right_shoulder"),
    "ShoulderCenter": ("left_shoulder", "right_shoulder"),
    "Head": ("left_ear", "right_ear"),
    **{
        f"{kj}{side.title()}": (f"{side}_{mj}",)
        for side in ("left", "right")
        for kj, mj in (("Shoulder", "shoulder"), ("Elbow", "elbow"), ("Wrist", "wrist"),
                       ("Hip", "hip"), ("Knee", "knee"), ("Ankle", "ankle"),
                       ("Foot", "foot_index"))
    },
    "HandLeft": ("left_index", "left_pinky"),
    "HandRight": ("right_index", "right_pinky"),
}  # fmt: skip


def expected_kinect(landmarks: np.ndarray) -> np.ndarray:
    """(33, 3) MediaPipe world landmarks -> (20, 3) Kinect v1 positions, by hand: each joint
    the mean of its landmarks, turned (x, y, z) -> (-x, -y, z)."""
    out = np.zeros((20, 3))
    for joint, parts in FROM_MP.items():
        out[K[joint]] = landmarks[[MP[p] for p in parts]].mean(axis=0)
    return out * [-1.0, -1.0, 1.0]


def json_frames() -> list[np.ndarray | None]:
    """The JSON test file's frames as (33, 3) arrays (None: no detection), read with json."""
    doc = json.loads((DATA / "mediapipe_pose.json").read_text())
    frames = []
    for f in doc["frames"]:
        lms = f["landmarks"] if isinstance(f, dict) else f
        frames.append(np.array([[lm[c] for c in "xyz"] for lm in lms]) if lms else None)
    return frames


def npz_bytes(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def write(path: Path, content: str | bytes) -> Path:
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return path


def body_frame_bones(positions: np.ndarray) -> np.ndarray:
    """(T, 20, 3) Kinect v1 -> (T, 4, 3) unit upper-arm and forearm directions in the body frame
    (forward, left, up), computed here with NumPy (the descriptor's definition)."""
    p = positions.astype(np.float64)
    up = p[:, K["ShoulderCenter"]] - p[:, K["HipCenter"]]
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    left = p[:, K["ShoulderLeft"]] - p[:, K["ShoulderRight"]]
    left -= (left * up).sum(-1, keepdims=True) * up
    left /= np.linalg.norm(left, axis=-1, keepdims=True)
    rot = np.stack([np.cross(left, up), left, up], axis=1)  # rows: forward, left, up
    pairs = [("ShoulderLeft", "ElbowLeft"), ("ElbowLeft", "WristLeft"),
             ("ShoulderRight", "ElbowRight"), ("ElbowRight", "WristRight")]  # fmt: skip
    d = np.stack([p[:, K[b]] - p[:, K[a]] for a, b in pairs], axis=1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.einsum("tij,tbj->tbi", rot, d)


# --- MediaPipe JSON ------------------------------------------------------------------------------


def test_mediapipe_json_frames_wrappers_visibility_and_timing() -> None:
    rec = read_skeleton(DATA / "mediapipe_pose.json")
    assert (rec.format, rec.skeleton) == ("mediapipe", "mediapipe_pose")
    assert rec.positions.shape == (4, 20, 3) and rec.positions.dtype == np.float32
    # frame 2: no detection; frame 3: the right elbow's visibility 0.31 < 0.5
    np.testing.assert_array_equal(rec.valid, [True, True, False, False])
    assert not rec.positions[2:].any()
    np.testing.assert_allclose(rec.times, np.arange(4) / 15.0, rtol=0, atol=1e-12)
    assert rec.time_source == "file (15 fps)"
    frames = json_frames()
    for t in (0, 1):
        np.testing.assert_allclose(rec.positions[t], expected_kinect(frames[t]), atol=ATOL)


def test_mediapipe_axes_are_turned_into_a_right_handed_kinect_frame(tmp_path: Path) -> None:
    # frame 3 (the right forearm pointing at the camera) with its visibility taken out
    doc = json.loads((DATA / "mediapipe_pose.json").read_text())
    pose = [{k: lm[k] for k in "xyz"} for lm in doc["frames"][3]]
    rec = read_skeleton(write(tmp_path / "one.json", json.dumps([pose])))
    assert rec.valid.all() and rec.time_source == "assumed 30 fps"
    p = rec.positions[0]
    assert p[K["Head"], 1] > p[K["ShoulderCenter"], 1] > p[K["HipCenter"], 1]  # y up
    assert p[K["ShoulderLeft"], 0] < p[K["ShoulderRight"], 0]  # facing the camera: left at -x
    assert p[K["WristRight"], 2] < p[K["ElbowRight"], 2] - 0.2  # nearer the camera: smaller z
    # the body frame's forward (left x up) points at the camera, and so does the right forearm
    bones = body_frame_bones(rec.positions)[0]
    np.testing.assert_allclose(bones[3], [1.0, 0.0, 0.0], atol=0.15)  # right forearm: forward
    np.testing.assert_allclose(bones[1], [0.0, 0.0, -1.0], atol=0.2)  # left forearm: down


def test_mediapipe_json_bare_list_null_and_empty_landmarks_frames(tmp_path: Path) -> None:
    frames = json_frames()
    pose = [{"x": x, "y": y, "z": z} for x, y, z in frames[0].tolist()]
    nan_pose = [dict(lm) for lm in pose]
    nan_pose[MP["left_elbow"]]["x"] = None  # a missing value: the frame is invalid
    doc = [pose, None, {"landmarks": []}, {"landmarks": pose, "timestamp_ms": 99}, nan_pose]
    rec = read_skeleton(write(tmp_path / "list.dat", json.dumps(doc)), format="auto")
    assert rec.format == "mediapipe"
    np.testing.assert_array_equal(rec.valid, [True, False, False, True, False])
    np.testing.assert_array_equal(rec.positions[0], rec.positions[3])
    np.testing.assert_allclose(rec.positions[0], expected_kinect(frames[0]), atol=ATOL)


# --- MediaPipe CSV -------------------------------------------------------------------------------


def test_mediapipe_csv_header_variant_frame_numbers_and_no_detection() -> None:
    rec = read_skeleton(DATA / "mediapipe_pose.csv")
    assert (rec.format, rec.skeleton) == ("mediapipe", "mediapipe_pose")
    np.testing.assert_array_equal(rec.valid, [True, True, False, True, False])
    np.testing.assert_allclose(rec.times, np.array([0, 1, 2, 4, 5]) / 30.0, rtol=0, atol=1e-12)
    assert rec.time_source == "frame numbers at 30 fps"
    js = read_skeleton(DATA / "mediapipe_pose.json")
    np.testing.assert_array_equal(rec.positions[:2], js.positions[:2])
    np.testing.assert_array_equal(rec.positions[3], js.positions[0])
    assert read_skeleton(DATA / "mediapipe_pose.csv", fps=10).times[-1] == pytest.approx(0.4)


def _csv(columns: list[str], rows: list[list[float]]) -> str:
    return ",".join(columns) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows)


def test_mediapipe_csv_without_visibility_in_any_column_order(tmp_path: Path) -> None:
    pose = json_frames()[1]
    names = mediapipe.LANDMARKS
    columns = [f"{n}_{c}" for n in names for c in "zyx"][::-1] + [f"{n}_presence" for n in names]
    row = [pose[names.index(c.rsplit("_", 1)[0]), "xyz".index(c[-1])] for c in columns[:99]]
    rec = read_skeleton(write(tmp_path / "p.csv", _csv(columns, [row + [0.0] * 33])))
    assert rec.valid.all()  # no visibility: nothing checked; presence is ignored
    np.testing.assert_allclose(rec.positions[0], expected_kinect(pose), atol=ATOL)


# --- visibility ---------------------------------------------------------------------------------


def test_visibility_checks_the_upper_body_and_frame_landmarks_only(tmp_path: Path) -> None:
    assert mediapipe.CHECKED_LANDMARKS == (
        "left_ear", "right_ear", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
        "left_wrist", "right_wrist", "left_hip", "right_hip",
    )  # fmt: skip
    pose = json_frames()[0]
    for name in mediapipe.LANDMARKS:
        vis = {n: 0.9 for n in mediapipe.LANDMARKS} | {name: 0.49}
        xyz = zip(mediapipe.LANDMARKS, pose.tolist(), strict=True)
        doc = [[{"x": x, "y": y, "z": z, "visibility": vis[n]} for n, (x, y, z) in xyz]]
        rec = read_skeleton(write(tmp_path / "v.json", json.dumps(doc)))
        assert rec.valid[0] == (name not in mediapipe.CHECKED_LANDMARKS), name


def test_visibility_of_zeros_only_is_no_visibility(tmp_path: Path) -> None:
    pose = json_frames()[0]
    doc = [[{"x": x, "y": y, "z": z, "visibility": 0} for x, y, z in pose.tolist()]] * 2
    rec = read_skeleton(write(tmp_path / "zeros.json", json.dumps(doc)))
    assert rec.valid.all()


# --- NPZ: MediaPipe, J dispatch, skeleton key, up ------------------------------------------------


def test_mediapipe_npz_matches_the_json() -> None:
    rec = read_skeleton(DATA / "mediapipe_pose.npz")
    assert (rec.format, rec.skeleton, rec.time_source) == (
        "npz",
        "mediapipe_pose",
        "assumed 30 fps",
    )
    np.testing.assert_array_equal(rec.valid, [True, True, False])  # visibility (T, 33)
    js = read_skeleton(DATA / "mediapipe_pose.json")
    np.testing.assert_allclose(rec.positions[:2], js.positions[:2], atol=ATOL)


# Kinect v1 joint -> the skeleton's joint at its place (from each SDK's joint table)
PLACES = {
    "kinect_v1": {"Head": 3, "ShoulderCenter": 2, "Spine": 1, "HandLeft": 7},
    "kinect_v2": {"Head": 3, "ShoulderCenter": 20, "Spine": 1, "HandLeft": 7},
    "azure_kinect": {"Head": 26, "ShoulderCenter": 3, "Spine": 1, "HandLeft": 8},
    "smpl": {"Head": 15, "ShoulderCenter": 12, "Spine": 6, "HandLeft": 22},
    "smplx": {"Head": 15, "ShoulderCenter": 12, "Spine": 6, "HipCenter": 0, "WristLeft": 20},
}


@pytest.mark.parametrize(
    ("n_joints", "name"),
    [(20, "kinect_v1"), (22, "smplx"), (24, "smpl"), (25, "kinect_v2"), (32, "azure_kinect"),
     (33, "mediapipe_pose"), (45, "smpl"), (52, "smplx"), (55, "smplx"), (73, "smplx"),
     (127, "smplx"), (144, "smplx")],
)  # fmt: skip
def test_npz_joint_count_says_the_skeleton(tmp_path: Path, n_joints: int, name: str) -> None:
    own = person_joints(name, seed=n_joints)  # a person's joints in that skeleton's layout
    rest = np.random.default_rng(n_joints).uniform(-1, 1, size=(2, n_joints - own.shape[1], 3))
    joints = np.concatenate([own, rest], axis=1)  # the smplx package's longer arrays
    key = "joints" if n_joints % 2 else "positions"
    rec = read_skeleton(write(tmp_path / "j.npz", npz_bytes(**{key: joints})))
    assert rec.skeleton == name and rec.positions.shape == (2, 20, 3) and rec.valid.all()
    # the guess is never silent: the recording says it, and how to say otherwise
    assert rec.skeleton_from == "count"
    assert f"skeleton {name} guessed from the joint count ({n_joints})" in rec.notes[0]
    assert "--skeleton NAME" in rec.notes[0]
    # the same array as .npy (HumanML3D's format) reads the same
    buf = io.BytesIO()
    np.save(buf, joints)
    npy = read_skeleton(write(tmp_path / "j.npy", buf.getvalue()))
    assert (npy.format, npy.skeleton, npy.notes) == ("npy", name, rec.notes)
    np.testing.assert_array_equal(npy.positions, rec.positions)
    for kj, sj in PLACES.get(name, {}).items():
        np.testing.assert_allclose(rec.positions[:, K[kj]], joints[:, sj], atol=ATOL)


def test_npz_skeleton_key_names_the_layout(tmp_path: Path) -> None:
    rec = read_skeleton(DATA / "smpl_24.npz")
    assert (rec.skeleton, rec.time_source) == ("smpl", "file (30 fps)")
    with np.load(DATA / "smpl_24.npz") as z:
        smpl = z["positions"]
    np.testing.assert_allclose(rec.positions[:, K["HandLeft"]], smpl[:, 22], atol=ATOL)
    # the SMPL-X body of the same motion: no hands, so the hand continues the forearm
    body = read_skeleton(DATA / "smplx_body_yup.npz")
    assert body.skeleton == "smplx"
    np.testing.assert_array_equal(
        body.positions[:, K["WristLeft"]], rec.positions[:, K["WristLeft"]]
    )
    fore = smpl[:, 20] - smpl[:, 18]
    want = smpl[:, 20] + skeletons.FILL_FRACTION * fore
    np.testing.assert_allclose(body.positions[:, K["HandLeft"]], want, atol=ATOL)
    # a full SMPL-X joint array named by its key, as bytes
    full = np.concatenate([smpl[:, :22], np.zeros((3, 33, 3))], axis=1)
    named = npz_bytes(joints=full, skeleton=np.bytes_(b"smplx"))
    rec55 = read_skeleton(write(tmp_path / "x.npz", named))
    np.testing.assert_array_equal(rec55.positions, body.positions)


def test_up_z_turns_amass_into_its_y_up_twin() -> None:
    yup = read_skeleton(DATA / "smplx_body_yup.npz")
    zup = read_skeleton(DATA / "amass_smplh_zup.npz", up="z")
    assert zup.skeleton == "smplx" and zup.time_source == "file (120 fps)"
    np.testing.assert_allclose(zup.positions, yup.positions, atol=ATOL)
    as_is = read_skeleton(DATA / "amass_smplh_zup.npz")  # read as if y-up: positions differ...
    assert np.abs(as_is.positions - yup.positions).max() > 0.5
    # ... but not the bones in the body's own frame, which the descriptor reads
    np.testing.assert_allclose(body_frame_bones(as_is.positions), body_frame_bones(yup.positions),
                               atol=1e-5)  # fmt: skip
    np.testing.assert_allclose(table.z_up_to_y_up([[1.0, 2.0, 3.0]]), [[1.0, 3.0, -2.0]])


def test_up_must_be_y_or_z_and_mediapipe_has_its_own_axes() -> None:
    with pytest.raises(ConfigError, match="up must be 'y' or 'z'"):
        read_skeleton(DATA / "smpl_24.npz", up="x")
    with pytest.raises(ConfigError, match="MediaPipe"):
        read_skeleton(DATA / "mediapipe_pose.npz", up="z")
    assert read_skeleton(DATA / "mediapipe_pose.json", up="z").valid[0]  # JSON: ignored


# --- detection -----------------------------------------------------------------------------------


def test_detection_by_content_and_no_clash_with_other_json_and_csv(tmp_path: Path) -> None:
    for name in ("mediapipe_pose.json", "mediapipe_pose.csv", "mediapipe_pose.npz", "smpl_24.npz"):
        data = (DATA / name).read_bytes()
        copy = write(tmp_path / f"{name}.dat", data)
        want = "npz" if name.endswith(".npz") else "mediapipe"
        assert recording_format(copy) == (want, ""), name
        assert recording_format(DATA / name) == (want, ""), name
    kinect_csv = ",".join(["0.5"] * 60) + "\n"
    assert not mediapipe.sniff(Head(tmp_path / "k.csv", kinect_csv.encode(), complete=True))[0]
    assert not table.sniff_csv(Head(tmp_path / "m.csv", (DATA / "mediapipe_pose.csv").read_bytes(),
                                    complete=True))[0]  # fmt: skip
    azure = {"frames": [{"bodies": [{"joint_positions": [[1.0, 2.0, 3.0]] * 32}]}]}
    recognised, why = mediapipe.sniff(Head(tmp_path / "a.json", json.dumps(azure).encode(), True))
    assert not recognised and "MediaPipe" in why
    npz = npz_bytes(angles=np.zeros((2, 26)))
    assert recording_format(write(tmp_path / "motion.npz", npz))[0] is None


# --- bad files -----------------------------------------------------------------------------------

_JSON = (DATA / "mediapipe_pose.json").read_text()
_CSV = (DATA / "mediapipe_pose.csv").read_text()
_CSV_LINES = _CSV.splitlines()
_POSE = [{"x": 0.1 * i, "y": -0.01 * i, "z": 0.0} for i in range(33)]


def _json(frames: object) -> str:
    return json.dumps(frames)


BAD_FILES: list[tuple[str, str, str | bytes, str, list[str]]] = [
    # (id, file name, content, format, words of the one-line message); "mediapipe": a JSON whose
    # start holds no landmark object is recognised by no format (named on its own, it says so)
    ("json-truncated", "t.json", _JSON[: len(_JSON) // 2], "auto", ["line ", "not valid JSON"]),
    (
        "json-32-landmarks",
        "n.json",
        _json([_POSE, _POSE[:32]]),
        "auto",
        ["frame 1", "found 32 landmarks"],
    ),
    (
        "json-no-z",
        "z.json",
        _json([[{"x": 0, "y": 0}] * 33]),
        "mediapipe",
        ["frame 0", "(nose) has no z"],
    ),
    (
        "json-string",
        "s.json",
        _json([[{**p, "y": "nan"} for p in _POSE]]),
        "auto",
        ["frame 0", "number"],
    ),
    (
        "json-no-frames-key",
        "k.json",
        _json({"poses": []}),
        "mediapipe",
        ["needs key 'frames'", "poses"],
    ),
    ("json-empty", "e.json", "[]", "mediapipe", ["no frames"]),
    (
        "json-no-detection",
        "d.json",
        _json([[], None, {"landmarks": []}]),
        "mediapipe",
        ["no pose detected"],
    ),
    ("json-undetected", "u.json", _json([[], None]), "auto", ["cannot detect", "no recording"]),
    ("json-several-poses", "m.json", _json([[_POSE, _POSE]]), "auto", ["frame 0", "several poses"]),
    (
        "json-visibility-logit",
        "v.json",
        _json([_POSE, [{**p, "visibility": 3.2} for p in _POSE]]),
        "auto",
        ["frame 1", "'nose'", "3.2", "[0, 1]"],
    ),
    ("json-fps", "f.json", _json({"frames": [_POSE], "fps": 0}), "auto", ["fps must be"]),
    (
        "csv-truncated",
        "t.csv",
        "\n".join(_CSV_LINES[:3]) + "\n" + _CSV_LINES[3][:200],
        "auto",
        ["line 4", "columns, expected 133"],
    ),
    (
        "csv-unknown-column",
        "u.csv",
        _CSV.replace("left_eye_x", "left_eye_w", 1),
        "auto",
        ["line 1, column 10", "'left_eye_w'"],
    ),
    (
        "csv-missing-column",
        "m.csv",
        _CSV.replace(", left_eye_z,", ",", 1),
        "auto",
        ["line 1", "no column left_eye_z"],
    ),
    (
        "csv-token",
        "tok.csv",
        _CSV.replace("-0.620", "-O.620", 1),
        "auto",
        ["line 2", "non-numeric", "'-O.620'"],
    ),
    (
        "csv-frames-back",
        "b.csv",
        _CSV.replace("\n4, ", "\n1, ", 1),
        "auto",
        ["line 5", "does not increase"],
    ),
    ("csv-header-only", "h.csv", _CSV_LINES[0] + "\n", "auto", ["no data rows"]),
    ("csv-no-header", "n.csv", "\n".join(_CSV_LINES[1:]), "mediapipe", ["line 1", "no header"]),
    (
        "csv-visibility",
        "v.csv",
        _CSV.replace(", 0.31,", ", 1.31,", 1),
        "auto",
        ["line 4", "'right_elbow'", "1.31"],
    ),
    (
        "csv-no-detection",
        "d.csv",
        _CSV_LINES[0] + "\n" + _CSV_LINES[-1] + "\n",
        "auto",
        ["no pose detected"],
    ),
    (
        "npz-unknown-j",
        "j.npz",
        npz_bytes(joints=np.ones((2, 15, 3))),
        "auto",
        ["15 joints", "add a 'skeleton' key", "33 mediapipe_pose"],
    ),
    (
        "npz-unknown-skeleton",
        "s.npz",
        npz_bytes(joints=np.ones((2, 24, 3)), skeleton=np.str_("smpl_h")),
        "auto",
        ["'smpl_h' is not a registered skeleton", "smplx"],
    ),
    (
        "npz-skeleton-count",
        "c.npz",
        npz_bytes(joints=np.ones((2, 22, 3)), skeleton=np.str_("smpl")),
        "auto",
        ["22 joints", "'smpl' records 24 or 45"],
    ),
    (
        "npz-skeleton-type",
        "t.npz",
        npz_bytes(joints=np.ones((2, 24, 3)), skeleton=np.arange(2)),
        "auto",
        ["skeleton must be one string"],
    ),
    (
        "npz-visibility-shape",
        "v.npz",
        npz_bytes(joints=np.ones((2, 33, 3)), visibility=np.ones((2, 32))),
        "auto",
        ["visibility has shape (2, 32)"],
    ),
    (
        "npz-visibility-range",
        "r.npz",
        npz_bytes(joints=np.ones((2, 33, 3)), visibility=np.full((2, 33), -1.0)),
        "auto",
        ["frame 0", "not a probability"],
    ),
    ("npz-truncated", "x.npz", (DATA / "smpl_24.npz").read_bytes()[:300], "auto", ["corrupt"]),
    (
        "npz-amass-parameters",
        "a.npz",
        npz_bytes(poses=np.zeros((2, 156)), betas=np.zeros(16), trans=np.zeros((2, 3))),
        "auto",
        ["missing key 'positions' or 'joints'", "poses", "save the model's joint positions"],
    ),
]


@pytest.mark.parametrize(
    ("name", "content", "fmt", "words"),
    [c[1:] for c in BAD_FILES],
    ids=[c[0] for c in BAD_FILES],
)
def test_bad_file_is_a_one_line_input_error(
    tmp_path: Path, name: str, content: str | bytes, fmt: str, words: list[str]
) -> None:
    path = write(tmp_path / name, content)
    with pytest.raises(InputError) as info:
        read_skeleton(path, format=fmt)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    for word in words:
        assert word in message, (word, message)
    err = info.value
    assert err.__cause__ is None and (err.__context__ is None or err.__suppress_context__)


def test_nan_and_non_finite_values_are_invalid_frames_not_errors(tmp_path: Path) -> None:
    joints = np.tile(json_frames()[0], (3, 1, 1))
    joints[1, MP["left_shoulder"], 0] = np.nan
    joints[2, MP["nose"], 2] = np.inf
    rec = read_skeleton(write(tmp_path / "nan.npz", npz_bytes(joints=joints)))
    np.testing.assert_array_equal(rec.valid, [True, False, True])  # the nose feeds no joint
    rows = _CSV_LINES[:2] + [_CSV_LINES[1].replace("-0.620", "nan", 1).replace("0, ", "1, ", 1)]
    csv = read_skeleton(write(tmp_path / "nan.csv", "\n".join(rows) + "\n"))
    np.testing.assert_array_equal(csv.valid, [True, True])  # the nose again
    rows[2] = rows[2].replace("0.170", "nan", 1)  # left shoulder x
    csv = read_skeleton(write(tmp_path / "nan2.csv", "\n".join(rows) + "\n"))
    np.testing.assert_array_equal(csv.valid, [True, False])
