"""Tests of the NTU RGB+D (``formats.ntu``) and Azure Kinect (``formats.azure_kinect``) readers on
the hand-made files of ``tests/data/formats`` (``README_ntu_azure.md`` there lists what each frame
holds) and on broken copies of them. NumPy only: nothing here builds a model or compiles."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import J
from jaxproj.io.formats import ntu
from jaxproj.io.readers import read_skeleton, recording_format

DATA = Path(__file__).resolve().parents[1] / "data" / "formats"
NTU_FILE = DATA / "S001C001P001R001A001.skeleton"
AZURE_FILE = DATA / "take_01_k4abt.json"

V2 = skeletons.get("kinect_v2").index
AZ = skeletons.get("azure_kinect").index


def ntu_lines() -> list[str]:
    """The NTU sample's lines (CRLF line ends dropped)."""
    return NTU_FILE.read_text().splitlines()


def ntu_raw_bodies() -> list[list[np.ndarray]]:
    """An independent walk of the NTU sample: per frame, per body, ``(25, 12)`` float64."""
    lines = ntu_lines()
    i, frames = 1, []
    for _ in range(int(lines[0])):
        n, i = int(lines[i]), i + 1
        bodies = []
        for _ in range(n):
            assert len(lines[i].split()) == 10 and lines[i + 1] == "25"
            rows = [list(map(float, line.split())) for line in lines[i + 2 : i + 27]]
            bodies.append(np.array(rows))
            i += 27
        frames.append(bodies)
    assert i == len(lines)
    return frames


def azure_doc() -> dict:
    return json.loads(AZURE_FILE.read_text())


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def one_line_error(path: Path, **kwargs) -> str:
    """The message of the ``InputError`` reading ``path`` raises, checked to be one line that
    starts with the file's name."""
    with pytest.raises(InputError) as info:
        read_skeleton(path, **kwargs)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    return message


# --- NTU RGB+D --------------------------------------------------------------------------------


def test_ntu_reads_the_first_body_as_kinect_v1_at_30_fps() -> None:
    rec = read_skeleton(NTU_FILE)
    assert (rec.format, rec.skeleton) == ("ntu", "kinect_v2")
    assert rec.positions.shape == (5, 20, 3) and rec.positions.dtype == np.float32
    # frame 2 has nobody; frame 3's AnkleLeft is not tracked; frame 0's feet are only inferred
    # and frame 4's hand tips not tracked (they do not feed Kinect v1): those stay valid
    np.testing.assert_array_equal(rec.valid, [True, True, False, False, True])
    np.testing.assert_array_equal(rec.positions[~rec.valid], 0.0)
    np.testing.assert_allclose(rec.times, np.arange(5) / 30.0)
    assert rec.time_source == "assumed 30 fps" and rec.fps == pytest.approx(30.0)
    rec15 = read_skeleton(NTU_FILE, fps=15)
    np.testing.assert_allclose(rec15.times, np.arange(5) / 15.0)
    assert rec15.time_source == "given 15 fps"


def test_ntu_kinect_v1_layout_takes_the_v2_joints_at_the_same_places() -> None:
    raw = ntu_raw_bodies()
    rec = read_skeleton(NTU_FILE)
    for f in np.flatnonzero(rec.valid):
        xyz = raw[f][0][:, :3]
        for v1, v2 in [("Head", "Head"), ("ShoulderCenter", "SpineShoulder"),
                       ("HipCenter", "SpineBase"), ("Spine", "SpineMid"),
                       ("WristLeft", "WristLeft"), ("HandRight", "HandRight"),
                       ("FootLeft", "FootLeft")]:  # fmt: skip
            np.testing.assert_allclose(rec.positions[f, J[v1]], xyz[V2[v2]], atol=1e-6)
    # v2's own Neck is not Kinect v1's ShoulderCenter (the neck bone starts at the spine top)
    assert np.abs(raw[0][0][V2["Neck"], :3] - rec.positions[0, J["ShoulderCenter"]]).max() > 0.05


