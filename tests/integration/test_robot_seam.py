"""The robot seam, end to end: a toy robot (tests/toy_robot.py, 9 joints, 8 driven, its own IK)
registered in one place builds a model, projects, retargets, streams, saves / loads and is
evaluated, through the same code the NAO uses and with no NAO number in sight."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from toy_robot import CHAINS, DRIVEN, JOINTS, LOWER, STANDING, UPPER, make_toy_robot

from jaxproj import robots
from jaxproj.errors import ConfigError, InputError
from jaxproj.eval import evaluate as ev
from jaxproj.human.skeleton import descriptor, level_neck, recording_neck_tilt
from jaxproj.io import datasets
from jaxproj.motion import streaming
from jaxproj.motion.feasible import FeasibleConfig, feasibility_report
from jaxproj.motion.retarget import retarget
from jaxproj.projection import api as engine
from jaxproj.robots import Robot


@pytest.fixture(scope="module")
def toy(tmp_path_factory: pytest.TempPathFactory):
    """The toy robot with its MJCF, registered for this module only."""
    r = robots.register(make_toy_robot(tmp_path_factory.mktemp("toy_seam")))
    yield r
    robots.unregister(r.name)


@pytest.fixture(scope="module")
def model(toy: Robot) -> engine.Model:
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3]))[::8]
    config = engine.BuildConfig(robot=toy.name, landmarks=(24, 32, 48, 32, 48), k=12, hidden=24)
    return engine.build(train, config)


@pytest.fixture(scope="module")
def held_out() -> list:
    """Subject 2, three arm actions: never seen by the model."""
    return datasets.msr_action3d(subjects=[2], actions=[1, 2, 3])


def _within(angles: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    return bool(((angles >= lo - 1e-6) & (angles <= hi + 1e-6)).all())


def test_the_model_is_built_for_the_toy(toy: Robot, model: engine.Model) -> None:
    assert model.robot is toy and model.config.robot == "toy"
    lay = model.projector.layout
    assert lay.names == tuple(c.name for c in CHAINS) and lay.n == len(DRIVEN) == toy.n_driven
    assert lay.outputs == tuple(toy.chain_joints(c) for c in CHAINS)
    want = {"gaze": 24, "left_shoulder": 32, "left_elbow": 48, "right_shoulder": 32,
            "right_elbow": 48}  # fmt: skip
    got = model.landmarks
    assert got.keys() == want.keys()
    assert all(abs(got[c] - want[c]) <= 0.05 * want[c] for c in want), got  # the search's rel_tol
    for c, chain in enumerate(CHAINS):  # robot landmarks: the toy's chain IK of the human ones
        p = model.projector.chain(c)
        np.testing.assert_array_equal(np.asarray(p.robot), chain.solve(np.asarray(p.human)))
        k = [toy.index(j) for j in chain.joints]
        np.testing.assert_array_equal(np.asarray(p.lower), LOWER[k])
        np.testing.assert_array_equal(np.asarray(p.upper), UPPER[k])


def test_unknown_robot_names_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"robot='nobody' is not a registered robot.*nao_h25"):
        engine.BuildConfig(robot="nobody")


def test_project_and_retarget_the_held_out_recording(
    toy: Robot, model: engine.Model, held_out: list, count_compiles
) -> None:
    seq = held_out[0]
    d, ok = descriptor(seq.positions)
    q, _ = engine.project(model, np.asarray(d)[np.asarray(ok)])
    assert q.shape == (int(np.sum(ok)), 8) and _within(q, toy.lower_driven, toy.upper_driven)
    res = retarget(seq.positions, seq.valid, model=model)
    assert res.angles.shape == (len(seq.positions), len(JOINTS))
    assert _within(res.angles, LOWER, UPPER) and np.isfinite(res.angles).all()
    assert (res.angles[:, 0] == STANDING[0]).all()  # the waist is not driven: it stands
    # relaxed retargeting follows the toy's own IK (the truth) closely
    # (of the descriptor retarget reads: the neck levelled per recording)
    truth = np.asarray(toy.ik(np.asarray(level_neck(d, recording_neck_tilt(d, seq.valid)))))
    unsmoothed = retarget(seq.positions, seq.valid, model=model, smoothing=None)
    err = np.degrees(np.abs(unsmoothed.angles[:, 1:] - truth))[unsmoothed.valid]
    assert err.mean() < 10.0
    # the IK method with the toy named: its IK inside the compiled pipeline
    ik_res = retarget(seq.positions, seq.valid, robot="toy", smoothing=None)
    np.testing.assert_allclose(ik_res.angles[ik_res.valid][:, 1:], truth[ik_res.valid], atol=1e-4)
    # feasibility for a robot without elbow rules: its own speed limits (5 rad/s) hold
    safe = retarget(seq.positions, seq.valid, model=model, feasible=FeasibleConfig())
    assert safe.angles.shape == res.angles.shape
    rep = feasibility_report(safe.angles, safe.times, robot=toy)
    assert rep["speed_violation_frames"] == 0 and rep["limit_violation_frames"] == 0
    # a second motion of the same bucket, same robot: nothing recompiles
    with count_compiles() as n:
        retarget(held_out[1].positions[:40], held_out[1].valid[:40], model=model)
        retarget(held_out[2].positions[:40], held_out[2].valid[:40], robot=toy, smoothing=None)
    assert n["motion"] == 0, n
    with pytest.raises(ConfigError, match="differs from the model's robot"):
        retarget(seq.positions, seq.valid, model=model, robot="nao_h25")


def test_streaming_the_toy(toy: Robot, model: engine.Model, held_out: list) -> None:
    state = streaming.init(model)
    np.testing.assert_array_equal(np.asarray(state.level), toy.standing_driven)
    for pos in held_out[0].positions[:5]:
        angles, state = streaming.update(model, state, pos)
    assert angles.shape == (8,) and _within(np.asarray(angles), toy.lower_driven, toy.upper_driven)
    with pytest.raises(ConfigError, match="differs from the model's robot"):
        streaming.init(model, robot="nao_h25")


def test_the_model_file_records_the_robot(toy: Robot, model: engine.Model, tmp_path: Path) -> None:
    path = tmp_path / "toy.npz"
    engine.save(model, path)
    with np.load(path) as z:
        meta = json.loads(str(z["meta"]))
    assert meta["config"]["robot"] == "toy" and meta["driven_joints"] == list(DRIVEN)
    assert meta["ik"] == {}  # the toy's IK has no constants to record
    back = engine.load(path)
    assert back.robot is toy and back.config == model.config
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[2], actions=[1]))[:50]
    a, b = engine.project(model, d)[0], engine.project(back, d)[0]
    assert a.tobytes() == b.tobytes()


def test_cli_retarget_takes_the_robot_from_the_model(
    toy: Robot, model: engine.Model, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``jaxproj retarget --model`` writes the model's robot's joints; ``--robot`` naming
    another robot is refused; ``--robot toy`` alone runs the toy's IK."""
    from jaxproj.cli import main

    path = tmp_path / "toy.npz"
    engine.save(model, path)
    src = tmp_path / "rec.npz"
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    np.savez(src, positions=seq.positions)
    out = tmp_path / "toy.csv"
    assert main(["retarget", str(src), "--method", "relaxed", "--model", str(path),
                 "--out", str(out)]) == 0  # fmt: skip
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["time", *JOINTS]  # the robot's joints, nothing else
    assert main(["retarget", str(src), "--method", "relaxed", "--model", str(path), "--robot",
                 robots.DEFAULT, "--out", str(tmp_path / "x.csv")]) == 2  # fmt: skip
    assert "conflicts with the model" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
    ik_out = tmp_path / "toy_ik.csv"
    assert main(["retarget", str(src), "--robot", toy.name, "--out", str(ik_out)]) == 0
    assert ik_out.read_text().splitlines()[0].split(",")[1 : 1 + len(JOINTS)] == list(JOINTS)


