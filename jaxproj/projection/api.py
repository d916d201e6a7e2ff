"""The projection's public API: build, project, save, load (re-exported), and the batching.

``project`` maps human descriptors to robot poses with the relaxed (``relaxed``) or the full
(``full``) objective in fixed-size jitted batches, on one device or split over several with
``shard_map`` (``placement``, ``resolve_devices``); ``project_batch`` is its traceable core for
callers that jit their own pipeline. The backend (the Pallas kernels of ``ops`` or their XLA
twins) is one ``impl`` argument, resolved once from the target device (``ops.resolve_impl``).

The rest of the engine lives in one module per stage and is re-exported here (the names other
layers and the notebooks use): settings (``config``), building (``build``), the model file
(``model_file``), the projector pytrees (``projector``), chain stacking (``stacked``).

Shapes: human descriptors ``(B, m)`` (``m = 15`` for the default upper-body bones), robot poses
``(B, n)`` over ``robot.DRIVEN_JOINTS`` (``n = 10``), radians.

Size: just over 500 lines: the public entry points (build with its calibration, project,
the batching and device placement) are one surface a reader checks together.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxproj._internal.jit import full_precision, jit
from jaxproj.errors import ConfigError, NonFiniteRowsError
from jaxproj.projection import build as _build
from jaxproj.projection.build import (
    Model,
    build_from_landmarks,
    check_training_data,
    from_landmarks,
)
from jaxproj.projection.confidence import CALIBRATION_FRAMES, HELD_OUT_RATIO
from jaxproj.projection.config import (
    DEFAULTS,
    BuildConfig,
    ChainConfig,
    FullConfig,
    PerChain,
)
from jaxproj.projection.full import project_full_one
from jaxproj.projection.model_file import FORMAT, FORMAT_VERSION, load, save
from jaxproj.projection.ops import Impl, ImplLike, platform_of, resolve_impl
from jaxproj.projection.projector import ChainLayout, Projector, StackedProjector
from jaxproj.projection.relaxed import project_relaxed_rows
from jaxproj.projection.stacked import layout_of, project_stacked_one

__all__ = [
    "DEFAULTS",
    "DEFAULT_BATCH",
    "FORMAT",
    "FORMAT_VERSION",
    "MIN_BATCH",
    "SEARCH_QUERIES_CPU",
    "AnyProjector",
    "BuildConfig",
    "ChainConfig",
    "ChainLayout",
    "FullConfig",
    "Impl",
    "Model",
    "Objective",
    "PerChain",
    "Projector",
    "Spread",
    "StackedProjector",
    "build",
    "build_from_landmarks",
    "calibrated",
    "check_neighbours",
    "check_training_data",
    "default_batch_size",
    "from_landmarks",
    "layout_of",
    "load",
    "placement",
    "project",
    "project_batch",
    "project_chunk",
    "project_sharded",
    "resolve_devices",
    "save",
    "search_batch",
    "sub_batch",
]

Objective = Literal["relaxed", "full"]
Spread = Literal["per_device", "shard_map"]
"""How ``project`` spreads a batch over several devices (see its ``spread`` argument)."""


AnyProjector = Projector | StackedProjector


def sub_batch(
    p: AnyProjector,
    objective: str,
    n_l: int,
    n_m: int,
    batch: int,
    impl: ImplLike = Impl.XLA,
) -> int:
    """Queries vmapped together inside one jitted batch (the rest is a ``lax.map`` loop).

    XLA's relaxed path and the full objective gather ``L * M`` backward kernels per query and
    chain (``L * M * hidden * (m + 2)`` floats); a sub-batch is sized so that this stays within
    a cache-sized (CPU, 16 MiB) or memory-sized (accelerators, 4 GiB) budget, and divides
    ``batch``. The relaxed path's fused Pallas kernels (``impl="pallas"``, the default on CUDA
    GPUs) gather nothing: a query holds its ``L`` candidates and ``L * M`` robot-landmark
    indices per chain (``L * (n + M + 1)`` numbers), so the whole batch is one sub-batch (before,
    2,048-query chunks sized for the XLA path: issue 46 measured 560 -> 516 ns per pose for
    chunks of 8,192 -> 65,536 on one H100).
    """
    chains = 1
    if isinstance(p, StackedProjector):
        chains, p = p.layout.n_chains, p.stack
    if objective == "relaxed" and resolve_impl(impl) is Impl.PALLAS:
        per_query = 4 * chains * n_l * (p.forward.d_out + n_m + 1)
    else:
        per_query = 4 * chains * n_l * n_m * p.backward.hidden * (p.backward.d_out + 2)
    if objective == "full":
        per_query *= 3  # values, gradients and optimiser state
    budget = 16 * 2**20 if jax.default_backend() == "cpu" else 4 * 2**30
    sub = 1
    while sub * 2 * per_query <= budget and sub * 2 <= batch:
        sub *= 2
    while batch % sub:
        sub //= 2
    return max(sub, 1)


SEARCH_QUERIES_CPU = 128
"""Queries per search call of the CPU's relaxed projection (``search_batch``)."""


