"""Issue 60's real-file checks: a skeleton named or guessed aloud, units read from the bones,
``.npy`` arrays, rates a file does not give, Azure files whose timestamps are all 0. NumPy only:
no model is built (milliseconds a test)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from helpers import person_joints, person_motion

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import JOINT_NAMES
from jaxproj.io import plausible
from jaxproj.io.readers import read_skeleton

AZURE_FILE = Path(__file__).resolve().parents[1] / "data" / "formats" / "take_01_k4abt.json"


def npz(path: Path, **arrays: object) -> Path:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    path.write_bytes(buf.getvalue())
    return path


def npy(path: Path, array: np.ndarray) -> Path:
    buf = io.BytesIO()
    np.save(buf, array)
    path.write_bytes(buf.getvalue())
    return path


def csv(path: Path, sdk: np.ndarray) -> Path:
    head = ",".join(f"{name}_{c}" for name in JOINT_NAMES for c in "xyz") + "\n"
    body = "".join(",".join(f"{v:.6f}" for v in frame.ravel()) + "\n" for frame in sdk)
    path.write_text(head + body)
    return path


def test_32_mediapipe_landmarks_are_not_read_as_azure_kinect_in_silence(tmp_path: Path) -> None:
    """The issue's case: 32 of MediaPipe's 33 landmarks, J = 32 = Azure Kinect's count."""
    mp32 = person_joints("mediapipe_pose")[:, :32]
    path = npz(tmp_path / "mp.npz", joints=mp32)
    with pytest.raises(InputError) as info:
        read_skeleton(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: read as azure_kinect (guessed from the joint count)")
    assert "--skeleton NAME" in msg and "\n" not in msg
    # naming the skeleton: 32 is not MediaPipe's count, said as such
    with pytest.raises(InputError, match="has 32 joints, but skeleton 'mediapipe_pose' records"):
        read_skeleton(path, skeleton="mediapipe_pose")
    # the same landmarks, all 33 of them, are read (and the guess is said)
    rec = read_skeleton(npz(tmp_path / "mp33.npz", joints=person_joints("mediapipe_pose")))
    assert rec.skeleton == "mediapipe_pose" and rec.skeleton_from == "count"


def test_a_named_skeleton_wins_over_the_count_and_the_file_key(tmp_path: Path) -> None:
    body = person_joints("smplx")  # 22 joints
    rec = read_skeleton(npz(tmp_path / "b.npz", joints=body), skeleton="smplx")
    assert (rec.skeleton, rec.skeleton_from) == ("smplx", "option")
    assert not any("guessed" in n for n in rec.notes)
    keyed = read_skeleton(npz(tmp_path / "k.npz", joints=body, skeleton="smplx"))
    assert keyed.skeleton_from == "file" and not any("guessed" in n for n in keyed.notes)
    np.testing.assert_array_equal(keyed.positions, rec.positions)
    with pytest.raises(ConfigError, match="'hand' is not a registered skeleton"):
        read_skeleton(tmp_path / "b.npz", skeleton="hand")
    # a format of one skeleton: naming another is refused
    with pytest.raises(ConfigError, match="a csv file records kinect_v1 joints"):
        read_skeleton(csv(tmp_path / "c.csv", person_motion(3)), skeleton="smpl")


@pytest.mark.parametrize(("unit", "factor"), [("cm", 100.0), ("mm", 1000.0)])
def test_centimetres_and_millimetres_are_converted_with_a_note(
    tmp_path: Path, unit: str, factor: float
) -> None:
    metres = person_joints("smpl", n_frames=3)
    want = read_skeleton(npz(tmp_path / "m.npz", joints=metres)).positions
    rec = read_skeleton(npz(tmp_path / "u.npz", joints=metres * factor))
    np.testing.assert_allclose(rec.positions, want, rtol=1e-6, atol=1e-6)
    word = {"cm": "centimetres", "mm": "millimetres"}[unit]
    assert any(n.startswith(f"positions read as {word}") for n in rec.notes)
    said = read_skeleton(tmp_path / "u.npz", units=unit)  # said: converted, no guess to note
    np.testing.assert_allclose(said.positions, want, rtol=1e-6, atol=1e-6)
    assert not any(n.startswith("positions read as") for n in said.notes)
    # a Kinect CSV in centimetres too
    sdk = person_motion(3)
    rec_csv = read_skeleton(csv(tmp_path / "c.csv", sdk * factor))
    np.testing.assert_allclose(rec_csv.positions, sdk, rtol=1e-5, atol=1e-5)


def test_units_of_no_person_are_refused_and_other_formats_keep_theirs(tmp_path: Path) -> None:
    inches = person_motion(3) / 0.0254  # a median bone of about 15.5: none of m, cm, mm
    path = csv(tmp_path / "in.csv", inches)
    with pytest.raises(InputError, match=r"the units are none of m, cm, mm; give the units"):
        read_skeleton(path)
    np.testing.assert_allclose(read_skeleton(path, units="m").positions, inches, atol=1e-5)
    with pytest.raises(ConfigError, match="units must be auto, m, cm, mm"):
        read_skeleton(path, units="in")
    with pytest.raises(ConfigError, match="a azure_kinect file states its own units"):
        read_skeleton(AZURE_FILE, units="cm")


def test_every_registered_layouts_count_is_read_aloud_or_refused(tmp_path: Path) -> None:
    """Every joint count the NPZ reader knows names its skeleton in a note (or, beyond the
    registered layouts, refuses and asks for the skeleton)."""
    from jaxproj.io.formats.table import JOINT_COUNTS

    for n, (name, k) in JOINT_COUNTS.items():
        own = person_joints(name)
        joints = np.concatenate([own, np.zeros((2, n - k, 3))], axis=1)
        rec = read_skeleton(npz(tmp_path / f"j{n}.npz", joints=joints))
        assert rec.skeleton == name
        assert rec.notes[0].startswith(f"skeleton {name} guessed from the joint count ({n})")
    with pytest.raises(InputError, match="add a 'skeleton' key"):
        read_skeleton(npz(tmp_path / "j21.npz", joints=np.ones((2, 21, 3))))
    assert set(skeletons.names()) == {name for name, _ in JOINT_COUNTS.values()}


def test_a_humanml3d_npy_and_a_bad_one(tmp_path: Path) -> None:
    joints = person_joints("smplx", n_frames=4)  # HumanML3D: (T, 22, 3), y up, metres
    rec = read_skeleton(npy(tmp_path / "000021.npy", joints), fps=20)
    assert (rec.format, rec.skeleton, rec.time_source) == ("npy", "smplx", "given 20 fps")
    np.testing.assert_allclose(rec.times, np.arange(4) / 20)
    with pytest.raises(InputError, match=r"joints has shape \(4, 22\), expected \(T, J, 3\)"):
        read_skeleton(npy(tmp_path / "flat.npy", joints[..., 0]))
    with pytest.raises(InputError, match="unreadable .npy array"):
        read_skeleton(npy(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object)))
    (tmp_path / "fake.npy").write_text("1,2,3\n")
    with pytest.raises(InputError, match="not a NumPy .npy array"):
        read_skeleton(tmp_path / "fake.npy")


