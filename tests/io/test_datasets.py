"""Tests of jaxproj.io.datasets: the bundled MSR Action3D archive and the bundling round trip."""

from __future__ import annotations

import zipfile
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from helpers import MSR_ROW, msr_text

from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import JOINT_NAMES, J
from jaxproj.io import datasets
from jaxproj.io.datasets import (
    ACTION_NAMES,
    ARM_ACTIONS,
    MotionSequence,
    bundle_msr_action3d,
    dataset_summary,
    msr_action3d,
)

ARMS = [J[f"{part}{side}"] for part in ("Elbow", "Wrist", "Hand") for side in ("Left", "Right")]
NON_ARM = [j for j in range(20) if j not in ARMS]
CVPR12_EXCLUDED = {
    "a02_s03_e02", "a04_s03_e01", "a07_s04_e01", "a13_s09_e01", "a13_s09_e02", "a13_s09_e03",
    "a14_s03_e01", "a20_s07_e01", "a20_s07_e03", "a20_s10_e03",
}  # fmt: skip


@pytest.fixture(scope="module")
def seqs() -> list[MotionSequence]:
    return msr_action3d()


@pytest.fixture(scope="module")
def by_name(seqs: list[MotionSequence]) -> dict[str, MotionSequence]:
    return {s.name: s for s in seqs}


@pytest.fixture(scope="module")
def valid_positions(seqs: list[MotionSequence]) -> np.ndarray:
    return np.concatenate([s.positions[s.valid] for s in seqs])


# --- the bundled dataset -------------------------------------------------------------------------


def test_summary_counts() -> None:
    assert dataset_summary() == {
        "sequences": 567,
        "frames": 23478,
        "valid_frames": 23478 - 1113,
        "subjects": 10,
        "actions": 20,
        "cvpr12_sequences": 557,
    }


def test_sequence_counts_and_names(seqs: list[MotionSequence]) -> None:
    assert len(seqs) == 567
    names = [s.name for s in seqs]
    assert names == sorted(names) and len(set(names)) == 567
    for s in seqs:
        assert s.name == f"a{s.action:02d}_s{s.subject:02d}_e{s.take:02d}"
        assert 1 <= s.take <= 3
    per_subject = Counter(s.subject for s in seqs)
    assert per_subject == {1: 60, 2: 59, 3: 56, 4: 38, 5: 57, 6: 58, 7: 59, 8: 60, 9: 60, 10: 60}
    per_action = Counter(s.action for s in seqs)
    expected = {a: 30 for a in range(1, 21)} | {1: 27, 2: 27, 3: 27, 4: 26, 5: 26, 6: 26}
    assert per_action == expected | {7: 28, 15: 20}
    lengths = [len(s.valid) for s in seqs]
    assert sum(lengths) == 23478 and min(lengths) == 13 and max(lengths) == 936


def test_arrays_are_consistent(seqs: list[MotionSequence]) -> None:
    for s in seqs:
        t = len(s.valid)
        assert s.positions.shape == (t, 20, 3) and s.positions.dtype == np.float32
        assert s.confidence.shape == (t, 20) and s.confidence.dtype == np.float32
        assert s.valid.dtype == np.bool_
    conf = np.concatenate([s.confidence for s in seqs])
    assert conf.min() == 0.0 and conf.max() == 1.0
    assert 0.45 < (conf == 1.0).mean() < 0.6  # SOURCE.md: about 52 % of values are 1.0


def test_first_frame_matches_raw_text(by_name: dict[str, MotionSequence]) -> None:
    # Rows 1, 6, 7, 13 and 20 of a01_s01_e01_skeleton3D.txt, copied from the raw file.
    s = by_name["a01_s01_e01"]
    raw = {
        "ShoulderLeft": (-0.371736, 0.371031, 2.674849, 1.0),
        "HipRight": (-0.054810, -0.017008, 2.629821, 0.971154),
        "HipCenter": (-0.189501, 0.002549, 2.759828, 0.0),
        "HandRight": (0.015747, -0.258155, 2.610892, 0.745192),
        "Head": (-0.182593, 0.659618, 2.547210, 1.0),
    }
    for name, (x, y, z, c) in raw.items():
        np.testing.assert_array_equal(s.positions[0, J[name]], np.float32([x, y, z]), name)
        assert s.confidence[0, J[name]] == np.float32(c), name
    assert MSR_ROW["Head"] == 20 and JOINT_NAMES[3] == "Head"


