"""Scale-out: the same public calls on one device and spread over several, in one run.

    python -m benchmarks.bench_multi_device [--robot nao_h25] [--model M.npz] [--devices all]
        [--spread per_device|shard_map] [--impl auto] [--queries 4194304]
        [--full-queries 262144] [--rollout-batch 32768] [--skip full,rollout] [--json OUT]

The robot's default model (``jaxproj build``'s: ``BuildConfig(robot=...)`` on
``datasets.training_sequences``; or ``--model``). For 1 device and for the N given
(``engine.resolve_devices``): ``jaxproj.project`` on a host array of ``--queries`` held-out MSR
Action3D descriptors (subjects 2,4,6,8,10, tiled; relaxed L = M = 10) and of ``--full-queries``
(full, exact), spread over the N devices as ``--spread`` says (``project``'s ``spread``), and
``rollout.simulate`` on ``--rollout-batch`` synthetic motions (NAO; 30 frames, 33 physics steps
each); first calls (compilation) timed apart, then the median of 3 calls. Answers are compared
between 1 and N devices (relaxed: bit-identical expected; full: max difference in degrees;
rollout: max |qpos| difference). The compiled program of one batch is inspected on 1 and on N
devices: XLA's per-device FLOP count and any collective in its HLO (the batch is one sub-batch
of the one-device program, so that no ``lax.map`` loop hides trips from the count).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

from benchmarks import bench_rollout
from benchmarks.bench_projection import TEST_SUBJECTS, default_model, queries, shuffled
from benchmarks.harness import header
from jaxproj import robots
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig
from jaxproj.robots.nao_h25 import robot

COLLECTIVES = ("all-gather", "all-reduce", "all-to-all", "collective-permute", "reduce-scatter")


def _median_call(fn, repeats: int = 3) -> tuple[float, float, object]:
    t0 = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        runs.append(time.perf_counter() - t0)
    return first, float(np.median(runs)), out


def _program(
    model, h: np.ndarray, objective: str, devices: list | None, batch: int, spread: str, impl: str
) -> dict:
    """XLA's view of the compiled program of one ``batch``-query call on ``devices`` (per
    device: ``per_device`` runs the one-device program on ``batch / N`` queries)."""
    p = model.projector
    full = FullConfig()
    impl = engine.resolve_impl(impl, devices)
    if devices is None or spread == "per_device":
        share = batch // len(devices or [0])
        x = jax.device_put(h[:share])
        compiled = engine.project_chunk.lower(p, x, objective, 10, 10, full, impl).compile()
    else:
        mesh = engine._placement(devices, batch)
        x = jax.device_put(
            h[:batch], jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
        )
        compiled = engine.project_sharded.lower(
            p, x, mesh=mesh, objective=objective, n_l=10, n_m=10, full=full, impl=impl
        ).compile()
    cost = compiled.cost_analysis()
    cost = cost[0] if isinstance(cost, list) else cost
    text = compiled.as_text()
    return {
        "batch": batch,
        "flops_per_device": float(cost.get("flops", float("nan"))),
        "collectives": [op for op in COLLECTIVES if op in text],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default=robots.DEFAULT, choices=robots.names())
    ap.add_argument("--model", help="the robot's model (else built as jaxproj build builds it)")
    ap.add_argument("--devices", default="all")
    ap.add_argument("--spread", default="per_device", choices=("per_device", "shard_map"))
    ap.add_argument("--impl", default="auto", help="project's impl: auto, xla or pallas")
    ap.add_argument("--queries", type=int, default=1 << 22)
    ap.add_argument("--full-queries", type=int, default=1 << 18)
    ap.add_argument("--rollout-batch", type=int, default=32768)
    ap.add_argument("--json", default=None)
    ap.add_argument("--skip", default="",
                    help="comma-separated parts to skip: relaxed,full,rollout")  # fmt: skip
    args = ap.parse_args(argv)
    skip = {x for x in args.skip.split(",") if x}
    many = engine.resolve_devices(args.devices)
    if not many:
        print("bench_multi_device: needs more than one JAX device", file=sys.stderr)
        return 2
    log = lambda s: print(s, file=sys.stderr, flush=True)  # noqa: E731
    out: dict = {
        "header": header(jax.devices()[0]),
        "devices": [str(d) for d in many],
        "robot": args.robot,
        "spread": args.spread,
        "impl": str(engine.resolve_impl(args.impl, many)),
    }

    def save() -> None:  # after every part: a crash later keeps what was measured
        if args.json:
            Path(args.json).write_text(json.dumps(out, indent=1, default=float))

    if {"relaxed", "full"} - skip:
        _projection(args, many, out, log, save, skip)
    if "rollout" not in skip:
        _rollout(args, many, out, log)
        save()
    print(json.dumps(out, indent=1, default=float))
    return 0


def _projection(args, many, out, log, save, skip: set[str]) -> None:
    t0 = time.perf_counter()
    model = default_model(args.robot, args.model)
    out["landmarks"] = model.landmarks
    out["model_s"] = time.perf_counter() - t0
    log(f"model: {model.landmarks} landmarks in {out['model_s']:.0f} s")
    test_seqs = datasets.msr_action3d(subjects=list(TEST_SUBJECTS))
    test = shuffled(np.asarray(datasets.valid_descriptors(test_seqs, bones=model.config.bones)))
    for objective, n_q in (("relaxed", args.queries), ("full", args.full_queries)):
        if objective in skip:
            continue
        h = queries(test, n_q)
        rec: dict = {"queries": n_q}
        answers = {}
        # the programs are compared on one batch small enough to be a single vmapped sub-batch
        # on one device (XLA's cost analysis counts a lax.map loop's body once, not per trip)
        program_batch = engine.sub_batch(
            model.projector, objective, 10, 10, engine.default_batch_size(None)
        )
        for label, devs in (("one", None), ("many", many)):
            first, sec, (r, _) = _median_call(
                lambda devs=devs, h=h, o=objective: engine.project(
                    model, h, o, devices=devs, spread=args.spread, impl=args.impl
                )
            )
            answers[label] = r
            rec[label] = {
                "devices": len(devs or [0]),
                "first_call_s": first,
                "call_s": sec,
                "poses_per_s": n_q / sec,
                "batch_size": engine.default_batch_size(devs),
                "program": _program(
                    model, h, objective, devs, program_batch, args.spread, args.impl
                ),
            }
            log(f"{objective} on {rec[label]['devices']} device(s): {n_q / sec:.4g} poses/s")
        rec["speedup"] = rec["one"]["call_s"] / rec["many"]["call_s"]
        rec["bit_identical"] = bool(np.array_equal(answers["one"], answers["many"]))
        rec["max_abs_diff_deg"] = float(np.degrees(np.abs(answers["one"] - answers["many"]).max()))
        out[objective] = rec
        save()


def _rollout(args, many, out, log) -> None:
    substeps = round((1.0 / 15.0) / robot.load_model("fixed").opt.timestep)
    ro: dict = {"batch": args.rollout_batch, "frames": 30, "substeps": substeps}
    qpos = {}
    for label, devs in (("one", None), ("many", many)):
        r = bench_rollout.bench(args.rollout_batch, 30, 0, 3, substeps, devices=devs)
        qpos[label] = r.pop("qpos0")
        ro[label] = {"devices": len(devs or [0]), **r}
        log(f"rollout on {ro[label]['devices']} device(s): {r['steps_per_s']:.4g} steps/s")
    ro["speedup"] = ro["many"]["steps_per_s"] / ro["one"]["steps_per_s"]
    ro["motion0_max_dq_rad"] = float(np.abs(qpos["one"] - qpos["many"]).max())
    out["rollout"] = ro


if __name__ == "__main__":
    sys.exit(main())
