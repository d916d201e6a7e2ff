"""A robot that lives outside the package, as its two files only, through the CLI: retarget with
the IK, build, retarget with the model, evaluate, render; and its model, in a fresh process
without the robot's folder, loads and projects (the model embeds the robot)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import jaxproj
from jaxproj import robots
from jaxproj.cli.main import main
from jaxproj.io import datasets
from jaxproj.io.motion_files import load_motion

TWO_ARMS = Path(__file__).parents[1] / "data" / "robots" / "two_arms"

FRESH = """
import json, sys
import numpy as np
import jaxproj
from jaxproj import robots
assert "two_arms" not in robots.names()
model = jaxproj.load(sys.argv[1])
d = np.load(sys.argv[2])["d"]
q, _ = jaxproj.project(model, d)
print(json.dumps({"robot": model.robot.name, "file": str(model.robot.file),
                  "q": np.asarray(q).tolist()}))
"""


@pytest.mark.slow
def test_a_robot_from_a_folder_goes_through_every_command(tmp_path, capsys):
    folder = tmp_path / "my_robots" / "two_arms"
    shutil.copytree(TWO_ARMS, folder)
    toml = str(folder / "robot.toml")
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    data = tmp_path / "data"
    data.mkdir()
    rec = data / "s02_a01.npz"
    np.savez(rec, positions=seq.positions, fps=15)
    try:
        assert main(["retarget", str(rec), "--robot", toml, "--out", str(tmp_path / "ik.npz")]) == 0
        ik = load_motion(tmp_path / "ik.npz", robot=toml)
        assert ik.robot.name == "two_arms" and np.isfinite(ik.angles).all()
        model = tmp_path / "m.npz"
        argv = ["build", "--robot", toml, "--subjects", "1", "--utkinect-people", "none",
                "--bandwidth", "0.18,0.15", "--k", "16", "--out", str(model)]  # fmt: skip
        assert main(argv) == 0
        assert "built upper chains: left_arm" in capsys.readouterr().out
        rel = tmp_path / "rel.npz"
        argv = ["retarget", str(rec), "--method", "relaxed", "--model", str(model), "--out",
                str(rel), "--no-smooth", "--no-feasible"]  # fmt: skip
        assert main(argv) == 0
        relaxed = load_motion(rel, robot="two_arms")
        # the projection is near the robot's own IK (unsmoothed, 60 landmarks: loosely)
        err = np.degrees(np.abs(relaxed.angles - ik.angles))[relaxed.valid]
        assert np.median(err) < 15.0
        argv = ["evaluate", "--model", str(model), "--data", str(data), "--objective", "relaxed",
                "--no-smooth", "--json", str(tmp_path / "e.json")]  # fmt: skip
        assert main(argv) == 0
        report = json.loads((tmp_path / "e.json").read_text())
        assert "relaxed" in json.dumps(report)
        video = tmp_path / "v.gif"
        argv = ["render", str(rel), "--robot", toml, "--backend", "matplotlib", "--stride", "20",
                "--size", "160x120", "--out", str(video)]  # fmt: skip
        assert main(argv) == 0 and video.stat().st_size > 0
        assert "two arms (right)" in capsys.readouterr().out
    finally:
        robots.unregister("two_arms")
    shutil.rmtree(tmp_path / "my_robots")  # the folder is gone: the model carries the robot
    d = tmp_path / "d.npz"
    np.savez(d, d=np.asarray(datasets.valid_descriptors([seq]))[:8])
    out = subprocess.run([sys.executable, "-c", FRESH, str(model), str(d)], check=True,
                         capture_output=True, text=True).stdout  # fmt: skip
    fresh = json.loads(out.strip().splitlines()[-1])
    assert fresh["robot"] == "two_arms" and not fresh["file"].startswith(str(tmp_path))
    try:  # here too the model's own copy of the robot is used, and answers the same
        here, _ = jaxproj.project(jaxproj.load(model), np.load(d)["d"])
        np.testing.assert_array_equal(np.asarray(fresh["q"], np.float32), np.asarray(here))
    finally:
        robots.unregister("two_arms")
