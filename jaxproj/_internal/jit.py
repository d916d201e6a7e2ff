"""The one jit policy of jaxproj, in one function.

* **Where**: jit sits at the public entry points only. A public function checks its arguments in
  plain Python (typed errors from ``jaxproj.errors``, before anything is traced) and calls one
  module-level compiled implementation made by ``jit`` below; helpers called inside it are plain
  functions, never jitted themselves, and nothing is jitted inside a loop or on a fresh closure.
* **Static arguments** are named (``static_argnames``), never positional.
* **Precision**: float32 matrix products run at full float32 precision. ``jit`` traces the
  implementation under ``jax.default_matmul_precision("highest")``, so no product inside needs its
  own ``precision=``. (XLA's GPU default, TF32, moved batched answers by up to 20 deg on an H200:
  the k-NN ranking and kernel outputs change; on CPU the setting changes nothing.) The MJX rollout
  is the one exception, with ``precision=None``: it keeps MJX's own defaults, as MuJoCo's physics
  is compared against CPU MuJoCo, not against our float32 algebra.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import jax


def jit(
    fun: Callable[..., Any] | None = None,
    *,
    static_argnames: str | Sequence[str] = (),
    precision: str | None = "highest",
) -> Any:
    """``jax.jit`` of ``fun`` traced under full float32 matmul precision (see the module doc).

    Usable as ``impl = jit(_impl, static_argnames=("n",))`` or as a decorator
    ``@jit(static_argnames=("n",))``. The result is a ``jax.jit`` function (``.lower`` works).
    """
    if fun is None:
        return functools.partial(jit, static_argnames=static_argnames, precision=precision)
    if precision is None:
        return jax.jit(fun, static_argnames=static_argnames)

    @functools.wraps(fun)
    def traced(*args: Any, **kwargs: Any) -> Any:
        with jax.default_matmul_precision(precision):
            return fun(*args, **kwargs)

    return jax.jit(traced, static_argnames=static_argnames)
