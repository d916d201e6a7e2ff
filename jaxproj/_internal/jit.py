"""The one jit policy of jaxproj, in one function.

* **Where**: jit sits at the public entry points only. A public function checks its arguments in
  plain Python (typed errors from ``jaxproj.errors``, before anything is traced) and calls one
  module-level compiled implementation made by ``jit`` below; helpers called inside it are plain
  functions, never jitted themselves, and nothing is jitted inside a loop or on a fresh closure.
* **Static arguments** are named (``static_argnames``), never positional.
* **Precision**: float32 matrix products run at full float32 precision, wherever they are
  traced. ``full_precision`` traces a function's body under
  ``jax.default_matmul_precision("highest")``: JAX fixes a product's precision when the product
  is traced, so the setting holds inside a caller's own ``jax.jit`` as well as ours, whatever
  default precision the caller runs under. Every public traceable core of the engine wears it
  (``projection.api.project_batch``, the IK's ``driven_angles``, the pipeline's stages, the
  smoothers, the feasibility filter, the FK), and ``jit`` applies it to every implementation, so
  no product inside needs its own ``precision=``. (XLA's GPU default, TF32, moved batched answers
  by up to 20 deg on an H200, and a plain ``jax.jit`` of ``project_batch`` put 639 of 1,000
  held-out poses more than 0.1 deg from the float64 reference on an H100 before the core set its
  own precision: the k-NN ranking and kernel outputs change; on CPU the setting changes nothing.)
  The MJX rollout is the one exception, with ``precision=None``: it keeps MJX's own defaults, as
  MuJoCo's physics is compared against CPU MuJoCo, not against our float32 algebra.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any, TypeVar, cast

import jax

PRECISION = "highest"
"""The engine's matmul precision (``jax.default_matmul_precision``): full float32."""

F = TypeVar("F", bound=Callable[..., Any])


def full_precision(fun: F, precision: str = PRECISION) -> F:
    """``fun`` with its body traced under ``jax.default_matmul_precision(precision)``.

    For the public traceable cores (see the module doc): their products keep full float32
    precision inside a caller's ``jax.jit`` under any default precision. Costs nothing at run
    time (the precision is part of each traced product).
    """

    @functools.wraps(fun)
    def traced(*args: Any, **kwargs: Any) -> Any:
        with jax.default_matmul_precision(precision):
            return fun(*args, **kwargs)

    return cast(F, traced)


def jit(
    fun: Callable[..., Any] | None = None,
    *,
    static_argnames: str | Sequence[str] = (),
    precision: str | None = PRECISION,
) -> Any:
    """``jax.jit`` of ``fun`` traced under full float32 matmul precision (see the module doc).

    Usable as ``impl = jit(_impl, static_argnames=("n",))`` or as a decorator
    ``@jit(static_argnames=("n",))``. The result is a ``jax.jit`` function (``.lower`` works).
    """
    if fun is None:
        return functools.partial(jit, static_argnames=static_argnames, precision=precision)
    if precision is None:
        return jax.jit(fun, static_argnames=static_argnames)
    return jax.jit(full_precision(fun, precision), static_argnames=static_argnames)