def search_batch(batch: int, sub: int) -> int:
    """Queries per search call of the relaxed projection (a multiple of ``sub``, dividing
    ``batch``).

    On the CPU the searches run XLA's ``TopK`` per row, whose per-call costs want many rows per
    call, while the back-projection wants few queries at a time (``sub``, its gathered kernels
    in cache): the searches take up to ``SEARCH_QUERIES_CPU`` queries per call and the
    back-projection loops over them ``sub`` at a time (``project_relaxed_rows``' ``chunk``).
    Measured on the 2-core VM, relaxed L = M = 10, batch 4,096, one process, interleaved rounds
    (``benchmarks/experiments/search_batch_ab.py``): default model (K up to 7,099) 386 -> 297 us
    per pose from 16 to 128 queries per call (the 16 MiB distance-row budget used before gave
    16), no gain at 64, none past 128; per-chain model at N = 1644, 277 -> 236 us from 64 to
    128. Against one search per sub-batch (2026-11-23) the forward kernels round differently in
    the last bit, so where two candidates' deviations tie to float32 round-off another one can
    be picked (``relaxed.TIE_RTOL``; ``benchmarks/experiments/two_level_ab.py``). Accelerators
    search and back-project ``sub`` queries together (their fused kernels hold no distance
    matrix): ``sub`` is returned.
    """
    if jax.default_backend() != "cpu":
        return sub
    out = sub
    while out * 2 <= min(SEARCH_QUERIES_CPU, batch) and batch % (out * 2) == 0:
        out *= 2
    return out


DESCRIPTOR_BOUND = 1e3
"""``project_batch`` clips every descriptor entry to ``[-DESCRIPTOR_BOUND, DESCRIPTOR_BOUND]``
first. Descriptors are unit-vector components (``|x| <= 1``), so no meaningful row changes; a
finite row far outside (``1e30``, ``-3.4e38``) otherwise overflows the kernels' products to
``inf`` and, where ``+inf`` meets ``-inf`` in a sum, to NaN angles: found on an AVX-512 CPU,
whose XLA kernels sum in another order than the AVX2 machines' that had given finite answers.
Clipped, such a row answers finite angles in the limits and a large value (confidence 0)."""


@full_precision
def project_batch(
    p: AnyProjector,
    h: jax.Array,
    objective: str = "relaxed",
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig = FullConfig(),  # noqa: B008 - frozen, hashable
    impl: ImplLike = Impl.AUTO,
    split: bool | None = None,
) -> tuple[jax.Array, jax.Array]:
    """The traceable core of ``project`` for one batch (call it inside a jitted function).

    ``(B, m)`` queries -> ``((B, n) angles, (B,) value)``, in sub-batches of ``sub_batch(...)``
    queries looped with ``lax.map``. Relaxed: ``relaxed.project_relaxed_rows`` per
    ``search_batch(...)`` queries (one human-landmark search for all of them, one
    robot-landmark search for all their candidates), back-projecting ``sub_batch(...)`` queries
    at a time; full: the one-query projection (of every chain, for a ``StackedProjector``;
    ``stacked.project_stacked_one``) vmapped. ``impl`` (static): the backend of the relaxed
    projection's searches and back-projection (``ops.Impl``; ``"auto"``: resolved here for the
    default backend); the full objective runs XLA only. ``split`` (static, relaxed only): a
    stacked projector's chains one after another at their own sizes or all at once padded to
    the largest; ``None`` (default): split with the Pallas kernels, not with XLA
    (``relaxed.project_relaxed_rows``). A projector built or loaded on a CUDA GPU carries its
    robot and human landmarks' pruning indices (``projector.with_search_index``): passed as an
    argument of the caller's jit (or closed over) they are used; a projector without them gives
    the same answers, computing them in every call. Entries beyond ``DESCRIPTOR_BOUND`` are
    clipped to it.
    """
    impl = resolve_impl(impl)
    h = jnp.clip(h, -DESCRIPTOR_BOUND, DESCRIPTOR_BOUND)  # absurd rows: no overflow to NaN
    sub = sub_batch(p, objective, n_l, n_m, h.shape[0], impl)
    if objective == "relaxed":  # batched form: one search call per search batch
        outer = search_batch(h.shape[0], sub)

        def rows(x: jax.Array) -> tuple[jax.Array, jax.Array]:
            return project_relaxed_rows(p, x, n_l, n_m, chunk=sub, impl=impl, split=split)

        if outer >= h.shape[0]:
            return rows(h)
        r, v = jax.lax.map(rows, h.reshape(-1, outer, h.shape[1]))
        return r.reshape(h.shape[0], -1), v.reshape(-1)

    def one(x: jax.Array) -> tuple[jax.Array, jax.Array]:
        if isinstance(p, StackedProjector):
            return project_stacked_one(p, x, objective, n_l, n_m, full)
        r, f, _ = project_full_one(p, x, n_l, n_m, full)
        return r, f

    if sub >= h.shape[0]:
        return jax.vmap(one)(h)
    return jax.lax.map(one, h, batch_size=sub)