def test_invalid_frames(seqs: list[MotionSequence], by_name: dict[str, MotionSequence]) -> None:
    assert not by_name["a13_s09_e02"].valid.any() and len(by_name["a13_s09_e02"].valid) == 38
    assert (~by_name["a13_s09_e03"].valid).sum() == 740
    v = by_name["a07_s04_e01"].valid
    assert len(v) == 45 and not v[:36].any() and v[36:].all()
    with_invalid = {s.name for s in seqs if not s.valid.all()}
    assert len(with_invalid) == 20
    assert {n[:3] for n in with_invalid} == {"a07", "a13", "a14", "a20"}
    for s in seqs:
        good = s.positions[s.valid]
        assert np.isfinite(good).all(), s.name
        assert (np.abs(good).sum(axis=-1) > 0).all(), s.name  # no joint is zero in a valid frame
        assert (s.positions[~s.valid] == 0).all(), s.name


def test_head_is_the_top_joint(seqs: list[MotionSequence], valid_positions: np.ndarray) -> None:
    y = valid_positions[..., 1]
    # Head is above every non-arm joint almost always (bending and pick-up lower it a little) ...
    top_non_arm = np.array(NON_ARM)[y[:, NON_ARM].argmax(axis=1)]
    assert (top_non_arm == J["Head"]).mean() > 0.95
    # ... and above every joint, hands included, in actions that keep the hands low.
    low_hands = np.concatenate(
        [s.positions[s.valid] for s in seqs if s.action in (2, 5, 10, 14, 15, 16)]
    )
    assert (low_hands[..., 1].argmax(axis=1) == J["Head"]).mean() > 0.95
    assert (y[:, J["Head"]] > y[:, J["HipCenter"]]).mean() > 0.99


def test_left_right_and_handedness(valid_positions: np.ndarray) -> None:
    p = valid_positions
    assert (p[:, J["ShoulderLeft"], 0] < p[:, J["ShoulderRight"], 0]).mean() > 0.95
    assert (p[:, J["HipLeft"], 0] < p[:, J["HipRight"], 0]).mean() > 0.95
    up = p[:, J["ShoulderCenter"]] - p[:, J["HipCenter"]]
    left = p[:, J["ShoulderLeft"]] - p[:, J["ShoulderRight"]]
    forward = np.cross(left, up)
    assert (forward[:, 2] < 0).mean() > 0.95  # a right-handed frame: the subject faces the camera


def test_one_arm_actions_use_the_right_hand(seqs: list[MotionSequence]) -> None:
    # The dataset's subjects used the right arm for one-arm actions: its hand travels farther.
    def travel(s: MotionSequence, joint: str) -> float:
        rel = s.positions[s.valid, J[joint]] - s.positions[s.valid, J["ShoulderCenter"]]
        return float(np.linalg.norm(np.diff(rel, axis=0), axis=-1).sum())

    for action in (1, 2, 3, 5, 6):
        one_arm = [s for s in seqs if s.action == action and s.valid.sum() > 1]
        right = sum(travel(s, "HandRight") for s in one_arm)
        left = sum(travel(s, "HandLeft") for s in one_arm)
        assert right > 2 * left, (ACTION_NAMES[action - 1], right, left)


def test_filters_and_cvpr12(seqs: list[MotionSequence]) -> None:
    arm = msr_action3d(subjects=[1, 3], actions=ARM_ACTIONS)
    assert arm == [s for s in seqs if s.subject in (1, 3) and s.action in ARM_ACTIONS]
    assert {s.subject for s in arm} == {1, 3} and {s.action for s in arm} == set(ARM_ACTIONS)
    assert len(msr_action3d(subjects=iter([4]))) == 38
    assert len(msr_action3d(actions=[15])) == 20
    cvpr = msr_action3d(cvpr12_only=True)
    assert len(cvpr) == 557
    assert {s.name for s in seqs} - {s.name for s in cvpr} == CVPR12_EXCLUDED
    with pytest.raises(ConfigError, match="subjects"):
        msr_action3d(subjects=[0])
    with pytest.raises(ConfigError, match="actions"):
        msr_action3d(actions=[21])


