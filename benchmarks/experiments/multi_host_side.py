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
``--timeline``: only ``project`` on 1 and N devices, traced (``timeline_1`` / ``timeline_N``:
per device thread, when its last call was dispatched, how long it waited for answers and how
long it spent copying them into ``project``'s arrays, and when it ended, all from the call's
start), and ``project`` with its answer arrays made and touched beforehand
(``project_1_touched`` / ``project_N_touched``: what the first writes into fresh memory cost).
Each figure is printed on stderr as it is measured.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
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

ROUNDS = 7


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
    ap.add_argument("--timeline", action="store_true")
    ap.add_argument("--trace", default=None, help="--timeline: a profile of one N-device call")
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
    if args.timeline:
        return _done(_timeline(out, model, h, devs, args.trace), args.json)
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


def _timeline(out: dict, model, h: np.ndarray, devs: list, trace: str | None) -> dict:
    """``--timeline``'s figures (module doc), into ``out``."""
    events: list[tuple[str, str, float]] = []
    chunk, put = engine.project_chunk, engine._Answers.put

    def traced_chunk(*a, **k):
        r = chunk(*a, **k)
        events.append((threading.current_thread().name, "dispatched", time.perf_counter()))
        return r

    def traced_put(self, start, o):
        name = threading.current_thread().name
        t0 = time.perf_counter()
        jax.block_until_ready(o)
        for x in o:
            np.asarray(x)
        t1 = time.perf_counter()
        put(self, start, o)
        events.extend([(name, "wait", t1 - t0), (name, "copy", time.perf_counter() - t1)])

    def summary(t0: float, t_end: float) -> dict:
        rows: dict = {}
        for name, what, v in events:
            r = rows.setdefault(name, {"last_dispatch_s": 0.0, "wait_s": 0.0, "copy_s": 0.0})
            if what == "dispatched":
                r["last_dispatch_s"] = round(v - t0, 4)
            else:
                r[f"{what}_s"] = round(r[f"{what}_s"] + v, 4)
        return {"total_s": round(t_end - t0, 4), "threads": rows}

    engine.project_chunk, engine._Answers.put = traced_chunk, traced_put
    try:
        for key, d in (("timeline_1", None), ("timeline_N", devs)):
            engine.project(model, h, "relaxed", devices=d)  # compiled, copies made
            events.clear()
            t0 = time.perf_counter()
            engine.project(model, h, "relaxed", devices=d)
            out[key] = summary(t0, time.perf_counter())
            _say(out)
    finally:
        engine.project_chunk, engine._Answers.put = chunk, put
    if trace:  # the JAX profiler (a Perfetto trace too) around one N-device call
        with jax.profiler.trace(trace, create_perfetto_trace=True):
            engine.project(model, h, "relaxed", devices=devs)
    touch = engine._Answers.touch

    def timed(d, fresh: bool) -> float:
        engine._Answers.touch = touch if not fresh else lambda self, a, b: None
        try:
            t0 = time.perf_counter()
            engine.project(model, h, "relaxed", devices=d)
            return time.perf_counter() - t0
        finally:
            engine._Answers.touch = touch

    runs: dict[str, list[float]] = {"project_1": [], "project_N": [], "project_1_fresh": [],
                                    "project_N_fresh": []}  # fmt: skip
    for _ in range(ROUNDS):  # interleaved: a drift of the machine moves both alike
        runs["project_1"].append(timed(None, False))
        runs["project_N"].append(timed(devs, False))
        runs["project_1_fresh"].append(timed(None, True))
        runs["project_N_fresh"].append(timed(devs, True))
    for key, v in runs.items():
        out[key] = float(np.median(v))
        out[key + "_runs"] = [round(x, 4) for x in v]
    out["project_speedup"] = out["project_1"] / out["project_N"]
    out["fresh_speedup"] = out["project_1_fresh"] / out["project_N_fresh"]
    out["speedup_runs"] = [round(x / y, 3) for x, y in zip(runs["project_1"], runs["project_N"],
                                                          strict=True)]  # fmt: skip
    return out


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
