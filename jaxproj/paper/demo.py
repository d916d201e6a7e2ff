"""The main job, end to end on the bundled data: ``jaxproj demo``.

The protocol is the results page's (``docs/results.md``, "Accuracy on held-out people"): the
default model (``BuildConfig()``, per chain) and the whole-body one built from the default
training set (``datasets.training_sequences``: MSR Action3D subjects 1,3,5,7,9, every action,
and the whole recordings of the UTKinect-Action3D people 3, 4, 6; valid frames); scored on the
arm actions of the held-out MSR subjects 2,4,6,8,10 (a01-a12, a17-a19: 8,355 valid frames) and
on the upper-body segments of the UTKinect-Action3D people the model did not train on (7 and 9:
578 frames; ``datasets.utkinect_held_out``), L = M = 10, degrees against the analytic IK.

1. build the per-chain (default) and the whole-body projector;
2. evaluate every method on the held-out arm actions with and without smoothing, and both
   models side by side on them and on UTKinect (cross-dataset; the whole-body model without the
   full objective, whose converged solver is the evaluation's slowest method);
3. roll out held-out arm motions in MuJoCo (MJX on accelerators, its Warp implementation on a
   CUDA GPU with warp-lang, CPU MuJoCo on a CPU-only machine: ``rollout.simulate``'s default
   backend): what ``jaxproj retarget`` writes for a robot with ``--method relaxed`` and with
   ``--method ik`` (smoothed, then ``jaxproj.motion.feasible``), beside the raw per-frame IK
   and the smoothed relaxed projection;
4. the paper's experiments: eight basic poses and motions, landmark-set sizes (1644, 961, 86
   per arm, and the default model), L = M sweep;
5. write ``report.json``, ``report.md`` (``jaxproj.paper.demo_report``) and the PNG plots to
   ``--out``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import jax
import numpy as np

from jaxproj.eval import evaluate
from jaxproj.io import datasets
from jaxproj.motion import feasible
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.smoothing import frame_gains
from jaxproj.paper import demo_report
from jaxproj.paper.demo_report import QUICK_LANDMARKS, QUICK_TEST_STRIDE, QUICK_TRAIN_STRIDE
from jaxproj.projection import api as engine
from jaxproj.robots import Robot
from jaxproj.viz import report

TRAIN_SUBJECTS = datasets.TRAIN_SUBJECTS
TEST_SUBJECTS = datasets.TEST_SUBJECTS
TEST_ACTIONS = datasets.ARM_ACTIONS
"""The held-out MSR actions scored: the arm actions, as on the results page."""

SIZES = (1644, 961, 86)
"""The landmark-size study's targets per arm (the paper's), besides the default model."""


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _train_descriptors(model_cfg: engine.BuildConfig) -> np.ndarray:
    """The default training set's valid descriptors: MSR ``TRAIN_SUBJECTS`` and the UTKinect
    people of ``model_cfg.utkinect_people`` (``datasets.training_sequences``)."""
    seqs = datasets.training_sequences(model_cfg.utkinect_people, TRAIN_SUBJECTS)
    return datasets.valid_descriptors(seqs, bones=model_cfg.bones, mirror=model_cfg.mirror)


def utkinect_split(model_cfg: engine.BuildConfig, quick: bool = False) -> list:
    """The UTKinect sequences the demo scores: the upper-body segments of the bundled people
    ``model_cfg`` did not train on (``datasets.utkinect_held_out``; quick: every 2nd)."""
    return datasets.utkinect_held_out(model_cfg.utkinect_people)[:: 2 if quick else 1]


def _smoothed_ik(data: evaluate.EvalData, spec: Robot) -> np.ndarray:
    """The per-frame IK of every held-out motion through the smoother ``evaluate`` gives the
    methods (the default offline one; MSR has no times: 15 fps): ``(S, T_max, n)``."""
    lengths = np.diff(data.offsets)
    gains = frame_gains(OFFLINE_SMOOTHING, None, lengths)
    _, smoothed, _ = evaluate._per_motion(
        data, data.truth[data.valid], gains, robot=spec, smoother="offline"
    )
    return smoothed


ROLLOUT_TRAJECTORIES: dict[str, str] = {
    "ik": "the per-frame IK, raw",
    "ik_feasible": "the IK smoothed and made robot-feasible: what `jaxproj retarget --method ik` "
    "writes",
    "relaxed": "the relaxed projection, smoothed",
    "relaxed_feasible": "the relaxed projection smoothed and made robot-feasible: what "
    "`jaxproj retarget --method relaxed --model P.npz` writes",
}
"""The rollout's trajectories, in the report's words."""


def _rollout_section(
    data: evaluate.EvalData, ev: dict, n_motions: int, spec: Robot, devices=None
) -> dict:
    from jaxproj.eval import rollout

    t0 = time.perf_counter()
    lengths = np.diff(data.offsets)
    arm = np.flatnonzero(np.isin(data.actions, datasets.ARM_ACTIONS))
    picks = np.unique(arm[np.linspace(0, len(arm) - 1, n_motions).round().astype(int)])
    t_max = int(lengths[picks].max())
    out: dict = {
        "motions": [data.names[i] for i in picks],
        "frame_dt": 1.0 / 15.0,
        "backend": rollout.resolve_backend("auto", devices),
        "trajectories": dict(ROLLOUT_TRAJECTORIES),
    }
    ik_smoothed = _smoothed_ik(data, spec)
    ik_smoothed = np.concatenate([ik_smoothed[s, :n] for s, n in enumerate(lengths)])
    traj = {
        "ik": ev["_truth"],
        "ik_smoothed": ik_smoothed,
        "relaxed": ev["_predictions"]["relaxed"],
    }
    batches = {}
    for name, per_frame in traj.items():
        b = np.tile(spec.standing, (len(picks), t_max, 1)).astype(np.float32)
        for row, s in enumerate(picks):
            a, e = data.offsets[s], data.offsets[s + 1]
            b[row, : e - a] = np.asarray(spec.driven_to_full(per_frame[a:e]))
            b[row, e - a :] = b[row, e - a - 1]
        batches[name] = b
    times = np.tile(np.arange(t_max) * out["frame_dt"], (len(picks), 1))
    smoothed_ik = batches.pop("ik_smoothed")
    batches["ik_feasible"] = feasible.make_feasible(smoothed_ik, times, lengths[picks], robot=spec)
    batches["relaxed_feasible"] = feasible.make_feasible(
        batches["relaxed"], times, lengths[picks], robot=spec
    )
    for name in ROLLOUT_TRAJECTORIES:
        b = batches[name]
        res = rollout.simulate(b, lengths[picks], devices=devices, robot=spec)
        out[name] = rollout.summarize(res, lengths[picks], b, robot=spec)
        # the targets' own distance from the per-frame IK (what the person did), deg
        err = [np.degrees(np.abs(b[r, : lengths[s]][:, spec.driven_index]
                                 - ev["_truth"][data.offsets[s] : data.offsets[s + 1]]))
               for r, s in enumerate(picks)]  # fmt: skip
        valid = np.concatenate([data.valid[data.offsets[s] : data.offsets[s + 1]] for s in picks])
        m_avg = np.concatenate(err).mean(axis=1)[valid]
        out[name]["targets_vs_ik_M_avg"] = evaluate.describe(m_avg)
    out["frames"] = int(lengths[picks].sum())
    out["wall_s"] = time.perf_counter() - t0  # the whole section, as the demo's timings say
    return out


def run_demo(
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    devices: list[jax.Device] | None = None,
    overwrite: bool = True,
) -> dict:
    """Run the whole demo and write the report; returns the report dict.

    The full run builds the default model (``BuildConfig()``) and scores it by the results
    page's protocol (module docstring). ``quick`` (the tests' setting, a smoke run of every
    stage in a few minutes on 2 cores) builds from every ``QUICK_TRAIN_STRIDE``-th training
    frame with ``QUICK_LANDMARKS`` landmarks per arm chain (and for the whole body) instead of
    the default model, evaluates every ``QUICK_TEST_STRIDE``-th held-out MSR arm recording and
    every 2nd UTKinect one, and runs a two-point landmark-size study (``QUICK_LANDMARKS``, 86),
    fewer rollouts and sweep points, and leaves the full objective out of the UTKinect block
    (the full run leaves it out of the whole-body blocks only); its numbers are not the
    report's (``report.json`` and the report's first line say ``quick``). ``progress`` shows
    progress bars on a terminal (stage lines always go to stderr). ``devices`` (several JAX
    devices, or ``None`` for the default one) shard the held-out evaluation's projections and
    the rollout (then MJX; ``engine.resolve_devices``). ``overwrite`` (default ``True``)
    replaces the report files of an earlier run in ``out_dir``; ``False`` refuses a folder that
    holds any (``check_report_folder``, before any work; ``jaxproj demo`` without ``--force``).
    """
    check_report_folder(out_dir, overwrite)
    t_start = time.perf_counter()
    out_dir.mkdir(exist_ok=True)
    timings: dict[str, float] = {}
    cfg = engine.BuildConfig(landmarks=QUICK_LANDMARKS) if quick else engine.BuildConfig()
    train = _train_descriptors(cfg)[:: QUICK_TRAIN_STRIDE if quick else 1]
    models = {}
    for name, c in (("per_chain", cfg), ("whole_body", replace(cfg, chains="whole"))):
        t0 = time.perf_counter()
        models[name] = engine.build(train, c)
        timings[f"build_{name}_s"] = time.perf_counter() - t0
        _log(
            f"[1/5] built the {name} model: {models[name].landmarks} landmarks from "
            f"{len(train)} frames in {timings[f'build_{name}_s']:.1f} s"
        )
    model = models["per_chain"]
    engine.save(model, out_dir / "projector.npz")
    engine.save(models["whole_body"], out_dir / "projector_whole_body.npz")

    t0 = time.perf_counter()
    test_seqs = datasets.msr_action3d(subjects=TEST_SUBJECTS, actions=TEST_ACTIONS)
    test_seqs = test_seqs[:: QUICK_TEST_STRIDE if quick else 1]
    data = evaluate.prepare(test_seqs)
    ev = evaluate.evaluate(model, data, evaluate.METHODS, progress=progress, devices=devices)
    splits = {
        "msr_held_out": data,
        "utkinect": evaluate.prepare(utkinect_split(cfg, quick)),
    }
    comparison: dict = {}
    comparison_s: dict[str, float] = {}
    for name, m in models.items():
        # the full objective (its converged Newton solver, the evaluation's slowest method) runs
        # on the headline's model only, not on the whole-body one (its relaxed rows compare the
        # two formulations); quick: on the held-out MSR block only
        skip_full = quick or name == "whole_body"
        methods = [x for x in evaluate.METHODS if not (skip_full and x == "full")]
        for split, d in splits.items():
            t1 = time.perf_counter()
            if name == "per_chain" and split == "msr_held_out":
                block = ev["unsmoothed"]
            else:
                block = evaluate.evaluate(m, d, methods, smoothing=None, feasibility=None)[
                    "unsmoothed"
                ]
                comparison_s[f"{name}/{split}"] = time.perf_counter() - t1
            comparison.setdefault(name, {})[split] = block
    timings["evaluate_s"] = time.perf_counter() - t0
    _log(
        f"[2/5] evaluated {len(evaluate.METHODS)} methods x {len(models)} models on "
        f"{ev['valid_frames']} held-out MSR and {int(splits['utkinect'].valid.sum())} UTKinect "
        f"frames in {timings['evaluate_s']:.1f} s"
    )

    rollout_out = _rollout_section(data, ev, 8 if quick else 32, model.robot, devices)
    timings["rollout_s"] = rollout_out["wall_s"]
    _log(
        f"[3/5] {rollout_out['backend']} rollout of {len(rollout_out['motions'])} motions "
        f"in {timings['rollout_s']:.1f} s"
    )

    from jaxproj.paper import experiments

    t0 = time.perf_counter()
    key = jax.random.PRNGKey(0)
    poses = experiments.run_pose_experiments(model, key=key)
    held_out = data.descriptors[data.valid]  # the frames evaluate scored: the same numbers
    sizes = experiments.landmark_size_study(
        train,
        # quick: the model of step 1 is the QUICK_LANDMARKS row; full: the default model's row
        sizes=(QUICK_LANDMARKS, 86) if quick else (None, *SIZES),
        key=key,
        eval_descriptors=held_out,
        config=engine.BuildConfig(),
        built={cfg: (model, timings["build_per_chain_s"])},  # the per-chain model of step 1
    )
    eff = experiments.efficiency_study(
        model, held_out, ls=(5, 10) if quick else (10, 20, 30, 50), batch=1024
    )
    timings["experiments_s"] = time.perf_counter() - t0
    _log(f"[4/5] paper experiments in {timings['experiments_s']:.1f} s")

    t0 = time.perf_counter()
    result = {
        **{k: v for k, v in ev.items()},
        "comparison": comparison,
        "comparison_frames": {k: int(d.valid.sum()) for k, d in splits.items()},
        "comparison_wall_s": comparison_s,
        "rollout": rollout_out,
        "experiments": {"basic_poses": poses, "landmark_size": sizes, "efficiency": eff},
        "build": {
            "landmarks": model.landmarks,
            "bandwidth": dict(zip(model.landmarks, model.bandwidth, strict=True)),
            "train_frames": len(train),
            "config": vars(model.config).copy(),
            "default_model": not quick,
        },
        "quick": quick,
        "train_subjects": list(TRAIN_SUBJECTS),
        "train_utkinect_people": list(cfg.utkinect_people),
        "test_utkinect_people": sorted({int(x) for x in splits["utkinect"].subjects}),
        "test_subjects": list(TEST_SUBJECTS),
        "test_actions": list(TEST_ACTIONS),
    }
    plots = _plots(out_dir, data, ev, test_seqs, sizes, eff, result, model.robot)
    result["plots"] = plots
    timings["report_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    result["timings"] = timings
    report.write_json(out_dir / "report.json", result)
    report.write_text(out_dir / "report.md", demo_report.markdown(result))
    _log(f"[5/5] report written to {out_dir} ({timings['total_s']:.0f} s in all)")
    return result


def _plots(
    out_dir: Path, data, ev, seqs, sizes: dict, eff: dict, result: dict, robot: Robot
) -> list[str]:
    names = []
    preds = ev["_predictions"]
    truth = ev["_truth"]
    valid = data.valid
    split = demo_report.msr_split(result)
    report.plot_distributions(
        out_dir / "error_distributions.png",
        {m: p[valid] for m, p in preds.items()},
        truth[valid],
        title=f"Error distributions, smoothed output: {split}",
    )
    names.append("error_distributions.png")
    by_name = {s.name: s for s in seqs}
    for name in _sample_motions(data):
        s = data.names.index(name)
        a, b = data.offsets[s], data.offsets[s + 1]
        sel = {m: preds[m][a:b] for m in ("relaxed", "full", "nearest_landmark")}
        fname = f"motion_{name}.png"
        report.plot_motion(
            out_dir / fname,
            f"{name}: {datasets.ACTION_NAMES[data.actions[s] - 1]}",
            by_name[name].positions,
            valid[a:b],
            truth[a:b],
            sel,
            robot=robot,
        )
        names.append(fname)
    report.plot_per_joint(out_dir / "per_joint_error.png", ev["summary"])
    names.append("per_joint_error.png")
    report.plot_landmark_size(
        out_dir / "landmark_size.png",
        sizes,
        title=f"Landmark-set size (relaxed, unsmoothed): {split}",
    )
    names.append("landmark_size.png")
    report.plot_efficiency(out_dir / "efficiency.png", eff)
    names.append("efficiency.png")
    return names


def _sample_motions(data) -> list[str]:
    wanted = (1, 5, 11)  # high arm wave, forward punch, two hand wave
    out = []
    for a in wanted:
        for i, name in enumerate(data.names):
            n_valid = data.valid[data.offsets[i] : data.offsets[i + 1]].sum()
            if data.actions[i] == a and n_valid >= 20:
                out.append(name)
                break
    return out


REPORT_FILES = (
    "projector.npz",
    "projector_whole_body.npz",
    "report.json",
    "report.md",
    "error_distributions.png",
    "per_joint_error.png",
    "landmark_size.png",
    "efficiency.png",
)
"""The files ``run_demo`` writes into its folder, besides ``motion_<recording>.png``."""


def check_report_folder(out_dir: Path, overwrite: bool) -> None:
    """``ConfigError`` (before any work) unless ``run_demo`` may write into ``out_dir``: it
    must be a folder or absent (its parent folder must exist: only the report folder itself is
    created), and, unless ``overwrite``, hold none of the files a run writes (``REPORT_FILES``,
    ``motion_*.png``)."""
    from jaxproj.errors import ConfigError

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError(
            f"{out_dir}: is a file, not a report folder: name a folder (created if missing)"
        )
    if not out_dir.parent.is_dir():
        raise ConfigError(
            f"{out_dir}: folder {out_dir.parent} does not exist (the report folder is created, "
            "its parent is not: create it first)"
        )
    if overwrite or not out_dir.is_dir():
        return
    found = sorted(
        f.name
        for f in out_dir.iterdir()
        if f.name in REPORT_FILES or (f.name.startswith("motion_") and f.suffix == ".png")
    )
    if found:
        shown = ", ".join(found[:3]) + (f" and {len(found) - 3} more" if len(found) > 3 else "")
        raise ConfigError(
            f"{out_dir}: holds the report of an earlier run ({shown}); pass --force (CLI) / "
            "overwrite=True (Python) to replace it, or name another folder"
        )