def test_names_and_arm_actions() -> None:
    assert len(ACTION_NAMES) == 20 and ACTION_NAMES[0] == "high arm wave"
    assert ACTION_NAMES[12] == "bend" and ACTION_NAMES[19] == "pickup & throw"
    assert ARM_ACTIONS == (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 17, 18, 19)


def test_cache_cannot_be_corrupted(seqs: list[MotionSequence]) -> None:
    s = seqs[0]
    for array in (s.positions, s.confidence, s.valid):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0
        with pytest.raises(ValueError):
            array.flags.writeable = True
    before = s.positions.copy()
    np.add(before, 1.0, out=before)  # a caller's copy is writable and independent
    assert msr_action3d()[0].positions[0, 0, 0] == s.positions[0, 0, 0] != before[0, 0, 0]


def test_bundled_archive_layout() -> None:
    with np.load(datasets.DATA_PATH, allow_pickle=False) as z:
        keys = set(z.files)
        assert int(z["format_version"]) == 1
        assert tuple(z["joint_names"]) == JOINT_NAMES
        assert z["positions_um_planes"].dtype == np.uint8
        assert z["positions_um_planes"].shape == (4, 23478 * 60)
        assert z["confidence_index"].shape == (23478, 20)
    assert {"names", "action", "subject", "take", "cvpr12", "offsets"} <= keys
    assert datasets.DATA_PATH.stat().st_size < 6_000_000


# --- bundling round trip -------------------------------------------------------------------------


def _write_raw(path: Path, rows: np.ndarray) -> None:
    """rows: (T, 20, 4) x y z c in SDK order -> MSR text (MSR row order)."""
    path.write_text(msr_text(rows[..., :3], rows[..., 3]))


@pytest.fixture
def raw_dir(tmp_path: Path) -> tuple[Path, dict[str, np.ndarray]]:
    rng = np.random.default_rng(7)
    src = tmp_path / "raw"
    src.mkdir()
    data = {}
    for name, t in [("a02_s05_e01", 3), ("a01_s10_e03", 4), ("a20_s01_e02", 2)]:
        rows = np.round(rng.uniform(-2.0, 4.0, size=(t, 20, 4)), 6)
        rows[..., 3] = rng.choice([0.0, 1.0, 0.971154, 0.000481], size=(t, 20))
        data[name] = rows
    data["a01_s10_e03"][1, :, :3] = 0.0  # a lost skeleton
    for name, rows in data.items():
        _write_raw(src / f"{name}_skeleton3D.txt", rows)
    (src / "files_used_in_cvpr12_paper.txt").write_text("a02_s05_e01\na20_s01_e02")
    (src / "README.txt").write_text("not a sequence\n")
    return src, data


def test_bundle_round_trip(tmp_path: Path, raw_dir: tuple[Path, dict[str, np.ndarray]]) -> None:
    src, data = raw_dir
    out = tmp_path / "bundle.npz"
    bundle_msr_action3d(src, out)
    loaded = datasets.load_msr_archive(out)
    names = [s.name for s in loaded.sequences]
    assert names == ["a01_s10_e03", "a02_s05_e01", "a20_s01_e02"]
    assert loaded.cvpr12 == (False, True, True)
    for s in loaded.sequences:
        rows = data[s.name]
        assert (s.action, s.subject, s.take) == tuple(int(s.name[i : i + 2]) for i in (1, 5, 9))
        np.testing.assert_array_equal(s.positions, rows[..., :3].astype(np.float32))
        np.testing.assert_array_equal(s.confidence, rows[..., 3].astype(np.float32))
        expected_valid = [s.name != "a01_s10_e03" or i != 1 for i in range(len(rows))]
        np.testing.assert_array_equal(s.valid, expected_valid)
    # lossless: the int32 micrometres are exactly the 6-decimal text values
    with np.load(out, allow_pickle=False) as z:
        um = np.ascontiguousarray(z["positions_um_planes"].T).view("<i4").reshape(-1, 20, 3)
        offsets = z["offsets"]
    first = data["a01_s10_e03"][..., :3]
    np.testing.assert_array_equal(um[offsets[0] : offsets[1]], np.round(first * 1e6))


