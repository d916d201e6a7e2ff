"""Bad input, tested like a library people depend on (issue 15): property / fuzz tests of every
reader, the CLI's battery of bad files (in process and driven from the outside), and bad
configurations that must fail before anything is traced.

Every example is derandomised (``derandomize=True``, no example database), so CI sees the same
examples every run; the whole module runs in well under a minute on 2 cores.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fuzzing import (
    READER_BAD,
    assert_one_line_error,
    frame_kinds,
    fuzz,
    make_frames,
    msr_file,
    no_tracing,
    npz_file,
    run_cli,
    utk_file,
    write_recording,
)
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import jaxproj
from jaxproj.cli import main
from jaxproj.errors import ConfigError, InputError
from jaxproj.io import datasets
from jaxproj.io.motion_files import load_motion
from jaxproj.io.readers import read_skeleton
from jaxproj.motion.retarget import retarget
from jaxproj.motion.smoothing import SmoothingParams
from jaxproj.projection import api as engine
from jaxproj.robots.nao_h25 import robot

_ONES = np.ones((3, 20, 3))


class TestReaderFuzz:
    """Every reader, fuzzed: a recording with finite positions and ``valid`` marking the bad
    frames, or a one-line ``InputError`` naming the file — never another exception, never NaN."""

    @fuzz(60)
    @given(
        kinds=frame_kinds,
        seed=st.integers(0, 2**16),
        fmt=st.sampled_from(["msr", "utkinect", "csv", "npz"]),
        variant=st.integers(0, 7),
    )
    def test_bad_frames_are_kept_zeroed_and_marked_invalid(self, kinds, seed, fmt, variant):
        pos = make_frames(kinds, seed)
        with tempfile.TemporaryDirectory() as tmp:
            path = write_recording(Path(tmp), fmt, pos, variant)
            try:
                rec = read_skeleton(path)
            except InputError as e:
                # a table's bones are read for units and a guessed layout (jaxproj.io.plausible):
                # refused, in one line, only where a person's frames are not the majority
                msg = str(e)
                assert msg.startswith(f"{path}: ") and "\n" not in msg, msg
                assert fmt in ("csv", "npz"), msg
                assert "units are none of" in msg or "bones are no person's" in msg, msg
                assert 2 * kinds.count("ok") <= len(kinds), msg
                return
        bad = np.array([k in READER_BAD for k in kinds])
        assert rec.format == fmt and rec.positions.dtype == np.float32
        np.testing.assert_array_equal(rec.valid, ~bad)
        assert np.isfinite(rec.positions).all() and (rec.positions[bad] == 0).all()
        np.testing.assert_array_equal(rec.positions[~bad], pos[~bad])  # bit-exact, 1e+-30 too
        assert np.isfinite(rec.times).all() and (np.diff(rec.times) > 0).all()

    @fuzz(40)
    @given(
        frames=st.lists(st.integers(0, 40), min_size=1, max_size=10),
        seed=st.integers(0, 2**16),
        variant=st.integers(0, 3),
    )
    def test_utkinect_duplicated_and_unordered_frame_numbers(self, frames, seed, variant):
        pos = make_frames(["ok"] * len(frames), seed)
        text = utk_file(pos, frames, "\r\n" if variant & 1 else "\n", " " if variant & 2 else "")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "joints_s01_e01.txt"
            path.write_text(text)
            rec = read_skeleton(path)
        first = {}
        for i, n in enumerate(frames):
            first.setdefault(n, i)  # the first line of each frame number is kept
        numbers = sorted(first)
        np.testing.assert_array_equal(rec.positions, pos[[first[n] for n in numbers]])
        np.testing.assert_allclose(rec.times, (np.array(numbers) - numbers[0]) / 30.0, atol=1e-12)

    _TOKENS = ["1", "0", "-2.5", "1e30", "1e-30", "nan", "inf", "-inf", "1e400", "x", "", "0x1",
               "9223372036854775808", "1e19", "3.0"]  # fmt: skip

    @fuzz(150)
    @given(
        lines=st.lists(
            st.one_of(
                st.sampled_from([3, 4, 5, 60, 61, 62])
                .flatmap(
                    lambda n: st.lists(
                        st.sampled_from(TestReaderFuzz._TOKENS), min_size=n, max_size=n
                    )  # fmt: skip
                )
                .map(" ".join),
                st.lists(
                    st.sampled_from(["1", "0.5", "nan", "1e30"]), min_size=60, max_size=60
                ).map(",".join),
                st.integers(-5, 10**20).map(lambda n: f"{n} " + " ".join(["0.5"] * 60)),
                st.text("0123456789 .,e-+\r\t\nnaif\u00a0", max_size=30),
            ),
            max_size=45,
        ),
        fmt=st.sampled_from(["auto", "msr", "utkinect", "csv"]),
        crlf=st.booleans(),
    )
    def test_any_text_reads_or_is_one_line_input_error(self, lines, fmt, crlf):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "fuzz.txt"
            path.write_bytes(("\r\n" if crlf else "\n").join(lines).encode())
            try:
                rec = read_skeleton(path, format=fmt)
            except InputError as err:
                msg = str(err)
                assert msg.startswith(f"{path}: ") and "\n" not in msg
                return
        assert rec.positions.shape == (len(rec.valid), 20, 3) and len(rec.valid) >= 1
        assert np.isfinite(rec.positions).all() and (rec.positions[~rec.valid] == 0).all()
        assert np.isfinite(rec.times).all() and (np.diff(rec.times) > 0).all()

    @fuzz(80)
    @given(
        positions=st.tuples(
            st.sampled_from([np.float16, np.float32, np.float64, np.int32, np.bool_, "U2"]),
            st.one_of(
                st.just((3, 20, 3)),
                st.tuples(st.integers(0, 3), st.sampled_from([19, 20]), st.sampled_from([2, 3])),
            ),
        ).flatmap(lambda t: hnp.arrays(t[0], t[1])),
        extra=st.fixed_dictionaries(
            {},
            optional={
                "valid": hnp.arrays(
                    st.sampled_from([np.bool_, np.int8, np.float32]), st.sampled_from([(3,), (2,)])
                ),
                "times": hnp.arrays(
                    st.sampled_from([np.float64, np.int64, np.complex64]),
                    st.sampled_from([(3,), (2,)]),
                ),
                "fps": st.one_of(
                    hnp.arrays(st.sampled_from([np.float64, np.int64]), st.just(())),
                    st.sampled_from([0.0, -1.0, 1e-310, 30.0, 1e300, np.nan]).map(np.float64),
                ),
            },
        ),
        fps=st.sampled_from([None, 30.0, 1e-310, 1e300, float("nan")]),
    )
    @example(positions=_ONES, extra={"fps": np.float64(1e-310)}, fps=None)
    @example(positions=_ONES, extra={"times": np.array([0.0, 1e-300, 1e300])}, fps=None)
    @example(positions=_ONES, extra={"valid": np.array([0.5, 1, 0], np.float32)}, fps=None)
    def test_any_npz_reads_or_is_one_line_error(self, positions, extra, fps):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "fuzz.npz"
            path.write_bytes(npz_file(positions, **extra))
            try:
                rec = read_skeleton(path, fps=fps)
            except InputError as err:
                assert str(err).startswith(f"{path}: ") and "\n" not in str(err)
                return
            except ConfigError as err:  # the fps argument, not the file
                assert fps is not None and "fps" in str(err) and "\n" not in str(err)
                return
        assert rec.positions.dtype == np.float32 and np.isfinite(rec.positions).all()
        assert np.isfinite(rec.times).all() and (np.diff(rec.times) > 0).all()


# --- the CLI's battery of bad files --------------------------------------------------------------

_GOOD = make_frames(["ok", "ok"], 0)


def _npz(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


_LINES = msr_file(_GOOD).splitlines()
_TRUNCATED_ROW = "\n".join(_LINES[:6] + [" ".join(_LINES[6].split()[:3])] + _LINES[7:])


_BVH_HIERARCHY = (
    "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
    "  End Site\n  {\n    OFFSET 0 1 0\n  }\n}\n"
)  # 10 lines: a one-joint BVH skeleton (BVH: tests/io/test_bvh.py)


def _truncated_npz() -> bytes:
    data = npz_file(make_frames(["ok"] * 30, 1))
    return data[: len(data) // 2]


BAD_FILES: list[tuple[str, str, bytes | str | None, list[str]]] = [
    # (id, file name, content: None = do not create, "<dir>" = a directory, words of the message)
    ("missing", "nope.txt", None, ["not found"]),
    ("directory", "adir.txt", "<dir>", ["a folder with no recording"]),  # a batch's input
    ("empty", "empty.txt", b"", ["empty"]),
    ("whitespace", "blank.txt", " \r\n\t\n", ["empty"]),
    ("rows-not-20", "rows.txt", "\n".join(msr_file(_GOOD).splitlines()[:25]), ["multiple of 20"]),
    ("truncated-row", "trunc.txt", _TRUNCATED_ROW, ["line 7", "found 3 columns", "expected 4"]),
    ("non-numeric", "tok.txt", msr_file(_GOOD).replace("1\n", "one\n", 1), ["non-numeric"]),
    ("binary", "bin.txt", b"\x00\xff\xfe\x81 garbage", ["not a text file"]),
    ("corrupt-npz", "corrupt.npz", b"PK\x03\x04" + bytes(200), ["corrupt"]),
    ("truncated-npz", "t.npz", _truncated_npz(), ["corrupt"]),
    ("npz-no-positions", "k.npz", _npz(xyz=_GOOD), ["missing key 'positions'", "xyz"]),
    ("npz-joints", "j.npz", npz_file(np.zeros((2, 15, 3))), ["15 joints"]),
    ("csv-joints", "j.csv", "\n".join(["0.5," * 44 + "0.5"] * 2), ["found 45 columns"]),
    (
        "utk-frame-not-integer",
        "joints_s01_e01.txt",
        "2.5" + utk_file(_GOOD, [1, 2]).split("\n", 1)[1],
        ["not an integer"],
    ),
    ("utk-frame-huge", "joints_s01_e02.txt", utk_file(_GOOD, [1, 10**17]), ["out of range"]),
    ("utk-frames-span", "joints_s01_e03.txt", utk_file(_GOOD, [0, 2**40]), ["time axis spans"]),
    ("npz-times", "times.npz", npz_file(_GOOD, times=np.array([1.0, 0.5])), ["increase"]),
    ("npz-fps", "fps.npz", npz_file(_GOOD, fps=np.float64(0.0)), ["fps"]),
    ("npz-fps-tiny", "fps2.npz", npz_file(_GOOD, fps=np.float64(1e-310)), ["fps must be one"]),
    ("npz-times-step", "t1.npz", npz_file(_GOOD, times=np.array([0.0, 1e-300])), ["1e-06 s"]),
    ("npz-times-span", "t2.npz", npz_file(_GOOD, times=np.array([0.0, 1e300])), ["spans 1e+300"]),
    ("undetectable", "seven.txt", "1 2 3 4 5 6 7\n", ["cannot detect the format"]),
    ("bvh-no-motion", "clip.bvh", _BVH_HIERARCHY, ["no MOTION section"]),
    ("bvh-row", "row.bvh", _BVH_HIERARCHY + "MOTION\nFrames: 2\nFrame Time: 0.1\n1 2 3\n4 5\n",
     ["line 15: found 2 values, expected 3"]),
    ("bvh-token", "tok.txt", _BVH_HIERARCHY + "MOTION\nFrames: 1\nFrame Time: 0.1\n1 x 3\n",
     ["line 14, column 2: non-numeric token 'x'"]),
    # readable, but not one valid frame: refused (issue 42), not a standing pose with exit 0
    ("all-nan-npz", "nan.npz", npz_file(np.full((50, 20, 3), np.nan)),
     ["no valid frame among 50: 50 marked invalid (lost tracking or non-finite values); "
      "nothing written"]),
    ("all-lost-msr", "lost.txt", msr_file(np.zeros((3, 20, 3))),
     ["no valid frame among 3: 3 marked invalid (lost tracking or non-finite values)"]),
]  # fmt: skip


def _make(tmp_path: Path, name: str, content: bytes | str | None) -> Path:
    path = tmp_path / name
    if content == "<dir>":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return path


class TestCliBattery:
    """``jaxproj retarget`` on every bad file: exit status 2, one stderr line naming the file and
    the problem, no traceback, no output file; and bad-but-readable recordings retarget to
    finite angles within the joint limits, with ``valid`` marking the bad frames."""

    @pytest.mark.parametrize(
        ("name", "content", "words"),
        [case[1:] for case in BAD_FILES],
        ids=[case[0] for case in BAD_FILES],
    )
    def test_bad_file_is_one_line_exit_2(self, tmp_path, capsys, name, content, words):
        src = _make(tmp_path, name, content)
        out = tmp_path / "out.npz"
        code, _, err = run_cli(capsys, "retarget", src, "--out", out)
        assert_one_line_error(code, err, str(src), *words)
        assert not out.exists()

    def test_bvh_scale_that_leaves_no_valid_frame(self, tmp_path, capsys):
        """``--bvh-scale 0.00001``: every bone shorter than 1 mm, so no valid frame: one line
        naming the file, the count and the option to check; exit 2, nothing written."""
        src = Path(__file__).resolve().parents[1] / "data" / "cmu_bvh" / "131_03_every6.bvh"
        out = tmp_path / "out.json"
        code, stdout, err = run_cli(capsys, "retarget", src, "--bvh-scale", "0.00001", "--out", out)
        assert_one_line_error(
            code, err, f"{src}: no valid frame among 184: 184 with a degenerate skeleton",
            "bones shorter than 1 mm", "check --bvh-scale", "nothing written",
        )  # fmt: skip
        assert stdout == "" and not out.exists()

    def test_unreadable_file(self, tmp_path, capsys, monkeypatch):
        """A file the process may not read (monkeypatched: the tests may run as root)."""
        src = tmp_path / "locked.txt"
        src.write_text(msr_file(_GOOD))
        real = Path.read_bytes

        def read_bytes(self: Path) -> bytes:
            if self.name == "locked.txt":
                raise PermissionError(13, "Permission denied", str(self))
            return real(self)

        monkeypatch.setattr(Path, "read_bytes", read_bytes)
        code, _, err = run_cli(capsys, "retarget", src, "--out", tmp_path / "o.npz")
        assert_one_line_error(code, err, str(src), "cannot read", "Permission denied")

    @fuzz(12)
    @given(
        kinds=frame_kinds,
        seed=st.integers(0, 2**16),
        fmt=st.sampled_from(["msr", "utkinect", "csv", "npz"]),
        out_ext=st.sampled_from(["npz", "csv", "json"]),
        smooth=st.booleans(),
    )
    def test_nasty_recordings_retarget_to_finite_angles(self, kinds, seed, fmt, out_ext, smooth):
        pos = make_frames(kinds, seed)
        with tempfile.TemporaryDirectory() as tmp:
            src = write_recording(Path(tmp), fmt, pos, seed % 8)
            out = Path(tmp) / f"motion.{out_ext}"  # may be the input itself (csv, npz)
            before = out.read_bytes() if out.exists() else None
            code = main(["retarget", str(src), "--out", str(out)]
                        + ([] if smooth else ["--no-smooth"]))  # fmt: skip
            if out == src:  # the output would replace the recording: refused (issue 56)
                assert code == 2 and out.read_bytes() == before
                return
            if "ok" not in kinds:  # no usable frame: an error (exit 2), nothing written
                assert code == 2
                assert (out.read_bytes() if out.exists() else None) == before
                return
            assert code == 0
            m = load_motion(out)
        assert m.angles.shape == (len(kinds), 26) and np.isfinite(m.angles).all()
        assert (m.angles >= robot.LOWER).all() and (m.angles <= robot.UPPER).all()
        assert np.isfinite(m.times).all()
        if out_ext != "csv":  # a CSV has no validity column
            # only the real frames are usable: non-finite and lost frames (the reader), 1e30 /
            # 1e-30 scales, far-away and zero-length bones (the descriptor) are marked invalid
            np.testing.assert_array_equal(m.valid, [k == "ok" for k in kinds])


def _subprocess_env() -> dict[str, str]:
    """The environment of a child ``python -m jaxproj.cli``: this tree's jaxproj first."""
    root = str(Path(jaxproj.__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
    env.setdefault("JAX_PLATFORMS", "cpu")
    return env


class TestCliFromOutside:
    """The same battery driven from the outside: ``python -m jaxproj.cli`` in a child process
    exits 2 with one ``jaxproj: error:`` line and no traceback."""

    def test_bad_inputs_from_a_child_process(self, tmp_path):
        cases = {case[0]: case for case in BAD_FILES}
        runs = []
        for key in ("missing", "directory", "rows-not-20", "corrupt-npz", "utk-frame-huge",
                    "all-nan-npz"):  # fmt: skip
            _, name, content, words = cases[key]
            src = _make(tmp_path, name, content)
            argv = ["retarget", str(src), "--out", str(tmp_path / f"{key}.npz")]
            runs.append((argv, [str(src), *words]))
        notamodel = _make(tmp_path, "p.npz", npz_file(_GOOD))
        runs.append(
            (
                ["retarget", str(tmp_path / "rows.txt"), "--out", str(tmp_path / "x.npz"),
                 "--method", "relaxed", "--model", str(notamodel)],
                [str(notamodel), "not a jaxproj model"],
            )
        )  # fmt: skip
        runs.append((["build", "--landmarks", "0", "--out", str(tmp_path / "m.npz")],
                     ["--landmarks", "0 is out of range", "2..100000"]))  # fmt: skip
        env = _subprocess_env()
        procs = [
            (
                subprocess.Popen(
                    [sys.executable, "-m", "jaxproj.cli", *argv],
                    env=env,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    text=True,
                ),
                words,
            )
            for argv, words in runs
        ]
        for proc, words in procs:
            out, err = proc.communicate(timeout=300)
            assert_one_line_error(proc.returncode, err, *words)
            assert out == ""
        assert not list(tmp_path.glob("*.tmp*")) and not list(tmp_path.glob(".*"))


# --- configuration ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def descriptors() -> np.ndarray:
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1], actions=[1]))
    return np.unique(d, axis=0)[:30]


