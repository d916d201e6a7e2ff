"""Timing primitives shared by the benchmarks (``benchmarks/``) and the paper's efficiency study.

One way to time JAX code, everywhere: compilation is timed apart (``compile_timed`` lowers and
compiles exactly the executable that is then called), every timed call waits for the device
(``jax.block_until_ready``), and a figure is the median over repeated calls (``time_calls``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import numpy as np


class Timing(NamedTuple):
    """Result of ``time_calls``.

    Attributes:
      median_s: median seconds per call.
      repeats: how many calls were timed.
      times_s: every call's seconds, in order.
    """

    median_s: float
    repeats: int
    times_s: tuple[float, ...]


def compile_timed(jitted: Any, *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """Lower and compile ``jitted`` (a ``jax.jit`` function) for these arguments.

    Returns:
      ``(compiled, seconds)``: the compiled executable (call it with the non-static arguments)
      and the time ``lower(...).compile()`` took.
    """
    t0 = time.perf_counter()
    compiled = jitted.lower(*args, **kwargs).compile()
    return compiled, time.perf_counter() - t0


def time_calls(
    fn: Callable[[], Any],
    *,
    min_repeats: int = 3,
    max_repeats: int = 100,
    min_time_s: float = 0.0,
) -> Timing:
    """Median seconds per ``fn()``, each call blocked until its outputs are ready.

    At least ``min_repeats`` calls; more (up to ``max_repeats``) while their total stays under
    ``min_time_s``. Call ``fn`` once before (warm-up) when the first call would compile.
    """
    ts: list[float] = []
    total = 0.0
    while len(ts) < min_repeats or (total < min_time_s and len(ts) < max_repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        dt = time.perf_counter() - t0
        ts.append(dt)
        total += dt
    return Timing(float(np.median(ts)), len(ts), tuple(ts))
