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

from collections.abc import Callable, Sequence
from typing import Any

import jax
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


def fine_bucket(n: int, minimum: int = MIN_ROWS) -> int:
    """Rows to pad ``n`` rows to where every row costs much (a bundled robot's generic IK: ~15 ms
    a frame on a 2-core CPU): the least of ``2^k``, ``1.25 * 2^k``, ``1.5 * 2^k``, ``1.75 * 2^k``
    that is ``>= max(n, minimum)``: at most a quarter of padding instead of ``bucket``'s half (1,157
    frames: 1,280 rows, not 2,048), for four compiled shapes per octave instead of one."""
    n = max(int(n), minimum, 1)
    top = 1 << (n - 1).bit_length()
    return next((top // 8 * f for f in (5, 6, 7) if top >= 8 and top // 8 * f >= n), top)


def pad_rows(a: np.ndarray, rows: int, value: float = 0.0) -> np.ndarray:
    """``a`` with its leading axis padded to ``rows`` with ``value`` (``a`` itself if long
    enough)."""
    if len(a) >= rows:
        return a
    pad = np.full((rows - len(a), *a.shape[1:]), value, a.dtype)
    return np.concatenate([a, pad], axis=0)


def call_bucketed(
    fn: Callable[[np.ndarray], Any],
    x: np.ndarray,
    item_ndim: int,
    minimum: int = MIN_ROWS,
    sizes: Callable[[int, int], int] = bucket,
) -> Any:
    """``fn`` on the items of host array ``x`` (its trailing ``item_ndim`` axes), in one call.

    The leading axes are flattened to ``n`` rows and padded with zeros to ``sizes(n,
    minimum)`` (``bucket``, or ``fine_bucket``); every output of ``fn`` (an array or a pytree
    of them, rows first) comes back cut to ``n`` rows and shaped with ``x``'s leading axes,
    as device arrays (``device_put``: ``jnp.asarray`` of a NumPy array compiles a copy
    program per shape).
    """
    lead = x.shape[: x.ndim - item_ndim]
    flat = x.reshape(-1, *x.shape[x.ndim - item_ndim :])
    n = len(flat)
    out = fn(pad_rows(flat, sizes(n, minimum)))

    def cut(a: Any) -> jax.Array:
        a = np.asarray(a)
        return jax.device_put(a[:n].reshape(lead + a.shape[1:]))

    return jax.tree.map(cut, out)


def packed_calls(
    lengths: Sequence[int], *, coarse: bool, frames: int, minimum: int = MIN_ROWS
) -> list[tuple[int, list[int], int]]:
    """Calls of a program over many motions of ``lengths`` frames, each a stack of motions of
    one padded length: ``(rows, members, count)`` per call, ``rows`` the padded length
    (``bucket``, powers of two, where ``coarse``: few programs; else ``fine_bucket``),
    ``members`` the motions' indices (at most ``frames // rows`` of them) and ``count`` the
    stack's size, a power of two (the caller repeats a member to fill it): a few compiled
    shapes serve any batch. Where ``coarse``, every call of a length the same ``count`` (that
    of its largest call): ``retarget_many``'s rule, so that a later stage over the same motions
    meets the shapes its calls compiled."""
    sizes = bucket if coarse else fine_bucket
    groups: dict[int, list[int]] = {}
    for i, n in enumerate(lengths):
        groups.setdefault(sizes(n, minimum), []).append(i)
    out = []
    for rows, members in groups.items():
        per_call = max(1, frames // rows)
        most = 1 << (min(per_call, len(members)) - 1).bit_length()
        for start in range(0, len(members), per_call):
            chunk = members[start : start + per_call]
            out.append((rows, chunk, most if coarse else 1 << (len(chunk) - 1).bit_length()))
    return out
