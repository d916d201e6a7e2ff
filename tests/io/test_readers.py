"""Tests of jaxproj.io.readers: every format round-trips, bad input raises a one-line InputError."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from helpers import MSR_ROW, msr_text, person_motion

from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import JOINT_NAMES, J
from jaxproj.io.readers import Recording, read_skeleton


def motion(n_frames: int = 7, seed: int = 0) -> np.ndarray:
    """(T, 20, 3) float64 positions with 6 decimals (exactly representable in every format): a
    person (the readers check a table's bones are a person's, in metres), each joint jittered
    by up to 5 cm a frame."""
    return person_motion(n_frames, seed, jitter=0.05)


def utk_text(sdk: np.ndarray, frame_numbers: list[int] | None = None) -> str:
    numbers = frame_numbers if frame_numbers is not None else list(range(1, len(sdk) + 1))
    return "".join(
        f"{n} " + " ".join(f"{v:.6f}" for v in frame.ravel()) + "\n"
        for n, frame in zip(numbers, sdk, strict=True)
    )


def csv_text(sdk: np.ndarray, header: bool = True) -> str:
    head = ",".join(f"{name}_{c}" for name in JOINT_NAMES for c in "xyz") + "\n"
    body = "".join(",".join(f"{v:.6f}" for v in frame.ravel()) + "\n" for frame in sdk)
    return (head if header else "") + body


def write(path: Path, content: str | bytes) -> Path:
    if isinstance(content, str):
        path.write_bytes(content.encode())
    else:
        path.write_bytes(content)
    return path


def npz_bytes(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def all_formats(tmp_path: Path, sdk: np.ndarray) -> dict[str, Path]:
    return {
        "msr": write(tmp_path / "a01_s01_e01_skeleton3D.txt", msr_text(sdk)),
        "utkinect": write(tmp_path / "joints_s01_e01.txt", utk_text(sdk)),
        "npz": write(tmp_path / "motion.npz", npz_bytes(positions=sdk)),
        "csv": write(tmp_path / "motion.csv", csv_text(sdk)),
    }


# --- round trips ---------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["msr", "utkinect", "npz", "csv"])
@pytest.mark.parametrize("explicit", [False, True])
def test_every_format_round_trips(tmp_path: Path, fmt: str, explicit: bool) -> None:
    sdk = motion()
    path = all_formats(tmp_path, sdk)[fmt]
    rec = read_skeleton(path, format=fmt if explicit else "auto")
    assert isinstance(rec, Recording)
    assert rec.format == fmt and rec.source == str(path)
    assert rec.positions.dtype == np.float32 and rec.valid.dtype == np.bool_
    np.testing.assert_allclose(rec.positions, sdk, rtol=0, atol=1e-6)
    # float32 of the decimal text, exactly (same value whichever format carried it)
    np.testing.assert_array_equal(rec.positions, sdk.astype(np.float32))
    assert rec.valid.all()


def test_msr_joint_order_matches_dataset_table(tmp_path: Path) -> None:
    # MSR row k (0-based) holds x = k: after conversion joint j must hold x = MSR_ROW[name] - 1.
    rows = np.zeros((2, 20, 4))
    rows[..., 0] = np.arange(20)
    rows[..., 1] = 1.0
    text = "\n".join(" ".join(f"{v:.6f}" for v in r) for r in rows.reshape(-1, 4))
    rec = read_skeleton(write(tmp_path / "order.txt", text), "msr")
    expected = [MSR_ROW[name] - 1 for name in JOINT_NAMES]
    np.testing.assert_array_equal(rec.positions[0, :, 0], expected)
    assert rec.positions[1, J["Head"], 0] == 19 and rec.positions[1, J["HipCenter"], 0] == 6


def test_text_variants_parse_the_same(tmp_path: Path) -> None:
    sdk = motion(3)
    crlf = msr_text(sdk, newline="\r\n")
    blank_lines = "\n\n" + msr_text(sdk).replace("\n", "\n\n", 5) + "\n\n"
    no_final_newline = msr_text(sdk).rstrip("\n")
    tabs = msr_text(sdk).replace(" ", "\t")
    nbsp = msr_text(sdk).replace(" ", "\u00a0", 3)  # non-ASCII whitespace: slow path
    for i, text in enumerate([crlf, blank_lines, no_final_newline, tabs, nbsp]):
        rec = read_skeleton(write(tmp_path / f"v{i}.txt", text))
        np.testing.assert_array_equal(rec.positions, sdk.astype(np.float32), err_msg=str(i))
    no_header = read_skeleton(write(tmp_path / "nohead.csv", csv_text(sdk, header=False)))
    np.testing.assert_array_equal(no_header.positions, sdk.astype(np.float32))
    spaced = csv_text(sdk).replace(",", " , ")
    rec = read_skeleton(write(tmp_path / "spaced.csv", spaced))
    np.testing.assert_array_equal(rec.positions, sdk.astype(np.float32))


def test_auto_detects_by_content_when_extension_says_nothing(tmp_path: Path) -> None:
    sdk = motion(2)
    assert read_skeleton(write(tmp_path / "x.dat", npz_bytes(positions=sdk))).format == "npz"
    assert read_skeleton(write(tmp_path / "y.txt", csv_text(sdk, header=False))).format == "csv"
    assert read_skeleton(write(tmp_path / "z", utk_text(sdk))).format == "utkinect"


def test_utkinect_repeated_frame_numbers_keep_first_then_order_by_frame(tmp_path: Path) -> None:
    sdk = motion(6, seed=1)
    path = write(tmp_path / "joints_s02_e01.txt", utk_text(sdk, [5, 6, 6, 7, 5, 3]))
    rec = read_skeleton(path)
    # frames 3, 5, 6, 7: the first line of each number, ordered by frame number
    np.testing.assert_array_equal(rec.positions, sdk[[5, 0, 1, 3]].astype(np.float32))
    np.testing.assert_allclose(rec.times, np.array([0, 2, 3, 4]) / 30.0, rtol=0, atol=1e-12)
    assert rec.time_source == "frame numbers at 30 fps"


def test_time_axis_of_every_format_and_the_fps_override(tmp_path: Path) -> None:
    sdk = motion(4)
    msr = read_skeleton(write(tmp_path / "a01_s01_e01_skeleton3D.txt", msr_text(sdk)))
    np.testing.assert_allclose(msr.times, np.arange(4) / 15.0, rtol=0, atol=1e-12)
    assert msr.time_source == "assumed 15 fps" and msr.fps == pytest.approx(15.0)
    csv = read_skeleton(write(tmp_path / "c.csv", csv_text(sdk)))
    np.testing.assert_allclose(csv.times, np.arange(4) / 30.0, rtol=0, atol=1e-12)
    utk = read_skeleton(write(tmp_path / "u.txt", utk_text(sdk, [10, 12, 16, 18])))
    np.testing.assert_allclose(utk.times, np.array([0, 2, 6, 8]) / 30.0, rtol=0, atol=1e-12)
    over = read_skeleton(tmp_path / "u.txt", fps=24.0)
    np.testing.assert_allclose(over.times, np.arange(4) / 24.0, rtol=0, atol=1e-12)
    assert over.time_source == "given 24 fps"
    times = np.array([1.0, 1.1, 1.25, 1.3])
    npz = read_skeleton(write(tmp_path / "t.npz", npz_bytes(positions=sdk, times=times)))
    np.testing.assert_allclose(npz.times, times - 1.0, rtol=0, atol=1e-12)
    assert npz.time_source == "file"
    rate = read_skeleton(write(tmp_path / "f.npz", npz_bytes(positions=sdk, fps=np.float64(60))))
    np.testing.assert_allclose(rate.times, np.arange(4) / 60.0, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="increase strictly"):
        read_skeleton(write(tmp_path / "b.npz", npz_bytes(positions=sdk, times=times[::-1])))
    with pytest.raises(InputError, match=r"times has shape"):
        read_skeleton(write(tmp_path / "s.npz", npz_bytes(positions=sdk, times=times[:2])))
    with pytest.raises(ConfigError, match="fps"):
        read_skeleton(tmp_path / "u.txt", fps=0.0)


def test_zero_and_nonfinite_frames_are_kept_and_marked_invalid(tmp_path: Path) -> None:
    sdk = motion(5)
    sdk[1] = 0.0
    sdk[3, 7, 2] = np.nan
    expected_valid = np.array([True, False, True, False, True])
    paths = all_formats(tmp_path, sdk)
    for fmt, path in paths.items():
        rec = read_skeleton(path)
        assert rec.positions.shape == (5, 20, 3), fmt
        np.testing.assert_array_equal(rec.valid, expected_valid, err_msg=fmt)
        assert np.isfinite(rec.positions).all(), fmt
        assert (rec.positions[~expected_valid] == 0).all(), fmt
        np.testing.assert_array_equal(
            rec.positions[expected_valid], sdk[expected_valid].astype(np.float32), fmt
        )
    # inf in text, and an npz valid mask that marks a good frame invalid
    text = msr_text(motion(2)).replace("0.500000", "inf", 1)
    assert read_skeleton(write(tmp_path / "inf.txt", text)).valid.tolist() == [True, True]
    text = text.replace(text.split()[0], "-inf", 1)
    assert read_skeleton(write(tmp_path / "inf2.txt", text)).valid.tolist() == [False, True]
    good = motion(3)
    mask = np.array([True, False, True])
    rec = read_skeleton(write(tmp_path / "m.npz", npz_bytes(positions=good, valid=mask)))
    np.testing.assert_array_equal(rec.valid, mask)
    rec = read_skeleton(write(tmp_path / "big.npz", npz_bytes(positions=good * 1e39)))
    assert not rec.valid.any() and (rec.positions == 0).all()


def test_reading_1000_frames_is_exact(tmp_path: Path) -> None:
    # a long file (the bundled dataset's longest motion has 936 frames); how fast it is read is
    # measured by benchmarks/bench_readers.py, not asserted here
    sdk = motion(1000)
    rec = read_skeleton(write(tmp_path / "long.txt", msr_text(sdk)))
    assert rec.format == "msr" and rec.positions.shape == (1000, 20, 3) and rec.valid.all()
    np.testing.assert_array_equal(rec.positions, sdk.astype(np.float32))


# --- bad input -----------------------------------------------------------------------------------


def _truncated_npz() -> bytes:
    data = npz_bytes(positions=motion(50))
    return data[: len(data) // 2]


def _corrupted_npz() -> bytes:
    data = bytearray(npz_bytes(positions=motion(50)))
    mid = len(data) // 3
    data[mid : mid + 64] = bytes(64)
    return bytes(data)


_SDK = motion(2)
_MSR = msr_text(_SDK)
_MSR_LINES = _MSR.splitlines()

BAD_INPUTS = [
    # (id, file name, content or None for "do not create", format, words the message must contain)
    ("missing", "nope.txt", None, "auto", ["not found"]),
    ("empty", "empty.txt", b"", "auto", ["empty"]),
    ("blank", "blank.txt", "\n  \n\t\n", "msr", ["empty"]),
    ("msr-rows", "short.txt", "\n".join(_MSR_LINES[:25]), "msr", ["25 rows", "multiple of 20"]),
    (
        "msr-columns",
        "cols.txt",
        "\n".join(_MSR_LINES[:4] + ["1.0 2.0 3.0"] + _MSR_LINES[5:]),
        "auto",
        ["line 5", "found 3 columns", "expected 4"],
    ),
    (
        "msr-token",
        "token.txt",
        "\n".join(_MSR_LINES[:2] + ["1.0 2.0 abc 1.0"] + _MSR_LINES[3:]),
        "msr",
        ["line 3", "column 3", "non-numeric", "'abc'"],
    ),
    (
        "msr-unicode-token",
        "uni.txt",
        "\n".join(_MSR_LINES[:6] + ["1.0 2.0 3.0 \u00e9"] + _MSR_LINES[7:]),
        "msr",
        ["line 7", "non-numeric", "'\u00e9'"],
    ),
    ("binary", "bin.txt", b"\xff\xfe\x00\x81garbage", "msr", ["not a text file"]),
    (
        "utk-columns",
        "joints_s01_e02.txt",
        utk_text(_SDK).replace("1 ", "", 1),
        "utkinect",
        ["line 1", "found 60 columns", "expected 61"],
    ),
    (
        "utk-frame",
        "joints_s01_e03.txt",
        "2.5" + utk_text(_SDK)[1:],
        "utkinect",
        ["line 1", "frame number 2.5", "not an integer"],
    ),
    (
        "csv-columns",
        "cols.csv",
        csv_text(_SDK) + "1,2,3\n",
        "auto",
        ["line 4", "found 3 columns", "expected 60"],
    ),
    (
        "csv-token",
        "tok.csv",
        csv_text(_SDK).replace("\n", "\n" + ",".join(["x"] * 60) + "\n", 1),
        "csv",
        ["line 2", "non-numeric", "'x'"],
    ),
    ("csv-extra-field", "more.csv", csv_text(_SDK, False).replace(",", ",,", 1), "csv", ["61 col"]),
    (
        "csv-empty-field",
        "hole.csv",
        csv_text(_SDK, False)[csv_text(_SDK, False).index(",") :],
        "csv",
        ["line 1, column 1", "non-numeric token ''"],
    ),
    ("csv-header-only", "head.csv", csv_text(_SDK[:0]), "csv", ["no data rows"]),
    ("npz-joints", "j.npz", npz_bytes(positions=np.zeros((4, 15, 3))), "auto", ["15 joints"]),
    ("npz-shape", "s.npz", npz_bytes(positions=np.zeros((4, 60))), "npz", ["shape (4, 60)"]),
    ("npz-frames", "f.npz", npz_bytes(positions=np.zeros((0, 20, 3))), "npz", ["no frames"]),
    ("npz-dtype", "d.npz", npz_bytes(positions=np.full((1, 20, 3), "a")), "npz", ["dtype"]),
    ("npz-key", "k.npz", npz_bytes(xyz=np.zeros((4, 20, 3))), "npz", ["missing key", ": xyz"]),
    (
        "npz-valid",
        "v.npz",
        npz_bytes(positions=np.ones((4, 20, 3)), valid=np.ones(3, bool)),
        "npz",
        ["valid", "shape (3,)"],
    ),
    ("npz-not-zip", "n.npz", b"this is not a zip archive", "auto", ["not an npz", "zip"]),
    ("npz-truncated", "t.npz", _truncated_npz(), "npz", ["corrupt"]),
    ("npz-corrupted", "c.npz", _corrupted_npz(), "npz", ["corrupt"]),
    ("unknown-format", "u.txt", _MSR, "c3d", ["unknown format", "'c3d'"]),
    ("undetectable", "seven.txt", "1 2 3 4 5 6 7\n", "auto", ["cannot detect", "7 columns"]),
]


@pytest.mark.parametrize(
    ("name", "content", "fmt", "words"),
    [case[1:] for case in BAD_INPUTS],
    ids=[case[0] for case in BAD_INPUTS],
)
def test_bad_input_raises_one_line_input_error(
    tmp_path: Path, name: str, content: str | bytes | None, fmt: str, words: list[str]
) -> None:
    path = tmp_path / name
    if content is not None:
        write(path, content)
    with pytest.raises(InputError) as info:
        read_skeleton(path, format=fmt)  # type: ignore[arg-type]
    message = str(info.value)
    assert message.startswith(str(path) + ": "), message
    assert "\n" not in message
    for word in words:
        assert word in message, (word, message)
    err = info.value
    assert err.__cause__ is None and (err.__context__ is None or err.__suppress_context__)


def test_directory_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="directory"):
        read_skeleton(tmp_path)


def test_input_error_is_a_value_error_with_path(tmp_path: Path) -> None:
    path = tmp_path / "missing.csv"
    with pytest.raises(ValueError) as info:
        read_skeleton(path)
    assert isinstance(info.value, InputError) and info.value.path == str(path)


def test_npz_with_bad_member_is_wrapped(tmp_path: Path) -> None:
    # a zip whose positions member is not an .npy file at all
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("positions.npy", b"not numpy")
    path = write(tmp_path / "member.npz", buf.getvalue())
    with pytest.raises(InputError, match="corrupt or unreadable npz") as info:
        read_skeleton(path)
    assert str(path) in str(info.value)


# --- the format registry and detection ------------------------------------------------------------


def test_registry_lists_every_format_once_and_the_cli_offers_them() -> None:
    import argparse

    from jaxproj import io as jio
    from jaxproj.cli.main import build_parser

    names = jio.format_names()  # the first ones; formats added later follow them
    assert names[:7] == ("msr", "utkinect", "npz", "csv", "bvh", "ntu", "azure_kinect")
    assert len(set(names)) == len(names)
    for fmt in jio.FORMATS:
        assert jio.get_format(fmt.name) is fmt and fmt.description and callable(fmt.read)
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    retarget = sub.choices["retarget"]
    choices = next(a.choices for a in retarget._actions if a.dest == "format")
    assert tuple(choices) == ("auto", *jio.format_names())


def test_file_and_folder_detection_agree_on_every_recording(tmp_path: Path) -> None:
    from jaxproj.io.readers import recording_format

    sdk = motion(3)
    paths = all_formats(tmp_path, sdk)
    paths["csv-as-txt"] = write(tmp_path / "table.txt", csv_text(sdk))
    paths["short-header"] = write(tmp_path / "short.dat", "x,y,z\n" + csv_text(sdk, header=False))
    paths["msr-named-csv"] = write(tmp_path / "really_msr.csv", msr_text(sdk))
    for name, path in paths.items():
        rec = read_skeleton(path)
        assert recording_format(path) == (rec.format, ""), name
        np.testing.assert_array_equal(rec.positions, sdk.astype(np.float32), err_msg=name)


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("notes.txt", "Hello, this is a note about the recordings.\n"),  # one line of prose
        ("LICENSE", "MIT License\n\nCopyright (c) 2026 someone\n\nPermission is granted.\n"),
        ("README.md", "# Recordings\n\nTaken on Tuesday.\n"),
    ],
)
def test_a_file_of_no_known_format_says_so_and_lists_the_formats(
    tmp_path: Path, name: str, content: str
) -> None:
    from jaxproj.io import format_names
    from jaxproj.io.readers import recording_format

    path = write(tmp_path / name, content)
    with pytest.raises(InputError) as info:
        read_skeleton(path)
    message = str(info.value)
    assert message.startswith(f"{path}: cannot detect the format: "), message
    assert "no recording of any known format" in message
    assert all(f"{fmt}: " in message for fmt in format_names()), message
    assert "--format" not in message and "format=" not in message  # forcing cannot help
    assert "but no data rows" not in message and "\n" not in message
    fmt, why = recording_format(path)
    assert fmt is None and why and why in message
    for forced in format_names():  # indeed: no reader takes it
        with pytest.raises(InputError):
            read_skeleton(path, format=forced)
