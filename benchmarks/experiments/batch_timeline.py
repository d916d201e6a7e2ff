"""Where a batch's time goes on an accelerator (issue 61): ``retarget_many`` over the bundled
recordings with every compiled call timed, then one motion's stages after the mapping timed
alone.

1. **The calls.** The bundled recordings (every UTKinect segment and MSR Action3D sequence of
   ``jaxproj/data`` and the CMU clips of ``tests/data/cmu_bvh``) retargeted by
   ``jaxproj.motion.retarget.retarget_many`` with the command line's settings (the IK,
   the feasibility filter, kept executables in a fresh folder), three times in one process:
   ``cold_all`` (an empty folder, the calls spread over every device), ``warm_one`` (the
   programs in memory, one device), ``warm_all`` (in memory, every device). Each
   ``executables.call`` is logged: its program, thread, device, input shape, start and
   seconds.
2. **The stages.** The longest recording's stages after the mapping (``robot.continuous``,
   the smoother, ``bound_steps``, ``playable_motion``), each compiled alone and timed warm
   (best of 3), beside the whole ``pipeline.motion``.
3. **The continuity pass's two ways** (``generic_ik.SIDE_BY_SIDE``): one scan of ``2T``
   steps against the two ways side by side (``vmap``, ``T`` steps) on one motion of
   ``--ways-frames`` frames, their answers' largest difference.

Measured on 2 H200s and kept in ``benchmarks/results/batch_timeline_g1_h200x2.json``
(2026-11-30; parts 1 and 2 before the two ways went side by side on a GPU, part 3 separately).

Usage::

    python -m benchmarks.experiments.batch_timeline [--robot unitree_g1] [--recordings N]
        [--ways-frames 128] [--skip-calls] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj import robots
from jaxproj._internal import executables
from jaxproj.io import datasets
from jaxproj.io.readers import read_skeleton
from jaxproj.motion import pipeline
from jaxproj.motion import retarget as R
from jaxproj.motion.pipeline import fill_invalid
from jaxproj.motion.smoothing import smooth_any
from jaxproj.robots import generic_ik

CMU = Path(__file__).resolve().parents[2] / "tests" / "data" / "cmu_bvh"


def _recordings(n: int) -> tuple[list, list, list]:
    seqs = [*datasets.utkinect_action3d(), *datasets.msr_action3d()][:n]
    pos, val, tim = [s.positions for s in seqs], [s.valid for s in seqs], [s.times for s in seqs]
    for f in sorted(CMU.glob("*.bvh")):
        r = read_skeleton(f)
        pos.append(r.positions), val.append(r.valid), tim.append(r.times)
    return pos, val, tim


def _plan(robot: robots.Robot, pos: np.ndarray, val: np.ndarray, times: Any, bones: str) -> Any:
    return R._plan(pos, val, model=None, method=None, n_l=10, n_m=10, full=None, bones=bones,
                   mirror=False, smoothing=R.OFFLINE_SMOOTHING, times=times, robot=robot,
                   neck_neutral="recording", level_legs=True, skeleton=R.skeletons.DEFAULT,
                   coarse=True)  # fmt: skip


def _timed(fn: Any, *args: Any) -> dict[str, float]:
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    runs = []
    for _ in range(3):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        runs.append(time.perf_counter() - t0)
    return {"first_s": round(first, 2), "warm_s": round(min(runs), 4), "out": out}


def _mapped(robot: robots.Robot, plan: Any, bones: str) -> tuple[jax.Array, ...]:
    st = plan.static
    before = jax.jit(lambda x, v, nn: pipeline._before_mapping(
        x, v, bones, False, robot, st["neck"], nn, st["level_legs"]))  # fmt: skip
    d, ok = before(plan.pos, plan.ok, np.float32(plan.neutral))

    def mapping(d: jax.Array) -> tuple[jax.Array, jax.Array]:
        return pipeline.map_frames(None, d, method="ik", n_l=10, n_m=10, full=st["full"],
                                   bones=bones, robot=robot)  # fmt: skip

    mapping = jax.jit(mapping)
    q, _ = mapping(d)
    return d, ok, q


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="unitree_g1")
    ap.add_argument("--recordings", type=int, default=10**9, help="bundled ones (then CMU's)")
    ap.add_argument("--ways-frames", type=int, default=128)
    ap.add_argument("--skip-calls", action="store_true", help="parts 2 and 3 only")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    robot = robots.get(args.robot)
    bones = "full" if len(robot.ik_bones) > 6 else "upper"
    pos, val, tim = _recordings(args.recordings)
    res: dict[str, Any] = {"robot": robot.name, "devices": [str(d) for d in jax.devices()],
                           "jax_version": jax.__version__, "recordings": len(pos),
                           "frames": int(sum(len(p) for p in pos))}  # fmt: skip
    log: list[dict[str, Any]] = []
    start = [0.0]
    call = executables.call

    def timed_call(jitted: Any, a: tuple, kw: Any = None, st: Any = None, **more: Any) -> Any:
        t0 = time.perf_counter()
        out = jax.block_until_ready(call(jitted, a, kw, st, **more))
        log.append({"name": more["name"], "thread": threading.current_thread().name,
                    "device": str(executables._default_device()),
                    "shape": list(np.shape(a[1] if more["name"] == "retarget_many" else a[0])),
                    "t0": round(t0 - start[0], 2),
                    "s": round(time.perf_counter() - t0, 2)})  # fmt: skip
        return out

    if not args.skip_calls:
        R.executables.call = timed_call  # type: ignore[attr-defined]
        with tempfile.TemporaryDirectory() as tmp, executables.kept_in(Path(tmp)):
            for label, devs in (("cold_all", jax.devices()), ("warm_one", None),
                                ("warm_all", jax.devices())):  # fmt: skip
                log.clear()
                start[0] = time.perf_counter()
                out = R.retarget_many(pos, val, tim, robot=robot, bones=bones,
                                      feasible=R.FeasibleConfig(), devices=devs)  # fmt: skip
                wall = time.perf_counter() - start[0]
                failed = sum(isinstance(o, Exception) for o in out)
                res[label] = {"wall_s": round(wall, 2), "failed": failed, "calls": list(log)}
                print(f"{label}: {wall:.1f} s, {failed} failed", flush=True)
        R.executables.call = call  # type: ignore[attr-defined]
    longest = int(np.argmax([len(p) for p in pos]))
    plan = _plan(robot, pos[longest], val[longest], tim[longest], bones)
    st = plan.static
    d, ok, q = _mapped(robot, plan, bones)
    n = jnp.int32(plan.t)
    stages = {
        "continuous": (jax.jit(lambda q, ok, d: robot.continuous(q, ok, d, bones, 1)), (q, ok, d)),
        "fill_invalid": (jax.jit(fill_invalid), (q, ok)),
        "smooth": (jax.jit(lambda q, ok, n, g: smooth_any(q, ok, n, g, st["smoother"])),
                   (q, ok, n, plan.gains)),
        "bound_steps": (jax.jit(lambda q, ok, d: robot.bound_steps(q, ok, d, bones)), (q, ok, d)),
        "playable_motion": (jax.jit(robot.playable_motion), (q,)),
        "whole motion": (jax.jit(lambda x, v, n, g, nn: pipeline.motion(
            None, x, v, n, g, neck_neutral=nn, **st)),
            (plan.pos, plan.ok, n, plan.gains, np.float32(plan.neutral))),
    }  # fmt: skip
    res["stages"] = {"frames": int(plan.pos.shape[0]), "true_frames": plan.t}
    for name, (fn, a) in stages.items():
        t = _timed(fn, *a)
        t.pop("out")
        res["stages"][name] = t
        print(f"stage {name}: {t}", flush=True)
    # part 3: the continuity pass's two ways, one after the other against side by side
    seqs = datasets.msr_action3d(subjects=[1], actions=[1, 2, 3, 4])
    x = np.concatenate([s.positions for s in seqs])[: args.ways_frames]
    v = np.concatenate([s.valid for s in seqs])[: len(x)]
    d, ok, q = _mapped(robot, _plan(robot, x, v, None, bones), bones)
    answers = {}
    for side in (False, True):
        generic_ik.SIDE_BY_SIDE = side
        t = _timed(jax.jit(lambda q, ok, d: robot.continuous(q, ok, d, bones, 1)), q, ok, d)
        answers[side] = np.asarray(t.pop("out"))
        res[f"ways_side_by_side_{side}"] = {"frames": int(len(q)), **t}
        print(f"two ways side by side={side}: {t}", flush=True)
    generic_ik.SIDE_BY_SIDE = None
    res["ways_max_diff_rad"] = float(np.abs(answers[True] - answers[False]).max())
    calls = ("cold_all", "warm_one", "warm_all")
    print(json.dumps({k: v for k, v in res.items() if k not in calls}, indent=1))
    if args.json is not None:
        args.json.write_text(json.dumps(res, indent=1) + "\n")


if __name__ == "__main__":
    main()