def _positions(t: int = 5) -> np.ndarray:
    return make_frames(["ok"] * t, 3)


CONFIG_CASES = [
    # (id, call, words of the ConfigError)
    ("landmarks-0", lambda d: engine.BuildConfig(landmarks=0), ["landmarks=0", ">= 2"]),
    (
        "k-above-landmarks",
        lambda d: engine.BuildConfig(landmarks=20, k=32),
        ["k=32", "landmark count 20", "lower k"],
    ),  # fmt: skip
    ("bandwidth-0", lambda d: engine.BuildConfig(bandwidth=0.0), ["bandwidth=0.0", "> 0"]),
    ("bandwidth-neg", lambda d: engine.BuildConfig(bandwidth=(0.1, -1.0, 0.1)), ["bandwidth=-1"]),
    ("hidden-below-k", lambda d: engine.BuildConfig(k=16, hidden=8), ["hidden=8", "k=16"]),
    ("per-chain-count", lambda d: engine.BuildConfig(k=(16, 16)), ["k has 2 values", "3 chains"]),
    ("unknown-chains", lambda d: engine.BuildConfig(chains="legs"), ["unknown chain set 'legs'"]),
    ("unknown-bones", lambda d: engine.BuildConfig(bones=("neck", "tail")), ["'tail'"]),
    ("ik-bones", lambda d: engine.BuildConfig(bones=("neck",)), ["IK needs the bones"]),
    (
        "too-few-frames",
        lambda d: engine.build(d, engine.BuildConfig(landmarks=50)),
        ["left_arm", "landmarks=50", "only", "distinct", "lower the landmark count"],
    ),  # fmt: skip
    (
        "too-few-frames-whole",
        lambda d: engine.build(d, engine.BuildConfig(chains="whole", landmarks=31, k=8, hidden=8)),
        ["whole", "landmarks=31", "only 30 distinct"],
    ),  # fmt: skip
    (
        "descriptor-width",
        lambda d: engine.build(d[:, :12], engine.BuildConfig(landmarks=5)),
        ["12 columns", "15"],
    ),  # fmt: skip
    ("retarget-no-model", lambda d: retarget(_positions(), method="full"), ["needs a projector"]),
    ("retarget-bones", lambda d: retarget(_positions(), bones=("neck", "tail")), ["'tail'"]),
    ("retarget-method", lambda d: retarget(_positions(), method="fast"), ["method must be"]),
    (
        "retarget-times",
        lambda d: retarget(_positions(3), times=np.array([0.0, 0.2, 0.1])),
        ["increase strictly"],
    ),  # fmt: skip
    (
        "retarget-times-span",
        lambda d: retarget(_positions(2), times=np.array([0.0, 1e300])),
        ["span at most"],
    ),  # fmt: skip
    ("retarget-shape", lambda d: retarget(np.zeros((0, 20, 3))), ["T >= 1"]),
    ("smoothing", lambda d: SmoothingParams(alpha=2.0), ["alpha"]),
]


