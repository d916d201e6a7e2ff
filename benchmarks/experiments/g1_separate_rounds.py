"""Do the G1's separation and feasibility filter settle when applied in turn? (issue 57)

Reads a smoothed G1 motion saved by ``benchmarks.experiments.g1_stages --save DIR``
(``DIR/<recording>_smooth.npz``), applies the feasibility filter (``FeasibleConfig()``), then
``ROUNDS`` rounds of separation (``Robot.playable``) and filter, and prints after each step the
frames with a self-contact (as ``benchmarks.g1_playable`` counts them) and how far the step
moved a joint.

    python -m benchmarks.experiments.g1_separate_rounds DIR/131_01_smooth.npz [--rounds 5]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np

from benchmarks import g1_playable as gp
from jaxproj import robots
from jaxproj.motion.feasible import FeasibleConfig, make_feasible
from jaxproj.motion.retarget import separate_motion


def contact_frames(q: np.ndarray, robot: robots.Robot) -> int:
    """Frames of ``(T, n_joints)`` angles with a self-contact as ``g1_playable`` counts them."""
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    adr = gp.qpos_addresses(model, robot)
    n = 0
    for t in range(len(q)):
        data.qpos[adr] = q[t]
        mujoco.mj_forward(model, data)
        n += bool(gp.contact_pairs(model, data))
    return n


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("motion", type=Path)
    p.add_argument("--rounds", type=int, default=5)
    a = p.parse_args(argv)
    robot = robots.get(gp.ROBOT)
    z = np.load(a.motion)
    q, times = np.asarray(z["angles"], np.float32), np.asarray(z["times"])
    cfg = FeasibleConfig()
    print(f"smoothed: {contact_frames(q, robot)} contact frames")
    f = make_feasible(q, times, config=cfg, robot=robot)
    print(f"filter: {contact_frames(f, robot)} contact frames, moved {np.abs(f - q).max():.2f} rad")
    for r in range(a.rounds):
        s = separate_motion(f, robot)
        print(f"round {r}: separation {contact_frames(s, robot)} contact frames, "
              f"moved {np.abs(s - f).max():.2f} rad", end="; ")  # fmt: skip
        f = make_feasible(s, times, config=cfg, robot=robot)
        print(f"filter {contact_frames(f, robot)}, moved {np.abs(f - s).max():.2f} rad")
    return 0


if __name__ == "__main__":
    sys.exit(main())
