"""The full objective, converged and fast: issue 30's table, on the default model.

    python -m benchmarks.full_objective [--model P.npz] [--speed-queries 262144]
        [--ref-queries 200] [--workers N] [--accuracy] [--json OUT]

On the default model (``BuildConfig()`` on MSR training subjects 1,3,5,7,9 unless ``--model``),
L = M = 10, queries from the held-out MSR subjects 2,4,6,8,10 (a fixed shuffle, seed 0):

* convergence: the engine's answers (public ``jaxproj.project``, ``NEWTON`` (recorded as
  ``newton_default``: it was ``FullConfig()`` when measured) and ``ADAM_30``) against the
  float64 reference's converged solve of the same problems
  (``jaxproj.testing.StackedReference``, ``solver="newton"``) on ``--ref-queries`` poses: the
  share within 0.1 deg on every joint, and the share whose objective value is within
  ``1 + 1e-4`` of the reference's (the engine's value is its own float32 evaluation);
* stability: one held-out recording projected, and again with every joint position moved by
  one float32 ulp (``np.nextafter`` away from zero): the largest change of any answer (deg);
* speed: the public ``jaxproj.project`` on a host array of ``--speed-queries`` descriptors
  (compiled first, timed apart, best of 3), full ``NEWTON``, ``ADAM_30`` (``FullConfig()``)
  and relaxed as the baseline, each named;
* ``--accuracy``: every reading of the full objective, converged (weighted / min, with and
  without the candidate as a vertex), against the IK on held-out MSR (arm actions) and
  UTKinect (upper body), unsmoothed and default output (offline smoother + feasibility),
  beside relaxed (``jaxproj.eval.evaluate``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import jax
import numpy as np

from benchmarks import heldout
from jaxproj.human.descriptors import valid_descriptors
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import ADAM_30, FULL_READINGS, NEWTON

READINGS = {name.replace("+", "_with_"): cfg for name, cfg in FULL_READINGS.items()}
"""``config.FULL_READINGS`` under the names this benchmark's JSON uses."""

_REF = None


def _ref_init(path: str) -> None:
    global _REF
    from jaxproj.testing import StackedReference

    _REF = StackedReference(engine.load(path).projector)


def _ref_one(h: np.ndarray) -> tuple[np.ndarray, float]:
    assert _REF is not None
    return _REF.project(h, "full", 10, 10, NEWTON)


def reference(model_path: str, h: np.ndarray, workers: int) -> tuple[np.ndarray, np.ndarray]:
    """The float64 converged answers ``(Q, n)`` and objective values ``(Q,)``."""
    ctx = multiprocessing.get_context("spawn")  # JAX's threads do not survive a fork
    before = os.environ.get("JAX_PLATFORMS")
    os.environ["JAX_PLATFORMS"] = "cpu"  # the workers load the model; keep them off the GPU
    try:
        with ProcessPoolExecutor(
            workers, ctx, initializer=_ref_init, initargs=(model_path,)
        ) as pool:
            out = list(pool.map(_ref_one, h, chunksize=4))
    finally:
        if before is None:
            del os.environ["JAX_PLATFORMS"]
        else:
            os.environ["JAX_PLATFORMS"] = before
    return np.stack([r for r, _ in out]), np.array([f for _, f in out])


def convergence(model: engine.Model, h: np.ndarray, want_r: np.ndarray, want_f: np.ndarray) -> dict:
    out = {}
    for name, cfg in (("newton_default", NEWTON), ("adam_30", ADAM_30)):
        r, f = engine.project(model, h, "full", full=cfg)
        diff = np.degrees(np.abs(r - want_r)).max(axis=1)
        ratio = f / np.maximum(want_f, 1e-30)
        out[name] = {
            "within_0.1_deg": float(np.mean(diff <= 0.1)),
            "diff_deg_p99": float(np.quantile(diff, 0.99)),
            "diff_deg_max": float(diff.max()),
            "objective_ratio_median": float(np.median(ratio)),
            "objective_within_1e-4": float(np.mean(ratio <= 1 + 1e-4)),
            "objective_ratio_min": float(ratio.min()),
        }
    return out