def test_bundle_is_deterministic_and_cli_works(
    tmp_path: Path, raw_dir: tuple[Path, dict[str, np.ndarray]], capsys: pytest.CaptureFixture
) -> None:
    src, _ = raw_dir
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    bundle_msr_action3d(src, a)
    assert datasets.main([str(src), str(b)]) == 0
    assert "3 sequences, 9 frames" in capsys.readouterr().out
    assert a.read_bytes() == b.read_bytes()
    with zipfile.ZipFile(a) as zf:  # no wall-clock timestamps in the archive
        assert {info.date_time for info in zf.infolist()} == {(1980, 1, 1, 0, 0, 0)}
    assert datasets.main([str(tmp_path / "nowhere"), str(tmp_path / "c.npz")]) == 1
    assert "nowhere: not a directory" in capsys.readouterr().err


def test_bundle_errors(tmp_path: Path, raw_dir: tuple[Path, dict[str, np.ndarray]]) -> None:
    src, _ = raw_dir
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no aXX_sYY_eZZ_skeleton3D.txt files"):
        bundle_msr_action3d(empty, tmp_path / "x.npz")
    bad = src / "a03_s01_e01_skeleton3D.txt"
    bad.write_text("0.1234567 1.0 2.0 1.0\n" * 20)
    with pytest.raises(InputError, match="a03_s01_e01_skeleton3D.txt: .*micrometres"):
        bundle_msr_action3d(src, tmp_path / "x.npz")
    bad.write_text("0.1 1.0 2.0 1.0\n" * 21)
    with pytest.raises(InputError, match="a03_s01_e01_skeleton3D.txt: .*multiple of 20"):
        bundle_msr_action3d(src, tmp_path / "x.npz")
    assert not (tmp_path / "x.npz").exists()
    with pytest.raises(InputError, match="not found"):
        datasets.load_msr_archive(tmp_path / "x.npz")


# --- UTKinect-Action3D ----------------------------------------------------------------------------

# Counts of the bundled subset, computed during development from the ten source files
# (/work/shared/data/utkinect_action3d): each joints_sXX_eYY.txt split into lines, a line whose
# frame number (column 1) was seen before dropped, and segments cut from actionLabel.txt as the
# kept frames whose frame number lies in [start, end]; cross-checked against
# readers.read_skeleton(format="utkinect"). Lines in the source: 9114 (413 repeats dropped).
UTK_FRAMES = {
    "s03_e01": 742, "s03_e02": 830, "s04_e01": 535, "s04_e02": 1271, "s06_e01": 655,
    "s06_e02": 692, "s07_e01": 840, "s07_e02": 609, "s09_e01": 1244, "s09_e02": 1283,
}  # fmt: skip
# Frames per action summed over the ten recordings (walk ... clapHands); 10 segments each.
UTK_ACTION_FRAMES = (409, 329, 255, 350, 539, 121, 298, 177, 446, 303)
# First kept line of joints_s03_e01.txt: frame 342, HipCenter and FootRight (SDK joints 0, 19).
UTK_S03_E01_FIRST = (342, (-1.088523, 0.085042, 2.450324), (-0.941222, -0.957707, 2.601439))


@pytest.fixture(scope="module")
def utk_recordings() -> list[MotionSequence]:
    return datasets.utkinect_action3d(segments=False)


@pytest.fixture(scope="module")
def utk_segments() -> list[MotionSequence]:
    return datasets.utkinect_action3d()


def test_utk_bundled_counts(
    utk_recordings: list[MotionSequence], utk_segments: list[MotionSequence]
) -> None:
    assert {r.name: len(r.valid) for r in utk_recordings} == UTK_FRAMES
    assert [(r.subject, r.take, r.action) for r in utk_recordings] == [
        (s, t, 0) for s in (3, 4, 6, 7, 9) for t in (1, 2)
    ]
    assert Counter(s.name[:7] for s in utk_segments) == {name: 10 for name in UTK_FRAMES}
    per_action = tuple(
        sum(len(s.valid) for s in utk_segments if s.action == a) for a in range(1, 11)
    )
    assert per_action == UTK_ACTION_FRAMES
    assert datasets.dataset_summary("utkinect") == {
        "recordings": 10,
        "frames": 8701,
        "valid_frames": 8701,
        "subjects": 5,
        "segments": 100,
        "segment_frames": sum(UTK_ACTION_FRAMES),
        "upper_body_segments": 50,
        "upper_body_frames": sum(UTK_ACTION_FRAMES[5:]),
    }
    assert dataset_summary()["sequences"] == 567  # the default is still MSR Action3D
    with pytest.raises(ConfigError, match="unknown dataset"):
        dataset_summary("kth")


