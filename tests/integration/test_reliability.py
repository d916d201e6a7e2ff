"""Reliability (issue 15): never NaN and always within the joint limits for every method; model
files that fail with a clear error naming the file; model and report writes that never leave a
half-written file; the same model bytes and outputs from two processes; folders of recordings
as a new user meets them (documentation files, other subjects, one unreadable recording).

Two tiny models (per-chain and whole-body, 40 landmarks, no mean shift) serve the module.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fuzzing import (
    MORE_KINDS,
    assert_one_line_error,
    fuzz,
    make_frames,
    msr_file,
    no_tracing,
    run_cli,
    utk_file,
)
from hypothesis import given
from hypothesis import strategies as st

import jaxproj
from jaxproj.errors import ConfigError, InputError, NonFiniteRowsError, NoValidFrameError
from jaxproj.io import datasets
from jaxproj.io.motion_files import load_motion
from jaxproj.motion.feasible import FeasibleConfig
from jaxproj.motion.retarget import retarget
from jaxproj.motion.smoothing import PAPER_SMOOTHING
from jaxproj.projection import api as engine
from jaxproj.robots.nao_h25 import ik, robot
from jaxproj.viz import report

L = M = 3


@pytest.fixture(scope="module")
def models() -> dict[str, engine.Model]:
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1], actions=[1, 2, 5]))
    uniq = np.unique(d, axis=0)
    human = uniq[np.sort(np.random.default_rng(0).choice(len(uniq), 40, replace=False))]
    poses = np.asarray(ik.solve_driven(human))
    out = {}
    for chains in ("upper", "whole"):
        cfg = engine.BuildConfig(
            chains=chains, landmarks=None, bandwidth=1.0, k=8, hidden=16, input_scale=1.0
        )
        out[chains] = engine.from_landmarks(human, poses, cfg)
    return out


@pytest.fixture(scope="module")
def model_file(models, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("model") / "p.npz"
    engine.save(models["upper"], path)
    return path


def _in_limits(angles: np.ndarray) -> bool:
    return bool((angles >= robot.LOWER).all() and (angles <= robot.UPPER).all())


# --- never NaN, always within the joint limits ----------------------------------------------------


class TestNeverNaN:
    """``retarget`` for every method (IK, relaxed and full on the per-chain and the whole-body
    model), smoothed or not, feasibility filter on or off, on fuzzed skeletons (NaN / inf,
    lost-tracking all-zero frames, zero-length bones, 1e30 / 1e-30 coordinates, collapsed or
    random skeletons, a single frame): finite angles within ``robot.LOWER / UPPER``, ``valid``
    false exactly where the frame was unusable."""

    @pytest.mark.parametrize(
        ("method", "chains"),
        [
            ("ik", None),
            ("relaxed", "upper"),
            ("full", "upper"),
            ("relaxed", "whole"),
            ("full", "whole"),
        ],  # fmt: skip
    )
    @fuzz(10)
    @given(
        kinds=st.lists(st.sampled_from(MORE_KINDS), min_size=1, max_size=10),
        seed=st.integers(0, 2**16),
        reader_valid=st.booleans(),
    )
    def test_finite_within_limits_valid_marks_bad_frames(
        self, models, method, chains, kinds, seed, reader_valid
    ):
        pos = make_frames(kinds, seed)
        # a reader's mask (non-finite / zero frames) when given, else retarget finds them itself
        valid_in = np.array([k not in ("nan", "inf", "zero") for k in kinds])
        if reader_valid:
            valid_in[seed % len(kinds)] = False  # and one frame the file marked invalid
        model = None if chains is None else models[chains]
        ok = np.array([k == "ok" for k in kinds]) & (valid_in if reader_valid else True)
        for smoothing in (None, PAPER_SMOOTHING):
            for feasible in (None, FeasibleConfig()):
                try:
                    res = retarget(
                        pos,
                        valid_in if reader_valid else None,
                        model=model,
                        method=method,
                        n_l=L,
                        n_m=M,
                        smoothing=smoothing,
                        feasible=feasible,
                    )
                except NoValidFrameError as e:  # nothing usable: refused, saying why
                    assert not ok.any() and e.n_frames == len(kinds)
                    assert str(e).startswith(f"positions: no valid frame among {len(kinds)}: ")
                    continue
                assert res.angles.shape == (len(kinds), 26) and res.angles.dtype == np.float32
                assert np.isfinite(res.angles).all() and np.isfinite(res.times).all()
                assert _in_limits(res.angles)
                usable = np.array([k in ("ok", "random") for k in kinds])
                if reader_valid:
                    usable &= valid_in
                assert not res.valid[~usable].any()
                assert res.valid[ok].all() and res.valid.any()

    @pytest.mark.parametrize("chains", ["upper", "whole"])
    def test_project_refuses_non_finite_rows_and_never_answers_nan(self, models, chains):
        """``project`` on NaN / inf rows: ``NonFiniteRowsError`` (a ``ConfigError``) naming the
        rows, before anything is traced, where it answered NaN angles and values (issue 42);
        finite rows far outside the descriptor's range answer finite angles, values never NaN."""
        model = models[chains]
        with no_tracing() as traced, pytest.raises(NonFiniteRowsError) as e:
            engine.project(model, np.full((5, 15), np.nan), "relaxed")
        assert traced == [] and isinstance(e.value, ConfigError)
        assert e.value.rows.tolist() == [0, 1, 2, 3, 4]
        assert str(e.value).startswith("descriptors must be finite: row(s) 0, 1, 2, 3, 4 of 5 ")
        seq = datasets.msr_action3d(subjects=[2], actions=[5])[0]
        d = np.asarray(datasets.valid_descriptors(seq.positions))[:40].copy()
        d[7, 3], d[30, 0] = np.inf, np.nan  # one bad value in a row is enough
        d[8:20] = -np.inf
        for objective in ("relaxed", "full"):
            with no_tracing() as traced, pytest.raises(NonFiniteRowsError) as e:
                engine.project(model, d, objective, n_l=L, n_m=M, batch_size=64)
            assert traced == [] and e.value.rows.tolist() == [7, *range(8, 20), 30]
            assert "row(s) 7, 8, 9, 10, 11, ... (14 rows) of 40 hold NaN or inf" in str(e.value)
        # finite but absurd rows (1e30, float32's largest): finite angles in the limits, no NaN
        huge = np.concatenate([np.full((2, 15), 1e30), np.full((2, 15), -3.4e38), d[:2]])
        for objective in ("relaxed", "full"):
            q, v = engine.project(model, huge, objective, n_l=L, n_m=M, batch_size=64)
            assert np.isfinite(q).all() and not np.isnan(v).any()
            assert (q >= robot.LOWER[robot.DRIVEN_INDEX]).all()
            assert (q <= robot.UPPER[robot.DRIVEN_INDEX]).all()

    def test_projection_configuration_errors_come_before_tracing(self, models):
        model = models["upper"]
        d = np.zeros((4, 15), np.float32)
        k = model.n_landmarks
        cases = [
            (dict(n_l=0), "L=0"),
            (dict(n_l=k + 1), f"L={k + 1}"),
            (dict(n_m=k + 1), "chain has"),
            (dict(batch_size=0), "batch_size=0"),
            (dict(objective="fast"), "objective must be"),
        ]
        for kwargs, word in cases:
            with no_tracing() as traced, pytest.raises(ConfigError, match=word):
                engine.project(model, d, **kwargs)
            assert traced == []
        with no_tracing() as traced, pytest.raises(ConfigError, match="must lie in"):
            retarget(make_frames(["ok"] * 3, 0), model=model, n_l=k + 1)
        assert traced == []
        with pytest.raises(ConfigError, match=r"descriptors must be \(B, 15\)"):
            engine.project(model, np.zeros((4, 57), np.float32))