def test_ntu_body_choice_picks_the_frames_nth_body() -> None:
    raw = ntu_raw_bodies()
    second = read_skeleton(NTU_FILE, body=1)
    np.testing.assert_array_equal(second.valid, [False, True, False, False, True])
    np.testing.assert_allclose(second.positions[1, J["Head"]], raw[1][1][V2["Head"], :3], atol=1e-6)
    first = read_skeleton(NTU_FILE, body=0)
    np.testing.assert_array_equal(first.positions, read_skeleton(NTU_FILE).positions)
    assert np.abs(second.positions[1] - first.positions[1]).max() > 0.9  # another person
    message = one_line_error(NTU_FILE, body=2)
    assert "no frame has body 2" in message and "at most 2 bodies" in message


@pytest.mark.parametrize("body", [-1, "second", True, 1.0, None])
def test_a_bad_body_choice_is_a_config_error(body) -> None:
    with pytest.raises(ConfigError, match="body must be 'first' or a 0-based index"):
        read_skeleton(NTU_FILE, body=body)


def ntu_copy(tmp_path: Path, lines: list[str], name: str = "edited.skeleton") -> Path:
    return write(tmp_path / name, "\n".join(lines) + "\n")


# lines (0-based) of the NTU sample: frame 0 = body count 1, then its body line 2, joint count 3
# and joints 4..28; frame 1 = count 29, bodies at 30 and 57; frame 2 = count 84 (no body);
# frame 3 = count 85, body 86; frame 4 = count 113, bodies at 114 and 141; 168 lines.
F0_JOINT0, F3_JOINT0 = 4, 88


def _replace(lines: list[str], k: int, text: str) -> list[str]:
    return [*lines[:k], text, *lines[k + 1 :]]


def _last_token(lines: list[str], k: int, token: str) -> list[str]:
    return _replace(lines, k, " ".join([*lines[k].split()[:-1], token]))


@pytest.mark.parametrize(("state", "valid"), [(0, False), (1, True), (2, True)])
def test_ntu_valid_mask_follows_the_tracking_state_of_the_joints_kinect_v1_reads(
    tmp_path: Path, state: int, valid: bool
) -> None:
    feeding = {int(i) for i in skeletons.get("kinect_v2").kinect_v1_sources}
    assert feeding == set(range(21)) - {V2["Neck"]}  # not Neck, the hand tips or the thumbs
    lines = _last_token(ntu_lines(), F0_JOINT0 + V2["ElbowRight"], str(state))
    assert bool(read_skeleton(ntu_copy(tmp_path, lines)).valid[0]) is valid
    # no Kinect v1 joint comes from a thumb: its state does not matter
    lines = _last_token(ntu_lines(), F0_JOINT0 + V2["ThumbLeft"], "0")
    assert read_skeleton(ntu_copy(tmp_path, lines)).valid[0]


def test_ntu_parse_keeps_every_body_of_every_frame() -> None:
    bodies = ntu.parse_ntu(NTU_FILE, NTU_FILE.read_bytes())
    raw = ntu_raw_bodies()
    assert bodies.n_frames == 5 and bodies.joints.shape == (6, 25, 12)
    np.testing.assert_array_equal(bodies.frame, [0, 1, 1, 3, 4, 4])
    np.testing.assert_array_equal(bodies.slot, [0, 0, 1, 0, 0, 1])
    np.testing.assert_array_equal(bodies.joints[2], raw[1][1])
    assert bodies.joint_lines[0, 0] == F0_JOINT0 + 1  # 1-based
    assert bodies.info[0, 0] == pytest.approx(72057594037931101)


