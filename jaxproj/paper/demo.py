"""The main job, end to end on the bundled data: ``jaxproj demo``.

1. build the per-chain (default) and the whole-body projector from subjects 1,3,5,7,9 (1,644
   landmarks per arm chain / for the whole body);
2. evaluate every method on subjects 2,4,6,8,10 with and without smoothing, and both models
   side by side on them and on the UTKinect-Action3D upper-body segments (cross-dataset);
3. roll out held-out arm motions in MuJoCo (MJX on accelerators, CPU MuJoCo on a CPU-only
   machine: ``rollout.simulate``'s default backend): the robot-feasible relaxed projection (what
   ``jaxproj retarget`` writes for a robot, ``jaxproj.motion.feasible``) beside the raw relaxed
   projection and the IK;
4. the paper's experiments: eight basic poses and motions, landmark-set sizes, L = M sweep;
5. write ``report.json``, ``report.md`` and the PNG plots to ``--out``.
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
from jaxproj.projection import api as engine
from jaxproj.robots.nao_h25 import robot
from jaxproj.robots.nao_h25.ik import driven_to_full
from jaxproj.viz import report, report_text

TRAIN_SUBJECTS = datasets.TRAIN_SUBJECTS
TEST_SUBJECTS = datasets.TEST_SUBJECTS

QUICK_TRAIN_STRIDE = 8
"""``run_demo(quick=True)``: every 8th training frame feeds the builds."""
QUICK_TEST_STRIDE = 32
"""``run_demo(quick=True)``: every 32nd held-out MSR recording (and every 2nd UTKinect one) is
evaluated (a smoke run: the tests run it, within CI's 15-minute budget)."""
QUICK_LANDMARKS = 200
"""``run_demo(quick=True)``: landmarks per arm chain and for the whole body."""


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _train_descriptors(model_cfg: engine.BuildConfig) -> np.ndarray:
    seqs = datasets.msr_action3d(subjects=TRAIN_SUBJECTS)
    return datasets.valid_descriptors(seqs, bones=model_cfg.bones, mirror=model_cfg.mirror)


def _rollout_section(data: evaluate.EvalData, ev: dict, n_motions: int, seqs, devices=None) -> dict:
    from jaxproj.eval import rollout

    t0 = time.perf_counter()
    lengths = np.diff(data.offsets)
    arm = np.flatnonzero(np.isin(data.actions, datasets.ARM_ACTIONS))
    picks = arm[np.linspace(0, len(arm) - 1, n_motions).round().astype(int)]
    t_max = int(lengths[picks].max())
    out: dict = {
        "motions": [data.names[i] for i in picks],
        "frame_dt": 1.0 / 15.0,
        "backend": rollout.resolve_backend("auto", devices),
    }
    traj = {"ik": ev["_truth"], "relaxed": ev["_predictions"]["relaxed"]}
    batches = {}
    for name, per_frame in traj.items():
        b = np.tile(robot.STANDING_POSTURE, (len(picks), t_max, 1)).astype(np.float32)
        for row, s in enumerate(picks):
            a, e = data.offsets[s], data.offsets[s + 1]
            b[row, : e - a] = np.asarray(driven_to_full(per_frame[a:e]))
            b[row, e - a :] = b[row, e - a - 1]
        batches[name] = b
    times = np.tile(np.arange(t_max) * out["frame_dt"], (len(picks), 1))
    batches["relaxed_feasible"] = feasible.make_feasible(batches["relaxed"], times, lengths[picks])
    for name, b in batches.items():
        res = rollout.simulate(b, lengths[picks], devices=devices)
        out[name] = rollout.summarize(res, lengths[picks], b)
    out["wall_s"] = time.perf_counter() - t0  # the whole section, as the demo's timings say
    return out


def run_demo(
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    devices: list[jax.Device] | None = None,
) -> dict:
    """Run the whole demo and write the report; returns the report dict.

    ``quick`` (the tests' setting, a smoke run of every stage in a few minutes on 2 cores)
    builds from every ``QUICK_TRAIN_STRIDE``-th training frame with ``QUICK_LANDMARKS``
    landmarks per arm chain (and for the whole body) instead of the paper's 1644, evaluates
    every ``QUICK_TEST_STRIDE``-th held-out MSR recording and every 2nd UTKinect one, and runs a
    two-point landmark-size study (``QUICK_LANDMARKS``, 86), fewer rollouts and sweep points,
    and leaves the full objective out of the whole-body / UTKinect comparison;
    its numbers are not the report's (``report.json`` says ``quick``). ``progress`` shows
    progress bars on a terminal (stage lines always go to
    stderr). ``devices`` (several JAX devices, or ``None`` for the default one) shard the
    held-out evaluation's projections and the rollout (then MJX; ``engine.resolve_devices``).
    """
    t_start = time.perf_counter()
    out_dir.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    cfg = engine.BuildConfig(landmarks=QUICK_LANDMARKS if quick else 1644)  # per chain
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
    test_seqs = datasets.msr_action3d(subjects=TEST_SUBJECTS)[:: QUICK_TEST_STRIDE if quick else 1]
    data = evaluate.prepare(test_seqs)
    ev = evaluate.evaluate(model, data, evaluate.METHODS, progress=progress, devices=devices)
    splits = {
        "msr_held_out": data,
        "utkinect": evaluate.prepare(
            datasets.utkinect_action3d(actions=datasets.UTK_UPPER_BODY_ACTIONS)[
                :: 2 if quick else 1
            ]
        ),
    }
    comparison: dict = {}
    # quick: the comparison's other three blocks without the full objective (its CPU time
    # dominated the quick run; the per-chain held-out MSR block has it)
    others = [m for m in evaluate.METHODS if not (quick and m == "full")]
    for name, m in models.items():
        for split, d in splits.items():
            if name == "per_chain" and split == "msr_held_out":
                block = ev["unsmoothed"]
            else:
                block = evaluate.evaluate(m, d, others, smoothing=None, feasibility=None)[
                    "unsmoothed"
                ]
            comparison.setdefault(name, {})[split] = block
    timings["evaluate_s"] = time.perf_counter() - t0
    _log(
        f"[2/5] evaluated {len(evaluate.METHODS)} methods x {len(models)} models on "
        f"{ev['valid_frames']} held-out MSR and {int(splits['utkinect'].valid.sum())} UTKinect "
        f"frames in {timings['evaluate_s']:.1f} s"
    )

    rollout_out = _rollout_section(data, ev, 8 if quick else 32, test_seqs, devices)
    timings["rollout_s"] = rollout_out["wall_s"]
    _log(
        f"[3/5] {rollout_out['backend']} rollout of {len(rollout_out['motions'])} motions "
        f"in {timings['rollout_s']:.1f} s"
    )

    from jaxproj.paper import experiments

    t0 = time.perf_counter()
    key = jax.random.PRNGKey(0)
    poses = experiments.run_pose_experiments(model, key=key)
    held_out = data.descriptors[
        data.valid & np.isin(np.repeat(data.actions, np.diff(data.offsets)), datasets.ARM_ACTIONS)
    ]
    sizes = experiments.landmark_size_study(
        train,
        sizes=(QUICK_LANDMARKS, 86) if quick else (1644, 961, 86),
        key=key,
        eval_descriptors=held_out,
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
        "rollout": rollout_out,
        "experiments": {"basic_poses": poses, "landmark_size": sizes, "efficiency": eff},
        "build": {
            "landmarks": model.landmarks,
            "bandwidth": dict(zip(model.landmarks, model.bandwidth, strict=True)),
            "train_frames": len(train),
            "config": vars(model.config).copy(),
        },
        "quick": quick,
        "train_subjects": list(TRAIN_SUBJECTS),
        "test_subjects": list(TEST_SUBJECTS),
    }
    plots = _plots(out_dir, data, ev, test_seqs, sizes, eff)
    result["plots"] = plots
    timings["report_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    result["timings"] = timings
    report.write_json(out_dir / "report.json", result)
    report.write_text(out_dir / "report.md", _markdown(result))
    _log(f"[5/5] report written to {out_dir} ({timings['total_s']:.0f} s in all)")
    return result


def _plots(out_dir: Path, data, ev, seqs, sizes: dict, eff: dict) -> list[str]:
    names = []
    preds = ev["_predictions"]
    truth = ev["_truth"]
    valid = data.valid
    report.plot_distributions(
        out_dir / "error_distributions.png",
        {m: p[valid] for m, p in preds.items()},
        truth[valid],
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
        )
        names.append(fname)
    report.plot_per_joint(out_dir / "per_joint_error.png", ev["summary"])
    names.append("per_joint_error.png")
    report.plot_landmark_size(out_dir / "landmark_size.png", sizes)
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


def _comparison_md(r: dict) -> list[str]:
    """Whole-body vs per-chain, per objective and baseline, on both held-out splits."""
    lines = [
        "",
        "## Whole-body vs per-chain projection (unsmoothed)",
        "",
        "The same five methods with the paper's whole-body projector (one set of landmarks over "
        "all 15 descriptor numbers) and with the per-chain projector built here (head, left arm, "
        f"right arm: {r['build']['landmarks']} landmarks, each chain searched and trained in its "
        "own bones; baselines per chain too). "
        "Held-out MSR Action3D subjects (all actions) and the UTKinect-Action3D upper-body "
        "segments (other people, another room: cross-dataset). Landmarks from MSR subjects "
        f"{r['train_subjects']}.",
        "",
        "| model | split | method | median M_avg | p95 M_max | p95 M_max w/o ElbowYaw "
        "| hand cm median / p95 (L, R) |",
        "|---|---|---|---:|---:|---:|---|",
    ]
    for model, splits in r["comparison"].items():
        for split, methods in splits.items():
            for name, s in methods.items():
                hand = " , ".join(
                    f"{s['task_space'][side]['hand_cm']['median']:.1f} / "
                    f"{s['task_space'][side]['hand_cm']['p95']:.1f}"
                    for side in ("left", "right")
                )
                lines.append(
                    f"| {model} | {split} | {name} | {s['M_avg']['median']:.2f} | "
                    f"{s['M_max']['p95']:.1f} | {s['M_max_no_elbow_yaw']['p95']:.1f} | {hand} |"
                )
    return lines


def _where_md(r: dict) -> list[str]:
    """The "Where the error is" section, from the smoothed per-method blocks."""
    s = r["summary"]
    return [
        "",
        "## Where the error is (smoothed)",
        "",
        "p95 of M_max with and without the two ElbowYaw joints (ill-conditioned in the IK truth "
        "itself when the arm is nearly straight), and task-space errors of the projected pose "
        "against the IK pose from forward kinematics of the MJCF: hand (the wrist point, where "
        "the hand attaches) and elbow position (cm) and upper-arm (shoulder -> elbow) and "
        "forearm (elbow -> wrist) direction (deg), median / p95 over the valid frames.",
        "",
        report.where_error_table(s),
        "",
        "Error per driven joint, p50 / p95 (deg):",
        "",
        report.per_joint_table(s),
    ]


def _rollout_md(ro: dict) -> list[str]:
    lines = ["", "## MuJoCo rollout (torso fixed, position actuators, gravity on)", ""]
    lines.append(
        f"{len(ro['motions'])} held-out arm motions tracked in MuJoCo "
        f"(backend `{ro['backend']}`, {ro['wall_s']:.1f} s): the IK trajectories, the relaxed "
        "projections and the relaxed projections made robot-feasible (`relaxed_feasible`, what "
        "`jaxproj retarget` writes for a robot). Tracking is against each trajectory's own "
        "targets; the peak speed is the simulated robot's."
    )
    lines += [
        "",
        "| trajectory | tracking mean (deg) | tracking p95 | self-collision frames "
        "(arm-torso / arm-head / arm-arm / any) | motions with contact | joint-limit frames "
        "(achieved / target) | peak speed / NAO limit | motions over the speed limit |",
        "|---|---:|---:|---|---:|---|---:|---:|",
    ]
    for name in ("ik", "relaxed", "relaxed_feasible"):
        x = ro[name]
        t, c = x["tracking_error_deg"], x["self_collision_frames"]
        lim, sp = x["joint_limit_violations"], x["speed"]
        lines.append(
            f"| {name} | {t['mean']:.2f} | {t['p95']:.2f} | {c['arm_torso']} / {c['arm_head']} "
            f"/ {c['arm_arm']} / {c['any']} | {c['motions']} | {lim['achieved_frames']} / "
            f"{lim['target_frames']} | {sp['max_ratio']:.2f} ({sp['worst_joint']}) | "
            f"{sp['motions_over_limit']} |"
        )
    return lines


def _feasibility_md(r: dict) -> list[str]:
    """Before / after the feasibility filter, from the smoothed evaluation."""
    fz = {m: r["feasibility"][m] for m in ("ik", "relaxed", "full") if m in r["feasibility"]}
    cfg = next(iter(fz.values()))["config"]
    lines = [
        "",
        "## Robot-feasible output (held-out MSR subjects, smoothed, 15 fps)",
        "",
        f"`jaxproj.motion.feasible` (on by default in `jaxproj retarget`): joint limits, "
        f"{100 * cfg['speed_fraction']:.0f} % of the NAO's no-load speeds and "
        f"{cfg['accel']:.0f} rad/s^2, zero-phase. Speed figures against the full no-load limits; "
        "errors against the IK of each frame; the last columns compare the filtered motion with "
        "the unfiltered one.",
        "",
        "| trajectory | motions over speed limit (before -> after) | frames over | max step "
        "(deg) | max accel (rad/s^2) | median M_avg (deg) | p95 M_max w/o ElbowYaw | hand p95 "
        "cm (L, R) | change vs unfiltered: joint deg p95 / hand cm p95 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, b in fz.items():
        bef, aft, err = b["before"], b["after"], b["after_errors"]
        unf = r["summary"].get(name)
        m_avg = f"{err['M_avg']['median']:.2f}"
        no_ey = f"{err['M_max_no_elbow_yaw']['p95']:.1f}"

        def hand_p95(block: dict) -> str:
            return ", ".join(
                f"{block['task_space'][side]['hand_cm']['p95']:.1f}" for side in ("left", "right")
            )

        hand = hand_p95(err)
        if unf is not None:
            m_avg = f"{unf['M_avg']['median']:.2f} -> {m_avg}"
            no_ey = f"{unf['M_max_no_elbow_yaw']['p95']:.1f} -> {no_ey}"
            hand = f"{hand_p95(unf)} -> {hand}"
        vs = b["vs_unfiltered"]
        lines.append(
            f"| {name} | {bef['motions_over_speed_limit']} -> {aft['motions_over_speed_limit']} of "
            f"{bef['motions']} | {bef['speed_violation_frames']} -> {aft['speed_violation_frames']}"
            f" | {bef['max_step_deg']:.0f} -> {aft['max_step_deg']:.0f} | {bef['max_accel']:.0f} "
            f"-> {aft['max_accel']:.0f} | {m_avg} | {no_ey} | {hand} | "
            f"{vs['joint_deg']['p95']:.1f} / {vs['hand_cm']['p95']:.1f} |"
        )
    return lines


def _experiments_md(ex: dict) -> list[str]:
    bp = ex["basic_poses"]
    lines = ["", "## Paper experiments", "", "### Eight basic poses and rest -> pose motions", ""]
    lines.append(
        f"Skeletons synthesised from the median bone lengths; motions of "
        f"{bp['frames_per_motion']} frames at {bp['fps']:.0f} fps with Kinect-like noise "
        f"({1000 * bp['noise_std_m']:.1f} mm per coordinate, measured). Degrees."
    )
    lines += [
        "",
        "| pose | relaxed pose M_max / M_avg | full pose M_max / M_avg | relaxed motion max "
        "M_max / mean M_avg | full motion max M_max / mean M_avg | nearest landmark (deg) |",
        "|---|---|---|---|---|---:|",
    ]
    for pose in bp["poses"]:
        ps, ms = bp["poses"][pose], bp["motions"][pose]
        cells = [f"{ps[o]['M_max']:.1f} / {ps[o]['M_avg']:.1f}" for o in ("relaxed", "full")]
        cells += [
            f"{ms[o]['M_max_max']:.1f} / {ms[o]['M_avg_mean']:.1f}" for o in ("relaxed", "full")
        ]
        cov = bp["coverage_deg"][pose]["pose"]
        lines.append(f"| {pose} | " + " | ".join(cells) + f" | {cov:.1f} |")
    lines += report_text.pose_notes(bp) + ["", "### Landmark-set size (relaxed)", ""]
    lines += [
        "| target | landmarks reached (per chain) | bandwidth | held-out median M_avg "
        "| held-out p95 M_max "
        "| POSE_8 motion max M_max | POSE_8 motion mean M_avg |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in ex["landmark_size"]["sizes"]:
        lines.append(
            f"| {row['target']} | {row['landmarks']} "
            f"({' / '.join(str(v) for v in row['landmarks_per_chain'].values())}) | "
            f"{' / '.join(f'{h:.4f}' for h in row['bandwidth'])} | "
            f"{row['M_avg_median']:.2f} | {row['M_max_p95']:.1f} "
            f"| {row['pose8_M_max']:.1f} | {row['pose8_M_avg_mean']:.2f} |"
        )
    eff = ex["efficiency"]
    lines += ["", f"### Efficiency vs L = M ({eff['objective']}, {eff['device']})", ""]
    lines += ["| L = M | batch | us / projection | median M_avg | p95 M_max |"]
    lines += ["|---:|---:|---:|---:|---:|"]
    for row in eff["rows"]:
        lines.append(
            f"| {row['L']} | {row['batch']} | {row['us_per_projection']:.1f} | "
            f"{row['M_avg_median']:.2f} | {row['M_max_p95']:.1f} |"
        )
    return lines


def _markdown(r: dict) -> str:
    s = r["summary"]
    lines = [
        "# jaxproj demo report",
        "",
        *(
            [
                f"**Quick run** (`--quick`, a smoke test): every {QUICK_TRAIN_STRIDE}th training "
                f"frame, every {QUICK_TEST_STRIDE}th held-out MSR recording, every 2nd UTKinect "
                f"one, {QUICK_LANDMARKS} landmarks per arm chain; not the report's numbers.",
                "",
            ]
            if r.get("quick")
            else []
        ),
        f"Landmarks per chain: {r['build']['landmarks']} (mean shift, bandwidths "
        f"{r['build']['bandwidth']}) from {r['build']['train_frames']} valid frames of "
        f"subjects {r['train_subjects']}; "
        f"evaluated on {r['valid_frames']} valid frames ({r['sequences']} sequences) of subjects "
        f"{r['test_subjects']}. L = {r['L']}, M = {r['M']}. Errors in degrees over the driven "
        f"joints {', '.join(r['driven_joints'])}, against the analytic IK. Devices: "
        f"{', '.join(r['devices'])}.",
        "",
        "## Accuracy of the default output: smoothed "
        f"({report_text.smoother_label(r['smoothing'])})",
        "",
        "Each method's per-frame answers, invalid frames filled, smoothed and clipped to the "
        "joint limits, against the IK of every valid frame (the feasibility filter's effect "
        "is its own section below).",
        "",
        report.summary_table(s),
        "",
        "## Accuracy of the projection itself (unsmoothed)",
        "",
        report.summary_table(r["unsmoothed"]),
        "",
        "## Smoothness and lag against the IK",
        "",
        "Mean squared joint jerk ((rad/s^3)^2) and lag (frames of best cross-correlation with "
        "the IK's motion; positive: late), before and after the smoother.",
        "",
        "| method | jerk raw | jerk smoothed | lag raw | lag smoothed |",
        "|---|---:|---:|---:|---:|",
    ]
    nan = float("nan")
    for m, v in r["smoothness"].items():
        lines.append(
            f"| {m} | {v['jerk_raw']:.3g} | {v.get('jerk_smoothed', nan):.3g} | "
            f"{v.get('lag_frames_raw', nan):+.2f} | {v.get('lag_frames_smoothed', nan):+.2f} |"
        )
    lines += report_text.confidence_md(r.get("confidence") or {})
    lines += _comparison_md(r)
    lines += _where_md(r)
    lines += ["", "## Per action (relaxed, smoothed): median M_avg / p95 M_max", ""]
    lines += ["| action | M_avg median | M_max p95 |", "|---|---:|---:|"]
    for a, v in r["per_action"].items():
        x = v["relaxed"]
        lines.append(f"| {a} | {x['M_avg']['median']:.2f} | {x['M_max']['p95']:.1f} |")
    lines += _feasibility_md(r)
    lines += _rollout_md(r["rollout"]) + _experiments_md(r["experiments"])
    lines += ["", "## Plots", ""]
    lines += [f"![{p}]({p})" for p in r["plots"]]
    lines += ["", "Timings (this run, this machine; seconds):", "", "| stage | s |", "|---|---:|"]
    lines += [f"| {k.removesuffix('_s')} | {v:.1f} |" for k, v in r["timings"].items()]
    lines += [""]
    return "\n".join(lines)
