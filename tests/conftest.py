"""Strict numerics for every test (no implicit dtype or rank promotion in JAX code), a
compilation counter for the no-recompilation tests, and JAX's caches cleared after every test
module.

Why the clearing: every XLA:CPU executable keeps its machine code in memory maps of its own,
and a process may hold at most ``vm.max_map_count`` of them (65,530 here). The MJX rollout
tests alone leave ~14,400 maps behind (one rollout program ~3,500), and the whole suite in one
process crossed the limit: a later compile crashed with a segmentation fault inside XLA
(``tests/test_testing.py``, in CI). ``jax.clear_caches()`` after a module releases them (one
rollout program: 4,618 -> 1,097 maps).

One persistent XLA compilation cache for the whole run (``pytest_configure``): the clearing above
would otherwise make every module compile again the programs an earlier module compiled (the
same model shapes, FK, MJX steps), and the child processes the tests start (the CLI, the
benchmarks, the notebooks' kernels) inherit it through ``JAX_COMPILATION_CACHE_DIR``; the
command line's cache (``jaxproj.cli.cache``, on by default) is pointed at it too
(``JAXPROJ_CACHE_DIR``), so no test writes into the user's cache folder. A cached
program is the same executable XLA would compile again, so no answer changes; the cache is a
fresh temporary folder per run (removed at the end), or ``$JAXPROJ_TEST_XLA_CACHE`` (or JAX's
own ``$JAX_COMPILATION_CACHE_DIR``) to keep one across local runs."""

from __future__ import annotations

import contextlib
import gc
import os
import shutil
import tempfile
from collections import Counter
from collections.abc import Callable, Iterator

import jax
import pytest

BACKEND_COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
"""The ``jax.monitoring`` duration event JAX records once per XLA compilation (also when the
executable comes from the persistent compilation cache), with the ``fun_name`` keyword set to
``"jit(<name of the jitted function>)"``."""


_CACHE_ENV = {
    "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0",
    "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "0",
}
_TEMP_CACHE: list[str] = []


def pytest_configure(config: pytest.Config) -> None:
    """Turn on the run's persistent compilation cache, here and in every child process."""
    # an xdist worker inherits its controller's folder through the environment
    folder = os.environ.get("JAXPROJ_TEST_XLA_CACHE") or os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if not folder:
        folder = tempfile.mkdtemp(prefix="jaxproj-test-xla-")
        _TEMP_CACHE.append(folder)
    # the command line's own cache (jaxproj.cli.cache) goes there too, never to the user's home
    # the command line's kept executables off (jaxproj._internal.executables): their key does
    # not see the monkeypatches of tests, and tests/test_executables.py turns them on itself
    os.environ.update(
        {
            "JAX_COMPILATION_CACHE_DIR": folder,
            "JAXPROJ_CACHE_DIR": folder,
            "JAXPROJ_KEEP_EXECUTABLES": "0",
            **_CACHE_ENV,
        }
    )
    jax.config.update("jax_compilation_cache_dir", folder)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    # strict numerics for the whole process, module and session fixtures included: the rules
    # are part of JAX's jit cache key, so a program a fixture compiled under other rules than
    # its test would compile again (one MJX rollout: ~25 s on 2 cores)
    jax.config.update("jax_numpy_dtype_promotion", "strict")
    jax.config.update("jax_numpy_rank_promotion", "raise")


_TIMELINE: dict[str, float] = {}

_COMPILED: Counter[str] = Counter()
"""Seconds of XLA compilation per jitted function's name during the current test (timeline)."""


