"""Is the model build reproducible across processes? Build and print a fingerprint.

Builds the default per-chain model at ``--landmarks`` from the benchmark's training subjects
(MSR Action3D 1, 3, 5, 7, 9) and prints the landmark counts per chain and a SHA-1 of each
chain's human landmarks. Run it several times, each in a fresh process, and compare the lines;
on a GPU try it with and without ``XLA_FLAGS=--xla_gpu_deterministic_ops=true``:

    for i in 1 2; do python -m benchmarks.experiments.build_determinism; done
    for i in 1 2; do XLA_FLAGS=--xla_gpu_deterministic_ops=true \\
        python -m benchmarks.experiments.build_determinism; done
"""

from __future__ import annotations

import argparse
import hashlib

import jax
import numpy as np

from benchmarks.bench_projection import TRAIN_SUBJECTS, descriptors  # noqa: E402
from jaxproj.projection import api as engine  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landmarks", type=int, default=1644)
    args = ap.parse_args()
    model = engine.build(descriptors(TRAIN_SUBJECTS),
                         engine.BuildConfig(chains="upper", landmarks=args.landmarks))  # fmt: skip
    sp = model.projector
    digest = [hashlib.sha1(np.asarray(sp.chain(c).human).tobytes()).hexdigest()[:10]
              for c in range(sp.layout.n_chains)]  # fmt: skip
    print(jax.devices()[0].device_kind, model.landmarks, digest)


if __name__ == "__main__":
    main()
