"""What a user gets by default, on people the landmarks never saw: issue 29's table.

The default model (``BuildConfig()``, built from the default training set unless ``--model``:
MSR Action3D training subjects 1,3,5,7,9 and UTKinect-Action3D people 3, 4, 6; until 0.2.0 MSR
alone), relaxed L = M = 10, on two held-out splits: MSR Action3D subjects 2,4,6,8,10 (arm
actions, 15 fps assumed) and the upper-body segments of the UTKinect-Action3D people the model
did not train on (``heldout.splits``: 7 and 9 for the default model, all five for an MSR-only
one; another room; times from their frame numbers). Per split and smoother (the default
zero-lag offline one, the paper's causal one), against the IK of every valid frame:

* unsmoothed: the projection itself (median M_avg, p95 M_max, p95 M_max without ElbowYaw);
* default output: smoothed, then the feasibility filter (``retarget``'s default for the robot):
  median M_avg, p95 M_max;
* lag (frames of best cross-correlation with the IK's motion) and mean squared jerk
  ((rad/s^3)^2) of the smoothed motion, the IK's own jerk beside them;
* the per-frame confidence against the unsmoothed error: the share of frames with M_max > 30
  deg in the least confident decile, and the share of those frames flagged low-confidence;
* the feasible output's simulated servo speed is ``benchmarks/bench_rollout.py``'s, not here.

    python -m benchmarks.default_output [--model P.npz] [--save-model P.npz] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from benchmarks import heldout
from jaxproj.eval import evaluate as ev
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.smoothing import PAPER_SMOOTHING


def row(r: dict) -> dict:
    """The table's numbers from one ``evaluate`` report (method ``relaxed``)."""
    raw, sm = r["unsmoothed"]["relaxed"], r["summary"]["relaxed"]
    after = r["feasibility"]["relaxed"]["after_errors"]
    s = r["smoothness"]
    return {
        "unsmoothed": {
            "M_avg_median": raw["M_avg"]["median"],
            "M_max_p95": raw["M_max"]["p95"],
            "M_max_no_elbow_yaw_p95": raw["M_max_no_elbow_yaw"]["p95"],
        },
        "smoothed": {"M_avg_median": sm["M_avg"]["median"], "M_max_p95": sm["M_max"]["p95"]},
        "default_output": {
            "M_avg_median": after["M_avg"]["median"],
            "M_max_p95": after["M_max"]["p95"],
            "M_max_no_elbow_yaw_p95": after["M_max_no_elbow_yaw"]["p95"],
        },
        "lag_frames": s["relaxed"]["lag_frames_smoothed"],
        "jerk": s["relaxed"]["jerk_smoothed"],
        "jerk_unsmoothed": s["relaxed"]["jerk_raw"],
        "jerk_ik": s["ik"]["jerk_raw"],
        "frames": r["valid_frames"],
        "confidence": r["confidence"]["relaxed"],
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", help="projector .npz (default: build the default model)")
    p.add_argument("--save-model", help="write the built model here")
    p.add_argument("--json", help="write the results here")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    model = heldout.default_model(args.model, save=args.save_model)
    out: dict = {"landmarks": model.landmarks, "splits": {}}
    lines = [
        "| split | smoother | unsmoothed median M_avg / p95 M_max / p95 w/o EY | default output "
        "median M_avg / p95 M_max / p95 w/o EY | lag (frames) | jerk (rad^2/s^6) | IK jerk | "
        "worst-confidence decile: share M_max > 30 | low-confidence frames: share of them / "
        "recall of M_max > 30 |",
        "|---|---|---|---|---:|---:|---:|---:|---|",
    ]
    for split, seqs in heldout.splits(model.config.utkinect_people).items():
        data = ev.prepare(seqs)
        for name, smoothing in (("offline", OFFLINE_SMOOTHING), ("paper", PAPER_SMOOTHING)):
            r = ev.evaluate(model, data, ["relaxed"], smoothing=smoothing)
            x = row(r)
            out["splits"].setdefault(split, {})[name] = x
            u, d, c = x["unsmoothed"], x["default_output"], x["confidence"]
            lines.append(
                f"| {split} ({x['frames']} frames) | {name} | {u['M_avg_median']:.2f} / "
                f"{u['M_max_p95']:.1f} / {u['M_max_no_elbow_yaw_p95']:.1f} | "
                f"{d['M_avg_median']:.2f} / {d['M_max_p95']:.1f} / "
                f"{d['M_max_no_elbow_yaw_p95']:.1f} | {x['lag_frames']:+.2f} | {x['jerk']:.3g} | "
                f"{x['jerk_ik']:.3g} | {100 * c['worst_decile_share_over']:.0f} % (all frames: "
                f"{100 * c['share_over']:.1f} %) | {100 * c['low_share']:.0f} % / "
                f"{100 * c['low_recall']:.0f} % |"
            )
    out["wall_s"] = time.perf_counter() - t0
    print("\n".join(lines))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