def test_utk_first_frame_matches_raw_text(utk_recordings: list[MotionSequence]) -> None:
    frame, hip, foot = UTK_S03_E01_FIRST
    r = utk_recordings[0]
    assert r.name == "s03_e01" and r.frame_numbers[0] == frame
    np.testing.assert_array_equal(r.positions[0, J["HipCenter"]], np.float32(hip))
    np.testing.assert_array_equal(r.positions[0, J["FootRight"]], np.float32(foot))


def test_utk_frames_and_segments(
    utk_recordings: list[MotionSequence], utk_segments: list[MotionSequence]
) -> None:
    with np.load(datasets.UTK_DATA_PATH, allow_pickle=False) as z:
        bounds = dict(zip(z["names"], z["segments"], strict=True))
    recordings = {r.name: r for r in utk_recordings}
    for s in (*utk_recordings, *utk_segments):
        t = len(s.valid)
        assert t >= 1 and s.positions.shape == (t, 20, 3) and s.positions.dtype == np.float32
        assert s.confidence.shape == (t, 20) and (s.confidence == 1).all()
        assert s.valid.all() and s.frame_numbers.dtype == np.int64
        assert (np.diff(s.frame_numbers) > 0).all(), s.name  # strictly increasing
        np.testing.assert_array_equal(s.times, s.frame_numbers / datasets.UTK_FPS)
        for array in (s.positions, s.frame_numbers, s.times, s.valid):
            with pytest.raises(ValueError, match="read-only"):
                array[0] = 0
    for name, r in recordings.items():
        segs = [s for s in utk_segments if s.name.startswith(name + "_")]
        assert [s.action for s in segs] == list(range(1, 11))
        for s in segs:
            assert s.name == f"{name}_{datasets.UTK_ACTION_NAMES[s.action - 1]}"
            assert (s.subject, s.take) == (r.subject, r.take)
            start, end = bounds[name][s.action - 1]
            inside = (r.frame_numbers >= start) & (r.frame_numbers <= end)
            lo = int(np.argmax(inside))
            # the segment is exactly the recording's frames within [start, end], in time order
            assert inside.sum() == len(s.valid) and inside[lo : lo + len(s.valid)].all()
            np.testing.assert_array_equal(s.frame_numbers, r.frame_numbers[inside])
            np.testing.assert_array_equal(s.positions, r.positions[inside])
            assert r.times[0] <= s.times[0] <= s.times[-1] <= r.times[-1]


def test_utk_filters_and_errors(utk_segments: list[MotionSequence]) -> None:
    upper = datasets.utkinect_action3d(actions=datasets.UTK_UPPER_BODY_ACTIONS)
    assert upper == [s for s in utk_segments if s.action in (6, 7, 8, 9, 10)]
    assert len(upper) == 50 and {s.action for s in upper} == {6, 7, 8, 9, 10}
    names = {datasets.UTK_ACTION_NAMES[a - 1] for a in datasets.UTK_UPPER_BODY_ACTIONS}
    assert names == {"throw", "push", "pull", "waveHands", "clapHands"}
    assert {s.name.split("_")[2] for s in upper} == names
    s3 = datasets.utkinect_action3d(subjects=[3, 5], actions=[9])
    assert [s.name for s in s3] == ["s03_e01_waveHands", "s03_e02_waveHands"]
    assert len(datasets.utkinect_action3d(subjects=[4], segments=False)) == 2
    for bad in ([0], [11]):
        with pytest.raises(ConfigError, match="subjects"):
            datasets.utkinect_action3d(subjects=bad)
    with pytest.raises(ConfigError, match="bundled UTKinect"):
        datasets.utkinect_action3d(subjects=[1, 2])  # real subjects, not in the subset
    with pytest.raises(ConfigError, match="actions"):
        datasets.utkinect_action3d(actions=[11])
    with pytest.raises(ConfigError, match="segments=False"):
        datasets.utkinect_action3d(actions=[6], segments=False)
    assert datasets.UTK_FPS == 30.0 and len(datasets.UTK_ACTION_NAMES) == 10


