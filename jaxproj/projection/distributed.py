"""Evaluation over several hosts: split a corpus by process, project on each host's own
devices, gather the answers.

JAX's multi-process runtime does the plumbing: every host runs the same program, after
``jax.distributed.initialize(...)`` (arguments, or the cluster's environment: SLURM, Open MPI,
Cloud TPU), and sees its own devices as ``jax.local_devices()`` and every device as
``jax.devices()``. Here each process takes a contiguous share of the corpus
(``process_share``), projects it over its local devices (``engine.project(...,
devices=jax.local_devices())``: one share per device, ``project``'s ``spread``), and the
shares are gathered, in process order, with ``jax.experimental.multihost_utils.process_allgather``
(``gather_rows``); process 0 writes the result. With one process every function is the plain
single-host call.

On CPU (tests, or clusters without accelerators) the processes need JAX's CPU collectives:
``jax.config.update("jax_cpu_collectives_implementation", "gloo")`` before initialising.
"""

from __future__ import annotations

import jax
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig


def process_share(
    n: int, process_index: int | None = None, process_count: int | None = None
) -> slice:
    """The contiguous rows ``[start, stop)`` of an ``n``-row corpus that one process takes.

    Shares differ in size by at most one row (the first ``n % count`` processes take one more);
    together they cover ``0..n`` once, in process order.

    Args:
      n: corpus size (>= 0).
      process_index, process_count: default ``jax.process_index()`` / ``jax.process_count()``.
    """
    i = jax.process_index() if process_index is None else int(process_index)
    c = jax.process_count() if process_count is None else int(process_count)
    if n < 0 or c < 1 or not 0 <= i < c:
        raise ConfigError(f"process_share: need n >= 0 and 0 <= index < count, got {n}, {i}, {c}")
    base, extra = divmod(n, c)
    start = i * base + min(i, extra)
    return slice(start, start + base + (i < extra))


def gather_rows(rows: np.ndarray) -> np.ndarray:
    """Concatenate every process's ``(n_i, ...)`` rows in process order (on every process).

    ``process_allgather`` needs equal shapes, so each share is padded to the largest ``n_i``
    and the padding dropped after the gather. With one process: ``rows`` itself.
    """
    rows = np.asarray(rows)
    if jax.process_count() == 1:
        return rows
    from jax.experimental import multihost_utils

    counts = multihost_utils.process_allgather(np.array([len(rows)], np.int64)).reshape(-1)
    width = int(counts.max())
    padded = np.zeros((width, *rows.shape[1:]), rows.dtype)
    padded[: len(rows)] = rows
    every = np.asarray(multihost_utils.process_allgather(padded))  # (processes, width, ...)
    return np.concatenate([every[p, : int(counts[p])] for p in range(len(counts))])


def project_corpus(
    model: engine.Model,
    descriptors: np.ndarray,
    objective: engine.Objective = "relaxed",
    *,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    batch_size: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Project a corpus over every process and device: this process projects its
    ``process_share`` on ``jax.local_devices()``, and every process gets the whole answer.

    Args:
      model: the projector (the same on every process).
      descriptors: ``(B, m)`` the whole corpus (the same on every process; each reads its
        share only).
      objective, n_l, n_m, full, batch_size: as ``engine.project`` (``batch_size`` a multiple
        of the local device count; default: ``engine.default_batch_size``).

    Returns:
      ``(angles (B, n), value (B,))``, identical to one process's ``engine.project`` on the
      whole corpus (the same program runs on every share).
    """
    share = process_share(len(descriptors))
    local = jax.local_devices()
    r, v = engine.project(
        model, np.asarray(descriptors)[share], objective, n_l=n_l, n_m=n_m, full=full,
        batch_size=batch_size, devices=local if len(local) > 1 else [local[0]],
    )  # fmt: skip
    return gather_rows(r), gather_rows(v)
