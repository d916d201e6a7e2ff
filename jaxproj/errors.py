"""Typed errors of jaxproj.

Every error a user can trigger with bad input or bad configuration is one of these, with a message
that names the file (and frame) and says what is wrong; the CLI prints that one line and exits
non-zero, without a traceback.
"""

from __future__ import annotations


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