class TestConfigErrors:
    """Bad settings: a ``ConfigError`` saying what to change, raised before JAX traces anything
    (no ``jaxpr_trace`` event while it is raised)."""

    @pytest.mark.parametrize(
        ("call", "words"), [c[1:] for c in CONFIG_CASES], ids=[c[0] for c in CONFIG_CASES]
    )
    def test_config_error_before_tracing(self, descriptors, call, words):
        with no_tracing() as traced, pytest.raises(ConfigError) as info:
            call(descriptors)
        assert traced == [], traced
        msg = str(info.value)
        assert "\n" not in msg
        for w in words:
            assert w in msg, (w, msg)

    def test_fps_of_read_skeleton(self, tmp_path):
        src = tmp_path / "a.txt"
        src.write_text(msr_file(_GOOD))
        for fps in (0.0, -1.0, float("nan"), 1e-310, 1e300):
            with pytest.raises(ConfigError, match="fps must be a frame rate"):
                read_skeleton(src, fps=fps)

    @pytest.mark.parametrize(
        ("argv", "words"),
        [
            (
                ["build", "--landmarks", "0"],
                ["argument --landmarks: 0 is out of range", "2..100000"],
            ),
            (["build", "--bandwidth", "0"], ["argument --bandwidth: 0 is out of range", "> 0"]),
            (["build", "--bandwidth", "0.1,0.2"], ["bandwidth has 2 values for 3 chains"]),
            (["build", "--landmarks", "100", "--k", "16", "--hidden", "8"], ["hidden=8"]),
            (["build", "--landmarks", "10", "--k", "16"], ["k=16 is larger", "landmark count 10"]),
            (
                ["build", "--subjects", "1", "--landmarks", "5000"],
                ["landmarks=5000", "distinct valid frames", "--landmarks"],
            ),  # fmt: skip
            (["build", "--subjects", "11", "--landmarks", "50"], ["subjects", "[11]"]),
            (
                ["evaluate", "--model", "m.npz", "--devices", "0", "--json", "r.json"],
                ["--devices 0"],
            ),  # fmt: skip
        ],
        ids=[
            "landmarks-0",
            "bandwidth-0",
            "bandwidth-count",
            "hidden",
            "k-above-landmarks",
            "too-few-frames",
            "subject-range",
            "devices-0",
        ],  # fmt: skip
    )
    def test_cli_config_errors(self, tmp_path, capsys, argv, words):
        if argv[0] == "build":
            argv = [*argv, "--out", str(tmp_path / "m.npz")]
        if words[0].startswith("argument "):  # a range the parser checks (issue 56)
            with pytest.raises(SystemExit) as info:
                run_cli(capsys, *argv)
            err = capsys.readouterr().err
            (line,) = err.strip().splitlines()
            assert info.value.code == 2 and line.startswith(f"jaxproj {argv[0]}: error: ")
            assert all(w in line for w in words), line
        else:
            code, _, err = run_cli(capsys, *argv)
            assert_one_line_error(code, err, *words)
        assert not (tmp_path / "m.npz").exists()

    def test_retarget_cli_settings(self, tmp_path, capsys):
        src = tmp_path / "a.txt"
        src.write_text(msr_file(_GOOD))
        with pytest.raises(SystemExit) as info:  # a range the parser checks (issue 56)
            run_cli(capsys, "retarget", src, "--out", tmp_path / "o.npz", "--fps", "0")
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert info.value.code == 2 and "argument --fps: 0 is out of range" in line
        code, _, err = run_cli(
            capsys, "retarget", src, "--out", tmp_path / "o.npz", "--method", "full"
        )
        assert_one_line_error(code, err, "--method full needs --model")
        code, _, err = run_cli(capsys, "retarget", src, "--out", tmp_path / "o.bvh")
        assert_one_line_error(code, err, ".npz, .csv or .json")

    def test_unknown_choices_are_argparse_errors(self, capsys):
        """Names the parser knows (chain sets, bones, methods) are refused by argparse: status 2,
        one error line (no usage block: ``options.Parser``), no traceback."""
        for argv in (["build", "--chains", "legs", "--out", "m.npz"],
                     ["retarget", "a.txt", "--out", "o.npz", "--bones", "tail"]):  # fmt: skip
            with pytest.raises(SystemExit) as info:
                main(argv)
            err = capsys.readouterr().err
            assert info.value.code == 2 and "invalid choice" in err and "Traceback" not in err
            assert len(err.strip().splitlines()) == 1 and "usage:" not in err