def test_load_sequences_names_the_datasets(utk_segments: list[MotionSequence]) -> None:
    assert datasets.load_sequences("utkinect") == utk_segments
    test_split = datasets.load_sequences("utkinect", [2, 4, 6, 8, 10])
    assert test_split == [s for s in utk_segments if s.subject in (4, 6)]
    assert datasets.load_sequences("msr", [4]) == datasets.load_sequences("bundled", [4])
    assert len(datasets.load_sequences("msr", [4])) == 38
    with pytest.raises(InputError, match="'utkinect'"):
        datasets.load_sequences("utk")


def test_utk_bundled_archive_layout() -> None:
    with np.load(datasets.UTK_DATA_PATH, allow_pickle=False) as z:
        assert str(z["dataset"]) == "utkinect_action3d" and int(z["format_version"]) == 1
        assert tuple(z["joint_names"]) == JOINT_NAMES
        assert tuple(z["action_names"]) == datasets.UTK_ACTION_NAMES
        assert z["positions_um_planes"].dtype == np.uint8
        assert z["positions_um_planes"].shape == (4, 8701 * 60)
        assert z["frame_numbers"].shape == (8701,) and z["segments"].shape == (10, 10, 2)
        assert (z["segments"] >= 0).all()  # no NaN segment among the ten recordings
    assert datasets.UTK_DATA_PATH.stat().st_size < 1_500_000
    with pytest.raises(InputError, match="unsupported"):
        datasets.load_msr_archive(datasets.UTK_DATA_PATH)
    with pytest.raises(InputError, match="not a UTKinect"):
        datasets.load_utkinect_archive(datasets.DATA_PATH)


def _write_utk(path: Path, frames: list[int], xyz: np.ndarray) -> None:
    """frames (T,), xyz (T, 20, 3) SDK order -> joints_sXX_eYY.txt text (6 decimals)."""
    path.write_text(
        "".join(
            f"{f}   " + "  ".join(f"{v:.6f}" for v in row.reshape(-1)) + "\n"
            for f, row in zip(frames, xyz, strict=True)
        )
    )


UTK_LABELS = """s01_e01
walk: 10 14
sitDown: NaN NaN
standUp: 16 30 \n pickUp: 40 50
carry:  3 3
throw: 1 2
push: 11 18
pull: 12 12
waveHands: 14 20
clapHands: 20 22
s02_e01
walk: 1 2
sitDown: 2 3
standUp: 3 4
pickUp: 4 5
carry: 5 6
throw: 6 7
push: 7 8
pull: 8 9
waveHands: 9 10
clapHands: 10 11
"""


@pytest.fixture
def utk_raw(tmp_path: Path) -> tuple[Path, np.ndarray]:
    """One synthetic recording with repeated frame numbers; the labels list another one too."""
    rng = np.random.default_rng(3)
    src = tmp_path / "utk"
    src.mkdir()
    frames = [10, 12, 12, 14, 18, 18, 20, 26]
    xyz = np.round(rng.uniform(-2.0, 4.0, size=(len(frames), 20, 3)), 6)
    _write_utk(src / "joints_s01_e01.txt", frames, xyz)
    (src / "actionLabel.txt").write_text(UTK_LABELS)
    (src / "README.txt").write_text("not a recording\n")
    return src, xyz


def test_utk_bundle_round_trip(tmp_path: Path, utk_raw: tuple[Path, np.ndarray]) -> None:
    from jaxproj.io.readers import read_skeleton

    src, xyz = utk_raw
    out = tmp_path / "utk.npz"
    datasets.bundle_utkinect_action3d(src, out)
    utk = datasets.load_utkinect_archive(out)
    (rec,) = utk.recordings
    kept = [0, 1, 3, 4, 6, 7]  # the second line of frames 12 and 18 is dropped
    assert (rec.name, rec.subject, rec.take, rec.action) == ("s01_e01", 1, 1, 0)
    np.testing.assert_array_equal(rec.frame_numbers, [10, 12, 14, 18, 20, 26])
    np.testing.assert_array_equal(rec.positions, xyz[kept].astype(np.float32))
    raw = read_skeleton(src / "joints_s01_e01.txt", format="utkinect")
    np.testing.assert_array_equal(rec.positions, raw.positions)  # the reader's rule, same values
    # lossless: the stored micrometres are the decimal text read as integers, no float parsing
    lines = (src / "joints_s01_e01.txt").read_text().splitlines()
    text_um = [[int(t.replace(".", "")) for t in lines[i].split()[1:]] for i in kept]
    with np.load(out, allow_pickle=False) as z:
        um = np.ascontiguousarray(z["positions_um_planes"].T).view("<i4").reshape(-1, 60)
        np.testing.assert_array_equal(um, text_um)
        np.testing.assert_array_equal(z["segments"][0, :2], [[10, 14], [-1, -1]])
    # walk 10-14, standUp 16-30, push 11-18, pull 12, waveHands 14-20, clapHands 20-22;
    # sitDown is NaN, pickUp / carry / throw hold no recorded frame: left out
    assert [(s.name, s.frame_numbers.tolist()) for s in utk.segments] == [
        ("s01_e01_walk", [10, 12, 14]),
        ("s01_e01_standUp", [18, 20, 26]),
        ("s01_e01_push", [12, 14, 18]),
        ("s01_e01_pull", [12]),
        ("s01_e01_waveHands", [14, 18, 20]),
        ("s01_e01_clapHands", [20]),
    ]
    assert [s.action for s in utk.segments] == [1, 3, 7, 8, 9, 10]
    np.testing.assert_array_equal(utk.segments[1].positions, xyz[[4, 6, 7]].astype(np.float32))


