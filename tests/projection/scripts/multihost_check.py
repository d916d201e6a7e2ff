"""Run by tests/projection/test_sharding.py: one of two processes of a CPU ``jax.distributed`` job.

    python multihost_check.py PROCESS_ID PORT OUT_JSON

Both processes project the same corpus with ``distributed.project_corpus`` (each its share, then
gathered); process 0 also projects the whole corpus alone and writes the comparison.
"""

import json
import sys

import jax

jax.config.update("jax_cpu_collectives_implementation", "gloo")

pid, port, out_path = int(sys.argv[1]), sys.argv[2], sys.argv[3]
jax.distributed.initialize(coordinator_address=f"127.0.0.1:{port}", num_processes=2, process_id=pid)

import numpy as np  # noqa: E402

from jaxproj.io import datasets  # noqa: E402
from jaxproj.projection import api as engine  # noqa: E402
from jaxproj.projection import distributed  # noqa: E402
from jaxproj.robots.nao_h25 import ik  # noqa: E402

train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1]))
uniq = np.unique(train, axis=0)
idx = np.sort(np.random.default_rng(0).choice(len(uniq), 120, replace=False))
human = uniq[idx].astype(np.float32)
model = engine.from_landmarks(
    human, np.asarray(ik.solve_driven(human), np.float32), engine.BuildConfig(k=16, hidden=32)
)
corpus = datasets.valid_descriptors(datasets.msr_action3d(subjects=[2], actions=[1, 2]))[:201]
share = distributed.process_share(len(corpus))
r, v = distributed.project_corpus(model, corpus, n_l=4, n_m=4, batch_size=64)
if pid == 0:
    alone, _ = engine.project(model, corpus, n_l=4, n_m=4, batch_size=64)
    with open(out_path, "w") as fh:
        json.dump(
            {
                "process_count": jax.process_count(),
                "share": [share.start, share.stop],
                "shape": list(r.shape),
                "bit_identical": bool(np.array_equal(r, alone)),
                "max_abs_diff": float(np.abs(r - alone).max()),
            },
            fh,
        )
jax.distributed.shutdown()