def test_ntu_is_detected_by_content_and_a_coordinate_nan_only_invalidates_its_frame(
    tmp_path: Path,
) -> None:
    lines = ntu_lines()
    assert recording_format(NTU_FILE) == ("ntu", "")
    assert recording_format(ntu_copy(tmp_path, lines, "take.txt")) == ("ntu", "")
    lines = _last_token(lines, F3_JOINT0 + V2["AnkleLeft"], "2")  # frame 3 made valid
    np.testing.assert_array_equal(
        read_skeleton(ntu_copy(tmp_path, lines)).valid, [True, True, False, True, True]
    )
    k = F3_JOINT0 + V2["Head"]
    lines = _replace(lines, k, "nan " + " ".join(lines[k].split()[1:]))
    rec = read_skeleton(ntu_copy(tmp_path, lines))
    np.testing.assert_array_equal(rec.valid, [True, True, False, False, True])


NTU_BAD = {  # name -> (edit of the sample's lines, what the message says)
    "truncated": (lambda ls: ls[:-10], "frame 4: the file ends at line 158 inside this frame"),
    "truncated-in-a-line": (
        lambda ls: [*ls[:-1], " ".join(ls[-1].split()[:5])],
        "frame 4: line 168: found 5 values, expected 12",
    ),
    "joint-count": (
        lambda ls: _replace(ls, 31, "20"),
        "frame 1: line 32: joint count 20, expected 25",
    ),
    "tracking-nan": (
        lambda ls: _last_token(ls, 10, "nan"),
        "frame 0: line 11: trackingState nan is not 0 (not tracked), 1 (inferred) or 2",
    ),
    "tracking-3": (lambda ls: _last_token(ls, 60, "3"), "frame 1: line 61: trackingState 3"),
    "count-nan": (lambda ls: _replace(ls, 84, "nan"), "line 85: expected frame 2's body count"),
    "frame-count-float": (lambda ls: _replace(ls, 0, "5.0"), "line 1: expected the frame count"),
    "malformed-number": (
        lambda ls: _replace(ls, 5, ls[5].replace("0.3000000", "0.30o0000")),
        "line 6, column 2: non-numeric token '0.30o0000'",
    ),
    "malformed-body-line": (
        lambda ls: _replace(ls, 2, ls[2].replace("0.02764709", "lean")),
        "line 3, column 8: non-numeric token 'lean'",
    ),
    "short-body-line": (
        lambda ls: _replace(ls, 57, " ".join(ls[57].split()[:9])),
        "frame 1: line 58: found 9 values, expected 10 (body 1 of the 2",
    ),
    "body-count-too-high": (
        lambda ls: _replace(ls, 85, "2"),
        "frame 3: line 114: found 1 values, expected 10 (body 1 of the 2",
    ),
    "extra-lines": (lambda ls: [*ls, "1"], "line 169: more lines after the 5 frames"),
    "no-frames": (lambda ls: ["0"], "line 1: the frame count is 0"),
    "no-body": (lambda ls: ["3", "0", "0", "0"], "no body in any of the 3 frames"),
}


@pytest.mark.parametrize("case", sorted(NTU_BAD))
def test_a_bad_ntu_file_is_one_line_naming_the_file_and_the_line(tmp_path: Path, case: str) -> None:
    edit, expected = NTU_BAD[case]
    path = ntu_copy(tmp_path, edit(ntu_lines()))
    message = one_line_error(path)
    assert f"{path}: {expected}" in message, message


# --- Azure Kinect ---------------------------------------------------------------------------


def azure_copy(tmp_path: Path, doc: dict, name: str = "edited.json") -> Path:
    return write(tmp_path / name, json.dumps(doc, indent=4))


