"""The command line's persistent compilation cache: XLA programs kept on disk between runs.

Much of a first run's time on a CPU is XLA compiling (a first generic-IK retarget of ~1,000 frames:
~40 s of its ~90 s on two cores); JAX's persistent compilation cache writes every compiled
program to a folder and reads it back the next time the same program is needed, in this
process or a later one. Every ``jaxproj`` subcommand runs with it (``compilation_cache``,
entered by ``jaxproj.cli.main.main`` only: importing the library never changes JAX's
configuration), in the first of:

1. ``$JAXPROJ_CACHE_DIR``;
2. JAX's own cache folder, where one is set (``$JAX_COMPILATION_CACHE_DIR``);
3. ``$XDG_CACHE_HOME/jaxproj/jax-cache``, else ``~/.cache/jaxproj/jax-cache``.

``--no-cache`` (every subcommand) runs without it. Every program is cached, however quickly it
compiled (``MIN_COMPILE_SECONDS``; ``$JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS`` overrides it):
the many small programs of a retarget add up to seconds. A cached program is the executable XLA
would compile again, so no answer changes. The folder is never pruned (``jaxproj info`` shows
its size); delete it whenever you like. Like any compilation cache it is trusted code: do not
point it at a folder others can write to.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import jax

from jaxproj._internal import executables

ENV = "JAXPROJ_CACHE_DIR"
"""The environment variable that names the cache folder."""

EXECUTABLES = "executables"
"""The subfolder of the cache folder that holds whole executables (``jaxproj._internal.
executables``: the retarget programs, loaded without tracing)."""

KEEP_ENV = "JAXPROJ_KEEP_EXECUTABLES"
"""``0`` in the environment: the compilation cache without the kept executables (for a process
that changes jaxproj's code at run time, which their key cannot see; the test suite)."""

MIN_COMPILE_SECONDS = 0.0
"""Programs that took at least this long to compile are cached (JAX's default: 1 s, which
leaves out the small programs a retarget compiles dozens of)."""

_SETTINGS = (
    "jax_enable_compilation_cache",
    "jax_compilation_cache_dir",
    "jax_persistent_cache_min_compile_time_secs",
)


def _setting(name: str) -> object:
    """The value of one of JAX's settings (``jax.config``), e.g. ``"jax_compilation_cache_dir"``."""
    return getattr(jax.config, name)


def default_folder() -> Path:
    """The cache folder when neither ``$JAXPROJ_CACHE_DIR`` nor JAX's own folder is set:
    ``$XDG_CACHE_HOME/jaxproj/jax-cache`` or ``~/.cache/jaxproj/jax-cache``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "jaxproj" / "jax-cache"


def folder() -> Path:
    """The folder the command line caches programs in (the module doc's order)."""
    chosen = os.environ.get(ENV) or _setting("jax_compilation_cache_dir")
    return Path(str(chosen)).expanduser() if chosen else default_folder()


def active_folder() -> Path | None:
    """The folder JAX caches compiled programs in now, or ``None`` when the cache is off."""
    path = _setting("jax_compilation_cache_dir")
    return Path(str(path)) if path and _setting("jax_enable_compilation_cache") else None


def usage(path: Path | None) -> tuple[int, int]:
    """``(files, bytes)`` under ``path`` (``(0, 0)`` for ``None`` or a missing folder)."""
    if path is None or not path.is_dir():
        return 0, 0
    files = [p for p in path.rglob("*") if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


@contextlib.contextmanager
def compilation_cache(enabled: bool = True) -> Iterator[Path | None]:
    """Run the block with the persistent compilation cache on (in ``folder()``) or off; JAX's
    settings are restored afterwards. Yields the folder, or ``None`` when off (also when the
    folder cannot be created: a warning on stderr, and the run goes on without it).

    Within one process JAX opens its cache once, at the first compilation: a later block does
    not move it to another folder (the command line runs one block per process)."""
    saved = {name: _setting(name) for name in _SETTINGS}
    path: Path | None = folder() if enabled else None
    if path is not None:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            print(f"jaxproj: warning: no compilation cache ({path}: {e})", file=sys.stderr)
            path = None
    try:
        if path is None:
            jax.config.update("jax_enable_compilation_cache", False)
        else:
            jax.config.update("jax_enable_compilation_cache", True)
            jax.config.update("jax_compilation_cache_dir", str(path))
            if "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS" not in os.environ:
                jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
        keep = path is not None and os.environ.get(KEEP_ENV, "1") != "0"
        with executables.kept_in(path / EXECUTABLES if keep and path is not None else None):
            yield path
    finally:
        for name, value in saved.items():
            jax.config.update(name, value)
