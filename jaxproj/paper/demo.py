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

Size: over 500 lines: the demo is one job whose stages, their progress lines and estimates
(``_Plan``), the output checks and the report are read in order; its pieces live in
``paper.experiments`` and ``paper.demo_report``, this module only sequences them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import jax
import numpy as np

from jaxproj._internal.progress import Heartbeat, Rates, duration
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

SPLIT_WORDS = {"msr_held_out": "held-out MSR", "utkinect": "UTKinect"}

SIZES = (1644, 961, 86)
"""The landmark-size study's targets per arm (the paper's), besides the default model."""


STAGES = 5
"""The demo's stages (module docstring); each prints ``[k/5]`` lines."""


@dataclass
class _Plan:
    """The demo's work counts, and the seconds they should take at the rates measured so far
    in this run (``Rates``): what the progress lines' estimates come from.

    Kinds of work: ``"build"`` (one model build, measured in stage 1), ``"frame:<method>"``
    (one held-out frame through ``evaluate``'s method, measured in stage 2's first block),
    ``"trajectory"`` (one batch of rollout motions, measured in stage 3), ``"report"`` (the
    plots and files, measured in stage 5). A stage whose kinds are unmeasured has no estimate.
    """

    rates: Rates
    quick: bool
    methods: tuple[str, ...]
    msr_frames: int = 0
    utk_frames: int = 0
    comparison: tuple[tuple[str, str, tuple[str, ...], int], ...] = ()
    new_sizes: int = 0
    pose_frames: int = 0
    ls: tuple[int, ...] = ()

    def frames(self, n: int, methods: tuple[str, ...]) -> float | None:
        """Seconds for ``n`` frames through each of ``methods`` (evaluate's rates)."""
        return self.rates.estimate(*((f"frame:{m}", n) for m in methods))

    def block(self, i: int) -> float | None:
        """Seconds of stage 2's comparison block ``i`` (``comparison``'s order)."""
        _, _, methods, n = self.comparison[i]
        return self.frames(n, methods)

    def poses(self) -> float | None:
        """Seconds of the basic poses and motions (relaxed and full objectives)."""
        return self.frames(self.pose_frames, ("relaxed", "full"))

    def size_frames(self) -> float | None:
        """Seconds of one landmark-set size's projections: POSE_8's motion, held-out frames."""
        return self.frames(self.msr_frames + self.pose_frames // 8, ("relaxed",))

    def size(self) -> float | None:
        """Seconds of one landmark-set size that builds its model."""
        return _sum([self.size_frames(), self.rates.estimate(("build", 1))])

    def efficiency(self) -> float | None:
        """Seconds of the L = M sweep: each L projects the held-out frames (and times a few
        batches) at a cost that grows with the L x M kernels of a query."""
        work = sum((n / 10) ** 2 for n in self.ls) * 2 * self.msr_frames
        return self.frames(int(work), ("relaxed",))

    def stage(self, k: int) -> float | None:
        """Seconds of stage ``k`` (1..5) from the rates measured so far."""
        if k == 1:
            return self.rates.estimate(("build", 2))
        if k == 2:
            first = self.frames(self.msr_frames, self.methods)
            return _sum([first, *(self.block(i) for i in range(len(self.comparison)))])
        if k == 3:
            return self.rates.estimate(("trajectory", len(ROLLOUT_TRAJECTORIES)))
        if k == 4:
            size = self.size()
            new = None if size is None else self.new_sizes * size
            return _sum([self.poses(), self.size_frames(), new, self.efficiency()])
        return self.rates.estimate(("report", 1))

    def later(self, k: int) -> tuple[float, bool]:
        """Seconds of the stages after ``k``, and whether some of them are not estimated yet
        (the sum then leaves them out)."""
        parts = [self.stage(j) for j in range(k + 1, STAGES + 1)]
        return sum(x for x in parts if x is not None), any(x is None for x in parts)


def _step(
    beat: Heartbeat,
    plan: _Plan,
    stage: int,
    step: tuple[int, int],
    what: str,
    expected: float | None,
    stage_rest: float | None,
) -> None:
    """Announce a step of ``stage`` (``step`` = (k, of n)) with its estimates."""
    later, partial = plan.later(stage)
    beat.step(
        f"[{stage}/{STAGES}] {step[0]}/{step[1]}",
        what,
        expected_s=expected,
        stage_rest_s=stage_rest,
        later_s=later,
        later_partial=partial,
    )


def _sum(xs: list[float | None]) -> float | None:
    """The sum of estimates; ``None`` if one of them is."""
    total = 0.0
    for x in xs:
        if x is None:
            return None
        total += x
    return total


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
    data: evaluate.EvalData,
    ev: dict,
    n_motions: int,
    spec: Robot,
    devices=None,
    *,
    beat: Heartbeat,
    plan: _Plan,
) -> dict:
    n_steps = 1 + len(ROLLOUT_TRAJECTORIES)
    _step(beat, plan, 3, (1, n_steps), "preparing the rollout's targets", None,
          plan.stage(3))  # fmt: skip
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
    for i, name in enumerate(ROLLOUT_TRAJECTORIES):
        left = len(ROLLOUT_TRAJECTORIES) - i - 1
        one, rest = (
            plan.rates.estimate(("trajectory", 1)),
            plan.rates.estimate(("trajectory", left)),
        )
        what = f"simulating {len(picks)} motions, trajectory {name!r}"
        _step(beat, plan, 3, (i + 2, n_steps), what, one, rest)
        t1 = time.perf_counter()
        b = batches[name]
        res = rollout.simulate(b, lengths[picks], devices=devices, robot=spec)
        plan.rates.add("trajectory", time.perf_counter() - t1)
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
    the rollout (then MJX; ``engine.resolve_devices``). ``overwrite=False`` refuses a folder
    holding an earlier run's report (``demo_report.check_report_folder``, first); default: replace.
    """
    demo_report.check_report_folder(out_dir, overwrite)
    t_start = time.perf_counter()
    out_dir.mkdir(exist_ok=True)
    with Heartbeat() as beat:
        return _run(out_dir, quick, progress, devices, beat, t_start)


def _run(
    out_dir: Path,
    quick: bool,
    progress: bool,
    devices: list[jax.Device] | None,
    beat: Heartbeat,
    t_start: float,
) -> dict:
    """``run_demo``'s stages, each step announced on ``beat`` with its estimates."""
    rates = Rates()
    plan = _Plan(rates, quick, tuple(evaluate.METHODS))
    timings: dict[str, float] = {}
    cfg = engine.BuildConfig(landmarks=QUICK_LANDMARKS) if quick else engine.BuildConfig()
    _step(beat, plan, 1, (1, 3), "reading the training recordings", None, None)
    train = _train_descriptors(cfg)[:: QUICK_TRAIN_STRIDE if quick else 1]
    models = {}
    builds = (("per_chain", cfg), ("whole_body", replace(cfg, chains="whole")))
    for i, (name, c) in enumerate(builds):
        expected = rates.estimate(("build", 1))
        _step(beat, plan, 1, (i + 2, 3), f"building the {name} model from {len(train):,} frames",
              expected, rates.estimate(("build", len(builds) - i - 1)))  # fmt: skip
        t0 = time.perf_counter()
        models[name] = engine.build(train, c)
        timings[f"build_{name}_s"] = time.perf_counter() - t0
        rates.add("build", timings[f"build_{name}_s"])
        beat.say(
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
    splits = {
        "msr_held_out": data,
        "utkinect": evaluate.prepare(utkinect_split(cfg, quick)),
    }
    # the full objective (its converged Newton solver, the evaluation's slowest method) runs
    # on the headline's model only, not on the whole-body one (its relaxed rows compare the
    # two formulations); quick: on the held-out MSR block only
    blocks = []
    for name in models:
        skip_full = quick or name == "whole_body"
        methods = tuple(x for x in evaluate.METHODS if not (skip_full and x == "full"))
        for split, d in splits.items():
            if not (name == "per_chain" and split == "msr_held_out"):
                blocks.append((name, split, methods, int(d.valid.sum())))
    plan.msr_frames, plan.comparison = int(data.valid.sum()), tuple(blocks)
    plan.utk_frames = int(splits["utkinect"].valid.sum())
    rest = _sum([plan.block(i) for i in range(len(blocks))])
    _step(beat, plan, 2, (1, len(blocks) + 1),
          f"evaluating {len(evaluate.METHODS)} methods on {plan.msr_frames:,} held-out MSR frames",
          None, rest)  # fmt: skip
    ev = evaluate.evaluate(model, data, evaluate.METHODS, progress=progress, devices=devices)
    for m in evaluate.METHODS:
        rates.add(f"frame:{m}", ev["wall_s"][m], plan.msr_frames)
    comparison: dict = {"per_chain": {"msr_held_out": ev["unsmoothed"]}}
    comparison_s: dict[str, float] = {}
    for i, (name, split, methods, n) in enumerate(blocks):
        rest = _sum([plan.block(j) for j in range(i + 1, len(blocks))])
        _step(beat, plan, 2, (i + 2, len(blocks) + 1),
              f"evaluating the {name} model on {n:,} {SPLIT_WORDS[split]} frames",
              plan.block(i), rest)  # fmt: skip
        t1 = time.perf_counter()
        comparison.setdefault(name, {})[split] = evaluate.evaluate(
            models[name], splits[split], list(methods), smoothing=None, feasibility=None
        )["unsmoothed"]
        comparison_s[f"{name}/{split}"] = time.perf_counter() - t1
    comparison = {name: {split: comparison[name][split] for split in splits} for name in models}
    timings["evaluate_s"] = time.perf_counter() - t0
    beat.say(
        f"[2/5] evaluated {len(evaluate.METHODS)} methods x {len(models)} models on "
        f"{ev['valid_frames']} held-out MSR and {plan.utk_frames} UTKinect "
        f"frames in {timings['evaluate_s']:.1f} s"
    )

    rollout_out = _rollout_section(
        data, ev, 8 if quick else 32, model.robot, devices, beat=beat, plan=plan
    )
    timings["rollout_s"] = rollout_out["wall_s"]
    beat.say(
        f"[3/5] {rollout_out['backend']} rollout of {len(rollout_out['motions'])} motions "
        f"in {timings['rollout_s']:.1f} s"
    )

    from jaxproj.paper import experiments
    from jaxproj.paper.synthetic import DEFAULT_FPS, POSE_NAMES

    t0 = time.perf_counter()
    key = jax.random.PRNGKey(0)
    held_out = data.descriptors[data.valid]  # the frames evaluate scored: the same numbers
    # quick: the model of step 1 is the QUICK_LANDMARKS row; full: the default model's row
    sizes_run: tuple[int | None, ...] = (QUICK_LANDMARKS, 86) if quick else (None, *SIZES)
    ls = (5, 10) if quick else (10, 20, 30, 50)
    built = {cfg: (model, timings["build_per_chain_s"])}  # the per-chain model of step 1
    plan.pose_frames = len(POSE_NAMES) * (1 + int(round(2.0 * DEFAULT_FPS)))
    plan.new_sizes, plan.ls = len(sizes_run) - 1, ls
    n_steps = 2 + len(sizes_run)

    def size_rest(k: int) -> float | None:
        """The sizes after the ``k``-th (0-based): each builds its model."""
        one = plan.size()
        return None if one is None else (plan.new_sizes - k) * one

    rest = _sum([plan.size_frames(), size_rest(0), plan.efficiency()])
    _step(beat, plan, 4, (1, n_steps), "projecting the basic poses and motions", plan.poses(),
          rest)  # fmt: skip
    poses = experiments.run_pose_experiments(model, key=key)
    rows = []
    for i, size in enumerate(sizes_run):
        reused = i == 0
        what = "the step-1 model" if size is None or reused else f"{size} landmarks per arm"
        rest = _sum([size_rest(i), plan.efficiency()])
        _step(beat, plan, 4, (i + 2, n_steps), f"landmark-set size: {what}",
              plan.size_frames() if reused else plan.size(), rest)  # fmt: skip
        t1 = time.perf_counter()
        one = experiments.landmark_size_study(
            train,
            sizes=(size,),
            key=key,
            eval_descriptors=held_out,
            config=engine.BuildConfig(),
            built=built,
        )
        rows += one["sizes"]
        if not reused:
            rates.add("build", one["sizes"][0]["build_s"])
            rates.add("frame:relaxed", time.perf_counter() - t1 - one["sizes"][0]["build_s"],
                      plan.msr_frames + plan.pose_frames // 8)  # fmt: skip
    sizes = {**one, "sizes": rows}
    _step(beat, plan, 4, (n_steps, n_steps), f"L = M sweep {', '.join(map(str, ls))}",
          plan.efficiency(), 0.0)  # fmt: skip
    eff = experiments.efficiency_study(model, held_out, ls=ls, batch=1024)
    timings["experiments_s"] = time.perf_counter() - t0
    beat.say(f"[4/5] paper experiments in {timings['experiments_s']:.1f} s")

    _step(beat, plan, 5, (1, 1), "writing the report and its plots", None, 0.0)
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
    plan.rates.add("report", time.perf_counter() - t0)
    report.write_json(out_dir / "report.json", result)
    report.write_text(out_dir / "report.md", demo_report.markdown(result))
    stage_s = ", ".join(
        f"{k.removesuffix('_s')} {duration(v)}" for k, v in timings.items() if k != "total_s"
    )
    beat.say(f"[5/5] report written to {out_dir} ({timings['total_s']:.0f} s in all: {stage_s})")
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