project_chunk = jit(
    project_batch, static_argnames=("objective", "n_l", "n_m", "full", "impl", "split")
)
"""Jitted ``project_batch``: ``(projector, (B, m), objective, L, M, full, impl) -> ((B, n),
(B,))``."""


def check_neighbours(model_or_projector: Model | AnyProjector, n_l: int, n_m: int) -> None:
    """Raise ``ConfigError`` unless ``1 <= L, M <= K`` (``K``: the smallest chain's count)."""
    p = model_or_projector
    if isinstance(p, Model):
        p = p.projector
    where = ""
    if isinstance(p, StackedProjector) and p.layout.n_chains > 1:
        c = int(np.argmin(p.layout.landmarks))
        where = (
            f" (the {p.layout.names[c]} chain has {p.layout.landmarks[c]}: lower L / M, or "
            "build that chain with more landmarks, e.g. --landmarks H,L,R or a smaller bandwidth)"
        )
    for name, v in (("L", n_l), ("M", n_m)):
        if not 1 <= v <= p.n_landmarks:
            raise ConfigError(
                f"{name}={v} must lie in [1, number of landmarks={p.n_landmarks}]{where}"
            )


def placement(devices: Sequence[jax.Device] | None, batch_size: int) -> Mesh | jax.Device | None:
    """Where each padded batch goes: the default device (``None``), one device, or a 1-D mesh
    ``("batch",)`` over several (``batch_size`` must then be a multiple of their number)."""
    if devices is None:
        return None
    devices = list(devices)
    if not devices:
        raise ConfigError("devices must name at least one JAX device (or be None)")
    if len(set(devices)) != len(devices):
        raise ConfigError(f"devices lists a device twice: {[str(d) for d in devices]}")
    if len(devices) == 1:
        return devices[0]
    if batch_size % len(devices):
        raise ConfigError(f"batch_size={batch_size} must be a multiple of {len(devices)} devices")
    return Mesh(np.array(devices), ("batch",))


_placement = placement  # the old private name, still used by benchmarks/bench_multi_device.py


def _sharded_batch(
    p: AnyProjector,
    h: jax.Array,
    *,
    mesh: Mesh,
    objective: str,
    n_l: int,
    n_m: int,
    full: FullConfig,
    impl: ImplLike = Impl.AUTO,
) -> tuple[jax.Array, jax.Array]:
    """``project_batch`` with the query axis split over ``mesh``: every device runs the whole
    one-device program (its own sub-batch loop) on its shard of the queries, the projector
    replicated; no collective (``shard_map``, see ``project``)."""

    def local(p_local: AnyProjector, h_local: jax.Array) -> tuple[jax.Array, jax.Array]:
        return project_batch(p_local, h_local, objective, n_l, n_m, full, impl)

    spec = PartitionSpec("batch")
    # check_vma=False: the fused k-NN kernel's pallas_call (CUDA) declares plain output shapes,
    # which shard_map's varying-axes check rejects; every output here varies along "batch".
    return jax.shard_map(
        local, mesh=mesh, in_specs=(PartitionSpec(), spec), out_specs=(spec, spec), check_vma=False
    )(p, h)


