"""Per-row work split over the host's CPU devices (``shard_map``): the generic IK on a CPU.

XLA runs one CPU device's program mostly on one core: the generic IK of a 1,280-row bucket
took 7.6 s of wall and 10 s of CPU on the 2-core VM, a core and a third. A process that starts
with several CPU devices (``XLA_FLAGS=--xla_force_host_platform_device_count=N``; the command
line asks for one per core, ``request_host_devices``) can run each device's share of the rows on
a core of its own: the same bucket split over two devices took 4.4 s, with answers equal to
the bit (each row is computed alone; measured 0.0 deg apart).

``host_shards()`` is how many devices a row-independent function is split over (1 unless the
default backend is the CPU and the process has more than one CPU device); ``over_rows(fn,
shards)`` is ``fn`` split over them. A library user's process has one CPU device unless it asks
for more, so nothing changes there by default.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
from collections.abc import Callable, Sequence
from typing import Any

import jax
import numpy as np
from jax.sharding import Mesh, PartitionSpec

MAX_SHARDS = 8
"""At most this many devices share one call's rows (and the command line asks for at most this
many CPU devices)."""

_FLAG = "--xla_force_host_platform_device_count"


def host_shards() -> int:
    """How many CPU devices a row-independent function is split over: the largest power of two
    ``<= min(CPU devices, MAX_SHARDS)`` when JAX's default backend is the CPU, else 1 (a GPU
    runs the rows in parallel already). Initialises JAX's backends."""
    if jax.default_backend() != "cpu":
        return 1
    n = min(len(jax.devices("cpu")), MAX_SHARDS)
    return 1 << (n.bit_length() - 1)


def over_rows(fn: Callable[..., Any], shards: int) -> Callable[..., Any]:
    """``fn``, a function of ``(rows, ...)`` arrays whose rows do not mix, split over the first
    ``shards`` CPU devices by rows (``shard_map``; traceable, inside a ``jit`` too). The rows
    must be a multiple of ``shards`` (the buckets of ``jaxproj._internal.buckets`` are);
    ``shards <= 1`` returns ``fn`` itself."""
    if shards <= 1:
        return fn
    mesh = Mesh(np.array(jax.devices("cpu")[:shards]), ("rows",))
    spec = PartitionSpec("rows")
    # check_vma=False: the loops inside (lax.scan, fori_loop) start their carries from
    # constants, which shard_map's type check would want cast to per-device values
    return jax.shard_map(fn, mesh=mesh, in_specs=spec, out_specs=spec, check_vma=False)


def _backends_running() -> bool:
    """Whether JAX has created its backends (after which ``$XLA_FLAGS`` is not read again);
    ``True`` where this JAX cannot say (the flag is then left alone)."""
    try:
        from jax._src import xla_bridge

        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):
        return True


def request_host_devices() -> int | None:
    """Ask XLA for one CPU device per core this process may use (at most ``MAX_SHARDS``), by
    adding the flag to ``$XLA_FLAGS``, unless the flag is there already or JAX's backends are
    running (then it could no longer take effect). Returns the number asked for, or ``None``.
    For the command line, at start; a library import never calls it."""
    if _FLAG in os.environ.get("XLA_FLAGS", "") or _backends_running():
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    n = max(1, min(cores or 1, MAX_SHARDS))
    if n == 1:
        return None
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {_FLAG}={n}".strip()
    return n


def on_devices(
    fn: Callable[[Any], None], items: Sequence[Any], devices: Sequence[jax.Device] | None
) -> None:
    """``fn(item)`` for every item, spread over ``devices``: one host thread a device, each
    taking the next item in order while any is left, with that device as JAX's default (a
    thread's own setting: its uncommitted arrays and its programs go there). ``None`` or one
    device: in order on this thread (on that device). A program with a loop in time order keeps
    its calling thread until it ends, so a thread a device is what lets devices overlap (as
    ``jaxproj.projection.api.project``'s ``per_device``). The first exception any call raised is
    raised after every thread has stopped (the others stop taking items)."""
    if not devices or len(devices) == 1:
        with contextlib.ExitStack() as stack:
            if devices:
                stack.enter_context(jax.default_device(devices[0]))
            for item in items:
                fn(item)
        return
    todo: queue.SimpleQueue[Any] = queue.SimpleQueue()
    for item in items:
        todo.put(item)
    failed: list[BaseException] = []

    def worker(device: jax.Device) -> None:
        with jax.default_device(device):
            while not failed:
                try:
                    item = todo.get_nowait()
                except queue.Empty:
                    return
                try:
                    fn(item)
                except BaseException as e:  # noqa: BLE001 (raised on the calling thread)
                    failed.append(e)

    threads = [threading.Thread(target=worker, args=(d,), name=f"jaxproj-{d}") for d in devices]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if failed:
        raise failed[0]
