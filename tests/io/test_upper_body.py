"""Upper body without hips (issue 60): a MediaPipe recording whose hips are hidden still drives a
robot that reads no leg bone. NumPy only (the command-line test replaces the retargeting)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from jaxproj.human import upper_body
from jaxproj.human.skeletons import KINECT_V1
from jaxproj.io.readers import read_skeleton

K = KINECT_V1.index
CLIP = Path(__file__).resolve().parents[1] / "data" / "formats" / "same_motion"
CLIP = CLIP / "131_03.mediapipe_pose.json"
HIPS = (23, 24)  # MediaPipe's left_hip, right_hip (the Pose landmarker guide's numbering)


@pytest.fixture
def half_hidden(tmp_path: Path) -> tuple[Path, int]:
    """The clip with both hips' visibility 0.3 from frame 15 on (a person leaning in)."""
    frames = json.loads(CLIP.read_text())
    for frame in frames[15:]:
        for j in HIPS:
            frame[j]["visibility"] = 0.3
    path = tmp_path / "desk.json"
    path.write_text(json.dumps(frames))
    return path, 15


def test_hidden_hips_invalidate_by_default_and_are_made_from_the_shoulders_on_request(
    half_hidden: tuple[Path, int],
) -> None:
    path, k = half_hidden
    seen = read_skeleton(CLIP, fps=10)
    strict = read_skeleton(path, fps=10)
    assert strict.valid[:k].all() and not strict.valid[k:].any()
    assert "left_hip (15 frames, 0.30)" in str(strict.invalid_reason)
    made = read_skeleton(path, fps=10, hips="shoulders")
    assert made.valid.all() and made.invalid_reason is None
    assert made.notes[0].startswith("hips hidden (visibility below 0.5) in 15 frames")
    np.testing.assert_array_equal(made.positions[:k], seen.positions[:k])  # shown: as they were
    keep = [K[j] for j in ("ShoulderCenter", "Head", "ShoulderLeft", "ElbowLeft", "WristLeft")]
    np.testing.assert_array_equal(made.positions[k:, keep], seen.positions[k:, keep])
    # the made trunk: the first half's median length, along the capture's up tilted by the
    # first half's median lean about the shoulder line
    p = made.positions[k:].astype(np.float64)
    trunk = p[:, K["ShoulderCenter"]] - p[:, K["HipCenter"]]
    first = seen.positions[:k].astype(np.float64)
    length = np.median(
        np.linalg.norm(first[:, K["ShoulderCenter"]] - first[:, K["HipCenter"]], axis=-1)
    )
    np.testing.assert_allclose(np.linalg.norm(trunk, axis=-1), length, rtol=1e-5)
    tilt = upper_body.trunk_tilt(seen.positions, np.arange(30) < k)
    np.testing.assert_allclose(upper_body.trunk_tilt(made.positions, np.arange(30) >= k), tilt,
                               atol=1e-5)  # fmt: skip
    left, up = upper_body.shoulder_axes(p)
    assert np.abs(np.sum(trunk * left, axis=-1)).max() < 1e-5  # square to the shoulders


def test_without_a_frame_that_shows_them_the_trunk_is_upright_and_sized_by_the_shoulders() -> None:
    rec = read_skeleton(CLIP, fps=10)
    every = np.ones(len(rec.valid), bool)
    made, tilt = upper_body.hips_from_shoulders(rec.positions, every, ~every)
    assert tilt == 0.0
    p = made.astype(np.float64)
    trunk = p[:, K["ShoulderCenter"]] - p[:, K["HipCenter"]]
    width = np.linalg.norm(p[:, K["ShoulderLeft"]] - p[:, K["ShoulderRight"]], axis=-1)
    length = upper_body.TRUNK_PER_SHOULDERS * np.median(width)
    np.testing.assert_allclose(np.linalg.norm(trunk, axis=-1), length, rtol=1e-5)
    _, up = upper_body.shoulder_axes(p)
    np.testing.assert_allclose(trunk / length, up, atol=1e-5)  # the capture's up, untilted


def test_retarget_makes_hips_for_the_nao_and_not_for_a_robot_with_legs(
    half_hidden: tuple[Path, int],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The NAO reads no leg bone: every frame drives it; the G1 reads the legs: the hidden half
    is invalid for it. The retargeting is replaced (the wiring is under test)."""
    from fuzzing import run_cli

    from jaxproj import robots
    from jaxproj.motion import retarget as rt

    seen: dict[str, np.ndarray] = {}

    def standing(positions, valid, **kwargs):  # type: ignore[no-untyped-def]
        robot = robots.get(kwargs.get("robot") or robots.DEFAULT)
        seen[robot.name] = np.asarray(valid)
        q = np.tile(robot.standing, (len(valid), 1)).astype(np.float32)
        return rt.RetargetResult(q, np.asarray(valid), kwargs["times"])

    monkeypatch.setattr(rt, "retarget", standing)
    path, k = half_hidden
    code, out, err = run_cli(capsys, "retarget", str(path), "--fps", "10", "--out",
                             str(tmp_path / "nao.npz"))  # fmt: skip
    assert code == 0, err
    assert seen[robots.DEFAULT].all() and "note: hips hidden" in out
    code, out, err = run_cli(capsys, "retarget", str(path), "--fps", "10", "--robot",
                             "unitree_g1", "--out", str(tmp_path / "g1.npz"))  # fmt: skip
    assert code == 0, err
    assert seen["unitree_g1"][:k].all() and not seen["unitree_g1"][k:].any()


def test_a_mediapipe_npz_reads_hidden_hips_as_its_json_does(
    half_hidden: tuple[Path, int], tmp_path: Path
) -> None:
    import io

    path, k = half_hidden
    frames = json.loads(path.read_text())
    joints = np.array([[[lm["x"], lm["y"], lm["z"]] for lm in f] for f in frames])
    vis = np.array([[lm["visibility"] for lm in f] for f in frames])
    buf = io.BytesIO()
    np.savez(buf, joints=joints, visibility=vis, skeleton="mediapipe_pose", fps=10)
    npz = tmp_path / "desk.npz"
    npz.write_bytes(buf.getvalue())
    strict, made = read_skeleton(npz), read_skeleton(npz, hips="shoulders")
    from_json = read_skeleton(path, fps=10, hips="shoulders")
    assert not strict.valid[k:].any() and "right_hip (15 frames, 0.30)" in str(
        strict.invalid_reason
    )
    assert made.valid.all() and made.invalid_reason is None and made.notes == from_json.notes
    np.testing.assert_allclose(made.positions, from_json.positions, atol=1e-6)
