"""Is the full objective's answer continuous in its input? One float32 ulp on every joint position.

Held-out MSR recordings (``datasets.TEST_SUBJECTS``) are turned into descriptors twice: as
recorded and with every joint coordinate moved by one float32 ulp (``np.nextafter`` toward
+inf). Both go through ``jaxproj.project(model, d, "full")`` (no smoothing, no feasibility
filter: the projection itself), and the per-frame largest joint change is reported, with the
frames that move more than 0.1 deg.

Each such frame and chain is judged by the engine's own numbers: the experiment runs the
engine's program again (``_diagnosed``: ``api.project_batch``'s batches, sub-batches and
chain ``vmap``, the projector passed as an argument as ``project_chunk`` does; every frame,
so the batches are the engine's) with the chain's objective value, the problem it answered
with and the screen's finalists as extra outputs, and checks that its answers are bitwise the
engine's (``diagnosis_mismatched_rows`` counts the jumping rows where they are not; those are
judged by numbers of another program). A
change is a *tie* when the two answers' objectives are within ``max(tie_rtol, 1e-3)`` of each
other (relative): equally good answers of the objective, whichever is returned. The others are
sorted by where the two runs parted: the same problem ending at another point ("same problem,
another minimum"), the screen keeping other finalists, or the same finalists and another pick.

``--accuracy`` also scores the same configuration against the IK on the held-out MSR arm
actions (subjects 2,4,6,8,10, unsmoothed): median ``M_avg``, p95 ``M_max`` (deg), the median and
mean objective value of the answers, and the wall time; so that a rule is not bought with
accuracy.

    python -m benchmarks.experiments.full_continuity MODEL.npz [--subjects 2,4] [--tie-rtol X]
        [--full KEY=VALUE,...] [--accuracy] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

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
from jaxproj.projection.stacked import StackedProjector


def _one_chain(p: Projector, h: jax.Array, cfg: FullConfig, n_l: int, n_m: int):
    """``full.project_full_one``'s default path (weighted Newton, every problem, the screen)
    for one query of one chain, with what it decided: ``(r, f, problem, finalists)``, the
    answer's problem and the finalists as candidate ranks (finalists padded with ``-1``)."""
    cand = candidates(p, h, n_l)
    ridx, _ = nearest(p.robot, p.robot_sq, cand, n_m)
    prs, w0 = jax.vmap(fo.problems, in_axes=(None, None, 0, 0, None))(p, h, cand, ridx, cfg)
    prs = fo._shared(prs, p, h, cfg)
    n_p = w0.shape[0]
    order = jnp.arange(n_p)
    solver = sn.gauss_newton(cfg.dec_tol, cfg.step_tol, cfg.gap_tol)
    axes = (fo._AXES, 0)
    states = jax.vmap(solver.init, in_axes=axes)(prs, w0)
    states = jax.vmap(lambda pr, s: solver.run(pr, s, cfg.screen), in_axes=axes)(prs, states)
    if cfg.finalists < n_p:
        _, keep = jax.lax.top_k(-states.d.f, cfg.finalists)
        prs = fo._batched(prs, lambda a: a[keep])
        states = jax.tree.map(lambda a: a[keep], states)
        order = order[keep]
    states = jax.vmap(lambda pr, s: solver.run(pr, s, cfg.iterations), in_axes=axes)(prs, states)
    j = fo.pick(states.d.f, order, cfg.tie_rtol)
    fin = jnp.full((n_p,), -1).at[: order.shape[0]].set(order)
    return jnp.clip(states.d.r[j], p.lower, p.upper), states.d.f[j], order[j], fin


def _diagnosed(sp: StackedProjector, d: np.ndarray, cfg: FullConfig):
    """The engine's full projection of ``d (Q, m)`` (``api.project``'s batches and program)
    with per chain: the objective value ``(Q, C)``, the problem ``(Q, C)`` and the finalists
    ``(Q, C, L)``."""
    if cfg.solver != "newton" or cfg.clusters or cfg.objective != "weighted" or not cfg.finalists:
        # (``finalists >= L``: every problem to the end, by the screened path)
        raise SystemExit("the diagnosis mirrors the default path: weighted Newton, finalists > 0")
    lay = sp.layout

    def one(s: StackedProjector, x: jax.Array):
        xs = jnp.concatenate([x, jnp.zeros((1,), x.dtype)])[lay.input_index()]
        r, f, j, fin = jax.vmap(lambda p, y: _one_chain(p, y, cfg, 10, 10))(s.stack, xs)
        return r.reshape(-1)[lay.output_index()], f, j, fin

    batch = engine.default_batch_size(None, len(d))
    sub = engine.sub_batch(sp, "full", 10, 10, batch)

    @jax.jit
    def run(s: StackedProjector, h: jax.Array):
        if sub >= h.shape[0]:
            return jax.vmap(lambda x: one(s, x))(h)
        return jax.lax.map(lambda x: one(s, x), h, batch_size=sub)

    h = np.asarray(d, np.float32)
    pad = (-len(h)) % batch
    h = np.concatenate([h, np.repeat(engine._padding_query(sp), pad, axis=0)], axis=0)
    outs = [run(sp, jnp.asarray(h[i : i + batch])) for i in range(0, len(h), batch)]
    return [np.concatenate([np.asarray(o[k]) for o in outs])[: len(d)] for k in range(4)]


