"""Where the time of the relaxed projection on several GPUs goes (issue 61): ``project`` on one
device and on N, against the same work with the host left out step by step.

    python -m benchmarks.experiments.multi_host_side [--robot nao_h25] [--model M.npz]
        [--queries 4194304] [--project-only] [--json OUT]

The robot's default model (or ``--model``), held-out MSR queries tiled to ``--queries`` (as
``benchmarks.bench_multi_device``), relaxed L = M = 10, the default batch of one device
(``B``) per device. Timed (median of 3 after a first call):

- ``project_1`` / ``project_N``: ``jaxproj.project`` on 1 / N devices (what a user gets);
- ``device_1`` / ``device_N``: the shares already on their devices and the projector copied
  once; each device's host thread runs ``project_chunk`` on its shares and waits for the last
  answer on the device (no transfer either way);
- ``in_N``: as ``device_N`` with each share sent from the host in the loop;
- ``inout_N``: as ``in_N`` with each answer fetched to the host (no writing into one array);
- ``copy_projector_s``: one ``device_put`` of the projector to the second device;
- ``check_isfinite_s`` / ``check_rows_s``: the host's finiteness check of the queries, as
  ``project`` made it before (``np.isfinite(h).all(axis=1)``) and as it makes it now
  (``api._finite_rows``), and ``project_1_isfinite`` / ``project_N_isfinite``: ``project`` with
  the check of before put back (the baseline, in the same run).

``--project-only``: only the checks and the ``project`` timings (a machine with little time).
Each figure is printed on stderr as it is measured.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import jax
import numpy as np

from benchmarks.bench_projection import TEST_SUBJECTS, default_model, queries, shuffled
from benchmarks.harness import header
from jaxproj import robots
from jaxproj.io import datasets
from jaxproj.projection import api as engine


def _median(fn, repeats: int = 3) -> float:
    fn()
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t0)
    return float(np.median(runs))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default=robots.DEFAULT, choices=robots.names())
    ap.add_argument("--model", help="the robot's model (else built as jaxproj build builds it)")
    ap.add_argument("--queries", type=int, default=1 << 22)
    ap.add_argument("--project-only", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    devs = jax.devices()
    k = len(devs)
    t0 = time.perf_counter()
    model = default_model(args.robot, args.model)
    out: dict = {"header": header(devs[0]), "robot": args.robot, "devices": k,
                 "model_s": time.perf_counter() - t0, "queries": args.queries}  # fmt: skip
    test_seqs = datasets.msr_action3d(subjects=list(TEST_SUBJECTS))
    test = shuffled(np.asarray(datasets.valid_descriptors(test_seqs, bones=model.config.bones)))
    h = queries(test, args.queries)
    b = engine.default_batch_size(None)
    kw = {"objective": "relaxed", "n_l": 10, "n_m": 10, "full": engine.FullConfig()}
    p = model.projector

    t0 = time.perf_counter()
    jax.block_until_ready(jax.device_put(p, devs[-1]))
    out["copy_projector_s"] = time.perf_counter() - t0
    copies = [jax.device_put(p, d) for d in devs]
    out["check_isfinite_s"] = _median(lambda: np.isfinite(h).all(axis=1))
    out["check_rows_s"] = _median(lambda: engine._finite_rows(h))
    out["model_s"] = round(out["model_s"], 1)
    _say(out)
    out["project_1"] = _median(lambda: engine.project(model, h, "relaxed"))
    _say(out)
    out["project_N"] = _median(lambda: engine.project(model, h, "relaxed", devices=devs))
    _say(out)
    now = engine._finite_rows
    engine._finite_rows = lambda x: np.isfinite(x).all(axis=1)  # the check of before
    try:
        out["project_1_isfinite"] = _median(lambda: engine.project(model, h, "relaxed"))
        _say(out)
        out["project_N_isfinite"] = _median(
            lambda: engine.project(model, h, "relaxed", devices=devs)
        )
        _say(out)
    finally:
        engine._finite_rows = now
    out["project_speedup"] = out["project_1"] / out["project_N"]
    out["project_isfinite_speedup"] = out["project_1_isfinite"] / out["project_N_isfinite"]
    if args.project_only:
        return _done(out, args.json)
    shares = [[h[s + i * b : s + (i + 1) * b] for s in range(0, len(h), b * k)] for i in range(k)]
    on_dev = [[jax.device_put(x, devs[i]) for x in shares[i]] for i in range(k)]
    one = [jax.device_put(h[s : s + b], devs[0]) for s in range(0, len(h), b)]

    def device_only(i: int, xs) -> None:
        last = [engine.project_chunk(copies[i], x, **kw) for x in xs]
        jax.block_until_ready(last)

    def with_in(i: int) -> None:
        last = [engine.project_chunk(copies[i], jax.device_put(x, devs[i]), **kw)
                for x in shares[i]]  # fmt: skip
        jax.block_until_ready(last)

    def with_inout(i: int) -> None:
        outs = []
        for x in shares[i]:
            o = engine.project_chunk(copies[i], jax.device_put(x, devs[i]), **kw)
            for a in o:
                a.copy_to_host_async()
            outs.append(o)
        [(np.asarray(r), np.asarray(v)) for r, v in outs]

    def threads(fn) -> None:
        with ThreadPoolExecutor(max_workers=k) as pool:
            list(pool.map(fn, range(k)))

    out["device_1"] = _median(lambda: device_only(0, one))
    out["device_N"] = _median(lambda: threads(lambda i: device_only(i, on_dev[i])))
    out["in_N"] = _median(lambda: threads(with_in))
    out["inout_N"] = _median(lambda: threads(with_inout))
    out["device_speedup"] = out["device_1"] / out["device_N"]
    return _done(out, args.json)


def _say(out: dict) -> None:
    print(f"multi_host_side: {out}", file=sys.stderr, flush=True)


def _done(out: dict, path: str | None) -> int:
    text = json.dumps(out, indent=1, default=float)
    print(text)
    if path:
        Path(path).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
