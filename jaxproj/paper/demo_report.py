"""The demo's ``report.md`` and its stdout summary (``jaxproj.paper.demo``): a headline by the
results page's protocol, the recommended method and why (from this run's numbers), then every
section's table, each under a line that says its split, its frame count and its metric.

Size: over 500 lines: one Markdown writer per section of the demo report, each with the line
that states its split, frame count and metric; nothing here computes.
"""

from __future__ import annotations

import os

from jaxproj.viz import report, report_text

QUICK_TRAIN_STRIDE = 8
"""``run_demo(quick=True)``: every 8th training frame feeds the builds."""
QUICK_TEST_STRIDE = 24
"""``run_demo(quick=True)``: every 24th held-out MSR arm recording (and every 2nd UTKinect one)
is evaluated (a smoke run: the tests run it, within CI's 15-minute budget)."""
QUICK_LANDMARKS = 200
"""``run_demo(quick=True)``: landmarks per arm chain and for the whole body."""

QUICK_NOTE = (
    "**Quick run** (`--quick`, a smoke test): every {train}th training frame, every {test}th "
    "held-out MSR arm recording, every 2nd UTKinect one, {k} landmarks per arm chain instead of "
    "the default model; not the report's numbers."
)

IK_METRIC = (
    "degrees against the analytic IK of each frame over the 10 driven joints (HeadYaw .. "
    "RElbowRoll); per frame M_avg (mean over the joints) and M_max (largest joint)"
)


def caption(split: str, frames: str, metric: str) -> str:
    """The line above every table: what it was measured on and in what."""
    return f"*Split:* {split}. *Frames:* {frames}. *Metric:* {metric}."


def _subjects(xs: list[int]) -> str:
    return ",".join(str(x) for x in xs)


def _actions(r: dict) -> str:
    """``a01-a12, a17-a19`` of the held-out actions."""
    acts = sorted(r.get("test_actions") or [])
    if not acts:
        return "all actions"
    runs: list[list[int]] = []
    for a in acts:
        if runs and a == runs[-1][-1] + 1:
            runs[-1].append(a)
        else:
            runs.append([a])
    return ", ".join(f"a{x[0]:02d}" if len(x) == 1 else f"a{x[0]:02d}-a{x[-1]:02d}" for x in runs)


def msr_split(r: dict) -> str:
    """The held-out MSR split in words, with its frame count."""
    return (
        f"held-out MSR Action3D subjects {_subjects(r['test_subjects'])}, arm actions "
        f"{_actions(r)} ({r['sequences']} recordings, {r['valid_frames']:,} valid frames)"
    )


def _utk_split(r: dict) -> str:
    """The UTKinect split in words: its people (none the model trained on) and frames."""
    n = r.get("comparison_frames", {}).get("utkinect")
    people = r.get("test_utkinect_people")
    who = f"people {_subjects(people)}, whom the model never saw" if people else "five other people"
    return f"UTKinect-Action3D upper-body segments ({who}, another room" + (
        f"; {n:,} valid frames)" if n is not None else ")"
    )


def _training_words(r: dict) -> str:
    """Where the training frames came from."""
    msr = f"MSR subjects {_subjects(r['train_subjects'])}"
    utk = r.get("train_utkinect_people")
    return f"{msr} and UTKinect-Action3D people {_subjects(utk)}" if utk else msr


def _model_words(r: dict) -> str:
    b = r["build"]
    counts = " / ".join(str(v) for v in b["landmarks"].values())
    which = "the default model (`BuildConfig()`)" if b.get("default_model") else "a small model"
    return (
        f"{which}, per chain: {counts} landmarks (head / left arm / right arm; mean-shift "
        f"bandwidths {report_text.bandwidths(b['bandwidth'])}) from {b['train_frames']:,} valid "
        f"frames (every action) of {_training_words(r)}"
    )


