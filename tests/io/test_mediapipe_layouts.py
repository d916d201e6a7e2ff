"""MediaPipe Pose as the public tools save it (issue 60, "Real files"): TensorFlow.js
``keypoints3D`` dumps, the JavaScript Pose solution's ``poseWorldLandmarks``, the Tasks API's
``worldLandmarks`` / ``pose_world_landmarks``, CSV of one row per landmark and of one row per
frame under the common header spellings; recognised by content, each read to the same positions
as the same landmarks in ``tests/data/formats/mediapipe_pose.json`` (the layout read already).
The near misses are one-line errors that say what to change; a frame refused for visibility
says whose (the reader's ``invalid_reason``, quoted by ``jaxproj retarget``).

Every file is written here, in tmp_path, in the layout the tool writes (the module docstring of
``jaxproj.io.formats.mediapipe`` cites the sources). NumPy only, except the last test, which runs
the CLI up to its refusal (nothing is traced).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from jaxproj.errors import InputError
from jaxproj.io.formats import mediapipe
from jaxproj.io.readers import read_skeleton, recording_format

DATA = Path(__file__).resolve().parents[1] / "data" / "formats"
NAMES = mediapipe.LANDMARKS
LEFT_HIP, RIGHT_HIP = NAMES.index("left_hip"), NAMES.index("right_hip")


def reference() -> tuple[list[list[dict[str, float]] | None], Any]:
    """The reference file's frames (33 landmark dicts, or None: no detection) and its reading.

    Frames 0 and 1 are valid poses, 2 has no detection, 3 has the right elbow's visibility
    0.31 (invalid); every landmark has a visibility."""
    doc = json.loads((DATA / "mediapipe_pose.json").read_text())
    frames = []
    for f in doc["frames"]:
        lms = f["landmarks"] if isinstance(f, dict) else f
        frames.append([{k: lm[k] for k in ("x", "y", "z", "visibility")} for lm in lms] or None)
    return frames, read_skeleton(DATA / "mediapipe_pose.json")


def write(path: Path, content: str) -> Path:
    path.write_text(content)
    return path


def same_as_reference(rec: Any, frames: list[int] | None = None) -> None:
    """``rec`` reads the reference's frames (all, or those listed) to the same positions."""
    _, ref = reference()
    keep = list(range(len(ref.valid))) if frames is None else frames
    assert (rec.format, rec.skeleton) == ("mediapipe", "mediapipe_pose")
    np.testing.assert_array_equal(rec.valid, ref.valid[keep])
    np.testing.assert_allclose(rec.positions, ref.positions[keep], rtol=0, atol=1e-6)


def image_landmarks(pose: list[dict[str, float]]) -> list[dict[str, float]]:
    """Image coordinates of a pose (x, y in [0, 1], as ``poseLandmarks``): other numbers."""
    return [{**lm, "x": 0.5 + 0.4 * lm["x"], "y": 0.55 + 0.4 * lm["y"]} for lm in pose]


def tfjs_pose(pose: list[dict[str, float]]) -> dict[str, Any]:
    """One pose as ``detector.estimatePoses`` returns it (BlazePose, then JSON.stringify):
    ``keypoints`` in pixels, ``keypoints3D`` the world landmarks, ``score`` the visibility."""
    kp = [
        {"x": 640 * lm["x"], "y": 480 * lm["y"], "z": lm["z"], "score": lm["visibility"],
         "name": name}
        for lm, name in zip(image_landmarks(pose), NAMES, strict=True)
    ]  # fmt: skip
    kp3 = [
        {"x": lm["x"], "y": lm["y"], "z": lm["z"], "score": lm["visibility"], "name": name}
        for lm, name in zip(pose, NAMES, strict=True)
    ]
    return {"score": 0.97, "keypoints": kp, "keypoints3D": kp3, "segmentation": {}}


# --- JSON ----------------------------------------------------------------------------------------


def test_tfjs_estimate_poses_dump_lists_of_poses_and_pose_objects(tmp_path: Path) -> None:
    frames, _ = reference()
    # a list over frames of estimatePoses' return value: [pose] or [] (no detection)
    dump = [[tfjs_pose(f)] if f else [] for f in frames]
    path = write(tmp_path / "poses.json", json.dumps(dump))
    assert recording_format(path) == ("mediapipe", "")
    same_as_reference(read_skeleton(path))
    # frames as objects with keypoints3D (a timestamp beside; no detection: an empty list)
    objects = [
        {"timestamp": 33.3 * t, **(tfjs_pose(f) if f else {"keypoints3D": []})}
        for t, f in enumerate(frames)
    ]
    same_as_reference(read_skeleton(write(tmp_path / "objects.json", json.dumps(objects))))


