"""The one jit policy of jaxproj, in one function.

* **Where**: jit sits at the public entry points only. A public function checks its arguments in
  plain Python (typed errors from ``jaxproj.exceptions``, before anything is traced) and calls one
  module-level compiled implementation made by ``jit`` below; helpers called inside it are plain
  functions, never jitted themselves, and nothing is jitted inside a loop or on a fresh closure.
* **Static arguments** are named (``static_argnames``), never positional.
* **Precision**: float32 matrix products run at full float32 precision. ``jit`` traces the
  implementation under ``jax.default_matmul_precision("highest")``, so no product inside needs its
  own ``precision=``. (XLA's GPU default, TF32, moved batched answers by up to 20 deg on an H200:
  the k-NN ranking and kernel outputs change; on CPU the setting changes nothing.) The MJX rollout
  is the one exception, with ``precision=None``: it keeps MJX's own defaults, as MuJoCo's physics
  is compared against CPU MuJoCo, not against our float32 algebra.
* **Determinism**: programs are compiled with XLA's ``xla_gpu_deterministic_ops`` (jit's
  per-function ``compiler_options``; ignored on CPU) unless made with ``deterministic=False``.
  Without it XLA:GPU autotunes its matrix products per process and may pick another algorithm
  (another summation order) in the next one: on an H200 two processes building the same
  per-chain model at 1,644 landmarks gave different float32 landmarks, and the bandwidth search
  then landed on 1,725 and on 1,642 right-arm landmarks; with the flag, repeated processes build
  bit-identical models. The hot paths opt out (``engine.project_chunk`` / ``project_sharded``,
  ``streaming.update``, the MJX rollout): on an H200 the flag cost the full objective 30 % and
  the rollout 29 % (relaxed: 2 %), for float32 round-off that may differ between processes
  there (within one process every call is reproducible). ``benchmarks/RESULTS.md`` has the runs.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import jax

DETERMINISTIC_OPTIONS: dict[str, Any] = {"xla_gpu_deterministic_ops": True}
"""XLA compiler options of every jaxproj program (see the module doc)."""


def jit(
    fun: Callable[..., Any] | None = None,
    *,
    static_argnames: str | Sequence[str] = (),
    precision: str | None = "highest",
    deterministic: bool = True,
) -> Any:
    """``jax.jit`` of ``fun`` traced under full float32 matmul precision, compiled with
    deterministic GPU ops unless ``deterministic=False`` (see the module doc).

    Usable as ``impl = jit(_impl, static_argnames=("n",))`` or as a decorator
    ``@jit(static_argnames=("n",))``. The result is a ``jax.jit`` function (``.lower`` works).
    """
    if fun is None:
        return functools.partial(
            jit, static_argnames=static_argnames, precision=precision, deterministic=deterministic
        )
    options = DETERMINISTIC_OPTIONS if deterministic else None
    if precision is None:
        out = jax.jit(fun, static_argnames=static_argnames, compiler_options=options)
        out.deterministic = deterministic  # the policy, readable by tests
        return out

    @functools.wraps(fun)
    def traced(*args: Any, **kwargs: Any) -> Any:
        with jax.default_matmul_precision(precision):
            return fun(*args, **kwargs)

    out = jax.jit(traced, static_argnames=static_argnames, compiler_options=options)
    out.deterministic = deterministic  # the policy, readable by tests
    return out
