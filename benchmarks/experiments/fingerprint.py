"""Fingerprint of every answer (hashes of exact bytes): the 0.2.0 refactor's bit-identity check.

    python -m benchmarks.experiments.fingerprint OUT.json        # from the repository root

Builds a small model (MSR subjects 1, 3, every 4th frame, 120 landmarks), saves it, projects
held-out descriptors (relaxed at L = M = 10 and L = 5, M = 7; full on 64), evaluates two
methods, retargets with the model and with the IK, writes NPZ / CSV / JSON motion files, streams
20 frames and reads the CMU BVH excerpts; writes a SHA-256 prefix of each answer's bytes. The
imports fall back to the 0.1.0 layout, so the same script runs on both sides of the refactor
(``PYTHONPATH=<0.1.0 checkout>``) and ``diff`` compares the two files.
"""

from __future__ import annotations

import glob
import hashlib
import json
import pathlib
import sys
import tempfile

import jax
import numpy as np

try:  # 0.2.0
    from jaxproj import read as read_skeleton
    from jaxproj.eval import evaluate as ev
    from jaxproj.io import datasets
    from jaxproj.io.motion_files import Motion, save_motion
    from jaxproj.motion import streaming
    from jaxproj.motion.retarget import retarget
    from jaxproj.projection import api as engine
except ImportError:  # 0.1.0
    from jaxproj.motion_io import Motion, save_motion
    from jaxproj.readers import read_skeleton
    from jaxproj.retarget import retarget

    from jaxproj import datasets, engine, streaming
    from jaxproj import evaluate as ev

UNTIMED = ("time", "seconds", "per_s", "_us", "rate", "wall_s")


def h(a):
    """``dtype(shape):sha256[:16]`` of an array (a list of them for a tuple)."""
    if isinstance(a, tuple):
        return [h(x) for x in a]
    a = np.ascontiguousarray(np.asarray(a))
    return f"{a.dtype}{a.shape}:" + hashlib.sha256(a.tobytes()).hexdigest()[:16]


def strip(o):
    """``o`` without its timing entries (they change from run to run)."""
    if isinstance(o, dict):
        return {k: strip(v) for k, v in o.items() if not any(s in k for s in UNTIMED)}
    if isinstance(o, list):
        return [strip(v) for v in o]
    return o


def main(path: str) -> dict:
    out: dict = {}
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3]))[::4]
    model = engine.build(train, engine.BuildConfig(landmarks=120))
    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / "m.npz"
        engine.save(model, p)
        out["model_file"] = hashlib.sha256(p.read_bytes()).hexdigest()[:16]
    test_seqs = datasets.msr_action3d(subjects=[2], actions=[1, 2, 3])
    data = ev.prepare(test_seqs)
    q = data.descriptors[data.valid][:600]
    out["relaxed"] = h(engine.project(model, q))
    out["relaxed_L5M7"] = h(engine.project(model, q, n_l=5, n_m=7))
    out["full"] = h(engine.project(model, q[:64], objective="full"))
    rep = ev.evaluate(model, data, methods=ev.METHODS[:2])
    preds, truth = rep.pop("_predictions"), rep.pop("_truth")
    out["evaluate_predictions"] = {k: h(v) for k, v in sorted(preds.items())}
    out["evaluate_truth"] = h(truth)
    rep.pop("devices", None)
    rep = strip(rep)
    out["evaluate"] = hashlib.sha256(
        json.dumps(rep, sort_keys=True, default=str).encode()
    ).hexdigest()[:16]
    seq = test_seqs[0]
    r = retarget(seq.positions, seq.valid, model=model)
    out["retarget_angles"] = h(r.angles)
    out["retarget_ik"] = h(retarget(seq.positions, seq.valid).angles)
    m = Motion(angles=np.asarray(r.angles), times=np.asarray(r.times), valid=np.asarray(r.valid))
    with tempfile.TemporaryDirectory() as d:
        for ext in ("npz", "csv", "json"):
            p = save_motion(pathlib.Path(d) / f"x.{ext}", m)
            out["motion_" + ext] = hashlib.sha256(p.read_bytes()).hexdigest()[:16]
            if ext == "npz":
                z = np.load(p)
                out["motion_npz_arrays"] = {k: h(z[k]) for k in z.files}
    st = streaming.init(model)
    frames = []
    for t in range(20):
        qq, st = streaming.update(model, st, seq.positions[t])
        frames.append(np.concatenate([np.ravel(x) for x in jax.tree_util.tree_leaves(qq)]))
    out["streaming"] = h(np.stack(frames))
    for f in sorted(glob.glob("tests/data/cmu_bvh/*.bvh")):
        rec = read_skeleton(f)
        out["bvh_" + pathlib.Path(f).stem] = [h(rec.positions), h(rec.valid), h(rec.times)]
    pathlib.Path(path).write_text(json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1]), indent=1))