def test_mediapipe_js_pose_solution_results(tmp_path: Path) -> None:
    """``pose.onResults(results)``: ``poseWorldLandmarks`` read, ``poseLandmarks`` not; a frame
    saved without a pose (JSON.stringify leaves undefined out: ``{}``) has no detection."""
    frames, _ = reference()
    dump = [
        {"poseLandmarks": image_landmarks(f), "poseWorldLandmarks": f} if f else {} for f in frames
    ]
    path = write(tmp_path / "results.json", json.dumps(dump))
    assert recording_format(path) == ("mediapipe", "")
    same_as_reference(read_skeleton(path))


def test_tasks_api_pose_landmarker_results_js_and_python(tmp_path: Path) -> None:
    frames, _ = reference()
    js = [
        {"landmarks": [image_landmarks(f)] if f else [], "worldLandmarks": [f] if f else []}
        for f in frames
    ]
    same_as_reference(read_skeleton(write(tmp_path / "tasks.json", json.dumps(js))))
    # Python: dataclasses.asdict(result), landmarks with presence (and name None)
    py = [
        {
            "pose_landmarks": [image_landmarks(f)] if f else [],
            "pose_world_landmarks": [[{**lm, "presence": 0.9, "name": None} for lm in f]]
            if f
            else [],
        }
        for f in frames
    ]
    path = write(tmp_path / "tasks.dat", json.dumps({"fps": 15, "frames": py}))
    assert recording_format(path) == ("mediapipe", "")
    rec = read_skeleton(path)
    same_as_reference(rec)
    assert rec.time_source == "file (15 fps)"
    # one result alone: one frame
    one = read_skeleton(write(tmp_path / "one.json", json.dumps(js[1])))
    same_as_reference(one, [1])


# --- CSV -----------------------------------------------------------------------------------------


def rows_per_landmark(frames: list[list[dict[str, float]] | None]) -> list[tuple[int, int, dict]]:
    """(frame number, landmark number, landmark) for every detected frame: what a loop over
    ``enumerate(landmarks)`` writes; a frame without detection writes no row."""
    return [(t, j, lm) for t, f in enumerate(frames) if f for j, lm in enumerate(f)]


def test_csv_one_row_per_landmark_names_and_numbers(tmp_path: Path) -> None:
    frames, _ = reference()
    # csv.writer, header frame,landmark,x,y,z,visibility; mp_pose.PoseLandmark(j).name
    buf = io.StringIO()
    out = csv.writer(buf)
    out.writerow(["frame", "landmark", "x", "y", "z", "visibility"])
    for t, j, lm in rows_per_landmark(frames):
        out.writerow([t, NAMES[j].upper(), lm["x"], lm["y"], lm["z"], lm["visibility"]])
    path = write(tmp_path / "long.csv", buf.getvalue())
    assert recording_format(path) == ("mediapipe", "")
    rec = read_skeleton(path)
    same_as_reference(rec, [0, 1, 3])  # frame 2: no rows
    np.testing.assert_allclose(rec.times, np.array([0, 1, 3]) / 30.0)
    assert rec.time_source == "frame numbers at 30 fps"
    # pandas DataFrame.to_csv (its unnamed index first), 0-based landmark_id, a presence and a
    # timestamp column, the landmarks of a frame in another order
    lines = [",frame_id,timestamp,landmark_id,x,y,z,visibility,presence"]
    rows = sorted(rows_per_landmark(frames), key=lambda r: (r[0], -r[1]))
    for i, (t, j, lm) in enumerate(rows):
        lines.append(f"{i},{t},{t * 33},{j},{lm['x']},{lm['y']},{lm['z']},{lm['visibility']},0.0")
    same_as_reference(read_skeleton(write(tmp_path / "df.csv", "\n".join(lines))), [0, 1, 3])
    # PoseLandmark.NAME strings and 1-based numbers
    enum = ["frame_number,name,x,y,z"] + [
        f"{t},PoseLandmark.{NAMES[j].upper()},{lm['x']},{lm['y']},{lm['z']}"
        for t, j, lm in rows_per_landmark(frames)
    ]
    one_based = ["frame,id,x,y,z,v"] + [
        f"{t},{j + 1},{lm['x']},{lm['y']},{lm['z']},{lm['visibility']}"
        for t, j, lm in rows_per_landmark(frames)
    ]
    no_vis = read_skeleton(write(tmp_path / "enum.csv", "\n".join(enum)))
    assert no_vis.valid.all()  # no visibility: frame 3 (the elbow at 0.31) is not checked
    _, ref = reference()
    np.testing.assert_allclose(no_vis.positions[:2], ref.positions[:2], atol=1e-6)
    same_as_reference(read_skeleton(write(tmp_path / "one.csv", "\n".join(one_based))), [0, 1, 3])


