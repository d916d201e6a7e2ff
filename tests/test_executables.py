"""Executables kept on disk by the command line (``jaxproj._internal.executables``): a second
call with the same key runs the kept program (no trace), a change of any part of the key is
another program, and what cannot be keyed is never kept."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj import robots
from jaxproj._internal import executables
from jaxproj.cli import main

TRACES: list[int] = []


def _f(x: jax.Array, *, scale: float) -> jax.Array:
    TRACES.append(1)  # runs while tracing only
    return jnp.sin(x) * scale


F = jax.jit(_f, static_argnames=("scale",))


def _call(x: np.ndarray, scale: float = 2.0, identity: object = ("t", 1)) -> np.ndarray:
    return np.asarray(
        executables.call(F, (x,), static={"scale": scale}, name="f", identity=identity)
    )


def _new_process() -> None:
    """Forget what this process traced and loaded, as a new process starts."""
    executables._LOADED.clear()
    jax.clear_caches()


@pytest.fixture(autouse=True)
def _fresh() -> None:
    _new_process()
    TRACES.clear()


def test_a_kept_program_runs_again_without_a_trace(tmp_path: Path) -> None:
    x = np.linspace(0, 1, 8, dtype=np.float32)
    with executables.kept_in(tmp_path):
        first = _call(x)
        np.testing.assert_allclose(first, np.sin(x) * 2.0, rtol=1e-6)
        assert len(TRACES) == 1 and len(list(tmp_path.glob("f-*.xla"))) == 1
        _new_process()
        np.testing.assert_array_equal(_call(x), first)  # from the file, not traced again
        assert len(TRACES) == 1
        # another static value, shape, dtype or identity: another program, another file
        _call(x, scale=3.0)
        _call(x[:4])
        _call(x.astype(np.float16))
        _call(x, identity=("t", 2))
        assert len(TRACES) == 5 and len(list(tmp_path.glob("f-*.xla"))) == 5


def test_a_broken_file_is_compiled_again_and_replaced(tmp_path: Path) -> None:
    x = np.ones(4, np.float32)
    with executables.kept_in(tmp_path):
        _call(x)
        (path,) = tmp_path.glob("f-*.xla")
        path.write_bytes(b"not a program")
        _new_process()
        np.testing.assert_allclose(_call(x), np.sin(x) * 2.0)
        assert len(TRACES) == 2 and path.read_bytes() != b"not a program"


def test_nothing_is_kept_without_a_folder_an_identity_or_a_stable_key(tmp_path: Path) -> None:
    x = np.ones(4, np.float32)
    _call(x)  # no folder: a plain jit call
    with executables.kept_in(tmp_path):
        _call(x, identity=None)
        # a static argument whose repr holds an address (differs in every process)
        executables.call(
            jax.jit(lambda v, *, fn: fn(v), static_argnames=("fn",)),
            (x,),
            static={"fn": lambda v: v + 1},
            name="g",
            identity=("t", 1),
        )
    assert not list(tmp_path.iterdir())


def test_a_robot_is_identified_by_its_files_only_as_registered() -> None:
    g1 = robots.get("unitree_g1")
    name, digest = robots.identity(g1)  # type: ignore[misc]
    assert name == "unitree_g1" and len(digest) == 64
    assert robots.identity(dataclasses.replace(g1, track=None, track_step=None)) is None
    assert len(executables.source_digest()) == 64


def test_the_second_retarget_of_the_command_line_loads_its_program(tmp_path: Path, capsys) -> None:
    """Through ``jaxproj retarget`` (the NAO, a robot file): the first run keeps the retarget
    program in the cache folder's ``executables``, the second loads it and writes the same."""
    from helpers import msr_text

    from jaxproj.io import datasets

    seq = datasets.msr_action3d(subjects=[1], actions=[1])[0]
    rec = tmp_path / "a01_s01_e01_skeleton3D.txt"
    rec.write_text(msr_text(seq.positions))
    cache = tmp_path / "cache"
    outs = []
    for i in range(2):
        _new_process()
        out = tmp_path / f"m{i}.npz"
        with pytest.MonkeyPatch.context() as m:
            m.setenv("JAXPROJ_CACHE_DIR", str(cache))
            m.setenv("JAXPROJ_KEEP_EXECUTABLES", "1")
            assert main(["retarget", str(rec), "--out", str(out)]) == 0, capsys.readouterr().err
        outs.append(np.load(out)["angles"])
    kept = sorted(p.name.split("-")[0] for p in (cache / "executables").glob("*.xla"))
    assert kept == ["retarget"]
    np.testing.assert_array_equal(outs[0], outs[1])


def test_a_kept_program_that_fails_to_run_is_dropped(tmp_path: Path, monkeypatch) -> None:
    """A program that loads but fails when it runs (XLA's runtime error): the file is deleted
    and the call answers as the plain jit call does."""
    x = np.ones(4, np.float32)
    with executables.kept_in(tmp_path):
        want = _call(x)
        (path,) = tmp_path.glob("f-*.xla")
        _new_process()

        class Broken:
            def __init__(self, *a: object, **k: object) -> None:
                pass

            def __call__(self, *a: object, **k: object) -> None:
                raise jax.errors.JaxRuntimeError("NOT_FOUND: Function fusion not found")

        import jax.experimental.serialize_executable as se

        monkeypatch.setattr(se, "deserialize_and_load", Broken)
        np.testing.assert_array_equal(_call(x), want)
        assert not path.exists() and not executables._LOADED


def test_two_models_of_one_shape_share_the_program_not_the_answers(tmp_path: Path) -> None:
    """The relaxed retarget of two models with the same shapes (seeds 0 and 1): one kept
    program (a projector's arrays are its arguments), each model's own answers, the same as
    without the kept program."""
    from jaxproj.io import datasets
    from jaxproj.motion.retarget import retarget
    from jaxproj.projection import api as engine
    from jaxproj.robots.nao_h25 import ik

    train = np.unique(datasets.valid_descriptors(datasets.msr_action3d(subjects=[1])), axis=0)
    human = train[np.sort(np.random.default_rng(0).choice(len(train), 120, replace=False))]
    robot = np.asarray(ik.solve_driven(human), np.float32)
    models = [
        engine.from_landmarks(human, robot, engine.BuildConfig(k=16, hidden=32, seed=s))
        for s in (0, 1)
    ]
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]

    def run(m: engine.Model) -> np.ndarray:
        return retarget(seq.positions, seq.valid, model=m).angles

    with executables.kept_in(tmp_path):
        kept = [run(m) for m in models]
    assert [p.name.split("-")[0] for p in tmp_path.glob("*.xla")] == ["retarget"]
    plain = [run(m) for m in models]
    np.testing.assert_array_equal(kept[0], plain[0])
    np.testing.assert_array_equal(kept[1], plain[1])
    assert np.abs(kept[0] - kept[1]).max() > 1e-3


def test_the_environment_turns_the_kept_executables_off(monkeypatch, tmp_path: Path) -> None:
    from jaxproj.cli import cache

    monkeypatch.setenv("JAXPROJ_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("JAXPROJ_KEEP_EXECUTABLES", "0")
    with cache.compilation_cache():
        assert executables.active() is None
    monkeypatch.setenv("JAXPROJ_KEEP_EXECUTABLES", "1")
    with cache.compilation_cache():
        assert executables.active() == tmp_path / cache.EXECUTABLES
    with cache.compilation_cache(enabled=False):
        assert executables.active() is None
