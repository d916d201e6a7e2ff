"""Throughput of the MJX rollout (``jaxproj.eval.rollout.simulate``) in NAO physics steps per
second.

Synthetic arm/head motions (sinusoids around the standing posture, inside the joint limits) are
played on the fixed-torso NAO at 15 frames/s (33 physics steps of 2 ms per frame). Before timing,
the script checks correctness: every simulated angle is finite, and motion 0 (contact-free by
construction) agrees with the same protocol run through CPU MuJoCo ``mj_step`` (max |dq| printed;
exit status 1 above 1e-3 rad). Per batch size it then times the first call (compile + run) and
the best of ``--repeat`` further calls (``block_until_ready``), and reports
``batch * frames * substeps / run time``; the CPU MuJoCo ``mj_step`` loop on motion 0 is the
same-run baseline (one core, one motion).

``--backend warp`` (MJX's Warp implementation, a CUDA GPU and the ``warp`` extra) first checks
``--check-backend`` benchmark motions against C MuJoCo (``backend="mujoco"``, float64): max
|dq| and |d max_speed| over the motions without self-contact (exit status 1 above 1e-4 rad /
1e-2 rad/s, the MJX-JAX tolerances of tests/eval/test_rollout.py) and over those with it, the
same for MJX-JAX on the same motions, and how many motions' line search hit its cap; then
it times each batch size on Warp and, in the same run, on MJX-JAX (``backend="mjx"``, the
same ``RolloutConfig``: the split model by default).

    python -m benchmarks.bench_rollout [--batch 1,64,1024] [--frames 30] [--device cpu|gpu]
                                       [--backend mjx|mujoco|warp] [--repeat 3] [--json OUT]

``--device`` sets ``JAX_PLATFORMS`` before JAX is imported (MJX puts the model on
``jax.devices()[0]``), so ``gpu`` needs a CUDA build of jaxlib.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import time
from pathlib import Path

PLATFORMS = {"cpu": "cpu", "gpu": "cuda"}


def _args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", default="1,64,1024", help="comma-separated batch sizes")
    ap.add_argument("--frames", type=int, default=30, help="frames per motion (15 frames/s)")
    ap.add_argument("--device", choices=sorted(PLATFORMS), default="cpu")
    ap.add_argument(
        "--backend",
        choices=("mjx", "mujoco", "warp"),
        default="mjx",
        help="rollout.simulate's backend: MJX (default), CPU MuJoCo (threads = cores) or MJX's "
        "Warp implementation (CUDA; MJX-JAX timed beside it)",
    )
    ap.add_argument(
        "--check-backend",
        type=int,
        default=256,
        help="--backend warp: benchmark motions checked against C MuJoCo before timing",
    )
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per batch size (best kept)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--solver-iterations",
        type=int,
        default=None,
        help="RolloutConfig.solver_iterations (default: the library default)",
    )
    ap.add_argument(
        "--ls-iterations",
        type=int,
        default=None,
        help="RolloutConfig.ls_iterations (default: the library default)",
    )
    ap.add_argument(
        "--frictionless",
        action="store_true",
        help="RolloutConfig(contact_friction=False): frictionless self-contacts",
    )
    ap.add_argument(
        "--no-split",
        action="store_true",
        help="RolloutConfig(split_legs=False): the whole model, not head-and-arms + legs",
    )
    ap.add_argument(
        "--whole-baseline",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="with the split (default), also time the whole model at each batch size",
    )
    ap.add_argument(
        "--check-solver",
        type=int,
        default=64,
        help="motions re-run with MuJoCo's own caps (100 / 50) to check the solver "
        "caps change nothing (0: skip)",
    )
    ap.add_argument("--json", default=None, help="write the results here")
    args = ap.parse_args()
    args.batch = [int(b) for b in args.batch.split(",") if b.strip()]
    if not args.batch or min(args.batch) < 1 or args.frames < 1 or args.repeat < 1:
        ap.error("batch sizes, --frames and --repeat must be positive")
    return args


ARGS = _args() if __name__ == "__main__" else None
if ARGS is not None:
    os.environ["JAX_PLATFORMS"] = PLATFORMS[ARGS.device]

import jax  # noqa: E402  (after JAX_PLATFORMS)
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from jaxproj.eval import rollout, rollout_warp  # noqa: E402
from jaxproj.robots import NAO_H25  # noqa: E402
from jaxproj.robots.nao_h25 import robot  # noqa: E402


def motions(batch: int, frames: int, seed: int) -> np.ndarray:
    """(batch, frames, 26) float32: driven joints swing around the standing posture.

    Motion 0 only raises / lowers the arms in front (ShoulderPitch, ElbowRoll, shoulders rolled
    outward) and nods: no self-contact, so it can be compared with CPU MuJoCo. The others move
    all 10 driven joints with random amplitudes (up to 0.8 rad), frequencies and phases.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(frames, dtype=np.float64) / 15.0
    q = np.tile(robot.STANDING_POSTURE.astype(np.float64), (batch, frames, 1))
    drv = robot.DRIVEN_INDEX
    amp = rng.uniform(0.1, 0.8, (batch, 1, drv.size))
    freq = rng.uniform(0.3, 1.5, (batch, 1, drv.size))
    phase = rng.uniform(0.0, 2 * np.pi, (batch, 1, drv.size))
    q[..., drv] += amp * np.sin(2 * np.pi * freq * t[None, :, None] + phase)
    i = robot.IDX
    swing = np.sin(2 * np.pi * 0.8 * t)
    q[0] = robot.STANDING_POSTURE
    q[0, :, i["HeadPitch"]] = 0.3 * swing
    for side, s in (("L", 1.0), ("R", -1.0)):
        q[0, :, i[f"{side}ShoulderPitch"]] = 0.9 + 0.6 * swing
        q[0, :, i[f"{side}ShoulderRoll"]] = s * 0.4
        q[0, :, i[f"{side}ElbowRoll"]] = -s * (0.8 + 0.4 * swing)
    margin = 0.02
    return np.clip(q, robot.LOWER + margin, robot.UPPER - margin).astype(np.float32)