def wide_header(style: str, fields: str = "xyzv") -> list[str]:
    names = {
        "x1": lambda j, c: f"{c}{j + 1}",  # the "body language decoder" notebooks: 1-based
        "x0": lambda j, c: f"{c}{j}",
        "x_0": lambda j, c: f"{c}_{j}",
        "landmark_0_x": lambda j, c: f"landmark_{j}_{'visibility' if c == 'v' else c}",
        "nose_x": lambda j, c: f"{NAMES[j]}_{'visibility' if c == 'v' else c}",
    }[style]
    return [names(j, c) for j in range(33) for c in fields]


@pytest.mark.parametrize("style", ["x1", "x0", "x_0", "landmark_0_x"])
def test_csv_one_row_per_frame_numbered_headers(tmp_path: Path, style: str) -> None:
    frames, _ = reference()
    detected = [t for t, f in enumerate(frames) if f]
    head = ["class", *wide_header(style)] if style == "x1" else ["frame", *wide_header(style)]
    lines = [",".join(head)]
    for t in detected:
        first = "waving" if style == "x1" else str(t)
        values = [frames[t][j][k] for j in range(33) for k in ("x", "y", "z", "visibility")]  # type: ignore[index]
        lines.append(",".join([first, *map(str, values)]))
    path = write(tmp_path / "wide.csv", "\n".join(lines) + "\n")
    assert recording_format(path) == ("mediapipe", "")
    rec = read_skeleton(path)
    same_as_reference(rec, detected)
    want = "assumed 30 fps" if style == "x1" else "frame numbers at 30 fps"
    assert rec.time_source == want


# --- near misses: one line that says what to change ----------------------------------------------


def _pose() -> list[dict[str, float]]:
    frames, _ = reference()
    assert frames[0] is not None
    return frames[0]


