"""Typed errors of jaxproj.

Every error a user can trigger with bad input or bad configuration is one of these, with a message
that names the file (and frame) and says what is wrong; the CLI prints that one line and exits
non-zero, without a traceback.
"""

from __future__ import annotations

import numpy as np


class JaxprojError(Exception):
    """Base class of every error raised on purpose by jaxproj."""


class InputError(JaxprojError, ValueError):
    """A skeleton / model file cannot be read: missing, empty, malformed, wrong shape.

    Args:
      path: the offending file.
      problem: what is wrong, in words.
      frame: 0-based frame index when the problem is local to a frame, else ``None``.
    """

    def __init__(self, path: object, problem: str, frame: int | None = None):
        self.path = str(path)
        self.problem = problem
        self.frame = frame
        where = self.path if frame is None else f"{self.path}: frame {frame}"
        super().__init__(f"{where}: {problem}")


class ConfigError(JaxprojError, ValueError):
    """A configuration value is out of range; the message says what to change."""


class NoValidFrameError(InputError):
    """A motion has no valid frame: nothing to retarget (``jaxproj.retarget``; the CLI's
    ``jaxproj retarget`` prints it naming the file, exits 2 and writes nothing).

    Raised instead of returning a motion at the standing posture: a recording in which every
    frame is lost, non-finite or degenerate is almost always a wrong file or a wrong unit
    (``--bvh-scale``), not a motion.

    Args:
      path: the recording (the Python API, which has no file: ``"positions"``).
      problem: what is wrong, in words (how many frames failed which check).
      n_frames: the number of frames.
    """

    def __init__(self, path: object, problem: str, n_frames: int):
        self.n_frames = int(n_frames)
        super().__init__(path, problem)


class NonFiniteRowsError(ConfigError):
    """``project`` was given descriptor rows holding NaN or inf (``rows``: their indices).

    ``project`` answers valid frames' descriptors only; it refuses such rows before anything
    is traced rather than answering them with NaN.
    """

    def __init__(self, rows: object, n_rows: int):
        self.rows = np.asarray(rows, dtype=np.int64)
        shown = ", ".join(str(int(r)) for r in self.rows[:5])
        more = "" if len(self.rows) <= 5 else f", ... ({len(self.rows)} rows)"
        super().__init__(
            f"descriptors must be finite: row(s) {shown}{more} of {int(n_rows)} hold NaN or inf "
            "(as float32); "
            "project answers valid frames only (skeleton.descriptor gives zeros, never NaN, at "
            "invalid frames: keep the rows where its valid is true, or d[np.isfinite(d).all(1)])"
        )