def cpu_rollout(
    targets: np.ndarray, substeps: int, interpolate: bool = True
) -> tuple[np.ndarray, int, float]:
    """The rollout protocol with CPU MuJoCo mj_step: (T, 26) qpos, contacts seen, seconds
    (``interpolate``: the command ramps from the previous frame's target to this frame's,
    ``RolloutConfig.interpolate``)."""
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    qi = robot.joint_qpos_index(model)
    act = robot.actuator_index(model)
    src = np.empty(model.nu, dtype=np.int64)
    for j, a in enumerate(act):
        if robot.JOINT_NAMES[j] != robot.COUPLED_JOINTS[1]:
            src[a] = j
    lo, hi = model.actuator_ctrlrange.T
    ctrl = np.clip(targets.astype(np.float64)[:, src], lo, hi)
    data.qpos[:] = robot.config_to_qpos(model, np.clip(targets[0], robot.LOWER, robot.UPPER))
    out = np.empty((len(targets), robot.N_JOINTS))
    ncon = 0
    t0 = time.perf_counter()
    for f in range(len(targets)):
        prev = ctrl[max(f - 1, 0)]
        for k in range(1, substeps + 1):
            w = k / substeps if interpolate else 1.0
            data.ctrl[:] = ctrl[f] if w >= 1.0 else prev + (ctrl[f] - prev) * np.float32(w)
            mujoco.mj_step(model, data)
            ncon += data.ncon
        out[f] = data.qpos[qi]
    return out, ncon, time.perf_counter() - t0


def config(args: argparse.Namespace) -> rollout.RolloutConfig:
    """The rollout config of this run (library defaults unless the flags override them)."""
    base = rollout.RolloutConfig()
    return rollout.RolloutConfig(
        solver_iterations=args.solver_iterations or base.solver_iterations,
        ls_iterations=args.ls_iterations or base.ls_iterations,
        contact_friction=not args.frictionless,
        split_legs=not args.no_split,
    )