def test_a_rate_the_file_does_not_give_is_said(tmp_path: Path) -> None:
    rec = read_skeleton(csv(tmp_path / "c.csv", person_motion(3)))
    assert rec.notes == ("the file gives no frame times: 30 fps assumed (--fps says the rate)",)
    assert read_skeleton(tmp_path / "c.csv", fps=21).notes == ()


def test_azure_timestamps_all_zero_ask_for_fps_and_fps_replaces_them(tmp_path: Path) -> None:
    doc = json.loads(AZURE_FILE.read_text())
    for frame in doc["frames"]:
        frame["timestamp_usec"] = 0
    path = tmp_path / "zero.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="every frame's timestamp_usec is 0: .* --fps"):
        read_skeleton(path)
    rec = read_skeleton(path, fps=30)
    assert rec.time_source == "given 30 fps"
    np.testing.assert_allclose(rec.times, np.arange(len(doc["frames"])) / 30)
    # broken timestamps do not matter once the rate is given
    doc["frames"][2]["timestamp_usec"] = "n/a"
    path.write_text(json.dumps(doc))
    assert read_skeleton(path, fps=15).times[-1] == pytest.approx((len(doc["frames"]) - 1) / 15)


def test_plausible_bone_lengths_are_the_persons() -> None:
    sdk = person_motion(5, jitter=0.0)
    lengths = plausible.bone_lengths(sdk, np.ones(5, bool))
    assert lengths["trunk"] == pytest.approx(0.5) and 0.2 < lengths["forearm left"] < 0.3