def _timeline_listener(event: str, duration: float, **kwargs: str | int) -> None:
    if event == BACKEND_COMPILE_EVENT:
        _COMPILED[str(kwargs.get("fun_name", ""))] += duration


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """With ``$JAXPROJ_TEST_TIMELINE`` set to a file: append one JSON line per test (worker,
    start, end, seconds of XLA compilation in this process during it, and those seconds per
    jitted function), to find where a run's time goes (which worker waits at the end, which
    tests compile what)."""
    path = os.environ.get("JAXPROJ_TEST_TIMELINE")
    if not path:
        yield
        return
    import json
    import time

    if not _TIMELINE.get("listening"):
        jax.monitoring.register_event_duration_secs_listener(_timeline_listener)
        _TIMELINE["listening"] = 1.0
    t0 = time.time()
    _COMPILED.clear()
    yield
    rec = {
        "worker": os.environ.get("PYTEST_XDIST_WORKER", "main"),
        "test": item.nodeid,
        "start": t0,
        "end": time.time(),
        "compile_s": sum(_COMPILED.values()),
        "compiled": {k: round(v, 3) for k, v in _COMPILED.items()},
    }
    with open(path, "a") as f:
        f.write(json.dumps(rec) + "\n")


def pytest_unconfigure(config: pytest.Config) -> None:
    for folder in _TEMP_CACHE:
        shutil.rmtree(folder, ignore_errors=True)


HEAVY_FILES = (
    "integration/test_notebooks.py",
    "projection/test_projection.py",
    "robots/test_generic_ik.py",
    "integration/test_reliability.py",
    "integration/test_demo.py",
    "integration/test_cli.py",
    "eval/test_rollout.py",
    "integration/test_robot_file_cli.py",
    "integration/test_readme.py",
    "integration/test_bench.py",
    "integration/test_robot_seam.py",
    "projection/test_sharding.py",
    "projection/test_search.py",
    "test_testing.py",
    "motion/test_streaming.py",
    "motion/test_pipeline.py",
    "projection/test_landmarks.py",
    "motion/test_whole_body.py",
    "robots/test_shards.py",
    "eval/test_evaluate.py",
    "motion/test_retarget_many.py",
    "motion/test_retarget.py",
    "motion/test_head.py",
)
"""The test files of more than ~35 worker-seconds, longest first (measured on the 2-core VM,
2026-11-30, ``JAXPROJ_TEST_TIMELINE`` summed per file under extra load: 294 s for the notebooks
down to 37 s; ``test_shards.py``, ~45 s alone, and ``test_robot_file_cli.py``, ~110 s, had been
left out and ran last: one worker ended ~50 s before the other)."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest files first (``HEAVY_FILES``, then every file holding a ``slow`` test), the
    rest in their usual order: with whole files per xdist worker (handed out in this order:
    ``--no-loadscope-reorder`` in pyproject.toml), longest first keeps the two workers' ends
    close (a long file that starts last leaves the other worker idle until it ends: measured,
    the quick demo alone for its last ~4 min), and the many short files fill the gaps."""
    root = config.rootpath / "tests"
    rank = {root / name: i for i, name in enumerate(HEAVY_FILES)}
    slow_files = {item.path for item in items if item.get_closest_marker("slow")}

    def key(item: pytest.Item) -> int:
        if item.path in rank:
            return rank[item.path]
        return len(rank) + (item.path not in slow_files)

    items.sort(key=key)  # stable: file order kept within a rank


@pytest.fixture(autouse=True, scope="module")
def _release_executables() -> Iterator[None]:
    """Drop the compiled programs of a test module when it ends (see the module doc)."""
    yield
    jax.clear_caches()
    gc.collect()


@contextlib.contextmanager
def _count_compiles() -> Iterator[Counter[str]]:
    """Count the XLA compilations made inside the block, per jitted function.

    Yields a ``Counter`` that fills while the block runs: ``counts[f.__name__]`` is how many
    programs were compiled for the jitted function ``f`` (small helper programs that eager
    operations compile, such as ``convert_element_type``, are counted under their own names).
    Built on the public ``jax.monitoring`` listener API, not on private attributes of jitted
    functions.
    """
    counts: Counter[str] = Counter()

    def listener(event: str, duration: float, **kwargs: str | int) -> None:
        if event == BACKEND_COMPILE_EVENT:
            name = str(kwargs.get("fun_name", ""))
            counts[name.removeprefix("jit(").removesuffix(")")] += 1

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield counts
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


@pytest.fixture
def count_compiles() -> Callable[[], contextlib.AbstractContextManager[Counter[str]]]:
    """The ``_count_compiles`` context manager, for tests: ``with count_compiles() as n: ...``."""
    return _count_compiles
