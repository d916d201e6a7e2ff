"""Compiled programs kept on disk by the command line, so that a second run does not trace.

The persistent compilation cache (``jaxproj.cli.cache``) spares a later run XLA's compiling, not
JAX's tracing and lowering: a 29-joint robot's retarget traced ~6 s on the 2-core VM each
time a process first calls it, a third of a second run's time. ``call`` keeps the compiled
executable itself (``jax.experimental.serialize_executable``) in a folder, keyed by everything
that decides the program, and a later process loads it (milliseconds) and runs it without
tracing.

The key (sha256) covers: the function's name; the bytes of every ``.py`` file of the installed
``jaxproj`` package (``source_digest``: any change of the code is a new program); JAX's and
jaxlib's versions, the backend, the devices and ``$XLA_FLAGS``; the JAX settings that change a
trace (64-bit, the promotion rules, the default matmul precision); the call's static arguments
(``repr``) and its arrays' tree, shapes and dtypes; and ``identity``, what the caller says
identifies the rest (a robot: its name and the digest of its robot file and MJCF,
``jaxproj.robots.identity``). A caller that cannot name what its program depends on passes
``identity=None`` and the call is a plain ``jitted(...)``. A file that does not load (another
version's, cut short) is compiled again and replaced; a program that loads but fails to run is
deleted and the call runs as a plain ``jitted(...)``. Like the compilation cache, the folder is
trusted code (its files are unpickled).

What the key cannot see: Python state that changes a trace without changing the code's bytes
or the call's arguments (a module's function or default replaced at run time, a monkeypatch):
a process that does that and calls ``retarget`` through the command line runs with
``--no-cache`` (the continuity-pass sweep of ``benchmarks/experiments`` does), else it gets the
program the first such run kept.

Off unless ``kept_in(folder)`` is active: the command line turns it on with its compilation
cache (``--no-cache`` turns both off); a library import never does.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.metadata
import os
import pickle
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxproj._internal.atomic import atomic_write

_FOLDER: list[Path] = []
_LOADED: dict[tuple[Path, int | None], Any] = {}
"""The executables this process loaded or compiled, by file and device (at most
``KEEP_LOADED``): a second call runs the one in memory (each load maps the program's code
again)."""
_LOCK = threading.Lock()
_COMPILING: dict[Path, threading.Lock] = {}
"""One lock a file: threads that need one program (``shards.on_devices``, a thread a device)
compile it once; the others wait, then load it for their own device."""

KEEP_LOADED = 8


@contextlib.contextmanager
def kept_in(folder: Path | None) -> Iterator[None]:
    """Within the block, ``call`` keeps its executables in ``folder`` (``None``: off)."""
    if folder is not None:
        _FOLDER.append(folder)
    try:
        yield
    finally:
        if folder is not None:
            _FOLDER.pop()


def active() -> Path | None:
    """The folder ``call`` keeps executables in now, or ``None``."""
    return _FOLDER[-1] if _FOLDER else None


@functools.cache
def source_digest() -> str:
    """sha256 (hex) over the path and bytes of every ``.py`` file of the ``jaxproj`` package."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _aval(x: Any) -> tuple[tuple[int, ...], str]:
    if hasattr(x, "shape") and hasattr(x, "dtype"):
        return tuple(x.shape), str(x.dtype)
    a = np.asarray(x)
    return a.shape, str(a.dtype)


def _key(
    name: str, args: tuple, kwargs: Mapping[str, Any], words: Mapping[str, str], identity: Any
) -> str:
    leaves = jax.tree.leaves((args, dict(kwargs)))  # their tree is in `words` ("(tree)")
    settings = tuple(
        str(getattr(jax.config, s, None))
        for s in (
            "jax_enable_x64",
            "jax_numpy_dtype_promotion",
            "jax_numpy_rank_promotion",
            "jax_default_matmul_precision",
        )
    )
    parts = (
        name,
        source_digest(),
        jax.__version__,
        importlib.metadata.version("jaxlib"),
        jax.default_backend(),
        tuple(str(d) for d in jax.devices()),
        os.environ.get("XLA_FLAGS", ""),
        settings,
        tuple(sorted(words.items())),
        tuple(_aval(x) for x in leaves),
        repr(identity),
    )
    return hashlib.sha256(repr(parts).encode()).hexdigest()