def solver_check(cfg: rollout.RolloutConfig, batch: int, frames: int, seed: int) -> dict:
    """What the speed settings of ``cfg`` change, on the first ``batch`` benchmark motions
    (random, many with self-contact): max |qpos difference| (rad) against MuJoCo's own solver
    caps (100 / 50) and, for frictionless contacts, against the same config with friction."""
    q = motions(batch, frames, seed)
    ref = dataclasses.replace(cfg, solver_iterations=100, ls_iterations=50)
    a = rollout.simulate(q, config=cfg, backend="mjx")
    qa = np.asarray(a.qpos)
    out = {
        "motions": batch,
        "max_dq_rad": float(np.abs(qa - rollout.simulate(q, config=ref, backend="mjx").qpos).max()),
    }
    if cfg.split_legs:
        w = rollout.simulate(q, config=dataclasses.replace(cfg, split_legs=False), backend="mjx")
        out["vs_whole"] = {
            "max_dq_rad": float(np.abs(qa - np.asarray(w.qpos)).max()),
            "max_dqvel_rad_s": float(np.abs(np.asarray(a.qvel) - np.asarray(w.qvel)).max()),
            "contact_frames_equal": bool(
                np.array_equal(np.asarray(a.contact_frames), np.asarray(w.contact_frames))
            ),
            "motions_with_contact": int((np.asarray(w.contact_frames).sum(axis=1) > 0).sum()),
        }
    if not cfg.contact_friction:
        f = rollout.simulate(
            q, config=dataclasses.replace(cfg, contact_friction=True), backend="mjx"
        )
        dq = np.abs(qa - np.asarray(f.qpos)).max(axis=(1, 2))
        touched = np.asarray(f.contact_frames).sum(axis=1) > 0
        out["vs_friction"] = {
            "max_dq_rad": float(dq.max()),
            "motions_with_contact": int(touched.sum()),
            "contact_free_max_dq_rad": float(dq[~touched].max()) if (~touched).any() else None,
        }
    return out


def backend_check(cfg: rollout.RolloutConfig, batch: int, frames: int, seed: int) -> dict:
    """MJX's Warp implementation (and MJX-JAX) against C MuJoCo on the first ``batch``
    benchmark motions (random, many with self-contact), split by whether C MuJoCo or Warp found
    self-contact in a motion: max / median / p95 of each motion's max |qpos difference| (rad),
    max |max_speed difference| (rad/s), contact frames, and line-search cap hits (Warp)."""
    q = motions(batch, frames, seed)
    n = np.full(batch, frames, dtype=np.int32)
    ref = rollout.simulate(q, n, cfg, backend="mujoco")
    warp, overflow = rollout_warp.simulate_warp(q, n, cfg, NAO_H25, with_overflow=True)
    overflow = np.asarray(overflow)
    mjx_jax = rollout.simulate(q, n, cfg, backend="mjx")
    ref_frames = np.asarray(ref.contact_frames).sum(axis=1)
    touched = (ref_frames > 0) | (np.asarray(warp.contact_frames).sum(axis=1) > 0)

    def errors(r: rollout.RolloutResult) -> dict:
        dq = np.abs(np.asarray(r.qpos) - np.asarray(ref.qpos)).max(axis=(1, 2))
        dv = np.abs(np.asarray(r.max_speed) - np.asarray(ref.max_speed)).max(axis=1)
        dframes = np.abs(np.asarray(r.contact_frames) - np.asarray(ref.contact_frames)).max(axis=1)
        out = {}
        for name, rows in (("contact_free", ~touched), ("contact", touched)):
            out[name] = {
                "motions": int(rows.sum()),
                "max_dq_rad": float(dq[rows].max()) if rows.any() else None,
                "median_dq_rad": float(np.median(dq[rows])) if rows.any() else None,
                "p95_dq_rad": float(np.percentile(dq[rows], 95)) if rows.any() else None,
                "max_dspeed_rad_s": float(dv[rows].max()) if rows.any() else None,
                "max_dcontact_frames": int(dframes[rows].max()) if rows.any() else None,
            }
        return out

    return {
        "motions": batch,
        "warp_vs_mujoco": errors(warp),
        "mjx_vs_mujoco": errors(mjx_jax),
        "warp_ls_capped_motions": int(np.sum((overflow & rollout_warp.OVERFLOW_LS_ITERATIONS) > 0)),
        "warp_solver_capped_motions": int(
            np.sum((overflow & rollout_warp.OVERFLOW_ITERATIONS) > 0)
        ),
        "solver_iterations": cfg.solver_iterations,
        "ls_iterations": cfg.ls_iterations,
    }


