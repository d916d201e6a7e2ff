"""Where a G1 flip or self-contact enters: ``jaxproj.retarget`` (method ik) with its stages
switched on one after another, scored like ``benchmarks.g1_playable`` (flip steps, contact
frames, largest step) on the same held-out recordings.

Variants: ``per_frame`` (no continuity pass, no smoother, no filter), ``track`` (the continuity
pass), ``smooth`` (+ the offline smoother), ``default`` (+ the feasibility filter and the last
separation: what ``retarget`` writes).

    python -m benchmarks.experiments.g1_stages [FILES...] [--data FOLDER] [--json OUT] [--save DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from benchmarks import g1_playable as gp
from jaxproj import robots
from jaxproj.io.motion_files import Motion
from jaxproj.io.readers import read_skeleton
from jaxproj.motion.feasible import FeasibleConfig
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.retarget import retarget


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="*", type=Path)
    p.add_argument("--data", type=Path, default=None)
    p.add_argument("--json", default=None)
    p.add_argument("--save", type=Path, default=None, help="folder: each variant's angles (NPZ)")
    a = p.parse_args(argv)
    g1 = robots.get(gp.ROBOT)
    loose = dataclasses.replace(g1, track=None, track_step=None)
    variants = {
        "per_frame": (loose, None, None),
        "track": (g1, None, None),
        "smooth": (g1, OFFLINE_SMOOTHING, None),
        "default": (g1, OFFLINE_SMOOTHING, FeasibleConfig()),
    }
    rows = []
    for f in a.files or gp.default_files(a.data):
        rec = read_skeleton(f)
        from jaxproj.cli.retarget import output_rate

        rec = output_rate(rec, "auto")
        for name, (robot, smoothing, feasible) in variants.items():
            res = retarget(rec.positions, rec.valid, method="ik", robot=robot, bones="full",
                           smoothing=smoothing, feasible=feasible, times=rec.times)  # fmt: skip
            motion = Motion(res.angles, res.times, res.valid, rec.positions, robot=g1)
            if a.save is not None:
                a.save.mkdir(parents=True, exist_ok=True)
                np.savez(a.save / f"{f.stem}_{name}.npz", angles=res.angles, valid=res.valid,
                         times=res.times, positions=rec.positions)  # fmt: skip
            bones, ok, frames = gp._bones(np.asarray(rec.positions, np.float32))
            r = {"file": f.name, "variant": name}
            fl = gp.flips(motion, bones, ok, g1)
            r |= {k: fl[k] for k in ("flip_steps", "steps_over_90", "max_step_deg", "examples")}
            geo = gp.geometry(motion, bones, ok, frames, g1, np.asarray(rec.positions))
            r |= {k: geo[k] for k in ("contact_frames", "contact_pairs", "lean_diff", "arm_median",
                                      "arm_p90")}  # fmt: skip
            rows.append(r)
            print(json.dumps(r), flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
