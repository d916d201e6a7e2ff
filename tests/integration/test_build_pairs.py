"""``jaxproj build --pairs RECORDING MOTION``: a projector from given pairs (the paper's
hand-given landmarks), with no IK and no mean shift."""

from __future__ import annotations

import numpy as np
import pytest

import jaxproj
from jaxproj.cli.main import main
from jaxproj.human.descriptors import frame_descriptors
from jaxproj.io import datasets
from jaxproj.io.motion_files import Motion, save_motion
from jaxproj.projection import landmarks
from jaxproj.robots import NAO_H25


@pytest.fixture(scope="module")
def pairs(tmp_path_factory: pytest.TempPathFactory):
    """A recording (MSR subject 1, two actions) and a motion for it: the robot's IK, with one
    frame marked invalid, as another retargeter's output."""
    folder = tmp_path_factory.mktemp("pairs")
    seqs = datasets.msr_action3d(subjects=[1], actions=[1, 5])
    pos = np.concatenate([s.positions for s in seqs])
    rec = folder / "rec.npz"
    np.savez(rec, positions=pos, fps=15)
    d, keep = frame_descriptors([jaxproj.read(rec)])
    q = NAO_H25.driven_to_full(NAO_H25.solve_ik(d, "upper"))
    valid = keep.copy()
    valid[3] = False
    times = np.arange(len(pos)) / 15.0
    motion = folder / "motion.npz"
    save_motion(motion, Motion(np.asarray(q), times, valid, robot=NAO_H25))
    return rec, motion, d[valid], np.asarray(NAO_H25.solve_ik(d[valid], "upper"))


def test_build_from_pairs_learns_them_without_an_ik(pairs, tmp_path, capsys, monkeypatch):
    rec, motion, d, labels = pairs

    def no_ik(*args, **kwargs):
        raise AssertionError("build --pairs called the IK")

    monkeypatch.setattr(type(NAO_H25), "solve_ik", no_ik)
    monkeypatch.setattr(landmarks, "build_landmarks", no_ik)  # no mean shift (nor chain IKs)
    out = tmp_path / "m.npz"
    assert main(["build", "--pairs", str(rec), str(motion), "--k", "16", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"from {len(d)} given pairs" in text and "no IK" in text
    monkeypatch.undo()
    model = jaxproj.load(out)
    assert model.n_train == len(d) and model.deviation_scale is not None
    # a projector reproduces its own landmarks' poses closely (the pairs it was given)
    q, _ = jaxproj.project(model, d, "relaxed")
    err = np.degrees(np.abs(np.asarray(q) - labels))
    assert np.median(err.mean(axis=1)) < 1.0


def test_build_pairs_refuses_mismatched_files_and_data_options(pairs, tmp_path, capsys):
    rec, motion, _, _ = pairs
    short = tmp_path / "short.npz"
    with np.load(rec) as z:
        np.savez(short, positions=z["positions"][:-5], fps=15)
    out = str(tmp_path / "m.npz")
    assert main(["build", "--pairs", str(short), str(motion), "--out", out]) == 2
    err = capsys.readouterr().err
    assert "one robot pose per recording frame" in err and "short.npz" in err
    assert main(["build", "--pairs", str(rec), str(motion), "--subjects", "1", "--out", out]) == 2
    assert "--pairs gives the training pairs: leave --subjects out" in capsys.readouterr().err
