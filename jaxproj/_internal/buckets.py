"""Padded sizes for host arrays handed to a compiled function: few shapes, so few compiles.

A jitted function compiles once per input shape; a recording, a dataset or a landmark set of
every new length would compile it again (~0.1-1.5 s each on a 2-core CPU). Callers pad the
leading axis to ``bucket(n)`` rows, run the compiled function, and keep the first ``n`` rows of
its answer (``pad_rows``), for functions whose rows do not mix (the descriptor, the IK, one ELM
kernel per landmark). A real row's answer is the function's, rounded as XLA rounds that
batch shape: float32 results already differ in the last bit between batch shapes (measured,
the descriptor of one MSR recording alone or inside the whole dataset: up to 3e-7), padded or
not. See each caller for the padding rows it uses.
"""

from __future__ import annotations

import numpy as np

MIN_ROWS = 64
"""The smallest bucket."""

LINEAR_FROM = 16384
"""Buckets are powers of two up to here, then multiples of it (at most ~1/n of waste)."""


def bucket(n: int, minimum: int = MIN_ROWS) -> int:
    """Rows to pad ``n`` rows to: the next power of two ``>= max(n, minimum)`` up to
    ``LINEAR_FROM``, past it the next multiple of ``LINEAR_FROM``."""
    n = max(int(n), minimum, 1)
    if n > LINEAR_FROM:
        return -(-n // LINEAR_FROM) * LINEAR_FROM
    return 1 << (n - 1).bit_length()


def pad_rows(a: np.ndarray, rows: int, value: float = 0.0) -> np.ndarray:
    """``a`` with its leading axis padded to ``rows`` with ``value`` (``a`` itself if long
    enough)."""
    if len(a) >= rows:
        return a
    pad = np.full((rows - len(a), *a.shape[1:]), value, a.dtype)
    return np.concatenate([a, pad], axis=0)
