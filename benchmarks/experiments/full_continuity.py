"""Is the full objective's answer continuous in its input? One float32 ulp on every joint position.

Held-out MSR recordings (``datasets.TEST_SUBJECTS``) are turned into descriptors twice: as
recorded and with every joint coordinate moved by one float32 ulp (``np.nextafter`` toward
+inf). Both go through ``jaxproj.project(model, d, "full")`` (no smoothing, no feasibility
filter: the projection itself), and the per-frame largest joint change is reported, with the
frames that move more than 0.1 deg. For each such frame and chain it says where the answers
parted: which problem (candidate, in human-landmark order) each run answered with, whether the
screen kept other finalists, and the relative gap of the finalists' converged objectives, so
the near-tie rule (``FullConfig.tie_rtol``) can be judged against what it has to absorb. A
frame's change counts as a tie when the two answers' objectives are within ``max(tie_rtol,
1e-3)`` of each other (relative): equally good answers of the objective, whichever is returned.

    python -m benchmarks.experiments.full_continuity MODEL.npz [--subjects 2,4] [--tie-rtol X]
        [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import full as fo
from jaxproj.projection import simplex_newton as sn
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector, candidates
from jaxproj.projection.search import nearest


def _finalists(p: Projector, h: jax.Array, cfg: FullConfig, n_l: int, n_m: int):
    """For one query of one chain: the original indices of the finalists, their converged F
    and poses (the default Newton path of ``full.project_full_one``)."""
    cand = candidates(p, h, n_l)
    ridx, _ = nearest(p.robot, p.robot_sq, cand, n_m)
    prs, w0 = jax.vmap(fo.problems, in_axes=(None, None, 0, 0, None))(p, h, cand, ridx, cfg)
    prs = fo._shared(prs, p, h, cfg)
    solver = sn.gauss_newton(cfg.dec_tol, cfg.step_tol)
    axes = (fo._AXES, 0)
    states = jax.vmap(solver.init, in_axes=axes)(prs, w0)
    states = jax.vmap(lambda pr, s: solver.run(pr, s, cfg.screen), in_axes=axes)(prs, states)
    screen_f = states.d.f
    _, keep = jax.lax.top_k(-screen_f, cfg.finalists)
    prs = fo._batched(prs, lambda a: a[keep])
    states = jax.tree.map(lambda a: a[keep], states)
    states = jax.vmap(lambda pr, s: solver.run(pr, s, cfg.iterations), in_axes=axes)(prs, states)
    return keep, states.d.f, states.d.r, screen_f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--subjects", default="2,4,6,8,10")
    ap.add_argument("--tie-rtol", type=float, default=None)
    ap.add_argument("--json")
    args = ap.parse_args()
    model = engine.load(args.model)
    cfg = FullConfig() if args.tie_rtol is None else FullConfig(tie_rtol=args.tie_rtol)
    subjects = [int(s) for s in args.subjects.split(",")]
    seqs = datasets.msr_action3d(subjects=subjects)
    pos = np.concatenate([s.positions[s.valid] for s in seqs]).astype(np.float32)
    nudged = np.nextafter(pos, np.float32(np.inf))
    d0, ok0 = descriptor(pos)
    d1, ok1 = descriptor(nudged)
    ok = np.asarray(ok0) & np.asarray(ok1)
    d0, d1 = np.asarray(d0)[ok], np.asarray(d1)[ok]
    r0, _ = engine.project(model, d0, "full", full=cfg)
    r1, _ = engine.project(model, d1, "full", full=cfg)
    move = np.degrees(np.abs(r0 - r1)).max(axis=1)
    jumps = np.flatnonzero(move > 0.1)
    sp = model.projector
    lay = sp.layout
    diag = jax.jit(lambda p, h: _finalists(p, h, cfg, 10, 10))
    cases = []
    for i in jumps:
        for c in range(lay.n_chains):
            p = sp.chain(c)
            cols = list(lay.inputs[c])
            a = diag(p, jnp.asarray(d0[i, cols]))
            b = diag(p, jnp.asarray(d1[i, cols]))
            ja = int(fo.pick(a[1], a[0], cfg.tie_rtol))
            jb = int(fo.pick(b[1], b[0], cfg.tie_rtol))
            pa, pb = int(a[0][ja]), int(b[0][jb])
            joints = list(lay.outputs[c])
            dc = float(np.degrees(np.abs(r0[i, joints] - r1[i, joints])).max())
            if dc <= 0.1:
                continue
            fa = np.sort(np.asarray(a[1]))
            cases.append(
                {
                    "frame": int(i),
                    "chain": lay.names[c],
                    "deg": dc,
                    "problem": [pa, pb],
                    "finalists": [sorted(map(int, a[0])), sorted(map(int, b[0]))],
                    "final_gap_rel": float((fa[1] - fa[0]) / max(fa[0], 1e-30)),
                    "f": [float(a[1][ja]), float(b[1][jb])],
                }
            )
    band = max(cfg.tie_rtol, 1e-3)
    for c in cases:  # both answers equally good under the near-tie rule's band
        c["tie"] = bool(abs(c["f"][0] - c["f"][1]) <= band * min(c["f"]))
    kinds = {
        "ties (objectives within the band)": sum(c["tie"] for c in cases),
        "same problem, another minimum": sum(c["problem"][0] == c["problem"][1] for c in cases),
        "other finalists": sum(c["finalists"][0] != c["finalists"][1] for c in cases),
        "same finalists, other pick": sum(
            c["finalists"][0] == c["finalists"][1] and c["problem"][0] != c["problem"][1]
            for c in cases
        ),
    }
    out = {
        "frames": int(len(d0)),
        "tie_rtol": cfg.tie_rtol,
        "max_deg": float(move.max()),
        "frames_over_0.1_deg": int(len(jumps)),
        "median_deg": float(np.median(move)),
        "kinds": kinds,
        "cases": cases,
        "config": dataclasses.asdict(cfg),
    }
    print(json.dumps({k: v for k, v in out.items() if k not in ("cases", "config")}))
    for c in cases[:20]:
        print(c)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