def _near_misses() -> list[tuple[str, str, str, list[str]]]:
    pose = _pose()
    numbers = ",".join(str(lm[k]) for lm in pose for k in ("x", "y", "z", "visibility"))
    hand = ",".join(f"{c}{j}" for j in range(21) for c in "xyz")
    no_z = ",".join(wide_header("x_0", "xyv"))
    long_rows = "\n".join(f"0,{j},{lm['x']},{lm['y']},{lm['z']}" for j, lm in enumerate(pose))
    image_rows = "\n".join(
        f"0,{j},{lm['x']},{lm['y']},{lm['z']}" for j, lm in enumerate(image_landmarks(pose))
    )
    movenet = [[{"score": 0.8, "keypoints": [{"x": 10.0, "y": 20.0, "score": 0.9,
                                              "name": "nose"}] * 17}]]  # fmt: skip
    return [
        # (id, file name, content, words of the message)
        ("csv-headerless-132", "n.csv", numbers + "\n" + numbers + "\n",
         ["line 1: no header line", "132 numbers", "x0,y0,z0,v0,x1,y1,z1,v1,...,x32,y32,z32,v32"]),
        ("csv-hand-21", "h.csv", hand + "\n" + ",".join(["0.1"] * 63) + "\n",
         ["line 1", "21 landmarks", "33"]),
        ("csv-wide-no-z", "z.csv", no_z + "\n" + ",".join(["0.1"] * 99) + "\n",
         ["line 1", "no z column", "x, y and z"]),
        ("csv-long-no-frame", "f.csv", "landmark,x,y,z\n" + long_rows.replace("0,", "", 33),
         ["line 1", "needs a frame column", "frame_id"]),
        ("csv-long-missing-landmark", "m.csv",
         "frame,landmark,x,y,z\n" + "\n".join(long_rows.splitlines()[:-1]),
         ["line 2", "no row for landmark 32 (right_foot_index)"]),
        ("csv-long-unknown-landmark", "u.csv", "frame,landmark,x,y,z\n0,LEFT_FOOT,1,2,3\n",
         ["line 2", "'LEFT_FOOT'", "neither"]),
        ("csv-image-landmarks", "i.csv", "frame,landmark,x,y,z\n" + image_rows,
         ["image landmarks", "normalised", "pose_world_landmarks"]),
        ("json-pose-landmarks-only", "p.json", json.dumps([{"poseLandmarks": pose}]),
         ["frame 0", "'poseLandmarks' (image coordinates)", "'poseWorldLandmarks'"]),
        ("json-tasks-landmarks-only", "t.json", json.dumps([{"landmarks": [pose]}]),
         ["frame 0", "image", "worldLandmarks"]),
        ("json-tfjs-two-poses", "2.json",
         json.dumps([[tfjs_pose(pose), tfjs_pose(pose)]]), ["frame 0", "several poses (2)"]),
        ("json-movenet", "mn.json", json.dumps(movenet), ["cannot detect", "keypoints3D"]),
        ("json-keyless", "k.json", json.dumps([{"time": 0, "pose": pose}, {"time": 1}]),
         ["frame 0", "needs one of the keys", "'keypoints3D'", "keys found: time, pose"]),
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("name", "content", "words"),
    [c[1:] for c in _near_misses()],
    ids=[c[0] for c in _near_misses()],
)
def test_near_misses_are_one_line_errors(
    tmp_path: Path, name: str, content: str, words: list[str]
) -> None:
    path = write(tmp_path / name, content)
    with pytest.raises(InputError) as info:
        read_skeleton(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    for word in words:
        assert word in message, (word, message)


def test_kinect_csv_and_other_files_are_not_claimed(tmp_path: Path) -> None:
    kinect = write(tmp_path / "k.csv", ",".join(["0.5"] * 60) + "\n")
    assert recording_format(kinect) == ("csv", "")
    other = write(tmp_path / "points.csv", "id,x,y\n1,2,3\n")
    assert recording_format(other)[0] is None
    labels = write(tmp_path / "labels.csv", "name,class\nwalk,1\n")
    assert recording_format(labels)[0] is None


# --- visibility: the frames refused, and why ----------------------------------------------------


def hips_hidden_dump(n: int = 130) -> str:
    """A desk webcam: the upper body seen, the hips half out of view (visibility 0.26-0.34),
    as a TensorFlow.js keypoints3D dump."""
    pose = _pose()
    rng = np.random.default_rng(60)
    dump = []
    for _ in range(n):
        p = [dict(lm) for lm in pose]
        for j in (LEFT_HIP, RIGHT_HIP):
            p[j]["visibility"] = float(rng.uniform(0.26, 0.34))
        dump.append([tfjs_pose(p)])
    dump[5][0]["keypoints3D"][LEFT_HIP]["score"] = 0.26  # the range's ends, exactly
    dump[6][0]["keypoints3D"][LEFT_HIP]["score"] = 0.34
    return json.dumps(dump)


def test_frames_refused_for_visibility_say_whose(tmp_path: Path) -> None:
    assert mediapipe.VISIBILITY_THRESHOLD == 0.5
    rec = read_skeleton(write(tmp_path / "desk.json", hips_hidden_dump()))
    assert not rec.valid.any()
    reason = rec.invalid_reason
    assert reason is not None and reason.startswith(
        "visibility below 0.5 in 130 of the file's 130 frames, of left_hip (130 frames, "
        "0.26-0.34), right_hip (130 frames, 0."
    ), reason
    # the reference: frame 2 without a pose, frame 3 the right elbow at 0.31
    _, ref = reference()
    assert ref.invalid_reason == (
        "visibility below 0.5 in 1 of the file's 4 frames, of right_elbow (1 frame, 0.31); "
        "no pose detected in 1 frame"
    )
    frames, _ = reference()
    good = [f for f in frames if f][:2]
    assert read_skeleton(write(tmp_path / "ok.json", json.dumps(good))).invalid_reason is None


def test_retarget_names_visibility_and_the_landmarks(tmp_path: Path, capsys) -> None:
    """A robot that reads the legs (the G1) needs the hips: the message says whose visibility
    (the NAO, which reads no leg bone, gets hips made from the shoulders: test_upper_body)."""
    from jaxproj.cli import main

    src = write(tmp_path / "desk.json", hips_hidden_dump())
    out = tmp_path / "o.npz"
    assert main(["retarget", str(src), "--robot", "unitree_g1", "--out", str(out)]) == 2
    _, err = capsys.readouterr()
    assert not out.exists()
    line = err.strip()
    assert line.startswith(
        f"jaxproj: error: {src}: no valid frame among 130: 130 marked invalid (visibility below "
        "0.5 in 130 of the file's 130 frames, of left_hip (130 frames, 0.26-0.34), right_hip "
        "(130 frames, 0."
    ), line
    assert line.endswith("); nothing written") and "lost tracking" not in line