def bench(
    batch: int,
    frames: int,
    seed: int,
    repeat: int,
    substeps: int,
    cfg: rollout.RolloutConfig | None = None,
    devices: list | None = None,
    backend: str = "mjx",
) -> dict:
    """Time ``rollout.simulate`` on ``batch`` benchmark motions (``cfg`` None: the defaults;
    ``devices``: several to shard the motions over, see ``rollout.simulate``; ``backend``: its
    backend, MJX by default, ``"mujoco"`` for CPU MuJoCo)."""
    cfg = cfg or rollout.RolloutConfig()
    q = motions(batch, frames, seed)
    n = np.full(batch, frames, dtype=np.int32)
    t0 = time.perf_counter()
    res = jax.block_until_ready(rollout.simulate(q, n, cfg, devices=devices, backend=backend))
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = jax.block_until_ready(rollout.simulate(q, n, cfg, devices=devices, backend=backend))
        runs.append(time.perf_counter() - t0)
    run = min(runs)
    qpos = np.asarray(res.qpos)
    steps = batch * frames * substeps
    return {
        "batch": batch,
        "first_call_s": first,
        "compile_s": max(first - run, 0.0),
        "run_s": run,
        "steps": steps,
        "steps_per_s": steps / run,
        "finite": bool(np.all(np.isfinite(qpos))),
        "qpos0": qpos[0],
    }