# --- model files ----------------------------------------------------------------------------------


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _meta(arrays: dict) -> dict:
    return json.loads(str(arrays["meta"]))


def _edit(src: Path, dst: Path, change) -> Path:
    """A copy of model file ``src`` at ``dst`` with ``change(arrays, meta)`` applied."""
    arrays = _arrays(src)
    meta = _meta(arrays)
    original = arrays["meta"]
    change(arrays, meta)
    if arrays.get("meta") is original:  # not replaced or dropped by the change
        arrays["meta"] = np.array(json.dumps(meta))
    np.savez(dst, **arrays)
    return dst


def _set(key, value):
    def change(a, m):
        a[key] = value(a[key]) if callable(value) else value

    return change


def _drop(key):
    return lambda a, m: a.pop(key)


def _meta_set(*keys_and_value):
    *keys, value = keys_and_value

    def change(a, m):
        d = m
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value(d[keys[-1]]) if callable(value) else value

    return change


BAD_MODELS = [
    # (id, change to a good model file, words of the InputError)
    ("future-version", _meta_set("format_version", engine.FORMAT_VERSION + 1),
     [f"version {engine.FORMAT_VERSION + 1}", "newer jaxproj", "upgrade jaxproj"]),
    ("old-version", _meta_set("format_version", 2), ["version 2", "rebuild"]),
    ("missing-array", _drop("chain1.forward.out"), ["missing array 'chain1.forward.out'"]),
    ("mis-shaped", _set("chain0.human", lambda x: x[:, :2]),
     ["'chain0.human' has shape", "m=3"]),
    ("mis-shaped-bank", _set("chain2.backward.out", lambda x: x[:, :, :4]),
     ["'chain2.backward.out'", "Hb=16"]),
    ("wrong-kind", _set("chain0.forward.neighbours", lambda x: x.astype(np.float32)),
     ["neighbours", "integers"]),
    ("non-finite", _set("chain1.robot", lambda x: np.where(x == x.max(), np.nan, x)),
     ["'chain1.robot' has non-finite values"]),
    ("bad-neighbours", _set("chain0.backward.neighbours", lambda x: x + 1000),
     ["indexes beyond"]),
    ("no-meta", _drop("meta"), ["not a jaxproj model", "no 'meta'"]),
    ("meta-not-json", _set("meta", np.array("{not json")), ["corrupt model metadata"]),
    ("other-format", _meta_set("format", "something-else"), ["not a jaxproj model"]),
    ("bad-config", _meta_set("config", "chains", "legs"),
     ["invalid model configuration", "legs"]),
    ("other-layout-names", _meta_set("chains", "names", lambda n: n[::-1]),
     ["chain names", "another chain layout"]),
    ("other-layout-outputs", _meta_set("chains", "outputs", lambda o: [o[0], o[2], o[1]]),
     ["chain outputs", "another chain layout"]),
    ("other-layout-chains", _meta_set("config", "chains", "whole"),
     ["another chain layout"]),
    ("extra-chain", lambda a, m: a.update({"chain3.human": a["chain2.human"]}),
     ["chain3", "beyond its 3 chain(s)", "another chain layout"]),
    ("driven-joints", _meta_set("driven_joints", lambda j: j[::-1]),
     ["driven joints", "another chain layout"]),
]  # fmt: skip


