"""How far ``RolloutConfig(split_legs=True)`` moves the rollout, against the whole model.

On the first ``--motions`` benchmark motions of ``benchmarks/bench_rollout.py`` (random arm and
head swings, most with self-contact), runs the whole model and the split (head-and-arms + legs)
each with the library's solver caps (8 / 4) and with MuJoCo's own (100 / 50), and prints the max
|qpos difference| of every pair, split by motions with and without self-contact (per the whole
model at 100 / 50), plus whether the contact frames agree.

    python -m benchmarks.experiments.rollout_split_check [--motions 64] [--frames 15]
                                                         [--device cpu|gpu] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
from pathlib import Path

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--motions", type=int, default=64)
ap.add_argument("--frames", type=int, default=15)
ap.add_argument("--seed", type=int, default=0)
ap.add_argument("--device", choices=("cpu", "gpu"), default="cpu")
ap.add_argument("--json", default=None)
ARGS = ap.parse_args()
os.environ["JAX_PLATFORMS"] = {"cpu": "cpu", "gpu": "cuda"}[ARGS.device]

import jax  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.bench_rollout import motions  # noqa: E402
from jaxproj.eval import rollout  # noqa: E402


def main() -> None:
    q = motions(ARGS.motions, ARGS.frames, ARGS.seed)
    base = rollout.RolloutConfig()
    configs = {
        "whole_8_4": dataclasses.replace(base, split_legs=False),
        "split_8_4": base,
        "whole_100_50": dataclasses.replace(
            base, split_legs=False, solver_iterations=100, ls_iterations=50
        ),
        "split_100_50": dataclasses.replace(base, solver_iterations=100, ls_iterations=50),
    }
    res = {k: rollout.simulate(q, config=c, backend="mjx") for k, c in configs.items()}
    qpos = {k: np.asarray(r.qpos, np.float64) for k, r in res.items()}
    touched = np.asarray(res["whole_100_50"].contact_frames).sum(axis=1) > 0
    dev = jax.devices()[0]
    out: dict = {
        "device": f"{dev.platform} {dev.device_kind}",
        "jax": jax.__version__,
        "motions": ARGS.motions,
        "frames": ARGS.frames,
        "motions_with_contact": int(touched.sum()),
        "pairs": {},
    }
    print(f"{out['device']} | {ARGS.motions} motions x {ARGS.frames} frames, "
          f"{int(touched.sum())} with self-contact")  # fmt: skip
    names = list(configs)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            dq = np.abs(qpos[a] - qpos[b]).max(axis=(1, 2))
            same = np.array_equal(
                np.asarray(res[a].contact_frames), np.asarray(res[b].contact_frames)
            )
            row = {
                "max_dq_rad": float(dq.max()),
                "contact_max_dq_rad": float(dq[touched].max()) if touched.any() else None,
                "free_max_dq_rad": float(dq[~touched].max()) if (~touched).any() else None,
                "motions_over_1e-3_rad": int((dq > 1e-3).sum()),
                "contact_frames_equal": same,
            }
            out["pairs"][f"{a} vs {b}"] = row
            print(f"{a:>13} vs {b:<13}: max |dq| {row['max_dq_rad']:.2e} rad (contact-free "
                  f"{row['free_max_dq_rad']}) | motions > 1e-3 rad: "
                  f"{row['motions_over_1e-3_rad']} | contact frames equal {same}")  # fmt: skip
    if ARGS.json:
        Path(ARGS.json).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
