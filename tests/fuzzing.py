"""Fuzzing helpers shared by the reliability tests (``test_bad_input``, ``test_reliability``):
deterministic hypothesis settings, skeletons with every kind of bad frame, the four input
formats written by hand, a JAX tracing monitor and the CLI's one-line error check."""

from __future__ import annotations

import contextlib
import io
import re
from collections.abc import Iterator
from pathlib import Path

import jax
import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from jaxproj.cli import main
from jaxproj.io import datasets
from jaxproj.io.readers import MSR_TO_SDK

FUZZ = settings(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
"""Deterministic hypothesis settings of this module (each test sets its own ``max_examples``)."""


def fuzz(max_examples: int) -> settings:
    """``FUZZ`` with ``max_examples``."""
    return settings(FUZZ, max_examples=max_examples)


TRACE_EVENT = "/jax/core/compile/jaxpr_trace_duration"
"""The ``jax.monitoring`` event JAX records each time it traces a function to a jaxpr."""


@contextlib.contextmanager
def no_tracing() -> Iterator[list[str]]:
    """Collects the JAX tracing events of the block (the test asserts there are none)."""
    events: list[str] = []

    def listener(event: str, duration: float, **kwargs: object) -> None:
        if event == TRACE_EVENT:
            events.append(str(kwargs.get("fun_name", "?")))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield events
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, *words: str) -> None:
    """Exit status 2, exactly one stderr line ``jaxproj: error: ...`` (or, for a usage error
    that argparse reports, ``jaxproj SUBCOMMAND: error: ...``) holding ``words``."""
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and re.match(r"jaxproj( [a-z]+)?: error: ", lines[0]), err
    for w in words:
        assert w in lines[0], (w, lines[0])


# --- skeleton files with every kind of bad frame -------------------------------------------------

_POOL = np.concatenate([s.positions[s.valid] for s in datasets.msr_action3d(subjects=[1])[:6]])
"""Real frames (float32 metres, SDK order) the fuzzed recordings are made of."""

READER_BAD = ("nan", "inf", "zero")
"""Frame kinds a reader marks invalid (non-finite values, lost tracking)."""
KINDS = ("ok", "ok", "nan", "inf", "zero", "huge", "tiny", "zero_bone", "far")
"""Frame kinds of the fuzzed recordings: ``huge`` / ``tiny`` scale a real frame by 1e30 /
1e-30, ``zero_bone`` puts the left elbow on the left shoulder, ``far`` moves it 1e30 away.
Only the ``ok`` frames are usable (valid after the descriptor)."""
MORE_KINDS = (*KINDS, "collapsed", "random")
"""``KINDS`` plus ``collapsed`` (every joint on one point: unusable) and ``random`` (joints
anywhere in a 4 m cube: usable or not, the descriptor decides)."""


def make_frames(kinds: list[str], seed: int) -> np.ndarray:
    """``(T, 20, 3)`` float32 positions, one frame of each kind."""
    rng = np.random.default_rng(seed)
    out = _POOL[rng.integers(len(_POOL), size=len(kinds))].copy()
    for t, kind in enumerate(kinds):
        if kind == "nan":
            out[t, rng.integers(20), rng.integers(3)] = np.nan
        elif kind == "inf":
            out[t, rng.integers(20), rng.integers(3)] = rng.choice([np.inf, -np.inf])
        elif kind == "zero":
            out[t] = 0.0
        elif kind == "huge":
            out[t] *= np.float32(1e30)
        elif kind == "tiny":
            out[t] *= np.float32(1e-30)
        elif kind == "zero_bone":
            out[t, 5] = out[t, 4]  # ElbowLeft on ShoulderLeft: upper arm of length 0
        elif kind == "far":
            out[t] += np.float32(1e30)
        elif kind == "collapsed":
            out[t] = out[t, :1]  # every joint on the hip centre
        elif kind == "random":
            out[t] = rng.uniform(-2.0, 2.0, size=(20, 3))
    return out


def _fmt(values: np.ndarray) -> list[str]:
    """``%.9g`` of float32 values: reads back to the same float32 (nan, inf included)."""
    return [f"{v:.9g}" for v in np.asarray(values, np.float32).ravel()]


def msr_file(pos: np.ndarray, nl: str = "\n", tail: str = "") -> str:
    msr = np.empty_like(pos)
    msr[:, list(MSR_TO_SDK)] = pos
    rows = [" ".join(_fmt(r) + ["1"]) + tail for r in msr.reshape(-1, 3)]
    return nl.join(rows) + nl


def utk_file(pos: np.ndarray, frames: list[int], nl: str = "\n", tail: str = "") -> str:
    rows = [f"{n} " + " ".join(_fmt(p)) + tail for n, p in zip(frames, pos, strict=True)]
    return nl.join(rows) + nl


def csv_file(pos: np.ndarray, nl: str = "\n", tail: str = "", header: bool = True) -> str:
    head = [",".join(f"j{j}_{c}" for j in range(20) for c in "xyz")] if header else []
    rows = [",".join(_fmt(p)) + tail for p in pos]
    return nl.join(head + rows) + nl


def npz_file(pos: np.ndarray, **extra: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, positions=pos, **extra)
    return buf.getvalue()


def write_recording(folder: Path, fmt: str, pos: np.ndarray, variant: int) -> Path:
    """One recording in ``fmt``; ``variant`` picks Windows line endings / trailing whitespace."""
    nl = "\r\n" if variant & 1 else "\n"
    tail = " \t" if variant & 2 else ""
    if fmt == "msr":
        path, data = folder / "a01_s01_e01_skeleton3D.txt", msr_file(pos, nl, tail)
    elif fmt == "utkinect":
        path, data = folder / "joints_s01_e01.txt", utk_file(pos, list(range(len(pos))), nl, tail)
    elif fmt == "csv":
        path, data = folder / "motion.csv", csv_file(pos, nl, tail, header=not variant & 4)
    else:
        path, data = folder / "motion.npz", npz_file(pos)
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


frame_kinds = st.lists(st.sampled_from(KINDS), min_size=1, max_size=10)
"""A recording's frame kinds (1 to 10 frames: every motion pads to one length bucket)."""
