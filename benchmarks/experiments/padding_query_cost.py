"""What ``project``'s padding query cost per call before it was kept per projector (issue 61):
the query made as before (a slice and a transfer from the device per chain, on every call)
against ``api._padding_query`` now (made once, then read from the projector's entry).

    python -m benchmarks.experiments.padding_query_cost [--json OUT]

A small model of the default robot on given landmark pairs (``from_landmarks``: 120 MSR
Action3D subject-1 descriptors and their IK poses; the cost is a few slices and transfers of
the projector's first landmarks, not a function of the model's size), its projector on the
default device. Timed: ``before_ms`` (median of 50 calls, after one), ``now_first_ms`` (the
first call, which makes the entry), ``now_ms`` (median of 50 later calls); the answers equal.
"""

from __future__ import annotations

import argparse
import sys
import time

import jax
import numpy as np

from benchmarks.harness import report
from jaxproj import robots
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.projector import StackedProjector


def _before(p: engine.AnyProjector) -> np.ndarray:
    """The padding query as ``project`` made it on every call until 2026-11-30."""
    if isinstance(p, StackedProjector):
        q = np.zeros((1, p.layout.m), np.float32)
        for c, cols in enumerate(p.layout.inputs):
            q[0, list(cols)] = np.asarray(p.stack.human[c, 0, : len(cols)])
        return q
    return np.asarray(p.human[:1])


def _ms(fn, n: int = 50) -> float:
    runs = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t0)
    return float(np.median(runs) * 1e3)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    robot = robots.get(robots.DEFAULT)
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1]))
    uniq = np.unique(train, axis=0)
    human = uniq[np.sort(np.random.default_rng(0).choice(len(uniq), 120, replace=False))]
    poses = np.asarray(robot.solve_ik(human), np.float32)
    model = engine.from_landmarks(human.astype(np.float32), poses, engine.BuildConfig())
    p = jax.device_put(model.projector, jax.devices()[0])
    _before(p)  # compiled
    out: dict = {"device": str(jax.devices()[0].device_kind), "jax_version": jax.__version__,
                 "stacked": isinstance(p, StackedProjector),
                 "before_ms": _ms(lambda: _before(p))}  # fmt: skip
    t0 = time.perf_counter()
    first = engine._padding_query(p)
    out["now_first_ms"] = (time.perf_counter() - t0) * 1e3
    out["now_ms"] = _ms(lambda: engine._padding_query(p))
    out["equal"] = bool(np.array_equal(first, _before(p)))
    report(out, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