def ulp_stability(model: engine.Model) -> dict:
    """Largest answer change (deg) when every joint position of a held-out recording moves by
    one float32 ulp."""
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    pos = np.asarray(seq.positions, np.float32)[np.asarray(seq.valid, bool)]
    nudged = np.nextafter(pos, np.copysign(np.inf, pos)).astype(np.float32)
    out = {}
    for name, cfg in (("newton_default", NEWTON), ("adam_30", ADAM_30)):
        a, _ = engine.project(model, valid_descriptors(pos), "full", full=cfg)
        b, _ = engine.project(model, valid_descriptors(nudged), "full", full=cfg)
        out[name] = float(np.degrees(np.abs(a - b)).max())
    out["frames"] = int(len(pos))
    return out


def speed(model: engine.Model, h: np.ndarray) -> dict:
    out = {"queries": int(len(h)), "device": str(jax.devices()[0].device_kind)}
    for name, objective, cfg in (
        ("relaxed", "relaxed", None),
        ("full_newton_default", "full", NEWTON),
        ("full_adam_30", "full", ADAM_30),
    ):
        t0 = time.perf_counter()
        engine.project(model, h[: min(len(h), 4096)], objective, full=cfg)  # compile
        compile_s = time.perf_counter() - t0
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            engine.project(model, h, objective, full=cfg)  # host arrays back: blocks
            best = min(best, time.perf_counter() - t0)
        out[name] = {
            "poses_per_s": len(h) / best,
            "us_per_pose": best / len(h) * 1e6,
            "first_call_s": compile_s,
        }
        print(name, out[name], file=sys.stderr, flush=True)
    return out


def accuracy(model: engine.Model) -> dict:
    from jaxproj.eval import evaluate as ev
    from jaxproj.motion.offline import OFFLINE_SMOOTHING

    out: dict = {}
    for split, seqs in heldout.splits().items():
        data = ev.prepare(seqs)
        rows: dict = {}
        for name, cfg in READINGS.items():
            r = ev.evaluate(model, data, ["relaxed", "full"], full=cfg, smoothing=OFFLINE_SMOOTHING)
            for method in ("relaxed", "full"):
                key = "relaxed" if method == "relaxed" else f"full_{name}"
                if key in rows:
                    continue
                after = r["feasibility"][method]["after_errors"]
                rows[key] = {
                    "unsmoothed_M_avg_median": r["unsmoothed"][method]["M_avg"]["median"],
                    "unsmoothed_M_max_p95": r["unsmoothed"][method]["M_max"]["p95"],
                    "default_output_M_avg_median": after["M_avg"]["median"],
                    "default_output_M_max_p95": after["M_max"]["p95"],
                }
            print(split, name, rows[f"full_{name}"], file=sys.stderr, flush=True)
        out[split] = {"frames": r["valid_frames"], "rows": rows}
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", help="projector .npz (default: build the default model)")
    p.add_argument("--speed-queries", type=int, default=1 << 18)
    p.add_argument("--ref-queries", type=int, default=200)
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--accuracy", action="store_true", help="also every reading vs the IK")
    p.add_argument("--json", help="write the results here")
    args = p.parse_args(argv)
    model_path = args.model or "/tmp/jaxproj_default_model.npz"
    model = heldout.default_model(args.model, save=None if args.model else model_path)
    test = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS))
    test = test[np.random.default_rng(0).permutation(len(test))]
    out: dict = {"landmarks": model.landmarks, "L": 10, "M": 10}
    if args.ref_queries:
        h = test[: args.ref_queries]
        t0 = time.perf_counter()
        want_r, want_f = reference(model_path, h, args.workers)
        out["reference_s"] = time.perf_counter() - t0
        out["convergence"] = convergence(model, h, want_r, want_f)
        out["convergence"]["queries"] = int(len(h))
        print(out["convergence"], file=sys.stderr, flush=True)
        out["ulp_stability_deg"] = ulp_stability(model)
        print(out["ulp_stability_deg"], file=sys.stderr, flush=True)
    if args.speed_queries:
        h = np.resize(test, (args.speed_queries, test.shape[1]))
        out["speed"] = speed(model, h)
    if args.accuracy:
        out["accuracy"] = accuracy(model)
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