def _hand(s: dict) -> list[str]:
    return [
        f"{s['task_space'][side]['hand_cm']['median']:.1f} / "
        f"{s['task_space'][side]['hand_cm']['p95']:.1f}"
        for side in ("left", "right")
    ]


SPLIT_NAMES = {"msr_held_out": "MSR held out", "utkinect": "UTKinect"}


def headline_table(r: dict) -> list[str]:
    """The per-chain model's unsmoothed errors on both splits: the results page's table."""
    lines = [
        "| split | frames | method | median M_avg | p95 M_max | p95 M_max no ElbowYaw "
        "| hand cm L (median / p95) | hand cm R |",
        "|---|---:|---|---:|---:|---:|---|---|",
    ]
    frames = r.get("comparison_frames", {})
    for split, methods in r["comparison"]["per_chain"].items():
        for name, s in methods.items():
            hl, hr = _hand(s)
            lines.append(
                f"| {SPLIT_NAMES.get(split, split)} | {frames.get(split, s['M_avg']['n']):,} | "
                f"{name} | {s['M_avg']['median']:.2f} | {s['M_max']['p95']:.1f} | "
                f"{s['M_max_no_elbow_yaw']['p95']:.1f} | {hl} | {hr} |"
            )
    return lines


def _headline_md(r: dict) -> list[str]:
    lines = [
        "## Headline: accuracy on held-out people (the results page's protocol)",
        "",
        f'Model: {_model_words(r)}. The protocol of `docs/results.md` ("Accuracy on held-out '
        'people", per-chain table): unsmoothed, L = M = 10, every method on the same landmarks. '
        "Where this report differs from that table: its `full` row is `FullConfig()` (the "
        "converged Gauss-Newton solver) where the page's table used 30 Adam steps (`ADAM_30`), "
        "and it does not run the page's `full (min, with candidate)` row nor the whole-body "
        "table's full rows (the converged solver is the evaluation's slowest method)"
        + ("; and this is a quick run on a small model (first line)." if r.get("quick") else "."),
        "",
        caption(
            f"{msr_split(r)}; {_utk_split(r)}",
            "per row (valid frames)",
            f"{IK_METRIC}, median / p95 over the frames; hand: the wrist point's position error "
            "from forward kinematics of the MJCF, cm",
        ),
        "",
        *headline_table(r),
    ]
    return lines


def _num(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}"


