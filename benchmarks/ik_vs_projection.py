"""The paper's thesis on the NAO: the relaxed projection against the IK it stands in for.

The default model (``jaxproj build`` with no options, or MODEL.npz) and the NAO's closed-form IK
(``jaxproj.robots.nao_h25.ik.solve_driven``, the landmarks' ground truth), on the same held-out
MSR descriptors (subjects 2,4,6,8,10, shuffled, tiled to ``--poses``), both through their
public calls with host arrays in and out: compile (first call) apart, then the median of
repeated calls, each blocked until ready. The projection's answers are checked against the IK
first (median M_avg / p95 M_max, deg, over the 10 driven joints).

    python -m benchmarks.ik_vs_projection [MODEL.npz] [--poses 16384] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import jax
import numpy as np

import jaxproj
from benchmarks.experiments.selection_ab import held_out_queries
from benchmarks.heldout import default_model
from jaxproj.eval import metrics
from jaxproj.robots.nao_h25 import ik
from jaxproj.timing import time_calls


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", nargs="?")
    ap.add_argument("--poses", type=int, default=16384)
    ap.add_argument("--json")
    args = ap.parse_args()
    model = default_model(args.model)
    d = held_out_queries(args.poses)

    def run_ik() -> np.ndarray:
        return np.asarray(ik.solve_driven(d))

    def run_projection() -> np.ndarray:
        return jaxproj.project(model, d, "relaxed")[0]

    out: dict = {
        "device": jax.devices()[0].device_kind,
        "platform": platform.processor() or platform.machine(),
        "model_landmarks": dict(model.landmarks),
        "poses": len(d),
    }
    truth, got = None, None
    for name, fn in (("ik", run_ik), ("relaxed", run_projection)):
        t0 = time.perf_counter()
        answer = fn()  # compiles
        first = time.perf_counter() - t0
        t = time_calls(fn, min_repeats=3, min_time_s=5.0)
        out[name] = {
            "first_call_s": first,
            "us_per_pose": 1e6 * t.median_s / len(d),
            "poses_per_s": len(d) / t.median_s,
            "repeats": t.repeats,
        }
        truth, got = (answer, got) if name == "ik" else (truth, answer)
    m_max, m_avg = metrics.frame_errors(got, truth)
    out["relaxed_vs_ik"] = {"median_m_avg_deg": float(np.median(m_avg)),
                            "p95_m_max_deg": float(np.percentile(m_max, 95))}  # fmt: skip
    out["ik_speedup_over_relaxed"] = out["relaxed"]["us_per_pose"] / out["ik"]["us_per_pose"]
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
