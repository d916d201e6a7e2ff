"""Run by tests/projection/test_sharding.py in a fresh process with 4 forced host devices.

Projects the same queries on one device and over 4 (``engine.project(..., devices=)``), both
ways of spreading a batch (``spread="per_device"``, the default, and ``"shard_map"``), and
inspects the compiled per-device programs of the ``shard_map`` one; prints one JSON object.
"""

import gc
import json
import os
import re
import sys

os.environ["XLA_FLAGS"] = (
    os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
).strip()

import jax  # noqa: E402
import numpy as np  # noqa: E402

from jaxproj.io import datasets  # noqa: E402
from jaxproj.projection import api as engine  # noqa: E402
from jaxproj.projection.config import FullConfig  # noqa: E402
from jaxproj.robots.nao_h25 import ik  # noqa: E402


def _model() -> engine.Model:
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1]))
    uniq = np.unique(train, axis=0)
    idx = np.sort(np.random.default_rng(0).choice(len(uniq), 120, replace=False))
    human = uniq[idx].astype(np.float32)
    robot = np.asarray(ik.solve_driven(human), np.float32)
    cfg = engine.BuildConfig(k=16, hidden=32)
    return engine.from_landmarks(human, robot, cfg)


def _flops(compiled) -> float:
    cost = compiled.cost_analysis()
    cost = cost[0] if isinstance(cost, list) else cost
    return float(cost["flops"])


def main() -> None:
    devices = jax.devices()
    model = _model()
    test = datasets.valid_descriptors(datasets.msr_action3d(subjects=[2], actions=[1, 2]))
    h = np.ascontiguousarray(test[:203])  # not a multiple of the batch: the last one is padded
    out: dict = {"devices": [str(d) for d in devices]}
    # fixed-step Adam: the same arithmetic on one device and on four, up to fusion ulps (a
    # converged solve stops where its tolerance says, which another rounding can move)
    full = FullConfig(solver="adam", iterations=3)
    for objective in ("relaxed", "full"):
        kw = {"n_l": 4, "n_m": 4, "full": full, "batch_size": 64}
        r1, v1 = engine.project(model, h, objective, **kw)
        r4, v4 = engine.project(model, h, objective, devices=devices, spread="shard_map", **kw)
        rp, vp = engine.project(model, h, objective, devices=devices, **kw)
        out[objective] = {
            "per_device": {
                "shape": list(rp.shape),
                "max_abs_diff": float(np.abs(r1 - rp).max()),
                "bit_identical": bool(np.array_equal(r1, rp) and np.array_equal(v1, vp)),
            },
            "shape": list(r4.shape),
            "max_abs_diff": float(np.abs(r1 - r4).max()),
            "bit_identical": bool(np.array_equal(r1, r4) and np.array_equal(v1, v4)),
            "angles_identical": bool(np.array_equal(r1, r4)),
            "value_max_rel_diff": float(np.max(np.abs(v1 - v4) / np.maximum(np.abs(v1), 1e-30))),
        }
        # the compiled programs of one 64-query batch: one device vs split over four
        p = model.projector
        chunk = jax.device_put(h[:64], devices[0])
        one = engine.project_chunk.lower(p, chunk, objective, 4, 4, full).compile()
        mesh = engine.placement(devices, 64)
        sharded_in = jax.device_put(
            h[:64], jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
        )
        lowered = engine.project_sharded.lower(
            p, sharded_in, mesh=mesh, objective=objective, n_l=4, n_m=4, full=full
        )
        four = lowered.compile()
        text = four.as_text()
        # zero-sized arrays in the program as lowered: under shard_map, XLA's GPU compiler
        # (Shardy, jax 0.11.2) crashes on any (benchmarks/experiments/pallas_shard_map.py)
        zero_sized = sorted(set(re.findall(r"\b[a-z]+[0-9]*\[(?:[0-9]+,)*0(?:,[0-9]+)*\]",
                                           lowered.as_text(dialect="hlo"))))  # fmt: skip
        out[objective].update(
            zero_sized=zero_sized,
            flops_one=_flops(one),
            flops_four=_flops(four),
            collectives=[
                op
                for op in ("all-gather", "all-reduce", "all-to-all", "collective-permute")
                if op in text
            ],
        )
    # the projector's copies on the devices are made once and dropped with the projector
    copies = dict(engine._COPIES)
    engine.project(model, h, "relaxed", n_l=4, n_m=4, batch_size=64, devices=devices)
    out["copies"] = {
        "after_calls": len(copies),
        "reused": all(engine._COPIES[k] is v for k, v in copies.items()),
    }
    # so is the padding query, made when a batch is first short
    out["fillers"] = {"after_calls": len(engine._FILLERS)}
    del model, p
    gc.collect()
    out["copies"]["after_del"] = len(engine._COPIES)
    out["fillers"]["after_del"] = len(engine._FILLERS)
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