def recommendation(r: dict) -> list[str]:
    """Which method this report recommends and why, from this run's measured numbers: the
    answer to "why the learned projector rather than the closed-form IK?"."""
    per = r["comparison"]["per_chain"]["msr_held_out"]
    utk = r["comparison"]["per_chain"].get("utkinect", {})
    ro = r["rollout"]
    rel, full = per["relaxed"], per.get("full")
    lines = ["", "## Which method, and why", ""]
    # the projector against the IK it was trained on: how close, on people it never saw
    hand = " / ".join(_num(rel["task_space"][s]["hand_cm"]["p95"], 1) for s in ("left", "right"))
    on_utk = f", {_num(utk['relaxed']['M_avg']['median'])} deg on UTKinect" if utk else ""
    close = (
        f"On people the landmarks never saw, the relaxed projection's angles are within "
        f"{_num(rel['M_avg']['median'])} deg of the IK's (median M_avg; p95 M_max "
        f"{_num(rel['M_max']['p95'], 1)}, {_num(rel['M_max_no_elbow_yaw']['p95'], 1)} without "
        f"the ElbowYaw joints; hand p95 {hand} cm)"
        + on_utk
        + ". The IK is the reference of every accuracy figure, so no accuracy figure can favour "
        "the projector over it: what the projector buys is measured on the robot side."
    )
    ik_r, ikf, rel_r, relf = ro["ik"], ro["ik_feasible"], ro["relaxed"], ro["relaxed_feasible"]

    def tr(x: dict) -> str:
        t = x["tracking_error_deg"]
        return f"{_num(t['mean'])} deg mean / {_num(t['p95'])} p95"

    def col(x: dict) -> int:
        return int(x["self_collision_frames"]["any"])

    n_mot, frames = len(ro["motions"]), ro.get("frames")
    frames_words = f", {frames:,} frames" if frames else ""
    robot_side = (
        f"In MuJoCo ({n_mot} held-out arm motions{frames_words}), what `jaxproj retarget "
        f"--method relaxed` writes (smoothed, made feasible) is tracked at {tr(relf)} with "
        f"{col(relf)} self-collision frames; what `--method ik` writes (the same smoother and "
        f"filter) at {tr(ikf)} with {col(ikf)}; the raw per-frame IK at {tr(ik_r)} with "
        f"{col(ik_r)}, the smoothed relaxed projection at {tr(rel_r)} with {col(rel_r)}. "
        "Against the per-frame IK, those written targets err "
        f"{_num(relf['targets_vs_ik_M_avg']['median'])} (relaxed) and "
        f"{_num(ikf['targets_vs_ik_M_avg']['median'])} (IK) deg median M_avg."
    )
    sm = r.get("smoothness", {})
    jerk = ""
    if "relaxed" in sm and "ik" in sm:
        jerk = (
            f" Unsmoothed, the relaxed projection's motion has a mean squared jerk of "
            f"{sm['relaxed']['jerk_raw']:.3g} (rad/s^3)^2 against the IK's "
            f"{sm['ik']['jerk_raw']:.3g}."
        )
    conf = r.get("confidence", {}).get("relaxed")
    conf_words = ""
    if conf:
        conf_words = (
            f" The projection also says which frames to distrust (the IK has no such measure): "
            f"its {100 * conf['low_share']:.0f} % low-confidence frames hold "
            f"{100 * conf['low_recall']:.0f} % of the frames with M_max > "
            f"{conf['over_deg']:.0f} deg."
        )
    verdict = _verdict(relf, ikf, ik_r)
    lines += [verdict, "", close, "", robot_side + jerk + conf_words]
    if full is not None:
        walls = r.get("wall_s", {})
        speed = ""
        if "relaxed_us_per_frame" in walls and "full_us_per_frame" in walls:
            speed = (
                f", at {walls['relaxed_us_per_frame']:.0f} against "
                f"{walls['full_us_per_frame']:.0f} us per frame in this run (compilation "
                "included)"
            )
        lines += [
            "",
            f"Relaxed rather than the full objective: median M_avg {_num(rel['M_avg']['median'])} "
            f"against {_num(full['M_avg']['median'])}, p95 M_max {_num(rel['M_max']['p95'], 1)} "
            f"against {_num(full['M_max']['p95'], 1)} on the same frames{speed}.",
        ]
    return lines


SEPARATES = 0.9
"""``_verdict``: one written motion is tracked better when its mean tracking error is below
this fraction of the other's (and it has no more self-collision frames)."""


def _verdict(relf: dict, ikf: dict, ik_raw: dict) -> str:
    """The recommendation, from the rollout of what ``retarget`` writes with each method
    (``relf``: ``--method relaxed``; ``ikf``: ``--method ik``; ``ik_raw``: the per-frame IK)."""
    t_rel, t_ik = relf["tracking_error_deg"]["mean"], ikf["tracking_error_deg"]["mean"]
    c_rel, c_ik = relf["self_collision_frames"]["any"], ikf["self_collision_frames"]["any"]
    nums = (
        f"(tracking {_num(t_rel)} against {_num(t_ik)} deg mean, {c_rel} against {c_ik} "
        "self-collision frames)"
    )
    if t_rel < SEPARATES * t_ik and c_rel <= c_ik:
        return (
            "**Recommended: `relaxed` on the default model** (`jaxproj retarget --method "
            "relaxed --model P.npz`, robot-feasible by default) for a robot: through the same "
            f"smoother and filter, the robot tracks its written motion better than the IK's {nums}."
        )
    if t_ik < SEPARATES * t_rel and c_ik <= c_rel:
        tie = f"the robot tracks the IK's written motion better than the projection's {nums}"
    else:
        tie = (
            "the robot tracks both written motions alike through the same smoother and filter "
            f"{nums}: the rollout does not favour the projector (what it gains over the raw "
            f"per-frame IK, tracked at {_num(ik_raw['tracking_error_deg']['mean'])} deg mean, "
            "is the smoother's and the filter's, which `--method ik` gets too)"
        )
    return (
        "**Recommended: `relaxed` on the default model where a per-frame confidence or the "
        "paper's projection is wanted; otherwise `--method ik` (the default, no model to "
        f"build)** for a robot: on this run {tie}, and the IK's written motion stays closer to "
        "the per-frame IK, which is what every accuracy figure measures."
    )


