"""Chain stacking: per-chain projectors padded into one ``StackedProjector``, and one query
projected through every chain.

``layout_of`` / ``chain_inputs`` say which descriptor columns and joints each chain of a
``BuildConfig`` owns (the one rule that the builder and the model file share);
``stack_projectors`` pads and stacks; ``project_stacked_one`` projects one query through every
chain with either objective (``relaxed`` / ``full``), so it sits above both.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import resolve_bones
from jaxproj.projection.config import BuildConfig, FullConfig
from jaxproj.projection.elm import ELMBank
from jaxproj.projection.full import project_full_one
from jaxproj.projection.ops import Impl, resolve_impl
from jaxproj.projection.projector import (
    ChainLayout,
    Projector,
    StackedProjector,
    with_search_index,
)
from jaxproj.projection.relaxed import project_relaxed_one
from jaxproj.robots import Chain


def _pad(a: jax.typing.ArrayLike, shape: tuple[int, ...], value: float = 0.0) -> np.ndarray:
    a = np.asarray(a)
    return np.pad(
        a, [(0, t - s) for s, t in zip(a.shape, shape, strict=True)], constant_values=value
    )


def _pad_bank(bank: ELMBank, k: int, hidden: int, d_in: int, d_out: int, kk: int) -> ELMBank:
    return ELMBank(
        w=_pad(bank.w, (hidden, d_in)),
        inv_scale=_pad(bank.inv_scale, (k,)),
        bias=_pad(bank.bias, (k, hidden)),
        out=_pad(bank.out, (k, d_out, hidden)),
        offset=_pad(bank.offset, (k, d_out)),
        neighbours=_pad(bank.neighbours, (k, kk), -1),
        n_kernels=k,
        hidden=hidden,
        d_in=d_in,
        d_out=d_out,
        k=kk,
    )


def stack_projectors(
    chains: Sequence[Projector], layout: ChainLayout, search_index: bool | None = None
) -> StackedProjector:
    """Pad per-chain projectors to the largest and stack them (see ``StackedProjector``).

    ``search_index``: compute each chain's robot- and human-landmark pruning indices once, here
    (``projector.with_search_index``: a model built or loaded carries them); ``None`` (default):
    where the default backend runs the Pallas kernels (CUDA GPUs; elsewhere the pruned search
    does not run by default).
    """
    if len(chains) != layout.n_chains or not chains:
        raise ConfigError(f"{len(chains)} projectors for {layout.n_chains} chains")
    for c, p in enumerate(chains):
        want: tuple[int, ...] = (layout.landmarks[c], len(layout.inputs[c]), len(layout.outputs[c]))
        want += (layout.hidden[c], layout.hidden[c], layout.k[c], layout.k[c])
        got: tuple[int, ...] = (p.n_landmarks, p.human.shape[1], p.robot.shape[1], p.forward.hidden)
        got += (p.backward.hidden, p.forward.k, p.backward.k)
        if got != want:
            raise ConfigError(f"chain {layout.names[c]}: projector {got} does not match {want}")
    k, m, n = max(layout.landmarks), layout.m_max, layout.n_max
    hf = hb = max(layout.hidden)
    kk = max(layout.k)
    padded = [
        Projector(
            human=_pad(p.human, (k, m)),
            robot=_pad(p.robot, (k, n)),
            human_sq=_pad(p.human_sq, (k,), np.inf),
            robot_sq=_pad(p.robot_sq, (k,), np.inf),
            forward=_pad_bank(p.forward, k, hf, m, n, kk),
            backward=_pad_bank(p.backward, k, hb, n, m, kk),
            lower=_pad(p.lower, (n,)),
            upper=_pad(p.upper, (n,)),
            n_landmarks=k,
        )
        for p in chains
    ]
    stack = jax.tree.map(lambda *a: jnp.asarray(np.stack(a)), *padded)
    sp = StackedProjector(stack=stack, layout=layout)
    if search_index is None:
        search_index = resolve_impl(Impl.AUTO) is Impl.PALLAS
    return with_search_index(sp) if search_index else sp


def chain_inputs(config: BuildConfig, chain: Chain) -> tuple[int, ...]:
    """Descriptor columns a chain of ``config`` reads: the whole descriptor for the one-chain
    (whole-body) set, else the chain's bones' columns (``Robot.chain_columns``)."""
    spec = config.robot_spec
    if len(spec.chain_set(config.chains)) == 1:
        return tuple(range(3 * len(resolve_bones(config.bones))))
    return tuple(spec.chain_columns(chain, config.bones))


def layout_of(config: BuildConfig, projectors: Sequence[Projector]) -> ChainLayout:
    """The ``ChainLayout`` of ``config``'s chains holding these per-chain projectors."""
    spec = config.robot_spec
    chains = spec.chain_set(config.chains)
    return ChainLayout(
        names=tuple(ch.name for ch in chains),
        inputs=tuple(chain_inputs(config, ch) for ch in chains),
        outputs=tuple(spec.chain_joints(ch) for ch in chains),
        landmarks=tuple(p.n_landmarks for p in projectors),
        hidden=tuple(p.forward.hidden for p in projectors),
        k=tuple(p.forward.k for p in projectors),
        width=3 * len(resolve_bones(config.bones)),
    )


def project_stacked_one(
    sp: StackedProjector, h: jax.Array, objective: str, n_l: int, n_m: int, full: FullConfig
) -> tuple[jax.Array, jax.Array]:
    """Project one query through every chain (vmapped over the chain axis).

    Args:
      sp: the stacked projector.
      h: ``(m,)`` whole descriptor.
      objective: ``"relaxed"`` or ``"full"`` (static).
      n_l, n_m: ``L`` and ``M`` per chain (static).
      full: full-objective settings (static).

    Returns:
      ``(r, value)``: ``(n,)`` driven joints (each chain's answer in its joints), and the
      objective's value over the whole descriptor: relaxed, ``sqrt(sum_c dev_c^2)`` (the chains
      split the descriptor, so this is the deviation of the assembled pose); full, ``sum_c f_c``.
    """

    def chain(p: Projector, x: jax.Array) -> tuple[jax.Array, jax.Array]:
        if objective == "relaxed":
            return project_relaxed_one(p, x, n_l, n_m)
        r, f, _ = project_full_one(p, x, n_l, n_m, full)
        return r, f

    lay = sp.layout
    if lay.identity:  # the whole-body projector: no gather, no scatter
        return chain(jax.tree.map(lambda a: a[0], sp.stack), h)
    x = jnp.concatenate([h, jnp.zeros((1,), h.dtype)])[lay.input_index()]  # (C, m_max)
    r, v = jax.vmap(chain)(sp.stack, x)  # (C, n_max), (C,)
    out = r.reshape(-1)[lay.output_index()]
    value = jnp.sqrt(jnp.sum(v * v)) if objective == "relaxed" else jnp.sum(v)
    return out, value
