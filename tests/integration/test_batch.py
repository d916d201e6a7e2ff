"""``jaxproj retarget`` over many recordings (``jaxproj.cli.batch``). The retargeting itself is
replaced by the robot's standing posture (the batch's wiring is under test: nothing compiles)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from fuzzing import assert_one_line_error, run_cli

from jaxproj import robots
from jaxproj.io.motion_files import load_motion

SAME = Path(__file__).resolve().parents[1] / "data" / "formats" / "same_motion"


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    from jaxproj.motion import retarget as rt

    seen: list[int] = []

    def standing(positions, valid, **kwargs):  # type: ignore[no-untyped-def]
        seen.append(len(valid))
        q = np.tile(robots.get(robots.DEFAULT).standing, (len(valid), 1)).astype(np.float32)
        return rt.RetargetResult(q, np.asarray(valid), kwargs["times"])

    def packed(positions, valid, times, skeleton, **kwargs):  # type: ignore[no-untyped-def]
        return [standing(p, v, times=t) for p, v, t in zip(positions, valid, times, strict=True)]

    monkeypatch.setattr(rt, "retarget", standing)
    monkeypatch.setattr(rt, "retarget_many", packed)
    return seen


@pytest.fixture
def data(tmp_path: Path) -> Path:
    """A folder of three recordings (one in a sub-folder), a README and a broken recording."""
    root = tmp_path / "data"
    (root / "more").mkdir(parents=True)
    shutil.copy(SAME / "131_01.kinect_v1.csv", root / "walk.csv")
    shutil.copy(SAME / "131_03.kinect_v1.csv", root / "more" / "hop.csv")
    shutil.copy(SAME / "131_03.smpl.npz", root / "hop_smpl.npz")
    (root / "README.md").write_text("# not a recording\n")
    lines = (SAME / "131_01.kinect_v1.csv").read_text().splitlines()
    (root / "broken.csv").write_text("\n".join(lines[:3] + ["1,2,3"]) + "\n")
    return root


def test_a_folder_is_retargeted_into_a_tree_and_a_bad_file_does_not_stop_it(
    data: Path, tmp_path: Path, calls: list[int], capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    code, text, err = run_cli(capsys, "retarget", str(data), "--out", str(out))
    assert code == 1  # one recording failed
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*.npz"))
    assert written == ["hop_smpl.npz", "more/hop.npz", "walk.npz"]
    assert len(calls) == 3
    assert "batch: 4 recordings: 3 written, 0 left out (--resume: output present), 1 failed" in text
    last = err.strip().splitlines()[-1]
    assert "broken.csv: failed: " in err and last.startswith(
        f"jaxproj: error: {data / 'broken.csv'}: "
    )
    assert last.count("broken.csv") == 1  # the file named once
    for name in written:
        m = load_motion(out / name)
        assert m.angles.shape[0] == 30 and m.meta["source"].startswith(str(data))
    # the same batch again: --resume leaves every written output out and retargets no more
    before = (out / "walk.npz").stat().st_mtime_ns
    code, text, _ = run_cli(capsys, "retarget", str(data), "--out", str(out), "--resume")
    assert code == 1 and len(calls) == 3 + 0 and "3 left out" in text
    assert (out / "walk.npz").stat().st_mtime_ns == before
    # without --resume or --force an existing output is refused before any work
    code, _, err = run_cli(capsys, "retarget", str(data), "--out", str(out))
    assert_one_line_error(code, err, "exists: --resume leaves it out, --force overwrites it")
    assert len(calls) == 3


def test_a_round_that_fails_as_a_whole_is_done_again_one_recording_at_a_time(
    data: Path, tmp_path: Path, calls: list[int], capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """The packed retargeting (``retarget_files``) raising for a whole round: the batch does
    that round again recording by recording (``retarget_file``) and writes what it writes."""
    from jaxproj.motion import retarget as rt

    def broken(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise RuntimeError("the packed call failed")

    monkeypatch.setattr(rt, "retarget_many", broken)
    out = tmp_path / "out"
    code, text, _ = run_cli(capsys, "retarget", str(data), "--out", str(out))
    assert code == 1 and len(calls) == 3  # each good recording retargeted alone
    assert "3 written" in text and "1 failed" in text
    assert sorted(p.name for p in out.rglob("*.npz")) == ["hop.npz", "hop_smpl.npz", "walk.npz"]
    # --no-pack: one recording at a time from the start (the packed call is never made)
    code, text, err = run_cli(capsys, "retarget", str(data), "--out", str(tmp_path / "one"),
                              "--no-pack")  # fmt: skip
    assert code == 1 and len(calls) == 6 and "3 written" in text
    assert "together" not in err


def test_files_and_lists_and_what_a_batch_refuses(
    data: Path, tmp_path: Path, calls: list[int], capsys: pytest.CaptureFixture[str]
) -> None:
    listed = tmp_path / "todo.txt"
    listed.write_text("# two recordings\nwalk.csv\n\nmore/hop.csv\nwalk.csv\n")
    shutil.move(listed, data / "todo.txt")
    out = tmp_path / "csv"
    code, text, err = run_cli(capsys, "retarget", f"@{data / 'todo.txt'}", str(data / "walk.csv"),
                              "--out", str(out), "--out-format", ".csv")  # fmt: skip
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["hop.csv", "walk.csv"]  # walk.csv once
    assert "2 written" in text and len(calls) == 2
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(data / "walk.csv", other / "walk.csv")
    for argv, words in (
        ([str(data / "walk.csv"), str(other / "walk.csv"), "--out", str(tmp_path / "x")],
         "would both write"),
        ([str(data), "--out", str(data / "walk.csv")], "a batch writes into a folder"),
        ([str(data), "--out", str(tmp_path / "all.npz")], "this names a file (4 recordings)"),
        ([str(data), "--out", str(tmp_path / "y"), "--plot", str(tmp_path / "p.png")],
         "--plot draws one recording"),
        ([f"@{tmp_path / 'none.txt'}", "--out", str(tmp_path / "z")], "no such list file"),
        ([str(tmp_path / "nothing"), str(data), "--out", str(tmp_path / "z")],
         "no such file or folder"),
        ([str(data / "walk.csv"), "--out", str(tmp_path / "w.npz"), "--processes",
          "localhost:1,2,0"], "--processes splits a batch"),
        ([str(data), "--out", str(tmp_path / "z"), "--processes", "localhost:1,2,5"],
         "with N >= 1 and 0 <= I < N"),
        ([str(data), "--out", str(tmp_path / "z"), "--processes", "two"], "expected HOST:PORT,N,I"),
        ([str(data / "walk.csv"), "--out", str(tmp_path / "w.npz"), "--no-pack"],
         "--no-pack is a batch's"),
        ([str(data / "walk.csv"), "--out", str(tmp_path / "w.npz"), "--devices", "2"],
         "--devices spreads a batch"),
        ([str(data), "--out", str(tmp_path / "z"), "--devices", "64"],
         "--devices 64: this process has"),  # at most 8 CPU devices (shards.MAX_SHARDS)
        ([str(data), "--out", str(tmp_path / "z"), "--devices", "some"],
         "--devices some: a count, 'all' or 'auto'"),
    ):  # fmt: skip
        code, _, err = run_cli(capsys, "retarget", *argv)
        assert_one_line_error(code, err, words)
    assert len(calls) == 2


CHILD = """
import sys

