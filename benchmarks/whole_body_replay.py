"""The physics check of issue 59 over a dataset: every frame of every whole-body file in a
folder (what ``jaxproj retarget FOLDER --root world --out DIR`` wrote) replayed kinematically in
MJX with contacts on, all frames in batched calls (``jaxproj.eval.replay.replay_depths``).

Checked first: on ``--check`` frames spread over the data (64), the MJX depths equal MuJoCo's
``mj_forward`` (the deepest floor and self contact of each pose) to 0.1 mm; that first call
compiles (``compile_s``: compiling and one batch). Then every frame, the program in memory
(``run_s``, the answers on the host).

Output (one JSON object): ``robot``, ``files``, ``frames``; ``floor_frames``: frames where a
robot geom is more than 5 mm below the floor (issue 59's penetration bound), ``floor_mm_max``;
``self_frames``: frames where two of the robot's geoms are more than 1 mm into each other
(``contact_frames`` of ``benchmarks.whole_body``), ``self_mm_max``; ``files_with_self`` (their
names) and ``files_with_floor``; ``check_max_diff_mm``; ``compile_s``, ``run_s`` and
``frames_per_s`` (``run_s``'s); ``device``, ``jax_version``.

The root's steps, sliding and the rest are ``benchmarks.whole_body``'s (one recording at a time,
on the host).

Usage::

    python -m benchmarks.whole_body_replay DIR [--robot unitree_g1] [--check 64] [--json OUT]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import numpy as np

from benchmarks.harness import report
from jaxproj import robots
from jaxproj.eval import replay
from jaxproj.io.motion_files import load_motion

FLOOR_BOUND_M = 5e-3
SELF_BOUND_M = 1e-3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--robot", default="unitree_g1")
    ap.add_argument("--check", type=int, default=64, help="frames compared with MuJoCo")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    robot = robots.get(args.robot)
    files = sorted(args.folder.glob("*.npz"))
    if not files:
        raise SystemExit(f"whole_body_replay: no .npz file in {args.folder}")
    pos, rot, ang, owner = [], [], [], []
    for i, f in enumerate(files):
        m = load_motion(f)
        if m.root_pos is None or m.root_rot is None:
            raise SystemExit(f"whole_body_replay: {f}: no root (written without --root world)")
        pos.append(m.root_pos)
        rot.append(m.root_rot)
        ang.append(m.angles)
        owner.append(np.full(len(m.angles), i))
    p, r, q, who = (np.concatenate(x) for x in (pos, rot, ang, owner))
    n = len(p)
    # correctness first: MJX against MuJoCo on frames spread over the data
    pick = np.unique(np.linspace(0, n - 1, min(args.check, n)).round().astype(int))
    t0 = time.perf_counter()
    got = replay.replay_depths(robot, p[pick], r[pick], q[pick])
    compile_s = time.perf_counter() - t0
    want = replay.host_depths(robot, p[pick], r[pick], q[pick])
    worst = float(max(np.abs(got.floor_m - want.floor_m).max(),
                      np.abs(got.self_m - want.self_m).max()))  # fmt: skip
    if worst > 1e-4:
        raise SystemExit(f"whole_body_replay: MJX and MuJoCo differ by {worst * 1000:.3f} mm")
    t0 = time.perf_counter()
    d = replay.replay_depths(robot, p, r, q)  # every frame: the batch's program compiled
    run_s = time.perf_counter() - t0
    floor_bad = d.floor_m > FLOOR_BOUND_M
    self_bad = d.self_m > SELF_BOUND_M
    devices = jax.devices()
    res = {
        "robot": args.robot,
        "files": len(files),
        "frames": n,
        "floor_frames": int(floor_bad.sum()),
        "floor_mm_max": round(float(d.floor_m.max()) * 1000, 3),
        "files_with_floor": len(set(who[floor_bad].tolist())),
        "self_frames": int(self_bad.sum()),
        "self_mm_max": round(float(d.self_m.max()) * 1000, 3),
        "files_with_self": sorted({files[i].name for i in who[self_bad].tolist()}),
        "check_frames": len(pick),
        "check_max_diff_mm": round(worst * 1000, 5),
        "compile_s": round(compile_s, 3),
        "run_s": round(run_s, 3),
        "frames_per_s": round(n / run_s, 1),
        "device": f"{len(devices)} x {devices[0].device_kind}",
        "jax_version": jax.__version__,
    }
    report(res, None if args.json is None else str(args.json))
    return 0


if __name__ == "__main__":
    sys.exit(main())
