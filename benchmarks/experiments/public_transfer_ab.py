"""What the public ``jaxproj.project`` adds to the jitted core on host poses, and the batch-by-batch
transfers against one transfer each way (issue 46, item 1).

The default NAO model (built here unless ``--model`` names a file), relaxed L = M = 10,
``--host-poses`` held-out MSR descriptors (subjects 2,4,6,8,10, tiled) as a host NumPy array,
on the default device, in one process:

* ``core``: ``api.project_chunk`` on one default batch already on the device (ns per pose; no
  transfer, no host work);
* ``one_transfer``: the public path before 2026-11-27, re-enacted here step for step: the host's
  finiteness check, the whole array padded to a multiple of the batch on the host, one transfer
  in, one call per batch on device slices, the answers concatenated on the device and one
  transfer out;
* ``per_batch``: today's ``jaxproj.project``: each batch transferred in just before its call and
  its answers' transfer out started just after it (``copy_to_host_async``), only the last batch
  padded.

The stages of ``one_transfer`` are also timed alone (blocked until ready): the host check, the
host padding, the transfer in, the transfer out of the answers. Compile apart (a first call of
each), then ``--rounds`` interleaved rounds, median. Correctness first: both paths' answers equal
bit for bit, and the first ``--check`` poses judged against the float64 reference under the
near-tie rule (``jaxproj.testing.StackedReference.judge``).

    python -m benchmarks.experiments.public_transfer_ab [--model P.npz] [--host-poses 1048576]
        [--rounds 5] [--check 200] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

import jaxproj
from benchmarks import heldout
from benchmarks.harness import report
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.testing import StackedReference

L = M = 10


def one_transfer(model: engine.Model, descriptors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The public path before 2026-11-27 (default batch, one device), step for step."""
    p = model.projector
    h = np.asarray(descriptors, np.float32)
    finite = np.isfinite(h).all(axis=1)
    if not finite.all():
        raise ValueError("non-finite rows")
    batch = engine.default_batch_size(None, len(h))
    pad = (-len(h)) % batch
    if pad:
        h = np.concatenate([h, np.repeat(engine._padding_query(p), pad, axis=0)], axis=0)
    h_dev = jax.device_put(h)
    outs = [engine.project_chunk(p, h_dev[s : s + batch]) for s in range(0, len(h), batch)]
    r = jnp.concatenate([o[0] for o in outs]) if len(outs) > 1 else outs[0][0]
    v = jnp.concatenate([o[1] for o in outs]) if len(outs) > 1 else outs[0][1]
    cut = len(h) - pad
    return np.asarray(r)[:cut], np.asarray(v)[:cut]


def seconds(fn: Callable[[], object]) -> float:
    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model")
    ap.add_argument("--host-poses", type=int, default=1 << 20)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--check", type=int, default=200)
    ap.add_argument("--json")
    args = ap.parse_args()
    t0 = time.perf_counter()
    model = heldout.default_model(args.model)
    p = model.projector
    out: dict = {
        "device": jax.devices()[0].device_kind,
        "host": platform.node(),
        "jax": jax.__version__,
        "model": "default (jaxproj build)" if not args.model else args.model,
        "landmarks": list(p.layout.landmarks),
        "model_s": round(time.perf_counter() - t0, 1),
        "host_poses": args.host_poses,
    }
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    d = datasets.valid_descriptors(seqs, bones=model.config.bones)
    hp = np.resize(d, (args.host_poses, d.shape[1])).astype(np.float32)
    batch = engine.default_batch_size(None, len(hp))
    out["batch"] = batch
    print(json.dumps(out), flush=True)

    # correctness first
    t0 = time.perf_counter()
    r_old, v_old = one_transfer(model, hp)
    out["compile_and_first_call_s"] = round(time.perf_counter() - t0, 2)
    r_new, v_new = jaxproj.project(model, hp)
    out["bitwise_equal"] = bool(np.array_equal(r_old, r_new) and np.array_equal(v_old, v_new))
    ref = StackedReference(p)
    verdicts = [ref.judge(hp[i], r_new[i], L, M, 1e-4) for i in range(args.check)]
    out["judged"] = {v: verdicts.count(v) for v in ("exact", "tie", "differs")}
    print(json.dumps(out), flush=True)

    h_dev = jax.device_put(hp[:batch])
    core = lambda: engine.project_chunk(p, h_dev)  # noqa: E731
    core()
    stages: dict[str, Callable[[], object]] = {
        "host_check": lambda: np.isfinite(hp).all(axis=1).all(),
        "host_pad": lambda: np.concatenate([hp, hp[:1]]),
        "transfer_in": lambda: jax.device_put(hp),
        "transfer_out": lambda: np.asarray(jnp.zeros((len(hp), p.layout.n), jnp.float32)),
    }
    times: dict[str, list[float]] = {k: [] for k in ("core", "one_transfer", "per_batch", *stages)}
    for _ in range(args.rounds):
        times["core"].append(seconds(core) / batch)
        times["one_transfer"].append(seconds(lambda: one_transfer(model, hp)) / len(hp))
        times["per_batch"].append(seconds(lambda: jaxproj.project(model, hp)) / len(hp))
        for k, fn in stages.items():
            times[k].append(seconds(fn) / len(hp))
    out["ns_per_pose"] = {k: round(1e9 * float(np.median(v)), 1) for k, v in times.items()}
    out["poses_per_s"] = {
        k: round(1 / float(np.median(times[k]))) for k in ("core", "one_transfer", "per_batch")
    }
    report(out, args.json)


if __name__ == "__main__":
    jnp.zeros(())  # start the backend before timing anything
    main()
