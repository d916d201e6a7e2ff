"""The ELM kernel bank: one regularised extreme learning machine per landmark, stacked.

Paper section II-C. The kernel of landmark ``i`` is a single-hidden-layer network
``kappa_i(x) = t_i + Q_i(x) B_i`` trained on the ``k`` nearest landmarks of landmark ``i``
(nearest in its *input* space, the landmark itself included): forward kernels map human
descriptors to robot angles (trained on the ``k`` nearest human landmarks of ``h_i``), backward
kernels map robot angles to human descriptors (``k`` nearest robot landmarks of ``r_i``).

Hidden layer (sigmoid, random, never trained)::

    Q_i(x) = sigmoid( W (x - c_i) / rho_i + b )          # (hidden,)

``W (hidden, d_in)`` and ``b (hidden,)`` are drawn once per direction from an explicit PRNG key
and *shared by every kernel of that direction*; ``c_i`` is the kernel's own landmark and
``rho_i`` the distance to its farthest training neighbour, so each kernel sees its
neighbourhood at unit scale. Because ``W (x - c_i) / rho_i + b = (W x) / rho_i + beta_i`` with
``beta_i = b - W c_i / rho_i``, the product ``W x`` is computed once per query point and each
kernel adds only a scale and a bias: that is what makes evaluating many kernels at one point
cheap (``features``).

Output weights, regularised ELM (Deng et al. 2009), with ``H (k, hidden)`` the hidden outputs
of the training inputs and ``T (k, d_out)`` the targets relative to the kernel's own landmark
target ``t_i``::

    B_i = H^T (lambda I + H H^T)^{-1} (T - t_i)           # (hidden, d_out)

``B_i`` is stored transposed, ``(d_out, hidden)`` per kernel: the contraction over ``hidden``
then runs along contiguous memory of each gathered kernel (measured: 78 -> 51 us per relaxed
projection on 2 CPU cores, 0.49 -> 0.41 us on an H200, answers bit-identical).

``hidden >= k`` so that, for small ``lambda``, each kernel can interpolate its ``k`` training
pairs. A regularised ELM reproduces its training pairs only approximately, which breaks the
paper's identity property (its Remark). With ``anchor=True`` (default) each kernel is made exact
at its own landmark: features are taken relative to the landmark's,
``H~ = H - 1 Q_i(c_i)^T``, ``B_i = H~^T (lambda I + H~ H~^T)^{-1} (T - t_i)`` and
``kappa_i(x) = t_i + (Q_i(x) - Q_i(c_i)) B_i``, so ``kappa_i(c_i) = t_i`` for any ``lambda``
and input scale. It costs nothing at evaluation time:
``t_i - Q_i(c_i) B_i`` is stored as the kernel's offset.
All kernels of a direction are trained in one vmapped call (no Python loop over landmarks).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.buckets import bucket, pad_rows
from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ELMBank:
    """All ELM kernels of one direction, as padded tensors (a pytree; sizes are static).

    Attributes:
      w: ``(hidden, d_in)`` shared random input weights.
      inv_scale: ``(n_kernels,)`` ``1 / rho_i``.
      bias: ``(n_kernels, hidden)`` ``beta_i = b - W c_i / rho_i``.
      out: ``(n_kernels, d_out, hidden)`` output weights ``B_i^T`` (transposed, see the module
        doc).
      offset: ``(n_kernels, d_out)`` constant term: ``t_i`` (the target of the kernel's own
        landmark), minus ``Q_i(c_i) B_i`` for anchored kernels.
      neighbours: ``(n_kernels, k)`` int32 indices of the training landmarks of each kernel.
      n_kernels, hidden, d_in, d_out, k: static sizes.
    """

    w: jax.Array | np.ndarray
    inv_scale: jax.Array | np.ndarray
    bias: jax.Array | np.ndarray
    out: jax.Array | np.ndarray
    offset: jax.Array | np.ndarray
    neighbours: jax.Array | np.ndarray
    n_kernels: int = field(metadata=dict(static=True))
    hidden: int = field(metadata=dict(static=True))
    d_in: int = field(metadata=dict(static=True))
    d_out: int = field(metadata=dict(static=True))
    k: int = field(metadata=dict(static=True))


def project_inputs(bank: ELMBank, x: jax.Array) -> jax.Array:
    """Shared part of the hidden layer: ``(..., d_in) -> (..., hidden)`` = ``W x``."""
    return jnp.einsum("...d,hd->...h", x, bank.w)


def predict(bank: ELMBank, x: jax.Array, idx: jax.Array) -> jax.Array:
    """Evaluate kernels ``idx`` at one point.

    Args:
      bank: the kernel bank.
      x: ``(d_in,)`` the point.
      idx: ``(...,)`` int kernel indices.

    Returns:
      ``(..., d_out)`` the kernels' predictions ``kappa_idx(x)``.
    """
    return predict_slice(take(bank, idx), project_inputs(bank, x))


class KernelSlice(NamedTuple):
    """The per-kernel arrays of some kernels ``idx (...,)``, gathered once for reuse."""

    inv_scale: jax.Array  # (...,)
    bias: jax.Array  # (..., hidden)
    out: jax.Array  # (..., d_out, hidden)
    offset: jax.Array  # (..., d_out)


def take(bank: ELMBank, idx: jax.Array) -> KernelSlice:
    """Gather kernels ``idx (...,)`` (do it once when they are evaluated many times)."""
    return KernelSlice(bank.inv_scale[idx], bank.bias[idx], bank.out[idx], bank.offset[idx])


def predict_slice(ks: KernelSlice, wx: jax.Array) -> jax.Array:
    """Evaluate gathered kernels at a point whose ``W x`` is ``wx (hidden,)``: ``(..., d_out)``."""
    pre = jnp.broadcast_to(wx, ks.bias.shape) * ks.inv_scale[..., None] + ks.bias
    q = jax.nn.sigmoid(pre)
    return ks.offset + jnp.einsum("...h,...oh->...o", q, ks.out)


def knn_indices(points: jax.Array, k: int) -> jax.Array:
    """``(K, d) -> (K, k)`` int32: the ``k`` nearest points of each point, itself first.

    Exact brute force in blocks of rows (the ``K x K`` distances are never all in memory at
    once). Ties are broken by index (``lax.top_k`` is stable): deterministic.
    """
    points = jnp.asarray(points, jnp.float32)
    n, d = points.shape
    sq = jnp.sum(points * points, axis=1)
    block = 256
    pad = (-n) % block
    rows = jnp.concatenate([points, jnp.zeros((pad, d), points.dtype)], axis=0)
    row_ids = jnp.arange(n + pad, dtype=jnp.int32).reshape(-1, block)

    def one_block(args: tuple[jax.Array, jax.Array]) -> jax.Array:
        xb, ids = args
        d2 = jnp.sum(xb * xb, axis=1)[:, None] - 2.0 * xb @ points.T + sq[None, :]
        d2 = jnp.where(ids[:, None] == jnp.arange(n)[None, :], -1.0, d2)  # self first
        return jax.lax.top_k(-d2, k)[1]

    out = jax.lax.map(one_block, (rows.reshape(-1, block, d), row_ids))
    return out.reshape(-1, k)[:n].astype(jnp.int32)


def _train_one(
    x_all: jax.Array,
    t_all: jax.Array,
    nbr: jax.Array,
    w: jax.Array,
    b: jax.Array,
    lam: jax.Array,
    min_scale: float,
    anchor: bool,
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    x = x_all[nbr]  # (k, d_in); nbr[0] is the kernel's own landmark
    t = t_all[nbr]  # (k, d_out)
    c = x[0]
    rho = jnp.maximum(jnp.max(jnp.sqrt(jnp.sum((x - c[None]) ** 2, axis=1))), min_scale)
    inv = 1.0 / rho
    beta = b - (w @ c) * inv
    h = jax.nn.sigmoid((x @ w.T) * inv + beta[None])  # (k, hidden)
    if anchor:
        h = h - h[0][None]  # features relative to the kernel's own landmark (row 0)
    gram = h @ h.T + lam * jnp.eye(h.shape[0], dtype=h.dtype)
    coef = jax.scipy.linalg.solve(gram, t - t[0][None], assume_a="pos")
    out = h.T @ coef  # (hidden, d_out)
    q0 = jax.nn.sigmoid((w @ c) * inv + beta)  # Q_i(c_i)
    offset = t[0] - q0 @ out if anchor else t[0]
    return inv, beta, out.T, offset


def train_bank(
    inputs: jax.typing.ArrayLike,
    targets: jax.typing.ArrayLike,
    key: jax.Array,
    *,
    k: int = 16,
    hidden: int = 32,
    lam: float = 1e-3,
    input_scale: float = 1.0,
    min_scale: float = 1e-3,
    anchor: bool = True,
) -> ELMBank:
    """Train one ELM kernel per landmark, all in one vmapped call.

    Args:
      inputs: ``(K, d_in)`` landmark coordinates in the kernels' input space.
      targets: ``(K, d_out)`` corresponding landmark coordinates in the output space.
      key: PRNG key for the shared random hidden layer.
      k: training neighbours per kernel (the landmark itself included), ``2 <= k <= K``.
      hidden: hidden units, ``>= k``.
      lam: ridge regulariser ``lambda > 0``.
      input_scale: standard deviation of the random input weights (inputs are seen at unit
        neighbourhood scale, so ~1 puts the sigmoids in their responsive range).
      min_scale: floor of ``rho_i`` where all neighbours coincide.
      anchor: make each kernel exact at its own landmark (see the module doc).

    Returns:
      The stacked ``ELMBank``.

    Raises:
      ConfigError: a bad setting, or training that gave non-finite weights (an ill-conditioned
        ridge system: the message says which setting to change); never a bank with NaN.
    """
    x_np = np.asarray(inputs, np.float32)  # host copies (a device array comes back once)
    t_np = np.asarray(targets, np.float32)
    n = x_np.shape[0]
    if t_np.shape[0] != n:
        raise ConfigError(f"inputs ({n}) and targets ({t_np.shape[0]}) differ in count")
    if not 2 <= k <= n:
        raise ConfigError(f"k={k} must lie in [2, number of landmarks={n}]")
    if hidden < k:
        raise ConfigError(f"hidden={hidden} must be >= k={k} (an ELM interpolates k samples)")
    if not lam > 0:
        raise ConfigError(f"lam={lam} must be > 0")
    # landmarks padded to a bucket (one compile for most counts): the padding rows coincide far
    # beyond every landmark, so no real kernel takes one as a neighbour (k <= n); their kernels
    # are cut off below
    finite = np.abs(x_np[np.isfinite(x_np)])
    far = 1e3 * (1.0 + (float(finite.max()) if finite.size else 0.0))
    rows = bucket(n, minimum=BANK_MIN_ROWS)
    padded = _train_bank_jit(
        jax.device_put(pad_rows(x_np, rows, far)),
        jax.device_put(pad_rows(t_np, rows)),
        key,
        jnp.float32(lam),
        k=k,
        hidden=hidden,
        input_scale=input_scale,
        min_scale=min_scale,
        anchor=anchor,
    )
    # device_put, not jnp.asarray: the latter compiles a copy program per shape
    cut = {f: jax.device_put(np.asarray(getattr(padded, f))[:n]) for f in _PER_KERNEL}
    bank = dataclasses.replace(padded, **cut, n_kernels=n)
    bad = ~np.isfinite(np.asarray(bank.out)).all(axis=(1, 2))
    bad |= ~np.isfinite(np.asarray(bank.offset)).all(axis=1)
    if bad.any():
        raise ConfigError(
            f"ELM training gave non-finite weights for {int(bad.sum())} of {n} kernels (first: "
            f"kernel {int(np.argmax(bad))}): the ridge system lam I + H H^T is not positive "
            f"definite in float32 with lam={lam}, hidden={hidden}, input_scale={input_scale}; "
            "raise lam or lower input_scale"
        )
    return bank


def _train_bank(
    inputs: jax.Array,
    targets: jax.Array,
    key: jax.Array,
    lam: jax.Array,
    *,
    k: int,
    hidden: int,
    input_scale: float,
    min_scale: float,
    anchor: bool,
) -> ELMBank:
    d_in, d_out = inputs.shape[1], targets.shape[1]
    kw, kb = jax.random.split(key)
    w = input_scale * jax.random.normal(kw, (hidden, d_in), jnp.float32)
    b = jax.random.uniform(kb, (hidden,), jnp.float32, -1.0, 1.0)
    nbr = knn_indices(inputs, k)
    inv, beta, out, off = jax.vmap(
        _train_one, in_axes=(None, None, 0, None, None, None, None, None)
    )(inputs, targets, nbr, w, b, lam, min_scale, anchor)
    return ELMBank(
        w=w,
        inv_scale=inv,
        bias=beta,
        out=out,
        offset=off,
        neighbours=nbr,
        n_kernels=int(inputs.shape[0]),
        hidden=hidden,
        d_in=int(d_in),
        d_out=int(d_out),
        k=k,
    )


BANK_MIN_ROWS = 256
"""The smallest landmark bucket of ``train_bank`` (``knn_indices``' row block)."""

_PER_KERNEL = ("inv_scale", "bias", "out", "offset", "neighbours")
"""``ELMBank``'s per-kernel fields (leading axis: the kernels)."""

_train_bank_jit = jit(
    _train_bank, static_argnames=("k", "hidden", "input_scale", "min_scale", "anchor")
)