def main(args: argparse.Namespace) -> int:
    substeps = round((1.0 / 15.0) / robot.load_model("fixed").opt.timestep)
    dev = jax.devices()[0]
    print(f"device: {dev.platform} {dev.device_kind} | jax {jax.__version__} | mujoco "
          f"{mujoco.__version__} | {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cpus")  # fmt: skip
    cfg = config(args)
    print(f"motions: {args.frames} frames at 15 frames/s, {substeps} steps/frame | solver caps "
          f"{cfg.solver_iterations} iterations / {cfg.ls_iterations} line-search | contact "
          f"friction {cfg.contact_friction} | split_legs {cfg.split_legs}")  # fmt: skip
    check = None
    if args.backend == "warp":
        args.check_solver = 0  # an MJX-JAX check; the Warp run checks against C MuJoCo below
        args.whole_baseline = False
    backend_ok, warp_check = True, None
    if args.backend == "warp" and args.check_backend:
        t0 = time.perf_counter()
        warp_check = backend_check(cfg, args.check_backend, args.frames, args.seed)
        warp_check["seconds"] = time.perf_counter() - t0
        for name in ("warp_vs_mujoco", "mjx_vs_mujoco"):
            for part, e in warp_check[name].items():
                print(f"{name} ({part}, {e['motions']} motions): max |dq| {e['max_dq_rad']} rad, "
                      f"median {e['median_dq_rad']}, p95 {e['p95_dq_rad']}, max |d max_speed| "
                      f"{e['max_dspeed_rad_s']} rad/s, max |d contact frames| "
                      f"{e['max_dcontact_frames']}")  # fmt: skip
        print(
            f"warp: line search at its cap ({warp_check['ls_iterations']}) in some step of "
            f"{warp_check['warp_ls_capped_motions']} motions, solver at its cap "
            f"({warp_check['solver_iterations']}) in {warp_check['warp_solver_capped_motions']}"
        )
        free = warp_check["warp_vs_mujoco"]["contact_free"]
        backend_ok = free["motions"] == 0 or (
            free["max_dq_rad"] <= 1e-4 and free["max_dspeed_rad_s"] <= 1e-2
        )
        if not backend_ok:
            print("warp vs C MuJoCo on contact-free motions: CHECK FAILED")
    if args.check_solver:
        check = solver_check(cfg, args.check_solver, args.frames, args.seed)
        print(f"solver caps vs MuJoCo's 100 / 50 on {args.check_solver} motions: max |dq| "
              f"{check['max_dq_rad']:.2e} rad")  # fmt: skip
        if "vs_friction" in check:
            v = check["vs_friction"]
            print(f"frictionless vs friction contacts: max |dq| {v['max_dq_rad']:.3g} rad over the "
                  f"{v['motions_with_contact']} motions with contact, "
                  f"{v['contact_free_max_dq_rad']} on the contact-free ones")  # fmt: skip
        if "vs_whole" in check:
            v = check["vs_whole"]
            print(f"split (head-and-arms + legs) vs whole model: max |dq| {v['max_dq_rad']:.2e} "
                  f"rad, max |dqvel| {v['max_dqvel_rad_s']:.2e} rad/s, contact frames equal "
                  f"{v['contact_frames_equal']} ({v['motions_with_contact']} motions with "
                  "contact)")  # fmt: skip

    # CPU MuJoCo baseline: motion 0, same protocol (warm-up run first, then timed)
    ref = motions(1, args.frames, args.seed)[0]
    cpu_rollout(ref[:2], substeps)
    cpu_q, cpu_ncon, cpu_s = cpu_rollout(ref, substeps)
    cpu_steps = args.frames * substeps
    print(f"CPU MuJoCo mj_step loop (1 motion): {cpu_steps / cpu_s:,.0f} steps/s")

    rows, ok = [], True
    for b in args.batch:
        r = bench(b, args.frames, args.seed, args.repeat, substeps, cfg, backend=args.backend)
        r["qpos0_"] = r["qpos0"]
        dq = float(np.abs(r.pop("qpos0") - cpu_q).max())
        r["mjx_vs_cpu_max_dq_rad"] = dq
        r["speedup_vs_cpu_mj_step"] = r["steps_per_s"] * cpu_s / cpu_steps
        good = r["finite"] and (dq <= 1e-3 or cpu_ncon > 0)
        ok &= good
        print(f"batch {b:6d}: compile {r['compile_s']:6.1f} s | run {r['run_s']:8.3f} s | "
              f"{r['steps_per_s']:12,.0f} steps/s | x{r['speedup_vs_cpu_mj_step']:.2f} vs CPU "
              f"mj_step | finite {r['finite']} | motion 0 vs CPU max |dq| {dq:.2e} rad"
              + ("" if good else "  <-- CHECK FAILED"))  # fmt: skip
        if cfg.split_legs and args.whole_baseline:
            whole = dataclasses.replace(cfg, split_legs=False)
            w = bench(b, args.frames, args.seed, args.repeat, substeps, whole)
            w.pop("qpos0")
            r["whole_model"] = w
            r["speedup_vs_whole"] = r["steps_per_s"] / w["steps_per_s"]
            print(f"              whole model (split_legs=False): compile {w['compile_s']:6.1f} s "
                  f"| run {w['run_s']:8.3f} s | {w['steps_per_s']:12,.0f} steps/s | split "
                  f"x{r['speedup_vs_whole']:.2f}")  # fmt: skip
        if args.backend == "warp":
            j = bench(b, args.frames, args.seed, args.repeat, substeps, cfg, backend="mjx")
            r["mjx_jax_vs_warp_max_dq_rad"] = float(np.abs(j.pop("qpos0") - r["qpos0_"]).max())
            r["mjx_jax"] = j
            r["speedup_vs_mjx_jax"] = r["steps_per_s"] / j["steps_per_s"]
            print(f"              MJX-JAX (same config): compile {j['compile_s']:6.1f} s | run "
                  f"{j['run_s']:8.3f} s | {j['steps_per_s']:12,.0f} steps/s | warp "
                  f"x{r['speedup_vs_mjx_jax']:.2f}")  # fmt: skip
        r.pop("qpos0_", None)
        rows.append(r)
    if cpu_ncon > 0:
        print("note: motion 0 touched itself on CPU MuJoCo; the MJX/CPU comparison is not exact")

    out = {
        "device": f"{dev.platform} {dev.device_kind}",
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "cpus": os.cpu_count(),
        "frames": args.frames,
        "substeps": substeps,
        "solver_iterations": cfg.solver_iterations,
        "ls_iterations": cfg.ls_iterations,
        "contact_friction": cfg.contact_friction,
        "split_legs": cfg.split_legs,
        "backend": args.backend,
        "solver_check": check,
        "backend_check": warp_check,
        "cpu_mj_step": {"steps": cpu_steps, "run_s": cpu_s, "steps_per_s": cpu_steps / cpu_s},
        "mjx": rows,
        "correct": bool(ok and backend_ok),
    }
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0 if ok and backend_ok else 1


if __name__ == "__main__":
    sys.exit(main(ARGS))
