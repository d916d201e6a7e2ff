"""Which last stage leaves the G1's output without flips AND without self-contact? (issue 57)

``retarget`` (method ik, the offline smoother, no filter) on the held-out recordings of
``benchmarks.g1_playable``, then each variant of the stages after the smoother, scored like
``g1_playable`` (flip steps, contact frames, lean, arms) and against the limits
(``feasible.feasibility_report``: rated-speed ratio, acceleration above the bound the variant
judged by):

stage orders (``--orders``, ``f`` the filter, ``s`` the separation): ``fsf`` filter ->
separation -> filter (``retarget`` before this experiment); ``fs`` (the separation last);
``fsfs`` (two rounds);
each with the acceleration bound ``N`` rad/s^2 on every joint (``_a<N>``, ``--accels``) or the
robot's own (``_arobot``, ``Robot.acceleration_limits``). The separation is
``pipeline.playable_full``: ``Robot.playable_motion``, frame by frame in time order.

    python -m benchmarks.experiments.g1_last_stage [FILES...] [--data DIR] [--json OUT] [--save DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from benchmarks import g1_playable as gp
from jaxproj import robots
from jaxproj.io.motion_files import Motion
from jaxproj.io.readers import read_skeleton
from jaxproj.motion.feasible import FeasibleConfig, feasibility_report, make_feasible
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.retarget import retarget, separate_motion


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="*", type=Path)
    p.add_argument("--data", type=Path, default=None)
    p.add_argument("--json", default=None)
    p.add_argument("--accels", default="robot,80", help="bounds, rad/s^2, or robot's own")
    p.add_argument("--orders", default="fs,fsf", help="stages after smoothing: f filter, s sep")
    p.add_argument("--save", type=Path, default=None, help="folder: the smoothed angles (NPZ)")
    a = p.parse_args(argv)
    g1 = robots.get(gp.ROBOT)
    from jaxproj.cli.retarget import output_rate

    variants: dict[str, tuple[robots.Robot, FeasibleConfig, str]] = {}
    for acc in a.accels.split(","):
        cfg = FeasibleConfig(accel=None if acc == "robot" else float(acc))
        for order in a.orders.split(","):
            name = "_".join({"f": "filter", "s": "sep"}[c] for c in order)
            variants[f"{name}_a{acc}"] = (g1, cfg, order)
    rows = []
    for f in a.files or gp.default_files(a.data):
        rec = output_rate(read_skeleton(f), "auto")
        res = retarget(rec.positions, rec.valid, method="ik", robot=g1, bones="full",
                       smoothing=OFFLINE_SMOOTHING, feasible=None, times=rec.times)  # fmt: skip
        smooth = np.asarray(res.angles, np.float32)
        if a.save is not None:
            a.save.mkdir(parents=True, exist_ok=True)
            np.savez(a.save / f"{f.stem}_smooth.npz", angles=smooth, valid=res.valid,
                     times=res.times, positions=rec.positions)  # fmt: skip
        bones, ok, frames = gp._bones(np.asarray(rec.positions, np.float32))
        for name, (robot, cfg, order) in variants.items():
            q = smooth
            for stage in order:
                if stage == "f":
                    q = make_feasible(q, res.times, config=cfg, robot=robot)
                else:
                    q = separate_motion(q, robot)
            motion = Motion(q, res.times, res.valid, rec.positions, robot=g1)
            r = {"file": f.name, "variant": name}
            fl = gp.flips(motion, bones, ok, g1)
            r |= {k: fl[k] for k in ("flip_steps", "max_step_deg", "examples")}
            geo = gp.geometry(motion, bones, ok, frames, g1, np.asarray(rec.positions))
            r |= {k: geo[k] for k in ("contact_frames", "contact_pairs", "lean_diff", "arm_median",
                                      "arm_p90")}  # fmt: skip
            rep = feasibility_report(q, res.times, cfg, robot=robot)
            r |= {k: rep[k] for k in ("rated_speed_ratio", "accel_violation_frames", "max_accel",
                                      "limit_violation_frames")}  # fmt: skip
            rows.append(r)
            print(json.dumps({k: v for k, v in r.items() if k != "examples"}), flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