class TestModelFiles:
    """``engine.load`` (and the CLI's ``--model``) on every kind of bad model file: an
    ``InputError`` naming the file and the problem, one line; never a crash in JAX later."""

    @pytest.mark.parametrize(
        ("change", "words"), [c[1:] for c in BAD_MODELS], ids=[c[0] for c in BAD_MODELS]
    )
    def test_bad_model_file(self, model_file, tmp_path, change, words):
        path = _edit(model_file, tmp_path / "bad.npz", change)
        with pytest.raises(InputError) as info:
            engine.load(path)
        msg = str(info.value)
        assert msg.startswith(f"{path}: ") and "\n" not in msg
        for w in words:
            assert w in msg, (w, msg)

    def test_broken_files(self, model_file, tmp_path):
        raw = model_file.read_bytes()
        motion = tmp_path / "motion.npz"
        assert run_cli_quiet("retarget", _msr(tmp_path), "--out", motion) == 0
        cases = {
            "truncated": (raw[: len(raw) // 2], "not a readable model file"),
            "truncated-head": (raw[:10], "not a readable model file"),
            "empty": (b"", "empty file"),
            "text": (b"hello\n", "not an npz archive"),
            "positions": (None, "not a jaxproj model"),
            "motion": (motion.read_bytes(), "not a jaxproj model"),
        }
        for name, (data, word) in cases.items():
            path = tmp_path / f"{name}.npz"
            if data is None:
                np.savez(path, positions=np.zeros((2, 20, 3)))
            else:
                path.write_bytes(data)
            with pytest.raises(InputError, match=word) as info:
                engine.load(path)
            assert str(info.value).startswith(f"{path}: "), name
        with pytest.raises(InputError, match="is a directory"):
            engine.load(tmp_path)
        with pytest.raises(InputError, match="not found"):
            engine.load(tmp_path / "nope.npz")

    def test_cli_refuses_bad_models_in_one_line(self, model_file, tmp_path, capsys):
        src = _msr(tmp_path)
        bad = {
            "future": _edit(model_file, tmp_path / "future.npz",
                            _meta_set("format_version", engine.FORMAT_VERSION + 1)),
            "truncated": tmp_path / "trunc.npz",
        }  # fmt: skip
        bad["truncated"].write_bytes(model_file.read_bytes()[:1000])
        for path in bad.values():
            argv = ["retarget", src, "--out", tmp_path / "o.npz", "--method", "relaxed"]
            code, _, err = run_cli(capsys, *argv, "--model", path)
            assert_one_line_error(code, err, str(path))
            argv = ["evaluate", "--model", path, "--json", tmp_path / "r.json"]
            code, _, err = run_cli(capsys, *argv)
            assert_one_line_error(code, err, str(path))
        assert not (tmp_path / "o.npz").exists() and not (tmp_path / "r.json").exists()


def run_cli_quiet(*argv) -> int:
    from jaxproj.cli import main

    return main([str(a) for a in argv])


def _msr(folder: Path, name: str = "a01_s02_e01_skeleton3D.txt", frames: int = 12) -> Path:
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    path = folder / name
    path.write_text(msr_file(seq.positions[:frames]))
    return path


# --- atomic writes --------------------------------------------------------------------------------


class TestAtomicWrites:
    """A model or report write that fails half-way leaves the previous file as it was and no
    temporary file behind."""

    def test_model_save_failing_midway(self, models, tmp_path, monkeypatch):
        path = tmp_path / "p.npz"
        engine.save(models["upper"], path)
        before = path.read_bytes()
        real = np.lib.format.write_array
        calls = []

        def failing(fh, array, **kwargs):
            calls.append(1)
            if len(calls) == 5:  # a few members in: the zip is half-written
                raise OSError(28, "No space left on device")
            return real(fh, array, **kwargs)

        monkeypatch.setattr(np.lib.format, "write_array", failing)
        with pytest.raises(InputError, match="No space left on device") as info:
            engine.save(models["whole"], path)
        assert str(info.value).startswith(str(path))
        calls.clear()

        def interrupted(fh, array, **kwargs):
            calls.append(1)
            if len(calls) == 5:
                raise KeyboardInterrupt
            return real(fh, array, **kwargs)

        monkeypatch.setattr(np.lib.format, "write_array", interrupted)
        with pytest.raises(KeyboardInterrupt):
            engine.save(models["whole"], path)
        assert path.read_bytes() == before
        assert sorted(p.name for p in tmp_path.iterdir()) == ["p.npz"]
        monkeypatch.undo()
        engine.load(path)  # still the good model

    def test_report_write_failing_midway(self, tmp_path):
        path = tmp_path / "r.json"
        report.write_json(path, {"a": 1.0, "_private": 2})
        before = path.read_text()
        assert json.loads(before) == {"a": 1.0}
        with pytest.raises(UnicodeEncodeError):  # fails while the text is being written
            report.write_text(path, '{"a": "' + "x" * 100_000 + '\ud800"}')
        with pytest.raises(TypeError):  # not JSON: fails before anything is written
            report.write_json(path, {"a": object()})
        assert path.read_text() == before
        assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
        with pytest.raises(ConfigError, match="is not a folder"):
            report.write_json(path / "below_a_file.json", {"a": 1})

    def test_no_writer_creates_a_folder(self, models, tmp_path):
        """One policy for the CLI and the Python API (issue 42): a missing folder is a
        ``ConfigError`` naming the file and the folder; nothing is created (``jaxproj.save``
        once made ``a/b/``, ``save_motion("/nope/x.json")`` made ``/nope``)."""
        for target in (tmp_path / "a" / "b" / "p.npz", tmp_path / "a" / "r.json"):
            with pytest.raises(ConfigError) as e:
                if target.suffix == ".npz":
                    jaxproj.save(models["upper"], target)
                else:
                    report.write_json(target, {"a": 1})
            assert str(e.value) == (
                f"{target}: folder {target.parent} does not exist (jaxproj creates no folder "
                "for an output file: create it first)"
            )
        assert list(tmp_path.iterdir()) == []


# --- outputs: never over an existing file unless told, never over an input (issue 56) ------------


EXISTS = "exists; pass overwrite=True (Python) / --force (CLI) to replace it"
"""The end of every Python API writer's refusal of an existing file."""


class WorkStarted(Exception):
    """Raised by the stand-ins of the commands' first piece of work (``_no_work``)."""


def _no_work(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every command's first piece of work raises ``WorkStarted``: reading a recording, a
    motion or the data, loading a model's arrays, running the demo."""
    from jaxproj.cli import options
    from jaxproj.io import motion_files, readers
    from jaxproj.paper import demo

    def started(*args, **kwargs):
        raise WorkStarted

    for module, name in ((readers, "read_skeleton"), (engine, "load"), (options, "load_data"),
                         (motion_files, "load_motion"), (demo, "run_demo")):  # fmt: skip
        monkeypatch.setattr(module, name, started)


def _standing_motion() -> jaxproj.Motion:
    n = 4
    standing = jaxproj.robots.get().standing
    return jaxproj.Motion(np.tile(standing, (n, 1)), np.arange(n) / 15.0, np.ones(n, bool))


class TestOutputs:
    """Issue 56: ``jaxproj retarget rec.npz --out rec.npz`` replaced the recording. Every CLI
    output refuses an existing file unless ``--force`` and one of the command's inputs even
    with it, and every Python API writer takes ``overwrite`` (default ``True``), all before any
    work; every check that needs no computation runs before the first."""

    def test_api_writers_refuse_an_existing_file_without_overwrite(self, models, tmp_path):
        from jaxproj.paper.demo import run_demo
        from jaxproj.viz import render, video

        motion = _standing_motion()
        frames = np.zeros((2, 32, 32, 3), np.uint8)
        summary = {"relaxed": {"per_joint": {j: {"p50": 1.0, "p95": 2.0}
                                             for j in robot.DRIVEN_JOINTS}}}  # fmt: skip
        writers = {
            "model.npz": lambda p, o: jaxproj.save(models["upper"], p, overwrite=o),
            "motion.npz": lambda p, o: jaxproj.save_motion(p, motion, overwrite=o),
            "motion.csv": lambda p, o: jaxproj.save_motion(p, motion, overwrite=o),
            "motion.json": lambda p, o: jaxproj.save_motion(p, motion, overwrite=o),
            "report.json": lambda p, o: report.write_json(p, {"a": 1}, overwrite=o),
            "report.md": lambda p, o: report.write_text(p, "# r\n", overwrite=o),
            "video.gif": lambda p, o: video.save_video(frames, p, 10.0, overwrite=o),
            "render.gif": lambda p, o: render.render_to_file(motion, p, overwrite=o),
            "motion_file.gif": lambda p, o: render.render_motion(motion, p, overwrite=o),
            "per_joint.png": lambda p, o: report.plot_per_joint(p, summary, overwrite=o),
            "sizes.png": lambda p, o: report.plot_landmark_size(p, {}, overwrite=o),
            "efficiency.png": lambda p, o: report.plot_efficiency(p, {}, overwrite=o),
            "cdf.png": lambda p, o: report.plot_distributions(p, {}, np.zeros(0), overwrite=o),
            "motion.png": lambda p, o: report.plot_motion(
                p, "", np.zeros(0), np.zeros(0), np.zeros(0), {}, robot=robot, overwrite=o
            ),
            "retarget.png": lambda p, o: report.plot_retarget(
                p, "", *[np.zeros(0)] * 5, robot=robot, overwrite=o
            ),
        }
        with no_tracing() as traced:
            for name, write in writers.items():
                path = tmp_path / name
                path.write_bytes(b"old")
                with pytest.raises(ConfigError) as e:
                    write(path, False)
                assert str(e.value) == f"{path}: {EXISTS}", name
                assert path.read_bytes() == b"old", name
            folder = tmp_path / "report"
            folder.mkdir()
            (folder / "report.md").write_text("old")
            with pytest.raises(ConfigError, match="holds the report of an earlier run"):
                run_demo(folder, quick=True, overwrite=False)
            with pytest.raises(ConfigError, match="is a file, not a report folder"):
                run_demo(tmp_path / "report.md", quick=True)
        assert traced == []
        # the default replaces, as numpy's savers do
        for name in ("model.npz", "motion.npz", "motion.json", "report.json"):
            writers[name](tmp_path / name, True)
            assert (tmp_path / name).read_bytes() != b"old", name
        assert engine.load(tmp_path / "model.npz").config == models["upper"].config
        assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []

    def test_api_writers_never_replace_their_input(self, tmp_path):
        from jaxproj._internal.atomic import check_output, same_file
        from jaxproj.viz import render

        src = tmp_path / "motion.npz"
        jaxproj.save_motion(src, _standing_motion())
        before = src.read_bytes()
        (tmp_path / "link.gif").symlink_to(src)
        os.link(src, tmp_path / "hard.gif")
        for alias in ("link.gif", "hard.gif"):
            assert same_file(tmp_path / alias, src)
            with pytest.raises(ConfigError, match="is the motion file too"):
                render.render_motion(src, tmp_path / alias, overwrite=True)
        assert src.read_bytes() == before
        # two outputs not written yet: the same resolved path
        assert same_file(tmp_path / "a.png", tmp_path / "sub" / ".." / "a.png")
        assert not same_file(tmp_path / "a.png", tmp_path / "b.png")
        with pytest.raises(ConfigError, match=r"b\.npz: is --out too"):
            check_output(tmp_path / "b.npz", inputs={"--out": tmp_path / "." / "b.npz"})

    def test_cli_refuses_existing_outputs_before_any_work(
        self, model_file, tmp_path, capsys, monkeypatch
    ):
        src = _msr(tmp_path)
        motion = tmp_path / "motion.npz"
        jaxproj.save_motion(motion, _standing_motion())
        old = {n: tmp_path / n for n in ("o.npz", "o.png", "m.npz", "r.json", "v.gif")}
        report_dir = tmp_path / "report"
        report_dir.mkdir()
        old["report"] = report_dir / "motion_a01_s02_e01.png"  # a file the demo writes
        for path in old.values():
            path.write_bytes(b"old")
        cases = [
            (["retarget", src, "--out", old["o.npz"]], f"--out {old['o.npz']}"),
            (["retarget", src, "--out", tmp_path / "n.npz", "--plot", old["o.png"]],
             f"--plot {old['o.png']}"),
            (["build", "--out", old["m.npz"]], f"--out {old['m.npz']}"),
            (["evaluate", "--model", model_file, "--json", old["r.json"]],
             f"--json {old['r.json']}"),
            (["render", motion, "--out", old["v.gif"]], f"--out {old['v.gif']}"),
            (["demo", "--out", report_dir], f"--out {report_dir}: holds the report of an "
             "earlier run (motion_a01_s02_e01.png)"),
        ]  # fmt: skip
        _no_work(monkeypatch)
        with no_tracing() as traced:
            for argv, words in cases:
                code, _, err = run_cli(capsys, *argv)
                assert_one_line_error(code, err, words, "pass --force to replace it")
                with pytest.raises(WorkStarted):  # --force: the checks pass, the work starts
                    run_cli(capsys, *argv, "--force")
        assert traced == []
        assert all(path.read_bytes() == b"old" for path in old.values())

    def test_cli_never_writes_over_an_input(self, model_file, tmp_path, capsys, monkeypatch):
        src = tmp_path / "rec.npz"  # a recording that `retarget --out` could name
        np.savez(src, positions=datasets.msr_action3d(subjects=[2], actions=[1])[0].positions)
        model = tmp_path / "p.npz"
        model.write_bytes(model_file.read_bytes())
        motion = tmp_path / "motion.npz"
        jaxproj.save_motion(motion, _standing_motion())
        os.link(src, tmp_path / "hard.npz")
        (tmp_path / "link.gif").symlink_to(motion)
        folder = tmp_path / "data"
        folder.mkdir()
        rec = _msr(folder)
        cases = [
            (["retarget", src, "--out", src], "the recording"),
            (["retarget", src, "--out", tmp_path / "hard.npz"], "the recording"),
            (["retarget", src, "--method", "relaxed", "--model", model, "--out", model],
             "--model"),
            (["retarget", src, "--out", tmp_path / "o.npz", "--plot",
              tmp_path / "x" / ".." / "o.npz"], "use a .png"),
            (["evaluate", "--model", model, "--json", model], "--model"),
            (["render", motion, "--out", tmp_path / "link.gif"], "the motion file"),
            (["build", "--data", folder, "--out", rec.with_suffix(".npz")], None),
            (["evaluate", "--model", model, "--data", folder, "--json", rec], "a file of --data"),
        ]  # fmt: skip
        rec.with_suffix(".npz").write_bytes(b"a recording")  # NPZ is a recording format too
        cases[6] = (cases[6][0], "a file of --data")
        before = {p: p.read_bytes() for p in (src, model, motion, rec, rec.with_suffix(".npz"))}
        _no_work(monkeypatch)
        for argv, what in cases:
            code, _, err = run_cli(capsys, *argv, "--force")
            assert_one_line_error(code, err, what)
            if what != "use a .png":
                assert "too: write the output to another file" in err and "--force" in err
        assert all(p.read_bytes() == b for p, b in before.items())

    def test_cli_checks_come_before_the_model_and_the_recording(
        self, model_file, tmp_path, capsys, monkeypatch
    ):
        """``--out x.json`` with a G1 model was refused after ~3 minutes of work: a model's
        robot, bones and mirroring are read from its metadata alone, and every option checked
        against them before the recording is read or the model's arrays loaded (here a file
        whose metadata says G1: its arrays, the NAO's, are never read)."""
        src = _msr(tmp_path)

        def to_g1(arrays, meta):
            meta["config"].update(robot="unitree_g1", bones="full")

        g1 = _edit(model_file, tmp_path / "g1.npz", to_g1)
        relaxed = ["retarget", src, "--method", "relaxed", "--out"]
        cases = [
            ([*relaxed, tmp_path / "o.json", "--model", g1],
             "a .json motion is not written for the unitree_g1 (its formats: .npz, .csv;"),
            ([*relaxed, tmp_path / "o.csv", "--model", g1, "--joints", "body"],
             "--joints picks the joints of a robot's own document"),
            ([*relaxed, tmp_path / "o.npz", "--model", model_file, "--joints", "upper"],
             "--joints picks the joints"),
            ([*relaxed, tmp_path / "o.npz", "--model", model_file, "--bones", "full"],
             "--bones full conflicts with the model"),
            ([*relaxed, tmp_path / "o.npz", "--model", g1, "--robot", "nao_h25"],
             "--robot nao_h25 conflicts with the model"),
            (["retarget", src, "--robot", "unitree_g1", "--out", tmp_path / "o.json"],
             "not written for the unitree_g1"),
        ]  # fmt: skip
        _no_work(monkeypatch)
        with no_tracing() as traced:
            for argv, words in cases:
                code, _, err = run_cli(capsys, *argv)
                assert_one_line_error(code, err, words)
        assert traced == []
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted([src.name, g1.name])
        with pytest.raises(WorkStarted):  # the same model with a .csv: on to the work
            run_cli(capsys, *relaxed, tmp_path / "o.csv", "--model", g1)


# --- determinism ----------------------------------------------------------------------------------


def _child_env() -> dict[str, str]:
    root = str(Path(jaxproj.__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
    env.setdefault("JAX_PLATFORMS", "cpu")
    return env


class TestDeterminism:
    """Same data, config and seed: byte-identical model files and identical outputs from two
    processes; save -> load -> project is project; the evaluate JSON is identical across runs
    except timings (``TestFolders``)."""

    def test_two_processes_build_the_same_bytes_and_retarget_the_same(self, tmp_path):
        src = _msr(tmp_path, frames=40)
        # bandwidths given (one mean shift per chain), not a landmark count to bisect: the same
        # pipeline in a fraction of the time
        script = (
            "import sys; from jaxproj.cli import main; d = sys.argv[1]; "
            "sys.exit(main(['build', '--subjects', '1', '--chains', 'upper', '--bandwidth', "
            "'0.01125,0.098,0.106', '--k', '16', '--hidden', '16', '--out', d + '/p.npz']) or "
            "main(['retarget', "
            "sys.argv[2], '--method', 'relaxed', '--model', d + '/p.npz', '--L', '5', '--M', "
            "'5', '--out', d + '/m.npz']))"
        )
        dirs = [tmp_path / "run1", tmp_path / "run2"]
        procs = []
        for d in dirs:
            d.mkdir()
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-c", script, str(d), str(src)],
                    env=_child_env(),
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    text=True,
                )
            )
        for p in procs:
            out, err = p.communicate(timeout=500)
            assert p.returncode == 0, err
        a, b = (d / "p.npz" for d in dirs)
        assert a.read_bytes() == b.read_bytes()
        with zipfile.ZipFile(a) as zf:  # no wall-clock timestamps in the file
            assert {i.date_time for i in zf.infolist()} == {(1980, 1, 1, 0, 0, 0)}
        ma, mb = (load_motion(d / "m.npz") for d in dirs)
        for field in ("angles", "times", "valid", "positions"):
            np.testing.assert_array_equal(getattr(ma, field), getattr(mb, field))
        assert ma.meta == mb.meta and np.isfinite(ma.angles).all()

    @pytest.mark.parametrize("chains", ["upper", "whole"])
    def test_save_load_project_equals_project(self, models, tmp_path, chains):
        model = models[chains]
        path = tmp_path / "p.npz"
        engine.save(model, path)
        back = engine.load(path)
        assert back.config == model.config and back.landmarks == model.landmarks
        seq = datasets.msr_action3d(subjects=[2], actions=[5])[0]
        d = np.asarray(datasets.valid_descriptors(seq.positions))[:40]
        for objective in ("relaxed", "full"):
            a, va = engine.project(model, d, objective, n_l=L, n_m=M, batch_size=64)
            b, vb = engine.project(back, d, objective, n_l=L, n_m=M, batch_size=64)
            np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(va, vb)
        engine.save(back, tmp_path / "again.npz")  # lossless: saving the loaded model again
        assert (tmp_path / "again.npz").read_bytes() == path.read_bytes()


# --- folders --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def folder(tmp_path_factory, model_file) -> Path:
    """A user's folder: three recordings (MSR subjects 2 and 4, UTKinect subject 3), the
    dataset's own SOURCE.md and actionLabel.txt, a model, a CSV of results, a hidden file, a
    subfolder and one broken recording (subject 6: 25 rows, not a multiple of 20)."""
    f = tmp_path_factory.mktemp("recordings")
    _msr(f, "a01_s02_e01_skeleton3D.txt", 16)
    seq = datasets.msr_action3d(subjects=[4], actions=[8])[0]
    (f / "a08_s04_e01_skeleton3D.txt").write_text(msr_file(seq.positions[:16]))
    utk = datasets.utkinect_action3d(subjects=[3], segments=False)[0]
    (f / "joints_s03_e01.txt").write_text(
        utk_file(utk.positions[:16], list(utk.frame_numbers[:16]), "\r\n", " ")
    )
    broken = msr_file(seq.positions[:2]).splitlines()[:25]
    (f / "a02_s06_e01_skeleton3D.txt").write_text("\n".join(broken) + "\n")
    (f / "SOURCE.md").write_text("# UTKinect Action3D subset\n\nWhere the files come from.\n")
    (f / "actionLabel.txt").write_text("s03_e01\nwalk: 252 390\nsitDown: 572 686\n")
    (f / "results.csv").write_text("method,error\nrelaxed,1.0\n")
    (f / "projector.npz").write_bytes(model_file.read_bytes())
    (f / ".DS_Store").write_bytes(b"\x00\x00\x00\x01Bud1\x00")
    (f / "old").mkdir()
    return f


RECORDINGS = {"a01_s02_e01_skeleton3D", "a08_s04_e01_skeleton3D", "joints_s03_e01"}


class TestFolders:
    """``evaluate`` / ``build`` over a folder: files that are not recordings are skipped with a
    note; every recording is used by default; ``--subjects`` says what it left out and why; an
    unreadable recording is reported and the rest evaluated unless ``--strict``."""

    def _evaluate(self, capsys, model_file, folder, out: Path, *extra: str):
        return run_cli(
            capsys,
            "evaluate", "--model", model_file, "--data", folder, "--objective", "relaxed",
            "--L", str(L), "--M", str(M), "--json", out, *extra,
        )  # fmt: skip

    def test_evaluate_skips_notes_and_reports_the_unreadable_recording(
        self, capsys, model_file, folder, tmp_path
    ):
        runs = []
        for i in range(2):
            out = tmp_path / f"r{i}.json"
            code, stdout, err = self._evaluate(capsys, model_file, folder, out)
            assert code == 0, err
            assert "Traceback" not in err
            runs.append((json.loads(out.read_text()), stdout, err))
        report_json, stdout, err = runs[0]
        for name in ("SOURCE.md", "actionLabel.txt", "results.csv", "projector.npz", ".DS_Store",
                     "old"):  # fmt: skip
            assert f"jaxproj: note: skipped {name}: " in err, name
        assert "jaxproj: note: unreadable recording, not used: " in err
        assert "a02_s06_e01_skeleton3D.txt: found 25 rows" in err
        assert "1 unreadable recording(s) not used: a02_s06_e01_skeleton3D.txt" in stdout
        # every recording of the folder by default (no subject filter)
        assert set(report_json["per_sequence"]) == RECORDINGS
        assert report_json["subjects"] == [2, 3, 4]
        files = report_json["data_files"]
        assert files["recordings"] == 3 and files["left_out"] == []
        assert [u["file"] for u in files["unreadable"]] == ["a02_s06_e01_skeleton3D.txt"]
        assert {s["file"] for s in files["skipped"]} == {
            ".DS_Store",
            "SOURCE.md",
            "actionLabel.txt",
            "old",
            "projector.npz",
            "results.csv",
        }
        assert np.isfinite(report_json["summary"]["relaxed"]["M_avg"]["median"])
        # the same data, model and settings: the same JSON, timings aside
        a, b = (dict(r[0]) for r in runs)
        assert a.pop("wall_s").keys() == b.pop("wall_s").keys()
        assert a == b

    def test_strict_stops_at_the_unreadable_recording(self, capsys, model_file, folder, tmp_path):
        out = tmp_path / "r.json"
        code, _, err = self._evaluate(capsys, model_file, folder, out, "--strict")
        assert_one_line_error(code, err, "a02_s06_e01_skeleton3D.txt", "multiple of 20")
        assert not out.exists()

    def test_subjects_say_what_was_left_out(self, capsys, model_file, folder, tmp_path):
        out = tmp_path / "r.json"
        code, stdout, err = self._evaluate(capsys, model_file, folder, out, "--subjects", "2,3,7")
        assert code == 0, err
        r = json.loads(out.read_text())
        assert set(r["per_sequence"]) == {"a01_s02_e01_skeleton3D", "joints_s03_e01"}
        assert "left out 2 recording(s) of subjects other than [2, 3, 7]: " in err
        assert "a02_s06_e01_skeleton3D.txt (subject 6)" in err
        assert "a08_s04_e01_skeleton3D.txt (subject 4)" in err
        assert "no recording of subject(s) [7]" in err
        assert r["data_files"]["unreadable"] == []  # the broken file was left out, not read
        assert "unreadable" not in stdout
        code, _, err = self._evaluate(capsys, model_file, folder, tmp_path / "r8.json",
                                      "--subjects", "8")  # fmt: skip
        assert_one_line_error(code, err, str(folder), "no recording to use", "other subjects")

    def test_build_from_the_folder_notes_the_unreadable_recording(self, capsys, folder, tmp_path):
        out = tmp_path / "m.npz"
        code, stdout, err = run_cli(
            capsys, "build", "--data", folder, "--chains", "whole", "--bandwidth", "0.3", "--k",
            "4", "--hidden", "8", "--out", out,
        )  # fmt: skip
        assert code == 0, err
        assert "skipped SOURCE.md" in err and "1 unreadable recording(s) not used" in stdout
        assert engine.load(out).n_train > 0
        code, _, err = run_cli(
            capsys,
            "build",
            "--data",
            folder,
            "--bandwidth",
            "0.3",
            "--strict",
            "--out",
            tmp_path / "s.npz",
        )
        assert_one_line_error(code, err, "a02_s06_e01_skeleton3D.txt")

    def test_library_folder_api(self, folder):
        with pytest.raises(InputError, match="a02_s06_e01_skeleton3D.txt"):
            datasets.load_sequences(folder)  # strict by default in Python
        contents = datasets.load_folder(folder, strict=False)
        assert {s.name for s in contents.sequences} == RECORDINGS
        assert [n for n, _ in contents.unreadable] == ["a02_s06_e01_skeleton3D.txt"]
        assert {s.subject for s in contents.sequences} == {2, 3, 4}
        why = dict(contents.skipped)
        assert "4 (MSR Action3D) or 61 (UTKinect) numbers" in why["SOURCE.md"]
        assert "without 'positions'" in why["projector.npz"]
        assert why["old"] == "a folder (not searched)"
        recs = datasets.load_sequences(folder, [2, 4])
        assert {s.name for s in recs} == {"a01_s02_e01_skeleton3D", "a08_s04_e01_skeleton3D"}
