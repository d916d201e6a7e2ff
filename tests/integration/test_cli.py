import argparse
import json
import os
from pathlib import Path

import jax
import numpy as np
import pytest

from jaxproj.cli import build_parser, main, projector
from jaxproj.cli import cache as cli_cache
from jaxproj.cli.retarget import EXPECTED_LOW_SHARE, confidence_lines
from jaxproj.eval import evaluate
from jaxproj.human.skeleton import descriptor, level_neck, recording_neck_tilt
from jaxproj.io import datasets
from jaxproj.io.readers import MSR_TO_SDK
from jaxproj.projection import api as engine
from jaxproj.projection.confidence import LOW_CONFIDENCE
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import ik, robot


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _write_msr(path: Path, positions: np.ndarray) -> None:
    """MSR Action3D text: 20 rows of `x y z c` per frame, MSR joint order."""
    msr = np.empty_like(positions)
    msr[:, MSR_TO_SDK] = positions
    rows = np.concatenate([msr.reshape(-1, 3), np.ones((msr.size // 3, 1))], axis=1)
    np.savetxt(path, rows, fmt="%.6f")


def test_info_json(capsys):
    code, out, _ = _run(capsys, "info", "--json")
    assert code == 0
    info = json.loads(out)
    assert info["robot"]["joints"] == list(robot.JOINT_NAMES) and len(info["robot"]["joints"]) == 26
    assert info["robot"]["driven_joints"] == list(robot.DRIVEN_JOINTS)
    mjcf = Path(info["robot"]["mjcf"])
    assert mjcf.is_absolute() and mjcf.is_file()
    msr = info["datasets"]["msr_action3d"]
    assert (msr["sequences"], msr["frames"], msr["subjects"]) == (567, 23478, 10)
    utk = info["datasets"]["utkinect_action3d"]  # the other bundled dataset is listed too
    want = datasets.dataset_summary("utkinect")
    assert utk == {k: want[k] for k in ("recordings", "frames", "subjects", "segments")}
    assert (utk["recordings"], utk["subjects"]) == (10, 5)
    assert info["devices"]
    code, out, _ = _run(capsys, "info")
    assert code == 0 and "dataset utkinect_action3d (--data utkinect): 10 recordings" in out
    # the compilation cache: the run's folder (tests/conftest.py), never the user's home
    run_cache = Path(os.environ["JAXPROJ_CACHE_DIR"])
    assert Path(info["compilation_cache"]["folder"]) == run_cache
    assert not run_cache.is_relative_to(cli_cache.default_folder())
    assert f"compilation cache: {run_cache} (" in out
    code, out, _ = _run(capsys, "info", "--json", "--no-cache")
    assert code == 0 and json.loads(out)["compilation_cache"] == {
        "folder": None, "files": 0, "bytes": 0}  # fmt: skip
    assert jax.config.jax_enable_compilation_cache  # the run's settings are back


def test_cache_folder_order(tmp_path, monkeypatch) -> None:
    """$JAXPROJ_CACHE_DIR, else JAX's own folder, else $XDG_CACHE_HOME/jaxproj/jax-cache, else
    ~/.cache/jaxproj/jax-cache; a folder that cannot be made: a warning, no cache."""
    assert cli_cache.folder() == Path(os.environ["JAXPROJ_CACHE_DIR"])
    monkeypatch.delenv("JAXPROJ_CACHE_DIR")
    assert cli_cache.folder() == Path(jax.config.jax_compilation_cache_dir)
    saved = jax.config.jax_compilation_cache_dir
    try:
        jax.config.update("jax_compilation_cache_dir", None)
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
        assert cli_cache.folder() == tmp_path / "xdg" / "jaxproj" / "jax-cache"
        monkeypatch.delenv("XDG_CACHE_HOME")
        monkeypatch.setenv("HOME", str(tmp_path / "home"))
        assert cli_cache.folder() == tmp_path / "home" / ".cache" / "jaxproj" / "jax-cache"
    finally:
        jax.config.update("jax_compilation_cache_dir", saved)
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("JAXPROJ_CACHE_DIR", str(tmp_path / "file" / "cache"))
    with cli_cache.compilation_cache() as used:
        assert used is None and not jax.config.jax_enable_compilation_cache
    assert jax.config.jax_enable_compilation_cache


def test_retarget_msr_text_with_lost_frames(tmp_path, capsys):
    seq = next(s for s in datasets.msr_action3d(subjects=[2], actions=[13]) if s.take == 2)
    assert (~seq.valid).any() and seq.valid.any()
    src = tmp_path / "a13_s02_e02_skeleton3D.txt"
    _write_msr(src, seq.positions)
    out = tmp_path / "out.npz"
    argv = ["retarget", str(src), "--out", str(out), "--no-smooth", "--no-feasible"]
    code, stdout, _ = _run(capsys, *argv)
    assert code == 0 and "valid" in stdout
    res = np.load(out)
    angles, valid = res["angles"], res["valid"]
    assert angles.shape == (len(seq.valid), 26) and angles.dtype == np.float32
    assert list(res["joint_names"]) == list(robot.JOINT_NAMES)
    np.testing.assert_array_equal(valid, seq.valid)
    assert np.isfinite(angles).all()
    assert (angles >= robot.LOWER).all() and (angles <= robot.UPPER).all()
    # valid frames are the IK of the frame; invalid ones hold the last valid (or first valid)
    d, _ = descriptor(seq.positions)  # as retarget reads it: the neck levelled per recording
    d = level_neck(d, recording_neck_tilt(d, seq.valid))
    want = np.asarray(ik.solve(d))
    np.testing.assert_allclose(angles[valid], want[valid], atol=1e-5)
    idx = np.flatnonzero(valid)
    for t in np.flatnonzero(~valid):
        src_t = idx[idx < t].max() if (idx < t).any() else idx.min()
        np.testing.assert_array_equal(angles[t], angles[src_t])


def test_retarget_smoothing_changes_the_motion_and_stays_in_limits(tmp_path, capsys):
    seq = datasets.msr_action3d(subjects=[1], actions=[1])[0]
    src = tmp_path / "m.npz"
    np.savez(src, positions=seq.positions)
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    assert _run(capsys, "retarget", str(src), "--out", str(a), "--no-feasible")[0] == 0
    argv = ["retarget", str(src), "--out", str(b), "--no-smooth", "--no-feasible"]
    assert _run(capsys, *argv)[0] == 0
    sa, sb = np.load(a)["angles"], np.load(b)["angles"]
    assert not np.allclose(sa, sb)
    assert (sa >= robot.LOWER).all() and (sa <= robot.UPPER).all()
    jerk = [np.mean(np.diff(x[:, robot.DRIVEN_INDEX], n=3, axis=0) ** 2) for x in (sa, sb)]
    assert jerk[0] < jerk[1]


def _utk_text(positions: np.ndarray, frames: np.ndarray) -> str:
    pairs = zip(frames, positions, strict=True)
    rows = [f"{f} " + " ".join(f"{v:.6f}" for v in p.reshape(-1)) for f, p in pairs]
    return "\n".join(rows) + "\n"


def test_retarget_utkinect_to_robot_files_with_time_and_no_speed_violation(tmp_path, capsys):
    """The issue's path: a UTKinect recording -> CSV and NAOqi JSON a NAO can play."""
    import json

    from jaxproj.io.motion_files import load_motion
    from jaxproj.motion.feasible import feasibility_report

    seq = datasets.utkinect_action3d(subjects=[3], segments=False)[0]
    n = 160
    src = tmp_path / "joints_s03_e01.txt"
    src.write_text(_utk_text(seq.positions[:n], seq.frame_numbers[:n]))
    want_t = (seq.frame_numbers[:n] - seq.frame_numbers[0]) / 30.0
    raw = tmp_path / "raw.npz"
    args = ("--no-feasible", "--rate", "input")  # the file's own (uneven) frame times
    assert _run(capsys, "retarget", str(src), "--out", str(raw), *args)[0] == 0
    raw_m = load_motion(raw)
    np.testing.assert_allclose(raw_m.times, want_t, rtol=0, atol=1e-9)
    assert (
        feasibility_report(raw_m.angles, raw_m.times, robot=NAO_H25)["speed_violation_frames"] > 0
    )
    rate = 1.0 / np.median(np.diff(want_t))  # --rate auto: the input's median rate
    grid = np.arange(int(want_t[-1] * rate + 1e-9) + 1) / rate
    assert len(np.unique(np.round(np.diff(want_t), 6))) > 1  # the input's steps are uneven
    for ext in ("csv", "json", "npz"):
        out = tmp_path / f"motion.{ext}"
        code, stdout, _ = _run(capsys, "retarget", str(src), "--out", str(out))
        assert code == 0 and "speed-limit frames" in stdout and "[feasible]" in stdout
        m = load_motion(out)
        np.testing.assert_allclose(m.times, grid, rtol=0, atol=1e-6)  # one step, every frame
        rep = feasibility_report(m.angles, m.times, robot=NAO_H25)
        assert rep["speed_violation_frames"] == 0 and rep["limit_violation_frames"] == 0
    doc = json.loads((tmp_path / "motion.json").read_text())
    assert set(doc) >= {"names", "angleLists", "timeLists", "isAbsolute"}
    assert doc["isAbsolute"] is True and len(doc["names"]) == 14
    assert all(len(a) == len(grid) for a in doc["angleLists"]) and doc["timeLists"][0][0] > 0
    header = (tmp_path / "motion.csv").read_text().splitlines()[0].split(",")
    assert header == ["time", *robot.JOINT_NAMES]  # what a robot's tool reads, nothing else
    assert len(doc["jaxproj"]["confidence"]) == len(grid)
    npz = load_motion(tmp_path / "motion.npz")  # validity and confidence: in the NPZ
    assert npz.confidence is not None and npz.positions.shape == (len(grid), 20, 3)
    assert npz.meta["rate"] == "auto" and "resampled to" in str(npz.meta["time_source"])
    # --fps replaces the file's timing
    fast = tmp_path / "fast.npz"
    assert _run(capsys, "retarget", str(src), "--out", str(fast), "--fps", "60")[0] == 0
    np.testing.assert_allclose(load_motion(fast).times, np.arange(n) / 60.0, atol=1e-9)
    code, _, err = _run(capsys, "retarget", str(src), "--out", str(tmp_path / "x.txt"))
    assert code == 2 and ".npz, .csv or .json" in err


def test_output_rate_puts_the_recording_on_a_uniform_grid():
    """--rate: auto is the input's median rate, an input already uniform at it is kept as it is,
    a frame inside a gap of more than GAP_S is invalid, input keeps the file's times."""
    from jaxproj.cli.retarget import GAP_S, output_rate, parse_rate
    from jaxproj.io.recording import Recording

    times = np.array([0.0, 0.1, 0.2, 0.4, 0.5, 0.6, 2.0, 2.1])  # steps 0.1, 0.2 and a 1.4 s gap
    pos = np.arange(len(times), dtype=np.float32)[:, None, None] * np.ones((1, 20, 3), np.float32)
    rec = Recording(pos, np.ones(len(times), bool), "x", "csv", times, "file")
    out = output_rate(rec, "auto")
    np.testing.assert_allclose(out.times, np.arange(22) / 10.0, atol=1e-12)
    gap = (out.times > 0.6 + 1e-9) & (out.times < 2.0 - 1e-9)
    want = np.interp(out.times, times, pos[:, 0, 0])
    np.testing.assert_allclose(out.positions[~gap, 0, 0], want[~gap], atol=1e-6)
    assert GAP_S < 1.4 and not out.valid[gap].any() and out.valid[~gap].all()
    assert (out.positions[gap] == 0).all()  # invalid frames are zeros, as readers write them
    assert output_rate(rec, "input") is rec
    assert output_rate(out, "auto") is out  # uniform already
    assert len(output_rate(rec, 20.0).times) == 43
    assert parse_rate("auto") == "auto" and parse_rate("12.5") == 12.5
    for bad in ("0", "-1", "nan", "fast"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_rate(bad)


def test_retarget_csv_and_no_valid_frame(tmp_path, capsys):
    """A recording without one valid frame is an error naming the file, not a standing pose
    written with exit 0; one with a few valid frames is written, with a warning."""
    src = tmp_path / "lost.csv"
    np.savetxt(src, np.zeros((4, 60)), delimiter=",")
    out = tmp_path / "o.npz"
    code, stdout, err = _run(capsys, "retarget", str(src), "--out", str(out))
    assert code == 2 and stdout == "" and not out.exists()
    lines = err.strip().splitlines()
    assert lines == [
        f"jaxproj: error: {src}: no valid frame among 4: 4 marked invalid (lost tracking or "
        "non-finite values); nothing written"
    ]
    # one valid frame of four: written, and a warning on stderr (under MIN_VALID_SHARE)
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    rows = np.zeros((4, 60))
    rows[2] = seq.positions[0].reshape(-1)
    np.savetxt(src, rows, delimiter=",")
    code, stdout, err = _run(capsys, "retarget", str(src), "--out", str(out))
    assert code == 0 and "4 frames (1 valid" in stdout
    np.testing.assert_array_equal(np.load(out)["valid"], [False, False, True, False])
    assert err.strip().splitlines() == [
        f"jaxproj: warning: {src}: only 1 of 4 frames (25 %) are valid, under the 50 % jaxproj "
        "warns at: the others hold or bridge the valid poses around them (valid = false in the "
        "output); check the recording (lost tracking, units)"
    ]
    # half the frames valid: no warning (--force: the motion of the last run is replaced)
    rows[0] = seq.positions[1].reshape(-1)
    np.savetxt(src, rows, delimiter=",")
    code, _, err = _run(capsys, "retarget", str(src), "--out", str(out), "--no-smooth", "--force")
    assert code == 0 and err == ""
    np.testing.assert_array_equal(np.load(out)["valid"], [True, False, True, False])


@pytest.mark.parametrize(
    ("content", "word"),
    [
        (None, "not found"),
        ("", "empty"),
        ("1 2 3 4\n" * 21, "multiple of 20"),
        ("1 2 3 x\n" * 20, "non-numeric"),
    ],
)
def test_retarget_bad_input_is_one_line_and_exit_2(tmp_path, capsys, content, word):
    src = tmp_path / "bad_skeleton.txt"
    if content is not None:
        src.write_text(content)
    code, _, err = _run(capsys, "retarget", str(src), "--out", str(tmp_path / "o.npz"))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "bad_skeleton.txt" in lines[0]
    assert word in lines[0].lower()
    assert "Traceback" not in err
    assert not (tmp_path / "o.npz").exists()


BANDWIDTHS_150 = "0.01125,0.09801621279652503,0.10628323275537813"
"""Per-chain mean-shift bandwidths (head, left arm, right arm) that ``--landmarks 150`` reaches
on MSR subject 1 (361, 147, 156 landmarks)."""


def test_build_then_retarget_with_the_model(tmp_path, capsys, monkeypatch):
    model = tmp_path / "p.npz"
    bars = []

    def bar(items, desc, **kw):  # the progress bar (shown only on a terminal): its stages
        bars.append((desc, tuple(items)))
        return iter(items)

    monkeypatch.setattr(projector, "bar", bar)
    # the bandwidths that `--landmarks 150` bisects to on subject 1 (the head keeps its own),
    # given directly: the same model, 20x faster (the bisection through the CLI is tested below)
    code, out, err = _run(
        capsys, "build", "--subjects", "1", "--bandwidth", BANDWIDTHS_150, "--k", "16",
        "--out", str(model),
    )  # fmt: skip
    assert code == 0 and "built upper chains" in out
    assert "head 361 " in out and "left_arm 147 " in out and "right_arm 156 " in out
    assert bars == [("build", projector.BUILD_STAGES)]
    assert "it/s" not in err and "\r" not in err  # no bar drawn: stderr is not a terminal
    # the hidden units used, per chain (with --k 16: max(16, 192)), not the option's None
    assert "hidden=None" not in out and out.count("hidden=192") == 3
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    src = tmp_path / "m.npz"
    np.savez(src, positions=seq.positions)
    d, _ = descriptor(seq.positions)
    d = np.asarray(d)
    truth = np.asarray(ik.solve(d))[:, robot.DRIVEN_INDEX]
    errs = {}
    for method in ("relaxed", "full"):
        dst = tmp_path / f"{method}.npz"
        argv = ["retarget", str(src), "--out", str(dst), "--method", method, "--model", str(model)]
        code, out, _ = _run(capsys, *argv, "--no-smooth", "--no-feasible", "--L", "5", "--M", "5")
        assert code == 0
        # the low-confidence line: the share of the valid frames, read against the held-out
        # training people's tenth (relaxed); full is told that the cut-off is relaxed's
        with np.load(dst) as z:
            share = np.mean(z["confidence"][z["valid"]] < LOW_CONFIDENCE)
        low = [line for line in out.splitlines() if "low-confidence" in line]
        assert len(low) == 1 and f"frames: {100 * share:.1f} % of the valid frames" in low[0]
        assert confidence_lines(method, share)[0] == low[0]
        assert ("calibrated on --method relaxed" in low[0]) == (method == "full")
        angles = np.load(dst)["angles"]
        assert np.isfinite(angles).all()
        assert (angles >= robot.LOWER).all() and (angles <= robot.UPPER).all()
        errs[method] = np.degrees(np.abs(angles[:, robot.DRIVEN_INDEX] - truth)).mean()
    # a learned mapping: better than snapping to the nearest landmark's pose
    nn = evaluate.predict_method(engine.load(model), "nearest_landmark", d)  # per chain
    snap = np.degrees(np.abs(nn - truth)).mean()
    assert errs["relaxed"] < snap and errs["full"] < snap
    # a method that needs a model, without one, is a clean error
    code, _, err = _run(
        capsys, "retarget", str(src), "--out", str(tmp_path / "x.npz"), "--method", "relaxed"
    )
    assert code == 2 and "--model" in err
    # and a model with the IK (the default method) is refused, not silently ignored
    for extra in ([], ["--method", "ik"]):
        argv = ["retarget", str(src), "--out", str(tmp_path / "x.npz"), "--model", str(model)]
        code, _, err = _run(capsys, *argv, *extra)
        assert code == 2 and err.strip().splitlines() == [
            f"jaxproj: error: --model {model} is used by --method relaxed / full only, and "
            "--method is ik (the default: the analytic IK, no model): add --method relaxed to "
            "use the model, or leave --model out"
        ]
    assert not (tmp_path / "x.npz").exists()


def test_the_confidence_line_says_what_the_share_means_and_what_to_do():
    """Relaxed: against the tenth of held-out training people's frames the cut-off was
    calibrated on; well above it (over 15 %), what to do. Full: that the cut-off is relaxed's."""
    like = confidence_lines("relaxed", EXPECTED_LOW_SHARE)
    assert len(like) == 1 and "10.0 % of the valid frames" in like[0]
    assert "this recording is like the people the model was built from" in like[0]
    assert len(confidence_lines("relaxed", 1.5 * EXPECTED_LOW_SHARE)) == 1
    unlike = confidence_lines("relaxed", 0.25)
    assert "2.5x the 10 % of held-out training people's frames" in unlike[0]
    assert "unlike the people the model was built from" in unlike[0]
    assert len(unlike) == 2 and "--data bundled+FOLDER" in unlike[1] and "--mirror" in unlike[1]
    full = confidence_lines("full", 0.25)
    assert len(full) == 1 and "25.0 % of the valid frames" in full[0]
    assert "calibrated on --method relaxed" in full[0] and "unlike" not in full[0]
    old = confidence_lines("relaxed", 0.25, calibrated=False)  # a model file without a scale
    assert (
        old[0] == unlike[0] and "predates per-model calibration" in old[1] and old[2:] == unlike[1:]
    )


def test_build_and_evaluate_from_a_folder_of_recordings(tmp_path, capsys):
    folder = tmp_path / "recordings"
    folder.mkdir()
    for s in datasets.msr_action3d(subjects=[1, 2], actions=[1, 2, 5]):
        _write_msr(folder / f"{s.name}_skeleton3D.txt", s.positions)
    np.savez(folder / "unnamed.npz", positions=datasets.msr_action3d(subjects=[3])[0].positions)
    model = tmp_path / "p.npz"
    code, out, _ = _run(
        capsys,
        "build",
        "--data",
        str(folder),
        "--subjects",
        "1",
        "--landmarks",
        "60",
        "--k",
        "8",
        "--out",
        str(model),
    )
    assert code == 0 and "target 60" in out
    for arm in ("left_arm", "right_arm"):  # each arm chain reaches its target within 5 %
        n_reached = int(out.split(f"{arm} ")[1].split()[0])
        assert f"{arm} {n_reached} (target 60," in out
        assert abs(n_reached - 60) <= 0.05 * 60
    report = tmp_path / "r.json"
    argv_eval = ["evaluate", "--model", str(model), "--data", str(folder), "--subjects", "2"]
    argv_eval += ["--objective", "relaxed", "--json", str(report)]
    # more neighbours than the smallest chain's landmarks (within --L's 1..200): refused, naming
    # the chain
    code, out, err = _run(capsys, *argv_eval, "--L", "150")
    assert code == 2 and "chain has" in err and "L=150" in err
    code, out, _ = _run(capsys, *argv_eval, "--L", "5", "--M", "5")
    assert code == 0
    r = json.loads(report.read_text())
    names = set(r["per_sequence"])
    assert any(n.startswith("a01_s02") for n in names) and "unnamed" in names
    assert not any("_s01_" in n for n in names)
    assert any(k.endswith("unknown action") for k in r["per_action"])
    assert r["summary"]["relaxed"]["M_avg"]["median"] > 0
    code, _, err = _run(
        capsys, "build", "--data", str(tmp_path / "nope"), "--landmarks", "5",
        "--out", str(tmp_path / "q.npz"),
    )  # fmt: skip
    assert code == 2 and "nope" in err


def _subcommand_parsers() -> dict:
    import argparse

    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_help_reads_as_plain_text_with_only_real_defaults():
    top = build_parser().format_help()
    assert "``" not in top and top.count("jaxproj") >= 2
    for name, parser in _subcommand_parsers().items():
        text = parser.format_help()
        assert "(default: None)" not in text and "(default: False)" not in text, name
        assert "``" not in text, name
    render_help = " ".join(_subcommand_parsers()["render"].format_help().split())
    assert "(default: 480x360)" in render_help and "(480, 360)" not in render_help
    assert _subcommand_parsers()["render"].parse_args(["m.npz", "--out", "v.gif"]).size == (
        480,
        360,
    )
    build_help = " ".join(_subcommand_parsers()["build"].format_help().split())
    assert "(default: 0)" in build_help  # --seed: a false-y default that is real
    assert "its folder must exist" in build_help


def test_outputs_go_only_into_existing_folders(tmp_path, capsys):
    """A typo in an output folder is an error naming it: nothing is created (``/no/dir`` once
    appeared at the filesystem root); ``build --out`` must name an ``.npz``."""
    src = tmp_path / "m.npz"
    np.savez(src, positions=datasets.msr_action3d(subjects=[1], actions=[1])[0].positions)
    missing = tmp_path / "no" / "dir"
    cases = [
        ["retarget", str(src), "--out", str(missing / "r.csv")],
        ["retarget", str(src), "--out", str(tmp_path / "r.csv"), "--plot", str(missing / "p.png")],
        ["build", "--out", str(missing / "m.npz")],
        ["evaluate", "--model", str(tmp_path / "p.npz"), "--json", str(missing / "r.json")],
        ["render", str(src), "--out", str(missing / "v.gif")],
        ["demo", "--out", str(missing / "report")],
    ]
    for argv in cases:
        code, _, err = _run(capsys, *argv)
        assert code == 2, argv
        assert f"folder {missing} does not exist" in err and len(err.strip().splitlines()) == 1
        assert not (tmp_path / "no").exists(), argv
    assert not (tmp_path / "r.csv").exists()
    for name in ("m.txt", "m"):
        code, _, err = _run(capsys, "build", "--out", str(tmp_path / name))
        assert code == 2 and "use a .npz file name" in err


def test_no_warp_notice_on_the_users_terminal(tmp_path):
    """MJX prints "Failed to import warp" when it is imported without NVIDIA Warp (jaxproj uses
    its JAX implementation): ``evaluate`` / ``demo`` keep that notice off the user's terminal."""
    import subprocess
    import sys

    from jaxproj._internal.mjx import drop_warp_notice

    notice = (
        "Failed to import warp: No module named 'warp'\n"
        "Failed to import mujoco_warp: No module named 'warp'\n"
    )
    assert drop_warp_notice(notice) == ""
    real = "Failed to import warp: CUDA driver version is insufficient\n"
    assert drop_warp_notice(notice + real) == real  # real errors still show
    # a fresh process: evaluate imports MJX (through jaxproj.eval), then fails on the model
    argv = ["evaluate", "--model", str(tmp_path / "none.npz"), "--json", str(tmp_path / "r.json")]
    res = subprocess.run(
        [sys.executable, "-m", "jaxproj.cli", *argv], capture_output=True, text=True
    )
    assert res.returncode == 2 and res.stdout == ""
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith("jaxproj: error:") and "none.npz" in line


def test_data_sources_join_with_plus(tmp_path):
    from jaxproj.cli import options
    from jaxproj.errors import ConfigError

    msr, _ = options.load_data("bundled", None, "train")
    utk, _ = options.load_data("utkinect", None, "train")
    both, contents = options.load_data("bundled+utkinect", None, "train")
    assert [s.name for s in both] == [s.name for s in msr] + [s.name for s in utk]
    assert contents is None
    some, _ = options.load_data("utkinect+msr", [3], "train")  # --subjects for each source
    assert {s.subject for s in some} == {3} and len(some) > len(utk) // 5
    with pytest.raises(ConfigError, match="empty source"):
        options.load_data("bundled+", None, "train")


def test_build_trains_on_the_default_training_set_and_evaluate_scores_the_others(capsys):
    """``build`` adds the default UTKinect people to the bundled MSR data unless --subjects or
    --utkinect-people picks otherwise; ``evaluate --data utkinect`` scores the others."""
    from jaxproj.errors import ConfigError

    people = projector.training_people  # (added, recorded in the model)
    assert people("bundled", None, None) == (datasets.UTK_TRAIN_SUBJECTS,) * 2
    assert datasets.UTK_TRAIN_SUBJECTS == (3, 4, 6)
    assert people("msr", [1, 3], None) == ((), ())  # --subjects picks the training people
    assert people("bundled", None, ()) == ((), ()) and people("bundled", [1], (7,)) == ((7,),) * 2
    assert people("utkinect", None, None) == ((), datasets.UTK_SUBJECTS)  # all five, as data
    assert people("bundled+utkinect", [9, 1, 3], None) == ((), (3, 9))
    assert people("/some/folder", None, None) == ((), ())
    with pytest.raises(ConfigError, match="--data bundled / msr only"):
        people("utkinect", None, (3,))
    assert projector._parse_people("none") == () and projector._parse_people("3,4") == (3, 4)
    chosen = projector._utkinect_subjects
    assert chosen("utkinect", None, (3, 4, 6)) == [7, 9]
    assert chosen("utkinect", None, ()) is None and chosen("bundled", None, (3, 4, 6)) is None
    assert chosen("utkinect", [3, 7], (3, 4, 6)) == [3, 7]
    assert "trained on UTKinect-Action3D people [3]" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="none is left"):
        chosen("utkinect", None, datasets.UTK_SUBJECTS)


NUMBERS = [
    # (subcommand argv before the option, option, a value out of range, its range in words)
    (["retarget", "r.npz", "--out", "o.npz"], "--fps", "1e5", "1..1000"),
    (["retarget", "r.npz", "--out", "o.npz"], "--fps", "0.5", "1..1000"),
    (["retarget", "r.npz", "--out", "o.npz"], "--fps", "nan", "1..1000"),
    (["retarget", "r.npz", "--out", "o.npz"], "--L", "0", "1..200"),
    (["retarget", "r.npz", "--out", "o.npz"], "--M", "201", "1..200"),
    (["evaluate", "--model", "p.npz", "--json", "r.json"], "--L", "1.5", "1..200"),
    (["build", "--out", "p.npz"], "--landmarks", "400,1,1644", "2..100000"),
    (["build", "--out", "p.npz"], "--bandwidth", "0.1,-1", "> 0 and <= 10"),
    (["build", "--out", "p.npz"], "--k", "1", "2..4096"),
    (["build", "--out", "p.npz"], "--hidden", "5000", "2..4096"),
    (["build", "--out", "p.npz"], "--lam", "0", "> 0"),
    (["build", "--out", "p.npz"], "--input-scale", "inf", "> 0"),
    (["build", "--out", "p.npz"], "--seed", "-1", "0..4294967295"),
    (["render", "m.npz", "--out", "v.gif"], "--stride", "0", "1..1000"),
    (["render", "m.npz", "--out", "v.gif"], "--fps", "300", "1..240"),
    (["render", "m.npz", "--out", "v.gif"], "--size", "16x360", "32..4096"),
]


@pytest.mark.parametrize(("argv", "option", "value", "words"), NUMBERS)
def test_numbers_out_of_range_are_one_line_at_parse_time(argv, option, value, words, capsys):
    """Issue 56: ``--fps 1e5`` was taken (and the motion broke the 80 rad/s^2 bound): every
    numeric option has a range, checked when the command line is read, one line, exit 2."""
    with pytest.raises(SystemExit) as e:
        main([*argv, option, value])
    err = capsys.readouterr().err
    assert e.value.code == 2
    (line,) = err.strip().splitlines()
    assert line.startswith(f"jaxproj {argv[0]}: error: argument {option}: ")
    assert words in line and f"(see jaxproj {argv[0]} --help)" in line


def test_every_numeric_option_has_a_documented_range():
    """No numeric option parses with a bare ``int`` / ``float``: each has a range
    (``options.Bounded``), and its help says it (the range is in the generated docs page)."""
    from jaxproj.cli import options

    seen = 0
    for name, parser in _subcommand_parsers().items():
        for action in parser._actions:
            assert action.type not in (int, float, options.parse_floats), (name, action.dest)
            if isinstance(action.type, options.Bounded):
                seen += 1
                assert action.type.RANGE in " ".join(action.help.split()), (name, action.dest)
    assert seen >= 12
    p = _subcommand_parsers()
    args = p["retarget"].parse_args(["r.npz", "--out", "o.npz", "--fps", "1000", "--L", "200"])
    assert (args.fps, args.L) == (1000.0, 200)
    args = p["build"].parse_args(["--out", "p.npz", "--landmarks", "2,100000,5", "--seed", "0"])
    assert args.landmarks == [2, 100000, 5]


def test_a_missing_opengl_back_end_is_one_line_not_a_traceback(tmp_path):
    """``MUJOCO_GL=osmesa`` without libOSMesa made ``import mujoco`` (so every command, even
    ``info``) die with a PyOpenGL AttributeError. ``info`` now reports rendering unavailable and
    ``render --backend mujoco`` is one line, exit 2. ``MUJOCO_GL=bogus`` fails the same way on
    every machine (MuJoCo's RuntimeError where PyOpenGL's AttributeError came), so the test can
    fail anywhere; one process (~6 s), not a second for ``osmesa``, which renders where
    libOSMesa is installed."""
    import subprocess
    import sys

    import jaxproj

    motion = tmp_path / "m.npz"
    nao = jaxproj.robots.get()
    standing = jaxproj.Motion(np.tile(nao.standing, (2, 1)), np.arange(2) / 15.0, np.ones(2, bool))
    jaxproj.save_motion(motion, standing)
    gif = tmp_path / "a.gif"
    script = (
        "import os\n"
        "from jaxproj.cli.main import main\n"
        "codes = [main(['info', '--json']), main(['info'])]\n"
        f"codes.append(main(['render', {str(motion)!r}, '--out', {str(gif)!r}, '--backend', "
        "'mujoco', '--size', '32x32']))\n"
        "print('codes', codes, os.environ['MUJOCO_GL'], os.environ.get('PYOPENGL_PLATFORM'))\n"
    )
    env = {**os.environ, "MUJOCO_GL": "bogus"}
    env.pop("PYOPENGL_PLATFORM", None)
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert "Traceback" not in res.stderr and res.returncode == 0, res.stderr
    info = json.loads(res.stdout[: res.stdout.index("\n}\n") + 2])
    assert info["rendering"]["mujoco_available"] is False
    problem = info["rendering"]["problem"]
    assert problem.startswith("MUJOCO_GL=bogus: MuJoCo's OpenGL back-end cannot load")
    assert f"rendering: MuJoCo OpenGL unavailable: {problem}" in res.stdout
    assert res.stdout.splitlines()[-1] == "codes [0, 0, 2] bogus None"  # the environment kept
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith("jaxproj: error: MuJoCo cannot render: MUJOCO_GL=bogus: ")
    assert not gif.exists()
