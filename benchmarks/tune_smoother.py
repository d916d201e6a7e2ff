"""Choose the offline smoother's setting on training people only (leave one subject out).

For each training subject of MSR Action3D (1, 3, 5, 7, 9; arm actions, 15 fps) the default model
(``BuildConfig()``) is built from the other four, and the subject's valid frames are projected
(relaxed, L = M = 10). Those left-out projections then go through the motion pipeline's stages
after the mapping (``evaluate``'s: fill, smooth, clip) with every candidate smoother, and each is
scored against the IK: median / p95 M_avg and M_max (deg, valid frames), the lag
(``metrics.lag_frames``) and the mean squared jerk (rad^2/s^6). The rule: the least median
M_avg among the settings whose jerk is at most the paper smoother's.

    python -m benchmarks.tune_smoother [--cache DIR] [--json OUT]

``--cache`` keeps the five leave-one-out projections (``loso_s<k>.npz``: angles, the objective's
value) so a second run skips the builds (~1 min each on 2 CPU cores). The held-out subjects
(2, 4, 6, 8, 10) and UTKinect are not read.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from jaxproj.eval import evaluate as ev
from jaxproj.eval import metrics
from jaxproj.io import datasets
from jaxproj.motion.offline import OFFLINE_SMOOTHING, OfflineSmoothing
from jaxproj.motion.smoothing import PAPER_SMOOTHING, frame_gains
from jaxproj.projection import api as engine
from jaxproj.robots import get

ACCEL_STDS = (4.0, 5.0, 6.0, 7.0, 8.0, 10.0, 12.0, 15.0, 20.0, 40.0, 80.0, 160.0)
"""Candidate ``accel_std`` (rad/s^2 per sqrt(Hz)) at ``noise_std`` 0.02 rad: only their ratio
shapes the output (module doc of ``jaxproj.motion.offline``)."""


def loso_projections(cache: Path | None) -> dict[int, tuple[ev.EvalData, np.ndarray, np.ndarray]]:
    """Subject -> (its EvalData, (V, n) relaxed angles, (V,) objective values), each subject
    projected by a default model built from the other training subjects."""
    out = {}
    for s in datasets.TRAIN_SUBJECTS:
        data = ev.prepare(datasets.msr_action3d(subjects=[s], actions=datasets.ARM_ACTIONS))
        h = data.descriptors[data.valid]
        path = None if cache is None else cache / f"loso_s{s}.npz"
        if path is not None and path.exists():
            z = np.load(path)
            q, v = z["angles"], z["value"]
        else:
            t0 = time.perf_counter()
            others = [k for k in datasets.TRAIN_SUBJECTS if k != s]
            train = datasets.valid_descriptors(datasets.msr_action3d(subjects=others))
            model = engine.build(train, engine.BuildConfig())
            q, v = engine.project(model, h)
            print(f"subject {s}: model {model.landmarks} from {others}, {len(h)} frames "
                  f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr)  # fmt: skip
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                np.savez(path, angles=q, value=v)
        out[s] = (data, q, v)
    return out


def score(runs, smoothing) -> dict:
    """Pooled scores of one smoother (``None``: unsmoothed) over the left-out subjects."""
    preds, truths, jerk_num, jerk_den = [], [], 0.0, 0
    lag_cost = []
    for data, q, _ in runs.values():
        lengths = np.diff(data.offsets)
        gains, kind = None, "offline"
        if smoothing is not None:
            gains, kind = frame_gains(smoothing, None, lengths), smoothing.kind
        robot = get(data.robot)
        truth_m = ev._per_motion(data, data.truth[data.valid], robot=robot)[0]
        _, sm, _ = ev._per_motion(data, q, gains, robot=robot, smoother=kind)
        flat = np.concatenate([sm[i, :n] for i, n in enumerate(lengths)])[data.valid]
        preds.append(flat)
        truths.append(data.truth[data.valid])
        n_j = sum(max(int(n) - 3, 0) for n in lengths) * sm.shape[2]
        jerk_num += ev.mean_squared_jerk(sm, lengths) * n_j
        jerk_den += n_j
        lag_cost.append((sm, truth_m, lengths, ev.padded_valid(data)))
    m_max, m_avg = metrics.frame_errors(np.concatenate(preds), np.concatenate(truths))
    lags = [metrics.lag_frames(a, b, n, v) for a, b, n, v in lag_cost]
    weights = [int(v.sum()) for *_, v in lag_cost]
    return {
        "M_avg": metrics.describe(m_avg),
        "M_max": metrics.describe(m_max),
        "lag_frames": float(np.average(lags, weights=weights)),
        "jerk": jerk_num / max(jerk_den, 1),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cache", type=Path, help="folder for the leave-one-out projections")
    p.add_argument("--json", type=Path, help="write the results here")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    runs = loso_projections(args.cache)
    rows: dict[str, dict] = {"none": score(runs, None), "paper": score(runs, PAPER_SMOOTHING)}
    for a in ACCEL_STDS:
        rows[f"offline a={a:g}"] = score(runs, OfflineSmoothing(accel_std=a, noise_std=0.02))
    cap = rows["paper"]["jerk"]
    ok = {k: r for k, r in rows.items() if k.startswith("offline") and r["jerk"] <= cap}
    best = min(ok, key=lambda k: ok[k]["M_avg"]["median"]) if ok else None
    print("| smoother | median M_avg | p95 M_avg | median M_max | p95 M_max | lag (frames) | "
          "jerk (rad^2/s^6) |\n|---|---|---|---|---|---|---|")  # fmt: skip
    for k, r in rows.items():
        mark = " (chosen)" if k == best else ""
        print(f"| {k}{mark} | {r['M_avg']['median']:.3f} | {r['M_avg']['p95']:.2f} | "
              f"{r['M_max']['median']:.2f} | {r['M_max']['p95']:.1f} | {r['lag_frames']:+.2f} | "
              f"{r['jerk']:.3g} |")  # fmt: skip
    default = f"offline a={OFFLINE_SMOOTHING.accel_std:g}"
    print(
        f"rule: least median M_avg with jerk <= the paper smoother's ({cap:.3g}): {best}; "
        f"the shipped default is {default}"
    )
    if args.json:
        out = {"rows": rows, "chosen": best, "default": default, "subjects": list(runs),
               "frames": int(sum(len(q) for _, q, _ in runs.values())),
               "wall_s": time.perf_counter() - t0}  # fmt: skip
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