def _devices(compiled: Any) -> list[int]:
    """The ids of the devices a compiled program runs on, in order (its shardings' devices; a
    loaded program must be told them: left alone it would take every local device)."""
    found: set[int] = set()
    for sharding in jax.tree.leaves((compiled.input_shardings, compiled.output_shardings)):
        found |= {d.id for d in sharding.device_set}
    if not found:
        raise ValueError("a program without devices")
    return sorted(found)


def _default_device() -> jax.Device | None:
    """The calling thread's ``jax.default_device`` where it names a device, else ``None``."""
    found = getattr(jax.config, "jax_default_device", None)  # a thread's own setting
    return found if isinstance(found, jax.Device) else None


def call(
    jitted: Any,
    args: tuple,
    kwargs: Mapping[str, Any] | None = None,
    static: Mapping[str, Any] | None = None,
    *,
    name: str,
    identity: Any,
    identified: tuple[str, ...] = ("robot",),
) -> Any:
    """``jitted(*args, **kwargs, **static)`` (``static``: its static arguments), through an
    executable kept on disk where ``kept_in`` is active and ``identity`` is not ``None`` (the
    module doc): loaded when its key's file is there, else compiled and written. The static
    arguments named in ``identified`` enter the key through ``identity`` (default: ``robot``,
    by ``jaxproj.robots.identity``), the others by their ``repr``."""
    kwargs, static = dict(kwargs or {}), dict(static or {})
    folder = active()
    # the static arguments' words: those `identity` stands for left out (a robot's repr holds
    # its functions' addresses, which differ in every process); any other such repr: no key
    words = {k: repr(v) for k, v in static.items() if k not in identified}
    words["(tree)"] = str(jax.tree.structure((args, kwargs)))  # a pytree's static fields too
    if folder is None or identity is None or any(" at 0x" in w for w in words.values()):
        return jitted(*args, **kwargs, **static)
    from jax.experimental.serialize_executable import deserialize_and_load, serialize

    path = folder / f"{name}-{_key(name, args, kwargs, words, identity)[:40]}.xla"
    # the thread's default device (``jax.default_device``, ``shards.on_devices``): a program
    # kept for one device loads onto another (a one-device program's code is the same)
    target = _default_device()
    slot = (path, None if target is None else target.id)  # (several devices: loaded per thread)
    with _LOCK:
        compiled = _LOADED.get(slot)
        gate = _COMPILING.setdefault(path, threading.Lock())
    if compiled is None:
        with gate:
            if path.is_file():
                try:
                    payload, in_tree, out_tree, ids = pickle.loads(path.read_bytes())
                    by_id = {d.id: d for d in jax.devices()}
                    # a one-device program onto the thread's device (or the default one,
                    # whichever device wrote it); one of several devices (a CPU's rows split
                    # over its cores) onto its own
                    if len(ids) == 1:
                        where = [target if target is not None else jax.devices()[0]]
                    else:
                        where = [by_id[i] for i in ids]
                    compiled = deserialize_and_load(
                        payload, in_tree, out_tree, execution_devices=where
                    )
                except Exception:  # noqa: BLE001 (another version's file, cut short: compile)
                    compiled = None
            if compiled is None:
                compiled = jitted.lower(*args, **kwargs, **static).compile()
                try:
                    folder.mkdir(parents=True, exist_ok=True)
                    data = pickle.dumps((*serialize(compiled), _devices(compiled)))

                    def write(tmp: Path) -> None:
                        tmp.write_bytes(data)

                    atomic_write(path, write)
                except Exception:  # noqa: BLE001 (a program that does not serialise, a full disk)
                    pass
    try:  # run it here, so that a program that fails to run is caught here
        out = jax.block_until_ready(compiled(*args, **kwargs))
    except jax.errors.JaxRuntimeError:
        # seen once in the test suite (2026-11-29, jaxlib 0.10.2): a kept XLA:CPU program that
        # loaded but could not find one of its own functions ("compare_reduce_fusion not
        # found"); its cause is not known. Dropped, and the call runs as a plain jit call.
        with _LOCK:
            _LOADED.pop(slot, None)
        with contextlib.suppress(OSError):
            path.unlink()
        return jitted(*args, **kwargs, **static)
    with _LOCK:
        if slot not in _LOADED:
            if len(_LOADED) >= KEEP_LOADED:
                _LOADED.pop(next(iter(_LOADED)))
            _LOADED[slot] = compiled
    return out