import numpy as np

from jaxproj import robots
from jaxproj.cli.main import main
from jaxproj.motion import retarget as rt


def standing(positions, valid, **kwargs):
    q = np.tile(robots.get(robots.DEFAULT).standing, (len(valid), 1)).astype(np.float32)
    q = q + np.float32(1e-3) * np.arange(len(valid), dtype=np.float32)[:, None]
    return rt.RetargetResult(q, np.asarray(valid), kwargs["times"])


def packed(positions, valid, times, skeleton, **kwargs):
    return [standing(p, v, times=t) for p, v, t in zip(positions, valid, times)]


rt.retarget = standing
rt.retarget_many = packed
sys.exit(main(sys.argv[1:]))
"""
"""A process of a batch: the command line with the retargeting replaced (as ``calls``)."""


def test_two_processes_write_the_files_one_writes(data: Path, tmp_path: Path) -> None:
    """``--processes``: two local processes on JAX's multi-process runtime (a local
    coordinator) share the batch; together they write what one process writes, to the bit."""
    import socket
    import subprocess
    import sys

    (data / "broken.csv").unlink()
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    one = subprocess.run([sys.executable, str(script), "retarget", str(data), "--out",
                          str(tmp_path / "one")], capture_output=True, text=True)  # fmt: skip
    assert one.returncode == 0, one.stderr
    procs = [
        subprocess.Popen(
            [
                sys.executable,
                str(script),
                "retarget",
                str(data),
                "--out",
                str(tmp_path / "two"),
                "--processes",
                f"localhost:{port},2,{i}",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for i in range(2)
    ]
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e for _, e in outs]
    assert "2 written" in outs[0][0] and "1 written" in outs[1][0]  # 3 recordings, shared
    names = sorted(p.relative_to(tmp_path / "one") for p in (tmp_path / "one").rglob("*.npz"))
    assert names == sorted(
        p.relative_to(tmp_path / "two") for p in (tmp_path / "two").rglob("*.npz")
    )
    for name in names:
        a, b = load_motion(tmp_path / "one" / name), load_motion(tmp_path / "two" / name)
        assert np.array_equal(a.angles, b.angles) and np.array_equal(a.times, b.times)


def test_build_and_evaluate_read_a_recording_or_a_list_as_data(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--data FILE`` and ``--data @LIST`` (``options.load_data``, which ``build`` and
    ``evaluate`` share): the files named, read by the folder's rules, the unreadable noted."""
    from jaxproj.cli import options
    from jaxproj.errors import ConfigError

    listed = tmp_path / "todo.txt"
    listed.write_text(f"# two recordings and a broken one\n{data / 'walk.csv'}\nmore/hop.csv\n"
                      "broken.csv\n")  # fmt: skip
    shutil.move(listed, data / "todo.txt")  # relative paths from the list's folder
    seqs, contents = options.load_data(f"@{data / 'todo.txt'}", None, "test")
    assert [s.name for s in seqs] == ["walk", "hop"]
    assert [name for name, _ in contents.unreadable] == ["broken.csv"]
    assert "unreadable recording, not used" in capsys.readouterr().err
    seqs, _ = options.load_data(str(data / "hop_smpl.npz"), None, "test")
    assert [s.name for s in seqs] == ["hop_smpl"] and len(seqs[0].positions) == 30
    with pytest.raises(ConfigError, match="no such list file"):
        options.load_data(f"@{data / 'todo.txt'}+@{tmp_path / 'none.txt'}", None, "test")
    with pytest.raises(ConfigError, match="at most one folder, file or list"):
        options.load_data(f"{data / 'walk.csv'}+{data / 'hop_smpl.npz'}", None, "test")
