"""The paper's thesis per robot: the relaxed projection against the IK it stands in for.

For ``--robot unitree_g1`` (default) the robot's default model (``BuildConfig(robot=...)`` on the
default training set, ``datasets.training_sequences``; or MODEL.npz) is built on the generic IK
with its collision term (the landmarks' ground truth), then on the same people it never saw —
held-out MSR Action3D subjects 2,4,6,8,10 (every action) and the UTKinect-Action3D people not
in training (every action) — it measures:

* accuracy of the relaxed projection against that IK (median M_avg / p95 M_max, deg, over the
  driven joints), and of the direction-only generic IK (no collision term) against it;
* how far the robot's upper arms and forearms point from the person's (deg, torso frame:
  the robot's directions by forward kinematics; median / p90), for each method;
* self-collision: frames where MuJoCo's own collision detection finds two robot geoms
  touching (penetration > 1 mm), for each method;
* the relaxed projection followed by ``GenericIK.separate`` (the G1: its collision pairs
  pushed apart; ``relaxed_separated``), measured as the rest;
* speed: public calls with host arrays (``robot.solve_ik``, ``jaxproj.project``), compile (the
  first call) apart, then the median of repeated calls, blocked until ready, on ``--poses``
  held-out MSR descriptors, on whatever device JAX runs (named in the output).

For ``--robot nao_h25`` the IK is the closed form, and the generic IK (arms, direction-only;
``tests/robots/test_generic_ik.py``'s table) is timed beside it.

    python -m benchmarks.robot_thesis [--robot unitree_g1] [--model M.npz] [--save M.npz]
        [--poses 8192] [--sets msr_held_out,utkinect_held_out] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from collections.abc import Callable

import jax
import mujoco
import numpy as np

import jaxproj
from jaxproj import robots
from jaxproj.eval import metrics
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.robots.generic_ik import Correspondence, GenericIK
from jaxproj.robots.kinematics import TreeFK
from jaxproj.timing import time_calls

PENETRATION_M = 1e-3
"""A frame is in self-collision when two robot geoms overlap by more than this (MuJoCo)."""


def held_out(robot: robots.Robot, bones: str | tuple[str, ...], people: tuple[int, ...]) -> dict:
    """Descriptors of the people the default model never saw, per set."""
    msr = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    utk = datasets.utkinect_held_out(people, actions=None)
    return {
        "msr_held_out": np.asarray(datasets.valid_descriptors(msr, bones=bones), np.float32),
        "utkinect_held_out": np.asarray(datasets.valid_descriptors(utk, bones=bones), np.float32),
    }


def self_collision_frames(robot: robots.Robot, q: np.ndarray) -> int:
    """Frames of driven angles ``q`` whose robot geoms overlap (MuJoCo, fixed base)."""
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    n = 0
    for row in np.asarray(q):
        data.qpos[:] = np.asarray(robot.driven_to_full(row))
        mujoco.mj_forward(model, data)
        dist = [c.dist for c in data.contact[: data.ncon]]
        n += bool(dist) and min(dist) < -PENETRATION_M
    return n


def arm_direction_errors(
    robot: robots.Robot, corr: Correspondence, bones: str | tuple[str, ...], d: np.ndarray,
    q: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """``(F, rows)`` deg between the robot's arm directions and the person's (torso frame)."""
    from jaxproj.human.skeleton import resolve_bones

    rows = [r for r in corr.pairs if r.bone.startswith(("upper_arm", "forearm"))]
    fk = TreeFK.from_model(
        robot.load_model("fixed"), robot.joint_names, [p for r in rows for p in (r.start, r.end)],
        corr.base,
    )  # fmt: skip
    p = np.asarray(fk.points(np.asarray(robot.driven_to_full(q))), np.float64)
    names = resolve_bones(bones)
    vec = d.reshape(len(d), -1, 3).astype(np.float64)
    out = []
    for k, r in enumerate(rows):
        u = p[:, 2 * k + 1] - p[:, 2 * k]
        h = vec[:, names.index(r.bone)]
        cos = np.sum(u * h, 1) / np.linalg.norm(u, axis=1) / np.linalg.norm(h, axis=1)
        out.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return np.stack(out, axis=1)


def timed(fn: Callable[[], object], n: int) -> dict:
    t0 = time.perf_counter()
    fn()  # compiles
    first = time.perf_counter() - t0
    t = time_calls(fn, min_repeats=3, min_time_s=3.0)
    return {
        "first_call_s": first,
        "us_per_pose": 1e6 * t.median_s / n,
        "poses_per_s": n / t.median_s,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="unitree_g1", choices=robots.names())
    ap.add_argument("--model", help="the robot's model (else built with BuildConfig(robot=...))")
    ap.add_argument("--save", help="write the built model here")
    ap.add_argument("--poses", type=int, default=8192)
    ap.add_argument("--sets", default="msr_held_out,utkinect_held_out",
                    help="which held-out sets to score (comma-separated)")  # fmt: skip
    ap.add_argument("--json")
    args = ap.parse_args()
    robot = robots.get(args.robot)
    t0 = time.perf_counter()
    if args.model:
        model = engine.load(args.model)
    else:
        cfg = engine.BuildConfig(robot=args.robot)
        train = datasets.valid_descriptors(datasets.training_sequences(cfg.utkinect_people),
                                           bones=cfg.bones)  # fmt: skip
        model = engine.build(train, cfg)
        if args.save:
            engine.save(model, args.save)
    build_s = time.perf_counter() - t0
    cfg = model.config
    _write({"model_build_s": build_s}, args.json)
    print(f"model: {model.landmarks} landmarks ({build_s:.0f} s)", file=sys.stderr)
    out: dict = {
        "robot": args.robot,
        "device": jax.devices()[0].device_kind,
        "platform": platform.processor() or platform.machine(),
        "model_landmarks": dict(model.landmarks),
        "model_build_s": build_s if not args.model else None,
        "training_utkinect_people": list(cfg.utkinect_people),
    }
    sets = held_out(robot, cfg.bones, cfg.utkinect_people)
    if args.robot == "unitree_g1":
        assert robot.generic is not None
        corr = robot.generic.correspondence
        direction_only = robot.generic.build(collision=False)
        solve_dir = jax.jit(lambda x: direction_only.solve(x, cfg.bones))
        methods: dict[str, Callable[[np.ndarray], np.ndarray]] = {
            "ik": lambda x: np.asarray(robot.solve_ik(x, cfg.bones)),
            "ik_direction_only": lambda x: np.asarray(solve_dir(x)),
        }
    else:
        from jaxproj.robots.nao_h25 import ik as nao_ik

        corr = nao_ik.ARM_CORRESPONDENCE
        generic = GenericIK.build(robot, corr, chains=robot.chains[1:])
        solve = jax.jit(lambda x: generic.solve(x, cfg.bones))
        head = list(robot.chain_joints(robot.chain("head")))

        def generic_arms(x: np.ndarray) -> np.ndarray:
            """The generic IK's arms; the head by the closed form's rule (not a direction)."""
            q = np.array(solve(x))
            q[:, head] = np.asarray(robot.solve_ik(x, cfg.bones))[:, head]
            return q

        methods = {
            "ik": lambda x: np.asarray(robot.solve_ik(x, cfg.bones)),
            "ik_generic_arms": generic_arms,
        }
    methods["relaxed"] = lambda x: np.asarray(jaxproj.project(model, x, "relaxed")[0])
    if args.robot == "unitree_g1":
        separate = jax.jit(robot.generic.build().separate)
        methods["relaxed_separated"] = lambda x: np.asarray(
            separate(jaxproj.project(model, x, "relaxed")[0])
        )
    for set_name, d in sets.items():
        if set_name not in args.sets.split(","):
            continue
        res: dict = {"frames": len(d)}
        answers = {}
        for name, fn in methods.items():
            t1 = time.perf_counter()
            answers[name] = fn(d)
            print(f"{set_name}: {name} {time.perf_counter() - t1:.1f} s", file=sys.stderr)
        truth = answers["ik"]
        for name, q in answers.items():
            entry: dict = {}
            if name != "ik":
                m_max, m_avg = metrics.frame_errors(q, truth)
                entry["vs_ik_M_avg_median"] = float(np.median(m_avg))
                entry["vs_ik_M_max_p95"] = float(np.percentile(m_max, 95))
                loose = metrics.m_max_without(q, truth, robot=robot)
                entry["vs_ik_M_max_p95_without_loose_joints"] = float(np.percentile(loose, 95))
                per_chain = {}
                for chain in robot.chains:
                    cols = list(robot.chain_joints(chain))
                    c_max, c_avg = metrics.frame_errors(q[:, cols], truth[:, cols])
                    per_chain[chain.name] = [
                        float(np.median(c_avg)),
                        float(np.percentile(c_max, 95)),
                    ]
                entry["vs_ik_per_chain_M_avg_median_M_max_p95"] = per_chain
            arm = arm_direction_errors(robot, corr, cfg.bones, d, q)
            entry["arm_direction_median_deg"] = float(np.median(arm))
            entry["arm_direction_p90_deg"] = float(np.percentile(arm, 90))
            entry["self_collision_frames"] = self_collision_frames(robot, q)
            entry["finite_and_within_limits"] = bool(
                np.isfinite(q).all()
                and ((q >= robot.lower_driven - 1e-6) & (q <= robot.upper_driven + 1e-6)).all()
            )
            res[name] = entry
        out[set_name] = res
        print(set_name, json.dumps(res, indent=1), file=sys.stderr)
        _write(out, args.json)
    msr = sets["msr_held_out"]
    d = np.tile(msr, (args.poses // len(msr) + 1, 1))[: args.poses]
    out["speed"] = {"poses": len(d)}
    for name, fn in methods.items():
        out["speed"][name] = timed(lambda fn=fn: fn(d), len(d))
        print(f"speed: {name} {out['speed'][name]}", file=sys.stderr)
        _write(out, args.json)
    print(json.dumps(out["speed"], indent=1))


def _write(out: dict, path: str | None) -> None:
    """Write what is measured so far (a run cut short keeps it)."""
    if path:
        with open(path, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