def test_azure_reads_metres_in_kinect_axes_with_times_from_the_timestamps() -> None:
    rec = read_skeleton(AZURE_FILE)
    assert (rec.format, rec.skeleton) == ("azure_kinect", "azure_kinect")
    assert rec.positions.shape == (5, 20, 3) and rec.positions.dtype == np.float32
    # frame 2: nobody; frame 3: WRIST_LEFT has confidence 0; frame 0's hand tips and frame 4's
    # ANKLE_LEFT are predicted (1) and frame 4's EAR_RIGHT is 0 (no Kinect v1 joint): valid
    np.testing.assert_array_equal(rec.valid, [True, True, False, False, True])
    stamps = [f["timestamp_usec"] for f in azure_doc()["frames"]]
    np.testing.assert_allclose(rec.times, (np.array(stamps) - stamps[0]) / 1e6)
    assert rec.times[3] == pytest.approx(0.133333)  # frame_id 3 was dropped: a gap
    assert rec.time_source == "file (timestamp_usec)"
    np.testing.assert_allclose(read_skeleton(AZURE_FILE, fps=10).times, np.arange(5) / 10)
    # millimetres, x right and y down -> metres, x left and y up (a turn about z)
    body = azure_doc()["frames"][0]["bodies"][0]
    head_mm = np.array(body["joint_positions"][AZ["HEAD"]])
    np.testing.assert_allclose(rec.positions[0, J["Head"]], head_mm * [-1e-3, -1e-3, 1e-3], 1e-6)
    assert rec.positions[0, J["Head"], 1] > rec.positions[0, J["HipCenter"], 1]  # head up
    assert rec.positions[0, J["ShoulderLeft"], 0] < rec.positions[0, J["ShoulderRight"], 0]


def test_azure_kinect_v1_layout_matches_the_ntu_recording_of_the_same_poses() -> None:
    # the two samples hold the same people (azure_kinect's spine top is NECK, its spine middle
    # SPINE_NAVEL; the clavicle joints are not read), the Azure one in mm and camera axes
    ntu_rec, az_rec = read_skeleton(NTU_FILE), read_skeleton(AZURE_FILE)
    np.testing.assert_array_equal(az_rec.valid, ntu_rec.valid)
    np.testing.assert_allclose(az_rec.positions, ntu_rec.positions, atol=1e-6)
    second = read_skeleton(AZURE_FILE, body=1)
    np.testing.assert_array_equal(second.valid, [False, True, False, False, True])
    np.testing.assert_allclose(second.positions[1], read_skeleton(NTU_FILE, body=1).positions[1],
                               atol=1e-6)  # fmt: skip
    assert "no frame has body 2" in one_line_error(AZURE_FILE, body=2)


def test_azure_without_confidence_levels_keeps_every_frame_with_the_body(tmp_path: Path) -> None:
    doc = azure_doc()
    for frame in doc["frames"]:
        for body in frame["bodies"]:
            del body["confidence_levels"]
    rec = read_skeleton(azure_copy(tmp_path, doc))
    np.testing.assert_array_equal(rec.valid, [True, True, False, True, True])


def test_azure_without_timestamps_is_assumed_30_fps_and_a_null_only_invalidates_its_frame(
    tmp_path: Path,
) -> None:
    doc = azure_doc()
    for frame in doc["frames"]:
        del frame["timestamp_usec"]
    doc["frames"][1]["bodies"][0]["joint_positions"][AZ["KNEE_RIGHT"]][2] = None
    doc["joint_names"][1] = "SPINE_NAVAL"  # the SDK documentation's spelling is accepted
    rec = read_skeleton(azure_copy(tmp_path, doc))
    np.testing.assert_allclose(rec.times, np.arange(5) / 30.0)
    assert rec.time_source == "assumed 30 fps"
    np.testing.assert_array_equal(rec.valid, [True, False, False, False, True])


def test_azure_sniff_claims_body_tracking_json_only(tmp_path: Path) -> None:
    assert recording_format(AZURE_FILE) == ("azure_kinect", "")
    doc = azure_doc()
    del doc["bone_list"], doc["k4abt_sdk_version"]
    assert recording_format(azure_copy(tmp_path, doc, "no_suffix")) == ("azure_kinect", "")
    others = {
        "motion.json": {"joints": ["HeadYaw"], "frames": [[0.0]], "t0": 0},
        "list.json": [{"frames": 1, "joint_positions": 2}],
        "landmarks.json": [[{"x": 0.1, "y": 0.2, "z": 0.3}]],
    }
    for name, other in others.items():
        path = write(tmp_path / name, json.dumps(other))
        assert recording_format(path)[0] != "azure_kinect", name