project_sharded = jit(
    _sharded_batch, static_argnames=("mesh", "objective", "n_l", "n_m", "full", "impl")
)
"""Jitted ``_sharded_batch``: ``(projector, (B, m) queries sharded over mesh) -> ((B, n), (B,))``
with ``mesh``, ``objective``, ``n_l``, ``n_m``, ``full``, ``impl`` static."""


def resolve_devices(spec: int | str | Sequence[jax.Device] | None) -> list[jax.Device] | None:
    """Devices from a user's ``--devices`` value: ``None`` / ``1`` -> ``None`` (the default
    device), ``N`` -> the first ``N`` of ``jax.devices()``, ``"all"`` -> every one of them, a
    sequence of devices -> as given.

    Raises:
      ConfigError: ``N`` outside ``1..len(jax.devices())``, or a string other than ``"all"``.
    """
    if spec is None:
        return None
    if isinstance(spec, str):
        if spec.strip().lower() == "all":
            found = jax.devices()
            return found if len(found) > 1 else None
        try:
            spec = int(spec)
        except ValueError:
            raise ConfigError(f"devices must be a number or 'all', got {spec!r}") from None
    if isinstance(spec, int):
        found = jax.devices()
        if not 1 <= spec <= len(found):
            raise ConfigError(
                f"devices={spec}: this machine has {len(found)} JAX device(s) "
                f"({', '.join(str(d) for d in found)}); use 1..{len(found)} or 'all'"
            )
        return found[:spec] if spec > 1 else None
    return list(spec)


DEFAULT_BATCH = {"cpu": 4096, "accelerator": 65536}
"""``project``'s default ``batch_size`` per backend and device: CPU 4096 (cache-sized
sub-batches inside anyway), GPU / TPU 65536 (enough queries per call to fill the device); over
several devices, that many for each."""


def default_batch_size(
    devices: Sequence[jax.Device] | None = None, n_queries: int | None = None
) -> int:
    """``project``'s batch when it is not given: ``DEFAULT_BATCH`` for the platform of
    ``devices`` (``None``: the default backend) times their number, so that each device gets
    the batch one device would (measured on 2 x H200 with the default model, relaxed: 1.63x
    one device so, 1.70x with 65,536 queries split in two halves, in another run: no gain
    shown either way; issue 61); for ``n_queries`` fewer than that, the next power of two ``>=
    n_queries`` (at least ``MIN_BATCH``, a multiple of the device count), so that a short call
    is not padded to a whole default batch (64 queries on a CPU: 64x less work than 4096)."""
    platform = platform_of(devices)
    k = len(list(devices)) if devices else 1
    default = DEFAULT_BATCH["cpu" if platform == "cpu" else "accelerator"] * k
    return default if n_queries is None else _fitted_batch(default, n_queries, devices)


MIN_BATCH = 64
"""The smallest batch ``project`` compiles for by default (fewer queries are padded to it)."""


