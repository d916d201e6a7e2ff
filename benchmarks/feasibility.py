"""What the robot-feasibility filter costs and buys, on people the landmarks never saw.

For each split (held-out MSR Action3D subjects 2,4,6,8,10, arm actions, 15 fps assumed; the
UTKinect-Action3D upper-body segments, times from their frame numbers) the relaxed projection is
smoothed (the default) and run through ``jaxproj.motion.feasible`` with its defaults (UTKinect:
the people the model did not train on, ``heldout.splits``); the IK
trajectory too. Printed and written as JSON: speed-limit violations, largest step and
acceleration before -> after, errors against the IK before -> after, and the change
against the unfiltered motion.

    python -m benchmarks.feasibility [--model P.npz] [--json OUT]

Without ``--model`` the default per-chain projector is built from the default training set
(``heldout.default_model``: MSR subjects 1,3,5,7,9 and UTKinect people 3, 4, 6; ~2 min on 2 CPU
cores).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from benchmarks import heldout
from jaxproj.eval import evaluate as ev


def _row(split: str, name: str, block: dict, before: dict | None) -> str:
    b, a, err = block["before"], block["after"], block["after_errors"]
    m_avg = f"{err['M_avg']['median']:.2f}"
    no_ey = f"{err['M_max_no_elbow_yaw']['p95']:.1f}"
    hand = "/".join(f"{err['task_space'][s]['hand_cm']['p95']:.1f}" for s in ("left", "right"))
    if before is not None:
        m_avg = f"{before['M_avg']['median']:.2f} -> {m_avg}"
        no_ey = f"{before['M_max_no_elbow_yaw']['p95']:.1f} -> {no_ey}"
        old = "/".join(
            f"{before['task_space'][s]['hand_cm']['p95']:.1f}" for s in ("left", "right")
        )
        hand = f"{old} -> {hand}"
    vs = block["vs_unfiltered"]
    return (
        f"| {split} | {name} | {b['motions_over_speed_limit']} -> "
        f"{a['motions_over_speed_limit']} of {b['motions']} | {b['speed_violation_frames']} -> "
        f"{a['speed_violation_frames']} | {b['max_step_deg']:.0f} -> {a['max_step_deg']:.0f} | "
        f"{b['max_accel']:.0f} -> {a['max_accel']:.0f} | {m_avg} | {no_ey} | {hand} | "
        f"{vs['joint_deg']['p95']:.1f} / {vs['hand_cm']['p95']:.1f} |"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", help="projector .npz (default: build the default per-chain one)")
    p.add_argument("--json", help="write the results here")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    model = heldout.default_model(args.model)
    out: dict = {"landmarks": list(model.landmarks), "splits": {}}
    lines = [
        "| split | trajectory | motions over speed limit | frames over | max step (deg) | max "
        "accel (rad/s^2) | median M_avg (deg) | p95 M_max no EY | hand p95 cm L/R | vs "
        "unfiltered: joint deg p95 / hand cm p95 |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for split, seqs in heldout.splits(model.config.utkinect_people).items():
        data = ev.prepare(seqs)
        r = ev.evaluate(model, data, methods=["relaxed"])
        out["splits"][split] = {
            "frames": r["valid_frames"],
            "summary": r["summary"],
            "feasibility": r["feasibility"],
        }
        for name in ("relaxed", "ik"):
            lines.append(_row(split, name, r["feasibility"][name], r["summary"].get(name)))
    out["wall_s"] = time.perf_counter() - t0
    print("\n".join(lines))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
