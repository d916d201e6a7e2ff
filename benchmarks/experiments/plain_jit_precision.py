"""The traceable core under a caller's plain ``jax.jit``: answers against the float64 reference.

``jaxproj.projection.api.project_batch`` is documented as the core to call inside one's own jitted
function. Here it is called the way a user would, ``jax.jit(lambda p, h: project_batch(p, h))``
with no precision setting (XLA's GPU default multiplies float32 in TF32), beside the package's
own ``jaxproj.project``, on held-out MSR poses; each answer is judged by the float64 reference
(``jaxproj.testing.StackedReference.judge``: exact to 0.001 deg, a near tie, or different) and
its largest joint distance from the reference's pick is counted beyond 0.1 and 1 deg.

    python -m benchmarks.experiments.plain_jit_precision MODEL.npz [--queries 1000]

Without a model file it builds the default model (``jaxproj.BuildConfig()``, MSR training
people). Prints one line per engine and writes the counts as JSON with ``--json``.
"""

from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np

import jaxproj
from benchmarks.experiments.selection_ab import held_out_queries
from benchmarks.heldout import default_model
from jaxproj.projection import api as engine
from jaxproj.testing import StackedReference


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", nargs="?")
    ap.add_argument("--queries", type=int, default=1000)
    ap.add_argument("--json")
    args = ap.parse_args()
    model = default_model(args.model)
    sp = model.projector
    q = held_out_queries(args.queries)
    device = jax.devices()[0].device_kind
    print(
        device,
        "landmarks",
        model.landmarks,
        "precision default:",
        jax.config.jax_default_matmul_precision,
        flush=True,
    )

    plain = jax.jit(lambda p, h: engine.project_batch(p, h, "relaxed", 10, 10))
    answers = {
        "plain jax.jit(project_batch)": np.asarray(plain(sp, jnp.asarray(q))[0]),
        "jaxproj.project": jaxproj.project(model, q, "relaxed", n_l=10, n_m=10)[0],
    }
    ref = StackedReference(sp)
    want = np.stack([ref.project(x, "relaxed", 10, 10)[0] for x in q])
    out = {"device": device, "queries": len(q), "landmarks": dict(model.landmarks)}
    for name, r in answers.items():
        d = np.degrees(np.abs(r - want)).max(axis=1)
        verdicts = [ref.judge(x, a, 10, 10, np.radians(1e-3)) for x, a in zip(q, r, strict=True)]
        row = {
            "over_0.1_deg": int(np.sum(d > 0.1)),
            "over_1_deg": int(np.sum(d > 1.0)),
            "max_deg": float(d.max()),
            "differs": verdicts.count("differs"),
            "ties": verdicts.count("tie"),
        }
        out[name] = row
        print(name, row, flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