def _accuracy(model: engine.Model, cfg: FullConfig) -> dict:
    """The full objective under ``cfg`` against the IK on held-out MSR arm actions."""
    from jaxproj.eval import evaluate as ev
    from jaxproj.eval.metrics import frame_errors

    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    data = ev.prepare(seqs)
    h, truth = data.descriptors[data.valid], data.truth[data.valid]
    engine.project(model, h[:16], "full", full=cfg)  # compiles (batch 16)
    t0 = time.perf_counter()
    r, f = engine.project(model, h, "full", full=cfg)
    wall = time.perf_counter() - t0
    m_max, m_avg = frame_errors(r, truth)
    return {
        "frames": int(len(h)),
        "median_M_avg": float(np.median(m_avg)),
        "p95_M_max": float(np.quantile(m_max, 0.95)),
        "median_f": float(np.median(f)),
        "mean_f": float(np.mean(f)),
        "wall_s": wall,
    }


def _config(args: argparse.Namespace) -> FullConfig:
    cfg = FullConfig() if args.tie_rtol is None else FullConfig(tie_rtol=args.tie_rtol)
    for item in filter(None, args.full.split(",")):
        key, value = item.split("=")
        kind = type(getattr(cfg, key))
        cfg = dataclasses.replace(cfg, **{key: kind(float(value)) if kind is int else kind(value)})
    return cfg


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--subjects", default="2,4,6,8,10")
    ap.add_argument("--tie-rtol", type=float, default=None)
    ap.add_argument(
        "--full", default="", help="FullConfig fields to change: KEY=VALUE,... (numbers)"
    )
    ap.add_argument("--accuracy", action="store_true", help="also score it against the IK")
    ap.add_argument("--json")
    args = ap.parse_args()
    model = engine.load(args.model)
    cfg = _config(args)
    subjects = [int(s) for s in args.subjects.split(",")]
    seqs = datasets.msr_action3d(subjects=subjects)
    pos = np.concatenate([s.positions[s.valid] for s in seqs]).astype(np.float32)
    nudged = np.nextafter(pos, np.float32(np.inf))
    d0, ok0 = descriptor(pos)
    d1, ok1 = descriptor(nudged)
    ok = np.asarray(ok0) & np.asarray(ok1)
    d0, d1 = np.asarray(d0)[ok], np.asarray(d1)[ok]
    r0, _ = engine.project(model, d0, "full", full=cfg)  # compiles
    t0 = time.perf_counter()
    r1, _ = engine.project(model, d1, "full", full=cfg)
    seconds = time.perf_counter() - t0
    move = np.degrees(np.abs(r0 - r1)).max(axis=1)
    jumps = np.flatnonzero(move > 0.1)
    sp = model.projector
    lay = sp.layout
    # every frame, so that the batches are the engine's
    ra, fa, pa, fin_a = (x[jumps] for x in _diagnosed(sp, d0, cfg))
    rb, fb, pb, fin_b = (x[jumps] for x in _diagnosed(sp, d1, cfg))
    mismatched = int(np.sum(np.any(ra != r0[jumps], axis=1) | np.any(rb != r1[jumps], axis=1)))
    band = max(cfg.tie_rtol, 1e-3)
    cases = []
    for k, i in enumerate(jumps):
        for c in range(lay.n_chains):
            joints = list(lay.outputs[c])
            dc = float(np.degrees(np.abs(r0[i, joints] - r1[i, joints])).max())
            if dc <= 0.1:
                continue
            f = [float(fa[k, c]), float(fb[k, c])]
            finalists = [sorted(int(x) for x in fin[k, c] if x >= 0) for fin in (fin_a, fin_b)]
            cases.append(
                {
                    "frame": int(i),
                    "chain": lay.names[c],
                    "deg": dc,
                    "problem": [int(pa[k, c]), int(pb[k, c])],
                    "finalists": finalists,
                    "f": f,
                    "f_gap_rel": abs(f[0] - f[1]) / max(min(f), 1e-30),
                    # both answers equally good under the near-tie rule's band
                    "tie": bool(abs(f[0] - f[1]) <= band * min(f)),
                }
            )
    other = [c for c in cases if not c["tie"]]
    kinds = {
        "ties (objectives within the band)": sum(c["tie"] for c in cases),
        "not ties": len(other),
        "not ties: same problem, another minimum": sum(
            c["problem"][0] == c["problem"][1] for c in other
        ),
        "not ties: other finalists": sum(c["finalists"][0] != c["finalists"][1] for c in other),
        "not ties: same finalists, other pick": sum(
            c["finalists"][0] == c["finalists"][1] and c["problem"][0] != c["problem"][1]
            for c in other
        ),
    }
    frames_not_tied = len({c["frame"] for c in other})
    out = {
        "frames": int(len(d0)),
        "tie_rtol": cfg.tie_rtol,
        "band": band,
        "max_deg": float(move.max()),
        "frames_over_0.1_deg": int(len(jumps)),
        "frames_over_0.1_deg_not_tied": frames_not_tied,
        "max_deg_not_tied": max((c["deg"] for c in other), default=0.0),
        "median_deg": float(np.median(move)),
        "seconds_second_projection": seconds,
        "device": str(jax.devices()[0].device_kind),
        "diagnosis_mismatched_rows": mismatched,
        "kinds": kinds,
        "cases": cases,
        "config": dataclasses.asdict(cfg),
    }
    if args.accuracy:
        out["accuracy_msr_held_out_arm"] = _accuracy(model, cfg)
    print(json.dumps({k: v for k, v in out.items() if k not in ("cases", "config")}))
    for c in cases:
        print(c)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
