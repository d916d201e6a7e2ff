"""A/B of the relaxed engine's GPU variants on a CUDA GPU (issue 46, item 1), in one run, on
the same model and queries. ``--variants`` names them (the first is the baseline), each a set of
module flags read when a program is traced (``VARIANTS``):

* ``default``: today's engine;
* ``exact_sigmoid``: the back-projection's sigmoid by libdevice's ``expf`` and a full division
  (``backproj_pallas.FAST_SIGMOID = False``; the engine before 2026-11-27);
* ``knn_8x8``: the pruned search's programs of 8 rows and 8 warps for every set (the engine
  before 2026-11-27's ``knn_pallas.prune_shape``);
* ``shared``: the back-projection by ``backproj_shared.back_min_shared`` (one program per query,
  each distinct kernel read once; a negative result, see there).

The run recorded in ``results/backproj_variants_h200.json`` compared ``FAST_SIGMOID`` 0 / 1 with
a second bit, a deferred cross-thread sum, since removed: it was no faster.

The default NAO model (built here unless ``--model`` names a file), relaxed L = M = 10, a
batch of 65,536 held-out MSR descriptors (subjects 2,4,6,8,10, tiled). For each variant
(compile apart; median of ``--repeats`` calls, blocked until ready, ns per pose): the jitted
core (``api.project_batch``'s program, traced afresh) and the back-projection alone (all
chains) on the batch's real candidate rows; then the least deviations' relative difference
from the baseline's, how many answers are bit-identical to the baseline's, and the first
``--check`` poses judged against the float64 reference under the near-tie rule
(``testing.StackedReference.judge``). With ``--public``, the public ``jaxproj.project`` on
1,048,576 host poses (median of 3 calls) for the first and the last variant.

    python -m benchmarks.experiments.backproj_variants_ab [--model P.npz]
        [--variants knn_8x8,default,shared] [--check 500] [--public] [--json OUT]
"""

from __future__ import annotations

import argparse
import platform

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks import heldout
from benchmarks.experiments import backproj_shared
from benchmarks.experiments.selection_ab import (
    BATCH,
    held_out_queries,
    per_pose_ns,
    public_rate,
)
from benchmarks.harness import report
from jaxproj._internal.jit import jit
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import relaxed
from jaxproj.projection.ops import backproj_pallas, knn_pallas, resolve_impl
from jaxproj.testing import StackedReference

L = M = 10

VARIANTS: dict[str, dict[tuple[object, str], object]] = {
    "default": {},
    "exact_sigmoid": {(backproj_pallas, "FAST_SIGMOID"): False},
    "knn_8x8": {
        (knn_pallas, "PRUNE_ROWS"): 8,
        (knn_pallas, "PRUNE_WARPS"): 8,
        (knn_pallas, "PRUNE_SMALL_ROWS"): 8,
        (knn_pallas, "PRUNE_SMALL_WARPS"): 8,
    },
    "shared": backproj_shared.use(),
}
"""Each variant's module flags (``(module, name): value``); the rest keep their defaults."""


def ns_per_pose(fn, args: tuple, repeats: int) -> float:
    """``selection_ab.per_pose_ns`` (compile apart, median of ``repeats``), rounded."""
    return round(per_pose_ns(fn, *args, repeats=repeats), 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--check", type=int, default=500)
    ap.add_argument("--variants", default="knn_8x8,default,shared")
    ap.add_argument("--public", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    model = heldout.default_model(args.model)
    p = model.projector
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    d = datasets.valid_descriptors(seqs, bones=model.config.bones)
    hp = np.resize(d, (BATCH, d.shape[1])).astype(np.float32)
    h = jax.device_put(hp)
    out: dict = {
        "device": jax.devices()[0].device_kind,
        "impl": str(resolve_impl("auto").value),
        "host": platform.node(),
        "jax": jax.__version__,
        "model": args.model or "default (jaxproj build)",
        "landmarks": dict(zip(p.layout.names, map(int, p.layout.landmarks), strict=True)),
        "batch": BATCH,
    }
    impl = resolve_impl("auto")
    dims = relaxed.backward_widths(p)
    answers, devs = {}, {}
    names = args.variants.split(",")
    hosts = held_out_queries(2**20) if args.public else None
    for name in names:
        flags = VARIANTS[name]
        saved = {key: getattr(*key) for key in flags}
        for (mod, attr), value in flags.items():
            setattr(mod, attr, value)  # read while tracing: programs traced anew
        jax.clear_caches()  # the public API's jitted core too
        try:
            core = jit(lambda p, h: engine.project_batch(p, h, "relaxed", L, M))
            res: dict = {"whole": ns_per_pose(core, (p, h), args.repeats)}
            answers[name] = np.asarray(core(p, h)[0])
            x, cand, ridx = jit(lambda q, h: relaxed.relaxed_candidates(q, h, L, M))(p, h)
            back = jit(lambda s, x, c, r: relaxed.least_deviations_rows(s, dims, x, c, r, impl))
            res["back_projection"] = ns_per_pose(back, (p.stack, x, cand, ridx), args.repeats)
            devs[name] = np.asarray(back(p.stack, x, cand, ridx))  # (B, chains, L)
            if hosts is not None and name in (names[0], names[-1]):
                res["public_poses_per_s"] = round(public_rate(model, hosts), 0)
        finally:
            for (mod, attr), value in saved.items():
                setattr(mod, attr, value)
        out[name] = res
        print(name, res, flush=True)
    ref = StackedReference(p)
    base = names[0]
    for name in names:
        a, b = devs[base], devs[name]
        r = np.abs(a - b) / np.maximum(np.abs(a), 1e-30)
        out[name]["deviation_rel_diff"] = {"median": float(np.median(r)), "max": float(r.max())}
        out[name]["same_pick_per_chain"] = np.mean(np.argmin(a, -1) == np.argmin(b, -1), 0).tolist()
        same = np.all(answers[base] == answers[name], 1)
        out[name]["bit_identical_answers"] = float(np.mean(same))
        verdicts = [ref.judge(hp[i], answers[name][i], L, M, 1e-4) for i in range(args.check)]
        out[name]["judged"] = {v: verdicts.count(v) for v in ("exact", "tie", "differs")}
    report(out, args.json)


if __name__ == "__main__":
    jnp.zeros(())  # start the backend before timing anything
    main()