def test_utk_bundle_is_deterministic_and_cli_works(
    tmp_path: Path, utk_raw: tuple[Path, np.ndarray], capsys: pytest.CaptureFixture
) -> None:
    src, _ = utk_raw
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    datasets.bundle_utkinect_action3d(src, a)
    assert datasets.main(["--dataset", "utkinect", str(src), str(b)]) == 0
    assert "1 recordings, 6 frames, 6 segments" in capsys.readouterr().out
    assert a.read_bytes() == b.read_bytes()
    with zipfile.ZipFile(a) as zf:
        assert {info.date_time for info in zf.infolist()} == {(1980, 1, 1, 0, 0, 0)}
    # the MSR archive format is chosen without --dataset, and it finds no MSR file here
    assert datasets.main([str(src), str(tmp_path / "c.npz")]) == 1
    assert "no aXX_sYY_eZZ_skeleton3D.txt files" in capsys.readouterr().err


def test_utk_bundle_errors(tmp_path: Path, utk_raw: tuple[Path, np.ndarray]) -> None:
    src, xyz = utk_raw
    out = tmp_path / "x.npz"
    labels = src / "actionLabel.txt"
    cases = [
        (labels, UTK_LABELS.replace("pull: 12 12", "pull: 12"), "line 9: expected"),
        (labels, UTK_LABELS.replace("pull: 12 12", "pull: 13 12"), "line 9: bounds"),
        (labels, UTK_LABELS.replace("pull: 12 12", "pull: 12 NaN"), "line 9: bounds"),
        (labels, UTK_LABELS.replace("pull: 12 12", "jump: 12 12"), "unknown action 'jump'"),
        (labels, UTK_LABELS.replace("pull: 12 12", "push: 12 12"), "repeated action 'push'"),
        (labels, UTK_LABELS.replace("s01_e01", "s01_e02"), "no segment block for s01_e01"),
        (labels, UTK_LABELS.replace("pull: 12 12\n", ""), r"s01_e01 lacks actions \['pull'\]"),
    ]
    for path, text, message in cases:
        path.write_text(text)
        with pytest.raises(InputError, match=message):
            datasets.bundle_utkinect_action3d(src, out)
    labels.unlink()
    with pytest.raises(InputError, match="segment labels not found"):
        datasets.bundle_utkinect_action3d(src, out)
    labels.write_text(UTK_LABELS)
    joints = src / "joints_s01_e01.txt"
    _write_utk(joints, [10, 14, 12], xyz[:3])
    with pytest.raises(InputError, match="joints_s01_e01.txt: frame numbers must"):
        datasets.bundle_utkinect_action3d(src, out)
    joints.write_text("10 " + " ".join(["0.1234567"] * 60) + "\n")  # 7 decimals
    with pytest.raises(InputError, match="joints_s01_e01.txt: .*micrometres"):
        datasets.bundle_utkinect_action3d(src, out)
    joints.write_text("10 1.0 2.0\n")
    with pytest.raises(InputError, match="line 1: found 3 columns, expected 61"):
        datasets.bundle_utkinect_action3d(src, out)
    joints.unlink()
    with pytest.raises(InputError, match="no joints_sXX_eYY.txt files"):
        datasets.bundle_utkinect_action3d(src, out)
    assert not out.exists()