def _azure_edit(path: str, value: object) -> Callable[[dict], dict]:
    """An edit setting ``doc[path...]`` (keys and indices separated by '/') to ``value``
    (``DELETE``: removes it)."""

    def edit(doc: dict) -> dict:
        *head, last = [int(p) if p.isdigit() else p for p in path.split("/")]
        node = doc
        for key in head:
            node = node[key]
        if value is DELETE:
            del node[last]
        else:
            node[last] = value
        return doc

    return edit


DELETE = object()
_POS = "frames/1/bodies/0/joint_positions"
AZURE_BAD = {  # name -> (edit of the sample, what the message says)
    "no-frames-key": (_azure_edit("frames", DELETE), "expected a list 'frames'"),
    "frames-empty": (_azure_edit("frames", []), "'frames' is empty"),
    "not-an-object": (lambda doc: doc["frames"], "expected a JSON object with 'frames'"),
    "31-joints": (
        lambda doc: _azure_edit(_POS, doc["frames"][1]["bodies"][0]["joint_positions"][:31])(doc),
        "frame 1: body 0: joint_positions is not 32 x [x, y, z] numbers",
    ),
    "string-coordinate": (_azure_edit(f"{_POS}/3/0", "12.5"), "frame 1: body 0: joint_positions"),
    "nan-confidence": (
        _azure_edit("frames/4/bodies/1/confidence_levels/0", None),
        "frame 4: body 1: confidence_levels is not 32 levels of 0, 1, 2 or 3",
    ),
    "confidence-5": (
        _azure_edit("frames/0/bodies/0/confidence_levels/3", 5),
        "frame 0: body 0: confidence_levels",
    ),
    "26-joint-names": (
        lambda doc: _azure_edit("joint_names", doc["joint_names"][:26])(doc),
        "joint_names lists 26 joints, expected the 32",
    ),
    "joint-name": (
        _azure_edit("joint_names/5", "SHOULDER_RIGHT"),
        "joint_names[5] is 'SHOULDER_RIGHT', expected 'SHOULDER_LEFT'",
    ),
    "timestamp-repeats": (
        _azure_edit("frames/3/timestamp_usec", 533288),
        "frame 3: timestamp_usec 533288 is not after the previous frame's 533288",
    ),
    "timestamp-missing": (
        _azure_edit("frames/2/timestamp_usec", DELETE),
        "frame 2: no timestamp_usec (other frames have one)",
    ),
    "num-bodies": (_azure_edit("frames/1/num_bodies", 1), "frame 1: num_bodies is 1 but"),
    "body-not-object": (_azure_edit("frames/0/bodies/0", [1, 2]), "frame 0: body 0 is not"),
    "no-body": (
        lambda doc: {
            **doc,
            "frames": [{**f, "bodies": [], "num_bodies": 0} for f in doc["frames"]],
        },
        "no body in any of the 5 frames",
    ),
}


@pytest.mark.parametrize("case", sorted(AZURE_BAD))
def test_a_bad_azure_file_is_one_line_naming_the_file_and_the_frame(
    tmp_path: Path, case: str
) -> None:
    edit, expected = AZURE_BAD[case]
    path = azure_copy(tmp_path, edit(azure_doc()))
    message = one_line_error(path, format="azure_kinect")
    assert f"{path}: {expected}" in message, message


def test_a_truncated_azure_file_names_the_line(tmp_path: Path) -> None:
    text = AZURE_FILE.read_text()
    path = write(tmp_path / "cut.json", text[: len(text) // 2])
    assert recording_format(path) == ("azure_kinect", "")  # its start is still recognised
    message = one_line_error(path)
    n_lines = text[: len(text) // 2].count("\n") + 1
    assert f"line {n_lines}, column" in message and "invalid JSON" in message, message
    assert "truncated" in message