def _fitted_batch(default: int, n: int, devices: Sequence[jax.Device] | None) -> int:
    """``default``, or for fewer queries ``n`` the next power of two ``>= n`` (at least
    ``MIN_BATCH``, a multiple of the device count)."""
    if n >= default:
        return default
    bucket = max(MIN_BATCH, 1 << max(n - 1, 0).bit_length())
    k = len(list(devices)) if devices else 1
    return min(default, -(-bucket // k) * k)


def project(
    model: Model | AnyProjector,
    descriptors: np.ndarray,
    objective: Objective = "relaxed",
    *,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    batch_size: int | None = None,
    devices: Sequence[jax.Device] | None = None,
    impl: ImplLike = Impl.AUTO,
    spread: Spread = "per_device",
) -> tuple[np.ndarray, np.ndarray]:
    """Project human descriptors to robot poses.

    The queries run as one jitted call per batch of ``batch_size`` (the last one padded),
    dispatched back to back without waiting: each batch's transfer to the device is issued
    just before its call and its answers' transfer back just after it, so the transfers overlap
    the device's work on the other batches (the host never waits for the device before the
    last batch's answers). Every call compiles once per ``(objective, L, M, full, batch_size,
    impl)``.

    Args:
      model: a ``Model``, or a bare ``StackedProjector`` / ``Projector``.
      descriptors: ``(B, m)`` human descriptors of valid frames: finite (a row holding NaN
        or inf is refused, ``NonFiniteRowsError``; ``skeleton.descriptor`` gives zeros, never
        NaN, at invalid frames: drop them by its ``valid``).
      objective: ``"relaxed"`` or ``"full"``.
      n_l, n_m: ``L`` human and ``M`` robot neighbours.
      full: settings of the full objective (default ``FullConfig()``).
      batch_size: queries per jitted call (``>= 1``); ``None``: ``default_batch_size`` (4096
        on CPU, 65536 on accelerators, per device), or for fewer queries than that the next
        power of two (at least ``MIN_BATCH``): one compilation per such size.
      devices: where to run: ``None`` (default) the default device; one device; or several
        (``resolve_devices`` turns ``"all"`` or a count into a list): each batch is split
        along the query axis into one equal share per device (``batch_size`` a multiple of
        their number; the padding of the last batch is cut off the answers), the projector
        copied to each, with no collective (see ``spread``).
      spread: how several ``devices`` share a batch. ``"per_device"`` (default): each device
        runs the one-device program (``project_chunk``, compiled once per device) on its
        share, dispatched by a host thread of its own, so the devices run together; the
        answers are those of one device given the same share. ``"shard_map"``: one program
        over a 1-D mesh (``project_sharded``); its per-device program is compiled once, but
        XLA fuses the share otherwise (last-bit differences in the value; a segmentation fault
        while compiling it with the Pallas kernels, jax 0.11.2, was the k-NN kernels'
        padding, fixed: ``knn_pallas._row_pad``).
      impl: backend of the relaxed projection's k-NN searches and back-projection:
        ``"auto"`` (default) resolved once from the platform of ``devices`` (``None``: the
        default backend): the Pallas kernels on CUDA GPUs, XLA elsewhere; ``"xla"``; or
        ``"pallas"`` (off CUDA GPUs: Pallas' interpreter, slow; for tests). See ``ops.Impl``.

    Returns:
      ``(angles, value)``: ``(B, n)`` float32 driven-joint angles (rad, within limits) and
      ``(B,)`` the objective's value (relaxed: back-projected deviation; full: ``f(w*)``);
      never NaN (a finite row far outside the unit-vector range, e.g. 1e30, is clipped to
      ``DESCRIPTOR_BOUND`` and gives a large value: confidence 0).

    Raises:
      ConfigError: a bad objective, ``L`` / ``M``, shape, ``batch_size`` or device list.
      NonFiniteRowsError: descriptor rows holding NaN or inf (a ``ConfigError`` naming them),
        before anything is traced.
    """
    p = model.projector if isinstance(model, Model) else model
    full = FullConfig() if full is None else full
    if objective not in ("relaxed", "full"):
        raise ConfigError(f"objective must be 'relaxed' or 'full', got {objective!r}")
    check_neighbours(p, n_l, n_m)
    m = p.layout.m if isinstance(p, StackedProjector) else p.human.shape[1]
    h = np.asarray(descriptors, np.float32)
    if h.ndim != 2 or h.shape[1] != m:
        raise ConfigError(f"descriptors must be (B, {m}), got {h.shape}")
    finite = _finite_rows(h)  # host side, before tracing: NaN in would be NaN out
    if not finite.all():
        raise NonFiniteRowsError(np.flatnonzero(~finite), len(h))
    if batch_size is None:
        batch_size = default_batch_size(devices, len(h))
    if batch_size < 1:
        raise ConfigError(f"batch_size={batch_size} must be >= 1")
    place = placement(devices, batch_size)
    if spread not in ("per_device", "shard_map"):
        raise ConfigError(f"spread must be 'per_device' or 'shard_map', got {spread!r}")
    impl = resolve_impl(impl, devices)
    n = p.layout.n if isinstance(p, StackedProjector) else p.robot.shape[1]
    if len(h) == 0:
        return np.zeros((0, n), np.float32), np.zeros((0,), np.float32)
    kw: dict[str, Any] = {"objective": objective, "n_l": n_l, "n_m": n_m, "full": full}
    if impl is not resolve_impl(Impl.AUTO):
        # another backend than ``project_batch``'s own "auto" (the default backend's) picks:
        # pass it; otherwise leave it out, so that every call of one backend shares one
        # executable with callers that compile ``project_chunk`` without ``impl``
        kw["impl"] = impl
    cut = len(h)
    if isinstance(place, Mesh) and spread == "per_device":
        return _project_per_device(p, h, list(place.devices.flat), batch_size, kw, n)
    answers = _Answers(cut, n, touching=platform_of(devices) != "cpu")
    pending: list[tuple[int, tuple[jax.Array, jax.Array]]] = []
    for s in range(0, cut, batch_size):
        # batch by batch: each batch's transfer in is issued right before its call and its
        # transfer out right after it, so both overlap the device's work on the batches around
        # them (one transfer of the whole array each way waited for all of it first); only the
        # last batch is padded, on its own
        part = _padded(h[s : s + batch_size], batch_size, p)
        if isinstance(place, Mesh):
            x = jax.device_put(part, NamedSharding(place, PartitionSpec("batch")))
            out = project_sharded(p, x, mesh=place, **kw)
        else:
            out = project_chunk(p, jax.device_put(part, place), **kw)
        for a in out:
            a.copy_to_host_async()
        pending.append((s, out))
    answers.touch(0, cut)  # while the device works through the calls
    for s, out in pending:
        answers.put(s, out)
    return answers.angles, answers.value


def _finite_rows(h: np.ndarray) -> np.ndarray:
    """``np.isfinite(h).all(axis=1)`` for ``(B, m)`` float32 ``h``, as ``(B,)`` bool, by way of
    each row's sum: NaN or inf in a row makes its sum NaN or inf, and a sum that overflowed is
    checked element by element. One BLAS matrix-vector product (threaded) reads ``h`` once
    and writes ``B`` floats, where ``isfinite`` wrote a ``(B, m)`` mask first: on 4 M rows of
    30 this check was most of ``project``'s host time that more devices do not share (2-core
    VM: 0.28 s against 0.08 s, issue 61)."""
    with np.errstate(over="ignore", invalid="ignore"):  # overflow: checked below
        ok = np.isfinite(h @ np.ones(h.shape[1], h.dtype))
    if not ok.all():
        unsure = np.flatnonzero(~ok)
        ok[unsure] = np.isfinite(h[unsure]).all(axis=1)
    return ok


class _Answers:
    """``project``'s answers, written batch by batch into arrays made once (no concatenation
    of the whole answer at the end: on 2 x H200 that serial copy of 4 M rows was a fixed cost
    that more devices do not share, issue 61); the padding rows past ``cut`` are dropped."""

    def __init__(self, cut: int, n: int, touching: bool = True) -> None:
        self.angles = np.empty((cut, n), np.float32)
        self.value = np.empty((cut,), np.float32)
        self.touching = touching

    def touch(self, start: int, stop: int) -> None:
        """Write zeros into rows ``start:stop`` (where ``touching``: not on a CPU, whose cores
        compute the answers too): the first write into fresh memory faults its pages in, which
        a caller does while its device works (2 x H200, the default robot's default model, 4 M
        queries: two devices' call 4-11 ms faster in three machine starts, issue 61)."""
        if self.touching:
            self.angles[start:stop] = 0.0
            self.value[start:stop] = 0.0

    def put(self, start: int, out: tuple[jax.Array, jax.Array]) -> None:
        """Write one call's ``(angles, value)`` from row ``start`` on (cut at the end)."""
        k = max(0, min(len(self.value) - start, int(out[1].shape[0])))
        self.angles[start : start + k] = np.asarray(out[0])[:k]
        self.value[start : start + k] = np.asarray(out[1])[:k]


def _project_per_device(
    p: AnyProjector,
    h: np.ndarray,
    devices: list[jax.Device],
    batch_size: int,
    kw: dict[str, Any],
    n: int,
) -> tuple[np.ndarray, np.ndarray]:
    """``project``'s loop with each batch split into one share per device, each share run by
    the one-device program on its device (the projector copied there once).

    One host thread per device dispatches that device's shares in order: a call whose program
    holds a loop with a data-dependent end (the full objective's solver, ``lax.map``) keeps
    its calling thread until the loop ends on XLA:GPU, so one thread for all devices ran them
    one after another (measured on 2 x H200: the full objective 1.00x on two devices; issue
    61); the first calls' compilations run side by side too."""
    k, cut = len(devices), len(h)
    share = batch_size // k
    starts = range(0, cut, batch_size)
    answers = _Answers(cut, n, touching=platform_of(devices) != "cpu")

    def run(i: int) -> None:
        q, d = _on_device(p, devices[i]), devices[i]
        pending = []
        for s in starts:
            part = _padded(h[s + i * share : min(s + (i + 1) * share, cut)], share, p)
            out = project_chunk(q, jax.device_put(part, d), **kw)
            for a in out:
                a.copy_to_host_async()
            pending.append((s + i * share, out))
        for s, _ in pending:  # while the device works through the calls
            answers.touch(s, s + share)
        for s, out in pending:  # each device's thread writes its own rows, as they arrive
            answers.put(s, out)

    with ThreadPoolExecutor(max_workers=k, thread_name_prefix="jaxproj-device") as pool:
        list(pool.map(run, range(k)))
    return answers.angles, answers.value


_COPIES: dict[tuple[int, int], AnyProjector] = {}


def _on_device(p: AnyProjector, device: jax.Device) -> AnyProjector:
    """``p`` copied to ``device``, once per projector and device: the copy is kept while ``p``
    lives (copying the default robot's default model to the second of 2 H200s on every
    ``project`` call cost more than a tenth of the call, issue 61)."""
    return _kept(p, _COPIES, (id(p), device.id), lambda: jax.device_put(p, device))


def _kept(p: AnyProjector, table: dict, key: Any, make: Callable[[], Any]) -> Any:
    """``table[key]``, made by ``make()`` on first use and dropped from ``table`` when the
    projector ``p`` is collected (its ``id`` may then be reused by another)."""
    hit = table.get(key)
    if hit is None:
        hit = table[key] = make()
        weakref.finalize(p, table.pop, key, None)
    return hit


def build(
    descriptors: np.ndarray,
    config: BuildConfig = BuildConfig(),  # noqa: B008 - frozen, hashable
    *, calibrate: bool = True, **mean_shift: Any,
) -> Model:  # fmt: skip
    """``projection.build.build``, then ``calibrated`` on the same frames (not with
    ``calibrate=False``, for a model whose confidence nobody reads: a sweep's)."""
    model = _build.build(descriptors, config, **mean_shift)
    return calibrated(model, descriptors) if calibrate else model


def calibrated(model: Model, descriptors: np.ndarray) -> Model:
    """``model`` with its confidence scale ``Model.deviation_scale``: the p90 of the relaxed
    deviation (L = M = 10 at most) of ``CALIBRATION_FRAMES`` evenly spaced ones of ``(N, m)``
    valid training descriptors, times ``HELD_OUT_RATIO`` (``projection.confidence``)."""
    d, k = np.asarray(descriptors, np.float32), min(10, model.n_landmarks)
    rows = np.linspace(0, len(d) - 1, min(CALIBRATION_FRAMES, len(d))).round().astype(int)
    _, v = project(model, d[rows], "relaxed", n_l=k, n_m=k, batch_size=CALIBRATION_FRAMES)
    return replace(model, deviation_scale=max(float(np.percentile(np.asarray(v), 90)), 1e-6)
                   * HELD_OUT_RATIO)  # fmt: skip


def _padded(part: np.ndarray, size: int, p: AnyProjector) -> np.ndarray:
    """``part`` (``(k, m)``, ``k <= size``) with ``p``'s padding query appended up to ``size``
    rows (``_padding_query``: asked only when a batch is short)."""
    if len(part) == size:
        return part
    return np.concatenate([part, np.repeat(_padding_query(p), size - len(part), axis=0)])


_FILLERS: dict[int, np.ndarray] = {}


def _padding_query(p: AnyProjector) -> np.ndarray:
    """``(1, m)``: a harmless padding query (the first landmark of each chain), made once per
    projector and kept while it lives: made on every ``project`` call it cost a slice and a
    transfer from the device per chain before any batch was sent (on 2 x H200 with the default
    robot's default model, most of the 48 ms before the first batch in a profiled call; issue
    61)."""

    def make() -> np.ndarray:
        if not isinstance(p, StackedProjector):
            return np.asarray(p.human[:1], np.float32)
        first = np.asarray(p.stack.human[:, 0])  # (chains, width): one transfer
        q = np.zeros((1, p.layout.m), np.float32)
        for c, cols in enumerate(p.layout.inputs):
            q[0, list(cols)] = first[c, : len(cols)]
        return q

    return _kept(p, _FILLERS, id(p), make)