def test_a_model_file_without_a_robot_is_the_nao(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    human = rng.normal(size=(24, 15)).astype(np.float32)
    nao = robots.get()
    poses = np.asarray(nao.ik(human))
    model = engine.from_landmarks(human, poses, engine.BuildConfig(k=8, hidden=16))
    path = tmp_path / "old.npz"
    engine.save(model, path)
    z = dict(np.load(path))
    meta = json.loads(str(z["meta"]))
    assert meta["config"].pop("robot") == "nao_h25"  # as files before robots were named
    z["meta"] = np.array(json.dumps(meta))
    np.savez(path, **z)
    assert engine.load(path).robot is nao
    meta["config"]["robot"] = "nobody"
    z["meta"] = np.array(json.dumps(meta))
    np.savez(path, **z)
    with pytest.raises(InputError, match="not a registered robot"):
        engine.load(path)


def test_evaluate_the_toy(toy: Robot, model: engine.Model, held_out: list) -> None:
    data = ev.prepare(held_out, robot="toy")
    assert data.robot == "toy" and data.truth.shape == (len(data.valid), 8)
    rep = ev.evaluate(model, data, methods=("relaxed", "nearest_landmark"))
    assert rep["driven_joints"] == list(DRIVEN)
    relaxed, nearest = rep["summary"]["relaxed"], rep["summary"]["nearest_landmark"]
    for block in (relaxed, nearest):
        assert np.isfinite([block["M_avg"]["mean"], block["M_max"]["mean"]]).all()
    # the paper's claim holds for the toy too: the projection beats its nearest landmark
    assert relaxed["M_avg"]["mean"] < nearest["M_avg"]["mean"]
    assert set(rep["feasibility"]) == {"relaxed", "nearest_landmark", "ik"}
    assert rep["feasibility"]["relaxed"]["after"]["speed_violation_frames"] == 0
    with pytest.raises(ConfigError, match="prepared for robot 'nao_h25'"):
        ev.evaluate(model, ev.prepare(held_out[:1]), methods=("relaxed",))