def stdout_summary(r: dict) -> str:
    """What ``jaxproj demo`` prints: the headline table with what it is, then the verdict."""
    quick = (
        " QUICK RUN (a smoke test on a small model; not the report's numbers)."
        if r.get("quick")
        else ""
    )
    head = (
        f"Headline (the results page's protocol){quick} Model: {_model_words(r)}. "
        f"Unsmoothed, L = M = 10; {IK_METRIC}, median / p95 over the valid frames of "
        f"{msr_split(r)} and {_utk_split(r)}."
    )
    verdict = recommendation(r)[3]
    return "\n".join([head, "", *headline_table(r), "", verdict])


def _summary_md(r: dict) -> list[str]:
    split = msr_split(r)
    return [
        "",
        "## Accuracy of the default output: smoothed "
        f"({report_text.smoother_label(r['smoothing'])})",
        "",
        "Each method's per-frame answers, invalid frames filled, smoothed and clipped to the "
        "joint limits, against the IK of every valid frame (the feasibility filter's effect "
        "is its own section below).",
        "",
        caption(split, f"{r['valid_frames']:,}", f"{IK_METRIC}; statistics over the frames"),
        "",
        report.summary_table(r["summary"]),
        "",
        "## Accuracy of the projection itself (unsmoothed)",
        "",
        "The headline's MSR rows, with more statistics.",
        "",
        caption(split, f"{r['valid_frames']:,}", f"{IK_METRIC}; statistics over the frames"),
        "",
        report.summary_table(r["unsmoothed"]),
        "",
        "## Smoothness and lag against the IK",
        "",
        caption(
            split,
            f"{r['valid_frames']:,} (in {r['sequences']} motions at 15 fps)",
            "mean squared joint jerk ((rad/s^3)^2) and lag (frames of best cross-correlation "
            "with the IK's motion; positive: late), before and after the smoother",
        ),
        "",
        "| method | jerk raw | jerk smoothed | lag raw | lag smoothed |",
        "|---|---:|---:|---:|---:|",
        *report_text.smoothness_md(r["smoothness"]),
    ]


def _comparison_md(r: dict) -> list[str]:
    """Whole-body vs per-chain, per objective and baseline, on both held-out splits."""
    frames = r.get("comparison_frames", {})
    lines = [
        "",
        "## Whole-body vs per-chain projection (unsmoothed)",
        "",
        "The same methods with the paper's whole-body projector (one set of landmarks over "
        "all 15 descriptor numbers) and with the per-chain projector of the headline (head, "
        "left arm, right arm, each chain searched and trained in its own bones; baselines per "
        "chain too). The whole-body rows leave the full objective out: its converged solver is "
        "the evaluation's slowest method; the results page has its whole-body rows."
        + (" Quick run: no full objective outside the first block." if r.get("quick") else ""),
        "",
        caption(
            f"{msr_split(r)}; {_utk_split(r)}",
            ", ".join(f"{SPLIT_NAMES[k]} {v:,}" for k, v in frames.items()),
            f"{IK_METRIC}, median / p95 over the frames; hand cm as in the headline",
        ),
        "",
        "| model | split | method | median M_avg | p95 M_max | p95 M_max w/o ElbowYaw "
        "| hand cm median / p95 (L, R) |",
        "|---|---|---|---:|---:|---:|---|",
    ]
    for model, splits in r["comparison"].items():
        for split, methods in splits.items():
            for name, s in methods.items():
                lines.append(
                    f"| {model} | {SPLIT_NAMES.get(split, split)} | {name} | "
                    f"{s['M_avg']['median']:.2f} | {s['M_max']['p95']:.1f} | "
                    f"{s['M_max_no_elbow_yaw']['p95']:.1f} | {' , '.join(_hand(s))} |"
                )
    return lines