def test_the_command_line_names_the_skeleton_says_its_notes_and_takes_the_options(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``retarget``'s summary names the format and skeleton and prints each note; ``--skeleton``,
    ``--units``, ``--up`` reach the reader. The retargeting is replaced by the robot's standing
    posture (the wiring is under test, not the IK: nothing compiles)."""
    from fuzzing import assert_one_line_error, run_cli

    from jaxproj import robots
    from jaxproj.io.motion_files import load_motion
    from jaxproj.motion import retarget as rt

    def standing(positions, valid, **kwargs):  # type: ignore[no-untyped-def]
        q = np.tile(robots.get(robots.DEFAULT).standing, (len(valid), 1)).astype(np.float32)
        return rt.RetargetResult(q, np.asarray(valid), kwargs["times"])

    monkeypatch.setattr(rt, "retarget", standing)
    path = npz(tmp_path / "body_cm.npz", joints=person_joints("smplx", n_frames=4) * 100.0)
    out = tmp_path / "m.npz"
    code, text, err = run_cli(capsys, "retarget", str(path), "--out", str(out))
    assert code == 0, err
    assert "; npz, skeleton smplx) ->" in text
    assert "  note: skeleton smplx guessed from the joint count (22)" in text
    assert "  note: positions read as centimetres" in text
    meta = load_motion(out).meta
    assert (meta["skeleton"], meta["skeleton_from"]) == ("smplx", "count")
    assert len(meta["reading_notes"].split(" | ")) == 3
    code, text, err = run_cli(capsys, "retarget", str(path), "--skeleton", "smplx", "--units",
                              "cm", "--up", "z", "--out", str(out), "--force")  # fmt: skip
    assert code == 0, err
    assert "note: skeleton" not in text and "note: positions" not in text
    assert load_motion(out).meta["skeleton_from"] == "option"
    # --body picks the NTU file's second person (valid in frames 1 and 4 only)
    ntu = AZURE_FILE.parent / "S001C001P001R001A001.skeleton"
    code, text, err = run_cli(capsys, "retarget", str(ntu), "--body", "1", "--out",
                              str(tmp_path / "b.npz"))  # fmt: skip
    assert code == 0, err
    assert "5 frames (2 valid" in text and "; ntu, skeleton kinect_v2)" in text
    with pytest.raises(SystemExit) as info:  # argparse's usage error
        run_cli(capsys, "retarget", str(ntu), "--body", "second", "--out", str(tmp_path / "c"))
    assert info.value.code == 2
    assert "expected 'first' or a 0-based body index" in capsys.readouterr().err
    mp32 = npz(tmp_path / "mp32.npz", joints=person_joints("mediapipe_pose")[:, :32])
    code, _, err = run_cli(capsys, "retarget", str(mp32), "--out", str(tmp_path / "x.npz"))
    assert_one_line_error(code, err, "read as azure_kinect (guessed", "--skeleton NAME")
    assert not (tmp_path / "x.npz").exists()