def _where_md(r: dict) -> list[str]:
    """The "Where the error is" section, from the smoothed per-method blocks."""
    s = r["summary"]
    split, n = msr_split(r), f"{r['valid_frames']:,}"
    return [
        "",
        "## Where the error is (smoothed)",
        "",
        caption(
            split,
            n,
            "p95 of M_max with and without the two ElbowYaw joints (ill-conditioned in the IK "
            "truth itself when the arm is nearly straight), deg; task-space errors of the "
            "projected pose against the IK pose from forward kinematics of the MJCF: hand (the "
            "wrist point) and elbow position (cm), upper-arm and forearm direction (deg), "
            "median / p95 over the frames",
        ),
        "",
        report.where_error_table(s),
        "",
        caption(split, n, "error per driven joint against the IK, p50 / p95 over the frames, deg"),
        "",
        report.per_joint_table(s),
    ]


def _per_action_md(r: dict) -> list[str]:
    lines = [
        "",
        "## Per action (relaxed, smoothed)",
        "",
        caption(msr_split(r), "per row", f"{IK_METRIC}: median M_avg, p95 M_max"),
        "",
        "| action | frames | M_avg median | M_max p95 |",
        "|---|---:|---:|---:|",
    ]
    for a, v in r["per_action"].items():
        x = v["relaxed"]
        lines.append(
            f"| {a} | {x['M_avg']['n']:,} | {x['M_avg']['median']:.2f} | {x['M_max']['p95']:.1f} |"
        )
    return lines


SPEED_WORDS = {
    "rated": "rated speeds (at the motors' nominal torque)",
    "no-load": "no-load speeds",
}
"""``FeasibleConfig.speeds`` in the report's words."""


OTHER_ROBOTS_NOTE = (
    "## Other robots: not in this report",
    "",
    "This report is the default robot's. The other registered robots are left out: a robot "
    "solved by the iterative generic IK costs minutes on a CPU (its default model's build and "
    "its ground truth), more than the demo's `--quick` run may take. Their numbers (accuracy on "
    "held-out people, self-collision, speed against their IK) are on the results page "
    "(`docs/results.md`), from `python -m benchmarks.robot_thesis --robot NAME`; for your own "
    "run: `jaxproj build --robot NAME --out m.npz`, then `jaxproj evaluate --model m.npz`.",
)
"""Why the demo report holds the default robot only, and where the others' numbers are."""


def _feasibility_md(r: dict) -> list[str]:
    """Before / after the feasibility filter, from the smoothed evaluation."""
    fz = {m: r["feasibility"][m] for m in ("ik", "relaxed", "full") if m in r["feasibility"]}
    cfg = next(iter(fz.values()))["config"]
    lines = [
        "",
        "## Robot-feasible output (smoothed, 15 fps)",
        "",
        f"`jaxproj.motion.feasible` (on by default in `jaxproj retarget`): joint limits, "
        f"{100 * cfg['speed_fraction']:.0f} % of the robot's {SPEED_WORDS[cfg['speeds']]} and "
        f"{cfg['accel']:.0f} rad/s^2, zero-phase. The `ik` row filters the raw per-frame IK, "
        "the others the smoothed motions.",
        "",
        caption(
            msr_split(r),
            f"{r['valid_frames']:,} (in {r['sequences']} motions)",
            "speed figures against the full no-load limits; errors against the IK of each frame "
            "(deg, cm); the last column compares the filtered motion with the unfiltered one",
        ),
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


def _rollout_md(r: dict) -> list[str]:
    ro = r["rollout"]
    lines = ["", "## MuJoCo rollout (torso fixed, position actuators, gravity on)", ""]
    lines.append(
        f"Backend `{ro['backend']}` ({ro['wall_s']:.1f} s). The trajectories: "
        + "; ".join(f"`{k}`, {v}" for k, v in ro["trajectories"].items())
        + ". Tracking is against each trajectory's own targets (a trajectory the robot can "
        "follow tracks well whether or not it is what the person did: the last column says how "
        "far its targets are from the per-frame IK); the peak speed is the simulated robot's."
    )
    frames = ro.get("frames")
    lines += [
        "",
        caption(
            f"{len(ro['motions'])} held-out arm motions of the headline's MSR split, spread over "
            "it",
            f"{frames:,}" if frames else "n/a",
            "tracking |achieved - target| (deg, driven joints pooled), frames with self-contact, "
            "frames outside the joint limits, peak joint speed over the robot's limit; targets vs "
            "IK: median M_avg of the targets against the per-frame IK (deg)",
        ),
        "",
        "| trajectory | tracking mean (deg) | tracking p95 | self-collision frames "
        "(arm-torso / arm-head / arm-arm / any) | motions with contact | joint-limit frames "
        "(achieved / target) | peak speed / robot limit | motions over the speed limit "
        "| targets vs IK, median M_avg |",
        "|---|---:|---:|---|---:|---|---:|---:|---:|",
    ]
    for name in ro["trajectories"]:
        x = ro[name]
        t, c = x["tracking_error_deg"], x["self_collision_frames"]
        lim, sp = x["joint_limit_violations"], x["speed"]
        lines.append(
            f"| {name} | {t['mean']:.2f} | {t['p95']:.2f} | {c['arm_torso']} / {c['arm_head']} "
            f"/ {c['arm_arm']} / {c['any']} | {c['motions']} | {lim['achieved_frames']} / "
            f"{lim['target_frames']} | {sp['max_ratio']:.2f} ({sp['worst_joint']}) | "
            f"{sp['motions_over_limit']} | {x['targets_vs_ik_M_avg']['median']:.2f} |"
        )
    return lines


def _experiments_md(r: dict) -> list[str]:
    ex = r["experiments"]
    bp = ex["basic_poses"]
    lines = ["", "## Paper experiments", "", "### Eight basic poses and rest -> pose motions", ""]
    lines.append(
        f"Skeletons synthesised from the median bone lengths; motions of "
        f"{bp['frames_per_motion']} frames at {bp['fps']:.0f} fps with Kinect-like noise "
        f"({1000 * bp['noise_std_m']:.1f} mm per coordinate, measured); the headline's model."
    )
    lines += [
        "",
        caption(
            "the paper's eight synthetic basic poses (noise-free) and their rest -> pose motions",
            f"8 poses, 8 x {bp['frames_per_motion']} motion frames",
            "degrees against the IK (M_max / M_avg of the pose; the motion's largest M_max / "
            "mean M_avg); nearest landmark: the largest bone angle to the nearest landmark",
        ),
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
    sizes = ex["landmark_size"]["sizes"]
    n_eval = sizes[0].get("eval_frames") if sizes else None
    lines += report_text.pose_notes(bp) + ["", "### Landmark-set size (relaxed)", ""]
    lines += [
        "One model per target (the arms' mean-shift bandwidth bisected to reach it; the head "
        "keeps its fixed bandwidth), and the headline's model (`default`). The held-out columns "
        "are the headline's frames, so its row repeats the headline's relaxed numbers.",
        "",
        caption(
            msr_split(r) + "; POSE_8's synthetic motion",
            f"{n_eval:,} held out, {bp['frames_per_motion']} POSE_8" if n_eval else "n/a",
            "degrees against the IK, unsmoothed, L = M = 10",
        ),
        "",
        "| target per arm | landmarks (head / left arm / right arm) | bandwidth (head / left / "
        "right) | held-out median M_avg | held-out p95 M_max | POSE_8 motion max M_max "
        "| POSE_8 motion mean M_avg |",
        "|---|---|---|---:|---:|---:|---:|",
    ]
    for row in sizes:
        target = "default (`BuildConfig()`)" if row["target"] is None else str(row["target"])
        lines.append(
            f"| {target} | {' / '.join(str(v) for v in row['landmarks_per_chain'].values())} | "
            f"{report_text.bandwidths(row['bandwidth'])} | "
            f"{row['M_avg_median']:.2f} | {row['M_max_p95']:.1f} "
            f"| {row['pose8_M_max']:.1f} | {row['pose8_M_avg_mean']:.2f} |"
        )
    eff = ex["efficiency"]
    lines += ["", f"### Efficiency vs L = M ({eff['objective']}, {eff['device']})", ""]
    lines += [
        caption(
            msr_split(r),
            f"{eff['n_queries']:,} scored; each time from one batch of {eff['batch']:,} queries "
            "per call",
            "median time per projection over the timed calls (us, compilation apart); degrees "
            "against the IK, unsmoothed",
        ),
        "",
        "| L = M | batch | us / projection | median M_avg | p95 M_max |",
        "|---:|---:|---:|---:|---:|",
    ]
    for row in eff["rows"]:
        lines.append(
            f"| {row['L']} | {row['batch']} | {row['us_per_projection']:.1f} | "
            f"{row['M_avg_median']:.2f} | {row['M_max_p95']:.1f} |"
        )
    return lines


def markdown(r: dict) -> str:
    """The whole ``report.md``."""
    lines = ["# jaxproj demo report", ""]
    if r.get("quick"):
        lines += [
            QUICK_NOTE.format(train=QUICK_TRAIN_STRIDE, test=QUICK_TEST_STRIDE, k=QUICK_LANDMARKS),
            "",
        ]
    lines += _headline_md(r)
    lines += recommendation(r)
    lines += [
        "",
        "## Set-up",
        "",
        f"Model: {_model_words(r)}. Scored on the {msr_split(r)}; cross-dataset, the "
        f"{_utk_split(r)}. L = {r['L']}, "
        f"M = {r['M']}. Devices: {', '.join(r['devices'])}.",
    ]
    lines += _summary_md(r)
    lines += report_text.confidence_md(
        r.get("confidence") or {},
        caption(msr_split(r), f"{r['valid_frames']:,}, in ten equal groups",
                "confidence against the unsmoothed M_max (deg) of the same frames"),
    )  # fmt: skip
    lines += _comparison_md(r) + _where_md(r) + _per_action_md(r) + _feasibility_md(r)
    lines += _rollout_md(r) + _experiments_md(r)
    lines += ["", *OTHER_ROBOTS_NOTE]
    lines += ["", "## Plots", ""]
    lines += [f"![{p}]({p})" for p in r["plots"]]
    lines += [
        "",
        "## Timings",
        "",
        caption("this run, this machine", "all of the above", "wall seconds per stage"),
        "",
        "| stage | s |",
        "|---|---:|",
    ]
    lines += [f"| {k.removesuffix('_s')} | {v:.1f} |" for k, v in r["timings"].items()]
    lines += [""]
    return "\n".join(lines)


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


def check_report_folder(out_dir: os.PathLike[str] | str, overwrite: bool) -> None:
    """``ConfigError`` (before any work) unless ``run_demo`` may write into ``out_dir``: it
    must be a folder or absent (its parent folder must exist: only the report folder itself is
    created), and, unless ``overwrite``, hold none of the files a run writes (``REPORT_FILES``,
    ``motion_*.png``)."""
    from pathlib import Path

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
